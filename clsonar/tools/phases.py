"""Where one ``clsonar run SCENE --out DIR --png PNG`` process spends its time (issue 16):
start-up and imports, the OpenCL device and kernels, each pipeline stage (report.json's
``seconds``), and each output, as a table of seconds and shares of the whole.

``python -m clsonar.tools.phases SCENE [--png all|stages|none] [--repeat N]`` runs the
steps of ``clsonar run`` (load, pipeline, outputs; :mod:`clsonar.cli`) in ``N`` fresh
processes, each timing its own phases, and prints each phase's shortest time, its share of
their sum, and the shortest whole process. A phase is the wall time from the end of the one
before; "interpreter start-up, ``import clsonar``" is what the process took before its first
phase began and after its last ended, its exit (the parent's wall time less the phases);
NumPy is one of the command line's imports (:mod:`clsonar.cli` sets its BLAS threads
first), and the collector freezes what exists as ``cli.main`` does. With ``--png all`` scene.png and
profile.png are drawn as the command draws them where a core is free, by a worker process
on the other core (:mod:`clsonar.drawing`; here even on a busy machine), whose own
seconds are listed after the table: they overlap its phases; ``--no-worker`` draws them
in the process, each a phase. With ``--png none`` or ``stages`` the worker places the
transducers and scores the truth (:func:`clsonar.drawing.run_worker`; the sensors stage
and part of the metrics are then waits for it), and stages.npz and the map pictures are
built in a thread (:class:`clsonar.outputs.EarlyFiles`, waited for as a phase) whatever
``--no-worker`` says. Compare tables taken in one session: the machine's load moves every
number.
"""

from __future__ import annotations

import time

_START = time.perf_counter()

import argparse  # noqa: E402  (the clock above starts first)
import contextlib  # noqa: E402
import gc  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

#: The first phase of the table: what a process does before this module's first line.
START_UP = "interpreter start-up, import clsonar"


class _Clock:
    """Seconds of each phase: from the end of the one before to :meth:`mark`."""

    def __init__(self) -> None:
        self.phases: dict[str, float] = {}
        self.since = _START

    def mark(self, name: str) -> None:
        now = time.perf_counter()
        self.phases[name] = now - self.since
        self.since = now


def measure(scene_path: str, png: str, out: str, worker: bool = True
            ) -> dict[str, float]:
    """The phases of one ``clsonar run scene_path --out out --png png``, in this process
    (which must not have imported the pipeline, the outputs or pyopencl yet).

    The worker runs as the command's does on an idle machine (:mod:`clsonar.drawing`,
    started even where the machine is busy; ``worker=False`` or none available: its work
    done here): it places the transducers, then with ``--png all`` draws the plots, else
    scores the truth. Its fork is a phase, and so is the wait for its PNGs once every other
    file is built; its own seconds (placing, drawing each plot, while the phases run) are
    returned too, named ``worker: ...``, not phases."""
    clock = _Clock()
    from .. import cli  # noqa: F401  (what the command line imports to start)

    gc.freeze()  # as the command's cli.main does once its line is read
    clock.mark("command line imports")
    from ..drawing import run_worker
    from ..scene import load_scene
    from ..skips import Skips

    scene = load_scene(scene_path)
    helper = run_worker(png, scene, None, Skips(), if_busy=True) if worker else None
    clock.mark("scene file read, worker forked" if helper is not None else "scene file read")
    with helper or contextlib.nullcontext():  # closed on every exit path from here
        from .. import outputs, pipeline  # noqa: F401  (imported by the command line's run)
        from ..files import write_folder

        clock.mark("pipeline imports")
        files = _run_and_write(scene, png, out, helper, clock)
    write_folder(outputs.check_out(out), files, outputs.OUTPUT_NAMES)
    clock.mark("writing the files")
    return {**clock.phases,
            **{f"{WORKER}{k}": v for k, v in (helper.seconds if helper else {}).items()}}


def _run_and_write(scene, png: str, out: str, helper, clock: _Clock) -> dict[str, bytes]:
    """The pipeline and every file of :func:`measure`, each step a phase (``helper``: the
    run's worker, :func:`clsonar.drawing.run_worker`, or None)."""
    from .. import outputs, pipeline
    from ..opencl import get_context

    context = get_context()
    clock.mark("pyopencl, device")
    early = outputs.EarlyFiles(png, helper)  # stages.npz, map PNGs built beside the run
    plotter = helper if helper is not None and helper.plots else None
    result = pipeline.run(scene, context=context, cache=outputs.early_plots(helper, scene),
                          placement=None if helper is None else helper.first,
                          maps_done=early.maps_done)
    clock.since += sum(result.seconds.values())  # each stage is a phase of its own
    clock.phases.update({f"stage {k}": v for k, v in result.seconds.items()})
    clock.mark("pipeline, outside the stages")
    jobs = outputs.plot_jobs(result) if png == "all" else {}
    if plotter is not None:
        plotter.submit(jobs)
    built = early.files(result)
    clock.mark("waiting for stages.npz, raw, filtered, thin.png")
    files = outputs.data_files(result, None, built)
    clock.mark("report.json, stages.npz, csv")
    files.update(outputs.map_pngs(result, png, built))
    clock.mark("raw, filtered, thin.png")
    drawn = plotter.collect() if plotter is not None else None
    if drawn is not None:
        files.update(drawn)
        clock.mark("scene.png, profile.png: waiting for the worker")
    elif jobs:  # drawn here (pictures imported by the map pictures already)
        for name, job in jobs.items():
            files.update(outputs.draw({name: job}))
            clock.mark(name)
    return files


#: The prefix of the worker's own seconds in :func:`measure`'s answer: not phases.
WORKER = "worker: "


def best_of(scene_path: str, png: str, repeat: int, worker: bool = True
            ) -> tuple[dict[str, float], float]:
    """:func:`measure` in ``repeat`` fresh processes: each phase's shortest time, with
    :data:`START_UP` first, and the shortest whole process (wall time); the worker's
    seconds (:data:`WORKER`) last."""
    best: dict[str, float] = {}
    whole = math.inf
    with tempfile.TemporaryDirectory(prefix="clsonar-phases-") as tmp:
        for k in range(max(1, repeat)):
            command = [sys.executable, "-m", "clsonar.tools.phases", scene_path, "--png", png,
                       "--child", str(Path(tmp) / str(k)), *([] if worker else ["--no-worker"])]
            start = time.perf_counter()
            done = subprocess.run(command, check=True, capture_output=True, text=True)
            wall = time.perf_counter() - start
            found = json.loads(done.stdout)
            phases = {n: v for n, v in found.items() if not n.startswith(WORKER)}
            phases = {START_UP: wall - sum(phases.values()), **phases,
                      **{n: v for n, v in found.items() if n.startswith(WORKER)}}
            best = {name: min(best.get(name, math.inf), s) for name, s in phases.items()}
            whole = min(whole, wall)
    return best, whole


def table(phases: dict[str, float], whole: float) -> list[str]:
    """Markdown rows: each phase's seconds and share of their sum, the sum, the whole
    process; then the worker's seconds, which overlap the phases."""
    own = {n: v for n, v in phases.items() if not n.startswith(WORKER)}
    total = sum(own.values())
    rows = ["| phase | seconds | share |", "| --- | ---: | ---: |"]
    rows += [f"| {name} | {s:.3f} | {100 * s / total:.0f} % |" for name, s in own.items()]
    rows += [f"| sum of the phases | {total:.3f} | |",
             f"| **whole process** | **{whole:.3f}** | |"]
    return rows + [f"| {name} (another core, during the phases) | {s:.3f} | |"
                   for name, s in phases.items() if name.startswith(WORKER)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.phases",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("--png", choices=("none", "stages", "all"), default="all")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--no-worker", action="store_true",
                        help="draw scene.png and profile.png in the process, as before the "
                             "plots' worker")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(measure(args.scene, args.png, args.child, not args.no_worker)))
        gc.freeze()  # and as it does before the interpreter's exit
        return 0
    print("\n".join(table(*best_of(args.scene, args.png, args.repeat, not args.no_worker))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
