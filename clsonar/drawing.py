"""The run's work that needs no OpenCL done on another core while the pipeline runs
(issue 16): the placement, scene.png and profile.png.

The pipeline leaves the second core mostly idle. :func:`start` forks a worker process
before the OpenCL context exists: it places the transducers (its ``first`` job, while the
main process imports pyopencl and sets up the device, :meth:`PlotWorker.first`), then
draws the plots as it is sent them
(:meth:`PlotWorker.submit`: scene.png once the pipeline has the echoes,
:class:`clsonar.outputs.EarlyPlots`; profile.png while the main process builds the data
files and the map pictures), and sends back their PNG bytes (:meth:`PlotWorker.collect`),
which the main process writes with every other file, as one folder.

Where there are no plots to draw (``--png none`` or ``stages``), the worker computes each
function it is sent after its ``first`` job, the truth the metrics score against
(:meth:`PlotWorker.call`, :meth:`PlotWorker.value`); the same code on a copy of the same
process, its answers pickled back: the same bits.

A plot is a :data:`Job`: the name of a :mod:`clsonar.pictures` function and its
arguments, drawn by :func:`draw` in either process, so the worker's bytes are the
in-process ones (the pictures depend only on their inputs, which are pickled exactly).

When no worker can help, none is started and the caller draws in process as before: where
no core is free at the start (:func:`core_free`: on a busy machine a worker takes its time
from the run); where ``fork`` is not the platform's safe start method (Windows; macOS,
whose system libraries are not fork-safe; spawning a fresh interpreter would import numpy
and clsonar again); on one core; once pyopencl is imported or a Python
thread runs (an OpenCL context starts PoCL's threads: a fork after it could copy a held
lock). A worker that fails, dies or is silent past its time limit is stopped, and
``collect`` answers None: the caller draws in process. The worker never outlives its
command: it is killed by :meth:`PlotWorker.close` (every exit path, as a context manager),
exits on its own when the main process's end of the pipe closes (even after ``kill -9``),
and ignores Ctrl-C, which the main process handles.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import struct
import sys
import time
import warnings
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .scene import Scene
    from .skips import Skips

#: One plot to draw: the name of a :mod:`clsonar.pictures` function and its arguments.
Job = tuple[str, tuple[Any, ...]]

#: Seconds the worker is given to place the transducers and draw, plus this many per million
#: map cells of the largest picture (a floor's profile.png resamples its thin map).
TIME_LIMIT_S = 60.0
TIME_PER_MEGACELL_S = 1.0

_HEADER = struct.Struct("<Q")


def draw(jobs: Mapping[str, Job]) -> dict[str, bytes]:
    """Each job's PNG bytes, drawn in this process, by file name."""
    if not jobs:
        return {}
    from . import pictures

    return {name: getattr(pictures, function)(*args)
            for name, (function, args) in jobs.items()}


#: The largest map a worker is sent (cells; a 50 m square at 1 cm): a larger one is drawn
#: in process, not copied to a second process that would hold it (and the picture's
#: working copies) beside the run's own maps.
MAX_CELLS = 25_000_000


def cells(jobs: Mapping[str, Job]) -> int:
    """The cells (array elements) of every map among the jobs' arguments."""
    import numpy as np

    return sum(a.size for _, args in jobs.values() for a in args if isinstance(a, np.ndarray))


def time_limit(jobs: Mapping[str, Job]) -> float:
    """How long to wait for ``jobs`` (:data:`TIME_LIMIT_S`, more for larger maps)."""
    return TIME_LIMIT_S + TIME_PER_MEGACELL_S * cells(jobs) / 1e6


def _cores() -> int:
    """The cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def fork_is_safe() -> bool:
    """Whether this process may fork a worker now: a platform whose ``fork`` is safe, two
    cores or more for it, no OpenCL context yet (pyopencl not even imported: PoCL starts
    its threads with the first context) and no thread started by Python. numpy's BLAS
    starts threads at import; OpenBLAS and MKL stop and restart them around a fork."""
    if not hasattr(os, "fork") or sys.platform == "darwin" or "pyopencl" in sys.modules:
        return False
    if _cores() < 2:
        return False
    threading = sys.modules.get("threading")
    return threading is None or threading.active_count() == 1


#: Where Linux says how many tasks are runnable now (``/proc/loadavg``'s fourth field).
LOADAVG = "/proc/loadavg"


def core_free() -> bool:
    """Whether a core has nothing else to run at this moment: fewer runnable tasks on the
    machine, this process included, than cores (:data:`LOADAVG`; True where it cannot be
    read). On a busy machine Linux shares a command's CPU time between its processes: a
    worker would take its time from the run instead of an idle core (docs/speed.md)."""
    try:
        with open(LOADAVG, encoding="ascii") as f:
            running = int(f.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return True
    return running < _cores()


def start(*, if_busy: bool = False, plots: bool = True,
          first: Callable[[], object] | None = None) -> PlotWorker | None:
    """A worker process drawing the plots (``plots``: :mod:`clsonar.pictures` imported),
    or None where none can help (:func:`fork_is_safe`, a core free now unless
    ``if_busy``: :func:`core_free`). ``first``: a job the worker runs before anything else,
    on its copy of this process (the fork's), whose value :meth:`PlotWorker.first` answers
    (pickled back): the run's placement while this process sets up the device."""
    if not fork_is_safe() or not (if_busy or core_free()):
        return None
    if not plots and first is None:
        return None
    jobs_r, jobs_w = os.pipe()
    done_r, done_w = os.pipe()
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)  # the child ignores Ctrl-C
    pid = -1
    try:
        with warnings.catch_warnings():  # Python 3.12+ warns of any thread, BLAS's too
            warnings.filterwarnings("ignore", "This process .* is multi-threaded",
                                    DeprecationWarning)
            pid = os.fork()
        if pid == 0:  # pragma: no cover - the child (its coverage is not collected)
            os.close(jobs_w)
            os.close(done_r)
            _serve(jobs_r, done_w, plots, first)
    except OSError:  # no fork: drawn in process
        for fd in (jobs_r, jobs_w, done_r, done_w):
            os.close(fd)
        return None
    finally:
        if pid != 0:
            signal.signal(signal.SIGINT, handler)
    os.close(jobs_r)
    os.close(done_w)
    os.set_blocking(jobs_w, False)  # a send waits no longer than the time limit
    return PlotWorker(pid, jobs_w, done_r, plots=plots, first=first is not None)


def run_worker(png: str, scene: Scene, preset: str | None, skips: Skips, *,
               if_busy: bool = False) -> PlotWorker | None:
    """The worker of one ``clsonar run`` of ``scene``, where one can help (a core free now,
    unless ``if_busy``): it places the transducers (the sensors stage,
    :func:`clsonar.placing.placement`: ``pipeline.run``'s ``placement`` is its
    :meth:`PlotWorker.first`) while this process imports the pipeline and pyopencl and
    sets up the device; then, where ``png`` asks for scene.png and profile.png, draws them
    (``plots``), else scores the truth the metrics read. Start it as soon as the scene is
    read — the worker imports only what placing needs, this process the rest meanwhile —
    and close it on every exit path (a context manager)."""

    def first() -> object:
        from .placing import placement  # in the worker: a tenth of the pipeline's imports

        return placement(scene, preset, skips)

    return start(if_busy=if_busy, plots=png == "all", first=first)


def _serve(jobs_fd: int, done_fd: int, with_plots: bool = True,
           first: Callable[[], object] | None = None
           ) -> None:  # pragma: no cover - runs in the child
    """The worker: run ``first`` and send its value (None where it raised: the main
    process then runs it itself, and meets the error there); with ``with_plots``, import
    the plots and say so (with the seconds it took). Then, until the main process closes
    the pipe, answer each ``call`` it is sent (a function and its arguments,
    :meth:`PlotWorker.call`) with the function's value (None where it raised), draw each
    batch of jobs it is sent as it comes, and on ``collect`` send every PNG drawn since the
    last one (a send only when asked: the main process never waits on a full pipe while it
    sends). Then exit, whatever happens (``os._exit``: none of the parent's clean-up runs
    twice)."""
    code = 0
    try:
        if first is not None:
            start = time.perf_counter()
            try:
                value = first()
            except Exception:  # raised again by the main process's own run
                value = None
            _send(done_fd, ("first", value, time.perf_counter() - start))
        if with_plots:
            start = time.perf_counter()
            try:
                from . import pictures  # noqa: F401
            except Exception as e:
                _send(done_fd, ("error", f"{type(e).__name__}: {e}"))
                return
            _send(done_fd, ("ready", time.perf_counter() - start))
        drawn: dict[str, bytes] = {}
        seconds: dict[str, float] = {}
        failed = ""
        while (message := _receive(jobs_fd, None)) is not None:
            what, jobs = message
            if what == "call":
                start = time.perf_counter()
                try:
                    function, args = jobs
                    value = function(*args)
                except Exception:  # computed again by the main process
                    value = None
                _send(done_fd, ("value", value, time.perf_counter() - start))
                continue
            if what == "collect":
                _send(done_fd, ("error", failed) if failed else ("done", drawn, seconds))
                drawn, seconds, failed = {}, {}, ""
                continue
            for name, job in jobs.items():
                start = time.perf_counter()
                try:
                    drawn.update(draw({name: job}))
                except Exception as e:
                    failed = failed or f"{name}: {type(e).__name__}: {e}"
                seconds[name] = time.perf_counter() - start
    except BaseException:  # a closed pipe, anything: the main process draws
        code = 1
    finally:
        os._exit(code)


def _send(fd: int, message: object, deadline: float | None = None) -> bool:
    """Send ``message`` on ``fd`` (non-blocking where ``deadline`` is given); False past
    ``deadline``."""
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_HEADER.pack(len(data)) + data)
    while view:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([], [fd], [], left)[1]:
                return False
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            pass
    return True


def _read(fd: int, size: int, deadline: float | None) -> bytes | None:
    """``size`` bytes from ``fd``, or None at its end or past ``deadline``."""
    parts: list[bytes] = []
    while size:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return None
        part = os.read(fd, min(size, 1 << 20))
        if not part:
            return None
        parts.append(part)
        size -= len(part)
    return b"".join(parts)


def _receive(fd: int, deadline: float | None) -> Any:
    """The next message on ``fd``; None at its end or past ``deadline``."""
    header = _read(fd, _HEADER.size, deadline)
    if header is None:
        return None
    data = _read(fd, _HEADER.unpack(header)[0], deadline)
    return None if data is None else pickle.loads(data)


def _same(a: object, b: object) -> bool:
    """Whether two jobs' arguments are the same: the same arrays, equal other values."""
    if a is b:
        return True
    if type(a) is not type(b) or type(a).__module__ == "numpy":
        return False
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(map(_same, a, b))
    try:
        return bool(a == b)
    except ValueError:  # a value holding arrays
        return False


class PlotWorker:
    """The main process's side of a worker (:func:`start`); a context manager that closes
    it. ``seconds``: the worker's own, importing the plots and drawing each PNG."""

    def __init__(self, pid: int, jobs_fd: int, done_fd: int, *, plots: bool = True,
                 first: bool = False) -> None:
        self.pid = pid
        self.plots = plots
        self._jobs_fd: int | None = jobs_fd
        self._done_fd: int | None = done_fd
        self._ready = False
        self._first: tuple[object] | None = None if first else (None,)
        self._calls: list[str] = []  # the functions sent to the worker, not yet answered
        self._values: list[object] = []
        self._held: list[tuple[str, Mapping[str, Job] | None]] = []
        self._sent: dict[str, Job] = {}
        self._deadline = 0.0
        self.seconds: dict[str, float] = {}

    def __enter__(self) -> PlotWorker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _take(self, deadline: float | None) -> bool:
        """Read the worker's next message (``first``'s value, or that the plots are
        imported), waiting until ``deadline`` (None: not at all); False where none came,
        or it failed (then stopped)."""
        if self._done_fd is None:
            return False
        wait = 0.0 if deadline is None else max(0.0, deadline - time.monotonic())
        if not select.select([self._done_fd], [], [], wait)[0]:
            return False
        message = _receive(self._done_fd, time.monotonic() + 5.0)
        if isinstance(message, tuple) and message[0] == "first" and self._first is None:
            self._first = (message[1],)
            self.seconds["first job"] = message[2]
        elif isinstance(message, tuple) and message[0] == "ready" and self.plots:
            self._ready = True
            self.seconds["pictures import"] = message[1]
        elif isinstance(message, tuple) and message[0] == "value" and self._calls:
            self._values.append(message[1])
            self.seconds[self._calls[len(self._values) - 1]] = message[2]
        else:
            self.close()
            return False
        return True

    def _check_ready(self, deadline: float | None) -> bool:
        """Whether the worker has imported the plots (waiting until ``deadline``; None:
        not at all); False for good once it failed."""
        while not self._ready and self._take(deadline):
            pass
        return self._ready

    def first(self, limit: float = TIME_LIMIT_S) -> Any:
        """The value of the worker's ``first`` job (waiting for it, ``limit`` seconds at
        most); None where it raised, or the worker failed, died or ran past the limit
        (then stopped). A worker without plots whose answer is None has nothing left to
        do: it is stopped too (a floor's rooms are placed apart, in the run)."""
        deadline = time.monotonic() + limit
        while self._first is None and self._take(deadline):
            pass
        if self._first is None or (self._first[0] is None and not self.plots):
            self.close()
            return None
        return self._first[0]

    def call(self, function: Callable[..., object], *args: object) -> bool:
        """Have a worker without plots compute ``function(*args)`` (a module's function:
        pickled by name, with its arguments), answered by :meth:`value`, while this process
        goes on; False where it cannot be sent (a worker that draws, or stopped). Not
        beside plots: its value, sent when computed, could fill the pipe while this process
        sends a plot's job (both would wait, until the time limit)."""
        if self.plots or self._jobs_fd is None:
            return False
        self._calls.append(f"{function.__module__}.{function.__qualname__}")
        try:
            sent = _send(self._jobs_fd, ("call", (function, args)),
                         time.monotonic() + TIME_LIMIT_S)
        except (OSError, pickle.PicklingError):
            sent = False
        if not sent:
            self.close()
        return sent

    def value(self, limit: float = TIME_LIMIT_S) -> Any:
        """The value of the oldest :meth:`call` not yet answered (waiting for it,
        ``limit`` seconds at most); None where it raised, or the worker failed, died or
        ran past the limit (then stopped)."""
        deadline = time.monotonic() + limit
        while not self._values and self._take(deadline):
            pass
        if not self._values:
            self.close()
            return None
        self._calls.pop(0)
        return self._values.pop(0)

    def submit(self, jobs: Mapping[str, Job]) -> None:
        """Have the worker draw ``jobs`` but those it was already sent with the same
        arguments (:meth:`collect` answers them all): sent now if it is ready for them,
        else by :meth:`collect` (a send to a busy worker would wait for it)."""
        new = {name: job for name, job in jobs.items()
               if name not in self._sent or not _same(job, self._sent[name])}
        if new:
            self._sent.update(new)
            self._held.append(("draw", new))
            self._deadline = max(self._deadline, time.monotonic() + time_limit(new))
        if self._check_ready(None):
            self._send_held()

    def _send_held(self) -> None:
        while self._held and self._jobs_fd is not None:
            try:
                sent = _send(self._jobs_fd, self._held[0], self._deadline)
            except OSError:  # it died
                sent = False
            if not sent:
                self.close()
                return
            self._held.pop(0)

    def collect(self) -> dict[str, bytes] | None:
        """The PNG bytes of every job submitted since the last ``collect``, by file name;
        None (the worker stopped) where it failed, died or ran past its time limit."""
        names, self._sent = list(self._sent), {}
        self._held.append(("collect", None))
        if self._check_ready(self._deadline):
            self._send_held()
        reply = None
        if self._done_fd is not None and not self._held:
            reply = _receive(self._done_fd, self._deadline)
        if not (isinstance(reply, tuple) and reply[0] == "done"
                and sorted(reply[1]) == sorted(names)):
            self.close()
            return None
        self.seconds.update(reply[2])
        return {name: reply[1][name] for name in names}

    def close(self) -> None:
        """Stop the worker (at once: it holds nothing that needs cleaning up) and wait
        for its end; closing again does nothing."""
        for fd in (self._jobs_fd, self._done_fd):
            if fd is not None:
                os.close(fd)
        self._jobs_fd = self._done_fd = None
        self._ready = False
        self._held = []
        if self.pid:
            try:
                os.kill(self.pid, signal.SIGKILL)
                os.waitpid(self.pid, 0)
            except (ProcessLookupError, ChildProcessError):
                pass
            self.pid = 0


__all__ = ["LOADAVG", "MAX_CELLS", "Job", "PlotWorker", "cells", "core_free", "draw",
           "fork_is_safe", "run_worker", "start", "time_limit"]
