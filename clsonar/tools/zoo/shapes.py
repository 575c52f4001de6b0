"""Plane geometry the zoo's scenes are built with: outlines of rooms, their loops inside the
walls, rings and linear arrays written as explicit transducers, and bounding boxes.

Everything is float64 NumPy in a scene's local frame; :func:`transform` turns and moves a
finished scene dict (every coordinate of format v1) to its pose.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ...sensors import ring

#: A point as a scene file writes it.
XY = list[float]

#: Decimals kept in the zoo's files: 1 µm, far below a cell.
DECIMALS = 6


def rect(w: float, h: float) -> np.ndarray:
    """A w × h rectangle from the origin, counter-clockwise."""
    return np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=np.float64)


def l_shape(w: float, h: float, cut_w: float, cut_h: float) -> np.ndarray:
    """A w × h rectangle with its top-right cut_w × cut_h corner taken out (an L),
    counter-clockwise."""
    return np.array([[0, 0], [w, 0], [w, h - cut_h], [w - cut_w, h - cut_h], [w - cut_w, h],
                     [0, h]], dtype=np.float64)


def u_shape(w: float, h: float, arm: float, notch: float) -> np.ndarray:
    """A w × h rectangle with a notch of depth ``notch`` cut into its top between two arms
    ``arm`` wide (a U), counter-clockwise."""
    return np.array([[0, 0], [w, 0], [w, h], [w - arm, h], [w - arm, h - notch],
                     [arm, h - notch], [arm, h], [0, h]], dtype=np.float64)


def t_shape(w: float, h: float, stem: float, bar: float) -> np.ndarray:
    """A T: a bar w wide and ``bar`` deep across the top of a stem ``stem`` wide, h high in
    all, counter-clockwise."""
    s0, s1 = (w - stem) / 2, (w + stem) / 2
    return np.array([[s0, 0], [s1, 0], [s1, h - bar], [w, h - bar], [w, h], [0, h],
                     [0, h - bar], [s0, h - bar]], dtype=np.float64)


def inset(polygon: np.ndarray, d: float) -> np.ndarray:
    """The loop ``d`` inside a counter-clockwise polygon: each side moved by ``d`` along its
    inward (left) normal, consecutive sides' lines intersected. Valid while ``d`` is below
    half the polygon's narrowest part (the zoo's rooms are built so)."""
    p = np.asarray(polygon, dtype=np.float64)
    q = np.roll(p, -1, axis=0)
    u = (q - p) / np.hypot(*(q - p).T)[:, None]
    normal = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    a = p + d * normal  # a point of each moved side
    out = []
    for k in range(len(p)):
        j = k - 1  # the side before vertex k
        # a[j] + s·u[j] = a[k] + t·u[k]
        m = np.array([u[j], -u[k]]).T
        s = np.linalg.solve(m, a[k] - a[j])[0]
        out.append(a[j] + s * u[j])
    return np.asarray(out)


def walk(loop: np.ndarray, step: float, start: float = 0.0
         ) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step`` along the closed ``loop`` from arc length ``start``, and the
    direction of travel (degrees) at each: a robot's poses in the order it logs them."""
    p = np.asarray(loop, dtype=np.float64)
    q = np.roll(p, -1, axis=0)
    seg = np.hypot(*(q - p).T)
    ends = np.cumsum(seg)
    s = (start + np.arange(int(ends[-1] // step)) * step) % ends[-1]
    k = np.searchsorted(ends, s, side="right")
    t = (s - (ends[k] - seg[k])) / seg[k]
    points = p[k] + t[:, None] * (q[k] - p[k])
    heading = np.degrees(np.arctan2(*(q[k] - p[k])[:, ::-1].T))
    return points, heading


def ring_transducers(center: np.ndarray, start_deg: float, group: int,
                     radius_m: float = 0.065, elements: int = 8) -> list[dict[str, Any]]:
    """One ring pose as explicit transducers (thesis §2.1.2: 8 facing outwards on 6.5 cm),
    all of one ``group``."""
    pos, head = ring((float(center[0]), float(center[1])), radius_m, elements, start_deg)
    return [{"position": [float(x), float(y)], "heading_deg": float(h), "group": group}
            for (x, y), h in zip(pos, head, strict=True)]


def array_transducers(center: np.ndarray, heading_deg: float, line_deg: float, elements: int,
                      pitch: float, group: int) -> list[dict[str, Any]]:
    """A linear array of ``elements`` transducers ``pitch`` apart along direction
    ``line_deg``, centred on ``center``, all facing ``heading_deg``, one ``group``."""
    u = np.array([math.cos(math.radians(line_deg)), math.sin(math.radians(line_deg))])
    offsets = (np.arange(elements) - (elements - 1) / 2) * pitch
    return [{"position": [float(x), float(y)], "heading_deg": float(heading_deg),
             "group": group} for x, y in np.asarray(center) + offsets[:, None] * u]


def unit(deg: float) -> np.ndarray:
    """The unit vector at ``deg`` degrees from +x."""
    return np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])


def scene_points(data: dict[str, Any]) -> np.ndarray:
    """[M, 2] every point a scene dict names (surfaces with a circle's or a sinusoid's reach,
    transducers, placements' starts and centres): what its extent must hold."""
    out: list[np.ndarray] = []
    for s in data["surfaces"]:
        if s["type"] == "polyline":
            out.append(np.asarray(s["points"], float))
        elif s["type"] == "circle":
            c, r = np.asarray(s["center"], float), s["radius"]
            out.append(c + r * np.array([[1, 1], [-1, -1]]))
        else:
            ends = np.asarray([s["from"], s["to"]], float)
            out += [ends + s["amplitude"], ends - s["amplitude"]]
    sensors = data.get("sensors", {})
    out += [np.asarray([t["position"] for t in sensors.get("transducers", [])],
                       float).reshape(-1, 2)]
    for p in [sensors.get("placement"), *sensors.get("placements", [])]:
        for key in ("start", "center"):
            if p is not None and key in p:
                out.append(np.asarray([p[key]], float))
    return np.concatenate(out)


def mover(angle_deg: float, shift: np.ndarray) -> Callable[[Any], XY]:
    """A function that turns a point by ``angle_deg`` about the origin, then moves it by
    ``shift`` (to :data:`DECIMALS`)."""
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))

    def xy(p: Any) -> XY:
        x, y = float(p[0]), float(p[1])
        return [round(c * x - s * y + float(shift[0]), DECIMALS),
                round(s * x + c * y + float(shift[1]), DECIMALS)]
    return xy


def transform(data: dict[str, Any], angle_deg: float, shift: np.ndarray) -> dict[str, Any]:
    """``data`` (a scene dict) turned by ``angle_deg`` about the origin, then moved by
    ``shift``: every point, heading and direction of format v1 (the extent is set later)."""
    xy = mover(angle_deg, shift)

    def deg(h: float) -> float:
        return round(float((h + angle_deg + 180.0) % 360.0 - 180.0), DECIMALS)

    for surface in data["surfaces"]:
        for key in ("points",):
            if key in surface:
                surface[key] = [xy(p) for p in surface[key]]
        for key in ("center", "from", "to"):
            if key in surface:
                surface[key] = xy(surface[key])
    sensors = data.get("sensors", {})
    for t in sensors.get("transducers", []):
        t["position"], t["heading_deg"] = xy(t["position"]), deg(t["heading_deg"])
    for p in [sensors.get("placement"), *sensors.get("placements", [])]:
        if p is None:
            continue
        for key in ("start", "center"):
            if key in p:
                p[key] = xy(p[key])
        for key in ("direction_deg", "facing_deg", "start_deg"):
            if key in p:
                p[key] = deg(p[key])
    return data


def extent_around(points: np.ndarray, margin: float) -> list[float]:
    """``[xmin, ymin, xmax, ymax]`` of ``points`` grown by ``margin``, to 1 mm."""
    lo, hi = points.min(axis=0) - margin, points.max(axis=0) + margin
    return [math.floor(lo[0] * 1000) / 1000, math.floor(lo[1] * 1000) / 1000,
            math.ceil(hi[0] * 1000) / 1000, math.ceil(hi[1] * 1000) / 1000]


def crosses(a: np.ndarray, b: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """[M] bool: whether each segment ``a[m]``→``b[m]`` meets a side of the open
    ``polyline`` [K, 2] (touching counts)."""
    a, b = np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2)
    p, q = np.asarray(polyline, float)[:-1], np.asarray(polyline, float)[1:]

    def side(o: np.ndarray, d: np.ndarray, x: np.ndarray) -> np.ndarray:
        return d[..., 0] * (x[..., 1] - o[..., 1]) - d[..., 1] * (x[..., 0] - o[..., 0])

    d1 = (b - a)[:, None]
    d2 = (q - p)[None]
    s1 = side(a[:, None], d1, p[None]) * side(a[:, None], d1, q[None])
    s2 = side(p[None], d2, a[:, None]) * side(p[None], d2, b[:, None])
    return np.any((s1 <= 0) & (s2 <= 0), axis=1)
