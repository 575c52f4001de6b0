"""A cylinder's circle from the short pieces of a room's profile (thesis §3.6; ``post.fit =
"walls"``): pieces whose points lie on one circle are the patches a ring sees of a cylinder
(:func:`find_circles`), bridged across gaps of arc (:class:`Arc`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..mapping.pillars import fit_circle
from .fits import Wall

#: Pieces whose points lie within this median distance of a circle belong to it.
CIRCLE_RESIDUAL_M = 0.008

#: Gaps between a circle's patches up to this angle are bridged (besides ``max_gap_m``):
#: a fitted circle says what lies between patches seen all around it.
CIRCLE_MAX_GAP_DEG = 60.0

#: Pieces wholly this close to a found circle, but not on it, are dropped with it.
CIRCLE_ABSORB_M = 0.25

#: A circle needs at least this many pieces (patches seen from different poses).
MIN_CIRCLE_PIECES = 3

#: Radii considered for cylinders, metres.
CIRCLE_RADII_M = (0.05, 20.0)


@dataclass
class Arc:
    """A circle (``centre``, ``radius``) fitted to the ``points`` of several pieces."""

    centre: np.ndarray
    radius: float
    points: np.ndarray

    def holds(self, points: np.ndarray) -> bool:
        """Whether ``points`` lie wholly within :data:`CIRCLE_ABSORB_M` of the circle: a
        locus's tangent stretch drawn through it, not a surface of its own."""
        d = np.abs(np.hypot(*(points - self.centre).T) - self.radius)
        return bool(np.all(d <= CIRCLE_ABSORB_M))

    def sample(self, spacing: float, max_gap: float) -> list[np.ndarray]:
        """The arcs the points cover, gaps up to ``max_gap`` of arc length or
        :data:`CIRCLE_MAX_GAP_DEG` bridged, sampled every ``spacing``."""
        d = self.points - self.centre
        theta = np.sort(np.arctan2(d[:, 1], d[:, 0]))
        gaps = np.diff(np.r_[theta, theta[0] + 2 * math.pi])
        open_gaps = np.flatnonzero((gaps * self.radius > max_gap)
                                   & (gaps > math.radians(CIRCLE_MAX_GAP_DEG)))
        if len(open_gaps) == 0:
            runs = [(theta[0], theta[0] + 2 * math.pi)]
        else:
            starts = theta[(open_gaps + 1) % len(theta)]
            ends = theta[open_gaps]
            ends = np.roll(ends, -1)
            runs = [(a, b if b >= a else b + 2 * math.pi) for a, b in zip(starts, ends,
                                                                          strict=True)]
        out = []
        for a, b in runs:
            n = max(2, math.ceil((b - a) * self.radius / spacing) + 1)
            t = np.linspace(a, b, n)
            out.append(self.centre + self.radius * np.stack([np.cos(t), np.sin(t)], axis=-1))
        return out


def _circle_through(a: Wall, b: Wall) -> tuple[np.ndarray, float] | None:
    """The circle that both pieces would be patches of: their normals' crossing and the
    mean distance to it (None when the normals are nearly parallel or the distances
    disagree)."""
    na = np.array([-a.direction[1], a.direction[0]])
    nb = np.array([-b.direction[1], b.direction[0]])
    cross = na[0] * nb[1] - na[1] * nb[0]
    if abs(cross) < math.sin(math.radians(3.0)):
        return None
    d = b.centre - a.centre
    s = (d[0] * nb[1] - d[1] * nb[0]) / cross
    centre = a.centre + s * na
    ra, rb = math.hypot(*(a.centre - centre)), math.hypot(*(b.centre - centre))
    if abs(ra - rb) > 4 * CIRCLE_RESIDUAL_M or not CIRCLE_RADII_M[0] <= ra <= CIRCLE_RADII_M[1]:
        return None
    return centre, 0.5 * (ra + rb)


def _refine_circle(points: np.ndarray, centre: np.ndarray, radius: float
                   ) -> tuple[np.ndarray, float]:
    """Geometric least-squares circle through ``points`` from a first guess: |C − p_k| = R
    by Gauss–Newton (:func:`~clsonar.mapping.pillars.fit_circle` with ρ = 0; it spares a
    run with a cylinder the 0.35–0.5 s import of ``scipy.optimize``)."""
    fitted, r, _ = fit_circle(points, np.zeros(len(points)), centre, radius)
    return fitted, float(abs(r))


def find_circles(pieces: list[np.ndarray]) -> tuple[list[Arc], list[np.ndarray]]:
    """Cylinders among short, unjoined ``pieces`` (the patches a moving ring sees of a
    convex curved surface, each around a specular point whose normal points at the ring):
    the normals of patches of one circle meet at its centre. Each pair of pieces proposes
    the circle through both; the circle that most pieces agree with (median distance
    within :data:`CIRCLE_RESIDUAL_M`) is refined by least squares on their points and kept
    if at least :data:`MIN_CIRCLE_PIECES` agree; repeated on the rest. Pieces lying
    wholly within :data:`CIRCLE_ABSORB_M` of a kept circle but not on it — a locus's
    tangent stretch drawn through a curved surface — are dropped with it. Returns the
    circles and the pieces left over."""
    fits = {k: Wall.fit(p) for k, p in enumerate(pieces) if len(p) >= 3}
    left = list(fits)
    arcs = []
    while len(left) >= MIN_CIRCLE_PIECES:
        best: list[int] = []
        best_circle = None
        on_circle = _OnCircle([pieces[k] for k in left])
        for n, i in enumerate(left):
            for j in left[n + 1:]:
                circle = _circle_through(fits[i], fits[j])
                if circle is None:
                    continue
                members = [k for k, on in zip(left, on_circle(*circle), strict=True) if on]
                if len(members) > len(best):
                    best, best_circle = members, circle
        if len(best) < MIN_CIRCLE_PIECES or best_circle is None:
            break
        centre, radius = _refine_circle(np.concatenate([pieces[k] for k in best]),
                                        *best_circle)
        on = [k for k, yes in zip(left, on_circle(centre, radius), strict=True) if yes]
        arc = Arc(centre, radius, np.concatenate([pieces[k] for k in on or best]))
        near = [k for k in left if arc.holds(pieces[k])]
        arcs.append(arc)
        left = [k for k in left if k not in set(best) | set(on) | set(near)]
    used = set(fits) - set(left)
    return arcs, [p for k, p in enumerate(pieces) if k not in used]


class _OnCircle:
    """Which of some pieces (each of 1 point or more) lie on a circle: the median distance
    of each piece's points to it within :data:`CIRCLE_RESIDUAL_M`, every piece at once.
    The median is decided by counting the points within (more than half: on; fewer than
    half: not), and only for a piece of an even count with exactly half within, from its
    two middle distances' mean as :func:`numpy.median` takes it: the same answer as
    ``np.median(d) <= CIRCLE_RESIDUAL_M`` piece by piece."""

    def __init__(self, pieces: list[np.ndarray]) -> None:
        self.points = np.concatenate(pieces) if pieces else np.zeros((0, 2))
        self.counts = np.array([len(p) for p in pieces], dtype=np.int64)
        self.starts = np.r_[0, np.cumsum(self.counts)[:-1]].astype(np.int64)

    def __call__(self, centre: np.ndarray, radius: float) -> np.ndarray:
        """[pieces] bool: each piece on the circle of ``centre`` and ``radius``."""
        if len(self.counts) == 0:
            return np.zeros(0, dtype=bool)
        d = np.abs(np.hypot(*(self.points - centre).T) - radius)
        within = d <= CIRCLE_RESIDUAL_M
        twice = 2 * np.add.reduceat(within.astype(np.int64), self.starts)
        on = twice > self.counts
        tie = twice == self.counts
        if tie.any():
            below = np.maximum.reduceat(np.where(within, d, -np.inf), self.starts)[tie]
            above = np.minimum.reduceat(np.where(within, np.inf, d), self.starts)[tie]
            on[tie] = np.mean(np.stack([below, above]), axis=0) <= CIRCLE_RESIDUAL_M
        return on


__all__ = ["CIRCLE_ABSORB_M", "CIRCLE_MAX_GAP_DEG", "CIRCLE_RADII_M", "CIRCLE_RESIDUAL_M",
           "MIN_CIRCLE_PIECES", "Arc", "find_circles"]
