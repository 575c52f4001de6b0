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
from typing import NamedTuple

import numpy as np

from . import steps
from .geometry import cell_centres
from .mapping import point_map, points_window
from .mapping.points import nonzero_cells
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


def first_hits_each(origins: np.ndarray, occluders: np.ndarray, cell: float,
                    within: np.ndarray, wanted: np.ndarray,
                    bin_rad: float = SIGHT_BIN_RAD, tiles: Tiles | None = None) -> np.ndarray:
    """[S, B] :func:`first_hits` of each of ``origins`` [S, 2] in one pass, with its own
    ``within`` [S] and ``wanted`` bins [S, B]; ``tiles``: :func:`occluder_tiles` of these
    occluders and cell, when already made.

    Only the (origin, occluder) pairs that :func:`_candidate_pairs` keeps are looked at (of
    the occluders within ``within`` of the origins' box along x and y): every occluder near
    enough and inside (or whose cell reaches into) the arc of the origin's wanted bins, found
    tile by tile. Those pairs go through the very arithmetic of :func:`first_hits`, so the
    distances are the same to the bit (tests/test_rooms.py; tests/test_speed_sight.py
    against the dense pre-filter of every pair this replaced). :func:`first_hits_at` is
    the same search giving the wanted bins alone."""
    n, bins = wanted.shape
    hits = np.full(n * bins, np.inf)
    owner, dist, lo, width = _covering(origins, occluders, cell, within,
                                       _wanted_arcs(wanted, bin_rad), bin_rad, tiles)
    use = _wanted_between(wanted, owner, lo % bins, width) > 0
    owner, dist, lo, width = owner[use], dist[use], lo[use], width[use]
    span = width + 1  # every bin lo .. lo + width of every cell, in one scatter
    first = np.cumsum(span) - span
    offset = np.arange(int(span.sum())) - np.repeat(first, span)
    where = np.repeat(owner * bins, span) + (np.repeat(lo, span) + offset) % bins
    np.minimum.at(hits, where, np.repeat(dist, span))
    return hits.reshape(n, bins)


def first_hits_at(origins: np.ndarray, occluders: np.ndarray, cell: float,
                  within: np.ndarray, rows: np.ndarray, at: np.ndarray, bins: int,
                  bin_rad: float = SIGHT_BIN_RAD, tiles: Tiles | None = None) -> np.ndarray:
    """[w] :func:`first_hits_each`'s distances in the wanted bins alone: bin ``at[k]`` of
    origin ``rows[k]`` (each once, by origin then bin: ``np.nonzero`` of the wanted
    [S, ``bins``]). Each pair's cell is scattered only into the wanted bins it covers
    (found in the sorted keys row·bins + bin, its range of bins round the circle in at
    most two runs) rather than into every bin it covers: the minimum of the same
    distances in each wanted bin (in any order: a minimum of numbers, none NaN, is one of
    them), so the same bits, without the [S, B] arrays (the room's near cells cover
    hundreds of bins each, a few of them wanted)."""
    keys = rows * bins + at
    hits = np.full(len(keys), np.inf)
    owner, dist, lo, width = _covering(origins, occluders, cell, within,
                                       _arcs_of(rows, at, len(origins), bins, bin_rad),
                                       bin_rad, tiles)
    base, start = owner * bins, lo % bins
    end = start + width  # the last bin, past the circle's end where it goes round
    a1 = np.searchsorted(keys, base + start)
    n1 = np.searchsorted(keys, base + np.minimum(end, bins - 1), side="right") - a1
    a2 = np.searchsorted(keys, base)  # round the circle: bins 0 .. end − bins
    n2 = np.where(end >= bins, np.searchsorted(keys, base + end - bins, side="right") - a2, 0)
    count = n1 + n2
    pair = np.repeat(np.arange(len(count)), count)
    offset = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    past = offset >= n1[pair]
    where = np.where(past, a2[pair] + offset - n1[pair], a1[pair] + offset)
    if len(where):  # each bin's least distance (np.minimum.at's, in a third of its time)
        order = np.argsort(where, kind="stable")
        where, value = where[order], dist[pair[order]]
        first = np.flatnonzero(np.r_[True, where[1:] != where[:-1]])
        hits[where[first]] = np.minimum.reduceat(value, first)
    return hits


def _covering(origins: np.ndarray, occluders: np.ndarray, cell: float, within: np.ndarray,
              arcs: tuple[np.ndarray, np.ndarray], bin_rad: float, tiles: Tiles | None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(origin, distance, lo, width)`` of the (origin, occluder) pairs :func:`first_hits`
    would use but for the wanted bins (farther than half a cell, at most ``within``), of
    the :func:`_candidate_pairs` within the origins' box: each cell covers the bins lo ..
    lo + width (lo may be negative: round the circle), its arithmetic
    :func:`first_hits`'s."""
    reach = float(np.max(within, initial=0.0))  # none farther along x or y is used
    (x0, y0), (x1, y1) = origins.min(axis=0) - reach, origins.max(axis=0) + reach
    if tiles is None:
        tiles = occluder_tiles(occluders, cell)
    owner, cell_of, dx, dy = _candidate_pairs(origins, occluders, tiles, cell, within, *arcs)
    x, y = occluders[:, 0][cell_of], occluders[:, 1][cell_of]
    box = (x >= x0) & (y >= y0) & (x <= x1) & (y <= y1)
    owner, dx, dy = owner[box], dx[box], dy[box]
    dist = np.hypot(dx, dy)
    ok = (dist > 0.5 * cell) & (dist <= within[owner])
    owner, dx, dy, dist = owner[ok], dx[ok], dy[ok], dist[ok]
    theta = np.arctan2(dy, dx)
    half = 0.75 * cell / dist
    lo = np.floor((theta - half) / bin_rad).astype(np.int64)
    width = np.floor((theta + half) / bin_rad).astype(np.int64) - lo
    return owner, dist, lo, width


def _wanted_between(wanted: np.ndarray, row: np.ndarray, start: np.ndarray,
                    width: np.ndarray) -> np.ndarray:
    """How many of the bins ``start`` … ``start + width`` (round the circle, width below
    the number of bins) of each ``row`` of ``wanted`` [S, B] are wanted: prefix counts
    of each row, the range's end taken round once where it passes the last bin."""
    n, bins = wanted.shape
    count = np.zeros((n, bins + 1), dtype=np.int32)
    np.cumsum(wanted, axis=1, dtype=np.int32, out=count[:, 1:])
    flat = count.ravel()
    base = row * (bins + 1)
    end = start + width + 1
    past = end > bins
    return (flat[base + np.where(past, end - bins, end)] - flat[base + start]
            + np.where(past, flat[base + bins], 0))


#: Side of the square tiles :func:`occluder_tiles` gathers the occluders in, cells (32:
#: with the z-buffers in the wanted bins alone, the room's line of sight 14.8 ms with 16,
#: 12.8 with 32, 18 with 48; any size gives the same bits).
SIGHT_TILE_CELLS = 32


class Tiles(NamedTuple):
    """Occluders gathered in square tiles (:func:`occluder_tiles`): ``order`` [m] lists
    them tile by tile, tile k holding ``order[starts[k]:ends[k]]``, all within ``radius[k]``
    of ``centre[k]`` [T, 2]."""

    order: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    centre: np.ndarray
    radius: np.ndarray


def occluder_tiles(occluders: np.ndarray, cell: float) -> Tiles:
    """The ``occluders`` [m, 2] in square tiles of :data:`SIGHT_TILE_CELLS` cells, each
    with the centre of its occluders' box and a radius a little over the farthest one's
    distance from it (rounding)."""
    if len(occluders) == 0:
        none = np.zeros(0, np.int64)
        return Tiles(none, none, none, np.zeros((0, 2)), np.zeros(0))
    key = np.floor((occluders - occluders.min(axis=0)) / (SIGHT_TILE_CELLS * cell))
    order = np.lexsort((key[:, 1], key[:, 0]))
    key = key[order]
    starts = np.flatnonzero(np.r_[True, (key[1:, 0] != key[:-1, 0]) | (key[1:, 1] != key[:-1, 1])])
    ends = np.r_[starts[1:], len(order)]
    held = occluders[order]
    centre = 0.5 * (np.minimum.reduceat(held, starts) + np.maximum.reduceat(held, starts))
    gap = held - np.repeat(centre, ends - starts, axis=0)
    radius = np.maximum.reduceat(np.hypot(gap[:, 0], gap[:, 1]), starts) * (1 + 1e-9) + 1e-9
    return Tiles(order, starts, ends, centre, radius)


def _candidate_pairs(origins: np.ndarray, occluders: np.ndarray, tiles: Tiles, cell: float,
                     within: np.ndarray, phi: np.ndarray, beta: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(origin, occluder, dx, dy)``: index pairs, a superset of those :func:`first_hits`
    uses (farther than half a cell, at most ``within`` [S], the cell's bins meeting a
    wanted one), by origin, and the occluder's offset from the origin. A tile (disc of
    centre c, radius ρ) is kept for an origin when it may reach within ``within`` and may
    hold an occluder whose cell reaches the arc φ ± β of the origin's wanted bins
    (:func:`_wanted_arcs`): seen from the origin at distance R, the disc's occluders lie
    within asin(ρ/R) of c's direction, farther than max(R − ρ, cell/2), so their cells'
    angular half-widths are below 0.75·cell/max(R − ρ, cell/2). :func:`_may_cover` then
    narrows the kept tiles' pairs."""
    v = tiles.centre[None, :, :] - origins[:, None, :]
    r = np.hypot(v[..., 0], v[..., 1])
    rho = tiles.radius
    with np.errstate(divide="ignore", invalid="ignore"):
        spread = np.arcsin(np.minimum(rho / r, 1.0))
    reach = beta[:, None] + spread + 0.75 * cell / np.maximum(r - rho, 0.5 * cell) + 1e-6
    toward = (v[..., 0] * np.cos(phi)[:, None] + v[..., 1] * np.sin(phi)[:, None]
              >= r * np.cos(np.minimum(reach, math.pi)) - 1e-9 * (r + 1.0))
    keep = (r - rho <= within[:, None] + 1e-9 * (r + 1.0)) & ((reach >= math.pi) | toward)
    owner, tile = nonzero_cells(keep)
    count = (tiles.ends - tiles.starts)[tile]
    first = np.cumsum(count) - count
    member = np.repeat(tiles.starts[tile] - first, count) + np.arange(int(count.sum()))
    owner, cell_of = np.repeat(owner, count), tiles.order[member]
    dx = occluders[:, 0][cell_of] - origins[:, 0][owner]
    dy = occluders[:, 1][cell_of] - origins[:, 1][owner]
    near = _may_cover(dx, dy, cell, within, phi, beta, owner)
    return owner[near], cell_of[near], dx[near], dy[near]


#: Rounding allowance of :func:`_may_cover`'s cheap distances and angles (metres per metre;
#: its arcs are also widened by two bins): far above float64's rounding, far below a cell.
_COVER_SLACK = 1e-9


def _may_cover(dx: np.ndarray, dy: np.ndarray, cell: float, within: np.ndarray,
               phi: np.ndarray, beta: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """[k] bool, a superset of the (origin, occluder) pairs :func:`first_hits` uses, of
    the pairs [k] (``owner`` [k]: the origin of each, ``within``, ``phi`` and ``beta`` [S]
    by origin): the occluder at (``dx``, ``dy``) from its origin is, up to rounding,
    farther than half a cell and at most ``within``, and its cell's angular half-width
    h = 0.75·cell/r reaches the arc ``phi`` ± ``beta`` of the origin's wanted bins
    (:func:`_wanted_arcs`): its angle to φ is at most β + h, which holds only if
    ``v·u ≥ r·cos(β + h) ≥ r·cos β − w·sin β − w²/(2r)`` with w = r·h = 0.75·cell (cos'' ≥ −1),
    or if β + h ≥ π. No arctangent and no hypot: a few products per pair, the cosines and
    sines taken per origin (each element's bits in any array) and gathered."""
    r = np.sqrt(dx * dx + dy * dy)
    slack = _COVER_SLACK * (r + 1.0)
    w = 0.75 * cell
    with np.errstate(divide="ignore"):
        bound = (r * np.cos(beta)[owner] - w * np.sin(beta)[owner] - w * w / (2.0 * r)
                 - slack)
    toward = dx * np.cos(phi)[owner] + dy * np.sin(phi)[owner] >= bound
    wide = r * (math.pi - beta[owner]) <= w + slack
    return (r + slack > 0.5 * cell) & (r - slack <= within[owner]) & (toward | wide)


def _wanted_arcs(wanted: np.ndarray, bin_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``wanted`` [S, B]: the centre φ and half-width β (radians) of the
    shortest arc holding all its wanted bins (bin k spans k·bin_rad to (k+1)·bin_rad, the
    angle taken in [0, 2π)), widened by two bins; π (all round) for a row without any."""
    n, bins = wanted.shape
    rows, at = nonzero_cells(wanted)
    return _arcs_of(rows, at, n, bins, bin_rad)


def _arcs_of(rows: np.ndarray, at: np.ndarray, n: int, bins: int, bin_rad: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_wanted_arcs` of the wanted bins ``at`` of rows ``rows`` (``np.nonzero`` of
    the [``n``, ``bins``] wanted)."""
    phi, beta = np.zeros(n), np.full(n, math.pi)
    if len(rows) == 0:
        return phi, beta
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    ends = np.r_[starts[1:], len(rows)] - 1
    after = np.r_[at[1:], 0]  # the next wanted bin of the same row, round the circle
    after[ends] = at[starts] + bins
    gap = after - at
    widest = np.lexsort((gap, rows))[ends]  # each row's widest gap (sorted by row, gap)
    length = bins - gap[widest] + 1  # the bins from the gap's end round to its start
    phi[rows[starts]] = (after[widest] + 0.5 * length) * bin_rad
    beta[rows[starts]] = np.minimum((0.5 * length + 2.0) * bin_rad, math.pi)
    return phi, beta


def _bin(origin: np.ndarray, points: np.ndarray, bins: int, bin_rad: float) -> np.ndarray:
    d = points - origin
    return np.floor(np.arctan2(d[:, 1], d[:, 0]) / bin_rad).astype(np.int64) % bins


#: Origin-tile pairs (or z-buffer bins, whichever are more) :func:`line_of_sight` looks
#: at in one pass: a few arrays of this many float64 (2 MB each) stay in the processor's
#: cache.
SIGHT_PAIRS_AT_ONCE = 1 << 18


def line_of_sight(points: np.ndarray, tx: np.ndarray, rx: np.ndarray,
                  positions: np.ndarray, occluders: np.ndarray, cell: float,
                  margin_m: float | None = None) -> np.ndarray:
    """[n] bool: which estimated reflection ``points`` [n, 2] of the pairs (``tx``, ``rx``)
    [n] are in sight of both transducers (``positions`` [N, 2]) — no occupied cell of
    ``occluders`` [m, 2] lies nearer than the point by more than ``margin_m`` (default
    :data:`SIGHT_MARGIN_CELLS` cells) in the point's direction, from T and from R.

    Every transducer's z-buffer is built at once, in the bins of its points alone
    (:func:`first_hits_at`), as many transducers at a time as
    :data:`SIGHT_PAIRS_AT_ONCE` allows;
    :func:`line_of_sight_per_sensor` is the same test one transducer at a time."""
    points, margin, keep = _start(points, cell, margin_m)
    if len(points) == 0 or len(occluders) == 0:
        return keep
    bins = round(2 * math.pi / SIGHT_BIN_RAD)
    sensor, point = _sensor_point_pairs(np.asarray(tx), np.asarray(rx))
    d = points[point] - positions[sensor]
    dist = np.hypot(d[:, 0], d[:, 1])
    where = np.floor(np.arctan2(d[:, 1], d[:, 0]) / SIGHT_BIN_RAD).astype(np.int64) % bins
    starts = np.flatnonzero(np.r_[True, sensor[1:] != sensor[:-1]])
    farthest = np.maximum.reduceat(dist, starts)
    tiles = occluder_tiles(occluders, cell)
    step = max(1, SIGHT_PAIRS_AT_ONCE // max(len(tiles.starts), bins))
    for first in range(0, len(starts), step):  # a group of transducers at a time
        steps.step("transducers", first, len(starts))
        a = starts[first]
        b = starts[first + step] if first + step < len(starts) else len(sensor)
        group = np.repeat(np.arange(len(starts[first:first + step])),
                          np.diff(np.r_[starts[first:first + step], b]))
        wanted = np.zeros((group[-1] + 1, bins), dtype=bool)
        wanted[group, where[a:b]] = True
        rows, at = nonzero_cells(wanted)
        hits = first_hits_at(positions[sensor[starts[first:first + step]]], occluders, cell,
                             farthest[first:first + step] - margin, rows, at, bins,
                             tiles=tiles)
        mine = np.searchsorted(rows * bins + at, group * bins + where[a:b])  # its bin's hit
        hidden = dist[a:b] > hits[mine] + margin
        keep[point[a:b][hidden]] = False
    steps.step("transducers", len(starts), len(starts))
    return keep


def line_of_sight_per_sensor(points: np.ndarray, tx: np.ndarray, rx: np.ndarray,
                             positions: np.ndarray, occluders: np.ndarray, cell: float,
                             margin_m: float | None = None) -> np.ndarray:
    """:func:`line_of_sight` one transducer at a time through :func:`first_hits`: the
    reference the vectorised test is checked against (tests/test_rooms.py)."""
    points, margin, keep = _start(points, cell, margin_m)
    if len(points) == 0 or len(occluders) == 0:
        return keep
    bins = round(2 * math.pi / SIGHT_BIN_RAD)
    sensor, point = _sensor_point_pairs(np.asarray(tx), np.asarray(rx))
    starts = np.flatnonzero(np.r_[True, sensor[1:] != sensor[:-1]])
    for a, b in zip(starts, np.r_[starts[1:], len(sensor)], strict=True):
        origin = positions[sensor[a]]
        mine = point[a:b]
        q = points[mine]
        dist = np.hypot(*(q - origin).T)
        where = _bin(origin, q, bins, SIGHT_BIN_RAD)
        wanted = np.zeros(bins, dtype=bool)
        wanted[where] = True
        hits = first_hits(origin, occluders, cell, within=dist.max() - margin, wanted=wanted)
        keep[mine[dist > hits[where] + margin]] = False
    return keep


def _start(points: np.ndarray, cell: float, margin_m: float | None
           ) -> tuple[np.ndarray, float, np.ndarray]:
    """The points as [n, 2] floats, the margin (default :data:`SIGHT_MARGIN_CELLS` cells)
    and every point kept, where both line-of-sight tests start."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    margin = SIGHT_MARGIN_CELLS * cell if margin_m is None else margin_m
    return points, margin, np.ones(len(points), dtype=bool)


def _sensor_point_pairs(tx: np.ndarray, rx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every (sensor, point) with the sensor in the point's pair (T = R once), sorted by
    sensor, then point."""
    sensor = np.concatenate([tx, rx])
    point = np.concatenate([np.arange(len(tx)), np.arange(len(rx))])
    order = np.lexsort((point, sensor))
    sensor, point = sensor[order], point[order]
    new = np.r_[True, (sensor[1:] != sensor[:-1]) | (point[1:] != point[:-1])]  # T = R once
    return sensor[new], point[new]


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
    iy, ix = nonzero_cells(thin)  # one-cell curves leave no gap between z-buffer bins
    cells = cell_centres(scene.extent, scene.cell, iy + row0, ix + col0)
    occluders = np.concatenate([cells, profile.points])
    return line_of_sight(points, tx, rx, positions, occluders, scene.cell)


__all__ = ["first_hits", "first_hits_at", "first_hits_each", "in_sight_of_map",
           "line_of_sight", "line_of_sight_per_sensor"]
