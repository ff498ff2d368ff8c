"""Fast paths of the reference solver against the plain implementations they replace (issue 5).

- ``_normal.dop853`` against scipy's ``solve_ivp(method="DOP853")``: the same
  scheme without the per-step overhead;
- the math-module MSF kernels of the impact RHS against MSFLaw's numpy methods;
- the self-consistent root seeded from the eps spline and polished, against
  the bracketed brentq root;
- whole impacts on the fast path against the same impacts through
  solve_ivp, the law's numpy methods and the bracketed root.

Physics and equality only; the time per impact is measured in
``benchmarks/reference.py``.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from msf_contact import _normal, _scaling, solver
from msf_contact.geometry import Curvature
from msf_contact.laws import MSFLaw, make_law
from msf_contact.materials import ContactPair, Material
from msf_contact.solver import Body, simulate_impact

#: dop853 and solve_ivp run the same tableau, error norm and step-size
#: control; only the rounding order of the stage sums and of the dense-output
#: polynomial differs. The adaptive steps carry that into the results at most
#: at the integration's own error (RTOL = 1e-11 per step, measured <= 4e-11 on
#: overlap-zero restitution); 1e-9 bounds it with margin and is three orders
#: below the reference accuracy of 1e-6 (issue 2).
SAME_SCHEME_RTOL = 1e-9
#: Step sizes follow error_norm^(-1/8) of an error estimate that is a
#: difference of nearly equal stage sums, so rounding moves them (measured
#: 2e-7 relative) without moving the solution beyond SAME_SCHEME_RTOL.
STEP_SIZE_RTOL = 1e-5
#: The inlined kernels evaluate MSFLaw's own expressions in the same order;
#: numpy's and the math module's sqrt are both correctly rounded.
SAME_EXPRESSION_RTOL = 4 * np.finfo(float).eps
#: Polished and bracketed roots of the same noisy residual both sit within
#: ~RTOL of it (measured: gamma 5e-12, restitution 4e-11 apart); 1e-9 bounds
#: the integration noise of the quantities at two such roots.
ROOT_PATHS_RTOL = 1e-9
#: Whole impacts, fast against plain path: the sum of the two above through
#: the stick-slip events, whose location uses a finite difference of the
#: Coulomb cap (measured <= 6e-10 on the work terms); 1e-8 leaves margin and
#: is two orders below the reference accuracy of 1e-6.
IMPACT_PATHS_RTOL = 1e-8
#: Dimensionless ratios that pass through zero (contact-point restitution of a
#: ball that ends nearly rolling, |F_t|/F_n at a force reversal) are compared
#: absolutely at the same level.
RATIO_ATOL = 1e-8

RUBBER = Material("rubber", 5e6, 0.1, 0.49, 930.0)
RIGID = Material.rigid_body()
R = 0.02


# ------------------------------------------------------------ integrator ---
def _unit_problem(gamma=0.3, eps=0.05, clamp=True):
    """The dimensionless MSF normal impact of msf_contact._scaling with its events."""

    def rhs(t, s):
        x, v = s[0], s[1]
        x = max(x, 0.0)
        F = math.sqrt(max(1.0 - eps * x, 1e-300)) * math.sqrt(x) * (x + gamma * v)
        return (v, -(max(F, 0.0) if clamp else F))

    def ev_turn(t, s):
        return s[1]

    def ev_force(t, s):
        return max(s[0], 0.0) + gamma * s[1] if s[1] < 0 else 1.0

    def ev_overlap(t, s):
        return s[0]

    ev_turn.direction = -1
    ev_force.terminal, ev_force.direction = True, -1
    ev_overlap.terminal, ev_overlap.direction = True, -1
    return rhs, [ev_turn, ev_force if clamp else ev_overlap]


@pytest.mark.parametrize("clamp", [True, False], ids=["force-zero", "overlap-zero"])
def test_dop853_takes_the_steps_of_solve_ivp(clamp):
    rhs, events = _unit_problem(clamp=clamp)
    kw = dict(rtol=_normal.RTOL, atol=_normal.ATOL_SCALED, first_step=1e-6)
    fast = _normal.dop853(rhs, (0.0, 1e3), (0.0, 1.0), events=events, **kw)
    plain = solve_ivp(rhs, (0.0, 1e3), (0.0, 1.0), method="DOP853", events=events, dense_output=True, **kw)
    assert fast.status == plain.status == 1
    # the same step-size sequence, up to rounding of the error norm (a difference
    # of nearly equal stage sums) that moves the step sizes by ~1e-7 relative
    assert abs(len(fast.t) - len(plain.t)) <= 1
    assert np.diff(fast.t)[:40] == pytest.approx(np.diff(plain.t)[:40], rel=STEP_SIZE_RTOL)
    for k in range(len(events)):
        assert fast.t_events[k] == pytest.approx(plain.t_events[k], rel=SAME_SCHEME_RTOL)
        assert fast.y_events[k] == pytest.approx(plain.y_events[k], rel=SAME_SCHEME_RTOL, abs=1e-12)
    tt = np.linspace(0.0, fast.t[-1], 57)
    assert fast.sol(tt) == pytest.approx(plain.sol(tt), rel=SAME_SCHEME_RTOL, abs=1e-12)
    assert fast.sol(tt[20]) == pytest.approx(plain.sol(tt[20]), rel=SAME_SCHEME_RTOL)


def test_dop853_without_events_reaches_the_end_of_the_span():
    """y' = -y over [0, 5]: status 0 at t = 5, y = exp(-5) to the tolerance."""
    fast = _normal.dop853(lambda t, y: (-y[0],), (0.0, 5.0), (1.0,), rtol=1e-11, atol=1e-14, first_step=1e-3)
    plain = solve_ivp(lambda t, y: -y, (0.0, 5.0), (1.0,), method="DOP853", rtol=1e-11, atol=1e-14, first_step=1e-3)
    assert fast.status == plain.status == 0
    assert fast.t[-1] == 5.0
    assert fast.y[0, -1] == pytest.approx(plain.y[0, -1], rel=SAME_SCHEME_RTOL)
    assert fast.y[0, -1] == pytest.approx(math.exp(-5.0), rel=1e-9)


# ---------------------------------------------------------------- kernels ---
class PlainMSF(MSFLaw):
    """MSFLaw with its normal force overridden (by itself): the solver must
    then call the law's methods instead of its inlined kernels."""

    def normal_force(self, x, xdot, onset):
        return super().normal_force(x, xdot, onset)


@pytest.mark.parametrize("kp_mode", ["msf", "msf-small", "hertz"])
@pytest.mark.parametrize("separation", ["force-zero", "overlap-zero"])
@pytest.mark.parametrize("curvature", [Curvature.sphere_on_plane(R), Curvature(0.02, 0.05)], ids=["sphere", "ellipse"])
def test_inlined_msf_kernels_equal_the_law(kp_mode, separation, curvature):
    law = MSFLaw(ContactPair(RUBBER, RIGID), curvature, kp_mode=kp_mode, separation=separation)
    assert solver._msf_inline(law) and not solver._msf_inline(PlainMSF(ContactPair(RUBBER, RIGID), curvature))
    m = 4 / 3 * math.pi * R**3 * RUBBER.density
    o1 = {k: np.atleast_1d(v)[:1] for k, v in law.onset_reference([1.3], [m]).items()}
    normal, kb, indicator, forces = solver._scalar_kernels(law, o1)
    rng = np.random.default_rng(0)
    xs = np.concatenate([[0.0, -1e-6, 1e-9, 2.0 * law.geom.R], rng.uniform(0.0, 3e-3, 40)])
    vs = rng.uniform(-2.0, 2.0, xs.size)
    for x, v in zip(xs.tolist(), vs.tolist()):
        xa = np.array([max(x, 0.0)])
        Fn, Fc = normal(x, v)
        assert Fn == pytest.approx(float(law.contact_normal_force(xa, np.array([v]), o1)[0]), rel=SAME_EXPRESSION_RTOL)
        assert Fc == pytest.approx(float(law.normal_force(xa, np.array([0.0]), o1)[0]), rel=SAME_EXPRESSION_RTOL)
        k, b = law.tangential_stiffness(xa, o1)
        assert kb(x) == pytest.approx((float(k[0, 0]), float(b[0, 0])), rel=SAME_EXPRESSION_RTOL)
        assert forces(x, v) == (Fn, Fc) + kb(x)
        assert indicator(xa[0], v) == pytest.approx(
            float(law.separation_indicator(xa, np.array([v]), o1)[0]), rel=SAME_EXPRESSION_RTOL)


# ------------------------------------------------------------------ roots ---
@pytest.mark.parametrize("separation", ["force-zero", "overlap-zero"])
@pytest.mark.parametrize("tan_delta", [0.02, 0.1, 0.25])
def test_polished_root_equals_the_bracketed_root(tan_delta, separation):
    """Between, on and beyond the table nodes, the seeded Newton/secant root
    is the brentq root, and it satisfies omega_x tau = pi to the tolerance."""
    for eps in (1e-4, 3e-3, 0.0123, 0.055, 0.3):
        fast = _scaling.self_consistent(tan_delta, eps, separation)
        slow = _scaling.self_consistent_bracketed(tan_delta, eps, separation)
        for key in ("gamma", "tau", "tau1", "x_max", "cor", "F_max"):
            assert getattr(fast, key) == pytest.approx(getattr(slow, key), rel=ROOT_PATHS_RTOL), (eps, key)
        residual = fast.gamma - 3.0 * tan_delta * fast.tau / math.pi
        assert abs(residual) <= _scaling.ROOT_TOL_PER_RTOL * _normal.RTOL * fast.gamma


def test_polish_falls_back_to_the_bracketed_root(monkeypatch):
    """Outside the table, or when the polish does not converge, the answer is
    the bracketed root itself."""
    tg, sep = 0.1, "force-zero"
    beyond = _scaling.EPS_NODES[-1] * 1.1
    assert _scaling.self_consistent.__wrapped__(tg, beyond, sep) == _scaling.self_consistent_bracketed(tg, beyond, sep)
    monkeypatch.setattr(_scaling, "MAX_POLISH_STEPS", 0)
    assert _scaling.self_consistent.__wrapped__(tg, 0.02, sep) == _scaling.self_consistent_bracketed(tg, 0.02, sep)


# ---------------------------------------------------------------- impacts ---
def _solve_ivp_dop853(fun, t_span, y0, *, rtol, atol, first_step, events=(), max_steps=None):
    """The plain integrator: solve_ivp's DOP853 with dense output, as before issue 5 (no step bound)."""
    return solve_ivp(fun, t_span, y0, method="DOP853", rtol=rtol, atol=atol, events=list(events),
                     dense_output=True, first_step=first_step)


#: Record fields compared relatively / absolutely (dimensionless ratios through zero).
RELATIVE_KEYS = ("cor_n", "cor_t", "tau", "tau1", "tau2", "x_max", "F_max", "Pc_max", "Pc_at_Fmax", "W_el_comp",
                 "W_visc_comp", "W_el_rest", "W_visc_rest", "W_diss_n", "W_diss_t", "Q_t", "spin_out",
                 "omega_x", "omega_y")
ABSOLUTE_KEYS = ("cor_t_contact", "f_min", "f_max", "cor_tau_ratio")


def _close(got, want, rtol, atol=0.0):
    if want is None or got is None:
        return got is want
    return abs(got - want) <= atol + rtol * abs(want)


@pytest.mark.parametrize("angle, spin, mu, separation", [
    (90.0, 0.0, None, "force-zero"),
    (45.0, 0.0, None, "force-zero"),
    (45.0, 30.0, 0.3, "force-zero"),
    (60.0, 0.0, None, "overlap-zero"),
])
def test_fast_impact_equals_the_plain_path(monkeypatch, angle, spin, mu, separation):
    """simulate_impact on its fast path (dop853, inlined kernels, polished
    root) against solve_ivp, the law's numpy methods and the bracketed root."""
    pair, curv = ContactPair(RUBBER, RIGID), Curvature.sphere_on_plane(R)
    b1, b2 = Body.sphere(RUBBER, R), Body.half_space(RIGID)
    fast = simulate_impact(MSFLaw(pair, curv, mu=mu, separation=separation), b1, b2, 1.7, angle, spin=spin)
    monkeypatch.setattr(solver, "dop853", _solve_ivp_dop853)
    monkeypatch.setattr(_normal, "dop853", _solve_ivp_dop853)
    monkeypatch.setattr(_scaling, "self_consistent", _scaling.self_consistent_bracketed)
    _scaling.unit_impact.cache_clear()
    try:
        plain = simulate_impact(make_law(PlainMSF, pair, curv, mu=mu, separation=separation), b1, b2, 1.7, angle,
                                spin=spin)
    finally:
        _scaling.unit_impact.cache_clear()  # its entries came from the plain integrator
    assert fast.ended_by == plain.ended_by
    for key in RELATIVE_KEYS:
        assert _close(getattr(fast, key), getattr(plain, key), IMPACT_PATHS_RTOL), key
    for key in ABSOLUTE_KEYS:
        assert _close(getattr(fast, key), getattr(plain, key), 0.0, RATIO_ATOL), key


def test_other_laws_take_the_fast_integrator_too(monkeypatch):
    """A law without inlined kernels (Hunt-Crossley with a Coulomb cap)
    gives the same impact through dop853 and through solve_ivp."""
    law = make_law("hunt-crossley", ContactPair(RUBBER, RIGID), Curvature.sphere_on_plane(R), cor=0.7, mu=0.2)
    b1, b2 = Body.sphere(RUBBER, R), Body.half_space(RIGID)
    fast = simulate_impact(law, b1, b2, 1.1, 30.0, spin=-20.0)
    monkeypatch.setattr(solver, "dop853", _solve_ivp_dop853)
    plain = simulate_impact(law, b1, b2, 1.1, 30.0, spin=-20.0)
    for key in RELATIVE_KEYS[:-2]:
        assert _close(getattr(fast, key), getattr(plain, key), IMPACT_PATHS_RTOL), key
    for key in ABSOLUTE_KEYS:
        assert _close(getattr(fast, key), getattr(plain, key), 0.0, RATIO_ATOL), key
