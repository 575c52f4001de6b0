"""What a scan heard along a room's walls, for the walls fit (``post.fit = "walls"``,
:func:`clsonar.post.walls.fit_walls`): the gaps it heard as free space
(:func:`~.openings.open_gaps`), and a wall's echoes beyond its mapped stretch
(:func:`heard_along`).

A ring moving straight at a wall, within a few degrees of its normal, hears it with the
element that faces along its path, its range changing by almost exactly each step: the
loci's envelope lies ahead along the scan, on either side of the path (±θ), which the
ranges cannot tell, so the scan envelope leaves it out (:data:`~.envelope.
ENVELOPE_MAX_ALONG`) and no other pose may hear that stretch — beside a corner that the
ring cuts (the zoo's unseen seed 120 room-25: a 97° corner whose walls were mapped to 0.74
and 1.0 m from it, the corner not located). Once the wall's line is known from other poses,
each such echo tells where it came from: a detection whose path is the line's mirror path
for its pair, within its tolerance, its reflection point inside both beams and as strong
as a mirror's echo there (:func:`~.strength.mirror_floor`: not an edge's diffraction), is
that wall's echo at that reflection point.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..scene import Scene
from ..sensors import SensorArray
from .heard import amplitude_noise
from .loci import as_loci
from .openings import OpenGap, line_mirrors, open_gaps
from .strength import mirror_echo, mirror_floor
from .window import heard_tolerance

#: ``along(centre, direction, lo, hi, slack, reach)``: the span ``(lo, hi)`` of the wall
#: through ``centre`` along the unit ``direction`` extended by its echoes beyond it, each
#: within its tolerance plus ``slack`` (metres of the line's own uncertainty) and within
#: ``reach`` of the end so far (the gap the walls fit bridges, ``post.max_gap_m``).
Along = Callable[[np.ndarray, np.ndarray, float, float, float, float], tuple[float, float]]


@dataclass(frozen=True)
class ScanHeard:
    """What a scan heard along the walls: :func:`~.openings.open_gaps` and
    :func:`heard_along`."""

    open_gap: OpenGap
    along: Along


def scan_heard(scene: Scene, sensors: SensorArray, loci) -> ScanHeard:
    """:class:`ScanHeard` of the detections ``loci`` (each indexed when first asked)."""
    open_gap = open_gaps(scene, sensors, loci)
    return ScanHeard(open_gap, heard_along(scene, sensors, loci, open_gap))


def heard_along(scene: Scene, sensors: SensorArray, loci, open_gap: OpenGap | None = None
                ) -> Along:
    """The extension of a wall's span by its echoes beyond it (module docstring): the
    reflection points, on the wall's line, of the detections whose path is its mirror
    path within their tolerance (:func:`~.window.heard_tolerance`) plus twice ``slack``,
    from in front of it, inside both beams, at least as strong as a mirror's echo there;
    taken one after another beyond each end while each lies within ``reach`` of the end
    so far and ``open_gap`` does not say the stretch between was heard as free space
    (a doorway: the echoes beyond it are the next stretch's, of the same line)."""
    c = scene.medium.c
    cut_sin2, ka = scene.transducer.beam(c)
    mirror, noise = mirror_echo(scene), amplitude_noise(scene)

    @functools.cache
    def indexed() -> tuple[np.ndarray, ...]:
        """(T, R, axT, axR, path, amplitude, tolerance) of every detection."""
        d = as_loci(loci)
        tol = heard_tolerance(d.amplitude, scene.signal.noise_std, c,
                              scene.transducer.pulse_sigma_s)
        return (sensors.positions[d.tx], sensors.positions[d.rx], sensors.axes[d.tx],
                sensors.axes[d.rx], c * d.tof_s, d.amplitude, tol)

    def along(centre: np.ndarray, direction: np.ndarray, lo: float, hi: float,
              slack: float, reach: float) -> tuple[float, float]:
        if mirror <= 0:
            return lo, hi
        T, R, axT, axR, path, amplitude, tol = indexed()
        found = []
        for seen, mirrored, x in line_mirrors(centre, direction, T, R, axT, axR, cut_sin2):
            ok = seen & (np.abs(mirrored - path) <= tol + 2.0 * slack)
            ok[ok] = amplitude[ok] >= mirror_floor(x[ok], T[ok], axT[ok], R[ok], axR[ok],
                                                   mirror, ka, noise)
            found.append((x[ok] - centre) @ direction)
        s = np.sort(np.concatenate(found))

        def free(a: float, b: float) -> bool:  # the stretch from a to b heard as free space
            return open_gap is not None and open_gap(centre + a * direction,
                                                     centre + b * direction)

        for v in s[s > hi]:
            if v - hi > reach or free(hi, float(v)):
                break
            hi = float(v)
        for v in s[s < lo][::-1]:
            if lo - v > reach or free(float(v), lo):
                break
            lo = float(v)
        return lo, hi

    return along


__all__ = ["Along", "ScanHeard", "heard_along", "scan_heard"]
