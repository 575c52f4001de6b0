"""Starting parameters of the reflector models for a family's rows (``mapping.mode =
"reflectors"``, :mod:`.families`): a seed's first plane, corner, point and free curve
(:func:`starts`), and every model's from another's fit (:func:`family_starts`)."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from ..numerics import median
from .models import corner_paths, curve_paths, dot2, fit_corner, plane_start


class Window(Protocol):
    """What the starts read of a stretch's detections (:class:`~.families.Window`, which
    imports this module)."""

    @property
    def T(self) -> np.ndarray: ...  # [m, 2] transmitters

    @property
    def R(self) -> np.ndarray: ...  # [m, 2] receivers

    @property
    def axT(self) -> np.ndarray: ...  # [m, 2] the transmitters' unit axes

    @property
    def paths(self) -> np.ndarray: ...  # [m] c·τ

    @property
    def x0(self) -> np.ndarray: ...  # [2] the curve model's reference point

    @property
    def least_curve(self) -> int: ...  # detections a free curve needs


#: A free curve (three parameters) needs this many detections of an array's neighbouring
#: pairs, whose paths barely tell its parameters apart: two more than it has.
MIN_CURVE = 5

#: The rows a start explains to within this are the first fit's, metres of path.
START_TOLERANCE_M = 0.005

#: A turned start leaves out at most this many of a seed's rows (the zoo's corners that
#: grew from one needed none or one; a sinusoid's seeds, which none explains, each cost
#: two fits per row left out).
TURN_DROPS = 2

#: The free curve started at a point starts as a post of this radius (a circle of radius
#: 0 has no normal to move it by).
POINT_START_RADIUS_M = 0.01

#: Normals tried for a seed's first plane: around its transmitter's axis, ± this, 0.25° apart.
START_SPREAD_RAD = math.radians(20.0)


def corner_start(w: Window, seed: int, rows: np.ndarray) -> np.ndarray | None:
    """The vertex V, of the crossings of the seed's corner locus (the circle of centre
    (T + R)/2 and radius c·τ/2, :func:`~.models.corner_paths`) with the other rows', that
    the most rows agree with to within :data:`START_TOLERANCE_M` (None: no crossing)."""
    m = 0.5 * (w.T[rows] + w.R[rows])
    r = 0.5 * w.paths[rows]
    m0, r0 = 0.5 * (w.T[seed] + w.R[seed]), 0.5 * w.paths[seed]
    d = m - m0
    dist = np.hypot(*d.T)
    ok = (dist > 1e-9) & (dist <= r + r0) & (dist >= np.abs(r - r0))
    if not ok.any():
        return None
    d, dist, r = d[ok], dist[ok], r[ok]
    a = (r0 * r0 - r * r + dist * dist) / (2 * dist)
    h = np.sqrt(np.maximum(r0 * r0 - a * a, 0.0))
    u = d / dist[:, None]
    v = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    cand = np.concatenate([m0 + a[:, None] * u + h[:, None] * v,
                           m0 + a[:, None] * u - h[:, None] * v])
    pred = np.hypot(*(w.T[rows][None] + w.R[rows][None] - 2 * cand[:, None]).transpose(2, 0, 1))
    votes = np.sum(np.abs(pred - w.paths[rows][None]) <= START_TOLERANCE_M, axis=1)
    return np.asarray(cand[int(np.argmax(votes))])


def turned_start(w: Window, start: np.ndarray, rows: np.ndarray, tolerance: np.ndarray
                 ) -> np.ndarray | None:
    """``(V, β)`` of a turned corner (:func:`~.models.corner_paths`) that explains every one
    of at least :data:`MIN_CURVE` of ``rows`` to within :data:`START_TOLERANCE_M` plus its
    ``tolerance`` [len(rows)], fitted from the right-angled corner's ``start`` (V) and
    dropping the row it fits worst until it does, at most :data:`TURN_DROPS` of them (a
    seed's rows hold other reflectors' echoes; one far off can keep the fit from turning
    at all, β = 0: dropped too); None if none does. For a corner the right
    angle misses by more than a start's tolerance: the double bounce turns R's image by
    π − β about V, so no locus of the right angle's crosses at V, and no right-angled
    corner grew from its rows (the zoo's seed 4 corner-07: an 85° corner 3.6 m from seven
    elements, its double bounces 6–27 mm from the right angle's, the vertex missed by
    12.7 cm)."""
    keep = np.arange(len(rows))
    while len(keep) >= MIN_CURVE and len(rows) - len(keep) <= TURN_DROPS:
        T, R, paths = w.T[rows[keep]], w.R[rows[keep]], w.paths[rows[keep]]
        right = fit_corner(T, R, paths, start[:2], turn=False)
        turned = fit_corner(T, R, paths, right.params).params
        off = np.abs(corner_paths(turned, T, R)[0] - paths)
        if not np.all(np.isfinite(off)):
            return None
        # a fit that did not turn (its rows held another reflector's, far off) drops one
        if turned[2] != 0.0 and np.all(off <= START_TOLERANCE_M + tolerance[keep]):
            return turned
        keep = np.delete(keep, int(np.argmax(off - tolerance[keep])))
    return None


def starts(w: Window, seed: int, rows: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """First parameters for the seed's rows, each robust to rows of other reflectors among
    them: the plane whose tangents to the loci agree best (median), the corner (or point:
    for T = R echoes the same) at the crossing of loci most rows agree with, and the free
    curve (planes and points are its members, named by :func:`~.families._simplest`) from
    whichever of the two explains more rows."""
    axis = math.atan2(w.axT[seed, 1], w.axT[seed, 0])
    phis = axis + np.arange(-START_SPREAD_RAD, START_SPREAD_RAD, math.radians(0.25))
    plane = plane_start(w.x0, w.T[rows], w.R[rows], w.paths[rows], phis)
    n = np.array([math.cos(plane[0]), math.sin(plane[0])])
    point = corner_start(w, seed, rows)
    if point is None:
        mid = 0.5 * (w.T[rows] + w.R[rows]).mean(axis=0)
        point = mid + 0.5 * float(median(w.paths[rows])) * n
    rel = point - w.x0
    reach = max(float(np.hypot(*rel)), 1e-3)
    phi = math.atan2(rel[1], rel[0])
    along = float(np.hypot(*rel) + dot2(np.array([math.cos(phi), math.sin(phi)]), w.x0))
    as_point = np.array([phi, along, 1.0 / (reach + POINT_START_RADIUS_M)])
    starts = [("plane", plane), ("corner", point), ("point", point)]
    if len(rows) >= w.least_curve:
        starts.append(("curve", max((plane, as_point), key=lambda p: explained(w, p, rows))))
    return starts


def explained(w: Window, params: np.ndarray, rows: np.ndarray) -> int:
    """How many ``rows`` the curve model ``params`` predicts to within
    :data:`START_TOLERANCE_M`."""
    path, _ = curve_paths(params, w.x0, w.T[rows], w.R[rows])
    return int(np.count_nonzero(np.abs(path - w.paths[rows]) <= START_TOLERANCE_M))


def family_starts(w: Window, kind: str, params: np.ndarray,
                   members: np.ndarray) -> dict[str, np.ndarray]:
    """Starting parameters of every model from the fitted ``kind``'s: a plane or curve's
    apex is the point and corner, a point's or corner's position the apex of a plane
    facing the window's middle and of a post of radius :data:`POINT_START_RADIUS_M`."""
    if kind in ("plane", "curve"):
        phi, d = float(params[0]), float(params[1])
        n = np.array([math.cos(phi), math.sin(phi)])
        apex = w.x0 + (d - float(dot2(n, w.x0))) * n
        curve = np.array([phi, d, params[2] if kind == "curve" else 0.0])
        return {"plane": np.array([phi, d, 0.0]), "curve": curve, "point": apex,
                "corner": apex}
    point = np.asarray(params[:2], dtype=np.float64)
    rel = point - w.x0
    reach = max(float(np.hypot(*rel)), 1e-3)
    phi = math.atan2(rel[1], rel[0])
    d = float(dot2(point, np.array([math.cos(phi), math.sin(phi)])))
    return {"plane": np.array([phi, d, 0.0]),
            "curve": np.array([phi, d, 1.0 / (reach + POINT_START_RADIUS_M)]),
            "point": point, "corner": point}


__all__ = ["MIN_CURVE", "POINT_START_RADIUS_M", "START_SPREAD_RAD", "START_TOLERANCE_M",
           "TURN_DROPS", "Window", "corner_start", "explained", "family_starts", "starts",
           "turned_start"]
