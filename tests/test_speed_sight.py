"""The line-of-sight z-buffers found tile by tile (issue 16) against the dense pre-filter of
every (origin, occluder) pair they replaced: the same distances to the bit."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import sight
from clsonar.sight import (
    SIGHT_BIN_RAD,
    _wanted_arcs,
    _wanted_between,
    first_hits_each,
    occluder_tiles,
)

BINS = round(2 * math.pi / SIGHT_BIN_RAD)


def dense_first_hits_each(origins, occluders, cell, within, wanted, bin_rad=SIGHT_BIN_RAD):
    """:func:`clsonar.sight.first_hits_each` as of commit 1610903: every (origin, occluder)
    pair of the origins' box through :func:`dense_may_cover` at once, [S, m] arrays."""
    n, bins = wanted.shape
    hits = np.full(n * bins, np.inf)
    reach = float(np.max(within, initial=0.0))
    box = np.all((occluders >= origins.min(axis=0) - reach)
                 & (occluders <= origins.max(axis=0) + reach), axis=1)
    occluders = occluders[box]
    dx = occluders[None, :, 0] - origins[:, None, 0]
    dy = occluders[None, :, 1] - origins[:, None, 1]
    owner, cell_of = np.nonzero(dense_may_cover(dx, dy, cell, within, wanted, bin_rad))
    dx, dy = dx[owner, cell_of], dy[owner, cell_of]
    dist = np.hypot(dx, dy)
    ok = (dist > 0.5 * cell) & (dist <= within[owner])
    owner, dx, dy, dist = owner[ok], dx[ok], dy[ok], dist[ok]
    theta = np.arctan2(dy, dx)
    half = 0.75 * cell / dist
    lo = np.floor((theta - half) / bin_rad).astype(np.int64)
    width = np.floor((theta + half) / bin_rad).astype(np.int64) - lo
    use = _wanted_between(wanted, owner, lo % bins, width) > 0
    owner, dist, lo, width = owner[use], dist[use], lo[use], width[use]
    span = width + 1
    first = np.cumsum(span) - span
    offset = np.arange(int(span.sum())) - np.repeat(first, span)
    where = np.repeat(owner * bins, span) + (np.repeat(lo, span) + offset) % bins
    np.minimum.at(hits, where, np.repeat(dist, span))
    return hits.reshape(n, bins)


def dense_may_cover(dx, dy, cell, within, wanted, bin_rad):
    """The [S, m] pre-filter of commit 1610903 (``sight._may_cover`` then)."""
    r = np.sqrt(dx * dx + dy * dy)
    slack = 1e-9 * (r + 1.0)
    phi, beta = _wanted_arcs(wanted, bin_rad)
    w = 0.75 * cell
    with np.errstate(divide="ignore"):
        bound = (r * np.cos(beta)[:, None] - w * np.sin(beta)[:, None] - w * w / (2.0 * r)
                 - slack)
    toward = dx * np.cos(phi)[:, None] + dy * np.sin(phi)[:, None] >= bound
    wide = r * (math.pi - beta)[:, None] <= w + slack
    return (r + slack > 0.5 * cell) & (r - slack <= within[:, None]) & (toward | wide)


@st.composite
def _cases(draw):
    """Origins, occluders (walls of cells, clusters, scattered ones, some on an origin),
    each origin's reach and wanted bins (arcs, across bin 0 or not; scattered; none; all)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    cell = draw(st.sampled_from([0.005, 0.01, 0.02, 0.05]))
    size = draw(st.sampled_from([0.3, 3.0, 12.0]))
    origins = rng.uniform(0.0, size, (draw(st.integers(1, 8)), 2))
    parts = [rng.uniform(-0.2 * size, 1.2 * size, (draw(st.integers(0, 80)), 2))]
    for _ in range(draw(st.integers(0, 4))):  # a wall's cells, one a cell
        a, b = rng.uniform(-0.2 * size, 1.2 * size, (2, 2))
        n = max(2, int(np.hypot(*(b - a)) / cell))
        parts.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    centre = rng.uniform(0.0, size, 2)
    parts.append(centre + rng.normal(0.0, 4 * cell, (draw(st.integers(0, 60)), 2)))
    parts.append(origins[: draw(st.integers(0, 2))] + rng.normal(0.0, cell, 2))
    occluders = np.concatenate(parts)
    within = rng.uniform(0.0, 1.5 * size, len(origins))
    share = draw(st.floats(0.0, 1.0))
    wanted = rng.random((len(origins), BINS)) < share**3 * 0.02
    for row in range(len(origins)):
        kind = draw(st.sampled_from(["arc", "scattered", "none", "all"]))
        if kind == "arc":
            start, length = rng.integers(0, BINS), draw(st.integers(1, BINS - 1))
            wanted[row] = False
            wanted[row, (start + np.arange(length)) % BINS] = True
        elif kind != "scattered":
            wanted[row] = kind == "all"
    return origins, occluders, cell, within, wanted


@settings(max_examples=150, deadline=None)
@given(case=_cases(), tile_cells=st.sampled_from([1, 4, 16, 200]))
def test_first_hits_each_by_tiles_is_the_dense_pre_filter_bit_for_bit(case, tile_cells):
    """Every bin of every origin's z-buffer equals the dense version's, whatever the tiles'
    size (one cell, the default, most of the scene)."""
    origins, occluders, cell, within, wanted = case
    want = dense_first_hits_each(origins, occluders, cell, within, wanted)
    old = sight.SIGHT_TILE_CELLS
    try:
        sight.SIGHT_TILE_CELLS = tile_cells
        got = first_hits_each(origins, occluders, cell, within, wanted)
    finally:
        sight.SIGHT_TILE_CELLS = old
    np.testing.assert_array_equal(got, want)
    assert np.isfinite(want).sum() == np.isfinite(got).sum()


def test_occluder_tiles_hold_every_occluder_once_within_their_discs():
    """Tiles of 32 cells: each occluder in exactly one tile, within its tile's radius of
    its centre; here a 1 m wall of 0.01 m cells falls in 4 tiles."""
    wall = np.stack([np.linspace(0.0, 1.0, 101), np.full(101, 2.0)], axis=-1)
    tiles = occluder_tiles(wall, 0.01)
    assert len(tiles.starts) == 4
    np.testing.assert_array_equal(np.sort(tiles.order), np.arange(101))
    for k, (a, b) in enumerate(zip(tiles.starts, tiles.ends, strict=True)):
        held = wall[tiles.order[a:b]]
        assert np.hypot(*(held - tiles.centre[k]).T).max() <= tiles.radius[k]
    assert tiles.radius[0] > 0.155  # cells 0 .. 31 around x = 0.155
