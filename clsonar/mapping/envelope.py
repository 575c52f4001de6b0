"""The scan envelope (:func:`scan_envelope`): surface points of the T = R loci of a moving
array (a wall-following ring), where the loci of one element at consecutive poses touch the
surface; and the beam test of sampled points (:func:`in_beams`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..numerics import unique
from ..scene import Scene
from ..sensors import SensorArray
from ..survey import group_centres, is_ring
from .loci import Loci, as_loci

#: How much nearer than its range an envelope point may be to a transducer (rounding).
ENVELOPE_TOL_M = 0.002

#: The stretch of locus kept around an envelope point: where it stays within this of the
#: surface's tangent, for a plane; a convex surface bends away twice as fast, so keep it
#: short — the envelope points themselves come every half step.
ENVELOPE_ARC_BIAS_M = 0.001

#: Envelope points within 30° of the scan direction are left out: there the offset across
#: the scan, sqrt(ρ² − along²), multiplies the error of ``along`` by along/across > 1.7.
ENVELOPE_MAX_ALONG = math.cos(math.radians(30.0))


#: Transducers whose axes are this close (cosine of 1°) face the same way.
_SAME_HEADING_COS = math.cos(math.radians(1.0))


def in_beams(p: np.ndarray, sensor: np.ndarray, axis: np.ndarray,
             cut_sin2: float) -> np.ndarray:
    """Whether points ``p`` [..., 2] lie in the beam of a transducer at ``sensor`` with unit
    ``axis`` (broadcast): ``axis·d > 0`` and ``(axis×d)² ≤ cut·|d|²`` for d = p − sensor."""
    d = p - sensor
    dist2 = d[..., 0] ** 2 + d[..., 1] ** 2
    cos = d[..., 0] * axis[..., 0] + d[..., 1] * axis[..., 1]
    cross = axis[..., 0] * d[..., 1] - axis[..., 1] * d[..., 0]
    return (cos > 0) & (cross * cross <= cut_sin2 * dist2)


#: Samples tested beyond each end of the computed arc of T's beam (rounding margin).
ARC_MARGIN = 2


def beam_arc_samples(u: np.ndarray, v: np.ndarray, axis: np.ndarray, a: np.ndarray,
                     f: np.ndarray, cut_sin2: float, samples: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, ks)``: for each locus (a > f; ``u``, ``v`` its axes, ``a``, ``f`` its half
    path and half focal distance), the indices of its ``samples`` (every 2π/samples of
    eccentric anomaly) on its arc inside the beam of its focus T (axis ``axis``), with
    :data:`ARC_MARGIN` more either side (moved here from :mod:`.tangents`)."""
    alpha = math.asin(math.sqrt(min(cut_sin2, 1.0)))
    ok = a > f
    e = np.where(ok, f / np.where(ok, a, 1.0), 0.0)
    beta = np.arctan2(np.sum(v * axis, -1), np.sum(u * axis, -1))  # axis angle from u
    step = 2 * np.pi / samples

    def anomaly(nu: np.ndarray) -> np.ndarray:
        nu = np.angle(np.exp(1j * nu))  # into (−π, π]
        return 2 * np.arctan2(np.sqrt(1 + e) * np.sin(nu / 2), np.sqrt(1 - e) * np.cos(nu / 2))

    lo, hi = anomaly(beta - alpha), anomaly(beta + alpha)
    hi = np.where(hi < lo, hi + 2 * np.pi, hi)
    k0 = np.floor(lo / step).astype(np.int64) - ARC_MARGIN
    k1 = np.ceil(hi / step).astype(np.int64) + ARC_MARGIN
    width = np.where(ok, np.minimum(k1 - k0 + 1, samples), 0)
    rows = np.repeat(np.arange(len(a)), width)
    first = np.repeat(np.cumsum(np.r_[0, width[:-1]]), width)
    ks = (np.repeat(k0, width) + np.arange(int(width.sum())) - first) % samples
    return rows, ks


def _in_beam(d0: float, d1: float, a0: float, a1: float, cut_sin2: float) -> bool:
    """:func:`in_beams` of one point d = p − sensor in floats: the same products, sums and
    comparisons (numpy's ``x ** 2`` is ``x * x``)."""
    cos = d0 * a0 + d1 * a1
    cross = a0 * d1 - a1 * d0
    return cos > 0 and cross * cross <= cut_sin2 * (d0 * d0 + d1 * d1)


@dataclass(frozen=True, eq=False)
class _Scan:
    """The loci of a scan and what the envelope of each pose's loci needs."""

    loci: Loci
    ranges: np.ndarray  # c·τ/2 of each locus
    pos: np.ndarray  # sensor positions
    axes: np.ndarray  # sensor unit axes
    #: per locus, sin² of the widest angle off its transducer's axis its echo may come
    #: from: the beam's cut, or less for an echo too loud to come from near it
    #: (:func:`~.strength.loud_beams`)
    beams: np.ndarray
    #: per sensor, whether its group is a ring (its elements face every way)
    ringed: np.ndarray | None = None


def ringed(sensors: SensorArray) -> np.ndarray:
    """[n] whether each transducer's group is a ring (:func:`~clsonar.survey.is_ring`, as
    the survey of the scene names it)."""
    out = np.zeros(len(sensors.groups), dtype=bool)
    for members in group_centres(sensors)[1]:
        out[members] = is_ring(sensors.positions[members], sensors.headings_deg[members])
    return out


#: An envelope point: (locus credited, locus circle's centre, its radius, the point).
EnvelopePoint = tuple[int, np.ndarray, float, np.ndarray]


def _first_echoes(sensors: SensorArray, loci: Loci,
                  ranges: np.ndarray) -> dict[tuple[int, int], list[int]]:
    """``{(group, element): [locus]}``: the nearest T = R echo of each element of each pose
    (element: its index within its group)."""
    groups = sensors.groups
    starts = {int(g): int(np.flatnonzero(groups == g)[0]) for g in unique(groups)}
    element = np.arange(len(groups)) - np.array([starts[int(g)] for g in groups], dtype=int)
    by_key: dict[tuple[int, int], list[int]] = {}
    for i in np.flatnonzero(loci.tx == loci.rx):
        t = int(loci.tx[i])
        key = (int(groups[t]), int(element[t]))
        if key not in by_key or ranges[i] < ranges[by_key[key][0]]:
            by_key[key] = [int(i)]
    return by_key


def _partner(s: _Scan, i: int, others: list[int] | None) -> int | None:
    """The locus of ``others`` (one element at a neighbouring pose) nearest in range to
    locus ``i``, if their ranges differ by at most the distance between the poses (and
    :data:`ENVELOPE_TOL_M` of rounding: a ring moving straight at a wall ahead of an
    element changes its range by exactly its step)."""
    if others is None:
        return None
    (x0, y0), (x1, y1) = s.pos[s.loci.tx[others[0]]].tolist(), s.pos[s.loci.tx[i]].tolist()
    gap = np.hypot(x0 - x1, y0 - y1)
    if len(others) == 1:  # an element's first echo: one locus (floats, the same numbers)
        diff = abs(float(s.ranges[others[0]]) - float(s.ranges[i]))
        return others[0] if diff <= gap + ENVELOPE_TOL_M else None
    diffs = np.abs(s.ranges[others] - s.ranges[i])
    k = int(np.argmin(diffs))
    return others[k] if diffs[k] <= gap + ENVELOPE_TOL_M else None


def _envelope_point(s: _Scan, i: int, j: int, centre: np.ndarray, r: float, d: np.ndarray,
                    dr: float, centred: bool) -> list[EnvelopePoint]:
    """The envelope point from loci i and j, credited to i (``centred``: at i's pose) or to
    both (midway); none unless it lies in both beams (at i's pose, j's beam is not needed
    when j's transducer faces the same way: the ring moved without turning) and is no
    nearer to either transducer than its range (the distance to the nearest point of the
    surface it came from)."""
    length = float(np.hypot(*d))
    along = -r * dr / length if length > 0 else np.inf
    if abs(along) > ENVELOPE_MAX_ALONG * r:
        return []  # the surface lies ahead along the scan: its side is ill-conditioned
    # the arithmetic of the 2-vectors in floats, element by element as numpy did it (r² −
    # along² ≥ r²/4 here), the products with the axes still BLAS's (their rounding)
    u0, u1 = (float(x) / length for x in d)
    v = np.array([-u1, u0])
    if v.dot(s.axes[s.loci.tx[i]]) < 0:
        v = -v
    (c0, c1), (v0, v1), root = centre.tolist(), v.tolist(), math.sqrt(r * r - along * along)
    q0, q1 = c0 + along * u0 + root * v0, c1 + along * u1 + root * v1
    # a point at i's pose need not be in the beam of j's transducer moved without turning
    # (the poses far apart for its range)
    straight = s.axes[s.loci.tx[i]].dot(s.axes[s.loci.tx[j]]) >= _SAME_HEADING_COS
    for k in (i, j):
        (t0, t1), (a0, a1) = s.pos[s.loci.tx[k]].tolist(), s.axes[s.loci.tx[k]].tolist()
        if (np.hypot(q0 - t0, q1 - t1) < s.ranges[k] - ENVELOPE_TOL_M
                or not (_in_beam(q0 - t0, q1 - t1, a0, a1, float(s.beams[k]))
                        or (k == j and centred and straight))):
            return []
    q = np.array([q0, q1])
    return [(k, centre, r, q) for k in ((i,) if centred else (i, j))]


def _unturned(s: _Scan, i: int, before: int | None, after: int | None) -> tuple[int, ...]:
    """Of the loci ``before`` and ``after`` (of i's element at the poses either side), the
    one whose transducer faces as i's does (within 1°) where the other's has turned: ()
    where both or neither do, where one is missing, or where i's group is no ring (a
    linear array's neighbours are other arrays, not the same element moved)."""
    if before is None or after is None or s.ringed is None or not s.ringed[s.loci.tx[i]]:
        return ()
    axis = s.axes[s.loci.tx[i]]
    same = [s.axes[s.loci.tx[k]].dot(axis) >= _SAME_HEADING_COS for k in (before, after)]
    return (before,) if same == [True, False] else (after,) if same == [False, True] else ()


def _pose_points(s: _Scan, i: int, before: int | None, after: int | None
                 ) -> tuple[list[EnvelopePoint], list[EnvelopePoint], bool]:
    """Locus ``i``'s envelope points: at its pose from the poses ``before`` and ``after``
    (from the one of them there is at a stretch's end: ``True``, first order, exact for a
    plane; and from the one that faces as i does where the other has turned and the
    central difference gives no point: a ring written by hand turns with its path, so at
    a bend of the path the element after faces another wall, the zoo's unseen seed 62
    room-28), and midway to the pose after."""
    at: list[EnvelopePoint] = []
    midway: list[EnvelopePoint] = []
    pos, tx, ranges = s.pos, s.loci.tx, s.ranges
    t = pos[tx[i]]
    one_sided = (before is None) != (after is None)
    if before is not None or after is not None:
        a = i if after is None else after
        b = i if before is None else before
        at = _envelope_point(s, i, a, t, ranges[i], pos[tx[a]] - pos[tx[b]],
                             ranges[a] - ranges[b], centred=True)
        for k in (_unturned(s, i, before, after) if not (at or one_sided) else ()):
            a, b = (i, k) if k == before else (k, i)
            at = _envelope_point(s, i, a, t, ranges[i], pos[tx[a]] - pos[tx[b]],
                                 ranges[a] - ranges[b], centred=True)
            if at:
                one_sided = True
                break
    if after is not None:
        ta = pos[tx[after]]
        midway = _envelope_point(s, i, after, 0.5 * (t + ta),
                                 0.5 * (ranges[i] + ranges[after]), ta - t,
                                 ranges[after] - ranges[i], centred=False)
    return at, midway, one_sided


#: An element's envelope points in scan order: ``(place, points, one-sided)``.
ElementScan = list[tuple[int, list[EnvelopePoint], bool]]


class _LinkedScan(list):
    """An :data:`ElementScan` as :func:`element_scans` makes it, keeping the links between
    its consecutive points (:func:`_links`) for the second :func:`_chains` of it."""

    links: list[float | None] | None = None


def element_scans(scene: Scene, sensors: SensorArray, loci,
                  beams: np.ndarray | None = None) -> list[ElementScan]:
    """Per element of the ring, its envelope points in scan order: ``(place, points,
    one_sided)`` with place 2·g at pose g and 2·g + 1 midway from pose g to g + 1 (a
    midway point credited to both of its loci; see :func:`_pose_points`): what
    :func:`scan_envelope` and :func:`envelope_links` are made of, computed once for both
    where a caller needs both. ``beams``: per locus, sin² of the widest angle off its axis
    its echo may come from (:func:`~.strength.loud_beams`; None: the beam's cut)."""
    loci = as_loci(loci)
    ranges = 0.5 * scene.medium.c * loci.tof_s
    by_key = _first_echoes(sensors, loci, ranges)
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    widest = np.full(len(loci), cut_sin2) if beams is None else np.minimum(beams, cut_sin2)
    s = _Scan(loci, ranges, sensors.positions, sensors.axes, widest, ringed(sensors))
    scans: dict[int, ElementScan] = {}
    for (g, e), members in sorted(by_key.items()):
        for i in members:
            at, midway, one_sided = _pose_points(
                s, i, _partner(s, i, by_key.get((g - 1, e))),
                _partner(s, i, by_key.get((g + 1, e))))
            scan = scans.setdefault(e, _LinkedScan())
            scan += [(2 * g, at, one_sided)] if at else []
            scan += [(2 * g + 1, midway, False)] if midway else []
    return list(scans.values())


def scan_envelope(scene: Scene, sensors: SensorArray, loci,
                  scans: list[ElementScan] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Surface points of the T = R loci of a moving array (a wall-following ring): the
    envelope of the loci of one element at consecutive poses.

    The loci ``|q − T(s)| = ρ(s)`` of one element moved along the scan touch the surface
    where ``(q − T)·T′ = −ρ·ρ′`` (differentiating in s), q on the side the element faces.
    Differences over consecutive poses give it to O(step²): at each pose from the poses
    before and after (``D = T₊ − T₋``, ``(q − T)·D̂ = −ρ·(ρ₊ − ρ₋)/|D|``), and between
    each two consecutive poses from the locus midway (``T = (T₁ + T₂)/2``,
    ``ρ = (ρ₁ + ρ₂)/2``, ``D = T₂ − T₁``), which also serves the poses at the ends of a
    stretch where the surface is in the beam. Unlike the middle of the in-beam arc it is
    right for oblique walls and cylinders (exact for a plane). Only each element's first
    echo is used (the nearest surface in its beam, the thesis' T = R rule), and
    neighbouring ranges must be able to come from one surface, ``|ρ₂ − ρ₁| ≤ |T₂ − T₁|``.

    Returns ``(locus [m], centre [m, 2], radius [m], point [m, 2])``: the locus each
    point is credited to (a midway point to both of its loci), the (possibly midway)
    locus circle and the envelope point on it. ``scans``: :func:`element_scans`, if the
    caller has them.
    """
    if scans is None:
        scans = element_scans(scene, sensors, loci)
    out = [p for scan in scans for _, points, one_sided in scan if not one_sided
           for p in points]
    if not out:
        return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2))
    idx, centre, radius, point = zip(*out, strict=True)
    return (np.asarray(idx, np.int64), np.asarray(centre), np.asarray(radius),
            np.asarray(point))


#: Consecutive envelope points of one element are joined by a straight stretch when their
#: normals, and the chord between them, agree with one plane within this angle ...
LINK_DEG = 3.0

#: ... and the surface their motion implies stays within this of the chord between them.
LINK_SAGITTA_M = 0.001


def _link_radius(a: EnvelopePoint, b: EnvelopePoint) -> float | None:
    """The radius of the surface through envelope points ``a`` and ``b`` (inf for a plane),
    or None where they do not lie on one nearly flat surface: their normals (from their
    locus circles' centres) and the chord between them within :data:`LINK_DEG`, and the
    chord what the scan's motion sweeps on a surface that bends by at most
    :data:`LINK_SAGITTA_M` over it. The envelope point of a plane moves with the
    transducer's motion along the plane, Δq = Δc − (Δc·n)·n; of a surface of radius R at
    range ρ, k = |Δq|/|Δc − (Δc·n)·n| = R/(R + ρ) (k → 0 for a corner or an edge,
    whose envelope points stay put), so R = ρ·k/|1 − k| and the chord's sagitta is
    |Δq|²/(8R)."""
    na = (a[3] - a[1]) / a[2]
    nb = (b[3] - b[1]) / b[2]
    chord = b[3] - a[3]
    length = float(np.hypot(*chord))
    tol = math.sin(math.radians(LINK_DEG))
    cross = na[0] * nb[1] - na[1] * nb[0]
    if not (na.dot(nb) > 0 and abs(cross) <= tol and abs(chord.dot(na)) <= tol * length
            and abs(chord.dot(nb)) <= tol * length):
        return None
    n = (na + nb) / np.hypot(*(na + nb))
    moved = (b[1] - a[1]) - ((b[1] - a[1]).dot(n)) * n
    if chord.dot(moved) <= 0:
        return None
    k = length / float(np.hypot(*moved))
    radius = 0.5 * (a[2] + b[2]) * k / abs(1.0 - k) if k != 1.0 else math.inf
    return radius if length * length <= 8.0 * radius * LINK_SAGITTA_M else None


#: A run of envelope points: the points, the smallest radius its links show, its loci.
Chain = tuple[list[EnvelopePoint], float, set[int]]


def _chains(scan: ElementScan, two_poses: bool = False) -> list[Chain]:
    """The runs of consecutive envelope points of one element (no pose between them
    without one) that lie on one nearly flat surface (:func:`_link_radius`) and hold two
    or more points from central differences (a run's one-sided ends alone do not tell a
    plane from a corner seen from afar), each with the smallest radius its links show and
    the loci it holds; a midway point as its later locus'. ``two_poses``: instead, the
    runs of two points or more with fewer from central differences (two or three
    consecutive poses' one-sided points, the midway ones and at most one central one,
    where each lies in the beams), which the envelope alone cannot tell from a point
    reflector's (:func:`two_pose_links`)."""
    chains: list[Chain] = []
    run: list[tuple[EnvelopePoint, bool, int]] = []
    loci: set[int] = set()
    radius = math.inf

    def close() -> None:
        central = [place for _, o, place in run if not o]
        if len(run) >= 2 and len(central) < 2 if two_poses else len(central) >= 2:
            chains.append(([q for q, _, _ in run], radius, loci))

    for (place, points, one_sided), link in zip(scan, _links(scan), strict=True):
        if link is None:
            close()
            run, radius, loci = [], math.inf, set()
        else:
            radius = min(radius, link)
        run.append((points[-1], one_sided, place))
        loci |= {q[0] for q in points}
    close()
    return chains


def _links(scan: ElementScan) -> list[float | None]:
    """:func:`_link_radius` of each point of ``scan`` (its last, for a midway point's two)
    and the one before it, None for the first and after a pose without one: the same for
    both kinds of :func:`_chains`, computed once for a scan :func:`element_scans` made."""
    links = getattr(scan, "links", None)
    if links is None:
        links, before, last = [], None, 0
        for place, points, _ in scan:
            links.append(_link_radius(before, points[-1])
                         if before is not None and place - last <= 2 else None)
            before, last = points[-1], place
        if isinstance(scan, _LinkedScan):
            scan.links = links
    return links


def envelope_links(scene: Scene, sensors: SensorArray, loci, step: float, bias: float,
                   scans: list[ElementScan] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The plane between consecutive envelope points of one element (at a pose, midway to
    the next, at the next pose; the midway point may be missing, out of a beam) where they
    lie on one plane: the region of constant depth that the scan swept (Leonard &
    Durrant-Whyte 1992), located as exactly as the envelope points. Each run goes on past
    its end points as far as their loci stay within ``bias`` of the plane,
    ±sqrt(2·ρ·bias), as the arc kept around an envelope point does (``bias`` =
    :data:`ENVELOPE_ARC_BIAS_M`: where a box's face ends at a convex edge, no farther),
    and no farther than a surface of the run's radius R stays within
    :data:`LINK_SAGITTA_M` of its tangent, sqrt(2·R·LINK_SAGITTA_M).
    Returns ``(points [m, 2], loci [m, 2])``: samples every ``step`` and the loci at both
    ends of the stretch each lies on. ``scans``: :func:`element_scans`, if the caller has
    them."""
    chains = [c for scan in (element_scans(scene, sensors, loci) if scans is None else scans)
              for c in _chains(scan)]
    return _stretches(chains, step, bias)


def two_pose_links(scene: Scene, sensors: SensorArray, loci, step: float, bias: float,
                   plane: Callable[[list[int], np.ndarray], bool],
                   scans: list[ElementScan] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`envelope_links` of the runs of one element's consecutive poses with fewer
    than two points from central differences (the face of a box a ring passes,
    heard by one element from two or three poses only: the zoo's seed 6 room-12, a box's
    face heard from three poses 2.3 m away, was drawn only around the middle pose's
    point) where ``plane(loci, normal)`` says the loci are a plane's (with
    unit ``normal`` from the surface towards the transducers' side, their common
    tangent's): two circles always have a common tangent, so the envelope alone cannot
    tell a plane from a point reflector heard twice (a concave corner's retro-reflection,
    both loci through its vertex); the caller decides from what else the scan heard."""
    chains = []
    for scan in element_scans(scene, sensors, loci) if scans is None else scans:
        for run, radius, ids in _chains(scan, two_poses=True):
            first = run[0]  # every point of the run has the common tangent's normal
            if len(ids) >= 2 and plane(sorted(ids), (first[1] - first[3]) / first[2]):
                chains.append((run, radius, ids))
    return _stretches(chains, step, bias)


def extended_run(run: list, radius: float, bias: float) -> np.ndarray:
    """The points of ``run`` (a chain of :func:`envelope_links`) and one past each end,
    along its last stretch, by √(2·r·bias) (r that end's range) but at most the sagitta's
    √(2·radius·:data:`LINK_SAGITTA_M`)."""
    q = np.array([p[3] for p in run])
    first, last = q[0] - q[1], q[-1] - q[-2]
    curved = math.sqrt(2.0 * radius * LINK_SAGITTA_M)
    ext = [min(math.sqrt(2.0 * end[2] * bias), curved) for end in (run[0], run[-1])]
    return np.r_[q[:1] + first / np.hypot(*first) * ext[0], q,
                 q[-1:] + last / np.hypot(*last) * ext[1]]


def _stretches(chains: list[Chain], step: float, bias: float) -> tuple[np.ndarray, np.ndarray]:
    """The samples (every ``step``) of the straight stretches between the consecutive
    points of each run in ``chains`` and past its ends (:func:`envelope_links`), and the
    loci at both ends of the stretch each lies on. A run's stretches at once: the n
    samples of each at ``np.linspace(0, 1, n)``'s fractions (j·(1/(n − 1)), the last 1),
    the same arithmetic per sample as one stretch at a time."""
    points, ends = [], []
    for run, radius, _ in chains:
        q = extended_run(run, radius, bias)
        ids = np.array([run[0][0], *(p[0] for p in run), run[-1][0]], dtype=np.int64)
        chord = q[1:] - q[:-1]
        n = np.array([max(2, math.ceil(math.hypot(*c) / step) + 1) for c in chord.tolist()])
        of = np.repeat(np.arange(len(n)), n)  # each sample's stretch
        t = (np.arange(len(of)) - np.repeat(np.cumsum(n) - n, n)) * (1.0 / (n - 1))[of] + 0.0
        t[np.cumsum(n) - 1] = 1.0
        points.append(q[:-1][of] + t[:, None] * chord[of])
        ends.append(np.stack([ids[:-1][of], ids[1:][of]], axis=1))
    if not points:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64)
    return np.concatenate(points), np.concatenate(ends).astype(np.int64)
