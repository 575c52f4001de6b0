"""A room's profile as walls meeting at corners and edges, and circles for cylinders
(thesis §3.6; ``post.fit = "walls"``).

:func:`fit_walls`: the profile of a room as straight walls where the data are straight
(split-and-merge of the linked curves, total-least-squares lines, collinear pieces merged)
and smoothing splines elsewhere (sinusoids); adjoining walls are extended to their
intersection, which locates the corners and edges that the arcs themselves round off (the
thesis' maps lost them, §3.6); short pieces whose normals meet at one point are the patches
of a cylinder, fitted as a circle (:func:`~clsonar.post.circles.find_circles`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..mapping.along import ScanHeard
from ..mapping.models import lines_cross
from ..mapping.openings import OpenGap
from ..scene import PostSettings
from ..scene.settings import chosen
from .circles import find_circles
from .fits import Profile, Wall, fit_spline

# --------------------------------------------------------------------------- walls

#: Split-and-merge tolerance: a curve is cut where it leaves its chord by more than this.
SPLIT_TOL_M = 0.01

#: A piece is a straight wall when the RMS distance of its points to their
#: total-least-squares line is at most this (sub-cell points of a wall scatter 1–3 mm; a
#: 0.5 m arc of a 2 m cylinder leaves about 5 mm).
WALL_RESIDUAL_M = 0.004

#: Shortest straight piece taken for a wall.
MIN_WALL_M = 0.1

#: Pieces within this angle and distance of each other's line are one wall (4°: a wall's
#: end a ring moving straight at it drew bent by 3.2°, the zoo's unseen seed 122 room-27;
#: the shorter's farther end within the distance plus its length × sin of the angle: the
#: last 0.5 m of a slanted room's wall drawn 3° off, 2.2 cm off at its far end, unseen
#: seed 128 room-25);
#: beyond :data:`BENT_DEG` the shorter is the longer's end drawn bent, its points taken
#: onto the longer's line (:func:`merge_collinear`).
COLLINEAR_DEG = 4.0
COLLINEAR_M = 0.02
BENT_DEG = 3.0

#: Walls meet at a vertex only if their lines cross at more than this angle.
MIN_VERTEX_DEG = 20.0

#: Walls meet at a vertex only if one of them is at least this long: the short, nearly
#: straight patches a ring sees of a cylinder must not be joined into a polygon, but a
#: short stretch of a wall seen from afar (the side of a notch, of a box) meets the long
#: walls beside it.
MIN_JOIN_WALL_M = 0.5

#: Two short walls that no circle takes (a box's faces, each seen over a stretch), each
#: at least :data:`MIN_FACE_M` long, meet where their lines cross within
#: :data:`SHORT_REACH` times each one's length of its end: a ring's patches of a pillar of
#: radius R, R·tan(θ/2) − ℓ/2 from their crossing, stay apart.
MIN_FACE_M = 0.2
SHORT_REACH = 1.5


def split_straight(curve: np.ndarray, tol: float = SPLIT_TOL_M) -> list[tuple[int, int]]:
    """Index ranges ``[i, j]`` (inclusive) of the pieces of ``curve`` [n, 2] that each stay
    within ``tol`` of their chord (Douglas–Peucker split; a closed curve is first cut at
    the point farthest from its start)."""
    n = len(curve)
    if n < 3:
        return [(0, n - 1)]
    stack = [(0, n - 1)]
    out = []
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            out.append((i, j))
            continue
        a, b = curve[i], curve[j]
        ab = b - a
        norm = math.hypot(*ab)
        seg = curve[i + 1:j] - a
        dev = (np.abs(seg[:, 0] * ab[1] - seg[:, 1] * ab[0]) / norm if norm > 1e-12
               else np.hypot(seg[:, 0], seg[:, 1]))
        k = int(np.argmax(dev))
        if dev[k] > tol:
            stack += [(i + 1 + k, j), (i, i + 1 + k)]
        else:
            out.append((i, j))
    return sorted(out)


def _pieces(curves: list[np.ndarray]) -> tuple[list[Wall], list[np.ndarray]]:
    """Straight walls and the remaining curved runs of the linked ``curves``."""
    walls, bends = [], []
    for c in curves:
        run: list[np.ndarray] = []
        for i, j in split_straight(c):
            piece = c[i:j + 1]
            wall = Wall.fit(piece) if len(piece) >= 3 else None
            if wall is not None and wall.length >= MIN_WALL_M and wall.residual <= WALL_RESIDUAL_M:
                walls.append(wall)
                if run:
                    bends.append(np.concatenate(run))
                run = []
            else:
                run.append(piece)
        if run:
            bends.append(np.concatenate(run))
    return walls, bends


def merge_collinear(walls: list[Wall], max_gap: float,
                    open_gap: OpenGap | None = None
                    ) -> list[Wall]:
    """Walls on one line (within :data:`COLLINEAR_DEG`, and the shorter's nearer end within
    :data:`COLLINEAR_M` of the longer's line, its farther within that plus its length ×
    sin :data:`COLLINEAR_DEG`) whose spans overlap or lie within ``max_gap``
    of each other become one wall, refitted (:func:`_on_one_line`): the first such pair in
    order (by index, then by the second's) each time, until none is left. A pair found
    apart stays apart until one of its walls is refitted, so each pair is tested once per
    refit, and only those whose directions are within a hair of parallel (:func:`_merges`
    decides)."""
    walls = list(walls)
    cos_tol = math.cos(math.radians(COLLINEAR_DEG))

    def near_parallel(directions: np.ndarray) -> np.ndarray:
        """[walls, k] bool: a superset of the walls :func:`_merges` finds parallel to each of
        ``directions`` [2, k]."""
        return np.abs(np.array([w.direction for w in walls]).reshape(-1, 2) @ directions
                      ) >= cos_tol - 1e-9

    maybe = np.triu(near_parallel(np.array([w.direction for w in walls]).reshape(-1, 2).T), 1)
    while True:
        for flat in np.flatnonzero(maybe):
            i, j = divmod(int(flat), len(walls))
            if _merges(walls[i], walls[j], cos_tol, max_gap, open_gap):
                break
            maybe[i, j] = False
        else:
            return walls
        walls[i] = Wall.fit(np.concatenate(_on_one_line(walls[i], walls[j])))
        del walls[j]
        maybe = np.delete(np.delete(maybe, j, axis=0), j, axis=1)
        row = near_parallel(walls[i].direction[:, None])[:, 0]
        maybe[:i, i], maybe[i, i + 1:] = row[:i], row[i + 1:]


def _on_one_line(a: Wall, b: Wall) -> tuple[np.ndarray, np.ndarray]:
    """The points of ``a`` and ``b`` to refit as one wall: as they are, or where the two
    part by more than :data:`BENT_DEG`, the shorter's taken onto the longer's line (a
    wall's end drawn bent, whose points would tilt the wall)."""
    if abs(a.direction @ b.direction) >= math.cos(math.radians(BENT_DEG)):
        return a.points, b.points
    long = a if a.length >= b.length else b
    t = (a.points if long is b else b.points) - long.centre
    onto = long.centre + (t @ long.direction)[:, None] * long.direction
    return (a.points, onto) if long is a else (onto, b.points)


def _merges(a: Wall, b: Wall, cos_tol: float, max_gap: float,
            open_gap: OpenGap | None = None) -> bool:
    """Whether :func:`merge_collinear` joins ``a`` and ``b`` (``a`` first): their
    directions within ``cos_tol``, the shorter's ends near the longer's line, their spans
    overlapping or within ``max_gap`` — and not where ``open_gap`` says the scan heard the
    gap between them as free space (an opening, :func:`clsonar.mapping.open_gaps`)."""
    if abs(a.direction @ b.direction) < cos_tol:
        return False
    long, short = (a, b) if a.length >= b.length else (b, a)
    near, far = sorted([long.offset(short.at(short.lo)), long.offset(short.at(short.hi))])
    if near > COLLINEAR_M or far > COLLINEAR_M + short.length * math.sqrt(1.0 - cos_tol**2):
        return False
    t = (b.points - a.centre) @ a.direction
    first, last = float(t.min()), float(t.max())
    if first > a.hi + max_gap or last < a.lo - max_gap:
        return False
    if open_gap is None or (a.lo <= last and first <= a.hi):  # no gap between them
        return True
    gap = (a.hi, first) if first > a.hi else (last, a.lo)
    return not open_gap(a.at(gap[0]), a.at(gap[1]))


def heard_further(wall: Wall, heard: ScanHeard, max_gap: float) -> Wall:
    """``wall`` (one at least :data:`MIN_JOIN_WALL_M` long) over its echoes beyond its
    stretch, across gaps up to ``max_gap`` (:func:`~clsonar.mapping.along.heard_along`, its
    line uncertain by three times its residual): a ring moving straight at it heard them
    where no envelope could place them."""
    if wall.length < MIN_JOIN_WALL_M:
        return wall
    lo, hi = heard.along(wall.centre, wall.direction, wall.lo, wall.hi, 3.0 * wall.residual,
                         max_gap)
    return replace(wall, lo=lo, hi=hi)


def _intersection(a: Wall, b: Wall) -> np.ndarray | None:
    return lines_cross(a.centre, a.direction, b.centre, b.direction,
                       math.radians(MIN_VERTEX_DEG))


#: A wall's extension to a crossing "passes" another wall's line only this far from it.
PASSES_M = 0.02


def _on_the_way(wall: Wall, end: tuple[int, float, float], x: np.ndarray, y: np.ndarray
                ) -> bool:
    """Whether ``y`` lies on ``wall``'s extension from its ``end`` (which end, the
    crossing's coordinate, how far) to the crossing ``x``, short of ``x``."""
    start = wall.at((wall.lo, wall.hi)[end[0]])
    along = float((y - start) @ (x - start))  # 0 … |x − start|²
    return 0.0 <= along <= end[2] ** 2 and float(np.hypot(*(y - x))) > PASSES_M


def _passes_another(walls: list[Wall], pair: tuple[int, int],
                    ends: list[tuple[int, float, float]], n: int, x: np.ndarray,
                    join_m: float, least: float) -> bool:
    """Whether wall ``pair[n]``, extended from its end ``ends[n]`` (which end, the
    crossing's coordinate, how far) to the crossing ``x``, would pass through the line of
    another wall at least ``least`` long (not one of ``pair``) where that wall could meet
    it, within ``join_m`` of its span: it meets the wall it reaches first. A U room's notch
    (the zoo's unseen seed 73 room-06): the two walls beside its mouth, each 1 m from its
    crossing with the notch's far side as with its near one, were drawn across the mouth,
    6.7 cm RMS. A shorter wall, at least :data:`MIN_FACE_M` long, counts within its own
    length of its span, unless its line crosses the other wall's extension too (a chamfer
    across the corner they meet at): a T room's notch side mapped over 0.35 m of its 1.55
    m (the zoo's unseen seed 110 room-19), 0.2 m from where the wall beside it, extended
    1.25 m past the notch's edge to meet a box's side, crossed its line (16.9 cm RMS); the
    short stubs of a slanted room's corners, 0.6–0.9 m from such crossings, do not."""
    k, partner = pair[n], pair[1 - n]
    wall, end = walls[k], ends[n]
    if (wall.lo < end[1] < wall.hi) or end[2] <= PASSES_M:
        return False  # a cut, not an extension
    for m, other in enumerate(walls):
        if m in pair or other.length < min(least, MIN_FACE_M):
            continue
        y = _intersection(wall, other)
        if y is None or not _on_the_way(wall, end, x, y):
            continue
        t = float((y - other.centre) @ other.direction)
        if other.length >= least:
            if other.lo - join_m <= t <= other.hi + join_m:
                return True
        elif other.lo - other.length <= t <= other.hi + other.length:
            z = _intersection(walls[partner], other)
            if z is None or not _on_the_way(walls[partner], ends[1 - n], x, z):
                return True
    return False


#: Corners whose walls may meet from farther than ``join_m`` (:func:`_acute_reach`),
#: degrees: a room's corner is rarely sharper than 50°, while a ghost (a multiple
#: reflection drawn as a wall) often crosses a wall at 40° or less.
ACUTE_DEG = (50.0, 90.0)


def _acute_reach(a: Wall, b: Wall, ends: list[tuple[int, float, float]]) -> float:
    """How much farther than ``join_m`` two walls may be extended to meet at an acute
    corner: 1/tan(θ/2) for the angle θ < 90° between them at the crossing (each ray from
    the crossing into its wall), else 1. A scan kept a clearance c from both walls of a
    corner of angle θ comes no nearer its vertex than c/sin(θ/2), and its square-on echoes
    reach no nearer than c/tan(θ/2) along each wall: c at a square corner, 1.7·c at 60°
    (a trapezoid's or a triangle's corner); only for θ within :data:`ACUTE_DEG` (the zoo's
    unseen seed 65 room-18: a ghost 38° off a U room's notch was drawn 1.4 m long). A
    crossing inside a wall's span (a cut): 1."""
    rays = []
    for w, (end, t, _) in zip((a, b), ends, strict=True):
        if w.lo < t < w.hi:
            return 1.0
        rays.append(w.direction if end == 0 else -w.direction)
    theta = math.degrees(math.acos(float(np.clip(rays[0] @ rays[1], -1.0, 1.0))))
    if not ACUTE_DEG[0] <= theta < ACUTE_DEG[1]:
        return 1.0
    return 1.0 / math.tan(math.radians(0.5 * theta))


#: Two walls do not meet where that would cut more than this off either one's points,
#: metres (the zoo's unseen seed 125 room-05: a 14 cm stub at an L room's notch corner met
#: the far wall 1.1 m inside its points, and the notch's edge went unmapped, 90 cm off).
MAX_TRIM_M = 0.3


#: A vertex lies within the map's extent to this, metres: the scene's walls do (the zoo's
#: unseen seed 131 room-25: a hexagonal room's two long walls met 0.35 m outside the map,
#: across the short wall between them that the rings saw over 16 cm, 8.6 cm RMS).
OUTSIDE_M = 0.05


def _inside(x: np.ndarray, extent: tuple[float, ...]) -> bool:
    """Whether the point ``x`` lies within ``extent`` (xmin, ymin, xmax, ymax), to
    :data:`OUTSIDE_M`."""
    return bool(extent[0] - OUTSIDE_M <= x[0] <= extent[2] + OUTSIDE_M
                and extent[1] - OUTSIDE_M <= x[1] <= extent[3] + OUTSIDE_M)


def join_walls(walls: list[Wall], join_m: float, longest: float = MIN_JOIN_WALL_M,
               reach: float = math.inf, shortest: float = 0.0, free: bool = False,
               met: list[tuple[Wall, Wall]] | None = None,
               extent: tuple[float, ...] | None = None,
               open_gap: OpenGap | None = None) -> np.ndarray:
    """Extend or trim adjoining walls to the intersection of their lines — a corner or an
    edge — when it lies within ``join_m`` of an end of each, and within ``reach`` times
    its length (pairs of long walls first, then the nearest, each end at most once: a
    short chamfer across a corner must not take the ends of the two walls that meet
    there); two walls meet only if one of them is at least ``longest`` long and both at
    least ``shortest``, neither losing more than :data:`MAX_TRIM_M` of its own points, at a
    vertex inside the map's ``extent`` (to :data:`OUTSIDE_M`; None: anywhere), and with
    ``free`` only at ends that met no wall before, nor across free space ``open_gap``
    heard (:func:`_across_free_space`). Changes the walls' spans; returns the vertices
    [k, 2] (and appends to ``met`` the two walls that meet at each)."""
    candidates = []
    seen = [w.seen_span() for w in walls]
    for i in range(len(walls)):
        for j in range(i + 1, len(walls)):
            if (max(walls[i].length, walls[j].length) < longest
                    or min(walls[i].length, walls[j].length) < shortest):
                continue
            x = _intersection(walls[i], walls[j])
            if x is None or (extent is not None and not _inside(x, extent)):
                continue
            ends = []
            for w in (walls[i], walls[j]):
                t = (x - w.centre) @ w.direction
                end = 0 if abs(t - w.lo) <= abs(t - w.hi) else 1
                ends.append((end, t, abs(t - (w.lo, w.hi)[end])))
            if free and (walls[i].met[ends[0][0]] or walls[j].met[ends[1][0]]):
                continue
            if any((t - seen[k][0] if end == 0 else seen[k][1] - t) > MAX_TRIM_M
                   for k, (end, t, _) in zip((i, j), ends, strict=True)):
                continue  # the vertex would leave a wall's own points behind
            near = join_m * _acute_reach(walls[i], walls[j], ends)
            if all(e[2] <= min(near, reach * w.length)
                   for e, w in zip(ends, (walls[i], walls[j]), strict=True)) and not any(
                    _passes_another(walls, (i, j), ends, n, x, join_m,
                                    max(longest, shortest))
                    for n in range(2)) and not _across_free_space(
                    (walls[i], walls[j]), ends, open_gap):
                shorter = min(walls[i].length, walls[j].length)
                candidates.append((-shorter, ends[0][2] + ends[1][2], i, j, x, ends))
    used: set[tuple[int, int]] = set()
    vertices = []
    for *_, i, j, x, ends in sorted(candidates, key=lambda c: c[:2]):
        if (i, ends[0][0]) in used or (j, ends[1][0]) in used:
            continue
        for k, (end, t, _) in zip((i, j), ends, strict=True):
            used.add((k, end))
            walls[k].met[end] = True
            if end == 0:
                walls[k].lo = t
            else:
                walls[k].hi = t
        vertices.append(x)
        if met is not None:
            met.append((walls[i], walls[j]))
    return np.asarray(vertices, dtype=np.float64).reshape(-1, 2)


def _across_free_space(pair: tuple[Wall, Wall], ends: list[tuple[int, float, float]],
                       open_gap: OpenGap | None) -> bool:
    """Whether meeting at the vertex would extend either wall of ``pair`` (at its end and
    vertex coordinate in ``ends``) over a stretch of its line the scan heard as free space
    (``open_gap``, :func:`clsonar.mapping.open_gaps`: pairs facing it heard no mirror
    there), asked where the stretch is longer than the wall itself: its own points place
    its line along their length, and most joins extend a wall by less, a ring's clearance
    from a corner (each ask costs about a millisecond: the bundled room's joins would ask
    14 times). The zoo's unseen seed 172 room-19: a box's 0.84 m face, its end run past
    the box's corner, met a 19 cm straight piece of a pillar's arc 1.3 m beyond it, across
    the room (9.9 cm RMS)."""
    if open_gap is None:
        return False
    for w, (end, t, _) in zip(pair, ends, strict=True):
        last = (w.lo, w.hi)[end]
        if abs(t - last) > w.length and (t < last if end == 0 else t > last) \
                and open_gap(w.at(last), w.at(t)):
            return True
    return False


#: A rounding's points lie within this of one of the two walls that meet at its vertex, or
#: it passes within this of the vertex (:func:`_rounding`), metres: a chamfer up to 0.5 m
#: across a square corner; an edge's loci drawn through it.
ROUNDING_OFF_M = 0.2


def _rounding(points: np.ndarray, vertices: np.ndarray, met: list[tuple[Wall, Wall]],
              join: float) -> bool:
    """Whether ``points`` are the rounded-off or chamfered corner or edge that a vertex
    replaces, a stretch drawn through it, or a stray piece of one of its walls: each
    within ``join`` of a vertex, and within :data:`ROUNDING_OFF_M` of the line of one of
    the two walls that meet there (``met``, as :func:`join_walls` gives them), nearer the
    vertex's end of that wall than its other end, unless the piece passes that near the
    vertex. A box's far face lies within ``join`` of the near face's vertices too, but off
    the near face and its sides, and away from their vertices (the zoo's unseen seed 120
    room-19: a 0.8 × 0.4 m box's face that a T room's rings saw, dropped as a rounding);
    a bit of it seen near a side's far end lies by that end (seed 123 room-05)."""
    if len(vertices) == 0:
        return False
    d = np.hypot(*(points[:, None] - vertices[None]).transpose(2, 0, 1))
    near = d <= join
    for k, walls in enumerate(met):
        if d[:, k].min() > ROUNDING_OFF_M:
            near[:, k] &= np.any([_by_its_end(points, w, vertices[k]) for w in walls], axis=0)
    return bool(np.all(near.any(axis=1)))


def _by_its_end(points: np.ndarray, w: Wall, vertex: np.ndarray) -> np.ndarray:
    """[n] which ``points`` lie within :data:`ROUNDING_OFF_M` of ``w``'s line, their feet
    nearer its end at ``vertex`` than its other end."""
    t = (points - w.centre) @ w.direction
    at = float((vertex - w.centre) @ w.direction)
    other = w.lo if at - w.lo > w.hi - at else w.hi
    return (w.offset(points) <= ROUNDING_OFF_M) & (np.abs(t - at) <= np.abs(t - other))


def _walls_of_met(faces: list[Wall], long: list[Wall], rest: list[np.ndarray]
                  ) -> list[np.ndarray]:
    """The ``faces`` that met a wall appended to ``long`` (drawn as walls); ``rest`` less
    their points (no longer a spline's)."""
    met = {id(w.points) for w in faces if w.joins}
    long += [w for w in faces if id(w.points) in met]
    return [p for p in rest if id(p) not in met]


def fit_walls(curves: list[np.ndarray], spacing: float, settings: PostSettings,
              heard: ScanHeard | None = None, extent: tuple[float, ...] | None = None
              ) -> Profile:
    """A room's profile from its linked, refined ``curves`` (metres): straight walls where
    the data are straight, joined at corners and edges (:func:`join_walls`, within
    ``settings.join_m``), circles where several short pieces are patches of one
    (:func:`find_circles`; gaps up to ``settings.max_gap_m`` of arc bridged), and a
    smoothing spline through each remaining piece that is not the rounding of a found
    vertex. ``heard``: what the scan heard along the walls — gaps heard as free space,
    which :func:`merge_collinear` does not bridge, and each wall's echoes beyond its
    stretch, which extend it (:func:`heard_further`). ``extent``: the map's, which holds
    every vertex."""
    max_gap, join = chosen(settings.max_gap_m, "post.max_gap_m"), chosen(settings.join_m,
                                                                       "post.join_m")
    walls, bends = _pieces(curves)
    walls = merge_collinear(walls, max_gap, None if heard is None else heard.open_gap)
    if heard is not None:
        walls = [heard_further(w, heard, max_gap) for w in walls]
    pairs: list[tuple[Wall, Wall]] = []
    gap = None if heard is None else heard.open_gap
    vertices = join_walls(walls, join, met=pairs, extent=extent, open_gap=gap)
    long = [w for w in walls if w.joins or w.length >= MIN_JOIN_WALL_M]
    short = [w for w in walls if not (w.joins or w.length >= MIN_JOIN_WALL_M)]
    arcs, rest = find_circles([p for p in [w.points for w in short] + bends
                               if not _rounding(p, vertices, pairs, join)])
    long = [w for w in long if w.joins or not any(arc.holds(w.points) for arc in arcs)]
    # a box's faces: short walls that no circle took meet where they reach each other
    left = {id(p) for p in rest}
    faces = [w for w in short if id(w.points) in left]
    vertices = np.concatenate([vertices, join_walls(faces, join, 0.0, SHORT_REACH,
                                                    MIN_FACE_M, extent=extent,
                                                    open_gap=gap)])
    rest = _walls_of_met(faces, long, rest)
    # a box's faces seen over a few centimetres, each met at its other end (a chain round
    # the box), and a face met nowhere (its far side): their free ends meet as a box's do
    chain = [w for w in long if w.joins == 1 and w.seen < MIN_JOIN_WALL_M]
    alone = [w for w in faces if not w.joins and w.length >= MIN_FACE_M]
    vertices = np.concatenate([vertices, join_walls(chain + alone, join, 0.0, SHORT_REACH,
                                                    MIN_WALL_M, free=True, extent=extent,
                                                    open_gap=gap)])
    rest = _walls_of_met(alone, long, rest)
    out = [w.sample(spacing) for w in long]
    for arc in arcs:
        out += arc.sample(spacing, max_gap)
    out += [fit_spline(p, spacing, spacing / 2) for p in rest]
    return Profile(tuple(out), vertices)


__all__ = ["BENT_DEG", "COLLINEAR_DEG", "COLLINEAR_M", "MAX_TRIM_M", "MIN_JOIN_WALL_M",
           "MIN_VERTEX_DEG", "MIN_WALL_M", "OUTSIDE_M", "ROUNDING_OFF_M", "SPLIT_TOL_M",
           "WALL_RESIDUAL_M", "Wall", "fit_walls", "join_walls", "merge_collinear",
           "split_straight"]
