"""How a zoo case's run is scored (issue 14 item 6), against :data:`THRESHOLDS`.

- **map**: the profile has points;
- **accuracy**: the RMS distance of the profile points to the true surfaces
  (:func:`clsonar.metrics.evaluate`'s ``accuracy_m.rms``);
- **completeness**: the share of the insonified true surface — the points of the scene that
  lie on the locus of an echo inside both beams that the run's detection could detect
  (:func:`clsonar.metrics.insonified`, :func:`clsonar.metrics.detectable_amplitude`), what a
  perfect map could recover — with a profile point within 3 cm (``completeness.3cm``);
- **vertex**: every true corner and edge in view (itself insonified: on the locus of an echo
  the detection could detect, as a corner's double bounce and an edge's diffraction are) to
  the nearest profile point or located vertex (Kleeman & Kuc 1995: a corner and an edge map
  to a point); the worst one. An edge whose diffraction stays under the detection's floor
  (a room's 1 unit) is not in view: no detection can come from it (issue 18);
- **seconds**: the run's stages summed (``report.json``'s ``seconds.total``).

A criterion is None (not scored) where it does not apply: completeness where nothing is
insonified, the vertex where no corner or edge is in view.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ...geometry import true_vertices
from ...metrics import insonified
from ...outputs import metric
from ...pipeline import RunResult
from .cases import ZooCase
from .thresholds import THRESHOLDS


def vertex_error(result: RunResult) -> tuple[int, float | None]:
    """``(corners and edges in view, the largest distance from one of them to the nearest
    profile point or located vertex)``; the distance is None when the profile is empty."""
    truth = true_vertices(result.geometry)
    if len(truth) == 0:
        return 0, None
    seen = truth[insonified(result.scene, result.sensors, result.echoes, truth)]
    found = np.concatenate([result.profile.points.reshape(-1, 2),
                            np.asarray(result.profile.vertices, float).reshape(-1, 2)])
    if len(seen) == 0 or len(found) == 0:
        return len(seen), None
    return len(seen), float(np.max(cKDTree(found).query(seen)[0]))


def judge(case: ZooCase, row: dict[str, Any]) -> dict[str, bool | None]:
    """Each of ``case.criteria`` against :data:`THRESHOLDS`: True (pass), False (fail) or
    None (does not apply to this run)."""
    t = THRESHOLDS[case.kind]
    out: dict[str, bool | None] = {}
    for c in case.criteria:
        if c == "map":
            out[c] = row["points"] > 0
        elif c == "accuracy":
            acc = row["accuracy_m"]
            out[c] = acc is not None and acc <= t.accuracy_for(case.noise)
        elif c == "completeness":
            share, least = row["completeness_3cm"], t.completeness_for(case.scan)
            out[c] = None if share is None or least is None else share >= least
        elif c == "vertex":
            worst = row["vertex_error_m"]
            out[c] = (None if row["vertices_in_view"] == 0 or t.vertex_m is None
                      else worst is not None and worst <= t.vertex_m)
    return out


def score(case: ZooCase, result: RunResult) -> dict[str, Any]:
    """The zoo's row of ``case`` run as ``result`` (module docstring): what it measured,
    ``pass`` per criterion and ``passed`` (no criterion failed)."""
    m = result.metrics
    in_view, worst = vertex_error(result)
    row: dict[str, Any] = {
        "name": case.name, "kind": case.kind, "scan": case.scan, "noise": case.noise,
        "tags": list(case.tags), "cells": case.cells,
        "transducers": int(result.counts.get("transducers", len(result.sensors))),
        "detections": int(result.counts.get("detections", len(result.detections))),
        "points": len(result.profile.points),
        "accuracy_m": metric(m, "accuracy_m.rms"),
        "completeness_3cm": metric(m, "completeness.3cm"),
        "vertices_in_view": in_view, "vertex_error_m": worst,
        "seconds": float(sum(result.seconds.values())),
    }
    row["pass"] = judge(case, row)
    row["passed"] = all(v is not False for v in row["pass"].values())
    return row
