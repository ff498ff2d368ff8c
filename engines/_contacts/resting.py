"""Resting islands: the settled path of connected resting contacts, solved
together (issue 10, "rest at the static overlaps").

A connected set of contacts that all rest (each past SETTLE_AFTER_DURATIONS
estimated durations and approaching slower than SETTLED_SPEED_RATIO v_x,
ContactManager._resting) took the settled path row by row on main f9780ae:
each row one backward-Euler step of its own law with its own W_pp, the
other rows' forces held from the last step in its a_ext. That is a
block-Jacobi splitting of the coupled implicit step, one sweep per engine
step, and it does not converge where a light body sits between two
contacts of similar stiffness: its two rows exchange their forces a step
late with a coupling as strong as their own. Measured there
(tests/test_static_overlaps.py's columns, R = 10 mm, placed touching on a
steel plate, dt = 1 ms, both engines alike): a steel ball on a rubber
ball never came to rest (5-10 mm/s after 3 s, engine overlaps 10-60 um
off the internal ones, E rising up to 3.9e-6 J in a step, no island to
flag it). Since d7f6b81 (issue 13) such a set is an island integrated by
RK4 at its stiffest contact's internal step, which rests but sub-cycles
the whole island every step as an impact (docs/engines.md: the substeps
counted), and, like the row path, left a column placed touching 4.9 um
(g dt^2 / 2) deeper in the engine than its static overlap (a row touching
at rest not begun with its neighbour: islands.step_island).

Here such a component is one backward-Euler step of all its rows at once,
the settled path's equations (reference.NumpyPath._settled) with the
coupling blocks W_pq = J_p M^-1 J_q^T of the island (the adapters' blocks,
as the RK4 islands use):

    z_p = z_free,p + dt sum_q B_p W_pq B_q^T phi_q(z_q),
    z_p = (n.v+, t1.v+, t2.v+)_p,  z_free,p = B_p (v_p + dt a_p),
    phi_q = (F_n(x_q + dt x'_q+, x'_q+), F_t(s_q + dt T_q v_q+, T_q v_q+)),

a_p the outside acceleration with the island's own held forces taken out
(island_compiled.island_blocks). Newton as the row path (Jacobian
I + dt M D, D the law's derivatives, the Coulomb cap and k(x) left out),
one sparse solve of 3k unknowns per iteration. The engine's semi-implicit
Euler then reaches that end state, so the step is backward Euler of the
whole component: stable at any dt, no energy gain, and its fixed point is
the exact static balance of every contact, F_n(x_s, 0) = the force the
balance of the bodies requires (msf_contact.statics). A component whose
solve fails (a row hit: too fast at the start or in the solution, a row at
x <= 0, no convergence in SETTLED_NEWTON_MAX) is integrated by the RK4
island instead (islands.step_island or its compiled copy), as a row alone
goes back to sub-cycling. Rows in the paper's tangential mode are left to
the RK4 island (their spring follows the centres' velocity, W_com), and
so are islands with a link (the manager takes this path for the pairs
the adapters mark ``own_gap``: free spheres, free bodies on fixed ones;
a robot's resting feet stay in issue 13's RK4 island).

The gaps listed beside the resting contacts (islands.push_reach: pairs that
nearly touch, within the reach of their bodies' speeds over a step or
TOUCH_TOL) are rows of the island too, and an island with one took RK4 for
as long as it was listed (two steel spheres resting on a plate 1e-13 m
apart: ~960 RK4 substeps a 1 ms step in MuJoCo, for ever;
tests/test_settling.py).
They join the step with no force (phi = 0): their end velocities follow
from the others' forces through the coupling blocks, and the step holds
only if every gap stays open at its end, x + dt x'+ < 0 (the engine moves
the bodies by dt v_end, so a gap open at the end was open throughout); a
gap that would close is an impact, and the island goes to RK4, which finds
its onset (the struck resting ball, tests/test_settling.py). Their end gap
is kept as the manager's own (ContactManager._own_gaps).

Numpy only, for both paths of the manager (there is no compiled copy to
keep in step: ContactManager(compiled=False) and the compiled manager run
this same function).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .state import (
    F_RATIO_FLOOR, SETTLED_FD_REL, SETTLED_NEWTON_MAX, SETTLED_SPEED_RATIO, SETTLED_VTOL,
    _P, _PI, _Q, _S, _V, _VC, _WEL, _WT, _WVI, _X, _dot, _tangent_basis, initial_state, lever_start,
)


def _row_forces(groups, on, x_e, xd_e, s_e, zt, delta, dt):
    """The law's forces at the end state of the rows in contact on (m,) (indices into the island's k
    rows; groups: (law, rows of that law, onset constants)), group by group, in on's order: F_n (m,), F_n
    at x_e + dt delta with rate xd_e + delta (m,) (the forward difference of the Jacobian), F_t (m, 2),
    k_t, b_t (m, 2). x_e, xd_e, delta (k,), s_e, zt (k, 2)."""
    m = on.size
    at = np.full(x_e.size, -1)
    at[on] = np.arange(m)
    Fn, Fd = np.empty(m), np.empty(m)
    Ft, kt, bt = np.empty((m, 2)), np.empty((m, 2)), np.empty((m, 2))
    for law, idx, o in groups:
        j = at[idx]
        o2 = {q: np.concatenate([a_, a_]) for q, a_ in o.items()}
        xe, xd = x_e[idx], xd_e[idx]
        F2 = law.contact_normal_force(np.concatenate([xe, xe + dt * delta[idx]]),
                                      np.concatenate([xd, xd + delta[idx]]), o2)
        Fn[j], Fd[j] = F2[:idx.size], F2[idx.size:]
        kt[j], bt[j] = law.tangential_stiffness(xe, o)
        Ft[j], _ = law.tangential_force(xe, s_e[idx], zt[idx], o, Fn[j])
    return Fn, Fd, Ft, kt, bt


def _block_matrix(diag, cp, cq, off, k):
    """The (3k, 3k) sparse matrix with 3x3 blocks diag (k, 3, 3) on the diagonal and off (b, 3, 3) at
    block (cp, cq)."""
    bi = np.concatenate([np.arange(k), cp])
    bj = np.concatenate([np.arange(k), cq])
    blk = np.concatenate([diag, off], axis=0)
    ii = (3 * bi[:, None, None] + np.arange(3)[None, :, None]) + np.zeros((1, 1, 3), int)
    jj = (3 * bj[:, None, None] + np.arange(3)[None, None, :]) + np.zeros((1, 3, 1), int)
    return sp.csc_matrix((blk.ravel(), (ii.ravel(), jj.ravel())), shape=(3 * k, 3 * k))


def settle_island(mgr, p, x_eng, n, v, vc, W, Wc, a, t0, info, cp, cq, Wpq, Wcpq, L=None):
    """One coupled backward-Euler step of a resting island (module docstring).

    Arguments as islands.step_island for the island's rows p (k,): x_eng (k,)
    [m], n (k, 3) unit normals, v, vc (k, 3) [m/s], W, Wc (k, 3, 3) [1/kg],
    a (k, 3) [m/s^2] with the island's held forces taken out, coupling rows
    cp, cq (b,) and blocks Wpq, Wcpq (b, 3, 3), L (k, NL) or None (the moving
    contact point: its start only, lever_start; a resting contact's overlap
    changes by ~0 over a step, as on the row path). Rows not in contact (the
    gaps the island lists: a body's near neighbours) carry no force and move
    with the island; the step holds only if each stays open at the end
    (x + dt x'+ < 0: no onset inside the step; module docstring). Returns the
    impulses (k, 3) [N s] to apply with the rows' state written back, or None
    (nothing written) when the component is not settled: the caller
    integrates it as an RK4 island."""
    dt = mgr.dt
    k = p.size
    act = mgr.active[p].copy()
    if np.any(mgr._paper[p]) or not np.any(act):
        return None
    y = initial_state(mgr, p, x_eng, n, v, vc, np.ones(k, bool), np.array([0, k]))
    lever_start(y, L)
    x0 = y[:, _X].copy()
    if np.any(x0[act] <= 0.0):
        return None
    on = np.flatnonzero(act)
    gid = mgr._group_of[p[on]]
    groups = []  # (law, rows in contact (indices of p), onset constants)
    for g in np.unique(gid):
        idx = on[gid == g]
        groups.append((mgr._groups[g], idx, {key: arr[mgr._pos[p[idx]]] for key, arr in mgr._onset[g].items()}))
    F_el = np.zeros(k)
    for law, idx, o in groups:
        F_el[idx] = law.contact_normal_force(x0[idx], np.zeros(idx.size), o)
    nWn = np.einsum("ki,kij,kj->k", n, W, n)
    vx = np.sqrt(np.maximum(F_el, 0.0) * np.maximum(x0, 0.0) * nWn)
    vv, vcc = y[:, _V], y[:, _VC]
    if not np.all((np.abs(_dot(vv[act], n[act])) <= SETTLED_SPEED_RATIO * vx[act]) & (vx[act] > 0)):
        return None
    t1, t2 = _tangent_basis(n)
    T = np.stack([t1, t2], axis=1)  # (k, 2, 3)
    Bm = np.concatenate([n[:, None, :], T], axis=1)  # (k, 3, 3): rows n, t1, t2
    BmT = Bm.transpose(0, 2, 1)
    Md = Bm @ W @ BmT  # (k, 3, 3): B_p W_pp B_p^T
    Mo = Bm[cp] @ Wpq @ BmT[cq] if cp.size else np.zeros((0, 3, 3))
    z_free = np.einsum("kai,ki->ka", Bm, vv + dt * a)
    z = np.einsum("kai,ki->ka", Bm, vv)
    s2 = np.einsum("kai,ki->ka", T, y[:, _S])
    delta = SETTLED_FD_REL * x0 / dt
    tol = SETTLED_VTOL * vx
    conv = np.zeros(k, bool)

    def m_times(phi):
        out = np.einsum("kij,kj->ki", Md, phi)
        if cp.size:
            np.add.at(out, cp, np.einsum("bij,bj->bi", Mo, phi[cq]))
        return out

    # the force phi of the rows in contact, zero on the gap rows; Newton on the rows in contact only (a gap
    # row's z follows from the others' forces: z = z_free + dt M phi, linear, set after the loop)
    sub = on.size < k
    if sub:
        pos = np.full(k, -1)
        pos[on] = np.arange(on.size)
        ce = (pos[cp] >= 0) & (pos[cq] >= 0)
        cp_on, cq_on, Mo_on = pos[cp[ce]], pos[cq[ce]], Mo[ce]
    else:
        cp_on, cq_on, Mo_on = cp, cq, Mo
    phi = np.zeros((k, 3))
    Fn, Ft, kt, bt = np.zeros(k), np.zeros((k, 2)), np.zeros((k, 2)), np.zeros((k, 2))
    for it in range(SETTLED_NEWTON_MAX + 1):
        xd_e = -z[:, 0]
        x_e = x0 + dt * xd_e
        s_e = s2 + dt * z[:, 1:]
        Fn_o, Fd_o, Ft_o, kt_o, bt_o = _row_forces(groups, on, x_e, xd_e, s_e, z[:, 1:], delta, dt)
        Fn[on], Ft[on], kt[on], bt[on] = Fn_o, Ft_o, kt_o, bt_o
        phi[on] = np.concatenate([Fn_o[:, None], Ft_o], axis=1)
        R = (z - z_free - dt * m_times(phi))[on]
        conv = np.max(np.abs(R), axis=1) <= tol[on]
        info["settled_iterations"] += 1
        if np.all(conv) or it == SETTLED_NEWTON_MAX:
            break
        D = np.concatenate([np.maximum((Fd_o - Fn_o) / delta[on], 0.0)[:, None], bt_o + kt_o * dt], axis=1)
        Jm = sp.identity(3 * on.size, format="csc") + dt * _block_matrix(Md[on] * D[:, None, :], cp_on, cq_on,
                                                                          Mo_on * D[cq_on][:, None, :], on.size)
        z[on] = z[on] - spla.spsolve(Jm, R.ravel()).reshape(on.size, 3)
    gap = ~act
    if sub:  # the gap rows' end velocities from the converged forces (exact: linear in phi)
        z[gap] = (z_free + dt * m_times(phi))[gap]
        xd_e = -z[:, 0]
        x_e = x0 + dt * xd_e
    ok = conv & (x_e[on] > 0) & (Fn[on] > 0) & (np.abs(xd_e[on]) <= SETTLED_SPEED_RATIO * vx[on])
    if not np.all(ok) or np.any(x_e[gap] >= 0.0):
        return None
    # the step's result: the law's forces at the end state, held over the step (as NumpyPath._settled)
    f = Fn[:, None] * n + np.einsum("ka,kai->ki", Ft, T)
    Wf = np.einsum("kij,kj->ki", W, f)
    Wcf = np.einsum("kij,kj->ki", Wc, f)
    if cp.size:
        np.add.at(Wf, cp, np.einsum("bij,bj->bi", Wpq, f[cq]))
        np.add.at(Wcf, cp, np.einsum("bij,bj->bi", Wcpq, f[cq]))
    v1 = vv + dt * (Wf + a)
    Fc = np.zeros(k)
    for law, idx, o in groups:
        Fc[idx] = law.normal_force(x_e[idx], np.zeros(idx.size), o)
    dx = np.where(act, x_e - x0, 0.0)
    y[:, _X] = x_e
    y[:, _V] = v1
    y[:, _VC] = vcc + dt * (Wcf + a)
    y[on, _S] = np.einsum("ka,kai->ki", s_e[on], T[on])
    y[:, _P] = f * dt
    y[:, _PI] = 0.5 * dt * dt * f
    y[:, _WEL] += Fc * dx
    y[:, _WVI] += (Fn - Fc) * dx
    y[:, _Q] += np.einsum("ka,ka->k", bt * z[:, 1:], z[:, 1:]) * dt * act
    y[:, _WT] -= _dot(f - Fn[:, None] * n, v1 - _dot(v1, n)[:, None] * n) * dt
    book_records(mgr, p[on], x_e[on], xd_e[on], Fn[on], Ft[on], y[on], t0)
    info["settled"] += on.size
    return _write_back(mgr, p, n, y, groups, t0, act)


def book_records(mgr, p, x_e, xd_e, Fn, Ft, y, t0):
    """The record bookkeeping of rows p (k,) of manager mgr after a settled step, as one substep at the
    end state: the turning point (tau1, x_turn, the compression's work), F_max and its x, x_max and the
    range of |F_t|/F_n. x_e, xd_e, Fn (k,) [m, m/s, N], Ft (k, 2) [N], y (k, NY) the rows' end state,
    t0 the step's start [s]. Shared by NumpyPath._settled and the resting island step."""
    dt = mgr.dt
    turn = ~mgr.turned[p] & (xd_e <= 0)
    if np.any(turn):
        q = p[turn]
        mgr.turned[q] = True
        mgr.tau1[q] = t0 + dt - mgr.t_onset[q]
        mgr.x_turn[q] = x_e[turn]
        mgr.W_el_comp[q] = y[turn, _WEL]
        mgr.W_visc_comp[q] = y[turn, _WVI]
    better = Fn > mgr.F_max[p]
    mgr.x_at_F[p] = np.where(better, x_e, mgr.x_at_F[p])
    mgr.F_max[p] = np.maximum(mgr.F_max[p], Fn)
    mgr.x_max[p] = np.maximum(mgr.x_max[p], x_e)
    okr = Fn >= F_RATIO_FLOOR * mgr.F_max[p]
    ratio = np.where(okr, np.hypot(Ft[:, 0], Ft[:, 1]) / Fn, 0.0)
    mgr.f_min[p] = np.where(okr, np.minimum(mgr.f_min[p], ratio), mgr.f_min[p])
    mgr.f_max[p] = np.where(okr, np.maximum(mgr.f_max[p], ratio), mgr.f_max[p])


def store_end_state(mgr, p, n, y):
    """Rows p (k,)'s end state y (k, NY) into the manager's per-pair arrays: the approach x [m], its
    rate along the normal n (k, 3) [m/s], the tangential spring s and the contact point's velocity vc,
    the works W_el, W_visc, Q_t, W_t [J] and the phase (1 while approaching). Shared by the resting
    island step and islands.write_back."""
    mgr.x[p] = y[:, _X]
    mgr.xdot[p] = -_dot(y[:, _V], n)
    mgr.s[p] = y[:, _S]
    mgr.vc[p] = y[:, _VC]
    mgr.W_el[p], mgr.W_visc[p], mgr.Q_t[p], mgr.W_t[p] = y[:, _WEL], y[:, _WVI], y[:, _Q], y[:, _WT]
    mgr.phase[p] = np.where(mgr.xdot[p] < 0, 1, 0)


def _write_back(mgr, p, n, y, groups, t0, act):
    """The rows' end state into the manager (as NumpyPath._step_group for settled rows: no timing
    correction, the force is held over the whole step); act (k,): the rows in contact (the others stay
    open gaps, their end gap kept as the manager's own, _own_gaps); returns the impulses P - J_previous
    (k, 3)."""
    dt = mgr.dt
    mgr.active[p] = act
    store_end_state(mgr, p, n, y)
    for law, idx, _o in groups:
        mgr.outside[p[idx]] |= law.outside(np.maximum(y[idx, _X], 0.0))
    mgr.settled[p] = act
    mgr.couple[p] = 0.0
    if mgr.history:
        Pn = _dot(y[:, _P], n) / dt
        for r in np.flatnonzero(act):
            mgr._hist.setdefault(int(p[r]), []).append((t0, float(Pn[r])))
    impulse = y[:, _P] - mgr.J[p]
    mgr.J[p] = 0.0
    mgr.dv_corr[p] = 0.0
    mgr.dvc_corr[p] = 0.0
    return impulse
