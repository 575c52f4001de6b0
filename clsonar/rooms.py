"""The rooms of a floor mapped in worker processes side by side, and put back together
(issue 16: the 100 m floor faster within the same memory).

A scene of separate closed rooms is mapped room by room (:mod:`clsonar.regions`); each
room's stages are host NumPy between OpenCL kernels, so one process keeps about one core
busy. :class:`Workers` maps the rooms in ``n`` worker processes (:func:`worker_count`), each
with its own OpenCL context on the parent's device (:func:`device_spec`; compiled programs
come from the disk cache), while the parent keeps the mosaic (:func:`add_to_mosaic`: a
room's maps come back by their non-zero cells, :func:`sparse_maps`) and
puts the rooms' transducers, echoes, detections and profiles side by side
(:func:`side_by_side`).

A worker is a fresh Python interpreter (``python -c``) that imports this package — not a
``fork`` of the parent, which holds a PoCL context and its threads that a forked child
would inherit broken, and not multiprocessing's ``spawn``, which imports the caller's main
script again. Jobs go out and results come back pickled through the worker's standard
input and output. :meth:`Workers.map` hands the results over in the order of the jobs, so
the mosaic is added up in the order of a single loop and every map, profile, metric and
count is the same bit for bit. While it waits it polls :func:`clsonar.steps.poll` (the
GUI's Cancel); closing the pool after an error or a cancel kills every worker, and a
worker's error comes back as the same exception with the same one line.
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import signal
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from . import post, steps
from .echoes import EchoTable
from .errors import ClsonarError, SceneError
from .sensors import SensorArray
from .signals import Detections

if TYPE_CHECKING:  # imported where workers start: a room's run does without them (8 ms)
    import subprocess
    from multiprocessing.connection import Connection

T = TypeVar("T")

#: Host memory the mosaic of a scene mapped room by room holds per cell: raw and filtered
#: maps (float32), the occupied and thin maps.
MOSAIC_BYTES_PER_CELL = 10

#: Environment variable: how many worker processes map a floor's rooms (0 or 1: the rooms
#: one after another in the calling process); unset: :func:`worker_count` chooses.
WORKERS_ENV = "CLSONAR_ROOM_WORKERS"

#: Host memory set aside per worker process (interpreter, NumPy, the OpenCL runtime and
#: one room's stages: a peak RSS of 190 MB measured on the 100 m floor's 5 m rooms, 110 MB
#: of it before any room; much of the runtime's is shared libraries).
WORKER_BYTES = 400 * 2**20

#: At most this many workers, whatever the cores: each holds its own runtime.
MAX_WORKERS = 8

#: Fewer rooms than this are mapped in the calling process (a worker's start costs more
#: than a few rooms).
MIN_ROOMS = 8

#: Seconds between two polls for a cancel while the workers map.
POLL_S = 0.05


def worker_count(rooms: int) -> int:
    """How many worker processes map ``rooms`` rooms: :data:`WORKERS_ENV` when set, else
    one per core this process may run on, at most :data:`MAX_WORKERS`, one per
    :data:`WORKER_BYTES` of half the memory available, and none below :data:`MIN_ROOMS`
    rooms or off POSIX. Below 2 the rooms are mapped in the calling process."""
    asked = os.environ.get(WORKERS_ENV, "").strip()
    if os.name != "posix":  # a worker's pipes are read as file descriptors
        return 0
    if asked:
        try:
            return max(0, min(int(asked), rooms))
        except ValueError:
            raise ClsonarError(f"{WORKERS_ENV}={asked!r}: must be a whole number") from None
    if rooms < MIN_ROOMS:
        return 0
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
        os.cpu_count() or 1)
    return max(0, min(cores, MAX_WORKERS, rooms, _available_bytes() // 2 // WORKER_BYTES))


def _available_bytes() -> int:
    """The host memory still available (``MemAvailable``; without /proc, as if plenty)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return MAX_WORKERS * WORKER_BYTES * 2


def device_spec(ctx) -> str | None:
    """``"P:D"`` (:func:`clsonar.opencl.choose_device`) of the device of context ``ctx``,
    for a worker to open its own context on; None when it is not among the platforms'."""
    import pyopencl as cl

    wanted = ctx.devices[0]
    for pi, platform in enumerate(cl.get_platforms()):
        for di, device in enumerate(platform.get_devices()):
            if device == wanted:
                return f"{pi}:{di}"
    return None


# ---- the parent's side


_BOOT = ("import sys; sys.path.insert(0, sys.argv[1]); "
         "from clsonar.rooms import serve; serve()")


class Workers:
    """``n`` worker processes, each holding ``init(*args)`` (an OpenCL context) for the
    jobs :meth:`map` gives it. Closed by :meth:`close` (or leaving a ``with`` block,
    whether by the end, an error or a cancel): every worker is killed."""

    def __init__(self, n: int, init: Callable[..., Any], *args: object) -> None:
        import subprocess
        from multiprocessing.connection import Connection

        root = str(Path(__file__).resolve().parents[1])
        self.procs: list[subprocess.Popen] = []
        self.conns: list[tuple[Connection, Connection]] = []
        self.starting = set(range(n))  # the workers whose ``init`` has not answered yet
        try:
            for _ in range(n):
                proc = subprocess.Popen([sys.executable, "-c", _BOOT, root],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE)
                self.procs.append(proc)
                assert proc.stdin is not None and proc.stdout is not None
                self.conns.append((Connection(os.dup(proc.stdin.fileno()), readable=False),
                                   Connection(os.dup(proc.stdout.fileno()), writable=False)))
                proc.stdin.close()
                proc.stdout.close()
                self.conns[-1][0].send((init, args))  # the worker's reply: ready or why not
        except BaseException:
            self.close()
            raise

    def __len__(self) -> int:
        return len(self.procs)

    def __enter__(self) -> Workers:
        return self

    def __exit__(self, kind, error, tb) -> None:
        self.close()

    def map(self, job: Callable[..., Any], items: Sequence[object],
            ahead: int = 2) -> Iterator[Any]:
        """``job(state, item)`` of each of ``items`` in the workers (``state``: the
        worker's ``init(*args)``), the results in the order of ``items``; at most
        ``ahead`` results per worker wait to be handed over. A worker's error is raised
        here when its item's turn comes; :func:`clsonar.steps.poll` is called while
        waiting."""
        from multiprocessing.connection import wait

        busy: dict[int, int | None] = dict.fromkeys(self.starting)  # None: init
        free = [w for w in range(len(self.conns)) if w not in self.starting]
        found: dict[int, Any] = {}
        sent = handed = 0
        while handed < len(items):
            while free and sent < len(items) and sent - handed < ahead * len(self.conns):
                w = free.pop()
                self.conns[w][0].send((job, (items[sent],)))
                busy[w], sent = sent, sent + 1
            if handed in found:
                ok, value = found.pop(handed)
                if not ok:  # raised in the order of the items: the first item's error
                    raise _rebuilt(value)
                yield value
                handed += 1
                continue
            inboxes = {self.conns[w][1]: w for w in busy}
            for inbox in wait(list(inboxes), timeout=POLL_S):
                w = inboxes[inbox]  # type: ignore[index]
                k, reply = busy.pop(w), self._receive(w)
                if k is not None:
                    found[k] = reply
                elif not reply[0]:
                    raise _rebuilt(reply[1])  # the worker could not start
                self.starting.discard(w)
                free.append(w)
            steps.poll()

    def _receive(self, w: int) -> tuple[bool, Any]:
        """Worker ``w``'s reply: ``(True, value)`` or ``(False, what its error was)``."""
        try:
            return self.conns[w][1].recv()
        except (EOFError, OSError):
            code = self.procs[w].wait()
            raise ClsonarError(f"a worker process mapping rooms stopped (exit status {code}); "
                               f"set {WORKERS_ENV}=0 to map them in one process") from None

    def close(self) -> None:
        """End every worker: killed (an idle one holds nothing to keep, and one stopped in
        the middle of a room, by a cancel or an error, must not go on), then waited for."""
        for outbox, inbox in self.conns:
            outbox.close()
            inbox.close()
        for proc in self.procs:
            proc.kill()
        for proc in self.procs:
            proc.wait()
        self.procs, self.conns = [], []


def split(items: Sequence[T], parts: int) -> list[Sequence[T]]:
    """``items`` in ``parts`` runs one after another, their lengths within one of each
    other (the first ones the shorter)."""
    n = len(items)
    return [items[k * n // parts:(k + 1) * n // parts] for k in range(parts)]


# ---- the worker's side


def serve() -> None:
    """A worker's loop: read ``(init, args)`` and keep ``init(*args)``, then answer each
    ``(job, (item,))`` with ``job(state, item)`` until the parent closes the pipe (or is
    gone); each reply is ``(True, value)`` or ``(False, error)``."""
    from multiprocessing.connection import Connection

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C: the parent decides
    inbox = Connection(os.dup(0), writable=False)
    outbox = Connection(os.dup(1), readable=False)
    os.dup2(2, 1)  # what anything prints goes to stderr, not into the replies
    state: object = None
    started = False
    while True:
        try:
            fn, args = inbox.recv()
        except (EOFError, OSError):
            return
        reply: tuple[bool, object]
        try:
            if started:  # a job
                reply = (True, fn(state, *args))
            else:  # the first message: what every job gets (an OpenCL context)
                state, reply = fn(*args), (True, None)
        except BaseException as error:
            reply = (False, _portable(error))
        started = True
        try:
            outbox.send(reply)
        except OSError:  # the parent is gone
            return


def _portable(error: BaseException) -> object:
    """What the parent needs to raise ``error`` again with the same one line: a
    :class:`SceneError`'s parts (its pickle would lose them), the error itself when it
    pickles to the same type and text, else its type's name and text (and traceback)."""
    if isinstance(error, SceneError):
        return ("SceneError", type(error), error.message, error.key, error.source)
    try:
        copy = pickle.loads(pickle.dumps(error))
        if type(copy) is type(error) and str(copy) == str(error):
            return error
    except Exception:
        pass
    return ("other", type(error).__name__, str(error),
            "".join(traceback.format_exception(error)))


def _rebuilt(found: object) -> BaseException:
    """The error :func:`_portable` sent, to be raised in the parent."""
    if isinstance(found, BaseException):
        return found
    assert isinstance(found, tuple)
    if found[0] == "SceneError":
        return found[1](found[2], found[3], found[4])
    error = RuntimeError(f"{found[1]}: {found[2]}")
    error.__cause__ = WorkerTraceback(found[3])  # shown under the parent's traceback
    return error


class WorkerTraceback(Exception):
    """The traceback of an error in a worker process whose own type could not come back
    (the cause of the error raised in the parent)."""


# ---- the mosaic


def empty_mosaic(shape: tuple[int, int]) -> dict[str, np.ndarray]:
    """The maps of a scene mapped room by room, all zero (:data:`MOSAIC_BYTES_PER_CELL`)."""
    return {"raw": np.zeros(shape, np.float32), "filtered": np.zeros(shape, np.float32),
            "occupied": np.zeros(shape, bool), "thin": np.zeros(shape, bool)}


#: The maps of a room result, in the order :func:`sparse_maps` gives them.
MAPS = ("raw", "filtered", "occupied", "thin")

#: A room's maps as :func:`sparse_maps` gives them: the grid's shape, and for each map the
#: flat indices of its non-zero cells and their values.
Sparse = tuple[tuple[int, int], list[tuple[np.ndarray, np.ndarray]]]


def sparse_maps(r: Any) -> Sparse:
    """The maps of room result ``r`` (:data:`MAPS`) by their non-zero cells only (2–3 % of a
    room's cells: what a worker sends back, a tenth of the dense maps' bytes)."""
    parts = []
    for name in MAPS:
        a = getattr(r, name)
        cells = np.flatnonzero(a)
        parts.append((cells, a.reshape(-1)[cells]))
    return r.raw.shape, parts


def add_to_mosaic(maps: dict[str, np.ndarray], found: Sparse, row0: int, col0: int) -> None:
    """Add a room's maps (:func:`sparse_maps`) into the scene's ``maps`` where the room's
    grid sits (from ``row0``, ``col0``): votes and filtered values added, occupied and thin
    cells or-ed, cell by cell as the dense maps would be (``m + v`` in the type NumPy
    gives a map and a room's values, stored in the map's). Only the non-zero cells: adding
    ±0 leaves every mosaic cell as it is (no cell is ever −0: it starts at +0, and +0 + −0
    and x + (−x) are +0), and or-ing False leaves it as it is."""
    (_, nx), parts = found
    for name, (cells, values) in zip(MAPS, parts, strict=True):
        rows, cols = np.divmod(cells, nx)
        where = (rows + row0, cols + col0)
        if values.dtype == np.bool_:
            maps[name][where] |= values
        else:
            maps[name][where] += values


def without_maps(r: Any) -> Any:
    """Room result ``r`` without its maps and votes, once they are in the mosaic: what
    :func:`side_by_side` and the pooled metrics read is kept."""
    empty = np.zeros((0, 0))
    return dataclasses.replace(r, votes=None, raw=empty, filtered=empty,
                               occupied=empty.astype(bool), thin=empty.astype(bool),
                               point_sums=None, point_window=None)


def side_by_side(parts: list[Any]) -> tuple[SensorArray, EchoTable, Detections, post.Profile]:
    """The rooms' transducers, echoes, detections and profiles one after another (indices
    of transducers and groups moved on by the rooms before)."""
    sensors = SensorArray(
        positions=np.concatenate([p.sensors.positions for p in parts]),
        headings_deg=np.concatenate([p.sensors.headings_deg for p in parts]),
        groups=np.concatenate(_offset_groups([p.sensors.groups for p in parts])),
        poses=np.concatenate([p.sensors.poses for p in parts]))
    first = np.cumsum([0] + [len(p.sensors) for p in parts])
    return (sensors, EchoTable(**_stack([p.echoes for p in parts], first, EchoTable)),
            Detections(**_stack([p.detections for p in parts], first, Detections)),
            post.Profile(tuple(c for p in parts for c in p.profile.curves),
                         np.concatenate([p.profile.vertices for p in parts])))


def _offset_groups(groups: list[np.ndarray]) -> list[np.ndarray]:
    out, first = [], 0
    for g in groups:
        out.append(g + first)
        first += int(g.max()) + 1 if len(g) else 0
    return out


def _stack(tables: list, first: np.ndarray, kind) -> dict[str, np.ndarray]:
    """The columns of ``tables`` (echo tables or detections) one after another, their
    ``tx``/``rx`` moved by each room's first transducer index ``first``."""
    columns = {}
    for f in dataclasses.fields(kind):
        parts = [getattr(t, f.name) + (first[i] if f.name in ("tx", "rx") else 0)
                 for i, t in enumerate(tables)]
        columns[f.name] = np.concatenate(parts) if parts else np.zeros(0)
    return columns


__all__ = ["MAPS", "MAX_WORKERS", "MIN_ROOMS", "MOSAIC_BYTES_PER_CELL", "WORKERS_ENV",
           "WORKER_BYTES", "Sparse", "Workers", "add_to_mosaic", "device_spec", "empty_mosaic",
           "serve", "side_by_side", "sparse_maps", "split", "without_maps", "worker_count"]
