"""The occupancy grid (``mapping.mode = "occupancy"``; Moravec & Elfes 1985, "High
resolution maps from wide angle sonar", ICRA; Elfes 1987, "Sonar-based real-world mapping
and navigation", IEEE J. Robotics and Automation 3(3)): every detection updates the cells
of its joint beam region by a sonar-cone sensor model, in log-odds (Elfes' Bayesian update
with a prior of ½, so the evidence of independent readings adds up).

Sensor model, per detection (T, R, c·τ), for a cell p inside both beams (the loci's hard
beam cut, :func:`clsonar.mapping.accumulate`):

- ``| |p − T| + |p − R| − c·τ | ≤ band/2`` (the locus' band): *occupied* evidence,
  ``ln(P_OCCUPIED / (1 − P_OCCUPIED))``;
- ``|p − T| + |p − R| < c·τ − band/2`` (nearer than the echo): *empty* evidence,
  ``ln(P_EMPTY / (1 − P_EMPTY))``, from each pair's first detection only (beyond its first
  echo a pair knows nothing empty).

A cell is occupied where its log-odds is above :data:`OCCUPIED_LOG_ODDS`. The model is
flat over the cone: Elfes' angular and radial fall-off of the probabilities is left out.
The kernel ``occupancy_map`` (``kernels/accumulate.cl``,
:func:`~clsonar.mapping.occupancy_grid`) and its float64 reference
(:func:`~clsonar.mapping.occupancy_grid_reference`) read the loci rows of
:func:`prepare_occupancy`.
"""

from __future__ import annotations

import math

import numpy as np

from ..scene import MappingSettings, Scene
from ..sensors import SensorArray
from .loci import MapProblem, as_loci, prepare_loci

#: Probability that a cell in a detection's band is occupied (Elfes' P_O, flat).
P_OCCUPIED = 0.65

#: Probability that a cell nearer than the echo is occupied (Elfes' 1 − P_E, flat); as far
#: below ½ as P_OCCUPIED is above, so one reading that a cell is empty cancels one that it
#: is occupied.
P_EMPTY = 0.35

#: Occupied cells: log-odds above this (0: more likely occupied than not).
OCCUPIED_LOG_ODDS = 0.0


def log_odds(p: float) -> float:
    """ln(p / (1 − p)): the evidence a reading of probability ``p`` adds."""
    return math.log(p / (1.0 - p))


def first_echoes(loci) -> np.ndarray:
    """[n] bool: each (tx, rx) pair's earliest detection (ties: the first row)."""
    loci = as_loci(loci)
    order = np.lexsort((np.arange(len(loci)), loci.tof_s, loci.rx, loci.tx))
    pair = np.stack([loci.tx[order], loci.rx[order]], axis=1)
    new = np.ones(len(order), dtype=bool)
    new[1:] = np.any(pair[1:] != pair[:-1], axis=1)
    first = np.zeros(len(loci), dtype=bool)
    first[order[new]] = True
    return first


def prepare_occupancy(scene: Scene, sensors: SensorArray, loci,
                      settings: MappingSettings | None = None) -> MapProblem:
    """The loci rows of :func:`~clsonar.mapping.prepare_loci` with the occupied evidence
    in column 9 and the empty evidence in column 10 (0 for a pair's later echoes)."""
    pb = prepare_loci(scene, sensors, loci, settings)
    rows = pb.rows.copy()
    rows[:, 9] = log_odds(P_OCCUPIED)
    rows[:, 10] = np.where(first_echoes(loci), log_odds(P_EMPTY), 0.0)
    return MapProblem(pb.grid, rows, "unit", pb.half_band, pb.cut_sin2, pb.beam_u)
