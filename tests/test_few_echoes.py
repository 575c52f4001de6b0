"""Maps of scenes heard by too few echoes for any reflector's model (issue 14: every scene
gives a map): the crossings of the loud echoes' loci, with a warning that says so."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import pipeline
from clsonar.mapping.crossings import crossing_points
from clsonar.mapping.few import common_tangents, loud_crossings, two_echo_corner
from clsonar.mapping.loci import Loci
from clsonar.mapping.methods import _loci
from clsonar.mapping.patches import Patches
from clsonar.opencl import get_context
from clsonar.scene import scene_from_dict
from clsonar.sensors import place_sensors
from clsonar.survey import DEFAULT_MIN_ENVELOPE
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


def _two_elements(point, xs, turns):
    """Two elements on the x axis at ``xs``, each turned ``turns`` degrees off the line to
    ``point`` (a point reflector), and the scene they stand in."""
    P = np.asarray(point, dtype=np.float64)
    T = np.stack([np.asarray(xs, dtype=np.float64), np.zeros(2)], axis=1)
    heading = [float(np.degrees(np.arctan2(*(P - t)[::-1]))) + d
               for t, d in zip(T, turns, strict=True)]
    scene = scene_from_dict({
        "clsonar": 1, "name": "two", "extent": [-2, -1, 2, 9],
        "surfaces": [{"type": "circle", "center": P.tolist(), "radius": 0.01}],
        "sensors": {"transducers": [{"position": t.tolist(), "heading_deg": h}
                                    for t, h in zip(T, heading, strict=True)]}})
    return scene, place_sensors(scene), T


@settings(max_examples=40)
@given(st.floats(-1, 1), st.floats(0.3, 8), st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)),
       st.tuples(st.floats(-8, 8), st.floats(-8, 8)))
def test_two_loci_of_a_point_reflector_cross_at_it(x, y, xs, turns):
    """Two monostatic loci (ranges |P − T_k|) of a point P inside both beams (±8° of the
    axes, the beam ±12°), from elements at least 5 cm apart: one crossing at P (loci
    sampled every 0.25°, crossings interpolated: within 50 µm out to 8 m), kept by the
    nearer locus."""
    if abs(xs[0] - xs[1]) < 0.05:
        return
    point = np.array([x, y])
    scene, sensors, T = _two_elements(point, xs, turns)
    r = np.hypot(*(point - T).T)
    loci = Loci(np.array([0, 1]), np.array([0, 1]), 2 * r / scene.medium.c, np.ones(2))
    q, source = crossing_points(scene, sensors, loci)
    assert len(q) == 1
    assert np.hypot(*(q[0] - point)) < 5e-5
    assert source[0] == int(np.argmin(r))


def test_loci_that_do_not_cross_give_no_point():
    """Two loud loci whose circles do not meet (ranges 3 and 3.6 m from elements 0.5 m
    apart): no point."""
    scene, sensors, _ = _two_elements((0.2, 3.0), (-0.2, 0.3), (0.0, 0.0))
    loci = Loci(np.array([0, 1]), np.array([0, 1]), np.array([6.0, 7.2]) / scene.medium.c,
                np.full(2, 2.0))
    q, source = crossing_points(scene, sensors, loci)
    assert q.shape == (0, 2) and source.shape == (0,)


def test_a_weak_echo_crosses_nothing():
    """A locus under the floor (a diffraction's or a multipath's) is left out: with one
    loud locus left, no point."""
    point = np.array([0.2, 3.0])
    scene, sensors, T = _two_elements(point, (-0.2, 0.3), (0.0, 0.0))
    r = np.hypot(*(point - T).T)
    none = np.zeros((0, 2))
    empty = Patches(none, np.zeros(0, np.int64), none, np.zeros(0, np.int64))
    for amplitude, found in ((DEFAULT_MIN_ENVELOPE, 1), (0.5 * DEFAULT_MIN_ENVELOPE, 0)):
        loci = Loci(np.array([0, 1]), np.array([0, 1]), 2 * r / scene.medium.c,
                    np.array([2.0, amplitude]))
        drawn = loud_crossings(scene, sensors, loci, empty)
        assert len(drawn.points) == len(drawn.vertices) == found


def test_a_thin_post_two_elements_heard_is_mapped_and_the_run_says_how():
    """The zoo's unseen seed 67 post-03: a 5 cm post 0.44 m from a sparse random-lines array,
    heard by two elements 12.6 cm apart and no other (two echoes): mapped at the crossing
    of their loci, 0.5 mm from the post's surface, where the map was empty before; the run
    warns that the map is only that."""
    case = draw(67, "post", 3)
    result = pipeline.run(case.scene, context=get_context())
    row = score(case, result)
    assert row["detections"] == 2 and row["points"] == 1
    assert row["accuracy_m"] < 0.001
    assert result.counts["crossing_points"] == 1
    assert result.warnings == ("the map holds only the 1 point(s) where two loud echoes' "
                               "loci cross: the 2 echoes detected are too few for a "
                               "surface's model",)


def test_a_map_of_a_located_vertex_alone_is_not_a_few_echoes_map():
    """The zoo's unseen seed 67 corner-00 (arrays): its map is the corner's vertex alone,
    located by the families (no patch, no point): no crossing is added, no warning."""
    result = pipeline.run(draw(67, "corner", 0).scene, context=get_context())
    assert result.counts["vertices_located"] == 1 and result.counts["crossing_points"] == 0
    assert len(result.profile.points) == 1 and result.warnings == ()


@settings(max_examples=60)
@given(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), st.tuples(st.floats(-5, 5), st.floats(-5, 5)),
       st.floats(0.1, 9), st.floats(0.1, 9))
def test_both_loci_touch_their_common_tangents(t1, t2, r1, r2):
    """Each line of few.common_tangents is ρ_k from T_k, both on the side away from n;
    none where one circle holds the other."""
    T, rho = np.array([t1, t2], dtype=np.float64), np.array([r1, r2])
    apart = np.hypot(*(T[0] - T[1]))
    if apart < abs(r1 - r2) or apart == 0:  # one circle inside the other: no such line
        assert np.all(np.isnan(common_tangents(T, rho)))
        return
    for n in common_tangents(T, rho):
        assert abs(np.hypot(*n) - 1.0) < 1e-12
        d = n @ T.T + rho  # the line n·x = d through each reflection point T_k + ρ_k·n
        assert abs(d[0] - d[1]) < 1e-9 * (1 + np.abs(d).max())


def test_a_wall_two_elements_heard_is_a_face_not_their_crossing():
    """The zoo's unseen seed 74 wall-07: two elements of a random-lines array 1.1 m apart,
    7.3 m from a wall tilted 29°, each heard it once, as loud as the plane their loci
    touch. Their crossing, 1.5 cm in front of the wall, was the map; now the face they
    are the echoes of is, over its regions of constant depth: 100 % complete."""
    case = draw(74, "wall", 7)
    result = pipeline.run(case.scene, context=get_context())
    row = score(case, result)
    assert row["accuracy_m"] < 1e-4 and row["completeness_3cm"] > 0.99
    assert result.counts["two_echo_faces"] == 1 and result.counts["crossing_points"] == 0
    assert result.warnings == ("the map holds only 1 face(s) each drawn from two elements' "
                               "echoes: the 2 echoes detected are too few for a surface's "
                               "model",)


def test_a_corner_two_elements_heard_by_its_double_bounce_is_its_vertex():
    """The zoo's unseen seed 157 corner-07: two elements of a random-lines placement, 1.4 m
    apart, heard a 90° corner 7.9 m away once each (its double bounce, 2.7 units, as a
    corner there returns; the plane their loci touch would give 0.29 and 4.3), and the
    map had only a free end's weak diffraction, 1.6 m from the corner. Their loci's
    crossing is located as the corner's vertex; a wall's two echoes (seed 74 wall-07) are
    no corner."""
    case = draw(157, "corner", 7)
    result = pipeline.run(case.scene, context=get_context())
    row = score(case, result)
    assert row["vertex_error_m"] < 1e-4 and row["passed"]
    wall = draw(74, "wall", 7).scene
    done = pipeline.run(wall, context=get_context())
    loci = _loci(wall, done.detections)
    assert len(loci) == 2
    assert two_echo_corner(wall, done.sensors, loci, np.array([0, 1])) is None


def test_an_echo_from_where_two_drawn_faces_cross_is_their_vertex():
    """few.faces_corners: two straight faces drawn 1 m short of where their lines cross
    (a right-angled corner at (0.2, 3.0)), and one element's echo from that point, too
    weak for a tangent point: the crossing is a located vertex. Not with the echo 1 cm
    off in path, nor with a vertex drawn there already, nor for faces 10° apart."""
    from clsonar.mapping.few import faces_corners

    corner = np.array([0.2, 3.0])
    scene, sensors, T = _two_elements(corner, (-0.2, 0.3), (0.0, 0.0))
    left = np.linspace(-1.8, -0.8, 21)[:, None] * np.array([[1.0, 0.0]]) + corner
    up = np.linspace(1.2, 2.0, 17)[:, None] * np.array([[0.0, 1.0]]) + corner
    points = np.concatenate([left, up])
    ends = np.array([len(left), len(points)])
    source = np.zeros(len(points), np.int64)  # every point credited to locus 0
    drawn = Patches(points, source, np.zeros((0, 2)), ends)
    path = 2 * np.hypot(*(corner - T[1]))
    for off, found in ((0.0, 1), (0.01, 0)):
        loci = Loci(np.array([0, 1]), np.array([0, 1]),
                    np.array([1.0, (path + off) / scene.medium.c]), np.array([2.0, 0.27]))
        out = faces_corners(scene, sensors, loci, drawn)
        assert len(out.vertices) == found
        if found:
            np.testing.assert_allclose(out.vertices[0], corner, atol=1e-9)
            assert out.source[-1] == 1
    loci = Loci(np.array([0, 1]), np.array([0, 1]), np.array([1.0, path / scene.medium.c]),
                np.array([2.0, 0.27]))
    there = Patches(points, source, corner[None], ends)
    assert len(faces_corners(scene, sensors, loci, there).vertices) == 1
    turn = np.radians(10.0)
    tilted = np.linspace(1.2, 2.0, 17)[:, None] * np.array([[-np.cos(turn), np.sin(turn)]])
    shallow = Patches(np.concatenate([left, tilted + corner]), source, np.zeros((0, 2)), ends)
    assert len(faces_corners(scene, sensors, loci, shallow).vertices) == 0


def test_a_corner_whose_walls_were_drawn_short_is_located_by_its_double_bounce():
    """The zoo's unseen seed 171 corner-07 (random lines, noise-free): both walls of a
    right-angled corner 2.1 m away were drawn, each about 1 m short of it, and one element
    heard its double bounce at 0.27 units: the vertex was 95 cm from the map. The walls'
    lines cross where that echo came from: the vertex, 0.001 cm off."""
    case = draw(171, "corner", 7)
    row = score(case, pipeline.run(case.scene, context=get_context()))
    assert row["passed"] and row["vertex_error_m"] < 0.001
