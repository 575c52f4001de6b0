"""Large but valid scenes (issue 19): each run as a user runs it, ``clsonar run FILE --out
DIR --png none`` in its own process, with its wall time and peak resident memory; each must
map within the memory limit or be refused in one line, never be killed.

The scenes are written as scene files (format v1, the defaults wherever a user would leave
a key out) so that they pass through the loader and its limits like a user's file:

- ``rings-10k``: 10,000 transducers, a robot's log of 1,250 ring poses (8 elements each,
  one group a pose) in a 26 m × 11 m room;
- ``outline-45k``: a round room whose outline is one closed polyline of 45,000 vertices
  (near the loader's 50,000 lists), first-order echoes (``echo.max_order`` 1: the
  loader's limit of 10⁷ reflection sequences), scanned by a ring; and the same file with
  the default ``max_order``, refused on reading;
- ``sinusoid-1M``: a sinusoidal wall sampled at 10⁶ intervals of ``echo.curve_step_m``
  (the loader's limit), seen by a 10-element array;
- ``floor-1km``: a 1 km × 100 m floor of 10 rooms 100 m square on a map of 5 cm cells
  (4·10⁷ cells), each room scanned by a wall-following ring every 2 m;
- ``floor-20-order-4``: 20 rooms 5 m square in a 5 × 4 floor, echoes to the fourth
  order;
- ``array-N`` (``--arrays``): one linear array of N elements (N² pairs) facing a wall 3 m
  away; 10,000 is refused before any echo (10⁸ pairs).

``python -m clsonar.tools.corpus --out DIR [--arrays 300,1000,3000,10000] [--markdown
PATH]`` writes the scene files, ``corpus.json`` and a table.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import json
import math
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..files import write_atomic
from .markdown import NONE, cm, percent

#: How long one scene may run before it counts as hung, seconds.
HANG_S = 900.0

SceneDict = dict[str, Any]


def _scene(name: str, extent: tuple[float, float, float, float], surfaces: list[SceneDict],
           sensors: SceneDict, cell: float = 0.01, blocks: SceneDict | None = None
           ) -> SceneDict:
    """A scene file's contents; ``blocks``: settings blocks (``{"echo": {...}}``)."""
    return {"clsonar": 1, "name": name, "extent": list(extent), "cell": cell,
            "surfaces": surfaces, "sensors": sensors, **(blocks or {})}


def _box(x0: float, y0: float, x1: float, y1: float) -> SceneDict:
    return {"type": "polyline", "points": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
            "closed": True}


def _ring(cx: float, cy: float, group: int, elements: int = 8,
          radius: float = 0.065) -> list[SceneDict]:
    """One ring pose as explicit transducers facing outwards, its own pair group."""
    out = []
    for k in range(elements):
        a = 2.0 * math.pi * k / elements
        out.append({"position": [round(cx + radius * math.cos(a), 6),
                                 round(cy + radius * math.sin(a), 6)],
                    "heading_deg": round(math.degrees(a), 6), "group": group})
    return out


def rings_10k() -> SceneDict:
    """1,250 ring poses (10,000 transducers) on a 50 × 25 grid in a 26 m × 11 m room."""
    poses = [(0.75 + 0.5 * i, 0.75 + 0.4 * j) for i in range(50) for j in range(25)]
    transducers = [t for g, (x, y) in enumerate(poses) for t in _ring(x, y, g)]
    return _scene("rings-10k", (-0.5, -0.5, 26.5, 11.5), [_box(0.0, 0.0, 26.0, 11.0)],
                  {"transducers": transducers})


def outline(vertices: int = 45_000, max_order: int | None = 1) -> SceneDict:
    """A round room of radius 4 m drawn as one closed polyline of ``vertices`` vertices,
    a ring at 1 m from its centre; ``max_order`` None leaves the file's default."""
    pts = [[round(5.0 + 4.0 * math.cos(a), 7), round(5.0 + 4.0 * math.sin(a), 7)]
           for a in (2.0 * math.pi * k / vertices for k in range(vertices))]
    extra = None if max_order is None else {"echo": {"max_order": max_order}}
    name = f"outline-{vertices // 1000}k" + ("" if max_order is not None else "-order-2")
    return _scene(name, (0.5, 0.5, 9.5, 9.5), [{"type": "polyline", "points": pts,
                                                "closed": True}],
                  {"transducers": _ring(6.0, 5.0, 0)}, blocks=extra)


def sinusoid_1m() -> SceneDict:
    """A 10 m sinusoidal wall sampled at 10⁶ intervals, 2 m from a 10-element array."""
    array = [{"position": [4.5 + 0.1 * k, 1.0], "heading_deg": 90.0} for k in range(10)]
    wall = {"type": "sinusoid", "from": [0.0, 3.0], "to": [10.0, 3.0], "amplitude": 0.1,
            "period": 1.0}
    return _scene("sinusoid-1M", (0.0, 0.0, 10.0, 4.0), [wall], {"transducers": array},
                  blocks={"echo": {"curve_step_m": 1e-5}})


def floor(name: str, columns: int, rows: int, room_m: float, cell: float, step_m: float,
          blocks: SceneDict | None = None) -> SceneDict:
    """A floor of ``columns`` × ``rows`` square rooms ``room_m`` apart (walls 0.2 m thick),
    one wall-following ring per room every ``step_m``."""
    surfaces, rings = [], []
    for i in range(columns):
        for j in range(rows):
            x0, y0 = i * room_m + 0.1, j * room_m + 0.1
            x1, y1 = (i + 1) * room_m - 0.1, (j + 1) * room_m - 0.1
            surfaces.append(_box(x0, y0, x1, y1))
            rings.append({"type": "wall-following", "start": [x0 + 0.6, (y0 + y1) / 2],
                          "step_m": step_m})
    return _scene(name, (0.0, 0.0, columns * room_m, rows * room_m), surfaces,
                  {"placements": rings}, cell=cell, blocks=blocks)


def array(elements: int, pitch: float = 0.017) -> SceneDict:
    """One linear array of ``elements`` facing a wall 3 m away, every pair fired."""
    length = elements * pitch
    ts = [{"position": [round(0.5 + k * pitch, 6), 1.0], "heading_deg": 90.0}
          for k in range(elements)]
    return _scene(f"array-{elements}", (0.0, 0.0, length + 1.0, 4.5),
                  [{"type": "polyline", "points": [[0.0, 4.0], [length + 1.0, 4.0]],
                    "closed": False}], {"transducers": ts})


#: The corpus: name → scene file contents.
SCENES: dict[str, Callable[[], SceneDict]] = {
    "rings-10k": rings_10k,
    "outline-45k": outline,
    "outline-45k-order-2": lambda: outline(max_order=None),
    "sinusoid-1M": sinusoid_1m,
    "floor-1km": lambda: floor("floor-1km", 10, 1, 100.0, 0.05, 2.0),
    "floor-20-order-4": lambda: floor("floor-20-order-4", 5, 4, 5.0, 0.01, 0.5,
                                      blocks={"echo": {"max_order": 4}}),
}


@dataclass(frozen=True)
class Outcome:
    """One scene's run: mapped or refused (``message``: the one line on stderr), its wall
    time, its peak resident memory and what the run itself recorded."""

    scene: str
    status: int
    seconds: float
    peak_bytes: int
    message: str
    lines: int  # lines on stderr
    estimate_bytes: float | None  # the larger of the pairs' and the maps' estimates
    limit_bytes: float | None  # what the run could count on (available, or --max-memory)
    profile_points: int | None
    accuracy_m: float | None
    completeness_2cm: float | None


#: The child :func:`run_scene` starts: ``clsonar`` ARGV in-process, then its peak memory
#: (:func:`clsonar.cost.peak_bytes`, this program's own) written to the file ARGV[1].
_CHILD = ("import sys\nfrom clsonar import cost\nfrom clsonar.cli import main\n"
          "try:\n    status = main(sys.argv[2:])\nfinally:\n"
          "    open(sys.argv[1], 'w').write(str(cost.peak_bytes()))\nsys.exit(status)\n")


def run_scene(path: Path, out: Path, extra: tuple[str, ...] = ()) -> Outcome:
    """``clsonar run PATH --out OUT --png none -q`` in a child process: its outcome, time
    (wall) and peak memory (its own high-water mark: a child's rusage would also count the
    memory of this process, which started it)."""
    peak_file = out.parent / f".{out.name}.peak"
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-c", _CHILD, str(peak_file), "run", str(path), "--out", str(out),
           "--png", "none", "-q", *extra]
    start = time.perf_counter()
    child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)
    timer = threading.Timer(HANG_S, child.kill)
    timer.start()
    _, err = child.communicate()
    timer.cancel()
    seconds = time.perf_counter() - start
    peak = int(peak_file.read_text()) if peak_file.exists() else 0
    peak_file.unlink(missing_ok=True)
    report = out / "report.json"
    data = json.loads(report.read_text()) if child.returncode == 0 and report.exists() else {}
    cost = data.get("cost") or {}
    metrics = data.get("metrics") or {}
    lines = [ln for ln in err.splitlines() if ln.strip()]
    message = lines[0].replace(str(path), path.name) if lines else ""
    return Outcome(path.stem, int(child.returncode), seconds, peak, message,
                   len(lines),
                   max(cost["pair_bytes"], cost["map_bytes"]) if cost else None,
                   cost.get("available_bytes"),
                   (data.get("counts") or {}).get("profile_points"),
                   (metrics.get("accuracy_m") or {}).get("rms"),
                   (metrics.get("completeness") or {}).get("2cm"))


def longest_silence(path: Path) -> dict[str, Any]:
    """Run the scene ``path`` through the pipeline in this process, listening to its stages
    and steps (:mod:`clsonar.steps`): the longest time between two reports — how long the
    GUI's Cancel can wait — and the reports around it."""
    from .. import steps
    from ..pipeline import run
    from ..scene import load_scene

    marks: list[tuple[float, str]] = [(time.perf_counter(), "start")]

    def stage(name: str, i: int, n: int) -> None:
        marks.append((time.perf_counter(), f"stage {name}"))

    def step(what: str, done: int, total: int) -> None:
        marks.append((time.perf_counter(), f"{what} {done}/{total}"))

    with steps.watching(step):
        run(load_scene(path), progress=stage)
    marks.append((time.perf_counter(), "end"))
    gap, after, before = max((b[0] - a[0], a[1], b[1]) for a, b in itertools.pairwise(marks))
    return {"scene": path.stem, "reports": len(marks) - 2, "longest_s": gap, "after": after,
            "before": before}


def write_scenes(folder: Path, names: list[str], arrays: list[int]) -> list[Path]:
    """The corpus' scene files in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    made: dict[str, Callable[[], SceneDict]] = {name: SCENES[name] for name in names}
    made.update({f"array-{n}": functools.partial(array, n) for n in arrays})
    paths = []
    for name, make in made.items():
        path = folder / f"{name}.json"
        write_atomic(path, json.dumps(make()).encode())
        paths.append(path)
    return paths


def table(rows: list[Outcome]) -> list[str]:
    """The markdown table of ``rows``."""
    def mb(b: float | None) -> str:
        return "–" if b is None else f"{b / 1e6:,.0f} MB"

    out = ["| scene | outcome | wall s | peak memory | estimate | limit | profile points | "
           "accuracy | ≤ 2 cm |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        outcome = "mapped" if r.status == 0 else f"exit {r.status}: {r.message}"
        points = NONE if r.profile_points is None else f"{r.profile_points:,}"
        out.append(f"| {r.scene} | {outcome} | {r.seconds:.1f} | {mb(r.peak_bytes)} "
                   f"| {mb(r.estimate_bytes)} | {mb(r.limit_bytes)} | {points} "
                   f"| {NONE if r.accuracy_m is None else cm(r.accuracy_m) + ' cm'} "
                   f"| {percent(r.completeness_2cm)} |")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m clsonar.tools.corpus",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True)
    p.add_argument("--scenes", default=",".join(SCENES))
    p.add_argument("--arrays", default="", help="array sizes, e.g. 300,1000,3000,10000")
    p.add_argument("--markdown", help="write the table here too")
    p.add_argument("--silence", metavar="SCENE.json",
                   help="instead, run SCENE.json here and print the longest time between "
                        "two progress reports (JSON)")
    args = p.parse_args(argv)
    if args.silence:
        print(json.dumps(longest_silence(Path(args.silence))))
        return 0
    out = Path(args.out)
    names = [n for n in args.scenes.split(",") if n]
    arrays = [int(n) for n in args.arrays.split(",") if n]
    rows = []
    for path in write_scenes(out / "scenes", names, arrays):
        row = run_scene(path, out / "runs" / path.stem)
        rows.append(row)
        print(table([row])[-1], flush=True)
    write_atomic(out / "corpus.json", json.dumps([asdict(r) for r in rows], indent=1).encode())
    text = "\n".join(table(rows)) + "\n"
    write_atomic(out / "corpus.md", text.encode())
    if args.markdown:
        write_atomic(Path(args.markdown), text.encode())
    return 0


if __name__ == "__main__":
    sys.exit(main())
