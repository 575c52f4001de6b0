"""Running a sweep: every planned run not yet in the table, locally on one OpenCL context
(:func:`run_local`) or on a Dask cluster (:func:`run_dask`), rows appended as runs finish;
and its progress bar."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TextIO

from ...errors import ClsonarError, one_line
from ...files import write_atomic, writing
from ...opencl import get_context
from ...pipeline import StageCache
from ...pipeline import run as run_pipeline
from ..progress import ProgressLine
from .plan import Run, plan
from .spec import Spec
from .table import SWEEP_JSON, TABLE_CSV, RunTable, SweepLock, columns, row_of, table_csv

#: ``(runs finished, runs planned, the last run)``: how a sweep reports progress.
RunProgress = Callable[[int, int, Run], None]


#: The OpenCL context this process built for each device (:func:`worker_context`).
CONTEXTS: dict[str | None, Any] = {}


def worker_context(device: str | None = None):
    """The OpenCL context of this process for ``device``, built on first use and reused by
    every later run (one per Dask worker process)."""
    if device not in CONTEXTS:
        CONTEXTS[device] = get_context(device)
    return CONTEXTS[device]


#: The front stages this process computed, reused by the runs whose inputs to them are
#: unchanged (a wall-following ring's poses and echoes across noise seeds).
CACHE = StageCache()


def run_one(run: Run, metrics: Sequence[str], device: str | None = None,
            context=None) -> dict[str, Any]:
    """Run the pipeline on ``run`` and return its row (the task a Dask worker executes);
    the front stages come from this process' :data:`CACHE` where they can."""
    ctx = context if context is not None else worker_context(device)
    result = run_pipeline(run.scene, context=ctx, preset=run.preset, cache=CACHE)
    return row_of(run, result, metrics)


def _header(spec: Spec, runs: list[Run]) -> dict[str, Any]:
    """``sweep.json``: the spec's name, parameters, metrics, seeds, scenes and run ids."""
    return {"name": spec.name, "spec": spec.source, "parameters": list(spec.parameters),
            "metrics": list(spec.metrics), "seeds": list(spec.seeds),
            "scenes": [e.label for e in spec.scenes], "runs": [r.run_id for r in runs]}


def sweep(spec: Spec, out: str | os.PathLike[str], *, device: str | None = None,
          client=None, progress: RunProgress | None = None) -> list[dict[str, Any]]:
    """Run every run of ``spec`` not already in ``out``'s table and return all the rows,
    in plan order.

    Locally (``client`` None) on ``device``; else on the Dask cluster of ``client`` (a
    ``dask.distributed.Client``), each worker on its own ``device``. Writes
    ``out/sweep.json`` (the plan), ``out/runs.jsonl`` (rows as they finish) and
    ``out/table.csv`` (when it stops, finished or interrupted).
    """
    runs = plan(spec)
    out = Path(out)
    with writing(out):
        out.mkdir(parents=True, exist_ok=True)
    with SweepLock(out):
        table = RunTable(out)
        table.repair()
        write_atomic(out / SWEEP_JSON, (json.dumps(_header(spec, runs), indent=1)
                                        + "\n").encode())
        try:
            if client is None:
                run_local(runs, table, spec.metrics, device=device, progress=progress)
            else:
                run_dask(runs, table, spec.metrics, client, device=device, progress=progress)
        finally:
            done = table.rows()
            rows = [done[r.run_id] for r in runs if r.run_id in done]
            write_atomic(out / TABLE_CSV, table_csv(rows, columns(spec.parameters,
                                                                  spec.metrics)).encode())
    return rows


def _todo(runs: list[Run], table: RunTable) -> tuple[list[Run], int]:
    """The runs not yet in ``table``, and how many are."""
    done = table.rows()
    return [r for r in runs if r.run_id not in done], sum(r.run_id in done for r in runs)


def run_local(runs: list[Run], table: RunTable, metrics: Sequence[str], *,
              device: str | None = None, context=None,
              progress: RunProgress | None = None) -> list[dict[str, Any]]:
    """Run, in this process and in order, every run not yet in ``table``; append each row
    as it finishes. Returns the new rows."""
    todo, finished = _todo(runs, table)
    ctx = context if context is not None else (worker_context(device) if todo else None)
    new = []
    for run in todo:
        row = run_one(run, metrics, context=ctx)
        table.append(row)
        new.append(row)
        finished += 1
        if progress is not None:
            progress(finished, len(runs), run)
    return new


def run_dask(runs: list[Run], table: RunTable, metrics: Sequence[str], client, *,
             device: str | None = None, progress: RunProgress | None = None,
             retries: int = 2, task: Callable[..., dict[str, Any]] | None = None
             ) -> list[dict[str, Any]]:
    """Send every run not yet in ``table`` to the Dask cluster of ``client`` and append
    each row as it comes back, in the order they finish. Returns the new rows.

    A run whose worker dies is rescheduled by Dask on another worker; a run that raises
    is retried ``retries`` times. ``task`` replaces :func:`run_one` (tests).
    """
    from distributed import as_completed

    todo, finished = _todo(runs, table)
    fn = task or run_one
    futures = {client.submit(fn, run, tuple(metrics), device, key=f"clsonar-{run.run_id}",
                             pure=False, retries=retries): run for run in todo}
    new = []
    try:
        for future in as_completed(futures):
            row = _result(future, futures[future], finished)
            table.append(row)
            new.append(row)
            finished += 1
            if progress is not None:
                progress(finished, len(runs), futures[future])
    finally:
        for future in futures:
            if not future.done():
                future.cancel()
    return new


def _result(future, run: Run, finished: int) -> dict[str, Any]:
    """The row ``future`` computed; a worker that died too often (``KilledWorker``) or a
    cluster that went away is one :class:`ClsonarError` line saying that the rows finished
    are kept."""
    from concurrent.futures import CancelledError

    from distributed import KilledWorker

    try:
        return future.result()
    except (KilledWorker, CancelledError, OSError) as e:
        raise ClsonarError(
            f"the Dask cluster lost run {run.index} ({run.label}, seed {run.seed}): "
            f"{type(e).__name__}: {one_line(str(e))}; the {finished} rows finished are kept: "
            "run the sweep again to resume") from None


#: How long :func:`connect` tries to reach a scheduler.
CONNECT_TIMEOUT_S = 10.0


def connect(scheduler: str):
    """A ``dask.distributed.Client`` of the cluster at ``scheduler`` (``tcp://HOST:PORT``)."""
    try:
        from distributed import Client
    except ModuleNotFoundError:
        raise ClsonarError("--scheduler needs dask.distributed: pip install "
                           "'clsonar[dask]'") from None
    try:
        return Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError) as e:
        raise ClsonarError(f"--scheduler {scheduler}: cannot reach the Dask scheduler "
                           f"({type(e).__name__}: {one_line(str(e))}); start it "
                           "(dask scheduler) or check the address") from None


class ProgressBar:
    """``[#####.....] 12/40  30 %  ETA 1m05s  plane-2m signal.noise_std=0.4 seed 2`` on one
    rewritten line of a terminal's stderr (nothing otherwise, :class:`ProgressLine`); the
    ETA comes from the runs finished in this session."""

    def __init__(self, enabled: bool = True, stream: TextIO | None = None) -> None:
        self.line = ProgressLine(enabled, stream)
        self.first: int | None = None

    def __call__(self, finished: int, total: int, run: Run) -> None:
        if self.first is None:
            self.first = finished - 1
        if not self.line.enabled:
            return
        elapsed = time.perf_counter() - self.line.start
        eta = elapsed / (finished - self.first) * (total - finished)
        width = 24
        bar = "#" * round(width * finished / total)
        what = " ".join([run.label, *(f"{k}={_short(v)}" for k, v in run.params.items()),
                         f"seed {run.seed}"])
        self.line.show(f"[{bar:.<{width}}] {finished}/{total} {100 * finished / total:3.0f} % "
                       f"ETA {_duration(eta)}  {what[:60]:<60}")

    def done(self) -> None:
        """End the line if anything was shown on it."""
        self.line.done()


def _short(v: Any) -> str:
    """A parameter value as the progress bar shows it."""
    return f"{v:g}" if isinstance(v, float) else json.dumps(v) if not isinstance(v, str) else v


def _duration(seconds: float) -> str:
    """``42s``, ``3m05s``, ``2h07m``."""
    s = round(seconds)
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else (
        f"{s // 60}m{s % 60:02d}s" if s >= 60 else f"{s}s")


