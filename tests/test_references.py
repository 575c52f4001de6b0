"""The reference solutions of clsonar.tools.references against themselves and the textbooks:
the piston's pattern, the Kirchhoff flat plane (the image source), the cylinder three ways
(series, Kirchhoff, geometrical optics), the BTM wedge at its zone boundaries and against
Keller's GTD, and a sinusoidal surface's focusing and caustic."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from clsonar.tools import references as ref

C = 343.0
F = ref.F_DEFAULT
K = 2 * math.pi * F / C


def _db(x: float, y: float) -> float:
    return abs(20 * math.log10(x / y))


def _polar(rho: float, theta: float) -> tuple[float, float]:
    return (rho * math.cos(theta), rho * math.sin(theta))


def _circle(a: float, n: int = 2001) -> np.ndarray:
    th = np.linspace(0.0, 2 * np.pi, n)
    return np.column_stack([a * np.cos(th), a * np.sin(th)])


def test_the_references_import_nothing_from_clsonar():
    tree = ast.parse(Path(ref.__file__).read_text(encoding="utf-8"))
    roots = {alias.name.split(".")[0] for node in ast.walk(tree)
             if isinstance(node, ast.Import) for alias in node.names}
    roots |= {node.module.split(".")[0] for node in ast.walk(tree)
              if isinstance(node, ast.ImportFrom) and node.module and not node.level}
    assert not any(isinstance(n, ast.ImportFrom) and n.level for n in ast.walk(tree))
    assert roots <= {"__future__", "math", "dataclasses", "numpy", "scipy"}


# --- the piston ---------------------------------------------------------------------------


def test_the_piston_is_one_on_axis_and_null_at_the_first_zero_of_j1():
    ka = 12.0
    assert ref.piston_two_way(0.0, 0.0, ka) == pytest.approx(1.0)
    null = math.asin(3.8317 / ka)
    assert abs(ref.piston_two_way(null, 0.0, ka)) < 1e-4
    assert abs(ref.piston_two_way(0.0, -null, ka)) < 1e-4
    theta = np.linspace(-0.2, 0.2, 9)
    assert np.allclose(ref.piston_two_way(theta, theta, ka),
                       ref.piston_two_way(-theta, 0.0, ka) ** 2)
    # the 3 dB (one way) point of a piston: ka sinθ = 1.616
    assert ref.piston_two_way(math.asin(1.616 / ka), 0.0, ka) == pytest.approx(
        1 / math.sqrt(2), abs=1e-3)


# --- Kirchhoff: the flat plane is the image source ----------------------------------------

FLAT = np.array([[-10.0, 0.0], [10.0, 0.0]])


@pytest.mark.parametrize("s, r", [((0.0, 2.0), (0.0, 2.0)), ((-1.0, 2.0), (1.5, 1.0)),
                                  ((-3.0, 0.5), (2.0, 0.8))])
def test_a_flat_plane_gives_the_image_source(s, r):
    length = math.hypot(r[0] - s[0], r[1] + s[1])
    assert ref.kirchhoff_gain_near(FLAT, s, r, length / C) == pytest.approx(1.0, rel=0.01)


def test_the_echo_list_of_a_flat_plane_is_its_specular_echo():
    echoes = ref.kirchhoff_echo(FLAT, (0.0, 2.0), (0.0, 2.0))
    assert len(echoes) == 1
    delay, gain = echoes[0]
    assert delay == pytest.approx(4.0 / C, abs=2e-6)
    assert gain == pytest.approx(1.0, rel=0.01)


def test_pistons_facing_the_plane_leave_its_gain_and_turning_them_away_cuts_it():
    s, axis = (0.0, 2.0), (0.0, -1.0)
    on = ref.kirchhoff_gain_near(FLAT, s, s, 4 / C, ka=10.0, axis_s=axis, axis_r=axis)
    tilted = (math.sin(0.2), -math.cos(0.2))
    off = ref.kirchhoff_gain_near(FLAT, s, s, 4 / C, ka=10.0, axis_s=tilted, axis_r=tilted)
    assert on == pytest.approx(1.0, rel=0.02)
    assert off == pytest.approx(float(ref.piston_two_way(0.2, 0.2, 10.0)), rel=0.03)


# --- the cylinder: series, Kirchhoff and geometrical optics -------------------------------


@pytest.mark.parametrize("a, d", [(0.1, 1.0), (0.5, 2.0), (0.05, 0.5)])
def test_a_cylinder_seen_monostatically(a, d):
    s = (0.0, a + d)
    go = ref.cylinder_go_gain(s, s, (0.0, 0.0), a)
    assert go == pytest.approx(math.sqrt(a / (a + d)))
    assert _db(ref.cylinder_series_gain(s, s, (0.0, 0.0), a, K), go) < 0.5
    assert _db(ref.cylinder_series_echo_gain(s, s, (0.0, 0.0), a, C, F), go) < 0.5
    assert _db(ref.kirchhoff_gain_near(_circle(a), s, s, 2 * d / C), go) < 0.5


def test_a_cylinder_seen_bistatically():
    a, s, r = 0.2, (-0.5, 1.0), (0.6, 0.8)
    length, d1, d2, cos_i = ref.cylinder_specular(s, r, (0.0, 0.0), a)
    assert 0 < cos_i < 1 and length == pytest.approx(d1 + d2)
    go = ref.cylinder_go_gain(s, r, (0.0, 0.0), a)
    assert go == pytest.approx(math.sqrt((d1 + d2) / (d1 + d2 + 2 * d1 * d2 / (a * cos_i))))
    assert _db(ref.cylinder_series_gain(s, r, (0.0, 0.0), a, K), go) < 0.5
    assert _db(ref.cylinder_series_echo_gain(s, r, (0.0, 0.0), a, C, F), go) < 0.5
    assert _db(ref.kirchhoff_gain_near(_circle(a), s, r, length / C), go) < 0.5


@pytest.mark.parametrize("a, d", [(2.0, 3.0), (5.0, 1.0)])
def test_the_series_holds_at_large_ka(a, d):
    s = (0.0, a + d)  # ka = 1810 and 4525
    assert _db(ref.cylinder_series_gain(s, s, (0.0, 0.0), a, K),
               ref.cylinder_go_gain(s, s, (0.0, 0.0), a)) < 0.05


def test_the_series_is_reciprocal():
    a, s, r = 0.05, (0.3, 0.4), (-0.6, 0.2)
    assert ref.cylinder_series_field(s, r, (0.0, 0.0), a, K) == pytest.approx(
        ref.cylinder_series_field(r, s, (0.0, 0.0), a, K), rel=1e-9)


# --- the wedge: BTM at the zone boundaries and against Keller's GTD -----------------------

HALF_PLANE = ((0.0, 0.0), (1.0, 0.0), (1.0, 0.0))  # V, face a, face b: the half-plane y = 0, x > 0
CORNER = ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0))  # a 90° solid, θ_W = 270°


def _corner(rho: float, theta: float) -> tuple[float, float]:
    """θ from face a (+x) through the free region, which turns clockwise from +x."""
    return _polar(rho, -theta)


@pytest.mark.parametrize("boundary", ["reflection", "shadow"])
def test_the_diffracted_field_is_half_the_geometrical_one_at_a_zone_boundary(boundary):
    ths = 1.0
    s = _polar(1.0, ths)
    b = math.pi - ths if boundary == "reflection" else math.pi + ths
    r = _polar(1.5, b + 1e-4)  # the dark side of either boundary: larger θ
    assert ref.btm_edge_gain(s, r, *HALF_PLANE, C, F) == pytest.approx(0.5, abs=0.02)
    # from the lit side to the dark one the diffracted field grows by the geometrical wave
    # that vanishes (the reflected or the incident one, of path 2.5 m): the total is continuous
    h = [ref.btm_edge_transfer(s, _polar(1.5, b + e), *HALF_PLANE, C, F) for e in (1e-5, -1e-5)]
    jump = (h[0] - h[1]) * 2.5 / np.exp(1j * K * 2.5)
    assert abs(abs(jump) - 1.0) < 0.005
    assert abs(np.angle(jump)) < 0.01


@pytest.mark.parametrize("wedge, place, ths, thr, rs, rr", [
    (HALF_PLANE, _polar, 1.0, 3.0, 1.0, 1.5),
    (HALF_PLANE, _polar, 0.5, 5.0, 2.0, 0.7),
    (CORNER, _corner, math.radians(40), math.radians(100), 2.0, 1.0),
    (CORNER, _corner, math.radians(40), math.radians(250), 2.0, 1.0),
    (CORNER, _corner, math.radians(120), math.radians(200), 0.5, 3.0),
])
def test_btm_meets_keller_away_from_the_zone_boundaries(wedge, place, ths, thr, rs, rr):
    s, r = place(rs, ths), place(rr, thr)
    v, fa, fb = wedge
    gtd = ref.keller_gtd_gain(s, r, v, fa, fb, K)
    pulse = ref.btm_edge_gain(s, r, v, fa, fb, C, F)
    assert _db(pulse, gtd) < 1.0
    assert _db(abs(ref.btm_edge_transfer(s, r, v, fa, fb, C, F)) * (rs + rr), gtd) < 0.2
    assert ref.btm_edge_gain(r, s, v, fa, fb, C, F) == pytest.approx(pulse, rel=1e-6)


def test_a_monostatic_corner_and_its_pistons():
    s = _corner(1.0, math.radians(135))  # on the corner's bisector, facing the edge
    bare = ref.btm_edge_gain(s, s, *CORNER, C, F)
    assert _db(bare, ref.keller_gtd_gain(s, s, *CORNER, K)) < 1.0
    facing = (-s[0], -s[1])
    narrow = ref.btm_edge_gain(s, s, *CORNER, C, F, ka=12.0, axis_s=facing, axis_r=facing)
    assert narrow == pytest.approx(bare, rel=0.05)  # the beam covers the edge's Fresnel zone
    sideways = ref.btm_edge_gain(s, s, *CORNER, C, F, ka=12.0, axis_s=(1.0, 0.0),
                                 axis_r=(1.0, 0.0))
    assert sideways < 0.1 * bare


def test_a_point_inside_the_solid_wedge_is_refused():
    with pytest.raises(ValueError):
        ref.btm_edge_gain((1.0, 1.0), (-1.0, 0.5), *CORNER, C, F)


# --- a sinusoidal surface: focusing troughs, the caustic, convex crests ------------------

A, PERIOD = 0.05, 2.0
RADIUS = PERIOD**2 / (4 * math.pi**2 * A)  # the radius of curvature at crests and troughs
X = np.linspace(-3.0, 3.0, 6001)
SINE = np.column_stack([X, A * np.sin(2 * np.pi * X / PERIOD)])


@pytest.mark.parametrize("d", [0.3, 1.0, 1.5])
def test_the_sinusoid_follows_ray_optics_away_from_its_caustic(d):
    trough, crest = (-0.5, -A + d), (0.5, A + d)
    concave = ref.kirchhoff_gain_near(SINE, trough, trough, 2 * d / C)
    convex = ref.kirchhoff_gain_near(SINE, crest, crest, 2 * d / C)
    assert _db(concave, math.sqrt(RADIUS / (RADIUS - d))) < 0.5  # focusing: gain > 1
    assert _db(convex, math.sqrt(RADIUS / (RADIUS + d))) < 0.5


def test_the_caustic_stays_finite_in_physical_optics():
    at = (-0.5, -A + RADIUS)  # the trough's centre of curvature: ray optics diverges
    caustic = ref.kirchhoff_gain_near(SINE, at, at, 2 * RADIUS / C)
    before = ref.kirchhoff_gain_near(SINE, (-0.5, -A + RADIUS / 2), (-0.5, -A + RADIUS / 2),
                                     RADIUS / C)
    assert math.isfinite(caustic) and 2 * before < caustic < 20
    echoes = ref.kirchhoff_echo(SINE, at, at)
    assert len(echoes) == 1 and echoes[0][1] == pytest.approx(caustic, rel=1e-4)
