"""``clsonar stress``: the numerical-stability property suite at scale on the user's device.

Runs ``count`` cases of the generators of :mod:`clsonar.tools.stability` — echo families and map
families in turn, seeds 0, 1, 2, … — on one OpenCL device, the float32 kernels against the
float64 references, and writes the worst error found per property and the bounds they are
held to into ``stress.md`` and ``stress.json`` (atomically). One case in ``work_group_every``
also reruns the kernels with other work-group sizes. The ``million`` map family draws
:data:`clsonar.tools.stability.MILLION` loci on one map; the ``many`` echo family one group of
``many`` transducers.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

from ..files import write_atomic
from . import stability
from .progress import Progress
from .stability import BOUNDS, ECHO_FAMILIES, MAP_FAMILIES, SIGNAL_FAMILIES, Findings

#: Cases of the ``million`` family run: one in this many map cases at most (they are slow).
MILLION_EVERY = 200


def schedule(count: int) -> list[tuple[str, str, int]]:
    """``count`` cases ``(kind, family, seed)``: echo, signal and map families in turn, each
    family's seeds counting up; ``million`` maps are capped to one per :data:`MILLION_EVERY`
    map cases (at least one)."""
    cases: list[tuple[str, str, int]] = []
    seeds: dict[tuple[str, str], int] = {}
    families = ([("echo", f) for f in ECHO_FAMILIES] + [("signal", f) for f in SIGNAL_FAMILIES]
                + [("map", f) for f in MAP_FAMILIES])
    i = 0
    while len(cases) < count:
        kind, family = families[i % len(families)]
        i += 1
        if family == "million":
            n_maps = sum(1 for c in cases if c[0] == "map")
            if seeds.get((kind, family), 0) > n_maps // MILLION_EVERY:
                continue
        seed = seeds.get((kind, family), 0)
        seeds[kind, family] = seed + 1
        cases.append((kind, family, seed))
    return cases


def run_stress(count: int, context, *, many: int = 200, million: int | None = None,
               work_group_every: int = 25,
               progress: Progress | None = None) -> tuple[dict[str, Findings], float]:
    """Run :func:`schedule` (``count``) on ``context``; returns findings per
    ``kind family`` and the seconds taken."""
    million = stability.MILLION if million is None else million
    start = time.perf_counter()
    per_family: dict[str, Findings] = {}
    plan = schedule(count)
    for n, (kind, family, seed) in enumerate(plan):
        if progress:
            progress(n + 1, len(plan), f"{kind} {family} seed={seed}")
        groups = n % work_group_every == 0
        if kind == "echo":
            f = stability.check_echo_case(family, seed, context, many=many, work_groups=groups)
        elif kind == "signal":
            f = stability.check_signal_case(family, seed, context, work_groups=groups)
        else:
            f = stability.check_map_case(family, seed, context, million=million,
                                         work_groups=groups)
        per_family.setdefault(f"{kind} {family}", Findings()).merge(f)
    return per_family, time.perf_counter() - start


def total(per_family: dict[str, Findings]) -> Findings:
    """All families' findings merged."""
    out = Findings()
    for f in per_family.values():
        out.merge(f)
    return out


def passed(f: Findings) -> bool:
    """Whether ``f`` holds every bound (:data:`clsonar.tools.stability.BOUNDS`)."""
    return (not f.failures and f.nonfinite == 0
            and f.differing <= BOUNDS["map_differing_fraction"] * max(f.pixels, 1))


def _us(seconds: float) -> str:
    return f"{seconds * 1e6:.4f} µs"


def markdown(per_family: dict[str, Findings], device: str, seconds: float,
             command: str) -> str:
    """The report: bounds, totals, then one row per family."""
    t = total(per_family)
    fraction = t.differing / max(t.pixels, 1)
    lines = [
        "# Numerical stability: float32 kernels against float64",
        "",
        f"Regenerate with `{command}` ({t.cases} cases on {device}, {seconds:.0f} s).",
        "The generators and the judges are `clsonar/tools/stability/`; the CI property suite",
        "(`tests/test_stability.py`) runs the same generators on fewer cases.",
        "",
        f"**Result: {'all bounds hold' if passed(t) else 'BOUNDS VIOLATED'}.**",
        "",
        "| property | bound | worst found |",
        "| --- | --- | --- |",
        f"| NaN or Inf in any echo table or map | none | {t.nonfinite} cases |",
        f"| float32 − float64 time of flight, matched echoes and detections ({t.echoes}) | "
        f"≤ 1 µs | "
        f"{_us(t.tof_max_s)} ({t.tof_worst or 'n/a'}) |",
        f"| echo or detection in one list only, float64 decision flips under a float32-sized "
        f"nudge | "
        f"allowed | {t.unmatched_edge} |",
        f"| echo in one table only, weaker than {BOUNDS['weak_echo']:.0%} of A0 | allowed | "
        f"{t.unmatched_weak} |",
        f"| echo or detection in one list only, otherwise | none | {t.unmatched_other} |",
        f"| float32 − float64 amplitude, relative (reported, no bound) | — | "
        f"{t.amp_max_rel:.3g} ({t.amp_worst or 'n/a'}) |",
        f"| map pixels differing ({t.pixels} pixels) | ≤ 0.1 % | {t.differing} "
        f"({fraction:.5%}); worst map {t.worst_fraction:.4%} ({t.worst_fraction_case or 'n/a'}) |",
        f"| differing pixels not on a band or beam edge | none | {t.differing_off_edge} |",
        f"| other work-group sizes give another result | never | {t.work_group_mismatches} |",
        "",
        "## Per family",
        "",
        "| family | cases | NaN/Inf | echoes or detections | max Δτ | in one list only "
        "(edge / weak / other) "
        "| pixels | differing (off edge) | work-group mismatches |",
        "| --- | ---: | ---: | ---: | ---: | --- | ---: | --- | ---: |",
    ]
    for name, f in per_family.items():
        lines.append(
            f"| {name} | {f.cases} | {f.nonfinite} | {f.echoes} | "
            f"{_us(f.tof_max_s) if f.echoes else '—'} | "
            f"{f.unmatched_edge} / {f.unmatched_weak} / {f.unmatched_other} | {f.pixels} | "
            f"{f.differing} ({f.differing_off_edge}) | {f.work_group_mismatches} |")
    if t.failures:
        lines += ["", "## Failures", ""] + [f"- {x}" for x in t.failures[:50]]
    lines += ["", "## What is checked", "", DEFINITIONS, "", CI_AND_FUZZ]
    return "\n".join(lines) + "\n"


DEFINITIONS = f"""\
- **Echoes** (`kernels/echoes.cl`, float32) against `echoes.reference_echoes` (NumPy
  float64), rows matched on (tx, rx, kind, order, element). A matched pair's times of flight
  must agree within {BOUNDS['tof_abs_s'] * 1e6:g} µs. An echo present in one table only must
  be a knife-edge decision: the float64 reference itself gains or loses it when every
  transducer moves and turns by {BOUNDS['edge_roundings']} float32 roundings of the scene's
  local coordinates (six random nudges), or it is weaker than {BOUNDS['weak_echo']:.0%} of
  the transmitted amplitude A0 (a beam edge or grazing incidence).
- **Detections** (`kernels/signals.cl`, float32) against `signals.detect_reference` (float64)
  on the float64 echoes of the echo families but `many`, with a random detector (threshold or
  envelope) and noise level: detections of one pair matched by nearest time, |Δτ| ≤
  {BOUNDS['tof_abs_s'] * 1e6:g} µs; one in one list only must flip in the float64
  reference when the echoes' amplitudes and times move by {BOUNDS['edge_roundings']}
  float32 roundings (a threshold crossing or a peak merge decided by rounding).
- **Maps** (`kernels/accumulate.cl`, float32) against `mapping.accumulate_reference` /
  `backproject_reference` (float64; for the `million` family the float64 kernel, which
  tests/test_mapping.py shows is bit-identical to the reference). A pixel differs when its
  values disagree by more than float32 summation rounding (√n·64ε relative, at least
  {BOUNDS['value_rtol']:g}; back-projection adds each envelope's slope times the delay's
  float32 error; beam weights add the beam's slope times each direction's float32 angle
  error, ≈ 2ε·S/|d|, which grows near a focus). Every differing pixel must lie, for some
  locus, within
  {BOUNDS['edge_roundings']} float32 roundings of its band edge (| |p−T|+|p−R| − c·τ | =
  band/2) or of a beam edge (axis·d = 0, (axis×d)² = cut·|d|²), computed in float64; at
  most {BOUNDS['map_differing_fraction']:.1%} of all pixels may differ.
- **Work groups**: one case in 25 is rerun with echo work groups of
  {', '.join(map(str, stability.ALT_ECHO_GROUPS))}, detection work groups of
  {', '.join(map(str, stability.ALT_SIGNAL_GROUPS))}, and map launches (pixels per item,
  dense kernel's group, tiled kernel's tile) {', '.join(map(str, stability.ALT_MAP_LAUNCH))},
  and its loci map drawn by the dense kernel instead of the tiled one; the outputs must be
  bit-identical.
- **Families**: echo — {', '.join(ECHO_FAMILIES)}; signal — {', '.join(SIGNAL_FAMILIES)};
  map — {', '.join(MAP_FAMILIES)}
  (clsonar/tools/stability/ describes each).
"""


CI_AND_FUZZ = f"""\
## In CI

`tests/test_stability.py` (PoCL's CPU device, hypothesis' derandomized `ci` profile) holds
every case to the same bounds: no NaN/Inf, |Δτ| ≤ {BOUNDS['tof_abs_s'] * 1e6:g} µs, no echo in
one table only unless on a knife edge or weaker than {BOUNDS['weak_echo']:.0%} of A0, no
differing pixel off an edge, at most {BOUNDS['map_differing_fraction']:.1%} of a map's pixels
differing (maps of ≥ 10⁴ pixels), and bit-identical results under other work-group sizes. It
runs 48 echo, 24 detection and 40 map cases drawn over every family, the `million` family
once with {stability.MILLION:,} loci, and six cases under other work-group sizes (about
15 s).

## Hostile scene files

`python -m clsonar.tools.fuzz --count 100000 --seed 0` feeds mutated bundled scenes (random bytes,
truncated JSON, deep nesting, huge arrays, a wrong type at a random key, NaN/Inf at a random
number, grids too large for memory, invalid UTF-8, byte edits) through the loader, the
pipeline's memory check and the sensor placement, and each refused one through `clsonar run
FILE --out DIR` in-process: one `clsonar: error:` line, exit status 2, DIR never created,
no traceback or warning, at most 1 s of CPU per input. Its last result is in
[fuzz.md](fuzz.md); `tests/test_fuzz.py` runs 1500 inputs in CI.
"""


def report_json(per_family: dict[str, Findings], device: str, seconds: float,
                command: str) -> str:
    t = total(per_family)
    data = {
        "command": command, "device": device, "seconds": round(seconds, 1),
        "passed": passed(t), "bounds": BOUNDS,
        "total": dataclasses.asdict(t),
        "families": {k: dataclasses.asdict(v) for k, v in per_family.items()},
    }
    return json.dumps(data, indent=2, ensure_ascii=False) + "\n"


def stress(out: Path, count: int, *, device: str | None = None, many: int = 200,
           progress: Progress | None = None, command: str = "clsonar stress") -> Findings:
    """Run ``count`` cases and write ``out/stress.md`` and ``out/stress.json`` (or, when
    ``out`` ends in ``.md``, that file and the ``.json`` beside it); returns the merged
    findings."""
    from ..opencl import get_context

    context = get_context(device)
    per_family, seconds = run_stress(count, context, many=many, progress=progress)
    name = context.devices[0].name.strip()
    md = out if out.suffix == ".md" else out / "stress.md"
    md.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(md, markdown(per_family, name, seconds, command).encode())
    write_atomic(md.with_suffix(".json"),
                 report_json(per_family, name, seconds, command).encode())
    return total(per_family)


__all__ = ["markdown", "passed", "report_json", "run_stress", "schedule", "stress", "total"]
