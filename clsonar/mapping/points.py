"""The map of estimated reflection points (``mapping.mode = "tangents"``): how many points
fall in each cell and the sum of their coordinates (:func:`point_map`), over the cells that
hold them (:func:`points_window`)."""

from __future__ import annotations

import numpy as np

from ..geometry import point_cells
from ..scene import Scene

#: Empty cells kept around the points' cells by :func:`points_window`.
POINTS_WINDOW_MARGIN = 8


def points_window(scene: Scene, points: np.ndarray) -> tuple[int, int, int, int]:
    """``(row0, col0, ny, nx)``: the cells of the map's grid that hold ``points``, grown by
    :data:`POINTS_WINDOW_MARGIN`, starting at an even row and column (thinning's subfields
    go by parity) and clipped to the grid (at least one cell)."""
    ny, nx = scene.grid_shape
    iy, ix = point_cells(scene.extent, scene.cell, np.asarray(points, dtype=np.float64))
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    if not ok.any():
        return 0, 0, 1, 1
    m = POINTS_WINDOW_MARGIN
    r0 = max(0, int(iy[ok].min()) - m) & ~1
    c0 = max(0, int(ix[ok].min()) - m) & ~1
    r1 = min(ny, int(iy[ok].max()) + m + 1)
    c1 = min(nx, int(ix[ok].max()) + m + 1)
    return r0, c0, r1 - r0, c1 - c0


#: Where float32 counts stop: 2²⁴ + 1 rounds to 2²⁴.
_FLOAT32_COUNTS = 1 << 24


def point_map(scene: Scene, points: np.ndarray,
              window: tuple[int, int, int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(counts [ny, nx], sums [ny, nx, 2])``: how many ``points`` fall in each cell and
    the sum of their coordinates (for sub-cell positions); over the grid's ``window``
    ``(row0, col0, ny, nx)`` only when given (points outside it are left out).

    The points' cells are numbered (``np.unique``) and ``np.bincount`` adds each cell's
    coordinates from 0 in the points' order, as ``np.add.at`` on the whole grid did (the
    same sums to the bit; tests/test_speed_accumulation.py keeps that form), then only
    those cells are written (a map's untouched pages stay unmapped; docs/speed.md). The
    counts are as float32's additions of 1 made them: exact up to 2²⁴, where they stop
    (2²⁴ + 1 rounds to 2²⁴)."""
    ny, nx = scene.grid_shape
    iy, ix = point_cells(scene.extent, scene.cell, points)
    if window is not None:
        row0, col0, ny, nx = window
        iy, ix = iy - row0, ix - col0
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    kept = points[ok]
    cells, cell_of = np.unique(iy[ok] * nx + ix[ok], return_inverse=True)
    counts = np.zeros((ny, nx), dtype=np.float32)
    counts.ravel()[cells] = np.minimum(np.bincount(cell_of, minlength=len(cells)),
                                       _FLOAT32_COUNTS)
    sums = np.zeros((ny, nx, 2))
    for axis in (0, 1):
        sums.reshape(-1, 2)[cells, axis] = np.bincount(cell_of, kept[:, axis], len(cells))
    return counts, sums


def nonzero_cells(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.nonzero`` of a 2-D ``mask``: the same (row, column) indices, intp, in the same
    row-major order, from ``np.flatnonzero`` and one division (numpy 2.4's 2-D
    ``nonzero`` takes 5 ms on a 950 × 950 map of a few thousand cells, this 0.25 ms)."""
    if mask.shape[1] == 0:
        rows, cols = np.nonzero(mask)
        return rows, cols
    flat = np.flatnonzero(mask)
    rows = flat // mask.shape[1]
    return rows, flat - rows * mask.shape[1]


def densified(run: np.ndarray, spacing: float, max_gap: float) -> np.ndarray:
    """The consecutive samples ``run`` [n, 2] of one arc with points added on the chord
    between each two farther apart than ``spacing`` but no farther than ``max_gap`` (the
    samples' own spacing; a wider gap is a hole in the run, left open), evenly, so that
    no two are farther apart than ``spacing``: a locus sampled every 0.25° at 6 m is
    2.6 cm between samples, and its cells, four or five apart on a 5 mm grid, do not link
    into a curve (:func:`~clsonar.post.curves.trace_curves` drops them as specks). The
    chord stays within (0.25°·ρ)²/(8ρ) of the arc, 14 µm at 6 m."""
    run = np.asarray(run, dtype=np.float64).reshape(-1, 2)
    if len(run) < 2:
        return run
    gaps = np.hypot(*np.diff(run, axis=0).T)
    parts = np.where((gaps > spacing) & (gaps <= max_gap), np.ceil(gaps / spacing), 1.0)
    n = parts.astype(np.int64)
    if np.all(n == 1):
        return run
    t = np.concatenate([np.arange(k) / k for k in n])
    start = np.repeat(np.arange(len(n)), n)
    out = run[start] + t[:, None] * (run[start + 1] - run[start])
    return np.concatenate([out, run[-1:]])
