"""Pillars from the ranges of a ring scan (:func:`pillar_arcs`): the isolated T = R loci
that no scan envelope holds — a pillar in the middle of a room, seen by one element from
poses too far apart for consecutive loci to touch it together — are fitted by a circle.

A locus of range ρ from T touches a circle (C, R) when |C − T| = ρ + R; three or more loci
from different transducer positions that agree on one circle (to within the pulse's range
resolution) place it, where the middle of each locus' in-beam arc would draw a straight
stub off it by up to ρ·α²/2 (α the angle between the beam's axis and the pillar).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Iterator

import numpy as np

from .. import steps
from ..numerics import lstsq, minimize_bounded, unique
from .models import circles_meet
from .strength import EDGE_SHARE

#: Candidate loci whose middle-of-arc points lie within this of each other are fitted
#: together, metres.
CLUSTER_M = 1.0

#: A fitted circle explains a locus when |C − T| − ρ − R is within this, metres.
PILLAR_TOL_M = 0.003

#: Radii taken for pillars, metres (a point reflector, R → 0, is a corner or an edge).
PILLAR_RADII_M = (0.03, 2.0)

#: Loci a circle needs, from as many different transducer positions.
MIN_PILLAR_LOCI = 3


#: Rows of :func:`_near_rows`' distances taken at once: at most this many distances.
NEAR_AT_ONCE = 1 << 16


def _near_rows(points: np.ndarray, reach: float) -> Iterator[np.ndarray]:
    """For each of ``points`` [n, 2] in turn, the indices of those within ``reach`` of it,
    ``np.flatnonzero(np.hypot(*(points - points[i]).T) <= reach)``: the distances of up to
    64 points' rows at once (at most :data:`NEAR_AT_ONCE` of them), each the very
    subtraction and hypot of the row alone (elementwise: the same bits in any array)."""
    n = len(points)
    rows = max(1, min(64, NEAR_AT_ONCE // max(n, 1)))
    x, y = points[:, 0], points[:, 1]
    for first in range(0, n, rows):
        block = points[first:first + rows]
        within = np.hypot(x - block[:, 0, None], y - block[:, 1, None]) <= reach
        for row in within:
            yield np.flatnonzero(row)


def _clusters(points: np.ndarray) -> list[np.ndarray]:
    """Single-linkage groups (index arrays) of ``points`` within :data:`CLUSTER_M`: point i
    in turn merges every group holding a point within reach of it into its own group
    (``label`` the group of each point; ``mark`` which groups merge, a table by label in
    place of ``np.isin``: the same labels)."""
    label = np.arange(len(points))
    mark = np.zeros(len(points), dtype=bool)
    for i, near in enumerate(_near_rows(points, CLUSTER_M)):
        if i % 64 == 0:
            steps.poll()
        merged = label[near]
        mark[merged] = True
        label[mark[label]] = label[i]
        mark[merged] = False
    order = np.argsort(label, kind="stable")  # each group's indices ascending, by label
    return np.split(order, np.flatnonzero(np.diff(label[order])) + 1) if len(order) else []


def _directions(x: np.ndarray, T: np.ndarray) -> np.ndarray:
    """[k, 2] unit vectors from each of ``T`` to ``x``: the gradient of |x − T_k| in x."""
    d = x - T
    return d / np.maximum(np.hypot(*d.T), 1e-300)[:, None]


class _Lengths:
    """|x − T_k| for a residual, kept with the differences x − T_k for the Jacobian at
    the same x (:func:`_gauss_newton` takes the step's Jacobian where it last evaluated
    the residual, unless a halving moved it): :func:`_directions` of x from them, the same
    arithmetic without computing them again."""

    def __init__(self, T: np.ndarray) -> None:
        self.T = T
        self.x: np.ndarray | None = None
        self.d = self.h = np.zeros(0)

    def __call__(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """[k] or [m, k]: the lengths |v − T_k| (``v`` the point of ``x``, [2] or [m, 2])."""
        self.d = v[..., None, :] - self.T
        self.h = np.hypot(self.d[..., 0], self.d[..., 1])
        self.x = x
        return self.h

    def directions(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        """:func:`_directions` of ``v`` (the point of ``x`` [n]) from T."""
        if x is self.x and self.d.ndim == 2:
            return self.d / np.maximum(self.h, 1e-300)[:, None]
        return _directions(v, self.T)


def fit_circle(T: np.ndarray, rho: np.ndarray, start: np.ndarray, radius: float = 0.1
               ) -> tuple[np.ndarray, float, np.ndarray]:
    """Least-squares circle ``(C, R)`` with |C − T_k| = ρ_k + R (:func:`_gauss_newton`
    from ``start`` and ``radius``), and the residuals: the circle the loci (T_k, ρ_k)
    touch, or with ρ = 0 the geometric fit of a circle through the points T."""
    lengths = _Lengths(T)
    jac = np.empty((len(T), 3))  # the columns [directions, −1], filled in place each step
    jac[:, 2] = -1.0

    def residual(x: np.ndarray) -> np.ndarray:  # x [3] or [m, 3]: [k] or [m, k]
        return lengths(x, x[..., :2]) - rho - x[..., 2, None]

    def jacobian(x: np.ndarray) -> np.ndarray:
        jac[:, :2] = lengths.directions(x, x[:2])
        return jac

    x, r = _gauss_newton(residual, jacobian, np.r_[start, radius])
    return x[:2], float(x[2]), r


def _gauss_newton(residual: Callable[[np.ndarray], np.ndarray],
                  jacobian: Callable[[np.ndarray], np.ndarray], start: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``(x, residual(x))``: least squares by Gauss–Newton from ``start``, each step halved
    until the cost falls (up to 29 times, :func:`_halved`), to a step of :data:`GN_STEP_M`
    (two or three unknowns: a solver's set-up would cost more than the solve, and this
    runs once per seed set). ``residual`` takes one x [n] or several [m, n]. Its sums of
    squares and products are ``ndarray.dot``: one ``cblas_ddot`` on the same arrays, as
    ``@`` is, without the matmul ufunc's set-up (0.3 against 0.7 µs a call; the same bits,
    tests/test_speed_accumulation.py)."""
    x = np.asarray(start, dtype=np.float64)
    r = residual(x)
    cost = r.dot(r)
    for _ in range(GN_ITERATIONS):
        step = _least_squares_step(jacobian(x), r)
        trial = x - step
        r_trial = residual(trial)
        trial_cost = r_trial.dot(r_trial)
        if not trial_cost <= cost:
            halved = _halved(residual, x, step, cost)
            if halved is None:
                break
            step, trial, r_trial = halved
            trial_cost = r_trial.dot(r_trial)
        x, r, cost = trial, r_trial, trial_cost
        if math.sqrt(float(step.dot(step))) <= GN_STEP_M:  # numpy.linalg.norm's own form
            break
    return x, r


#: The halvings of a Gauss–Newton step tried after the whole step (:func:`_halved`).
GN_HALVINGS = 29
_HALVES = 0.5 ** np.arange(1, GN_HALVINGS + 1)[:, None]
_TINY = float(np.finfo(np.float64).tiny)
_EPS = float(np.finfo(np.float64).eps)


def _halved(residual: Callable[[np.ndarray], np.ndarray], x: np.ndarray, step: np.ndarray,
            cost: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(step, x − step, its residual)`` for the first of ``step``/2, ``step``/4, … (up
    to :data:`GN_HALVINGS` times) at which the cost ``r·r`` is at most ``cost``, or None:
    the halvings one after another, their residuals evaluated together (a power of two
    scales exactly, so each trial is the one the halving loop would reach).

    The cost of each is summed by ``r @ r`` (BLAS's order of summation) only where another
    order's sum of the k squares, within (k + 2)·ε of it either way (Higham, *Accuracy
    and Stability of Numerical Algorithms*, §3.1), leaves it in doubt."""
    # two or three numbers: Python's min (with a NaN: the least finite one, or NaN where it
    # comes first; numpy's: NaN) takes the product form only where no finite entry's
    # halvings are subnormal, where both forms give the same bits (NaN stays NaN)
    nonzero = [abs(v) for v in step.tolist() if v != 0]
    if nonzero and min(nonzero) * _HALVES[-1, 0] >= _TINY:
        halvings = step * _HALVES
    else:  # a halving may round (subnormal): one after another, as the loop would
        halvings = np.empty((GN_HALVINGS, len(step)))
        for j in range(GN_HALVINGS):
            halvings[j] = 0.5 * (step if j == 0 else halvings[j - 1])
    trials = x - halvings
    r_trials = residual(trials)
    k = r_trials.shape[1]
    rough = np.einsum("ij,ij->i", r_trials, r_trials)
    for j in np.flatnonzero(~(rough > cost * (1.0 + 4.0 * (k + 2) * _EPS) + 1e-300)).tolist():
        if r_trials[j].dot(r_trials[j]) <= cost:
            return halvings[j], trials[j], r_trials[j]
    return None


def _least_squares_step(jac: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The least-squares solution s of J·s = r: for two unknowns by the normal equations
    (Cramer's rule: a tenth of ``numpy.linalg.lstsq``'s cost, and this runs thousands of
    times a map), by ``lstsq`` (:func:`~clsonar.numerics.lstsq`, NumPy's to the bit) for
    more or where J is (nearly) of rank one."""
    if jac.shape[1] == 2:  # the sums by numpy (BLAS), the rest in floats: the same IEEE
        jx, jy = jac[:, 0], jac[:, 1]
        a, b, c = float(jx.dot(jx)), float(jx.dot(jy)), float(jy.dot(jy))
        det = a * c - b * b
        if det > 1e-10 * a * c:  # J's columns far from parallel: a well-posed 2 × 2 solve
            gx, gy = float(jx.dot(r)), float(jy.dot(r))
            return np.array([(c * gx - b * gy) / det, (a * gy - b * gx) / det])
    return lstsq(jac, r)


#: Gauss–Newton steps of :func:`_gauss_newton`, and the step (metres) at which it stops: a
#: micrometre, three orders below the finest cell a map is drawn on (1e-10 before stop 39:
#: a fit that explains nothing converges linearly, and its last steps cost a floor's point
#: fits a third of their time; the zoo's 672 room and cylinder cases of seeds 0–3 and
#: 60–71 moved by at most 4e-11 m in accuracy, the 46 bundled runs by 1e-12 m).
GN_ITERATIONS = 30
GN_STEP_M = 1e-6


def fit_pillar(T: np.ndarray, rho: np.ndarray, middles: np.ndarray, tol: np.ndarray
               ) -> tuple[np.ndarray, float, np.ndarray] | None:
    """The circle the loci (T_k, ρ_k) touch, started from their middle-of-arc points, fitted
    again without the loci it does not explain (within 27, 9, 3 and then 1 times ``tol``):
    ``(centre, radius, explained)``, or None when fewer than :data:`MIN_PILLAR_LOCI` loci
    from as many positions agree or the radius is not a pillar's."""
    keep = np.ones(len(T), dtype=bool)
    fitted = b""
    for loose in (27.0, 9.0, 3.0, 1.0, 1.0):  # outliers dropped, the bar lowered
        if np.count_nonzero(keep) < MIN_PILLAR_LOCI:
            return None
        if keep.tobytes() != fitted:  # the same loci would give the same circle again
            centre, radius, _ = fit_circle(T[keep], rho[keep], middles[keep].mean(axis=0))
            fitted = keep.tobytes()
        keep = np.abs(np.hypot(*(centre - T).T) - rho - radius) <= loose * tol
    if (_positions(T[keep]) < MIN_PILLAR_LOCI
            or not PILLAR_RADII_M[0] <= radius <= PILLAR_RADII_M[1]
            or _a_point(T[keep], rho[keep], centre, tol[keep])):
        return None
    return centre, radius, keep


def _a_point(T: np.ndarray, rho: np.ndarray, centre: np.ndarray, tol: np.ndarray) -> bool:
    """Whether one point (|V − T_k| = ρ_k: a corner or an edge) explains the loci as well:
    seen over a narrow spread of directions a pillar and a point cannot be told apart, and
    a room's corners are far more common than pillars."""

    _, off = _point_from(T, T, rho, centre)
    return bool(np.all(np.abs(off) <= tol))


def pillar_arc(centre: np.ndarray, radius: float, T: np.ndarray, rho: float, bias: float,
               step: float) -> np.ndarray:
    """The stretch of the circle around the point the locus (T, ρ) touches, as far as the
    locus stays within ``bias`` of it: a point θ round from it is farther from T by about
    R·(ρ + R)·θ²/(2ρ)."""
    u = (T - centre) / np.hypot(*(T - centre))
    half = math.sqrt(2.0 * rho * bias / (radius * (rho + radius)))
    n = max(1, math.ceil(half * radius / step))
    theta = math.atan2(u[1], u[0]) + np.linspace(-half, half, 2 * n + 1)
    return centre + radius * np.stack([np.cos(theta), np.sin(theta)], axis=-1)


#: Each candidate pillar is first fitted to the loci whose middle-of-arc points lie within
#: this of one locus' (a pillar's stubs around it), metres.
SEED_M = 0.5


#: ``seen_through(centre, radius, reach)``: whether some element no farther than ``reach``
#: from the circle had its echo from beyond the circle's point nearest it, inside its beam
#: (it would have heard the circle first, as the loci that touch it did from as far).
SeenThrough = Callable[[np.ndarray, float, float], bool]

#: ``admits(point)``: [k] whether each locus may be drawn as ``point`` (it lies in the
#: locus' beams, and near enough to what the locus drew).
Admits = Callable[[np.ndarray], np.ndarray]


def _plausible(T: np.ndarray, rho: np.ndarray, tol: np.ndarray) -> bool:
    """Whether a circle the loci touch (|C − T|² = (ρ + R)², linear in C, R and
    w = |C|² − R²: one least-squares solve) explains :data:`MIN_PILLAR_LOCI` of them within
    three times their tolerance — the quick test before the least-squares fit."""
    a = np.column_stack([-2.0 * T, -2.0 * rho, np.ones(len(T))])
    x = lstsq(a, rho * rho - np.sum(T * T, axis=1))
    off = np.abs(np.hypot(*(x[:2] - T).T) - rho - x[2])
    return bool(np.count_nonzero(off <= 3.0 * tol) >= MIN_PILLAR_LOCI)


def _seed_sets(middles: np.ndarray, reach: float = SEED_M, whole: bool = True,
               least: int = MIN_PILLAR_LOCI, tried: set[bytes] | None = None
               ) -> Iterator[np.ndarray]:
    """The loci a reflector is first fitted to: the neighbourhood (``reach``) of each
    locus' middle-of-arc point in turn, then (``whole``) all of them (a pillar seen from
    every side has its stubs all round it, farther apart than :data:`SEED_M`), each set
    once (not one of ``tried``) and only with ``least`` loci or more."""
    tried = set() if tried is None else tried
    every = [np.arange(len(middles))] if whole else []
    for near in itertools.chain(_near_rows(middles, reach), every):
        steps.poll()
        if len(near) >= least and near.tobytes() not in tried:
            tried.add(near.tobytes())
            yield near


#: Where no seed set of :func:`_seed_sets` gives a pillar, the neighbourhoods of these
#: reaches are tried in turn (metres), each pillar found from them over-determined (one
#: locus more than :data:`MIN_PILLAR_LOCI`: any three loci touch some circle). A 0.48 m
#: pillar in a room's middle heard once by each of five wall-following poses all round it
#: has its five stubs up to a metre apart, and the loci of another pillar 1.4 m away made
#: the whole cluster's circle implausible (the zoo's unseen seed 131 room-24).
WIDER_SEEDS_M = (2 * SEED_M, 4 * SEED_M)


def _best_pillar(T: np.ndarray, rho: np.ndarray, middles: np.ndarray, tol: np.ndarray,
                 seen_through: SeenThrough) -> tuple[np.ndarray, float, np.ndarray] | None:
    """The pillar that explains the most of the loci: fitted (:func:`fit_pillar`) from each
    of :func:`_seed_sets` (then, where none, from the :data:`WIDER_SEEDS_M` ones), then
    again to every locus it explains (several pillars in one cluster are found one by
    one); none that the scan saw through (``seen_through``: a convex block's faces and
    edges, whose ranges a circle can mimic, stand beside free space other elements see
    into)."""
    tried: set[bytes] = set()
    best = _best_seeded(T, rho, middles, tol, seen_through,
                        _seed_sets(middles, tried=tried), 0)
    for reach in WIDER_SEEDS_M if best is None else ():
        wide = _seed_sets(middles, reach, False, MIN_PILLAR_LOCI + 1, tried)
        best = _best_seeded(T, rho, middles, tol, seen_through, wide, MIN_PILLAR_LOCI + 1)
        if best is not None:
            break
    if best is None:
        return None
    found = fit_pillar(T[best[2]], rho[best[2]], middles[best[2]], tol[best[2]])
    if found is None or seen_through(found[0], found[1], float(rho[best[2]][found[2]].max())):
        return None
    centre, radius, _ = found
    return centre, radius, np.abs(np.hypot(*(centre - T).T) - rho - radius) <= tol


def _best_seeded(T: np.ndarray, rho: np.ndarray, middles: np.ndarray, tol: np.ndarray,
                 seen_through: SeenThrough, seeds: Iterator[np.ndarray], least: int
                 ) -> tuple[np.ndarray, float, np.ndarray] | None:
    """``(centre, radius, explained)`` of the circle fitted from ``seeds`` that explains
    the most loci, at least ``least`` of them (None: none)."""
    best = None
    for near in seeds:
        if len(near) > MIN_PILLAR_LOCI and not _plausible(T[near], rho[near], tol[near]):
            continue
        found = fit_pillar(T[near], rho[near], middles[near], tol[near])
        if found is None or seen_through(found[0], found[1], float(rho[near][found[2]].max())):
            continue
        centre, radius, _ = found
        explained = np.abs(np.hypot(*(centre - T).T) - rho - radius) <= tol
        if explained.sum() >= least and (best is None or explained.sum() > best[2].sum()):
            best = (centre, radius, explained)
            if explained.all():  # no later seed set can explain more
                break
    return best


def _point_residual(v: np.ndarray, T: np.ndarray, R: np.ndarray, a: np.ndarray,
                    kept: tuple[_Lengths, _Lengths] | None = None) -> np.ndarray:
    """[k] how far the point ``v`` lies off each locus, (|v − T_k| + |v − R_k|)/2 − a_k
    ([m, k] for points ``v`` [m, 2]; ``R is T``: |v − T_k| − a_k, the same to the bit);
    ``kept``: the lengths from T and R, kept for the Jacobian (:class:`_Lengths`)."""
    to_t, to_r = kept or (_Lengths(T), _Lengths(R))
    hT = to_t(v, v)
    if R is T:  # 0.5·(h + h) is h: doubling and halving are exact
        return hT - a
    return 0.5 * (hT + to_r(v, v)) - a


def _positions(T: np.ndarray) -> int:
    """How many different transducer positions ``T`` [k, 2] holds (to a micrometre)."""
    return len(unique(np.round(T, 6), axis=0))


def _point_from(T: np.ndarray, R: np.ndarray, a: np.ndarray, start: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares point V on the loci (|V − T_k| + |V − R_k|)/2 = a_k (a corner or an
    edge seen from several positions; T = R: |V − T_k| = ρ_k), and the residuals
    (:func:`_gauss_newton` from ``start``)."""
    if R is not T and T.shape == R.shape and T.tobytes() == R.tobytes():
        R = T  # T = R: each distance computed once
    kept = _Lengths(T), _Lengths(R)
    if R is T:  # 0.5·(d + d) is d
        return _gauss_newton(lambda v: _point_residual(v, T, T, a, kept),
                             lambda v: kept[0].directions(v, v), start)
    return _gauss_newton(lambda v: _point_residual(v, T, R, a, kept),
                         lambda v: 0.5 * (kept[0].directions(v, v) + kept[1].directions(v, v)),
                         start)


class _Fits:
    """:func:`_point_from` of each set of loci and start fitted once: a cluster searched
    again once a reflector took some of its loci (:func:`_one_by_one`) fits most of the
    same seed sets again, the same rows from the same start (the room: 173 of 371 point
    fits). Called as :func:`_point_from`: the first fit's point (a copy: each caller's
    own) and residuals (read only)."""

    def __init__(self) -> None:
        self.done: dict[tuple[bytes, ...], tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, T: np.ndarray, R: np.ndarray, a: np.ndarray, start: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        key = (T.tobytes(), R.tobytes(), a.tobytes(), np.asarray(start, np.float64).tobytes())
        found = self.done.get(key)
        if found is None:
            found = self.done[key] = _point_from(T, R, a, start)
        return found[0].copy(), found[1]


#: ``quiet(normal, explained)``: whether the loci ``explained`` (their indices) were all
#: heard weaker than a plane of that unit normal (from the transducers towards it) would
#: return them.
Quiet = Callable[[np.ndarray, np.ndarray], bool]


#: A point found after the cluster's best was refused explains at least this share of as
#: many loci as that best (:func:`_best_point`).
NEXT_POINT_SHARE = 0.5


def _best_point(T: np.ndarray, R: np.ndarray, a: np.ndarray, middles: np.ndarray,
                tol: np.ndarray, admits: Admits, quiet: Quiet | None = None,
                tight: np.ndarray | None = None, fits: _Fits | None = None
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """The point reflector that explains the most of the loci within ``tol``, from
    :data:`MIN_PILLAR_LOCI` transmitter positions or more, each explaining locus admitting
    it (``admits``: inside its beams): fitted from each of :func:`_seed_sets`, then again
    to every locus it explains, the one that explains most first; not one a plane explains
    as well (:func:`_a_plane`) unless its loci were all too ``quiet`` for that plane's
    echoes, nor one from fewer positions, but then the next that shares no locus with
    those refused and explains at least :data:`NEXT_POINT_SHARE` as many loci as the
    first, each within ``tight`` (its range's noise; none is tried without ``tight``).
    The zoo's unseen seed 108 room-07: a wall's 13 loci, which a point at its foot
    explains too, hid a T room's notch edge that 11 poses moving straight at it heard. A
    point that explains some of a refused one's loci too is that plane's; a few loci from
    far apart, within their tolerance, a coincidence (the bundled rooms at σ 0.6: 3–5
    loci, 2–3 mm off, a point 3–6 cm from a corner). ``fits``: the point fits made so
    far (:class:`_Fits`), shared by the searches of one cluster."""
    fit = fits if fits is not None else _Fits()

    def off_by(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # |residual|, explained
        off = np.abs(_point_residual(v, T, R, a))
        return off, (off <= tol) & admits(v)

    found: list[tuple[np.ndarray, np.ndarray]] = []
    for near in _seed_sets(middles):
        v, off = fit(T[near], R[near], a[near], middles[near].mean(axis=0))
        if np.count_nonzero(np.abs(off) <= tol[near]) < MIN_PILLAR_LOCI:
            continue
        found.append((v, off_by(v)[1]))
        if found[-1][1].all():  # no later seed set can explain more
            break
    refused = np.zeros(len(T), dtype=bool)  # the loci of the points refused so far
    least = -1  # before the first is refused
    for start, first in sorted(found, key=lambda f: -int(f[1].sum())):  # ties: first found
        v, _ = fit(T[first], R[first], a[first], start)
        off, explained = off_by(v)
        if least >= 0 and (tight is None or np.any(explained & refused)
                           or np.count_nonzero(explained) < least
                           or np.any(off[explained] > tight[explained])):
            continue
        if least < 0:
            least = math.ceil(NEXT_POINT_SHARE * np.count_nonzero(explained))
        if _positions(T[explained]) >= MIN_PILLAR_LOCI:
            normal = _a_plane(0.5 * (T + R)[explained], a[explained], tol[explained])
            if normal is None or (quiet is not None and quiet(normal, explained)):
                return v, explained
        refused |= explained
    return None


def _a_plane(centres: np.ndarray, a: np.ndarray, tol: np.ndarray) -> np.ndarray | None:
    """The unit normal n of one plane that explains the loci (centres, a) as well — n·c_k
    + a_k = d, each locus tangent to it at c_k + a_k·n — or None: the loci of a ring
    moving straight at a wall, or stepping little for its range, all pass through the foot
    of the wall as a point reflector's would (Kleeman & Kuc 1995 tell the two apart by the
    same test). The normal is scanned every degree, then refined."""
    def spread(theta: np.ndarray) -> np.ndarray:
        r = a[:, None] + centres @ np.stack([np.cos(theta), np.sin(theta)])
        return np.abs(r - r.mean(axis=0)).max(axis=0)

    grid = np.radians(np.arange(360.0))
    best = grid[int(np.argmin(spread(grid)))]
    found = minimize_bounded(lambda t: float(spread(np.array([t]))[0]), best - 0.02, best + 0.02)
    if spread(np.array([found]))[0] > 2.0 * float(np.max(tol)):
        return None
    return np.array([math.cos(found), math.sin(found)])


def point_reflectors(T: np.ndarray, R: np.ndarray, a: np.ndarray, middles: np.ndarray,
                     tol: np.ndarray, admits: Admits, quiet: Quiet | None = None,
                     tight: np.ndarray | None = None) -> dict[int, np.ndarray]:
    """``{k: point}`` for the loci (T_k, R_k, a_k) that one point explains,
    (|V − T_k| + |V − R_k|)/2 = a_k within ``tol``, from :data:`MIN_PILLAR_LOCI`
    transmitter positions or more, each admitting it (``admits``: inside its beams): a
    room's corner (its retro-reflected double bounce) or a convex edge that a moving ring
    hears from several poses, whose loci cross there (Kleeman & Kuc 1995's point
    reflector, a pillar of radius 0). Cluster by cluster (:data:`CLUSTER_M`), point after
    point, as :func:`pillar_arcs`. Loci a plane explains as well are a point's only where
    they are too ``quiet`` for that plane; where the best is refused, the next within
    ``tight`` (:func:`_best_point`)."""

    fits = _Fits()

    def best(m: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        return _best_point(T[m], R[m], a[m], middles[m], tol[m], lambda v: admits(v)[m],
                           None if quiet is None else lambda n, e: quiet(n, np.asarray(m)[e]),
                           None if tight is None else tight[m], fits)

    return {int(k): v for (v, _), ks in _one_by_one(middles, best) for k in ks}


def _one_by_one(middles: np.ndarray, best: Callable[[np.ndarray], tuple | None]
                ) -> Iterator[tuple[tuple, np.ndarray]]:
    """Reflectors found one after another in each cluster (:data:`CLUSTER_M`) of the loci'
    ``middles``: ``best(members)`` gives the one that explains most of ``members`` (its
    last item the mask of those it explains) or None; yields it with the loci it explains,
    then searches the rest of the cluster."""
    for members in steps.each("clusters", _clusters(middles)):
        while len(members) >= MIN_PILLAR_LOCI:
            found = best(members)
            if found is None:
                break
            explained = found[-1]
            yield found, members[explained]
            members = members[~explained]


#: The loudest a plane's echo is heard against a mirror's: its reflection point near the
#: plane's edge, the first maximum of a straight edge's Fresnel pattern, |F| = 1.17 (Born &
#: Wolf §8.7); a few Fresnel zones from it, the edge's diffracted echo arrives within the
#: pulse but apart, and the envelopes add, the edge's at most half a mirror's (the uniform
#: theory at the shadow boundary, :data:`~.strength.EDGE_SHARE`, also the least a plane's
#: echo gets, its reflection point on the edge). The zoo's seed 0 room-12 (noise-free): a
#: box's face 2.6 m away heard at 1.72 units, its mirror echo 1.50 and its edge's 0.31 a
#: centimetre of range later, against the plane's 1.37 at the reflection point (1.17 of
#: it: 1.60).
PLANE_AND_EDGE = 1.0 + EDGE_SHARE


def loci_crossing(T: np.ndarray, rho: np.ndarray, near: np.ndarray) -> np.ndarray:
    """The crossing of the circles (``T[0]``, ``rho[0]``) and (``T[1]``, ``rho[1]``) nearer
    ``near`` (where they only touch, the point between them on the line of centres): a
    point reflector heard by both would lie there (:func:`~.models.circles_meet`)."""
    points = circles_meet(T, rho)
    return points[int(np.argmin(np.hypot(*(points - near).T)))]


def a_plane_not_a_corner(heard: np.ndarray, plane: np.ndarray, corner: np.ndarray,
                         spare: float) -> bool:
    """Whether the echoes ``heard`` of two loci are a plane's rather than a point
    reflector's (Kleeman & Kuc 1995's plane/corner test, by their strengths): each between
    :data:`~.strength.EDGE_SHARE` and :data:`PLANE_AND_EDGE` of the ``plane``'s echo (its
    edge's diffraction arriving with it; ``spare`` for noise), and nearer to the plane's
    echoes than to a concave corner's at the loci's crossing (``corner``: its
    retro-reflection, as loud from any angle inside the beam, changes with the angle
    between the poses where a plane's stays)."""
    inside = (heard >= EDGE_SHARE * plane - spare) & (heard <= PLANE_AND_EDGE * plane + spare)
    return bool(np.all(inside) and np.sum((heard - plane) ** 2) < np.sum((heard - corner) ** 2))


def pillar_circles(T: np.ndarray, rho: np.ndarray, middles: np.ndarray, tol: np.ndarray,
                   seen_through: SeenThrough) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """``[(centre, radius, loci)]``: the pillars fitted to the loci (T_k, ρ_k) (middles of
    arc ``middles``, range tolerances ``tol``), cluster by cluster, pillar after pillar
    (:func:`_best_pillar`), each with the indices of the loci it explains."""

    def best(m: np.ndarray) -> tuple[np.ndarray, float, np.ndarray] | None:
        return _best_pillar(T[m], rho[m], middles[m], tol[m], seen_through)

    return [(centre, radius, ks) for (centre, radius, _), ks in _one_by_one(middles, best)]


def pillar_arcs(T: np.ndarray, rho: np.ndarray, middles: np.ndarray, tol: np.ndarray,
                bias: float, step: float, seen_through: SeenThrough
                ) -> dict[int, np.ndarray]:
    """``{k: arc points}`` for the loci (T_k, ρ_k) that a fitted pillar explains
    (:func:`pillar_circles`): each its stretch of the pillar (:func:`pillar_arc`) in
    place of its middle-of-arc stub."""
    return {int(k): pillar_arc(centre, radius, T[k], float(rho[k]), bias, step)
            for centre, radius, ks in pillar_circles(T, rho, middles, tol, seen_through)
            for k in ks}


__all__ = [
    "CLUSTER_M",
    "MIN_PILLAR_LOCI",
    "PILLAR_RADII_M",
    "PILLAR_TOL_M",
    "SEED_M",
    "WIDER_SEEDS_M",
    "fit_circle",
    "fit_pillar",
    "pillar_arc",
    "pillar_arcs",
    "pillar_circles",
    "point_reflectors",
]
