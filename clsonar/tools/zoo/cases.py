"""The zoo's scenes: rooms, corridors and single reflectors, drawn from a seed.

Each case is a format-v1 dict with no ``detection``, ``mapping`` or ``post`` section (the
defaults run), read with :func:`clsonar.scene.scene_from_dict`. Every case draws its numbers
from its own stream ``(seed, kind, index)``, so adding cases of one kind changes no other.

- **rooms** (thesis §2.1.2, §3.6): rectangular, L, U and T outlines, 3–12 m, some with
  pillars (circles r 0.1–0.5 m) and a few with a box (a closed polyline inside the room),
  scanned by the ``wall-following`` placement, by rings written by hand (8 elements facing
  outwards on 6.5 cm, one group per pose, poses every 0.3–0.6 m along a loop 0.6–1.2 m inside
  the walls, in the order a robot logs them) or by ``per-wall`` arrays;
- **corridors** 10–30 m × 1.5–3 m (two open walls, some with a side opening) with a ring by
  hand every 0.5 m along the middle;
- **single reflectors** — a wall, a concave corner, a convex edge, a cylinder (r 0.1–2 m),
  a sinusoid, a thin post (r 1–5 cm) — seen by 1–3 linear arrays written by hand (4–300
  elements, pitch 1.5–10 cm, 1–9 m away, one group per array; walls tilted 0–30° from the
  array's line, corners seen 0–60° from a wall's normal) or by a ``random-lines`` placement.

A third of the cases carry noise (σ 0.3, 0.6 or 1.2 units), a quarter are moved tens to
thousands of metres from the origin, and cells are 0.5–2 cm (at most :data:`MAX_CELLS`).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...echoes import reference_echoes
from ...geometry import build_geometry, true_vertices
from ...scene import Scene, scene_from_dict
from ...sensors import SensorArray, place_sensors
from . import targets
from .draft import Draft, audible_floor, noise_for
from .rooms import corridor, room
from .shapes import extent_around, mover, scene_points, transform
from .thresholds import KINDS, criteria

#: Largest map of a zoo scene (cells): each runs in seconds.
MAX_CELLS = 20_000_000

#: The cell sizes drawn (metres).
CELLS = (0.005, 0.0075, 0.01, 0.015, 0.02)

#: Space kept around everything a scene names (metres).
MARGIN_M = 0.3

#: Cases of each kind in the zoo.
COUNTS = {"room": 30, "corridor": 8, "wall": 10, "corner": 8, "edge": 6, "cylinder": 6,
          "sinusoid": 5, "post": 4}


@dataclass(frozen=True, eq=False)
class ZooCase:
    """One scene of the zoo and what to score on it."""

    name: str
    kind: str  # one of thresholds.KINDS
    scan: str  # one of thresholds.SCANS
    noise: float  # signal.noise_std, units
    scene: Scene
    data: dict[str, Any] = field(repr=False)  # the scene file (format v1)
    #: what the case has beyond its kind: "pillars", "box", "opening", "offset", "oblique",
    #: "big array", ...
    tags: tuple[str, ...] = ()
    #: the criteria it is scored on (thresholds.criteria)
    criteria: tuple[str, ...] = ()

    @property
    def cells(self) -> int:
        ny, nx = self.scene.grid_shape
        return ny * nx


def case_rng(seed: int, kind: str, index: int) -> np.random.Generator:
    """The random stream of case ``index`` of ``kind`` (independent of every other case)."""
    return np.random.default_rng([seed, zlib.crc32(kind.encode()), index])


def _shift(rng: np.random.Generator, index: int) -> np.ndarray:
    """Where case ``index`` is moved: every fourth case 10–5000 m from the origin."""
    if index % 4 != 3:
        return np.zeros(2)
    r = 10.0 ** rng.uniform(1.0, math.log10(5000.0))
    a = rng.uniform(0.0, 2 * math.pi)
    return np.array([r * math.cos(a), r * math.sin(a)])


def _cell(rng: np.random.Generator, extent: list[float]) -> float:
    """A cell of :data:`CELLS`, the next larger while the map would exceed MAX_CELLS."""
    k = int(rng.integers(len(CELLS)))
    area = (extent[2] - extent[0]) * (extent[3] - extent[1])
    while k < len(CELLS) - 1 and area / CELLS[k] ** 2 > MAX_CELLS:
        k += 1
    return CELLS[k]


def finish(draft: Draft, name: str, index: int, rng: np.random.Generator) -> ZooCase:
    """The case of ``draft``: turned and moved, its extent and cell set, noise added, read
    with :func:`scene_from_dict` (a zoo scene is a valid scene file)."""
    data: dict[str, Any] = {"clsonar": 1, "name": name, "extent": [0.0, 0.0, 1.0, 1.0],
                            "surfaces": draft.surfaces, "sensors": draft.sensors}
    angle = float(rng.uniform(-180.0, 180.0)) if draft.turn else 0.0
    shift = _shift(rng, index)
    transform(data, angle, shift)
    xy = mover(angle, shift)
    points = np.concatenate([scene_points(data),
                             np.asarray([xy(p) for p in draft.extra], float).reshape(-1, 2)])
    data["extent"] = extent_around(points, MARGIN_M)
    data["cell"] = _cell(rng, data["extent"])
    noise = noise_for(draft.kind, index)
    if noise > 0:
        data["signal"] = {"noise_std": noise, "seed": 1 + index}
    tags = list(draft.tags) + (["offset"] if np.any(shift) else [])
    scene = scene_from_dict(data, f"zoo:{name}")
    has_vertices = len(true_vertices(build_geometry(scene))) > 0
    return ZooCase(name, draft.kind, draft.scan, noise, scene, data, tuple(tags),
                   criteria(draft.kind, draft.scan, has_vertices))


#: The builder of each kind: ``(rng, index) -> Draft``.
BUILDERS: dict[str, Callable[[np.random.Generator, int], Draft]] = {
    "room": room, "corridor": corridor, "wall": targets.wall, "corner": targets.corner,
    "edge": targets.edge, "cylinder": targets.cylinder, "sinusoid": targets.sinusoid,
    "post": targets.post,
}


#: Kinds whose cases are redrawn until they are audible (rooms and corridors always are).
CHECKED = ("wall", "corner", "edge", "cylinder", "sinusoid", "post")

#: Draws of a checked case before the generator gives up.
TRIES = 100


def audible(scene: Scene, noise: float) -> bool:
    """Whether at least two echoes of ``scene`` reach :func:`~.draft.audible_floor` — by the
    NumPy float64 echo engine (clsonar.echoes.reference_echoes) on up to 12 transducers of
    each group, evenly spread: a scene whose echoes all lie below the default detection's
    floor cannot give a map, so it is no fair test of the defaults."""
    sensors = place_sensors(scene, build_geometry(scene))
    keep = np.concatenate([
        idx[np.unique(np.linspace(0, len(idx) - 1, min(12, len(idx))).round().astype(int))]
        for idx in (np.flatnonzero(sensors.groups == g) for g in np.unique(sensors.groups))])
    subset = SensorArray(positions=sensors.positions[keep],
                         headings_deg=sensors.headings_deg[keep], groups=sensors.groups[keep],
                         poses=sensors.poses)
    amplitude = np.asarray(reference_echoes(scene, subset).amplitude)
    return int(np.count_nonzero(amplitude >= audible_floor(noise))) >= 2


def draw(seed: int, kind: str, index: int) -> ZooCase:
    """Case ``index`` of ``kind``: drawn from its own stream, and drawn again (the stream
    goes on) while a single reflector is not :func:`audible`."""
    rng = case_rng(seed, kind, index)
    for _ in range(TRIES):
        draft = BUILDERS[kind](rng, index)
        case = finish(draft, f"{kind}-{index:02d}-{draft.detail}", index, rng)
        if kind not in CHECKED or audible(case.scene, case.noise):
            return case
    raise RuntimeError(f"zoo: no audible draw of {kind} {index} in {TRIES}")


def zoo(seed: int = 0, kinds: tuple[str, ...] = KINDS) -> list[ZooCase]:
    """The zoo drawn from ``seed``: :data:`COUNTS` cases of each of ``kinds``, in the order
    of :data:`~clsonar.tools.zoo.thresholds.KINDS`. Deterministic for a seed."""
    return [draw(seed, kind, i) for kind in KINDS if kind in kinds
            for i in range(COUNTS[kind])]
