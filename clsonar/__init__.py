"""clsonar: ultrasonic sonar simulator and map builder for 2-D indoor scenes (OpenCL)."""

from .errors import ClsonarError, DeviceError, SceneError
from .scene import Scene, load_scene, save_scene
from .version import __version__


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
