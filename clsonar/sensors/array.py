"""All transducers of a scene as one :class:`SensorArray`, and the pairs that fire."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import SceneError
from ..geometry import Geometry, build_geometry
from ..scene import Circular, PerWall, RandomLines, Scene, WallFollowing
from .lines import place_per_wall, place_random_lines
from .rings import Traced, place_circular, place_wall_following, wall_following_paths


@dataclass(frozen=True, eq=False)
class SensorArray:
    """All transducers of a scene, as arrays (float64)."""

    positions: np.ndarray  # [N, 2] metres
    headings_deg: np.ndarray  # [N] direction of each transducer's axis, degrees from +x
    groups: np.ndarray  # [N] int64 pair group
    poses: np.ndarray  # [G, 2] ring centres (circular, wall-following) or array centres
    # (per-wall); none for random-lines

    def __len__(self) -> int:
        return len(self.positions)

    @cached_property
    def fired_pairs(self) -> np.ndarray:
        """[P, 2] the pairs that fire (:func:`pairs`), computed once, read-only."""
        out = _fired_pairs(self)
        out.flags.writeable = False
        return out

    @property
    def pair_count(self) -> int:
        """How many pairs fire (:func:`pairs`): the square of each pair group's size (T = R
        and both directions), counted without listing them."""
        _, sizes = np.unique(self.groups, return_counts=True)
        return int(np.sum(sizes.astype(np.int64) ** 2))

    @property
    def axes(self) -> np.ndarray:
        """[N, 2] unit vectors along each transducer's axis."""
        h = np.radians(self.headings_deg)
        return np.stack([np.cos(h), np.sin(h)], axis=-1)


def place_sensors_together(scenes: list[Scene], geoms: list[Geometry]
                           ) -> list[SensorArray | SceneError]:
    """:func:`place_sensors` of each of ``scenes`` (with its geometry), every
    wall-following trace of them all run side by side (:func:`wall_following_paths`: the
    rooms of a floor): each scene's transducers, or the error it raises alone."""
    jobs = [(k, p) for k, scene in enumerate(scenes)
            for p in (scene.sensors.placement, *scene.sensors.placements)
            if isinstance(p, WallFollowing)]
    traces = wall_following_paths([(p, scenes[k], geoms[k]) for k, p in jobs])
    traced: list[dict[int, Traced]] = [{} for _ in scenes]
    failed: dict[int, SceneError] = {}
    for (k, p), found in zip(jobs, traces, strict=True):
        if isinstance(found, SceneError):
            failed.setdefault(k, found)
        else:
            traced[k][id(p)] = found
    out: list[SensorArray | SceneError] = []
    for k, (scene, geom) in enumerate(zip(scenes, geoms, strict=True)):
        try:
            out.append(failed.get(k) or place_sensors(scene, geom, traced[k]))
        except SceneError as error:
            out.append(error)
    return out


def place_sensors(scene: Scene, geom: Geometry | None = None,
                  traced: dict[int, Traced] | None = None) -> SensorArray:
    """The scene's transducers: explicit ones first, in file order, then placed ones
    (``traced``: the wall-following placements' traces already run, by ``id``)."""
    explicit = scene.sensors.transducers
    pos = np.asarray([t.position for t in explicit], dtype=np.float64).reshape(-1, 2)
    head = np.asarray([t.heading_deg for t in explicit], dtype=np.float64)
    groups = np.asarray([t.group for t in explicit], dtype=np.int64)
    poses = [np.zeros((0, 2))]
    placements = [p for p in (scene.sensors.placement, *scene.sensors.placements)
                  if p is not None]
    for placement in placements:
        if isinstance(placement, Circular):
            p_pos, p_head, p_group, p_poses = place_circular(placement)
        else:
            geom = geom if geom is not None else build_geometry(scene)
            if isinstance(placement, RandomLines):
                p_pos, p_head, p_group, p_poses = place_random_lines(placement, scene, geom)
            elif isinstance(placement, PerWall):
                p_pos, p_head, p_group, p_poses = place_per_wall(placement, scene, geom)
            else:
                p_pos, p_head, p_group, p_poses = place_wall_following(
                    placement, scene, geom, (traced or {}).get(id(placement)))
        first = int(groups.max()) + 1 if len(groups) else 0
        pos = np.concatenate([pos, p_pos])
        head = np.concatenate([head, p_head])
        groups = np.concatenate([groups, p_group + first])
        poses.append(np.asarray(p_poses, dtype=np.float64).reshape(-1, 2))
    return SensorArray(pos, head, groups, np.concatenate(poses))


def pairs(sensors: SensorArray) -> np.ndarray:
    """[P, 2] int64 ordered (tx, rx) pairs that fire: all pairs within each group, T = R
    included, sorted by tx then rx (see :mod:`clsonar.sensors`). Computed once per array
    (read-only)."""
    return sensors.fired_pairs


def _fired_pairs(sensors: SensorArray) -> np.ndarray:
    g = sensors.groups
    if len(g) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    order = np.argsort(g, kind="stable")
    out = []
    bounds = np.flatnonzero(np.diff(g[order])) + 1
    for members in np.split(order, bounds):
        members = np.sort(members)
        pair = np.empty((len(members), len(members), 2), dtype=np.int64)
        pair[:, :, 0] = members[:, None]  # (tx, rx) row by row: tx, then rx, ascending
        pair[:, :, 1] = members[None, :]
        out.append(pair.reshape(-1, 2))
    result = np.concatenate(out)
    key = result[:, 0] * len(g) + result[:, 1]
    if np.all(key[1:] > key[:-1]):  # groups of consecutive transducers: already in order
        return result
    return result[np.lexsort((result[:, 1], result[:, 0]))]


def heading_deg(v: np.ndarray) -> np.ndarray:
    """Heading in degrees of direction vectors [..., 2]."""
    return np.degrees(np.arctan2(v[..., 1], v[..., 0]))
