"""``clsonar bench``: run time against error, side by side with a plain NumPy baseline.

Two measurements per scene, every timing the best of ``repeat`` runs (these machines are
shared; ratios taken in one run are what to compare, absolute seconds wander):

- **pipeline**: the whole pipeline (:func:`clsonar.run`) under the thesis-faithful settings
  (preset ``thesis``) and ours (the scene's own settings): seconds per stage and in all,
  and the error — eq. 2.6 RMS where the scene is one wall, the accuracy RMS always, and the
  completeness within 2 cm. This is the run-time-against-error table.
- **accumulation**: the thesis' locus accumulation (thesis §2.1.1 part 4: a vote where
  ``| |p−T| + |p−R| − c·τ |`` is within the band, inside both beams) of the scene's
  detections over every pixel, by the OpenCL kernel in float32 and float64 and by the
  NumPy float64 reference (:func:`clsonar.mapping.accumulate_reference`, the vectorised
  program a user would otherwise write), with the speed ratio, the pixel-locus tests per
  second, and whether the maps agree (float64: identical; float32: share of equal pixels).

Results go to ``bench.md`` and ``bench.json``, written atomically.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .scene import Scene, load_scene, write_atomic

#: The scenes benchmarked by default: the thesis' shapes at their first distance and rooms.
DEFAULT_SCENES = ("plane-2m", "corner-4m", "edge-1m", "cylinder-2.1m", "sinusoid-1m", "room",
                  "room-cylinder")

#: Settings compared in the pipeline table: the thesis' methods, and the scene's own (ours).
SETTINGS = (("thesis", "thesis"), ("best", None))


@dataclass(frozen=True)
class PipelineRow:
    """One scene under one setting: seconds per stage, total, and the error."""

    scene: str
    settings: str
    seconds: dict[str, float]
    total_s: float
    rms_m: float | None
    accuracy_m: float | None
    completeness_2cm: float | None


@dataclass(frozen=True)
class AccumulationRow:
    """The locus accumulation of one scene's detections: OpenCL against NumPy."""

    scene: str
    pixels: int
    loci: int
    numpy_s: float | None
    opencl_s: dict[str, float]
    tests_per_s: dict[str, float]
    speedup: dict[str, float | None]
    float64_identical: bool | None
    float32_equal_share: float | None


def best_time(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    """The shortest of ``repeat`` wall-clock runs of ``fn`` and its last result."""
    best, result = float("inf"), None
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def bench_pipeline(scene: Scene, settings: str, preset: str | None, context,
                   repeat: int) -> PipelineRow:
    """Time the whole pipeline on ``scene`` (the run with the shortest total counts)."""
    from .pipeline import run

    runs = [run(scene, context=context, preset=preset) for _ in range(max(1, repeat))]
    fastest = min(runs, key=lambda r: sum(r.seconds.values()))
    m = fastest.metrics
    return PipelineRow(scene.name, settings, dict(fastest.seconds),
                       float(sum(fastest.seconds.values())), m["rms_m"],
                       m["accuracy_m"]["rms"], m["completeness"]["2cm"])


def loci_scene(scene: Scene) -> Scene:
    """``scene`` with the thesis' accumulation: votes of weight 1 on every detection's
    locus, summed, both (T, R) and (R, T) drawn."""
    mapping = dataclasses.replace(scene.mapping, mode="loci", weight="unit", combine="sum",
                                  reciprocal="both")
    return dataclasses.replace(scene, mapping=mapping)


def bench_accumulation(scene: Scene, context, repeat: int,
                       numpy: bool = True) -> AccumulationRow:
    """Time the locus accumulation of ``scene``'s detections (module docstring)."""
    from . import mapping, signals
    from .echoes import compute_echoes
    from .geometry import build_geometry
    from .opencl import has_fp64
    from .sensors import place_sensors

    scene = loci_scene(scene)
    sensors = place_sensors(scene, build_geometry(scene))
    echoes = compute_echoes(scene, sensors, context=context)
    loci = mapping.as_loci(signals.detect(scene, sensors, echoes, context=context))
    pixels = int(np.prod(scene.grid_shape))
    precisions = ("float32", "float64") if has_fp64(context) else ("float32",)
    maps, seconds = {}, {}
    for precision in precisions:
        mapping.accumulate(scene, sensors, loci, context=context, precision=precision)  # build
        seconds[precision], maps[precision] = best_time(
            lambda p=precision: mapping.accumulate(scene, sensors, loci, context=context,
                                                   precision=p), repeat)
    numpy_s, reference = None, None
    if numpy:
        numpy_s, reference = best_time(
            lambda: mapping.accumulate_reference(scene, sensors, loci), 1)
    tests = float(pixels) * len(loci)
    return AccumulationRow(
        scene.name, pixels, len(loci), numpy_s, seconds,
        {p: tests / s for p, s in seconds.items()},
        {p: (numpy_s / s if numpy_s else None) for p, s in seconds.items()},
        bool(np.array_equal(maps["float64"], reference))
        if reference is not None and "float64" in maps else None,
        float(np.mean(maps["float32"] == reference)) if reference is not None else None)


def _cm(value: float | None) -> str:
    return "–" if value is None else f"{value * 100:.2f}"


def _ratio(value: float | None) -> str:
    return "–" if value is None else f"{value:.0f}×"


def markdown(pipeline: list[PipelineRow], accumulation: list[AccumulationRow],
             device: str, command: str) -> str:
    """The report: the run-time-against-error table and the accumulation table."""
    stages = [s for s in pipeline[0].seconds] if pipeline else []
    lines = ["# Benchmark", "", f"Regenerate with `{command}` (device: {device}). Timings are "
             "the best of the repeats; compare the ratios, absolute seconds wander on a "
             "shared machine.", "", "## Run time against error (whole pipeline)", "",
             "| scene | settings | total s | " + " | ".join(stages) +
             " | RMS eq. 2.6 (cm) | accuracy RMS (cm) | completeness ≤ 2 cm |",
             "| --- | --- |" + " ---: |" * (len(stages) + 4)]
    for r in pipeline:
        comp = "–" if r.completeness_2cm is None else f"{r.completeness_2cm * 100:.0f} %"
        lines.append(f"| {r.scene} | {r.settings} | {r.total_s:.2f} | "
                     + " | ".join(f"{r.seconds.get(s, 0.0):.2f}" for s in stages)
                     + f" | {_cm(r.rms_m)} | {_cm(r.accuracy_m)} | {comp} |")
    lines += ["", "`thesis`: threshold detection, loci summed, eq. 2.5 thinning, polynomial "
              "fit. `best`: the scene's own settings (envelope detection, tangent points, "
              "Guo–Hall thinning, spline or walls fit).", "",
              "## Locus accumulation: OpenCL against NumPy float64", "",
              "| scene | pixels | loci | NumPy s | float32 s | float64 s | float32 tests/s | "
              "float32 speed-up | float64 speed-up | float64 map identical | float32 equal "
              "pixels |", "| --- |" + " ---: |" * 10]
    for a in accumulation:
        f64 = a.opencl_s.get("float64")
        lines.append(
            f"| {a.scene} | {a.pixels:,} | {a.loci} | "
            f"{'–' if a.numpy_s is None else f'{a.numpy_s:.2f}'} | "
            f"{a.opencl_s['float32']:.3f} | {'–' if f64 is None else f'{f64:.3f}'} | "
            f"{a.tests_per_s['float32']:.2e} | {_ratio(a.speedup.get('float32'))} | "
            f"{_ratio(a.speedup.get('float64'))} | "
            f"{'–' if a.float64_identical is None else ('yes' if a.float64_identical else 'NO')}"
            f" | {'–' if a.float32_equal_share is None else f'{a.float32_equal_share:.6f}'} |")
    lines += ["", "Dense accumulation: every pixel tests every locus (no tiling yet); "
              "tests/s = pixels × loci / seconds."]
    return "\n".join(lines) + "\n"


def bench(out: Path, scenes_dir: Path | None = None, names: tuple[str, ...] = DEFAULT_SCENES,
          *, repeat: int = 3, numpy: bool = True, device: str | None = None,
          progress: Callable[[int, int, str], None] | None = None,
          command: str = "clsonar bench --out docs/bench"
          ) -> tuple[list[PipelineRow], list[AccumulationRow]]:
    """Benchmark the ``names`` scenes of ``scenes_dir`` (default: the bundled ones) and write
    ``bench.md`` and ``bench.json`` into ``out``."""
    from .opencl import get_context
    from .reproduce import bundled_scenes

    context = get_context(device)
    folder = scenes_dir or bundled_scenes()
    scenes = [load_scene(folder / f"{name}.json") for name in names]
    pipeline, accumulation = [], []
    steps = len(scenes) * (len(SETTINGS) + 1)
    step = 0
    for scene in scenes:
        for label, preset in SETTINGS:
            step += 1
            if progress is not None:
                progress(step, steps, f"{scene.name}: pipeline, {label} settings")
            pipeline.append(bench_pipeline(scene, label, preset, context, repeat))
        step += 1
        if progress is not None:
            progress(step, steps, f"{scene.name}: accumulation")
        accumulation.append(bench_accumulation(scene, context, repeat, numpy))
    device_name = f"{context.devices[0].name.strip()} ({context.devices[0].platform.name.strip()})"
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "bench.md", markdown(pipeline, accumulation, device_name,
                                            command).encode())
    write_atomic(out / "bench.json", (json.dumps(
        {"device": device_name, "pipeline": [dataclasses.asdict(r) for r in pipeline],
         "accumulation": [dataclasses.asdict(a) for a in accumulation]},
        indent=1) + "\n").encode())
    return pipeline, accumulation


__all__ = [
    "DEFAULT_SCENES",
    "AccumulationRow",
    "PipelineRow",
    "bench",
    "bench_accumulation",
    "bench_pipeline",
    "best_time",
    "loci_scene",
    "markdown",
]
