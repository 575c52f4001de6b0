"""clsonar: ultrasonic sonar simulator and map builder for 2-D indoor scenes (OpenCL)."""

from .errors import ClsonarError, DeviceError, SceneError
from .scene import Scene, load_scene, save_scene

__all__ = ["ClsonarError", "DeviceError", "Scene", "SceneError", "load_scene", "save_scene"]
__version__ = "0.1.0"
