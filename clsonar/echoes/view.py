"""Which pairs can have an echo at all (:func:`pairs_in_view`), decided from the beams and
the surfaces alone before any path is traced."""

from __future__ import annotations

import math

import numpy as np

from .. import steps
from ..geometry import dot
from .problem import EchoProblem

#: Margin added to every surface and beam in :func:`pairs_in_view`, metres and radians, so
#: that rounding can only keep a pair, never drop one with an echo.
VIEW_MARGIN_M = 1e-6
VIEW_MARGIN_RAD = 1e-6


def _view_primitives(pb: EchoProblem) -> np.ndarray:
    """[n, 5] every surface as a thick segment (x0, y0, x1, y1, radius) that contains it:
    walls (radius 0), circles (a point of radius r), sinusoids (their base line, radius
    |A|)."""
    parts = [np.column_stack([pb.walls, np.zeros(len(pb.walls))]),
             np.column_stack([pb.circles[:, :2], pb.circles[:, :2], pb.circles[:, 2]])]
    for k, cv in enumerate(pb.curves):
        s = pb.interval_s[pb.interval_curve == k]
        f, t = cv[:2], cv[2:4]
        parts.append(np.r_[f + s.min() * t, f + s.max() * t, abs(cv[4])][None])
    return np.concatenate(parts).reshape(-1, 5)


def _wedge_planes(pb: EchoProblem, sensor: np.ndarray) -> np.ndarray:
    """[N, 2, 3] the beams of ``sensor`` as two half-planes each, ``n·p + d ≥ 0``: the
    beam (inside where sin²θ ≤ cut_sin2 and cos θ > 0) is a wedge of half-angle α < 90°
    about the axis, the intersection of the half-planes of its two edges."""
    alpha = math.asin(math.sqrt(pb.cut_sin2)) + VIEW_MARGIN_RAD
    axis, origin = pb.axes[sensor], pb.positions[sensor]
    planes = []
    for side in (1.0, -1.0):  # inward normal of the edge at angle ±α from the axis
        a = side * alpha
        edge = np.stack([axis[:, 0] * math.cos(a) - axis[:, 1] * math.sin(a),
                         axis[:, 0] * math.sin(a) + axis[:, 1] * math.cos(a)], axis=-1)
        n = -side * np.stack([-edge[:, 1], edge[:, 0]], axis=-1)
        planes.append(np.column_stack([n, -dot(n, origin)]))
    return np.stack(planes, axis=1)


def _meets(planes: np.ndarray, prims: np.ndarray) -> np.ndarray:
    """[P, n] bool: whether each thick segment of ``prims`` [n, 5] meets the intersection
    of the half-planes ``planes`` [P, H, 3] (each grown by the segment's radius; Cyrus–Beck
    clipping of the segment's parameter t ∈ [0, 1])."""
    lo = np.zeros((len(planes), len(prims)))
    hi = np.ones((len(planes), len(prims)))
    for h in range(planes.shape[1]):
        n, d = planes[:, h, None, :2], planes[:, h, None, 2]
        f0 = dot(n, prims[None, :, :2]) + d + prims[None, :, 4] + VIEW_MARGIN_M
        f1 = dot(n, prims[None, :, 2:4]) + d + prims[None, :, 4] + VIEW_MARGIN_M
        slope = f1 - f0  # f(t) = f0 + t·slope ≥ 0
        with np.errstate(divide="ignore", invalid="ignore"):
            root = -f0 / slope
        lo = np.where(slope > 0, np.maximum(lo, root), lo)
        hi = np.where(slope < 0, np.minimum(hi, root), hi)
        hi = np.where((slope == 0) & (f0 < 0), -1.0, hi)
    return lo <= hi


def pairs_in_view(pb: EchoProblem, block: int = 4096) -> np.ndarray:
    """[P] bool: the pairs of ``pb`` that can have an echo at all. A first-order return's
    reflection point lies in the joint beam region of T and R (thesis §2.1.1: inside both
    beams, amplitude 0 outside); a higher-order path leaves T inside T's beam and reaches
    R inside R's. So a pair is kept when some surface meets its joint beam region, or (when
    ``max_order`` ≥ 2) some surface meets T's beam and some R's. Conservative: a kept pair
    may still have no echo; a dropped pair has none (every kernel family gives it amplitude
    0)."""
    n = len(pb.pairs)
    prims = _view_primitives(pb)
    if n == 0 or pb.cut_sin2 >= 1.0 - 1e-9:
        return np.ones(n, dtype=bool)
    if len(prims) == 0:
        return np.zeros(n, dtype=bool)
    sensors = np.arange(len(pb.positions))
    planes = _wedge_planes(pb, sensors)
    sees = _meets(planes, prims)  # [N, n]: surfaces meeting each sensor's beam
    keep = np.zeros(n, dtype=bool)
    t, r = pb.pairs[:, 0], pb.pairs[:, 1]
    bounces = bool(np.any(pb.sequence_order >= 2) or len(pb.corners))  # multi-bounce paths
    either = np.any(sees, axis=1)  # [N]: the sensor's beam meets some surface
    for i in range(0, n, block):
        steps.step("pairs in view", i, n)
        sl = slice(i, min(n, i + block))
        if bounces:
            keep[sl] = either[t[sl]] & either[r[sl]]
        cand = sees[t[sl]] & sees[r[sl]]
        rows = np.flatnonzero(cand.any(axis=1) & ~keep[sl])
        if len(rows):
            joint = np.concatenate([planes[t[sl][rows]], planes[r[sl][rows]]], axis=1)
            keep[i + rows] = (_meets(joint, prims) & cand[rows]).any(axis=1)
    return keep
