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


def point_map(scene: Scene, points: np.ndarray,
              window: tuple[int, int, int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(counts [ny, nx], sums [ny, nx, 2])``: how many ``points`` fall in each cell and
    the sum of their coordinates (for sub-cell positions); over the grid's ``window``
    ``(row0, col0, ny, nx)`` only when given (points outside it are left out)."""
    ny, nx = scene.grid_shape
    iy, ix = point_cells(scene.extent, scene.cell, points)
    if window is not None:
        row0, col0, ny, nx = window
        iy, ix = iy - row0, ix - col0
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    counts = np.zeros((ny, nx), dtype=np.float32)
    sums = np.zeros((ny, nx, 2))
    np.add.at(counts, (iy[ok], ix[ok]), 1.0)
    np.add.at(sums, (iy[ok], ix[ok]), points[ok])
    return counts, sums


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
