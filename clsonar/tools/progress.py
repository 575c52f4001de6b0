"""Progress on one rewritten line of a terminal's stderr (nothing when it is not a terminal),
for the command line and the tools it runs."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

#: ``(steps done, steps in all, what is being done)``: how the tools report progress.
Progress = Callable[[int, int, str], None]


class ProgressLine:
    """One line of ``stream`` (default stderr) rewritten in place, only when ``enabled`` and
    the stream is a terminal. Called as a :data:`Progress`, it shows ``[i/n] what``;
    :meth:`stage` shows a pipeline stage (:data:`clsonar.pipeline.Progress`) with a bar;
    :meth:`done` ends the line if anything was shown."""

    def __init__(self, enabled: bool = True, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled and self.stream.isatty()
        self.start = time.perf_counter()
        self.shown = False
        self.head = ""  # the stage part of the line
        self.loop = Loop()
        self.drawn = 0.0  # when the line was last drawn by :meth:`step`

    def show(self, text: str) -> None:
        """Replace the line with ``text``."""
        if self.enabled:
            print(f"\r{text}", end="", file=self.stream, flush=True)
            self.shown = True

    def __call__(self, i: int, n: int, what: str) -> None:
        self.show(f"[{i}/{n}] {what:<48}")

    def stage(self, stage: str, index: int, total: int) -> None:
        """``[###.....] 3/8 detection     1.2 s``: pipeline stage ``index`` of ``total``."""
        bar = "#" * index + "." * (total - index)
        elapsed = time.perf_counter() - self.start
        self.head = f"[{bar}] {index}/{total} {stage:<13}"
        self.loop = Loop()
        self.show(f"{self.head} {elapsed:6.1f} s{'':<40}")

    def step(self, what: str, done: int, total: int) -> None:
        """Progress inside the stage (:data:`clsonar.steps.Step`): ``… detection  pairs
        300/1,000, 2 s left``, drawn at most 10 times a second."""
        if not total:
            return  # a poll (:func:`clsonar.steps.poll`): nothing new to show
        now = time.perf_counter()
        left = self.loop.update(what, done, total, now)
        if now - self.drawn < 0.1 and done < total:
            return
        self.drawn = now
        eta = "" if left is None else f", {left:.0f} s left"
        self.show(f"{self.head} {now - self.start:6.1f} s  {what} {done:,}/{total:,}{eta}"
                  f"{'':<8}")

    def done(self) -> None:
        """End the line (a newline) if anything was shown on it."""
        if self.shown:
            print(file=self.stream)
            self.shown = False


class Loop:
    """The loop a stage reports (:func:`clsonar.steps.step`): its name, when it started and
    the time left at its rate so far."""

    def __init__(self) -> None:
        self.what: str | None = None
        self.since = 0.0
        self.first = 0

    def update(self, what: str, done: int, total: int, now: float) -> float | None:
        """Note ``done`` of ``total`` of ``what`` at ``now``; the seconds left (None until
        some of it is done)."""
        if what != self.what or done < self.first:
            self.what, self.since, self.first = what, now, done
        if done <= self.first or now <= self.since:
            return None
        return (now - self.since) / (done - self.first) * (total - done)
