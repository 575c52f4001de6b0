"""Scene file format v1: load, validate and save (docs/design.md, "Scene file format v1").

A scene is a tree of frozen dataclasses (:mod:`.model`, :mod:`.settings`), so scenes compare
with ``==`` and hash (the pipeline's cache keys on them). :func:`load_scene` reads JSON and
validates every key (:mod:`.reader`); any problem raises :class:`~clsonar.errors.SceneError`
naming the file and the key path, e.g. ``room.json: surfaces[2].radius: must be > 0``.
:func:`save_scene` writes the full normalised form (every default spelled out) atomically
(:mod:`.writer`), so load → save → load gives an identical scene.

docs/scene-format.md lists every key, its default and its allowed values (all units SI,
angles in degrees where the key says so); tests/test_scene.py checks that it misses none.
Placements are documented with their dataclasses and implemented in clsonar.sensors.
"""

from .limits import (
    MAX_CELLS_PER_SIDE,
    MAX_CIRCLES,
    MAX_CONTAINERS,
    MAX_CURVE_SAMPLES,
    MAX_DEPTH,
    MAX_EXPLICIT_PAIRS,
    MAX_MAGNITUDE,
    MAX_SEPARATORS,
    MAX_WALL_SEQUENCES,
    MIN_LENGTH_M,
)
from .model import (
    FORMAT_VERSION,
    Circle,
    Circular,
    PerWall,
    Placement,
    Point,
    Polyline,
    RandomLines,
    Scene,
    Sensors,
    Sinusoid,
    Surface,
    Transducer,
    WallDirection,
    WallFollowing,
    per_wall_surface_problem,
)
from .reader import load_scene, parse_scene_text, scene_from_dict
from .settings import (
    Combine,
    DetectionMode,
    DetectionSettings,
    Directivity,
    EchoModel,
    EdgeModel,
    Fit,
    MappingMode,
    MappingSettings,
    Medium,
    PostFilter,
    PostSettings,
    Precision,
    Receiver,
    Reciprocal,
    Signal,
    Thinning,
    TransducerModel,
    VoteWeight,
)
from .writer import save_scene, scene_json, scene_to_dict

__all__ = [
    "FORMAT_VERSION", "MAX_CELLS_PER_SIDE", "MAX_CIRCLES", "MAX_CONTAINERS",
    "MAX_CURVE_SAMPLES", "MAX_DEPTH", "MAX_EXPLICIT_PAIRS", "MAX_MAGNITUDE", "MAX_SEPARATORS",
    "MAX_WALL_SEQUENCES", "MIN_LENGTH_M", "Circle", "Circular", "Combine", "DetectionMode",
    "DetectionSettings", "Directivity", "EchoModel", "EdgeModel", "Fit", "MappingMode",
    "MappingSettings",
    "Medium", "PerWall", "Placement", "Point", "Polyline", "PostFilter", "PostSettings",
    "Precision", "RandomLines", "Receiver", "Reciprocal", "Scene", "Sensors", "Signal", "Sinusoid",
    "Surface", "Thinning", "Transducer", "TransducerModel", "VoteWeight", "WallDirection",
    "WallFollowing", "load_scene", "parse_scene_text", "per_wall_surface_problem",
    "save_scene", "scene_from_dict", "scene_json", "scene_to_dict",
]
