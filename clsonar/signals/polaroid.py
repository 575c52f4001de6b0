"""The Polaroid 6500 ranging module's receiver as a detection option (``detection.receiver``
``"polaroid-6500"``, issue 18): its stepped time-varying gain and fixed comparator, its
blanking, its ranging window and its single-echo mode, expressed as a time-dependent
threshold on clsonar's envelope (docs/detection.md, "The Polaroid 6500 receiver").

The module is TI's TL851 (control) and TL852 (receiver). Their data sheets give:

- TL851 *Sonar ranging control* (SLSS004, 1983, rev. 1988): ranging from 6 in to 35 ft;
  16 pulses at 420 kHz/8.5 = 49.4 kHz; a synchronous 4-bit gain control output of 12
  steps whose ends after INIT are its *Gain Control Output Table*
  (:data:`STEP_ENDS_S`: 2.38, 5.12, … 38.04 ms; step 11 lasts until INIT falls); the
  internal blanking interval of the receive input, 2.38 ms (its electrical
  characteristics: the end of step 0); a receive level detector of fixed threshold
  (1.2 V); single-echo mode unless BLNK is used.
- TL852 *Sonar ranging receiver* (SLSS003): the relative receiver gain of each step, its
  *Figure 2* (:data:`RELATIVE_GAIN`, step 2 = 1, read from the figure's drawing); the
  detect level is inversely proportional to the gain; R1 sets the overall gain, "a
  nominal peak-to-peak value of 230 mV input during gain step 2 is recommended".

With clsonar's amplitudes relative to a mirror with the spreading undone (docs/physics.md),
an echo of amplitude A arriving at t has k·A/(c·t) volts at the receiver, k the
transducer's volts per unit at 1 m of path, and the comparator trips where that times the
step's gain reaches its level: A ≥ T0·c·t/g(t), T0 = V2/k with V2 the detect level of step
2. The one free number T0 (R1, in units: clsonar has no volts, and no text found gives the
transducer's source level and sensitivity) is set on the module's specification: a wall
at normal incidence (A0·ρ) at 35 ft, with air's absorption (ISO 9613-1 at 50 kHz, 20 °C,
50 % RH: :data:`AIR_ABSORPTION_DB_PER_M`) over its 70 ft path, just trips it
(:func:`polaroid_6500`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import physics

FOOT_M = 0.3048

#: The 6500's ranging window ends at 35 ft (TL851 and 6500 data sheets), metres of range.
WINDOW_M = 35.0 * FOOT_M

#: TL851 Gain Control Output Table: the ends of gain steps 0–10 after INIT, seconds, for
#: the nominal 420 kHz resonator; step 11 lasts until INIT falls.
STEP_ENDS_S = (2.38e-3, 5.12e-3, 7.87e-3, 10.61e-3, 13.35e-3, 16.09e-3, 18.84e-3, 21.58e-3,
               27.07e-3, 32.55e-3, 38.04e-3)

#: TL852 Figure 2, relative receiver gain of steps 0–11 (step 2 = 1). Read from the figure's
#: vector drawing: the plotted staircase's heights against the figure's own grid lines;
#: eight lie on a grid line, 0.25, 1.66, 8.4 and 11.2 are interpolated logarithmically
#: between the two nearest.
RELATIVE_GAIN = (0.25, 0.5, 1.0, 1.66, 3.0, 4.0, 5.0, 6.0, 7.0, 8.4, 10.0, 11.2)

#: The TL851's internal blanking interval of the receive input (its electrical
#: characteristics, 420 kHz resonator): the end of gain step 0.
BLANKING_S = STEP_ENDS_S[0]

#: Air's absorption at 50 kHz, 20 °C and 50 % relative humidity (ISO 9613-1), dB/m: the
#: air the module's level is set in (:func:`polaroid_6500`).
AIR_ABSORPTION_DB_PER_M = 1.66


@dataclass(frozen=True)
class Polaroid6500:
    """The module's receiver as clsonar sees it: echoes in units of a mirror's (spreading
    undone) against a threshold that depends on the echo's time of flight."""

    window_s: float  # no echo after this time (2·35 ft / c)
    c: float  # speed of sound, m/s: an echo at t has travelled c·t
    level_per_m: float  # T0: the threshold in units per metre of path at relative gain 1
    step_ends_s: tuple[float, ...] = STEP_ENDS_S
    gains: tuple[float, ...] = RELATIVE_GAIN

    @property
    def blanking_s(self) -> float:
        """No echo before this time: the internal blanking, the end of gain step 0."""
        return self.step_ends_s[0]

    def gain(self, t: np.ndarray) -> np.ndarray:
        """The relative gain (step 2 = 1) of the step holding at times ``t`` (s)."""
        k = np.searchsorted(np.asarray(self.step_ends_s), np.asarray(t, float), side="right")
        return np.asarray(self.gains)[k]

    def thresholds(self, t: np.ndarray) -> np.ndarray:
        """The threshold in units for echoes at times ``t`` (s): T0·c·t/g(t) — the detect
        level, inversely proportional to the step's gain (TL852), over the spreading the
        module does not undo — infinite inside the blanking and after the window."""
        t = np.asarray(t, dtype=np.float64)
        inside = (t >= self.blanking_s) & (t <= self.window_s)
        return np.where(inside, self.level_per_m * self.c * t / self.gain(t), np.inf)

    @property
    def floor(self) -> float:
        """The lowest threshold over the window: at the start of a step (it rises as t
        within each)."""
        starts = np.array([t for t in self.step_ends_s if t < self.window_s])
        return float(np.min(self.thresholds(starts)))


def polaroid_6500(c: float, wall: float) -> Polaroid6500:
    """The receiver for sound speed ``c`` (m/s) and a wall's echo ``wall`` (units, A0·ρ):
    T0 set so that the wall at 35 ft, with air's absorption over its 70 ft path, just
    reaches the threshold at the window's end (in step 11)."""
    window_s = 2.0 * WINDOW_M / c
    path = np.array(2.0 * WINDOW_M)
    far_wall = wall * float(physics.absorption_factor(path, AIR_ABSORPTION_DB_PER_M))
    level_per_m = far_wall * RELATIVE_GAIN[-1] / (2.0 * WINDOW_M)
    if not (math.isfinite(level_per_m) and level_per_m > 0):
        raise ValueError("the Polaroid 6500 receiver needs a wall echo > 0")
    return Polaroid6500(window_s, c, level_per_m)


def first_per_pair(slot: np.ndarray) -> np.ndarray:
    """Mask of the first row of each run of equal ``slot`` (rows sorted by slot, then time):
    the module's single-echo mode, where ECHO latches on the first echo of a firing."""
    return np.r_[True, slot[1:] != slot[:-1]] if len(slot) else np.zeros(0, bool)


__all__ = ["AIR_ABSORPTION_DB_PER_M", "BLANKING_S", "FOOT_M", "RELATIVE_GAIN", "STEP_ENDS_S",
           "WINDOW_M", "Polaroid6500", "first_per_pair", "polaroid_6500"]
