"""Derived geometry of a scene: what the echo engine and the sensor placement need.

From a :class:`~clsonar.scene.Scene`'s surfaces this builds flat arrays (float64):

- **walls**: every segment of every polyline, with the unit normal of its *front* (free)
  side. A closed polyline is a room: only its interior side reflects — or a solid
  obstacle (a box, a pillar; :func:`~clsonar.outlines.solid_surfaces`): only its outside
  reflects. An open polyline is a thin wall: both sides reflect (``two_sided``).
- **vertices**: every polyline vertex, classified as seen from the left and from the right
  of the polyline's direction: ``corner`` (concave: the two walls enclose the observer,
  interior angle < 180°), ``edge`` (convex, > 180°), ``flat`` (collinear to 1e-9) or
  ``end`` (free end of an open polyline); the outside of a room and the inside of a solid
  obstacle are ``solid``.
- **diffractors**: the vertices that a free side sees as a convex ``edge``; a point sees
  one when it is not strictly inside the *solid cone*, the convex angle between the two
  walls at the vertex. Also the free ends inside the map (:func:`free_ends`): a thin
  wall's real end, a knife edge (its solid cone of angle 0, seen from everywhere); an end
  on or beyond the map's border is taken to continue beyond the map and diffracts
  nothing.
- **corner pairs**: pairs of walls meeting at a vertex that a free side sees as a concave
  corner (multi-bounce between them is labelled ``corner``).
- **corners**: those concave vertices with the unit normals of their two walls towards the
  concave side (the echo engine's double bounce through the vertex itself).
- **circles** ``(cx, cy, r)``: solid cylinders.
- **curves**: sinusoids, kept analytically ``(Fx, Fy, tx, ty, amplitude, ω, length)`` and
  sampled into intervals of at most ``min(echo.curve_step_m, period/32)`` along the base
  line (default ≤ 1 cm). The echo engine searches each interval for specular points; the
  chords between samples stand in for the curve when it occludes a path (the chord sags
  by at most ``κ·Δs²/8``, about 6 µm for the default scenes).
- **occluders**: walls followed by all curve chords; circles occlude analytically.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .numerics import union1d, unique
from .outlines import sensor_anchors, solid_surfaces
from .scene import Circle, Polyline, Scene, Sinusoid

#: Vertex kind codes (see the module docstring).
FLAT, CORNER, EDGE, END, SOLID = range(5)

#: Interior angles within this many radians of 180° count as ``flat``.
FLAT_TOLERANCE = 1e-9

#: A sinusoid is sampled at no fewer than this many intervals per period.
SAMPLES_PER_PERIOD = 32


@dataclass(frozen=True, eq=False)
class Geometry:
    walls: np.ndarray  # [S, 4] x0, y0, x1, y1
    wall_normal: np.ndarray  # [S, 2] unit normal towards the front side
    wall_two_sided: np.ndarray  # [S] bool
    wall_surface: np.ndarray  # [S] index into scene.surfaces
    vertices: np.ndarray  # [V, 2]
    vertex_walls: np.ndarray  # [V, 2] incoming and outgoing wall, -1 at a free end
    vertex_left: np.ndarray  # [V] kind code seen from the left of the polyline direction
    vertex_right: np.ndarray  # [V] kind code seen from the right
    diffractors: np.ndarray  # [D, 6] vertex x, y; unit vector to previous point; to next
    diffractor_vertex: np.ndarray  # [D] index into vertices
    corner_walls: np.ndarray  # [Q, 2] the two walls meeting at each concave corner
    corners: np.ndarray  # [Q, 6] vertex x, y; unit normals of both walls to the concave side
    corner_vertex: np.ndarray  # [Q] index into vertices
    circles: np.ndarray  # [C, 3]
    circle_surface: np.ndarray  # [C]
    curves: np.ndarray  # [K, 7] Fx, Fy, tx, ty, amplitude, omega, length
    curve_surface: np.ndarray  # [K]
    interval_curve: np.ndarray  # [I] index into curves
    interval_s: np.ndarray  # [I, 2] base-line parameters s0 < s1
    chord_start: np.ndarray  # [K] index of the curve's first chord in occluders
    surface_solid: np.ndarray  # [len(scene.surfaces)] bool: a closed polyline read as solid

    @cached_property
    def occluders(self) -> np.ndarray:
        """[O, 4] segments that block paths: the walls, then every curve chord."""
        if len(self.interval_s) == 0:
            return self.walls
        k = self.interval_curve
        a = curve_point(self.curves[k], self.interval_s[:, 0])
        b = curve_point(self.curves[k], self.interval_s[:, 1])
        return np.concatenate([self.walls, np.concatenate([a, b], axis=1)])

    @cached_property
    def occluder_frames(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The occluders as start points A [O, 2], directions B − A [O, 2] and their
        squared lengths [O] (what :func:`nearest_surface_point` projects onto, kept)."""
        a = self.occluders[:, :2]
        ab = self.occluders[:, 2:] - a
        return a, ab, ab[:, 0] * ab[:, 0] + ab[:, 1] * ab[:, 1]

    @property
    def curve_counts(self) -> np.ndarray:
        """Number of intervals (= chords) of each curve."""
        return np.bincount(self.interval_curve, minlength=len(self.curves))


@dataclass
class _PolylineParts:
    """Walls and vertices of a scene's polylines, gathered surface by surface."""

    walls: list[tuple[float, ...]] = field(default_factory=list)  # x0, y0, x1, y1
    normals: list[np.ndarray] = field(default_factory=list)
    two_sided: list[bool] = field(default_factory=list)
    owner: list[int] = field(default_factory=list)
    verts: list[np.ndarray] = field(default_factory=list)
    vwalls: list[tuple[int, int]] = field(default_factory=list)
    vleft: list[int] = field(default_factory=list)
    vright: list[int] = field(default_factory=list)


def build_geometry(scene: Scene) -> Geometry:
    """Derive the :class:`Geometry` of ``scene`` (see the module docstring)."""
    parts = _PolylineParts()
    solid = solid_surfaces(scene.surfaces, sensor_anchors(scene))
    for si, surface in enumerate(scene.surfaces):
        if isinstance(surface, Polyline):
            _add_polyline(surface, si, parts, solid[si])
    walls = np.asarray(parts.walls, dtype=np.float64).reshape(-1, 4)
    vertex_walls = np.asarray(parts.vwalls, dtype=np.int64).reshape(-1, 2)
    vertices = np.asarray(parts.verts, dtype=np.float64).reshape(-1, 2)
    left = np.asarray(parts.vleft, dtype=np.int8)
    right = np.asarray(parts.vright, dtype=np.int8)
    corner_idx = np.flatnonzero((left == CORNER) | (right == CORNER))
    corners = _corners(walls, vertices, vertex_walls, left, corner_idx)
    diff_idx = union1d(np.flatnonzero((left == EDGE) | (right == EDGE)),
                       free_ends(scene.extent, walls, vertices, vertex_walls))
    circles = [(s.center[0], s.center[1], s.radius) for s in scene.surfaces
               if isinstance(s, Circle)]
    circle_surface = [i for i, s in enumerate(scene.surfaces) if isinstance(s, Circle)]
    return Geometry(
        walls=walls, wall_normal=np.asarray(parts.normals, dtype=np.float64).reshape(-1, 2),
        wall_two_sided=np.asarray(parts.two_sided, dtype=np.bool_),
        wall_surface=np.asarray(parts.owner, dtype=np.int64),
        vertices=vertices, vertex_walls=vertex_walls,
        vertex_left=left, vertex_right=right,
        diffractors=_diffractors(walls, vertices, vertex_walls, diff_idx),
        diffractor_vertex=diff_idx.astype(np.int64),
        corner_walls=vertex_walls[corner_idx].reshape(-1, 2),
        corners=corners, corner_vertex=corner_idx.astype(np.int64),
        circles=np.asarray(circles, dtype=np.float64).reshape(-1, 3),
        circle_surface=np.asarray(circle_surface, dtype=np.int64),
        **_sinusoid_arrays(scene, len(walls)),
        surface_solid=np.asarray(solid, dtype=np.bool_).reshape(-1),
    )


def _corners(walls: np.ndarray, vertices: np.ndarray, vertex_walls: np.ndarray,
             left: np.ndarray, corner_idx: np.ndarray) -> np.ndarray:
    """``corners [Q, 6]`` of the concave vertices ``corner_idx`` (see :class:`Geometry`)."""
    corners = np.zeros((len(corner_idx), 6))
    for row, v in enumerate(corner_idx):
        a, b = vertex_walls[v]
        side = 1.0 if left[v] == CORNER else -1.0  # left normals point to the concave side?
        corners[row, :2] = vertices[v]
        for col, w in ((2, a), (4, b)):
            d = _unit(walls[w, 2:] - walls[w, :2])
            corners[row, col:col + 2] = side * np.array([-d[1], d[0]])
    return corners


def meet_at_corner(geom: Geometry, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether walls ``a`` and ``b`` (arrays of wall indices) meet at a concave corner, in
    either order (a sorted list of the corners' wall pairs, not an [S, S] matrix: a room
    drawn with 45,000 walls)."""
    n = len(geom.walls) + 1
    w = geom.corner_walls
    keys = unique(np.r_[w[:, 0] * n + w[:, 1], w[:, 1] * n + w[:, 0]])
    want = np.asarray(a, dtype=np.int64) * n + np.asarray(b, dtype=np.int64)
    at = np.minimum(np.searchsorted(keys, want), max(len(keys) - 1, 0))
    return (keys[at] == want) if len(keys) else np.zeros(want.shape, dtype=bool)


def _diffractors(walls: np.ndarray, vertices: np.ndarray, vertex_walls: np.ndarray,
                 diff_idx: np.ndarray) -> np.ndarray:
    """[D, 6] the convex vertices ``diff_idx``: the vertex, the unit vectors to the previous
    and to the next point of its polyline."""
    diffractors = np.zeros((len(diff_idx), 6))
    for row, v in enumerate(diff_idx):
        a, b = vertex_walls[v]
        p = vertices[v]
        diffractors[row, :2] = p
        # a free end's one wall is both faces of its knife edge
        diffractors[row, 2:4] = _unit(walls[a, :2] - p) if a >= 0 else _unit(walls[b, 2:] - p)
        diffractors[row, 4:6] = _unit(walls[b, 2:] - p) if b >= 0 else diffractors[row, 2:4]
    return diffractors


#: A free end this close to another wall (metres) is a junction, not an edge.
JUNCTION_M = 1e-3


def free_ends(extent: tuple[float, ...], walls: np.ndarray, vertices: np.ndarray,
              vertex_walls: np.ndarray) -> np.ndarray:
    """The free ends of open polylines that end inside the map: strictly inside
    ``extent`` and farther than :data:`JUNCTION_M` from every other wall. Such an end is a
    thin wall's real end, a knife edge (wedge index n = 2, :func:`~clsonar.physics.
    wedge_angles`) that diffracts; an end on or beyond the map's border is taken to
    continue beyond the map, and one on another wall (a partition's foot, a box drawn as
    an open polyline back to its start) is a junction."""
    ends = np.flatnonzero(np.any(vertex_walls < 0, axis=1))
    x, y = vertices[ends].T
    ends = ends[(x > extent[0]) & (x < extent[2]) & (y > extent[1]) & (y < extent[3])]
    a, d = walls[:, :2], walls[:, 2:] - walls[:, :2]
    q = vertices[ends][:, None]
    t = np.clip(np.sum((q - a) * d, -1) / np.maximum(np.sum(d * d, -1), 1e-300), 0.0, 1.0)
    apart = np.hypot(*(q - a - t[..., None] * d).transpose(2, 0, 1))
    apart[np.arange(len(ends)), vertex_walls[ends].max(axis=1)] = np.inf  # its own wall
    return ends[np.min(apart, axis=1, initial=np.inf) > JUNCTION_M]


def _sinusoid_arrays(scene: Scene, n_walls: int) -> dict[str, np.ndarray]:
    """The :class:`Geometry` fields of the scene's sinusoids (``curves`` … ``chord_start``);
    their chords follow the ``n_walls`` walls among the occluders."""
    curves: list[tuple[float, ...]] = []
    curve_surface: list[int] = []
    interval_curve: list[int] = []
    interval_s: list[tuple[float, float]] = []
    chord_start: list[int] = []
    for si, s in enumerate(scene.surfaces):
        if not isinstance(s, Sinusoid):
            continue
        params, s_edges = _sample_sinusoid(s, scene.echo.curve_step_m)
        chord_start.append(n_walls + len(interval_s))
        curve_surface.append(si)
        interval_curve.extend([len(curves)] * (len(s_edges) - 1))
        interval_s.extend(itertools.pairwise(s_edges))
        curves.append(params)
    return {
        "curves": np.asarray(curves, dtype=np.float64).reshape(-1, 7),
        "curve_surface": np.asarray(curve_surface, dtype=np.int64),
        "interval_curve": np.asarray(interval_curve, dtype=np.int64),
        "interval_s": np.asarray(interval_s, dtype=np.float64).reshape(-1, 2),
        "chord_start": np.asarray(chord_start, dtype=np.int64),
    }


def _unit(v: np.ndarray) -> np.ndarray:
    return v / math.hypot(v[0], v[1])


def _add_polyline(p: Polyline, si: int, parts: _PolylineParts, solid: bool = False) -> None:
    """Append the walls and vertices of polyline ``p`` (``scene.surfaces[si]``) to ``parts``;
    a closed ``p`` is a room (free inside) or, ``solid``, an obstacle (free outside)."""
    pts = np.asarray(p.points, dtype=np.float64)
    n = len(pts)
    # The left side of a counter-clockwise outline is its inside: free for a room, solid
    # for an obstacle.
    free_left = p.closed and (_signed_area(pts) > 0) != solid
    first = len(parts.walls)
    nseg = n if p.closed else n - 1
    for i in range(nseg):
        a, b = pts[i], pts[(i + 1) % n]
        d = _unit(b - a)
        left_normal = np.array([-d[1], d[0]])
        parts.walls.append((*a, *b))
        # Closed outlines reflect only on their free side.
        parts.normals.append(left_normal if (free_left or not p.closed) else -left_normal)
        parts.two_sided.append(not p.closed)
        parts.owner.append(si)
    for i in range(n):
        has_in = p.closed or i > 0
        has_out = p.closed or i < n - 1
        parts.verts.append(pts[i])
        parts.vwalls.append((first + (i - 1) % nseg if has_in else -1,
                             first + i % nseg if has_out else -1))
        if not (has_in and has_out):
            left, right = END, END
        else:
            left, right = _vertex_kinds(pts[(i - 1) % n], pts[i], pts[(i + 1) % n])
            if p.closed:  # the side that is not free is solid
                if free_left:
                    right = SOLID
                else:
                    left = SOLID
        parts.vleft.append(left)
        parts.vright.append(right)


def _vertex_kinds(before: np.ndarray, at: np.ndarray, after: np.ndarray) -> tuple[int, int]:
    """Kinds of the joint ``at`` between walls from ``before`` and to ``after``, seen from the
    left and from the right of the polyline's direction."""
    d_in = _unit(at - before)
    d_out = _unit(after - at)
    turn = cross(d_in, d_out)
    if abs(turn) <= FLAT_TOLERANCE and np.dot(d_in, d_out) > 0:
        return FLAT, FLAT
    if turn > 0:  # left turn: the left side is inside the bend
        return CORNER, EDGE
    # right turn, or a 180° fold back (an edge seen from both sides)
    return (EDGE, CORNER) if turn < 0 else (EDGE, EDGE)


def _signed_area(pts: np.ndarray) -> float:
    x, y = pts[:, 0], pts[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# --------------------------------------------------------------------------- sinusoids


def _sample_sinusoid(s: Sinusoid, step: float) -> tuple[tuple[float, ...], np.ndarray]:
    f = np.asarray(s.start, dtype=np.float64)
    e = np.asarray(s.end, dtype=np.float64)
    length = float(np.hypot(*(e - f)))
    t = (e - f) / length
    omega = 2.0 * math.pi / s.period
    ds = min(step, s.period / SAMPLES_PER_PERIOD)
    n = max(1, math.ceil(length / ds - 1e-9))
    return (f[0], f[1], t[0], t[1], s.amplitude, omega, length), np.linspace(0.0, length, n + 1)


def curve_point(curve: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Points ``F + s·t + A·sin(ωs)·n`` of sinusoids (``curve`` rows broadcast against ``s``)."""
    curve = np.asarray(curve, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    fx, fy, tx, ty, amp, omega = (curve[..., i] for i in range(6))
    h = amp * np.sin(omega * s)
    return np.stack([fx + s * tx - h * ty, fy + s * ty + h * tx], axis=-1)


def curve_derivatives(curve: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and second derivatives ``P'(s)``, ``P''(s)`` of sinusoids with respect to ``s``."""
    curve = np.asarray(curve, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    _, _, tx, ty, amp, omega = (curve[..., i] for i in range(6))
    h1 = amp * omega * np.cos(omega * s)
    h2 = -amp * omega * omega * np.sin(omega * s)
    d1 = np.stack([tx - h1 * ty, ty + h1 * tx], axis=-1)
    d2 = np.stack([-h2 * ty, h2 * tx], axis=-1)
    return d1, d2


# --------------------------------------------------------------------------- queries


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products of 2-D vectors ``a``, ``b`` [..., 2] (broadcast)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z-components of the cross products of 2-D vectors ``a``, ``b`` [..., 2] (broadcast)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def norm(a: np.ndarray) -> np.ndarray:
    """Lengths of 2-D vectors ``a`` [..., 2]."""
    return np.sqrt(dot(a, a))


#: Point-to-segment distances :func:`nearest_surface_point` computes at once (each of its
#: [points, segments] arrays then takes at most 16 MB).
NEAREST_BLOCK = 1 << 21


def nearest_surface_point(geom: Geometry, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each of ``points`` [M, 2] to the nearest surface, and that surface point.

    Walls and curve chords are exact segments, circles analytic. With no surfaces the
    distance is ``inf`` and the point is NaN (:func:`nearest_points` on this one scene).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    block = max(1, NEAREST_BLOCK // max(len(geom.occluders), len(geom.circles), 1))
    if len(p) > block:  # bounded memory: a few points × every segment at a time
        parts = [nearest_surface_point(geom, p[i:i + block]) for i in range(0, len(p), block)]
        return np.concatenate([d for d, _ in parts]), np.concatenate([q for _, q in parts])
    best, near = nearest_points(SurfaceSets.of([geom]), p[None])
    return best[0], near[0]


@dataclass(frozen=True)
class SurfaceSets:
    """The occluders (as :attr:`Geometry.occluder_frames`) and circles of several scenes
    side by side, padded to the most of any (``walls``/``rings`` mark the real ones): what
    :func:`nearest_points` measures against, for traces run together."""

    a: np.ndarray  # [B, O, 2] segment starts
    ab: np.ndarray  # [B, O, 2] segment directions
    ab2: np.ndarray  # [B, O] their squared lengths (1 where padded)
    walls: np.ndarray  # [B, O] bool: a real segment
    circles: np.ndarray  # [B, C, 3]
    rings: np.ndarray  # [B, C] bool: a real circle

    @classmethod
    def of(cls, geoms: list[Geometry]) -> SurfaceSets:
        o = max((len(g.occluders) for g in geoms), default=0)
        c = max((len(g.circles) for g in geoms), default=0)
        a, ab = np.zeros((len(geoms), o, 2)), np.zeros((len(geoms), o, 2))
        ab[..., 0] = 1.0
        ab2, circles = np.ones((len(geoms), o)), np.zeros((len(geoms), c, 3))
        walls, rings = np.zeros((len(geoms), o), bool), np.zeros((len(geoms), c), bool)
        for b, g in enumerate(geoms):
            n, m = len(g.occluders), len(g.circles)
            a[b, :n], ab[b, :n], ab2[b, :n] = g.occluder_frames
            circles[b, :m] = g.circles
            walls[b, :n], rings[b, :m] = True, True
        return cls(a, ab, ab2, walls, circles, rings)

    @cached_property
    def columns(self) -> tuple[np.ndarray, ...]:
        """The segments' ``(ax, ay, abx, aby, ab2)`` and the circles' ``(cx, cy, r)``,
        each [B, O or C, 1] (:func:`nearest_xy`)."""
        return tuple(np.ascontiguousarray(v[..., None]) for v in (
            self.a[..., 0], self.a[..., 1], self.ab[..., 0], self.ab[..., 1], self.ab2,
            *self.circles.transpose(2, 0, 1)))

    @cached_property
    def kinds(self) -> tuple[bool, bool, bool, bool]:
        """``(any wall, some scene's walls padded, any circle, some scene's padded)``."""
        return (bool(self.walls.any()), not self.walls.all(), bool(self.rings.any()),
                not self.rings.all())

    def take(self, rows: np.ndarray) -> SurfaceSets:
        """The scenes ``rows`` (ascending) of these."""
        if len(rows) == len(self.walls):
            return self
        return SurfaceSets(self.a[rows], self.ab[rows], self.ab2[rows], self.walls[rows],
                           self.circles[rows], self.rings[rows])


#: numpy's clip ufunc itself: ``np.clip``'s Python layers cost the trace more than clipping
_clip = getattr(getattr(np, "_core", None), "umath", np).clip


def nearest_points(surfaces: SurfaceSets, points: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``(distance [B, M], surface point [B, M, 2])``: for each scene b of ``surfaces``,
    the distance from each of its ``points[b]`` [M, 2] to its nearest surface and that
    point (:func:`nearest_xy`)."""
    best, qx, qy = nearest_xy(surfaces, points[..., 0], points[..., 1])
    near = np.empty(points.shape)
    near[..., 0], near[..., 1] = qx, qy
    return best, near


def nearest_xy(surfaces: SurfaceSets, px: np.ndarray, py: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(distance, x, y)`` [B, M] each: for each scene b of ``surfaces``, the distance
    from each point ``(px[b, m], py[b, m])`` to its nearest surface, and that surface
    point (``inf`` and NaN with no surface). Few array operations, one set per sub-step
    of the wall-following traces: the segments' frames precomputed as columns [B, O, 1]
    against the points' rows [B, 1, M], padding masked only where there is some; per
    point and segment the arithmetic of the earlier form (points [B, M, 2] against
    segments [B, 1, O, 2], kept in tests/test_speed_trace.py), so the same bits."""
    best, qx, qy = _nearest(surfaces, px, py, True)
    assert qx is not None and qy is not None
    return best, qx, qy


def nearest_distances(surfaces: SurfaceSets, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """[B, M] the distances of :func:`nearest_xy` alone (no point gathered)."""
    return _nearest(surfaces, px, py, False)[0]


def _nearest(surfaces: SurfaceSets, px: np.ndarray, py: np.ndarray, near: bool
             ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """:func:`nearest_xy`, its points only with ``near`` (else None)."""
    px, py = px[:, None], py[:, None]  # [B, 1, M]
    shape = (px.shape[0], px.shape[2])
    any_wall, ragged, any_circle, ragged_circles = surfaces.kinds
    qx = qy = None
    if any_wall:  # ragged: some scene has fewer segments than the padding
        ax, ay, bx, by, ab2 = surfaces.columns[:5]
        dx, dy = px - ax, py - ay  # [B, O, M]
        dx *= bx
        dy *= by
        t = dx + dy
        t /= ab2
        _clip(t, 0.0, 1.0, out=t)
        qx, qy = t * bx, t * by
        qx += ax  # a + t·ab
        qy += ay
        d = np.hypot(np.subtract(px, qx, out=dx), np.subtract(py, qy, out=dy), out=dx)
        if ragged:
            d = np.where(surfaces.walls[:, :, None], d, np.inf)
        if near:
            at = _gather(d.argmin(axis=1), d.shape)
            best, qx, qy = d.ravel()[at], qx.ravel()[at], qy.ravel()[at]
            if ragged:  # a scene without walls: no point
                qx[~np.isfinite(best)] = qy[~np.isfinite(best)] = np.nan
        else:
            best, qx, qy = d.min(axis=1), None, None
    else:
        best = np.full(shape, np.inf)
        if near:
            qx, qy = np.full(shape, np.nan), np.full(shape, np.nan)
    if any_circle:
        best, qx, qy = _nearer_circles(surfaces, px, py, best, qx, qy, ragged_circles)
    return best, qx, qy


def _gather(j: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """[B, M] flat indices of the entries ``[b, j[b, m], m]`` of an array [B, K, M]."""
    b, k, m = shape
    return j * m + (np.arange(b)[:, None] * (k * m) + np.arange(m))


def _nearer_circles(surfaces: SurfaceSets, px: np.ndarray, py: np.ndarray, best: np.ndarray,
                    qx: np.ndarray | None, qy: np.ndarray | None, ragged: bool
                    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """:func:`_nearest`'s ``(best, x, y)`` where a circle of ``surfaces`` is nearer
    (points ``px``, ``py`` [B, 1, M])."""
    cx, cy, r = surfaces.columns[5:]
    vx, vy = px - cx, py - cy  # [B, C, M]
    dist_c = np.hypot(vx, vy)
    d = np.abs(dist_c - r)
    if ragged:
        d = np.where(surfaces.rings[:, :, None], d, np.inf)
    if qx is None or qy is None:  # the distances alone
        d_j = d.min(axis=1)
        return np.where(d_j < best, d_j, best), qx, qy
    j = d.argmin(axis=1)
    at = _gather(j, d.shape)
    d_j = d.ravel()[at]
    closer = d_j < best
    length = np.maximum(dist_c.ravel()[at], 1e-300)
    circle = surfaces.circles[np.arange(len(j))[:, None], j]  # [B, M, 3]
    x = circle[..., 0] + vx.ravel()[at] / length * circle[..., 2]
    y = circle[..., 1] + vy.ravel()[at] / length * circle[..., 2]
    return np.where(closer, d_j, best), np.where(closer, x, qx), np.where(closer, y, qy)


def segment_distance(points: np.ndarray, polygon: np.ndarray, closed: bool = True
                     ) -> np.ndarray:
    """[M] the distance of each of ``points`` [M, 2] to the sides of ``polygon`` [K, 2]
    (closed: the last vertex joined to the first)."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(polygon, dtype=np.float64)
    d = np.roll(a, -1, axis=0) - a
    return np.min(segment_distances(pts, a if closed else a[:-1], d if closed else d[:-1]), 1)


def segment_distances(points: np.ndarray, a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """[M, K] the distance of each of ``points`` [M, 2] to each segment a[k] + t·d[k]."""
    t = np.clip(np.einsum("mkj,kj->mk", points[:, None] - a[None], d)
                / np.maximum(np.sum(d * d, 1), 1e-300), 0, 1)
    return np.hypot(*(points[:, None] - (a[None] + t[..., None] * d[None])).transpose(2, 0, 1))


def ray_distance(geom: Geometry, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Distance along each ray (unit ``directions``) to the first surface it meets (``inf``
    if none). Rays starting on a surface do not hit it at distance 0."""
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    u = np.asarray(directions, dtype=np.float64).reshape(-1, 2)
    best = np.full(len(o), np.inf)
    occ = geom.occluders
    if len(occ):
        a, e = occ[None, :, :2], occ[None, :, 2:] - occ[None, :, :2]
        denom = cross(u[:, None], e)
        w = a - o[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = cross(w, e) / denom  # along the ray
            s = cross(w, u[:, None]) / denom  # along the segment
        hit = (np.abs(denom) > 1e-15) & (t > 1e-12) & (s >= 0) & (s <= 1)
        best = np.minimum(best, np.where(hit, t, np.inf).min(axis=1))
    if len(geom.circles):
        c, r = geom.circles[None, :, :2], geom.circles[None, :, 2]
        w = o[:, None] - c
        b = np.sum(w * u[:, None], -1)
        disc = b * b - (np.sum(w * w, -1) - r * r)
        root = np.sqrt(np.maximum(disc, 0.0))
        t1, t2 = -b - root, -b + root
        t = np.where(t1 > 1e-12, t1, np.where(t2 > 1e-12, t2, np.inf))
        best = np.minimum(best, np.where(disc >= 0, t, np.inf).min(axis=1))
    return best


def true_vertices(geom: Geometry) -> np.ndarray:
    """[k, 2] the true corners and edges: polyline vertices that a free side sees as a
    concave corner or a convex edge (flat joints and free ends left out)."""
    kinds = [CORNER, EDGE]
    seen = np.isin(geom.vertex_left, kinds) | np.isin(geom.vertex_right, kinds)
    return geom.vertices[seen]


def cell_centres(extent: tuple[float, ...], cell: float, iy: np.ndarray, ix: np.ndarray
                 ) -> np.ndarray:
    """[..., 2] the (x, y) centres of map cells ``(iy, ix)`` (scene format v1: the centre of
    cell ``(iy, ix)`` is ``(xmin + (ix + 0.5)·cell, ymin + (iy + 0.5)·cell)``). The one place
    this convention is written; every map stage converts cells to metres through it."""
    iy, ix = np.asarray(iy), np.asarray(ix)
    return np.stack([extent[0] + (ix + 0.5) * cell, extent[1] + (iy + 0.5) * cell], axis=-1)


def point_cells(extent: tuple[float, ...], cell: float, points: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(iy, ix)`` [n] int64: the map cells holding ``points`` [n, 2] (the inverse of
    :func:`cell_centres`; cells outside the grid are not clipped), in the points' own
    precision."""
    points = np.asarray(points).reshape(-1, 2)
    ix = np.floor((points[:, 0] - extent[0]) / cell).astype(np.int64)
    iy = np.floor((points[:, 1] - extent[1]) / cell).astype(np.int64)
    return iy, ix
