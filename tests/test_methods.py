"""The arc-map methods of the literature (issue 15; docs/mapping.md): point marking, the
directional maximum, the occupancy grid and morphological processing, each on a case whose
answer is known by hand; the directional maximum's and the occupancy grid's kernels against
their NumPy float64 references on generated cases; every mode through the pipeline."""

from __future__ import annotations

import dataclasses
import functools
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsonar.mapping as mapping
from clsonar import pipeline, post
from clsonar.files import bundled_scenes
from clsonar.mapping.occupancy import P_EMPTY, P_OCCUPIED, log_odds
from clsonar.mapping.reference import pixel_view
from clsonar.opencl import get_context, has_fp64
from clsonar.scene import MappingSettings, PostSettings, Scene, TransducerModel, load_scene
from clsonar.sensors import SensorArray

EPS32 = float(np.finfo(np.float32).eps)
NEW_MODES = ("point-marking", "directional-maximum", "occupancy", "morphological",
             "arc-transversal-median", "triangulation")


@functools.cache
def context():
    return get_context()


def precisions() -> tuple[str, ...]:
    return ("float32", "float64") if has_fp64(context()) else ("float32",)


def scene_of(extent=(0.0, 0.0, 3.0, 2.0), cell=0.01, mode="loci", band_m=None,
             combine="sum") -> Scene:
    return Scene(name="methods-test", extent=extent, cell=cell, transducer=TransducerModel(),
                 mapping=MappingSettings(mode=mode, band_m=band_m, combine=combine))


def sensors_of(transducers, groups=None) -> SensorArray:
    """Transducers ``(x, y, heading_deg)``, in ``groups`` (default all in group 0)."""
    t = np.asarray(transducers, dtype=np.float64).reshape(-1, 3)
    g = np.zeros(len(t), np.int64) if groups is None else np.asarray(groups, np.int64)
    return SensorArray(t[:, :2].copy(), t[:, 2].copy(), g, np.zeros((0, 2)))


def loci_of(scene: Scene, rows) -> mapping.Loci:
    """Rows ``(tx, rx, path length c·τ in m)``, amplitude 1."""
    r = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
    return mapping.Loci(r[:, 0].astype(np.int64), r[:, 1].astype(np.int64),
                        r[:, 2] / scene.medium.c, np.ones(len(r)))


def votes_of(scene, sensors, loci) -> mapping.Votes:
    """The method ``scene.mapping.mode`` names, on ``loci`` as detections."""
    return mapping.map_votes(scene, sensors, None, loci, context=context())  # type: ignore[arg-type]


def cells_of(scene: Scene, points: np.ndarray) -> set[tuple[int, int]]:
    xmin, ymin = scene.extent[:2]
    return {(math.floor((y - ymin) / scene.cell), math.floor((x - xmin) / scene.cell))
            for x, y in points}


# --------------------------------------------------------------------------- point marking


def test_point_marking_puts_a_wall_seen_square_on_at_its_foot():
    """A transducer 2 m from a wall, facing it square on, and a pair 0.2 m apart facing it:
    the middle of each in-beam arc is the foot of the wall in front of the transducer (of
    the pair's midpoint), within a cell."""
    scene = scene_of(mode="point-marking")
    sensors = sensors_of([(0.5, 1.0, 0.0), (0.5, 0.9, 0.0), (0.5, 1.1, 0.0)])
    wall_x = 2.5
    pair_path = 2.0 * math.hypot(wall_x - 0.5, 0.1)
    loci = loci_of(scene, [(0, 0, 2.0 * (wall_x - 0.5)), (1, 2, pair_path)])
    votes = votes_of(scene, sensors, loci)
    assert votes.raw is None and votes.points is not None and votes.tx is not None
    assert votes.points.shape == (2, 2)
    assert np.all(np.hypot(votes.points[:, 0] - wall_x, votes.points[:, 1] - 1.0)
                  < scene.cell)
    assert votes.tx.tolist() == [0, 1] and votes.rx is not None and votes.rx.tolist() == [0, 2]
    # the point lies on its locus
    d = np.hypot(*(votes.points[1] - sensors.positions[1])) + np.hypot(
        *(votes.points[1] - sensors.positions[2]))
    assert d == pytest.approx(pair_path, abs=1e-4)


def test_point_marking_follows_a_turned_transducer_and_skips_loci_out_of_its_beams():
    """A transducer turned 30°: its point is on its axis at the range; a pair whose beams
    do not meet on the locus gives none."""
    scene = scene_of(mode="point-marking")
    sensors = sensors_of([(0.5, 0.5, 30.0), (0.5, 1.5, 90.0)])
    loci = loci_of(scene, [(0, 0, 2.0), (0, 1, 2.5)])
    points, source = mapping.arc_middles(scene, sensors, loci)
    want = np.array([0.5 + math.cos(math.radians(30.0)), 0.5 + math.sin(math.radians(30.0))])
    assert source.tolist() == [0]
    assert np.hypot(*(points[0] - want)) < 0.5 * scene.cell


# --------------------------------------------------------------------------- directional maximum


def crossing_arcs():
    """Two viewpoints (groups) whose monostatic arcs cross at Q, a cell centre, each
    transducer aimed at Q from 1.118 m."""
    q = np.array([1.505, 1.005])
    t0, t1 = q - (1.0, 0.5), q - (1.0, -0.5)
    aim = math.degrees(math.atan2(0.5, 1.0))
    sensors = sensors_of([(*t0, aim), (*t1, -aim)], groups=[0, 1])
    r = math.hypot(1.0, 0.5)
    return q, sensors, [(0, 0, 2 * r), (1, 1, 2 * r)]


@pytest.mark.parametrize("combine", ["sum", "viewpoints"])
def test_directional_maximum_keeps_where_two_arcs_cross(combine):
    q, sensors, rows = crossing_arcs()
    scene = scene_of(mode="directional-maximum", combine=combine)
    loci = loci_of(scene, rows)
    acc = mapping.accumulate(scene, sensors, loci, context=context())
    iq = (int(q[1] / scene.cell), int(q[0] / scene.cell))
    assert acc[iq] == 2.0 and acc.max() == 2.0 and np.count_nonzero(acc == 1.0) > 100
    votes = votes_of(scene, sensors, loci)
    assert votes.raw is None and votes.points is not None and votes.tx is not None
    kept = cells_of(scene, votes.points)
    assert iq in kept
    # only the cells both arcs cross, each kept by both arcs
    assert all(acc[c] == 2.0 for c in kept)
    assert len(votes.points) == 2 * len(kept) == 2 * np.count_nonzero(acc == 2.0)
    assert sorted(votes.tx.tolist()) == [0] * len(kept) + [1] * len(kept)
    assert np.all(np.hypot(*(votes.points - q).T) < 2.5 * scene.cell)


def test_directional_maximum_of_a_lone_arc_is_the_arc():
    """With nothing else on the map every cell of an arc is its maximum."""
    scene = scene_of()
    sensors = sensors_of([(0.5, 1.0, 0.0)])
    loci = loci_of(scene, [(0, 0, 3.0)])
    acc = mapping.accumulate(scene, sensors, loci, context=context())
    found = mapping.arc_maxima(scene, sensors, loci, acc, context=context())
    assert found.best.tolist() == [1.0]
    assert np.array_equal(found.cells, np.flatnonzero(acc.ravel()))


@st.composite
def arc_cases(draw):
    """A map 20–70 cells a side anywhere in ±100 m, 1–3 transducers aimed near points of
    it, 1–5 loci (T = R or not) through points near it, and an accumulated map of small
    integers (ties everywhere) or the loci's own map."""
    cell = draw(st.floats(0.005, 0.05))
    nx, ny = draw(st.integers(20, 70)), draw(st.integers(20, 70))
    x0, y0 = draw(st.floats(-100.0, 100.0)), draw(st.floats(-100.0, 100.0))
    w, h = nx * cell * 0.999, ny * cell * 0.999
    band = draw(st.one_of(st.none(), st.floats(0.5, 3.0).map(lambda f: f * cell)))
    scene = scene_of((x0, y0, x0 + w, y0 + h), cell, band_m=band)
    unit = st.floats(-0.3, 1.3)

    def point():
        return np.array([x0 + draw(unit) * w, y0 + draw(unit) * h])

    transducers = []
    for _ in range(draw(st.integers(1, 3))):
        p, aim = point(), point()
        heading = math.degrees(math.atan2(*(aim - p)[::-1])) + draw(st.floats(-15.0, 15.0))
        transducers.append((*p, heading))
    sensors = sensors_of(transducers)
    rows = []
    for _ in range(draw(st.integers(1, 5))):
        t = draw(st.integers(0, len(transducers) - 1))
        r = t if draw(st.booleans()) else draw(st.integers(0, len(transducers) - 1))
        q = point()
        path = sum(math.hypot(*(q - np.array(transducers[k][:2]))) for k in (t, r))
        rows.append((t, r, path + draw(st.floats(-2.0, 2.0)) * cell))
    loci = loci_of(scene, rows)
    seed = draw(st.integers(0, 2**31 - 1))
    acc = (np.random.default_rng(seed).integers(0, 4, scene.grid_shape).astype(np.float64)
           if draw(st.booleans()) else mapping.accumulate_reference(scene, sensors, loci))
    return scene, sensors, loci, acc


def near_edges(scene, sensors, loci, ulps: float = 16.0) -> np.ndarray:
    """[n, ny, nx]: pixels within ``ulps`` float32 roundings of a locus' band edge (or of
    the edge of its empty region, the same path) or of a beam's edge."""
    pb = mapping.prepare_loci(scene, sensors, loci)
    g = pb.grid
    scale = math.hypot(g.nx, g.ny) * g.cell + float(np.abs(pb.rows[:, :4]).max())
    tol = ulps * EPS32 * scale
    out = []
    with np.errstate(divide="ignore", invalid="ignore"):
        for row in pb.rows:
            v = pixel_view(pb, row)
            band = np.abs(np.abs(v["path"] - row[8]) - pb.half_band) <= tol * (1 + row[8])
            beam = ((np.abs(v["s_t"] ** 2 - pb.cut_sin2 * v["dd_t"]) <= tol * (1 + v["dd_t"]))
                    | (np.abs(v["s_r"] ** 2 - pb.cut_sin2 * v["dd_r"]) <= tol * (1 + v["dd_r"])))
            out.append(band | beam)
    return np.asarray(out)


@settings(max_examples=60, deadline=None)
@given(arc_cases())
def test_arc_maxima_kernels_match_the_reference(case):
    scene, sensors, loci, acc = case
    ref = mapping.arc_maxima_reference(scene, sensors, loci, acc)
    assert len(ref.best) == len(loci) and np.all(ref.best >= 0)
    # the reference by its definition: each kept cell is on its arc and holds its best
    assert np.all(acc.ravel()[ref.cells] == ref.best[ref.source])
    for precision in precisions():
        got = mapping.arc_maxima(scene, sensors, loci, acc, context=context(),
                                 precision=precision)
        if precision == "float64":
            for a, b in ((got.best, ref.best), (got.source, ref.source),
                         (got.cells, ref.cells)):
                assert np.array_equal(a, b)
            continue
        edges = near_edges(scene, sensors, loci)
        for i in range(len(loci)):  # float32 decides alike but near an edge
            if edges[i].any():
                continue
            assert got.best[i] == ref.best[i]
            assert np.array_equal(got.cells[got.source == i], ref.cells[ref.source == i])


# --------------------------------------------------------------------------- occupancy


def test_occupancy_marks_in_front_of_a_wall_empty_and_the_band_occupied():
    """A transducer 1 m from a wall, square on: inside its beam the cells nearer than the
    echo's band are empty (the log-odds of P_EMPTY), the band occupied (of P_OCCUPIED),
    the cells beyond the echo and outside the beam untouched."""
    scene = scene_of(mode="occupancy")
    sensors = sensors_of([(0.505, 1.005, 0.0)])
    loci = loci_of(scene, [(0, 0, 2.0)])
    odds = mapping.occupancy_grid(scene, sensors, loci, context=context())
    arc = mapping.accumulate(scene, sensors, loci, context=context()) > 0
    occ, emp = log_odds(P_OCCUPIED), log_odds(P_EMPTY)
    assert emp == pytest.approx(-occ)
    assert np.array_equal(odds > 0, arc)
    assert np.allclose(odds[arc], occ, rtol=1e-6)
    row = 100  # y = 1.005, the axis
    for x, want in ((0.7, emp), (1.0, emp), (1.45, emp), (1.505, occ), (1.6, 0.0), (2.5, 0.0)):
        assert odds[row, int(x / scene.cell)] == pytest.approx(want, rel=1e-6), x
    assert odds[150, 100] == 0.0  # 0.5 m off the axis at 0.5 m: outside the ±12° beam
    votes = votes_of(scene, sensors, loci)
    assert votes.tx is None and votes.points is not None
    assert cells_of(scene, votes.points) == set(zip(*np.nonzero(arc), strict=True))


def test_occupancy_adds_readings_and_a_pairs_later_echo_clears_nothing():
    """Readings add up in log-odds: a cell one reading sees occupied and another empty is
    even (not occupied); a pair's second echo, beyond its first, leaves the first's band
    occupied."""
    scene = scene_of(mode="occupancy")
    sensors = sensors_of([(0.505, 1.005, 0.0), (0.205, 1.005, 0.0)])
    occ = log_odds(P_OCCUPIED)
    both = loci_of(scene, [(0, 0, 2.0), (1, 1, 2.6)])  # 1 m and 1.3 m: both at x = 1.505
    odds = mapping.occupancy_grid(scene, sensors, both, context=context())
    assert odds[100, 150] == pytest.approx(2 * occ, rel=1e-6)
    cleared = loci_of(scene, [(0, 0, 2.0), (1, 1, 3.6)])  # the second sees past x = 1.505
    odds = mapping.occupancy_grid(scene, sensors, cleared, context=context())
    assert odds[100, 150] == pytest.approx(0.0, abs=1e-6)
    assert odds[100, 200] == pytest.approx(occ, rel=1e-6)
    later = loci_of(scene, [(0, 0, 2.0), (0, 0, 3.0)])  # one pair's first and second echo
    odds = mapping.occupancy_grid(scene, sensors, later, context=context())
    assert odds[100, 150] == pytest.approx(occ, rel=1e-6)
    assert odds[100, 200] == pytest.approx(occ, rel=1e-6)
    assert odds[100, 120] == pytest.approx(log_odds(P_EMPTY), rel=1e-6)


@settings(max_examples=60, deadline=None)
@given(arc_cases())
def test_occupancy_kernel_matches_the_reference(case):
    scene, sensors, loci, _ = case
    ref = mapping.occupancy_grid_reference(scene, sensors, loci)
    assert ref.shape == scene.grid_shape and ref.dtype == np.float64
    for precision in precisions():
        got = mapping.occupancy_grid(scene, sensors, loci, context=context(),
                                     precision=precision)
        if precision == "float64":
            assert np.array_equal(got, ref)
            continue
        differ = np.abs(got - ref) > 1e-5 * (1.0 + np.abs(ref))
        assert not np.any(differ & ~near_edges(scene, sensors, loci).any(axis=0))


# --------------------------------------------------------------------------- morphological


def test_morphological_processing_of_one_arc_is_a_one_cell_thick_curve():
    """One arc (a band √2 cells thick) closed and thinned: an 8-connected curve one cell
    thick along the arc, about as many cells as the arc is long."""
    scene = scene_of(mode="morphological")
    sensors = sensors_of([(0.5, 1.0, 0.0)])
    radius = 1.5
    loci = loci_of(scene, [(0, 0, 2 * radius)])
    votes = votes_of(scene, sensors, loci)
    assert votes.tx is None and votes.points is not None
    closed = np.zeros(scene.grid_shape, bool)
    closed[tuple(np.array(sorted(cells_of(scene, votes.points))).T)] = True
    arc = mapping.accumulate(scene, sensors, loci, context=context()) > 0
    assert np.all(closed[arc]) and closed.sum() <= arc.sum() * 1.2
    thin = post.thin_map(closed, PostSettings())
    assert not np.any(thin[:-1, :-1] & thin[1:, :-1] & thin[:-1, 1:] & thin[1:, 1:])
    iy, ix = np.nonzero(thin)
    r = np.hypot((ix + 0.5) * scene.cell - 0.5, (iy + 0.5) * scene.cell - 1.0)
    assert np.all(np.abs(r - radius) <= scene.cell)
    length = 2 * radius * math.radians(12.0)
    assert 0.7 * length / scene.cell <= thin.sum() <= 1.1 * length / scene.cell
    assert len(set(iy.tolist())) == thin.sum()  # one cell per row: the arc runs along y


def test_closing_fills_the_gap_between_two_arcs():
    binary = np.zeros((9, 12), bool)
    binary[4, 1:5] = True
    binary[4, 6:11] = True  # one cell apart
    binary[0, :3] = True  # at the map's edge: kept
    closed = mapping.closed_arc_map(binary)
    assert closed[4, 1:11].all() and closed[0, :3].all()
    assert closed.sum() == binary.sum() + 1


# --------------------------------------------------------------------------- arc-transversal median


def corner_seen_from(positions, corner=(2.005, 1.005)):
    """Transducers at ``positions`` aimed at a point reflector (a corner) ``corner``, one
    monostatic locus each through it."""
    c = np.asarray(corner)
    transducers = [(x, y, math.degrees(math.atan2(c[1] - y, c[0] - x))) for x, y in positions]
    rows = [(k, k, 2.0 * math.hypot(*(c - p))) for k, p in enumerate(positions)]
    return c, sensors_of(transducers), rows


def test_arc_transversal_median_of_three_loci_through_a_corner_is_the_corner():
    """Three transducers 0.3 m apart, 1.5 m from a corner, aimed at it: each locus crosses
    the other two there (their second crossings, mirrored about the transducers' line, are
    behind them), so each locus' median crossing is the corner."""
    scene = scene_of(mode="arc-transversal-median")
    corner, sensors, rows = corner_seen_from([(0.505, 0.705), (0.505, 1.005), (0.505, 1.305)])
    votes = votes_of(scene, sensors, loci_of(scene, rows))
    assert votes.points is not None and votes.tx is not None and votes.rx is not None
    assert votes.tx.tolist() == [0, 1, 2] and votes.rx.tolist() == [0, 1, 2]
    assert np.all(np.hypot(*(votes.points - corner).T) < 0.1 * scene.cell)


def test_arc_transversal_median_puts_a_walls_loci_on_the_wall():
    """Five transducers 0.1 m apart facing a wall 2 m away square on: neighbouring circles
    cross δ²/(8r) in front of the wall, and each circle's median crossing lies on the wall,
    within a cell, across from the transducers."""
    scene = scene_of(mode="arc-transversal-median")
    ys = [0.8, 0.9, 1.0, 1.1, 1.2]
    sensors = sensors_of([(0.5, y, 0.0) for y in ys])
    votes = votes_of(scene, sensors, loci_of(scene, [(k, k, 4.0) for k in range(5)]))
    assert votes.points is not None and len(votes.points) == 5
    assert np.all(np.abs(votes.points[:, 0] - 2.5) < scene.cell)
    # each circle's crossings lie halfway to the others: its median toward the middle
    assert votes.points[2, 1] == pytest.approx(1.0, abs=1e-3)
    assert np.all(np.diff(votes.points[:, 1]) > 0)
    assert np.all((votes.points[:, 1] >= 0.8) & (votes.points[:, 1] <= 1.2))


def test_a_locus_that_crosses_none_gives_no_arc_transversal_median():
    scene = scene_of(mode="arc-transversal-median")
    sensors = sensors_of([(0.5, 0.5, 0.0), (0.5, 1.5, 0.0)])  # beams 1 m apart
    points, source = mapping.arc_transversal_medians(scene, sensors,
                                                     loci_of(scene, [(0, 0, 3.0), (1, 1, 3.0)]))
    assert points.shape == (0, 2) and source.shape == (0,)


# --------------------------------------------------------------------------- triangulation


def test_triangulation_of_a_corner_seen_from_three_nearby_positions_is_one_point():
    """Three transducers 0.3 m apart (within the 1 m baseline) aimed at a corner: their
    three pairwise crossings are the corner, one cluster of three, one point there with
    the pair of the nearest locus."""
    scene = scene_of(mode="triangulation")
    corner, sensors, rows = corner_seen_from([(0.505, 0.705), (0.605, 1.005), (0.505, 1.305)])
    votes = votes_of(scene, sensors, loci_of(scene, rows))
    assert votes.points is not None and votes.tx is not None and votes.rx is not None
    assert votes.points.shape == (1, 2)
    assert np.hypot(*(votes.points[0] - corner)) < 0.1 * scene.cell
    assert votes.tx.tolist() == [1] and votes.rx.tolist() == [1]  # 1.4 m: the nearest


def test_triangulation_keeps_nothing_of_arcs_that_share_no_reflector():
    """Two loci that cross once inside their beams: one intersection, fewer than three."""
    scene = scene_of(mode="triangulation")
    corner, sensors, rows = corner_seen_from([(0.505, 0.705), (0.505, 1.305)])
    rows = [rows[0], (1, 1, rows[1][2] + 0.13)]  # the second locus 6.5 cm farther
    loci = loci_of(scene, rows)
    sampled = mapping.tangents.sample_loci(scene, sensors, loci)
    q, _, _ = mapping.tangents.locus_crossings(sampled, 0, np.array([1]))
    assert len(q) == 1 and np.hypot(*(q[0] - corner)) > 0.02
    votes = votes_of(scene, sensors, loci)
    assert votes.points is not None and votes.points.shape == (0, 2)


def test_triangulation_ignores_transmitters_beyond_the_baseline():
    """The corner seen from three positions 1.2 m apart: no pair within 1 m, no point;
    with a 1.5 m baseline, the corner."""
    scene = scene_of(extent=(0.0, 0.0, 4.0, 4.0), mode="triangulation")
    corner, sensors, rows = corner_seen_from([(0.505, 0.805), (0.505, 2.005), (0.505, 3.205)],
                                             corner=(2.505, 2.005))
    loci = loci_of(scene, rows)
    points, _ = mapping.triangulated_points(scene, sensors, loci)
    assert points.shape == (0, 2)
    points, source = mapping.triangulated_points(scene, sensors, loci, baseline_m=1.5)
    assert points.shape == (1, 2) and np.hypot(*(points[0] - corner)) < 0.1 * scene.cell
    assert source.tolist() == [1]  # 2 m from the corner, the others 2.33 m


def test_support_clusters_seed_the_best_supported_and_do_not_chain():
    """A chain of points 1 cm apart along a line, 2 cm radius: clusters of at most 5
    (never the whole chain), each 3 or more; a lone pair stays unclustered."""
    chain = np.stack([np.arange(20) * 0.01, np.zeros(20)], axis=1)
    lone = np.array([[5.0, 5.0], [5.005, 5.0]])
    labels = mapping.crossings.support_clusters(np.vstack([chain, lone]), 0.02, 3)
    assert np.all(labels[20:] == -1)
    sizes = np.bincount(labels[labels >= 0])
    assert len(sizes) >= 4 and sizes.min() >= 3 and sizes.max() <= 5


# --------------------------------------------------------------------------- the pipeline


@pytest.mark.parametrize("mode", [m for m in NEW_MODES if m != "triangulation"])
def test_every_new_mode_maps_the_bundled_plane(mode):
    """plane-2m (a wall at x = 9 m seen by thesis-style arrays, 14 echoes) through the whole
    pipeline: the thin map lies on the wall; every mode but point marking and the
    arc-transversal median, whose dozen (the loci that cross another: four) isolated points
    make no curve, gives a profile there."""
    scene = load_scene(bundled_scenes() / "plane-2m.json")
    scene = dataclasses.replace(scene, mapping=dataclasses.replace(scene.mapping, mode=mode))
    result = pipeline.run(scene, context=context())
    assert result.thin is not None and result.profile is not None
    ix = np.nonzero(result.thin)[1]
    assert len(ix) >= (4 if mode == "arc-transversal-median" else 10)
    assert np.median(np.abs((ix + 0.5) * scene.cell - 9.0)) < 0.05
    rms = result.metrics["accuracy_m"]["rms"]
    if mode in ("point-marking", "arc-transversal-median"):
        assert len(result.profile.points) == 0 and rms is None
    else:
        assert len(result.profile.points) > 100 and rms < 0.1


def test_triangulation_maps_the_bundled_corner_and_not_the_plane():
    """Triangulation finds what three crossings or more agree on: at corner-4m (47 echoes)
    a few points in the corner, within a cm of its walls; plane-2m's 14 echoes cross too
    seldom for a cluster: nothing."""
    for name, want in (("corner-4m.json", True), ("plane-2m.json", False)):
        scene = load_scene(bundled_scenes() / name)
        scene = dataclasses.replace(scene, mapping=dataclasses.replace(scene.mapping,
                                                                       mode="triangulation"))
        result = pipeline.run(scene, context=context())
        found = result.counts["triangulated_points"]
        assert (found >= 3) if want else (found == 0), name
        if want:
            assert result.metrics["accuracy_m"]["rms"] < 0.01


def test_the_comparison_runs_every_mode_on_the_same_detections(tmp_path):
    """python -m clsonar.tools.methods on plane-2m, noise-free, three modes: one row each,
    the same detections, the table and the JSON written."""
    from clsonar.tools import methods

    modes = ("loci", "point-marking", "occupancy")
    assert methods.main(["--out", str(tmp_path), "--scenes", "plane-2m.json", "--noise", "0",
                         "--modes", ",".join(modes)]) == 0
    rows = json.loads((tmp_path / "methods.json").read_text())
    assert [r["mode"] for r in rows] == list(modes)
    assert {r["kind"] for r in rows} == {"shapes"}
    assert len({r["detections"] for r in rows}) == 1 and rows[0]["detections"] == 14
    by_mode = {r["mode"]: r for r in rows}
    assert by_mode["point-marking"]["accuracy_m"] is None  # no profile: a dozen points
    assert by_mode["point-marking"]["map_error_m"] < 0.05  # but they lie on the wall
    assert by_mode["occupancy"]["accuracy_m"] < 0.1
    # the occupancy grid marks nearly all of the wall's full cells, point marking a few
    assert by_mode["occupancy"]["full_rate"] > 0.9 > 0.2 > by_mode["point-marking"]["full_rate"]
    assert all(0.99 < r["empty_rate"] <= 1.0 for r in rows)
    table = (tmp_path / "methods.md").read_text()
    assert "### plane-2m" in table and table.count("| 0 | `") == 3
    assert "## Who wins where" in table and "**shapes** (1 run of each mode)" in table
    assert "### shapes" in table
    if (tmp_path / "methods-pareto-shapes.png").exists():
        assert "(methods-pareto-shapes.png)" in table


def summary_row(scene, mode, seconds, error, full=0.9, kind=None):
    """A row of the comparison: ``seconds`` of map (post-processing 1 s more), its map
    error and full-cell rate."""
    from clsonar.tools import methods

    return {"scene": scene, "kind": kind or methods.load_case(scene)[1], "mode": mode,
            "map_s": None if seconds is None else seconds - 1.0,
            "post_s": 1.0, "map_error_m": error, "full_rate": full, "empty_rate": 0.99,
            "accuracy_m": error, "completeness_2cm": full}


def test_the_pareto_front_keeps_the_modes_nothing_beats():
    """Seconds against error: (1, 5) and (1, 6) tie on time, (1, 5) wins; (2, 5) is beaten
    by (1, 5); (3, 1) and (0.5, 9) are each best at something."""
    from clsonar.tools import methods

    cost = np.array([1.0, 1.0, 2.0, 3.0, 0.5])
    error = np.array([5.0, 6.0, 5.0, 1.0, 9.0])
    assert methods.pareto_front(cost, error).tolist() == [4, 0, 3]
    rows = [summary_row("room", "a", 2.0, 0.02, 0.9), summary_row("room-l", "a", 4.0, 0.04, 0.7),
            summary_row("room", "b", 1.0, None, 0.0),
            summary_row("plane-2m", "a", 1.0, 0.5, None),
            summary_row("plane-2m", "c", 1.0, 0.1, 0.1)]
    rooms = methods.mode_summary(rows, "rooms")
    assert list(rooms) == ["a"]  # b gave no map
    assert (rooms["a"].seconds, rooms["a"].mapped, rooms["a"].rows) == (3.0, 2, 2)
    assert rooms["a"].map_error_m == pytest.approx(0.03)
    assert rooms["a"].full_rate == pytest.approx(0.8)
    shapes = methods.mode_summary(rows, "shapes")
    assert shapes["a"].full_rate == 0.0 and shapes["c"].full_rate == 0.1
    # c is as fast and more accurate, but marks 10 % of the full cells: the second front
    # has neither
    assert methods.fronts(shapes) == (["c"], [])


def test_the_verdict_names_the_winners_and_why_the_default_is_off_a_front():
    """Three modes by hand: ``reflectors`` (the default) 0.5 s, 0.30 cm, 90 % of the full
    cells; ``tangents`` 0.4 s, 0.30 cm, 80 %; ``point-marking`` 0.1 s, 0.20 cm, 5 %."""
    from clsonar.tools import methods

    rows = [summary_row("room", "reflectors", 0.5, 0.003, 0.9),
            summary_row("room", "tangents", 0.4, 0.003, 0.8),
            summary_row("room", "point-marking", 0.1, 0.002, 0.05)]
    summary = methods.mode_summary(rows, "rooms")
    (text,) = methods.verdict("rooms", summary)
    # a tie goes to the faster
    assert "most accurate of the modes that mark ≥ 50 % of the full cells: `tangents`" in text
    assert "(80 % of the full cells), tied with `reflectors` (0.30 cm)." in text
    assert "Lowest map error of any mode: `point-marking` (0.20 cm), marking 5 %" in text
    assert "Fastest: `point-marking` (0.10 s a run), 5.0× faster than the default" in text
    # tangents dominates the default on time at the same map error
    assert ("not on the front of the maps ≥ 50 % full: `tangents` is 20 % faster (0.40 "
            "against 0.50 s) with as low a map error (0.30 cm), marking 80 % of the full "
            "cells against 90 %") in text
    assert "not on the front of all modes: `tangents` is 20 % faster" in text
    assert ("; `point-marking` is 5.0× faster (0.10 against 0.50 s) with 0.10 cm lower map "
            "error (0.20 against 0.30 cm), marking 5 % of the full cells against 90 %.") in text
    # tangents drawing the default's very maps: the default is off by its seconds alone
    (text,) = methods.verdict("rooms", summary, twins=["tangents"])
    assert ("`tangents` draws the same maps on every run (the same cells) and is 20 % "
            "faster (0.40 against 0.50 s): the default is off the front by its seconds "
            "alone") in text
    # and when the default is the faster of the two, it is on the front, and says so
    rows[1] = summary_row("room", "tangents", 0.6, 0.003, 0.9)
    (text,) = methods.verdict("rooms", methods.mode_summary(rows, "rooms"), twins=["tangents"])
    assert ("The default `reflectors` is on the front of the maps ≥ 50 % full (`tangents` "
            "draws the same maps on every run, 0.10 s slower).") in text
    # a faster, more accurate reflectors is on both fronts
    rows[0] = summary_row("room", "reflectors", 0.05, 0.001, 0.9)
    (text,) = methods.verdict("rooms", methods.mode_summary(rows, "rooms"))
    assert "0.20 cm (3.0×) below the next, `tangents`" in text
    assert "Fastest: `reflectors` (0.05 s a run)." in text
    assert text.count("is on the front") == 2


def test_same_maps_are_equal_on_every_run():
    from clsonar.tools import methods

    rows = [{**summary_row(scene, mode, 1.0, 0.01), "noise": 0.0, "map_cells": cells}
            for scene, mode, cells in (("room", "a", 5), ("room", "b", 5), ("room", "c", 5),
                                       ("room-l", "a", 7), ("room-l", "b", 7),
                                       ("room-l", "c", 8))]
    assert methods.same_maps(rows, "rooms", "a") == ["b"]
    assert methods.same_maps(rows, "shapes", "a") == []


def test_cell_rates_of_a_map_by_hand():
    """A 5 × 7 map whose true surface is row 2, insonified at columns 1-5; the echoes
    sounded columns 0-3. Marked: (1, 1) beside the surface, (4, 3) two cells from it, (0, 6)
    outside the sounded region. Within one cell: the full cells of columns 1 and 2 are
    found (2 of 5); the truly empty sounded cells are rows 0 and 4, columns 0-3 (8), one
    of them marked (7 of 8). Within no cell: no full cell is marked, and the truly empty
    sounded cells are every row but 2 (16), two of them marked."""
    from clsonar.metrics import cell_rates

    surface = np.zeros((5, 7), bool)
    surface[2] = True
    full = np.zeros_like(surface)
    full[2, 1:6] = True
    region = np.zeros_like(surface)
    region[:, :4] = True
    marked = np.zeros_like(surface)
    marked[1, 1] = marked[4, 3] = marked[0, 6] = True
    assert cell_rates(full, surface, region, marked) == (0.4, 0.875)
    assert cell_rates(full, surface, region, marked, tolerance=0) == (0.0, 0.875)
    assert cell_rates(full, surface, region, np.zeros_like(surface)) == (0.0, 1.0)
    assert cell_rates(np.zeros_like(surface), surface, surface, marked) == (None, None)


def test_sounded_cells_are_the_cone_of_a_locus():
    """A transducer at (0.5, 1) facing +x and its echo from 1.5 m: the cells inside its
    beam out to 1.5 m (and the band's half) are sounded, none behind it, beyond the echo
    or outside the beam; their area is the beam's sector, r²·θ."""
    scene = scene_of()
    sensors = sensors_of([(0.5, 1.0, 0.0)])
    region = mapping.sounded_cells(scene, sensors, loci_of(scene, [(0, 0, 3.0)]),
                                   context=context())

    def at(x, y):
        return bool(region[math.floor(y / scene.cell), math.floor(x / scene.cell)])

    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    half = math.asin(math.sqrt(cut_sin2))
    assert at(1.0, 1.0) and at(1.98, 1.0) and at(1.5, 1.0 + 0.9 * math.tan(half))
    assert not at(0.4, 1.0) and not at(2.05, 1.0) and not at(1.5, 1.0 + 1.1 * math.tan(half))
    area = region.sum() * scene.cell**2
    assert area == pytest.approx(1.5**2 * half, rel=0.03)


def test_a_case_is_a_bundled_scene_or_a_zoo_case():
    from clsonar.tools import methods

    assert methods.load_case("room-l")[1] == "rooms"
    assert methods.load_case("plane-2m.json")[1] == "shapes"
    scene, kind = methods.load_case("zoo:0:post:2")
    assert kind == "zoo" and scene.name.startswith("post-02")
    for bad in ("nope", "zoo:0:post", "zoo:x:post:1", "zoo:0:dragon:1"):
        with pytest.raises(ValueError):
            methods.load_case(bad)


def test_clsonar_bench_methods_writes_the_comparison(tmp_path, capsys):
    """clsonar bench --methods on plane-2m, σ 0, three modes: the tool's files, its command
    line in the page; a mode or scene that does not exist is one line, before any work."""
    from clsonar.cli import main

    out = tmp_path / "bench"
    assert main(["bench", "--methods", "--out", str(out), "--scenes", "plane-2m", "--noise",
                 "0", "--modes", "reflectors,point-marking,occupancy"]) == 0
    rows = json.loads((out / "methods.json").read_text())
    assert [r["mode"] for r in rows] == ["reflectors", "point-marking", "occupancy"]
    assert rows[0]["full_rate"] > 0.9 and rows[0]["map_error_m"] < 0.01
    page = (out / "methods.md").read_text()
    assert (f"clsonar bench --out {out} --scenes plane-2m --noise 0 --modes "
            "reflectors,point-marking,occupancy --methods") in page
    assert "The default `reflectors` is on the front of the maps ≥ 50 % full" in page
    for args, flag in ((["--modes", "loci,dragon"], "--modes"),
                       (["--scenes", "plane-2m,zoo:0:dragon:1"], "--scenes"),
                       (["--noise", "0,-1"], "--noise")):
        capsys.readouterr()
        assert main(["bench", "--methods", "--out", str(tmp_path / "no"), *args]) == 2
        assert capsys.readouterr().err.startswith(f"clsonar: error: {flag}")
        assert not (tmp_path / "no").exists()
