"""Tangent points (``mapping.mode = "tangents"``, the default): the points where the loci of
neighbouring transducers cross inside all beams, with the loci's tangent segments around
them (:func:`tangent_points`; docs/mapping.md)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import steps
from ..numerics import median, unique
from ..physics import absorption_factor, piston_pattern
from ..scene import Scene
from ..sensors import SensorArray
from ..signals import envelope_noise_scale, signal_model
from .envelope import (
    ENVELOPE_ARC_BIAS_M,
    beam_arc_samples,
    element_scans,
    envelope_links,
    in_beams,
    scan_envelope,
    two_pose_links,
)
from .families import two_way, window_tolerance
from .heard import amplitude_noise
from .loci import Loci, as_loci
from .middles import LOCUS_SAMPLES, arcs_around, middle_of_arc
from .mirrored import on_the_surface
from .models import ellipse_axes
from .pillars import (
    MIN_PILLAR_LOCI,
    PILLAR_TOL_M,
    a_plane_not_a_corner,
    loci_crossing,
    pillar_arc,
    pillar_circles,
    point_reflectors,
)
from .points import densified, nonzero_cells
from .strength import circle_echo, corner_echo, loud_beams, mirror_echo, quieter_than_a_plane

#: Most radial error a pair of loci may contribute: two circles of radius r tangent to a
#: plane at feet δ apart cross δ²/(8r) in front of it, so pairs need δ ≤ sqrt(8·r·bias).
TANGENT_BIAS_M = 0.002

#: Spacing of the samples of a stretch between envelope points, metres (about the spacing
#: of a locus' own samples, 0.25° at 0.5 m: a stretch weighs as much as the arcs it joins).
LINK_STEP_M = 0.002

#: A pillar is seen through where an element's first echo came from beyond it within this
#: share of the beam's half-angle (sine) of the element's axis, and the pillar's echo there
#: would have been as strong as the weakest of the echoes that place it
#: (:func:`circle_echo`), by :data:`HEARD_NOISE_SCALES` of the envelope's noise to spare.
SEEN_THROUGH_SHARE = 1.0 / 3.0
HEARD_NOISE_SCALES = 3.0

#: The echoes that place a pillar are at most this many times as loud as the circle's
#: echo (their median and MIN_PILLAR_LOCI of them, noise to spare): a wall's echoes, a
#: mirror's, are 2.5–6 times a 0.2 m pillar's at 1–6 m, and a ring moving straight at a
#: wall hears its foot as every locus' tangent point, which a circle can mimic.
CIRCLE_ECHO_FACTOR = 2.0


def _locus_samples(scene: Scene, sensors: SensorArray, loci: Loci):
    """[n, S, 2] points of each locus (ellipse with foci T, R and path length c·τ) and
    [n, S] whether each lies inside both beams; [n] the half path length a.

    Only the samples near T's beam are computed (the others are left 0 and outside): with T
    a focus, the ray from T at angle ν from the major axis meets the ellipse once, at
    eccentric anomaly E = 2·atan2(√(1+e)·sin(ν/2), √(1−e)·cos(ν/2)) (e = f/a), so T's beam
    (ν within ±α of its axis) is one arc of samples; two samples more either side are
    tested as well, and each sample is then tested exactly as before."""
    pos, axes = sensors.positions, sensors.axes
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    T, R = pos[loci.tx], pos[loci.rx]
    a, f, b, u = ellipse_axes(T, R, scene.medium.c * loci.tof_s)
    v = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    phi = 2 * np.pi * np.arange(LOCUS_SAMPLES) / LOCUS_SAMPLES
    centre = 0.5 * (T + R)
    rows, ks = beam_arc_samples(u, v, axes[loci.tx], a, f, cut_sin2, LOCUS_SAMPLES)
    p = np.zeros((len(a), LOCUS_SAMPLES, 2))
    # cos and sin of the 1,440 angles, gathered: each element's bits whatever the array
    at = (centre[rows] + (a[rows] * np.cos(phi)[ks])[:, None] * u[rows]
          + (b[rows] * np.sin(phi)[ks])[:, None] * v[rows])
    p[rows, ks] = at
    inside = np.zeros((len(a), LOCUS_SAMPLES), dtype=bool)
    inside[rows, ks] = in_beams(at, T[rows], axes[loci.tx][rows], cut_sin2)
    inside &= (a > f)[:, None]
    # R's beam tested only where T's holds (a small part), and not where R is T (the same
    # test on the same numbers: it holds)
    i, k = nonzero_cells(inside & (loci.tx != loci.rx)[:, None])
    inside[i, k] = in_beams(p[i, k], R[i], axes[loci.rx][i], cut_sin2)
    return p, inside, a


@dataclass(frozen=True, eq=False)
class SampledLoci:
    """The loci, their samples (:func:`_locus_samples`) and what the crossings need."""

    loci: Loci
    p: np.ndarray  # [n, S, 2] samples
    inside: np.ndarray  # [n, S] in both beams
    a: np.ndarray  # [n] half path length
    T: np.ndarray  # [n, 2] transmitter positions
    R: np.ndarray  # [n, 2] receiver positions
    centre: np.ndarray  # [n, 2] (T + R)/2
    axes: np.ndarray  # the sensors' unit axes
    cut_sin2: float


def sample_loci(scene: Scene, sensors: SensorArray, loci) -> SampledLoci:
    """The loci sampled every 360°/:data:`LOCUS_SAMPLES` of eccentric anomaly, each sample
    tested against both beams (:func:`_locus_samples`), with what their crossings need
    (:func:`locus_crossings`)."""
    loci = as_loci(loci)
    p, inside, a = _locus_samples(scene, sensors, loci)
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    T, R = sensors.positions[loci.tx], sensors.positions[loci.rx]
    return SampledLoci(loci, p, inside, a, T, R, 0.5 * (T + R), sensors.axes, cut_sin2)


def run_starts(inside: np.ndarray) -> np.ndarray:
    """[n] the first sample of each locus' run of samples in both beams (``inside`` [n, S];
    the run may wrap around sample 0; 0 for a locus with none, or all, in)."""
    starts = inside & ~np.roll(inside, 1, axis=-1)
    return np.where(starts.any(axis=-1), np.argmax(starts, axis=-1), 0)


def _neighbour_pairs(s: SampledLoci, groups: np.ndarray, lo: int, hi: int,
                     max_bias_m: float) -> tuple[np.ndarray, np.ndarray]:
    """``(mine, other)``: for each locus from ``lo`` to ``hi`` that has a sample in its
    beams, the later loci of its viewpoint whose centres lie within sqrt(8·a·max_bias_m)
    of its own; by locus, then by other."""
    i, j = np.arange(lo, hi)[:, None], np.arange(len(s.loci))
    has = np.asarray(s.inside[lo:hi].any(axis=1))[:, None]
    mine, other = nonzero_cells((groups[j] == groups[i]) & (j > i) & has)
    mine = mine + lo
    near = np.hypot(*(s.centre[other] - s.centre[mine]).T) <= np.sqrt(8.0 * s.a[mine] * max_bias_m)
    return mine[near], other[near]


def _crossings(s: SampledLoci, i: int, others: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, k, b)``: where locus i crosses ``others`` between samples k and k+1 (both in
    i's beams), interpolated, and the locus b crossed; in every beam of b or not, unchecked
    (:func:`_pair_crossings` of the pairs (i, b))."""
    q, k, _, b = _pair_crossings(s, np.full(len(others), i), np.asarray(others, np.int64))
    return q, k, b


def _pair_crossings(s: SampledLoci, mine: np.ndarray, other: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(q, k, i, b)``: where each locus ``mine[n]`` crosses ``other[n]`` between its samples k
    and k+1 (both in its beams), interpolated: the sign changes of b's path-length
    residual |q−T| + |q−R| − 2a, evaluated only at those steps (the in-beam arc is a small
    part); ordered by pair, then by k. Element by element as for one locus at a time: the
    residual at sample k + 1 of a pair's step k is its next step's own where that step
    follows (the same point, the same locus b: the same number), computed once."""
    rows, inv = np.unique(mine, return_inverse=True)
    ok = s.inside[rows] & np.roll(s.inside[rows], -1, axis=-1)
    row_of, step_of = nonzero_cells(ok)  # each row's steps, ascending
    first = np.searchsorted(row_of, np.arange(len(rows)))
    count = np.count_nonzero(ok, axis=-1)[inv]
    pair = np.repeat(np.arange(len(mine)), count)
    k = step_of[np.repeat(first[inv] - np.cumsum(count) + count, count) + np.arange(len(pair))]
    i, b = mine[pair], other[pair]
    flat = s.p.reshape(-1, 2)  # one index a sample: a third quicker than [i, k]
    here = flat[i * LOCUS_SAMPLES + k]
    g_here = _path_residual(s, here, b)
    follows = np.zeros(len(k), dtype=bool)
    follows[:-1] = (pair[1:] == pair[:-1]) & (k[1:] == k[:-1] + 1)
    g_next = np.empty_like(g_here)
    g_next[:-1] = g_here[1:]
    alone = np.flatnonzero(~follows)  # a pair's last step, or one before a gap
    after = i[alone] * LOCUS_SAMPLES + (k[alone] + 1) % LOCUS_SAMPLES
    g_next[alone] = _path_residual(s, flat[after], b[alone])
    n = np.flatnonzero(np.sign(g_here) != np.sign(g_next))
    t = g_here[n] / (g_here[n] - g_next[n])
    there = flat[i[n] * LOCUS_SAMPLES + (k[n] + 1) % LOCUS_SAMPLES]
    return here[n] + t[:, None] * (there - here[n]), k[n], i[n], b[n]


def _path_residual(s: SampledLoci, q: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each locus b's path-length residual |q−T| + |q−R| − 2a at its ``q``; |q−R| is
    |q−T| itself where R equals T (the same numbers: even a signed zero's difference has
    the same hypot), taken only where they differ."""
    dT = q - s.T[b]
    to_t = np.hypot(dT[:, 0], dT[:, 1])
    to_r = to_t.copy()
    two = np.flatnonzero(np.any(s.T != s.R, axis=1)[b])
    dR = q[two] - s.R[b[two]]
    to_r[two] = np.hypot(dR[:, 0], dR[:, 1])
    return to_t + to_r - 2 * s.a[b]


def locus_crossings(s: SampledLoci, i: int, others: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(q, k, b)``: where locus i crosses the loci ``others`` inside the joint beam
    regions of both (:func:`_crossings`, then the beams of the locus b crossed)."""
    q, k, b = _crossings(s, i, others)
    keep = (in_beams(q, s.T[b], s.axes[s.loci.tx[b]], s.cut_sin2)
            & in_beams(q, s.R[b], s.axes[s.loci.rx[b]], s.cut_sin2))
    return q[keep], k[keep], b[keep]


def _tangent_segments(s: SampledLoci, i: int, ks: np.ndarray,
                      max_bias_m: float) -> list[np.ndarray]:
    """The locus stays within max_bias_m of the surface for ±sqrt(2·r·bias) of arc around
    its tangent point: the in-beam samples of locus i that far around each sample in ``ks``."""
    half = int(np.sqrt(2.0 * max_bias_m / s.a[i]) / (2 * np.pi / LOCUS_SAMPLES))
    out = []
    for centre_k in unique(ks):
        idx = (centre_k + np.arange(-half, half + 1)) % LOCUS_SAMPLES
        out.append(s.p[i][idx[s.inside[i, idx]]])
    return out


def _isolated_points(s: SampledLoci, isolated: np.ndarray, bias: float, linked: np.ndarray,
                     env: tuple[np.ndarray, ...]) -> tuple[list[np.ndarray], list[int]]:
    """Per locus in ``isolated``: where the scan envelope ``env`` has points on it, the arcs
    around them inside the element's beam (:func:`~.middles.arcs_around`); else the middle of its
    in-beam arc (none for a locus in ``linked``: the scan envelope's links already hold its
    surface point). And the slots of the loci given a middle of arc (point and pillar)."""
    arcs, locus = arcs_around(env, min(bias, ENVELOPE_ARC_BIAS_M))
    beam = in_beams(arcs, s.T[locus], s.axes[s.loci.tx[locus]], s.cut_sin2)
    order = np.argsort(locus[beam], kind="stable")  # by locus, in the envelope's order
    arcs, ends = arcs[beam][order], np.searchsorted(locus[beam][order], [isolated, isolated + 1])
    enveloped, linked_set, found, stubs = np.isin(isolated, env[0]), set(linked.tolist()), [], []
    for k, (i, a, b) in enumerate(zip(isolated.tolist(), *ends.tolist(), strict=True)):
        if enveloped[k] or i in linked_set:  # a linked locus has no arc (a = b)
            found.append(arcs[a:b])
        else:
            found.append(middle_of_arc(s.p[i], s.inside[i], s.a[i], bias))
            if len(found[-1]):
                stubs.append(k)
    return found, stubs


def _range_tolerance(scene: Scene, s: SampledLoci, loci: np.ndarray) -> np.ndarray:
    """How far the range of each of ``loci`` may be off, metres: its noise
    (:func:`_range_noise`), at least :data:`~.pillars.PILLAR_TOL_M`."""
    return np.maximum(PILLAR_TOL_M, _range_noise(scene, s, loci))


def _range_noise(scene: Scene, s: SampledLoci, loci: np.ndarray) -> np.ndarray:
    """Half the detection window's tolerance of each of ``loci`` (its noise), metres."""
    return 0.5 * window_tolerance(s.loci.amplitude[loci], scene.signal.noise_std,
                                  scene.medium.c, scene.transducer.pulse_sigma_s)


#: A locus drawn around its scan envelope's points is a point reflector's only where they
#: lie within this of the reflector, metres (the envelope's central differences put a
#: corner's point a few cm off at a metre's step: O(step²), exact only for a plane).
POINT_ENVELOPE_M = 0.15


def _points(scene: Scene, s: SampledLoci, loci: np.ndarray, found: list[np.ndarray],
            slots: list[int], stubs: set[int], env: tuple[np.ndarray, ...]
            ) -> dict[int, np.ndarray]:
    """``{slot: point}``: the arcs (``found[slot]`` of locus ``loci[n]``) whose loci cross
    at one point inside their beams, from three positions or more — a corner's
    retro-reflection or an edge (:func:`~.pillars.point_reflectors`): the point in place
    of the arc, which would stand across the corner, tangent to the locus, up to
    sqrt(2·a·bias) long. A middle-of-arc stub (slot in ``stubs``) may be anywhere in the
    beam; an arc around the scan envelope's points ``env`` must be around this point
    (consecutive poses' loci of a point reflector touch there)."""
    if len(loci) < MIN_PILLAR_LOCI:
        return {}
    T, R = s.T[loci], s.R[loci]
    t_axes, r_axes = s.axes[s.loci.tx[loci]], s.axes[s.loci.rx[loci]]
    middles = np.array([found[k].mean(axis=0) if k in stubs
                        else env[3][env[0] == i].mean(axis=0)
                        for k, i in zip(slots, loci, strict=True)])
    reach = np.array([np.inf if k in stubs else POINT_ENVELOPE_M for k in slots])

    def admits(v: np.ndarray) -> np.ndarray:
        return (in_beams(v[None], T, t_axes, s.cut_sin2)
                & in_beams(v[None], R, r_axes, s.cut_sin2)
                & (np.hypot(*(middles - v).T) <= reach))

    def quiet(normal: np.ndarray, m: np.ndarray) -> bool:
        return quieter_than_a_plane(scene, normal, T[m], t_axes[m], R[m], r_axes[m],
                                    s.a[loci][m], s.loci.amplitude[loci][m], noise)

    noise = amplitude_noise(scene)
    tight = _range_noise(scene, s, loci)
    points = point_reflectors(T, R, s.a[loci], middles, np.maximum(PILLAR_TOL_M, tight),
                              admits, quiet, tight)
    return {slots[n]: v for n, v in points.items()}


def envelope_noise(scene: Scene) -> float:
    """The Rayleigh scale of the noise on a detection's envelope, units (0 noise-free;
    :func:`~clsonar.signals.envelope_noise_scale`, which does not depend on the detection's
    floor: a floor the scene leaves to be chosen is taken as 0 for it)."""
    if scene.signal.noise_std == 0:
        return 0.0
    if scene.detection.min_envelope is None:
        scene = replace(scene, detection=replace(scene.detection, min_envelope=0.0))
    return envelope_noise_scale(signal_model(scene))


def _touching(scene: Scene, s: SampledLoci, loci: np.ndarray,
              circles: list[tuple[np.ndarray, float]]) -> list[int]:
    """The indices of the T = R ``loci`` that touch one of the pillars ``circles`` within
    their range tolerance: a pillar's echoes, though not among the stubs it was fitted
    to (never a face between two poses: the zoo's unseen seed 135 room-24, one element's
    echoes of a 0.27 m pillar from two consecutive poses drawn as a 0.5 m face tangent
    to it, 0.68 cm RMS)."""
    if not circles or len(loci) == 0:
        return []
    mono = s.loci.tx[loci] == s.loci.rx[loci]
    tol = _range_tolerance(scene, s, loci)
    near = np.zeros(len(loci), dtype=bool)
    for centre, radius in circles:
        near |= np.abs(np.hypot(*(s.T[loci] - centre).T) - s.a[loci] - radius) <= tol
    return np.flatnonzero(mono & near).tolist()


def first_echoes(loci: Loci, a: np.ndarray) -> np.ndarray:
    """The index of each element's nearest T = R locus (``a`` the loci's half paths): the
    first echo, from the nearest surface in its beam (thesis §2.1.1)."""
    mono = np.flatnonzero(loci.tx == loci.rx)
    order = mono[np.lexsort((a[mono], loci.tx[mono]))]
    return order[np.r_[True, loci.tx[order][1:] != loci.tx[order][:-1]]]


def _pillars(scene: Scene, s: SampledLoci, loci: np.ndarray, found: list[np.ndarray],
             slots: list[int], bias: float
             ) -> tuple[dict[int, np.ndarray], list[tuple[np.ndarray, float]]]:
    """``({slot: arc}, [(centre, radius)])``: the middle-of-arc stubs (``found[slot]`` of
    T = R locus ``loci[n]``) that a pillar fitted to their ranges replaces
    (:mod:`.pillars`), each arc kept inside its element's beam, and the pillars."""
    if len(loci) < MIN_PILLAR_LOCI:
        return {}, []
    T, tol = s.T[loci], _range_tolerance(scene, s, loci)
    middles = np.array([found[k].mean(axis=0) for k in slots])
    first = first_echoes(s.loci, s.a)
    axes, first_tol = s.axes[s.loci.tx[first]], _range_tolerance(scene, s, first)
    spare = HEARD_NOISE_SCALES * envelope_noise(scene)

    def seen_through(centre: np.ndarray, radius: float, reach: float) -> bool:
        """Whether the scan rules the circle out: the loci that touch it are louder than it can echo
        (:data:`CIRCLE_ECHO_FACTOR`: a wall's echoes, from poses moving towards it), fewer than
        MIN_PILLAR_LOCI of them are each no louder (a box's corner), or an element within
        ``reach`` of the circle had its first T = R echo from beyond the circle's point nearest
        it, near its beam's axis (:data:`SEEN_THROUGH_SHARE`), where the circle's echo
        (:func:`circle_echo`) would have been as strong as the weakest echo of the loci that touch
        it, noise to spare: the element would have heard the circle first. Nearer the beam's edge,
        from farther than the loci that touch it, or weaker, a pillar's echo may be missed."""
        touching = np.abs(np.hypot(*(T - centre).T) - s.a[loci] - radius) <= tol
        own = circle_echo(scene, T[touching], s.axes[s.loci.tx[loci[touching]]], centre,
                          radius)
        heard = s.loci.amplitude[loci[touching]]
        if (np.count_nonzero(heard - spare <= CIRCLE_ECHO_FACTOR * own) < MIN_PILLAR_LOCI
                or median((heard - spare) / own) > CIRCLE_ECHO_FACTOR):
            return True
        d = s.T[first] - centre
        near = np.hypot(*d.T) - radius
        q = centre + radius * d / np.maximum(near + radius, 1e-12)[:, None]
        beyond = ((near < s.a[first] - first_tol) & (near <= reach)
                  & in_beams(q, s.T[first], axes, SEEN_THROUGH_SHARE**2 * s.cut_sin2))
        if not (beyond.any() and touching.any()):
            return bool(beyond.any())
        echo = circle_echo(scene, s.T[first][beyond], axes[beyond], centre, radius)
        return bool(np.any(echo >= own.min() + spare))

    circles = pillar_circles(T, s.a[loci], middles, tol, seen_through)
    out = {}
    for centre, radius, ks in circles:
        for n in ks.tolist():
            arc = pillar_arc(centre, radius, T[n], float(s.a[loci[n]]), bias, 0.5 * scene.cell)
            out[slots[n]] = arc[in_beams(arc, T[n], s.axes[s.loci.tx[loci[n]]], s.cut_sin2)]
    return out, [(centre, radius) for centre, radius, _ in circles]


#: A T = R echo this little farther than its element's first one, metres, is a multiple
#: reflection's (the double bounce in the corner beside the wall heard first, a wall's
#: echo via a nearby obstacle): the thesis keeps only the first (§2.1.1).
MULTIPATH_M = 0.15


def _just_after_first(s: SampledLoci, isolated: np.ndarray, stubs: list[int]) -> list[int]:
    """The slots of ``stubs`` whose T = R locus lies within :data:`MULTIPATH_M` beyond a
    nearer T = R locus of the same element: drawn as the middle of its in-beam arc it would
    stand a few cm behind the surface heard first, too near it for the line of sight to
    tell (its ghost and the surface thin into one thick curve)."""
    tx, rx = s.loci.tx, s.loci.rx
    nearest = first_echoes(s.loci, s.a)
    first = np.full(int(tx.max(initial=0)) + 1, np.inf)  # each element's nearest echo
    first[tx[nearest]] = s.a[nearest]
    i = isolated[np.asarray(stubs, dtype=np.int64)]
    after = (tx[i] == rx[i]) & (first[tx[i]] < s.a[i]) & (s.a[i] <= first[tx[i]] + MULTIPATH_M)
    return [k for k, late in zip(stubs, after, strict=True) if late]


def _facing_too_weak(scene: Scene, s: SampledLoci, loci: np.ndarray, bias: float) -> np.ndarray:
    """[n] Whether the echo of each T = R locus of ``loci`` is too weak for the middle of
    its in-beam arc: that stub is within ``bias`` of the surface only where a surface
    faces the element's axis within θ, ρ·(1 − cos θ) = bias, and what faces it so near
    the axis echoes at least A0·ρ²·b(θ)² (a concave corner's retro-reflection, two
    reflections, the weakest; a wall's is A0·ρ·b(θ)²; absorbed over 2ρ) — more than the
    echo by three envelope noise scales to spare. A weaker echo is a surface seen off
    the axis (the face of a box seen obliquely, its end beside the stub: the stub stands
    ρ·θ²/2 in front of it, or in free space past its edge), or a weak reflector's that
    no point or pillar explained. Nothing is decided where the amplitude cannot tell the
    angle: under threshold detection (a sample, not the echo's peak) or a uniform beam
    (``transducer.directivity``, the thesis' world: every angle inside the cut echoes
    alike, and a weaker echo there is one lowered by another overlapping it — a wall's
    25 cm from a corner at 0.83 of a mirror's in the bundled room-per-wall-steps)."""
    loci = np.asarray(loci, dtype=np.int64)
    out = np.zeros(len(loci), dtype=bool)
    mono = s.loci.tx[loci] == s.loci.rx[loci]
    _, ka = scene.transducer.beam(scene.medium.c)
    if scene.detection.mode != "envelope" or ka == 0 or not mono.any():
        return out
    rho = s.a[loci[mono]]
    theta = np.arccos(np.clip(1.0 - bias / rho, -1.0, 1.0))
    facing = (mirror_echo(scene) * scene.echo.reflection_coefficient
              * piston_pattern(ka * np.sin(theta)) ** 2
              * absorption_factor(2.0 * rho, scene.echo.absorption_db_per_m))
    spare = HEARD_NOISE_SCALES * envelope_noise(scene)
    out[mono] = s.loci.amplitude[loci[mono]] + spare < facing
    return out


def plane_echoes(scene: Scene, s: SampledLoci, loci: list[int], normal: np.ndarray) -> bool:
    """Whether the T = R ``loci`` (two or more) are a plane's with unit ``normal`` (towards the
    transducers; :func:`~.pillars.a_plane_not_a_corner`): heard as loud as its echo at each
    reflection point T − ρ·n would be (a mirror's A0·ρ times the two-way beam there and the
    absorption over 2ρ), not as a concave corner's at the first two's crossing (two reflections: the
    reflection coefficient squared, as in :func:`_facing_too_weak`), three envelope noise scales to
    spare. False where the amplitude cannot tell (threshold detection, a uniform beam)."""
    _, ka = scene.transducer.beam(scene.medium.c)
    idx = np.asarray(loci, dtype=np.int64)
    if scene.detection.mode != "envelope" or ka == 0 or np.any(s.loci.tx[idx] != s.loci.rx[idx]):
        return False
    return a_plane_not_a_corner(s.loci.amplitude[idx], *plane_and_corner(scene, s, idx, normal),
                                HEARD_NOISE_SCALES * envelope_noise(scene))


def plane_and_corner(scene: Scene, s: SampledLoci, idx: np.ndarray, normal: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The echoes of the T = R loci ``idx`` from the plane they touch with unit ``normal``
    (towards them), and from a concave corner at the first two's crossing."""
    _, ka = scene.transducer.beam(scene.medium.c)
    T, axes, rho = s.T[idx], s.axes[s.loci.tx[idx]], s.a[idx]
    q = T - rho[:, None] * normal
    mirror = mirror_echo(scene) * absorption_factor(2.0 * rho, scene.echo.absorption_db_per_m)
    return (mirror * two_way(q, T, axes, T, axes, ka),
            corner_echo(scene, loci_crossing(T, rho, q.mean(axis=0)), T, axes, rho, ka))


def _two_pose_faces(scene: Scene, sensors: SensorArray, s: SampledLoci, points: np.ndarray,
                    scans: list, isolated: np.ndarray, bias: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The stretches between the loci of one element heard from two (or three) consecutive
    poses only (:func:`~.envelope.two_pose_links`: a box's face a ring passes obliquely)
    where all are isolated, none a point reflector's nor a pillar's (``points``: the
    loci those explain), and their echoes are the plane's of their common tangent
    (:func:`plane_echoes`): two circles always have one, and a concave corner heard
    twice has both loci through its vertex, heard at angles either side of the tangent's
    (one louder than the plane would be, one weaker, or both weaker), and a pillar echoes
    sqrt(R/(R + d)) of a plane."""

    def plane(loci: list[int], normal: np.ndarray) -> bool:
        return (bool(np.all(np.isin(loci, isolated))) and not np.any(np.isin(loci, points))
                and plane_echoes(scene, s, loci, normal))

    return two_pose_links(scene, sensors, s.loci, LINK_STEP_M, bias, plane, scans)


def _add_isolated(scene: Scene, sensors: SensorArray, s: SampledLoci, isolated: np.ndarray,
                  bias: float, found: list[np.ndarray], source: list[np.ndarray],
                  vertices: list[np.ndarray]) -> None:
    """Append to ``found`` and ``source`` what the ``isolated`` loci give: the scan
    envelope's links between them (:func:`~.envelope.envelope_links`; none between two
    loci a point reflector explains), and each one's
    points (:func:`_isolated_points`), a pillar's stretch for those a pillar explains
    (:func:`_pillars`), the point where they cross for those a point reflector explains
    (:func:`_points`; the point also to ``vertices``); a middle of arc that neither
    explains and whose echo is too weak for it (:func:`_facing_too_weak`) is dropped;
    and the faces heard from two poses only (:func:`_two_pose_faces`)."""
    if len(isolated) == 0:
        return
    scans = element_scans(scene, sensors, s.loci,
                          loud_beams(scene, s.loci, HEARD_NOISE_SCALES * envelope_noise(scene)))
    points, ends = envelope_links(scene, sensors, s.loci, LINK_STEP_M,
                                  min(bias, ENVELOPE_ARC_BIAS_M), scans)
    keep = np.isin(ends, isolated).all(axis=1)
    links = len(found)  # the links' slot, filled once the point reflectors are known
    found.append(points[keep])
    source.append(ends[keep, 0])
    env = scan_envelope(scene, sensors, s.loci, scans)
    arcs, stubs = _isolated_points(s, isolated, bias, unique(ends[keep]), env)
    for k in _just_after_first(s, isolated, stubs):
        arcs[k] = np.zeros((0, 2))
    stubs = [k for k in stubs if len(arcs[k])]
    mono = [k for k in stubs if s.loci.tx[isolated[k]] == s.loci.rx[isolated[k]]]
    pillars, circles = _pillars(scene, s, isolated[mono], arcs, mono, bias)
    # a point reflector's loci from consecutive poses have their scan envelope at the point
    # itself, and the arc around it would stand across it: every drawn arc is a candidate
    left = [k for k, arc in enumerate(arcs) if len(arc) and k not in pillars]
    corners = on_the_surface(_points(scene, s, isolated[left], arcs, left, set(stubs), env),
                             s.T[isolated], s.R[isolated], arcs, found)
    for k, drawn in [*pillars.items(), *((k, v[None]) for k, v in corners.items())]:
        arcs[k] = drawn
    vertices += list({v.tobytes(): v for v in corners.values()}.values())
    if corners:  # a point reflector's loci touch at the point, not along a stretch
        keep &= ~np.isin(ends, isolated[list(corners)]).all(axis=1)
        found[links], source[links] = points[keep], ends[keep, 0]
    left = [k for k in stubs if k not in pillars and k not in corners]
    vouched = scene.detection.mode == "envelope" and scene.transducer.beam(scene.medium.c)[1]
    for k, weak in zip(left, _facing_too_weak(scene, s, isolated[left], bias), strict=True):
        if weak:
            arcs[k] = np.zeros((0, 2))
        elif vouched and s.loci.tx[isolated[k]] == s.loci.rx[isolated[k]]:  # a facing surface
            arcs[k] = densified(arcs[k], LINK_STEP_M, 3 * np.pi * s.a[isolated[k]] / LOCUS_SAMPLES)
    explained = [*pillars, *corners, *_touching(scene, s, isolated, circles)]
    points, ends = _two_pose_faces(scene, sensors, s, isolated[explained], scans,
                                   isolated, min(bias, ENVELOPE_ARC_BIAS_M))
    found.append(points)
    source.append(ends[:, 0])
    for locus, arc in zip(isolated, arcs, strict=True):
        found.append(arc)
        source.append(np.full(len(arc), locus))


def tangent_points(scene: Scene, sensors: SensorArray, loci, max_bias_m: float = TANGENT_BIAS_M,
                   isolated_bias_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m])`` of :func:`tangent_map`."""
    points, source, _ = tangent_map(scene, sensors, loci, max_bias_m, isolated_bias_m)
    return points, source


def tangent_map(scene: Scene, sensors: SensorArray, loci,
                max_bias_m: float = TANGENT_BIAS_M, isolated_bias_m: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m], vertices [k, 2])``: the points where the loci of
    neighbouring transducers cross, inside all beams, the index of the locus each came
    from, and the point reflectors located from isolated loci (:func:`_points`).

    A smooth surface is the envelope of the loci of its echoes: each locus touches it at its
    reflection point. Two loci of transducers δ apart, tangent to the surface at points
    δ apart, cross within δ²/(8r) of it (r the range) — even where their bands overlap
    over a long stretch — so the crossings of loci from one viewpoint (pair group) whose
    centres lie within sqrt(8·r·max_bias_m) of each other are surface points (the
    arc-transversal idea of sonar mapping). Each locus is sampled every 0.25° and crossings
    are found as sign changes of the other locus' path-length residual, interpolated. Around
    each crossing the locus' own tangent segment is added: the ±sqrt(2·r·max_bias_m) of arc
    over which it stays within ``max_bias_m`` of its tangent. With ``isolated_bias_m`` > 0
    a locus that crosses no neighbour contributes the middle of its in-beam arc,
    ±sqrt(2·r·isolated_bias_m): a surface facing the beams' middle (the line of sight,
    thesis §2.1.1 part 1) is there to within that — or, for a T = R locus of a moving
    ring, the same stretch around its point of the scan's envelope (:func:`scan_envelope`).
    """
    loci = as_loci(loci)
    none = np.zeros((0, 2)), np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    if len(loci) < 2:
        return none
    s = sample_loci(scene, sensors, loci)
    groups = sensors.groups[loci.tx]
    found: list[np.ndarray] = []
    source: list[np.ndarray] = []
    crossed = np.zeros(len(loci), dtype=bool)
    for lo in range(0, len(loci), 64):
        steps.step("loci", lo, len(loci))
        mine, other = _neighbour_pairs(s, groups, lo, min(lo + 64, len(loci)), max_bias_m)
        q, k, owner, b = _pair_crossings(s, mine, other)
        keep = (in_beams(q, s.T[b], s.axes[s.loci.tx[b]], s.cut_sin2)
                & in_beams(q, s.R[b], s.axes[s.loci.rx[b]], s.cut_sin2))
        crossed[b[keep]] = True
        q, k, owner, mine = q[keep], k[keep], owner[keep], unique(mine)
        ends = np.searchsorted(owner, [mine, mine + 1]).tolist()
        for i, n0, n1 in zip(mine.tolist(), *ends, strict=True):
            found.append(q[n0:n1])  # as locus_crossings(s, i, its neighbours) gives them
            source.append(np.full(n1 - n0, i))
            crossed[i] |= n1 > n0
            for segment in _tangent_segments(s, i, k[n0:n1], max_bias_m):
                found.append(segment)
                source.append(np.full(len(segment), i))
    isolated = np.flatnonzero(~crossed & s.inside.any(axis=1) & (isolated_bias_m > 0))
    vertices: list[np.ndarray] = []
    _add_isolated(scene, sensors, s, isolated, isolated_bias_m, found, source, vertices)
    if not found:
        return none
    return (np.concatenate(found), np.concatenate(source).astype(np.int64),
            np.asarray(vertices, dtype=np.float64).reshape(-1, 2))
