"""A face's edge heard once in a scan of rings (tangent maps, :mod:`.tangents`): where an
element's weak echo, too weak for a surface facing it (:func:`~.tangents._facing_too_weak`),
has its locus cross the line of a drawn face just beyond the face's end, inside its beam,
the face's edge is there (:func:`heard_edges`), as :func:`~.ends.heard_ends` puts it for
the faces of arrays' families.

A ring scan draws a face where its loci touch it: around the reflection points of the
poses that face it. A box's face seen obliquely by a wall-following ring ends at the last
pose's reflection point, short of its edge by up to a pose's spacing (the zoo's unseen seed
26 room-12: a diamond box's faces drawn to 15 and 17 cm of their edges). The edge
diffracts, far weaker than a face's mirror echo; where one element heard it, its locus
passes through the edge, which lies on the face's line: their crossing.
"""

from __future__ import annotations

import numpy as np

from ..scene import Scene
from ..sensors import SensorArray
from .envelope import in_beams
from .families import window_tolerance
from .loci import Loci
from .models import dot2
from .patches import mirror_echo
from .strength import EDGE_SHARE, two_way

#: An edge is looked for this far beyond a drawn face's end at most, metres (a ring's
#: pose spacing, 0.5 m by default, and arrays' :data:`~.joins.MEET_M`).
EDGE_REACH_M = 0.5

#: The face's drawn end is its points within this of the end, metres ...
RUN_M = 0.1

#: ... at least this many of them (a ring's scan envelope draws a face's stretch between
#: two poses every 2.5 cm) ...
MIN_RUN_POINTS = 4

#: ... on one line to within this RMS, metres.
STRAIGHT_M = 0.001

#: Behind its end, within this of it (metres) and :data:`BAND_M` of its line, a face's
#: drawn points stay within :data:`CURVED_M` of the line, and go on at least
#: ``BACK_M − RUN_M`` back; a curve's (a pillar's stretch ending in its tangent) leave it:
#: R = 0.48 m by 4 cm 0.2 m back.
BACK_M = 0.3
BAND_M = 0.05
CURVED_M = 0.003

#: Drawn faces' ends tried per locus, nearest its circle first.
MAX_TRIED = 6

#: The face's line crosses the circle at least this steeply (the cosine between the line
#: and the circle's radius there): a line that grazes it fixes no point (a direction off
#: by δ moves the crossing by t·δ/cos).
MIN_CROSSING_COS = 0.5


def _run_end(points: np.ndarray, E: np.ndarray) -> np.ndarray | None:
    """The unit direction out of ``E`` of the straight run of ``points`` within
    :data:`RUN_M` of it (:data:`MIN_RUN_POINTS`, :data:`STRAIGHT_M`) that ends at ``E``;
    None where they are no straight run, go on past ``E``, or curve away from its line
    behind it (:data:`BACK_M`: a curve's tangent, not a face)."""
    run = points[np.hypot(*(points - E).T) <= RUN_M]
    if len(run) < MIN_RUN_POINTS:
        return None
    centred = run - run.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    if sv[1] / np.sqrt(len(run)) > STRAIGHT_M:
        return None  # not a face's straight end
    u = vt[0] if dot2(E - run.mean(axis=0), vt[0]) >= 0 else -vt[0]
    if np.max(dot2(run - E, u)) > STRAIGHT_M:
        return None  # the run goes on past E
    along, off = dot2(points - E, u), np.abs(dot2(points - E, np.array([-u[1], u[0]])))
    behind = (along <= 0) & (along >= -BACK_M) & (off <= BAND_M)
    back = np.min(along[behind & (off <= CURVED_M)], initial=0.0)
    return None if np.any(off[behind] > CURVED_M) or back > RUN_M - BACK_M else u


def _crossing(E: np.ndarray, u: np.ndarray, T: np.ndarray, rho: float) -> float | None:
    """The least t > 0 with |E + t·u − T| = ρ (None where the line misses the circle or
    crosses it only behind ``E``)."""
    p = E - T
    b = float(dot2(p, u))
    disc = b * b - (float(dot2(p, p)) - rho * rho)
    if disc < 0:
        return None
    roots = [t for t in (-b - np.sqrt(disc), -b + np.sqrt(disc)) if t > 0]
    return float(roots[0]) if roots else None


def _edge(scene: Scene, E: np.ndarray, u: np.ndarray | None, T: np.ndarray,
          axis: np.ndarray, rho: float, amplitude: float, tolerance: float) -> np.ndarray | None:
    """Where the face ending at ``E`` in direction ``u`` has its edge on the circle of
    radius ``rho`` about the element at ``T`` (unit ``axis``), as :func:`heard_edges`
    tests it; None where it has none."""
    t = None if u is None else _crossing(E, u, T, rho)
    if u is None or t is None or t > EDGE_REACH_M:
        return None
    c = scene.medium.c
    cut_sin2, ka = scene.transducer.beam(c)
    X = E + t * u
    steep = abs(float(dot2((X - T) / max(float(np.hypot(*(X - T))), 1e-12), u)))
    loud = EDGE_SHARE * mirror_echo(scene) * float(
        two_way(X[None], T[None], axis[None], T[None], axis[None], ka)[0])
    if (steep < MIN_CROSSING_COS or tolerance > 2 * c * scene.transducer.pulse_sigma_s * steep
            or amplitude > loud
            or not bool(in_beams(X, T, axis, cut_sin2))):
        return None
    return X


def _silent(E: np.ndarray, X: np.ndarray, T: np.ndarray, scene: Scene,
            sensors: SensorArray, heard: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether an element in front of the stretch from ``E`` to ``X`` (on the side of the
    face's line where the elements ``T`` [k, 2] that drew its end are, on average: the side
    it was seen from), with the stretch's foot inside its beam and no
    farther than the farthest echo, heard no T = R echo at the foot's distance (within a
    pulse's resolution c·σ): had the face gone on to ``X``, it would have echoed there as a
    mirror does. ``heard``: ``(element, range)`` of every T = R detection."""
    length = float(np.hypot(*(X - E)))
    u = (X - E) / length
    n = np.array([-u[1], u[0]])
    n = n if float(np.mean(dot2(T - E, n))) > 0 else -n
    rel = sensors.positions - E
    along, depth = dot2(rel, u), dot2(rel, n)
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    facing = (along > 0) & (along < length) & (depth > 0) & (depth <= heard[1].max(initial=0))
    facing &= in_beams(E + along[:, None] * u, sensors.positions, sensors.axes, cut_sin2)
    resolution = scene.medium.c * scene.transducer.pulse_sigma_s
    for j in np.flatnonzero(facing).tolist():
        if not np.any(np.abs(heard[1][heard[0] == j] - depth[j]) <= resolution):
            return True
    return False


def heard_edges(scene: Scene, sensors: SensorArray, loci: Loci, a: np.ndarray,
                weak: np.ndarray, points: np.ndarray, source: np.ndarray, step: float,
                known: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray],
                                            list[np.ndarray]]:
    """``(points, source, vertices)`` to draw: for each T = R locus ``weak`` of ``loci``
    (``a``: their half paths; these too weak for a surface facing them) but those of
    ``known`` (a pillar's or a point reflector's, :mod:`.pillars`; nor is a face drawn on
    from their points: a pillar's stretch ends in its tangent, 0.35–0.5 m pillars' drawn
    on 3 cm off them, the zoo's unseen seed 26 room-15 and room-19), where its circle
    crosses the line of a drawn face beyond the face's straight end (:func:`_run_end`, of
    the drawn ``points`` inside its beam and not credited to it by ``source``, the ends
    nearest its circle first, at most :data:`MAX_TRIED`), within :data:`EDGE_REACH_M` of
    it, inside the element's beam, no louder there than an edge's diffraction can be
    (:data:`~.strength.EDGE_SHARE` of a flat mirror's echo through its two-way beam), fixed
    along the line to within the pulse's resolution c·σ by the detection's path tolerance,
    crossing the line at least as steeply as :data:`MIN_CROSSING_COS` (a locus that grazes
    the line fixes no point on it), and where no element in front of the stretch was
    silent (:func:`_silent`): the face drawn on to that point every ``step`` metres, and
    the point a located vertex."""
    T, axes = sensors.positions[loci.tx[weak]], sensors.axes[loci.tx[weak]]
    rho, amplitude = a[weak], loci.amplitude[weak]
    mono = loci.tx == loci.rx
    heard = (loci.tx[mono], a[mono])
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    tolerance = window_tolerance(amplitude, scene.signal.noise_std, scene.medium.c,
                                 scene.transducer.pulse_sigma_s)
    out: tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]] = ([], [], [])
    ours = ~np.isin(source, known)
    for k, locus in enumerate(weak.tolist()):
        if locus in set(known.tolist()):
            continue
        keep = ours & (source != locus) & in_beams(points, T[k], axes[k], cut_sin2)
        mine, whose = points[keep], source[keep]
        off = np.abs(np.hypot(*(mine - T[k]).T) - rho[k])
        tried: list[np.ndarray] = []
        for i in np.argsort(off, kind="stable")[:np.count_nonzero(off <= EDGE_REACH_M)]:
            if len(tried) >= MAX_TRIED:
                break
            E = mine[i]
            if any(np.hypot(*(E - x)) <= RUN_M for x in tried):
                continue  # a run already tried
            tried.append(E)
            X = _edge(scene, E, _run_end(mine, E), T[k], axes[k], float(rho[k]),
                      float(amplitude[k]), float(tolerance[k]))
            seen = sensors.positions[loci.tx[whose[np.hypot(*(mine - E).T) <= RUN_M]]]
            if X is not None and not _silent(E, X, seen, scene, sensors, heard):
                t = float(np.hypot(*(X - E)))
                drawn = E + np.arange(1, int(t / step) + 1)[:, None] * step * (X - E) / t
                out[0].append(np.vstack([drawn, X[None]]))
                out[1].append(np.full(len(drawn) + 1, locus))
                out[2].append(X)
                break
    return out


__all__ = ["BACK_M", "BAND_M", "CURVED_M", "EDGE_REACH_M", "MAX_TRIED", "MIN_CROSSING_COS",
           "MIN_RUN_POINTS", "RUN_M", "STRAIGHT_M", "heard_edges"]
