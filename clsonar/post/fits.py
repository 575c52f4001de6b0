"""The fitted profile (thesis §2.1.1, part 5): the thesis' polynomial along the points'
principal axis (:func:`fit_polynomial`), a smoothing spline per curve (:func:`fit_spline`),
the :class:`Profile` a fit yields, and a straight piece's line (:class:`Wall`, what
:mod:`~clsonar.post.walls` joins and :mod:`~clsonar.post.circles` reads patches of)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..numerics import median, parametric_spline, principal_axes, spline_values


@dataclass(frozen=True, eq=False)
class Profile:
    """The estimated surfaces: curves of points in metres (the fitted profile), and the
    corners and edges located as intersections of adjoining walls (``fit = "walls"``)."""

    curves: tuple[np.ndarray, ...]
    vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    #: fitted points dropped as unsupported by the map (:func:`~clsonar.post.bound_profile`)
    dropped: int = 0

    @property
    def points(self) -> np.ndarray:
        """[n, 2] all curves' points (``profile.csv``)."""
        if not self.curves:
            return np.zeros((0, 2))
        return np.concatenate(self.curves)


def fit_polynomial(points: np.ndarray, order: int, spacing: float) -> list[np.ndarray]:
    """The thesis' polynomial fit (§2.1.1, part 5; order 5–8 in chapter 3): in the frame of
    the points' principal axis u, fit v = P(u) by least squares and sample it every
    ``spacing`` over the points' span of u — keeping only the samples within the points'
    span of v too (give or take ``spacing``): a polynomial says nothing where it has no
    data, and where its data are few or not a function of u (a room's outline) it runs far
    away. Returns the [n, 2] curves of the samples kept (one, unless P leaves the span and
    comes back)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) <= order:
        return [p]
    centre, vt, _ = principal_axes(p)
    u_axis, v_axis = vt[0], vt[1]
    u = (p - centre) @ u_axis
    v = (p - centre) @ v_axis
    poly = np.polynomial.Polynomial.fit(u, v, order)
    us = np.arange(u.min(), u.max() + 0.5 * spacing, spacing)
    vs = poly(us)
    keep = (vs >= v.min() - spacing) & (vs <= v.max() + spacing)
    cuts = np.flatnonzero(np.diff(keep.astype(np.int8)) != 0) + 1
    samples = centre + us[:, None] * u_axis + vs[:, None] * v_axis
    return [c for c, k in zip(np.split(samples, cuts), np.split(keep, cuts), strict=True)
            if k[0]]


def fit_spline(curve: np.ndarray, spacing: float, noise: float) -> np.ndarray:
    """A smoothing spline through an ordered curve of points (FITPACK's parametric spline,
    :func:`clsonar.numerics.parametric_spline`,
    smoothing chosen so the residual RMS is about ``noise``), sampled every ``spacing`` of
    arc length. Short or degenerate curves come back unchanged."""
    p = np.asarray(curve, dtype=np.float64)
    keep = np.r_[True, np.any(np.diff(p, axis=0) != 0, axis=1)]
    p = p[keep]
    if len(p) < 4:
        return p
    steps = np.hypot(*np.diff(p, axis=0).T)
    closed = len(p) > 8 and np.hypot(*(p[0] - p[-1])) <= 2 * median(steps)
    if closed and np.any(p[0] != p[-1]):
        p = np.concatenate([p, p[:1]])
        steps = np.r_[steps, np.hypot(*(p[-1] - p[-2]))]
    arc = np.r_[0.0, np.cumsum(steps)]
    try:
        spline = parametric_spline(p.T, arc, len(p) * noise**2, bool(closed))
    except (ValueError, TypeError):
        return p
    samples = np.arange(0.0, arc[-1] + 0.5 * spacing, spacing)
    return np.stack(list(spline_values(samples, spline)), axis=-1)


@dataclass
class Wall:
    """A straight wall: the total-least-squares line of its ``points`` through ``centre``
    along unit ``direction``, spanning ``[lo, hi]`` of the coordinate along it."""

    points: np.ndarray
    centre: np.ndarray
    direction: np.ndarray
    lo: float
    hi: float
    residual: float
    #: which ends (lo, hi) were extended or trimmed to a vertex
    met: list[bool] = field(default_factory=lambda: [False, False])

    @classmethod
    def fit(cls, points: np.ndarray) -> Wall:
        p = np.asarray(points, dtype=np.float64)
        centre, axes, residual = principal_axes(p)
        t = (p - centre) @ axes[0]
        return cls(p, centre, axes[0], float(t.min()), float(t.max()), residual)

    @property
    def length(self) -> float:
        return self.hi - self.lo

    @property
    def joins(self) -> int:
        """How many of its ends met a vertex."""
        return sum(self.met)

    @property
    def seen(self) -> float:
        """How long a stretch its points cover (its span before any join)."""
        first, last = self.seen_span()
        return last - first

    def seen_span(self) -> tuple[float, float]:
        """The span of its own points along it: their coordinates' least and greatest."""
        t = (self.points - self.centre) @ self.direction
        return float(t.min()), float(t.max())

    def at(self, t: float) -> np.ndarray:
        return self.centre + t * self.direction

    def offset(self, q: np.ndarray) -> np.ndarray:
        """Distance of the point ``q`` [2] (or of each of the points [n, 2]) from the wall's
        line."""
        d = q - self.centre
        return np.abs(d[..., 0] * self.direction[1] - d[..., 1] * self.direction[0])

    def sample(self, spacing: float) -> np.ndarray:
        n = max(2, math.ceil(self.length / spacing) + 1)
        return self.at(0.0)[None] + np.linspace(self.lo, self.hi, n)[:, None] * self.direction


__all__ = ["Profile", "Wall", "fit_polynomial", "fit_spline"]
