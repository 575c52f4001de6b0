"""What a scene is and how it is scanned, and the settings a scene file leaves out chosen from
that (issue 14: maps without tuning).

:func:`survey` reads the scene's geometry and its placed transducers: whether every
transducer is inside a closed polyline (a room), which pair groups are rings (elements on a
circle facing outwards from its centre: one pose of a circular array, thesis §2.1.2) and
which are linear arrays (thesis §2.1), and whether the ring poses, in file order, follow a
path (a robot driving along walls or down a corridor). :func:`choose_settings` then fills in
every setting the file left out (null) from :data:`CHOICES`, and says for each setting which
value was used and why; a value the file (or a preset) gives always wins.

Why these choices: a ring's elements face away from each other, so the loci of one pose
never cross and the tangent-point method keeps nothing unless an isolated locus keeps the
stretch around its tangent (``mapping.isolated_bias_m``); a room or a path is straight walls
meeting at corners and edges, which the ``walls`` fit recovers (thesis §3.6), with the gaps
between poses' patches (up to about the scan step and beyond) bridged and walls joined at
their vertices (``post.max_gap_m``, ``post.join_m``). The envelope's floor
(``detection.min_envelope``) is low in an open scene, where arrays face reflectors whose
echoes are weak (a convex edge's diffraction), and 1 unit where rings scan walls square on.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .geometry import Geometry, build_geometry, nearest_surface_point
from .numerics import median
from .outlines import inside_polygon
from .scene import Polyline, Scene, WallFollowing
from .sensors import SensorArray, square_to_walls, walls_share_heading

#: A group is a ring when its elements' distances from their centre agree within this
#: share, the ring is at most :data:`MAX_RING_RADIUS_M` across, and every element faces
#: within :data:`RING_FACING_DEG` of the outward direction.
RING_RADIUS_SPREAD = 0.1
MAX_RING_RADIUS_M = 0.5
RING_FACING_DEG = 15.0

#: A group is a linear array when its elements lie within this of one line and face
#: within :data:`ARRAY_FACING_DEG` of each other.
ARRAY_LINE_M = 0.01
ARRAY_FACING_DEG = 30.0

#: Ring poses form a path when most steps between consecutive poses are this short.
PATH_STEP_M = 1.5
PATH_SHARE = 0.8
PATH_MIN_POSES = 3

#: The kinds of scan :func:`survey` tells apart, each with its description in report.json.
ROOM_RINGS = "ring poses inside a closed room"
ROOM = "transducers inside a closed room"
PATH = "ring poses along a path"
RINGS = "rings in an open scene"
OPEN = "an open scene"

#: The envelope threshold's floor (units) where rings scan or transducers stand in a room:
#: the walls they face square on return ρ·A0 ≈ 4.5, and the diffraction of every convex
#: corner they pass (a few hundredths) would only add stubs to the tangent points' map.
DEFAULT_MIN_ENVELOPE = 1.0

#: The floor in an open scene (arrays facing reflectors): a convex edge's diffraction 2–4 m
#: away is 0.003–0.03 units for a 5-unit pulse (docs/physics.md), which a Polaroid-type
#: sensor detects (Kleeman & Kuc 1995; the thesis' edges out to 3–4 m), and the reflector
#: families tell it from the faces' echoes by its strength (mapping.families).
OPEN_MIN_ENVELOPE = 0.01

#: The settings chosen for each kind of scan where the scene file leaves them out (null).
_SCANNED_WALLS = {"detection.min_envelope": DEFAULT_MIN_ENVELOPE,
                  "mapping.isolated_bias_m": 0.005, "post.fit": "walls",
                  "post.max_gap_m": 1.0, "post.join_m": 1.0}
_OPEN = {"detection.min_envelope": OPEN_MIN_ENVELOPE, "mapping.isolated_bias_m": 0.0,
         "post.fit": "spline", "post.max_gap_m": 0.3, "post.join_m": 0.5}
CHOICES: dict[str, dict[str, object]] = {
    ROOM_RINGS: _SCANNED_WALLS,
    ROOM: _SCANNED_WALLS,
    PATH: _SCANNED_WALLS,
    RINGS: {**_OPEN, "detection.min_envelope": DEFAULT_MIN_ENVELOPE,
            "mapping.isolated_bias_m": 0.005},
    OPEN: _OPEN,
}

#: The settings that are chosen from the scene when the file leaves them out.
AUTO_KEYS = tuple(_OPEN)


@dataclass(frozen=True)
class Survey:
    """What :func:`survey` found: the kind of scan (one of :data:`CHOICES`' keys) and its
    counts."""

    kind: str
    groups: int
    rings: int
    arrays: int
    in_room: bool
    ring_path: bool
    #: ring scans: the median distance of the ring poses from the nearest surface and the
    #: median step between consecutive poses, metres (None: no ring path)
    clearance_m: float | None = None
    step_m: float | None = None


def group_centres(sensors: SensorArray) -> tuple[np.ndarray, list[np.ndarray]]:
    """The pair groups in file order (of their first element): [G, 2] centroids and each
    group's element indices."""
    groups, first = np.unique(sensors.groups, return_index=True)
    order = np.argsort(first)
    members = [np.flatnonzero(sensors.groups == g) for g in groups[order]]
    centres = np.array([sensors.positions[m].mean(axis=0) for m in members]).reshape(-1, 2)
    return centres, members


def is_ring(positions: np.ndarray, headings_deg: np.ndarray) -> bool:
    """Whether transducers at ``positions`` [n, 2] with ``headings_deg`` [n] form a ring:
    at least 3 on a small circle, each facing away from its centre."""
    if len(positions) < 3:
        return False
    d = positions - positions.mean(axis=0)
    r = np.hypot(d[:, 0], d[:, 1])
    if r.mean() <= 0 or r.mean() > MAX_RING_RADIUS_M or np.ptp(r) > RING_RADIUS_SPREAD * r.mean():
        return False
    out = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    off = (headings_deg - out + 180.0) % 360.0 - 180.0
    return bool(np.all(np.abs(off) <= RING_FACING_DEG))


def is_linear_array(positions: np.ndarray, headings_deg: np.ndarray) -> bool:
    """Whether transducers at ``positions`` [n, 2] form a linear array: at least 2 within
    :data:`ARRAY_LINE_M` of one line, facing within :data:`ARRAY_FACING_DEG` of each other."""
    if len(positions) < 2:
        return False
    d = positions - positions.mean(axis=0)
    _, sv, _ = np.linalg.svd(d, full_matrices=False)
    if sv[-1] / math.sqrt(len(d)) > ARRAY_LINE_M:
        return False
    h = np.radians(headings_deg)
    mean = math.atan2(np.sin(h).mean(), np.cos(h).mean())
    off = (np.degrees(h - mean) + 180.0) % 360.0 - 180.0
    return bool(np.all(np.abs(off) <= ARRAY_FACING_DEG))


def follows_a_path(poses: np.ndarray) -> bool:
    """Whether ``poses`` [P, 2] in order are a path: at least :data:`PATH_MIN_POSES`, most
    steps shorter than :data:`PATH_STEP_M`."""
    if len(poses) < PATH_MIN_POSES:
        return False
    steps = np.hypot(*np.diff(poses, axis=0).T)
    return bool(np.mean(steps <= PATH_STEP_M) >= PATH_SHARE)


def in_a_room(scene: Scene, positions: np.ndarray) -> bool:
    """Whether every transducer lies inside one of the scene's closed polylines."""
    rooms = [np.asarray(s.points, dtype=np.float64) for s in scene.surfaces
             if isinstance(s, Polyline) and s.closed]
    if not rooms or len(positions) == 0:
        return False
    inside = np.zeros(len(positions), dtype=bool)
    for poly in rooms:
        inside |= inside_polygon(poly, positions)
    return bool(inside.all())


def survey(scene: Scene, sensors: SensorArray, geom: Geometry | None = None) -> Survey:
    """What ``scene`` is and how ``sensors`` scan it (:class:`Survey`; ``geom``: the
    scene's geometry, if the caller has built it)."""
    centres, members = group_centres(sensors)
    rings = [is_ring(sensors.positions[m], sensors.headings_deg[m]) for m in members]
    arrays = sum(is_linear_array(sensors.positions[m], sensors.headings_deg[m])
                 for m in members)
    room = in_a_room(scene, sensors.positions)
    poses = centres[np.asarray(rings, dtype=bool)]
    path = follows_a_path(poses) if any(rings) else False
    if room:
        kind = ROOM_RINGS if any(rings) else ROOM
    elif path:
        kind = PATH
    else:
        kind = RINGS if any(rings) else OPEN
    clearance = step = None
    if path:
        geom = build_geometry(scene) if geom is None else geom
        clearance = float(median(nearest_surface_point(geom, poses)[0]))
        step = float(median(np.hypot(*np.diff(poses, axis=0).T)))
    return Survey(kind, len(members), sum(rings), int(arrays), room, path, clearance, step)


def join_reach(found: Survey) -> float | None:
    """How far from a corner a ring path's walls may end, metres: the ring keeps its
    clearance from both walls as it turns there and maps each wall from where its beams
    first meet it square on, up to a step later — clearance + step (None: no ring
    path). ``post.join_m`` is at least this, so the walls of a scan far from them still
    meet at their corners."""
    if found.clearance_m is None or found.step_m is None:
        return None
    return round(found.clearance_m + found.step_m, 2)


def choose_settings(scene: Scene, found: Survey, given: str = "file",
                    geom: Geometry | None = None) -> tuple[Scene, dict[str, str]]:
    """``scene`` with every setting of :data:`AUTO_KEYS` it leaves out (None) chosen for
    the kind of scan ``found`` (:data:`CHOICES`), and a wall-following ring's heading
    square to the walls (:func:`~clsonar.sensors.square_to_walls`, on ``geom``, the
    scene's geometry if the caller has built it; left unset where the walls share no
    heading, so that each pose turns to its nearest wall,
    :func:`~clsonar.sensors.pose_headings`); and, per setting, why its value was used:
    ``"auto: <kind>"`` or ``given`` (where the file, or a preset, set it)."""
    why: dict[str, str] = {}
    auto = f"auto: {found.kind}"

    choices = dict(CHOICES[found.kind])
    reach = join_reach(found)
    farther = reach is not None and reach > float(choices["post.join_m"])  # type: ignore[arg-type]
    if farther:
        choices["post.join_m"] = reach

    def filled(settings: Any, block: str) -> Any:
        changes: dict[str, Any] = {}
        for key in AUTO_KEYS:
            name = key.removeprefix(f"{block}.")
            if name != key:
                unset = getattr(settings, name) is None
                why[key] = auto if unset else given
                if unset:
                    changes[name] = choices[key]
                    if key == "post.join_m" and farther:
                        why[key] = (f"{auto}, {found.clearance_m:.2f} m from the walls every "
                                    f"{found.step_m:.2f} m")
        return dataclasses.replace(settings, **changes)

    scene = dataclasses.replace(scene, detection=filled(scene.detection, "detection"),
                                mapping=filled(scene.mapping, "mapping"),
                                post=filled(scene.post, "post"))
    placement = scene.sensors.placement
    if isinstance(placement, WallFollowing):
        unset = placement.start_deg is None
        why["sensors.placement.start_deg"] = "auto: square to the walls" if unset else given
        if unset:
            geom = build_geometry(scene) if geom is None else geom
            start = square_to_walls(geom, placement.elements)
            if walls_share_heading(geom, placement.elements, start):
                scene = dataclasses.replace(scene, sensors=dataclasses.replace(
                    scene.sensors, placement=dataclasses.replace(placement, start_deg=start)))
            else:  # left unset: the placement turns each pose (sensors.pose_headings)
                why["sensors.placement.start_deg"] = "auto: square to each pose's nearest wall"
    return scene, why


def with_detection_chosen(scene: Scene, sensors: SensorArray) -> Scene:
    """``scene`` with the detection settings it leaves out chosen as :func:`choose_settings`
    would (for callers of the signal stage outside the pipeline)."""
    if scene.detection.min_envelope is not None:
        return scene
    floor = CHOICES[survey(scene, sensors).kind]["detection.min_envelope"]
    assert isinstance(floor, float)
    return dataclasses.replace(scene, detection=dataclasses.replace(
        scene.detection, min_envelope=floor))
