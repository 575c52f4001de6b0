"""Fault injection (issue 19, docs/faults.md): faults injected into real runs of ``clsonar
run`` and ``clsonar sweep``, and each ending checked. A run's outputs must be whole (one
run's files, their counts agreeing with its report.json) or absent; a sweep killed or
stopped by a full disk and run again must end with exactly an uninterrupted sweep's table
(no row lost or repeated); every failure must be exactly one line on stderr with its exit
status (2: the user can fix it; 1: an internal fault, its traceback saved to the file the
line names); and no temporary file may outlive the next write.

The faults (:data:`FAULTS`): kill -9 at random moments of ``clsonar run`` and of ``clsonar
sweep``, and halfway through each of their writes (processes); two runs writing the same
``--out`` at once (processes); a full disk (``ENOSPC``) at every write of every writer
(``os.write`` replaced in this process: half the bytes written, then the error, and every
later write refused too); a kernel that fails to build, at every build; an exception, and
an OpenCL error, at every stage of the pipeline; a Dask scheduler out of reach; a Dask
worker killed mid-sweep (a ``LocalCluster``).

Run ``python -m clsonar.tools.faults [--count N] [--seed S]`` for the markdown table;
tests/test_faults.py runs every fault with a small count. The package: :mod:`.harness` (the
checks and the injectors), :mod:`.cases` (the faults).
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from .cases import (
    concurrent_out,
    dask_worker,
    disk_full_files,
    disk_full_run,
    disk_full_sweep,
    kernel_build,
    kill_run,
    kill_run_writes,
    kill_sweep,
    kill_sweep_writes,
    opencl_failure,
    pipeline_exception,
    unreachable_scheduler,
)
from .harness import SCENES, Outcome, disk_full, outputs_of, run_argv, small_scene, temporary

__all__ = ["FAULTS", "SCENES", "Outcome", "disk_full", "inject", "main", "markdown",
           "outputs_of", "run_argv", "small_scene", "temporary"]

#: Every fault: its injections (count: those drawn at random; the rest inject at every
#: write, build or stage).
FAULTS: dict[str, Callable[[Path, random.Random, int], Outcome]] = {
    "kill-run": kill_run, "kill-sweep": kill_sweep, "kill-run-writes": kill_run_writes,
    "kill-sweep-writes": kill_sweep_writes, "concurrent-out": concurrent_out,
    "disk-full-run": disk_full_run, "disk-full-sweep": disk_full_sweep,
    "disk-full-files": disk_full_files, "kernel-build": kernel_build,
    "pipeline-exception": pipeline_exception, "opencl-failure": opencl_failure,
    "unreachable-scheduler": unreachable_scheduler, "dask-worker": dask_worker,
}


def inject(name: str, count: int = 3, seed: int = 0) -> Outcome:
    """Run fault ``name``'s injections in a temporary folder (``count`` random moments
    where it draws them, from ``seed``)."""
    with tempfile.TemporaryDirectory(prefix=f"clsonar-faults-{name}-") as work:
        return FAULTS[name](Path(work), random.Random(seed), count)


def markdown(outcomes: Sequence[Outcome], command: str) -> str:
    """docs/faults.md's table: per fault, the injections, the runs that lost or repeated a
    result, those that did not end in one line, those that left a temporary file."""
    rows = ["| Fault | Injected | Lost or repeated a result | Not one line | "
            "Temporary files left |", "|---|---:|---:|---:|---:|"]
    rows += [f"| {o.fault} | {o.injections} | {o.lost} | "
             f"{'–' if o.not_one_line is None else o.not_one_line} | {o.temporary} |"
             for o in outcomes]
    return "\n".join([*rows, "", f"Regenerate: `{command}` (– : a kill -9 leaves "
                      "nothing to print).", ""])


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m clsonar.tools.faults``: every fault, the table on stdout; status 1 when
    any run lost a result, did not end in one line or left a temporary file."""
    p = argparse.ArgumentParser(prog="python -m clsonar.tools.faults")
    p.add_argument("--count", type=int, default=6, help="random kills and rounds per fault")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    outcomes = []
    for name in FAULTS:
        try:
            outcomes.append(inject(name, args.count, args.seed))
        except ModuleNotFoundError as e:  # the Dask fault without clsonar[dask]
            print(f"{name}: not run: {e}", file=sys.stderr)
    print(markdown(outcomes, f"python -m clsonar.tools.faults --count {args.count} "
                             f"--seed {args.seed}"))
    for o in outcomes:
        for problem in o.problems:
            print(f"{o.fault}: {problem}", file=sys.stderr)
    return 1 if any(o.problems for o in outcomes) else 0

