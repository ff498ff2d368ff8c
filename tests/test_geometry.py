"""Contact geometry (13)-(26), (29), (36), (41)-(42), (47*)."""

import math

import numpy as np
import pytest

from msf_contact import geometry as g
from msf_contact.materials import ContactPair, Material

#: Algebraic identities: float rounding only.
ALG_RTOL = 1e-12

SOFT = Material("soft", 5e6, 0.1, 0.49, 930.0)
HARD = Material("hard", 200e9, 1e-3, 0.3, 7800.0)


def test_kp_modes():
    x, R = 1e-4, 0.01
    assert g.kp(x, R, "hertz") == 1.0
    assert g.kp(x, R, "msf-small") == pytest.approx(math.sqrt(2), rel=ALG_RTOL)
    assert g.kp(x, R, "msf") == pytest.approx(math.sqrt(2 - x / R), rel=ALG_RTOL)


def test_kp_msf_refuses_x_beyond_2R_and_clamped_variant_flags_it():
    with pytest.raises(ValueError, match="x/R = 2.5"):
        g.kp(0.025, 0.01, "msf")
    k, outside = g.kp_clamped(np.array([0.001, 0.025]), 0.01, "msf")
    assert np.all(np.isfinite(k))
    assert outside.tolist() == [False, True]
    with pytest.raises(ValueError, match="kp_mode"):
        g.kp(1e-4, 0.01, "bogus")


def test_14_reproduces_13_exactly_in_msf_mode():
    R = 0.01
    x = np.linspace(1e-6, 1.5 * R, 7)
    assert np.allclose(g.contact_radius(x, R, "msf") ** 2, 2 * R * x - x**2, rtol=ALG_RTOL)
    assert np.allclose(g.contact_radius_exact(x, R) ** 2, 2 * R * x - x**2, rtol=ALG_RTOL)


def test_area_41_is_pi_a_b_over_4_with_26():
    pair = ContactPair(SOFT, Material.rigid_body())
    geom = g.ContactGeometry.of(pair, g.Curvature(0.02, 0.05))
    x = 3e-4
    a, b = g.contact_axes(x, geom, "msf")
    assert g.area(x, geom, "msf") == pytest.approx(math.pi * a * b / 4, rel=ALG_RTOL)


def test_psi_29_for_a_sphere():
    geom = g.ContactGeometry.of(ContactPair(SOFT, Material.rigid_body()), g.Curvature.sphere_on_plane(0.02))
    x = 1e-4
    assert g.psi(x, geom, "msf") == pytest.approx(2 * g.kp(x, 0.02, "msf") * math.sqrt(0.02), rel=ALG_RTOL)


def test_depth_coefficient_47star_hard_sphere_on_soft_half_space():
    """(47*): a hard sphere on a softer half-space has k_h = D1 (h_x = x_1)."""
    pair = ContactPair(HARD, SOFT)  # body 1 = the hard sphere
    curv = g.Curvature(0.01, 0.01)  # body 2 (soft) is a plane
    geom = g.ContactGeometry.of(pair, curv)
    assert geom.k_ha == pytest.approx(pair.moduli().D1, rel=ALG_RTOL)


def test_depth_clamped_for_soft_ball_on_harder_plane():
    pair = ContactPair(SOFT, HARD)
    geom = g.ContactGeometry.of(pair, g.Curvature(0.01, 0.01))
    assert geom.k_ha_raw == pytest.approx(-pair.moduli().D2, rel=ALG_RTOL)
    assert geom.k_ha == 0.0


def test_effective_radius_13():
    geom = g.ContactGeometry.of(ContactPair(SOFT, HARD), g.Curvature.two_spheres(0.01, 0.03))
    assert geom.R_a == pytest.approx(0.01 * 0.03 / 0.04, rel=ALG_RTOL)


def test_two_planes_refused_and_bad_radius():
    with pytest.raises(ValueError, match="two planes"):
        g.Curvature(math.inf, math.inf)
    with pytest.raises(ValueError, match="R1a"):
        g.Curvature(-0.01, 0.01)


def test_peak_pressure_42_equals_20_with_37():
    """(42) is (20) applied to (37) over (41)."""
    geom = g.ContactGeometry.of(ContactPair(SOFT, Material.rigid_body()), g.Curvature(0.02, 0.03))
    E, eta = 5e6, 300.0
    x, xd = 2e-4, 0.7
    psi = g.psi(x, geom, "msf")
    F = 2 * eta * psi * xd * math.sqrt(x) + 2 / 3 * E * psi * x**1.5  # (37)
    assert g.peak_pressure_closed(x, xd, E, eta, geom, "msf") == pytest.approx(
        g.peak_pressure(F, x, geom, "msf"), rel=ALG_RTOL
    )


def test_shear_lengths_36():
    geom = g.ContactGeometry.of(ContactPair(HARD, SOFT), g.Curvature(0.01, 0.02))
    x = 1e-4
    P_bx, P_ax = g.shear_lengths(x, geom, "msf")
    assert P_bx == pytest.approx(geom.k_ha * x + 2 * g.kp(x, geom.R_b) * math.sqrt(geom.R_b * x), rel=ALG_RTOL)
    assert P_ax == pytest.approx(geom.k_hb * x + 2 * g.kp(x, geom.R_a) * math.sqrt(geom.R_a * x), rel=ALG_RTOL)
