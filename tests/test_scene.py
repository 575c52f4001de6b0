"""Scene format v1: validation errors name the file and key; load → save → load is identity."""

import dataclasses
import json
import math
import types
import typing
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar import SceneError, load_scene, save_scene
from clsonar.scene import (
    Circle,
    Circular,
    PerWall,
    Polyline,
    RandomLines,
    Scene,
    Sensors,
    Sinusoid,
    WallFollowing,
    parse_scene_text,
    scene_from_dict,
    scene_to_dict,
)

DESIGN_EXAMPLE = {
    "clsonar": 1,
    "name": "plane-2m",
    "extent": [0.0, 0.0, 10.0, 10.0],
    "cell": 0.01,
    "medium": {"temperature_k": 293.15},
    "transducer": {"frequency_hz": 50000, "radius_m": 0.02, "half_beam_deg": 12.0,
                   "amplitude": 5.0},
    "signal": {"noise_std": 0.0, "threshold": 4.0, "seed": 1},
    "surfaces": [
        {"type": "polyline", "points": [[9.0, 0.0], [9.0, 10.0]], "closed": False},
        {"type": "circle", "center": [5.0, 5.0], "radius": 2.0},
        {"type": "sinusoid", "from": [8.0, 0.0], "to": [8.0, 10.0], "amplitude": 0.3,
         "period": 5.0},
    ],
    "sensors": {
        "transducers": [{"position": [7.0, 5.0], "heading_deg": 0.0, "group": 0}],
        "placement": {"type": "random-lines", "seed": 3},
    },
}


def test_design_example_loads():
    s = scene_from_dict(DESIGN_EXAMPLE, "x.json")
    assert s.name == "plane-2m"
    assert s.surfaces[0] == Polyline(((9.0, 0.0), (9.0, 10.0)), False)
    assert s.surfaces[1] == Circle((5.0, 5.0), 2.0)
    assert s.surfaces[2] == Sinusoid((8.0, 0.0), (8.0, 10.0), 0.3, 5.0)
    assert s.grid_shape == (1000, 1000)
    assert s.medium.c == pytest.approx(331.4 * math.sqrt(293.15 / 273))


def test_minimal_scene_has_documented_defaults():
    s = scene_from_dict({"clsonar": 1, "extent": [0, 0, 1, 2]}, "min.json")
    assert s.name == "min" and s.cell == 0.01 and s.grid_shape == (200, 100)
    assert s.transducer.half_beam_deg == 12.0 and s.transducer.amplitude == 5.0
    assert s.signal.threshold == 4.0 and s.echo.max_order == 2
    assert s.surfaces == () and s.sensors.transducers == ()


def test_round_trip(tmp_path):
    s1 = scene_from_dict(DESIGN_EXAMPLE, "x.json")
    save_scene(s1, tmp_path / "a.json")
    s2 = load_scene(tmp_path / "a.json")
    save_scene(s2, tmp_path / "b.json")
    assert s1 == s2 == load_scene(tmp_path / "b.json")
    assert (tmp_path / "a.json").read_text() == (tmp_path / "b.json").read_text()
    assert [p.name for p in tmp_path.iterdir()] != []  # no temporary files left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json"]


def _with(path: str, value):
    """DESIGN_EXAMPLE with the value at dotted/indexed ``path`` replaced (or deleted)."""
    data = json.loads(json.dumps(DESIGN_EXAMPLE))
    keys = [int(k) if k.isdigit() else k for k in path.replace("[", ".").replace("]", "")
            .split(".")]
    node = data
    for k in keys[:-1]:
        node = node[k]
    if value is _DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return json.dumps(data)


_DELETE = object()

BAD = [
    # (description, file text, expected "key: message" fragment)
    ("empty file", "", "file is empty"),
    ("blank file", "  \n", "file is empty"),
    ("invalid JSON", '{"clsonar": 1,', "invalid JSON at line 1"),
    ("not an object", "[1, 2]", "must be an object"),
    ("unknown top key", _with("colour", "red"), "colour: unknown key"),
    ("unknown nested key", _with("surfaces[1].radiu", 2.0), "surfaces[1].radiu: unknown key"),
    ("wrong type", _with("cell", "0.01"), "cell: must be a number, not a string"),
    ("bool as number", _with("surfaces[1].radius", True), "surfaces[1].radius: must be a number"),
    ("wrong type list", _with("extent", [0, 0, 10]), "extent: must be a list of 4 numbers"),
    ("NaN literal", _with("cell", 0.01).replace("0.01", "NaN", 1), "NaN is not a valid number"),
    ("Infinity literal", _with("cell", 0.01).replace("0.01", "Infinity", 1),
     "Infinity is not a valid number"),
    ("huge number", _with("cell", 0.01).replace("0.01", "1e999", 1), "cell: must be a finite"),
    ("negative radius", _with("surfaces[1].radius", -2.0), "surfaces[1].radius: must be > 0"),
    ("zero radius", _with("surfaces[1].radius", 0), "surfaces[1].radius: must be > 0"),
    ("zero cell", _with("cell", 0), "cell: must be > 0"),
    ("negative cell", _with("cell", -0.01), "cell: must be > 0"),
    ("zero-length segment", _with("surfaces[0].points", [[9, 0], [9, 0]]),
     "surfaces[0].points[1]: zero-length segment"),
    ("unsupported version", _with("clsonar", 2), "clsonar: unsupported format version 2"),
    ("missing version", _with("clsonar", _DELETE), "clsonar: missing format version"),
    ("bad surface type", _with("surfaces[0].type", "blob"), "surfaces[0].type: must be one of"),
    ("inverted extent", _with("extent", [10, 0, 0, 10]), "extent: must be [xmin"),
    ("negative noise", _with("signal.noise_std", -1), "signal.noise_std: must be >= 0"),
    ("fractional seed", _with("signal.seed", 1.5), "signal.seed: must be an integer"),
    ("bad placement", _with("sensors.placement.type", "grid"), "sensors.placement.type"),
    ("missing radius", _with("surfaces[1].radius", _DELETE), "surfaces[1].radius: missing"),
    ("deep nesting", "[" * 100000 + "]" * 100000, "nested deeper"),
    ("solid open polyline", _with("surfaces[0].solid", True),
     'surfaces[0].solid: true needs "closed": true'),
    ("solid not a bool", _with("surfaces[0].solid", "yes"),
     "surfaces[0].solid: must be true, false or null, not a string"),
]


@pytest.mark.parametrize(("text", "expected"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_input_is_one_clear_line(tmp_path, text, expected):
    f = tmp_path / "bad.json"
    f.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(f)
    message = str(info.value)
    assert message.startswith(f"{f}: "), message
    assert expected in message, message
    assert "\n" not in message


def test_unreadable_file_names_it(tmp_path):
    with pytest.raises(SceneError, match=r"missing\.json: cannot read file"):
        load_scene(tmp_path / "missing.json")


def test_not_utf8(tmp_path):
    f = tmp_path / "bin.json"
    f.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(SceneError, match="not UTF-8"):
        load_scene(f)


def test_solid_is_read_written_and_null_by_default(tmp_path):
    room = {"type": "polyline", "points": [[0, 0], [9, 0], [9, 9], [0, 9]], "closed": True}
    box = {**room, "points": [[3, 3], [4, 3], [4, 4], [3, 4]]}
    for value in (None, True, False):
        data = {**DESIGN_EXAMPLE, "surfaces": [room, {**box, "solid": value}]}
        scene = scene_from_dict(data)
        assert scene.surfaces[1].solid is value
        save_scene(scene, tmp_path / "s.json")
        assert json.loads((tmp_path / "s.json").read_text())["surfaces"][1]["solid"] is value
        assert load_scene(tmp_path / "s.json") == scene
    assert scene_from_dict({**DESIGN_EXAMPLE, "surfaces": [box]}).surfaces[0].solid is None


def test_wall_following_keys():
    d = json.loads(_with("sensors.placement", {"type": "wall-following", "start": [1, 5],
                                               "step_m": 0.75}))
    p = scene_from_dict(d).sensors.placement
    assert p == WallFollowing(start=(1.0, 5.0), step_m=0.75)


def _per_wall_scene(**placement) -> dict:
    """A rectangular room scanned wall by wall (thesis §3.6, Figs 3.21–3.22)."""
    return {
        "clsonar": 1, "name": "room", "extent": [0.0, 0.0, 10.0, 10.0],
        "surfaces": [
            {"type": "circle", "center": [5.0, 5.0], "radius": 1.0},
            {"type": "polyline", "points": [[1, 1], [9, 1], [9, 9], [1, 9]], "closed": True},
        ],
        "sensors": {"placement": {"type": "per-wall", "surface": 1, **placement}},
    }


def test_per_wall_keys_and_defaults():
    p = scene_from_dict(_per_wall_scene()).sensors.placement
    assert p == PerWall(surface=1)
    assert (p.distance_m, p.distance_step_m, p.margin_m, p.elements) == (1.0, 0.0, None, 10)
    assert p.spacing_m == (0.05, 0.11) and p.separation_m == (0.5, 1.65)
    assert p.heading_spread_deg == 0.0
    p = scene_from_dict(_per_wall_scene(distance_m=1.5, distance_step_m=-0.25, margin_m=0.25,
                                        elements=8, spacing_m=[0.06, 0.1], seed=9,
                                        heading_spread_deg=90, clearance_m=0.1)).sensors.placement
    assert p == PerWall(seed=9, surface=1, distance_m=1.5, distance_step_m=-0.25, margin_m=0.25,
                        elements=8, spacing_m=(0.06, 0.1), heading_spread_deg=90.0,
                        clearance_m=0.1)


@pytest.mark.parametrize("placement", [{}, {"distance_step_m": 0.25, "margin_m": 0.5, "seed": 4}])
def test_per_wall_round_trip(tmp_path, placement):
    s1 = scene_from_dict(_per_wall_scene(**placement), "room.json")
    save_scene(s1, tmp_path / "a.json")
    s2 = load_scene(tmp_path / "a.json")
    save_scene(s2, tmp_path / "b.json")
    assert s1 == s2 == load_scene(tmp_path / "b.json")
    assert (tmp_path / "a.json").read_text() == (tmp_path / "b.json").read_text()
    saved = json.loads((tmp_path / "a.json").read_text())["sensors"]["placement"]
    assert saved["type"] == "per-wall" and saved["margin_m"] == placement.get("margin_m")


@pytest.mark.parametrize(("placement", "expected"), [
    ({"distance_m": -1.0}, "sensors.placement.distance_m: must be > 0"),
    ({"distance_m": 0}, "sensors.placement.distance_m: must be > 0"),
    ({"margin_m": -0.1}, "sensors.placement.margin_m: must be >= 0"),
    ({"surface": 2}, "sensors.placement.surface: no surfaces[2] (the scene has 2 surfaces)"),
    ({"surface": -1}, "sensors.placement.surface: must be >= 0"),
    ({"surface": 0}, "sensors.placement.surface: surfaces[0] is a circle; per-wall needs a "
                     "closed polyline"),
    ({"surface": 1.5}, "sensors.placement.surface: must be an integer"),
    ({"elements": 0}, "sensors.placement.elements: must be >= 1"),
    ({"spacing_m": [0.1, 0.05]}, "sensors.placement.spacing_m: upper bound"),
    ({"separation_m": [0, 1]}, "sensors.placement.separation_m[0]: must be > 0"),
    ({"heading_spread_deg": 200}, "sensors.placement.heading_spread_deg: must be <= 180"),
    ({"clearance_m": -1}, "sensors.placement.clearance_m: must be >= 0"),
    ({"distance_step_m": "big"}, "sensors.placement.distance_step_m: must be a number"),
    ({"seed": -1}, "sensors.placement.seed: must be >= 0"),
    ({"facing_deg": 0}, "sensors.placement.facing_deg: unknown key"),
])
def test_per_wall_bad_values_are_one_clear_line(tmp_path, placement, expected):
    f = tmp_path / "room.json"
    f.write_text(json.dumps(_per_wall_scene(**placement)))
    with pytest.raises(SceneError) as info:
        load_scene(f)
    message = str(info.value)
    assert message.startswith(f"{f}: "), message
    assert expected in message, message
    assert "\n" not in message


def test_per_wall_on_an_open_polyline_is_refused():
    d = _per_wall_scene()
    d["surfaces"][1]["closed"] = False
    with pytest.raises(SceneError, match=r"surfaces\[1\] is an open polyline"):
        scene_from_dict(d)


finite = st.floats(-1e3, 1e3, allow_nan=False)
points = st.tuples(finite, finite)


def _apart(pts) -> bool:
    """No two points closer than the loader's shortest segment (scene.MIN_LENGTH_M)."""
    return all(math.dist(p, q) >= 1e-6 for i, p in enumerate(pts) for q in pts[i + 1:])


@st.composite
def scenes(draw):
    surfaces = []
    for _ in range(draw(st.integers(0, 4))):
        kind = draw(st.sampled_from(["polyline", "circle", "sinusoid"]))
        if kind == "polyline":
            pts = draw(st.lists(points, min_size=3, max_size=6, unique=True).filter(_apart))
            closed = draw(st.booleans()) and len(pts) >= 3
            solid = draw(st.sampled_from([None, False, True] if closed else [None, False]))
            surfaces.append(Polyline(tuple(pts), closed, solid))
        elif kind == "circle":
            surfaces.append(Circle(draw(points), draw(st.floats(1e-3, 1e3))))
        else:
            a, b = draw(st.lists(points, min_size=2, max_size=2, unique=True).filter(_apart))
            surfaces.append(Sinusoid(a, b, draw(finite), draw(st.floats(1e-3, 1e3))))
    x0, y0 = draw(points)
    return Scene(name=draw(st.text(max_size=10)),
                 extent=(x0, y0, x0 + draw(st.floats(0.1, 100)), y0 + draw(st.floats(0.1, 100))),
                 cell=draw(st.floats(1e-3, 1.0)), surfaces=tuple(surfaces))


@settings(max_examples=100)
@given(scenes())
def test_round_trip_property(scene):
    text = json.dumps(scene_to_dict(scene), allow_nan=False)
    assert parse_scene_text(text) == scene


def test_atomic_writes_get_ordinary_permissions(tmp_path):
    import os
    import stat

    from clsonar.files import write_atomic

    target = tmp_path / "report.json"
    write_atomic(target, b"{}")
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~mask
    assert target.read_bytes() == b"{}"


DOC = (Path(__file__).resolve().parents[1] / "docs" / "scene-format.md").read_text()


def _documented(word: str, key: str = "") -> bool:
    """Whether docs/scene-format.md names ``word`` as a key or value (`word` or "word"),
    on a line that names ``key`` if given (the values of a setting on its row)."""
    lines = [line for line in DOC.splitlines() if not key or f"`{key}`" in line]
    return any(f"`{word}`" in line or f'"{word}"' in line for line in lines)


def _inner(hint) -> tuple:
    """The types inside a field's annotation: the members of unions and tuples."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType, tuple):
        return tuple(t for arg in typing.get_args(hint) for t in (arg, *_inner(arg)))
    return ()


def _settings_fields(cls=Scene, seen=None):
    """(dataclass, field name, annotation) of every dataclass a scene is made of."""
    seen = set() if seen is None else seen
    seen.add(cls)
    for name, hint in typing.get_type_hints(cls).items():
        yield cls, name, hint
        for t in (hint, *_inner(hint)):
            if dataclasses.is_dataclass(t) and t not in seen:
                yield from _settings_fields(t, seen)


def test_every_choice_is_documented():
    """Every value of every Literal setting (clsonar.scene.settings) is in the doc."""
    choices = [(cls, name, t) for cls, name, hint in _settings_fields()
               for t in (hint, *_inner(hint)) if typing.get_origin(t) is typing.Literal]
    assert len(choices) >= 15
    missing = [f"{cls.__name__}.{name}: {value}" for cls, name, t in choices
               for value in typing.get_args(t) if not _documented(value, name)]
    assert not missing, missing


def test_every_key_is_documented():
    """Every key the reader accepts (all are written by save_scene) is in the doc."""
    scene = scene_from_dict(DESIGN_EXAMPLE)
    room = Polyline(((1.0, 1.0), (9.0, 1.0), (9.0, 9.0)), closed=True)
    scene = dataclasses.replace(scene, surfaces=(room, *scene.surfaces), sensors=Sensors(
        scene.sensors.transducers, RandomLines(),
        (Circular((1.0, 1.0)), WallFollowing((1.0, 1.0)), PerWall())))

    def keys(node):
        if isinstance(node, dict):
            for k, v in node.items():
                yield k
                yield from keys(v)
        elif isinstance(node, list):
            for v in node:
                yield from keys(v)

    data = scene_to_dict(scene)
    assert scene_from_dict(data) == scene
    missing = sorted({k for k in keys(data) if not _documented(k)})
    assert not missing, missing


def test_precisions_are_the_kernels():
    from clsonar.opencl import PRECISIONS
    from clsonar.scene import Precision

    assert set(typing.get_args(Precision)) == set(PRECISIONS)


# --------------------------------------------------------------------------- detection.receiver


@pytest.mark.parametrize(("detection", "expected"), [
    ({"receiver": "polaroid"}, "detection.receiver: must be one of 'ideal', 'polaroid-6500'"),
    ({"receiver": 6500}, "detection.receiver: must be one of"),
    ({"mode": "threshold", "receiver": "polaroid-6500"},
     'detection.receiver: "polaroid-6500" needs detection.mode "envelope"'),
])
def test_bad_detection_receiver_is_one_line_naming_file_and_key_exit_2(tmp_path, capsys,
                                                                      detection, expected):
    from clsonar.cli import main

    f = tmp_path / "receiver.json"
    f.write_text(json.dumps(dict(DESIGN_EXAMPLE, detection=detection)))
    with pytest.raises(SceneError) as info:
        load_scene(f)
    assert str(info.value).startswith(f"{f}: ") and expected in str(info.value)
    assert "\n" not in str(info.value)
    assert main(["echoes", str(f), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and expected in err[0]


def test_detection_receiver_defaults_to_ideal_and_round_trips(tmp_path):
    assert scene_from_dict(DESIGN_EXAMPLE, "x.json").detection.receiver == "ideal"
    s = scene_from_dict(dict(DESIGN_EXAMPLE, detection={"receiver": "polaroid-6500"}), "x.json")
    assert s.detection.receiver == "polaroid-6500" and s.detection.mode == "envelope"
    save_scene(s, tmp_path / "p.json")
    assert load_scene(tmp_path / "p.json") == s
