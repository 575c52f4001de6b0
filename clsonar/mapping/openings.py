"""Openings: a gap between two stretches of one wall that the scan heard as free space
(:func:`open_gaps`), which the walls fit must not bridge (:func:`clsonar.post.walls.
merge_collinear`).

A ring scanning a corridor hears each wall square on wherever an element faces it, so
the walls come out in stretches; the walls fit joins the stretches of one line across gaps
up to ``post.max_gap_m`` (1 m for a ring scan: a stretch the ring missed between poses,
or one a pillar hid). A side opening or a doorway narrower than that is such a gap too: the
zoo's unseen seed 79 corridor-07, a corridor's side opening 1.0 m wide, was drawn over
(6.8 cm RMS). What tells them apart is what the pairs facing the gap heard: where a wall
were there, a pair whose reflection point on its line lies in the gap, inside both
beams, would hear a flat mirror's echo well above the detection's floor at the mirror
path; silence there, at every such pair, is an opening.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterator

import numpy as np

from ..numerics import unique
from ..scene import Scene
from ..sensors import SensorArray
from .envelope import in_beams
from .heard import Heard, amplitude_noise, group_pairs, heard_index, loudest
from .loci import as_loci
from .models import plane_points
from .strength import mirror_echo, mirror_floor

#: A pair's reflection point must lie this far inside the gap (metres) to speak for it:
#: nearer its ends, the stretches' own edges echo.
GAP_MARGIN_M = 0.1

#: Only pairs within this of the gap (half their mirror path, metres) speak for it: a
#: ring scan passes its walls within about a metre, and from across a room an obstacle
#: that echoes nothing back (a box's face seen obliquely) may hide the wall (the zoo's
#: unseen seed 60 room-12: an element 6.5 m from the wall, behind a box, heard nothing).
GAP_REACH_M = 2.0

#: ``open_gap(p, q)``: whether the stretch of line from ``p`` to ``q`` is free space.
OpenGap = Callable[[np.ndarray, np.ndarray], bool]


def open_gaps(scene: Scene, sensors: SensorArray, loci) -> OpenGap:
    """The test of a gap from ``p`` to ``q`` on a wall's line (module docstring): at least
    one pair in front of it, within :data:`GAP_REACH_M`, whose reflection point lies in
    the gap (:data:`GAP_MARGIN_M` inside), inside both beams, that would hear a mirror
    there at twice the detection's floor (:func:`~.strength.mirror_floor`) and heard
    nothing nearer (no obstacle on the way: a pillar or a box hides the wall behind it),
    and none of them with a detection (of ``loci``) within the pulse's resolution c·σ of
    the mirror path. The detections are indexed at the first gap tested: a run that
    bridges none pays nothing."""
    c = scene.medium.c
    cut_sin2, ka = scene.transducer.beam(c)
    mirror, noise = mirror_echo(scene), amplitude_noise(scene)
    floor = max(float(scene.detection.min_envelope or 0.0), 3.0 * noise)
    resolution = c * scene.transducer.pulse_sigma_s

    @functools.cache
    def indexed() -> tuple[Heard, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
        """The detections, every pair, its shortest path heard, and (T, R, axT, axR):
        made at the first gap tested."""
        pairs = [k for g in unique(sensors.groups) for k in group_pairs(sensors, int(g))]
        every = np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)
        heard = heard_index(as_loci(loci), sensors, c)
        ends = (sensors.positions[every[:, 0]], sensors.positions[every[:, 1]],
                sensors.axes[every[:, 0]], sensors.axes[every[:, 1]])
        return heard, every, _first_paths(heard, every), ends

    def open_gap(p: np.ndarray, q: np.ndarray) -> bool:
        length = float(np.hypot(*(q - p)))
        if length <= 2.0 * GAP_MARGIN_M or mirror <= 0:
            return False
        heard, pairs, first, (T, R, axT, axR) = indexed()
        u = (q - p) / length
        facing = []
        for seen, path, x in line_mirrors(p, u, T, R, axT, axR, cut_sin2):
            s = (x - p) @ u
            keep = (seen & (s > GAP_MARGIN_M) & (s < length - GAP_MARGIN_M)
                    & (first >= path - resolution)  # nothing heard nearer: a clear way
                    & (path <= 2.0 * GAP_REACH_M))
            keep[keep] = mirror_floor(x[keep], T[keep], axT[keep], R[keep], axR[keep],
                                      mirror, ka, noise) >= 2.0 * floor
            facing.append((np.flatnonzero(keep), path))
        if sum(len(k) for k, _ in facing) == 0:
            return False
        return not any(loudest(heard, pairs[k], path[k], resolution)[1].any()
                       for k, path in facing if len(k))

    return open_gap


def line_mirrors(p: np.ndarray, u: np.ndarray, T: np.ndarray, R: np.ndarray, axT: np.ndarray,
                 axR: np.ndarray, cut_sin2: float
                 ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """For each side of the line through ``p`` along the unit ``u``: ``(seen, path, x)``,
    each pair's (T, R) mirror path off that line and reflection point on it
    (:func:`~.models.plane_points`), and whether the pair stands on that side with ``x``
    inside both of its beams."""
    for n in (np.array([u[1], -u[0]]), np.array([-u[1], u[0]])):
        front = ((T - p) @ n < 0) & ((R - p) @ n < 0)
        path, x = plane_points(math.atan2(n[1], n[0]), float(p @ n), T, R)
        yield (front & in_beams(x, T, axT, cut_sin2) & in_beams(x, R, axR, cut_sin2)), path, x


def _first_paths(heard: Heard, pairs: np.ndarray) -> np.ndarray:
    """[p] the shortest path each of ``pairs`` (T ≤ R) heard (inf: none)."""
    out = np.full(len(pairs), np.inf)
    if len(heard.key) == 0:
        return out
    keys, starts = np.unique(heard.key, return_index=True)  # heard.key is sorted
    least = np.minimum.reduceat(heard.path, starts)
    want = pairs[:, 0] * heard.base + pairs[:, 1]
    at = np.minimum(np.searchsorted(keys, want), len(keys) - 1)
    found = keys[at] == want
    out[found] = least[at[found]]
    return out


__all__ = ["GAP_MARGIN_M", "GAP_REACH_M", "OpenGap", "line_mirrors", "open_gaps"]
