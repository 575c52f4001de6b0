"""What every zoo scene must show with the default settings: one table, per kind of scene,
of issue 14's "What must be shown" (used by tests/test_zoo.py and the zoo's report).

- every scene gives a map (profile points > 0);
- accuracy (RMS distance of the profile points to the true surfaces): noise-free ≤ 0.5 cm on
  rooms, corridors and walls, ≤ 1 cm on corners, edges, cylinders, sinusoids and thin
  posts; ≤ 2 cm on every kind with noise (σ ≤ 1.2 units);
- completeness (share of the insonified true surface with a profile point within 3 cm):
  ≥ 95 % on rooms and corridors scanned by rings (placed by hand or wall-following), ≥ 80 %
  on walls seen by arrays (linear arrays, ``random-lines``, a room's ``per-wall`` arrays);
- vertices: every corner and edge in view (on the locus of an echo, inside both beams)
  within 2 cm of the profile, out to 9 m at any viewing angle.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..defaults import ZOO_KINDS

#: The kinds of zoo scene, in the order the report lists them.
KINDS = ZOO_KINDS  # tools/defaults.py

#: How a zoo scene is scanned: the ``wall-following`` placement; rings written by hand as
#: explicit transducers, one group per pose; ``per-wall`` arrays; linear arrays written by
#: hand, one group per array; ``random-lines`` placements.
SCANS = ("wall-following", "rings", "per-wall", "arrays", "random-lines")

#: The noise levels of the zoo (``signal.noise_std``, units of the thesis' amplitude 5).
NOISES = (0.0, 0.3, 0.6, 1.2)


@dataclass(frozen=True)
class Thresholds:
    """What a zoo scene of one kind must show with the defaults (module docstring)."""

    #: RMS distance of the profile points to the true surfaces, noise-free (metres)
    accuracy_m: float
    #: the same with noise, σ ≤ 1.2 units (metres)
    accuracy_noisy_m: float = 0.02
    #: (scan, least share of the insonified surface within 3 cm of the profile)
    completeness: tuple[tuple[str, float], ...] = ()
    #: the worst corner or edge in view, to the nearest profile point or located vertex
    #: (metres); None: not scored
    vertex_m: float | None = None

    def accuracy_for(self, noise: float) -> float:
        """The accuracy a scene with ``noise`` (σ, units) must reach."""
        return self.accuracy_m if noise == 0 else self.accuracy_noisy_m

    def completeness_for(self, scan: str) -> float | None:
        """The completeness a scene scanned by ``scan`` must reach (None: not scored)."""
        return dict(self.completeness).get(scan)


_RINGS = (("wall-following", 0.95), ("rings", 0.95))
_ARRAYS = (("arrays", 0.80), ("random-lines", 0.80))

#: Issue 14's thresholds per kind of zoo scene.
THRESHOLDS: dict[str, Thresholds] = {
    "room": Thresholds(0.005, completeness=(*_RINGS, ("per-wall", 0.80)), vertex_m=0.02),
    "corridor": Thresholds(0.005, completeness=(("rings", 0.95),), vertex_m=0.02),
    "wall": Thresholds(0.005, completeness=_ARRAYS),
    "corner": Thresholds(0.01, vertex_m=0.02),
    "edge": Thresholds(0.01, vertex_m=0.02),
    "cylinder": Thresholds(0.01),
    "sinusoid": Thresholds(0.01),
    "post": Thresholds(0.01),
}

#: The criteria a case is scored on, in the report's order.
CRITERIA = ("map", "accuracy", "completeness", "vertex")


def criteria(kind: str, scan: str, has_vertices: bool) -> tuple[str, ...]:
    """The criteria a scene of ``kind`` scanned by ``scan`` is scored on (its vertex only
    when it has corners or edges; whether they are in view is known after the run)."""
    t = THRESHOLDS[kind]
    return tuple(c for c in CRITERIA if c in ("map", "accuracy")
                 or (c == "completeness" and t.completeness_for(scan) is not None)
                 or (c == "vertex" and t.vertex_m is not None and has_vertices))
