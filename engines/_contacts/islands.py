"""Contacts solved together: islands of contacts that share a moving body
(issue 10, item 1).

The contact manager integrates each contact inside the engine step with its
own inverse inertia W_pp, the other contacts' forces entering only one step
later through a_ext. Two stiff contacts on one body within a step then
exchange their impulses a step late, and the pushes compound: a Newton's
cradle of steel balls gained 60,000 times its energy at dt = 1 ms. Here the
candidate rows of one step are grouped into islands (rows linked through a
body that moves), and an island with more than one row is integrated as one
system inside the step:

    x_p'  = -(v_p . n_p)
    v_p'  = sum_q W_pq f_q + a_p,     W_pq = J_p M^-1 J_q^T   (the adapter's blocks)
    v_c,p' = sum_q Wc_pq f_q + a_p,   Wc_pq = J_c,p M^-1 J_q^T

with f_q the law's force of row q while it is in contact (zero otherwise),
classical RK4 at the internal step of the stiffest contact in contact (the
smallest ``manager.h``), and the onsets, maximum compressions and ends of
every row located by root finding on a partial RK4 step of the whole island
(the island is advanced to the earliest event, the event is applied, and
the integration goes on). A row that is not in contact moves with the
island (its bodies are pushed by the others) until its own onset.

Which rows join: rows sharing a moving body are linked, and a connected
set of two or more rows is an island, whether its contacts are new,
closing or resting (issue 13). Resting contacts (older than
SETTLE_AFTER_DURATIONS estimated durations and slow) were left to the
settled path row by row when their whole set rested, each row stepped
alone with its neighbours' held forces in its a_ext a step late: on a
robot, whose joints pass load from one foot to another within a step,
that put energy in at rest (MuJoCo's ant in a user's loop,
scripts/rest_energy.py ant.xml --torque-steps 200 --rest-steps 600 --seed 3
--unit-controls: 58 rest steps above RestEnergy's bound, up to 1.3 mJ;
none solved in its island). A resting row in an island keeps its resting
relaxation (state.relax, energy-funded inside the island). An island of
free bodies whose contacts all rest is solved as one settled
(backward-Euler) step of all its rows (engines._contacts.resting: exact
static balance at any dt, a resting pile's cost), and by RK4 as here
where that solve fails. An adapter may
hold sets apart (ContactManager.set_together: pybullet's multibodies with
a joint at a limit, whose coupled solve would take the one-sided limit as
held): a set of resting contacts only with a row held apart takes the
settled path row by row. A row alone keeps the manager's own path
unchanged (bit-identical: tests/test_kernel.py, test_engine_core.py), so
does a sphere resting alone on a plane (the resting spheres' benchmark).

Articulated links: the adapters give a link's body key as its tree's root,
so contacts on links of one chain form one island, and W_pq comes from the
engine's Jacobians and mass matrix (MuJoCo). pybullet's blocks cover free
bodies; a multibody's links are coupled only through a_ext (stated in
docs/engines.md).
"""

from __future__ import annotations

import math

import numpy as np

from .reference import _Batch, _find_root
from .resting import store_end_state
from .state import (
    initial_state, lever_start,
    _G, _P, _PD, _PI, _Q, _S, _V, _VC, _WEL, _WT, _WVI, _X, F_RATIO_FLOOR, MAX_SEGMENTS, NY, SUBSTEPS_PER_CONTACT, _dot, _Rows,
    CENTRED_RTOL, L_ON, L_W01, L_W11, _cross, _tangent_basis,
)


#: Extra candidate reach [m] of a pair whose bodies touch others: a gap at
#: the float64 rounding of positions (1e-12 m; spheres placed 2R apart touch
#: to ~1e-18 m) counts as touching, so a touching neighbour is listed and
#: carries the push down a row of touching bodies.
TOUCH_TOL = 1e-12


def push_reach(keys, pair, x, v_rel, dt: float, factor: float, gaps=None, budgets: bool = False):
    """Extra candidate reach of every pair from its bodies' other contacts [m] (P,).

    A body in a candidate contact can be pushed within the next step at up to
    about that contact's relative speed (a struck ball leaves at up to twice
    the striker's speed for a light target: the factor), so it travels up to
    B = factor |v_rel| dt in the step, and a pair sharing that body closes its
    gap by up to B: the adapters list it as a candidate that far out, and it
    is solved in the island. The push travels on through the gaps it closes:
    a body pushed by B must first cross its gap g to a neighbour, which then
    travels at most B - g (the same bound on the speed, the time left), so
    B passes from body to body less each gap on the way (a path's budget,
    the largest over all paths: a shortest-path relaxation). A pair's reach
    is TOUCH_TOL plus the larger budget of its two bodies (the factor's
    margin covers two pushes meeting in one gap). keys (P, 2) body keys (-1 fixed); pair (k,), x (k,)
    [m], v_rel (k, 3) [m/s]: the last step's rows, their speeds the sources;
    gaps (P,) [m] or None: every pair's x in the last step (NaN where the
    adapter did not read it), the pairs the push may travel through. None:
    through the rows only (the push then stops at the first pair that was
    not a candidate: a Newton's cradle hanging with 0.1 mm gaps lists only
    the first two of its four pairs in the step of the strike, the third is
    found 0.4 mm deep a step later and the cradle gains 25,000 times its
    energy; issue 10). With ``budgets``: (reach, each body key's budget [m]
    (max key + 1,), 0 for a key the push does not reach)."""
    keys = np.asarray(keys)
    P = keys.shape[0]
    out = np.full(P, TOUCH_TOL)
    if pair.size == 0 or keys.size == 0 or int(keys.max()) < 0:
        return (out, np.zeros(0)) if budgets else out
    budget = np.zeros(int(keys.max()) + 1)
    u = np.linalg.norm(np.asarray(v_rel, dtype=float).reshape(-1, 3), axis=1)
    for side in (0, 1):
        kk = keys[pair, side]
        on = kk >= 0
        np.maximum.at(budget, kk[on], factor * dt * u[on])
    bmax = float(budget.max())
    q = np.asarray(pair)
    g = -np.asarray(x, dtype=float).reshape(-1)
    if gaps is not None:  # and the pairs a push can cross at all (a pile's far pairs, NaN: not read)
        far = np.flatnonzero(np.asarray(gaps) > -(bmax + TOUCH_TOL))
        q, g = np.concatenate([q, far]), np.concatenate([g, -np.asarray(gaps, dtype=float)[far]])
    g = np.maximum(g - TOUCH_TOL, 0.0)  # touching to the rounding of positions: no gap
    near = g < bmax
    q, g = q[near], g[near]
    if q.size:
        k1, k2 = keys[q, 0], keys[q, 1]
        both = (k1 >= 0) & (k2 >= 0)  # a push crosses to a moving body only
        k1, k2, g = k1[both], k2[both], g[both]
        for _ in range(k1.size):  # relax until no budget grows (at most one pass per pair on a path)
            before = budget.copy()
            np.maximum.at(budget, k2, budget[k1] - g)
            np.maximum.at(budget, k1, budget[k2] - g)
            if np.array_equal(before, budget):
                break
    # each side's budget + TOUCH_TOL; a fixed side (key -1) reads the appended 0: TOUCH_TOL, as out
    # (gathers over all P: boolean masks cost ~1 ms a step for the jet's 35,511 pairs)
    ext = np.append(budget, 0.0)
    for side in (0, 1):
        out = np.maximum(out, ext[keys[:, side]] + TOUCH_TOL)
    return (out, budget) if budgets else out


def island_lever(L, n, W):
    """The moving contact points (state.LEVER_DOC) the island rows take: L
    (k, NL) or None as the adapter gave it (row by row), n (k, 3), W (k, 3, 3);
    returns L with L_ON cleared for the off-centre rows (a copy; None stays).

    A row's lever terms carry the turn of its bodies under its own force
    only; the other rows' share (the cross terms J_p1 M^-1 J_q^T f_q) is left
    out. For a sphere the normal force passes through the centre and turns
    nothing (W01^T n = 0: only the tangential force turns it, the lever's own
    effect); a contact off its body's centre (a side's two ends, a box's
    corners) is turned by its normal force, which the island's other rows
    counter (a cylinder lying flat: the two ends' torques cancel), so such a
    row keeps its point frozen (measured: with it moving, pybullet's lying
    cylinder's COR 0.676119 against the line law's 0.676106, 2e-5; frozen
    1e-6). Off-centre: |W01^T n| > CENTRED_RTOL sqrt(|W11| n.W.n), the lever
    arm's share across n against the body's radius of gyration."""
    if L is None:
        return None
    k = L.shape[0]
    W01 = L[:, L_W01:L_W01 + 9].reshape(k, 3, 3)
    W11 = L[:, L_W11:L_W11 + 9].reshape(k, 3, 3)
    turn = np.linalg.norm(np.einsum("kji,kj->ki", W01, n), axis=1)
    scale = np.sqrt(np.linalg.norm(W11, axis=(1, 2)) * np.einsum("ki,kij,kj->k", n, W, n))
    L = L.copy()
    L[turn > CENTRED_RTOL * scale, L_ON] = 0.0
    return L


def islands(pair, active, age_ok, keys, together=None):
    """Islands of the step's rows: (k,) island label per row (rows of one
    island share a label; a row alone has a label of its own).

    An island is a connected set of rows linked through shared moving bodies
    (the module docstring: resting contacts too). pair: pair index per row
    (k,); active: in contact at the step start (k,); age_ok: past
    SETTLE_AFTER_DURATIONS durations (k,), with active the resting rows;
    keys: (k, 2) body keys of the rows' two bodies (-1: fixed; links of one
    tree share their root's key). together: (k,) bool or None (every row),
    the rows that may be solved together when all of their set rests
    (ContactManager.set_together): a set of resting contacts only that holds
    a row not together is left row by row (the settled path), a set with a
    new, closing or young contact is an island whatever the mask says."""
    k = pair.shape[0]
    parent = np.arange(k)

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    by_key: dict[int, list[int]] = {}
    for r in range(k):
        for b in keys[r]:
            if b >= 0:
                by_key.setdefault(int(b), []).append(r)
    for rows in by_key.values():
        a = find(rows[0])
        for r in rows[1:]:
            b = find(r)
            if b != a:
                parent[b] = a
    lab = np.array([find(r) for r in range(k)])
    if together is None:
        return lab
    # a set of resting contacts only, with a row held apart, keeps the settled path row by row
    dynamic = ~(active & age_ok)
    live = np.ones(k, bool)
    live[np.unique(lab[~np.asarray(together, bool)])] = False
    live[np.unique(lab[dynamic])] = True
    return np.where(live[lab], lab, np.arange(k) + k)


class _Island:
    """The rows of one island over one engine step: per-law batches (with
    the rows' moving contact points L (k, NL) or None, state.LEVER_DOC) and
    the coupling blocks."""

    def __init__(self, mgr, p, n, W, Wc, a, cp, cq, Wpq, Wcpq, L=None):
        self.mgr, self.p, self.n, self.W, self.a = mgr, p, n, W, a
        self.k = p.size
        self.cp, self.cq, self.Wpq, self.Wcpq = cp, cq, Wpq, Wcpq
        # rows whose point moves while they are not in contact (free flight's v += g d, d' = x' at x > 0)
        self.lev = None if L is None else L[:, L_ON] != 0.0
        t1, t2 = _tangent_basis(n)
        self.groups = []  # (law group id, law, row indices, _Batch)
        gid = mgr._group_of[p]
        for g in np.unique(gid):
            idx = np.flatnonzero(gid == g)
            b = _Batch(mgr._groups[g], n[idx], t1[idx], t2[idx], W[idx], Wc[idx], a[idx], mgr._paper[p[idx]],
                       L=None if L is None else L[idx])
            self.groups.append((g, mgr._groups[g], idx, b))
        self.refresh_onset()

    def refresh_onset(self):
        mgr = self.mgr
        for g, _law, idx, b in self.groups:
            store = mgr._onset[g]
            b.onset = {key: arr[mgr._pos[self.p[idx]]] for key, arr in store.items()}

    def rhs(self, y, in_c):
        """dy/dt (k, NY), F_n (k,), |F_t| (k,) of the island at y."""
        dy = np.zeros_like(y)
        Fn = np.zeros(self.k)
        Ft = np.zeros(self.k)
        for _g, _law, idx, b in self.groups:
            on = in_c[idx]
            if np.any(on):
                j = idx[on]
                bs = b if np.all(on) else b.sub(np.flatnonzero(on))
                d, fn, ft = bs.rhs(y[j])
                dy[j], Fn[j], Ft[j] = d, fn, ft
        off = ~in_c
        if np.any(off):  # free rows: x' = -(v . n), v' = a (plus the island's pushes below)
            dy[off, _X] = -_dot(y[off, _V], self.n[off])
            dy[off, _V] = self.a[off]
            dy[off, _VC] = self.a[off]
            dy[off, _PI] = y[off, _P]
        if self.cp.size:
            f = dy[:, _P]
            np.add.at(dy[:, _V], self.cp, np.einsum("bij,bj->bi", self.Wpq, f[self.cq]))
            np.add.at(dy[:, _VC], self.cp, np.einsum("bij,bj->bi", self.Wcpq, f[self.cq]))
        return dy, Fn, Ft

    def rk4(self, y, h, in_c):
        """One RK4 step of length h [s] of the island, the free rows' moving
        contact points as in free flight, then the Coulomb slip of
        the tangential springs of the rows in contact (_Batch.slip, as the
        rows' own path: without it the spring displacement s of a sliding
        row kept growing past mu F_n / k, so its force stayed on the cap
        after the slip reversed and k |s|^2 / 2 held slip as stored energy)."""
        k1, Fn, Ft = self.rhs(y, in_c)
        k2, _, _ = self.rhs(y + 0.5 * h * k1, in_c)
        k3, _, _ = self.rhs(y + 0.5 * h * k2, in_c)
        k4, _, _ = self.rhs(y + h * k3, in_c)
        y1 = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if self.lev is not None:  # a free row's point moves while it overlaps: v += g (max(x1, 0) - max(x0, 0)),
            mv = ~in_c & self.lev  # exactly as free flight (ContactManager._free_flight; LEVER_DOC)
            y1[mv, _V] += y[mv, _G] * (np.maximum(y1[mv, _X], 0.0) - np.maximum(y[mv, _X], 0.0))[:, None]
        for _g, _law, idx, b in self.groups:
            on = in_c[idx]
            if np.any(on):
                j = idx[on]
                bs = b if np.all(on) else b.sub(np.flatnonzero(on))
                y1[j] = bs.slip(y[j], y1[j], np.full(j.size, h))
        return y1, Fn, Ft

    def xdot(self, y):
        return -_dot(y[:, _V], self.n)

    def indicator(self, y):
        out = np.ones(self.k)
        for _g, law, idx, b in self.groups:
            if not b.onset:  # no row of this law has begun a contact yet
                continue
            x = np.maximum(y[idx, _X], 0.0)
            with np.errstate(invalid="ignore"):  # rows never in contact carry NaN constants
                out[idx] = law.separation_indicator(x, -_dot(y[idx, _V], self.n[idx]), b.onset)
        return out


def step_island(mgr, p, x_eng, n, v, vc, W, Wc, a, t0, info, cp, cq, Wpq, Wcpq, resting, L=None):
    """Integrate the rows of one island over the engine step; returns the
    impulses to apply (k, 3) [N s] (the manager divides by dt). Arguments as
    ContactManager._step_group for the island's rows (normals unit), plus the
    coupling blocks: rows cp (b,) receive W_pq (b, 3, 3) times the force of
    rows cq (b,), and Wc_pq (b, 3, 3) on their centre-of-mass velocity;
    resting (k,): the rows in a resting contact (ContactManager._resting),
    whose internal x relaxes toward the engine's (a contact being hit keeps
    its own x: the engine's leads it in an impact); L (k, NL) or None: the
    rows' moving contact points (state.LEVER_DOC), each row's own terms as a
    row alone (_Batch.rhs, free flight's v += g d); the lever's cross terms
    between rows (J_p1 M^-1 J_q^T f_q: the push of row q's force through row
    p's moved point, and q's moved point in W_pq) are left out."""
    dt = mgr.dt
    k = p.size
    act = mgr.active[p].copy()
    y = initial_state(mgr, p, x_eng, n, v, vc, resting, np.array([0, k]))
    lever_start(y, L)
    isl = _Island(mgr, p, n, W, Wc, a, cp, cq, Wpq, Wcpq, L)
    rows = _Rows(n, W, a, L)
    in_c = act.copy()
    t_loc = 0.0
    for _ in range(MAX_SEGMENTS):
        info["segments"] += 1
        rem = dt - t_loc
        if rem <= 0.0:
            break
        # contacts that begin now (x >= 0 with a closing speed: the manager's onset rule; also a
        # row touching at rest while the island pushes: it closes from the next instant on)
        xd = isl.xdot(y)
        touching = (y[:, _X] >= 0) & (xd >= 0)
        closing = ~in_c & touching & ((y[:, _X] > 0) | (xd > 0))
        # a row that begins now pushes too: a sphere touching the plate at rest (x = x' = 0) under a
        # sphere whose contact with it begins at the same instant (a column placed at touching) was
        # left to free flight, found 4.9 um deep a step later (g dt^2 / 2 at 1 ms), and the engine's
        # body rested that much below the static overlap
        now = closing | (~in_c & touching & bool(np.any(in_c) or np.any(closing)))
        if np.any(now):
            _begin_rows(mgr, p, np.flatnonzero(now), y, rows, t0 + t_loc)
            in_c[now] = True
            isl.refresh_onset()
            info["onsets"] += int(np.count_nonzero(now))
        if not np.any(in_c):
            # no force acts: every row moves freely, the first onset (if any) ends the segment
            fi = np.arange(k)
            tc = mgr._free_flight(y.copy(), fi, rows, np.full(k, rem))
            t_first = float(np.min(tc))
            if not math.isfinite(t_first):
                mgr._free_flight(y, fi, rows, np.full(k, rem))
                t_loc = dt
                break
            mgr._free_flight(y, fi, rows, np.full(k, t_first))
            t_loc += t_first
            new = np.flatnonzero(np.isfinite(tc) & (tc <= t_first))
            _begin_rows(mgr, p, new, y, rows, t0 + t_loc)
            in_c[new] = True
            isl.refresh_onset()
            info["onsets"] += int(new.size)
            continue
        h_isl = min(float(np.min(mgr.h[p[in_c]])), _stiff_step(isl, y, in_c))
        nsub = max(1, int(math.ceil(rem / h_isl - 1e-9)))
        h = rem / nsub
        stopped = False
        for _i in range(nsub):
            Y1, Fn0, Ft0 = isl.rk4(y, h, in_c)
            info["substeps"] += 1
            _peaks(mgr, p, in_c, y, Fn0, Ft0)
            xd0, xd1 = isl.xdot(y), isl.xdot(Y1)
            # first maximum compression of rows in contact (no change of the island's forces)
            turn = in_c & ~mgr.turned[p] & (xd0 > 0) & (xd1 <= 0)
            lo = np.zeros(k)
            for j in np.flatnonzero(turn):
                th = _root_row(lambda th, j=j: isl.xdot(isl.rk4(y, th * h, in_c)[0])[j], 0.0, 1.0, xd0[j], xd1[j])
                Yt = isl.rk4(y, th * h, in_c)[0]
                q = p[j]
                mgr.turned[q] = True
                mgr.tau1[q] = t0 + t_loc + th * h - mgr.t_onset[q]
                mgr.x_turn[q] = Yt[j, _X]
                mgr.x_max[q] = max(mgr.x_max[q], Yt[j, _X])
                mgr.W_el_comp[q] = Yt[j, _WEL]
                mgr.W_visc_comp[q] = Yt[j, _WVI]
                lo[j] = th
            mgr.x_max[p[in_c]] = np.maximum(mgr.x_max[p[in_c]], Y1[in_c, _X])
            # ends of rows in contact, onsets of rows not in contact
            g_end = _g_end(isl, mgr, Y1, p)
            ends = in_c & (xd1 < 0) & (g_end <= 0)
            g_on1 = np.minimum(Y1[:, _X], xd1)
            g_on0 = np.minimum(y[:, _X], xd0)
            ons = ~in_c & (g_on0 < 0) & (g_on1 >= 0)
            if not (np.any(ends) or np.any(ons)):
                y = Y1
                t_loc += h
                continue
            # the earliest event of the island
            cand = []
            for j in np.flatnonzero(ends):
                Ylo = isl.rk4(y, lo[j] * h, in_c)[0] if lo[j] > 0 else y
                scale = _g_scales(isl, mgr, Ylo, p, j)
                g_lo = max(_g_end_row(isl, mgr, Ylo, p, j, scale), 1e-300)
                g_hi = _g_end_row(isl, mgr, Y1, p, j, scale)
                th = _root_row(lambda th, j=j, sc=scale: _g_end_row(isl, mgr, isl.rk4(y, th * h, in_c)[0], p, j, sc),
                               lo[j], 1.0, g_lo, g_hi)
                cand.append((th, j, "end"))
            for j in np.flatnonzero(ons):
                th = _root_row(lambda th, j=j: -_g_on_row(isl, isl.rk4(y, th * h, in_c)[0], j), 0.0, 1.0,
                               -g_on0[j], -g_on1[j])
                cand.append((th, j, "onset"))
            th_star = min(c[0] for c in cand)
            Ye = isl.rk4(y, th_star * h, in_c)[0]
            t_ev = t_loc + th_star * h
            for th, j, kind in cand:
                if th > th_star + 1e-12:
                    continue
                if kind == "end":
                    by_force = mgr.pairs[p[j]].law.separation == "force-zero" and Ye[j, _X] > 0
                    mgr._end(int(p[j]), Ye[j], float(t0 + t_ev), "force-zero" if by_force else "overlap-zero", n[j])
                    in_c[j] = False
                    info["ends"] += 1
                else:
                    _begin_rows(mgr, p, np.array([j]), Ye, rows, t0 + t_ev)
                    in_c[j] = True
                    isl.refresh_onset()
                    info["onsets"] += 1
            y = Ye
            t_loc = t_ev
            stopped = True
            break
        if not stopped:
            t_loc = dt
    else:
        raise RuntimeError(f"more than {MAX_SEGMENTS} contact onsets/separations in one step of {dt!r} s")
    return write_back(mgr, p, n, W, Wc, y, in_c, t0, cp, cq, Wpq, Wcpq)


def write_back(mgr, p, n, W, Wc, y, in_c, t0, cp, cq, Wpq, Wcpq) -> np.ndarray:
    """Write the island rows' end state y (k, NY) back (as
    ContactManager._step_group) and return the step's impulses (k, 3) [N s]:
    P + J - J_previous with the timing correction J, whose velocity offset
    dv_corr holds the coupling terms W_pq J_q of the neighbours (cp, cq (b,)
    rows of p, Wpq, Wcpq (b, 3, 3)). Shared by step_island and the compiled path."""
    dt = mgr.dt
    k = p.size
    mgr.active[p] = in_c
    store_end_state(mgr, p, n, y)
    gid = mgr._group_of[p]
    for g in np.unique(gid):
        idx = np.flatnonzero(gid == g)
        mgr.outside[p[idx]] |= mgr._groups[g].outside(np.maximum(y[idx, _X], 0.0)) & in_c[idx]
    J = y[:, _PI] / dt - 0.5 * y[:, _P] if mgr.timing_correction else np.zeros((k, 3))
    mgr.settled[p] = False
    mgr.couple[p] = 0.5 * _cross(n, y[:, _PD])  # n x PD / 2 of the moving contact points (state.LEVER_DOC)
    if mgr.history:
        Pn = np.einsum("ki,ki->k", y[:, _P], n) / dt
        for r in np.flatnonzero(np.any(y[:, _P] != 0.0, axis=1)):
            mgr._hist.setdefault(int(p[r]), []).append((t0, float(Pn[r])))
    impulse = y[:, _P] + J - mgr.J[p]
    mgr.J[p] = J
    # the engine's velocity offset of every row from all the island's corrections
    dv = np.einsum("kij,kj->ki", W, J)
    dvc = np.einsum("kij,kj->ki", Wc, J)
    if cp.size:
        np.add.at(dv, cp, np.einsum("bij,bj->bi", Wpq, J[cq]))
        np.add.at(dvc, cp, np.einsum("bij,bj->bi", Wcpq, J[cq]))
    mgr.dv_corr[p] = dv
    mgr.dvc_corr[p] = dvc
    return impulse


def _stiff_step(isl, y, in_c) -> float:
    """Internal step [s] from the island's contacts as they are now: pi
    sqrt(m/k) / SUBSTEPS_PER_CONTACT with k = 1.5 F_el(x)/x (the local Hertz
    stiffness) and m = 1/(n W n). A contact that began slowly (a resting one,
    its onset duration from the floor speed) can be pressed hard by its
    island's impacts; its own h from onset would then be far too long."""
    h = math.inf
    for _g, law, idx, b in isl.groups:
        on = in_c[idx] & (y[idx, _X] > 0)
        if not np.any(on) or not b.onset:
            continue
        j = idx[on]
        x = y[j, _X]
        o = {key: val[on] for key, val in b.onset.items()}
        F = law.contact_normal_force(x, np.zeros(x.size), o)
        k = 1.5 * np.maximum(F, 0.0) / x
        nWn = np.einsum("ki,kij,kj->k", isl.n[j], isl.W[j], isl.n[j])
        with np.errstate(divide="ignore"):
            tau = np.where(k > 0, math.pi / np.sqrt(k * nWn), np.inf)
        h = min(h, float(np.min(tau)) / SUBSTEPS_PER_CONTACT)
    return h


def _begin_rows(mgr, p, new, y, rows, t_abs):
    """ContactManager._begin for island rows ``new``, law group by law group."""
    if new.size == 0:
        return
    grp = mgr._group_of[p[new]]
    for g in np.unique(grp):
        sel = new[grp == g]
        mgr._begin(g, mgr._groups[g], p, sel, y, rows, np.full(sel.size, t_abs))
        kl = mgr._kernel_law[g]
        if kl is not None:  # keep the compiled kernel's per-pair constants in step for later steps
            from .. import _kernel as K

            store, pp = mgr._onset[g], p[sel]
            for c, key in enumerate(K.ONSET_KEYS[kl[0]]):
                mgr._oc[pp, c] = store[key][mgr._pos[pp]]


def _peaks(mgr, p, in_c, y, Fn0, Ft0):
    """Peak force and friction ratio at the substep start (as _integrate)."""
    j = np.flatnonzero(in_c)
    if j.size == 0:
        return
    pp = p[j]
    Fn, Ft = Fn0[j], Ft0[j]
    better = Fn > mgr.F_max[pp]
    mgr.x_at_F[pp] = np.where(better, y[j, _X], mgr.x_at_F[pp])
    mgr.F_max[pp] = np.maximum(mgr.F_max[pp], Fn)
    ok = (Fn >= F_RATIO_FLOOR * mgr.F_max[pp]) & (Fn > 0)
    ratio = np.where(ok, Ft / np.where(ok, Fn, 1.0), 0.0)
    mgr.f_min[pp] = np.where(ok, np.minimum(mgr.f_min[pp], ratio), mgr.f_min[pp])
    mgr.f_max[pp] = np.where(ok, np.maximum(mgr.f_max[pp], ratio), mgr.f_max[pp])


def _g_end(isl, mgr, Y, p):
    """Per row: min(x, B) with B the separation indicator for force-zero laws (sign only)."""
    g = Y[:, _X].copy()
    B = isl.indicator(Y)
    for _g, law, idx, _b in isl.groups:
        if law.separation == "force-zero":
            g[idx] = np.minimum(g[idx], B[idx])
    return g


def _g_scales(isl, mgr, Y, p, j):
    x = Y[j, _X]
    B = abs(float(isl.indicator(Y)[j]))
    return (x if x > 0 else 1.0, B if B > 0 else 1.0)


def _g_end_row(isl, mgr, Y, p, j, scale):
    """The end event function of row j, scaled (the manager's gfun)."""
    gx = Y[j, _X] / scale[0]
    if mgr.pairs[p[j]].law.separation != "force-zero":
        return gx
    xd = -float(Y[j, _V] @ isl.n[j])
    gb = float(isl.indicator(Y)[j]) / scale[1] if xd < 0 else 1.0
    return min(gx, gb)


def _g_on_row(isl, Y, j):
    return min(Y[j, _X], -float(Y[j, _V] @ isl.n[j]))


def _root_row(g, lo, hi, g_lo, g_hi):
    """_find_root for one row: g(theta) scalar with g(lo) > 0 >= g(hi)."""
    th = _find_root(lambda t: np.array([g(float(t[0]))]), np.array([lo], float), np.array([hi], float),
                    np.array([g_lo], float), np.array([g_hi], float))
    return float(th[0])
