"""A point reflector and its mirror image across the line of its loci's centres
(:func:`on_the_surface`).

A ring moving straight at a vertex hears it with one element at every pose: the loci's
centres (their transducers) lie on one line, and every circle centred on a line that
passes through a point passes through that point's mirror image across the line too. The
ranges cannot tell the two apart, and the point fit (:func:`~.pillars.point_reflectors`)
finds whichever its start is nearer (the zoo's unseen seed 124 room-19: a T room's notch
corner 3.2 cm off the line of eight poses, every locus within 0.17 mm of both, located
at the image, 7.0 cm off). The surface does tell them apart: the vertex is where the walls
beside it end, so of the two the one on the line of the surface points around them —
the wall that the other poses mapped up to it — is the vertex.
"""

from __future__ import annotations

import numpy as np

from ..numerics import principal_axes

#: Loci's centres are on one line when each lies within this of their least-squares line
#: (metres): a ring's element moved along a straight path.
ON_ONE_LINE_M = 0.001

#: The surface points within this of the two candidates' midpoint (metres) are the wall
#: that tells them apart.
AROUND_M = 0.5

#: Those points are one wall when they lie within this RMS of their line (metres), and
#: the image is the vertex when it lies within this of that line.
WALL_RMS_M = 0.002
ON_WALL_M = 0.005

#: Fewest surface points that make a wall here.
LEAST_POINTS = 10


def _line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(centre, unit normal, RMS distance)`` of the points' total-least-squares line."""
    centre, axes, rms = principal_axes(points)
    return centre, axes[-1], rms


def on_the_surface(points: dict[int, np.ndarray], T: np.ndarray, R: np.ndarray,
                   arcs: list[np.ndarray], others: list[np.ndarray]) -> dict[int, np.ndarray]:
    """``points`` (``{k: point}`` of the loci k with transducers ``T``, ``R``) with each
    point whose loci's transducers lie on one line (:data:`ON_ONE_LINE_M`) replaced by its
    mirror image across that line where the image lies on the wall of the surface points
    around the two — ``others`` and the ``arcs`` of the loci that are no point's
    (:data:`AROUND_M`, one line within :data:`WALL_RMS_M`, the image within
    :data:`ON_WALL_M` of it) — and the point does not (module docstring)."""
    out = dict(points)
    surface: np.ndarray | None = None  # gathered for the first point it may move
    groups: dict[bytes, list[int]] = {}
    for k, v in points.items():
        groups.setdefault(np.asarray(v).tobytes(), []).append(k)
    for ks in groups.values():
        if len(ks) < 2:
            continue
        v = np.asarray(points[ks[0]], dtype=np.float64)
        ends = np.concatenate([T[ks], R[ks]])
        centre, n, _ = _line(ends)
        if np.max(np.abs((ends - centre) @ n)) > ON_ONE_LINE_M:
            continue
        image = v - 2.0 * float((v - centre) @ n) * n
        middle = 0.5 * (v + image)
        if surface is None:
            parts = [*others, *(a for k, a in enumerate(arcs) if k not in points)]
            surface = np.concatenate(parts) if parts else np.zeros((0, 2))
        near = surface[np.hypot(*(surface - middle).T) <= AROUND_M]
        if len(near) < LEAST_POINTS:
            continue
        c, m, rms = _line(near)
        if rms > WALL_RMS_M:
            continue
        off_v, off_image = abs(float((v - c) @ m)), abs(float((image - c) @ m))
        if off_image <= ON_WALL_M and off_v > 2.0 * ON_WALL_M:
            for k in ks:
                out[k] = image
    return out


__all__ = ["AROUND_M", "LEAST_POINTS", "ON_ONE_LINE_M", "ON_WALL_M", "WALL_RMS_M",
           "on_the_surface"]
