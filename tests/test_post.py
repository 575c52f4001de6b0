"""Post-processing: eq. 2.4 low-pass, eq. 2.5 thinning as written, proper thinning."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from clsonar.post import binarize, low_pass, thin, thin_thesis

EIGHT = np.ones((3, 3), dtype=bool)


def test_low_pass_eq_2_4():
    raw = np.zeros((5, 5))
    raw[2, 2] = 9.0
    f = low_pass(raw)
    assert np.allclose(f[1:4, 1:4], 1.0) and f.sum() == 9.0
    assert low_pass(np.ones((3, 3)))[0, 0] == 4 / 9  # zero outside the map


def test_thin_thesis_keeps_cells_with_empty_row_above_and_full_row_below():
    b = np.zeros((6, 7), dtype=bool)
    b[1:4, 1:6] = True  # a band 3 rows tall, rows iy = 1..3
    kept = thin_thesis(b)
    # only the top row of the band (iy = 3) with a full row below and empty row above,
    # away from the band's ends (the row below must be full across the 3 columns)
    expected = np.zeros_like(b)
    expected[3, 2:5] = True
    assert np.array_equal(kept, expected)


def _topology(b):
    return ndimage.label(b, EIGHT)[1], ndimage.label(np.pad(~b, 1, constant_values=True))[1]


def _only_necessary_thickness(t):
    """Every pixel of a 2×2 block or staircase corner is needed: deleting it changes the
    number of 8-connected curves or of 4-connected holes (e.g. at a four-arm junction)."""
    p = np.pad(t, 1)
    thick = t & ((p[2:, 1:-1] | p[:-2, 1:-1]) & (p[1:-1, 2:] | p[1:-1, :-2]))
    reference = _topology(t)
    for y, x in zip(*np.nonzero(thick), strict=True):
        u = t.copy()
        u[y, x] = False
        if _topology(u) == reference:
            return False
    return True


def test_thin_gives_one_pixel_curves():
    yy, xx = np.mgrid[0:80, 0:120]
    ring_band = np.abs(np.hypot(yy - 40, xx - 60) - 30) < 3  # a thick ring
    line = (np.abs(yy - 0.3 * xx - 5) < 2.5) & (xx < 50)  # a thick oblique line
    b = ring_band | line
    t = thin(b)
    assert np.all(t <= b) and _only_necessary_thickness(t)
    assert _topology(t) == _topology(b)  # curves and the ring's hole survive
    # every pixel of a thin curve has at most 2 neighbours except at junctions
    neighbours = ndimage.correlate(t.astype(int), EIGHT.astype(int), mode="constant") - 1
    assert np.mean(neighbours[t] <= 2) > 0.95


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1), st.floats(0.3, 0.7))
def test_thin_preserves_components_and_is_idempotent(seed, density):
    rng = np.random.default_rng(seed)
    b = ndimage.binary_dilation(rng.random((40, 40)) > 1 - density / 10, iterations=2)
    t = thin(b)
    assert np.all(t <= b) and _only_necessary_thickness(t)
    assert _topology(t) == _topology(b)
    assert np.array_equal(thin(t), t)


def test_binarize():
    assert binarize(np.array([0.1, 0.5, 0.6]), 0.5).tolist() == [False, True, True]
