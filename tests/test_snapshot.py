"""Snapshots of runs (clsonar.tools.snapshot): the same code gives no difference; a changed
metric or map is named."""

import json
import shutil
from pathlib import Path

import numpy as np

from clsonar.tools import snapshot

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def test_snapshots_of_the_same_code_agree_and_a_change_is_named(tmp_path):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    for name in ("plane-2m", "edge-1m"):
        shutil.copy(SCENES / f"{name}.json", scenes)
    names = snapshot.save(tmp_path / "a", scenes)
    assert names == ["edge-1m-file", "edge-1m-thesis", "plane-2m-file", "plane-2m-thesis"]
    snapshot.save(tmp_path / "b", scenes)
    assert snapshot.compare(tmp_path / "a", tmp_path / "b") == []
    report = tmp_path / "b" / "plane-2m-file.json"
    data = json.loads(report.read_text())
    data["metrics"]["points"] += 1
    report.write_text(json.dumps(data))
    arrays = dict(np.load(tmp_path / "b" / "edge-1m-thesis.npz"))
    arrays["thin"] = ~arrays["thin"]
    np.savez(tmp_path / "b" / "edge-1m-thesis.npz", **arrays)
    found = snapshot.compare(tmp_path / "a", tmp_path / "b")
    assert found[0] == "edge-1m-thesis: thin differs"
    assert found[1].startswith("plane-2m-file: report.metrics: points ")
    assert snapshot.main(["compare", str(tmp_path / "a"), str(tmp_path / "b")]) == 1
