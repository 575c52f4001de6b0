"""Issue 16, the room's pipeline: post-processing's faster forms give the bits of the forms
they replace, kept here as the references."""

from __future__ import annotations

import numpy as np
import pytest

from clsonar.post import filters


def _low_pass_reference(raw: np.ndarray) -> np.ndarray:
    """``filters.low_pass`` before issue 16's pipeline work: whole-map passes."""
    p = np.pad(np.asarray(raw, dtype=np.float64), 1)
    ny, nx = p.shape[0] - 2, p.shape[1] - 2
    total = np.zeros((ny, nx))
    for dy in range(3):
        for dx in range(3):
            total += p[dy:dy + ny, dx:dx + nx]
    return total / 9.0


@pytest.mark.parametrize("share", [0.0, 1e-4, 0.01, 0.05, 0.5, 1.0])
def test_the_low_pass_by_rows_is_the_whole_maps_bits(share):
    """Votes on few cells or many, counts, fractional weights and negative values, votes on
    the map's border, maps of fewer and more rows than a block: the same values to the
    bit as the whole-map passes."""
    rng = np.random.default_rng(int(share * 1e4))
    for shape in [(1, 1), (1, 7), (5, 3), (60, 80), (filters.LOW_PASS_ROWS + 1, 9)]:
        raw = np.where(rng.random(shape) < share, rng.integers(1, 9, shape), 0)
        weights = raw * rng.random(shape) * rng.choice([-1.0, 1.0], shape)
        for m in (raw, weights):
            want = _low_pass_reference(m)
            got = filters.low_pass(m)
            assert got.dtype == np.float64 and got.tobytes() == want.tobytes()
    raw = np.zeros((40, 50))
    raw[0, 0], raw[39, 49], raw[20, 0], raw[5, 7] = 3.0, 1.0, 2.0, -0.0
    out = filters.low_pass(raw)
    assert out.tobytes() == _low_pass_reference(raw).tobytes()
    assert out[0, 0] == out[1, 1] == pytest.approx(3.0 / 9.0) and out[5, 7] == 0.0
    assert np.count_nonzero(out) == 4 + 4 + 6
