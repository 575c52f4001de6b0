"""Writing scene format v1: the full normalised form (every default spelled out), so load →
save → load gives an identical scene."""

from __future__ import annotations

import json
import os
from dataclasses import fields
from typing import Any

from ..files import write_atomic
from .model import FORMAT_VERSION, Circle, Point, Polyline, Scene, Surface


def _point(p: Point) -> list[float]:
    return [float(p[0]), float(p[1])]


def _surface_dict(s: Surface) -> dict[str, Any]:
    if isinstance(s, Polyline):
        return {"type": "polyline", "points": [_point(p) for p in s.points], "closed": s.closed,
                "solid": s.solid}
    if isinstance(s, Circle):
        return {"type": "circle", "center": _point(s.center), "radius": s.radius}
    return {"type": "sinusoid", "from": _point(s.start), "to": _point(s.end),
            "amplitude": s.amplitude, "period": s.period}


def _plain(obj: Any) -> dict[str, Any]:
    """A dataclass as a JSON-ready dict (tuples → lists), ``type`` first where present."""
    out: dict[str, Any] = {}
    if hasattr(obj, "type"):
        out["type"] = obj.type
    for f in fields(obj):
        if f.name == "type":
            continue
        v = getattr(obj, f.name)
        out[f.name] = list(v) if isinstance(v, tuple) else v
    return out


def scene_to_dict(scene: Scene) -> dict[str, Any]:
    """The full normalised JSON form of ``scene`` (every default written out)."""
    sensors: dict[str, Any] = {
        "transducers": [{"position": _point(t.position), "heading_deg": t.heading_deg,
                         "group": t.group} for t in scene.sensors.transducers],
        "placement": None if scene.sensors.placement is None else _plain(scene.sensors.placement),
        "placements": [_plain(p) for p in scene.sensors.placements],
    }
    return {
        "clsonar": FORMAT_VERSION,
        "name": scene.name,
        "extent": list(scene.extent),
        "cell": scene.cell,
        "medium": _plain(scene.medium),
        "transducer": _plain(scene.transducer),
        "signal": _plain(scene.signal),
        "echo": _plain(scene.echo),
        "detection": _plain(scene.detection),
        "mapping": _plain(scene.mapping),
        "post": _plain(scene.post),
        "surfaces": [_surface_dict(s) for s in scene.surfaces],
        "sensors": sensors,
    }


def scene_json(data: dict[str, Any]) -> str:
    """JSON text of a scene dict, indented, with lists of numbers and objects that fit on
    one line kept on one line (readable scene files)."""

    def dump(value: Any, indent: int) -> str:
        flat = json.dumps(value, allow_nan=False)
        if len(flat) + indent <= 96 or not isinstance(value, (dict, list)):
            return flat
        pad = " " * (indent + 2)
        if isinstance(value, dict):
            items = [f"{pad}{json.dumps(k)}: {dump(v, indent + 2)}" for k, v in value.items()]
            return "{\n" + ",\n".join(items) + "\n" + " " * indent + "}"
        items = [pad + dump(v, indent + 2) for v in value]
        return "[\n" + ",\n".join(items) + "\n" + " " * indent + "]"

    return dump(data, 0) + "\n"


def save_scene(scene: Scene, path: str | os.PathLike[str]) -> None:
    """Write ``scene`` as format v1 JSON (:func:`scene_json`), atomically."""
    write_atomic(path, scene_json(scene_to_dict(scene)).encode("utf-8"))
