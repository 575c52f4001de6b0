"""The NumPy float64 reference of the map's kernels (``kernels/accumulate.cl``):
:func:`accumulate_reference`, :func:`occupancy_grid_reference` and :func:`backproject_reference`
evaluate the kernels' expressions, in the same order, in float64, so the float64 kernels
reproduce them bit for bit (the model is described in :mod:`clsonar.mapping`)."""

from __future__ import annotations

import numpy as np

from .. import physics
from ..scene import MappingSettings, Scene
from ..sensors import SensorArray
from .grid import check_map_memory
from .loci import MapProblem, prepare_backprojection, prepare_loci
from .occupancy import prepare_occupancy


def reference_beam(sin2: np.ndarray, beam_u: float) -> np.ndarray:
    """b(θ) from sin²θ: the kernels' beam series by Horner's rule (common.h ``beam()``)."""
    coeffs = physics.beam_series_coefficients(14)
    u = beam_u * sin2
    acc = np.zeros_like(u)
    for c in coeffs[::-1]:
        acc = acc * u + c
    return (1.0 - u) * acc


def pixel_view(pb: MapProblem, row: np.ndarray) -> dict[str, np.ndarray]:
    """|p − T|², axis_T × (p − T) (the same for R), |p − T| + |p − R| and the joint-beam
    mask over the whole map, evaluated exactly as the kernels' ``view_pixel``."""
    g = pb.grid
    px = ((g.col0 + np.arange(g.nx)).astype(np.float64) * g.cell)[None, :]
    py = ((g.row0 + np.arange(g.ny)).astype(np.float64) * g.cell)[:, None]
    tx, ty = px - row[0], py - row[1]
    rx, ry = px - row[2], py - row[3]
    dd_t = tx * tx + ty * ty
    dd_r = rx * rx + ry * ry
    c_t = row[4] * tx + row[5] * ty
    c_r = row[6] * rx + row[7] * ry
    s_t = row[4] * ty - row[5] * tx
    s_r = row[6] * ry - row[7] * rx
    path = np.sqrt(dd_t) + np.sqrt(dd_r)
    inside = ((c_t > 0) & (s_t * s_t <= pb.cut_sin2 * dd_t)
              & (c_r > 0) & (s_r * s_r <= pb.cut_sin2 * dd_r))
    return {"dd_t": dd_t, "s_t": s_t, "dd_r": dd_r, "s_r": s_r, "path": path,
            "inside": inside}


def _ref_joint_beam(pb: MapProblem, v: dict[str, np.ndarray]) -> np.ndarray:
    """b(θ_T)·b(θ_R) as the kernels' ``joint_beam``."""
    return (reference_beam((v["s_t"] * v["s_t"]) / v["dd_t"], pb.beam_u)
            * reference_beam((v["s_r"] * v["s_r"]) / v["dd_r"], pb.beam_u))


def _reference_loci(pb: MapProblem) -> np.ndarray:
    acc = np.zeros((pb.grid.ny, pb.grid.nx))
    with np.errstate(divide="ignore", invalid="ignore"):
        for row in pb.rows:
            v = pixel_view(pb, row)
            vote = (np.abs(v["path"] - row[8]) <= pb.half_band) & v["inside"]
            w = _ref_joint_beam(pb, v) if pb.weight == "beam" else row[9]
            acc += np.where(vote, w, 0.0)
    return acc


def _reference_occupancy(pb: MapProblem) -> np.ndarray:
    acc = np.zeros((pb.grid.ny, pb.grid.nx))
    with np.errstate(divide="ignore", invalid="ignore"):
        for row in pb.rows:
            v = pixel_view(pb, row)
            miss = v["path"] - row[8]
            acc += np.where((np.abs(miss) <= pb.half_band) & v["inside"], row[9], 0.0)
            acc += np.where((miss < -pb.half_band) & v["inside"], row[10], 0.0)
    return acc


def _reference_backprojection(pb: MapProblem) -> np.ndarray:
    acc = np.zeros((pb.grid.ny, pb.grid.nx))
    env = pb.envelopes
    if env is None:
        raise ValueError("a back-projection problem needs its envelopes")
    last = float(env.shape[1] - 1) if env.ndim == 2 else 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, row in enumerate(pb.rows):
            v = pixel_view(pb, row)
            t = v["path"] * pb.inv_c_dt
            k = np.minimum(np.floor(t), last - 1.0)
            f = t - k
            ik = k.astype(np.int64)
            e0, e1 = env[i][ik], env[i][ik + 1]
            w = e0 + f * (e1 - e0)
            if pb.weight == "beam":
                w = w * _ref_joint_beam(pb, v)
            acc += np.where((t <= last) & v["inside"], w, 0.0)
    return acc


def accumulate_reference(scene: Scene, sensors: SensorArray, loci, *,
                         settings: MappingSettings | None = None) -> np.ndarray:
    """The loci map in NumPy float64 ([ny, nx]): the reference of :func:`accumulate`."""
    check_map_memory(scene, "float64", reference=True)
    return _reference_loci(prepare_loci(scene, sensors, loci, settings))


def occupancy_grid_reference(scene: Scene, sensors: SensorArray, loci, *,
                        settings: MappingSettings | None = None) -> np.ndarray:
    """The occupancy grid's log-odds in NumPy float64 ([ny, nx]): the reference of
    :func:`~clsonar.mapping.occupancy_grid`."""
    check_map_memory(scene, "float64", reference=True)
    return _reference_occupancy(prepare_occupancy(scene, sensors, loci, settings))


def backproject_reference(scene: Scene, sensors: SensorArray, pairs, envelopes, dt: float, *,
                          settings: MappingSettings | None = None) -> np.ndarray:
    """The back-projected map in NumPy float64 ([ny, nx]): the reference of
    :func:`backproject`."""
    check_map_memory(scene, "float64", reference=True)
    return _reference_backprojection(
        prepare_backprojection(scene, sensors, pairs, envelopes, dt, settings))
