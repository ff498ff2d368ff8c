"""Compiled (numba) twin of :func:`engines._contacts.islands.step_island`:
the islands of one engine step integrated in one call.

The numpy :func:`~engines._contacts.islands.step_island` is the readable
reference (read it first); this kernel repeats its algorithm island by
island with scalar arithmetic, reusing the per-row right-hand side of
:mod:`engines._kernel` (``rhs``, ``forces``, ``indicator``, ``free_flight``)
and adding the coupling of the island's rows (the adapter's blocks):

    dy[cp, V]  += W_pq  f[cq]     (W_pq  = J_p M^-1 J_q^T)
    dy[cp, VC] += Wc_pq f[cq]     (Wc_pq = J_c,p M^-1 J_q^T)

Per island, segment by segment as step_island: the rows that begin now
(touching with a closing speed, or touching at rest while the island has a
contact), free flight of the whole island to its first onset when no row is
in contact, otherwise classical RK4 of the whole island at the internal step
of its stiffest contact (``min(h_p, _stiff_step)``), with the first maximum
compressions located inside a substep and the earliest end or onset of the
island found by Illinois root finding on a partial RK4 step of the whole
island, each RK4 step followed by the Coulomb slip of the rows in contact
(engines._kernel.slip, as step_island's _Island.rk4).

Two shortcuts that change no bit of the result (the 200-sphere pile,
scripts/pile.py, is one island of ~560 rows a step): the coupling sums run
over the entries whose row q is in contact only (a free row's force is
zero), and a root's trial steps move only the rows the root's row reads
through the RK4 stages (:func:`_rk4_cone`, three levels of neighbours):
each trial step of the whole island cost as much as a substep, and a step
of the pile had as many of them as substeps.

The islands are stored CSR-style: the rows of island i are io[i]..io[i+1]-1
of the (k, ...) row arrays, its coupling entries cio[i]..cio[i+1]-1 of cp,
cq (global row indices), W_pq, Wc_pq (b, 3, 3). :func:`advance_islands`
moves every island until it is over or stops at an onset (``law.onset`` is
Python: the caller begins the rows with status ST_ONSET and calls again) or
an end (the caller writes the records of the rows with ST_ENDED, by
ended_by, and calls again); the island's state is then the one at that
instant, its time t_loc[i]. The caller (engines._contacts.island_compiled)
sets up y and writes the state back as step_island does.

The moving contact point (the lever, state.LEVER_DOC): each row's own
terms as a row alone (engines._kernel.rhs and free_flight with the row's
Lr[r] (NL,); a free row's point moves while it overlaps, v += g (max(x1, 0)
- max(x0, 0)) after each RK4 step, as in free flight), the
cross terms between rows left out, as step_island. Allocates nothing
(scratch from the caller), as engines._kernel.
"""

from __future__ import annotations

import math

from . import _kernel as K
from ._kernel import G, L_ON, LC_FZ, NY, PI, VC, WEL, WVI, X, V, P, ST_DONE, ST_ENDED, ST_ONSET, END_FORCE, END_OVERLAP
from ._kernel import jit, jit_inline
from msf_contact._jitcache import guard as _guard

# island status (ist)
IS_RUN, IS_DONE, IS_STOP, IS_OVER = 0, 1, 2, 3
# columns of the row scratch sc (k, NSC)
SC_LO, SC_XD0, SC_XD1, SC_G0, SC_G1, SC_TH, SC_EV = range(7)
NSC = 7
EV_NONE, EV_END, EV_ON = 0, 1, 2
# columns of the row index scratch ri (k, NRI): row r's coupling entries with a force are eb[ri[r, RI_S]]..
# eb[ri[r, RI_E] - 1] (_island); a mark and a list of rows for _cone
RI_S, RI_E, RI_MARK, RI_LIST = range(4)
NRI = 4


@jit_inline
def _own(r, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, in_c, y, dy, F, buf, want):
    """Row r's own terms of dy/dt (_rhs): in contact by engines._kernel.rhs, else moving freely."""
    if in_c[r]:
        kr = kg[r]
        Fn, Ft = K.rhs(codes[kr], LC[kr], oc, pairs[r], n[r], T[r], W[r], Wc[r], a[r], paper[r], Lr[r], y[r],
                       dy[r], buf, want)
    else:
        for j in range(NY):
            dy[r, j] = 0.0
        dy[r, X] = -(y[r, V] * n[r, 0] + y[r, V + 1] * n[r, 1] + y[r, V + 2] * n[r, 2])
        for i in range(3):
            dy[r, V + i] = a[r, i]
            dy[r, VC + i] = a[r, i]
            dy[r, PI + i] = y[r, P + i]
        Fn = Ft = 0.0
    if want:
        F[r, 0] = Fn
        F[r, 1] = Ft


@jit_inline
def _couple(b, cp, cq, Wpq, Wcpq, dy):
    """Entry b's coupling term (_rhs): row cp[b] pushed by the force of row cq[b]."""
    pr, qr = cp[b], cq[b]
    f0, f1, f2 = dy[qr, P], dy[qr, P + 1], dy[qr, P + 2]
    for i in range(3):
        dy[pr, V + i] += Wpq[b, i, 0] * f0 + Wpq[b, i, 1] * f1 + Wpq[b, i, 2] * f2
        dy[pr, VC + i] += Wcpq[b, i, 0] * f0 + Wcpq[b, i, 1] * f1 + Wcpq[b, i, 2] * f2


@jit
def _rhs(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y, dy, F,
         buf, want):
    """dy/dt of the island's rows r0..r1-1 (step_island's _Island.rhs):
    rows in contact by engines._kernel.rhs, the others moving freely
    (x' = -(v . n), v' = v_c' = a), then the coupling terms of entries
    eb[cb0..cb1-1]. With want, F[r] = (F_n, |F_t|) at y."""
    for r in range(r0, r1):
        _own(r, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, in_c, y, dy, F, buf, want)
    for e in range(cb0, cb1):  # the entries whose row q is in contact (eb, _island): a free row has no force
        _couple(eb[e], cp, cq, Wpq, Wcpq, dy)


@jit_inline
def _finish(r, pairs, n, T, Lr, kg, codes, LC, oc, paper, in_c, y, out, h, buf):
    """Row r after its RK4 step y -> out (step_island's _Island.rk4): a free
    row's moving point, as free flight; the Coulomb slip of a row in contact."""
    if not in_c[r] and Lr[r, L_ON] != 0.0:
        dm = max(out[r, X], 0.0) - max(y[r, X], 0.0)
        for i in range(3):
            out[r, V + i] += y[r, G + i] * dm
    if in_c[r]:
        kr = kg[r]
        K.slip(codes[kr], LC[kr], oc, pairs[r], n[r], T[r], paper[r], y[r], out[r], h, buf)


@jit
def _rk4(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y, h, out,
         work, F, buf, k1_ready):
    """One classical RK4 step of the island of length h from y into out (rows
    r0..r1-1); F[r] = (F_n, |F_t|) at y unless k1_ready (work[0] then holds
    the slope at y from an earlier call from the same y). work (5, k, NY)."""
    k1, k2, k3, k4, yt = work[0], work[1], work[2], work[3], work[4]
    if not k1_ready:
        _rhs(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y,
             k1, F, buf, True)
    for r in range(r0, r1):
        for j in range(NY):
            yt[r, j] = y[r, j] + 0.5 * h * k1[r, j]
    _rhs(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, yt, k2, F,
         buf, False)
    for r in range(r0, r1):
        for j in range(NY):
            yt[r, j] = y[r, j] + 0.5 * h * k2[r, j]
    _rhs(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, yt, k3, F,
         buf, False)
    for r in range(r0, r1):
        for j in range(NY):
            yt[r, j] = y[r, j] + h * k3[r, j]
    _rhs(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, yt, k4, F,
         buf, False)
    for r in range(r0, r1):
        for j in range(NY):
            out[r, j] = y[r, j] + h / 6.0 * (k1[r, j] + 2.0 * k2[r, j] + 2.0 * k3[r, j] + k4[r, j])
    for r in range(r0, r1):
        _finish(r, pairs, n, T, Lr, kg, codes, LC, oc, paper, in_c, y, out, h, buf)


@jit
def _cone(r, ri, eb, cq):
    """The rows a partial RK4 step of row r reads (_rk4_cone), breadth first
    through the coupling entries with a force (row p reads the rows
    cq[eb[e]], e in ri[p, RI_S]..ri[p, RI_E]-1): r, then the rows it reads,
    theirs, and theirs, into ri[:, RI_LIST]. Returns n1, n2, n3: the ends
    of the first two, three and four levels in that list (r alone: 1)."""
    ri[0, RI_LIST] = r
    ri[r, RI_MARK] = 1
    m, lo = 1, 0
    n1 = n2 = 1
    for level in range(3):
        hi = m
        for j in range(lo, hi):
            p = ri[j, RI_LIST]
            for e in range(ri[p, RI_S], ri[p, RI_E]):
                q = cq[eb[e]]
                if ri[q, RI_MARK] == 0:
                    ri[q, RI_MARK] = 1
                    ri[m, RI_LIST] = q
                    m += 1
        lo = hi
        if level == 0:
            n1 = m
        elif level == 1:
            n2 = m
    for j in range(m):
        ri[ri[j, RI_LIST], RI_MARK] = 0
    return n1, n2, m


@jit
def _rhs_cone(ri, nown, ncoup, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y,
              dy, F, buf):
    """_rhs on the first rows of a cone's list (ri[:, RI_LIST], _cone): their
    own terms for the first nown, the coupling terms of the first ncoup (each
    row's entries in _rhs's order: the same sums, to the bit)."""
    for j in range(nown):
        _own(ri[j, RI_LIST], pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, in_c, y, dy, F, buf, False)
    for j in range(ncoup):
        pr = ri[j, RI_LIST]
        for e in range(ri[pr, RI_S], ri[pr, RI_E]):
            _couple(eb[e], cp, cq, Wpq, Wcpq, dy)


@jit
def _rk4_cone(r, ri, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y, h, out,
              work, F, buf):
    """out[r] of _rk4(..., k1_ready=True) for the one row r, to the bit, from
    the rows it reads only (_cone): the slope k_s of a row reads the forces
    of the rows it couples to at stage s - 1, so k4[r] needs k3 on r and its
    neighbours (level <= 1), k3 there needs k2 on level <= 2, and k2 there
    needs the own forces at stage 1 on level <= 3 (k1 in work[0] holds for
    every row). The island's root finding (_root) reads row r only: a
    partial step of the whole island cost it as much as a substep."""
    n1, n2, n3 = _cone(r, ri, eb, cq)
    k1, k2, k3, k4, yt = work[0], work[1], work[2], work[3], work[4]
    for j in range(n3):
        q = ri[j, RI_LIST]
        for i in range(NY):
            yt[q, i] = y[q, i] + 0.5 * h * k1[q, i]
    _rhs_cone(ri, n3, n2, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, yt, k2,
              F, buf)
    for j in range(n2):
        q = ri[j, RI_LIST]
        for i in range(NY):
            yt[q, i] = y[q, i] + 0.5 * h * k2[q, i]
    _rhs_cone(ri, n2, n1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, yt, k3,
              F, buf)
    for j in range(n1):
        q = ri[j, RI_LIST]
        for i in range(NY):
            yt[q, i] = y[q, i] + h * k3[q, i]
    _rhs_cone(ri, n1, 1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, yt, k4,
              F, buf)
    for i in range(NY):
        out[r, i] = y[r, i] + h / 6.0 * (k1[r, i] + 2.0 * k2[r, i] + 2.0 * k3[r, i] + k4[r, i])
    _finish(r, pairs, n, T, Lr, kg, codes, LC, oc, paper, in_c, y, out, h, buf)


@jit
def _xd(Y, r, n):
    return -(Y[r, V] * n[r, 0] + Y[r, V + 1] * n[r, 1] + Y[r, V + 2] * n[r, 2])


@jit
def _g_end(code, lc, oc, p, Y, r, n, xs, Bs):
    """step_island's _g_end_row: x/x_s, and for force-zero laws min(x/x_s, B/B_s) while separating."""
    gx = Y[r, X] / xs
    if lc[LC_FZ] == 0.0:
        return gx
    xd = _xd(Y, r, n)
    gb = K.indicator(code, lc, oc, p, max(Y[r, X], 0.0), xd) / Bs if xd < 0 else 1.0
    return min(gx, gb)


@jit
def _root(kind, r, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, ri, in_c, y, h, lo, hi,
          g_lo, g_hi, xs, Bs, tmp, work, F, buf, root_iter, root_tol):
    """Illinois regula falsi for th in [lo, hi], g(lo) > 0 >= g(hi), g of row r at
    the island state rk4(y, th h) (engines._contacts.reference._find_root for
    one row): kind 0 x' (maximum compression), 1 the end function _g_end,
    2 -min(x, x') (an onset). y is the substep's start, its slope in work[0];
    the trial steps move only what row r reads (_rk4_cone): the same g."""
    side = 0
    if hi - lo <= root_tol or g_hi == 0:
        return hi
    code, lc, p = codes[kg[r]], LC[kg[r]], pairs[r]
    for _ in range(root_iter):
        th, at_hi = K.illinois_next(lo, hi, g_lo, g_hi)
        if at_hi:
            return hi
        _rk4_cone(r, ri, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y, th * h,
                  tmp, work, F, buf)
        if kind == 0:
            gt = _xd(tmp, r, n)
        elif kind == 1:
            gt = _g_end(code, lc, oc, p, tmp, r, n, xs, Bs)
        else:
            gt = -min(tmp[r, X], _xd(tmp, r, n))
        lo, hi, g_lo, g_hi, side = K.illinois_update(th, gt, lo, hi, g_lo, g_hi, side)
        if hi - lo <= root_tol or g_hi == 0:
            break
    return hi


@jit
def _stiff_step(r0, r1, pairs, n, W, kg, codes, LC, oc, in_c, y, buf, substeps):
    """step_island's _stiff_step: pi sqrt(m/k) / substeps over the rows in
    contact with x > 0, k = 1.5 F_el(x)/x, m = 1/(n W n) [s]."""
    hs = math.inf
    for r in range(r0, r1):
        if not in_c[r] or not y[r, X] > 0:
            continue
        x = y[r, X]
        K.forces(codes[kg[r]], LC[kg[r]], oc, pairs[r], x, 0.0, buf)
        kk = 1.5 * max(buf[0], 0.0) / x
        nWn = 0.0
        for i in range(3):
            for j in range(3):
                nWn += n[r, i] * W[r, i, j] * n[r, j]
        tau = math.pi / math.sqrt(kk * nWn) if kk > 0 else math.inf
        hs = min(hs, tau / substeps)
    return hs


@jit
def _island(i, cst, substeps, max_segments, io, cio, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq,
            Wcpq, eb, ri, t0, dt, hp, y, in_c, t_loc, phase, nseg, status, ended_by, turned, fl, ints, buf, work, Y1,
            Yt, tmp, F, sc):
    """Move island i on from t_loc[i] (module docstring); returns IS_DONE,
    IS_STOP (rows with status ST_ONSET/ST_ENDED for the caller) or IS_OVER
    (more than max_segments segments)."""
    r0, r1 = io[i], io[i + 1]
    cb0, cb1 = cio[i], cio[i + 1]
    # the coupling entries whose row q carries a force (in contact: in_c holds through the call), in their
    # order, into eb[cb0:cb1]: a free row's dy[q, P] is zero, so its entries add exactly nothing (and
    # skipping them in the loop by a branch cost as much as their arithmetic, the rows' in_c being random)
    ne = cb0
    for b in range(cb0, cb1):
        if in_c[cq[b]]:
            eb[ne] = b
            ne += 1
    cb1 = ne
    for r in range(r0, r1):  # each row's entries, contiguous (sorted by cp: coupled_rows), for _cone
        ri[r, RI_S] = ri[r, RI_E] = 0
    for e in range(cb0, cb1):
        r = cp[eb[e]]
        if ri[r, RI_E] == 0:
            ri[r, RI_S] = e
        ri[r, RI_E] = e + 1
    riter, rtol = int(cst[K.C_RITER]), cst[K.C_RTOL]
    for r in range(r0, r1):
        status[r] = ST_DONE
    while True:
        if phase[i] == 0:  # a new segment
            nseg[i] += 1
            if nseg[i] > max_segments:
                return IS_OVER
            if dt - t_loc[i] <= 0.0:
                return IS_DONE
            # contacts that begin now (x >= 0 with a closing speed; touching at rest while the island pushes)
            # (a row that begins now pushes too: a sphere touching the plate at rest under another
            # beginning its contact with it at the same instant, islands.step_island)
            any_in = False
            for r in range(r0, r1):
                any_in = any_in or in_c[r]
                if not in_c[r]:
                    xr, xd = y[r, X], _xd(y, r, n)
                    any_in = any_in or (xr >= 0 and xd >= 0 and (xr > 0 or xd > 0))
            nnow = 0
            for r in range(r0, r1):
                if in_c[r]:
                    continue
                xr, xd = y[r, X], _xd(y, r, n)
                if xr >= 0 and xd >= 0 and (xr > 0 or xd > 0 or any_in):
                    status[r] = ST_ONSET
                    nnow += 1
            if nnow:
                phase[i] = 1  # the caller begins them; this segment then goes on
                return IS_STOP
        phase[i] = 0
        rem = dt - t_loc[i]
        any_in = False
        for r in range(r0, r1):
            any_in = any_in or in_c[r]
        if not any_in:
            # no force acts: every row moves freely, the first onset (if any) ends the segment
            t_first = math.inf
            for r in range(r0, r1):
                for j in range(NY):
                    tmp[r, j] = y[r, j]
                tc = K.free_flight(n[r], a[r], Lr[r], tmp[r], rem)
                sc[r, SC_LO] = tc
                if tc < t_first:
                    t_first = tc
            if not math.isfinite(t_first):
                for r in range(r0, r1):
                    K.free_flight(n[r], a[r], Lr[r], y[r], rem)
                t_loc[i] = dt
                return IS_DONE
            for r in range(r0, r1):
                K.free_flight(n[r], a[r], Lr[r], y[r], t_first)
            t_loc[i] += t_first
            for r in range(r0, r1):
                if sc[r, SC_LO] <= t_first:
                    status[r] = ST_ONSET
            return IS_STOP
        h_isl = math.inf
        for r in range(r0, r1):
            if in_c[r]:
                h_isl = min(h_isl, hp[pairs[r]])
        h_isl = min(h_isl, _stiff_step(r0, r1, pairs, n, W, kg, codes, LC, oc, in_c, y, buf, substeps))
        nsub = max(1, int(math.ceil(rem / h_isl - 1e-9)))
        h = rem / nsub
        for _s in range(nsub):
            _rk4(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y,
                 h, Y1, work, F, buf, False)
            ints[2] += 1
            for r in range(r0, r1):
                sc[r, SC_LO] = 0.0
                sc[r, SC_XD0] = _xd(y, r, n)
                sc[r, SC_XD1] = _xd(Y1, r, n)
                if not in_c[r]:
                    continue
                # peak force and friction ratio at the substep start (step_island's _peaks)
                p = pairs[r]
                Fn, Ft = F[r, 0], F[r, 1]
                if Fn > fl[K.F_FMAX, p]:
                    fl[K.F_XATF, p] = y[r, X]
                fl[K.F_FMAX, p] = max(fl[K.F_FMAX, p], Fn)
                if Fn >= cst[K.C_FRATIO] * fl[K.F_FMAX, p] and Fn > 0:
                    ratio = Ft / Fn
                    fl[K.F_FMIN, p] = min(fl[K.F_FMIN, p], ratio)
                    fl[K.F_FMAXR, p] = max(fl[K.F_FMAXR, p], ratio)
            # first maximum compression of rows in contact (no change of the island's forces)
            for r in range(r0, r1):
                p = pairs[r]
                xd0, xd1 = sc[r, SC_XD0], sc[r, SC_XD1]
                if in_c[r] and not turned[p] and xd0 > 0 and xd1 <= 0:
                    th = _root(0, r, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, ri,
                               in_c, y, h, 0.0, 1.0, xd0, xd1, 1.0, 1.0, tmp, work, F, buf, riter, rtol)
                    _rk4_cone(r, ri, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c,
                              y, th * h, Yt, work, F, buf)  # Yt[r] only is read
                    turned[p] = True
                    fl[K.F_TAU1, p] = t0 + t_loc[i] + th * h - fl[K.F_TONSET, p]
                    fl[K.F_XTURN, p] = Yt[r, X]
                    fl[K.F_XMAX, p] = max(fl[K.F_XMAX, p], Yt[r, X])
                    fl[K.F_WELC, p] = Yt[r, WEL]
                    fl[K.F_WVIC, p] = Yt[r, WVI]
                    sc[r, SC_LO] = th
            # ends of rows in contact, onsets of rows not in contact
            nev = 0
            for r in range(r0, r1):
                sc[r, SC_EV] = EV_NONE
                xd0, xd1 = sc[r, SC_XD0], sc[r, SC_XD1]
                if in_c[r]:
                    p = pairs[r]
                    fl[K.F_XMAX, p] = max(fl[K.F_XMAX, p], Y1[r, X])
                    if xd1 < 0:
                        kr = kg[r]
                        end = Y1[r, X] <= 0
                        if not end and LC[kr, LC_FZ] != 0.0:
                            end = K.indicator(codes[kr], LC[kr], oc, p, max(Y1[r, X], 0.0), xd1) <= 0
                        if end:
                            sc[r, SC_EV] = EV_END
                            nev += 1
                else:
                    g0 = min(y[r, X], xd0)
                    g1 = min(Y1[r, X], xd1)
                    if g0 < 0 and g1 >= 0:
                        sc[r, SC_EV] = EV_ON
                        sc[r, SC_G0] = g0
                        sc[r, SC_G1] = g1
                        nev += 1
            if nev == 0:
                for r in range(r0, r1):
                    for j in range(NY):
                        y[r, j] = Y1[r, j]
                t_loc[i] += h
                continue
            # the earliest event of the island
            th_star = math.inf
            for r in range(r0, r1):
                if sc[r, SC_EV] != EV_END:
                    continue
                kr, p = kg[r], pairs[r]
                code, lc = codes[kr], LC[kr]
                lo = sc[r, SC_LO]
                if lo > 0:
                    _rk4_cone(r, ri, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c,
                              y, lo * h, Yt, work, F, buf)  # Ylo[r] only is read
                    Ylo = Yt
                else:
                    Ylo = y
                xs = Ylo[r, X] if Ylo[r, X] > 0 else 1.0
                B = abs(K.indicator(code, lc, oc, p, max(Ylo[r, X], 0.0), _xd(Ylo, r, n)))
                Bs = B if B > 0 else 1.0
                g_lo = _g_end(code, lc, oc, p, Ylo, r, n, xs, Bs)
                if 1e-300 > g_lo:  # Python's max(g, 1e-300)
                    g_lo = 1e-300
                g_hi = _g_end(code, lc, oc, p, Y1, r, n, xs, Bs)
                th = _root(1, r, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, ri, in_c,
                           y, h, lo, 1.0, g_lo, g_hi, xs, Bs, tmp, work, F, buf, riter, rtol)
                sc[r, SC_TH] = th
                if th < th_star:
                    th_star = th
            for r in range(r0, r1):
                if sc[r, SC_EV] != EV_ON:
                    continue
                th = _root(2, r, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, ri, in_c,
                           y, h, 0.0, 1.0, -sc[r, SC_G0], -sc[r, SC_G1], 1.0, 1.0, tmp, work, F, buf, riter, rtol)
                sc[r, SC_TH] = th
                if th < th_star:
                    th_star = th
            _rk4(r0, r1, cb0, cb1, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp, cq, Wpq, Wcpq, eb, in_c, y,
                 th_star * h, Yt, work, F, buf, True)
            t_loc[i] = t_loc[i] + th_star * h
            for r in range(r0, r1):
                for j in range(NY):
                    y[r, j] = Yt[r, j]
                ev = sc[r, SC_EV]
                if ev == EV_NONE or sc[r, SC_TH] > th_star + 1e-12:
                    continue
                if ev == EV_END:
                    status[r] = ST_ENDED
                    fz = LC[kg[r], LC_FZ] != 0.0
                    ended_by[r] = END_FORCE if (fz and y[r, X] > 0) else END_OVERLAP
                else:
                    status[r] = ST_ONSET
            return IS_STOP
        t_loc[i] = dt  # the segment ran to the step's end


@jit
def advance_islands(cst, substeps, max_segments, io, cio, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, cp,
                    cq, Wpq, Wcpq, eb, ri, t0, dt, hp, y, in_c, t_loc, phase, nseg, ist, status, ended_by, turned, fl,
                    ints, buf, work, Y1, Yt, tmp, F, sc):
    """Move every island whose ist is IS_RUN (module docstring); ist[i]
    becomes IS_DONE, IS_STOP (the caller handles its rows' status and sets
    it back to IS_RUN) or IS_OVER. Returns the number of islands stopped
    (IS_STOP or IS_OVER)."""
    stopped = 0
    for i in range(io.shape[0] - 1):
        if ist[i] != IS_RUN:
            continue
        st = _island(i, cst, substeps, max_segments, io, cio, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc,
                     cp, cq, Wpq, Wcpq, eb, ri, t0, dt, hp, y, in_c, t_loc, phase, nseg, status, ended_by, turned, fl,
                     ints, buf, work, Y1, Yt, tmp, F, sc)
        ist[i] = st
        if st != IS_DONE:
            stopped += 1
    return stopped


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__, K)
