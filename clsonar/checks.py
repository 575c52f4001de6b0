"""Warnings of a run: what a user should know about a result that is not an error.

A run that completes is never refused for these; each is one line of ``report.json``'s
``warnings`` list, and ``clsonar run`` prints it on stderr as ``clsonar: warning: FILE:
TEXT`` (exit status 0). Four are given:

- the scene has a closed polyline inside another one and the file leaves its ``solid``
  unset: it is read as a solid obstacle (a box, a pillar) that reflects on its outside
  (:func:`clsonar.outlines.solid_surfaces`), which the user may not have meant;
- a ``wall-following`` ring in a room never comes near the room's walls: its start was
  nearest an obstacle, which it circles instead (:func:`placement_warnings`);
- the map is empty although echoes were detected: the surfaces heard lie outside the map's
  extent, or the settings lost every detection on the way to the profile (the counters say
  at which stage);
- the map holds only faces drawn from two elements' echoes each and the points where two
  loud echoes' loci cross: too few echoes were heard for any reflector's model
  (:func:`clsonar.mapping.few.loud_crossings`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .geometry import segment_distance
from .outlines import enclosing, in_the_open, inside_polygon, sensor_anchors
from .scene import Polyline, Scene, WallFollowing


def scene_warnings(scene: Scene) -> list[str]:
    """One line per closed polyline of ``scene`` that is read as solid only because it lies
    inside another closed polyline, or because every transducer stands outside it (its
    ``solid`` is null)."""
    inside = enclosing(scene.surfaces)
    open_scene = in_the_open(scene.surfaces, sensor_anchors(scene))
    out = []
    for i, (s, j) in enumerate(zip(scene.surfaces, inside, strict=True)):
        if not (isinstance(s, Polyline) and s.closed and s.solid is None):
            continue
        if j is not None:
            where = f"inside surfaces[{j}]"
        elif open_scene:
            where = "with every transducer outside it"
        else:
            continue
        out.append(f"surfaces[{i}], a closed polyline {where}, is read as a solid obstacle "
                   "that reflects on its outside (set its \"solid\" to false for a room, "
                   "true to say so)")
    return out


def result_warnings(counts: Mapping[str, int]) -> list[str]:
    """One line when a run's profile is empty although echoes were detected, or holds only
    two-echo faces and the crossings of loud echoes' loci (``counts``: the run's counters)."""
    detected = counts.get("detections", 0)
    crossings, faces = counts.get("crossing_points", 0), counts.get("two_echo_faces", 0)
    if (crossings or faces) and counts.get("profile_points", 0) > 0:
        held = [f"{faces} face(s) each drawn from two elements' echoes"] if faces else []
        if crossings:
            held.append(f"the {crossings} point(s) where two loud echoes' loci cross")
        return [f"the map holds only {' and '.join(held)}: the {detected} echoes detected "
                "are too few for a surface's model"]
    if detected == 0 or counts.get("profile_points", 0) > 0:
        return []
    return [f"the map is empty although {detected} echoes were detected "
            f"({counts.get('cells_voted', 0)} cells voted, "
            f"{counts.get('occupied_cells', 0)} occupied, {counts.get('thin_cells', 0)} thin, "
            "0 profile points): the surfaces heard lie outside the extent, or the mapping "
            "and post-processing settings do not suit this scene"]


#: A wall-following trace follows a room's walls when it passes this close to them, beyond
#: its clearance (metres).
FOLLOWS_WALLS_M = 0.05


def placement_warnings(scene: Scene, poses: np.ndarray) -> list[str]:
    """One line when a ``wall-following`` ring (its ``poses``) stands in a room but its
    trace never comes near the room's walls: it circles the obstacle nearest its start."""
    p = scene.sensors.placement
    if not isinstance(p, WallFollowing) or len(poses) == 0:
        return []
    for i, s in enumerate(scene.surfaces):
        if not (isinstance(s, Polyline) and s.closed):
            continue
        outline = np.asarray(s.points, dtype=np.float64)
        if not inside_polygon(outline, np.asarray([p.start], dtype=np.float64))[0]:
            continue
        if segment_distance(poses, outline).min() > p.clearance_m + FOLLOWS_WALLS_M:
            return [f"the wall-following ring circles an obstacle, not the walls of "
                    f"surfaces[{i}] (it follows the surface nearest its start): move "
                    f"sensors.placement.start nearer a wall to scan the room"]
    return []


def run_warnings(scene: Scene, counts: Mapping[str, int],
                 poses: np.ndarray | None = None) -> tuple[str, ...]:
    """Every warning of a run of ``scene`` with counters ``counts`` (and the sensors'
    ``poses``, for :func:`placement_warnings`)."""
    placed = placement_warnings(scene, poses) if poses is not None else []
    return (*scene_warnings(scene), *placed, *result_warnings(counts))


__all__ = ["FOLLOWS_WALLS_M", "placement_warnings", "result_warnings", "run_warnings",
           "scene_warnings"]
