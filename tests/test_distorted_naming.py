"""A noise-free family whose best model leaves one echo in fifty outside its tolerance
(issue 14; clsonar/mapping/families.py outside_allowed): an echo an overlapping one
distorted is no evidence for a model of more parameters."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from clsonar.mapping.families import BASE_TOLERANCE_M, outside_allowed
from clsonar.opencl import get_context
from clsonar.pipeline import run
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


def test_noise_free_detections_allow_one_distorted_echo_in_fifty():
    """Noise-free tolerances (the base's alone): 2 % of a family may lie outside; with
    noise, 10 %."""
    clean = SimpleNamespace(tolerance=np.full(60, BASE_TOLERANCE_M))
    noisy = SimpleNamespace(tolerance=np.full(60, BASE_TOLERANCE_M + 1e-3))
    rows = np.arange(55)
    assert outside_allowed(clean, rows) == 0.02 * 55
    assert outside_allowed(noisy, rows) == 0.1 * 55


def test_an_edges_diffraction_with_one_distorted_echo_is_a_point():
    """The zoo's unseen seed 28 edge-04: an edge 7 m from an array, heard only by its
    diffraction (55 echoes), one of them 0.3 mm off the point that fits the rest to
    33 µm. Named a free curve, it was drawn 1.5–3.5 cm off the edge (1.73 cm RMS); as the
    point it is the vertex."""
    case = draw(28, "edge", 4)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"]
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.001
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.002
