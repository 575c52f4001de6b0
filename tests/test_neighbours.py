"""clsonar.neighbours against scipy's k-d tree: the same distances and pairs to the bit."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from clsonar import neighbours
from clsonar.neighbours import nearest, nearest_within, pairs_within


@st.composite
def point_sets(draw):
    """Points and queries: scattered, clustered about far-off centres, or on a lattice (ties
    at exactly the radius), at scales from a millimetre to a hundred metres."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = 10.0 ** draw(st.floats(-3, 2))
    centre = rng.uniform(-1e3, 1e3, 2)
    n, m = draw(st.integers(0, 300)), draw(st.integers(0, 300))
    if draw(st.booleans()):
        step = scale / 10
        pts = centre + step * rng.integers(0, 30, (n, 2))
        q = centre + step * (rng.integers(0, 30, (m, 2)) + rng.choice([0.0, 0.5], (m, 2)))
        radius = step * draw(st.sampled_from([0.5, 1.0, 2**0.5, 2.0, 3.0]))
    else:
        pts = centre + scale * rng.normal(size=(n, 2))
        q = centre + scale * rng.normal(size=(m, 2))
        radius = scale * 10.0 ** draw(st.floats(-2, 0.5))
    return pts, q, radius


@settings(max_examples=150, deadline=None)
@given(point_sets())
def test_the_k_d_tree_answers(case):
    pts, q, radius = case
    if len(pts):
        tree = cKDTree(pts)
        assert np.array_equal(nearest_within(pts, q, radius),
                              tree.query(q, distance_upper_bound=radius)[0].reshape(-1))
        assert np.array_equal(nearest(pts, q), tree.query(q)[0].reshape(-1))
        expected = np.array(sorted(tree.query_pairs(radius)), dtype=np.int64).reshape(-1, 2)
        assert np.array_equal(pairs_within(pts, radius), expected)
    else:
        assert np.all(np.isinf(nearest_within(pts, q, radius)))
        assert np.all(np.isinf(nearest(pts, q)))


def test_chunks_and_the_tree_for_many_points(monkeypatch):
    """Queries answered a chunk at a time, and past TREE_FROM by scipy: the same answers."""
    rng = np.random.default_rng(3)
    pts, q = rng.uniform(0, 5, (3000, 2)), rng.uniform(-1, 6, (2000, 2))
    want = nearest_within(pts, q, 0.05)
    assert np.isfinite(want).any() and np.isinf(want).any()
    monkeypatch.setattr(neighbours, "_CHUNK_PAIRS", 500)
    assert np.array_equal(nearest_within(pts, q, 0.05), want)
    assert np.array_equal(nearest(pts, q), cKDTree(pts).query(q)[0])
    pairs = pairs_within(pts, 0.02)
    monkeypatch.setattr(neighbours, "TREE_FROM", 100)
    assert np.array_equal(nearest_within(pts, q, 0.05), want)
    assert np.array_equal(pairs_within(pts, 0.02), pairs)
