"""Rings of transducers (thesis §2.1.2): one ring standing still (``circular``), or moved
along the walls (``wall-following``) on the curve at ``clearance_m`` from the surfaces."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

from .. import steps
from ..errors import SceneError
from ..geometry import Geometry, SurfaceSets, nearest_distances, nearest_surface_point, nearest_xy
from ..scene import Circular, Scene, WallFollowing
from .headings import pose_headings
from .space import (
    NearestOne,
    Placed,
    crosses,
    crosses_each,
    extent_contains,
    in_free_space,
    placement_error,
)


def ring(center: tuple[float, float], radius_m: float, elements: int,
         start_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions [n, 2] and outward headings [n] of a ring of ``elements`` transducers at
    equal angles from ``start_deg`` (thesis §2.1.2: 8 at 45° on a 6.5 cm radius)."""
    headings = start_deg + 360.0 * np.arange(elements) / elements
    h = np.radians(headings)
    pos = np.asarray(center, dtype=np.float64) + radius_m * np.stack([np.cos(h), np.sin(h)], -1)
    return pos, headings


def place_circular(p: Circular) -> Placed:
    """One ring, one group: (positions, headings_deg, group index per element, poses)."""
    pos, head = ring(p.center, p.radius_m, p.elements, p.start_deg)
    return pos, head, np.zeros(p.elements, dtype=np.int64), np.asarray([p.center], float)


# --------------------------------------------------------------------------- wall following

#: Angular samples of the circle searched for the next point of the wall-following trace.
_SWEEP_SAMPLES = 72

#: A traced point counts as on the offset curve within this distance (metres).
_ON_CURVE_TOL = 1e-6


def wall_following_substep(p: WallFollowing) -> float:
    """Length of one trace sub-step: ``min(clearance/4, step/4, 2 cm)``."""
    return min(p.clearance_m / 4.0, p.step_m / 4.0, 0.02)


def _project(geom: Geometry, point: np.ndarray, c: float
             ) -> tuple[np.ndarray, float, np.ndarray]:
    """Move ``point`` to distance ``c`` from the nearest surface, along the line from the
    nearest surface point; repeat while another surface becomes the nearest (concave
    corners). Returns the point, its final distance error and its nearest surface point
    (:func:`_projects` of one)."""
    out, err, q = _projects(SurfaceSets.of([geom]), np.asarray(point, float)[None],
                            np.array([c]))
    return out[0], float(err[0]), q[0]


def _projects(surfaces: SurfaceSets, points: np.ndarray, c: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_project` of ``points[b]`` [B, 2] onto the curve at ``c[b]`` from scene b of
    ``surfaces``, side by side: the points, their distance errors and nearest surface
    points, each point moved until it is on its curve (16 moves at most). x and y apart
    (:func:`~clsonar.geometry.nearest_xy`), every row measured at once until one must
    move (a sub-step's point is mostly on its curve at once)."""
    points = np.asarray(points, dtype=np.float64)
    x, y = points[:, 0].copy(), points[:, 1].copy()
    err, qx, qy = np.full(len(x), math.inf), x.copy(), y.copy()
    live: np.ndarray | None = None  # None: every row
    sets, c_live = surfaces, c
    for _ in range(16):
        px, py = (x, y) if live is None else (x[live], y[live])
        d, nx, ny = (v[:, 0] for v in nearest_xy(sets, px[:, None], py[:, None]))
        off = np.abs(d - c_live)
        if live is None:
            err[:], qx[:], qy[:] = off, nx, ny
        else:
            err[live], qx[live], qy[live] = off, nx, ny
        off = ~((off <= _ON_CURVE_TOL * 0.01) | ~np.isfinite(d) | (d <= 1e-12))
        if not off.any():
            break
        live = np.flatnonzero(off) if live is None else live[off]
        scale = c_live[off] / d[off]
        x[live] = nx[off] + (px[off] - nx[off]) * scale
        y[live] = ny[off] + (py[off] - ny[off]) * scale
        sets, c_live = surfaces.take(live), c[live]
    return np.stack([x, y], axis=-1), err, np.stack([qx, qy], axis=-1)


def wall_following_path(p: WallFollowing, scene: Scene, geom: Geometry
                        ) -> tuple[np.ndarray, np.ndarray, float]:
    """Trace the curve the ring centre follows (thesis §2.1.2, generalised).

    The curve is the set of free points at distance ``p.clearance_m`` from the nearest
    surface, on the side of ``p.start``. The start is projected onto it (from the nearest
    surface point Q, along Q→start, to distance ``clearance_m``). From each traced point P
    the next is the first point at distance h (one sub-step, :func:`wall_following_substep`)
    from P that is back at the clearance, found by sweeping the circle of radius h around P
    from the direction of the nearest surface: counter-clockwise for ``ccw``, which keeps the
    nearest surface on the right of the motion (a room outline is then run counter-clockwise
    and an obstacle clockwise), clockwise for ``cw`` (surface on the left). The found point
    is re-projected onto the curve. Along a straight wall this moves parallel to it, at a
    concave corner the nearest wall changes and the path turns, around a convex edge or a
    cylinder the nearest point is the vertex (the circle) and the path arcs around it. (The
    thesis picks the moving direction "by comparing the vertical and horizontal distances";
    following the nearest surface does the same in axis-aligned rooms and also works along
    oblique walls, edges and cylinders.)

    The trace stops when a sub-step passes within h/2 of the start after having been more
    than 2h away from it.

    Returns ``(path [M, 2], arc [M], length)``: the traced points (the start first), their
    arc length from the start (sum of sub-step chords), and the length of the closed curve.
    Raises :class:`SceneError` (key ``sensors.placement``) when the start is not in free
    space, the curve cannot be followed (no room for the clearance, stuck), it would leave
    the extent or cross a surface, or it does not close within ``max_poses`` poses.
    """
    found = wall_following_paths([(p, scene, geom)])[0]
    if isinstance(found, SceneError):
        raise found
    return found


#: One wall-following trace to run: its placement, scene and geometry.
TraceJob = tuple[WallFollowing, Scene, Geometry]

#: A finished trace: ``(path [M, 2], arc [M], length)`` (:func:`wall_following_path`).
Traced = tuple[np.ndarray, np.ndarray, float]


@dataclass
class _Trace:
    """One wall-following trace as :func:`wall_following_paths` runs it: its constants,
    its points so far (the start first) and its sub-steps' pending checks."""

    c: float  # clearance
    h: float  # sub-step
    sweep: np.ndarray  # the angles swept from the nearest surface's direction
    fail: Callable[[str], SceneError]
    checks: _SubstepChecks
    max_length: float
    max_substeps: int
    path: list[np.ndarray]
    arc: list[float]
    wall: np.ndarray  # the nearest surface point of the start
    max_poses: int  # for the message of a trace that does not close
    step_m: float

    def unclosed(self) -> SceneError:
        """The error of a trace that has not closed within its ``max_poses``."""
        self.checks.flush()
        return self.fail(f"the trace did not return to its start within max_poses = "
                         f"{self.max_poses} poses (step_m = {self.step_m:g}); raise max_poses "
                         "or check the start")


def _start_trace(p: WallFollowing, scene: Scene, geom: Geometry) -> _Trace:
    """The trace of ``p`` at its start (:func:`_trace_start`; its errors raised)."""
    c, h = p.clearance_m, wall_following_substep(p)

    def fail(message: str) -> SceneError:
        return placement_error(scene, "wall-following: " + message)

    p0, wall = _trace_start(p, scene, geom, fail)
    sign = 1.0 if p.direction == "ccw" else -1.0
    max_length = (p.max_poses + 1) * p.step_m
    return _Trace(c=c, h=h,
                  sweep=sign * 2.0 * math.pi * np.arange(1, _SWEEP_SAMPLES + 1) / _SWEEP_SAMPLES,
                  fail=fail, checks=_SubstepChecks(scene, geom, fail), max_length=max_length,
                  max_substeps=int(max_length / (0.25 * h)) + 100, path=[p0], arc=[0.0],
                  wall=wall, max_poses=p.max_poses, step_m=p.step_m)


@dataclass
class _Going:
    """The traces still going, side by side (row k is trace ``ids[k]``): where each is,
    its nearest surface point, whether it has been more than 2h from its start, and its
    constants as arrays."""

    ids: np.ndarray  # [L] indices of the traces
    surfaces: SurfaceSets
    point: np.ndarray  # [L, 2]
    wall: np.ndarray  # [L, 2]
    left: np.ndarray  # [L] bool
    p0: np.ndarray  # [L, 2]
    h: np.ndarray  # [L]
    c: np.ndarray  # [L]
    sweep: np.ndarray  # [L, S]

    @classmethod
    def start(cls, traces: dict[int, _Trace], surfaces: SurfaceSets) -> _Going:
        """The ``traces`` (by index) at their starts, scene b of ``surfaces`` the b-th."""
        t = list(traces.values())
        p0 = np.array([x.path[0] for x in t]).reshape(-1, 2)
        return cls(np.array(list(traces), dtype=np.int64), surfaces, p0,
                   np.array([x.wall for x in t]).reshape(-1, 2), np.zeros(len(t), bool), p0,
                   np.array([x.h for x in t]), np.array([x.c for x in t]),
                   np.array([x.sweep for x in t]).reshape(len(t), _SWEEP_SAMPLES))

    def take(self, rows: np.ndarray) -> _Going:
        return _Going(self.ids[rows], self.surfaces.take(rows), self.point[rows],
                      self.wall[rows], self.left[rows], self.p0[rows], self.h[rows],
                      self.c[rows], self.sweep[rows])


def wall_following_paths(jobs: list[TraceJob]) -> list[Traced | SceneError]:
    """:func:`wall_following_path` of every job, the traces run side by side (one set of
    array operations per sub-step for all of them: the rooms of a floor): each trace's
    ``(path, arc, length)``, or the error it raises alone. Each sub-step is the same
    arithmetic as one trace alone, so the paths are the same to the bit."""
    out: list[Traced | SceneError | None] = [None] * len(jobs)
    traces: dict[int, _Trace] = {}
    for i, (p, scene, geom) in enumerate(jobs):
        try:
            traces[i] = _start_trace(p, scene, geom)
        except SceneError as error:
            out[i] = error
    if len(traces) == 1:  # one trace: its sub-steps in floats (_trace_alone)
        (i, trace), = traces.items()
        try:
            out[i] = _trace_alone(trace, jobs[i][2])
        except SceneError as error:
            out[i] = error
        return [r for r in out if r is not None]
    going = _Going.start(traces, SurfaceSets.of([jobs[i][2] for i in traces]))
    while len(going.ids):
        steps.poll()
        going = _advance(going, traces, out)
    return [r for r in out if r is not None]


def _advance(going: _Going, traces: dict[int, _Trace],
             out: list[Traced | SceneError | None]) -> _Going:
    """One sub-step of every trace still going: each one that closes or fails gets its
    result in ``out``; the rest go on (returned)."""
    nxt, near, step, stuck = _substeps(going, [traces[int(i)] for i in going.ids])
    p0, h = going.p0, going.h
    # the exact closing test only where the sub-step can pass within h/2 of the start
    may_close = going.left & (np.hypot(*(going.point - p0).T) <= step + 0.5 * h + 1e-9)
    left = going.left | (np.hypot(*(nxt - p0).T) > 2.0 * h)
    keep = np.ones(len(going.ids), dtype=bool)
    for k, i in enumerate(going.ids.tolist()):
        trace = traces[i]
        try:
            if stuck[k] is not None:
                trace.checks.flush()  # a sub-step that failed its checks before is first
                raise cast(SceneError, stuck[k])
            trace.checks.add(going.point[k], nxt[k])
            if may_close[k] and (t := _closing(p0[k], going.point[k], nxt[k], float(step[k]),
                                               float(h[k]))) is not None:
                trace.checks.flush()
                out[i] = (np.asarray(trace.path), np.asarray(trace.arc),
                          trace.arc[-1] + t * float(step[k]))
                keep[k] = False
                continue
            trace.path.append(nxt[k])
            trace.arc.append(trace.arc[-1] + float(step[k]))
            if trace.arc[-1] > trace.max_length or len(trace.path) > trace.max_substeps:
                raise trace.unclosed()
        except SceneError as error:
            out[i] = error
            keep[k] = False
    going = _Going(going.ids, going.surfaces, nxt, near, left, p0, h, going.c, going.sweep)
    return going if keep.all() else going.take(np.flatnonzero(keep))


#: Sweep samples of the circle evaluated first (:func:`_substeps`): along a wall the next
#: point is the 18th; the rest of the circle only where some trace turns farther.
FIRST_SAMPLES = 24


def _substeps(going: _Going, traces: list[_Trace]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[SceneError | None]]:
    """One sub-step of each trace going from its last point: the first point back at its
    clearance c on the circle of radius h swept from the direction of its nearest surface,
    re-projected onto the curve. ``(points [L, 2], their nearest surface points, the
    steps' lengths [L], each trace's error or None)``.

    The circle's samples are measured :data:`FIRST_SAMPLES` first, the rest only where
    some trace finds none of those back at its clearance: each sample's clearance is its
    own arithmetic whatever others are measured with it, so the first found and the one
    before it are those of the whole circle, to the bit."""
    point, h, c = going.point, going.h, going.c
    to_wall = going.wall - point
    phi0 = np.array([math.atan2(y, x) for x, y in to_wall.tolist()])
    angles = phi0[:, None] + going.sweep[:, :FIRST_SAMPLES]
    g = _clearances(going, angles)
    ahead = g >= 0.0
    if not ahead.any(axis=1).all():
        rest = phi0[:, None] + going.sweep[:, FIRST_SAMPLES:]
        angles = np.concatenate([angles, rest], axis=1)
        g = np.concatenate([g, _clearances(going, rest)], axis=1)
        ahead = g >= 0.0
    k = np.argmax(ahead, axis=1)
    rows = np.arange(len(point))
    found = ahead[rows, k]  # some sample back at the clearance
    g_k, a_k = g[rows, k], angles[rows, k]
    if k.all():  # the sample before the first found is on the circle
        g_prev, a_prev = g[rows, k - 1], angles[rows, k - 1]
    else:  # before the first sample: the nearest surface's direction, a clearance of -h
        first = k > 0
        g_prev = np.where(first, g[rows, k - 1], -h)
        a_prev = np.where(first, angles[rows, k - 1], phi0)
    same = g_k == g_prev
    frac = np.where(same, 1.0, g_prev / np.where(same, 1.0, g_prev - g_k))
    a = (a_prev + frac * (a_k - a_prev)).tolist()
    turn = np.array([[math.cos(x), math.sin(x)] for x in a]).reshape(-1, 2)
    nxt, err, near = _projects(going.surfaces, point + h[:, None] * turn, c)
    step = np.hypot(*(nxt - point).T)
    errors: list[SceneError | None] = [None] * len(point)
    for b in np.flatnonzero(~found | (err > _ON_CURVE_TOL) | (step < 0.25 * h)):
        x, y = point[b]
        errors[b] = traces[b].fail(
            f"stuck at ({x:.3f}, {y:.3f}): no way on at clearance_m = {c[b]:g}"
            if not found[b] else
            f"stuck at ({x:.3f}, {y:.3f}): the curve at clearance_m = {c[b]:g} cannot be "
            "followed there")
    return nxt, near, step, errors


def _clearances(going: _Going, angles: np.ndarray) -> np.ndarray:
    """[L, S] how far beyond its clearance c each point of the circle of radius h around
    each trace's point, at ``angles`` [L, S], lies from the trace's surfaces."""
    h = going.h[:, None]
    x = going.point[:, 0, None] + h * np.cos(angles)
    y = going.point[:, 1, None] + h * np.sin(angles)
    return nearest_distances(going.surfaces, x, y) - going.c[:, None]


def _trace_alone(trace: _Trace, geom: Geometry) -> Traced:
    """The one trace of :func:`wall_following_paths` (its result; its error raised): the
    sub-steps of :func:`_advance` and :func:`_substeps` with a trace's scalars as Python
    floats — the same IEEE operations, math's atan2, cos and sin where those use them and
    numpy's hypot where they use numpy's (math.hypot rounds otherwise) — and only the
    circle's samples and the projection's distances as arrays: a third of their array
    operations, the same path to the bit."""
    surfaces, h = (SurfaceSets.of([geom]), NearestOne(geom)), trace.h
    (x0, y0), (wx, wy) = trace.path[0].tolist(), trace.wall.tolist()
    x, y, left = x0, y0, False
    while True:
        steps.poll()
        stuck, nx, ny, wx, wy = _substep_alone(surfaces, trace, x, y, wx, wy)
        step, back, gone = np.hypot([nx - x, x - x0, nx - x0], [ny - y, y - y0, ny - y0]).tolist()
        if stuck is None and step < 0.25 * h:
            stuck = _stuck(trace, x, y, True)
        if stuck is not None:
            trace.checks.flush()  # a sub-step that failed its checks before is first
            raise stuck
        trace.checks.add(np.array([x, y]), np.array([nx, ny]))
        if left and back <= step + 0.5 * h + 1e-9 and (t := _closing(
                trace.path[0], np.array([x, y]), np.array([nx, ny]), step, h)) is not None:
            trace.checks.flush()
            return np.asarray(trace.path), np.asarray(trace.arc), trace.arc[-1] + t * step
        left = left or gone > 2.0 * h
        trace.path.append(np.array([nx, ny]))
        trace.arc.append(trace.arc[-1] + step)
        if trace.arc[-1] > trace.max_length or len(trace.path) > trace.max_substeps:
            raise trace.unclosed()
        x, y = nx, ny


def _substep_alone(both: tuple[SurfaceSets, NearestOne], trace: _Trace, x: float, y: float,
                   wx: float, wy: float) -> tuple[SceneError | None, float, float, float, float]:
    """:func:`_substeps` of the one trace at ``(x, y)``, its nearest surface point
    ``(wx, wy)``, its scene's surfaces ``both`` ways: ``(its error or None, the next
    point, its nearest surface point)`` (the step's length checked by the caller)."""
    (surfaces, one), c, h = both, trace.c, trace.h
    phi0 = math.atan2(wy - y, wx - x)
    angles = phi0 + trace.sweep[:FIRST_SAMPLES]
    g = _clearances_alone(surfaces, x, y, h, c, angles)
    k = int(np.argmax(g >= 0.0))
    if not g[k] >= 0.0:
        angles = np.concatenate([angles, phi0 + trace.sweep[FIRST_SAMPLES:]])
        g = np.concatenate([g, _clearances_alone(surfaces, x, y, h, c,
                                                 angles[FIRST_SAMPLES:])])
        k = int(np.argmax(g >= 0.0))
    if not g[k] >= 0.0:
        return _stuck(trace, x, y, False), x, y, wx, wy
    g_k, a_k = float(g[k]), float(angles[k])
    g_prev, a_prev = (float(g[k - 1]), float(angles[k - 1])) if k else (-h, phi0)
    frac = 1.0 if g_k == g_prev else g_prev / (g_prev - g_k)
    a = a_prev + frac * (a_k - a_prev)
    nx, ny, err, wx, wy = _project_alone(surfaces, one, x + h * math.cos(a),
                                         y + h * math.sin(a), c)
    return (_stuck(trace, x, y, True) if err > _ON_CURVE_TOL else None), nx, ny, wx, wy


def _clearances_alone(surfaces: SurfaceSets, x: float, y: float, h: float, c: float,
                      angles: np.ndarray) -> np.ndarray:
    """[S] :func:`_clearances` of the one trace at ``(x, y)``."""
    return nearest_distances(surfaces, (x + h * np.cos(angles))[None],
                             (y + h * np.sin(angles))[None])[0] - c


def _project_alone(surfaces: SurfaceSets, one: NearestOne, x: float, y: float, c: float
                   ) -> tuple[float, float, float, float, float]:
    """:func:`_projects` of the one point ``(x, y)``: ``(x, y, error, nearest x, y)``
    (its distances by ``one`` where it is usable)."""
    err = qx = qy = math.inf
    for _ in range(16):
        d, qx, qy = one(x, y) if one.usable else (
            float(v[0, 0]) for v in nearest_xy(surfaces, np.array([[x]]), np.array([[y]])))
        err = abs(d - c)
        if err <= _ON_CURVE_TOL * 0.01 or not math.isfinite(d) or d <= 1e-12:
            break
        x, y = qx + (x - qx) * (c / d), qy + (y - qy) * (c / d)
    return x, y, err, qx, qy


def _stuck(trace: _Trace, x: float, y: float, found: bool) -> SceneError:
    """The error of a trace stuck at ``(x, y)``: ``found`` a point back at its clearance
    on the circle, which the curve does not follow (else no way on)."""
    return trace.fail(
        f"stuck at ({x:.3f}, {y:.3f}): the curve at clearance_m = {trace.c:g} cannot be "
        "followed there" if found else
        f"stuck at ({x:.3f}, {y:.3f}): no way on at clearance_m = {trace.c:g}")


def _closing(p0: np.ndarray, point: np.ndarray, nxt: np.ndarray, step: float, h: float
             ) -> float | None:
    """Where (as a share of the sub-step) the sub-step ``point`` → ``nxt`` of length
    ``step`` passes within h/2 of the trace's start ``p0``; None if it does not."""
    t = float(np.clip(np.dot(p0 - point, nxt - point) / (step * step), 0.0, 1.0))
    return t if np.hypot(*(point + t * (nxt - point) - p0)) <= 0.5 * h else None


#: Sub-steps of the trace checked together (:class:`_SubstepChecks`).
CHECK_BATCH = 64


class _SubstepChecks:
    """The trace's sub-steps, each checked not to cross a surface nor leave the extent
    (:func:`_check_substeps`), :data:`CHECK_BATCH` at a time: one vectorised check in
    place of one per sub-step (a third of the trace's time), the same first error. The
    trace must :meth:`flush` before it returns or fails."""

    def __init__(self, scene: Scene, geom: Geometry, fail: Callable[[str], SceneError]) -> None:
        self.scene, self.geom, self.fail = scene, geom, fail
        self.starts: list[np.ndarray] = []
        self.ends: list[np.ndarray] = []

    def add(self, point: np.ndarray, nxt: np.ndarray) -> None:
        self.starts.append(point)
        self.ends.append(nxt)
        if len(self.starts) >= CHECK_BATCH:
            self.flush()

    def flush(self) -> None:
        if self.starts:
            starts, ends = np.asarray(self.starts), np.asarray(self.ends)
            self.starts, self.ends = [], []
            _check_substeps(self.scene, self.geom, starts, ends, self.fail)


def _check_substeps(scene: Scene, geom: Geometry, points: np.ndarray, nxt: np.ndarray,
                    fail: Callable[[str], SceneError]) -> None:
    """Fail at the first sub-step ``points[i]`` → ``nxt[i]`` that crosses a surface or
    leaves the extent."""
    crossing = crosses_each(geom, points, nxt)
    bad = np.flatnonzero(crossing | ~extent_contains(scene, nxt))
    if len(bad) == 0:
        return
    i = int(bad[0])
    if crossing[i]:
        raise fail(f"the trace would cross a surface near ({points[i, 0]:.3f}, "
                   f"{points[i, 1]:.3f})")
    raise fail(f"the trace left the extent at ({nxt[i, 0]:.3f}, {nxt[i, 1]:.3f}) before "
               "closing: wall-following needs a closed room or an obstacle inside "
               "the extent")


def _trace_start(p: WallFollowing, scene: Scene, geom: Geometry,
                 fail: Callable[[str], SceneError]) -> tuple[np.ndarray, np.ndarray]:
    """The first point of the wall-following trace (``p.start`` projected onto the curve at
    ``clearance_m``) and its nearest surface point; ``fail`` makes the error of a start
    that cannot be used."""
    c = p.clearance_m
    start = np.asarray(p.start, dtype=np.float64)
    if len(geom.occluders) == 0 and len(geom.circles) == 0:
        raise fail("the scene has no surface to follow")
    if not (extent_contains(scene, start)[0] and in_free_space(scene, geom, start)[0]):
        raise fail(f"start ({start[0]:g}, {start[1]:g}) is not in free space inside the extent")
    dist, near = nearest_surface_point(geom, start[None])
    if dist[0] <= 1e-9:
        raise fail(f"start ({start[0]:g}, {start[1]:g}) lies on a surface")
    p0, err, wall = _project(geom, near[0] + (start - near[0]) * (c / dist[0]), c)
    if err > _ON_CURVE_TOL:
        raise fail(f"no place at clearance_m = {c:g} from the surfaces near the start "
                   f"({start[0]:g}, {start[1]:g})")
    if crosses(geom, start, p0) or not in_free_space(scene, geom, p0)[0]:
        raise fail(f"the start ({start[0]:g}, {start[1]:g}) cannot reach the curve at "
                   f"clearance_m = {c:g} without crossing a surface")
    if not extent_contains(scene, p0)[0]:
        raise fail(f"the trace start ({p0[0]:.3f}, {p0[1]:.3f}) is outside the extent")
    return p0, wall


def place_wall_following(p: WallFollowing, scene: Scene, geom: Geometry,
                         traced: Traced | None = None) -> Placed:
    """Ring poses along the walls, thesis §2.1.2 (see :class:`~clsonar.scene.WallFollowing`).

    The ring centre runs along :func:`wall_following_path`; a pose every ``step_m`` of arc
    length, the first at the projected start, the last the last one before the trace is back
    at the start (a pose closer than half a sub-step to the start is dropped). Each pose is
    a :func:`ring` and its own pair group, its first element at ``start_deg`` or, where
    the file leaves that out, square to the walls (:func:`~.headings.pose_headings`: one
    heading for every pose where the walls share one, else each pose square to its
    nearest wall).

    Returns ``(positions [G·n, 2], headings_deg, groups, poses [G, 2])``. ``traced``: the
    trace, when already run (:func:`wall_following_paths`).
    """
    if p.radius_m >= p.clearance_m:
        raise placement_error(scene, f"ring radius_m = {p.radius_m:g} must be smaller than "
                                     f"clearance_m = {p.clearance_m:g}",
                              "sensors.placement.radius_m")
    path, arc, length = wall_following_path(p, scene, geom) if traced is None else traced
    h = wall_following_substep(p)
    targets = np.arange(0.0, length - 0.5 * h, p.step_m)
    if len(targets) > p.max_poses:
        raise placement_error(scene, f"wall-following: {len(targets)} poses needed, more than "
                                     f"max_poses = {p.max_poses}")
    closed_path = np.concatenate([path, path[:1]])
    closed_arc = np.append(arc, length)
    centres, surfaces, one = [], SurfaceSets.of([geom]), NearestOne(geom)
    for s in targets:
        i = min(int(np.searchsorted(closed_arc, s, side="right")) - 1, len(path) - 1)
        seg = closed_arc[i + 1] - closed_arc[i]
        t = (s - closed_arc[i]) / seg if seg > 0 else 0.0
        gx, gy = (closed_path[i] + t * (closed_path[i + 1] - closed_path[i])).tolist()
        centres.append(_project_alone(surfaces, one, gx, gy, p.clearance_m)[:2])  # _project
    poses = np.asarray(centres).reshape(-1, 2)
    starts = (pose_headings(geom, poses, p.elements) if p.start_deg is None
              else np.full(len(poses), p.start_deg))
    pos, head = [], []
    for centre, start_deg in zip(poses, starts.tolist(), strict=True):
        rp, rh = ring(tuple(centre), p.radius_m, p.elements, start_deg)
        pos.append(rp)
        head.append(rh)
    groups = np.repeat(np.arange(len(poses), dtype=np.int64), p.elements)
    return (np.concatenate(pos), np.concatenate(head), groups, poses)
