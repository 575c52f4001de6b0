"""The zoo's single reflectors — a wall, a concave corner, a convex edge, a cylinder, a
sinusoid, a thin post — and the linear arrays that look at them (thesis §2.1, §3.1–3.5;
Kleeman & Kuc 1995's plane, corner and edge).

In its local frame a target sits at the origin and is seen from the −x side; the arrays are
posed by a ``pose(rng)`` that gives an array's centre, heading, line direction and tags, and
kept only where every element is clear of the target (:func:`scan`). Every fourth case is
scanned by a ``random-lines`` placement instead of arrays written by hand.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ...geometry import segment_distance
from .draft import Draft, noise_for, reach
from .shapes import array_transducers, crosses, unit

#: ``pose(rng) -> (centre, heading_deg, line_deg, tags)`` of one array.
Pose = Callable[[np.random.Generator], tuple[np.ndarray, float, float, list[str]]]

#: ``clear(element positions [n, 2]) -> bool``: the elements are clear of the target.
Clear = Callable[[np.ndarray], bool]

#: Longest array written by hand (metres).
MAX_ARRAY_M = 5.0

#: An element keeps this far from the target's surfaces (metres).
CLEAR_M = 0.3

#: Cases with one large array: (kind, index) -> (elements, pitch m, distance m).
BIG_ARRAYS = {("wall", 1): (300, 0.017, 3.0), ("wall", 6): (120, 0.03, 5.0),
              ("corner", 4): (100, 0.02, 4.0), ("cylinder", 4): (150, 0.02, 2.5)}


def _elements(rng: np.random.Generator) -> tuple[int, float]:
    """Elements (4–64, log-uniform) and pitch (1.5–10 cm) of an array at most
    :data:`MAX_ARRAY_M` long."""
    n = round(10 ** rng.uniform(math.log10(4), math.log10(64)))
    pitch = float(rng.uniform(0.015, 0.10))
    return n, round(min(pitch, max(0.015, MAX_ARRAY_M / (n - 1))), 4)


def _posed(rng: np.random.Generator, pose: Pose, clear: Clear, length: float
           ) -> tuple[np.ndarray, float, float, list[str]]:
    """A pose of an array ``length`` long whose elements are all clear (up to 200 tries)."""
    for _ in range(200):
        centre, heading, line, tags = pose(rng)
        ends = centre + np.outer([-length / 2, 0.0, length / 2], unit(line))
        if clear(ends):
            return centre, heading, line, tags
    raise RuntimeError("zoo: no clear array pose")  # the poses are drawn to make this rare


def scan(rng: np.random.Generator, index: int, kind: str, pose: Pose, clear: Clear,
         line_m: tuple[float, float] = (1.0, 4.0), spreads: tuple[float, ...] = (10, 30, 90)
         ) -> tuple[str, dict[str, Any], list[list[float]], list[str]]:
    """The sensors of target case ``index``: ``(scan, sensors, extra points, tags)`` — a
    ``random-lines`` placement every fourth case (a line ``line_m`` long, headings spread by
    one of ``spreads`` degrees), else 1–3 linear arrays written by hand (one group each;
    :data:`BIG_ARRAYS` gives some cases one large array)."""
    if index % 4 == 3:
        length = float(rng.uniform(*line_m))
        centre, heading, line, tags = _posed(rng, pose, clear, length)
        start = centre - length / 2 * unit(line)
        end = start + length * unit(line)
        spread = float(rng.choice(spreads))
        placement = {"type": "random-lines", "seed": int(rng.integers(1, 1000)),
                     "start": [float(start[0]), float(start[1])], "direction_deg": line,
                     "length_m": round(length, 2), "elements": int(rng.integers(4, 17)),
                     "facing_deg": heading, "heading_spread_deg": spread}
        return "random-lines", {"placement": placement}, [[float(end[0]), float(end[1])]], \
            [*tags, f"spread {spread:.0f}°"]
    big = BIG_ARRAYS.get((kind, index))
    transducers: list[dict[str, Any]] = []
    all_tags: list[str] = []
    for group in range(1 if big else int(rng.integers(1, 4))):
        n, pitch = (big[0], big[1]) if big else _elements(rng)
        centre, heading, line, tags = _posed(rng, pose, clear, (n - 1) * pitch)
        transducers += array_transducers(centre, heading, line, n, pitch, group)
        all_tags += [f"{n}×{pitch * 100:.1f} cm", *tags]
    return "arrays", {"transducers": transducers}, [], all_tags


def _jitter(rng: np.random.Generator, deg: float = 5.0) -> float:
    return float(rng.uniform(-deg, deg))


def _flat(index: int, kind: str, max_tilt: float) -> Pose:
    """The pose of arrays before a flat target along the y axis (a wall or a sinusoid's base
    line): the array's line square on in a quarter of the draws, else tilted up to
    ``max_tilt``° from the target, 1–9 m away, facing it within ±6° (the large array of
    :data:`BIG_ARRAYS` square on, at its distance)."""
    big = BIG_ARRAYS.get((kind, index))

    def pose(r: np.random.Generator) -> tuple[np.ndarray, float, float, list[str]]:
        d = big[2] if big else float(r.uniform(1.0, 9.0))
        tilt = (0.0 if big or r.random() < 0.25
                else float(r.uniform(0.0, max_tilt)) * float(r.choice([-1, 1])))
        centre = np.array([-d, float(r.uniform(-1.0, 1.0))])
        tags = [f"{d:.1f} m"] + ([f"tilt {abs(tilt):.0f}°"] if abs(tilt) >= 1 else [])
        return centre, 0.0 if big else _jitter(r, 6.0), 90.0 + tilt, tags
    return pose


def _footprint(sensors: dict[str, Any], extra: list[list[float]], spread: float
               ) -> tuple[float, float]:
    """The y range the beams of the elements (±12°, headings ±``spread``) cover on x = 0."""
    pts = [t["position"] for t in sensors.get("transducers", [])]
    p = sensors.get("placement")
    if p is not None:
        pts += [p["start"], *extra]
    xy = np.asarray(pts, float)
    reach = np.tan(np.radians(min(12.0 + spread, 60.0))) * np.abs(xy[:, 0])
    return float(np.min(xy[:, 1] - reach)), float(np.max(xy[:, 1] + reach))


def _along_y(rng: np.random.Generator, sensors: dict[str, Any], extra: list[list[float]]
             ) -> tuple[float, float]:
    """Ends of a target along the y axis: the beams' footprint, each end moved by −0.5 to
    +1.5 m (some ends inside the beams)."""
    p = sensors.get("placement")
    lo, hi = _footprint(sensors, extra, 0.0 if p is None else p["heading_spread_deg"])
    return lo - float(rng.uniform(-0.5, 1.5)), hi + float(rng.uniform(-0.5, 1.5))


def wall(rng: np.random.Generator, index: int) -> Draft:
    """A straight wall seen by arrays tilted 0–30° from it, 1–9 m away."""
    pose = _flat(index, "wall", 30.0)
    kind_scan, sensors, extra, tags = scan(rng, index, "wall", pose,
                                           lambda e: bool(np.all(e[:, 0] < -CLEAR_M)))
    lo, hi = _along_y(rng, sensors, extra)
    surfaces = [{"type": "polyline", "points": [[0.0, lo], [0.0, hi]]}]
    return Draft("wall", kind_scan, kind_scan, surfaces, sensors, extra, tags)


def sinusoid(rng: np.random.Generator, index: int) -> Draft:
    """A sinusoid (amplitude 2–30 cm, period 0.5–5 m, slope ≤ 1) along the y axis, seen by
    arrays tilted 0–20° from its base line, 1–9 m away."""
    amp = float(rng.uniform(0.02, 0.3))
    period = float(rng.uniform(max(0.5, 2 * math.pi * amp), 5.0))
    pose = _flat(index, "sinusoid", 20.0)
    kind_scan, sensors, extra, tags = scan(
        rng, index, "sinusoid", pose, lambda e: bool(np.all(e[:, 0] < -amp - CLEAR_M)))
    lo, hi = _along_y(rng, sensors, extra)
    surfaces = [{"type": "sinusoid", "from": [0.0, lo], "to": [0.0, hi],
                 "amplitude": round(amp, 3), "period": round(period, 3)}]
    return Draft("sinusoid", kind_scan, kind_scan, surfaces, sensors, extra,
                 [f"A {amp * 100:.0f} cm P {period:.1f} m", *tags])


def _vertex_pose(rng: np.random.Generator, index: int, kind: str,
                 bearing: Callable[[np.random.Generator], tuple[float, str]]) -> Pose:
    """Arrays looking at the origin (a vertex) from ``bearing(rng)`` (degrees, and its tag),
    1–9 m away, facing it within ±5°, their line across the line of sight."""
    big = BIG_ARRAYS.get((kind, index))

    def pose(r: np.random.Generator) -> tuple[np.ndarray, float, float, list[str]]:
        b, tag = bearing(r)
        d = big[2] if big else float(r.uniform(1.0, 9.0))
        heading = b + 180.0 + _jitter(r)
        return d * unit(b), heading, heading + 90.0, [f"{d:.1f} m", tag]
    return pose


def _clear_of(walls: np.ndarray, aim: np.ndarray) -> Clear:
    """Elements at least :data:`CLEAR_M` from ``walls`` with a clear line to ``aim`` (so
    none looks at the back of a wall)."""
    def clear(e: np.ndarray) -> bool:
        toward = aim + 0.01 * (e - aim) / np.hypot(*(e - aim).T)[:, None]
        return bool(np.all(segment_distance(e, walls, closed=False) >= CLEAR_M)
                    and not np.any(crosses(e, toward, walls)))
    return clear


def _two_walls(rng: np.random.Generator, a: float, b: float) -> np.ndarray:
    """Two walls from the origin along directions ``a`` and ``b`` (degrees), 1–3 m each."""
    la, lb = rng.uniform(1.0, 3.0, size=2)
    return np.array([la * unit(a), [0.0, 0.0], lb * unit(b)])


def _angle(rng: np.random.Generator, lo: float, hi: float) -> float:
    """90° in two cases of three, else uniform in [lo, hi]."""
    return 90.0 if rng.random() < 2 / 3 else float(rng.uniform(lo, hi))


def _vertex_case(rng: np.random.Generator, index: int, kind: str, walls: np.ndarray,
                 bearing: Callable[[np.random.Generator], tuple[float, str]], tag: str
                 ) -> Draft:
    """A corner or edge case: the two ``walls`` meeting at the origin, scanned from a pose
    drawn with ``bearing`` (:func:`_vertex_pose`), tagged ``tag`` and the scan's tags."""
    pose = _vertex_pose(rng, index, kind, bearing)
    kind_scan, sensors, extra, tags = scan(rng, index, kind, pose,
                                           _clear_of(walls, np.zeros(2)))
    surfaces = [{"type": "polyline", "points": walls.tolist()}]
    return Draft(kind, kind_scan, kind_scan, surfaces, sensors, extra, [tag, *tags])


def corner(rng: np.random.Generator, index: int) -> Draft:
    """A concave corner (90°, or 60–120°) open towards −x, seen 3–60° from its first
    wall's normal (45°: along the bisector of a right angle), 1–9 m away."""
    alpha = _angle(rng, 60.0, 120.0)
    walls = _two_walls(rng, 180.0 - alpha / 2, 180.0 + alpha / 2)
    normal = 270.0 - alpha / 2  # wall A's normal into the corner

    def bearing(r: np.random.Generator) -> tuple[float, str]:
        psi = float(r.uniform(max(0.0, 90.0 - alpha) + 3.0, 60.0))
        return normal - psi, f"seen at {psi:.0f}°"
    return _vertex_case(rng, index, "corner", walls, bearing, f"{alpha:.0f}°")


def edge(rng: np.random.Generator, index: int) -> Draft:
    """A convex edge (90°, or 60–150°) pointing towards −x, seen within ±60° of its
    bisector, 1–9 m away."""
    beta = _angle(rng, 60.0, 150.0)
    walls = _two_walls(rng, beta / 2, -beta / 2)

    def bearing(r: np.random.Generator) -> tuple[float, str]:
        psi = float(r.uniform(-60.0, 60.0))
        return 180.0 + psi, f"seen at {psi:.0f}°"
    return _vertex_case(rng, index, "edge", walls, bearing, f"{beta:.0f}°")


def _round(rng: np.random.Generator, index: int, kind: str, radius: float,
           near: float, far: float, **lines: Any) -> Draft:
    """A circle of ``radius`` touching the origin from +x, seen by arrays within ±90° of
    −x, ``near``–``far`` m from its surface, facing its centre within ±5° (``lines``: the
    ``random-lines`` keywords of :func:`scan`)."""
    centre = np.array([radius, 0.0])
    big = BIG_ARRAYS.get((kind, index))

    def pose(r: np.random.Generator) -> tuple[np.ndarray, float, float, list[str]]:
        b = 180.0 + float(r.uniform(-90.0, 90.0))
        d = big[2] if big else float(r.uniform(near, far))
        heading = b + 180.0 + _jitter(r)
        return centre + (radius + d) * unit(b), heading, heading + 90.0, [f"{d:.1f} m"]

    def clear(e: np.ndarray) -> bool:
        return bool(np.all(np.hypot(*(e - centre).T) >= radius + CLEAR_M))
    kind_scan, sensors, extra, tags = scan(rng, index, kind, pose, clear, **lines)
    surfaces = [{"type": "circle", "center": centre.tolist(), "radius": round(radius, 4)}]
    return Draft(kind, kind_scan, kind_scan, surfaces, sensors, extra,
                 [f"r {radius * 100:.0f} cm", *tags])


def cylinder(rng: np.random.Generator, index: int) -> Draft:
    """A cylinder, r 0.1–2 m (log-uniform), 1–9 m from the arrays but no farther than its
    echo stays audible (:func:`~.draft.reach`; a 10 cm one is seen from about 1.3 m)."""
    noise = noise_for("cylinder", index)
    least = max(0.1, 1.05 / reach(1.0, noise))
    radius = float(10 ** rng.uniform(math.log10(least), math.log10(2.0)))
    return _round(rng, index, "cylinder", radius, 1.0, min(9.0, max(1.0, reach(radius, noise))))


def post(rng: np.random.Generator, index: int) -> Draft:
    """A thin post, r 4–8 cm, 0.4 m to as far as it stays audible (about 1 m); a
    ``random-lines`` line 0.6–1.2 m long, headings within ±10° (its echo is barely above
    the detection's floor: only an element facing it hears it)."""
    radius = float(rng.uniform(0.04, 0.08))
    return _round(rng, index, "post", radius, 0.4, max(0.45, reach(radius, 0.0)),
                  line_m=(0.6, 1.2), spreads=(10.0,))
