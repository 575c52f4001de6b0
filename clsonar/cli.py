"""The ``clsonar`` command line (DESIGN.md, "Command line — a contract").

- ``clsonar run SCENE.json --out DIR`` runs the whole pipeline and writes report.json,
  stages.npz, profile.csv, echoes.csv and one PNG per stage into DIR (outputs.py).
- ``clsonar echoes SCENE.json`` prints the echo table as CSV:
  ``tx,rx,tof_s,amplitude,kind,order``.
- ``clsonar devices`` lists the OpenCL devices, whether each can build kernels, and which one
  would be used.

Errors a user can fix (a bad scene file, no usable OpenCL device) print one line on stderr
and exit with status 2; nothing is written to an output file that is not complete.
"""

from __future__ import annotations

import argparse
import io
import os
import sys
import time
from collections.abc import Callable, Sequence

from .errors import ClsonarError
from .version import __version__

EXIT_USAGE = 2


def _device_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--device", metavar="DEV",
                   help="OpenCL device: 'P:D' as 'clsonar devices' lists, or part of its name "
                        "(default: PYOPENCL_CTX, else the first GPU, else the CPU)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="clsonar",
        description="Ultrasonic sonar simulator and map builder for 2-D indoor scenes (OpenCL).")
    parser.add_argument("--version", action="version", version=f"clsonar {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("run", help="run the whole mapping pipeline and write its outputs",
                       description="Sensors, echoes, detection, map accumulation, filtering, "
                                   "thinning, profile fit and metrics; writes report.json, "
                                   "stages.npz, profile.csv, echoes.csv and PNGs into DIR.")
    p.add_argument("scene", metavar="SCENE.json")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--preset", choices=("thesis", "best"),
                   help="detection/mapping/post settings: the thesis' methods or ours "
                        "(default: the scene file's settings, which default to ours)")
    _device_args(p)
    p.add_argument("--no-skip", action="append", default=[], metavar="WORK",
                   choices=("all", "empty_pairs", "silent_pairs", "quiet_samples", "tiles",
                            "empty_cells", "rooms"),
                   help="do work the scene does not need anyway (to measure what skipping "
                        "saves; the output is the same): empty_pairs, silent_pairs, "
                        "quiet_samples, tiles, "
                        "empty_cells, rooms or all; repeatable")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")
    p.set_defaults(func=_cmd_run)

    p = sub.add_parser("reproduce", help="rerun the thesis' experiments and compare",
                       description="Plane, corner, edge, cylinder and sinusoid at the thesis' "
                                   "distances and the RMS curves of Figs 3.5, 3.6, 3.19, 3.20, "
                                   "with thesis-faithful and best settings; writes "
                                   "reproduce.md, reproduce.json and PNGs into DIR.")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--seeds", type=int, default=5, help="runs per experiment (default 5)")
    p.add_argument("--scenes", metavar="DIR", help="scene folder (default: the bundled ones)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run the trials on this existing Dask cluster (needs clsonar[dask])")
    _device_args(p)
    p.set_defaults(func=_cmd_reproduce)

    p = sub.add_parser("bench", help="time the pipeline against its error, and the "
                                     "accumulation against NumPy",
                       description="Whole-pipeline seconds per stage and error under the "
                                   "thesis' and our settings, and the locus accumulation on "
                                   "OpenCL (float32, float64) against the NumPy float64 "
                                   "reference; writes bench.md and bench.json into DIR.")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--scenes", metavar="NAMES",
                   help="comma-separated bundled scene names (default: the thesis' shapes "
                        "and two rooms)")
    p.add_argument("--repeat", type=int, default=3, help="timed runs, best kept (default 3)")
    p.add_argument("--no-numpy", action="store_true",
                   help="skip the NumPy baseline (slow on large maps)")
    p.add_argument("--floors", default="50", metavar="SIZES",
                   help="comma-separated sizes (m) of multi-room floors mapped at 1 cm, each "
                        "in its own process with its peak memory (default 50; '' for none; "
                        "100 is 10^8 cells)")
    _device_args(p)
    p.set_defaults(func=_cmd_bench)

    p = sub.add_parser("sweep", help="run a Monte-Carlo sweep: scenes × parameter grid × "
                                     "seeds, locally or on a Dask cluster",
                       description="Every (scene, grid point, seed) of the sweep spec (TOML "
                                   "or JSON, docs/sweep.md) is one pipeline run and one row "
                                   "of DIR/table.csv; rows are saved as runs finish, so a "
                                   "sweep run again resumes where it stopped.")
    p.add_argument("spec", metavar="SPEC")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on this existing Dask cluster (needs clsonar[dask])")
    _device_args(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")
    p.set_defaults(func=_cmd_sweep)

    p = sub.add_parser("plot", help="plot a sweep's metrics against its parameters",
                       description="One PNG per metric and swept parameter: mean over seeds "
                                   "with the spread (min–max) shaded, one line per value of "
                                   "the other parameters; written into DIR/plots/.")
    p.add_argument("folder", metavar="DIR", help="a folder written by clsonar sweep")
    p.set_defaults(func=_cmd_plot)

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

    p = sub.add_parser("echoes", help="print the echo table of a scene as CSV",
                       description="Compute every echo return of every transmitter→receiver "
                                   "pair and print tx,rx,tof_s,amplitude,kind,order.")
    p.add_argument("scene", metavar="SCENE.json")
    _device_args(p)
    p.add_argument("--precision", choices=("float32", "float64"), default="float32",
                   help="kernel arithmetic (float64 needs cl_khr_fp64; default float32)")
    p.add_argument("--reference", action="store_true",
                   help="use the NumPy float64 reference instead of OpenCL")
    p.add_argument("-o", "--output", metavar="FILE",
                   help="write the CSV to FILE (atomically) instead of standard output")
    p.set_defaults(func=_cmd_echoes)

    p = sub.add_parser("devices", help="list OpenCL devices and the one clsonar would use")
    _device_args(p)
    p.set_defaults(func=_cmd_devices)
    return parser


class _ProgressLine:
    """``[3/8] detection`` on one rewritten line of stderr, only on a terminal."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()
        self.start = time.perf_counter()

    def __call__(self, stage: str, index: int, total: int) -> None:
        if self.enabled:
            bar = "#" * index + "." * (total - index)
            elapsed = time.perf_counter() - self.start
            print(f"\r[{bar}] {index}/{total} {stage:<13} {elapsed:6.1f} s", end="",
                  file=sys.stderr, flush=True)

    def done(self) -> None:
        if self.enabled:
            print(file=sys.stderr)


def _cmd_run(args: argparse.Namespace) -> int:
    from .scene import load_scene

    scene = load_scene(args.scene)  # a bad scene fails here, before anything is written
    from .outputs import write_outputs
    from .pipeline import SKIP_NAMES, Skips, run

    off = SKIP_NAMES if "all" in args.no_skip else args.no_skip
    skips = Skips(**{name: name not in off for name in SKIP_NAMES})
    progress = _ProgressLine(not args.quiet)
    try:
        result = run(scene, device=args.device, preset=args.preset, progress=progress,
                     skips=skips)
    finally:
        progress.done()
    paths = write_outputs(result, args.out)
    if not args.quiet:
        m = result.metrics
        rms = m["rms_m"]
        acc = m["accuracy_m"]["rms"]
        done = m["completeness"]["2cm"]
        print(f"{scene.name}: {result.counts['echoes']} echoes, "
              f"{result.counts['detections']} detections, "
              f"{sum(result.seconds.values()):.2f} s on {result.device}")
        print("  " + ", ".join(x for x in (
            None if rms is None else f"RMS (eq. 2.6) {rms * 100:.2f} cm",
            None if acc is None else f"accuracy RMS {acc * 100:.2f} cm",
            None if done is None else f"completeness within 2 cm {done * 100:.0f} %",
        ) if x))
        print(f"  outputs in {args.out}/: " + ", ".join(p.name for p in paths))
    return 0


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .tools.reproduce import reproduce

    if args.seeds < 1:
        raise ClsonarError(f"--seeds must be >= 1, not {args.seeds}")
    client = None
    if args.scheduler:
        from .tools.sweep import connect

        client = connect(args.scheduler)
    progress, done = _progress_line()
    try:
        reproduce(Path(args.out), Path(args.scenes) if args.scenes else None,
                  seeds=args.seeds, device=args.device, progress=progress, client=client)
    finally:
        done()
        if client is not None:
            client.close()
    print(f"wrote {args.out}/reproduce.md, reproduce.json and the figures' PNGs")
    return 0


def _progress_line() -> tuple[Callable[[int, int, str], None], Callable[[], None]]:
    """A one-line progress display on a terminal (nothing otherwise) and its closer."""
    show = sys.stderr.isatty()

    def progress(i: int, n: int, what: str) -> None:
        if show:
            print(f"\r[{i}/{n}] {what:<48}", end="", file=sys.stderr, flush=True)

    def done() -> None:
        if show:
            print(file=sys.stderr)

    return progress, done


def _cmd_bench(args: argparse.Namespace) -> int:
    from pathlib import Path

    from .files import bundled_scenes
    from .tools.bench import DEFAULT_SCENES, bench

    if args.repeat < 1:
        raise ClsonarError(f"--repeat must be >= 1, not {args.repeat}")
    names = tuple(n.strip() for n in args.scenes.split(",")) if args.scenes else DEFAULT_SCENES
    missing = [n for n in names if not (bundled_scenes() / f"{n}.json").is_file()]
    if missing:
        raise ClsonarError(f"--scenes: no bundled scene {', '.join(missing)}")
    try:
        floors = tuple(float(x) for x in args.floors.split(",") if x.strip())
    except ValueError:
        raise ClsonarError(f"--floors: not a list of sizes in metres: {args.floors!r}") from None
    if any(not 5.0 <= f <= 1000.0 for f in floors):
        raise ClsonarError(f"--floors: sizes must be 5 to 1000 m, not {args.floors!r}")
    command = "clsonar bench --out " + args.out + (f" --scenes {args.scenes}"
                                                   if args.scenes else "") + (
        f" --floors {args.floors}" if args.floors != "50" else "") + (
        f" --repeat {args.repeat}" if args.repeat != 3 else "")
    progress, done = _progress_line()
    try:
        bench(Path(args.out), names=names, repeat=args.repeat, numpy=not args.no_numpy,
              device=args.device, progress=progress, command=command, floors=floors)
    finally:
        done()
    print(f"wrote {args.out}/bench.md and bench.json")
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
    from pathlib import Path

    from .tools.stress import passed, stress

    if args.count < 1:
        raise ClsonarError(f"--count must be >= 1, not {args.count}")
    command = f"clsonar stress --count {args.count} --out {args.out}"
    progress, done = _progress_line()
    try:
        found = stress(Path(args.out), args.count, device=args.device, progress=progress,
                       command=command)
    finally:
        done()
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ClsonarError as e:
        print(f"clsonar: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("clsonar: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `clsonar echoes x.json | head`
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
