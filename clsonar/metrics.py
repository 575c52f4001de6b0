"""Error of an estimated profile against the true geometry (thesis eq. 2.6, and more).

- :func:`rms_along_wall`: thesis eq. 2.6, ``sqrt(mean |C_actual(x_i) − C_estimated(x_i)|²)``,
  where the scene is one surface that is a function along a wall: one straight open wall
  (a plane) or one sinusoid. ``x_i`` are the estimated points' positions along the wall,
  ``C`` the displacement across it.
- accuracy: RMS and 95th percentile of the distance from each estimated point to the
  nearest true surface;
- completeness: the share of the *insonified* true geometry that has an estimated point
  within 1, 2, 3 and 5 cm. A point of a true surface is insonified when it lies on the locus
  of an echo return inside both beams that the run's detection could detect
  (:func:`insonified`, :func:`detectable_amplitude`: at least its threshold, and at least
  10 % of the transmitted amplitude): the parts of the scene the detected echoes could
  speak of, so what a perfect map could recover; ``coverage`` is their share of all the
  true geometry;
- spurious share: the share of estimated points farther than 5 cm from every true surface;
- rooms (thesis §3.6): each true corner and edge against the nearest vertex the profile
  located (:func:`vertex_errors`; found within 3 cm), and the share of each cylinder's
  perimeter with an estimated point within 2 cm (:func:`cylinder_coverage`).
"""

from __future__ import annotations

import math
from typing import NamedTuple, TypedDict

import numpy as np

from . import physics, steps
from .echoes import EDGE
from .geometry import Geometry, curve_point, nearest_surface_point, point_cells, true_vertices
from .neighbours import nearest, nearest_within
from .numerics import percentile, unique
from .scene import Polyline, Scene, Sinusoid
from .sensors import SensorArray
from .signals import envelope_noise_scale, signal_model
from .signals.detection import envelope_floor
from .survey import with_detection_chosen

#: Distances at which completeness is reported, metres.
COMPLETENESS_RADII = (0.01, 0.02, 0.03, 0.05)

#: An estimated point farther than this from every surface is spurious, metres.
SPURIOUS_M = 0.05

#: Echoes weaker than this share of the transmitted amplitude insonify nothing, whatever
#: the detection's floor (:func:`least_amplitude`).
LEAST_SHARE = 0.1

#: A true point within about this range of an echo's locus is insonified by it, metres.
LOCUS_TOL_M = 0.01

#: A true corner or edge is found when a located vertex lies within this, metres.
VERTEX_FOUND_M = 0.03

#: A cylinder's perimeter point is covered when an estimated point lies within this.
CYLINDER_TOL_M = 0.02


def truth_points(scene: Scene, geom: Geometry, spacing: float) -> np.ndarray:
    """[M, 2] points every ``spacing`` along every true surface, inside the extent."""
    out = []
    for x0, y0, x1, y1 in geom.walls:
        n = max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / spacing))
        t = (np.arange(n) + 0.5) / n
        out.append(np.stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)], axis=-1))
    for cx, cy, r in geom.circles:
        n = max(8, math.ceil(2 * math.pi * r / spacing))
        a = 2 * math.pi * (np.arange(n) + 0.5) / n
        out.append(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=-1))
    for k, curve in enumerate(geom.curves):
        s_all = geom.interval_s[geom.interval_curve == k]
        s = np.arange(s_all[0, 0], s_all[-1, 1], spacing / 4)  # dense in s, then thinned
        p = curve_point(curve, s)
        arc = np.r_[0.0, np.cumsum(np.hypot(*np.diff(p, axis=0).T))]
        keep = np.searchsorted(arc, np.arange(0.0, arc[-1], spacing))
        out.append(p[keep])
    if not out:
        return np.zeros((0, 2))
    pts = np.concatenate(out)
    xmin, ymin, xmax, ymax = scene.extent
    inside = (pts[:, 0] >= xmin) & (pts[:, 0] <= xmax) & (pts[:, 1] >= ymin) & (pts[:, 1] <= ymax)
    return pts[inside]


def heard(scene: Scene, echoes, min_amplitude: float | None = None) -> np.ndarray:
    """[n] bool: the echo returns at least ``min_amplitude`` strong (default
    :func:`least_amplitude`, the same at every noise σ and detection mode)."""
    floor = least_amplitude(scene) if min_amplitude is None else min_amplitude
    return np.asarray(echoes.amplitude) >= floor


def least_amplitude(scene: Scene) -> float:
    """The weakest echo any run's metrics read: :data:`LEAST_SHARE` of the transmitted
    amplitude, units."""
    return LEAST_SHARE * scene.transducer.amplitude


def detection_level(scene: Scene, sensors: SensorArray | None = None) -> float:
    """The weakest echo the run's detection could detect (units): the signal's threshold
    (``detection.mode`` ``"threshold"``, thesis §2.1.1), else the envelope's lowest
    threshold — the floor (``detection.min_envelope``, chosen from the scene with
    ``sensors`` where the file leaves it out; the Polaroid receiver's comparator level) or,
    with noise, ``false_alarm_sigmas`` times the envelope noise's Rayleigh scale
    (docs/detection.md), whichever is higher. An isolated echo of amplitude A reads A on
    either detector, so an echo weaker than this gives no detection. (Without a floor to
    read: :func:`least_amplitude`.)"""
    if scene.detection.min_envelope is None and sensors is not None:
        scene = with_detection_chosen(scene, sensors)
    if scene.detection.mode == "threshold":
        return float(scene.signal.threshold)
    if scene.detection.min_envelope is None:
        return least_amplitude(scene)
    model = signal_model(scene)
    floor = envelope_floor(model)
    if model.receiver is None:
        floor = max(floor, model.false_alarm_sigmas * envelope_noise_scale(model))
    return floor


def detectable_amplitude(scene: Scene, sensors: SensorArray | None = None) -> float:
    """:func:`detection_level`, and at least :func:`least_amplitude` (units): the echoes
    whose loci the metrics call insonified — an echo weaker than the detection's level
    speaks of nothing a map could show, and the metrics read none weaker than a tenth of
    the transmitted amplitude whatever the detection."""
    return max(least_amplitude(scene), detection_level(scene, sensors))


def insonified(scene: Scene, sensors: SensorArray, echoes, points: np.ndarray,
               min_amplitude: float | None = None) -> np.ndarray:
    """[M] bool: which ``points`` of the true geometry lie on the locus of an echo return
    at least ``min_amplitude`` strong (default :func:`detectable_amplitude`: an echo the
    run's detection could detect; :func:`strongest_echo`)."""
    least = detectable_amplitude(scene, sensors) if min_amplitude is None else min_amplitude
    return strongest_echo(scene, sensors, echoes, points, least) >= least


def strongest_echo(scene: Scene, sensors: SensorArray, echoes, points: np.ndarray,
                   min_amplitude: float | None = None) -> np.ndarray:
    """[M] float: the amplitude of the strongest echo return at least ``min_amplitude``
    strong (default :func:`least_amplitude`) on whose locus each of ``points`` lies, 0
    where none.

    A point q is on the locus of the echo (T, R, τ) when ``| |q−T| + |q−R| − c·τ | ≤
    2·LOCUS_TOL_M`` (about ±1 cm in range) and q is inside both beams: what the echoes
    themselves say about the scene, so what a perfect map could recover. A smooth wall
    only echoes around its specular points; the rest of it, even inside a beam, is silent.
    An edge's diffraction comes from its vertex alone (the echo's ``point``; Keller's
    geometrical theory of diffraction): it insonifies the points within 2·LOCUS_TOL_M of
    the vertex, not the stretches of the faces its locus crosses.
    """
    t = scene.transducer
    c = scene.medium.c
    keep = heard(scene, echoes, min_amplitude)
    tx, rx = np.asarray(echoes.tx)[keep], np.asarray(echoes.rx)[keep]
    path = np.asarray(echoes.tof_s)[keep] * c
    amp = np.asarray(echoes.amplitude, dtype=np.float64)[keep]
    kind = getattr(echoes, "kind", None)
    edge = (np.zeros(len(amp), bool) if kind is None else np.asarray(kind)[keep] == EDGE)
    vertex = np.asarray(echoes.point)[keep] if edge.any() else np.zeros((len(amp), 2))
    cut_sin2 = physics.beam_cut_sin2(t.frequency_hz, t.radius_m, t.half_beam_deg, c)
    best = np.zeros(len(points))
    if len(path) == 0 or len(points) == 0:
        return best
    # each echo tests the points both of its sensors see (_views_by_tiles, _sensor_views)
    if cut_sin2 <= _NARROW_BEAM_SIN2:
        tiles = truth_tiles(points)
        pts = points[tiles.order]
        seen = _views_by_tiles(pts, tiles, sensors, tx, rx, path, cut_sin2)
        order = tiles.order
    else:
        order = np.argsort(points[:, 0], kind="stable")
        pts = points[order]
        seen = _sensor_views(pts, sensors, tx, rx, path, cut_sin2)
    best[order] = _loci_strongest(pts, seen, tx, rx, path, amp, edge, vertex)
    return best


#: Largest table (sensors × points) :func:`_loci_strongest` looks the points of a sensor
#: up in (4 bytes each); beyond it, a binary search of the sorted keys.
_LOOKUP_AT_MOST = 1 << 23


def _loci_strongest(pts: np.ndarray, seen: dict[int, tuple[np.ndarray, np.ndarray]],
                    tx: np.ndarray, rx: np.ndarray, path: np.ndarray, amp: np.ndarray,
                    edge: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """[M] the strongest of the echoes (``tx``, ``rx``, ``path``, ``amp``, ``edge``,
    ``vertex`` [n] each) on whose locus each of ``pts`` lies (:func:`strongest_echo`), 0
    where none, from the points each sensor sees (``seen``, :func:`_sensor_views`). All
    echoes at once, :data:`STEP_ECHOES` pairs at a time: each echo's points of the sensor
    that sees fewer are looked up among the other's (sorted keys sensor·M + point), with
    the arithmetic of one echo at a time (|dt + dr − c·τ| ≤ 2·LOCUS_TOL_M, the sum taken
    either way round is the same number)."""
    used = np.array(sorted(seen), dtype=np.int64)
    index = np.concatenate([seen[int(s)][0] for s in used]).astype(np.int64)
    dist = np.concatenate([seen[int(s)][1] for s in used])
    count = np.array([len(seen[int(s)][0]) for s in used], dtype=np.int64)
    start = np.cumsum(count) - count
    keys = np.repeat(np.arange(len(used)), count) * len(pts) + index
    best = np.zeros(len(pts))
    if len(keys) == 0:
        return best
    lookup = None  # where each key is, -1 where none, when that table is small enough
    if len(used) * len(pts) <= _LOOKUP_AT_MOST:
        lookup = np.full(len(used) * len(pts), -1, dtype=np.int32)
        lookup[keys] = np.arange(len(keys))
    slot_t, slot_r = np.searchsorted(used, tx), np.searchsorted(used, rx)
    swap = count[slot_r] < count[slot_t]
    small, other = np.where(swap, slot_r, slot_t), np.where(swap, slot_t, slot_r)
    load = np.cumsum(count[small])
    first = 0
    while first < len(tx):
        steps.step("echoes' loci", first, len(tx))
        last = max(first + 1, int(np.searchsorted(load, load[first] - count[small[first]]
                                                  + STEP_ECHOES * 64, side="right")))
        echo = np.arange(first, min(last, len(tx)))
        n = count[small[echo]]
        offset = np.cumsum(n) - n
        member = np.repeat(start[small[echo]] - offset, n) + np.arange(int(n.sum()))
        echo = np.repeat(echo, n)
        want = other[echo] * len(pts) + index[member]
        if lookup is None:
            at = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
            both = keys[at] == want
        else:
            at = lookup[want]
            both = at >= 0
        echo, member, at = echo[both], member[both], at[both]
        on = np.abs(dist[member] + dist[at] - path[echo]) <= 2 * LOCUS_TOL_M
        echo, hit = echo[on], index[member[on]]
        near = np.flatnonzero(edge[echo])
        if len(near):
            d = pts[hit[near]] - vertex[echo[near]]
            far = near[d[:, 0] ** 2 + d[:, 1] ** 2 > (2 * LOCUS_TOL_M) ** 2]
            echo, hit = np.delete(echo, far), np.delete(hit, far)
        np.maximum.at(best, hit, amp[echo])
        first = int(last)
    steps.step("echoes' loci", len(tx), len(tx))
    return best


#: Echoes :func:`insonified` tests between two reports of its progress.
STEP_ECHOES = 4096


#: Widest beam (sin² of its half-angle) :func:`_views_by_tiles` narrows the points for;
#: beyond it (45°) a sensor's whole x-slice goes to the beam test (:func:`_sensor_views`).
_NARROW_BEAM_SIN2 = 0.5


def _sensor_views(pts: np.ndarray, sensors: SensorArray, tx: np.ndarray, rx: np.ndarray,
                  path: np.ndarray, cut_sin2: float) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per sensor that heard an echo, ``(indices, distances)`` of the x-sorted ``pts``
    inside its beam and within its longest path (a point of the locus of (T, R, τ) is at
    most c·τ from T and from R: a slice of the points sorted by x), indices ascending;
    sensor by sensor, for a beam wider than :data:`_NARROW_BEAM_SIN2`
    (:func:`_views_by_tiles` for the others)."""
    reach = np.zeros(len(sensors.positions))
    np.maximum.at(reach, tx, path)
    np.maximum.at(reach, rx, path)
    seen: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    axes, x = sensors.axes, pts[:, 0]
    for s in unique(np.concatenate([tx, rx])):
        steps.poll()
        origin, axis, far = sensors.positions[s], axes[s], float(reach[s])
        lo, hi = np.searchsorted(x, [origin[0] - far, origin[0] + far], side="left")
        index = lo + np.arange(hi - lo)
        d = pts[index] - origin
        dist = np.hypot(d[:, 0], d[:, 1])
        cross = axis[0] * d[:, 1] - axis[1] * d[:, 0]
        beam = (d @ axis > 0) & (cross * cross <= cut_sin2 * dist * dist)
        seen[int(s)] = (index[beam], dist[beam])
    return seen


#: Side of the square tiles :func:`truth_tiles` gathers the true surface's points in, metres.
TRUTH_TILE_M = 0.125

#: (Sensor, tile) pairs :func:`_views_by_tiles` tests at once.
_TILE_PAIRS_AT_ONCE = 1 << 20


class TruthTiles(NamedTuple):
    """Points gathered in square tiles (:func:`truth_tiles`): ``order`` [M] lists them tile
    by tile, tile k holding ``order[starts[k]:ends[k]]`` (ascending positions of the points
    taken in that order), inside the box ``low[k]`` .. ``high[k]`` [T, 2] and within
    ``radius[k]`` of ``centre[k]`` [T, 2]."""

    order: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    low: np.ndarray
    high: np.ndarray
    centre: np.ndarray
    radius: np.ndarray


def truth_tiles(points: np.ndarray, side: float | None = None) -> TruthTiles:
    """The ``points`` [M, 2] (M ≥ 1) in square tiles of ``side`` (default
    :data:`TRUTH_TILE_M`), each with its points' box, the box's centre and a radius a
    little over the farthest point's distance from it (rounding)."""
    side = TRUTH_TILE_M if side is None else side
    key = np.floor((points - points.min(axis=0)) / side)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key = key[order]
    starts = np.flatnonzero(np.r_[True, (key[1:, 0] != key[:-1, 0])
                                  | (key[1:, 1] != key[:-1, 1])])
    ends = np.r_[starts[1:], len(order)]
    held = points[order]
    low, high = np.minimum.reduceat(held, starts), np.maximum.reduceat(held, starts)
    centre = 0.5 * (low + high)
    gap = held - np.repeat(centre, ends - starts, axis=0)
    radius = np.maximum.reduceat(np.hypot(gap[:, 0], gap[:, 1]), starts) * (1 + 1e-9) + 1e-12
    return TruthTiles(order, starts, ends, low, high, centre, radius)


def _views_by_tiles(pts: np.ndarray, tiles: TruthTiles, sensors: SensorArray, tx: np.ndarray,
                    rx: np.ndarray, path: np.ndarray, cut_sin2: float
                    ) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """:func:`_sensor_views` of a narrow beam (sin² of its half-angle at most
    :data:`_NARROW_BEAM_SIN2`) for every sensor at once, ``pts`` being the points in the
    order of their ``tiles``. A point goes to the beam test only if it lies in the
    sensor's x-slice, in the box of its beam out to its reach + 2·:data:`LOCUS_TOL_M` (no
    point farther lies on a locus of this sensor; :func:`_beam_boxes`) and in a cone a
    little wider than the beam (:func:`_beam_tests`), and only the tiles whose box meets
    slice and box and whose disc may reach into the beam (its half-angle widened by
    asin(ρ/R)) are expanded. The points and distances of the sensor-by-sensor loop this
    replaced, to the bit (tests/test_speed_metrics.py): its beam test's ``d @ axis`` may
    round otherwise than ``axis·d`` written out, but only where the point is off the axis
    by 90° within 1e-15 rad, which a beam of at most 45° leaves out either way."""
    reach = np.zeros(len(sensors.positions))
    np.maximum.at(reach, tx, path)
    np.maximum.at(reach, rx, path)
    used = unique(np.concatenate([tx, rx]))
    origin, axis, far = sensors.positions[used], sensors.axes[used], reach[used]
    bounds = _beam_boxes(origin, axis, far + 2 * LOCUS_TOL_M + 1e-6, cut_sin2)
    slice_lo, slice_hi = origin[:, 0] - far, origin[:, 0] + far
    half = math.asin(math.sqrt(cut_sin2))
    xs, ys = np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])
    step = max(1, _TILE_PAIRS_AT_ONCE // len(tiles.starts))
    owners, indices, dists = [], [], []
    for a in range(0, len(used), step):
        steps.poll()
        b = min(a + step, len(used))
        v = tiles.centre[None, :, :] - origin[a:b, None, :]
        r = np.hypot(v[..., 0], v[..., 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            spread = np.arcsin(np.minimum(tiles.radius / r, 1.0))
        cone = np.cos(np.minimum(half + spread + 1e-6, math.pi))
        toward = (v[..., 0] * axis[a:b, 0, None] + v[..., 1] * axis[a:b, 1, None]
                  >= r * cone - 1e-9 * (r + 1.0))
        box = ((tiles.high[:, 0] >= np.maximum(slice_lo[a:b], bounds[0][a:b])[:, None])
               & (tiles.low[:, 0] <= np.minimum(slice_hi[a:b], bounds[2][a:b])[:, None])
               & (tiles.high[:, 1] >= bounds[1][a:b, None])
               & (tiles.low[:, 1] <= bounds[3][a:b, None]))
        owner, tile = np.nonzero(box & (toward | (r <= tiles.radius)))
        owner += a
        count = (tiles.ends - tiles.starts)[tile]
        first = np.cumsum(count) - count
        index = np.repeat(tiles.starts[tile] - first, count) + np.arange(int(count.sum()))
        owner = np.repeat(owner, count)
        seen, dist = _beam_tests(xs[index], ys[index], owner, origin, axis, slice_lo,
                                 slice_hi, bounds, cut_sin2)
        owners.append(owner[seen])
        indices.append(index[seen])
        dists.append(dist)
    owner, index, dist = np.concatenate(owners), np.concatenate(indices), np.concatenate(dists)
    cut = np.searchsorted(owner, np.arange(len(used) + 1))
    return {int(s): (index[cut[k]:cut[k + 1]], dist[cut[k]:cut[k + 1]])
            for k, s in enumerate(used)}


def _beam_tests(x: np.ndarray, y: np.ndarray, owner: np.ndarray, origin: np.ndarray,
                axis: np.ndarray, slice_lo: np.ndarray, slice_hi: np.ndarray,
                bounds: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                cut_sin2: float) -> tuple[np.ndarray, np.ndarray]:
    """``(seen, distances)``: which points (``x``, ``y``) [k] pass, for the sensor
    ``owner`` [k] of each, the tests of :func:`_views_by_tiles`: its x-slice as
    ``searchsorted`` cut it (``slice_lo`` ≤ x < ``slice_hi``), its beam's box ``bounds``,
    a cone a little wider than the beam (sin²θ ≤ s ⇔ across² ≤ s/(1 − s)·along² in front,
    with room for rounding, no square root) and the beam test, and the distances of those
    that do. (Columns gathered one by one: a row gather of [S, 2] costs 30 times more.)"""
    keep = ((x >= slice_lo[owner]) & (x < slice_hi[owner]) & (x >= bounds[0][owner])
            & (x <= bounds[2][owner]) & (y >= bounds[1][owner]) & (y <= bounds[3][owner]))
    at = np.flatnonzero(keep)
    owner = owner[at]
    d0 = x[at] - np.ascontiguousarray(origin[:, 0])[owner]
    d1 = y[at] - np.ascontiguousarray(origin[:, 1])[owner]
    u0, u1 = np.ascontiguousarray(axis[:, 0])[owner], np.ascontiguousarray(axis[:, 1])[owner]
    along = u0 * d0 + u1 * d1
    across = u0 * d1 - u1 * d0
    k = cut_sin2 / (1.0 - cut_sin2) * (1.0 + 1e-6)
    dist = np.hypot(d0, d1)
    beam = ((along > -1e-9) & (across * across <= k * along * along + 1e-12)
            & (along > 0) & (across * across <= cut_sin2 * dist * dist))
    seen = np.zeros(len(x), dtype=bool)
    seen[at[beam]] = True
    return seen, dist[beam]


def _beam_boxes(origin: np.ndarray, axis: np.ndarray, radius: np.ndarray, cut_sin2: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(xmin, ymin, xmax, ymax)``, [S] each: boxes holding every point within ``radius``
    [S] of ``origin`` [S, 2] inside the beam of ``axis`` [S, 2] (half-angle θ, sin²θ =
    ``cut_sin2`` ≤ 1/2): the box of the triangle ``origin``, ``origin + radius·(axis ±
    tanθ·normal)``, widened for rounding."""
    spread = math.sqrt(cut_sin2 / (1.0 - cut_sin2)) * np.stack([-axis[:, 1], axis[:, 0]], -1)
    corners = origin[:, None, :] + radius[:, None, None] * np.stack(
        [np.zeros_like(axis), axis + spread, axis - spread], axis=1)
    slack = 1e-9 * (radius + np.abs(origin).max(axis=1) + 1.0)
    low, high = corners.min(axis=1) - slack[:, None], corners.max(axis=1) + slack[:, None]
    return low[:, 0], low[:, 1], high[:, 0], high[:, 1]


def single_wall(scene: Scene) -> tuple[np.ndarray, np.ndarray, Sinusoid | None] | None:
    """``(origin, unit direction, sinusoid or None)`` when the scene's only surface is one
    straight open wall or one sinusoid (the profile is then a function along the wall)."""
    if len(scene.surfaces) != 1:
        return None
    s = scene.surfaces[0]
    if isinstance(s, Sinusoid):
        a, b = np.asarray(s.start, float), np.asarray(s.end, float)
        return a, (b - a) / np.hypot(*(b - a)), s
    if isinstance(s, Polyline) and not s.closed and len(s.points) == 2:
        a, b = np.asarray(s.points[0], float), np.asarray(s.points[1], float)
        return a, (b - a) / np.hypot(*(b - a)), None
    return None


def rms_along_wall(scene: Scene, points: np.ndarray) -> float | None:
    """Thesis eq. 2.6 over the estimated ``points``: each point's position x along the wall
    and displacement C across it, against the true displacement at the same x (0 for a
    plane, ``A·sin(2πx/P)`` for a sinusoid). None when the scene is not a single wall or
    there are no points."""
    wall = single_wall(scene)
    if wall is None or len(points) == 0:
        return None
    origin, u, sinusoid = wall
    normal = np.array([-u[1], u[0]])
    rel = np.asarray(points, dtype=np.float64) - origin
    x, c_est = rel @ u, rel @ normal
    c_true = (np.zeros_like(x) if sinusoid is None
              else sinusoid.amplitude * np.sin(2 * math.pi * x / sinusoid.period))
    return float(np.sqrt(np.mean((c_true - c_est) ** 2)))


class VertexError(TypedDict):
    """A true corner or edge at (x, y), the distance to the nearest located vertex (None if
    none was located) and whether that is within :data:`VERTEX_FOUND_M`."""

    x: float
    y: float
    error_m: float | None
    found: bool


def vertex_errors(geom: Geometry, located: np.ndarray) -> list[VertexError]:
    """For each true corner and edge (geometry.true_vertices): its position, the distance
    to the nearest ``located`` vertex [k, 2] (None if none) and whether that is within
    :data:`VERTEX_FOUND_M`."""
    truth = true_vertices(geom)
    located = np.asarray(located, dtype=np.float64).reshape(-1, 2)
    gap = nearest(located, truth)
    return [{"x": float(v[0]), "y": float(v[1]),
             "error_m": float(g) if np.isfinite(g) else None,
             "found": bool(g <= VERTEX_FOUND_M)} for v, g in zip(truth, gap, strict=True)]


def vertex_summary(corners: list[VertexError]) -> dict[str, object]:
    """``vertices`` (``corners``), ``vertices_found`` ("found/all") and
    ``vertex_error_max_m`` (None if a vertex was not located at all)."""
    errors = [v["error_m"] for v in corners]
    located = [e for e in errors if e is not None]
    return {"vertices": corners,
            "vertices_found": f"{sum(v['found'] for v in corners)}/{len(corners)}",
            "vertex_error_max_m": max(located) if len(located) == len(errors) else None}


def cylinder_coverage(geom: Geometry, points: np.ndarray, spacing: float) -> list[dict]:
    """For each circle of the scene: the share of its perimeter (sampled every ``spacing``)
    with an estimated point within :data:`CYLINDER_TOL_M`."""
    out = []
    for cx, cy, r in geom.circles:
        n = max(8, math.ceil(2 * math.pi * r / spacing))
        a = 2 * math.pi * (np.arange(n) + 0.5) / n
        perimeter = np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=-1)
        gap = nearest_within(points, perimeter, 2 * CYLINDER_TOL_M)  # exact to the bound
        out.append({"x": float(cx), "y": float(cy), "radius_m": float(r),
                    "coverage_2cm": float(np.mean(gap <= CYLINDER_TOL_M))})
    return out


def lit_truth(scene: Scene, geom: Geometry, sensors: SensorArray, echoes
              ) -> tuple[np.ndarray, np.ndarray]:
    """``(truth, strongest)``: the points every ``min(cell, 5 mm)`` along the true surfaces
    (:func:`truth_points`) and the strongest echo on whose locus each lies
    (:func:`strongest_echo`, 0: none): what :func:`evaluate` scores a profile against, the
    same for every profile mapped from these echoes, whatever detected them (it keeps the
    points the run's detection could hear, :func:`detectable_amplitude`)."""
    truth = truth_points(scene, geom, min(scene.cell, 0.005))
    return truth, strongest_echo(scene, sensors, echoes, truth)


def evaluate(scene: Scene, geom: Geometry, sensors: SensorArray, echoes,
             points: np.ndarray, vertices: np.ndarray | None = None,
             scored: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, object]:
    """All metrics of the estimated profile ``points`` [n, 2] (module docstring), as a
    JSON-ready dict: ``rms_m`` (eq. 2.6 or None), ``accuracy_m`` {rms, p95},
    ``completeness`` {"1cm", "2cm", "3cm", "5cm"}, ``spurious_share``, ``insonified_m``
    (length of the insonified true geometry: lit by an echo the run's detection could
    detect, :func:`detectable_amplitude`), ``coverage`` (its share of all of it),
    ``points``, and
    for scenes with corners, edges or cylinders ``vertices`` (:func:`vertex_errors` of the
    located ``vertices``, with ``vertices_found`` and ``vertex_error_max_m``) and
    ``cylinders`` (:func:`cylinder_coverage`). ``scored``: :func:`lit_truth` of the
    scene, sensors and echoes when already computed."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    spacing = min(scene.cell, 0.005)
    truth, strongest = lit_truth(scene, geom, sensors, echoes) if scored is None else scored
    lit = truth[strongest >= detectable_amplitude(scene, sensors)]
    out: dict[str, object] = {
        "points": len(points), "rms_m": rms_along_wall(scene, points),
        "insonified_m": len(lit) * spacing,
        "coverage": len(lit) / len(truth) if len(truth) else None,
    }
    steps.poll()
    if len(points) and len(truth):
        dist, _ = nearest_surface_point(geom, points)
        out["accuracy_m"] = {"rms": float(np.sqrt(np.mean(dist**2))),
                             "p95": float(percentile(dist, 95))}
        out["spurious_share"] = float(np.mean(dist > SPURIOUS_M))
    else:
        out["accuracy_m"] = {"rms": None, "p95": None}
        out["spurious_share"] = None
    steps.poll()
    if len(lit):
        gap = nearest_within(points, lit, 2 * max(COMPLETENESS_RADII))  # exact to the radii
        out["completeness"] = {f"{round(r * 100)}cm": float(np.mean(gap <= r))
                               for r in COMPLETENESS_RADII}
    else:
        out["completeness"] = {f"{round(r * 100)}cm": None for r in COMPLETENESS_RADII}
    corners = vertex_errors(geom, np.zeros((0, 2)) if vertices is None else vertices)
    if corners:
        out.update(vertex_summary(corners))
    if len(geom.circles):
        out["cylinders"] = cylinder_coverage(geom, points, spacing)
    return out


#: A true full cell is detected when the map marks a cell within this many cells of it
#: (Chebyshev distance: the 3 × 3 block around it), and a marked cell this near the true
#: surface is not a wrongly marked empty cell (:func:`cell_rates`).
CELL_TOLERANCE = 1


def surface_cells(scene: Scene, geom: Geometry, sensors: SensorArray, echoes
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``(full, surface)``, [ny, nx] bool each, at the map's cells: the cells holding a
    point of the insonified true surface (:func:`truth_points` every ``min(cell, 5 mm)``,
    :func:`insonified` by echoes of at least :func:`least_amplitude`, the same at every
    noise σ and detection mode: the full cells a perfect map would mark, Barshan 2007),
    and those
    holding any point of the true surface."""
    truth = truth_points(scene, geom, min(scene.cell, 0.005))
    lit = (insonified(scene, sensors, echoes, truth, least_amplitude(scene)) if len(truth)
           else np.zeros(0, bool))
    out = []
    for pts in (truth[lit], truth):
        grid = np.zeros(scene.grid_shape, dtype=bool)
        iy, ix = point_cells(scene.extent, scene.cell, pts)
        ok = (iy >= 0) & (iy < grid.shape[0]) & (ix >= 0) & (ix < grid.shape[1])
        grid[iy[ok], ix[ok]] = True
        out.append(grid)
    return out[0], out[1]


def cell_rates(full: np.ndarray, surface: np.ndarray, region: np.ndarray, marked: np.ndarray,
               tolerance: int = CELL_TOLERANCE) -> tuple[float | None, float | None]:
    """The rates of correctly detected full and empty cells of the map ``marked`` (Kurt,
    MSc, Bilkent 2005; Barshan, IJRR 26(8), 2007, beside the map's mean absolute error),
    all arguments [ny, nx] bool at the map's cells:

    - full: the share of the true full cells ``full`` (the insonified true surface's,
      :func:`surface_cells`) with a marked cell within ``tolerance`` cells (the
      (2·tolerance + 1)² block around it);
    - empty: the share of the truly empty cells of ``region`` (the cells the echoes
      sounded, :func:`clsonar.mapping.sounded_cells`) left unmarked, truly empty meaning
      farther than ``tolerance`` cells from every cell of the true surface ``surface``.

    Each None where there is no such cell."""
    from scipy.ndimage import binary_dilation

    block = np.ones((2 * tolerance + 1, 2 * tolerance + 1), dtype=bool)
    near_marked = binary_dilation(marked, block)
    empty = region & ~binary_dilation(surface, block)
    return (float(np.mean(near_marked[full])) if full.any() else None,
            float(np.mean(~marked[empty])) if empty.any() else None)
