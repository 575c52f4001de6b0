"""Loci binned to the map's tiles (:func:`bin_loci`), for the tiled kernel ``loci_tiles``:
per tile, in locus order, the loci that may vote for one of its pixels, found conservatively
from bounding boxes (of the locus' outer ellipse and of its two beam sectors) and then ring
and beam tests widened by each tile's half-diagonal, coarse tiles first."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .grid import MapGrid
from .loci import MapProblem

#: Loci the binning takes at once: as many as have about this many tiles in their bounding
#: boxes (bounds its temporary memory).
BIN_CANDIDATES = 1 << 22

#: The binning tests tiles of BIN_REFINE² times as many pixels first, from the coarsest
#: level of at most 8 × 8 such tiles down, and only the children of those kept.
BIN_REFINE = 4

#: float32 roundings (of the coordinates' scale) added to every bound of the binning, so
#: that a pixel the float32 kernel decides to vote for is never left out by it.
BIN_ROUNDINGS = 256


@dataclass(frozen=True, eq=False)
class TileBins:
    """Loci binned to the tiles of a map, as CSR: tile ``k`` (row-major over ``shape``
    = (tiles along y, along x); tile (ty, tx) holds pixels ``[ty·th, ty·th + th)`` ×
    ``[tx·tw, tx·tw + tw)``) may get votes only from loci ``members[start[k]:start[k + 1]]``,
    in ascending order (the order the dense kernel adds them)."""

    shape: tuple[int, int]
    tile: tuple[int, int]  # (tw, th) pixels along x, along y
    start: np.ndarray  # [tiles + 1] int64
    members: np.ndarray  # [m] int64

    @property
    def counts(self) -> np.ndarray:
        """[tiles] loci per tile."""
        return np.diff(self.start)


def _sector_boxes(apex: np.ndarray, axis: np.ndarray, alpha: float,
                  radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding boxes ``(lo [n, 2], hi [n, 2])`` of the circular sectors with ``apex``,
    unit ``axis``, half-angle ``alpha`` (≤ π) and ``radius``: the apex, the two edge ends
    and the ends of the ±x, ±y radii that lie within the sector."""
    phi = np.arctan2(axis[:, 1], axis[:, 0])
    angles = [phi - alpha, phi + alpha]
    points = [apex] + [apex + radius[:, None] * np.stack([np.cos(a), np.sin(a)], axis=1)
                       for a in angles]
    for k, direction in enumerate(((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))):
        off = np.angle(np.exp(1j * (k * math.pi / 2 - phi)))  # wrapped to (−π, π]
        end = apex + radius[:, None] * np.asarray(direction)
        points.append(np.where((np.abs(off) <= alpha)[:, None], end, apex))
    stack = np.stack(points)
    return stack.min(axis=0), stack.max(axis=0)


def _beam_may_hold(centre: np.ndarray, apex: np.ndarray, axis: np.ndarray, alpha: float,
                   radius: np.ndarray) -> np.ndarray:
    """Whether a disc (``centre``, ``radius``) may hold points of the beam (a cone of
    half-angle ``alpha`` ≤ π/2 about ``axis`` from ``apex``): the disc holds the apex, or the
    angle θ to its centre is at most alpha plus its angular radius s = asin(radius/d), i.e.
    cos θ ≥ cos(alpha + s) = cos alpha·sqrt(d² − radius²)/d − sin alpha·radius/d."""
    d = centre - apex
    dist2 = d[:, 0] ** 2 + d[:, 1] ** 2
    along = axis[:, 0] * d[:, 0] + axis[:, 1] * d[:, 1]
    return ((dist2 <= radius * radius)
            | (along >= math.cos(alpha) * np.sqrt(np.maximum(dist2 - radius * radius, 0.0))
               - math.sin(alpha) * radius))


@dataclass(frozen=True, eq=False)
class _Reach:
    """Per locus, what the binning tests against: its rows' columns, its pad (half a cell
    and the float32 roundings), the beams' half-angle, and the range of pixels ``first`` to
    ``last`` (x, y) its band's bounding box covers on the map (``reach``: any)."""

    T: np.ndarray
    R: np.ndarray
    aT: np.ndarray
    aR: np.ndarray
    L: np.ndarray  # c·τ
    half_band: float
    pad: np.ndarray
    alpha: float
    size: np.ndarray  # (nx, ny)
    first: np.ndarray
    last: np.ndarray
    reach: np.ndarray


def _ellipse_boxes(T: np.ndarray, R: np.ndarray, a: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(lo, hi, f)``: bounding boxes of the ellipses |p−T| + |p−R| = 2a (foci 2f apart)."""
    f = 0.5 * np.hypot(*(R - T).T)
    b = np.sqrt(np.maximum(a * a - f * f, 0.0))
    u = np.where((f > 0)[:, None], (R - T) / np.maximum(2.0 * f, 1e-300)[:, None],
                 np.array([1.0, 0.0]))
    half = np.stack([np.hypot(a * u[:, 0], b * u[:, 1]), np.hypot(a * u[:, 1], b * u[:, 0])],
                    axis=1)
    return 0.5 * (T + R) - half, 0.5 * (T + R) + half, f


def _reach(pb: MapProblem) -> _Reach:
    """The :class:`_Reach` of ``pb``'s loci: the bounding box of each band (the outer
    ellipse, path c·τ + band/2) ∩ those of its two beams (sectors out to the ellipse's
    reach a + f) ∩ the map, padded."""
    g, rows = pb.grid, pb.rows
    cell = g.cell
    T, R, aT, aR, L = rows[:, 0:2], rows[:, 2:4], rows[:, 4:6], rows[:, 6:8], rows[:, 8]
    corner = np.abs(np.array([[g.col0, g.row0], [g.col0 + g.nx - 1, g.row0 + g.ny - 1]],
                             dtype=np.float64) * cell).max(axis=0)
    scale = (math.hypot(*corner) + np.hypot(T[:, 0], T[:, 1]) + np.hypot(R[:, 0], R[:, 1])
             + np.abs(L))
    pad = 0.5 * cell + BIN_ROUNDINGS * float(np.finfo(np.float32).eps) * scale
    alpha = math.asin(math.sqrt(min(max(pb.cut_sin2, 0.0), 1.0)))
    a = 0.5 * (L + pb.half_band) + pad
    lo, hi, f = _ellipse_boxes(T, R, a)
    for apex, axis in ((T, aT), (R, aR)):
        s_lo, s_hi = _sector_boxes(apex, axis, alpha, a + f)
        lo, hi = np.maximum(lo, s_lo - pad[:, None]), np.minimum(hi, s_hi + pad[:, None])
    origin = np.array([g.col0, g.row0], dtype=np.float64)
    size = np.array([g.nx, g.ny])
    first = np.clip(np.ceil(lo / cell - origin), -1, size)  # pixel index ranges
    last = np.clip(np.floor(hi / cell - origin), -1, size)
    reach = (a >= f)[:, None] & (first <= last) & (last >= 0) & (first <= size - 1)
    return _Reach(T, R, aT, aR, L, pb.half_band, pad, alpha, size, first, last,
                  reach.all(axis=1))


def band_boxes(pb: MapProblem) -> np.ndarray:
    """[n, 4] int32 ``(x0, y0, x1, y1)``: the map pixels (inclusive) of the bounding box of
    each locus' band inside both beams (:func:`_reach`: the outer ellipse ∩ the beams'
    sectors, padded as the binning is, so every pixel the kernels give a vote lies in it);
    x1 < x0 for a locus that reaches no pixel."""
    if len(pb.rows) == 0:
        return np.zeros((0, 4), dtype=np.int32)
    r = _reach(pb)
    top = r.size - 1
    first, last = np.clip(r.first, 0, top), np.clip(r.last, 0, top)
    last[~r.reach, 0] = first[~r.reach, 0] - 1
    return np.concatenate([first, last], axis=1).astype(np.int32)


def _coarse_levels(ntx: int, nty: int) -> int:
    """Coarse levels of BIN_REFINE² tiles each, down to at most 8 × 8 tiles."""
    levels = 0
    while -(-max(ntx, nty) // BIN_REFINE ** levels) > 8:
        levels += 1
    return levels


def _tiles_of(r: _Reach, tile: tuple[int, int], level: int) -> tuple[np.ndarray, np.ndarray]:
    """Per locus, its first and last tile (x, y) at ``level``."""
    step = np.array(tile) * BIN_REFINE ** level
    t_first = (np.clip(r.first, 0, r.size - 1) // step).astype(np.int64)
    t_last = (np.clip(r.last, 0, r.size - 1) // step).astype(np.int64)
    return t_first, t_last


def _may_vote(r: _Reach, g: MapGrid, tile: tuple[int, int], level: int, li: np.ndarray,
              tx: np.ndarray, ty: np.ndarray) -> np.ndarray:
    """Indices of the (locus ``li``, tile (``tx``, ``ty``) at ``level``) candidates that pass
    the ring test ``| |c−T| + |c−R| − c·τ | ≤ band/2 + 2h`` and both beam tests (h the
    tile's half-diagonal plus the locus' pad, c its centre)."""
    w, hh = tile[0] * BIN_REFINE ** level, tile[1] * BIN_REFINE ** level
    cell = g.cell
    centre = np.stack([(g.col0 + tx * w + 0.5 * (w - 1)) * cell,
                       (g.row0 + ty * hh + 0.5 * (hh - 1)) * cell], axis=1)
    radius = 0.5 * cell * math.hypot(w - 1, hh - 1) + r.pad[li]
    path = np.hypot(*(centre - r.T[li]).T) + np.hypot(*(centre - r.R[li]).T)
    keep = np.flatnonzero(np.abs(path - r.L[li]) <= r.half_band + 2.0 * radius)
    for apex, axis in ((r.T, r.aT), (r.R, r.aR)):
        j = li[keep]
        keep = keep[_beam_may_hold(centre[keep], apex[j], axis[j], r.alpha, radius[keep])]
    return keep


def _children(li: np.ndarray, tx: np.ndarray, ty: np.ndarray,
              bounds: tuple[np.ndarray, np.ndarray]
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The BIN_REFINE² children of tiles (``tx``, ``ty``) a level up, for loci ``li``, that
    lie within each locus' tile ``bounds`` (first, last) at their level."""
    sub = np.arange(BIN_REFINE)
    shape = (len(li), BIN_REFINE, BIN_REFINE)
    tx = np.broadcast_to(tx[:, None, None] * BIN_REFINE + sub, shape).ravel()
    ty = np.broadcast_to(ty[:, None, None] * BIN_REFINE + sub[:, None], shape).ravel()
    li = np.repeat(li, BIN_REFINE * BIN_REFINE)
    lo_t, hi_t = bounds
    inside = ((tx >= lo_t[li, 0]) & (tx <= hi_t[li, 0])
              & (ty >= lo_t[li, 1]) & (ty <= hi_t[li, 1]))
    return li[inside], tx[inside], ty[inside]


def _bin_chunk(r: _Reach, g: MapGrid, tile: tuple[int, int],
               bounds: list[tuple[np.ndarray, np.ndarray]], i0: int, i1: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(li, tx, ty)``: the (locus, finest tile) pairs of loci ``i0`` to ``i1`` that pass
    every level's tests, from the coarsest level's bounding boxes down."""
    levels = len(bounds) - 1
    top_first, top_last = bounds[levels]
    top_span = np.where(r.reach[:, None], top_last - top_first + 1, 0)
    cnt = top_span[i0:i1, 0] * top_span[i0:i1, 1]
    li = np.repeat(np.arange(i0, i1), cnt)
    k = np.arange(len(li)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    tx = top_first[li, 0] + k % top_span[li, 0]
    ty = top_first[li, 1] + k // top_span[li, 0]
    for level in range(levels, -1, -1):
        if level < levels:  # the children of the tiles kept a level up, in bounds
            li, tx, ty = _children(li, tx, ty, bounds[level])
        keep = _may_vote(r, g, tile, level, li, tx, ty)
        li, tx, ty = li[keep], tx[keep], ty[keep]
    return li, tx, ty


def _pairs(pb: MapProblem, tile: tuple[int, int], ntx: int, nty: int
           ) -> tuple[np.ndarray, np.ndarray]:
    """``(tile index, locus)`` of every (tile, locus) pair that passes the tests, loci in
    chunks of about :data:`BIN_CANDIDATES` fine candidates."""
    pairs_tile: list[np.ndarray] = []
    pairs_locus: list[np.ndarray] = []
    n = len(pb.rows)
    if n:
        r = _reach(pb)
        bounds = [_tiles_of(r, tile, level) for level in range(_coarse_levels(ntx, nty) + 1)]
        span0 = np.where(r.reach[:, None], bounds[0][1] - bounds[0][0] + 1, 0)
        ends = np.cumsum(span0[:, 0] * span0[:, 1])  # fine candidates: bounds each chunk
        i0 = 0
        while i0 < n:
            base = ends[i0 - 1] if i0 else 0
            i1 = max(i0 + 1, int(np.searchsorted(ends, base + BIN_CANDIDATES, side="right")))
            i1 = min(i1, n)
            li, tx, ty = _bin_chunk(r, pb.grid, tile, bounds, i0, i1)
            pairs_tile.append(ty * ntx + tx)
            pairs_locus.append(li)
            i0 = i1
    tile_of = np.concatenate(pairs_tile) if pairs_tile else np.zeros(0, np.int64)
    locus = np.concatenate(pairs_locus) if pairs_locus else np.zeros(0, np.int64)
    return tile_of, locus


def bin_loci(pb: MapProblem, tile: tuple[int, int]) -> TileBins:
    """Bin ``pb``'s loci to the map's tiles of ``tile`` = (tw, th) pixels, conservatively:
    a tile lists every locus that may vote for one of its pixels (thesis §2.1.1 part 4: the
    band ``| |p−T| + |p−R| − c·τ | ≤ band/2`` inside both beams).

    Per locus, the candidate tiles are those meeting the bounding box of its band (the
    outer ellipse, path c·τ + band/2) intersected with the bounding boxes of the two beams
    (sectors of half-angle α out to the farthest point of that ellipse) and with the map.
    A candidate tile, whose pixel centres lie within h (its half-diagonal) of its centre c,
    keeps the locus iff ``| |c−T| + |c−R| − c·τ | ≤ band/2 + 2h`` (each distance changes by
    at most h across the tile) and c's direction from each transducer is within α plus
    asin(h/|c−T|) of its axis. Every bound is widened by half a cell and
    :data:`BIN_ROUNDINGS` float32 roundings of the coordinates' scale, so the float32
    kernel's decisions near an edge are covered too.
    """
    g = pb.grid
    tw, th = tile
    ntx, nty = -(-g.nx // tw), -(-g.ny // th)
    n_tiles = ntx * nty
    tile_of, locus = _pairs(pb, tile, ntx, nty)
    order = np.argsort(tile_of, kind="stable")  # loci ascending within each tile
    start = np.zeros(n_tiles + 1, dtype=np.int64)
    np.cumsum(np.bincount(tile_of, minlength=n_tiles), out=start[1:])
    return TileBins((nty, ntx), (tw, th), start, locus[order].astype(np.int64))
