"""Pure edits of an immutable :class:`~clsonar.scene.Scene` (no Qt).

Every edit the GUI makes is a function ``Scene → Scene`` from this module; the editor keeps
the scene before and after as one undo step (:mod:`clsonar.gui.editor`). Scenes produced
here are re-validated through :func:`clsonar.scene.scene_from_dict`, so the GUI can never
hold a scene that the file format would refuse.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Sequence
from typing import Any

from ..scene import (
    Circle,
    Circular,
    PerWall,
    Point,
    Polyline,
    RandomLines,
    Scene,
    Surface,
    Transducer,
    WallFollowing,
    scene_from_dict,
    scene_to_dict,
)

#: Scene groups whose settings the parameters panel edits, by scene attribute.
SETTING_GROUPS = ("medium", "transducer", "signal", "echo", "detection", "mapping", "post")

#: Placement classes by their ``type`` key (scene format v1, ``sensors.placement``).
PLACEMENTS = {"random-lines": RandomLines, "circular": Circular,
              "wall-following": WallFollowing, "per-wall": PerWall}


def validated(scene: Scene) -> Scene:
    """``scene`` read back through the format's validation (raises SceneError if invalid)."""
    return scene_from_dict(scene_to_dict(scene), source=scene.name)


def snap(value: float, grid: float | None) -> float:
    """``value`` rounded to a multiple of ``grid`` (None or 0: unchanged)."""
    if not grid:
        return float(value)
    return round(round(value / grid) * grid, 9)


def snap_point(p: Sequence[float], grid: float | None) -> Point:
    """A point with both coordinates snapped to ``grid``."""
    return (snap(p[0], grid), snap(p[1], grid))


def snap_surface(s: Surface, grid: float | None) -> Surface:
    """``s`` with its defining points (and a circle's radius) snapped to ``grid``."""
    if isinstance(s, Polyline):
        return dataclasses.replace(s, points=tuple(snap_point(p, grid) for p in s.points))
    if isinstance(s, Circle):
        return Circle(snap_point(s.center, grid), max(snap(s.radius, grid), grid or s.radius))
    return dataclasses.replace(s, start=snap_point(s.start, grid), end=snap_point(s.end, grid))


def add_surface(scene: Scene, surface: Surface) -> Scene:
    """``scene`` with ``surface`` appended."""
    return dataclasses.replace(scene, surfaces=(*scene.surfaces, surface))


def replace_surface(scene: Scene, index: int, surface: Surface) -> Scene:
    """``scene`` with ``surfaces[index]`` replaced."""
    s = list(scene.surfaces)
    s[index] = surface
    return dataclasses.replace(scene, surfaces=tuple(s))


def remove_surface(scene: Scene, index: int) -> Scene:
    """``scene`` without ``surfaces[index]``; a per-wall placement that scanned it is
    dropped, one that scanned a later surface follows its index."""
    s = list(scene.surfaces)
    del s[index]
    sensors = scene.sensors
    p = sensors.placement
    if isinstance(p, PerWall) and p.surface >= index:
        placement = None if p.surface == index else dataclasses.replace(p, surface=p.surface - 1)
        sensors = dataclasses.replace(sensors, placement=placement)
    return dataclasses.replace(scene, surfaces=tuple(s), sensors=sensors)


def add_transducer(scene: Scene, position: Point, heading_deg: float = 0.0,
                   group: int = 0) -> Scene:
    """``scene`` with one explicit transducer appended."""
    t = Transducer((float(position[0]), float(position[1])), float(heading_deg), group)
    sensors = dataclasses.replace(scene.sensors, transducers=(*scene.sensors.transducers, t))
    return dataclasses.replace(scene, sensors=sensors)


def replace_transducer(scene: Scene, index: int, position: Point, heading_deg: float,
                       group: int | None = None) -> Scene:
    """``scene`` with explicit transducer ``index`` moved/turned (its group kept unless
    given)."""
    ts = list(scene.sensors.transducers)
    ts[index] = Transducer((float(position[0]), float(position[1])),
                           float(heading_deg) % 360.0,
                           ts[index].group if group is None else int(group))
    return dataclasses.replace(scene, sensors=dataclasses.replace(scene.sensors,
                                                                  transducers=tuple(ts)))


def remove_transducer(scene: Scene, index: int) -> Scene:
    """``scene`` without explicit transducer ``index``."""
    ts = list(scene.sensors.transducers)
    del ts[index]
    return dataclasses.replace(scene, sensors=dataclasses.replace(scene.sensors,
                                                                  transducers=tuple(ts)))


def heading_to(a: Sequence[float], b: Sequence[float]) -> float:
    """Heading in degrees [0, 360) of the direction from ``a`` to ``b``."""
    return math.degrees(math.atan2(b[1] - a[1], b[0] - a[0])) % 360.0


def set_placement(scene: Scene, kind: str | None, **values: Any) -> Scene:
    """``scene`` with placement ``kind`` (None: no placement) built from ``values``; keys a
    placement of the same kind already had are kept unless given."""
    if kind is None:
        placement = None
    else:
        cls = PLACEMENTS[kind]
        old = scene.sensors.placement
        base: dict[str, Any] = {}
        if old is not None and isinstance(old, cls):
            base = {f.name: getattr(old, f.name) for f in dataclasses.fields(old)}
        base.update(values)
        base.pop("type", None)
        placement = cls(**base)
    return dataclasses.replace(scene, sensors=dataclasses.replace(scene.sensors,
                                                                  placement=placement))


def place_ring(scene: Scene, center: Point) -> Scene:
    """``scene`` with a ring placed at ``center``: the wall-following ring starts there if
    the scene has one, else a fixed ``circular`` ring stands there (thesis §2.1.2)."""
    center = (float(center[0]), float(center[1]))
    if isinstance(scene.sensors.placement, WallFollowing):
        return set_placement(scene, "wall-following", start=center)
    return set_placement(scene, "circular", center=center)


def set_setting(scene: Scene, group: str, key: str, value: Any) -> Scene:
    """``scene`` with ``scene.<group>.<key> = value`` (``group`` "scene": ``name``/``cell``)."""
    if group == "scene":
        return dataclasses.replace(scene, **{key: value})
    return dataclasses.replace(scene, **{group: dataclasses.replace(getattr(scene, group),
                                                                    **{key: value})})


def choices(cls: type, name: str) -> tuple[Any, ...] | None:
    """The allowed values of a ``Literal`` field of dataclass ``cls`` (None if not one);
    an optional one (``Fit | None``: chosen from the scene when None) also allows None."""
    hint = typing.get_type_hints(cls)[name]
    if typing.get_origin(hint) is typing.Literal:
        return typing.get_args(hint)
    args = typing.get_args(hint)
    literals = [a for a in args if typing.get_origin(a) is typing.Literal]
    if literals and type(None) in args:
        return (*typing.get_args(literals[0]), None)
    return None


def optional(cls: type, name: str) -> bool:
    """Whether field ``name`` of dataclass ``cls`` may be None ("auto": chosen from the
    scene, or a default the library picks)."""
    return type(None) in typing.get_args(typing.get_type_hints(cls)[name])


def surface_label(s: Surface) -> str:
    """A short description of a surface for menus and undo texts."""
    if isinstance(s, Polyline):
        return f"{'room' if s.closed else 'wall'} ({len(s.points)} points)"
    if isinstance(s, Circle):
        return f"circle r={s.radius:g} m"
    return "sinusoid"


def changed_groups(a: Scene, b: Scene) -> set[str]:
    """The top-level scene fields (``surfaces``, ``post``, …) in which ``a`` and ``b``
    differ; ``{"post"}`` alone means a finished run needs only post-processing again."""
    return {f.name for f in dataclasses.fields(Scene) if getattr(a, f.name) != getattr(b, f.name)}


def default_placement(scene: Scene, kind: str) -> dict[str, Any]:
    """Required keys of a new placement of ``kind``: rings start at the extent's centre,
    per-wall scans the first closed polyline."""
    xmin, ymin, xmax, ymax = scene.extent
    centre = (0.5 * (xmin + xmax), 0.5 * (ymin + ymax))
    if kind == "circular":
        return {"center": centre}
    if kind == "wall-following":
        return {"start": centre}
    if kind == "per-wall":
        rooms = [i for i, s in enumerate(scene.surfaces) if isinstance(s, Polyline) and s.closed]
        return {"surface": rooms[0] if rooms else 0}
    return {}
