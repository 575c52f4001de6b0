"""Directional maximum (``mapping.mode = "directional-maximum"``; Barshan 2007,
"Directional processing of ultrasonic arc maps and its comparison with existing
techniques", IJRR 26(8)): the arcs are accumulated as for ``loci`` (:func:`accumulate`),
then along each arc only the cells where the accumulated map is largest are kept.

Two implementations, as for the other kernels: :func:`arc_maxima` runs ``arc_maxima`` and
``arc_maxima_cells`` of ``kernels/directional.cl`` (one work item per arc, over the
bounding box of its band, :func:`~clsonar.mapping.tiles.band_boxes`);
:func:`arc_maxima_reference` evaluates the same tests on the whole map in NumPy float64
(:mod:`.reference`'s view of a pixel), so the float64 kernels reproduce it bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..opencl import PRECISIONS, build_program, context_for, precision_defines
from ..opencl import kernel as kernel_of
from ..opencl import queue as queue_of
from ..scene import MappingSettings, Scene
from ..sensors import SensorArray
from .grid import check_map_memory
from .loci import MapProblem, prepare_loci
from .reference import pixel_view
from .tiles import band_boxes


@dataclass(frozen=True, eq=False)
class ArcMaxima:
    """Per arc (locus row) the largest accumulated value on it, ``best`` [n] (0: none),
    and the cells that hold it: ``source`` [m] the arc, ``cells`` [m] the flat index
    ``iy·nx + ix`` of the cell, arc after arc, each arc's cells in row-major order."""

    best: np.ndarray
    source: np.ndarray
    cells: np.ndarray


def _check(pb: MapProblem, acc: np.ndarray) -> np.ndarray:
    acc = np.asarray(acc)
    if acc.shape != (pb.grid.ny, pb.grid.nx):
        raise ValueError(f"the accumulated map must be [{pb.grid.ny}, {pb.grid.nx}], "
                         f"not {list(acc.shape)}")
    return acc


def arc_maxima_reference(scene: Scene, sensors: SensorArray, loci, acc: np.ndarray, *,
                         settings: MappingSettings | None = None) -> ArcMaxima:
    """:func:`arc_maxima` in NumPy float64 over the whole map: the cells of each arc are
    those :func:`~clsonar.mapping.accumulate_reference` gives its vote."""
    check_map_memory(scene, "float64", reference=True)
    pb = prepare_loci(scene, sensors, loci, settings)
    acc = _check(pb, acc).astype(np.float64)
    best = np.zeros(len(pb.rows))
    source: list[np.ndarray] = []
    cells: list[np.ndarray] = []
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, row in enumerate(pb.rows):
            v = pixel_view(pb, row)
            on = (np.abs(v["path"] - row[8]) <= pb.half_band) & v["inside"]
            best[i] = max(0.0, float(acc[on].max())) if on.any() else 0.0
            if best[i] > 0:
                kept = np.flatnonzero((on & (acc == best[i])).ravel())
                cells.append(kept)
                source.append(np.full(len(kept), i))
    return ArcMaxima(best, _joined(source), _joined(cells))


def _joined(parts: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)


def arc_maxima(scene: Scene, sensors: SensorArray, loci, acc: np.ndarray, *, context=None,
               device: str | None = None, precision: str | None = None,
               settings: MappingSettings | None = None) -> ArcMaxima:
    """The directional maximum of each arc (Barshan 2007) by the OpenCL kernels of
    ``kernels/directional.cl``: for each locus of ``loci``, the largest value of ``acc``
    (the accumulated arc map, [ny, nx], e.g. :func:`~clsonar.mapping.accumulate`'s) over
    the cells it votes for, and those of its cells that hold it. ``acc`` is read in the
    kernels' precision; ``settings`` as :func:`~clsonar.mapping.accumulate`. Same model as
    :func:`arc_maxima_reference`."""
    import pyopencl as cl

    settings = settings if settings is not None else scene.mapping
    precision = precision or settings.precision
    ctx = context_for(context, device, precision)
    check_map_memory(scene, precision, ctx.devices[0])
    pb = prepare_loci(scene, sensors, loci, settings)
    real = PRECISIONS[precision]
    acc = np.ascontiguousarray(_check(pb, acc), dtype=real)
    n = len(pb.rows)
    if n == 0:
        return ArcMaxima(np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64))
    program = build_program(ctx, "directional.cl", precision_defines(precision))
    queue = queue_of(ctx)
    mf = cl.mem_flags

    def buffer(a: np.ndarray):
        return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

    g = pb.grid
    common = (buffer(np.ascontiguousarray(pb.rows, dtype=real)), buffer(band_boxes(pb)),
              np.int32(n), buffer(acc), np.int32(g.nx), real(g.cell), real(pb.half_band),
              real(pb.cut_sin2), np.int32(g.col0), np.int32(g.row0))
    best, kept = np.empty(n, dtype=real), np.empty(n, dtype=np.int32)
    best_buf = cl.Buffer(ctx, mf.READ_WRITE, best.nbytes)
    kept_buf = cl.Buffer(ctx, mf.WRITE_ONLY, kept.nbytes)
    kernel_of(program, "arc_maxima")(queue, (n,), None, *common, best_buf, kept_buf)
    cl.enqueue_copy(queue, best, best_buf)
    cl.enqueue_copy(queue, kept, kept_buf)
    offset = np.concatenate([[0], np.cumsum(kept, dtype=np.int64)])
    cells = np.zeros(max(int(offset[-1]), 1), dtype=np.int64)
    cells_buf = cl.Buffer(ctx, mf.WRITE_ONLY, cells.nbytes)
    kernel_of(program, "arc_maxima_cells")(queue, (n,), None, *common, best_buf,
                                           buffer(offset[:-1].copy()), cells_buf)
    cl.enqueue_copy(queue, cells, cells_buf)
    queue.finish()
    source = np.repeat(np.arange(n, dtype=np.int64), kept)
    return ArcMaxima(best.astype(np.float64), source, cells[:int(offset[-1])])
