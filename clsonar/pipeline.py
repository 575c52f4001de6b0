"""The whole mapping pipeline, stage by stage (DESIGN.md, "Data flow"; thesis §2.1.1).

``Scene → sensors → echoes → detections → raw map → filtered → occupied → thin → profile →
metrics``: :func:`run` calls each stage's module in turn, times it and keeps its result in a
:class:`RunResult`. Presets (:data:`PRESETS`) switch the detection, mapping and
post-processing settings between the thesis' methods (``thesis``) and ours (``best``, the
defaults of a scene file).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import __version__, metrics, post, rooms
from .echoes import EchoTable, compute_echoes
from .geometry import Geometry, build_geometry
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


def run(scene: Scene, *, device: str | None = None, context=None, preset: str | None = None,
        progress: Progress | None = None) -> RunResult:
    """Run the whole pipeline on ``scene`` and return every stage (:class:`RunResult`).

    ``device``/``context`` choose the OpenCL device (:func:`clsonar.opencl.get_context`);
    ``preset`` applies :data:`PRESETS` first; ``progress(stage, i, n)`` is called as each
    stage starts.
    """
    from . import mapping, signals
    from .opencl import get_context

    scene = apply_preset(scene, preset)
    ctx = context if context is not None else get_context(device)
    # Refuse a grid that cannot be held before any work is done (one clear message).
    mapping.check_map_memory(scene, scene.mapping.precision, ctx.devices[0],
                             host_bytes_per_cell=PIPELINE_BYTES_PER_CELL)
    clock = _Stopwatch(progress)

    clock.start("sensors")
    geom = build_geometry(scene)
    sensors = place_sensors(scene, geom)
    clock.start("echoes")
    echoes = compute_echoes(scene, sensors, context=ctx)
    clock.start("detection")
    detections = signals.detect(scene, sensors, echoes, context=ctx)
    clock.start("accumulation")
    point_sums = None
    ghosts = 0
    if scene.mapping.mode == "backprojection":
        dt, env = signals.envelopes(scene, sensors, echoes, context=ctx)
        raw = mapping.backproject(scene, sensors, pairs(sensors), env, dt, context=ctx)
    else:
        loci = mapping.as_loci(detections)
        if scene.mapping.reciprocal == "merge":
            loci = mapping.merge_reciprocal(loci, 6.0 * scene.transducer.pulse_sigma_s)
        if scene.mapping.mode == "tangents":
            points, source = mapping.tangent_points(
                scene, sensors, loci, isolated_bias_m=scene.mapping.isolated_bias_m)
            if scene.mapping.line_of_sight:
                seen = rooms.in_sight_of_map(scene, sensors.positions, points,
                                             loci.tx[source], loci.rx[source])
                ghosts = int(np.count_nonzero(~seen))
                points = points[seen]
            raw, point_sums = mapping.point_map(scene, points)
        elif scene.mapping.combine == "viewpoints":
            raw = mapping.count_viewpoints(
                scene, sensors, loci, lambda part: mapping.accumulate(scene, sensors, part,
                                                                      context=ctx))
        else:
            raw = mapping.accumulate(scene, sensors, loci, context=ctx)
    counts = {
        "transducers": len(sensors),
        "pairs": len(pairs(sensors)),
        # noise-free pairs without an echo, left out of detection (signals.scanned_slots)
        "pairs_skipped_silent": (0 if scene.signal.noise_std > 0 else len(pairs(sensors))
                                 - len({(int(t), int(r)) for t, r in zip(
                                     echoes.tx, echoes.rx, strict=True)})),
        "echoes": len(echoes),
        "detections": len(detections),
        "map_cells": int(raw.size),
        "cells_voted": int(np.count_nonzero(raw)),
        "ghost_points": ghosts,
    }
    front = RunResult(scene, geom, sensors, echoes, detections, raw, raw, raw, raw,
                      post.Profile(()), {}, clock.stop(), counts, _device_name(ctx),
                      point_sums)
    return rerun_post(front, scene.post, progress=progress)


def rerun_post(result: RunResult, settings: PostSettings | None = None, *,
               progress: Progress | None = None) -> RunResult:
    """``result`` with post-processing (filter → thinning → profile → metrics) run again.

    The stages before it (sensors, echoes, detection, accumulation) are reused as they are,
    so changing a :class:`~clsonar.scene.PostSettings` value costs only post-processing.
    """
    scene = result.scene if settings is None else dataclasses.replace(result.scene,
                                                                      post=settings)
    raw, point_sums = result.raw, result.point_sums
    clock = _Stopwatch(progress)
    clock.start("filter")
    filtered = post.low_pass(raw) if scene.post.filter == "mean3" else np.asarray(raw, float)
    level = post.occupancy_level(filtered, scene.post, points=point_sums is not None)
    occupied = post.binarize(filtered, level)
    clock.start("thinning")
    thin = post.thin_map(occupied, scene.post)
    clock.start("profile")
    profile = post.extract_profile(thin, scene.extent, scene.cell, scene.post, filtered,
                                   raw if point_sums is not None else None, point_sums)
    clock.start("metrics")
    result_metrics = metrics.evaluate(scene, result.geometry, result.sensors, result.echoes,
                                      profile.points, profile.vertices)
    seconds = {k: v for k, v in result.seconds.items() if k in STAGES[:4]}
    seconds.update(clock.stop())
    counts = {**{k: v for k, v in result.counts.items() if k not in _POST_COUNTS},
              "occupied_cells": int(np.count_nonzero(occupied)),
              "thin_cells": int(np.count_nonzero(thin)),
              "profile_curves": len(profile.curves),
              "profile_points": len(profile.points)}
    return dataclasses.replace(result, scene=scene, filtered=filtered, occupied=occupied,
                               thin=thin, profile=profile, metrics=result_metrics,
                               seconds=seconds, counts=counts)


_POST_COUNTS = ("occupied_cells", "thin_cells", "profile_curves", "profile_points")


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
