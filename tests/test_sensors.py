"""Transducer placement (thesis §2.1 random linear arrays, §2.1.2 circular and wall-following
arrays) and the transmitter→receiver pairs."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.errors import SceneError
from clsonar.geometry import build_geometry, nearest_surface_point, ray_distance
from clsonar.scene import Circular, PerWall, RandomLines, WallFollowing, scene_from_dict
from clsonar.sensors import (
    SensorArray,
    in_free_space,
    pairs,
    per_wall_lines,
    place_circular,
    place_per_wall,
    place_random_lines,
    place_sensors,
    place_wall_following,
    ring,
    square_to_walls,
    wall_following_path,
    wall_following_substep,
)

TOL = 1e-9


def make_scene(surfaces, placement=None, transducers=(), extent=(0.0, 0.0, 10.0, 10.0)):
    return scene_from_dict({
        "clsonar": 1, "name": "test", "extent": list(extent), "surfaces": list(surfaces),
        "sensors": {"transducers": list(transducers), "placement": placement},
    })


def wall(a, b):
    return {"type": "polyline", "points": [list(a), list(b)], "closed": False}


def room(points):
    return {"type": "polyline", "points": [list(p) for p in points], "closed": True}


def circle(c, r):
    return {"type": "circle", "center": list(c), "radius": r}


PLANE = [wall((9.0, 0.0), (9.0, 10.0))]


def lines(**kw):
    return {"type": "random-lines", **kw}


def place(scene):
    return place_sensors(scene, build_geometry(scene))


def segments_cross(geom, a, b):
    """[M] bool: segments a[i]→b[i] meet a surface."""
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    return ray_distance(geom, a, d / length[:, None]) <= length


# --------------------------------------------------------------------------- ring / circular


def test_ring_is_thesis_circular_array():
    pos, head = ring((2.0, 3.0), 0.065, 8, 0.0)
    np.testing.assert_allclose(head, np.arange(8) * 45.0)
    np.testing.assert_allclose(np.hypot(*(pos - [2.0, 3.0]).T), 0.065)
    # every transducer faces straight outwards
    outward = np.degrees(np.arctan2(pos[:, 1] - 3.0, pos[:, 0] - 2.0)) % 360.0
    np.testing.assert_allclose(outward, head % 360.0, atol=1e-9)
    np.testing.assert_allclose(pos[0], [2.065, 3.0])
    np.testing.assert_allclose(pos[2], [2.0, 3.065])


def test_place_circular_defaults_to_thesis_ring():
    pos, head, groups, poses = place_circular(Circular(center=(5.0, 5.0)))
    assert pos.shape == (8, 2) and head.shape == (8,)
    assert groups.dtype == np.int64 and np.all(groups == 0)
    np.testing.assert_allclose(poses, [[5.0, 5.0]])
    np.testing.assert_allclose(np.hypot(*(pos - 5.0).T), 0.065)


# --------------------------------------------------------------------------- random lines


def _check_random_lines(p: RandomLines, pos, head, groups):
    """Spacing, gaps, headings, group sizes and collinearity of a random-lines placement."""
    u = np.array([math.cos(math.radians(p.direction_deg)), math.sin(math.radians(p.direction_deg))])
    start = np.asarray(p.start)
    rel = pos - start
    s = rel @ u
    np.testing.assert_allclose(rel[:, 0] * u[1] - rel[:, 1] * u[0], 0.0, atol=1e-9)  # on line
    assert s[0] == pytest.approx(0.0, abs=1e-12)
    assert np.all(s <= p.length_m + TOL)
    same = np.diff(groups) == 0
    steps = np.diff(s)
    assert np.all(np.diff(groups) >= 0) and np.all(np.diff(groups) <= 1)
    assert groups[0] == 0 and groups.dtype == np.int64
    lo, hi = p.spacing_m
    assert np.all((steps[same] >= lo - TOL) & (steps[same] <= hi + TOL))
    sizes = np.bincount(groups)
    full = np.flatnonzero(sizes == p.elements)
    centres = np.array([0.5 * (s[groups == g].min() + s[groups == g].max()) for g in full])
    lo, hi = p.separation_m
    assert np.all((np.diff(centres) >= lo - TOL) & (np.diff(centres) <= hi + TOL))
    assert np.all(sizes[:-1] == p.elements) and 1 <= sizes[-1] <= p.elements
    offset = (head - p.facing_deg + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(offset) <= p.heading_spread_deg + TOL)
    return s


def test_random_lines_thesis_ranges_in_front_of_a_plane():
    scene = make_scene(PLANE, lines(seed=5, start=[7.0, 0.1], length_m=9.8))
    p = scene.sensors.placement
    pos, head, groups, poses = place_random_lines(p, scene, build_geometry(scene))
    assert poses.shape == (0, 2)
    assert len(pos) >= 30
    _check_random_lines(p, pos, head, groups)
    # facing the wall ±90°: the thesis' "orientations between 0° and 180°"
    assert np.all(np.abs(head) <= 90.0)
    assert len(np.unique(np.round(head, 6))) == len(head)  # really random


@settings(max_examples=25)
@given(seed=st.integers(0, 2**32), direction=st.floats(-180, 180),
       elements=st.integers(1, 12), spread=st.floats(0, 180), facing=st.floats(-360, 360))
def test_random_lines_ranges_property(seed, direction, elements, spread, facing):
    scene = make_scene(PLANE, lines(seed=seed, start=[5.0, 5.0], direction_deg=direction,
                                    elements=elements, heading_spread_deg=spread,
                                    facing_deg=facing, length_m=20.0))
    p = scene.sensors.placement
    geom = build_geometry(scene)
    pos, head, groups, _ = place_random_lines(p, scene, geom)
    _check_random_lines(p, pos, head, groups)
    assert np.all(nearest_surface_point(geom, pos)[0] >= p.clearance_m)
    assert np.all((pos >= 0.0) & (pos <= 10.0))


def test_random_lines_deterministic_for_a_seed():
    a = make_scene(PLANE, lines(seed=42, start=[6.0, 0.5]))
    b = make_scene(PLANE, lines(seed=42, start=[6.0, 0.5]))
    c = make_scene(PLANE, lines(seed=43, start=[6.0, 0.5]))
    pa, pb, pc = place(a), place(b), place(c)
    np.testing.assert_array_equal(pa.positions, pb.positions)
    np.testing.assert_array_equal(pa.headings_deg, pb.headings_deg)
    np.testing.assert_array_equal(pa.groups, pb.groups)
    assert not np.array_equal(pa.headings_deg, pc.headings_deg)


def test_random_lines_random_start_is_seeded_and_in_free_space():
    scene = make_scene([room([(1, 1), (9, 1), (9, 9), (1, 9)]), circle((5, 5), 1.0)],
                       lines(seed=7, length_m=3.0))
    first, second = place(scene), place(scene)
    np.testing.assert_array_equal(first.positions, second.positions)
    geom = build_geometry(scene)
    assert len(first) >= 1
    assert np.all(in_free_space(scene, geom, first.positions))
    assert np.all(nearest_surface_point(geom, first.positions)[0] >= 0.05)


def test_random_lines_stop_before_a_surface_across_the_line():
    # wall across the line at y = 6: placement ends there for good
    scene = make_scene([wall((0.0, 6.0), (10.0, 6.0))],
                       lines(seed=3, start=[5.0, 0.2], length_m=9.0, clearance_m=0.3))
    s = place(scene)
    y = s.positions[:, 1]
    assert np.all(y <= 6.0 - 0.3 + TOL)
    # it stopped because of the wall, not the length: the next element would have been
    # closer than the clearance, at most one gap (1.65 m) further on
    assert y.max() > 6.0 - 0.3 - 1.65


def test_random_lines_stop_at_the_extent():
    scene = make_scene(PLANE, lines(seed=4, start=[5.0, 8.0], length_m=50.0))
    s = place(scene)
    assert np.all(s.positions[:, 1] <= 10.0)
    assert s.positions[:, 1].max() > 10.0 - 1.65


def test_random_lines_stop_at_length():
    scene = make_scene(PLANE, lines(seed=4, start=[5.0, 0.0], length_m=2.0))
    s = place(scene)
    assert s.positions[:, 1].max() <= 2.0
    assert s.positions[:, 1].max() > 2.0 - 1.65


def test_random_lines_never_jump_over_a_thin_wall():
    # no clearance, so only the crossing test can stop it at the wall y = 3
    scene = make_scene([wall((0.0, 3.0), (10.0, 3.0))],
                       lines(seed=9, start=[5.0, 0.1], length_m=9.0, clearance_m=0.0))
    s = place(scene)
    assert np.all(s.positions[:, 1] < 3.0)


def test_random_lines_inside_a_room_stay_inside():
    scene = make_scene([room([(1, 1), (9, 1), (9, 9), (1, 9)])],
                       lines(seed=2, start=[2.0, 1.5], length_m=20.0))
    s = place(scene)
    assert np.all((s.positions[:, 1] > 1.0) & (s.positions[:, 1] < 9.0 - 0.05))


@pytest.mark.parametrize("start, why", [
    ([9.02, 5.0], "clearance"),  # too near the wall
    ([11.0, 5.0], "extent"),  # outside the map
    ([5.0, 5.0], "solid"),  # inside the cylinder
])
def test_random_lines_that_place_nothing_raise(start, why):
    scene = make_scene([*PLANE, circle((5.0, 5.0), 1.0)], lines(seed=1, start=start))
    with pytest.raises(SceneError, match="placed no transducer") as e:
        place(scene)
    assert e.value.key == "sensors.placement"
    assert e.value.source == "test"
    assert why in str(e.value)


# --------------------------------------------------------------------------- wall following

RECT = [(1, 1), (9, 1), (9, 6), (1, 6)]
L_ROOM = [(1, 1), (9, 1), (9, 4), (4, 4), (4, 9), (1, 9)]  # convex edge at (4, 4)


def _wall_following(surfaces, **kw):
    scene = make_scene(surfaces, {"type": "wall-following", **kw})
    geom = build_geometry(scene)
    p = scene.sensors.placement
    return scene, geom, p, place_wall_following(p, scene, geom)


def _check_wall_following(scene, geom, p: WallFollowing, result):
    pos, head, groups, poses = result
    g = len(poses)
    assert g >= 3
    assert pos.shape == (g * p.elements, 2) and head.shape == (g * p.elements,)
    np.testing.assert_array_equal(groups, np.repeat(np.arange(g), p.elements))
    # each pose a thesis ring around its centre
    for k in (0, g // 2, g - 1):
        start = square_to_walls(geom, p.elements) if p.start_deg is None else p.start_deg
        rp, rh = ring(tuple(poses[k]), p.radius_m, p.elements, start)
        np.testing.assert_allclose(pos[groups == k], rp)
        np.testing.assert_allclose(head[groups == k], rh)
    # at the clearance, in free space, never behind a wall
    dist = nearest_surface_point(geom, poses)[0]
    np.testing.assert_allclose(dist, p.clearance_m, atol=0.01)
    assert np.all(in_free_space(scene, geom, poses))
    assert np.all(in_free_space(scene, geom, pos))
    assert np.all(nearest_surface_point(geom, pos)[0] > p.clearance_m - p.radius_m - 0.01)
    closed = np.concatenate([poses, poses[:1]])
    assert not np.any(segments_cross(geom, closed[:-1], closed[1:]))
    # consecutive poses step_m apart along the traced path, which closes on itself
    path, arc, length = wall_following_path(p, scene, geom)
    h = wall_following_substep(p)
    assert not np.any(segments_cross(geom, path[:-1], path[1:]))
    assert np.all(np.diff(arc) <= 1.01 * h) and np.all(np.diff(arc) > 0.25 * h)
    assert np.hypot(*(path[-1] - path[0])) <= 1.5 * h
    np.testing.assert_allclose(poses[0], path[0], atol=1e-9)
    nearest = np.argmin(np.hypot(*(poses[:, None] - path[None]).transpose(2, 0, 1)), axis=1)
    pose_arc = arc[nearest]
    np.testing.assert_allclose(np.diff(pose_arc), p.step_m, atol=h)
    assert length - pose_arc[-1] <= p.step_m + h  # last pose is the last one before the start
    assert g == math.ceil((length - 0.5 * h) / p.step_m)
    chords = np.hypot(*np.diff(poses, axis=0).T)
    assert np.all(chords <= p.step_m + 1e-6) and np.all(chords >= p.step_m / 3)
    return path, length


def test_wall_following_rectangle():
    scene, geom, p, result = _wall_following([room(RECT)], start=[3.0, 3.0])
    _path, length = _check_wall_following(scene, geom, p, result)
    # offset rectangle 7 × 4 with clearance 0.5: perimeter 22, start projected to (3, 1.5)
    assert length == pytest.approx(22.0, abs=0.01)
    np.testing.assert_allclose(result[3][0], [3.0, 1.5])
    assert len(result[3]) == 44


@pytest.mark.parametrize("direction, sign", [("ccw", 1.0), ("cw", -1.0)])
def test_wall_following_direction(direction, sign):
    """ccw keeps the wall on the right (runs a room counter-clockwise), cw on the left."""
    _scene, _geom, _p, result = _wall_following([room(RECT)], start=[3.0, 3.0],
                                             direction=direction)
    poses = result[3]
    x, y = poses[:, 0], poses[:, 1]
    area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
    assert np.sign(area) == sign
    assert abs(area) == pytest.approx(7.0 * 4.0, rel=0.02)
    assert poses[1][0] == pytest.approx(3.0 + 0.5 * sign)


def test_wall_following_l_room_arcs_around_the_convex_edge():
    scene, geom, p, result = _wall_following([room(L_ROOM)], start=[2.0, 2.0],
                                             step_m=0.3, clearance_m=0.4)
    path, length = _check_wall_following(scene, geom, p, result)
    # around the edge (4, 4) the path is a quarter circle of radius 0.4
    near_edge = path[np.all(path <= 4.0, axis=1) & (np.hypot(*(path - [4.0, 4.0]).T) < 0.45)]
    assert len(near_edge) > 5
    np.testing.assert_allclose(np.hypot(*(near_edge - [4.0, 4.0]).T), 0.4, atol=1e-6)
    # offset outline: the straight runs of the six walls shortened at the five concave
    # corners, plus the quarter circle round the edge
    straight = (8 - 0.8) + (3 - 0.8) + (5 - 0.4) + (5 - 0.4) + (8 - 0.8) + (3 - 0.8)
    assert length == pytest.approx(straight + 0.5 * math.pi * 0.4, abs=0.01)


def test_wall_following_around_a_cylinder_near_a_wall():
    # gap of 0.5 m between the cylinder and the bottom wall: too narrow for the ring, so
    # the path leaves the wall, goes round the cylinder and comes back to the wall
    scene, geom, p, result = _wall_following([room(RECT), circle((5.0, 2.3), 0.8)],
                                             start=[2.0, 3.0])
    path, _ = _check_wall_following(scene, geom, p, result)
    around = np.hypot(*(path - [5.0, 2.3]).T)
    assert np.any(np.abs(around - 1.3) < 1e-6) and np.all(around > 1.3 - 1e-6)
    assert np.any(path[:, 1] > 3.5)  # over the top of the cylinder


def test_wall_following_around_a_free_cylinder():
    scene, geom, p, result = _wall_following([room(RECT), circle((5.0, 3.5), 1.0)],
                                             start=[5.0, 4.8], step_m=0.4, clearance_m=0.3)
    _path, length = _check_wall_following(scene, geom, p, result)
    assert length == pytest.approx(2 * math.pi * 1.3, rel=1e-3)
    assert len(result[3]) == math.ceil(2 * math.pi * 1.3 / 0.4)
    np.testing.assert_allclose(np.hypot(*(result[3] - [5.0, 3.5]).T), 1.3, atol=1e-6)


BOX = [(4.0, 3.0), (6.0, 3.0), (6.0, 4.0), (4.0, 4.0)]


@pytest.mark.parametrize("box", [BOX, BOX[::-1]], ids=["ccw", "cw"])
def test_wall_following_around_a_box_inside_a_room(box):
    """A closed polyline inside the room is a solid box: the ring goes round its outside
    (the offset square with quarter circles at its four edges), never inside it."""
    scene, geom, p, result = _wall_following([room(RECT), room(box)], start=[5.0, 4.5],
                                             step_m=0.4, clearance_m=0.3)
    path, length = _check_wall_following(scene, geom, p, result)
    assert length == pytest.approx(2 * (2.0 + 1.0) + 2 * math.pi * 0.3, rel=1e-3)
    x, y = path[:, 0], path[:, 1]
    assert not np.any((x > 4.0) & (x < 6.0) & (y > 3.0) & (y < 4.0))
    assert np.all(nearest_surface_point(geom, path)[0] == pytest.approx(0.3, abs=1e-6))
    assert not np.any(in_free_space(scene, geom, np.array([[5.0, 3.5], [4.1, 3.9]])))
    # "solid": false: the same outline is a room inside the room, followed on its inside
    inner = {**room(box), "solid": False}
    scene, geom, p, result = _wall_following([room(RECT), inner], start=[5.0, 3.5],
                                             step_m=0.2, clearance_m=0.3)
    assert np.all(np.abs(result[3] - [5.0, 3.5]) <= [0.7 + 1e-6, 0.2 + 1e-6])


@pytest.mark.parametrize("surfaces, kw, message", [
    ([room(RECT), room(BOX)], {"start": [5.0, 3.5]}, "not in free space"),
    ([wall((9.0, 0.0), (9.0, 10.0))], {"start": [8.0, 5.0]}, "left the extent"),
    ([room(RECT)], {"start": [3.0, 3.0], "clearance_m": 3.0}, "no place at clearance"),
    ([room(RECT)], {"start": [3.0, 3.0], "max_poses": 10}, "max_poses"),
    ([room(RECT)], {"start": [0.5, 3.0]}, "not in free space"),
    ([room(RECT), circle((5, 3), 1)], {"start": [5.0, 3.0]}, "not in free space"),
    ([room(RECT)], {"start": [3.0, 1.0]}, "on a surface"),
    ([], {"start": [3.0, 3.0]}, "no surface"),
    ([room(RECT)], {"start": [3.0, 3.0], "radius_m": 0.6}, "smaller than clearance"),
    # corridor 0.8 m wide, clearance 0.5: no curve to follow
    ([room([(1, 1), (9, 1), (9, 1.8), (1, 1.8)])], {"start": [3.0, 1.4]}, "clearance"),
])
def test_wall_following_errors_name_the_placement(surfaces, kw, message):
    scene = make_scene(surfaces, {"type": "wall-following", **kw})
    with pytest.raises(SceneError, match=message) as e:
        place(scene)
    assert e.value.key.startswith("sensors.placement")


# --------------------------------------------------------------------------- per wall

#: RECT's walls in outline order: (first end, second end, inward normal, heading facing it).
RECT_WALLS = [((1, 1), (9, 1), (0, 1), -90.0), ((9, 1), (9, 6), (-1, 0), 0.0),
              ((9, 6), (1, 6), (0, -1), 90.0), ((1, 6), (1, 1), (1, 0), 180.0)]


def per_wall(**kw):
    return {"type": "per-wall", **kw}


def _wall_of(head):
    """Index into RECT_WALLS of the wall each heading faces (headings spread < 45°)."""
    facing = np.array([w[3] for w in RECT_WALLS])
    diff = np.abs((head[:, None] - facing[None] + 180.0) % 360.0 - 180.0)
    return np.argmin(diff, axis=1), diff.min(axis=1)


@pytest.mark.parametrize("step", [0.0, 0.25])
def test_per_wall_rectangle_every_wall_scanned_at_its_distance(step):
    scene = make_scene([room(RECT)], per_wall(seed=3, distance_m=1.0, distance_step_m=step))
    geom = build_geometry(scene)
    p = scene.sensors.placement
    assert isinstance(p, PerWall)
    pos, head, groups, poses = place_per_wall(p, scene, geom)
    assert groups.dtype == np.int64 and len(pos) == len(head) == len(groups)
    assert np.all(in_free_space(scene, geom, pos))
    assert np.all(nearest_surface_point(geom, pos)[0] >= p.clearance_m)
    wall_of, off = _wall_of(head)
    np.testing.assert_allclose(off, 0.0, atol=1e-9)  # heading_spread_deg 0: facing the wall
    for k, (a, b, n, _) in enumerate(RECT_WALLS):
        mine = wall_of == k
        assert len(np.unique(groups[mine])) >= 1  # every wall has at least one array
        a, b, n = np.asarray(a, float), np.asarray(b, float), np.asarray(n, float)
        d = 1.0 + k * step
        rel = pos[mine] - a
        np.testing.assert_allclose(rel @ n, d, atol=1e-9)  # on the line at the LoS distance
        u = (b - a) / np.hypot(*(b - a))
        along = rel @ u
        assert np.all((along >= d - TOL) & (along <= np.hypot(*(b - a)) - d + TOL))  # margins
        # the axis points at the wall: the ray along it meets this wall at distance d
        axes = np.stack([np.cos(np.radians(head[mine])), np.sin(np.radians(head[mine]))], -1)
        np.testing.assert_allclose(ray_distance(geom, pos[mine], axes), d, atol=1e-9)
    # every array is its own group, numbered 0, 1, … over the room, never across walls
    assert groups[0] == 0 and np.all(np.diff(groups) >= 0) and np.all(np.diff(groups) <= 1)
    for g in np.unique(groups):
        assert len(np.unique(wall_of[groups == g])) == 1
        assert np.sum(groups == g) <= p.elements
    assert len(poses) == groups.max() + 1
    for g, centre in enumerate(poses):
        members = pos[groups == g]
        np.testing.assert_allclose(centre, 0.5 * (members[0] + members[-1]))


def test_per_wall_lines_are_random_lines():
    """Each wall's arrays are what random-lines places along that wall's line."""
    scene = make_scene([room(RECT)], per_wall(seed=8, distance_m=0.8, heading_spread_deg=30))
    geom = build_geometry(scene)
    p = scene.sensors.placement
    lines_ = per_wall_lines(p, scene, geom)
    assert [k for k, _ in lines_] == [0, 1, 2, 3]
    assert len({line.seed for _, line in lines_}) == 4
    pos, head, groups, _ = place_per_wall(p, scene, geom)
    first = 0
    for k, line in lines_:
        assert line.facing_deg % 360.0 == pytest.approx(RECT_WALLS[k][3] % 360.0)
        assert line.length_m == pytest.approx(np.hypot(*np.subtract(*RECT_WALLS[k][:2])) - 1.6)
        wp, wh, wg, _ = place_random_lines(line, scene, geom)
        sl = slice(first, first + len(wp))
        np.testing.assert_array_equal(pos[sl], wp)
        np.testing.assert_array_equal(head[sl], wh)
        np.testing.assert_array_equal(groups[sl], wg + groups[first])
        _check_random_lines(line, wp, wh, wg)
        first += len(wp)
    assert first == len(pos)


def test_per_wall_deterministic_for_a_seed():
    a, b, c = (place(make_scene([room(RECT)], per_wall(seed=s, heading_spread_deg=20)))
               for s in (5, 5, 6))
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.headings_deg, b.headings_deg)
    np.testing.assert_array_equal(a.groups, b.groups)
    np.testing.assert_array_equal(a.poses, b.poses)
    assert not np.array_equal(a.headings_deg, c.headings_deg)


def test_per_wall_skips_walls_too_short_or_outside_the_room():
    # L room: walls 1 and 4 are 3 m long, less 2·1.5 m of margin: no line there
    scene = make_scene([room(L_ROOM)], per_wall(seed=1, distance_m=1.5))
    geom = build_geometry(scene)
    assert [k for k, _ in per_wall_lines(scene.sensors.placement, scene, geom)] == [0, 2, 3, 5]
    s = place_sensors(scene, geom)
    assert np.all(in_free_space(scene, geom, s.positions))
    assert len(np.unique(np.round(s.headings_deg % 360.0, 6))) == 4
    # LoS distance growing 8 m per wall: the lines of walls 1–3 lie outside the room
    scene = make_scene([room(RECT)], per_wall(seed=1, distance_m=1.0, distance_step_m=8.0,
                                              margin_m=0.2))
    geom = build_geometry(scene)
    assert len(per_wall_lines(scene.sensors.placement, scene, geom)) == 4
    s = place_sensors(scene, geom)
    np.testing.assert_allclose(s.positions[:, 1], 2.0)
    np.testing.assert_allclose(s.headings_deg, -90.0)


def test_per_wall_after_explicit_transducers_and_in_pairs():
    explicit = [{"position": [5.0, 3.0], "heading_deg": 0.0, "group": 2}]
    s = place(make_scene([room(RECT)], per_wall(seed=2), explicit))
    assert s.groups[0] == 2 and s.groups[1] == 3
    assert len(s.poses) == s.groups.max() - 2
    sizes = np.bincount(s.groups)
    assert len(pairs(s)) == int(np.sum(sizes**2))


@pytest.mark.parametrize("surfaces, kw, key, message", [
    ([room(RECT)], {"distance_m": 4.5}, "sensors.placement", "placed no transducer"),
    ([room(RECT)], {"distance_m": 1.0, "margin_m": 4.0}, "sensors.placement",
     "placed no transducer"),
    ([room(RECT)], {"distance_m": 1.0, "clearance_m": 2.0}, "sensors.placement",
     "placed no transducer"),
])
def test_per_wall_that_places_nothing_raises(surfaces, kw, key, message):
    scene = make_scene(surfaces, per_wall(**kw))
    with pytest.raises(SceneError, match=message) as e:
        place(scene)
    assert e.value.key == key and e.value.source == "test"


@pytest.mark.parametrize("surfaces, index, message", [
    ([room(RECT)], 1, "no surfaces[1]"),
    (PLANE, 0, "open polyline"),
    ([circle((5, 5), 1)], 0, "a circle"),
])
def test_per_wall_needs_a_closed_polyline(surfaces, index, message):
    with pytest.raises(SceneError, match=re.escape(message)) as e:
        make_scene(surfaces, per_wall(surface=index))
    assert e.value.key == "sensors.placement.surface"
    # and a Scene built without the reader fails the same way when placed
    scene = make_scene(surfaces)
    scene = dataclasses.replace(scene, sensors=dataclasses.replace(
        scene.sensors, placement=PerWall(surface=index)))
    with pytest.raises(SceneError, match=re.escape(message)) as e:
        place(scene)
    assert e.value.key == "sensors.placement.surface"


def test_per_wall_room_maps_end_to_end():
    """Thesis §3.6, Fig 3.21: a per-wall scanned room gives detections and a map."""
    import clsonar

    scene = scene_from_dict({
        "clsonar": 1, "name": "per-wall", "extent": [0.0, 0.0, 4.0, 3.0], "cell": 0.02,
        "transducer": {"directivity": "uniform"}, "echo": {"curvature_gain": False},
        "surfaces": [room([(0.2, 0.2), (3.8, 0.2), (3.8, 2.8), (0.2, 2.8)])],
        "sensors": {"placement": per_wall(seed=1, distance_m=0.8, margin_m=0.3)},
    })
    result = clsonar.run(scene)
    assert result.counts["detections"] > 0
    assert result.counts["thin_cells"] > 0
    assert len(np.unique(np.round(result.sensors.headings_deg % 360.0, 6))) == 4


# --------------------------------------------------------------------------- place_sensors, pairs


def test_place_sensors_explicit_first_then_placed_groups():
    explicit = [{"position": [1.0, 1.0], "heading_deg": 0.0, "group": 0},
                {"position": [1.0, 2.0], "heading_deg": 0.0, "group": 3}]
    scene = make_scene([room(RECT)], {"type": "circular", "center": [5.0, 3.0]}, explicit)
    s = place(scene)
    assert len(s) == 10
    np.testing.assert_array_equal(s.groups, [0, 3] + [4] * 8)
    np.testing.assert_allclose(s.positions[:2], [[1, 1], [1, 2]])
    np.testing.assert_allclose(s.poses, [[5.0, 3.0]])
    np.testing.assert_allclose(np.hypot(*s.axes.T), 1.0)


def test_place_sensors_without_placement():
    scene = make_scene(PLANE, None, [{"position": [1.0, 1.0], "heading_deg": 30.0}])
    s = place(scene)
    assert len(s) == 1 and s.poses.shape == (0, 2)


def test_pairs_n_squared_per_group_including_t_equals_r():
    groups = np.array([0, 0, 0, 1, 1, 2, 0], dtype=np.int64)
    s = SensorArray(np.zeros((7, 2)), np.zeros(7), groups, np.zeros((0, 2)))
    pr = pairs(s)
    assert len(pr) == 4 * 4 + 2 * 2 + 1
    assert np.all(groups[pr[:, 0]] == groups[pr[:, 1]])
    assert {(i, i) for i in range(7)} <= set(map(tuple, pr.tolist()))
    assert len(set(map(tuple, pr.tolist()))) == len(pr)
    assert np.all(np.diff(pr[:, 0] * 7 + pr[:, 1]) > 0)  # sorted by tx, then rx
    empty = SensorArray(np.zeros((0, 2)), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, 2)))
    assert pairs(empty).shape == (0, 2)


def test_pairs_of_a_placement():
    scene = make_scene(PLANE, lines(seed=1, start=[7.0, 0.1], length_m=9.8))
    s = place(scene)
    sizes = np.bincount(s.groups)
    assert len(pairs(s)) == int(np.sum(sizes**2))


def _turned(points, deg):
    a = math.radians(deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return [list(rot @ (np.asarray(p, float) - 5.0) + 5.0) for p in points]


@pytest.mark.parametrize("deg", [0.0, 7.0, -20.0, 33.0])
def test_wall_following_ring_is_turned_square_to_the_walls(deg):
    """start_deg left out: a room turned by θ gets rings turned by θ modulo 45°, a box turned
    otherwise inside it does not move that; the thesis' axis-aligned room keeps 0."""
    box = {"type": "polyline", "closed": True,
           "points": _turned([[5.0, 4.0], [5.6, 4.1], [5.5, 4.7], [4.9, 4.6]], deg)}
    small = [(2, 2), (8, 2), (8, 6), (2, 6)]  # stays inside the extent turned
    scene, geom, p, result = _wall_following([room(_turned(small, deg)), box],
                                              start=_turned([[3.0, 3.0]], deg)[0])
    expected = (deg + 22.5) % 45.0 - 22.5
    assert square_to_walls(geom, 8) == pytest.approx(expected, abs=1e-6)
    heads = result[1].reshape(-1, 8)
    np.testing.assert_allclose((heads[:, 0] - expected + 180) % 360 - 180, 0.0, atol=1e-6)
    explicit = dataclasses.replace(p, start_deg=5.0)
    assert place_wall_following(explicit, scene, geom)[1][0] == 5.0


@pytest.mark.parametrize("outline", [
    [(1, 1), (9, 1), (7, 6), (2, 6)],  # a trapezoid: walls at 0°, ±68°
    [(5 + 3.5 * math.cos(math.radians(60 * k)), 5 + 3.5 * math.sin(math.radians(60 * k)))
     for k in range(6)],  # a hexagon: walls every 60°
    [(1, 1), (9, 1), (4, 8)],  # a triangle
])
def test_wall_following_rings_turn_square_to_each_wall_where_walls_share_no_heading(outline):
    """start_deg left out in a room whose walls no one heading faces (modulo 45°): each
    pose turns square to its nearest wall — one element faces that wall along its normal —
    and the poses whose nearest wall is square to the main heading keep it to the bit; the
    survey leaves start_deg unset and says why."""
    from clsonar.sensors import pose_headings, walls_share_heading
    from clsonar.survey import choose_settings, survey

    scene, geom, _, (_, head, _, poses) = _wall_following(
        [room(outline)], start=list(np.mean(outline, axis=0)))
    assert not walls_share_heading(geom, 8)
    heads = head.reshape(-1, 8)
    assert len(np.unique(np.round(heads[:, 0], 6))) > 1
    walls = geom.walls
    for centre, ring_heads in zip(poses, heads, strict=True):
        d = [_segment_distance(centre, w) for w in walls]
        k = int(np.argmin(d))
        a, b = walls[k, :2], walls[k, 2:]
        foot = a + np.clip((centre - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1) * (b - a)
        n = np.array([(b - a)[1], -(b - a)[0]])
        n = n if n @ (a - centre) >= 0 else -n
        square = math.degrees(math.atan2(n[1], n[0]))
        off = np.abs((ring_heads - square + 180.0) % 360.0 - 180.0).min()
        assert off < 1e-5 or np.hypot(*(foot - a)) < 1e-9 or np.hypot(*(foot - b)) < 1e-9
    main = square_to_walls(geom, 8)
    starts = pose_headings(geom, poses, 8)
    np.testing.assert_array_equal(starts, heads[:, 0])
    assert np.any(starts == main)
    chosen, why = choose_settings(scene, survey(scene, place_sensors(scene, geom)))
    assert chosen.sensors.placement.start_deg is None
    assert why["sensors.placement.start_deg"] == "auto: square to each pose's nearest wall"


def _segment_distance(point, wall):
    a, b = np.asarray(wall[:2]), np.asarray(wall[2:])
    t = np.clip((point - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
    return float(np.hypot(*(point - a - t * (b - a))))


def test_wall_following_traces_run_together_are_each_one_alone():
    """Issue 16: the rooms of a floor traced side by side (``wall_following_paths``) give
    each room's path to the bit, and a trace that fails fails alone, with its own error."""
    from clsonar.geometry import SurfaceSets, nearest_points
    from clsonar.sensors import place_sensors_together, wall_following_paths

    rooms = [([room(RECT)], [3.0, 3.0], "ccw"), ([room(L_ROOM)], [2.0, 7.0], "cw"),
             ([room(RECT), circle((5.0, 3.5), 0.5)], [2.0, 2.0], "ccw"),
             ([room(RECT)], [5.0, 3.5], "ccw")]  # clearance 3 m fits nowhere in a 5 m room
    jobs, scenes = [], []
    for k, (surfaces, start, direction) in enumerate(rooms):
        placement = {"type": "wall-following", "start": start, "direction": direction}
        if k == 3:
            placement["clearance_m"] = 3.0
        scene = make_scene(surfaces, placement)
        scenes.append(scene)
        jobs.append((scene.sensors.placement, scene, build_geometry(scene)))
    together = wall_following_paths(jobs)
    for (p, scene, geom), found in zip(jobs, together, strict=True):
        try:
            alone = wall_following_path(p, scene, geom)
        except SceneError as error:
            assert isinstance(found, SceneError) and str(found) == str(error)
            continue
        assert not isinstance(found, SceneError)
        for a, b in zip(alone, found, strict=True):
            assert np.array_equal(a, b)
    assert isinstance(together[3], SceneError)
    placed = place_sensors_together(scenes[:3], [j[2] for j in jobs[:3]])
    for scene, sensors in zip(scenes[:3], placed, strict=True):
        assert not isinstance(sensors, SceneError)
        assert np.array_equal(sensors.positions, place_sensors(scene).positions)
    # the padded surfaces measure each scene's points as its own geometry does
    geoms = [j[2] for j in jobs]
    pts = np.random.default_rng(3).uniform(0, 10, (len(geoms), 50, 2))
    dist, near = nearest_points(SurfaceSets.of(geoms), pts)
    for k, geom in enumerate(geoms):
        d, q = nearest_surface_point(geom, pts[k])
        assert np.array_equal(dist[k], d) and np.array_equal(near[k], q)


def test_nearest_walls_block_by_block_is_all_at_once(monkeypatch):
    """The nearest wall of each pose, a block of poses at a time (bounded memory), is the
    one all the distances at once give, and the nearest by brute force."""
    from clsonar.sensors import headings

    rng = np.random.default_rng(5)
    walls, points = rng.uniform(0, 10, (37, 4)), rng.uniform(0, 10, (501, 2))
    whole = headings.nearest_walls(walls, points)
    monkeypatch.setattr(headings, "NEAREST_AT_ONCE", 100)  # blocks of two poses
    blocks = headings.nearest_walls(walls, points)
    np.testing.assert_array_equal(blocks, whole)
    brute = [int(np.argmin([_segment_distance(p, w) for w in walls])) for p in points]
    np.testing.assert_array_equal(blocks, brute)
