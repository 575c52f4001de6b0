"""scene.png and profile.png drawn from the arrays (clsonar.pictures on clsonar.canvas, no
matplotlib): the raster primitives against a brute force over every pixel, the ticks, the
text, what each plot draws, and that it draws without vertices or poses too."""

from __future__ import annotations

import dataclasses
import math
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import clsonar
from clsonar import canvas, pictures
from clsonar.geometry import build_geometry, true_vertices
from clsonar.post import Profile
from clsonar.sensors import place_sensors

SCENES = Path(__file__).resolve().parents[1] / "scenes"
PNG = b"\x89PNG\r\n\x1a\n"


def _placed(name):
    scene = clsonar.load_scene(SCENES / f"{name}.json")
    geom = build_geometry(scene)
    return scene, geom, place_sensors(scene, geom)


def _decoded(png: bytes) -> np.ndarray:
    """The RGB pixels of a PNG written by clsonar.pictures.png (one IDAT, no filter)."""
    assert png[:8] == PNG
    w, h = (int.from_bytes(png[16 + 4 * k:20 + 4 * k], "big") for k in range(2))
    start = png.index(b"IDAT") + 4
    size = int.from_bytes(png[start - 8:start - 4], "big")
    rows = np.frombuffer(zlib.decompress(png[start:start + size]), np.uint8)
    return rows.reshape(h, 1 + 3 * w)[:, 1:].reshape(h, w, 3)


def test_true_vertices_are_the_corners_and_edges():
    _, geom, _ = _placed("room-obstacles")
    got = {tuple(v) for v in true_vertices(geom)}
    room = {(0.5, 0.5), (10.5, 0.5), (10.5, 8.5), (0.5, 8.5)}
    box = {(8.5, 5.5), (8.5, 7.0), (7.5, 7.0), (7.5, 5.5)}
    assert got == room | box  # not the box polyline's free ends at (8, 5.5), a flat side


def _brute(shape, share_of):
    """Every pixel's share by ``share_of(x, y)`` of its centre."""
    rows, cols = np.indices(shape)
    return share_of(cols + 0.5, rows + 0.5)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(2.0, 38.0), min_size=4, max_size=4), st.floats(0.3, 6.0))
def test_a_stroke_reaches_every_pixel_it_covers(ends, width):
    """segment_pixels (pixels around points a pixel apart) against every pixel of the
    picture, each one's share from its centre's distance to the segment: the same pixels,
    the same shares (to float32's precision)."""
    a, b = np.array([ends[:2]]), np.array([ends[2:]])
    rows, cols, share = canvas.segment_pixels(a, b, width)
    inside = (rows >= 0) & (rows < 40) & (cols >= 0) & (cols < 40)
    got = np.zeros((40, 40))
    np.maximum.at(got, (rows[inside], cols[inside]), share[inside])
    want = _brute((40, 40), lambda x, y: canvas.cover(
        canvas._segment_distance(x, y, a[0], b[0]), 0.5 * width))
    np.testing.assert_allclose(got, want, atol=1e-5)  # the strokes are drawn in float32


@pytest.mark.parametrize("marker", ["x", "o", "disc", "s"])
@pytest.mark.parametrize("size, width", [(3.0, 1.0), (10.4, 1.7), (12.5, 2.5)])
def test_a_marker_reaches_every_pixel_it_covers(marker, size, width):
    """marker_pixels against every pixel: nothing covered outside the stamp it computes,
    and a ring's, a disc's and a square's pixels where their shapes say."""
    centre = np.array([[20.3, 19.6]])
    rows, cols, share = canvas.marker_pixels(centre, marker, size, width)
    got = np.zeros((40, 40))
    np.maximum.at(got, (rows, cols), share)
    big = canvas.marker_pixels(centre, marker, size + 8, width)  # a larger stamp: the same
    r = _brute((40, 40), lambda x, y: np.hypot(x - 20.3, y - 19.6))
    square = _brute((40, 40), lambda x, y: np.maximum(abs(x - 20.3), abs(y - 19.6)))
    assert got.sum() > 0 and np.all(got[square > 0.5 * size + width + 1] == 0)
    if marker == "o":
        np.testing.assert_allclose(got, canvas.cover(np.abs(r - 0.5 * size), 0.5 * width),
                                   atol=1e-5)  # float32
    elif marker == "disc":
        np.testing.assert_allclose(got, np.clip(0.5 * size + 0.5 - r, 0, 1), atol=1e-5)
    assert len(big[0]) >= len(rows)


def test_ticks_and_their_labels_are_matplotlibs():
    np.testing.assert_allclose(canvas.nice_ticks(0, 10, 9), [0, 2, 4, 6, 8, 10])
    np.testing.assert_allclose(canvas.nice_ticks(0, 3, 9), np.arange(7) * 0.5)
    np.testing.assert_allclose(canvas.nice_ticks(-2.5, 2.5, 9), [-2, -1, 0, 1, 2])
    np.testing.assert_allclose(canvas.nice_ticks(1000.3, 1004.1, 9), np.arange(1, 9) * 0.5 + 1000)
    assert [canvas.tick_label(v, s) for v, s in [(0.5, 0.5), (5, 2.5), (2.5, 2.5), (-1, 1),
                                                 (0.75, 0.25), (-0.0, 1), (1000, 200)]] == [
        "0.5", "5.0", "2.5", "−1", "0.75", "0", "1000"]


def test_text_is_set_from_the_atlas_by_its_advances():
    """A line of text is as wide as its characters' advances; a character the atlas
    lacks is set as "?"; the text has ink."""
    font = canvas.font("normal")
    alpha, baseline, width = canvas.text_alpha("x (m)")
    assert width == pytest.approx(sum(font.advance[font.index[c]] for c in "x (m)"))
    assert alpha.max() > 0.9 and 0 < baseline < alpha.shape[0]
    assert canvas.text_alpha("ж")[2] == canvas.text_alpha("?")[2]
    assert font.advance[font.index["W"]] > font.advance[font.index["i"]] > 0


@pytest.mark.parametrize(("name", "label", "joined"), [
    ("room-l", "ring poses", True), ("room-per-wall", "array centres", False),
    ("plane-2m", None, False)])
def test_poses_are_drawn_and_labelled_by_placement(name, label, joined):
    """Ring poses joined along their closed path, per-wall array centres apart, random
    lines without poses; each pose's pixel green."""
    scene, _, sensors = _placed(name)
    c, axes = pictures._plot(scene)
    entries = pictures._poses(c, axes, scene, sensors.poses, light=False)
    assert [e.label for e in entries] == ([label] if label else [])
    if label is None:
        assert (c.rgb == 255).all()
        return
    green = np.asarray(canvas.COLOURS["tab:green"])
    p = axes.pixels(sensors.poses).astype(int)
    np.testing.assert_allclose(c.rgb[p[:, 1], p[:, 0]], np.tile(green, (len(p), 1)), atol=40)
    middle = axes.pixels(0.5 * (sensors.poses[-1] + sensors.poses[0])).astype(int)[0]
    assert (np.abs(c.rgb[middle[1], middle[0]] - green).max() < 40) == joined


def test_profile_png_with_and_without_vertices():
    scene, geom, sensors = _placed("room-l")
    thin = np.zeros(scene.grid_shape, dtype=bool)
    points = np.array([[0.5, 1.0], [0.5, 2.0], [0.5, 3.0]])
    for vertices in (np.zeros((0, 2)), np.array([[0.5, 0.5], [4.5, 3.5]])):
        png = pictures.profile_png(scene, geom, thin, "t", Profile((points,), vertices),
                                   sensors)
        assert _decoded(png).shape == (1050, 1125, 3)
    scene, geom, sensors = _placed("plane-2m")  # no poses, no true vertices, no curves
    png = pictures.profile_png(scene, geom, np.zeros(scene.grid_shape, dtype=bool), "t",
                               Profile(()), sensors)
    assert _decoded(png).shape == (1050, 1125, 3)


def test_a_one_cell_curve_stays_visible_on_a_large_map():
    """A 3000 × 2000-cell map is shown by 5 × 5 blocks (at most MAP_PIXELS a side): a
    one-cell line and a single voted cell are still drawn, black, where they lie."""
    scene, _, _ = _placed("plane-2m")
    scene = dataclasses.replace(scene, extent=(0.0, 0.0, 30.0, 20.0), cell=0.01)
    image = np.zeros(scene.grid_shape, dtype=bool)
    image[1234, 100:2900] = True  # y = 12.34 m, x 1 to 29 m
    image[7, 2999] = True
    c, axes = pictures._plot(scene)
    pictures._map_image(c, axes, scene, image)
    row = axes.pixels(np.array([[0.0, 12.345]]))[0, 1]
    corner = axes.pixels(np.array([[29.995, 0.075]]))[0].astype(int)
    ink = np.flatnonzero((c.rgb[:, :corner[0] - 3] == 0).all(axis=2).any(axis=1))
    assert math.floor(row) - 2 <= ink.min() and ink.max() <= math.floor(row) + 2
    line = (c.rgb[math.floor(row) - 2:math.floor(row) + 3] == 0).all(axis=2).any(axis=0)
    x = axes.pixels(np.array([[1.05, 0.0], [28.95, 0.0]]))[:, 0].astype(int)
    assert line[x[0]:x[1]].all()
    assert (c.rgb[corner[1] - 3:corner[1] + 4, corner[0] - 3:corner[0] + 4] == 0).any()


def test_scene_png_draws_the_truth_the_echoes_and_a_title():
    """The room's scene.png: red along a wall, orange at a reflection point, dark text
    above the axes."""
    scene, geom, sensors = _placed("room-l")
    echoes = np.array([[0.5, 1.5]])
    picture = _decoded(pictures.scene_png(scene, geom, sensors, echoes)).astype(float)
    _, axes = pictures._plot(scene)
    (x, y), = axes.pixels(np.array([[geom.walls[0, 0] * 0.5 + geom.walls[0, 2] * 0.5,
                                     geom.walls[0, 1] * 0.5 + geom.walls[0, 3] * 0.5]]))
    assert picture[int(y), int(x), 0] > picture[int(y), int(x), 1] + 60  # red
    (ex, ey), = axes.pixels(echoes)
    assert np.abs(picture[int(ey), int(ex)] - canvas.COLOURS["tab:orange"]).max() < 60
    assert (picture[:int(axes.top) - 2] < 100).all(axis=2).any()  # the title's ink


def test_an_artist_drawn_in_parts_is_the_artist_drawn_at_once(monkeypatch):
    """Many segments and markers (a floor's transducers and echoes) are looked at a part at
    a time, in bounded memory (canvas.PART_PIXELS): the same picture as all at once, each
    pixel blended once with its largest share."""
    rng = np.random.default_rng(7)
    a, b = rng.uniform(5, 195, (300, 2)), rng.uniform(5, 195, (300, 2))
    centres = rng.uniform(0, 200, (500, 2))
    pictures_drawn = []
    for part in (1 << 20, 300):
        monkeypatch.setattr(canvas, "PART_PIXELS", part)
        c = canvas.Canvas(200, 200)
        c.lines(a, b, "tab:red", 0.8, 0.8)
        c.markers(centres, "x", "tab:orange", 3.0)
        c.markers(np.zeros((0, 2)), "o", "grey", 5.0)
        pictures_drawn.append(c.rgb)
    np.testing.assert_allclose(pictures_drawn[0], pictures_drawn[1], atol=1e-4)
    assert list(canvas._parts(np.array([5, 5, 5, 20, 1]), 10)) == [
        slice(0, 2), slice(2, 3), slice(3, 4), slice(4, 5)]


@pytest.mark.parametrize("marker", ["x", "o", "disc", "s"])
def test_markers_are_stamped_by_their_fraction_of_a_pixel(marker):
    """Canvas.markers stamps each centre (rounded to an eighth of a pixel, each place once)
    with its fraction's marker_pixels moved by whole pixels: the picture of marker_pixels
    at the rounded centres."""
    rng = np.random.default_rng(3)
    centres = rng.uniform(10, 90, (400, 2))
    centres = np.r_[centres, centres[:50]]  # drawn once
    stamped, direct = canvas.Canvas(100, 100), canvas.Canvas(100, 100)
    stamped.markers(centres, marker, "tab:blue", 5.0, 1.2)
    rounded = np.unique(np.round(centres * canvas.MARKER_GRID), axis=0) / canvas.MARKER_GRID
    direct.paint([canvas.marker_pixels(rounded, marker, canvas.px(5.0), canvas.px(1.2))],
                 "tab:blue")
    np.testing.assert_allclose(stamped.rgb, direct.rgb, atol=1e-3)
