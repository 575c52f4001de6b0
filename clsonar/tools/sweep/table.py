"""The table of a sweep: one JSON line per finished run in ``DIR/runs.jsonl`` (durable,
resumable, one writer at a time), its rows (:func:`row_of`) and its CSV form."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import socket
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from ...errors import ClsonarError
from ...files import append_whole, writing
from ...outputs import metric
from ...pipeline import STAGES, RunResult
from .plan import Run

#: The files of a sweep folder: the rows as runs finish, the CSV table, the plan.
TABLE_JSONL = "runs.jsonl"
TABLE_CSV = "table.csv"
SWEEP_JSON = "sweep.json"


class RunTable:
    """The rows of a sweep, one JSON line per finished run in ``DIR/runs.jsonl``.

    :meth:`append` writes a whole line with ``O_APPEND`` and ``fsync``s it, or cuts the
    file back when the write fails (:func:`~clsonar.files.append_whole`); :meth:`rows`
    drops a last line cut short by a kill (no newline), so a row is either there whole or
    not at all.
    """

    def __init__(self, folder: str | os.PathLike[str]) -> None:
        self.folder = Path(folder)
        self.path = self.folder / TABLE_JSONL

    def rows(self) -> dict[str, dict[str, Any]]:
        """The finished rows by run id (the first row of an id wins)."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return {}
        complete = data[:data.rfind(b"\n") + 1]
        out: dict[str, dict[str, Any]] = {}
        for number, line in enumerate(complete.splitlines(), 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                raise ClsonarError(f"{self.path}: line {number}: not a JSON row; move the "
                                   "file away to start the sweep afresh") from None
            out.setdefault(row["run"], row)
        return out

    def repair(self) -> None:
        """Cut a last line that was cut short, so appended rows start on a line of their own."""
        try:
            data = self.path.read_bytes()
        except FileNotFoundError:
            return
        end = data.rfind(b"\n") + 1
        if end != len(data):
            with open(self.path, "r+b") as f:
                f.truncate(end)
                os.fsync(f.fileno())

    def append(self, row: dict[str, Any]) -> None:
        """Add one finished run's row, durably and whole: a write cut short (a full disk)
        leaves the table as it was and is one :class:`~clsonar.errors.WriteError` line."""
        append_whole(self.path, (json.dumps(row, allow_nan=False) + "\n").encode())


def columns(parameters: Sequence[str], metrics: Sequence[str]) -> list[str]:
    """The table's columns, in order."""
    return (["run", "index", "scene", *parameters, "seed", *metrics]
            + [f"seconds.{s}" for s in (*STAGES, "total")] + ["device", "host"])


def _cell(value: Any) -> str:
    """A value as a CSV cell: empty for None, JSON for lists and tables."""
    if value is None:
        return ""
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


def table_csv(rows: Iterable[dict[str, Any]], cols: Sequence[str]) -> str:
    """The tidy table as CSV text: one row per run, in plan order."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for row in sorted(rows, key=lambda r: r["index"]):
        w.writerow([_cell(row.get(c)) for c in cols])
    return buf.getvalue()


class SweepLock:
    """An exclusive lock on the folder's table (``flock``): one sweep writes to a folder at
    a time."""

    def __init__(self, folder: Path) -> None:
        self.path = folder / TABLE_JSONL
        self.fd: int | None = None

    def __enter__(self) -> SweepLock:
        import fcntl

        with writing(self.path):
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self.fd)
            raise ClsonarError(f"{self.path.parent}: another sweep is writing there") from None
        return self

    def __exit__(self, *exc: object) -> None:
        if self.fd is not None:
            os.close(self.fd)


def metric_value(result: RunResult, name: str) -> Any:
    """The metric ``name`` (``a.b`` paths into ``result.metrics``, ``counts.x`` into
    ``result.counts``) as a plain JSON value; None where the scene has no such metric."""
    head, _, rest = name.partition(".")
    value = result.counts.get(rest) if head == "counts" else metric(result.metrics, name)
    if value is None or isinstance(value, str):
        return value
    value = float(value) if not isinstance(value, (bool, int)) else value
    return value if not isinstance(value, float) or math.isfinite(value) else None


def row_of(run: Run, result: RunResult, metrics: Sequence[str]) -> dict[str, Any]:
    """The table row of ``run`` from its :class:`~clsonar.pipeline.RunResult`."""
    row: dict[str, Any] = {"run": run.run_id, "index": run.index, "scene": run.label,
                           **run.params, "seed": run.seed}
    row.update({m: metric_value(result, m) for m in metrics})
    row.update({f"seconds.{s}": float(result.seconds.get(s, 0.0)) for s in STAGES})
    row["seconds.total"] = float(sum(result.seconds.values()))
    row["device"] = result.device
    row["host"] = socket.gethostname()
    return row


def read_sweep(folder: str | os.PathLike[str]) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """A sweep folder's plan (``sweep.json``) and its finished rows, in plan order."""
    folder = Path(folder)
    try:
        header = json.loads((folder / SWEEP_JSON).read_text())
    except FileNotFoundError:
        raise ClsonarError(f"{folder}: no {SWEEP_JSON} here: not a sweep folder (run "
                           "'clsonar sweep SPEC --out DIR' first)") from None
    except (OSError, ValueError) as e:
        raise ClsonarError(f"{folder / SWEEP_JSON}: cannot read: {e}") from None
    done = RunTable(folder).rows()
    return header, [done[i] for i in header["runs"] if i in done]

