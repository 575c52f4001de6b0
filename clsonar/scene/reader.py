"""Reading scene format v1: JSON text → a validated :class:`~clsonar.scene.Scene`.

Every key is checked (clsonar.scene.values); any problem raises
:class:`~clsonar.errors.SceneError` naming the file and the key path. Files beyond the limits
of clsonar.scene.limits are refused before any heavy work.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import Any

from ..errors import SceneError
from ..files import read_text
from .limits import (
    MAX_CELLS_PER_SIDE,
    MAX_CIRCLES,
    MAX_CONTAINERS,
    MAX_CURVE_SAMPLES,
    MAX_DEPTH,
    MAX_EXPLICIT_PAIRS,
    MAX_SEPARATORS,
    MIN_LENGTH_M,
)
from .model import (
    FORMAT_VERSION,
    Circle,
    Circular,
    PerWall,
    Placement,
    Polyline,
    RandomLines,
    Scene,
    Sensors,
    Sinusoid,
    Surface,
    Transducer,
    WallDirection,
    WallFollowing,
    per_wall_surface_problem,
)
from .settings import (
    Combine,
    DetectionMode,
    DetectionSettings,
    Directivity,
    EchoModel,
    EdgeModel,
    Fit,
    MappingMode,
    MappingSettings,
    Medium,
    PostFilter,
    PostSettings,
    Precision,
    Receiver,
    Reciprocal,
    Signal,
    Thinning,
    TransducerModel,
    VoteWeight,
)
from .values import JsonReader, join, type_name


def _keys(cls: type) -> tuple[str, ...]:
    """The keys of the section or placement read into dataclass ``cls``: its fields."""
    return tuple(f.name for f in fields(cls))


# --------------------------------------------------------------------------- settings


def _read_medium(r: JsonReader, d: Any) -> Medium:
    d = r.obj(d, "medium", _keys(Medium))
    t = r.number(d, "temperature_k", "medium", Medium.temperature_k, gt=0)
    c = None
    if d.get("speed_of_sound") is not None:
        c = r.number(d, "speed_of_sound", "medium", gt=0)
    return Medium(t, c)


def _read_transducer(r: JsonReader, d: Any) -> TransducerModel:
    k, tm = "transducer", TransducerModel
    d = r.obj(d, k, _keys(tm))
    return TransducerModel(
        frequency_hz=r.number(d, "frequency_hz", k, tm.frequency_hz, gt=0),
        radius_m=r.number(d, "radius_m", k, tm.radius_m, gt=0),
        half_beam_deg=r.number(d, "half_beam_deg", k, tm.half_beam_deg, gt=0, le=90),
        amplitude=r.number(d, "amplitude", k, tm.amplitude, gt=0),
        pulse_sigma_s=r.number(d, "pulse_sigma_s", k, tm.pulse_sigma_s, gt=0),
        directivity=r.literal(d, "directivity", k, Directivity, tm.directivity),
    )


def _read_signal(r: JsonReader, d: Any) -> Signal:
    k = "signal"
    d = r.obj(d, k, _keys(Signal))
    return Signal(
        noise_std=r.number(d, "noise_std", k, Signal.noise_std, ge=0),
        threshold=r.number(d, "threshold", k, Signal.threshold, gt=0),
        seed=r.integer(d, "seed", k, Signal.seed, ge=0, le=2**63 - 1),
    )


def _read_echo(r: JsonReader, d: Any) -> EchoModel:
    k, em = "echo", EchoModel
    d = r.obj(d, k, _keys(em))
    return EchoModel(
        max_order=r.integer(d, "max_order", k, em.max_order, ge=1, le=4),
        reflection_coefficient=r.number(d, "reflection_coefficient", k,
                                        em.reflection_coefficient, ge=0, le=1),
        edge_coefficient=r.number(d, "edge_coefficient", k, em.edge_coefficient, ge=0),
        edge_model=r.literal(d, "edge_model", k, EdgeModel, em.edge_model),
        absorption_db_per_m=r.number(d, "absorption_db_per_m", k, em.absorption_db_per_m,
                                     ge=0),
        curve_step_m=r.number(d, "curve_step_m", k, em.curve_step_m, gt=0),
        curvature_gain=r.boolean(d, "curvature_gain", k, em.curvature_gain),
    )


def _read_detection(r: JsonReader, d: Any) -> DetectionSettings:
    k, ds = "detection", DetectionSettings
    d = r.obj(d, k, _keys(ds))
    return DetectionSettings(
        mode=r.literal(d, "mode", k, DetectionMode, ds.mode),
        sample_rate_hz=r.number(d, "sample_rate_hz", k, ds.sample_rate_hz, gt=0),
        false_alarm_sigmas=r.number(d, "false_alarm_sigmas", k, ds.false_alarm_sigmas, gt=0),
        min_envelope=r.optional_number(d, "min_envelope", k, ge=0),
        receiver=_receiver(r, d, k, ds),
    )


def _receiver(r: JsonReader, d: Any, k: str, ds: type[DetectionSettings]) -> Receiver:
    """``detection.receiver``; a receiver other than the ideal one needs the envelope
    detector (its gain and comparator act on the envelope, clsonar.signals.polaroid)."""
    receiver = r.literal(d, "receiver", k, Receiver, ds.receiver)
    if receiver != "ideal" and d.get("mode", ds.mode) != "envelope":
        raise r.fail(f"{k}.receiver", f'"{receiver}" needs detection.mode "envelope"')
    return receiver


def _read_mapping(r: JsonReader, d: Any) -> MappingSettings:
    k, ms = "mapping", MappingSettings
    d = r.obj(d, k, _keys(ms))
    return MappingSettings(
        mode=r.literal(d, "mode", k, MappingMode, ms.mode),
        weight=r.literal(d, "weight", k, VoteWeight, ms.weight),
        band_m=r.optional_number(d, "band_m", k, gt=0),
        precision=r.literal(d, "precision", k, Precision, ms.precision),
        reciprocal=r.literal(d, "reciprocal", k, Reciprocal, ms.reciprocal),
        combine=r.literal(d, "combine", k, Combine, ms.combine),
        isolated_bias_m=r.optional_number(d, "isolated_bias_m", k, ge=0),
        line_of_sight=r.boolean(d, "line_of_sight", k, ms.line_of_sight),
    )


def _read_post(r: JsonReader, d: Any) -> PostSettings:
    k, ps = "post", PostSettings
    d = r.obj(d, k, _keys(ps))
    return PostSettings(
        filter=r.literal(d, "filter", k, PostFilter, ps.filter),
        level=r.optional_number(d, "level", k, gt=0, le=1),
        thinning=r.literal(d, "thinning", k, Thinning, ps.thinning),
        fit=r.optional_literal(d, "fit", k, Fit),
        poly_order=r.integer(d, "poly_order", k, ps.poly_order, ge=1, le=12),
        max_gap_m=r.optional_number(d, "max_gap_m", k, ge=0),
        subcell=r.boolean(d, "subcell", k, ps.subcell),
        join_m=r.optional_number(d, "join_m", k, ge=0),
    )


# --------------------------------------------------------------------------- surfaces


def _read_polyline(r: JsonReader, d: dict[str, Any], key: str) -> Polyline:
    d = r.obj(d, key, ("type", "points", "closed", "solid"), ("points",))
    raw = d["points"]
    path = join(key, "points")
    closed = r.boolean(d, "closed", key, False)
    solid = d.get("solid")
    if solid is not None and not isinstance(solid, bool):
        raise r.fail(join(key, "solid"), f"must be true, false or null, not {type_name(solid)}")
    if solid and not closed:
        raise r.fail(join(key, "solid"), "true needs \"closed\": true (only a closed polyline "
                                         "encloses a solid)")
    if not isinstance(raw, list):
        raise r.fail(path, f"must be a list of [x, y] points, not {type_name(raw)}")
    points = tuple(r.xy(p, f"{path}[{i}]") for i, p in enumerate(raw))
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
    return Polyline(points, closed, solid)


def _read_circle(r: JsonReader, d: dict[str, Any], key: str) -> Circle:
    d = r.obj(d, key, ("type", "center", "radius"), ("center", "radius"))
    radius = r.number(d, "radius", key, gt=0)
    if radius < MIN_LENGTH_M:
        raise r.fail(join(key, "radius"), f"must be at least {MIN_LENGTH_M:g} m")
    return Circle(r.point(d, "center", key), radius)


def _read_sinusoid(r: JsonReader, d: dict[str, Any], key: str) -> Sinusoid:
    d = r.obj(d, key, ("type", "from", "to", "amplitude", "period"),
              ("from", "to", "amplitude", "period"))
    start, end = r.point(d, "from", key), r.point(d, "to", key)
    if start == end:
        raise r.fail(join(key, "to"), "zero-length base line (same point as 'from')")
    if math.dist(start, end) < MIN_LENGTH_M:
        raise r.fail(join(key, "to"), f"base line shorter than {MIN_LENGTH_M:g} m")
    return Sinusoid(start, end, r.number(d, "amplitude", key), r.number(d, "period", key, gt=0))


#: The reader of each surface ``type``.
_SURFACE_READERS: dict[str, Callable[[JsonReader, dict[str, Any], str], Surface]] = {
    "polyline": _read_polyline, "circle": _read_circle, "sinusoid": _read_sinusoid}


def _read_surfaces(r: JsonReader, raw: Any) -> tuple[Surface, ...]:
    if not isinstance(raw, list):
        raise r.fail("surfaces", f"must be a list of surfaces, not {type_name(raw)}")
    out: list[Surface] = []
    for i, s in enumerate(raw):
        key = f"surfaces[{i}]"
        if not isinstance(s, dict):
            raise r.fail(key, f"must be an object, not {type_name(s)}")
        kind = r.choice(s, "type", key, tuple(_SURFACE_READERS))
        out.append(_SURFACE_READERS[kind](r, s, key))
    return tuple(out)


# --------------------------------------------------------------------------- sensors


def _read_transducers(r: JsonReader, raw: Any, key: str) -> tuple[Transducer, ...]:
    if not isinstance(raw, list):
        raise r.fail(key, f"must be a list of transducers, not {type_name(raw)}")
    out = []
    for i, t in enumerate(raw):
        k = f"{key}[{i}]"
        t = r.obj(t, k, _keys(Transducer), ("position", "heading_deg"))
        out.append(Transducer(r.point(t, "position", k), r.number(t, "heading_deg", k),
                              r.integer(t, "group", k, 0, ge=0, le=2**31 - 1)))
    return tuple(out)


def _read_random_lines(r: JsonReader, d: dict[str, Any], k: str,
                       surfaces: tuple[Surface, ...]) -> RandomLines:
    d = r.obj(d, k, _keys(RandomLines))
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


def _read_circular(r: JsonReader, d: dict[str, Any], k: str,
                   surfaces: tuple[Surface, ...]) -> Circular:
    d = r.obj(d, k, _keys(Circular), ("center",))
    return Circular(
        center=r.point(d, "center", k),
        radius_m=r.number(d, "radius_m", k, Circular.radius_m, ge=0),
        elements=r.integer(d, "elements", k, Circular.elements, ge=1, le=10000),
        start_deg=r.number(d, "start_deg", k, Circular.start_deg),
    )


def _read_wall_following(r: JsonReader, d: dict[str, Any], k: str,
                         surfaces: tuple[Surface, ...]) -> WallFollowing:
    d = r.obj(d, k, _keys(WallFollowing), ("start",))
    w = WallFollowing
    return WallFollowing(
        start=r.point(d, "start", k),
        step_m=r.number(d, "step_m", k, w.step_m, gt=0),
        clearance_m=r.number(d, "clearance_m", k, w.clearance_m, gt=0),
        radius_m=r.number(d, "radius_m", k, w.radius_m, ge=0),
        elements=r.integer(d, "elements", k, w.elements, ge=1, le=10000),
        start_deg=r.optional_number(d, "start_deg", k),
        direction=r.literal(d, "direction", k, WallDirection, w.direction),
        max_poses=r.integer(d, "max_poses", k, w.max_poses, ge=1, le=10**6),
    )


def _read_per_wall(r: JsonReader, d: dict[str, Any], k: str,
                   surfaces: tuple[Surface, ...]) -> PerWall:
    d = r.obj(d, k, _keys(PerWall))
    p = PerWall
    surface = r.integer(d, "surface", k, p.surface, ge=0)
    problem = per_wall_surface_problem(surfaces, surface)
    if problem:
        raise r.fail(join(k, "surface"), problem)
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


#: The reader of each placement ``type`` (the tag each placement dataclass carries).
_PLACEMENT_READERS: dict[str, Callable[[JsonReader, dict[str, Any], str,
                                        tuple[Surface, ...]], Placement]] = {
    RandomLines.type: _read_random_lines, Circular.type: _read_circular,
    WallFollowing.type: _read_wall_following, PerWall.type: _read_per_wall}


def _read_one_placement(r: JsonReader, d: Any, surfaces: tuple[Surface, ...],
                        k: str) -> Placement:
    if not isinstance(d, dict):
        raise r.fail(k, f"must be an object, not {type_name(d)}")
    kind = r.choice(d, "type", k, tuple(_PLACEMENT_READERS))
    return _PLACEMENT_READERS[kind](r, d, k, surfaces)


def _read_sensors(r: JsonReader, d: Any, surfaces: tuple[Surface, ...]) -> Sensors:
    d = r.obj(d, "sensors", _keys(Sensors))
    more = d.get("placements", [])
    if not isinstance(more, list):
        raise r.fail("sensors.placements", f"must be a list of placements, not "
                                           f"{type_name(more)}")
    placements = []
    for i, item in enumerate(more):
        key = f"sensors.placements[{i}]"
        if item is None:
            raise r.fail(key, "must be an object, not null")
        placements.append(_read_one_placement(r, item, surfaces, key))
    transducers = _read_transducers(r, d.get("transducers", []), "sensors.transducers")
    single = d.get("placement")
    placement = (None if single is None
                 else _read_one_placement(r, single, surfaces, "sensors.placement"))
    return Sensors(transducers, placement, tuple(placements))


# --------------------------------------------------------------------------- the scene

_TOP_KEYS = ("clsonar", *_keys(Scene))


def _read_frame(r: JsonReader, d: dict[str, Any]
                ) -> tuple[tuple[float, float, float, float], float]:
    """The scene's ``extent`` and ``cell``, checked against :data:`MAX_CELLS_PER_SIDE`."""
    if "extent" not in d:
        raise r.fail("extent", "missing required key")
    xmin, ymin, xmax, ymax = r.vector(d["extent"], "extent", 4)
    if not (xmax > xmin and ymax > ymin):
        raise r.fail("extent", "must be [xmin, ymin, xmax, ymax] with xmax > xmin and ymax > ymin")
    cell = r.number(d, "cell", "", 0.01, gt=0)
    cells = max(xmax - xmin, ymax - ymin) / cell
    if not cells <= MAX_CELLS_PER_SIDE:  # also catches an infinite width or count
        raise r.fail("cell", f"the extent is {cells:.3g} cells of {cell:g} m a side, more "
                             f"than the {MAX_CELLS_PER_SIDE:.0e} any map can hold")
    return (xmin, ymin, xmax, ymax), cell


def scene_from_dict(data: Any, source: str = "<scene>") -> Scene:
    """Validate a parsed scene (format v1) and build the :class:`Scene`.

    Raises :class:`SceneError` naming ``source`` and the offending key.
    """
    r = JsonReader(source)
    d = r.obj(data, "", _TOP_KEYS)
    if "clsonar" not in d:
        raise r.fail("clsonar", "missing format version (expected \"clsonar\": 1)")
    version = d["clsonar"]
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise r.fail("clsonar", f"unsupported format version {version!r:.20} "
                                f"(this program reads version {FORMAT_VERSION})")
    name = d.get("name", Path(source).stem if source != "<scene>" else "scene")
    if not isinstance(name, str):
        raise r.fail("name", f"must be a string, not {type_name(name)}")
    extent, cell = _read_frame(r, d)
    surfaces = _read_surfaces(r, d.get("surfaces", []))
    scene = Scene(
        name=name,
        extent=extent,
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


def _check_work(r: JsonReader, scene: Scene) -> None:
    """Refuse a scene whose echo model would need more memory than any machine has (the
    mirror sequences are counted where they are built, room by room on a floor:
    :func:`clsonar.echoes.check_sequences`)."""
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


# --------------------------------------------------------------------------- JSON text


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
