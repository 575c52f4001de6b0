"""The envelope detector's signal processing, on arrays: quadrature demodulation and two
running boxes (the envelope E), the histogram of E² that estimates the noise, and the peak
refinement. Shared by the model's calibration, the NumPy reference and the host code."""

from __future__ import annotations

import math

import numpy as np

#: Histogram of E² for the noise estimate: bin 0 below 2⁻⁴⁰ (E < 1e-6), then 4 bins per octave
#: of E² (the top two mantissa bits of its float32), the last bin open above.
HIST_BINS = 256
HIST_LOW_LOG2 = -40
HIST_BASE = (127 + HIST_LOW_LOG2) << 2
#: Every this many envelope samples enter the histogram (neighbours are strongly correlated).
HIST_STRIDE = 4

#: Rayleigh median / scale: median(E) = ŝ·√(2 ln 2) for noise-only envelopes.
RAYLEIGH_MEDIAN = math.sqrt(2.0 * math.log(2.0))


def _box(x: np.ndarray, length: int) -> np.ndarray:
    """Causal running sum of ``length`` samples (zeros before the start)."""
    c = np.cumsum(x)
    out = c.copy()
    out[length:] -= c[:-length]
    return out


def envelope_sq_raw(s: np.ndarray, ratio: float, box: int) -> np.ndarray:
    """|y|² of the two-box demodulated signal (uncalibrated)."""
    n = np.arange(len(s), dtype=np.float64)
    z = s * np.exp(-2j * math.pi * ((ratio * n) % 1.0))
    y = _box(_box(z, box), box)
    return y.real**2 + y.imag**2


def hist_bins(e2: np.ndarray) -> np.ndarray:
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


def noise_scale(hist: np.ndarray) -> np.ndarray:
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


def refine(m: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
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
