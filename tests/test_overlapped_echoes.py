"""A window whose loudest detections are two reflectors' overlapped echoes
(:func:`clsonar.mapping.families._sweep`): its family search does not stop at its loudest
seeds, none of which any model explains, but tries seeds spread over the quieter ones."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import pipeline
from clsonar.mapping.families import _sweep
from clsonar.opencl import get_context
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 400), st.integers(1, 40), st.data())
def test_a_sweep_spreads_its_seeds_over_the_untried_ones(n, max_failed, data):
    order = data.draw(st.permutations(range(n))) if n else []
    tried = np.asarray(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool)
    deferred = np.asarray(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)),
                          dtype=bool)
    picked = _sweep(list(order), tried, deferred, max_failed)
    rest = [s for s in order if not tried[s] and not deferred[s]]
    assert len(picked) == min(len(rest), max_failed // 2)
    assert all(s in rest for s in picked)
    ranks = [rest.index(s) for s in picked]
    assert ranks == sorted(ranks) and len(set(ranks)) == len(ranks)  # in the order given
    if len(picked) >= 2 and len(rest) >= 2 * len(picked):
        assert ranks[-1] >= len(rest) // 2  # reaching the quieter half


def test_a_corner_seen_square_to_one_wall_is_located():
    """Unseen seed 106 corner-06: a 35-element array 6.3 m away, square to a wall within 6°,
    hears the wall and the corner's double bounce 2-7 cm of path apart. Where they
    overlap, the detections are their sums, the loudest of all and neither reflector's:
    the search stopped after its 24 loudest seeds grew nothing, and the tangent points drew
    a wave 8.4 cm RMS off, its corner 6 cm from the vertex."""
    case = draw(106, "corner", 6)
    row = score(case, pipeline.run(case.scene, context=get_context(None)))
    assert row["passed"]
    assert row["accuracy_m"] <= 0.001 and row["vertex_error_m"] <= 0.002


def test_a_plane_of_a_corners_merged_echoes_is_that_corner():
    """Unseen seed 100 corner-00: a 14-element array 4.8 m away hears a 90.1° corner's
    double bounce and one wall's echo 4 cm of path apart; merged, 14 of its detections lie
    up to 11 mm off the double bounce the corner located from 325 echoes predicts, and a
    plane through the vertex fitted them to 0.1 mm: drawn 25 cm past the vertex, behind
    the other wall (7.8 cm RMS). Within the pulse's resolution of the corner's paths, they
    are its echoes (mapping.reflectors.a_vertexs_distorted_echoes, now also of a plane)."""
    case = draw(100, "corner", 0)
    row = score(case, pipeline.run(case.scene, context=get_context(None)))
    assert row["passed"] and row["accuracy_m"] <= 0.001
