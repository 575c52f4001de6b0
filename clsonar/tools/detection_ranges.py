"""How far each reflector kind is detected with the default settings (issue 18,
docs/physics.md): the largest distance at which a transducer facing the reflector hears
its echo above the envelope floor chosen for the scene (:mod:`clsonar.survey`: 0.01
units in an open scene, 1.0 where rings scan or transducers stand in a room), beside the
ranges the literature reports.

The echo of each kind, monostatic and on both beams' axes, is A0·ρⁿ·G (physics.py): a
plane's and a corner's do not fall with range (the receiver's time-varying gain
compensates spherical spreading), so they are heard as far as the ranging window reaches
(the Polaroid 6500's 10.7 m); a convex edge's diffraction falls as 1/sqrt(k·d)
(:func:`~clsonar.physics.edge_gain`, the uniform theory and the default, and
:func:`~clsonar.physics.edge_gain_estimate`, ``echo.edge_model`` ``"estimate"``); a
cylinder's and a post's as sqrt(r/(r + d)) (:func:`~clsonar.physics.curved_gain`).

The last column is ``detection.receiver`` ``"polaroid-6500"``
(:mod:`clsonar.signals.polaroid`) in air: the echo, with air's absorption over its path,
against the module's threshold at its time of flight 2d/c — infinite inside the blanking
(0.41 m) and past the 35 ft window, T0·c·t/g(t) in between, g the TL852's relative gain
of the TL851's step holding at t.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import physics
from ..scene import EchoModel, Medium, TransducerModel
from ..signals.polaroid import AIR_ABSORPTION_DB_PER_M, WINDOW_M, Polaroid6500, polaroid_6500
from ..survey import DEFAULT_MIN_ENVELOPE, OPEN_MIN_ENVELOPE

#: Distances searched (m); a kind still heard at the last is reported as beyond it.
DISTANCES = np.geomspace(0.1, 100.0, 4001)

#: The Polaroid 6500 ranging module's window: 6 in to 35 ft (its data sheet).
POLAROID_MAX_RANGE_M = round(WINDOW_M, 1)



@dataclass(frozen=True)
class Kind:
    """One reflector: its name, the echo amplitude over distance, what the literature
    reports."""

    name: str
    echo: Callable[[np.ndarray], np.ndarray]
    literature: str
    polaroid_note: str = ""  # after the Polaroid receiver's range


def _defaults() -> tuple[float, float, float]:
    """A0·ρ, ρ and k of the default transducer, medium and echo model."""
    t, e = TransducerModel(), EchoModel()
    c = Medium().c
    return t.amplitude * e.reflection_coefficient, e.reflection_coefficient, \
        physics.wavenumber(t.frequency_hz, c)


def kinds() -> list[Kind]:
    """The kinds of the table, each with its default echo over distance."""
    mirror, rho, k = _defaults()
    bisector = np.full(1, 0.75 * math.pi)  # a 90° box corner seen along its bisector

    def utd(d: np.ndarray) -> np.ndarray:
        # the diffraction carries no ρ of its own: the faces' ρ weights its terms
        return mirror / rho * physics.edge_gain(d, d, bisector, bisector, np.full(1, 1.5), k,
                                                1.0, rho)

    def estimate(d: np.ndarray) -> np.ndarray:
        return mirror / rho * physics.edge_gain_estimate(d, d, k,
                                                         EchoModel().edge_coefficient)

    def circle(radius: float) -> Callable[[np.ndarray], np.ndarray]:
        return lambda d: mirror * physics.curved_gain(d, d, np.full(1, 1.0 / radius),
                                                      np.ones(1))

    return [
        Kind("plane", lambda d: np.full(d.shape, mirror),
             f"{POLAROID_MAX_RANGE_M:g} m (Polaroid 6500 data sheet: 6 in to 35 ft); the "
             "thesis: to 9 m", " (its level's calibration)"),
        Kind("corner (double bounce)", lambda d: np.full(d.shape, mirror * rho),
             "the thesis: to 9 m"),
        Kind("convex edge, 90° (default model, uniform theory)", utd, "the thesis: to 3–4 m"),
        Kind("convex edge, 90° (`edge_model` estimate)", estimate, "the thesis: to 3–4 m"),
        Kind("cylinder r 1 m", circle(1.0), "–"),
        Kind("cylinder r 0.3 m", circle(0.3), "–"),
        Kind("post r 5 cm", circle(0.05), "–"),
    ]


def max_range(echo: Callable[[np.ndarray], np.ndarray], floor: float,
              absorption_db_per_m: float = 0.0) -> float:
    """The largest of :data:`DISTANCES` whose echo, after ``absorption_db_per_m`` over
    its two-way path, is at least ``floor`` (0: none; inf: the last)."""
    heard = np.flatnonzero(echo(DISTANCES) * physics.absorption_factor(
        2.0 * DISTANCES, absorption_db_per_m) >= floor)
    if len(heard) == 0:
        return 0.0
    return math.inf if heard[-1] == len(DISTANCES) - 1 else float(DISTANCES[heard[-1]])


def polaroid_range(echo: Callable[[np.ndarray], np.ndarray],
                   receiver: Polaroid6500 | None = None) -> float:
    """The largest of :data:`DISTANCES` whose echo, after air's absorption
    (:data:`AIR_ABSORPTION_DB_PER_M`) over its two-way path, reaches the Polaroid 6500
    receiver's threshold at its time of flight (``receiver`` default: the default medium's
    and wall's, :func:`~clsonar.signals.polaroid.polaroid_6500`); 0: none."""
    rx = receiver if receiver is not None else _default_receiver()
    c = Medium().c
    echo_at = echo(DISTANCES) * physics.absorption_factor(2.0 * DISTANCES,
                                                          AIR_ABSORPTION_DB_PER_M)
    heard = np.flatnonzero(echo_at >= rx.thresholds(2.0 * DISTANCES / c))
    return float(DISTANCES[heard[-1]]) if len(heard) else 0.0


def _default_receiver() -> Polaroid6500:
    """The Polaroid 6500 receiver of the default medium, transducer and echo model."""
    mirror, _, _ = _defaults()
    return polaroid_6500(Medium().c, mirror)


def _metres(r: float, short: int = 1) -> str:
    """A range for the table: ``short`` decimals below 1 m, one above."""
    if math.isinf(r):
        return f"beyond {DISTANCES[-1]:g} m (the ranging window's end)"
    return "never" if r == 0 else f"{r:.{short if r < 1 else 1}f} m"


def markdown() -> str:
    """The table: each kind's echo at 1 m and its maximum range at either floor, in an
    open scene with air's absorption, and with the Polaroid 6500 receiver in air."""
    lines = ["| reflector | echo at 1 m (units) | open scene (floor "
             f"{OPEN_MIN_ENVELOPE:g}) | room or rings (floor {DEFAULT_MIN_ENVELOPE:g}) | "
             f"open scene, absorption {AIR_ABSORPTION_DB_PER_M:g} dB/m | `detection.receiver` "
             f"polaroid-6500, absorption {AIR_ABSORPTION_DB_PER_M:g} dB/m | literature |",
             "| --- | ---: | --- | --- | --- | --- | --- |"]
    air = AIR_ABSORPTION_DB_PER_M
    for kind in kinds():
        at_1m = float(kind.echo(np.ones(1))[0])
        lines.append(f"| {kind.name} | {at_1m:.3g} | "
                     f"{_metres(max_range(kind.echo, OPEN_MIN_ENVELOPE))} | "
                     f"{_metres(max_range(kind.echo, DEFAULT_MIN_ENVELOPE))} | "
                     f"{_metres(max_range(kind.echo, OPEN_MIN_ENVELOPE, air))} | "
                     f"{_metres(polaroid_range(kind.echo), 2)}{kind.polaroid_note} | "
                     f"{kind.literature} |")
    return "\n".join(lines) + "\n"


__all__ = ["AIR_ABSORPTION_DB_PER_M", "DISTANCES", "POLAROID_MAX_RANGE_M", "Kind", "kinds",
           "markdown", "max_range", "polaroid_range"]
