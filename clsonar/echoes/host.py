"""The echo model on an OpenCL device: the host side of the kernels of kernels/echoes.cl."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .. import physics, steps
from ..opencl import (
    PRECISIONS,
    beam_series_defines,
    build_program,
    context_for,
    kernel,
    precision_defines,
    read_only_buffer,
    work_group,
)
from ..opencl import queue as queue_of
from ..scene import Scene
from ..sensors import SensorArray
from .problem import BISECT_ITERATIONS, OCCLUSION_EPS_M, EchoProblem, prepare_problem
from .table import EchoTable, solve
from .view import pairs_in_view

#: Work-group size of the kernels along the surface elements (:func:`clsonar.opencl.work_group`).
WORK_GROUP = 32

#: The kernel of each surface family in kernels/echoes.cl.
KERNEL_NAMES = {"mirror": "mirror_paths", "vertex": "vertex_paths", "edge": "edge_paths",
                "circle": "circle_paths", "curve": "curve_paths"}


def _program(context, precision: str, max_order: int):
    """``kernels/echoes.cl`` built for ``precision`` and ``max_order`` (memoised)."""
    defines: dict[str, object] = {
        "MAX_ORDER": max(1, max_order),
        "EPS_M": float(OCCLUSION_EPS_M),
        "MAX_FOCUS_GAIN": float(physics.MAX_FOCUS_GAIN),
        "FRESNEL_SWITCH": float(physics.FRESNEL_SWITCH),
        "BISECT_ITERATIONS": BISECT_ITERATIONS[precision],
        **beam_series_defines(),
        **precision_defines(precision),
    }
    return build_program(context, "echoes.cl", defines)


def _constants(pb: EchoProblem) -> np.ndarray:
    """The kernels' per-scene constants (``K_*`` in kernels/common.h), float64."""
    return np.array([
        pb.amplitude,
        (pb.ka / physics.J1_FIRST_ZERO) ** 2,
        pb.cut_sin2,
        pb.rho,
        pb.absorption_db_per_m * math.log(10.0) / 20.0,
        pb.edge_coefficient,
        1.0 / pb.c,
        pb.curvature,
        pb.wavenumber,
        pb.edge_utd,
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
    ctx = context_for(context, device, precision)
    pb = prepare_problem(scene, sensors)
    steps.poll()
    n_pairs = len(pb.pairs)
    if skip_empty_pairs:
        pb = dataclasses.replace(pb, pairs=pb.pairs[pairs_in_view(pb)])
    if stats is not None:
        stats["pairs_evaluated"] = len(pb.pairs)
        stats["pairs_skipped_empty"] = n_pairs - len(pb.pairs)
        stats["echo_families_run"] = sum(1 for w in pb.widths.values() if w and len(pb.pairs))
    return solve(pb, _Launcher(ctx, pb, precision))


class _Launcher:
    """The buffers and kernels of one :class:`EchoProblem` on one context; called with a
    family and a chunk of pairs, it runs that family's kernel and returns its outputs
    ``(tof, amp, point, phase)`` [pairs, elements] (see :func:`~clsonar.echoes.table.solve`)."""

    def __init__(self, ctx, pb: EchoProblem, precision: str) -> None:
        import pyopencl as cl

        self.cl, self.ctx, self.pb = cl, ctx, pb
        self.real = PRECISIONS[precision]
        self.queue = queue_of(ctx)
        program = _program(ctx, precision, pb.max_order)
        circles4 = np.zeros((len(pb.circles), 4))
        circles4[:, :3] = pb.circles
        real = self.real
        self.shared = {
            "pos": self.buf(pb.positions, real), "axis": self.buf(pb.axes, real),
            "occ": self.buf(pb.occluders, real, 4), "n_occ": np.int32(len(pb.occluders)),
            "circles": self.buf(circles4, real, 4), "n_circles": np.int32(len(pb.circles)),
            "k": self.buf(_constants(pb), real),
        }
        self.kernels = {family: kernel(program, name) for family, name in KERNEL_NAMES.items()}
        self.args: dict[str, list] = {}

    def buf(self, array: np.ndarray, dtype, columns: int | None = None):
        """A read-only device copy of ``array`` as ``dtype`` (:func:`read_only_buffer`)."""
        return read_only_buffer(self.ctx, array, dtype, columns or 1)

    def family_args(self, family: str) -> list:
        """The buffers of ``family``'s surface elements (made on first use)."""
        if family not in self.args:
            pb, real, buf = self.pb, self.real, self.buf
            self.args[family] = {
                "mirror": lambda: [buf(pb.walls, real, 4), buf(pb.normals, real, 2),
                                   buf(pb.two_sided, np.int32), buf(pb.sequences, np.int32)],
                "vertex": lambda: [buf(pb.corners, real, 6)],
                "edge": lambda: [buf(pb.diffractors, real, 6)],
                "circle": lambda: [],
                "curve": lambda: [buf(pb.curves, real, 7), buf(pb.interval_curve, np.int32),
                                  buf(pb.interval_s, real, 2),
                                  buf(pb.interval_skip, np.int32, 2),
                                  buf(pb.interval_last, np.int32)],
            }[family]()
        return self.args[family]

    def __call__(self, family: str, chunk: slice) -> tuple[np.ndarray, ...]:
        cl, ctx, queue, shared = self.cl, self.ctx, self.queue, self.shared
        width = self.pb.widths[family]
        args = self.family_args(family)
        pr = self.buf(self.pb.pairs[chunk], np.int32)
        n = chunk.stop - chunk.start
        tof = np.empty((n, width), dtype=self.real)
        amp = np.empty((n, width), dtype=self.real)
        point = np.empty((n, width, 2), dtype=self.real)
        phase = np.empty((n, width), dtype=self.real)
        hosts = (tof, amp, point, phase)
        out = [cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, a.nbytes) for a in hosts]
        group = work_group(self.kernels[family], ctx.devices[0], WORK_GROUP)
        padded = -(-width // group) * group
        self.kernels[family](queue, (padded, n), (group, 1), np.int32(width), pr,
                             shared["pos"], shared["axis"], *args, shared["occ"],
                             shared["n_occ"], shared["circles"], shared["n_circles"],
                             shared["k"], *out)
        for host, dev in zip(hosts, out, strict=True):
            cl.enqueue_copy(queue, host, dev)
        queue.finish()
        return hosts
