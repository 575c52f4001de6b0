"""The scene: its surfaces, its sensors and their placements, and the :class:`Scene` that
holds them with its settings (clsonar.scene.settings).

Every class is a frozen dataclass, so scenes compare with ``==`` and hash (the pipeline's
cache keys on them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from .settings import (
    DetectionSettings,
    EchoModel,
    MappingSettings,
    Medium,
    PostSettings,
    Signal,
    TransducerModel,
)

#: The scene file format this program reads and writes (the ``clsonar`` key).
FORMAT_VERSION = 1

Point = tuple[float, float]

#: The way a wall-following ring goes round its room.
WallDirection = Literal["ccw", "cw"]


# --------------------------------------------------------------------------- surfaces


@dataclass(frozen=True)
class Polyline:
    """Flat walls through ``points``; ``closed`` makes it a room whose interior is free space,
    or, with ``solid``, an obstacle (a box, a pillar) whose outside is free space. ``solid``
    None is automatic: a closed polyline inside another closed one is solid
    (:func:`clsonar.outlines.solid_surfaces`)."""

    points: tuple[Point, ...]
    closed: bool = False
    solid: bool | None = None


@dataclass(frozen=True)
class Circle:
    """A cylinder (solid disc in the plane)."""

    center: Point
    radius: float


@dataclass(frozen=True)
class Sinusoid:
    """Base line ``start`` → ``end`` (JSON ``from``/``to``) displaced along its left normal by
    ``amplitude·sin(2π·s/period)``, ``s`` the distance along the base line."""

    start: Point
    end: Point
    amplitude: float
    period: float


Surface = Polyline | Circle | Sinusoid


# --------------------------------------------------------------------------- sensors


@dataclass(frozen=True)
class Transducer:
    position: Point
    heading_deg: float
    group: int = 0


@dataclass(frozen=True)
class RandomLines:
    """Linear arrays placed one after another along a line, thesis §2.1 and §3.1.

    Arrays of ``elements`` transducers start at ``start`` (random inside the extent if
    null) and run along ``direction_deg``; element spacing is uniform in ``spacing_m``,
    the separation of consecutive arrays' centres uniform in ``separation_m``; each heading
    is ``facing_deg`` plus a uniform offset in ±``heading_spread_deg``. Placement stops
    after ``length_m`` or when an element would come within ``clearance_m`` of a surface or
    leave the extent.
    """

    seed: int = 1
    start: Point | None = None
    direction_deg: float = 90.0
    length_m: float = 10.0
    elements: int = 10
    spacing_m: tuple[float, float] = (0.05, 0.11)
    separation_m: tuple[float, float] = (0.5, 1.65)
    facing_deg: float = 0.0
    heading_spread_deg: float = 90.0
    clearance_m: float = 0.05
    type: Literal["random-lines"] = "random-lines"


@dataclass(frozen=True)
class Circular:
    """A ring of ``elements`` transducers facing outwards, thesis §2.1.2 (8 at 45°, r = 6.5 cm)."""

    center: Point
    radius_m: float = 0.065
    elements: int = 8
    start_deg: float = 0.0
    type: Literal["circular"] = "circular"


@dataclass(frozen=True)
class WallFollowing:
    """The circular array moved along the walls, thesis §2.1.2.

    The ring's centre keeps ``clearance_m`` from the nearest surface and moves by
    ``step_m`` (25–150 cm in the thesis) ``ccw`` or ``cw`` until it is back at ``start``;
    each pose is a ring as in :class:`Circular` and its own pair group.
    """

    start: Point
    step_m: float = 0.5
    clearance_m: float = 0.5
    radius_m: float = 0.065
    elements: int = 8
    start_deg: float | None = None  # None: square to the walls (rings.square_to_walls)
    direction: WallDirection = "ccw"
    max_poses: int = 2000
    type: Literal["wall-following"] = "wall-following"


@dataclass(frozen=True)
class PerWall:
    """Closed-room scan of thesis §3.6 (Figs 3.21–3.22): each wall scanned independently.

    For every wall (segment) of the closed polyline ``surfaces[surface]``, in outline order,
    random linear arrays are laid as in :class:`RandomLines` along a line parallel to the
    wall, at line-of-sight distance ``distance_m + k·distance_step_m`` (k = 0, 1, … the
    wall's index in the outline) on the room's inner side, from ``margin_m`` after the wall's
    first end to ``margin_m`` before its second (``margin_m`` null: the wall's LoS distance).
    Each heading is the direction facing the wall plus a uniform offset in
    ±``heading_spread_deg``; so "the normal of the transducer array is turned by 90° after
    each wall scan" in a rectangular room. ``distance_step_m`` ≠ 0 is the variant of Fig
    3.22, where "after one scan, LoS distance is changed". Each array is its own pair group.
    """

    seed: int = 1
    surface: int = 0
    distance_m: float = 1.0
    distance_step_m: float = 0.0
    margin_m: float | None = None
    elements: int = 10
    spacing_m: tuple[float, float] = (0.05, 0.11)
    separation_m: tuple[float, float] = (0.5, 1.65)
    heading_spread_deg: float = 0.0
    clearance_m: float = 0.05
    type: Literal["per-wall"] = "per-wall"


Placement = RandomLines | Circular | WallFollowing | PerWall


@dataclass(frozen=True)
class Sensors:
    """Explicit transducers, then those of ``placement``, then those of each of
    ``placements`` (e.g. one wall-following ring per room of a floor)."""

    transducers: tuple[Transducer, ...] = ()
    placement: Placement | None = None
    placements: tuple[Placement, ...] = ()


def per_wall_surface_problem(surfaces: tuple[Surface, ...], index: int) -> str:
    """Why ``surfaces[index]`` cannot be scanned by a :class:`PerWall` placement, or ``""``."""
    if not 0 <= index < len(surfaces):
        return (f"no surfaces[{index}] (the scene has {len(surfaces)} surface"
                f"{'' if len(surfaces) == 1 else 's'}); per-wall needs a closed polyline")
    s = surfaces[index]
    if not (isinstance(s, Polyline) and s.closed):
        kind = "an open polyline" if isinstance(s, Polyline) else f"a {type(s).__name__.lower()}"
        return f"surfaces[{index}] is {kind}; per-wall needs a closed polyline (a room)"
    return ""


# --------------------------------------------------------------------------- scene


@dataclass(frozen=True)
class Scene:
    name: str
    extent: tuple[float, float, float, float]
    cell: float = 0.01
    medium: Medium = field(default_factory=Medium)
    transducer: TransducerModel = field(default_factory=TransducerModel)
    signal: Signal = field(default_factory=Signal)
    echo: EchoModel = field(default_factory=EchoModel)
    detection: DetectionSettings = field(default_factory=DetectionSettings)
    mapping: MappingSettings = field(default_factory=MappingSettings)
    post: PostSettings = field(default_factory=PostSettings)
    surfaces: tuple[Surface, ...] = ()
    sensors: Sensors = field(default_factory=Sensors)

    @property
    def grid_shape(self) -> tuple[int, int]:
        """``(ny, nx)``: cells of ``cell`` covering the extent (the last may be partial)."""
        xmin, ymin, xmax, ymax = self.extent
        ny = math.ceil((ymax - ymin) / self.cell - 1e-9)
        nx = math.ceil((xmax - xmin) / self.cell - 1e-9)
        return (ny, nx)
