"""What a run of a scene will cost, from the scene alone, before any kernel runs (issue 19:
``clsonar run --dry-run``): the transducers placed and the pairs they fire, the samples of
each pair's received signal, the map's cells, and the memory the pairs and the map take at
the pipeline's peak against what this machine has available — the same figures the run
itself refuses on (:func:`~clsonar.mapping.check_pair_memory`,
:func:`~clsonar.mapping.check_map_memory`)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from . import regions
from .echoes import scene_walls
from .geometry import build_geometry
from .mapping import PAIR_BYTES, grid
from .mapping.grid import memory_limit as memory_limit  # clsonar run --max-memory
from .pipeline import MOSAIC_BYTES_PER_CELL, PIPELINE_BYTES_PER_CELL, RunResult, apply_preset
from .scene import MAX_WALL_SEQUENCES, Scene
from .sensors import SensorArray, place_sensors
from .signals import signal_model
from .survey import choose_settings, survey


@dataclass(frozen=True)
class Estimate:
    """A run's cost before it starts (module docstring)."""

    transducers: int
    pairs: int
    samples_per_pair: int
    cells: int
    rooms: int  # mapped one by one (0: the scene is mapped whole)
    walls: int  # walls of the map (the room) with the most: its echoes go among them
    max_order: int
    pair_bytes: float
    map_bytes: float
    available_bytes: int | None

    @property
    def fits(self) -> bool:
        """Whether the pairs and the map fit this machine's available memory."""
        return self.available_bytes is None or (
            max(self.pair_bytes, self.map_bytes) <= self.available_bytes)


def estimate(scene: Scene, preset: str | None = None) -> Estimate:
    """The cost of running ``scene`` (with ``preset``): its transducers are placed (a
    wall-following trace included) and its settings chosen, nothing else is computed."""
    scene = apply_preset(scene, preset)
    geom = build_geometry(scene)
    sensors = place_sensors(scene, geom)
    scene, _ = choose_settings(scene, survey(scene, sensors, geom), geom=geom)
    return _estimate(scene, sensors)


def of_run(result: RunResult) -> Estimate:
    """The estimate :func:`estimate` gives for the scene ``result`` ran, from its placed
    transducers and chosen settings (nothing placed again; a floor mapped room by room,
    whose rooms chose their own, has the floor's chosen as :func:`estimate` does)."""
    scene = result.scene
    if result.counts.get("rooms_mapped"):
        scene, _ = choose_settings(scene, survey(scene, result.sensors, result.geometry),
                                   geom=result.geometry)
    return _estimate(scene, result.sensors)


def peak_bytes() -> int:
    """This process's peak resident memory so far, bytes: Linux's VmHWM, the high-water mark
    of this program's own memory (getrusage's ru_maxrss elsewhere, which also counts the
    memory of the process that started this one, up to its exec)."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import resource

    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def record(e: Estimate, peak: int | None = None) -> dict[str, object]:
    """``report.json``'s ``cost``: the estimate the run was checked against, beside the
    process' ``peak`` resident memory (bytes) and the pairs and cells used."""
    return {**asdict(e), "peak_bytes": peak}


def _estimate(scene: Scene, sensors: SensorArray) -> Estimate:
    """The :class:`Estimate` of ``scene`` (settings chosen) with ``sensors`` placed."""
    ny, nx = scene.grid_shape
    rooms = regions.split_rooms(scene)
    per_cell = MOSAIC_BYTES_PER_CELL if rooms else PIPELINE_BYTES_PER_CELL
    pairs = sensors.pair_count
    walls = max(scene_walls(part) for part in ([r.scene for r in rooms] if rooms else [scene]))
    return Estimate(transducers=len(sensors), pairs=pairs,
                    samples_per_pair=signal_model(scene).n_samples, cells=ny * nx,
                    rooms=len(rooms) if rooms else 0, walls=walls,
                    max_order=scene.echo.max_order, pair_bytes=float(pairs) * PAIR_BYTES,
                    map_bytes=float(ny) * nx * per_cell,
                    available_bytes=grid.host_available_bytes())


def lines(e: Estimate) -> list[str]:
    """The estimate as the lines ``clsonar run --dry-run`` prints."""
    mapped = f"room by room ({e.rooms} rooms)" if e.rooms else "whole"
    size = grid.format_bytes
    free = "unknown" if e.available_bytes is None else size(e.available_bytes)
    return [f"transducers {e.transducers:,}, fired pairs {e.pairs:,}",
            f"received signal {e.samples_per_pair:,} samples a pair "
            f"({float(e.pairs) * e.samples_per_pair:.3g} at most in all)",
            f"map {e.cells:,} cells, mapped {mapped}",
            f"echoes among {e.walls:,} walls (the most of one map) to order {e.max_order}: "
            f"at most {float(e.walls) ** e.max_order:.3g} mirror sequences"
            + ("" if float(e.walls) ** e.max_order <= MAX_WALL_SEQUENCES else
               f", more than {MAX_WALL_SEQUENCES:.0e}: the run would be refused"),
            f"memory: pairs about {size(e.pair_bytes)} ({PAIR_BYTES} B a pair), maps about "
            f"{size(e.map_bytes)}; available {free}: "
            + ("fits" if e.fits else "does not fit: the run would be refused")]


def parse_size(text: str) -> int:
    """Bytes from ``text``: a number with an optional unit, k, M, G or T (powers of 1000;
    ``2G``, ``500M``, ``1.5e9``); ValueError when it is not one, or not above 0."""
    units = {"": 1, "K": 10**3, "M": 10**6, "G": 10**9, "T": 10**12}
    t = text.strip().upper().removesuffix("B")
    unit = t[-1:] if t[-1:] in units else ""
    value = float(t[: len(t) - len(unit)])
    if not (math.isfinite(value) and value > 0):
        raise ValueError(text)
    return int(value * units[unit])


__all__ = ["Estimate", "estimate", "lines", "memory_limit", "of_run", "parse_size",
           "peak_bytes", "record"]
