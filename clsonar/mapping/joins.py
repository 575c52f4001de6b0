"""Patches put together (``mapping.mode = "reflectors"``): plane patches of one line
joined (:func:`join_collinear`), walls met at their corners and edges and patches reaching
located vertices (:func:`meet`), and the located vertices of one reflector merged
(:func:`merge_vertices`); then everything drawn (:func:`draw_families`).

After the walls fit of rooms (thesis §3.6, :mod:`clsonar.post.walls`), but on the models'
lines rather than on the map: two plane patches whose lines agree to within
:data:`SAME_LINE_RAD` and :data:`SAME_LINE_M` and whose spans overlap or leave a gap of at
most :data:`JOIN_GAP_M` are one wall, fitted again to all of their detections. Two walls
whose lines cross within :data:`MEET_M` of an end of each meet there: both are extended or
cut to the crossing, which is a located corner or edge.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .. import steps
from ..numerics import unique
from ..scene import Scene
from ..sensors import SensorArray
from .ends import heard_ends
from .families import Family
from .heard import Heard, heard_index
from .loci import Loci
from .models import curve_geometry, curve_paths, dot2, fit_curve
from .patches import (
    STEP_CELLS,
    Patch,
    Patches,
    carrier_points,
    clamp_to_silence,
    coordinates,
    draw_patch,
    flat,
    patch_of,
    spread_patch,
    trusted_reach,
)

#: Plane patches whose normals differ by at most this are candidates for one line.
SAME_LINE_RAD = math.radians(1.0)

#: ... and whose spans' ends lie within this of the other's line, metres.
SAME_LINE_M = 0.005

#: Gap between the spans of one line's patches that is bridged, metres.
JOIN_GAP_M = 0.3

#: Two walls meet where their lines cross within this of an end of each, metres (and at
#: an angle of at least :data:`MEET_MIN_ANGLE_RAD`).
MEET_M = 0.5
MEET_MIN_ANGLE_RAD = math.radians(20.0)

#: A wall's extension is cut where it runs through the line of another wall whose span
#: comes within this of the crossing, metres.
CUT_M = 1.0

#: A patch reaches a located vertex within this of its line and :data:`MEET_M` of its drawn
#: end.
VERTEX_ON_LINE_M = 0.015

#: Located vertices closer than this are one reflector, metres.
SAME_VERTEX_M = 0.2

#: Two straight patches whose reflection points lie at least this far on both sides of
#: their lines' crossing (metres), crossing at :data:`CROSSED_MIN_ANGLE_RAD` or more, are
#: a point reflector's (:func:`crossed_faces`).
CROSSED_INSIDE_M = 0.01
CROSSED_MIN_ANGLE_RAD = math.radians(3.0)


def _straddles(p: Patch, x: np.ndarray) -> bool:
    """Whether ``p``'s reflection points lie on both sides of ``x`` (a point of its line),
    :data:`CROSSED_INSIDE_M` or more."""
    at = float(coordinates(p.params, p.x0, x[None])[0])
    return bool(p.u.min() <= at - CROSSED_INSIDE_M and p.u.max() >= at + CROSSED_INSIDE_M)


def crossed_faces(patches: list[Patch]) -> tuple[list[Patch], np.ndarray, np.ndarray]:
    """``(patches left, vertices [k, 2], their weights [k])``: two straight patches whose
    reflection points lie on both sides of where their lines cross are no faces — a face
    seen from its front ends where another face meets it, and cannot go on behind it —
    but a point reflector's echoes (a corner's double bounce, an edge's diffraction),
    each array's fitted as the plane facing it: an array too short, or its echoes too
    noisy, to tell a point's paths from a plane's (Kleeman & Kuc's difference, L²/(4r), is
    0.6 mm for 13 cm at 6.7 m). Their crossing is the vertex (weighed by their loci), and
    the two patches go."""
    straight = [k for k, p in enumerate(patches) if p.straight]
    gone: set[int] = set()
    found, weights = [], []
    for n, i in enumerate(straight):
        for j in straight[n + 1:]:
            if i in gone or j in gone:
                continue
            x = _crossing(patches[i], patches[j], CROSSED_MIN_ANGLE_RAD)
            if x is not None and _straddles(patches[i], x) and _straddles(patches[j], x):
                gone |= {i, j}
                found.append(x)
                weights.append(len(patches[i].loci) + len(patches[j].loci))
    return ([p for k, p in enumerate(patches) if k not in gone],
            np.asarray(found, dtype=np.float64).reshape(-1, 2),
            np.asarray(weights, dtype=np.float64))


def _line(p: Patch) -> tuple[np.ndarray, np.ndarray]:
    """A straight patch's (normal, tangent)."""
    phi = float(p.params[0])
    n = np.array([math.cos(phi), math.sin(phi)])
    return n, np.array([-n[1], n[0]])


def _ends(p: Patch) -> np.ndarray:
    return carrier_points(p.params, p.x0, np.array([p.lo, p.hi]))


def _same_line(a: Patch, b: Patch) -> bool:
    na, ta = _line(a)
    nb, _ = _line(b)
    if float(dot2(na, nb)) < math.cos(SAME_LINE_RAD):
        return False
    off_b = np.abs(dot2(_ends(b), na) - float(a.params[1]))
    off_a = np.abs(dot2(_ends(a), nb) - float(b.params[1]))
    if max(off_a.max(), off_b.max()) > SAME_LINE_M:
        return False
    ua, ub = dot2(_ends(a), ta), dot2(_ends(b), ta)
    gap = max(ub.min() - ua.max(), ua.min() - ub.max())
    return gap <= JOIN_GAP_M


def _joined(parts: list[Patch]) -> Patch:
    """One straight patch over all the spans of ``parts``, on the line fitted to all of
    their detections (the largest part's line if that fits them worse than twice their
    own lines do)."""
    T = np.concatenate([p.T for p in parts])
    R = np.concatenate([p.R for p in parts])
    paths = np.concatenate([p.paths for p in parts])
    x0 = 0.5 * (T + R).mean(axis=0)
    big = max(parts, key=lambda p: len(p.u))
    start = np.array([big.params[0], float(big.params[1]), 0.0])
    fit = fit_curve(x0, T, R, paths, start, fix_psi=True)
    own = np.concatenate([curve_paths(p.params, p.x0, p.T, p.R)[0] - p.paths for p in parts])
    params = fit.params if fit.rms <= 2 * float(np.sqrt(np.mean(own**2))) + 1e-4 else start
    ends = np.concatenate([_ends(p) for p in parts])
    q_all = np.concatenate([carrier_points(p.params, p.x0, p.u) for p in parts])
    span = coordinates(params, x0, ends)
    return Patch(params, x0, coordinates(params, x0, q_all), float(span.min()),
                 float(span.max()), np.concatenate([p.loci for p in parts]),
                 min(p.bend for p in parts), np.concatenate([p.tx for p in parts]),
                 np.concatenate([p.rx for p in parts]), T, R, paths)


def join_collinear(patches: list[Patch], clamp: Callable[[Patch], Patch]) -> list[Patch]:
    """Straight patches of one line joined (module docstring), each join's span cut again
    by ``clamp`` (:func:`silence_clamp`: the silence of the pairs that would hear any of
    its detections' surface, not only each part's); circles as they are."""
    straight = [p for p in patches if p.straight]
    root = list(range(len(straight)))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    for i in range(len(straight)):
        for j in range(i + 1, len(straight)):
            if find(i) != find(j) and _same_line(straight[i], straight[j]):
                root[find(i)] = find(j)
    groups: dict[int, list[Patch]] = {}
    for i, p in enumerate(straight):
        groups.setdefault(find(i), []).append(p)
    joined = [g[0] if len(g) == 1 else clamp(_joined(g)) for g in groups.values()]
    return joined + [p for p in patches if not p.straight]


def silence_clamp(scene: Scene, sensors: SensorArray, heard: Heard
                  ) -> Callable[[Patch], Patch]:
    """A patch's span cut where the arrays heard nothing
    (:func:`~.patches.clamp_to_silence`). For a join of one line's patches: each part was
    cut by the pairs that would hear it as well as its own weakest echo, and the union of
    their spans kept a part's region of constant depth that no pair of its own could
    test, past an end that another part's silent pairs had placed (the zoo's unseen seed
    61 edge-02, σ 0.3: a face seen by three arrays, 20 echoes of one drawn 21 cm past the
    edge where the others' pairs heard nothing, 4.8 cm RMS). A join of one group's parts
    is left as it is: each part was cut by every pair of its group already, and cut again
    as one patch, by the weakest of all its parts' echoes, it lost the end that the part
    nearest the edge had found (unseen seed 60 edge-02, σ 0.3: two families of one array
    on one face, the joined face cut 2.4 cm short of the edge its second part reached)."""
    def clamp(p: Patch) -> Patch:
        if len(unique(sensors.groups[np.concatenate([p.tx, p.rx])])) == 1:
            return p
        lo, hi = clamp_to_silence(p, scene, sensors, heard, p.lo, p.hi)
        return replace(p, lo=lo, hi=hi)

    return clamp


def _crossing(a: Patch, b: Patch, least: float = MEET_MIN_ANGLE_RAD) -> np.ndarray | None:
    """Where the lines of ``a`` and ``b`` cross (None where they cross at under ``least``
    radians)."""
    na, _ = _line(a)
    nb, _ = _line(b)
    det = na[0] * nb[1] - na[1] * nb[0]
    if abs(det) < math.sin(least):
        return None
    da, db = float(a.params[1]), float(b.params[1])
    return np.array([(da * nb[1] - db * na[1]) / det, (na[0] * db - nb[0] * da) / det])


def _reach(p: Patch, x: np.ndarray, drawn: bool = False) -> Patch | None:
    """``p`` extended or cut so that its end nearest ``x`` is at ``x`` (None when ``x``
    lies farther than :data:`MEET_M` from both of its ends, or inside its reflection
    points). The ends are its reflection points' and its drawn span's, or with ``drawn``
    its drawn span's alone (a located vertex, :func:`meet`)."""
    ux = float(coordinates(p.params, p.x0, x[None])[0])
    first, last = float(p.u.min()), float(p.u.max())
    lo, hi = p.lo - MEET_M, p.hi + MEET_M
    if not drawn:
        lo, hi = max(lo, first - MEET_M), min(hi, last + MEET_M)
    if lo <= ux <= first + 1e-9:
        return replace(p, lo=ux)
    if last - 1e-9 <= ux <= hi:
        return replace(p, hi=ux)
    return None


def _cut(p: Patch, x: np.ndarray, inside: float = 0.0) -> Patch:
    """``p`` cut at ``x`` where its extension beyond its reflection points runs past it
    (``x`` beyond them, or within ``inside``, in ``p``'s coordinate, of the last)."""
    ux = float(coordinates(p.params, p.x0, x[None])[0])
    first, last = float(p.u.min()), float(p.u.max())
    if p.lo < ux < min(first + inside, 0.5 * (first + last)):
        return replace(p, lo=ux)
    if max(last - inside, 0.5 * (first + last)) < ux < p.hi:
        return replace(p, hi=ux)
    return p


def _near_span(p: Patch, x: np.ndarray, reach: float) -> bool:
    ux = float(coordinates(p.params, p.x0, x[None])[0])
    return p.lo - reach <= ux <= p.hi + reach


def meet(patches: list[Patch], vertices: np.ndarray) -> tuple[list[Patch], np.ndarray]:
    """Walls met at the crossings of their lines, walls cut where their extension runs
    through another wall's line near that wall, and walls reaching the located
    ``vertices`` that lie on their lines (module docstring; within :data:`MEET_M` of the
    end drawn, whose regions of constant depth may already run past its reflection
    points: a face seen from 0.65 m of its located edge, drawn from 0.47 m); the crossings
    where two walls meet are vertices."""
    found = [vertices]
    patches = list(patches)
    for i in range(len(patches)):
        for j in range(i + 1, len(patches)):
            a, b = patches[i], patches[j]
            x = _crossing(a, b) if a.straight and b.straight else None
            if x is None:
                continue
            a2, b2 = _reach(a, x), _reach(b, x)
            if a2 is not None and b2 is not None:
                patches[i], patches[j] = a2, b2
                found.append(x[None])
                continue
            if _near_span(b, x, CUT_M):
                patches[i] = _cut(a, x)
            if _near_span(a, x, CUT_M):
                patches[j] = _cut(b, x)
    for k, p in enumerate(patches):
        for v in vertices:
            foot, off = _foot(p, v)
            if abs(off) > VERTEX_ON_LINE_M or not flat(p):
                continue
            if not p.straight:  # a circle is a curved wall's local one: cut, not extended
                patches[k] = p = _cut(p, foot)
                continue
            reached = _reach(p, foot, drawn=True)
            if reached is not None:
                patches[k] = p = reached
    return patches, np.concatenate(found)


def _foot(p: Patch, v: np.ndarray) -> tuple[np.ndarray, float]:
    """The point of ``p``'s line or circle nearest ``v``, and ``v``'s signed distance from
    it: a located edge on a nearly flat circle (:func:`~.patches.flat`), beyond its
    reflection points, ends it as one on a plane's line does (the echoes of a face's last
    stretch, their times shifted by up to a millimetre by its edge's diffraction arriving
    with them, may be fitted best by a slightly bent circle)."""
    if p.straight:
        n, _ = _line(p)
        off = float(dot2(v, n)) - float(p.params[1])
        return v - off * n, off
    centre, rho, _ = curve_geometry(p.params, p.x0)
    out = v - centre
    dist = max(float(np.hypot(*out)), 1e-12)
    return centre + abs(rho) * out / dist, dist - abs(rho)


def clip_to_extent(p: Patch, extent: tuple[float, ...]) -> Patch:
    """``p`` without the parts of its span outside the map's ``extent`` (what lies beyond
    the extent is not the map's; a wall past it would end there anyway)."""
    xmin, ymin, xmax, ymax = extent
    u = np.linspace(p.lo, p.hi, 2001)
    q = carrier_points(p.params, p.x0, u)
    inside = (q[:, 0] >= xmin) & (q[:, 0] <= xmax) & (q[:, 1] >= ymin) & (q[:, 1] <= ymax)
    if inside.all() or not inside.any():
        return p
    mid = int(np.argmin(np.abs(u - 0.5 * (float(p.u.min()) + float(p.u.max())))))
    lo_k, hi_k = mid, mid
    while lo_k > 0 and inside[lo_k - 1]:
        lo_k -= 1
    while hi_k < len(u) - 1 and inside[hi_k + 1]:
        hi_k += 1
    return replace(p, lo=float(u[lo_k]), hi=float(u[hi_k]))


def merge_vertices(vertices: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Located vertices within :data:`SAME_VERTEX_M` of a heavier one dropped (one
    reflector located twice, by two stretches of an array or two arrays, or a weak family
    of echoes distorted by an overlapping one); the heaviest first."""
    order = np.argsort(-weights, kind="stable")
    kept: list[np.ndarray] = []
    for k in order:
        v = vertices[k]
        if all(np.hypot(*(v - w)) > SAME_VERTEX_M for w in kept):
            kept.append(v)
    return np.asarray(kept).reshape(-1, 2)


def drawn_spans(p: Patch) -> list[tuple[float, float]]:
    """The stretches of ``p``'s span ``[lo, hi]`` that are drawn: all of it but the gaps
    between consecutive reflection points that are wider than :data:`JOIN_GAP_M` beyond
    the trusted reach of both (:func:`~.patches.trusted_reach`). No echo came from such a
    gap, and the detections leave the surface there bent enough to leave the fitted line
    or circle by more than :data:`~.patches.PATCH_BIAS_M` (a plane fitted to two
    elements' echoes of a curved wall is a chord of it): the rule that joins separate
    patches of one line only across :data:`JOIN_GAP_M`. A plane the detections show
    straight (its bend small) is drawn whole."""
    scale = 1.0 if p.straight else abs(float(curve_geometry(p.params, p.x0)[1]))
    reach = trusted_reach(p)
    u = np.sort(p.u)
    wide = np.flatnonzero(np.diff(u) > JOIN_GAP_M / max(scale, 1e-12) + 2.0 * reach)
    starts = np.r_[p.lo, u[wide + 1] - reach]
    stops = np.r_[u[wide] + reach, p.hi]
    return [(float(a), float(b)) for a, b in zip(starts, stops, strict=True)]


#: A patch's end within this of a located vertex (metres) ends there.
END_AT_VERTEX_M = 0.02


def reach_heard_ends(patches: list[Patch], vertices: np.ndarray, scene: Scene,
                     sensors: SensorArray, loci: Loci, heard: Heard, rows: np.ndarray
                     ) -> tuple[list[Patch], np.ndarray]:
    """Faces (planes, circles as flat as their range: :func:`~.patches.flat`) whose ends no
    located vertex ends, each extended to the edge that one diffraction of ``rows`` puts
    nearest it beyond its drawn end (:func:`~.ends.heard_ends`), farther than the
    detection's tolerance moves it (nearer, the face is drawn to its edge already) and
    within :data:`MEET_M`, where the arrays' silence lets it go on that far, to within
    the pulse's resolution c·σ (:func:`~.patches.clamp_to_silence`, whose end is a
    region of constant depth's); those edges are located vertices."""
    found = [vertices]
    if len(rows) == 0:
        return patches, vertices
    resolution = scene.medium.c * scene.transducer.pulse_sigma_s
    for k, p in enumerate(patches):
        if not flat(p):
            continue
        scale = 1.0 if p.straight else abs(float(curve_geometry(p.params, p.x0)[1]))
        for end in (p.lo, p.hi):
            at = carrier_points(p.params, p.x0, np.array([end]))
            done = np.concatenate(found)
            if len(done) and np.hypot(*(done - at).T).min() <= END_AT_VERTEX_M:
                continue
            s, X, spread = heard_ends(p, end, scene, sensors, loci, rows, MEET_M)
            side = np.flatnonzero((s > spread) & (s <= MEET_M))
            if len(side) == 0:
                continue
            x = X[side[np.argmin(s[side])]]
            ux = float(coordinates(p.params, p.x0, x[None])[0])
            lo, hi = clamp_to_silence(p, scene, sensors, heard, min(ux, p.lo), max(ux, p.hi))
            if not lo - resolution / scale <= ux <= hi + resolution / scale:
                continue  # pairs that would have heard the face on the way heard nothing
            reached = _reach(p, x, drawn=True)
            if reached is not None:
                patches[k] = p = reached
                found.append(x[None])
    return patches, np.concatenate(found)


#: A face's reflection points within this of a located vertex on its line, past it, may be
#: the vertex's own echoes (metres): a face drawn on past it is cut there
#: (:func:`cut_at_vertices`). Noisy edges located 1.6–1.9 cm inside their faces' last
#: reflection points (the zoo's unseen seeds 148 and 150 edge-05, σ 0.6) are not their ends.
OWN_ECHOES_M = 0.01


def cut_at_vertices(patches: list[Patch], vertices: np.ndarray, inside: float
                    ) -> list[Patch]:
    """``patches`` cut where the stretch drawn beyond their reflection points runs past a
    located vertex on their line or (flat) circle, within :data:`VERTEX_ON_LINE_M`, that
    lies beyond them or within ``inside`` (metres, along the carrier) of the last of them
    (:func:`_cut`): a face ends at its edge, whose own echoes' reflection points may lie
    on it. For the edges :func:`reach_heard_ends` locates after :func:`meet`, and those a
    face's echoes reach (the zoo's unseen seed 127 edge-04: a circle fitted to a face's
    last echoes ran 17 cm past the edge one diffraction located afterwards; seed 136
    edge-01: a circle fitted to a face and its edge's echoes, 12 cm past the edge)."""
    cut = []
    for p in patches:
        if flat(p):
            scale = 1.0 if p.straight else abs(float(curve_geometry(p.params, p.x0)[1]))
            for v in vertices:
                foot, off = _foot(p, v)
                if abs(off) <= VERTEX_ON_LINE_M:
                    p = _cut(p, foot, inside / max(scale, 1e-12))
        cut.append(p)
    return cut


def draw_families(scene: Scene, sensors: SensorArray, loci: Loci,
                  families: list[Family], alone: np.ndarray | None = None) -> Patches:
    """The points and vertices of ``families``: patches spread over their regions of
    constant depth, joined, met at corners and edges, reaching the edges that one
    diffraction of the detections ``alone`` (no family's) puts at their ends
    (:func:`reach_heard_ends`), drawn every :data:`STEP_CELLS` cells."""
    spread = [f for f in families if f.kind in ("plane", "curve")]
    heard = heard_index(loci, sensors, scene.medium.c)
    patches = [spread_patch(patch_of(f, loci), scene, sensors, heard,
                            loci.amplitude[f.loci])
               for f in steps.each("patches", spread)]
    patches, crossed, weights = crossed_faces(patches)
    points = [f for f in families if f.kind in ("point", "corner")]
    vertices = merge_vertices(
        np.concatenate([np.asarray([f.params[:2] for f in points],
                                   dtype=np.float64).reshape(-1, 2), crossed]),
        np.r_[np.asarray([len(f.rows) for f in points], dtype=np.float64), weights])
    patches, vertices = meet(join_collinear(patches, silence_clamp(scene, sensors, heard)),
                             vertices)
    if alone is not None:
        patches, vertices = reach_heard_ends(patches, vertices, scene, sensors, loci, heard,
                                             alone)
    patches = cut_at_vertices(patches, vertices, OWN_ECHOES_M)
    return draw_patches(scene, patches, merge_vertices(vertices, np.zeros(len(vertices))))


def draw_patches(scene: Scene, patches: list[Patch], vertices: np.ndarray) -> Patches:
    """``patches`` inside the map's extent drawn every :data:`STEP_CELLS` cells over their
    drawn spans (:func:`drawn_spans`), with the located ``vertices``."""
    patches = [clip_to_extent(p, scene.extent) for p in patches]
    step = STEP_CELLS * scene.cell
    drawn = [draw_patch(replace(p, lo=a, hi=b), step) for p in patches
             for a, b in drawn_spans(p)]
    pts = np.concatenate([d[0] for d in drawn]) if drawn else np.zeros((0, 2))
    src = np.concatenate([d[1] for d in drawn]) if drawn else np.zeros(0, np.int64)
    ends = np.cumsum([len(d[0]) for d in drawn]).astype(np.int64)
    return Patches(pts, src.astype(np.int64), vertices, ends)


__all__ = ["CROSSED_INSIDE_M", "CROSSED_MIN_ANGLE_RAD", "END_AT_VERTEX_M", "JOIN_GAP_M",
           "MEET_M", "OWN_ECHOES_M", "SAME_LINE_M", "SAME_LINE_RAD", "SAME_VERTEX_M",
           "crossed_faces", "cut_at_vertices", "draw_families", "draw_patches", "drawn_spans",
           "join_collinear", "meet", "merge_vertices", "reach_heard_ends"]
