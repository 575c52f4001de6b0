"""A stretch of an array's detections and the families found in it (``mapping.mode =
"reflectors"``, :mod:`.families`): the :class:`Window` of detections with their path
tolerances (:func:`window_tolerance`), and a :class:`Family`, one reflector's share of
them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..numerics import median
from .starts import MIN_CURVE

#: Path residual every detection may have (m): planes, points and corners are exact models
#: and noise-free detections are good to a few µm, but an echo distorted by an overlapping
#: one is off by 0.5–9 mm and must not join.
BASE_TOLERANCE_M = 0.0002

#: Path residual a free curve's detections may have: a circle is a curved wall's local
#: approximation (a sinusoid's crest leaves its osculating circle by about 1 mm 0.1 m
#: from the apex).
CURVE_TOLERANCE_M = 0.001

#: Path noise per unit of signal noise over the echo's amplitude, in units of the pulse's
#: c·σ, as the families' tolerances take it (a detection's tolerance is 3.5 of these).
#: Measured again in stop 34 on the zoo's walls at σn 0.3–1.2 (seeds 36–43, 20 cases,
#: 60–3,500 detections each, against the true wall's paths), the path noise is 1.8–2.4
#: times this (:data:`MEASURED_PATH_FACTOR`): the tolerance is 1.7 of its σ, and a tenth
#: of a family's noisy rows fall outside it, as ``families.NOISY_OUTSIDE_SHARE`` allows.
NOISE_PATH_FACTOR = 0.1
NOISE_SIGMAS = 3.5

#: The path noise as measured (above): where a detection must be found near a path
#: whatever its noise (whether a pair heard a patch's surface, :mod:`.patches`).
MEASURED_PATH_FACTOR = 0.21

#: Kinds of family.
KINDS = ("plane", "point", "corner", "curve")


@dataclass(frozen=True, eq=False)
class Window:
    """The detections of one stretch of a linear array (float64 rows)."""

    rows: np.ndarray  # [m] indices into the loci
    T: np.ndarray  # [m, 2]
    R: np.ndarray  # [m, 2]
    axT: np.ndarray  # [m, 2] unit axes
    axR: np.ndarray  # [m, 2]
    paths: np.ndarray  # [m] c·τ
    amplitude: np.ndarray  # [m]
    tolerance: np.ndarray  # [m] path residual allowed
    x0: np.ndarray  # [2] reference point (the stretch's middle)
    cut_sin2: float
    neighbour_m: float  # pairs whose transducers moved this far (or less) are neighbours
    curve_tolerance: float = 0.0  # least path residual a free curve's rows may have
    max_failed: int = 24  # seeds in a row that grow nothing before the search stops
    #: detections a free curve needs (:func:`_least`): :data:`~.starts.MIN_CURVE`, one
    #: fewer for the detections of scattered elements (:func:`~.reflectors._families`)
    least_curve: int = MIN_CURVE
    #: a flat mirror's echo on both axes (A0·ρ), the beam's k·a and the noise σ of a
    #: detection's amplitude (:func:`~.heard.amplitude_noise`), for the amplitude a
    #: plane's echo has (:func:`mirror_floor`); mirror 0: not checked
    mirror: float = 0.0
    ka: float = 0.0
    noise_std: float = 0.0


@dataclass(frozen=True, eq=False)
class Family:
    """One reflector: its kind (:data:`KINDS`), model parameters (curve ``(φ, d, ψ)``
    about ``x0``, point F, corner V), the window rows it explains and their reflection
    points, and the RMS path residual."""

    kind: str
    params: np.ndarray
    x0: np.ndarray
    rows: np.ndarray  # indices into the window
    q: np.ndarray  # [k, 2] reflection points
    rms: float
    window: Window
    #: how far (1/m) the surface's curvature may be from the model's (3σ; inf when the
    #: rows cannot tell: fewer than a free curve needs)
    bend: float = math.inf

    @property
    def loci(self) -> np.ndarray:
        """The loci (rows of the whole table) the family explains."""
        return self.window.rows[self.rows]


def window_tolerance(amplitude: np.ndarray, noise_std: float, c: float,
                     pulse_sigma_s: float) -> np.ndarray:
    """Path residual each detection may have: :data:`BASE_TOLERANCE_M` plus
    :data:`NOISE_SIGMAS` times its expected path noise, :data:`NOISE_PATH_FACTOR`·c·σ·
    (noise / amplitude)."""
    return _path_tolerance(NOISE_PATH_FACTOR, amplitude, noise_std, c, pulse_sigma_s)


def heard_tolerance(amplitude: np.ndarray, noise_std: float, c: float,
                    pulse_sigma_s: float) -> np.ndarray:
    """How far from a path a detection of an echo of ``amplitude`` may be: as
    :func:`window_tolerance`, with the path noise :data:`MEASURED_PATH_FACTOR` measures."""
    return _path_tolerance(MEASURED_PATH_FACTOR, amplitude, noise_std, c, pulse_sigma_s)


def _path_tolerance(factor: float, amplitude: np.ndarray, noise_std: float, c: float,
                    pulse_sigma_s: float) -> np.ndarray:
    """:data:`BASE_TOLERANCE_M` plus :data:`NOISE_SIGMAS` times the path noise
    ``factor``·c·σ·(noise / amplitude)."""
    sigma = factor * c * pulse_sigma_s * noise_std / np.maximum(amplitude, 1e-6)
    return BASE_TOLERANCE_M + NOISE_SIGMAS * sigma


def detection_noise(tolerance: np.ndarray) -> float:
    """The path noise σ of detections whose path ``tolerance`` is :func:`window_tolerance`'s
    (their median: a tolerance is :data:`BASE_TOLERANCE_M` plus :data:`NOISE_SIGMAS` of
    their noise), metres; 0 without noise."""
    return float(median(tolerance - BASE_TOLERANCE_M)) / NOISE_SIGMAS


__all__ = ["BASE_TOLERANCE_M", "CURVE_TOLERANCE_M", "KINDS", "MEASURED_PATH_FACTOR",
           "NOISE_PATH_FACTOR", "NOISE_SIGMAS", "Family", "Window", "detection_noise",
           "heard_tolerance", "window_tolerance"]
