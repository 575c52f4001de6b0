"""The echo problem: what both implementations (the OpenCL kernels and the NumPy reference)
start from — the scene's geometry, transducers and fired pairs, the wall sequences of the
image method and the amplitude model's constants, as float64 arrays relative to the extent's
centre (so float32 keeps micrometre resolution anywhere in the scene)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import physics
from ..errors import SceneError
from ..geometry import Geometry, build_geometry, meet_at_corner
from ..scene import MAX_WALL_SEQUENCES, Polyline, Scene
from ..sensors import SensorArray, pairs, place_sensors

#: A leg crossing an occluder (or entering a circle) within this many metres of either end is
#: not blocked: paths end on surfaces, and a reflection point may sit next to a vertex.
OCCLUSION_EPS_M = 1e-4

#: Bisection steps of the curved-surface searches: 40 halve a bracket of ≤ π rad (or ≤ 1 cm)
#: below float64 resolution, 32 below float32's.
BISECT_ITERATIONS = {"float64": 40, "float32": 32}


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
    edge_utd: float  # 1.0: physics.edge_gain (echo.edge_model "utd"); 0.0: edge_gain_estimate
    absorption_db_per_m: float
    curvature: float  # 1.0, or 0.0: curved surfaces reflect like flat ones (echo.curvature_gain)

    @property
    def widths(self) -> dict[str, int]:
        """Number of surface elements of each kernel family (work items per pair)."""
        return {"mirror": len(self.sequences), "vertex": len(self.corners),
                "edge": len(self.diffractors),
                "circle": len(self.circles), "curve": len(self.interval_s)}


def scene_walls(scene: Scene) -> int:
    """How many walls (polyline segments) ``scene`` has."""
    return sum(len(s.points) - (0 if s.closed else 1)
               for s in scene.surfaces if isinstance(s, Polyline))


def check_sequences(scene: Scene) -> None:
    """Refuse (one line, :class:`~clsonar.errors.SceneError`) a scene whose mirror
    sequences (:func:`wall_sequences`: at most walls^``echo.max_order``) could be more than
    :data:`~clsonar.scene.MAX_WALL_SEQUENCES`. A floor mapped room by room is checked room
    by room (:func:`clsonar.pipeline.check_work`): each room's echoes stay among its own
    walls."""
    walls = scene_walls(scene)
    if float(walls) ** scene.echo.max_order > MAX_WALL_SEQUENCES:
        raise SceneError(f"{walls} walls to the power {scene.echo.max_order} are more than "
                         f"the {MAX_WALL_SEQUENCES:.0e} reflection sequences clsonar can hold "
                         "in one map: use a lower max_order or fewer polyline points",
                         key="echo.max_order", source=scene.name)


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


def _sequence_kinds(geom: Geometry, seq: np.ndarray, max_order: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(order [M], corner [M])`` of the wall sequences ``seq``: their number of walls, and
    whether there are at least two and every consecutive pair meets at a concave corner."""
    order = np.sum(seq >= 0, axis=1)
    corner = order >= 2
    for j in range(1, max_order):
        both = (seq[:, j] >= 0)
        a, b = seq[both, j - 1], seq[both, j]
        corner[both] &= meet_at_corner(geom, a, b)
    return order, corner


def _interval_skip(geom: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """``(skip [I, 2], last [I])`` of the sinusoids' sampling intervals: the occluders (the
    interval's own chord and its neighbours' on the same curve) a leg ending on the interval
    does not test, and whether it is the last interval of its curve."""
    n_walls = len(geom.walls)
    icurve = geom.interval_curve
    idx = np.arange(len(icurve))
    same_prev = np.r_[False, icurve[1:] == icurve[:-1]]
    same_next = np.r_[icurve[1:] == icurve[:-1], False]
    skip = np.stack([n_walls + idx - same_prev, n_walls + idx + same_next], axis=1)
    return skip.astype(np.int64).reshape(-1, 2), ~same_next


def _shifted(rows: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """A copy of ``rows`` whose first two columns (a point) are made relative to ``origin``."""
    out = rows.copy()
    out[:, :2] -= origin
    return out


def prepare_problem(scene: Scene, sensors: SensorArray | None = None,
                    geom: Geometry | None = None) -> EchoProblem:
    """Build the :class:`EchoProblem` of ``scene`` (``sensors`` default: place_sensors)."""
    check_sequences(scene)
    geom = geom if geom is not None else build_geometry(scene)
    sensors = sensors if sensors is not None else place_sensors(scene, geom)
    xmin, ymin, xmax, ymax = scene.extent
    origin = np.array([0.5 * (xmin + xmax), 0.5 * (ymin + ymax)])
    shift4 = np.concatenate([origin, origin])
    max_order = int(scene.echo.max_order)
    seq = wall_sequences(len(geom.walls), max_order)
    order, corner = _sequence_kinds(geom, seq, max_order)
    skip, last = _interval_skip(geom)
    c = scene.medium.c
    t = scene.transducer
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
        corners=_shifted(geom.corners, origin),
        diffractors=_shifted(geom.diffractors, origin),
        circles=_shifted(geom.circles, origin),
        curves=_shifted(geom.curves, origin),
        interval_curve=geom.interval_curve,
        interval_s=geom.interval_s,
        interval_skip=skip,
        interval_last=last,
        occluders=geom.occluders - shift4,
        max_order=max_order,
        c=c,
        amplitude=t.amplitude,
        wavenumber=physics.wavenumber(t.frequency_hz, c),
        ka=ka,
        cut_sin2=cut_sin2,
        rho=scene.echo.reflection_coefficient,
        edge_coefficient=scene.echo.edge_coefficient,
        edge_utd=1.0 if scene.echo.edge_model == "utd" else 0.0,
        absorption_db_per_m=scene.echo.absorption_db_per_m,
        curvature=1.0 if scene.echo.curvature_gain else 0.0,
    )
