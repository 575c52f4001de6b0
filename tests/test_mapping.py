"""The map (clsonar/mapping/, kernels/accumulate.cl): the OpenCL kernels against the NumPy
float64 reference, and both against an independent float64 model of the loci (thesis §2.1.1,
parts 3–4), on PoCL's CPU device."""

from __future__ import annotations

import dataclasses
import functools
import math
import time
import typing
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsonar.mapping as mapping
import clsonar.mapping.launch as map_launch
import clsonar.mapping.tangents as map_tangents
from clsonar import physics
from clsonar.errors import ClsonarError
from clsonar.mapping import (
    Loci,
    accumulate,
    accumulate_reference,
    backproject,
    backproject_reference,
)
from clsonar.opencl import get_context, has_fp64
from clsonar.scene import MappingSettings, Scene, TransducerModel
from clsonar.sensors import SensorArray

EPS32 = float(np.finfo(np.float32).eps)


@functools.cache
def context():
    return get_context()


def kernel_map(scene, sensors, loci, precision, **kw):
    if precision == "float64" and not has_fp64(context()):
        pytest.skip("the OpenCL device has no cl_khr_fp64")
    return accumulate(scene, sensors, loci, context=context(), precision=precision, **kw)


def kernel_backprojection(scene, sensors, pairs, env, dt, precision, **kw):
    if precision == "float64" and not has_fp64(context()):
        pytest.skip("the OpenCL device has no cl_khr_fp64")
    return backproject(scene, sensors, pairs, env, dt, context=context(), precision=precision,
                       **kw)


def make_scene(extent=(0.0, 0.0, 2.0, 1.5), cell=0.01, *, weight="unit", band_m=None,
               half_beam_deg=12.0) -> Scene:
    return Scene(name="map-test", extent=extent, cell=cell,
                 transducer=TransducerModel(half_beam_deg=half_beam_deg),
                 mapping=MappingSettings(weight=weight, band_m=band_m))


def make_sensors(*transducers) -> SensorArray:
    """Transducers ``(x, y, heading_deg)``."""
    t = np.asarray(transducers, dtype=np.float64).reshape(-1, 3)
    return SensorArray(t[:, :2].copy(), t[:, 2].copy(), np.zeros(len(t), dtype=np.int64),
                       np.zeros((0, 2)))


def make_loci(rows) -> Loci:
    """Rows ``(tx, rx, path length c·τ in m, amplitude)`` at the default speed of sound."""
    r = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    c = make_scene().medium.c
    return Loci(r[:, 0].astype(np.int64), r[:, 1].astype(np.int64), r[:, 2] / c, r[:, 3].copy())


# --------------------------------------------------------------------------- independent model


def cell_grid(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres [ny, nx] by docs/design.md's convention, in scene coordinates."""
    ny, nx = scene.grid_shape
    xmin, ymin = scene.extent[:2]
    x = xmin + (np.arange(nx) + 0.5) * scene.cell
    y = ymin + (np.arange(ny) + 0.5) * scene.cell
    return np.meshgrid(x, y)


def beam_geometry(scene: Scene):
    t = scene.transducer
    c = scene.medium.c
    ka = physics.wavenumber(t.frequency_hz, c) * t.radius_m
    cut = physics.beam_cut_sin2(t.frequency_hz, t.radius_m, t.half_beam_deg, c)
    return ka, cut


def model_rows(scene: Scene, sensors: SensorArray, loci: Loci, settings=None):
    """Per locus row, in float64 and scene coordinates: the vote mask, the vote's weight,
    the distance of each pixel's path length error from the band edge (m), its distance from
    the nearest beam edge (m), and the size of the coordinates the float32 kernel sees."""
    settings = settings or scene.mapping
    X, Y = cell_grid(scene)
    ka, cut = beam_geometry(scene)
    sin_c, cos_c = math.sqrt(cut), math.sqrt(1.0 - cut)
    band = settings.band_m if settings.band_m is not None else 2.0 * math.sqrt(2.0) * scene.cell
    origin = np.asarray(mapping.map_grid(scene).origin)
    pixel_scale = np.hypot(X - origin[0], Y - origin[1])
    out = []
    for tx, rx, tof, amp in zip(loci.tx, loci.rx, loci.tof_s, loci.amplitude, strict=True):
        inside = np.ones(X.shape, dtype=bool)
        weight = np.ones(X.shape)
        edge = np.full(X.shape, np.inf)
        dist = []
        scale = pixel_scale.copy()
        for i in (tx, rx):
            px, py = sensors.positions[i]
            h = math.radians(sensors.headings_deg[i])
            ax, ay = math.cos(h), math.sin(h)
            dx, dy = X - px, Y - py
            r = np.hypot(dx, dy)
            cos_t = ax * dx + ay * dy
            sin_t = ax * dy - ay * dx
            inside &= (cos_t > 0) & (sin_t**2 <= cut * r**2)
            with np.errstate(divide="ignore", invalid="ignore"):
                b = physics.beam_pattern(cos_t / r, sin_t / r, ka, cut)
            weight *= np.where(r > 0, b, 0.0)
            edge = np.minimum(edge, np.abs(np.abs(sin_t) * cos_c - cos_t * sin_c))
            dist.append(r)
            scale = np.maximum(scale, math.hypot(px - origin[0], py - origin[1]))
        path = scene.medium.c * tof
        err = dist[0] + dist[1] - path
        vote = inside & (np.abs(err) <= band / 2)
        if settings.weight == "unit":
            weight = np.ones(X.shape)
        elif settings.weight == "amplitude":
            weight = np.full(X.shape, amp)
        out.append(SimpleNamespace(
            vote=vote, weight=weight, band_edge=np.abs(np.abs(err) - band / 2), beam_edge=edge,
            scale=scale, path=abs(path), near=np.minimum(dist[0], dist[1])))
    return out


def model_map(rows) -> np.ndarray:
    return sum((np.where(r.vote, r.weight, 0.0) for r in rows), np.zeros(rows[0].vote.shape))


def on_edge(rows, ulps: float, atol: float = 0.0) -> np.ndarray:
    """Pixels within ``ulps`` float32 roundings (of the coordinates the kernel sees and of
    the path length), or ``atol`` metres, of some row's band edge or beam edge."""
    edge = np.zeros(rows[0].vote.shape, dtype=bool)
    for r in rows:
        tol = ulps * EPS32 * (r.scale + r.path) + atol
        edge |= (r.band_edge <= tol) | (r.beam_edge <= ulps * EPS32 * r.scale + atol)
    return edge


def value_tolerance(rows, weight: str) -> np.ndarray:
    """How far a float32 sum may be from the float64 one when every vote agrees."""
    tol = np.zeros(rows[0].vote.shape)
    for r in rows:
        if weight == "beam":
            # the series in float32, and θ from coordinates rounded at the map's scale
            term = 4e-6 + 64 * EPS32 * r.scale / np.maximum(r.near, 1e-300)
        else:
            term = 4 * EPS32 * (np.abs(r.weight) + 1.0)
        tol += np.where(r.vote, term, 0.0)
    return tol + 1e-12


# --------------------------------------------------------------------------- property test


@st.composite
def map_cases(draw):
    """A map 40–120 cells a side whose last cells are partial, anywhere in ±500 m; 1–4
    transducers in and around it, each aimed near a point of the map or with a pixel centre
    exactly on its beam's edge; 1–6 loci (T = R or not) through a point of the map or with a
    pixel centre exactly on the band's edge (so that float32 rounding has edges to decide).
    Returns the scene, sensors, loci and the number of edges put on pixel centres."""
    cell = draw(st.floats(0.004, 0.05))
    nx, ny = draw(st.integers(40, 120)), draw(st.integers(40, 120))
    fx, fy = draw(st.floats(0.05, 0.95)), draw(st.floats(0.05, 0.95))  # partial last cells
    x0, y0 = draw(st.floats(-500.0, 500.0)), draw(st.floats(-500.0, 500.0))
    width, height = (nx - 1 + fx) * cell, (ny - 1 + fy) * cell
    weight = draw(st.sampled_from(mapping.WEIGHTS))
    band = draw(st.one_of(st.none(), st.floats(0.3, 3.0).map(lambda f: f * cell)))
    half_beam = draw(st.sampled_from([12.0, 5.0, 20.0, 40.0]))
    scene = make_scene((x0, y0, x0 + width, y0 + height), cell, weight=weight, band_m=band,
                       half_beam_deg=half_beam)
    half_cut = math.degrees(math.asin(math.sqrt(beam_geometry(scene)[1])))
    unit = st.floats(-0.2, 1.2)

    def point():
        return (x0 + draw(unit) * width, y0 + draw(unit) * height)

    def pixel_centre():
        ix, iy = draw(st.integers(0, nx - 1)), draw(st.integers(0, ny - 1))
        return (x0 + (ix + 0.5) * cell, y0 + (iy + 0.5) * cell)

    transducers = []
    seeded = 0
    for _ in range(draw(st.integers(1, 4))):
        px, py = point()
        on_cut = draw(st.booleans())
        seeded += on_cut
        tx, ty = pixel_centre() if on_cut else point()
        aim = math.degrees(math.atan2(ty - py, tx - px)) if (tx, ty) != (px, py) else 0.0
        if on_cut:
            aim += draw(st.sampled_from([-half_cut, half_cut]))
        else:
            aim += draw(st.floats(-20.0, 20.0))
        transducers.append((px, py, aim))
    sensors = make_sensors(*transducers)
    half_band = (band if band is not None else 2.0 * math.sqrt(2.0) * cell) / 2
    rows = []
    for _ in range(draw(st.integers(1, 6))):
        t = draw(st.integers(0, len(transducers) - 1))
        r = t if draw(st.booleans()) else draw(st.integers(0, len(transducers) - 1))
        on_band_edge = draw(st.booleans())
        seeded += on_band_edge
        qx, qy = pixel_centre() if on_band_edge else point()
        path = (math.hypot(qx - transducers[t][0], qy - transducers[t][1])
                + math.hypot(qx - transducers[r][0], qy - transducers[r][1]))
        if on_band_edge:
            path += draw(st.sampled_from([-half_band, half_band]))
        else:
            path += draw(st.floats(-2.0, 2.0)) * cell
        rows.append((t, r, path, draw(st.floats(0.1, 5.0))))
    return scene, sensors, make_loci(rows), seeded


@settings(max_examples=120, deadline=None)
@given(map_cases())
def test_kernels_match_reference_and_model(case):
    scene, sensors, loci, seeded = case
    ref = accumulate_reference(scene, sensors, loci)
    assert ref.shape == scene.grid_shape and ref.dtype == np.float64
    rows = model_rows(scene, sensors, loci)
    weight = scene.mapping.weight

    # The reference is the model: every pixel agrees but within float64 rounding of an edge.
    model = model_map(rows)
    differ = np.abs(ref - model) > 1e-9 * (1.0 + np.abs(model))
    far = max(map(abs, scene.extent))  # the model works in scene coordinates
    assert not np.any(differ & ~on_edge(rows, 0, 1e-13 * (far + 10))), "reference ≠ model"

    k64 = kernel_map(scene, sensors, loci, "float64")
    assert k64.dtype == np.float64 and np.array_equal(k64, ref)

    k32 = kernel_map(scene, sensors, loci, "float32")
    assert k32.dtype == np.float32 and k32.shape == ref.shape
    assert np.all(np.isfinite(k32))
    differ = np.abs(k32.astype(np.float64) - ref) > value_tolerance(rows, weight)
    # ≥ 99.9 % equal, besides the pixels put on an edge on purpose
    assert np.count_nonzero(differ) <= 1e-3 * ref.size + seeded
    off_edge = differ & ~on_edge(rows, 4)
    assert not np.any(off_edge), (
        f"float32 differs off the edges at {np.argwhere(off_edge)[:5].tolist()}: "
        f"{k32[off_edge][:5]} vs {ref[off_edge][:5]}")


def test_float32_equals_float64_on_a_thesis_sized_map():
    """10 m × 10 m at 1 cm (thesis §2.1), 20 transducers facing a wall, 300 echoes."""
    if not has_fp64(context()):
        pytest.skip("the OpenCL device has no cl_khr_fp64")
    scene = make_scene((0.0, 0.0, 10.0, 10.0), 0.01, weight="amplitude")
    rng = np.random.default_rng(7)
    ys = np.sort(rng.uniform(1.0, 9.0, 20))
    sensors = make_sensors(*[(rng.uniform(1.0, 2.0), y, rng.uniform(-20, 20)) for y in ys])
    tx, rx = rng.integers(0, 20, 300), rng.integers(0, 20, 300)
    rx[:60] = tx[:60]
    wall = np.stack([np.full(300, 9.0), rng.uniform(0.0, 10.0, 300)], axis=1)
    path = (np.linalg.norm(wall - sensors.positions[tx], axis=1)
            + np.linalg.norm(wall - sensors.positions[rx], axis=1))
    loci = Loci(tx, rx, path / scene.medium.c, rng.uniform(0.5, 5.0, 300))
    k64 = kernel_map(scene, sensors, loci, "float64")
    k32 = kernel_map(scene, sensors, loci, "float32")
    assert k64.shape == (1000, 1000) and np.count_nonzero(k64) > 5000
    differ = np.abs(k32 - k64) > 4 * EPS32 * (np.abs(k64) + 30)
    assert np.count_nonzero(differ) <= 1e-3 * k64.size
    # every differing pixel is within a few float32 roundings of some locus' edge
    ys_, xs_ = np.nonzero(differ)
    sub = SimpleNamespace(tx=tx, rx=rx, tof_s=loci.tof_s, amplitude=loci.amplitude)
    for iy, ix in zip(ys_, xs_, strict=True):
        pixel = make_scene((ix * 0.01, iy * 0.01, (ix + 1) * 0.01, (iy + 1) * 0.01), 0.01,
                           weight="amplitude")
        rows = model_rows(pixel, sensors, sub)
        for r in rows:  # the kernel's coordinates are relative to the big map's middle
            r.scale = np.maximum(r.scale, 7.1)
        assert on_edge(rows, 4)[0, 0], (iy, ix)


# --------------------------------------------------------------------------- geometry


def test_grid_origin_follows_the_cell_convention():
    scene = make_scene((-3.0, 2.0, 0.105, 2.777), 0.01)
    g = mapping.map_grid(scene)
    ny, nx = scene.grid_shape
    assert (g.ny, g.nx) == (ny, nx) == (78, 311)
    x, y = mapping.cell_centres(scene)
    assert np.allclose(g.origin[0] + (g.col0 + np.arange(nx)) * g.cell, x, atol=1e-12)
    assert np.allclose(g.origin[1] + (g.row0 + np.arange(ny)) * g.cell, y, atol=1e-12)
    assert -nx < g.col0 <= 0 and -ny < g.row0 <= 0


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_monostatic_locus_is_a_ring_arc_within_the_half_beam(precision):
    scene = make_scene((0.0, 0.0, 3.0, 3.0), 0.01)
    T = (0.4, 0.6)
    heading = 30.0
    radius = 1.7
    sensors = make_sensors((*T, heading))
    m = kernel_map(scene, sensors, make_loci([(0, 0, 2 * radius, 1.0)]), precision)
    X, Y = cell_grid(scene)
    r = np.hypot(X - T[0], Y - T[1])
    angle = np.degrees(np.arctan2(Y - T[1], X - T[0])) - heading
    band = 2.0 * math.sqrt(2.0) * scene.cell
    voted = m > 0
    assert np.all(m[voted] == 1.0)
    # |2r − 2·radius| ≤ band/2: a ring of half-width band/4 around the radius ...
    assert np.all(np.abs(r[voted] - radius) <= band / 4 + 1e-6)
    # ... limited to ±12° around the axis, and all of it
    assert np.all(np.abs(angle[voted]) <= 12.0 + 1e-6)
    assert np.abs(angle[voted]).max() > 11.5
    clearly_in = (np.abs(r - radius) < band / 4 - 1e-4) & (np.abs(angle) < 12.0 - 0.01)
    assert np.all(voted[clearly_in])
    # pixels along the axis, checked by hand: each votes iff its centre's distance is
    # within band/4 of the radius
    ax, ay = math.cos(math.radians(heading)), math.sin(math.radians(heading))
    checked = []
    for k in range(-6, 7):
        dist = radius + k * scene.cell / 3
        ix = int((T[0] + dist * ax) / scene.cell)
        iy = int((T[1] + dist * ay) / scene.cell)
        centre_r = math.hypot((ix + 0.5) * scene.cell - T[0], (iy + 0.5) * scene.cell - T[1])
        if abs(abs(centre_r - radius) - band / 4) > 1e-6:
            assert m[iy, ix] == float(abs(centre_r - radius) <= band / 4), (k, centre_r)
            checked.append(m[iy, ix])
    assert 0.0 in checked and 1.0 in checked
    # the arc is 2·radius·12° long and band/2 thick (the path length changes twice as fast
    # as the distance): about that area in pixels
    area = 2 * radius * math.radians(12.0) * band / 2
    assert 0.7 * area < voted.sum() * scene.cell**2 < 1.3 * area


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_bistatic_locus_is_an_ellipse_arc_with_foci_at_the_transducers(precision):
    scene = make_scene((0.0, 0.0, 3.0, 3.0), 0.01, half_beam_deg=20.0)  # cut at the null
    half_beam = math.degrees(math.asin(math.sqrt(beam_geometry(scene)[1])))
    assert 12.0 < half_beam < 12.2
    T, R = (0.5, 1.2), (0.5, 1.5)
    path = 3.4  # major axis; foci 0.3 m apart
    sensors = make_sensors((*T, 0.0), (*R, 0.0))
    m = kernel_map(scene, sensors, make_loci([(0, 1, path, 1.0)]), precision)
    X, Y = cell_grid(scene)
    err = np.hypot(X - T[0], Y - T[1]) + np.hypot(X - R[0], Y - R[1]) - path
    voted = m > 0
    band = 2.0 * math.sqrt(2.0) * scene.cell
    assert voted.sum() > 20
    assert np.all(np.abs(err[voted]) <= band / 2 + 1e-6)
    # pixels by hand: the minor axis' vertex (the foci's midpoint + b along the beams) is on
    # the locus; the point at the semi-major axis a there, where a circle around the
    # midpoint would be, is not (|p − T| + |p − R| = 2·sqrt(a² + f²) > 2a)
    a, f = path / 2, 0.15
    for x, expected in ((0.5 + math.sqrt(a**2 - f**2), None), (0.5 + a + 0.01, 0.0)):
        ix, iy = int(x / scene.cell), int(1.3499 / scene.cell)
        xc, yc = (ix + 0.5) * scene.cell, (iy + 0.5) * scene.cell
        e = math.hypot(xc - T[0], yc - T[1]) + math.hypot(xc - R[0], yc - R[1]) - path
        assert m[iy, ix] == float(abs(e) <= band / 2)
        if expected is not None:
            assert m[iy, ix] == expected
    # every pixel clearly inside the band and both beams votes
    inside = np.ones(X.shape, dtype=bool)
    for (px, py) in (T, R):
        inside &= np.abs(np.degrees(np.arctan2(Y - py, X - px))) < half_beam - 0.01
    assert np.all(voted[(np.abs(err) < band / 2 - 1e-4) & inside])


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_votes_add_up_over_loci_and_launch_blocks(precision, monkeypatch):
    scene = make_scene((0.0, 0.0, 2.0, 2.0), 0.02, weight="amplitude")
    sensors = make_sensors((0.2, 1.0, 0.0), (0.25, 1.1, -5.0), (0.3, 0.9, 10.0))
    rows = [(0, 0, 2.0, 1.5), (0, 1, 2.1, 0.5), (1, 2, 2.4, 2.0), (2, 2, 2.0, 4.0),
            (1, 1, 2.2, 1.0), (2, 0, 3.0, 0.25), (0, 0, 2.0, 1.0)]
    whole = kernel_map(scene, sensors, make_loci(rows), precision)
    parts = sum(kernel_map(scene, sensors, make_loci([r]), precision).astype(np.float64)
                for r in rows)
    assert np.allclose(whole, parts, rtol=1e-6, atol=0)
    # the first and last rows draw the same ring: its pixels get 1.5 + 1.0 from them
    ring = kernel_map(scene, sensors, make_loci([rows[0]]), precision) > 0
    assert np.all(whole[ring] >= 2.5 - 1e-6)
    # blocks of loci per launch do not change the sum, to the bit
    monkeypatch.setattr(map_launch, "MAX_ROWS_PER_LAUNCH", 3)
    assert np.array_equal(kernel_map(scene, sensors, make_loci(rows), precision), whole)


def test_unit_amplitude_and_beam_weights():
    scene = make_scene((0.0, 0.0, 2.0, 2.0), 0.01, band_m=0.03)
    sensors = make_sensors((0.2, 1.0, 0.0), (0.3, 1.05, 0.0))
    loci = make_loci([(0, 1, 2.5, 3.0)])
    maps = {w: kernel_map(scene, sensors, loci, "float32",
                          settings=MappingSettings(weight=w, band_m=0.03))
            for w in mapping.WEIGHTS}
    voted = maps["unit"] > 0
    assert voted.sum() > 50
    assert np.all(maps["amplitude"][voted] == 3.0) and np.all(maps["amplitude"][~voted] == 0)
    b = maps["beam"]
    assert np.all((b[voted] > 0) & (b[voted] <= 1.0)) and np.all(b[~voted] == 0)
    # on the axes' direction the beams are near their peak, towards the edges they fall
    assert b.max() > 0.9 and b[voted].min() < 0.3
    rows = model_rows(scene, sensors, loci, MappingSettings(weight="beam", band_m=0.03))
    assert np.allclose(b, model_map(rows), atol=1e-5)


@pytest.mark.parametrize("weight", mapping.WEIGHTS)
def test_degenerate_loci_give_finite_maps(weight):
    """A transducer on a pixel centre, τ = 0, a locus far outside the map, T on R's axis."""
    scene = make_scene((0.0, 0.0, 1.0, 1.0), 0.02, weight=weight)
    sensors = make_sensors((0.51, 0.51, 0.0), (0.51, 0.51, 180.0), (0.11, 0.51, 0.0))
    loci = make_loci([(0, 0, 0.0, 1.0), (0, 1, 0.0, 1.0), (1, 1, 0.01, 1.0),
                      (0, 0, 1e4, 1.0), (2, 0, 0.4, 1.0), (2, 2, 0.8, 1.0), (0, 2, 1e-3, 1.0)])
    for precision in ("float32", "float64"):
        m = kernel_map(scene, sensors, loci, precision)
        assert np.all(np.isfinite(m)) and np.all(m >= 0)
    ref = accumulate_reference(scene, sensors, loci)
    assert np.all(np.isfinite(ref))
    assert np.array_equal(kernel_map(scene, sensors, loci, "float64"), ref)


def test_any_table_with_the_four_columns_will_do():
    scene = make_scene((0.0, 0.0, 1.0, 1.0), 0.02)
    sensors = make_sensors((0.1, 0.5, 0.0))
    loci = make_loci([(0, 0, 1.2, 2.0)])
    table = SimpleNamespace(tx=list(loci.tx), rx=loci.rx.astype(np.int32), tof_s=loci.tof_s,
                            amplitude=loci.amplitude, kind=np.zeros(1))
    assert np.array_equal(kernel_map(scene, sensors, table, "float32"),
                          kernel_map(scene, sensors, loci, "float32"))
    empty = Loci(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    m = kernel_map(scene, sensors, empty, "float32")
    assert m.shape == scene.grid_shape and m.dtype == np.float32 and not m.any()
    assert not accumulate_reference(scene, sensors, empty).any()


def test_bad_loci_are_refused():
    scene = make_scene((0.0, 0.0, 1.0, 1.0), 0.02)
    sensors = make_sensors((0.1, 0.5, 0.0))
    with pytest.raises(ValueError, match="sensor indices"):
        accumulate_reference(scene, sensors, make_loci([(0, 1, 1.0, 1.0)]))
    bad = Loci(np.zeros(1, np.int64), np.zeros(1, np.int64), np.array([np.nan]), np.ones(1))
    with pytest.raises(ValueError, match="finite"):
        kernel_map(scene, sensors, bad, "float32")
    with pytest.raises(ValueError, match="one length"):
        accumulate_reference(scene, sensors, SimpleNamespace(
            tx=[0], rx=[0, 0], tof_s=[0.01], amplitude=[1.0]))
    with pytest.raises(TypeError, match="tof_s"):
        accumulate_reference(scene, sensors, SimpleNamespace(tx=[0], rx=[0]))
    with pytest.raises(ValueError, match="precision"):
        accumulate(scene, sensors, make_loci([(0, 0, 1.0, 1.0)]), context=context(),
                   precision="float16")


# float16 vectors are wider than AVX2: PoCL's compiler warns about their calling convention
@pytest.mark.filterwarnings("ignore::pyopencl.CompilerWarning")
@pytest.mark.parametrize("vec, group", [(1, (64, 2)), (2, (8, 4)), (4, (16, 1)),
                                        (16, (4, 1))])
def test_every_vector_width_computes_the_same_map(vec, group, monkeypatch):
    """GPUs run one pixel per work item (vec 1): the same code path, checked here on PoCL."""
    scene = make_scene((0.0, 0.0, 1.03, 0.77), 0.01, weight="beam")
    sensors = make_sensors((0.05, 0.4, 0.0), (0.1, 0.35, 10.0), (0.51, 0.51, -20.0))
    loci = make_loci([(0, 0, 1.2, 1.0), (0, 1, 1.3, 2.0), (1, 2, 0.6, 1.0), (2, 2, 0.5, 1.0),
                      (2, 2, 0.0, 1.0)])
    pairs = np.array([(0, 0), (0, 1), (1, 2), (2, 2)])
    env = np.random.default_rng(3).random((len(pairs), 400))
    dt = 2e-5
    runs = {}
    for label, launch in (("default", None), ("vec", (vec, group))):
        if launch is not None:  # (doubles wider than 4 do not fit an AVX2 register)
            monkeypatch.setitem(mapping.LAUNCH, ("CPU", "float32"), launch)
            monkeypatch.setitem(mapping.LAUNCH, ("CPU", "float64"), (min(vec, 4), group))
        for precision in ("float32", "float64"):
            runs[label, precision] = (
                kernel_map(scene, sensors, loci, precision),
                kernel_backprojection(scene, sensors, pairs, env, dt, precision,
                                      settings=MappingSettings(weight="beam")))
    assert np.count_nonzero(runs["vec", "float32"][0]) > 20
    for precision in ("float32", "float64"):
        for a, b in zip(runs["default", precision], runs["vec", precision], strict=True):
            assert np.array_equal(a, b)
    assert np.array_equal(runs["vec", "float64"][0], accumulate_reference(scene, sensors, loci))


# --------------------------------------------------------------------------- memory


def test_a_map_too_large_for_memory_is_refused_up_front():
    scene = make_scene((0.0, 0.0, 100.0, 100.0), 1e-5)  # 1e7 × 1e7 cells: 400 TB in float32
    sensors = make_sensors((1.0, 1.0, 0.0))
    loci = make_loci([(0, 0, 1.0, 1.0)])
    start = time.perf_counter()
    with pytest.raises(ClsonarError, match="10000000 × 10000000 cells") as err:
        accumulate(scene, sensors, loci, context=context())
    message = str(err.value)
    assert "needs 400 TB" in message and "larger cell" in message, message
    with pytest.raises(ClsonarError, match="needs"):
        accumulate_reference(scene, sensors, loci)
    with pytest.raises(ClsonarError, match="needs"):
        backproject(scene, sensors, [[0, 0]], np.zeros((1, 4)), 1e-5, context=context())
    # more cells along one side than float32 indexes exactly
    wide = make_scene((0.0, 0.0, 2e3, 0.01), 1e-4)
    with pytest.raises(ClsonarError, match="cells along x"):
        accumulate(wide, sensors, loci, context=context())
    assert time.perf_counter() - start < 5.0


def test_memory_check_passes_a_thesis_sized_map():
    scene = make_scene((0.0, 0.0, 10.0, 10.0), 0.01)
    assert scene.grid_shape == (1000, 1000)
    mapping.check_map_memory(scene, "float32", context().devices[0])


# --------------------------------------------------------------------------- back-projection


def random_backprojection(seed: int):
    rng = np.random.default_rng(seed)
    scene = make_scene((-1.0, 2.0, 1.37, 3.61), 0.023, half_beam_deg=25.0)
    sensors = make_sensors(*[(rng.uniform(-1.2, -0.8), rng.uniform(2.0, 3.6),
                              rng.uniform(-30, 30)) for _ in range(3)])
    pairs = np.array([(t, r) for t in range(3) for r in range(3)])
    dt = 2e-5
    n = 800
    t = np.arange(n) * dt
    centres = rng.uniform(0, n * dt, (len(pairs), 3))
    env = np.exp(-((t[None, None, :] - centres[..., None]) / 1e-4) ** 2 / 2).sum(axis=1)
    return scene, sensors, pairs, env, dt


@pytest.mark.parametrize("weight", ["unit", "beam"])
@pytest.mark.parametrize("seed", [0, 1])
def test_backprojection_kernels_match_reference(weight, seed):
    scene, sensors, pairs, env, dt = random_backprojection(seed)
    st_ = MappingSettings(mode="backprojection", weight=weight)
    ref = backproject_reference(scene, sensors, pairs, env, dt, settings=st_)
    assert ref.shape == scene.grid_shape and np.count_nonzero(ref) > 100
    k64 = kernel_backprojection(scene, sensors, pairs, env, dt, "float64", settings=st_)
    assert np.array_equal(k64, ref)
    k32 = kernel_backprojection(scene, sensors, pairs, env, dt, "float32", settings=st_)
    assert k32.dtype == np.float32 and np.all(np.isfinite(k32))
    # a delay of t samples is off by a few float32 roundings of t; the envelopes' slope is
    # at most 0.61·dt/σ per sample (Gaussians of σ = 100 µs)
    t_max = np.hypot(*np.ptp(np.concatenate([sensors.positions, [scene.extent[:2],
                                                                scene.extent[2:]]]), axis=0))
    t_max *= 2 / (scene.medium.c * dt)
    tol = len(pairs) * (8 * EPS32 * t_max * 0.61 * dt / 1e-4 * 3 + 1e-5)
    close = np.abs(k32 - ref) <= tol
    assert np.count_nonzero(~close) <= 1e-3 * ref.size
    # whatever differs more is on a beam edge (a pair's term is there or not)
    rows = model_rows(scene, sensors, Loci(pairs[:, 0], pairs[:, 1], np.zeros(len(pairs)),
                                           np.ones(len(pairs))))
    beam_edge = np.zeros(ref.shape, dtype=bool)
    for r in rows:
        beam_edge |= r.beam_edge <= 16 * EPS32 * r.scale
    assert not np.any(~close & ~beam_edge)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_backprojection_peaks_on_the_ellipse_and_at_the_reflector(precision):
    scene = make_scene((0.0, 0.0, 2.0, 2.0), 0.01, half_beam_deg=30.0)
    c = scene.medium.c
    sensors = make_sensors((0.2, 0.9, 5.0), (0.2, 1.1, -5.0), (0.25, 1.0, 0.0))
    reflector = np.array([1.405, 1.055])  # a pixel centre
    dt, sigma, n = 5e-6, 2e-5, 3000  # linear interpolation loses < 1 % at the peak
    t = np.arange(n) * dt

    def envelope(tx, rx):
        d = (np.linalg.norm(reflector - sensors.positions[tx])
             + np.linalg.norm(reflector - sensors.positions[rx]))
        return np.exp(-((t - d / c) ** 2) / (2 * sigma**2)), d

    X, Y = cell_grid(scene)
    # one pair: the map is largest on its ellipse |p − T| + |p − R| = c·τ
    env, d = envelope(0, 1)
    m = kernel_backprojection(scene, sensors, [[0, 1]], env[None], dt, precision)
    iy, ix = np.unravel_index(np.argmax(m), m.shape)
    path = (math.hypot(X[iy, ix] - 0.2, Y[iy, ix] - 0.9)
            + math.hypot(X[iy, ix] - 0.2, Y[iy, ix] - 1.1))
    assert abs(path - d) <= scene.cell * math.sqrt(2) / 2
    assert m.max() > 0.99
    on = np.abs(np.hypot(X - 0.2, Y - 0.9) + np.hypot(X - 0.2, Y - 1.1) - d) < 1e-3
    assert np.all(m[on & (m > 0)] > 0.95)
    # all nine pairs: the ellipses cross at the reflector, where the map peaks
    pairs = np.array([(a, b) for a in range(3) for b in range(3)])
    envs = np.stack([envelope(a, b)[0] for a, b in pairs])
    m = kernel_backprojection(scene, sensors, pairs, envs, dt, precision)
    iy, ix = np.unravel_index(np.argmax(m), m.shape)
    assert math.hypot(X[iy, ix] - reflector[0], Y[iy, ix] - reflector[1]) <= 2 * scene.cell
    assert m.max() > 0.95 * len(pairs)


def test_backprojection_inputs_are_checked():
    scene = make_scene((0.0, 0.0, 1.0, 1.0), 0.02)
    sensors = make_sensors((0.1, 0.5, 0.0))
    with pytest.raises(ValueError, match="P = 1"):
        backproject_reference(scene, sensors, [[0, 0]], np.zeros((2, 10)), 1e-5)
    with pytest.raises(ValueError, match="2 samples"):
        backproject_reference(scene, sensors, [[0, 0]], np.zeros((1, 1)), 1e-5)
    with pytest.raises(ValueError, match="dt"):
        backproject_reference(scene, sensors, [[0, 0]], np.zeros((1, 4)), 0.0)
    m = kernel_backprojection(scene, sensors, np.zeros((0, 2), np.int64), np.zeros((0, 4)),
                              1e-5, "float32")
    assert m.shape == scene.grid_shape and not m.any()


def test_merge_reciprocal_pairs_one_locus_per_path():
    from clsonar.mapping import merge_reciprocal

    rows = [(0, 1, 0.010, 2.0), (1, 0, 0.0102, 4.0), (2, 2, 0.02, 1.0), (0, 1, 0.03, 1.0),
            (3, 1, 0.05, 1.0)]
    r = np.asarray(rows)
    loci = Loci(r[:, 0].astype(np.int64), r[:, 1].astype(np.int64), r[:, 2], r[:, 3])
    merged = merge_reciprocal(loci, tolerance_s=1e-3)
    got = list(zip(merged.tx.tolist(), merged.rx.tolist(), merged.tof_s.tolist(),
                   merged.amplitude.tolist(), strict=True))
    assert got == [(0, 1, pytest.approx(0.0101), 3.0), (0, 1, 0.03, 1.0), (1, 3, 0.05, 1.0),
                   (2, 2, 0.02, 1.0)]


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 60), st.integers(1, 5))
def test_merge_reciprocal_matches_its_row_by_row_reference(seed, n, sensors):
    """The vectorised merge of pairs heard at most once each way, with the reference's
    loop for the others, gives the reference's rows exactly."""
    from clsonar.mapping.loci import merge_reciprocal, merge_reciprocal_reference

    rng = np.random.default_rng(seed)
    tx, rx = rng.integers(0, sensors, n), rng.integers(0, sensors, n)
    tof = np.round(rng.uniform(0.01, 0.012, n), 4)  # ties and near misses
    loci = Loci(tx.astype(np.int64), rx.astype(np.int64), tof, rng.uniform(0.1, 5.0, n))
    got, want = merge_reciprocal(loci, 5e-4), merge_reciprocal_reference(loci, 5e-4)
    for name in ("tx", "rx", "tof_s", "amplitude"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name))


@settings(max_examples=120, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([5.0, 12.0, 30.0, 89.0]),
       st.sampled_from([0.0, 1e-7, 0.01, 0.13, 1.0]))
def test_locus_samples_computed_near_the_beam_equal_every_sample_tested(seed, half_beam,
                                                                        spread):
    """_locus_samples computes only the arc near T's beam; the in-beam samples and their
    points must be those that testing every sample gives."""
    rng = np.random.default_rng(seed)
    n = 6
    pos = rng.uniform(-2, 2, (n, 2))
    pos[1] = pos[0] + spread * np.array([1.0, 0.3])  # nearly coincident pairs
    sensors = SensorArray(pos, rng.uniform(-540, 540, n), np.zeros(n, np.int64),
                          np.zeros((0, 2)))
    scene = Scene("arc", (-5.0, -5.0, 5.0, 5.0),
                  transducer=TransducerModel(half_beam_deg=half_beam, directivity="uniform"))
    tx, rx = rng.integers(0, n, 40), rng.integers(0, n, 40)
    tx[:5], rx[:5] = 0, 1
    c = scene.medium.c
    gap = np.hypot(*(pos[rx] - pos[tx]).T)
    path = gap + rng.choice([0.0, 1e-9, 1e-4, 0.3, 3.0], 40) * rng.uniform(0.5, 1.0, 40)
    loci = mapping.Loci(tx, rx, path / c, np.ones(40))
    p, inside, a = map_tangents._locus_samples(scene, sensors, loci)
    # every sample, tested directly
    cut_sin2, _ = scene.transducer.beam(c)
    T, R = pos[tx], pos[rx]
    f = 0.5 * gap
    b = np.sqrt(np.maximum(a * a - f * f, 0.0))
    u = np.where((f > 0)[:, None], (R - T) / np.maximum(2 * f, 1e-300)[:, None], [1.0, 0.0])
    v = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    phi = 2 * np.pi * np.arange(mapping.LOCUS_SAMPLES) / mapping.LOCUS_SAMPLES
    full = (0.5 * (T + R)[:, None] + (a[:, None] * np.cos(phi))[..., None] * u[:, None]
            + (b[:, None] * np.sin(phi))[..., None] * v[:, None])
    axes = sensors.axes
    want = (mapping.in_beams(full, T[:, None], axes[tx][:, None], cut_sin2)
            & mapping.in_beams(full, R[:, None], axes[rx][:, None], cut_sin2)
            & (a > f)[:, None])
    assert np.array_equal(inside, want)
    assert np.array_equal(p[inside], full[want])


# --------------------------------------------------------------------------- methods (mapping.mode)


def test_the_methods_are_the_allowed_modes():
    mode = typing.get_type_hints(MappingSettings)["mode"]
    assert set(mapping.METHODS) == set(typing.get_args(mode))


@functools.cache
def bundled_inputs():
    """plane-2m's scene, sensors, echoes and detections (the stages before the map)."""
    from clsonar import signals
    from clsonar.echoes import compute_echoes
    from clsonar.files import bundled_scenes
    from clsonar.scene import load_scene
    from clsonar.sensors import place_sensors

    scene = load_scene(bundled_scenes() / "plane-2m.json")
    sensors = place_sensors(scene)
    echoes = compute_echoes(scene, sensors, context=context())
    return scene, sensors, echoes, signals.detect(scene, sensors, echoes, context=context())


def direct_votes(scene, sensors, echoes, detections, tiles):
    """What each method does, spelt out with the module's functions."""
    from clsonar import signals
    from clsonar.sensors import pairs

    if scene.mapping.mode == "backprojection":
        dt, env = signals.envelopes(scene, sensors, echoes, context=context())
        return backproject(scene, sensors, pairs(sensors), env, dt, context=context()), {}
    loci = mapping.as_loci(detections)
    if scene.mapping.reciprocal == "merge":
        loci = mapping.merge_reciprocal(loci, 6.0 * scene.transducer.pulse_sigma_s)
    if scene.mapping.mode == "tangents":
        points, source = mapping.tangent_points(scene, sensors, loci,
                                                isolated_bias_m=scene.mapping.isolated_bias_m)
        return (points, loci.tx[source], loci.rx[source]), {}
    stats = []

    def draw(part):
        votes, one = mapping.accumulate_with_stats(scene, sensors, part, context=context(),
                                                   tiles=tiles)
        stats.append(one)
        return votes

    raw = (mapping.count_viewpoints(scene, sensors, loci, draw)
           if scene.mapping.combine == "viewpoints" else draw(loci))
    return raw, {"tiles_total": sum(s.tiles_total for s in stats),
                 "tiles_skipped": sum(s.tiles_skipped for s in stats),
                 "pixel_locus_tests": sum(s.pixel_locus_tests for s in stats),
                 "dense_pixel_locus_tests": sum(s.dense_tests for s in stats)}


@pytest.mark.parametrize("mode, changes, tiles", [
    ("backprojection", {}, True),
    ("loci", {"combine": "viewpoints", "reciprocal": "merge"}, True),
    ("loci", {"combine": "sum", "reciprocal": "both"}, False),
    ("tangents", {"isolated_bias_m": 0.005}, True),
])
def test_map_votes_runs_the_method_the_scene_names(mode, changes, tiles):
    scene, sensors, echoes, detections = bundled_inputs()
    scene = dataclasses.replace(
        scene, mapping=dataclasses.replace(scene.mapping, mode=mode, **changes))
    got = mapping.map_votes(scene, sensors, echoes, detections, context=context(), tiles=tiles)
    want, counts = direct_votes(scene, sensors, echoes, detections, tiles)
    assert got.counts == counts
    if mode == "tangents":
        assert got.raw is None and len(want[0]) > 0
        for a, b in zip((got.points, got.tx, got.rx), want, strict=True):
            assert b is not None and np.array_equal(a, b)
    else:
        assert got.points is None and got.tx is None and got.rx is None
        assert got.raw is not None and np.count_nonzero(want) > 0
        assert got.raw.dtype == want.dtype and np.array_equal(got.raw, want)
    if mode == "loci":
        assert counts["tiles_total"] > 0 if tiles else counts["tiles_total"] == 0


def test_map_votes_refuses_an_unknown_mode():
    scene, sensors, echoes, detections = bundled_inputs()
    scene = dataclasses.replace(scene, mapping=dataclasses.replace(scene.mapping, mode="none"))
    with pytest.raises(ValueError, match="unknown mapping mode"):
        mapping.map_votes(scene, sensors, echoes, detections, context=context())


@pytest.mark.parametrize("turn_deg", [0.0, 3.0, 7.0])
def test_circle_echo_is_the_echo_engines_circle(turn_deg):
    """A pillar's echo as the seen-through test predicts it (tangents.circle_echo) is the
    reference echo engine's first-order echo of the circle, for elements on and off its
    axis at several ranges."""
    from clsonar.echoes.reference import reference_echoes
    from clsonar.scene import scene_from_dict
    from clsonar.sensors import place_sensors

    heading = 180.0 + turn_deg
    scene = scene_from_dict({
        "clsonar": 1, "name": "pillar", "extent": [-1, -4, 7, 4], "cell": 0.02,
        "surfaces": [{"type": "circle", "center": [0.0, 0.0], "radius": 0.35}],
        "sensors": {"transducers": [{"position": [x, 0.0], "heading_deg": heading,
                                     "group": k} for k, x in enumerate((1.5, 3.0, 5.5))]},
    }, "test")
    sensors = place_sensors(scene)
    echoes = reference_echoes(scene, sensors)
    mono = (np.asarray(echoes.tx) == np.asarray(echoes.rx)) & (np.asarray(echoes.order) == 1)
    got = np.asarray(echoes.amplitude)[mono][np.argsort(np.asarray(echoes.tx)[mono])]
    want = map_tangents.circle_echo(scene, sensors.positions, sensors.axes,
                                    np.zeros(2), 0.35)
    assert np.allclose(got, want, rtol=1e-6)
