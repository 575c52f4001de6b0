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
    names = list(found)
    assert names[0] == phases.START_UP
    assert names[1:4] == ["command line imports", "pipeline imports (scipy)", "pyopencl, device"]
    assert [n for n in names if n.startswith("stage ")] == [
        "stage sensors", "stage echoes", "stage detection", "stage accumulation", "stage sight",
        "stage filter", "stage thinning", "stage profile", "stage metrics"]
    assert names[-3:] == ["report.json, stages.npz, csv", "raw, filtered, thin.png",
                          "writing the files"]
    assert all(s >= 0 for s in found.values())
    assert sum(found.values()) <= whole + 1e-9  # each phase's best; the best process
    rows = phases.table(found, whole)
    assert rows[-2:] == [f"| sum of the phases | {sum(found.values()):.3f} | |",
                         f"| **whole process** | **{whole:.3f}** | |"]
    assert len(rows) == len(found) + 4
