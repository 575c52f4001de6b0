"""Corners that are not right-angled (issue 14): the double bounce in walls meeting at an
angle γ turns the receiver's image about the vertex by 2γ (image sources), so the corner
model's path is |T − V + Rot(−β)(R − V)| with β = π − 2γ (clsonar/mapping/models.py), and
an array maps such a corner to its vertex."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.mapping import models
from clsonar.opencl import get_context
from clsonar.pipeline import run
from clsonar.scene import scene_from_dict
from clsonar.tools.zoo.cases import draw
from clsonar.tools.zoo.score import score


def _mirror(x: np.ndarray, angle: float) -> np.ndarray:
    """``x`` [n, 2] reflected across the line through the origin at ``angle``."""
    c, s = math.cos(2 * angle), math.sin(2 * angle)
    return np.stack([c * x[:, 0] + s * x[:, 1], s * x[:, 0] - c * x[:, 1]], axis=-1)


@settings(max_examples=40, deadline=None)
@given(gamma=st.floats(min_value=math.radians(60), max_value=math.radians(120)),
       turn=st.floats(min_value=-math.pi, max_value=math.pi),
       seed=st.integers(min_value=0, max_value=2**16))
def test_the_corner_path_is_the_image_sources_double_bounce(gamma, turn, seed):
    """For walls through V at angles θa and θb = θa + γ, the path T → wall b → wall a → R
    is |T − R″| with R″ R's image in wall a, then in wall b (a turn by 2γ about V); the
    model with β = π − 2γ gives it where R lies clockwise of V seen from T, the other
    order elsewhere, and −β the other way round (a pair and its reciprocal hear one
    path); β = 0 is the right angle's |T + R − 2V|."""
    rng = np.random.default_rng(seed)
    V = rng.uniform(-3, 3, 2)
    T, R = V + rng.uniform(-5, 5, (6, 2)), V + rng.uniform(-5, 5, (6, 2))
    a, b = turn, turn + gamma
    ab = V + _mirror(_mirror(R - V, b), a)
    ba = V + _mirror(_mirror(R - V, a), b)
    beta = math.pi - 2 * gamma
    path, q = models.corner_paths(np.array([*V, beta]), T, R)
    other, _ = models.corner_paths(np.array([*V, -beta]), T, R)
    side = ((V - T)[:, 0] * (R - T)[:, 1] - (V - T)[:, 1] * (R - T)[:, 0]) <= 0
    first, second = np.hypot(*(T - ba).T), np.hypot(*(T - ab).T)
    assert np.allclose(path, np.where(side, first, second), atol=1e-9)
    assert np.allclose(other, np.where(side, second, first), atol=1e-9)
    assert np.allclose(q, V)
    right, _ = models.corner_paths(V, T, R)
    assert np.allclose(right, np.hypot(*(T + R - 2 * V).T), atol=1e-12)


def test_a_corner_of_86_degrees_is_its_vertex():
    """A corner of 86° 6 m from a 31-element array seen 30° off its bisector: the
    right-angled model misses its pairs' double bounces by centimetres (the image turns by
    172°, not 180°) and the echoes were drawn as stray patches; the turned corner is its
    vertex."""
    gamma = math.radians(86.0)
    V = np.array([10.0, 10.0])
    wall_a = V + 4 * np.array([math.cos(math.radians(225 - 43)), math.sin(math.radians(225 - 43))])
    wall_b = V + 4 * np.array([math.cos(math.radians(225 + 43)), math.sin(math.radians(225 + 43))])
    view = math.radians(225 + 30)
    centre = V + 6.0 * np.array([math.cos(view), math.sin(view)])
    heading = math.degrees(view) - 180
    along = np.array([-math.sin(math.radians(heading)), math.cos(math.radians(heading))])
    transducers = [{"position": list(centre + (k - 15) * 0.06 * along),
                    "heading_deg": heading, "group": 0} for k in range(31)]
    assert abs(math.degrees(gamma) - 86.0) < 1e-9
    scene = scene_from_dict({"clsonar": 1, "name": "corner86", "extent": [3, 3, 11, 11],
                             "cell": 0.01, "surfaces": [{"type": "polyline", "points": [
                                 wall_a.tolist(), V.tolist(), wall_b.tolist()]}],
                             "sensors": {"transducers": transducers}}, "corner86")
    m = run(scene, context=get_context(None)).metrics
    print(m["vertices"], m["accuracy_m"])
    assert m["vertices"][0]["error_m"] < 0.02
    assert m["accuracy_m"]["rms"] < 0.01


def test_a_pair_and_its_reciprocal_have_one_double_bounce():
    """Reciprocity: T → a → b → R is R → b → a → T backwards, one path, but the walls are
    met in the other order; the model turns by β or −β by the pair's side (R clockwise of
    V seen from T or not), so (T, R) and (R, T) get one path, and it is the image
    sources' of the walls meeting at 90° − β/2, in one order or the other. The unfolded
    images are where the legs point: |T − R*| = |R − T*| is the path, and 2V − R, 2V − T
    for a right angle."""
    rng = np.random.default_rng(3)
    V, beta = np.array([1.0, 5.0]), 0.17
    T, R = rng.uniform(-1, 1, (8, 2)), rng.uniform(-1, 1, (8, 2))
    one, _ = models.corner_paths(np.array([*V, beta]), T, R)
    back, _ = models.corner_paths(np.array([*V, beta]), R, T)
    assert np.allclose(back, one, atol=1e-12)
    gamma = (math.pi - beta) / 2
    ab = V + _mirror(_mirror(R - V, gamma), 0.0)
    ba = V + _mirror(_mirror(R - V, 0.0), gamma)
    orders = np.stack([np.hypot(*(T - ab).T), np.hypot(*(T - ba).T)])
    assert np.allclose(np.min(np.abs(orders - one), axis=0), 0.0, atol=1e-12)
    assert np.abs(orders[0] - orders[1]).min() > 1e-3  # the two orders differ
    r_star, t_star = models.corner_images(np.array([*V, beta]), T, R)
    assert np.allclose(np.hypot(*(T - r_star).T), one, atol=1e-12)
    assert np.allclose(np.hypot(*(R - t_star).T), one, atol=1e-12)
    r_star, t_star = models.corner_images(V, T, R)
    assert np.allclose(r_star, 2 * V - R) and np.allclose(t_star, 2 * V - T)


def test_an_85_degree_corner_heard_by_nine_echoes_is_its_vertex():
    """Zoo seed 4 corner-07 (random lines, 7 elements, 3.6 m from an 85° corner, 13
    echoes, noise-free): the right angle misses its double bounces by 6-27 mm, so no
    corner grew from it and the vertex was missed by 55 cm (12.7 cm with the families
    of stop 31). A turned corner started without the right angle
    (starts.turned_start), each pair in the order of the walls nearer its path
    (models.corner_turns), is the vertex."""
    from clsonar import pipeline
    from clsonar.opencl import get_context
    from clsonar.tools.zoo import zoo
    from clsonar.tools.zoo.score import score

    (case,) = [c for c in zoo(4, ("corner",)) if c.name == "corner-07-random-lines"]
    row = score(case, pipeline.run(case.scene, context=get_context(None)))
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.001
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.001


def test_an_off_square_corners_far_pairs_are_no_tangent_points():
    """The zoo's unseen seed 20 corner-06: an 88° corner 6.5 m from nine elements 8.2 cm
    apart. The right angle explains the close pairs' double bounces to a few µm, not three
    far pairs' (2 cm off, β·L/2 for β = 4°): left over, their tangent points were drawn
    across the corner's mouth (21 cm RMS). As double bounces a corner within 7.5° of
    square would give (reflectors.turned_about), they are the located corner's."""
    case = draw(20, "corner", 6)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"] and row["accuracy_m"] is not None and row["accuracy_m"] <= 0.005
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.01


def test_a_noisy_plane_through_a_located_corner_is_that_corner():
    """The zoo's unseen seed 19 corner-05 (σ 0.6): ten elements 2 cm apart 7.4 m from a
    corner cannot tell its double bounce from a plane's echo (L²/4r, 0.4 mm); their 51
    echoes made a plane drawn through the vertex (13.7 cm RMS). The corner another array
    located from 250 echoes predicts them at 0.79 mm RMS, within 1.5 times the plane's
    0.51 mm plus their noise, as families are named (owners.fits_as_well)."""
    case = draw(19, "corner", 5)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"] and row["accuracy_m"] is not None and row["accuracy_m"] <= 0.005


def test_a_corners_double_bounce_heard_only_by_pairs_farther_apart_than_a_stretch_is_mapped():
    """The zoo's unseen seed 22 corner-01: a 95° corner 7.1 m from 21 elements 8.3 cm
    apart. Off square by 5°, it returns each double bounce 10° askew, to an element about
    1.2 m from the transmitter: every pair that heard it is farther apart than an array's
    1 m stretch, no stretch held one, and the map was empty. Those pairs go to the search
    over all arrays, and their tangent points are drawn: the vertex located (it was
    missed); the mouth's tangent points are left (6.8 cm RMS)."""
    case = draw(22, "corner", 1)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["points"] > 0
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.01


def test_a_noisy_plane_through_a_corner_located_off_by_millimetres_is_that_corner():
    """The zoo's unseen seeds 105 corner-02 (σ 0.3) and 112 corner-05 (σ 0.6): one array
    located the corner from 10 (21) double bounces, 4–5 mm off with the noise; another,
    too small for its range to tell a corner from a plane, fitted 15 (36) of its echoes
    with a plane through the vertex, square to its line of sight, drawn 8.6 (6.0) cm RMS
    off the walls. The corner as located misses them by 2.4–4.7 mm, twice its error along
    their line of sight; refitted to both arrays' echoes it explains them and its own
    (owners.fits_as_well), though it holds fewer: no plane explains its own echoes."""
    for seed, index in ((105, 2), (112, 5)):
        case = draw(seed, "corner", index)
        row = score(case, run(case.scene, context=get_context(None)))
        assert row["passed"] and row["accuracy_m"] <= 0.005
        assert row["vertex_error_m"] <= 0.01


def test_a_corner_refitted_far_from_where_it_was_located_is_not_the_corner():
    """The zoo's unseen seed 130 edge-02 (σ 0.3): an edge 7.4 m from 16 elements 8.4 cm
    apart. Two stretches located it as a point from 54 and 25 diffractions, 1.5 and 2.7 cm
    off; the search over the detections left made a corner of 5 of them, 35 cm off.
    Refitted to the point's echoes, that corner moved 37 cm onto the point and explained
    both, so it claimed the point's echoes and stayed where it was: the edge was mapped
    35 cm off. A refit may move a corner by the pulse's resolution only
    (owners.fits_as_well); the corner's echoes are then the point's."""
    case = draw(130, "edge", 2)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"]
    assert row["vertex_error_m"] is not None and row["vertex_error_m"] <= 0.02
    assert row["accuracy_m"] is not None and row["accuracy_m"] <= 0.005


def test_an_exactly_fitted_corner_of_four_echoes_shadows_its_other_double_bounces():
    """The zoo's unseen seed 158 corner-03 (random lines, noise-free): an 87° corner whose
    family of 4 echoes fits to 29 µm, and 14 more of its double bounces, off the right
    angle's paths, drawn as tangent points along a line across its mouth: 3.2 cm RMS. A
    corner fitted as exactly as noise-free detections are shadows them as one of 10
    echoes does (reflectors.EXACT_CORNER_ROWS)."""
    case = draw(158, "corner", 3)
    row = score(case, run(case.scene, context=get_context(None)))
    assert row["passed"] and row["accuracy_m"] < 0.001
