"""Reflector-aware mapping (``mapping.mode = "reflectors"``, the default): the echoes of
each linear array fitted by reflector models (Kleeman & Kuc 1995), the rest by tangent
points.

Each pair group whose transducers lie on one line (a linear array) is cut into stretches of
at most :data:`WINDOW_M` (half overlapping); the detections of each stretch's pairs are
split into reflector families (:func:`~clsonar.mapping.families.find_families`): planes,
points (edges, thin posts), right-angled corners and circles (cylinders, a curved wall's
crests and troughs); the detections none explains are searched again, all arrays
together, a family whose echoes a located corner explains as well is that corner's
(:func:`corners_own`), and each plane takes those of them it predicts (:func:`_widened`:
another element's echo of its face). A plane is drawn over its reflection points' span and
a circle over its arc (:mod:`.patches`); points and corners are located vertices. Loci that
cross at one point so map to that point, and loci tangent to one curve to the curve,
whatever the angle between the surface and the array.

Groups that are not linear arrays (the rings of a wall-following scan) and every group of a
scene whose transducers stand inside a closed room are mapped as ``tangents`` maps them
(:func:`~clsonar.mapping.tangent_points`), unchanged.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import numpy as np

from .. import steps
from ..numerics import median, principal_axes, setdiff1d, union1d, unique
from ..scene import Scene
from ..scene.settings import chosen
from ..sensors import SensorArray
from ..survey import DEFAULT_MIN_ENVELOPE, in_a_room
from .families import (
    MIN_FAMILY,
    POINT_SPREAD,
    Family,
    Window,
    _predict,
    _valid,
    find_families,
    outside_allowed,
    window_tolerance,
)
from .heard import amplitude_noise, group_pairs, heard_index, loudest
from .joins import END_AT_VERTEX_M, draw_families
from .loci import Loci, _subset
from .models import corner_images, corner_paths, dot2
from .owners import (
    a_corners_echoes,
    as_plane,
    drawn_faces_echoes,
    fits_as_well,
    one_point_each,
    widened,
)
from .patches import Patches
from .starts import MIN_CURVE
from .strength import mirror_echo, strongest_echo, two_way
from .tangents import tangent_map
from .turned import turned_corners
from .window import BASE_TOLERANCE_M

#: Longest stretch of an array whose detections are fitted together, metres.
WINDOW_M = 1.0

#: A group is a linear array when its transducers lie within this of their line, metres
#: (and within this fraction of the array's length).
LINEAR_TOL_M = 0.01
LINEAR_TOL_SHARE = 0.02


def linear_groups(sensors: SensorArray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """``{group: (origin, unit direction)}`` of the groups of two or more transducers that
    lie on one line (a linear array): within :data:`LINEAR_TOL_M` (or
    :data:`LINEAR_TOL_SHARE` of the length, if less) of their principal axis."""
    out = {}
    for g in unique(sensors.groups):
        pos = sensors.positions[sensors.groups == g]
        if len(pos) < 2:
            continue
        centre, vt, _ = principal_axes(pos)
        along = dot2(pos - centre, vt[0])
        across = np.abs(dot2(pos - centre, vt[1])) if len(vt) > 1 else np.zeros(len(pos))
        length = float(along.max() - along.min())
        if length > 0 and across.max() <= min(LINEAR_TOL_M, LINEAR_TOL_SHARE * length + 1e-9):
            out[int(g)] = (centre, vt[0])
    return out


#: The search over all arrays together gives up after this many seeds in a row grew no
#: family (its seeds are single detections far apart; a few tell whether any wall is there).
GLOBAL_MAX_FAILED = 12

#: A free curve of the detections no stretch explained, all arrays together, needs this
#: many: scattered elements (thesis-style random lines, one element of each of several
#: arrays) see a reflector from directions far apart, so four of their detections fix a
#: circle and test it, as three do a plane (the zoo's seed 7 cylinder-03: a 1 m cylinder
#: heard by four pairs of three elements, an empty map; seed 0 sinusoid-03). An array's
#: stretch keeps :data:`~.starts.MIN_CURVE` (with four, seed 4 sinusoid-01's crests drew
#: circles of a crest's echoes and a trough's: 0.41 → 1.06 cm RMS), and so does the loose
#: pass (seed 6 corner-00: a circle of five distorted double bounces, 0.00 → 3.84 cm).
SCATTERED_CURVE = MIN_CURVE - 1

#: Neighbouring pairs of an array: transducers moved by at most this many element pitches.
NEIGHBOUR_PITCHES = 1.5


def _window(scene: Scene, sensors: SensorArray, loci: Loci, rows: np.ndarray,
            x0: np.ndarray, neighbour_m: float) -> Window:
    """The detections ``rows`` as a :class:`~.families.Window` about ``x0``."""
    c = scene.medium.c
    cut_sin2, _ = scene.transducer.beam(c)
    pos, axes = sensors.positions, sensors.axes
    amp = loci.amplitude[rows]
    tol = window_tolerance(amp, scene.signal.noise_std, c, scene.transducer.pulse_sigma_s)
    return Window(rows=rows, T=pos[loci.tx[rows]], R=pos[loci.rx[rows]],
                  axT=axes[loci.tx[rows]], axR=axes[loci.rx[rows]],
                  paths=c * loci.tof_s[rows], amplitude=amp, tolerance=tol, x0=x0,
                  cut_sin2=cut_sin2, neighbour_m=neighbour_m,
                  mirror=mirror_echo(scene),
                  ka=scene.transducer.beam(c)[1], noise_std=amplitude_noise(scene))


def _windows(scene: Scene, sensors: SensorArray, loci: Loci, rows: np.ndarray,
             origin: np.ndarray, direction: np.ndarray) -> list[Window]:
    """The stretches of one linear array (module docstring) with the detections of the
    pairs inside each."""
    pos = sensors.positions
    sT = dot2(pos[loci.tx[rows]] - origin, direction)
    sR = dot2(pos[loci.rx[rows]] - origin, direction)
    lo, hi = float(min(sT.min(), sR.min())), float(max(sT.max(), sR.max()))
    count = max(1, math.ceil((hi - lo) / (0.5 * WINDOW_M)) - 1)
    starts = (np.linspace(lo, max(lo, hi - WINDOW_M), count) if hi - lo > WINDOW_M
              else np.array([lo]))
    elements = unique(np.round(np.r_[sT, sR], 9))
    pitch = float(median(np.diff(elements))) if len(elements) > 1 else 1.0
    out = []
    for s0 in starts:
        inside = ((np.minimum(sT, sR) >= s0 - 1e-9)
                  & (np.maximum(sT, sR) <= s0 + WINDOW_M + 1e-9))
        if inside.any():
            mid = origin + direction * (s0 + 0.5 * min(WINDOW_M, hi - lo))
            out.append(_window(scene, sensors, loci, rows[inside], mid,
                               NEIGHBOUR_PITCHES * pitch))
    return out


def _families(scene: Scene, sensors: SensorArray, loci: Loci,
              arrays: dict[int, tuple[np.ndarray, np.ndarray]]
              ) -> tuple[list[Family], np.ndarray]:
    """The families of every linear array's stretches, then of the detections none
    explained, all arrays together (a wall seen by one element of each of several arrays);
    and the rows still unexplained (less the echoes a family's shadowed:
    :func:`~.families.shadowed`). Detections stronger than one echo can be
    (:func:`strongest_echo`) are left out: overlapping echoes, whose time of flight is
    neither's."""
    group_of = sensors.groups[loci.tx]
    resolution = scene.medium.c * scene.transducer.pulse_sigma_s
    single = loci.amplitude <= strongest_echo(scene)
    families: list[Family] = []
    left: list[np.ndarray] = []
    for g, (origin, direction) in arrays.items():
        rows = np.flatnonzero((group_of == g) & single)
        if len(rows) == 0:
            continue
        windows = _windows(scene, sensors, loci, rows, origin, direction)
        explained = np.zeros(len(loci), dtype=bool)
        for w in steps.each(f"array {g}: stretches", windows):
            found, free = find_families(w, resolution)
            families += found
            left.append(w.rows[free])
            for f in found:
                explained[f.loci] = True
        left[-len(windows):] = [r[~explained[r]] for r in left[-len(windows):]]
        # pairs farther apart than any stretch (an off-square corner's double bounce)
        covered = np.concatenate([w.rows for w in windows]) if windows else rows[:0]
        left.append(setdiff1d(rows, covered))
    rest = unique(np.concatenate(left)) if left else np.zeros(0, np.int64)
    if len(rest) >= MIN_FAMILY:
        x0 = sensors.positions[loci.tx[rest]].mean(axis=0)
        w = replace(_window(scene, sensors, loci, rest, x0, math.inf),
                    max_failed=GLOBAL_MAX_FAILED, least_curve=SCATTERED_CURVE)
        found, free = find_families(w, resolution)
        scattered = [_scattered_enough(f, group_of) for f in found]
        families += [f for f, ok in zip(found, scattered, strict=True) if ok]
        rest = union1d(rest[free], np.concatenate(
            [rest[:0], *(f.loci for f, ok in zip(found, scattered, strict=True) if not ok)]))
    families = turned_corners(corners_heard(families, sensors, loci, scene), group_of,
                              lambda r: _window(scene, sensors, loci, r,
                                                sensors.positions[loci.tx[r]].mean(axis=0),
                                                math.inf))
    families, dropped = planes_own(vertices_own(one_point_each(corners_own(
        families, resolution)), resolution))
    families, rest = _widened(scene, sensors, loci, families, union1d(rest, dropped))
    return families, _unshadowed(scene, sensors, loci, families, rest, resolution)


def _scattered_enough(f: Family, group_of: np.ndarray) -> bool:
    """Whether the family ``f`` of the search over all arrays together is one: a free
    curve of fewer than :data:`~.starts.MIN_CURVE` detections (:data:`SCATTERED_CURVE`)
    only where they are not all one array's, whose stretch it needs (the zoo's unseen seed
    117 edge-01: the face's four echoes that its edge's diffraction did not swallow, from
    three neighbouring elements at 8.5 m, each shifted by a millimetre by the diffraction
    arriving with it, fitted to a micrometre by a circle whose reflection points ran 14 cm
    past the located edge: 9.6 cm RMS)."""
    return (f.kind != "curve" or len(f.rows) >= MIN_CURVE
            or len(unique(group_of[f.loci])) > 1)


#: A located corner is its array's silence's where fewer than this share of the pairs that
#: would hear its double bounce did (:func:`corners_heard`).
CORNER_HEARD_SHARE = 0.5

#: Those pairs see the vertex within this of the direction one of its own pairs saw it
#: from (radians): inside the aperture of a corner that echoed to them.
CORNER_APERTURE_RAD = math.radians(10.0)


def corners_heard(families: list[Family], sensors: SensorArray, loci: Loci, scene: Scene
                  ) -> list[Family]:
    """``families`` with each corner that the silence of its own arrays refutes named a
    plane, where a plane explains each of its echoes within their tolerance as strongly as
    a mirror's. A right-angled corner retro-reflects: every pair of its arrays that sees
    the vertex from within :data:`CORNER_APERTURE_RAD` of one of its own pairs, and whose
    two-way beam along the double bounce's legs holds it at least as well as for the
    corner's weakest echo, would have heard it at its path (:func:`~.heard.loudest`);
    where fewer than :data:`CORNER_HEARD_SHARE` of them did, no corner is there. A few
    echoes of two neighbouring elements cannot tell a plane from a corner by their paths
    alone (they part by L²/(4r): 0.15 mm for elements 5.6 cm apart at 4.8 m, as much as
    a weak echo overlapping a detection shifts it): docs/reproduce's edge at 3 m, seed 0,
    a face's three echoes named a corner 0.56 m from the edge, which 3 of the 55 pairs
    that would have heard it did. Noise-free detections only: with noise the naming
    already takes a plane that explains the echoes within their noise
    (:func:`~.families.outside_allowed`), and a noisy sinusoid's trough named a corner was
    drawn as a plane across it (docs/reproduce's Fig 3.20 at σ 1.2: 0.40 → 0.49 cm)."""
    corners = [k for k, f in enumerate(families)
               if f.kind == "corner" and f.window.noise_std == 0]
    if not corners:
        return families
    heard = heard_index(loci, sensors, scene.medium.c)
    ka = scene.transducer.beam(scene.medium.c)[1]
    out = list(families)
    for k in corners:
        f = out[k]
        if _heard_share(f, sensors, loci, heard, ka) < CORNER_HEARD_SHARE:
            out[k] = as_plane(f) or f
    return out


def _heard_share(f: Family, sensors: SensorArray, loci: Loci, heard, ka: float) -> float:
    """The share of the pairs of corner ``f``'s arrays that would hear it
    (:func:`corners_heard`) and have a detection at its path (1 where none would)."""
    w, rows, v = f.window, f.rows, f.params[:2]
    own = _corner_gain(f.params, w.T[rows], w.axT[rows], w.R[rows], w.axR[rows], ka)
    seen = np.concatenate([_bearing(w.T[rows], v), _bearing(w.R[rows], v)])
    share, total = 0.0, 0
    for g in unique(sensors.groups[loci.tx[f.loci]]):
        for pairs in group_pairs(sensors, int(g)):
            T, R = sensors.positions[pairs[:, 0]], sensors.positions[pairs[:, 1]]
            near = _within(_bearing(T, v), seen) & _within(_bearing(R, v), seen)
            axT, axR = sensors.axes[pairs[:, 0]], sensors.axes[pairs[:, 1]]
            near &= _corner_gain(f.params, T, axT, R, axR, ka) >= own.min() * (1 - 1e-9)
            path, _ = corner_paths(f.params, T[near], R[near])
            share += float(np.count_nonzero(loudest(heard, pairs[near], path)[1]))
            total += int(np.count_nonzero(near))
    return share / total if total else 1.0


def _within(bearing: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """Whether each ``bearing`` (radians) turns by at most :data:`CORNER_APERTURE_RAD`
    to one of the directions ``seen``: ``min |angle(e^{i(b − s)})|`` over the seen
    directions nearest it round the circle, two on either side (the nearest has the
    least turn; the same minimum as over all of them, without a bearings × seen
    matrix: 10⁴ pairs against 3,700 directions took 17 s of the zoo's seed 0 corner-04)."""
    if len(seen) == 0:
        return np.zeros(len(bearing), dtype=bool)
    key = np.mod(seen, 2.0 * math.pi)
    order = np.argsort(key, kind="stable")
    at = np.searchsorted(key[order], np.mod(bearing, 2.0 * math.pi))
    near = order[np.mod(at[:, None] + np.arange(-2, 2), len(seen))]  # [bearings, 4]
    turn = np.angle(np.exp(1j * (bearing[:, None] - seen[near])))
    return np.min(np.abs(turn), axis=1) <= CORNER_APERTURE_RAD


def _bearing(X: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The directions (radians) from ``v`` to the points ``X`` [n, 2]."""
    return np.arctan2(X[:, 1] - v[1], X[:, 0] - v[0])


def _corner_gain(params: np.ndarray, T: np.ndarray, axT: np.ndarray, R: np.ndarray,
                 axR: np.ndarray, ka: float) -> np.ndarray:
    """The two-way beam (:func:`~.strength.two_way`) of a corner's double bounce: T's beam
    towards R's image, R's towards T's."""
    at_t, at_r = corner_images(params, T, R)
    return two_way(at_t, T, axT, R, axR, ka, at_r)


def corners_own(families: list[Family], resolution: float) -> list[Family]:
    """``families`` less those whose every echo a located corner of more rows explains
    (:func:`~clsonar.mapping.owners.a_corners_echoes`): pairs too close together for
    their range, or too noisy, to tell its double bounce from a plane's echo name it a
    plane through the vertex, square to their line of sight (the zoo's seed 3 corner-02,
    a 110° corner seen by a long array at 2.5 m and a short one at 7.7 m), or that it
    predicts as well once refitted to both, moving by at most ``resolution`` (the
    pulse's, c·σ: :func:`~clsonar.mapping.owners.fits_as_well`)."""
    corners = sorted((f for f in families if f.kind == "corner"), key=lambda f: -len(f.rows))
    certain = [functools.cache(lambda c=c: as_plane(c) is None) for c in corners]
    return [f for f in families
            if not any(a_corners_echoes(f, c) or fits_as_well(f, c, resolution, sure)
                       for c, sure in zip(corners, certain, strict=True))]


#: A family whose echoes a located vertex explains puts them elsewhere when some reflection
#: point of it lies farther than this from the vertex, metres
#: (:func:`a_vertexs_distorted_echoes`).
ELSEWHERE_M = 0.1


def a_vertexs_distorted_echoes(f: Family, vertex: Family, resolution: float) -> bool:
    """Whether every echo of ``f`` (a curve, point or corner family, or a plane where the
    vertex is a corner's) lies within
    ``resolution`` (the pulse's, c·σ) of the path the located ``vertex`` (a corner or
    point family of more rows) predicts for its pair, the vertex inside both beams: that
    vertex's echoes, which an overlapping echo shifted by millimetres, beyond its
    tolerance — a face's echo arriving a few resolutions later, or, at a corner off the
    right angle, the double bounce's other order (wall A then B against B then A, which
    part by millimetres) — and which a loose circle, or a right-angled corner elsewhere,
    fitted. The window search shadows such echoes (:func:`~.families.shadowed`), but only within one
    stretch of the array, and the vertex may have been located in another. Only where
    ``f`` puts them elsewhere: some reflection point of it more than
    :data:`ELSEWHERE_M` from the vertex (a crest located as a point by many pairs and as
    a circle about it by fewer is one reflector, and its circle is kept). A plane: a
    corner's double bounce merged with its wall's echo 4 cm of path later, which a plane
    through the vertex fitted to 0.1 mm and drew 25 cm past it, behind the other wall
    (the zoo's unseen seed 100 corner-00, 7.8 cm RMS)."""
    owned = ("curve", "point", "corner", "plane") if vertex.kind == "corner" else (
        "curve", "point", "corner")
    if (f.kind not in owned or vertex.kind not in ("corner", "point")
            or len(vertex.rows) <= len(f.rows)):
        return False
    apart = np.hypot(*(f.q - vertex.params[:2]).T)
    return bool(np.max(apart) > ELSEWHERE_M
                and np.all(near_vertex(f.window, vertex, f.rows, resolution)))


def near_vertex(w: Window, vertex: Family, rows: np.ndarray, resolution: float
                ) -> np.ndarray:
    """Which ``rows`` of ``w`` lie within ``resolution`` of the path the located
    ``vertex`` (a corner or point family) predicts for their pair, the vertex inside both
    beams, and are no stronger than its echoes (over their beams, within
    :data:`POINT_SPREAD` of its detections' median): a face's specular echo beside an
    edge is 20–40 dB stronger than the edge's diffraction, and the diffraction barely
    shifts it — that echo is the face's."""
    path, q = _predict(w, vertex.kind, vertex.params, rows)
    return (np.abs(path - w.paths[rows]) <= resolution) & _as_its_echoes(w, vertex, rows, q)


def _as_its_echoes(w: Window, vertex: Family, rows: np.ndarray, q: np.ndarray
                   ) -> np.ndarray:
    """Whether the located ``vertex`` (reflection points ``q`` for ``rows``) lies inside
    both beams of each of ``rows`` and their echoes are no stronger than its own over
    their beams (within :data:`POINT_SPREAD` of its detections' median)."""
    return _valid(w, vertex.kind, vertex.params, rows, q) & (
        _seen(w, vertex.kind, vertex.params, rows)
        <= POINT_SPREAD * float(median(_seen(vertex.window, vertex.kind, vertex.params,
                                                 vertex.rows))))


def _seen(w: Window, kind: str, params: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The detections ``rows``' amplitudes over their two-way beams towards the vertex of
    ``params`` (for a corner, along the double bounce's legs)."""
    T, axT, R, axR = w.T[rows], w.axT[rows], w.R[rows], w.axR[rows]
    gain = (_corner_gain(params, T, axT, R, axR, w.ka) if kind == "corner"
            else two_way(np.broadcast_to(params[:2], T.shape), T, axT, R, axR, w.ka))
    return w.amplitude[rows] / np.maximum(gain, 1e-3)


def vertices_own(families: list[Family], resolution: float) -> list[Family]:
    """``families`` less the curve, point and corner families whose every echo a located
    vertex of more rows predicts within the pulse's ``resolution``
    (:func:`a_vertexs_distorted_echoes`): its echoes, shifted
    by an overlapping one. Their detections are left out, not mapped again: their time of
    flight is neither echo's. The zoo's seed 6: corner-06, a corner at 5 m whose double
    bounce a face's echo 2–6 cm behind it shifted by 2–12 mm for six pairs of one array's
    end (a circle through the vertex, drawn 0.7 m into free space); corner-00, an 85°
    corner whose two double bounces part by 17 mm, which few pairs fitted as right-angled
    corners 47 cm from the vertex."""
    vertices = [f for f in families if f.kind in ("corner", "point")]
    return [f for f in families
            if not any(a_vertexs_distorted_echoes(f, v, resolution) for v in vertices)]


def planes_own(families: list[Family]) -> tuple[list[Family], np.ndarray]:
    """``(families, left)``: ``families`` with each corner whose echoes a plane family of
    more rows predicts (within their tolerance, in front of it, inside both beams, as
    strong as a mirror's echo: :func:`~.owners.widened`) taken into that plane,
    refitted to both, and the loci of such a corner's echoes it leaves out: the converse
    of :func:`corners_own`. A corner's double bounce and a plane's echo differ by about
    L²/(4r) of path (Kleeman & Kuc 1995), so a short array far away, with noise, fits
    its echoes of a wall's specular point as well by a right-angled corner there (its own
    plane left one echo outside its tolerance); the plane another array located through
    that point is the one reflector (the zoo's seed 3 wall-08: 6 elements at 6 m, σ 1.2).
    With noise the plane may leave some of the echoes out, as the naming lets the best
    fit (:func:`~.families.outside_allowed`)."""
    out, left = list(families), []
    corners = sorted((f for f in out if f.kind == "corner"), key=lambda f: len(f.rows))
    for corner in corners:
        w, rows = corner.window, corner.rows
        least = len(rows) - int(outside_allowed(w, rows))
        planes = sorted((k for k, f in enumerate(out)
                         if f.kind == "plane" and len(f.rows) > len(rows)),
                        key=lambda k: -len(out[k].rows))
        for k in planes:
            plane, taken = widened(out[k], w, rows)
            if len(taken) >= max(least, MIN_FAMILY):
                out[k] = plane
                out = [f for f in out if f is not corner]
                left.append(w.rows[setdiff1d(rows, taken)])
                break
    return out, np.concatenate(left) if left else np.zeros(0, np.int64)


def _widened(scene: Scene, sensors: SensorArray, loci: Loci, families: list[Family],
             rest: np.ndarray) -> tuple[list[Family], np.ndarray]:
    """``families`` with each plane widened by the detections of ``rest`` (those no family
    explained) that its plane predicts (:func:`~.owners.widened`: another element's
    echo of the same face, alone or too far from the others to be a family), largest
    family first; and the rows still left."""
    if len(rest) == 0 or not families:
        return families, rest
    x0 = sensors.positions[loci.tx[rest]].mean(axis=0)
    w = _window(scene, sensors, loci, rest, x0, math.inf)
    free = np.ones(len(rest), dtype=bool)
    out = list(families)
    for k in sorted(range(len(out)), key=lambda k: -len(out[k].rows)):
        out[k], taken = widened(out[k], w, np.flatnonzero(free))
        free[taken] = False
    return out, rest[free]


#: Fewest echoes of a located corner whose leftover neighbours :func:`_unshadowed` leaves
#: out (a corner of fewer, a sinusoid's trough as often as a corner, locates too little),
#: unless its fit to :data:`EXACT_CORNER_ROWS` or more is exact: within the path residual
#: every noise-free detection may have (:data:`~.window.BASE_TOLERANCE_M`; the zoo's
#: unseen seed 158 corner-03, an 87° corner's 4 echoes fitted to 29 µm and 14 others
#: drawn across its mouth: 3.20 → 0.01 cm RMS; a noisy sinusoid's trough, 5 echoes to
#: 1.7 mm, stays no corner's).
SHADOWING_ROWS = 2 * MIN_CURVE
EXACT_CORNER_ROWS = 4


def _unshadowed(scene: Scene, sensors: SensorArray, loci: Loci, families: list[Family],
                rest: np.ndarray, resolution: float) -> np.ndarray:
    """The rows of ``rest`` (detections no family explains) that no located corner predicts within
    the pulse's ``resolution`` (:func:`near_vertex`): a double bounce that an overlapping echo
    shifted, or its other order, is left out as the window search shadows one (the zoo's seed 6
    corner-00: five echoes of an 85° corner, within 2 mm of its located vertex's paths, drawn as a
    30 cm stroke across its mouth by tangent points). Only about a corner that
    :data:`SHADOWING_ROWS` echoes or more located (or :data:`EXACT_CORNER_ROWS`, fitted exactly),
    not about a located point: beside a sinusoid's crest, or a trough that three echoes named a
    corner, a leftover echo's tangent point is its flank's."""
    vertices = [f for f in families if f.kind == "corner" and (
        len(f.rows) >= SHADOWING_ROWS
        or (len(f.rows) >= EXACT_CORNER_ROWS and f.rms <= BASE_TOLERANCE_M))]
    if len(rest) == 0 or not vertices:
        return rest
    w = _window(scene, sensors, loci, rest, sensors.positions[loci.tx[rest]].mean(axis=0),
                math.inf)
    every = np.arange(len(rest))
    near = np.zeros(len(rest), dtype=bool)
    for vertex in vertices:
        near |= turned_about(w, vertex, every, resolution)
        if vertex.kind != "corner":  # a corner's: turned_about's rows with no turn, a subset
            near |= near_vertex(w, vertex, every, resolution)
    return rest[~near]


#: The most a located corner's walls may turn from square for :func:`turned_about`
#: (radians of β: walls within 7.5° of a right angle).
MAX_TURN = math.radians(15.0)


def turned_about(w: Window, vertex: Family, rows: np.ndarray, resolution: float
                 ) -> np.ndarray:
    """Which ``rows`` of ``w`` may be double bounces of the located corner ``vertex`` with
    its walls off square: within the pulse's ``resolution`` of the right angle's path
    plus what a turn by β up to :data:`MAX_TURN` moves it, β·|a × b|/|a + b| to first
    order (a = T − V, b = R − V: nothing for T = R, about β·L/2 for elements L apart), and
    as :func:`near_vertex` asks, inside both beams and as strong as the vertex's echoes
    over their beams (:func:`_as_its_echoes`). A right angle explains the double bounces
    of an 88° corner's close pairs to a few µm, not its far pairs' (the zoo's unseen seed
    20 corner-06: 2 cm off, their tangent points drawn across the corner's mouth, 21 cm
    RMS)."""
    v = np.asarray(vertex.params[:2], dtype=np.float64)
    a, b = w.T[rows] - v, w.R[rows] - v
    first = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) / np.maximum(
        np.hypot(*(a + b).T), 1e-12)
    path, q = _predict(w, "corner", vertex.params, rows)
    return ((np.abs(path - w.paths[rows]) <= resolution + MAX_TURN * first)
            & _as_its_echoes(w, vertex, rows, q))


def reflector_points(scene: Scene, sensors: SensorArray, loci: Loci) -> Patches:
    """The points, their loci and the located vertices (:class:`~.patches.Patches`) of
    every linear array's families (their faces reaching the edges that one diffraction no
    family explains locates: :func:`~.joins.reach_heard_ends`), and the tangent points of
    the other groups' detections and of those no family explains, where they are as
    strong as a room scan's floor
    (:data:`~clsonar.survey.DEFAULT_MIN_ENVELOPE`): a tangent point is a specular echo's,
    and a weak echo no reflector explains is a diffraction's or a multipath's."""
    arrays = {} if in_a_room(scene, sensors.positions) else linear_groups(sensors)
    families, left = _families(scene, sensors, loci, arrays)
    explained = np.zeros(len(loci), dtype=bool)
    for f in families:
        explained[f.loci] = True
    drawn = draw_families(scene, sensors, loci, families, np.flatnonzero(~explained))
    others = np.flatnonzero(~np.isin(sensors.groups[loci.tx], list(arrays)))
    loud = loci.amplitude >= DEFAULT_MIN_ENVELOPE
    left = left[loud[left]]
    left = left[~_drawn_faces_echoes(scene, sensors, loci, left, drawn)]
    rest = np.sort(np.concatenate([others[loud[others]], left]))
    if len(rest):
        points, source, vertices = tangent_map(
            scene, sensors, _subset(loci, rest),
            isolated_bias_m=chosen(scene.mapping.isolated_bias_m, "mapping.isolated_bias_m"))
        keep = ~past_located_ends(points, drawn)
        drawn = drawn.plus(points[keep], rest[source[keep]], vertices)
    return drawn


def _drawn_faces_echoes(scene: Scene, sensors: SensorArray, loci: Loci, rows: np.ndarray,
                        drawn: Patches) -> np.ndarray:
    """Which of the detections ``rows`` a drawn face reflects
    (:func:`~.owners.drawn_faces_echoes`), within their tolerance or the pulse's
    resolution (c·σ: echoes nearer in path merge), whichever is wider."""
    c = scene.medium.c
    P, A = sensors.positions, sensors.axes
    tx, rx = loci.tx[rows], loci.rx[rows]
    tolerance = np.maximum(c * scene.transducer.pulse_sigma_s, window_tolerance(
        loci.amplitude[rows], scene.signal.noise_std, c, scene.transducer.pulse_sigma_s))
    return drawn_faces_echoes(P[tx], P[rx], A[tx], A[rx], loci.tof_s[rows] * c, tolerance,
                              drawn.points, drawn.ends, scene.transducer.beam(c)[0])


#: A face that ends at a located vertex (within :data:`~.joins.END_AT_VERTEX_M`) does not
#: go on past it: no tangent point is drawn within :data:`PAST_END_M` beyond that end,
#: within :data:`PAST_END_WIDTH_M` plus :data:`PAST_END_SLOPE` of the distance from its line.
PAST_END_M = 0.5
PAST_END_WIDTH_M = 0.01
PAST_END_SLOPE = 0.1


def past_located_ends(points: np.ndarray, drawn: Patches) -> np.ndarray:
    """[n] bool: which ``points`` (tangent points of echoes no family explains) continue a
    drawn patch past an end of it that a located vertex (an edge, a corner) marks: the
    face ends there, and such a point is another array's echo of the face's last stretch,
    moved by the edge's diffraction arriving with it, drawn at the middle of its in-beam
    arc (a stub past the edge)."""
    out = np.zeros(len(points), dtype=bool)
    if len(points) == 0 or len(drawn.vertices) == 0 or len(drawn.ends) == 0:
        return out
    starts = np.r_[0, drawn.ends[:-1]]
    for a, b in zip(starts, drawn.ends, strict=True):
        if b - a < 2:
            continue
        for end, before in ((drawn.points[b - 1], drawn.points[b - 2]),
                            (drawn.points[a], drawn.points[a + 1])):
            if np.hypot(*(drawn.vertices - end).T).min() > END_AT_VERTEX_M:
                continue
            u = (end - before) / max(float(np.hypot(*(end - before))), 1e-12)
            rel = points - end
            along = dot2(rel, u)
            across = np.abs(rel[:, 0] * u[1] - rel[:, 1] * u[0])
            out |= (along > 0) & (along <= PAST_END_M) & (
                across <= PAST_END_WIDTH_M + PAST_END_SLOPE * along)
    return out


__all__ = ["LINEAR_TOL_M", "WINDOW_M", "corners_own", "in_a_room", "linear_groups",
           "reflector_points", "strongest_echo"]
