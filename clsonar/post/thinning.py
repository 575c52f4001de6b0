"""Thinning of the occupied cells (thesis §2.1.1, part 5).

- :func:`thin_thesis`: the template of eq. 2.5 exactly as the thesis writes it, and
  :func:`thin_oriented`, the same in the direction that fits each part of the map;
- :func:`thin`: a proper thinning (Guo and Hall's parallel algorithm) that leaves one-pixel
  wide, 8-connected curves and keeps every curve's connectivity;
- :func:`thin_map`: the stage, one or the other as the settings say.

Maps are indexed ``[iy, ix]`` with ``iy`` growing with y (docs/design.md).
"""

from __future__ import annotations

import numpy as np

from ..mapping.points import nonzero_cells
from ..scene import PostSettings

#: Correlation weights giving each pixel an 8-bit code of its neighbours: bit k−1 is
#: neighbour x_k of Guo and Hall, counted counter-clockwise from x1 = east (array rows grow
#: downwards here, so "north" is row − 1; the algorithm is symmetric and does not care).
_NEIGHBOUR_BITS = np.array([[8, 4, 2], [16, 0, 1], [32, 64, 128]])


def thin_thesis(binary: np.ndarray, up: tuple[int, int] = (0, -1)) -> np.ndarray:
    """Thinning as thesis eq. 2.5 is written: keep a cell that matches

    ::

        0 0 0
        X 1 X      (X: don't care)
        1 1 1

    i.e. the three cells "above" it are empty and the three "below" it are occupied; every
    other cell is zeroed. This keeps one edge of each thick band, one pixel wide where the
    band is at least two pixels deep; cells outside the map count as empty.

    ``up`` is the array step ``(diy, dix)`` to the row above. The thesis' MATLAB maps index
    their rows by x ("a wall located 9 m away from the origin along the x direction" is a
    row of the image), so by default the row above a cell is the one at smaller x, and the
    template keeps the edge of a band that faces the sensors of the thesis' scenes.
    """
    b = np.pad(np.asarray(binary, dtype=bool), 1)
    ny, nx = binary.shape
    side = (up[1], up[0])  # perpendicular to up

    def shifted(dy: int, dx: int) -> np.ndarray:
        return b[1 + dy:1 + dy + ny, 1 + dx:1 + dx + nx]

    centre = shifted(0, 0)
    above = np.zeros_like(centre)
    below = np.ones_like(centre)
    for k in (-1, 0, 1):
        oy, ox = k * side[0], k * side[1]
        above |= shifted(up[0] + oy, up[1] + ox)
        below &= shifted(-up[0] + oy, -up[1] + ox)
    return centre & ~above & below


def _neighbour_bits() -> np.ndarray:
    """[256, 10] the neighbours x_1 … x_8 of each 8-bit neighbour code (bit k−1 = x_k,
    x1 = east, counter-clockwise) in columns 1–8, x_9 = x_1 again; column 0 unused."""
    x = (np.arange(256)[:, None] >> np.arange(8)) & 1
    return np.concatenate([np.zeros((256, 1), dtype=x.dtype), x, x[:, :1]], axis=1)


def _guo_hall_tables() -> tuple[np.ndarray, np.ndarray]:
    """Deletion tables of the two sub-iterations of Guo and Hall (1989), indexed by the
    8-bit neighbour code (:func:`_neighbour_bits`)."""
    x = _neighbour_bits()
    crossings = sum((1 - x[:, i]) & (x[:, i + 1] | x[:, i + 2]) for i in (1, 3, 5, 7))
    n1 = sum(x[:, 2 * k - 1] | x[:, 2 * k] for k in range(1, 5))
    n2 = sum(x[:, 2 * k] | x[:, 2 * k + 1] for k in range(1, 5))
    deletable = (crossings == 1) & (np.minimum(n1, n2) >= 2) & (np.minimum(n1, n2) <= 3)
    first = deletable & (((x[:, 2] | x[:, 3] | (1 - x[:, 8])) & x[:, 1]) == 0)
    second = deletable & (((x[:, 6] | x[:, 7] | (1 - x[:, 4])) & x[:, 5]) == 0)
    return first, second


_DELETE_FIRST, _DELETE_SECOND = _guo_hall_tables()


def _simple_table() -> np.ndarray:
    """Whether a foreground pixel with a given neighbour code is *simple*: deleting it keeps
    the topology (its neighbours form one 8-connected foreground component and it touches
    one 4-connected background component) — where Yokoi's 8-connectivity number
    N = Σ_{k = 1, 3, 5, 7} (x̄_k − x̄_k·x̄_{k+1}·x̄_{k+2}) is 1, x̄ = 1 − x (Yokoi, Toriwaki &
    Fukumura 1975; tests/test_post.py checks it against scipy's labelling of that
    definition, code by code)."""
    off = 1 - _neighbour_bits()
    return sum(off[:, k] - off[:, k] * off[:, k + 1] * off[:, k + 2] for k in (1, 3, 5, 7)) == 1


_SIMPLE = _simple_table()


def _codes_at(p: np.ndarray, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """The neighbour code (the correlation with :data:`_NEIGHBOUR_BITS`) of the pixels
    ``(iy, ix)`` of the padded map ``p`` only (indices into ``p``, never on its one-pixel
    border) — thinning needs it at set pixels, a few per cent of a map. Each neighbour is
    read from the flattened map at the pixel's flat index plus the neighbour's offset."""
    flat = p.reshape(-1).view(np.uint8)  # a bool map: 0 or 1 a byte
    at = iy * p.shape[1] + ix
    code = np.zeros(len(iy), dtype=np.uint8)
    for i in range(3):
        for j in range(3):
            if _NEIGHBOUR_BITS[i, j]:
                code |= flat[at + ((i - 1) * p.shape[1] + j - 1)] * np.uint8(_NEIGHBOUR_BITS[i, j])
    return code


def _redundant_at(p: np.ndarray, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """Whether the set pixels ``(iy, ix)`` of the padded map ``p`` make a curve thicker than
    one pixel in the 8-connected sense: two orthogonal 4-neighbours set (a staircase corner,
    or part of a 2×2 block)."""
    north, south = p[iy + 1, ix], p[iy - 1, ix]
    east, west = p[iy, ix + 1], p[iy, ix - 1]
    return (north | south) & (east | west)


def _guo_hall(p: np.ndarray, iy: np.ndarray, ix: np.ndarray, max_iterations: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """Guo and Hall's two sub-iterations on the padded map ``p`` (in place), whose set
    pixels are ``(iy, ix)``, until nothing changes; returns the set pixels left."""
    for _ in range(max_iterations):
        before = len(iy)
        for table in (_DELETE_FIRST, _DELETE_SECOND):
            gone = table[_codes_at(p, iy, ix)]
            p[iy[gone], ix[gone]] = False
            iy, ix = iy[~gone], ix[~gone]
        if len(iy) == before:
            break
    return iy, ix


def thin(binary: np.ndarray, max_iterations: int = 10_000) -> np.ndarray:
    """Thin occupied bands to one-pixel-wide 8-connected curves, keeping the connectivity
    (and the holes) of every band.

    Guo and Hall's parallel thinning (the algorithm of ``skimage.morphology.thin``) runs
    to convergence; it can leave 2×2 blocks and staircase corners, whose *simple* pixels
    (deleting them keeps the topology) are then deleted one parity subfield at a time —
    pixels of one subfield are never neighbours, so deleting them together cannot
    disconnect anything. Both steps repeat until nothing changes. Each step looks only at
    the set pixels (their indices kept as pixels are deleted, the map padded once).
    """
    p = np.pad(np.asarray(binary, dtype=bool), 1)
    iy, ix = nonzero_cells(p)
    for _ in range(max_iterations):
        before = len(iy)
        iy, ix = _guo_hall(p, iy, ix, max_iterations)
        for a, b in ((1, 1), (1, 0), (0, 1), (0, 0)):  # the parities of the unpadded map
            mine = np.flatnonzero((iy % 2 == a) & (ix % 2 == b))
            gone = mine[_redundant_at(p, iy[mine], ix[mine])
                        & _SIMPLE[_codes_at(p, iy[mine], ix[mine])]]
            p[iy[gone], ix[gone]] = False
            keep = np.ones(len(iy), dtype=bool)
            keep[gone] = False
            iy, ix = iy[keep], ix[keep]
        if len(iy) == before:
            break
    return p[1:-1, 1:-1].copy()


#: A part of the map runs along x where its occupied cells spread along x more than this
#: many times (in second moment) as along y: within about 35° of x.
ALONG_RATIO = 2.0

#: Half-width in cells of the window whose occupied cells give a cell's local direction
#: (:func:`along_x`).
WINDOW_HALF_WIDTH = 10


def along_x(occupied: np.ndarray) -> np.ndarray:
    """[ny, nx] bool: the occupied cells where the map runs along x, from the map alone (the
    principal direction of its cells, by their second moments Σ dx² and Σ dy²):

    - none, when the map as a whole runs along y (Σ dy² ≥ Σ dx² over all its cells), as the
      maps of the thesis' scenes do — their walls, and the loci around them, run along y;
    - otherwise each cell whose neighbourhood, the (2·:data:`WINDOW_HALF_WIDTH` + 1)² window
      around it, runs along x (Σ dx² > :data:`ALONG_RATIO` · Σ dy² of the occupied cells
      in it): the walls along x of a corridor or a room, each part of a room's outline in
      its own direction.
    """
    from scipy import ndimage  # only here: its import costs a plain run 0.2 s

    b = np.asarray(occupied, dtype=bool)
    iy, ix = nonzero_cells(b)
    if len(iy) == 0 or np.var(iy) >= np.var(ix):
        return np.zeros_like(b)
    o = b.astype(np.float64)
    size = 2 * WINDOW_HALF_WIDTH + 1
    offsets2 = np.arange(-WINDOW_HALF_WIDTH, WINDOW_HALF_WIDTH + 1, dtype=np.float64) ** 2
    spread_x = ndimage.correlate1d(ndimage.uniform_filter1d(o, size, axis=0, mode="constant"),
                                   offsets2, axis=1, mode="constant")
    spread_y = ndimage.correlate1d(ndimage.uniform_filter1d(o, size, axis=1, mode="constant"),
                                   offsets2, axis=0, mode="constant")
    return b & (spread_x > ALONG_RATIO * spread_y + 1e-9)


def thin_oriented(binary: np.ndarray) -> np.ndarray:
    """Eq. 2.5 in the direction that fits the surface: the thesis writes its template for
    walls along y (rows along x, :func:`thin_thesis`'s default), where it keeps the edge of
    a band at smaller x; where the map runs along x (:func:`along_x`) the same template
    runs along y and keeps the edge at smaller y. A wall along x would otherwise vanish:
    its band has no cell with three empty cells at smaller x and three full ones at
    larger x. Maps that run along y (the thesis' scenes) thin exactly as
    :func:`thin_thesis`."""
    b = np.asarray(binary, dtype=bool)
    rows = thin_thesis(b)
    turn = along_x(b)
    if not turn.any():
        return rows
    return np.where(turn, thin_thesis(b, up=(-1, 0)), rows)


def thin_map(occupied: np.ndarray, settings: PostSettings) -> np.ndarray:
    """The thinning stage: eq. 2.5 in the direction that fits the surface (``thesis``,
    :func:`thin_oriented`) or :func:`thin` (``guo-hall``)."""
    return thin_oriented(occupied) if settings.thinning == "thesis" else thin(occupied)


__all__ = ["along_x", "thin", "thin_map", "thin_oriented", "thin_thesis"]
