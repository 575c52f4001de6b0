"""Errors a user can act on: each prints as one line, and the CLI exits with status 2."""

from __future__ import annotations


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
