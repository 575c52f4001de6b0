"""Detection's host side, shared by the kernels and the NumPy reference: candidates become
detections (thesis §2.1.1 parts 3–4: first crossings with hold-off; envelope peaks above a
noise-adaptive threshold, refined)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..scene import DetectionMode
from .dsp import noise_scale, refine
from .model import SignalModel
from .polaroid import first_per_pair
from .synthesis import PairEchoes

#: Envelope thresholds are at least this fraction of the transmitted amplitude A0: below it,
#: a noise-free envelope holds only the float32 round-off of the running sums.
ENVELOPE_FLOOR = 1e-4


@dataclass(frozen=True, eq=False)
class Detections:
    """Detected echoes, one row each, sorted by (tx, rx, tof_s)."""

    tx: np.ndarray  # int64
    rx: np.ndarray  # int64
    tof_s: np.ndarray  # float64 time-of-flight estimate
    amplitude: np.ndarray  # float64: s at the crossing (threshold) / envelope peak (envelope)

    def __len__(self) -> int:
        return len(self.tof_s)


def empty_detections() -> Detections:
    """No detection."""
    return Detections(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))


@dataclass(frozen=True, eq=False)
class Candidates:
    """Candidate detections of pair slots, before the finish (:func:`finish_threshold`,
    :func:`finish_envelope`)."""

    slot: np.ndarray  # int64 pair slot
    n: np.ndarray  # int64 sample (threshold) / envelope index (envelope)
    values: np.ndarray  # [k] s[n] (threshold) or [k, 3] E[m − span], E[m], E[m + span]


def join_candidates(mode: DetectionMode, parts: list[Candidates]) -> Candidates:
    """The candidates of ``parts`` together (values [k] for ``threshold``, [k, 3] else)."""
    shape = () if mode == "threshold" else (3,)
    return Candidates(
        np.concatenate([c.slot for c in parts]) if parts else np.zeros(0, np.int64),
        np.concatenate([c.n for c in parts]) if parts else np.zeros(0, np.int64),
        np.concatenate([c.values for c in parts]) if parts else np.zeros((0, *shape)))


def envelope_floor(model: SignalModel) -> float:
    """The lowest envelope threshold: ``min_envelope`` (the Polaroid receiver: its
    comparator's level), and at least :data:`ENVELOPE_FLOOR`·A0."""
    low = model.min_envelope if model.receiver is None else model.receiver.floor
    return max(low, ENVELOPE_FLOOR * model.amplitude)


#: Noise cannot reach a threshold this many of its standard scales away (σn for the
#: threshold detector's signal, the Rayleigh scale for the envelope's): the chance is
#: e^(−50) ≈ 2e-22 per sample, below 1e-12 for a run of 10⁹ samples.
QUIET_SIGMAS = 10.0


def envelope_noise_scale(model: SignalModel) -> float:
    """The Rayleigh scale of a noise-only envelope, in units: the two boxes' triangle h
    gives each quadrature σn·calibration·sqrt(Σh²/2) (docs/detection.md: 0.145·σn)."""
    tri = np.convolve(np.ones(model.box), np.ones(model.box))
    return model.noise_std * model.calibration * math.sqrt(float(np.sum(tri**2)) / 2.0)


def noise_stays_quiet(model: SignalModel) -> bool:
    """Whether the noise alone cannot be detected: the lowest threshold is at least
    :data:`QUIET_SIGMAS` of the noise's scale (always, noise-free). Then only the samples an
    echo reaches can hold a detection, and every threshold is the floor (the noise's
    estimate, 6·ŝ, stays far below it), so scanning only those samples gives the full
    scan's detections bit for bit, but with a chance below 1e-12 per run."""
    if model.noise_std == 0:
        return True
    if model.mode == "threshold":
        return model.threshold >= QUIET_SIGMAS * model.noise_std
    return envelope_floor(model) >= QUIET_SIGMAS * envelope_noise_scale(model)


def envelope_thresholds(model: SignalModel, hist: np.ndarray) -> np.ndarray:
    """Per-pair envelope threshold max(min_envelope, false_alarm_sigmas·ŝ) from histograms,
    never below :data:`ENVELOPE_FLOOR`·A0 (float32 round-off of the running sums)."""
    return thresholds_of(model, noise_scale(hist))


def thresholds_of(model: SignalModel, scales: np.ndarray) -> np.ndarray:
    """:func:`envelope_thresholds` from the pairs' noise scales ŝ; the Polaroid receiver's
    comparator is fixed (TL851: a 1.2 V level detector), so it ignores them: its floor,
    then its time-dependent threshold per echo (:func:`finish_envelope`)."""
    if model.receiver is not None:
        return np.full(len(scales), envelope_floor(model))
    return np.maximum(envelope_floor(model), model.false_alarm_sigmas * scales)


def finish_threshold(model: SignalModel, pe: PairEchoes, cand: Candidates) -> Detections:
    """First crossing (T = R) or crossings with hold-off (T ≠ R), per pair."""
    order = np.lexsort((cand.n, cand.slot))
    slot, n, v = cand.slot[order], cand.n[order], np.asarray(cand.values)[order]
    if len(slot) == 0:
        return empty_detections()
    starts = np.flatnonzero(np.r_[True, slot[1:] != slot[:-1]])
    keep = np.zeros(len(slot), dtype=bool)
    keep[starts] = True
    monostatic = pe.pairs[slot, 0] == pe.pairs[slot, 1]
    stride = model.n_samples + model.holdoff + 1
    key = slot * stride + n
    cur = starts[~monostatic[starts]]
    while len(cur):
        nxt = np.searchsorted(key, key[cur] + model.holdoff, side="left")
        ok = nxt < len(key)
        ok[ok] &= slot[nxt[ok]] == slot[cur[ok]]
        cur = nxt[ok]
        keep[cur] = True
    slot, n, v = slot[keep], n[keep], v[keep]
    return Detections(pe.pairs[slot, 0].copy(), pe.pairs[slot, 1].copy(), n / model.fs,
                      v.astype(np.float64))


def finish_envelope(model: SignalModel, pe: PairEchoes, cand: Candidates,
                    thresholds: np.ndarray) -> Detections:
    """Threshold, non-maximum suppression within one pulse length, peak refinement; the
    Polaroid receiver: its threshold at each candidate's echo time, then the first echo of
    each pair (single-echo mode)."""
    vals = np.asarray(cand.values, dtype=np.float64).reshape(-1, 3)
    thr = thresholds[cand.slot]
    if model.receiver is not None:
        thr = np.maximum(thr, model.receiver.thresholds((cand.n - model.delay) / model.fs))
    keep = vals[:, 1] >= thr if len(vals) else np.zeros(0, bool)
    slot, m, vals = cand.slot[keep], cand.n[keep], vals[keep]
    order = np.lexsort((m, slot))
    slot, m, vals = slot[order], m[order], vals[order]
    peak = vals[:, 1]
    suppressed = np.zeros(len(m), dtype=bool)
    for k in range(1, len(m)):
        a, b = np.arange(len(m) - k), np.arange(k, len(m))
        close = (slot[a] == slot[b]) & (m[b] - m[a] < model.holdoff)
        if not close.any():
            break
        b_wins = peak[b] > peak[a]  # on a tie the earlier peak wins
        suppressed[a[close & b_wins]] = True
        suppressed[b[close & ~b_wins]] = True
    slot, m, vals = slot[~suppressed], m[~suppressed], vals[~suppressed]
    pos, amp = refine(m.astype(np.float64), vals[:, 0], vals[:, 1], vals[:, 2], model.span)
    tof = (pos - model.delay) / model.fs
    ok = tof >= 0
    slot, tof, amp = slot[ok], tof[ok], amp[ok]
    order = np.lexsort((tof, slot))
    slot, tof, amp = slot[order], tof[order], amp[order]
    if model.receiver is not None:
        first = first_per_pair(slot)
        slot, tof, amp = slot[first], tof[first], amp[first]
    return Detections(pe.pairs[slot, 0].copy(), pe.pairs[slot, 1].copy(), tof, amp)


def merge_candidates(a: Candidates, b: Candidates, drop: np.ndarray) -> Candidates:
    """``a`` without the slots in ``drop``, plus ``b``."""
    keep = ~np.isin(a.slot, drop)
    return Candidates(np.concatenate([a.slot[keep], b.slot]),
                      np.concatenate([a.n[keep], b.n]),
                      np.concatenate([np.asarray(a.values)[keep], np.asarray(b.values)]))
