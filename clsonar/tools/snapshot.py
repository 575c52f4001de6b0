"""Snapshots of every bundled scene's run, to show that a change of the code changed no result.

``python -m clsonar.tools.snapshot save DIR`` runs every bundled scene with its own settings
and with the thesis preset and keeps, per run, the report (less seconds and device) and every
array a user sees: the raw, filtered, occupied and thin maps, the profile's points and
vertices, the echoes and the detections. ``python -m clsonar.tools.snapshot compare OLD NEW``
lists every difference — a metric, a setting, a counter, an array not equal to the bit — and
exits 1 if there is any. Take a snapshot before a refactor, another after, compare.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..files import bundled_scenes, write_atomic
from ..opencl import get_context
from ..pipeline import RunResult, run
from ..scene import load_scene

#: Report keys that may differ between two runs of the same code.
UNSTABLE_KEYS = ("seconds", "device")


def arrays(result: RunResult) -> dict[str, np.ndarray]:
    """The arrays of a run that a snapshot keeps."""
    return {"raw": result.raw, "filtered": result.filtered, "occupied": result.occupied,
            "thin": result.thin, "profile": result.profile.points,
            "vertices": result.profile.vertices,
            "echoes": np.stack([result.echoes.tx, result.echoes.rx, result.echoes.tof_s,
                                result.echoes.amplitude]),
            "detections": np.stack([result.detections.tx, result.detections.rx,
                                    result.detections.tof_s, result.detections.amplitude])}


def save(out: Path, scenes: Path | None = None, device: str | None = None) -> list[str]:
    """Run every scene of ``scenes`` (default: the bundled ones) with its own settings and
    with the thesis preset; write ``NAME-file.json/.npz`` and ``NAME-thesis.json/.npz``
    into ``out``. Returns the run names."""
    out.mkdir(parents=True, exist_ok=True)
    context = get_context(device)
    names = []
    for path in sorted((scenes or bundled_scenes()).glob("*.json")):
        for preset in (None, "thesis"):
            result = run(load_scene(path), context=context, preset=preset)
            name = f"{path.stem}-{preset or 'file'}"
            report = {k: v for k, v in result.report().items() if k not in UNSTABLE_KEYS}
            write_atomic(out / f"{name}.json",
                         json.dumps(report, sort_keys=True, indent=1, default=str).encode())
            kept: dict[str, Any] = arrays(result)  # numpy's stubs type **kwds as its options
            np.savez_compressed(out / f"{name}.npz", **kept)
            names.append(name)
    return names


def compare(old: Path, new: Path) -> list[str]:
    """Every difference between the snapshots in ``old`` and ``new``, one line each."""
    found = []
    for a in sorted(old.glob("*.json")):
        b = new / a.name
        if not b.exists():
            found.append(f"{a.stem}: missing in {new}")
            continue
        ra, rb = json.loads(a.read_text()), json.loads(b.read_text())
        for key in sorted(set(ra) | set(rb)):
            if ra.get(key) != rb.get(key):
                found.append(f"{a.stem}: report.{key}: {_delta(ra.get(key), rb.get(key))}")
        na, nb = np.load(a.with_suffix(".npz")), np.load(b.with_suffix(".npz"))
        for key in sorted(set(na.files) | set(nb.files)):
            if key not in na.files or key not in nb.files \
                    or na[key].shape != nb[key].shape or not np.array_equal(na[key], nb[key]):
                found.append(f"{a.stem}: {key} differs")
    return found


def _delta(a: object, b: object) -> str:
    """The entries of two report values that differ (dicts: by key)."""
    if isinstance(a, dict) and isinstance(b, dict):
        keys = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        return ", ".join(f"{k} {a.get(k)!r} → {b.get(k)!r}" for k in keys)
    return f"{a!r} → {b!r}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.snapshot",
                                     description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("save", help="run every bundled scene and keep its results")
    p.add_argument("out", type=Path)
    p.add_argument("--scenes", type=Path, help="a folder of scenes instead of the bundled ones")
    p.add_argument("--device")
    p = sub.add_parser("compare", help="list the differences between two snapshots")
    p.add_argument("old", type=Path)
    p.add_argument("new", type=Path)
    args = parser.parse_args(argv)
    if args.command == "save":
        names = save(args.out, args.scenes, args.device)
        print(f"{len(names)} runs saved in {args.out}")
        return 0
    differences = compare(args.old, args.new)
    for line in differences:
        print(line)
    print(f"{len(list(args.old.glob('*.json')))} runs compared, {len(differences)} differences")
    return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())
