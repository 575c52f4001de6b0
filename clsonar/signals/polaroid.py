"""The Polaroid 6500 ranging module's receiver as a detection option (``detection.receiver``
``"polaroid-6500"``, issue 18): its stepped time-varying gain and fixed comparator, its
blanking, its ranging window and its single-echo mode, expressed as a time-dependent
threshold on clsonar's envelope (docs/detection.md, "The Polaroid 6500 receiver").

What the data sheets give (their text; the sources are listed in docs/detection.md):

- TI TL851 *Sonar ranging control* (SLSS004, 1983, rev. 1988), the module's controller:
  ranging from 6 in to 35 ft; a 420 kHz resonator; a burst of 16 pulses at 420/8.5 =
  49.4 kHz; a *synchronous 4-bit gain control output* GCA–GCD (at most 16 gain states);
  an *internal 1.2-V level detector* (a fixed comparator); internal blanking of the
  receive input after INIT ("3.8 ms", but also "objects closer than 1.3 feet", which is
  2.3 ms of round trip).
- TI TL852 *Sonar ranging receiver* (SLSS003): the digitally controlled variable-gain
  amplifier; its overall gain set by one resistor R1, "a nominal peak-to-peak value of
  230 mV input during gain step 2 is recommended", not below 50 mV; "a plot showing
  relative gain for the various gain steps versus time can be seen in Figure 2" — a plot
  only: no text gives the step times or the gain of each step.
- Polaroid 6500 Series Sonar Ranging Module data sheet, and *The Mechatronics Handbook*
  (2002), p. 19-92, after Polaroid (1990): 6 in to 35 ft, 16 cycles at 49.4 kHz, 2.38 ms
  blanking (0.41 m: the TL851's 1.3 ft), "returning echoes that exceed a fixed-threshold
  value are recorded", single-echo mode (ECHO latches on the first echo) unless the
  blanking input BLNK is toggled after each echo (multiple-echo mode).

What no text found gives, and the model chosen for it (an assumption, stated as such in
docs/detection.md):

- **The gain steps.** The TL851 counts through at most 16 states; the 6500 data sheet
  promises a wall to 35 ft, which is what the gain is for. The model: the 15 states after
  the blanking start at times spaced evenly in log time from the blanking's end to the
  window's end (:func:`gain_steps`, 1.9 dB a step at 343 m/s), and each holds the gain
  that undoes spreading exactly at its start — clsonar's own ideal gain, sampled and held.
  An echo at time t in the state that began at t_k thus reaches the comparator at
  A·t_k/t of clsonar's amplitude A (spreading undone): never more than the ideal gain
  gives, at most 1.9 dB less.
- **The level.** The 230 mV recommendation fixes R1 in volts at the transducer; clsonar's
  amplitudes are relative to a mirror, and turning volts into them needs the transducer's
  source level and receive sensitivity, which no text found gives. The one free level is
  therefore set on the module's own specification: a wall at normal incidence (clsonar's
  A0·ρ) at the window's end, 35 ft, in air (ISO 9613-1 at 50 kHz, 20 °C, 50 % RH:
  :data:`AIR_ABSORPTION_DB_PER_M`) just reaches the comparator (:func:`polaroid_6500`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import physics

FOOT_M = 0.3048

#: The 6500's ranging window ends at 35 ft (TL851 and 6500 data sheets), metres of range.
WINDOW_M = 35.0 * FOOT_M

#: The 6500's internal blanking after INIT (6500 data sheet), seconds.
BLANKING_S = 2.38e-3

#: The TL851's gain counter is 4 bits (GCA–GCD): at most 16 gain states.
GAIN_STATES = 16

#: Air's absorption at 50 kHz, 20 °C and 50 % relative humidity (ISO 9613-1), dB/m: the
#: air the module's level is set in (:func:`polaroid_6500`).
AIR_ABSORPTION_DB_PER_M = 1.66


@dataclass(frozen=True)
class Polaroid6500:
    """The module's receiver as clsonar sees it: echoes in units of a mirror's (spreading
    undone) against a threshold that depends on the echo's time of flight."""

    blanking_s: float  # no echo before this time (internal blanking)
    window_s: float  # no echo after this time (2·35 ft / c)
    steps_s: tuple[float, ...]  # start times of the gain states after the blanking
    level: float  # comparator level, units, at a state's start (where the gain is ideal)

    def thresholds(self, t: np.ndarray) -> np.ndarray:
        """The threshold in units for echoes at times ``t`` (s): level·t/t_k, t_k the start
        of the gain state holding at t (the stepped gain is the ideal one, ∝ t, held from
        t_k), infinite before the blanking ends and after the window."""
        t = np.asarray(t, dtype=np.float64)
        steps = np.asarray(self.steps_s)
        k = np.clip(np.searchsorted(steps, t, side="right") - 1, 0, len(steps) - 1)
        inside = (t >= self.blanking_s) & (t <= self.window_s)
        return np.where(inside, self.level * t / steps[k], np.inf)

    @property
    def floor(self) -> float:
        """The lowest threshold: the level, at the start of each gain state."""
        return self.level


def gain_steps(blanking_s: float, window_s: float, states: int = GAIN_STATES
               ) -> tuple[float, ...]:
    """Start times of the ``states − 1`` gain states after the blanking (state 0 holds
    during it), evenly spaced in log time: t_k = t_b·r^(k−1), r = (t_w/t_b)^(1/(states−1)),
    so the last state ends at the window's end one ratio r after its start. (The step
    times are not in any data sheet text found: the assumption of this module.)"""
    n = states - 1
    ratio = (window_s / blanking_s) ** (1.0 / n)
    return tuple(blanking_s * ratio**k for k in range(n))


def polaroid_6500(c: float, wall: float) -> Polaroid6500:
    """The receiver for sound speed ``c`` (m/s) and a wall's echo ``wall`` (units, A0·ρ):
    the level is set so that the wall at 35 ft, with air's absorption over its 70 ft path,
    reaches the threshold at the window's end, where the last gain state has fallen
    behind the ideal gain by its full ratio r."""
    window_s = 2.0 * WINDOW_M / c
    steps = gain_steps(BLANKING_S, window_s)
    far_wall = wall * float(physics.absorption_factor(np.array(2.0 * WINDOW_M),
                                                      AIR_ABSORPTION_DB_PER_M))
    level = far_wall * steps[-1] / window_s
    if not (math.isfinite(level) and level > 0):
        raise ValueError("the Polaroid 6500 receiver needs a wall echo > 0")
    return Polaroid6500(BLANKING_S, window_s, steps, level)


def first_per_pair(slot: np.ndarray) -> np.ndarray:
    """Mask of the first row of each run of equal ``slot`` (rows sorted by slot, then time):
    the module's single-echo mode, where ECHO reports the first echo of a firing."""
    return np.r_[True, slot[1:] != slot[:-1]] if len(slot) else np.zeros(0, bool)


__all__ = ["AIR_ABSORPTION_DB_PER_M", "BLANKING_S", "FOOT_M", "GAIN_STATES", "WINDOW_M",
           "Polaroid6500", "first_per_pair", "gain_steps", "polaroid_6500"]
