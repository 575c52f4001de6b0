"""PNG pictures (plots.py): what each picture draws, and that it draws without vertices or
poses too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

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
