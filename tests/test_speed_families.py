"""Issue 14's run time per scene (the zoo's arrays): the families' fits cheaper to the bit.
Each new form is checked against the one it replaced, kept here as the reference, on
generated inputs: the circle's specular points with T's and R's rows as two lines of one
array (not concatenated), a held parameter's Jacobian column not computed, a seed's
neighbours from every frontier row at once, a right-angled corner's path not turned."""

from __future__ import annotations

import functools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from clsonar.mapping import families, models

finite = functools.partial(st.floats, allow_nan=False, allow_infinity=False)


def _concatenated_circle_points(centre, rho, sign, T, R):
    """models.circle_points before: T's and R's rows concatenated, cos and sin twice."""
    cx, cy = float(centre[0]), float(centre[1])
    n = len(T)
    px, py = np.concatenate([T[:, 0], R[:, 0]]), np.concatenate([T[:, 1], R[:, 1]])
    ax, ay = sign * (cx - px), sign * (cy - py)
    la = np.maximum(np.hypot(ax, ay), 1e-300)
    ux, uy = ax / la, ay / la
    alpha = np.arctan2(uy[:n] + uy[n:], ux[:n] + ux[n:])
    for _ in range(models.SPECULAR_STEPS):
        c, s = np.cos(alpha), np.sin(alpha)
        c2, s2 = np.concatenate([c, c]), np.concatenate([s, s])
        dx, dy = cx - rho * c2 - px, cy - rho * s2 - py
        lu = np.maximum(np.hypot(dx, dy), 1e-300)
        proj = rho * (dx * s2 - dy * c2) / lu
        curv = (rho * rho - proj * proj + rho * (dx * c2 + dy * s2)) / lu
        grad, total = proj[:n] + proj[n:], curv[:n] + curv[n:]
        alpha = alpha - np.where(total != 0, grad / np.where(total != 0, total, 1.0), 0.0)
    qx, qy = cx - rho * np.cos(alpha), cy - rho * np.sin(alpha)
    path = np.hypot(T[:, 0] - qx, T[:, 1] - qy) + np.hypot(R[:, 0] - qx, R[:, 1] - qy)
    return path, np.stack([qx, qy], axis=-1)


def _pairs(seed: int, n: int, far: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    T = rng.normal(0.0, 2.0, (n, 2)) + far
    return T, T + rng.normal(0.0, 0.3, (n, 2))


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 50), far=finite(-2000.0, 2000.0),
       cx=finite(-6.0, 6.0), cy=finite(-6.0, 6.0), log_rho=finite(-3.0, 3.0),
       concave=st.booleans(), sign=st.sampled_from([-1.0, 1.0]))
def test_circle_points_are_the_concatenated_forms_bits(seed, n, far, cx, cy, log_rho,
                                                       concave, sign):
    T, R = _pairs(seed, n, far)
    centre = np.array([cx + far, cy + far])
    rho = (-1.0 if concave else 1.0) * 10.0**log_rho
    new, old = models.circle_points(centre, rho, sign, T, R), \
        _concatenated_circle_points(centre, rho, sign, T, R)
    assert new[0].tobytes() == old[0].tobytes() and new[1].tobytes() == old[1].tobytes()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(3, 300), psi=finite(-0.5, 0.5),
       kind=st.sampled_from(["plane", "curve held phi", "right corner"]))
def test_a_fit_with_held_parameters_is_the_whole_jacobians_bits(seed, n, psi, kind):
    """least_squares with the held columns not computed gives the bits it gave when the
    whole Jacobian was taken and its free columns cut out (Fortran order, as then)."""
    T, R = _pairs(seed, n, 0.0)
    x0 = T.mean(axis=0)
    if kind == "right corner":
        truth, steps, fixed = np.array([3.0, 4.0, 0.0]), models.TURN_STEPS, (False, False, True)
        start = truth + np.array([0.05, -0.03, 0.0])

        def model(p):
            return models.corner_paths(p, T, R)
    else:
        truth = np.array([0.3, 4.0 + float(x0 @ [np.cos(0.3), np.sin(0.3)]), psi])
        steps = models.CURVE_STEPS
        fixed = (False, False, True) if kind == "plane" else (True, False, False)
        start = truth + np.array([0.0 if kind != "plane" else 0.01, 0.02, 0.0])

        def model(p):
            return models.curve_paths(p, x0, T, R)
    paths = model(truth)[0] + 1e-4 * np.sin(np.arange(n))
    jacobian = models._jacobian

    def whole(model_, p, steps_, free, *rest):  # the former form: every column, then cut
        return jacobian(model_, p, steps_, np.ones(3, bool), *rest)[:, free]

    new = models.least_squares(model, paths, start, steps, fixed=np.asarray(fixed))
    try:
        models._jacobian = whole
        old = models.least_squares(model, paths, start, steps, fixed=np.asarray(fixed))
    finally:
        models._jacobian = jacobian
    assert new.params.tobytes() == old.params.tobytes() and new.rms == old.rms


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(2, 60), k=st.integers(1, 8))
def test_a_seeds_neighbours_from_all_frontier_rows_at_once_are_each_rows(seed, n, k):
    T, R = _pairs(seed, n, 0.0)
    w = families.Window(rows=np.arange(n), T=T, R=R, axT=T * 0, axR=R * 0,
                        paths=np.zeros(n), amplitude=np.ones(n), tolerance=np.zeros(n),
                        x0=np.zeros(2), cut_sin2=0.0, neighbour_m=0.1)
    rows = np.arange(n)
    frontier = np.random.default_rng(seed).integers(0, n, k)
    together = families._moved(w, frontier[:, None], rows)
    for i, a in enumerate(frontier):
        assert together[i].tobytes() == families._moved(w, int(a), rows).tobytes()


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 40), vx=finite(-5.0, 5.0),
       vy=finite(-5.0, 5.0))
def test_a_right_angled_corners_path_is_the_turned_forms_bits(seed, n, vx, vy):
    T, R = _pairs(seed, n, 0.0)
    v = np.array([vx, vy])
    turned = models._rotate(R - v, -0.0 * models._sides(v, T, R))  # by 0, as before
    old = np.hypot(*(T - v + turned).T)
    assert models.corner_paths(np.array([vx, vy, 0.0]), T, R)[0].tobytes() == old.tobytes()
