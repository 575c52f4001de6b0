"""What the stability judges find, and the bounds they hold it to (:data:`BOUNDS`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

EPS32 = float(np.finfo(np.float32).eps)

#: What the property suite and ``clsonar stress`` require (docs/stability.md states them).
BOUNDS = {
    "tof_abs_s": 1e-6,  # float32 time of flight against float64
    "map_differing_fraction": 1e-3,  # pixels where the float32 map differs
    "edge_roundings": 16,  # "on an edge": within this many float32 roundings of it
    "value_rtol": 1e-5,  # float32 summation rounding allowed in a pixel's value
    "weak_echo": 0.05,  # echoes weaker than this × A0 may be in one table only
}


#: Rows of two tables paired: ``(pairs (i, j), rows of the first only, of the second only)``.
Matches = tuple[list[tuple[int, int]], list[int], list[int]]


@dataclass
class Findings:
    """Worst errors and counts of one or many cases, per property (``clsonar stress``)."""

    cases: int = 0
    nonfinite: int = 0
    echoes: int = 0
    tof_max_s: float = 0.0
    tof_worst: str = ""
    amp_max_rel: float = 0.0
    amp_worst: str = ""
    unmatched_edge: int = 0
    unmatched_weak: int = 0
    unmatched_other: int = 0
    pixels: int = 0
    differing: int = 0
    differing_off_edge: int = 0
    worst_fraction: float = 0.0
    worst_fraction_case: str = ""
    work_group_mismatches: int = 0
    failures: list[str] = field(default_factory=list)

    def merge(self, other: Findings) -> None:
        """Add ``other``'s counts to these and keep the worse of each worst case."""
        for name in ("cases", "nonfinite", "echoes", "unmatched_edge", "unmatched_weak",
                     "unmatched_other",
                     "pixels", "differing", "differing_off_edge", "work_group_mismatches"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        if other.tof_max_s > self.tof_max_s:
            self.tof_max_s, self.tof_worst = other.tof_max_s, other.tof_worst
        if other.amp_max_rel > self.amp_max_rel:
            self.amp_max_rel, self.amp_worst = other.amp_max_rel, other.amp_worst
        if other.worst_fraction > self.worst_fraction:
            self.worst_fraction = other.worst_fraction
            self.worst_fraction_case = other.worst_fraction_case
        self.failures.extend(other.failures)

    def fail(self, case: str, what: str) -> None:
        """Record a failed property of ``case``."""
        self.failures.append(f"{case}: {what}")


def finite(*arrays: object) -> bool:
    """Whether every value of every array is finite (no NaN or Inf)."""
    return all(np.all(np.isfinite(np.asarray(a, dtype=np.float64))) for a in arrays)
