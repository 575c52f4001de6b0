"""Run time against error: the knobs that trade one for the other, and what skipping saves.

Part of ``clsonar bench`` (issue "Fast"). For each scene, the whole pipeline runs under
every setting of :data:`KNOBS` — the thesis-faithful settings, ours, and ours with one knob
turned (cell size 0.5 / 1 / 2 / 5 cm, threshold detection, locus votes with a narrow or
wide band, float64 kernels, fewer transducers, no line-of-sight check) — and each run's
seconds and error are
kept. :func:`pareto` marks the settings no other setting beats on both; :func:`beats_thesis`
names the settings faster *and* more accurate than the thesis-faithful ones on every scene.
:func:`bench_skips` times the same run with every skip on and off (:class:`Skips`) and
checks that the output is identical.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..outputs import metric
from ..pipeline import RunResult, Skips, run
from ..scene import RandomLines, Scene, WallFollowing


def _cell(size: float) -> Callable[[Scene], Scene]:
    return lambda s: dataclasses.replace(s, cell=size)


def _with(section: str, **values) -> Callable[[Scene], Scene]:
    def change(s: Scene) -> Scene:
        return dataclasses.replace(s, **{section: dataclasses.replace(getattr(s, section),
                                                                      **values)})
    return change


def _fewer_transducers(s: Scene) -> Scene | None:
    """Half the elements per random line, or 1.5× the wall-following step (None: n/a)."""
    p = s.sensors.placement
    if isinstance(p, RandomLines):
        p = dataclasses.replace(p, elements=max(2, p.elements // 2))
    elif isinstance(p, WallFollowing):
        p = dataclasses.replace(p, step_m=1.5 * p.step_m)
    else:
        return None
    return dataclasses.replace(s, sensors=dataclasses.replace(s.sensors, placement=p))


#: ``(label, preset, change)``: the settings compared (``change`` may return None: n/a).
KNOBS: tuple[tuple[str, str | None, Callable[[Scene], Scene | None] | None], ...] = (
    ("thesis", "thesis", None),
    ("thesis, 2 cm", "thesis", _cell(0.02)),
    ("ours", None, None),
    ("ours, 0.5 cm", None, _cell(0.005)),
    ("ours, 2 cm", None, _cell(0.02)),
    ("ours, 5 cm", None, _cell(0.05)),
    ("ours, threshold detection", None, _with("detection", mode="threshold")),
    ("ours, loci, band 1 cm", None, _with("mapping", mode="loci", band_m=0.01)),
    ("ours, loci, band 3 cm", None, _with("mapping", mode="loci", band_m=0.03)),
    ("ours, float64", None, _with("mapping", precision="float64")),
    ("ours, fewer transducers", None, _fewer_transducers),
    ("ours, no line of sight", None, _with("mapping", line_of_sight=False)),
    ("ours, 2 cm, no line of sight", None,
     lambda s: _with("mapping", line_of_sight=False)(_cell(0.02)(s))),
)

THESIS = "thesis"


@dataclass(frozen=True)
class TradeoffRow:
    """One scene under one setting: seconds and error (accuracy RMS, None: no profile)."""

    scene: str
    setting: str
    total_s: float
    accuracy_m: float | None
    rms_m: float | None
    completeness_2cm: float | None
    pareto: bool = False


def fastest_run(scene: Scene, context, repeat: int, **options) -> RunResult:
    """The run with the shortest total of ``repeat`` runs (the first also builds kernels)."""
    runs = [run(scene, context=context, **options) for _ in range(max(1, repeat))]
    return min(runs, key=lambda r: sum(r.seconds.values()))


def bench_tradeoff(scene: Scene, context, repeat: int,
                   knobs=KNOBS) -> list[TradeoffRow]:
    """Every applicable setting of ``knobs`` on ``scene``, Pareto front marked."""
    rows = []
    for label, preset, change in knobs:
        variant = scene if change is None else change(scene)
        if variant is None:
            continue
        r = fastest_run(variant, context, repeat, preset=preset)
        m = r.metrics
        rows.append(TradeoffRow(scene.name, label, float(sum(r.seconds.values())),
                                metric(m, "accuracy_m.rms"), metric(m, "rms_m"),
                                metric(m, "completeness.2cm")))
    return pareto(rows)


def _error(row: TradeoffRow) -> float:
    return math.inf if row.accuracy_m is None else row.accuracy_m


def pareto(rows: list[TradeoffRow]) -> list[TradeoffRow]:
    """``rows`` with ``pareto`` set on those no other row of the same scene beats on both
    time and error (:func:`pareto_front`)."""
    front: set[int] = set()
    for scene in {r.scene for r in rows}:
        mine = [i for i, r in enumerate(rows) if r.scene == scene]
        at = pareto_front(np.array([rows[i].total_s for i in mine]),
                          np.array([_error(rows[i]) for i in mine]))
        front.update(mine[k] for k in at)
    return [dataclasses.replace(r, pareto=i in front) for i, r in enumerate(rows)]


def pareto_front(cost: np.ndarray, error: np.ndarray) -> np.ndarray:
    """The indices, by increasing cost, of the points that no other point dominates (as
    cheap and as accurate, and better in one): the Pareto front of time against error."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    dominated = ((cost[None] <= cost[:, None]) & (error[None] <= error[:, None])
                 & ((cost[None] < cost[:, None]) | (error[None] < error[:, None]))).any(axis=1)
    front = np.flatnonzero(~dominated)
    return front[np.argsort(cost[front], kind="stable")]


def beats_thesis(rows: list[TradeoffRow]) -> list[str]:
    """The settings both faster and more accurate than ``thesis`` on every scene."""
    scenes = sorted({r.scene for r in rows})
    thesis = {r.scene: r for r in rows if r.setting == THESIS}
    winners = []
    for label, _, _ in KNOBS:
        mine = {r.scene: r for r in rows if r.setting == label}
        if label != THESIS and scenes and all(
                s in mine and s in thesis and mine[s].total_s < thesis[s].total_s
                and _error(mine[s]) < _error(thesis[s]) for s in scenes):
            winners.append(label)
    return winners


@dataclass(frozen=True)
class SkipRow:
    """One scene with every skip on and off: seconds, ratio, identical output."""

    scene: str
    settings: str
    skipping_s: float
    no_skipping_s: float
    speedup: float
    identical: bool
    counts: dict[str, int]


def identical(a: RunResult, b: RunResult) -> bool:
    """Same maps, profile and metrics."""
    return (all(np.array_equal(getattr(a, k), getattr(b, k))
                for k in ("raw", "filtered", "occupied", "thin"))
            and np.array_equal(a.profile.points, b.profile.points) and a.metrics == b.metrics)


def bench_skips(scene: Scene, settings: str, preset: str | None, context,
                repeat: int) -> SkipRow:
    """The pipeline on ``scene`` with :class:`Skips` on and with every skip off."""
    on = fastest_run(scene, context, repeat, preset=preset)
    off = fastest_run(scene, context, repeat, preset=preset, skips=Skips.none())
    t_on, t_off = sum(on.seconds.values()), sum(off.seconds.values())
    keys = ("pairs", "pairs_skipped_empty", "pairs_skipped_silent", "map_cells",
            "cells_post_processed", "tiles_total", "tiles_skipped")
    return SkipRow(scene.name, settings, t_on, t_off, t_off / t_on, identical(on, off),
                   {k: on.counts[k] for k in keys if k in on.counts})


def tradeoff_png(rows: list[TradeoffRow]) -> bytes:
    """Run time against error per scene (log–log), the Pareto front joined, the thesis
    setting in red."""
    from ..plots import figure, png_bytes

    scenes = list(dict.fromkeys(r.scene for r in rows))
    cols = min(3, max(1, len(scenes)))
    nrows = max(1, math.ceil(len(scenes) / cols))
    fig = figure((4.2 * cols, 3.6 * nrows), 120)
    for i, name in enumerate(scenes):
        ax = fig.add_subplot(nrows, cols, i + 1)
        mine = [(r, r.accuracy_m * 100) for r in rows
                if r.scene == name and r.accuracy_m is not None]
        front = sorted(((r, cm) for r, cm in mine if r.pareto), key=lambda p: p[0].total_s)
        ax.plot([r.total_s for r, _ in front], [cm for _, cm in front], "-",
                color="tab:blue", alpha=0.5, label="Pareto front")
        for r, cm in mine:
            thesis = r.setting.startswith(THESIS)
            ax.plot(r.total_s, cm, "o" if r.pareto else ".",
                    color="tab:red" if thesis else "tab:blue")
            ax.annotate(r.setting.replace("ours, ", ""), (r.total_s, cm),
                        fontsize=6, xytext=(3, 2), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("run time (s)", fontsize=8)
        ax.set_ylabel("accuracy RMS (cm)", fontsize=8)
        ax.tick_params(labelsize=7)
    return png_bytes(fig)


__all__ = ["KNOBS", "SkipRow", "TradeoffRow", "beats_thesis", "bench_skips", "bench_tradeoff",
           "fastest_run", "identical", "pareto", "pareto_front", "tradeoff_png"]
