"""Numerical stability: the float32 kernels against their float64 references on hostile scenes.

One set of scene generators serves the property tests (tests/test_stability.py, a few dozen
cases on every CI run) and ``clsonar stress`` (thousands, on the user's device). A case is
``(family, seed)``: the family names the hazard, the seed draws the rest from NumPy's
``default_rng``, so every case is reproducible from those two values alone.

Echo families (kernels/echoes.cl against :func:`clsonar.echoes.reference_echoes`):

- ``far`` — a room up to 10⁵ m from the origin; ``tiny`` — a room a few centimetres wide;
- ``coincident`` — T = R and receivers 0 … 1 mm from their transmitter;
- ``grazing`` — transducers a hair above a wall's line, or on a circle's tangent;
- ``ends`` — reflection points exactly at a wall's end or at a vertex;
- ``caustic`` — sinusoids curved so that several specular points crowd together, and very
  short periods;
- ``headings`` — headings at and around ±180° (and ±540°);
- ``many`` — one group of many transducers: a long pair list.

Detection (kernels/signals.cl against :func:`clsonar.signals.detect_reference`): every echo
family but ``many``, its float64 echoes received with a random detector (threshold or
envelope) and noise level.

Map families (kernels/accumulate.cl against :func:`clsonar.mapping.accumulate_reference`,
:func:`clsonar.mapping.backproject_reference`): ``far``, ``tiny``, ``coincident`` (T = R and
nearly coincident T and R), ``flat`` (c·τ within 1 µm of |T − R|: a flat ellipse), ``focus``
(a transducer exactly on a pixel centre), ``knife`` (pixel centres exactly on a band edge),
``headings``, ``outside`` (transducers outside the map,
beams leaving it), ``ragged`` (extents that are not multiples of the cell), ``million``
(``MILLION`` loci on one map) and ``backprojection``.

The properties (:data:`BOUNDS`), checked on every case:

- no NaN or Inf in any output;
- echoes: each float32 echo matched to its float64 twin has |Δτ| ≤ 1 µs; an echo present in
  one table only must be a knife-edge decision: the float64 reference itself gains or loses
  it when the transducers move by a float32 rounding (:func:`_edge_echo_keys`), or be
  weaker than 5 % of A0 (a beam edge or grazing incidence, as tests/test_echoes.py allows);
- maps: every pixel where float32 and float64 differ (beyond float32 summation rounding)
  lies within a few float32 roundings of a band edge or a beam edge of some locus
  (:func:`edge_pixels`), and at most 0.1 % of the pixels differ;
- work groups: the same case run with other work-group sizes (and tile shapes, and the dense
  map kernel instead of the tiled one) gives bit-identical output.
"""

from __future__ import annotations

import contextlib
import inspect
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from .. import echoes as echoes_mod
from .. import mapping
from ..echoes import host as echo_host
from ..mapping import Loci
from ..scene import Circle, EchoModel, MappingSettings, Polyline, Scene, Sensors, Sinusoid
from ..scene import Transducer as SceneTransducer
from ..sensors import SensorArray

EPS32 = float(np.finfo(np.float32).eps)

#: What the property suite and ``clsonar stress`` require (docs/stability.md states them).
BOUNDS = {
    "tof_abs_s": 1e-6,  # float32 time of flight against float64
    "map_differing_fraction": 1e-3,  # pixels where the float32 map differs
    "edge_roundings": 16,  # "on an edge": within this many float32 roundings of it
    "value_rtol": 1e-5,  # float32 summation rounding allowed in a pixel's value
    "weak_echo": 0.05,  # echoes weaker than this × A0 may be in one table only
}

ECHO_FAMILIES = ("far", "tiny", "coincident", "grazing", "ends", "caustic", "headings", "many")
MAP_FAMILIES = ("far", "tiny", "coincident", "flat", "focus", "knife", "headings", "outside",
                "ragged", "million", "backprojection")

#: Loci of the ``million`` map family.
MILLION = 1_000_000

#: Alternative launch shapes: echo kernels' work-group size, and the map kernels'
#: (pixels per work item, work-group shape) on a CPU (GPUs: vector width 1).
ALT_ECHO_GROUPS = (8, 1)
ALT_MAP_LAUNCH = ((1, (16, 4), (16, 16)), (4, (4, 2), (64, 8)))


# --------------------------------------------------------------------------- scenes


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _heading(a: np.ndarray, b: np.ndarray) -> float:
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
    surfaces: list = field(default_factory=list)
    transducers: list = field(default_factory=list)
    echo: dict = field(default_factory=dict)

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
        targets = []
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
        return _heading(p, t) + float(self.rng.normal(0.0, 4.0))

    def groups(self, n_groups: int = 2, per_group: tuple[int, int] = (1, 4)) -> None:
        for g in range(n_groups):
            p = self.point()
            step = _unit(self.rng.uniform(0, 2 * math.pi)) * self.rng.uniform(0.01, 0.05)
            step *= min(self.size)
            heading = self.aim(p)
            for _ in range(int(self.rng.integers(*per_group, endpoint=True))):
                self.add(p, heading + self.rng.normal(0.0, 3.0), g)
                p = p + step

    def scene(self, name: str) -> Scene:
        k, (ox, oy) = self.scale, self.offset

        def move(p):
            return (float(p[0]) * k + ox, float(p[1]) * k + oy)

        surfaces = []
        for s in self.surfaces:
            if isinstance(s, Polyline):
                surfaces.append(Polyline(tuple(move(p) for p in s.points), s.closed))
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
            b.add(p + gap * _unit(rng.uniform(0, 2 * math.pi)), heading + rng.normal(0, 1), g)
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
        b.add(t, _heading(t, mid) + rng.normal(0, 0.5), g)
        b.add(r, _heading(r, mid) + rng.normal(0, 0.5), g)
    centre, radius = np.array([3.0, 1.0]), float(rng.uniform(0.1, 0.5))
    b.surfaces.append(Circle(tuple(centre), radius))
    phi = rng.uniform(0, 2 * math.pi)
    touch = centre + radius * _unit(phi)
    along = _unit(phi + math.pi / 2)
    for side in (-1, 1):
        p = touch + side * rng.uniform(0.3, 1.0) * along + rng.uniform(0, 1e-4) * _unit(phi)
        b.add(p, _heading(p, touch) + rng.normal(0, 0.5), 2)
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
        t = q + rng.uniform(1.0, 2.5) * _unit(rng.uniform(0.3, math.pi - 0.3))
        image = _mirror(t, a, c)
        r = q + (q - image) / np.linalg.norm(q - image) * rng.uniform(0.5, 2.0)
        b.add(t, _heading(t, q) + rng.normal(0, 1), g)
        b.add(r, _heading(r, q) + rng.normal(0, 1), g)
        b.add(t, _heading(t, q), g)  # T = R aimed at the vertex: an edge echo
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


def _sensor_array(transducers: list[tuple[float, float, float]]) -> SensorArray:
    t = np.asarray(transducers, dtype=np.float64).reshape(-1, 3)
    return SensorArray(t[:, :2].copy(), t[:, 2].copy(), np.zeros(len(t), np.int64),
                       np.zeros((0, 2)))


def map_case(family: str, seed: int, *, million: int = MILLION) -> MapCase:
    """The map case ``(family, seed)``; ``million`` loci in the ``million`` family."""
    rng = np.random.default_rng([seed, 100 + MAP_FAMILIES.index(family)])
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
    w, h = size
    extent = (origin[0], origin[1], origin[0] + w, origin[1] + h)

    def inside(margin: float = 0.1) -> np.ndarray:
        return origin + rng.uniform(margin, 1 - margin, 2) * size

    def pixel_centre() -> np.ndarray:
        ny, nx = math.ceil(h / cell - 1e-9), math.ceil(w / cell - 1e-9)
        return origin + (np.array([rng.integers(nx), rng.integers(ny)]) + 0.5) * cell

    transducers = []
    for i in range(n_sensors):
        if family == "outside":
            p = origin + rng.uniform(-0.5, 1.5, 2) * size
        elif family == "focus" and i < 2:
            p = pixel_centre()
        else:
            p = inside()
        if family == "headings":
            heading = float(rng.choice([180.0, -180.0, 180.0 - 1e-6, -180.0 + 1e-6, 540.0]))
        else:
            heading = _heading(p, inside(0.3)) + rng.normal(0.0, 15.0)
            if family == "outside" and rng.random() < 0.3:
                heading += 180.0
        transducers.append((p[0], p[1], heading))
    if family == "coincident":
        t = transducers[0]
        for gap in rng.choice([0.0, 1e-9, 1e-7, 1e-5, 1e-3], 2):
            v = gap * _unit(rng.uniform(0, 2 * math.pi))
            transducers.append((t[0] + v[0], t[1] + v[1], t[2] + rng.normal(0, 1)))
    n = len(transducers)
    pos = np.asarray(transducers)[:, :2]
    tx = rng.integers(0, n, n_loci)
    rx = np.where(rng.random(n_loci) < 0.3, tx, rng.integers(0, n, n_loci))
    if family == "coincident":
        tx[: n_loci // 2] = 0
        rx[: n_loci // 2] = rng.integers(n - 2, n, n_loci // 2)
    q = origin + rng.uniform(0.0, 1.0, (n_loci, 2)) * size
    path = (np.linalg.norm(q - pos[tx], axis=1) + np.linalg.norm(q - pos[rx], axis=1)
            + rng.normal(0.0, 2.0, n_loci) * cell)
    if family == "flat":
        path = np.linalg.norm(pos[tx] - pos[rx], axis=1) + rng.uniform(0.0, 1e-6, n_loci)
    elif family == "knife":  # a pixel centre exactly on the band's edge
        q = np.array([pixel_centre() for _ in range(n_loci)])
        path = (np.linalg.norm(q - pos[tx], axis=1) + np.linalg.norm(q - pos[rx], axis=1)
                + rng.choice([-0.5, 0.5], n_loci) * mapping.band_m(Scene("x", extent, cell)))
    c = 343.0
    settings = MappingSettings(mode="loci", weight=str(rng.choice(mapping.WEIGHTS)),
                               combine="sum")
    scene = Scene(name=f"stress-map-{family}-{seed}", extent=tuple(map(float, extent)),
                  cell=cell, mapping=settings)
    c = scene.medium.c
    loci = Loci(tx.astype(np.int64), rx.astype(np.int64), np.maximum(path, 0.0) / c,
                rng.uniform(0.1, 5.0, n_loci))
    sensors = _sensor_array(transducers)
    if family != "backprojection":
        return MapCase(scene, sensors, loci)
    pr = np.unique(np.stack([tx, rx], axis=1), axis=0)
    dt = 1e-6
    samples = int(2 * np.hypot(w + 1, h + 1) / c / dt) + 2
    return MapCase(scene, sensors, loci, pr, _envelopes(rng, len(pr), samples, dt), dt)


def _envelopes(rng: np.random.Generator, n_pairs: int, samples: int, dt: float) -> np.ndarray:
    """[n_pairs, samples] smooth envelopes: Gaussian echoes of the pulse's σ (thesis eq. 2.3)
    at random delays on a small noise floor, as the envelope detector gives them."""
    from ..physics import DEFAULT_PULSE_SIGMA_S

    t = np.arange(samples) * dt
    env = np.full((n_pairs, samples), 0.01)
    for i in range(n_pairs):
        for delay, amp in zip(rng.uniform(0, t[-1], 3), rng.uniform(0.5, 5.0, 3), strict=True):
            env[i] += amp * np.exp(-0.5 * ((t - delay) / DEFAULT_PULSE_SIGMA_S) ** 2)
    return env


# --------------------------------------------------------------------------- judging echoes


def _keys(table) -> list[tuple]:
    return list(zip(table.tx.tolist(), table.rx.tolist(), table.kind.tolist(),
                    table.order.tolist(), table.element.tolist(), strict=True))


def _n_circles(scene: Scene) -> int:
    return sum(isinstance(s, Circle) for s in scene.surfaces)


def match_echoes(ref, got, n_circles: int) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """Pair rows of ``got`` with rows of ``ref`` on (tx, rx, kind, order, element), nearest
    time of flight first; a sinusoid's echo may come from the neighbouring sampling interval
    (its specular point on the shared sample). Returns (pairs, ref-only rows, got-only rows)."""
    index: dict[tuple, list[int]] = {}
    for j, key in enumerate(_keys(got)):
        index.setdefault(key, []).append(j)
    used = np.zeros(len(got), dtype=bool)
    matched, ref_only = [], []
    for i, key in enumerate(_keys(ref)):
        candidates = [key]
        if key[2] == echoes_mod.CURVED and key[4] >= n_circles:
            candidates += [(*key[:4], key[4] - 1), (*key[:4], key[4] + 1)]
        options = [j for k in candidates for j in index.get(k, []) if not used[j]]
        if not options:
            ref_only.append(i)
            continue
        j = min(options, key=lambda j: abs(got.tof_s[j] - ref.tof_s[i]))
        used[j] = True
        matched.append((i, j))
    return matched, ref_only, np.flatnonzero(~used).tolist()


def _jittered(scene: Scene, rng: np.random.Generator, delta: float) -> Scene:
    """``scene`` with every transducer moved by up to ``delta`` and turned by up to
    ``delta`` radians (float32 rounding of a position or direction)."""
    ts = tuple(SceneTransducer((t.position[0] + rng.uniform(-delta, delta),
                                t.position[1] + rng.uniform(-delta, delta)),
                               t.heading_deg + math.degrees(rng.uniform(-delta, delta)), t.group)
               for t in scene.sensors.transducers)
    return replace(scene, sensors=replace(scene.sensors, transducers=ts))


def _edge_echo_keys(scene: Scene, jitters: int = 6) -> set[tuple]:
    """Keys (tx, rx, kind, order, element) of echoes whose existence in the float64
    reference changes when the transducers move by a few float32 roundings of the scene's
    local coordinates: knife-edge decisions that float32 may take either way."""
    x0, y0, x1, y1 = scene.extent
    local = 0.5 * math.hypot(x1 - x0, y1 - y0)
    delta = BOUNDS["edge_roundings"] * EPS32 * max(local, 1e-3)
    base = set(_keys(echoes_mod.reference_echoes(scene)))
    rng = np.random.default_rng(0)
    unstable: set[tuple] = set()
    for _ in range(jitters):
        unstable |= base ^ set(_keys(echoes_mod.reference_echoes(_jittered(scene, rng, delta))))
    return unstable


def _near_keys(key: tuple, n_circles: int) -> list[tuple]:
    if key[2] == echoes_mod.CURVED and key[4] >= n_circles:
        return [key, (*key[:4], key[4] - 1), (*key[:4], key[4] + 1)]
    return [key]


@dataclass
class Findings:
    """Worst errors and counts of one or many cases, per property (``clsonar stress``)."""

    cases: int = 0
    nonfinite: int = 0
    echoes: int = 0
    tof_max_s: float = 0.0
    tof_worst: str = ""
    amp_max_rel: float = 0.0
    amp_worst: str = ""
    unmatched_edge: int = 0
    unmatched_weak: int = 0
    unmatched_other: int = 0
    pixels: int = 0
    differing: int = 0
    differing_off_edge: int = 0
    worst_fraction: float = 0.0
    worst_fraction_case: str = ""
    work_group_mismatches: int = 0
    failures: list[str] = field(default_factory=list)

    def merge(self, other: Findings) -> None:
        for name in ("cases", "nonfinite", "echoes", "unmatched_edge", "unmatched_weak",
                     "unmatched_other",
                     "pixels", "differing", "differing_off_edge", "work_group_mismatches"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        if other.tof_max_s > self.tof_max_s:
            self.tof_max_s, self.tof_worst = other.tof_max_s, other.tof_worst
        if other.amp_max_rel > self.amp_max_rel:
            self.amp_max_rel, self.amp_worst = other.amp_max_rel, other.amp_worst
        if other.worst_fraction > self.worst_fraction:
            self.worst_fraction = other.worst_fraction
            self.worst_fraction_case = other.worst_fraction_case
        self.failures.extend(other.failures)

    def fail(self, case: str, what: str) -> None:
        self.failures.append(f"{case}: {what}")


def _finite(*arrays) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, dtype=np.float64))) for a in arrays)


def _table_arrays(t) -> tuple:
    return (t.tx, t.rx, t.tof_s, t.amplitude, t.kind, t.order, t.point, t.element)


def _same_table(a, b) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in
                                    zip(_table_arrays(a), _table_arrays(b), strict=True))


@contextlib.contextmanager
def echo_work_group(size: int) -> Iterator[None]:
    """Run the echo kernels with work groups of ``size`` along the elements."""
    saved = echo_host.WORK_GROUP
    echo_host.WORK_GROUP = size
    try:
        yield
    finally:
        echo_host.WORK_GROUP = saved


@contextlib.contextmanager
def map_launch(vec: int, group: tuple[int, int], tile: tuple[int, int]) -> Iterator[None]:
    """Run the map kernels with ``vec`` pixels per work item in work groups of ``group``
    (dense kernels) and tiles of ``tile`` pixels, one work group each (tiled kernel)."""
    saved = dict(mapping.LAUNCH), dict(getattr(mapping, "TILES", {}))
    for key in mapping.LAUNCH:
        mapping.LAUNCH[key] = (vec if key[0] == "CPU" else 1, group)
    for key in getattr(mapping, "TILES", {}):
        mapping.TILES[key] = tile
    try:
        yield
    finally:
        mapping.LAUNCH.clear()
        mapping.LAUNCH.update(saved[0])
        if hasattr(mapping, "TILES"):
            mapping.TILES.clear()
            mapping.TILES.update(saved[1])


def check_echo_case(family: str, seed: int, context, *, many: int = 40,
                    work_groups: bool = False) -> Findings:
    """Compare the float32 echo kernels with the float64 reference on one case."""
    name = f"echo {family} seed={seed}"
    scene = echo_scene(family, seed, many=many)
    f = Findings(cases=1)
    ref = echoes_mod.reference_echoes(scene)
    got = echoes_mod.compute_echoes(scene, context=context, precision="float32")
    for label, t in (("reference", ref), ("float32", got)):
        if not _finite(t.tof_s, t.amplitude, t.point):
            f.nonfinite += 1
            f.fail(name, f"NaN or Inf in the {label} echo table")
            return f
    n_circles = _n_circles(scene)
    matched, ref_only, got_only = match_echoes(ref, got, n_circles)
    f.echoes = len(ref)
    if matched:
        i, j = np.asarray(matched).T
        err = np.abs(got.tof_s[j] - ref.tof_s[i])
        k = int(np.argmax(err))
        f.tof_max_s = float(err[k])
        f.tof_worst = (f"{name} pair {ref.tx[i[k]]}->{ref.rx[i[k]]} "
                       f"{echoes_mod.KINDS[ref.kind[i[k]]]}")
        rel = np.abs(got.amplitude[j] - ref.amplitude[i]) / ref.amplitude[i]
        k = int(np.argmax(rel))
        f.amp_max_rel = float(rel[k])
        f.amp_worst = (f"{name} pair {ref.tx[i[k]]}->{ref.rx[i[k]]} "
                       f"{echoes_mod.KINDS[ref.kind[i[k]]]} A={ref.amplitude[i[k]]:.3g}")
        if f.tof_max_s > BOUNDS["tof_abs_s"]:
            f.fail(name, f"time of flight differs by {f.tof_max_s:.3g} s > 1 µs ({f.tof_worst})")
    if ref_only or got_only:
        edge = _edge_echo_keys(scene)
        keys_ref, keys_got = _keys(ref), _keys(got)
        weak = BOUNDS["weak_echo"] * scene.transducer.amplitude
        lonely = ([(keys_ref[i], ref.amplitude[i]) for i in ref_only]
                  + [(keys_got[j], got.amplitude[j]) for j in got_only])
        for key, amp in lonely:
            if any(k in edge for k in _near_keys(key, n_circles)):
                f.unmatched_edge += 1
            elif amp < weak:
                f.unmatched_weak += 1
            else:
                f.unmatched_other += 1
                f.fail(name, f"echo {key} in one table only, and not on a knife edge")
    if work_groups:
        for size in ALT_ECHO_GROUPS:
            with echo_work_group(size):
                again = echoes_mod.compute_echoes(scene, context=context, precision="float32")
            if not _same_table(got, again):
                f.work_group_mismatches += 1
                f.fail(name, f"work groups of {size} give another echo table")
    return f


# --------------------------------------------------------------------------- judging signals

#: Echo families whose scenes also drive the detection check (``many`` has too many pairs
#: for the NumPy reference's A-scans).
SIGNAL_FAMILIES = tuple(f for f in ECHO_FAMILIES if f != "many")

#: Alternative work-group sizes of the detection kernels. (Other chunk lengths, samples per
#: work item, restart the running sums elsewhere: detections move by float32 rounding,
#: ~10⁻¹⁰ s, so they are not compared bit for bit.)
ALT_SIGNAL_GROUPS = (8, 1)


def signal_scene(family: str, seed: int) -> Scene:
    """The echo case's scene with a random detector (threshold or envelope) and noise."""
    rng = np.random.default_rng([seed, 200 + ECHO_FAMILIES.index(family)])
    scene = echo_scene(family, seed)
    mode = str(rng.choice(["threshold", "envelope"]))
    noise = float(rng.choice([0.0, 0.0, 0.3, 1.0]))
    return replace(scene, detection=replace(scene.detection, mode=mode),
                   signal=replace(scene.signal, noise_std=noise, seed=int(seed)))


def _match_detections(ref, got) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """Pair detections of one (tx, rx) by nearest time of flight, closest pairs first."""
    by_pair: dict[tuple[int, int], list[int]] = {}
    for j, key in enumerate(zip(got.tx.tolist(), got.rx.tolist(), strict=True)):
        by_pair.setdefault(key, []).append(j)
    candidates = []
    for i, key in enumerate(zip(ref.tx.tolist(), ref.rx.tolist(), strict=True)):
        candidates += [(abs(got.tof_s[j] - ref.tof_s[i]), i, j) for j in by_pair.get(key, [])]
    used_i, used_j, matched = set(), set(), []
    for gap, i, j in sorted(candidates):
        if i not in used_i and j not in used_j and gap <= 10 * BOUNDS["tof_abs_s"]:
            used_i.add(i)
            used_j.add(j)
            matched.append((i, j))
    return (matched, [i for i in range(len(ref)) if i not in used_i],
            [j for j in range(len(got)) if j not in used_j])


def _nudged(table, rng: np.random.Generator, rel: float):
    """``table`` with amplitudes and times of flight off by float32-sized relative amounts."""
    return replace(table, amplitude=table.amplitude * (1 + rng.uniform(-rel, rel, len(table))),
                   tof_s=table.tof_s * (1 + rng.uniform(-rel, rel, len(table))))


def _edge_detections(scene: Scene, echoes, sensors, jitters: int = 6) -> set[tuple]:
    """(tx, rx, tof rounded to 10 µs) of detections that the float64 reference gains or
    loses when the echoes' amplitudes and times move by a few float32 roundings: threshold
    crossings and peak merges decided by rounding."""
    from .. import signals

    def keys(d) -> set[tuple]:
        return {(t, r, round(x * 1e5)) for t, r, x in
                zip(d.tx.tolist(), d.rx.tolist(), d.tof_s.tolist(), strict=True)}

    base = keys(signals.detect_reference(scene, sensors, echoes))
    rng = np.random.default_rng(1)
    unstable: set[tuple] = set()
    for _ in range(jitters):
        nudged = _nudged(echoes, rng, BOUNDS["edge_roundings"] * EPS32)
        unstable |= base ^ keys(signals.detect_reference(scene, sensors, nudged))
    return unstable


def check_signal_case(family: str, seed: int, context, *, work_groups: bool = False
                      ) -> Findings:
    """Compare the float32 detection kernels (kernels/signals.cl) with the float64 reference
    (:func:`clsonar.signals.detect_reference`) on the float64 echoes of one case."""
    from .. import signals
    from ..sensors import place_sensors

    name = f"signal {family} seed={seed}"
    scene = signal_scene(family, seed)
    sensors = place_sensors(scene)
    echoes = echoes_mod.reference_echoes(scene, sensors)
    f = Findings(cases=1)
    ref = signals.detect_reference(scene, sensors, echoes)
    got = signals.detect(scene, sensors, echoes, context=context)
    for label, d in (("reference", ref), ("float32", got)):
        if not _finite(d.tof_s, d.amplitude):
            f.nonfinite += 1
            f.fail(name, f"NaN or Inf in the {label} detections")
            return f
    matched, ref_only, got_only = _match_detections(ref, got)
    f.echoes = len(ref)
    if matched:
        i, j = np.asarray(matched).T
        err = np.abs(got.tof_s[j] - ref.tof_s[i])
        k = int(np.argmax(err))
        f.tof_max_s = float(err[k])
        f.tof_worst = f"{name} pair {ref.tx[i[k]]}->{ref.rx[i[k]]} ({scene.detection.mode})"
        if f.tof_max_s > BOUNDS["tof_abs_s"]:
            f.fail(name, f"detected time of flight differs by {f.tof_max_s:.3g} s > 1 µs")
    if ref_only or got_only:
        edge = _edge_detections(scene, echoes, sensors)
        lonely = ([(ref.tx[i], ref.rx[i], ref.tof_s[i]) for i in ref_only]
                  + [(got.tx[j], got.rx[j], got.tof_s[j]) for j in got_only])
        for t, r, x in lonely:
            if any((int(t), int(r), round(x * 1e5) + dx) in edge for dx in (-1, 0, 1)):
                f.unmatched_edge += 1
            else:
                f.unmatched_other += 1
                f.fail(name, f"detection {t}->{r} at {x:.7g} s in one list only, and not "
                             "on a knife edge")
    if work_groups:
        for group in ALT_SIGNAL_GROUPS:
            again = signals.detect(scene, sensors, echoes, context=context, work_group=group)
            if not all(np.array_equal(a, b) for a, b in zip(
                    (got.tx, got.rx, got.tof_s, got.amplitude),
                    (again.tx, again.rx, again.tof_s, again.amplitude), strict=True)):
                f.work_group_mismatches += 1
                f.fail(name, f"work groups of {group} detect otherwise")
    return f


# --------------------------------------------------------------------------- judging maps


def edge_pixels(pb: mapping.MapProblem, iy: np.ndarray, ix: np.ndarray,
                loci: bool = True) -> np.ndarray:
    """For pixels ``(iy, ix)`` of problem ``pb``: is the pixel, for some row, within
    ``edge_roundings`` float32 roundings of a band edge (loci) or of a beam edge, in float64?

    A float32 coordinate carries an error ≈ ε·S (S the largest local coordinate involved), so
    a distance d an error ≈ 2ε·S, the path an error ≈ ε·(4S + path), sin²θ·|d|² an error
    ≈ 2ε·|d|·(|d| + 2S). The beam edges are ``axis·d > 0`` and ``(axis×d)² ≤ cut·|d|²``
    (mapping.py); the band edge ``| path − c·τ | = band/2``.
    """
    g = pb.grid
    k = BOUNDS["edge_roundings"] * EPS32
    px = ((g.col0 + ix).astype(np.float64) * g.cell)[:, None]
    py = ((g.row0 + iy).astype(np.float64) * g.cell)[:, None]
    out = np.zeros(len(iy), dtype=bool)
    for start in range(0, len(pb.rows), 4096):
        r = pb.rows[start:start + 4096].T
        scale = np.maximum(np.abs(px) + np.abs(py),
                           np.maximum(np.abs(r[0]) + np.abs(r[1]), np.abs(r[2]) + np.abs(r[3])))
        near = np.zeros((len(iy), r.shape[1]), dtype=bool)
        for fx, fy, ax, ay in ((r[0], r[1], r[4], r[5]), (r[2], r[3], r[6], r[7])):
            dx, dy = px - fx, py - fy
            dd = dx * dx + dy * dy
            d = np.sqrt(dd)
            cos_d = ax * dx + ay * dy
            sin_d = ax * dy - ay * dx
            near |= np.abs(cos_d) <= k * (d + scale)
            near |= np.abs(sin_d * sin_d - pb.cut_sin2 * dd) <= 2 * k * d * (d + 2 * scale)
        if loci:
            path = (np.hypot(px - r[0], py - r[1]) + np.hypot(px - r[2], py - r[3]))
            near |= (np.abs(np.abs(path - r[8]) - pb.half_band)
                     <= k * (4 * scale + path + np.abs(r[8])))
        out |= near.any(axis=1)
    return out


def value_tolerance(pb: mapping.MapProblem, ref: np.ndarray) -> np.ndarray:
    """Per pixel, the difference between float32 and float64 values that rounding alone
    explains: a sum of n terms rounds to ≈ √n·ε relative (``value_rtol`` at least), and a
    back-projected envelope read at a delay off by δ samples changes by its slope times δ,
    δ from the path's float32 error (see :func:`edge_pixels`)."""
    n = max(len(pb.rows), 1)
    rtol = max(BOUNDS["value_rtol"], 64 * EPS32 * math.sqrt(n))
    tol = rtol * (np.abs(ref) + 1e-2 * (np.abs(ref).max() if ref.size else 0.0))
    if pb.envelopes is not None and pb.envelopes.size:
        g = pb.grid
        far = (max(abs(g.col0), g.nx + g.col0) + max(abs(g.row0), g.ny + g.row0)) * g.cell
        far = max(far, float(np.abs(pb.rows[:, :4]).max()) if len(pb.rows) else 0.0)
        delay = BOUNDS["edge_roundings"] * EPS32 * 8 * far * pb.inv_c_dt
        slope = np.abs(np.diff(pb.envelopes, axis=1)).max(axis=1)
        tol = tol + float(np.sum(slope)) * (delay + 1e-3)
    return tol


def _beam_slope(pb: mapping.MapProblem) -> float:
    """max |d(b(θ))/dθ| inside the beam cut (rad⁻¹), b the kernels' beam series."""
    theta = np.linspace(0.0, math.asin(math.sqrt(min(pb.cut_sin2, 1.0))), 2001)
    b = mapping._ref_beam(np.sin(theta) ** 2, pb.beam_u)
    return float(np.max(np.abs(np.diff(b)) / np.diff(theta)))


def beam_slack(pb: mapping.MapProblem, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """For pixels ``(iy, ix)`` of a ``weight = "beam"`` problem: how much b(θ_T)·b(θ_R)
    summed over the rows that vote there (or nearly) can change when each direction p − T,
    p − R is off by its float32 error, ≈ 2ε·S/|d| rad (S the largest local coordinate,
    :func:`edge_pixels`): the beam's slope times that angle, per transducer."""
    g = pb.grid
    k = BOUNDS["edge_roundings"] * EPS32
    slope = _beam_slope(pb)
    px = ((g.col0 + ix).astype(np.float64) * g.cell)[:, None]
    py = ((g.row0 + iy).astype(np.float64) * g.cell)[:, None]
    out = np.zeros(len(iy))
    for start in range(0, len(pb.rows), 4096):
        r = pb.rows[start:start + 4096].T
        scale = np.maximum(np.abs(px) + np.abs(py),
                           np.maximum(np.abs(r[0]) + np.abs(r[1]), np.abs(r[2]) + np.abs(r[3])))
        d_t = np.hypot(px - r[0], py - r[1])
        d_r = np.hypot(px - r[2], py - r[3])
        near = np.abs(d_t + d_r - r[8]) <= pb.half_band * (1 + 1e-3) + k * (4 * scale + r[8])
        angle = k * (scale / np.maximum(d_t, 1e-30) + scale / np.maximum(d_r, 1e-30))
        out += np.sum(np.where(near, np.minimum(slope * angle, 1.0), 0.0), axis=1)
    return out


def compare_maps(pb: mapping.MapProblem, ref: np.ndarray, got: np.ndarray, name: str,
                 loci: bool = True) -> Findings:
    """Judge a float32 map ``got`` against its float64 twin ``ref``: values within
    :func:`value_tolerance` (plus :func:`beam_slack` for beam weights), other pixels on an
    edge (:func:`edge_pixels`)."""
    f = Findings(cases=1, pixels=int(ref.size))
    if not (_finite(got) and _finite(ref)):
        f.nonfinite += 1
        f.fail(name, "NaN or Inf in a map")
        return f
    if got.shape != ref.shape:
        f.fail(name, f"map shape {got.shape} ≠ {ref.shape}")
        return f
    delta = np.abs(got.astype(np.float64) - ref)
    differ = delta > value_tolerance(pb, ref)
    if loci and pb.weight == "beam" and np.any(differ):  # the beam weight's own rounding
        iy, ix = np.nonzero(differ)
        differ[iy, ix] = delta[iy, ix] > (value_tolerance(pb, ref)[iy, ix]
                                          + beam_slack(pb, iy, ix))
    iy, ix = np.nonzero(differ)
    f.differing = len(iy)
    f.worst_fraction = f.differing / max(ref.size, 1)
    f.worst_fraction_case = name
    if f.differing:
        on_edge = edge_pixels(pb, iy, ix, loci)
        f.differing_off_edge = int(np.count_nonzero(~on_edge))
        if f.differing_off_edge:
            where = list(zip(iy[~on_edge][:3].tolist(), ix[~on_edge][:3].tolist(), strict=True))
            f.fail(name, f"{f.differing_off_edge} pixels differ off every edge, e.g. {where}")
    if f.worst_fraction > BOUNDS["map_differing_fraction"] and ref.size >= 10_000:
        f.fail(name, f"{f.worst_fraction:.2%} of the pixels differ")
    return f


def check_map_case(family: str, seed: int, context, *, million: int = MILLION,
                   work_groups: bool = False) -> Findings:
    """Compare the float32 map kernel with float64 on one case: with the NumPy reference,
    or, for the ``million`` family, with the float64 kernel (bit-identical to the reference,
    tests/test_mapping.py) where the device has ``cl_khr_fp64``."""
    from ..opencl import has_fp64

    name = f"map {family} seed={seed}"
    case = map_case(family, seed, million=million)
    scene, sensors = case.scene, case.sensors
    if case.pairs is not None:
        args = (scene, sensors, case.pairs, case.envelopes, case.dt)
        pb = mapping.prepare_backprojection(*args)
        ref = mapping.backproject_reference(*args)
        run = lambda: mapping.backproject(*args, context=context, precision="float32")  # noqa: E731
        loci = False
    else:
        pb = mapping.prepare_loci(scene, sensors, case.loci)
        if family == "million":
            if not has_fp64(context):
                return Findings()
            ref = mapping.accumulate(scene, sensors, case.loci, context=context,
                                     precision="float64")
        else:
            ref = mapping.accumulate_reference(scene, sensors, case.loci)
        run = lambda: mapping.accumulate(scene, sensors, case.loci, context=context,  # noqa: E731
                                         precision="float32")
        loci = True
    got = run()
    f = compare_maps(pb, ref, got, name, loci)
    if work_groups:
        for vec, group, tile in ALT_MAP_LAUNCH:
            with map_launch(vec, group, tile):
                again = run()
            if not np.array_equal(got, again):
                f.work_group_mismatches += 1
                f.fail(name, f"{vec} pixels per item in groups of {group}, tiles of {tile}, "
                             "give another map")
        if loci and "tiles" in inspect.signature(mapping.accumulate).parameters:
            dense = mapping.accumulate(scene, sensors, case.loci, context=context,
                                       precision="float32", tiles=False)
            if not np.array_equal(got, dense):
                f.work_group_mismatches += 1
                f.fail(name, "the dense kernel gives another map than the tiled one")
    return f


__all__ = ["BOUNDS", "ECHO_FAMILIES", "MAP_FAMILIES", "MILLION", "SIGNAL_FAMILIES", "Findings",
           "MapCase", "check_echo_case", "check_map_case", "check_signal_case", "compare_maps",
           "echo_scene", "edge_pixels", "map_case", "match_echoes", "signal_scene"]
