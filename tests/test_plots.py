"""PNG pictures (plots.py): what each picture draws, and that it draws without vertices or
poses too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsonar
from clsonar import plots
from clsonar.geometry import build_geometry, true_vertices
from clsonar.post import Profile
from clsonar.sensors import place_sensors

SCENES = Path(__file__).resolve().parents[1] / "scenes"
PNG = b"\x89PNG\r\n\x1a\n"


def _placed(name):
    scene = clsonar.load_scene(SCENES / f"{name}.json")
    geom = build_geometry(scene)
    return scene, geom, place_sensors(scene, geom)


def _axes():
    return plots.figure((6.4, 4.8), 100).add_subplot()


def test_true_vertices_are_the_corners_and_edges():
    _, geom, _ = _placed("room-obstacles")
    got = {tuple(v) for v in true_vertices(geom)}
    room = {(0.5, 0.5), (10.5, 0.5), (10.5, 8.5), (0.5, 8.5)}
    box = {(8.5, 5.5), (8.5, 7.0), (7.5, 7.0), (7.5, 5.5)}
    assert got == room | box  # not the box polyline's free ends at (8, 5.5), a flat side


@pytest.mark.parametrize(("name", "label", "joined"), [
    ("room-l", "ring poses", True), ("room-per-wall", "array centres", False)])
def test_poses_are_labelled_by_placement(name, label, joined):
    scene, _, sensors = _placed(name)
    ax = _axes()
    plots.draw_poses(ax, scene, sensors.poses)
    (line,) = ax.get_lines()
    assert line.get_label() == label
    assert (line.get_linestyle() != "None") == joined
    xy = line.get_xydata()
    if joined:  # the wall-following path is drawn closed
        assert len(xy) == len(sensors.poses) + 1 and np.array_equal(xy[0], xy[-1])
    else:
        assert len(xy) == len(sensors.poses)


def test_random_lines_have_no_poses_to_draw():
    scene, _, sensors = _placed("plane-2m")
    ax = _axes()
    plots.draw_poses(ax, scene, sensors.poses)
    assert not ax.get_lines()


def test_profile_png_with_and_without_vertices():
    scene, geom, sensors = _placed("room-l")
    thin = np.zeros(scene.grid_shape, dtype=bool)
    points = np.array([[0.5, 1.0], [0.5, 2.0], [0.5, 3.0]])
    for vertices in (np.zeros((0, 2)), np.array([[0.5, 0.5], [4.5, 3.5]])):
        png = plots.profile_png(scene, geom, thin, "t", Profile((points,), vertices), sensors)
        assert png[:8] == PNG
    scene, geom, sensors = _placed("plane-2m")  # no poses, no true vertices, no curves
    png = plots.profile_png(scene, geom, np.zeros(scene.grid_shape, dtype=bool), "t",
                            Profile(()), sensors)
    assert png[:8] == PNG


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 40), st.integers(1, 40), st.integers(1, 7), st.integers(0, 2**31))
def test_a_map_is_shown_by_the_maximum_of_each_block(ny, nx, size, seed):
    """plots.block_maximum against a loop over the blocks: each pixel shown is the maximum
    of its size × size cells (the last blocks cut at the map's edge)."""
    image = np.random.default_rng(seed).uniform(-1.0, 3.0, (ny, nx))
    shown = plots.block_maximum(image, size)
    want = np.array([[image[i:i + size, j:j + size].max() for j in range(0, nx, size)]
                     for i in range(0, ny, size)])
    np.testing.assert_array_equal(shown, want)


def test_a_one_cell_curve_stays_visible_on_a_large_map():
    """A 3000 × 2000-cell map is shown by 5 × 5 blocks (at most MAP_PIXELS a side): a
    one-cell line and a single voted cell are still drawn."""
    image = np.zeros((2000, 3000))
    image[1234, 100:2900] = 1.0
    image[7, 2999] = 1.0
    size = -(-3000 // plots.MAP_PIXELS)
    shown = plots.block_maximum(image, size)
    assert shown.shape == (400, 600) and size == 5
    assert shown[1234 // size, 100 // size:2900 // size].all() and shown[1, 599] == 1.0
    assert np.count_nonzero(shown) == 2900 // size - 100 // size + 1
