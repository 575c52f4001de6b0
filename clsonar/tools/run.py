"""``clsonar run SCENE --out DIR``: the scene read, the worker that places its transducers
forked at once (:func:`clsonar.drawing.run_worker`), the pipeline run and its files written
(:mod:`clsonar.outputs`), and what it found summed up; or, with ``--dry-run``, its cost."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from .. import steps
from ..errors import ClsonarError, SceneError
from ..skips import SKIP_NAMES, Skips
from .progress import ProgressLine

if TYPE_CHECKING:
    from ..drawing import PlotWorker
    from ..pipeline import RunResult
    from ..scene import Scene


def run_command(args: argparse.Namespace) -> int:
    """``clsonar run``: the scene read (a bad one fails here, before anything is written),
    its worker forked at once, then its cost (``--dry-run``) or the run."""
    from ..scene import load_scene

    if args.out is None and not args.dry_run:
        raise ClsonarError("run: --out DIR is needed (or --dry-run)")
    scene = load_scene(args.scene)
    off = SKIP_NAMES if "all" in args.no_skip else args.no_skip
    skips = Skips(**{name: name not in off for name in SKIP_NAMES})
    worker = None
    if not args.dry_run:  # placing on the other core while the pipeline is imported
        from ..drawing import run_worker

        worker = run_worker(args.png, scene, args.preset, skips)  # no OpenCL yet
    with worker or contextlib.nullcontext():
        from .. import cost

        try:
            limit = None if args.max_memory is None else cost.parse_size(args.max_memory)
        except ValueError:
            raise ClsonarError(f"--max-memory {args.max_memory!r}: not a size (2G, 500M, "
                               "1.5e9)") from None
        with cost.memory_limit(limit), _named_by_file(scene, args.scene):
            return _run_scene(args, scene, skips, worker)


@contextlib.contextmanager
def _named_by_file(scene: Scene, path: str) -> Iterator[None]:
    """A :class:`~clsonar.errors.SceneError` about ``scene`` raised while it runs (beyond the
    memory, a placement that cannot be made) names its file ``path``, as the loader's do."""
    try:
        yield
    except SceneError as e:
        if e.source != scene.name:
            raise
        raise SceneError(e.message, key=e.key, source=path) from None


def _run_scene(args: argparse.Namespace, scene: Scene, skips: Skips,
               worker: PlotWorker | None) -> int:
    """``clsonar run`` of the loaded ``scene``: its cost (``--dry-run``) or the run, its
    outputs written and summed up (``worker``: :func:`clsonar.drawing.run_worker`'s)."""
    from .. import cost, outputs, pipeline

    if args.dry_run:  # (a run is checked by pipeline.run, before any work)
        pipeline.check_work(pipeline.apply_preset(scene, args.preset), skips)
        print("\n".join(f"{scene.name}: {line}"
                        for line in cost.lines(cost.estimate(scene, args.preset))))
        return 0
    outputs.check_out(args.out)  # and so does an --out that cannot be written
    with outputs.EarlyFiles(args.png, worker) as early:
        line = ProgressLine(not args.quiet)
        try:
            with steps.watching(line.step):
                result = pipeline.run(scene, device=args.device, preset=args.preset,
                                      progress=line.stage, skips=skips,
                                      cache=outputs.early_plots(worker, scene, args.preset),
                                      placement=None if worker is None else worker.first,
                                      maps_done=early.maps_done)
        finally:
            line.done()
        paths = outputs.write_outputs(result, args.out, png=args.png, worker=worker,
                                      early=early, extra={
            "cost": cost.record(cost.of_run(result), cost.peak_bytes())})
    for warning in result.warnings:  # report.json's "warnings", also with --quiet
        print(f"clsonar: warning: {args.scene}: {warning}", file=sys.stderr)
    if not args.quiet:
        _print_run_summary(result, args.out, paths)
    return 0


def _print_run_summary(result: RunResult, out: str, paths: list[Path]) -> None:
    """What ``clsonar run`` found and wrote, in three lines (four when settings were chosen
    from the scene)."""
    from .. import outputs

    m = result.metrics
    rms, acc, done = (outputs.metric(m, k) for k in ("rms_m", "accuracy_m.rms", "completeness.2cm"))
    print(f"{result.scene.name}: {result.counts['echoes']} echoes, "
          f"{result.counts['detections']} detections, "
          f"{sum(result.seconds.values()):.2f} s on {result.device}")
    print("  " + ", ".join(x for x in (
        None if rms is None else f"RMS (eq. 2.6) {rms * 100:.2f} cm",
        None if acc is None else f"accuracy RMS {acc * 100:.2f} cm",
        None if done is None else f"completeness within 2 cm {done * 100:.0f} %",
    ) if x))
    chosen = outputs.chosen_settings(result)
    if chosen:
        print(f"  {chosen}")
    print(f"  outputs in {out}/: " + ", ".join(p.name for p in paths))


__all__ = ["run_command"]
