"""Multi-room floors for the benchmark at scale (issue "Fast": a 50 m × 50 m floor at 1 cm,
and a 100 m × 100 m one, 10⁸ cells, within 2 GB of host memory).

A floor is a grid of closed square rooms, each mapped as the thesis maps its closed room
(§2.1.2, §3.6): an 8-element ring follows the walls of each room and fires all pairs at
every step. Every fourth room holds a cylinder. The pipeline maps such a scene room by room
(:mod:`clsonar.regions`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .. import heap
from ..scene import Circle, Polyline, Scene, Sensors, WallFollowing


def floor_scene(size_m: float = 50.0, room_m: float = 5.0, wall_m: float = 0.2,
                cell: float = 0.01, step_m: float = 0.5, name: str | None = None,
                base: Scene | None = None) -> Scene:
    """A ``size_m`` × ``size_m`` floor of square rooms ``room_m`` apart whose walls are
    ``wall_m`` thick (each room's outline is its square inset by ``wall_m``/2), on a map of
    ``cell``; one wall-following ring per room, ``step_m`` between poses; a cylinder of
    radius 0.8 m in every fourth room. Transducer, signal, echo, mapping and
    post-processing settings are those of ``base`` (default: the bundled closed room,
    ``scenes/room.json``)."""
    if base is None:
        from ..files import bundled_scenes
        from ..scene import load_scene

        base = load_scene(bundled_scenes() / "room.json")
    n = max(1, round(size_m / room_m))
    half = wall_m / 2
    surfaces: list = []
    rings = []
    for i in range(n):
        for j in range(n):
            x0, y0 = i * room_m + half, j * room_m + half
            x1, y1 = (i + 1) * room_m - half, (j + 1) * room_m - half
            surfaces.append(Polyline(((x0, y0), (x1, y0), (x1, y1), (x0, y1)), closed=True))
            if (i + j) % 4 == 3:
                surfaces.append(Circle(((x0 + x1) / 2, (y0 + y1) / 2), 0.8))
            rings.append(WallFollowing(start=(x0 + 0.6, (y0 + y1) / 2), step_m=step_m,
                                       clearance_m=0.5, radius_m=0.065, elements=8))
    return dataclasses.replace(base, name=name or f"floor-{size_m:g}m",
                               extent=(0.0, 0.0, n * room_m, n * room_m), cell=cell,
                               surfaces=tuple(surfaces), sensors=Sensors(placements=tuple(rings)))


@dataclass(frozen=True)
class FloorRow:
    """One floor run: its size, cells, rooms, seconds per stage, peak memory and error."""

    scene: str
    cells: int
    rooms: int
    transducers: int
    pairs: int
    seconds: dict[str, float]
    total_s: float
    peak_rss_mb: float
    mosaic_mb: float
    accuracy_m: float | None
    completeness_2cm: float | None
    vertices_found: str | None
    #: seconds of the whole :func:`clsonar.run` call (the stages' ``seconds`` are summed
    #: over the rooms, several at a time in worker processes)
    wall_s: float = 0.0
    #: worker processes that mapped the rooms (:func:`clsonar.rooms.worker_count`), and the
    #: largest one's peak memory (``peak_rss_mb`` is this process's own)
    workers: int = 0
    workers_peak_rss_mb: float = 0.0
    #: :func:`result_digest` of the run (``--digest``; empty when not asked for)
    digest: str = ""


def result_digest(r) -> str:
    """A sha256 of everything a run's result says but its seconds: the four maps, the
    profile's curves and vertices, the transducers, every column of the echoes and the
    detections, the metrics, counts and warnings (to show two runs the same to the bit)."""
    import hashlib
    import json

    import numpy as np

    h = hashlib.sha256()
    arrays = [r.raw, r.filtered, r.occupied, r.thin, *r.profile.curves, r.profile.vertices,
              r.sensors.positions, r.sensors.headings_deg, r.sensors.groups, r.sensors.poses]
    arrays += [getattr(t, f.name) for t in (r.echoes, r.detections)
               for f in dataclasses.fields(t)]
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        raw = a.reshape(-1).view(np.uint8)
        for i in range(0, len(raw), 1 << 24):  # 16 MB copies at a time, not a map's 400 MB
            h.update(raw[i:i + (1 << 24)].tobytes())
    h.update(json.dumps([r.metrics, r.counts, list(r.warnings)], sort_keys=True,
                        default=str).encode())
    return h.hexdigest()


def run_floor(size_m: float, device: str | None = None, digest: bool = False) -> FloorRow:
    """Build and map a floor of ``size_m`` in this process; report its peak memory (the
    whole process's high-water mark, interpreter and OpenCL runtime included) and the
    largest worker process's (the rooms mapped side by side, :mod:`clsonar.rooms`), and
    with ``digest`` the :func:`result_digest` of the run."""
    import resource
    import time

    from ..outputs import metric
    from ..pipeline import MOSAIC_BYTES_PER_CELL, run
    from ..rooms import worker_count

    scene = floor_scene(size_m)
    start = time.perf_counter()
    r = run(scene, device=device)
    wall = time.perf_counter() - start
    m = r.metrics
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux
    workers = worker_count(int(r.counts.get("rooms_mapped", 0)))
    return FloorRow(scene.name, int(r.raw.size), int(r.counts.get("rooms_mapped", 1)),
                    len(r.sensors), int(r.counts["pairs"]), dict(r.seconds),
                    float(sum(r.seconds.values())), peak,
                    r.raw.size * MOSAIC_BYTES_PER_CELL / 2**20, metric(m, "accuracy_m.rms"),
                    metric(m, "completeness.2cm"), metric(m, "vertices_found"), wall,
                    workers if workers > 1 else 0,
                    resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0,
                    result_digest(r) if digest else "")


def bench_floor(size_m: float, device: str | None = None, timeout_s: float = 3600) -> FloorRow:
    """:func:`run_floor` in a fresh Python process, so that its peak memory is its own."""
    import json
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "clsonar.tools.floors", f"{size_m:g}"]
    if device:
        cmd += ["--device", device]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, check=True)
    return FloorRow(**json.loads(done.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> int:
    """``python -m clsonar.tools.floors SIZE_M [--device D] [--digest]``: map a floor,
    print its :class:`FloorRow` as one JSON line."""
    import argparse
    import json

    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.floors")
    parser.add_argument("size_m", type=float)
    parser.add_argument("--device")
    parser.add_argument("--digest", action="store_true",
                        help="also a sha256 of the maps, profile, tables, metrics and counts")
    args = parser.parse_args(argv)
    if argv is None:  # this process's own command, as ``clsonar`` runs one (cli.main)
        heap.settle()
    print(json.dumps(dataclasses.asdict(run_floor(args.size_m, args.device, args.digest))))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = ["FloorRow", "bench_floor", "floor_scene", "result_digest", "run_floor"]
