"""The signal model of a scene (thesis eq. 2.3, §2.1.1 part 2): sampling, window, pulse, the
envelope filter's sizes and calibration — everything both detectors need, in samples."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache

import numpy as np

from .. import physics
from ..scene import DetectionMode, Scene
from ..scene.settings import chosen
from .dsp import envelope_sq_raw, refine
from .philox import philox_key
from .polaroid import Polaroid6500, polaroid_6500

#: Longest box of the envelope filter, samples (private rings in the kernel).
MAX_BOX = 4096


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
    mode: DetectionMode
    holdoff: int  # one pulse length in whole samples, ceil(6σ)
    box: int  # samples of each of the two envelope boxes
    span: int  # half-span of the peak interpolation, samples
    calibration: float  # E = calibration·|y|
    peak_bias: float  # the peak interpolation's systematic offset, samples (_calibration)
    n_env: int  # envelope peaks are searched at m in [1, n_env)
    false_alarm_sigmas: float
    min_envelope: float
    demod_period: int  # samples per carrier period if whole (table-free exact phase), else 0
    receiver: Polaroid6500 | None = None  # detection.receiver "polaroid-6500"; None: ideal

    @property
    def key(self) -> tuple[int, int]:
        """Philox key (low, high 32 bits of the seed)."""
        return philox_key(self.seed)

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
        false_alarm_sigmas=float(d.false_alarm_sigmas),
        min_envelope=float(chosen(d.min_envelope, "detection.min_envelope")),
        demod_period=_demod_period(ratio), receiver=_receiver(scene))
    return _with_calibration(model)


def _receiver(scene: Scene) -> Polaroid6500 | None:
    """The module of ``detection.receiver`` (None: the ideal receiver), its level set on a
    wall of the scene's transducer and reflection coefficient (clsonar.signals.polaroid)."""
    if scene.detection.receiver == "ideal":
        return None
    if scene.detection.mode != "envelope":
        raise ValueError(f'detection.receiver "{scene.detection.receiver}" needs '
                         'detection.mode "envelope"')
    wall = scene.transducer.amplitude * scene.echo.reflection_coefficient
    return polaroid_6500(scene.medium.c, wall)


def _with_calibration(m: SignalModel) -> SignalModel:
    """``m`` with the envelope detector's calibration (:func:`_calibration`)."""
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
        s = physics.pulse_shape(n - tau, sigma, ratio, k_norm)  # unit pulse, in samples
        e = np.sqrt(envelope_sq_raw(s, ratio, box))
        m = int(np.argmax(e))
        pos, amp = refine(np.array([m], float), e[[m - span]], e[[m]], e[[m + span]], span)
        peaks.append(float(amp[0]))
        offsets.append(float(pos[0]) - tau - (box - 1) - 3.0 * sigma)
    return 1.0 / float(np.mean(peaks)), float(np.mean(offsets))


def envelope_offset(model: SignalModel) -> int:
    """Envelope index of echo time 0 in :func:`~clsonar.signals.envelopes` (the delay rounded
    to a sample)."""
    return round(model.delay)


def envelope_grid(model: SignalModel, rate_hz: float) -> tuple[int, int]:
    """``(decimation, samples)`` of envelopes decimated to about ``rate_hz`` over the window."""
    if not rate_hz > 0:
        raise ValueError("rate_hz must be > 0")
    dec = max(1, round(model.fs / rate_hz))
    n_out = (model.n_samples - 1) // dec + 1
    return dec, n_out
