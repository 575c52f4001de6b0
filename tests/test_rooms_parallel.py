"""A floor's rooms mapped in worker processes (clsonar.rooms): the same maps, profile,
metrics and counts as one after another; progress told room by room; a cancel stops the
run and leaves no process behind; a worker's error comes back as the same one line."""

import dataclasses
import os
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

from clsonar import rooms, steps
from clsonar.errors import ClsonarError, DeviceError, SceneError
from clsonar.opencl import get_context
from clsonar.pipeline import STAGES, run
from clsonar.scene import scene_from_dict
from clsonar.tools.floors import floor_scene


def _all_children() -> set[int]:
    found: set[int] = set()
    for task in Path(f"/proc/{os.getpid()}/task").iterdir():
        found |= {int(p) for p in (task / "children").read_text().split()}
    return found


_EARLIER: set[int] = set()


@pytest.fixture(autouse=True)
def _earlier_children():
    """The children earlier tests of the session left (a dask cluster's, a plot worker's
    not yet waited for): not this test's."""
    _EARLIER.clear()
    _EARLIER.update(_all_children())


def _children() -> list[int]:
    """The processes this test started and has not yet waited for."""
    return sorted(_all_children() - _EARLIER)


def _same(a, b) -> None:
    for name in ("raw", "filtered", "occupied", "thin"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and np.array_equal(x, y), name
    assert len(a.profile.curves) == len(b.profile.curves) > 0
    for c, d in zip(a.profile.curves, b.profile.curves, strict=True):
        assert np.array_equal(c, d)
    assert np.array_equal(a.profile.vertices, b.profile.vertices)
    assert a.metrics == b.metrics and a.counts == b.counts and a.warnings == b.warnings
    for table in ("echoes", "detections"):
        for f in dataclasses.fields(getattr(a, table)):
            assert np.array_equal(getattr(getattr(a, table), f.name),
                                  getattr(getattr(b, table), f.name)), (table, f.name)
    assert np.array_equal(a.sensors.poses, b.sensors.poses)
    assert a.seconds.keys() == b.seconds.keys()


def _one_by_one(size_m: float):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(rooms.WORKERS_ENV, "0")
        return run(floor_scene(size_m=size_m))


@pytest.fixture(scope="module")
def one_by_one():
    """The 15 m floor's 9 rooms mapped one after another in this process."""
    return _one_by_one(15.0)


@pytest.fixture(scope="module")
def small():
    """The 10 m floor's 4 rooms, likewise."""
    return _one_by_one(10.0)


def test_workers_map_a_floor_to_the_same_bits_and_tell_each_room(one_by_one, monkeypatch):
    monkeypatch.setenv(rooms.WORKERS_ENV, "2")
    told, stepped = [], []
    with steps.watching(lambda what, done, total: stepped.append((what, done, total))):
        r = run(floor_scene(size_m=15.0), progress=lambda *a: told.append(a))
    _same(one_by_one, r)
    assert r.counts["rooms_mapped"] == 9 and r.metrics["rooms"] == 9
    assert r.metrics["vertices_found"] == one_by_one.metrics["vertices_found"] == "36/36"
    n = len(STAGES)
    assert told[-9:] == [(STAGES[-1], k * n, 9 * n) for k in range(1, 10)]
    assert [s for s in stepped if s[0] == "rooms"] == [("rooms", k, 9) for k in range(1, 10)]
    assert _children() == []


def test_without_processes_the_rooms_are_mapped_here_the_same(small, monkeypatch):
    monkeypatch.setenv(rooms.WORKERS_ENV, "2")

    def refused(*args, **kwargs):
        raise OSError(11, "Resource temporarily unavailable")

    monkeypatch.setattr(subprocess, "Popen", refused)  # rooms.Workers imports it to start
    _same(small, run(floor_scene(size_m=10.0)))


class Cancelled(Exception):
    pass


def test_a_cancel_stops_a_floor_in_workers_and_leaves_no_process(monkeypatch):
    monkeypatch.setenv(rooms.WORKERS_ENV, "2")
    seen = []

    def listener(what: str, done: int, total: int) -> None:
        seen.append(what)
        if what == "rooms" and done >= 2:
            raise Cancelled

    with steps.watching(listener), pytest.raises(Cancelled):
        run(floor_scene(size_m=10.0))
    assert seen.count("rooms") == 2
    assert _children() == []


def test_a_workers_error_comes_back_as_the_same_one_line():
    with pytest.raises(SceneError) as here:
        scene_from_dict({}, "bad.json")
    with rooms.Workers(2, dict) as pool, pytest.raises(SceneError) as there:
        list(pool.map(scene_from_dict, ["bad.json"]))
    assert str(there.value) == str(here.value) and "\n" not in str(there.value)
    assert (there.value.key, there.value.source) == (here.value.key, here.value.source)
    assert _children() == []
    with pytest.raises(DeviceError, match="no OpenCL platform 99") as e:
        with rooms.Workers(1, get_context, "99:0") as pool:
            list(pool.map(len, ["abc"]))
    assert "\n" not in str(e.value)
    assert _children() == []


def test_workers_hand_results_over_in_order():
    with rooms.Workers(2, str, "-") as pool:
        assert list(pool.map(str.join, [["a", "b"], ["c"], ["d", "e", "f"]] * 3)) == [
            "a-b", "c", "d-e-f"] * 3
    assert _children() == []


def test_how_many_workers(monkeypatch):
    monkeypatch.delenv(rooms.WORKERS_ENV, raising=False)
    assert rooms.worker_count(rooms.MIN_ROOMS - 1) == 0
    assert 1 <= rooms.worker_count(400) <= rooms.MAX_WORKERS
    assert rooms.worker_count(2 * rooms.MIN_ROOMS) <= len(os.sched_getaffinity(0))
    monkeypatch.setenv(rooms.WORKERS_ENV, "3")
    assert (rooms.worker_count(2), rooms.worker_count(400)) == (2, 3)
    monkeypatch.setenv(rooms.WORKERS_ENV, "many")
    with pytest.raises(ClsonarError, match="CLSONAR_ROOM_WORKERS='many'"):
        rooms.worker_count(400)


def test_the_device_is_named_for_the_workers():
    ctx = get_context()
    assert get_context(rooms.device_spec(ctx)) is ctx


class _Odd(Exception):
    """An error that cannot be pickled: it holds a lock (its constructor also needs two
    values, which a pickle of its one message cannot give again — unless, as in the whole
    suite after dask's tblib is installed, exceptions pickle by their attributes)."""

    def __init__(self, a: int, b: int) -> None:
        super().__init__(f"odd {a} {b}")
        self.lock = threading.Lock()


def test_an_error_that_cannot_be_pickled_comes_back_as_its_type_and_one_line():
    try:
        raise _Odd(1, 2)
    except _Odd as error:
        back = rooms._rebuilt(rooms._portable(error))
    assert isinstance(back, RuntimeError) and str(back) == "_Odd: odd 1 2"
    assert "raise _Odd(1, 2)" in str(back.__cause__)
    scene_error = SceneError("must be > 0", "surfaces[2].radius", "room.json")
    back = rooms._rebuilt(rooms._portable(scene_error))
    assert type(back) is SceneError and str(back) == "room.json: surfaces[2].radius: must be > 0"


def test_the_floor_tool_reports_its_workers_and_their_memory(small, one_by_one, monkeypatch):
    from clsonar.tools.floors import result_digest, run_floor

    monkeypatch.setenv(rooms.WORKERS_ENV, "2")
    row = run_floor(10.0, digest=True)
    assert row.digest == result_digest(small) and len(row.digest) == 64
    assert result_digest(one_by_one) != row.digest
    assert (row.rooms, row.workers, row.vertices_found) == (4, 2, "16/16")
    assert row.accuracy_m == small.metrics["accuracy_m"]["rms"]
    assert 0 < row.workers_peak_rss_mb and 0 < row.wall_s
    assert row.total_s == sum(row.seconds.values())


def test_rooms_added_by_their_non_zero_cells_make_the_dense_sums_bit_for_bit():
    """rooms.add_to_mosaic of sparse_maps against adding the dense maps: overlapping
    rooms, float64 filtered values into the float32 mosaic, zeros of both signs."""
    rng = np.random.default_rng(3)
    dense, sparse = rooms.empty_mosaic((40, 50)), rooms.empty_mosaic((40, 50))
    for row0, col0 in [(0, 0), (5, 7), (20, 30), (3, 2), (0, 0)]:
        ny, nx = 20, 20
        keep = rng.random((ny, nx)) < 0.3
        filtered = np.where(keep, rng.normal(0, 1e3, (ny, nx)), rng.choice([0.0, -0.0], (ny, nx)))
        room = type("Room", (), {
            "raw": np.where(keep, rng.random((ny, nx)), 0).astype(np.float32),
            "filtered": filtered, "occupied": keep & (rng.random((ny, nx)) < 0.5),
            "thin": keep & (rng.random((ny, nx)) < 0.2)})
        window = (slice(row0, row0 + ny), slice(col0, col0 + nx))
        dense["raw"][window] += room.raw
        dense["filtered"][window] += room.filtered
        dense["occupied"][window] |= room.occupied
        dense["thin"][window] |= room.thin
        found = rooms.sparse_maps(room)
        assert found[0] == (ny, nx) and len(found[1][1][0]) == np.count_nonzero(filtered)
        rooms.add_to_mosaic(sparse, found, row0, col0)
    for name in rooms.MAPS:
        assert dense[name].dtype == sparse[name].dtype
        assert dense[name].tobytes() == sparse[name].tobytes(), name


def test_a_worker_that_dies_is_one_line_naming_the_way_round():
    import signal

    with pytest.raises(ClsonarError) as e, rooms.Workers(1, os.getpid) as pool:
        list(pool.map(os.kill, [signal.SIGKILL]))  # the worker kills itself
    assert str(e.value) == ("a worker process mapping rooms stopped (exit status -9); set "
                            "CLSONAR_ROOM_WORKERS=0 to map them in one process")
    assert _children() == []
