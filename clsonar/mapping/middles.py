"""Stretches of a locus' samples (:mod:`.tangents`): the middle of its in-beam arc, where a
surface facing the beam lies (the line of sight, thesis §2.1.1 part 1), and the arcs
around the scan envelope's points."""

from __future__ import annotations

import numpy as np

#: Samples of each locus (an ellipse with foci T and R) searched for crossings: 0.25°.
LOCUS_SAMPLES = 1440


def arcs_around(env: tuple[np.ndarray, ...], bias: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples (every 0.25°) of each scan envelope point's circle (``env``: locus, centre, r,
    point) within ±sqrt(2·r·bias) of the point (within ``bias`` of its tangent); their loci."""
    step = 2 * np.pi / LOCUS_SAMPLES
    half = (np.sqrt(2.0 * bias / env[2]) / step).astype(np.int64)
    row = np.repeat(np.arange(len(half)), 2 * half + 1)
    offset = np.arange(len(row)) - np.repeat(np.cumsum(2 * half + 1) - half - 1, 2 * half + 1)
    phi = np.arctan2(env[3][:, 1] - env[1][:, 1], env[3][:, 0] - env[1][:, 0])[row] + step * offset
    return env[1][row] + env[2][row, None] * np.stack([np.cos(phi), np.sin(phi)], -1), env[0][row]


def middle_of_arc(samples: np.ndarray, inside: np.ndarray, a: float,
                  bias: float) -> np.ndarray:
    """The samples within ±sqrt(2·a·bias) of arc around the middle of the in-beam run."""
    idx = np.flatnonzero(inside)
    if len(idx) == 0:
        return np.zeros((0, 2))
    # the in-beam run may wrap around sample 0: unwrap it before taking its middle
    gaps = np.diff(idx)
    if len(gaps) and gaps.max() > 1:
        start = int(np.argmax(gaps)) + 1
        idx = np.r_[idx[start:], idx[:start] + LOCUS_SAMPLES]
    middle = int(idx[len(idx) // 2])
    half = int(np.sqrt(2.0 * bias / a) / (2 * np.pi / LOCUS_SAMPLES))
    window = np.arange(middle - half, middle + half + 1) % LOCUS_SAMPLES
    return samples[window[inside[window]]]


__all__ = ["LOCUS_SAMPLES", "arcs_around", "middle_of_arc"]
