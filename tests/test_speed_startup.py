"""What a ``clsonar`` process sets up before and around the pipeline (issue 16, docs/speed.md
"2026-11-27, start-up"): ``import clsonar`` without NumPy, the command's one BLAS thread,
the garbage collector left out of what the command imported, the text outputs written
from Python numbers — each checked in a fresh process or against the element-by-element
form it replaced, the same text."""

import io
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import clsonar
from clsonar.echoes.table import KINDS, EchoTable
from clsonar.numerics import fitpack_release
from clsonar.outputs import profile_csv

ROOT = Path(__file__).resolve().parents[1]
ROOM = str(ROOT / "scenes" / "room.json")


def _fresh(code: str, **env: str) -> dict:
    """What ``code`` prints as JSON on its last line, run by a new interpreter with ``env``
    added to (or, where a value is empty, removed from) this one's environment."""
    environ = {k: v for k, v in os.environ.items() if k not in env}
    environ.update({k: v for k, v in env.items() if v})
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300, env=environ, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


_MODULES = ("import json, sys; print(json.dumps(sorted({m.split('.')[0] for m in sys.modules}"
            " & {'numpy', 'scipy', 'matplotlib', 'pyopencl', 'clsonar'})))")


def test_import_clsonar_imports_no_numpy():
    assert _fresh(f"import clsonar; {_MODULES}") == ["clsonar"]


def test_the_scene_names_are_imported_when_asked_for():
    from clsonar.scene import Scene, load_scene, save_scene

    assert (clsonar.Scene, clsonar.load_scene, clsonar.save_scene) == (
        Scene, load_scene, save_scene)
    assert set(clsonar.SCENE_NAMES) <= set(clsonar.__all__)
    assert _fresh("from clsonar import load_scene; import json; "
                  f"print(json.dumps(load_scene({ROOM!r}).name))") == "room"
    assert _fresh("import clsonar, json; "
                  "print(json.dumps(clsonar.scene.Scene.__name__))") == "Scene"
    with pytest.raises(AttributeError, match="no attribute 'Scenes'"):
        clsonar.Scenes  # noqa: B018


def test_the_command_line_imports_neither_scipy_nor_matplotlib_nor_pyopencl():
    assert _fresh(f"import clsonar.cli; {_MODULES}") == ["clsonar", "numpy"]


def test_pyopencl_and_pytools_versions_from_their_folders_are_importlib_metadata_s():
    """The ``version`` modules clsonar makes for pyopencl and pytools hold what their own
    modules would (the same three names from ``importlib.metadata``), and are the
    packages' ``version`` attributes as an import would have made them."""
    code = ("import json, re, sys; from clsonar import opencl; cl = opencl._cl()\n"
            "from importlib import metadata\n"
            "out = {}\n"
            "for p in opencl.VERSIONED:\n"
            "    m = sys.modules[p + '.version']\n"
            "    text = metadata.version(p)\n"
            "    g = re.match(r'^([0-9.]+)([a-z0-9]*?)$', text)\n"
            "    out[p] = [m is getattr(sys.modules[p], 'version'), m.VERSION_TEXT == text,\n"
            "              m.VERSION_STATUS == g.group(2),\n"
            "              m.VERSION == tuple(int(n) for n in g.group(1).split('.'))]\n"
            "print(json.dumps(out))")
    assert _fresh(code) == {p: [True] * 4 for p in ("pytools", "pyopencl")}


def test_the_command_line_starts_numpy_with_one_blas_thread_unless_told():
    code = ("import os, json, clsonar.cli, numpy; "
            "print(json.dumps(os.environ['OPENBLAS_NUM_THREADS']))")
    assert _fresh(code, OPENBLAS_NUM_THREADS="") == "1"
    assert _fresh(code, OPENBLAS_NUM_THREADS="2") == "2"


@pytest.mark.skipif(not fitpack_release(),
                    reason="this scipy's splines come through scipy.interpolate")
def test_a_room_run_with_png_none_imports_no_scipy_package_nor_matplotlib(tmp_path):
    """Only scipy's FITPACK extensions are loaded (numerics._extension), never the
    ``scipy`` or ``scipy.interpolate`` package; nor are the pictures (``clsonar.pictures``,
    ``clsonar.canvas``) that no file needs, nor ``numpy.ma`` (clsonar.numerics' unique and
    median: NumPy's plain forms import it, 7 ms), nor ``importlib.metadata`` (pyopencl's
    and pytools' versions come from their folders: opencl._versions_from_folders)."""
    code = ("import json, sys; from clsonar.cli import main\n"
            f"assert main(['run', {ROOM!r}, '--out', {str(tmp_path)!r}, '-q', "
            "'--png', 'none']) == 0\n"
            "print(json.dumps(sorted({'scipy', 'scipy.interpolate', 'matplotlib', "
            "'pyopencl', 'clsonar.pictures', 'clsonar.canvas', 'numpy.ma', "
            "'importlib.metadata'} & set(sys.modules))))")
    assert _fresh(code) == ["pyopencl"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "echoes.csv", "profile.csv", "report.json", "stages.npz"]


def test_the_process_command_freezes_the_collector_and_a_call_with_argv_does_not():
    code = ("import gc, json, sys; from clsonar.cli import main\n"
            "n = gc.get_freeze_count(); sys.argv = {argv!r}\n"
            "status = main({given})\n"
            "print(json.dumps([status, gc.get_freeze_count() - n > 1000]))")
    args = ["devices"]
    assert _fresh(code.format(argv=["clsonar", *args], given="")) == [0, True]
    assert _fresh(code.format(argv=["python"], given=repr(args))) == [0, False]


@pytest.mark.parametrize("scene, status", [(ROOM, 0), ("/nonexistent/room.json", 2)])
def test_clsonar_run_as_the_process_command_ends_the_process_with_its_status(scene, status):
    """``clsonar run`` as the process's own command ends the process when it is done
    (``cli._exit_now``: nothing after ``main`` runs), its lines written out first; called
    with ``argv`` it returns as any command does."""
    code = ("import sys; from clsonar.cli import main\n"
            "sys.argv = {argv!r}\n"
            "status = main({given})\n"
            "print('returned', status)")
    args = ["run", scene, "--dry-run"]
    done = [subprocess.run([sys.executable, "-c", code.format(argv=argv, given=given)],
                           capture_output=True, text=True, timeout=300)
            for argv, given in ((["clsonar", *args], ""), (["python"], repr(args)))]
    assert [d.returncode for d in done] == [status, 0]
    assert "returned" not in done[0].stdout
    assert done[1].stdout.splitlines()[-1] == f"returned {status}"
    lines = [re.sub(r"available [0-9.]+ [kMGT]?B", "available", d.stdout) for d in done]
    assert lines[0] == lines[1].replace(f"returned {status}\n", "")  # the memory free moves
    assert done[0].stderr == done[1].stderr and len(done[0].stderr.splitlines()) == status // 2


def _profile_csv_before(points: np.ndarray) -> str:
    """profile.csv as written before: each NumPy element formatted."""
    return "x,y\n" + "".join(f"{x:.6f},{y:.6f}\n" for x, y in points)


def _awkward(rng: np.random.Generator, n: int, dtype) -> np.ndarray:
    """``n`` values of every magnitude, signed zeros, infinities and a NaN, as ``dtype``."""
    values = rng.normal(size=n) * 10.0 ** rng.integers(-12, 5, size=n)
    values[:6] = [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-7]
    return values.astype(dtype)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_profile_csv_is_the_text_of_each_element(dtype):
    rng = np.random.default_rng(16)
    points = _awkward(rng, 4000, dtype).reshape(-1, 2)
    text = profile_csv(points)
    assert text == _profile_csv_before(points)
    assert text.splitlines()[1:4] == ["0.000000,-0.000000", "inf,-inf", "nan,0.000000"]
    assert profile_csv(np.zeros((0, 2))) == "x,y\n"


def _echoes_csv_before(t: EchoTable) -> str:
    """echoes.csv as written before: one row at a time, each NumPy element formatted."""
    file = io.StringIO()
    file.write("tx,rx,tof_s,amplitude,kind,order\n")
    names = t.kind_names()
    for i in range(len(t)):
        file.write(f"{t.tx[i]},{t.rx[i]},{t.tof_s[i]:.12g},"
                   f"{t.amplitude[i]:.9g},{names[i]},{t.order[i]}\n")
    return file.getvalue()


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_echoes_csv_is_the_text_of_each_element(dtype):
    rng = np.random.default_rng(17)
    n = 3000
    table = EchoTable(
        tx=rng.integers(0, 400, n), rx=rng.integers(0, 400, n),
        tof_s=_awkward(rng, n, dtype), amplitude=_awkward(rng, n, dtype),
        kind=rng.integers(0, len(KINDS), n).astype(np.int8),
        order=rng.integers(0, 6, n).astype(np.int8), point=np.zeros((n, 2)),
        element=np.zeros(n, np.int64), phase=np.zeros(n))
    file = io.StringIO()
    table.write_csv(file)
    assert file.getvalue() == _echoes_csv_before(table)
    assert file.getvalue().splitlines()[1].split(",")[2:4] == ["0", "0"]
    empty = io.StringIO()
    EchoTable(**{k: getattr(table, k)[:0] for k in EchoTable.__dataclass_fields__}
              ).write_csv(empty)
    assert empty.getvalue() == "tx,rx,tof_s,amplitude,kind,order\n"


def test_write_folder_syncs_every_file_before_the_folder_is_swapped_in(tmp_path, monkeypatch):
    from clsonar import files

    synced: list[str] = []
    real_fsync, real_rename = os.fsync, os.rename

    def fsync(fd: int) -> None:
        synced.append(os.readlink(f"/proc/self/fd/{fd}").rsplit("/", 1)[-1])
        real_fsync(fd)

    def rename(src, dst) -> None:
        assert sorted(synced) == ["a.txt", "b.txt", "c.txt"]  # all synced before
        real_rename(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "rename", rename)
    out = tmp_path / "out"
    files.write_folder(out, {"a.txt": b"1", "b.txt": b"22", "c.txt": b""})
    assert {p.name: p.read_bytes() for p in out.iterdir()} == {
        "a.txt": b"1", "b.txt": b"22", "c.txt": b""}


def test_a_sync_that_fails_in_a_thread_fails_the_write_and_leaves_nothing(tmp_path,
                                                                          monkeypatch):
    from clsonar import files
    from clsonar.errors import WriteError

    real_fsync = os.fsync
    opened = set(os.listdir("/proc/self/fd"))

    def fsync(fd: int) -> None:
        if os.readlink(f"/proc/self/fd/{fd}").endswith("b.txt"):  # not the first: a thread's
            raise OSError(5, "Input/output error")
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    with pytest.raises(WriteError, match="Input/output error"):
        files.write_folder(tmp_path / "out", {"a.txt": b"1", "b.txt": b"2", "c.txt": b"3"})
    assert os.listdir(tmp_path) == []
    assert set(os.listdir("/proc/self/fd")) <= opened  # every file closed
