"""Command-line contract: bad input gives one line naming file and key, exit 2, no output."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from clsonar.cli import main
from clsonar.numerics import fitpack_release

#: Where the installed scipy is not a release whose FITPACK wrappers clsonar.numerics loads
#: itself, a spline is fitted through ``scipy.interpolate`` (the public functions).
NEEDS_PRIVATE_FITPACK = pytest.mark.skipif(
    not fitpack_release(), reason="this scipy's splines come through scipy.interpolate")

ROOT = Path(__file__).resolve().parents[1]


def _clsonar(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "clsonar", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=120)


BAD_SCENES = {
    "invalid.json": '{"clsonar": 1, "extent": [0, 0, 1',
    "empty.json": "",
    "unknown.json": json.dumps({"clsonar": 1, "extent": [0, 0, 1, 1], "colour": 1}),
    "type.json": json.dumps({"clsonar": 1, "extent": [0, 0, 1, 1], "cell": "1cm"}),
    "nan.json": '{"clsonar": 1, "extent": [0, 0, 1, NaN]}',
    "inf.json": '{"clsonar": 1, "extent": [0, 0, 1, Infinity]}',
    "radius.json": json.dumps({"clsonar": 1, "extent": [0, 0, 1, 1], "surfaces": [
        {"type": "circle", "center": [0, 0], "radius": -1}]}),
    "cell.json": json.dumps({"clsonar": 1, "extent": [0, 0, 1, 1], "cell": 0}),
    "segment.json": json.dumps({"clsonar": 1, "extent": [0, 0, 1, 1], "surfaces": [
        {"type": "polyline", "points": [[0, 0], [0, 0]]}]}),
    "version.json": json.dumps({"clsonar": 7, "extent": [0, 0, 1, 1]}),
}
EXPECTED_KEY = {"invalid.json": "invalid JSON", "empty.json": "file is empty",
                "unknown.json": "colour", "type.json": "cell", "nan.json": "NaN",
                "inf.json": "Infinity", "radius.json": "surfaces[0].radius",
                "cell.json": "cell", "segment.json": "surfaces[0].points[1]",
                "version.json": "clsonar"}


@pytest.mark.parametrize("name", sorted(BAD_SCENES))
def test_bad_scene_in_process(tmp_path, capsys, name):
    f = tmp_path / name
    f.write_text(BAD_SCENES[name])
    out = tmp_path / "echoes.csv"
    assert main(["echoes", str(f), "-o", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"clsonar: error: {f}: ")
    assert EXPECTED_KEY[name] in lines[0]
    assert list(tmp_path.iterdir()) == [f]  # nothing written


def test_bad_scene_subprocess_has_no_traceback(tmp_path):
    f = tmp_path / "radius.json"
    f.write_text(BAD_SCENES["radius.json"])
    r = _clsonar("echoes", str(f))
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip() == f"clsonar: error: {f}: surfaces[0].radius: must be > 0"


def test_missing_file(tmp_path, capsys):
    assert main(["echoes", str(tmp_path / "nope.json")]) == 2
    assert "nope.json: cannot read file" in capsys.readouterr().err


def test_devices_lists_the_cpu_and_the_choice():
    r = _clsonar("devices")
    assert r.returncode == 0, r.stderr
    assert "CPU" in r.stdout and "clsonar would use 0:0" in r.stdout


def test_unknown_device_is_one_line(capsys):
    assert main(["devices", "--device", "no-such-gpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "clsonar: error: --device 'no-such-gpu' matches no OpenCL device " \
                  "(see 'clsonar devices')"


def test_echoes_prints_the_csv_contract(tmp_path):
    r = _clsonar("echoes", str(ROOT / "scenes" / "plane-2m.json"))
    assert r.returncode == 0, r.stderr
    rows = r.stdout.splitlines()
    assert rows[0] == "tx,rx,tof_s,amplitude,kind,order"
    assert len(rows) > 1
    tx, rx, tof, amp, kind, order = rows[1].split(",")
    assert int(tx) >= 0 and int(rx) >= 0 and float(tof) > 0 and float(amp) > 0
    assert kind in {"specular", "corner", "edge", "curved"} and int(order) >= 1
    out = tmp_path / "e.csv"
    assert main(["echoes", str(ROOT / "scenes" / "plane-2m.json"), "-o", str(out)]) == 0
    assert out.read_text().splitlines() == rows


def test_no_opencl_device_says_what_to_install(tmp_path):
    env = {**__import__("os").environ, "OCL_ICD_VENDORS": str(tmp_path)}  # no ICD files
    r = subprocess.run([sys.executable, "-m", "clsonar", "devices"], capture_output=True,
                       text=True, env=env, timeout=120)
    assert r.returncode == 1
    assert "No OpenCL device found" in r.stdout and "pocl-opencl-icd" in r.stdout
    assert "Traceback" not in r.stderr


def test_device_that_cannot_build_is_reported_not_used(monkeypatch, capsys):
    import clsonar.opencl as ocl

    monkeypatch.setattr(ocl, "_build_problem",
                        lambda d: "cannot build kernels (unknown target CPU 'generic')")
    assert main(["devices"]) == 1
    out = capsys.readouterr().out
    assert "unknown target CPU 'generic'" in out and "No device can build kernels" in out
    with pytest.raises(ocl.DeviceError, match="pocl-opencl-icd"):
        ocl.choose_device()


def _run_without_matplotlib(out: Path, *flags: str, scene: str = "plane-2m",
                            blocked: tuple[str, ...] = ("matplotlib",)
                            ) -> subprocess.CompletedProcess:
    code = (f"import sys; sys.modules.update(dict.fromkeys({list(blocked)!r}))\n"
            "from clsonar.cli import main\n"
            f"raise SystemExit(main(['run', {str(ROOT / 'scenes' / f'{scene}.json')!r}, "
            f"'--out', {str(out)!r}, '-q', *{list(flags)!r}]))")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)


DATA_FILES = ["echoes.csv", "profile.csv", "report.json", "stages.npz"]
STAGE_PNGS = ["filtered.png", "raw.png", "thin.png"]


def test_run_without_matplotlib_writes_every_output(tmp_path):
    """Issue 16: ``clsonar run`` draws every picture from the arrays, scene.png and
    profile.png too (clsonar.pictures, clsonar.canvas): without matplotlib (the
    ``clsonar[plots]`` extra, for the tools' figures) it writes every output, silently."""
    out = tmp_path / "out"
    r = _run_without_matplotlib(out)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [*DATA_FILES, *STAGE_PNGS, "profile.png", "scene.png"])


@pytest.mark.parametrize("png, pictures", [("none", []), ("stages", STAGE_PNGS)])
def test_run_png_none_and_stages_need_no_matplotlib(tmp_path, png, pictures):
    """Issue 16: ``--png none`` writes no picture and ``--png stages`` the map stages only,
    neither importing matplotlib nor warning."""
    out = tmp_path / "out"
    r = _run_without_matplotlib(out, "--png", png)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(DATA_FILES + pictures)


@pytest.mark.parametrize("scene, blocked", [
    pytest.param("room", ("scipy.ndimage", "scipy.optimize", "scipy.special",
                          "scipy.interpolate"), marks=NEEDS_PRIVATE_FITPACK),
    ("room-cylinder", ("scipy.ndimage",))])
def test_a_room_run_needs_no_scipy_package(tmp_path, scene, blocked):
    """Issue 16: importing scipy.ndimage costs a process 0.2-0.4 s, scipy.optimize 0.35 s,
    scipy.interpolate 0.5 s; a run of a room with the default (tangent-point) mapping and
    thinning never calls ndimage, and reaches J1, Brent's minimiser and FITPACK through
    clsonar.numerics, so imports none of them (a room with a cylinder still fits its
    circle with scipy.optimize.least_squares)."""
    out = tmp_path / "out"
    r = _run_without_matplotlib(out, "--png", "stages", scene=scene,
                                blocked=("matplotlib", *blocked))
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert sorted(p.name for p in out.iterdir()) == sorted(DATA_FILES + STAGE_PNGS)


@pytest.mark.parametrize("command", [["plot", "DIR"], ["reproduce", "--out", "DIR"]])
def test_pictures_commands_without_matplotlib_refuse_in_one_line(tmp_path, capsys,
                                                                 monkeypatch, command):
    from clsonar import outputs

    monkeypatch.setattr(outputs, "plots_available", lambda: False)
    argv = [str(tmp_path / "d") if a == "DIR" else a for a in command]
    assert main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"clsonar: error: clsonar {command[0]}")
    assert err[0].endswith("needs matplotlib: pip install 'clsonar[plots]'")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where", ["a-file", "a-file/sub"])
def test_an_out_that_cannot_be_a_folder_is_one_line(tmp_path, capsys, where):
    """Issue 19: --out naming a file (or a folder inside one) was a traceback and exit 1;
    now one line and exit 2, before any work, and nothing written."""
    (tmp_path / "a-file").write_text("keep me")
    scene = Path(__file__).resolve().parents[1] / "scenes" / "plane-2m.json"
    assert main(["run", str(scene), "--out", str(tmp_path / where), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clsonar: error: ") and "folder" in err[0]
    assert (tmp_path / "a-file").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]


def test_a_scene_whose_pairs_cannot_be_held_is_refused_in_one_line(tmp_path, capsys,
                                                                   monkeypatch):
    """Issue 19: the fired pairs' memory is judged before any echo is computed: a
    100-element array (10⁴ pairs, about 2 MB) on a machine with 1 MB free is one line and
    exit 2, nothing written."""
    from clsonar.mapping import grid

    n = 100
    scene = {"clsonar": 1, "name": "crowd", "extent": [-0.5, -1.0, 1.5, 1.0], "cell": 0.02,
             "surfaces": [{"type": "polyline", "points": [[1.0, -1.0], [1.0, 1.0]]}],
             "sensors": {"transducers": [{"position": [0.0, -0.5 + i / (n - 1)],
                                          "heading_deg": 0.0} for i in range(n)]}}
    path = tmp_path / "crowd.json"
    path.write_text(json.dumps(scene))
    monkeypatch.setattr(grid, "host_available_bytes", lambda: 1 << 20)
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "10,000 fired pairs (100 transducers)" in err[0], err
    assert not (tmp_path / "out").exists()


def test_dry_run_prints_the_cost_and_writes_nothing(tmp_path, capsys, monkeypatch):
    """Issue 19: ``clsonar run --dry-run`` places the transducers and prints the pairs,
    samples, cells, mirror sequences and memory; with too little memory it says the run
    would be refused."""
    from clsonar.mapping import grid

    room = ROOT / "scenes" / "room.json"
    assert main(["run", str(room), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "room: transducers 512, fired pairs 4,096"
    assert "82,364 samples a pair" in out[1] and "map 1,000,000 cells" in out[2]
    assert out[3] == ("room: echoes among 8 walls (the most of one map) to order 2: at most "
                      "64 mirror sequences")
    assert out[4].endswith("fits")
    monkeypatch.setattr(grid, "host_available_bytes", lambda: 1 << 20)
    assert main(["run", str(room), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    assert capsys.readouterr().out.rstrip().endswith("does not fit: the run would be refused")
    assert not (tmp_path / "out").exists()


def test_max_memory_refuses_in_one_line_and_report_records_the_cost(tmp_path, capsys):
    """Issue 19: ``--max-memory`` is the most a run may count on (a map or pairs needing
    more are refused before any work, naming the limit; a size that is not one is refused
    too); report.json's ``cost`` holds the estimate beside the run's peak memory."""
    from clsonar.mapping import grid

    plane = ROOT / "scenes" / "plane-2m.json"
    out = tmp_path / "out"
    assert main(["run", str(plane), "--out", str(out), "-q", "--max-memory", "1M"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "48 MB of memory, more than the --max-memory limit (1 MB)" in err[0]
    assert main(["run", str(plane), "--out", str(out), "-q", "--max-memory", "lots"]) == 2
    assert capsys.readouterr().err.strip() == (
        "clsonar: error: --max-memory 'lots': not a size (2G, 500M, 1.5e9)")
    assert not out.exists() and grid.host_available_bytes() != 1_000_000  # limit undone
    assert main(["run", str(plane), "--out", str(out), "-q", "--png", "none",
                 "--max-memory", "2G"]) == 0
    cost = json.loads((out / "report.json").read_text())["cost"]
    assert cost["pairs"] == 900 and cost["cells"] == 1_000_000
    assert cost["map_bytes"] == 48e6 and cost["available_bytes"] <= 2e9
    assert 0 < cost["peak_bytes"]
