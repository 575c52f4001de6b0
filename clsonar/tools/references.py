"""Independent reference solutions for the echoes of rigid 2-D scenes (walls, wedges,
cylinders, infinite in z) seen by point-like 3-D transducers in the plane z = 0.

Written from the published formulas only, with nothing taken from clsonar's own echo model,
so that tests can hold the model against them:

* :func:`piston_two_way` — the baffled circular piston's far field, two ways.
* :func:`btm_edge_gain`, :func:`btm_edge_transfer` — the exact Biot–Tolstoy–Medwin edge
  diffraction of an infinite rigid wedge, in the secondary-source form of Svensson, Fred &
  Vanderkooy, JASA 105(5), 2331–2342 (1999), eqs. 18–21; :func:`keller_gtd_gain`, Keller's
  GTD coefficient, its high-frequency limit away from the zone boundaries.
  :func:`wedge_echo_gain`, the wedge's whole echo: its faces' image sources and the BTM
  diffraction together, as they interfere near a reflection boundary.
* :func:`cylinder_series_gain`, :func:`cylinder_series_echo_gain` — the exact eigenfunction
  series of a rigid circular cylinder (Morse & Ingard, *Theoretical Acoustics* §8.1; Bowman,
  Senior & Uslenghi ch. 2), carried from a line source to a point source by stationary phase
  in k_z; :func:`cylinder_go_gain`, the geometrical-optics limit.
* :func:`kirchhoff_echo`, :func:`kirchhoff_gain_near` — the Kirchhoff (physical-optics)
  integral of a rigid z-invariant surface (Ogilvy, *Theory of Wave Scattering from Random
  Rough Surfaces* ch. 4; Medwin & Clay, *Fundamentals of Acoustical Oceanography* §12),
  with the z integral done by stationary phase.

Conventions. SI units; time dependence e^{−iωt}, so a free field is e^{ikr}/r and a delay τ
is a factor e^{iωτ}; P(ω) = ∫ p(t) e^{iωt} dt. The pulse is the thesis' eq. 2.3,
p(t) = exp(−(t − 3σ)²/(2σ²)) sin(2πft) on 0 ≤ t ≤ 6σ. Received signals are handled as
analytic signals (positive frequencies only), whose modulus is the envelope. The *relative
gain* of an echo is the peak of its envelope × L / the peak envelope of the pulse, L the
echo's total path length: the echo a perfect flat rigid mirror gives (a point image source,
p(t − L/c)/L) has gain 1 at any range. Transducers are omnidirectional unless a piston
``ka`` and axes are given; then the relative gain includes both piston patterns (the mirror
reference is taken on axis). Angles in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, signal, special

Arr = NDArray[np.float64]

#: The thesis' defaults: a 49.4 kHz carrier, 16 cycles in 6σ.
F_DEFAULT = 49.4e3
SIGMA_DEFAULT = 16 / 49.4e3 / 6
#: Received signals are sampled at σ/64; pulse templates span [−4σ, 12σ] around a tap.
_STEPS_PER_SIGMA = 64
_PRE, _POST = 4.0, 12.0


def _vec(p: ArrayLike) -> Arr:
    return np.asarray(p, dtype=float).reshape(2)


def _piston(theta: ArrayLike, ka: float) -> Arr:
    x = ka * np.sin(np.asarray(theta, dtype=float))
    small = np.abs(x) < 1e-8
    return np.where(small, 1.0, 2 * special.j1(x) / np.where(small, 1.0, x))


def piston_two_way(theta_t: ArrayLike, theta_r: ArrayLike, ka: float) -> Arr:
    """The two-way far-field pattern of a baffled circular piston of radius a (Kinsler et
    al., *Fundamentals of Acoustics* eq. 7.4.17): (2 J1(ka sinθ_T)/(ka sinθ_T)) ×
    (2 J1(ka sinθ_R)/(ka sinθ_R)); 1 on axis, first null at ka sinθ = 3.8317."""
    return _piston(theta_t, ka) * _piston(theta_r, ka)


def pulse(t: ArrayLike, f: float = F_DEFAULT, sigma: float = SIGMA_DEFAULT) -> Arr:
    """The transmitted pulse, thesis eq. 2.3: a Gaussian-windowed sine, 0 ≤ t ≤ 6σ."""
    t = np.asarray(t, dtype=float)
    inside = (t >= 0) & (t <= 6 * sigma)
    return np.where(inside, np.exp(-((t - 3 * sigma) ** 2) / (2 * sigma**2))
                    * np.sin(2 * np.pi * f * t), 0.0)


def pulse_spectrum(omega: ArrayLike, f: float = F_DEFAULT,
                   sigma: float = SIGMA_DEFAULT) -> NDArray[np.complex128]:
    """P(ω) = ∫ p(t) e^{iωt} dt of :func:`pulse` (trapezoid rule, 125 points a cycle)."""
    t = np.linspace(0.0, 6 * sigma, 2001)
    w = np.full(t.size, t[1] - t[0])
    w[[0, -1]] /= 2
    om = np.atleast_1d(np.asarray(omega, dtype=float))
    return np.exp(1j * np.outer(om, t)) @ (pulse(t, f, sigma) * w)


def _templates(f: float, sigma: float, c: float
               ) -> tuple[Arr, dict[str, NDArray[np.complex128]]]:
    """Baseband received pulses q̃_A(t) = (1/π)∫₀^∞ P(ω) A(ω) e^{−i(ω−ω₀)t} dω on
    [−4σ, 12σ] for the transfer factors A of a mirror (1) and of the Kirchhoff integrand
    (e^{−iπ/4}√(k/2π) and i e^{−iπ/4}/√(2πk), see :func:`_kirchhoff_taps`). The band is
    ω₀ ± 8/σ (the pulse spectrum's standard deviation is 1/σ), 1025 points: the sampling
    period 2π/Δω ≈ 400σ leaves the templates unaliased."""
    w0 = 2 * np.pi * f
    w = w0 + np.linspace(-8 / sigma, 8 / sigma, 1025)
    dw = w[1] - w[0]
    w = w[w > 0]
    t = np.arange(-_PRE * sigma, _POST * sigma, sigma / _STEPS_PER_SIGMA)
    kern = np.exp(-1j * np.outer(t, w - w0)) * (dw / np.pi)
    spec = pulse_spectrum(w, f, sigma)
    k = w / c
    rot = np.exp(-1j * np.pi / 4)
    mults = {"mirror": np.ones_like(k), "ka": rot * np.sqrt(k / (2 * np.pi)),
             "kb": 1j * rot / np.sqrt(2 * np.pi * k)}
    return t, {name: kern @ (spec * m) for name, m in mults.items()}


@dataclass(frozen=True)
class Received:
    """A received echo's envelope ``env`` at times ``t`` (s), and the mirror reference: the
    pulse's peak envelope ``ref_peak`` and the time ``ref_time`` after its start at which
    that peak comes (≈ 3σ)."""

    t: Arr
    env: Arr
    ref_peak: float
    ref_time: float

    def gain_at(self, i: int, c: float, path: float | None = None) -> float:
        """Relative gain of the envelope at sample ``i``; the path length is ``path`` or,
        if None, c × the delay the sample implies."""
        length = c * (self.t[i] - self.ref_time) if path is None else path
        return float(self.env[i] * length / self.ref_peak)


def _received(taus: Arr, parts: dict[str, Arr], f: float, sigma: float, c: float,
              t_lo: float, t_hi: float) -> Received:
    """The envelope on [t_lo, t_hi] of y(t) = Σ_j w_j q_A(t − τ_j), a sum of delayed,
    weighted received pulses (``parts`` maps each template A to its tap weights). The taps'
    complex weights w_j e^{iω₀τ_j} carry the exact carrier phase; they are spread linearly
    onto the σ/64 grid (an envelope shift of < σ/128) and convolved with the baseband
    templates. Exact on the window up to the templates' truncation to [−4σ, 12σ]."""
    tt, templ = _templates(f, sigma, c)
    dt = tt[1] - tt[0]
    keep = (taus > t_lo - _POST * sigma) & (taus < t_hi + _PRE * sigma)
    origin = t_lo - _POST * sigma
    m = math.ceil((t_hi + _PRE * sigma - origin) / dt) + 2
    pos = (taus[keep] - origin) / dt
    i = np.floor(pos).astype(int)
    a = pos - i
    y = np.zeros(m + tt.size - 1, dtype=complex)
    for name, w in parts.items():
        cw = w[keep] * np.exp(2j * np.pi * f * taus[keep])
        acc = np.zeros(m, dtype=complex)
        np.add.at(acc, i, cw * (1 - a))
        np.add.at(acc, i + 1, cw * a)
        y += signal.fftconvolve(acc, templ[name])
    t = origin + tt[0] + dt * np.arange(y.size)
    sel = (t >= t_lo) & (t <= t_hi)
    ref = np.abs(templ["mirror"])
    return Received(t[sel], np.abs(y[sel]), float(ref.max()), float(tt[np.argmax(ref)]))


# --- Edge diffraction: Biot–Tolstoy–Medwin, Svensson et al. 1999 ---------------------------


def _wedge_frame(p: Arr, v: Arr, face_a: Arr, face_b: Arr) -> tuple[float, float, float]:
    """(r, θ, θ_W) of point ``p`` about an edge at ``v``: r its distance from the edge, θ
    its angle from face a measured through the free region, θ_W the open (exterior) wedge
    angle, 2π less the solid wedge's angle between the faces (θ_W = 2π: a half-plane)."""
    fa, fb = face_a / np.hypot(*face_a), face_b / np.hypot(*face_b)
    theta_w = 2 * np.pi - math.acos(float(np.clip(fa @ fb, -1.0, 1.0)))
    d = p - v
    rel = math.atan2(d[1], d[0]) - math.atan2(fa[1], fa[0])
    cross = fa[0] * fb[1] - fa[1] * fb[0]
    theta = (-rel if cross > 0 else rel) % (2 * np.pi)
    if not 0 < theta < theta_w:
        raise ValueError("the point is inside the solid wedge or on a face")
    return float(np.hypot(*d)), theta, theta_w


def _btm_taps(s_xy: ArrayLike, r_xy: ArrayLike, v_xy: ArrayLike, face_a: ArrayLike,
              face_b: ArrayLike, c: float, dtau_max: float, n: int,
              piston: tuple[float, ArrayLike, ArrayLike] | None) -> tuple[Arr, Arr, float]:
    """Delays τ (s) and weights of the BTM secondary sources along the edge, Svensson et al.
    1999 eqs. 18–21: h(t) = −(ν/4π) ∫ δ(t − (m+l)/c) Σᵢ βᵢ/(m l) dz with ν = π/θ_W,
    βᵢ = sin(νφᵢ)/(cosh νη − cos νφᵢ), φᵢ = π ± θ_S ± θ_R, cosh η = (z² + m l)/(r_S r_R).
    The edge is sampled in s = √(τ − τ₀) (z ∝ s at the apex, where the delay is quadratic
    in z), uniformly to √dtau_max plus a geometric refinement near the apex that resolves
    the Lorentzian peak of β near a zone boundary; both branches ±z (S, R at z = 0).
    Exactly on a zone boundary the singular βᵢ is left out (its limit is half the
    geometrical wave, to be added to it). Also returns L₀ = r_S + r_R."""
    s_, r_, v_ = _vec(s_xy), _vec(r_xy), _vec(v_xy)
    rs, ths, theta_w = _wedge_frame(s_, v_, _vec(face_a), _vec(face_b))
    rr, thr, _ = _wedge_frame(r_, v_, _vec(face_a), _vec(face_b))
    nu = np.pi / theta_w
    s_max = math.sqrt(dtau_max)
    nodes = np.unique(np.concatenate([np.linspace(0.0, s_max, n + 1),
                                      s_max * np.geomspace(1e-7, 2e-2, 800)]))
    s, ds = (nodes[1:] + nodes[:-1]) / 2, np.diff(nodes)
    d0 = rs + rr
    cs2 = c * s * s
    dist = d0 + cs2
    z_over_s = np.sqrt(c * (cs2 + 2 * rr) * (cs2 + 2 * rs) * (dist + d0)) / (2 * dist)
    z = z_over_s * s
    m, ell = np.hypot(rs, z), np.hypot(rr, z)  # Svensson's m and l
    dz_ds = 2 * c / (z_over_s * (1 / m + 1 / ell))
    x = (z**2 + (z**2 * (rs**2 + rr**2) + z**4) / (m * ell + rs * rr)) / (rs * rr)
    eta = np.log1p(x + np.sqrt(x * (x + 2)))  # cosh η − 1 = x, no cancellation
    phi = np.pi + np.array([ths + thr, ths - thr, -ths + thr, -ths - thr])[:, None]
    half = np.sin(nu * phi / 2)
    denom = 2 * np.sinh(nu * eta / 2) ** 2 + 2 * half**2  # cosh νη − cos νφ
    beta = np.where(np.abs(half) < 1e-12, 0.0, np.sin(nu * phi) / denom).sum(axis=0)
    w = -(nu / (4 * np.pi)) * beta / (m * ell) * dz_ds * ds * 2
    if piston is not None:
        ka, ax_s, ax_r = piston
        for src, ax in ((s_, _vec(ax_s)), (r_, _vec(ax_r))):
            horiz = (v_ - src) @ (ax / np.hypot(*ax))
            w = w * _piston(np.arccos(np.clip(horiz / np.hypot(np.hypot(*(v_ - src)), z),
                                              -1, 1)), ka)
    return dist / c, w, d0


def btm_edge_gain(s_xy: ArrayLike, r_xy: ArrayLike, v_xy: ArrayLike, face_a: ArrayLike,
                  face_b: ArrayLike, c: float = 343.0, f: float = F_DEFAULT,
                  sigma: float = SIGMA_DEFAULT, *, ka: float | None = None,
                  axis_s: ArrayLike = (1.0, 0.0), axis_r: ArrayLike = (1.0, 0.0),
                  n: int = 6000) -> float:
    """Relative gain of the pulse echo diffracted by an infinite rigid wedge (edge along z
    through ``v_xy``; faces leaving it along ``face_a``, ``face_b``, the solid the convex
    region between them; equal faces: a half-plane), by the exact BTM solution of Svensson,
    Fred & Vanderkooy 1999 (:func:`_btm_taps`) convolved with the pulse: peak envelope ×
    L₀ / the pulse's, L₀ = |S−V| + |V−R|. With ``ka`` the secondary source at height z is
    weighted by both pistons' patterns at the 3-D angle between the (horizontal) axis and
    the direction to it. The edge is followed to a delay of 16σ past the apex, exact for
    the envelope on the 12σ after it."""
    tau, w, d0 = _btm_taps(s_xy, r_xy, v_xy, face_a, face_b, c, 16 * sigma, n,
                           None if ka is None else (ka, axis_s, axis_r))
    tau0 = d0 / c
    echo = _received(tau, {"mirror": w}, f, sigma, c, tau0 - sigma, tau0 + 12 * sigma)
    return echo.gain_at(int(np.argmax(echo.env)), c, d0)


def _face_image_taps(s_xy: Arr, r_xy: Arr, v_xy: Arr, faces: tuple[Arr, ...], c: float
                     ) -> tuple[Arr, Arr]:
    """Delays τ (s) and weights 1/L of the geometrical reflections of S in each face of the
    wedge (image sources, the rigid face's reflection coefficient 1): S mirrored across the
    face's line, the reflection valid where the ray from R to the image crosses the face
    itself (at or beyond the edge along the face's direction), i.e. R on the lit side of
    the face's reflection boundary."""
    taus, weights = [], []
    for face in faces:
        u = face / np.hypot(*face)
        n = np.array([-u[1], u[0]])
        hs, hr = (s_xy - v_xy) @ n, (r_xy - v_xy) @ n
        if hs * hr <= 0:
            continue  # not both in front of this face
        image = s_xy - 2 * hs * n
        crossing = r_xy + (image - r_xy) * (hr / (hr - (image - v_xy) @ n))
        if (crossing - v_xy) @ u > 0:
            length = float(np.hypot(*(r_xy - image)))
            taus.append(length / c)
            weights.append(1.0 / length)
    return np.array(taus), np.array(weights)


def wedge_echo_gain(s_xy: ArrayLike, r_xy: ArrayLike, v_xy: ArrayLike, face_a: ArrayLike,
                    face_b: ArrayLike, c: float = 343.0, f: float = F_DEFAULT,
                    sigma: float = SIGMA_DEFAULT, n: int = 6000) -> float:
    """Relative gain of the whole echo of an infinite rigid wedge (edge along z through
    ``v_xy``, faces along ``face_a``, ``face_b``) for the pulse: the geometrical
    reflections in its faces (:func:`_face_image_taps`) and the exact BTM diffraction
    (Svensson, Fred & Vanderkooy 1999, :func:`_btm_taps`) summed as received signals, their
    envelope's peak within 12σ of the edge's arrival × c·(its delay) / the pulse's (the
    receiver's time-varying gain at that time, as a mirror's echo would have it). Near a
    face's reflection boundary the face's echo and the edge's arrive within a pulse and
    interfere: on the boundary they sum to half a mirror's (Medwin 1981; the BTM terms'
    half-geometrical limit). No direct sound from S to R is included."""
    s_, r_, v_ = _vec(s_xy), _vec(r_xy), _vec(v_xy)
    tau, w, d0 = _btm_taps(s_, r_, v_, face_a, face_b, c, 16 * sigma, n, None)
    t_img, w_img = _face_image_taps(s_, r_, v_, (_vec(face_a), _vec(face_b)), c)
    tau0 = d0 / c
    echo = _received(np.concatenate([tau, t_img]), {"mirror": np.concatenate([w, w_img])},
                     f, sigma, c, tau0 - sigma, tau0 + 12 * sigma)
    return echo.gain_at(int(np.argmax(echo.env)), c)


def btm_edge_transfer(s_xy: ArrayLike, r_xy: ArrayLike, v_xy: ArrayLike, face_a: ArrayLike,
                      face_b: ArrayLike, c: float, f: float, *, periods: float = 300.0,
                      ka: float | None = None, axis_s: ArrayLike = (1.0, 0.0),
                      axis_r: ArrayLike = (1.0, 0.0)) -> complex:
    """The BTM diffracted field at one frequency, H(ω) = ∫ h(τ) e^{iωτ} dτ with the
    free-field normalisation e^{ikr}/r (Svensson et al. 1999 eq. 21 transformed); the
    conditionally convergent edge integral is summed with a smooth cos² taper over the
    second half of ``periods`` carrier periods of delay (Abel summation); relative
    error ≲ 1e-3 for the default. |H| × L₀ is the single-frequency relative gain."""
    n = int(70 * periods)
    tau, w, _ = _btm_taps(s_xy, r_xy, v_xy, face_a, face_b, c, periods / f, n,
                          None if ka is None else (ka, axis_s, axis_r))
    x = np.sqrt(np.clip((tau - tau.min()) * f / periods, 0, 1))
    taper = np.where(x < 0.5, 1.0, np.cos(np.pi * (x - 0.5)) ** 2)
    return complex(np.sum(w * taper * np.exp(2j * np.pi * f * tau)))


def keller_gtd_gain(s_xy: ArrayLike, r_xy: ArrayLike, v_xy: ArrayLike, face_a: ArrayLike,
                    face_b: ArrayLike, k: float) -> float:
    """Keller's GTD edge diffraction (rigid wedge, normal incidence; Keller, JOSA 52, 116
    (1962); Pierce, *Acoustics* §9.7): |D| = sin(π/n)/(n√(2πk)) × |1/(cos π/n − cos((θ_R −
    θ_S)/n)) + 1/(cos π/n − cos((θ_R + θ_S)/n))|, n = θ_W/π; relative gain
    |D| √((d₁+d₂)/(d₁ d₂)). Infinite on the zone boundaries; kd ≫ 1 away from them."""
    fa, fb, v_ = _vec(face_a), _vec(face_b), _vec(v_xy)
    d1, ths, theta_w = _wedge_frame(_vec(s_xy), v_, fa, fb)
    d2, thr, _ = _wedge_frame(_vec(r_xy), v_, fa, fb)
    nn = theta_w / np.pi
    cpi = math.cos(np.pi / nn)
    bracket = 1 / (cpi - math.cos((thr - ths) / nn)) + 1 / (cpi - math.cos((thr + ths) / nn))
    big_d = math.sin(np.pi / nn) / (nn * math.sqrt(2 * np.pi * k)) * abs(bracket)
    return big_d * math.sqrt((d1 + d2) / (d1 * d2))


# --- Rigid circular cylinder: the exact series --------------------------------------------


def cylinder_specular(s_xy: ArrayLike, r_xy: ArrayLike, c_xy: ArrayLike, a: float
                      ) -> tuple[float, float, float, float]:
    """The specular ray S → P → R on a circle of radius ``a`` about ``c_xy``: P minimises
    |S−P| + |P−R| (the smallest ellipse with foci S, R that touches the circle). Returns
    (L, d₁, d₂, cos θᵢ): the path length, its two legs and the incidence angle's cosine."""
    s_, r_, c_ = _vec(s_xy), _vec(r_xy), _vec(c_xy)
    us, ur = (s_ - c_) / np.hypot(*(s_ - c_)), (r_ - c_) / np.hypot(*(r_ - c_))
    bis = us + ur
    if np.hypot(*bis) < 1e-9:
        raise ValueError("forward scattering: no specular point")
    psi_b = math.atan2(bis[1], bis[0])

    def path(psi: float) -> float:
        p = c_ + a * np.array([math.cos(psi), math.sin(psi)])
        return float(np.hypot(*(s_ - p)) + np.hypot(*(r_ - p)))

    res = optimize.minimize_scalar(path, bounds=(psi_b - np.pi / 2, psi_b + np.pi / 2),
                                   method="bounded", options={"xatol": 1e-12})
    nrm = np.array([math.cos(res.x), math.sin(res.x)])
    p = c_ + a * nrm
    d1, d2 = float(np.hypot(*(s_ - p))), float(np.hypot(*(r_ - p)))
    return d1 + d2, d1, d2, float(nrm @ (s_ - p) / d1)


def cylinder_go_gain(s_xy: ArrayLike, r_xy: ArrayLike, c_xy: ArrayLike, a: float) -> float:
    """Geometrical-optics relative gain of a convex cylinder (curved in the plane only):
    √((d₁+d₂)/(d₁+d₂+2d₁d₂/(a cos θᵢ))); monostatic √(a/(a+d)). (A concave surface of
    radius a has −a in the formula; it diverges on the caustic, d₁+d₂ = 2d₁d₂/(a cos θᵢ).)"""
    _, d1, d2, cos_i = cylinder_specular(s_xy, r_xy, c_xy, a)
    return math.sqrt((d1 + d2) / (d1 + d2 + 2 * d1 * d2 / (a * cos_i)))


def cylinder_series_field(s_xy: ArrayLike, r_xy: ArrayLike, c_xy: ArrayLike, a: float,
                          k: float) -> complex:
    """The exact 2-D field scattered by a rigid (Neumann) cylinder from a line source whose
    incident field is H₀⁽¹⁾(k|r − r_S|) (Morse & Ingard §8.1, Graf's addition theorem):
    p_s = −Σ_n ε_n [J_n'(ka)/H_n'(ka)] H_n(k r_S) H_n(k r) cos n(φ − φ_S), ε₀ = 1, ε_n = 2,
    n ≤ N = ka + 10 (ka)^{1/3} + 10 (the ratio falls super-exponentially past ka). Terms
    whose Hankel functions overflow (n ≫ kr, only for very small kr) are dropped; scipy's
    AMOS routines keep ~1e-10 accuracy to ka of several thousand (about 0.3 s at 2000)."""
    s_, r_, c_ = _vec(s_xy), _vec(r_xy), _vec(c_xy)
    ds, dr = s_ - c_, r_ - c_
    rs, rr = float(np.hypot(*ds)), float(np.hypot(*dr))
    dphi = math.atan2(dr[1], dr[0]) - math.atan2(ds[1], ds[0])
    ka = k * a
    n = np.arange(int(ka + 10 * ka ** (1 / 3) + 10) + 1)
    with np.errstate(all="ignore"):
        terms = (special.jvp(n, ka) / special.h1vp(n, ka) * special.hankel1(n, k * rs)
                 * special.hankel1(n, k * rr) * np.where(n == 0, 1.0, 2.0) * np.cos(n * dphi))
    bad = ~np.isfinite(terms)
    if bad.any():
        terms = terms[: int(np.argmax(bad))]
    return complex(-terms.sum())


def cylinder_series_gain(s_xy: ArrayLike, r_xy: ArrayLike, c_xy: ArrayLike, a: float,
                         k: float) -> float:
    """Single-frequency relative gain of a rigid cylinder for point transducers at z = 0:
    |p_s,2D| / |H₀⁽¹⁾(k L)|, L the specular path (:func:`cylinder_specular`). A point source
    is the k_z-superposition of line sources; with S and R at z = 0 its stationary point is
    k_z = 0, and the out-of-plane spreading of the specular ray (z-invariant surface) is
    that of free space over L, the same as for a flat mirror at the same path, which the
    2-D mirror gives as H₀(kL). Error O(1/(kL)) (stationary phase, Hankel asymptotics).
    Creeping waves are included (single frequency); they matter for ka ≲ 20."""
    length = cylinder_specular(s_xy, r_xy, c_xy, a)[0]
    return abs(cylinder_series_field(s_xy, r_xy, c_xy, a, k)) / abs(
        special.hankel1(0, k * length))


def cylinder_series_echo_gain(s_xy: ArrayLike, r_xy: ArrayLike, c_xy: ArrayLike, a: float,
                              c: float = 343.0, f: float = F_DEFAULT,
                              sigma: float = SIGMA_DEFAULT, n_freq: int = 64) -> float:
    """Relative gain of the pulse echo of a rigid cylinder: the series
    (:func:`cylinder_series_field`) at ``n_freq`` frequencies over ω₀ ± 5/σ, each carried to
    3-D by the factor e^{ikL}/(L H₀(kL)) of :func:`cylinder_series_gain`, weighted by the
    pulse spectrum, summed to the analytic signal on the gate [−2σ, 8σ] about the specular
    delay L/c and compared with the mirror echo at L summed the same way. The frequency
    sampling repeats the response every 2π/Δω ≈ 40σ (n_freq = 64); creeping waves that
    arrive 2σ–8σ after the specular echo (modulo that period) fall in the gate."""
    length = cylinder_specular(s_xy, r_xy, c_xy, a)[0]
    w = 2 * np.pi * f + np.linspace(-5 / sigma, 5 / sigma, n_freq)
    k = w / c
    field = np.array([cylinder_series_field(s_xy, r_xy, c_xy, a, kk) for kk in k])
    spec = pulse_spectrum(w, f, sigma)
    rel = field / (length * special.hankel1(0, k * length))  # times e^{ikL}, removed
    t = np.linspace(-2 * sigma, 8 * sigma, 321)
    kern = np.exp(-1j * np.outer(t, w))
    echo = np.abs(kern @ (spec * rel)).max()
    mirror = np.abs(kern @ (spec / length)).max()
    return float(echo / mirror)


# --- Kirchhoff (physical optics) for z-invariant surfaces -----------------------------------


def _resample(curve: Arr, step: float) -> tuple[Arr, Arr, Arr]:
    """The polyline ``curve`` resampled at arc-length spacing ≤ ``step``; also the new and
    the old points' arc lengths."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(curve, axis=0).T))])
    u = np.linspace(0.0, s[-1], max(math.ceil(s[-1] / step), 1) + 1)
    return np.column_stack([np.interp(u, s, curve[:, 0]), np.interp(u, s, curve[:, 1])]), u, s


def _kirchhoff_taps(curve_xy: ArrayLike, s_xy: ArrayLike, r_xy: ArrayLike, c: float,
                    f: float, sigma: float, normals: ArrayLike | None,
                    piston: tuple[float, ArrayLike, ArrayLike] | None
                    ) -> tuple[Arr, dict[str, Arr]]:
    """Kirchhoff integral p_s = (1/4π)∫∫ 2 p_inc ∂G/∂n dS, p_inc = e^{ikr₁}/r₁,
    G = e^{ikr₂}/r₂, n into the fluid, on a z-invariant surface; ∂G/∂n = −ik cosθ₂ (1 +
    i/(kr₂)) G. The z integral by stationary phase at z = 0,
    ∫ e^{ik(r₁+r₂)} dz ≈ √(2πρ₁ρ₂/(k(ρ₁+ρ₂))) e^{iπ/4} e^{ik(ρ₁+ρ₂)}, leaves
    p_s = Σ_j Δs cosθ₂/√(ρ₁ρ₂(ρ₁+ρ₂)) e^{−iπ/4}√(k/2π) (1 + i/(kρ₂)) e^{ik(ρ₁+ρ₂)},
    i.e. taps at τ = (ρ₁+ρ₂)/c on the templates "ka" (weights w) and "kb" (w/ρ₂). The curve
    is resampled at λ/16 of the band's top frequency. Shadowing: only points with
    n·(S−x) > 0 and n·(R−x) > 0 (exact for convex surfaces, fine for gentle ones).
    Normals: given per curve point, or the curve's left normals turned so that the point
    nearest S faces S."""
    crv = np.asarray(curve_xy, dtype=float)
    s_, r_ = _vec(s_xy), _vec(r_xy)
    pts, u, s_old = _resample(crv, c / (f + 8 / (2 * np.pi * sigma)) / 16)
    mid, seg = (pts[1:] + pts[:-1]) / 2, np.diff(pts, axis=0)
    ds = np.hypot(*seg.T)
    if normals is None:
        nrm = np.column_stack([-seg[:, 1], seg[:, 0]]) / ds[:, None]
        j = int(np.argmin(np.hypot(*(mid - s_).T)))
        nrm = nrm if nrm[j] @ (s_ - mid[j]) > 0 else -nrm
    else:
        nv = np.asarray(normals, dtype=float)
        um = (u[1:] + u[:-1]) / 2
        nrm = np.column_stack([np.interp(um, s_old, nv[:, 0]), np.interp(um, s_old, nv[:, 1])])
        nrm /= np.hypot(*nrm.T)[:, None]
    v1, v2 = s_ - mid, r_ - mid
    rho1, rho2 = np.hypot(*v1.T), np.hypot(*v2.T)
    cos1, cos2 = np.sum(nrm * v1, axis=1) / rho1, np.sum(nrm * v2, axis=1) / rho2
    w = np.where((cos1 > 0) & (cos2 > 0), ds * cos2 / np.sqrt(rho1 * rho2 * (rho1 + rho2)), 0)
    if piston is not None:
        ka, ax_s, ax_r = piston
        for vv, rho, ax in ((v1, rho1, _vec(ax_s)), (v2, rho2, _vec(ax_r))):
            cosang = -(vv @ (ax / np.hypot(*ax))) / rho
            w = w * _piston(np.arccos(np.clip(cosang, -1, 1)), ka)
    lit = w != 0
    return ((rho1 + rho2) / c)[lit], {"ka": w[lit], "kb": (w / rho2)[lit]}


def kirchhoff_echo(curve_xy: ArrayLike, s_xy: ArrayLike, r_xy: ArrayLike, c: float = 343.0,
                   f: float = F_DEFAULT, sigma: float = SIGMA_DEFAULT, *,
                   normals: ArrayLike | None = None, min_gain: float = 0.02,
                   ka: float | None = None, axis_s: ArrayLike = (1.0, 0.0),
                   axis_r: ArrayLike = (1.0, 0.0)) -> list[tuple[float, float]]:
    """The echoes of a rigid z-invariant surface (cross-section ``curve_xy``, [n, 2]) in
    the Kirchhoff approximation (:func:`_kirchhoff_taps`) with the pulse: (delay, relative
    gain) of each local maximum of the envelope with gain ≥ ``min_gain`` (maxima closer
    than 2σ merged), delay = the peak's time less the pulse's peak time (≈ 3σ), and the
    gain's path length c × delay. Specular points, caustics (finite here, where ray optics
    diverges) and the truncated ends' edge waves (physical-optics, approximate) all show."""
    taus, parts = _kirchhoff_taps(curve_xy, s_xy, r_xy, c, f, sigma, normals,
                                  None if ka is None else (ka, axis_s, axis_r))
    if taus.size == 0:
        return []
    echo = _received(taus, parts, f, sigma, c, taus.min() - 2 * sigma,
                     taus.max() + 8 * sigma)
    gain = echo.env * c * np.maximum(echo.t - echo.ref_time, 0) / echo.ref_peak
    peaks, _ = signal.find_peaks(gain, height=min_gain, distance=2 * _STEPS_PER_SIGMA)
    return [(float(echo.t[p] - echo.ref_time), float(gain[p])) for p in peaks]


def kirchhoff_gain_near(curve_xy: ArrayLike, s_xy: ArrayLike, r_xy: ArrayLike, tof: float,
                        c: float = 343.0, f: float = F_DEFAULT, sigma: float = SIGMA_DEFAULT,
                        *, normals: ArrayLike | None = None, ka: float | None = None,
                        axis_s: ArrayLike = (1.0, 0.0),
                        axis_r: ArrayLike = (1.0, 0.0)) -> float:
    """Relative gain of the Kirchhoff echo (:func:`kirchhoff_echo`) whose envelope peaks
    nearest a time of flight ``tof`` (the echo's start, s): the envelope's maximum on
    [tof − 2σ, tof + 8σ]; only the taps that reach that window are summed (fast for long
    surfaces). The path length of the gain is c × (peak time − the pulse's peak time)."""
    taus, parts = _kirchhoff_taps(curve_xy, s_xy, r_xy, c, f, sigma, normals,
                                  None if ka is None else (ka, axis_s, axis_r))
    echo = _received(taus, parts, f, sigma, c, tof - 2 * sigma, tof + 8 * sigma)
    return echo.gain_at(int(np.argmax(echo.env)), c)
