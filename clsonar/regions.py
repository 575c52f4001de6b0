"""Closed rooms mapped one by one: the regions of a scene (issue "Fast": skip what a scene
does not need, bounded memory at scale).

Sound does not pass a wall: a transducer inside a closed polyline (a room, thesis §3.6)
hears only that room's walls and what stands inside it, and no pair of transducers in two
different rooms has an echo. When every placement and explicit transducer of a scene lies
in one of several closed rooms (none inside another; a closed polyline read as a solid
obstacle, :func:`clsonar.outlines.solid_surfaces`, is not a room but a surface of the room
around it), :func:`split_rooms` cuts the scene
into one sub-scene per room — its outline, the surfaces inside it, its transducers, and an
extent of the room's bounding box plus :data:`MARGIN_M`, on the floor's own cell grid — and
the pipeline runs each one on its own (:func:`clsonar.pipeline.run`): the pairs across
rooms, the walls of other rooms and the cells outside every room are never looked at, and
host memory holds one room's stages at a time in each worker process (:mod:`clsonar.rooms`,
one per core) plus the floor's mosaic. :func:`combine_metrics`
pools the rooms' metrics.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .outlines import holding, inside_polygon, outline_boxes, sensor_anchors, solid_surfaces
from .scene import (
    Circle,
    Circular,
    PerWall,
    Polyline,
    RandomLines,
    Scene,
    Sensors,
    Sinusoid,
    WallFollowing,
)

#: Free border around each room's bounding box in its sub-scene, metres.
MARGIN_M = 0.2


@dataclass(frozen=True)
class Region:
    """One room of a scene: its sub-scene and where its grid sits in the scene's grid."""

    scene: Scene
    row0: int
    col0: int


def _inside(poly: np.ndarray, p: np.ndarray) -> np.ndarray:
    return inside_polygon(poly, np.asarray(p, dtype=np.float64).reshape(-1, 2))


def _anchor(item) -> tuple[float, float] | None:
    """A point that says which room a placement or surface is in (None: cannot say)."""
    if isinstance(item, WallFollowing | RandomLines) and item.start is not None:
        return item.start
    if isinstance(item, Circular):
        return item.center
    if isinstance(item, Circle):
        return item.center
    if isinstance(item, Sinusoid):
        return item.start
    if isinstance(item, Polyline) and item.closed:  # an obstacle: its vertices' mean
        x, y = np.mean(np.asarray(item.points, dtype=np.float64), axis=0)
        return (float(x), float(y))
    if isinstance(item, Polyline):
        return item.points[0]
    return None


def split_rooms(scene: Scene) -> list[Region] | None:
    """The rooms of ``scene`` as :class:`Region`s, or None when the scene is not several
    separate closed rooms, each holding all of the transducers it maps (then it is mapped
    whole)."""
    solid = solid_surfaces(scene.surfaces, sensor_anchors(scene))  # obstacles, not rooms
    rooms = [s for i, s in enumerate(scene.surfaces)
             if isinstance(s, Polyline) and s.closed and not solid[i]]
    placements = [p for p in (scene.sensors.placement, *scene.sensors.placements)
                  if p is not None]
    if len(rooms) < 2 or any(isinstance(p, PerWall) for p in placements):
        return None
    boxes = outline_boxes(polys := [np.asarray(r.points, dtype=np.float64) for r in rooms])
    if any(i != j and _inside(polys[j], a[:1])[0]  # a room inside another
           for i, a in enumerate(polys) for j in holding(boxes, a[0])):
        return None

    def room_of(point) -> int | None:
        hits = [int(i) for i in holding(boxes, point) if _inside(polys[i], point)[0]]
        return hits[0] if len(hits) == 1 else None

    surfaces: list[list] = [[r] for r in rooms]
    for i, s in enumerate(scene.surfaces):
        if isinstance(s, Polyline) and s.closed and not solid[i]:
            continue
        home = room_of(_anchor(s))
        if home is None:
            return None
        surfaces[home].append(s)
    own: list[list] = [[] for _ in rooms]
    for p in placements:
        home = None if _anchor(p) is None else room_of(_anchor(p))
        if home is None:
            return None
        own[home].append(p)
    explicit: list[list] = [[] for _ in rooms]
    for t in scene.sensors.transducers:
        home = room_of(t.position)
        if home is None:
            return None
        explicit[home].append(t)
    xmin, ymin = scene.extent[:2]
    cell = scene.cell
    ny, nx = scene.grid_shape
    regions = []
    for i, poly in enumerate(polys):
        if not own[i] and not explicit[i]:
            continue  # a room nobody maps: nothing to compute
        lo = poly.min(axis=0) - MARGIN_M
        hi = poly.max(axis=0) + MARGIN_M
        col0 = max(0, math.floor((lo[0] - xmin) / cell))
        row0 = max(0, math.floor((lo[1] - ymin) / cell))
        col1 = min(nx, math.ceil((hi[0] - xmin) / cell))
        row1 = min(ny, math.ceil((hi[1] - ymin) / cell))
        extent = (xmin + col0 * cell, ymin + row0 * cell, xmin + col1 * cell,
                  ymin + row1 * cell)
        sub = dataclasses.replace(
            scene, name=f"{scene.name}[{i}]", extent=extent, surfaces=tuple(surfaces[i]),
            sensors=Sensors(tuple(explicit[i]), None, tuple(own[i])))
        regions.append(Region(sub, row0, col0))
    return regions


def _weighted(parts: list[dict], key, weight) -> float | None:
    pairs = [(key(m), weight(m)) for m in parts if key(m) is not None and weight(m)]
    total = sum(w for _, w in pairs)
    return None if not total else sum(v * w for v, w in pairs) / total


def combine_metrics(parts: list[dict]) -> dict[str, object]:
    """The metrics of a scene mapped room by room, pooled from each room's
    (:func:`clsonar.metrics.evaluate`): sums of points and insonified length; accuracy RMS
    pooled over all profile points; completeness and coverage weighted by each room's
    insonified length; the spurious share by its points; the vertices and cylinders of all
    rooms. ``accuracy_m.p95`` is the largest of the rooms' (an upper bound)."""
    points = sum(int(m["points"]) for m in parts)
    lit = sum(float(m["insonified_m"]) for m in parts)
    rms = _weighted(parts, lambda m: None if m["accuracy_m"]["rms"] is None
                    else m["accuracy_m"]["rms"] ** 2, lambda m: m["points"])
    p95 = [m["accuracy_m"]["p95"] for m in parts if m["accuracy_m"]["p95"] is not None]
    total_m = sum(float(m["insonified_m"]) / m["coverage"] for m in parts if m["coverage"])
    out: dict[str, object] = {
        "points": points, "rms_m": None, "insonified_m": lit,
        "coverage": lit / total_m if total_m else None,
        "accuracy_m": {"rms": None if rms is None else math.sqrt(rms),
                       "p95": max(p95) if p95 else None},
        "spurious_share": _weighted(parts, lambda m: m["spurious_share"],
                                    lambda m: m["points"]),
        "completeness": {r: _weighted(parts, lambda m, r=r: m["completeness"][r],
                                      lambda m: m["insonified_m"])
                         for r in parts[0]["completeness"]} if parts else {},
    }
    corners = [v for m in parts for v in m.get("vertices", [])]
    if corners:
        errors = [v["error_m"] for v in corners]
        out["vertices"] = corners
        out["vertices_found"] = f"{sum(v['found'] for v in corners)}/{len(corners)}"
        out["vertex_error_max_m"] = None if None in errors else max(errors)
    cylinders = [c for m in parts for c in m.get("cylinders", [])]
    if cylinders:
        out["cylinders"] = cylinders
    out["rooms"] = len(parts)
    return out


__all__ = ["MARGIN_M", "Region", "combine_metrics", "split_rooms"]
