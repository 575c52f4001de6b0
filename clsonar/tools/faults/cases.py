"""The faults: each injects its fault into real runs in folder ``work`` and returns the
:class:`~.harness.Outcome` (``count``: kills or rounds, where they are drawn from ``rng``)."""

from __future__ import annotations

import contextlib
import os
import random
import re
import signal
import tempfile
import time
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any
from unittest import mock

from ...cli import DEVICE_FIX
from ...errors import ClsonarError
from ...files import remove_stale
from ...pipeline import PRESETS, STAGES
from .. import sweep as sw
from .harness import (
    INJECTED,
    NO_SPACE,
    SCENES,
    Outcome,
    call,
    disk_full,
    failing_build,
    failing_stage,
    killed_writer,
    one_line,
    outputs_of,
    process,
    rmtree,
    run_argv,
    small_scene,
    sweep_rows,
    table_matches,
    temporary,
    write_spec,
    writes,
)

# --------------------------------------------------------------------------- process faults


def _kill_at(argv: Sequence[str], moment: float) -> bool:
    """Start ``clsonar ARGV`` and kill -9 it ``moment`` seconds later; whether it was still
    running then."""
    proc = process(argv)
    time.sleep(moment)
    alive = proc.poll() is None
    if alive:
        proc.send_signal(signal.SIGKILL)
    proc.wait()
    return alive


def _seconds(argv: Sequence[str]) -> float:
    """Wall seconds of ``clsonar ARGV`` run whole in a new process."""
    start = time.perf_counter()
    if process(argv).wait() != 0:
        raise ClsonarError(f"clsonar {' '.join(argv)} failed")
    return time.perf_counter() - start


def _kill_while_running(argv: Sequence[str], rng: random.Random, seconds: float,
                        prepare: Callable[[], object], tries: int = 4) -> bool:
    """``prepare()``, then kill -9 ``clsonar ARGV`` at a random moment of the ``seconds``
    it takes; again (at most ``tries`` times, each within half the time before: ``seconds``
    was one run's, which a loaded machine or a cold cache lengthens) when it ended before
    the kill. Whether a kill landed."""
    for k in range(tries):
        prepare()
        if _kill_at(argv, rng.uniform(0.02, 0.95) * seconds / 2**k):
            return True
    return False


def _after_run_kill(outcome: Outcome, what: str, out: Path, existing: bool) -> None:
    """Count a kill of a run writing ``out``: it must hold one run's whole outputs (or none,
    if it was new), and every temporary file must be the killed writer's, which the next
    write removes (:func:`~clsonar.files.remove_stale`)."""
    found = outputs_of(out)
    remove_stale(out.parent, out.name)
    left = temporary(out.parent)
    outcome.add(f"{what}: outputs {found!r}, temporary {left}", line=None,
                lost=found not in (SCENES if existing else (*SCENES, "")),
                temporary=bool(left))


def _after_sweep_kill(outcome: Outcome, what: str, argv: list[str], out: Path,
                      reference: list[dict[str, Any]]) -> None:
    """Run a killed sweep again (``clsonar ARGV``) and count it: its table must be exactly
    the ``reference`` rows, with no temporary file left."""
    status, err = call(argv)
    outcome.add(f"{what}: status {status} {err.strip()}", line=None,
                lost=status != 0 or not table_matches(out, reference),
                temporary=bool(temporary(out)))


def kill_run(work: Path, rng: random.Random, count: int) -> Outcome:
    """kill -9 at random moments of ``clsonar run``: into a new folder (even kills) and
    over another scene's whole outputs (odd ones)."""
    outcome = Outcome("kill -9 at a random moment of `clsonar run`")
    scene, other = (small_scene(n, work) for n in SCENES)
    out = work / "out"
    seconds = _seconds(run_argv(other, out))
    for k in range(count):
        existing = k % 2 == 1
        prepare = partial(call, run_argv(other, out)) if existing else partial(rmtree, out)
        if not _kill_while_running(run_argv(scene, out), rng, seconds, prepare):
            outcome.problems.append(f"kill {k}: the run always ended before its kill")
            continue
        _after_run_kill(outcome, f"kill {k}", out, existing)
    return outcome


def kill_sweep(work: Path, rng: random.Random, count: int) -> Outcome:
    """kill -9 at random moments of ``clsonar sweep``, then the sweep run again to its end:
    its table must be exactly an uninterrupted sweep's."""
    outcome = Outcome("kill -9 at a random moment of `clsonar sweep`, then run again")
    spec = write_spec(work)
    seconds = _seconds(["sweep", str(spec), "--out", str(work / "reference"), "-q"])
    reference = sweep_rows(work / "reference")
    for k in range(count):
        out = work / f"sweep-{k}"
        argv = ["sweep", str(spec), "--out", str(out), "-q"]
        if not _kill_while_running(argv, rng, seconds, partial(rmtree, out)):
            outcome.problems.append(f"sweep kill {k}: the sweep always ended before its kill")
            continue
        _after_sweep_kill(outcome, f"sweep kill {k}", argv, out, reference)
    return outcome


def _check_killed(outcome: Outcome, status: int, what: str) -> None:
    """A process meant to kill itself mid-write that was not killed is a problem."""
    if status != -signal.SIGKILL:
        outcome.problems.append(f"{what}: ended with status {status}, not killed")


def kill_run_writes(work: Path, rng: random.Random, count: int) -> Outcome:
    """kill -9 halfway through each write of ``clsonar run``'s outputs, into a new folder
    and over another scene's outputs."""
    outcome = Outcome("kill -9 halfway through each write of `clsonar run`")
    scene, other = (small_scene(n, work) for n in SCENES)
    out = work / "out"
    argv = run_argv(scene, out)
    total = writes(work, lambda: call(argv))
    for existing in (False, True):
        for fail_at in range(1, total + 1):
            rmtree(out)
            if existing:
                call(run_argv(other, out))
            status = killed_writer(work, fail_at, argv).wait()
            _check_killed(outcome, status, f"write {fail_at}")
            _after_run_kill(outcome, f"write {fail_at}, existing {existing}, status {status}",
                            out, existing)
    return outcome


def _sweep_writes(work: Path) -> tuple[Path, int, list[dict[str, Any]]]:
    """A sweep spec in ``work``, how many writes its uninterrupted sweep makes, and that
    sweep's rows: what a fault at each write is checked against."""
    spec = write_spec(work)
    reference_out = work / "reference"
    total = writes(work, lambda: call(["sweep", str(spec), "--out", str(reference_out), "-q"]))
    return spec, total, sweep_rows(reference_out)


def kill_sweep_writes(work: Path, rng: random.Random, count: int) -> Outcome:
    """kill -9 halfway through each write of ``clsonar sweep`` (its plan, each row, its
    table), then the sweep run again to its end."""
    outcome = Outcome("kill -9 halfway through each write of `clsonar sweep`, then run again")
    spec, total, reference = _sweep_writes(work)
    for fail_at in range(1, total + 1):
        out = work / f"sweep-{fail_at}"
        argv = ["sweep", str(spec), "--out", str(out), "-q"]
        status = killed_writer(out, fail_at, argv).wait()
        _check_killed(outcome, status, f"write {fail_at}")
        _after_sweep_kill(outcome, f"write {fail_at}, status {status}", argv, out, reference)
    return outcome


def concurrent_out(work: Path, rng: random.Random, count: int) -> Outcome:
    """Two ``clsonar run`` of different scenes writing the same ``--out`` at once, into a
    new folder (even rounds) and over earlier outputs (odd ones): both succeed and the
    folder holds one run's whole outputs."""
    outcome = Outcome("two `clsonar run` writing one `--out` at once")
    scenes = [small_scene(n, work) for n in SCENES]
    out = work / "out"
    for k in range(count):
        if k % 2 == 0:
            rmtree(out)
        procs = [process(run_argv(s, out)) for s in rng.sample(scenes, 2)]
        status = [p.wait() for p in procs]
        found = outputs_of(out)
        outcome.add(f"round {k}: status {status}, outputs {found!r}", line=status == [0, 0],
                    lost=found not in SCENES, temporary=bool(temporary(work)))
    return outcome


# --------------------------------------------------------------------------- full disk


def disk_full_run(work: Path, rng: random.Random, count: int) -> Outcome:
    """``ENOSPC`` at every write of ``clsonar run``'s outputs, into a new folder and over
    earlier outputs: one line naming the folder, exit 2, the folder as it was."""
    outcome = Outcome("full disk: `clsonar run` outputs")
    scene, other = (small_scene(n, work) for n in SCENES)
    out = work / "out"
    total = writes(work, lambda: call(run_argv(scene, out)))
    for existing in (False, True):
        for fail_at in range(1, total + 1):
            rmtree(out)
            if existing:
                call(run_argv(other, out))
            with disk_full(work, fail_at):
                status, err = call(run_argv(scene, out))
            found = outputs_of(out)
            outcome.add(f"write {fail_at}, existing {existing}: {err.strip()!r} {found!r}",
                        line=one_line(err, status, 2, str(out), NO_SPACE),
                        lost=found != (SCENES[1] if existing else ""),
                        temporary=bool(temporary(work)))
    return outcome


def disk_full_sweep(work: Path, rng: random.Random, count: int) -> Outcome:
    """``ENOSPC`` at every write of ``clsonar sweep`` (its plan, each row, its table), then
    the sweep run again with space: one line, exit 2, then exactly the uninterrupted
    table."""
    outcome = Outcome("full disk: `clsonar sweep` table, then run again")
    spec, total, reference = _sweep_writes(work)
    for fail_at in range(1, total + 1):
        out = work / f"sweep-{fail_at}"
        argv = ["sweep", str(spec), "--out", str(out), "-q"]
        with disk_full(out, fail_at):
            status, err = call(argv)
        again, _ = call(argv)
        outcome.add(f"write {fail_at}: {err.strip()!r}, then status {again}",
                    line=one_line(err, status, 2, NO_SPACE),
                    lost=again != 0 or not table_matches(out, reference),
                    temporary=bool(temporary(out)))
    return outcome


def disk_full_files(work: Path, rng: random.Random, count: int) -> Outcome:
    """``ENOSPC`` while a scene file is saved over an older one (``save_scene``, the GUI's
    writer) and while ``clsonar echoes -o FILE`` writes: one line, the old file kept."""
    from ...scene import load_scene, save_scene

    outcome = Outcome("full disk: scene file (`save_scene`), `clsonar echoes -o`")
    scene = small_scene(SCENES[0], work)
    target = work / "saved.json"
    target.write_text("old\n")
    with disk_full(work, 1):
        try:
            save_scene(load_scene(scene), target)
            message = ""
        except ClsonarError as e:
            message = str(e)
    outcome.add(f"save_scene: {message!r}", lost=target.read_text() != "old\n",
                line=one_line(f"clsonar: {message}", 2, 2, str(target), NO_SPACE),
                temporary=bool(temporary(work)))
    csv = work / "echoes.csv"
    csv.write_text("old\n")
    with disk_full(work, 1):
        status, err = call(["echoes", str(scene), "-o", str(csv)])
    outcome.add(f"echoes -o: {err.strip()!r}", lost=csv.read_text() != "old\n",
                line=one_line(err, status, 2, str(csv), NO_SPACE),
                temporary=bool(temporary(work)))
    return outcome


# --------------------------------------------------------------------------- device, pipeline


def kernel_build(work: Path, rng: random.Random, count: int) -> Outcome:
    """Each kernel the run builds (the device's test kernel first) fails to build in
    turn: one line naming the device and the fix, exit 2, nothing written."""
    outcome = Outcome("kernel fails to build (each build of a run, both presets)")
    scene = small_scene(SCENES[0], work)
    out = work / "out"
    from ...opencl import INSTALL_HINT, choose_device

    device = choose_device().name.strip()
    for preset in PRESETS:  # ours: echoes and signals; the thesis': the map's kernel too
        argv = run_argv(scene, out, "--preset", preset)
        counted = [0]
        with failing_build(None, counted):
            call(argv)
        for fail_at in range(1, counted[0] + 1):
            rmtree(out)
            with failing_build(fail_at, [0]):
                status, err = call(argv)
            outcome.add(f"{preset} build {fail_at}: {err.strip()!r}", lost=out.exists(),
                        line=one_line(err, status, 2, device, INSTALL_HINT))
    return outcome


def _stage_faults(work: Path, outcome: Outcome, error: Callable[[], Exception],
                  *words: str) -> Outcome:
    """``error()`` raised at each stage of ``clsonar run``: one line holding ``words`` and
    naming a traceback file that holds the error, exit 1, nothing written."""
    scene = small_scene(SCENES[0], work)
    out = work / "out"
    with mock.patch.object(tempfile, "tempdir", str(work)):
        for index in range(1, len(STAGES) + 1):
            rmtree(out)
            with failing_stage(index, error):
                status, err = call(run_argv(scene, out))
            saved = re.search(r"traceback in (\S+?)[;)]", err)
            kept = saved is not None and INJECTED in Path(saved[1]).read_text()
            outcome.add(f"stage {index}: {err.strip()!r}", lost=out.exists(),
                        line=one_line(err, status, 1, *words) and kept)
    return outcome


def pipeline_exception(work: Path, rng: random.Random, count: int) -> Outcome:
    """An unexpected exception at each stage of the pipeline."""
    return _stage_faults(work, Outcome("unexpected exception in each pipeline stage"),
                         lambda: ZeroDivisionError(INJECTED),
                         f"internal error: ZeroDivisionError: {INJECTED}", "traceback in ")


def opencl_failure(work: Path, rng: random.Random, count: int) -> Outcome:
    """An OpenCL error (a kernel that fails to run) at each stage of the pipeline."""
    import pyopencl as cl

    return _stage_faults(work, Outcome("OpenCL error in each pipeline stage"),
                         lambda: cl.RuntimeError(f"clEnqueueNDRangeKernel: {INJECTED}"),
                         "OpenCL failed on ", DEVICE_FIX, "traceback in ")


# --------------------------------------------------------------------------- Dask


def unreachable_scheduler(work: Path, rng: random.Random, count: int) -> Outcome:
    """``clsonar sweep --scheduler`` at an address where no scheduler listens: one line,
    exit 2, nothing written."""
    from ..sweep import runners

    outcome = Outcome("Dask scheduler out of reach")
    spec = write_spec(work)
    for k, address in enumerate(("tcp://127.0.0.1:1", "tcp://localhost:9")):
        out = work / f"out-{k}"
        with mock.patch.object(runners, "CONNECT_TIMEOUT_S", 1.0):
            status, err = call(["sweep", str(spec), "--out", str(out), "--scheduler",
                                address])
        outcome.add(f"{address}: {err.strip()!r}", lost=out.exists(),
                    line=one_line(err, status, 2, address, "cannot reach the Dask scheduler"))
    return outcome


def die_once(marker: str, victim: str, run: sw.Run, metrics: Sequence[str],
             device: str | None) -> dict[str, Any]:
    """The sweep's task, except that the worker given run ``victim`` first dies (once:
    ``marker`` is created then)."""
    if run.run_id == victim:
        with contextlib.suppress(FileExistsError):
            os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
            os._exit(1)
    return sw.run_one(run, metrics, device)


def dask_worker(work: Path, rng: random.Random, count: int) -> Outcome:
    """A Dask worker killed while it runs a random run of the sweep (a two-process
    ``LocalCluster``): the table must be exactly the local sweep's. Each round sweeps new
    seeds (the cluster would otherwise hand back the rows it still holds)."""
    from distributed import Client, LocalCluster

    outcome = Outcome("Dask worker killed mid-sweep")
    with LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                      dashboard_address=None, silence_logs=50) as cluster, \
            Client(cluster) as client:
        for k in range(count):
            spec = sw.load_spec(write_spec(work, first_seed=10 * k))
            runs = sw.plan(spec)
            sw.sweep(spec, work / f"reference-{k}")
            out, marker = work / f"dask-{k}", work / f"died-{k}"
            out.mkdir()
            task = partial(die_once, str(marker), rng.choice(runs).run_id)
            sw.run_dask(runs, sw.RunTable(out), spec.metrics, client, task=task)
            outcome.add(f"dask {k}: died {marker.exists()}", line=None,
                        lost=not marker.exists()
                        or sweep_rows(out) != sweep_rows(work / f"reference-{k}"))
    return outcome


