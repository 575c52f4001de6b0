"""Tiled locus accumulation (clsonar/mapping/tiles.py ``bin_loci``, kernel ``loci_tiles``): the same
map as the dense kernel to the bit, in both precisions and weights, whatever the tile shape,
the tiles per launch and where the loci fall; the counters; maps drawn in several launches."""

from __future__ import annotations

import functools
import json
import math
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsonar.mapping as mapping
import clsonar.mapping.launch as map_launch
from clsonar.mapping import Loci, accumulate_reference, accumulate_with_stats
from clsonar.opencl import device_kind, get_context, has_fp64
from clsonar.scene import MappingSettings, Scene, TransducerModel
from clsonar.sensors import SensorArray


@functools.cache
def context():
    return get_context()


def tiles_of(shape, tile) -> int:
    """How many tiles of ``tile`` = (width, height) pixels cover a map of ``shape``
    = (width, height)."""
    return math.ceil(shape[0] / tile[0]) * math.ceil(shape[1] / tile[1])


def on_cpu() -> bool:
    return device_kind(context().devices[0]) == "CPU"


def precisions() -> tuple[str, ...]:
    return ("float32", "float64") if has_fp64(context()) else ("float32",)


def scene_of(extent, cell, weight="unit", band_m=None, half_beam_deg=12.0) -> Scene:
    return Scene(name="tiles-test", extent=extent, cell=cell,
                 transducer=TransducerModel(half_beam_deg=half_beam_deg),
                 mapping=MappingSettings(weight=weight, band_m=band_m))


def sensors_of(transducers) -> SensorArray:
    """Transducers ``(x, y, heading_deg)``."""
    t = np.asarray(transducers, dtype=np.float64).reshape(-1, 3)
    return SensorArray(t[:, :2].copy(), t[:, 2].copy(), np.zeros(len(t), dtype=np.int64),
                       np.zeros((0, 2)))


def loci_of(scene: Scene, rows) -> Loci:
    """Rows ``(tx, rx, path length c·τ in m, amplitude)``."""
    r = np.asarray(rows, dtype=np.float64).reshape(-1, 4)
    return Loci(r[:, 0].astype(np.int64), r[:, 1].astype(np.int64), r[:, 2] / scene.medium.c,
                r[:, 3].copy())


def draw_both(scene, sensors, loci, precision, tile=None, launch_bytes=None):
    """(dense map, tiled map, tiled stats), the tiles of ``tile`` pixels drawn at most
    ``launch_bytes`` of them per launch."""
    patches = []
    if tile is not None:
        patches.append(mock.patch.dict(mapping.TILES, {"CPU": tile, "GPU": tile,
                                                       "other": tile}))
    if launch_bytes is not None:
        patches.append(mock.patch.object(map_launch, "MAX_LAUNCH_BYTES", launch_bytes))
    kw = dict(context=context(), precision=precision)
    dense, _ = accumulate_with_stats(scene, sensors, loci, tiles=False, **kw)
    for p in patches:
        p.start()
    try:
        tiled, stats = accumulate_with_stats(scene, sensors, loci, **kw)
    finally:
        for p in patches:
            p.stop()
    return dense, tiled, stats


# --------------------------------------------------------------------------- property test


@st.composite
def tile_cases(draw):
    """A map 20–150 cells a side (not a multiple of any tile), 1–4 transducers in, on the
    edge of or outside it, 0–8 loci through a point near an edge or a corner of the map, just
    reaching it, or missing it; a tile shape and the bytes of tiles per launch."""
    cell = draw(st.sampled_from([0.005, 0.01, 0.023]))
    nx, ny = draw(st.integers(20, 150)), draw(st.integers(20, 150))
    x0, y0 = draw(st.floats(-50.0, 50.0)), draw(st.floats(-50.0, 50.0))
    width, height = (nx - 0.5) * cell, (ny - 0.5) * cell
    weight = draw(st.sampled_from(["unit", "amplitude", "beam"]))
    band = draw(st.one_of(st.none(), st.floats(0.3, 3.0).map(lambda f: f * cell)))
    half_beam = draw(st.sampled_from([12.0, 5.0, 40.0, 90.0]))
    scene = scene_of((x0, y0, x0 + width, y0 + height), cell, weight, band, half_beam)
    near_edge = st.sampled_from([-0.1, -0.01, 0.0, 0.005, 0.5, 0.995, 1.0, 1.01, 1.1])

    def point():
        if draw(st.booleans()):  # near an edge or a corner
            return x0 + draw(near_edge) * width, y0 + draw(near_edge) * height
        return x0 + draw(st.floats(-0.3, 1.3)) * width, y0 + draw(st.floats(-0.3, 1.3)) * height

    transducers, targets = [], []
    for _ in range(draw(st.integers(1, 4))):  # each aimed near a point of interest
        px, py = point()
        qx, qy = x0 + draw(st.floats(-0.1, 1.1)) * width, y0 + draw(st.floats(-0.1, 1.1)) * height
        aim = math.degrees(math.atan2(qy - py, qx - px)) if (qx, qy) != (px, py) else 0.0
        aim += draw(st.floats(-1.2, 1.2)) * min(half_beam, 12.0)
        transducers.append((px, py, aim))
        targets.append((qx, qy))
    rows = []
    for _ in range(draw(st.integers(0, 8))):
        t = draw(st.integers(0, len(transducers) - 1))
        r = t if draw(st.booleans()) else draw(st.integers(0, len(transducers) - 1))
        qx, qy = targets[t] if draw(st.booleans()) else point()
        qx += draw(st.floats(-0.05, 0.05)) * width
        qy += draw(st.floats(-0.05, 0.05)) * height
        path = (math.hypot(qx - transducers[t][0], qy - transducers[t][1])
                + math.hypot(qx - transducers[r][0], qy - transducers[r][1]))
        if draw(st.integers(0, 7)) == 0:
            path = draw(st.sampled_from([0.0, 1e3]))  # misses the map (or is a point)
        rows.append((t, r, path, draw(st.floats(0.1, 5.0))))
    tile = draw(st.sampled_from([None, (8, 4), (16, 8)]))
    launch_bytes = draw(st.sampled_from([None, 1, 5000]))
    return scene, sensors_of(transducers), loci_of(scene, rows), tile, launch_bytes


@settings(max_examples=150, deadline=None)
@given(tile_cases())
def test_tiled_map_equals_dense_map_to_the_bit(case):
    scene, sensors, loci, tile, launch_bytes = case
    for precision in precisions():
        dense, tiled, stats = draw_both(scene, sensors, loci, precision, tile, launch_bytes)
        assert tiled.dtype == dense.dtype and tiled.shape == dense.shape == scene.grid_shape
        assert np.array_equal(tiled, dense), (
            f"{precision}: {np.count_nonzero(tiled != dense)} pixels differ, first at "
            f"{np.argwhere(tiled != dense)[:3].tolist()}")
        ny, nx = scene.grid_shape
        tw, th = stats.tile
        assert stats.tiled and stats.tiles_total == -(-nx // tw) * -(-ny // th)
        if tile is not None:
            assert stats.tile == tile
        if launch_bytes == 1:  # one tile per launch
            assert stats.launches == stats.tiles_total - stats.tiles_skipped
        assert 0 <= stats.tiles_skipped <= stats.tiles_total
        if len(loci) == 0:
            assert stats.tiles_skipped == stats.tiles_total and stats.pixel_locus_tests == 0
        if precision == "float64":
            assert np.array_equal(tiled, accumulate_reference(scene, sensors, loci))


# --------------------------------------------------------------------------- binning


def test_bins_list_exactly_the_tiles_a_locus_reaches_and_keep_locus_order():
    """A monostatic arc in the middle of the map: its tiles are the ones its votes fall in,
    plus at most a ring of neighbours (the bounds are conservative, not loose)."""
    scene = scene_of((0.0, 0.0, 6.4, 6.4), 0.01)
    sensors = sensors_of([(0.5, 3.2, 0.0), (0.5, 3.0, 5.0)])
    loci = loci_of(scene, [(0, 0, 8.0, 1.0), (1, 1, 6.0, 1.0), (0, 1, 7.0, 1.0)])
    pb = mapping.prepare_loci(scene, sensors, loci)
    bins = mapping.bin_loci(pb, (32, 32))
    assert bins.shape == (20, 20) and len(bins.start) == 401
    for k in range(400):  # each tile's loci in ascending order
        assert np.all(np.diff(bins.members[bins.start[k]:bins.start[k + 1]]) > 0)
    for i in range(len(loci)):
        votes = accumulate_reference(scene, sensors, Loci(*(np.asarray(c)[[i]] for c in (
            loci.tx, loci.rx, loci.tof_s, loci.amplitude))))
        iy, ix = np.nonzero(votes)
        voted = set((iy // 32 * 20 + ix // 32).tolist())
        listed = {k for k in range(400)
                  if i in bins.members[bins.start[k]:bins.start[k + 1]]}
        assert voted and voted <= listed
        # no listed tile is far from a voted one: within one tile of it
        near = {(a + dy) * 20 + b + dx for t in voted for a, b in [divmod(t, 20)]
                for dy in (-1, 0, 1) for dx in (-1, 0, 1)}
        assert listed <= near, sorted(listed - near)
        assert len(listed) <= 3 * len(voted)


def test_loci_that_miss_the_map_are_binned_nowhere():
    scene = scene_of((0.0, 0.0, 1.0, 1.0), 0.01)
    sensors = sensors_of([(0.5, 0.5, 0.0), (3.0, 0.5, 0.0), (0.5, 0.5, 180.0)])
    # too long; shorter than the foci's distance; a beam pointing away from the map
    loci = loci_of(scene, [(0, 0, 10.0, 1.0), (0, 1, 2.0, 1.0), (1, 1, 1.0, 1.0)])
    bins = mapping.bin_loci(mapping.prepare_loci(scene, sensors, loci), (32, 32))
    assert len(bins.members) == 0 and not bins.counts.any()
    m, stats = accumulate_with_stats(scene, sensors, loci, context=context())
    # 100 × 100 pixels: 4 × 4 tiles of a CPU's 32 × 32, 4 × 13 of a GPU's 32 × 8
    assert not m.any() and stats.tiles_skipped == stats.tiles_total == tiles_of((100, 100),
                                                                                stats.tile)
    assert stats.pixel_locus_tests == 0 and stats.dense_tests > 0


# ------------------------------------------------------------------------ counters, launches


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_counters_and_launches(precision):
    if precision not in precisions():
        pytest.skip("the OpenCL device has no cl_khr_fp64")
    scene = scene_of((0.0, 0.0, 3.0, 2.5), 0.01, weight="beam")
    sensors = sensors_of([(0.1, 1.2, 0.0), (0.1, 1.3, -10.0), (2.9, 0.1, 135.0)])
    loci = loci_of(scene, [(0, 0, 4.0, 1.0), (0, 1, 4.2, 1.0), (2, 2, 3.0, 1.0),
                           (1, 1, 1.0, 1.0), (2, 0, 3.5, 1.0)])
    dense, tiled, stats = draw_both(scene, sensors, loci, precision, (32, 32))
    assert np.array_equal(dense, tiled) and np.count_nonzero(tiled) > 300
    pb = mapping.prepare_loci(scene, sensors, loci)
    # 32 × 32 asked; a GPU's kernel may take fewer work items a group: rows are cut
    tw, th = stats.tile
    assert tw == 32 and th in (32, 16, 8) and (th == 32 or not on_cpu())
    counts = mapping.bin_loci(pb, (tw, th)).counts
    assert stats.tiles_total == tiles_of((300, 250), (tw, th))  # 10 × 8 of 32 × 32
    assert stats.tiles_skipped == int(np.count_nonzero(counts == 0)) > 20
    assert stats.pixel_locus_tests == int(counts.sum()) * tw * th
    assert stats.pixel_locus_tests < stats.dense_tests / 3
    assert stats.launches == 1
    assert stats.as_dict()["tile"] == [tw, th]
    # one tile per launch: the same map, in as many launches as tiles drawn
    _, split, small = draw_both(scene, sensors, loci, precision, (32, 32), launch_bytes=1)
    assert np.array_equal(split, tiled)
    assert small.launches == stats.tiles_total - stats.tiles_skipped
    assert small.pixel_locus_tests == stats.pixel_locus_tests
    # dense: every pixel of the padded map tests every locus
    _, dense_stats = accumulate_with_stats(scene, sensors, loci, context=context(),
                                           precision=precision, tiles=False)
    assert not dense_stats.tiled and dense_stats.tiles_total == 0
    assert dense_stats.pixel_locus_tests == dense_stats.dense_tests == stats.dense_tests
    assert dense_stats.dense_tests >= 300 * 250 * 5 and dense_stats.launches == 1
    with mock.patch.object(map_launch, "MAX_ROWS_PER_LAUNCH", 2):
        blocks = accumulate_with_stats(scene, sensors, loci, context=context(),
                                       precision=precision, tiles=False)
    assert blocks[1].launches == 3 and np.array_equal(blocks[0], dense)


@pytest.mark.parametrize("seed, weight, tile, launch_bytes", [
    (0, "unit", (8, 4), None), (1, "beam", (8, 4), 1), (2, "amplitude", None, 20000),
    (3, "unit", (16, 8), None)])
def test_many_loci_across_many_tile_edges(seed, weight, tile, launch_bytes):
    """200 loci of 12 transducers around and inside a 2.57 m × 1.93 m map (not a multiple of
    any tile), half of them bistatic, wide and narrow beams: thousands of voted pixels on
    tile edges, the same to the bit."""
    rng = np.random.default_rng(seed)
    scene = scene_of((-1.0, 0.5, 1.57, 2.43), 0.01, weight, half_beam_deg=[12.0, 40.0][seed % 2])
    x = rng.uniform(-1.3, 1.9, 12)
    y = rng.uniform(0.2, 2.7, 12)
    aim = np.degrees(np.arctan2(rng.uniform(0.5, 2.4, 12) - y, rng.uniform(-1.0, 1.6, 12) - x))
    sensors = sensors_of(np.stack([x, y, aim + rng.uniform(-15, 15, 12)], axis=1))
    t = rng.integers(0, 12, 200)
    r = np.where(rng.random(200) < 0.5, t, rng.integers(0, 12, 200))
    q = np.stack([rng.uniform(-1.1, 1.7, 200), rng.uniform(0.4, 2.5, 200)], axis=1)
    path = (np.hypot(*(q - sensors.positions[t]).T) + np.hypot(*(q - sensors.positions[r]).T))
    loci = Loci(t, r, path / scene.medium.c, rng.uniform(0.5, 2.0, 200))
    for precision in precisions():
        dense, tiled, stats = draw_both(scene, sensors, loci, precision, tile, launch_bytes)
        assert np.count_nonzero(dense) > 2000
        assert np.array_equal(tiled, dense), np.count_nonzero(tiled != dense)
        assert stats.pixel_locus_tests < stats.dense_tests


BIG_MAP = """
import json, resource
import numpy as np
from clsonar import mapping
from clsonar.mapping import Loci
from clsonar.opencl import get_context
from clsonar.scene import MappingSettings, Scene, TransducerModel
from clsonar.sensors import SensorArray
scene = Scene(name="hall", extent=(0.0, 0.0, 100.0, 100.0), cell=0.01,
              transducer=TransducerModel(half_beam_deg=12.0), mapping=MappingSettings())
rng = np.random.default_rng(5)
n, N = 100, 300
xy, aim = rng.uniform(10, 90, (n, 2)), rng.uniform(-180, 180, n)
sensors = SensorArray(xy, aim, np.zeros(n, dtype=np.int64), np.zeros((0, 2)))
t = rng.integers(0, n, N)
q = xy[t] + rng.uniform(1, 30, N)[:, None] * np.stack(
    [np.cos(np.radians(aim[t])), np.sin(np.radians(aim[t]))], axis=1)
loci = Loci(t, t, 2 * np.hypot(*(q - xy[t]).T) / scene.medium.c, np.ones(N))
m, stats = mapping.accumulate_with_stats(scene, sensors, loci, context=get_context())
m += 1  # touch every page, as a caller would
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps({"shape": list(m.shape), "dtype": str(m.dtype), "peak": peak,
                  "voted": int(np.count_nonzero(m > 1)), **stats.as_dict()}))
"""


@pytest.mark.slow
def test_a_hundred_metre_hall_at_one_centimetre_fits_in_2_gb():
    """10⁸ cells (issue 5): 400 MB of float32 map, drawn in launches of at most
    MAX_LAUNCH_BYTES of tiles; the process' peak resident memory stays under 2 GB."""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", BIG_MAP], capture_output=True, text=True,
                          timeout=300, check=True)
    got = json.loads(done.stdout.splitlines()[-1])
    assert got["shape"] == [10000, 10000] and got["dtype"] == "float32"
    assert got["voted"] > 50_000 and got["tiles_total"] == tiles_of((10_000, 10_000),
                                                                     got["tile"])
    assert got["tiles_skipped"] > got["tiles_total"] // 2 and got["launches"] >= 1
    assert got["pixel_locus_tests"] < 1e-3 * got["dense_tests"]
    assert got["peak"] < 2e9, f"peak resident memory {got['peak'] / 1e9:.2f} GB"


# float16 vectors are wider than AVX2: PoCL's compiler warns about their calling convention
@pytest.mark.filterwarnings("ignore::pyopencl.CompilerWarning")
@pytest.mark.parametrize("vec, group", [(1, (64, 2)), (2, (8, 4)), (4, (16, 1)),
                                        (16, (4, 1))])
def test_every_vector_width_tiles_the_same_map(vec, group):
    """GPUs run one pixel per work item (vec 1), tiles of 32 × 8: the tiled kernel at every
    vector width and tile shape gives the dense map of the default width, to the bit."""
    scene = scene_of((0.0, 0.0, 1.03, 0.77), 0.01, "beam")
    sensors = sensors_of([(0.05, 0.4, 0.0), (0.1, 0.35, 10.0), (0.51, 0.51, -20.0)])
    loci = loci_of(scene, [(0, 0, 1.2, 1.0), (0, 1, 1.3, 2.0), (1, 2, 0.6, 1.0),
                           (2, 2, 0.5, 1.0), (2, 2, 0.0, 1.0)])
    for precision in precisions():
        want = accumulate_with_stats(scene, sensors, loci, context=context(),
                                     precision=precision, tiles=False)[0]
        assert np.count_nonzero(want) > 20
        kind = device_kind(context().devices[0])
        launch = {(kind, "float32"): (vec, group), (kind, "float64"): (min(vec, 4), group)}
        with mock.patch.dict(mapping.LAUNCH, launch):
            tile = (32, 8) if vec == 1 else (32, 32)
            _, tiled, stats = draw_both(scene, sensors, loci, precision, tile)
            # a GPU's kernel may take fewer work items a group than the tile: rows are cut
            assert stats.tile[0] == tile[0] and (stats.tile == tile or not on_cpu())
            assert np.array_equal(tiled, want)


def test_launches_split_the_tiles_by_count_and_by_pairs(monkeypatch):
    start = np.array([0, 3, 3, 10, 11, 11, 20])  # tiles 0..5: 3, 0, 7, 1, 0, 9 loci
    live = np.array([0, 2, 3, 5])
    split = map_launch._launches
    assert [x.tolist() for x in split(start, live, 10)] == [[0, 2, 3, 5]]
    assert [x.tolist() for x in split(start, live, 3)] == [[0, 2, 3], [5]]
    monkeypatch.setattr(map_launch, "MAX_PAIRS_PER_LAUNCH", 8)
    assert [x.tolist() for x in split(start, live, 10)] == [[0], [2, 3], [5]]
    assert [x.tolist() for x in split(start, live[:0], 10)] == []
