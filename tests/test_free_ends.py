"""Thin walls that end inside the map (issue 18's knife edges, geometry.free_ends) mapped
with the defaults: the zoo's cases that the echo model's silent free ends had made fail,
or that the new diffraction touched (issue 14)."""

from __future__ import annotations

import functools

import pytest

from clsonar import pipeline
from clsonar.opencl import get_context
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


@functools.cache
def _row(seed: int, kind: str, index: int) -> dict:
    case = draw(seed, kind, index)
    assert not {"detection", "mapping", "post"} & set(case.data)  # the defaults
    return score(case, pipeline.run(case.scene, context=get_context(None)))


@pytest.mark.parametrize(("seed", "kind", "index", "accuracy_m"), [
    (6, "edge", 0, 0.001),  # a face drawn 6.9 cm RMS past its free end before
    (6, "corner", 7, 0.002),  # random lines at a corner with two free ends: 1.84 cm
    (2, "corner", 6, 0.001),  # a wall end at 8 m drawn 6 cm past it with a rigid edge's ρ
    # an end pair's echo raised to 1.14 of the others' by the end's diffraction (the
    # knife edge's first Fresnel maximum), where only a weakened one ended the face: a
    # wall 1.5 m away drawn 9.7 cm past its free end, 1.15 cm RMS (unseen until stop 34)
    (45, "wall", 4, 0.001),
])
def test_a_face_stops_at_its_free_end(seed, kind, index, accuracy_m):
    row = _row(seed, kind, index)
    assert row["passed"]
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= accuracy_m


def test_a_corners_double_bounce_is_not_shadowed_by_a_faint_diffraction():
    """Seed 13 corner-03 (random lines, a corner with both free ends in the map): the
    corner's strongest echo, 3.9 units, lies within the pulse's resolution of the path of
    a free end's located diffraction (0.01-0.08 units); so faint an echo barely shifts it
    (families.shadowed), and the corner is located from its three echoes again."""
    row = _row(13, "corner", 3)
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.001
