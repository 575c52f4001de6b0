"""Received signals (thesis eq. 2.3, §2.1.1 part 2) and detection (§2.1.1 parts 3–4, and better).

The received signal of a fired pair (T, R), sampled at ``detection.sample_rate_hz`` (fs, default
1 MHz) from t = 0 to the window end t_max (default: the longest round trip inside the extent,
2·diagonal/c, rounded up to a whole sample), is

    s(t) = Σ_e A_e·p(t − τ_e) + noise_std·N(0, 1)

with p the unit-amplitude pulse of eq. 2.3 (:func:`clsonar.physics.pulse`, support [0, 6σ]) and
(τ_e, A_e) the pair's echoes from the :class:`~clsonar.echoes.EchoTable`. The noise is
counter-based: Philox4x32-10 (the random123 generator pyopencl ships) with key = the scene's
``signal.seed`` (low, high 32 bits) and counter (n >> 2, T, R, 0) gives four uint32 per four
samples; Box–Muller turns each two into two normals (uniforms (2·(x >> 9) + 1)·2⁻²⁴, exact in
float32). A sample is thus a function of (seed, T, R, n) alone — the same on every device,
work-group size and chunking. :func:`philox4x32` and :func:`noise` are the NumPy reference.

Detection (``scene.detection.mode``), both with an OpenCL path (:func:`detect`) and a NumPy
float64 reference (:func:`detect_reference`) that share the host-side finalisation:

``threshold`` — the thesis: rising crossings of ``signal.threshold`` (s[n − 1] < thr ≤ s[n]);
    time of flight = that sample's time (the thesis' late-biased estimate, kept on purpose);
    T = R: only the first crossing; T ≠ R: every crossing at least one pulse length (6σ) after
    the previous counted one; amplitude = s[n].

``envelope`` — ours: quadrature demodulation at the carrier, z[n] = s[n]·exp(−2πi·f·n/fs),
    and two running boxes of :attr:`SignalModel.box` samples each (a triangle of about the
    pulse envelope's FWHM on each side, 99 % of the matched filter's SNR for the Gaussian
    envelope; the box length is a whole number of carrier half-periods, so the 2f term of the
    demodulation cancels), O(1) per sample. E = calibration·|y| reads ≈ A at the peak of an
    isolated echo of amplitude A. Noise-adaptive threshold per pair = max(``min_envelope``,
    ``false_alarm_sigmas``·ŝ), ŝ the Rayleigh scale of the envelope's noise estimated from the
    pair's own A-scan: median(E)/√(2 ln 2) (the A-scan is mostly noise), the median read from a
    histogram of every :data:`HIST_STRIDE`-th E² (8 bins per octave of E, interpolated).
    Every local maximum above threshold with no stronger local maximum within one pulse length
    is a detection. Time of flight = peak time − (box − 1)/fs (the filter's delay) − 3σ, the
    peak refined by a parabola through ln E at m − span, m, m + span (exact for a Gaussian
    peak; its ≈ −0.06-sample residual for this peak shape is calibrated out); amplitude = the
    refined peak value. Thresholds never go below :data:`ENVELOPE_FLOOR`·A0. See
    docs/detection.md for the measured bias and variance (at the Cramér–Rao bound).

The OpenCL path never materialises an A-scan: work items own (pair, chunk of samples),
compute the samples they need on the fly (each sums only the echoes whose pulse covers it;
a pair's echoes are a sorted slice of the echo table) including the history their chunk needs,
and append candidates to a bounded per-pair buffer; pairs whose buffer overflowed are run
again with exactly the room they need (and, for the envelope, the final threshold as floor).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

from . import physics
from .echoes import EchoTable
from .opencl import PRECISIONS, context_for, device_kind
from .opencl import kernel as kernel_of
from .opencl import queue as queue_of
from .opencl import work_group as fixed_work_group
from .scene import Scene
from .sensors import SensorArray, pairs, place_sensors

#: Philox4x32 multipliers and Weyl key increments (random123, as in pyopencl's philox.cl).
PHILOX_M = (0xD2511F53, 0xCD9E8D57)
PHILOX_W = (0x9E3779B9, 0xBB67AE85)
PHILOX_ROUNDS = 10

#: Histogram of E² for the noise estimate: bin 0 below 2⁻⁴⁰ (E < 1e-6), then 4 bins per octave
#: of E² (the top two mantissa bits of its float32), the last bin open above.
HIST_BINS = 256
HIST_LOW_LOG2 = -40
HIST_BASE = (127 + HIST_LOW_LOG2) << 2
#: Every this many envelope samples enter the histogram (neighbours are strongly correlated).
HIST_STRIDE = 4

#: Rayleigh median / scale: median(E) = ŝ·√(2 ln 2) for noise-only envelopes.
RAYLEIGH_MEDIAN = math.sqrt(2.0 * math.log(2.0))

#: Envelope thresholds are at least this fraction of the transmitted amplitude A0: below it,
#: a noise-free envelope holds only the float32 round-off of the running sums.
ENVELOPE_FLOOR = 1e-4

#: Candidate capacity per pair of the first pass (a re-run gives overflowing pairs more).
DEFAULT_CAPACITY = {"threshold": 256, "envelope": 64}

#: Samples per work item (chunk), by device kind and mode.
DEFAULT_CHUNK = {("CPU", "threshold"): 8192, ("CPU", "envelope"): 4096,
                 ("GPU", "threshold"): 1024, ("GPU", "envelope"): 1024}

#: Work-group size (fixed: PoCL compiles a kernel anew for each size it meets).
WORK_GROUP = 32

#: Work items per launch and candidate slots per launch (pairs are split into launches).
ITEMS_PER_LAUNCH = 1 << 20
SLOTS_PER_LAUNCH = 1 << 22

#: Longest box of the envelope filter, samples (private rings in the kernel).
MAX_BOX = 4096



# --------------------------------------------------------------------------- results


@dataclass(frozen=True, eq=False)
class Detections:
    """Detected echoes, one row each, sorted by (tx, rx, tof_s)."""

    tx: np.ndarray  # int64
    rx: np.ndarray  # int64
    tof_s: np.ndarray  # float64 time-of-flight estimate
    amplitude: np.ndarray  # float64: s at the crossing (threshold) / envelope peak (envelope)

    def __len__(self) -> int:
        return len(self.tof_s)


def _empty_detections() -> Detections:
    return Detections(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))


# --------------------------------------------------------------------------- the model


@dataclass(frozen=True)
class SignalModel:
    """Everything the signal model and both detectors need, in samples where it says so."""

    fs: float  # sample rate, Hz
    n_samples: int  # A-scan samples n = 0 … n_samples − 1 (t = n/fs up to window_s)
    window_s: float  # t_max
    sigma: float  # σ of the pulse envelope, samples
    pulse_len: float  # 6σ, samples
    ratio: float  # carrier cycles per sample, f/fs
    k_norm: float  # K of eq. 2.3 (physics.pulse_normalisation)
    noise_std: float
    threshold: float
    seed: int
    amplitude: float  # A0, transmitted amplitude (units)
    mode: str
    holdoff: int  # one pulse length in whole samples, ceil(6σ)
    box: int  # samples of each of the two envelope boxes
    span: int  # half-span of the peak interpolation, samples
    calibration: float  # E = calibration·|y|
    peak_bias: float  # the peak interpolation's systematic offset, samples (_calibration)
    n_env: int  # envelope peaks are searched at m in [1, n_env)
    false_alarm_sigmas: float
    min_envelope: float
    demod_period: int  # samples per carrier period if whole (table-free exact phase), else 0

    @property
    def key(self) -> tuple[int, int]:
        """Philox key (low, high 32 bits of the seed)."""
        return (self.seed & 0xFFFFFFFF, (self.seed >> 32) & 0xFFFFFFFF)

    @property
    def delay(self) -> float:
        """Samples from an echo's arrival to its refined envelope peak: the filter's delay
        (box − 1), the pulse's centre 3σ and the interpolation's bias."""
        return (self.box - 1) + 3.0 * self.sigma + self.peak_bias


def default_window_s(scene: Scene) -> float:
    """The longest round trip inside the extent, 2·diagonal/c, rounded up to a whole sample."""
    xmin, ymin, xmax, ymax = scene.extent
    fs = scene.detection.sample_rate_hz
    t = 2.0 * math.hypot(xmax - xmin, ymax - ymin) / scene.medium.c
    return math.ceil(t * fs - 1e-9) / fs


def _box_length(sigma: float, ratio: float) -> int:
    """About the envelope's FWHM (2.355σ) in samples, a whole number of carrier half-periods
    when a half-period is at least a sample (then the demodulation's 2f term cancels)."""
    fwhm = 2.0 * math.sqrt(2.0 * math.log(2.0)) * sigma
    half = 0.5 / ratio
    if half >= 1.0:
        box = round(max(1, round(fwhm / half)) * half)
    else:
        box = round(fwhm)
    return int(min(max(box, 1), MAX_BOX))


def _demod_period(ratio: float) -> int:
    """Smallest p ≤ 4096 with ratio·p a whole number (the carrier's period in samples), else 0."""
    for p in range(1, 4097):
        if abs(ratio * p - round(ratio * p)) < 1e-9 * max(1.0, ratio * p):
            return p
    return 0


def signal_model(scene: Scene, window_s: float | None = None) -> SignalModel:
    """The :class:`SignalModel` of ``scene``; ``window_s`` overrides the window end t_max."""
    d = scene.detection
    t = scene.transducer
    fs = float(d.sample_rate_hz)
    window = default_window_s(scene) if window_s is None else float(window_s)
    if not window > 0 or not math.isfinite(window):
        raise ValueError("window_s must be a positive number of seconds")
    n_samples = math.ceil(window * fs - 1e-9) + 1
    if n_samples > 2**31 - 2**24:
        raise ValueError(f"an A-scan of {n_samples} samples is too long (window × sample rate)")
    sigma = t.pulse_sigma_s * fs
    ratio = t.frequency_hz / fs
    box = _box_length(sigma, ratio)
    span = max(1, round(sigma / 2))
    pulse_len = 6.0 * sigma
    n_env = n_samples + (box - 1) + math.ceil(3.0 * sigma)
    model = SignalModel(
        fs=fs, n_samples=n_samples, window_s=(n_samples - 1) / fs, sigma=sigma,
        pulse_len=pulse_len, ratio=ratio,
        k_norm=physics.pulse_normalisation(t.pulse_sigma_s, t.frequency_hz),
        noise_std=float(scene.signal.noise_std), threshold=float(scene.signal.threshold),
        seed=int(scene.signal.seed), amplitude=float(t.amplitude), mode=d.mode,
        holdoff=math.ceil(pulse_len - 1e-9),
        box=box, span=span, calibration=1.0, peak_bias=0.0, n_env=n_env,
        false_alarm_sigmas=float(d.false_alarm_sigmas), min_envelope=float(d.min_envelope),
        demod_period=_demod_period(ratio))
    return _with_calibration(model)


def _with_calibration(m: SignalModel) -> SignalModel:
    from dataclasses import replace

    gain, bias = _calibration(m.sigma, m.ratio, m.k_norm, m.box, m.span)
    return replace(m, calibration=gain, peak_bias=bias)


@cache
def _calibration(sigma: float, ratio: float, k_norm: float, box: int,
                 span: int) -> tuple[float, float]:
    """``(gain, bias)`` of the envelope detector from noise-free unit echoes at 8 sub-sample
    arrival times: gain = 1 / the mean refined peak value, so an isolated echo of amplitude A
    reads ≈ A; bias = the mean of (refined peak position − arrival − (box − 1) − 3σ), samples,
    the interpolation's small systematic offset (≈ −0.06 samples), removed from times of
    flight."""
    peaks, offsets = [], []
    n_total = math.ceil(6 * sigma) + 2 * box + 2 * span + 8
    for j in range(8):
        tau = 2.0 + j / 8.0
        n = np.arange(n_total, dtype=np.float64)
        s = _pulse_samples(n - tau, sigma, ratio, k_norm)
        e = np.sqrt(_envelope_sq_raw(s, ratio, box))
        m = int(np.argmax(e))
        pos, amp = _refine(np.array([m], float), e[[m - span]], e[[m]], e[[m + span]], span)
        peaks.append(float(amp[0]))
        offsets.append(float(pos[0]) - tau - (box - 1) - 3.0 * sigma)
    return 1.0 / float(np.mean(peaks)), float(np.mean(offsets))


# --------------------------------------------------------------------------- noise (reference)


def philox4x32(counter: np.ndarray, key: tuple[int, int]) -> np.ndarray:
    """Philox4x32-10 of ``counter`` ([..., 4] uint32) under ``key`` (k0, k1): [..., 4] uint32.

    Vectorised NumPy in uint64 arithmetic; bit-identical to random123's ``philox4x32``.
    """
    mask = np.uint64(0xFFFFFFFF)
    c = np.asarray(counter, dtype=np.uint32).astype(np.uint64)
    c0, c1, c2, c3 = c[..., 0], c[..., 1], c[..., 2], c[..., 3]
    k0, k1 = np.uint64(key[0] & 0xFFFFFFFF), np.uint64(key[1] & 0xFFFFFFFF)
    m0, m1 = np.uint64(PHILOX_M[0]), np.uint64(PHILOX_M[1])
    w0, w1 = np.uint64(PHILOX_W[0]), np.uint64(PHILOX_W[1])
    shift = np.uint64(32)
    for r in range(PHILOX_ROUNDS):
        if r:
            k0 = (k0 + w0) & mask
            k1 = (k1 + w1) & mask
        p0 = m0 * c0
        p1 = m1 * c2
        c0, c1, c2, c3 = (p1 >> shift) ^ c1 ^ k0, p1 & mask, (p0 >> shift) ^ c3 ^ k1, p0 & mask
    return np.stack([c0, c1, c2, c3], axis=-1).astype(np.uint32)


def box_muller(raw: np.ndarray) -> np.ndarray:
    """Four normals per four uint32 ([..., 4] → [..., 4] float64), as the kernel computes
    them: u = (2·(x >> 9) + 1)·2⁻²⁴, (r cos 2πv, r sin 2πv) with r = √(−2 ln u), for (x0, x1)
    and (x2, x3)."""
    x = np.asarray(raw, dtype=np.uint32)
    u = (2.0 * (x >> np.uint32(9)).astype(np.float64) + 1.0) * 2.0**-24
    r = np.sqrt(-2.0 * np.log(u[..., 0::2]))
    th = 2.0 * math.pi * u[..., 1::2]
    out = np.empty(x.shape, dtype=np.float64)
    out[..., 0::2] = r * np.cos(th)
    out[..., 1::2] = r * np.sin(th)
    return out


def noise(seed: int, tx: int, rx: int, n_samples: int, start: int = 0) -> np.ndarray:
    """Standard normals of samples [start, start + n_samples) of pair (tx, rx) (float64)."""
    key = (seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF)
    if n_samples <= 0:
        return np.zeros(0)
    b0, b1 = start >> 2, (start + n_samples - 1) >> 2
    blocks = np.arange(b0, b1 + 1, dtype=np.uint64)
    ctr = np.zeros((len(blocks), 4), dtype=np.uint32)
    ctr[:, 0] = blocks.astype(np.uint32)
    ctr[:, 1] = tx
    ctr[:, 2] = rx
    z = box_muller(philox4x32(ctr, key)).ravel()
    off = start - 4 * b0
    return z[off:off + n_samples]


# --------------------------------------------------------------------------- pairs and echoes


@dataclass(frozen=True, eq=False)
class _PairEchoes:
    """The fired pairs and each one's slice [lo, hi) of the echoes sorted by (tx, rx, tof)."""

    pairs: np.ndarray  # [P, 2] int64
    lo: np.ndarray  # [P] int64
    hi: np.ndarray  # [P] int64
    ek: np.ndarray  # [E] int64 floor(τ·fs)
    ef: np.ndarray  # [E] float64 τ·fs − ek
    ea: np.ndarray  # [E] float64 A·K
    tof: np.ndarray  # [E] float64 τ (s)
    amp: np.ndarray  # [E] float64 A


def _pair_echoes(model: SignalModel, sensors: SensorArray, echoes: EchoTable,
                 pair_list: np.ndarray | None = None) -> _PairEchoes:
    pr = pairs(sensors) if pair_list is None else np.asarray(pair_list, np.int64).reshape(-1, 2)
    tx = np.asarray(echoes.tx, np.int64)
    rx = np.asarray(echoes.rx, np.int64)
    n_sensors = 1 + max([len(sensors), *(int(a.max()) for a in (pr, tx, rx) if a.size)])
    tof = np.asarray(echoes.tof_s, np.float64)
    amp = np.asarray(echoes.amplitude, np.float64)
    order = np.lexsort((tof, rx, tx))
    tx, rx, tof, amp = tx[order], rx[order], tof[order], amp[order]
    if np.any(~np.isfinite(tof)) or np.any(tof < 0) or np.any(~np.isfinite(amp)):
        raise ValueError("echo times of flight must be finite and ≥ 0, amplitudes finite")
    ekey = tx * n_sensors + rx
    pkey = pr[:, 0] * n_sensors + pr[:, 1]
    lo = np.searchsorted(ekey, pkey, side="left")
    hi = np.searchsorted(ekey, pkey, side="right")
    x = tof * model.fs
    ek = np.floor(x)
    if len(ek) and ek.max() > 2**31 - 2**24:
        raise ValueError("an echo arrives too late for the sample index range")
    return _PairEchoes(pr, lo.astype(np.int64), hi.astype(np.int64), ek.astype(np.int64),
                       x - ek, amp * model.k_norm, tof, amp)


# --------------------------------------------------------------------------- reference signals


def _pulse_samples(u: np.ndarray, sigma: float, ratio: float, k_norm: float) -> np.ndarray:
    """Unit pulse of eq. 2.3 at u samples after arrival (σ in samples), K·envelope·carrier."""
    env = np.exp(-((u - 3.0 * sigma) ** 2) / (2.0 * sigma**2))
    p = k_norm * env * np.sin(2.0 * math.pi * ratio * u)
    return np.where((u >= 0.0) & (u <= 6.0 * sigma), p, 0.0)


def _reference_signal(model: SignalModel, pe: _PairEchoes, slot: int,
                      n_total: int) -> np.ndarray:
    """s[n], n in [0, n_total), of pair slot ``slot`` in float64 (physics.pulse, eq. 2.3)."""
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
        s[n] += pe.amp[e] * physics.pulse(u / model.fs, sigma_s, f, 1.0)
    return s


def _box(x: np.ndarray, length: int) -> np.ndarray:
    """Causal running sum of ``length`` samples (zeros before the start)."""
    c = np.cumsum(x)
    out = c.copy()
    out[length:] -= c[:-length]
    return out


def _envelope_sq_raw(s: np.ndarray, ratio: float, box: int) -> np.ndarray:
    """|y|² of the two-box demodulated signal (uncalibrated)."""
    n = np.arange(len(s), dtype=np.float64)
    z = s * np.exp(-2j * math.pi * ((ratio * n) % 1.0))
    y = _box(_box(z, box), box)
    return y.real**2 + y.imag**2


def _reference_envelope_sq(model: SignalModel, s: np.ndarray) -> np.ndarray:
    """E², calibrated, of the A-scan samples ``s`` (from n = 0)."""
    return model.calibration**2 * _envelope_sq_raw(s, model.ratio, model.box)


def _hist_bins(e2: np.ndarray) -> np.ndarray:
    """Histogram bins of E² values as the kernel computes them (from float32 bits)."""
    bits = np.asarray(e2, dtype=np.float32).view(np.uint32).astype(np.int64)
    return np.clip((bits >> 21) - HIST_BASE + 1, 0, HIST_BINS - 1)


def _hist_edges() -> np.ndarray:
    """[HIST_BINS + 1] lower edges of E² bins (bin 0 from 0)."""
    b = np.arange(HIST_BINS + 1, dtype=np.int64)
    bits = ((b - 1 + HIST_BASE) << 21).astype(np.uint32)
    edges = bits.view(np.float32).astype(np.float64)
    edges[0] = 0.0
    return edges


_EDGES = _hist_edges()


def _noise_scale(hist: np.ndarray) -> np.ndarray:
    """Rayleigh scale ŝ of each row's envelope noise: median(E)/√(2 ln 2), the median of E²
    read from the histogram (linear inside the bin)."""
    hist = np.atleast_2d(np.asarray(hist, dtype=np.float64))
    total = hist.sum(axis=1)
    cum = np.cumsum(hist, axis=1)
    half = 0.5 * total
    b = np.argmax(cum >= half[:, None], axis=1)
    rows = np.arange(len(hist))
    below = np.where(b > 0, cum[rows, np.maximum(b - 1, 0)], 0.0)
    inside = hist[rows, b]
    frac = np.where(inside > 0, (half - below) / np.where(inside > 0, inside, 1.0), 0.0)
    lo, hi = _EDGES[b], _EDGES[b + 1]
    med_e2 = np.where(total > 0, lo + frac * (hi - lo), 0.0)
    return np.sqrt(med_e2) / RAYLEIGH_MEDIAN


def envelope_thresholds(model: SignalModel, hist: np.ndarray) -> np.ndarray:
    """Per-pair envelope threshold max(min_envelope, false_alarm_sigmas·ŝ) from histograms,
    never below :data:`ENVELOPE_FLOOR`·A0 (float32 round-off of the running sums)."""
    floor = max(model.min_envelope, ENVELOPE_FLOOR * model.amplitude)
    return np.maximum(floor, model.false_alarm_sigmas * _noise_scale(hist))


# --------------------------------------------------------------------------- candidates


@dataclass(frozen=True, eq=False)
class _Candidates:
    slot: np.ndarray  # int64 pair slot
    n: np.ndarray  # int64 sample (threshold) / envelope index (envelope)
    values: np.ndarray  # [k] s[n] (threshold) or [k, 3] E[m − span], E[m], E[m + span]


def _ref_threshold_candidates(model: SignalModel, s: np.ndarray, first_only: bool):
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


def _refine(m: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
            span: int) -> tuple[np.ndarray, np.ndarray]:
    """Peak position and value from E at m − span, m, m + span: the vertex of the parabola
    through ln E (exact for a Gaussian peak), or of E itself where a value is 0."""
    with np.errstate(divide="ignore", invalid="ignore"):
        la, lb, lc = np.log(a), np.log(b), np.log(c)
        use_log = (a > 0) & (b > 0) & (c > 0)
        fa = np.where(use_log, la, a)
        fb = np.where(use_log, lb, b)
        fc = np.where(use_log, lc, c)
        den = fa - 2.0 * fb + fc
        ok = den < 0
        d = np.where(ok, 0.5 * (fa - fc) / np.where(ok, den, -1.0), 0.0)
        d = np.clip(d, -1.0, 1.0)
        top = fb - 0.25 * (fa - fc) * d
        value = np.where(use_log, np.exp(top), top)
    return m + span * d, np.where(ok, value, b)


def _finish_threshold(model: SignalModel, pe: _PairEchoes, cand: _Candidates) -> Detections:
    """First crossing (T = R) or crossings with hold-off (T ≠ R), per pair."""
    order = np.lexsort((cand.n, cand.slot))
    slot, n, v = cand.slot[order], cand.n[order], np.asarray(cand.values)[order]
    if len(slot) == 0:
        return _empty_detections()
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


def _finish_envelope(model: SignalModel, pe: _PairEchoes, cand: _Candidates,
                     thresholds: np.ndarray) -> Detections:
    """Threshold, non-maximum suppression within one pulse length, peak refinement."""
    vals = np.asarray(cand.values, dtype=np.float64).reshape(-1, 3)
    keep = vals[:, 1] >= thresholds[cand.slot] if len(vals) else np.zeros(0, bool)
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
    pos, amp = _refine(m.astype(np.float64), vals[:, 0], vals[:, 1], vals[:, 2], model.span)
    tof = (pos - model.delay) / model.fs
    ok = tof >= 0
    slot, tof, amp = slot[ok], tof[ok], amp[ok]
    order = np.lexsort((tof, slot))
    slot, tof, amp = slot[order], tof[order], amp[order]
    return Detections(pe.pairs[slot, 0].copy(), pe.pairs[slot, 1].copy(), tof, amp)


# --------------------------------------------------------------------------- NumPy reference


def _inputs(scene: Scene, sensors: SensorArray | None, echoes: EchoTable,
            window_s: float | None, pair_list: np.ndarray | None = None):
    sensors = sensors if sensors is not None else place_sensors(scene)
    model = signal_model(scene, window_s)
    return model, _pair_echoes(model, sensors, echoes, pair_list)


def _reference_candidates(model: SignalModel, pe: _PairEchoes):
    """Candidates (and, for the envelope, histograms) of every pair, from materialised
    float64 A-scans — what the kernels compute without materialising them."""
    slots, ns, vals = [], [], []
    hist = np.zeros((len(pe.pairs), HIST_BINS), dtype=np.int64)
    for p in range(len(pe.pairs)):
        if model.mode == "threshold":
            s = _reference_signal(model, pe, p, model.n_samples)
            n, v = _ref_threshold_candidates(model, s, pe.pairs[p, 0] == pe.pairs[p, 1])
        else:
            s = _reference_signal(model, pe, p, model.n_env + model.span)
            e2 = _reference_envelope_sq(model, s)
            hist[p] = np.bincount(_hist_bins(e2[:model.n_env:HIST_STRIDE]),
                                  minlength=HIST_BINS)
            n, v = _ref_envelope_candidates(
                model, e2, max(model.min_envelope, ENVELOPE_FLOOR * model.amplitude))
        slots.append(np.full(len(n), p, dtype=np.int64))
        ns.append(n.astype(np.int64))
        vals.append(v)
    width = () if model.mode == "threshold" else (3,)
    cand = _Candidates(
        np.concatenate(slots) if slots else np.zeros(0, np.int64),
        np.concatenate(ns) if ns else np.zeros(0, np.int64),
        np.concatenate(vals) if vals else np.zeros((0, *width)))
    return cand, hist


def detect_reference(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
                     window_s: float | None = None) -> Detections:
    """The detections of every fired pair in NumPy float64, materialising each A-scan (tests,
    small scenes): the reference of :func:`detect`."""
    model, pe = _inputs(scene, sensors, echoes, window_s)
    cand, hist = _reference_candidates(model, pe)
    if model.mode == "threshold":
        return _finish_threshold(model, pe, cand)
    return _finish_envelope(model, pe, cand, envelope_thresholds(model, hist))


def a_scan(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, tx: int, rx: int, *,
           window_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(t, s)``: the A-scan of pair (tx, rx) over the window, float64 NumPy (for plots)."""
    model, pe = _inputs(scene, sensors, echoes, window_s, np.array([[tx, rx]]))
    s = _reference_signal(model, pe, 0, model.n_samples)
    return np.arange(model.n_samples) / model.fs, s


def envelope_offset(model: SignalModel) -> int:
    """Envelope index of echo time 0 in :func:`envelopes` (the delay rounded to a sample)."""
    return round(model.delay)


def _envelope_grid(model: SignalModel, rate_hz: float) -> tuple[int, int]:
    if not rate_hz > 0:
        raise ValueError("rate_hz must be > 0")
    dec = max(1, round(model.fs / rate_hz))
    n_out = (model.n_samples - 1) // dec + 1
    return dec, n_out


def envelopes_reference(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
                        rate_hz: float = 1e5, window_s: float | None = None
                        ) -> tuple[float, np.ndarray]:
    """NumPy float64 reference of :func:`envelopes`."""
    model, pe = _inputs(scene, sensors, echoes, window_s)
    dec, n_out = _envelope_grid(model, rate_hz)
    off = envelope_offset(model)
    idx = np.arange(n_out) * dec + off
    env = np.zeros((len(pe.pairs), n_out))
    for p in range(len(pe.pairs)):
        s = _reference_signal(model, pe, p, int(idx[-1]) + 1)
        env[p] = np.sqrt(_reference_envelope_sq(model, s)[idx])
    return dec / model.fs, env


# --------------------------------------------------------------------------- OpenCL


def _program(context, precision: str, box: int, span: int, demod_period: int):
    """``kernels/signals.cl`` built for ``precision`` and the filter's sizes (memoised)."""
    from .opencl import build_program, precision_defines

    defines: dict[str, object] = {
        "BOX": box, "SPAN": span, "RING": 2 * span + 1, "HIST_BINS": HIST_BINS,
        "HIST_BASE": HIST_BASE, "HIST_STRIDE": HIST_STRIDE, "DEMOD_PERIOD": demod_period,
    }
    return build_program(context, "signals.cl", {**defines, **precision_defines(precision)})


class _Runner:
    """The buffers and launches of one scene on one context."""

    def __init__(self, model: SignalModel, pe: _PairEchoes, context, precision: str,
                 chunk: int | None, work_group: int | None, skip_quiet: bool = True):
        import pyopencl as cl

        #: noise-free: chunks of samples no echo reaches are not synthesised (their signal,
        #: envelope and candidates are exactly 0; their histogram counts go to bin 0)
        self.skip_quiet = skip_quiet and model.noise_std == 0
        self.samples = {"scanned": 0, "skipped": 0}

        context_for(context, None, precision)  # checks the precision against the device
        self.cl, self.ctx, self.model, self.pe = cl, context, model, pe
        self.real = PRECISIONS[precision]
        self.queue = queue_of(context)
        self.program = _program(context, precision, model.box, model.span, model.demod_period)
        self.chunk = chunk
        self.work_group = work_group
        mf = cl.mem_flags

        def buf(a, dtype):
            a = np.ascontiguousarray(a, dtype=dtype)
            if a.size == 0:
                a = np.zeros(1, dtype=dtype)
            return cl.Buffer(context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

        self.ek = buf(pe.ek, np.int32)
        self.ef = buf(pe.ef, self.real)
        self.ea = buf(pe.ea, self.real)
        table = np.zeros((len(pe.pairs), 4), dtype=np.int32)
        if len(pe.pairs):
            table[:, :2] = pe.pairs
            table[:, 2] = pe.lo
            table[:, 3] = pe.hi
        self.table = table
        vec = cl.cltypes.double4 if precision == "float64" else cl.cltypes.float4
        kc = np.zeros(1, dtype=vec)
        kc[0] = (model.noise_std, model.sigma, model.pulse_len, model.ratio)
        self.kc = kc[0]
        self.k0, self.k1 = (np.uint32(k) for k in model.key)
        period = max(model.demod_period, 1)
        k = np.arange(period)
        phase = 2.0 * math.pi * ((model.ratio * k) % 1.0)
        self.demod = buf(np.stack([np.cos(phase), -np.sin(phase)], axis=-1), self.real)

    def chunk_for(self, mode: str) -> int:
        if self.chunk is not None:
            return max(1, int(self.chunk))
        return DEFAULT_CHUNK[("GPU" if device_kind(self.ctx.devices[0]) == "GPU" else "CPU", mode)]

    def launch(self, name: str, n_items: int, args: list) -> None:
        kernel = kernel_of(self.program, name)
        group = self.work_group or fixed_work_group(kernel, self.ctx.devices[0], WORK_GROUP)
        padded = -(-n_items // group) * group
        kernel(self.queue, (padded,), (group,), *args)

    def quiet_histogram(self, items: np.ndarray, k: int, chunk: int,
                        n_chunks: int) -> np.ndarray:
        """[k] histogram counts of the chunks left out of each slot: every HIST_STRIDE-th
        m of [0, n_env) that no launched chunk covers."""
        n_env = self.model.n_env

        def strided(m0, m1):  # multiples of HIST_STRIDE in [m0, m1)
            return -(-m1 // HIST_STRIDE) - -(-m0 // HIST_STRIDE)

        m0 = items[:, 1].astype(np.int64) * chunk
        covered = np.bincount(items[:, 0], strided(m0, np.minimum(m0 + chunk, n_env)),
                              minlength=k)
        return (strided(0, n_env) - covered).astype(np.int32)

    def chunk_items(self, slots: np.ndarray, chunk: int, n_chunks: int) -> np.ndarray:
        """[i, 2] int32 (index into ``slots``, chunk) of the chunks whose samples an echo of
        the pair can reach: an echo at sample ek covers ek … ek + ⌈6σ⌉ + 1; a chunk reads
        from its start − (SPAN + 2·(BOX − 1) + 1) to its end + SPAN."""
        m, pe = self.model, self.pe
        lo, hi = pe.lo[slots], pe.hi[slots]
        n = hi - lo
        which = np.repeat(np.arange(len(slots)), n)
        echo = np.repeat(lo - np.cumsum(np.r_[0, n[:-1]]), n) + np.arange(int(n.sum()))
        start = pe.ek[echo]
        end = start + math.ceil(m.pulse_len) + 1
        lead, tail = m.span + 2 * (m.box - 1) + 1, m.span
        c0 = np.clip((start - tail) // chunk, 0, n_chunks - 1)
        c1 = np.clip((end + lead) // chunk, 0, n_chunks - 1)
        width = c1 - c0 + 1
        rows = np.repeat(which, width)
        cols = np.repeat(c0, width) + (np.arange(int(width.sum()))
                                       - np.repeat(np.cumsum(np.r_[0, width[:-1]]), width))
        items = np.unique(np.stack([rows, cols], axis=-1), axis=0)
        return np.ascontiguousarray(items, dtype=np.int32).reshape(-1, 2)

    def pair_buffer(self, slots: np.ndarray):
        mf = self.cl.mem_flags
        t = np.ascontiguousarray(self.table[slots])
        return self.cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=t)

    def blocks(self, slots: np.ndarray, n_chunks: int, width: int):
        """Split ``slots`` so each launch has at most ITEMS_PER_LAUNCH items and
        SLOTS_PER_LAUNCH output slots of ``width`` each."""
        step = max(1, min(ITEMS_PER_LAUNCH // max(n_chunks, 1),
                          SLOTS_PER_LAUNCH // max(width, 1)))
        for i in range(0, len(slots), step):
            yield slots[i:i + step]

    def scan(self, slots: np.ndarray, capacity: int, floor: np.ndarray | None,
             histogram: bool) -> tuple[np.ndarray, _Candidates, np.ndarray | None]:
        """Candidates of pair slots ``slots``; returns (counts, candidates, histograms)."""
        cl, m = self.cl, self.model
        mode = m.mode
        chunk = self.chunk_for(mode)
        total = m.n_samples if mode == "threshold" else m.n_env
        n_chunks = -(-total // chunk)
        counts, cs, cn, cv = [], [], [], []
        hists = []
        mf = cl.mem_flags
        for block in self.blocks(slots, n_chunks, capacity):
            k = len(block)
            count = np.zeros(k, dtype=np.int32)
            count_buf = cl.Buffer(self.ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=count)
            cand_n = np.empty((k, capacity), dtype=np.int32)
            width = 1 if mode == "threshold" else 4
            cand_v = np.empty((k, capacity, width), dtype=self.real)
            n_buf = cl.Buffer(self.ctx, mf.WRITE_ONLY, cand_n.nbytes)
            v_buf = cl.Buffer(self.ctx, mf.WRITE_ONLY, cand_v.nbytes)
            common = [self.pair_buffer(block), np.int32(k), self.ek, self.ef, self.ea,
                      self.k0, self.k1, self.kc]
            hist = hist_buf = None
            n_items, items, items_buf = k * n_chunks, None, None
            if self.skip_quiet:
                items = self.chunk_items(block, chunk, n_chunks)
                n_items = len(items)
                items_buf = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                                      hostbuf=items if n_items else np.zeros((1, 2), np.int32))
            self.samples["scanned"] += n_items * chunk
            self.samples["skipped"] += (k * n_chunks - n_items) * chunk
            order = [items_buf, np.int32(n_items)]
            if mode == "threshold":
                if n_items:
                    self.launch("threshold_scan", n_items, [
                        *common, self.real(m.threshold), np.int32(m.n_samples),
                        np.int32(chunk), np.int32(n_chunks), np.int32(capacity), count_buf,
                        n_buf, v_buf, *order])
            else:
                fl = np.ascontiguousarray(floor[block], dtype=self.real)
                fl_buf = cl.Buffer(self.ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=fl)
                if histogram:
                    hist = np.zeros((k, HIST_BINS), dtype=np.int32)
                    hist_buf = cl.Buffer(self.ctx, mf.READ_WRITE | mf.COPY_HOST_PTR,
                                         hostbuf=hist)
                if n_items:
                    self.launch("envelope_scan", n_items, [
                        *common, self.real(m.calibration**2), np.int32(m.n_env),
                        np.int32(chunk), np.int32(n_chunks), fl_buf, np.int32(capacity),
                        count_buf, n_buf, v_buf, hist_buf, self.demod, *order])
            cl.enqueue_copy(self.queue, count, count_buf)
            cl.enqueue_copy(self.queue, cand_n, n_buf)
            cl.enqueue_copy(self.queue, cand_v, v_buf)
            if hist is not None:
                cl.enqueue_copy(self.queue, hist, hist_buf)
                if items is not None:  # the chunks left out: every E² there is 0 (bin 0)
                    hist[:, 0] += self.quiet_histogram(items, k, chunk, n_chunks)
                hists.append(hist)
            self.queue.finish()
            filled = np.minimum(count, capacity)
            mask = np.arange(capacity)[None, :] < filled[:, None]
            rows = np.nonzero(mask)[0]
            counts.append(count)
            cs.append(block[rows])
            cn.append(cand_n[mask].astype(np.int64))
            v = cand_v[mask].astype(np.float64)
            cv.append(v[:, 0] if mode == "threshold" else v[:, :3])
        width = () if mode == "threshold" else (3,)
        cand = _Candidates(
            np.concatenate(cs) if cs else np.zeros(0, np.int64),
            np.concatenate(cn) if cn else np.zeros(0, np.int64),
            np.concatenate(cv) if cv else np.zeros((0, *width)))
        return (np.concatenate(counts) if counts else np.zeros(0, np.int32), cand,
                np.concatenate(hists) if hists else None)


def _merge(a: _Candidates, b: _Candidates, drop: np.ndarray) -> _Candidates:
    """``a`` without the slots in ``drop``, plus ``b``."""
    keep = ~np.isin(a.slot, drop)
    return _Candidates(np.concatenate([a.slot[keep], b.slot]),
                       np.concatenate([a.n[keep], b.n]),
                       np.concatenate([np.asarray(a.values)[keep], np.asarray(b.values)]))


def _context(context, device):
    from .opencl import get_context

    return context if context is not None else get_context(device)


def scanned_slots(model: SignalModel, pe: _PairEchoes) -> np.ndarray:
    """The pair slots whose signal must be scanned: all of them when there is noise, else
    only those with an echo — a noise-free pair without one receives nothing, crosses no
    threshold and has no envelope peak, so skipping it changes no detection."""
    slots = np.arange(len(pe.pairs), dtype=np.int64)
    return slots if model.noise_std > 0 else slots[pe.hi > pe.lo]


def detect(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *, context=None,
           device: str | None = None, precision: str = "float32",
           window_s: float | None = None, chunk: int | None = None,
           work_group: int | None = None, capacity: int | None = None,
           skip_silent: bool = True, skip_quiet: bool = True,
           stats: dict | None = None) -> Detections:
    """The detections of every fired pair, computed by the kernels of ``kernels/signals.cl``.

    ``context`` or ``device`` chooses the OpenCL device (:func:`clsonar.opencl.get_context`);
    ``precision="float64"`` needs ``cl_khr_fp64``. ``window_s`` overrides t_max; ``chunk``
    (samples per work item: each restarts the envelope's running sums, so it changes the
    result by float32 rounding only), ``work_group`` and ``capacity`` (first-pass candidates
    per pair) tune the launch; the last two never change the result; nor does
    ``skip_silent``, which leaves out
    the noise-free pairs without an echo (:func:`scanned_slots`), nor does ``skip_quiet``,
    which in a noise-free scene synthesises only the chunks of samples an echo reaches (the
    rest is exactly 0). ``stats``, if given, receives ``pairs_scanned``,
    ``pairs_skipped_silent``, ``samples_scanned`` and ``samples_skipped_quiet``. Same model
    as :func:`detect_reference`.
    """
    model, pe = _inputs(scene, sensors, echoes, window_s)
    slots = scanned_slots(model, pe) if skip_silent else np.arange(len(pe.pairs))
    samples = {"scanned": 0, "skipped": 0}
    found = _empty_detections()
    if len(slots):
        run = _Runner(model, pe, _context(context, device), precision, chunk, work_group,
                      skip_quiet)
        found = _detect(model, pe, run, capacity, slots)
        samples = run.samples
    if stats is not None:
        stats.update(pairs_scanned=len(slots), pairs_skipped_silent=len(pe.pairs) - len(slots),
                     samples_scanned=samples["scanned"],
                     samples_skipped_quiet=samples["skipped"])
    return found


def _detect(model: SignalModel, pe: _PairEchoes, run: _Runner, capacity: int | None,
            slots: np.ndarray) -> Detections:
    """:func:`detect` of the pair ``slots`` once the runner is built."""
    cap = int(capacity) if capacity is not None else DEFAULT_CAPACITY[model.mode]
    cap = max(1, cap)
    if model.mode == "threshold":
        counts, cand, _ = run.scan(slots, cap, None, histogram=False)
        over = counts > cap  # per scanned slot
        if over.any():
            _, extra, _ = run.scan(slots[over], int(counts[over].max()), None,
                                   histogram=False)
            cand = _merge(cand, extra, slots[over])
        return _finish_threshold(model, pe, cand)
    floor = np.full(len(pe.pairs), max(model.min_envelope, ENVELOPE_FLOOR * model.amplitude))
    counts, cand, hist = run.scan(slots, cap, floor, histogram=True)
    thresholds = np.full(len(pe.pairs), np.inf)  # indexed by slot; unscanned slots: none
    thresholds[slots] = envelope_thresholds(model, hist)
    over = counts > cap
    if over.any():
        # the same local maxima, now only those above the final threshold (a hair lower, so
        # float32 rounding of thr² cannot drop one the host keeps)
        floor2 = thresholds * (1.0 - 1e-6)
        _, extra, _ = run.scan(slots[over], int(counts[over].max()), floor2, histogram=False)
        cand = _merge(cand, extra, slots[over])
    return _finish_envelope(model, pe, cand, thresholds)


def envelopes(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
              rate_hz: float = 1e5, context=None, device: str | None = None,
              precision: str = "float32", window_s: float | None = None,
              chunk: int | None = None) -> tuple[float, np.ndarray]:
    """``(dt, env)``: the calibrated envelope E of every fired pair (rows in the order of
    :func:`clsonar.sensors.pairs`) decimated to about ``rate_hz``, for back-projection.

    ``env[p, j]`` is E at echo time ``j·dt`` (the filter's delay and the pulse's 3σ removed, to
    the nearest sample), so an isolated echo of amplitude A arriving at τ peaks ≈ A at
    ``j ≈ τ/dt``; j covers [0, t_max]. Noise is included: the noise floor has Rayleigh
    statistics (mean ≈ 1.25·ŝ, see :func:`detect`). float32 (or float64) array [P, n].
    """
    model, pe = _inputs(scene, sensors, echoes, window_s)
    dec, n_out = _envelope_grid(model, rate_hz)
    dt = dec / model.fs
    if len(pe.pairs) == 0:
        return dt, np.zeros((0, n_out), dtype=PRECISIONS[precision])
    run = _Runner(model, pe, _context(context, device), precision, chunk, None)
    cl = run.cl
    per_item = max(1, run.chunk_for("envelope") // dec)
    n_chunks = -(-n_out // per_item)
    off = envelope_offset(model)
    out = np.empty((len(pe.pairs), n_out), dtype=run.real)
    slots = np.arange(len(pe.pairs), dtype=np.int64)
    row = 0
    for block in run.blocks(slots, n_chunks, n_out):
        k = len(block)
        buf = cl.Buffer(run.ctx, cl.mem_flags.WRITE_ONLY, k * n_out * out.itemsize)
        run.launch("envelope_samples", k * n_chunks, [
            run.pair_buffer(block), np.int32(k), run.ek, run.ef, run.ea, run.k0, run.k1,
            run.kc, run.real(model.calibration**2), np.int32(per_item), np.int32(n_chunks),
            np.int32(dec), np.int32(off), np.int32(n_out), buf, run.demod])
        cl.enqueue_copy(run.queue, out[row:row + k], buf)
        run.queue.finish()
        row += k
    return dt, out


def _kernel_a_scans(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
                    context=None, precision: str = "float32", window_s: float | None = None,
                    chunk: int = 4096, work_group: int | None = None) -> np.ndarray:
    """[P, n_samples] A-scans of every fired pair from the kernel (tests: chunking and
    work-group independence; small scenes only)."""
    model, pe = _inputs(scene, sensors, echoes, window_s)
    run = _Runner(model, pe, _context(context, None), precision, chunk, work_group)
    cl = run.cl
    n_chunks = -(-model.n_samples // chunk)
    out = np.empty((len(pe.pairs), model.n_samples), dtype=run.real)
    buf = cl.Buffer(run.ctx, cl.mem_flags.WRITE_ONLY, max(out.nbytes, 4))
    slots = np.arange(len(pe.pairs), dtype=np.int64)
    run.launch("a_scans", len(slots) * n_chunks, [
        run.pair_buffer(slots), np.int32(len(slots)), run.ek, run.ef, run.ea, run.k0,
        run.k1, run.kc, np.int32(model.n_samples), np.int32(chunk), np.int32(n_chunks), buf])
    cl.enqueue_copy(run.queue, out, buf)
    run.queue.finish()
    return out


def _kernel_philox(context, seed: int, tx: int, rx: int, block0: int, count: int,
                   precision: str = "float32", work_group: int | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Raw Philox outputs [count, 4] uint32 and normals [count, 4] from the kernel (tests)."""
    import pyopencl as cl

    real = PRECISIONS[precision]
    program = _program(context, precision, 1, 1, 0)
    queue = queue_of(context)
    raw = np.empty((count, 4), dtype=np.uint32)
    normals = np.empty((count, 4), dtype=real)
    rb = cl.Buffer(context, cl.mem_flags.WRITE_ONLY, raw.nbytes)
    nb = cl.Buffer(context, cl.mem_flags.WRITE_ONLY, normals.nbytes)
    kernel = kernel_of(program, "philox_normals")
    group = work_group or fixed_work_group(kernel, context.devices[0], WORK_GROUP)
    padded = -(-count // group) * group
    kernel(queue, (padded,), (group,), np.uint32(seed & 0xFFFFFFFF),
           np.uint32((seed >> 32) & 0xFFFFFFFF), np.uint32(tx), np.uint32(rx),
           np.uint32(block0), np.int32(count), rb, nb)
    cl.enqueue_copy(queue, raw, rb)
    cl.enqueue_copy(queue, normals, nb)
    queue.finish()
    return raw, normals.astype(np.float64)


__all__ = ["Detections", "SignalModel", "a_scan", "box_muller", "default_window_s", "detect",
           "detect_reference", "envelope_thresholds", "envelopes", "envelopes_reference",
           "noise", "philox4x32", "signal_model"]
