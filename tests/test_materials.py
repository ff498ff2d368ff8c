"""Materials and pair parameters: (9), (10), (48), (91), master curves, WLF."""

import math

import numpy as np
import pytest

from msf_contact.materials import (
    WLF,
    ContactPair,
    Material,
    PronySeries,
    TabulatedMasterCurve,
    preset,
    preset_names,
)

#: Algebraic identities: only float rounding separates the two sides.
ALG_RTOL = 1e-13

RUBBER = Material("rubber", 5e6, 0.1, 0.49, 930.0)
STEEL = Material("steel", 210e9, 1e-3, 0.3, 7850.0)


def test_series_rule_9_and_deformation_split_10():
    pair = ContactPair(RUBBER, STEEL)
    mod = pair.moduli()
    E1, E2 = RUBBER.E_storage, STEEL.E_storage
    assert mod.E == pytest.approx(1.0 / (1.0 / E1 + 1.0 / E2), rel=ALG_RTOL)
    # (8): E' x = E'_1 x_1 = E'_2 x_2 with x_1 = D1 x, x_2 = D2 x
    x = 1e-4
    assert mod.D1 + mod.D2 == pytest.approx(1.0, rel=ALG_RTOL)
    assert E1 * mod.D1 * x == pytest.approx(mod.E * x, rel=ALG_RTOL)
    assert E2 * mod.D2 * x == pytest.approx(mod.E * x, rel=ALG_RTOL)


def test_tan_delta_91_closed_form():
    pair = ContactPair(RUBBER, STEEL)
    E1, E2 = RUBBER.E_storage, STEEL.E_storage
    L1, L2 = RUBBER.E_loss, STEEL.E_loss
    want = L1 * L2 * (E1 + E2) / (E1 * E2 * (L1 + L2))  # (91) as printed
    assert pair.moduli().tan_delta == pytest.approx(want, rel=ALG_RTOL)


def test_rigid_partner_leaves_the_soft_body_alone():
    mod = ContactPair(RUBBER, Material.rigid_body()).moduli()
    assert mod.E == RUBBER.E_storage
    assert mod.tan_delta == pytest.approx(RUBBER.tan_delta, rel=ALG_RTOL)
    assert (mod.D1, mod.D2) == (1.0, 0.0)
    assert mod.G == pytest.approx(RUBBER.E_storage / (2 * (1 + RUBBER.nu)), rel=ALG_RTOL)


def test_lossless_partner_makes_the_pair_lossless_by_91():
    """(91) puts the viscosities in series: one E'' = 0 gives E'' = 0 (errata)."""
    lossless = Material("ideal", 210e9, 0.0, 0.3, 7850.0)
    assert ContactPair(RUBBER, lossless).moduli().tan_delta == 0.0


def test_hertz_convention():
    mod = ContactPair(RUBBER, STEEL, convention="hertz").moduli()
    want = 1.0 / ((1 - RUBBER.nu**2) / RUBBER.E_storage + (1 - STEEL.nu**2) / STEEL.E_storage)
    assert mod.E == pytest.approx(want, rel=ALG_RTOL)
    # the loss factor stays that of (91)
    assert mod.tan_delta == pytest.approx(ContactPair(RUBBER, STEEL).moduli().tan_delta, rel=ALG_RTOL)


def test_shear_defaults_and_48():
    assert RUBBER.G == pytest.approx(5e6 / (2 * 1.49), rel=ALG_RTOL)
    assert RUBBER.G_loss / RUBBER.G == pytest.approx(RUBBER.E_loss / RUBBER.E_storage, rel=ALG_RTOL)


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(E_storage=-1.0), "E_storage"),
        (dict(E_storage=0.0), "E_storage"),
        (dict(E_storage=float("nan")), "NaN"),
        (dict(tan_delta=-0.1), "tan_delta"),
        (dict(nu=0.5), "nu"),
        (dict(nu=-1.0), "nu"),
        (dict(density=0.0), "density"),
        (dict(density=float("inf") * 0), "NaN"),
    ],
)
def test_bad_material_inputs(kwargs, needle):
    base = dict(name="m", E_storage=1e6, tan_delta=0.1, nu=0.3, density=1000.0)
    base.update(kwargs)
    with pytest.raises(ValueError, match=needle):
        Material(**base)


def test_two_rigid_bodies_refused():
    with pytest.raises(ValueError, match="rigid"):
        ContactPair(Material.rigid_body(), Material.rigid_body())


def test_presets_have_sources_and_unknown_names_list_valid_ones():
    for name in preset_names():
        m = preset(name)
        assert m.source
    with pytest.raises(ValueError, match="valid names: .*steel"):
        preset("unobtainium")


def test_prony_limits_and_loss_peak():
    p = PronySeries(E_inf=1e6, E_i=(4e6,), tau_i=(1e-3,))
    low, _ = p.moduli(1e-9)
    high, _ = p.moduli(1e12)
    assert low == pytest.approx(1e6, rel=1e-9)  # relaxed modulus
    assert high == pytest.approx(5e6, rel=1e-9)  # glassy modulus
    s, l_ = p.moduli(1.0 / 1e-3)  # omega tau = 1: loss peak E_i/2
    assert l_ == pytest.approx(2e6, rel=ALG_RTOL)
    assert s == pytest.approx(1e6 + 2e6, rel=ALG_RTOL)


def test_wlf_shift_and_material_at():
    wlf = WLF(C1=17.44, C2=51.6, T_ref=293.15)
    assert wlf.log10_aT(293.15) == 0.0
    p = PronySeries(E_inf=1e6, E_i=(4e6,), tau_i=(1e-3,))
    m = Material("visco", 3e6, 2 / 3, 0.49, 1000.0, master_curve=p, wlf=wlf)
    T = 303.15
    aT = 10 ** (-17.44 * 10 / (51.6 + 10))
    got = m.at(500.0, T)
    s, l_ = p.moduli(500.0 * aT)
    assert got.E_storage == pytest.approx(s, rel=ALG_RTOL)
    assert got.tan_delta == pytest.approx(l_ / s, rel=ALG_RTOL)
    with pytest.raises(ValueError, match="WLF singularity"):
        wlf.log10_aT(293.15 - 60)


def test_tabulated_master_curve_interpolates_in_log_log():
    t = TabulatedMasterCurve(omega=(1.0, 100.0), storage=(1e6, 1e8), loss=(1e5, 1e7))
    s, l_ = t.moduli(10.0)  # geometric mid-point in log-log
    assert s == pytest.approx(1e7, rel=1e-12)
    assert l_ == pytest.approx(1e6, rel=1e-12)
    with pytest.raises(ValueError, match="increase"):
        TabulatedMasterCurve(omega=(2.0, 1.0), storage=(1.0, 1.0), loss=(1.0, 1.0))


def test_sound_speed_is_the_softer_bar_speed():
    c = ContactPair(RUBBER, Material.rigid_body()).sound_speed()
    assert c == pytest.approx(math.sqrt(5e6 / 930.0), rel=ALG_RTOL)
    assert np.isfinite(c)
