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

Detection (``scene.detection.mode``), both with an OpenCL path (:func:`detect`, :mod:`.host`)
and a NumPy float64 reference (:func:`detect_reference`, :mod:`.reference`) that share the
host-side finalisation (:mod:`.detection`):

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

The package: :mod:`.model` (the signal model and the envelope's calibration), :mod:`.philox`,
:mod:`.synthesis` (each pair's echoes and float64 signal), :mod:`.dsp` (demodulation,
histogram, peak refinement), :mod:`.detection`, :mod:`.reference` and :mod:`.host`.
"""

from .detection import (
    ENVELOPE_FLOOR,
    QUIET_SIGMAS,
    Detections,
    envelope_noise_scale,
    envelope_thresholds,
    noise_stays_quiet,
)
from .dsp import HIST_BASE, HIST_BINS, HIST_LOW_LOG2, HIST_STRIDE, RAYLEIGH_MEDIAN
from .host import (
    DEFAULT_CAPACITY,
    DEFAULT_CHUNK,
    ITEMS_PER_LAUNCH,
    SLOTS_PER_LAUNCH,
    WORK_GROUP,
    detect,
    envelopes,
    scanned_slots,
)
from .model import MAX_BOX, SignalModel, default_window_s, envelope_offset, signal_model
from .philox import PHILOX_M, PHILOX_ROUNDS, PHILOX_W, box_muller, noise, philox4x32
from .reference import a_scan, detect_reference, envelopes_reference

__all__ = [
    "DEFAULT_CAPACITY",
    "DEFAULT_CHUNK",
    "ENVELOPE_FLOOR",
    "HIST_BASE",
    "HIST_BINS",
    "HIST_LOW_LOG2",
    "HIST_STRIDE",
    "ITEMS_PER_LAUNCH",
    "MAX_BOX",
    "PHILOX_M",
    "PHILOX_ROUNDS",
    "PHILOX_W",
    "QUIET_SIGMAS",
    "RAYLEIGH_MEDIAN",
    "SLOTS_PER_LAUNCH",
    "WORK_GROUP",
    "Detections",
    "SignalModel",
    "a_scan",
    "box_muller",
    "default_window_s",
    "detect",
    "detect_reference",
    "envelope_noise_scale",
    "envelope_offset",
    "envelope_thresholds",
    "envelopes",
    "envelopes_reference",
    "noise",
    "noise_stays_quiet",
    "philox4x32",
    "scanned_slots",
    "signal_model",
]
