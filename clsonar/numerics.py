"""The numerical routines a run needs, reached without importing scipy's packages:
``import scipy.special`` costs a process about 0.1 s, ``scipy.optimize`` 0.35 s and
``scipy.interpolate`` 0.5 s (each pulls linalg, sparse, special and fft), more than a room's
whole mapping (issue 16: nothing imported that the command does not use).

- :func:`j1`, the Bessel function of the first kind of order one, by Cephes' rational
  approximations (S. L. Moshier, Cephes Math Library, ``j1.c``), the same coefficients and
  order of operations as ``scipy.special.j1``, so that the piston pattern
  (:func:`clsonar.physics.piston_pattern`) is scipy's to the bit;
- :func:`minimize_bounded`, Brent's minimiser of a function of one variable on an interval
  (R. P. Brent, *Algorithms for Minimization without Derivatives*, 1973, ch. 5; Forsythe,
  Malcolm & Moler's ``fmin``), step for step ``scipy.optimize.minimize_scalar(...,
  method="bounded")``;
- :func:`parametric_spline` and :func:`spline_values`, Dierckx's FITPACK smoothing spline of
  a curve (``parcur``/``clocur``, P. Dierckx, *Curve and Surface Fitting with Splines*,
  1993) and its values (``splev``): scipy's compiled FITPACK itself, loaded straight from
  its extension files (:func:`_fitpack`, 1 ms) rather than through ``scipy.interpolate``'s
  package, with the arguments ``scipy.interpolate.splprep``/``splev`` pass — so the same
  spline to the bit. Where those files are not found (another scipy's layout), the public
  ``splprep``/``splev`` are used instead;
- :func:`unique`, :func:`union1d`, :func:`setdiff1d`, :func:`median` and :func:`percentile`,
  NumPy's own answers without importing ``numpy.ma`` (7 ms of a process): the plain
  ``np.unique`` asks ``np.ma.is_masked``, ``np.median`` ``np.ma.isMaskedArray``, and
  ``np.percentile``, ``np.union1d`` and ``np.setdiff1d`` call the plain ``np.unique``;
- :func:`lstsq`, ``np.linalg.lstsq``'s least-squares solution, by NumPy's own LAPACK call
  without the wrapper's checks and conversions (6 against 16 µs: a room's pillar fits make
  500 of them);
- :func:`nearest_index`, the index of the value nearest each query, by binary search
  (tests/test_reflectors.py holds it to the argmin of the distances).

tests/test_numerics.py holds them all to scipy's and NumPy's answers, to the bit.
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import math
import os
import sys
import warnings
from collections.abc import Callable
from functools import cache
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from numpy.typing import ArrayLike

# Cephes j1.c: |x| <= 5, J1(x) = x·(x² − z1)(x² − z2)·RP(x²)/RQ(x²), z1, z2 the squares of
# its first two zeros; beyond, the asymptotic form with the phase and modulus polynomials.
_RP = (-8.99971225705559398224E8, 4.52228297998194034323E11, -7.27494245221818276015E13,
       3.68295732863852883286E15)
_RQ = (1.0, 6.20836478118054335476E2, 2.56987256757748830383E5, 8.35146791431949253037E7,
       2.21511595479792499675E10, 4.74914122079991414898E12, 7.84369607876235854894E14,
       8.95222336184627338078E16, 5.32278620332680085395E18)
_PP = (7.62125616208173112003E-4, 7.31397056940917570436E-2, 1.12719608129684925192E0,
       5.11207951146807644818E0, 8.42404590141772420927E0, 5.21451598682361504063E0,
       1.00000000000000000254E0)
_PQ = (5.71323128072548699714E-4, 6.88455908754495404082E-2, 1.10514232634061696926E0,
       5.07386386128601488557E0, 8.39985554327604159757E0, 5.20982848682361821619E0,
       9.99999999999999997461E-1)
_QP = (5.10862594750176621635E-2, 4.98213872951233449420E0, 7.58238284132545283818E1,
       3.66779609360150777800E2, 7.10856304998926107277E2, 5.97489612400613639965E2,
       2.11688757100572135698E2, 2.52070205858023719784E1)
_QQ = (1.0, 7.42373277035675149943E1, 1.05644886038262816351E3, 4.98641058337653607651E3,
       9.56231892404756170795E3, 7.99704160447350683650E3, 2.82619278517639096600E3,
       3.36093607810698293419E2)
_Z1 = 1.46819706421238932572E1
_Z2 = 4.92184563216946036703E1
_THPIO4 = 2.35619449019234492885  # 3π/4
_SQ2OPI = 7.9788456080286535587989E-1  # √(2/π)


def principal_axes(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(centre, axes, rms)`` of the points [n, 2]: their mean, the rows of V of the SVD of
    the centred points (``axes[0]`` along their total-least-squares line, ``axes[-1]``
    across it) and their RMS distance from that line (0 for a single point)."""
    p = np.asarray(points, dtype=np.float64)
    centre = p.mean(axis=0)
    _, sv, vt = np.linalg.svd(p - centre, full_matrices=False)
    return centre, vt, float(sv[1] / math.sqrt(len(p))) if len(sv) > 1 else 0.0


def unique(values: ArrayLike, axis: int | None = None) -> np.ndarray:
    """``np.unique(values, axis=axis)``: the sorted distinct values (or rows), by the form
    that counts them, which does not import ``numpy.ma``."""
    return np.unique(values, axis=axis, return_counts=True)[0]


def union1d(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """``np.union1d(a, b)``: the sorted distinct values of both (:func:`unique`)."""
    return unique(np.concatenate((a, b), axis=None))


def setdiff1d(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """``np.setdiff1d(a, b)``: the sorted distinct values of ``a`` not in ``b``."""
    first = unique(a)
    return first[np.isin(first, b, invert=True)]


def median(values: ArrayLike, axis: int | None = None) -> Any:
    """``np.median(values, axis=axis)`` for a real array: the middle of the sorted values,
    or the mean ``(a + b)/2`` of the two middle ones (NumPy's ``mean`` of two: their sum
    over 2); NaN where a NaN is among them."""
    v = np.sort(np.asarray(values, dtype=np.float64), axis=axis)
    v = np.moveaxis(v, axis, 0) if axis is not None else v
    n = len(v)
    if n == 0:
        return np.float64(np.nan) if axis is None else np.full(v.shape[1:], np.nan)
    middle = v[n // 2] if n % 2 else (v[n // 2 - 1] + v[n // 2]) / 2.0
    return np.where(np.isnan(v[-1]), np.nan, middle)[()]


def percentile(values: ArrayLike, q: ArrayLike) -> Any:
    """``np.percentile(values, q)`` of a 1-D real array by its default ("linear") method:
    at the virtual index (n − 1)·q/100 of the sorted values, between the values either
    side, a + (b − a)·γ, or b − (b − a)·(1 − γ) from γ = 0.5 on (NumPy's ``_lerp``)."""
    v = np.sort(np.asarray(values, dtype=np.float64))
    at = (len(v) - 1) * (np.asarray(q, dtype=np.float64) / 100)
    below = np.floor(at)
    after = np.minimum(below + 1, len(v) - 1).astype(np.intp)
    gamma = at - below
    a, b = v[below.astype(np.intp)], v[after]
    step = b - a
    out = np.where(gamma >= 0.5, b - step * (1 - gamma), a + step * gamma)
    return np.where(np.isnan(v[-1]), np.nan, out)[()]


def nearest_index(values: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """For each of ``queries``, the index of the nearest of ``values`` (ties: the lowest
    index), as ``np.abs(queries[:, None] - values).argmin(axis=1)`` gives it, by binary
    search instead of the [queries × values] matrix (a joined wall seen by a 1000-element
    array: 2400 × 10⁵ distances, 2 GB; :func:`clsonar.mapping.patches.draw_patch`)."""
    order = np.argsort(values, kind="stable")
    v = np.asarray(values, dtype=np.float64)[order]
    k = np.searchsorted(v, queries, side="left")  # v[k] is the first ≥ the query
    right = np.minimum(k, len(v) - 1)
    left = np.searchsorted(v, v[np.maximum(k - 1, 0)], side="left")  # its run's first
    d_right = np.where(k < len(v), np.abs(v[right] - queries), np.inf)
    d_left = np.where(k > 0, np.abs(queries - v[left]), np.inf)
    take_left = (d_left < d_right) | ((d_left == d_right) & (order[left] < order[right]))
    return np.where(take_left, order[left], order[right])


def _lstsq_failed(*_: object) -> None:
    raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")


#: NumPy's gufunc behind ``np.linalg.lstsq`` (LAPACK's ``dgelsd``), None where a NumPy
#: lays it out otherwise (then the public function is called).
_GELSD = getattr(getattr(np.linalg, "_umath_linalg", None), "lstsq", None)
_EPS = float(np.finfo(np.float64).eps)


def lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.lstsq(a, b, rcond=None)[0]`` for a real float64 ``a`` [m, n] (m ≥ 1) and
    ``b`` [m]: the same gufunc with the same cut-off (ε·max(m, n)) and the same error on
    failure, so the same bits; only the wrapper's checks, which these arrays pass, left
    out."""
    if _GELSD is None:
        return np.linalg.lstsq(a, b, rcond=None)[0]
    with np.errstate(call=_lstsq_failed, invalid="call", over="ignore", divide="ignore",
                     under="ignore"):
        x = _GELSD(a, b[:, None], _EPS * max(a.shape), signature="ddd->ddid")[0]
    return x[:, 0]


def _polynomial(z: np.ndarray, coefficients: tuple[float, ...]) -> np.ndarray:
    """Horner's rule, highest power first; a leading 1 is Cephes' ``p1evl`` (the first
    product skipped, as there)."""
    if coefficients[0] == 1.0:
        out, rest = z + coefficients[1], coefficients[2:]
    else:
        out, rest = np.full_like(z, coefficients[0]), coefficients[1:]
    for c in rest:
        out = out * z + c
    return out


def j1(x: np.ndarray | float) -> np.ndarray:
    """Bessel function J1(x), float64, as ``scipy.special.j1`` (Cephes)."""
    x = np.asarray(x, dtype=np.float64)
    a = np.abs(x)
    out = np.empty_like(a)
    small = a <= 5.0
    s = a[small]
    z = s * s
    out[small] = _polynomial(z, _RP) / _polynomial(z, _RQ) * s * (z - _Z1) * (z - _Z2)
    big = a[~small]
    if big.size:
        w = 5.0 / big
        z = w * w
        p = _polynomial(z, _PP) / _polynomial(z, _PQ)
        q = _polynomial(z, _QP) / _polynomial(z, _QQ)
        phase = (big - _THPIO4).tolist()  # the C library's cos and sin, as Cephes calls them
        cos = np.array([math.cos(v) for v in phase])
        sin = np.array([math.sin(v) for v in phase])
        out[~small] = (p * cos - w * q * sin) * _SQ2OPI / np.sqrt(big)
    return np.where(x < 0, -out, out)


def minimize_bounded(f: Callable[[float], float], lower: float, upper: float,
                     xatol: float = 1e-5, max_evaluations: int = 500) -> float:
    """The x in [lower, upper] that minimises ``f``: Brent's golden-section search with
    parabolic steps, stopped when the bracket is within ``xatol`` (absolute) and
    ``√ε·|x|`` of its best point — ``scipy.optimize.minimize_scalar(f, bounds=(lower,
    upper), method="bounded").x`` step for step (the same evaluations, the same answer)."""
    sqrt_eps = math.sqrt(2.2e-16)
    golden = 0.5 * (3.0 - math.sqrt(5.0))
    a, b = lower, upper
    v = w = x = a + golden * (b - a)  # the best point so far is x, then w, then v
    fx = fw = fv = f(x)
    step = previous = 0.0
    evaluations = 1
    middle = 0.5 * (a + b)
    tol1 = sqrt_eps * np.abs(x) + xatol / 3.0
    tol2 = 2.0 * tol1
    while np.abs(x - middle) > tol2 - 0.5 * (b - a):
        parabolic = False
        if np.abs(previous) > tol1:  # the parabola through (v, w, x), if acceptable
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = np.abs(q)
            r, previous = previous, step
            if np.abs(p) < np.abs(0.5 * q * r) and q * (a - x) < p < q * (b - x):
                parabolic = True
                step = (p + 0.0) / q
                u = x + step
                if (u - a) < tol2 or (b - u) < tol2:  # not so near either bound
                    step = tol1 * (np.sign(middle - x) + ((middle - x) == 0))
        if not parabolic:  # a golden-section step into the larger part
            previous = (a - x) if x >= middle else (b - x)
            step = golden * previous
        u = x + (np.sign(step) + (step == 0)) * np.maximum(np.abs(step), tol1)
        fu = f(u)
        evaluations += 1
        if fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
        middle = 0.5 * (a + b)
        tol1 = sqrt_eps * np.abs(x) + xatol / 3.0
        tol2 = 2.0 * tol1
        if evaluations >= max_evaluations:
            break
    return float(x)


#: A spline as FITPACK gives it: knots, one row of coefficients per coordinate, degree.
Spline = tuple[np.ndarray, np.ndarray, int]

#: FITPACK's curfit/parcur error codes above 0 that still return a spline (scipy warns).
_USABLE_IER = {1: "the storage needed exceeds the storage available (s too small)",
               2: "a theoretically impossible result (s too small)",
               3: "the maximum of 20 iterations reached (s too small)"}


def _extension(package: str, name: str) -> ModuleType | None:
    """The compiled module ``package.name`` from its file, without running ``package``'s
    ``__init__`` (None where no such file is found)."""
    full = f"{package}.{name}"
    if full in sys.modules:
        return sys.modules[full]
    found = importlib.util.find_spec(package.split(".")[0])
    if found is None or found.origin is None:
        return None
    folder = os.path.join(os.path.dirname(found.origin), *package.split(".")[1:])
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = os.path.join(folder, name + suffix)
        if os.path.exists(path):
            spec = importlib.util.spec_from_file_location(full, path)
            if spec is None or spec.loader is None:
                return None
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            return module
    return None


#: The scipy releases whose private FITPACK wrappers :func:`parametric_spline` and
#: :func:`spline_values` call as ``splprep``/``splev`` do (checked to the bit by
#: tests/test_numerics.py); any other release gets the public functions.
FITPACK_SCIPY = ("1.15.", "1.16.", "1.17.")


def fitpack_release() -> bool:
    """Whether the installed scipy is a release of :data:`FITPACK_SCIPY`, whose private
    FITPACK wrappers :func:`_fitpack` loads (another gets ``scipy.interpolate``'s public
    functions)."""
    return installed_version("scipy").startswith(FITPACK_SCIPY)


def installed_version(package: str) -> str:
    """The installed ``package``'s version: from the one ``NAME-VERSION.dist-info`` folder
    beside it (a wheel's layout, PEP 427: one listing of its folder, 0.1 ms), else
    ``importlib.metadata``'s (which reads every installed distribution's metadata: 3 ms a
    run, and 15 ms to import where nothing has)."""
    found = importlib.util.find_spec(package)
    if found is not None and found.origin is not None:
        folder = os.path.dirname(os.path.dirname(found.origin))
        names = [n for n in os.listdir(folder)
                 if n.startswith(f"{package}-") and n.endswith(".dist-info")]
        if len(names) == 1:
            return names[0][len(package) + 1:-len(".dist-info")]
    from importlib import metadata

    return metadata.version(package)


@cache
def _fitpack() -> tuple[Any, Any] | None:
    """scipy's FITPACK wrappers ``(_fitpack, _dfitpack)``, the modules its ``splprep`` and
    ``splev`` call, or None where they cannot be loaded so, or scipy is not a release of
    :data:`FITPACK_SCIPY` (:func:`fitpack_release`)."""
    try:
        if not fitpack_release():
            return None
        if sys.modules.get("scipy.interpolate") is not None:  # paid for: the package's own
            from scipy.interpolate import _dfitpack, _fitpack

            return _fitpack, _dfitpack
    except ImportError:
        return None
    try:
        c, f2py = (_extension("scipy.interpolate", "_fitpack"),
                   _extension("scipy.interpolate", "_dfitpack"))
    except ImportError:
        return None
    if c is None or f2py is None or not hasattr(c, "_parcur") or not hasattr(f2py, "splev"):
        return None
    return c, f2py


def parametric_spline(points: np.ndarray, u: np.ndarray, s: float, closed: bool,
                      k: int = 3) -> Spline:
    """The smoothing spline of degree ``k`` through the [dims, m] ``points`` at parameter
    values ``u`` with smoothing factor ``s`` (FITPACK's parcur; clocur, periodic, where
    ``closed``; the first and last points of a closed curve must be equal): scipy's
    ``splprep(points, u=u, s=s, k=k, per=closed)`` without its package import. Raises
    ValueError or TypeError as splprep does where FITPACK refuses the data."""
    modules = _fitpack()
    if modules is None:
        from scipy import interpolate

        (t, c, k), _ = interpolate.splprep(points, u=u, s=s, k=k, per=int(closed))
        return t, np.asarray(c), k
    c_module, f2py = modules
    x = np.atleast_1d(points)
    dims, m = x.shape
    if m <= k:
        raise TypeError("m > k must hold")
    nest = max(m + 2 * k if (s != 0 or closed) else m + k + 1, 2 * k + 3)
    t, c, out = c_module._parcur(
        np.ravel(np.transpose(x)), np.ones(m, float), u, u[0], u[-1], k, 0, True, s,
        np.array([], float), nest, np.array([], float),
        np.array([], f2py.types.intvar.dtype), int(closed))
    ier = out["ier"]
    if ier in _USABLE_IER:
        warnings.warn(RuntimeWarning(f"FITPACK: {_USABLE_IER[ier]}"), stacklevel=2)
    elif ier > 0:
        raise (ValueError if ier == 10 else TypeError)(f"FITPACK refused the curve (ier {ier})")
    return t, c.reshape((dims, len(t) - k - 1)), k


def spline_values(x: np.ndarray, spline: Spline) -> np.ndarray:
    """[dims, len(x)] the values of a :func:`parametric_spline` at ``x`` (FITPACK's splev,
    extrapolating beyond the knots): scipy's ``splev(x, spline)``."""
    t, c, k = spline
    modules = _fitpack()
    if modules is None:
        from scipy import interpolate

        return np.asarray(interpolate.splev(x, (t, list(c), k)))
    x = np.atleast_1d(np.asarray(x)).ravel()
    rows = []
    for row in c:
        y, ier = modules[1].splev(t, row, k, x, 0)
        if ier:
            raise ValueError(f"FITPACK could not evaluate the spline (ier {ier})")
        rows.append(y)
    return np.stack(rows)
