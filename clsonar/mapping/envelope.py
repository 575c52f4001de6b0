"""The scan envelope (:func:`scan_envelope`): surface points of the T = R loci of a moving
array (a wall-following ring), where the loci of one element at consecutive poses touch the
surface; and the beam test of sampled points (:func:`in_beams`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene import Scene
from ..sensors import SensorArray
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


def in_beams(p: np.ndarray, sensor: np.ndarray, axis: np.ndarray,
             cut_sin2: float) -> np.ndarray:
    """Whether points ``p`` [..., 2] lie in the beam of a transducer at ``sensor`` with unit
    ``axis`` (broadcast): ``axis·d > 0`` and ``(axis×d)² ≤ cut·|d|²`` for d = p − sensor."""
    d = p - sensor
    dist2 = d[..., 0] ** 2 + d[..., 1] ** 2
    cos = d[..., 0] * axis[..., 0] + d[..., 1] * axis[..., 1]
    cross = axis[..., 0] * d[..., 1] - axis[..., 1] * d[..., 0]
    return (cos > 0) & (cross * cross <= cut_sin2 * dist2)


@dataclass(frozen=True, eq=False)
class _Scan:
    """The loci of a scan and what the envelope of each pose's loci needs."""

    loci: Loci
    ranges: np.ndarray  # c·τ/2 of each locus
    pos: np.ndarray  # sensor positions
    axes: np.ndarray  # sensor unit axes
    cut_sin2: float


#: An envelope point: (locus credited, locus circle's centre, its radius, the point).
EnvelopePoint = tuple[int, np.ndarray, float, np.ndarray]


def _first_echoes(sensors: SensorArray, loci: Loci,
                  ranges: np.ndarray) -> dict[tuple[int, int], list[int]]:
    """``{(group, element): [locus]}``: the nearest T = R echo of each element of each pose
    (element: its index within its group)."""
    groups = sensors.groups
    starts = {int(g): int(np.flatnonzero(groups == g)[0]) for g in np.unique(groups)}
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
    locus ``i``, if their ranges differ by at most the distance between the poses."""
    if others is None:
        return None
    gap = np.hypot(*(s.pos[s.loci.tx[others[0]]] - s.pos[s.loci.tx[i]]))
    diff = np.abs(s.ranges[others] - s.ranges[i])
    k = int(np.argmin(diff))
    return others[k] if diff[k] <= gap else None


def _envelope_point(s: _Scan, i: int, j: int, centre: np.ndarray, r: float, d: np.ndarray,
                    dr: float, centred: bool) -> list[EnvelopePoint]:
    """The envelope point from loci i and j, credited to i (``centred``: at i's pose) or to
    both (midway); none unless it lies in both beams and is no nearer to either transducer
    than its range (the distance to the nearest point of the surface it came from)."""
    length = float(np.hypot(*d))
    along = -r * dr / length if length > 0 else np.inf
    if abs(along) > ENVELOPE_MAX_ALONG * r:
        return []  # the surface lies ahead along the scan: its side is ill-conditioned
    u = d / length
    v = np.array([-u[1], u[0]])
    if v @ s.axes[s.loci.tx[i]] < 0:
        v = -v
    q = centre + along * u + np.sqrt(r * r - along * along) * v
    for k in (i, j):
        t = s.pos[s.loci.tx[k]]
        if (np.hypot(*(q - t)) < s.ranges[k] - ENVELOPE_TOL_M
                or not in_beams(q, t, s.axes[s.loci.tx[k]], s.cut_sin2)):
            return []
    return [(k, centre, r, q) for k in ((i,) if centred else (i, j))]


def _pose_points(s: _Scan, i: int, before: int | None, after: int | None
                 ) -> list[EnvelopePoint]:
    """Locus ``i``'s envelope points: at its pose from the poses ``before`` and ``after``,
    and midway to the pose after."""
    out: list[EnvelopePoint] = []
    pos, tx, ranges = s.pos, s.loci.tx, s.ranges
    t = pos[tx[i]]
    if before is not None and after is not None:
        out += _envelope_point(s, i, after, t, ranges[i], pos[tx[after]] - pos[tx[before]],
                               ranges[after] - ranges[before], centred=True)
    if after is not None:
        ta = pos[tx[after]]
        out += _envelope_point(s, i, after, 0.5 * (t + ta), 0.5 * (ranges[i] + ranges[after]),
                               ta - t, ranges[after] - ranges[i], centred=False)
    return out


def scan_envelope(scene: Scene, sensors: SensorArray, loci
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
    locus circle and the envelope point on it.
    """
    loci = as_loci(loci)
    ranges = 0.5 * scene.medium.c * loci.tof_s
    by_key = _first_echoes(sensors, loci, ranges)
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    s = _Scan(loci, ranges, sensors.positions, sensors.axes, cut_sin2)
    out: list[EnvelopePoint] = []
    for (g, e), members in by_key.items():
        for i in members:
            out += _pose_points(s, i, _partner(s, i, by_key.get((g - 1, e))),
                                _partner(s, i, by_key.get((g + 1, e))))
    if not out:
        return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2))
    idx, centre, radius, point = zip(*out, strict=True)
    return (np.asarray(idx, np.int64), np.asarray(centre), np.asarray(radius),
            np.asarray(point))
