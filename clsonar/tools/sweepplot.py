"""``clsonar plot DIR``: a sweep's metrics against its parameters (matplotlib, Agg).

One PNG per numeric metric and swept parameter, as the thesis' Figs 3.5, 3.6, 3.19 and 3.20
draw the RMS error (eq. 2.6) against distance and noise: the mean over seeds, with the
spread (min–max over seeds) shaded, one line for each base scene and value of the other
swept parameters. ``clsonar reproduce`` draws its curves with the same :func:`draw_spread`.
"""

from __future__ import annotations

import itertools
import json
import os
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ClsonarError
from ..files import write_atomic
from ..outputs import require_plots
from .sweep import read_sweep


def draw_spread(ax, x: Sequence[float], samples: Sequence[Sequence[float]], style: str,
                label: str) -> None:
    """Draw the mean of each ``samples[i]`` at ``x[i]`` with the min–max spread shaded
    (NaN where a point has no sample)."""
    means = [float(np.mean(s)) if len(s) else np.nan for s in samples]
    lo = [float(np.min(s)) if len(s) else np.nan for s in samples]
    hi = [float(np.max(s)) if len(s) else np.nan for s in samples]
    line, = ax.plot(x, means, style, label=label)
    ax.fill_between(x, lo, hi, alpha=0.2, color=line.get_color())


def _numeric(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _scale(metric: str) -> tuple[float, str]:
    """Metres are drawn in cm (``rms_m`` → ``rms_m (cm)``)."""
    head = metric.split(".")[0]
    return (100.0, f"{metric} (cm)") if head.endswith("_m") else (1.0, metric)


def _label(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v) if isinstance(v, str) else json.dumps(v)


def _key(v: Any) -> str:
    return json.dumps(v, sort_keys=True)


def metric_png(name: str, rows: list[dict[str, Any]], metric: str, param: str,
               others: Sequence[str]) -> bytes | None:
    """``metric`` against ``param``: mean ± spread over seeds, one line per scene and
    combination of ``others``; None if ``metric`` has no numeric value."""
    from ..plots import figure, png_bytes

    if not any(_numeric(r.get(metric)) for r in rows):
        return None
    factor, ylabel = _scale(metric)
    xs = list({_key(r[param]): r[param] for r in rows}.values())
    numeric_x = all(_numeric(v) for v in xs)
    if numeric_x:
        xs.sort()
    positions = [float(v) for v in xs] if numeric_x else list(range(len(xs)))
    groups = ["scene", *others]
    fig = figure((6.5, 4.2), 120)
    ax = fig.add_subplot()
    lines = {tuple(_key(r.get(g)) for g in groups): r for r in rows}
    seeds = len({r["seed"] for r in rows})
    every = []
    for (keys, sample), style in zip(sorted(lines.items()), itertools.cycle(
            ("o-", "s-", "^-", "D-", "v-", "x-")), strict=False):
        chosen = [r for r in rows if tuple(_key(r.get(g)) for g in groups) == keys]
        samples = [[r[metric] * factor for r in chosen
                    if _key(r[param]) == _key(x) and _numeric(r.get(metric))] for x in xs]
        every += [v for s in samples for v in s]
        label = ", ".join([str(sample["scene"])]
                          + [f"{g}={_label(sample.get(g))}" for g in others])
        draw_spread(ax, positions, samples, style, label)
    if not numeric_x:
        ax.set_xticks(positions, [_label(v) for v in xs])
    positive = [v for v in every if v > 0]
    if positive and len(positive) == len(every) and max(positive) / min(positive) > 30:
        ax.set_yscale("log")
    ax.set_xlabel(param)
    ax.set_ylabel(ylabel)
    ax.set_title(f"{name}: {metric} against {param}\nmean over {seeds} seed"
                 f"{'s' if seeds != 1 else ''}, shaded: min–max", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return png_bytes(fig)


def plot_file_name(metric: str, param: str) -> str:
    """``rms_m_vs_signal.noise_std.png``: the PNG of ``metric`` against ``param``."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", f"{metric}_vs_{param}") + ".png"


def plot_sweep(folder: str | os.PathLike[str]) -> list[Path]:
    """Draw every numeric metric of the sweep in ``folder`` against each swept parameter
    into ``folder/plots/``; returns the PNGs written."""
    require_plots("clsonar plot")
    folder = Path(folder)
    header, rows = read_sweep(folder)
    if not rows:
        raise ClsonarError(f"{folder}: no finished run to plot yet")
    # a parameter given one value is a setting, not a variable: nothing to draw against
    params = [p for p in header["parameters"] if len({_key(r.get(p)) for r in rows}) > 1]
    out = folder / "plots"
    out.mkdir(exist_ok=True)
    written = []
    for metric in header["metrics"]:
        for param in params:
            others = [p for p in params if p != param]
            png = metric_png(header["name"], rows, metric, param, others)
            if png is not None:
                path = out / plot_file_name(metric, param)
                write_atomic(path, png)
                written.append(path)
    return written
