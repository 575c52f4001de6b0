"""``clsonar sweep``: Monte-Carlo sweeps of the pipeline, locally or on a Dask cluster.

A **sweep spec** (TOML or JSON, ``docs/sweep.md``) names base scenes, a parameter grid and
seeds; every (scene, grid point, seed) is one run of :func:`clsonar.pipeline.run`, and every
run is one row of a tidy table (parameters, seed, metrics, per-stage seconds, device, host).
The statistics are those the thesis plots against distance and noise (chapter 3, Figs 3.5,
3.6, 3.19, 3.20: RMS of eq. 2.6 over seeds).

- Grid keys are scene-file key paths (scene format v1, ``docs/scene-format.md``):
  ``signal.noise_std``, ``sensors.placement.distance_m``, ``surfaces[0].radius``. Each value
  is set in the scene's full dict (:func:`~clsonar.scene.scene_to_dict`) and the result is
  validated by :func:`~clsonar.scene.scene_from_dict`, so a wrong value fails with the scene
  loader's own message. Two more keys are not scene keys: ``preset`` (``thesis``/``best``,
  :data:`clsonar.pipeline.PRESETS`) and ``distance_m`` (a ``random-lines`` placement moved
  to that distance from the surface, :func:`clsonar.tools.reproduce.at_distance`; the scene entry
  declares its own distance).
- Seed ``k`` advances the placement and noise seeds by ``k``
  (:func:`clsonar.tools.reproduce.with_seed`), as ``clsonar reproduce`` does.
- Every run has a stable id, a hash of its final scene, preset, parameters and seed. Rows go
  to ``DIR/runs.jsonl`` as they finish: one line each, written with a single ``O_APPEND``
  write and ``fsync``; a line without its newline (a write cut short) is dropped when the
  table is read. So an interrupted sweep, run again, skips every finished run and redoes
  only the missing ones; ``DIR/table.csv`` (one row per planned run, in plan order) is
  rewritten atomically when a sweep stops, finished or not.
- Locally every run shares one OpenCL context (:func:`run_local`). With a Dask cluster
  (:func:`run_dask`) each worker builds its context once (:func:`worker_context`) and reuses
  it; rows stream back into the same table as runs finish; a worker that dies loses only its
  in-flight runs, which the scheduler gives to another worker.
"""

from __future__ import annotations

import csv
import hashlib
import io
import itertools
import json
import math
import os
import re
import socket
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import ClsonarError, SceneError
from ..files import read_text, write_atomic
from ..scene import Scene, scene_from_dict, scene_to_dict

#: Metrics a spec may collect: paths into :attr:`RunResult.metrics` (metrics.evaluate), or
#: ``counts.NAME`` into :attr:`RunResult.counts`.
KNOWN_METRICS = ("rms_m", "accuracy_m.rms", "accuracy_m.p95", "completeness.1cm",
                 "completeness.2cm", "completeness.5cm", "spurious_share", "insonified_m",
                 "coverage", "points", "vertices_found", "vertex_error_max_m")
DEFAULT_METRICS = ("rms_m", "accuracy_m.rms", "completeness.2cm")

#: Grid keys that are not scene-file keys (module docstring).
PSEUDO_KEYS = ("preset", "distance_m")

SPEC_KEYS = ("name", "scenes", "seeds", "metrics", "preset", "grid")
SCENE_ENTRY_KEYS = ("scene", "distance_m")

TABLE_JSONL = "runs.jsonl"
TABLE_CSV = "table.csv"
SWEEP_JSON = "sweep.json"


class SpecError(SceneError):
    """A sweep spec that cannot be read or is not valid: ``"FILE: KEY: message"``."""


# --------------------------------------------------------------------------- the spec


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


@dataclass(frozen=True, eq=False)
class Run:
    """One planned run: the final scene (parameters and seed applied) and its row's keys."""

    index: int
    label: str
    params: dict[str, Any]
    seed: int
    scene: Scene
    preset: str | None
    run_id: str


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


def _read_spec_file(path: Path) -> dict[str, Any]:
    source = str(path)
    text = read_text(path, SpecError)
    if path.suffix.lower() == ".toml":
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            raise SpecError("TOML specs need Python 3.11 or later: write the spec as JSON",
                            source=source) from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise SpecError(f"invalid TOML: {e}", source=source) from None
    else:
        def _constant(name: str):
            raise ValueError(f"{name} is not a number")
        try:
            data = json.loads(text, parse_constant=_constant)
        except (json.JSONDecodeError, ValueError) as e:
            raise SpecError(f"invalid JSON: {e}", source=source) from None
    if not isinstance(data, dict):
        raise SpecError("must be a table (TOML) or an object (JSON)", source=source)
    return data


def _scene_entry(entry: Any, key: str, base: Path, source: str) -> SceneEntry:
    from ..files import bundled_scenes
    from ..scene import load_scene

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


def _type_name(v: Any) -> str:
    return {bool: "true/false", str: "a string", dict: "a table", list: "a list",
            type(None): "null"}.get(type(v), "a number")


def load_spec(path: str | os.PathLike[str]) -> Spec:
    """Read and validate a sweep spec (TOML if it ends in ``.toml``, else JSON).

    Every run is expanded and its scene validated here, so a bad spec fails with one
    :class:`SpecError` (or the scene loader's :class:`SceneError`) before anything runs.
    """
    from ..pipeline import PRESETS

    path = Path(path)
    source = str(path)
    data = _read_spec_file(path)
    for k in data:
        if k not in SPEC_KEYS:
            raise SpecError(f"unknown key (allowed: {', '.join(SPEC_KEYS)})", k, source)
    name = data.get("name", path.stem)
    if not isinstance(name, str):
        raise SpecError(f"must be a string, not {_type_name(name)}", "name", source)
    scenes = data.get("scenes")
    if isinstance(scenes, (str, dict)):
        scenes = [scenes]
    if not isinstance(scenes, list) or not scenes:
        raise SpecError("must be a non-empty list of scene files or bundled scene names",
                        "scenes", source)
    entries = tuple(_scene_entry(e, f"scenes[{i}]", path.parent, source)
                    for i, e in enumerate(scenes))
    labels = [e.label for e in entries]
    if len(set(labels)) != len(labels):
        raise SpecError("a scene is listed twice", "scenes", source)
    seeds = data.get("seeds", 1)
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
    metrics = data.get("metrics", list(DEFAULT_METRICS))
    if not isinstance(metrics, list) or not metrics or not all(isinstance(m, str)
                                                               for m in metrics):
        raise SpecError("must be a non-empty list of metric names", "metrics", source)
    for i, m in enumerate(metrics):
        if m not in KNOWN_METRICS and not re.fullmatch(r"counts\.[a-z_]+", m):
            raise SpecError(f"unknown metric {m!r} (known: {', '.join(KNOWN_METRICS)}, "
                            "counts.NAME)", f"metrics[{i}]", source)
    preset = data.get("preset")
    if preset is not None and preset not in PRESETS:
        raise SpecError(f"must be one of {', '.join(map(repr, PRESETS))}, not {preset!r:.40}",
                        "preset", source)
    grid = _grid(data.get("grid"), source)
    for key, values in grid:
        for v in values:
            if key == "preset" and v not in PRESETS:
                raise SpecError(f"must be one of {', '.join(map(repr, PRESETS))}, "
                                f"not {v!r:.40}", "grid.preset", source)
            if key == "distance_m" and (isinstance(v, bool) or not isinstance(v, (int, float))
                                        or not v > 0):
                raise SpecError(f"must be numbers > 0, not {v!r:.40}", "grid.distance_m",
                                source)
    if "distance_m" in dict(grid):
        for i, e in enumerate(entries):
            if e.distance_m is None:
                raise SpecError("grid.distance_m needs the scene's own distance: write "
                                f"{{scene = {e.label!r}, distance_m = ...}}", f"scenes[{i}]",
                                source)
    spec = Spec(name, source, entries, grid, tuple(seeds), tuple(metrics), preset)
    plan(spec)  # validates every run's scene
    return spec


# --------------------------------------------------------------------------- the plan


def run_id(scene: Scene, preset: str | None, params: dict[str, Any], seed: int) -> str:
    """A stable id of a run: a hash of its final scene, preset, parameters, seed and the
    clsonar version (a sweep resumed by another version redoes its runs)."""
    from ..version import __version__

    text = json.dumps({"scene": scene_to_dict(scene), "preset": preset, "params": params,
                       "seed": seed, "clsonar": __version__}, sort_keys=True,
                      allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def make_run(index: int, label: str, scene: Scene, params: dict[str, Any], seed: int,
             preset: str | None) -> Run:
    """A :class:`Run` of ``scene`` (parameters already applied) at seed ``seed``."""
    from .variants import with_seed

    seeded = with_seed(scene, seed)
    return Run(index, label, dict(params), seed, seeded, preset,
               run_id(seeded, preset, params, seed))


def _apply(spec: Spec, entry: SceneEntry, params: dict[str, Any]) -> Scene:
    """``entry``'s scene with the scene-key parameters set (validated) and moved to
    ``distance_m`` if that is swept."""
    from .variants import at_distance

    data = scene_to_dict(entry.scene)
    for key, value in params.items():
        if key in PSEUDO_KEYS:
            continue
        try:
            data = set_key(data, key, value)
        except KeyError as e:
            raise SpecError(f"unknown key path in scene {entry.label!r}: {e.args[0]}",
                            f"grid.{key}", spec.source) from None
    where = ", ".join(f"{k}={json.dumps(v)}" for k, v in params.items())
    scene = scene_from_dict(data, source=f"{spec.source} ({entry.label}, {where})")
    if "distance_m" in params:
        try:
            scene = at_distance(scene, entry.distance_m, float(params["distance_m"]))
        except ValueError as e:
            raise SpecError(str(e), "grid.distance_m", spec.source) from None
    return scene


def plan(spec: Spec) -> list[Run]:
    """Every run of ``spec``, in order: scenes × grid (first key slowest) × seeds."""
    runs: list[Run] = []
    keys = spec.parameters
    for entry in spec.scenes:
        for values in itertools.product(*(v for _, v in spec.grid)):
            params = dict(zip(keys, values, strict=True))
            scene = _apply(spec, entry, params)
            preset = params.get("preset", spec.preset)
            for seed in spec.seeds:
                runs.append(make_run(len(runs), entry.label, scene, params, seed, preset))
    return runs


# --------------------------------------------------------------------------- one run


def metric_value(result, name: str) -> Any:
    """The metric ``name`` (``a.b`` paths into ``result.metrics``, ``counts.x`` into
    ``result.counts``) as a plain JSON value; None where the scene has no such metric."""
    head, _, rest = name.partition(".")
    value: Any = result.counts if head == "counts" else result.metrics.get(head)
    if head == "counts":
        value = value.get(rest)
    elif rest:
        value = value.get(rest) if isinstance(value, dict) else None
    if value is None or isinstance(value, str):
        return value
    value = float(value) if not isinstance(value, (bool, int)) else value
    return value if not isinstance(value, float) or math.isfinite(value) else None


def row_of(run: Run, result, metrics: Sequence[str]) -> dict[str, Any]:
    """The table row of ``run`` from its :class:`~clsonar.pipeline.RunResult`."""
    from ..pipeline import STAGES

    row: dict[str, Any] = {"run": run.run_id, "index": run.index, "scene": run.label,
                           **run.params, "seed": run.seed}
    row.update({m: metric_value(result, m) for m in metrics})
    row.update({f"seconds.{s}": float(result.seconds.get(s, 0.0)) for s in STAGES})
    row["seconds.total"] = float(sum(result.seconds.values()))
    row["device"] = result.device
    row["host"] = socket.gethostname()
    return row


_CONTEXTS: dict[str | None, Any] = {}


def worker_context(device: str | None = None):
    """The OpenCL context of this process for ``device``, built on first use and reused by
    every later run (one per Dask worker process)."""
    if device not in _CONTEXTS:
        from ..opencl import get_context

        _CONTEXTS[device] = get_context(device)
    return _CONTEXTS[device]


def run_one(run: Run, metrics: Sequence[str], device: str | None = None,
            context=None) -> dict[str, Any]:
    """Run the pipeline on ``run`` and return its row (the task a Dask worker executes)."""
    from ..pipeline import run as run_pipeline

    ctx = context if context is not None else worker_context(device)
    result = run_pipeline(run.scene, context=ctx, preset=run.preset)
    return row_of(run, result, metrics)


# --------------------------------------------------------------------------- the table


class RunTable:
    """The rows of a sweep, one JSON line per finished run in ``DIR/runs.jsonl``.

    :meth:`append` writes a whole line with one ``O_APPEND`` write and ``fsync``s it;
    :meth:`rows` drops a last line cut short (no newline), so a row is either there whole
    or not at all.
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self.path = self.folder / TABLE_JSONL

    def rows(self) -> dict[str, dict[str, Any]]:
        """The finished rows by run id (the first row of an id wins)."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return {}
        complete = data[:data.rfind(b"\n") + 1]
        out: dict[str, dict[str, Any]] = {}
        for number, line in enumerate(complete.splitlines(), 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                raise ClsonarError(f"{self.path}: line {number}: not a JSON row; move the "
                                   "file away to start the sweep afresh") from None
            out.setdefault(row["run"], row)
        return out

    def repair(self) -> None:
        """Cut a last line that was cut short, so appended rows start on a line of their own."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return
        end = data.rfind(b"\n") + 1
        if end != len(data):
            with open(self.path, "r+b") as f:
                f.truncate(end)
                os.fsync(f.fileno())

    def append(self, row: dict[str, Any]) -> None:
        """Add one finished run's row, durably."""
        line = (json.dumps(row, allow_nan=False) + "\n").encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line)
            os.fsync(fd)
        finally:
            os.close(fd)


def columns(parameters: Sequence[str], metrics: Sequence[str]) -> list[str]:
    """The table's columns, in order."""
    from ..pipeline import STAGES

    return (["run", "index", "scene", *parameters, "seed", *metrics]
            + [f"seconds.{s}" for s in (*STAGES, "total")] + ["device", "host"])


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


def table_csv(rows: Iterable[dict[str, Any]], cols: Sequence[str]) -> str:
    """The tidy table as CSV text: one row per run, in plan order."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for row in sorted(rows, key=lambda r: r["index"]):
        w.writerow([_cell(row.get(c)) for c in cols])
    return buf.getvalue()


# --------------------------------------------------------------------------- running

Progress = Callable[[int, int, Run], None]  # (runs finished, runs planned, the last run)


class _Lock:
    """An exclusive lock on the folder's table (``flock``): one sweep writes to a folder at
    a time."""

    def __init__(self, folder: Path) -> None:
        self.path = folder / TABLE_JSONL
        self.fd: int | None = None

    def __enter__(self) -> _Lock:
        import fcntl

        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self.fd)
            raise ClsonarError(f"{self.path.parent}: another sweep is writing there") from None
        return self

    def __exit__(self, *exc) -> None:
        if self.fd is not None:
            os.close(self.fd)


def _header(spec: Spec, runs: list[Run]) -> dict[str, Any]:
    return {"name": spec.name, "spec": spec.source, "parameters": list(spec.parameters),
            "metrics": list(spec.metrics), "seeds": list(spec.seeds),
            "scenes": [e.label for e in spec.scenes], "runs": [r.run_id for r in runs]}


def sweep(spec: Spec, out: str | os.PathLike[str], *, device: str | None = None,
          client=None, progress: Progress | None = None) -> list[dict[str, Any]]:
    """Run every run of ``spec`` not already in ``out``'s table and return all the rows,
    in plan order.

    Locally (``client`` None) on ``device``; else on the Dask cluster of ``client`` (a
    ``dask.distributed.Client``), each worker on its own ``device``. Writes
    ``out/sweep.json`` (the plan), ``out/runs.jsonl`` (rows as they finish) and
    ``out/table.csv`` (when it stops, finished or interrupted).
    """
    runs = plan(spec)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with _Lock(out):
        table = RunTable(out)
        table.repair()
        write_atomic(out / SWEEP_JSON, (json.dumps(_header(spec, runs), indent=1)
                                        + "\n").encode())
        try:
            if client is None:
                run_local(runs, table, spec.metrics, device=device, progress=progress)
            else:
                run_dask(runs, table, spec.metrics, client, device=device, progress=progress)
        finally:
            done = table.rows()
            rows = [done[r.run_id] for r in runs if r.run_id in done]
            write_atomic(out / TABLE_CSV, table_csv(rows, columns(spec.parameters,
                                                                  spec.metrics)).encode())
    return rows


def _todo(runs: list[Run], table: RunTable) -> tuple[list[Run], int]:
    done = table.rows()
    return [r for r in runs if r.run_id not in done], sum(r.run_id in done for r in runs)


def run_local(runs: list[Run], table: RunTable, metrics: Sequence[str], *,
              device: str | None = None, context=None,
              progress: Progress | None = None) -> list[dict[str, Any]]:
    """Run, in this process and in order, every run not yet in ``table``; append each row
    as it finishes. Returns the new rows."""
    todo, finished = _todo(runs, table)
    ctx = context if context is not None else (worker_context(device) if todo else None)
    new = []
    for run in todo:
        row = run_one(run, metrics, context=ctx)
        table.append(row)
        new.append(row)
        finished += 1
        if progress is not None:
            progress(finished, len(runs), run)
    return new


def run_dask(runs: list[Run], table: RunTable, metrics: Sequence[str], client, *,
             device: str | None = None, progress: Progress | None = None,
             retries: int = 2, task: Callable[..., dict[str, Any]] | None = None
             ) -> list[dict[str, Any]]:
    """Send every run not yet in ``table`` to the Dask cluster of ``client`` and append
    each row as it comes back, in the order they finish. Returns the new rows.

    A run whose worker dies is rescheduled by Dask on another worker; a run that raises
    is retried ``retries`` times. ``task`` replaces :func:`run_one` (tests).
    """
    from distributed import as_completed

    todo, finished = _todo(runs, table)
    fn = task or run_one
    futures = {client.submit(fn, run, tuple(metrics), device, key=f"clsonar-{run.run_id}",
                             pure=False, retries=retries): run for run in todo}
    new = []
    try:
        for future in as_completed(futures):
            row = future.result()
            table.append(row)
            new.append(row)
            finished += 1
            if progress is not None:
                progress(finished, len(runs), futures[future])
    finally:
        for future in futures:
            if not future.done():
                future.cancel()
    return new


def connect(scheduler: str):
    """A ``dask.distributed.Client`` of the cluster at ``scheduler`` (``tcp://HOST:PORT``)."""
    try:
        from distributed import Client
    except ModuleNotFoundError:
        raise ClsonarError("--scheduler needs dask.distributed: pip install "
                           "'clsonar[dask]'") from None
    try:
        return Client(scheduler, timeout="10s")
    except (OSError, TimeoutError, ValueError) as e:
        raise ClsonarError(f"--scheduler {scheduler}: cannot reach the Dask scheduler "
                           f"({type(e).__name__}: {e})".replace("\n", " ")) from None


class ProgressBar:
    """``[#####.....] 12/40  30 %  ETA 1m05s  plane-2m signal.noise_std=0.4 seed 2`` on one
    rewritten line of a terminal's stderr (nothing otherwise); the ETA comes from the runs
    finished in this session."""

    def __init__(self, enabled: bool = True, stream=None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled and self.stream.isatty()
        self.start = time.perf_counter()
        self.first: int | None = None

    def __call__(self, finished: int, total: int, run: Run) -> None:
        if self.first is None:
            self.first = finished - 1
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        eta = elapsed / (finished - self.first) * (total - finished)
        width = 24
        bar = "#" * round(width * finished / total)
        what = " ".join([run.label, *(f"{k}={_short(v)}" for k, v in run.params.items()),
                         f"seed {run.seed}"])
        print(f"\r[{bar:.<{width}}] {finished}/{total} {100 * finished / total:3.0f} % "
              f"ETA {_duration(eta)}  {what[:60]:<60}", end="", file=self.stream,
              flush=True)

    def done(self) -> None:
        if self.enabled and self.first is not None:
            print(file=self.stream)


def _short(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else json.dumps(v) if not isinstance(v, str) else v


def _duration(seconds: float) -> str:
    s = round(seconds)
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else (
        f"{s // 60}m{s % 60:02d}s" if s >= 60 else f"{s}s")


def read_sweep(folder: str | os.PathLike[str]) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """A sweep folder's plan (``sweep.json``) and its finished rows, in plan order."""
    folder = Path(folder)
    try:
        header = json.loads((folder / SWEEP_JSON).read_text())
    except FileNotFoundError:
        raise ClsonarError(f"{folder}: no {SWEEP_JSON} here: not a sweep folder (run "
                           "'clsonar sweep SPEC --out DIR' first)") from None
    except (OSError, ValueError) as e:
        raise ClsonarError(f"{folder / SWEEP_JSON}: cannot read: {e}") from None
    done = RunTable(folder).rows()
    return header, [done[i] for i in header["runs"] if i in done]

