"""A located corner's double bounce, heard by pairs that cannot tell it from a plane's echo,
is the corner's (issue 14): Kleeman & Kuc's T ≠ R pairs tell a corner from a plane by about
L²/(4r) of path, so a short array far away, or an array's last stretch of weak, noisy
echoes, names the vertex's echoes a plane through it, square to its line of sight, which
was drawn as a straight patch across the corner (``reflectors.corners_own``,
``owners.a_corners_echoes``)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from clsonar import pipeline
from clsonar.mapping.families import Family, Window
from clsonar.mapping.models import corner_paths
from clsonar.mapping.owners import a_corners_echoes
from clsonar.opencl import get_context
from clsonar.tools.zoo import zoo
from clsonar.tools.zoo.score import score


@functools.cache
def _scored(seed: int, name: str) -> dict:
    (case,) = [c for c in zoo(seed, ("corner",)) if c.name == name]
    return score(case, pipeline.run(case.scene, context=get_context(None)))


@pytest.mark.parametrize(("seed", "name", "before"), [
    (3, "corner-02-arrays", 0.098),  # 110°: a long array at 2.5 m, 5 elements at 7.7 m
    (5, "corner-05-arrays", 0.073),  # the last stretch of a 7 m array's weak echoes
])
def test_a_corner_s_echoes_a_plane_fits_as_well_are_its_vertex(seed, name, before):
    """The zoo's scenes nobody tuned on, at σ 0.3: the plane through the vertex (accuracy
    ``before``, metres RMS) is gone, the vertex stays where it was (within 1 mm)."""
    row = _scored(seed, name)
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.002 < before
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.001


def _window(T: np.ndarray, R: np.ndarray, paths: np.ndarray) -> Window:
    n = len(paths)
    up = np.tile([0.0, 1.0], (n, 1))
    return Window(rows=np.arange(n), T=T, R=R, axT=up, axR=up, paths=paths,
                  amplitude=np.ones(n), tolerance=np.full(n, 2e-4), x0=T.mean(axis=0),
                  cut_sin2=np.sin(np.radians(30)) ** 2, neighbour_m=0.1)


def test_a_family_is_a_corner_s_only_where_the_corner_predicts_every_echo():
    """Five elements 0.05 m apart, 7 m below a corner at V: the corner's double bounces
    fit a plane through V (they differ by L²/(4r) ≤ 0.014 mm); a located corner of more
    rows predicts them all, so they are its echoes. Not with a path moved by 1 mm, nor
    from a corner of fewer rows, nor for a corner family itself."""
    V = np.array([0.3, 7.0])
    xs = np.arange(5) * 0.05
    T = np.array([[x, 0.0] for x in xs for _ in xs])
    R = np.array([[y, 0.0] for _ in xs for y in xs])
    paths, q = corner_paths(V, T, R)
    w = _window(T, R, paths)
    plane = Family("plane", np.array([np.pi / 2, 7.0, 0.0]), w.x0, np.arange(len(paths)), q,
                   1e-5, w)
    big = _window(np.repeat(T, 2, axis=0), np.repeat(R, 2, axis=0), np.repeat(paths, 2))
    corner = Family("corner", V, big.x0, np.arange(len(big.paths)),
                    np.broadcast_to(V, big.T.shape), 1e-6, big)
    assert a_corners_echoes(plane, corner)
    assert not a_corners_echoes(corner, corner)
    few = Family("corner", V, w.x0, np.arange(3), q[:3], 1e-6, w)
    assert not a_corners_echoes(plane, few)
    moved = paths.copy()
    moved[7] += 0.001
    off = Family("plane", plane.params, w.x0, plane.rows, q, 1e-5, _window(T, R, moved))
    assert not a_corners_echoes(off, corner)
