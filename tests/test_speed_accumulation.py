"""Issue 16, the room's accumulation and sight in fewer operations, the same bits: the
fits' dot products through ``ndarray.dot`` (the same ``cblas_ddot`` call as ``@``, without
the matmul ufunc's set-up), the circle fit's Jacobian filled in place, the neighbourhoods of
the clusters and seed sets taken 64 rows at a time, and the point map counted by
``np.bincount`` — each against the form it replaced, kept here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_speed_sight import _cases as _sight_cases

from clsonar import sight
from clsonar.files import bundled_scenes
from clsonar.mapping import pillars, points
from clsonar.mapping.models import ellipse_axes
from clsonar.mapping.pillars import CLUSTER_M, GN_ITERATIONS, GN_STEP_M, SEED_M
from clsonar.mapping.points import nonzero_cells
from clsonar.scene import load_scene


def _least_squares_step_matmul(jac, r):
    """``pillars._least_squares_step`` before: the sums by ``@``."""
    if jac.shape[1] == 2:
        jx, jy = jac[:, 0], jac[:, 1]
        a, b, c = float(jx @ jx), float(jx @ jy), float(jy @ jy)
        det = a * c - b * b
        if det > 1e-10 * a * c:
            gx, gy = float(jx @ r), float(jy @ r)
            return np.array([(c * gx - b * gy) / det, (a * gy - b * gx) / det])
    return np.linalg.lstsq(jac, r, rcond=None)[0]


def _gauss_newton_matmul(residual, jacobian, start):
    """``pillars._gauss_newton`` before (each halving in turn, as
    tests/test_tangent_speed.py's loop), its costs and steps summed by ``@``."""
    x = np.asarray(start, dtype=np.float64)
    r = residual(x)
    for _ in range(GN_ITERATIONS):
        step = _least_squares_step_matmul(jacobian(x), r)
        for _ in range(30):
            trial = x - step
            r_trial = residual(trial)
            if r_trial @ r_trial <= r @ r:
                break
            step = 0.5 * step
        else:
            break
        x, r = trial, r_trial
        if math.sqrt(float(step @ step)) <= GN_STEP_M:
            break
    return x, r


def _point_from_matmul(T, a, start):
    """``pillars._point_from`` for T = R before."""
    return _gauss_newton_matmul(lambda v: np.hypot(*(v - T).T) - a,
                                lambda v: pillars._directions(v, T), start)


def _fit_matmul(T, rho, start):
    """``pillars.fit_circle`` before: the Jacobian a fresh ``np.column_stack`` each step."""

    def residual(x):
        return np.hypot(*(x[:2] - T).T) - rho - x[2]

    def jacobian(x):
        return np.column_stack([pillars._directions(x[:2], T), -np.ones(len(T))])

    x, r = _gauss_newton_matmul(residual, jacobian, np.r_[start, 0.1])
    return x[:2], float(x[2]), r


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 70), st.integers(1, 3),
       st.sampled_from([1e-300, 1e-3, 1.0, 1e200]))
def test_dot_is_matmul_to_the_bit(seed, n, stride, scale):
    """``x.dot(y)`` and ``x @ y`` of 1-D float64 arrays are one ``cblas_ddot`` call: the
    same bits, contiguous or strided (a column of an [n, 2] array), of any length."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, stride)) * scale
    b = rng.normal(size=(n, stride))
    for x, y in ((a[:, 0], b[:, 0]), (a[:, -1], a[:, 0]), (a[:, 0].copy(), b[:, 0].copy()),
                 (a[:, 0], b[:, 0].copy())):
        with np.errstate(all="ignore"):  # 1e200: inf and NaN sums alike
            assert np.float64(x.dot(y)).tobytes() == np.float64(x @ y).tobytes()


@st.composite
def loci(draw):
    """T = R loci around a point or a circle (radius 0 to 0.3 m), range errors from none
    to centimetres, started near or far off."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    k = draw(st.integers(3, 40))
    target = rng.uniform(-5, 5, 2)
    angle = rng.uniform(0, 2 * np.pi, k)
    T = target + rng.uniform(0.3, 6.0, (k, 1)) * np.stack([np.cos(angle), np.sin(angle)], -1)
    radius = draw(st.sampled_from([0.0, 0.05, 0.3]))
    a = np.hypot(*(target - T).T) - radius
    a = a + rng.normal(0, 1, k) * draw(st.sampled_from([0.0, 1e-4, 3e-3, 0.05]))
    start = target + rng.normal(0, 1, 2) * draw(st.sampled_from([0.01, 0.3, 2.0]))
    return T, a, start


@settings(max_examples=300, deadline=None)
@given(loci())
def test_the_fits_are_the_matmul_fits(case):
    T, a, start = case
    v, r = pillars._point_from(T, T, a, start)
    v0, r0 = _point_from_matmul(T, a, start)
    assert v.tobytes() == v0.tobytes() and r.tobytes() == r0.tobytes()
    c, radius, r = pillars.fit_circle(T, a, start)
    c0, radius0, r0 = _fit_matmul(T, a, start)
    assert c.tobytes() == c0.tobytes() and radius == radius0 and r.tobytes() == r0.tobytes()


def test_a_fit_of_the_room_is_the_matmul_fit():
    """A corner heard from four poses: both forms land on it, the same bits."""
    corner = np.array([2.0, 3.0])
    T = np.array([[0.0, 0.0], [1.0, 0.2], [3.5, 0.5], [4.0, 1.0]])
    a = np.hypot(*(corner - T).T) + np.array([0.0, 1e-3, -2e-3, 5e-4])
    v, r = pillars._point_from(T, T, a, np.array([2.3, 2.6]))
    v0, r0 = _point_from_matmul(T, a, np.array([2.3, 2.6]))
    assert v.tobytes() == v0.tobytes() and r.tobytes() == r0.tobytes()
    np.testing.assert_allclose(v, corner, atol=3e-3)


def _near_rows_each(points, reach):
    """``pillars._near_rows`` before: one row at a time."""
    return [np.flatnonzero(np.hypot(*(points - p).T) <= reach) for p in points]


def _seed_sets_each(middles):
    """``pillars._seed_sets`` before."""
    tried, out = set(), []
    for m in [*middles, None]:
        near = (np.arange(len(middles)) if m is None
                else np.flatnonzero(np.hypot(*(middles - m).T) <= SEED_M))
        if len(near) >= pillars.MIN_PILLAR_LOCI and near.tobytes() not in tried:
            tried.add(near.tobytes())
            out.append(near)
    return out


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 300), st.sampled_from([0.2, 1.0, 4.0]))
def test_the_near_rows_and_seed_sets_are_one_row_at_a_time(seed, n, scale):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-scale, scale, (n, 2))
    if n > 4:  # points exactly at the reach from another, and repeated points
        pts[1] = pts[0] + [CLUSTER_M, 0.0]
        pts[2] = pts[0] + [0.0, SEED_M]
        pts[3] = pts[0]
    for reach in (CLUSTER_M, SEED_M):
        got = list(pillars._near_rows(pts, reach))
        want = _near_rows_each(pts, reach)
        assert len(got) == len(want)
        assert all(g.dtype == w.dtype and np.array_equal(g, w)
                   for g, w in zip(got, want, strict=True))
    got = list(pillars._seed_sets(pts))
    want = _seed_sets_each(pts)
    assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))


def test_near_rows_in_blocks_of_fewer_rows(monkeypatch):
    """Many points: fewer than 64 rows at once, the same rows."""
    monkeypatch.setattr(pillars, "NEAR_AT_ONCE", 1000)
    pts = np.random.default_rng(5).uniform(0.0, 3.0, (257, 2))
    got = list(pillars._near_rows(pts, CLUSTER_M))
    assert all(np.array_equal(g, w) for g, w in zip(got, _near_rows_each(pts, CLUSTER_M),
                                                     strict=True))


def _point_map_add_at(scene, pts, window=None):
    """``points.point_map`` before: ``np.add.at``."""
    from clsonar.geometry import point_cells

    ny, nx = scene.grid_shape
    iy, ix = point_cells(scene.extent, scene.cell, pts)
    if window is not None:
        row0, col0, ny, nx = window
        iy, ix = iy - row0, ix - col0
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    counts = np.zeros((ny, nx), dtype=np.float32)
    sums = np.zeros((ny, nx, 2))
    np.add.at(counts, (iy[ok], ix[ok]), 1.0)
    np.add.at(sums, (iy[ok], ix[ok]), pts[ok])
    return counts, sums


_ROOM = load_scene(bundled_scenes() / "room.json")


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 3000), st.booleans(), st.booleans())
def test_the_point_map_is_add_at(seed, n, windowed, single):
    """Random points, many in few cells (sums of many terms in the points' order), some
    outside the grid or the window, NaN, float32: the same counts and sums to the bit."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-1.0, 11.0, (n, 2))
    pts[: n // 2] = rng.uniform(4.0, 4.03, (n // 2, 2))  # three by three cells, crowded
    if n > 3:
        pts[0] = np.nan
        pts[1] = [-0.0, 5.0]
    if single:
        pts = pts.astype(np.float32)
    window = points.points_window(_ROOM, pts) if windowed else None
    counts, sums = points.point_map(_ROOM, pts, window)
    want_counts, want_sums = _point_map_add_at(_ROOM, pts, window)
    assert counts.dtype == want_counts.dtype and counts.shape == want_counts.shape
    assert counts.tobytes() == want_counts.tobytes() and sums.tobytes() == want_sums.tobytes()
    assert float(counts.sum()) == np.count_nonzero(
        np.isfinite(pts).all(axis=1) & (pts >= 0).all(axis=1) & (pts < 10).all(axis=1)
    ) or windowed


def test_the_point_map_counts_stop_where_float32_stops(monkeypatch):
    """More than 2²⁴ points in one cell: float32's additions of 1 stop at 2²⁴, and so do
    the counts (here with a smaller stop, the same rule)."""
    monkeypatch.setattr(points, "_FLOAT32_COUNTS", 5)
    pts = np.full((9, 2), 5.005)
    counts, sums = points.point_map(_ROOM, pts)
    assert counts.max() == 5.0 and sums[500, 500].tolist() == [9 * 5.005, 9 * 5.005]
    counts, _ = points.point_map(_ROOM, pts[:3])
    assert counts.max() == 3.0


@settings(max_examples=150, deadline=None)
@given(case=_sight_cases(), tile_cells=st.sampled_from([1, 16, 200]))
def test_first_hits_at_is_first_hits_each_in_the_wanted_bins(case, tile_cells):
    """The z-buffers in the wanted bins alone (sight.first_hits_at) are the whole
    z-buffers' (first_hits_each, tests/test_speed_sight.py's cases: walls, clusters,
    occluders on an origin; arcs across bin 0, scattered bins, none, all), to the bit."""
    origins, occluders, cell, within, wanted = case
    old = sight.SIGHT_TILE_CELLS
    try:
        sight.SIGHT_TILE_CELLS = tile_cells
        whole = sight.first_hits_each(origins, occluders, cell, within, wanted)
        rows, at = nonzero_cells(wanted)
        got = sight.first_hits_at(origins, occluders, cell, within, rows, at, wanted.shape[1])
    finally:
        sight.SIGHT_TILE_CELLS = old
    assert got.tobytes() == whole[rows, at].tobytes()


def test_nonzero_cells_is_nonzero():
    rng = np.random.default_rng(3)
    for shape in ((0, 5), (5, 0), (1, 1), (7, 3600), (953, 952)):
        mask = rng.random(shape) < 0.01
        for m in (mask, mask.T, mask[::2]):  # views too
            got, want = nonzero_cells(m), np.nonzero(m)
            assert all(g.dtype == w.dtype and np.array_equal(g, w)
                       for g, w in zip(got, want, strict=True))


def _recorded(monkeypatch, function, *places) -> list:
    """The arguments of every call of ``function``, set in each of ``places`` (a module
    and a name) as a spy that records them and calls it."""
    calls: list = []

    def spy(*args):
        calls.append(args)
        return function(*args)

    for module, name in places:
        monkeypatch.setattr(module, name, spy)
    return calls


def test_the_room_line_of_sight_is_one_transducer_at_a_time(monkeypatch):
    """The room's own points, pairs and map (on PoCL's CPU, 1,471 ghosts of its 37,470
    points since stop 41 located one more point reflector in it: 1,622 of 37,666
    before; the NVIDIA H200's float32 map gave 1,623 of them): the wanted bins' z-buffers
    give what one z-buffer per transducer gives."""
    from clsonar.opencl import choose_device, device_kind
    from clsonar.pipeline import run

    whole = sight.line_of_sight
    calls = _recorded(monkeypatch, whole, (sight, "line_of_sight"))
    result = run(_ROOM)
    assert len(calls) == 1
    points_, tx, rx, positions, occluders, cell = calls[0]
    seen = whole(*calls[0])
    assert result.counts["ghost_points"] == np.count_nonzero(~seen)
    if device_kind(choose_device()) == "CPU":
        assert (len(points_), np.count_nonzero(~seen)) == (37470, 1471)
    np.testing.assert_array_equal(
        seen, sight.line_of_sight_per_sensor(points_, tx, rx, positions, occluders, cell))


def _halved_numpy_min(residual, x, step, cost):
    """``pillars._halved`` before: the smallest nonzero |step| by numpy's min."""
    nonzero = np.abs(step[step != 0])
    if len(nonzero) and nonzero.min() * pillars._HALVES[-1, 0] >= pillars._TINY:
        halvings = step * pillars._HALVES
    else:
        halvings = np.empty((pillars.GN_HALVINGS, len(step)))
        for j in range(pillars.GN_HALVINGS):
            halvings[j] = 0.5 * (step if j == 0 else halvings[j - 1])
    trials = x - halvings
    r_trials = residual(trials)
    for j in range(pillars.GN_HALVINGS):
        if r_trials[j] @ r_trials[j] <= cost:
            return halvings[j], trials[j], r_trials[j]
    return None


def test_halvings_with_nan_infinite_and_subnormal_steps_are_numpys():
    """Steps holding NaN (first or after a number), infinities, subnormal and tiny
    entries: Python's min of the few |entries| takes the product form only where numpy's
    did or where both forms give the same bits."""
    tiny = np.finfo(np.float64).tiny
    T = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])

    def residual(v):
        d = v[..., None, :] - T
        return np.hypot(d[..., 0], d[..., 1]) - 0.7

    x = np.array([0.3, 0.2])
    cost = float(residual(x) @ residual(x))
    for step in ([np.nan, 0.4], [0.4, np.nan], [np.nan, 3 * tiny], [3 * tiny, np.nan],
                 [np.inf, 0.1], [0.0, 5e-310], [1e-300, 0.2], [0.0, 0.0], [0.25, -0.5]):
        step = np.array(step)
        with np.errstate(all="ignore"):
            got = pillars._halved(residual, x, step, cost)
            want = _halved_numpy_min(residual, x, step, cost)
        assert (got is None) == (want is None)
        if got is not None:
            assert all(g.tobytes() == w.tobytes() for g, w in zip(got, want, strict=True))


def _locus_samples_before(scene, sensors, loci):
    """``tangents._locus_samples`` before: cos and sin of each sample's angle, the samples
    gathered back for T's beam test, R's beam tested where R is T too."""
    from clsonar.mapping.envelope import beam_arc_samples, in_beams
    from clsonar.mapping.tangents import LOCUS_SAMPLES

    pos, axes = sensors.positions, sensors.axes
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    T, R = pos[loci.tx], pos[loci.rx]
    a, f, b, u = ellipse_axes(T, R, scene.medium.c * loci.tof_s)
    v = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    phi = 2 * np.pi * np.arange(LOCUS_SAMPLES) / LOCUS_SAMPLES
    centre = 0.5 * (T + R)
    rows, ks = beam_arc_samples(u, v, axes[loci.tx], a, f, cut_sin2, LOCUS_SAMPLES)
    p = np.zeros((len(a), LOCUS_SAMPLES, 2))
    p[rows, ks] = (centre[rows] + (a[rows] * np.cos(phi[ks]))[:, None] * u[rows]
                   + (b[rows] * np.sin(phi[ks]))[:, None] * v[rows])
    inside = np.zeros((len(a), LOCUS_SAMPLES), dtype=bool)
    inside[rows, ks] = in_beams(p[rows, ks], T[rows], axes[loci.tx][rows], cut_sin2)
    inside &= (a > f)[:, None]
    i, k = np.nonzero(inside)
    inside[i, k] = in_beams(p[i, k], R[i], axes[loci.rx][i], cut_sin2)
    return p, inside, a


@pytest.mark.parametrize("name, noise", [("room.json", 0.0), ("room-obstacles.json", 0.6),
                                         ("room-per-wall.json", 0.0), ("room-l.json", 0.6)])
def test_the_locus_samples_are_the_earlier_forms(name, noise, monkeypatch):
    """The rooms' own loci (T = R and pairs, 337 of the room's 465 T = R):
    the samples and their beam tests to the bit."""
    from clsonar.mapping import tangents
    from clsonar.pipeline import run
    from clsonar.tools.variants import with_seed

    calls = []
    mine = tangents._locus_samples

    def spy(*args):
        calls.append(args)
        return mine(*args)

    monkeypatch.setattr(tangents, "_locus_samples", spy)
    scene = load_scene(bundled_scenes() / name)
    run(scene if noise == 0 else with_seed(scene, 1, noise))
    assert calls
    for args in calls:
        loci = args[2]
        assert np.any(loci.tx != loci.rx)
        got, want = mine(*args), _locus_samples_before(*args)
        assert all(g.tobytes() == w.tobytes() for g, w in zip(got, want, strict=True))
        assert np.count_nonzero(got[1]) > 100


def test_cos_and_sin_gathered_are_of_the_gathered_angles():
    """numpy's cos and sin give each element the same bits in any array (lengths 1 to 80,
    unaligned, and the room's 47,067 samples' length): the 1,440 angles' values gathered
    are those of the gathered angles."""
    phi = 2 * np.pi * np.arange(1440) / 1440
    rng = np.random.default_rng(2)
    for n in [*range(1, 81), 47067]:
        ks = rng.integers(0, len(phi), n)
        for offset in range(3):
            buf = np.empty(n + offset)
            buf[offset:] = phi[ks]
            x = buf[offset:]
            assert np.cos(phi)[ks].tobytes() == np.cos(x).tobytes()
            assert np.sin(phi)[ks].tobytes() == np.sin(x).tobytes()


def _envelope_point_arrays(s, i, j, centre, r, d, dr, centred):
    """``envelope._envelope_point`` before: its 2-vectors as numpy arrays."""
    from clsonar.mapping.envelope import (
        _SAME_HEADING_COS,
        ENVELOPE_MAX_ALONG,
        ENVELOPE_TOL_M,
        in_beams,
    )

    length = float(np.hypot(*d))
    along = -r * dr / length if length > 0 else np.inf
    if abs(along) > ENVELOPE_MAX_ALONG * r:
        return []
    u = d / length
    v = np.array([-u[1], u[0]])
    if v @ s.axes[s.loci.tx[i]] < 0:
        v = -v
    q = centre + along * u + np.sqrt(r * r - along * along) * v
    straight = s.axes[s.loci.tx[i]] @ s.axes[s.loci.tx[j]] >= _SAME_HEADING_COS
    for k in (i, j):
        t = s.pos[s.loci.tx[k]]
        if (np.hypot(*(q - t)) < s.ranges[k] - ENVELOPE_TOL_M
                or not (in_beams(q, t, s.axes[s.loci.tx[k]], s.beams[k])
                        or (k == j and centred and straight))):
            return []
    return [(k, centre, r, q) for k in ((i,) if centred else (i, j))]


def _partner_arrays(s, i, others):
    """``envelope._partner`` before: numpy arrays for one locus too."""
    from clsonar.mapping.envelope import ENVELOPE_TOL_M

    if others is None:
        return None
    gap = np.hypot(*(s.pos[s.loci.tx[others[0]]] - s.pos[s.loci.tx[i]]))
    diff = np.abs(s.ranges[others] - s.ranges[i])
    k = int(np.argmin(diff))
    return others[k] if diff[k] <= gap + ENVELOPE_TOL_M else None


@pytest.mark.parametrize("name, noise", [("room.json", 0.0), ("room-obstacles.json", 0.6),
                                         ("room-cylinder.json", 0.0), ("room-l.json", 0.6)])
def test_the_envelope_points_are_the_array_forms(name, noise, monkeypatch):
    """The rooms' element scans (every envelope point, its locus, circle and place) with
    the 2-vectors and the partners' ranges in floats are those with numpy arrays, to the
    bit."""
    from clsonar.mapping import envelope, tangents
    from clsonar.pipeline import run
    from clsonar.tools.variants import with_seed

    mine = envelope.element_scans
    calls = _recorded(monkeypatch, mine, (envelope, "element_scans"),
                      (tangents, "element_scans"))
    scene = load_scene(bundled_scenes() / name)
    run(scene if noise == 0 else with_seed(scene, 1, noise))
    assert calls
    got = mine(*calls[0])
    monkeypatch.setattr(envelope, "_envelope_point", _envelope_point_arrays)
    monkeypatch.setattr(envelope, "_partner", _partner_arrays)
    want = mine(*calls[0])
    flat = [(place, one, k, c.tobytes(), float(r), q.tobytes())
            for scan in got for place, points_, one in scan for k, c, r, q in points_]
    flat_want = [(place, one, k, c.tobytes(), float(r), q.tobytes())
                 for scan in want for place, points_, one in scan for k, c, r, q in points_]
    assert flat == flat_want and len(flat) > 100


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.01, 0.05, 0.3]))
def test_one_point_beam_test_is_in_beams(seed, cut_sin2):
    """Random points and axes, some exactly on the beam's edge or on the sensor."""
    from clsonar.mapping.envelope import _in_beam, in_beams

    rng = np.random.default_rng(seed)
    angle = rng.uniform(0, 2 * np.pi, 50)
    axes = np.stack([np.cos(angle), np.sin(angle)], -1)
    sensor = rng.uniform(-3, 3, (50, 2))
    edge = math.asin(math.sqrt(cut_sin2)) * rng.choice([-1.0, 1.0], 50)
    turn = np.where(rng.random(50) < 0.5, edge, rng.uniform(-np.pi, np.pi, 50))
    direction = np.stack([np.cos(angle + turn), np.sin(angle + turn)], -1)
    p = sensor + rng.uniform(0, 5, (50, 1)) * direction
    p[:3] = sensor[:3]
    for k in range(50):
        d = (p[k] - sensor[k]).tolist()
        assert _in_beam(*d, *axes[k].tolist(), cut_sin2) == bool(
            in_beams(p[k], sensor[k], axes[k], cut_sin2))


def _stretches_each(chains, step, bias):
    """``envelope._stretches`` before: one stretch at a time through ``np.linspace``
    (the run's ends extended as it still does, ``envelope.extended_run``)."""
    from clsonar.mapping.envelope import extended_run

    points, ends = [], []
    for run, radius, _ in chains:
        q = extended_run(run, radius, bias)
        run = [run[0], *run, run[-1]]
        for k in range(len(run) - 1):
            n = max(2, math.ceil(math.hypot(*(q[k + 1] - q[k])) / step) + 1)
            t = np.linspace(0.0, 1.0, n)[:, None]
            points.append(q[k] + t * (q[k + 1] - q[k]))
            ends.append(np.tile([run[k][0], run[k + 1][0]], (n, 1)))
    if not points:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64)
    return np.concatenate(points), np.concatenate(ends).astype(np.int64)


@settings(max_examples=150, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 5), st.sampled_from([0.002, 0.01, 0.3]))
def test_the_stretches_are_one_at_a_time(seed, chains, step):
    """Runs of 2 to 12 envelope points (some repeated, radii finite or infinite): every
    sample and its loci as np.linspace one stretch at a time gave them."""
    from clsonar.mapping.envelope import _stretches

    rng = np.random.default_rng(seed)
    made = []
    for _ in range(chains):
        m = int(rng.integers(2, 13))
        q = np.cumsum(rng.normal(0, 0.05, (m, 2)), axis=0) + rng.uniform(-5, 5, 2)
        if m > 3 and rng.random() < 0.3:
            q[1] = q[2]  # a zero-length stretch inside the run (not at an end: no direction)
        run = [(int(rng.integers(0, 500)), rng.uniform(-5, 5, 2), float(rng.uniform(0.3, 6)),
                q[k]) for k in range(m)]
        made.append((run, float(rng.choice([np.inf, rng.uniform(0.1, 50)])), set()))
    got, want = _stretches(made, step, 0.001), _stretches_each(made, step, 0.001)
    assert all(g.dtype == w.dtype and g.tobytes() == w.tobytes()
               for g, w in zip(got, want, strict=True))


def _chains_each(scan, two_poses=False):
    """``envelope._chains`` before: each link computed where it is met."""
    from clsonar.mapping.envelope import _link_radius

    chains, run, loci, radius, last = [], [], set(), math.inf, 0

    def close():
        central = [place for _, o, place in run if not o]
        if len(run) >= 2 and len(central) < 2 if two_poses else len(central) >= 2:
            chains.append(([q for q, _, _ in run], radius, loci))

    for place, points_, one_sided in scan:
        p = points_[-1]
        link = _link_radius(run[-1][0], p) if run and place - last <= 2 else None
        if link is None:
            close()
            run, radius, loci = [], math.inf, set()
        else:
            radius = min(radius, link)
        run.append((p, one_sided, place))
        loci |= {q[0] for q in points_}
        last = place
    close()
    return chains


@pytest.mark.parametrize("name, noise", [("room.json", 0.0), ("room-obstacles.json", 0.6),
                                         ("room-cylinder.json", 0.0)])
def test_the_chains_with_their_links_once_are_the_loops(name, noise, monkeypatch):
    """Both kinds of chains of every element's scan, links kept from the first (as
    element_scans makes the scans) or not (a plain list): the loop's, to the bit."""
    from clsonar.mapping import envelope
    from clsonar.pipeline import run
    from clsonar.tools.variants import with_seed

    calls = []
    mine = envelope.element_scans

    def spy(*args):
        calls.append(args)
        return mine(*args)

    monkeypatch.setattr("clsonar.mapping.tangents.element_scans", spy)
    scene = load_scene(bundled_scenes() / name)
    run(scene if noise == 0 else with_seed(scene, 1, noise))
    found = 0
    for scan in mine(*calls[0]):
        for kinds in ((False, True), (True, False)):
            for form in (scan, list(scan)) if kinds[0] else (scan,):
                for two in kinds:
                    got, want = envelope._chains(form, two), _chains_each(scan, two)
                    assert len(got) == len(want)
                    for (q, r, ids), (q0, r0, ids0) in zip(got, want, strict=True):
                        assert r == r0 and ids == ids0 and len(q) == len(q0)
                        assert all(a[3].tobytes() == b[3].tobytes()
                                   for a, b in zip(q, q0, strict=True))
                    found += len(got)
    assert found > 10
