"""The map stages' pictures (raw.png, filtered.png, thin.png) drawn straight from the arrays:
a colour map of the cells, the true surfaces in red over it, encoded as PNG with zlib —
no figure, no axes, no matplotlib (issue 16: outputs that cost little).

A picture has one pixel per map cell, or per block of cells on a map wider than
:data:`MAX_SIDE` (each block shows its largest value, so one-cell arcs stay visible). North
is up: the map's row 0 (its lowest y) is the picture's last row. The plots where axes and
legends matter (scene.png, profile.png) stay in :mod:`clsonar.plots`.
"""

from __future__ import annotations

import math
import struct
import zlib

import numpy as np

from .geometry import Geometry
from .metrics import truth_points
from .scene import Scene

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
    (the last blocks padded with the image's minimum)."""
    if block <= 1:
        return np.asarray(image, dtype=np.float64)
    ny, nx = image.shape
    py, px = -ny % block, -nx % block
    low = float(np.min(image)) if image.size else 0.0
    padded = np.pad(np.asarray(image, dtype=np.float64), ((0, py), (0, px)),
                    constant_values=low)
    return padded.reshape((ny + py) // block, block, (nx + px) // block, block).max(axis=(1, 3))


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


__all__ = ["MAX_SIDE", "PNG_LEVEL", "block_max", "colour", "coloured", "map_picture", "png",
           "to_bytes", "truth_pixels"]
