"""Metrics: thesis eq. 2.6 along a wall, accuracy, completeness, spurious share."""

import math

import numpy as np
import pytest

from clsonar.geometry import build_geometry
from clsonar.metrics import evaluate, insonified, rms_along_wall, truth_points
from clsonar.scene import Polyline, Scene, Sensors, Sinusoid, Transducer
from clsonar.sensors import place_sensors

WALL = Polyline(((9.0, 0.0), (9.0, 10.0)))


def _scene(*surfaces, transducers=((7.0, 5.0, 0.0),)):
    return Scene("m", (0.0, 0.0, 10.0, 10.0), surfaces=surfaces, sensors=Sensors(
        transducers=tuple(Transducer((x, y), h) for x, y, h in transducers)))


def test_rms_eq_2_6_plane_and_sinusoid():
    scene = _scene(WALL)
    y = np.linspace(4, 6, 201)
    assert rms_along_wall(scene, np.stack([np.full_like(y, 9.0), y], -1)) == 0.0
    assert rms_along_wall(scene, np.stack([np.full_like(y, 9.02), y], -1)) == pytest.approx(0.02)
    sin = Sinusoid((8.0, 0.0), (8.0, 10.0), 0.3, 5.0)
    x = 8.0 - 0.3 * np.sin(2 * math.pi * y / 5.0)  # left normal of +y is -x
    assert rms_along_wall(_scene(sin), np.stack([x, y], -1)) == pytest.approx(0.0, abs=1e-12)
    assert rms_along_wall(_scene(WALL, sin), np.zeros((3, 2))) is None


def test_insonified_patch_is_the_beam_footprint():
    scene = _scene(WALL)
    geom = build_geometry(scene)
    truth = truth_points(scene, geom, 0.005)
    lit = truth[insonified(scene, geom, place_sensors(scene, geom), truth)]
    half = 2.0 * math.tan(math.radians(12.0))
    assert lit[:, 1].min() == pytest.approx(5 - half, abs=0.01)
    assert lit[:, 1].max() == pytest.approx(5 + half, abs=0.01)


def test_evaluate_accuracy_completeness_spurious():
    scene = _scene(WALL)
    geom = build_geometry(scene)
    sensors = place_sensors(scene, geom)
    y = np.arange(4.5, 5.5, 0.005)
    good = np.stack([np.full_like(y, 9.005), y], -1)
    junk = np.array([[5.0, 5.0], [6.0, 5.0]])
    m = evaluate(scene, geom, sensors, np.concatenate([good, junk]))
    assert m["completeness"]["1cm"] == pytest.approx(1.0)
    assert m["accuracy_m"]["p95"] == pytest.approx(0.005, abs=1e-9)
    assert m["spurious_share"] == pytest.approx(2 / (len(y) + 2))
    assert m["insonified_m"] == pytest.approx(4 * math.tan(math.radians(12)), rel=0.02)
    empty = evaluate(scene, geom, sensors, np.zeros((0, 2)))
    assert empty["completeness"]["5cm"] == 0.0 and empty["accuracy_m"]["rms"] is None
