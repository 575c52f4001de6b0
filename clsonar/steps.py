"""Progress inside a stage, and the point where a run can be stopped (issue 19).

The pipeline tells its stages as they start (:data:`clsonar.pipeline.Progress`); a stage's
long loops — the detection's launches, the echoes' chunks of pairs, the reflector families'
patches, a floor's rooms — also call :func:`step` with how much of the loop is done. Whoever
runs the pipeline listens with :func:`watching` (the command line's progress line, the GUI's
job): its callback sees ``(what, done, total)`` and may raise to stop the run there (the
GUI's Cancel), so a run stops within one step, not at the end of its stage; where one
step is long, :func:`poll` inside it is a point to stop at that shows nothing new
(``total`` 0). With nobody watching, :func:`step` costs one lookup. The listener is
per thread (a context variable): two runs in two threads each report to their own.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from typing import TypeVar

#: ``(what, done, total)``: ``done`` of ``total`` units of the loop ``what`` are done.
Step = Callable[[str, int, int], None]

T = TypeVar("T")

_listener: ContextVar[Step | None] = ContextVar("clsonar_step_listener", default=None)


def step(what: str, done: int, total: int) -> None:
    """Tell the listener (if any) that ``done`` of ``total`` units of ``what`` are done;
    raises whatever the listener raises (a cancelled run)."""
    listener = _listener.get()
    if listener is not None:
        listener(what, done, total)


def poll() -> None:
    """Inside a long step: a point where the run can be stopped, with nothing new to show
    (the listener is told ``("", 0, 0)``)."""
    step("", 0, 0)


def each(what: str, items: Sequence[T]) -> Iterator[T]:
    """``items`` one by one, telling :func:`step` before each (``0 … n − 1`` done) and
    after the last (``n`` done)."""
    for k, item in enumerate(items):
        step(what, k, len(items))
        yield item
    step(what, len(items), len(items))


@contextmanager
def watching(listener: Step | None) -> Iterator[None]:
    """:func:`step` calls ``listener`` inside the ``with`` block (in this thread)."""
    token = _listener.set(listener)
    try:
        yield
    finally:
        _listener.reset(token)


__all__ = ["Step", "each", "poll", "step", "watching"]
