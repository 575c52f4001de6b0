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
somewhere between: where the pairs' echoes beyond fall to half a mirror's, as a face's
does with its reflection point on its edge, or, with nothing heard there, halfway to the
first silent pair (:func:`clamp_to_silence`, :func:`_end`).

Plane patches of one line (overlapping stretches of an array, or other arrays) join into
one, fitted again to all their detections, across gaps up to :data:`JOIN_GAP_M`; two plane
patches whose lines meet near both ends meet there, at a located corner or edge, and a patch
whose line passes by a located vertex reaches it (:mod:`.corners`). Points come every
:data:`STEP_CELLS` cells, each credited to the locus whose reflection point is nearest.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from .. import steps
from ..numerics import median, nearest_index, percentile, unique
from ..physics import wavenumber
from ..scene import Scene
from ..sensors import SensorArray
from .envelope import in_beams
from .families import Family
from .heard import HEARD_TOL_M, Heard, amplitude_noise, group_pairs, loudest
from .loci import Loci
from .models import curve_geometry, curve_paths, dot2, plane_points
from .strength import (
    EDGE_SHARE,
    as_flat_as_its_range,
    convex_share,
    edge_distance,
    mirror_echo,
    mirror_floor,
    two_way,
)
from .window import heard_tolerance

#: The two-way beams of pairs towards points: (q, T, axT, R, axR).
Beams = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]

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
    docstring) along its carrier, from the :data:`END_DETECTIONS` detections nearest each end."""
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


def own_beams(p: Patch, sensors: SensorArray) -> Beams:
    """The beams of ``p``'s own detections at their reflection points: ``(q, T, axis of T,
    R, axis of R)`` for :func:`~.strength.two_way`."""
    return (carrier_points(p.params, p.x0, p.u), p.T, sensors.axes[p.tx], p.R,
            sensors.axes[p.rx])


def clamp_to_silence(p: Patch, scene: Scene, sensors: SensorArray, heard: Heard,
                     lo: float, hi: float) -> tuple[float, float]:
    """The span ``(lo, hi)`` cut where the arrays heard nothing (module docstring): pairs
    in front of the surface whose two-way beam (:func:`~.strength.two_way`) points at it
    beyond the span at least as well as for the weakest of the patch's own detections,
    and that have no echo there as strong as its own (:func:`_beyond`, :data:`~.heard.SILENCE_PAIRS`
    pairs of a group at a time). The patch's own group counts wherever beyond its
    reflection points; another group (another array, which sees the surface from
    elsewhere) where a plane would be drawn, over the span ``(lo, hi)``
    (:func:`_listeners`). Where it is cut, the patch ends as :func:`_end` says."""
    first, last = float(p.u.min()), float(p.u.max())
    if lo >= first and hi <= last:
        return lo, hi  # nothing a silent pair could cut
    ka = scene.transducer.beam(scene.medium.c)[1]
    beams = own_beams(p, sensors)
    weakest = two_way(*beams, ka).min()
    own_pairs = np.sort(np.stack([p.tx, p.rx], axis=-1), axis=-1)
    found = [(p.u, *_strength(p, scene, heard, own_pairs, p.paths, beams, ka), p.T, p.R)]
    middle = float(median(found[0][1]))  # the patch's own echoes over the surface's
    for own, pairs in _listeners(p, sensors):
        steps.poll()
        u, ratio, loud, spread, T, R = _beyond(p, scene, sensors, heard, pairs, weakest)
        keep = np.ones(len(u), dtype=bool) if own else (u >= lo) & (u <= hi)
        found.append((u[keep], ratio[keep], loud[keep], spread[keep], T[keep], R[keep]))
    u, ratio, loud, spread, T, R = (np.concatenate(parts) for parts in zip(*found, strict=True))
    weak = loud & _weakened(ratio, spread, middle)
    _, own_ratio, _, own_spread, _, _ = found[0]
    raised = loud & _raised(p, own_ratio, own_spread, ratio, spread)
    gauged = math.isfinite(p.bend) and flat(p)
    # a circle the detections cannot tell from its tangent (its ψ within 3σ of 0)
    line = p.straight or abs(float(p.params[2])) <= p.bend
    scale = 1.0 if p.straight else abs(float(curve_geometry(p.params, p.x0)[1]))
    ends = []
    for end, side, sign in ((first, u <= first, -1.0), (last, u >= last, 1.0)):
        if line:
            q, along = _tangent(p, end, T[side], R[side], u[side])
        else:
            along = (u[side] - end) * sign * scale  # arc length
        stop = _end(along, ratio[side], loud[side], gauged, p.straight)
        if math.isinf(stop) and gauged and line:
            reach = first - lo if sign < 0 else hi - last
            stop = _fading_end(scene, q, outward(p, end), along, ratio[side], weak[side],
                               raised[side], T[side], R[side], reach)
        if stop == 0 or math.isinf(stop):
            ends.append(end + sign * stop)
        elif line:
            ends.append(float(coordinates(p.params, p.x0,
                                          (q + stop * outward(p, end))[None])[0]))
        else:
            ends.append(end + sign * stop / scale)
    return max(lo, ends[0]), min(hi, ends[1])


def outward(p: Patch, end: float) -> np.ndarray:
    """The unit tangent of ``p``'s carrier at coordinate ``end``, away from its reflection
    points."""
    ahead = end + (1e-6 if end >= float(p.u.max()) else -1e-6)
    step = carrier_points(p.params, p.x0, np.array([end, ahead]))
    d = step[1] - step[0]
    return d / max(float(np.hypot(*d)), 1e-300)


def _tangent(p: Patch, end: float, T: np.ndarray, R: np.ndarray, u: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """``(q, along)``: ``p``'s point at its reflection points' ``end`` and how far, along
    its tangent there, away from its reflection points, the pairs (T, R) at coordinates
    ``u`` (the patch's own, at ``end`` and inside, and those beyond) reflect from the
    tangent line (a plane's own line; a face's last stretch fitted by a slightly bent
    circle reflects beyond it, along the face, as the line does: on the circle, the pairs'
    reflection points are drawn together by its curvature)."""
    q = carrier_points(p.params, p.x0, np.array([end]))[0]
    t = outward(p, end)
    n = np.array([t[1], -t[0]])
    if float(dot2(n, T.mean(axis=0) - q)) > 0:
        n = -n  # the plane's normal points away from the transducers
    _, on_line = plane_points(math.atan2(n[1], n[0]), float(dot2(n, q)), T, R)
    along = dot2(on_line - q, t)
    inside = (u - end) * (1.0 if end >= float(p.u.max()) else -1.0) <= 0
    return q, np.where(inside, np.minimum(along, 0.0), along)


def _end(along: np.ndarray, ratio: np.ndarray, loud: np.ndarray, gauged: bool,
         halfway: bool) -> float:
    """How far beyond its last reflection point (``along`` 0; the pairs ``along`` their
    reflection points' distances away from it, the patch's own at 0 or less) a surface
    ends, from whether the pairs heard it as strongly as its echo is (``loud``) and their
    echoes' strength over a mirror's (``ratio``, 0: none): inf where no pair beyond was
    silent; else, with its curvature and echo unknown (not ``gauged``), 0; else where the
    echo falls to half a mirror's (:data:`~.strength.EDGE_SHARE`), linearly between the
    pairs either side — a face's echo is half a mirror's with its reflection point on the
    face's edge (the uniform theory, Kouyoumjian & Pathak 1974) — and, with no
    diffraction heard (an edge model that gives none, a free end), halfway between the
    last echo and the first silent pair if ``halfway`` (a plane: it ends somewhere
    between, so halfway is off by at most half the gap), else at the last echo (a circle
    with nothing heard beyond may be a curved surface turning away from it)."""
    order = np.argsort(along, kind="stable")
    along, ratio, loud = along[order], ratio[order], loud[order]
    start = int(np.searchsorted(along, 0.0, side="right"))  # the first beyond
    silent = np.flatnonzero(~loud[start:]) + start
    if len(silent) == 0:
        return math.inf
    if not gauged:
        return 0.0
    prev = int(silent[0]) - 1  # the last heard: one of the patch's own at the latest
    for k in range(int(silent[0]), len(along)):
        if ratio[k] < EDGE_SHARE:
            if ratio[k] <= 0 and not halfway:
                return max(float(along[prev]), 0.0)
            drop = float(ratio[prev] - ratio[k])
            share = (float(ratio[prev]) - EDGE_SHARE) / drop if drop > 0 else 0.5
            return max(float(along[prev] + min(max(share, 0.0), 1.0)
                             * (along[k] - along[prev])), 0.0)
        prev = k
    return max(float(along[prev]), 0.0)


def _fading_end(scene: Scene, q: np.ndarray, t: np.ndarray, along: np.ndarray,
                ratio: np.ndarray, weak: np.ndarray, raised: np.ndarray, T: np.ndarray,
                R: np.ndarray, reach: float) -> float:
    """Where a face ends that every pair beyond its reflection points heard (``along``
    their reflection points' distances from its end ``q``, along its outward tangent
    ``t``), the farthest ``weak``: its echo falls towards half a mirror's as the face
    nears its edge (Kouyoumjian & Pathak 1974). Each weak pair beyond puts the edge where
    a face ending there echoes its ``ratio`` of a mirror's (:func:`~.strength.edge_distance`,
    at most ``reach`` past ``q``; at its reflection point with the edges' echo model the
    estimate, which has no such fall); the median of theirs, no nearer than the farthest
    pair's reflection point, which lies on the face. Where the farthest is ``raised``
    instead (:func:`_raised`: the edge's diffraction in phase, a Fresnel zone or so from
    the edge), the face ends at its reflection point, as at a face's own raised last echo
    (:func:`weakened_ends`). Inf where the farthest pair beyond is neither (the face may
    go on). The zoo's unseen seed 59 edge-02 (σ 0.3): pairs beyond heard 0.83 and 0.72 of
    a mirror's, and the face was drawn 19 cm past its edge; seed 172 wall-04: 0.90, 1.14
    and, the farthest, 1.15, and it was drawn 7 cm past a free end."""
    last = int(np.argmax(along))
    if along[last] <= 0 or not (weak[last] or raised[last]):
        return math.inf
    if not weak[last]:
        return float(along[last])
    k = np.flatnonzero(weak & (along > 0))
    s = _to_edge(scene, ratio[k], T[k], R[k], q + along[k][:, None] * t, t,
                 max(reach - float(along[last]), 0.0))
    return max(float(median(along[k] + s)), float(along[last]))


def _to_edge(scene: Scene, ratio: np.ndarray, T: np.ndarray, R: np.ndarray, q: np.ndarray,
             t: np.ndarray, reach: float) -> np.ndarray:
    """How far past the reflection points ``q`` of the pairs (T, R), along ``t``, the edge
    of a face lies that gives their echoes ``ratio`` of a mirror's
    (:func:`~.strength.edge_distance`, at most ``reach``); 0 with the estimate edge
    model, whose face echoes a mirror's up to its end."""
    if scene.echo.edge_model != "utd":
        return np.zeros(len(ratio))
    k = wavenumber(scene.transducer.frequency_hz, scene.medium.c)
    return edge_distance(ratio, T, R, q, t, k, scene.echo.reflection_coefficient, reach)


def _strength(p: Patch, scene: Scene, heard: Heard, pairs: np.ndarray, path: np.ndarray,
              beams: Beams, ka: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(ratio, loud, spread)`` of ``pairs`` for ``p`` along ``path`` with the two-way
    ``beams`` (q, T, axT, R, axR): the strongest echo within :data:`HEARD_TOL_M` of the
    path, or with noise within the path tolerance of a detection of the echo's strength
    there (:func:`~.window.heard_tolerance`, at most the pulse's resolution c·σ), over
    :func:`_surface_echo` (0: none), whether it is as strong as :func:`_least_echo`, and
    three σ of that ratio's noise (:func:`amplitude_noise` over the surface's echo).
    (At σn 1.2 a wall's echoes of 1.5–2.5 units read 3–5 mm off the plane: the zoo's
    seed 41 wall-08, whose patches ended at their reflection points, 78 % complete.)"""
    mirror = _surface_echo(p, scene, beams, ka)
    c, sigma = scene.medium.c, scene.transducer.pulse_sigma_s
    tolerance = np.minimum(np.maximum(heard_tolerance(mirror, scene.signal.noise_std, c, sigma),
                                      HEARD_TOL_M), c * sigma)
    amplitude, near = loudest(heard, pairs, path, tolerance)
    ratio = np.where(near, amplitude / np.maximum(mirror, 1e-300), 0.0)
    return ratio, near & (amplitude >= _least_echo(p, scene, beams, ka)), _spread(scene, mirror)


def _spread(scene: Scene, echo: np.ndarray) -> np.ndarray:
    """Three σ of a detection's amplitude noise (:func:`amplitude_noise`) over ``echo``:
    of its ratio to the surface's echo."""
    return 3.0 * amplitude_noise(scene) / np.maximum(echo, 1e-300)


def _raised(p: Patch, own: np.ndarray, own_spread: np.ndarray, ratio: np.ndarray,
            spread: np.ndarray) -> np.ndarray:
    """Echoes (``ratio`` of the surface's, noise ``spread``) over :data:`END_RAISED` of the
    face's own (``own``, noise ``own_spread``) beyond noise, where a mirror's echo is the
    surface's within 5 % (κ·r ≤ 0.1) and its own are steady (no sinusoid's stretch)."""
    middle = float(median(own))
    low, high = percentile(own, [10, 90])
    if (0.5 * float(median(p.paths)) <= 0.1 * abs(curve_geometry(p.params, p.x0)[1])
            and high - low <= 0.05 * middle + 2.0 * float(median(own_spread))):
        return ratio - spread > middle * END_RAISED
    return np.zeros(len(ratio), dtype=bool)


def _weakened(ratio: np.ndarray, spread: np.ndarray, middle: float) -> np.ndarray:
    """Echoes (``ratio`` of the surface's, noise ``spread``) under :data:`END_WEAKENING` of
    the face's own (``middle``) beyond their noise: falling towards its edge."""
    return ratio + spread < END_WEAKENING * middle


def _surface_echo(p: Patch, scene: Scene, beams: Beams, ka: float) -> np.ndarray:
    """``p``'s echo at the two-way ``beams``: a mirror's times :func:`_echo_share`."""
    share = _echo_share(p, beams)
    return mirror_echo(scene) * (1.0 if share is None else share) * two_way(*beams, ka)


def _beyond(p: Patch, scene: Scene, sensors: SensorArray, heard: Heard,
            pairs: np.ndarray, weakest: float) -> tuple[np.ndarray, ...]:
    """``(u, ratio, loud, spread, T, R)`` (:func:`_strength`) of the ``pairs`` in front of
    the surface whose reflection points lie beyond the patch's own, inside both beams, and
    that would hear it there at least as well as the patch's weakest detection (tests in order of
    cost: each on the pairs the last one kept); ``u`` their reflection points'
    coordinates."""
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
    louder = two_way(q[ok], T[ok], axT[ok], R[ok], axR[ok], ka) >= weakest * (1.0 - 1e-9)
    ok, u = ok[louder], u[louder]
    beams = (q[ok], T[ok], axT[ok], R[ok], axR[ok])
    return (u, *_strength(p, scene, heard, pairs[ok], path[ok], beams, ka), T[ok], R[ok])


def _echo_share(p: Patch, beams: Beams) -> np.ndarray | None:
    """``p``'s echo over a mirror's at the pairs' ``beams`` (1 for a plane; a circle's
    divergence, :func:`~.strength.convex_share`; None for a point-like circle)."""
    return convex_share(p.params, p.x0, beams[0], beams[1], beams[3], p.paths)


def _least_echo(p: Patch, scene: Scene, beams: Beams, ka: float) -> np.ndarray:
    """The least amplitude at which pairs with the two-way ``beams`` (q, T, axT, R, axR)
    hear ``p``: a plane's a mirror's floor (:func:`~.strength.mirror_floor`), a circle
    the same with the mirror weakened by its divergence (:func:`_echo_share`: a face's
    last echoes, shifted by its edge's diffraction, fit a circle, and that diffraction
    past its end is not its echo); anything for a point-like one."""
    share = _echo_share(p, beams)
    if share is None:  # a point-like circle's echo may be as weak as an edge's
        return np.full(len(beams[0]), -np.inf)
    return mirror_floor(*beams, mirror_echo(scene) * share, ka, amplitude_noise(scene))


def flat(p: Patch) -> bool:
    """Whether ``p`` is a plane or a circle at least as flat as its range
    (:func:`~.strength.as_flat_as_its_range`): a face, or its slightly bent last stretch,
    whose echo is a mirror's (:func:`_least_echo`), not a curved wall's own bent circle."""
    return p.straight or as_flat_as_its_range(p.params, p.x0, p.paths)


def _listeners(p: Patch, sensors: SensorArray) -> Iterator[tuple[bool, np.ndarray]]:
    """``(own, pairs)``: the pairs of the patch's own group, then, for a plane, those of
    every other group (its line is the surface's wherever it is drawn; a circle is only a
    curved wall's local shape, which another array's pairs, seeing the wall elsewhere,
    would not hear)."""
    group = sensors.groups[int(p.tx[0])]
    for pairs in group_pairs(sensors, group):
        yield True, pairs
    if not p.straight:
        return
    for other in unique(sensors.groups):
        if other != group:
            for pairs in group_pairs(sensors, other):
                yield False, pairs


def spread_patch(p: Patch, scene: Scene, sensors: SensorArray, heard: Heard,
                 amplitude: np.ndarray) -> Patch:
    """``p`` over its regions of constant depth, cut where the array heard nothing (the
    detections ``heard``, :func:`~.heard.heard_index`) or, where nothing beyond could
    tell, at an end its echoes say is near (:func:`weakened_ends`), as far as its curvature is known
    (:func:`trusted_reach`, by its paths or by its echoes' strength ``amplitude``:
    :func:`strength_bend`)."""
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    span = extents(p, sensors, cut_sin2, scene.medium.c * scene.transducer.pulse_sigma_s)
    lo, hi = clamp_to_silence(p, scene, sensors, heard, *span)
    first, last = weakened_ends(p, scene, sensors, amplitude, span)
    lo = p.lo - first if first is not None and lo == span[0] else lo
    hi = p.hi + last if last is not None and hi == span[1] else hi
    reach = trusted_reach(replace(p, bend=min(p.bend, strength_bend(p, scene, sensors,
                                                                     amplitude))))
    return replace(p, lo=min(max(lo, p.lo - reach), p.lo), hi=max(min(hi, p.hi + reach), p.hi))


#: A face's outermost echo under this share of its median one, or over it by
#: :data:`END_RAISED` (a steady mirror's: the knife edge's ripples raise it to 1.17 and
#: 1.08 within 1.5 Fresnel zones of its edge; 1.11 before stop 42: the zoo's unseen seed
#: 119 wall-09, a last echo 1.095 of the others' 5 cm from a free end, the face drawn 10
#: cm past it), beyond three noise σ, ends it within a Fresnel zone (:func:`weakened_ends`).
END_WEAKENING = 0.9
END_RAISED = 1.05


def weakened_ends(p: Patch, scene: Scene, sensors: SensorArray, amplitude: np.ndarray,
                  span: tuple[float, float]) -> tuple[float | None, float | None]:
    """Where the echo (``amplitude``) of ``p``'s first and last reflection points over
    the surface's there (:func:`_surface_echo`) is off its median (:data:`END_WEAKENING`),
    how far past that reflection point the face ends (None where it is not off): a face's
    echo falls to half a mirror's as its reflection point nears its edge over about a
    Fresnel zone, √(λ·r/2) (8 cm at 1.5 m; Kouyoumjian & Pathak 1974), so a weakened
    one puts the edge where a face ending there gives it (a plane's, :func:`_to_edge`,
    within its region of constant depth ``span``; the zoo's unseen seed 37 edge-02, σ
    0.3, a face stopped at its last reflection point 3.4 cm short of its edge); a raised
    one, its echo rising to 1.17 of it a zone or so before (the edge's diffraction in
    phase: the zoo's seed 45 wall-04, a pair's echo 1.14 of the others' 2–5 cm from a
    free end, the face drawn 9.7 cm past it; raised only where the surface echoes a
    mirror's, steadily), at that point. Neither with threshold detection (a sample) or
    no mirror."""
    if scene.detection.mode != "envelope" or mirror_echo(scene) <= 0 or len(amplitude) < 3:
        return None, None
    beams = own_beams(p, sensors)
    echo = np.maximum(_surface_echo(p, scene, beams, scene.transducer.beam(scene.medium.c)[1]),
                      1e-300)
    ratio, spread = amplitude / echo, _spread(scene, echo)
    middle = float(median(ratio))
    weak = _weakened(ratio, spread, middle)
    off = weak | _raised(p, ratio, spread, ratio, spread)
    ends: list[float | None] = []
    for i, reach in ((int(np.argmin(p.u)), p.lo - span[0]), (int(np.argmax(p.u)), span[1] - p.hi)):
        if not off[i]:
            ends.append(None)
        elif weak[i] and p.straight:
            q = carrier_points(p.params, p.x0, p.u[i:i + 1])
            ends.append(float(_to_edge(scene, ratio[i:i + 1], p.T[i:i + 1], p.R[i:i + 1], q,
                                       outward(p, float(p.u[i])), max(reach, 0.0))[0]))
        else:
            ends.append(0.0)
    return ends[0], ends[1]


def strength_bend(p: Patch, scene: Scene, sensors: SensorArray, amplitude: np.ndarray
                  ) -> float:
    """3σ of a plane's curvature (1/m) as its echoes' strength ``amplitude`` measures it:
    a curved wall's echo is a flat mirror's times sqrt(L / (L + 2κ·d1·d2/cosθi))
    (physics.curved_gain: a convex wall's divergence, a concave one's focusing), so each
    echo over a mirror's, ``g``, gives κ = (1/g² − 1)·L·cosθi / (2·d1·d2), to within its
    amplitude noise (:func:`amplitude_noise`) over the mirror's; their weighted mean plus
    three σ (its noise or its scatter, the larger), where that is flatter than a surface
    of unknown curvature is taken to be (radius no less than the range,
    :func:`trusted_reach`) and the mean shows no curvature, beyond its 3σ, that would
    bend the wall more than :data:`PATCH_BIAS_M` over a region of constant depth
    (√(c·τ·c·σ/2)): such a wall is a curved reflector, whose reflection points and beams
    a plane misplaces (a 1.19 m cylinder's ten echoes, named a plane, read 0.63 /m for
    its 0.84). Inf (unknown) otherwise, for a circle, or where the strength does not
    follow the curvature: threshold detection (the amplitude is a sample), or a scene
    without the curvature gain."""
    if (not p.straight or not scene.echo.curvature_gain or scene.detection.mode != "envelope"
            or len(amplitude) < 2):
        return math.inf
    ka = scene.transducer.beam(scene.medium.c)[1]
    beams = own_beams(p, sensors)
    q = beams[0]
    mirror = mirror_echo(scene) * two_way(*beams, ka)
    d1 = np.maximum(np.hypot(*(p.T - q).T), 1e-12)
    d2 = np.maximum(np.hypot(*(p.R - q).T), 1e-12)
    n = np.array([math.cos(float(p.params[0])), math.sin(float(p.params[0]))])
    cos_i = np.maximum(np.abs(dot2((p.T - q) / d1[:, None], n)), 1e-6)
    per = 2.0 * d1 * d2 / ((d1 + d2) * cos_i)  # dL_eff / L per unit curvature
    g = np.maximum(amplitude / np.maximum(mirror, 1e-300), 1e-6)
    kappa = (1.0 / g**2 - 1.0) / per
    sigma = 2.0 * amplitude_noise(scene) / np.maximum(mirror, 1e-300) / (g**3 * per)
    weight = 1.0 / sigma**2 if np.all(sigma > 0) else np.ones(len(kappa))
    mean = float(np.sum(weight * kappa) / np.sum(weight))
    spread = math.sqrt(float(np.sum(weight * (kappa - mean) ** 2) / np.sum(weight))
                       / (len(kappa) - 1))
    noise = math.sqrt(1.0 / float(np.sum(weight))) if np.all(sigma > 0) else 0.0
    bound = abs(mean) + 3.0 * max(noise, spread)
    # a curvature the echoes show (beyond 3σ) that would bend the wall more than
    # PATCH_BIAS_M over a region of constant depth, sqrt(c·τ·c·σ/2) (docs/mapping.md):
    # a curved reflector, whose reflection points and beams a plane misplaces
    region2 = float(median(p.paths)) * scene.medium.c * scene.transducer.pulse_sigma_s / 2
    if abs(mean) > 3.0 * max(noise, spread) and abs(mean) > 2.0 * PATCH_BIAS_M / region2:
        return math.inf
    return bound if bound < 2.0 / float(median(p.paths)) else math.inf


#: A patch is extended only as far as a surface of the curvature its detections allow
#: (:attr:`~.families.Family.bend`) stays within this of it, metres.
PATCH_BIAS_M = 0.002


def trusted_reach(p: Patch) -> float:
    """How far beyond its reflection points (in its coordinate) a patch may go: where a
    curve bent by ``p.bend`` more than the fitted one leaves it by :data:`PATCH_BIAS_M`;
    with the bend unknown, as far as a surface of radius no less than the range stays
    within that of the tangent (the tangent stretch of :mod:`.tangents`)."""
    bend = p.bend if math.isfinite(p.bend) else 2.0 / float(median(p.paths))
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


__all__ = ["BISECTIONS", "PATCH_BIAS_M", "STEP_CELLS", "Beams", "Patch", "Patches",
           "carrier_points", "clamp_to_silence", "coordinates", "draw_patch",
           "extents", "flat", "outward", "patch_of", "spread_patch",
           "strength_bend", "trusted_reach"]
