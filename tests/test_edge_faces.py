"""The faces of a convex edge seen by scattered linear arrays (issue 18, docs/reproduce's
edge rows): with the uniform theory's diffraction the face's last echoes arrive with the
edge's, and the faces must still be mapped as far as their echoes reach."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import clsonar
from clsonar.files import bundled_scenes
from clsonar.mapping.families import Window, find_families
from clsonar.mapping.joins import meet
from clsonar.mapping.models import plane_points
from clsonar.mapping.owners import widened
from clsonar.mapping.patches import Patch, coordinates
from clsonar.outputs import metric
from clsonar.tools.variants import at_distance, with_seed


def _wall_window(T: np.ndarray, phi: float, d: float) -> Window:
    """T = R echoes of the wall {n·p = d}, n = (cos φ, sin φ), each element facing it."""
    paths, q = plane_points(phi, d, T, T)
    axes = (q - T) / np.hypot(*(q - T).T)[:, None]
    m = len(T)
    return Window(rows=np.arange(m), T=T, R=T, axT=axes, axR=axes, paths=paths,
                  amplitude=np.full(m, 4.5), tolerance=np.full(m, 2e-4), x0=T.mean(axis=0),
                  cut_sin2=math.sin(math.radians(12)) ** 2, neighbour_m=math.inf,
                  mirror=4.5, ka=0.0, noise_std=0.0)


def test_a_plane_takes_other_elements_echoes_of_its_face():
    """A wall's family of four elements 10 cm apart takes two lone echoes of other
    elements, 1.0 and 1.6 m along the wall past its last, that its plane predicts; an
    echo 2 mm off the plane stays, and a point takes none."""
    phi, d = 0.0, 3.0  # the wall x = 3
    own = np.array([[0.0, 0.0], [0.0, 0.1], [0.0, 0.2], [0.0, 0.3]])
    (family,), _ = find_families(_wall_window(own, phi, d), 0.0185)
    assert family.kind == "plane" and len(family.rows) == 4
    lone = np.array([[0.0, 1.3], [0.5, 1.9], [0.0, 2.5]])
    w = _wall_window(lone, phi, d)
    w = dataclasses.replace(w, paths=w.paths + np.array([0.0, 0.0, 0.002]),
                            rows=np.array([10, 11, 12]))
    wide, taken = widened(family, w, np.arange(3))
    assert taken.tolist() == [0, 1]
    assert len(wide.rows) == 6
    assert wide.params[0] == pytest.approx(0.0, abs=1e-9)
    assert wide.params[1] == pytest.approx(3.0, abs=1e-9)
    u = coordinates(np.asarray(wide.params), wide.x0, wide.q)
    assert u.min() == pytest.approx(0.0, abs=1e-9) and u.max() == pytest.approx(1.9, abs=1e-9)
    # six echoes over 1.9 m of a straight wall bound its curvature (it was unknown)
    assert family.bend < 0.01 and wide.bend < family.bend
    assert widened(dataclasses.replace(family, kind="point"), w, np.arange(3))[1].size == 0


def test_a_widened_plane_takes_the_far_echoes_its_refit_predicts():
    """A family whose own short stretch left its plane 0.1 mrad off: the lone echo 0.6 m
    along the wall is 0.12 mm off that plane, inside its 0.2 mm tolerance, but those 2.5
    and 3.1 m along are 0.5 and 0.6 mm off. Widened by the near echo, the plane is
    refitted to the wall and takes the far ones too; with the near echo missing it takes
    none."""
    own = np.array([[0.0, 0.0], [0.0, 0.1], [0.0, 0.2], [0.0, 0.3]])
    (family,), _ = find_families(_wall_window(own, 0.0, 3.0), 0.0185)
    off = dataclasses.replace(family, params=np.array([1e-4, 3.0, 0.0]))
    lone = np.array([[0.0, 0.9], [0.0, 2.8], [0.0, 3.4]])
    w = dataclasses.replace(_wall_window(lone, 0.0, 3.0), rows=np.array([10, 11, 12]))
    wide, taken = widened(off, w, np.arange(3))
    assert taken.tolist() == [0, 1, 2] and len(wide.rows) == 7
    assert wide.params[0] == pytest.approx(0.0, abs=1e-6)  # the wall, to the fit's steps
    assert wide.params[1] == pytest.approx(3.0, abs=1e-6)
    assert widened(off, w, np.array([1, 2]))[1].size == 0


def test_a_patch_reaches_a_located_vertex_within_meet_m_of_its_drawn_end():
    """A face whose reflection points start 0.65 m from its located edge, drawn from
    0.47 m (its regions of constant depth), reaches the edge: within MEET_M (0.5 m) of
    its drawn end, though not of its reflection points; a vertex 1.01 m before the drawn
    end does not pull it."""
    u = np.array([0.65, 0.81, 0.89, 1.0])
    k = len(u)
    patch = Patch(np.array([0.0, 1.0, 0.0]), np.zeros(2), u, 0.47, 1.2, np.arange(k),
                  math.inf, np.zeros(k, np.int64), np.zeros(k, np.int64), np.zeros((k, 2)),
                  np.zeros((k, 2)), np.ones(k))
    (reached,), _ = meet([patch], np.array([[1.0, 0.0]]))
    assert reached.lo == pytest.approx(0.0, abs=1e-12)
    (kept,), _ = meet([patch], np.array([[1.0, -0.54]]))
    assert kept.lo == pytest.approx(0.47)


def _edge_runs(distance: float, seeds: tuple[int, ...]) -> list[float]:
    """docs/reproduce's edge experiment: scenes/edge-1m.json moved to ``distance``, seeds
    advanced by each of ``seeds``, preset best; each run's completeness within 2 cm."""
    base = at_distance(clsonar.load_scene(bundled_scenes() / "edge-1m.json"), 1.0, distance)
    return [metric(clsonar.run(with_seed(base, k), preset="best").metrics,
                   "completeness.2cm") for k in seeds]


def test_the_edge_s_faces_are_mapped_as_far_as_their_echoes_reach():
    """docs/reproduce's edge at 1 m, seeds 1, 2 and 4, were 48, 50 and 54 % complete
    within 2 cm: the faces drawn only around the families' own echoes, lone echoes of
    other arrays left, four echoes metres apart on one face a plane of unknown bend
    drawn in pieces."""
    one = _edge_runs(1.0, (1, 2, 4))
    assert min(one) >= 0.99, one
