"""Progress inside a stage (clsonar.steps): what the stages' loops report, that a listener
can stop a run there, the detection's launches sized to a time, and the command line's
progress line."""

from __future__ import annotations

import importlib.resources
import io
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from clsonar import pipeline, steps
from clsonar.scene import load_scene
from clsonar.signals import host
from clsonar.tools.progress import Loop, ProgressLine


def _bundled(name: str):
    return load_scene(str(importlib.resources.files("clsonar.scenes") / name))


def test_each_reports_before_every_item_and_after_the_last():
    seen: list[tuple[str, int, int]] = []
    with steps.watching(lambda *a: seen.append(a)):
        assert list(steps.each("loop", "abc")) == ["a", "b", "c"]
    assert seen == [("loop", 0, 3), ("loop", 1, 3), ("loop", 2, 3), ("loop", 3, 3)]
    steps.step("nobody listens", 1, 2)  # outside: nothing, no error


def test_listeners_are_per_thread_and_restored():
    outer: list[int] = []
    inner: list[int] = []
    other: list[int] = []
    with steps.watching(lambda w, d, t: outer.append(d)):
        with steps.watching(lambda w, d, t: inner.append(d)):
            steps.step("x", 1, 9)
            thread = threading.Thread(target=lambda: steps.step("x", 5, 9))
            thread.start()
            thread.join()
        steps.step("x", 2, 9)
    with steps.watching(lambda w, d, t: other.append(d)):
        pass
    assert (outer, inner, other) == ([2], [1], [])


def test_a_run_reports_the_loops_of_its_long_stages(monkeypatch):
    """The echoes' launches, the detection's pairs (one launch each here) and the families'
    patches are reported, each from 0 to its total, inside their stages."""
    monkeypatch.setattr(host, "FIRST_LAUNCH_SLOTS", 1)
    monkeypatch.setattr(host, "launch_size", lambda size, seconds, most: 1)
    log: list[tuple[str, str, int, int]] = []
    stage = [""]

    def on_stage(name, i, n):
        stage[0] = name

    with steps.watching(lambda w, d, t: log.append((stage[0], w, d, t))):
        r = pipeline.run(_bundled("plane-2m.json"), progress=on_stage)
    by_loop: dict[tuple[str, str], list[int]] = {}
    for name, what, done, total in log:
        by_loop.setdefault((name, what), []).append(done)
        assert 0 <= done <= total
    scanned = r.counts["pairs_scanned"]
    assert by_loop[("detection", "pairs")] == list(range(scanned + 1))
    assert by_loop[("echoes", "launches")][-1] >= 1
    assert ("accumulation", "patches") in by_loop
    assert by_loop[("metrics", "echoes' loci")][-1] > 0


def test_a_listener_that_raises_stops_the_run_in_the_stage():
    class Stop(Exception):
        pass

    stages: list[str] = []

    def stop_at_patches(what, done, total):
        if what == "patches":
            raise Stop

    with pytest.raises(Stop), steps.watching(stop_at_patches):
        pipeline.run(_bundled("plane-2m.json"), progress=lambda s, i, n: stages.append(s))
    assert stages[-1] == "accumulation"


@pytest.mark.parametrize(("mode", "loop"), [("arc-transversal-median", "arc-transversal medians"),
                                            ("triangulation", "locus intersections")])
def test_the_arc_maps_report_their_loci_one_by_one_and_stop_there(mode, loop):
    """The arc-transversal median and triangulation cross each locus with the others, a
    loop of minutes on a large array (the zoo's seed 300 wall-01, 300 elements: 19,044
    loci at about 55 a second here): each locus is a step, where a run can be stopped."""
    import dataclasses

    class Stop(Exception):
        pass

    scene = _bundled("plane-2m.json")
    scene = dataclasses.replace(scene, mapping=dataclasses.replace(scene.mapping, mode=mode))
    log: list[tuple[str, int, int]] = []
    with steps.watching(lambda w, d, t: log.append((w, d, t))):
        pipeline.run(scene)
    done = [d for w, d, t in log if w == loop]
    assert done == list(range(len(done))) and len(done) > 1

    def stop_in_loop(what, d, t):
        if what == loop and d == 1:
            raise Stop

    with pytest.raises(Stop), steps.watching(stop_in_loop):
        pipeline.run(scene)


@given(st.integers(1, 10**6), st.floats(0.0, 100.0), st.integers(1, 10**7))
def test_launch_sizes_aim_at_the_launch_time_within_bounds(size, seconds, most):
    n = host.launch_size(size, seconds, most)
    assert 1 <= n <= most
    assert n <= 4 * size and (n >= size // 4 or n == most)
    if 1e-6 < seconds and size * host.LAUNCH_S / seconds < min(size * 4, most) and \
            size * host.LAUNCH_S / seconds > max(size / 4, 1):
        assert n == int(size * host.LAUNCH_S / seconds)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_progress_line_shows_the_loop_and_the_time_left():
    out = _Terminal()
    line = ProgressLine(stream=out)
    line.stage("detection", 3, 9)
    line.step("pairs", 0, 1000)
    line.step("pairs", 1000, 1000)
    text = out.getvalue()
    assert "3/9 detection" in text and "pairs 1,000/1,000, 0 s left" in text


def test_a_loops_time_left_is_its_rate_so_far():
    loop = Loop()
    assert loop.update("pairs", 0, 100, now=10.0) is None
    assert loop.update("pairs", 25, 100, now=11.0) == pytest.approx(3.0)
    assert loop.update("patches", 5, 10, now=12.0) is None  # a new loop starts over
    assert loop.update("patches", 6, 10, now=13.0) == pytest.approx(4.0)


def test_a_poll_is_a_step_with_nothing_to_show():
    seen: list[tuple[str, int, int]] = []
    with steps.watching(lambda *a: seen.append(a)):
        steps.step("patches", 3, 9)
        steps.poll()
    assert seen == [("patches", 3, 9), ("", 0, 0)]
    out = _Terminal()
    line = ProgressLine(stream=out)
    line.step("", 0, 0)
    assert out.getvalue() == ""
