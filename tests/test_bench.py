"""``clsonar bench``: the report's contents (values, not timings)."""

import json

import pytest

from clsonar.bench import bench, loci_scene, markdown
from clsonar.cli import main
from clsonar.reproduce import bundled_scenes
from clsonar.scene import load_scene


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    pipeline, accumulation = bench(out, names=("plane-2m",), repeat=1)
    return out, pipeline, accumulation


def test_bench_writes_both_settings_and_an_identical_float64_map(report):
    out, pipeline, accumulation = report
    assert [(r.scene, r.settings) for r in pipeline] == [("plane-2m", "thesis"),
                                                          ("plane-2m", "best")]
    for r in pipeline:
        assert r.total_s == pytest.approx(sum(r.seconds.values()))
        assert r.rms_m is not None and r.rms_m < 0.01  # both beat the thesis' 0.72 cm
    (a,) = accumulation
    assert a.pixels == 1_000_000 and a.loci > 0
    assert a.float32_equal_share >= 0.999
    if "float64" in a.opencl_s:
        assert a.float64_identical is True
    assert a.tests_per_s["float32"] == pytest.approx(a.pixels * a.loci / a.opencl_s["float32"])
    saved = json.loads((out / "bench.json").read_text())
    assert saved["accumulation"][0]["loci"] == a.loci
    text = (out / "bench.md").read_text()
    assert "| plane-2m | thesis |" in text and "| plane-2m | best |" in text


def test_loci_scene_is_the_thesis_accumulation():
    scene = loci_scene(load_scene(bundled_scenes() / "room.json"))
    m = scene.mapping
    assert (m.mode, m.weight, m.combine, m.reciprocal) == ("loci", "unit", "sum", "both")


def test_markdown_of_nothing_is_still_a_report():
    assert markdown([], [], "cpu", "clsonar bench --out x").startswith("# Benchmark")


def test_bench_refuses_an_unknown_scene(tmp_path, capsys):
    assert main(["bench", "--out", str(tmp_path / "b"), "--scenes", "nope"]) == 2
    assert "nope" in capsys.readouterr().err
    assert not (tmp_path / "b").exists()
