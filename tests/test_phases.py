"""The phases of a `clsonar run` process (clsonar.tools.phases, issue 16): every phase of
the command is timed, in a fresh process, and the table adds them up."""

import pytest

from clsonar.files import bundled_scenes
from clsonar.tools import phases


def test_a_process_is_timed_phase_by_phase():
    try:
        found, whole = phases.best_of(str(bundled_scenes() / "plane-2m.json"), "stages",
                                      repeat=2)
    except Exception as e:  # pragma: no cover - depends on the machine's OpenCL
        pytest.skip(f"the command cannot run here: {e}")
    worker = [n for n in found if n.startswith(phases.WORKER)]
    names = [n for n in found if n not in worker]
    assert names[0] == phases.START_UP
    forked = "scene file read, worker forked" in names  # the placement on another core
    assert names[1:5] == ["command line imports",  # the worker forked as the scene is read
                          "scene file read, worker forked" if forked else "scene file read",
                          "pipeline imports", "pyopencl, device"]
    # its seconds, not phases: the placement, then the truth the metrics score against
    assert worker == ["worker: first job", "worker: clsonar.metrics.lit_truth"] * forked
    assert [n for n in names if n.startswith("stage ")] == [
        "stage sensors", "stage echoes", "stage detection", "stage accumulation", "stage sight",
        "stage filter", "stage thinning", "stage profile", "stage metrics"]
    assert names[-4:] == ["waiting for stages.npz, raw, filtered, thin.png",
                          "report.json, stages.npz, csv", "raw, filtered, thin.png",
                          "writing the files"]
    assert all(s >= 0 for s in found.values())
    total = sum(found[n] for n in names)
    assert total <= whole + 1e-9  # each phase's best; the best process
    rows = phases.table(found, whole)
    assert rows[len(names) + 2:len(names) + 4] == [
        f"| sum of the phases | {total:.3f} | |", f"| **whole process** | **{whole:.3f}** | |"]
    assert len(rows) == len(found) + 4
