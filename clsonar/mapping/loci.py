"""What a map is drawn from: the detected echoes as :class:`Loci` (checked by
:func:`as_loci`, reciprocal pairs merged by :func:`merge_reciprocal`, split by viewpoint by
:func:`count_viewpoints`), and the float64 rows both implementations of the map read
(:class:`MapProblem`, from :func:`prepare_loci` and :func:`prepare_backprojection`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import get_args

import numpy as np

from .. import physics
from ..numerics import unique
from ..scene import MappingSettings, Scene
from ..scene.settings import VoteWeight
from ..sensors import SensorArray
from .grid import MapGrid, band_m, map_grid

WEIGHTS: tuple[VoteWeight, ...] = get_args(VoteWeight)

#: Reals per locus row in the kernels: (T, R), (axis T, axis R), (c·τ, weight, 0, 0).
LOCUS_COLUMNS = 12
#: Reals per back-projection pair: (T, R), (axis T, axis R).
PAIR_COLUMNS = 8


@dataclass(frozen=True, eq=False)
class Loci:
    """What the map is built from: one row per detected echo (any object with these four
    arrays, e.g. the detector's table or :class:`clsonar.echoes.EchoTable`, will do)."""

    tx: np.ndarray  # int64 indices into the SensorArray
    rx: np.ndarray  # int64
    tof_s: np.ndarray  # float64 time of flight, s
    amplitude: np.ndarray  # float64

    def __len__(self) -> int:
        return len(self.tof_s)


def as_loci(rows) -> Loci:
    """``rows`` (anything with ``tx``, ``rx``, ``tof_s``, ``amplitude``) as a checked
    :class:`Loci`: 1-D arrays of one length, integer indices, finite times and amplitudes."""
    try:
        cols = [np.asarray(getattr(rows, k)) for k in ("tx", "rx", "tof_s", "amplitude")]
    except AttributeError as e:
        raise TypeError(f"loci need tx, rx, tof_s and amplitude arrays ({e})") from None
    if any(c.ndim != 1 for c in cols) or len({len(c) for c in cols}) != 1:
        raise ValueError("loci: tx, rx, tof_s and amplitude must be 1-D arrays of one length")
    tx, rx, tof, amp = cols
    for name, c in (("tx", tx), ("rx", rx)):
        if c.size and not np.issubdtype(c.dtype, np.integer):
            raise ValueError(f"loci.{name} must hold integer sensor indices")
    tof = tof.astype(np.float64)
    amp = amp.astype(np.float64)
    if not (np.all(np.isfinite(tof)) and np.all(np.isfinite(amp))):
        raise ValueError("loci: tof_s and amplitude must be finite")
    return Loci(tx.astype(np.int64), rx.astype(np.int64), tof, amp)


def merge_reciprocal(loci: Loci, tolerance_s: float) -> Loci:
    """One locus per physical path: (T, R) and (R, T) travel the same path, so a detection
    of each whose times of flight differ by at most ``tolerance_s`` become one row with
    T < R, their mean time of flight (√2 less noise) and mean amplitude. Unmatched rows and
    T = R rows stay as they are. Rows come back sorted by (tx, rx, tof).

    A pair with at most one detection each way (nearly all of them) is merged in one
    vectorised pass; the others by :func:`merge_reciprocal_reference`, nearest first."""
    loci = as_loci(loci)
    a, b = np.minimum(loci.tx, loci.rx), np.maximum(loci.tx, loci.rx)
    key = a * (int(b.max(initial=0)) + 1) + b
    backward = loci.tx > loci.rx  # rows of (R, T); T = R rows count as forward
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    n_back = np.bincount(inverse, backward, minlength=len(counts))
    simple = ((counts - n_back) <= 1) & (n_back <= 1)
    mine = simple[inverse]
    order = np.lexsort((backward, key))  # each simple pair: its forward row, then backward
    order = order[mine[order]]
    k = key[order]
    first = np.r_[True, k[1:] != k[:-1]][:len(k)]
    alone = order[first]  # one row per simple pair: the forward, or a lone backward
    partner = np.full(len(alone), -1)
    has_two = np.flatnonzero(~first) - 1  # positions in ``order`` whose next row pairs them
    partner[np.cumsum(first)[has_two] - 1] = order[has_two + 1]
    i, j = alone[partner >= 0], partner[partner >= 0]
    close = np.abs(loci.tof_s[i] - loci.tof_s[j]) <= tolerance_s
    merged_i, merged_j = i[close], j[close]
    single = np.r_[alone[partner < 0], i[~close], j[~close]]
    rest = merge_reciprocal_reference(_subset(loci, np.flatnonzero(~mine)), tolerance_s)
    tx = np.r_[a[merged_i], a[single], rest.tx]
    rx = np.r_[b[merged_i], b[single], rest.rx]
    tof = np.r_[(loci.tof_s[merged_i] + loci.tof_s[merged_j]) / 2.0, loci.tof_s[single],
                rest.tof_s]
    amp = np.r_[(loci.amplitude[merged_i] + loci.amplitude[merged_j]) / 2.0,
                loci.amplitude[single], rest.amplitude]
    order = np.lexsort((tof, rx, tx))
    return Loci(tx[order].astype(np.int64), rx[order].astype(np.int64),
                tof[order].astype(np.float64), amp[order].astype(np.float64))


def merge_reciprocal_reference(loci: Loci, tolerance_s: float) -> Loci:
    """:func:`merge_reciprocal` row by row: each (T, R) detection, in order, takes the
    nearest unused (R, T) detection of its pair within ``tolerance_s``."""
    loci = as_loci(loci)
    groups: dict[tuple[int, int], list[int]] = {}
    for i, (t, r) in enumerate(zip(loci.tx.tolist(), loci.rx.tolist(), strict=True)):
        groups.setdefault((min(t, r), max(t, r)), []).append(i)
    tx: list[int] = []
    rx: list[int] = []
    tof: list[float] = []
    amp: list[float] = []
    for (a, b), rows in groups.items():
        if a == b:
            forward, backward = rows, []
        else:
            forward = [i for i in rows if loci.tx[i] == a]
            backward = [i for i in rows if loci.tx[i] == b]
        used = set()
        for i in forward:
            match = min((j for j in backward if j not in used),
                        key=lambda j: abs(loci.tof_s[j] - loci.tof_s[i]), default=None)
            if match is not None and abs(loci.tof_s[match] - loci.tof_s[i]) <= tolerance_s:
                used.add(match)
                both = [i, match]
            else:
                both = [i]
            tx.append(a)
            rx.append(b if a != b else a)
            tof.append(float(np.mean(loci.tof_s[both])))
            amp.append(float(np.mean(loci.amplitude[both])))
        for j in backward:
            if j not in used:
                tx.append(a)
                rx.append(b)
                tof.append(float(loci.tof_s[j]))
                amp.append(float(loci.amplitude[j]))
    order = np.lexsort((tof, rx, tx))
    return Loci(np.asarray(tx, np.int64)[order], np.asarray(rx, np.int64)[order],
                np.asarray(tof, np.float64)[order], np.asarray(amp, np.float64)[order])


def _subset(loci: Loci, keep: np.ndarray) -> Loci:
    return Loci(loci.tx[keep], loci.rx[keep], loci.tof_s[keep], loci.amplitude[keep])


def count_viewpoints(scene: Scene, sensors: SensorArray, loci,
                     draw: Callable[[Loci], np.ndarray]) -> np.ndarray:
    """How many *viewpoints* have a locus through each cell ([ny, nx] float32).

    A viewpoint is a pair group (one linear array, one ring pose). Its loci are nearly
    concentric — transducers a few centimetres apart looking at a surface metres away — so
    they agree along their whole arcs, not only at the surface; loci from two viewpoints
    cross where the surface is. ``draw`` maps one viewpoint's loci (:func:`accumulate` or
    :func:`accumulate_reference` with the scene's settings).
    """
    loci = as_loci(loci)
    groups = sensors.groups[loci.tx]
    total = np.zeros(scene.grid_shape, dtype=np.float32)
    for g in unique(groups):
        total += draw(_subset(loci, groups == g)) > 0
    return total


# --------------------------------------------------------------------------- kernel inputs


@dataclass(frozen=True, eq=False)
class MapProblem:
    """Inputs of both implementations: float64 rows relative to ``grid.origin``."""

    grid: MapGrid
    rows: np.ndarray  # [n, LOCUS_COLUMNS] loci, or [n, PAIR_COLUMNS] back-projection pairs
    weight: str
    half_band: float  # band/2 (loci)
    cut_sin2: float
    beam_u: float  # (ka/j1)²: u = beam_u·sin²θ in the beam series
    envelopes: np.ndarray | None = None  # [n, samples] (back-projection)
    inv_c_dt: float = 0.0  # 1/(c·dt) (back-projection)


def _beam_constants(scene: Scene) -> tuple[float, float]:
    cut, ka = scene.transducer.beam(scene.medium.c)
    return cut, (ka / physics.J1_FIRST_ZERO) ** 2


def _settings(scene: Scene, settings: MappingSettings | None) -> MappingSettings:
    settings = settings if settings is not None else scene.mapping
    if settings.weight not in WEIGHTS:
        raise ValueError(f"mapping weight must be one of {', '.join(WEIGHTS)}, "
                         f"not {settings.weight!r}")
    return settings


def _geometry_rows(sensors: SensorArray, tx: np.ndarray, rx: np.ndarray,
                   grid: MapGrid) -> np.ndarray:
    """[n, 8]: T and R relative to the grid's origin, then their unit axes."""
    n = len(sensors)
    for name, idx in (("tx", tx), ("rx", rx)):
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise ValueError(f"{name} holds sensor indices outside 0..{n - 1}")
    pos = np.asarray(sensors.positions, dtype=np.float64).reshape(-1, 2) - np.asarray(grid.origin)
    axes = np.asarray(sensors.axes, dtype=np.float64).reshape(-1, 2)
    return np.concatenate([pos[tx], pos[rx], axes[tx], axes[rx]], axis=1)


def prepare_loci(scene: Scene, sensors: SensorArray, loci,
                 settings: MappingSettings | None = None) -> MapProblem:
    """The :class:`MapProblem` of drawing ``loci`` on the scene's map."""
    settings = _settings(scene, settings)
    grid = map_grid(scene)
    rows = as_loci(loci)
    band = band_m(scene, settings)
    if not (math.isfinite(band) and band > 0):
        raise ValueError(f"mapping band must be > 0, not {band!r}")
    table = np.zeros((len(rows), LOCUS_COLUMNS))
    table[:, :8] = _geometry_rows(sensors, rows.tx, rows.rx, grid)
    table[:, 8] = scene.medium.c * rows.tof_s
    table[:, 9] = rows.amplitude if settings.weight == "amplitude" else 1.0
    cut, beam_u = _beam_constants(scene)
    return MapProblem(grid, table, settings.weight, 0.5 * band, cut, beam_u)


def _check_backprojection(pr: np.ndarray, env: np.ndarray, dt: float) -> None:
    """Raise ValueError unless ``pr`` [P, 2], ``env`` [P, n ≥ 2] and ``dt`` make sense."""
    if pr.ndim != 2 or pr.shape[1] != 2 or (pr.size and not np.issubdtype(pr.dtype, np.integer)):
        raise ValueError("pairs must be a [P, 2] array of integer (tx, rx) sensor indices")
    if env.ndim != 2 or env.shape[0] != len(pr):
        raise ValueError(f"envelopes must be [P, n] with P = {len(pr)} rows, one per pair")
    if len(pr) and env.shape[1] < 2:
        raise ValueError("envelopes need at least 2 samples")
    if not np.all(np.isfinite(env)):
        raise ValueError("envelopes must be finite")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, not {dt!r}")


def prepare_backprojection(scene: Scene, sensors: SensorArray, pairs, envelopes, dt: float,
                           settings: MappingSettings | None = None) -> MapProblem:
    """The :class:`MapProblem` of back-projecting ``envelopes`` [P, n] of ``pairs`` [P, 2]."""
    settings = _settings(scene, settings)
    grid = map_grid(scene)
    pr = np.asarray(pairs)
    env = np.asarray(envelopes, dtype=np.float64)
    _check_backprojection(pr, env, dt)
    rows = _geometry_rows(sensors, pr[:, 0].astype(np.int64), pr[:, 1].astype(np.int64), grid)
    cut, beam_u = _beam_constants(scene)
    return MapProblem(grid, rows, settings.weight, 0.0, cut, beam_u, env,
                      1.0 / (scene.medium.c * dt))
