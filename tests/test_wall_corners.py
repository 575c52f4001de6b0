"""A short array far from a wall, with noise, fits its echoes of the wall's specular point
as well by a right-angled corner there (a corner's double bounce and a plane's echo differ
by about L²/(4r) of path, Kleeman & Kuc 1995); the plane another array located through
that point, which predicts them, takes them (clsonar/mapping/reflectors.py planes_own),
and the wall is drawn over both arrays' regions of constant depth (issue 14)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from clsonar.mapping import reflectors
from clsonar.mapping.families import Family


def _case():
    from clsonar.tools.zoo import zoo

    (case,) = [c for c in zoo(3, ("wall",)) if c.name == "wall-08-arrays"]
    return case


def test_a_corner_on_another_arrays_plane_is_that_plane():
    """Zoo seed 3 wall-08 (a 6-element array at 6 m and an 8-element one, σ 1.2): the
    short array's 20 echoes were named a corner on the wall (its plane left one echo
    outside its tolerance) and its half of the wall was not drawn: 75 % complete. The
    8-element array's plane predicts 19 of them; they join it, the noisy one is left."""
    from clsonar import pipeline
    from clsonar.opencl import get_context

    case = _case()
    seen: list[tuple[list[str], list[str], int]] = []
    own = reflectors.planes_own

    def spy(families: list[Family]) -> tuple[list[Family], np.ndarray]:
        out, left = own(families)
        seen.append(([f.kind for f in families], [f.kind for f in out], len(left)))
        return out, left

    reflectors.planes_own = spy
    try:
        result = pipeline.run(case.scene, context=get_context(None))
    finally:
        reflectors.planes_own = own
    assert seen == [(["corner", "plane"], ["plane"], 1)]
    assert result.metrics["completeness"]["3cm"] == 1.0
    assert result.metrics["accuracy_m"]["rms"] <= 0.0005


def test_a_corner_no_plane_predicts_stays():
    """A corner whose echoes no larger plane predicts (here: no plane at all, or a plane
    of fewer rows) is kept, and nothing is left."""
    case = _case()
    from clsonar import pipeline
    from clsonar.opencl import get_context

    kept: list[list[Family]] = []
    own = reflectors.planes_own

    def spy(families: list[Family]) -> tuple[list[Family], np.ndarray]:
        kept.append(families)
        return own(families)

    reflectors.planes_own = spy
    try:
        pipeline.run(case.scene, context=get_context(None))
    finally:
        reflectors.planes_own = own
    (families,) = kept
    corners = [f for f in families if f.kind == "corner"]
    out, left = own(corners)
    assert [f.kind for f in out] == ["corner"] and len(left) == 0
    plane = next(f for f in families if f.kind == "plane")
    small = Family(plane.kind, plane.params, plane.x0, plane.rows[:5], plane.q[:5],
                   plane.rms, plane.window, plane.bend)
    out, left = own([corners[0], small])
    assert [f.kind for f in out] == ["corner", "plane"] and len(left) == 0


def _spread_args(seed: int, name: str) -> tuple[list[tuple], dict]:
    """The arguments of every :func:`~clsonar.mapping.patches.strength_bend` call of the
    zoo's case ``name`` at ``seed``, and its run's metrics."""
    from clsonar import pipeline
    from clsonar.mapping import patches
    from clsonar.opencl import get_context
    from clsonar.tools.zoo import zoo

    (case,) = [c for c in zoo(seed, ("wall",)) if c.name == name]
    calls: list[tuple] = []
    own = patches.strength_bend

    def spy(*args):
        calls.append(args)
        return own(*args)

    patches.strength_bend = spy
    try:
        result = pipeline.run(case.scene, context=get_context(None))
    finally:
        patches.strength_bend = own
    return calls, result.metrics


def test_a_walls_echo_strength_bounds_its_curvature():
    """Zoo seed 5 wall-07 (random lines 8 m from a wall, noise-free, 3 echoes of one
    plane): its paths leave the curvature unknown, so the plane was drawn only as far as
    a surface of radius no less than the range stays within 2 mm (±0.18 m), 61 %
    complete. Its echoes are a flat mirror's to 0.04 %: a wall bent by κ would give
    sqrt(L / (L + 2κ·d1·d2/cosθi)) of it (physics.curved_gain), so the strength bounds
    κ, and the plane is drawn over its regions of constant depth. Echoes weakened as a
    convex wall's of κ = 0.01 /m would measure that curvature back; of κ = 0.05 /m,
    which bends the wall more than 2 mm over its regions of constant depth (±0.39 m),
    they are a curved reflector's, and the strength bounds nothing."""
    from clsonar.mapping import patches
    from clsonar.physics import curved_gain

    calls, metrics = _spread_args(5, "wall-07-random-lines")
    assert metrics["completeness"]["3cm"] >= 0.99
    assert metrics["accuracy_m"]["rms"] <= 0.0001
    (args,) = calls
    p, scene, sensors, amplitude = args
    assert patches.strength_bend(*args) <= 1e-3
    q = patches.carrier_points(p.params, p.x0, p.u)
    d1, d2 = np.hypot(*(p.T - q).T), np.hypot(*(p.R - q).T)
    n = np.array([np.cos(p.params[0]), np.sin(p.params[0])])
    cos_i = np.abs(((p.T - q) / d1[:, None]) @ n)
    gentle = amplitude * curved_gain(d1, d2, np.full(len(q), 0.01), cos_i)
    assert abs(patches.strength_bend(p, scene, sensors, gentle) - 0.01) <= 0.001
    bent = amplitude * curved_gain(d1, d2, np.full(len(q), 0.05), cos_i)
    assert patches.strength_bend(p, scene, sensors, bent) == np.inf
    threshold = replace(scene, detection=replace(scene.detection, mode="threshold"))
    assert patches.strength_bend(p, threshold, sensors, amplitude) == np.inf


def test_a_far_short_arrays_wall_is_drawn_over_its_regions():
    """Zoo seed 4 wall-05 (4 elements 6 m from a wall, σ 0.6): the 10 echoes' paths bound
    the curvature to 0.19 /m (±0.14 m drawn past the reflection points, 58 % complete);
    their strength to about a tenth of that."""
    from clsonar.mapping import patches

    calls, metrics = _spread_args(4, "wall-05-arrays")
    assert metrics["completeness"]["3cm"] >= 0.99
    assert metrics["accuracy_m"]["rms"] <= 0.0005
    (args,) = calls
    assert args[0].bend > 0.15 and patches.strength_bend(*args) < 0.03
