"""The insonified truth found for all sensors and echoes at once (issue 16) against the
sensor-by-sensor and echo-by-echo loops it replaced: the same amplitudes to the bit."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import metrics, physics
from clsonar.echoes import EDGE
from clsonar.metrics import LOCUS_TOL_M, strongest_echo, truth_tiles
from clsonar.sensors import SensorArray


def loop_strongest_echo(scene, sensors, echoes, points, min_amplitude):
    """:func:`clsonar.metrics.strongest_echo` as of commit 1610903: the points sorted by x,
    each sensor's view (:func:`loop_sensor_views`), then one echo at a time."""
    t, c = scene.transducer, scene.medium.c
    keep = np.asarray(echoes.amplitude) >= min_amplitude
    tx, rx = np.asarray(echoes.tx)[keep], np.asarray(echoes.rx)[keep]
    path = np.asarray(echoes.tof_s)[keep] * c
    amp = np.asarray(echoes.amplitude, dtype=np.float64)[keep]
    edge = np.asarray(echoes.kind)[keep] == EDGE
    vertex = np.asarray(echoes.point)[keep] if edge.any() else np.zeros((len(amp), 2))
    cut_sin2 = physics.beam_cut_sin2(t.frequency_hz, t.radius_m, t.half_beam_deg, c)
    best = np.zeros(len(points))
    if len(path) == 0 or len(points) == 0:
        return best
    order = np.argsort(points[:, 0], kind="stable")
    pts = points[order]
    seen = loop_sensor_views(pts, sensors, tx, rx, path, cut_sin2)
    best_sorted = np.zeros(len(pts))
    for k, (a, b, length) in enumerate(zip(tx, rx, path, strict=True)):
        (it, dt), (ir, dr) = seen[int(a)], seen[int(b)]
        if len(it) == 0 or len(ir) == 0:
            continue
        at = np.minimum(np.searchsorted(ir, it), len(ir) - 1)
        both = ir[at] == it
        on = np.abs(dt[both] + dr[at[both]] - length) <= 2 * LOCUS_TOL_M
        hit = it[both][on]
        if edge[k]:
            near = pts[hit] - vertex[k]
            hit = hit[near[:, 0] ** 2 + near[:, 1] ** 2 <= (2 * LOCUS_TOL_M) ** 2]
        best_sorted[hit] = np.maximum(best_sorted[hit], amp[k])
    best[order] = best_sorted
    return best


def loop_sensor_views(pts, sensors, tx, rx, path, cut_sin2):
    """``metrics._sensor_views`` with ``_near_beam`` of commit 1610903, sensor by sensor."""
    reach = np.zeros(len(sensors.positions))
    np.maximum.at(reach, tx, path)
    np.maximum.at(reach, rx, path)
    seen = {}
    axes = sensors.axes
    for s in np.unique(np.concatenate([tx, rx])):
        origin, axis = sensors.positions[s], axes[s]
        index = loop_near_beam(pts, origin, axis, float(reach[s]), cut_sin2)
        d = pts[index] - origin
        dist = np.hypot(d[:, 0], d[:, 1])
        cross = axis[0] * d[:, 1] - axis[1] * d[:, 0]
        beam = (d @ axis > 0) & (cross * cross <= cut_sin2 * dist * dist)
        seen[int(s)] = (index[beam], dist[beam])
    return seen


def loop_near_beam(pts, origin, axis, reach, cut_sin2):
    """``metrics._near_beam`` of commit 1610903."""
    x = pts[:, 0]
    lo, hi = np.searchsorted(x, [origin[0] - reach, origin[0] + reach], side="left")
    if cut_sin2 > 0.5:
        return lo + np.arange(hi - lo)
    xmin, ymin, xmax, ymax = _beam_box(origin, axis, reach + 2 * LOCUS_TOL_M + 1e-6, cut_sin2)
    lo = max(lo, int(np.searchsorted(x, xmin, side="left")))
    hi = max(lo, min(hi, int(np.searchsorted(x, xmax, side="right"))))
    y = pts[lo:hi, 1]
    index = lo + np.flatnonzero((y >= ymin) & (y <= ymax))
    return index[_in_cone(pts[index] - origin, axis, cut_sin2)]


def _beam_box(origin, axis, radius, cut_sin2):
    """``metrics._beam_box`` of commit 1610903."""
    spread = math.sqrt(cut_sin2 / (1.0 - cut_sin2)) * np.array([-axis[1], axis[0]])
    corners = origin + radius * np.array([[0.0, 0.0], axis + spread, axis - spread])
    slack = 1e-9 * (radius + np.abs(origin).max() + 1.0)
    (xmin, ymin), (xmax, ymax) = corners.min(axis=0) - slack, corners.max(axis=0) + slack
    return float(xmin), float(ymin), float(xmax), float(ymax)


def _in_cone(d, axis, cut_sin2):
    """``metrics._in_cone`` of commit 1610903."""
    along = axis[0] * d[:, 0] + axis[1] * d[:, 1]
    across = axis[0] * d[:, 1] - axis[1] * d[:, 0]
    k = cut_sin2 / (1.0 - cut_sin2) * (1.0 + 1e-6)
    return (along > -1e-9) & (across * across <= k * along * along + 1e-12)


@st.composite
def _cases(draw):
    """A scene's transducer (beams of 3° to 90°), sensors facing about the points, the
    true points (walls sampled every 5 mm, scattered ones, some on a sensor), and echoes
    off points of them (some edges' diffraction, a few off any locus)."""
    rng = np.random.default_rng(draw(st.integers(0, 2**31)))
    half_beam = draw(st.sampled_from([3.0, 12.0, 30.0, 45.0, 60.0, 90.0]))
    size = draw(st.sampled_from([0.5, 4.0, 15.0]))
    n = draw(st.integers(1, 12))
    positions = rng.uniform(0.0, size, (n, 2))
    headings = rng.uniform(-180.0, 180.0, n)
    if draw(st.booleans()):  # axis-aligned headings: points straight ahead or abeam
        headings = rng.integers(-2, 2, n) * 90.0
    sensors = SensorArray(positions, headings, np.zeros(n, np.int64), positions[:1])
    parts = [rng.uniform(-0.2 * size, 1.2 * size, (draw(st.integers(0, 200)), 2)),
             positions[: draw(st.integers(0, 2))]]
    for _ in range(draw(st.integers(0, 4))):
        a, b = rng.uniform(-0.2 * size, 1.2 * size, (2, 2))
        parts.append(a + np.linspace(0.0, 1.0, max(2, int(np.hypot(*(b - a)) / 0.005)))[:, None]
                     * (b - a))
    points = np.concatenate(parts)
    if draw(st.booleans()):
        points = np.round(points, 2)  # many points on one x, some on one another
    m = draw(st.integers(0, 150))
    tx, rx = rng.integers(0, n, m), rng.integers(0, n, m)
    rx = np.where(rng.random(m) < 0.3, tx, rx)
    q = points[rng.integers(0, len(points), m)] if len(points) else np.zeros((m, 2))
    c = 343.0
    length = (np.hypot(*(q - positions[tx]).T) + np.hypot(*(q - positions[rx]).T)
              + rng.normal(0.0, 0.01, m) * (rng.random(m) < 0.5))
    echoes = SimpleNamespace(tx=tx, rx=rx, tof_s=length / c, amplitude=rng.uniform(0, 2, m),
                             kind=np.where(rng.random(m) < 0.2, EDGE, 0), point=q)
    scene = SimpleNamespace(transducer=SimpleNamespace(
        frequency_hz=50_000.0, radius_m=0.001, half_beam_deg=half_beam, amplitude=5.0),
        medium=SimpleNamespace(c=c))
    return scene, sensors, echoes, points


@settings(max_examples=150, deadline=None)
@given(case=_cases(), tile=st.sampled_from([0.01, 0.125, 3.0]),
       lookup=st.sampled_from([0, 1 << 23]), at_once=st.sampled_from([1, 1 << 20]))
def test_strongest_echo_all_at_once_is_the_loops_bit_for_bit(case, tile, lookup, at_once):
    """Every point's strongest echo equals the loops', whatever the tiles' size, with the
    lookup table or the binary search, a few (sensor, tile) pairs at a time or all."""
    scene, sensors, echoes, points = case
    want = loop_strongest_echo(scene, sensors, echoes, points, 0.2)
    old = metrics.TRUTH_TILE_M, metrics._LOOKUP_AT_MOST, metrics._TILE_PAIRS_AT_ONCE
    try:
        metrics.TRUTH_TILE_M, metrics._LOOKUP_AT_MOST, metrics._TILE_PAIRS_AT_ONCE = (
            tile, lookup, at_once)
        got = strongest_echo(scene, sensors, echoes, points, 0.2)
    finally:
        metrics.TRUTH_TILE_M, metrics._LOOKUP_AT_MOST, metrics._TILE_PAIRS_AT_ONCE = old
    np.testing.assert_array_equal(got, want)


def test_truth_tiles_hold_every_point_once_in_their_boxes():
    """A 1 m wall every 5 mm in tiles of 0.125 m: 8 tiles, each point in one, inside its
    tile's box and disc, positions in tile order."""
    wall = np.stack([np.linspace(0.0, 1.0, 201), np.full(201, 2.0)], axis=-1)
    tiles = truth_tiles(wall)
    assert len(tiles.starts) == 9  # x = 1.0 starts a ninth tile
    np.testing.assert_array_equal(np.sort(tiles.order), np.arange(201))
    for k, (a, b) in enumerate(zip(tiles.starts, tiles.ends, strict=True)):
        held = wall[tiles.order[a:b]]
        assert np.all((held >= tiles.low[k]) & (held <= tiles.high[k]))
        assert np.hypot(*(held - tiles.centre[k]).T).max() <= tiles.radius[k]
