"""The map stages' pictures drawn from the arrays (clsonar.pictures, issue 16), read back
by Pillow (an independent PNG decoder)."""

import io

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from clsonar import pictures
from clsonar.geometry import build_geometry
from clsonar.scene import Polyline, Scene

Image = pytest.importorskip("PIL.Image")


def _decoded(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


@settings(max_examples=50, deadline=None)
@given(arrays(np.uint8, st.tuples(st.integers(1, 40), st.integers(1, 40), st.just(3))))
def test_png_round_trips_through_an_independent_decoder(rgb):
    np.testing.assert_array_equal(_decoded(pictures.png(rgb)), rgb)


@settings(max_examples=100, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 30), st.integers(1, 30)),
              elements=st.floats(-5, 5)), st.integers(1, 7))
def test_block_max_is_each_blocks_largest_value(image, block):
    got = pictures.block_max(image, block)
    ny, nx = image.shape
    want = np.array([[image[i:i + block, j:j + block].max() for j in range(0, nx, block)]
                     for i in range(0, ny, block)])
    np.testing.assert_array_equal(got, want)


def test_a_map_picture_is_north_up_with_the_truth_in_red():
    """A 2 m × 1 m map at 1 cm: 200 × 100 pixels; its cell (iy 0, ix 10) is the picture's
    bottom row; a wall along y = 0.505 is red across the picture's middle row."""
    scene = Scene(name="p", extent=(0.0, 0.0, 2.0, 1.0), cell=0.01,
                  surfaces=(Polyline(points=((0.0, 0.505), (2.0, 0.505))),))
    image = np.zeros((100, 200))
    image[0, 10] = 3.0
    rgb = _decoded(pictures.map_picture(scene, build_geometry(scene), image))
    assert rgb.shape == (100, 200, 3)
    assert tuple(rgb[99, 10]) == tuple(pictures.VIRIDIS[-1].astype(np.uint8))
    assert tuple(rgb[99, 11]) == tuple(pictures.VIRIDIS[0].astype(np.uint8))
    row = rgb[100 - 1 - 50]
    assert np.all(row[:, 0] > 150) and np.all(row[:, 1] < 100)  # red over the dark map
    binary = _decoded(pictures.map_picture(scene, build_geometry(scene), image, binary=True))
    assert tuple(binary[99, 10]) == (0, 0, 0) and tuple(binary[0, 0]) == (255, 255, 255)


def test_a_wide_map_is_shown_by_blocks_that_keep_one_cell_arcs():
    scene = Scene(name="w", extent=(0.0, 0.0, 30.0, 1.0), cell=0.01)
    image = np.zeros((100, 3000))
    image[57, 1234] = 1.0
    rgb = _decoded(pictures.map_picture(scene, build_geometry(scene), image, binary=True))
    block = 3  # ceil(3000 / MAX_SIDE)
    assert rgb.shape == (34, 1000, 3)
    assert tuple(rgb[33 - 57 // block, 1234 // block]) == (0, 0, 0)
    assert np.count_nonzero(rgb[..., 0] == 0) == 1
