"""Reading and validating a sweep spec (TOML or JSON, ``docs/sweep.md``): base scenes,
grid, seeds, metrics and preset, each checked with a message naming the file and the key;
and the scene-file key paths the grid sets (:func:`parse_key_path`, :func:`set_key`)."""

from __future__ import annotations

import json
import math
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import SceneError
from ...files import bundled_scenes, read_text
from ...pipeline import PRESETS
from ...scene import Scene, load_scene

KNOWN_METRICS = ("rms_m", "accuracy_m.rms", "accuracy_m.p95", "completeness.1cm",
                 "completeness.2cm", "completeness.3cm", "completeness.5cm", "spurious_share",
                 "insonified_m", "coverage", "points", "vertices_found", "vertex_error_max_m")
DEFAULT_METRICS = ("rms_m", "accuracy_m.rms", "completeness.2cm")

#: Grid keys that are not scene-file keys (module docstring).
PSEUDO_KEYS = ("preset", "distance_m")

SPEC_KEYS = ("name", "scenes", "seeds", "metrics", "preset", "grid")
SCENE_ENTRY_KEYS = ("scene", "distance_m")

class SpecError(SceneError):
    """A sweep spec that cannot be read or is not valid: ``"FILE: KEY: message"``."""



@dataclass(frozen=True)
class SceneEntry:
    """A base scene of a sweep: its label in the table, the scene, its own distance."""

    label: str
    scene: Scene
    distance_m: float | None = None


@dataclass(frozen=True)
class Spec:
    """A validated sweep spec: base scenes × grid (key path → values) × seeds."""

    name: str
    source: str
    scenes: tuple[SceneEntry, ...]
    grid: tuple[tuple[str, tuple[Any, ...]], ...]
    seeds: tuple[int, ...]
    metrics: tuple[str, ...]
    preset: str | None = None

    @property
    def parameters(self) -> tuple[str, ...]:
        """The swept key paths, in spec order."""
        return tuple(k for k, _ in self.grid)


_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_KEY_PATH = re.compile(rf"{_NAME}(\[\d+\])*(\.{_NAME}(\[\d+\])*)*")


def parse_key_path(path: str) -> list[str | int]:
    """``"surfaces[0].radius"`` → ``["surfaces", 0, "radius"]``; ``ValueError`` if malformed."""
    if not _KEY_PATH.fullmatch(path):
        raise ValueError(f"malformed key path {path!r} (write e.g. signal.noise_std or "
                         "surfaces[0].radius)")
    return [int(i) if i else name for name, i in re.findall(rf"({_NAME})|\[(\d+)\]", path)]


def set_key(data: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    """A copy of the scene dict ``data`` with the key at ``path`` set to ``value``.

    ``KeyError`` (its message says what exists there) if the path leads nowhere in ``data``.
    """
    tokens = parse_key_path(path)
    out = json.loads(json.dumps(data))
    node: Any = out
    where = ""
    for i, tok in enumerate(tokens):
        last = i == len(tokens) - 1
        if isinstance(tok, int):
            if not isinstance(node, list) or tok >= len(node):
                n = len(node) if isinstance(node, list) else 0
                raise KeyError(f"{where or 'scene'} has {n} item(s), no [{tok}]")
            here = f"{where}[{tok}]"
        else:
            if not isinstance(node, dict) or tok not in node:
                keys = ", ".join(node) if isinstance(node, dict) else "no keys"
                what = "null" if node is None else f"keys: {keys}"
                raise KeyError(f"{where or 'scene'} has no key {tok!r} ({what})")
            here = f"{where}.{tok}" if where else tok
        if last:
            node[tok] = value
        else:
            node, where = node[tok], here
    return out


def _parse_toml(text: str, source: str) -> Any:
    """The TOML document ``text`` (Python 3.11 or later: ``tomllib``)."""
    if sys.version_info >= (3, 11):
        import tomllib

        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise SpecError(f"invalid TOML: {e}", source=source) from None
    raise SpecError("TOML specs need Python 3.11 or later: write the spec as JSON",
                    source=source)


def _read_spec_file(path: Path) -> dict[str, Any]:
    """The spec file's table (TOML) or object (JSON)."""
    source = str(path)
    text = read_text(path, SpecError)
    if path.suffix.lower() == ".toml":
        data = _parse_toml(text, source)
    else:
        def _constant(name: str) -> float:
            raise ValueError(f"{name} is not a number")
        try:
            data = json.loads(text, parse_constant=_constant)
        except (json.JSONDecodeError, ValueError) as e:
            raise SpecError(f"invalid JSON: {e}", source=source) from None
    if not isinstance(data, dict):
        raise SpecError("must be a table (TOML) or an object (JSON)", source=source)
    return data


def _scene_entry(entry: Any, key: str, base: Path, source: str) -> SceneEntry:
    """One entry of ``scenes``: a file relative to the spec, a bundled scene's name, or
    ``{scene = ..., distance_m = ...}``."""
    distance = None
    if isinstance(entry, dict):
        for k in entry:
            if k not in SCENE_ENTRY_KEYS:
                raise SpecError(f"unknown key (allowed: {', '.join(SCENE_ENTRY_KEYS)})",
                                f"{key}.{k}", source)
        if "scene" not in entry:
            raise SpecError("missing required key", f"{key}.scene", source)
        distance = entry.get("distance_m")
        if distance is not None and (isinstance(distance, bool)
                                     or not isinstance(distance, (int, float))
                                     or not math.isfinite(distance) or distance <= 0):
            raise SpecError("must be a number > 0", f"{key}.distance_m", source)
        key, entry = f"{key}.scene", entry["scene"]
    if not isinstance(entry, str) or not entry:
        raise SpecError("must be a scene file path or a bundled scene name", key, source)
    candidates = [base / entry, bundled_scenes() / f"{entry}.json"]
    path = next((p for p in candidates if p.is_file()), None)
    if path is None:
        raise SpecError(f"no scene file {entry!r} (relative to the spec) nor a bundled scene "
                        "of that name", key, source)
    return SceneEntry(entry, load_scene(path), None if distance is None else float(distance))


def _grid(raw: Any, source: str) -> tuple[tuple[str, tuple[Any, ...]], ...]:
    """``grid``: key paths (or :data:`PSEUDO_KEYS`), each with a non-empty list of values."""
    if raw is None:
        raise SpecError("missing: give at least one key path and its values", "grid", source)
    if not isinstance(raw, dict):
        raise SpecError("must be a table of key path = [values]", "grid", source)
    if not raw:
        raise SpecError("empty: give at least one key path and its values", "grid", source)
    out = []
    for path, values in raw.items():
        key = f"grid.{path}"
        if path not in PSEUDO_KEYS:
            try:
                parse_key_path(path)
            except ValueError as e:
                raise SpecError(str(e), key, source) from None
        if not isinstance(values, list):
            raise SpecError(f"must be a list of values, not {_type_name(values)}", key, source)
        if not values:
            raise SpecError("empty list: give at least one value", key, source)
        out.append((path, tuple(values)))
    return tuple(out)


def _check_pseudo_values(grid: tuple[tuple[str, tuple[Any, ...]], ...], source: str) -> None:
    """The grid's values of ``preset`` must name presets, those of ``distance_m`` be > 0."""
    for key, values in grid:
        for v in values:
            if key == "preset":
                _check_preset(v, "grid.preset", source)
            if key == "distance_m" and (isinstance(v, bool) or not isinstance(v, (int, float))
                                        or not v > 0):
                raise SpecError(f"must be numbers > 0, not {v!r:.40}", "grid.distance_m",
                                source)


def _check_preset(value: Any, key: str, source: str) -> None:
    if value not in PRESETS:
        raise SpecError(f"must be one of {', '.join(map(repr, PRESETS))}, not {value!r:.40}",
                        key, source)


def _type_name(v: Any) -> str:
    """How an error message names the JSON/TOML type of ``v``."""
    return {bool: "true/false", str: "a string", dict: "a table", list: "a list",
            type(None): "null"}.get(type(v), "a number")


def _check_keys(data: dict[str, Any], source: str) -> None:
    for k in data:
        if k not in SPEC_KEYS:
            raise SpecError(f"unknown key (allowed: {', '.join(SPEC_KEYS)})", k, source)


def _name(data: dict[str, Any], path: Path, source: str) -> str:
    name = data.get("name", path.stem)
    if not isinstance(name, str):
        raise SpecError(f"must be a string, not {_type_name(name)}", "name", source)
    return name


def _scene_entries(scenes: Any, base: Path, source: str) -> tuple[SceneEntry, ...]:
    """``scenes``: one entry or a non-empty list of them (:func:`_scene_entry`), no scene
    twice."""
    if isinstance(scenes, (str, dict)):
        scenes = [scenes]
    if not isinstance(scenes, list) or not scenes:
        raise SpecError("must be a non-empty list of scene files or bundled scene names",
                        "scenes", source)
    entries = tuple(_scene_entry(e, f"scenes[{i}]", base, source)
                    for i, e in enumerate(scenes))
    labels = [e.label for e in entries]
    if len(set(labels)) != len(labels):
        raise SpecError("a scene is listed twice", "scenes", source)
    return entries


def _seeds(seeds: Any, source: str) -> tuple[int, ...]:
    """``seeds``: a number of seeds (0, 1, …) or a list of distinct integers >= 0."""
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        if seeds < 1:
            raise SpecError("must be >= 1 (the number of seeds) or a list of seeds", "seeds",
                            source)
        seeds = list(range(seeds))
    if (not isinstance(seeds, list) or not seeds
            or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds)):
        raise SpecError("must be a number of seeds or a non-empty list of integers >= 0",
                        "seeds", source)
    if len(set(seeds)) != len(seeds):
        raise SpecError("a seed is listed twice", "seeds", source)
    return tuple(seeds)


def _metrics(metrics: Any, source: str) -> tuple[str, ...]:
    """``metrics``: names of :data:`KNOWN_METRICS` or ``counts.NAME``."""
    if not isinstance(metrics, list) or not metrics or not all(isinstance(m, str)
                                                               for m in metrics):
        raise SpecError("must be a non-empty list of metric names", "metrics", source)
    for i, m in enumerate(metrics):
        if m not in KNOWN_METRICS and not re.fullmatch(r"counts\.[a-z_]+", m):
            raise SpecError(f"unknown metric {m!r} (known: {', '.join(KNOWN_METRICS)}, "
                            "counts.NAME)", f"metrics[{i}]", source)
    return tuple(metrics)


def _check_distances(grid: tuple[tuple[str, tuple[Any, ...]], ...],
                     entries: tuple[SceneEntry, ...], source: str) -> None:
    """A swept ``distance_m`` needs every scene's own distance."""
    if "distance_m" in dict(grid):
        for i, e in enumerate(entries):
            if e.distance_m is None:
                raise SpecError("grid.distance_m needs the scene's own distance: write "
                                f"{{scene = {e.label!r}, distance_m = ...}}", f"scenes[{i}]",
                                source)


def read_spec(path: str | os.PathLike[str]) -> Spec:
    """Read a sweep spec (TOML if it ends in ``.toml``, else JSON) and validate each of its
    keys, loading its base scenes; :func:`clsonar.tools.sweep.load_spec` also validates
    every run."""
    path = Path(path)
    source = str(path)
    data = _read_spec_file(path)
    _check_keys(data, source)
    name = _name(data, path, source)
    entries = _scene_entries(data.get("scenes"), path.parent, source)
    seeds = _seeds(data.get("seeds", 1), source)
    metrics = _metrics(data.get("metrics", list(DEFAULT_METRICS)), source)
    preset = data.get("preset")
    if preset is not None:
        _check_preset(preset, "preset", source)
    grid = _grid(data.get("grid"), source)
    _check_pseudo_values(grid, source)
    _check_distances(grid, entries, source)
    return Spec(name, source, entries, grid, seeds, metrics, preset)
