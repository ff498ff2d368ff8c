"""Force laws: each against what it must reduce to, and the onset paths."""

import math
import warnings

import numpy as np
import pytest

from msf_contact import _scaling
from msf_contact import closed_forms as cf
from msf_contact.geometry import Curvature
from msf_contact.laws import LAWS, ForceLaw, HertzLaw, MSFLaw, get_law, make_law
from msf_contact.materials import ContactPair, Material, preset

#: Algebraic identities between two evaluations of the same formula.
ALG_RTOL = 1e-12
#: The engines' onset interpolates omega_x in eps = x_0/2R with a cubic
#: spline (msf_contact._scaling.EPS_NODES); measured error <= 6e-8 up to
#: x_max/R ~ 0.5; this bound leaves a margin and is far below the engines'
#: 0.1% COR acceptance.
ONSET_TABLE_RTOL = 1e-6
#: Self-consistency omega_x tau = pi is solved by brentq on an integration
#: with rtol 1e-11 (msf_contact._normal.RTOL).
SELF_CONSISTENT_RTOL = 1e-8

RUBBER = Material("rubber", 5e6, 0.1, 0.49, 930.0)
PAIR = ContactPair(RUBBER, Material.rigid_body())
R = 0.02
MASS = 4 / 3 * math.pi * R**3 * 930.0
SPHERE = Curvature.sphere_on_plane(R)


def onset_with(E, eta, n=1):
    return {"E": np.full(n, E), "eta_E": np.full(n, eta)}


@pytest.mark.parametrize("kp_mode", ["msf", "msf-small", "hertz"])
def test_msf_sphere_normal_force_is_43(kp_mode):
    law = MSFLaw(PAIR, SPHERE, kp_mode=kp_mode, omega=1000.0)
    x = np.array([1e-5, 3e-4, 1e-3])
    xd = np.array([0.5, -0.2, 0.0])
    eta = RUBBER.E_loss / 1000.0
    kp = {"msf": np.sqrt(2 - x / R), "msf-small": math.sqrt(2), "hertz": 1.0}[kp_mode]
    want = 4 * kp * eta * math.sqrt(R) * xd * np.sqrt(x) + 4 / 3 * kp * RUBBER.E_storage * math.sqrt(R) * x**1.5
    got = law.normal_force(x, xd, onset_with(RUBBER.E_storage, eta, 3))
    assert np.allclose(got, want, rtol=ALG_RTOL)


def test_elliptic_37_with_equal_radii_is_the_sphere():
    sph = MSFLaw(PAIR, SPHERE, omega=1000.0)
    ell = MSFLaw(PAIR, Curvature(R, R * (1 + 1e-15)), omega=1000.0)
    x, xd = np.array([2e-4]), np.array([0.3])
    o = onset_with(5e6, 50.0)
    assert ell.normal_force(x, xd, o) == pytest.approx(sph.normal_force(x, xd, o), rel=1e-12)


def test_msf_with_kp_one_and_no_damping_is_hertz_30():
    elastic = Material("elastic", 5e6, 0.0, 0.49, 930.0)
    pair = ContactPair(elastic, Material.rigid_body())
    msf = MSFLaw(pair, SPHERE, kp_mode="hertz", omega=1000.0)
    hz = HertzLaw(pair, SPHERE)
    x = np.linspace(0, 1e-3, 5)
    o = onset_with(5e6, 0.0, 5)
    assert np.allclose(msf.normal_force(x, np.ones(5), o), hz.normal_force(x, np.ones(5), {}), rtol=ALG_RTOL)
    assert np.allclose(hz.normal_force(x, 0 * x, {}), 4 / 3 * 5e6 * math.sqrt(R) * x**1.5, rtol=ALG_RTOL)


def test_kuwabara_kono_brilliantov_form():
    kk = make_law("kuwabara-kono", PAIR, SPHERE, A=2e-5)
    rho = 4 / 3 * RUBBER.E_storage * math.sqrt(R)  # Brilliantov et al. 1996
    x, xd = np.array([3e-4]), np.array([0.4])
    want = rho * (x**1.5 + 1.5 * 2e-5 * xd * np.sqrt(x))
    assert kk.normal_force(x, xd, {}) == pytest.approx(want, rel=ALG_RTOL)


def test_hunt_crossley_flores_damping():
    hc = make_law("hunt-crossley", PAIR, SPHERE, cor=0.8)
    o = hc.onset([2.0], [MASS])
    assert o["chi"][0] == pytest.approx(8 * 0.2 / (5 * 0.8 * 2.0), rel=ALG_RTOL)  # Flores et al. 2011


def test_spring_dashpot_default_is_84_equivalent():
    sd = make_law("spring-dashpot", PAIR, SPHERE)
    o = sd.onset([2.0], [MASS])
    tg = PAIR.moduli().tan_delta
    x_m = cf.x_max_90(MASS, 2.0, RUBBER.E_storage, tg, R, 1.0)
    C_x = 16 / 15 * RUBBER.E_storage * math.sqrt(R) * math.sqrt(x_m)  # (84), k_p = 1
    assert o["k"][0] == pytest.approx(C_x, rel=ALG_RTOL)
    # (103): B_x / C_x = 3 tg / omega_x
    w = cf.omega_x_equivalent(MASS, x_m, RUBBER.E_storage, tg, R, 1.0)
    assert o["c"][0] / o["k"][0] == pytest.approx(3 * tg / w, rel=ALG_RTOL)


def test_tangential_force_36_37_sign_and_coulomb_cap():
    law = MSFLaw(PAIR, SPHERE, omega=1000.0)
    o = law.onset([1.0], [MASS])
    x = np.array([2e-4])
    s = np.array([[1e-5, -2e-5]])
    sd = np.array([[0.1, 0.0]])
    F, sliding = law.tangential_force(x, s, sd, o)
    P_bx, P_ax = law.shear_lengths(x)
    want_y = -(o["eta_Gy"][0] * P_bx[0] * 0.1 + o["G"][0] * P_bx[0] * 1e-5)
    assert F[0, 0] == pytest.approx(want_y, rel=ALG_RTOL)
    assert F[0, 1] == pytest.approx(o["G"][0] * P_ax[0] * 2e-5, rel=ALG_RTOL)
    assert not sliding[0]
    capped = MSFLaw(PAIR, SPHERE, omega=1000.0, mu=0.1)
    Fc, sl = capped.tangential_force(x, s, sd, o, F_n=np.array([1.0]))
    assert sl[0]
    assert np.hypot(*Fc[0]) == pytest.approx(0.1, rel=ALG_RTOL)
    assert np.allclose(Fc[0] / np.hypot(*Fc[0]), F[0] / np.hypot(*F[0]), rtol=ALG_RTOL)


def test_no_adhesion_in_force_zero_mode():
    law = MSFLaw(PAIR, SPHERE, omega=1000.0)
    o = onset_with(5e6, 5e4)
    x, xd = np.array([1e-4]), np.array([-5.0])
    assert law.normal_force(x, xd, o)[0] < 0  # raw law is tensile here
    assert law.contact_normal_force(x, xd, o)[0] == 0.0
    tensile = MSFLaw(PAIR, SPHERE, omega=1000.0, separation="overlap-zero")
    assert tensile.contact_normal_force(x, xd, o)[0] < 0


def test_forces_are_finite_beyond_2R_and_flagged():
    law = MSFLaw(PAIR, SPHERE, omega=1000.0)
    x = np.array([0.5 * R, 2.5 * R])
    F = law.normal_force(x, np.zeros(2), onset_with(5e6, 1.0, 2))
    assert np.all(np.isfinite(F))
    assert law.outside(x).tolist() == [False, True]


def test_registry_accepts_class_and_lists_names():
    assert get_law("msf") is MSFLaw
    assert get_law(HertzLaw) is HertzLaw
    with pytest.raises(ValueError, match="valid names: msf, hertz, kuwabara-kono, hunt-crossley, spring-dashpot"):
        get_law("coulomb")
    assert all(issubclass(c, ForceLaw) for c in LAWS.values())


@pytest.mark.parametrize(
    "name, kwargs, needle",
    [
        ("msf", dict(omega=-5.0), "omega"),
        ("msf", dict(omega="sometimes"), "omega"),
        ("msf", dict(kp_mode="fast"), "kp_mode"),
        ("msf", dict(separation="never"), "separation"),
        ("msf", dict(mu=-0.1), "mu"),
        ("kuwabara-kono", dict(A=-1e-5), "A"),
        ("hunt-crossley", dict(cor=1.5), "cor"),
        ("hunt-crossley", dict(cor=0.0), "cor"),
        ("spring-dashpot", dict(k=0.0), "k"),
        ("spring-dashpot", dict(c=-1.0), "c"),
    ],
)
def test_bad_law_options(name, kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        make_law(name, PAIR, SPHERE, **kwargs)


def test_tan_delta_above_one_third_warns_and_strict_raises():
    lossy = ContactPair(Material("lossy", 5e6, 0.4, 0.49, 930.0), Material.rigid_body())
    with pytest.warns(UserWarning, match=r"\(100\)"):
        MSFLaw(lossy, SPHERE)
    with pytest.raises(ValueError, match=r"\(100\)"):
        MSFLaw(lossy, SPHERE, strict=True)


@pytest.mark.parametrize("kp_mode", ["msf", "msf-small", "hertz"])
def test_self_consistent_onset_satisfies_omega_tau_pi(kp_mode):
    """(46), (87): the collision solved with omega_x lasts pi/omega_x."""
    law = MSFLaw(PAIR, SPHERE, kp_mode=kp_mode)
    o = law.onset_reference([2.0], [MASS])
    sol = law.solve_normal(2.0, MASS, o)
    assert o["omega_x"][0] * sol.tau == pytest.approx(math.pi, rel=SELF_CONSISTENT_RTOL)
    assert o["x_max_pred"][0] == pytest.approx(sol.x_max, rel=SELF_CONSISTENT_RTOL)


def test_scaled_onset_matches_direct_dimensional_root():
    """The dimensionless path (_scaling) against brentq on the dimensional ODE."""
    law = MSFLaw(PAIR, SPHERE)
    slow = law.onset_one(1.5, MASS)
    fast = law.onset_reference([1.5], [MASS])
    assert fast["omega_x"][0] == pytest.approx(slow["omega_x"][0], rel=SELF_CONSISTENT_RTOL)


@pytest.mark.parametrize("speed", [0.3, 3.0, 15.0])
def test_engine_onset_table_accuracy(speed):
    law = MSFLaw(PAIR, SPHERE)
    ref = law.onset_reference([speed], [MASS])
    fast = law.onset([speed], [MASS])
    for key in ("omega_x", "x_max_pred", "omega_y"):
        assert fast[key][0] == pytest.approx(ref[key][0], rel=ONSET_TABLE_RTOL)


def test_constant_kp_cor_depends_on_tan_delta_only():
    """Scaling (msf_contact._scaling): with constant k_p the self-consistent
    COR is independent of speed, mass and modulus."""
    a = _scaling.self_consistent(0.1, 0.0, "force-zero").cor
    law = MSFLaw(PAIR, SPHERE, kp_mode="msf-small")
    for v, m in ((0.5, MASS), (7.0, 3 * MASS)):
        o = law.onset_reference([v], [m])
        assert law.solve_normal(v, m, o).cor == pytest.approx(a, rel=SELF_CONSISTENT_RTOL)


def test_omega_y_from_84_86():
    law = MSFLaw(PAIR, SPHERE)
    o = law.onset_reference([2.0], [MASS])
    P_m = law.shear_lengths(o["x_max_pred"])[0][0]
    G = PAIR.moduli().G
    tg = PAIR.moduli().tan_delta
    w = o["omega_y"][0]
    # omega_y^2 = C_y/m - (B_y/2m)^2 with B_y = G'' P_m/omega_y, C_y = G' P_m
    assert w**2 == pytest.approx(G * P_m / MASS - (tg * G * P_m / w / (2 * MASS)) ** 2, rel=1e-10)


def test_vectorised_onset_equals_one_by_one():
    law = MSFLaw(PAIR, SPHERE)
    v = np.array([0.5, 1.0, 4.0])
    o = law.onset(v, np.full(3, MASS))
    for i, vi in enumerate(v):
        oi = law.onset([vi], [MASS])
        assert o["omega_x"][i] == oi["omega_x"][0]


@pytest.mark.parametrize("pair, R", [(PAIR, None), (ContactPair(preset("glass"), preset("polyurethane")), 2.5e-4),
                                     (ContactPair(preset("steel"), preset("steel")), 0.01)])
def test_compiled_onset_equals_the_numpy_form(pair, R):
    """MSFLaw.onset's compiled rows (msf_contact._onset_kernel) equal its numpy
    form (compiled_onset = False) bit for bit, every key, on random batches of
    speeds and masses across the table (eps from ~1e-6 to deep, near 2R); a
    batch with a row past the table takes the numpy path (the same
    constants, or the same refusal past 2R)."""
    law = MSFLaw(pair, SPHERE if R is None else Curvature.sphere_on_plane(R))
    numpy_law = MSFLaw(pair, SPHERE if R is None else Curvature.sphere_on_plane(R))
    numpy_law.compiled_onset = False
    rng = np.random.default_rng(11)
    K = law._scale_K()
    two_R = 2.0 * law.geom.R
    for n in (1, 2, 7, 40):
        eps = 10.0 ** rng.uniform(-6.0, math.log10(_scaling.EPS_NODES[-1]), n)  # x_0/2R across the table
        m = 10.0 ** rng.uniform(-9.0, -3.0, n)
        v = np.sqrt((eps * two_R) ** 2.5 * K / m)  # x_0 = (m v^2/K)^(2/5) = eps 2R
        got, want = law.onset(v, m), numpy_law.onset(v, m)
        assert list(got) == list(want)
        for key in want:
            np.testing.assert_array_equal(got[key], want[key], err_msg=key)
    for deep in (1.2, 3.0):  # past the table: its own roots (1.2), or past 2R (3.0): refused alike
        v = np.array([1.0, np.sqrt((deep * _scaling.EPS_NODES[-1] * two_R) ** 2.5 * K / MASS)])
        got, want = (_answer(lw.onset, v, np.full(2, MASS)) for lw in (law, numpy_law))
        assert type(got) is type(want)
        if isinstance(want, str):
            assert got == want and "2R" in want
        else:
            for key in want:
                np.testing.assert_array_equal(got[key], want[key], err_msg=key)


def test_compiled_tangential_stiffness_equals_the_numpy_form():
    """MSFLaw.tangential_stiffness's compiled rows (msf_contact._onset_kernel.
    stiffness_rows) equal its numpy form bit for bit, k and b, at overlaps from
    -R to past 2R (clamped k_p), 0, -0.0 and NaN, with onset constants of
    rows; scalars in the onset take the numpy form."""
    law = MSFLaw(PAIR, SPHERE)
    numpy_law = MSFLaw(PAIR, SPHERE)
    numpy_law.compiled_onset = False
    rng = np.random.default_rng(4)
    x = np.concatenate([rng.uniform(-R, 2.5 * R, 60), [0.0, -0.0, np.nan, 2.0 * R]])
    o = law.onset(rng.uniform(0.1, 10.0, x.size), np.full(x.size, MASS))
    for got, want in zip(law.tangential_stiffness(x, o), numpy_law.tangential_stiffness(x, o)):
        np.testing.assert_array_equal(got, want)
        assert np.array_equal(np.signbit(got), np.signbit(want))
    o1 = {key: float(val[0]) for key, val in o.items()}
    for got, want in zip(law.tangential_stiffness(x, o1), numpy_law.tangential_stiffness(x, o1)):
        np.testing.assert_array_equal(got, want)


def _answer(f, *args):
    """f(*args), or the text of the ValueError it raises."""
    try:
        return f(*args)
    except ValueError as exc:
        return str(exc)


def test_frequency_dependent_material_uses_the_fixed_point():
    from msf_contact.materials import PronySeries

    p = PronySeries(E_inf=3e6, E_i=(2e6,), tau_i=(2e-4,))
    m = Material("visco", 4e6, 0.1, 0.49, 930.0, master_curve=p)
    law = MSFLaw(ContactPair(m, Material.rigid_body()), SPHERE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        o = law.onset([2.0], [MASS])
    w = o["omega_x"][0]
    s, _ = p.moduli(w)
    assert o["E"][0] == pytest.approx(s, rel=ALG_RTOL)  # moduli evaluated at the collision's omega
    sol = law.solve_normal(2.0, MASS, o)
    assert w * sol.tau == pytest.approx(math.pi, rel=SELF_CONSISTENT_RTOL)


#: The exact Hunt-Crossley damping solves alpha (1 + e) = ln((1 + alpha)/(1 - alpha e))
#: to 1e-14; the reference solver's COR is good to ~1e-10 (measured <= 1.1e-10 for e in [1e-6, 1]).
HC_EXACT_RTOL = 1e-9


@pytest.mark.parametrize("e", [0.01, 0.3, 0.8, 0.999])
@pytest.mark.parametrize("separation", ["force-zero", "overlap-zero"])
def test_hunt_crossley_exact_damping_rebounds_with_its_target(e, separation):
    """Issue 14 item 5: --hc-cor with the exact recipe returns the COR asked
    for; Flores' recipe (the default) returns 0.7885 for 0.8."""
    from msf_contact.solver import Body, simulate_impact

    pair = ContactPair(RUBBER, Material.rigid_body())
    curv = Curvature.sphere_on_plane(0.02)
    ball, plate = Body.sphere(RUBBER, 0.02), Body.half_space(Material.rigid_body())
    law = make_law("hunt-crossley", pair, curv, cor=e, damping="exact", separation=separation)
    assert simulate_impact(law, ball, plate, 1.7).cor_n == pytest.approx(e, rel=HC_EXACT_RTOL)
    if e == 0.8:
        flores = make_law("hunt-crossley", pair, curv, cor=e, separation=separation)
        assert simulate_impact(flores, ball, plate, 1.7).cor_n == pytest.approx(0.7885, abs=5e-5)


def test_hunt_crossley_damping_choice_is_checked():
    with pytest.raises(ValueError, match="damping = 'exakt' is not one of 'flores', 'exact'"):
        make_law("hunt-crossley", ContactPair(RUBBER, Material.rigid_body()), Curvature.sphere_on_plane(0.02),
                 cor=0.8, damping="exakt")
