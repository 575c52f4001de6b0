"""PNG pictures of a run's stages with the true geometry drawn over them (matplotlib, Agg).

Uses matplotlib's object API (``Figure`` + Agg canvas), never ``pyplot``, so it keeps no
global state and needs no display.
"""

from __future__ import annotations

import io

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy import ndimage

from .geometry import Geometry, curve_point
from .scene import Scene

TRUTH_STYLE = {"color": "tab:red", "linewidth": 0.8, "alpha": 0.8}


def draw_truth(ax, scene: Scene, geom: Geometry) -> None:
    """Draw every true surface of ``scene`` on ``ax`` (metres)."""
    for x0, y0, x1, y1 in geom.walls:
        ax.plot([x0, x1], [y0, y1], **TRUTH_STYLE)
    for cx, cy, r in geom.circles:
        a = np.linspace(0, 2 * np.pi, 361)
        ax.plot(cx + r * np.cos(a), cy + r * np.sin(a), **TRUTH_STYLE)
    for k, curve in enumerate(geom.curves):
        s = geom.interval_s[geom.interval_curve == k]
        p = curve_point(curve, np.linspace(s[0, 0], s[-1, 1], 2000))
        ax.plot(p[:, 0], p[:, 1], **TRUTH_STYLE)


def _figure(scene: Scene, title: str):
    fig = Figure(figsize=(7.5, 7.0), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    xmin, ymin, xmax, ymax = scene.extent
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=10)
    return fig, ax


def png_bytes(fig) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def map_png(scene: Scene, geom: Geometry, image: np.ndarray, title: str, *,
            binary: bool = False, sensors=None, points: np.ndarray | None = None) -> bytes:
    """A map stage (``[iy, ix]``) as a PNG, the true geometry in red over it."""
    fig, ax = _figure(scene, title)
    xmin, ymin = scene.extent[:2]
    ny, nx = image.shape
    # One map cell can be smaller than a pixel of the picture: show each pixel's maximum,
    # so thin arcs and one-cell curves stay visible.
    size = max(1, int(np.ceil(max(nx, ny) / 700)))
    shown = ndimage.maximum_filter(np.asarray(image, dtype=float), size=2 * size - 1)
    im = ax.imshow(shown, origin="lower", interpolation="nearest",
                   extent=(xmin, xmin + nx * scene.cell, ymin, ymin + ny * scene.cell),
                   cmap="gray_r" if binary else "viridis")
    if not binary:
        fig.colorbar(im, ax=ax, shrink=0.8, label="votes")
    draw_truth(ax, scene, geom)
    if sensors is not None and len(sensors):
        ax.plot(sensors.positions[:, 0], sensors.positions[:, 1], ".", color="tab:blue",
                markersize=1.5)
    if points is not None and len(points):
        ax.plot(points[:, 0], points[:, 1], ".", color="black", markersize=1.0)
    return png_bytes(fig)


def scene_png(scene: Scene, geom: Geometry, sensors, echo_points: np.ndarray) -> bytes:
    """The scene: true geometry, transducers with short axis ticks, ring poses, and the
    reflection points of all echoes."""
    fig, ax = _figure(scene, f"{scene.name}: {len(sensors)} transducers, "
                             f"{len(echo_points)} echoes")
    draw_truth(ax, scene, geom)
    tick = 0.02 * max(scene.extent[2] - scene.extent[0], scene.extent[3] - scene.extent[1])
    ends = sensors.positions + tick * sensors.axes
    for p, e in zip(sensors.positions, ends, strict=True):
        ax.plot([p[0], e[0]], [p[1], e[1]], color="tab:blue", linewidth=0.5)
    if len(sensors.poses):
        ax.plot(sensors.poses[:, 0], sensors.poses[:, 1], "-o", color="tab:green",
                markersize=2, linewidth=0.6, label="ring poses")
    if len(echo_points):
        ax.plot(echo_points[:, 0], echo_points[:, 1], "x", color="tab:orange", markersize=3,
                label="reflection points")
    if len(sensors.poses) or len(echo_points):
        ax.legend(loc="upper left", fontsize=7)
    return png_bytes(fig)
