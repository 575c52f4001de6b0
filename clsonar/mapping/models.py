"""Reflector models of one viewpoint's echoes (``mapping.mode = "reflectors"``): the path
length each predicts for a transmitter→receiver pair, its reflection point, and a
least-squares fit of its parameters to detected paths. NumPy float64 throughout.

After Kleeman & Kuc (1995, "Mobile robot sonar for target localization and
classification", IJRR 14(4)): a *plane* reflects as a mirror (the path is the distance from
T to R's mirror image), an *edge* or a thin post as a point (the path goes through the
point), a right-angled *corner* as a retro-reflector (its double bounce is a point
reflection through the vertex V: the path is ``|T + R − 2V|``). With T ≠ R pairs the three
predict different times of flight, so a family of pairs tells which reflector it saw.

**Curve model** (:func:`curve_paths`), parameters ``(φ, d, ψ)`` relative to a reference
point X0 (the middle of the array): the surface's normal n = (cos φ, sin φ) points away
from the transducers, its apex F = X0 + A·n with A = d − n·X0 (d = n·F), and ψ is the
curvature of the ranges seen from X0: the circle of centre C = X0 + n/ψ and signed radius
ρ = 1/ψ − A through F. ψ = 0 is a plane (exact mirror path), ψ = 1/A a point (ρ = 0: an
edge, a post), 0 < ψ < 1/A a convex cylinder, ψ > 1/A or ψ < 0 a concave one. The ranges
of T = R echoes near X0 are A + x²·ψ/2 along the array, so ψ is what the data measure, and
planes, cylinders and points are one family of which the fit picks the member.

**Corner model** (:func:`corner_paths`), parameters V (and β): ``|T + R − 2V|``, the double
bounce of a right-angled corner (the two reflections make a rotation by 180° about V); for
walls meeting at γ = 90° − β/2 the image sources turn R's image by 2γ = π − β instead,
``|T − V + Rot(−β)(R − V)|``, turned by −β instead on the pair's other side (a pair and
its reciprocal hear one path: :func:`corner_paths`); the beams hold its legs, towards the
images of :func:`corner_images`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..numerics import lstsq, median

#: Below this |ψ| (1/m) the curve model is the plane itself (a circle of radius 10⁶ m
#: leaves its tangent by 0.5 µm over 1 m).
PSI_PLANE = 1e-6

#: Newton steps refining the specular point on a circle (from the bisector's point, whose
#: path is already right to second order).
SPECULAR_STEPS = 2


def dot2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a·b`` over the last axis of 2-vectors, written out (no BLAS: the same bits
    whatever the threads, as a Dask worker's run must give)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def apart(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``|X − Y|`` over the last axis of 2-vectors (``np.hypot``), broadcast."""
    d = X - Y
    return np.hypot(d[..., 0], d[..., 1])


def gram(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``Jᵀ·r`` (r a vector or a matrix) as NumPy sums, not BLAS: the same bits on every
    run, however many threads the BLAS would use."""
    if r.ndim == 1:
        return np.sum(J * r[:, None], axis=0)
    return np.sum(J[:, :, None] * r[:, None, :], axis=0)


def _normal(phi: float) -> np.ndarray:
    return np.array([math.cos(phi), math.sin(phi)])


def plane_points(phi: float, d: float, T: np.ndarray, R: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(path [n], q [n, 2])`` for the plane {p: n·p = d}, transducers on the side
    n·p < d: the mirror path sqrt(4·h_T·h_R + |T − R|²) (h the distances to the plane) and
    the reflection point, where the segment from T to R's mirror image meets the plane."""
    n = _normal(phi)
    hT, hR = d - dot2(T, n), d - dot2(R, n)
    path = np.sqrt(np.maximum(4.0 * hT * hR + np.sum((T - R) ** 2, axis=-1), 0.0))
    mirror = R + 2.0 * hR[:, None] * n
    share = hT / np.where(hT + hR != 0, hT + hR, 1.0)
    return path, T + share[:, None] * (mirror - T)


def circles_meet(T: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """[2, 2] where the circles (``T[0]``, ``rho[0]``) and (``T[1]``, ``rho[1]``) cross
    (where they do not meet, the point between them on the line of centres, twice)."""
    d = T[1] - T[0]
    dist = max(float(np.hypot(*d)), 1e-12)
    along = (rho[0] ** 2 - rho[1] ** 2 + dist**2) / (2 * dist)
    across = math.sqrt(max(float(rho[0] ** 2 - along**2), 0.0))
    u = d / dist
    return T[0] + along * u + np.array([across, -across])[:, None] * np.array([-u[1], u[0]])


def lines_cross(p: np.ndarray, u: np.ndarray, q: np.ndarray, v: np.ndarray,
                least_rad: float) -> np.ndarray | None:
    """Where the line through ``p`` along the unit ``u`` crosses the one through ``q``
    along the unit ``v`` (None where they cross at under ``least_rad`` radians)."""
    across = u[0] * v[1] - u[1] * v[0]
    if abs(across) < math.sin(least_rad):
        return None
    d = q - p
    return p + (d[0] * v[1] - d[1] * v[0]) / across * u


def circle_points(centre: np.ndarray, rho: float, sign: float, T: np.ndarray,
                  R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(path [n], q [n, 2])`` for the circle of ``centre`` and signed radius ``rho``
    (> 0 convex towards the transducers, < 0 concave): the specular point q, where the path
    |T − q| + |q − R| is stationary on the circle, found from the point on the bisector of
    the directions to T and R (``sign`` = sign of ψ: which side of the centre faces the
    transducers) by :data:`SPECULAR_STEPS` Newton steps on its angle."""
    cx, cy = float(centre[0]), float(centre[1])
    px = np.stack([T[:, 0], R[:, 0]])  # [2, n]: T's and R's rows, one per line
    py = np.stack([T[:, 1], R[:, 1]])
    ax, ay = sign * (cx - px), sign * (cy - py)
    la = np.maximum(np.hypot(ax, ay), 1e-300)
    ux, uy = ax / la, ay / la
    alpha = np.arctan2(uy[0] + uy[1], ux[0] + ux[1])
    for _ in range(SPECULAR_STEPS):
        c, s = np.cos(alpha), np.sin(alpha)  # [n], each used for both lines
        dx, dy = (cx - rho * c) - px, (cy - rho * s) - py  # q − T, q − R
        lu = np.maximum(np.hypot(dx, dy), 1e-300)
        proj = rho * (dx * s - dy * c) / lu  # (q − X)·dq/dα / |q − X|
        curv = (rho * rho - proj * proj + rho * (dx * c + dy * s)) / lu
        grad, total = proj[0] + proj[1], curv[0] + curv[1]
        alpha = alpha - np.where(total != 0, grad / np.where(total != 0, total, 1.0), 0.0)
    qx, qy = cx - rho * np.cos(alpha), cy - rho * np.sin(alpha)
    path = np.hypot(T[:, 0] - qx, T[:, 1] - qy) + np.hypot(R[:, 0] - qx, R[:, 1] - qy)
    return path, np.stack([qx, qy], axis=-1)


def project_paths(params: np.ndarray, x0: np.ndarray, T: np.ndarray, R: np.ndarray,
                  q: np.ndarray) -> np.ndarray:
    """The path T → q′ → R through the points ``q`` moved onto the curve model
    ``params``'s line or circle (along its normal): the specular path is stationary along
    the surface, so near the specular points this has the model's path and its first
    derivatives (the Jacobian without the Newton steps)."""
    phi, d, psi = (float(v) for v in params)
    if abs(psi) < PSI_PLANE:
        n = _normal(phi)
        moved = q + (d - dot2(q, n))[:, None] * n
    else:
        centre, rho, _ = curve_geometry(np.array([phi, d, psi]), x0)
        rel = math.copysign(1.0, psi) * (centre - q)  # e(α), as circle_points orients it
        moved = centre - rho * rel / np.maximum(np.hypot(*rel.T), 1e-300)[:, None]
    return np.hypot(*(T - moved).T) + np.hypot(*(R - moved).T)


def curve_geometry(params: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, float, float]:
    """``(centre, rho, A)`` of the curve model ``(φ, d, ψ)`` (centre inf for a plane)."""
    phi, d, psi = params
    n = _normal(phi)
    A = d - float(n[0] * x0[0] + n[1] * x0[1])
    if abs(psi) < PSI_PLANE:
        return np.array([np.inf, np.inf]), math.inf, A
    return x0 + n / psi, 1.0 / psi - A, A


def curve_paths(params: np.ndarray, x0: np.ndarray, T: np.ndarray, R: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(path [n], q [n, 2])`` the curve model ``(φ, d, ψ)`` (module docstring) predicts
    for the pairs (T, R): the plane's mirror path for |ψ| < :data:`PSI_PLANE`, else the
    circle's specular path (:func:`circle_points`)."""
    phi, d, psi = (float(v) for v in params)
    if abs(psi) < PSI_PLANE:
        return plane_points(phi, d, T, R)
    centre, rho, _ = curve_geometry(np.array([phi, d, psi]), x0)
    return circle_points(centre, rho, math.copysign(1.0, psi), T, R)


def point_paths(params: np.ndarray, T: np.ndarray, R: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(path [n], q [n, 2])`` of a point reflector F = ``params`` (an edge, a thin post):
    |T − F| + |F − R|, and F itself."""
    f = np.asarray(params, dtype=np.float64)
    return np.hypot(*(T - f).T) + np.hypot(*(R - f).T), _repeated(f, len(T))


def _repeated(v: np.ndarray, n: int) -> np.ndarray:
    """[n, 2]: the point ``v`` in every row (a point's or a corner's reflection point)."""
    out = np.empty((n, 2))
    out[:] = v[:2]
    return out


def corner_paths(params: np.ndarray, T: np.ndarray, R: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(path [n], q [n, 2])`` of a corner at V = ``params[:2]``: the double bounce's
    length and V itself. By image sources, two reflections in walls through V that meet
    at an angle γ turn R's image about V by 2γ (the reflections across lines at angles
    θa, θb compose to a rotation by 2(θa − θb)), so the path is |T − V − Rot(2γ)(R − V)|;
    with 2γ = π − β (β = ``params[2]``, 0 when absent: a right angle, twice the corner's
    departure from one; its sign the order in which the walls are met) that is
    |T − V + Rot(−β)(R − V)|, the point reflection |T + R − 2V| for β = 0. The order is
    the pair's side: β where R lies clockwise of V as seen from T, −β otherwise
    (:func:`_sides`), so a pair and its reciprocal, which hear one path (reciprocity: T →
    a → b → R is R → b → a → T backwards), have one prediction; the other order, where a
    pair hears it too, is a second family."""
    v = np.asarray(params[:2], dtype=np.float64)
    beta = float(params[2]) if len(params) > 2 else 0.0
    # turned by 0, R − V is itself to the bit (cos 0 = 1, sin 0 = 0)
    turned = _rotate(R - v, -beta * _sides(v, T, R)) if beta != 0.0 else R - v
    return np.hypot(*(T - v + turned).T), _repeated(v, len(T))


def corner_images(params: np.ndarray, T: np.ndarray, R: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``(R*, T*)``: the double bounce of :func:`corner_paths` unfolded — R's image in the
    two walls, V − Rot(−β)(R − V), which T's first leg points at, and T's, V − Rot(β)(T −
    V), which R's last leg comes from (2V − R and 2V − T for a right angle): the
    directions the two beams must hold, which for T ≠ R or a turned corner are not the
    vertex's (|T − R*| = |R − T*| is the path)."""
    v = np.asarray(params[:2], dtype=np.float64)
    beta = float(params[2]) if len(params) > 2 else 0.0
    turn = beta * _sides(v, T, R)
    return v - _rotate(R - v, -turn), v - _rotate(T - v, turn)


def _sides(v: np.ndarray, T: np.ndarray, R: np.ndarray) -> np.ndarray:
    """+1 where R lies clockwise of V as seen from T (or on the line T–V), −1 otherwise:
    swapping T and R swaps the sign."""
    a, b = v - T, R - T
    return np.where(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] > 0, -1.0, 1.0)


def _rotate(d: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """``d`` [n, 2] turned by ``angle`` (radians, anticlockwise; one or one per row)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=-1)


#: ``params → (path, q)`` of one model for fixed pairs.
PathModel = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Fit:
    """A least-squares fit: the parameters, the RMS path residual over the rows used and
    whether it converged."""

    params: np.ndarray
    rms: float
    converged: bool


def _jacobian(model: PathModel, p: np.ndarray, steps: np.ndarray, free: np.ndarray, rows: int,
              linear: LinearModel | None = None, q: np.ndarray | None = None,
              exact: np.ndarray | None = None) -> np.ndarray:
    """Central differences of ``model``'s paths, or of ``linear(p, q)`` (the model near the
    reflection points ``q``) for the parameters not marked ``exact``: the columns of the
    ``free`` parameters (a held one's column would be thrown away)."""
    columns = np.flatnonzero(free).tolist()
    J = np.empty((rows, len(columns)), order="F")  # gram's sums add down each column
    for j, k in enumerate(columns):
        h = steps[k]
        dp = np.zeros_like(p)
        dp[k] = h
        if linear is None or q is None or (exact is not None and exact[k]):
            J[:, j] = (model(p + dp)[0] - model(p - dp)[0]) / (2 * h)
        else:
            J[:, j] = (linear(p + dp, q) - linear(p - dp, q)) / (2 * h)
    return J



#: Levenberg–Marquardt stops when a step changes no parameter by more than this (metres,
#: radians, 1/m: far below what a map can show) or the cost by less than this share, or
#: when the RMS path residual is under :data:`STOP_RMS` (what a detection is good to).
STOP_STEP = 1e-8
STOP_COST_SHARE = 1e-6
STOP_RMS = 5e-6

#: ``(params, reflection points at params) → paths``: a cheaper model for the Jacobian.
LinearModel = Callable[[np.ndarray, np.ndarray], np.ndarray]


def least_squares(model: PathModel, paths: np.ndarray, start: np.ndarray,
                  steps: np.ndarray, iterations: int = 30, fixed: np.ndarray | None = None,
                  linear: LinearModel | None = None, exact: np.ndarray | None = None
                  ) -> Fit:
    """Levenberg–Marquardt on the path residuals ``model(p)[0] − paths`` from ``start``
    (central-difference Jacobian with ``steps``, of ``linear(p, q)`` at the reflection
    points q of the current p when given, but for the parameters marked ``exact``);
    parameters where ``fixed`` is True stay."""
    p = np.asarray(start, dtype=np.float64).copy()
    free = np.ones(len(p), bool) if fixed is None else ~np.asarray(fixed)
    pred, q = model(p)
    r = pred - paths
    cost = float(np.sum(r * r))
    lam = 1e-3
    converged = False
    fresh = True
    for _ in range(iterations):
        if fresh:  # the Jacobian changes only when p does
            # laid out as the whole Jacobian's free columns were (Fortran order): gram's
            # sums then add in the same order, to the bit
            J = _jacobian(model, p, steps, free, len(paths), linear, q, exact)
            g, H = gram(J, r), gram(J, J)
            gain = float(np.sum(g * _damped_step(H, g, 0.0)))  # a Gauss–Newton step's gain
            if gain <= STOP_COST_SHARE * cost or cost <= len(paths) * STOP_RMS**2:
                converged = True
                break
        step = _damped_step(H, g, lam)
        trial = p.copy()
        trial[free] -= step
        pred_new, q_new = model(trial)
        r_new = pred_new - paths
        new_cost = float(np.sum(r_new * r_new))
        fresh = bool(np.isfinite(new_cost) and new_cost <= cost)
        if fresh:
            small = cost - new_cost <= STOP_COST_SHARE * cost and lam <= 1e-3
            p, r, q, cost, lam = trial, r_new, q_new, new_cost, max(lam / 10, 1e-12)
            if small or (np.all(np.abs(step) <= STOP_STEP) and lam <= 1e-3):
                converged = True
                break
        else:
            lam *= 10
            if lam > 1e6:
                converged = True
                break
    return Fit(p, math.sqrt(cost / max(len(paths), 1)), converged)


def _damped_step(H: np.ndarray, g: np.ndarray, lam: float) -> np.ndarray:
    """The Levenberg–Marquardt step (H + λ·diag H)⁻¹·g (Gauss–Newton for λ = 0)."""
    d = H.diagonal()
    A = H + 0.0  # off the diagonal H + λ·0, as the diagonal matrix's zeros add
    A.flat[::len(d) + 1] = d + lam * np.maximum(d, 1e-12)
    try:
        return np.linalg.solve(A, g)
    except np.linalg.LinAlgError:
        return lstsq(A, g)


#: Finite-difference steps of the curve model's (φ, d, ψ) and of a point's or corner's
#: position (ψ's straddles the plane's threshold :data:`PSI_PLANE` with circles of 10⁴ m).
CURVE_STEPS = np.array([1e-7, 1e-7, 1e-4])
CORNER_STEPS = np.array([1e-7, 1e-7])
#: ... and of a corner's (V, β).
TURN_STEPS = np.array([1e-7, 1e-7, 1e-7])


#: The curve fit's frame: its origin is X0 rounded to this many metres (0 for arrays
#: within 50 m of the scene's origin), so that d stays within about 70 m of the apex
#: distance A. Far from it φ and d are nearly collinear parameters (turning the line by
#: δφ moves it by |X0|·δφ), and 300 m out the fit stopped millimetres from the surface.
FRAME_M = 100.0


def curve_frame(x0: np.ndarray) -> np.ndarray:
    """The origin O of :func:`fit_curve`'s frame: ``x0`` rounded to :data:`FRAME_M`."""
    return np.round(np.asarray(x0, dtype=np.float64) / FRAME_M) * FRAME_M


def fit_curve(x0: np.ndarray, T: np.ndarray, R: np.ndarray, paths: np.ndarray,
              start: np.ndarray, fix_psi: bool = False) -> Fit:
    """The curve model's least-squares ``(φ, d, ψ)`` from ``start``; ψ held at its start
    value with ``fix_psi`` (ψ = 0: the best plane). Fitted in the frame of
    :func:`curve_frame` (d′ = d − n·O, the same φ and ψ), returned in the scene's."""
    origin = curve_frame(x0)
    if not origin.any():
        return _fit_curve(x0, T, R, paths, start, fix_psi)
    local = np.array(start, dtype=np.float64)
    local[1] -= float(dot2(_normal(local[0]), origin))
    fit = _fit_curve(x0 - origin, T - origin, R - origin, paths, local, fix_psi)
    params = fit.params.copy()
    params[1] += float(dot2(_normal(params[0]), origin))
    return Fit(params, fit.rms, fit.converged)


def _fit_curve(x0: np.ndarray, T: np.ndarray, R: np.ndarray, paths: np.ndarray,
               start: np.ndarray, fix_psi: bool) -> Fit:
    def model(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return curve_paths(p, x0, T, R)

    def linear(p: np.ndarray, q: np.ndarray) -> np.ndarray:
        return project_paths(p, x0, T, R, q)

    fixed = np.array([False, False, fix_psi])
    return least_squares(model, paths, start, CURVE_STEPS, fixed=fixed, linear=linear,
                         exact=np.array([False, False, True]))


def fit_corner(T: np.ndarray, R: np.ndarray, paths: np.ndarray, start: np.ndarray,
               turn: bool = True) -> Fit:
    """The corner model's least-squares vertex V and turn β (:func:`corner_paths`) from
    ``start`` (V, or V and β: 0 if not given); β held at its start without ``turn``."""
    p0 = np.zeros(3)
    p0[:min(len(start), 3)] = np.asarray(start, dtype=np.float64)[:3]
    return least_squares(lambda p: corner_paths(p, T, R), paths, p0, TURN_STEPS,
                         fixed=np.array([False, False, not turn]))


def fit_point(T: np.ndarray, R: np.ndarray, paths: np.ndarray, start: np.ndarray) -> Fit:
    """The point model's least-squares position F from ``start``."""
    return least_squares(lambda p: point_paths(p, T, R), paths, start, CORNER_STEPS)


def ellipse_axes(T: np.ndarray, R: np.ndarray, paths: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(a, f, b, u)`` of the loci of ``paths`` with foci T and R (eq. 2.2's ellipses):
    half the major axis, half the foci's distance, half the minor axis, and the unit major
    axis from T to R (x where T = R: a circle)."""
    a = 0.5 * paths
    f = 0.5 * np.hypot(*(R - T).T)
    b = np.sqrt(np.maximum(a * a - f * f, 0.0))
    u = np.where((f > 0)[:, None], (R - T) / np.maximum(2 * f, 1e-300)[:, None], [1.0, 0.0])
    return a, f, b, u


def plane_start(x0: np.ndarray, T: np.ndarray, R: np.ndarray, paths: np.ndarray,
                phis: np.ndarray) -> np.ndarray:
    """A starting ``(φ, d, 0)``: of the normals ``phis`` tried, the one whose tangent lines
    to the loci (each locus' support function, the line a plane of that normal would be)
    agree best; d their median."""
    n = np.stack([np.cos(phis), np.sin(phis)], axis=-1)  # [k, 2]
    centre = 0.5 * (T + R)
    a, _, b, u = ellipse_axes(T, R, paths)
    along = (n[:, None, 0] * u[None, :, 0] + n[:, None, 1] * u[None, :, 1])  # [k, m]
    support = (n[:, None, 0] * centre[None, :, 0] + n[:, None, 1] * centre[None, :, 1]).T \
        + np.sqrt((a[:, None] * along.T) ** 2
                                         + (b[:, None] ** 2) * (1 - along.T**2))
    spread = median(np.abs(support - median(support, axis=0)), axis=0)
    best = int(np.argmin(spread))
    return np.array([phis[best], float(median(support[:, best])), 0.0])


__all__ = ["CORNER_STEPS", "CURVE_STEPS", "FRAME_M", "PSI_PLANE", "SPECULAR_STEPS", "Fit",
           "PathModel", "apart", "circle_points", "circles_meet", "corner_images", "corner_paths",
           "curve_frame", "curve_geometry", "curve_paths", "dot2", "ellipse_axes", "fit_corner",
           "fit_curve",
           "fit_point", "gram", "least_squares", "lines_cross", "plane_points", "plane_start",
           "point_paths",
           "project_paths"]
