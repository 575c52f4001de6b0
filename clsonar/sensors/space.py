"""What every placement checks: the extent, free space, segments that meet a surface, and
the error of a placement that cannot be made."""

from __future__ import annotations

import math

import numpy as np

from ..errors import SceneError
from ..geometry import Geometry, ray_distance
from ..outlines import inside_polygon
from ..scene import Polyline, Scene

#: What a placement returns: ``(positions [n, 2], headings_deg [n], groups [n] int64 from 0,
#: poses [G, 2])``.
Placed = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def extent_contains(scene: Scene, pts: np.ndarray) -> np.ndarray:
    """[M] bool: which of ``pts`` [M, 2] lie inside the scene's extent (its border included)."""
    xmin, ymin, xmax, ymax = scene.extent
    p = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    return (p[:, 0] >= xmin) & (p[:, 0] <= xmax) & (p[:, 1] >= ymin) & (p[:, 1] <= ymax)


def in_free_space(scene: Scene, geom: Geometry, points: np.ndarray) -> np.ndarray:
    """[M] bool: which ``points`` lie in free space: not inside a cylinder or a solid
    obstacle (a closed polyline read as solid, ``geom.surface_solid``), and inside a room
    (a closed polyline that is not solid) when the scene has any: a room's outside is
    solid. Points exactly on a surface count as free; callers keep a clearance anyway."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    free = np.ones(len(p), dtype=bool)
    if len(geom.circles):
        v = p[:, None] - geom.circles[None, :, :2]
        free &= ~np.any(np.hypot(v[..., 0], v[..., 1]) < geom.circles[None, :, 2], axis=1)
    closed = [(np.asarray(s.points, dtype=np.float64), bool(geom.surface_solid[i]))
              for i, s in enumerate(scene.surfaces) if isinstance(s, Polyline) and s.closed]
    rooms = [outline for outline, solid in closed if not solid]
    if rooms:
        free &= np.any([inside_polygon(r, p) for r in rooms], axis=0)
    for outline, solid in closed:
        if solid:
            free &= ~inside_polygon(outline, p)
    return free


def crosses(geom: Geometry, a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the segment ``a``→``b`` meets a surface."""
    return bool(crosses_each(geom, np.asarray(a)[None], np.asarray(b)[None])[0])


def crosses_each(geom: Geometry, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """[n] bool: whether each segment ``a[i]``→``b[i]`` meets a surface."""
    d = b - a
    length = np.array([math.hypot(x, y) for x, y in d])
    hit = np.zeros(len(d), dtype=bool)
    some = length > 0.0
    if some.any():
        ray = ray_distance(geom, a[some], d[some] / length[some, None])
        hit[some] = ray <= length[some]
    return hit


def placement_error(scene: Scene, message: str, key: str = "sensors.placement") -> SceneError:
    """The error of a placement of ``scene`` that cannot be made (the scene's name as source)."""
    return SceneError(message, key=key, source=scene.name)


class NearestOne:
    """The nearest surface point of one point at a time, from a scene's few segments and
    circles as Python floats (a wall-following trace's projections, one point per call):
    the arithmetic of :func:`~clsonar.geometry.nearest_xy` for one point — its clip as
    numpy's (``max`` then ``min``, -0 clipped to +0), numpy's hypot on the lists, the
    first of equal distances — so the same bits, without its array operations per
    segment. ``usable`` is False where a segment has no length or there are more than
    :data:`MAX_SEGMENTS` (the arrays are cheaper then)."""

    #: Segments and circles beyond which the arrays of ``nearest_xy`` cost less.
    MAX_SEGMENTS = 32

    def __init__(self, geom: Geometry) -> None:
        a, ab, ab2 = geom.occluder_frames
        self.walls = list(zip(*(v.tolist() for v in (a[:, 0], a[:, 1], ab[:, 0], ab[:, 1],
                                                       ab2)), strict=True))
        self.circles = geom.circles.tolist()
        self.usable = (bool(np.all(ab2 > 0.0))
                       and len(self.walls) + len(self.circles) <= self.MAX_SEGMENTS)

    def __call__(self, x: float, y: float) -> tuple[float, float, float]:
        """``(distance, nearest x, nearest y)`` of the point ``(x, y)`` (inf, NaN, NaN
        with no surface)."""
        dx, dy, near = [], [], []
        for ax, ay, bx, by, ab2 in self.walls:
            t = ((x - ax) * bx + (y - ay) * by) / ab2
            t = t if t > 0.0 else 0.0
            t = t if t < 1.0 else 1.0
            qx, qy = ax + t * bx, ay + t * by
            dx.append(x - qx)
            dy.append(y - qy)
            near.append((qx, qy))
        n = len(near)
        for cx, cy, _ in self.circles:
            dx.append(x - cx)
            dy.append(y - cy)
        h = np.hypot(dx, dy).tolist()
        best, qx, qy = math.inf, math.nan, math.nan
        if n:
            j = min(range(n), key=h.__getitem__)  # the first of the least
            best, (qx, qy) = h[j], near[j]
        if self.circles:
            d = [abs(length - r) for length, (_, _, r) in zip(h[n:], self.circles, strict=True)]
            j = min(range(len(d)), key=d.__getitem__)
            if d[j] < best:
                cx, cy, r = self.circles[j]
                length = h[n + j] if h[n + j] > 1e-300 else 1e-300
                best, qx, qy = d[j], cx + dx[n + j] / length * r, cy + dy[n + j] / length * r
        return best, qx, qy
