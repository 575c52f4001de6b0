"""What a user waits for (issue 16): Monte-Carlo throughput — a sweep of one scene over
seeds at each noise level, in one process with one OpenCL context and one stage cache, as a
sweep runs it — and the whole ``clsonar run`` command as a process, with each choice of
pictures (``--png``). A section of ``clsonar bench``."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..files import PNG_CHOICES
from ..pipeline import StageCache
from ..pipeline import run as run_pipeline
from ..scene import Scene
from .variants import with_seed

#: The noise levels (σn, units) and seeds of the sweep.
NOISES = (0.0, 0.6)
SEEDS = 20


@dataclass(frozen=True)
class SweepRow:
    """One noise level of the sweep: its runs, their seconds and runs per second."""

    noise_std: float
    runs: int
    seconds: float
    runs_per_s: float
    #: the same runs with every stage of every run computed (no cache)
    computed_runs_per_s: float = float("nan")


@dataclass(frozen=True)
class ProcessRow:
    """``clsonar run SCENE --png PNG`` as a process: the best wall time of the repeats."""

    png: str
    seconds: float


def bench_sweep(scene: Scene, context, seeds: int = SEEDS, noises: tuple[float, ...] = NOISES
                ) -> list[SweepRow]:
    """``scene`` run at each of ``noises`` for ``seeds`` seeds (placement and noise seeds
    advanced, :func:`~clsonar.tools.variants.with_seed`), as ``clsonar sweep`` runs them:
    one context and one :class:`~clsonar.pipeline.StageCache` (a first run, not counted,
    builds the kernels); and again with every stage computed."""
    cache = StageCache()
    run_pipeline(scene, context=context, cache=cache)
    rows = []
    for noise in noises:
        seconds = [_sweep_seconds(scene, context, seeds, noise, c) for c in (cache, None)]
        rows.append(SweepRow(noise, seeds, seconds[0], seeds / seconds[0],
                             seeds / seconds[1]))
    return rows


def _sweep_seconds(scene: Scene, context, seeds: int, noise: float,
                   cache: StageCache | None) -> float:
    """Seconds of ``seeds`` runs of ``scene`` at ``noise``, each with its seed, through
    ``cache`` (None: every stage of every run computed)."""
    start = time.perf_counter()
    for k in range(seeds):
        run_pipeline(with_seed(scene, k + 1, noise), context=context, cache=cache)
    return time.perf_counter() - start


def bench_process(scene_path: Path, repeat: int, device: str | None = None
                  ) -> list[ProcessRow]:
    """``clsonar run scene_path --png P -q`` as a process for each of
    :data:`~clsonar.files.PNG_CHOICES`, the best of ``repeat`` wall times."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="clsonar-bench-") as tmp:
        for png in PNG_CHOICES:
            best = float("inf")
            for k in range(max(1, repeat)):
                command = [sys.executable, "-m", "clsonar", "run", str(scene_path), "--out",
                           str(Path(tmp) / f"{png}-{k}"), "-q", "--png", png]
                if device is not None:
                    command += ["--device", device]
                start = time.perf_counter()
                subprocess.run(command, check=True, capture_output=True)
                best = min(best, time.perf_counter() - start)
            rows.append(ProcessRow(png, best))
    return rows


def throughput_markdown(name: str, sweep: list[SweepRow], process: list[ProcessRow]
                        ) -> list[str]:
    """The section of ``bench.md``: the sweep's runs per second and the command's time."""
    lines = ["", f"## End to end: `{name}`", "",
             "A sweep over seeds, as `clsonar sweep` runs it (one context, one stage cache "
             "reusing every stage whose inputs are unchanged: a noise-free run of a "
             "placement without randomness is the same run for every seed), and the same "
             "runs with every stage computed:", "",
             "| noise σn | runs | seconds | runs per second | every stage computed, runs "
             "per second |", "| ---: | ---: | ---: | ---: | ---: |"]
    lines += [f"| {r.noise_std:g} | {r.runs} | {r.seconds:.2f} | {r.runs_per_s:.2f} | "
              f"{r.computed_runs_per_s:.2f} |" for r in sweep]
    lines += ["", "`clsonar run` as a whole process (start-up, kernels, outputs), best of the "
              "repeats:", "", "| `--png` | seconds |", "| --- | ---: |"]
    lines += [f"| {r.png} | {r.seconds:.2f} |" for r in process]
    return lines


__all__ = ["NOISES", "SEEDS", "ProcessRow", "SweepRow", "bench_process", "bench_sweep",
           "throughput_markdown"]
