"""An arc-map method of the literature built on the crossings of loci (the crossing search
of the tangent points, :func:`~.tangents.locus_crossings`): the arc-transversal median
(``mapping.mode = "arc-transversal-median"``, ATM; Choset, Nagatani & Lazar 2003,
:func:`arc_transversal_medians`)."""

from __future__ import annotations

import numpy as np

from ..scene import Scene
from ..sensors import SensorArray
from .loci import as_loci
from .tangents import LOCUS_SAMPLES, SampledLoci, locus_crossings, sample_loci


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


def _run_start(inside: np.ndarray) -> int:
    """The first sample of a locus' run of samples in both beams (the run may wrap around
    sample 0): arc angles are counted from it."""
    starts = inside & ~np.roll(inside, 1)
    return int(np.argmax(starts)) if starts.any() else 0


def _median_on_arc(s: SampledLoci, i: int, q: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The point of locus i at the median arc angle of its crossings ``q`` (between its
    samples ``k`` and k+1): a crossing itself for an odd count, else the point of the arc
    halfway (in angle) between the middle two."""
    first = _run_start(s.inside[i])
    p = s.p[i]
    step = np.hypot(*(p[(k + 1) % LOCUS_SAMPLES] - p[k]).T)
    t = np.hypot(*(q - p[k]).T) / np.maximum(step, 1e-300)
    m = float(np.median((k - first) % LOCUS_SAMPLES + t))
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
    for i in np.flatnonzero(some).tolist():
        others = _overlapping(boxes, i, np.flatnonzero(some & (np.arange(len(loci)) != i)))
        q, k, _ = locus_crossings(s, i, others)
        if len(q):
            points.append(_median_on_arc(s, i, q, k))
            source.append(i)
    return (np.asarray(points, dtype=np.float64).reshape(-1, 2),
            np.asarray(source, dtype=np.int64))
