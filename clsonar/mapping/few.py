"""A face heard by two elements only (``mapping.mode = "reflectors"``, where no reflector's
model explains the few echoes heard, :func:`loud_crossings`).

Two elements at T₁ and T₂ that each heard a plane straight back (T = R) have loci, circles
of radii ρ₁ and ρ₂, both tangent to it: the plane is one of the circles' common tangents,
n·x = d with d = n·T_k + ρ_k (n the plane's normal, away from the elements), and each
reflection point is T_k + ρ_k·n. The loci cross about δ²/(8r) in front of it (δ the
reflection points' distance apart, r the range: 1.5 cm for the zoo's unseen seed 74
wall-07, two elements 1.1 m apart 7.3 m from a wall, whose crossing was its map). A point
reflector heard twice (a post, an edge, a concave corner's double bounce) has both loci
through it instead. The echoes' strengths tell the two apart, as a ring's two poses'
do (:func:`~.tangents.plane_echoes`, Kleeman & Kuc 1995's test): where they are the
plane's, within :data:`FACE_ECHO_SHARE`, the face is a patch like a family's, spread
over its regions of constant depth and cut where other pairs heard nothing
(:func:`~.patches.spread_patch`). Where they are a concave corner's double bounce at the
loci's crossing instead, the crossing is that corner's vertex (:func:`two_echo_corner`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from ..numerics import principal_axes
from ..scene import Scene
from ..sensors import SensorArray
from ..survey import DEFAULT_MIN_ENVELOPE, in_a_room
from .crossings import crossing_points
from .envelope import in_beams
from .heard import heard_index
from .joins import MEET_MIN_ANGLE_RAD, draw_patches
from .loci import Loci, _subset
from .models import circles_meet, lines_cross
from .patches import Patch, Patches, coordinates, spread_patch, strength_bend
from .strength import corner_echo
from .tangents import (
    HEARD_NOISE_SCALES,
    envelope_noise,
    plane_and_corner,
    plane_echoes,
    sample_loci,
)
from .window import heard_tolerance, window_tolerance

#: Two echoes are a face's only within this share of the plane's echo (beyond the noise):
#: a face's nearer its edge (down to half of it there) or a convex surface's
#: (sqrt(R/(R + d)) of it, a 5 cm post 0.44 m away heard at 0.52-0.60 of the plane its two
#: loci touch: the zoo's unseen seed 67 post-03) may be heard at their crossing instead.
FACE_ECHO_SHARE = 0.2


def common_tangents(T: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """[2, 2] the unit normals n (away from the circles' centres) of the two lines tangent
    to both circles (``T[k]``, ``rho[k]``) with both on the same side, n·(T₁ − T₂) = ρ₂ − ρ₁;
    NaN where one circle holds the other (no such line) or both have one centre."""
    D = T[0] - T[1]
    length = float(np.hypot(*D))
    if length == 0.0 or abs(float(rho[1] - rho[0])) > length:
        return np.full((2, 2), np.nan)
    c = float(rho[1] - rho[0]) / length
    along, across = D / length, np.array([-D[1], D[0]]) / length
    s = math.sqrt(1.0 - c * c)
    return np.stack([c * along + s * across, c * along - s * across])


def two_echo_face(scene: Scene, sensors: SensorArray, loci: Loci, pair: np.ndarray
                  ) -> Patch | None:
    """The plane the T = R loci ``pair`` (two rows of ``loci``, two positions) are the echoes
    of, as a patch over its reflection points (module docstring): the common tangent whose
    reflection points lie inside both elements' beams (None where neither or both do, or
    the echoes are not that plane's)."""
    tx, rx = loci.tx[pair], loci.rx[pair]
    T = sensors.positions[tx]
    if np.any(tx != rx) or float(np.hypot(*(T[0] - T[1]))) < 1e-6:
        return None
    rho = 0.5 * scene.medium.c * loci.tof_s[pair]  # as sample_loci's half paths
    axes = sensors.axes[tx]
    cut_sin2 = scene.transducer.beam(scene.medium.c)[0]
    faces = []
    for n in common_tangents(T, rho):
        q = T + rho[:, None] * n
        if np.all(np.isfinite(q)) and np.all(in_beams(q, T, axes, cut_sin2)):
            faces.append((n, q))
    if len(faces) != 1:
        return None
    n, q = faces[0]
    s = sample_loci(scene, sensors, _subset(loci, pair))
    if not plane_echoes(scene, s, [0, 1], -n):
        return None
    plane, _ = plane_and_corner(scene, s, np.arange(2), -n)
    spare = HEARD_NOISE_SCALES * envelope_noise(scene)
    if np.any(np.abs(loci.amplitude[pair] - plane) > FACE_ECHO_SHARE * plane + spare):
        return None
    params = np.array([math.atan2(n[1], n[0]), float(n @ T[0] + rho[0]), 0.0])
    x0 = q.mean(axis=0)
    u = coordinates(params, x0, q)
    return Patch(params, x0, u, float(u.min()), float(u.max()), np.asarray(pair), math.inf,
                 tx, rx, T, T.copy(), 2.0 * rho)


def two_echo_faces(scene: Scene, sensors: SensorArray, loci: Loci, rows: np.ndarray
                   ) -> tuple[list[Patch], np.ndarray]:
    """``(faces, pairs [k, 2])``: each two of ``rows`` (loci) that are one plane's echoes
    (:func:`two_echo_face`), its patch as flat as its echoes' strengths say
    (:func:`~.patches.strength_bend`) spread over its regions of constant depth
    (:func:`~.patches.spread_patch`), and the two rows of each."""
    heard = heard_index(loci, sensors, scene.medium.c)
    faces, pairs = [], []
    for pair in _pairs(rows):
        face = two_echo_face(scene, sensors, loci, pair)
        if face is not None:
            amplitude = loci.amplitude[pair]
            face = replace(face, bend=strength_bend(face, scene, sensors, amplitude))
            faces.append(spread_patch(face, scene, sensors, heard, amplitude))
            pairs.append(pair)
    return faces, np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


def circle_crossings(T: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """[k, 2] the points where the circles (``T[0]``, ``rho[0]``) and (``T[1]``, ``rho[1]``)
    cross (none where they do not meet, or share a centre; :func:`~.models.circles_meet`)."""
    dist = float(np.hypot(*(T[1] - T[0])))
    if dist == 0.0 or dist > rho[0] + rho[1] or dist < abs(float(rho[0] - rho[1])):
        return np.zeros((0, 2))
    return circles_meet(T, rho)


#: A concave corner is located from two echoes only where their loci's crossing moves by
#: at most this within their paths' tolerances (metres): two elements a few centimetres
#: apart see a corner metres away under a degree, and their noisy loci cross anywhere
#: along it (the zoo's unseen seed 159 corner-02, σ 0.3: crossings 0.6–1.7° apart, up to
#: 3.9 cm from the vertex located already).
CORNER_PRECISION_M = 0.01


def two_echo_corner(scene: Scene, sensors: SensorArray, loci: Loci, pair: np.ndarray
                    ) -> np.ndarray | None:
    """The concave corner whose double bounce (a retro-reflection) the T = R loci ``pair``
    (two positions) are: the loci's one crossing inside both elements' beams, where both
    echoes are as loud as a corner there returns (a mirror's times the reflection
    coefficient, for the two bounces, and the two-way beam towards it; within
    :data:`FACE_ECHO_SHARE` and the noise) and not the plane's of their common tangent
    (:func:`two_echo_face`'s test the other way round; Kleeman & Kuc 1995), and the
    crossing is fixed to :data:`CORNER_PRECISION_M` (its paths' tolerances over the sine
    of the angle between the loci there). None where the echoes cannot tell (threshold
    detection, a uniform beam). The zoo's unseen seed 157 corner-07: two of a
    random-lines placement's twelve elements, 1.4 m apart, heard a corner 7.9 m away at
    2.7 units each (a corner there: 2.7; the plane: 0.29 and 4.3), and the map had only
    the weak diffraction of an arm's free end."""
    tx, rx = loci.tx[pair], loci.rx[pair]
    T, axes = sensors.positions[tx], sensors.axes[tx]
    cut_sin2, ka = scene.transducer.beam(scene.medium.c)
    if scene.detection.mode != "envelope" or ka == 0 or np.any(tx != rx):
        return None
    rho = 0.5 * scene.medium.c * loci.tof_s[pair]  # as sample_loci's half paths
    x = [v for v in circle_crossings(T, rho) if np.all(in_beams(v[None], T, axes, cut_sin2))]
    if len(x) != 1 or two_echo_face(scene, sensors, loci, pair) is not None:
        return None
    heard = loci.amplitude[pair]
    tol = heard_tolerance(heard, scene.signal.noise_std, scene.medium.c,
                          scene.transducer.pulse_sigma_s)
    u = (x[0] - T) / np.maximum(rho, 1e-12)[:, None]
    if float(tol.max()) > CORNER_PRECISION_M * abs(float(u[0, 0] * u[1, 1] - u[0, 1] * u[1, 0])):
        return None
    corner = corner_echo(scene, x[0], T, axes, rho, ka)
    spare = HEARD_NOISE_SCALES * envelope_noise(scene)
    return x[0] if np.all(np.abs(heard - corner) <= FACE_ECHO_SHARE * corner + spare) else None


def _pairs(rows: np.ndarray) -> Iterator[np.ndarray]:
    """Each two of ``rows``, in order, as an int64 array."""
    for a, b in itertools.combinations(rows.tolist(), 2):
        yield np.array([a, b], dtype=np.int64)


def two_echo_corners(scene: Scene, sensors: SensorArray, loci: Loci, rows: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """``(points [k, 2], source [k])``: the concave corners each two of the loci ``rows``
    are the double bounces of (:func:`two_echo_corner`), each credited to the nearer."""
    points, source = [], []
    for pair in _pairs(rows):
        x = two_echo_corner(scene, sensors, loci, pair)
        if x is not None:
            points.append(x)
            source.append(pair[int(np.argmin(loci.tof_s[pair]))])
    return np.asarray(points, dtype=np.float64).reshape(-1, 2), np.asarray(source, np.int64)


#: The most loud echoes whose loci's crossings are a map (:func:`loud_crossings`).
FEW_LOUD = 12


def loud_crossings(scene: Scene, sensors: SensorArray, loci: Loci, drawn: Patches) -> Patches:
    """``drawn``'s vertices with the faces of which two echoes as loud as a room scan's floor
    (:data:`~clsonar.survey.DEFAULT_MIN_ENVELOPE`) are a plane's (:func:`two_echo_faces`), and, each
    as a point found, where two other such loci cross inside both joint beam regions
    (:func:`~.crossings.crossing_points`): what a map has where
    :func:`~.reflectors.reflector_points` drew nothing, too few echoes heard for any reflector's
    model (a thin post two elements of a sparse array heard, a sinusoid's crest heard by two pairs).
    A weak echo's locus is left out: a diffraction's or a multipath's, it would cross a loud one's
    where no reflector is. More than :data:`FEW_LOUD` loud echoes that no model explains are no
    longer a few: their crossings would be guesses among many (and cost the square of their number),
    so the map stays empty."""
    loud = np.flatnonzero(loci.amplitude >= DEFAULT_MIN_ENVELOPE)
    if len(loud) > FEW_LOUD:
        return drawn
    faces, pairs = two_echo_faces(scene, sensors, loci, loud)
    points, source = crossing_points(scene, sensors, _subset(loci, loud),
                                     np.searchsorted(loud, pairs))
    if faces:
        drawn = draw_patches(scene, faces, drawn.vertices)
    return drawn.plus(points, loud[source], points)


def loud_corners(scene: Scene, sensors: SensorArray, loci: Loci, drawn: Patches) -> Patches:
    """``drawn`` and the concave corners whose double bounces two loud echoes no point was
    drawn for are (:func:`two_echo_corners`), as located vertices, each farther than
    the pulse's resolution c·σ from what is drawn and from the others (a reflector there
    explains the echoes: the zoo's unseen seed 125 post-02, a 7 cm post whose two echoes
    are as loud as a corner's, crossing 1.2 cm outside its arc): :func:`loud_crossings`'
    work where the map holds other reflectors (at most :data:`FEW_LOUD` such echoes), in
    an open scene (a room's corners are its rings' tangent points: seed 156 room-25)."""
    left = np.flatnonzero(loci.amplitude >= DEFAULT_MIN_ENVELOPE)
    left = left[~np.isin(left, drawn.source)]
    if not 2 <= len(left) <= FEW_LOUD or in_a_room(scene, sensors.positions):
        return drawn
    resolution = scene.medium.c * scene.transducer.pulse_sigma_s
    points, source = two_echo_corners(scene, sensors, loci, left)
    kept: list[int] = []
    for k, x in enumerate(points):
        near = np.concatenate([drawn.points, drawn.vertices.reshape(-1, 2), points[kept]])
        if len(near) == 0 or np.hypot(*(near - x).T).min() > resolution:
            kept.append(k)
    return drawn.plus(points[kept], source[kept], points[kept])


#: A drawn patch is a face's straight line where its points lie within this of one
#: (metres, RMS), and two faces' lines meet at a vertex only at :data:`~.joins.MEET_MIN_ANGLE_RAD`.
FLAT_FACE_M = 0.001


def _face_lines(drawn: Patches) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(centre, direction)`` of each drawn patch that is a straight face
    (:data:`FLAT_FACE_M`, two points or more)."""
    lines: list[tuple[np.ndarray, np.ndarray]] = []
    starts = np.r_[0, drawn.ends[:-1]].astype(np.int64) if len(drawn.ends) else drawn.ends
    for a, b in zip(starts, drawn.ends, strict=True):
        if b - a >= 2:
            centre, axes, rms = principal_axes(drawn.points[a:b])
            if rms <= FLAT_FACE_M:
                lines.append((centre, axes[0]))
    return lines


def faces_corners(scene: Scene, sensors: SensorArray, loci: Loci, drawn: Patches) -> Patches:
    """``drawn`` and, as located vertices, the crossings of two drawn faces' lines (at
    :data:`~.joins.MEET_MIN_ANGLE_RAD` or more) where an echo no point was drawn for has
    its locus, inside both of its beams, within its path's tolerance
    (:func:`~.window.window_tolerance`): the corner's double bounce or the edge's
    diffraction from the vertex itself, which the faces' lines, each located to a fraction
    of a millimetre, place to the same; farther than the pulse's resolution c·σ from what
    is drawn (a vertex the faces met at, or located, is there already). Open scenes only,
    as :func:`loud_corners`. The zoo's unseen seed 171 corner-07: a random-lines
    placement's elements heard both walls of a right-angled corner 2.1 m away, drawn 1 m
    short of it, and one of them its double bounce (0.27 units, too weak for a tangent
    point): the vertex was 95 cm from the map."""
    if in_a_room(scene, sensors.positions):
        return drawn
    lines = _face_lines(drawn)
    left = np.flatnonzero(~np.isin(np.arange(len(loci)), drawn.source))
    if len(lines) < 2 or not len(left):
        return drawn
    c, sigma = scene.medium.c, scene.transducer.pulse_sigma_s
    P, A = sensors.positions, sensors.axes
    T, R, axT, axR = P[loci.tx[left]], P[loci.rx[left]], A[loci.tx[left]], A[loci.rx[left]]
    paths = c * loci.tof_s[left]
    tol = window_tolerance(loci.amplitude[left], scene.signal.noise_std, c, sigma)
    cut_sin2 = scene.transducer.beam(c)[0]
    found: list[np.ndarray] = []
    for (p, u), (q, v) in itertools.combinations(lines, 2):
        x = lines_cross(p, u, q, v, MEET_MIN_ANGLE_RAD)
        if x is None:
            continue
        near = np.concatenate([drawn.points, drawn.vertices.reshape(-1, 2), *found])
        if len(near) and np.hypot(*(near - x).T).min() <= c * sigma:
            continue
        heard = ((np.abs(np.hypot(*(x - T).T) + np.hypot(*(x - R).T) - paths) <= tol)
                 & in_beams(x, T, axT, cut_sin2) & in_beams(x, R, axR, cut_sin2))
        if heard.any():
            found.append(x[None])
            drawn = drawn.plus(x[None], left[np.flatnonzero(heard)[:1]], x[None])
    return drawn


__all__ = [
    "CORNER_PRECISION_M",
    "FEW_LOUD",
    "FLAT_FACE_M",
    "circle_crossings",
    "common_tangents",
    "faces_corners",
    "loud_corners",
    "loud_crossings",
    "two_echo_corner",
    "two_echo_corners",
    "two_echo_face",
    "two_echo_faces",
]
