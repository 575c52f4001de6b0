"""Transducers of a scene and the transmitter→receiver pairs that fire (thesis §2.1, §2.1.2).

The sensors of a scene are its explicit ``sensors.transducers`` (in file order) followed by
those its ``sensors.placement`` places; indices into :class:`SensorArray` are the ``tx`` and
``rx`` of the echo table. Every transducer belongs to a *group*: one linear array of
``random-lines``, one ring of ``circular``, one pose of ``wall-following``; explicit
transducers keep their ``group`` key. Placed groups are numbered after the explicit ones.

Which pairs fire (:func:`pairs`): every transducer transmits in turn and every transducer of
its own group receives, so a group of n transducers gives n² ordered pairs (T, R), T = R
included (the line-of-sight echo of thesis §2.1.1 part 1; T ≠ R the elliptical echoes of
part 2). Transducers of different groups never pair: the arrays and the ring poses fire at
different times. (T, R) and (R, T) travel the same paths, but their received signals carry
independent noise, so both are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import Geometry, build_geometry
from .scene import Circular, RandomLines, Scene, WallFollowing


@dataclass(frozen=True, eq=False)
class SensorArray:
    """All transducers of a scene, as arrays (float64)."""

    positions: np.ndarray  # [N, 2] metres
    headings_deg: np.ndarray  # [N] direction of each transducer's axis, degrees from +x
    groups: np.ndarray  # [N] int64 pair group
    poses: np.ndarray  # [G, 2] ring centres of circular / wall-following placements

    def __len__(self) -> int:
        return len(self.positions)

    @property
    def axes(self) -> np.ndarray:
        """[N, 2] unit vectors along each transducer's axis."""
        h = np.radians(self.headings_deg)
        return np.stack([np.cos(h), np.sin(h)], axis=-1)


def ring(center: tuple[float, float], radius_m: float, elements: int,
         start_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions [n, 2] and outward headings [n] of a ring of ``elements`` transducers at
    equal angles from ``start_deg`` (thesis §2.1.2: 8 at 45° on a 6.5 cm radius)."""
    headings = start_deg + 360.0 * np.arange(elements) / elements
    h = np.radians(headings)
    pos = np.asarray(center, dtype=np.float64) + radius_m * np.stack([np.cos(h), np.sin(h)], -1)
    return pos, headings


def place_circular(p: Circular) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One ring, one group: (positions, headings_deg, group index per element, poses)."""
    pos, head = ring(p.center, p.radius_m, p.elements, p.start_deg)
    return pos, head, np.zeros(p.elements, dtype=np.int64), np.asarray([p.center], float)


def place_random_lines(p: RandomLines, scene: Scene, geom: Geometry):
    """Linear arrays of thesis §2.1 (see :class:`~clsonar.scene.RandomLines`)."""
    raise NotImplementedError


def place_wall_following(p: WallFollowing, scene: Scene, geom: Geometry):
    """Ring poses along the walls, thesis §2.1.2 (see :class:`~clsonar.scene.WallFollowing`)."""
    raise NotImplementedError


def place_sensors(scene: Scene, geom: Geometry | None = None) -> SensorArray:
    """The scene's transducers: explicit ones first, in file order, then placed ones."""
    explicit = scene.sensors.transducers
    pos = np.asarray([t.position for t in explicit], dtype=np.float64).reshape(-1, 2)
    head = np.asarray([t.heading_deg for t in explicit], dtype=np.float64)
    groups = np.asarray([t.group for t in explicit], dtype=np.int64)
    poses = np.zeros((0, 2))
    placement = scene.sensors.placement
    if placement is not None:
        if isinstance(placement, Circular):
            p_pos, p_head, p_group, poses = place_circular(placement)
        else:
            geom = geom if geom is not None else build_geometry(scene)
            place = (place_random_lines if isinstance(placement, RandomLines)
                     else place_wall_following)
            p_pos, p_head, p_group, poses = place(placement, scene, geom)
        first = int(groups.max()) + 1 if len(groups) else 0
        pos = np.concatenate([pos, p_pos])
        head = np.concatenate([head, p_head])
        groups = np.concatenate([groups, p_group + first])
    return SensorArray(pos, head, groups, np.asarray(poses, dtype=np.float64).reshape(-1, 2))


def pairs(sensors: SensorArray) -> np.ndarray:
    """[P, 2] int64 ordered (tx, rx) pairs that fire: all pairs within each group, T = R
    included, sorted by tx then rx (see the module docstring)."""
    g = sensors.groups
    if len(g) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    order = np.argsort(g, kind="stable")
    out = []
    bounds = np.flatnonzero(np.diff(g[order])) + 1
    for members in np.split(order, bounds):
        members = np.sort(members)
        tx, rx = np.meshgrid(members, members, indexing="ij")
        out.append(np.stack([tx.ravel(), rx.ravel()], axis=-1))
    result = np.concatenate(out)
    return result[np.lexsort((result[:, 1], result[:, 0]))]


def heading_deg(v: np.ndarray) -> np.ndarray:
    """Heading in degrees of direction vectors [..., 2]."""
    return np.degrees(np.arctan2(v[..., 1], v[..., 0]))


__all__ = ["SensorArray", "heading_deg", "pairs", "place_sensors", "ring"]
