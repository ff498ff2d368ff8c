"""The compiled kernel of :mod:`engines.mujoco._resting`: one resting step of
the MuJoCo adapter's free group, chaining the compiled passes of
:mod:`engines.mujoco._kernels` and :mod:`engines._kernel` (that module's
docstring says when it is taken and why its results are the general
path's)."""

from __future__ import annotations

import numpy as np
from numba import njit

from engines import _kernel as K, _sweep
from engines.mujoco import _kernels as MK
from msf_contact._jitcache import guard as _guard

#: resting_step's codes: the whole step done; the general path goes on from the kinematics; the
#: free-group detection failed (the adapter's numpy detection says why)
RESTING, NOT_RESTING, BAD_DETECTION = 0, 1, 2


@njit(cache=True, error_model="numpy", _nrt=False)
def resting_step(t0, dt, settle_rate, timing, qfrc, force, point_c, pair_c,
                 gi, gf, group_of, pp_idx, geom_xpos, geom_xmat, cvel, subtree_com, xipos, ximat, xanchor, xmat,
                 required, last_v, last_dv, have_last, factor, coincident_rtol, push, last_r, last_gap, hold_pp, n_in,
                 fk_pair, fk_x, fk_n, fk_point, fk_v, fk_vc, fk_W, fk_Wc, fk_a, p1, p2, fk_scratch,
                 x_last, ad_p1, ad_p2,
                 active, settled, Jst, seen, point_state, n_unit, dv_corr, dvc_corr, x_state, listed, own_gap, xdot,
                 xd0, an, off, xd0_new, an_new, x_eng, save3, touch_tol, in_island, island_of,
                 cst, kg_pair, paper_pair, kg, paper, L0, codes, LC, oc, s_state, tau_est, W_el, W_visc, Q_t,
                 W_t, y, T, t_loc, in_c, settled_r, status, turned, fl, ints, buf, m33, v3, M34,
                 vc_state, phase, outside, couple, impulse,
                 hold, t_onset, settle_after, steps_min, hit, keep, bodies, F, arm):
    """One resting step of the adapter's free group (module docstring).

    The arguments are those of the passes it chains, under the adapter's and
    the manager's names: the free group's constants and MjData arrays
    (:func:`engines.mujoco._kernels.free_kinematics_into`, its buffers
    ``fk_*``, ``p1``, ``p2``), the adapter's a_ext state and contact points
    (P, 3), the manager's per-pair state (P,[ 3]) and per-row scratch
    (k,[ ...]) of :func:`engines._kernel.check`, ``approach_rates``,
    ``own_gaps``, ``prelude`` and ``finale``; save3 (3, k): the own-gap state
    of the rows kept for a restore; hold_pp, hold (P,) bool: scratch.

    Compiled without numba's reference counting (as engines._kernel): nothing
    is allocated, so a call boxes no array and unboxes its ~100 array
    arguments without a reference-counted wrapper each (measured: ~4 us per
    call with 90 arrays). Its outputs go into the caller's arrays: force,
    point_c (k, 3) [N, m] and pair_c (k,), the manager's ContactForces in
    their first n rows; hit, keep (k,) bool, bodies (2k, 3) int64, F, arm
    (2k, 3): :func:`engines.mujoco._kernels.after_step`'s outputs in their
    first n and m rows.

    Returns (code, n, the detection's error code, n_hit, n_unheld, m): on RESTING
    after_step's counts and m; otherwise n (the candidates in the fk buffers).
    """
    P = active.shape[0]
    # the adapter's required mask and held sphere-sphere geometry (_compute_compiled, _held_geometry)
    MK.required_mask(active, Jst, required)
    for q in range(hold_pp.shape[0]):
        hold_pp[q] = False
    for j in range(pp_idx.shape[0]):
        q = pp_idx[j]
        hold_pp[q] = required[q] and tau_est[q] < dt and not (
            active[q] and (t0 - t_onset[q]) > settle_after * tau_est[q]) and (
            active[q] or Jst[q, 0] != 0.0 or Jst[q, 1] != 0.0 or Jst[q, 2] != 0.0)
    err, n = MK.free_kinematics_into(gi, gf, geom_xpos, geom_xmat, cvel, subtree_com, xipos, ximat, required,
                                     last_v, last_dv, have_last, dt, factor, coincident_rtol, push, last_r, last_gap,
                                     hold_pp, n_in, x_state, fk_pair, fk_x, fk_n, fk_point, fk_v, fk_vc, fk_W, fk_Wc,
                                     fk_a, p1, p2, fk_scratch)
    if err != MK.ERR_NONE:
        return BAD_DETECTION, 0, err, 0, 0, 0
    for g in range(gi.shape[0]):  # the adapter's _p1, _p2 of the group's pairs
        q = gi[g, MK.I_PAIR]
        for i in range(3):
            ad_p1[q, i] = p1[g, i]
            ad_p2[q, i] = p2[g, i]
    pair = fk_pair[:n]
    x = fk_x[:n]
    nrm = fk_n[:n]
    point = fk_point[:n]
    v = fk_v[:n]
    vc = fk_vc[:n]
    W = fk_W[:n]
    Wc = fk_Wc[:n]
    a = fk_a[:n]
    # 2. a moving contact point for a row not settled in the last step (_lever, lever_free): general path
    for r in range(n):
        if not settled[pair[r]]:
            return NOT_RESTING, n, 0, 0, 0, 0
    # lever_free without live rows: x_last = max(x, 0) of the rows, 0 elsewhere
    for q in range(x_last.shape[0]):
        x_last[q] = 0.0
    for r in range(n):
        x_last[pair[r]] = MK._nonneg(x[r])
    # ContactManager.step: the input check, the own gaps
    nu = n_unit[:n]
    code, row = K.check(pair, P, x, nrm, point, v, vc, W, Wc, a, active, Jst, seen, nu, point_state)
    if code:
        return NOT_RESTING, n, 0, 0, 0, 0
    for r in range(n):  # the own-gap state the general path would start from again
        q = pair[r]
        save3[0, r], save3[1, r], save3[2, r] = off[q], xd0[q], an[q]
    K.approach_rates(pair, v, dv_corr, a, nu, xd0_new[:n], an_new[:n])
    xe = x_eng[:n]
    K.own_gaps(pair, x, x_state, active, listed, own_gap, xdot, xd0, an, off, xd0_new[:n], an_new[:n], dt,
               settle_rate, touch_tol, xe)
    for q in range(P):
        in_island[q] = False
        island_of[q] = -1
    # _step_compiled: prelude; 3. every row settled, else back to the general path
    for r in range(n):
        kg[r] = kg_pair[pair[r]]
        paper[r] = paper_pair[pair[r]]
    ints[0], ints[1], ints[2], ints[3] = 0, 0, 0, 0
    K.prelude(cst, pair, xe, nu, v, vc, W, Wc, a, paper[:n], L0[:n], t0, dt, settle_rate, True, kg[:n], codes, LC, oc,
              active, settled, x_state, s_state, tau_est, dv_corr, dvc_corr, W_el, W_visc, Q_t, W_t, y[:n], T[:n],
              t_loc[:n], in_c[:n], settled_r[:n], status[:n], turned, fl, ints, buf, m33, v3, M34)
    for r in range(n):
        if not settled_r[r]:
            for j in range(n):
                q = pair[j]
                off[q], xd0[q], an[q] = save3[0, j], save3[1, j], save3[2, j]
            return NOT_RESTING, n, 0, 0, 0, 0
    # advance() has nothing to do (every row's t_loc is dt); finale, the forces (impulse / dt)
    imp = impulse[:n]
    K.finale(pair, nu, W, Wc, settled_r[:n], in_c[:n], y[:n], dt, timing, kg[:n], LC, active, x_state, xdot, s_state,
             vc_state, W_el, W_visc, Q_t, W_t, phase, outside, settled, Jst, dv_corr, dvc_corr, imp, couple)
    for r in range(n):
        for i in range(3):
            force[r, i] = imp[r, i] / dt
            point_c[r, i] = point[r, i]
        pair_c[r] = pair[r]
    for q in range(P):
        listed[q] = False
    for r in range(n):
        listed[pair[r]] = True
    # the adapter: held_forces (ContactManager.held) and after_step
    t_next = t0 + dt
    for q in range(P):
        hold[q] = False
    for r in range(n):
        q = pair[r]
        hold[q] = active[q] and (settled[q] or (t_next - t_onset[q]) > settle_after * tau_est[q]
                                 or tau_est[q] >= steps_min * dt)
    n_hit, n_unheld, m = MK.after_step_into(
        gi, group_of, pair_c[:n], force[:n], hold, hold, t_onset, tau_est, t_next, settle_after, steps_min, dt, p1,
        p2, xipos, W, last_dv, dt, hit[:n], keep[:n], bodies, F, arm)
    if n_hit and not n_unheld:  # every force held: the hook's first application (MujocoAdapter._passive)
        MK.apply(qfrc, xipos, xanchor, xmat, bodies[:m], F[:m], arm[:m])
    return RESTING, n, 0, n_hit, n_unheld, m


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__, K, MK, _sweep)
