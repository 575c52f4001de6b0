"""Multi-room floors for the benchmark at scale (issue "Fast": a 50 m × 50 m floor at 1 cm,
and a 100 m × 100 m one, 10⁸ cells, within 2 GB of host memory).

A floor is a grid of closed square rooms, each mapped as the thesis maps its closed room
(§2.1.2, §3.6): an 8-element ring follows the walls of each room and fires all pairs at
every step. Every fourth room holds a cylinder. The pipeline maps such a scene room by room
(:mod:`clsonar.regions`).
"""

from __future__ import annotations

import dataclasses

from .scene import Circle, Polyline, Scene, Sensors, WallFollowing


def floor_scene(size_m: float = 50.0, room_m: float = 5.0, wall_m: float = 0.2,
                cell: float = 0.01, step_m: float = 0.5, name: str | None = None,
                base: Scene | None = None) -> Scene:
    """A ``size_m`` × ``size_m`` floor of square rooms ``room_m`` apart whose walls are
    ``wall_m`` thick (each room's outline is its square inset by ``wall_m``/2), on a map of
    ``cell``; one wall-following ring per room, ``step_m`` between poses; a cylinder of
    radius 0.4 m in every fourth room. Transducer, signal, echo, mapping and
    post-processing settings are those of ``base`` (default: the bundled closed room,
    ``scenes/room.json``)."""
    if base is None:
        from .reproduce import bundled_scenes
        from .scene import load_scene

        base = load_scene(bundled_scenes() / "room.json")
    n = max(1, round(size_m / room_m))
    half = wall_m / 2
    surfaces: list = []
    rings = []
    for i in range(n):
        for j in range(n):
            x0, y0 = i * room_m + half, j * room_m + half
            x1, y1 = (i + 1) * room_m - half, (j + 1) * room_m - half
            surfaces.append(Polyline(((x0, y0), (x1, y0), (x1, y1), (x0, y1)), closed=True))
            if (i + j) % 4 == 3:
                surfaces.append(Circle(((x0 + x1) / 2, (y0 + y1) / 2), 0.4))
            rings.append(WallFollowing(start=(x0 + 1.0, (y0 + y1) / 2), step_m=step_m,
                                       clearance_m=0.5, radius_m=0.065, elements=8))
    return dataclasses.replace(base, name=name or f"floor-{size_m:g}m",
                               extent=(0.0, 0.0, n * room_m, n * room_m), cell=cell,
                               surfaces=tuple(surfaces), sensors=Sensors(placements=tuple(rings)))


__all__ = ["floor_scene"]
