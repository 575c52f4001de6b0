"""Nearest neighbours in the plane, without importing ``scipy.spatial`` (its package pulls
scipy.sparse, linalg and special: 0.3 s of a room's 1.5 s run as a process, issue 16).

The scores and the profile ask three questions of point sets, each answered exactly, with
the distances and bounds of ``cKDTree`` (the square root of dx² + dy²; a query's upper
bound r holds where dx² + dy² < r², a pair within r where dx² + dy² ≤ r²):

- :func:`nearest_within`: each query's distance to the nearest point where that is less
  than a radius (``inf`` from it on). The points are binned into square cells of the radius
  (:class:`_Cells`) and each query tests the points of its own cell and the 8 around it, a
  chunk of queries at a time (bounded memory on a 100 m floor's million points);
- :func:`pairs_within`: the pairs of points within a radius, by the same cells;
- :func:`nearest`: each query's distance to the nearest point at any range, by brute force
  in chunks: for few points (the true and located vertices).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .numerics import unique

#: Query-point pairs held at once: about 4 million (tens of MB).
_CHUNK_PAIRS = 1 << 22

#: From this many points and queries together, scipy's k-d tree answers instead (the same
#: results, tested): its import is then a small share of the work, and it is 5× faster.
TREE_FROM = 200_000


def _as_points(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=np.float64).reshape(-1, 2)


def nearest(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """[Q] the distance from each of ``queries`` [Q, 2] to the nearest of ``points`` [P, 2]
    (``inf`` when there are none): ``cKDTree(points).query(queries)[0]``."""
    pts, q = _as_points(points), _as_points(queries)
    out = np.full(len(q), np.inf)
    if len(pts) == 0:
        return out
    step = max(1, _CHUNK_PAIRS // len(pts))
    for s in range(0, len(q), step):
        d = q[s:s + step, None] - pts[None]
        out[s:s + step] = np.sqrt(np.min(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1], axis=1))
    return out


class _Cells:
    """``points`` binned into square cells a little wider than ``radius`` (so that a point
    within ``radius`` of a query is, whatever the rounding, in one of the 3 × 3 cells
    around the query's), sorted by cell."""

    def __init__(self, points: np.ndarray, radius: float) -> None:
        self.size = radius * (1.0 + 1e-6)
        self.origin = points.min(axis=0)
        cells = np.floor((points - self.origin) / self.size).astype(np.int64)
        self.high = cells.max(axis=0)
        self.width = int(self.high[1]) + 1
        keys = cells[:, 0] * self.width + cells[:, 1]
        self.order = np.argsort(keys, kind="stable")
        self.keys, self.points = keys[self.order], points[self.order]
        per_cell = len(points) / len(unique(keys))
        self.chunk = max(1, int(_CHUNK_PAIRS / (9 * per_cell)))

    def candidates(self, q: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """For each of the 3 × 3 cells around each of ``q`` [Q, 2] in turn: ``(count [Q],
        who, at)``: how many points that cell holds for each query, and for each of them
        the query's index and the point's (sorted) index, grouped by query."""
        home = np.floor((q - self.origin) / self.size)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                cell = home + np.array([dx, dy])
                inside = np.all((cell >= 0) & (cell <= self.high), axis=1)
                key = np.where(inside, cell[:, 0] * self.width + cell[:, 1], -1)
                key = key.astype(np.int64)
                lo = np.searchsorted(self.keys, key, "left")
                count = np.where(inside, np.searchsorted(self.keys, key, "right") - lo, 0)
                if count.any():
                    first = np.cumsum(count) - count
                    at = np.arange(count.sum()) - np.repeat(first - lo, count)
                    yield count, np.repeat(np.arange(len(q)), count), at


def _squared(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = a - b
    return d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]


def nearest_within(points: np.ndarray, queries: np.ndarray, radius: float) -> np.ndarray:
    """[Q] the distance from each of ``queries`` [Q, 2] to the nearest of ``points`` [P, 2]
    where it is less than ``radius`` (> 0), else ``inf``: ``cKDTree(points).query(queries,
    distance_upper_bound=radius)[0]``."""
    pts, q = _as_points(points), _as_points(queries)
    best = np.full(len(q), np.inf)
    if len(pts) == 0 or len(q) == 0:
        return best
    if len(pts) + len(q) >= TREE_FROM:
        from scipy.spatial import cKDTree

        return cKDTree(pts).query(q, distance_upper_bound=radius)[0]
    cells = _Cells(pts, radius)
    for s in range(0, len(q), cells.chunk):
        part = best[s:s + cells.chunk]  # a view: filled in place
        for count, who, at in cells.candidates(q[s:s + cells.chunk]):
            d2 = _squared(cells.points[at], q[s + who])
            has = count > 0
            first = (np.cumsum(count) - count)[has]
            part[has] = np.minimum(part[has], np.minimum.reduceat(d2, first))
    return np.where(best < radius * radius, np.sqrt(best), np.inf)  # strictly, as the tree


def pairs_within(points: np.ndarray, radius: float) -> np.ndarray:
    """[n, 2] the pairs ``i < j`` of ``points`` [P, 2] at most ``radius`` apart, in
    ascending order: ``sorted(cKDTree(points).query_pairs(radius))``."""
    pts = _as_points(points)
    if len(pts) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    if len(pts) >= TREE_FROM:
        from scipy.spatial import cKDTree

        return np.array(sorted(cKDTree(pts).query_pairs(radius)), dtype=np.int64).reshape(-1, 2)
    cells = _Cells(pts, radius)
    found = []
    for s in range(0, len(pts), cells.chunk):
        q = pts[s:s + cells.chunk]
        for _, who, at in cells.candidates(q):
            i, j = s + who, cells.order[at]
            keep = (i < j) & (_squared(pts[j], pts[i]) <= radius * radius)
            found.append(np.stack([i[keep], j[keep]], axis=1))
    out = np.concatenate(found) if found else np.zeros((0, 2), dtype=np.int64)
    return out[np.lexsort((out[:, 1], out[:, 0]))].astype(np.int64)
