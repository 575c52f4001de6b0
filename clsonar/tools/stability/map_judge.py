"""Judging the map kernels (kernels/accumulate.cl, float32) against their float64 references
(:func:`clsonar.mapping.accumulate_reference`, :func:`clsonar.mapping.backproject_reference`)
on the map cases: every differing pixel must lie on a band or beam edge."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import numpy as np

from ... import mapping
from ...opencl import has_fp64
from .findings import BOUNDS, EPS32, Findings, finite
from .map_cases import MILLION, map_case

#: Alternative launch shapes of the map kernels: (pixels per work item on a CPU — GPUs: 1 —,
#: the dense kernels' work-group shape, the tiled kernel's tile shape).
ALT_MAP_LAUNCH = ((1, (16, 4), (16, 16)), (4, (4, 2), (64, 8)))

def _pixel_xy(pb: mapping.MapProblem, iy: np.ndarray, ix: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Local coordinates (metres, float64) of pixels ``(iy, ix)`` as column vectors."""
    g = pb.grid
    px = ((g.col0 + ix).astype(np.float64) * g.cell)[:, None]
    py = ((g.row0 + iy).astype(np.float64) * g.cell)[:, None]
    return px, py


def _scale(px: np.ndarray, py: np.ndarray, r: np.ndarray) -> np.ndarray:
    """S, the largest local coordinate a pixel's test against locus rows ``r`` involves
    (the pixel's, T's or R's), per pixel and row."""
    return np.maximum(np.abs(px) + np.abs(py),
                      np.maximum(np.abs(r[0]) + np.abs(r[1]), np.abs(r[2]) + np.abs(r[3])))


def edge_pixels(pb: mapping.MapProblem, iy: np.ndarray, ix: np.ndarray,
                loci: bool = True) -> np.ndarray:
    """For pixels ``(iy, ix)`` of problem ``pb``: is the pixel, for some row, within
    ``edge_roundings`` float32 roundings of a band edge (loci) or of a beam edge, in float64?

    A float32 coordinate carries an error ≈ ε·S (S the largest local coordinate involved), so
    a distance d an error ≈ 2ε·S, the path an error ≈ ε·(4S + path), sin²θ·|d|² an error
    ≈ 2ε·|d|·(|d| + 2S). The beam edges are ``axis·d > 0`` and ``(axis×d)² ≤ cut·|d|²``
    (mapping.py); the band edge ``| path − c·τ | = band/2``.
    """
    k = BOUNDS["edge_roundings"] * EPS32
    px, py = _pixel_xy(pb, iy, ix)
    out = np.zeros(len(iy), dtype=bool)
    for start in range(0, len(pb.rows), 4096):
        r = pb.rows[start:start + 4096].T
        scale = _scale(px, py, r)
        near = np.zeros((len(iy), r.shape[1]), dtype=bool)
        for fx, fy, ax, ay in ((r[0], r[1], r[4], r[5]), (r[2], r[3], r[6], r[7])):
            dx, dy = px - fx, py - fy
            dd = dx * dx + dy * dy
            d = np.sqrt(dd)
            cos_d = ax * dx + ay * dy
            sin_d = ax * dy - ay * dx
            near |= np.abs(cos_d) <= k * (d + scale)
            near |= np.abs(sin_d * sin_d - pb.cut_sin2 * dd) <= 2 * k * d * (d + 2 * scale)
        if loci:
            path = (np.hypot(px - r[0], py - r[1]) + np.hypot(px - r[2], py - r[3]))
            near |= (np.abs(np.abs(path - r[8]) - pb.half_band)
                     <= k * (4 * scale + path + np.abs(r[8])))
        out |= near.any(axis=1)
    return out


def value_tolerance(pb: mapping.MapProblem, ref: np.ndarray) -> np.ndarray:
    """Per pixel, the difference between float32 and float64 values that rounding alone
    explains: a sum of n terms rounds to ≈ √n·ε relative (``value_rtol`` at least), and a
    back-projected envelope read at a delay off by δ samples changes by its slope times δ,
    δ from the path's float32 error (see :func:`edge_pixels`)."""
    n = max(len(pb.rows), 1)
    rtol = max(BOUNDS["value_rtol"], 64 * EPS32 * math.sqrt(n))
    tol = rtol * (np.abs(ref) + 1e-2 * (np.abs(ref).max() if ref.size else 0.0))
    if pb.envelopes is not None and pb.envelopes.size:
        g = pb.grid
        far = (max(abs(g.col0), g.nx + g.col0) + max(abs(g.row0), g.ny + g.row0)) * g.cell
        far = max(far, float(np.abs(pb.rows[:, :4]).max()) if len(pb.rows) else 0.0)
        delay = BOUNDS["edge_roundings"] * EPS32 * 8 * far * pb.inv_c_dt
        slope = np.abs(np.diff(pb.envelopes, axis=1)).max(axis=1)
        tol = tol + float(np.sum(slope)) * (delay + 1e-3)
    return tol


def _beam_slope(pb: mapping.MapProblem) -> float:
    """max |d(b(θ))/dθ| inside the beam cut (rad⁻¹), b the kernels' beam series."""
    theta = np.linspace(0.0, math.asin(math.sqrt(min(pb.cut_sin2, 1.0))), 2001)
    b = mapping.reference_beam(np.sin(theta) ** 2, pb.beam_u)
    return float(np.max(np.abs(np.diff(b)) / np.diff(theta)))


def beam_slack(pb: mapping.MapProblem, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """For pixels ``(iy, ix)`` of a ``weight = "beam"`` problem: how much b(θ_T)·b(θ_R)
    summed over the rows that vote there (or nearly) can change when each direction p − T,
    p − R is off by its float32 error, ≈ 2ε·S/|d| rad (S the largest local coordinate,
    :func:`edge_pixels`): the beam's slope times that angle, per transducer."""
    k = BOUNDS["edge_roundings"] * EPS32
    slope = _beam_slope(pb)
    px, py = _pixel_xy(pb, iy, ix)
    out = np.zeros(len(iy))
    for start in range(0, len(pb.rows), 4096):
        r = pb.rows[start:start + 4096].T
        scale = _scale(px, py, r)
        d_t = np.hypot(px - r[0], py - r[1])
        d_r = np.hypot(px - r[2], py - r[3])
        near = np.abs(d_t + d_r - r[8]) <= pb.half_band * (1 + 1e-3) + k * (4 * scale + r[8])
        angle = k * (scale / np.maximum(d_t, 1e-30) + scale / np.maximum(d_r, 1e-30))
        out += np.sum(np.where(near, np.minimum(slope * angle, 1.0), 0.0), axis=1)
    return out


def compare_maps(pb: mapping.MapProblem, ref: np.ndarray, got: np.ndarray, name: str,
                 loci: bool = True) -> Findings:
    """Judge a float32 map ``got`` against its float64 twin ``ref``: values within
    :func:`value_tolerance` (plus :func:`beam_slack` for beam weights), other pixels on an
    edge (:func:`edge_pixels`)."""
    f = Findings(cases=1, pixels=int(ref.size))
    if not (finite(got) and finite(ref)):
        f.nonfinite += 1
        f.fail(name, "NaN or Inf in a map")
        return f
    if got.shape != ref.shape:
        f.fail(name, f"map shape {got.shape} ≠ {ref.shape}")
        return f
    delta = np.abs(got.astype(np.float64) - ref)
    differ = delta > value_tolerance(pb, ref)
    if loci and pb.weight == "beam" and np.any(differ):  # the beam weight's own rounding
        iy, ix = np.nonzero(differ)
        differ[iy, ix] = delta[iy, ix] > (value_tolerance(pb, ref)[iy, ix]
                                          + beam_slack(pb, iy, ix))
    iy, ix = np.nonzero(differ)
    f.differing = len(iy)
    f.worst_fraction = f.differing / max(ref.size, 1)
    f.worst_fraction_case = name
    if f.differing:
        on_edge = edge_pixels(pb, iy, ix, loci)
        f.differing_off_edge = int(np.count_nonzero(~on_edge))
        if f.differing_off_edge:
            where = list(zip(iy[~on_edge][:3].tolist(), ix[~on_edge][:3].tolist(), strict=True))
            f.fail(name, f"{f.differing_off_edge} pixels differ off every edge, e.g. {where}")
    if f.worst_fraction > BOUNDS["map_differing_fraction"] and ref.size >= 10_000:
        f.fail(name, f"{f.worst_fraction:.2%} of the pixels differ")
    return f




@contextlib.contextmanager
def map_launch(vec: int, group: tuple[int, int], tile: tuple[int, int]) -> Iterator[None]:
    """Run the map kernels with ``vec`` pixels per work item in work groups of ``group``
    (dense kernels) and tiles of ``tile`` pixels, one work group each (tiled kernel)."""
    saved = dict(mapping.LAUNCH), dict(mapping.TILES)
    for key in mapping.LAUNCH:
        mapping.LAUNCH[key] = (vec if key[0] == "CPU" else 1, group)
    for kind in mapping.TILES:
        mapping.TILES[kind] = tile
    try:
        yield
    finally:
        mapping.LAUNCH.clear()
        mapping.LAUNCH.update(saved[0])
        mapping.TILES.clear()
        mapping.TILES.update(saved[1])


def check_map_case(family: str, seed: int, context, *, million: int = MILLION,
                   work_groups: bool = False) -> Findings:
    """Compare the float32 map kernel with float64 on one case: with the NumPy reference,
    or, for the ``million`` family, with the float64 kernel (bit-identical to the reference,
    tests/test_mapping.py) where the device has ``cl_khr_fp64``."""
    name = f"map {family} seed={seed}"
    case = map_case(family, seed, million=million)
    scene, sensors = case.scene, case.sensors
    if case.pairs is not None:
        args = (scene, sensors, case.pairs, case.envelopes, case.dt)
        pb = mapping.prepare_backprojection(*args)
        ref = mapping.backproject_reference(*args)
        run = lambda: mapping.backproject(*args, context=context, precision="float32")  # noqa: E731
        loci = False
    else:
        pb = mapping.prepare_loci(scene, sensors, case.loci)
        if family == "million":
            if not has_fp64(context):
                return Findings()
            ref = mapping.accumulate(scene, sensors, case.loci, context=context,
                                     precision="float64")
        else:
            ref = mapping.accumulate_reference(scene, sensors, case.loci)
        run = lambda: mapping.accumulate(scene, sensors, case.loci, context=context,  # noqa: E731
                                         precision="float32")
        loci = True
    got = run()
    f = compare_maps(pb, ref, got, name, loci)
    if work_groups:
        for vec, group, tile in ALT_MAP_LAUNCH:
            with map_launch(vec, group, tile):
                again = run()
            if not np.array_equal(got, again):
                f.work_group_mismatches += 1
                f.fail(name, f"{vec} pixels per item in groups of {group}, tiles of {tile}, "
                             "give another map")
        if loci:
            dense = mapping.accumulate(scene, sensors, case.loci, context=context,
                                       precision="float32", tiles=False)
            if not np.array_equal(got, dense):
                f.work_group_mismatches += 1
                f.fail(name, "the dense kernel gives another map than the tiled one")
    return f
