"""The low-pass and the occupancy of the accumulated map (thesis §2.1.1, part 5).

- :func:`low_pass`: the 3×3 mean filter of eq. 2.4;
- :func:`occupancy_level` and :func:`binarize`: the occupied ("black") cells of the filtered
  map;
- :func:`voted_box`, :func:`filter_box`, :func:`embed` and :func:`filter_and_thin`: the
  same stages on the box of the voted cells only, placed back on the whole map.

Maps are indexed ``[iy, ix]`` with ``iy`` growing with y (docs/design.md).
"""

from __future__ import annotations

import numpy as np

from ..scene import PostSettings
from .thinning import thin_map

#: Occupied cells need at least this many coincident votes after the low-pass (automatic
#: level): one locus band alone (√2 cells wide) averages to about 0.5 there, two to 1.
AUTO_LEVEL_VOTES = 0.75

#: Automatic level of a map of surface points (``mapping.mode`` ``tangents``): any point
#: within a 3×3 neighbourhood (the points are already cross-checked by two loci).
AUTO_LEVEL_POINTS = 0.99 / 9.0

#: Zero cells kept around the voted cells when post-processing looks at their box only.
BOX_MARGIN = 4


def low_pass(raw: np.ndarray) -> np.ndarray:
    """3×3 mean filter, thesis eq. 2.4 (``(1/9)·ones(3, 3)``), zero outside the map.

    Each cell is the sum of its nine cells, added in a fixed order, divided by 9: a cell's
    value depends on those nine cells only (a running-sum filter would leave rounding
    residues far from any vote), so filtering a part of the map gives the same values.
    The sums go :data:`LOW_PASS_ROWS` rows at a time (the nine shifted rows stay in the
    processor's cache: a quarter less time on the room's map than whole-map passes)."""
    raw = np.asarray(raw, dtype=np.float64)
    ny, nx = raw.shape
    p = np.zeros((ny + 2, nx + 2))  # zero outside the map
    p[1:-1, 1:-1] = raw
    out = np.empty((ny, nx))
    for r0 in range(0, ny, LOW_PASS_ROWS):
        r1 = min(ny, r0 + LOW_PASS_ROWS)
        total = out[r0:r1]
        total[...] = 0.0
        for dy in range(3):
            for dx in range(3):
                total += p[r0 + dy:r1 + dy, dx:dx + nx]
        total /= 9.0
    return out


#: Rows of the map :func:`low_pass` sums at a time.
LOW_PASS_ROWS = 32


def binarize(filtered: np.ndarray, level: float) -> np.ndarray:
    """Cells whose filtered value is at least ``level`` (the occupied, "black" cells). A cell
    with no vote is never occupied, so a map without echoes stays empty at any level."""
    filtered = np.asarray(filtered)
    return (filtered >= level) & (filtered > 0)


def occupancy_level(filtered: np.ndarray, settings: PostSettings, points: bool = False) -> float:
    """The value above which a filtered cell is occupied: ``settings.level`` × the map's
    maximum, or (automatic) :data:`AUTO_LEVEL_VOTES` for a map of loci — cells where loci
    coincide stay, lone arcs go — or :data:`AUTO_LEVEL_POINTS` for a map of points."""
    peak = float(np.max(filtered)) if np.size(filtered) else 0.0
    if settings.level is not None:
        return settings.level * peak
    return AUTO_LEVEL_POINTS if points else AUTO_LEVEL_VOTES


def voted_box(raw: np.ndarray, margin: int = BOX_MARGIN) -> tuple[slice, slice]:
    """``(rows, cols)``: the bounding box of the voted (nonzero) cells of ``raw``, grown by
    ``margin`` cells and starting at an even row and column (thinning's subfields go by
    parity), clipped to the map; empty when nothing voted."""
    rows = np.flatnonzero(np.any(raw != 0, axis=1))
    if len(rows) == 0:
        return slice(0, 0), slice(0, 0)
    cols = np.flatnonzero(np.any(raw[rows[0]:rows[-1] + 1] != 0, axis=0))
    r0, c0 = max(0, rows[0] - margin) & ~1, max(0, cols[0] - margin) & ~1
    return (slice(r0, min(raw.shape[0], rows[-1] + margin + 1)),
            slice(c0, min(raw.shape[1], cols[-1] + margin + 1)))


def filter_box(raw: np.ndarray, settings: PostSettings, points: bool = False,
               box: bool = True) -> tuple[tuple[slice, slice], np.ndarray, np.ndarray]:
    """Low-pass (eq. 2.4, when ``settings.filter`` is ``mean3``), occupancy level and
    binarize: ``(window, filtered, occupied)`` of the map's ``window``.

    With ``box`` the window is the :func:`voted_box` — the same result as the whole map
    (every cell farther than one cell from a vote filters to exactly 0: a 3×3 window, zero
    outside the map; the level is a fraction of the maximum); else the whole map.
    """
    raw = np.asarray(raw)
    window = voted_box(raw) if box else (slice(0, raw.shape[0]), slice(0, raw.shape[1]))
    part = raw[window]
    filtered = low_pass(part) if settings.filter == "mean3" else np.asarray(part, float)
    return window, filtered, binarize(filtered, occupancy_level(filtered, settings, points))


def embed(shape: tuple[int, ...], window: tuple[slice, slice], part: np.ndarray) -> np.ndarray:
    """``part`` placed at ``window`` of a zero map of ``shape`` (``part`` itself when the
    window is the whole map)."""
    if part.shape == tuple(shape):
        return part
    full = np.zeros(shape, dtype=part.dtype)
    full[window] = part
    return full


def filter_and_thin(raw: np.ndarray, settings: PostSettings, points: bool = False,
                    box: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(filtered, occupied, thin)`` full-size maps of :func:`filter_box` and
    :func:`~clsonar.post.thinning.thin_map` (thinning changes only occupied cells, so the
    box gives the same)."""
    window, filtered, occupied = filter_box(raw, settings, points, box)
    thin_cells = thin_map(occupied, settings)
    shape = np.shape(raw)
    return (embed(shape, window, filtered), embed(shape, window, occupied),
            embed(shape, window, thin_cells))


__all__ = ["AUTO_LEVEL_POINTS", "AUTO_LEVEL_VOTES", "BOX_MARGIN", "binarize", "embed",
           "filter_and_thin", "filter_box", "low_pass", "occupancy_level", "voted_box"]
