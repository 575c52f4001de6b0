"""How strong a reflector's echoes are against a flat mirror's (``mapping.mode =
"reflectors"``): the floor a plane's echoes must reach, and a convex curve's, so that a
face's echoes are told from its edge's diffraction (docs/mapping.md; the uniform theory's
half a mirror's on a reflection boundary, docs/physics.md)."""

from __future__ import annotations

import numpy as np

from ..numerics import median
from ..physics import (
    J1_FIRST_ZERO,
    MAX_FOCUS_GAIN,
    absorption_factor,
    curved_gain,
    edge_diffraction,
    piston_pattern,
    wedge_angles,
)
from ..scene import Scene, Sinusoid
from .models import curve_geometry, dot2

#: A plane's echo is at least this share of a flat mirror's at its reflection point (less
#: three noise σ). Diffraction at a face's end continues the face's echoes past it, at half
#: a mirror's on the reflection boundary and less further on (physics.edge_gain): those
#: echoes are the edge's, not a longer face's.
MIRROR_SHARE = 0.6

#: The most an edge's diffraction gives, as a share of a flat mirror's echo: half, on a
#: face's reflection boundary (the uniform theory, physics.edge_diffraction; Kouyoumjian
#: & Pathak 1974). Noise never lowers a plane's floor below it.
EDGE_SHARE = 0.5


def mirror_echo(scene: Scene) -> float:
    """A flat mirror's echo on both transducers' axes, A0·ρ (units)."""
    return scene.transducer.amplitude * scene.echo.reflection_coefficient


def strongest_echo(scene: Scene, concave: bool = True) -> float:
    """The largest amplitude one echo can have (the transmitted amplitude times the
    reflection coefficient, on both axes, from a flat wall or, with ``echo.curvature_gain``,
    a focusing one, physics.MAX_FOCUS_GAIN, unless ``concave`` is False: the scene has no
    concave surface), with 5 % and three noise σ to spare: a detection above it is two or
    more echoes overlapping."""
    focus = MAX_FOCUS_GAIN if scene.echo.curvature_gain and concave else 1.0
    return 1.05 * mirror_echo(scene) * focus + 3.0 * scene.signal.noise_std


def mirror_floor(q: np.ndarray, T: np.ndarray, axT: np.ndarray, R: np.ndarray,
                 axR: np.ndarray, mirror: float | np.ndarray, ka: float,
                 noise_std: float) -> np.ndarray:
    """The least amplitude the pairs (T, R) hear from a flat mirror with reflection points
    ``q``: :data:`MIRROR_SHARE` of ``mirror``·b(θ_T)·b(θ_R), less three σ of the
    detections' amplitude noise, but at least :data:`EDGE_SHARE` of it (an echo no
    stronger than that may be a face's edge diffracting); −inf (anything) when
    ``mirror`` is 0."""
    if np.all(np.asarray(mirror) <= 0):
        return np.full(len(q), -np.inf)
    heard = mirror * two_way(q, T, axT, R, axR, ka)
    return np.maximum(MIRROR_SHARE * heard - 3.0 * noise_std, EDGE_SHARE * heard)


def mirror_strong(amplitude: np.ndarray, q: np.ndarray, T: np.ndarray, axT: np.ndarray,
                  R: np.ndarray, axR: np.ndarray, mirror: float | np.ndarray, ka: float,
                  noise_std: float) -> np.ndarray:
    """Whether echoes of ``amplitude`` are as strong as a flat mirror's with reflection
    points ``q`` for the pairs (T, R) (:func:`mirror_floor`); all, when ``mirror`` is 0."""
    return amplitude >= mirror_floor(q, T, axT, R, axR, mirror, ka, noise_std)


def quieter_than_a_plane(scene: Scene, normal: np.ndarray, T: np.ndarray, axT: np.ndarray,
                         R: np.ndarray, axR: np.ndarray, a: np.ndarray,
                         amplitude: np.ndarray, noise_std: float) -> bool:
    """Whether every echo (pairs (T, R), half paths ``a``, of ``amplitude``) is weaker
    than a flat mirror of unit ``normal`` tangent to their loci would return it
    (:func:`mirror_floor` at the loci's points c + a·n, c the pair's middle, with the
    absorption over the path 2a): a convex edge heard by a ring moving straight at it
    returns loci that one plane square to the motion touches too, but an edge's
    diffraction is a fraction of a mirror's echo."""
    q = 0.5 * (T + R) + a[:, None] * normal
    mirror = mirror_echo(scene) * absorption_factor(2.0 * a, scene.echo.absorption_db_per_m)
    ka = scene.transducer.beam(scene.medium.c)[1]
    return bool(np.all(amplitude < mirror_floor(q, T, axT, R, axR, mirror, ka, noise_std)))


def two_way(q: np.ndarray, T: np.ndarray, axT: np.ndarray, R: np.ndarray, axR: np.ndarray,
            ka: float, q_r: np.ndarray | None = None) -> np.ndarray:
    """The two-way beam b(θ_T)·b(θ_R) of the pairs (T, R) with unit axes towards ``q``
    (R's towards ``q_r`` where given: a corner's double bounce leaves T and reaches R along
    different legs): the piston's patterns, without the hard cut."""
    out = np.ones(len(q))
    for X, axis, towards in ((T, axT, q), (R, axR, q if q_r is None else q_r)):
        d = towards - X
        dist = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)
        out = out * piston_pattern(ka * np.abs(axis[:, 0] * d[:, 1] - axis[:, 1] * d[:, 0])
                                   / dist)
    return out


#: Two echoes arriving together are heard at most this many times as loud as the louder
#: (in phase).
OVERLAP_FACTOR = 2.0

#: The piston's main lobe, k·a·sinθ from the axis to the first null, for its inverse.
_LOBE_X = np.linspace(0.0, J1_FIRST_ZERO, 4001)
_LOBE_B = piston_pattern(_LOBE_X)


def loud_beams(scene: Scene, loci, spare: float) -> np.ndarray | None:
    """[n] sin² of the widest angle θ off its transducer's axis the echo of each T = R locus
    can come from, as loud as it was heard: a reflector there returns at most
    :func:`strongest_echo` (focused only by a sinusoid's troughs: walls and solid discs
    do not focus) times the two-way beam b(θ)², two echoes together
    :data:`OVERLAP_FACTOR` times that (``spare``: the amplitude's noise). A Polaroid's
    echo of a mirror's strength comes from within 5° of its axis (b(θ)² ≥ 0.5): a point
    drawn 9.3° off it (b² = 0.06), where two loci of different reflectors touch one
    tangent, is not where that echo came from (the zoo's unseen seed 31 room-19: a wall
    heard at 4.5 units from one pose and, from the next, where a box hid the wall, a
    corner's double bounce 7 cm of range later, put a stretch 10 cm in front of the
    wall: 0.85 cm RMS). Loci of T ≠ R pairs: 1 (any angle). None where the amplitude
    cannot tell the angle: threshold detection (a sample, not the echo's peak) or a
    uniform beam (``transducer.directivity``)."""
    _, ka = scene.transducer.beam(scene.medium.c)
    if scene.detection.mode != "envelope" or ka == 0:
        return None
    concave = any(isinstance(s, Sinusoid) for s in scene.surfaces)  # walls, solid discs: none
    share = (loci.amplitude - spare) / (OVERLAP_FACTOR * strongest_echo(scene, concave))
    b = np.sqrt(np.clip(share, 0.0, 1.0))  # the least b(θ) the echo needs
    x = np.interp(b, _LOBE_B[::-1], _LOBE_X[::-1])  # b falls from 1 to 0 over the lobe
    return np.where(loci.tx == loci.rx, (x / ka) ** 2, 1.0)


def as_flat_as_its_range(params: np.ndarray, x0: np.ndarray, paths: np.ndarray) -> bool:
    """Whether the curve model ``params`` (about ``x0``) is at least as flat as its range:
    its radius at least half the median of ``paths`` (a plane always). A face, or the
    slight bend of its last stretch (its echoes' times shifted by its edge's diffraction
    arriving with them), whose echo is a mirror's; not a curved wall's own circle (a
    post, a cylinder, a sinusoid's crest), whose echo the strength cannot tell from an
    edge's."""
    return abs(float(curve_geometry(params, x0)[1])) >= 0.5 * float(median(paths))


#: A circle of radius under this share of its range is point-like (:func:`convex_share`):
#: its echo, a thin post's or an edge's, is no divergence's share of a mirror's (a box
#: corner's 55 diffractions 3 m away, 0.006 of a mirror's, fit circles of 1–100 mm,
#: whose geometrical divergence gives 0.02–0.19).
POINT_LIKE = 0.1


def convex_share(params: np.ndarray, x0: np.ndarray, q: np.ndarray, T: np.ndarray,
                 R: np.ndarray, paths: np.ndarray) -> np.ndarray | None:
    """The echo of the curve model ``params`` (about ``x0``) at the reflection points ``q``
    of the pairs (T, R), paths ``paths``, over a flat mirror's, where it is less (a
    convex surface's divergence, physics.curved_gain: a curved wall's echo is a
    mirror's times its focusing; a concave one's, not counted above 1 as a scene may
    leave the focusing out; past its caustic, where a circle more bent than its range
    reflects, less): past a face's end its edge's diffraction, half a mirror's on the
    reflection boundary and less beyond, is no slightly curved wall's echo; nor are a
    face's echo and its edge's four, 20× weaker, one convex circle of 1 m at 4.3 m (0.43
    of a mirror's: the zoo's seed 11 corner-03), nor a sinusoid's crests and troughs one
    loose concave circle. A lower bound whether the scene's echoes model the curvature
    or not (``echo.curvature_gain``: without it every curve echoes a mirror's). None
    without reflection points, or for a circle of radius under :data:`POINT_LIKE` of its
    range (half the median path)."""
    centre, rho, _ = curve_geometry(params, x0)
    if not np.all(np.isfinite(centre)):
        return np.ones(len(q))
    if not len(q) or abs(rho) < POINT_LIKE * 0.5 * float(median(paths)):
        return None
    d1 = np.maximum(np.hypot(*(T - q).T), 1e-12)
    d2 = np.maximum(np.hypot(*(R - q).T), 1e-12)
    normal = (q - centre) / np.maximum(np.hypot(*(q - centre).T), 1e-12)[:, None]
    cos_i = np.maximum(np.abs(dot2(normal, (T - q) / d1[:, None])), 1e-6)
    kappa = np.full(len(q), 1.0 / rho)  # the surface's curvature, convex > 0
    return np.minimum(curved_gain(d1, d2, kappa, cos_i), 1.0)


def face_end_echo(T: np.ndarray, R: np.ndarray, E: np.ndarray, outward: np.ndarray,
                  k: float, rho: float) -> np.ndarray:
    """A face's echo over a flat mirror's, ``|ρ + G·e^(−ik·δ)| / ρ``, for the pairs (T, R)
    whose reflection points lie on a face that ends at ``E`` (each row its own), the face
    leaving it along −``outward``: its specular echo ρ and the diffraction G of its end,
    a half-plane's (physics.edge_diffraction, wavenumber ``k``, the faces' reflection
    coefficient ``rho``), which arrives δ = d1 + d2 − the mirror path later, within the
    pulse. Half a mirror's (:data:`EDGE_SHARE`) with the reflection point on the edge,
    rising to the knife edge's first Fresnel maximum, about 1.17, a Fresnel zone inside
    (4 cm at 0.5 m, 15 cm at 9 m), then rippling about 1: the uniform theory near the
    reflection boundary, whose term is nearly the same for any wedge (a thin wall's end
    or a box's corner: within 5 % for wedges of 11–150°, up to 11 % for a nearly flat
    one, 169°, with the reflection point on its edge), and what clsonar's echoes and
    envelope detection give near the edge (tests/test_face_ends.py; farther in, where δ
    parts the two pulses, the ripples are weaker)."""
    t = np.asarray(outward, dtype=np.float64)
    face = np.broadcast_to(-t, E.shape)
    d1, d2 = np.hypot(*(E - T).T), np.hypot(*(E - R).T)
    phi_t, n = wedge_angles(T, E, face, face)
    phi_r, _ = wedge_angles(R, E, face, face)
    g = edge_diffraction(d1, d2, phi_t, phi_r, n, k, 1.0, rho)
    normal = np.array([-t[1], t[0]])  # the mirror path through the face's line (T, R in front)
    hT, hR = dot2(E - T, normal), dot2(E - R, normal)
    mirror = np.sqrt(np.maximum(4.0 * hT * hR + np.sum((T - R) ** 2, axis=-1), 0.0))
    # the diffracted echo arrives (d1 + d2) − mirror later: its carrier turns by k times that
    return np.abs(rho + g * np.exp(-1j * k * (d1 + d2 - mirror))) / rho


#: :func:`edge_distance` looks for the first rise through a ratio on this many steps of
#: its reach, then bisects the step it finds this many times (nanometres).
EDGE_GRID = 128
EDGE_STEPS = 20


def edge_distance(ratio: np.ndarray, T: np.ndarray, R: np.ndarray, q: np.ndarray,
                  outward: np.ndarray, k: float, rho: float, reach: float) -> np.ndarray:
    """How far beyond the reflection points ``q`` of the pairs (T, R), along the unit
    ``outward``, a face ends whose echoes there are ``ratio`` of a mirror's: the nearest
    distance in [0, ``reach``] at which :func:`face_end_echo`, rising from half a
    mirror's on the edge to its first maximum (the knife edge's first Fresnel maximum,
    about 1.17), is ``ratio`` (the first of :data:`EDGE_GRID` steps where it reaches
    it, bisected); 0 for a ratio no more than its value on the edge, ``reach`` for one
    it does not reach there (or within a few thousandths of its maximum, which may fall
    between the grid's steps: the mapping inverts weak echoes, under 0.9 of a face's)."""
    ratio = np.asarray(ratio, dtype=np.float64)
    grid = np.linspace(0.0, float(reach), EDGE_GRID + 1)
    E = q[:, None, :] + grid[None, :, None] * outward  # [pairs, steps, 2]
    echo = face_end_echo(np.repeat(T, len(grid), 0), np.repeat(R, len(grid), 0),
                         E.reshape(-1, 2), outward, k, rho).reshape(len(ratio), len(grid))
    reached = echo >= ratio[:, None]
    first = np.where(reached.any(axis=1), np.argmax(reached, axis=1), len(grid))
    lo = grid[np.clip(first - 1, 0, len(grid) - 1)]
    hi = grid[np.clip(first, 0, len(grid) - 1)]
    for _ in range(EDGE_STEPS):
        mid = 0.5 * (lo + hi)
        below = face_end_echo(T, R, q + mid[:, None] * outward, outward, k, rho) < ratio
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return np.where(first == 0, 0.0, np.where(first == len(grid), float(reach), 0.5 * (lo + hi)))


def corner_echo(scene: Scene, vertex: np.ndarray, T: np.ndarray, axes: np.ndarray,
                rho: np.ndarray, ka: float) -> np.ndarray:
    """[k] The echo a concave right-angled corner at ``vertex`` returns to the transducers
    at ``T`` [k, 2] with unit ``axes`` [k, 2], each its own receiver, ``rho`` [k] away: its
    double bounce, a mirror's A0·ρ with the absorption over 2ρ, times the reflection
    coefficient (the second bounce) and the two-way beam towards the vertex."""
    mirror = mirror_echo(scene) * absorption_factor(2.0 * rho, scene.echo.absorption_db_per_m)
    return mirror * scene.echo.reflection_coefficient * two_way(
        np.tile(vertex, (len(T), 1)), T, axes, T, axes, ka)


def circle_echo(scene: Scene, T: np.ndarray, axes: np.ndarray, centre: np.ndarray,
                radius: float) -> np.ndarray:
    """[k] The echo amplitude a circle (``centre``, ``radius``: a pillar) returns to the
    transducers at ``T`` [k, 2] with unit ``axes`` [k, 2], each its own receiver (T = R):
    a flat mirror's A0·ρ times the two-way beam towards the circle's point nearest it, the
    gain of the circle's curvature seen from the distance d to that point, sqrt(R/(R + d))
    (``physics.curved_gain``; 1 without ``echo.curvature_gain``), and the absorption over
    the path 2·d — the echo engine's specular amplitude of a convex circle."""
    out = T - centre
    far = np.maximum(np.hypot(out[:, 0], out[:, 1]), radius + 1e-12)
    q = centre + radius * out / far[:, None]
    d = far - radius
    gain = (curved_gain(d, d, np.full(len(d), 1.0 / radius), np.ones(len(d)))
            if scene.echo.curvature_gain else 1.0)
    return (mirror_echo(scene) * two_way(q, T, axes, T, axes, scene.transducer.beam(
        scene.medium.c)[1]) * gain * absorption_factor(2.0 * d, scene.echo.absorption_db_per_m))


__all__ = [
    "EDGE_SHARE",
    "MIRROR_SHARE",
    "OVERLAP_FACTOR",
    "POINT_LIKE",
    "as_flat_as_its_range",
    "circle_echo",
    "convex_share",
    "corner_echo",
    "edge_distance",
    "face_end_echo",
    "loud_beams",
    "mirror_echo",
    "mirror_floor",
    "mirror_strong",
    "quieter_than_a_plane",
    "strongest_echo",
    "two_way",
]
