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
        self.show(f"[{bar}] {index}/{total} {stage:<13} {elapsed:6.1f} s")

    def done(self) -> None:
        """End the line (a newline) if anything was shown on it."""
        if self.shown:
            print(file=self.stream)
            self.shown = False
