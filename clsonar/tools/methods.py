"""The mapping methods side by side (issue 15): every ``mapping.mode`` of the registry
(:data:`clsonar.mapping.METHODS`) on the same echoes of the thesis' shapes, the bundled
rooms and a few cases of the scene zoo, at noise σ 0, 0.6 and 1.2, with its run time and
its errors.

``clsonar bench --methods --out DIR`` (or ``python -m clsonar.tools.methods --out DIR``)
writes ``DIR/methods.json`` (one row per scene, noise σ and mode), ``DIR/methods.md`` and,
when matplotlib is installed, ``DIR/methods-pareto-KIND.png``. The front stages (sensors,
echoes, detection) run once per scene and σ and are shared by the modes
(:class:`StageCache`), so each mode's seconds are its map (``accumulation``) and its
post-processing. Errors: the pipeline's (``accuracy_m.rms`` of the profile,
``completeness.2cm``) and the literature's (Kurt, MSc, Bilkent 2005; Barshan, IJRR 26(8),
2007) on the map a mode hands over (its thin map and located vertices, :func:`map_cells`):
its mean absolute distance to the true surfaces (the map error, which also scores a map
too sparse for a profile) and its rates of correctly detected full and empty cells
(:func:`clsonar.metrics.cell_rates`). Per scene kind (the thesis'
shapes, the rooms, the zoo) each mode's means, the Pareto front of seconds against map
error (:func:`pareto_front`), and at the top of the page who wins where and by how much
(:func:`verdict`), computed from those means so that it stays true when regenerated.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import geometry, mapping, metrics
from ..errors import ClsonarError
from ..files import bundled_scenes, write_atomic
from ..mapping import METHODS
from ..outputs import metric, plots_available
from ..pipeline import RunResult, StageCache, run
from ..scene import MappingMode, MappingSettings, Scene, load_scene
from .defaults import METHODS_NOISE, METHODS_SCENES
from .markdown import NONE, cm, percent
from .progress import Progress, ProgressLine
from .tradeoff import pareto_front

#: The scenes compared by default: the thesis' shapes, the bundled rooms, a few zoo cases
#: (:data:`clsonar.tools.defaults.METHODS_SCENES`).
SCENES = METHODS_SCENES

#: Noise σ of the received signals (``signal.noise_std``).
NOISE = METHODS_NOISE

#: The scene kinds, in the order the page shows them.
KINDS = ("shapes", "rooms", "zoo")

#: The post-processing stages, whose seconds are a mode's besides its map's.
POST_STAGES = ("sight", "filter", "thinning", "profile")

#: A mode maps a scene kind when its maps mark at least this share of the true full
#: cells on average (:func:`clsonar.metrics.cell_rates`): the second Pareto front leaves
#: out the sparse maps, whose few cells score a small map error however little of the
#: surfaces they show.
COMPLETE = 0.5


def load_case(spec: str) -> tuple[Scene, str]:
    """The scene ``spec`` names and its kind (:data:`KINDS`): a bundled scene (``room``,
    ``plane-2m.json``; ``rooms`` when its name starts with ``room``, else ``shapes``) or
    ``zoo:SEED:KIND:INDEX``, case INDEX of KIND in the scene zoo of SEED
    (:func:`clsonar.tools.zoo.cases.draw`; ``zoo``). ValueError for a name that is
    neither."""
    if spec.startswith("zoo:"):
        from .zoo.cases import COUNTS, draw

        parts = spec.split(":")
        if (len(parts) != 4 or parts[2] not in COUNTS
                or not (parts[1].isdigit() and parts[3].isdigit())):
            raise ValueError(f"{spec!r}: a zoo case is zoo:SEED:KIND:INDEX, KIND one of "
                             f"{', '.join(COUNTS)}")
        return draw(int(parts[1]), parts[2], int(parts[3])).scene, "zoo"
    path = bundled_scenes() / (spec if spec.endswith(".json") else f"{spec}.json")
    if not path.is_file():
        raise ValueError(f"{spec!r}: no bundled scene of that name")
    return load_scene(path), "rooms" if path.stem.startswith("room") else "shapes"


def with_mode(scene: Scene, mode: str, noise: float) -> Scene:
    """``scene`` mapped by ``mode`` (one of :data:`~clsonar.mapping.METHODS`) with
    received signals of noise σ ``noise``."""
    if mode not in METHODS:
        raise ValueError(f"unknown mapping mode {mode!r} (choose from {', '.join(METHODS)})")
    return dataclasses.replace(
        scene, mapping=dataclasses.replace(scene.mapping, mode=cast(MappingMode, mode)),
        signal=dataclasses.replace(scene.signal, noise_std=noise))


def map_cells(result: RunResult) -> np.ndarray:
    """[ny, nx] bool: the cells of the map a mode hands over, its thin map and the cells
    of the vertices its profile located (a corner ``reflectors`` locates from a few
    elements is one point and no thin cell)."""
    cells = np.array(result.thin, dtype=bool)
    iy, ix = geometry.point_cells(result.scene.extent, result.scene.cell,
                                  result.profile.vertices)
    ok = (iy >= 0) & (iy < cells.shape[0]) & (ix >= 0) & (ix < cells.shape[1])
    cells[iy[ok], ix[ok]] = True
    return cells


def map_error(result: RunResult, cells: np.ndarray) -> float | None:
    """Mean absolute distance (m) of the map's ``cells`` (:func:`map_cells`) to the true
    surfaces (None for an empty map): the literature's map error (Barshan 2007)."""
    if not np.any(cells):
        return None
    iy, ix = np.nonzero(cells)
    centres = geometry.cell_centres(result.scene.extent, result.scene.cell, iy, ix)
    return float(np.mean(geometry.nearest_surface_point(result.geometry, centres)[0]))


@dataclass(frozen=True, eq=False)
class CellTruth:
    """The true map of a scene at its map's cells ([ny, nx] bool each): the insonified
    true surface's cells and all of the surface's (:func:`clsonar.metrics.surface_cells`),
    and the cells its echoes sounded (:func:`clsonar.mapping.sounded_cells`)."""

    full: np.ndarray
    surface: np.ndarray
    region: np.ndarray


def cell_truth(result: RunResult) -> CellTruth:
    """The :class:`CellTruth` of a run's scene, sensors and echo returns (the echoes
    :func:`clsonar.metrics.heard` reads: the same at every noise σ and mode)."""
    s, echoes = result.scene, result.echoes
    full, surface = metrics.surface_cells(s, result.geometry, result.sensors, echoes)
    keep = metrics.heard(s, echoes)
    heard = mapping.Loci(*(np.asarray(getattr(echoes, k))[keep]
                           for k in ("tx", "rx", "tof_s", "amplitude")))
    return CellTruth(full, surface, mapping.sounded_cells(s, result.sensors, heard))


def method_row(scene: Scene, kind: str, mode: str, noise: float,
               cache: StageCache | None = None, truth: CellTruth | None = None,
               device: str | None = None) -> tuple[dict[str, Any], CellTruth]:
    """One run of ``scene`` (of ``kind``) by ``mode`` at noise σ ``noise``: its seconds
    and errors, and the scene's :class:`CellTruth` (``truth`` when given)."""
    started = time.perf_counter()
    result = run(with_mode(scene, mode, noise), cache=cache, device=device)
    wall = time.perf_counter() - started
    truth = truth if truth is not None else cell_truth(result)
    marked = map_cells(result)
    full_rate, empty_rate = metrics.cell_rates(truth.full, truth.surface, truth.region, marked)
    return {
        "scene": scene.name, "kind": kind, "noise": noise, "mode": mode,
        "map_s": result.seconds.get("accumulation"),
        "post_s": sum(result.seconds.get(k, 0.0) for k in POST_STAGES),
        "run_s": wall,
        "accuracy_m": metric(result.metrics, "accuracy_m.rms"),
        "completeness_2cm": metric(result.metrics, "completeness.2cm"),
        "map_error_m": map_error(result, marked),
        "full_rate": full_rate, "empty_rate": empty_rate,
        "map_cells": int(np.count_nonzero(marked)),
        "detections": result.counts.get("detections"),
    }, truth


def check_modes(modes: Sequence[str]) -> None:
    """ValueError unless every one of ``modes`` is a mapping mode (:data:`METHODS`)."""
    unknown = [m for m in modes if m not in METHODS]
    if unknown or not modes:
        raise ValueError(f"unknown mapping mode {', '.join(unknown) or '(none)'} "
                         f"(choose from {', '.join(METHODS)})")


def compare_cases(cases: Sequence[tuple[Scene, str]], noises: Sequence[float] = NOISE,
                  modes: Sequence[str] = tuple(METHODS), device: str | None = None,
                  progress: Progress | None = None) -> list[dict[str, Any]]:
    """:func:`method_row` of every scene and its kind of ``cases`` (:func:`load_case`),
    noise σ and mode; ``progress(done, total, what)`` after each."""
    check_modes(modes)
    rows: list[dict[str, Any]] = []
    total = len(cases) * len(noises) * len(modes)
    for scene, kind in cases:
        truth = None
        for noise in noises:
            cache = StageCache()
            for mode in modes:
                row, truth = method_row(scene, kind, mode, noise, cache, truth, device)
                rows.append(row)
                if progress is not None:
                    progress(len(rows), total, progress_line(row))
    return rows


def compare(scenes: Sequence[str] = SCENES, noises: Sequence[float] = NOISE,
            modes: Sequence[str] = tuple(METHODS), device: str | None = None,
            progress: Progress | None = None) -> list[dict[str, Any]]:
    """:func:`compare_cases` of the scenes ``scenes`` names (:func:`load_case`; every one
    checked before any work)."""
    check_modes(modes)
    return compare_cases([load_case(spec) for spec in scenes], noises, modes, device,
                         progress)


@dataclass(frozen=True)
class ModeSummary:
    """One mode over the rows of one scene kind (:func:`mode_summary`)."""

    seconds: float  # mean of its map and post-processing seconds
    map_error_m: float  # mean map error over the rows with a map
    accuracy_m: float | None  # mean profile accuracy over the rows with a profile
    completeness: float  # mean share of the truth within 2 cm of the profile (none: 0)
    full_rate: float  # mean rate of correctly detected full cells
    empty_rate: float | None  # mean rate of correctly detected empty cells
    mapped: int  # rows with a map
    rows: int


def _mean(values: Sequence[float | None]) -> float | None:
    """The mean of the values that are not None (None if none is)."""
    given = [v for v in values if v is not None]
    return float(np.mean(given)) if given else None


def mode_summary(rows: list[dict[str, Any]], kind: str) -> dict[str, ModeSummary]:
    """Per mode, its means over the rows of scenes of ``kind``: seconds, completeness and
    the cell rates over all of them, the map error over those with a map, the accuracy
    over those with a profile. A mode with no map in any row is left out."""
    out = {}
    for mode in dict.fromkeys(str(r["mode"]) for r in rows):
        mine = [r for r in rows if r["mode"] == mode and r["kind"] == kind]
        error = _mean([r["map_error_m"] for r in mine])
        if error is None:
            continue
        out[mode] = ModeSummary(
            seconds=float(np.mean([(r["map_s"] or 0.0) + r["post_s"] for r in mine])),
            map_error_m=error, accuracy_m=_mean([r["accuracy_m"] for r in mine]),
            completeness=float(np.mean([r["completeness_2cm"] or 0.0 for r in mine])),
            full_rate=float(np.mean([r["full_rate"] or 0.0 for r in mine])),
            empty_rate=_mean([r["empty_rate"] for r in mine]),
            mapped=sum(r["map_error_m"] is not None for r in mine), rows=len(mine))
    return out


def fronts(summary: dict[str, ModeSummary]) -> tuple[list[str], list[str]]:
    """The modes on the Pareto front of seconds against map error, fastest first: of all
    modes, and of those that map the kind (full-cell rate ≥ :data:`COMPLETE`)."""
    def front(modes: list[str]) -> list[str]:
        at = pareto_front(np.array([summary[m].seconds for m in modes]),
                          np.array([summary[m].map_error_m for m in modes]))
        return [modes[i] for i in at]

    return front(list(summary)), front(complete_modes(summary))


def complete_modes(summary: dict[str, ModeSummary]) -> list[str]:
    """The modes that map the kind: full-cell rate ≥ :data:`COMPLETE`."""
    return [m for m in summary if summary[m].full_rate >= COMPLETE]


#: The names of the two fronts of :func:`fronts`.
FRONT_NAMES = ("front of all modes", f"front of the maps ≥ {percent(COMPLETE)} full")


def pareto_png(summary: dict[str, ModeSummary], kind: str) -> bytes:
    """The modes' mean seconds against mean map error (log–log), hollow where they mark
    less than :data:`COMPLETE` of the full cells, both Pareto fronts (:func:`fronts`)
    joined, their modes ringed."""
    from ..plots import figure, png_bytes

    fig = figure((6.5, 4.5), 120)
    ax = fig.add_subplot()
    for modes, style, label in zip(fronts(summary), ("--", "-"), FRONT_NAMES, strict=True):
        ax.plot([summary[m].seconds for m in modes],
                [100 * summary[m].map_error_m for m in modes], style,
                color="0.5", zorder=1, label=label, marker="o", markersize=10,
                markerfacecolor="none")
    placed: list[tuple[float, float]] = []
    for m, s in summary.items():
        x, y = max(s.seconds, 1e-6), max(100 * s.map_error_m, 1e-6)
        ax.scatter([x], [y], zorder=2, color="C0",
                   facecolors="C0" if s.full_rate >= COMPLETE else "none")
        # a label below those of the modes already drawn at about the same point
        near = sum(abs(np.log10(x / a)) < 0.15 and abs(np.log10(y / b)) < 0.1
                   for a, b in placed)
        placed.append((x, y))
        ax.annotate(m, (x, y), textcoords="offset points", xytext=(4, 3 - 9 * near),
                    fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("mean seconds (map + post-processing)")
    ax.set_ylabel("mean map error (cm)")
    ax.set_title(f"The mapping methods on the {kind}: time against error", fontsize=10)
    ax.legend(fontsize=8)
    return png_bytes(fig)


def _times(fast: float, slow: float) -> str:
    """How much quicker ``fast`` seconds is than ``slow``: ``"3.2×"``, or under 2× the
    time it saves (``"4 %"``)."""
    if fast <= 0:
        return "∞×"
    return f"{slow / fast:.1f}×" if slow >= 2 * fast else percent(1 - fast / slow)


def _beats(mode: str, s: ModeSummary, default: ModeSummary, same: bool) -> str:
    """How ``mode`` (``s``) dominates the default: seconds, map error and full cells;
    ``same``: it drew the default's map on every run."""
    speed = (f"{_times(s.seconds, default.seconds)} faster ({s.seconds:.2f} against "
             f"{default.seconds:.2f} s)" if s.seconds < default.seconds
             else f"as fast ({s.seconds:.2f} s)")
    if same:
        return (f"`{mode}` draws the same maps on every run (the same cells) and is {speed}: "
                "the default is off the front by its seconds alone")
    gap = 100 * (default.map_error_m - s.map_error_m)
    error = (f"{gap:.2f} cm lower map error ({cm(s.map_error_m)} against "
             f"{cm(default.map_error_m)} cm)" if round(gap, 2) > 0
             else f"as low a map error ({cm(s.map_error_m)} cm)")
    return (f"`{mode}` is {speed} with {error}, marking {percent(s.full_rate)} of the full "
            f"cells against {percent(default.full_rate)}")


def same_maps(rows: list[dict[str, Any]], kind: str, a: str) -> list[str]:
    """The modes whose maps are mode ``a``'s on every run of ``kind`` (the same number of
    cells, map error and full-cell rate, scene by scene and σ by σ)."""
    def maps(mode: str) -> list[tuple[Any, ...]]:
        return [(r["scene"], r["noise"], r["map_cells"], r["map_error_m"], r["full_rate"])
                for r in rows if r["kind"] == kind and r["mode"] == mode]

    mine = maps(a)
    return [m for m in dict.fromkeys(str(r["mode"]) for r in rows)
            if m != a and mine and maps(m) == mine]


def verdict(kind: str, summary: dict[str, ModeSummary],
            default: str = MappingSettings().mode, twins: Sequence[str] = ()) -> list[str]:
    """Who wins on ``kind``, and by how much, from its :func:`mode_summary`: the most
    accurate of the modes that map it (lowest mean map error, full-cell rate ≥
    :data:`COMPLETE`) and its margin over the next (and the lowest map error of any mode
    when a sparse one has it), the fastest mode against the default, and whether the
    default is on each Pareto front of :func:`fronts` — if not, each mode that dominates
    it and by how much (``twins``: the modes that drew the default's maps, :func:`same_maps`).
    Markdown, one paragraph."""
    if not summary:
        return [f"**{kind}**: no mode gave a map."]
    n = max(s.rows for s in summary.values())
    out = [f"**{kind}** ({n} run{'s' if n != 1 else ''} of each mode):"]
    ranked = sorted(complete_modes(summary),
                    key=lambda m: (summary[m].map_error_m, summary[m].seconds))
    if ranked:
        best = summary[ranked[0]]
        out.append(f"most accurate of the modes that mark ≥ {percent(COMPLETE)} of the full "
                   f"cells: `{ranked[0]}`, mean map error {cm(best.map_error_m)} cm "
                   f"({percent(best.full_rate)} of the full cells")
        if len(ranked) > 1:
            nxt = summary[ranked[1]]
            gap = 100 * (nxt.map_error_m - best.map_error_m)
            out[-1] += (f"), {gap:.2f} cm ({nxt.map_error_m / best.map_error_m:.1f}×) below "
                        f"the next, `{ranked[1]}` ({cm(nxt.map_error_m)} cm)."
                        if round(gap, 2) > 0 else
                        f"), tied with `{ranked[1]}` ({cm(nxt.map_error_m)} cm).")
        else:
            out[-1] += "), the only one."
    else:
        out.append(f"no mode marks {percent(COMPLETE)} of the full cells.")
    lowest = min(summary, key=lambda m: summary[m].map_error_m)
    if not ranked or lowest != ranked[0]:
        out.append(f"Lowest map error of any mode: `{lowest}` "
                   f"({cm(summary[lowest].map_error_m)} cm), marking "
                   f"{percent(summary[lowest].full_rate)} of the full cells.")
    fastest = min(summary, key=lambda m: summary[m].seconds)
    out.append(f"Fastest: `{fastest}` ({summary[fastest].seconds:.2f} s a run)"
               + (f", {_times(summary[fastest].seconds, summary[default].seconds)} faster "
                  f"than the default `{default}` ({summary[default].seconds:.2f} s)."
                  if default in summary and fastest != default else "."))
    if default not in summary:
        return [" ".join([*out, f"The default `{default}` gave no map."])]
    mine = summary[default]
    for name, front, among in zip(FRONT_NAMES, fronts(summary),
                                  (list(summary), complete_modes(summary)), strict=True):
        if default in front:
            out.append(f"The default `{default}` is on the {name}"
                       + "".join(f" (`{m}` draws the same maps on every run, "
                                 f"{summary[m].seconds - mine.seconds:.2f} s slower)"
                                 for m in twins if m in among and m not in front) + ".")
        elif default not in among:
            out.append(f"The default `{default}` is not on the {name}: it marks "
                       f"{percent(mine.full_rate)} of the full cells.")
        else:
            out.append(f"The default `{default}` is not on the {name}: "
                       + "; ".join(_beats(m, summary[m], mine, m in twins) for m in among
                                   if dominates(summary[m], mine)) + ".")
    return [" ".join(out)]


def dominates(a: ModeSummary, b: ModeSummary) -> bool:
    """Whether ``a`` is as fast and as accurate (map error) as ``b``, and better in one."""
    return (a.seconds <= b.seconds and a.map_error_m <= b.map_error_m
            and (a.seconds < b.seconds or a.map_error_m < b.map_error_m))


def _seconds(value: float | None) -> str:
    return NONE if value is None else f"{float(value):.2f}"


def _kinds(rows: list[dict[str, Any]]) -> list[str]:
    """The scene kinds of ``rows``, in the order of :data:`KINDS`."""
    return [k for k in KINDS if any(r["kind"] == k for r in rows)]


def _kind_section(rows: list[dict[str, Any]], kind: str, image: str | None) -> list[str]:
    """The summary table of ``kind``: each mode's means and whether it is on each front."""
    summary = mode_summary(rows, kind)
    on = fronts(summary)
    scenes = list(dict.fromkeys(str(r["scene"]) for r in rows if r["kind"] == kind))
    noises = ", ".join(dict.fromkeys(f"{r['noise']:g}" for r in rows if r["kind"] == kind))
    out = [f"### {kind}", "", f"{', '.join(scenes)}; σ {noises}.", "",
           "| mode | maps | s | map error (cm) | accuracy (cm) | ≤ 2 cm | full cells |"
           " empty cells | front | front, ≥ 50 % full |",
           "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | :---: | :---: |"]
    for m, s in summary.items():
        out.append(f"| `{m}` | {s.mapped}/{s.rows} | {s.seconds:.2f} | {cm(s.map_error_m)} | "
                   f"{cm(s.accuracy_m)} | {percent(s.completeness)} | "
                   f"{percent(s.full_rate)} | {percent(s.empty_rate, 2)} | "
                   + " | ".join("yes" if m in f else NONE for f in on) + " |")
    return out + [""] + ([f"![{kind}: time against error]({image})", ""] if image else [])


def _scene_table(rows: list[dict[str, Any]], name: str) -> list[str]:
    """The rows of scene ``name``, modes by noise σ."""
    out = [f"### {name}", "",
           "| σ | mode | map s | post s | accuracy (cm) | ≤ 2 cm | map error (cm) |"
           " full cells | empty cells | map cells |",
           "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in (r for r in rows if r["scene"] == name):
        out.append(
            f"| {r['noise']:g} | `{r['mode']}` | {_seconds(r['map_s'])} | "
            f"{_seconds(r['post_s'])} | {cm(r['accuracy_m'])} | "
            f"{percent(r['completeness_2cm'])} | {cm(r['map_error_m'])} | "
            f"{percent(r['full_rate'])} | {percent(r['empty_rate'], 2)} | {r['map_cells']} |")
    return [*out, ""]


def _cost(rows: list[dict[str, Any]]) -> str:
    """What the comparison cost: its runs' seconds in all, and the slowest mode's share."""
    total = sum(r["run_s"] for r in rows)
    by_mode = {m: sum(r["run_s"] for r in rows if r["mode"] == m)
               for m in dict.fromkeys(r["mode"] for r in rows)}
    slowest = max(by_mode, key=lambda m: by_mode[m])
    return (f"The {len(rows)} runs took {total / 60:.1f} minutes on the machine that wrote "
            f"this page, `{slowest}` {by_mode[slowest] / 60:.1f} of them "
            f"({percent(by_mode[slowest] / total)}).")


def markdown(rows: list[dict[str, Any]], command: str,
             images: dict[str, str] | None = None) -> str:
    """The comparison as markdown: who wins where (:func:`verdict`), one summary table per
    scene kind with its Pareto front (``images``: the kind's PNG's path), one table per
    scene, modes by noise σ."""
    default = MappingSettings().mode
    images = images or {}
    out = ["# The mapping methods side by side", "",
           "Every `mapping.mode` on the same detections of each scene (issue 15; docs/mapping.md",
           "describes each method). Regenerate with:", "", f"    {command}", "",
           _cost(rows), "",
           "## Who wins where", "",
           "Computed from the summary tables below (`clsonar.tools.methods.verdict`). The",
           "map error is the mean distance of the map's cells to the true surfaces, so a",
           "method that marks few cells can score a small one: the most accurate mode is",
           f"taken among those whose maps mark at least {percent(COMPLETE)} of the true full "
           "cells.", ""]
    for kind in _kinds(rows):
        out += [*verdict(kind, mode_summary(rows, kind), default,
                         same_maps(rows, kind, default)), ""]
    out += ["## Per scene kind", "",
            "Each mode's means over the kind's scenes and noise levels. A mode's map: the",
            "cells of its thin map and of the vertices its profile located. maps: the runs",
            "that gave a map of the runs; s: map and post-processing seconds; map error:",
            "mean absolute distance of the map's cells to the truth, over the runs with a",
            "map (Barshan 2007's mean absolute error); accuracy: RMS distance of the",
            "profile's points to the truth, over the runs with a profile; ≤ 2 cm: the share",
            "of the insonified truth with a profile point within 2 cm (none: 0); full",
            "cells: the share of the cells of the insonified true surface with a map cell",
            "within one cell (the rate of correctly detected full cells); empty cells:",
            "the share of the truly empty cells the echoes sounded (inside both beams and",
            "no farther than an echo, more than a cell from every surface) left unmarked (the",
            "rate of correctly detected empty cells; `clsonar.metrics.cell_rates`). front:",
            "on the Pareto front of seconds against map error of all modes, and of those",
            f"that mark at least {percent(COMPLETE)} of the full cells (hollow in the "
            f"figure: the others). The default is `{default}`. Timings from one run on the",
            "machine that wrote this page (PoCL on a shared CPU): compare them within a",
            "table.", ""]
    for kind in _kinds(rows):
        out += _kind_section(rows, kind, images.get(kind))
    out += ["## Per scene", ""]
    for name in dict.fromkeys(str(r["scene"]) for r in rows):
        out += _scene_table(rows, name)
    return "\n".join(out)


def write_report(rows: list[dict[str, Any]], out: Path, command: str,
                 table: Path | None = None) -> Path:
    """``out/methods.json``, the :func:`markdown` page (``table``, default
    ``out/methods.md``) and, with matplotlib, ``methods-pareto-KIND.png`` beside the page;
    returns the page's path."""
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "methods.json", (json.dumps(rows, indent=1) + "\n").encode())
    table = table or out / "methods.md"
    images = {}
    if plots_available():
        for kind in _kinds(rows):
            images[kind] = f"methods-pareto-{kind}.png"
            write_atomic(table.parent / images[kind], pareto_png(mode_summary(rows, kind), kind))
    write_atomic(table, (markdown(rows, command, images) + "\n").encode())
    return table


def options(scenes: str | None, noise: str | None, modes: str | None
            ) -> tuple[list[tuple[Scene, str]], tuple[float, ...], list[str]]:
    """The cases (:func:`load_case`), noise σ and modes of ``clsonar bench --methods``'s
    ``--scenes``, ``--noise`` and ``--modes`` (comma-separated; None: the defaults), every
    one checked before any work: :class:`~clsonar.errors.ClsonarError` naming the option."""
    try:
        noises = (tuple(float(x) for x in noise.split(",") if x.strip()) if noise
                  else METHODS_NOISE)
    except ValueError:
        raise ClsonarError(f"--noise: not a list of numbers: {noise!r}") from None
    if not noises or any(not 0.0 <= n < float("inf") for n in noises):
        raise ClsonarError(f"--noise: σ must be finite and >= 0, not {noise!r}")
    chosen = [m.strip() for m in modes.split(",") if m.strip()] if modes else list(METHODS)
    try:
        check_modes(chosen)
    except ValueError as e:
        raise ClsonarError(f"--modes: {e}") from None
    names = [n.strip() for n in scenes.split(",") if n.strip()] if scenes else METHODS_SCENES
    try:
        return [load_case(name) for name in names], noises, chosen
    except ValueError as e:
        raise ClsonarError(f"--scenes: {e}") from None


def bench_methods(args: argparse.Namespace, command: str) -> int:
    """``clsonar bench --methods``: :func:`compare_cases` of the command line's
    :func:`options` on its ``--device``, with a progress line, and :func:`write_report`
    into ``--out`` (``command``: the line that regenerates it)."""
    cases, noises, modes = options(args.scenes, args.noise, args.modes)
    line = ProgressLine()
    try:
        rows = compare_cases(cases, noises, modes, device=args.device, progress=line)
    finally:
        line.done()
    write_report(rows, Path(args.out), command)
    print(f"wrote {args.out}/methods.md, methods.json and the Pareto PNGs")
    return 0


def progress_line(row: dict[str, Any]) -> str:
    """One line of a row's progress: scene, σ, mode and seconds."""
    return f"{row['scene']} σ {row['noise']:g} {row['mode']}: {row['run_s']:.1f} s"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.methods",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", required=True, type=Path, help="folder for methods.json")
    parser.add_argument("--markdown", type=Path, help="the table's path (DIR/methods.md)")
    parser.add_argument("--scenes", default=",".join(SCENES),
                        help="bundled scene names and zoo:SEED:KIND:INDEX cases")
    parser.add_argument("--noise", default=",".join(f"{n:g}" for n in NOISE),
                        help="noise σ values")
    parser.add_argument("--modes", default=",".join(METHODS), help="mapping modes")
    args = parser.parse_args(argv)
    rows = compare(args.scenes.split(","), [float(n) for n in args.noise.split(",")],
                   args.modes.split(","),
                   progress=lambda i, n, what: print(f"[{i}/{n}] {what}", flush=True))
    write_report(rows, args.out, "python -m clsonar.tools.methods --out DIR --markdown "
                 "docs/methods.md", args.markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
