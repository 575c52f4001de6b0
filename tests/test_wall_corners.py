"""A short array far from a wall, with noise, fits its echoes of the wall's specular point
as well by a right-angled corner there (a corner's double bounce and a plane's echo differ
by about L²/(4r) of path, Kleeman & Kuc 1995); the plane another array located through
that point, which predicts them, takes them (clsonar/mapping/reflectors.py planes_own),
and the wall is drawn over both arrays' regions of constant depth (issue 14)."""

from __future__ import annotations

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
