"""Metrics: thesis eq. 2.6 along a wall, accuracy, completeness, spurious share."""

import dataclasses
import math

import numpy as np
import pytest

from clsonar import physics
from clsonar.echoes import reference_echoes
from clsonar.geometry import build_geometry
from clsonar.metrics import (
    LOCUS_TOL_M,
    detectable_amplitude,
    evaluate,
    insonified,
    rms_along_wall,
    strongest_echo,
    truth_points,
)
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


def _setup(scene):
    geom = build_geometry(scene)
    sensors = place_sensors(scene, geom)
    return geom, sensors, reference_echoes(scene, sensors)


def test_insonified_is_where_the_echo_loci_meet_the_wall():
    scene = _scene(WALL)  # one transducer 2 m from the wall, facing it
    geom, sensors, echoes = _setup(scene)
    assert len(echoes) == 1
    truth = truth_points(scene, geom, 0.005)
    lit = truth[insonified(scene, sensors, echoes, truth)]
    # |q − T| ≤ 2 m + 1 cm on the wall: |y − 5| ≤ sqrt(2.01² − 2²) ≈ 0.20 m
    half = math.sqrt(2.01**2 - 2.0**2)
    assert lit[:, 1].min() == pytest.approx(5 - half, abs=0.006)
    assert lit[:, 1].max() == pytest.approx(5 + half, abs=0.006)
    quiet = _scene(WALL, transducers=((7.0, 5.0, 20.0),))  # faces away from the normal
    assert not insonified(quiet, *_setup(quiet)[1:], truth).any()


def _insonified_by_definition(scene, sensors, echoes, points, floor):
    """insonified's docstring, echo by echo and point by point: an echo at least ``floor``
    strong, on its locus within 2·LOCUS_TOL_M and inside both beams (in front, sin² of the
    angle at most the cut), and an edge's diffraction within 2·LOCUS_TOL_M of its vertex."""
    t, c = scene.transducer, scene.medium.c
    cut = physics.beam_cut_sin2(t.frequency_hz, t.radius_m, t.half_beam_deg, c)
    lit = np.zeros(len(points), dtype=bool)
    for tx, rx, tof, amp, kind, vertex in zip(echoes.tx, echoes.rx, echoes.tof_s,
                                              echoes.amplitude, echoes.kind_names(),
                                              echoes.point, strict=True):
        if amp < floor:
            continue
        dist = {}
        inside = np.ones(len(points), dtype=bool)
        for s in (tx, rx):
            d = points - sensors.positions[s]
            axis = sensors.axes[s]
            dist[s] = np.hypot(d[:, 0], d[:, 1])
            cross = axis[0] * d[:, 1] - axis[1] * d[:, 0]
            along = axis[0] * d[:, 0] + axis[1] * d[:, 1]
            inside &= (along > 0) & (cross * cross <= cut * dist[s] * dist[s])
        if kind == "edge":  # a diffraction speaks of its vertex alone
            inside &= np.hypot(*(points - vertex).T) <= 2 * LOCUS_TOL_M
        lit |= inside & (np.abs(dist[tx] + dist[rx] - tof * c) <= 2 * LOCUS_TOL_M)
    return lit


@pytest.mark.parametrize("half_beam", [12.0, 60.0])
def test_insonified_is_its_definition_in_a_room(half_beam):
    """A box room with transducers facing every way (T = R and T ≠ R echoes, walls and
    corners): the sensor-by-sensor slices and the all-echoes join find exactly the points
    the definition does, for a narrow beam and a wide one."""
    room = Polyline(((1.0, 1.0), (8.0, 1.0), (8.0, 6.0), (1.0, 6.0)), closed=True)
    heads = [(3.0, 3.0, 0.0), (3.0, 3.0, 135.0), (5.0, 4.0, -90.0), (6.0, 2.0, 30.0),
             (2.0, 5.0, 200.0), (7.0, 5.0, 45.0)]
    scene = _scene(room, transducers=heads)
    scene = dataclasses.replace(scene, transducer=dataclasses.replace(
        scene.transducer, half_beam_deg=half_beam, directivity="uniform"))
    geom, sensors, echoes = _setup(scene)
    assert np.any(echoes.tx != echoes.rx)
    truth = truth_points(scene, geom, 0.005)
    # transducers in a closed room: the detection's floor is chosen at 1 unit
    assert detectable_amplitude(scene, sensors) == 1.0
    want = _insonified_by_definition(scene, sensors, echoes, truth, 1.0)
    assert want.any()
    np.testing.assert_array_equal(insonified(scene, sensors, echoes, truth), want)
    strong = _insonified_by_definition(scene, sensors, echoes, truth, 4.2)
    assert np.any(want & ~strong)
    np.testing.assert_array_equal(insonified(scene, sensors, echoes, truth, 4.2), strong)
    best = strongest_echo(scene, sensors, echoes, truth)
    np.testing.assert_array_equal(best >= 1.0, want)
    np.testing.assert_array_equal(best >= 4.2, strong)


def test_evaluate_accuracy_completeness_spurious():
    scene = _scene(WALL)
    geom, sensors, echoes = _setup(scene)
    y = np.arange(4.7, 5.3, 0.005)
    good = np.stack([np.full_like(y, 9.005), y], -1)
    junk = np.array([[5.0, 5.0], [6.0, 5.0]])
    m = evaluate(scene, geom, sensors, echoes, np.concatenate([good, junk]))
    assert m["completeness"]["1cm"] == pytest.approx(1.0)
    assert m["accuracy_m"]["p95"] == pytest.approx(0.005, abs=1e-9)
    assert m["spurious_share"] == pytest.approx(2 / (len(y) + 2))
    assert m["insonified_m"] == pytest.approx(2 * math.sqrt(2.01**2 - 4), rel=0.05)
    assert m["coverage"] == pytest.approx(m["insonified_m"] / 10.0, rel=0.01)
    empty = evaluate(scene, geom, sensors, echoes, np.zeros((0, 2)))
    assert empty["completeness"]["5cm"] == 0.0 and empty["accuracy_m"]["rms"] is None


def test_detectable_amplitude_is_the_detections_threshold_and_at_least_a_tenth():
    """An echo insonifies only where the run's detection could detect it (issue 18: a
    vertex lit only by an echo under a room's floor of 1 unit is not one to find)."""
    scene = _scene(WALL)  # open scene: the floor is 0.01, so a tenth of A0 (0.5) rules
    sensors = _setup(scene)[1]
    assert detectable_amplitude(scene, sensors) == pytest.approx(0.1 * scene.transducer.amplitude)
    noisy = dataclasses.replace(scene, signal=dataclasses.replace(scene.signal, noise_std=1.2))
    # 6 Rayleigh scales of the envelope's noise, 0.145·σn each (docs/detection.md)
    assert detectable_amplitude(noisy, sensors) == pytest.approx(6 * 0.145 * 1.2, rel=0.02)
    thesis = dataclasses.replace(scene, detection=dataclasses.replace(
        scene.detection, mode="threshold"))
    assert detectable_amplitude(thesis, sensors) == max(0.5, scene.signal.threshold)
    floor = dataclasses.replace(scene, detection=dataclasses.replace(
        scene.detection, min_envelope=2.0))
    assert detectable_amplitude(floor, sensors) == 2.0


def test_an_edges_diffraction_insonifies_its_vertex_not_the_faces_its_locus_crosses():
    """Issue 18: a transducer 1 m from a box corner, 0.3° into the shadow of a face's
    reflection boundary, hears only the edge's diffraction, about half a mirror's (the
    uniform theory). Its locus runs along the face for ±20 cm around the vertex; the face
    there says nothing (no specular point), so only the vertex is insonified."""
    from clsonar.tools import physics_check as pc

    t = pc._polar(1.0, 180.0 - 90.3)
    scene = pc._scene([{"type": "polyline", "points": [[-10.0, 0.0], [0.0, 0.0],
                                                       [0.0, -10.0]]}],
                      [(t, np.zeros(2))], open_floor=True)
    geom, sensors, echoes = _setup(scene)
    assert echoes.kind_names().tolist() == ["edge"] and echoes.amplitude[0] > 2.0
    truth = truth_points(scene, geom, 0.005)
    lit = truth[insonified(scene, sensors, echoes, truth)]
    assert len(lit) > 0 and np.hypot(*lit.T).max() <= 2 * LOCUS_TOL_M
    path = echoes.tof_s[0] * scene.medium.c
    on_locus = np.abs(2 * np.hypot(*(truth - t).T) - path) <= 2 * LOCUS_TOL_M
    assert np.hypot(*truth[on_locus].T).max() > 0.1  # what the locus alone would light
