"""Hostile scene files (issue 6): every one ends in one clear error line and exit status 2,
never a traceback, a hang or a half-written --out (clsonar/tools/fuzz.py; the 10⁵-input run is in
docs/stability.md)."""

from __future__ import annotations

import json
import random

import pytest

from clsonar.cli import main
from clsonar.tools import fuzz


def test_a_bounded_fuzzing_run_finds_nothing():
    report = fuzz.fuzz(1500, seed=12345, limit_s=5.0)
    assert report.findings == []
    assert report.inputs == 1500 and report.refused + report.accepted == 1500
    assert set(report.by_mutation) == set(fuzz.MUTATIONS)
    assert report.refused > 0.9 * report.inputs and report.cli_checked == report.refused


def test_mutations_are_reproducible_and_hostile():
    seeds = fuzz.seed_texts()
    a = [fuzz.hostile_input(random.Random(3), seeds) for _ in range(20)]
    b = [fuzz.hostile_input(random.Random(3), seeds) for _ in range(20)]
    assert a == b


def scene_text(**changes) -> str:
    data = json.loads(fuzz.seed_texts()[0])
    data.update(changes)
    return json.dumps(data)


BAD = [
    ("huge grid", scene_text(extent=[0, 0, 1e6, 1e6], cell=1e-6), "cell: the extent is"),
    ("overflowing grid", scene_text(extent=[-1e9, -1e9, 1e9, 1e9], cell=5e-324),
     "cell: the extent is inf cells"),
    ("coordinate out of range", scene_text(extent=[0, 0, 1e300, 10]), "extent[2]: 1e+300 is out"),
    ("too many items", scene_text(surfaces=[0] * 250_000), "too large"),
    ("too many objects", scene_text(surfaces=[[[0, 0]]] * 30_000), "too large"),
    ("walls to the power max_order",
     scene_text(surfaces=[{"type": "polyline", "points": [[i * 0.01, 0] for i in range(4000)]}],
                echo={"max_order": 2}), "echo.max_order"),
    ("tiny segment", scene_text(surfaces=[{"type": "polyline", "points": [[0, 0], [5e-324, 0]]}]),
     "shorter than"),
    ("tiny radius", scene_text(surfaces=[{"type": "circle", "center": [1, 1], "radius": 1e-300}]),
     "surfaces[0].radius"),
    ("sinusoid sampled too finely",
     scene_text(surfaces=[{"type": "sinusoid", "from": [0, 0], "to": [1e8, 0], "amplitude": 0.1,
                           "period": 1.0}]), "echo.curve_step_m"),
    ("too many circles",
     scene_text(surfaces=[{"type": "circle", "center": [1, 1], "radius": 0.1}] * 1001),
     "surfaces: 1001 circles"),
    ("too many pairs",
     scene_text(sensors={"transducers": [{"position": [1, 1], "heading_deg": 0}] * 4000}),
     "sensors.transducers"),
    ("NaN", scene_text().replace('"cell": 0.01', '"cell": NaN'), "NaN"),
    ("deep", "[" * 100_000, "nested deeper"),
]


@pytest.mark.parametrize(("text", "expected"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_clsonar_run_refuses_hostile_scenes_in_one_line(tmp_path, capsys, text, expected):
    path = tmp_path / "bad.json"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"clsonar: error: {path}: "), err
    assert expected in err, err
    assert not out.exists()
