"""Transducers of a scene and the transmitter→receiver pairs that fire (thesis §2.1, §2.1.2).

The sensors of a scene are its explicit ``sensors.transducers`` (in file order) followed by
those its ``sensors.placement`` places; indices into :class:`SensorArray` are the ``tx`` and
``rx`` of the echo table. Every transducer belongs to a *group*: one linear array of
``random-lines`` or ``per-wall``, one ring of ``circular``, one pose of ``wall-following``; explicit
transducers keep their ``group`` key. Placed groups are numbered after the explicit ones.

Which pairs fire (:func:`pairs`): every transducer transmits in turn and every transducer of
its own group receives, so a group of n transducers gives n² ordered pairs (T, R), T = R
included (the line-of-sight echo of thesis §2.1.1 part 1; T ≠ R the elliptical echoes of
part 2). Transducers of different groups never pair: the arrays and the ring poses fire at
different times. (T, R) and (R, T) travel the same paths, but their received signals carry
independent noise, so both are kept.

Placements (each returns ``(positions [n, 2], headings_deg [n], group per element [n] int64
from 0, poses [G, 2])``): :func:`place_random_lines` (thesis §2.1, §3.1),
:func:`place_circular` and :func:`place_wall_following` (§2.1.2, traced by
:func:`wall_following_path`; several at once, the rooms of a floor, by
:func:`place_sensors_together`), :func:`place_per_wall` (§3.6, Figs 3.21–3.22). They are
deterministic: random numbers come only from the
placement's ``seed``. A placement that cannot be made raises
:class:`~clsonar.errors.SceneError` with key ``sensors.placement`` and the scene's name as
source.
"""

from .array import SensorArray, heading_deg, pairs, place_sensors, place_sensors_together
from .headings import pose_headings, square_to_walls, walls_share_heading
from .lines import per_wall_lines, per_wall_seed, place_per_wall, place_random_lines
from .rings import (
    place_circular,
    place_wall_following,
    ring,
    wall_following_path,
    wall_following_paths,
    wall_following_substep,
)
from .space import Placed, in_free_space

__all__ = [
    "Placed",
    "SensorArray",
    "heading_deg",
    "in_free_space",
    "pairs",
    "per_wall_lines",
    "per_wall_seed",
    "place_circular",
    "place_per_wall",
    "place_random_lines",
    "place_sensors",
    "place_sensors_together",
    "place_wall_following",
    "pose_headings",
    "ring",
    "square_to_walls",
    "wall_following_path",
    "wall_following_paths",
    "wall_following_substep",
    "walls_share_heading",
]
