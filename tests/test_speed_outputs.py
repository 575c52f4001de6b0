"""Issue 16's work beside the pipeline in ``clsonar run``: stages.npz and the map pictures
built in a thread while the profile and the metrics are computed
(:class:`clsonar.outputs.EarlyFiles`), and the transducers placed by the run's worker
process while this one sets up the device (:func:`clsonar.drawing.run_worker`,
:meth:`clsonar.drawing.PlotWorker.first`). Both give the bytes and bits of the work done in
order; a thread or worker that fails leaves the work to the run, which meets any error
itself; a run that fails writes no folder and leaves no process or thread behind.

A worker is forked only before pyopencl is imported, which this test process may already
have done: those runs are in fresh processes (:func:`_python`)."""

import json
import os
import pickle
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from test_plot_worker import CHILDREN  # the child processes a fresh process has

from clsonar import outputs, pipeline, placing
from clsonar.files import bundled_scenes
from clsonar.scene import load_scene
from clsonar.tools.floors import floor_scene

ROOM = str(bundled_scenes() / "room.json")
PLANE = str(bundled_scenes() / "plane-2m.json")

needs_fork = pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin",
                                reason="a worker needs fork (not macOS's)")


@pytest.fixture(scope="module")
def room():
    """The bundled room run once, its maps told to two :class:`EarlyFiles` (``none`` and
    ``stages``) and the stage running when they were told."""
    early = {png: outputs.EarlyFiles(png) for png in ("none", "stages")}
    stages, told = [], []

    def maps_done(*args):
        told.append((stages[-1], args))
        for files in early.values():
            files.maps_done(*args)

    result = pipeline.run(load_scene(ROOM), progress=lambda s, i, n: stages.append(s),
                          maps_done=maps_done)
    return result, early, told


def test_the_files_built_beside_the_run_are_the_bytes_built_after_it(room):
    """The thread's stages.npz and raw, filtered, thin.png are the in-order functions'
    bytes, of the result's own maps, told once, when thinning is done (before the
    profile and metrics)."""
    result, early, told = room
    assert len(told) == 1
    stage, (scene, geometry, raw, filtered, thin) = told[0]
    assert stage == "thinning"
    assert scene is result.scene and geometry is result.geometry
    assert raw is result.raw and filtered is result.filtered and thin is result.thin
    npz = outputs.data_files(result)["stages.npz"]
    assert early["none"].files(result) == {"stages.npz": npz}
    assert early["stages"].files(result) == {"stages.npz": npz,
                                             **outputs.map_pngs(result, "stages")}
    with np.load(__import__("io").BytesIO(npz)) as maps:
        assert np.array_equal(maps["raw"], result.raw) and maps["thin"].sum() > 100
        assert np.array_equal(maps["extent"], np.asarray(result.scene.extent))


def test_files_are_used_only_for_the_run_whose_maps_they_were_told(room, tmp_path):
    """Another run's result, or a run that never told its maps, gets nothing: its files
    are built in order. write_outputs with and without them writes the same bytes."""
    result, early, _ = room
    other = pipeline.run(load_scene(PLANE))
    assert early["stages"].files(other) == {}
    assert outputs.EarlyFiles("none").files(result) == {}
    outputs.write_outputs(result, tmp_path / "early", png="stages", early=early["stages"])
    outputs.write_outputs(result, tmp_path / "order", png="stages")
    _same_files(tmp_path / "early", tmp_path / "order")


def test_no_thread_beside_a_worker_that_draws_the_plots(room):
    """With a worker drawing scene.png and profile.png the files are built after the run
    (while it draws profile.png): told the maps, no thread starts and nothing is built;
    a worker without plots (the placement's) leaves the thread on."""

    class Worker:
        def __init__(self, plots):
            self.plots = plots

    result, _, told = room
    args = told[0][1]
    drawing, placing = (outputs.EarlyFiles("all", Worker(p)) for p in (True, False))
    for early in (drawing, placing):
        early.maps_done(*args)
    assert drawing.off and drawing.files(result) == {}
    assert not placing.off and sorted(placing.files(result)) == [
        "filtered.png", "raw.png", "stages.npz", "thin.png"]


def test_a_thread_that_fails_leaves_the_files_to_the_run(monkeypatch, tmp_path):
    """stages.npz failing in the thread: no traceback, nothing built there, and
    write_outputs builds every file itself, the same bytes."""
    build = outputs.stages_npz

    def only_here(*args):
        if threading.current_thread() is not threading.main_thread():
            raise MemoryError("not in the thread")
        return build(*args)

    monkeypatch.setattr(outputs, "stages_npz", only_here)
    before = set(threading.enumerate())  # other tests' threads (the GUI's, a pool's) stay
    early = outputs.EarlyFiles("none")
    result = pipeline.run(load_scene(PLANE), maps_done=early.maps_done)
    assert early.files(result) == {}
    outputs.write_outputs(result, tmp_path / "a", png="none", early=early)
    monkeypatch.setattr(outputs, "stages_npz", build)
    outputs.write_outputs(result, tmp_path / "b", png="none")
    _same_files(tmp_path / "a", tmp_path / "b")
    assert set(threading.enumerate()) <= before  # the files' thread is gone


def test_a_placement_made_elsewhere_gives_the_same_run():
    """The run with the placement given (:func:`placing.placement`, as the worker
    computes it), and with a placement that answers None (computed in the run): the same
    transducers, maps, profile and metrics as the plain run; a floor mapped room by room
    has no whole-scene placement."""
    scene = load_scene(ROOM)
    plain = pipeline.run(scene, preset="thesis")
    given = placing.placement(scene, "thesis")
    assert given is not None
    here = pipeline.placed_sensors(pipeline.apply_preset(scene, "thesis"))
    assert pickle.dumps(given) == pickle.dumps(here)  # (the run's geometry holds caches)
    for name in ("positions", "axes"):
        assert getattr(given[1], name).tobytes() == getattr(plain.sensors, name).tobytes()
    asked = []
    for placement in (lambda: given, lambda: asked.append(1)):
        r = pipeline.run(scene, preset="thesis", placement=placement)
        assert np.array_equal(r.sensors.positions, plain.sensors.positions)
        for name in ("raw", "filtered", "thin"):
            assert np.array_equal(getattr(r, name), getattr(plain, name))
        assert np.array_equal(r.profile.points, plain.profile.points)
        assert r.metrics == plain.metrics and r.counts == plain.counts
    assert asked == [1]
    assert placing.placement(floor_scene(size_m=10.0)) is None


def _python(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; its last line of output, as JSON."""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.splitlines()[-1])


@needs_fork
def test_the_worker_places_the_transducers_first_then_answers_calls():
    """A worker without plots answers its first job with the placement made here (the
    same pickled bytes), then each call with the function's value: the room's truth
    (``metrics.lit_truth``, what the run's cache asks it for) the same bits as here, None
    for a call that raises; one whose first job raises, or that is killed, answers None
    and is closed (it takes no call). ``close`` leaves no process."""
    found = _python(CHILDREN + f"""
import json, os, pickle, signal
from clsonar import drawing, metrics, outputs, pipeline, placing
from clsonar.scene import load_scene
scene = load_scene({ROOM!r})
def boom():
    raise ValueError("no placement")
workers = [drawing.start(if_busy=True, plots=False, first=f)
           for f in (lambda: placing.placement(scene), boom, lambda: placing.placement(scene))]
os.kill(workers[2].pid, signal.SIGKILL)
answers = [w.first() for w in workers]
here = placing.placement(scene)
forked = children() == [workers[0].pid] and workers[1].pid == workers[2].pid == 0
result = pipeline.run(scene)
truth = metrics.lit_truth(scene, *here, result.echoes)
sent = [workers[0].call(metrics.lit_truth, scene, *answers[0], result.echoes),
        workers[0].call(metrics.lit_truth, scene, None, None, None),
        workers[1].call(metrics.least_amplitude, scene), workers[2].call(len, [])]
values = [workers[0].value(), workers[0].value()]
same = all(a.tobytes() == b.tobytes() for a, b in zip(values[0], truth))
for w in workers:
    w.close()
print(json.dumps({{"same": pickle.dumps(answers[0]) == pickle.dumps(here), "truth": same,
                  "none": [a is None for a in answers], "forked": forked, "sent": sent,
                  "raised": values[1] is None, "left": children(),
                  "seconds": sorted(workers[0].seconds)}}))
""")
    assert found["same"] and found["truth"] and found["forked"]
    assert found["none"] == [False, True, True]
    assert found["sent"] == [True, True, False, False]  # those that answered None: closed
    assert found["raised"]
    assert found["left"] == []
    assert found["seconds"] == ["clsonar.metrics.lit_truth", "first job"]


def _cli_run(out: str, png: str, worker: bool, fail: bool = False) -> dict:
    """``clsonar run ROOM --out out --png png -q`` in a fresh process, its worker started
    as where a core is free (``worker``) or never; ``fail``: its metrics raise. Its exit
    status, whether a worker started (and for plots), which of the pipeline's modules this
    process had imported when it forked, and the child processes and threads left after
    it."""
    return _python(CHILDREN + f"""
import json, os, sys, threading
from clsonar import cli, drawing, metrics
drawing.core_free = lambda: True  # as on an idle machine
started, start, imported = [], drawing.start, []
def counted(**k):
    imported.extend(m for m in ("clsonar.pipeline", "clsonar.mapping", "pyopencl")
                    if m in sys.modules)
    started.append(start(**k) if {worker!r} else None)
    return started[-1]
drawing.start = counted
def fails(*a, **k):
    raise ValueError("metrics failed")
if {fail!r}:
    metrics.evaluate = fails
    import tempfile  # the traceback beside the outputs, not in the machine's /tmp
    tempfile.tempdir = {os.path.dirname(out)!r}
code = cli.main(['run', {ROOM!r}, '--out', {out!r}, '-q', '--png', {png!r}])
print(json.dumps({{"code": code, "started": [w is not None for w in started],
                  "plots": [w.plots for w in started if w], "imported": imported,
                  "left": children(),
                  "threads": threading.active_count()}}))
""")


@needs_fork
@pytest.mark.parametrize("png", ["none", "stages"])
def test_clsonar_run_with_its_worker_writes_the_files_written_without(tmp_path, png):
    """``clsonar run --png none`` and ``stages`` of the room with the worker placing the
    transducers (as where a core is free) and without any worker: the same bytes but
    report.json's seconds and memory; no child process or thread left. The worker is
    forked as soon as the scene is read, before the pipeline's imports (which this
    process makes while the worker places)."""
    found = [_cli_run(str(tmp_path / str(w)), png, w) for w in (True, False)]
    assert [f["code"] for f in found] == [0, 0]
    assert [f["started"] for f in found] == [[True], [False]]
    assert [f["imported"] for f in found] == [[], []]
    assert found[0]["plots"] == [False]
    assert all(f["left"] == [] and f["threads"] == 1 for f in found)
    _same_files(tmp_path / "True", tmp_path / "False")
    assert len(list((tmp_path / "True").iterdir())) == (4 if png == "none" else 7)


@needs_fork
def test_a_run_that_fails_with_its_worker_leaves_no_folder_process_or_thread(tmp_path):
    """The room's metrics raising after its worker placed the transducers and its thread
    built stages.npz: exit 1 (one line, the traceback saved), no folder, nothing left."""
    found = _cli_run(str(tmp_path / "out"), "stages", True, fail=True)
    assert found["code"] == 1 and found["started"] == [True]
    assert found["left"] == [] and found["threads"] == 1
    assert not (tmp_path / "out").exists()
    assert "metrics failed" in next(tmp_path.glob("clsonar-traceback-*.txt")).read_text()


def _same_files(a: Path, b: Path) -> None:
    """The same files with the same bytes, but report.json's seconds and memory."""
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for name in names:
        if name != "report.json":
            assert (a / name).read_bytes() == (b / name).read_bytes(), name
    reports = [json.loads((d / "report.json").read_text()) for d in (a, b)]
    for report in reports:
        report.pop("seconds")
        for key in ("peak_bytes", "available_bytes"):
            report.get("cost", {}).pop(key, None)
    assert reports[0] == reports[1]
