"""Where a face ends (issue 14, item 3: coverage without paying in accuracy): a face is
drawn over its echoes' regions of constant depth, but not past an end its own echoes say
is near (patches.weakened_ends)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from clsonar.opencl import get_context
from clsonar.pipeline import run
from clsonar.scene import scene_from_dict
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


@functools.cache
def _lowest(wall_from_y: float) -> float:
    """The lowest profile point's y of a wall along x = 0 from ``wall_from_y`` to 2.3 m,
    seen square-on from 1.5 m by 12 elements 1.8 cm apart from y = 0.29 to 0.49 m."""
    ys = 0.29 + 0.018 * np.arange(12)
    scene = scene_from_dict({
        "clsonar": 1, "name": "end", "extent": [-0.3, -1.2, 1.8, 2.6], "cell": 0.0075,
        "surfaces": [{"type": "polyline", "points": [[0.0, 2.3], [0.0, wall_from_y]]}],
        "sensors": {"transducers": [{"position": [1.5, float(y)], "heading_deg": 180.0,
                                     "group": 0} for y in ys]}}, "end")
    result = run(scene, context=get_context(None))
    return float(result.profile.points[:, 1].min())


def test_a_face_ending_at_the_arrays_end_is_not_drawn_past_it():
    """The wall's free end 1 cm below the last element's reflection point: that echo is
    already weaker than a mirror's (its reflection point within a Fresnel zone, 8 cm,
    of the end), so the face ends where a face ending there gives that echo
    (strength.edge_distance): 1.6 mm past its end, where stopping at that reflection
    point left it 9.7 mm short; the region of constant depth drew it 14 cm past its end
    (the zoo's unseen seed 19 wall-09: 4.27 cm RMS)."""
    assert abs(_lowest(0.28) - 0.28) <= 0.003


def test_a_face_going_on_is_still_drawn_over_its_regions_of_constant_depth():
    """The same wall going on 1.5 m below the array: the echoes at the array's end are a
    mirror's, and the face is drawn past its last reflection point (coverage)."""
    assert _lowest(-1.0) <= 0.29 - 0.05


@pytest.mark.parametrize(("seed", "kind", "index"), [(19, "wall", 9), (119, "wall", 9)])
def test_the_zoos_face_past_its_free_end_passes(seed, kind, index):
    case = draw(seed, kind, index)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"] and row["accuracy_m"] is not None and row["accuracy_m"] <= 0.001
