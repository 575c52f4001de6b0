"""The plots of a run where axes and legends matter (scene.png, profile.png; matplotlib, Agg);
the map stages' pictures are drawn from the arrays by :mod:`clsonar.pictures`.

Uses matplotlib's object API (``Figure`` + Agg canvas, :func:`figure`), never ``pyplot``, so
it keeps no global state and needs no display. This is the one module that imports
matplotlib (the ``clsonar[plots]`` extra): the tools draw their figures with
:func:`figure` and :func:`png_bytes`, and import this module only when they draw.
"""

from __future__ import annotations

import io
from typing import Literal

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from .geometry import Geometry, curve_point, true_vertices
from .post import Profile
from .scene import PerWall, Scene, WallFollowing
from .sensors import SensorArray

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


def figure(figsize: tuple[float, float], dpi: int,
           layout: Literal["constrained", "compressed", "tight"] | None = "constrained"
           ) -> Figure:
    """A new figure on its own Agg canvas, laid out with ``layout`` (no pyplot)."""
    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


#: Where a run's scene and profile plots put their axes (figure fractions): fixed, as
#: constrained layout lays a figure out by drawing it twice (0.07 s a plot).
SCENE_AXES = {"left": 0.1, "right": 0.97, "bottom": 0.1, "top": 0.95}


def _scene_figure(scene: Scene, title: str):
    """A figure whose axes span the scene's extent in metres (equal aspect), titled, with
    room below for a legend."""
    fig = figure((7.5, 7.0), 150, layout=None)
    fig.subplots_adjust(**SCENE_AXES)
    ax = fig.add_subplot()
    xmin, ymin, xmax, ymax = scene.extent
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=10)
    return fig, ax


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


#: Most pixels along either side of a map shown in a figure (its axes are about 800 wide).
MAP_PIXELS = 700


def block_maximum(image: np.ndarray, size: int) -> np.ndarray:
    """``image`` [ny, nx] shrunk ``size`` times along each side, each pixel the maximum of
    its ``size`` × ``size`` block of cells (the last blocks padded with the image's least
    value): a map cell smaller than a pixel of the picture, a thin arc or a one-cell
    curve, stays visible, and matplotlib resamples no more pixels than it shows."""
    a = np.asarray(image)
    if size <= 1 or a.size == 0:
        return a.astype(float)
    ny, nx = a.shape
    by, bx = -(-ny // size), -(-nx // size)
    padded = np.pad(a, ((0, by * size - ny), (0, bx * size - nx)), constant_values=a.min())
    # the maximum of the size² strided views, in the map's own type (a thin map's bools):
    # the same values as a reduction over a float copy, a twentieth of the time
    shown = padded[::size, ::size].copy()
    for dy in range(size):
        for dx in range(size):
            np.maximum(shown, padded[dy::size, dx::size], out=shown)
    return shown.astype(float)


def _map_axes(scene: Scene, geom: Geometry, image: np.ndarray, title: str, binary: bool):
    """A figure showing a map stage (``[iy, ix]``) with the true geometry in red over it."""
    fig, ax = _scene_figure(scene, title)
    xmin, ymin = scene.extent[:2]
    size = max(1, int(np.ceil(max(image.shape) / MAP_PIXELS)))  # map cells per pixel
    shown = block_maximum(image, size)
    ny, nx = shown.shape
    im = ax.imshow(shown, origin="lower", interpolation="nearest",
                   extent=(xmin, xmin + nx * size * scene.cell,
                           ymin, ymin + ny * size * scene.cell),
                   cmap="gray_r" if binary else "viridis")
    if not binary:
        fig.colorbar(im, ax=ax, shrink=0.8, label="votes")
    draw_truth(ax, scene, geom)
    return fig, ax


def profile_png(scene: Scene, geom: Geometry, image: np.ndarray, title: str,
                profile: Profile, sensors: SensorArray) -> bytes:
    """The thinned map with the profile (``post.Profile``) in black, its corners and edges
    as red crosses, the true ones as grey circles, and the sensors drawn lightly."""
    fig, ax = _map_axes(scene, geom, image, title, binary=True)
    if len(sensors):
        ax.plot(sensors.positions[:, 0], sensors.positions[:, 1], ".", color="tab:blue",
                alpha=0.5, markersize=1.0)
    draw_poses(ax, scene, sensors.poses, light=True)
    points = profile.points
    if len(points):
        ax.plot(points[:, 0], points[:, 1], ".", color="black", markersize=1.0)
    truth = true_vertices(geom)
    if len(truth):
        ax.plot(truth[:, 0], truth[:, 1], "o", markersize=5, markerfacecolor="none",
                markeredgecolor="0.5", markeredgewidth=0.8, label="true corners and edges")
    if len(profile.vertices):
        ax.plot(profile.vertices[:, 0], profile.vertices[:, 1], "x", color="red",
                markersize=6, markeredgewidth=1.2, label="corners and edges")
    _legend(ax)
    return png_bytes(fig)


def draw_poses(ax, scene: Scene, poses: np.ndarray, *, light: bool = False) -> None:
    """Draw the placement's poses: ring centres joined along their path (wall-following,
    closed; circular), or the centres of the per-wall arrays as separate markers."""
    if not len(poses):
        return
    if isinstance(scene.sensors.placement, PerWall):
        label, style = "array centres", {"linestyle": "none", "marker": "s", "markersize": 3}
    else:
        label, style = "ring poses", {"linestyle": "-", "marker": "o", "markersize": 2,
                                      "linewidth": 0.6}
        if isinstance(scene.sensors.placement, WallFollowing):
            poses = np.concatenate([poses, poses[:1]])  # the path closes on its start
    ax.plot(poses[:, 0], poses[:, 1], color="tab:green", label=label,
            alpha=0.4 if light else 1.0, **style)


#: Room under the axes for the tick labels and the x label, and the least room under the
#: legend's top for one row of it, as shares of the figure.
LABELS_BELOW = 0.062
LEGEND_ROW = 0.035


def _legend(ax) -> None:
    """A legend of the labelled artists, if any, below the axes and their x label (not over
    the map): under the box the equal aspect leaves them, found without drawing."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.apply_aspect()
        top = max(ax.get_position().y0 - LABELS_BELOW, LEGEND_ROW)
        ax.figure.legend(handles, labels, loc="upper center", ncols=len(handles),
                         fontsize=7, frameon=False, bbox_to_anchor=(0.5, top))


def scene_png(scene: Scene, geom: Geometry, sensors: SensorArray,
              echo_points: np.ndarray) -> bytes:
    """The scene: true geometry, transducers with short axis ticks, the placement's poses
    (ring poses or array centres), and the reflection points of all echoes."""
    fig, ax = _scene_figure(scene, f"{scene.name}: {len(sensors)} transducers, "
                             f"{len(echo_points)} echoes")
    draw_truth(ax, scene, geom)
    tick = 0.02 * max(scene.extent[2] - scene.extent[0], scene.extent[3] - scene.extent[1])
    ends = sensors.positions + tick * sensors.axes
    ax.add_collection(LineCollection(list(np.stack([sensors.positions, ends], axis=1)),
                                     colors="tab:blue", linewidths=0.5,
                                     capstyle="projecting", joinstyle="round"),
                      autolim=False)
    draw_poses(ax, scene, sensors.poses)
    if len(echo_points):
        ax.plot(echo_points[:, 0], echo_points[:, 1], "x", color="tab:orange", markersize=3,
                label="reflection points")
    _legend(ax)
    return png_bytes(fig)
