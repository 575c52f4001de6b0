"""The echoes of one linear array split into reflector families (``mapping.mode =
"reflectors"``): each family is the set of detections one reflector explains — a plane, a
point (an edge, a thin post), a corner (right-angled, or turned) or a circle (a cylinder,
the crest or trough of a curved wall) — with the model's parameters and each detection's
reflection point (:func:`find_families`).

The plane/corner/edge distinction of Kleeman & Kuc (1995): with T ≠ R pairs the three
predict different times of flight (:mod:`.models`), so the family's pairs decide. The
families are grown from seeds: a detection and its nearest detections in the array give
a first fit of each model (:mod:`.starts`); each model then takes every unexplained
detection it predicts within the tolerance, its reflection point in both beams, is fitted
again, and so on; the model that explains most wins the detections, and the simplest
(plane, point, corner) that explains them about as well as the free curve names the
family. A plane takes the detections no family explained that it predicts
(:func:`~.owners.widened`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..numerics import median
from .envelope import in_beams
from .models import (
    CURVE_STEPS,
    Fit,
    _jacobian,
    apart,
    corner_images,
    corner_paths,
    curve_paths,
    dot2,
    fit_corner,
    fit_curve,
    fit_point,
    gram,
    point_paths,
)
from .starts import MIN_CURVE, START_TOLERANCE_M, family_starts, starts, turned_start
from .strength import convex_share, mirror_strong, two_way
from .window import (
    BASE_TOLERANCE_M,
    CURVE_TOLERANCE_M,
    KINDS,
    Family,
    Window,
    detection_noise,
    window_tolerance,
)

#: A family needs this many detections (fewer and every model fits them; three are the
#: T₁ = R₁, T₂ = R₂, T₁ → R₂ triple of Kleeman & Kuc).
MIN_FAMILY = 3

#: Turned corners a window's search grows where a right-angled corner's start explained
#: enough rows but grew none (:func:`_grow`), as many as a scattered window's failed seeds.
TURN_RETRIES = 12


@dataclass
class Budget:
    """How many more times a costly try may be made (a window's turned corners)."""

    left: int


#: Rounds of taking the explained rows and fitting again.
GROW_ROUNDS = 6

#: Detections in a seed's first fit.
SEED_SIZE = 10

#: A seed's first fit takes rows whose echoes are within this factor of its own: one
#: reflector's neighbouring echoes differ by their beams only, and a face's specular echo
#: is 30–60 dB above its edge's diffraction.
SEED_SPREAD = 10.0

#: How much a path may change per metre its transducers move: at most 1 (the triangle
#: inequality).
MAX_PATH_SLOPE = 1.0

#: The simplest model is kept when its RMS is within this factor of the best fit's, plus
#: the detections' expected noise and :data:`DETECTION_FLOOR_M`.
SIMPLER_RMS_FACTOR = 1.5

#: Another model is not fitted to a family whose rows its start misses by this RMS (m):
#: a point or a corner where a plane fits (or the reverse) across a wide array.
HOPELESS_START_M = 0.05

#: With noise, a simpler model that fits the members best of all (a corner's T ≠ R paths
#: tell it from a curve at first order) may leave this share of them outside its tolerance
#: (a detection's noise exceeds NOISE_SIGMAS of it now and then, and the free curve, with
#: a parameter more, takes it in); they leave the family.
NOISY_OUTSIDE_SHARE = 0.1

#: Without noise, a model that fits a family best may leave this share of it outside its
#: tolerance, echoes an overlapping one distorted (one in 50: the zoo's unseen seed 28
#: edge-04, an edge's 55 diffracted echoes, one 0.3 mm off the point, named a free curve
#: drawn 1.5–3.5 cm off the edge).
DISTORTED_SHARE = 0.02

#: Path precision of a noise-free detection (measured: a few µm), metres.
DETECTION_FLOOR_M = 2e-5

#: The order in which :func:`_simplest` names a family, among models of as many parameters
#: (a turned corner, of three, after the point).
SIMPLEST = ("plane", "corner", "point", "curve")


#: The echoes of one point reflector, each over its two-way beam, agree within this factor.
POINT_SPREAD = 10.0


def _strong(w: Window, kind: str, rows: np.ndarray, q: np.ndarray,
            params: np.ndarray) -> np.ndarray:
    """Whether the detections ``rows`` are as strong as a ``kind`` reflector's echoes can
    be (planes: :func:`mirror_strong`; curves: the same, the mirror weakened by their
    divergence, :func:`~.strength.convex_share`; a point's, within :data:`POINT_SPREAD` of
    each other over their beams); all, for corners (a post's echo may be as weak as an
    edge's: it is a tight circle or a point, not a corner), or a window without a
    mirror."""
    beams = (q, w.T[rows], w.axT[rows], w.R[rows], w.axR[rows])
    if kind in ("plane", "curve") and w.mirror > 0:
        share = (convex_share(params, w.x0, q, w.T[rows], w.R[rows], w.paths[rows])
                 if kind == "curve" else 1.0)
        if share is None:
            return np.ones(len(rows), dtype=bool)
        return mirror_strong(w.amplitude[rows], *beams, w.mirror * share, w.ka, w.noise_std)
    if kind == "point" and w.mirror > 0 and len(rows):
        # one point reflector's echoes differ by their beams only: not by 20 dB (a face's
        # specular echo beside its edge's diffraction, 40 dB weaker, fits a point too)
        seen = w.amplitude[rows] / np.maximum(two_way(*beams, w.ka), 1e-3)
        middle = float(median(seen))
        return (seen <= POINT_SPREAD * middle) & (seen >= middle / POINT_SPREAD)
    return np.ones(len(rows), dtype=bool)


def _predict(w: Window, kind: str, params: np.ndarray, idx: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    T, R = w.T[idx], w.R[idx]
    if kind == "corner":
        return corner_paths(params, T, R)
    if kind == "point":
        return point_paths(params, T, R)
    return curve_paths(params, w.x0, T, R)


def predict(f: Family, T: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The path family ``f``'s model predicts for the pairs (T, R)."""
    if f.kind == "corner":
        return corner_paths(f.params, T, R)[0]
    if f.kind == "point":
        return point_paths(f.params, T, R)[0]
    return curve_paths(f.params, f.x0, T, R)[0]


def _valid(w: Window, kind: str, params: np.ndarray, idx: np.ndarray,
           q: np.ndarray) -> np.ndarray:
    """Reflection points inside both beams (and, for the curve model, in front of both
    transducers: on the far side of the surface's tangent from neither)."""
    at_t, at_r = q, q
    if kind == "corner":  # the double bounce leaves T towards R's image, not V
        at_t, at_r = corner_images(params, w.T[idx], w.R[idx])
    ok = (in_beams(at_t, w.T[idx], w.axT[idx], w.cut_sin2)
          & in_beams(at_r, w.R[idx], w.axR[idx], w.cut_sin2))
    if kind in ("plane", "curve"):
        n = np.array([math.cos(params[0]), math.sin(params[0])])
        ok &= (dot2(q - w.T[idx], n) > 0) & (dot2(q - w.R[idx], n) > 0)
    return ok


def _fit(w: Window, kind: str, idx: np.ndarray, start: np.ndarray) -> Fit:
    T, R, P = w.T[idx], w.R[idx], w.paths[idx]
    if kind == "corner":
        return _fit_corner(w, idx, start)
    if kind == "point":
        return fit_point(T, R, P, start)
    return fit_curve(w.x0, T, R, P, start, fix_psi=kind == "plane")


def _fit_corner(w: Window, idx: np.ndarray, start: np.ndarray) -> Fit:
    """The corner of the rows ``idx``: right-angled (a point reflection through V), or
    turned (:func:`~.models.corner_paths`: walls meeting at 90° − β/2) where the rows can
    tell β (at least :data:`MIN_CURVE`, as a free curve's ψ) and the right angle fits
    them worse than :data:`SIMPLER_RMS_FACTOR` times the turned corner, plus their noise
    (the simpler model wins otherwise, as :func:`_simplest` names families)."""
    T, R, P = w.T[idx], w.R[idx], w.paths[idx]
    right = fit_corner(T, R, P, start[:2], turn=False)
    if len(idx) < MIN_CURVE:
        return right
    turned = fit_corner(T, R, P, right.params)
    if len(start) > 2 and start[2] != 0:  # and from a turned start (starts.turned_start)
        turned = min(turned, fit_corner(T, R, P, start), key=lambda f: f.rms)
    noise = detection_noise(w.tolerance[idx])
    if right.rms <= SIMPLER_RMS_FACTOR * turned.rms + noise + DETECTION_FLOOR_M:
        return right
    return turned


def _inliers(w: Window, kind: str, params: np.ndarray, free: np.ndarray) -> np.ndarray:
    """The rows of ``free`` the model predicts within their tolerance, in both beams."""
    path, q = _predict(w, kind, params, free)
    ok = (np.abs(path - w.paths[free]) <= _tolerance(w, kind, free)) & np.isfinite(path)
    ok &= _valid(w, kind, params, free, q) & _strong(w, kind, free, q, params)
    return free[ok]


def _tolerance(w: Window, kind: str, rows: np.ndarray) -> np.ndarray:
    """The path residual ``rows`` may have under ``kind``: the detections' own, and for
    the free curve, a local circle, at least the window's ``curve_tolerance``."""
    tol = w.tolerance[rows]
    return np.maximum(tol, w.curve_tolerance) if kind == "curve" else tol


def _least(w: Window, kind: str) -> int:
    """Fewest members a family of ``kind`` needs: more than the model has parameters
    (for a free curve, the window's ``least_curve``)."""
    return w.least_curve if kind == "curve" else MIN_FAMILY


def _close(w: Window, kind: str, start: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The ``rows`` the start of ``kind`` explains to within :data:`START_TOLERANCE_M`
    plus their tolerance."""
    path, _ = _predict(w, kind, start, rows)
    return rows[np.abs(path - w.paths[rows]) <= START_TOLERANCE_M + w.tolerance[rows]]


def _grow(w: Window, kind: str, start: np.ndarray, seed_rows: np.ndarray,
          free: np.ndarray, turns: Budget) -> tuple[np.ndarray, Fit] | None:
    """Fit ``kind`` to the seed's rows that its ``start`` explains to within
    :data:`START_TOLERANCE_M` (a free curve, started from a plane or a point, to all of
    them if those are too few), then alternately take the rows of ``free`` it explains and
    fit again, until they no longer change (at most :data:`GROW_ROUNDS` rounds); the
    members are those the last fit explains. None if the start of a plane, point or corner
    explains fewer rows than it needs (:func:`_least`), or the last fit does.

    A corner grows from a turned start (:func:`~.starts.turned_start`) where its
    right-angled start explains too few rows, or, while the window's ``turns`` last
    (:data:`TURN_RETRIES` a window), where it explains enough of at least
    :data:`~.starts.MIN_CURVE` seed rows but grew none: an off-square corner's double
    bounces may cross, right-angled, a metre or two from the vertex and explain a few
    rows there by chance (the zoo's unseen seed 43 corner-03: 77°, 8.3 m along its
    bisector, the right-angled start 1.8 m from the vertex; seed 50 corner-07, 86°:
    both orders of its walls' double bounces)."""
    close = _close(w, kind, start, seed_rows)
    least = _least(w, kind)
    if kind == "corner" and len(close) < least:  # a corner off the right angle?
        turned = turned_start(w, start, seed_rows, w.tolerance[seed_rows])
        if turned is not None:
            start, close = turned, _close(w, kind, turned, seed_rows)
    elif kind == "corner" and len(seed_rows) >= MIN_CURVE and turns.left > 0:
        grown = _grown(w, kind, start, close, seed_rows, free)
        if grown is not None:
            return grown
        turns.left -= 1
        turned = turned_start(w, start, seed_rows, w.tolerance[seed_rows])
        if turned is None:
            return None
        start, close = turned, _close(w, kind, turned, seed_rows)
    if len(close) < least and kind != "curve":
        return None  # the start explains too few: another model's seed
    return _grown(w, kind, start, close, seed_rows, free)


def _grown(w: Window, kind: str, start: np.ndarray, close: np.ndarray, seed_rows: np.ndarray,
           free: np.ndarray) -> tuple[np.ndarray, Fit] | None:
    """:func:`_grow`'s rounds from ``start`` and the seed's rows it explains, ``close``."""
    least = _least(w, kind)
    members = close if len(close) >= least else seed_rows
    fit = _fit(w, kind, members, start)
    for _ in range(GROW_ROUNDS):
        found = _inliers(w, kind, fit.params, free)
        if len(found) < least:
            return None
        if np.array_equal(found, members):
            return members, fit
        members = found
        fit = _fit(w, kind, members, fit.params)
    members = _inliers(w, kind, fit.params, members)
    return (members, fit) if len(members) >= least else None


def _moved(w: Window, a: int | np.ndarray, rows: np.ndarray) -> np.ndarray:
    """How far the transducers of each of ``rows`` lie from row ``a``'s (T to T and R to R,
    or crossed: a pair and its reciprocal are one path); ``a`` a column of rows: each
    against each, [len(a), len(rows)]."""
    T, R, Ta, Ra = w.T[rows], w.R[rows], w.T[a], w.R[a]
    return np.minimum(apart(T, Ta) + apart(R, Ra), apart(T, Ra) + apart(R, Ta))


def _seed_rows(w: Window, seed: int, free: np.ndarray) -> np.ndarray:
    """The seed and the free rows reached from it through neighbouring pairs (transducers
    moved by at most the window's ``neighbour_m``) whose paths change no more than one
    surface allows (:data:`MAX_PATH_SLOPE`), nearest first, at most :data:`SEED_SIZE`; when
    these are too few to fit, the nearest free rows whose paths are within that of the
    seed's, however far, and if still too few, however weaker (a sparse array's elements
    face every way: their beams part one reflector's echoes more than :data:`SEED_SPREAD`)."""
    step = w.neighbour_m
    members = [seed]
    frontier = [seed]
    ratio = w.amplitude[free] / max(float(w.amplitude[seed]), 1e-300)
    left = free[(free != seed) & (ratio <= SEED_SPREAD) & (ratio >= 1.0 / SEED_SPREAD)]
    while frontier and len(members) < 4 * SEED_SIZE and len(left):
        a = np.asarray(frontier)[:, None]  # every frontier row against every left one
        moved = _moved(w, a, left)
        reached = np.any((moved <= step) & (np.abs(w.paths[left] - w.paths[a])
                                            <= MAX_PATH_SLOPE * moved + w.tolerance[left]
                                            + w.tolerance[a]), axis=0)
        frontier = left[reached].tolist()
        members += frontier
        left = left[~reached]
    for weaker in (False, True):  # a sparse array: farther, then however weaker
        if len(members) >= MIN_FAMILY:
            break
        pool = free[(free != seed) & ~np.isin(free, members)] if weaker else left
        moved = _moved(w, seed, pool)
        near = np.abs(w.paths[pool] - w.paths[seed]) <= (MAX_PATH_SLOPE * moved
                                                         + w.tolerance[pool] + w.tolerance[seed])
        members += pool[near][np.argsort(moved[near], kind="stable")].tolist()
    found = np.asarray(members)
    order = np.argsort(_moved(w, seed, found), kind="stable")
    return np.sort(found[order[:SEED_SIZE]])


def _best_family(w: Window, seed: int, free: np.ndarray, turns: Budget) -> Family | None:
    """The model that, grown from ``seed``, explains the most free rows (ties: the lower
    RMS), named by :func:`_simplest`; None if none explains :data:`MIN_FAMILY`
    (``turns``: :func:`_grow`'s budget of turned corners)."""
    rows = _seed_rows(w, seed, free)
    if len(rows) < MIN_FAMILY:
        return None
    # the curve model about the seed's own middle: its normal then points at the reflector
    w = replace(w, x0=0.5 * (w.T[rows] + w.R[rows]).mean(axis=0))
    best: tuple[np.ndarray, Fit, str] | None = None
    for kind, start in starts(w, seed, rows):
        if w.curve_tolerance > 0 and kind != "curve":
            continue  # the loose pass is the free curve's alone
        grown = _grow(w, kind, start, rows, free, turns)
        if grown is None:
            continue
        members, fit = grown
        q = _predict(w, kind, fit.params, members)[1]
        members = members[_strong(w, kind, members, q, fit.params)]
        if seed not in members or len(members) < _least(w, kind):
            continue
        if (best is None or len(members) > len(best[0])
                or (len(members) == len(best[0]) and fit.rms < best[1].rms)):
            best = (members, fit, kind)
    if best is None:
        return None
    return _simplest(w, *best)


def as_well_limit(rms: float, noise: float) -> float:
    """The RMS another model may have and still fit as well as one of RMS ``rms``:
    :data:`SIMPLER_RMS_FACTOR` times it plus the detections' ``noise``
    (:func:`~.window.detection_noise`) and :data:`DETECTION_FLOOR_M`."""
    return SIMPLER_RMS_FACTOR * rms + noise + DETECTION_FLOOR_M


def _simplest(w: Window, members: np.ndarray, fit: Fit, kind: str) -> Family:
    """The family of ``members``: the free curve refitted, and the simplest of plane, point
    and corner (fewest parameters first, then in :data:`SIMPLEST`'s order) whose RMS is
    within :data:`SIMPLER_RMS_FACTOR` of the best fit's and that still explains every
    member — with noise, all but the share a best fit may leave
    outside their tolerance (:func:`outside_allowed`) where it fits best, or where it and
    the best fit are both of two parameters (:func:`_parameters`: plane, point,
    right-angled corner): at noise above what tells those apart (a plane's and a corner's
    paths part by about L²/(4r), 1.3 mm for 5 elements at 6.7 m, under σ 0.6's 1.4 mm
    tolerance) which one fits best is chance, and the one first in order was named only
    when it fitted best (the zoo's seed 12 wall-05: a wall named a corner, 7 % of it
    mapped). Any other model must still explain every member: a noisy cylinder's circle
    is not named a plane, nor a sinusoid's trough a turned corner."""
    fits: dict[str, Fit] = {kind: fit}
    first = family_starts(w, kind, fit.params, members)
    for other, start in first.items():
        if other in fits or len(members) < _least(w, other):
            continue
        path, _ = _predict(w, other, start, members)
        if np.sqrt(np.mean((path - w.paths[members]) ** 2)) <= HOPELESS_START_M:
            fits[other] = _fit(w, other, members, start)
    floor = min(f.rms for f in fits.values())
    noise = detection_noise(w.tolerance[members])
    limit = as_well_limit(floor, noise)
    bend = _measured_bend(w, members, fits, first, noise)
    best = max(_parameters(name, f) for name, f in fits.items() if f.rms <= floor * (1 + 1e-9))
    for name in sorted(fits, key=lambda n: (_parameters(n, fits[n]), SIMPLEST.index(n))):
        f = fits[name]
        if f.rms > limit and name != "curve":
            continue
        path, q = _predict(w, name, f.params, members)
        within = np.abs(path - w.paths[members]) <= _tolerance(w, name, members)
        tied = f.rms <= floor * (1.0 + 1e-9) or _parameters(name, f) == best == 2
        allowed = outside_allowed(w, members) if tied else 0
        if np.count_nonzero(~within) > allowed:
            continue
        kept, q = members[within], q[within]
        if name in ("plane", "point"):  # a face's echoes and its edge's apart
            strong = _strong(w, name, kept, q, f.params)
            if np.count_nonzero(strong) < MIN_FAMILY:
                continue
            kept, q = kept[strong], q[strong]
        return Family(name, f.params, w.x0, kept, q, f.rms, w, bend)
    path, q = _predict(w, kind, fit.params, members)
    return Family(kind, fit.params, w.x0, members, q, fit.rms, w, bend)


def _parameters(kind: str, fit: Fit) -> int:
    """How many parameters the model ``kind`` fitted: three for the free curve and a
    turned corner (its β), two for a plane, a point and a right-angled corner."""
    return 3 if kind == "curve" or (kind == "corner" and fit.params[2] != 0) else 2


#: The free curve measures a family's bend (:func:`_bend`) from this many detections, as
#: many as its parameters: fitted exactly, its ψ is what a plane's residual says, bounded
#: by the detections' noise (it names a family only from :data:`MIN_CURVE`).
MIN_BEND = 3


def _measured_bend(w: Window, members: np.ndarray, fits: dict[str, Fit],
                   first: dict[str, np.ndarray], noise: float) -> float:
    """How far from the family's model the surface's curvature may be (1/m): 3σ of the
    free curve's ψ (:func:`_bend`), the curve fitted to name the family; or, with fewer
    members than a curve needs to name one but at least :data:`MIN_BEND`, or for a plane
    widened by other arrays' echoes (:func:`~.owners.widened`), of the curve fitted for its bend
    alone where its ψ is within that of none: the rows show the plane straight (four
    T = R echoes of scattered elements, metres apart on one face). Inf otherwise: the
    curvature is unknown (a cylinder's four echoes, named a plane, show it bent)."""
    if "curve" in fits:
        return _bend(w, members, fits["curve"], noise)
    if len(members) < MIN_BEND or "curve" not in first:
        return math.inf
    curve = _fit(w, "curve", members, first["curve"])
    bend = _bend(w, members, curve, noise)
    return bend if abs(float(curve.params[2])) <= bend else math.inf


def _bend(w: Window, members: np.ndarray, fit: Fit | None, noise: float) -> float:
    """3σ of the free curve's ψ (the curvature the rows measure, 1/m), from its fit's
    Jacobian and its RMS (at least the detections' noise, :data:`DETECTION_FLOOR_M`):
    how far from the fitted curvature the surface may be. Inf without a free curve."""
    if fit is None:
        return math.inf
    J = np.ascontiguousarray(_jacobian(  # laid out by rows, as gram's sums always were here
        lambda p: curve_paths(p, w.x0, w.T[members], w.R[members]), fit.params, CURVE_STEPS,
        np.ones(3, dtype=bool), len(members)))
    sigma = max(fit.rms, noise, DETECTION_FLOOR_M)
    try:
        cov = np.linalg.inv(gram(J, J)) * sigma**2
    except np.linalg.LinAlgError:
        return math.inf
    return 3.0 * math.sqrt(max(float(cov[2, 2]), 0.0))


def outside_allowed(w: Window, rows: np.ndarray) -> float:
    """How many of ``rows`` a model that fits them best may leave outside their tolerance:
    :data:`NOISY_OUTSIDE_SHARE` of them where the detections are noisy (a detection's
    noise exceeds its tolerance now and then), :data:`DISTORTED_SHARE` where they are not
    (an echo an overlapping one distorted)."""
    noisy = detection_noise(w.tolerance[rows]) > 0
    return (NOISY_OUTSIDE_SHARE if noisy else DISTORTED_SHARE) * len(rows)


def shadowed(w: Window, families: list[Family], rows: np.ndarray,
             resolution: float) -> np.ndarray:
    """Which ``rows`` lie within ``resolution`` (the pulse's, c·σ) of the path a family
    predicts for their pair: echoes of that reflector that an overlapping echo distorted
    (or another reflector's that no detector could have told from it) — but not a
    detection :data:`POINT_SPREAD` times stronger than every echo of the family, which so
    weak an echo barely shifts (a corner's double bounce beside a wall end's diffraction)."""
    out = np.zeros(len(rows), dtype=bool)
    for f in families:
        loudest = POINT_SPREAD * float(np.max(f.window.amplitude[f.rows]))
        out |= (np.abs(predict(f, w.T[rows], w.R[rows]) - w.paths[rows]) <= resolution) \
            & (w.amplitude[rows] <= loudest)
    return out


def _candidates(w: Window, rows: np.ndarray, resolution: float) -> list[Family]:
    """A family of ``rows`` grown from each seed among them that no earlier candidate
    explains, strongest echo first, until the window's ``max_failed`` seeds in a row grew
    none; the echoes an earlier candidate :func:`shadowed` (within ``resolution``: most
    are that reflector's, which :func:`_select` gives it anyway) seed last, when every
    other seed has been tried."""
    everything = np.arange(len(w.paths))
    tried = np.ones(len(w.paths), dtype=bool)
    tried[rows] = False
    deferred = np.zeros(len(w.paths), dtype=bool)
    found: list[Family] = []
    turns = Budget(TURN_RETRIES)  # the turned corners _grow may try where a right angle grew none
    for last in (False, True):
        failed = 0
        swept = last  # the shadowed seeds are never swept
        stack = np.argsort(-w.amplitude, kind="stable")[::-1].tolist()  # strongest on top
        while stack:
            seed = stack.pop()
            if tried[seed] or deferred[seed] != last:
                continue
            if failed >= w.max_failed:
                if swept or found:
                    break
                swept = True
                sweep = _sweep([seed, *stack[::-1]], tried, deferred, w.max_failed)
                stack += [seed, *sweep[::-1]]
                failed -= len(sweep)
                continue
            tried[seed] = True
            family = _best_family(w, int(seed), rows, turns)
            if family is None:
                failed += 1
                continue
            failed = failed if last else 0  # the shadowed seeds: max_failed in all
            found.append(family)
            tried[family.rows] = True
            deferred |= shadowed(w, [family], everything, resolution)
    return found


def _sweep(order: list[int], tried: np.ndarray, deferred: np.ndarray, max_failed: int
           ) -> list[int]:
    """Half of ``max_failed`` seeds spread evenly over the untried ones of ``order``
    (strongest first), tried once a window's strongest ``max_failed`` grew nothing: where
    two reflectors' echoes overlap (a wall seen square beside its corner's double bounce),
    the loudest detections are their sums, no model's, and the clean echoes of either
    come later (the zoo's unseen seed 106 corner-06)."""
    rest = [s for s in order if not tried[s] and not deferred[s]]
    stride = max(1, len(rest) // max(1, max_failed // 2))
    return rest[stride - 1::stride][:max_failed // 2]


def _select(w: Window, rows: np.ndarray, taken: np.ndarray, resolution: float
            ) -> list[Family]:
    """The candidates of ``rows`` taken largest first (marking ``taken`` the rows each
    holds or shadows); a candidate that lost rows to an earlier one is fitted again to the
    rest and named again, or dropped with too few."""
    everything = np.arange(len(w.paths))
    families: list[Family] = []
    for cand in sorted(_candidates(w, rows, resolution), key=lambda f: -len(f.rows)):
        keep = cand.rows[~taken[cand.rows]]
        v = cand.window
        if len(keep) < _least(v, cand.kind):
            continue
        if len(keep) < len(cand.rows):
            kind = "curve" if cand.kind == "plane" and len(keep) >= v.least_curve else cand.kind
            keep = _inliers(v, kind, _fit(v, kind, keep, cand.params).params, keep)
            if len(keep) < _least(v, kind):
                continue
            cand = _simplest(v, keep, _fit(v, kind, keep, cand.params), kind)
        families.append(cand)
        taken[cand.rows] = True
        taken |= shadowed(v, [cand], everything, resolution)
    return families


def find_families(w: Window, resolution: float) -> tuple[list[Family], np.ndarray]:
    """The window's families (module docstring) and the rows none explains and that no
    family's echo :func:`shadowed` (within ``resolution``). Candidates are grown from
    seeds (:func:`_candidates`) and taken largest first (:func:`_select`): first with
    every model exact to the detections' tolerance, then, of the rows left, free curves
    to :data:`CURVE_TOLERANCE_M` (local circles of a curved wall) — so that a family of
    exact echoes shadows the distorted ones before a loose circle could take them."""
    taken = np.zeros(len(w.paths), dtype=bool)
    families = _select(w, np.arange(len(w.paths)), taken, resolution)
    left = np.flatnonzero(~taken)
    if len(left) >= MIN_CURVE:  # loose curves need as many rows as an array's
        loose = replace(w, curve_tolerance=CURVE_TOLERANCE_M, least_curve=MIN_CURVE)
        families += _select(loose, left, taken, resolution)
    return families, np.flatnonzero(~taken)


__all__ = ["BASE_TOLERANCE_M", "CURVE_TOLERANCE_M", "KINDS", "MIN_FAMILY", "Family", "Window",
           "as_well_limit",
           "detection_noise", "find_families", "outside_allowed", "predict", "shadowed",
           "window_tolerance"]
