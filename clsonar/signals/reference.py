"""Detection and envelopes in NumPy float64 from materialised A-scans (tests, small
scenes): the reference of the kernels of kernels/signals.cl (clsonar.signals.host)."""

from __future__ import annotations

import numpy as np

from ..echoes import EchoTable
from ..scene import Scene
from ..sensors import SensorArray
from .detection import (
    Candidates,
    Detections,
    envelope_floor,
    envelope_thresholds,
    finish_envelope,
    finish_threshold,
    join_candidates,
)
from .dsp import HIST_BINS, HIST_STRIDE, hist_bins
from .model import SignalModel, envelope_grid, envelope_offset
from .synthesis import PairEchoes, inputs, reference_envelope_sq, reference_signal


def _ref_threshold_candidates(model: SignalModel, s: np.ndarray, first_only: bool
                              ) -> tuple[np.ndarray, np.ndarray]:
    """Rising crossings of the threshold in the A-scan ``s`` (only the first if
    ``first_only``): their samples and values."""
    n = np.flatnonzero((s[:-1] < model.threshold) & (s[1:] >= model.threshold)) + 1
    if first_only:
        n = n[:1]
    return n, s[n]


def _ref_envelope_candidates(model: SignalModel, e2: np.ndarray, floor: float):
    """Local maxima of E² at m in [1, n_env) with E ≥ floor; values E at m − span, m, m + span."""
    m = np.arange(1, model.n_env)
    q = e2[m]
    ok = (e2[m - 1] < q) & (q >= e2[m + 1]) & (q >= floor * floor)
    m = m[ok]
    before = np.where(m - model.span >= 0, e2[np.maximum(m - model.span, 0)], 0.0)
    vals = np.sqrt(np.stack([before, e2[m], e2[m + model.span]], axis=-1))
    return m, vals


def reference_candidates(model: SignalModel, pe: PairEchoes):
    """Candidates (and, for the envelope, histograms) of every pair, from materialised
    float64 A-scans — what the kernels compute without materialising them."""
    found = []
    hist = np.zeros((len(pe.pairs), HIST_BINS), dtype=np.int64)
    for p in range(len(pe.pairs)):
        if model.mode == "threshold":
            s = reference_signal(model, pe, p, model.n_samples)
            n, v = _ref_threshold_candidates(model, s, pe.pairs[p, 0] == pe.pairs[p, 1])
        else:
            s = reference_signal(model, pe, p, model.n_env + model.span)
            e2 = reference_envelope_sq(model, s)
            hist[p] = np.bincount(hist_bins(e2[:model.n_env:HIST_STRIDE]),
                                  minlength=HIST_BINS)
            n, v = _ref_envelope_candidates(model, e2, envelope_floor(model))
        found.append(Candidates(np.full(len(n), p, dtype=np.int64), n.astype(np.int64), v))
    return join_candidates(model.mode, found), hist


def detect_reference(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
                     window_s: float | None = None) -> Detections:
    """The detections of every fired pair in NumPy float64, materialising each A-scan (tests,
    small scenes): the reference of :func:`detect`."""
    model, pe = inputs(scene, sensors, echoes, window_s)
    cand, hist = reference_candidates(model, pe)
    if model.mode == "threshold":
        return finish_threshold(model, pe, cand)
    return finish_envelope(model, pe, cand, envelope_thresholds(model, hist))


def a_scan(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, tx: int, rx: int, *,
           window_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(t, s)``: the A-scan of pair (tx, rx) over the window, float64 NumPy (for plots)."""
    model, pe = inputs(scene, sensors, echoes, window_s, np.array([[tx, rx]]))
    s = reference_signal(model, pe, 0, model.n_samples)
    return np.arange(model.n_samples) / model.fs, s


def envelopes_reference(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
                        rate_hz: float = 1e5, window_s: float | None = None
                        ) -> tuple[float, np.ndarray]:
    """NumPy float64 reference of :func:`envelopes`."""
    model, pe = inputs(scene, sensors, echoes, window_s)
    dec, n_out = envelope_grid(model, rate_hz)
    off = envelope_offset(model)
    idx = np.arange(n_out) * dec + off
    env = np.zeros((len(pe.pairs), n_out))
    for p in range(len(pe.pairs)):
        s = reference_signal(model, pe, p, int(idx[-1]) + 1)
        env[p] = np.sqrt(reference_envelope_sq(model, s)[idx])
    return dec / model.fs, env
