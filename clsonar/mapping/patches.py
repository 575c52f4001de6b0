"""What reflector families draw on the map (``mapping.mode = "reflectors"``): a plane its
straight patch, a circle its arc, a point or a corner a located vertex
(:func:`draw_families`).

**Regions of constant depth** (Leonard & Durrant-Whyte 1991): an echo cannot tell its
reflection point from the other surface points whose path differs from it by less than the
pulse's resolution (c·σ of the pulse, eq. 2.3) inside both beams; a patch therefore runs
over the union of its detections' regions, not only over their reflection points
(:func:`extents`). Where a pair of the same array (or, for a plane, of any group, over
the span drawn) would have had its reflection point on that extension, inside beams as
wide as the family's own detections show, and heard no echo there, the surface ends
somewhere between: a plane whose detections show it straight stops halfway between its
last reflection point on that side and the nearest silent pair's, any other patch at its
last reflection point (:func:`_clamp_to_silence`).

Plane patches of the same line (from overlapping stretches of an array, or other arrays)
join into one, fitted again to all their detections, across gaps up to :data:`JOIN_GAP_M`;
two plane patches whose lines meet near both ends meet there, at a located corner or edge,
and a patch whose line passes by a located vertex reaches it (:mod:`.corners`). The points
are laid every :data:`STEP_CELLS` cells, each credited to the locus whose reflection point
is nearest (the line-of-sight check asks which pair saw it).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from .. import steps
from ..scene import Scene
from ..sensors import SensorArray
from ..signals import envelope_noise_scale, signal_model
from .envelope import in_beams
from .families import Family
from .loci import Loci
from .models import curve_geometry, curve_paths, dot2
from .strength import mirror_floor, two_way

#: Spacing of a patch's points, in cells.
STEP_CELLS = 0.5

#: Bisection steps finding the ends of a detection's region of constant depth.
BISECTIONS = 18


@dataclass(frozen=True, eq=False)
class Patches:
    """Estimated surface points with the locus each is credited to, the located vertices
    (corners, edges, thin posts), and where each drawn patch's points end: the first
    ``ends[-1]`` points are the patches', in order along each."""

    points: np.ndarray  # [n, 2]
    source: np.ndarray  # [n] locus index
    vertices: np.ndarray  # [k, 2]
    ends: np.ndarray  # [m] exclusive end of each patch's points

    def plus(self, points: np.ndarray, source: np.ndarray,
             vertices: np.ndarray | None = None) -> Patches:
        """These patches and more points (not a patch's) after them, and more vertices."""
        more = np.zeros((0, 2)) if vertices is None else vertices
        return Patches(np.concatenate([self.points, points]),
                       np.concatenate([self.source, source]).astype(np.int64),
                       np.concatenate([self.vertices.reshape(-1, 2), more]), self.ends)


@dataclass(frozen=True, eq=False)
class Patch:
    """A plane's or circle's stretch: the curve model ``(φ, d, ψ)`` about ``x0``, the
    coordinate along it (arc length along a line from its foot d·n; angle on a circle from
    the direction −n) of each detection's reflection point, the span drawn, and the loci."""

    params: np.ndarray
    x0: np.ndarray
    u: np.ndarray  # [k] reflection points' coordinates
    lo: float
    hi: float
    loci: np.ndarray  # [k]
    bend: float  # 3σ of the curvature (1/m; inf: unknown)
    tx: np.ndarray  # [k] transmitter of each locus
    rx: np.ndarray  # [k] receiver
    T: np.ndarray  # [k, 2]
    R: np.ndarray  # [k, 2]
    paths: np.ndarray  # [k]

    @property
    def straight(self) -> bool:
        return not np.all(np.isfinite(curve_geometry(self.params, self.x0)[0]))


def carrier_points(params: np.ndarray, x0: np.ndarray, u: np.ndarray) -> np.ndarray:
    """[k, 2] the points at coordinates ``u`` of the curve model's line or circle."""
    phi = float(params[0])
    n = np.array([math.cos(phi), math.sin(phi)])
    centre, rho, _ = curve_geometry(params, x0)
    u = np.asarray(u, dtype=np.float64)
    if not np.all(np.isfinite(centre)):
        t = np.array([-n[1], n[0]])
        return float(params[1]) * n + u[..., None] * t
    e = np.stack([np.cos(phi + u), np.sin(phi + u)], axis=-1)
    return centre - rho * e


def coordinates(params: np.ndarray, x0: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The coordinates (:class:`Patch`) of points ``q`` [k, 2] on the carrier."""
    phi = float(params[0])
    centre, rho, _ = curve_geometry(params, x0)
    if not np.all(np.isfinite(centre)):
        return dot2(q, np.array([-math.sin(phi), math.cos(phi)]))
    rel = (centre - q) / rho
    return np.angle(np.exp(1j * (np.arctan2(rel[:, 1], rel[:, 0]) - phi)))


def _region_end(p: Patch, k: np.ndarray, direction: np.ndarray, axes: tuple[np.ndarray, ...],
                cut_sin2: float, resolution: float, reach: np.ndarray) -> np.ndarray:
    """For detections ``k``: how far from its reflection point, in ``direction`` (±1 each)
    along the carrier, the points stay inside both beams with a path within ``resolution``
    of the detected one (bisection; at most ``reach``)."""
    axT, axR = axes  # the axes of the rows k

    def inside(step: np.ndarray) -> np.ndarray:
        q = carrier_points(p.params, p.x0, p.u[k] + direction * step)
        path = np.hypot(*(p.T[k] - q).T) + np.hypot(*(p.R[k] - q).T)
        return ((np.abs(path - p.paths[k]) <= resolution)
                & in_beams(q, p.T[k], axT, cut_sin2) & in_beams(q, p.R[k], axR, cut_sin2))

    lo, hi = np.zeros(len(k)), np.asarray(reach, dtype=np.float64).copy()
    whole = inside(hi)
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        ok = inside(mid)
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    return np.where(whole, reach, lo)


#: The union of regions of constant depth is taken over this many detections at each end
#: of a patch (those whose reflection points lie nearest that end).
END_DETECTIONS = 8


def extents(p: Patch, sensors: SensorArray, cut_sin2: float, resolution: float
            ) -> tuple[float, float]:
    """``(lo, hi)``: the union of the patch's detections' regions of constant depth (module
    docstring) along its carrier, from the :data:`END_DETECTIONS` detections nearest each
    end."""
    order = np.argsort(p.u, kind="stable")
    m = min(END_DETECTIONS, len(order))
    k = np.concatenate([order[:m], order[-m:]])
    direction = np.r_[-np.ones(m), np.ones(m)]
    axes = (sensors.axes[p.tx[k]], sensors.axes[p.rx[k]])
    scale = 1.0 if p.straight else 1.0 / abs(curve_geometry(p.params, p.x0)[1])
    reach = np.minimum(p.paths[k] * scale, math.pi / 2 if not p.straight else np.inf)
    ends = p.u[k] + direction * _region_end(p, k, direction, axes, cut_sin2, resolution,
                                            reach)
    return float(ends[:m].min()), float(ends[m:].max())


def patch_of(f: Family, loci: Loci) -> Patch:
    """The :class:`Patch` of a plane or circle family over its reflection points."""
    w = f.window
    params = np.array([f.params[0], f.params[1], 0.0 if f.kind == "plane" else f.params[2]])
    u = coordinates(params, f.x0, f.q)
    return Patch(params, f.x0, u, float(u.min()), float(u.max()), f.loci, f.bend,
                 loci.tx[f.loci],
                 loci.rx[f.loci], w.T[f.rows], w.R[f.rows], w.paths[f.rows])


def _clamp_to_silence(p: Patch, scene: Scene, sensors: SensorArray, heard: Heard,
                      lo: float, hi: float) -> tuple[float, float]:
    """The span ``(lo, hi)`` cut where the arrays heard nothing (module docstring): pairs
    whose two-way beam (:func:`~.strength.two_way`) points at the surface beyond the span
    at least as well as for the weakest of the patch's own detections, and that have no
    echo there (:func:`_silent_beyond`, :data:`SILENCE_PAIRS` pairs of a group at a
    time). The patch's own group counts wherever beyond its reflection points; another
    group (another array, which sees the surface from elsewhere) where a plane would be
    drawn, over the span ``(lo, hi)`` (:func:`_listeners`)."""
    first, last = float(p.u.min()), float(p.u.max())
    if lo >= first and hi <= last:
        return lo, hi  # nothing a silent pair could cut
    ka = scene.transducer.beam(scene.medium.c)[1]
    weakest = two_way(carrier_points(p.params, p.x0, p.u), p.T, sensors.axes[p.tx], p.R,
                      sensors.axes[p.rx], ka).min()
    below, above = -math.inf, math.inf  # the nearest silent reflection points
    for own, pairs in _listeners(p, sensors):
        steps.poll()
        u = _silent_beyond(p, scene, sensors, heard, pairs, weakest)
        if not own:
            u = u[(u >= lo) & (u <= hi)]
        below = max(below, float(u[u < first].max(initial=-math.inf)))
        above = min(above, float(u[u > last].min(initial=math.inf)))
    # the surface ends between its last reflection point and the first silent one: halfway
    # for a plane whose detections show it straight (with its curvature unknown the
    # silence may be the surface bending away from the line; a circle's pairs are heard
    # at any strength, so an edge's diffraction past a face's end passes for its echo)
    share = 0.5 if p.straight and math.isfinite(p.bend) else 0.0
    return (max(lo, first + share * (below - first)) if below > -math.inf else lo,
            min(hi, last + share * (above - last)) if above < math.inf else hi)


def _listeners(p: Patch, sensors: SensorArray) -> Iterator[tuple[bool, np.ndarray]]:
    """``(own, pairs)``: the pairs of the patch's own group, then, for a plane, those of
    every other group (its line is the surface's wherever it is drawn; a circle is only a
    curved wall's local shape, which another array's pairs, seeing the wall elsewhere,
    would not hear)."""
    group = sensors.groups[int(p.tx[0])]
    for pairs in _group_pairs(sensors, group):
        yield True, pairs
    if not p.straight:
        return
    for other in np.unique(sensors.groups):
        if other != group:
            for pairs in _group_pairs(sensors, other):
                yield False, pairs


def _silent_beyond(p: Patch, scene: Scene, sensors: SensorArray, heard: Heard,
                   pairs: np.ndarray, weakest: float) -> np.ndarray:
    """The coordinates of the reflection points, beyond the patch's own, of the ``pairs``
    in front of the surface that would hear it there at least as well as the patch's
    weakest detection and heard nothing (tests in order of cost: each on the pairs the
    last one kept)."""
    c = scene.medium.c
    cut_sin2, ka = scene.transducer.beam(c)
    T, R = sensors.positions[pairs[:, 0]], sensors.positions[pairs[:, 1]]
    axT, axR = sensors.axes[pairs[:, 0]], sensors.axes[pairs[:, 1]]
    path, q = curve_paths(p.params, p.x0, T, R)
    n = np.array([math.cos(float(p.params[0])), math.sin(float(p.params[0]))])
    front = (dot2(q - T, n) > 0) & (dot2(q - R, n) > 0) if p.straight else True
    ok = np.flatnonzero(in_beams(q, T, axT, cut_sin2) & in_beams(q, R, axR, cut_sin2)
                        & np.isfinite(path) & front)
    u = coordinates(p.params, p.x0, q[ok])
    beyond = (u < p.u.min()) | (u > p.u.max())
    ok, u = ok[beyond], u[beyond]
    beams = (q[ok], T[ok], axT[ok], R[ok], axR[ok])
    louder = two_way(*beams, ka) >= weakest * (1.0 - 1e-9)
    ok, u, beams = ok[louder], u[louder], tuple(b[louder] for b in beams)
    # a plane is heard at a mirror's strength; a curve's echo may be weaker or stronger
    least = (mirror_floor(*beams, mirror_echo(scene), ka, amplitude_noise(scene))
             if p.straight else np.full(len(ok), -np.inf))
    return u[~_heard(heard, pairs[ok], path[ok], least)]


#: Pairs of a group the silence test takes at a time (its memory; about 100 MB).
SILENCE_PAIRS = 1 << 18


def _group_pairs(sensors: SensorArray, group: int) -> Iterator[np.ndarray]:
    """[p, 2] the pairs (T ≤ R) of ``group``, about :data:`SILENCE_PAIRS` at a time."""
    members = np.flatnonzero(sensors.groups == group)
    n = len(members)
    rows = max(1, SILENCE_PAIRS // max(n, 1))
    for i0 in range(0, n, rows):
        i, j = _triangle_rows(n, i0, min(i0 + rows, n))
        yield np.stack([members[i], members[j]], axis=-1)


def _triangle_rows(n: int, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
    """``(i, j)`` of the upper triangle (j ≥ i) of an n × n matrix, rows i0 … i1 − 1."""
    width = n - np.arange(i0, i1)
    i = np.repeat(np.arange(i0, i1), width)
    j = np.arange(int(width.sum())) - np.repeat(np.cumsum(width) - width, width) + i
    return i, j


#: A pair heard the surface where one of its detections lies within this of the
#: predicted path, metres.
HEARD_TOL_M = 0.003


def mirror_echo(scene: Scene) -> float:
    """A flat mirror's echo on both transducers' axes, A0·ρ (units)."""
    return scene.transducer.amplitude * scene.echo.reflection_coefficient


def amplitude_noise(scene: Scene) -> float:
    """The noise σ of a detection's amplitude (units): with envelope detection the
    envelope's Rayleigh scale (each quadrature's σ, 0.145·σn for the default pulse,
    :func:`clsonar.signals.envelope_noise_scale`, docs/detection.md), with threshold
    detection the signal's σn (its amplitude is a sample)."""
    noise = scene.signal.noise_std
    if noise == 0 or scene.detection.mode != "envelope":
        return noise
    floor = scene.detection.min_envelope  # the scale does not depend on it
    detection = replace(scene.detection, min_envelope=1.0 if floor is None else floor)
    return envelope_noise_scale(signal_model(replace(scene, detection=detection)))


@dataclass(frozen=True)
class Heard:
    """The detections by pair (either direction), sorted once for :func:`_heard`:
    ``key`` = min(T, R)·base + max(T, R), their path c·τ and amplitude."""

    base: int
    key: np.ndarray
    path: np.ndarray
    amplitude: np.ndarray


def heard_index(loci: Loci, sensors: SensorArray, c: float) -> Heard:
    """:class:`Heard` of ``loci`` (speed of sound ``c``)."""
    base = len(sensors.positions) + 1
    key = np.minimum(loci.tx, loci.rx) * base + np.maximum(loci.tx, loci.rx)
    order = np.argsort(key, kind="stable")
    return Heard(base, key[order], c * loci.tof_s[order], loci.amplitude[order])


def _heard(heard: Heard, pairs: np.ndarray, path: np.ndarray,
           least: np.ndarray) -> np.ndarray:
    """Whether each pair has a detection (either direction) within :data:`HEARD_TOL_M` of
    ``path`` and of at least ``least`` amplitude (the surface's echo)."""
    want = pairs[:, 0] * heard.base + pairs[:, 1]
    start = np.searchsorted(heard.key, want, side="left")
    count = np.searchsorted(heard.key, want, side="right") - start
    pair = np.repeat(np.arange(len(pairs)), count)  # each of the pairs' detections
    row = np.arange(len(pair)) - np.repeat(np.cumsum(count) - count, count) \
        + np.repeat(start, count)
    near = ((np.abs(heard.path[row] - path[pair]) <= HEARD_TOL_M)
            & (heard.amplitude[row] >= least[pair]))
    return np.bincount(pair[near], minlength=len(pairs)) > 0


def spread_patch(p: Patch, scene: Scene, sensors: SensorArray, heard: Heard) -> Patch:
    """``p`` over its regions of constant depth, cut where the array heard nothing (the
    detections ``heard``, :func:`heard_index`)."""
    c = scene.medium.c
    cut_sin2, _ = scene.transducer.beam(c)
    resolution = c * scene.transducer.pulse_sigma_s
    lo, hi = extents(p, sensors, cut_sin2, resolution)
    lo, hi = _clamp_to_silence(p, scene, sensors, heard, lo, hi)
    reach = trusted_reach(p)
    return replace(p, lo=min(max(lo, p.lo - reach), p.lo), hi=max(min(hi, p.hi + reach), p.hi))


#: A patch is extended only as far as a surface of the curvature its detections allow
#: (:attr:`~.families.Family.bend`) stays within this of it, metres.
PATCH_BIAS_M = 0.002


def trusted_reach(p: Patch) -> float:
    """How far beyond its reflection points (in its coordinate) a patch may go: where a
    curve bent by ``p.bend`` more than the fitted one leaves it by :data:`PATCH_BIAS_M`;
    with the bend unknown, as far as a surface of radius no less than the range stays
    within that of the tangent (the tangent stretch of :mod:`.tangents`)."""
    bend = p.bend if math.isfinite(p.bend) else 2.0 / float(np.median(p.paths))
    reach = math.sqrt(2.0 * PATCH_BIAS_M / max(bend, 1e-12))
    if p.straight:
        return reach
    return reach / abs(curve_geometry(p.params, p.x0)[1])


def draw_patch(p: Patch, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The points of ``p`` every ``step`` (metres of arc) and the locus credited to each."""
    scale = 1.0 if p.straight else abs(curve_geometry(p.params, p.x0)[1])
    du = step / max(scale, 1e-9)
    u = np.arange(p.lo, p.hi + 0.5 * du, du)
    return carrier_points(p.params, p.x0, u), p.loci[nearest_index(p.u, u)]


def nearest_index(values: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """For each of ``queries``, the index of the nearest of ``values`` (ties: the lowest
    index), as ``np.abs(queries[:, None] - values).argmin(axis=1)`` gives it, by binary
    search instead of the [queries × values] matrix (a joined wall seen by a 1000-element
    array: 2400 × 10⁵ distances, 2 GB)."""
    order = np.argsort(values, kind="stable")
    v = np.asarray(values, dtype=np.float64)[order]
    k = np.searchsorted(v, queries, side="left")  # v[k] is the first ≥ the query
    right = np.minimum(k, len(v) - 1)
    left = np.searchsorted(v, v[np.maximum(k - 1, 0)], side="left")  # its run's first
    d_right = np.where(k < len(v), np.abs(v[right] - queries), np.inf)
    d_left = np.where(k > 0, np.abs(queries - v[left]), np.inf)
    take_left = (d_left < d_right) | ((d_left == d_right) & (order[left] < order[right]))
    return np.where(take_left, order[left], order[right])


__all__ = [
    "BISECTIONS",
    "HEARD_TOL_M",
    "PATCH_BIAS_M",
    "STEP_CELLS",
    "Patch",
    "Patches",
    "amplitude_noise",
    "carrier_points",
    "coordinates",
    "draw_patch",
    "extents",
    "nearest_index",
    "patch_of",
    "spread_patch",
    "trusted_reach",
]
