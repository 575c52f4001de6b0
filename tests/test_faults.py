"""Issue 19's fault-injection suite (clsonar/tools/faults/, docs/faults.md): kill -9 at
random moments of ``clsonar run`` and ``clsonar sweep`` and halfway through each of their
writes, two runs writing one ``--out`` at once, a full disk at every write of every writer,
a kernel that fails to build, an exception and an OpenCL error in every stage, a Dask
scheduler out of reach, a Dask worker killed mid-sweep: nothing lost or repeated, every
failure one line, no temporary file left. And the pieces they rest on: whole-folder
writes, whole appends, one-line errors."""

import errno
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from clsonar import files
from clsonar.cli import DEVICE_FIX, error_line, fault_line, main
from clsonar.errors import ClsonarError, DeviceError, WriteError
from clsonar.pipeline import STAGES
from clsonar.tools import faults

ROOT = Path(__file__).resolve().parents[1]

# --------------------------------------------------------------------------- the pieces


def test_a_write_error_is_one_line_and_an_os_error():
    e = WriteError("/data/out", OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    assert str(e) == "/data/out: cannot write: No space left on device"
    assert isinstance(e, OSError) and isinstance(e, ClsonarError)
    assert (e.errno, e.filename) == (errno.ENOSPC, "/data/out")


def test_a_device_error_without_a_fix_gets_one():
    built = DeviceError("kernels/echoes.cl failed to build on cpu: error: x")
    assert error_line(built) == ("clsonar: error: kernels/echoes.cl failed to build on cpu: "
                                 f"error: x; {DEVICE_FIX}")
    told = DeviceError("--device 'x' matches no OpenCL device (see 'clsonar devices')")
    assert error_line(told) == f"clsonar: error: {told}"
    assert "--device" in DEVICE_FIX and "pocl-opencl-icd" in DEVICE_FIX


def test_an_os_error_naming_a_file_is_the_users_and_anything_else_a_fault(tmp_path,
                                                                          monkeypatch):
    assert fault_line(PermissionError(errno.EACCES, "Permission denied", "/x/y")) == (
        "clsonar: error: /x/y: Permission denied", 2)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    try:
        raise RuntimeError("boom\nmore")
    except RuntimeError as e:
        line, status = fault_line(e)
    saved = next(tmp_path.glob("clsonar-traceback-*.txt"))
    assert status == 1
    assert line == (f"clsonar: internal error: RuntimeError: boom more (traceback in {saved}; "
                    "please report it)")
    assert "RuntimeError: boom\nmore" in saved.read_text()


def test_write_folder_replaces_a_runs_outputs_whole_and_keeps_other_files(tmp_path):
    owned = {"a.txt", "b.txt", "c.txt"}
    out = tmp_path / "out"
    files.write_folder(out, {"a.txt": b"1", "b.txt": b"1", "c.txt": b"1"}, owned)
    files.write_folder(out, {"a.txt": b"2", "b.txt": b"2"}, owned)  # swapped in whole
    assert {p.name: p.read_bytes() for p in out.iterdir()} == {"a.txt": b"2", "b.txt": b"2"}
    assert oct(out.stat().st_mode & 0o777) == oct(files.FOLDER_MODE)
    (out / "mine.txt").write_bytes(b"keep")  # a folder with other files: ours replaced
    files.write_folder(out, {"a.txt": b"3"}, owned)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == {"a.txt": b"3",
                                                               "mine.txt": b"keep"}
    assert faults.temporary(tmp_path) == []


def test_write_folder_never_swaps_the_working_folder(tmp_path, monkeypatch):
    out = tmp_path / "out"
    files.write_folder(out, {"a.txt": b"1"}, {"a.txt"})
    inode = out.stat().st_ino
    monkeypatch.chdir(out)
    files.write_folder(Path("."), {"a.txt": b"2"}, {"a.txt"})
    assert out.stat().st_ino == inode and (out / "a.txt").read_bytes() == b"2"
    assert faults.temporary(out) == []


def test_a_killed_writers_temporary_files_go_with_the_next_write(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (tmp_path / f".out.clsonar-{dead}-x1").mkdir()
    (tmp_path / f".t.csv.clsonar-{dead}-x2").write_text("half")
    (tmp_path / f".out.clsonar-{os.getpid()}-x3").mkdir()  # a live writer's: kept
    files.write_folder(tmp_path / "out", {"a": b"1"})
    files.write_atomic(tmp_path / "t.csv", b"x\n")
    assert faults.temporary(tmp_path) == [f".out.clsonar-{os.getpid()}-x3"]


def test_an_append_cut_short_by_a_full_disk_leaves_the_file_as_it_was(tmp_path):
    path = tmp_path / "runs.jsonl"
    files.append_whole(path, b'{"run": 1}\n')
    with faults.disk_full(tmp_path, 1), pytest.raises(WriteError, match="No space left"):
        files.append_whole(path, b'{"run": 2, "a long row": "' + b"x" * 1000 + b'"}\n')
    assert path.read_bytes() == b'{"run": 1}\n'


def test_an_out_that_cannot_be_written_is_refused_before_any_work(tmp_path, capsys,
                                                                  monkeypatch):
    """Tests run as root, for whom every folder is writable: the permission is injected."""
    monkeypatch.setattr("clsonar.outputs.os.access", lambda path, mode: False)
    out = tmp_path / "locked" / "out"
    assert main(faults.run_argv(ROOT / "scenes" / "plane-2m.json", out)) == 2
    assert capsys.readouterr().err == (f"clsonar: error: {out}: cannot write in {tmp_path} "
                                       "(permission denied)\n")
    assert list(tmp_path.iterdir()) == []


def test_a_worker_that_keeps_dying_is_one_line_saying_the_rows_are_kept():
    distributed = pytest.importorskip("distributed")
    from clsonar.tools.sweep import runners

    class Dead:
        def result(self):
            raise distributed.KilledWorker("clsonar-x", SimpleNamespace(address="tcp://w:1"), 3)

    run = SimpleNamespace(index=3, label="plane-2m", seed=1)
    with pytest.raises(ClsonarError) as e:
        runners._result(Dead(), run, 2)
    text = str(e.value)
    assert text.startswith("the Dask cluster lost run 3 (plane-2m, seed 1): KilledWorker: ")
    assert text.endswith("the 2 rows finished are kept: run the sweep again to resume")
    assert "\n" not in text


# --------------------------------------------------------------------------- the faults

#: Per fault: (random kills or rounds asked, the injections made). The others inject at
#: every write (a run's 4 files, into a new and an existing folder; a sweep's plan, 4 rows
#: and table), build or stage.
CASES = {
    "kill-run": (4, 4), "kill-sweep": (2, 2), "kill-run-writes": (1, 8),
    "kill-sweep-writes": (1, 6), "concurrent-out": (2, 2),
    "disk-full-run": (1, 8), "disk-full-sweep": (1, 6), "disk-full-files": (1, 2),
    "kernel-build": (1, None), "pipeline-exception": (1, len(STAGES)),
    "opencl-failure": (1, len(STAGES)), "unreachable-scheduler": (1, 2),
    "dask-worker": (1, 1),
}


def test_every_fault_is_in_the_suite():
    assert set(CASES) == set(faults.FAULTS)


@pytest.mark.parametrize("name", list(CASES))
def test_fault(name):
    if name in ("dask-worker", "unreachable-scheduler"):  # without dask: another line
        pytest.importorskip("distributed")
    count, injections = CASES[name]
    outcome = faults.inject(name, count, seed=19)
    assert outcome.problems == []
    assert (outcome.lost, outcome.temporary) == (0, 0)
    assert outcome.not_one_line == (None if "kill" in name or name == "dask-worker" else 0)
    if injections is None:  # each kernel of both presets, the device's test kernel maybe
        assert outcome.injections >= 5
    else:
        assert outcome.injections == injections


def test_the_scenes_outputs_tell_apart(tmp_path):
    """outputs_of names a run by its counts: the two scenes' must differ, and a mix of
    their files is no run's."""
    outs = []
    for name in faults.SCENES:
        out = tmp_path / name
        assert main(faults.run_argv(faults.small_scene(name, tmp_path), out)) == 0
        assert faults.outputs_of(out) == name
        outs.append(out)
    (outs[0] / "echoes.csv").write_bytes((outs[1] / "echoes.csv").read_bytes())
    assert faults.outputs_of(outs[0]) is None
    assert faults.outputs_of(tmp_path / "absent") == ""


def test_the_table():
    rows = [faults.Outcome("kill", 3, 0, None), faults.Outcome("disk", 8, 0, 0)]
    assert faults.markdown(rows, "python -m clsonar.tools.faults").splitlines()[:4] == [
        "| Fault | Injected | Lost or repeated a result | Not one line | "
        "Temporary files left |", "|---|---:|---:|---:|---:|",
        "| kill | 3 | 0 | – | 0 |", "| disk | 8 | 0 | 0 | 0 |"]
