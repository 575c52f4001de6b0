"""The sensors stage before any OpenCL: which maps a scene is run as (:func:`check_work`)
and one map's geometry and transducers (:func:`placed_sensors`, :func:`placement`).

Kept apart from :mod:`clsonar.pipeline` so that ``clsonar run``'s worker process
(:func:`clsonar.drawing.run_worker`) can place the transducers having imported only what
placing needs — the geometry, the sensors, the rooms, the echo model's check — while the
main process imports the rest of the pipeline and pyopencl (issue 16).
"""

from __future__ import annotations

from . import regions
from .echoes import check_sequences
from .geometry import Geometry, build_geometry
from .presets import apply_preset
from .scene import Scene
from .sensors import SensorArray, place_sensors
from .skips import Skips


def check_work(scene: Scene, skips: Skips = Skips()) -> list[regions.Region] | None:
    """The rooms ``scene`` is mapped by (:func:`clsonar.regions.split_rooms`; None: whole),
    once each map's echo model is known to fit (:func:`~clsonar.echoes.check_sequences`):
    refused before any work."""
    rooms = regions.split_rooms(scene) if skips.rooms else None
    for part in [scene] if rooms is None else [room.scene for room in rooms]:
        check_sequences(part)
    return rooms


def placed_sensors(scene: Scene) -> tuple[Geometry, SensorArray]:
    """The sensors stage of ``scene`` as one map: its geometry and its transducers."""
    geom = build_geometry(scene)
    return geom, place_sensors(scene, geom)


def placement(scene: Scene, preset: str | None = None, skips: Skips | None = None
              ) -> tuple[Geometry, SensorArray] | None:
    """The sensors stage of ``pipeline.run(scene, preset=preset, skips=skips)``
    (:func:`placed_sensors` of the scene with the preset applied); None where the scene is
    mapped room by room, whose rooms are placed apart."""
    scene = apply_preset(scene, preset)
    if check_work(scene, skips or Skips()) is not None:
        return None
    return placed_sensors(scene)


__all__ = ["check_work", "placed_sensors", "placement"]
