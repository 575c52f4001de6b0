"""clsonar: ultrasonic sonar simulator and map builder for 2-D indoor scenes (OpenCL).

``import clsonar`` imports neither NumPy nor the scene model: :class:`Scene`,
:func:`load_scene` and :func:`save_scene` are imported from :mod:`clsonar.scene` when first
asked for, so the command line (:mod:`clsonar.cli`) can choose how NumPy starts before it is
loaded (docs/speed.md, "2026-11-27, start-up").
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import ClsonarError, DeviceError, SceneError
from .version import __version__

if TYPE_CHECKING:
    from .scene import Scene, load_scene, save_scene

#: The names of :mod:`clsonar.scene` this package gives, imported when first asked for.
SCENE_NAMES = ("Scene", "load_scene", "save_scene")


def __getattr__(name: str) -> Any:
    """``clsonar.Scene``, ``clsonar.load_scene``, ``clsonar.save_scene`` and
    ``clsonar.scene`` itself: from :mod:`clsonar.scene`, imported on first use (PEP 562)."""
    if name in SCENE_NAMES or name == "scene":
        scene = importlib.import_module(".scene", __name__)
        return scene if name == "scene" else getattr(scene, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def run(scene: Scene, *, device: str | None = None, context=None, preset: str | None = None,
        progress=None, **options):
    """Run the whole mapping pipeline on ``scene``; see :func:`clsonar.pipeline.run`.

    Returns a :class:`clsonar.pipeline.RunResult` with every stage (sensors, echoes,
    detections, raw/filtered/thin maps, profile), per-stage seconds, counts and metrics.
    ``options``: ``skips`` and ``cache`` of :func:`clsonar.pipeline.run`.
    """
    from .pipeline import run as _run

    return _run(scene, device=device, context=context, preset=preset, progress=progress,
                **options)


__all__ = [
    "ClsonarError",
    "DeviceError",
    "Scene",
    "SceneError",
    "__version__",
    "load_scene",
    "run",
    "save_scene",
]
