"""How a zoo case's run is scored (issue 14 item 6), against :data:`THRESHOLDS`.

- **map**: the profile has points;
- **accuracy**: the RMS distance of the profile points to the true surfaces
  (:func:`clsonar.metrics.evaluate`'s ``accuracy_m.rms``);
- **completeness**: the share of the insonified true surface — the points of the scene that
  lie on the locus of an echo inside both beams that the run's detection could detect
  (:func:`clsonar.metrics.insonified`, :func:`clsonar.metrics.detectable_amplitude`), what a
  perfect map could recover — with a profile point within 3 cm (``completeness.3cm``);
- **vertex**: every true corner and edge in view (:func:`in_view`) to the nearest profile
  point or located vertex (Kleeman & Kuc 1995: a corner and an edge map to a point); the
  worst one. A vertex is in view when the echoes locate it: its own echo — a corner's
  double bounce, an edge's diffraction — is at least what the run's detection detects
  (:func:`clsonar.metrics.detection_level`) and a detection of its pair reports it
  (within the pulse's σ of its time of flight: an echo under a louder one's tail, which
  the detector never reported, locates nothing), or the insonified truth reaches within
  :data:`FACES_NEAR_M` of it on two faces (it is where their lines meet; nearer than
  :data:`FACES_FROM_M` a face's locus band also crosses the other face). A wall's free
  end that only its own face's echoes reach, or an edge whose diffraction stays under the
  detection's floor (a room's 1 unit, issue 18) without its second face heard, is not in
  view: a face's echo says where its reflection point is, not where the face ends;
- **seconds**: the run's stages summed (``report.json``'s ``seconds.total``).

A criterion is None (not scored) where it does not apply: completeness where nothing is
insonified, the vertex where no corner or edge is in view.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...echoes.table import KINDS
from ...geometry import true_vertices
from ...mapping.heard import Heard, loudest
from ...metrics import (
    LOCUS_TOL_M,
    detectable_amplitude,
    detection_level,
    insonified,
    lit_truth,
)
from ...neighbours import nearest
from ...outputs import metric
from ...pipeline import RunResult
from .cases import ZooCase
from .thresholds import THRESHOLDS

#: A vertex is in view by its faces when the insonified truth comes within this of it...
FACES_NEAR_M = 0.05

#: ... farther from it than this (a face's echo's locus band, ±LOCUS_TOL_M in range, also
#: crosses the other face within LOCUS_TOL_M of the corner: that is not the other face heard)...
FACES_FROM_M = 2 * LOCUS_TOL_M

#: ... in directions (seen from the vertex) at least this far apart: two faces, not one.
FACES_APART_RAD = math.radians(20.0)

#: The echoes that come from a vertex itself: a corner's double bounce, an edge's diffraction.
OWN_ECHOES = (KINDS.index("corner"), KINDS.index("edge"))


def _own_echoes(echoes, detections=None, resolution: float = 0.0):
    """The rows of ``echoes`` (an EchoTable) of the kinds :data:`OWN_ECHOES`; with
    ``detections``, only those a detection of their pair reports within ``resolution``
    of their path (metres; times of flight × c): an echo the detector never reported,
    under a louder one's tail, locates nothing."""
    keep = np.isin(np.asarray(echoes.kind), OWN_ECHOES)
    if detections is not None:
        keep &= _reported(echoes, detections, resolution)
    return dataclasses.replace(echoes, **{f.name: np.asarray(getattr(echoes, f.name))[keep]
                                          for f in dataclasses.fields(echoes)})


def _reported(echoes, detections, resolution: float) -> np.ndarray:
    """[n] bool: which ``echoes`` have a detection of their pair (the same transmitter
    and receiver) within ``resolution`` seconds of their time of flight: the mapping's
    search of a pair's detections (:func:`~clsonar.mapping.heard.loudest`), keyed by the
    ordered pair, on times of flight."""
    tx, rx = np.asarray(detections.tx, np.int64), np.asarray(detections.rx, np.int64)
    pairs = np.stack([np.asarray(echoes.tx, np.int64), np.asarray(echoes.rx, np.int64)], -1)
    base = int(max(tx.max(initial=0), rx.max(initial=0), pairs.max(initial=0))) + 1
    key = tx * base + rx
    order = np.argsort(key, kind="stable")
    heard = Heard(base, key[order], np.asarray(detections.tof_s)[order],
                  np.asarray(detections.amplitude)[order])
    return loudest(heard, pairs, np.asarray(echoes.tof_s, dtype=np.float64), resolution)[1]


def between_faces(vertices: np.ndarray, lit: np.ndarray) -> np.ndarray:
    """[V] bool: which ``vertices`` [V, 2] have insonified truth points ``lit`` [n, 2]
    between :data:`FACES_FROM_M` and :data:`FACES_NEAR_M` from them in directions at least
    :data:`FACES_APART_RAD` apart (the widest gap between their directions round the vertex
    leaves at least that much)."""
    out = np.zeros(len(vertices), dtype=bool)
    for i, v in enumerate(vertices):
        d = lit - v
        r2 = d[:, 0] ** 2 + d[:, 1] ** 2
        d = d[(r2 <= FACES_NEAR_M**2) & (r2 > FACES_FROM_M**2)]
        if len(d) >= 2:
            a = np.sort(np.arctan2(d[:, 1], d[:, 0]))
            widest = np.max(np.diff(np.r_[a, a[0] + 2 * math.pi]))
            out[i] = 2 * math.pi - widest >= FACES_APART_RAD
    return out


def in_view(result: RunResult) -> np.ndarray:
    """[V] bool: which true corners and edges (``geometry.true_vertices``) the echoes locate
    (module docstring, **vertex**)."""
    scene, sensors, echoes = result.scene, result.sensors, result.echoes
    truth = true_vertices(result.geometry)
    if len(truth) == 0:
        return np.zeros(0, dtype=bool)
    resolution = scene.transducer.pulse_sigma_s  # the pulse's σ: c·σ of path
    own = insonified(scene, sensors, _own_echoes(echoes, result.detections, resolution),
                     truth, detection_level(scene, sensors))
    points, strongest = lit_truth(scene, result.geometry, sensors, echoes)
    return own | between_faces(truth, points[strongest >= detectable_amplitude(scene, sensors)])


def vertex_error(result: RunResult) -> tuple[int, float | None]:
    """``(corners and edges in view, the largest distance from one of them to the nearest
    profile point or located vertex)``; the distance is None when the profile is empty."""
    truth = true_vertices(result.geometry)
    if len(truth) == 0:
        return 0, None
    seen = truth[in_view(result)]
    found = np.concatenate([result.profile.points.reshape(-1, 2),
                            np.asarray(result.profile.vertices, float).reshape(-1, 2)])
    if len(seen) == 0 or len(found) == 0:
        return len(seen), None
    return len(seen), float(np.max(nearest(found, seen)))


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
