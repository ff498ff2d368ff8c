"""The MuJoCo adapter's resting step in one compiled call (issue 10).

When every contact of a step is resting, the adapter's per-step work is a
fixed chain of compiled passes (:mod:`engines.mujoco._kernels`,
:mod:`engines._kernel`) with Python between them: the free group's
kinematics, the manager's input check, its own gaps, the settled path, the
write-back, the held forces and their application to ``qfrc_passive``.
:func:`engines.mujoco._resting_kernel.resting_step` runs that chain in one
call, calling the same compiled functions in the same order on the same
arrays, so its results are those of the general path bit for bit
(tests/test_resting_fused.py), with no Python between the passes.

It is taken when the step is a resting step, which the kernel decides as it
goes, before it changes anything the general path would then compute again:

1. the adapter's conditions (:func:`eligible`): the compiled free group
   only (no pair read through Jacobians, no narrow phase), no islands
   (no body in two pairs), no link of a chain, every pair on MSF, no record
   waiting for its body probe, no island energy check open, the manager's
   settled path on and its ``step`` its own;
2. after the kinematics: every candidate row's pair took the settled path in
   the last step (so no moving contact point is integrated: the adapter's
   ``_lever`` is None), else ``NOT_RESTING``;
3. after the manager's input check (a failure: ``NOT_RESTING``, and the
   general path raises) and the settled path: every row took it, else the
   manager's own-gap state is restored and ``NOT_RESTING`` (the settled path
   writes only the rows' scratch and record bookkeeping, which the general
   path writes again with the same values).

On ``NOT_RESTING`` the adapter goes on with the general path from the
kinematics, which the kernel has taken (they update the a_ext state once).
"""

from __future__ import annotations

import numba
import numpy as np

from engines import _kernel as K
from engines._contacts.compiled import _KCST
from engines._contacts.islands import TOUCH_TOL
from engines._contacts.manager import ContactManager
from engines._contacts.state import SETTLE_AFTER_DURATIONS
from engines._geometry import COINCIDENT_RTOL
from engines.contract import STEPS_PER_CONTACT_MIN, ContactForces, ContactKinematics
from engines.mujoco._resting_kernel import BAD_DETECTION, RESTING, resting_step

#: the manager's own step (eligible: a manager whose step was replaced takes the general path)
_MANAGER_STEP = ContactManager.step


def eligible(ad) -> bool:
    """The adapter's conditions for a resting step (module docstring, 1): ad a compiled
    engines.mujoco.MujocoAdapter. Its own part (``_fused_static``: a free group and no pair
    read through Jacobians, so no box edge handed to MuJoCo either; no body in two pairs; no
    link of a chain) is fixed at its construction; ``_all_msf`` follows set_mode. A manager
    whose ``step`` is not ContactManager.step (wrapped to watch it, or a stand-in) takes the
    general path, which calls it."""
    mgr = ad.manager
    return (ad._fused_static and ad._all_msf and getattr(mgr.step, "__func__", None) is _MANAGER_STEP
            and mgr._coupling is None and mgr.settled_path and mgr._all_kernel and not mgr.history
            and not mgr._pending and not (mgr._balance is not None and mgr._balance._open))


def _args(ad, factor: float) -> list:
    """[MjData's qfrc_passive, resting_step's arguments after the per-call ones, its counters,
    what to call, the rows k of the free group, the last resting step's kinematics and after_step
    views (None until made; :func:`step`)]: the adapter's, the manager's and the MjData's arrays,
    which live as long as the adapter, built once (again when the manager's law tables are
    replaced: ContactManager.set_law); factor: the adapter's CANDIDATE_FACTOR. What to call:
    resting_step until its first call with these arguments, then its compiled function for their
    types (:func:`_compiled`)."""
    mgr = ad.manager
    a = ad._rest_args
    if a is not None and a[0] is mgr._kcodes and a[1] is mgr._kLC:
        return a[2]
    d = ad.data
    k, P = ad._gi.shape[0], len(ad._pairs)
    fk = ad._fk_buffers()
    ints = np.zeros(4, np.int64)
    args = (
        ad._gi, ad._gf, ad._group_of, ad._pp_idx, d.geom_xpos, d.geom_xmat, d.cvel, d.subtree_com, d.xipos, d.ximat,
        d.xanchor, d.xmat, ad._required, ad._last_v, ad._last_dv, ad._have_last, factor, COINCIDENT_RTOL,
        ad._push, ad._last_r, ad._last_gap, np.zeros(P, np.bool_), mgr.n_in, *fk, ad._x_last, ad._p1, ad._p2,
        mgr.active, mgr.settled, mgr.J, mgr._seen, mgr._point, np.empty((k, 3)), mgr.dv_corr, mgr.dvc_corr, mgr.x,
        mgr._listed, mgr.own_gap, mgr.xdot, mgr._xd0, mgr._an, mgr._off, np.empty(k), np.empty(k), np.empty(k),
        np.empty((3, k)), TOUCH_TOL, mgr.in_island, mgr._island_of,
        _KCST, mgr._kg_of_pair, mgr._paper, np.empty(k, np.int64), np.empty(k, np.bool_), mgr._L0, mgr._kcodes,
        mgr._kLC, mgr._oc, mgr.s, mgr.tau_est, mgr.W_el, mgr.W_visc, mgr.Q_t, mgr.W_t, np.empty((k, K.NY)),
        np.empty((k, 2, 3)), np.empty(k), np.empty(k, np.bool_), np.empty(k, np.bool_), np.empty(k, np.int8),
        mgr.turned, mgr._fl, ints, *mgr._scr_settled,
        mgr.vc, mgr.phase, mgr.outside, mgr.couple, np.empty((k, 3)),
        np.zeros(P, np.bool_), mgr.t_onset, SETTLE_AFTER_DURATIONS, STEPS_PER_CONTACT_MIN,
        np.empty(k, np.bool_), np.empty(k, np.bool_), np.empty((2 * k, 3), np.int64), np.empty((2 * k, 3)),
        np.empty((2 * k, 3)))
    ad._rest_args = (mgr._kcodes, mgr._kLC, [d.qfrc_passive, args, ints, resting_step, k, None, None])
    return ad._rest_args[2]


def _compiled(call_args: tuple):
    """resting_step's compiled function for the types of ``call_args`` (numba's
    Dispatcher.get_overload, after a call with them compiled it or loaded it from the cache):
    called directly it skips the dispatcher's per-call typing of ~120 arguments (~3 us in the
    hook, measured). The types cannot change between calls: the arrays are the ones _args keeps
    (dtype, dimensions and layout fixed for the adapter's life), the per-step ones are made with
    fixed dtypes, and the scalars are passed as Python float and bool (step)."""
    try:
        return resting_step.get_overload(tuple(numba.typeof(a) for a in call_args))
    except KeyError:  # not expected (numba typed the call otherwise): the dispatcher types every call
        return lambda *a: resting_step(*a)


def step(ad, factor: float) -> tuple[bool, bool, int]:
    """The adapter's ``_compute_compiled`` for a resting step (module docstring) in one
    :func:`resting_step` call, which also applies the step's forces for the hook call it is
    made from when every one is held. Returns (done, applied, n): done, the step computed as
    the general path computes it (applied: and its forces added to qfrc_passive); not done, the
    free group's n candidate rows are in the adapter's kinematics buffers and the general path
    goes on from there. factor: the adapter's CANDIDATE_FACTOR.

    Its Python runs once per engine step between MuJoCo's passes, with the interpreter's caches
    cold (in the 1,000-sphere benchmark a Python operation here costs ~2-3 times what it costs in
    a loop): the views and kinematics of the last resting step are kept (:func:`_args`' last two
    slots) and the common case is one test."""
    mgr = ad.manager
    a = ad._rest_args
    cached = a[2] if a is not None and a[0] is mgr._kcodes and a[1] is mgr._kLC else _args(ad, factor)
    qfrc, args, ints, call, k, kin, todo = cached
    # d.time, which the step tracker read in this hook call (only the hook calls this, after
    # StepTracker.classify; an MjData field read from Python costs ~1 us in the hook)
    t0 = ad._tracker.t0
    res = ad._native_result
    if res is None:
        # the step's ContactForces arrays, new every step (the manager's are; a caller may keep them)
        force, point, pair = np.empty((k, 3)), np.empty((k, 3)), np.empty(k, np.int64)
        code, n, bad, n_hit, n_unheld, m = call(t0, float(mgr.dt), float(mgr.settle_rate),
                                                bool(mgr.timing_correction), qfrc, force, point, pair, *args)
        if call is resting_step:
            cached[3] = _compiled((t0, float(mgr.dt), float(mgr.settle_rate), bool(mgr.timing_correction), qfrc,
                                   force, point, pair) + args)
    else:  # the native hook called resting_step for this step (engines.mujoco._native: the same arguments)
        ad._native_result = None
        code, n, bad, n_hit, n_unheld, m, force, point, pair = res
    if code != RESTING:
        if code == BAD_DETECTION:
            ad._detection_failed(bad)
        return False, False, n
    if n_hit and m and not n_unheld:  # the common case: every force held and applied
        finish(ad, cached, force, point, pair, n, m, t0)
        return True, True, n
    # what the general path leaves on the adapter and the manager, as finish
    if n != k or kin is None or kin is not ad._last_kin or todo[0].shape[0] != m:
        force, point, pair, kin, todo = _views(ad, cached, force, point, pair, n, m, t0)
    else:
        kin.t = t0
    _info(mgr, ints, n)
    ad._last_out = ad.last_forces = ContactForces(force, point, pair)
    ad._apply = []
    ad._apply_couple = None
    ad._apply_fast = todo if n_hit and m else None
    if not n:
        ad.last_forces = None
    if n_hit and n_unheld:  # not applied: the general path's bookkeeping, then the hook applies them
        fk = ad._fk_bufs
        ad._after_forces(kin, True, fk[9], fk[10], {}, [], None, pair, force, args[-5][:n], args[-4][:n], n_hit,
                         n_unheld, todo)
        return True, False, n
    return True, bool(n_hit), n


def finish(ad, cached: list, force, point, pair, n: int, m: int, t0: float) -> None:
    """What the general path leaves on the adapter and the manager (_compute_rest,
    ContactManager.step) after a resting step whose n rows' forces were all held and applied (m
    after_step rows): the step's ContactForces (force, point (k or n, 3) [N, m], pair), the
    kinematics and after_step views, last_step_info; t0: the step's start time [s]. No link pairs
    (eligible): _check_deep_onsets has nothing to do. The kinematics of the last resting step
    (views of the same buffers) are kept when n is the same and the general path has not made
    others since; after_step's outputs stay in the kernel's buffers (the last arguments), views kept
    while m is the same. Called by :func:`step` and, for a step the native hook did, by
    engines.mujoco._native.Native.sync."""
    kin, todo = cached[5], cached[6]
    if n != cached[4] or kin is None or kin is not ad._last_kin or todo[0].shape[0] != m:
        force, point, pair, kin, todo = _views(ad, cached, force, point, pair, n, m, t0)
    else:
        kin.t = t0
    _info(ad.manager, cached[2], n)
    ad._last_out = ad.last_forces = ContactForces(force, point, pair)
    ad._apply = []
    ad._apply_couple = None
    ad._apply_fast = todo
    ad._rested = True  # (engines.mujoco._native arms after such a step)


def _info(mgr, ints, n: int) -> None:
    """The manager's last_step_info of a resting step of n rows (the kernel's counters ints)."""
    c = ints.tolist()
    mgr.last_step_info = {"rows": n, "substeps": c[2], "segments": 1, "onsets": 0, "ends": c[3], "settled": c[0],
                          "settled_iterations": c[1], "island_rows": 0}


def _views(ad, cached: list, force, point, pair, n: int, m: int, t0: float) -> tuple:
    """:func:`step`'s (force, point, pair) cut to the n rows, and the kinematics and after_step
    views of this step, made (and kept in ``cached`` and on the adapter) when the kept ones do
    not fit."""
    if n != cached[4]:
        force, point, pair = force[:n], point[:n], pair[:n]
    kin = cached[5]
    if kin is None or kin is not ad._last_kin or kin.pair.shape[0] != n:
        fk = ad._fk_bufs
        kin = cached[5] = ContactKinematics(fk[0][:n], fk[1][:n], fk[2][:n], fk[3][:n], fk[4][:n], fk[5][:n],
                                            fk[6][:n], fk[7][:n], fk[8][:n], t0)
        ad._last_kin = kin
    else:
        kin.t = t0
    todo = cached[6]
    if todo is None or todo[0].shape[0] != m:
        args = cached[1]
        todo = cached[6] = (args[-3][:m], args[-2][:m], args[-1][:m])
    return force, point, pair, kin, todo
