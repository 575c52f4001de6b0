"""The edited scene: one immutable :class:`~clsonar.scene.Scene` behind a ``QUndoStack``.

Every edit replaces the whole scene (scenes are small frozen dataclasses), so an undo step is
just the scene before and after it (:class:`SceneCommand`); a drag pushes one command when
it ends. Saving writes scene format v1 atomically (:func:`clsonar.scene.save_scene`); every
change is also written to a recovery file that :func:`recovery_path` names, removed when the
scene is saved or closed cleanly, so unsaved work survives a crash.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from PySide6.QtCore import QObject, Signal
from PySide6.QtGui import QUndoCommand, QUndoStack

from ..scene import Scene, load_scene, save_scene
from .edits import validated


class SceneCommand(QUndoCommand):
    """One undoable edit: the scene before and after it."""

    def __init__(self, doc: Document, before: Scene, after: Scene, text: str) -> None:
        super().__init__(text)
        self.doc, self.before, self.after = doc, before, after

    def redo(self) -> None:
        self.doc._set(self.after)

    def undo(self) -> None:
        self.doc._set(self.before)


def recovery_path(folder: str | os.PathLike[str], scene_path: str | None) -> Path:
    """The recovery file of a scene file (or of an untitled scene) in ``folder``."""
    key = hashlib.sha1(os.path.abspath(scene_path).encode()).hexdigest()[:12] \
        if scene_path else "untitled"
    return Path(folder) / f"recovery-{key}.json"


class Document(QObject):
    """The scene being edited, its file, its undo stack and its recovery file."""

    sceneChanged = Signal(object)  # the new Scene
    recoveryFailed = Signal(str)  # one line: the recovery file could not be written

    def __init__(self, scene: Scene, path: str | None = None,
                 recovery_dir: str | os.PathLike[str] | None = None) -> None:
        super().__init__()
        self.scene = scene
        self.path = path
        self.recovery_dir = recovery_dir
        self.undo = QUndoStack(self)
        self.undo.indexChanged.connect(self._write_recovery)

    # -- editing
    def apply(self, after: Scene, text: str) -> bool:
        """Push the edit ``scene → after`` as one undo step; an invalid scene is refused
        with :class:`~clsonar.errors.SceneError` (and nothing changes)."""
        after = validated(after)
        if after == self.scene:
            return False
        self.undo.push(SceneCommand(self, self.scene, after, text))
        return True

    def _set(self, scene: Scene) -> None:
        self.scene = scene
        self.sceneChanged.emit(scene)

    @property
    def modified(self) -> bool:
        return not self.undo.isClean()

    # -- files
    def save(self, path: str | None = None) -> None:
        """Write the scene (format v1, atomic) to ``path`` or its own file."""
        path = path or self.path
        if path is None:
            raise ValueError("no file name")
        old = self.recovery_file
        save_scene(self.scene, path)
        self.path = path
        self.undo.setClean()
        for f in {old, self.recovery_file}:
            if f is not None:
                f.unlink(missing_ok=True)

    def reset(self, scene: Scene, path: str | None = None) -> None:
        """Edit ``scene`` (from file ``path``) from now on, with an empty undo history."""
        self.undo.clear()
        self.path = None if path is None else os.fspath(path)
        self._set(scene)

    def open(self, path: str) -> None:
        """Edit the scene file ``path`` (SceneError, and no change, if it is not valid)."""
        self.reset(load_scene(path), path)

    # -- crash recovery
    @property
    def recovery_file(self) -> Path | None:
        if self.recovery_dir is None:
            return None
        return recovery_path(self.recovery_dir, self.path)

    def _write_recovery(self, *_: object) -> None:
        f = self.recovery_file
        if f is None:
            return
        if not self.modified:
            f.unlink(missing_ok=True)
            return
        try:  # written whole or not at all: the last one written stays (clsonar.files)
            f.parent.mkdir(parents=True, exist_ok=True)
            save_scene(self.scene, f)
        except OSError as e:  # a full disk, a folder that cannot be written
            self.recoveryFailed.emit(f"unsaved changes not kept for recovery: {e}")

    def discard_recovery(self) -> None:
        """Forget the recovery file (the user closed without saving, on purpose)."""
        f = self.recovery_file
        if f is not None:
            f.unlink(missing_ok=True)

    def recovered(self) -> Scene | None:
        """The unsaved scene a crashed session left for this file, if any and valid."""
        f = self.recovery_file
        if f is None or not f.exists():
            return None
        try:
            return load_scene(f)
        except Exception:
            return None
