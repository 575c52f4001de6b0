"""The received signal of each fired pair in NumPy float64 (thesis eq. 2.3): its echoes,
sorted slices of the echo table, each a pulse (physics.pulse) at its time of flight, plus
the counter-based noise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import physics
from ..echoes import EchoTable
from ..scene import Scene
from ..sensors import SensorArray, pairs, place_sensors
from ..survey import with_detection_chosen
from .dsp import envelope_sq_raw
from .model import SignalModel, signal_model
from .philox import noise


@dataclass(frozen=True, eq=False)
class PairEchoes:
    """The fired pairs and each one's slice [lo, hi) of the echoes sorted by (tx, rx, tof)."""

    pairs: np.ndarray  # [P, 2] int64
    lo: np.ndarray  # [P] int64
    hi: np.ndarray  # [P] int64
    ek: np.ndarray  # [E] int64 floor(τ·fs)
    ef: np.ndarray  # [E] float64 τ·fs − ek
    ea: np.ndarray  # [E, 2] float64 (A·K, carrier phase φ), the kernels' real2
    tof: np.ndarray  # [E] float64 τ (s)
    amp: np.ndarray  # [E] float64 A
    phase: np.ndarray  # [E] float64 φ (rad): the pulse is A·p(t − τ) with its carrier + φ


def pair_echoes(model: SignalModel, sensors: SensorArray, echoes: EchoTable,
                pair_list: np.ndarray | None = None) -> PairEchoes:
    pr = pairs(sensors) if pair_list is None else np.asarray(pair_list, np.int64).reshape(-1, 2)
    tx = np.asarray(echoes.tx, np.int64)
    rx = np.asarray(echoes.rx, np.int64)
    n_sensors = 1 + max([len(sensors), *(int(a.max()) for a in (pr, tx, rx) if a.size)])
    tof = np.asarray(echoes.tof_s, np.float64)
    amp = np.asarray(echoes.amplitude, np.float64)
    phase = np.asarray(echoes.phase, np.float64)
    order = np.lexsort((tof, rx, tx))
    tx, rx, tof, amp, phase = tx[order], rx[order], tof[order], amp[order], phase[order]
    if (np.any(~np.isfinite(tof)) or np.any(tof < 0) or np.any(~np.isfinite(amp))
            or np.any(~np.isfinite(phase))):
        raise ValueError("echo times of flight must be finite and ≥ 0, amplitudes and "
                         "phases finite")
    ekey = tx * n_sensors + rx
    pkey = pr[:, 0] * n_sensors + pr[:, 1]
    lo, hi = _echo_ranges(ekey, pkey)
    x = tof * model.fs
    ek = np.floor(x)
    if len(ek) and ek.max() > 2**31 - 2**24:
        raise ValueError("an echo arrives too late for the sample index range")
    ea = np.stack([amp * model.k_norm, phase], axis=-1)
    return PairEchoes(pr, lo, hi, ek.astype(np.int64), x - ek, ea, tof, amp, phase)


def _echo_ranges(ekey: np.ndarray, pkey: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)``: the echoes (sorted keys ``ekey``) of each pair (keys ``pkey``) are
    ``lo[p]:hi[p]`` — ``np.searchsorted(ekey, pkey)`` left and right. Pairs in order (the
    pipeline's) look each echo up among the pairs instead, far fewer than the pairs of a
    large array: the echoes below pair p are those whose key no pair key before p reaches."""
    if len(pkey) < 2 * len(ekey) or np.any(pkey[1:] < pkey[:-1]):
        return (np.searchsorted(ekey, pkey, side="left").astype(np.int64),
                np.searchsorted(ekey, pkey, side="right").astype(np.int64))
    n = len(pkey) + 1
    below = np.bincount(np.searchsorted(pkey, ekey, side="right"), minlength=n)
    upto = np.bincount(np.searchsorted(pkey, ekey, side="left"), minlength=n)
    return (np.cumsum(below)[:-1].astype(np.int64, copy=False),
            np.cumsum(upto)[:-1].astype(np.int64, copy=False))


def inputs(scene: Scene, sensors: SensorArray | None, echoes: EchoTable,
           window_s: float | None, pair_list: np.ndarray | None = None):
    """The signal model of ``scene`` (its detection settings chosen from the scene where
    the file leaves them out, as the pipeline does) and the echoes of each pair."""
    sensors = sensors if sensors is not None else place_sensors(scene)
    model = signal_model(with_detection_chosen(scene, sensors), window_s)
    return model, pair_echoes(model, sensors, echoes, pair_list)


def reference_signal(model: SignalModel, pe: PairEchoes, slot: int,
                     n_total: int) -> np.ndarray:
    """s[n], n in [0, n_total), of pair slot ``slot`` in float64 (physics.pulse, eq. 2.3,
    each echo's carrier shifted by its phase)."""
    tx, rx = (int(v) for v in pe.pairs[slot])
    if model.noise_std > 0:
        s = model.noise_std * noise(model.seed, tx, rx, n_total)
    else:
        s = np.zeros(n_total)
    sigma_s = model.sigma / model.fs
    f = model.ratio * model.fs
    reach = math.ceil(model.pulse_len) + 2
    for e in range(pe.lo[slot], pe.hi[slot]):
        k = int(pe.ek[e])
        if k >= n_total:
            break
        n = np.arange(k, min(n_total, k + reach))
        u = (n - k) - pe.ef[e]
        s[n] += pe.amp[e] * physics.pulse(u / model.fs, sigma_s, f, 1.0, pe.phase[e])
    return s


def reference_envelope_sq(model: SignalModel, s: np.ndarray) -> np.ndarray:
    """E², calibrated, of the A-scan samples ``s`` (from n = 0)."""
    return model.calibration**2 * envelope_sq_raw(s, model.ratio, model.box)
