"""Errors a user can act on: each prints as one line, and the CLI exits with status 2; and
how an internal fault becomes one line with its traceback saved to a file (exit status 1)."""

from __future__ import annotations

import os
import tempfile
import time
import traceback
from pathlib import Path


class ClsonarError(Exception):
    """Base class of the errors the CLI reports as one line (exit status 2)."""


class SceneError(ClsonarError, ValueError):
    """A scene file that cannot be read or is not valid scene format v1.

    ``str(err)`` is ``"FILE: KEY: message"``, e.g.
    ``"room.json: surfaces[2].radius: must be > 0"``.
    """

    def __init__(self, message: str, key: str = "", source: str = "<scene>") -> None:
        self.message = message
        self.key = key
        self.source = source
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.source}: {self.key}: " if self.key else f"{self.source}: "
        return where + self.message


class DeviceError(ClsonarError, RuntimeError):
    """No OpenCL device can be used; the message says what to install or set."""


class WriteError(ClsonarError, OSError):
    """A file or folder that cannot be written (a full disk, no permission): ``"PATH:
    cannot write: No space left on device"``. Also an :class:`OSError` (``errno``,
    ``filename``), so callers that catch those still do."""

    def __init__(self, path: str | os.PathLike[str], error: OSError) -> None:
        super().__init__(error.errno, error.strerror or str(error), os.fspath(path))

    def __str__(self) -> str:
        return f"{self.filename}: cannot write: {self.strerror}"


def one_line(text: str) -> str:
    """``text`` on one line: its lines joined with spaces, blank ones dropped."""
    return " ".join(line.strip() for line in text.splitlines() if line.strip())


def save_traceback(error: BaseException, folder: str | os.PathLike[str] | None = None
                   ) -> Path | None:
    """Write ``error``'s traceback to a new file ``clsonar-traceback-TIME-PID.txt`` in
    ``folder`` (default: the temporary folder) and return its path; None when it cannot
    be written."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    text = "".join(traceback.format_exception(error))
    try:
        fd, name = tempfile.mkstemp(prefix=f"clsonar-traceback-{stamp}-{os.getpid()}-",
                                    suffix=".txt", dir=folder)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError:
        return None
    return Path(name)
