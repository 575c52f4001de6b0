"""Settings chosen from the scene (issue 14, item 1; clsonar/survey.py): rings, arrays, rooms
and paths told apart, the file's values kept, and scenes a user writes with the defaults —
a room scanned by the wall-following ring, by rings placed by hand, a corridor driven down by
a robot — mapped accurately and completely."""

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import clsonar
from clsonar import survey as sv
from clsonar.cli import main
from clsonar.geometry import build_geometry
from clsonar.opencl import get_context
from clsonar.scene import scene_from_dict
from clsonar.sensors import place_sensors

ROOM = [[0.5, 0.5], [6.5, 0.5], [6.5, 4.5], [0.5, 4.5]]


def ring(cx: float, cy: float, group: int, n: int = 8, start: float = 0.0) -> list[dict]:
    """One pose of a circular array: ``n`` elements 6.5 cm from the centre, facing out."""
    return [{"position": [cx + 0.065 * math.cos(math.radians(start + 360 * k / n)),
                          cy + 0.065 * math.sin(math.radians(start + 360 * k / n))],
             "heading_deg": start + 360 * k / n, "group": group} for k in range(n)]


def loop(corners: list[tuple[float, float]], step: float) -> list[tuple[float, float]]:
    """Poses every ``step`` along the closed path through ``corners``."""
    poses = []
    for (x0, y0), (x1, y1) in zip(corners, corners[1:] + corners[:1], strict=True):
        n = int(math.hypot(x1 - x0, y1 - y0) / step)
        poses += [(x0 + (x1 - x0) * k / n, y0 + (y1 - y0) * k / n) for k in range(n)]
    return poses


def scene(name: str, surfaces: list[dict], extent: list[float], sensors: dict):
    return scene_from_dict({"clsonar": 1, "name": name, "extent": extent,
                            "surfaces": surfaces, "sensors": sensors})


def room_by_wall_following():
    return scene("room", [{"type": "polyline", "closed": True, "points": ROOM}], [0, 0, 7, 5],
                 {"placement": {"type": "wall-following", "start": [2.0, 2.5]}})


def room_by_hand():
    poses = loop([(1.5, 1.5), (5.5, 1.5), (5.5, 3.5), (1.5, 3.5)], 0.5)
    tr = [t for g, (x, y) in enumerate(poses) for t in ring(x, y, g)]
    return scene("rings", [{"type": "polyline", "closed": True, "points": ROOM}], [0, 0, 7, 5],
                 {"transducers": tr})


def corridor():
    tr = [t for g in range(37) for t in ring(1.0 + 0.5 * g, 1.0, g)]
    walls = [{"type": "polyline", "points": [[0, 0], [20, 0]]},
             {"type": "polyline", "points": [[0, 2], [20, 2]]}]
    return scene("corridor", walls, [-0.5, -0.5, 20.5, 2.5], {"transducers": tr})


def arrays():
    tr = [{"position": [5.0, 3.0 + 0.1 * k], "heading_deg": 0.0, "group": 0} for k in range(10)]
    return scene("wall", [{"type": "polyline", "points": [[7, 0.5], [7, 7.5]]}], [4, 0, 9, 8],
                 {"transducers": tr})


def surveyed(s):
    return sv.survey(s, place_sensors(s, build_geometry(s)))


@given(st.floats(-50, 50), st.floats(-50, 50), st.integers(3, 16), st.floats(0.02, 0.4),
       st.floats(-180, 180))
def test_a_ring_is_a_ring_and_not_an_array(cx, cy, n, r, start):
    a = np.radians(start + 360.0 * np.arange(n) / n)
    pos = np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=-1)
    heads = np.degrees(a)
    assert sv.is_ring(pos, heads)
    assert not sv.is_linear_array(pos, heads)
    assert not sv.is_ring(pos, heads + 180.0)  # facing inwards: not a sonar ring


@given(st.floats(-50, 50), st.floats(-50, 50), st.integers(2, 300), st.floats(0.01, 0.1),
       st.floats(-180, 180), st.floats(-20, 20))
def test_a_linear_array_is_an_array_and_not_a_ring(x, y, n, pitch, along, facing):
    t = pitch * np.arange(n)
    u = np.radians(along)
    pos = np.stack([x + t * np.cos(u), y + t * np.sin(u)], axis=-1)
    heads = np.full(n, along + 90.0 + facing)
    assert sv.is_linear_array(pos, heads)
    assert not sv.is_ring(pos, heads)


def test_the_kind_of_each_scan():
    assert surveyed(room_by_wall_following()).kind == sv.ROOM_RINGS
    assert surveyed(room_by_hand()).kind == sv.ROOM_RINGS
    assert surveyed(corridor()).kind == sv.PATH
    found = surveyed(arrays())
    assert found.kind == sv.OPEN and found.arrays == 1 and found.rings == 0
    one = scene("one ring", [], [0, 0, 4, 4], {"transducers": ring(2, 2, 0)})
    assert surveyed(one).kind == sv.RINGS
    per_wall = clsonar.load_scene(clsonar.files.bundled_scenes() / "room-per-wall.json")
    assert surveyed(per_wall).kind == sv.ROOM


def test_the_file_wins_and_every_choice_says_why():
    s = room_by_hand()
    import dataclasses
    s = dataclasses.replace(s, post=dataclasses.replace(s.post, fit="spline"))
    used, why = sv.choose_settings(s, surveyed(s))
    assert used.post.fit == "spline" and why["post.fit"] == "file"
    assert used.mapping.isolated_bias_m == 0.005 and used.post.max_gap_m == 1.0
    assert why["mapping.isolated_bias_m"] == "auto: ring poses inside a closed room"
    assert set(why) == set(sv.AUTO_KEYS)
    assert all(k in c for c in sv.CHOICES.values() for k in sv.AUTO_KEYS)


@pytest.mark.parametrize("make", [room_by_wall_following, room_by_hand, corridor])
def test_scenes_scanned_by_rings_map_with_the_defaults(make):
    """Issue 14: 0 profile points with the defaults before; now accurate and complete."""
    r = clsonar.run(make(), context=get_context())
    m = r.metrics
    assert m["accuracy_m"]["rms"] <= 0.005
    assert m["completeness"]["2cm"] >= 0.95
    for v in m.get("vertices", []):
        assert v["found"] and v["error_m"] <= 0.02
    assert r.settings_why["post.fit"].startswith("auto: ")


def test_report_says_which_settings_were_chosen_and_why(tmp_path):
    path = tmp_path / "corridor.json"
    s = corridor()
    data = clsonar.scene.scene_to_dict(s)
    for block in ("detection", "mapping", "post"):
        data.pop(block)
    path.write_text(json.dumps(data))
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "-q"]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["settings"]["post"]["fit"] == "walls"
    assert report["settings_why"]["post.fit"] == "auto: ring poses along a path"
