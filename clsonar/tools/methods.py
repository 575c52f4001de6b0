"""The mapping methods side by side (issue 15): every ``mapping.mode`` of the registry
(:data:`clsonar.mapping.METHODS`) on the same echoes of a few bundled scenes, at a few noise
levels, with its run time and its error.

``python -m clsonar.tools.methods --out DIR`` writes ``DIR/methods.json`` (one row per
scene, noise σ and mode) and ``DIR/methods.md`` (one table per scene; ``--markdown PATH``
writes it there instead, e.g. docs/methods.md). The front stages (sensors, echoes,
detection) run once per scene and σ and are shared by the modes (:class:`StageCache`), so
each mode's seconds are its map (``accumulation``) and its post-processing. Errors: the
pipeline's (``accuracy_m.rms`` of the profile, ``completeness.2cm``), and the mean
absolute distance of the thin map's cells to the true surfaces — the map error of the
literature's comparisons (Barshan 2007), which also scores a map too sparse for a profile.
Per scene kind (the thesis' shapes, the rooms) the modes' mean seconds against their mean
map error, and the Pareto front of the two (:func:`pareto_front`), drawn as
``methods-pareto-KIND.png`` beside the table when matplotlib is installed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np

from .. import geometry
from ..files import bundled_scenes, write_atomic
from ..mapping import METHODS
from ..outputs import metric, plots_available
from ..pipeline import RunResult, StageCache, run
from ..scene import MappingMode, MappingSettings, Scene, load_scene
from .markdown import NONE, cm, percent

#: The scenes compared (bundled): a wall, a corner, a cylinder, a room.
SCENES = ("plane-2m.json", "corner-4m.json", "cylinder-2.1m.json", "room.json")

#: Noise σ of the received signals (``signal.noise_std``).
NOISE = (0.0, 0.6)

#: The post-processing stages, whose seconds are a mode's besides its map's.
POST_STAGES = ("sight", "filter", "thinning", "profile")


def with_mode(scene: Scene, mode: str, noise: float) -> Scene:
    """``scene`` mapped by ``mode`` (one of :data:`~clsonar.mapping.METHODS`) with
    received signals of noise σ ``noise``."""
    if mode not in METHODS:
        raise ValueError(f"unknown mapping mode {mode!r} (choose from {', '.join(METHODS)})")
    return dataclasses.replace(
        scene, mapping=dataclasses.replace(scene.mapping, mode=cast(MappingMode, mode)),
        signal=dataclasses.replace(scene.signal, noise_std=noise))


def map_error(result: RunResult) -> float | None:
    """Mean absolute distance (m) of the thin map's cells to the true surfaces (None for
    an empty map)."""
    if result.thin is None or not np.any(result.thin):
        return None
    iy, ix = np.nonzero(result.thin)
    cells = geometry.cell_centres(result.scene.extent, result.scene.cell, iy, ix)
    return float(np.mean(geometry.nearest_surface_point(result.geometry, cells)[0]))


def method_row(scene: Scene, mode: str, noise: float, cache: StageCache | None = None
               ) -> dict[str, Any]:
    """One run of ``scene`` by ``mode`` at noise σ ``noise``: its seconds and errors."""
    started = time.perf_counter()
    result = run(with_mode(scene, mode, noise), cache=cache)
    wall = time.perf_counter() - started
    return {
        "scene": scene.name, "noise": noise, "mode": mode,
        "map_s": result.seconds.get("accumulation"),
        "post_s": sum(result.seconds.get(k, 0.0) for k in POST_STAGES),
        "run_s": wall,
        "accuracy_m": metric(result.metrics, "accuracy_m.rms"),
        "completeness_2cm": metric(result.metrics, "completeness.2cm"),
        "map_error_m": map_error(result),
        "thin_cells": int(np.count_nonzero(result.thin)) if result.thin is not None else 0,
        "detections": result.counts.get("detections"),
    }


def compare(scenes: Sequence[str] = SCENES, noises: Sequence[float] = NOISE,
            modes: Sequence[str] = tuple(METHODS), progress=None) -> list[dict[str, Any]]:
    """:func:`method_row` of every bundled scene of ``scenes``, noise σ and mode."""
    rows = []
    for name in scenes:
        scene = load_scene(bundled_scenes() / name)
        for noise in noises:
            cache = StageCache()
            for mode in modes:
                rows.append(method_row(scene, mode, noise, cache))
                if progress is not None:
                    progress(rows[-1])
    return rows


def scene_kind(name: str) -> str:
    """``"rooms"`` for a room (its name starts with ``room``), else ``"shapes"`` (the
    thesis' single reflectors)."""
    return "rooms" if name.startswith("room") else "shapes"


#: A mode maps a scene kind when its mean share of the truth within 2 cm of its profile
#: is at least this: the second front leaves out the sparse maps, whose few points score a
#: small map error however little of the surfaces they show.
COMPLETE = 0.5


def mode_summary(rows: list[dict[str, Any]], kind: str
                 ) -> dict[str, tuple[float, float, float]]:
    """Per mode, over the rows of scenes of ``kind`` (:func:`scene_kind`) with a map: the
    mean of its own seconds (map and post-processing), of its map errors and of its
    completeness within 2 cm (none: 0). A mode with no map is left out."""
    out = {}
    for mode in dict.fromkeys(str(r["mode"]) for r in rows):
        mine = [r for r in rows if r["mode"] == mode and scene_kind(str(r["scene"])) == kind
                and r["map_error_m"] is not None]
        if mine:
            out[mode] = (float(np.mean([(r["map_s"] or 0.0) + r["post_s"] for r in mine])),
                         float(np.mean([r["map_error_m"] for r in mine])),
                         float(np.mean([r.get("completeness_2cm") or 0.0 for r in mine])))
    return out


def pareto_front(cost: np.ndarray, error: np.ndarray) -> np.ndarray:
    """The indices, by increasing cost, of the points that no other point dominates (as
    cheap and as accurate, and better in one): the Pareto front of time against error."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    dominated = ((cost[None] <= cost[:, None]) & (error[None] <= error[:, None])
                 & ((cost[None] < cost[:, None]) | (error[None] < error[:, None]))).any(axis=1)
    front = np.flatnonzero(~dominated)
    return front[np.argsort(cost[front], kind="stable")]


def fronts(summary: dict[str, tuple[float, float, float]]) -> tuple[list[str], list[str]]:
    """The modes on the Pareto front of seconds against map error, fastest first: of all
    modes, and of those that map the kind (completeness ≥ :data:`COMPLETE`)."""
    def front(modes: list[str]) -> list[str]:
        at = pareto_front(np.array([summary[m][0] for m in modes]),
                          np.array([summary[m][1] for m in modes]))
        return [modes[i] for i in at]

    return (front(list(summary)),
            front([m for m in summary if summary[m][2] >= COMPLETE]))


def pareto_png(summary: dict[str, tuple[float, float, float]], kind: str) -> bytes:
    """The modes' mean seconds against mean map error (log–log), hollow where they map
    less than :data:`COMPLETE` of the truth, both Pareto fronts (:func:`fronts`) joined."""
    from ..plots import figure, png_bytes

    fig = figure((6.5, 4.5), 120)
    ax = fig.add_subplot()
    for modes, style, label in zip(fronts(summary), ("--", "-"),
                                   ("front", f"front of the maps ≥ {percent(COMPLETE)} complete"),
                                   strict=True):
        ax.plot([summary[m][0] for m in modes], [100 * summary[m][1] for m in modes], style,
                color="0.5", zorder=1, label=label)
    for m, (x, e, c) in summary.items():
        ax.scatter([x], [100 * e], zorder=2, color="C0",
                   facecolors="C0" if c >= COMPLETE else "none")
        ax.annotate(m, (x, 100 * e), textcoords="offset points", xytext=(4, 3), fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("mean seconds (map + post-processing)")
    ax.set_ylabel("mean map error (cm)")
    ax.set_title(f"The mapping methods on the {kind}: time against error", fontsize=10)
    ax.legend(fontsize=8)
    return png_bytes(fig)


def _pareto_section(rows: list[dict[str, Any]], images: dict[str, str]) -> list[str]:
    """Per scene kind, the modes on both Pareto fronts and whether the default is one."""
    default = MappingSettings().mode
    out = ["## Time against error", "",
           "Per scene kind, each mode's mean seconds (map and post-processing) against its",
           "mean map error over the kind's scenes and noise levels. The Pareto front: the",
           "modes no other is both faster and more accurate than; the map error scores",
           "only the cells a mode draws, so the second front keeps the modes whose profile",
           f"covers at least {percent(COMPLETE)} of the truth within 2 cm on average (hollow in",
           "the figure: the others).", ""]
    for kind in dict.fromkeys(scene_kind(str(r["scene"])) for r in rows):
        summary = mode_summary(rows, kind)
        for name, front in zip(("front", f"front of the maps ≥ {percent(COMPLETE)} complete"),
                               fronts(summary), strict=True):
            on = "is" if default in front else "is not"
            out += [f"**{kind}**, {name} (fastest first): "
                    + ", ".join(f"`{m}` ({summary[m][0]:.2f} s, {100 * summary[m][1]:.2f} cm, "
                                f"{percent(summary[m][2])})" for m in front)
                    + f"; the default `{default}` {on} on it.", ""]
        if kind in images:
            out += [f"![{kind}: time against error]({images[kind]})", ""]
    return out


def _seconds(value: float | None) -> str:
    return NONE if value is None else f"{float(value):.2f}"


def markdown(rows: list[dict[str, Any]], command: str,
             images: dict[str, str] | None = None) -> str:
    """The comparison as markdown: one table per scene, modes by noise σ, then per scene
    kind the Pareto front of time against error (``images``: the kind's PNG's path)."""
    default = MappingSettings().mode
    out = ["# The mapping methods side by side", "",
           "Every `mapping.mode` on the same detections of each scene (issue 15; docs/mapping.md",
           "describes each method). Regenerate with:", "", f"    {command}", "",
           "map s: the method's own stage (accumulation); post s: line of sight, filter,",
           "thinning and profile; accuracy: RMS distance of the profile's points to the true",
           "surfaces; ≤ 2 cm: the share of the insonified truth with a profile point within",
           "2 cm; map error: mean absolute distance of the thin map's cells to the truth (the",
           f"literature's map error). The default is `{default}`. Timings from one run on the",
           "machine that wrote this page (PoCL on a shared CPU): compare them within a table.",
           ""]
    for name in dict.fromkeys(str(r["scene"]) for r in rows):
        out += [f"## {name}", "",
                "| σ | mode | map s | post s | accuracy (cm) | ≤ 2 cm | map error (cm) |"
                " thin cells |",
                "| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
        for r in (r for r in rows if r["scene"] == name):
            out.append(
                f"| {r['noise']:g} | `{r['mode']}` | {_seconds(r['map_s'])} | "
                f"{_seconds(r['post_s'])} | {cm(r['accuracy_m'])} | "
                f"{percent(r['completeness_2cm'])} | "
                f"{cm(r['map_error_m'])} | {r['thin_cells']} |")
        out.append("")
    out += _pareto_section(rows, images or {})
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.methods",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", required=True, type=Path, help="folder for methods.json")
    parser.add_argument("--markdown", type=Path, help="the table's path (DIR/methods.md)")
    parser.add_argument("--scenes", default=",".join(SCENES), help="bundled scene files")
    parser.add_argument("--noise", default=",".join(f"{n:g}" for n in NOISE),
                        help="noise σ values")
    parser.add_argument("--modes", default=",".join(METHODS), help="mapping modes")
    args = parser.parse_args(argv)
    rows = compare(args.scenes.split(","), [float(n) for n in args.noise.split(",")],
                   args.modes.split(","),
                   progress=lambda r: print(f"{r['scene']} σ {r['noise']:g} {r['mode']}: "
                                            f"{r['run_s']:.1f} s", flush=True))
    args.out.mkdir(parents=True, exist_ok=True)
    write_atomic(args.out / "methods.json", (json.dumps(rows, indent=1) + "\n").encode())
    command = "python -m clsonar.tools.methods --out DIR --markdown docs/methods.md"
    table = args.markdown or args.out / "methods.md"
    images = {}
    if plots_available():
        for kind in dict.fromkeys(scene_kind(str(r["scene"])) for r in rows):
            images[kind] = f"methods-pareto-{kind}.png"
            write_atomic(table.parent / images[kind], pareto_png(mode_summary(rows, kind), kind))
    write_atomic(table, (markdown(rows, command, images) + "\n").encode())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
