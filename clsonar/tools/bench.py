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

- **skipping**: the pipeline with every skip on and off (:mod:`clsonar.tools.tradeoff`), the
  speed-up and whether the output is identical.
- **run time against error**: the thesis' shapes under every knob of
  :data:`clsonar.tools.tradeoff.KNOBS`, the Pareto front and the settings that beat the
  thesis-faithful ones on both time and error on every shape (``tradeoff.png``).
- **scene zoo** (with ``zoo``, ``clsonar bench --zoo``; a few minutes): every case of
  :mod:`clsonar.tools.zoo` with the defaults, its summary per kind in ``bench.md`` and the
  whole table in ``zoo.md`` and ``zoo.json``.

Results go to ``bench.md``, ``bench.json`` and ``tradeoff.png``, written atomically.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ..errors import ClsonarError
from ..files import bundled_scenes, write_atomic
from ..outputs import metric, require_plots
from ..pipeline import STAGES
from ..scene import Scene, load_scene
from .defaults import BENCH_FLOORS, BENCH_REPEAT, BENCH_SCENES
from .floors import FloorRow, bench_floor
from .markdown import NONE, cm, percent
from .progress import Progress
from .throughput import ProcessRow, SweepRow, bench_process, bench_sweep, throughput_markdown
from .tradeoff import (
    SkipRow,
    TradeoffRow,
    beats_thesis,
    bench_skips,
    bench_tradeoff,
    fastest_run,
    tradeoff_png,
)
from .zoo.report import summary_markdown, zoo_report

DEFAULT_SCENES = BENCH_SCENES  # tools/defaults.py


def scene_names(scenes: str | None) -> tuple[str, ...]:
    """The bundled scenes ``--scenes`` names (default :data:`DEFAULT_SCENES`);
    :class:`~clsonar.errors.ClsonarError` for one that is not bundled."""
    names = tuple(n.strip() for n in scenes.split(",")) if scenes else DEFAULT_SCENES
    missing = [n for n in names if not (bundled_scenes() / f"{n}.json").is_file()]
    if missing:
        raise ClsonarError(f"--scenes: no bundled scene {', '.join(missing)}")
    return names


def floor_sizes(floors: str) -> tuple[float, ...]:
    """The floor sizes ``--floors`` gives, each 5 to 1000 m (else
    :class:`~clsonar.errors.ClsonarError`)."""
    try:
        sizes = tuple(float(x) for x in floors.split(",") if x.strip())
    except ValueError:
        raise ClsonarError(f"--floors: not a list of sizes in metres: {floors!r}") from None
    if any(not 5.0 <= f <= 1000.0 for f in sizes):
        raise ClsonarError(f"--floors: sizes must be 5 to 1000 m, not {floors!r}")
    return sizes

#: Settings compared in the pipeline table: the thesis' methods, and the scene's own (ours).
SETTINGS = (("thesis", "thesis"), ("best", None))

DEFAULT_REPEAT, DEFAULT_FLOORS = BENCH_REPEAT, BENCH_FLOORS

T = TypeVar("T")


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
    tiled_s: float = 0.0  # float32, tiled (the default)
    tiled_speedup: float | None = None  # against NumPy
    tiled_identical: bool = False  # tiled float32 map == dense float32 map, to the bit
    tiles_total: int = 0
    tiles_skipped: int = 0
    tiled_tests: int = 0  # pixel-locus tests the tiled kernel made


@dataclass(frozen=True)
class StageRow:
    """The echo and detection stages of one scene: OpenCL float32 against NumPy float64."""

    scene: str
    pairs: int
    echoes_numpy_s: float
    echoes_opencl_s: float
    echoes_speedup: float
    echoes_matched: float  # share of NumPy's echoes found by OpenCL (same pair, kind and
    # element, time of flight within 1 µs)
    unmatched_max_amplitude: float  # the strongest echo in one table only, share of A0
    detection_numpy_s: float
    detection_opencl_s: float
    detection_speedup: float
    detections_same: bool  # same detections, times of flight within 1 µs


def bench_stages(scene: Scene, context, repeat: int) -> StageRow:
    """Time the echoes (:func:`clsonar.echoes.compute_echoes` against
    :func:`~clsonar.echoes.reference_echoes`) and the detection (:func:`clsonar.signals.detect`
    against :func:`~clsonar.signals.detect_reference`, which synthesises every pair's
    received signal) of ``scene``."""
    from .. import signals
    from ..echoes import compute_echoes, reference_echoes
    from ..geometry import build_geometry
    from ..sensors import pairs, place_sensors

    sensors = place_sensors(scene, build_geometry(scene))
    compute_echoes(scene, sensors, context=context)
    cl_s, table = best_time(lambda: compute_echoes(scene, sensors, context=context), repeat)
    np_s, ref = best_time(lambda: reference_echoes(scene, sensors), 1)
    signals.detect(scene, sensors, table, context=context)
    det_s, found = best_time(lambda: signals.detect(scene, sensors, table, context=context),
                             repeat)
    det_np_s, found_ref = best_time(lambda: signals.detect_reference(scene, sensors, table), 1)

    def same(a, b, columns) -> bool:
        return (len(a) == len(b)
                and all(np.array_equal(getattr(a, c), getattr(b, c)) for c in columns)
                and bool(np.all(np.abs(a.tof_s - b.tof_s) <= 1e-6)))

    def keyed(t) -> dict:
        return {(int(a), int(b), int(k), int(e)): (tof, amp) for a, b, k, e, tof, amp in zip(
            t.tx, t.rx, t.kind, t.element, t.tof_s, t.amplitude, strict=True)}

    mine, theirs = keyed(table), keyed(ref)
    matched = [k for k, (tof, _) in theirs.items()
               if k in mine and abs(mine[k][0] - tof) <= 1e-6]
    lone = [v[1] for k, v in {**mine, **theirs}.items() if k not in matched]
    return StageRow(scene.name, len(pairs(sensors)), np_s, cl_s, np_s / cl_s,
                    len(matched) / max(len(theirs), 1),
                    max(lone, default=0.0) / scene.transducer.amplitude, det_np_s, det_s,
                    det_np_s / det_s, same(found, found_ref, ("tx", "rx")))


def stages_markdown(rows: list[StageRow]) -> list[str]:
    lines = ["", "## Echoes and detection: OpenCL against NumPy float64", "",
             "The echo engine (`kernels/echoes.cl` against `echoes.reference_echoes`) and the "
             "detection (`kernels/signals.cl`, with its skips, against "
             "`signals.detect_reference`, the plain program that synthesises and scans every "
             "pair's received signal). An echo in one table only is a knife edge: its reflection "
             "point lies exactly at a wall's end (in the rooms, where a ring pose faces a "
             "corner), and float32 and float64 round it to different sides; or a weak grazing "
             "return (docs/stability.md).", "",
             "| scene | pairs | echoes NumPy s | echoes OpenCL s | speed-up | echoes matched | "
             "strongest unmatched (A0) | detection NumPy s | detection OpenCL s | speed-up | "
             "same detections |", "| --- |" + " ---: |" * 10]
    for r in rows:
        lines.append(f"| {r.scene} | {r.pairs:,} | {r.echoes_numpy_s:.3f} | "
                     f"{r.echoes_opencl_s:.4f} | {r.echoes_speedup:.0f}× | "
                     f"{r.echoes_matched * 100:.2f} % | {r.unmatched_max_amplitude:.3f} | "
                     f"{r.detection_numpy_s:.2f} | "
                     f"{r.detection_opencl_s:.4f} | {r.detection_speedup:.0f}× | "
                     f"{_yes(r.detections_same)} |")
    return lines


def best_time(fn: Callable[[], T], repeat: int) -> tuple[float, T]:
    """The shortest of ``repeat`` wall-clock runs of ``fn`` and its last result."""
    best = float("inf")
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def bench_pipeline(scene: Scene, settings: str, preset: str | None, context,
                   repeat: int) -> PipelineRow:
    """Time the whole pipeline on ``scene`` (the run with the shortest total counts)."""
    fastest = fastest_run(scene, context, repeat, preset=preset)
    m = fastest.metrics
    return PipelineRow(scene.name, settings, dict(fastest.seconds),
                       float(sum(fastest.seconds.values())), metric(m, "rms_m"),
                       metric(m, "accuracy_m.rms"), metric(m, "completeness.2cm"))


def loci_scene(scene: Scene) -> Scene:
    """``scene`` with the thesis' accumulation: votes of weight 1 on every detection's
    locus, summed, both (T, R) and (R, T) drawn."""
    mapping = dataclasses.replace(scene.mapping, mode="loci", weight="unit", combine="sum",
                                  reciprocal="both")
    return dataclasses.replace(scene, mapping=mapping)


def bench_accumulation(scene: Scene, context, repeat: int,
                       numpy: bool = True) -> AccumulationRow:
    """Time the locus accumulation of ``scene``'s detections (module docstring)."""
    from .. import mapping, signals
    from ..echoes import compute_echoes
    from ..geometry import build_geometry
    from ..opencl import has_fp64
    from ..sensors import place_sensors

    scene = loci_scene(scene)
    sensors = place_sensors(scene, build_geometry(scene))
    echoes = compute_echoes(scene, sensors, context=context)
    loci = mapping.as_loci(signals.detect(scene, sensors, echoes, context=context))
    pixels = int(np.prod(scene.grid_shape))
    precisions = ("float32", "float64") if has_fp64(context) else ("float32",)
    maps, seconds = {}, {}
    for precision in precisions:  # dense: every pixel tests every locus
        def dense(p=precision):
            return mapping.accumulate(scene, sensors, loci, context=context, precision=p,
                                      tiles=False)
        dense()  # builds the kernel
        seconds[precision], maps[precision] = best_time(dense, repeat)

    def tiled():
        return mapping.accumulate_with_stats(scene, sensors, loci, context=context,
                                             precision="float32")
    tiled()
    tiled_s, (tiled_map, stats) = best_time(tiled, repeat)
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
        float(np.mean(maps["float32"] == reference)) if reference is not None else None,
        tiled_s, numpy_s / tiled_s if numpy_s else None,
        bool(np.array_equal(tiled_map, maps["float32"])), stats.tiles_total,
        stats.tiles_skipped, stats.pixel_locus_tests)


def _yes(flag: bool) -> str:
    return "yes" if flag else "NO"


def _ratio(value: float | None) -> str:
    return NONE if value is None else f"{value:.0f}×"


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
        lines.append(f"| {r.scene} | {r.settings} | {r.total_s:.2f} | "
                     + " | ".join(f"{r.seconds.get(s, 0.0):.2f}" for s in stages)
                     + f" | {cm(r.rms_m)} | {cm(r.accuracy_m)} | "
                     f"{percent(r.completeness_2cm)} |")
    lines += ["", "`thesis`: threshold detection, loci summed, eq. 2.5 thinning, polynomial "
              "fit. `best`: the scene's own settings (envelope detection, tangent points, "
              "Guo–Hall thinning, spline or walls fit).", "",
              "## Locus accumulation: OpenCL against NumPy float64", "",
              "Dense: every pixel tests every locus (kernel `loci_map`), tests/s = pixels × "
              "loci / seconds. Tiled (the default, kernel `loci_tiles`): each tile tests only "
              "the loci whose band can reach it, empty tiles are skipped; its map must equal "
              "the dense float32 map to the bit.", "",
              "| scene | pixels | loci | NumPy s | dense float32 s | dense float64 s | dense "
              "float32 tests/s | dense float32 speed-up | float64 speed-up | float64 map "
              "identical | float32 equal pixels | tiled float32 s | tiled speed-up | tiles "
              "skipped | tiled tests | tiled = dense |", "| --- |" + " ---: |" * 15]
    for a in accumulation:
        f64 = a.opencl_s.get("float64")
        lines.append(
            f"| {a.scene} | {a.pixels:,} | {a.loci} | "
            f"{NONE if a.numpy_s is None else f'{a.numpy_s:.2f}'} | "
            f"{a.opencl_s['float32']:.3f} | {NONE if f64 is None else f'{f64:.3f}'} | "
            f"{a.tests_per_s['float32']:.2e} | {_ratio(a.speedup.get('float32'))} | "
            f"{_ratio(a.speedup.get('float64'))} | "
            f"{NONE if a.float64_identical is None else _yes(a.float64_identical)}"
            f" | {NONE if a.float32_equal_share is None else f'{a.float32_equal_share:.6f}'} | "
            f"{a.tiled_s:.4f} | {_ratio(a.tiled_speedup)} | "
            f"{a.tiles_skipped:,} of {a.tiles_total:,} | {a.tiled_tests:.2e} | "
            f"{_yes(a.tiled_identical)} |")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class BenchReport:
    """Everything one ``clsonar bench`` measured (written to ``bench.md``/``bench.json``)."""

    device: str
    pipeline: list[PipelineRow]
    accumulation: list[AccumulationRow]
    stages: list[StageRow]
    skips: list[SkipRow]
    tradeoff: list[TradeoffRow]
    beats_thesis: list[str]
    floors: list[FloorRow]
    zoo: list[dict[str, Any]] = dataclasses.field(default_factory=list)
    sweep: list[SweepRow] = dataclasses.field(default_factory=list)  # of THROUGHPUT_SCENE
    process: list[ProcessRow] = dataclasses.field(default_factory=list)


#: The scene whose sweep throughput and process time are measured (when benchmarked).
THROUGHPUT_SCENE = "room"

#: The thesis' shapes (the trade-off table runs every knob on these).
THESIS_SCENES = ("plane-2m", "corner-4m", "edge-1m", "cylinder-2.1m", "sinusoid-1m")


def skips_markdown(rows: list[SkipRow]) -> list[str]:
    lines = ["", "## What skipping saves", "",
             "The whole pipeline with every skip on (pairs whose beams meet no surface, "
             "noise-free pairs without an echo, empty tiles of the accumulation, "
             "post-processing outside the voted cells' box) and with every skip off "
             "(`clsonar run --no-skip all`); the output must be identical.", "",
             "| scene | settings | skipping s | no skipping s | speed-up | identical output "
             "| pairs | skipped (no surface) | skipped (silent) | cells post-processed |",
             "| --- | --- |" + " ---: |" * 8]
    for r in rows:
        c = r.counts
        lines.append(
            f"| {r.scene} | {r.settings} | {r.skipping_s:.3f} | {r.no_skipping_s:.3f} | "
            f"{r.speedup:.1f}× | {_yes(r.identical)} | {c.get('pairs', 0):,} | "
            f"{c.get('pairs_skipped_empty', 0):,} | {c.get('pairs_skipped_silent', 0):,} | "
            f"{c.get('cells_post_processed', 0):,} of {c.get('map_cells', 0):,} |")
    return lines


def tradeoff_markdown(rows: list[TradeoffRow], winners: list[str]) -> list[str]:
    lines = ["", "## Run time against error: the knobs", "",
             "Each thesis scene under the thesis-faithful settings, ours, and ours with one "
             "knob turned; ★ marks the Pareto front (no other setting is both faster and more "
             "accurate). Plot: `tradeoff.png`.", "",
             "| scene | setting | total s | accuracy RMS (cm) | RMS eq. 2.6 (cm) | "
             "completeness ≤ 2 cm | Pareto |", "| --- | --- |" + " ---: |" * 4 + " :---: |"]
    for r in rows:
        lines.append(f"| {r.scene} | {r.setting} | {r.total_s:.3f} | {cm(r.accuracy_m)} | "
                     f"{cm(r.rms_m)} | {percent(r.completeness_2cm)} | "
                     f"{'★' if r.pareto else ''} |")
    lines += ["", "Faster and more accurate than the thesis-faithful settings on every thesis "
              "scene: " + (", ".join(f"**{w}**" for w in winners) if winners else "none") + "."]
    return lines


def floors_markdown(rows: list[FloorRow]) -> list[str]:
    lines = ["", "## Floors at scale", "",
             "Square rooms 5 m apart (walls 0.2 m thick, a 1.6 m cylinder in every fourth), "
             "each scanned by its own wall-following ring at 50 cm steps, mapped room by room "
             "(`clsonar.regions`) into a mosaic at 1 cm. Each floor runs in a fresh process; "
             "its rooms are mapped in `workers` processes side by side (`clsonar.rooms`; "
             "– : one loop), so the run's wall time is less than its stages' seconds, "
             "summed over the rooms. Peak memory is the whole process's high-water mark "
             "(interpreter and OpenCL runtime included) plus the largest worker's for each "
             "worker, the mosaic the floor's own maps.", "",
             "| floor | cells | rooms | transducers | pairs | wall s | workers | stages s | "
             + " | ".join(STAGES) + " | peak memory | mosaic | accuracy RMS (cm) | "
             "completeness ≤ 2 cm | vertices found |",
             "| --- |" + " ---: |" * (12 + len(STAGES))]
    for f in rows:
        peak = f.peak_rss_mb + f.workers * f.workers_peak_rss_mb
        lines.append(f"| {f.scene} | {f.cells:,} | {f.rooms} | {f.transducers:,} | "
                     f"{f.pairs:,} | {f.wall_s:.1f} | {f.workers or NONE} | {f.total_s:.1f} | "
                     + " | ".join(f"{f.seconds.get(s, 0.0):.1f}" for s in STAGES)
                     + f" | {peak:,.0f} MB | {f.mosaic_mb:,.0f} MB | "
                     f"{cm(f.accuracy_m)} | {percent(f.completeness_2cm, 1)} | "
                     f"{f.vertices_found or NONE} |")
    return lines


def zoo_markdown(rows: list[dict[str, Any]]) -> list[str]:
    return ["", "## Scene zoo", "",
            "Every case of the scene zoo (docs/zoo.md) run with the default settings: cases "
            "passing each of issue 14's thresholds, of the cases it applies to. Every case: "
            "`zoo.md` beside this file.", "", *summary_markdown(rows)]


def _stepper(progress: Progress | None, steps: int) -> Callable[[str], None]:
    """A callback that reports the next of ``steps`` steps, named, to ``progress``."""
    step = 0

    def tell(what: str) -> None:
        nonlocal step
        step += 1
        if progress is not None:
            progress(step, steps, what)
    return tell


def bench_scene(scene: Scene, context, repeat: int, numpy: bool, tell: Callable[[str], None]
                ) -> tuple[list[PipelineRow], list[SkipRow], AccumulationRow, StageRow | None]:
    """Every per-scene measurement of ``scene``: the pipeline and skipping under each of
    :data:`SETTINGS`, the accumulation, and (with ``numpy``) the echo and detection stages."""
    pipeline, skips = [], []
    for label, preset in SETTINGS:
        tell(f"{scene.name}: pipeline, {label} settings")
        pipeline.append(bench_pipeline(scene, label, preset, context, repeat))
        tell(f"{scene.name}: skipping on and off, {label} settings")
        skips.append(bench_skips(scene, label, preset, context, repeat))
    tell(f"{scene.name}: accumulation")
    accumulation = bench_accumulation(scene, context, repeat, numpy)
    stages = None
    if numpy:
        tell(f"{scene.name}: echoes and detection against NumPy")
        stages = bench_stages(scene, context, repeat)
    return pipeline, skips, accumulation, stages


def report_markdown(report: BenchReport, command: str) -> str:
    """``bench.md``: every table of ``report`` that has rows."""
    text = markdown(report.pipeline, report.accumulation, report.device, command)
    return text + "\n".join(
        (stages_markdown(report.stages) if report.stages else [])
        + skips_markdown(report.skips)
        + (tradeoff_markdown(report.tradeoff, report.beats_thesis) if report.tradeoff else [])
        + (throughput_markdown(THROUGHPUT_SCENE, report.sweep, report.process)
           if report.sweep else [])
        + (floors_markdown(report.floors) if report.floors else [])
        + (zoo_markdown(report.zoo) if report.zoo else [])) + "\n"


def bench(out: Path, scenes_dir: Path | None = None, names: tuple[str, ...] = DEFAULT_SCENES,
          *, repeat: int = DEFAULT_REPEAT, numpy: bool = True, device: str | None = None,
          progress: Progress | None = None, command: str = "clsonar bench --out docs/bench",
          floors: tuple[float, ...] = DEFAULT_FLOORS, zoo: bool = False) -> BenchReport:
    """Benchmark the ``names`` scenes of ``scenes_dir`` (default: the bundled ones) and write
    ``bench.md``, ``bench.json`` and ``tradeoff.png`` into ``out``: the pipeline under both
    settings, the accumulation against NumPy, skipping on against off, and (for the thesis'
    shapes among ``names``) the knobs' run time against error, and the ``floors`` (sizes in
    metres, :mod:`clsonar.tools.floors`) mapped room by room; with ``zoo``, the scene zoo
    (``zoo.md``, ``zoo.json``)."""
    from ..files import bundled_scenes
    from ..opencl import device_name, get_context

    folder = scenes_dir or bundled_scenes()
    scenes = [load_scene(folder / f"{name}.json") for name in names]
    shapes = [s for s in scenes if s.name in THESIS_SCENES]
    if shapes:
        require_plots("clsonar bench (tradeoff.png)")
    context = get_context(device)
    ends = THROUGHPUT_SCENE in names
    tell = _stepper(progress, len(scenes) * (2 * len(SETTINGS) + 1 + numpy) + len(shapes)
                    + len(floors) + zoo + 2 * ends)
    pipeline, skips, accumulation, stage_rows = [], [], [], []
    for scene in scenes:
        rows, skipped, accumulated, stages = bench_scene(scene, context, repeat, numpy, tell)
        pipeline += rows
        skips += skipped
        accumulation.append(accumulated)
        stage_rows += [] if stages is None else [stages]
    trade = []
    for scene in shapes:
        tell(f"{scene.name}: run time against error")
        trade += bench_tradeoff(scene, context, repeat)
    sweep, process = [], []
    if ends:
        tell(f"{THROUGHPUT_SCENE}: a sweep over seeds and noise")
        sweep = bench_sweep(scenes[names.index(THROUGHPUT_SCENE)], context)
        tell(f"{THROUGHPUT_SCENE}: clsonar run as a process")
        process = bench_process(folder / f"{THROUGHPUT_SCENE}.json", repeat, device)
    floor_rows = []
    for size in floors:
        tell(f"floor {size:g} m × {size:g} m (a separate process)")
        floor_rows.append(bench_floor(size, device))
    zoo_rows = []
    if zoo:
        tell("scene zoo")
        zoo_rows = zoo_report(out, context=context, command=command)
    report = BenchReport(device_name(context), pipeline,
                         accumulation, stage_rows, skips, trade, beats_thesis(trade),
                         floor_rows, zoo_rows, sweep, process)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "bench.md", report_markdown(report, command).encode())
    if trade:
        write_atomic(out / "tradeoff.png", tradeoff_png(trade))
    write_atomic(out / "bench.json", (json.dumps(dataclasses.asdict(report), indent=1)
                                      + "\n").encode())
    return report


__all__ = [
    "DEFAULT_FLOORS",
    "DEFAULT_REPEAT",
    "DEFAULT_SCENES",
    "THESIS_SCENES",
    "AccumulationRow",
    "BenchReport",
    "PipelineRow",
    "StageRow",
    "bench",
    "bench_accumulation",
    "bench_pipeline",
    "bench_scene",
    "bench_stages",
    "best_time",
    "loci_scene",
    "markdown",
    "report_markdown",
]
