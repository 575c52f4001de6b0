"""clsonar sweep and clsonar plot: spec validation, the resumable table, local and Dask
runners (a two-process LocalCluster), the plots."""

import csv
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from clsonar.cli import main
from clsonar.errors import ClsonarError
from clsonar.pipeline import run as run_pipeline
from clsonar.scene import load_scene, scene_to_dict
from clsonar.tools import sweep as sw
from clsonar.tools.sweepplot import draw_spread
from clsonar.tools.variants import at_distance, with_seed

ROOT = Path(__file__).resolve().parents[1]

#: A small, fast sweep: the thesis' plane at coarse cells, 2 noise levels × 2 distances
#: × 2 seeds = 8 runs of a few hundredths of a second each.
SPEC = {
    "name": "small",
    "scenes": [{"scene": "plane-2m", "distance_m": 2.0}],
    "seeds": 2,
    "metrics": ["rms_m", "accuracy_m.rms", "completeness.2cm", "counts.detections"],
    "grid": {"cell": [0.05], "signal.noise_std": [0.0, 0.6], "distance_m": [2.0, 3.0]},
}
TIMING = ("host",)


def _spec(tmp_path, data=None, name="spec.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(SPEC if data is None else data))
    return path


def _read_csv(path: Path, drop=True) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if drop:  # seconds and host differ from run to run; everything else must not
        rows = [{k: v for k, v in r.items() if not k.startswith("seconds.") and k not in TIMING}
                for r in rows]
    return rows


# --------------------------------------------------------------------------- spec


def test_key_paths():
    assert sw.parse_key_path("surfaces[0].points[1]") == ["surfaces", 0, "points", 1]
    for bad in ("a..b", ".a", "a.", "[0]", "a[x]", "0a", "signal noise"):
        with pytest.raises(ValueError, match="malformed key path"):
            sw.parse_key_path(bad)
    data = scene_to_dict(load_scene(ROOT / "scenes" / "plane-2m.json"))
    changed = sw.set_key(data, "surfaces[0].points[1]", [9.5, 10.0])
    assert changed["surfaces"][0]["points"] == [[9.0, 0.0], [9.5, 10.0]]
    assert data["surfaces"][0]["points"][1] == [9.0, 10.0]  # the input is left alone
    with pytest.raises(KeyError, match="signal has no key 'noise'"):
        sw.set_key(data, "signal.noise", 1.0)
    with pytest.raises(KeyError, match=r"surfaces has 1 item\(s\), no \[3\]"):
        sw.set_key(data, "surfaces[3].radius", 1.0)


def test_plan_applies_keys_distance_and_seeds(tmp_path):
    spec = sw.load_spec(_spec(tmp_path))
    runs = sw.plan(spec)
    assert len(runs) == 8 and len({r.run_id for r in runs}) == 8
    assert [r.index for r in runs] == list(range(8))
    base = load_scene(ROOT / "scenes" / "plane-2m.json")
    r = runs[7]  # the last grid point, second seed
    assert r.params == {"cell": 0.05, "signal.noise_std": 0.6, "distance_m": 3.0}
    assert r.seed == 1
    expected = with_seed(at_distance(base, 2.0, 3.0), 1, 0.6)
    assert r.scene.signal == expected.signal
    assert r.scene.sensors == expected.sensors
    assert r.scene.cell == 0.05
    assert r.scene.sensors.placement.start == pytest.approx((6.0, 0.1))
    assert r.scene.sensors.placement.seed == base.sensors.placement.seed + 1
    # the ids are stable: the same spec plans the same ids
    assert [x.run_id for x in sw.plan(sw.load_spec(_spec(tmp_path)))] == [x.run_id
                                                                           for x in runs]


def test_toml_spec(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('scenes = ["plane-2m"]\nseeds = [3, 5]\n[grid]\n'
                    '"signal.noise_std" = [0.2]\n')
    spec = sw.load_spec(path)
    assert spec.seeds == (3, 5) and spec.grid == (("signal.noise_std", (0.2,)),)
    assert spec.metrics == sw.DEFAULT_METRICS and spec.name == "s"


BAD_SPECS = {
    "unknown-path": ({**SPEC, "grid": {"signal.noise": [0.1]}}, "grid.signal.noise",
                     "unknown key path in scene 'plane-2m': signal has no key 'noise'"),
    "empty-grid": ({**SPEC, "grid": {}}, "grid", "empty"),
    "empty-values": ({**SPEC, "grid": {"cell": []}}, "grid.cell", "empty list"),
    "wrong-type": ({**SPEC, "grid": {"signal.noise_std": ["loud"]}}, "signal.noise_std",
                   "must be a number, not a string"),
    "negative": ({**SPEC, "grid": {"cell": [0.05, -1]}}, "cell", "must be > 0"),
    "not-a-list": ({**SPEC, "grid": {"cell": 0.05}}, "grid.cell", "must be a list"),
    "seeds": ({**SPEC, "seeds": "three"}, "seeds", "number of seeds"),
    "metric": ({**SPEC, "metrics": ["rmse"]}, "metrics[0]", "unknown metric 'rmse'"),
    "top-key": ({**SPEC, "grids": {}}, "grids", "unknown key"),
    "scene": ({**SPEC, "scenes": ["no-such-scene"]}, "scenes[0]", "no scene file"),
    "distance": ({**SPEC, "scenes": ["plane-2m"]}, "scenes[0]", "own distance"),
    "malformed": ({**SPEC, "grid": {"signal..noise_std": [1]}}, "grid.signal..noise_std",
                  "malformed key path"),
    "preset": ({**SPEC, "grid": {"preset": ["fast"]}}, "grid.preset", "must be one of"),
}


@pytest.mark.parametrize("case", sorted(BAD_SPECS))
def test_bad_spec_one_line_exit_2(tmp_path, capsys, case):
    data, key, words = BAD_SPECS[case]
    path = _spec(tmp_path, data)
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert captured.out == "" and len(lines) == 1, captured.err
    assert lines[0].startswith(f"clsonar: error: {path}")
    assert key in lines[0] and words in lines[0], lines[0]
    assert not out.exists()  # nothing written


def test_bad_toml_one_line(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text('scenes = ["plane-2m"\n')
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"clsonar: error: {path}: invalid TOML")


def test_scheduler_without_dask(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    assert main(["sweep", str(_spec(tmp_path)), "--out", str(tmp_path / "out"),
                 "--scheduler", "tcp://127.0.0.1:8786"]) == 2
    assert capsys.readouterr().err == ("clsonar: error: --scheduler needs dask.distributed: "
                                       "pip install 'clsonar[dask]'\n")
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- local runs


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    """The small sweep run locally through the CLI: (spec path, out folder)."""
    tmp = tmp_path_factory.mktemp("local")
    spec = _spec(tmp)
    assert main(["sweep", str(spec), "--out", str(tmp / "out"), "-q"]) == 0
    return spec, tmp / "out"


def test_local_sweep_rows_are_the_pipeline_results(local_sweep):
    spec_path, out = local_sweep
    rows = _read_csv(out / "table.csv", drop=False)
    spec = sw.load_spec(spec_path)
    runs = sw.plan(spec)
    assert [r["run"] for r in rows] == [r.run_id for r in runs]
    assert list(rows[0]) == sw.columns(spec.parameters, spec.metrics)
    for k in (0, 5):  # two runs redone directly through the pipeline give the same row
        result = run_pipeline(runs[k].scene)
        assert float(rows[k]["rms_m"]) == result.metrics["rms_m"]
        assert float(rows[k]["accuracy_m.rms"]) == result.metrics["accuracy_m"]["rms"]
        assert int(rows[k]["counts.detections"]) == result.counts["detections"]
        assert rows[k]["device"] == result.device
        assert float(rows[k]["seconds.total"]) > 0
    assert rows[5]["signal.noise_std"] == "0.6" and rows[5]["distance_m"] == "2.0"
    assert rows[5]["seed"] == "1"
    # the noise-free plane at 2 m maps to a few millimetres (docs/reproduce)
    assert all(float(r["rms_m"]) < 0.01 for r in rows[:2])


def test_interrupted_sweep_resumes_without_repeat_or_loss(tmp_path):
    spec = sw.load_spec(_spec(tmp_path))
    runs = sw.plan(spec)
    out = tmp_path / "out"

    class Stop(Exception):
        pass

    def stop_after_3(finished, total, run):
        if finished == 3:
            raise Stop

    with pytest.raises(Stop):
        sw.sweep(spec, out, progress=stop_after_3)
    first = (out / sw.TABLE_JSONL).read_bytes().splitlines()
    assert len(first) == 3
    assert [r["run"] for r in _read_csv(out / "table.csv")] == [r.run_id for r in runs[:3]]
    # a fourth row cut short by a crash mid-write is dropped, and that run redone
    partial = json.dumps({"run": runs[3].run_id, "index": 3})[:25]
    with open(out / sw.TABLE_JSONL, "a") as f:
        f.write(partial)
    seen = []
    rows = sw.sweep(spec, out, progress=lambda i, n, run: seen.append(run.index))
    assert seen == [3, 4, 5, 6, 7]  # only the missing runs ran
    lines = (out / sw.TABLE_JSONL).read_bytes().splitlines()
    assert lines[:3] == first  # finished rows kept as they were
    ids = [json.loads(x)["run"] for x in lines]
    assert sorted(ids) == sorted(r.run_id for r in runs) and len(set(ids)) == len(ids)
    assert [r["run"] for r in rows] == [r.run_id for r in runs]
    # a third call has nothing left to do
    assert sw.sweep(spec, out, progress=lambda *a: pytest.fail("ran again")) == rows


def test_resumed_table_equals_uninterrupted(local_sweep, tmp_path):
    spec = sw.load_spec(local_sweep[0])
    out = tmp_path / "out"

    def stop(finished, total, run):
        if finished == 5:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sw.sweep(spec, out, progress=stop)
    sw.sweep(spec, out)
    assert _read_csv(out / "table.csv") == _read_csv(local_sweep[1] / "table.csv")


def test_one_sweep_per_folder(tmp_path):
    spec = sw.load_spec(_spec(tmp_path))
    out = tmp_path / "out"
    out.mkdir()
    with sw.SweepLock(out), pytest.raises(ClsonarError, match="another sweep is writing there"):
        sw.sweep(spec, out)


# --------------------------------------------------------------------------- plots


def test_plot_writes_one_png_per_metric_and_swept_parameter(local_sweep, capsys):
    _, out = local_sweep
    assert main(["plot", str(out)]) == 0
    names = sorted(p.name for p in (out / "plots").iterdir())
    # cell has one value: a setting, not drawn against
    assert names == sorted(f"{m}_vs_{p}.png" for m in SPEC["metrics"]
                           for p in ("signal.noise_std", "distance_m"))
    assert all((out / "plots" / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in names)
    assert capsys.readouterr().out == f"wrote 8 PNGs in {out}/plots/\n"


def test_draw_spread_mean_and_min_max():
    from matplotlib.figure import Figure

    ax = Figure().add_subplot()
    draw_spread(ax, [1.0, 2.0, 3.0], [[1.0, 3.0], [2.0, 2.0, 5.0], []], "o-", "x")
    line = ax.get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), [2.0, 3.0, np.nan])
    band = ax.collections[0].get_paths()[0].vertices
    assert {tuple(v) for v in band} >= {(1.0, 1.0), (1.0, 3.0), (2.0, 2.0), (2.0, 5.0)}


def test_plot_of_no_sweep_is_one_line(tmp_path, capsys):
    assert main(["plot", str(tmp_path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "not a sweep folder" in err[0]


# --------------------------------------------------------------------------- Dask


def _die_once(marker, run, metrics, device):
    """The sweep's task, except that the first worker to run it dies (a crash)."""
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return sw.run_one(run, metrics, device)
    os.close(fd)
    os._exit(1)


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # _die_once on the workers
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None, silence_logs=50) as c:
        yield c


def test_distributed_table_equals_local_row_for_row(cluster, local_sweep, tmp_path):
    spec, local_out = local_sweep
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "-q",
                 "--scheduler", cluster.scheduler_address]) == 0
    distributed_rows = _read_csv(out / "table.csv")
    assert distributed_rows == _read_csv(local_out / "table.csv")
    assert len(distributed_rows) == 8
    # each worker process built one OpenCL context and reused it for all its runs
    from distributed import Client

    with Client(cluster.scheduler_address) as client:
        built = client.run(lambda: sorted(map(str, sw.CONTEXTS)))
    assert len(built) == 2 and all(v == ["None"] for v in built.values())


def test_dead_worker_loses_only_its_run(cluster, local_sweep, tmp_path):
    from functools import partial

    from distributed import Client

    spec = sw.load_spec(local_sweep[0])
    out = tmp_path / "out"
    out.mkdir()
    task = partial(_die_once, str(tmp_path / "died"))
    with Client(cluster.scheduler_address) as client:
        table = sw.RunTable(out)
        new = sw.run_dask(sw.plan(spec), table, spec.metrics, client, task=task)
        client.wait_for_workers(2, timeout=60)  # the nanny restarted the dead one
    assert (tmp_path / "died").exists()  # a worker did die
    assert len(new) == 8 and len({r["run"] for r in new}) == 8
    lines = (out / sw.TABLE_JSONL).read_text().splitlines()
    assert len(lines) == 8
    got = sorted(({k: v for k, v in r.items() if not k.startswith("seconds.") and k != "host"}
                  for r in new), key=lambda r: r["index"])
    local = [{k: v for k, v in json.loads(x).items() if not k.startswith("seconds.")
              and k != "host"} for x in (local_sweep[1] / sw.TABLE_JSONL).read_text()
             .splitlines()]
    assert got == sorted(local, key=lambda r: r["index"])
