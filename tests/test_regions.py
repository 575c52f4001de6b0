"""Separate closed rooms are mapped one by one (clsonar.regions), for floors at scale."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import clsonar
from clsonar.echoes import compute_echoes
from clsonar.errors import ClsonarError, SceneError
from clsonar.opencl import get_context
from clsonar.pipeline import rerun_post
from clsonar.regions import combine_metrics, split_rooms
from clsonar.scene import scene_from_dict, scene_to_dict
from clsonar.tools.floors import floor_scene

SCENES = Path(__file__).resolve().parents[1] / "scenes"


@pytest.fixture(scope="module")
def floor():
    scene = floor_scene(size_m=10.0)
    return scene, clsonar.run(scene, context=get_context())


def test_a_floor_splits_into_its_rooms_and_a_room_does_not():
    rooms = split_rooms(floor_scene(size_m=10.0))
    assert rooms is not None and len(rooms) == 4
    for r in rooms:
        ny, nx = r.scene.grid_shape
        assert r.scene.extent[0] == pytest.approx(r.col0 * 0.01)
        assert 510 <= ny <= 520 and 510 <= nx <= 520  # 4.8 m room + margins, clipped
        assert len(r.scene.sensors.placements) == 1
        assert len(r.scene.surfaces) == 1  # its own outline only
    for name in ("room", "room-obstacles", "plane-2m"):
        assert split_rooms(clsonar.load_scene(SCENES / f"{name}.json")) is None


def test_floor_room_by_room_finds_every_wall_and_corner(floor):
    scene, r = floor
    m = r.metrics
    assert m["rooms"] == r.counts["rooms_mapped"] == 4
    assert m["accuracy_m"]["rms"] < 0.005 and m["completeness"]["2cm"] >= 0.95
    assert m["vertices_found"] == "16/16" and m["vertex_error_max_m"] < 0.03
    assert r.raw.shape == r.thin.shape == scene.grid_shape and r.thin.any()
    assert len(r.sensors) == r.counts["transducers"] and len(r.sensors.poses) > 4 * 20


def test_rooms_hear_exactly_the_echoes_of_the_whole_floor(floor):
    scene, r = floor
    whole = compute_echoes(scene, r.sensors, context=get_context())
    assert len(whole) == len(r.echoes) > 0
    for column in ("tx", "rx", "kind", "order"):
        assert np.array_equal(getattr(whole, column), getattr(r.echoes, column)), column
    assert np.allclose(whole.tof_s, r.echoes.tof_s, rtol=0, atol=1e-7)


def test_post_processing_of_a_floor_cannot_rerun_alone(floor):
    with pytest.raises(ClsonarError, match="room by room"):
        rerun_post(floor[1])


def test_combined_metrics_pool_the_rooms():
    def room(points, rms, lit, comp, cov):
        return {"points": points, "insonified_m": lit, "coverage": cov,
                "accuracy_m": {"rms": rms, "p95": rms}, "spurious_share": 0.0,
                "completeness": {"2cm": comp}, "rms_m": None}

    m = combine_metrics([room(100, 0.003, 10.0, 1.0, 0.5), room(300, 0.001, 30.0, 0.5, 1.0)])
    assert m["points"] == 400 and m["insonified_m"] == 40.0
    assert m["accuracy_m"]["rms"] == pytest.approx(np.sqrt((100 * 9e-6 + 300 * 1e-6) / 400))
    assert m["completeness"]["2cm"] == pytest.approx(0.625)
    assert m["coverage"] == pytest.approx(40.0 / 50.0)


def test_placements_round_trip_and_bad_placements_name_their_key():
    scene = floor_scene(size_m=10.0)
    again = scene_from_dict(scene_to_dict(scene))
    assert again.sensors == scene.sensors
    data = scene_to_dict(scene)
    data["sensors"]["placements"] = {"type": "circular"}
    with pytest.raises(SceneError, match=r"sensors\.placements: must be a list"):
        scene_from_dict(data)
    data["sensors"]["placements"] = [{"type": "circular", "center": [1, 1]}, {"type": "x"}]
    with pytest.raises(SceneError, match=r"sensors.placements\[1\]"):
        scene_from_dict(data)
    one = dataclasses.replace(scene, sensors=dataclasses.replace(scene.sensors,
                                                                placements=()))
    assert scene_to_dict(one)["sensors"]["placements"] == []


def _enclosing_every_pair(surfaces):
    """outlines.enclosing as it was, every outline tried for every one (the reference)."""
    from clsonar.outlines import encloses
    from clsonar.scene import Polyline

    outlines = {i: np.asarray(s.points, dtype=np.float64) for i, s in enumerate(surfaces)
                if isinstance(s, Polyline) and s.closed}
    out = [None] * len(surfaces)
    for i, pts in outlines.items():
        for j, outer in outlines.items():
            if j != i and encloses(outer, pts):
                out[i] = j
                break
    return out


def test_only_outlines_whose_box_holds_a_point_are_tried_with_the_same_answers():
    """outlines.enclosing and the rooms' lookup (outlines.outline_boxes, holding) try only the
    outlines whose widened box holds the point: the same answers as trying every one, for
    outlines nested, touching, sharing edges and a hair apart (random, seeded)."""
    from clsonar.outlines import enclosing, holding, inside_polygon, outline_boxes
    from clsonar.scene import Polyline

    rng = np.random.default_rng(7)
    for _ in range(40):
        shapes = []
        for _ in range(int(rng.integers(2, 9))):
            c = rng.choice([0.0, 1.0, 2.0, 1e-12, 1.0 + 1e-15], size=2) + rng.uniform(0, 2, 2) \
                * rng.integers(0, 2)
            r = rng.choice([0.25, 0.5, 1.0, 2.0])
            k = int(rng.integers(3, 7))
            a = np.sort(rng.uniform(0, 2 * np.pi, k)) if rng.random() < 0.5 else \
                np.linspace(0, 2 * np.pi, k, endpoint=False) + np.pi / 4
            pts = c + r * np.column_stack([np.cos(a), np.sin(a)])
            shapes.append(Polyline(tuple(map(tuple, pts.tolist())), closed=True))
        assert enclosing(tuple(shapes)) == _enclosing_every_pair(tuple(shapes))
        polys = [np.asarray(s.points, dtype=np.float64) for s in shapes]
        boxes = outline_boxes(polys)
        for p in [v for s in shapes for v in s.points] + rng.uniform(-1, 4, (30, 2)).tolist():
            held = set(holding(boxes, p).tolist())
            inside = {i for i, poly in enumerate(polys) if inside_polygon(poly, np.array([p]))[0]}
            assert inside <= held
    floor = floor_scene(size_m=20.0)
    assert enclosing(floor.surfaces) == _enclosing_every_pair(floor.surfaces)
