"""What the canvas and the stage views draw, as arrays (metres), and pyqtgraph set-up.

Map arrays are ``[iy, ix]`` (docs/design.md): with ``imageAxisOrder='row-major'`` and the cell
rectangle from :func:`map_rect`, row 0 sits at ``ymin`` and y grows upwards, so maps show
the right way up in metres.
"""

from __future__ import annotations

import math

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QRectF

from ..geometry import Geometry, curve_point
from ..scene import Scene, WallFollowing

pg.setConfigOptions(imageAxisOrder="row-major", antialias=True, background="w",
                    foreground="k")

TRUTH_PEN = pg.mkPen((220, 30, 30), width=1.5)
BEAM_PEN = pg.mkPen((30, 100, 220, 110), width=1)
SENSOR_BRUSH = pg.mkBrush(30, 100, 220)
PATH_PEN = pg.mkPen((30, 160, 60), width=1.5, style=pg.QtCore.Qt.PenStyle.DashLine)
PROFILE_PEN = pg.mkPen((0, 0, 0), width=2)

#: Length of the beam cones drawn on the canvas, as a fraction of the scene's size.
BEAM_FRACTION = 0.06


def map_rect(scene: Scene, shape: tuple[int, int]) -> QRectF:
    """The rectangle in metres that a ``[ny, nx]`` map of ``scene`` covers."""
    xmin, ymin = scene.extent[:2]
    ny, nx = shape
    return QRectF(xmin, ymin, nx * scene.cell, ny * scene.cell)


def truth_paths(geom: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` of every true surface, separate paths split by NaN (``connect='finite'``):
    the walls, each circle, and each sinusoid over its surface parameter range."""
    parts = [np.array([[x0, y0], [x1, y1]]) for x0, y0, x1, y1 in geom.walls]
    a = np.linspace(0.0, 2.0 * np.pi, 181)
    parts += [np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], -1) for cx, cy, r in
              geom.circles]
    for k, curve in enumerate(geom.curves):
        s = geom.interval_s[geom.interval_curve == k]
        if len(s):
            parts.append(curve_point(curve, np.linspace(s[0, 0], s[-1, 1], 600)))
    return _joined(parts)


def _joined(parts: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    if not parts:
        return np.zeros(0), np.zeros(0)
    gap = np.full((1, 2), np.nan)
    xy = np.concatenate([q for p in parts for q in (p, gap)])
    return xy[:, 0], xy[:, 1]


def beam_paths(positions: np.ndarray, headings_deg: np.ndarray, half_beam_deg: float,
               length: float) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` of each transducer's beam cone (±``half_beam_deg``, thesis §2.1) drawn as a
    closed wedge of ``length`` metres, NaN-separated."""
    if not len(positions):
        return np.zeros(0), np.zeros(0)
    arc = np.radians(np.linspace(-half_beam_deg, half_beam_deg, 7))
    h = np.radians(headings_deg)[:, None] + arc[None, :]
    tip = positions[:, None, :] + length * np.stack([np.cos(h), np.sin(h)], -1)
    p = positions[:, None, :]
    wedge = np.concatenate([p, tip, p], axis=1)
    return _joined(list(wedge))


def beam_length(scene: Scene) -> float:
    """Length in metres of the beam cones drawn for ``scene``."""
    xmin, ymin, xmax, ymax = scene.extent
    return BEAM_FRACTION * max(xmax - xmin, ymax - ymin)


def pose_path(scene: Scene, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` of the ring poses in order; a wall-following path closes on its start."""
    if not len(poses):
        return np.zeros(0), np.zeros(0)
    if isinstance(scene.sensors.placement, WallFollowing):
        poses = np.concatenate([poses, poses[:1]])
    return poses[:, 0].copy(), poses[:, 1].copy()


def heading_vector(heading_deg: float) -> tuple[float, float]:
    """Unit vector of a heading in degrees."""
    a = math.radians(heading_deg)
    return (math.cos(a), math.sin(a))
