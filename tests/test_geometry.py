"""Derived geometry: walls' front sides, vertex classification, curve sampling, queries."""

import dataclasses
import math

import numpy as np
import pytest

from clsonar.geometry import (
    CORNER,
    EDGE,
    END,
    FLAT,
    SOLID,
    build_geometry,
    curve_derivatives,
    curve_point,
    meet_at_corner,
    nearest_surface_point,
    ray_distance,
)
from clsonar.scene import Circle, EchoModel, Polyline, Scene, Sinusoid

L_ROOM = ((0, 0), (6, 0), (6, 3), (3, 3), (3, 6), (0, 6))  # counter-clockwise, one convex edge


def _geom(*surfaces, **kw):
    return build_geometry(Scene("t", (-10, -10, 10, 10), surfaces=surfaces, **kw))


@pytest.mark.parametrize("points", [L_ROOM, L_ROOM[::-1]], ids=["ccw", "cw"])
def test_room_interior_is_the_front_and_the_reflex_vertex_is_an_edge(points):
    g = _geom(Polyline(points, closed=True))
    assert len(g.walls) == 6 and not g.wall_two_sided.any()
    mid = (g.walls[:, :2] + g.walls[:, 2:]) / 2
    # a step along the front normal from each wall's midpoint lands inside the L
    inside = mid + 0.01 * g.wall_normal
    x, y = inside[:, 0], inside[:, 1]
    assert np.all((x > 0) & (y > 0) & ((x < 3) | (y < 3)) & (x < 6) & (y < 6))
    interior = g.vertex_left if points == L_ROOM else g.vertex_right
    outside = g.vertex_right if points == L_ROOM else g.vertex_left
    idx = [tuple(v) for v in g.vertices].index((3.0, 3.0))
    assert interior[idx] == EDGE
    assert sorted(interior.tolist()) == [CORNER] * 5 + [EDGE]
    assert set(outside.tolist()) == {SOLID}
    assert g.diffractors.shape == (1, 6) and tuple(g.diffractors[0, :2]) == (3.0, 3.0)
    assert len(g.corner_walls) == 5


BOX = ((2.0, 2.0), (4.0, 2.0), (4.0, 3.0), (2.0, 3.0))


@pytest.mark.parametrize("box", [BOX, BOX[::-1]], ids=["ccw", "cw"])
def test_a_closed_polyline_inside_a_room_is_a_solid_box(box):
    """Nested outlines are obstacles: their walls face outwards, their vertices are edges
    seen from outside (diffractors) and true vertices; ``solid`` overrides either way."""
    from clsonar.geometry import true_vertices
    from clsonar.outlines import solid_surfaces

    room = Polyline(((0, 0), (6, 0), (6, 5), (0, 5)), closed=True)
    g = _geom(room, Polyline(box, closed=True))
    assert g.surface_solid.tolist() == [False, True]
    mine = g.wall_surface == 1
    mid = (g.walls[mine, :2] + g.walls[mine, 2:]) / 2
    out = mid + 0.01 * g.wall_normal[mine]
    assert not np.any((out[:, 0] > 2) & (out[:, 0] < 4) & (out[:, 1] > 2) & (out[:, 1] < 3))
    box_vertices = slice(4, 8)
    kinds = {(int(a), int(b)) for a, b in zip(g.vertex_left[box_vertices],
                                              g.vertex_right[box_vertices], strict=True)}
    assert kinds == ({(SOLID, EDGE)} if box == BOX else {(EDGE, SOLID)})
    assert sorted(map(tuple, g.diffractors[:, :2].tolist())) == sorted(BOX)
    assert len(g.corners) == 4  # the room's four corners only
    assert len(true_vertices(g)) == 8
    alone = Polyline(box, closed=True)
    assert solid_surfaces((alone,)) == (False,)  # not nested: a room
    assert solid_surfaces((dataclasses.replace(alone, solid=True),)) == (True,)
    assert solid_surfaces((room, dataclasses.replace(alone, solid=False))) == (False, False)
    touching = Polyline(((0, 0), (1, 0), (1, 1), (0, 1)), closed=True)  # in the room's corner
    assert solid_surfaces((room, touching, Polyline(((1, 1), (2, 1), (2, 2))))) == (
        False, True, False)


def test_open_polyline_vertices_from_both_sides():
    # a corner opening to -x: from the left of the direction of travel it is an edge
    g = _geom(Polyline(((5, 0), (10, 5), (5, 10))))
    assert g.wall_two_sided.all()
    assert g.vertex_left.tolist() == [END, CORNER, END]
    assert g.vertex_right.tolist() == [END, EDGE, END]
    # seen as an edge from behind, and the free end (5, 0) inside the map a knife edge;
    # (5, 10) is on the map's border
    assert [tuple(v) for v in g.diffractors[:, :2]] == [(5.0, 0.0), (10.0, 5.0)]
    met = meet_at_corner(g, np.array([0, 1, 0]), np.array([1, 0, 0]))
    assert met.tolist() == [True, True, False]


def test_collinear_vertex_is_flat():
    g = _geom(Polyline(((0, 0), (1, 0), (2, 0))))
    assert g.vertex_left[1] == FLAT and g.vertex_right[1] == FLAT
    # the flat joint diffracts nothing (the two free ends inside the map do)
    assert [tuple(v) for v in g.diffractors[:, :2]] == [(0.0, 0.0), (2.0, 0.0)]
    assert len(g.corner_walls) == 0


def test_sinusoid_sampling_density_and_analytic_curve():
    s = Sinusoid((8, 0), (8, 10), 0.3, 5.0)
    g = _geom(s)
    steps = np.diff(g.interval_s, axis=1)
    assert len(g.interval_s) == 1000 and np.allclose(steps, 0.01)
    # displaced along the left normal of the base direction (+y → left is -x)
    p = curve_point(g.curves[0], np.array([1.25]))  # quarter period: crest
    assert p[0] == pytest.approx([7.7, 1.25])
    d1, _ = curve_derivatives(g.curves[0], np.array([0.0]))
    assert d1[0] == pytest.approx([-0.3 * 2 * math.pi / 5, 1.0])
    # chords follow walls in the occluders
    assert g.occluders.shape == (1000, 4) and g.chord_start.tolist() == [0]
    short = _geom(Sinusoid((0, 0), (1, 0), 0.01, 0.1), echo=EchoModel(curve_step_m=0.05))
    assert np.max(np.diff(short.interval_s, axis=1)) <= 0.1 / 32 + 1e-12


def test_nearest_point_and_ray_distance():
    g = _geom(Polyline(((9, 0), (9, 10))), Circle((0, 0), 1.0))
    d, q = nearest_surface_point(g, np.array([[8.0, 5.0], [3.0, 0.0], [9.0, 20.0]]))
    assert d == pytest.approx([1.0, 2.0, 10.0])
    assert q == pytest.approx(np.array([[9, 5], [1, 0], [9, 10]]))
    r = ray_distance(g, np.array([[5.0, 5.0], [5.0, 0.0], [5.0, 0.0], [0.0, 0.0]]),
                     np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [1.0, 0.0]]))
    assert r[0] == pytest.approx(4.0) and r[1] == pytest.approx(4.0)
    assert math.isinf(r[2]) and r[3] == pytest.approx(1.0)  # from inside the circle


def test_empty_scene():
    g = _geom()
    d, _ = nearest_surface_point(g, np.zeros((2, 2)))
    assert np.isinf(d).all()
    assert g.occluders.shape == (0, 4) and g.circles.shape == (0, 3)


def test_corner_normals_point_into_the_concave_side():
    for points in (((5, 0), (10, 5), (5, 10)), ((5, 10), (10, 5), (5, 0))):
        g = _geom(Polyline(points))
        assert g.corners.shape == (1, 6) and tuple(g.corners[0, :2]) == (10.0, 5.0)
        inside = np.array([8.0, 5.0]) - g.corners[0, :2]  # a point inside the corner
        assert np.dot(inside, g.corners[0, 2:4]) > 0 and np.dot(inside, g.corners[0, 4:6]) > 0
    room = _geom(Polyline(L_ROOM, closed=True))
    assert len(room.corners) == 5


def test_a_free_end_inside_the_map_is_a_knife_edge_and_one_beyond_it_continues():
    """Issue 18: a thin wall ending inside the map ends there and diffracts as a half-plane
    (both faces of its solid cone along the wall: n = 2); an end on or beyond the map's
    border is taken to continue, and an end on another wall is a junction."""
    from clsonar import physics
    from clsonar.geometry import free_ends

    g = _geom(Polyline(((-20, 0), (2, 0)), closed=False))  # ends at x = -20 (off the map), 2
    assert g.diffractors.shape == (1, 6)
    assert g.diffractors[0].tolist() == [2.0, 0.0, -1.0, 0.0, -1.0, 0.0]
    assert g.vertex_left[g.diffractor_vertex[0]] == END  # still a free end to the mapping
    phi, n = physics.wedge_angles(np.array([2.0, 1.0]), g.diffractors[0, :2],
                                  g.diffractors[0, 2:4], g.diffractors[0, 4:6])
    assert float(n) == 2.0 and float(phi) == pytest.approx(math.pi / 2)
    # an end on the border, and the foot of a partition on a room's wall: no edges
    on_border = _geom(Polyline(((-10, 0), (2, 0)), closed=False))
    assert [tuple(v) for v in on_border.diffractors[:, :2]] == [(2.0, 0.0)]
    room = Polyline(((-5, -5), (5, -5), (5, 5), (-5, 5)), closed=True)
    partition = Polyline(((0, -5), (0, 1)), closed=False)
    g = _geom(room, partition)
    assert [tuple(v) for v in g.diffractors[:, :2]] == [(0.0, 1.0)]
    # a box drawn as an open polyline back to its start: its two ends meet, a junction
    # (its three other corners diffract as convex edges, as before)
    box = Polyline(((1, 1), (2, 1), (2, 2), (1, 2), (1, 1)), closed=False)
    g = _geom(box)
    ends = free_ends((-10, -10, 10, 10), g.walls, g.vertices, g.vertex_walls)
    assert len(ends) == 0 and len(g.diffractors) == 3
