"""The echo model in NumPy float64: the reference of the OpenCL kernels (kernels/echoes.cl),
one function per kernel family, evaluating the same formulas."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import physics
from ..geometry import cross, curve_derivatives, curve_point, dot, norm
from ..scene import Scene
from ..sensors import SensorArray
from .problem import BISECT_ITERATIONS, OCCLUSION_EPS_M, EchoProblem, prepare_problem
from .table import EchoTable, solve

#: |â + b̂| below this: T and R are on opposite sides of a cylinder, no shorter arc.
MIN_BISECTOR = 1e-6


def reference_echoes(scene: Scene, sensors: SensorArray | None = None) -> EchoTable:
    """The echo table computed in NumPy float64: the reference of :func:`compute_echoes`."""
    pb = prepare_problem(scene, sensors)
    families = {"mirror": _ref_mirror, "vertex": _ref_vertex, "edge": _ref_edge,
                "circle": _ref_circle, "curve": _ref_curve}
    with np.errstate(divide="ignore", invalid="ignore"):
        return solve(pb, lambda family, chunk: _with_phase(families[family](pb, pb.pairs[chunk])))


def _with_phase(out: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """A family's ``(tof, amp, point[, phase])`` with the carrier phase, 0 where the family
    gives none (every reflection: only an edge's diffraction shifts the carrier)."""
    return out if len(out) == 4 else (*out, np.zeros_like(out[1]))


def _ref_beam(pb: EchoProblem, axis: np.ndarray, d: np.ndarray) -> np.ndarray:
    """b(θ) between unit ``axis`` and direction ``d`` (physics.beam_pattern; sin²θ from the
    cross product as the kernels compute it)."""
    c = dot(axis, d)
    s = cross(axis, d)
    sin2 = (s * s) / dot(d, d)
    inside = (c > 0) & (sin2 <= pb.cut_sin2)
    x = pb.ka * np.sqrt(np.where(inside, sin2, 0.0))
    return np.where(inside, physics.piston_pattern(x), 0.0)


def _ref_blocked(pb: EchoProblem, a: np.ndarray, b: np.ndarray, skip_lo: np.ndarray | int = -1,
                 skip_hi: np.ndarray | int = -1, skip_circle: np.ndarray | int = -1,
                 ) -> np.ndarray:
    """[n] whether legs a→b [n, 2] are blocked (kernels/common.h ``leg_blocked``)."""
    n = len(a)
    skip_lo = np.broadcast_to(skip_lo, (n,))[:, None]
    skip_hi = np.broadcast_to(skip_hi, (n,))[:, None]
    skip_circle = np.broadcast_to(skip_circle, (n,))[:, None]
    eps = OCCLUSION_EPS_M
    d = b - a
    len2 = dot(d, d)
    length = np.sqrt(len2)
    blocked = np.zeros(n, dtype=bool)
    occ = pb.occluders
    if len(occ):
        q = occ[None, :, :2]
        e = occ[None, :, 2:] - q
        den = cross(d[:, None], e)
        w = q - a[:, None]
        t = cross(w, e) / den
        u = cross(w, d[:, None]) / den
        i = np.arange(len(occ))[None, :]
        ln = length[:, None]
        hit = ((den != 0) & ~((i >= skip_lo) & (i <= skip_hi)) & (u >= 0) & (u <= 1)
               & (t * ln > eps) & ((1.0 - t) * ln > eps))
        blocked |= hit.any(axis=1)
    if len(pb.circles):
        t_lo = eps / length
        t_hi = 1.0 - t_lo
        w = pb.circles[None, :, :2] - a[:, None]
        t = np.clip(dot(w, d[:, None]) / len2[:, None], t_lo[:, None], t_hi[:, None])
        gap = w - t[..., None] * d[:, None]
        r = pb.circles[None, :, 2]
        i = np.arange(len(pb.circles))[None, :]
        hit = (dot(gap, gap) < r * r) & (i != skip_circle) & (length > 2.0 * eps)[:, None]
        blocked |= hit.any(axis=1)
    return blocked


#: One leg of the candidates of :func:`_unblock`: endpoints ``a``, ``b`` [n, 2], a mask (or
#: True) of the candidates that have it, and keyword arguments for :func:`_ref_blocked`.
Leg = tuple[np.ndarray, np.ndarray, "np.ndarray | bool", dict[str, np.ndarray]]


def _unblock(pb: EchoProblem, amp: np.ndarray,
             legs: Callable[[tuple[np.ndarray, ...]], list[Leg]]) -> None:
    """Zero ``amp`` [P, W] in place where a leg of a candidate (amp > 0) is blocked.

    ``legs(index)`` gives, for the candidates ``index`` (a tuple of arrays), a list of
    ``(a, b, active, skip)`` legs: endpoints [n, 2], a mask of the candidates that have this
    leg, and keyword arguments for :func:`_ref_blocked`.
    """
    index = np.nonzero(amp > 0)
    if len(index[0]) == 0:
        return
    blocked = np.zeros(len(index[0]), dtype=bool)
    for a, b, active, skip in legs(index):
        sel = np.flatnonzero(active & ~blocked)
        if len(sel):
            kw = {k: (v[sel] if np.ndim(v) else v) for k, v in skip.items()}
            blocked[sel] = _ref_blocked(pb, a[sel], b[sel], **kw)
    amp[tuple(ix[blocked] for ix in index)] = 0.0


def _ref_mirror(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Specular and multi-bounce paths by the image method (kernel ``mirror_paths``)."""
    seq = pb.sequences
    order = pb.sequence_order
    m, kmax = len(seq), seq.shape[1]
    w = np.maximum(seq, 0)
    q = pb.walls[w][..., :2]  # [M, K, 2]
    e = pb.walls[w][..., 2:] - q
    nrm = pb.normals[w]
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    img = _mirror_images(T, seq, q, nrm, (len(pr), m, 2))
    valid, pts = _back_trace(T, R, img, order, q, e, nrm)
    valid &= _mirror_legs_ok(pb, pts, order, w, q, nrm)
    path = norm(R - img[kmax])
    last = pts[:, np.arange(m), order]
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], pts[:, :, 1] - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], last - R)
    amp = np.where(valid, amp, 0.0) * pb.rho ** order
    amp = amp * physics.absorption_factor(path, pb.absorption_db_per_m)

    def legs(ix):
        leg_pts = pts[ix]  # [n, K + 2, 2]
        k = order[ix[1]]
        return [(leg_pts[:, j], leg_pts[:, j + 1], j <= k, {}) for j in range(kmax + 1)]

    _unblock(pb, amp, legs)
    return path / pb.c, amp, last


def _mirror_images(T: np.ndarray, seq: np.ndarray, q: np.ndarray, nrm: np.ndarray,
                   shape: tuple[int, int, int]) -> list[np.ndarray]:
    """The images I0 = T, Ij = Ij−1 mirrored across wall j of each sequence (walls at points
    ``q`` with unit normals ``nrm``; unchanged past the sequence's end), each ``shape``
    [pairs, sequences, 2]."""
    img = [np.broadcast_to(T, shape)]
    for j in range(seq.shape[1]):
        h = dot(img[j] - q[:, j], nrm[:, j])
        mirrored = img[j] - (2.0 * h)[..., None] * nrm[:, j]
        img.append(np.where((seq[:, j] >= 0)[:, None], mirrored, img[j]))
    return img


def _back_trace(T: np.ndarray, R: np.ndarray, img: list[np.ndarray], order: np.ndarray,
                q: np.ndarray, e: np.ndarray, nrm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trace back from R towards each image: ``(valid [P, M], pts [P, M, K + 2, 2])``, the
    path T, reflection points j = 1 … order, then R; valid where every crossing lies
    strictly between its two points and on its wall (``q`` + [0, 1]·``e``)."""
    n_pairs, m = img[0].shape[:2]
    kmax = len(img) - 1
    valid = np.ones((n_pairs, m), dtype=bool)
    pts = np.empty((n_pairs, m, kmax + 2, 2))
    pts[:, :, 0] = T
    pts[:, :, 1:] = R[:, :, None, :]
    x = np.broadcast_to(R, (n_pairs, m, 2))
    for j in range(kmax, 0, -1):
        active = (order >= j)[None, :]
        qj, ej, nj = q[:, j - 1], e[:, j - 1], nrm[:, j - 1]
        hx = dot(x - qj, nj)
        hi = dot(img[j] - qj, nj)
        crosses = ((hx > 0) & (hi < 0)) | ((hx < 0) & (hi > 0))
        t = hx / (hx - hi)
        p = x + t[..., None] * (img[j] - x)
        u = dot(p - qj, ej) / dot(ej, ej)
        valid &= ~active | (crosses & (u >= 0) & (u <= 1))
        x = np.where(active[..., None], p, x)
        pts[:, :, j] = x
    return valid, pts


def _mirror_legs_ok(pb: EchoProblem, pts: np.ndarray, order: np.ndarray, w: np.ndarray,
                    q: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    """[P, M] whether every bounce has its incoming and outgoing points strictly on the
    wall's front (two-sided walls: on one side) and every leg is longer than
    :data:`OCCLUSION_EPS_M`."""
    kmax = pts.shape[2] - 2
    valid = np.ones(pts.shape[:2], dtype=bool)
    for j in range(1, kmax + 1):
        active = (order >= j)[None, :]
        h_in = dot(pts[:, :, j - 1] - q[:, j - 1], nrm[:, j - 1])
        h_out = dot(pts[:, :, j + 1] - q[:, j - 1], nrm[:, j - 1])
        front = (h_in > 0) & (h_out > 0)
        back = (h_in < 0) & (h_out < 0)
        ok = np.where(pb.two_sided[w[:, j - 1]], front | back, front)
        valid &= ~active | ok
    for j in range(kmax + 1):
        longer = norm(pts[:, :, j + 1] - pts[:, :, j]) > OCCLUSION_EPS_M
        valid &= ~(order >= j)[None, :] | longer
    return valid


def _ref_mirror_at(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """x mirrored across the line through the origin with unit normal n."""
    return x - (2.0 * dot(x, n))[..., None] * n


def _ref_vertex(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Double bounce through the vertex of a concave corner (kernel ``vertex_paths``)."""
    V = pb.corners[None, :, :2]
    na, nb = pb.corners[None, :, 2:4], pb.corners[None, :, 4:6]
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    t, r = T - V, R - V
    valid = (dot(t, na) > 0) & (dot(t, nb) > 0) & (dot(r, na) > 0) & (dot(r, nb) > 0)
    d1, d2 = norm(t), norm(r)
    valid &= (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)

    def on_return_ray(image):
        return ((dot(r, image) < 0)
                & (np.abs(cross(r, image)) <= OCCLUSION_EPS_M * norm(image)))

    valid &= (on_return_ray(_ref_mirror_at(_ref_mirror_at(t, na), nb))
              | on_return_ray(_ref_mirror_at(_ref_mirror_at(t, nb), na)))
    path = d1 + d2
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], V - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], V - R)
    amp = np.where(valid, amp, 0.0) * pb.rho**2
    amp = amp * physics.absorption_factor(path, pb.absorption_db_per_m)
    vb_ = np.broadcast_to(V, (*amp.shape, 2))
    tb = np.broadcast_to(T, vb_.shape)
    rb = np.broadcast_to(R, vb_.shape)
    _unblock(pb, amp, lambda ix: [(tb[ix], vb_[ix], True, {}), (vb_[ix], rb[ix], True, {})])
    return path / pb.c, amp, vb_


def _ref_in_solid_cone(x: np.ndarray, v: np.ndarray, va: np.ndarray, vb: np.ndarray):
    """Whether x is strictly inside the convex angle between va and vb at v (kernel
    ``in_solid_cone``)."""
    cab = cross(va, vb)
    w = x - v
    alpha = cross(w, vb) / cab
    beta = cross(va, w) / cab
    return (cab != 0) & (alpha > 0) & (beta > 0)


def _ref_edge(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Diffraction at convex edges (kernel ``edge_paths``): times of flight, amplitudes
    (|G| of physics.edge_diffraction), vertices and carrier phases (arg G)."""
    V = pb.diffractors[None, :, :2]
    va, vb = pb.diffractors[None, :, 2:4], pb.diffractors[None, :, 4:6]
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    valid = ~_ref_in_solid_cone(T, V, va, vb) & ~_ref_in_solid_cone(R, V, va, vb)
    d1 = norm(V - T)
    d2 = norm(R - V)
    valid &= (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)
    path = d1 + d2
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], V - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], V - R)
    amp = np.where(valid, amp, 0.0)
    if pb.edge_utd:
        phi_t, n = physics.wedge_angles(T, V, va, vb)
        phi_r, _ = physics.wedge_angles(R, V, va, vb)
        g = physics.edge_diffraction(d1, d2, phi_t, phi_r, n, pb.wavenumber,
                                     pb.edge_coefficient, pb.rho)
        gain, phase = np.abs(g), np.angle(g)
    else:
        gain = physics.edge_gain_estimate(d1, d2, pb.wavenumber, pb.edge_coefficient)
        phase = np.zeros_like(gain)
    amp = amp * gain
    amp = amp * physics.absorption_factor(path, pb.absorption_db_per_m)
    amp = np.where(valid, amp, 0.0)
    vb_ = np.broadcast_to(V, (*amp.shape, 2))
    tb = np.broadcast_to(T, (*amp.shape, 2))
    rb = np.broadcast_to(R, (*amp.shape, 2))
    _unblock(pb, amp, lambda ix: [(tb[ix], vb_[ix], True, {}), (vb_[ix], rb[ix], True, {})])
    return path / pb.c, amp, vb_, np.where(amp > 0, phase, 0.0)


def _circle_residual(a, b, r, n):
    """g = cross(n, û_T + û_R) at the circle point r·n (kernel ``circle_residual``)."""
    ut = a - r[..., None] * n
    ur = b - r[..., None] * n
    return cross(n, ut / norm(ut)[..., None] + ur / norm(ur)[..., None])


def _ref_circle(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Specular points on cylinders by bisection on the shorter arc (kernel ``circle_paths``)."""
    C = pb.circles[None, :, :2]
    r = np.broadcast_to(pb.circles[None, :, 2], (len(pr), len(pb.circles)))
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    a, b = T - C, R - C
    la, lb = norm(a), norm(b)
    valid = (la > r) & (lb > r)
    ah, bh = a / la[..., None], b / lb[..., None]
    m = ah + bh
    lm = norm(m)
    valid &= lm > MIN_BISECTOR
    mh = m / lm[..., None]
    mp = np.stack([-mh[..., 1], mh[..., 0]], axis=-1)
    side = np.where(cross(ah, bh) < 0, -1.0, 1.0)
    half = np.arctan2(norm(ah - bh), lm)
    lo, hi = -half, half.copy()
    g_lo = _circle_residual(a, b, r, ah)
    hi = np.where(g_lo == 0, lo, hi)

    def normal(delta):
        return np.cos(delta)[..., None] * mh + (side * np.sin(delta))[..., None] * mp

    for _ in range(BISECT_ITERATIONS["float64"]):
        mid = 0.5 * (lo + hi)
        g = _circle_residual(a, b, r, normal(mid))
        go_up = (g != 0) & ((g < 0) == (g_lo < 0))
        lo = np.where(go_up, mid, lo)
        hi = np.where(go_up, hi, mid)
    n = normal(0.5 * (lo + hi))
    P = r[..., None] * n
    vt, vr = a - P, b - P
    d1, d2 = norm(vt), norm(vr)
    cos_t = dot(n, vt) / d1
    cos_r = dot(n, vr) / d2
    valid &= (cos_t > 0) & (cos_r > 0) & (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)
    path = d1 + d2
    Pw = C + P
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], Pw - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], Pw - R)
    amp = np.where(valid, amp, 0.0)
    gain = physics.curved_gain(d1, d2, pb.curvature / r, np.where(valid, cos_t, 1.0))
    amp = amp * pb.rho * gain * physics.absorption_factor(path, pb.absorption_db_per_m)
    amp = np.where(valid, amp, 0.0)
    circle = np.broadcast_to(np.arange(len(pb.circles))[None, :], amp.shape)
    tb = np.broadcast_to(T, Pw.shape)
    rb = np.broadcast_to(R, Pw.shape)
    _unblock(pb, amp, lambda ix: [(tb[ix], Pw[ix], True, {"skip_circle": circle[ix]}),
                                  (Pw[ix], rb[ix], True, {"skip_circle": circle[ix]})])
    return path / pb.c, amp, Pw


def _curve_residual(cv, s, T, R):
    """f(s) = dot(P'(s), û_T + û_R), the derivative of −(path length) (kernel
    ``curve_residual``)."""
    p = curve_point(cv, s)
    d1, _ = curve_derivatives(cv, s)
    ut, ur = T - p, R - p
    return dot(d1, ut / norm(ut)[..., None] + ur / norm(ur)[..., None])


def _ref_curve(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Specular points on sinusoids, one bisection per sampling interval (kernel
    ``curve_paths``)."""
    n_pairs, n_int = len(pr), len(pb.interval_s)
    tof = np.zeros((n_pairs, n_int))
    amp = np.zeros((n_pairs, n_int))
    point = np.zeros((n_pairs, n_int, 2))
    cv_all = pb.curves[pb.interval_curve]
    T_all = pb.positions[pr[:, 0]][:, None, :]
    R_all = pb.positions[pr[:, 1]][:, None, :]
    s0, s1 = pb.interval_s[None, :, 0], pb.interval_s[None, :, 1]
    f0 = _curve_residual(cv_all[None], s0, T_all, R_all)
    f1 = _curve_residual(cv_all[None], s1, T_all, R_all)
    bracket = ((f0 == 0) | ((f1 != 0) & ((f0 < 0) != (f1 < 0)))
               | (pb.interval_last[None, :] & (f1 == 0)))
    p_idx, i_idx = np.nonzero(bracket)
    if len(p_idx) == 0:
        return tof, amp, point
    cv = cv_all[i_idx]
    T = pb.positions[pr[p_idx, 0]]
    R = pb.positions[pr[p_idx, 1]]
    f0 = f0[p_idx, i_idx]
    f1 = f1[p_idx, i_idx]
    lo, hi = pb.interval_s[i_idx, 0], pb.interval_s[i_idx, 1]
    hi = np.where(f0 == 0, lo, hi)
    lo = np.where((f0 != 0) & (f1 == 0), hi, lo)
    for _ in range(BISECT_ITERATIONS["float64"]):
        mid = 0.5 * (lo + hi)
        f = _curve_residual(cv, mid, T, R)
        go_up = (f != 0) & ((f < 0) == (f0 < 0))
        lo = np.where(go_up, mid, lo)
        hi = np.where(go_up, hi, mid)
    s = 0.5 * (lo + hi)
    P = curve_point(cv, s)
    d1v, d2v = curve_derivatives(cv, s)
    vt, vr = T - P, R - P
    side_t, side_r = cross(d1v, vt), cross(d1v, vr)
    valid = ((side_t > 0) & (side_r > 0)) | ((side_t < 0) & (side_r < 0))
    d1, d2 = norm(vt), norm(vr)
    valid &= (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)
    path = d1 + d2
    a = pb.amplitude * _ref_beam(pb, pb.axes[pr[p_idx, 0]], P - T)
    a = a * _ref_beam(pb, pb.axes[pr[p_idx, 1]], P - R)
    a = np.where(valid, a, 0.0)
    speed = norm(d1v)
    curvature = cross(d1v, d2v) / (speed * speed * speed)
    kappa = np.where(side_t > 0, -curvature, curvature)
    cos_i = np.abs(cross(d1v, vt)) / (speed * d1)
    gain = physics.curved_gain(d1, d2, pb.curvature * kappa, np.where(valid, cos_i, 1.0))
    a = a * pb.rho * gain * physics.absorption_factor(path, pb.absorption_db_per_m)
    a = np.where(valid, a, 0.0)[None, :]
    skip = pb.interval_skip[i_idx]
    _unblock(pb, a, lambda ix: [
        (T[ix[1]], P[ix[1]], True, {"skip_lo": skip[ix[1], 0], "skip_hi": skip[ix[1], 1]}),
        (P[ix[1]], R[ix[1]], True, {"skip_lo": skip[ix[1], 0], "skip_hi": skip[ix[1], 1]})])
    tof[p_idx, i_idx] = path / pb.c
    amp[p_idx, i_idx] = a[0]
    point[p_idx, i_idx] = P
    return tof, amp, point
