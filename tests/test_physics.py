"""Physical models of chapter 2: eq. 2.1, eq. 2.2, the piston beam, eq. 2.3."""

import math

import numpy as np
import pytest
from scipy import special

from clsonar import physics


def test_speed_of_sound_eq_2_1():
    assert physics.speed_of_sound(273.0) == pytest.approx(331.4)
    assert physics.speed_of_sound(293.15) == pytest.approx(343.4, abs=0.05)


def test_half_beam_angle_eq_2_2_is_about_12_degrees():
    c = physics.speed_of_sound(293.15)
    theta = math.degrees(physics.half_beam_angle(50e3, 0.02, c))
    assert theta == pytest.approx(12.1, abs=0.05)
    # ... and it is the piston pattern's first null (0.61·2π ≈ j1)
    ka = physics.wavenumber(50e3, c) * 0.02
    assert ka * math.sin(math.radians(theta)) == pytest.approx(physics.J1_FIRST_ZERO, rel=2e-3)


def test_beam_pattern_and_hard_cut():
    c = physics.speed_of_sound(293.15)
    ka = physics.wavenumber(50e3, c) * 0.02
    cut = physics.beam_cut_sin2(50e3, 0.02, 12.0, c)
    th = np.radians([0.0, 5.0, 11.9, 12.1, 30.0, 180.0])
    b = physics.beam_pattern(np.cos(th), np.sin(th), ka, cut)
    assert b[0] == 1.0
    assert b[1] == pytest.approx(2 * special.j1(ka * np.sin(th[1])) / (ka * np.sin(th[1])))
    assert 0 < b[2] < 0.05
    assert list(b[3:]) == [0.0, 0.0, 0.0]


def test_beam_series_matches_bessel_near_the_null():
    coeffs = physics.beam_series_coefficients()
    u = np.linspace(0, 1, 1001)
    series = (1 - u) * np.polynomial.polynomial.polyval(u, coeffs)
    exact = physics.piston_pattern(physics.J1_FIRST_ZERO * np.sqrt(u))
    assert np.max(np.abs(series - exact)) < 1e-12
    near = (u > 0.98) & (u < 1)  # relative accuracy holds right up to the null
    assert np.max(np.abs(series[near] / exact[near] - 1)) < 1e-9


def test_pulse_eq_2_3():
    sigma = physics.DEFAULT_PULSE_SIGMA_S
    assert 6 * sigma == pytest.approx(320e-6, rel=0.02)  # the Polaroid burst length
    t = np.linspace(-1e-4, 7 * sigma, 200001)
    p = physics.pulse(t, sigma, 50e3, 5.0)
    assert np.max(np.abs(p)) == pytest.approx(5.0, rel=1e-5)
    assert np.all(p[(t < 0) | (t > 6 * sigma)] == 0)


def test_curved_gain_is_one_for_a_plane_and_below_one_for_a_cylinder():
    assert physics.curved_gain(2.0, 3.0, 0.0, 0.7) == pytest.approx(1.0)
    g = physics.curved_gain(2.0, 2.0, 0.5, 1.0)  # 2 m cylinder seen from 2 m: L_eff = 8
    assert g == pytest.approx(math.sqrt(4 / 8))
    assert physics.curved_gain(1.0, 1.0, -1.0, 1.0) == pytest.approx(physics.MAX_FOCUS_GAIN)


def test_edge_diffraction_changes_sign_across_a_reflection_boundary():
    """Kouyoumjian & Pathak 1974: on a face's reflection boundary the diffracted field is
    half the reflected one, −1/2 on the lit side (where the face's mirror echo, +1, makes
    the total 1/2) and +1/2 on the shadow side; far from the boundaries its phase is
    Keller's −π/4 (e^{+iωt}), and edge_gain and edge_phase are its modulus and argument."""
    k = physics.wavenumber(50e3, 343.4)
    n = 1.5  # a box corner; face a's reflection boundary for T = R is φ = 90°
    lit, dark = (complex(physics.edge_diffraction(2.0, 2.0, math.radians(p), math.radians(p),
                                                  n, k, 1.0)) for p in (89.999, 90.001))
    assert lit == pytest.approx(-0.5, abs=0.01)
    assert dark == pytest.approx(0.5, abs=0.01)
    far = physics.edge_diffraction(1.0, 1.0, math.radians(135.0), math.radians(135.0), n, k,
                                   2.0)
    assert np.angle(far) == pytest.approx(-math.pi / 4, abs=0.01)
    assert abs(far) == pytest.approx(physics.edge_gain(1.0, 1.0, math.radians(135.0),
                                                       math.radians(135.0), n, k, 2.0))
    assert physics.edge_phase(1.0, 1.0, math.radians(135.0), math.radians(135.0), n, k) \
        == pytest.approx(float(np.angle(far)))


def test_edge_gain_is_kellers_far_from_the_boundaries_and_half_a_mirror_on_them():
    k = physics.wavenumber(50e3, 343.4)
    n, phi = 1.5, math.radians(135.0)  # a box corner seen along its diagonal, from 1 m
    g = physics.edge_gain(1.0, 1.0, phi, phi, n, k, 1.0)
    keller = (math.sin(math.pi / n) / (n * math.sqrt(2 * math.pi * k))
              * abs(1 / (math.cos(math.pi / n) - 1)
                    + 1 / (math.cos(math.pi / n) - math.cos(2 * phi / n))))
    assert g == pytest.approx(keller * math.sqrt(2.0), rel=1e-3)  # |D|·sqrt((d1+d2)/(d1d2))
    assert 0.005 < g < 0.02
    # on the reflection boundary of face a (φ_T + φ_R = π) the edge gives half a mirror
    on = physics.edge_gain(2.0, 3.0, math.radians(40.0), math.radians(140.0), n, k, 1.0)
    assert on == pytest.approx(0.5, abs=0.01)
    assert physics.edge_gain(1.0, 1.0, phi, phi, n, k, 3.0) == pytest.approx(3 * g)


def test_wedge_angles_from_face_a_through_the_free_region():
    v, va, vb = np.zeros(2), np.array([0.0, -1.0]), np.array([1.0, 0.0])  # solid: x > 0, y < 0
    pts = np.array([[-1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [-1.0, -1.0]])
    phi, n = physics.wedge_angles(pts, v, va, vb)
    np.testing.assert_allclose(np.degrees(phi), [90.0, 180.0, 225.0, 45.0])
    np.testing.assert_allclose(n, 1.5)
    phi2, _ = physics.wedge_angles(pts, v, vb, va)  # faces swapped: measured the other way
    np.testing.assert_allclose(np.degrees(phi2), 270.0 - np.degrees(phi))


def test_fresnel_auxiliary_functions_against_scipys_fresnel_integrals():
    z = np.linspace(0.0, 20.0, 20001)
    s, c = special.fresnel(z)
    x = np.pi * z**2 / 2
    f = -(0.5 - c) * np.sin(x) + (0.5 - s) * np.cos(x)  # A&S 7.3.9–10 solved for f, g
    g = (0.5 - c) * np.cos(x) + (0.5 - s) * np.sin(x)
    fa, ga = physics.fresnel_auxiliary(z)
    assert np.max(np.abs(np.hypot(fa, ga) / np.hypot(f, g) - 1)) < 0.014
    assert np.max(np.abs(fa - f)) < 2e-3 and np.max(np.abs(ga - g)) < 2e-3
