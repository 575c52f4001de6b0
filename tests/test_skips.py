"""Work the scene does not need is skipped without changing the result (issue "Fast"),
and the content-keyed stage cache reuses exactly the stages whose inputs are unchanged."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import clsonar
from clsonar import post
from clsonar.cli import main
from clsonar.opencl import get_context
from clsonar.pipeline import SKIP_NAMES, Skips, StageCache, apply_preset, rerun_post
from clsonar.scene import PostSettings

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _same(a, b) -> None:
    for name in ("raw", "filtered", "occupied", "thin"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.profile.points, b.profile.points)
    assert a.metrics == b.metrics


@pytest.mark.parametrize(("name", "preset"), [("cylinder-2.1m", None), ("corner-9m", "thesis"),
                                              ("sinusoid-4m", None), ("room-l", None)])
def test_skipping_changes_nothing_but_the_counts(name, preset):
    scene = clsonar.load_scene(SCENES / f"{name}.json")
    ctx = get_context()
    fast = clsonar.run(scene, context=ctx, preset=preset)
    slow = clsonar.run(scene, context=ctx, preset=preset, skips=Skips.none())
    _same(fast, slow)
    assert slow.counts["pairs_skipped_empty"] == slow.counts["pairs_skipped_silent"] == 0
    assert slow.counts["cells_post_processed"] == slow.counts["map_cells"]
    assert fast.counts["cells_post_processed"] < fast.counts["map_cells"]
    if name != "room-l":  # every beam of a closed room meets a wall
        assert fast.counts["pairs_skipped_empty"] > 0
    assert fast.counts["pairs_skipped_silent"] > 0


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.float64, st.tuples(st.integers(1, 40), st.integers(1, 40)),
                  elements=st.sampled_from([0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 0.37, 5.5])),
       st.sampled_from(["guo-hall", "thesis"]), st.sampled_from(["mean3", "none"]),
       st.sampled_from([None, 0.3]), st.booleans())
def test_post_processing_the_voted_box_equals_the_whole_map(raw, thinning, filt, level, points):
    s = PostSettings(thinning=thinning, filter=filt, level=level)
    whole = post.filter_and_thin(raw, s, points, box=False)
    boxed = post.filter_and_thin(raw, s, points, box=True)
    for a, b in zip(whole, boxed, strict=True):
        assert a.shape == b.shape and np.array_equal(a, b)


def test_low_pass_is_eq_2_4_and_local():
    raw = np.zeros((7, 9))
    raw[3, 4] = 9.0
    f = post.low_pass(raw)
    assert np.array_equal(f[2:5, 3:6], np.ones((3, 3))) and f.sum() == 9.0
    assert np.count_nonzero(f) == 9  # nothing leaks beyond the 3×3 window


def test_stage_cache_reuses_only_unchanged_stages():
    scene = apply_preset(clsonar.load_scene(SCENES / "plane-2m.json"), "thesis")
    ctx = get_context()
    cache = StageCache()
    first = clsonar.run(scene, context=ctx, cache=cache)
    assert first.counts["stages_reused"] == 0
    again = clsonar.run(scene, context=ctx, cache=cache)
    assert again.counts["stages_reused"] == 9  # every stage: post-processing too
    _same(first, again)
    # a noise-free signal draws nothing: another noise seed is the same run
    reseeded = dataclasses.replace(scene, signal=dataclasses.replace(scene.signal, seed=7))
    same = clsonar.run(reseeded, context=ctx, cache=cache)
    assert same.counts["stages_reused"] == 9 and same.scene.signal.seed == 7
    _same(same, clsonar.run(reseeded, context=ctx))
    thin_post = dataclasses.replace(scene, post=dataclasses.replace(scene.post, filter="none"))
    assert clsonar.run(thin_post, context=ctx, cache=cache).counts["stages_reused"] == 4
    noisy = dataclasses.replace(scene, signal=dataclasses.replace(scene.signal, noise_std=0.5))
    r = clsonar.run(noisy, context=ctx, cache=cache)
    assert r.counts["stages_reused"] == 2  # sensors and echoes
    fresh = clsonar.run(noisy, context=ctx)
    _same(r, fresh)
    other_noise = dataclasses.replace(noisy, signal=dataclasses.replace(noisy.signal, seed=7))
    assert clsonar.run(other_noise, context=ctx, cache=cache).counts["stages_reused"] == 2
    # line of sight reads the post settings, but it runs after the votes (pipeline.sight):
    # the votes are reused and the result is a fresh run's
    room = clsonar.load_scene(SCENES / "room-l.json")
    clsonar.run(room, context=ctx, cache=cache)
    other = dataclasses.replace(room, post=dataclasses.replace(room.post, join_m=0.5))
    reused = clsonar.run(other, context=ctx, cache=cache)
    assert reused.counts["stages_reused"] == 4
    _same(reused, clsonar.run(other, context=ctx))


def test_cli_no_skip_writes_the_same_outputs(tmp_path):
    scene = str(SCENES / "cylinder-2.1m.json")
    assert main(["run", scene, "--out", str(tmp_path / "a"), "-q"]) == 0
    assert main(["run", scene, "--out", str(tmp_path / "b"), "-q", "--no-skip", "all"]) == 0
    for name in ("stages.npz", "profile.csv", "echoes.csv"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    counts = [json.loads((tmp_path / d / "report.json").read_text())["counts"] for d in "ab"]
    assert counts[0]["pairs_skipped_empty"] > 0 and counts[1]["pairs_skipped_empty"] == 0
    assert set(SKIP_NAMES) == {"empty_pairs", "silent_pairs", "quiet_samples", "tiles",
                               "empty_cells", "rooms"}


def test_post_processing_of_tangent_points_in_their_window_matches_the_whole_grid():
    """The sums of tangent points are kept only over their window of cells; profiles from
    cell centres (subcell off) still come out as on the whole grid."""
    scene = clsonar.load_scene(SCENES / "room-l.json")  # no line of sight: its points
    scene = dataclasses.replace(  # would depend on the post settings
        scene, mapping=dataclasses.replace(scene.mapping, line_of_sight=False))
    ctx = get_context()
    windowed = clsonar.run(scene, context=ctx)
    assert windowed.point_window is not None
    assert windowed.point_sums.shape[:2] == windowed.point_window[2:]
    centres = dataclasses.replace(scene.post, subcell=False)
    again = rerun_post(windowed, centres)
    whole = clsonar.run(dataclasses.replace(scene, post=centres), context=ctx,
                        skips=Skips.none())
    assert whole.point_window is None
    _same(again, whole)


def test_noisy_detection_scans_once_with_the_same_detections(monkeypatch):
    """Issue 16: the detection's first pass keeps only the envelope's local maxima above
    0.7 of the threshold the noise is expected to set (signals.host.first_pass_floor), not
    every noise peak above an open scene's floor of 0.01 units: every noisy pair used to
    overflow its candidates and be scanned twice. The detections are the same."""
    from clsonar.signals import host, signal_model
    from clsonar.signals.detection import envelope_floor
    from clsonar.tools.variants import with_seed

    scene = with_seed(clsonar.load_scene(SCENES / "plane-2m.json"), 1, 0.6)
    ctx = get_context()
    once = clsonar.run(scene, context=ctx)
    model = signal_model(once.scene)
    assert host.first_pass_floor(model) > 10 * envelope_floor(model)
    monkeypatch.setattr(host, "first_pass_floor", envelope_floor)
    twice = clsonar.run(scene, context=ctx)
    assert once.counts["samples_scanned"] * 2 == twice.counts["samples_scanned"]
    for name in ("tx", "rx", "tof_s", "amplitude"):
        assert np.array_equal(getattr(once.detections, name), getattr(twice.detections, name))
    _same(once, twice)
