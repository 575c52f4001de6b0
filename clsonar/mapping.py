"""The map: per-pixel accumulation of time-of-flight loci (thesis §2.1.1, parts 3–4).

Two implementations of one model, as for the echoes: :func:`accumulate` and
:func:`backproject` run the OpenCL kernels of ``kernels/accumulate.cl`` (float32 by default,
float64 where the device has ``cl_khr_fp64``); :func:`accumulate_reference` and
:func:`backproject_reference` evaluate the same expressions, in the same order, in NumPy
float64, so the float64 kernels reproduce them bit for bit.

**Loci** (``mapping.mode = "loci"``, the thesis). Each detected echo (T, R, τ) puts the
reflector on the locus ``|p − T| + |p − R| = c·τ``: for T = R the circle of radius c·τ/2
("a 24° arc is drawn from the centre of the transducer with a radius equal to half of the
round-trip distance"), for T ≠ R the ellipse with foci T and R ("the elliptical arc which falls
within the joint sensitivity region ... is drawn"). The map has one pixel per cell
(DESIGN.md: arrays ``[iy, ix]``, cell centres ``(xmin + (ix + ½)·cell, ymin + (iy + ½)·cell)``);
every pixel centre p gets, from every row, a vote iff

    | |p − T| + |p − R| − c·τ | ≤ band/2      (band = mapping.band_m, default √2·cell)

and p lies inside both beams: cosθ > 0 and sin²θ ≤ the hard cut
(:func:`clsonar.physics.beam_cut_sin2`) for the angles θ_T, θ_R between each transducer's
axis and the direction d to p: the echo engine's ``beam()`` test ``axis·d > 0`` and
``(axis×d)²/|d|² ≤ cut``, multiplied out as ``(axis×d)² ≤ cut·|d|²``. The vote is 1
(``weight = "unit"``, the thesis), the detected amplitude (``"amplitude"``) or
b(θ_T)·b(θ_R) (``"beam"``, the piston pattern of :func:`clsonar.physics.beam_pattern`).
Votes add up over rows in row order.

**Back-projection** (``mapping.mode = "backprojection"``): every pixel in a pair's joint beam
adds that pair's envelope at the pixel's delay ``(|p − T| + |p − R|)/c``, linearly
interpolated between samples taken every ``dt`` from 0 (0 past the last sample); with
``weight = "beam"`` times b(θ_T)·b(θ_R), otherwise unweighted.

Numerics: coordinates are taken relative to the centre of an *origin pixel* in the middle of
the map, in float64 on the host, so the kernels see pixel centres as exact integers times
the cell and distances of at most the map's half-diagonal; float32 then decides every pixel
as float64 does except those within a few float32 roundings of a band edge or a beam edge.

Performance: one work item computes 8 pixels of a row as one float8 vector on a CPU (PoCL
does not vectorise across work items a kernel with a loop), one pixel on a GPU; the loop over
loci is branch-free. :func:`accumulate` works on tiles (default): :func:`bin_loci` bounds
each locus' band on the host (the bounding box of its outer ellipse ∩ those of its two beam
sectors, then per tile the ring and beam tests widened by the tile's half-diagonal, coarse
tiles first) and lists per tile, in locus order, the loci that can vote there; the kernel
``loci_tiles`` runs one work-group per non-empty tile with its loci in local memory, and empty
tiles are never launched. The map is the dense one to the bit (same votes, same order). At
most :data:`MAX_LAUNCH_BYTES` of tiles are drawn per launch, so the device never holds the
whole map: a 100 m × 100 m floor at 1 cm (10⁸ cells) takes 0.4 GB of host memory in float32.
``tiles=False`` runs the dense kernel ``loci_map`` (loci in ``__constant`` memory in blocks of
at most :data:`MAX_ROWS_PER_LAUNCH`), every pixel against every locus.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from . import physics
from .errors import ClsonarError
from .opencl import PRECISIONS, context_for, device_kind, max_work_group
from .opencl import kernel as kernel_of
from .opencl import queue as queue_of
from .scene import MappingSettings, Scene
from .sensors import SensorArray

WEIGHTS = ("unit", "amplitude", "beam")

#: (pixels along x per work item, i.e. the ``realN`` vector width; work-group shape in work
#: items) by device kind and precision. A CPU gets one AVX2 register per work item (8 floats
#: or 4 doubles) and 64 pixels of a row per group; a GPU one pixel per work item.
LAUNCH = {
    ("CPU", "float32"): (8, (8, 1)),
    ("CPU", "float64"): (4, (16, 1)),
    ("GPU", "float32"): (1, (64, 2)),
    ("GPU", "float64"): (1, (64, 2)),
    ("other", "float32"): (1, (32, 1)),
    ("other", "float64"): (1, (32, 1)),
}

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

#: Loci the binning takes at once: as many as have about this many tiles in their bounding
#: boxes (bounds its temporary memory).
BIN_CANDIDATES = 1 << 22

#: The binning tests tiles of BIN_REFINE² times as many pixels first, from the coarsest
#: level of at most 8 × 8 such tiles down, and only the children of those kept.
BIN_REFINE = 4

#: Reals per locus row in the kernels: (T, R), (axis T, axis R), (c·τ, weight, 0, 0).
LOCUS_COLUMNS = 12
#: Reals per back-projection pair: (T, R), (axis T, axis R).
PAIR_COLUMNS = 8

#: Largest number of pixels along x or y: float32 represents pixel indices exactly below it.
MAX_CELLS_PER_AXIS = 1 << 24

#: float64 arrays of the map's size the NumPy reference holds at once (estimate).
REFERENCE_TEMPORARIES = 24


# --------------------------------------------------------------------------- inputs


@dataclass(frozen=True, eq=False)
class Loci:
    """What the map is built from: one row per detected echo (any object with these four
    arrays, e.g. the detector's table or :class:`clsonar.echoes.EchoTable`, will do)."""

    tx: np.ndarray  # int64 indices into the SensorArray
    rx: np.ndarray  # int64
    tof_s: np.ndarray  # float64 time of flight, s
    amplitude: np.ndarray  # float64

    def __len__(self) -> int:
        return len(self.tof_s)


def as_loci(rows) -> Loci:
    """``rows`` (anything with ``tx``, ``rx``, ``tof_s``, ``amplitude``) as a checked
    :class:`Loci`: 1-D arrays of one length, integer indices, finite times and amplitudes."""
    try:
        cols = [np.asarray(getattr(rows, k)) for k in ("tx", "rx", "tof_s", "amplitude")]
    except AttributeError as e:
        raise TypeError(f"loci need tx, rx, tof_s and amplitude arrays ({e})") from None
    if any(c.ndim != 1 for c in cols) or len({len(c) for c in cols}) != 1:
        raise ValueError("loci: tx, rx, tof_s and amplitude must be 1-D arrays of one length")
    tx, rx, tof, amp = cols
    for name, c in (("tx", tx), ("rx", rx)):
        if c.size and not np.issubdtype(c.dtype, np.integer):
            raise ValueError(f"loci.{name} must hold integer sensor indices")
    tof = tof.astype(np.float64)
    amp = amp.astype(np.float64)
    if not (np.all(np.isfinite(tof)) and np.all(np.isfinite(amp))):
        raise ValueError("loci: tof_s and amplitude must be finite")
    return Loci(tx.astype(np.int64), rx.astype(np.int64), tof, amp)


@dataclass(frozen=True)
class MapGrid:
    """The pixels a kernel computes and the local origin of their coordinates.

    Pixel ``(iy, ix)`` of the map has its centre at ``((col0 + ix)·cell, (row0 + iy)·cell)``
    relative to ``origin``, the centre of the map's pixel ``(-row0, -col0)``.
    """

    ny: int
    nx: int
    cell: float
    origin: tuple[float, float]
    col0: int
    row0: int



def merge_reciprocal(loci: Loci, tolerance_s: float) -> Loci:
    """One locus per physical path: (T, R) and (R, T) travel the same path, so a detection
    of each whose times of flight differ by at most ``tolerance_s`` become one row with
    T < R, their mean time of flight (√2 less noise) and mean amplitude. Unmatched rows and
    T = R rows stay as they are. Rows come back sorted by (tx, rx, tof)."""
    loci = as_loci(loci)
    groups: dict[tuple[int, int], list[int]] = {}
    for i, (t, r) in enumerate(zip(loci.tx.tolist(), loci.rx.tolist(), strict=True)):
        groups.setdefault((min(t, r), max(t, r)), []).append(i)
    tx, rx, tof, amp = [], [], [], []
    for (a, b), rows in groups.items():
        if a == b:
            forward, backward = rows, []
        else:
            forward = [i for i in rows if loci.tx[i] == a]
            backward = [i for i in rows if loci.tx[i] == b]
        used = set()
        for i in forward:
            match = min((j for j in backward if j not in used),
                        key=lambda j: abs(loci.tof_s[j] - loci.tof_s[i]), default=None)
            if match is not None and abs(loci.tof_s[match] - loci.tof_s[i]) <= tolerance_s:
                used.add(match)
                both = [i, match]
            else:
                both = [i]
            tx.append(a)
            rx.append(b if a != b else a)
            tof.append(float(np.mean(loci.tof_s[both])))
            amp.append(float(np.mean(loci.amplitude[both])))
        for j in backward:
            if j not in used:
                tx.append(a)
                rx.append(b)
                tof.append(float(loci.tof_s[j]))
                amp.append(float(loci.amplitude[j]))
    order = np.lexsort((tof, rx, tx))
    return Loci(np.asarray(tx, np.int64)[order], np.asarray(rx, np.int64)[order],
                np.asarray(tof, np.float64)[order], np.asarray(amp, np.float64)[order])

def map_grid(scene: Scene) -> MapGrid:
    """The scene's map (``scene.grid_shape`` cells of ``scene.cell``) around its middle pixel."""
    ny, nx = scene.grid_shape
    xmin, ymin = scene.extent[0], scene.extent[1]
    ox, oy = nx // 2, ny // 2
    origin = (xmin + (ox + 0.5) * scene.cell, ymin + (oy + 0.5) * scene.cell)
    return MapGrid(ny, nx, float(scene.cell), origin, -ox, -oy)


def cell_centres(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """``(x [nx], y [ny])``: the map's cell centres in scene coordinates (DESIGN.md)."""
    ny, nx = scene.grid_shape
    xmin, ymin = scene.extent[0], scene.extent[1]
    return (xmin + (np.arange(nx) + 0.5) * scene.cell,
            ymin + (np.arange(ny) + 0.5) * scene.cell)


def band_m(scene: Scene, settings: MappingSettings | None = None) -> float:
    """Width of a locus in path length: ``settings.band_m``, or 2√2·cell when it is null.

    |p−T| + |p−R| changes at most twice as fast as the distance across the locus (exactly
    twice for T = R), so 2√2·cell of path length make every locus at least √2 cells thick
    on the map: one 8-connected band, never a dotted one."""
    settings = settings if settings is not None else scene.mapping
    return settings.band_m if settings.band_m is not None else 2.0 * math.sqrt(2.0) * scene.cell


@dataclass(frozen=True, eq=False)
class MapProblem:
    """Inputs of both implementations: float64 rows relative to ``grid.origin``."""

    grid: MapGrid
    rows: np.ndarray  # [n, LOCUS_COLUMNS] loci, or [n, PAIR_COLUMNS] back-projection pairs
    weight: str
    half_band: float  # band/2 (loci)
    cut_sin2: float
    beam_u: float  # (ka/j1)²: u = beam_u·sin²θ in the beam series
    envelopes: np.ndarray | None = None  # [n, samples] (back-projection)
    inv_c_dt: float = 0.0  # 1/(c·dt) (back-projection)


def _beam_constants(scene: Scene) -> tuple[float, float]:
    cut, ka = scene.transducer.beam(scene.medium.c)
    return cut, (ka / physics.J1_FIRST_ZERO) ** 2


def _settings(scene: Scene, settings: MappingSettings | None) -> MappingSettings:
    settings = settings if settings is not None else scene.mapping
    if settings.weight not in WEIGHTS:
        raise ValueError(f"mapping weight must be one of {', '.join(WEIGHTS)}, "
                         f"not {settings.weight!r}")
    return settings


def _geometry_rows(sensors: SensorArray, tx: np.ndarray, rx: np.ndarray,
                   grid: MapGrid) -> np.ndarray:
    """[n, 8]: T and R relative to the grid's origin, then their unit axes."""
    n = len(sensors)
    for name, idx in (("tx", tx), ("rx", rx)):
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise ValueError(f"{name} holds sensor indices outside 0..{n - 1}")
    pos = np.asarray(sensors.positions, dtype=np.float64).reshape(-1, 2) - np.asarray(grid.origin)
    axes = np.asarray(sensors.axes, dtype=np.float64).reshape(-1, 2)
    return np.concatenate([pos[tx], pos[rx], axes[tx], axes[rx]], axis=1)


def prepare_loci(scene: Scene, sensors: SensorArray, loci,
                 settings: MappingSettings | None = None) -> MapProblem:
    """The :class:`MapProblem` of drawing ``loci`` on the scene's map."""
    settings = _settings(scene, settings)
    grid = map_grid(scene)
    rows = as_loci(loci)
    band = band_m(scene, settings)
    if not (math.isfinite(band) and band > 0):
        raise ValueError(f"mapping band must be > 0, not {band!r}")
    table = np.zeros((len(rows), LOCUS_COLUMNS))
    table[:, :8] = _geometry_rows(sensors, rows.tx, rows.rx, grid)
    table[:, 8] = scene.medium.c * rows.tof_s
    table[:, 9] = rows.amplitude if settings.weight == "amplitude" else 1.0
    cut, beam_u = _beam_constants(scene)
    return MapProblem(grid, table, settings.weight, 0.5 * band, cut, beam_u)


def prepare_backprojection(scene: Scene, sensors: SensorArray, pairs, envelopes, dt: float,
                           settings: MappingSettings | None = None) -> MapProblem:
    """The :class:`MapProblem` of back-projecting ``envelopes`` [P, n] of ``pairs`` [P, 2]."""
    settings = _settings(scene, settings)
    grid = map_grid(scene)
    pr = np.asarray(pairs)
    env = np.asarray(envelopes, dtype=np.float64)
    if pr.ndim != 2 or pr.shape[1] != 2 or (pr.size and not np.issubdtype(pr.dtype, np.integer)):
        raise ValueError("pairs must be a [P, 2] array of integer (tx, rx) sensor indices")
    if env.ndim != 2 or env.shape[0] != len(pr):
        raise ValueError(f"envelopes must be [P, n] with P = {len(pr)} rows, one per pair")
    if len(pr) and env.shape[1] < 2:
        raise ValueError("envelopes need at least 2 samples")
    if not np.all(np.isfinite(env)):
        raise ValueError("envelopes must be finite")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, not {dt!r}")
    rows = _geometry_rows(sensors, pr[:, 0].astype(np.int64), pr[:, 1].astype(np.int64), grid)
    cut, beam_u = _beam_constants(scene)
    return MapProblem(grid, rows, settings.weight, 0.0, cut, beam_u, env,
                      1.0 / (scene.medium.c * dt))


# --------------------------------------------------------------------------- memory


def _bytes(n: float) -> str:
    for unit, size in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def _host_available_bytes() -> int | None:
    """Memory this machine can still give (MemAvailable), None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _items(nx: int, ny: int, vec: int, wgx: int, wgy: int) -> tuple[int, int]:
    """Work items along x and y covering nx × ny pixels, in whole work-groups."""
    def ceil_div(a: int, b: int) -> int:
        return -(-a // b)

    return ceil_div(ceil_div(nx, vec), wgx) * wgx, ceil_div(ny, wgy) * wgy


def _grid_error(scene: Scene, problem: str) -> ClsonarError:
    ny, nx = scene.grid_shape
    xmin, ymin, xmax, ymax = scene.extent
    return ClsonarError(
        f"{scene.name}: the map of {ny} × {nx} cells (extent {xmax - xmin:g} m × "
        f"{ymax - ymin:g} m, cell {scene.cell:g} m) {problem}: use a larger cell or a "
        "smaller extent")


def check_map_memory(scene: Scene, precision: str = "float32", device=None, *,
                     reference: bool = False, host_bytes_per_cell: float | None = None) -> None:
    """Raise :class:`~clsonar.errors.ClsonarError` naming the size needed when the scene's
    map cannot be held: by ``device`` (a ``pyopencl.Device``: one buffer of the padded map),
    by this machine's free memory (the result, plus the reference's temporaries when
    ``reference``, or ``host_bytes_per_cell`` for a caller that holds several maps), or by
    float32 pixel indices (at most :data:`MAX_CELLS_PER_AXIS` a side).
    """
    ny, nx = scene.grid_shape
    if max(ny, nx) > MAX_CELLS_PER_AXIS:
        side = "x" if nx >= ny else "y"
        raise _grid_error(scene, f"has more than the {MAX_CELLS_PER_AXIS} cells along {side} "
                                 "that the kernels index exactly")
    itemsize = np.dtype(PRECISIONS[precision]).itemsize
    if device is not None:
        vec, group = LAUNCH[device_kind(device), precision]
        items_x, items_y = _items(nx, ny, vec, *group)
        padded = float(items_x * vec) * items_y * itemsize
        limit = min(int(device.max_mem_alloc_size), int(device.global_mem_size))
        if padded > limit:
            raise _grid_error(scene, f"needs {_bytes(padded)} as a {precision} map, more than "
                                     f"one buffer on {device.name.strip()} can hold "
                                     f"({_bytes(limit)})")
    if host_bytes_per_cell is not None:
        needed = float(ny) * nx * host_bytes_per_cell
    elif reference:
        needed = float(ny) * nx * 8 * REFERENCE_TEMPORARIES
    else:
        needed = float(ny) * nx * itemsize * 3  # padded transfer copy, result, its caller
    available = _host_available_bytes()
    if available is not None and needed > available:
        raise _grid_error(scene, f"needs {_bytes(needed)} of memory, more than this machine "
                                 f"has available ({_bytes(available)})")


# --------------------------------------------------------------------------- NumPy reference


def _ref_beam(sin2: np.ndarray, beam_u: float) -> np.ndarray:
    """b(θ) from sin²θ: the kernels' beam series by Horner's rule (common.h ``beam()``)."""
    coeffs = physics.beam_series_coefficients(14)
    u = beam_u * sin2
    acc = np.zeros_like(u)
    for c in coeffs[::-1]:
        acc = acc * u + c
    return (1.0 - u) * acc


def _ref_view(pb: MapProblem, row: np.ndarray) -> dict[str, np.ndarray]:
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
    return (_ref_beam((v["s_t"] * v["s_t"]) / v["dd_t"], pb.beam_u)
            * _ref_beam((v["s_r"] * v["s_r"]) / v["dd_r"], pb.beam_u))


def _reference_loci(pb: MapProblem) -> np.ndarray:
    acc = np.zeros((pb.grid.ny, pb.grid.nx))
    with np.errstate(divide="ignore", invalid="ignore"):
        for row in pb.rows:
            v = _ref_view(pb, row)
            vote = (np.abs(v["path"] - row[8]) <= pb.half_band) & v["inside"]
            w = _ref_joint_beam(pb, v) if pb.weight == "beam" else row[9]
            acc += np.where(vote, w, 0.0)
    return acc


def _reference_backprojection(pb: MapProblem) -> np.ndarray:
    acc = np.zeros((pb.grid.ny, pb.grid.nx))
    env = pb.envelopes
    last = float(env.shape[1] - 1) if env is not None and env.ndim == 2 else 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        for i, row in enumerate(pb.rows):
            v = _ref_view(pb, row)
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


def backproject_reference(scene: Scene, sensors: SensorArray, pairs, envelopes, dt: float, *,
                          settings: MappingSettings | None = None) -> np.ndarray:
    """The back-projected map in NumPy float64 ([ny, nx]): the reference of
    :func:`backproject`."""
    check_map_memory(scene, "float64", reference=True)
    return _reference_backprojection(
        prepare_backprojection(scene, sensors, pairs, envelopes, dt, settings))


# --------------------------------------------------------------------------- tiles

#: float32 roundings (of the coordinates' scale) added to every bound of the binning, so
#: that a pixel the float32 kernel decides to vote for is never left out by it.
BIN_ROUNDINGS = 256


@dataclass(frozen=True, eq=False)
class TileBins:
    """Loci binned to the tiles of a map, as CSR: tile ``k`` (row-major over ``shape``
    = (tiles along y, along x); tile (ty, tx) holds pixels ``[ty·th, ty·th + th)`` ×
    ``[tx·tw, tx·tw + tw)``) may get votes only from loci ``members[start[k]:start[k + 1]]``,
    in ascending order (the order the dense kernel adds them)."""

    shape: tuple[int, int]
    tile: tuple[int, int]  # (tw, th) pixels along x, along y
    start: np.ndarray  # [tiles + 1] int64
    members: np.ndarray  # [m] int64

    @property
    def counts(self) -> np.ndarray:
        """[tiles] loci per tile."""
        return np.diff(self.start)


def _sector_boxes(apex: np.ndarray, axis: np.ndarray, alpha: float,
                  radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding boxes ``(lo [n, 2], hi [n, 2])`` of the circular sectors with ``apex``,
    unit ``axis``, half-angle ``alpha`` (≤ π) and ``radius``: the apex, the two edge ends
    and the ends of the ±x, ±y radii that lie within the sector."""
    phi = np.arctan2(axis[:, 1], axis[:, 0])
    angles = [phi - alpha, phi + alpha]
    points = [apex] + [apex + radius[:, None] * np.stack([np.cos(a), np.sin(a)], axis=1)
                       for a in angles]
    for k, direction in enumerate(((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))):
        off = np.angle(np.exp(1j * (k * math.pi / 2 - phi)))  # wrapped to (−π, π]
        end = apex + radius[:, None] * np.asarray(direction)
        points.append(np.where((np.abs(off) <= alpha)[:, None], end, apex))
    stack = np.stack(points)
    return stack.min(axis=0), stack.max(axis=0)


def _beam_may_hold(centre: np.ndarray, apex: np.ndarray, axis: np.ndarray, alpha: float,
                   radius: np.ndarray) -> np.ndarray:
    """Whether a disc (``centre``, ``radius``) may hold points of the beam (a cone of
    half-angle ``alpha`` ≤ π/2 about ``axis`` from ``apex``): the disc holds the apex, or the
    angle θ to its centre is at most alpha plus its angular radius s = asin(radius/d), i.e.
    cos θ ≥ cos(alpha + s) = cos alpha·sqrt(d² − radius²)/d − sin alpha·radius/d."""
    d = centre - apex
    dist2 = d[:, 0] ** 2 + d[:, 1] ** 2
    along = axis[:, 0] * d[:, 0] + axis[:, 1] * d[:, 1]
    return ((dist2 <= radius * radius)
            | (along >= math.cos(alpha) * np.sqrt(np.maximum(dist2 - radius * radius, 0.0))
               - math.sin(alpha) * radius))


def bin_loci(pb: MapProblem, tile: tuple[int, int]) -> TileBins:
    """Bin ``pb``'s loci to the map's tiles of ``tile`` = (tw, th) pixels, conservatively:
    a tile lists every locus that may vote for one of its pixels (thesis §2.1.1 part 4: the
    band ``| |p−T| + |p−R| − c·τ | ≤ band/2`` inside both beams).

    Per locus, the candidate tiles are those meeting the bounding box of its band (the
    outer ellipse, path c·τ + band/2) intersected with the bounding boxes of the two beams
    (sectors of half-angle α out to the farthest point of that ellipse) and with the map.
    A candidate tile, whose pixel centres lie within h (its half-diagonal) of its centre c,
    keeps the locus iff ``| |c−T| + |c−R| − c·τ | ≤ band/2 + 2h`` (each distance changes by
    at most h across the tile) and c's direction from each transducer is within α plus
    asin(h/|c−T|) of its axis. Every bound is widened by half a cell and
    :data:`BIN_ROUNDINGS` float32 roundings of the coordinates' scale, so the float32
    kernel's decisions near an edge are covered too.
    """
    g = pb.grid
    tw, th = tile
    ntx, nty = -(-g.nx // tw), -(-g.ny // th)
    n_tiles = ntx * nty
    rows = pb.rows
    pairs_tile: list[np.ndarray] = []
    pairs_locus: list[np.ndarray] = []
    if len(rows):
        cell = g.cell
        T, R, aT, aR, L = rows[:, 0:2], rows[:, 2:4], rows[:, 4:6], rows[:, 6:8], rows[:, 8]
        corner = np.abs(np.array([[g.col0, g.row0], [g.col0 + g.nx - 1, g.row0 + g.ny - 1]],
                                 dtype=np.float64) * cell).max(axis=0)
        scale = (math.hypot(*corner) + np.hypot(T[:, 0], T[:, 1]) + np.hypot(R[:, 0], R[:, 1])
                 + np.abs(L))
        pad = 0.5 * cell + BIN_ROUNDINGS * float(np.finfo(np.float32).eps) * scale
        hb = pb.half_band
        alpha = math.asin(math.sqrt(min(max(pb.cut_sin2, 0.0), 1.0)))
        # bounding box of the outer ellipse |p−T| + |p−R| = 2a (foci 2f apart)
        a = 0.5 * (L + hb) + pad
        f = 0.5 * np.hypot(*(R - T).T)
        b = np.sqrt(np.maximum(a * a - f * f, 0.0))
        u = np.where((f > 0)[:, None], (R - T) / np.maximum(2.0 * f, 1e-300)[:, None],
                     np.array([1.0, 0.0]))
        half = np.stack([np.hypot(a * u[:, 0], b * u[:, 1]), np.hypot(a * u[:, 1], b * u[:, 0])],
                        axis=1)
        lo, hi = 0.5 * (T + R) - half, 0.5 * (T + R) + half
        for apex, axis in ((T, aT), (R, aR)):  # ∩ each beam out to the ellipse's reach a + f
            s_lo, s_hi = _sector_boxes(apex, axis, alpha, a + f)
            lo, hi = np.maximum(lo, s_lo - pad[:, None]), np.minimum(hi, s_hi + pad[:, None])
        origin = np.array([g.col0, g.row0], dtype=np.float64)
        size = np.array([g.nx, g.ny])
        first = np.clip(np.ceil(lo / cell - origin), -1, size)  # pixel index ranges
        last = np.clip(np.floor(hi / cell - origin), -1, size)
        reach = (a >= f)[:, None] & (first <= last) & (last >= 0) & (first <= size - 1)
        reach = reach.all(axis=1)
        levels = 0  # coarse levels of BIN_REFINE² tiles each, down to ≤ 8 × 8 tiles
        while -(-max(ntx, nty) // BIN_REFINE ** levels) > 8:
            levels += 1

        def tiles_of(level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            """Per locus, its first and last tile (x, y) at ``level``, and whether any."""
            step = np.array([tw, th]) * BIN_REFINE ** level
            t_first = (np.clip(first, 0, size - 1) // step).astype(np.int64)
            t_last = (np.clip(last, 0, size - 1) // step).astype(np.int64)
            return t_first, t_last, reach

        def may_vote(li, tx, ty, level: int) -> np.ndarray:
            """Indices of the (locus, tile) candidates that pass the ring and beam tests."""
            w, hh = tw * BIN_REFINE ** level, th * BIN_REFINE ** level
            centre = np.stack([(g.col0 + tx * w + 0.5 * (w - 1)) * cell,
                               (g.row0 + ty * hh + 0.5 * (hh - 1)) * cell], axis=1)
            radius = 0.5 * cell * math.hypot(w - 1, hh - 1) + pad[li]
            path = np.hypot(*(centre - T[li]).T) + np.hypot(*(centre - R[li]).T)
            keep = np.flatnonzero(np.abs(path - L[li]) <= hb + 2.0 * radius)
            for apex, axis in ((T, aT), (R, aR)):
                j = li[keep]
                keep = keep[_beam_may_hold(centre[keep], apex[j], axis[j], alpha, radius[keep])]
            return keep

        bounds = [tiles_of(level) for level in range(levels + 1)]
        span0 = np.where(reach[:, None], bounds[0][1] - bounds[0][0] + 1, 0)
        ends = np.cumsum(span0[:, 0] * span0[:, 1])  # fine candidates: bounds each chunk
        top_first, top_last, _ = bounds[levels]
        top_span = np.where(reach[:, None], top_last - top_first + 1, 0)
        i0 = 0
        while i0 < len(rows):  # loci in chunks of about BIN_CANDIDATES fine candidates
            base = ends[i0 - 1] if i0 else 0
            i1 = max(i0 + 1, int(np.searchsorted(ends, base + BIN_CANDIDATES, side="right")))
            i1 = min(i1, len(rows))
            cnt = top_span[i0:i1, 0] * top_span[i0:i1, 1]
            li = np.repeat(np.arange(i0, i1), cnt)
            k = np.arange(len(li)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            tx = top_first[li, 0] + k % top_span[li, 0]
            ty = top_first[li, 1] + k // top_span[li, 0]
            for level in range(levels, -1, -1):
                if level < levels:  # the children of the tiles kept a level up, in bounds
                    sub = np.arange(BIN_REFINE)
                    shape = (len(li), BIN_REFINE, BIN_REFINE)
                    tx = np.broadcast_to(tx[:, None, None] * BIN_REFINE + sub, shape).ravel()
                    ty = np.broadcast_to(ty[:, None, None] * BIN_REFINE + sub[:, None],
                                         shape).ravel()
                    li = np.repeat(li, BIN_REFINE * BIN_REFINE)
                    lo_t, hi_t, _ = bounds[level]
                    inside = ((tx >= lo_t[li, 0]) & (tx <= hi_t[li, 0])
                              & (ty >= lo_t[li, 1]) & (ty <= hi_t[li, 1]))
                    li, tx, ty = li[inside], tx[inside], ty[inside]
                keep = may_vote(li, tx, ty, level)
                li, tx, ty = li[keep], tx[keep], ty[keep]
            pairs_tile.append(ty * ntx + tx)
            pairs_locus.append(li)
            i0 = i1
    tile_of = np.concatenate(pairs_tile) if pairs_tile else np.zeros(0, np.int64)
    locus = np.concatenate(pairs_locus) if pairs_locus else np.zeros(0, np.int64)
    order = np.argsort(tile_of, kind="stable")  # loci ascending within each tile
    start = np.zeros(n_tiles + 1, dtype=np.int64)
    np.cumsum(np.bincount(tile_of, minlength=n_tiles), out=start[1:])
    return TileBins((nty, ntx), (tw, th), start, locus[order].astype(np.int64))


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


# --------------------------------------------------------------------------- OpenCL


def _program(context, precision: str, weight_beam: bool, vec: int):
    """``kernels/accumulate.cl`` for ``precision``, the beam weight or not, and ``vec``
    pixels per work item (memoised by :func:`clsonar.opencl.build_program`)."""
    from .opencl import beam_series_defines, build_program, precision_defines

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


def _run(ctx, pb: MapProblem, precision: str, name: str) -> np.ndarray:
    """Launch kernel ``name`` over the whole map, rows in blocks; return the [ny, nx] map."""
    import pyopencl as cl

    device = ctx.devices[0]
    vec, (wgx, wgy) = LAUNCH[device_kind(device), precision]
    real = PRECISIONS[precision]
    itemsize = np.dtype(real).itemsize
    g = pb.grid
    if len(pb.rows) == 0:
        return np.zeros((g.ny, g.nx), dtype=real)
    program = _program(ctx, precision, pb.weight == "beam", vec)
    kernel = kernel_of(program, name)
    limit = max_work_group(kernel, device)
    while wgx * wgy > limit and wgx * wgy > 1:
        wgx, wgy = (wgx, wgy // 2) if wgy > 1 else (wgx // 2, wgy)
    items_x, items_y = _items(g.nx, g.ny, vec, wgx, wgy)
    pitch = items_x * vec
    queue = queue_of(ctx)
    mf = cl.mem_flags
    out = cl.Buffer(ctx, mf.READ_WRITE, pitch * items_y * itemsize)
    block = _rows_per_launch(device, pb.rows.shape[1], itemsize)
    if pb.envelopes is not None:
        env_bytes = pb.envelopes.shape[1] * itemsize
        block = max(1, min(block, int(device.max_mem_alloc_size) // 2 // env_bytes))
    cell = real(g.cell)
    beam = (real(pb.cut_sin2), real(pb.beam_u))
    where = (np.int32(g.col0), np.int32(g.row0))
    for first in range(0, len(pb.rows), block):
        rows = np.ascontiguousarray(pb.rows[first:first + block], dtype=real)
        n = np.int32(len(rows))
        rows_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=rows)
        tail = (*where, np.int32(first == 0), out, np.int64(0), np.int32(pitch))
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
    items_x, items_y = _items(pb.grid.nx, pb.grid.ny, vec, wgx, wgy)
    tests = items_x * vec * items_y * len(pb.rows)
    block = _rows_per_launch(device, LOCUS_COLUMNS, np.dtype(PRECISIONS[precision]).itemsize)
    return AccumulationStats(False, None, 0, 0, tests, tests, -(-len(pb.rows) // block))


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


def _run_tiles(ctx, pb: MapProblem, precision: str) -> tuple[np.ndarray, AccumulationStats]:
    """Draw the loci map tile by tile (kernel ``loci_tiles``, one work-group per tile that
    :func:`bin_loci` lists any locus for), at most :data:`MAX_LAUNCH_BYTES` of tiles (and the
    device's largest buffer) per launch, each launch's tiles copied into the host map."""
    import pyopencl as cl

    device = ctx.devices[0]
    vec, _ = LAUNCH[device_kind(device), precision]
    real = PRECISIONS[precision]
    itemsize = np.dtype(real).itemsize
    g = pb.grid
    kernel = kernel_of(_program(ctx, precision, pb.weight == "beam", vec), "loci_tiles")
    tw, th = _tile_shape(kernel, device, vec)
    bins = bin_loci(pb, (tw, th))
    nty, ntx = bins.shape
    counts = bins.counts
    live = np.flatnonzero(counts)
    limit = min(MAX_LAUNCH_BYTES, int(device.max_mem_alloc_size), int(device.global_mem_size) // 2)
    launches = _launches(bins.start, live, max(1, limit // (tw * th * itemsize)))
    result = np.zeros((g.ny, g.nx), dtype=real)
    stats = AccumulationStats(True, (tw, th), ntx * nty, ntx * nty - len(live),
                              int(counts.sum()) * tw * th,
                              _dense_stats(ctx, pb, precision).dense_tests, len(launches))
    if len(live) == 0:
        return result, stats
    queue = queue_of(ctx)
    mf = cl.mem_flags
    rows_buf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR,
                         hostbuf=np.ascontiguousarray(pb.rows, dtype=real))
    size = max(map(len, launches))
    out = cl.Buffer(ctx, mf.WRITE_ONLY, size * th * tw * itemsize)
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
    return result, stats


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
    (:class:`Loci`, the detector's table, an echo table); ``sensors`` the
    :class:`~clsonar.sensors.SensorArray` they index. ``settings`` (default
    ``scene.mapping``) gives ``weight``, ``band_m`` and ``precision`` (overridden by
    ``precision``); its ``mode`` is the caller's business: this draws loci. float32 maps come
    back as float32, float64 (needs ``cl_khr_fp64``) as float64. A map that cannot fit in
    the device's or this machine's memory raises :class:`~clsonar.errors.ClsonarError`.
    Same model as :func:`accumulate_reference`. :func:`accumulate_with_stats` also returns
    the counters (tiles skipped, tests made).
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
    :func:`accumulate`; same model as :func:`backproject_reference`.
    """
    settings = settings if settings is not None else scene.mapping
    precision = precision or settings.precision
    ctx = context_for(context, device, precision)
    check_map_memory(scene, precision, ctx.devices[0])
    pb = prepare_backprojection(scene, sensors, pairs, envelopes, dt, settings)
    return _run(ctx, pb, precision, "backproject_map")


__all__ = ["AccumulationStats", "Loci", "MapGrid", "MapProblem", "TileBins", "accumulate",
           "accumulate_reference", "accumulate_with_stats", "as_loci", "backproject",
           "backproject_reference", "band_m", "bin_loci", "cell_centres",
           "check_map_memory", "map_grid", "prepare_backprojection", "prepare_loci"]


def _subset(loci: Loci, keep: np.ndarray) -> Loci:
    return Loci(loci.tx[keep], loci.rx[keep], loci.tof_s[keep], loci.amplitude[keep])


def count_viewpoints(scene: Scene, sensors: SensorArray, loci,
                     draw: Callable[[Loci], np.ndarray]) -> np.ndarray:
    """How many *viewpoints* have a locus through each cell ([ny, nx] float32).

    A viewpoint is a pair group (one linear array, one ring pose). Its loci are nearly
    concentric — transducers a few centimetres apart looking at a surface metres away — so
    they agree along their whole arcs, not only at the surface; loci from two viewpoints
    cross where the surface is. ``draw`` maps one viewpoint's loci (:func:`accumulate` or
    :func:`accumulate_reference` with the scene's settings).
    """
    loci = as_loci(loci)
    groups = sensors.groups[loci.tx]
    total = np.zeros(scene.grid_shape, dtype=np.float32)
    for g in np.unique(groups):
        total += draw(_subset(loci, groups == g)) > 0
    return total


# --------------------------------------------------------------------------- tangent points

#: Most radial error a pair of loci may contribute: two circles of radius r tangent to a
#: plane at feet δ apart cross δ²/(8r) in front of it, so pairs need δ ≤ sqrt(8·r·bias).
TANGENT_BIAS_M = 0.002

#: Samples of each locus (an ellipse with foci T and R) searched for crossings: 0.25°.
LOCUS_SAMPLES = 1440


def _locus_samples(scene: Scene, sensors: SensorArray, loci: Loci):
    """[n, S, 2] points of each locus (ellipse with foci T, R and path length c·τ) and
    [n, S] whether each lies inside both beams; [n] the half path length a.

    Only the samples near T's beam are computed (the others are left 0 and outside): with T
    a focus, the ray from T at angle ν from the major axis meets the ellipse once, at
    eccentric anomaly E = 2·atan2(√(1+e)·sin(ν/2), √(1−e)·cos(ν/2)) (e = f/a), so T's beam
    (ν within ±α of its axis) is one arc of samples; two samples more either side are
    tested as well, and each sample is then tested exactly as before."""
    pos, axes = sensors.positions, sensors.axes
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    T, R = pos[loci.tx], pos[loci.rx]
    a = 0.5 * scene.medium.c * loci.tof_s
    f = 0.5 * np.hypot(*(R - T).T)
    b = np.sqrt(np.maximum(a * a - f * f, 0.0))
    u = np.where((f > 0)[:, None], (R - T) / np.maximum(2 * f, 1e-300)[:, None], [1.0, 0.0])
    v = np.stack([-u[:, 1], u[:, 0]], axis=-1)
    phi = 2 * np.pi * np.arange(LOCUS_SAMPLES) / LOCUS_SAMPLES
    centre = 0.5 * (T + R)
    rows, ks = _beam_arc_samples(u, v, axes[loci.tx], a, f, cut_sin2)
    p = np.zeros((len(a), LOCUS_SAMPLES, 2))
    p[rows, ks] = (centre[rows] + (a[rows] * np.cos(phi[ks]))[:, None] * u[rows]
                   + (b[rows] * np.sin(phi[ks]))[:, None] * v[rows])
    inside = np.zeros((len(a), LOCUS_SAMPLES), dtype=bool)
    inside[rows, ks] = _in_beams(p[rows, ks], T[rows], axes[loci.tx][rows], cut_sin2)
    inside &= (a > f)[:, None]
    i, k = np.nonzero(inside)  # R's beam tested only where T's holds (a small part)
    inside[i, k] = _in_beams(p[i, k], R[i], axes[loci.rx][i], cut_sin2)
    return p, inside, a


#: Samples tested beyond each end of the computed arc of T's beam (rounding margin).
_ARC_MARGIN = 2


def _beam_arc_samples(u: np.ndarray, v: np.ndarray, axis: np.ndarray, a: np.ndarray,
                      f: np.ndarray, cut_sin2: float) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, samples)``: for each locus (a > f), the sample indices of its arc inside
    the beam of its focus T (axis ``axis``), with :data:`_ARC_MARGIN` more either side."""
    alpha = math.asin(math.sqrt(min(cut_sin2, 1.0)))
    ok = a > f
    e = np.where(ok, f / np.where(ok, a, 1.0), 0.0)
    beta = np.arctan2(np.sum(v * axis, -1), np.sum(u * axis, -1))  # axis angle from u
    step = 2 * np.pi / LOCUS_SAMPLES

    def anomaly(nu: np.ndarray) -> np.ndarray:
        nu = np.angle(np.exp(1j * nu))  # into (−π, π]
        return 2 * np.arctan2(np.sqrt(1 + e) * np.sin(nu / 2), np.sqrt(1 - e) * np.cos(nu / 2))

    lo, hi = anomaly(beta - alpha), anomaly(beta + alpha)
    hi = np.where(hi < lo, hi + 2 * np.pi, hi)
    k0 = np.floor(lo / step).astype(np.int64) - _ARC_MARGIN
    k1 = np.ceil(hi / step).astype(np.int64) + _ARC_MARGIN
    width = np.where(ok, np.minimum(k1 - k0 + 1, LOCUS_SAMPLES), 0)
    rows = np.repeat(np.arange(len(a)), width)
    first = np.repeat(np.cumsum(np.r_[0, width[:-1]]), width)
    ks = (np.repeat(k0, width) + np.arange(int(width.sum())) - first) % LOCUS_SAMPLES
    return rows, ks


def _in_beams(p, sensor, axis, cut_sin2):
    d = p - sensor
    dist2 = d[..., 0] ** 2 + d[..., 1] ** 2
    cos = d[..., 0] * axis[..., 0] + d[..., 1] * axis[..., 1]
    cross = axis[..., 0] * d[..., 1] - axis[..., 1] * d[..., 0]
    return (cos > 0) & (cross * cross <= cut_sin2 * dist2)


def tangent_points(scene: Scene, sensors: SensorArray, loci,
                   max_bias_m: float = TANGENT_BIAS_M,
                   isolated_bias_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m])``: the points where the loci of neighbouring
    transducers cross, inside all beams, and the index of the locus each came from.

    A smooth surface is the envelope of the loci of its echoes: each locus touches it at its
    reflection point. Two loci of transducers δ apart, tangent to the surface at points
    δ apart, cross within δ²/(8r) of it (r the range) — even where their bands overlap
    over a long stretch — so the crossings of loci from one viewpoint (pair group) whose
    centres lie within sqrt(8·r·max_bias_m) of each other are surface points (the
    arc-transversal idea of sonar mapping). Each locus is sampled every 0.25° and crossings
    are found as sign changes of the other locus' path-length residual, interpolated. Around
    each crossing the locus' own tangent segment is added: the ±sqrt(2·r·max_bias_m) of arc
    over which it stays within ``max_bias_m`` of its tangent. With ``isolated_bias_m`` > 0
    a locus that crosses no neighbour contributes the middle of its in-beam arc,
    ±sqrt(2·r·isolated_bias_m): a surface facing the beams' middle (the line of sight,
    thesis §2.1.1 part 1) is there to within that — or, for a T = R locus of a moving
    ring, the same stretch around its point of the scan's envelope (:func:`scan_envelope`).
    """
    loci = as_loci(loci)
    if len(loci) < 2:
        return np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
    p, inside, a = _locus_samples(scene, sensors, loci)
    pos = sensors.positions
    T, R = pos[loci.tx], pos[loci.rx]
    centre = 0.5 * (T + R)
    path = 2 * a
    groups = sensors.groups[loci.tx]
    axes = sensors.axes
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)
    found: list[np.ndarray] = []
    source: list[np.ndarray] = []
    crossed = np.zeros(len(loci), dtype=bool)
    for i in range(len(loci)):
        others = np.flatnonzero((groups == groups[i]) & (np.arange(len(loci)) > i))
        if len(others) == 0 or not inside[i].any():
            continue
        reach = np.sqrt(8.0 * a[i] * max_bias_m)
        others = others[np.hypot(*(centre[others] - centre[i]).T) <= reach]
        if len(others) == 0:
            continue
        pi = p[i]  # [S, 2]
        # the steps k → k+1 with both ends in i's beams; the others' path-length residual
        # at both ends (only there: the in-beam arc is a small part of the locus)
        steps = np.flatnonzero(inside[i] & np.roll(inside[i], -1))
        if len(steps) == 0:
            continue

        def residual(q: np.ndarray, others=others) -> np.ndarray:
            return (np.hypot(*(q[None] - T[others, None]).transpose(2, 0, 1))
                    + np.hypot(*(q[None] - R[others, None]).transpose(2, 0, 1))
                    - path[others, None])

        g_here = residual(pi[steps])
        g_next = residual(pi[(steps + 1) % LOCUS_SAMPLES])
        j, m = np.nonzero(np.sign(g_here) != np.sign(g_next))
        if len(j) == 0:
            continue
        k = steps[m]
        g0, g1 = g_here[j, m], g_next[j, m]
        t = g0 / (g0 - g1)
        q = pi[k] + t[:, None] * (pi[(k + 1) % LOCUS_SAMPLES] - pi[k])
        b = others[j]
        keep = (_in_beams(q, T[b], axes[loci.tx[b]], cut_sin2)
                & _in_beams(q, R[b], axes[loci.rx[b]], cut_sin2))
        found.append(q[keep])
        source.append(np.full(int(keep.sum()), i))
        crossed[i] |= keep.any()
        crossed[b[keep]] = True
        # The locus itself stays within max_bias_m of the surface for ±sqrt(2·r·bias) of
        # arc around its tangent point: add those samples too (tangent segments).
        half = int(np.sqrt(2.0 * max_bias_m / a[i]) / (2 * np.pi / LOCUS_SAMPLES))
        for centre_k in np.unique(k[keep]):
            idx = (centre_k + np.arange(-half, half + 1)) % LOCUS_SAMPLES
            found.append(pi[idx[inside[i, idx]]])
            source.append(np.full(len(found[-1]), i))
    isolated = np.flatnonzero(~crossed & inside.any(axis=1) & (isolated_bias_m > 0))
    env = scan_envelope(scene, sensors, loci) if len(isolated) else None
    for i in isolated:
        mine = np.flatnonzero(env[0] == i) if env is not None else ()
        if len(mine) == 0:
            found.append(_middle_of_arc(p[i], inside[i], a[i], isolated_bias_m))
        else:  # around the scan envelope's points, inside the element's beam
            arcs = np.concatenate([_arc_around(env[1][m], env[2][m], env[3][m],
                                               min(isolated_bias_m, ENVELOPE_ARC_BIAS_M))
                                   for m in mine])
            found.append(arcs[_in_beams(arcs, T[i], axes[loci.tx[i]], cut_sin2)])
        source.append(np.full(len(found[-1]), i))
    if not found:
        return np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
    return np.concatenate(found), np.concatenate(source).astype(np.int64)


#: How much nearer than its range an envelope point may be to a transducer (rounding).
ENVELOPE_TOL_M = 0.002

#: The stretch of locus kept around an envelope point: where it stays within this of the
#: surface's tangent, for a plane; a convex surface bends away twice as fast, so keep it
#: short — the envelope points themselves come every half step.
ENVELOPE_ARC_BIAS_M = 0.001

#: Envelope points within 30° of the scan direction are left out: there the offset across
#: the scan, sqrt(ρ² − along²), multiplies the error of ``along`` by along/across > 1.7.
ENVELOPE_MAX_ALONG = math.cos(math.radians(30.0))


def scan_envelope(scene: Scene, sensors: SensorArray, loci
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Surface points of the T = R loci of a moving array (a wall-following ring): the
    envelope of the loci of one element at consecutive poses.

    The loci ``|q − T(s)| = ρ(s)`` of one element moved along the scan touch the surface
    where ``(q − T)·T′ = −ρ·ρ′`` (differentiating in s), q on the side the element faces.
    Differences over consecutive poses give it to O(step²): at each pose from the poses
    before and after (``D = T₊ − T₋``, ``(q − T)·D̂ = −ρ·(ρ₊ − ρ₋)/|D|``), and between
    each two consecutive poses from the locus midway (``T = (T₁ + T₂)/2``,
    ``ρ = (ρ₁ + ρ₂)/2``, ``D = T₂ − T₁``), which also serves the poses at the ends of a
    stretch where the surface is in the beam. Unlike the middle of the in-beam arc it is
    right for oblique walls and cylinders (exact for a plane). Only each element's first
    echo is used (the nearest surface in its beam, the thesis' T = R rule), and
    neighbouring ranges must be able to come from one surface, ``|ρ₂ − ρ₁| ≤ |T₂ − T₁|``.

    Returns ``(locus [m], centre [m, 2], radius [m], point [m, 2])``: the locus each
    point is credited to (a midway point to both of its loci), the (possibly midway)
    locus circle and the envelope point on it.
    """
    loci = as_loci(loci)
    groups = sensors.groups
    starts = {int(g): int(np.flatnonzero(groups == g)[0]) for g in np.unique(groups)}
    element = np.arange(len(groups)) - np.array([starts[int(g)] for g in groups], dtype=int)
    ranges = 0.5 * scene.medium.c * loci.tof_s
    pos, axes = sensors.positions, sensors.axes
    by_key: dict[tuple[int, int], list[int]] = {}  # the first echo of each element
    for i in np.flatnonzero(loci.tx == loci.rx):
        t = int(loci.tx[i])
        key = (int(groups[t]), int(element[t]))
        if key not in by_key or ranges[i] < ranges[by_key[key][0]]:
            by_key[key] = [int(i)]

    def partner(i: int, others: list[int] | None) -> int | None:
        if others is None:
            return None
        gap = np.hypot(*(pos[loci.tx[others[0]]] - pos[loci.tx[i]]))
        diff = np.abs(ranges[others] - ranges[i])
        k = int(np.argmin(diff))
        return others[k] if diff[k] <= gap else None

    out: list[tuple[int, np.ndarray, float, np.ndarray]] = []
    cut_sin2, _ = scene.transducer.beam(scene.medium.c)

    def envelope(i: int, j: int, centre: np.ndarray, r: float, d: np.ndarray,
                 dr: float, centred: bool) -> None:
        """Add the envelope point from loci i and j, credited to i (``centred``: at i's
        pose) or to both (midway); it must lie in both beams and be no nearer to either
        transducer than its range (the distance to the nearest point of the surface it
        came from)."""
        length = float(np.hypot(*d))
        along = -r * dr / length if length > 0 else np.inf
        if abs(along) > ENVELOPE_MAX_ALONG * r:
            return  # the surface lies ahead along the scan: its side is ill-conditioned
        u = d / length
        v = np.array([-u[1], u[0]])
        if v @ axes[loci.tx[i]] < 0:
            v = -v
        q = centre + along * u + np.sqrt(r * r - along * along) * v
        for k in (i, j):
            t = pos[loci.tx[k]]
            if (np.hypot(*(q - t)) < ranges[k] - ENVELOPE_TOL_M
                    or not _in_beams(q, t, axes[loci.tx[k]], cut_sin2)):
                return
        out.extend((k, centre, r, q) for k in ((i,) if centred else (i, j)))

    for (g, e), members in by_key.items():
        for i in members:
            before = partner(i, by_key.get((g - 1, e)))
            after = partner(i, by_key.get((g + 1, e)))
            t = pos[loci.tx[i]]
            if before is not None and after is not None:
                envelope(i, after, t, ranges[i],
                         pos[loci.tx[after]] - pos[loci.tx[before]],
                         ranges[after] - ranges[before], centred=True)
            if after is not None:
                ta = pos[loci.tx[after]]
                envelope(i, after, 0.5 * (t + ta), 0.5 * (ranges[i] + ranges[after]), ta - t,
                         ranges[after] - ranges[i], centred=False)
    if not out:
        return np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2))
    idx, centre, radius, point = zip(*out, strict=True)
    return (np.asarray(idx, np.int64), np.asarray(centre), np.asarray(radius),
            np.asarray(point))


def _arc_around(centre: np.ndarray, radius: float, point: np.ndarray,
                bias: float) -> np.ndarray:
    """Samples (every 0.25°) of the circle (``centre``, ``radius``) within ±sqrt(2·r·bias)
    of arc around its ``point``: where it stays within ``bias`` of its tangent there."""
    step = 2 * np.pi / LOCUS_SAMPLES
    half = int(np.sqrt(2.0 * bias / radius) / step)
    phi = np.arctan2(*(point - centre)[::-1]) + step * np.arange(-half, half + 1)
    return centre + radius * np.stack([np.cos(phi), np.sin(phi)], axis=-1)


def _middle_of_arc(samples: np.ndarray, inside: np.ndarray, a: float,
                   bias: float) -> np.ndarray:
    """The samples within ±sqrt(2·a·bias) of arc around the middle of the in-beam run."""
    idx = np.flatnonzero(inside)
    if len(idx) == 0:
        return np.zeros((0, 2))
    # the in-beam run may wrap around sample 0: unwrap it before taking its middle
    gaps = np.diff(idx)
    if len(gaps) and gaps.max() > 1:
        start = int(np.argmax(gaps)) + 1
        idx = np.r_[idx[start:], idx[:start] + LOCUS_SAMPLES]
    middle = int(idx[len(idx) // 2])
    half = int(np.sqrt(2.0 * bias / a) / (2 * np.pi / LOCUS_SAMPLES))
    window = np.arange(middle - half, middle + half + 1) % LOCUS_SAMPLES
    return samples[window[inside[window]]]


def _point_cells(scene: Scene, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    xmin, ymin = scene.extent[:2]
    ix = np.floor((points[:, 0] - xmin) / scene.cell).astype(np.int64)
    iy = np.floor((points[:, 1] - ymin) / scene.cell).astype(np.int64)
    return iy, ix


#: Empty cells kept around the points' cells by :func:`points_window`.
POINTS_WINDOW_MARGIN = 8


def points_window(scene: Scene, points: np.ndarray) -> tuple[int, int, int, int]:
    """``(row0, col0, ny, nx)``: the cells of the map's grid that hold ``points``, grown by
    :data:`POINTS_WINDOW_MARGIN`, starting at an even row and column (thinning's subfields
    go by parity) and clipped to the grid (at least one cell)."""
    ny, nx = scene.grid_shape
    iy, ix = _point_cells(scene, np.asarray(points, dtype=np.float64).reshape(-1, 2))
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    if not ok.any():
        return 0, 0, 1, 1
    m = POINTS_WINDOW_MARGIN
    r0 = max(0, int(iy[ok].min()) - m) & ~1
    c0 = max(0, int(ix[ok].min()) - m) & ~1
    r1 = min(ny, int(iy[ok].max()) + m + 1)
    c1 = min(nx, int(ix[ok].max()) + m + 1)
    return r0, c0, r1 - r0, c1 - c0


def point_map(scene: Scene, points: np.ndarray,
              window: tuple[int, int, int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(counts [ny, nx], sums [ny, nx, 2])``: how many ``points`` fall in each cell and
    the sum of their coordinates (for sub-cell positions); over the grid's ``window``
    ``(row0, col0, ny, nx)`` only when given (points outside it are left out)."""
    ny, nx = scene.grid_shape
    iy, ix = _point_cells(scene, points)
    if window is not None:
        row0, col0, ny, nx = window
        iy, ix = iy - row0, ix - col0
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    counts = np.zeros((ny, nx), dtype=np.float32)
    sums = np.zeros((ny, nx, 2))
    np.add.at(counts, (iy[ok], ix[ok]), 1.0)
    np.add.at(sums, (iy[ok], ix[ok]), points[ok])
    return counts, sums


# --------------------------------------------------------------------------- registry
# (temporary on main: the mapping package of issue 17 replaces this section)

@dataclasses.dataclass(frozen=True, eq=False)
class Votes:
    """What a mapping method hands to post-processing: a raw map of votes, or estimated
    reflection points (with their pairs) whose map is drawn after the line-of-sight check."""

    raw: np.ndarray | None = None
    points: np.ndarray | None = None
    tx: np.ndarray | None = None
    rx: np.ndarray | None = None
    counts: dict[str, int] = dataclasses.field(default_factory=dict)


def _merged_loci(scene: Scene, detections) -> Loci:
    loci = as_loci(detections)
    if scene.mapping.reciprocal == "merge":
        loci = merge_reciprocal(loci, 6.0 * scene.transducer.pulse_sigma_s)
    return loci


def _backprojection(scene, sensors, echoes, detections, context, tiles) -> Votes:
    from . import signals
    from .sensors import pairs

    dt, env = signals.envelopes(scene, sensors, echoes, context=context)
    return Votes(raw=backproject(scene, sensors, pairs(sensors), env, dt, context=context))


def _tangents(scene, sensors, echoes, detections, context, tiles) -> Votes:
    loci = _merged_loci(scene, detections)
    points, source = tangent_points(scene, sensors, loci,
                                    isolated_bias_m=scene.mapping.isolated_bias_m)
    return Votes(points=points, tx=loci.tx[source], rx=loci.rx[source])


def _loci(scene, sensors, echoes, detections, context, tiles) -> Votes:
    loci = _merged_loci(scene, detections)
    stats: list[AccumulationStats] = []

    def draw(part) -> np.ndarray:
        votes, st = accumulate_with_stats(scene, sensors, part, context=context, tiles=tiles)
        stats.append(st)
        return votes

    raw = (count_viewpoints(scene, sensors, loci, draw)
           if scene.mapping.combine == "viewpoints" else draw(loci))
    return Votes(raw=raw, counts={
        "tiles_total": sum(t.tiles_total for t in stats),
        "tiles_skipped": sum(t.tiles_skipped for t in stats),
        "pixel_locus_tests": sum(t.pixel_locus_tests for t in stats),
        "dense_pixel_locus_tests": sum(t.dense_tests for t in stats)})


METHODS = {"loci": _loci, "backprojection": _backprojection, "tangents": _tangents}


def map_votes(scene, sensors, echoes, detections, *, context, tiles: bool = True) -> Votes:
    return METHODS[scene.mapping.mode](scene, sensors, echoes, detections, context, tiles)
