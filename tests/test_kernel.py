"""The compiled contact core (engines._kernel) against the manager's numpy path.

Both paths run the same scenes in the tiny engine of test_engine_core; the
records, the forces and the per-pair state must agree. The numpy path is
the implementation the engines' tests were built on; the kernel is what
the adapters run by default.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_engine_core import (CORE_RTOL, LAWS_PTFE, LAWS_RUBBER, PTFE, R_PTFE, RIGID, FakeEngine, _static_overlap,
                              balls_on_plate)

from engines._contacts import ContactManager, kernel_law
from engines.base import PairSpec
from msf_contact import ContactPair, Curvature, make_law, preset
from msf_contact.laws import MSFLaw

#: One contact row: both paths do the same arithmetic in another order
#: (einsum against written-out sums) and find the same roots to ROOT_TOL
#: (1e-13 of a substep): agreement to round-off, amplified by the
#: root finding's conditioning near a grazing end; 1e-9 relative.
SAME_RTOL = 1e-9
#: Several rows at once: the numpy path steps every row of a batch with the
#: finest row's internal step and iterates Newton until all rows converge,
#: the kernel steps each row with its own. Each path is within CORE_RTOL of
#: the exact contact (test_engine_core), so they agree within twice that;
#: repeated bounces under gravity carry the difference from one bounce to
#: the next (measured: 1e-4 on the fifth bounce's COR).
BATCH_RTOL = 2 * CORE_RTOL
RECORD_KEYS = ("cor_n", "cor_t", "cor_t_contact", "tau", "tau1", "x_max", "F_max", "Pc_max", "W_el_comp",
               "W_visc_comp", "W_diss_n", "W_diss_t", "Q_t", "spin_in", "spin_out", "f_min", "f_max")


def twin(make, compiled):
    """The engine of make() with its manager rebuilt as compiled or numpy."""
    eng = make()
    old = eng.mgr
    eng.mgr = ContactManager(old.pairs, old.dt, "fake", compiled=compiled)
    eng.mgr.set_body_probe(lambda q: {"omega1": eng.w[eng.idx[q, 0]].copy()})
    return eng


def run_both(make, steps):
    """(compiled engine, numpy engine, per-step forces of each) after `steps` steps."""
    out = []
    for compiled in (True, False):
        eng = twin(make, compiled)
        forces = []
        for _ in range(steps):
            kin = eng.kinematics()
            res = eng.mgr.step(kin)
            forces.append((res.pair.copy(), res.force.copy()))
            eng.integrate(res)
        out.append((eng, forces))
    return out


def close(a, b, rtol, scale):
    if a is None or b is None:
        return a is None and b is None
    return abs(a - b) <= rtol * max(abs(b), scale)


def compare(make, steps, rtol, min_records=1):
    (ec, fc), (en, fn) = run_both(make, steps)
    rc, rn = ec.mgr.pop_records(), en.mgr.pop_records()
    assert len(rc) == len(rn) >= min_records
    for a, b in zip(rc, rn):
        assert a.ended_by == b.ended_by
        assert a.inputs["pair"] == b.inputs["pair"]
        for key in RECORD_KEYS:
            va, vb = getattr(a, key), getattr(b, key)
            # each quantity against its natural scale (it may be ~0, e.g. a normal impact's cor_t)
            scale = 0.0
            if key.startswith(("W_", "Q_")):  # works: against the impact's kinetic energy (differences)
                scale = 0.5 * b.inputs["mass_effective"] * (b.inputs["v_n_in"] ** 2 + b.inputs["v_t_in"] ** 2)
            elif key in ("cor_n", "cor_t", "cor_t_contact", "f_min", "f_max"):  # ratios of order 1
                scale = 1.0
            elif key.startswith("spin"):  # against the spin a rolling ball at the impact speed would have
                scale = (b.inputs["v_n_in"] + b.inputs["v_t_in"]) / 0.001
            assert close(va, vb, rtol, scale), (key, va, vb)
    # final body states (the forces applied, step after step)
    vscale = float(np.max(np.abs(en.v))) + 1e-30
    assert np.allclose(ec.v, en.v, rtol=rtol, atol=rtol * vscale)
    assert np.allclose(ec.p, en.p, rtol=rtol, atol=rtol * float(np.max(np.abs(en.p))))
    assert np.array_equal(ec.mgr.active, en.mgr.active)
    return rc, ec, en


# -- one row: the same arithmetic --------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS_RUBBER))
def test_one_ball_every_law_matches_numpy_path(name):
    law = LAWS_RUBBER[name]
    dt = 1e-3
    # gap 0.37 of a step's travel: onset inside a step, contact over several steps
    compare(lambda: balls_on_plate(law, 0.02, 2.0, dt, [0.37 * 2.0 * dt]), 12, SAME_RTOL)


@pytest.mark.parametrize("name", list(LAWS_PTFE))
def test_one_short_contact_inside_a_step_matches_numpy_path(name):
    # PTFE at 1 m/s lasts ~0.4 ms: the whole contact inside one 2 ms step (onset, turn and end located)
    law = LAWS_PTFE[name]
    compare(lambda: balls_on_plate(law, R_PTFE, 1.0, 2e-3, [0.61 * 1.0 * 2e-3]), 4, SAME_RTOL)


def test_oblique_spin_coulomb_cap_and_paper_mode_match_numpy_path():
    pair = ContactPair(PTFE, RIGID)
    law = make_law("msf", pair, Curvature.sphere_on_plane(R_PTFE), omega=8000.0, mu=0.2)
    for mode in ("contact-point", "paper"):
        rc, _, _ = compare(lambda: balls_on_plate(law, R_PTFE, 1.0, 1e-4, [1.3e-5], angle_deg=30.0, spin=40.0,
                                                  tangential=mode), 80, SAME_RTOL)
        assert rc[0].cor_t is not None and rc[0].f_max > 0  # the tangential force acted


def test_overlap_zero_and_small_kp_match_numpy_path():
    pair = ContactPair(PTFE, RIGID)
    c = Curvature.sphere_on_plane(R_PTFE)
    for law in (make_law("msf", pair, c, omega=8000.0, separation="overlap-zero"),
                make_law("msf", pair, c, omega=8000.0, kp_mode="msf-small"),
                make_law("spring-dashpot", pair, c, separation="overlap-zero")):
        rc, _, _ = compare(lambda: balls_on_plate(law, R_PTFE, 1.0, 1e-3, [3e-4]), 6, SAME_RTOL)
        assert rc[0].ended_by == ("overlap-zero" if law.separation == "overlap-zero" else rc[0].ended_by)


def test_self_consistent_omega_matches_numpy_path():
    law = make_law("msf", ContactPair(PTFE, RIGID), Curvature.sphere_on_plane(R_PTFE))
    compare(lambda: balls_on_plate(law, R_PTFE, 1.0, 1e-3, [4e-4]), 6, SAME_RTOL)


def test_two_free_spheres_match_numpy_path():
    law = make_law("msf", ContactPair(PTFE, PTFE), Curvature.two_spheres(R_PTFE, R_PTFE), omega=8000.0)
    m = 4.0 / 3.0 * math.pi * R_PTFE**3 * PTFE.density

    def make():
        pos = [[0.0, 0.0, 0.0], [2 * R_PTFE + 2.3e-4, 0.003, 0.0]]
        return FakeEngine([PairSpec("a", "b", law)], [(0, 1)], [R_PTFE] * 2, [m, m], pos,
                          [[1.0, 0.0, 0.0], [-0.5, 0.0, 0.0]], [[0, 0, 3.0], [0, 0, 0]], 1e-3)

    compare(make, 5, SAME_RTOL)


# -- many rows: bounces, micro-bounces and the settled path ----------------------------------
def rows_are_independent(law, R, dt, gaps, steps, gravity):
    """The kernel with one row per ball equals the numpy path run for each ball
    alone (the numpy path steps the rows of a batch together, so only a
    single-row numpy run is the same computation). Returns the kernel engine."""
    multi = twin(lambda: balls_on_plate(law, R, 0.0, dt, gaps, gravity=gravity), True)
    for _ in range(steps):
        multi.step()
    recs = multi.mgr.pop_records()
    for k, gap in enumerate(gaps):
        one = twin(lambda: balls_on_plate(law, R, 0.0, dt, [gap], gravity=gravity), False)
        for _ in range(steps):
            one.step()
        mine = [r for r in recs if r.inputs["pair"] == k]
        theirs = one.mgr.pop_records()
        assert len(mine) == len(theirs)
        for a, b in zip(mine, theirs):
            for key in ("cor_n", "tau", "x_max", "F_max", "W_diss_n"):
                assert close(getattr(a, key), getattr(b, key), SAME_RTOL, 0.0), (k, key)
        assert np.allclose(multi.v[k], one.v[0], rtol=SAME_RTOL, atol=1e-15)
        assert np.allclose(multi.p[k, 2], one.p[0, 2], rtol=SAME_RTOL, atol=0.0)
        assert multi.mgr.settled[k] == one.mgr.settled[0]
    return multi, recs


def test_dropped_balls_bounce_and_settle_row_by_row():
    # natural rubber balls dropped from different gaps at dt = 1 ms under gravity: impacts,
    # bounces down to micro-bounces, then resting contacts on the settled path; 600 steps
    multi, recs = rows_are_independent(LAWS_RUBBER["msf"], 0.02, 1e-3, [0.0, 1e-4, 7e-4, 3e-3, 1.1e-2], 600, 9.81)
    assert len(recs) > 20
    assert np.all(multi.mgr.settled[:3])  # the three lowest drops ended on the settled path


def test_steel_on_steel_rests_on_the_settled_path_row_by_row():
    # omega dt ~ 30 (test_engine_core): only the settled path keeps this stable
    steel, R = preset("steel"), 0.01
    law = make_law("msf", ContactPair(steel, steel), Curvature.sphere_on_plane(R))
    m = 4.0 / 3.0 * math.pi * R**3 * steel.density
    x_s = _static_overlap(law, m, law.onset([1.0], [m]))
    multi, _ = rows_are_independent(law, R, 2e-3, [-0.99 * x_s, 0.0], 150, 9.81)
    assert np.all(multi.mgr.settled)


def test_batch_of_first_impacts_matches_numpy_batch():
    # first impacts only (no history to diverge): the numpy batch's shared internal step
    # against the kernel's own step per row, BATCH_RTOL
    law = LAWS_RUBBER["msf"]
    compare(lambda: balls_on_plate(law, 0.02, 1.0, 1e-3, [0.0, 3e-4, 6e-4, 9e-4]), 8, BATCH_RTOL, 4)


# -- which laws the kernel takes --------------------------------------------------------------
class _OwnTangential(MSFLaw):
    def tangential_force(self, x, s, sdot, onset, F_n=None):
        F, sl = super().tangential_force(x, s, sdot, onset, F_n)
        return 0.5 * F, sl


def test_registry_laws_take_the_kernel_and_overridden_laws_do_not():
    pair = ContactPair(PTFE, RIGID)
    c = Curvature.sphere_on_plane(R_PTFE)
    for law in LAWS_PTFE.values():
        assert kernel_law(law) is not None
    own = _OwnTangential(pair, c, omega=8000.0)
    assert kernel_law(own) is None
    mgr = ContactManager([PairSpec("a", "b", own)], 1e-3, "fake")
    assert all(v is None for v in mgr._kernel_law.values())
    # and a run with it still works on the numpy path, with its own tangential force
    eng = balls_on_plate(own, R_PTFE, 1.0, 1e-4, [1e-5], angle_deg=30.0)
    rec = eng.run_until_records(1, 0.01)[0]
    assert 0.0 < rec.cor_n < 1.0


def test_rows_of_several_laws_in_one_kernel_call():
    # a rubber MSF ball, a PTFE Hertz ball and a PTFE Kuwabara-Kono ball in one manager: one kernel
    # call carries the three laws; each ball equals its own single-law numpy run
    specs = [(LAWS_RUBBER["msf"], 0.02, 0.6e-3), (LAWS_PTFE["hertz"], R_PTFE, 0.3e-3),
             (LAWS_PTFE["kuwabara-kono"], R_PTFE, 0.45e-3)]

    def engine(items, compiled):
        masses = [4.0 / 3.0 * math.pi * R**3 * law.pair.body1.density for law, R, _ in items]
        eng = FakeEngine([PairSpec(f"b{k}", "plate", law) for k, (law, _, _) in enumerate(items)],
                         [(k, -1) for k in range(len(items))], [R for _, R, _ in items], masses,
                         [[0.1 * k, 0.0, R + gap] for k, (_, R, gap) in enumerate(items)],
                         [[0.0, 0.0, -1.0]] * len(items), [[0.0, 0.0, 0.0]] * len(items), 1e-3)
        eng.mgr = ContactManager(eng.mgr.pairs, 1e-3, "fake", compiled=compiled)
        return eng

    multi = engine(specs, True)
    assert multi.mgr._kcodes.size == 3 and multi.mgr._all_kernel
    for _ in range(10):
        multi.step()
    recs = multi.mgr.pop_records()
    assert len(recs) == 3
    for k, item in enumerate(specs):
        one = engine([item], False)
        for _ in range(10):
            one.step()
        (b,) = one.mgr.pop_records()
        (a,) = [r for r in recs if r.inputs["pair"] == k]
        assert a.law == b.law
        for key in ("cor_n", "tau", "x_max", "F_max"):
            assert close(getattr(a, key), getattr(b, key), SAME_RTOL, 0.0), (k, key)
        assert np.allclose(multi.v[k], one.v[0], rtol=SAME_RTOL, atol=1e-15)


def _kin(**over):
    base = dict(pair=np.array([0]), x=np.array([-1e-3]), normal=np.array([[0, 0, 1.0]]), point=np.zeros((1, 3)),
                v_rel=np.array([[0.0, 0.0, -1.0]]), v_com_rel=np.array([[0.0, 0.0, -1.0]]), W=np.eye(3)[None],
                W_com=np.eye(3)[None], a_ext=np.zeros((1, 3)), t=0.0)
    base.update(over)
    from engines.base import ContactKinematics
    return ContactKinematics(**base)


@pytest.mark.parametrize("compiled", [True, False])
def test_bad_kinematics_are_refused_by_name(compiled):
    law = LAWS_PTFE["hertz"]
    specs = [PairSpec("a", "plate", law), PairSpec("b", "plate", law)]
    for field, value in (("x", np.array([np.nan])), ("normal", np.array([[0.0, np.inf, 1.0]])),
                         ("v_rel", np.array([[np.nan, 0.0, 0.0]])), ("W", np.full((1, 3, 3), np.inf)),
                         ("a_ext", np.array([[0.0, 0.0, -np.inf]]))):
        mgr = ContactManager(specs, 1e-3, "fake", compiled=compiled)
        with pytest.raises(ValueError, match=f"kinematics.{field} is not finite"):
            mgr.step(_kin(**{field: value}))
    mgr = ContactManager(specs, 1e-3, "fake", compiled=compiled)
    with pytest.raises(ValueError, match="unit vectors"):
        mgr.step(_kin(normal=np.array([[0.0, 0.0, 1.1]])))
    with pytest.raises(ValueError, match="twice"):
        mgr.step(_kin(pair=np.array([1, 1]), x=np.full(2, -1e-3), normal=np.tile([0, 0, 1.0], (2, 1)),
                      point=np.zeros((2, 3)), v_rel=np.zeros((2, 3)), v_com_rel=np.zeros((2, 3)),
                      W=np.tile(np.eye(3), (2, 1, 1)), W_com=np.tile(np.eye(3), (2, 1, 1)), a_ext=np.zeros((2, 3))))
    # huge but finite values are not an error (their sum overflows: the row is then checked element-wise)
    mgr = ContactManager(specs, 1e-3, "fake", compiled=compiled)
    mgr.step(_kin(point=np.array([[1e308, 1e308, 1e308]])))


def test_body_probe_batch_is_used_once_per_batch_between_steps():
    # records completed when read (pop_records) take one batch probe for all of them
    law = LAWS_PTFE["hertz"]
    eng = balls_on_plate(law, R_PTFE, 1.0, 1e-3, [1e-4, 2e-4, 3e-4])
    calls = {"batch": 0, "probe": 0}

    def probe(q):
        calls["probe"] += 1
        return {"omega1": eng.w[eng.idx[q, 0]].copy()}

    def batch():
        calls["batch"] += 1
        return probe

    eng.mgr.set_body_probe(probe, batch=batch)
    for _ in range(2):  # the three 0.4 ms contacts begin and end in step 1; step 2 removes their correction
        eng.step()
    assert eng.mgr.pending_count == 3  # waiting for their post-impact state
    recs = eng.mgr.pop_records()
    assert len(recs) == 3 and all(r.inputs["body_out"] is not None for r in recs)
    assert calls["batch"] == 1
    with pytest.raises(ValueError, match="batch"):
        eng.mgr.set_body_probe(probe, batch=42)


def _own_gaps_numpy(pair, x, xm_state, active, listed, own_gap, xdot, xd0, an, off, xd0_new, an_new, dt, rate, tol):
    """ContactManager._own_gaps as written in numpy before it was compiled (commit 23c1939), less its
    condition xm <= 0 (issue 13: a contact that ended at force zero with x > 0 restarts from
    touching, not from the engine's x)."""
    xm = xm_state[pair]
    act, lst = active[pair], listed[pair]
    lead = 0.5 * dt * (np.abs(xdot[pair] - xd0[pair]) + np.abs(an[pair]) * dt)
    o = np.where(lst, off[pair] * np.where(act, 1.0, 1.0 - rate) + lead, 0.0)
    own = own_gap[pair] & ~act & lst & (np.abs(x - xm) <= 2.0 * o + tol)
    off[pair] = np.where(act | own, o, 0.0)
    xd0[pair] = xd0_new
    an[pair] = an_new
    return np.where(own, np.minimum(xm + rate * (x - xm), 0.0), x), int(own.sum())


def test_own_gaps_kernel_is_the_numpy_arithmetic_bit_for_bit():
    """engines._kernel.own_gaps against its numpy form on random states where
    about half the rows keep the manager's gap: the same gaps and the same
    per-pair state, bit for bit (the same operations in the same order), so
    compiling it changed no result."""
    from engines import _kernel as K
    from engines._contacts.islands import TOUCH_TOL

    rng = np.random.default_rng(7)
    P, k, dt, rate = 400, 300, 1e-3, 0.3
    for _ in range(20):
        pair = rng.permutation(P)[:k].astype(np.int64)
        xm = np.where(rng.random(P) < 0.7, -rng.random(P) * 1e-4, rng.random(P) * 1e-5)
        xm[rng.random(P) < 0.05] = 0.0
        active, listed, own_gap = (rng.random(P) < 0.3), (rng.random(P) < 0.8), (rng.random(P) < 0.8)
        xdot, xd0, an = rng.normal(size=P), rng.normal(size=P), rng.normal(size=P) * 10
        off = rng.random(P) * 1e-4
        x = xm[pair] + rng.normal(size=k) * 2e-4
        xd0_new, an_new = rng.normal(size=k), rng.normal(size=k)
        states = [[a.copy() for a in (xd0, an, off)] for _ in range(2)]
        ref, n_ref = _own_gaps_numpy(pair, x, xm, active, listed, own_gap, xdot, *states[0], xd0_new, an_new, dt,
                                     rate, TOUCH_TOL)
        out = np.empty(k)
        n_k = K.own_gaps(pair, x, xm, active, listed, own_gap, xdot, *states[1], xd0_new, an_new, dt, rate,
                         TOUCH_TOL, out)
        assert n_k == n_ref
        assert 0 < n_ref < k
        np.testing.assert_array_equal(out, ref)
        for a, b in zip(*states):
            np.testing.assert_array_equal(a, b)


#: tangential_w_max against LAPACK's eigvalsh: both round differently (a 2x2
#: closed form against an iterative 3x3 solve), a few ulp of the eigenvalue
#: (measured <= 1.4e-15 relative on these matrices).
W_MAX_RTOL = 1e-13


def test_tangential_w_max_is_the_largest_eigenvalue_of_TWT():
    """engines._kernel.tangential_w_max (ContactManager._begin's tangential
    inverse inertia, which sets the tangential internal step) against
    np.linalg.eigvalsh(T W T)[-1], T = I - n n^T, on random symmetric
    positive W, normals along the axes (the tangent basis' switch at
    |n_x| = 0.9) and isotropic W (a double eigenvalue, where a root of a
    difference would lose digits)."""
    from engines import _kernel as K

    rng = np.random.default_rng(11)
    k = 500
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    n[:3] = np.eye(3)
    A = rng.normal(size=(k, 3, 3))
    W = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(3)
    W[3:10] = 2.5 * np.eye(3)
    T = np.eye(3) - n[:, :, None] * n[:, None, :]
    want = np.linalg.eigvalsh(T @ W @ T)[:, -1]
    got = np.empty(k)
    K.tangential_w_max(n, W, got, np.empty((2, 3)))
    np.testing.assert_allclose(got, want, rtol=W_MAX_RTOL, atol=0.0)
    np.testing.assert_allclose(got[3:10], 2.5, rtol=W_MAX_RTOL)


def test_approach_rates_are_the_numpy_dot_products():
    """engines._kernel.approach_rates (ContactManager._own_gaps' approach rate
    and normal acceleration) against the numpy form it replaced,
    -einsum('ij,ij->i', v - dv_corr[pair], n) and -einsum('ij,ij->i', a, n):
    the same products summed in einsum's order, equal to an ulp of the
    largest product (bit for bit where einsum sums lanes pairwise, as on the
    x86 machines measured)."""
    from engines import _kernel as K

    rng = np.random.default_rng(3)
    P, k = 300, 200
    pair = rng.permutation(P)[:k].astype(np.int64)
    v, a = rng.normal(size=(k, 3)) * 3.0, rng.normal(size=(k, 3)) * 10.0
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    dv = rng.normal(size=(P, 3)) * 1e-3
    xd0, an = np.empty(k), np.empty(k)
    K.approach_rates(pair, v, dv, a, n, xd0, an)
    u = v - dv[pair]
    for got, want, scale in ((xd0, -np.einsum("ij,ij->i", u, n), np.abs(u).max(axis=1)),
                             (an, -np.einsum("ij,ij->i", a, n), np.abs(a).max(axis=1))):
        assert np.all(np.abs(got - want) <= 4e-16 * scale)
