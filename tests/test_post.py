"""Post-processing: eq. 2.4 low-pass, eq. 2.5 thinning as written, proper thinning."""

import numpy as np
import pytest
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
    kept = thin_thesis(b, up=(1, 0))  # the row above is iy + 1
    # only the top row of the band (iy = 3), away from the band's ends (the row below must
    # be full across the 3 columns)
    expected = np.zeros_like(b)
    expected[3, 2:5] = True
    assert np.array_equal(kept, expected)


def test_thin_thesis_default_keeps_the_edge_at_smaller_x():
    b = np.zeros((8, 8), dtype=bool)
    b[:, 3:6] = True  # a wall along y, three cells thick
    kept = thin_thesis(b)
    assert np.array_equal(np.unique(np.nonzero(kept)[1]), [3])
    assert kept[1:-1, 3].all()


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


def test_the_simple_pixel_table_is_the_labelled_definition():
    """``thinning._SIMPLE`` (Yokoi's connectivity number, so the module needs no scipy.ndimage)
    against the definition by scipy's labelling: one 8-connected foreground component
    among the neighbours, one 4-connected background component touching the pixel."""
    from clsonar.post import thinning

    bits = thinning._NEIGHBOUR_BITS
    for code in range(256):
        patch = (code & bits) > 0
        n_fg = ndimage.label(patch, np.ones((3, 3)))[1]
        bg, _ = ndimage.label(~patch & (bits > 0), ndimage.generate_binary_structure(2, 1))
        touching = {bg[i, j] for i, j in ((0, 1), (1, 0), (1, 2), (2, 1)) if bg[i, j]}
        assert thinning._SIMPLE[code] == (n_fg == 1 and len(touching) == 1), code


def test_binarize():
    assert binarize(np.array([0.1, 0.5, 0.6]), 0.5).tolist() == [False, True, True]
    assert not binarize(np.zeros((3, 3)), 0.0).any()  # no echo: nothing occupied


# --------------------------------------------------------------------------- profile

from clsonar.post import bridge_gaps, extract_profile, fit_polynomial, fit_spline, trace_curves  # noqa: E402
from clsonar.scene import PostSettings  # noqa: E402


def _ring(n=60, r=20):
    yy, xx = np.mgrid[0:n, 0:n]
    return thin(np.abs(np.hypot(yy - n / 2, xx - n / 2) - r) < 1.5)


def test_trace_closed_ring_open_line_and_junction():
    curves = trace_curves(_ring())
    assert len(curves) == 1 and len(curves[0]) > 100
    line = np.zeros((10, 30), dtype=bool)
    line[5, 2:28] = True
    (c,) = trace_curves(line)
    assert len(c) == 26 and {tuple(c[0]), tuple(c[-1])} == {(5, 2), (5, 27)}
    tee = line.copy()
    tee[0:5, 15] = True
    branches = trace_curves(tee)  # the stem and both arms, meeting at the junction
    assert len(branches) == 3
    covered = {tuple(c) for b in branches for c in b}
    near_junction = {(y, x) for y in (4, 5, 6) for x in (14, 15, 16)}
    assert set(zip(*np.nonzero(tee), strict=True)) - covered <= near_junction
    specks = np.zeros((10, 10), dtype=bool)
    specks[2, 2] = specks[5, 5:7] = True
    assert trace_curves(specks) == []


def test_bridge_gaps_joins_nearest_ends():
    a = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([[3.0, 0.0], [1.2, 0.0]])  # reversed, its near end last
    far = np.array([[10.0, 0.0], [11.0, 0.0]])
    joined = bridge_gaps([a, b, far], max_gap=0.5)
    assert len(joined) == 2
    long = max(joined, key=len)
    assert np.allclose(long[:, 0], [0.0, 1.0, 1.2, 3.0]) or np.allclose(
        long[:, 0], [3.0, 1.2, 1.0, 0.0])


def test_fit_polynomial_along_principal_axis():
    rng = np.random.default_rng(1)
    y = np.linspace(0, 10, 500)
    x = 9.0 + 0.002 * rng.standard_normal(500)  # a wall along y
    (fitted,) = fit_polynomial(np.stack([x, y], axis=-1), 7, 0.01)
    assert np.max(np.abs(fitted[:, 0] - 9.0)) < 0.003
    assert fitted[:, 1].min() == pytest.approx(0, abs=0.01)
    assert len(fitted) == pytest.approx(1001, abs=2)


def test_fit_polynomial_stays_within_its_data():
    """A room's outline is no function along its principal axis: the polynomial through it
    runs metres away from it. Only the samples within the data's span of u and of v are
    kept (the thesis' polynomial on a room: 10 m off in docs/bench before)."""
    a = np.linspace(0, 2 * np.pi, 800, endpoint=False)
    outline = np.stack([5 + 4 * np.cos(a), 5 + 0.5 * np.sin(a)], axis=-1)
    outline[::7, 1] += 0.3  # not symmetric: the fit must run somewhere
    curves = fit_polynomial(outline, 8, 0.01)
    pts = np.concatenate(curves)
    assert len(pts) > 100
    assert pts[:, 0].min() >= 1.0 - 0.01 and pts[:, 0].max() <= 9.0 + 0.01
    assert pts[:, 1].min() >= 4.5 - 0.011 and pts[:, 1].max() <= 5.8 + 0.011
    few = np.array([[0.0, 0.0], [1.0, 3.0], [2.0, -1.0], [3.0, 0.5]])
    assert np.array_equal(fit_polynomial(few, 7, 0.01)[0], few)  # fewer points than the order


def test_bound_profile_drops_what_the_map_does_not_support():
    """Points outside the extent or more than NEAR_CELLS cells from an occupied cell are
    dropped and their curve cut there — unless they fill a gap up to max_gap or no longer
    than the supported stretches on both sides (interpolation), or end the curve at a
    located vertex; vertices are dropped only outside the extent."""
    from clsonar.post import NEAR_CELLS, Profile, bound_profile

    near = 0.1 * NEAR_CELLS
    occupied = np.zeros((40, 60), dtype=bool)  # cells of 0.1 m from (1, 2): x 1..7, y 2..6
    occupied[10, 5:20] = True  # y = 3.05, x = 1.5..3.0
    occupied[10, 40:45] = True  # x = 5.0..5.5: a gap longer than this stretch
    occupied[30, 5:25] = True  # y = 5.05, x = 1.5..3.5
    occupied[30, 35:55] = True  # x = 4.5..6.5: a gap shorter than both stretches
    x = np.arange(0.0, 9.0, 0.05)
    cut, bridged, off = (np.stack([x, np.full_like(x, y)], axis=-1)
                         for y in (3.05, 5.05, 3.05 + 0.1 * (NEAR_CELLS + 1)))
    to_corner = cut[(cut[:, 0] >= 1.5) & (cut[:, 0] <= 4.0)]  # ends at a located vertex
    vertices = np.array([[4.0, 3.05], [0.5, 3.0]])
    extent = (1.0, 2.0, 7.0, 6.0)
    bounded = bound_profile(Profile((cut, bridged, off, to_corner), vertices), occupied,
                            extent, 0.1)
    first, second, whole, wall = bounded.curves  # nothing left of the line off the map
    assert first[0, 0] == pytest.approx(1.5 - near, abs=0.05)
    assert first[-1, 0] == pytest.approx(3.0 + near, abs=0.05)
    assert second[0, 0] == pytest.approx(5.0 - near, abs=0.05)
    assert second[-1, 0] == pytest.approx(5.5 + near, abs=0.05)
    assert whole[0, 0] == pytest.approx(1.5 - near, abs=0.05)
    assert whole[-1, 0] == pytest.approx(6.5 + near, abs=0.05)
    assert np.all(whole[:, 1] == 5.05) and np.all(np.diff(whole[:, 0]) == pytest.approx(0.05))
    assert np.array_equal(wall, to_corner)
    assert np.array_equal(bounded.vertices, vertices[:1])
    assert bounded.dropped == 3 * len(x) - len(first) - len(second) - len(whole)
    # the gaps the settings let a fit bridge (post.max_gap_m) are kept
    loose = bound_profile(Profile((cut,)), occupied, extent, 0.1, max_gap=1.5)
    (one,) = loose.curves
    assert one[0, 0] == pytest.approx(1.5 - near, abs=0.05)
    assert one[-1, 0] == pytest.approx(5.5 + near, abs=0.05)
    # a loop is cut only where it leaves the map, wherever its samples start
    a = np.linspace(0.0, 2 * np.pi, 400, endpoint=False) + 1.0
    loop = np.stack([4.0 + 1.5 * np.cos(a), 4.0 + 1.5 * np.sin(a)], axis=-1)
    ring = np.zeros((40, 60), dtype=bool)
    angle = np.arctan2(*(cell_grid(40, 60) - 4.0)[::-1]) % (2 * np.pi)
    radius = np.hypot(*(cell_grid(40, 60) - 4.0))
    ring[(np.abs(radius - 1.5) < 0.06) & ((angle < 2.0) | (angle > 5.0))] = True
    (arc,) = bound_profile(Profile((loop,)), ring, extent, 0.1).curves
    kept = np.arctan2(arc[:, 1] - 4.0, arc[:, 0] - 4.0) % (2 * np.pi)
    assert np.all((kept < 2.0 + 0.3) | (kept > 5.0 - 0.3)) and len(arc) > 150
    # the same map as a window of a larger grid: origin moves the cells, not the points
    shifted = bound_profile(Profile((cut, bridged, off)), occupied[5:, 3:], extent, 0.1,
                            origin=(5, 3))
    assert all(np.array_equal(a, b) for a, b in zip(shifted.curves, bounded.curves[:3],
                                                    strict=True))


def cell_grid(ny: int, nx: int, origin=(1.0, 2.0), cell: float = 0.1) -> np.ndarray:
    """[2, ny, nx] the (x, y) centres of a grid's cells."""
    iy, ix = np.mgrid[0:ny, 0:nx]
    return np.stack([origin[0] + (ix + 0.5) * cell, origin[1] + (iy + 0.5) * cell])


def test_thin_oriented_thins_walls_along_x_and_keeps_the_thesis_along_y():
    """Eq. 2.5 as written keeps nothing of a band along x; oriented, it keeps its edge at
    smaller y. A band along y thins exactly as written."""
    from clsonar.post import along_x, thin_oriented

    b = np.zeros((40, 80), dtype=bool)
    b[20:24, 5:75] = True  # a wall along x, 4 cells thick
    assert np.array_equal(np.unique(np.nonzero(thin_thesis(b))[1]), [5])  # its end only
    kept = thin_oriented(b)
    rows, cols = np.nonzero(kept)
    assert np.array_equal(np.unique(rows), [20]) and len(cols) >= 60
    assert along_x(b)[21, 40] and not along_x(b.T)[40, 21]
    assert np.array_equal(thin_oriented(b.T), thin_thesis(b.T))
    both = b.copy()
    both[:, 60:64] = True  # and a wall along y crossing it: each thinned its own way
    kept = thin_oriented(both)
    assert kept[20, 10:50].all() and kept[2:15, 60].all()


def test_fit_spline_follows_a_circle():
    a = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    pts = np.stack([np.cos(a), np.sin(a)], axis=-1) * 2.0
    fitted = fit_spline(np.concatenate([pts, pts[:1]]), 0.01, 0.001)  # closed, as traced
    assert np.max(np.abs(np.hypot(*fitted.T) - 2.0)) < 0.003  # smoothing allows ~1 mm RMS


def test_extract_profile_from_a_thin_map():
    t = _ring()
    prof = extract_profile(t, (0.0, 0.0, 0.6, 0.6), 0.01, PostSettings(fit="spline", max_gap_m=0.3))
    assert len(prof.curves) == 1
    r = np.hypot(*(prof.points - 0.3).T)
    assert abs(np.median(r) - 0.2) < 0.01
    none = extract_profile(t, (0.0, 0.0, 0.6, 0.6), 0.01, PostSettings(fit="none", max_gap_m=0.3))
    assert len(none.points) == np.count_nonzero(t) + 1  # closed loop repeats its start


def test_refine_cells_finds_the_ridge_between_cells():
    from clsonar.post import refine_cells

    w = np.zeros((5, 6))
    w[:, 2] = w[:, 3] = 1.0  # a ridge on the boundary between columns 2 and 3
    refined = refine_cells(np.array([[2, 2], [2, 3]]), w)
    assert np.allclose(refined[:, 1], 2.5) and np.allclose(refined[:, 0], 2.0)


def test_a_patch_of_one_point_is_kept_and_longer_patches_lose_lone_points():
    from clsonar.post import Profile
    from clsonar.post.profile import with_patches

    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.1, 0.0], [1.2, 0.0], [2.0, 0.0]])
    ends = np.array([1, 5])  # a thin post's single specular spot, then a 4-point patch
    keep = np.array([True, True, False, True, True])  # the patch's 2nd point out of sight
    out = with_patches(Profile(()), points, ends, keep, 0.02)
    assert [c.tolist() for c in out.curves] == [[[0.0, 0.0]], [[1.2, 0.0], [2.0, 0.0]]]


@pytest.mark.parametrize("cell, kept", [(0.005, False), (0.01, False), (0.02, True)])
def test_a_short_diagonal_curve_is_a_speck_only_on_small_cells(cell, kept):
    """Three diagonal cells beside a long curve: 2.8 cells long, a speck on a map of 0.5
    or 1 cm cells, but 5.7 cm of surface on one of 2 cm cells (a pillar's stub, the zoo's
    unseen seed 170 room-16), which is kept (post.profile.MIN_CURVE_M). Five cells in a
    row (4 cells long), or four on a diagonal (4.2), are no speck at any cell size."""
    from clsonar.post.profile import _traced

    t = np.zeros((30, 30), dtype=bool)
    t[2, 2:28] = True  # a long curve
    for k in range(3):
        t[10 + k, 10 + k] = True
    curves = _traced(t, cell)
    assert len(curves) == (2 if kept else 1)
    t[13, 13] = True
    t[20, 5:10] = True
    assert len(_traced(t, cell)) == 3
