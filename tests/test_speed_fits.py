"""Issue 16, the room's pipeline: a cylinder's circle refined without scipy.optimize, the
point and circle fits' Jacobians taken from the
residual's own differences (``pillars._Lengths``) are ``pillars._directions`` to the bit
(tests/test_tangent_speed.py checks the whole fits against the loops they replaced), and
the isolated loci's arcs, all at once, are the locus-by-locus loop's, kept here."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.files import bundled_scenes
from clsonar.mapping import middles, pillars, tangents
from clsonar.mapping.envelope import in_beams
from clsonar.pipeline import run
from clsonar.post.circles import _refine_circle
from clsonar.scene import load_scene
from clsonar.tools.variants import with_seed


def test_the_kept_lengths_give_the_directions_bits():
    rng = np.random.default_rng(11)
    for k in (1, 3, 17, 40):
        T = rng.uniform(-5.0, 5.0, (k, 2))
        lengths = pillars._Lengths(T)
        x = rng.uniform(-5.0, 5.0, 3)
        h = lengths(x, x[:2])
        assert np.array_equal(h, np.hypot(*(x[:2] - T).T))
        kept = lengths.directions(x, x[:2])
        assert kept.tobytes() == pillars._directions(x[:2], T).tobytes()
        other = x.copy()  # equal values, another array: computed afresh, the same
        assert lengths.directions(other, other[:2]).tobytes() == kept.tobytes()
        trials = x[:2] - rng.normal(0.0, 1.0, (5, 2))
        assert lengths(trials, trials).shape == (5, k)  # a batch: nothing kept for one x
        assert lengths.directions(trials[2], trials[2]).tobytes() == pillars._directions(
            trials[2], T).tobytes()
    on = pillars._Lengths(np.array([[1.0, 2.0]]))  # x on T: no direction, 0 as before
    on(np.array([1.0, 2.0]), np.array([1.0, 2.0]))
    assert np.array_equal(on.directions(on.x, on.x), np.zeros((1, 2)))


def test_a_point_fit_reaches_the_point():
    """The corner a ring hears from four poses: the fit lands on it, its residuals 0."""
    corner = np.array([2.0, 3.0])
    T = np.array([[0.0, 0.0], [1.0, 0.2], [3.5, 0.5], [4.0, 1.0]])
    a = np.hypot(*(corner - T).T)
    v, r = pillars._point_from(T, T, a, np.array([2.3, 2.6]))
    np.testing.assert_allclose(v, corner, atol=1e-12)
    np.testing.assert_allclose(r, 0.0, atol=1e-12)


def _arc_around_reference(centre, radius, point, bias):
    """``tangents._arc_around`` before issue 16's pipeline work: one envelope point."""
    step = 2 * np.pi / tangents.LOCUS_SAMPLES
    half = int(np.sqrt(2.0 * bias / radius) / step)
    phi = np.arctan2(*(point - centre)[::-1]) + step * np.arange(-half, half + 1)
    return centre + radius * np.stack([np.cos(phi), np.sin(phi)], axis=-1)


def _isolated_points_reference(s, isolated, bias, linked, env):
    """``tangents._isolated_points`` before issue 16's pipeline work: locus by locus."""
    found, stubs = [], []
    for k, i in enumerate(isolated):
        mine = np.flatnonzero(env[0] == i)
        if len(mine):
            arcs = np.concatenate([_arc_around_reference(
                env[1][m], env[2][m], env[3][m], min(bias, tangents.ENVELOPE_ARC_BIAS_M))
                for m in mine])
            found.append(arcs[in_beams(arcs, s.T[i], s.axes[s.loci.tx[i]], s.cut_sin2)])
        elif i in linked:
            found.append(np.zeros((0, 2)))
        else:
            found.append(middles.middle_of_arc(s.p[i], s.inside[i], s.a[i], bias))
            if len(found[-1]):
                stubs.append(k)
    return found, stubs


@pytest.mark.parametrize("name, noise", [("room.json", 0.0), ("room-obstacles.json", 0.6),
                                         ("room-cylinder.json", 0.0)])
def test_the_isolated_loci_arcs_are_the_loops_bits(name, noise, monkeypatch):
    """The arcs around the scan envelope's points, all at once, and the loci's grouping:
    the loop's arcs, stubs and empty slots to the bit, on the rooms' own isolated loci."""
    calls = []
    mine = tangents._isolated_points

    def spy(*args):
        found, stubs = mine(*args)
        calls.append((args, (list(found), list(stubs))))  # the caller replaces slots
        return found, stubs

    monkeypatch.setattr(tangents, "_isolated_points", spy)
    scene = load_scene(bundled_scenes() / name)
    run(scene if noise == 0 else with_seed(scene, 1, noise))
    assert calls
    for args, (found, stubs) in calls:
        want, want_stubs = _isolated_points_reference(*args)
        assert stubs == want_stubs and len(found) == len(want) == len(args[1])
        for a, b in zip(found, want, strict=True):
            assert a.shape == b.shape and a.tobytes() == b.tobytes()
        assert sum(len(f) for f in found) > 100 and len(stubs) > 0


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.05, 3.0), st.floats(0.5, 6.2),
       st.sampled_from([0.0, 1e-4, 2e-3]))
def test_the_refined_circle_is_scipys_least_squares(seed, radius, span, noise):
    """``post.walls._refine_circle`` (Gauss–Newton, no scipy.optimize import) lands where
    ``scipy.optimize.least_squares`` does, from the same first guess: arcs of 0.5 rad to a
    whole turn, radii 5 cm to 3 m, points off by up to 2 mm. On an arc of a radian or more,
    or without noise, its sum of squares is never above scipy's (which stops where the
    cost changes by 1e-8 of itself: micrometres before the minimum along the arc's poorly
    fixed direction); on a shorter noisy arc both stop in a flat valley, millimetres
    apart, the sums of squares within 1 %."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(seed)
    centre = rng.uniform(-5, 5, 2)
    theta = rng.uniform(0, 2 * np.pi) + np.sort(rng.uniform(0, span, 40))
    points = centre + (radius + rng.normal(0, 1, 40) * noise)[:, None] * np.stack(
        [np.cos(theta), np.sin(theta)], -1)
    guess = centre + rng.normal(0, 0.02, 2) * radius, radius * rng.uniform(0.9, 1.1)
    got_c, got_r = _refine_circle(points, *guess)
    want = least_squares(lambda x: np.hypot(*(points - x[:2]).T) - x[2], np.r_[guess]).x
    cost = np.sum((np.hypot(*(points - got_c).T) - got_r) ** 2)
    want_cost = np.sum((np.hypot(*(points - want[:2]).T) - abs(want[2])) ** 2)
    if span >= 1.0 or noise == 0:
        np.testing.assert_allclose(np.r_[got_c, got_r], np.r_[want[:2], abs(want[2])],
                                   atol=1e-4 * max(1.0, radius))
        assert cost <= want_cost * (1 + 1e-9) + 1e-20  # round-off where both are exact
    else:  # a flat valley: both stop somewhere along it
        assert cost <= want_cost * 1.01


def test_the_heap_thresholds_are_set_once_and_handed_to_children(monkeypatch):
    """``heap.settle``: glibc takes both thresholds and the environment carries them to the
    processes a run starts (room workers); where the environment names either, nothing."""
    import os
    import subprocess
    import sys

    from clsonar import heap

    for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_"):
        monkeypatch.delenv(name, raising=False)
    assert heap.settle() is True
    assert os.environ["MALLOC_MMAP_THRESHOLD_"] == str(heap.MMAP_THRESHOLD)
    assert os.environ["MALLOC_TRIM_THRESHOLD_"] == str(heap.TRIM_THRESHOLD)
    child = subprocess.run([sys.executable, "-c", "import os; print(os.environ["
                            "'MALLOC_MMAP_THRESHOLD_'])"], capture_output=True, text=True)
    assert child.stdout.strip() == str(heap.MMAP_THRESHOLD)
    assert heap.settle() is False  # named already: left as it is
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "1000")
    monkeypatch.delenv("MALLOC_MMAP_THRESHOLD_")
    assert heap.settle() is False and "MALLOC_MMAP_THRESHOLD_" not in os.environ


def test_a_point_fit_made_again_is_the_first_fits_bits(monkeypatch):
    """``pillars._Fits``: the same loci (rows, not indices) from the same start fitted once
    — the room's clusters searched again once a reflector took some of their loci repeated
    173 of 371 point fits — each answer the bits of a fit made afresh, its point a copy."""
    rng = np.random.default_rng(43)
    T, R = rng.uniform(-3.0, 3.0, (9, 2)), rng.uniform(-3.0, 3.0, (9, 2))
    v = np.array([0.4, -0.2])
    a = 0.5 * (np.hypot(*(v - T).T) + np.hypot(*(v - R).T)) + rng.normal(0.0, 1e-3, 9)
    made = []
    fresh = pillars._point_from
    monkeypatch.setattr(pillars, "_point_from", lambda *x: made.append(1) or fresh(*x))
    fits = pillars._Fits()
    rows = np.arange(9)
    for near, start in [(rows[:6], (0.0, 0.0)), (rows[:6].copy(), (0.0, 0.0)),
                        (rows[3:], (0.0, 0.0)), (rows[:6], (0.1, 0.0)), (rows, (0.0, 0.0))]:
        got = fits(T[near], R[near], a[near], np.array(start))
        want = fresh(T[near], R[near], a[near], np.array(start))
        assert [g.tobytes() for g in got] == [w.tobytes() for w in want]
        got[0][:] = np.nan  # the caller's own copy
    assert len(made) == 4  # the second is the first's rows from the same start
