"""A zoo case being built (:class:`Draft`), before it is posed and read as a scene."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .thresholds import NOISES

#: An echo the default detection surely finds, noise-free: this many units (its envelope
#: threshold's floor, ``detection.min_envelope`` 1.0, and a fifth), plus 2σ with noise.
AUDIBLE_UNITS = 1.2

#: The strongest echo of the default transducer: amplitude 5 × reflection coefficient 0.9.
STRONGEST_UNITS = 4.5


def noise_for(kind: str, index: int) -> float:
    """σ of case ``index`` of ``kind``: every third case noisy, cycling 0.3, 0.6, 1.2 —
    but thin posts, whose echoes (1.2–1.6 units) noise would drown."""
    if kind == "post" or index % 3 != 2:
        return 0.0
    return NOISES[1 + (index // 3) % 3]


def audible_floor(noise: float) -> float:
    """The amplitude (units) an echo needs to count as audible with ``noise`` (σ)."""
    return AUDIBLE_UNITS + 2.0 * noise


def reach(radius: float, noise: float) -> float:
    """How far (metres from its surface) a cylinder of ``radius`` stays audible square on:
    its echo is ``sqrt(r / (r + d))`` of a flat wall's (clsonar.physics.curved_gain with
    d1 = d2 = d, κ = 1/r)."""
    ratio = STRONGEST_UNITS / audible_floor(noise)
    return radius * (ratio * ratio - 1.0)


@dataclass
class Draft:
    """A case being built, in its local frame: surfaces and sensors of format v1, the points
    its extent must also hold (ends of placement lines), and its tags."""

    kind: str
    scan: str
    detail: str
    surfaces: list[dict[str, Any]]
    sensors: dict[str, Any]
    extra: list[list[float]] = field(default_factory=list)
    tags: list[str] = field(default_factory=list)
    #: turn the whole scene by a random angle (False: keep its axes)
    turn: bool = True
