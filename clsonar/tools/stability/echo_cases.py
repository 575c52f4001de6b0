"""The echo cases' scenes: rooms with clutter, far from the origin or tiny, coincident
transducers, grazing incidence, reflections at a wall's end, caustics of sinusoids, headings
around ±180°, and one group of many transducers (the package docstring lists them)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...scene import Circle, EchoModel, Polyline, Scene, Sensors, Sinusoid, Surface
from ...scene import Transducer as SceneTransducer

ECHO_FAMILIES = ("far", "tiny", "coincident", "grazing", "ends", "caustic", "headings", "many")


def unit(angle: float) -> np.ndarray:
    """The unit vector at ``angle`` radians."""
    return np.array([math.cos(angle), math.sin(angle)])


def heading_to(a: np.ndarray, b: np.ndarray) -> float:
    """Heading in degrees from ``a`` towards ``b``."""
    return math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))


def _mirror(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``p`` mirrored across the line through ``a`` and ``b``."""
    u = (b - a) / np.linalg.norm(b - a)
    d = p - a
    return a + 2 * np.dot(d, u) * u - d


@dataclass
class _Builder:
    """Surfaces and transducers in local metres, moved by ``offset`` and scaled at the end."""

    rng: np.random.Generator
    scale: float = 1.0
    offset: tuple[float, float] = (0.0, 0.0)
    size: tuple[float, float] = (4.0, 3.0)
    surfaces: list[Surface] = field(default_factory=list)
    transducers: list[tuple[float, float, float, int]] = field(default_factory=list)
    echo: dict[str, Any] = field(default_factory=dict)  # EchoModel keys

    def room(self) -> None:
        w, h = self.size
        self.surfaces.append(Polyline(((0.0, 0.0), (w, 0.0), (w, h), (0.0, h)), closed=True))

    def point(self, margin: float = 0.2) -> np.ndarray:
        w, h = self.size
        return np.array([self.rng.uniform(margin * w, (1 - margin) * w),
                         self.rng.uniform(margin * h, (1 - margin) * h)])

    def add(self, p, heading_deg: float, group: int = 0) -> None:
        self.transducers.append((float(p[0]), float(p[1]), float(heading_deg), group))

    def clutter(self) -> None:
        """A wall, a cylinder and a sinusoid inside the room, each maybe."""
        if self.rng.random() < 0.6:
            a, b = self.point(), self.point()
            if np.linalg.norm(a - b) > 0.1 * min(self.size):
                self.surfaces.append(Polyline((tuple(a), tuple(b))))
        if self.rng.random() < 0.6:
            self.surfaces.append(Circle(tuple(self.point()),
                                        self.rng.uniform(0.02, 0.12) * min(self.size)))
        if self.rng.random() < 0.5:
            a, b = self.point(), self.point()
            if np.linalg.norm(a - b) > 0.1 * min(self.size):
                self.surfaces.append(Sinusoid(tuple(a), tuple(b),
                                              self.rng.uniform(-0.05, 0.05) * min(self.size),
                                              self.rng.uniform(0.1, 0.5) * min(self.size)))

    def aim(self, p: np.ndarray) -> float:
        """A heading from ``p`` towards some surface point (or anywhere, sometimes)."""
        targets: list[np.ndarray] = []
        for s in self.surfaces:
            if isinstance(s, Polyline):
                pts = np.asarray(s.points)
                targets.extend(pts)
                targets.extend(0.5 * (pts[1:] + pts[:-1]))
            elif isinstance(s, Circle):
                targets.append(np.asarray(s.center))
            else:
                f = self.rng.random()
                targets.append((1 - f) * np.asarray(s.start) + f * np.asarray(s.end))
        if not targets or self.rng.random() < 0.15:
            return float(self.rng.uniform(-180.0, 180.0))
        t = targets[self.rng.integers(len(targets))]
        return heading_to(p, t) + float(self.rng.normal(0.0, 4.0))

    def groups(self, n_groups: int = 2, per_group: tuple[int, int] = (1, 4)) -> None:
        for g in range(n_groups):
            p = self.point()
            step = unit(self.rng.uniform(0, 2 * math.pi)) * self.rng.uniform(0.01, 0.05)
            step *= min(self.size)
            heading = self.aim(p)
            for _ in range(int(self.rng.integers(*per_group, endpoint=True))):
                self.add(p, heading + self.rng.normal(0.0, 3.0), g)
                p = p + step

    def scene(self, name: str) -> Scene:
        k, (ox, oy) = self.scale, self.offset

        def move(p):
            return (float(p[0]) * k + ox, float(p[1]) * k + oy)

        surfaces: list[Surface] = []
        for s in self.surfaces:
            if isinstance(s, Polyline):
                surfaces.append(Polyline(tuple(move(p) for p in s.points), s.closed, s.solid))
            elif isinstance(s, Circle):
                surfaces.append(Circle(move(s.center), s.radius * k))
            else:
                surfaces.append(Sinusoid(move(s.start), move(s.end), s.amplitude * k,
                                         s.period * k))
        sensors = tuple(SceneTransducer(move(t[:2]), t[2], t[3]) for t in self.transducers)
        w, h = self.size
        margin = 0.1 * max(w, h)
        x0, y0 = move((-margin, -margin))
        x1, y1 = move((w + margin, h + margin))
        echo = {"curve_step_m": 0.01 * k, **self.echo}
        return Scene(name=name, extent=(x0, y0, x1, y1), cell=0.01 * k, surfaces=tuple(surfaces),
                     sensors=Sensors(transducers=sensors), echo=EchoModel(**echo))


def _base(rng: np.random.Generator, **kw) -> _Builder:
    b = _Builder(rng, size=(rng.uniform(2.5, 6.0), rng.uniform(2.5, 5.0)), **kw)
    b.room()
    b.clutter()
    b.echo = {"max_order": int(rng.choice([1, 2, 2, 3]))}
    return b


def _echo_far(rng):
    b = _base(rng, offset=tuple(rng.choice([-1, 1], 2) * rng.uniform(1e3, 1e5, 2)))
    b.groups()
    return b


def _echo_tiny(rng):
    b = _base(rng, scale=float(rng.uniform(0.005, 0.02)))  # rooms of 1.5–12 cm
    b.groups()
    return b


def _echo_coincident(rng):
    b = _base(rng)
    for g in range(2):
        p = b.point()
        heading = b.aim(p)
        b.add(p, heading, g)
        for gap in rng.choice([0.0, 1e-9, 1e-7, 1e-5, 1e-3], 2):
            b.add(p + gap * unit(rng.uniform(0, 2 * math.pi)), heading + rng.normal(0, 1), g)
    return b


def _echo_grazing(rng):
    b = _Builder(rng, size=(6.0, 4.0))
    b.room()
    y = 2.0
    a, c = np.array([0.5, y]), np.array([5.5, y])
    b.surfaces.append(Polyline((tuple(a), tuple(c))))
    for g, height in enumerate(rng.choice([1e-6, 1e-4, 1e-3, 1e-2, 5e-2], 2)):
        t = np.array([rng.uniform(0.6, 1.5), y + height])
        r = np.array([rng.uniform(4.5, 5.4), y + height * rng.uniform(0.5, 2.0)])
        mid = np.array([0.5 * (t[0] + r[0]), y])
        b.add(t, heading_to(t, mid) + rng.normal(0, 0.5), g)
        b.add(r, heading_to(r, mid) + rng.normal(0, 0.5), g)
    centre, radius = np.array([3.0, 1.0]), float(rng.uniform(0.1, 0.5))
    b.surfaces.append(Circle(tuple(centre), radius))
    phi = rng.uniform(0, 2 * math.pi)
    touch = centre + radius * unit(phi)
    along = unit(phi + math.pi / 2)
    for side in (-1, 1):
        p = touch + side * rng.uniform(0.3, 1.0) * along + rng.uniform(0, 1e-4) * unit(phi)
        b.add(p, heading_to(p, touch) + rng.normal(0, 0.5), 2)
    b.echo = {"max_order": 1}
    return b


def _echo_ends(rng):
    b = _Builder(rng, size=(6.0, 5.0))
    b.room()
    pts = [np.array([1.5, 1.0]), np.array([3.0, 1.0 + rng.uniform(-0.5, 0.5)]),
           np.array([4.5, 1.2])]
    b.surfaces.append(Polyline(tuple(map(tuple, pts))))
    for g, q in enumerate(pts):
        a, c = (pts[0], pts[1]) if g < 2 else (pts[1], pts[2])
        t = q + rng.uniform(1.0, 2.5) * unit(rng.uniform(0.3, math.pi - 0.3))
        image = _mirror(t, a, c)
        r = q + (q - image) / np.linalg.norm(q - image) * rng.uniform(0.5, 2.0)
        b.add(t, heading_to(t, q) + rng.normal(0, 1), g)
        b.add(r, heading_to(r, q) + rng.normal(0, 1), g)
        b.add(t, heading_to(t, q), g)  # T = R aimed at the vertex: an edge echo
    b.echo = {"max_order": 2}
    return b


def _echo_caustic(rng):
    b = _Builder(rng, size=(4.0, 3.0))
    b.room()
    period = float(rng.choice([rng.uniform(0.02, 0.1), rng.uniform(0.2, 1.0)]))
    omega = 2 * math.pi / period
    distance = rng.uniform(0.3, 1.5)
    # amplitude·ω² = 1/d puts the crests' centres of curvature near the transducers
    amplitude = min(0.2, float(rng.uniform(0.3, 3.0) / (distance * omega**2)))
    y = 0.5
    b.surfaces.append(Sinusoid((0.3, y), (3.7, y), amplitude, period))
    for g in range(2):
        p = np.array([rng.uniform(1.0, 3.0), y + distance])
        for _ in range(int(rng.integers(1, 4))):
            b.add(p, -90.0 + rng.normal(0, 6), g)
            p = p + np.array([rng.uniform(0.005, 0.05), 0.0])
    b.echo = {"max_order": 1, "curve_step_m": float(min(0.01, period / 8))}
    return b


def _echo_headings(rng):
    b = _base(rng)
    w, h = b.size
    for g in range(2):
        p = np.array([rng.uniform(0.3, 0.6) * w, rng.uniform(0.2, 0.8) * h])
        for heading in rng.choice([180.0, -180.0, 180.0 - 1e-6, -180.0 + 1e-6, 179.9, -179.9,
                                   540.0, -540.0, 180.0 + 1e-4], 3):
            b.add(p, heading, g)
            p = p + np.array([0.0, rng.uniform(0.01, 0.1)])
    return b


def _echo_many(rng, count: int = 40):
    b = _base(rng)
    w, h = b.size
    x = rng.uniform(0.5, 0.8) * w
    ys = np.linspace(0.1 * h, 0.9 * h, count)
    for y in ys:
        b.add((x, y), rng.normal(0.0, 6.0) + rng.choice([0.0, 180.0]), 0)
    b.echo = {"max_order": 1}
    return b


ECHO_GENERATORS: dict[str, Callable[..., _Builder]] = {
    "far": _echo_far, "tiny": _echo_tiny, "coincident": _echo_coincident,
    "grazing": _echo_grazing, "ends": _echo_ends, "caustic": _echo_caustic,
    "headings": _echo_headings, "many": _echo_many}


def echo_scene(family: str, seed: int, *, many: int = 40) -> Scene:
    """The echo case ``(family, seed)``: a :class:`~clsonar.scene.Scene` with explicit
    transducers; ``many`` transducers in the ``many`` family."""
    rng = np.random.default_rng([seed, ECHO_FAMILIES.index(family)])
    gen = ECHO_GENERATORS[family]
    b = gen(rng, many) if family == "many" else gen(rng)
    return b.scene(f"stress-echo-{family}-{seed}")
