"""The checks every fault's injections end with, and the injectors themselves (a full
disk, a failing stage, a failing kernel build)."""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import zipfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np

from ...cli import main
from ...files import bundled_scenes
from ...outputs import DATA_NAMES
from .. import sweep as sw
from ..progress import ProgressLine

#: Two small scenes whose outputs tell apart (:func:`outputs_of`): the thesis' planes at 5 cm.
SCENES = ("plane-2m", "plane-4m")
CELL = 0.05
#: A sweep of 4 runs (2 cells × :data:`SWEEP_SEEDS` seeds) of a few tenths of a second each.
SWEEP_SPEC = {"name": "faults", "scenes": [{"scene": "plane-2m", "distance_m": 2.0}],
              "metrics": ["rms_m", "accuracy_m.rms", "counts.detections"],
              "grid": {"cell": [0.05, 0.1]}}
SWEEP_SEEDS = 2
#: Columns of a sweep's table that differ from run to run.
VOLATILE = ("host",)
INJECTED = "injected fault"
NO_SPACE = os.strerror(errno.ENOSPC)


@dataclass
class Outcome:
    """What the injections of one fault did."""

    fault: str
    injections: int = 0
    lost: int = 0  # runs that lost or repeated a result, or left outputs not whole
    not_one_line: int | None = 0  # None: the fault leaves nothing to print (kill -9)
    temporary: int = 0  # injections after which a temporary file would stay
    problems: list[str] = field(default_factory=list)

    def add(self, what: str, *, lost: bool = False, line: bool | None = True,
            temporary: bool = False) -> None:
        """Count one injection: whether it lost a result, ended in one line (None: not
        applicable), left a temporary file; ``what`` describes it for :attr:`problems`."""
        self.injections += 1
        self.lost += lost
        self.temporary += temporary
        if line is None:
            self.not_one_line = None
        elif self.not_one_line is not None:
            self.not_one_line += not line
        if lost or line is False or temporary:
            self.problems.append(what)


# --------------------------------------------------------------------------- checks


def small_scene(name: str, folder: Path) -> Path:
    """The bundled scene ``name`` at :data:`CELL` cells, written into ``folder``."""
    data = json.loads((bundled_scenes() / f"{name}.json").read_text())
    path = folder / f"{name}.json"
    path.write_text(json.dumps({**data, "cell": CELL}))
    return path


def outputs_of(out: Path) -> str | None:
    """The scene whose whole outputs (``--png none``) ``out`` holds; ``""`` when it is
    absent; None when its files are partial or of different runs (their counts disagree
    with report.json's)."""
    if not out.exists():
        return ""
    if sorted(os.listdir(out)) != sorted(DATA_NAMES):
        return None
    try:
        report = json.loads((out / "report.json").read_text())
        with np.load(out / "stages.npz") as z:
            thin = int(np.count_nonzero(z["thin"]))
        found = (len((out / "echoes.csv").read_text().splitlines()) - 1,
                 len((out / "profile.csv").read_text().splitlines()) - 1, thin)
        counts = report["counts"]
        wanted = (counts["echoes"], counts["profile_points"], counts["thin_cells"])
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return None
    return report["scene"] if found == wanted else None


def temporary(folder: Path) -> list[str]:
    """The temporary files and folders (``.NAME.clsonar-…``) in ``folder``."""
    return sorted(e for e in os.listdir(folder) if e.startswith(".") and ".clsonar-" in e)


def one_line(err: str, status: int, expected: int, *words: str) -> bool:
    """Whether a command ended with exit status ``expected`` and exactly one ``clsonar:``
    line on stderr holding every one of ``words``."""
    lines = err.splitlines()
    return (status == expected and len(lines) == 1 and lines[0].startswith("clsonar: ")
            and all(w in lines[0] for w in words))


def call(argv: Sequence[str]) -> tuple[int, str]:
    """``clsonar ARGV`` in this process: (exit status, stderr)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = main(list(argv))
    return status, err.getvalue()


def run_argv(scene: Path, out: Path, *more: str) -> list[str]:
    """``clsonar run SCENE --out OUT -q --png none MORE``."""
    return ["run", str(scene), "--out", str(out), "-q", "--png", "none", *more]


def process(argv: Sequence[str]) -> subprocess.Popen:
    """``clsonar ARGV`` in a new process, its output discarded."""
    return subprocess.Popen([sys.executable, "-m", "clsonar", *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def sweep_rows(out: Path) -> list[dict[str, Any]]:
    """A sweep's finished rows in plan order, without the run-to-run columns; every row
    once (a repeated run id shows as a repeated row)."""
    lines = (out / sw.TABLE_JSONL).read_text().splitlines()
    rows = [json.loads(x) for x in lines if x.strip()]
    return sorted(({k: v for k, v in r.items() if not k.startswith("seconds.")
                    and k not in VOLATILE} for r in rows), key=lambda r: r["index"])


def table_matches(out: Path, reference: list[dict[str, Any]]) -> bool:
    """Whether ``out``'s sweep ended with exactly the ``reference`` rows, and its
    table.csv lists each once."""
    text = (out / sw.TABLE_CSV).read_text().splitlines()
    return sweep_rows(out) == reference and len(text) == len(reference) + 1


def write_spec(folder: Path, first_seed: int = 0) -> Path:
    """:data:`SWEEP_SPEC` (its seeds from ``first_seed`` on) as a file in ``folder``."""
    path = folder / f"spec-{first_seed}.json"
    seeds = list(range(first_seed, first_seed + SWEEP_SEEDS))
    path.write_text(json.dumps({**SWEEP_SPEC, "seeds": seeds}))
    return path


# --------------------------------------------------------------------------- injectors


class DiskFull:
    """``os.write`` for files under ``root`` that counts its calls and, from call
    ``fail_at`` on, refuses with ``ENOSPC`` (the first refusal after writing half the
    bytes, as a disk that fills mid-write)."""

    def __init__(self, root: Path, fail_at: int | None = None) -> None:
        self.root = os.path.join(root, "")
        self.fail_at = fail_at
        self.calls = 0
        self.write = os.write

    def __call__(self, fd: int, data: Any) -> int:
        if not self._ours(fd):
            return self.write(fd, data)
        self.calls += 1
        if self.fail_at is None or self.calls < self.fail_at:
            return self.write(fd, data)
        if self.calls == self.fail_at:
            self.write(fd, bytes(data)[:len(data) // 2])
            self.fail()
        raise OSError(errno.ENOSPC, NO_SPACE)

    def fail(self) -> None:
        """What the first failing write does after its half (a full disk: nothing more)."""

    def _ours(self, fd: int) -> bool:
        try:
            return os.readlink(f"/proc/self/fd/{fd}").startswith(self.root)
        except OSError:
            return False


class KilledWriter(DiskFull):
    """``os.write`` for files under ``root`` whose ``fail_at``-th call writes half its
    bytes and kills this process (kill -9)."""

    def fail(self) -> None:
        os.kill(os.getpid(), signal.SIGKILL)


def killed_writer(root: Path, fail_at: int, argv: Sequence[str]) -> subprocess.Popen:
    """``clsonar ARGV`` in a new process that kills itself halfway through its
    ``fail_at``-th write under ``root`` (:class:`KilledWriter`)."""
    code = ("import os, sys\nfrom pathlib import Path\nfrom unittest import mock\n"
            "from clsonar.cli import main\n"
            "from clsonar.tools.faults.harness import KilledWriter\n"
            "with mock.patch.object(os, 'write', KilledWriter(Path(sys.argv[1]), "
            "int(sys.argv[2]))):\n    main(sys.argv[3:])\n")
    return subprocess.Popen([sys.executable, "-c", code, str(root), str(fail_at), *argv],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def writes(root: Path, action: Callable[[], object]) -> int:
    """How many ``os.write`` calls ``action`` makes on files under ``root``."""
    counter = DiskFull(root)
    with mock.patch.object(os, "write", counter):
        action()
    return counter.calls


def disk_full(root: Path, fail_at: int) -> contextlib.AbstractContextManager[Any]:
    """A full disk under ``root`` from the ``fail_at``-th write on (:class:`DiskFull`)."""
    return mock.patch.object(os, "write", DiskFull(root, fail_at))


@contextlib.contextmanager
def failing_stage(index: int, error: Callable[[], Exception]) -> Iterator[None]:
    """The pipeline raises ``error()`` as it starts its ``index``-th stage (through the
    command line's progress callback)."""
    def stage(self: ProgressLine, name: str, i: int, n: int) -> None:
        if i == index:
            raise error()

    with mock.patch.object(ProgressLine, "stage", stage):
        yield


@contextlib.contextmanager
def failing_build(fail_at: int | None, counted: list[int]) -> Iterator[None]:
    """Every kernel built afresh from source (not loaded from the program cache); the
    ``fail_at``-th build fails as a compiler would (``None``: none fails); ``counted[0]``
    counts the builds."""
    import pyopencl as cl

    from ... import opencl

    build = cl.Program.build

    def failing(self: Any, *args: Any, **kwargs: Any) -> Any:
        counted[0] += 1
        if counted[0] == fail_at:
            raise cl.RuntimeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE\n"
                                  f"error: {INJECTED}\n")
        return build(self, *args, **kwargs)

    with mock.patch.object(opencl, "_PROGRAMS", {}), \
            mock.patch.dict(os.environ, {"PYOPENCL_NO_CACHE": "1"}), \
            mock.patch.object(cl.Program, "build", failing):
        yield


def rmtree(path: Path) -> None:
    """Remove folder ``path`` and what it holds, if it is there."""
    shutil.rmtree(path, ignore_errors=True)
