"""The whole mapping pipeline, stage by stage (DESIGN.md, "Data flow"; thesis §2.1.1).

``Scene → sensors → echoes → detections → raw map → filtered → occupied → thin → profile →
metrics``: :func:`run` calls each stage's module in turn, times it and keeps its result in a
:class:`RunResult`. Presets (:data:`PRESETS`) switch the detection, mapping and
post-processing settings between the thesis' methods (``thesis``) and ours (``best``, the
defaults of a scene file).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import __version__, mapping, metrics, post, regions, rooms, signals
from .echoes import EchoTable, compute_echoes
from .errors import ClsonarError
from .geometry import Geometry, build_geometry
from .opencl import get_context
from .scene import DetectionSettings, MappingSettings, PostSettings, Scene, scene_to_dict
from .sensors import SensorArray, pairs, place_sensors

STAGES = ("sensors", "echoes", "detection", "accumulation", "filter", "thinning", "profile",
          "metrics")

#: Settings of the thesis' method and of ours (the defaults of a scene file).
PRESETS: dict[str, dict[str, object]] = {
    "thesis": {
        "detection": DetectionSettings(mode="threshold"),
        "mapping": MappingSettings(mode="loci", weight="unit", reciprocal="both", combine="sum"),
        "post": PostSettings(filter="mean3", level=1e-6, thinning="thesis", fit="polynomial",
                             poly_order=7, subcell=False),
    },
    "best": {"detection": DetectionSettings(), "mapping": MappingSettings(),
             "post": PostSettings()},
}

Progress = Callable[[str, int, int], None]  # (stage, index from 1, number of stages)

#: Host memory a run holds per map cell: the raw map, the filtered map and its filter's
#: temporary (float64), the occupied and thin maps, the point sums of ``tangents``.
PIPELINE_BYTES_PER_CELL = 48


def apply_preset(scene: Scene, preset: str | None) -> Scene:
    """``scene`` with the detection/mapping/post settings of ``preset`` (None: unchanged)."""
    if preset is None:
        return scene
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r} (choose from {', '.join(PRESETS)})")
    return dataclasses.replace(scene, **PRESETS[preset])


@dataclass(frozen=True, eq=False)
class RunResult:
    """Every stage of one run, with per-stage seconds, counters and metrics."""

    scene: Scene
    geometry: Geometry
    sensors: SensorArray
    echoes: EchoTable
    detections: object  # clsonar.signals.Detections
    raw: np.ndarray  # [ny, nx] accumulated votes
    filtered: np.ndarray  # after the low-pass (eq. 2.4)
    occupied: np.ndarray  # bool, filtered ≥ level
    thin: np.ndarray  # bool, after thinning
    profile: post.Profile
    metrics: dict[str, object]
    seconds: dict[str, float]
    counts: dict[str, int]
    device: str
    point_sums: np.ndarray | None = None  # tangent-point sums per cell (sub-cell profile)
    #: (row0, col0, ny, nx): the cells ``point_sums`` covers (None: the whole grid)
    point_window: tuple[int, int, int, int] | None = None

    def report(self) -> dict[str, object]:
        """The JSON-ready ``report.json`` of DESIGN.md's ``clsonar run``."""
        s = self.scene
        return {
            "clsonar": __version__,
            "scene": s.name,
            "device": self.device,
            "settings": {k: scene_to_dict(s)[k] for k in ("detection", "mapping", "post")},
            "counts": self.counts,
            "seconds": {**self.seconds, "total": sum(self.seconds.values())},
            "metrics": self.metrics,
        }


def _device_name(context) -> str:
    d = context.devices[0]
    return f"{d.name.strip()} ({d.platform.name.strip()})"


@dataclass(frozen=True)
class Skips:
    """Work the pipeline leaves out because the scene does not need it; none of it changes
    the result. A switch set False does that work anyway, so ``clsonar bench`` can show
    what each saves; ``report.json`` counts what was skipped (``counts``)."""

    #: echoes: pairs whose beams meet no surface are not evaluated (echoes.pairs_in_view)
    empty_pairs: bool = True
    #: detection: noise-free pairs without an echo are not scanned (signals.scanned_slots)
    silent_pairs: bool = True
    #: detection: in a noise-free scene only the chunks of samples an echo reaches are
    #: synthesised and scanned (the rest of every signal is exactly 0)
    quiet_samples: bool = True
    #: accumulation: loci drawn tile by tile, empty tiles skipped (mapping.accumulate)
    tiles: bool = True
    #: post-processing: only the box of the voted cells is filtered and thinned
    #: (post.voted_box; line of sight's own pass too)
    empty_cells: bool = True
    #: separate closed rooms mapped one by one (regions.split_rooms): no pair across rooms,
    #: no wall of another room, no cell outside every room
    rooms: bool = True

    @classmethod
    def none(cls) -> Skips:
        """Every switch off: the work a scene does not need is done anyway."""
        return cls(**{f.name: False for f in dataclasses.fields(cls)})


SKIP_NAMES = tuple(f.name for f in dataclasses.fields(Skips))


class StageCache:
    """A content-keyed cache of the stages before post-processing (sensors, echoes,
    detection, accumulation): a stage is reused when every scene key it reads, the device
    and the skips are unchanged. Keeps the last ``size`` results of each stage."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._entries: dict[str, dict[str, object]] = {}

    def get(self, stage: str, key: str) -> object | None:
        return self._entries.get(stage, {}).get(key)

    def put(self, stage: str, key: str, value: object) -> None:
        entries = self._entries.setdefault(stage, {})
        entries.pop(key, None)
        entries[key] = value
        while len(entries) > self.size:
            entries.pop(next(iter(entries)))


#: The scene-file keys each stage reads (and, through its inputs, every earlier stage's).
STAGE_KEYS = {
    "sensors": ("extent", "surfaces", "sensors"),
    "echoes": ("medium", "transducer", "echo"),
    "detection": ("signal", "detection"),
    "accumulation": ("cell", "mapping"),
}


def stage_keys(scene: Scene, device: str, skips: Skips) -> dict[str, str]:
    """The cache key of each stage: a hash of the scene keys it and the stages before it
    read (:data:`STAGE_KEYS`), the device and the skips. Tangent points checked for line of
    sight also read the post-processing settings (rooms.in_sight_of_map)."""
    data = scene_to_dict(scene)
    keys, seen = {}, [device, repr(skips)]
    for stage, names in STAGE_KEYS.items():
        seen += [data.get(n) for n in names]
        if stage == "accumulation" and scene.mapping.mode == "tangents" \
                and scene.mapping.line_of_sight:
            seen.append(data.get("post"))
        keys[stage] = hashlib.sha256(json.dumps(seen, sort_keys=True).encode()).hexdigest()
    return keys


def run(scene: Scene, *, device: str | None = None, context=None, preset: str | None = None,
        progress: Progress | None = None, skips: Skips = Skips(),
        cache: StageCache | None = None) -> RunResult:
    """Run the whole pipeline on ``scene`` and return every stage (:class:`RunResult`).

    ``device``/``context`` choose the OpenCL device (:func:`clsonar.opencl.get_context`);
    ``preset`` applies :data:`PRESETS` first; ``progress(stage, i, n)`` is called as each
    stage starts. ``skips`` (:class:`Skips`) says which unneeded work to leave out;
    ``cache`` (:class:`StageCache`) reuses the stages whose inputs are unchanged.
    """
    scene = apply_preset(scene, preset)
    ctx = context if context is not None else get_context(device)
    rooms = regions.split_rooms(scene) if skips.rooms else None
    if rooms is not None:
        return _run_rooms(scene, rooms, ctx, skips, progress)
    # Refuse a grid that cannot be held before any work is done (one clear message).
    mapping.check_map_memory(scene, scene.mapping.precision, ctx.devices[0],
                             host_bytes_per_cell=PIPELINE_BYTES_PER_CELL)
    device_name = _device_name(ctx)
    keys = stage_keys(scene, device_name, skips) if cache is not None else {}
    clock = _Stopwatch(progress)
    reused: list[str] = []

    def stage(name: str, compute: Callable[[], tuple]) -> tuple:
        clock.start(name)
        value = cache.get(name, keys[name]) if cache is not None else None
        if value is None:
            value = compute()
            if cache is not None:
                cache.put(name, keys[name], value)
        else:
            reused.append(name)
        return value

    geom, sensors = stage("sensors", lambda: _sensors(scene))
    echoes, echo_stats = stage("echoes", lambda: _echoes(scene, sensors, ctx, skips))
    detections, detect_stats = stage("detection",
                                     lambda: _detect(scene, sensors, echoes, ctx, skips))
    raw, point_sums, point_window, ghosts, tile_counts = stage(
        "accumulation", lambda: _accumulate(scene, sensors, echoes, detections, ctx, skips))
    counts = {
        "transducers": len(sensors),
        "pairs": len(pairs(sensors)),
        **echo_stats,
        **detect_stats,
        "echoes": len(echoes),
        "detections": len(detections),
        "map_cells": int(raw.size),
        "cells_voted": int(np.count_nonzero(raw)),
        "ghost_points": ghosts,
        **tile_counts,
        "stages_reused": len(reused),
    }
    front = RunResult(scene, geom, sensors, echoes, detections, raw, raw, raw, raw,
                      post.Profile(()), {}, clock.stop(), counts, device_name, point_sums,
                      point_window)
    return rerun_post(front, scene.post, progress=progress, skips=skips)


#: Host memory the mosaic of a scene mapped room by room holds per cell: raw and filtered
#: maps (float32), the occupied and thin maps.
MOSAIC_BYTES_PER_CELL = 10


def _run_rooms(scene: Scene, rooms: list[regions.Region], ctx, skips: Skips,
               progress: Progress | None) -> RunResult:
    """Run each room of ``scene`` on its own (:mod:`clsonar.regions`) and put the results
    together: the maps as a mosaic on the scene's grid, the rooms' curves, vertices,
    transducers, echoes and detections side by side, metrics pooled, seconds and counts
    summed."""
    mapping.check_map_memory(scene, scene.mapping.precision, None,
                             host_bytes_per_cell=MOSAIC_BYTES_PER_CELL)
    shape = scene.grid_shape
    raw = np.zeros(shape, np.float32)
    filtered = np.zeros(shape, np.float32)
    occupied = np.zeros(shape, bool)
    thin = np.zeros(shape, bool)
    parts: list[RunResult] = []
    seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
    counts: dict[str, int] = {}
    inner = dataclasses.replace(skips, rooms=False)
    for k, room in enumerate(rooms):
        def tell(stage: str, i: int, n: int, k: int = k) -> None:
            if progress is not None:
                progress(stage, k * n + i, len(rooms) * n)

        r = run(room.scene, context=ctx, skips=inner, progress=tell)
        ny, nx = r.raw.shape
        window = (slice(room.row0, room.row0 + ny), slice(room.col0, room.col0 + nx))
        raw[window] += r.raw
        filtered[window] += r.filtered
        occupied[window] |= r.occupied
        thin[window] |= r.thin
        for stage, t in r.seconds.items():
            seconds[stage] += t
        for key, value in r.counts.items():
            counts[key] = counts.get(key, 0) + value
        # keep only what the whole floor needs of each room (its maps are in the mosaic)
        parts.append(dataclasses.replace(r, raw=None, filtered=None, occupied=None, thin=None,
                                         point_sums=None, point_window=None))
    counts.update(map_cells=int(raw.size), cells_voted=int(np.count_nonzero(raw)),
                  rooms_mapped=len(rooms))
    sensors = SensorArray(*(np.concatenate([getattr(p.sensors, f) for p in parts])
                            for f in ("positions", "headings_deg")),
                          np.concatenate(_offset_groups([p.sensors.groups for p in parts])),
                          np.concatenate([p.sensors.poses for p in parts]))
    first = np.cumsum([0] + [len(p.sensors) for p in parts])
    echoes = EchoTable(**_stack([p.echoes for p in parts], first, EchoTable))
    found = signals.Detections(**_stack([p.detections for p in parts], first,
                                        signals.Detections))
    profile = post.Profile(tuple(c for p in parts for c in p.profile.curves),
                           np.concatenate([p.profile.vertices for p in parts]))
    return RunResult(scene, build_geometry(scene), sensors, echoes, found, raw, filtered,
                     occupied, thin, profile,
                     regions.combine_metrics([p.metrics for p in parts]), seconds, counts,
                     _device_name(ctx))


def _offset_groups(groups: list[np.ndarray]) -> list[np.ndarray]:
    out, first = [], 0
    for g in groups:
        out.append(g + first)
        first += int(g.max()) + 1 if len(g) else 0
    return out


def _stack(tables: list, first: np.ndarray, kind) -> dict[str, np.ndarray]:
    """The columns of ``tables`` (echo tables or detections) one after another, their
    ``tx``/``rx`` moved by each room's first transducer index ``first``."""
    columns = {}
    for f in dataclasses.fields(kind):
        parts = [getattr(t, f.name) + (first[i] if f.name in ("tx", "rx") else 0)
                 for i, t in enumerate(tables)]
        columns[f.name] = np.concatenate(parts) if parts else np.zeros(0)
    return columns


def _sensors(scene: Scene) -> tuple[Geometry, SensorArray]:
    geom = build_geometry(scene)
    return geom, place_sensors(scene, geom)


def _echoes(scene: Scene, sensors: SensorArray, ctx, skips: Skips) -> tuple:
    stats: dict[str, int] = {}
    table = compute_echoes(scene, sensors, context=ctx, skip_empty_pairs=skips.empty_pairs,
                           stats=stats)
    return table, stats


def _detect(scene: Scene, sensors: SensorArray, echoes: EchoTable, ctx, skips: Skips) -> tuple:
    stats: dict[str, int] = {}
    found = signals.detect(scene, sensors, echoes, context=ctx, skip_silent=skips.silent_pairs,
                           skip_quiet=skips.quiet_samples, stats=stats)
    return found, stats


def _accumulate(scene: Scene, sensors: SensorArray, echoes: EchoTable, detections,
                ctx, skips: Skips) -> tuple:
    """The raw map, the tangent-point sums (or None) and the cells they cover (None: all),
    the number of ghost points and the tiled accumulation's counters."""
    if scene.mapping.mode == "backprojection":
        dt, env = signals.envelopes(scene, sensors, echoes, context=ctx)
        return (mapping.backproject(scene, sensors, pairs(sensors), env, dt, context=ctx), None,
                None, 0, {})
    loci = mapping.as_loci(detections)
    if scene.mapping.reciprocal == "merge":
        loci = mapping.merge_reciprocal(loci, 6.0 * scene.transducer.pulse_sigma_s)
    if scene.mapping.mode == "tangents":
        points, source = mapping.tangent_points(
            scene, sensors, loci, isolated_bias_m=scene.mapping.isolated_bias_m)
        ghosts = 0
        if scene.mapping.line_of_sight:
            seen = rooms.in_sight_of_map(scene, sensors.positions, points,
                                         loci.tx[source], loci.rx[source],
                                         box=skips.empty_cells)
            ghosts = int(np.count_nonzero(~seen))
            points = points[seen]
        if not skips.empty_cells:
            raw, point_sums = mapping.point_map(scene, points)
            return raw, point_sums, None, ghosts, {}
        window = mapping.points_window(scene, points)  # the sums only where points are
        counts, point_sums = mapping.point_map(scene, points, window)
        return post.embed(scene.grid_shape, _slices(window), counts), point_sums, window, \
            ghosts, {}
    tile_stats: list[mapping.AccumulationStats] = []

    def draw(part) -> np.ndarray:
        votes, stats = mapping.accumulate_with_stats(scene, sensors, part, context=ctx,
                                                     tiles=skips.tiles)
        tile_stats.append(stats)
        return votes

    raw = (mapping.count_viewpoints(scene, sensors, loci, draw)
           if scene.mapping.combine == "viewpoints" else draw(loci))
    return raw, None, None, 0, {
        "tiles_total": sum(t.tiles_total for t in tile_stats),
        "tiles_skipped": sum(t.tiles_skipped for t in tile_stats),
        "pixel_locus_tests": sum(t.pixel_locus_tests for t in tile_stats),
        "dense_pixel_locus_tests": sum(t.dense_tests for t in tile_stats)}


def rerun_post(result: RunResult, settings: PostSettings | None = None, *,
               progress: Progress | None = None, skips: Skips = Skips()) -> RunResult:
    """``result`` with post-processing (filter → thinning → profile → metrics) run again.

    The stages before it (sensors, echoes, detection, accumulation) are reused as they are,
    so changing a :class:`~clsonar.scene.PostSettings` value costs only post-processing.
    """
    if result.counts.get("rooms_mapped"):
        raise ClsonarError(f"{result.scene.name}: a scene mapped room by room cannot re-run "
                           "its post-processing alone; run it again")
    scene = result.scene if settings is None else dataclasses.replace(result.scene,
                                                                      post=settings)
    raw, point_sums, outer = result.raw, result.point_sums, result.point_window
    if point_sums is not None and outer is not None and not scene.post.subcell:
        # cell-centre profiles need the whole grid's indices: the sums on the whole grid
        point_sums, outer = post.embed((*raw.shape, 2), _slices(outer), point_sums), None
    outer = outer if point_sums is not None and outer is not None else (0, 0, *raw.shape)
    part = raw[_slices(outer)]  # post-processing needs no cell outside the points' window
    clock = _Stopwatch(progress)
    clock.start("filter")
    window, filtered, occupied = post.filter_box(part, scene.post, point_sums is not None,
                                                 box=skips.empty_cells)
    clock.start("thinning")
    thin = post.embed(part.shape, window, post.thin_map(occupied, scene.post))
    filtered = post.embed(part.shape, window, filtered)
    clock.start("profile")
    profile = post.extract_profile(thin, scene.extent, scene.cell, scene.post, filtered,
                                   part if point_sums is not None else None, point_sums)
    inner = (outer[0] + window[0].start, outer[1] + window[1].start,
             window[0].stop - window[0].start, window[1].stop - window[1].start)
    filtered = post.embed(raw.shape, _slices(outer), filtered)
    thin = post.embed(raw.shape, _slices(outer), thin)
    occupied = post.embed(raw.shape, _slices(inner), occupied)
    clock.start("metrics")
    result_metrics = metrics.evaluate(scene, result.geometry, result.sensors, result.echoes,
                                      profile.points, profile.vertices)
    seconds = {k: v for k, v in result.seconds.items() if k in STAGES[:4]}
    seconds.update(clock.stop())
    counts = {**{k: v for k, v in result.counts.items() if k not in _POST_COUNTS},
              "cells_post_processed": int(window[0].stop - window[0].start)
              * int(window[1].stop - window[1].start),
              "occupied_cells": int(np.count_nonzero(occupied)),
              "thin_cells": int(np.count_nonzero(thin)),
              "profile_curves": len(profile.curves),
              "profile_points": len(profile.points)}
    return dataclasses.replace(result, scene=scene, filtered=filtered, occupied=occupied,
                               thin=thin, profile=profile, metrics=result_metrics,
                               seconds=seconds, counts=counts)


def _slices(window: tuple[int, int, int, int]) -> tuple[slice, slice]:
    """The ``[rows, cols]`` of a ``(row0, col0, ny, nx)`` window."""
    row0, col0, ny, nx = window
    return slice(row0, row0 + ny), slice(col0, col0 + nx)


_POST_COUNTS = ("cells_post_processed", "occupied_cells", "thin_cells", "profile_curves",
                "profile_points")


class _Stopwatch:
    """Seconds spent in each stage; tells ``progress`` as each stage starts."""

    def __init__(self, progress: Progress | None) -> None:
        self.progress = progress
        self.seconds: dict[str, float] = {}
        self.current: str | None = None
        self.since = time.perf_counter()

    def start(self, name: str) -> None:
        self.stop()
        self.current = name
        if self.progress is not None:
            self.progress(name, STAGES.index(name) + 1, len(STAGES))

    def stop(self) -> dict[str, float]:
        now = time.perf_counter()
        if self.current is not None:
            self.seconds[self.current] = now - self.since
        self.current, self.since = None, now
        return self.seconds
