"""Closed polylines: which are rooms and which are solid obstacles (boxes, pillars), from
how they nest and where the transducers stand (docs/scene-format.md, ``solid``).

A closed polyline is a room outline (only its inside reflects) unless it is read as solid
(only its outside reflects): where its ``solid`` says so, or, left automatic, when another
closed polyline encloses it (a box drawn inside a room) or the transducers all stand
outside every closed polyline (an open scene, whose closed polylines are objects).
"""

from __future__ import annotations

import numpy as np

from .scene import Polyline, Scene, Surface, WallFollowing


def enclosing(surfaces: tuple[Surface, ...]) -> list[int | None]:
    """For each surface, the index of a closed polyline that encloses it when it is itself a
    closed polyline (every vertex inside or on that outline, the mean of its vertices
    strictly inside), else None."""
    outlines = {i: np.asarray(s.points, dtype=np.float64) for i, s in enumerate(surfaces)
                if isinstance(s, Polyline) and s.closed}
    out: list[int | None] = [None] * len(surfaces)
    index = list(outlines)
    boxes = outline_boxes([outlines[j] for j in index])
    for i, pts in outlines.items():
        for j in (index[k] for k in holding(boxes, pts.mean(axis=0))):
            if j != i and encloses(outlines[j], pts):
                out[i] = j
                break
    return out


def encloses(outer: np.ndarray, pts: np.ndarray) -> bool:
    """Whether the closed outline ``outer`` encloses the polygon ``pts`` [n, 2]: every
    vertex inside or on it, the mean of the vertices strictly inside."""
    mean = pts.mean(axis=0, keepdims=True)
    return (bool(inside_polygon(outer, mean)[0]) and not bool(on_outline(outer, mean)[0])
            and bool(np.all(inside_polygon(outer, pts) | on_outline(outer, pts))))


def outline_boxes(polys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Each outline's bounding box ``(lo [n, 2], hi [n, 2])``, widened by 10⁻⁹ of the
    largest coordinate (far beyond rounding): a point outside an outline's box is not
    strictly inside it (:func:`inside_polygon`: a line through it crosses the outline
    nowhere, or an even number of times), so only the outlines whose box holds a point
    (:func:`holding`) need the exact test — the same answers, without testing the point
    against every room of a floor."""
    lo = np.array([p.min(axis=0) for p in polys]).reshape(-1, 2)
    hi = np.array([p.max(axis=0) for p in polys]).reshape(-1, 2)
    widen = 1e-9 * (1.0 + float(np.abs(np.concatenate([lo, hi])).max(initial=0.0)))
    return lo - widen, hi + widen


def holding(boxes: tuple[np.ndarray, np.ndarray], point) -> np.ndarray:
    """The indices, ascending, of the outlines whose box (:func:`outline_boxes`) holds
    ``point``."""
    p = np.asarray(point, dtype=np.float64).reshape(2)
    return np.flatnonzero(np.all((boxes[0] <= p) & (p <= boxes[1]), axis=1))


def sensor_anchors(scene: Scene) -> np.ndarray | None:
    """[k, 2] where ``scene``'s transducers are known to stand before they are placed: the
    explicit transducers and each ``random-lines`` start or ``circular`` centre; None where
    a placement's may be anywhere (``random-lines`` without a start) or scans a room's
    walls (``per-wall``, ``wall-following``: a start outside every room is a mistake the
    placement names)."""
    points = [t.position for t in scene.sensors.transducers]
    for p in (scene.sensors.placement, *scene.sensors.placements):
        if p is None:
            continue
        anchor = getattr(p, "start", None) or getattr(p, "center", None)
        if anchor is None or isinstance(p, WallFollowing):
            return None
        points.append(anchor)
    return np.asarray(points, dtype=np.float64).reshape(-1, 2)


def in_the_open(surfaces: tuple[Surface, ...], anchors: np.ndarray | None) -> bool:
    """Whether transducers at ``anchors`` (:func:`sensor_anchors`) all stand outside every
    closed polyline not marked solid: an open scene, whose closed polylines are objects
    (boxes, pillars) since a room around none of them would echo to no one."""
    if anchors is None or len(anchors) == 0:
        return False
    for s in surfaces:
        if isinstance(s, Polyline) and s.closed and s.solid is not True:
            poly = np.asarray(s.points, dtype=np.float64)
            if np.any(inside_polygon(poly, anchors) | on_outline(poly, anchors)):
                return False
    return True


def solid_surfaces(surfaces: tuple[Surface, ...], anchors: np.ndarray | None = None
                   ) -> tuple[bool, ...]:
    """Which surfaces are closed polylines read as solid obstacles (free space outside,
    walls reflecting outwards): those whose ``solid`` says so, and, where ``solid`` is null
    (automatic), those enclosed by another closed polyline (:func:`enclosing`) — a box or a
    pillar drawn inside a room — and every one in an open scene (:func:`in_the_open`,
    transducers at ``anchors``)."""
    inside = enclosing(surfaces)
    open_scene = in_the_open(surfaces, anchors)
    return tuple(isinstance(s, Polyline) and s.closed
                 and (s.solid if s.solid is not None
                      else (inside[i] is not None or open_scene))
                 for i, s in enumerate(surfaces))


def on_outline(poly: np.ndarray, p: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """[M] bool: ``p`` [M, 2] within ``tol`` (relative to the outline's largest coordinate,
    at least 1 m) of the closed outline ``poly`` [K, 2]."""
    tol *= max(1.0, float(np.abs(poly).max()))
    a = poly[None, :, :]
    ab = np.roll(poly, -1, axis=0)[None, :, :] - a
    t = np.clip(np.sum((p[:, None] - a) * ab, -1) / np.sum(ab * ab, -1), 0.0, 1.0)
    gap = p[:, None] - (a + t[..., None] * ab)
    return np.any(np.hypot(gap[..., 0], gap[..., 1]) <= tol, axis=1)


def inside_polygon(poly: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Even-odd rule: [M] bool, ``p`` [M, 2] strictly inside the closed polygon [K, 2]."""
    a = poly[None, :, :]
    b = np.roll(poly, -1, axis=0)[None, :, :]
    x, y = p[:, None, 0], p[:, None, 1]
    straddle = (a[..., 1] > y) != (b[..., 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    return (np.count_nonzero(straddle & (x < xc), axis=1) % 2) == 1
