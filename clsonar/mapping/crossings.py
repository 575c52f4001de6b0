"""Two arc-map methods of the literature built on the crossings of loci (the crossing
search of the tangent points, :func:`~.tangents.locus_crossings`): the arc-transversal
median (``mapping.mode = "arc-transversal-median"``, ATM; Choset, Nagatani & Lazar 2003,
:func:`arc_transversal_medians`) and triangulation-based fusion (``"triangulation"``, TBF;
Wijk & Christensen 2000, :func:`triangulated_points`); and the reflector mapping's last
resort where too few echoes were heard for any reflector's model
(:func:`crossing_points`)."""

from __future__ import annotations

import numpy as np

from .. import steps
from ..numerics import median
from ..scene import Scene
from ..sensors import SensorArray
from .loci import as_loci
from .tangents import LOCUS_SAMPLES, SampledLoci, locus_crossings, run_starts, sample_loci

#: TBF: the farthest apart two transmitters whose loci are intersected, metres (Wijk &
#: Christensen's nearby sensor poses).
TBF_BASELINE_M = 1.0

#: TBF: intersections within this of a cluster's seed support it, metres.
TBF_RADIUS_M = 0.02

#: TBF: the fewest intersections (the seed included) that make a cluster a point.
TBF_MIN_SUPPORT = 3


def _arc_boxes(s: SampledLoci) -> np.ndarray:
    """[n, 4] ``(xmin, ymin, xmax, ymax)`` of each locus' samples inside its joint beam
    region (NaN for a locus with none)."""
    x = np.where(s.inside, s.p[..., 0], np.nan)
    y = np.where(s.inside, s.p[..., 1], np.nan)
    out = np.full((len(s.a), 4), np.nan)
    some = s.inside.any(axis=1)
    out[some] = np.stack([np.nanmin(x[some], 1), np.nanmin(y[some], 1),
                          np.nanmax(x[some], 1), np.nanmax(y[some], 1)], axis=1)
    return out


def _overlapping(boxes: np.ndarray, i: int, others: np.ndarray) -> np.ndarray:
    """The loci of ``others`` whose in-beam arcs' boxes overlap locus i's: the only ones
    its in-beam arc can cross."""
    b, o = boxes[i], boxes[others]
    return others[(o[:, 0] <= b[2]) & (o[:, 2] >= b[0]) & (o[:, 1] <= b[3]) & (o[:, 3] >= b[1])]


def _median_on_arc(s: SampledLoci, i: int, q: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The point of locus i at the median arc angle of its crossings ``q`` (between its
    samples ``k`` and k+1): a crossing itself for an odd count, else the point of the arc
    halfway (in angle) between the middle two."""
    first = int(run_starts(s.inside[i]))  # arc angles are counted from it
    p = s.p[i]
    step = np.hypot(*(p[(k + 1) % LOCUS_SAMPLES] - p[k]).T)
    t = np.hypot(*(q - p[k]).T) / np.maximum(step, 1e-300)
    m = float(median((k - first) % LOCUS_SAMPLES + t))
    j = (first + int(np.floor(m))) % LOCUS_SAMPLES
    return p[j] + (m - np.floor(m)) * (p[(j + 1) % LOCUS_SAMPLES] - p[j])


def arc_transversal_medians(scene: Scene, sensors: SensorArray, loci
                            ) -> tuple[np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m])``: the arc-transversal median (ATM; Choset, Nagatani &
    Lazar 2003, "The arc-transversal median algorithm: a geometric approach to increasing
    ultrasonic sensor azimuth accuracy", IEEE T-RA 19(3)). Each locus is crossed by the
    loci of every other pair, viewpoint and pose that met the same reflector, and the
    reflector is where most of them cross it: the locus' point is the median, by arc
    angle, of its crossings with all the other loci inside the joint beam regions of both
    (:func:`~.tangents.locus_crossings`; loci sampled every 0.25°). A locus that crosses
    none gives nothing; ``source`` is the locus of each point."""
    loci = as_loci(loci)
    if len(loci) < 2:
        return np.zeros((0, 2)), np.zeros(0, np.int64)
    s = sample_loci(scene, sensors, loci)
    boxes = _arc_boxes(s)
    some = s.inside.any(axis=1)
    points, source = [], []
    for i in steps.each("arc-transversal medians", np.flatnonzero(some).tolist()):
        others = _overlapping(boxes, i, np.flatnonzero(some & (np.arange(len(loci)) != i)))
        q, k, _ = locus_crossings(s, i, others)
        if len(q):
            points.append(_median_on_arc(s, i, q, k))
            source.append(i)
    return (np.asarray(points, dtype=np.float64).reshape(-1, 2),
            np.asarray(source, dtype=np.int64))


def support_clusters(points: np.ndarray, radius_m: float, min_support: int) -> np.ndarray:
    """[n] the cluster of each point (−1: none). The point with the most others within
    ``radius_m`` seeds a cluster of the unclustered points within ``radius_m`` of it, kept
    when they are at least ``min_support``; then the next best seed, and so on. A cluster
    is never wider than 2·``radius_m``: a wall's chain of intersections does not merge
    into one."""
    labels = np.full(len(points), -1, dtype=np.int64)
    if len(points) < max(min_support, 1):
        return labels
    from scipy.spatial import cKDTree  # only here (the arc maps' clusters): 0.3 s to import

    tree = cKDTree(points)
    support = tree.query_ball_point(points, radius_m, return_length=True)
    for seed in np.argsort(-support, kind="stable"):
        if support[seed] < min_support:
            break
        if labels[seed] >= 0:
            continue
        near = np.asarray(tree.query_ball_point(points[seed], radius_m), dtype=np.int64)
        near = near[labels[near] < 0]
        if len(near) >= min_support:
            labels[near] = labels.max() + 1
    return labels


def _intersections(s: SampledLoci, baseline_m: float) -> tuple[np.ndarray, np.ndarray]:
    """``(q [m, 2], loci [m, 2])``: every crossing, inside both joint beam regions, of two
    loci whose transmitters stand within ``baseline_m`` of each other, and the two loci."""
    boxes = _arc_boxes(s)
    some = s.inside.any(axis=1)
    q_all, pairs = [], []
    for i in steps.each("locus intersections", np.flatnonzero(some).tolist()):
        near = np.hypot(*(s.T - s.T[i]).T) <= baseline_m
        others = _overlapping(boxes, i, np.flatnonzero(some & near & (np.arange(len(s.a)) > i)))
        q, _, b = locus_crossings(s, i, others)
        q_all.append(q)
        pairs.append(np.stack([np.full(len(b), i), b], axis=1))
    if not q_all:
        return np.zeros((0, 2)), np.zeros((0, 2), np.int64)
    return np.concatenate(q_all), np.concatenate(pairs).astype(np.int64)


def triangulated_points(scene: Scene, sensors: SensorArray, loci, *,
                        baseline_m: float = TBF_BASELINE_M, radius_m: float = TBF_RADIUS_M,
                        min_support: int = TBF_MIN_SUPPORT) -> tuple[np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m])``: triangulation-based fusion (TBF; Wijk & Christensen
    2000, "Triangulation-based fusion of sonar data with application in robot pose
    tracking", IEEE T-RA 16(6)). Two loci of transmitters within ``baseline_m`` (nearby
    sensor poses) that met one reflector cross at it: every such pair is intersected
    (:func:`~.tangents.locus_crossings`, inside both joint beam regions), the
    intersections clustered (:func:`support_clusters`: within ``radius_m`` of a seed, at
    least ``min_support`` of them), and each cluster's centroid is a point. ``source``: of
    the cluster's loci, the nearest (least path length), whose pair the point keeps."""
    loci = as_loci(loci)
    none = np.zeros((0, 2)), np.zeros(0, np.int64)
    if len(loci) < 2:
        return none
    s = sample_loci(scene, sensors, loci)
    q, crossed = _intersections(s, baseline_m)
    labels = support_clusters(q, radius_m, min_support)
    kept = labels >= 0
    if not kept.any():
        return none
    n = int(labels.max()) + 1
    count = np.bincount(labels[kept], minlength=n)
    centroids = np.stack([np.bincount(labels[kept], q[kept, d], n) / count for d in (0, 1)],
                         axis=1)
    member = np.repeat(labels[kept], 2)
    locus = crossed[kept].ravel()
    order = np.lexsort((locus, s.a[locus], member))
    first = np.r_[True, member[order][1:] != member[order][:-1]]
    return centroids, locus[order][first]


#: Crossings of the same two loci this close are one (metres).
SAME_CROSSING_M = 1e-6


def crossing_points(scene: Scene, sensors: SensorArray, loci, apart: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m])``: where each two of the loci cross inside the joint
    beam regions of both (:func:`_intersections`, any baseline), and the nearer of the two
    (least path length), whose pair the point keeps: triangulation with the support of one
    crossing (Wijk & Christensen's TBF asks for three), for the few echoes no reflector's
    model explains. Two loci tangent to one smooth surface at points δ apart cross within
    about δ²/(8r) of it (:func:`~.tangents.tangent_map`), and two loci of one point
    reflector (a thin post, an edge, a corner's vertex) cross at it. The rows of
    ``apart`` [k, 2] are pairs of loci whose crossing is no point (one plane's echoes:
    :func:`~.few.two_echo_faces`)."""
    loci = as_loci(loci)
    if len(loci) < 2:
        return np.zeros((0, 2)), np.zeros(0, np.int64)
    s = sample_loci(scene, sensors, loci)
    q, crossed = _intersections(s, np.inf)
    if apart is not None and len(apart):  # two loci of one plane: no reflector where they cross
        faces = {tuple(sorted(p)) for p in apart.tolist()}
        keep = np.array([tuple(sorted(p)) not in faces for p in crossed.tolist()], dtype=bool)
        q, crossed = q[keep].reshape(-1, 2), crossed[keep].reshape(-1, 2)
    # a crossing on a sample is found from both sides of it: once
    order = np.lexsort((q[:, 1], q[:, 0], crossed[:, 1], crossed[:, 0]))
    q, crossed = q[order], crossed[order]
    again = np.zeros(len(q), dtype=bool)
    again[1:] = (np.all(crossed[1:] == crossed[:-1], axis=1)
                 & (np.hypot(*(q[1:] - q[:-1]).T) <= SAME_CROSSING_M))
    q, crossed = q[~again], crossed[~again]
    nearer = np.where(s.a[crossed[:, 0]] <= s.a[crossed[:, 1]], crossed[:, 0], crossed[:, 1])
    return q, nearer.astype(np.int64)
