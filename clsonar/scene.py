"""Scene file format v1: load, validate and save (DESIGN.md, "Scene file format v1").

A scene is a tree of frozen dataclasses, so scenes compare with ``==`` and hash (the
pipeline's cache keys on them). :func:`load_scene` reads JSON and validates every key;
any problem raises :class:`~clsonar.errors.SceneError` naming the file and the key path,
e.g. ``room.json: surfaces[2].radius: must be > 0``. :func:`save_scene` writes the full
normalised form (every default spelled out) atomically, so load → save → load gives an
identical scene.

Optional keys and their defaults (all units SI, angles in degrees where the key says so):

``medium``      ``temperature_k`` 293.15; ``speed_of_sound`` (m/s) overrides eq. 2.1 if set.
``transducer``  ``frequency_hz`` 50000, ``radius_m`` 0.02, ``half_beam_deg`` 12.0,
                ``amplitude`` 5.0, ``pulse_sigma_s`` ≈ 54 µs (see physics.DEFAULT_PULSE_SIGMA_S),
                ``directivity`` "piston" (or "uniform", the thesis' flat sensitivity).
``signal``      ``noise_std`` 0.0, ``threshold`` 4.0, ``seed`` 1.
``echo``        ``max_order`` 2 (reflections on flat walls), ``reflection_coefficient`` 0.9,
                ``edge_coefficient`` 1.0, ``absorption_db_per_m`` 0.0, ``curve_step_m`` 0.01
                (sampling of curved surfaces, see geometry.py), ``curvature_gain`` true.
``detection``, ``mapping``, ``post``: see :class:`DetectionSettings`,
                :class:`MappingSettings`, :class:`PostSettings`.
``sensors``     ``transducers`` [] and ``placement`` null; placements are documented with
                their dataclasses below and implemented in sensors.py.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal

from .errors import SceneError
from .files import read_text, write_atomic
from .physics import (
    DEFAULT_PULSE_SIGMA_S,
    DEFAULT_REFLECTION_COEFFICIENT,
    beam_constants,
    speed_of_sound,
)

FORMAT_VERSION = 1

#: Largest scene file read, in bytes: anything bigger is refused before parsing.

#: Deepest JSON nesting accepted (the format needs 5 levels).
MAX_DEPTH = 16

#: Most JSON objects and lists (``{``/``[``, counted before parsing, strings included) and
#: most list items (``,``) a scene may have: 50 000 points of polylines, so that any file is
#: parsed and checked well within a second.
MAX_CONTAINERS = 50_000
MAX_SEPARATORS = 200_000

#: Largest magnitude of a real-valued setting or coordinate (metres, seconds, hertz, …):
#: anything beyond is a typo, and would overflow the geometry's float64 products.
MAX_MAGNITUDE = 1e9

#: Shortest wall segment, sinusoid base line and circle radius, metres (shorter ones
#: underflow the geometry's squared lengths).
MIN_LENGTH_M = 1e-6

#: Most cells a map may have along x or y: more is refused on reading (a grid too large for
#: any memory; mapping.check_map_memory judges the device and this machine).
MAX_CELLS_PER_SIDE = 1e9

Point = tuple[float, float]


# --------------------------------------------------------------------------- surfaces


@dataclass(frozen=True)
class Polyline:
    """Flat walls through ``points``; ``closed`` makes it a room whose interior is free space."""

    points: tuple[Point, ...]
    closed: bool = False


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


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class Medium:
    temperature_k: float = 293.15
    speed_of_sound: float | None = None

    @property
    def c(self) -> float:
        """Speed of sound in m/s: the override if given, else thesis eq. 2.1."""
        if self.speed_of_sound is not None:
            return self.speed_of_sound
        return speed_of_sound(self.temperature_k)


@dataclass(frozen=True)
class TransducerModel:
    """The Polaroid 6500 series transducer of thesis §2.1 (50 kHz, 4 cm diameter, ±12°)."""

    frequency_hz: float = 50000.0
    radius_m: float = 0.02
    half_beam_deg: float = 12.0
    amplitude: float = 5.0
    pulse_sigma_s: float = DEFAULT_PULSE_SIGMA_S
    directivity: Literal["piston", "uniform"] = "piston"

    def beam(self, c: float) -> tuple[float, float]:
        """``(cut_sin2, ka)`` for :func:`clsonar.physics.beam_pattern`."""
        return beam_constants(self.frequency_hz, self.radius_m, self.half_beam_deg,
                              self.directivity, c)


@dataclass(frozen=True)
class Signal:
    noise_std: float = 0.0
    threshold: float = 4.0
    seed: int = 1


@dataclass(frozen=True)
class EchoModel:
    """Settings of the echo engine; see physics.py for the amplitude model.

    ``curvature_gain`` false makes curved surfaces reflect as strongly as flat ones, as in
    the thesis' ray tracing (its scenes use it with ``transducer.directivity`` uniform).
    """

    max_order: int = 2
    reflection_coefficient: float = DEFAULT_REFLECTION_COEFFICIENT
    edge_coefficient: float = 1.0
    absorption_db_per_m: float = 0.0
    curve_step_m: float = 0.01
    curvature_gain: bool = True


@dataclass(frozen=True)
class DetectionSettings:
    """How times of flight are found in each pair's received signal (thesis §2.1.1, 3–4).

    ``threshold``: as the thesis: the first sample above ``signal.threshold`` gives the time
    of flight; for T = R only that first crossing (the line-of-sight arc), for T ≠ R every
    crossing (after a hold-off of one pulse length, 6σ). ``envelope``: quadrature
    demodulation and a matched low-pass give the envelope, whose peaks above a
    noise-adaptive threshold (``false_alarm_sigmas`` times the estimated envelope noise, at
    least ``min_envelope`` units) give the time of flight as peak − 3σ (no threshold bias).
    """

    mode: Literal["threshold", "envelope"] = "envelope"
    sample_rate_hz: float = 1.0e6
    false_alarm_sigmas: float = 6.0
    min_envelope: float = 1.0


@dataclass(frozen=True)
class MappingSettings:
    """How detections become a map (thesis §2.1.1, 3–4).

    ``mode``:

    - ``loci`` (the thesis): every pixel p gets a vote from each detection whose time of
      flight τ puts p on its locus, ``| |p−T| + |p−R| − c·τ | ≤ band_m/2``, inside both beams
      (a circle for T = R, an ellipse otherwise); ``band_m`` null means 2√2·cell (loci at
      least √2 cells thick). ``weight``: ``unit`` (the thesis), ``amplitude`` (the detected
      amplitude) or ``beam`` (b(θ_T)·b(θ_R) at the pixel). ``combine``: ``sum`` adds the
      votes (the thesis); ``viewpoints`` counts the viewpoints (pair groups: an array, a
      ring pose) with a locus through each cell.
    - ``tangents`` (ours): the points where loci of neighbouring transducers of one viewpoint
      cross, which lie on the surface to within δ²/(8r) (mapping.tangent_points), with the
      loci's tangent segments around them, counted per cell. A locus that crosses none keeps
      the middle of its in-beam arc within ``isolated_bias_m`` of its tangent (0: dropped),
      which suits transducers that face the surface squarely, as a wall-following ring does.
    - ``backprojection``: the sum over pairs of each pair's envelope at the pixel's delay
      (delay-and-sum, "total focusing").

    ``reciprocal``: ``merge`` makes the detections of (T, R) and (R, T) — one path measured
    twice — one locus with their mean time of flight; ``both`` draws both (the thesis).
    ``precision``: the kernels' arithmetic. ``line_of_sight`` (``tangents`` only): drop the
    points that the map itself shows hidden behind a surface from their transducers — the
    ghosts of multiply reflected echoes (rooms.line_of_sight).
    """

    mode: Literal["loci", "tangents", "backprojection"] = "tangents"
    weight: Literal["unit", "amplitude", "beam"] = "unit"
    band_m: float | None = None
    precision: Literal["float32", "float64"] = "float32"
    reciprocal: Literal["merge", "both"] = "merge"
    combine: Literal["sum", "viewpoints"] = "viewpoints"
    isolated_bias_m: float = 0.0
    line_of_sight: bool = True


@dataclass(frozen=True)
class PostSettings:
    """Post-processing of the map (thesis §2.1.1, 5): low-pass, thinning, profile fit.

    ``filter``: ``mean3`` (eq. 2.4) or ``none``; ``level``: occupied cells of the filtered
    map, as a fraction of its maximum (null: automatic); ``thinning``: ``thesis`` (eq. 2.5
    as written) or ``guo-hall`` (one-pixel 8-connected curves); ``fit``: ``polynomial`` of
    ``poly_order`` along a single wall (the thesis: 5–8), ``spline`` along each linked curve
    (rooms too), ``walls`` (rooms: straight walls where the data are straight, extended to
    meet at corners and edges within ``join_m`` of their ends, splines elsewhere;
    rooms.fit_walls) or ``none``; curves closer than ``max_gap_m`` are bridged; ``subcell``
    moves each thin cell to the vote-weighted centroid of the filtered map around it.
    """

    filter: Literal["mean3", "none"] = "mean3"
    level: float | None = None
    thinning: Literal["thesis", "guo-hall"] = "guo-hall"
    fit: Literal["polynomial", "spline", "walls", "none"] = "spline"
    poly_order: int = 7
    max_gap_m: float = 0.3
    subcell: bool = True
    join_m: float = 0.5


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
    start_deg: float = 0.0
    direction: Literal["ccw", "cw"] = "ccw"
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


# --------------------------------------------------------------------------- reading

_MISSING: Any = object()


class _Reader:
    """Typed access to a parsed JSON tree that fails with the key path of the bad value."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, message: str) -> SceneError:
        return SceneError(message, key, self.source)

    def obj(self, value: Any, key: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()):
        if not isinstance(value, dict):
            raise self.fail(key, f"must be an object, not {_type_name(value)}")
        for k in value:
            if k not in allowed:
                raise self.fail(_join(key, k), f"unknown key (allowed: {', '.join(allowed)})")
        for k in required:
            if k not in value:
                raise self.fail(_join(key, k), "missing required key")
        return value

    def number(self, d: dict, name: str, key: str, default: Any = _MISSING, *,
               gt: float | None = None, ge: float | None = None, le: float | None = None,
               lt: float | None = None) -> float:
        path = _join(key, name)
        if name not in d:
            if default is _MISSING:
                raise self.fail(path, "missing required key")
            return default
        return self._bounded(self.check_number(d[name], path, gt=gt, ge=ge, le=le, lt=lt), path)

    def _bounded(self, v: float, path: str) -> float:
        if abs(v) > MAX_MAGNITUDE:
            raise self.fail(path, f"{v:.3g} is out of range (at most ±{MAX_MAGNITUDE:.0e})")
        return v

    def check_number(self, v: Any, path: str, *, gt: float | None = None,
                     ge: float | None = None, le: float | None = None,
                     lt: float | None = None) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(path, f"must be a number, not {_type_name(v)}")
        v = float(v)
        if not math.isfinite(v):
            raise self.fail(path, "must be a finite number")
        checks = ((gt, ">", v > (gt or 0.0)), (ge, ">=", v >= (ge or 0.0)),
                  (lt, "<", v < (lt or 0.0)), (le, "<=", v <= (le or 0.0)))
        for bound, word, ok in checks:
            if bound is not None and not ok:
                raise self.fail(path, f"must be {word} {bound:g}")
        return v

    def integer(self, d: dict, name: str, key: str, default: Any = _MISSING, *,
                ge: int | None = None, le: int | None = None) -> int:
        path = _join(key, name)
        if name not in d:
            if default is _MISSING:
                raise self.fail(path, "missing required key")
            return default
        v = d[name]
        if isinstance(v, float) and v.is_integer() and abs(v) < 2**53:
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(path, f"must be an integer, not {_type_name(v)}")
        if ge is not None and v < ge:
            raise self.fail(path, f"must be >= {ge}")
        if le is not None and v > le:
            raise self.fail(path, f"must be <= {le}")
        return v

    def boolean(self, d: dict, name: str, key: str, default: bool) -> bool:
        v = d.get(name, default)
        if not isinstance(v, bool):
            raise self.fail(_join(key, name), f"must be true or false, not {_type_name(v)}")
        return v

    def choice(self, d: dict, name: str, key: str, options: tuple[str, ...],
               default: Any = _MISSING) -> str:
        path = _join(key, name)
        if name not in d:
            if default is _MISSING:
                raise self.fail(path, "missing required key")
            return default
        v = d[name]
        if v not in options or not isinstance(v, str):
            raise self.fail(path, f"must be one of {', '.join(map(repr, options))}, not {v!r:.40}")
        return v

    def vector(self, v: Any, path: str, length: int) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) != length:
            raise self.fail(path, f"must be a list of {length} numbers")
        return tuple(self._bounded(self.check_number(x, f"{path}[{i}]"), f"{path}[{i}]")
                     for i, x in enumerate(v))

    def point(self, d: dict, name: str, key: str, default: Any = _MISSING) -> Point:
        path = _join(key, name)
        if name not in d or (d[name] is None and default is None):
            if default is _MISSING:
                raise self.fail(path, "missing required key")
            return default
        return self.vector(d[name], path, 2)  # type: ignore[return-value]

    def interval(self, d: dict, name: str, key: str, default: tuple[float, float],
                 *, gt: float | None = None) -> tuple[float, float]:
        path = _join(key, name)
        if name not in d:
            return default
        lo, hi = self.vector(d[name], path, 2)
        if gt is not None and lo <= gt:
            raise self.fail(f"{path}[0]", f"must be > {gt:g}")
        if hi < lo:
            raise self.fail(path, "upper bound must be >= lower bound")
        return (lo, hi)


def _join(key: str, name: str | int) -> str:
    if isinstance(name, int):
        return f"{key}[{name}]"
    return f"{key}.{name}" if key else name


def _type_name(v: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean",
            type(None): "null", int: "a number", float: "a number"}.get(type(v), type(v).__name__)


def _read_medium(r: _Reader, d: Any) -> Medium:
    d = r.obj(d, "medium", ("temperature_k", "speed_of_sound"))
    t = r.number(d, "temperature_k", "medium", Medium.temperature_k, gt=0)
    c = None
    if d.get("speed_of_sound") is not None:
        c = r.number(d, "speed_of_sound", "medium", gt=0)
    return Medium(t, c)


def _read_transducer(r: _Reader, d: Any) -> TransducerModel:
    k = "transducer"
    d = r.obj(d, k, tuple(f.name for f in fields(TransducerModel)))
    m = TransducerModel(
        frequency_hz=r.number(d, "frequency_hz", k, TransducerModel.frequency_hz, gt=0),
        radius_m=r.number(d, "radius_m", k, TransducerModel.radius_m, gt=0),
        half_beam_deg=r.number(d, "half_beam_deg", k, TransducerModel.half_beam_deg, gt=0, le=90),
        amplitude=r.number(d, "amplitude", k, TransducerModel.amplitude, gt=0),
        pulse_sigma_s=r.number(d, "pulse_sigma_s", k, TransducerModel.pulse_sigma_s, gt=0),
        directivity=r.choice(d, "directivity", k, ("piston", "uniform"),  # type: ignore[arg-type]
                             TransducerModel.directivity),
    )
    return m


def _read_signal(r: _Reader, d: Any) -> Signal:
    k = "signal"
    d = r.obj(d, k, ("noise_std", "threshold", "seed"))
    return Signal(
        noise_std=r.number(d, "noise_std", k, Signal.noise_std, ge=0),
        threshold=r.number(d, "threshold", k, Signal.threshold, gt=0),
        seed=r.integer(d, "seed", k, Signal.seed, ge=0, le=2**63 - 1),
    )


def _read_echo(r: _Reader, d: Any) -> EchoModel:
    k = "echo"
    d = r.obj(d, k, tuple(f.name for f in fields(EchoModel)))
    return EchoModel(
        max_order=r.integer(d, "max_order", k, EchoModel.max_order, ge=1, le=4),
        reflection_coefficient=r.number(d, "reflection_coefficient", k,
                                        EchoModel.reflection_coefficient, ge=0, le=1),
        edge_coefficient=r.number(d, "edge_coefficient", k, EchoModel.edge_coefficient, ge=0),
        absorption_db_per_m=r.number(d, "absorption_db_per_m", k,
                                     EchoModel.absorption_db_per_m, ge=0),
        curve_step_m=r.number(d, "curve_step_m", k, EchoModel.curve_step_m, gt=0),
        curvature_gain=r.boolean(d, "curvature_gain", k, EchoModel.curvature_gain),
    )


def _read_detection(r: _Reader, d: Any) -> DetectionSettings:
    k, ds = "detection", DetectionSettings
    d = r.obj(d, k, tuple(f.name for f in fields(ds)))
    return DetectionSettings(
        mode=r.choice(d, "mode", k, ("threshold", "envelope"), ds.mode),  # type: ignore[arg-type]
        sample_rate_hz=r.number(d, "sample_rate_hz", k, ds.sample_rate_hz, gt=0),
        false_alarm_sigmas=r.number(d, "false_alarm_sigmas", k, ds.false_alarm_sigmas, gt=0),
        min_envelope=r.number(d, "min_envelope", k, ds.min_envelope, ge=0),
    )


def _read_mapping(r: _Reader, d: Any) -> MappingSettings:
    k, ms = "mapping", MappingSettings
    d = r.obj(d, k, tuple(f.name for f in fields(ms)))
    band = None if d.get("band_m") is None else r.number(d, "band_m", k, gt=0)
    return MappingSettings(
        mode=r.choice(d, "mode", k, ("loci", "tangents", "backprojection"),  # type: ignore[arg-type]
                      ms.mode),
        weight=r.choice(d, "weight", k, ("unit", "amplitude", "beam"), ms.weight),  # type: ignore[arg-type]
        band_m=band,
        precision=r.choice(d, "precision", k, ("float32", "float64"), ms.precision),  # type: ignore[arg-type]
        reciprocal=r.choice(d, "reciprocal", k, ("merge", "both"), ms.reciprocal),  # type: ignore[arg-type]
        combine=r.choice(d, "combine", k, ("sum", "viewpoints"), ms.combine),  # type: ignore[arg-type]
        isolated_bias_m=r.number(d, "isolated_bias_m", k, ms.isolated_bias_m, ge=0),
        line_of_sight=r.boolean(d, "line_of_sight", k, ms.line_of_sight),
    )


def _read_post(r: _Reader, d: Any) -> PostSettings:
    k, ps = "post", PostSettings
    d = r.obj(d, k, tuple(f.name for f in fields(ps)))
    level = None if d.get("level") is None else r.number(d, "level", k, gt=0, le=1)
    return PostSettings(
        filter=r.choice(d, "filter", k, ("mean3", "none"), ps.filter),  # type: ignore[arg-type]
        level=level,
        thinning=r.choice(d, "thinning", k, ("thesis", "guo-hall"), ps.thinning),  # type: ignore[arg-type]
        fit=r.choice(d, "fit", k, ("polynomial", "spline", "walls", "none"), ps.fit),  # type: ignore[arg-type]
        poly_order=r.integer(d, "poly_order", k, ps.poly_order, ge=1, le=12),
        max_gap_m=r.number(d, "max_gap_m", k, ps.max_gap_m, ge=0),
        subcell=r.boolean(d, "subcell", k, ps.subcell),
        join_m=r.number(d, "join_m", k, ps.join_m, ge=0),
    )


def _read_polyline(r: _Reader, d: dict, key: str) -> Polyline:
    d = r.obj(d, key, ("type", "points", "closed"), ("points",))
    raw = d["points"]
    path = _join(key, "points")
    closed = r.boolean(d, "closed", key, False)
    if not isinstance(raw, list):
        raise r.fail(path, f"must be a list of [x, y] points, not {_type_name(raw)}")
    points = tuple(r.vector(p, f"{path}[{i}]", 2) for i, p in enumerate(raw))
    if len(points) < (3 if closed else 2):
        raise r.fail(path, f"needs at least {3 if closed else 2} points")
    pairs = [(i, i + 1) for i in range(len(points) - 1)]
    if closed:
        pairs.append((len(points) - 1, 0))
    for i, j in pairs:
        if points[i] == points[j]:
            raise r.fail(f"{path}[{j}]", f"zero-length segment (same point as points[{i}])")
        if math.dist(points[i], points[j]) < MIN_LENGTH_M:
            raise r.fail(f"{path}[{j}]", f"segment from points[{i}] shorter than "
                                         f"{MIN_LENGTH_M:g} m")
    return Polyline(points, closed)  # type: ignore[arg-type]


def _read_circle(r: _Reader, d: dict, key: str) -> Circle:
    d = r.obj(d, key, ("type", "center", "radius"), ("center", "radius"))
    radius = r.number(d, "radius", key, gt=0)
    if radius < MIN_LENGTH_M:
        raise r.fail(_join(key, "radius"), f"must be at least {MIN_LENGTH_M:g} m")
    return Circle(r.point(d, "center", key), radius)


def _read_sinusoid(r: _Reader, d: dict, key: str) -> Sinusoid:
    d = r.obj(d, key, ("type", "from", "to", "amplitude", "period"),
              ("from", "to", "amplitude", "period"))
    start, end = r.point(d, "from", key), r.point(d, "to", key)
    if start == end:
        raise r.fail(_join(key, "to"), "zero-length base line (same point as 'from')")
    if math.dist(start, end) < MIN_LENGTH_M:
        raise r.fail(_join(key, "to"), f"base line shorter than {MIN_LENGTH_M:g} m")
    return Sinusoid(start, end, r.number(d, "amplitude", key), r.number(d, "period", key, gt=0))


_SURFACE_READERS = {"polyline": _read_polyline, "circle": _read_circle, "sinusoid": _read_sinusoid}


def _read_surfaces(r: _Reader, raw: Any) -> tuple[Surface, ...]:
    if not isinstance(raw, list):
        raise r.fail("surfaces", f"must be a list of surfaces, not {_type_name(raw)}")
    out = []
    for i, s in enumerate(raw):
        key = f"surfaces[{i}]"
        if not isinstance(s, dict):
            raise r.fail(key, f"must be an object, not {_type_name(s)}")
        kind = r.choice(s, "type", key, tuple(_SURFACE_READERS))
        out.append(_SURFACE_READERS[kind](r, s, key))
    return tuple(out)


def _read_transducers(r: _Reader, raw: Any, key: str) -> tuple[Transducer, ...]:
    if not isinstance(raw, list):
        raise r.fail(key, f"must be a list of transducers, not {_type_name(raw)}")
    out = []
    for i, t in enumerate(raw):
        k = f"{key}[{i}]"
        t = r.obj(t, k, ("position", "heading_deg", "group"), ("position", "heading_deg"))
        out.append(Transducer(r.point(t, "position", k), r.number(t, "heading_deg", k),
                              r.integer(t, "group", k, 0, ge=0, le=2**31 - 1)))
    return tuple(out)


def _read_per_wall(r: _Reader, d: dict, k: str, surfaces: tuple[Surface, ...]) -> PerWall:
    d = r.obj(d, k, tuple(f.name for f in fields(PerWall)))
    p = PerWall
    surface = r.integer(d, "surface", k, p.surface, ge=0)
    problem = per_wall_surface_problem(surfaces, surface)
    if problem:
        raise r.fail(_join(k, "surface"), problem)
    margin = None if d.get("margin_m") is None else r.number(d, "margin_m", k, ge=0)
    return PerWall(
        seed=r.integer(d, "seed", k, p.seed, ge=0, le=2**63 - 1),
        surface=surface,
        distance_m=r.number(d, "distance_m", k, p.distance_m, gt=0),
        distance_step_m=r.number(d, "distance_step_m", k, p.distance_step_m),
        margin_m=margin,
        elements=r.integer(d, "elements", k, p.elements, ge=1, le=10000),
        spacing_m=r.interval(d, "spacing_m", k, p.spacing_m, gt=0),
        separation_m=r.interval(d, "separation_m", k, p.separation_m, gt=0),
        heading_spread_deg=r.number(d, "heading_spread_deg", k, p.heading_spread_deg,
                                    ge=0, le=180),
        clearance_m=r.number(d, "clearance_m", k, p.clearance_m, ge=0),
    )


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


def _read_placement(r: _Reader, d: Any, surfaces: tuple[Surface, ...] = (),
                    k: str = "sensors.placement") -> Placement | None:
    if d is None:
        return None
    if not isinstance(d, dict):
        raise r.fail(k, f"must be an object, not {_type_name(d)}")
    kind = r.choice(d, "type", k, ("random-lines", "circular", "wall-following", "per-wall"))
    if kind == "per-wall":
        return _read_per_wall(r, d, k, surfaces)
    if kind == "random-lines":
        d = r.obj(d, k, tuple(f.name for f in fields(RandomLines)))
        p = RandomLines
        return RandomLines(
            seed=r.integer(d, "seed", k, p.seed, ge=0, le=2**63 - 1),
            start=r.point(d, "start", k, None),
            direction_deg=r.number(d, "direction_deg", k, p.direction_deg),
            length_m=r.number(d, "length_m", k, p.length_m, gt=0),
            elements=r.integer(d, "elements", k, p.elements, ge=1, le=10000),
            spacing_m=r.interval(d, "spacing_m", k, p.spacing_m, gt=0),
            separation_m=r.interval(d, "separation_m", k, p.separation_m, gt=0),
            facing_deg=r.number(d, "facing_deg", k, p.facing_deg),
            heading_spread_deg=r.number(d, "heading_spread_deg", k, p.heading_spread_deg,
                                        ge=0, le=180),
            clearance_m=r.number(d, "clearance_m", k, p.clearance_m, ge=0),
        )
    if kind == "circular":
        d = r.obj(d, k, tuple(f.name for f in fields(Circular)), ("center",))
        return Circular(
            center=r.point(d, "center", k),
            radius_m=r.number(d, "radius_m", k, Circular.radius_m, ge=0),
            elements=r.integer(d, "elements", k, Circular.elements, ge=1, le=10000),
            start_deg=r.number(d, "start_deg", k, Circular.start_deg),
        )
    d = r.obj(d, k, tuple(f.name for f in fields(WallFollowing)), ("start",))
    w = WallFollowing
    return WallFollowing(
        start=r.point(d, "start", k),
        step_m=r.number(d, "step_m", k, w.step_m, gt=0),
        clearance_m=r.number(d, "clearance_m", k, w.clearance_m, gt=0),
        radius_m=r.number(d, "radius_m", k, w.radius_m, ge=0),
        elements=r.integer(d, "elements", k, w.elements, ge=1, le=10000),
        start_deg=r.number(d, "start_deg", k, w.start_deg),
        direction=r.choice(d, "direction", k, ("ccw", "cw"), w.direction),  # type: ignore[arg-type]
        max_poses=r.integer(d, "max_poses", k, w.max_poses, ge=1, le=10**6),
    )


def _read_sensors(r: _Reader, d: Any, surfaces: tuple[Surface, ...]) -> Sensors:
    d = r.obj(d, "sensors", ("transducers", "placement", "placements"))
    more = d.get("placements", [])
    if not isinstance(more, list):
        raise r.fail("sensors.placements", f"must be a list of placements, not "
                                           f"{_type_name(more)}")
    placements = []
    for i, item in enumerate(more):
        key = f"sensors.placements[{i}]"
        if item is None:
            raise r.fail(key, "must be an object, not null")
        placements.append(_read_placement(r, item, surfaces, key))
    return Sensors(_read_transducers(r, d.get("transducers", []), "sensors.transducers"),
                   _read_placement(r, d.get("placement"), surfaces), tuple(placements))


_TOP_KEYS = ("clsonar", "name", "extent", "cell", "medium", "transducer", "signal", "echo",
             "detection", "mapping", "post", "surfaces", "sensors")


def scene_from_dict(data: Any, source: str = "<scene>") -> Scene:
    """Validate a parsed scene (format v1) and build the :class:`Scene`.

    Raises :class:`SceneError` naming ``source`` and the offending key.
    """
    r = _Reader(source)
    d = r.obj(data, "", _TOP_KEYS)
    if "clsonar" not in d:
        raise r.fail("clsonar", "missing format version (expected \"clsonar\": 1)")
    version = d["clsonar"]
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise r.fail("clsonar", f"unsupported format version {version!r:.20} "
                                f"(this program reads version {FORMAT_VERSION})")
    name = d.get("name", Path(source).stem if source != "<scene>" else "scene")
    if not isinstance(name, str):
        raise r.fail("name", f"must be a string, not {_type_name(name)}")
    if "extent" not in d:
        raise r.fail("extent", "missing required key")
    extent = r.vector(d["extent"], "extent", 4)
    if not (extent[2] > extent[0] and extent[3] > extent[1]):
        raise r.fail("extent", "must be [xmin, ymin, xmax, ymax] with xmax > xmin and ymax > ymin")
    cell = r.number(d, "cell", "", 0.01, gt=0)
    cells = max(extent[2] - extent[0], extent[3] - extent[1]) / cell
    if not cells <= MAX_CELLS_PER_SIDE:  # also catches an infinite width or count
        raise r.fail("cell", f"the extent is {cells:.3g} cells of {cell:g} m a side, more "
                             f"than the {MAX_CELLS_PER_SIDE:.0e} any map can hold")
    surfaces = _read_surfaces(r, d.get("surfaces", []))
    scene = Scene(
        name=name,
        extent=extent,  # type: ignore[arg-type]
        cell=cell,
        medium=_read_medium(r, d.get("medium", {})),
        transducer=_read_transducer(r, d.get("transducer", {})),
        signal=_read_signal(r, d.get("signal", {})),
        echo=_read_echo(r, d.get("echo", {})),
        detection=_read_detection(r, d.get("detection", {})),
        mapping=_read_mapping(r, d.get("mapping", {})),
        post=_read_post(r, d.get("post", {})),
        surfaces=surfaces,
        sensors=_read_sensors(r, d.get("sensors", {}), surfaces),
    )
    _check_work(r, scene)
    return scene


#: Most wall sequences (walls to the power echo.max_order) and explicitly fired pairs
#: (the sum of each group's size squared) a scene may ask for: more would not fit in memory.
MAX_WALL_SEQUENCES = 10**7
MAX_EXPLICIT_PAIRS = 10**7

#: Most sampling intervals of all sinusoids together (their lengths / echo.curve_step_m).
MAX_CURVE_SAMPLES = 10**6

#: Most circles in a scene (sensor placement tests every pose against every surface).
MAX_CIRCLES = 1000


def _check_work(r: _Reader, scene: Scene) -> None:
    """Refuse a scene whose echo model would need more memory than any machine has."""
    walls = sum(len(s.points) - (0 if s.closed else 1)
                for s in scene.surfaces if isinstance(s, Polyline))
    if float(walls) ** scene.echo.max_order > MAX_WALL_SEQUENCES:
        raise r.fail("echo.max_order", f"{walls} walls to the power {scene.echo.max_order} "
                                       f"are more than the {MAX_WALL_SEQUENCES:.0e} reflection "
                                       "sequences clsonar can hold: use a lower max_order or "
                                       "fewer polyline points")
    samples = sum(math.dist(s.start, s.end) for s in scene.surfaces
                  if isinstance(s, Sinusoid)) / scene.echo.curve_step_m
    if samples > MAX_CURVE_SAMPLES:
        raise r.fail("echo.curve_step_m", f"the sinusoids would be sampled at {samples:.3g} "
                                          f"points, more than {MAX_CURVE_SAMPLES:.0e}: use a "
                                          "larger step")
    circles = sum(isinstance(s, Circle) for s in scene.surfaces)
    if circles > MAX_CIRCLES:
        raise r.fail("surfaces", f"{circles} circles, more than the {MAX_CIRCLES} a scene may "
                                 "have")
    groups: dict[int, int] = {}
    for t in scene.sensors.transducers:
        groups[t.group] = groups.get(t.group, 0) + 1
    fired = sum(n * n for n in groups.values())
    if fired > MAX_EXPLICIT_PAIRS:
        raise r.fail("sensors.transducers", f"{fired} transmitter→receiver pairs fire, more "
                                            f"than {MAX_EXPLICIT_PAIRS:.0e}: split the "
                                            "transducers into smaller groups")


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a valid number here (numbers must be finite)")


def _depth(value: Any, limit: int) -> int:
    """Nesting depth of a parsed JSON value, stopping early once ``limit`` is exceeded."""
    stack = [(value, 1)]
    deepest = 0
    while stack:
        v, level = stack.pop()
        deepest = max(deepest, level)
        if deepest > limit:
            return deepest
        children = v.values() if isinstance(v, dict) else v if isinstance(v, list) else ()
        stack.extend((c, level + 1) for c in children if isinstance(c, (dict, list)))
    return deepest


def parse_scene_text(text: str, source: str = "<scene>") -> Scene:
    """Parse JSON text of a scene; every problem is a :class:`SceneError` naming ``source``."""
    if not text.strip():
        raise SceneError("file is empty (expected a JSON scene object)", source=source)
    if text.count(",") > MAX_SEPARATORS:
        raise SceneError(f"too large: more than {MAX_SEPARATORS} list items", source=source)
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as e:
        raise SceneError(f"invalid JSON at line {e.lineno} column {e.colno}: {e.msg}",
                         source=source) from None
    except ValueError as e:  # NaN / Infinity literals
        raise SceneError(f"invalid JSON: {e}", source=source) from None
    except RecursionError:
        raise SceneError(f"JSON nested deeper than {MAX_DEPTH} levels", source=source) from None
    if text.count("[") + text.count("{") > MAX_CONTAINERS:  # before walking every node
        raise SceneError(f"too large: more than {MAX_CONTAINERS} JSON objects and lists",
                         source=source)
    if _depth(data, MAX_DEPTH) > MAX_DEPTH:
        raise SceneError(f"JSON nested deeper than {MAX_DEPTH} levels", source=source)
    return scene_from_dict(data, source)


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Read and validate a scene file (format v1). Raises :class:`SceneError` on any problem."""
    return parse_scene_text(read_text(path), os.fspath(path))


# --------------------------------------------------------------------------- writing


def _point(p: Point) -> list[float]:
    return [float(p[0]), float(p[1])]


def _surface_dict(s: Surface) -> dict[str, Any]:
    if isinstance(s, Polyline):
        return {"type": "polyline", "points": [_point(p) for p in s.points], "closed": s.closed}
    if isinstance(s, Circle):
        return {"type": "circle", "center": _point(s.center), "radius": s.radius}
    return {"type": "sinusoid", "from": _point(s.start), "to": _point(s.end),
            "amplitude": s.amplitude, "period": s.period}


def _plain(obj: Any) -> Any:
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
