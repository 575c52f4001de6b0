"""The thinned cells as curves (thesis §2.1.1, part 5): linked into ordered curves,
refined to sub-cell positions and joined across gaps.

- :func:`trace_curves`: the one-cell curves of a thinned map, cell by cell;
- :func:`refine_cells` and :func:`refine_to_points`: sub-cell positions from the filtered
  map or from the mapped points;
- :func:`bridge_gaps`: curves whose ends are close joined into one.

Maps are indexed ``[iy, ix]`` with ``iy`` growing with y (docs/design.md).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from ..mapping.points import nonzero_cells
from .filters import voted_box

#: Linked curves shorter than this many cells are dropped as specks.
MIN_CURVE_CELLS = 5

_STEPS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]

def trace_curves(thin_map: np.ndarray, min_cells: int = MIN_CURVE_CELLS) -> list[np.ndarray]:
    """Link the cells of a thinned map into ordered curves ([n, 2] ``(iy, ix)`` each).

    Cells with one neighbour are curve ends, cells with three or more are junctions; each
    run between ends and junctions becomes a curve (a closed loop without junctions is one
    curve, its first cell repeated at its end). Curves of fewer than ``min_cells`` cells
    (spurs, specks) are dropped. A cell is walked as one integer, ``iy·w + ix`` (w one more
    than the map's width: a step off either side lands on no cell), whose order is the
    ``(iy, ix)`` order.
    """
    t = np.asarray(thin_map, dtype=bool)
    rows, cols = voted_box(t, margin=1)  # only the set cells' box is looked at
    part = t[rows, cols]
    iy, ix = nonzero_cells(part)
    codes = _codes(part, iy, ix)
    w = t.shape[1] + 1
    keys = (iy + rows.start) * w + (ix + cols.start)
    cells = dict(zip(keys.tolist(), codes.tolist(), strict=True))
    steps = _steps(w)
    node = {c for c, code in cells.items() if len(_OFFSETS[code]) != 2}
    used_edges: set[tuple[int, int]] = set()
    curves = []
    for start in sorted(node):
        for first in _neighbours(start, cells, steps):
            if (start, first) not in used_edges:
                curves.append(_walk(start, first, cells, node, used_edges, steps))
    visited = {c for curve in curves for c in curve}
    for start in sorted(cells.keys() - visited - node):  # closed loops without junctions
        if start in visited:
            continue
        first = _neighbours(start, cells, steps)[0]
        loop = _walk(start, first, cells, node, used_edges, steps)
        visited.update(loop)
        curves.append(loop)
    return [np.stack(np.divmod(np.array(c, dtype=np.int64), w), axis=-1)
            for c in curves if len(c) >= min_cells]


#: Per 8-bit code (bit s set: the neighbour ``_STEPS[s]`` is set), those neighbours' steps,
#: and the same with the 4-neighbours first (a stable sort: ``_STEPS`` order within each).
_OFFSETS = [tuple(st for bit, st in enumerate(_STEPS) if code >> bit & 1) for code in range(256)]
_BY_NEARNESS = [tuple(sorted(steps, key=lambda st: abs(st[0]) + abs(st[1])))
                for steps in _OFFSETS]


def _steps(w: int) -> tuple[list[tuple[int, ...]], list[tuple[int, ...]]]:
    """:data:`_OFFSETS` and :data:`_BY_NEARNESS` as steps between cell numbers ``iy·w + ix``."""
    return ([tuple(dy * w + dx for dy, dx in steps) for steps in _OFFSETS],
            [tuple(dy * w + dx for dy, dx in steps) for steps in _BY_NEARNESS])


def _codes(part: np.ndarray, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """Which of the 8 neighbours of the set cells ``(iy, ix)`` of ``part`` are set (cells
    outside it unset), bit s for ``_STEPS[s]``, at those cells only: a few per cent of the
    map. The number of bits set is the cell's degree."""
    p = np.pad(part, 1)
    return sum((p[iy + 1 + dy, ix + 1 + dx].astype(np.int64) << bit
                for bit, (dy, dx) in enumerate(_STEPS)), start=np.zeros(len(iy), dtype=np.int64))


def _walk(start: int, first: int, cells: dict[int, int], node: set[int],
          used_edges: set[tuple[int, int]],
          steps: tuple[list[tuple[int, ...]], list[tuple[int, ...]]]) -> list[int]:
    """The cells from ``start`` through its neighbour ``first`` on to the next end or
    junction (``node``), or back to ``start``; marks each step taken in ``used_edges``.
    Each step goes to the first neighbour not come from nor stepped to before, the
    4-neighbours first (the curve's next cell at a staircase), in ``_STEPS`` order
    (``steps``: :func:`_steps`)."""
    nearness = steps[1]
    path = [start, first]
    used_edges.add((start, first))
    used_edges.add((first, start))
    prev, here = start, first
    while here not in node and here != start:
        for d in nearness[cells[here]]:
            n = here + d
            if n != prev and (here, n) not in used_edges:
                break
        else:
            break
        prev, here = here, n
        used_edges.add((prev, here))
        used_edges.add((here, prev))
        path.append(here)
    return path


def _neighbours(c: int, cells: dict[int, int],
                steps: tuple[list[tuple[int, ...]], list[tuple[int, ...]]]) -> list[int]:
    """The 8-neighbours of cell ``c`` among ``cells`` (each cell's code of :func:`_codes`),
    in the order of ``_STEPS``."""
    return [c + d for d in steps[0][cells[c]]]


def bridge_gaps(curves: list[np.ndarray], max_gap: float) -> list[np.ndarray]:
    """Join curves whose ends are within ``max_gap`` (same units as the points), nearest
    ends first, each end at most once and never into a loop, reversing curves as needed:
    gaps left by unscanned parts of a surface."""
    curves = [np.asarray(c, dtype=np.float64) for c in curves]
    if len(curves) < 2:
        return curves
    link = _end_links(curves, max_gap)
    out, done = [], set()
    for i in range(len(curves)):
        if i in done or (2 * i in link and 2 * i + 1 in link):
            continue  # chains are walked from a curve with a free end
        start_end = 2 * i if 2 * i not in link else 2 * i + 1  # the free end
        chain, end = [], start_end
        while True:
            k = end // 2
            done.add(k)
            chain.append(curves[k] if end % 2 == 0 else curves[k][::-1])
            other = end ^ 1  # the far end of this curve
            if other not in link:
                break
            end = link[other]
        out.append(np.concatenate(chain))
    return out


def _end_links(curves: list[np.ndarray], max_gap: float) -> dict[int, int]:
    """Which curve ends :func:`bridge_gaps` joins: end ``2i`` is the start of curve i,
    ``2i + 1`` its end; each joined end maps to the end it is joined to."""
    from scipy.spatial import cKDTree

    ends = np.array([c[k] for c in curves for k in (0, -1)])
    pairs = np.array(sorted(cKDTree(ends).query_pairs(max_gap, output_type="set")))
    link: dict[int, int] = {}
    if len(pairs) == 0:
        return link
    pairs = pairs[pairs[:, 0] // 2 != pairs[:, 1] // 2]
    order = np.argsort(np.hypot(*(ends[pairs[:, 0]] - ends[pairs[:, 1]]).T), kind="stable")
    root = list(range(len(curves)))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    for a, b in pairs[order].tolist():
        if a in link or b in link or find(a // 2) == find(b // 2):
            continue
        link[a], link[b] = b, a
        root[find(a // 2)] = find(b // 2)
    return link


def _around(cells: np.ndarray, shape: tuple[int, ...], radius: int
            ) -> Iterator[tuple[int, int, np.ndarray, np.ndarray, np.ndarray]]:
    """For each offset (dy, dx) of the (2·radius + 1)² window: the offset, the indices
    ``(iy, ix)`` of the cells' neighbours, and which of them lie inside the map (no padded
    copy of the map: this runs once per linked curve)."""
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            iy, ix = cells[:, 0] + dy, cells[:, 1] + dx
            inside = (iy >= 0) & (iy < shape[0]) & (ix >= 0) & (ix < shape[1])
            yield dy, dx, np.where(inside, iy, 0), np.where(inside, ix, 0), inside


def refine_cells(cells: np.ndarray, weights: np.ndarray, radius: int = 1) -> np.ndarray:
    """[n, 2] sub-cell ``(iy, ix)`` of ``cells`` [n, 2]: the centroid of ``weights`` (the
    filtered map) over the (2·radius + 1)² cells around each. A vote ridge symmetric about
    the true surface puts the centroid on it, to a fraction of a cell."""
    cells = np.asarray(cells, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    total = np.zeros(len(cells))
    moment = np.zeros((len(cells), 2))
    for dy, dx, iy, ix, inside in _around(cells, w.shape, radius):
        v = np.where(inside, w[iy, ix], 0.0)
        total += v
        moment += v[:, None] * np.array([dy, dx])
    shift = np.where(total[:, None] > 0, moment / np.maximum(total, 1e-300)[:, None], 0.0)
    return cells + shift


def refine_to_points(cells: np.ndarray, counts: np.ndarray, sums: np.ndarray,
                     radius: int = 1) -> np.ndarray | None:
    """[n, 2] metres: the mean of the points counted in the (2·radius + 1)² cells around each
    of ``cells`` (``counts`` per cell and ``sums`` [ny, nx, 2] of their coordinates); cells
    with no point nearby are dropped (None if none is left)."""
    n, total = point_means(cells, counts, sums, radius)
    keep = n > 0
    return total[keep] / n[keep, None] if keep.any() else None


def point_means(cells: np.ndarray, counts: np.ndarray, sums: np.ndarray, radius: int = 1
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(n [k], sum [k, 2])``: the points counted in the (2·radius + 1)² cells around each
    of ``cells`` [k, 2] and the sum of their coordinates (:func:`refine_to_points`), cell
    by cell."""
    cells = np.asarray(cells, dtype=np.int64)
    n = np.zeros(len(cells))
    total = np.zeros((len(cells), 2))
    for _, _, iy, ix, inside in _around(cells, counts.shape, radius):
        n += np.where(inside, counts[iy, ix], 0.0)
        total += np.where(inside[:, None], sums[iy, ix], 0.0)
    return n, total


__all__ = ["MIN_CURVE_CELLS", "bridge_gaps", "point_means", "refine_cells", "refine_to_points",
           "trace_curves"]
