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
