"""Fuzzing the scene loader and ``clsonar run``'s handling of bad input (docs/design.md: "Bad
input … one clear line on stderr naming the file and the offending key, exit status 2, no
traceback, and nothing written to ``--out``. Never a crash or a hang.").

Hostile inputs are mutations of the bundled scenes (:func:`hostile_input`): random bytes,
truncated JSON, deep nesting, huge arrays, a wrong type at a random key, NaN/Inf (and
overflowing literals) at a random number, grids too large for memory, invalid UTF-8, and
random byte edits. Each input is written to a file and goes through what ``clsonar run`` does
before any heavy work: :func:`clsonar.scene.load_scene`, the pipeline's memory check
(:func:`clsonar.mapping.check_map_memory`) and the sensor placement. An input refused there
must raise :class:`~clsonar.errors.ClsonarError` only; it is then also run through the
command line in-process (``clsonar run FILE --out DIR``), which must print exactly one line
``clsonar: error: …`` on stderr, return 2 and leave DIR absent. Anything else is a finding:
another exception (a traceback), a Python warning, more than ``limit_s`` seconds of this
process' CPU time for one input (both steps; the machine may be shared, so wall time would
count other programs), still running after 10·``limit_s`` s of wall time (a hang), or a wrong
exit.
Inputs the loader accepts are counted, not run (a valid scene may legitimately take long).

Run: ``python -m clsonar.tools.fuzz --count 100000 [--seed 0] [--limit-s 1]`` (docs/stability.md).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import random
import resource
import shutil
import signal
import tempfile
import time
import traceback
import warnings
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from ..errors import ClsonarError
from .progress import Progress, ProgressLine

MUTATIONS = ("bytes", "truncate", "nesting", "huge-array", "wrong-type", "nonfinite",
             "huge-grid", "utf8", "edit")

WRONG_VALUES: tuple[Any, ...] = (None, True, False, "x", "", 0, -1, 1, 2**64, -(2**70), 1e308,
                                 -1e308, 5e-324, 0.5, [], {}, [1], [[1, 2]], {"a": 1},
                                 [None, None], "NaN", [1e308, 1e308])
NONFINITE = ("NaN", "Infinity", "-Infinity", "1e999", "-1e999", "nan", "inf")

#: Seconds of CPU an input may take (``--limit-s``).
LIMIT_S = 1.0


def seed_texts() -> list[str]:
    """The bundled scenes' JSON texts, the starting points of every mutation."""
    from ..files import bundled_scenes

    return [p.read_text(encoding="utf-8") for p in sorted(bundled_scenes().glob("*.json"))]


def _paths(value: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path in a parsed JSON value (the root excluded)."""
    out = []
    items = (value.items() if isinstance(value, dict)
             else enumerate(value) if isinstance(value, list) else ())
    for k, v in items:
        out.append((*prefix, k))
        out.extend(_paths(v, (*prefix, k)))
    return out


def _set(root: Any, path: tuple, value: Any) -> Any:
    if not path:
        return value
    node = root
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return root


def _numbers(value: Any, prefix: tuple = ()) -> list[tuple]:
    return [p for p in _paths(value, prefix) if _is_number(_get(value, p))]


def _get(root: Any, path: tuple) -> Any:
    for k in path:
        root = root[k]
    return root


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _marker_json(data: Any, path: tuple, literal: str) -> str:
    """JSON text of ``data`` with the value at ``path`` written as ``literal``."""
    marker = "__fuzz_marker__"
    return json.dumps(_set(data, path, marker)).replace(f'"{marker}"', literal, 1)


def hostile_input(rng: random.Random, seeds: list[str]) -> tuple[str, bytes]:
    """One hostile input: ``(mutation, bytes)``."""
    kind = rng.choice(MUTATIONS)
    text = rng.choice(seeds)
    data = json.loads(text)
    paths = _paths(data)
    if kind == "bytes":
        return kind, bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 600)))
    if kind == "truncate":
        return kind, text.encode()[:rng.randrange(0, len(text))]
    if kind == "nesting":
        depth = rng.choice([17, 50, 1000, 100_000, 1_000_000])
        if rng.random() < 0.5:
            nest = "[" * depth + "]" * depth
        else:
            nest = '{"a":' * depth + "1" + "}" * depth
        if rng.random() < 0.3:
            nest = nest[: len(nest) // 2]  # unbalanced too
        return kind, _marker_json(data, rng.choice(paths), nest).encode()
    if kind == "huge-array":
        n = rng.choice([1000, 24_000, 49_000, 199_000, 400_000])  # around the loader's limits
        item = rng.choice(["0", "1.5", "[0,0]", '{"type":"circle","center":[1,1],"radius":0.1}',
                           '{"position":[1,1],"heading_deg":0}'])
        huge = "[" + ",".join([item] * n) + "]"
        return kind, _marker_json(data, rng.choice(paths), huge).encode()
    if kind == "wrong-type":
        return kind, json.dumps(_set(data, rng.choice(paths), rng.choice(WRONG_VALUES))).encode()
    if kind == "nonfinite":
        numbers = _numbers(data)
        return kind, _marker_json(data, rng.choice(numbers), rng.choice(NONFINITE)).encode()
    if kind == "huge-grid":
        x0 = rng.choice([0.0, -1e9, 1e12])
        size = rng.choice([1e4, 1e6, 1e12, 1e300])
        data["extent"] = [x0, x0, x0 + size, x0 + size * rng.choice([1.0, 1e-3])]
        data["cell"] = rng.choice([1e-3, 1e-6, 1e-12, 5e-324, 0.01])
        return kind, json.dumps(data).encode()
    if kind == "utf8":
        raw = bytearray(text.encode())
        raw[rng.randrange(len(raw))] = rng.choice([0x80, 0xC3, 0xFF, 0xFE, 0x00])
        return kind, (b"\xef\xbb\xbf" if rng.random() < 0.3 else b"") + bytes(raw)
    raw = bytearray(text.encode())
    for _ in range(rng.randrange(1, 8)):
        i = rng.randrange(len(raw))
        op = rng.random()
        if op < 0.4:
            raw[i] = rng.choice(b'{}[]",:0123456789-.eE ntfaluxNI')
        elif op < 0.7:
            del raw[i]
        else:
            raw.insert(i, rng.choice(b'{}[]",:0-.eE9'))
    return "edit", bytes(raw)


@dataclass
class FuzzReport:
    """What a fuzzing run found."""

    inputs: int = 0
    refused: int = 0
    accepted: int = 0
    cli_checked: int = 0
    by_mutation: Counter[str] = field(default_factory=Counter)
    slowest_s: float = 0.0
    slowest: str = ""
    findings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    peak_rss_mb: float = 0.0

    def summary(self) -> str:
        return (f"{self.inputs} inputs ({self.refused} refused with one error line, "
                f"{self.accepted} accepted as valid scenes; {self.cli_checked} also through "
                f"`clsonar run`), {len(self.findings)} findings, slowest {self.slowest_s:.3f} s "
                f"({self.slowest}), {self.seconds:.0f} s, peak memory {self.peak_rss_mb:.0f} MB")


class _Timeout(Exception):
    pass


@contextlib.contextmanager
def _alarm(seconds: float):
    """Raise :class:`_Timeout` after ``seconds`` (a hang guard; main thread only)."""
    def ring(signum, frame):
        raise _Timeout()

    old = signal.signal(signal.SIGALRM, ring)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def preflight(path: str, device=None) -> None:
    """What ``clsonar run`` does with a scene file before the heavy stages: load and
    validate it, refuse a grid it cannot hold, place the sensors."""
    from .. import mapping
    from ..geometry import build_geometry
    from ..pipeline import PIPELINE_BYTES_PER_CELL
    from ..scene import load_scene
    from ..sensors import place_sensors

    scene = load_scene(path)
    mapping.check_map_memory(scene, scene.mapping.precision, device,
                             host_bytes_per_cell=PIPELINE_BYTES_PER_CELL)
    place_sensors(scene, build_geometry(scene))


def run_cli(path: str, out: str) -> tuple[int, str]:
    """``clsonar run path --out out`` in-process: (exit status, stderr)."""
    from ..cli import main

    err, sink = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(sink):
        rc = main(["run", path, "--out", out, "-q"])
    return rc, err.getvalue()


def _preflight_input(path: str, device, limit_s: float, label: str,
                     report: FuzzReport) -> bool | None:
    """:func:`preflight` on one input, counted in ``report``: True if it was refused with a
    :class:`~clsonar.errors.ClsonarError`, False if accepted, None if it was a finding."""
    try:
        with _alarm(10 * limit_s), warnings.catch_warnings():
            warnings.simplefilter("error")  # a warning is a finding too
            preflight(path, device)
    except ClsonarError as e:
        report.refused += 1
        if "\n" in str(e):
            report.findings.append(f"{label}: error message of several lines")
        return True
    except _Timeout:
        report.findings.append(f"{label}: still running after {10 * limit_s:g} s")
        return None
    except Exception:  # a finding: anything but ClsonarError
        report.findings.append(f"{label}: {traceback.format_exc(limit=-2).strip()}")
        return None
    report.accepted += 1
    return False


def _cli_input(path: str, out: str, limit_s: float, label: str, report: FuzzReport) -> bool:
    """A refused input through ``clsonar run`` in-process: a finding unless it prints one
    ``clsonar: error:`` line, returns 2 and leaves ``out`` absent. False if it hung or
    raised."""
    report.cli_checked += 1
    try:
        with _alarm(10 * limit_s), warnings.catch_warnings():
            warnings.simplefilter("error")
            rc, err = run_cli(path, out)
    except _Timeout:
        report.findings.append(f"{label}: clsonar run still running")
        return False
    except BaseException:  # a traceback is the finding
        report.findings.append(f"{label}: clsonar run: "
                               f"{traceback.format_exc(limit=-2).strip()}")
        return False
    lines = err.splitlines()
    if rc != 2 or len(lines) != 1 or not lines[0].startswith("clsonar: error: "):
        report.findings.append(f"{label}: clsonar run exit {rc}, stderr {err!r:.300}")
    if os.path.exists(out):
        report.findings.append(f"{label}: clsonar run wrote {out}")
        shutil.rmtree(out, ignore_errors=True)
    return True


def _timed(report: FuzzReport, label: str, elapsed: float, limit_s: float) -> None:
    """Keep the slowest input; more than ``limit_s`` seconds of CPU is a finding."""
    if elapsed > report.slowest_s:
        report.slowest_s, report.slowest = elapsed, label
    if elapsed > limit_s:
        report.findings.append(f"{label}: took {elapsed:.2f} s > {limit_s:g} s")


def fuzz(count: int, seed: int = 0, *, limit_s: float = LIMIT_S, device=None,
         progress: Progress | None = None) -> FuzzReport:
    """Feed ``count`` hostile inputs (seeded by ``seed``) through :func:`preflight` and, for
    the refused ones, through ``clsonar run``; collect findings (see the module docstring)."""
    rng = random.Random(seed)
    seeds = seed_texts()
    report = FuzzReport()
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="clsonar-fuzz-") as tmp:
        path = os.path.join(tmp, "scene.json")
        out = os.path.join(tmp, "out")
        for i in range(count):
            if progress and i % 1000 == 0:
                progress(i, count, "inputs")
            kind, data = hostile_input(rng, seeds)
            report.inputs += 1
            report.by_mutation[kind] += 1
            with open(path, "wb") as f:
                f.write(data)
            label = f"input {i} ({kind}, seed {seed})"
            t0 = time.process_time()  # this process' own work: other load does not count
            refused = _preflight_input(path, device, limit_s, label, report)
            if refused is None or (refused and not _cli_input(path, out, limit_s, label,
                                                              report)):
                continue
            _timed(report, label, time.process_time() - t0, limit_s)
    report.seconds = time.perf_counter() - start
    report.peak_rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return report


def main(argv: list[str] | None = None) -> int:
    """``python -m clsonar.tools.fuzz``: exit status 0 when nothing was found, 1 otherwise."""
    p = argparse.ArgumentParser(prog="python -m clsonar.tools.fuzz",
                                description="Fuzz the scene loader and clsonar run's "
                                            "handling of bad input.")
    p.add_argument("--count", type=int, default=10_000,
                   help="hostile inputs to try (default 10000)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the mutations: the same seed, the same inputs (default 0)")
    p.add_argument("--limit-s", type=float, default=LIMIT_S,
                   help=f"seconds an input may take (default {LIMIT_S:g})")
    p.add_argument("--out", metavar="FILE.md", help="also write the result as markdown")
    p.add_argument("--device", help="OpenCL device for the memory check (default: none, "
                                    "this machine's memory only)")
    args = p.parse_args(argv)
    device = None
    if args.device:
        from ..opencl import get_context

        device = get_context(args.device).devices[0]
    line = ProgressLine()
    try:
        report = fuzz(args.count, args.seed, limit_s=args.limit_s, device=device,
                      progress=line)
    finally:
        line.done()
    print(report.summary())
    print("by mutation: " + ", ".join(f"{k} {v}" for k, v in sorted(report.by_mutation.items())))
    for f in report.findings[:20]:
        print("FINDING", f)
    if args.out:
        from ..files import write_atomic

        limit = f" --limit-s {args.limit_s:g}" if args.limit_s != LIMIT_S else ""
        command = (f"python -m clsonar.tools.fuzz --count {args.count} --seed {args.seed}"
                   f"{limit} --out {args.out}")
        write_atomic(args.out, markdown(report, command).encode())
    return 0 if not report.findings else 1


def markdown(report: FuzzReport, command: str) -> str:
    """The result of a fuzzing run as a short markdown page."""
    lines = ["# Fuzzing the scene loader", "",
             f"Regenerate with `{command}` (clsonar/tools/fuzz.py describes the mutations and "
             "what counts as a finding).", "",
             f"**{report.summary()}.**", "",
             "| mutation | inputs |", "| --- | ---: |"]
    lines += [f"| {k} | {v} |" for k, v in sorted(report.by_mutation.items())]
    lines += ["", "## Findings", ""]
    lines += [f"- {f}" for f in report.findings[:100]] or ["None."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())


__all__ = ["MUTATIONS", "FuzzReport", "fuzz", "hostile_input", "main", "markdown", "preflight",
           "run_cli"]
