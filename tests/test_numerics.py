"""clsonar.numerics against scipy, which it stands in for on a run's path (issue 16)."""

from __future__ import annotations

import importlib.metadata
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize, special

from clsonar.numerics import (
    fitpack_release,
    installed_version,
    j1,
    lstsq,
    median,
    minimize_bounded,
    parametric_spline,
    percentile,
    setdiff1d,
    spline_values,
    union1d,
    unique,
)

#: The installed scipy; its j1 and FITPACK wrappers are matched to the bit only by the
#: releases checked here (another release's are held to their values, not their bits).
SCIPY = importlib.metadata.version("scipy")


def _ulps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance in units of the last place (0 where equal)."""
    return np.abs(a - b) / np.spacing(np.maximum(np.abs(a), np.abs(b)))


@pytest.mark.parametrize("lo, hi", [(0.0, 5.0), (0.0, 1e-3), (3.8, 3.85), (4.99, 5.01),
                                    (5.0, 40.0), (40.0, 1e4), (-30.0, 30.0)])
def test_j1_is_cephes(lo: float, hi: float) -> None:
    """Both branches of Cephes' j1 (|x| ≤ 5 and beyond) as scipy has them: the same bits
    here (scipy 1.17; 1.14.1 gave the same bits too), within 2 units of the last place on
    that release. Another release may compute j1 otherwise (the NVIDIA machine's scipy,
    its version not printed, differed by up to 3e8 units of the last place next to J1's
    zeros, by how much in value that run did not say): there the values agree within
    1e-13 (|J1| ≤ 0.582; the piston pattern needs far less)."""
    x = np.random.default_rng(7).uniform(lo, hi, 200_000)
    if not SCIPY.startswith("1.17."):
        np.testing.assert_allclose(j1(x), special.j1(x), rtol=0, atol=1e-13)
        return
    ulps = _ulps(j1(x), special.j1(x))
    assert np.max(ulps) <= 2.0
    assert np.mean(ulps == 0) > 0.99


def test_j1_special_values() -> None:
    x = np.array([0.0, -0.0, 5.0, -5.0, 1e-320, 3.8317059702075125])
    assert np.allclose(j1(x), special.j1(x), rtol=0, atol=1e-16)
    assert j1(0.0) == 0.0 and j1(np.array([2.0, -2.0]))[1] == -j1(2.0)


def _scipys(f, lo: float, hi: float) -> float:
    return float(optimize.minimize_scalar(f, bounds=(lo, hi), method="bounded").x)


@settings(max_examples=200, deadline=None)
@given(centre=st.floats(-10, 10), width=st.floats(1e-4, 5), lo=st.floats(-10, 10),
       span=st.floats(1e-3, 10), power=st.sampled_from([1.0, 2.0, 4.0]))
def test_minimize_bounded_is_scipys_bounded_brent(centre: float, width: float, lo: float,
                                                  span: float, power: float) -> None:
    """The same evaluations, so the same answer, on smooth and kinked functions whose
    minimum lies inside the bounds, at a bound or outside them."""
    def f(x: float) -> float:
        return float(abs(x - centre) ** power / width + math.sin(3.0 * x) * 0.1 * width)

    assert minimize_bounded(f, lo, lo + span) == _scipys(f, lo, lo + span)


def test_minimize_bounded_on_the_plane_test() -> None:
    """The spread of a plane's loci over normal directions (mapping.pillars._a_plane's
    objective: a maximum of absolute values, kinked), as scipy finds it."""
    rng = np.random.default_rng(3)
    centres = rng.uniform(-1, 1, (12, 2))
    a = 2.0 - centres @ np.array([math.cos(0.7), math.sin(0.7)]) + rng.normal(0, 1e-4, 12)

    def spread(t: float) -> float:
        r = a + centres @ np.array([math.cos(t), math.sin(t)])
        return float(np.max(np.abs(r - r.mean())))

    assert minimize_bounded(spread, 0.68, 0.72) == _scipys(spread, 0.68, 0.72)
    assert abs(minimize_bounded(spread, 0.68, 0.72) - 0.7) < 1e-3


def _scipys_spline(points: np.ndarray, u: np.ndarray, s: float, closed: bool,
                   x: np.ndarray) -> np.ndarray:
    from scipy import interpolate

    tck, _ = interpolate.splprep(points, u=u, s=s, k=3, per=int(closed))
    return np.stack(interpolate.splev(x, tck))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(4, 120), noise=st.floats(0.0, 0.01),
       closed=st.booleans(), s_scale=st.floats(0.0, 2.0))
def test_the_spline_is_scipys_fitpack(seed: int, m: int, noise: float, closed: bool,
                                      s_scale: float) -> None:
    """A noisy arc or closed loop, any smoothing: knots, coefficients and values to the bit
    (the same FITPACK called with the same arguments)."""
    rng = np.random.default_rng(seed)
    angle = np.linspace(0.0, 2 * np.pi if closed else rng.uniform(0.3, 4.0), m)
    p = np.stack([np.cos(angle), 0.7 * np.sin(angle)], axis=1) + rng.normal(0, noise, (m, 2))
    if closed:
        p[-1] = p[0]
    steps = np.hypot(*np.diff(p, axis=0).T)
    if np.any(steps == 0):
        return
    u = np.r_[0.0, np.cumsum(steps)]
    x = np.linspace(-0.1, u[-1] + 0.1, 57)
    s = m * (s_scale * max(noise, 1e-4)) ** 2
    try:
        ours = spline_values(x, parametric_spline(p.T, u, s, closed))
    except (ValueError, TypeError) as error:
        with pytest.raises(type(error)):
            _scipys_spline(p.T, u, s, closed, x)
        return
    assert np.array_equal(ours, _scipys_spline(p.T, u, s, closed, x))



def test_the_spline_without_the_extension_files_is_scipys_public_one(monkeypatch) -> None:
    """Where scipy's FITPACK files are not where clsonar looks (another scipy's layout),
    the public splprep/splev give the same spline."""
    import clsonar.numerics as numerics

    t = np.linspace(0.0, 1.5, 30)
    p = np.stack([t, np.sin(t)])
    x = np.linspace(0.0, 1.5, 11)
    direct = spline_values(x, parametric_spline(p, t, 1e-4, False))
    monkeypatch.setattr(numerics, "_fitpack", lambda: None)
    assert np.array_equal(spline_values(x, parametric_spline(p, t, 1e-4, False)), direct)


@pytest.mark.skipif(not fitpack_release(),
                    reason=f"scipy {SCIPY}'s FITPACK wrappers are not the ones checked")
def test_another_scipy_release_gets_the_public_functions(monkeypatch) -> None:
    """The private wrappers are called only for the releases whose splprep/splev call them
    so (FITPACK_SCIPY); any other release's private layout is not trusted."""
    import clsonar.numerics as numerics

    monkeypatch.setattr(numerics, "installed_version", lambda name: "1.99.0")
    assert numerics._fitpack.__wrapped__() is None
    monkeypatch.setattr(numerics, "installed_version", lambda name: "1.17.9")
    assert numerics._fitpack.__wrapped__() is not None


_REALS = st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from([0.0, 0.5, -2.0]))


def _same(ours, numpy_s) -> None:
    """The same value, type, dtype and shape, to the bit (NaN where NumPy has NaN)."""
    assert type(ours) is type(numpy_s)
    assert np.asarray(ours).dtype == np.asarray(numpy_s).dtype
    assert np.array_equal(ours, numpy_s, equal_nan=True)


@settings(max_examples=300, deadline=None)
@given(st.lists(_REALS, min_size=1, max_size=40), st.booleans(),
       st.lists(st.floats(0.0, 100.0), min_size=1, max_size=3), st.booleans())
def test_median_and_percentile_are_numpys(values: list[float], nan: bool, qs: list[float],
                                          one: bool) -> None:
    """numerics.median and numerics.percentile give NumPy's answers to the bit (and NaN
    where a value is NaN), one percentile or several."""
    a = np.array(values + [math.nan] * nan)
    _same(median(a), np.median(a))
    q = qs[0] if one else qs
    _same(percentile(a, q), np.percentile(a, q))
    m = np.resize(a, (len(a), 3)) * np.array([1.0, -1.0, 0.5])
    _same(median(m, axis=0), np.median(m, axis=0))
    _same(median(m, axis=1), np.median(m, axis=1))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-5, 5), max_size=30), st.lists(st.integers(-5, 5), max_size=10),
       st.lists(_REALS, max_size=10))
def test_unique_union_and_difference_are_numpys(ints: list[int], others: list[int],
                                                reals: list[float]) -> None:
    """numerics.unique, union1d and setdiff1d give NumPy's sorted arrays, of its dtype."""
    i, j, r = np.array(ints, dtype=np.int64), np.array(others, dtype=np.int64), np.array(reals)
    _same(unique(i), np.unique(i))
    _same(unique(r), np.unique(r))
    _same(union1d(i, j), np.union1d(i, j))
    _same(union1d(i, r), np.union1d(i, r))
    _same(setdiff1d(i, j), np.setdiff1d(i, j))
    rows = np.resize(i, (len(i) // 2, 2)) if len(i) >= 2 else np.zeros((0, 2), np.int64)
    _same(unique(rows, axis=0), np.unique(rows, axis=0))


@pytest.mark.parametrize("package", ["scipy", "numpy", "pyopencl"])
def test_an_installed_version_is_importlib_metadata_s(package: str) -> None:
    """numerics.installed_version reads the package's dist-info folder's name: the version
    importlib.metadata gives (which reads every installed distribution's metadata)."""
    assert installed_version(package) == importlib.metadata.version(package)


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 40), st.integers(1, 3), st.integers(0, 2**32 - 1), st.booleans(),
       st.sampled_from([1e-6, 1.0, 1e6]))
def test_lstsq_is_numpys(m: int, n: int, seed: int, repeated: bool, scale: float) -> None:
    """numerics.lstsq gives np.linalg.lstsq's solution to the bit: over- and
    under-determined, of full rank or with a column repeated (rank-deficient), at any
    scale."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(m, n)) * scale
    if repeated and n > 1:
        a[:, -1] = a[:, 0]
    b = rng.normal(size=m)
    _same(lstsq(a, b), np.linalg.lstsq(a, b, rcond=None)[0])
    column = np.asfortranarray(a)  # as the Gauss–Newton Jacobians are laid out
    _same(lstsq(column, b), np.linalg.lstsq(column, b, rcond=None)[0])


def test_lstsq_fails_as_numpy_does() -> None:
    """A NaN makes LAPACK's SVD fail: numpy's LinAlgError, as np.linalg.lstsq raises."""
    with pytest.raises(np.linalg.LinAlgError, match="SVD did not converge"):
        lstsq(np.full((3, 2), np.nan), np.ones(3))
