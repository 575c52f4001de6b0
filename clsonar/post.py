"""Post-processing of the accumulated map (thesis §2.1.1, part 5).

- :func:`low_pass`: the 3×3 mean filter of eq. 2.4;
- :func:`binarize`: occupied cells of the filtered map;
- :func:`thin_thesis`: the template of eq. 2.5 exactly as the thesis writes it;
- :func:`thin`: a proper thinning (Guo and Hall's parallel algorithm) that leaves one-pixel
  wide, 8-connected curves and keeps every curve's connectivity.

Maps are indexed ``[iy, ix]`` with ``iy`` growing with y (DESIGN.md). The thesis draws its
maps as images, row 0 at the top, so "the row above" in eq. 2.5 is ``iy + 1`` here.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

#: Correlation weights giving each pixel an 8-bit code of its neighbours: bit k−1 is
#: neighbour x_k of Guo and Hall, counted counter-clockwise from x1 = east (array rows grow
#: downwards here, so "north" is row − 1; the algorithm is symmetric and does not care).
_NEIGHBOUR_BITS = np.array([[8, 4, 2], [16, 0, 1], [32, 64, 128]])


def low_pass(raw: np.ndarray) -> np.ndarray:
    """3×3 mean filter, thesis eq. 2.4 (``(1/9)·ones(3, 3)``), zero outside the map."""
    return ndimage.uniform_filter(np.asarray(raw, dtype=np.float64), size=3, mode="constant",
                                  cval=0.0)


def binarize(filtered: np.ndarray, level: float) -> np.ndarray:
    """Cells whose filtered value is at least ``level`` (the occupied, "black" cells)."""
    return np.asarray(filtered) >= level


def thin_thesis(binary: np.ndarray) -> np.ndarray:
    """Thinning as thesis eq. 2.5 is written: keep a cell that matches

    ::

        0 0 0
        X 1 X      (X: don't care)
        1 1 1

    i.e. the three cells above it are empty and the three below it are occupied; every
    other cell is zeroed. This keeps the upper boundary of each thick band, one pixel wide
    where the band is at least two pixels tall; cells outside the map count as empty.
    """
    b = np.pad(np.asarray(binary, dtype=bool), 1)
    centre = b[1:-1, 1:-1]
    above = b[2:, :-2] | b[2:, 1:-1] | b[2:, 2:]  # iy + 1 is the row above
    below = b[:-2, :-2] & b[:-2, 1:-1] & b[:-2, 2:]
    return centre & ~above & below


def _guo_hall_tables() -> tuple[np.ndarray, np.ndarray]:
    """Deletion tables of the two sub-iterations of Guo and Hall (1989), indexed by the
    8-bit neighbour code (bit k−1 = neighbour x_k, x1 = east, counter-clockwise)."""
    first = np.zeros(256, dtype=bool)
    second = np.zeros(256, dtype=bool)
    for code in range(256):
        x = [None] + [(code >> k) & 1 for k in range(8)] + [code & 1]  # x[1..8], x[9] = x1
        crossings = sum(1 for i in (1, 3, 5, 7) if not x[i] and (x[i + 1] or x[i + 2]))
        n1 = sum(x[2 * k - 1] | x[2 * k] for k in range(1, 5))
        n2 = sum(x[2 * k] | x[2 * k + 1] for k in range(1, 5))
        if crossings != 1 or not 2 <= min(n1, n2) <= 3:
            continue
        first[code] = ((x[2] | x[3] | (1 - x[8])) & x[1]) == 0
        second[code] = ((x[6] | x[7] | (1 - x[4])) & x[5]) == 0
    return first, second


_DELETE_FIRST, _DELETE_SECOND = _guo_hall_tables()


def _simple_table() -> np.ndarray:
    """Whether a foreground pixel with a given neighbour code is *simple*: deleting it keeps
    the topology (its neighbours form one 8-connected foreground component and it touches
    one 4-connected background component)."""
    table = np.zeros(256, dtype=bool)
    four = ndimage.generate_binary_structure(2, 1)
    for code in range(256):
        patch = (code & _NEIGHBOUR_BITS) > 0
        n_fg = ndimage.label(patch, np.ones((3, 3)))[1]
        bg, _ = ndimage.label(~patch & (_NEIGHBOUR_BITS > 0), four)
        touching = {bg[i, j] for i, j in ((0, 1), (1, 0), (1, 2), (2, 1)) if bg[i, j]}
        table[code] = n_fg == 1 and len(touching) == 1
    return table


_SIMPLE = _simple_table()


def _neighbour_code(b: np.ndarray) -> np.ndarray:
    return ndimage.correlate(b.astype(np.uint8), _NEIGHBOUR_BITS, mode="constant")


def _redundant(b: np.ndarray) -> np.ndarray:
    """Pixels that make a curve thicker than one pixel in the 8-connected sense: those with
    two orthogonal 4-neighbours set (a staircase corner, or part of a 2×2 block)."""
    p = np.pad(b, 1)
    north, south = p[2:, 1:-1], p[:-2, 1:-1]
    east, west = p[1:-1, 2:], p[1:-1, :-2]
    return b & ((north | south) & (east | west))


def _guo_hall(skeleton: np.ndarray, max_iterations: int) -> np.ndarray:
    for _ in range(max_iterations):
        before = np.count_nonzero(skeleton)
        for table in (_DELETE_FIRST, _DELETE_SECOND):
            skeleton &= ~table[_neighbour_code(skeleton)]
        if np.count_nonzero(skeleton) == before:
            break
    return skeleton


def thin(binary: np.ndarray, max_iterations: int = 10_000) -> np.ndarray:
    """Thin occupied bands to one-pixel-wide 8-connected curves, keeping the connectivity
    (and the holes) of every band.

    Guo and Hall's parallel thinning (the algorithm of ``skimage.morphology.thin``) runs
    to convergence; it can leave 2×2 blocks and staircase corners, whose *simple* pixels
    (deleting them keeps the topology) are then deleted one parity subfield at a time —
    pixels of one subfield are never neighbours, so deleting them together cannot
    disconnect anything. Both steps repeat until nothing changes.
    """
    skeleton = np.asarray(binary, dtype=bool).copy()
    iy, ix = np.indices(skeleton.shape)
    subfields = [(iy % 2 == a) & (ix % 2 == b) for a in (0, 1) for b in (0, 1)]
    for _ in range(max_iterations):
        before = np.count_nonzero(skeleton)
        skeleton = _guo_hall(skeleton, max_iterations)
        for field in subfields:
            code = _neighbour_code(skeleton)
            skeleton &= ~(field & _redundant(skeleton) & _SIMPLE[code])
        if np.count_nonzero(skeleton) == before:
            break
    return skeleton
