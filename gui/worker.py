"""Long work off the GUI thread: a :class:`Job` runs one function in a ``QThread``.

The function gets a ``progress(stage, i, n)`` callback (the shape of
:data:`clsonar.pipeline.Progress`) and runs watched by :func:`clsonar.steps.watching`, so
the stages' long loops report their steps too (signal ``stepped``, at most 10 a second);
:meth:`Job.cancel` makes the next report of either kind raise :class:`Cancelled`, so a
pipeline run stops within one step of a stage (a fraction of a second), not only between
stages. The outcome comes back as
exactly one of the signals ``succeeded(result)``, ``failed(message)`` or ``cancelled()``,
delivered on the GUI thread; nothing the function raises can crash the GUI.
"""

from __future__ import annotations

import gc
import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, QThread, QTimer, Signal

from .. import steps
from ..errors import ClsonarError
from ..pipeline import Progress


class Cancelled(Exception):
    """Raised inside a job's progress callback after :meth:`Job.cancel`."""


def error_line(e: BaseException) -> str:
    """One line for the user: the message of an error they can act on, else its type too."""
    if isinstance(e, (ClsonarError, ValueError)):
        return str(e)
    return f"{type(e).__name__}: {e}"


class Job(QThread):
    """Runs ``fn(progress)`` in its own thread; see the module docstring."""

    progressed = Signal(str, int, int)
    stepped = Signal(str, int, int)
    succeeded = Signal(object)
    failed = Signal(str)
    cancelled = Signal()

    def __init__(self, fn: Callable[[Progress], Any], name: str = "run",
                 parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.fn = fn
        self.name = name
        self._cancel = threading.Event()
        self.stages: list[str] = []  # the stages it reported, in order
        self._stepped = 0.0  # when ``stepped`` was last emitted

    def cancel(self) -> None:
        """Ask the job to stop at its next progress report."""
        self._cancel.set()

    def _progress(self, stage: str, i: int, n: int) -> None:
        if self._cancel.is_set():
            raise Cancelled
        self.stages.append(stage)
        self.progressed.emit(stage, i, n)

    def _step(self, what: str, done: int, total: int) -> None:
        if self._cancel.is_set():
            raise Cancelled
        now = time.perf_counter()
        if total and (now - self._stepped >= 0.1 or done >= total):
            self._stepped = now
            self.stepped.emit(what, done, total)

    def run(self) -> None:  # the thread's body
        try:
            with steps.watching(self._step):
                result = self.fn(self._progress)
        except Cancelled:
            self.cancelled.emit()
        except Exception as e:
            traceback.print_exc()
            self.failed.emit(error_line(e))
        else:
            if self._cancel.is_set():
                self.cancelled.emit()
            else:
                self.succeeded.emit(result)


class GuiThreadCollector(QObject):
    """Python's cyclic garbage collection on the GUI thread only, while a window lives.

    Python collects in whichever thread happens to allocate when a generation's threshold
    is crossed: a :class:`Job` running the pipeline, or a library's own thread (Dask's
    event loop after a sweep). The collection frees what garbage cycles hold, Qt objects
    among them (a closed dialog, a replaced plot item), and a Qt object deleted off the GUI
    thread while that thread paints can crash the process (a segmentation fault in CI, in
    the GUI tests after the Dask ones). So, as pyqtgraph's ``GarbageCollector`` does,
    automatic collection is off while any collector is started, and a timer collects on the
    GUI thread each ``interval_ms`` with Python's own thresholds. When the last one stops,
    collection is as it was before the first started.
    """

    _started = 0
    _was_enabled = True

    def __init__(self, parent: QObject, interval_ms: int = 1000) -> None:
        super().__init__(parent)
        self._timer = QTimer(self)
        self._timer.timeout.connect(collect_by_thresholds)
        self._timer.start(interval_ms)
        cls = GuiThreadCollector
        if cls._started == 0:
            cls._was_enabled = gc.isenabled()
            gc.disable()
        cls._started += 1
        self._running = True

    def stop(self) -> None:
        """Stop collecting here (idempotent); automatic collection resumes after the last.
        The window calls it when it closes (and ``main`` before deleting it), never from
        Qt's ``destroyed``: collection turned on inside a widget tree's destruction, with
        the counts grown all the while the window lived, runs at the next allocation there
        and deadlocks in ``QObject::disconnect`` (seen in CI). Here what the window left
        is collected first."""
        if not self._running:
            return
        self._running = False
        self._timer.stop()
        collect_by_thresholds()  # what this window left, on this thread
        cls = GuiThreadCollector
        cls._started -= 1
        if cls._started == 0 and cls._was_enabled:
            gc.enable()


def collect_by_thresholds() -> None:
    """One step of Python's automatic collection, done by hand: each generation whose count
    passed its threshold is collected (with the younger ones)."""
    counts, thresholds = gc.get_count(), gc.get_threshold()
    if thresholds[0] == 0:  # collection was turned off (gc.set_threshold(0))
        return
    generation = -1
    for g in range(3):
        if counts[g] <= thresholds[g]:
            break
        generation = g
    if generation >= 0:
        gc.collect(generation)
