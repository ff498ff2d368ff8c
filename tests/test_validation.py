"""Validation of the numerical laws through the reference solver, and the
measured differences between the MSF law and the paper's closed forms.

The computations live in ``msf_contact.validation`` (shared with
``scripts/make_validation.py``); the references there are independent
(analytic solutions, a published series, quadrature). This file asserts the
checks, re-derives some references by a second route, and checks that
``docs/validation.md`` and ``docs/errata.md`` state what is measured now.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from msf_contact import closed_forms as cf
from msf_contact import validation as val
from msf_contact.solver import simulate_impact

DOCS = Path(__file__).resolve().parents[1] / "docs"

# ------------------------------------------------------------ tolerances ----
#: Reference integration (rtol 1e-11) against exact results; spec: 1e-6.
SOLVER_RTOL = val.EXACT_RTOL
#: Exact relations solved by brentq; integration error far below this.
SOLVER_TIGHT_RTOL = val.EXACT_TIGHT_RTOL
#: Two code paths integrating the same ODE at rtol 1e-11 (self-consistent
#: omega by brentq to 1e-13): agreement well inside 1e-8.
SAME_ODE_RTOL = 1e-8
#: KK residual ratio err(V)/err(V/10) = 10^(3/5) = 3.98 for an O(V^(3/5))
#: residual; the next term O(V^(4/5)) shifts it by ~beta V^(1/5) ~ 10 %.
KK_SCALING_RTOL = 0.10
#: First-order slope of 1 - COR measured at tg = 1e-3: the O(tg) correction
#: is 0.18 % there (0.35 % at tg = 2e-3), so 0.5 % bounds it.
SLOPE_RTOL = 5e-3
#: (89) overestimates the integrated COR by more than this for tg >= 0.05
#: (a qualitative threshold; the measured values are in docs/validation.md).
COR89_OVERESTIMATE_MIN = 0.05
#: ... and by more than this at every tg measured (0.02 - 0.3).
COR89_OVERESTIMATE_ANY = 0.02
#: (95) printed and consistent both underestimate the integrated tau by more than this.
TAU95_UNDERESTIMATE_MIN = 0.15


def _assert_rows(rows):
    bad = [f"{r.case} {r.quantity}: {r.rel_diff:+.3e} > {r.tolerance:.1e}" for r in rows if r.passed is False]
    assert not bad, "\n".join(bad)
    assert all(r.passed is not None for r in rows if r.tolerance is not None)


# ----------------------------------------------------- (a) Hertz limit ------
def test_hertz_elastic_limit():
    rows = val.hertz_elastic_rows()
    _assert_rows(rows)
    assert {r.quantity for r in rows} == {"x_max [m]", "tau [s]", "F_max [N]", "COR [-]"}
    # the reference tau agrees with the textbook route (quadrature of the 2.94328 factor)
    c = val.HERTZ_CASE
    m = 4 / 3 * math.pi * c["R"] ** 3 * c["density"]
    ref = val.hertz_reference(m, c["V"], c["E"], c["R"])
    tau_row = next(r for r in rows if r.quantity == "tau [s]")
    assert abs(tau_row.reference / ref["tau"] - 1) < 1e-9


# -------------------------------------------------- (b) Kuwabara-Kono -------
def test_ramirez_C1_is_the_first_order_loss_integral():
    """C1 = 2 int_0^Xm X^(1/2) sqrt(1 - 0.8 X^(5/2)) dX with beta = 3/2 A (rho/m)^(2/5)."""
    assert abs(val.ramirez_C1_integral() / val.RAMIREZ_C1 - 1) < 1e-6  # C1 printed to 7 digits


def test_kuwabara_kono_cor_against_ramirez_series():
    errs = {}
    for V in val.KK_SPEEDS:
        num, ser, beta = val.kuwabara_kono_cor(V)
        b = beta * V**0.2
        errs[V] = num - ser
        assert 0.01 < b < 0.1  # the series regime, and damping large enough to measure
        assert abs(errs[V]) / b**3 <= val.KK_RESIDUAL_BOUND
        assert abs(1 - num) > 20 * abs(errs[V])  # the check is not vacuous: the loss is resolved
    # residual scales as (beta V^(1/5))^3: 10x lower speed, 10^(3/5) smaller
    v1, v2 = val.KK_SPEEDS
    ratio = errs[v1] / errs[v2]
    assert abs(ratio / (v1 / v2) ** 0.6 - 1) < KK_SCALING_RTOL
    _assert_rows(val.kuwabara_kono_rows())


# --------------------------------------------------- (c) Hunt-Crossley ------
def test_hunt_crossley_exact_relation_solver():
    """The reference itself: chi -> 0 is elastic; the root satisfies the energy relation."""
    assert abs(val.hunt_crossley_exact_cor(1e-9, 1.0) - 1) < 1e-8
    chi, v0 = 0.3, 1.0
    e = val.hunt_crossley_exact_cor(chi, v0)
    lhs = chi * v0 - math.log1p(chi * v0)
    rhs = -chi * e * v0 - math.log1p(-chi * e * v0)
    assert abs(lhs - rhs) < 1e-14 and 0 < e < 1


def test_hunt_crossley_both_separations():
    rows = val.hunt_crossley_rows()
    _assert_rows(rows)
    assert {r.case.split(", ")[-1] for r in rows if r.tolerance} == {"force-zero", "overlap-zero"}
    # Flores' chi is an approximation: the measured COR differs from the target
    flores = [r for r in rows if r.tolerance is None]
    assert flores and all(r.rel_diff < 0 for r in flores)


# --------------------------------------------------- (d) spring-dashpot -----
def test_spring_dashpot_reference_force_zero_time():
    """The Schwager-Poeschel end time makes k x + c x' vanish, x > 0, x' < 0 there."""
    k, c, m, v0 = 1e4, 3.0, 0.05, 1.0
    e, t = val.spring_dashpot_exact(k, c, m, v0, "force-zero")
    g = c / (2 * m)
    w = math.sqrt(k / m - g * g)
    x = v0 / w * math.exp(-g * t) * math.sin(w * t)
    xd = v0 * math.exp(-g * t) * (math.cos(w * t) - g / w * math.sin(w * t))
    assert abs(k * x + c * xd) < 1e-12 * c * v0 and x > 0 and xd < 0
    assert t < math.pi / w
    e0, t0 = val.spring_dashpot_exact(k, c, m, v0, "overlap-zero")
    assert abs(e0 - math.exp(-g * math.pi / w)) < 1e-14 and e > e0


def test_spring_dashpot():
    _assert_rows(val.spring_dashpot_rows())


# ---------------------------------------------------- (e) Chung & Ooi -------
def test_chung_ooi_tests_1_and_2():
    rows = val.chung_ooi_rows()
    _assert_rows(rows)
    assert len(rows) == 4 * (len(val.CHUNG_OOI_TEST1["speeds"]) + len(val.CHUNG_OOI_TEST2))


# ------------------------------------------------------- (f) MSF ------------
@pytest.fixture(scope="module")
def comps():
    return val.msf_comparisons()


@pytest.fixture(scope="module")
def errata(comps):
    return val.errata_numbers(comps)


def test_msf_is_self_consistent(comps):
    """omega_x tau_x = pi (46), (87) for every solved case."""
    for r in comps:
        assert abs(r.omega * r.tau / math.pi - 1) < SAME_ODE_RTOL


def test_msf_cor_independent_of_constant_kp(comps):
    """With k_p constant the self-consistent problem is scale-free: COR depends on tg only."""
    by = {(r.tan_delta, r.kp_mode): r for r in comps}
    for t in val.MSF_TAN_DELTAS:
        assert abs(by[(t, "hertz")].cor - by[(t, "msf-small")].cor) < SAME_ODE_RTOL
        # tau scales as k_p^(-2/5) like the Hertz duration
        assert abs(by[(t, "msf-small")].tau / by[(t, "hertz")].tau - 2 ** -0.2) < SAME_ODE_RTOL


def test_msf_89_overestimates_cor(comps):
    for r in comps:
        over = r.cor_89 / r.cor - 1
        assert over > COR89_OVERESTIMATE_ANY
        if r.tan_delta >= 0.05:
            assert over > COR89_OVERESTIMATE_MIN
    msf = sorted((r for r in comps if r.kp_mode == "msf"), key=lambda r: r.tan_delta)
    overs = [r.cor_89 / r.cor - 1 for r in msf]
    assert overs == sorted(overs)  # grows with tg(beta)


def test_msf_90_and_95_against_integrated(comps):
    for r in comps:
        assert r.x_max_90 > r.x_max * 1.01  # (90) overestimates x_max (uses the too high k_x of (89))
        assert r.tau_95_printed < r.tau * (1 - TAU95_UNDERESTIMATE_MIN)
        assert r.tau_95 < r.tau * (1 - TAU95_UNDERESTIMATE_MIN)
        assert abs(r.tau_95_printed / r.tau_95 - math.sqrt(cf.C95_PRINTED / cf.C95_CONSISTENT)) < 1e-12
        assert r.tau1 > r.tau - r.tau1  # force-zero: restitution shorter, against (62)


def test_msf_first_order_slope_against_ramirez(errata):
    """1 - COR ~ s tg: the integrated law follows Ramirez' C1 with A = 2 tg/omega_x; (89) does not."""
    s = errata["slope_msf_numerical"]
    assert abs(s / val.MSF_SLOPE_FIRST_ORDER - 1) < SLOPE_RTOL
    assert s / val.SLOPE_89 > 1.8


def test_msf_elastic_limit_is_hertz_with_kp():
    """tg -> 0: x_max and tau of the MSF law tend to Hertz (30) with k_p (msf-small: sqrt 2)."""
    r = val.msf_comparison(1e-6, "msf-small")
    assert abs(r.tau / r.tau_hertz - 1) < 1e-5  # O(tg) deviation
    x_h = float(cf.hertz_x_max(r.mass, val.MSF_CASE["V"], r.E, val.MSF_CASE["R"], math.sqrt(2)))
    assert abs(r.x_max / x_h - 1) < 1e-5
    assert 0 < 1 - r.cor < 1e-5


def test_kuwabara_kono_with_equivalent_A_is_the_msf_law():
    """(47) with omega fixed equals Kuwabara-Kono with A = 2 tg/omega: same COR, same tau."""
    tg, omega = 0.1, 1200.0
    law, b1, b2 = val.msf_case_law(tg, "hertz", omega=omega)
    msf = simulate_impact(law, b1, b2, val.MSF_CASE["V"])
    kk = val.kk_with_A(float(cf.kuwabara_kono_A_equivalent(tg, omega)), tg, omega)
    assert abs(kk / msf.cor_n - 1) < SAME_ODE_RTOL


def test_simulate_impact_and_self_consistent_agree():
    law, b1, b2 = val.msf_case_law(0.1, "msf")
    rec = simulate_impact(law, b1, b2, val.MSF_CASE["V"])
    omega, sol, _ = law.self_consistent(val.MSF_CASE["V"], b1.mass)
    assert abs(rec.cor_n / sol.cor - 1) < SAME_ODE_RTOL
    assert abs(rec.tau / sol.tau - 1) < SAME_ODE_RTOL
    assert abs(rec.omega_x / omega - 1) < SAME_ODE_RTOL


# --------------------------------------------------- documents current ------
def test_validation_md_is_current(comps):
    """docs/validation.md holds the MSF table as measured now (regenerate: make docs)."""
    text = (DOCS / "validation.md").read_text(encoding="utf-8")
    assert val.REGENERATE in text
    assert val.render_msf_table(comps) in text, "docs/validation.md is stale: run `make docs`"
    assert "Checks failing: 0." in text


def test_errata_md_is_current(comps, errata):
    text = (DOCS / "errata.md").read_text(encoding="utf-8")
    assert val.REGENERATE.split("  #")[0] in text
    for name, body in val.render_errata_blocks(comps, errata).items():
        block = f"<!-- generated:{name} -->\n{body}\n<!-- /generated:{name} -->"
        assert block in text, f"docs/errata.md block {name!r} is stale: run `make docs`"


def test_rule_91_measurement(errata):
    """(91) makes the pair lossless with an elastic plate; the compliance series does not."""
    r = errata["rule91"]
    assert r["tg_pair"] == 0.0 and r["tg_91"] == 0.0
    assert abs(r["cor_91"] - 1) < 1e-8
    assert 0.09 < r["tg_complex"] <= 0.1 and r["cor_complex"] < 0.8
    assert np.isfinite([r["cor_91"], r["cor_complex"]]).all()


#: Chung & Ooi test 3: spring-dashpot (linear oscillator) and Hunt-Crossley
#: with the exact damping return e itself; the reference solver's COR is good
#: to ~1e-10 (measured <= 3e-11 relative over the 20 cells).
CHUNG_OOI_COR_RTOL = 1e-9
#: Test 4, gross sliding: the compliant contact against the rigid-body limit
#: e_t = 1 - mu (1 + e_n)/tan(theta); the remaining difference is the lever
#: arm R - x/2 and the stick phase at onset (measured <= 3e-5 in cor_t and
#: 1.5e-3 in spin).
CHUNG_OOI_SLIDING_RTOL = 2e-3


def test_chung_ooi_tests_3_and_4():
    """Issue 12: tests 3-4 run in the suite, and test 3 is no longer circular
    for MSF (tg(beta) from the paper's (88), not from the solver's own COR)."""
    from experiments.scenarios import chung_ooi

    cfg = chung_ooi.load({"scenario": "chung-ooi", "tests": {"run": [3, 4]}}, "chung_ooi.toml")
    for cell in chung_ooi.cells(cfg):
        (r,) = chung_ooi.run_cell(cell)
        if cell["test"] == 3:
            if cell["law"] in ("spring-dashpot", "hunt-crossley"):
                assert r["cor_n"] == pytest.approx(cell["cor"], rel=CHUNG_OOI_COR_RTOL), cell
            elif r["applies"] and cell["cor"] < 1:
                # (89) overstates the model's COR: the solver returns less than the e whose (88) tg(beta) it got
                assert 0.8 * cell["cor"] < r["cor_n"] < cell["cor"], cell
            else:
                assert r["applies"] == (cell["cor"] >= 0.5), cell  # (88) gives tg(beta) > 1/3 below e ~ 0.52
        elif r["sliding_regime"]:
            assert r["cor_t"] == pytest.approx(r["ref_cor_t_sliding"], rel=CHUNG_OOI_SLIDING_RTOL), cell
            assert r["spin_out"] == pytest.approx(r["ref_spin_sliding"], rel=CHUNG_OOI_SLIDING_RTOL), cell
