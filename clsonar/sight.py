"""Line of sight (thesis §2.1.2, §3.6): estimated reflection points that were never in sight
of their pair are ghosts.

An estimated reflection point q of the pair (T, R) is real only if sound can go T → q → R,
so a point that the map itself shows hidden behind a surface, as seen from T or from R, is a
ghost — the locus of a multiply reflected echo drawn as if it were a single reflection
(thesis §2.1.2: "for edges, corners, and cylinders multiple reflections occur"). Each
transducer's first hit in every direction is taken from the occupied cells (a polar
z-buffer), and points farther than it by more than a margin go.

The pipeline runs this step in the open, between the map and its post-processing
(:mod:`clsonar.pipeline`): map the points → post-process them (pass 1) → drop the points
hidden behind that map → map and post-process the rest. It reads the post-processing
settings, so a change of them re-runs it (``pipeline.rerun_post``).
"""

from __future__ import annotations

import math

import numpy as np

from .geometry import cell_centres
from .mapping import point_map, points_window
from .post import extract_profile, filter_and_thin
from .scene import Scene

#: Angular resolution of the polar z-buffer of first hits, radians (0.1°).
SIGHT_BIN_RAD = math.radians(0.1)

#: A point may lie this many cells behind the first hit in its direction and still be seen
#: (the occupied band of a wall is a few cells thick; a corner's two walls meet there).
SIGHT_MARGIN_CELLS = 4


def first_hits(origin: np.ndarray, occluders: np.ndarray, cell: float,
               bin_rad: float = SIGHT_BIN_RAD, *, within: float = math.inf,
               wanted: np.ndarray | None = None) -> np.ndarray:
    """[B] distance from ``origin`` [2] to the nearest of the occupied cells ``occluders``
    [m, 2] (their centres) in each direction bin of ``bin_rad``; inf where none. A cell
    covers every bin within its angular half-width 0.75·cell/d.

    Only what a caller asks for is computed: cells farther than ``within`` and cells that
    cover none of the ``wanted`` bins (bool [B]) are left out (their bins may read inf)."""
    bins = round(2 * math.pi / bin_rad)
    hits = np.full(bins, np.inf)
    d = occluders - origin
    dist = np.hypot(d[:, 0], d[:, 1])
    ok = (dist > 0.5 * cell) & (dist <= within)
    dist, d = dist[ok], d[ok]
    theta = np.arctan2(d[:, 1], d[:, 0])
    half = 0.75 * cell / dist
    lo = np.floor((theta - half) / bin_rad).astype(np.int64)
    width = np.floor((theta + half) / bin_rad).astype(np.int64) - lo
    if wanted is not None:  # keep cells whose bins lo .. lo+width meet a wanted bin
        count = np.concatenate([[0], np.cumsum(np.tile(wanted, 2))])
        start = lo % bins
        use = count[start + width + 1] - count[start] > 0
        dist, lo, width = dist[use], lo[use], width[use]
    count = width + 1  # every bin lo .. lo + width of every cell, in one scatter
    first = np.cumsum(count) - count
    offset = np.arange(int(count.sum())) - np.repeat(first, count)
    np.minimum.at(hits, (np.repeat(lo, count) + offset) % bins, np.repeat(dist, count))
    return hits


def _bin(origin: np.ndarray, points: np.ndarray, bins: int, bin_rad: float) -> np.ndarray:
    d = points - origin
    return np.floor(np.arctan2(d[:, 1], d[:, 0]) / bin_rad).astype(np.int64) % bins


def line_of_sight(points: np.ndarray, tx: np.ndarray, rx: np.ndarray,
                  positions: np.ndarray, occluders: np.ndarray, cell: float,
                  margin_m: float | None = None) -> np.ndarray:
    """[n] bool: which estimated reflection ``points`` [n, 2] of the pairs (``tx``, ``rx``)
    [n] are in sight of both transducers (``positions`` [N, 2]) — no occupied cell of
    ``occluders`` [m, 2] lies nearer than the point by more than ``margin_m`` (default
    :data:`SIGHT_MARGIN_CELLS` cells) in the point's direction, from T and from R."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    margin = SIGHT_MARGIN_CELLS * cell if margin_m is None else margin_m
    keep = np.ones(len(points), dtype=bool)
    if len(points) == 0 or len(occluders) == 0:
        return keep
    bins = round(2 * math.pi / SIGHT_BIN_RAD)
    for s, mine in _points_of_each_sensor(np.asarray(tx), np.asarray(rx)):
        origin = positions[s]
        q = points[mine]
        dist = np.hypot(*(q - origin).T)
        where = _bin(origin, q, bins, SIGHT_BIN_RAD)
        wanted = np.zeros(bins, dtype=bool)
        wanted[where] = True
        hits = first_hits(origin, occluders, cell, within=dist.max() - margin, wanted=wanted)
        keep[mine[dist > hits[where] + margin]] = False
    return keep


def _points_of_each_sensor(tx: np.ndarray, rx: np.ndarray):
    """For each sensor in ``tx`` or ``rx`` (ascending): the indices (ascending) of the
    points whose pair it is part of."""
    sensor = np.concatenate([tx, rx])
    point = np.concatenate([np.arange(len(tx)), np.arange(len(rx))])
    order = np.lexsort((point, sensor))
    sensor, point = sensor[order], point[order]
    new = np.r_[True, (sensor[1:] != sensor[:-1]) | (point[1:] != point[:-1])]  # T = R once
    sensor, point = sensor[new], point[new]
    starts = np.flatnonzero(np.r_[True, sensor[1:] != sensor[:-1]])
    for a, b in zip(starts, np.r_[starts[1:], len(sensor)], strict=True):
        yield sensor[a], point[a:b]


def in_sight_of_map(scene: Scene, positions: np.ndarray, points: np.ndarray,
                    tx: np.ndarray, rx: np.ndarray, box: bool = True) -> np.ndarray:
    """:func:`line_of_sight` against the map the ``points`` make themselves: the occluders
    are the thinned cells of their point map (low-pass, automatic level and thinning, as
    the pipeline draws it; an 8-connected one-cell curve covers every z-buffer bin it
    spans) and the profile extracted from it — where the profile bridges the gaps between
    the patches of a wall (``fit = "walls"``), a ghost cannot slip through. ``box``: this
    map is drawn only over the points' box of cells (:func:`clsonar.mapping.points_window`;
    sub-cell profiles come from the points themselves, so nothing changes)."""
    window = points_window(scene, points) if box and scene.post.subcell else None
    row0, col0 = (window[0], window[1]) if window is not None else (0, 0)
    counts, sums = point_map(scene, points, window)
    filtered, _, thin = filter_and_thin(counts, scene.post, points=True, box=box)
    profile = extract_profile(thin, scene.extent, scene.cell, scene.post, filtered, counts, sums)
    iy, ix = np.nonzero(thin)  # one-cell curves leave no gap between z-buffer bins
    cells = cell_centres(scene.extent, scene.cell, iy + row0, ix + col0)
    occluders = np.concatenate([cells, profile.points])
    return line_of_sight(points, tx, rx, positions, occluders, scene.cell)


__all__ = ["first_hits", "in_sight_of_map", "line_of_sight"]
