"""Point families that other windows or arrays located at one point are one reflector
(owners.one_point_each, issue 14): with noise, each array's loci place a convex edge only
as well as that array's spread of pairs allows, cm across its line of sight; two arrays
seeing it from different bearings pin it together."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.mapping.models import fit_point, point_paths
from clsonar.mapping.owners import one_point_each
from clsonar.mapping.window import Family, Window


def _array_family(V: np.ndarray, heard: np.ndarray, bearing: float, distance: float,
                  first_row: int, rng: np.random.Generator, noise: float) -> Family:
    """The point family one array of six elements 5 cm apart, ``distance`` from ``V`` at
    ``bearing`` (degrees) and facing it, fits to its pairs' echoes of ``heard`` (paths
    with Gaussian noise of σ ``noise``)."""
    u = np.array([math.cos(math.radians(bearing)), math.sin(math.radians(bearing))])
    along = np.array([-u[1], u[0]])
    pos = V + distance * u + (np.arange(6) - 2.5)[:, None] * 0.05 * along
    i, j = np.triu_indices(6)
    T, R = pos[i], pos[j]
    paths = point_paths(heard, T, R)[0] + rng.normal(0.0, noise, len(T))
    n = len(T)
    w = Window(rows=first_row + np.arange(n), T=T, R=R, axT=np.tile(-u, (n, 1)),
               axR=np.tile(-u, (n, 1)), paths=paths, amplitude=np.ones(n),
               tolerance=np.full(n, 1.5e-3), x0=pos.mean(axis=0), cut_sin2=1.0,
               neighbour_m=0.075)
    fit = fit_point(T, R, paths, V + 0.01)
    q = point_paths(fit.params, T, R)[1]
    return Family("point", fit.params, w.x0, np.arange(n), q, fit.rms, w)


@settings(max_examples=40, deadline=None)
@given(bearing=st.floats(-180.0, 180.0), apart=st.floats(20.0, 120.0),
       distances=st.tuples(st.floats(2.0, 8.0), st.floats(2.0, 8.0)),
       seed=st.integers(0, 2**16))
def test_two_arrays_families_of_one_point_become_one(bearing, apart, distances, seed):
    """Two arrays' point families of one point (paths with 0.3 mm of noise) become one
    family of all 42 echoes, its point the least-squares point of them all; of two points
    5 cm apart, each exact, they stay two."""
    rng = np.random.default_rng(seed)
    V = rng.uniform(-20, 20, 2)
    a = _array_family(V, V, bearing, distances[0], 0, rng, 3e-4)
    b = _array_family(V, V, bearing + apart, distances[1], 21, rng, 3e-4)
    merged = one_point_each([a, b])
    assert len(merged) == 1 and sorted(merged[0].loci.tolist()) == list(range(42))
    w = merged[0].window
    joint = fit_point(w.T, w.R, w.paths, merged[0].params)
    assert np.hypot(*(joint.params - merged[0].params)) < 1e-6

    other = V + 0.05 * np.array([math.cos(seed), math.sin(seed)])
    a = _array_family(V, V, bearing, distances[0], 0, rng, 0.0)
    c = _array_family(V, other, bearing + apart, distances[1], 21, rng, 0.0)
    assert len(one_point_each([a, c])) == 2


def test_a_noisy_edge_seen_by_two_arrays_is_placed_by_both():
    """The zoo's unseen seed 163 edge-02 (σ 0.3): a 132° edge seen by two arrays (17
    elements 1.9 m away, 34 elements 6.5 m away), each of whose point families placed it
    0.9 and 2.0 cm off; together 0.28 cm."""
    from clsonar import pipeline
    from clsonar.opencl import get_context
    from clsonar.tools.zoo.cases import draw
    from clsonar.tools.zoo.score import score

    case = draw(163, "edge", 2)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["passed"] and row["vertex_error_m"] < 0.005
