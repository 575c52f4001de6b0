"""Issue 14: where a wall's end is drawn — a wall meets the first wall its extension reaches
(post.walls, a U room's notch), and a join of one array's parts keeps the end its parts
found (mapping.joins.silence_clamp)."""

import numpy as np

from clsonar import pipeline
from clsonar.opencl import get_context
from clsonar.post.walls import PASSES_M, fit_walls
from clsonar.scene import PostSettings
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score

#: a room's automatic walls fit (survey), with the zoo's seed 73 room-06's join_m
WALLS = PostSettings(fit="walls", max_gap_m=0.3, join_m=1.64)


def _segment(a, b, step=0.005):
    a, b = np.asarray(a, float), np.asarray(b, float)
    n = int(np.hypot(*(b - a)) / step) + 1
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def _notch(top=7.578, left=3.116, right=4.156):
    """What a ring scan maps of a U room's notch, as in seed 73 room-06: the two walls
    beside its mouth, each ending near it, and its two sides, ending about 1 m below the
    mouth (the ring never comes nearer), all about 2.2 m long."""
    return [_segment((0.86, top), (left - 0.08, top)), _segment((right + 0.04, top), (6.4, top)),
            _segment((left, 4.28), (left, 6.585)), _segment((right, 4.44), (right, 6.58))]


def test_the_walls_beside_a_notchs_mouth_meet_its_near_sides():
    """Each wall beside the mouth meets the notch's side it reaches first, not the far one
    (which the longest-first order joined before: two walls drawn across the mouth)."""
    profile = fit_walls(_notch(), 0.005, WALLS)
    vertices = {tuple(np.round(v, 3)) for v in profile.vertices}
    assert vertices == {(3.116, 7.578), (4.156, 7.578)}
    points = np.concatenate(profile.curves)
    in_mouth = (points[:, 0] > 3.116 + PASSES_M) & (points[:, 0] < 4.156 - PASSES_M)
    assert not np.any(in_mouth & (np.abs(points[:, 1] - 7.578) < 0.01))


def test_a_wall_still_meets_a_far_wall_past_a_short_one():
    """A stretch shorter than 0.5 m on the way (a chamfer's piece across a corner) does
    not stop two long walls from meeting at their corner."""
    curves = [_segment((0.0, 2.0), (1.6, 2.0)), _segment((2.0, 0.0), (2.0, 1.6)),
              _segment((1.75, 1.95), (1.95, 1.75))]
    vertices = fit_walls(curves, 0.005, WALLS).vertices
    assert np.min(np.hypot(*(vertices - (2.0, 2.0)).T)) < 1e-9


def test_a_u_rooms_notch_is_not_bridged():
    """The zoo's unseen seed 73 room-06 (a U room scanned by rings): 6.7 cm RMS with the
    mouth of its notch drawn over, 0.1 cm now."""
    case = draw(73, "room", 6)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["accuracy_m"] < 0.002 and row["vertex_error_m"] < 0.01


def test_one_arrays_joined_face_keeps_the_end_its_parts_found():
    """The zoo's unseen seed 60 edge-02 (σ 0.3): two families of one array on one face,
    joined; cut again as one patch it ended 2.4 cm short of the edge (its second part had
    reached it), 0.17 cm now."""
    case = draw(60, "edge", 2)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["vertex_error_m"] < 0.005 and row["accuracy_m"] < 0.001
