"""``clsonar reproduce``: the thesis' experiments of chapter 3, rerun and compared.

Each experiment is a bundled scene (``scenes/``) moved to a distance: the placement line of a
``random-lines`` scene is shifted towards or away from the surface, so "plane at 4 m" is
``plane-2m.json`` with its arrays 2 m farther back. Every experiment runs with five seeds
(placement and noise seeds 0..4 added to the scene's) under the thesis-faithful settings
(preset ``thesis``) and ours (preset ``best``). The curves are those of the thesis' figures:

- Fig 3.5: plane, RMS (eq. 2.6) against the distance 2–8 m, no noise;
- Fig 3.6: plane at 5 m, RMS against the noise σ;
- Fig 3.19: sinusoid, RMS against the distance 1–7 m, no noise;
- Fig 3.20: sinusoid at 5 m, RMS against the noise σ.

The closed rooms of §3.6 (Figs 3.21–3.26: per-wall arrays, the wall-following ring at steps
of 50, 70 and 75 cm, the room with a 2 m cylinder; :data:`ROOMS`) run once each — they are
noise-free and their placement has no randomness — with the thesis' observation beside our
accuracy, completeness, corners and edges found, and cylinder coverage, and one profile
PNG each.

The report is a markdown table with the thesis' numbers beside ours, a JSON file of every
run, and one PNG per figure.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..files import bundled_scenes, write_atomic
from ..outputs import metric, require_plots
from ..pipeline import PRESETS
from ..scene import Scene, load_scene
from .defaults import REPRODUCE_SEEDS
from .markdown import NONE, cm, percent
from .progress import Progress
from .sweep import Run, RunTable, make_run, run_dask, run_local
from .variants import at_distance

#: The thesis' RMS errors in cm (chapter 3: Figs 3.2–3.4 and 3.16–3.18).
THESIS_RMS_CM = {("plane", 2.0): 0.72, ("plane", 4.0): 3.14, ("plane", 8.0): 6.69,
                 ("sinusoid", 1.0): 13.72, ("sinusoid", 4.0): 16.54, ("sinusoid", 6.0): 22.80}

#: The table's experiments: (family, bundled scene, the scene's distance, distances to run).
TABLE = (
    ("plane", "plane-2m", 2.0, (2.0, 4.0, 8.0)),
    ("corner", "corner-4m", 4.0, (4.0, 7.0, 9.0)),
    ("edge", "edge-1m", 1.0, (1.0, 3.0, 5.0)),
    ("cylinder", "cylinder-2.1m", 2.1, (2.1, 3.0, 4.0)),
    ("sinusoid", "sinusoid-1m", 1.0, (1.0, 4.0, 6.0)),
)

#: The figures' curves: (figure, family, scene, its distance, what varies, values).
CURVES = (
    ("3.5", "plane", "plane-2m", 2.0, "distance_m", (2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0)),
    ("3.6", "plane", "plane-2m", 2.0, "noise_std", (0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2)),
    ("3.19", "sinusoid", "sinusoid-1m", 1.0, "distance_m", (1.0, 2.0, 3.0, 4.0, 5.0, 6.0,
                                                             7.0)),
    ("3.20", "sinusoid", "sinusoid-1m", 1.0, "noise_std", (0.0, 0.2, 0.4, 0.6, 0.8, 1.0,
                                                            1.2)),
)

#: The closed rooms of §3.6: (figure, bundled scene, what the thesis observed).
ROOMS = (
    ("3.21", "room-per-wall", "per-wall arrays of 10: \"some gaps occur in the constructed "
                              "map\""),
    ("3.22", "room-per-wall-steps", "LoS distance changed from wall to wall: \"better "
                                    "estimated map but it is not very good at the vertex of "
                                    "the edges and corners\""),
    ("3.23", "room", "ring, step 50 cm: \"all of the simulated surfaces are accurately "
                     "estimated\"; 50 cm \"is sufficient to estimate any type of surface "
                     "profile\""),
    ("3.24", "room-step70", "step 70 cm: \"one of the edges (left-bottom) cannot be estimated "
                            "accurately\""),
    ("3.25", "room-step75", "step 75 cm: \"again, vertex estimation problem occurs\""),
    ("3.26", "room-cylinder", "2 m cylinder at the centre: walls, edges and corners \"easily "
                              "extracted\"; \"some of the boundaries of the cylinder can be "
                              "extracted\""),
    ("–", "room-l", "(ours) L-shaped room, one convex edge"),
    ("–", "room-obstacles", "(ours) a cylinder and a box inside a rectangular room"),
)

#: Distance of the noise curves (thesis: 5 m for both).
NOISE_DISTANCE_M = 5.0

DEFAULT_SEEDS = REPRODUCE_SEEDS  # tools/defaults.py


@dataclass(frozen=True)
class Trial:
    """One run of the pipeline and what came out of it."""

    family: str
    distance_m: float
    noise_std: float
    preset: str
    seed: int
    rms_m: float | None
    accuracy_m: float | None
    completeness_2cm: float | None
    seconds: float


#: The metrics each trial keeps (:func:`clsonar.tools.sweep.metric_value` names).
METRICS = ("rms_m", "accuracy_m.rms", "completeness.2cm")


def trial_of(row: dict) -> Trial:
    """The :class:`Trial` of one row of the sweep table (:mod:`clsonar.tools.sweep`)."""
    return Trial(row["family"], row["distance_m"], row["noise_std"], row["preset"],
                 row["seed"], row["rms_m"], row["accuracy_m.rms"], row["completeness.2cm"],
                 row["seconds.total"])


@dataclass(frozen=True)
class RoomTrial:
    """One closed-room run (thesis §3.6) and what came out of it."""

    figure: str
    scene: str
    poses: int
    accuracy_m: float | None
    completeness_2cm: float | None
    vertices_found: str | None
    vertex_error_max_m: float | None
    cylinder_coverage_2cm: list[float]
    seconds: float


def run_room(scene: Scene, figure: str, context) -> tuple[RoomTrial, bytes]:
    """Run a closed room and draw its profile."""
    from ..outputs import profile_png
    from ..pipeline import run

    result = run(scene, context=context)
    m = result.metrics
    trial = RoomTrial(figure, scene.name, len(result.sensors.poses),
                      metric(m, "accuracy_m.rms"), metric(m, "completeness.2cm"),
                      metric(m, "vertices_found"), metric(m, "vertex_error_max_m"),
                      [c["coverage_2cm"] for c in metric(m, "cylinders") or []],
                      float(sum(result.seconds.values())))
    return trial, profile_png(result)


def rooms_markdown(trials: list[RoomTrial]) -> str:
    """The closed rooms' table: the thesis' observation beside our numbers."""
    notes = {name: note for _, name, note in ROOMS}
    lines = ["## Closed rooms (thesis §3.6, Figs 3.21–3.26)", "",
             "| fig | scene | poses / arrays | accuracy RMS (cm) | completeness ≤ 2 cm | "
             "corners and edges within 3 cm | worst vertex (cm) | cylinder perimeter "
             "≤ 2 cm | seconds | the thesis observed |",
             "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for t in trials:
        cyl = ", ".join(percent(c) for c in t.cylinder_coverage_2cm) or NONE
        lines.append(f"| {t.figure} | {t.scene} | {t.poses} | {cm(t.accuracy_m)} | "
                     f"{percent(t.completeness_2cm, 1)} | {t.vertices_found or NONE} | "
                     f"{cm(t.vertex_error_max_m)} | {cyl} | {t.seconds:.1f} | "
                     f"{notes[t.scene]} |")
    lines += ["", "Noise-free, thesis' world (uniform directivity, no curvature gain), mapping "
              "`tangents` with line of sight, profile `walls`, bounded by the map (a circle "
              "is not drawn where the map has nothing within 3 cells of it). The thesis took "
              "about 2 minutes per room. Pictures: `room_<scene>.png`.", ""]
    lines += [f"![{t.scene}](room_{t.scene}.png)" for t in trials]
    return "\n".join(lines)


def plan(scenes_dir: Path, seeds: int) -> list[Run]:
    """Every (family, distance, noise, preset, seed) of the table and the curves, once, as
    the runs of a sweep (:mod:`clsonar.tools.sweep`) with those as its parameters."""
    jobs: dict[tuple, Run] = {}
    bases = {name: load_scene(scenes_dir / f"{name}.json")
             for name in {t[1] for t in TABLE} | {c[2] for c in CURVES}}

    def add(family: str, base: str, d0: float, distance: float, noise: float) -> None:
        moved = at_distance(bases[base], d0, distance)
        moved = dataclasses.replace(moved, signal=dataclasses.replace(moved.signal,
                                                                      noise_std=noise))
        for preset in PRESETS:
            params = {"family": family, "distance_m": distance, "noise_std": noise,
                      "preset": preset}
            for k in range(seeds):
                key = (family, distance, noise, preset, k)
                if key not in jobs:
                    jobs[key] = make_run(len(jobs), base, moved, params, k, preset)

    for family, base, d0, distances in TABLE:
        for d in distances:
            add(family, base, d0, d, 0.0)
    for _, family, base, d0, varies, values in CURVES:
        for v in values:
            add(family, base, d0, *curve_setting(varies, v))
    return list(jobs.values())


def curve_setting(varies: str, value: float) -> tuple[float, float]:
    """``(distance_m, noise_std)`` of a curve's point: ``value`` is the distance (no noise)
    or the noise σ (at :data:`NOISE_DISTANCE_M`)."""
    return (value, 0.0) if varies == "distance_m" else (NOISE_DISTANCE_M, value)


def _mean(values: Iterable[float | None]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.mean(v)) if v else None


def _select(trials: list[Trial], **where: object) -> list[Trial]:
    return [t for t in trials if all(getattr(t, k) == v for k, v in where.items())]


def _on_curve(trials: list[Trial], family: str, varies: str, value: float,
              preset: str) -> list[Trial]:
    """The trials of one point of a curve (:func:`curve_setting`) under ``preset``."""
    distance, noise = curve_setting(varies, value)
    return _select(trials, family=family, distance_m=distance, noise_std=noise, preset=preset)


def table_markdown(trials: list[Trial], seeds: int) -> str:
    """The comparison table: thesis RMS beside ours, mean over seeds, per experiment."""
    lines = [
        "| experiment | thesis RMS (cm) | thesis-faithful RMS (cm) | best RMS (cm) | "
        "thesis-faithful accuracy RMS (cm) | best accuracy RMS (cm) | "
        "best completeness ≤ 2 cm | best seconds |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for family, _, _, distances in TABLE:
        for d in distances:
            faithful = _select(trials, family=family, distance_m=d, noise_std=0.0,
                               preset="thesis")
            best = _select(trials, family=family, distance_m=d, noise_std=0.0, preset="best")
            thesis = THESIS_RMS_CM.get((family, d))
            lines.append(
                f"| {family} {d:g} m | {NONE if thesis is None else f'{thesis:.2f}'} | "
                f"{cm(_mean(t.rms_m for t in faithful))} | {cm(_mean(t.rms_m for t in best))}"
                f" | {cm(_mean(t.accuracy_m for t in faithful))}"
                f" | {cm(_mean(t.accuracy_m for t in best))} | "
                f"{percent(_mean(t.completeness_2cm for t in best))} | "
                f"{_mean(t.seconds for t in best) or 0:.2f} |")
    lines.append("")
    lines.append(f"Means over {seeds} seeds, noise-free. RMS is thesis eq. 2.6 along the wall "
                 "(plane and sinusoid only); accuracy is the RMS distance from the estimated "
                 "points to the true surface, for every scene (mean over the seeds that gave "
                 "a profile; – where none did). The thesis' single polynomial (thesis-faithful) "
                 "is only meant for one wall: across a corner or an edge its accuracy is "
                 "poor, and the thesis gives no number there either. Every profile keeps "
                 "only what the map supports (docs/scene-format.md, `post`): the polynomial "
                 "within its data's span, no point beyond 3 cells of the occupied map but "
                 "to bridge a gap between supported stretches. At the edge's 5 m the "
                 "array sees neither wall specularly (no completeness to measure); its "
                 "diffracted echoes (≈0.02 units for a 5-unit pulse) are above an open "
                 "scene's envelope floor of 0.01 units, so the edge is located as a point; "
                 "the thesis found one wall there.")
    return "\n".join(lines)


def curve_png(figure: str, family: str, varies: str, values: tuple[float, ...],
              trials: list[Trial]) -> bytes:
    """One of the thesis' RMS curves, thesis-faithful and best, mean ± spread over seeds."""
    from ..plots import figure as new_figure
    from ..plots import png_bytes
    from .sweepplot import draw_spread

    fig = new_figure((6, 4), 120)
    ax = fig.add_subplot()
    for preset, style in zip(PRESETS, ("o-", "s-"), strict=True):
        samples = [[t.rms_m * 100 for t in _on_curve(trials, family, varies, v, preset)
                    if t.rms_m is not None] for v in values]
        draw_spread(ax, values, samples, style, f"clsonar, {preset} settings")
    marks = [(d, v) for (f, d), v in THESIS_RMS_CM.items() if f == family]
    if varies == "distance_m" and marks:
        ax.plot(*zip(*marks, strict=True), "k*", markersize=10, label="thesis")
    ax.set_xlabel("distance to the surface (m)" if varies == "distance_m"
                  else "noise standard deviation (units)")
    ax.set_ylabel("RMS error, eq. 2.6 (cm)")
    ax.set_title(f"Thesis Fig {figure}: {family}"
                 + (f" at {NOISE_DISTANCE_M:g} m" if varies == "noise_std" else ", no noise"))
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return png_bytes(fig)


def curves_markdown(trials: list[Trial]) -> str:
    """The figures' curves as tables (mean RMS in cm over seeds)."""
    out = []
    for figure, family, _, _, varies, values in CURVES:
        label = "distance (m)" if varies == "distance_m" else "noise σ"
        out += [f"### Fig {figure}: {family}, RMS (cm) against {label}", "",
                f"| {label} | " + " | ".join(f"{v:g}" for v in values) + " |",
                "| --- |" + " ---: |" * len(values)]
        for preset in PRESETS:
            row = [cm(_mean(t.rms_m for t in _on_curve(trials, family, varies, v, preset)))
                   for v in values]
            label_preset = "thesis-faithful" if preset == "thesis" else preset
            out.append(f"| {label_preset} | " + " | ".join(row) + " |")
        out += ["", f"![Fig {figure}](fig{figure.replace('.', '_')}.png)", ""]
    return "\n".join(out)


def run_trials(jobs: list[Run], out: Path, context, *, device: str | None = None,
               progress: Progress | None = None, client=None) -> list[Trial]:
    """Run the table's and the curves' trials as a sweep whose table is ``out/runs.jsonl``
    (locally on ``context``, or on the Dask cluster of ``client``); returns them in plan
    order."""
    table = RunTable(out)
    table.repair()

    def tell(i: int, n: int, run: Run) -> None:
        if progress is not None:
            progress(i, n, f"{run.scene.name} σ={run.scene.signal.noise_std:g} {run.preset}")

    if client is None:
        run_local(jobs, table, METRICS, context=context, progress=tell)
    else:
        run_dask(jobs, table, METRICS, client, device=device, progress=tell)
    done = table.rows()
    return [trial_of(done[job.run_id]) for job in jobs]


def run_rooms(scenes_dir: Path, context, progress: Progress | None = None
              ) -> tuple[list[RoomTrial], dict[str, bytes]]:
    """Run every closed room of :data:`ROOMS`; returns the trials and their profile PNGs
    by file name."""
    rooms, pictures = [], {}
    for i, (figure, name, _) in enumerate(ROOMS):
        if progress is not None:
            progress(i + 1, len(ROOMS), f"{name} (closed room)")
        trial, png = run_room(load_scene(scenes_dir / f"{name}.json"), figure, context)
        rooms.append(trial)
        pictures[f"room_{name}.png"] = png
    return rooms, pictures


def report_markdown(trials: list[Trial], rooms: list[RoomTrial], seeds: int,
                    device: str) -> str:
    """``reproduce.md``: the table, the curves and the closed rooms."""
    return "\n".join([
        "# The thesis' experiments, reproduced",
        "",
        f"Regenerate with `clsonar reproduce --out docs/reproduce --seeds {seeds}` "
        f"(device: {device}).",
        "",
        table_markdown(trials, seeds),
        "",
        curves_markdown(trials),
        "",
        rooms_markdown(rooms),
    ]) + "\n"


def reproduce(out: Path, scenes_dir: Path | None = None, *, seeds: int = DEFAULT_SEEDS,
              device: str | None = None, progress: Progress | None = None,
              client=None) -> list[Trial]:
    """Run every experiment and write ``reproduce.md``, ``reproduce.json`` and the figures'
    PNGs into ``out``; returns the trials.

    The trials run as a sweep (:mod:`clsonar.tools.sweep`) whose table is ``out/runs.jsonl``: an
    interrupted reproduce, run again, redoes only the trials it had not finished (the table
    is removed once everything is written). With a
    ``dask.distributed.Client`` they run on its cluster.
    """
    from ..opencl import get_context

    require_plots("clsonar reproduce (its figures)")
    context = get_context(device)
    folder = scenes_dir or bundled_scenes()
    out.mkdir(parents=True, exist_ok=True)
    trials = run_trials(plan(folder, seeds), out, context, device=device, progress=progress,
                        client=client)
    rooms, pictures = run_rooms(folder, context, progress)
    text = report_markdown(trials, rooms, seeds, context.devices[0].name.strip())
    write_atomic(out / "reproduce.md", text.encode())
    write_atomic(out / "reproduce.json", (json.dumps(
        [dataclasses.asdict(t) for t in trials + rooms], indent=1) + "\n").encode())
    for name, png in pictures.items():
        write_atomic(out / name, png)
    for figure, family, _, _, varies, values in CURVES:
        name = f"fig{figure.replace('.', '_')}.png"
        write_atomic(out / name, curve_png(figure, family, varies, values, trials))
    RunTable(out).path.unlink()  # it only serves to resume an interrupted reproduce
    return trials
