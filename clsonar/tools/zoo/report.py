"""``clsonar zoo``: every zoo case run with the default settings on one OpenCL context,
scored (:mod:`.score`) and written to ``zoo.md`` and ``zoo.json`` atomically; with a
baseline (an earlier ``zoo.json``), each case's seconds against the baseline's (issue 14:
"run time per scene within 1.5× of today's")."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ... import pipeline
from ...errors import ClsonarError
from ...files import read_text, write_atomic
from ...opencl import device_name, get_context
from ...scene import scene_from_dict
from ...version import __version__
from ..markdown import NONE, cm, percent
from ..progress import Progress
from .cases import ZooCase, zoo
from .score import score
from .thresholds import CRITERIA, KINDS, THRESHOLDS

#: A later run's seconds may be this many times a case's baseline seconds.
SLOWER_ALLOWED = 1.5

#: Run once, untimed, before the zoo: builds every kernel a default run uses (rings, arrays,
#: noise), so no case's seconds include building them.
WARM_UP: tuple[dict[str, Any], ...] = (
    {"clsonar": 1, "name": "warm-up-ring", "extent": [0, 0, 3, 3], "cell": 0.02,
     "surfaces": [{"type": "polyline", "closed": True,
                   "points": [[0.2, 0.2], [2.8, 0.2], [2.8, 2.8], [0.2, 2.8]]}],
     "sensors": {"placement": {"type": "circular", "center": [1.5, 1.5]}}},
    {"clsonar": 1, "name": "warm-up-array", "extent": [0, 0, 3, 3], "cell": 0.02,
     "signal": {"noise_std": 0.3},
     "surfaces": [{"type": "polyline", "points": [[2.5, 0.5], [2.5, 2.5]]}],
     "sensors": {"transducers": [{"position": [0.5, 1.4 + 0.05 * k], "heading_deg": 0.0}
                                 for k in range(4)]}},
)


def run_case(case: ZooCase, context, repeat: int = 1) -> dict[str, Any]:
    """The scored row of one case run with its defaults, the fastest of ``repeat`` runs (the
    runs are identical but for their seconds); an error a user could meet, such as a
    placement that cannot be made, is kept in the row as ``error`` (no map)."""
    try:
        result = min((pipeline.run(case.scene, context=context) for _ in range(repeat)),
                     key=lambda r: sum(r.seconds.values()))
    except ClsonarError as e:
        passes = {c: (False if c == "map" else None) for c in case.criteria}
        return {"name": case.name, "kind": case.kind, "scan": case.scan, "noise": case.noise,
                "tags": list(case.tags), "cells": case.cells, "error": str(e), "points": 0,
                "accuracy_m": None, "completeness_3cm": None, "vertices_in_view": 0,
                "vertex_error_m": None, "seconds": None, "pass": passes, "passed": False}
    return score(case, result)


def run_zoo(cases: list[ZooCase], *, context=None, device: str | None = None,
            progress: Progress | None = None, repeat: int = 1) -> list[dict[str, Any]]:
    """Every case of ``cases`` run (``repeat`` times, the fastest kept) and scored on one
    context, after a warm-up."""
    ctx = context if context is not None else get_context(device)
    for data in WARM_UP:
        pipeline.run(scene_from_dict(data, "zoo:warm-up"), context=ctx)
    rows = []
    for i, case in enumerate(cases):
        if progress is not None:
            progress(i + 1, len(cases), case.name)
        rows.append(run_case(case, ctx, repeat))
    return rows


def summary(rows: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per kind (in :data:`KINDS` order, those present): cases, and for each criterion and
    ``all`` the cases scored and the cases passing, and the seconds summed."""
    out: dict[str, dict[str, Any]] = {}
    for kind in KINDS:
        mine = [r for r in rows if r["kind"] == kind]
        if not mine:
            continue
        s: dict[str, Any] = {"cases": len(mine)}
        for c in CRITERIA:
            judged = [r["pass"][c] for r in mine if r["pass"].get(c) is not None]
            s[c] = {"scored": len(judged), "passed": sum(judged)}
        s["all"] = {"scored": len(mine), "passed": sum(r["passed"] for r in mine)}
        s["seconds"] = sum(r["seconds"] or 0.0 for r in mine)
        out[kind] = s
    return out


def _mark(value: bool | None) -> str:
    return NONE if value is None else ("pass" if value else "**fail**")


def _ratio(row: dict[str, Any], baseline: dict[str, float] | None) -> str:
    before = None if baseline is None else baseline.get(row["name"])
    if not before or row["seconds"] is None:
        return NONE
    ratio = row["seconds"] / before
    return f"{ratio:.2f}×" + (" **slow**" if ratio > SLOWER_ALLOWED else "")


def summary_markdown(rows: list[dict[str, Any]]) -> list[str]:
    """The table of passes per kind and criterion (``passed/scored``)."""
    lines = ["| kind | cases | " + " | ".join(CRITERIA) + " | all | seconds |",
             "| --- |" + " ---: |" * (len(CRITERIA) + 3)]
    for kind, s in summary(rows).items():
        cells = [f"{s[c]['passed']}/{s[c]['scored']}" if s[c]["scored"] else NONE
                 for c in (*CRITERIA, "all")]
        lines.append(f"| {kind} | {s['cases']} | " + " | ".join(cells)
                     + f" | {s['seconds']:.1f} |")
    return lines


def thresholds_markdown() -> list[str]:
    """The table of :data:`THRESHOLDS`."""
    lines = ["| kind | accuracy, σ = 0 | accuracy, σ > 0 | completeness ≤ 3 cm | vertex |",
             "| --- | ---: | ---: | --- | ---: |"]
    for kind, t in THRESHOLDS.items():
        done = ", ".join(f"{scan} ≥ {share * 100:.0f} %" for scan, share in t.completeness)
        lines.append(f"| {kind} | ≤ {cm(t.accuracy_m)} cm | ≤ {cm(t.accuracy_noisy_m)} cm | "
                     f"{done or NONE} | "
                     f"{NONE if t.vertex_m is None else f'≤ {cm(t.vertex_m)} cm'} |")
    return lines


def cases_markdown(rows: list[dict[str, Any]], baseline: dict[str, float] | None
                   ) -> list[str]:
    """One line per case: what it is, what it measured, pass or fail per criterion."""
    slow = [] if baseline is None else ["s / baseline"]
    lines = ["| case | kind | scan | noise | cells | points | accuracy cm | completeness "
             "3 cm | vertex error cm | seconds | " + " | ".join([*slow, *CRITERIA])
             + " | notes |", "| --- | --- | --- |" + " ---: |" * (7 + len(slow))
             + " :---: |" * len(CRITERIA) + " --- |"]
    for r in rows:
        seconds = NONE if r["seconds"] is None else f"{r['seconds']:.2f}"
        notes = ", ".join(r["tags"]) + (f"; error: {r['error']}" if "error" in r else "")
        vertex = (NONE if not r["vertices_in_view"] else
                  f"{cm(r['vertex_error_m'])} ({r['vertices_in_view']})")
        lines.append(
            f"| {r['name']} | {r['kind']} | {r['scan']} | {r['noise']:g} | {r['cells']:,} | "
            f"{r['points']} | {cm(r['accuracy_m'])} | {percent(r['completeness_3cm'])} | "
            f"{vertex} | {seconds} | "
            + " | ".join([_ratio(r, baseline)] if baseline is not None else [])
            + (" | " if baseline is not None else "")
            + " | ".join(_mark(r["pass"].get(c)) for c in CRITERIA) + f" | {notes} |")
    return lines


def markdown(rows: list[dict[str, Any]], device: str, command: str, seed: int,
             baseline: dict[str, float] | None = None) -> str:
    """``zoo.md``: what this is, the summary per kind, the thresholds, every case."""
    failed = sum(not r["passed"] for r in rows)
    lines = [
        "# Scene zoo", "",
        f"Regenerate with `{command}` (seed {seed}, device: {device}). docs/zoo.md says what "
        "the zoo is and how it is scored.", "",
        f"**This is the state of the default settings on the day it was written: {failed} of "
        f"{len(rows)} cases fail a threshold.** The zoo measures issue 14's work (maps without "
        "tuning); a case that fails shows what is still missing, and the fast subset in "
        "tests/test_zoo.py marks today's failures as expected failures, so each turns into a "
        "test failure the day it is fixed.", "",
        "## Summary per kind", "",
        "Cases passing each threshold, of the cases it applies to (`passed/scored`); `all`: "
        "cases that fail none.", "", *summary_markdown(rows), "",
        "## Thresholds (issue 14, \"What must be shown\")", "", *thresholds_markdown(), "",
        "## Cases", "",
        "Accuracy: RMS distance of the profile points to the true surfaces. Completeness: share "
        "of the insonified true surface with a profile point within 3 cm. Vertex error: the "
        "worst corner or edge in view (how many in brackets) to the nearest profile point or "
        "located vertex. Seconds: the run's stages summed (the fastest of the command's "
        "`--repeat` runs)"
        + (f"; s / baseline: against the baseline's, **slow** above {SLOWER_ALLOWED}×"
           if baseline is not None else "") + ".", "", *cases_markdown(rows, baseline)]
    return "\n".join(lines) + "\n"


def read_baseline(path: str | Path) -> dict[str, float]:
    """Each case's seconds in an earlier ``zoo.json`` (one clear error if it is not one)."""
    text = read_text(path)
    try:
        data = json.loads(text)
        return {r["name"]: float(r["seconds"]) for r in data["cases"]
                if r.get("seconds") is not None}
    except (ValueError, KeyError, TypeError) as e:
        raise ClsonarError(f"{path}: not a zoo.json written by clsonar zoo ({e})") from None


def zoo_report(out: Path, *, seed: int = 0, kinds: tuple[str, ...] = KINDS,
               context=None, device: str | None = None, progress: Progress | None = None,
               command: str = "clsonar zoo --out docs/zoo", write_scenes: bool = False,
               baseline: dict[str, float] | None = None, repeat: int = 1
               ) -> list[dict[str, Any]]:
    """Run the zoo of ``seed`` (``kinds`` only; each case ``repeat`` times, the fastest
    kept) and write ``out``/zoo.md and zoo.json, and with ``write_scenes`` every scene file
    into ``out``/scenes/. Returns the rows."""
    cases = zoo(seed, kinds)
    ctx = context if context is not None else get_context(device)
    rows = run_zoo(cases, context=ctx, progress=progress, repeat=repeat)
    out.mkdir(parents=True, exist_ok=True)
    if write_scenes:
        (out / "scenes").mkdir(exist_ok=True)
        for case in cases:
            write_atomic(out / "scenes" / f"{case.name}.json",
                         (json.dumps(case.data, indent=1) + "\n").encode())
    name = device_name(ctx)
    write_atomic(out / "zoo.md", markdown(rows, name, command, seed, baseline).encode())
    report = {"clsonar": __version__, "seed": seed, "device": name, "command": command,
              "repeat": repeat,
              "thresholds": {k: {"accuracy_m": t.accuracy_m,
                                 "accuracy_noisy_m": t.accuracy_noisy_m,
                                 "completeness": dict(t.completeness), "vertex_m": t.vertex_m}
                             for k, t in THRESHOLDS.items()},
              "summary": summary(rows), "cases": rows}
    write_atomic(out / "zoo.json", (json.dumps(report, indent=1) + "\n").encode())
    return rows
