"""Large but valid scenes (issue 19, clsonar.tools.corpus), each run as a user runs it, in
its own process: mapped within a fixed peak memory, or refused in one line before any work
(exit 2, nothing written)."""

from __future__ import annotations

import json

import pytest

from clsonar.tools import corpus

#: Peak resident memory every mapped scene of the corpus stays under (bytes): the process
#: with its interpreter, NumPy and the OpenCL runtime (about 150 MB) included.
PEAK_BUDGET = 1_000_000_000

MAPPED = ["outline-45k", "sinusoid-1M", "floor-20-order-4"]
REFUSED = {"outline-45k-order-2": "echo.max_order", "array-10000": "sensors.transducers"}


def _run(tmp_path, name: str) -> corpus.Outcome:
    arrays = [int(name.split("-")[1])] if name.startswith("array-") else []
    names = [] if arrays else [name]
    (path,) = corpus.write_scenes(tmp_path / "scenes", names, arrays)
    return corpus.run_scene(path, tmp_path / "out")


@pytest.mark.parametrize("name", MAPPED)
def test_a_large_valid_scene_maps_within_its_memory(tmp_path, name):
    r = _run(tmp_path, name)
    assert r.status == 0 and r.lines == 0, r.message
    assert r.peak_bytes <= PEAK_BUDGET
    assert r.profile_points and r.accuracy_m is not None and r.accuracy_m <= 0.01
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["cost"]["peak_bytes"] <= PEAK_BUDGET


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_a_scene_beyond_the_limits_is_refused_in_one_line_before_any_work(tmp_path, name):
    r = _run(tmp_path, name)
    assert (r.status, r.lines) == (2, 1), r.message
    assert r.message.startswith("clsonar: error: ") and REFUSED[name] in r.message
    assert not (tmp_path / "out").exists()
    assert r.peak_bytes <= 300_000_000  # no echo computed


def test_the_corpus_scenes_load_as_files(tmp_path):
    """Every scene of the corpus is a valid file (format v1), the run's refusal included
    (its mirror sequences are counted room by room, where they are built); the array of
    10,000 elements, 10⁸ pairs, is refused by the loader too."""
    from clsonar.errors import ClsonarError
    from clsonar.scene import load_scene

    for path in corpus.write_scenes(tmp_path, list(corpus.SCENES), [300]):
        assert load_scene(path).name == path.stem
    (big,) = corpus.write_scenes(tmp_path, [], [10_000])
    with pytest.raises(ClsonarError, match=r"sensors\.transducers"):
        load_scene(big)
