"""Detection and envelopes on an OpenCL device: the host side of kernels/signals.cl (how the
kernels do without materialising A-scans: see :mod:`clsonar.signals`)."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np

from .. import steps
from ..echoes import EchoTable
from ..numerics import unique
from ..opencl import (
    PRECISIONS,
    build_program,
    context_for,
    device_kind,
    get_context,
    precision_defines,
    read_only_buffer,
)
from ..opencl import kernel as kernel_of
from ..opencl import queue as queue_of
from ..opencl import work_group as fixed_work_group
from ..scene import Scene
from ..sensors import SensorArray
from .detection import (
    Candidates,
    Detections,
    empty_detections,
    envelope_floor,
    envelope_noise_scale,
    finish_envelope,
    finish_threshold,
    join_candidates,
    merge_candidates,
    noise_stays_quiet,
    thresholds_of,
)
from .dsp import HIST_BASE, HIST_BINS, HIST_STRIDE, noise_scale
from .model import SignalModel, envelope_grid, envelope_offset
from .philox import philox_key
from .synthesis import PairEchoes, inputs

#: Candidate capacity per pair of the first pass (a re-run gives overflowing pairs more).
DEFAULT_CAPACITY = {"threshold": 256, "envelope": 64}

#: Samples per work item (chunk), by device kind and mode.
DEFAULT_CHUNK = {("CPU", "threshold"): 8192, ("CPU", "envelope"): 4096,
                 ("GPU", "threshold"): 1024, ("GPU", "envelope"): 1024}

#: Work-group size (fixed: PoCL compiles a kernel anew for each size it meets).
WORK_GROUP = 32

#: Work items per launch and candidate slots per launch (pairs are split into launches).
ITEMS_PER_LAUNCH = 1 << 20
SLOTS_PER_LAUNCH = 1 << 22

#: Pair slots of a scan's first launch; later launches are sized from the time it took so
#: that each lasts about LAUNCH_S seconds: a run can report progress and stop (the GUI's
#: Cancel) between two launches. The split never changes a detection: every pair slot is
#: scanned on its own.
FIRST_LAUNCH_SLOTS = 1024
LAUNCH_S = 0.2


def launch_size(size: int, seconds: float, most: int) -> int:
    """The pair slots of the next launch after one of ``size`` slots took ``seconds``:
    scaled to last :data:`LAUNCH_S`, at most 4× larger or smaller than the last, between
    1 and ``most``."""
    scaled = size * LAUNCH_S / max(seconds, 1e-6)
    return int(min(max(scaled, size / 4.0, 1.0), size * 4.0, most))


def _program(context, precision: str, box: int, span: int, demod_period: int):
    """``kernels/signals.cl`` built for ``precision`` and the filter's sizes (memoised)."""
    defines: dict[str, object] = {
        "BOX": box, "SPAN": span, "RING": 2 * span + 1, "HIST_BINS": HIST_BINS,
        "HIST_BASE": HIST_BASE, "HIST_STRIDE": HIST_STRIDE, "DEMOD_PERIOD": demod_period,
    }
    return build_program(context, "signals.cl", {**defines, **precision_defines(precision)})


class Runner:
    """The buffers and launches of one scene on one context."""

    def __init__(self, model: SignalModel, pe: PairEchoes, context, precision: str,
                 chunk: int | None, work_group: int | None, skip_quiet: bool = True):
        import pyopencl as cl

        #: chunks of samples no echo reaches are not synthesised where noise cannot be
        #: detected (noise_stays_quiet: noise-free, their signal, envelope and candidates
        #: are exactly 0); their histogram counts go to bin 0
        self.skip_quiet = skip_quiet and noise_stays_quiet(model)
        self.samples = {"scanned": 0, "skipped": 0}

        context_for(context, None, precision)  # checks the precision against the device
        self.cl, self.ctx, self.model, self.pe = cl, context, model, pe
        self.real = PRECISIONS[precision]
        self.queue = queue_of(context)
        self.program = _program(context, precision, model.box, model.span, model.demod_period)
        self.chunk = chunk
        self.work_group = work_group
        self.ek = read_only_buffer(context, pe.ek, np.int32)
        self.ef = read_only_buffer(context, pe.ef, self.real)
        self.ea = read_only_buffer(context, pe.ea, self.real, 2)
        table = np.zeros((len(pe.pairs), 4), dtype=np.int32)
        if len(pe.pairs):
            table[:, :2] = pe.pairs
            table[:, 2] = pe.lo
            table[:, 3] = pe.hi
        self.table = table
        vec = cl.cltypes.double4 if precision == "float64" else cl.cltypes.float4
        kc = np.zeros(1, dtype=vec)
        kc[0] = (model.noise_std, model.sigma, model.pulse_len, model.ratio)
        self.kc = kc[0]
        self.k0, self.k1 = (np.uint32(k) for k in model.key)
        period = max(model.demod_period, 1)
        k = np.arange(period)
        phase = 2.0 * math.pi * ((model.ratio * k) % 1.0)
        self.demod = read_only_buffer(context, np.stack([np.cos(phase), -np.sin(phase)], axis=-1),
                                      self.real)

    def chunk_for(self, mode: str) -> int:
        """Samples per work item: the runner's ``chunk``, else the device kind's default."""
        if self.chunk is not None:
            return max(1, int(self.chunk))
        return DEFAULT_CHUNK[("GPU" if device_kind(self.ctx.devices[0]) == "GPU" else "CPU", mode)]

    def launch(self, name: str, n_items: int, args: list) -> None:
        """Run kernel ``name`` over ``n_items`` work items (padded to whole work groups)."""
        kernel = kernel_of(self.program, name)
        group = self.work_group or fixed_work_group(kernel, self.ctx.devices[0], WORK_GROUP)
        padded = -(-n_items // group) * group
        kernel(self.queue, (padded,), (group,), *args)

    def quiet_histogram(self, items: np.ndarray, k: int, chunk: int,
                        n_chunks: int) -> np.ndarray:
        """[k] histogram counts of the chunks left out of each slot: every HIST_STRIDE-th
        m of [0, n_env) that no launched chunk covers."""
        n_env = self.model.n_env

        def strided(m0, m1):  # multiples of HIST_STRIDE in [m0, m1)
            return -(-m1 // HIST_STRIDE) - -(-m0 // HIST_STRIDE)

        m0 = items[:, 1].astype(np.int64) * chunk
        covered = np.bincount(items[:, 0], strided(m0, np.minimum(m0 + chunk, n_env)),
                              minlength=k)
        return (strided(0, n_env) - covered).astype(np.int32)

    def chunk_items(self, slots: np.ndarray, chunk: int, n_chunks: int) -> np.ndarray:
        """[i, 2] int32 (index into ``slots``, chunk) of the chunks whose samples an echo of
        the pair can reach: an echo at sample ek covers ek … ek + ⌈6σ⌉ + 1; a chunk reads
        from its start − (SPAN + 2·(BOX − 1) + 1) to its end + SPAN."""
        m, pe = self.model, self.pe
        lo, hi = pe.lo[slots], pe.hi[slots]
        n = hi - lo
        which = np.repeat(np.arange(len(slots)), n)
        echo = np.repeat(lo - np.cumsum(np.r_[0, n[:-1]]), n) + np.arange(int(n.sum()))
        start = pe.ek[echo]
        end = start + math.ceil(m.pulse_len) + 1
        lead, tail = m.span + 2 * (m.box - 1) + 1, m.span
        c0 = np.clip((start - tail) // chunk, 0, n_chunks - 1)
        c1 = np.clip((end + lead) // chunk, 0, n_chunks - 1)
        width = c1 - c0 + 1
        rows = np.repeat(which, width)
        cols = np.repeat(c0, width) + (np.arange(int(width.sum()))
                                       - np.repeat(np.cumsum(np.r_[0, width[:-1]]), width))
        items = unique(np.stack([rows, cols], axis=-1), axis=0)
        return np.ascontiguousarray(items, dtype=np.int32).reshape(-1, 2)

    def pair_buffer(self, slots: np.ndarray):
        """The rows (tx, rx, first echo, end of echoes) of pair ``slots`` on the device."""
        return read_only_buffer(self.ctx, self.table[slots], np.int32)

    def blocks(self, slots: np.ndarray, n_chunks: int, width: int) -> Iterator[np.ndarray]:
        """Split ``slots`` so each launch has at most ITEMS_PER_LAUNCH items and
        SLOTS_PER_LAUNCH output slots of ``width`` each, and lasts about
        :data:`LAUNCH_S` (:func:`launch_size`, timing the work done on each block before
        the next is asked for), telling :func:`clsonar.steps.step` the pairs done."""
        most = max(1, min(ITEMS_PER_LAUNCH // max(n_chunks, 1),
                          SLOTS_PER_LAUNCH // max(width, 1)))
        size, done = min(most, FIRST_LAUNCH_SLOTS), 0
        while done < len(slots):
            steps.step("pairs", done, len(slots))
            block = slots[done:done + size]
            start = time.perf_counter()
            yield block
            size = launch_size(size, time.perf_counter() - start, most)
            done += len(block)
        steps.step("pairs", len(slots), len(slots))

    def scan(self, slots: np.ndarray, capacity: int, floor: np.ndarray | None,
             histogram: bool) -> tuple[np.ndarray, Candidates, np.ndarray]:
        """Candidates of pair slots ``slots``, at most ``capacity`` per slot (the envelope's
        at least ``floor[slot]``), and if ``histogram`` each slot's envelope noise scale ŝ
        (:func:`~.dsp.noise_scale` of its histogram, taken block by block: 10⁶ pairs'
        histograms would be 1 GB); returns (candidates found per slot, candidates, ŝ)."""
        mode = self.model.mode
        chunk = self.chunk_for(mode)
        total = self.model.n_samples if mode == "threshold" else self.model.n_env
        n_chunks = -(-total // chunk)
        counts, found, scales = [], [], []
        for block in self.blocks(slots, n_chunks, capacity):
            count, cand, hist = self.scan_block(block, chunk, n_chunks, capacity, floor,
                                                histogram)
            counts.append(count)
            found.append(cand)
            if hist is not None:
                scales.append(noise_scale(hist))
        return (np.concatenate(counts) if counts else np.zeros(0, np.int32),
                join_candidates(mode, found),
                np.concatenate(scales) if scales else np.zeros(0))

    def scan_block(self, block: np.ndarray, chunk: int, n_chunks: int, capacity: int,
                   floor: np.ndarray | None, histogram: bool
                   ) -> tuple[np.ndarray, Candidates, np.ndarray | None]:
        """One launch of :meth:`scan` over the pair slots ``block``."""
        cl, m, k = self.cl, self.model, len(block)
        mf = cl.mem_flags
        count = np.zeros(k, dtype=np.int32)
        count_buf = cl.Buffer(self.ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=count)
        cand_n = np.empty((k, capacity), dtype=np.int32)
        cand_v = np.empty((k, capacity, 1 if m.mode == "threshold" else 4), dtype=self.real)
        n_buf = cl.Buffer(self.ctx, mf.WRITE_ONLY, cand_n.nbytes)
        v_buf = cl.Buffer(self.ctx, mf.WRITE_ONLY, cand_v.nbytes)
        common = [self.pair_buffer(block), np.int32(k), self.ek, self.ef, self.ea,
                  self.k0, self.k1, self.kc]
        items, n_items, order = self.launch_items(block, chunk, n_chunks)
        sizes = [np.int32(chunk), np.int32(n_chunks)]
        hist = hist_buf = None
        if m.mode == "threshold":
            if n_items:
                self.launch("threshold_scan", n_items, [
                    *common, self.real(m.threshold), np.int32(m.n_samples), *sizes,
                    np.int32(capacity), count_buf, n_buf, v_buf, *order])
        else:
            if floor is None:
                raise ValueError("the envelope scan needs a floor per pair slot")
            fl_buf = read_only_buffer(self.ctx, floor[block], self.real)
            if histogram:
                hist = np.zeros((k, HIST_BINS), dtype=np.int32)
                hist_buf = cl.Buffer(self.ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=hist)
            if n_items:
                self.launch("envelope_scan", n_items, [
                    *common, self.real(m.calibration**2), np.int32(m.n_env), *sizes, fl_buf,
                    np.int32(capacity), count_buf, n_buf, v_buf, hist_buf, self.demod, *order])
        for host, dev in ((count, count_buf), (cand_n, n_buf), (cand_v, v_buf)):
            cl.enqueue_copy(self.queue, host, dev)
        if hist is not None:
            cl.enqueue_copy(self.queue, hist, hist_buf)
            if items is not None:  # the chunks left out: every E² there is 0 (bin 0)
                hist[:, 0] += self.quiet_histogram(items, k, chunk, n_chunks)
        self.queue.finish()
        return count, self.found(block, count, cand_n, cand_v, capacity), hist

    def launch_items(self, block: np.ndarray, chunk: int, n_chunks: int
                     ) -> tuple[np.ndarray | None, int, list]:
        """The work items of a scan of ``block``: ``(items, count, kernel arguments)``, every
        (slot, chunk) pair (items None) or, skipping quiet chunks, :meth:`chunk_items`; the
        samples scanned and skipped are counted."""
        k = len(block)
        n_items, items, items_buf = k * n_chunks, None, None
        if self.skip_quiet:
            items = self.chunk_items(block, chunk, n_chunks)
            n_items = len(items)
            items_buf = read_only_buffer(self.ctx, items, np.int32, 2)
        self.samples["scanned"] += n_items * chunk
        self.samples["skipped"] += (k * n_chunks - n_items) * chunk
        return items, n_items, [items_buf, np.int32(n_items)]

    def found(self, block: np.ndarray, count: np.ndarray, cand_n: np.ndarray,
              cand_v: np.ndarray, capacity: int) -> Candidates:
        """The candidates the kernel stored for the slots ``block`` (at most ``capacity``
        of each slot's ``count``)."""
        filled = np.minimum(count, capacity)
        mask = np.arange(capacity)[None, :] < filled[:, None]
        rows = np.nonzero(mask)[0]
        v = cand_v[mask].astype(np.float64)
        return Candidates(block[rows], cand_n[mask].astype(np.int64),
                          v[:, 0] if self.model.mode == "threshold" else v[:, :3])


def _context(context, device):
    """``context``, or the one of ``device`` (:func:`clsonar.opencl.get_context`)."""
    return context if context is not None else get_context(device)


def scanned_slots(model: SignalModel, pe: PairEchoes) -> np.ndarray:
    """The pair slots whose signal must be scanned: all of them when the noise can be
    detected, else only those with an echo — a pair without one receives nothing (or noise
    no threshold reaches, :func:`~.detection.noise_stays_quiet`), so skipping it changes no
    detection."""
    slots = np.arange(len(pe.pairs), dtype=np.int64)
    return slots[pe.hi > pe.lo] if noise_stays_quiet(model) else slots


def detect(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *, context=None,
           device: str | None = None, precision: str = "float32",
           window_s: float | None = None, chunk: int | None = None,
           work_group: int | None = None, capacity: int | None = None,
           skip_silent: bool = True, skip_quiet: bool = True,
           stats: dict | None = None) -> Detections:
    """The detections of every fired pair, computed by the kernels of ``kernels/signals.cl``.

    ``context`` or ``device`` chooses the OpenCL device (:func:`clsonar.opencl.get_context`);
    ``precision="float64"`` needs ``cl_khr_fp64``. ``window_s`` overrides t_max; ``chunk``
    (samples per work item: each restarts the envelope's running sums, so it changes the
    result by float32 rounding only), ``work_group`` and ``capacity`` (first-pass candidates
    per pair) tune the launch; the last two never change the result; nor does
    ``skip_silent``, which leaves out
    the pairs without an echo (:func:`scanned_slots`), nor does ``skip_quiet``, which
    synthesises only the chunks of samples an echo reaches — both where noise cannot be
    detected (:func:`~.detection.noise_stays_quiet`: noise-free, or every threshold at
    least 10 noise scales up; then the rest of every signal holds no detection, but with a
    chance below 1e-12 per run). ``stats``, if given, receives ``pairs_scanned``,
    ``pairs_skipped_silent``, ``samples_scanned`` and ``samples_skipped_quiet``. Same model
    as :func:`detect_reference`.
    """
    model, pe = inputs(scene, sensors, echoes, window_s)
    steps.poll()
    slots = scanned_slots(model, pe) if skip_silent else np.arange(len(pe.pairs))
    samples = {"scanned": 0, "skipped": 0}
    found = empty_detections()
    if len(slots):
        run = Runner(model, pe, _context(context, device), precision, chunk, work_group,
                     skip_quiet)
        found = _detect(model, pe, run, capacity, slots)
        samples = run.samples
    if stats is not None:
        stats.update(pairs_scanned=len(slots), pairs_skipped_silent=len(pe.pairs) - len(slots),
                     samples_scanned=samples["scanned"],
                     samples_skipped_quiet=samples["skipped"])
    return found


#: The first pass keeps the local maxima of the envelope above this share of the threshold
#: the noise is expected to set (false_alarm_sigmas times its Rayleigh scale): about one a
#: pair of noise alone, where the envelope floor of an open scene (0.01 units) kept them
#: all and every noisy pair was scanned twice.
FIRST_PASS_SHARE = 0.7


def first_pass_floor(model: SignalModel) -> float:
    """The envelope floor of the detection's first pass: the scene's floor, or
    :data:`FIRST_PASS_SHARE` of the threshold the noise is expected to set where that is
    higher (the detections are the same: the final thresholds, from each pair's own
    noise, are higher still but for a chance, and a pair where one is not is scanned
    again with it)."""
    floor = envelope_floor(model)
    if model.receiver is not None:  # a fixed comparator: no noise estimate
        return floor
    return max(floor, FIRST_PASS_SHARE * model.false_alarm_sigmas * envelope_noise_scale(model))


def _detect(model: SignalModel, pe: PairEchoes, run: Runner, capacity: int | None,
            slots: np.ndarray) -> Detections:
    """:func:`detect` of the pair ``slots`` once the runner is built."""
    cap = int(capacity) if capacity is not None else DEFAULT_CAPACITY[model.mode]
    cap = max(1, cap)
    if model.mode == "threshold":
        counts, cand, _ = run.scan(slots, cap, None, histogram=False)
        over = counts > cap  # per scanned slot
        if over.any():
            _, extra, _ = run.scan(slots[over], int(counts[over].max()), None,
                                   histogram=False)
            cand = merge_candidates(cand, extra, slots[over])
        return finish_threshold(model, pe, cand)
    first = first_pass_floor(model)
    counts, cand, scales = run.scan(slots, cap, np.full(len(pe.pairs), first), histogram=True)
    thresholds = np.full(len(pe.pairs), np.inf)  # indexed by slot; unscanned slots: none
    thresholds[slots] = thresholds_of(model, scales)
    over = counts > cap  # scanned again: a pair with more candidates than room, or
    if first > envelope_floor(model):  # one whose threshold came out under a raised floor
        over |= thresholds[slots] * (1.0 - 1e-6) < first  # (a chance: see first_pass_floor)
    if over.any():
        # the same local maxima, now only those above the final threshold (a hair lower, so
        # float32 rounding of thr² cannot drop one the host keeps)
        floor2 = thresholds * (1.0 - 1e-6)
        # at least one place each: a pair may be scanned again with no candidate at all
        room = max(1, int(counts[over].max()))
        _, extra, _ = run.scan(slots[over], room, floor2, histogram=False)
        cand = merge_candidates(cand, extra, slots[over])
    return finish_envelope(model, pe, cand, thresholds)


def envelopes(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
              rate_hz: float = 1e5, context=None, device: str | None = None,
              precision: str = "float32", window_s: float | None = None,
              chunk: int | None = None) -> tuple[float, np.ndarray]:
    """``(dt, env)``: the calibrated envelope E of every fired pair (rows in the order of
    :func:`clsonar.sensors.pairs`) decimated to about ``rate_hz``, for back-projection.

    ``env[p, j]`` is E at echo time ``j·dt`` (the filter's delay and the pulse's 3σ removed, to
    the nearest sample), so an isolated echo of amplitude A arriving at τ peaks ≈ A at
    ``j ≈ τ/dt``; j covers [0, t_max]. Noise is included: the noise floor has Rayleigh
    statistics (mean ≈ 1.25·ŝ, see :func:`detect`). float32 (or float64) array [P, n].
    """
    model, pe = inputs(scene, sensors, echoes, window_s)
    dec, n_out = envelope_grid(model, rate_hz)
    dt = dec / model.fs
    if len(pe.pairs) == 0:
        return dt, np.zeros((0, n_out), dtype=PRECISIONS[precision])
    run = Runner(model, pe, _context(context, device), precision, chunk, None)
    cl = run.cl
    per_item = max(1, run.chunk_for("envelope") // dec)
    n_chunks = -(-n_out // per_item)
    off = envelope_offset(model)
    out = np.empty((len(pe.pairs), n_out), dtype=run.real)
    slots = np.arange(len(pe.pairs), dtype=np.int64)
    row = 0
    for block in run.blocks(slots, n_chunks, n_out):
        k = len(block)
        buf = cl.Buffer(run.ctx, cl.mem_flags.WRITE_ONLY, k * n_out * out.itemsize)
        run.launch("envelope_samples", k * n_chunks, [
            run.pair_buffer(block), np.int32(k), run.ek, run.ef, run.ea, run.k0, run.k1,
            run.kc, run.real(model.calibration**2), np.int32(per_item), np.int32(n_chunks),
            np.int32(dec), np.int32(off), np.int32(n_out), buf, run.demod])
        cl.enqueue_copy(run.queue, out[row:row + k], buf)
        run.queue.finish()
        row += k
    return dt, out


def kernel_a_scans(scene: Scene, sensors: SensorArray | None, echoes: EchoTable, *,
                   context=None, precision: str = "float32", window_s: float | None = None,
                   chunk: int = 4096, work_group: int | None = None) -> np.ndarray:
    """[P, n_samples] A-scans of every fired pair from the kernel (tests: chunking and
    work-group independence; small scenes only)."""
    model, pe = inputs(scene, sensors, echoes, window_s)
    run = Runner(model, pe, _context(context, None), precision, chunk, work_group)
    cl = run.cl
    n_chunks = -(-model.n_samples // chunk)
    out = np.empty((len(pe.pairs), model.n_samples), dtype=run.real)
    buf = cl.Buffer(run.ctx, cl.mem_flags.WRITE_ONLY, max(out.nbytes, 4))
    slots = np.arange(len(pe.pairs), dtype=np.int64)
    run.launch("a_scans", len(slots) * n_chunks, [
        run.pair_buffer(slots), np.int32(len(slots)), run.ek, run.ef, run.ea, run.k0,
        run.k1, run.kc, np.int32(model.n_samples), np.int32(chunk), np.int32(n_chunks), buf])
    cl.enqueue_copy(run.queue, out, buf)
    run.queue.finish()
    return out


def kernel_philox(context, seed: int, tx: int, rx: int, block0: int, count: int,
                  precision: str = "float32", work_group: int | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Raw Philox outputs [count, 4] uint32 and normals [count, 4] from the kernel (tests)."""
    import pyopencl as cl

    real = PRECISIONS[precision]
    program = _program(context, precision, 1, 1, 0)
    queue = queue_of(context)
    raw = np.empty((count, 4), dtype=np.uint32)
    normals = np.empty((count, 4), dtype=real)
    rb = cl.Buffer(context, cl.mem_flags.WRITE_ONLY, raw.nbytes)
    nb = cl.Buffer(context, cl.mem_flags.WRITE_ONLY, normals.nbytes)
    kernel = kernel_of(program, "philox_normals")
    group = work_group or fixed_work_group(kernel, context.devices[0], WORK_GROUP)
    padded = -(-count // group) * group
    key = (np.uint32(k) for k in philox_key(seed))
    kernel(queue, (padded,), (group,), *key, np.uint32(tx), np.uint32(rx),
           np.uint32(block0), np.int32(count), rb, nb)
    cl.enqueue_copy(queue, raw, rb)
    cl.enqueue_copy(queue, normals, nb)
    queue.finish()
    return raw, normals.astype(np.float64)
