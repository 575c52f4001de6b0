"""Physical constants and models of the Polaroid-6500-like transducer (thesis chapter 2).

Everything here is float64 NumPy; the OpenCL kernels implement the same formulas and the
host passes them the constants computed here (see :func:`beam_series_coefficients`).

The echo amplitude model
------------------------
An echo that leaves transmitter T at angle θ_T off its axis and reaches receiver R at θ_R
off its axis, after ``n`` reflections along a path of length ``L``, has amplitude

    A = A0 · b(θ_T) · b(θ_R) · ρⁿ · G_kind · 10^(−α·L/20)

- ``A0`` is the transmitted amplitude (5 units in the thesis);
- ``b`` is the circular-piston beam pattern with the thesis' hard cut (:func:`beam_pattern`);
- ``ρ`` is the reflection coefficient of a wall (default 0.9, see below);
- ``α`` is the air absorption in dB/m left after the receiver's time-varying gain (default 0);
- the receiver's time-varying gain (TVG) compensates the spherical spreading of a flat
  reflector exactly, so a flat wall at normal incidence returns ``ρ·A0`` from any distance;
- ``G_kind`` is 1 for flat walls (specular and corner multi-bounce); for curved surfaces
  the extra divergence of the reflected ray tube relative to a flat mirror
  (:func:`curved_gain`; scene key ``echo.curvature_gain`` false sets it to 1, as the
  thesis' ray tracing had it); for diffraction at a convex edge the uniform theory of
  diffraction's coefficient of a rigid wedge (:func:`edge_gain`).

Why ρ = 0.9: with the thesis' threshold of 4 units and A0 = 5, a single reflection at
normal incidence gives 4.5 (detected), a double reflection 4.05 — above threshold only
when both beams are within about 0.6° of perfect alignment — so multiply-reflected echoes
"attenuate and may stay below the threshold" (thesis §2.1.2) while direct echoes clear it.
"""

from __future__ import annotations

import math

import numpy as np

from .numerics import j1

#: First zero of the Bessel function J1: the piston pattern's first null (ka·sinθ = j1).
J1_FIRST_ZERO = 3.8317059702075125

#: Length of the Polaroid 6500 ranging module's burst: 16 cycles at 49.4 kHz ≈ 320 µs.
POLAROID_BURST_S = 16 / 49.4e3

#: Default σ of the pulse envelope (eq. 2.3): its 6σ support equals the burst length, so
#: σ = 320 µs / 6 ≈ 54 µs.
DEFAULT_PULSE_SIGMA_S = POLAROID_BURST_S / 6

#: Default wall reflection coefficient ρ (see the module docstring).
DEFAULT_REFLECTION_COEFFICIENT = 0.9

#: Focusing by a concave surface raises the echo at most by this factor over a flat mirror
#: (geometrical optics diverges at a caustic; a real aperture does not).
MAX_FOCUS_GAIN = 4.0


def speed_of_sound(temperature_k: float) -> float:
    """Speed of sound in air, thesis eq. 2.1: ``c = 331.4·sqrt(T/273)`` m/s."""
    if not temperature_k > 0:
        raise ValueError("temperature must be > 0 K")
    return 331.4 * math.sqrt(temperature_k / 273.0)


def wavenumber(frequency_hz: float, c: float) -> float:
    """Acoustic wavenumber ``k = 2π f / c`` in rad/m."""
    return 2.0 * math.pi * frequency_hz / c


def half_beam_angle(frequency_hz: float, radius_m: float, c: float) -> float:
    """Half-beam angle θ0 in radians, thesis eq. 2.2: ``θ0 = asin(0.61·λ/a)``.

    ≈ 12.1° for 50 kHz, a = 2 cm, c = 343.4 m/s. It is (to 0.1 %) the piston pattern's first
    null, since 0.61·2π ≈ j1 = 3.832. Raises ``ValueError`` when 0.61·λ/a ≥ 1 (no beam).
    """
    s = 0.61 * (c / frequency_hz) / radius_m
    if not 0 < s < 1:
        raise ValueError("0.61·λ/a must be below 1: the transducer is too small for its frequency")
    return math.asin(s)


def piston_pattern(x: np.ndarray | float) -> np.ndarray:
    """Circular-piston far-field amplitude ``2·J1(x)/x`` with ``x = k·a·sinθ`` (1 at x = 0)."""
    x = np.asarray(x, dtype=np.float64)
    safe = np.where(x == 0.0, 1.0, x)
    return np.where(x == 0.0, 1.0, 2.0 * j1(safe) / safe)


def beam_cut_sin2(frequency_hz: float, radius_m: float, half_beam_deg: float, c: float) -> float:
    """sin² of the effective hard cut: the smaller of ``half_beam_deg`` and the first null.

    Only the main lobe is modelled; beyond the cut the sensitivity is zero (thesis §2.1).
    """
    ka = wavenumber(frequency_hz, c) * radius_m
    s_null = min(1.0, J1_FIRST_ZERO / ka)
    s_cut = math.sin(math.radians(min(half_beam_deg, 90.0)))
    return min(s_cut, s_null) ** 2


def beam_pattern(
    cos_theta: np.ndarray, sin_theta: np.ndarray, ka: float, cut_sin2: float
) -> np.ndarray:
    """Sensitivity ``b(θ) = 2·J1(ka·sinθ)/(ka·sinθ)`` inside the hard cut, 0 outside.

    ``cos_theta``/``sin_theta`` describe the angle between the transducer's axis and the
    direction to the point; a point behind the transducer (cosθ ≤ 0) or with
    ``sin²θ > cut_sin2`` gets 0. Thesis §2.1 and eq. 2.2 (beam of ±θ0).
    """
    cos_theta = np.asarray(cos_theta, dtype=np.float64)
    sin_theta = np.asarray(sin_theta, dtype=np.float64)
    inside = (cos_theta > 0) & (sin_theta * sin_theta <= cut_sin2)
    return np.where(inside, piston_pattern(ka * np.abs(sin_theta)), 0.0)


def beam_constants(frequency_hz: float, radius_m: float, half_beam_deg: float,
                   directivity: str, c: float) -> tuple[float, float]:
    """``(cut_sin2, ka)`` of a transducer for :func:`beam_pattern`: the hard cut and the
    piston's k·a. ``directivity`` ``"uniform"`` (the thesis' flat sensitivity inside the
    cut, §2.1: "divided into 25 parts starting at −12° and ending at +12°") gives ka = 0,
    which makes the pattern 1 everywhere inside the cut."""
    cut = beam_cut_sin2(frequency_hz, radius_m, half_beam_deg, c)
    ka = 0.0 if directivity == "uniform" else wavenumber(frequency_hz, c) * radius_m
    return cut, ka


def beam_series_coefficients(terms: int = 14) -> np.ndarray:
    """Coefficients ``c_k`` of ``2·J1(x)/x = (1 − u)·Σ c_k·u^k`` with ``u = (x/j1)²``.

    With ``a_m`` the Taylor coefficients of ``2·J1(x)/x`` in ``u`` (``a_m = (−1)^m
    (j1²/4)^m / (m!(m+1)!)``), dividing by ``(1 − u)`` gives the partial sums
    ``c_k = Σ_{m≤k} a_m``. Factoring out the null keeps the relative error small right up
    to the beam edge, which a plain Taylor series in float32 does not. 14 terms give
    |error| < 1e-12 on 0 ≤ u ≤ 1. The kernels evaluate the sum by Horner's rule.
    """
    q = J1_FIRST_ZERO**2 / 4.0
    a = [(-q) ** m / (math.factorial(m) * math.factorial(m + 1)) for m in range(terms)]
    return np.cumsum(a)


def curved_gain(
    d1: np.ndarray, d2: np.ndarray, curvature: np.ndarray, cos_incidence: np.ndarray
) -> np.ndarray:
    """Echo amplitude from a curved reflector relative to a flat mirror at the same path length.

    In the plane of the scene a reflector of curvature κ (> 0 convex as seen by the
    transducers, < 0 concave) at incidence angle θi spreads the reflected ray tube as if
    the path were ``L_eff = d1 + d2 + 2κ·d1·d2/cosθi`` long (d1, d2: distances from the
    transmitter and to the receiver). Across the plane the surface is flat (a cylinder or a
    corrugated wall), so the 3-D amplitude relative to a flat mirror is
    ``sqrt((d1 + d2) / |L_eff|)``, capped at :data:`MAX_FOCUS_GAIN` near caustics.
    """
    d1 = np.asarray(d1, dtype=np.float64)
    d2 = np.asarray(d2, dtype=np.float64)
    path = d1 + d2
    l_eff = np.abs(path + 2.0 * curvature * d1 * d2 / cos_incidence)
    floor = path / MAX_FOCUS_GAIN**2
    return np.sqrt(path / np.maximum(l_eff, floor))


def edge_gain_estimate(d1: np.ndarray, d2: np.ndarray, k: float,
                       coefficient: float) -> np.ndarray:
    """Echo amplitude diffracted by a convex edge relative to a flat mirror at the same
    path, as an order of magnitude (``echo.edge_model`` ``"estimate"``): the geometrical
    theory of diffraction's ``|D|/sqrt(d1·d2·(d1+d2))`` against ``1/(d1 + d2)`` with
    ``|D| ≈ 1/(2·sqrt(2πk))`` and no angular factor, ``coefficient · sqrt((d1+d2)/(d1·d2))
    / (2·sqrt(2πk))`` (about 0.01 at 1 m for 50 kHz). Against the exact wedge it is 4 dB
    low along a box corner's diagonal and tens of dB low near the faces' reflection
    boundaries (docs/physics.md); :func:`edge_gain` is the uniform theory."""
    d1 = np.asarray(d1, dtype=np.float64)
    d2 = np.asarray(d2, dtype=np.float64)
    return coefficient * np.sqrt((d1 + d2) / (d1 * d2)) / (2.0 * math.sqrt(2.0 * math.pi * k))


#: Below this argument the Fresnel auxiliary functions are the rational approximations of
#: Abramowitz & Stegun 7.3.32–33 (absolute error < 2e-3), above it their asymptotic series,
#: A&S 7.3.27–28 to the second term (relative error < 2e-4).
FRESNEL_SWITCH = 3.0


def fresnel_auxiliary(z: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """``(f(z), g(z))``, the auxiliary functions of the Fresnel integrals (A&S 7.3.9–10:
    ``C(z) = 1/2 + f·sin(πz²/2) − g·cos(πz²/2)``, ``S(z) = 1/2 − f·cos(πz²/2) −
    g·sin(πz²/2)``), z ≥ 0; f(0) = g(0) = 1/2, f ~ 1/(πz) and g ~ 1/(π²z³) for large z.
    ``|f + i·g|`` is within 1.4 % of the exact value (tests/test_physics.py), which is what
    :func:`edge_gain` needs; the kernels use the same formulas (:data:`FRESNEL_SWITCH`)."""
    z = np.asarray(z, dtype=np.float64)
    zf = np.maximum(z, FRESNEL_SWITCH)  # the far branch, evaluated only where it applies
    x2 = (math.pi * zf * zf) ** -2.0
    f_far = (1.0 - 3.0 * x2 + 105.0 * x2 * x2) / (math.pi * zf)
    g_far = (1.0 - 15.0 * x2 + 945.0 * x2 * x2) / (math.pi**2 * zf**3)
    f_near = (1.0 + 0.926 * z) / (2.0 + 1.792 * z + 3.104 * z * z)
    g_near = 1.0 / (2.0 + 4.142 * z + 3.492 * z * z + 6.670 * z**3)
    far = z >= FRESNEL_SWITCH
    return np.where(far, f_far, f_near), np.where(far, g_far, g_near)


def wedge_angles(x: np.ndarray, v: np.ndarray, va: np.ndarray, vb: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(φ, n)`` of points ``x`` [..., 2] about a convex edge at ``v`` whose faces leave
    it along the unit vectors ``va`` and ``vb`` (the solid wedge is the convex angle α
    between them): φ the angle of x − v from face a through the free region, 0 ≤ φ ≤ nπ,
    and n = (2π − α)/π the wedge index of the diffraction coefficient (n = 1.5 for a right-
    angled box corner, 2 for a thin wall's end)."""
    cab = va[..., 0] * vb[..., 1] - va[..., 1] * vb[..., 0]
    s = np.where(cab >= 0, 1.0, -1.0)
    alpha = np.arctan2(np.abs(cab), va[..., 0] * vb[..., 0] + va[..., 1] * vb[..., 1])
    w = x - v
    cross_aw = va[..., 0] * w[..., 1] - va[..., 1] * w[..., 0]
    phi = np.arctan2(-s * cross_aw, va[..., 0] * w[..., 0] + va[..., 1] * w[..., 1])
    return np.where(phi < 0, phi + 2.0 * math.pi, phi), (2.0 * math.pi - alpha) / math.pi


def edge_diffraction(d1: np.ndarray, d2: np.ndarray, phi_t: np.ndarray, phi_r: np.ndarray,
                     n: np.ndarray, k: float, coefficient: float, rho: float = 1.0
                     ) -> np.ndarray:
    """Complex echo diffracted by a rigid convex edge relative to a flat mirror at the same
    path length: the uniform theory of diffraction (Kouyoumjian & Pathak, Proc. IEEE
    62(11), 1974, eqs. 25–27 and 32; time dependence e^{+iωt}) for a spherical wave, edge
    perpendicular to the scene's plane.

    The diffracted field is ``u_i·D·sqrt(d1/(d2·(d1 + d2)))·e^{−ik·d2}`` against
    ``e^{−ik(d1+d2)}/(d1 + d2)`` for a mirror, so the ratio is ``D/sqrt(L)``,
    L = d1·d2/(d1 + d2). D (hard wedge, the sum of its four terms) is
    ``−e^{−iπ/4}/(2n·sqrt(2πk))·Σ cot((π ± β)/(2n))·F(kL·a±(β))`` over β = φ_R ∓ φ_T,
    F(X) = 2i·sqrt(X)·e^{iX}·∫_{sqrt X}^∞ e^{−iτ²} dτ. With ε the distance of π ± β from its
    nearest multiple of 2πn, each term is ``2·sqrt(πkL)·q·(f(z) + i·g(z))``,
    q = cot(ε/2n)·|sin(ε/2)| and z = 2|sin(ε/2)|·sqrt(kL/π) (:func:`fresnel_auxiliary`:
    F = sqrt(2πX)·(f + i·g)), so that

        G = −coefficient · e^{−iπ/4} · Σ q·(f + i·g) / (n·sqrt(2)).

    Far from the shadow and reflection boundaries |G| is Keller's geometrical theory of
    diffraction (about 0.01 at 1 m for 50 kHz) and its phase −π/4 (or 3π/4, by the sign of
    the cotangents). On a face's reflection boundary the singular term's q is ±n, f = g =
    1/2 and G = ∓1/2, real: −1/2 on the lit side, where the face's specular echo (+1) adds
    to it to half a mirror's, +1/2 on the shadow side, where it is the whole echo; so the
    sign of G flips across the boundary and the total is continuous. Faces that reflect
    ``rho`` of the sound (``echo.reflection_coefficient``) weight the two reflection-boundary
    terms (β = φ_R + φ_T) by it (Luebbers, IEEE Trans. AP-32(1), 1984), so the total stays
    continuous: ρ/2 on the boundary from either side, where the face's specular echo is ρ.
    ``coefficient`` (scene key ``echo.edge_coefficient``, default 1) scales it; the 2-D
    scene's edges are infinitely long.
    """
    d1 = np.asarray(d1, dtype=np.float64)
    d2 = np.asarray(d2, dtype=np.float64)
    kl = k * d1 * d2 / (d1 + d2)
    total = np.zeros(np.broadcast(d1, d2, phi_t, phi_r, n).shape, dtype=np.complex128)
    for sign_b, weight in ((-1.0, 1.0), (1.0, rho)):
        beta = phi_r + sign_b * phi_t
        for x in (math.pi + beta, math.pi - beta):
            eps = x - 2.0 * math.pi * n * np.floor(x / (2.0 * math.pi * n) + 0.5)
            half = np.abs(np.sin(0.5 * eps))
            sn = np.sin(eps / (2.0 * n))
            tiny = np.abs(sn) < 1e-12
            q = np.where(tiny, n, np.cos(eps / (2.0 * n)) * half / np.where(tiny, 1.0, sn))
            f, g = fresnel_auxiliary(2.0 * half * np.sqrt(kl / math.pi))
            total = total + weight * q * (f + 1j * g)
    return -coefficient * np.exp(-0.25j * math.pi) * total / (n * math.sqrt(2.0))


def edge_gain(d1: np.ndarray, d2: np.ndarray, phi_t: np.ndarray, phi_r: np.ndarray,
              n: np.ndarray, k: float, coefficient: float, rho: float = 1.0) -> np.ndarray:
    """Echo amplitude diffracted by a rigid convex edge relative to a flat mirror at the
    same path length, ``|G|`` of :func:`edge_diffraction` (Kouyoumjian & Pathak 1974):
    Keller's GTD far from the boundaries, 1/2 on them. Its phase is :func:`edge_phase`."""
    return np.abs(edge_diffraction(d1, d2, phi_t, phi_r, n, k, coefficient, rho))


def edge_phase(d1: np.ndarray, d2: np.ndarray, phi_t: np.ndarray, phi_r: np.ndarray,
               n: np.ndarray, k: float, rho: float = 1.0) -> np.ndarray:
    """The diffracted echo's carrier phase against a mirror's at the same path, radians in
    (−π, π]: ``arg G`` of :func:`edge_diffraction` (time dependence e^{+iωt}), so that the
    echo is ``|G|·env(u)·sin(ωu + arg G)`` where a mirror's is ``env(u)·sin(ωu)``
    (:func:`pulse`; the narrow-band pulse's analytic signal times G). −π/4 or 3π/4 far from
    the boundaries, 0 or π on a reflection boundary (π on its lit side)."""
    return np.angle(edge_diffraction(d1, d2, phi_t, phi_r, n, k, 1.0, rho))


def absorption_factor(path_m: np.ndarray, absorption_db_per_m: float) -> np.ndarray:
    """Amplitude factor ``10^(−α·L/20)`` of the absorption left after the receiver's TVG."""
    return 10.0 ** (-absorption_db_per_m * np.asarray(path_m, dtype=np.float64) / 20.0)


def pulse(
    t: np.ndarray, sigma_s: float, frequency_hz: float, amplitude: float, phase: float = 0.0
) -> np.ndarray:
    """Transmitted pulse, thesis eq. 2.3, scaled so its largest sample magnitude is ``amplitude``.

    ``p(t) = K·exp(−(t − 3σ)²/(2σ²))·sin(2π f t + φ)`` for ``0 ≤ t ≤ 6σ``, else 0. ``K`` is
    the normalisation that makes the peak of the envelope-times-carrier equal ``amplitude``
    (5 units in the thesis); see :func:`pulse_normalisation`. ``phase`` φ shifts the carrier
    under its envelope (an edge's diffraction, :func:`edge_phase`; 0 for the thesis' pulse).
    """
    t = np.asarray(t, dtype=np.float64)
    k = amplitude * pulse_normalisation(sigma_s, frequency_hz)
    return pulse_shape(t, sigma_s, frequency_hz, k, phase)


def pulse_shape(t: np.ndarray, sigma: float, frequency: float, k: float,
                phase: float = 0.0) -> np.ndarray:
    """``K·exp(−(t − 3σ)²/(2σ²))·sin(2π f t + φ)`` for ``0 ≤ t ≤ 6σ``, else 0: eq. 2.3 with a
    given ``K`` and carrier phase φ, in any unit of time (seconds and hertz, or samples and
    cycles per sample)."""
    env = np.exp(-((t - 3.0 * sigma) ** 2) / (2.0 * sigma**2))
    p = k * env * np.sin(2.0 * math.pi * frequency * t + phase)
    return np.where((t >= 0.0) & (t <= 6.0 * sigma), p, 0.0)


def pulse_normalisation(sigma_s: float, frequency_hz: float) -> float:
    """``K`` of eq. 2.3 for unit amplitude: 1 / max over t of |envelope·carrier|.

    The maximum lies at the carrier peak nearest the envelope centre 3σ; it is found on a
    fine grid around it (1/1000 of a carrier period) and is ≥ 1.
    """
    period = 1.0 / frequency_hz
    t = 3.0 * sigma_s + np.linspace(-period, period, 2001)
    env = np.exp(-((t - 3.0 * sigma_s) ** 2) / (2.0 * sigma_s**2))
    return float(1.0 / np.max(np.abs(env * np.sin(2.0 * math.pi * frequency_hz * t))))
