"""Transducers of a scene and the transmitter→receiver pairs that fire (thesis §2.1, §2.1.2).

The sensors of a scene are its explicit ``sensors.transducers`` (in file order) followed by
those its ``sensors.placement`` places; indices into :class:`SensorArray` are the ``tx`` and
``rx`` of the echo table. Every transducer belongs to a *group*: one linear array of
``random-lines`` or ``per-wall``, one ring of ``circular``, one pose of ``wall-following``; explicit
transducers keep their ``group`` key. Placed groups are numbered after the explicit ones.

Which pairs fire (:func:`pairs`): every transducer transmits in turn and every transducer of
its own group receives, so a group of n transducers gives n² ordered pairs (T, R), T = R
included (the line-of-sight echo of thesis §2.1.1 part 1; T ≠ R the elliptical echoes of
part 2). Transducers of different groups never pair: the arrays and the ring poses fire at
different times. (T, R) and (R, T) travel the same paths, but their received signals carry
independent noise, so both are kept.

Placements (each returns ``(positions [n, 2], headings_deg [n], group per element [n] int64
from 0, poses [G, 2])``): :func:`place_random_lines` (thesis §2.1, §3.1),
:func:`place_circular` and :func:`place_wall_following` (§2.1.2, traced by
:func:`wall_following_path`), :func:`place_per_wall` (§3.6, Figs 3.21–3.22). They are
deterministic: random numbers come only from the
placement's ``seed``. A placement that cannot be made raises
:class:`~clsonar.errors.SceneError` with key ``sensors.placement`` and the scene's name as
source.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .errors import SceneError
from .geometry import Geometry, build_geometry, nearest_surface_point, ray_distance
from .scene import (
    Circular,
    PerWall,
    Polyline,
    RandomLines,
    Scene,
    WallFollowing,
    per_wall_surface_problem,
)


@dataclass(frozen=True, eq=False)
class SensorArray:
    """All transducers of a scene, as arrays (float64)."""

    positions: np.ndarray  # [N, 2] metres
    headings_deg: np.ndarray  # [N] direction of each transducer's axis, degrees from +x
    groups: np.ndarray  # [N] int64 pair group
    poses: np.ndarray  # [G, 2] ring centres (circular, wall-following) or array centres
    # (per-wall); none for random-lines

    def __len__(self) -> int:
        return len(self.positions)

    @cached_property
    def fired_pairs(self) -> np.ndarray:
        """[P, 2] the pairs that fire (:func:`pairs`), computed once, read-only."""
        out = _fired_pairs(self)
        out.flags.writeable = False
        return out

    @property
    def axes(self) -> np.ndarray:
        """[N, 2] unit vectors along each transducer's axis."""
        h = np.radians(self.headings_deg)
        return np.stack([np.cos(h), np.sin(h)], axis=-1)


def ring(center: tuple[float, float], radius_m: float, elements: int,
         start_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions [n, 2] and outward headings [n] of a ring of ``elements`` transducers at
    equal angles from ``start_deg`` (thesis §2.1.2: 8 at 45° on a 6.5 cm radius)."""
    headings = start_deg + 360.0 * np.arange(elements) / elements
    h = np.radians(headings)
    pos = np.asarray(center, dtype=np.float64) + radius_m * np.stack([np.cos(h), np.sin(h)], -1)
    return pos, headings


def place_circular(p: Circular) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One ring, one group: (positions, headings_deg, group index per element, poses)."""
    pos, head = ring(p.center, p.radius_m, p.elements, p.start_deg)
    return pos, head, np.zeros(p.elements, dtype=np.int64), np.asarray([p.center], float)


def _extent_contains(scene: Scene, pts: np.ndarray) -> np.ndarray:
    xmin, ymin, xmax, ymax = scene.extent
    p = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    return (p[:, 0] >= xmin) & (p[:, 0] <= xmax) & (p[:, 1] >= ymin) & (p[:, 1] <= ymax)


def in_free_space(scene: Scene, geom: Geometry, points: np.ndarray) -> np.ndarray:
    """[M] bool: which ``points`` lie in free space (not inside a cylinder, and inside a
    closed polyline when the scene has any: a room's outside is solid). Points exactly on a
    surface count as free; callers keep a clearance anyway."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    free = np.ones(len(p), dtype=bool)
    if len(geom.circles):
        v = p[:, None] - geom.circles[None, :, :2]
        free &= ~np.any(np.hypot(v[..., 0], v[..., 1]) < geom.circles[None, :, 2], axis=1)
    rooms = [np.asarray(s.points, dtype=np.float64) for s in scene.surfaces
             if isinstance(s, Polyline) and s.closed]
    if rooms:
        free &= np.any([_inside_polygon(r, p) for r in rooms], axis=0)
    return free


def _inside_polygon(poly: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Even-odd rule: [M] bool, ``p`` [M, 2] strictly inside the closed polygon [K, 2]."""
    a = poly[None, :, :]
    b = np.roll(poly, -1, axis=0)[None, :, :]
    x, y = p[:, None, 0], p[:, None, 1]
    straddle = (a[..., 1] > y) != (b[..., 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    return (np.count_nonzero(straddle & (x < xc), axis=1) % 2) == 1


def _crosses(geom: Geometry, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment ``a``→``b`` meets a surface."""
    return bool(_crosses_each(geom, np.asarray(a)[None], np.asarray(b)[None])[0])


def _crosses_each(geom: Geometry, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """[n] bool: whether each segment ``a[i]``→``b[i]`` meets a surface."""
    d = b - a
    length = np.array([math.hypot(x, y) for x, y in d])
    hit = np.zeros(len(d), dtype=bool)
    some = length > 0.0
    if some.any():
        ray = ray_distance(geom, a[some], d[some] / length[some, None])
        hit[some] = ray <= length[some]
    return hit


def _placement_error(scene: Scene, message: str, key: str = "sensors.placement") -> SceneError:
    return SceneError(message, key=key, source=scene.name)


# --------------------------------------------------------------------------- random lines


def place_random_lines(p: RandomLines, scene: Scene, geom: Geometry):
    """Linear arrays of thesis §2.1 and §3.1 (see :class:`~clsonar.scene.RandomLines`).

    Elements are placed one after another along the line from ``p.start`` in direction
    ``p.direction_deg``: the first element at the start, each next element of an array
    ``uniform(spacing_m)`` further on; the centre of the next array lies
    ``uniform(separation_m)`` beyond the centre of the previous one (thesis §2.1:
    "separations of the centers of the transducer arrays vary between 50 cm and 165 cm"), so
    arrays longer than their separation interleave, and a 10 m line holds the thesis' 100
    transducers. Each heading is ``facing_deg + uniform(±heading_spread_deg)`` (the thesis'
    "random orientations between 0° and 180°" is ``facing ± 90°``). Placement ends for good
    ("the localization process is terminated", §2.1) at the first element that would lie
    beyond ``length_m`` along the line, outside the extent, outside free space, within
    ``clearance_m`` of a surface, or behind a surface as seen from the previous element;
    what was placed is kept, a partly filled last array included. Each array is one pair
    group (0, 1, …).

    With ``start`` null the start is drawn inside the extent, retrying (up to 1000 draws)
    until it is in free space and at least ``clearance_m`` from every surface. All random
    numbers come from ``numpy.random.default_rng(p.seed)``, so a scene always gives the
    same placement.

    Returns ``(positions [n, 2], headings_deg [n], groups [n] int64, poses [0, 2])``.
    Raises :class:`SceneError` (key ``sensors.placement``) if nothing could be placed.
    """
    rng = np.random.default_rng(p.seed)
    if p.start is None:
        start = _random_start(p, scene, geom, rng)
    else:
        start = np.asarray(p.start, dtype=np.float64)
    angle = math.radians(p.direction_deg)
    u = np.array([math.cos(angle), math.sin(angle)])

    positions: list[np.ndarray] = []
    headings: list[float] = []
    groups: list[int] = []
    prev: np.ndarray | None = None
    reason = ""
    array = 0
    centre = 0.0
    while not reason:
        offsets = np.r_[0.0, np.cumsum(rng.uniform(*p.spacing_m, size=p.elements - 1))]
        half = 0.5 * offsets[-1]
        first = 0.0 if array == 0 else centre + rng.uniform(*p.separation_m) - half
        centre = first + half
        along = first + offsets
        points = start + along[:, None] * u
        reasons = _random_lines_stops(p, scene, geom, points, prev, along)
        for point, reason in zip(points, reasons, strict=True):
            if reason:
                break
            positions.append(point)
            headings.append(p.facing_deg + rng.uniform(-p.heading_spread_deg,
                                                       p.heading_spread_deg))
            groups.append(array)
            prev = point
        array += 1
    if not positions:
        raise _placement_error(scene, f"placement placed no transducer: the first element at "
                                      f"({start[0]:.3f}, {start[1]:.3f}) is {reason}")
    return (np.asarray(positions).reshape(-1, 2), np.asarray(headings, dtype=np.float64),
            np.asarray(groups, dtype=np.int64), np.zeros((0, 2)))


def _random_lines_stops(p: RandomLines, scene: Scene, geom: Geometry, points: np.ndarray,
                        prev: np.ndarray | None, along: np.ndarray) -> list[str]:
    """For each of an array's candidate ``points`` (``along`` the line, in order, each
    following the one before it and the first ``prev``): why it would end the placement,
    or ``""`` (the checks of all the array's elements at once)."""
    inside = _extent_contains(scene, points)
    free = in_free_space(scene, geom, points)
    dist, _ = nearest_surface_point(geom, points)
    before = np.concatenate([[prev if prev is not None else points[0]], points[:-1]])
    behind = _crosses_each(geom, before, points)
    if prev is None:
        behind[0] = False
    reasons = []
    for i, s in enumerate(along):
        if s > p.length_m:
            reasons.append(f"beyond length_m = {p.length_m:g} along the line")
        elif not inside[i]:
            reasons.append("outside the extent")
        elif not free[i]:
            reasons.append("inside a solid (outside the room or inside a cylinder)")
        elif dist[i] < p.clearance_m:
            reasons.append(f"within clearance_m = {p.clearance_m:g} of a surface")
        elif behind[i]:
            reasons.append("behind a surface")
        else:
            reasons.append("")
    return reasons


def _random_start(p: RandomLines, scene: Scene, geom: Geometry,
                  rng: np.random.Generator) -> np.ndarray:
    xmin, ymin, xmax, ymax = scene.extent
    for _ in range(1000):
        point = np.array([rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)])
        if (in_free_space(scene, geom, point)[0]
                and nearest_surface_point(geom, point[None])[0][0] >= p.clearance_m):
            return point
    raise _placement_error(scene, "placement placed no transducer: no random start in free "
                                  f"space at least clearance_m = {p.clearance_m:g} from every "
                                  "surface was found in 1000 draws; give sensors.placement.start")


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
    corners). Returns the point, its final distance error and its nearest surface point."""
    err = math.inf
    q = point
    for _ in range(16):
        dist, near = nearest_surface_point(geom, point[None])
        d, q = float(dist[0]), near[0]
        err = abs(d - c)
        if err <= _ON_CURVE_TOL * 0.01 or not math.isfinite(d) or d <= 1e-12:
            break
        point = q + (point - q) * (c / d)
    return point, err, q


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
    c = p.clearance_m
    h = wall_following_substep(p)
    start = np.asarray(p.start, dtype=np.float64)

    def fail(message: str) -> SceneError:
        return _placement_error(scene, "wall-following: " + message)

    if len(geom.occluders) == 0 and len(geom.circles) == 0:
        raise fail("the scene has no surface to follow")
    if not (_extent_contains(scene, start)[0] and in_free_space(scene, geom, start)[0]):
        raise fail(f"start ({start[0]:g}, {start[1]:g}) is not in free space inside the extent")
    dist, near = nearest_surface_point(geom, start[None])
    if dist[0] <= 1e-9:
        raise fail(f"start ({start[0]:g}, {start[1]:g}) lies on a surface")
    p0, err, wall = _project(geom, near[0] + (start - near[0]) * (c / dist[0]), c)
    if err > _ON_CURVE_TOL:
        raise fail(f"no place at clearance_m = {c:g} from the surfaces near the start "
                   f"({start[0]:g}, {start[1]:g})")
    if _crosses(geom, start, p0) or not in_free_space(scene, geom, p0)[0]:
        raise fail(f"the start ({start[0]:g}, {start[1]:g}) cannot reach the curve at "
                   f"clearance_m = {c:g} without crossing a surface")
    if not _extent_contains(scene, p0)[0]:
        raise fail(f"the trace start ({p0[0]:.3f}, {p0[1]:.3f}) is outside the extent")

    sign = 1.0 if p.direction == "ccw" else -1.0
    sweep = sign * 2.0 * math.pi * np.arange(1, _SWEEP_SAMPLES + 1) / _SWEEP_SAMPLES
    max_length = (p.max_poses + 1) * p.step_m
    max_substeps = int(max_length / (0.25 * h)) + 100
    path = [p0]
    arc = [0.0]
    left = False
    point = p0
    for _ in range(max_substeps):
        to_wall = wall - point
        phi0 = math.atan2(to_wall[1], to_wall[0])
        angles = phi0 + sweep
        ring_pts = point + h * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
        g = nearest_surface_point(geom, ring_pts)[0] - c
        hit = np.flatnonzero(g >= 0.0)
        if len(hit) == 0:
            raise fail(f"stuck at ({point[0]:.3f}, {point[1]:.3f}): no way on at "
                       f"clearance_m = {c:g}")
        k = int(hit[0])
        g_prev = g[k - 1] if k > 0 else -h
        a_prev = angles[k - 1] if k > 0 else phi0
        frac = g_prev / (g_prev - g[k]) if g[k] != g_prev else 1.0
        a = a_prev + frac * (angles[k] - a_prev)
        nxt, err, next_wall = _project(geom, point + h * np.array([math.cos(a), math.sin(a)]), c)
        step = float(np.hypot(*(nxt - point)))
        if err > _ON_CURVE_TOL or step < 0.25 * h:
            raise fail(f"stuck at ({point[0]:.3f}, {point[1]:.3f}): the curve at "
                       f"clearance_m = {c:g} cannot be followed there")
        if _crosses(geom, point, nxt):
            raise fail(f"the trace would cross a surface near ({point[0]:.3f}, "
                       f"{point[1]:.3f})")
        if not _extent_contains(scene, nxt)[0]:
            raise fail(f"the trace left the extent at ({nxt[0]:.3f}, {nxt[1]:.3f}) before "
                       "closing: wall-following needs a closed room or an obstacle inside "
                       "the extent")
        if left:
            t = float(np.clip(np.dot(p0 - point, nxt - point) / (step * step), 0.0, 1.0))
            if np.hypot(*(point + t * (nxt - point) - p0)) <= 0.5 * h:
                length = arc[-1] + t * step
                return np.asarray(path), np.asarray(arc), length
        elif np.hypot(*(nxt - p0)) > 2.0 * h:
            left = True
        path.append(nxt)
        arc.append(arc[-1] + step)
        point, wall = nxt, next_wall
        if arc[-1] > max_length:
            break
    raise fail(f"the trace did not return to its start within max_poses = {p.max_poses} "
               f"poses (step_m = {p.step_m:g}); raise max_poses or check the start")


def place_wall_following(p: WallFollowing, scene: Scene, geom: Geometry):
    """Ring poses along the walls, thesis §2.1.2 (see :class:`~clsonar.scene.WallFollowing`).

    The ring centre runs along :func:`wall_following_path`; a pose every ``step_m`` of arc
    length, the first at the projected start, the last the last one before the trace is back
    at the start (a pose closer than half a sub-step to the start is dropped). Each pose is
    a :func:`ring` and its own pair group.

    Returns ``(positions [G·n, 2], headings_deg, groups, poses [G, 2])``.
    """
    if p.radius_m >= p.clearance_m:
        raise _placement_error(scene, f"ring radius_m = {p.radius_m:g} must be smaller than "
                                      f"clearance_m = {p.clearance_m:g}",
                               "sensors.placement.radius_m")
    path, arc, length = wall_following_path(p, scene, geom)
    h = wall_following_substep(p)
    targets = np.arange(0.0, length - 0.5 * h, p.step_m)
    if len(targets) > p.max_poses:
        raise _placement_error(scene, f"wall-following: {len(targets)} poses needed, more than "
                                      f"max_poses = {p.max_poses}")
    closed_path = np.concatenate([path, path[:1]])
    closed_arc = np.append(arc, length)
    centres = []
    for s in targets:
        i = min(int(np.searchsorted(closed_arc, s, side="right")) - 1, len(path) - 1)
        seg = closed_arc[i + 1] - closed_arc[i]
        t = (s - closed_arc[i]) / seg if seg > 0 else 0.0
        guess = closed_path[i] + t * (closed_path[i + 1] - closed_path[i])
        centres.append(_project(geom, guess, p.clearance_m)[0])
    poses = np.asarray(centres).reshape(-1, 2)
    pos, head = [], []
    for centre in poses:
        rp, rh = ring(tuple(centre), p.radius_m, p.elements, p.start_deg)
        pos.append(rp)
        head.append(rh)
    groups = np.repeat(np.arange(len(poses), dtype=np.int64), p.elements)
    return (np.concatenate(pos), np.concatenate(head), groups, poses)


# --------------------------------------------------------------------------- per wall


def per_wall_seed(seed: int, wall: int) -> int:
    """Seed of the :class:`~clsonar.scene.RandomLines` of wall ``wall`` of a per-wall
    placement: independent streams for every wall, all derived from the placement's seed."""
    return int(np.random.SeedSequence([seed, wall]).generate_state(1, np.uint64)[0])


def per_wall_lines(p: PerWall, scene: Scene, geom: Geometry) -> list[tuple[int, RandomLines]]:
    """The line of arrays of each scanned wall of a per-wall placement (thesis §3.6).

    For wall k (the k-th segment of the closed polyline ``surfaces[p.surface]``, from its
    point k to point k+1) at LoS distance ``d = p.distance_m + k·p.distance_step_m`` and
    margin ``m`` (``p.margin_m``, or d if null): a :class:`~clsonar.scene.RandomLines` that
    starts at distance ``m`` from the wall's first end, shifted by ``d`` along the wall's
    inward normal, runs ``length − 2m`` along the wall and faces the wall (the inward normal
    reversed), with seed :func:`per_wall_seed`. Walls with ``d ≤ 0`` or too short for the
    shortest possible array (``(elements − 1)·spacing_m[0]`` after the margins) are left
    out. Returns ``[(k, lines)]`` in outline order.
    """
    problem = per_wall_surface_problem(scene.surfaces, p.surface)
    if problem:
        raise _placement_error(scene, problem, "sensors.placement.surface")
    mine = np.flatnonzero(geom.wall_surface == p.surface)
    shortest = (p.elements - 1) * p.spacing_m[0]
    out = []
    for k, w in enumerate(mine):
        a, b = geom.walls[w, :2], geom.walls[w, 2:]
        inward = geom.wall_normal[w]
        length = float(np.hypot(*(b - a)))
        u = (b - a) / length
        distance = p.distance_m + k * p.distance_step_m
        margin = distance if p.margin_m is None else p.margin_m
        run = length - 2.0 * margin
        if distance <= 0.0 or run < shortest:
            continue
        start = a + margin * u + distance * inward
        out.append((k, RandomLines(
            seed=per_wall_seed(p.seed, k),
            start=(float(start[0]), float(start[1])),
            direction_deg=float(np.degrees(np.arctan2(u[1], u[0]))),
            length_m=run,
            elements=p.elements,
            spacing_m=p.spacing_m,
            separation_m=p.separation_m,
            facing_deg=float(np.degrees(np.arctan2(-inward[1], -inward[0]))),
            heading_spread_deg=p.heading_spread_deg,
            clearance_m=p.clearance_m,
        )))
    return out


def place_per_wall(p: PerWall, scene: Scene, geom: Geometry):
    """Per-wall scan of a closed room, thesis §3.6 (see :class:`~clsonar.scene.PerWall`).

    "In the room, each wall is scanned independently. […] Transducers are localized as in
    the previous simulations for each of the scanned walls of the room": every line of
    :func:`per_wall_lines` is filled by :func:`place_random_lines`, so it ends where that
    placement ends (its length, an element leaving free space, coming within
    ``clearance_m`` of a surface, or hidden behind one); a line whose first element cannot
    be placed is skipped. Walls are taken in outline order and every array stays its own
    pair group, numbered 0, 1, … over the whole room.

    Returns ``(positions [n, 2], headings_deg [n], groups [n] int64, poses [G, 2])`` with
    ``poses`` the centre of each array (the midpoint of its first and last element).
    Raises :class:`SceneError` (key ``sensors.placement``) if no wall gets a transducer.
    """
    pos: list[np.ndarray] = []
    head: list[np.ndarray] = []
    groups: list[np.ndarray] = []
    first = 0
    for _, line in per_wall_lines(p, scene, geom):
        try:
            wp, wh, wg, _ = place_random_lines(line, scene, geom)
        except SceneError:
            continue
        pos.append(wp)
        head.append(wh)
        groups.append(wg + first)
        first += int(wg.max()) + 1
    if not pos:
        raise _placement_error(scene, f"per-wall placed no transducer: no wall of surfaces"
                                      f"[{p.surface}] has room for an array at distance_m = "
                                      f"{p.distance_m:g} (distance_step_m = "
                                      f"{p.distance_step_m:g}) inside the room")
    g = np.concatenate(groups)
    positions = np.concatenate(pos)
    poses = np.asarray([0.5 * (positions[g == k][0] + positions[g == k][-1])
                        for k in range(first)])
    return positions, np.concatenate(head), g, poses.reshape(-1, 2)


def place_sensors(scene: Scene, geom: Geometry | None = None) -> SensorArray:
    """The scene's transducers: explicit ones first, in file order, then placed ones."""
    explicit = scene.sensors.transducers
    pos = np.asarray([t.position for t in explicit], dtype=np.float64).reshape(-1, 2)
    head = np.asarray([t.heading_deg for t in explicit], dtype=np.float64)
    groups = np.asarray([t.group for t in explicit], dtype=np.int64)
    poses = [np.zeros((0, 2))]
    placements = [p for p in (scene.sensors.placement, *scene.sensors.placements)
                  if p is not None]
    for placement in placements:
        if isinstance(placement, Circular):
            p_pos, p_head, p_group, p_poses = place_circular(placement)
        else:
            geom = geom if geom is not None else build_geometry(scene)
            if isinstance(placement, RandomLines):
                p_pos, p_head, p_group, p_poses = place_random_lines(placement, scene, geom)
            elif isinstance(placement, PerWall):
                p_pos, p_head, p_group, p_poses = place_per_wall(placement, scene, geom)
            else:
                p_pos, p_head, p_group, p_poses = place_wall_following(placement, scene, geom)
        first = int(groups.max()) + 1 if len(groups) else 0
        pos = np.concatenate([pos, p_pos])
        head = np.concatenate([head, p_head])
        groups = np.concatenate([groups, p_group + first])
        poses.append(np.asarray(p_poses, dtype=np.float64).reshape(-1, 2))
    return SensorArray(pos, head, groups, np.concatenate(poses))


def pairs(sensors: SensorArray) -> np.ndarray:
    """[P, 2] int64 ordered (tx, rx) pairs that fire: all pairs within each group, T = R
    included, sorted by tx then rx (see the module docstring). Computed once per array
    (read-only)."""
    return sensors.fired_pairs


def _fired_pairs(sensors: SensorArray) -> np.ndarray:
    g = sensors.groups
    if len(g) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    order = np.argsort(g, kind="stable")
    out = []
    bounds = np.flatnonzero(np.diff(g[order])) + 1
    for members in np.split(order, bounds):
        members = np.sort(members)
        tx, rx = np.meshgrid(members, members, indexing="ij")
        out.append(np.stack([tx.ravel(), rx.ravel()], axis=-1))
    result = np.concatenate(out)
    return result[np.lexsort((result[:, 1], result[:, 0]))]


def heading_deg(v: np.ndarray) -> np.ndarray:
    """Heading in degrees of direction vectors [..., 2]."""
    return np.degrees(np.arctan2(v[..., 1], v[..., 0]))


__all__ = ["SensorArray", "heading_deg", "in_free_space", "pairs", "per_wall_lines",
           "per_wall_seed", "place_circular", "place_per_wall", "place_random_lines",
           "place_sensors", "place_wall_following", "ring", "wall_following_path",
           "wall_following_substep"]
