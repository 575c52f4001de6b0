"""Where a face ends at a convex edge (issue 18): the face's last echoes and its edge's
diffraction arrive together, and with the uniform theory's diffraction (half a mirror's
echo on the reflection boundary) the mapping must still end the face at its edge."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from clsonar.mapping.joins import meet
from clsonar.mapping.patches import Patch, amplitude_noise, carrier_points, coordinates
from clsonar.scene import DetectionSettings, Scene, Signal


def _patch(params: tuple[float, float, float], u: np.ndarray, hi: float) -> Patch:
    """A patch of the curve model ``params`` about the origin with reflection points at
    coordinates ``u``, drawn from the first to ``hi``."""
    k = len(u)
    zeros = np.zeros((k, 2))
    return Patch(np.asarray(params, float), np.zeros(2), u, float(u.min()), hi,
                 np.arange(k), math.inf, np.zeros(k, np.int64), np.zeros(k, np.int64),
                 zeros, zeros, np.ones(k))


def test_a_located_edge_on_a_curved_patch_ends_it_where_it_ran_past():
    """A face's last stretch, its echoes shifted by the edge's diffraction arriving with
    them, may be fitted by a slightly bent circle that runs on past the edge: a located
    vertex on the circle beyond the reflection points cuts it there (as one on a plane's
    line does), but neither extends the circle to a vertex nor cuts inside its points,
    nor cuts a circle more bent than its range (a curved wall's own)."""
    params = (math.pi / 2, 0.0, -0.05)  # a circle of radius 20 m touching y = 0 at x = 0
    u = np.linspace(-0.02, -0.001, 8)
    curved = _patch(params, u, hi=0.02)
    vertex = carrier_points(curved.params, curved.x0, np.array([0.005]))
    (cut,), _ = meet([curved], vertex + np.array([0.0, 0.004]))  # 4 mm off the circle: on it
    assert cut.hi == pytest.approx(float(coordinates(cut.params, cut.x0, vertex)[0]),
                                   abs=1e-4)
    assert cut.lo == curved.lo
    (kept,), _ = meet([curved], carrier_points(curved.params, curved.x0,
                                               np.array([-0.01])))  # among its points
    assert kept.hi == curved.hi
    short = _patch(params, u, hi=float(u.max()))
    (same,), _ = meet([short], vertex)  # never extended along a circle
    assert same.hi == short.hi
    (far,), _ = meet([curved], vertex + np.array([0.0, 0.05]))  # 5 cm off: another reflector's
    assert far.hi == curved.hi
    # a curved wall's own circle (radius 0.5 m seen from 2 m) runs on past a located
    # crest: it is no face's slightly bent end
    wall = replace(_patch((math.pi / 2, 0.0, -2.0), u, hi=0.02), paths=np.full(8, 4.0))
    crest = carrier_points(wall.params, wall.x0, np.array([0.005]))
    (kept_on,), _ = meet([wall], crest)
    assert kept_on.hi == wall.hi


def test_a_detection_s_amplitude_noise_is_the_envelope_s():
    """The amplitude a plane's echo must reach is a mirror's share less three σ of the
    detection's amplitude: the envelope's noise (0.145·σn, docs/detection.md), not the
    signal's σn, which let an edge's diffraction (half a mirror's) pass for a face's
    echo at σn 0.3."""
    def scene(noise: float, mode: str = "envelope") -> Scene:
        return Scene(name="noise", extent=(0.0, 0.0, 1.0, 1.0), signal=Signal(noise_std=noise),
                     detection=DetectionSettings(mode=mode))

    assert amplitude_noise(scene(0.0)) == 0.0
    assert amplitude_noise(scene(1.0)) == pytest.approx(0.145, abs=0.005)
    assert amplitude_noise(scene(0.6)) == pytest.approx(0.6 * amplitude_noise(scene(1.0)))
    assert amplitude_noise(scene(0.6, "threshold")) == 0.6
