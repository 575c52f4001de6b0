"""Analytic echo returns of every transmitter→receiver pair (thesis §2.1.1, figs. 2.2, 2.5).

Two implementations of one model: :func:`compute_echoes` runs the OpenCL kernels of
``kernels/echoes.cl`` (float32 by default, float64 where the device has ``cl_khr_fp64``) and
:func:`reference_echoes` evaluates the same formulas in NumPy float64. Both start from the
same :class:`EchoProblem` (:func:`_prepare_problem`) and end in the same :class:`EchoTable`.

The model, for every fired pair (T, R) of :func:`clsonar.sensors.pairs`:

- **specular / corner** (image method, thesis fig. 2.2): every sequence of 1..``max_order``
  flat walls with consecutive walls distinct. Images I0 = T, Ij = Ij−1 mirrored across wall
  sj; back-tracing from R gives the reflection points. Valid iff every crossing lies strictly
  between its two points and on its wall, and every bounce has its incoming and outgoing
  points strictly on the wall's front (two-sided walls: strictly on one side). Path length
  ``|R − Ik|``; ``corner`` if k ≥ 2 and each consecutive pair of walls meets at a concave
  corner, else ``specular``; amplitude factor ρ^k. Legs shorter than
  :data:`OCCLUSION_EPS_M` are rejected, so a path through a corner's vertex is left to:
- **corner vertex**: the double bounce T→V→R through the vertex V of a concave corner, the
  retro-reflection of a right-angled corner (for T = R the image method's middle leg has
  zero length). Valid iff T and R are strictly inside the corner and R lies within
  :data:`OCCLUSION_EPS_M` of the ray from V away from T's second-order image; ``corner``,
  order 2, factor ρ².
- **edge**: diffraction at each convex vertex V, path T→V→R, valid iff neither T nor R is
  strictly inside the solid cone; factor :func:`~clsonar.physics.edge_gain`.
- **curved**: the specular point on a cylinder (bisection on the shorter arc between the
  directions to T and R) or on a sinusoid (bisection of the path length's derivative in each
  sampling interval); factor ρ·:func:`~clsonar.physics.curved_gain`.
- **occlusion**: each leg is blocked by an occluder (wall or curve chord) it crosses more than
  :data:`OCCLUSION_EPS_M` from both ends, or a circle it passes through.
- **amplitude** ``A0·b(θ_T)·b(θ_R)·factor·absorption``, θ the angles between each
  transducer's axis and its leg (physics.py); an echo is kept only when A > 0, i.e. strictly
  inside both beams. Time of flight = path length / c (eq. 2.1).

All coordinates are made relative to the scene extent's centre before the kernels see them, so
float32 keeps micrometre resolution anywhere in the scene.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from . import physics
from .geometry import Geometry, build_geometry, curve_derivatives, curve_point
from .scene import Scene
from .sensors import SensorArray, pairs, place_sensors

KINDS = ("specular", "corner", "edge", "curved")
SPECULAR, CORNER, EDGE, CURVED = range(4)

#: A leg crossing an occluder (or entering a circle) within this many metres of either end is
#: not blocked: paths end on surfaces, and a reflection point may sit next to a vertex.
OCCLUSION_EPS_M = 1e-4

#: Bisection steps of the curved-surface searches: 40 halve a bracket of ≤ π rad (or ≤ 1 cm)
#: below float64 resolution, 32 below float32's.
BISECT_ITERATIONS = {"float64": 40, "float32": 32}

#: |â + b̂| below this: T and R are on opposite sides of a cylinder, no shorter arc.
MIN_BISECTOR = 1e-6

#: Work-group size of the kernels along the surface elements (:func:`clsonar.opencl.work_group`).
WORK_GROUP = 32

#: Work items per kernel launch (pairs are split into chunks of at most this many slots).
SLOTS_PER_LAUNCH = 1 << 21


# --------------------------------------------------------------------------- the table


@dataclass(frozen=True, eq=False)
class EchoTable:
    """One row per echo return, sorted by (tx, rx, tof_s, kind, element).

    ``element`` identifies the surface element so echoes can be matched one to one: for
    ``specular``/``corner`` the row of :func:`wall_sequences` (geometry walls, max_order),
    for a path through a corner's vertex ``len(wall_sequences)`` + the row of
    ``geometry.corners``, for ``edge`` the row of ``geometry.diffractors``, for ``curved``
    the circle index, or ``len(circles)`` + the index of the sinusoid's sampling interval.
    ``point`` is the last reflection point before the receiver (the vertex for corner-vertex
    and edge paths), in scene coordinates.
    """

    tx: np.ndarray  # int64 index into SensorArray
    rx: np.ndarray  # int64
    tof_s: np.ndarray  # float64
    amplitude: np.ndarray  # float64
    kind: np.ndarray  # int8 code into KINDS
    order: np.ndarray  # int8 number of reflections
    point: np.ndarray  # [n, 2] float64
    element: np.ndarray  # int64

    def __len__(self) -> int:
        return len(self.tof_s)

    def kind_names(self) -> np.ndarray:
        """The ``kind`` column as strings (``KINDS``)."""
        return np.asarray(KINDS)[self.kind]

    def write_csv(self, file: TextIO) -> None:
        """Write ``tx,rx,tof_s,amplitude,kind,order`` rows (DESIGN.md, ``echoes.csv``)."""
        file.write("tx,rx,tof_s,amplitude,kind,order\n")
        names = self.kind_names()
        for i in range(len(self)):
            file.write(f"{self.tx[i]},{self.rx[i]},{self.tof_s[i]:.12g},"
                       f"{self.amplitude[i]:.9g},{names[i]},{self.order[i]}\n")


# --------------------------------------------------------------------------- the problem


@dataclass(frozen=True, eq=False)
class EchoProblem:
    """Inputs of both implementations as float64 arrays, relative to the local ``origin``."""

    origin: np.ndarray  # [2] extent centre, subtracted from every coordinate below
    pairs: np.ndarray  # [P, 2] int64 (tx, rx)
    positions: np.ndarray  # [N, 2]
    axes: np.ndarray  # [N, 2] unit
    walls: np.ndarray  # [S, 4]
    normals: np.ndarray  # [S, 2] unit, towards the front
    two_sided: np.ndarray  # [S] bool
    sequences: np.ndarray  # [M, max_order] int64 wall indices, -1 padded; orders ascending
    sequence_order: np.ndarray  # [M] int64
    sequence_corner: np.ndarray  # [M] bool: order ≥ 2 and all consecutive walls corner pairs
    corners: np.ndarray  # [Q, 6] concave vertex, unit normals of its walls to the concave side
    diffractors: np.ndarray  # [D, 6] V, unit to previous point, unit to next point
    circles: np.ndarray  # [C, 3] cx, cy, r
    curves: np.ndarray  # [K, 7] Fx, Fy, tx, ty, amplitude, ω, length
    interval_curve: np.ndarray  # [I] int64
    interval_s: np.ndarray  # [I, 2]
    interval_skip: np.ndarray  # [I, 2] occluder indices (inclusive) a leg to this interval skips
    interval_last: np.ndarray  # [I] bool: last interval of its curve (closed at its end)
    occluders: np.ndarray  # [O, 4] walls then curve chords
    max_order: int
    c: float  # speed of sound, m/s
    amplitude: float  # A0
    wavenumber: float  # k = 2πf/c
    ka: float
    cut_sin2: float
    rho: float
    edge_coefficient: float
    absorption_db_per_m: float
    curvature: float  # 1.0, or 0.0: curved surfaces reflect like flat ones (echo.curvature_gain)

    @property
    def widths(self) -> dict[str, int]:
        """Number of surface elements of each kernel family (work items per pair)."""
        return {"mirror": len(self.sequences), "vertex": len(self.corners),
                "edge": len(self.diffractors),
                "circle": len(self.circles), "curve": len(self.interval_s)}


def wall_sequences(n_walls: int, max_order: int) -> np.ndarray:
    """[M, max_order] all sequences of 1..max_order walls, consecutive walls distinct,
    ordered by length then lexicographically, padded with -1."""
    out = []
    current = np.arange(n_walls, dtype=np.int64)[:, None]
    for order in range(1, max_order + 1):
        if order > 1:
            nxt = np.arange(n_walls, dtype=np.int64)
            grid = np.repeat(current, n_walls, axis=0)
            tail = np.tile(nxt, len(current))
            keep = tail != grid[:, -1]
            current = np.concatenate([grid, tail[:, None]], axis=1)[keep]
        pad = np.full((len(current), max_order - order), -1, dtype=np.int64)
        out.append(np.concatenate([current, pad], axis=1))
    if not out or n_walls == 0:
        return np.zeros((0, max(max_order, 1)), dtype=np.int64)
    return np.concatenate(out)


def _prepare_problem(scene: Scene, sensors: SensorArray | None = None,
                     geom: Geometry | None = None) -> EchoProblem:
    """Build the :class:`EchoProblem` of ``scene`` (``sensors`` default: place_sensors)."""
    geom = geom if geom is not None else build_geometry(scene)
    sensors = sensors if sensors is not None else place_sensors(scene, geom)
    xmin, ymin, xmax, ymax = scene.extent
    origin = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
    shift4 = np.concatenate([origin, origin])

    max_order = int(scene.echo.max_order)
    seq = wall_sequences(len(geom.walls), max_order)
    order = np.sum(seq >= 0, axis=1)
    corner = order >= 2
    for j in range(1, max_order):
        both = (seq[:, j] >= 0)
        a, b = seq[both, j - 1], seq[both, j]
        corner[both] &= geom.corner_pairs[a, b]

    n_walls = len(geom.walls)
    icurve = geom.interval_curve
    idx = np.arange(len(icurve))
    same_prev = np.r_[False, icurve[1:] == icurve[:-1]]
    same_next = np.r_[icurve[1:] == icurve[:-1], False]
    skip = np.stack([n_walls + idx - same_prev, n_walls + idx + same_next], axis=1)

    diffractors = geom.diffractors.copy()
    diffractors[:, :2] -= origin
    corners = geom.corners.copy()
    corners[:, :2] -= origin
    circles = geom.circles.copy()
    circles[:, :2] -= origin
    curves = geom.curves.copy()
    curves[:, :2] -= origin

    c = scene.medium.c
    t = scene.transducer
    k = physics.wavenumber(t.frequency_hz, c)
    cut_sin2, ka = t.beam(c)
    return EchoProblem(
        origin=origin,
        pairs=pairs(sensors),
        positions=sensors.positions - origin,
        axes=sensors.axes,
        walls=geom.walls - shift4,
        normals=geom.wall_normal,
        two_sided=geom.wall_two_sided,
        sequences=seq,
        sequence_order=order.astype(np.int64),
        sequence_corner=corner,
        corners=corners,
        diffractors=diffractors,
        circles=circles,
        curves=curves,
        interval_curve=icurve,
        interval_s=geom.interval_s,
        interval_skip=skip.astype(np.int64).reshape(-1, 2),
        interval_last=~same_next,
        occluders=geom.occluders - shift4,
        max_order=max_order,
        c=c,
        amplitude=t.amplitude,
        wavenumber=k,
        ka=ka,
        cut_sin2=cut_sin2,
        rho=scene.echo.reflection_coefficient,
        edge_coefficient=scene.echo.edge_coefficient,
        absorption_db_per_m=scene.echo.absorption_db_per_m,
        curvature=1.0 if scene.echo.curvature_gain else 0.0,
    )


# --------------------------------------------------------------------------- pairs in view

#: Margin added to every surface and beam in :func:`pairs_in_view`, metres and radians, so
#: that rounding can only keep a pair, never drop one with an echo.
VIEW_MARGIN_M = 1e-6
VIEW_MARGIN_RAD = 1e-6


def _view_primitives(pb: EchoProblem) -> np.ndarray:
    """[n, 5] every surface as a thick segment (x0, y0, x1, y1, radius) that contains it:
    walls (radius 0), circles (a point of radius r), sinusoids (their base line, radius
    |A|)."""
    parts = [np.column_stack([pb.walls, np.zeros(len(pb.walls))]),
             np.column_stack([pb.circles[:, :2], pb.circles[:, :2], pb.circles[:, 2]])]
    for k, cv in enumerate(pb.curves):
        s = pb.interval_s[pb.interval_curve == k]
        f, t = cv[:2], cv[2:4]
        parts.append(np.r_[f + s.min() * t, f + s.max() * t, abs(cv[4])][None])
    return np.concatenate(parts).reshape(-1, 5)


def _wedge_planes(pb: EchoProblem, sensor: np.ndarray) -> np.ndarray:
    """[N, 2, 3] the beams of ``sensor`` as two half-planes each, ``n·p + d ≥ 0``: the
    beam (inside where sin²θ ≤ cut_sin2 and cos θ > 0) is a wedge of half-angle α < 90°
    about the axis, the intersection of the half-planes of its two edges."""
    alpha = math.asin(math.sqrt(pb.cut_sin2)) + VIEW_MARGIN_RAD
    axis, origin = pb.axes[sensor], pb.positions[sensor]
    planes = []
    for side in (1.0, -1.0):  # inward normal of the edge at angle ±α from the axis
        a = side * alpha
        edge = np.stack([axis[:, 0] * math.cos(a) - axis[:, 1] * math.sin(a),
                         axis[:, 0] * math.sin(a) + axis[:, 1] * math.cos(a)], axis=-1)
        n = -side * np.stack([-edge[:, 1], edge[:, 0]], axis=-1)
        planes.append(np.column_stack([n, -_dot(n, origin)]))
    return np.stack(planes, axis=1)


def _meets(planes: np.ndarray, prims: np.ndarray) -> np.ndarray:
    """[P, n] bool: whether each thick segment of ``prims`` [n, 5] meets the intersection
    of the half-planes ``planes`` [P, H, 3] (each grown by the segment's radius; Cyrus–Beck
    clipping of the segment's parameter t ∈ [0, 1])."""
    lo = np.zeros((len(planes), len(prims)))
    hi = np.ones((len(planes), len(prims)))
    for h in range(planes.shape[1]):
        n, d = planes[:, h, None, :2], planes[:, h, None, 2]
        f0 = _dot(n, prims[None, :, :2]) + d + prims[None, :, 4] + VIEW_MARGIN_M
        f1 = _dot(n, prims[None, :, 2:4]) + d + prims[None, :, 4] + VIEW_MARGIN_M
        slope = f1 - f0  # f(t) = f0 + t·slope ≥ 0
        with np.errstate(divide="ignore", invalid="ignore"):
            root = -f0 / slope
        lo = np.where(slope > 0, np.maximum(lo, root), lo)
        hi = np.where(slope < 0, np.minimum(hi, root), hi)
        hi = np.where((slope == 0) & (f0 < 0), -1.0, hi)
    return lo <= hi


def pairs_in_view(pb: EchoProblem, block: int = 4096) -> np.ndarray:
    """[P] bool: the pairs of ``pb`` that can have an echo at all. A first-order return's
    reflection point lies in the joint beam region of T and R (thesis §2.1.1: inside both
    beams, amplitude 0 outside); a higher-order path leaves T inside T's beam and reaches
    R inside R's. So a pair is kept when some surface meets its joint beam region, or (when
    ``max_order`` ≥ 2) some surface meets T's beam and some R's. Conservative: a kept pair
    may still have no echo; a dropped pair has none (every kernel family gives it amplitude
    0)."""
    n = len(pb.pairs)
    prims = _view_primitives(pb)
    if n == 0 or pb.cut_sin2 >= 1.0 - 1e-9:
        return np.ones(n, dtype=bool)
    if len(prims) == 0:
        return np.zeros(n, dtype=bool)
    sensors = np.arange(len(pb.positions))
    planes = _wedge_planes(pb, sensors)
    sees = _meets(planes, prims)  # [N, n]: surfaces meeting each sensor's beam
    keep = np.zeros(n, dtype=bool)
    t, r = pb.pairs[:, 0], pb.pairs[:, 1]
    if np.any(pb.sequence_order >= 2) or len(pb.corners):  # multi-bounce paths exist
        keep = sees[t].any(axis=1) & sees[r].any(axis=1)
    for i in range(0, n, block):
        sl = slice(i, min(n, i + block))
        cand = sees[t[sl]] & sees[r[sl]]
        rows = np.flatnonzero(cand.any(axis=1) & ~keep[sl])
        if len(rows):
            joint = np.concatenate([planes[t[sl][rows]], planes[r[sl][rows]]], axis=1)
            keep[i + rows] = (_meets(joint, prims) & cand[rows]).any(axis=1)
    return keep


# --------------------------------------------------------------------------- assembling


def _pair_chunks(n_pairs: int, width: int) -> Iterator[slice]:
    """Slices of the pairs so that each launch has at most SLOTS_PER_LAUNCH work items."""
    step = max(1, SLOTS_PER_LAUNCH // max(width, 1))
    for start in range(0, n_pairs, step):
        yield slice(start, min(start + step, n_pairs))


def _rows(pb: EchoProblem, family: str, first_pair: int, tof: np.ndarray, amp: np.ndarray,
          point: np.ndarray) -> dict[str, np.ndarray]:
    """The echoes (amplitude > 0) among one launch's [pairs, elements] output slots."""
    p, e = np.nonzero(amp > 0)
    pair = pb.pairs[first_pair + p]
    n = len(p)
    if family == "mirror":
        kind = np.where(pb.sequence_corner[e], CORNER, SPECULAR)
        order = pb.sequence_order[e]
        element = e
    elif family == "vertex":
        kind = np.full(n, CORNER)
        order = np.full(n, 2)
        element = e + len(pb.sequences)
    else:
        kind = np.full(n, EDGE if family == "edge" else CURVED)
        order = np.ones(n, dtype=np.int64)
        element = e + len(pb.circles) if family == "curve" else e
    return {
        "tx": pair[:, 0], "rx": pair[:, 1],
        "tof_s": tof[p, e].astype(np.float64), "amplitude": amp[p, e].astype(np.float64),
        "kind": kind.astype(np.int8), "order": order.astype(np.int8),
        "point": point[p, e].astype(np.float64) + pb.origin, "element": element.astype(np.int64),
    }


def _table(parts: list[dict[str, np.ndarray]]) -> EchoTable:
    """Concatenate row blocks and sort them by (tx, rx, tof_s, kind, element)."""
    if not parts:
        return EchoTable(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                         np.zeros(0, np.int8), np.zeros(0, np.int8), np.zeros((0, 2)),
                         np.zeros(0, np.int64))
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    idx = np.lexsort((cols["element"], cols["kind"], cols["tof_s"], cols["rx"], cols["tx"]))
    return EchoTable(**{k: v[idx] for k, v in cols.items()})


def _solve(pb: EchoProblem, run: Callable[[str, slice], tuple]) -> EchoTable:
    """Run every non-empty family over chunks of pairs and collect the echoes."""
    parts = []
    for family, width in pb.widths.items():
        if width == 0 or len(pb.pairs) == 0:
            continue
        for chunk in _pair_chunks(len(pb.pairs), width):
            tof, amp, point = run(family, chunk)
            parts.append(_rows(pb, family, chunk.start, tof, amp, point))
    return _table(parts)


# --------------------------------------------------------------------------- NumPy reference


def reference_echoes(scene: Scene, sensors: SensorArray | None = None) -> EchoTable:
    """The echo table computed in NumPy float64: the reference of :func:`compute_echoes`."""
    pb = _prepare_problem(scene, sensors)
    families = {"mirror": _ref_mirror, "vertex": _ref_vertex, "edge": _ref_edge,
                "circle": _ref_circle, "curve": _ref_curve}
    with np.errstate(divide="ignore", invalid="ignore"):
        return _solve(pb, lambda family, chunk: families[family](pb, pb.pairs[chunk]))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(_dot(a, a))


def _ref_beam(pb: EchoProblem, axis: np.ndarray, d: np.ndarray) -> np.ndarray:
    """b(θ) between unit ``axis`` and direction ``d`` (physics.beam_pattern; sin²θ from the
    cross product as the kernels compute it)."""
    c = _dot(axis, d)
    s = _cross(axis, d)
    sin2 = (s * s) / _dot(d, d)
    inside = (c > 0) & (sin2 <= pb.cut_sin2)
    x = pb.ka * np.sqrt(np.where(inside, sin2, 0.0))
    return np.where(inside, physics.piston_pattern(x), 0.0)


def _ref_blocked(pb: EchoProblem, a: np.ndarray, b: np.ndarray, skip_lo: np.ndarray | int = -1,
                 skip_hi: np.ndarray | int = -1, skip_circle: np.ndarray | int = -1,
                 ) -> np.ndarray:
    """[n] whether legs a→b [n, 2] are blocked (kernels/common.h ``leg_blocked``)."""
    n = len(a)
    skip_lo = np.broadcast_to(skip_lo, (n,))[:, None]
    skip_hi = np.broadcast_to(skip_hi, (n,))[:, None]
    skip_circle = np.broadcast_to(skip_circle, (n,))[:, None]
    eps = OCCLUSION_EPS_M
    d = b - a
    len2 = _dot(d, d)
    length = np.sqrt(len2)
    blocked = np.zeros(n, dtype=bool)
    occ = pb.occluders
    if len(occ):
        q = occ[None, :, :2]
        e = occ[None, :, 2:] - q
        den = _cross(d[:, None], e)
        w = q - a[:, None]
        t = _cross(w, e) / den
        u = _cross(w, d[:, None]) / den
        i = np.arange(len(occ))[None, :]
        ln = length[:, None]
        hit = ((den != 0) & ~((i >= skip_lo) & (i <= skip_hi)) & (u >= 0) & (u <= 1)
               & (t * ln > eps) & ((1.0 - t) * ln > eps))
        blocked |= hit.any(axis=1)
    if len(pb.circles):
        t_lo = eps / length
        t_hi = 1.0 - t_lo
        w = pb.circles[None, :, :2] - a[:, None]
        t = np.clip(_dot(w, d[:, None]) / len2[:, None], t_lo[:, None], t_hi[:, None])
        gap = w - t[..., None] * d[:, None]
        r = pb.circles[None, :, 2]
        i = np.arange(len(pb.circles))[None, :]
        hit = (_dot(gap, gap) < r * r) & (i != skip_circle) & (length > 2.0 * eps)[:, None]
        blocked |= hit.any(axis=1)
    return blocked


def _unblock(pb: EchoProblem, amp: np.ndarray, legs: Callable[[np.ndarray], list]) -> None:
    """Zero ``amp`` [P, W] in place where a leg of a candidate (amp > 0) is blocked.

    ``legs(index)`` gives, for the candidates ``index`` (a tuple of arrays), a list of
    ``(a, b, active, skip)`` legs: endpoints [n, 2], a mask of the candidates that have this
    leg, and keyword arguments for :func:`_ref_blocked`.
    """
    index = np.nonzero(amp > 0)
    if len(index[0]) == 0:
        return
    blocked = np.zeros(len(index[0]), dtype=bool)
    for a, b, active, skip in legs(index):
        sel = np.flatnonzero(active & ~blocked)
        if len(sel):
            kw = {k: (v[sel] if np.ndim(v) else v) for k, v in skip.items()}
            blocked[sel] = _ref_blocked(pb, a[sel], b[sel], **kw)
    amp[tuple(ix[blocked] for ix in index)] = 0.0


def _ref_mirror(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Specular and multi-bounce paths by the image method (kernel ``mirror_paths``)."""
    seq = pb.sequences
    order = pb.sequence_order
    n_pairs, m, kmax = len(pr), len(seq), seq.shape[1]
    eps = OCCLUSION_EPS_M
    w = np.maximum(seq, 0)
    q = pb.walls[w][..., :2]  # [M, K, 2]
    e = pb.walls[w][..., 2:] - q
    nrm = pb.normals[w]
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]

    img = [np.broadcast_to(T, (n_pairs, m, 2))]
    for j in range(kmax):
        h = _dot(img[j] - q[:, j], nrm[:, j])
        mirrored = img[j] - (2.0 * h)[..., None] * nrm[:, j]
        img.append(np.where((seq[:, j] >= 0)[:, None], mirrored, img[j]))

    valid = np.ones((n_pairs, m), dtype=bool)
    pts = np.empty((n_pairs, m, kmax + 2, 2))
    pts[:, :, 0] = T
    pts[:, :, 1:] = R[:, :, None, :]
    x = np.broadcast_to(R, (n_pairs, m, 2))
    for j in range(kmax, 0, -1):
        active = (order >= j)[None, :]
        qj, ej, nj = q[:, j - 1], e[:, j - 1], nrm[:, j - 1]
        hx = _dot(x - qj, nj)
        hi = _dot(img[j] - qj, nj)
        crosses = ((hx > 0) & (hi < 0)) | ((hx < 0) & (hi > 0))
        t = hx / (hx - hi)
        p = x + t[..., None] * (img[j] - x)
        u = _dot(p - qj, ej) / _dot(ej, ej)
        valid &= ~active | (crosses & (u >= 0) & (u <= 1))
        x = np.where(active[..., None], p, x)
        pts[:, :, j] = x
    for j in range(1, kmax + 1):
        active = (order >= j)[None, :]
        h_in = _dot(pts[:, :, j - 1] - q[:, j - 1], nrm[:, j - 1])
        h_out = _dot(pts[:, :, j + 1] - q[:, j - 1], nrm[:, j - 1])
        front = (h_in > 0) & (h_out > 0)
        back = (h_in < 0) & (h_out < 0)
        ok = np.where(pb.two_sided[w[:, j - 1]], front | back, front)
        valid &= ~active | ok
    for j in range(kmax + 1):
        valid &= ~(order >= j)[None, :] | (_norm(pts[:, :, j + 1] - pts[:, :, j]) > eps)

    path = _norm(R - img[kmax])
    last = pts[:, np.arange(m), order]
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], pts[:, :, 1] - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], last - R)
    amp = np.where(valid, amp, 0.0) * pb.rho ** order
    amp = amp * physics.absorption_factor(path, pb.absorption_db_per_m)

    def legs(ix):
        leg_pts = pts[ix]  # [n, K + 2, 2]
        k = order[ix[1]]
        return [(leg_pts[:, j], leg_pts[:, j + 1], j <= k, {}) for j in range(kmax + 1)]

    _unblock(pb, amp, legs)
    return path / pb.c, amp, last


def _ref_mirror_at(x: np.ndarray, n: np.ndarray) -> np.ndarray:
    """x mirrored across the line through the origin with unit normal n."""
    return x - (2.0 * _dot(x, n))[..., None] * n


def _ref_vertex(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Double bounce through the vertex of a concave corner (kernel ``vertex_paths``)."""
    V = pb.corners[None, :, :2]
    na, nb = pb.corners[None, :, 2:4], pb.corners[None, :, 4:6]
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    t, r = T - V, R - V
    valid = (_dot(t, na) > 0) & (_dot(t, nb) > 0) & (_dot(r, na) > 0) & (_dot(r, nb) > 0)
    d1, d2 = _norm(t), _norm(r)
    valid &= (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)

    def on_return_ray(image):
        return ((_dot(r, image) < 0)
                & (np.abs(_cross(r, image)) <= OCCLUSION_EPS_M * _norm(image)))

    valid &= (on_return_ray(_ref_mirror_at(_ref_mirror_at(t, na), nb))
              | on_return_ray(_ref_mirror_at(_ref_mirror_at(t, nb), na)))
    path = d1 + d2
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], V - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], V - R)
    amp = np.where(valid, amp, 0.0) * pb.rho**2
    amp = amp * physics.absorption_factor(path, pb.absorption_db_per_m)
    vb_ = np.broadcast_to(V, (*amp.shape, 2))
    tb = np.broadcast_to(T, vb_.shape)
    rb = np.broadcast_to(R, vb_.shape)
    _unblock(pb, amp, lambda ix: [(tb[ix], vb_[ix], True, {}), (vb_[ix], rb[ix], True, {})])
    return path / pb.c, amp, vb_


def _ref_in_solid_cone(x: np.ndarray, v: np.ndarray, va: np.ndarray, vb: np.ndarray):
    """Whether x is strictly inside the convex angle between va and vb at v (kernel
    ``in_solid_cone``)."""
    cab = _cross(va, vb)
    w = x - v
    alpha = _cross(w, vb) / cab
    beta = _cross(va, w) / cab
    return (cab != 0) & (alpha > 0) & (beta > 0)


def _ref_edge(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Diffraction at convex edges (kernel ``edge_paths``)."""
    V = pb.diffractors[None, :, :2]
    va, vb = pb.diffractors[None, :, 2:4], pb.diffractors[None, :, 4:6]
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    valid = ~_ref_in_solid_cone(T, V, va, vb) & ~_ref_in_solid_cone(R, V, va, vb)
    d1 = _norm(V - T)
    d2 = _norm(R - V)
    valid &= (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)
    path = d1 + d2
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], V - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], V - R)
    amp = np.where(valid, amp, 0.0)
    amp = amp * physics.edge_gain(d1, d2, pb.wavenumber, pb.edge_coefficient)
    amp = amp * physics.absorption_factor(path, pb.absorption_db_per_m)
    amp = np.where(valid, amp, 0.0)
    vb_ = np.broadcast_to(V, (*amp.shape, 2))
    tb = np.broadcast_to(T, (*amp.shape, 2))
    rb = np.broadcast_to(R, (*amp.shape, 2))
    _unblock(pb, amp, lambda ix: [(tb[ix], vb_[ix], True, {}), (vb_[ix], rb[ix], True, {})])
    return path / pb.c, amp, vb_


def _circle_residual(a, b, r, n):
    """g = cross(n, û_T + û_R) at the circle point r·n (kernel ``circle_residual``)."""
    ut = a - r[..., None] * n
    ur = b - r[..., None] * n
    return _cross(n, ut / _norm(ut)[..., None] + ur / _norm(ur)[..., None])


def _ref_circle(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Specular points on cylinders by bisection on the shorter arc (kernel ``circle_paths``)."""
    C = pb.circles[None, :, :2]
    r = np.broadcast_to(pb.circles[None, :, 2], (len(pr), len(pb.circles)))
    T = pb.positions[pr[:, 0]][:, None, :]
    R = pb.positions[pr[:, 1]][:, None, :]
    a, b = T - C, R - C
    la, lb = _norm(a), _norm(b)
    valid = (la > r) & (lb > r)
    ah, bh = a / la[..., None], b / lb[..., None]
    m = ah + bh
    lm = _norm(m)
    valid &= lm > MIN_BISECTOR
    mh = m / lm[..., None]
    mp = np.stack([-mh[..., 1], mh[..., 0]], axis=-1)
    side = np.where(_cross(ah, bh) < 0, -1.0, 1.0)
    half = np.arctan2(_norm(ah - bh), lm)
    lo, hi = -half, half.copy()
    g_lo = _circle_residual(a, b, r, ah)
    hi = np.where(g_lo == 0, lo, hi)

    def normal(delta):
        return np.cos(delta)[..., None] * mh + (side * np.sin(delta))[..., None] * mp

    for _ in range(BISECT_ITERATIONS["float64"]):
        mid = 0.5 * (lo + hi)
        g = _circle_residual(a, b, r, normal(mid))
        go_up = (g != 0) & ((g < 0) == (g_lo < 0))
        lo = np.where(go_up, mid, lo)
        hi = np.where(go_up, hi, mid)
    n = normal(0.5 * (lo + hi))
    P = r[..., None] * n
    vt, vr = a - P, b - P
    d1, d2 = _norm(vt), _norm(vr)
    cos_t = _dot(n, vt) / d1
    cos_r = _dot(n, vr) / d2
    valid &= (cos_t > 0) & (cos_r > 0) & (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)
    path = d1 + d2
    Pw = C + P
    amp = pb.amplitude * _ref_beam(pb, pb.axes[pr[:, 0]][:, None], Pw - T)
    amp = amp * _ref_beam(pb, pb.axes[pr[:, 1]][:, None], Pw - R)
    amp = np.where(valid, amp, 0.0)
    gain = physics.curved_gain(d1, d2, pb.curvature / r, np.where(valid, cos_t, 1.0))
    amp = amp * pb.rho * gain * physics.absorption_factor(path, pb.absorption_db_per_m)
    amp = np.where(valid, amp, 0.0)
    circle = np.broadcast_to(np.arange(len(pb.circles))[None, :], amp.shape)
    tb = np.broadcast_to(T, Pw.shape)
    rb = np.broadcast_to(R, Pw.shape)
    _unblock(pb, amp, lambda ix: [(tb[ix], Pw[ix], True, {"skip_circle": circle[ix]}),
                                  (Pw[ix], rb[ix], True, {"skip_circle": circle[ix]})])
    return path / pb.c, amp, Pw


def _curve_residual(cv, s, T, R):
    """f(s) = dot(P'(s), û_T + û_R), the derivative of −(path length) (kernel
    ``curve_residual``)."""
    p = curve_point(cv, s)
    d1, _ = curve_derivatives(cv, s)
    ut, ur = T - p, R - p
    return _dot(d1, ut / _norm(ut)[..., None] + ur / _norm(ur)[..., None])


def _ref_curve(pb: EchoProblem, pr: np.ndarray) -> tuple[np.ndarray, ...]:
    """Specular points on sinusoids, one bisection per sampling interval (kernel
    ``curve_paths``)."""
    n_pairs, n_int = len(pr), len(pb.interval_s)
    tof = np.zeros((n_pairs, n_int))
    amp = np.zeros((n_pairs, n_int))
    point = np.zeros((n_pairs, n_int, 2))
    cv_all = pb.curves[pb.interval_curve]
    T_all = pb.positions[pr[:, 0]][:, None, :]
    R_all = pb.positions[pr[:, 1]][:, None, :]
    s0, s1 = pb.interval_s[None, :, 0], pb.interval_s[None, :, 1]
    f0 = _curve_residual(cv_all[None], s0, T_all, R_all)
    f1 = _curve_residual(cv_all[None], s1, T_all, R_all)
    bracket = ((f0 == 0) | ((f1 != 0) & ((f0 < 0) != (f1 < 0)))
               | (pb.interval_last[None, :] & (f1 == 0)))
    p_idx, i_idx = np.nonzero(bracket)
    if len(p_idx) == 0:
        return tof, amp, point
    cv = cv_all[i_idx]
    T = pb.positions[pr[p_idx, 0]]
    R = pb.positions[pr[p_idx, 1]]
    f0 = f0[p_idx, i_idx]
    f1 = f1[p_idx, i_idx]
    lo, hi = pb.interval_s[i_idx, 0], pb.interval_s[i_idx, 1]
    hi = np.where(f0 == 0, lo, hi)
    lo = np.where((f0 != 0) & (f1 == 0), hi, lo)
    for _ in range(BISECT_ITERATIONS["float64"]):
        mid = 0.5 * (lo + hi)
        f = _curve_residual(cv, mid, T, R)
        go_up = (f != 0) & ((f < 0) == (f0 < 0))
        lo = np.where(go_up, mid, lo)
        hi = np.where(go_up, hi, mid)
    s = 0.5 * (lo + hi)
    P = curve_point(cv, s)
    d1v, d2v = curve_derivatives(cv, s)
    vt, vr = T - P, R - P
    side_t, side_r = _cross(d1v, vt), _cross(d1v, vr)
    valid = ((side_t > 0) & (side_r > 0)) | ((side_t < 0) & (side_r < 0))
    d1, d2 = _norm(vt), _norm(vr)
    valid &= (d1 > OCCLUSION_EPS_M) & (d2 > OCCLUSION_EPS_M)
    path = d1 + d2
    a = pb.amplitude * _ref_beam(pb, pb.axes[pr[p_idx, 0]], P - T)
    a = a * _ref_beam(pb, pb.axes[pr[p_idx, 1]], P - R)
    a = np.where(valid, a, 0.0)
    speed = _norm(d1v)
    curvature = _cross(d1v, d2v) / (speed * speed * speed)
    kappa = np.where(side_t > 0, -curvature, curvature)
    cos_i = np.abs(_cross(d1v, vt)) / (speed * d1)
    gain = physics.curved_gain(d1, d2, pb.curvature * kappa, np.where(valid, cos_i, 1.0))
    a = a * pb.rho * gain * physics.absorption_factor(path, pb.absorption_db_per_m)
    a = np.where(valid, a, 0.0)[None, :]
    skip = pb.interval_skip[i_idx]
    _unblock(pb, a, lambda ix: [
        (T[ix[1]], P[ix[1]], True, {"skip_lo": skip[ix[1], 0], "skip_hi": skip[ix[1], 1]}),
        (P[ix[1]], R[ix[1]], True, {"skip_lo": skip[ix[1], 0], "skip_hi": skip[ix[1], 1]})])
    tof[p_idx, i_idx] = path / pb.c
    amp[p_idx, i_idx] = a[0]
    point[p_idx, i_idx] = P
    return tof, amp, point


# --------------------------------------------------------------------------- OpenCL


def _program(context, precision: str, max_order: int):
    """``kernels/echoes.cl`` built for ``precision`` and ``max_order`` (memoised)."""
    from .opencl import beam_series_defines, build_program, precision_defines

    defines: dict[str, object] = {
        "MAX_ORDER": max(1, max_order),
        "EPS_M": float(OCCLUSION_EPS_M),
        "MAX_FOCUS_GAIN": float(physics.MAX_FOCUS_GAIN),
        "BISECT_ITERATIONS": BISECT_ITERATIONS[precision],
        **beam_series_defines(),
        **precision_defines(precision),
    }
    return build_program(context, "echoes.cl", defines)


#: The kernel of each surface family in kernels/echoes.cl.
KERNEL_NAMES = {"mirror": "mirror_paths", "vertex": "vertex_paths", "edge": "edge_paths",
                "circle": "circle_paths", "curve": "curve_paths"}


def _constants(pb: EchoProblem) -> np.ndarray:
    """The kernels' per-scene constants (``K_*`` in kernels/common.h), float64."""
    return np.array([
        pb.amplitude,
        (pb.ka / physics.J1_FIRST_ZERO) ** 2,
        pb.cut_sin2,
        pb.rho,
        pb.absorption_db_per_m * math.log(10.0) / 20.0,
        pb.edge_coefficient / (2.0 * math.sqrt(2.0 * math.pi * pb.wavenumber)),
        1.0 / pb.c,
        pb.curvature,
    ])


def compute_echoes(scene: Scene, sensors: SensorArray | None = None, *, context=None,
                   device: str | None = None, precision: str = "float32",
                   skip_empty_pairs: bool = True, stats: dict | None = None) -> EchoTable:
    """The echo table of ``scene`` computed by the OpenCL kernels of ``kernels/echoes.cl``.

    ``context`` (a ``pyopencl.Context``) or ``device`` (see :func:`clsonar.opencl.get_context`)
    chooses the device. ``precision="float64"`` needs ``cl_khr_fp64`` (else
    :class:`~clsonar.errors.DeviceError`). Same model as :func:`reference_echoes`.

    Work a scene does not need is left out, never changing the table: pairs whose beams meet
    no surface (:func:`pairs_in_view`; ``skip_empty_pairs=False`` evaluates them anyway) and
    the kernel families of surface kinds the scene lacks (no walls: no mirror sequences, no
    concave corner: no corner returns, no free end or convex vertex: no diffraction, no
    circle or sinusoid: no specular-point search). ``stats``, if given, receives the counts
    ``pairs_evaluated``, ``pairs_skipped_empty`` and ``echo_families_run``.
    """
    import pyopencl as cl

    from .opencl import PRECISIONS, context_for, kernel, work_group
    from .opencl import queue as queue_of

    ctx = context_for(context, device, precision)
    pb = _prepare_problem(scene, sensors)
    n_pairs = len(pb.pairs)
    if skip_empty_pairs:
        pb = dataclasses.replace(pb, pairs=pb.pairs[pairs_in_view(pb)])
    if stats is not None:
        stats["pairs_evaluated"] = len(pb.pairs)
        stats["pairs_skipped_empty"] = n_pairs - len(pb.pairs)
        stats["echo_families_run"] = sum(1 for w in pb.widths.values() if w and len(pb.pairs))
    real = PRECISIONS[precision]
    queue = queue_of(ctx)
    program = _program(ctx, precision, pb.max_order)
    mf = cl.mem_flags

    def buf(array: np.ndarray, dtype, columns: int | None = None):
        a = np.ascontiguousarray(array, dtype=dtype)
        if a.size == 0:  # OpenCL has no empty buffers; the kernels never read this one
            a = np.zeros(columns or 1, dtype=dtype)
        return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

    def circles4() -> np.ndarray:
        out = np.zeros((len(pb.circles), 4))
        out[:, :3] = pb.circles
        return out

    shared = {
        "pos": buf(pb.positions, real), "axis": buf(pb.axes, real),
        "occ": buf(pb.occluders, real, 4), "n_occ": np.int32(len(pb.occluders)),
        "circles": buf(circles4(), real, 4), "n_circles": np.int32(len(pb.circles)),
        "k": buf(_constants(pb), real),
    }
    family_args = {
        "mirror": lambda: [buf(pb.walls, real, 4), buf(pb.normals, real, 2),
                           buf(pb.two_sided, np.int32), buf(pb.sequences, np.int32)],
        "vertex": lambda: [buf(pb.corners, real, 6)],
        "edge": lambda: [buf(pb.diffractors, real, 6)],
        "circle": lambda: [],
        "curve": lambda: [buf(pb.curves, real, 7), buf(pb.interval_curve, np.int32),
                          buf(pb.interval_s, real, 2), buf(pb.interval_skip, np.int32, 2),
                          buf(pb.interval_last, np.int32)],
    }
    kernels = {family: kernel(program, name) for family, name in KERNEL_NAMES.items()}
    args_cache: dict[str, list] = {}

    def run(family: str, chunk: slice):
        width = pb.widths[family]
        if family not in args_cache:
            args_cache[family] = family_args[family]()
        pr = buf(pb.pairs[chunk], np.int32)
        n = chunk.stop - chunk.start
        tof = np.empty((n, width), dtype=real)
        amp = np.empty((n, width), dtype=real)
        point = np.empty((n, width, 2), dtype=real)
        out = [cl.Buffer(ctx, mf.WRITE_ONLY, a.nbytes) for a in (tof, amp, point)]
        group = work_group(kernels[family], ctx.devices[0], WORK_GROUP)
        padded = -(-width // group) * group
        kernels[family](queue, (padded, n), (group, 1), np.int32(width), pr,
                        shared["pos"], shared["axis"],
                        *args_cache[family], shared["occ"], shared["n_occ"], shared["circles"],
                        shared["n_circles"], shared["k"], *out)
        for host, dev in zip((tof, amp, point), out, strict=True):
            cl.enqueue_copy(queue, host, dev)
        queue.finish()
        return tof, amp, point

    return _solve(pb, run)


__all__ = ["KINDS", "EchoProblem", "EchoTable", "compute_echoes", "pairs_in_view",
           "reference_echoes",
           "wall_sequences"]
