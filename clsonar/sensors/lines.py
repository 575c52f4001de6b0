"""Linear arrays laid along lines: ``random-lines`` (thesis §2.1, §3.1) and the per-wall
scan of a closed room (§3.6, Figs 3.21–3.22), which fills one such line along each wall."""

from __future__ import annotations

import math

import numpy as np

from ..errors import SceneError
from ..geometry import Geometry, nearest_surface_point
from ..scene import PerWall, RandomLines, Scene, per_wall_surface_problem
from .space import Placed, crosses_each, extent_contains, in_free_space, placement_error


def place_random_lines(p: RandomLines, scene: Scene, geom: Geometry) -> Placed:
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
        along, centre = _next_array(p, rng, array, centre)
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
        raise placement_error(scene, f"placement placed no transducer: the first element at "
                                     f"({start[0]:.3f}, {start[1]:.3f}) is {reason}")
    return (np.asarray(positions).reshape(-1, 2), np.asarray(headings, dtype=np.float64),
            np.asarray(groups, dtype=np.int64), np.zeros((0, 2)))


def _next_array(p: RandomLines, rng: np.random.Generator, array: int,
                centre: float) -> tuple[np.ndarray, float]:
    """Positions along the line of the elements of array number ``array`` (the first at 0,
    the next after the array centred at ``centre``), and its centre: spacings uniform in
    ``spacing_m``, the centres of consecutive arrays ``uniform(separation_m)`` apart."""
    offsets = np.r_[0.0, np.cumsum(rng.uniform(*p.spacing_m, size=p.elements - 1))]
    half = 0.5 * offsets[-1]
    first = 0.0 if array == 0 else centre + rng.uniform(*p.separation_m) - half
    return first + offsets, first + half


def _random_lines_stops(p: RandomLines, scene: Scene, geom: Geometry, points: np.ndarray,
                        prev: np.ndarray | None, along: np.ndarray) -> list[str]:
    """For each of an array's candidate ``points`` (``along`` the line, in order, each
    following the one before it and the first ``prev``): why it would end the placement,
    or ``""`` (the checks of all the array's elements at once)."""
    inside = extent_contains(scene, points)
    free = in_free_space(scene, geom, points)
    dist, _ = nearest_surface_point(geom, points)
    before = np.concatenate([[prev if prev is not None else points[0]], points[:-1]])
    behind = crosses_each(geom, before, points)
    if prev is None:
        behind[0] = False
    reasons = []
    for i, s in enumerate(along):
        if s > p.length_m:
            reasons.append(f"beyond length_m = {p.length_m:g} along the line")
        elif not inside[i]:
            reasons.append("outside the extent")
        elif not free[i]:
            reasons.append("inside a solid (outside the room, inside a box or a cylinder)")
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
    raise placement_error(scene, "placement placed no transducer: no random start in free "
                                 f"space at least clearance_m = {p.clearance_m:g} from every "
                                 "surface was found in 1000 draws; give sensors.placement.start")


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
        raise placement_error(scene, problem, "sensors.placement.surface")
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


def place_per_wall(p: PerWall, scene: Scene, geom: Geometry) -> Placed:
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
        raise placement_error(scene, f"per-wall placed no transducer: no wall of surfaces"
                                     f"[{p.surface}] has room for an array at distance_m = "
                                     f"{p.distance_m:g} (distance_step_m = "
                                     f"{p.distance_step_m:g}) on its free side")
    g = np.concatenate(groups)
    positions = np.concatenate(pos)
    poses = np.asarray([0.5 * (positions[g == k][0] + positions[g == k][-1])
                        for k in range(first)])
    return positions, np.concatenate(head), g, poses.reshape(-1, 2)
