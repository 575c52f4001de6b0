"""Which pairs heard what (``mapping.mode = "reflectors"``): the detections indexed by
pair (:func:`heard_index`), the strongest of a pair's near a predicted path
(:func:`loudest`), the noise of a detection's amplitude (:func:`amplitude_noise`), and
a group's pairs a few at a time (:func:`group_pairs`) — what a patch's ends and a located
corner's silence are read from."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from ..scene import Scene
from ..sensors import SensorArray
from ..signals import envelope_noise_scale, signal_model
from .loci import Loci

#: A pair heard the surface where one of its detections lies within this of the
#: predicted path, metres.
HEARD_TOL_M = 0.003


def amplitude_noise(scene: Scene) -> float:
    """The noise σ of a detection's amplitude (units): with envelope detection the
    envelope's Rayleigh scale (each quadrature's σ, 0.145·σn for the default pulse,
    :func:`clsonar.signals.envelope_noise_scale`, docs/detection.md), with threshold
    detection the signal's σn (its amplitude is a sample)."""
    noise = scene.signal.noise_std
    if noise == 0 or scene.detection.mode != "envelope":
        return noise
    floor = scene.detection.min_envelope  # the scale does not depend on it
    detection = replace(scene.detection, min_envelope=1.0 if floor is None else floor)
    return envelope_noise_scale(signal_model(replace(scene, detection=detection)))


@dataclass(frozen=True)
class Heard:
    """The detections by pair (either direction), sorted once for :func:`loudest`:
    ``key`` = min(T, R)·base + max(T, R), their path c·τ and amplitude."""

    base: int
    key: np.ndarray
    path: np.ndarray
    amplitude: np.ndarray


def heard_index(loci: Loci, sensors: SensorArray, c: float) -> Heard:
    """:class:`Heard` of ``loci`` (speed of sound ``c``)."""
    base = len(sensors.positions) + 1
    key = np.minimum(loci.tx, loci.rx) * base + np.maximum(loci.tx, loci.rx)
    order = np.argsort(key, kind="stable")
    return Heard(base, key[order], c * loci.tof_s[order], loci.amplitude[order])


def loudest(heard: Heard, pairs: np.ndarray, path: np.ndarray,
            tolerance: float | np.ndarray = HEARD_TOL_M) -> tuple[np.ndarray, np.ndarray]:
    """``(amplitude, near)``: the strongest of each pair's detections (either direction;
    ``pairs`` T ≤ R) within ``tolerance`` (one, or one per pair) of ``path``, and whether
    it has one."""
    want = pairs[:, 0] * heard.base + pairs[:, 1]
    start = np.searchsorted(heard.key, want, side="left")
    count = np.searchsorted(heard.key, want, side="right") - start
    pair = np.repeat(np.arange(len(pairs)), count)  # each of the pairs' detections
    row = np.arange(len(pair)) - np.repeat(np.cumsum(count) - count, count) \
        + np.repeat(start, count)
    near = np.abs(heard.path[row] - path[pair]) <= np.broadcast_to(tolerance, len(pairs))[pair]
    amplitude = np.zeros(len(pairs))
    np.maximum.at(amplitude, pair[near], heard.amplitude[row[near]])
    return amplitude, np.bincount(pair[near], minlength=len(pairs)) > 0


#: Pairs of a group the silence test takes at a time (its memory; about 100 MB).
SILENCE_PAIRS = 1 << 18


def group_pairs(sensors: SensorArray, group: int) -> Iterator[np.ndarray]:
    """[p, 2] the pairs (T ≤ R) of ``group``, about :data:`SILENCE_PAIRS` at a time."""
    members = np.flatnonzero(sensors.groups == group)
    n = len(members)
    rows = max(1, SILENCE_PAIRS // max(n, 1))
    for i0 in range(0, n, rows):
        i, j = _triangle_rows(n, i0, min(i0 + rows, n))
        yield np.stack([members[i], members[j]], axis=-1)


def _triangle_rows(n: int, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
    """``(i, j)`` of the upper triangle (j ≥ i) of an n × n matrix, rows i0 … i1 − 1."""
    width = n - np.arange(i0, i1)
    i = np.repeat(np.arange(i0, i1), width)
    j = np.arange(int(width.sum())) - np.repeat(np.cumsum(width) - width, width) + i
    return i, j


__all__ = ["HEARD_TOL_M", "SILENCE_PAIRS", "Heard", "amplitude_noise", "group_pairs", "heard_index",
           "loudest"]
