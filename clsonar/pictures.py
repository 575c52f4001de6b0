"""A run's pictures drawn straight from its arrays, encoded as PNG with zlib — no
matplotlib (issue 16: outputs that cost little).

The map stages (raw.png, filtered.png, thin.png): a colour map of the cells, the true
surfaces in red over it. A picture has one pixel per map cell, or per block of cells on a
map wider than :data:`MAX_SIDE` (each block shows its largest value, so one-cell arcs stay
visible). North is up: the map's row 0 (its lowest y) is the picture's last row.

The plots with axes (scene.png, profile.png, :func:`scene_png`, :func:`profile_png`): the
extent in metres at equal scale, ticks, labels, a title and a legend, drawn by
:mod:`clsonar.canvas` as matplotlib drew them before.
"""

from __future__ import annotations

import math
import struct
import zlib
from typing import TYPE_CHECKING

import numpy as np

from .canvas import DPI, Axes, Canvas, Entry, legend
from .geometry import Geometry, curve_point, true_vertices
from .metrics import truth_points
from .scene import PerWall, Scene, WallFollowing

if TYPE_CHECKING:
    from .post import Profile
    from .sensors import SensorArray

#: Largest side of a picture, pixels.
MAX_SIDE = 1400

#: zlib's level for the pictures: its fastest. A map is mostly one colour, so level 6
#: makes a 1000 × 1000 picture half as large (12 against 25 kB) in three times the time
#: (17 against 5 ms).
PNG_LEVEL = 1

#: viridis (matplotlib's default colour map) at 17 evenly spaced values, 8-bit RGB; values
#: between are interpolated.
VIRIDIS = np.array([
    (68, 1, 84), (72, 24, 106), (71, 45, 123), (66, 64, 134), (59, 82, 139), (51, 99, 141),
    (44, 114, 142), (38, 130, 142), (33, 145, 140), (31, 160, 136), (40, 174, 128),
    (63, 188, 115), (94, 201, 98), (132, 212, 75), (173, 220, 48), (216, 226, 25),
    (253, 231, 37)], dtype=np.float64)

#: The true surfaces' colour and opacity over the map.
TRUTH_RGB = np.array([214.0, 39.0, 40.0])
TRUTH_ALPHA = 0.6


def block_max(image: np.ndarray, block: int) -> np.ndarray:
    """``image`` [ny, nx] reduced by the largest value of each ``block`` × ``block`` block
    (the last blocks cut at the image's edge), as float64: the maximum of the block²
    strided views in the image's own type, so a floor's map (10⁸ cells) is never copied
    whole (a float64 copy and its padding were 1.6 GB)."""
    image = np.asarray(image)
    if block <= 1:
        return image.astype(np.float64)
    ny, nx = image.shape
    out = np.full((-(-ny // block), -(-nx // block)), image.min() if image.size else 0,
                  dtype=image.dtype)
    for dy in range(min(block, ny)):
        for dx in range(min(block, nx)):
            view = image[dy::block, dx::block]
            part = out[:view.shape[0], :view.shape[1]]
            np.maximum(part, view, out=part)
    return out.astype(np.float64)


def colour(values: np.ndarray, binary: bool, top: float | None = None) -> np.ndarray:
    """[..., 3] float RGB of ``values``: black on white where ``binary``, else viridis
    from 0 to ``top`` (default: the largest value)."""
    if binary:
        return np.repeat(np.where(values > 0, 0.0, 255.0)[..., None], 3, axis=-1)
    if top is None:
        top = float(values.max()) if values.size else 0.0
    x = np.clip(values / top, 0.0, 1.0) if top > 0 else np.zeros_like(values)
    pos = x * (len(VIRIDIS) - 1)
    k = np.minimum(pos.astype(np.int64), len(VIRIDIS) - 2)
    t = (pos - k)[..., None]
    return VIRIDIS[k] * (1.0 - t) + VIRIDIS[k + 1] * t


def to_bytes(rgb: np.ndarray) -> np.ndarray:
    """Float RGB rounded to 8 bits."""
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8)


def coloured(values: np.ndarray, binary: bool, top: float) -> np.ndarray:
    """[h, w, 3] 8-bit :func:`colour` of ``values`` [h, w] (viridis up to ``top``), computed
    only for the nonzero cells (a map is mostly empty; every zero cell has the colour of 0)."""
    h, w = values.shape
    row = np.tile(to_bytes(colour(np.zeros(1), binary, top))[0], w)  # one row, then copies
    rgb = np.broadcast_to(row, (h, 3 * w)).copy().reshape(h, w, 3)
    flat, cells = values.ravel(), np.flatnonzero(values)
    rgb.reshape(-1, 3)[cells] = to_bytes(colour(flat[cells], binary, top))
    return rgb


def truth_pixels(scene: Scene, geom: Geometry, shape: tuple[int, ...], pixel_m: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The (rows, cols) of a north-up picture of ``shape`` (``pixel_m`` metres per pixel)
    that the true surfaces of ``scene`` cross, sampled at half a pixel."""
    pts = truth_points(scene, geom, 0.5 * pixel_m)
    h, w = shape[:2]
    ix = np.floor((pts[:, 0] - scene.extent[0]) / pixel_m).astype(np.int64)
    iy = np.floor((pts[:, 1] - scene.extent[1]) / pixel_m).astype(np.int64)
    inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    return h - 1 - iy[inside], ix[inside]


def over_truth(rgb: np.ndarray) -> np.ndarray:
    """Float RGB ``rgb`` with the true surfaces' red blended over it."""
    return (1.0 - TRUTH_ALPHA) * rgb + TRUTH_ALPHA * TRUTH_RGB


def png(rgb: np.ndarray) -> bytes:
    """RGB ``rgb`` [h, w, 3] (8-bit, or float rounded to it) as PNG bytes (one IDAT, no
    filtering)."""
    h, w = rgb.shape[:2]
    rgb = rgb if rgb.dtype == np.uint8 else to_bytes(rgb)
    rows = np.concatenate([np.zeros((h, 1), np.uint8), rgb.reshape(h, 3 * w)], axis=1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)  # 8-bit RGB
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(rows.tobytes(), PNG_LEVEL)) + chunk(b"IEND", b""))


def map_picture(scene: Scene, geom: Geometry, image: np.ndarray, *,
                binary: bool = False) -> bytes:
    """A map stage (``[iy, ix]``) as a PNG: its cells coloured (:func:`colour`), north up,
    the true surfaces in red over them (:func:`truth_pixels`; only the nonzero cells and
    the truth's pixels are coloured one by one, :func:`coloured`)."""
    ny, nx = image.shape
    block = max(1, math.ceil(max(nx, ny, 1) / MAX_SIDE))
    values = block_max(image, block)[::-1]
    top = float(values.max()) if values.size else 0.0
    rgb = coloured(values, binary, top)
    rows, cols = truth_pixels(scene, geom, values.shape, block * scene.cell)
    rgb[rows, cols] = to_bytes(over_truth(colour(values[rows, cols], binary, top)))
    return png(rgb)


#: The plots' size (7.5 × 7 in), where their axes may lie, and the top of the legend's
#: row below them (shares of it).
FIGURE_IN = (7.5, 7.0)
PLOT_FRAME = {"left": 0.1, "right": 0.97, "bottom": 0.1, "top": 0.95}
LEGEND_ROW = 0.035

#: Most pixels along either side of a map shown in a plot (its axes are about 800 wide).
MAP_PIXELS = 700


def _plot(scene: Scene) -> tuple[Canvas, Axes]:
    """A white plot whose axes span the scene's extent in metres at equal scale."""
    canvas = Canvas(round(FIGURE_IN[0] * DPI), round(FIGURE_IN[1] * DPI))
    return canvas, Axes.fit(canvas, scene.extent, PLOT_FRAME)


def _finish(canvas: Canvas, axes: Axes, title: str, entries: list[Entry]) -> bytes:
    """The plot's frame, labels, title and legend (in the figure's last row), as PNG
    bytes."""
    axes.frame(canvas, "x (m)", "y (m)", title)
    legend(canvas, entries, axes.left + 0.5 * axes.width,
           (1.0 - LEGEND_ROW) * canvas.height)
    return png(canvas.rgb)


def truth_lines(geom: Geometry) -> np.ndarray:
    """[n, 2, 2] segments (metres) tracing every true surface: walls, circles by 360
    chords, curves by 2000."""
    parts = [geom.walls.reshape(-1, 2, 2)]
    for cx, cy, r in geom.circles:
        a = np.linspace(0.0, 2.0 * np.pi, 361)
        parts.append(_chords(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1)))
    for k, curve in enumerate(geom.curves):
        s = geom.interval_s[geom.interval_curve == k]
        parts.append(_chords(curve_point(curve, np.linspace(s[0, 0], s[-1, 1], 2000))))
    return np.concatenate(parts)


def _chords(points: np.ndarray) -> np.ndarray:
    return np.stack([points[:-1], points[1:]], axis=1)


def _truth(canvas: Canvas, axes: Axes, geom: Geometry) -> None:
    """The true surfaces in red (0.8 pt, 80 %)."""
    seg = truth_lines(geom)
    axes.segments(canvas, seg[:, 0], seg[:, 1], "tab:red", 0.8, 0.8)


def _poses(canvas: Canvas, axes: Axes, scene: Scene, poses: np.ndarray, light: bool
           ) -> list[Entry]:
    """The placement's poses: ring centres joined along their path (wall-following,
    closed; circular), or the centres of the per-wall arrays as separate squares; the
    legend's entry."""
    if not len(poses):
        return []
    alpha = 0.4 if light else 1.0
    if isinstance(scene.sensors.placement, PerWall):
        axes.markers(canvas, poses, "s", "tab:green", 4.0, alpha=alpha)
        return [Entry("array centres", "tab:green", "s", 4.0, alpha=alpha)]
    if isinstance(scene.sensors.placement, WallFollowing):
        poses = np.concatenate([poses, poses[:1]])  # the path closes on its start
    axes.polyline(canvas, poses, "tab:green", 0.6, alpha)
    axes.markers(canvas, poses, "disc", "tab:green", 3.0, alpha=alpha)
    return [Entry("ring poses", "tab:green", "disc", 3.0, line_pt=0.6, alpha=alpha)]


def scene_png(scene: Scene, geom: Geometry, sensors: SensorArray,
              echo_points: np.ndarray) -> bytes:
    """scene.png: the true geometry, the transducers with short axis ticks, the
    placement's poses (ring poses or array centres) and the reflection points of all
    echoes."""
    canvas, axes = _plot(scene)
    _truth(canvas, axes, geom)
    tick = 0.02 * max(scene.extent[2] - scene.extent[0], scene.extent[3] - scene.extent[1])
    axes.segments(canvas, sensors.positions, sensors.positions + tick * sensors.axes,
                  "tab:blue", 0.5)
    entries = _poses(canvas, axes, scene, sensors.poses, light=False)
    if len(echo_points):
        axes.markers(canvas, echo_points, "x", "tab:orange", 3.0)
        entries.append(Entry("reflection points", "tab:orange", "x", 3.0))
    return _finish(canvas, axes, f"{scene.name}: {len(sensors)} transducers, "
                   f"{len(echo_points)} echoes", entries)


def _map_image(canvas: Canvas, axes: Axes, scene: Scene, image: np.ndarray) -> None:
    """A binary map (``[iy, ix]``) in black on white over the axes' box, shown by blocks
    of at most :data:`MAP_PIXELS` a side (:func:`block_max`), each pixel the block under
    its centre."""
    block = max(1, math.ceil(max(image.shape) / MAP_PIXELS))
    shown = block_max(image, block) > 0
    r0, c0, r1, c1 = axes.clip
    size = block * scene.cell * axes.scale  # pixels a block
    bx = np.floor((np.arange(c0, c1) + 0.5 - axes.left) / size).astype(np.int64)
    by = np.floor((axes.top + axes.height - np.arange(r0, r1) - 0.5) / size).astype(np.int64)
    ok_x = (bx >= 0) & (bx < shown.shape[1])
    ok_y = (by >= 0) & (by < shown.shape[0])
    on = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    on[np.ix_(ok_y, ok_x)] = shown[np.ix_(by[ok_y], bx[ok_x])]
    canvas.rgb[r0:r1, c0:c1][on] = 0.0


def profile_png(scene: Scene, geom: Geometry, image: np.ndarray, title: str,
                profile: Profile, sensors: SensorArray) -> bytes:
    """profile.png: the thinned map with the profile (``post.Profile``) in black, its
    corners and edges as red crosses, the true ones as grey rings, the true surfaces in
    red and the sensors drawn lightly."""
    canvas, axes = _plot(scene)
    _map_image(canvas, axes, scene, np.asarray(image))
    _truth(canvas, axes, geom)
    if len(sensors):
        axes.markers(canvas, sensors.positions, "disc", "tab:blue", 1.5, alpha=0.5)
    entries = _poses(canvas, axes, scene, sensors.poses, light=True)
    if len(profile.points):
        axes.markers(canvas, profile.points, "disc", "black", 1.5)
    truth = true_vertices(geom)
    if len(truth):
        axes.markers(canvas, truth, "o", "grey", 5.0, 0.8)
        entries.append(Entry("true corners and edges", "grey", "o", 5.0, 0.8))
    if len(profile.vertices):
        axes.markers(canvas, profile.vertices, "x", "red", 6.0, 1.2)
        entries.append(Entry("corners and edges", "red", "x", 6.0, 1.2))
    return _finish(canvas, axes, title, entries)


__all__ = ["MAP_PIXELS", "MAX_SIDE", "PNG_LEVEL", "block_max", "colour", "coloured",
           "map_picture", "png", "profile_png", "scene_png", "to_bytes", "truth_lines",
           "truth_pixels"]
