"""The zoo's rooms and corridors (thesis §2.1.2, §3.6; issue 14: rings placed by hand or by
a robot's path, ``wall-following``, ``per-wall``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...geometry import segment_distance
from ...outlines import inside_polygon
from .draft import Draft
from .shapes import inset, l_shape, rect, ring_transducers, t_shape, u_shape
from .shapes import walk as walk_loop

#: Outlines of the zoo's rooms, cycled case by case.
ROOM_SHAPES = ("rect", "L", "U", "T")

#: Room cases from this index on have a ``slanted`` outline (:func:`slanted`), their scans
#: cycled case by case: walls at any angle, which no one ring heading faces.
SLANTED_FROM = 24

#: Scans of the zoo's rooms, cycled every four cases (one of each outline).
ROOM_SCANS = ("wall-following", "rings", "per-wall")

#: Clearance of the ``wall-following`` placement's default (metres).
FOLLOW_M = 0.5


def outline(rng: np.random.Generator, shape: str, arm: float) -> np.ndarray:
    """A counter-clockwise room outline of ``shape`` 3–12 m across, whose every part is at
    least ``arm`` wide (so a loop ``arm``/2 − 0.3 m inside the walls stays one loop)."""
    if shape == "rect":
        return rect(rng.uniform(max(3.0, arm), 12.0), rng.uniform(max(3.0, arm), 12.0))
    if shape == "L":
        w, h = rng.uniform(max(4.0, 2 * arm + 1), 12.0, size=2)
        return l_shape(w, h, rng.uniform(1.0, w - arm), rng.uniform(1.0, h - arm))
    if shape == "U":
        w, h = rng.uniform(max(6.0, 2 * arm + 1), 12.0), rng.uniform(max(4.0, arm + 1), 12.0)
        side = rng.uniform(arm, (w - 1.0) / 2)
        return u_shape(w, h, side, rng.uniform(1.0, h - arm))
    w, h = rng.uniform(max(6.0, arm + 2), 12.0), rng.uniform(max(5.0, 2 * arm + 1.5), 12.0)
    return t_shape(w, h, rng.uniform(arm, w - 2.0), rng.uniform(arm, h - 1.5))


def slanted(rng: np.random.Generator, arm: float) -> np.ndarray:
    """A convex counter-clockwise room of 3–6 walls at random angles (a triangle, a
    trapezoid, a hexagon …) 4–12 m across: every wall at least 1.5 m long, every corner
    50–160°, and a loop ``arm``/2 inside the walls still one loop with every side."""
    while True:
        n = int(rng.integers(3, 7))
        size = rng.uniform(max(4.0, 2 * arm + 1), 12.0)
        angle = np.sort(rng.uniform(0.0, 2 * math.pi, n))
        polygon = 0.5 * size * rng.uniform(0.75, 1.0, (n, 1)) * np.stack(
            [np.cos(angle), np.sin(angle)], axis=-1)
        side = np.roll(polygon, -1, axis=0) - polygon
        before = np.roll(side, 1, axis=0)
        turn = np.degrees(np.arctan2(before[:, 0] * side[:, 1] - before[:, 1] * side[:, 0],
                                     np.einsum("ij,ij->i", before, side)))
        if np.any(turn <= 20.0) or np.any(turn >= 130.0):  # corners 50–160°, convex
            continue
        if np.hypot(*side.T).min() < 1.5:
            continue
        loop = inset(polygon, 0.5 * arm)
        kept = np.einsum("ij,ij->i", np.roll(loop, -1, axis=0) - loop, side)
        if np.all(kept > 0.2 * np.hypot(*side.T) ** 2):
            return polygon - polygon.min(axis=0)


def _spot(rng: np.random.Generator, polygon: np.ndarray, keep: float,
          taken: list[tuple[np.ndarray, float]], r: float) -> np.ndarray | None:
    """A random point inside ``polygon``, ``keep`` + r from its walls and clear of the
    obstacles ``taken`` (centre, radius); None after 200 tries."""
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    for _ in range(200):
        p = rng.uniform(lo, hi)
        if not inside_polygon(polygon, p[None])[0]:
            continue
        if segment_distance(p, polygon)[0] < keep + r:
            continue
        if all(np.hypot(*(p - c)) > r + q + 0.6 for c, q in taken):
            return p
    return None


def _nearest_obstacle(p: np.ndarray, extra: list[dict[str, Any]]) -> float:
    """The distance from ``p`` to the nearest of the obstacles ``extra`` (inf if none)."""
    out = math.inf
    for s in extra:
        if s["type"] == "circle":
            out = min(out, float(np.hypot(*(p - np.asarray(s["center"])))) - s["radius"])
        else:
            out = min(out, float(segment_distance(p, np.asarray(s["points"]))[0]))
    return out


def _follow_start(rng: np.random.Generator, polygon: np.ndarray,
                  extra: list[dict[str, Any]]) -> np.ndarray:
    """A ``wall-following`` start for a scan of the room's walls: a random point inside
    ``polygon`` 0.6–1.2 m from its walls and nearer them than any obstacle (a start nearer
    a pillar would follow the pillar, as the placement is documented to)."""
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    while True:
        p = rng.uniform(lo, hi)
        d = float(segment_distance(p, polygon)[0])
        if (inside_polygon(polygon, p[None])[0] and 0.6 <= d <= 1.2
                and _nearest_obstacle(p, extra) > d + 0.1):
            return p


def obstacles(rng: np.random.Generator, polygon: np.ndarray, keep: float, pillars: int,
              box: bool) -> tuple[list[dict[str, Any]], list[str]]:
    """Up to ``pillars`` circles (r 0.1–0.5 m) and, with ``box``, one closed rectangle
    (0.4–1.2 m, turned), each ``keep`` + 0.5 m clear of the walls; and their tags."""
    taken: list[tuple[np.ndarray, float]] = []
    out: list[dict[str, Any]] = []
    for _ in range(pillars):
        r = float(rng.uniform(0.1, 0.5))
        c = _spot(rng, polygon, keep + 0.5, taken, r)
        if c is not None:
            taken.append((c, r))
            out.append({"type": "circle", "center": [float(c[0]), float(c[1])], "radius": r})
    tags = ["pillars"] if out else []
    if box:
        w, h = rng.uniform(0.4, 1.2, size=2)
        c = _spot(rng, polygon, keep + 0.5, taken, float(np.hypot(w, h)) / 2)
        if c is not None:
            a = rng.uniform(0, np.pi)
            u, v = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])
            corners = [c + sx * w / 2 * u + sy * h / 2 * v
                       for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            out.append({"type": "polyline", "closed": True,
                        "points": [[float(x), float(y)] for x, y in corners]})
            tags.append("box")
    return out, tags


def rings_along(loop: np.ndarray, step: float, start: float, reverse: bool
                ) -> list[dict[str, Any]]:
    """Rings written by hand every ``step`` along ``loop`` from arc length ``start`` (in
    the order a robot logs its poses), each facing its direction of travel, one group per
    pose."""
    path = loop[::-1] if reverse else loop
    poses, heading = walk_loop(path, step, start)
    return [t for g, (p, h) in enumerate(zip(poses, heading, strict=True))
            for t in ring_transducers(p, float(h), g)]


def room(rng: np.random.Generator, index: int) -> Draft:
    """Room case ``index``: outline ``ROOM_SHAPES[index % 4]`` scanned by
    ``ROOM_SCANS[(index // 4) % 3]`` (from :data:`SLANTED_FROM` on, a :func:`slanted`
    outline scanned by ``ROOM_SCANS[index % 3]``), pillars in about half, a box in every
    seventh."""
    if index >= SLANTED_FROM:
        shape, scan = "slanted", ROOM_SCANS[index % 3]
    else:
        shape, scan = ROOM_SHAPES[index % 4], ROOM_SCANS[(index // 4) % 3]
    loop_m = float(rng.uniform(0.6, 1.2))
    polygon = (slanted(rng, 2 * loop_m + 0.6) if shape == "slanted"
               else outline(rng, shape, 2 * loop_m + 0.6))
    keep = {"wall-following": 2 * FOLLOW_M, "rings": loop_m}.get(scan, 1.5)
    extra, tags = obstacles(rng, polygon, keep, int(rng.integers(1, 4)) if rng.random() < 0.5
                            else 0, index % 7 == 5)
    surfaces = [{"type": "polyline", "closed": True,
                 "points": [[float(x), float(y)] for x, y in polygon]}, *extra]
    sensors: dict[str, Any]
    if scan == "wall-following":
        start = _follow_start(rng, polygon, extra)
        sensors = {"placement": {"type": "wall-following",
                                 "start": [float(start[0]), float(start[1])],
                                 "step_m": round(float(rng.uniform(0.25, 0.75)), 2)}}
    elif scan == "rings":
        loop = inset(polygon, loop_m)
        length = float(np.sum(np.hypot(*(np.roll(loop, -1, 0) - loop).T)))
        sensors = {"transducers": rings_along(loop, round(float(rng.uniform(0.3, 0.6)), 2),
                                              float(rng.uniform(0, length)),
                                              bool(rng.random() < 0.5))}
        tags.append(f"loop {loop_m:.1f} m")
    else:
        sensors = {"placement": {"type": "per-wall", "surface": 0,
                                 "distance_m": round(float(rng.uniform(0.8, 1.5)), 2),
                                 "seed": int(rng.integers(1, 1000))}}
    return Draft("room", scan, f"{shape}-{scan}", surfaces, sensors, tags=tags,
                 turn=index % 2 == 1)


def corridor(rng: np.random.Generator, index: int) -> Draft:
    """Corridor case ``index``: 10–30 m × 1.5–3 m, two open walls (every other one with a
    side opening and stubs of a side corridor), a ring by hand every 0.5 m along the middle
    (a robot driving down it)."""
    length, width = float(rng.uniform(10.0, 30.0)), float(rng.uniform(1.5, 3.0))
    surfaces: list[dict[str, Any]] = [{"type": "polyline", "points": [[0.0, 0.0], [length, 0.0]]}]
    tags = []
    if index % 2 == 1:
        x0, gap = float(rng.uniform(0.3, 0.6) * length), float(rng.uniform(1.0, 2.0))
        stub = float(rng.uniform(0.5, 1.5))
        surfaces += [{"type": "polyline", "points": [[0.0, width], [x0, width],
                                                      [x0, width + stub]]},
                     {"type": "polyline", "points": [[x0 + gap, width + stub],
                                                      [x0 + gap, width], [length, width]]}]
        tags.append("opening")
    else:
        surfaces.append({"type": "polyline", "points": [[0.0, width], [length, width]]})
    xs = np.arange(0.5, length - 0.5 + 1e-9, 0.5)
    if rng.random() < 0.5:
        xs = xs[::-1]
    heading = 0.0 if xs[0] < xs[-1] else 180.0
    sensors = {"transducers": [t for g, x in enumerate(xs)
                               for t in ring_transducers(np.array([x, width / 2]), heading, g)]}
    return Draft("corridor", "rings", f"{length:.0f}x{width:.1f}m", surfaces, sensors,
                 tags=tags, turn=index % 3 != 0)
