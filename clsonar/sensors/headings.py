"""Which way a wall-following ring is turned (thesis §2.1.2) when the scene file leaves its
``start_deg`` out: square to the walls, so that an element faces each wall it passes.

A ring of n elements repeats every 360°/n, so a heading is only defined modulo that. A room
whose walls all share one heading (modulo 360°/n: any rectangular, L, U or T room, turned
or not) gets that heading at every pose (:func:`square_to_walls`, the thesis' ring in a room
along x and y). A room with walls at other angles — a trapezoid, a hexagon, a wall cut at
30° — has walls no fixed heading faces: there each pose is turned square to its nearest
wall (:func:`pose_headings`), as a robot following a wall holds its heading along it.
"""

from __future__ import annotations

import numpy as np

from ..geometry import Geometry, segment_distances

#: Walls whose normals agree within this (modulo the ring's symmetry) share a heading.
SQUARE_TOL_DEG = 2.0


def _off(a: np.ndarray, b: float, period: float) -> np.ndarray:
    """``a − b`` in degrees, wrapped to [−period/2, period/2)."""
    return (a - b + 0.5 * period) % period - 0.5 * period


def _normals_deg(walls: np.ndarray) -> np.ndarray:
    """[S] the angle of each wall's normal (one of its two), degrees."""
    d = walls[:, 2:] - walls[:, :2]
    return np.degrees(np.arctan2(d[:, 0], -d[:, 1]))


def square_to_walls(geom: Geometry, elements: int) -> float:
    """The ring heading (``start_deg``) that turns an element square to the most wall: a
    ring of n elements repeats every 360°/n, so each wall's normal angle is taken modulo
    that; the angle shared (within :data:`SQUARE_TOL_DEG`) by the greatest length of wall
    wins, refined to those walls' length-weighted mean. A room turned by θ gives θ modulo
    360°/n whatever boxes stand in it; a room whose walls run along x and y gives 0, the
    thesis' ring. In (−180°/n, 180°/n], rounded to 1e-6°."""
    walls = geom.walls
    if len(walls) == 0 or elements < 1:
        return 0.0
    period = 360.0 / elements
    d = walls[:, 2:] - walls[:, :2]
    length = np.hypot(d[:, 0], d[:, 1])
    normal = _normals_deg(walls)
    share = [float(length[np.abs(_off(normal, n, period)) <= SQUARE_TOL_DEG].sum())
             for n in normal]
    best = float(normal[int(np.argmax(share))])
    near = np.abs(_off(normal, best, period)) <= SQUARE_TOL_DEG
    mean = best + float(length[near] @ _off(normal[near], best, period)) / float(length[near].sum())
    return round(float(_off(np.array([mean]), 0.0, period)[0]), 6) + 0.0


def walls_share_heading(geom: Geometry, elements: int, heading: float | None = None) -> bool:
    """Whether every wall is square to ``heading`` (default :func:`square_to_walls`'; within
    :data:`SQUARE_TOL_DEG`, modulo 360°/``elements``): one heading then serves every pose."""
    if len(geom.walls) == 0 or elements < 1:
        return True
    period = 360.0 / elements
    heading = square_to_walls(geom, elements) if heading is None else heading
    return bool(np.all(np.abs(_off(_normals_deg(geom.walls), heading, period))
                       <= SQUARE_TOL_DEG))


#: Point-to-wall distances :func:`nearest_walls` computes at once (bounded memory).
NEAREST_AT_ONCE = 1 << 18


def nearest_walls(walls: np.ndarray, points: np.ndarray) -> np.ndarray:
    """[P] the index of the wall (segment of ``walls`` [S, 4]) nearest each of ``points``
    [P, 2] (:func:`~clsonar.geometry.segment_distances`), for a block of points at a time
    (at most :data:`NEAREST_AT_ONCE` distances)."""
    a, d = walls[:, :2], walls[:, 2:] - walls[:, :2]
    block = max(1, NEAREST_AT_ONCE // max(len(walls), 1))
    return np.concatenate([np.argmin(segment_distances(points[first:first + block], a, d), axis=1)
                           for first in range(0, len(points), block)] or [np.zeros(0, np.int64)])


def pose_headings(geom: Geometry, poses: np.ndarray, elements: int) -> np.ndarray:
    """[G] ``start_deg`` of each ring pose ``poses`` [G, 2] left to turn square to the walls:
    :func:`square_to_walls`' heading where the pose's nearest wall is square to it (every
    pose, in a room whose walls share it), else square to that nearest wall (an element
    facing it along its normal). In (−180°/n, 180°/n]."""
    heading = square_to_walls(geom, elements)
    if len(poses) == 0 or walls_share_heading(geom, elements, heading):
        return np.full(len(poses), heading)
    period = 360.0 / elements
    walls = geom.walls[nearest_walls(geom.walls, poses)]
    d = walls[:, 2:] - walls[:, :2]
    normal = np.stack([d[:, 1], -d[:, 0]], axis=1)
    towards = np.einsum("pk,pk->p", normal, walls[:, :2] - poses) >= 0.0  # facing the wall
    normal = np.where(towards[:, None], normal, -normal)
    own = np.round(_off(np.degrees(np.arctan2(normal[:, 1], normal[:, 0])), 0.0, period), 6)
    square = np.abs(_off(own, heading, period)) <= SQUARE_TOL_DEG
    return np.where(square, heading, own) + 0.0
