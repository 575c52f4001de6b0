"""The scenes shipped in scenes/: they load, place transducers as in the thesis figures (or,
for the extra rooms, as the wall-following of §2.1.2 would), and survive load → save → load
unchanged."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import clsonar
from clsonar.geometry import EDGE, SOLID, build_geometry, nearest_surface_point, ray_distance
from clsonar.scene import Circle, PerWall, Polyline, RandomLines, WallFollowing
from clsonar.sensors import in_free_space, per_wall_lines, place_random_lines, place_sensors

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes").glob("*.json"))

#: Scene name → x of the random-lines array (thesis chapter 3: surface position − distance).
ARRAY_X = {
    "plane-2m": 7.0, "plane-4m": 5.0, "plane-8m": 1.0,
    "corner-4m": 6.0, "corner-7m": 3.0, "corner-9m": 1.0,
    "edge-1m": 5.5, "edge-3m": 3.5, "edge-5m": 1.5,
    "cylinder-2.1m": 5.4, "cylinder-3m": 4.5, "cylinder-4m": 3.5,
    "sinusoid-1m": 6.7, "sinusoid-4m": 3.7, "sinusoid-6m": 1.7,
}
WALL_FOLLOWING = {"room": 0.5, "room-step70": 0.7, "room-step75": 0.75, "room-cylinder": 0.5}
#: Scene name → LoS distance step of the per-wall scan (thesis §3.6: Fig 3.21, Fig 3.22).
PER_WALL = {"room-per-wall": 0.0, "room-per-wall-steps": 0.25}
THESIS = set(ARRAY_X) | set(WALL_FOLLOWING) | set(PER_WALL)
#: Rooms beyond the thesis' (wall-following, step 0.5 m) → length of the ring's closed path:
#: the walls, less 2·0.5 m at each concave corner, plus a quarter circle of radius 0.5 m round
#: each convex edge.
EXTRA_ROOMS = {
    "room-l": 28.0 - 5 * 1.0 + 1 * (np.pi / 2 * 0.5),  # 8 m × 6 m less a 4 m × 3 m notch
    "room-obstacles": 36.0 - 4 * 1.0,  # 10 m × 8 m; the obstacles are off the ring's path
}


def test_every_thesis_scene_is_bundled():
    names = {p.stem for p in SCENES}
    assert THESIS | set(EXTRA_ROOMS) <= names


def test_docs_list_every_bundled_scene():
    text = (ROOT / "docs" / "scenes.md").read_text(encoding="utf-8")
    for path in SCENES:
        assert f"`{path.name}`" in text


@pytest.fixture(scope="module")
def placed():
    """Each bundled scene with its geometry and placement, computed once."""
    out = {}
    for path in SCENES:
        scene = clsonar.load_scene(path)
        geom = build_geometry(scene)
        out[path.stem] = (scene, geom, place_sensors(scene, geom))
    return out


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_bundled_scene_loads_places_and_round_trips(path, tmp_path, placed):
    scene, geom, sensors = placed[path.stem]
    assert scene.name == path.stem
    assert scene.cell == 0.01
    if path.stem in THESIS:
        assert scene.extent == (0.0, 0.0, 10.0, 10.0)
    else:  # the extent fits the room with a margin of 0.5 m at least
        lo = geom.vertices.min(axis=0) - 0.5
        hi = geom.vertices.max(axis=0) + 0.5
        assert np.all(np.asarray(scene.extent[:2]) <= lo + 1e-9)
        assert np.all(np.asarray(scene.extent[2:]) >= hi - 1e-9)
    assert scene.transducer.half_beam_deg == 12.0 and scene.transducer.amplitude == 5.0
    assert scene.signal.noise_std == 0.0 and scene.signal.threshold == 4.0
    assert len(sensors) >= 1
    xmin, ymin, xmax, ymax = scene.extent
    assert np.all((sensors.positions >= [xmin, ymin]) & (sensors.positions <= [xmax, ymax]))
    assert np.all(in_free_space(scene, geom, sensors.positions))

    out = tmp_path / path.name
    clsonar.save_scene(scene, out)
    again = clsonar.load_scene(out)
    assert again == scene
    clsonar.save_scene(again, out)
    assert clsonar.load_scene(out) == scene
    # and the file as shipped is the same data as its normalised form, defaults aside
    shipped = json.loads(path.read_text(encoding="utf-8"))
    assert shipped["clsonar"] == 1 and shipped["name"] == path.stem


@pytest.mark.parametrize("name", sorted(ARRAY_X))
def test_random_lines_scenes_match_the_thesis(name, placed):
    scene, geom, sensors = placed[name]
    p = scene.sensors.placement
    assert isinstance(p, RandomLines)
    assert p.elements == 10 and p.facing_deg == 0.0 and p.heading_spread_deg == 90.0
    np.testing.assert_allclose(sensors.positions[:, 0], ARRAY_X[name])
    assert len(sensors) >= 40  # arrays over most of the 10 m, as in the figures
    assert np.all(nearest_surface_point(geom, sensors.positions)[0] >= p.clearance_m)
    assert np.all(np.abs(sensors.headings_deg) <= 90.0)  # facing the surface (+x)


def test_random_lines_seeds_are_distinct():
    seeds = [clsonar.load_scene(ROOT / "scenes" / f"{n}.json").sensors.placement.seed
             for n in ARRAY_X]
    assert len(set(seeds)) == len(seeds)


@pytest.mark.parametrize("name", sorted(WALL_FOLLOWING))
def test_wall_following_scenes_match_the_thesis(name, placed):
    scene, geom, sensors = placed[name]
    p = scene.sensors.placement
    assert isinstance(p, WallFollowing)
    assert p.step_m == WALL_FOLLOWING[name] and p.clearance_m == 0.5
    assert p.elements == 8 and p.radius_m == 0.065
    np.testing.assert_allclose(nearest_surface_point(geom, sensors.poses)[0], 0.5, atol=0.01)
    # the ring runs round the whole outline: 36 m of walls, less 2·0.5 m at each of the six
    # concave corners, plus a quarter circle of radius 0.5 m round each of the two edges
    perimeter = 36.0 - 6 * 1.0 + 2 * (np.pi / 2 * 0.5)
    assert len(sensors.poses) == int(np.ceil(perimeter / p.step_m - 0.05))
    assert len(sensors) == 8 * len(sensors.poses)


@pytest.mark.parametrize("name", sorted(PER_WALL))
def test_per_wall_scenes_match_the_thesis(name, placed):
    scene, geom, sensors = placed[name]
    room = clsonar.load_scene(ROOT / "scenes" / "room.json")
    assert scene.surfaces == room.surfaces and scene.echo == room.echo
    assert scene.mapping == room.mapping and scene.transducer == room.transducer
    p = scene.sensors.placement
    assert isinstance(p, PerWall)
    assert p.elements == 10 and p.distance_m == 1.0 and p.distance_step_m == PER_WALL[name]
    lines = per_wall_lines(p, scene, geom)
    assert [k for k, _ in lines] == list(range(8))  # every wall of the room is scanned
    first = 0
    for k, line in lines:
        pos = place_random_lines(line, scene, geom)[0]
        np.testing.assert_array_equal(sensors.positions[first:first + len(pos)], pos)
        axes = sensors.axes[first:first + len(pos)]
        # each transducer faces its wall, at that wall's LoS distance
        np.testing.assert_allclose(ray_distance(geom, pos, axes), 1.0 + k * PER_WALL[name],
                                   atol=1e-9)
        first += len(pos)
    assert first == len(sensors)
    assert len(sensors.poses) == sensors.groups.max() + 1


@pytest.mark.parametrize("name", sorted(EXTRA_ROOMS))
def test_extra_rooms_are_scanned_like_the_thesis_room(name, placed):
    scene, geom, sensors = placed[name]
    room = clsonar.load_scene(ROOT / "scenes" / "room.json")
    for section in ("transducer", "signal", "echo", "mapping", "post", "medium"):
        assert getattr(scene, section) == getattr(room, section), section
    p = scene.sensors.placement
    assert isinstance(p, WallFollowing)
    assert (p.step_m, p.clearance_m, p.elements, p.radius_m) == (0.5, 0.5, 8, 0.065)
    np.testing.assert_allclose(nearest_surface_point(geom, sensors.poses)[0], 0.5, atol=0.01)
    assert len(sensors.poses) == int(np.ceil(EXTRA_ROOMS[name] / p.step_m - 0.05))
    assert len(sensors) == 8 * len(sensors.poses)


def test_room_l_has_one_convex_edge(placed):
    scene, geom, _ = placed["room-l"]
    (outline,) = scene.surfaces
    assert isinstance(outline, Polyline) and outline.closed and len(outline.points) == 6
    seen = np.where(geom.vertex_right == SOLID, geom.vertex_left, geom.vertex_right)
    assert np.count_nonzero(seen == EDGE) == 1


def test_room_obstacles_stand_clear_of_the_walls_and_the_ring(placed):
    scene, geom, sensors = placed["room-obstacles"]
    outline, cylinder, box = scene.surfaces
    assert isinstance(outline, Polyline) and outline.closed
    assert isinstance(cylinder, Circle) and 0.5 <= cylinder.radius <= 0.8
    # the box is a thin wall run round and back to its start (mid-side, so no free end is a
    # corner): a closed polyline would be a second room, reflecting only inside
    assert isinstance(box, Polyline) and not box.closed and box.points[0] == box.points[-1]
    box_walls = geom.walls[geom.wall_surface == 2]
    corners = geom.vertices[(geom.vertex_left == EDGE) | (geom.vertex_right == EDGE)]
    assert len(corners) == 4  # the box's four corners are edges seen from outside
    room_walls = geom.walls[geom.wall_surface == 0]
    xmin, ymin = room_walls[:, :2].min(axis=0)
    xmax, ymax = room_walls[:, :2].max(axis=0)
    c, r = np.asarray(cylinder.center), cylinder.radius
    assert min(c[0] - xmin, xmax - c[0], c[1] - ymin, ymax - c[1]) - r >= 1.5
    b = box_walls[:, :2]
    assert min(b[:, 0].min() - xmin, xmax - b[:, 0].max(),
               b[:, 1].min() - ymin, ymax - b[:, 1].max()) >= 1.5
    nearest_box = np.clip(c, b.min(axis=0), b.max(axis=0))
    assert np.hypot(*(c - nearest_box)) - r >= 1.5
    # the ring runs round the room only: every pose is 1 m or more from both obstacles
    d_cyl = np.hypot(*(sensors.poses - c).T) - r
    d_box = np.hypot(*(sensors.poses - np.clip(sensors.poses, b.min(axis=0),
                                               b.max(axis=0))).T)
    assert d_cyl.min() >= 1.0 and d_box.min() >= 1.0
