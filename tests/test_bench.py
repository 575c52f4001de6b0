"""``clsonar bench``: the report's contents (values, not timings)."""

import json

import pytest

from clsonar.cli import main
from clsonar.files import bundled_scenes
from clsonar.scene import load_scene
from clsonar.tools.bench import bench, loci_scene, markdown


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    report = bench(out, names=("plane-2m",), repeat=1, floors=(10.0,))
    return out, report.pipeline, report.accumulation, report


def test_bench_writes_both_settings_and_an_identical_float64_map(report):
    out, pipeline, accumulation, _ = report
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
    assert a.tiled_identical and 0 < a.tiles_skipped < a.tiles_total
    assert 0 < a.tiled_tests < a.pixels * a.loci
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


def test_bench_skipping_keeps_the_output_and_knobs_are_compared(report):
    out, _, _, full = report
    assert [r.settings for r in full.skips] == ["thesis", "best"]
    for r in full.skips:
        assert r.identical and r.counts["pairs_skipped_empty"] > 0
    settings = [r.setting for r in full.tradeoff]
    assert settings[:3] == ["thesis", "thesis, 2 cm", "ours"] and "ours, 5 cm" in settings
    assert any(r.pareto for r in full.tradeoff)
    ours = next(r for r in full.tradeoff if r.setting == "ours")
    thesis = next(r for r in full.tradeoff if r.setting == "thesis")
    assert ours.accuracy_m < thesis.accuracy_m
    assert (out / "tradeoff.png").read_bytes().startswith(b"\x89PNG")
    text = (out / "bench.md").read_text()
    assert "## What skipping saves" in text and "## Run time against error: the knobs" in text


def test_pareto_front_and_settings_that_beat_the_thesis():
    from clsonar.tools.tradeoff import TradeoffRow, beats_thesis, pareto

    def row(scene, setting, t, err):
        return TradeoffRow(scene, setting, t, err, None, None)

    rows = pareto([row("a", "thesis", 1.0, 0.05), row("a", "ours", 0.5, 0.01),
                   row("a", "ours, 2 cm", 0.4, 0.02), row("a", "ours, 5 cm", 0.6, None),
                   row("b", "thesis", 1.0, None), row("b", "ours", 0.9, 0.03),
                   row("b", "ours, 2 cm", 1.1, 0.01)])
    assert [r.pareto for r in rows] == [False, True, True, False, False, True, True]
    assert beats_thesis(rows) == ["ours"]


def test_bench_maps_a_floor_room_by_room_in_its_own_process(report):
    out, _, _, full = report
    (f,) = full.floors
    assert (f.scene, f.cells, f.rooms) == ("floor-10m", 1_000_000, 4)
    assert f.vertices_found == "16/16" and f.accuracy_m < 0.005
    assert 0 < f.mosaic_mb < f.peak_rss_mb and f.total_s == pytest.approx(sum(f.seconds.values()))
    assert "| floor-10m | 1,000,000 | 4 |" in (out / "bench.md").read_text()


def test_bench_times_echoes_and_detection_against_numpy(report):
    out, _, _, full = report
    (r,) = full.stages
    assert r.scene == "plane-2m" and r.pairs == 900
    assert r.echoes_matched == 1.0 and r.unmatched_max_amplitude == 0.0 and r.detections_same
    assert r.echoes_speedup == pytest.approx(r.echoes_numpy_s / r.echoes_opencl_s)
    assert "## Echoes and detection: OpenCL against NumPy float64" in (out / "bench.md").read_text()


def test_throughput_section_counts_the_sweeps_runs_and_every_png_choice(tmp_path):
    """Issue 16: the sweep's runs per second (its runs counted, not timed) and the whole
    command as a process with each ``--png``, written into bench.md."""
    from clsonar.files import PNG_CHOICES
    from clsonar.opencl import get_context
    from clsonar.tools.throughput import bench_process, bench_sweep, throughput_markdown

    scene = load_scene(bundled_scenes() / "plane-2m.json")
    sweep = bench_sweep(scene, get_context(), seeds=2, noises=(0.0, 0.6))
    assert [(r.noise_std, r.runs) for r in sweep] == [(0.0, 2), (0.6, 2)]
    assert all(r.runs_per_s == pytest.approx(r.runs / r.seconds) for r in sweep)
    assert all(r.computed_runs_per_s > 0 for r in sweep)  # every stage computed, measured
    process = bench_process(bundled_scenes() / "plane-2m.json", repeat=1)
    assert [r.png for r in process] == list(PNG_CHOICES)
    text = "\n".join(throughput_markdown("plane-2m", sweep, process))
    assert "## End to end: `plane-2m`" in text and "| stages |" in text
    assert "every stage computed" in text


def test_the_floors_table_gives_the_wall_time_and_every_process_memory():
    """A floor mapped by two worker processes: its wall time beside the stages' seconds
    summed over the rooms (about twice it), and the peak memory of the parent plus each
    worker's."""
    from clsonar.tools.bench import floors_markdown
    from clsonar.tools.floors import FloorRow

    row = FloorRow("floor-100m", 10**8, 400, 99200, 793600, {"accumulation": 40.0}, 70.0,
                   1152.0, 954.0, 0.0006, 0.999, "1600/1600", wall_s=35.8, workers=2,
                   workers_peak_rss_mb=178.0)
    table = "\n".join(floors_markdown([row]))
    assert "| wall s | workers | stages s |" in table
    line = next(x for x in table.splitlines() if x.startswith("| floor-100m"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert cells[5:8] == ["35.8", "2", "70.0"]
    assert "1,508 MB" in cells
