"""scene.png and profile.png drawn by a worker process on the other core (clsonar.drawing,
issue 16): the same bytes as drawn in process, a worker that fails, dies or stalls falls
back to drawing in process, no process outlives a run, and bad input starts no worker.

A worker is forked only before pyopencl is imported, which this test process may already
have done: the forks happen in fresh processes (:func:`_python`)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from clsonar import drawing, outputs
from clsonar.cli import main

ROOT = Path(__file__).resolve().parents[1]
PLANE = str(ROOT / "scenes" / "plane-2m.json")

pytestmark = pytest.mark.skipif(not hasattr(os, "fork") or sys.platform == "darwin",
                                reason="a worker needs fork (not macOS's)")


def _python(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; its last line of output, as JSON."""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.splitlines()[-1])


#: Helpers for the fresh processes: the child processes this one has (from /proc).
CHILDREN = """
import os
def children():
    found = []
    for pid in os.listdir('/proc'):
        if pid.isdigit():
            try:
                stat = open(f'/proc/{pid}/stat').read()
            except OSError:
                continue
            if int(stat.rsplit(')', 1)[1].split()[1]) == os.getpid():
                found.append(int(pid))
    return found
"""


def test_workers_draw_the_bytes_drawn_in_process_and_fall_back_when_they_fail():
    """Four workers forked before the pipeline runs: one draws the plane's scene.png and
    profile.png (the in-process bytes); one killed, one stopped past its time limit, one
    sent a plot that does not exist: each answers None at once or at its limit, and
    is gone after ``close``."""
    found = _python(CHILDREN + f"""
import json, signal, sys
from clsonar import drawing, outputs, pipeline
from clsonar.scene import load_scene
workers = [drawing.start(if_busy=True) for _ in range(4)]
started = [w is not None for w in workers]
forked = sorted(children()) == sorted(w.pid for w in workers)
result = pipeline.run(load_scene({PLANE!r}))
after_opencl = drawing.start(if_busy=True) is None
jobs = outputs.plot_jobs(result)
here = drawing.draw(jobs)
good, killed, stopped, failing = workers
good.submit(jobs)
drawn = good.collect()
os.kill(killed.pid, signal.SIGKILL)
killed.submit(jobs)
os.kill(stopped.pid, signal.SIGSTOP)
drawing.TIME_LIMIT_S = 0.5
stopped.submit(jobs)
failing.submit({{"scene.png": ("no_such_plot", ())}})
answers = [w.collect() for w in (killed, stopped, failing)]
for w in workers:
    w.close()
print(json.dumps({{"started": started, "forked": forked, "after_opencl": after_opencl,
                  "names": list(drawn), "same": drawn == here,
                  "answers": [a is None for a in answers], "left": children()}}))
""")
    assert found["started"] == [True] * 4 and found["forked"]
    assert found["after_opencl"]  # never forked once the OpenCL context exists
    assert found["names"] == ["scene.png", "profile.png"] and found["same"]
    assert found["answers"] == [True, True, True]
    assert found["left"] == []


def test_a_run_with_a_worker_writes_the_in_process_files_and_leaves_no_process(tmp_path):
    """``clsonar run --png all`` interrupted (Ctrl-C in the pipeline: exit 130, no folder),
    then run (its worker drawing the plots); in another process, a run whose worker is
    killed before it is sent the plots (drawn in process): every file the same bytes as
    the API's in-process ones but report.json's seconds and memory, and no child left."""
    out = str(tmp_path)
    found = _python(CHILDREN + f"""
import json, sys
from clsonar import cli, drawing, outputs, pipeline
from clsonar.scene import load_scene
drawing.core_free = lambda: True  # as on an idle machine
started, start = [], drawing.start
drawing.start = lambda **k: started.append(start(**k)) or started[-1]
def interrupted(*a, **k):
    raise KeyboardInterrupt
pipeline.run, run = interrupted, pipeline.run
codes = [cli.main(['run', {PLANE!r}, '--out', {out!r} + '/stopped', '-q'])]
left = [children()]
pipeline.run = run
codes.append(cli.main(['run', {PLANE!r}, '--out', {out!r} + '/worker', '-q']))
left.append(children())
imported = "matplotlib" in sys.modules  # a run draws every picture without it
outputs.write_outputs(run(load_scene({PLANE!r})), {out!r} + '/here')
print(json.dumps({{"codes": codes, "left": left, "imported": imported,
                  "started": [w is not None for w in started]}}))
""")
    killed = _python(CHILDREN + f"""
import json, os, signal
from clsonar import cli, drawing
start = drawing.start
def killed(**k):
    worker = start(if_busy=True)
    os.kill(worker.pid, signal.SIGKILL)
    return worker
drawing.start = killed
code = cli.main(['run', {PLANE!r}, '--out', {out!r} + '/killed', '-q'])
print(json.dumps({{"codes": [code], "left": [children()]}}))
""")
    assert found["started"] == [True, True]  # forked before each run's pipeline
    assert not found["imported"]
    assert found["codes"] + killed["codes"] == [130, 0, 0]
    assert found["left"] + killed["left"] == [[], [], []]
    assert not (tmp_path / "stopped").exists()
    here = {p.name: p.read_bytes() for p in (tmp_path / "here").iterdir()}
    assert sorted(here) == sorted(outputs.OUTPUT_NAMES)
    for run in ("worker", "killed"):
        files = {p.name: p.read_bytes() for p in (tmp_path / run).iterdir()}
        assert sorted(files) == sorted(here)
        for name in here:
            if name != "report.json":
                assert files[name] == here[name], (run, name)
        report, expected = (json.loads(f["report.json"]) for f in (files, here))
        for key in ("seconds", "cost"):
            report.pop(key, None), expected.pop(key, None)
        assert report == expected


def test_bad_input_starts_no_worker(tmp_path, capsys, monkeypatch):
    """A bad scene is one line and exit 2 before any worker starts."""
    monkeypatch.setattr(drawing, "start", lambda **k: pytest.fail("a worker was started"))
    bad = tmp_path / "bad.json"
    bad.write_text('{"clsonar": 1, "extent": [0, 0, 1')
    assert main(["run", str(bad), "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"clsonar: error: {bad}: ")
    assert not (tmp_path / "out").exists()


def test_no_fork_once_pyopencl_is_imported_or_a_thread_runs(monkeypatch):
    """The worker is forked only while no OpenCL context can exist and no Python thread
    runs; on one core, or without fork (macOS's is not safe), the plots are drawn in
    process."""
    import threading

    monkeypatch.setitem(sys.modules, "pyopencl", object())
    assert not drawing.fork_is_safe()
    monkeypatch.delitem(sys.modules, "pyopencl")
    if hasattr(os, "sched_getaffinity") and len(os.sched_getaffinity(0)) >= 2:
        assert drawing.fork_is_safe() == (threading.active_count() == 1)
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
        assert not drawing.fork_is_safe()
    monkeypatch.setattr(sys, "platform", "darwin")
    assert not drawing.fork_is_safe()
    event = threading.Event()
    thread = threading.Thread(target=event.wait)
    thread.start()
    try:
        monkeypatch.setattr(sys, "platform", "linux")
        assert not drawing.fork_is_safe()
    finally:
        event.set()
        thread.join()


def test_the_time_limit_grows_with_the_maps():
    import numpy as np

    jobs = {"profile.png": ("profile_png", (None, np.zeros((2000, 1000), dtype=bool), "t"))}
    assert drawing.time_limit(jobs) == drawing.TIME_LIMIT_S + 2 * drawing.TIME_PER_MEGACELL_S
    assert drawing.time_limit({}) == drawing.TIME_LIMIT_S



class _Worker:
    """A stand-in for a worker process: records what it is sent, answers ``drawn``."""

    plots = True  # it draws (not only the placement)

    def __init__(self, drawn):
        self.sent, self.drawn = [], drawn

    def submit(self, jobs):
        self.sent += list(jobs)

    def collect(self):
        return self.drawn


@pytest.fixture(scope="module")
def plane():
    from clsonar import pipeline
    from clsonar.scene import load_scene

    result = pipeline.run(load_scene(PLANE))
    return result, outputs.stage_pngs(result)


@pytest.mark.parametrize("drawn", [None, {}, {"scene.png": b"from the worker"}])
def test_what_a_worker_does_not_draw_is_drawn_in_process(tmp_path, plane, monkeypatch, drawn):
    """A worker's PNGs are written as it sent them; what it did not draw (it failed:
    None; nothing; one plot) is drawn here; a map larger than MAX_CELLS is never sent."""
    result, expected = plane
    worker = _Worker(drawn)
    outputs.write_outputs(result, tmp_path / "out", worker=worker)
    assert worker.sent == ["scene.png", "profile.png"]
    written = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    assert {**expected, **(drawn or {})} == {n: written[n] for n in expected}
    monkeypatch.setattr(drawing, "MAX_CELLS", result.thin.size - 1)
    worker = _Worker(drawn)
    outputs.write_outputs(result, tmp_path / "large", worker=worker)
    assert worker.sent == ["scene.png"]  # the profile's map is drawn here


def test_the_phases_table_lists_the_worker_apart():
    from clsonar.tools import phases

    rows = phases.table({"a": 0.25, "b": 0.75, "worker: matplotlib import": 0.5}, 1.5)
    assert rows[2:] == ["| a | 0.250 | 25 % |", "| b | 0.750 | 75 % |",
                        "| sum of the phases | 1.000 | |", "| **whole process** | **1.500** | |",
                        "| worker: matplotlib import (another core, during the phases) "
                        "| 0.500 | |"]


def test_a_fork_that_fails_leaves_the_plots_to_this_process(monkeypatch):
    """``os.fork`` failing (too many processes): no worker, the pipes closed, Ctrl-C
    handled here again."""
    import signal

    opened = []
    pipe = os.pipe

    def recorded_pipe():
        opened.extend(pipe())
        return opened[-2:]

    def no_fork():
        raise BlockingIOError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(drawing, "fork_is_safe", lambda: True)
    monkeypatch.setattr(os, "pipe", recorded_pipe)
    monkeypatch.setattr(os, "fork", no_fork)
    handler = signal.getsignal(signal.SIGINT)
    assert drawing.start(if_busy=True) is None
    assert signal.getsignal(signal.SIGINT) is handler
    assert len(opened) == 4
    for fd in opened:
        with pytest.raises(OSError):
            os.fstat(fd)


@pytest.mark.parametrize("loadavg, free", [("0.52 0.40 0.31 1/119 4242\n", True),
                                           ("6.09 5.52 5.35 7/119 4242\n", False),
                                           ("2.00 2.00 2.00 2/119 4242\n", False),
                                           (None, True), ("not a loadavg", True)])
def test_a_worker_starts_only_where_a_core_is_free(tmp_path, monkeypatch, loadavg, free):
    """On a busy machine (as many runnable tasks as cores, this one included) a worker
    would take its time from the run: none is started, unless asked (``if_busy``), and the
    plots are drawn in process."""
    path = tmp_path / "loadavg"
    if loadavg is not None:
        path.write_text(loadavg)
    monkeypatch.setattr(drawing, "LOADAVG", str(path))
    monkeypatch.setattr(drawing, "_cores", lambda: 2)
    assert drawing.core_free() is free
    monkeypatch.setattr(drawing, "fork_is_safe", lambda: True)
    forked = []

    def fork():
        forked.append(1)
        raise OSError("not here")

    monkeypatch.setattr(os, "fork", fork)
    assert drawing.start() is None and len(forked) == (1 if free else 0)
    assert drawing.start(if_busy=True) is None and len(forked) == (2 if free else 1)
