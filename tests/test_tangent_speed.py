"""The faster forms of the tangent map's searches and of the profile's curve tracing
(issue 16) against the loops they replace: the same results to the bit."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.geometry import cell_centres
from clsonar.mapping import pillars, tangents
from clsonar.mapping.loci import Loci
from clsonar.mapping.pillars import CLUSTER_M, GN_ITERATIONS, GN_STEP_M
from clsonar.mapping.tangents import LOCUS_SAMPLES, SampledLoci
from clsonar.post import curves, profile
from clsonar.post.curves import _STEPS
from clsonar.post.fits import Profile
from clsonar.scene import PostSettings


def _clusters_loop(points):
    """pillars._clusters as it was: np.isin per point, groups by np.unique."""
    label = np.arange(len(points))
    for i in range(len(points)):
        near = np.flatnonzero(np.hypot(*(points - points[i]).T) <= CLUSTER_M)
        label[np.isin(label, label[near])] = label[i]
    return [np.flatnonzero(label == k) for k in np.unique(label)]


def _gauss_newton_loop(residual, jacobian, start):
    """pillars._gauss_newton as it was: each halving of the step evaluated in turn."""
    x = np.asarray(start, dtype=np.float64)
    r = residual(x)
    for _ in range(GN_ITERATIONS):
        step = pillars._least_squares_step(jacobian(x), r)
        for _ in range(30):
            trial = x - step
            r_trial = residual(trial)
            if r_trial @ r_trial <= r @ r:
                break
            step = 0.5 * step
        else:
            break
        x, r = trial, r_trial
        if float(np.linalg.norm(step)) <= GN_STEP_M:
            break
    return x, r


def _point_from_loop(T, R, a, start):
    """pillars._point_from as it was: both distances always, one point at a time."""

    def residual(v):
        return 0.5 * (np.hypot(*(v - T).T) + np.hypot(*(v - R).T)) - a

    return _gauss_newton_loop(residual, lambda v: 0.5 * (pillars._directions(v, T)
                                                         + pillars._directions(v, R)), start)


def _fit_loop(T, rho, start):
    """pillars.fit_circle as it was."""

    def residual(x):
        return np.hypot(*(x[:2] - T).T) - rho - x[2]

    def jacobian(x):
        return np.column_stack([pillars._directions(x[:2], T), -np.ones(len(T))])

    x, r = _gauss_newton_loop(residual, jacobian, np.r_[start, 0.1])
    return x[:2], float(x[2]), r


@st.composite
def loci_sets(draw):
    """Loci around a point or a circle, seen from a ring's poses (T = R) or from pairs of
    elements, with range errors from none to centimetres, started near or far off."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    k = draw(st.integers(3, 40))
    target = rng.uniform(-5, 5, 2)
    angle = rng.uniform(0, 2 * np.pi, k)
    T = target + rng.uniform(0.3, 6.0, (k, 1)) * np.stack([np.cos(angle), np.sin(angle)], -1)
    R = T.copy() if draw(st.booleans()) else T + rng.normal(0, 0.05, (k, 2))
    radius = draw(st.sampled_from([0.0, 0.05, 0.3]))
    a = 0.5 * (np.hypot(*(target - T).T) + np.hypot(*(target - R).T)) - radius
    a = a + rng.normal(0, 1, k) * draw(st.sampled_from([0.0, 1e-4, 3e-3, 0.05]))
    start = target + rng.normal(0, 1, 2) * draw(st.sampled_from([0.01, 0.3, 2.0]))
    return T, R, a, start


@settings(max_examples=300, deadline=None)
@given(loci_sets())
def test_the_point_and_circle_fits_are_the_loops(case):
    T, R, a, start = case
    v, r = pillars._point_from(T, R, a, start)
    v0, r0 = _point_from_loop(T, R, a, start)
    assert v.tobytes() == v0.tobytes() and r.tobytes() == r0.tobytes()
    c, radius, r = pillars.fit_circle(T, a, start)
    c0, radius0, r0 = _fit_loop(T, a, start)
    assert c.tobytes() == c0.tobytes() and radius == radius0 and r.tobytes() == r0.tobytes()


def test_a_halving_search_that_never_lowers_the_cost_stops_where_the_loop_does():
    T = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    x0 = np.array([0.3, 0.2])

    def residual(x):  # every step away from x0 raises the cost: the loop halves 30 times
        return (1.0 + np.sum(np.abs(x - x0), axis=-1, keepdims=True)) * np.ones(3)

    def jacobian(x):
        return pillars._directions(x, T)

    x, r = pillars._gauss_newton(residual, jacobian, x0)
    want_x, want_r = _gauss_newton_loop(residual, jacobian, x0)
    assert x.tobytes() == want_x.tobytes() and r.tobytes() == want_r.tobytes()
    assert np.array_equal(x, x0)


def test_halvings_of_a_subnormal_step_round_as_the_loop_rounds():
    step = np.array([3.0 * np.nextafter(np.finfo(np.float64).tiny, 1.0)])
    x = np.zeros(1)

    def residual(v):
        return v * 2.0**1000

    cost = float((step[0] * 2.0**-20 * 2.0**1000) ** 2)
    out = pillars._halved(residual, x, step, cost)
    s = step
    for _ in range(pillars.GN_HALVINGS):  # the loop's halvings, each rounded
        s = 0.5 * s
        if residual(x - s) @ residual(x - s) <= cost:
            break
    assert out is not None and out[0].tobytes() == s.tobytes()
    assert out[1].tobytes() == (x - s).tobytes()


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 200), st.sampled_from([0.3, 1.0, 5.0]))
def test_the_clusters_are_the_loops(seed, n, scale):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-3 * scale, 3 * scale, (max(1, n // 10), 2))
    points = centres[rng.integers(0, len(centres), n)] + rng.normal(0, scale, (n, 2))
    if n and rng.random() < 0.3:  # ties at exactly the reach
        points = np.round(points / CLUSTER_M) * CLUSTER_M
    got, want = pillars._clusters(points), _clusters_loop(points)
    assert len(got) == len(want)
    assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))


def _trace_loop(thin_map, min_cells):
    """curves.trace_curves as it was: each cell's neighbours looked up in a set."""
    t = np.asarray(thin_map, dtype=bool)
    iy, ix = np.nonzero(t)
    cells = set(zip(iy.tolist(), ix.tolist(), strict=True))

    def neighbours(c):
        return [(c[0] + dy, c[1] + dx) for dy, dx in _STEPS if (c[0] + dy, c[1] + dx) in cells]

    node = {c for c in cells if len(neighbours(c)) != 2}
    used: set = set()

    def walk(start, first):
        path = [start, first]
        used.update({(start, first), (first, start)})
        prev, here = start, first
        while here not in node and here != start:
            nxt = [n for n in neighbours(here) if n != prev and (here, n) not in used]
            if not nxt:
                break
            nxt.sort(key=lambda n: abs(n[0] - here[0]) + abs(n[1] - here[1]))
            prev, here = here, nxt[0]
            used.update({(prev, here), (here, prev)})
            path.append(here)
        return path

    out = []
    for start in sorted(node):
        for first in neighbours(start):
            if (start, first) not in used:
                out.append(walk(start, first))
    visited = {c for curve in out for c in curve}
    for start in sorted(cells - visited - node):
        if start in visited:
            continue
        loop = walk(start, neighbours(start)[0])
        visited.update(loop)
        out.append(loop)
    return [np.asarray(c) for c in out if len(c) >= min_cells]


@st.composite
def thin_maps(draw):
    """Sparse random cells, drawn lines and circles (ends, junctions, closed loops)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    ny, nx = draw(st.integers(1, 60)), draw(st.integers(1, 60))
    m = rng.random((ny, nx)) < draw(st.sampled_from([0.0, 0.02, 0.1, 0.3]))
    for _ in range(draw(st.integers(0, 4))):
        y0, x0, y1, x1 = rng.integers(0, [ny, nx, ny, nx])
        n = max(abs(y1 - y0), abs(x1 - x0)) + 1
        m[np.round(np.linspace(y0, y1, n)).astype(int),
          np.round(np.linspace(x0, x1, n)).astype(int)] = True
    if draw(st.booleans()):
        r = rng.uniform(2, 20)
        phi = np.linspace(0, 2 * math.pi, 400)
        y = np.round(ny / 2 + r * np.sin(phi)).astype(int)
        x = np.round(nx / 2 + r * np.cos(phi)).astype(int)
        ok = (y >= 0) & (y < ny) & (x >= 0) & (x < nx)
        m[y[ok], x[ok]] = True
    return m


@settings(max_examples=300, deadline=None)
@given(thin_maps(), st.sampled_from([1, 5]))
def test_the_traced_curves_are_the_loops(thin, min_cells):
    got, want = curves.trace_curves(thin, min_cells), _trace_loop(thin, min_cells)
    assert len(got) == len(want)
    assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))


def _neighbours_loop(s, groups, i, max_bias_m):
    """tangents._neighbours as it was, one locus at a time."""
    others = np.flatnonzero((groups == groups[i]) & (np.arange(len(s.loci)) > i))
    if len(others) == 0 or not s.inside[i].any():
        return others[:0]
    reach = np.sqrt(8.0 * s.a[i] * max_bias_m)
    return others[np.hypot(*(s.centre[others] - s.centre[i]).T) <= reach]


def _crossings_loop(s, i, others):
    """tangents._crossings as it was, one locus at a time."""
    def residual(q, others):
        return (np.hypot(*(q[None] - s.T[others, None]).transpose(2, 0, 1))
                + np.hypot(*(q[None] - s.R[others, None]).transpose(2, 0, 1))
                - 2 * s.a[others, None])

    pi = s.p[i]
    steps = np.flatnonzero(s.inside[i] & np.roll(s.inside[i], -1))
    if len(steps) == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    g_here = residual(pi[steps], others)
    g_next = residual(pi[(steps + 1) % LOCUS_SAMPLES], others)
    j, m = np.nonzero(np.sign(g_here) != np.sign(g_next))
    k = steps[m]
    t = g_here[j, m] / (g_here[j, m] - g_next[j, m])
    return pi[k] + t[:, None] * (pi[(k + 1) % LOCUS_SAMPLES] - pi[k]), k, others[j]


@st.composite
def sampled_loci(draw):
    """Loci round a few centres with runs of in-beam samples (some wrapping round sample
    0, some empty or full), in a few viewpoint groups."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(0, 40))
    T = rng.uniform(-1, 1, (n, 2))
    R = np.where(rng.random((n, 1)) < 0.5, T, T + rng.normal(0, 0.1, (n, 2)))
    a = 0.5 * np.hypot(*(R - T).T) + rng.uniform(0.2, 1.5, n)
    phi = 2 * np.pi * np.arange(LOCUS_SAMPLES) / LOCUS_SAMPLES
    centre = 0.5 * (T + R)
    p = centre[:, None] + a[:, None, None] * np.stack([np.cos(phi), np.sin(phi)], -1)
    start, width = rng.integers(0, LOCUS_SAMPLES, n), rng.integers(0, 300, n)
    width[rng.random(n) < 0.05] = LOCUS_SAMPLES
    inside = ((np.arange(LOCUS_SAMPLES)[None] - start[:, None]) % LOCUS_SAMPLES) < width[:, None]
    loci = Loci(tx=np.arange(n), rx=np.arange(n), tof_s=np.zeros(n), amplitude=np.ones(n))
    s = SampledLoci(loci, p, inside, a, T, R, centre, np.tile([1.0, 0.0], (n, 1)), 0.05)
    return s, rng.integers(0, draw(st.integers(1, 4)), n), draw(st.sampled_from([0.002, 0.05, 0.3]))


@settings(max_examples=150, deadline=None)
@given(sampled_loci())
def test_the_crossings_of_all_pairs_are_the_loops(case):
    s, groups, bias = case
    n = len(s.a)
    mine, other = tangents._neighbour_pairs(s, groups, 0, n, bias)
    want = [_neighbours_loop(s, groups, i, bias) for i in range(n)]
    assert np.array_equal(other, np.concatenate([np.zeros(0, np.int64), *want]))
    assert np.array_equal(mine, np.repeat(np.arange(n), [len(w) for w in want]))
    q, k, owner, b = tangents._pair_crossings(s, mine, other)
    for i in range(n):
        q0, k0, b0 = _crossings_loop(s, i, want[i])
        assert q[owner == i].tobytes() == q0.tobytes()
        assert np.array_equal(k[owner == i], k0) and np.array_equal(b[owner == i], b0)


def _curves_in_metres_loop(linked, extent, cell, settings, weights, counts, sums):
    """profile._curves_in_metres as it was, curve by curve."""
    out = []
    for c in linked:
        if settings.subcell and counts is not None and sums is not None:
            refined = curves.refine_to_points(c, counts, sums)
            if refined is not None:
                out.append(refined)
            continue
        if settings.subcell and weights is not None:
            c = curves.refine_cells(c, weights)
        out.append(cell_centres(extent, cell, c[:, 0], c[:, 1]))
    return out


def _bound_loop(prof, occupied, extent, cell, origin, max_gap, near):
    """profile.bound_profile as it was, curve by curve."""
    out = []
    for c in prof.curves:
        inside = profile._inside(c, extent)
        keep = inside & profile._near_occupied(c, occupied, extent, cell, origin, near)
        if profile._closed(c) and keep.any() and not keep.all():
            start = int(np.flatnonzero(keep & ~np.roll(keep, 1))[0])
            c, keep, inside = (np.roll(a, -start, axis=0) for a in (c, keep, inside))
        keep |= inside & profile._bridged(c, keep, max_gap, prof.vertices, cell)
        cuts = np.flatnonzero(np.diff(keep.astype(np.int8)) != 0) + 1
        for piece, kept in zip(np.split(c, cuts), np.split(keep, cuts), strict=True):
            if kept[0]:
                out.append(piece)
    return out


@settings(max_examples=100, deadline=None)
@given(thin_maps(), st.integers(0, 2**32 - 1), st.sampled_from(["points", "weights", "none"]))
def test_the_curves_in_metres_and_their_bounds_are_the_loops(thin, seed, refine):
    rng = np.random.default_rng(seed)
    linked = curves.trace_curves(thin, 1)
    ny, nx = thin.shape
    extent, cell = (-0.3, 0.2, -0.3 + nx * 0.01, 0.2 + ny * 0.01), 0.01
    counts = np.where(rng.random(thin.shape) < 0.5, rng.integers(0, 4, thin.shape), 0) * thin
    sums = counts[..., None] * (cell_centres(extent, cell, *np.indices(thin.shape))
                                + rng.normal(0, 0.002, (ny, nx, 2)))
    weights = rng.random(thin.shape) * thin
    args = (extent, cell, PostSettings(subcell=refine != "none"),
            weights if refine == "weights" else None,
            counts if refine == "points" else None, sums if refine == "points" else None)
    got, want = profile._curves_in_metres(linked, *args), _curves_in_metres_loop(linked, *args)
    assert len(got) == len(want)
    assert all(g.tobytes() == w.tobytes() for g, w in zip(got, want, strict=True))
    prof = Profile(tuple(want), rng.uniform(-0.3, 0.3, (int(rng.integers(0, 3)), 2)))
    occupied = rng.random(thin.shape) < 0.3
    bound = profile.bound_profile(prof, occupied, extent, cell, (0, 0), 0.05)
    want = _bound_loop(prof, occupied, extent, cell, (0, 0), 0.05, profile.NEAR_CELLS)
    assert len(bound.curves) == len(want)
    assert all(g.tobytes() == w.tobytes() for g, w in zip(bound.curves, want, strict=True))
