"""A face's end located by its edge's diffraction heard alone (``mapping.mode =
"reflectors"``): where one pair's weak echo, which no family explains, has its locus
cross a plane family's line beyond the face's reflection points, inside both beams, the
face's edge is there (:func:`heard_ends`).

A convex edge, or a wall's free end, diffracts: its echo comes from the vertex itself,
at every pair that sees it, far weaker than the face's mirror echo (at most half of it,
on the face's reflection boundary; the uniform theory, docs/physics.md). With one such
echo no family of three forms, so the vertex was never located, and the face was drawn
only over its own detections' regions of constant depth, short of its edge (the zoo's
seed 4 and seed 13 edge-03: a random-lines array's face drawn to within 32 and 19 cm
of its edge, whose diffraction one pair heard). The edge lies on the face's line (the
face ends there), so one locus fixes it: the crossing of that locus with the line.
"""

from __future__ import annotations

import numpy as np

from ..scene import Scene
from ..sensors import SensorArray
from .envelope import in_beams
from .families import window_tolerance
from .loci import Loci
from .models import dot2
from .patches import Patch, carrier_points, outward
from .strength import EDGE_SHARE, mirror_echo, two_way


def locus_crossings(T: np.ndarray, R: np.ndarray, path: np.ndarray, foot: np.ndarray,
                    t: np.ndarray) -> np.ndarray:
    """[k, 2] coordinates along the line ``foot + u·t`` where it crosses the locus
    ``|X − T| + |X − R| = path`` of each pair (the ellipse with foci T and R, eq. 2.2;
    the circle for T = R): the two roots of the ellipse's quadratic along the line, NaN
    where the line misses it."""
    m = 0.5 * (T + R)
    half = 0.5 * np.hypot(*(R - T).T)
    a = 0.5 * path
    b2 = np.maximum(a * a - half * half, 0.0)
    w = np.where(half[:, None] > 0, (R - T) / np.maximum(2 * half, 1e-300)[:, None], t)
    v = np.stack([-w[:, 1], w[:, 0]], axis=-1)
    p0 = foot - m
    # X - m = p0 + u·t in the ellipse's axes: (x/a)² + (y/b)² = 1, a quadratic in u
    px, pt = np.sum(p0 * w, axis=1), w @ t
    qx, qt = np.sum(p0 * v, axis=1), v @ t
    A = pt * pt / (a * a) + qt * qt / np.maximum(b2, 1e-300)
    B = 2 * (px * pt / (a * a) + qx * qt / np.maximum(b2, 1e-300))
    C = px * px / (a * a) + qx * qx / np.maximum(b2, 1e-300) - 1.0
    disc = B * B - 4 * A * C
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    return np.stack([(-B - root) / (2 * A), (-B + root) / (2 * A)], axis=-1)


def heard_ends(p: Patch, end: float, scene: Scene, sensors: SensorArray, loci: Loci,
               rows: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(s, points, spread)``: where the loci of ``rows`` (detections no family explains) cross
    the tangent of ``p``'s carrier at its coordinate ``end`` (a plane's line; a circle at
    least as flat as its range, a face's slightly bent last stretch, is as good as its
    tangent there), ``s`` metres beyond that end, inside both of their beams, no stronger
    there than an edge's diffraction can be (:data:`~.strength.EDGE_SHARE` of a flat
    mirror's echo through their two-way beam), and where the detection's path tolerance
    (:func:`~.families.window_tolerance`) moves the crossing along the line by at most
    the pulse's resolution c·σ (``spread``, how far it does): the places one heard
    diffraction puts the face's edge (module docstring). A locus whose other crossing
    lies on the face within ``reach`` of that end is left out: its diffraction may be
    of an edge the face is drawn past (the zoo's seed 14 corner-03: a free end 5 cm
    inside the drawn end, its monostatic locus crossing the line 6 cm inside and 5 cm
    beyond it)."""
    c = scene.medium.c
    cut_sin2, ka = scene.transducer.beam(c)
    T, R = sensors.positions[loci.tx[rows]], sensors.positions[loci.rx[rows]]
    axT, axR = sensors.axes[loci.tx[rows]], sensors.axes[loci.rx[rows]]
    at, t = carrier_points(p.params, p.x0, np.array([end]))[0], outward(p, end)
    both = locus_crossings(T, R, loci.tof_s[rows] * c, at, t)
    # a locus that also crosses the drawn face near this end says nothing of which side
    # the edge is on: the face may be drawn past its edge there
    inner = np.where(np.isfinite(both[:, 0]), both[:, 0], np.inf)  # the lesser root
    k, j = np.nonzero(np.isfinite(both) & (both > 0) & ~((inner < 0) & (inner >= -reach))[:, None])
    s = both[k, j]
    X = at + s[:, None] * t
    amplitude = loci.amplitude[rows[k]]
    # how far along the line the path's tolerance moves the crossing: a locus that grazes
    # the line (a face's own echo) fixes no point on it
    slope = np.abs(dot2((X - T[k]) / np.hypot(*(X - T[k]).T)[:, None]
                        + (X - R[k]) / np.hypot(*(X - R[k]).T)[:, None], t))
    spread = window_tolerance(amplitude, scene.signal.noise_std, c,
                              scene.transducer.pulse_sigma_s) / np.maximum(slope, 1e-12)
    ok = (in_beams(X, T[k], axT[k], cut_sin2) & in_beams(X, R[k], axR[k], cut_sin2)
          & (amplitude <= EDGE_SHARE * mirror_echo(scene)
             * two_way(X, T[k], axT[k], R[k], axR[k], ka))
          & (spread <= c * scene.transducer.pulse_sigma_s))
    return s[ok], X[ok], spread[ok]


__all__ = ["heard_ends", "locus_crossings"]
