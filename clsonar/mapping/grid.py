"""The map's grid: its pixels and local origin (:class:`MapGrid`), the width of a locus
(:func:`band_m`) and the memory check run before any map is drawn (:func:`check_map_memory`).

Numerics: coordinates are taken relative to the centre of an *origin pixel* in the middle of
the map, in float64 on the host, so the kernels see pixel centres as exact integers times the
cell and distances of at most the map's half-diagonal.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from .. import geometry
from ..errors import SceneError
from ..opencl import PRECISIONS, device_kind
from ..scene import MappingSettings, Scene
from ..sensors import SensorArray

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

#: Largest number of pixels along x or y: float32 represents pixel indices exactly below it.
MAX_CELLS_PER_AXIS = 1 << 24

#: float64 arrays of the map's size the NumPy reference holds at once (estimate).
REFERENCE_TEMPORARIES = 24


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


def map_grid(scene: Scene) -> MapGrid:
    """The scene's map (``scene.grid_shape`` cells of ``scene.cell``) around its middle pixel."""
    ny, nx = scene.grid_shape
    ox, oy = nx // 2, ny // 2
    x, y = geometry.cell_centres(scene.extent, scene.cell, np.asarray(oy), np.asarray(ox))
    return MapGrid(ny, nx, float(scene.cell), (float(x), float(y)), -ox, -oy)


def cell_centres(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """``(x [nx], y [ny])``: the map's cell centres in scene coordinates
    (:func:`clsonar.geometry.cell_centres`)."""
    ny, nx = scene.grid_shape
    x = geometry.cell_centres(scene.extent, scene.cell, np.zeros(nx, np.int64), np.arange(nx))
    y = geometry.cell_centres(scene.extent, scene.cell, np.arange(ny), np.zeros(ny, np.int64))
    return x[:, 0], y[:, 1]


def band_m(scene: Scene, settings: MappingSettings | None = None) -> float:
    """Width of a locus in path length: ``settings.band_m``, or 2√2·cell when it is null.

    |p−T| + |p−R| changes at most twice as fast as the distance across the locus (exactly
    twice for T = R), so 2√2·cell of path length make every locus at least √2 cells thick
    on the map: one 8-connected band, never a dotted one."""
    settings = settings if settings is not None else scene.mapping
    return settings.band_m if settings.band_m is not None else 2.0 * math.sqrt(2.0) * scene.cell


# --------------------------------------------------------------------------- memory


def format_bytes(n: float) -> str:
    """``n`` bytes in decimal units, three significant digits (``1.6 GB``)."""
    for unit, size in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


#: The most memory a run may count on, bytes (``clsonar run --max-memory``,
#: :func:`memory_limit`; None: what the machine has available).
_memory_limit: int | None = None


@contextmanager
def memory_limit(limit: int | None) -> Iterator[None]:
    """Within the block, :func:`host_available_bytes` — what a run's memory checks count
    on — is at most ``limit`` bytes (None: the machine's available memory)."""
    global _memory_limit
    before, _memory_limit = _memory_limit, limit
    try:
        yield
    finally:
        _memory_limit = before


def host_available_bytes() -> int | None:
    """Memory a run may take: what this machine can still give (MemAvailable), at most the
    limit :func:`memory_limit` sets; None if neither is known."""
    free = _machine_available_bytes()
    if _memory_limit is None:
        return free
    return _memory_limit if free is None else min(free, _memory_limit)


def _available_text(available: int) -> str:
    """What ``available`` bytes are, for an error line: the machine's memory or the limit."""
    if _memory_limit is not None and available >= _memory_limit:
        return f"the --max-memory limit ({format_bytes(available)})"
    return f"this machine has available ({format_bytes(available)})"


def _machine_available_bytes() -> int | None:
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


#: Host memory a fired pair takes at the pipeline's peak, bytes: its echoes, its
#: detections and their loci (measured: 160 B a pair for 9·10⁶ pairs, 424 B for 10⁶ with
#: the fixed costs; a 3000-element array peaks at 1.6 GB).
PAIR_BYTES = 200


def check_pair_memory(scene: Scene, sensors: SensorArray) -> None:
    """Raise :class:`~clsonar.errors.SceneError` (one line, key ``sensors``, before any echo
    is computed) when the fired pairs of ``sensors`` would take more memory than this
    machine has available (:data:`PAIR_BYTES` a pair)."""
    count = sensors.pair_count
    needed = float(count) * PAIR_BYTES
    available = host_available_bytes()
    if available is not None and needed > available:
        raise SceneError(
            f"{count:,} fired pairs ({len(sensors.groups):,} transducers) need about "
            f"{format_bytes(needed)} of memory, more than {_available_text(available)}: use "
            "fewer transducers or smaller pair groups", key="sensors", source=scene.name)


def work_items(nx: int, ny: int, vec: int, wgx: int, wgy: int) -> tuple[int, int]:
    """Work items along x and y covering nx × ny pixels, in whole work-groups."""
    def ceil_div(a: int, b: int) -> int:
        return -(-a // b)

    return ceil_div(ceil_div(nx, vec), wgx) * wgx, ceil_div(ny, wgy) * wgy


def _grid_error(scene: Scene, problem: str) -> SceneError:
    """The one line of a map that cannot be held (key ``cell``, the scene's name as its
    source: the command line puts the file there)."""
    ny, nx = scene.grid_shape
    xmin, ymin, xmax, ymax = scene.extent
    return SceneError(
        f"the map of {ny} × {nx} cells (extent {xmax - xmin:g} m × {ymax - ymin:g} m, cell "
        f"{scene.cell:g} m) {problem}: use a larger cell or a smaller extent", key="cell",
        source=scene.name)


def _check_device_memory(scene: Scene, precision: str, device) -> None:
    """Raise when one buffer of the padded map does not fit on ``device``."""
    ny, nx = scene.grid_shape
    vec, group = LAUNCH[device_kind(device), precision]
    items_x, items_y = work_items(nx, ny, vec, *group)
    padded = float(items_x * vec) * items_y * np.dtype(PRECISIONS[precision]).itemsize
    limit = min(int(device.max_mem_alloc_size), int(device.global_mem_size))
    if padded > limit:
        raise _grid_error(scene, f"needs {format_bytes(padded)} as a {precision} map, more "
                                 f"than one buffer on {device.name.strip()} can hold "
                                 f"({format_bytes(limit)})")


def check_map_memory(scene: Scene, precision: str = "float32", device=None, *,
                     reference: bool = False, host_bytes_per_cell: float | None = None) -> None:
    """Raise :class:`~clsonar.errors.SceneError` naming the size needed when the scene's
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
    if device is not None:
        _check_device_memory(scene, precision, device)
    if host_bytes_per_cell is not None:
        needed = float(ny) * nx * host_bytes_per_cell
    elif reference:
        needed = float(ny) * nx * 8 * REFERENCE_TEMPORARIES
    else:  # padded transfer copy, result, its caller
        needed = float(ny) * nx * np.dtype(PRECISIONS[precision]).itemsize * 3
    available = host_available_bytes()
    if available is not None and needed > available:
        raise _grid_error(scene, f"needs {format_bytes(needed)} of memory, more than "
                                 f"{_available_text(available)}")
