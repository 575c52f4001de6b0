"""The whole mapping pipeline, stage by stage (docs/design.md, "Data flow"; thesis §2.1.1).

``scene → sensors → echoes → detections → votes → line of sight → raw map → filtered →
occupied → thin → profile → metrics``: :func:`run` calls each stage's module in turn, in the
order of the data, times it and keeps its result in a :class:`RunResult`. No stage calls a
later one. The stages up to the votes (the *front*) read no post-processing setting and are
what :class:`StageCache` keeps; everything after them is :func:`post_process`, which
:func:`rerun_post` runs again on its own — so a run and a re-run of its post-processing are
the same computation. Presets (:data:`PRESETS`) switch the detection, mapping and
post-processing settings between the thesis' methods (``thesis``) and ours (``best``, the
defaults of a scene file).
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TypeVar, cast

import numpy as np

from . import checks, mapping, metrics, post, regions, sight, signals, steps
from . import rooms as roomwork
from .cache import StageCache as StageCache  # re-exported: pipeline.StageCache
from .cache import stage_keys
from .echoes import EchoTable, compute_echoes
from .errors import ClsonarError, SceneError
from .geometry import Geometry, build_geometry
from .mapping import Votes
from .opencl import device_name, get_context
from .placing import check_work as check_work  # re-exported: pipeline.check_work
from .placing import placed_sensors as placed_sensors  # re-exported
from .presets import PRESETS as PRESETS  # re-exported: pipeline.PRESETS
from .presets import Preset as Preset
from .presets import apply_preset
from .rooms import MOSAIC_BYTES_PER_CELL as MOSAIC_BYTES_PER_CELL  # re-exported
from .scene import (
    PostSettings,
    Scene,
    scene_to_dict,
)
from .sensors import SensorArray, pairs, place_sensors_together
from .signals import Detections
from .skips import SKIP_NAMES as SKIP_NAMES  # re-exported: pipeline.SKIP_NAMES
from .skips import Skips
from .survey import Survey, choose_settings, survey
from .version import __version__

#: The stages in the order of the data. The first four are the front (cached, no
#: post-processing setting read); ``sight`` (line of sight, then the map of the points left)
#: and the rest are post-processing (:func:`post_process`).
STAGES = ("sensors", "echoes", "detection", "accumulation", "sight", "filter", "thinning",
          "profile", "metrics")
FRONT_STAGES = STAGES[:4]

T = TypeVar("T")

Progress = Callable[[str, int, int], None]  # (stage, index from 1, number of stages)

#: Host memory a run holds per map cell: the raw map, the filtered map and its filter's
#: temporary (float64), the occupied and thin maps, the point sums of ``tangents``.
PIPELINE_BYTES_PER_CELL = 48


@dataclass(frozen=True, eq=False)
class RunResult:
    """Every stage of one run, with per-stage seconds, counters and metrics."""

    scene: Scene
    geometry: Geometry
    sensors: SensorArray
    echoes: EchoTable
    detections: Detections
    #: what the mapping method gave (None for a scene mapped room by room)
    votes: Votes | None
    raw: np.ndarray  # [ny, nx] accumulated votes (points: the points in sight)
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
    #: what the scene is and how it is scanned (None for a scene mapped room by room)
    survey: Survey | None = None
    #: per setting chosen from the scene (survey.AUTO_KEYS): why its value was used
    settings_why: dict[str, str] = dataclasses.field(default_factory=dict)
    #: the scene as asked for (preset applied; settings to be chosen still None); ``scene``
    #: is the one used, every setting filled in
    asked: Scene | None = None
    #: what the user should know about this run (clsonar.checks), one line each
    warnings: tuple[str, ...] = ()

    def report(self) -> dict[str, object]:
        """The JSON-ready ``report.json`` of docs/design.md's ``clsonar run``: the settings
        used (``scene`` holds them all, chosen ones filled in) and why each setting that
        can be chosen from the scene has its value."""
        s = self.scene
        return {
            "clsonar": __version__,
            "scene": s.name,
            "device": self.device,
            "settings": {k: scene_to_dict(s)[k] for k in ("detection", "mapping", "post")},
            "settings_why": self.settings_why,
            "counts": self.counts,
            "seconds": {**self.seconds, "total": sum(self.seconds.values())},
            "metrics": self.metrics,
            "warnings": list(self.warnings),
        }


#: :func:`run`'s ``placement`` (:func:`placed_sensors`' answer, or None) and ``maps_done``.
Placement = Callable[[], "tuple[Geometry, SensorArray] | None"]
MapsDone = Callable[[Scene, Geometry, np.ndarray, np.ndarray, np.ndarray], None]


def run(scene: Scene, *, device: str | None = None, context=None, preset: str | None = None,
        progress: Progress | None = None, skips: Skips = Skips(),
        cache: StageCache | None = None, placement: Placement | None = None,
        maps_done: MapsDone | None = None) -> RunResult:
    """Run the whole pipeline on ``scene`` and return every stage (:class:`RunResult`).

    ``device``/``context`` choose the OpenCL device (:func:`clsonar.opencl.get_context`);
    ``preset`` applies :data:`PRESETS` first; ``progress(stage, i, n)`` is called as each
    stage starts. ``skips`` (:class:`Skips`) says which unneeded work to leave out;
    ``cache`` (:class:`StageCache`) reuses the front stages whose inputs are unchanged.

    For a scene mapped as one map (not room by room; issue 16's overlapped work):
    ``placement()`` gives the sensors stage's geometry and transducers computed elsewhere
    (another process, the same code and bits; None: computed here); ``maps_done(scene,
    geometry, raw, filtered, thin)`` is told the result's once thinning is done (read-only).
    """
    scene = apply_preset(scene, preset)
    given = "file" if preset is None else f"preset {preset}"
    ctx = context if context is not None else get_context(device)
    rooms = check_work(scene, skips)
    if rooms is not None:
        return _run_rooms(scene, rooms, ctx, skips, progress, given)
    return _run_whole(scene, ctx, skips, cache, progress, given, placement=placement,
                      maps_done=maps_done)


def _run_whole(scene: Scene, ctx, skips: Skips, cache: StageCache | None,
               progress: Progress | None, given: str,
               placed: tuple[Geometry, SensorArray] | None = None, *,
               placement: Placement | None = None,
               maps_done: MapsDone | None = None) -> RunResult:
    """Every stage on ``scene`` as one map (a grid that cannot be held is refused before
    any work, with one clear message); ``placement``, ``maps_done``: :func:`run`'s."""
    mapping.check_map_memory(scene, scene.mapping.precision, ctx.devices[0],
                             host_bytes_per_cell=PIPELINE_BYTES_PER_CELL)
    keys = stage_keys(scene, device_name(ctx), skips) if cache is not None else {}
    front = _run_front(scene, ctx, skips, cache, keys, progress, given, placed, placement)
    if cache is None:
        return post_process(front, progress=progress, skips=skips, maps_done=maps_done)
    done = cache.get("post", keys["post"])
    if isinstance(done, RunResult):
        return _post_reused(front, done)
    # the truth reads the echoes (and the cell), which no setting chosen later changes
    truth_key = f"{keys['echoes']} {scene.cell!r}"

    def truth() -> tuple[np.ndarray, np.ndarray]:
        """The truth the metrics score against: it reads the echoes, not the detections."""
        found = cache.get("truth", truth_key)
        if found is None:
            found = metrics.lit_truth(front.scene, front.geometry, front.sensors,
                                      front.echoes)
            cache.put("truth", truth_key, found)
        return cast(tuple[np.ndarray, np.ndarray], found)

    done = post_process(front, progress=progress, skips=skips, truth=truth,
                        maps_done=maps_done)
    cache.put("post", keys["post"], done)
    return done


def _post_reused(front: RunResult, done: RunResult) -> RunResult:
    """``front`` with the post-processing of an earlier run whose every input was the same
    (``done``): its maps, profile, metrics and warnings, this run's front seconds and the
    post-processing stages at 0 s."""
    seconds = {**front.seconds, **dict.fromkeys(STAGES[len(FRONT_STAGES):], 0.0)}
    counts = {**done.counts, "stages_reused": len(STAGES)}
    return dataclasses.replace(done, scene=front.scene, asked=front.asked,
                               settings_why=front.settings_why, seconds=seconds,
                               counts=counts)


def _run_front(scene: Scene, ctx, skips: Skips, cache: StageCache | None,
               keys: dict[str, str], progress: Progress | None, given: str = "file",
               placed: tuple[Geometry, SensorArray] | None = None,
               placement: Placement | None = None) -> RunResult:
    """The front stages (sensors → echoes → detection → votes), each reused from ``cache``
    when its key (``keys``: :func:`~clsonar.cache.stage_keys`) is there; the result's maps
    and profile are still empty. The sensors are ``placed``, else ``placement()``'s, else
    computed here. After the
    sensors, the settings the scene leaves out are chosen from what it is
    (:mod:`clsonar.survey`; ``given`` names where the others come from)."""
    device = device_name(ctx)
    clock = _Stopwatch(progress)
    counts: dict[str, int] = {}
    reused: list[str] = []

    def stage(name: str, compute: Callable[[], tuple[T, dict[str, int]]]) -> T:
        """Run (or reuse) one stage: ``compute()`` gives its value and its counters."""
        clock.start(name)
        found = cache.get(name, keys[name]) if cache is not None else None
        if found is None:
            found = compute()
            if cache is not None:
                cache.put(name, keys[name], found)
        else:
            reused.append(name)
        value, stage_counts = cast(tuple[T, dict[str, int]], found)
        counts.update(stage_counts)
        return value

    geom, sensors = stage("sensors", lambda: (
        placed or (placement and placement()) or placed_sensors(scene), {}))
    mapping.check_pair_memory(scene, sensors)  # refused in one line before any echo
    asked = scene
    found = survey(scene, sensors, geom)
    scene, why = choose_settings(scene, found, given, geom)
    echoes = stage("echoes", lambda: _echoes(scene, sensors, ctx, skips))
    detections = stage("detection", lambda: _detect(scene, sensors, echoes, ctx, skips))
    votes = stage("accumulation", lambda: _votes(scene, sensors, echoes, detections, ctx,
                                                  skips))
    counts = {"transducers": len(sensors), "pairs": len(pairs(sensors)), **counts,
              "echoes": len(echoes), "detections": len(detections),
              "stages_reused": len(reused)}
    empty = np.zeros((0, 0))
    return RunResult(scene=scene, geometry=geom, sensors=sensors, echoes=echoes,
                     detections=detections, votes=votes, raw=empty, filtered=empty,
                     occupied=empty, thin=empty, profile=post.Profile(()), metrics={},
                     seconds=clock.stop(), counts=counts, device=device, survey=found,
                     settings_why=why, asked=asked)


def _run_rooms(scene: Scene, rooms: list[regions.Region], ctx, skips: Skips,
               progress: Progress | None, given: str) -> RunResult:
    """Run each room of ``scene`` on its own (:mod:`clsonar.regions`), in worker processes
    when there are enough rooms (:func:`clsonar.rooms.worker_count`), and put the results
    together: the maps as a mosaic on the scene's grid, the rooms' curves, vertices,
    transducers, echoes and detections side by side, metrics pooled, seconds and counts
    summed — the same in workers as one after another."""
    mapping.check_map_memory(scene, scene.mapping.precision, None,
                             host_bytes_per_cell=MOSAIC_BYTES_PER_CELL)
    maps = roomwork.empty_mosaic(scene.grid_shape)
    parts: list[RunResult] = []
    seconds: dict[str, float] = dict.fromkeys(STAGES, 0.0)
    counts: dict[str, int] = {}
    with _room_workers(len(rooms), ctx) as pool:  # traces and rooms in workers, or here
        start = time.perf_counter()
        placed = _sensors_together([room.scene for room in rooms], pool)
        seconds["sensors"] += time.perf_counter() - start
        jobs = [(room.scene, dataclasses.replace(skips, rooms=False), given, placed[k])
                for k, room in enumerate(rooms)]
        for k, (r, found) in enumerate(_rooms_mapped(jobs, ctx, pool, progress)):
            roomwork.add_to_mosaic(maps, found, rooms[k].row0, rooms[k].col0)
            for stage, t in r.seconds.items():
                seconds[stage] += t
            for key, value in r.counts.items():
                counts[key] = counts.get(key, 0) + value
            parts.append(r)  # its maps are in the mosaic: 400 rooms' were 2.7 GB
    counts.update(map_cells=int(maps["raw"].size),
                  cells_voted=int(np.count_nonzero(maps["raw"])), rooms_mapped=len(rooms))
    sensors, echoes, detections, profile = roomwork.side_by_side(parts)
    used = dataclasses.replace(scene, mapping=parts[0].scene.mapping, post=parts[0].scene.post)
    return RunResult(scene=used, geometry=build_geometry(scene), sensors=sensors,
                     echoes=echoes, detections=detections, votes=None, raw=maps["raw"],
                     filtered=maps["filtered"], occupied=maps["occupied"], thin=maps["thin"],
                     profile=profile, metrics=regions.combine_metrics([p.metrics for p in parts]),
                     seconds=seconds, counts=counts, device=device_name(ctx),
                     settings_why=parts[0].settings_why, asked=scene,
                     warnings=checks.run_warnings(scene, counts, sensors.poses))


_Job = tuple[Scene, Skips, str, tuple[Geometry, SensorArray]]


def _room_workers(rooms: int, ctx) -> contextlib.AbstractContextManager:
    """The worker processes that map ``rooms`` rooms (:class:`clsonar.rooms.Workers`, each
    with a context on ``ctx``'s device), or None (in a ``with``) to map them here: one
    worker or none is wanted, the device cannot be named, or no process can start."""
    n = roomwork.worker_count(rooms)
    spec = roomwork.device_spec(ctx) if n > 1 else None
    if spec is None:
        return contextlib.nullcontext()
    try:
        return roomwork.Workers(n, get_context, spec)
    except OSError:
        return contextlib.nullcontext()


def _rooms_mapped(jobs: list[_Job], ctx, pool: roomwork.Workers | None,
                  progress: Progress | None
                  ) -> Iterator[tuple[RunResult, roomwork.Sparse]]:
    """Each room's result without its maps, and its maps by their non-zero cells
    (:func:`_map_room`), in the order of ``jobs``: from the workers of ``pool``, telling
    ``progress`` and :func:`clsonar.steps.step` as each room is done, or one after another
    here, telling ``progress`` each stage."""
    n = len(STAGES)
    if pool is not None:
        for k, done in enumerate(pool.map(_map_room, jobs)):
            if progress is not None:
                progress(STAGES[-1], (k + 1) * n, len(jobs) * n)
            steps.step("rooms", k + 1, len(jobs))
            yield done
        return
    for k, job in enumerate(jobs):
        def tell(stage: str, i: int, n: int, k: int = k) -> None:
            if progress is not None:
                progress(stage, k * n + i, len(jobs) * n)

        done = _map_room(ctx, job, tell)
        steps.poll()
        yield done


def _map_room(ctx, job: _Job, progress: Progress | None = None
              ) -> tuple[RunResult, roomwork.Sparse]:
    """One room of a floor, every stage (:func:`_run_whole`; ``job``: its scene, skips,
    where its settings come from and its placed transducers): the result without its
    maps, votes and point sums, and its maps by their non-zero cells (what a worker
    process sends back: :func:`clsonar.rooms.sparse_maps`)."""
    scene, skips, given, placed = job
    r = _run_whole(scene, ctx, skips, None, progress, given, placed)
    return roomwork.without_maps(r), roomwork.sparse_maps(r)


def _sensors_together(scenes: list[Scene], pool: roomwork.Workers | None = None
                      ) -> list[tuple[Geometry, SensorArray]]:
    """:func:`placed_sensors` of every scene (the rooms of a floor), their wall-following
    traces side by side (:func:`_placed_together`), in ``pool``'s workers a run of rooms
    each; the first scene's error, if any, raised before any room is mapped."""
    if pool is None:
        return _placed_together(None, scenes)
    return [p for part in pool.map(_placed_together, roomwork.split(scenes, len(pool)))
            for p in part]


def _placed_together(ctx, scenes: list[Scene]) -> list[tuple[Geometry, SensorArray]]:
    """:func:`placed_sensors` of every scene, their wall-following traces run side by side
    (:func:`clsonar.sensors.place_sensors_together`, the same to the bit as one by one);
    the first scene's error, if any, raised (``ctx``: unused, as a worker's job)."""
    geoms = [build_geometry(scene) for scene in scenes]
    placed = place_sensors_together(scenes, geoms)
    for found in placed:
        if isinstance(found, SceneError):
            raise found
    return [(geom, cast(SensorArray, found)) for geom, found in zip(geoms, placed, strict=True)]


def _echoes(scene: Scene, sensors: SensorArray, ctx, skips: Skips
            ) -> tuple[EchoTable, dict[str, int]]:
    stats: dict[str, int] = {}
    table = compute_echoes(scene, sensors, context=ctx, skip_empty_pairs=skips.empty_pairs,
                           stats=stats)
    return table, stats


def _detect(scene: Scene, sensors: SensorArray, echoes: EchoTable, ctx, skips: Skips
            ) -> tuple[Detections, dict[str, int]]:
    stats: dict[str, int] = {}
    found = signals.detect(scene, sensors, echoes, context=ctx, skip_silent=skips.silent_pairs,
                           skip_quiet=skips.quiet_samples, stats=stats)
    return found, stats


def _votes(scene: Scene, sensors: SensorArray, echoes: EchoTable, detections: Detections,
           ctx, skips: Skips) -> tuple[Votes, dict[str, int]]:
    """The mapping method's votes (:data:`clsonar.mapping.METHODS`, by ``mapping.mode``)."""
    votes = mapping.map_votes(scene, sensors, echoes, detections, context=ctx,
                              tiles=skips.tiles)
    return votes, votes.counts


def rerun_post(result: RunResult, settings: PostSettings | None = None, *,
               progress: Progress | None = None, skips: Skips = Skips()) -> RunResult:
    """``result`` with post-processing run again, with ``settings`` if given.

    The front stages (sensors, echoes, detection, votes) are reused as they are; the rest
    — line of sight, the map of the points, filter → thinning → profile → metrics — is
    :func:`post_process`, the very code a full run ends with, so the result equals a fresh
    :func:`run` of the scene with those settings.
    """
    if result.votes is None:
        raise ClsonarError(f"{result.scene.name}: a scene mapped room by room cannot re-run "
                           "its post-processing alone; run it again")
    scene, why, asked = result.scene, result.settings_why, result.asked
    if settings is not None:
        assert result.survey is not None
        scene, chosen = choose_settings(dataclasses.replace(scene, post=settings),
                                        result.survey)
        why = {**why, **{k: v for k, v in chosen.items() if k.startswith("post.")}}
        asked = None if asked is None else dataclasses.replace(asked, post=settings)
    return post_process(dataclasses.replace(result, scene=scene, settings_why=why,
                                            asked=asked), progress=progress, skips=skips)


def post_process(front: RunResult, *, progress: Progress | None = None,
                 skips: Skips = Skips(),
                 truth: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None,
                 maps_done: MapsDone | None = None) -> RunResult:
    """Every stage after the votes, on ``front`` (a result whose front stages are done):
    the line of sight and the raw map (``sight``), then filter → thinning → profile →
    metrics (``truth()``: :func:`clsonar.metrics.lit_truth` of ``front``, from a cache;
    ``maps_done``: :func:`run`'s).
    Reads ``front.scene.post``; nothing it computes feeds an earlier stage."""
    assert front.votes is not None
    scene = front.scene
    clock = _Stopwatch(progress)
    clock.start("sight")
    drawn = _raw_map(scene, front.sensors, front.votes, skips)
    clock.start("filter")
    ends = front.votes.patch_ends
    only_patches = (ends is not None and len(ends) > 0 and front.votes.points is not None
                    and int(ends[-1]) == len(front.votes.points))
    tell = None if maps_done is None else lambda *maps: maps_done(scene, front.geometry, *maps)
    maps = _post_maps(scene, drawn, skips, clock, not only_patches, tell,
                      mapping.scan_heard(scene, front.sensors, front.detections))
    profile = _reflectors_in(maps.profile, front.votes, drawn.seen, scene)
    clock.start("metrics")
    result_metrics = metrics.evaluate(scene, front.geometry, front.sensors, front.echoes,
                                      profile.points, profile.vertices,
                                      None if truth is None else truth())
    seconds = {k: v for k, v in front.seconds.items() if k in FRONT_STAGES}
    seconds.update(clock.stop())
    counts = {**{k: v for k, v in front.counts.items() if k not in _POST_COUNTS},
              "map_cells": int(drawn.raw.size),
              "cells_voted": int(np.count_nonzero(drawn.raw)),
              "ghost_points": drawn.ghosts,
              **maps.counts, "profile_curves": len(profile.curves),
              "profile_points": len(profile.points)}
    return dataclasses.replace(front, raw=drawn.raw, filtered=maps.filtered,
                               occupied=maps.occupied, thin=maps.thin, profile=profile,
                               metrics=result_metrics, seconds=seconds, counts=counts,
                               point_sums=drawn.point_sums, point_window=drawn.window,
                               warnings=checks.run_warnings(scene, counts,
                                                            front.sensors.poses))


def _reflectors_in(profile: post.Profile, votes: Votes, seen: np.ndarray | None,
                   scene: Scene) -> post.Profile:
    """``profile`` with the reflectors the mapping fitted (``reflectors``: each patch's points
    in sight in place of the map's curves near them, and the point reflectors it located
    as vertices), none outside the extent."""
    if votes.patch_ends is None and votes.vertices is None:
        return profile
    keep = None if votes.points is None else (
        np.ones(len(votes.points), dtype=bool) if seen is None else seen)
    profile = post.with_vertices(post.with_patches(profile, votes.points, votes.patch_ends,
                                                   keep, PATCH_RADIUS_CELLS * scene.cell),
                                 votes.vertices)
    return post.within_extent(profile, scene.extent)


#: The map's profile gives way to the fitted patches within this many cells of them.
PATCH_RADIUS_CELLS = 2.0


@dataclass(frozen=True, eq=False)
class _Drawn:
    """The raw map post-processing starts from: the votes, or the map of the points in
    sight with their coordinate sums over ``window`` of cells (None: the whole grid)."""

    raw: np.ndarray
    point_sums: np.ndarray | None = None
    window: tuple[int, int, int, int] | None = None
    ghosts: int = 0
    seen: np.ndarray | None = None  # which of the votes' points were kept (line of sight)


def _raw_map(scene: Scene, sensors: SensorArray, votes: Votes, skips: Skips) -> _Drawn:
    """The raw map of ``votes``: a method's map as it is; estimated reflection points
    first checked for line of sight (:func:`clsonar.sight.in_sight_of_map`, when
    ``mapping.line_of_sight``), the ghosts dropped, then counted per cell."""
    if votes.points is None:
        assert votes.raw is not None
        return _Drawn(votes.raw)
    points, ghosts = votes.points, 0
    seen = np.ones(len(points), dtype=bool)
    if scene.mapping.line_of_sight and votes.tx is not None:  # points with their pairs
        assert votes.rx is not None
        seen = sight.in_sight_of_map(scene, sensors.positions, points, votes.tx, votes.rx,
                                     box=skips.empty_cells)
        ghosts = int(np.count_nonzero(~seen))
        points = points[seen]
    if not skips.empty_cells:
        raw, point_sums = mapping.point_map(scene, points)
        return _Drawn(raw, point_sums, None, ghosts, seen)
    window = mapping.points_window(scene, points)  # the sums only where points are
    counts, point_sums = mapping.point_map(scene, points, window)
    return _Drawn(post.embed(scene.grid_shape, _slices(window), counts), point_sums, window,
                  ghosts, seen)


@dataclass(frozen=True, eq=False)
class _PostMaps:
    filtered: np.ndarray
    occupied: np.ndarray
    thin: np.ndarray
    profile: post.Profile
    counts: dict[str, int]


def _post_maps(scene: Scene, drawn: _Drawn, skips: Skips, clock: _Stopwatch,
               trace: bool = True, maps_done: Callable[..., None] | None = None,
               heard: mapping.ScanHeard | None = None) -> _PostMaps:
    """Filter (eq. 2.4), threshold, thinning and profile of ``drawn``, within the cells
    that can hold anything (the points' window, then the voted box when
    ``skips.empty_cells``); the maps come back on the whole grid, told to ``maps_done``
    before the profile (which reads, never writes, them). Without ``trace`` the thin cells
    are not traced (every point is a fitted patch's); ``heard``: the scan along walls."""
    raw, point_sums, outer = drawn.raw, drawn.point_sums, drawn.window
    if point_sums is not None and outer is not None and not scene.post.subcell:
        # cell-centre profiles need the whole grid's indices: the sums on the whole grid
        point_sums, outer = post.embed((*raw.shape, 2), _slices(outer), point_sums), None
    outer = outer if point_sums is not None and outer is not None else (0, 0, *raw.shape)
    part = raw[_slices(outer)]  # post-processing needs no cell outside the points' window
    window, filtered, occupied = post.filter_box(part, scene.post, point_sums is not None,
                                                 box=skips.empty_cells)
    clock.start("thinning")
    thin = post.embed(part.shape, window, post.thin_map(occupied, scene.post))
    filtered = post.embed(part.shape, window, filtered)
    whole_thin = post.embed(raw.shape, _slices(outer), thin)
    whole_filtered = post.embed(raw.shape, _slices(outer), filtered)
    if maps_done is not None:
        maps_done(raw, whole_filtered, whole_thin)
    clock.start("profile")
    inner = (outer[0] + window[0].start, outer[1] + window[1].start,
             window[0].stop - window[0].start, window[1].stop - window[1].start)
    profile = (post.extract_profile(thin, scene.extent, scene.cell, scene.post, filtered,
                                    part if point_sums is not None else None, point_sums,
                                    occupied=occupied, origin=inner[:2], heard=heard)
               if trace else post.Profile(()))
    occupied = post.embed(raw.shape, _slices(inner), occupied)
    return _PostMaps(
        filtered=whole_filtered, occupied=occupied, thin=whole_thin, profile=profile,
        counts={"cells_post_processed": int(inner[2]) * int(inner[3]),
                "occupied_cells": int(np.count_nonzero(occupied)),
                "thin_cells": int(np.count_nonzero(thin)),
                "profile_curves": len(profile.curves),
                "profile_points": len(profile.points),
                "profile_points_dropped": profile.dropped})


def _slices(window: tuple[int, int, int, int]) -> tuple[slice, slice]:
    """The ``[rows, cols]`` of a ``(row0, col0, ny, nx)`` window."""
    row0, col0, ny, nx = window
    return slice(row0, row0 + ny), slice(col0, col0 + nx)


#: The counters :func:`post_process` sets (a re-run replaces them).
_POST_COUNTS = ("map_cells", "cells_voted", "ghost_points", "cells_post_processed",
                "occupied_cells", "thin_cells", "profile_curves", "profile_points",
                "profile_points_dropped")


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
