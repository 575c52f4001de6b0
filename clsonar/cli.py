"""The ``clsonar`` command line (docs/design.md, "Command line — a contract").

- ``clsonar run SCENE.json --out DIR`` runs the whole pipeline and writes report.json,
  stages.npz, profile.csv, echoes.csv and one PNG per stage into DIR (outputs.py). Each of
  the run's warnings (report.json's ``warnings``, :mod:`clsonar.checks`) is one line on stderr,
  ``clsonar: warning: SCENE.json: TEXT``; the exit status stays 0.
- ``clsonar reproduce``, ``bench``, ``zoo``, ``sweep``, ``plot`` and ``stress`` run the tools
  of :mod:`clsonar.tools`.
- ``clsonar echoes SCENE.json`` prints the echo table as CSV (``tx,rx,tof_s,amplitude,kind,
  order``); ``clsonar devices`` lists the OpenCL devices, which can build kernels, which one
  would be used.

Errors a user can fix (a bad scene file, an --out that cannot be written, a full disk, no
usable OpenCL device, a Dask scheduler out of reach) print one line on stderr and exit with
status 2; an internal fault prints one line naming the file its traceback was saved in and
exits with status 1. Nothing is written to an output file that is not complete.
"""

from __future__ import annotations

import os

# NumPy's BLAS starts one thread, not one per core, unless the environment says otherwise
# (set before anything below imports NumPy; docs/speed.md, "2026-11-27, start-up").
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import contextlib
import gc
import io
import shlex
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn, TypeAlias

from . import heap
from .errors import ClsonarError, DeviceError, one_line, save_traceback
from .files import PNG_CHOICES
from .opencl import INSTALL_HINT, PRECISIONS
from .presets import PRESETS
from .skips import SKIP_NAMES
from .tools import defaults
from .tools.defaults import ZOO_KINDS
from .tools.progress import ProgressLine
from .version import __version__

if TYPE_CHECKING:

    Subparsers: TypeAlias = argparse._SubParsersAction[argparse.ArgumentParser]

EXIT_USAGE = 2
EXIT_FAULT = 1

#: What to do when the OpenCL device cannot build or run clsonar's kernels.
DEVICE_FIX = f"choose another device with --device ('clsonar devices' lists them) or {INSTALL_HINT}"


def _device_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--device", metavar="DEV",
                   help="OpenCL device: 'P:D' as 'clsonar devices' lists, or part of its name "
                        "(default: PYOPENCL_CTX, else the first GPU, else the CPU)")


def _out_arg(p: argparse.ArgumentParser, required: bool = True) -> None:
    p.add_argument("--out", required=required, metavar="DIR",
                   help="output folder" + ("" if required else " (not with --dry-run)"))


def _scheduler_arg(p: argparse.ArgumentParser, what: str = "") -> None:
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help=f"run {what}on this existing Dask cluster (needs clsonar[dask])")


def _quiet_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")


def _add_run(sub: Subparsers) -> None:
    p = sub.add_parser("run", help="run the whole mapping pipeline and write its outputs",
                       description="Sensors, echoes, detection, map accumulation, filtering, "
                                   "thinning, profile fit and metrics; writes report.json, "
                                   "stages.npz, profile.csv, echoes.csv and PNGs into DIR.")
    p.add_argument("scene", metavar="SCENE.json")
    _out_arg(p, required=False)
    p.add_argument("--preset", choices=tuple(PRESETS),
                   help="detection/mapping/post settings: the thesis' methods or ours "
                        "(default: the scene file's settings, which default to ours)")
    _device_args(p)
    p.add_argument("--no-skip", action="append", default=[], metavar="WORK",
                   choices=("all", *SKIP_NAMES),
                   help="do work the scene does not need anyway (to measure what skipping "
                        f"saves; the output is the same): {', '.join(SKIP_NAMES)} "
                        "or all; "
                        "repeatable")
    p.add_argument("--dry-run", action="store_true",
                   help="place the transducers and print what the run would cost (pairs, "
                        "samples, cells, memory) without running it or writing anything")
    p.add_argument("--max-memory", metavar="SIZE", default=None,
                   help="the most memory the run may count on (2G, 500M, …): a scene "
                        "whose pairs or maps would need more is refused before any work, "
                        "in one line with the estimate (default: what this machine has "
                        "available)")
    p.add_argument("--png", choices=PNG_CHOICES, default="all",
                   help="pictures to write: none; stages (raw, filtered, thin, drawn from "
                        "the maps); all (and scene.png, profile.png). Default: all")
    _quiet_arg(p)
    p.set_defaults(func=_cmd_run)


def _add_reproduce(sub: Subparsers) -> None:
    p = sub.add_parser("reproduce", help="rerun the thesis' experiments and compare",
                       description="Plane, corner, edge, cylinder and sinusoid at the thesis' "
                                   "distances and the RMS curves of Figs 3.5, 3.6, 3.19, 3.20, "
                                   "with thesis-faithful and best settings; writes "
                                   "reproduce.md, reproduce.json and PNGs into DIR.")
    _out_arg(p)
    p.add_argument("--seeds", type=int, default=defaults.REPRODUCE_SEEDS,
                   help=f"runs per experiment (default {defaults.REPRODUCE_SEEDS})")
    p.add_argument("--scenes", metavar="DIR", help="scene folder (default: the bundled ones)")
    _scheduler_arg(p, "the trials ")
    _device_args(p)
    p.set_defaults(func=_cmd_reproduce)


def _add_bench(sub: Subparsers) -> None:
    p = sub.add_parser("bench", help="time the pipeline against its error, and the "
                                     "accumulation against NumPy",
                       description="Whole-pipeline seconds per stage and error under the "
                                   "thesis' and our settings, and the locus accumulation on "
                                   "OpenCL (float32, float64) against the NumPy float64 "
                                   "reference; writes bench.md and bench.json into DIR.")
    _out_arg(p)
    p.add_argument("--scenes", metavar="NAMES",
                   help="comma-separated bundled scene names (default: the thesis' shapes "
                        "and two rooms)")
    p.add_argument("--repeat", type=int, default=defaults.BENCH_REPEAT,
                   help=f"timed runs, best kept (default {defaults.BENCH_REPEAT})")
    p.add_argument("--no-numpy", action="store_true",
                   help="skip the NumPy baseline (slow on large maps)")
    p.add_argument("--floors", default=_sizes(defaults.BENCH_FLOORS), metavar="SIZES",
                   help="comma-separated sizes (m) of multi-room floors mapped at 1 cm, each "
                        "in its own process with its peak memory (default "
                        f"{_sizes(defaults.BENCH_FLOORS)}; '' for none; 100 is 10^8 cells)")
    p.add_argument("--zoo", action="store_true",
                   help="also run the scene zoo with the default settings (a few minutes; "
                        "zoo.md and zoo.json in DIR)")
    p.add_argument("--methods", action="store_true",
                   help="instead, every mapping mode side by side (docs/methods.md): "
                        "methods.md, methods.json and PNGs in DIR; --scenes also takes "
                        "zoo:SEED:KIND:INDEX")
    p.add_argument("--noise", metavar="SIGMAS", help="with --methods: noise σ (default "
                   f"{_sizes(defaults.METHODS_NOISE)})")
    p.add_argument("--modes", metavar="MODES", help="with --methods: modes (default all)")
    _device_args(p)
    p.set_defaults(func=_cmd_bench)


def _add_zoo(sub: Subparsers) -> None:
    p = sub.add_parser("zoo", help="run the scene zoo with the default settings and score it",
                       description="Rooms, corridors, walls, corners, edges, cylinders, "
                                   "sinusoids and thin posts drawn from a seed (docs/zoo.md), "
                                   "each run with the default settings and scored against "
                                   "issue 14's thresholds; writes zoo.md and zoo.json into "
                                   "DIR.")
    _out_arg(p)
    p.add_argument("--seed", type=int, default=0, help="seed of the zoo (default 0)")
    p.add_argument("--kinds", metavar="KINDS",
                   help=f"comma-separated kinds to run (default all: {','.join(ZOO_KINDS)})")
    p.add_argument("--write-scenes", action="store_true",
                   help="also write every scene file into DIR/scenes/")
    p.add_argument("--baseline", metavar="ZOO.json",
                   help="an earlier zoo.json: each case's seconds against its own there")
    p.add_argument("--repeat", type=int, default=1,
                   help="runs of each case, the fastest one's seconds kept (default 1)")
    _device_args(p)
    p.set_defaults(func=_cmd_zoo)


def _add_sweep(sub: Subparsers) -> None:
    p = sub.add_parser("sweep", help="run a Monte-Carlo sweep: scenes × parameter grid × "
                                     "seeds, locally or on a Dask cluster",
                       description="Every (scene, grid point, seed) of the sweep spec (TOML "
                                   "or JSON, docs/sweep.md) is one pipeline run and one row "
                                   "of DIR/table.csv; rows are saved as runs finish, so a "
                                   "sweep run again resumes where it stopped.")
    p.add_argument("spec", metavar="SPEC")
    _out_arg(p)
    _scheduler_arg(p)
    _device_args(p)
    _quiet_arg(p)
    p.set_defaults(func=_cmd_sweep)


def _add_plot(sub: Subparsers) -> None:
    p = sub.add_parser("plot", help="plot a sweep's metrics against its parameters",
                       description="One PNG per metric and swept parameter: mean over seeds "
                                   "with the spread (min–max) shaded, one line per value of "
                                   "the other parameters; written into DIR/plots/.")
    p.add_argument("folder", metavar="DIR", help="a folder written by clsonar sweep")
    p.set_defaults(func=_cmd_plot)


def _add_stress(sub: Subparsers) -> None:
    p = sub.add_parser("stress", help="stress-test the float32 kernels against float64",
                       description="Run the numerical-stability generators (far and tiny "
                                   "scenes, coincident transducers, grazing incidence, "
                                   "caustics, ±180° headings, a million loci, …) on the "
                                   "device and write the worst error per property into "
                                   "DIR/stress.md and DIR/stress.json.")
    p.add_argument("--count", type=int, default=1000, help="cases to run (default 1000)")
    p.add_argument("--out", default="stress", metavar="DIR",
                   help="output folder (default ./stress), or a FILE.md to write with "
                        "FILE.json beside it")
    _device_args(p)
    p.set_defaults(func=_cmd_stress)


def _add_echoes(sub: Subparsers) -> None:
    p = sub.add_parser("echoes", help="print the echo table of a scene as CSV",
                       description="Compute every echo return of every transmitter→receiver "
                                   "pair and print tx,rx,tof_s,amplitude,kind,order.")
    p.add_argument("scene", metavar="SCENE.json")
    _device_args(p)
    p.add_argument("--precision", choices=tuple(PRECISIONS), default="float32",
                   help="kernel arithmetic (float64 needs cl_khr_fp64; default float32)")
    p.add_argument("--reference", action="store_true",
                   help="use the NumPy float64 reference instead of OpenCL")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="write the CSV to FILE (atomically) instead of standard output")
    p.set_defaults(func=_cmd_echoes)


def _add_devices(sub: Subparsers) -> None:
    p = sub.add_parser("devices", help="list OpenCL devices and the one clsonar would use")
    _device_args(p)
    p.set_defaults(func=_cmd_devices)


def build_parser() -> argparse.ArgumentParser:
    """The ``clsonar`` parser: one subcommand per ``_add_*`` function, in this order."""
    parser = argparse.ArgumentParser(prog="clsonar", description=(
        "Ultrasonic sonar simulator and map builder for 2-D indoor scenes (OpenCL)."))
    parser.add_argument("--version", action="version", version=f"clsonar {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_add_run, _add_reproduce, _add_bench, _add_zoo, _add_sweep, _add_plot,
                _add_stress, _add_echoes, _add_devices):
        add(sub)
    return parser


def _sizes(values: Sequence[float]) -> str:
    """``(50.0, 100.0)`` → ``"50,100"``: sizes as the command line writes them."""
    return ",".join(f"{v:g}" for v in values)


def _cmd_run(args: argparse.Namespace) -> int:
    from .tools.run import run_command

    return run_command(args)


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from .tools import reproduce

    if args.seeds < 1:
        raise ClsonarError(f"--seeds must be >= 1, not {args.seeds}")
    client = None
    if args.scheduler:
        from .tools.sweep import connect

        client = connect(args.scheduler)
    line = ProgressLine()
    try:
        reproduce.reproduce(Path(args.out), Path(args.scenes) if args.scenes else None,
                            seeds=args.seeds, device=args.device, progress=line,
                            client=client)
    finally:
        line.done()
        if client is not None:
            client.close()
    print(f"wrote {args.out}/reproduce.md, reproduce.json and the figures' PNGs")
    return 0


def _bench_command(args: argparse.Namespace) -> str:
    """The ``clsonar bench`` command line that regenerates the report (defaults left out)."""
    given = (("--scenes", args.scenes or None, None),
             ("--floors", args.floors, _sizes(defaults.BENCH_FLOORS)),
             ("--repeat", args.repeat, defaults.BENCH_REPEAT),
             ("--noise", getattr(args, "noise", None), None),
             ("--modes", getattr(args, "modes", None), None))
    return f"clsonar bench --out {args.out}" + "".join(
        f" {flag} {shlex.quote(str(value))}" for flag, value, default in given
        if value != default) + "".join(
        f" --{flag}" for flag in ("zoo", "methods") if getattr(args, flag, False))


def _cmd_bench(args: argparse.Namespace) -> int:
    from .tools import bench

    if args.methods:
        from .tools.methods import bench_methods

        return bench_methods(args, _bench_command(args))
    if args.repeat < 1:
        raise ClsonarError(f"--repeat must be >= 1, not {args.repeat}")
    names, floors = bench.scene_names(args.scenes), bench.floor_sizes(args.floors)
    line = ProgressLine()
    try:
        bench.bench(Path(args.out), names=names, repeat=args.repeat, numpy=not args.no_numpy,
                    device=args.device, progress=line, command=_bench_command(args),
                    floors=floors, zoo=args.zoo)
    finally:
        line.done()
    print(f"wrote {args.out}/bench.md and bench.json"
          + (" and the zoo's zoo.md and zoo.json" if args.zoo else ""))
    return 0


def _zoo_kinds(kinds: str | None) -> tuple[str, ...]:
    """The kinds ``--kinds`` names (default: every kind of the zoo)."""
    if not kinds:
        return ZOO_KINDS
    names = tuple(k.strip() for k in kinds.split(",") if k.strip())
    unknown = [k for k in names if k not in ZOO_KINDS]
    if unknown or not names:
        raise ClsonarError(f"--kinds: no zoo kind {', '.join(unknown) or repr(kinds)} "
                           f"(kinds: {', '.join(ZOO_KINDS)})")
    return names


def _cmd_zoo(args: argparse.Namespace) -> int:
    from .tools.zoo.report import read_baseline, zoo_report

    if args.seed < 0:
        raise ClsonarError(f"--seed must be >= 0, not {args.seed}")
    if args.repeat < 1:
        raise ClsonarError(f"--repeat must be >= 1, not {args.repeat}")
    kinds = _zoo_kinds(args.kinds)
    baseline = read_baseline(args.baseline) if args.baseline else None
    command = f"clsonar zoo --out {shlex.quote(args.out)}" + "".join(
        f" {flag} {shlex.quote(str(value))}" for flag, value in
        (("--seed", args.seed or None), ("--kinds", args.kinds),
         ("--repeat", args.repeat if args.repeat > 1 else None)) if value)
    line = ProgressLine()
    try:
        rows = zoo_report(Path(args.out), seed=args.seed, kinds=kinds, device=args.device,
                          progress=line, command=command, write_scenes=args.write_scenes,
                          baseline=baseline, repeat=args.repeat)
    finally:
        line.done()
    passed = sum(r["passed"] for r in rows)
    print(f"{passed} of {len(rows)} cases pass every threshold; wrote {args.out}/zoo.md and "
          "zoo.json" + (f" and {len(rows)} scenes in {args.out}/scenes/"
                        if args.write_scenes else ""))
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .tools.sweep import ProgressBar, connect, load_spec, sweep

    spec = load_spec(args.spec)  # a bad spec fails here, before anything is written
    client = connect(args.scheduler) if args.scheduler else None
    progress = ProgressBar(not args.quiet)
    try:
        rows = sweep(spec, args.out, device=args.device, client=client, progress=progress)
    finally:
        progress.done()
        if client is not None:
            client.close()
    if not args.quiet:
        print(f"{spec.name}: {len(rows)} runs in {args.out}/table.csv "
              f"(clsonar plot {args.out} draws them)")
    return 0


def _cmd_plot(args: argparse.Namespace) -> int:
    from .tools.sweepplot import plot_sweep

    paths = plot_sweep(args.folder)
    print(f"wrote {len(paths)} PNGs in {args.folder}/plots/")
    return 0


def _cmd_stress(args: argparse.Namespace) -> int:
    from .tools.stress import passed, stress

    if args.count < 1:
        raise ClsonarError(f"--count must be >= 1, not {args.count}")
    command = f"clsonar stress --count {args.count} --out {args.out}"
    line = ProgressLine()
    try:
        found = stress(Path(args.out), args.count, device=args.device, progress=line,
                       command=command)
    finally:
        line.done()
    fraction = found.differing / max(found.pixels, 1)
    print(f"{found.cases} cases: {found.nonfinite} with NaN/Inf, max |Δτ| "
          f"{found.tof_max_s * 1e6:.4f} µs, {fraction:.4%} of map pixels differ "
          f"({found.differing_off_edge} off an edge), {found.work_group_mismatches} "
          f"work-group mismatches: {'pass' if passed(found) else 'FAIL'}")
    print(f"wrote {args.out}" + ("" if args.out.endswith(".md") else "/stress.md")
          + " and its .json")
    return 0 if passed(found) else 1


def _cmd_echoes(args: argparse.Namespace) -> int:
    from .files import write_atomic
    from .scene import load_scene

    scene = load_scene(args.scene)  # a bad scene fails here, before OpenCL is touched
    from .echoes import compute_echoes, reference_echoes

    if args.reference:
        table = reference_echoes(scene)
    else:
        table = compute_echoes(scene, device=args.device, precision=args.precision)
    if args.output:
        buf = io.StringIO()
        table.write_csv(buf)
        write_atomic(args.output, buf.getvalue().encode("utf-8"))
    else:
        table.write_csv(sys.stdout)
    return 0


def _cmd_devices(args: argparse.Namespace) -> int:
    from .opencl import INSTALL_HINT, choose_device, list_devices

    devices = list_devices()
    if not devices:
        print(f"No OpenCL device found: {INSTALL_HINT}.")
        return 1
    print(f"{'index':6} {'kind':5} {'fp64':4} {'memory':>9}  device")
    for d in devices:
        status = "ok" if d.usable else d.problem
        print(f"{d.index:6} {d.kind:5} {'yes' if d.fp64 else 'no':4} "
              f"{d.global_mem_bytes / 2**30:7.1f} G  {d.name} ({d.platform}): {status}")
    if not any(d.usable for d in devices):
        print(f"No device can build kernels: {INSTALL_HINT}.")
        return 1
    chosen = choose_device(args.device)
    index = next(d.index for d in devices if d.name == chosen.name.strip())
    print(f"clsonar would use {index}: {chosen.name.strip()}")
    return 0


def error_line(error: ClsonarError) -> str:
    """``clsonar: error: …``: the error on one line; a device error that does not say what
    to do (a kernel that failed to build) gets :data:`DEVICE_FIX`."""
    text = one_line(str(error))
    if isinstance(error, DeviceError) and not any(
            hint in text for hint in ("install", "clsonar devices", "precision=")):
        text += f"; {DEVICE_FIX}"
    return f"clsonar: error: {text}"


def _device_label(device: str | None) -> str:
    """The name of the device ``--device`` chooses, for a line about an OpenCL failure."""
    from .opencl import choose_device

    try:
        return choose_device(device).name.strip()
    except Exception:  # the failure being reported comes first
        return f"device {device!r}" if device else "the OpenCL device"


def fault_line(error: Exception, device: str | None = None) -> tuple[str, int]:
    """The one line and exit status of an exception no command turned into a
    :class:`ClsonarError`: a file system error naming its file is the user's to fix
    (status 2); anything else is a fault (status 1) whose traceback is saved to a file the
    line names, an OpenCL failure naming the device and what to do."""
    cl = sys.modules.get("pyopencl")
    if cl is not None and isinstance(error, cl.Error):
        what = (f"OpenCL failed on {_device_label(device)}: {one_line(str(error))[:200]}; "
                f"{DEVICE_FIX}")
    elif isinstance(error, OSError) and error.filename is not None:
        return f"clsonar: error: {error.filename}: {error.strerror or error}", EXIT_USAGE
    else:
        what = f"internal error: {type(error).__name__}: {one_line(str(error))[:200]}"
    saved = save_traceback(error)
    where = f"traceback in {saved}" if saved else "the traceback could not be saved"
    return f"clsonar: {what} ({where}; please report it)", EXIT_FAULT


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0; 2: an error the user can fix; 1:
    an internal fault; 130: interrupted). Every failure is one line on stderr. Without
    ``argv`` (the process's own command) the garbage collector leaves alone what exists
    before and after the command (``gc.freeze``): a full collection of 18-21 ms in a run of
    the room, 15-40 ms of the interpreter's exit; and ``clsonar run`` then ends the
    process at once (:func:`_exit_now`)."""
    args = build_parser().parse_args(argv)
    whole = argv is None  # this process's own command line: it ends when main returns
    if whole:  # what it imported lives to its exit: no collection of cycles searches it
        gc.freeze()
        heap.settle()  # and its arrays come from the heap, not from fresh mappings
    status = _command(args, whole)
    if whole and args.func is _cmd_run:
        _exit_now(status)
    return status


def _command(args: argparse.Namespace, whole: bool) -> int:
    """The command ``args`` names, run: its exit status, every failure one line on stderr
    (``whole``: the process's own command line, :func:`main`)."""
    try:
        return args.func(args)
    except ClsonarError as e:
        print(error_line(e), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("clsonar: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `clsonar echoes x.json | head`
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as e:  # an internal fault: one line, its traceback saved
        line, status = fault_line(e, getattr(args, "device", None))
        print(line, file=sys.stderr)
        return status
    finally:
        if whole:  # nor does the interpreter's exit search what the command made
            gc.freeze()


def _exit_now(status: int) -> NoReturn:
    """End this process with ``status`` now, its standard streams flushed: what ``clsonar
    run`` leaves — its folder written (or not at all), its worker and thread closed — the
    interpreter's exit would only tear down (20-40 ms of a 0.6 s run of the room: every
    module, pyopencl's context and PoCL's threads). No ``atexit`` handler runs; clsonar
    registers none, and no command a run starts outlives it."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing to flush
            stream.flush()
    os._exit(status)
