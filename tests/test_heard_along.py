"""A wall's echoes beyond its mapped stretch extend it (:func:`clsonar.mapping.along.
heard_along`, :func:`clsonar.post.walls.heard_further`): a ring moving straight at a wall
hears it where no scan envelope places it, and the wall's line, once known, does."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import pipeline
from clsonar.mapping.along import heard_along
from clsonar.mapping.strength import mirror_echo
from clsonar.opencl import get_context
from clsonar.scene import scene_from_dict
from clsonar.sensors import place_sensors
from clsonar.signals.detection import Detections
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score

#: The wall y = 0 seen from y = RANGE by elements facing it square-on.
RANGE = 1.0


def _scene(xs: list[float]):
    return scene_from_dict({
        "clsonar": 1, "name": "along", "extent": [-2.0, -0.5, 6.0, 1.5], "cell": 0.01,
        "surfaces": [{"type": "polyline", "points": [[-2.0, 0.0], [6.0, 0.0]]}],
        "sensors": {"transducers": [{"position": [x, RANGE], "heading_deg": -90.0}
                                    for x in xs]}}, "along")


def _along(xs: list[float], off_m: list[float] | None = None,
           share: list[float] | None = None):
    """``heard_along`` of one T = R echo per element at x, its path ``off_m`` from the
    wall's mirror path and its amplitude ``share`` of a mirror's."""
    scene = _scene(xs)
    sensors = place_sensors(scene)
    n = len(xs)
    off = np.zeros(n) if off_m is None else np.asarray(off_m)
    amp = mirror_echo(scene) * (np.ones(n) if share is None else np.asarray(share))
    tx = np.arange(n, dtype=np.int64)
    found = Detections(tx, tx.copy(), (2 * RANGE + off) / scene.medium.c, amp)
    return heard_along(scene, sensors, found)


CENTRE, ALONG = np.array([0.0, 0.0]), np.array([1.0, 0.0])


@settings(max_examples=40, deadline=None)
@given(xs=st.lists(st.floats(0.05, 5.0), min_size=1, max_size=8, unique=True),
       reach=st.floats(0.1, 1.5))
def test_echoes_extend_a_wall_one_reach_after_another(xs, reach):
    """From its end at x = 0 the span takes each reflection point within ``reach`` of the
    end so far, and stops at the first gap wider than that."""
    lo, hi = _along(xs)(CENTRE, ALONG, -1.0, 0.0, 0.0, reach)
    end = 0.0
    for x in sorted(xs):
        if x - end > reach:
            break
        end = x
    assert lo == -1.0
    assert abs(hi - end) <= 1e-9


def test_echoes_beyond_either_end_extend_it():
    lo, hi = _along([-1.4, -1.2, 0.3])(CENTRE, ALONG, -1.0, 0.0, 0.0, 0.5)
    assert abs(lo + 1.4) <= 1e-9 and abs(hi - 0.3) <= 1e-9


def test_an_echo_off_the_walls_path_or_too_weak_for_a_mirror_does_not():
    """A path 5 mm off the line's mirror path (another reflector's echo), or an echo no
    stronger than an edge's diffraction (under half a mirror's), is not the wall's."""
    assert _along([0.3], off_m=[0.005])(CENTRE, ALONG, -1.0, 0.0, 0.0, 1.0) == (-1.0, 0.0)
    assert _along([0.3], share=[0.4])(CENTRE, ALONG, -1.0, 0.0, 0.0, 1.0) == (-1.0, 0.0)
    _, hi = _along([0.3], off_m=[0.003])(CENTRE, ALONG, -1.0, 0.0, 0.002, 1.0)
    assert abs(hi - 0.3) <= 1e-6  # within the line's own uncertainty (slack)


def test_a_walls_stretch_a_ring_moving_straight_at_it_heard_meets_the_corner():
    """Unseen seed 120 room-25: a slanted room's 97° corner that the rings' loop cuts; the
    only poses that heard the walls beside it moved straight at them (within 7° of their
    normals), their envelope ahead along the path, and the walls stopped 0.74 and 1.0 m
    short of the corner (75 cm vertex error, 84 % complete)."""
    case = draw(120, "room", 25)
    row = score(case, pipeline.run(case.scene, context=get_context(None)))
    assert row["passed"]
    assert row["vertex_error_m"] <= 0.002 and row["completeness_3cm"] >= 0.99
