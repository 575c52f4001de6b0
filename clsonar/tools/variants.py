"""Variants of a scene for the experiments: another seed, another distance."""

from __future__ import annotations

import dataclasses
import math

from ..scene import PerWall, RandomLines, Scene


def at_distance(scene: Scene, scene_distance: float, distance: float) -> Scene:
    """``scene`` with its random-lines placement moved back by ``distance − scene_distance``
    (against the direction the arrays face), renamed ``family-<distance>m``."""
    p = scene.sensors.placement
    if not isinstance(p, RandomLines) or p.start is None:
        raise ValueError(f"{scene.name}: needs a random-lines placement with a start")
    back = distance - scene_distance
    a = math.radians(p.facing_deg)
    start = (p.start[0] - back * math.cos(a), p.start[1] - back * math.sin(a))
    name = f"{scene.name.rsplit('-', 1)[0]}-{distance:g}m"
    sensors = dataclasses.replace(scene.sensors, placement=dataclasses.replace(p, start=start))
    return dataclasses.replace(scene, name=name, sensors=sensors)


def with_seed(scene: Scene, k: int, noise_std: float | None = None) -> Scene:
    """``scene`` with placement and noise seeds advanced by ``k`` (and the noise σ set);
    placements without randomness (``circular``, ``wall-following``) are kept."""
    p = scene.sensors.placement
    sensors = scene.sensors
    if isinstance(p, (RandomLines, PerWall)):
        sensors = dataclasses.replace(sensors, placement=dataclasses.replace(p, seed=p.seed + k))
    sig = scene.signal
    signal = dataclasses.replace(sig, seed=sig.seed + k,
                                 noise_std=sig.noise_std if noise_std is None else noise_std)
    return dataclasses.replace(scene, sensors=sensors, signal=signal)
