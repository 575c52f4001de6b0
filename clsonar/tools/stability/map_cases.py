"""The map cases: loci (or back-projected envelopes) on small maps far from the origin, tiny,
ragged, with coincident or focused transducers, flat ellipses, pixel centres on a band's edge,
headings around ±180°, transducers outside the map, and a million loci (the package
docstring lists them)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import mapping
from ...mapping import Loci
from ...physics import DEFAULT_PULSE_SIGMA_S
from ...scene import MappingSettings, Scene
from ...sensors import SensorArray
from .echo_cases import heading_to, unit

MAP_FAMILIES = ("far", "tiny", "coincident", "flat", "focus", "knife", "headings", "outside",
                "ragged", "million", "backprojection")

#: Loci of the ``million`` map family.
MILLION = 1_000_000

Transducers = list[tuple[float, float, float]]  # (x, y, heading in degrees)


@dataclass(frozen=True, eq=False)
class MapCase:
    """A map case: scene (extent, cell, mapping settings), sensors and loci (or, for
    back-projection, pairs with envelopes sampled every ``dt``)."""

    scene: Scene
    sensors: SensorArray
    loci: Loci
    pairs: np.ndarray | None = None
    envelopes: np.ndarray | None = None
    dt: float = 0.0


@dataclass(frozen=True, eq=False)
class _Area:
    """A case's map, ``size`` metres from ``origin`` in cells of ``cell``, and the case's
    random numbers."""

    rng: np.random.Generator
    origin: np.ndarray
    size: np.ndarray
    cell: float

    @property
    def extent(self) -> tuple[float, float, float, float]:
        (x0, y0), (w, h) = self.origin, self.size
        return (float(x0), float(y0), float(x0 + w), float(y0 + h))

    def inside(self, margin: float = 0.1) -> np.ndarray:
        """A random point of the map, ``margin`` of its size from its sides."""
        return self.origin + self.rng.uniform(margin, 1 - margin, 2) * self.size

    def pixel_centre(self) -> np.ndarray:
        """The centre of a random pixel of the map."""
        w, h = self.size
        ny, nx = math.ceil(h / self.cell - 1e-9), math.ceil(w / self.cell - 1e-9)
        return self.origin + (np.array([self.rng.integers(nx), self.rng.integers(ny)])
                              + 0.5) * self.cell


def _sensor_array(transducers: Transducers) -> SensorArray:
    t = np.asarray(transducers, dtype=np.float64).reshape(-1, 3)
    return SensorArray(t[:, :2].copy(), t[:, 2].copy(), np.zeros(len(t), np.int64),
                       np.zeros((0, 2)))


def _frame(family: str, rng: np.random.Generator, million: int) -> tuple[_Area, int, int]:
    """The case's map, and its numbers of transducers and loci."""
    cell = 0.01
    size = rng.uniform(0.8, 1.6, 2)
    origin = np.zeros(2)
    n_sensors, n_loci = int(rng.integers(2, 6)), int(rng.integers(3, 40))
    if family == "far":
        origin = rng.choice([-1, 1], 2) * rng.uniform(1e3, 1e5, 2)
    elif family == "tiny":
        cell = float(rng.choice([5e-4, 2e-4]))
        size = size * cell / 0.01
    elif family == "ragged":
        cell = float(rng.uniform(0.003, 0.02))
        size = np.floor(size / cell) * cell + rng.uniform(0.01, 0.99, 2) * cell
        origin = rng.uniform(-50.0, 50.0, 2)
    elif family == "knife":
        n_loci = int(rng.integers(3, 12))
    elif family == "million":
        size = rng.uniform(0.2, 0.4, 2)
        n_loci = million
    return _Area(rng, origin, size, cell), n_sensors, n_loci


def _transducers(family: str, area: _Area, n_sensors: int) -> Transducers:
    """The case's transducers: aimed into the map (some outside it, on pixel centres, at
    ±180°, or nearly coincident with the first, as the family asks)."""
    rng = area.rng
    transducers = []
    for i in range(n_sensors):
        if family == "outside":
            p = area.origin + rng.uniform(-0.5, 1.5, 2) * area.size
        elif family == "focus" and i < 2:
            p = area.pixel_centre()
        else:
            p = area.inside()
        if family == "headings":
            heading = float(rng.choice([180.0, -180.0, 180.0 - 1e-6, -180.0 + 1e-6, 540.0]))
        else:
            heading = heading_to(p, area.inside(0.3)) + rng.normal(0.0, 15.0)
            if family == "outside" and rng.random() < 0.3:
                heading += 180.0
        transducers.append((p[0], p[1], heading))
    if family == "coincident":
        t = transducers[0]
        for gap in rng.choice([0.0, 1e-9, 1e-7, 1e-5, 1e-3], 2):
            v = gap * unit(rng.uniform(0, 2 * math.pi))
            transducers.append((t[0] + v[0], t[1] + v[1], t[2] + rng.normal(0, 1)))
    return transducers


def _loci_paths(family: str, area: _Area, transducers: Transducers, n_loci: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(tx, rx, path)`` of the case's loci: paths T → a random point → R with some noise
    (flat ellipses, or pixel centres exactly on the band's edge, as the family asks)."""
    rng = area.rng
    n = len(transducers)
    pos = np.asarray(transducers)[:, :2]
    tx = rng.integers(0, n, n_loci)
    rx = np.where(rng.random(n_loci) < 0.3, tx, rng.integers(0, n, n_loci))
    if family == "coincident":
        tx[: n_loci // 2] = 0
        rx[: n_loci // 2] = rng.integers(n - 2, n, n_loci // 2)
    q = area.origin + rng.uniform(0.0, 1.0, (n_loci, 2)) * area.size
    path = (np.linalg.norm(q - pos[tx], axis=1) + np.linalg.norm(q - pos[rx], axis=1)
            + rng.normal(0.0, 2.0, n_loci) * area.cell)
    if family == "flat":
        path = np.linalg.norm(pos[tx] - pos[rx], axis=1) + rng.uniform(0.0, 1e-6, n_loci)
    elif family == "knife":  # a pixel centre exactly on the band's edge
        q = np.array([area.pixel_centre() for _ in range(n_loci)])
        band = mapping.band_m(Scene("x", area.extent, area.cell))
        path = (np.linalg.norm(q - pos[tx], axis=1) + np.linalg.norm(q - pos[rx], axis=1)
                + rng.choice([-0.5, 0.5], n_loci) * band)
    return tx, rx, path


def map_case(family: str, seed: int, *, million: int = MILLION) -> MapCase:
    """The map case ``(family, seed)``; ``million`` loci in the ``million`` family."""
    rng = np.random.default_rng([seed, 100 + MAP_FAMILIES.index(family)])
    area, n_sensors, n_loci = _frame(family, rng, million)
    transducers = _transducers(family, area, n_sensors)
    tx, rx, path = _loci_paths(family, area, transducers, n_loci)
    weight = mapping.WEIGHTS[int(rng.choice(len(mapping.WEIGHTS)))]
    settings = MappingSettings(mode="loci", weight=weight, combine="sum")
    scene = Scene(name=f"stress-map-{family}-{seed}", extent=area.extent,
                  cell=area.cell, mapping=settings)
    c = scene.medium.c
    loci = Loci(tx.astype(np.int64), rx.astype(np.int64), np.maximum(path, 0.0) / c,
                rng.uniform(0.1, 5.0, n_loci))
    sensors = _sensor_array(transducers)
    if family != "backprojection":
        return MapCase(scene, sensors, loci)
    pr = np.unique(np.stack([tx, rx], axis=1), axis=0)
    dt = 1e-6
    w, h = area.size
    samples = int(2 * np.hypot(w + 1, h + 1) / c / dt) + 2
    return MapCase(scene, sensors, loci, pr, _envelopes(rng, len(pr), samples, dt), dt)


def _envelopes(rng: np.random.Generator, n_pairs: int, samples: int, dt: float) -> np.ndarray:
    """[n_pairs, samples] smooth envelopes: Gaussian echoes of the pulse's σ (thesis eq. 2.3)
    at random delays on a small noise floor, as the envelope detector gives them."""
    t = np.arange(samples) * dt
    env = np.full((n_pairs, samples), 0.01)
    for i in range(n_pairs):
        for delay, amp in zip(rng.uniform(0, t[-1], 3), rng.uniform(0.5, 5.0, 3), strict=True):
            env[i] += amp * np.exp(-0.5 * ((t - delay) / DEFAULT_PULSE_SIGMA_S) ** 2)
    return env
