"""The host side of ``kernels/accumulate.cl``: :func:`accumulate` (loci, tiled or dense),
:func:`accumulate_with_stats` (with its :class:`AccumulationStats`),
:func:`occupancy_grid` and :func:`backproject`.

One work item computes 8 pixels of a row as one float8 vector on a CPU (PoCL does not
vectorise across work items a kernel with a loop), one pixel on a GPU (:data:`LAUNCH`); the
loop over loci is branch-free. The tiled kernel ``loci_tiles`` runs one work-group per
non-empty tile (:func:`clsonar.mapping.tiles.bin_loci`) with its loci in local memory, at most
:data:`MAX_LAUNCH_BYTES` of tiles per launch, each launch's tiles copied into the host map;
the dense kernels ``loci_map`` and ``backproject_map`` take their rows in ``__constant``
memory in blocks of at most :data:`MAX_ROWS_PER_LAUNCH`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import physics
from ..opencl import (
    PRECISIONS,
    beam_series_defines,
    build_program,
    context_for,
    device_kind,
    max_work_group,
    precision_defines,
)
from ..opencl import kernel as kernel_of
from ..opencl import queue as queue_of
from ..scene import MappingSettings, Scene
from ..sensors import SensorArray
from .grid import LAUNCH, check_map_memory, work_items
from .loci import LOCUS_COLUMNS, MapProblem, prepare_backprojection, prepare_loci
from .occupancy import prepare_occupancy
from .tiles import bin_loci

#: Most loci (or back-projection pairs) per kernel launch; fewer where the device's
#: ``__constant`` memory is smaller (half of it is used).
MAX_ROWS_PER_LAUNCH = 4096

#: Tile shape (pixels along x, along y) of the tiled accumulation (kernel ``loci_tiles``)
#: by device kind: one work-group per tile, TILE_W/VEC × TILE_H work items.
TILES = {"CPU": (32, 32), "GPU": (32, 8), "other": (32, 8)}

#: Loci a work-group copies into local memory at a time (kernel ``loci_tiles``).
TILE_CHUNK = 64

#: Most bytes of tiles the tiled accumulation draws per launch (less where the device's
#: largest buffer is smaller): a map with more non-empty tiles is drawn in several launches,
#: each launch's tiles copied into the host map, so no device buffer holds the whole map.
MAX_LAUNCH_BYTES = 64 << 20

#: Most (tile, locus) pairs per launch of the tiled kernel (it indexes them in 32 bits).
MAX_PAIRS_PER_LAUNCH = 1 << 28


@dataclass(frozen=True)
class AccumulationStats:
    """What one accumulation did (for ``report.json``): ``tiles_total`` tiles of the map
    (0 when dense), ``tiles_skipped`` of them empty (no locus can vote there: not
    launched), ``pixel_locus_tests`` the pixel-locus tests the kernel made (tiles launched ×
    pixels per tile × loci listed; dense: the padded map × every locus), ``dense_tests``
    what the dense kernel makes (the padded map × every locus), ``launches`` of the tiled
    kernel (of at most :data:`MAX_LAUNCH_BYTES` of tiles each; dense: of at most
    :data:`MAX_ROWS_PER_LAUNCH` loci each), ``tile`` the tile shape (pixels along x, y) or
    None."""

    tiled: bool
    tile: tuple[int, int] | None
    tiles_total: int
    tiles_skipped: int
    pixel_locus_tests: int
    dense_tests: int
    launches: int

    def as_dict(self) -> dict[str, object]:
        """The counters as a JSON-ready dict."""
        d = dataclasses.asdict(self)
        d["tile"] = list(self.tile) if self.tile is not None else None
        return d


def _program(context, precision: str, weight_beam: bool, vec: int):
    """``kernels/accumulate.cl`` for ``precision``, the beam weight or not, and ``vec``
    pixels per work item (memoised by :func:`clsonar.opencl.build_program`)."""
    defines: dict[str, object] = {
        "VEC": vec,
        "WEIGHT_BEAM": int(weight_beam),
        "MAX_FOCUS_GAIN": float(physics.MAX_FOCUS_GAIN),
        "TILE_CHUNK": TILE_CHUNK,
        **beam_series_defines(),
        **precision_defines(precision),
    }
    return build_program(context, "accumulate.cl", defines)


def _rows_per_launch(device, columns: int, itemsize: int) -> int:
    """Rows the dense kernels take per launch: :data:`MAX_ROWS_PER_LAUNCH`, or what half
    the device's ``__constant`` memory holds."""
    constant_rows = int(device.max_constant_buffer_size) // 2 // (columns * itemsize)
    return max(1, min(MAX_ROWS_PER_LAUNCH, constant_rows))


# --------------------------------------------------------------------------- dense


def _fit_group(kernel, device, group: tuple[int, int]) -> tuple[int, int]:
    """The work-group ``group`` halved (y first) down to the kernel's largest."""
    wgx, wgy = group
    limit = max_work_group(kernel, device)
    while wgx * wgy > limit and wgx * wgy > 1:
        wgx, wgy = (wgx, wgy // 2) if wgy > 1 else (wgx // 2, wgy)
    return wgx, wgy


def _block_rows(device, pb: MapProblem, itemsize: int) -> int:
    """Rows per launch of a dense kernel: what ``__constant`` memory holds, and for
    back-projection what half the device's largest buffer of envelopes holds."""
    block = _rows_per_launch(device, pb.rows.shape[1], itemsize)
    if pb.envelopes is not None:
        env_bytes = pb.envelopes.shape[1] * itemsize
        block = max(1, min(block, int(device.max_mem_alloc_size) // 2 // env_bytes))
    return block


def _run(ctx, pb: MapProblem, precision: str, name: str) -> np.ndarray:
    """Launch kernel ``name`` over the whole map, rows in blocks; return the [ny, nx] map."""
    import pyopencl as cl

    device = ctx.devices[0]
    real = PRECISIONS[precision]
    itemsize = np.dtype(real).itemsize
    g = pb.grid
    if len(pb.rows) == 0:
        return np.zeros((g.ny, g.nx), dtype=real)
    vec, group = LAUNCH[device_kind(device), precision]
    kernel = kernel_of(_program(ctx, precision, pb.weight == "beam", vec), name)
    wgx, wgy = _fit_group(kernel, device, group)
    items_x, items_y = work_items(g.nx, g.ny, vec, wgx, wgy)
    pitch = items_x * vec
    queue = queue_of(ctx)
    mf = cl.mem_flags
    out = cl.Buffer(ctx, mf.READ_WRITE, pitch * items_y * itemsize)
    block = _block_rows(device, pb, itemsize)
    cell = real(g.cell)
    beam = (real(pb.cut_sin2), real(pb.beam_u))
    where = (np.int32(g.col0), np.int32(g.row0))
    for first in range(0, len(pb.rows), block):
        rows = np.ascontiguousarray(pb.rows[first:first + block], dtype=real)
        n = np.int32(len(rows))
        rows_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=rows)
        tail = (*where, np.int32(first == 0), out, np.int64(0), np.int32(pitch))
        args: tuple[object, ...]
        if pb.envelopes is None:
            args = (rows_buf, n, cell, real(pb.half_band), *beam, *tail)
        else:
            env = np.ascontiguousarray(pb.envelopes[first:first + block], dtype=real)
            env_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=env)
            args = (rows_buf, n, env_buf, np.int32(env.shape[1]), real(pb.inv_c_dt), cell,
                    *beam, *tail)
        kernel(queue, (items_x, items_y), (wgx, wgy), *args)
    host = np.empty((items_y, pitch), dtype=real)
    cl.enqueue_copy(queue, host, out)
    queue.finish()
    return np.ascontiguousarray(host[:g.ny, :g.nx])


def _dense_stats(ctx, pb: MapProblem, precision: str) -> AccumulationStats:
    device = ctx.devices[0]
    vec, (wgx, wgy) = LAUNCH[device_kind(device), precision]
    items_x, items_y = work_items(pb.grid.nx, pb.grid.ny, vec, wgx, wgy)
    tests = items_x * vec * items_y * len(pb.rows)
    block = _rows_per_launch(device, LOCUS_COLUMNS, np.dtype(PRECISIONS[precision]).itemsize)
    return AccumulationStats(False, None, 0, 0, tests, tests, -(-len(pb.rows) // block))


# --------------------------------------------------------------------------- tiled


def _tile_shape(kernel, device, vec: int) -> tuple[int, int]:
    """:data:`TILES` for ``device``, its height cut to the kernel's largest work-group."""

    tw, th = TILES[device_kind(device)]
    tw = max(tw, vec) // vec * vec
    limit = max_work_group(kernel, device)
    return tw, max(1, min(th, limit // (tw // vec)))


def _place_tiles(result: np.ndarray, tiles: np.ndarray, ty: np.ndarray, tx: np.ndarray
                 ) -> None:
    """Copy ``tiles`` [k, th, tw] into ``result`` [ny, nx] at tile rows ``ty``, columns
    ``tx``, the map's partial last tiles cut (a plain loop: faster here than NumPy's
    advanced indexing into a strided view of the map)."""
    ny, nx = result.shape
    _, th, tw = tiles.shape
    for k, (y, x) in enumerate(zip((ty * th).tolist(), (tx * tw).tolist(), strict=True)):
        result[y:y + th, x:x + tw] = tiles[k, :min(th, ny - y), :min(tw, nx - x)]


def _launches(start: np.ndarray, live: np.ndarray, most: int) -> list[np.ndarray]:
    """``live`` tiles (ascending; tile k lists loci ``start[k]`` to ``start[k + 1]``) in
    consecutive launches of at most ``most`` tiles and :data:`MAX_PAIRS_PER_LAUNCH`
    (tile, locus) pairs (the kernel indexes them with 32-bit integers); a tile with more
    pairs gets a launch of its own."""
    out = []
    ends = start[live + 1]
    first = 0
    while first < len(live):
        cap = int(np.searchsorted(ends, start[live[first]] + MAX_PAIRS_PER_LAUNCH, side="right"))
        last = max(first + 1, min(first + most, cap))
        out.append(live[first:last])
        first = last
    return out


def _draw_tiles(ctx, kernel, pb: MapProblem, bins, launches: list[np.ndarray], vec: int,
                result: np.ndarray) -> None:
    """Run ``kernel`` (``loci_tiles``) once per launch of tiles and copy each launch's
    tiles into ``result``."""
    import pyopencl as cl

    real = result.dtype.type
    g = pb.grid
    tw, th = bins.tile
    ntx = bins.shape[1]
    queue = queue_of(ctx)
    mf = cl.mem_flags
    rows_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                         hostbuf=np.ascontiguousarray(pb.rows, dtype=real))
    size = max(map(len, launches))
    out = cl.Buffer(ctx, mf.WRITE_ONLY, size * th * tw * result.itemsize)
    host = np.empty((size, th, tw), dtype=real)
    constants = (real(g.cell), real(pb.half_band), real(pb.cut_sin2), real(pb.beam_u),
                 np.int32(g.col0), np.int32(g.row0))
    group = (tw // vec, th)
    for ids in launches:
        s0, s1 = int(bins.start[ids[0]]), int(bins.start[ids[-1] + 1])
        members = np.ascontiguousarray(bins.members[s0:s1], dtype=np.int32)
        start = np.append(bins.start[ids] - s0, s1 - s0).astype(np.int32)
        ty, tx = ids // ntx, ids % ntx
        at = np.stack([tx * tw, ty * th], axis=1).astype(np.int32)
        bufs = [cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)
                for a in (members, start, at)]
        kernel(queue, (len(ids) * group[0], group[1]), group, rows_buf, *bufs, *constants,
               out)
        cl.enqueue_copy(queue, host[:len(ids)], out)
        queue.finish()
        _place_tiles(result, host[:len(ids)], ty, tx)


def _run_tiles(ctx, pb: MapProblem, precision: str) -> tuple[np.ndarray, AccumulationStats]:
    """Draw the loci map tile by tile (kernel ``loci_tiles``, one work-group per tile that
    :func:`~clsonar.mapping.tiles.bin_loci` lists any locus for), at most
    :data:`MAX_LAUNCH_BYTES` of tiles (and the device's largest buffer) per launch, each
    launch's tiles copied into the host map."""
    device = ctx.devices[0]
    vec, _ = LAUNCH[device_kind(device), precision]
    real = PRECISIONS[precision]
    itemsize = np.dtype(real).itemsize
    kernel = kernel_of(_program(ctx, precision, pb.weight == "beam", vec), "loci_tiles")
    tw, th = _tile_shape(kernel, device, vec)
    bins = bin_loci(pb, (tw, th))
    nty, ntx = bins.shape
    counts = bins.counts
    live = np.flatnonzero(counts)
    limit = min(MAX_LAUNCH_BYTES, int(device.max_mem_alloc_size), int(device.global_mem_size) // 2)
    launches = _launches(bins.start, live, max(1, limit // (tw * th * itemsize)))
    result = np.zeros((pb.grid.ny, pb.grid.nx), dtype=real)
    stats = AccumulationStats(True, (tw, th), ntx * nty, ntx * nty - len(live),
                              int(counts.sum()) * tw * th,
                              _dense_stats(ctx, pb, precision).dense_tests, len(launches))
    if len(live):
        _draw_tiles(ctx, kernel, pb, bins, launches, vec, result)
    return result, stats


# --------------------------------------------------------------------------- public


def accumulate_with_stats(scene: Scene, sensors: SensorArray, loci, *, context=None,
                          device: str | None = None, precision: str | None = None,
                          settings: MappingSettings | None = None, tiles: bool = True
                          ) -> tuple[np.ndarray, AccumulationStats]:
    """:func:`accumulate`'s map and the :class:`AccumulationStats` of drawing it."""
    settings = settings if settings is not None else scene.mapping
    precision = precision or settings.precision
    ctx = context_for(context, device, precision)
    if tiles:  # the device holds one band at a time; the host the map
        check_map_memory(scene, precision,
                         host_bytes_per_cell=np.dtype(PRECISIONS[precision]).itemsize)
    else:
        check_map_memory(scene, precision, ctx.devices[0])
    pb = prepare_loci(scene, sensors, loci, settings)
    if tiles:
        return _run_tiles(ctx, pb, precision)
    return _run(ctx, pb, precision, "loci_map"), _dense_stats(ctx, pb, precision)


def accumulate(scene: Scene, sensors: SensorArray, loci, *, context=None,
               device: str | None = None, precision: str | None = None,
               settings: MappingSettings | None = None, tiles: bool = True) -> np.ndarray:
    """The loci map ``[ny, nx]`` of ``scene`` drawn by the OpenCL kernel ``loci_tiles``
    (``tiles``, default: each tile of the map tests only the loci that can reach it, empty
    tiles are skipped, no device buffer holds the whole map) or ``loci_map``
    (not ``tiles``: every pixel tests every locus). Both give the same map, to the bit.

    ``loci``: any object with ``tx``, ``rx``, ``tof_s`` and ``amplitude`` arrays
    (:class:`~clsonar.mapping.Loci`, the detector's table, an echo table); ``sensors`` the
    :class:`~clsonar.sensors.SensorArray` they index. ``settings`` (default
    ``scene.mapping``) gives ``weight``, ``band_m`` and ``precision`` (overridden by
    ``precision``); its ``mode`` is the caller's business: this draws loci. float32 maps come
    back as float32, float64 (needs ``cl_khr_fp64``) as float64. A map that cannot fit in
    the device's or this machine's memory raises :class:`~clsonar.errors.ClsonarError`.
    Same model as :func:`~clsonar.mapping.accumulate_reference`.
    :func:`accumulate_with_stats` also returns the counters (tiles skipped, tests made).
    """
    return accumulate_with_stats(scene, sensors, loci, context=context, device=device,
                                 precision=precision, settings=settings, tiles=tiles)[0]


def backproject(scene: Scene, sensors: SensorArray, pairs, envelopes, dt: float, *,
                context=None, device: str | None = None, precision: str | None = None,
                settings: MappingSettings | None = None) -> np.ndarray:
    """The back-projected map ``[ny, nx]`` (``mapping.mode = "backprojection"``) by the
    OpenCL kernel ``backproject_map``.

    ``pairs`` [P, 2] are (tx, rx) sensor indices; ``envelopes`` [P, n] their received
    envelopes sampled every ``dt`` seconds from the transmission (n ≥ 2). Otherwise as
    :func:`accumulate`; same model as :func:`~clsonar.mapping.backproject_reference`.
    """
    settings = settings if settings is not None else scene.mapping
    precision = precision or settings.precision
    ctx = context_for(context, device, precision)
    check_map_memory(scene, precision, ctx.devices[0])
    pb = prepare_backprojection(scene, sensors, pairs, envelopes, dt, settings)
    return _run(ctx, pb, precision, "backproject_map")


def occupancy_grid(scene: Scene, sensors: SensorArray, loci, *, context=None,
                   device: str | None = None, precision: str | None = None,
                   settings: MappingSettings | None = None) -> np.ndarray:
    """The occupancy grid's log-odds ``[ny, nx]`` (``mapping.mode = "occupancy"``; Elfes
    1987) by the OpenCL kernel ``occupancy_map``: every detection of ``loci`` adds, inside
    both beams, the occupied evidence over its band and the empty evidence nearer than it
    (:mod:`clsonar.mapping.occupancy`). Dense (every pixel against every detection: the
    empty cones cover most of the beams), otherwise as :func:`accumulate`; same model as
    :func:`~clsonar.mapping.occupancy_grid_reference`."""
    settings = settings if settings is not None else scene.mapping
    precision = precision or settings.precision
    ctx = context_for(context, device, precision)
    check_map_memory(scene, precision, ctx.devices[0])
    return _run(ctx, prepare_occupancy(scene, sensors, loci, settings), precision,
                "occupancy_map")


def sounded_cells(scene: Scene, sensors: SensorArray, loci, *, context=None,
                  device: str | None = None) -> np.ndarray:
    """[ny, nx] bool: the cells inside the sonar cone of some locus of ``loci`` — inside
    both beams and no farther than the locus' band (|p − T| + |p − R| ≤ c·τ + band/2): the
    region the echoes sounded, by the occupancy grid's sensor model (Elfes 1987,
    :mod:`clsonar.mapping.occupancy`) with every locus' occupied and empty evidence 1, so
    that no reading cancels another. The region of the rate of correctly detected empty
    cells (Barshan 2007; :func:`clsonar.metrics.cell_rates`)."""
    precision = scene.mapping.precision
    ctx = context_for(context, device, precision)
    check_map_memory(scene, precision, ctx.devices[0])
    pb = prepare_occupancy(scene, sensors, loci)
    pb.rows[:, 9:11] = 1.0
    return _run(ctx, pb, precision, "occupancy_map") > 0
