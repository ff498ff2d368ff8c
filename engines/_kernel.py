"""Compiled (numba) core of :class:`engines._contacts.ContactManager`.

(Over 600 lines because it is one algorithm written out per row, the
compiled twin of :mod:`engines._contacts.reference`, kept in one file to be
read side by side with it.)

The same algorithm as the manager's numpy path (module docstring of
:mod:`engines._contacts`; the numpy path, :mod:`engines._contacts.reference`,
is the readable reference of this kernel: read it first), written per
contact row with scalar arithmetic and compiled, for the five registry
laws of :mod:`msf_contact.laws` used unchanged (their classes not
subclassed with other force methods). Per engine step the manager calls

1. :func:`prelude`: the internal state y (k, NY) of each candidate row
   (timing correction removed, resting relaxation, tangential displacement
   re-projected), then the settled path (one backward-Euler step of the law,
   solved by Newton) for the rows that qualify;
2. :func:`advance`, repeatedly: each row moves through its step (free
   flight in closed form, RK4 sub-cycling with the maximum compression and
   the separation located by Illinois root finding on a partial RK4 step)
   until the step is over, or an onset (law.onset is Python: the manager
   computes the onset constants and calls again) or a separation (the
   manager writes the record, in Python) stops it;
3. :func:`finale`: the state written back, the timing correction and the
   step's impulse per row.

The force laws (``CODE_*``), each as in :mod:`msf_contact.laws`:
MSF (37) with k_p of (15) in the law's mode and the tangential (36)-(37);
Hertz (30), Kuwabara-Kono, Hunt-Crossley and the linear spring-dashpot with
the Hertz-Mindlin tangential stiffness 8 G sqrt(R x); the Coulomb cap
mu F_n when mu is set. Onset constants per pair ``oc`` (P, NOC): see
:data:`ONSET_KEYS`. Law constants ``lc`` (NLC,): see ``LC_*``; rows of
several laws go through one call, row r with the law kg[r] of codes (G,)
and LC (G, NLC).

Equality with the numpy path is tested (tests/test_kernel.py); the two
differ only where the numpy path treats rows in lock-step (one internal
step for all rows of a batch, Newton iterated until every row converged).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from msf_contact._jitcache import guard as _guard

#: Compiled without numba's reference counting (NRT): the kernel allocates
#: nothing (scratch arrays come from the caller), and the refcounts numba
#: otherwise keeps on every array passed or aliased per row cost more than
#: a resting contact's whole step (measured: ~150 ns per row).
jit = njit(cache=True, _nrt=False)
jit_inline = njit(cache=True, _nrt=False, inline="always")

# law codes
CODE_MSF, CODE_HERTZ, CODE_KK, CODE_HC, CODE_SD = 0, 1, 2, 3, 4
#: engines._narrow.SideEndLaw: one end's share of the MSF line law (37), F_n = W_end (2 eta x' + 2/3 E' x),
#: W_end of its class docstring from the LC_S* constants (the side's pose, refreshed every step).
CODE_SIDE = 5
#: Onset constants each law's rows carry, in the order of the columns of oc.
ONSET_KEYS = {CODE_MSF: ("E", "eta_E", "G", "eta_Gy", "eta_Gz"), CODE_HERTZ: (), CODE_KK: (),
              CODE_HC: ("chi",), CODE_SD: ("k", "c"), CODE_SIDE: ("E", "eta_E", "G", "eta_Gy", "eta_Gz")}
NOC = 5
# law constants
LC_RA, LC_RB, LC_KHA, LC_KHB, LC_MU, LC_K, LC_A, LC_GM, LC_RM, LC_FZ, LC_KPMODE, LC_SRA, LC_SRB = range(13)
# CODE_SIDE only: the end's width radius R_w, end radius e, straight length L [m], e (1 - cos tilt) [m], rise (sin)
LC_SRW, LC_SE, LC_SL, LC_SDROP, LC_SRISE = range(13, 18)
#: CODE_SIDE of a cylinder's rim ring (engines._narrow.RimArcLaw) when lc[LC_SRING] != 0: then LC_SRW is the
#: rim's bottom radius Q [m], LC_SE the edge radius [m], LC_SL the slot's sector half-angle [rad], LC_SDROP the
#: ring's depth amplitude Q sin(tilt) [m] and LC_SRISE the slot's angle from the rim's lowest point [rad]
LC_SRING = 18
NLC = 19  # LC_SRA, LC_SRB: sqrt(R_a), sqrt(R_b)
KP_MSF, KP_SMALL, KP_HERTZ = 0, 1, 2

# layout of y, as engines._contacts
X, V, S, VC, P, WEL, WVI, Q, WT, PI, G, PD = 0, 1, 4, 7, 10, 13, 14, 15, 16, 17, 20, 23
NY = 26
# the moving contact point of a row, Lr (NL,) (engines._contacts.state.LEVER_DOC): on flag, x_ref,
# W01 = J0 M^-1 J1^T (3, 3) row-major, W11 = J1 M^-1 J1^T (3, 3), g0 = J1 qdot (3,)
L_ON, L_XREF, L_W01, L_W11, L_G0 = 0, 1, 2, 11, 20
NL = 23

# tuning constants, passed in as cst (their values and reasons: engines._contacts)
C_SPEED, C_NEWTON, C_VTOL, C_FD, C_FRATIO, C_RITER, C_RTOL, C_SETTLE = range(8)
NCST = 8

# row status after advance()
ST_DONE, ST_ONSET, ST_ENDED = 0, 1, 2
# ended_by codes
END_FORCE, END_OVERLAP = 0, 1


@jit_inline
def _kp(x, R, mode):
    if mode == KP_MSF:
        r = x / R
        if r > 2.0 - 1e-12:
            r = 2.0 - 1e-12
        return math.sqrt(2.0 - r)
    if mode == KP_SMALL:
        return math.sqrt(2.0)
    return 1.0


@jit_inline
def _overlap(a, b, c, d):
    """Length of [a, b] and [c, d] in common (0 if disjoint)."""
    return max(0.0, min(b, d) - max(a, c))


@jit_inline
def _ring_parts(lc, x):
    """(2 rho0, arc) [m] of a RimArcLaw slot at x >= 0 [m], at x = 0 its right limit
    (engines._narrow.RimArcLaw._width_one)."""
    e, Q, h, c, psi = lc[LC_SE], lc[LC_SRW], lc[LC_SL], lc[LC_SDROP], lc[LC_SRISE]
    rho0 = math.sqrt(max(x * (2.0 * e - x), 0.0))
    x0 = x + c * (1.0 - math.cos(psi))  # the rim's lowest point
    phi0 = math.pi if (c <= 0.0 or x0 >= 2.0 * c) else math.acos(1.0 - x0 / c)
    tp = 2.0 * math.pi
    ang = (_overlap(psi - h, psi + h, -phi0, phi0) + _overlap(psi - h, psi + h, tp - phi0, tp + phi0)
           + _overlap(psi - h, psi + h, -tp - phi0, -tp + phi0))
    return 2.0 * rho0, Q * ang


@jit_inline
def _side_parts(lc, x):
    """(w a, b) [m] of a SideEndLaw end at x >= 0 [m] (engines._narrow.SideEndLaw._width_one)."""
    if lc[LC_SRING] != 0.0:  # the ring's W at x = 0 is its right limit (RimArcLaw)
        return _ring_parts(lc, max(x, 0.0))
    if x <= 0.0:
        return 0.0, 0.0
    e, L, rise = lc[LC_SE], lc[LC_SL], lc[LC_SRISE]
    a = 2.0 * math.sqrt(max(x * (2.0 * lc[LC_SRW] - x), 0.0))
    rho0 = math.sqrt(max(x * (2.0 * e - x), 0.0))
    d, half = x - lc[LC_SDROP], 0.5 * L
    if rise > 0.0:
        ell = min(max(d / rise, 0.0), half)
    elif rise < 0.0:
        ell = half - min(max(d / rise, 0.0), half)
    else:
        ell = half if d > 0.0 else 0.0
    return (1.0 - ell / L) * a, rho0 + max(rho0, ell)


@jit_inline
def forces(code, lc, oc, p, x, xd, out):
    """F_n after the separation rule, its elastic part F_n(x, 0) [N], the
    tangential stiffnesses k_y, k_z [N/m] and dampings b_y, b_z [N s/m]
    into out[0:6]; x >= 0 [m], xd [m/s]; onset constants oc[p]."""
    fz = lc[LC_FZ] != 0.0
    if code == CODE_MSF:
        Ra, Rb = lc[LC_RA], lc[LC_RB]
        mode = int(lc[LC_KPMODE])
        kpa = _kp(x, Ra, mode)
        kpb = kpa if Rb == Ra else _kp(x, Rb, mode)
        sx = math.sqrt(x)
        sra, srb = lc[LC_SRA], lc[LC_SRB]
        base = (kpa * sra + kpb * srb) * sx
        el = (2.0 / 3.0) * oc[p, 0] * x
        F = base * (2.0 * oc[p, 1] * xd + el)
        P_bx = lc[LC_KHA] * x + 2.0 * kpb * (srb * sx)
        P_ax = lc[LC_KHB] * x + 2.0 * kpa * (sra * sx)
        out[1] = base * el
        out[2] = oc[p, 2] * P_bx
        out[3] = oc[p, 2] * P_ax
        out[4] = oc[p, 3] * P_bx
        out[5] = oc[p, 4] * P_ax
    elif code == CODE_SIDE:  # (37) with W = (w a + b)/2; (36) with (P_bx, P_ax) = (k_ha x + b, k_hb x + w a)
        wa, b = _side_parts(lc, x)
        el = (2.0 / 3.0) * oc[p, 0] * x
        base = 0.5 * (wa + b)
        F = base * (2.0 * oc[p, 1] * xd + el)
        P_bx = lc[LC_KHA] * x + b
        P_ax = lc[LC_KHB] * x + wa
        out[1] = base * el
        out[2] = oc[p, 2] * P_bx
        out[3] = oc[p, 2] * P_ax
        out[4] = oc[p, 3] * P_bx
        out[5] = oc[p, 4] * P_ax
    else:
        K = lc[LC_K]
        if code == CODE_SD:
            el = oc[p, 0] * x
            F = el + oc[p, 1] * xd
        else:
            el = K * x * math.sqrt(x)
            if code == CODE_HERTZ:
                F = el
            elif code == CODE_KK:
                F = K * math.sqrt(x) * (x + 1.5 * lc[LC_A] * xd)
            else:
                F = el * (1.0 + oc[p, 0] * xd)
        out[1] = el
        km = 8.0 * lc[LC_GM] * math.sqrt(lc[LC_RM] * x)
        out[2] = km
        out[3] = km
        out[4] = 0.0
        out[5] = 0.0
    out[0] = max(F, 0.0) if fz else F


@jit_inline
def coulomb(mu, Fn, Fa, Fb):
    """The tangential force (Fa, Fb) [N] capped at mu max(F_n, 0) (mu NaN: no cap)."""
    if not math.isnan(mu):
        cap = mu * max(Fn, 0.0)
        mag = math.hypot(Fa, Fb)
        if mag > cap:
            sc = cap / mag if mag > 0 else 1.0
            return Fa * sc, Fb * sc
    return Fa, Fb


@jit
def indicator(code, lc, oc, p, x, xd):
    """The law's separation indicator B(x, x') (force-zero: B < 0 ends the contact)."""
    if code == CODE_MSF or code == CODE_SIDE:
        return 2.0 * oc[p, 1] * xd + (2.0 / 3.0) * oc[p, 0] * x
    if code == CODE_HERTZ:
        return x
    if code == CODE_KK:
        return x + 1.5 * lc[LC_A] * xd
    if code == CODE_HC:
        return 1.0 + oc[p, 0] * xd
    return oc[p, 0] * x + oc[p, 1] * xd


@jit
def rhs(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, y, dy, buf, want_ft):
    """dy/dt of one row (NY,) as _Batch.rhs; returns (F_n, |F_t|) at y
    (|F_t| only when want_ft, else 0: the RK4 stages after the first need neither).
    Lr (NL,): the moving contact point (_Batch.rhs, engines._contacts.state.LEVER_DOC)."""
    x = max(y[X], 0.0)
    xd = -(y[V] * n[0] + y[V + 1] * n[1] + y[V + 2] * n[2])
    forces(code, lc, oc, p, x, xd, buf)
    Fn, Fc = buf[0], buf[1]
    vt0 = y[V] + xd * n[0]
    vt1 = y[V + 1] + xd * n[1]
    vt2 = y[V + 2] + xd * n[2]
    if paper:
        vcn = y[VC] * n[0] + y[VC + 1] * n[1] + y[VC + 2] * n[2]
        sd0 = y[VC] - vcn * n[0]
        sd1 = y[VC + 1] - vcn * n[1]
        sd2_ = y[VC + 2] - vcn * n[2]
    else:
        sd0, sd1, sd2_ = vt0, vt1, vt2
    s_a = T[0, 0] * y[S] + T[0, 1] * y[S + 1] + T[0, 2] * y[S + 2]
    s_b = T[1, 0] * y[S] + T[1, 1] * y[S + 1] + T[1, 2] * y[S + 2]
    d_a = T[0, 0] * sd0 + T[0, 1] * sd1 + T[0, 2] * sd2_
    d_b = T[1, 0] * sd0 + T[1, 1] * sd1 + T[1, 2] * sd2_
    Fa = -(buf[4] * d_a + buf[2] * s_a)
    Fb = -(buf[5] * d_b + buf[3] * s_b)
    Fa, Fb = coulomb(lc[LC_MU], Fn, Fa, Fb)
    f0 = Fn * n[0] + Fa * T[0, 0] + Fb * T[1, 0]
    f1 = Fn * n[1] + Fa * T[0, 1] + Fb * T[1, 1]
    f2 = Fn * n[2] + Fa * T[0, 2] + Fb * T[1, 2]
    Ft0, Ft1, Ft2 = f0 - Fn * n[0], f1 - Fn * n[1], f2 - Fn * n[2]
    dy[X] = xd
    if Lr[L_ON] != 0.0:
        # the contact point moves with the overlap: v' = W(d) f + a + d' g, g' = (W01^T + d W11) f,
        # W(d) = W + d (W01 + W01^T) + d^2 W11, d = max(x, 0) - max(x_ref, 0); PD' = d f (LEVER_DOC)
        d = max(y[X], 0.0) - Lr[L_XREF]
        dd = xd  # in contact: d' = x' (at x < 0 only within round-off of the onset or past the end; _Batch.rhs)
        for i in range(3):
            A = Lr[L_W01 + 3 * i] * f0 + Lr[L_W01 + 3 * i + 1] * f1 + Lr[L_W01 + 3 * i + 2] * f2
            B = Lr[L_W01 + i] * f0 + Lr[L_W01 + 3 + i] * f1 + Lr[L_W01 + 6 + i] * f2
            C = Lr[L_W11 + 3 * i] * f0 + Lr[L_W11 + 3 * i + 1] * f1 + Lr[L_W11 + 3 * i + 2] * f2
            dy[V + i] = W[i, 0] * f0 + W[i, 1] * f1 + W[i, 2] * f2 + (d * (A + B + d * C) + dd * y[G + i]) + a[i]
            dy[G + i] = B + d * C
        dy[PD] = d * f0
        dy[PD + 1] = d * f1
        dy[PD + 2] = d * f2
    else:
        for i in range(3):
            dy[V + i] = W[i, 0] * f0 + W[i, 1] * f1 + W[i, 2] * f2 + a[i]
            dy[G + i] = 0.0
            dy[PD + i] = 0.0
    for i in range(3):
        dy[VC + i] = Wc[i, 0] * f0 + Wc[i, 1] * f1 + Wc[i, 2] * f2 + a[i]
        dy[PI + i] = y[P + i]
    dy[S] = sd0
    dy[S + 1] = sd1
    dy[S + 2] = sd2_
    dy[P] = f0
    dy[P + 1] = f1
    dy[P + 2] = f2
    dy[WEL] = Fc * xd
    dy[WVI] = (Fn - Fc) * xd
    dy[Q] = buf[4] * d_a * d_a + buf[5] * d_b * d_b
    dy[WT] = -(Ft0 * vt0 + Ft1 * vt1 + Ft2 * vt2)
    return Fn, (math.hypot(Fa, Fb) if want_ft else 0.0)


@jit
def rk4(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, y, h, out, work, buf, k1_ready):
    """One classical RK4 step of length h from y into out; returns (F_n, |F_t|) at y.
    work: (5, NY) scratch; work[0] holds the slope at y: with k1_ready it is
    the one of the previous call from the same y (the partial steps of root
    finding all start at the substep's start), and (0, 0) is returned."""
    k1, k2, k3, k4, yt = work[0], work[1], work[2], work[3], work[4]
    Fn = Ft = 0.0
    if not k1_ready:
        Fn, Ft = rhs(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, y, k1, buf, True)
    for j in range(NY):
        yt[j] = y[j] + 0.5 * h * k1[j]
    rhs(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, yt, k2, buf, False)
    for j in range(NY):
        yt[j] = y[j] + 0.5 * h * k2[j]
    rhs(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, yt, k3, buf, False)
    for j in range(NY):
        yt[j] = y[j] + h * k3[j]
    rhs(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, yt, k4, buf, False)
    for j in range(NY):
        out[j] = y[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    slip(code, lc, oc, p, n, T, paper, y, out, h, buf)
    return Fn, Ft


@jit_inline
def slip(code, lc, oc, p, n, T, paper, y0, y1, h, buf):
    """Coulomb slip of the tangential spring over the step y0 -> y1 (NY,)
    of length h, in place on y1 (_Batch.slip for one row): where the trial
    force exceeds mu F_n, k s + b (s - s0)/h = -F_capped per axis."""
    mu = lc[LC_MU]
    if math.isnan(mu) or not h > 0:
        return
    x = max(y1[X], 0.0)
    xd = -(y1[V] * n[0] + y1[V + 1] * n[1] + y1[V + 2] * n[2])
    forces(code, lc, oc, p, x, xd, buf)
    Fn = buf[0]
    if paper:
        vcn = y1[VC] * n[0] + y1[VC + 1] * n[1] + y1[VC + 2] * n[2]
        sd0, sd1, sd2_ = y1[VC] - vcn * n[0], y1[VC + 1] - vcn * n[1], y1[VC + 2] - vcn * n[2]
    else:
        sd0, sd1, sd2_ = y1[V] + xd * n[0], y1[V + 1] + xd * n[1], y1[V + 2] + xd * n[2]
    s_a = T[0, 0] * y1[S] + T[0, 1] * y1[S + 1] + T[0, 2] * y1[S + 2]
    s_b = T[1, 0] * y1[S] + T[1, 1] * y1[S + 1] + T[1, 2] * y1[S + 2]
    d_a = T[0, 0] * sd0 + T[0, 1] * sd1 + T[0, 2] * sd2_
    d_b = T[1, 0] * sd0 + T[1, 1] * sd1 + T[1, 2] * sd2_
    Fa = -(buf[4] * d_a + buf[2] * s_a)
    Fb = -(buf[5] * d_b + buf[3] * s_b)
    cap = mu * max(Fn, 0.0)
    mag = math.hypot(Fa, Fb)
    if not mag > cap:
        return
    sc = cap / mag if mag > 0 else 1.0
    Fa *= sc
    Fb *= sc
    s0_a = T[0, 0] * y0[S] + T[0, 1] * y0[S + 1] + T[0, 2] * y0[S + 2]
    s0_b = T[1, 0] * y0[S] + T[1, 1] * y0[S + 1] + T[1, 2] * y0[S + 2]
    bh_a, bh_b = buf[4] / h, buf[5] / h
    den_a, den_b = buf[2] + bh_a, buf[3] + bh_b
    if den_a > 0:
        s_a = (bh_a * s0_a - Fa) / den_a
    if den_b > 0:
        s_b = (bh_b * s0_b - Fb) / den_b
    for i in range(3):
        y1[S + i] = s_a * T[0, i] + s_b * T[1, i]


@jit_inline
def _xdot(y, n):
    return -(y[V] * n[0] + y[V + 1] * n[1] + y[V + 2] * n[2])


@jit
def _gfun(kind, code, lc, oc, p, n, yy, xs, Bs, fz):
    """Root functions: kind 0, x' (maximum compression); kind 1, the
    separation (x/x_s, and with force-zero min(x/x_s, B/B_s) while separating)."""
    if kind == 0:
        return _xdot(yy, n)
    gx = yy[X] / xs
    if not fz:
        return gx
    xd = _xdot(yy, n)
    gb = indicator(code, lc, oc, p, max(yy[X], 0.0), xd) / Bs if xd < 0 else 1.0
    return min(gx, gb)


@jit
def _root(kind, code, lc, oc, p, n, T, W, Wc, a, paper, Lr, y0, h, lo, hi, g_lo, g_hi, xs, Bs, fz, tmp, work, buf,
          root_iter, root_tol):
    """Illinois regula falsi for th in [lo, hi] with g(lo) > 0 >= g(hi), g of the
    state rk4(y0, th h); as engines._contacts._find_root for one row. y0 is
    the substep's start, whose slope rk4 left in work[0]."""
    side = 0
    if hi - lo <= root_tol or g_hi == 0:
        return hi
    for _ in range(root_iter):
        th, at_hi = illinois_next(lo, hi, g_lo, g_hi)
        if at_hi:
            return hi
        rk4(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, y0, th * h, tmp, work, buf, True)
        gt = _gfun(kind, code, lc, oc, p, n, tmp, xs, Bs, fz)
        lo, hi, g_lo, g_hi, side = illinois_update(th, gt, lo, hi, g_lo, g_hi, side)
        if hi - lo <= root_tol or g_hi == 0:
            break
    return hi


@jit_inline
def illinois_next(lo, hi, g_lo, g_hi):
    """The next trial th of Illinois regula falsi on [lo, hi] (g(lo) > 0 >= g(hi)):
    the secant's root, bisection where it stalls at an end; (th, True) when
    the secant lands on hi (hi is the root to rounding: the caller returns hi)."""
    den = g_lo - g_hi
    th = lo + g_lo * (hi - lo) / den if den > 0 else 0.5 * (lo + hi)
    if den > 0 and th >= hi:
        return th, True
    if th <= lo or th >= hi:
        th = 0.5 * (lo + hi)
    return th, False


@jit_inline
def illinois_update(th, gt, lo, hi, g_lo, g_hi, side):
    """The bracket after g(th) = gt: (lo, hi, g_lo, g_hi, side), the value at the
    end that stays twice in a row halved (Illinois)."""
    if gt > 0:
        if side == 1:
            g_hi *= 0.5
        return th, hi, gt, g_hi, 1
    if side == -1:
        g_lo *= 0.5
    return lo, th, g_lo, gt, -1


@jit
def tangent_basis(n, T):
    """t1, t2 into T (2, 3) with t1 x t2 = n, as engines._contacts._tangent_basis."""
    if abs(n[0]) < 0.9:
        e0, e1, e2 = 1.0, 0.0, 0.0
    else:
        e0, e1, e2 = 0.0, 1.0, 0.0
    d = e0 * n[0] + e1 * n[1] + e2 * n[2]
    t0, t1, t2 = e0 - d * n[0], e1 - d * n[1], e2 - d * n[2]
    ln = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    t0 /= ln
    t1 /= ln
    t2 /= ln
    T[0, 0], T[0, 1], T[0, 2] = t0, t1, t2
    T[1, 0] = n[1] * t2 - n[2] * t1
    T[1, 1] = n[2] * t0 - n[0] * t2
    T[1, 2] = n[0] * t1 - n[1] * t0


@jit_inline
def _w_t_max(n, W, r, T):
    """The largest eigenvalue of T W T for row r (tangential_w_max); T (2, 3) scratch."""
    tangent_basis(n[r], T)
    b00 = b01 = b10 = b11 = 0.0
    for i in range(3):
        w0 = W[r, i, 0] * T[0, 0] + W[r, i, 1] * T[0, 1] + W[r, i, 2] * T[0, 2]  # (W t1)_i
        w1 = W[r, i, 0] * T[1, 0] + W[r, i, 1] * T[1, 1] + W[r, i, 2] * T[1, 2]  # (W t2)_i
        b00 += T[0, i] * w0
        b01 += T[0, i] * w1
        b10 += T[1, i] * w0
        b11 += T[1, i] * w1
    half = 0.5 * (b00 - b11)
    off = 0.5 * (b01 + b10)
    return 0.5 * (b00 + b11) + math.sqrt(half * half + off * off)


@jit
def tangential_w_max(n, W, out, T):
    """The largest eigenvalue of T W T, T = I - n n^T, per row into out (k,)
    [1/kg]: n (k, 3) unit normals, W (k, 3, 3) symmetric (to round-off)
    inverse inertias. T W T has the eigenvalue 0 along n; its other two are
    those of the symmetric 2x2 block B_ij = t_i . W t_j in the tangent basis
    (tangent_basis), the larger one (B11 + B22)/2 + sqrt(((B11 - B22)/2)^2 +
    B12^2) (no cancellation under the root; B12 the mean of the two
    off-diagonal products, as numpy's eigvalsh reads one triangle of a
    matrix symmetric to round-off). T (2, 3): scratch."""
    for r in range(n.shape[0]):
        out[r] = _w_t_max(n, W, r, T)


@jit_inline
def _dot3(a, i, b, j):
    """a[i] . b[j] (rows of 3) summed as (p0 + p2) + p1, the order numpy's
    einsum('ij,ij->i') sums three products in (see approach_rates)."""
    return (a[i, 0] * b[j, 0] + a[i, 2] * b[j, 2]) + a[i, 1] * b[j, 1]


@jit
def onset_pre(new, n, W, a, y, m, vn, a_n):
    """ContactManager._begin before law.onset, for the rows ``new`` (k,) of
    the step's n, W, a (rows, 3[, 3]) and y: the effective mass m = 1/(n W n)
    [kg], the closing speed vn = max(-v . n, 0) [m/s] (v = y's V) and the
    closing acceleration a_n = -a . n [m/s^2], into (k,) arrays. Returns -1,
    or the first i whose n W n is <= 0 (nothing is written past it)."""
    for i in range(new.shape[0]):
        r = new[i]
        nWn = 0.0
        for u in range(3):
            nWn += n[r, u] * ((W[r, u, 0] * n[r, 0] + W[r, u, 1] * n[r, 1]) + W[r, u, 2] * n[r, 2])
        if nWn <= 0.0:
            return i
        m[i] = 1.0 / nWn
        d = -((y[r, V] * n[r, 0] + y[r, V + 2] * n[r, 2]) + y[r, V + 1] * n[r, 1])
        vn[i] = 0.0 if d < 0.0 else d  # np.maximum(d, 0.0), NaN kept
        a_n[i] = -_dot3(a, r, n, r)
    return -1


@jit
def onset_post(pp, new, n, W, y, t_abs, vn, v_used, m, tau_n, k_t, sub_n, sub_t, point, in_island, island_contact,
               tau_est, v_n_in, v_n_used, m_eff, n_in, p_in, u_in, vc_in, x_onset, turned, outside, fl, T):
    """ContactManager._begin after law.onset, for the new contacts of pairs
    pp (k,) at rows ``new`` of the step's n, W, y: the internal step h =
    min(tau_n/sub_n, tau_t/sub_t) with tau_t = pi/sqrt(max(k_t) w_t) [s]
    (k_t (k, 2) [N/m] the law's tangential stiffness at the Hertz x_max, w_t
    the largest eigenvalue of T W T [1/kg]: tangential_w_max; inf without
    stiffness), the onset bookkeeping (t_abs (k,) [s], speeds, m_eff, normal,
    point, tangential velocities at onset, approach at onset) and the record
    bookkeeping reset; y's tangential displacement and works zeroed. T (2, 3):
    scratch. NaN propagates as numpy's maximum/minimum would."""
    for i in range(pp.shape[0]):
        p, r = pp[i], new[i]
        island_contact[p] = in_island[p]
        w_t = _w_t_max(n, W, r, T)
        kt = k_t[i, 0] if (k_t[i, 0] >= k_t[i, 1] or k_t[i, 0] != k_t[i, 0]) else k_t[i, 1]
        kw = kt * w_t
        tau_t = math.pi / math.sqrt(kw) if kw > 0.0 else math.inf
        hn, ht = tau_n[i] / sub_n, tau_t / sub_t
        tau_est[p] = tau_n[i]
        fl[F_H, p] = hn if (hn <= ht or hn != hn) else ht
        fl[F_TONSET, p] = t_abs[i]
        v_n_in[p] = vn[i]
        v_n_used[p] = v_used[i]
        m_eff[p] = m[i]
        dv = (y[r, V] * n[r, 0] + y[r, V + 2] * n[r, 2]) + y[r, V + 1] * n[r, 1]
        dc = (y[r, VC] * n[r, 0] + y[r, VC + 2] * n[r, 2]) + y[r, VC + 1] * n[r, 1]
        for u in range(3):
            n_in[p, u] = n[r, u]
            p_in[p, u] = point[p, u]
            u_in[p, u] = y[r, V + u] - dv * n[r, u]
            vc_in[p, u] = y[r, VC + u] - dc * n[r, u]
            y[r, S + u] = 0.0
        x0 = y[r, X]
        fl[F_XMAX, p] = 0.0 if x0 < 0.0 else x0
        x_onset[p] = x0
        fl[F_XTURN, p] = 0.0
        turned[p] = False
        fl[F_TAU1, p] = 0.0
        fl[F_FMAX, p] = 0.0
        fl[F_XATF, p] = 0.0
        fl[F_FMIN, p] = math.inf
        fl[F_FMAXR, p] = 0.0
        fl[F_WELC, p] = 0.0
        fl[F_WVIC, p] = 0.0
        outside[p] = False
        y[r, WEL] = 0.0
        y[r, WVI] = 0.0
        y[r, Q] = 0.0
        y[r, WT] = 0.0


@jit
def _solve3(A3, ia, B, ib, iout, M):
    """B[iout] = A3[ia]^-1 B[ib] for a 3x3 matrix (Gaussian elimination with
    partial pivoting, M (3, 4) scratch); returns False when it is singular."""
    for i in range(3):
        for j in range(3):
            M[i, j] = A3[ia, i, j]
        M[i, 3] = B[ib, i]
    for c in range(3):
        piv = c
        for r in range(c + 1, 3):
            if abs(M[r, c]) > abs(M[piv, c]):
                piv = r
        if M[piv, c] == 0.0:
            return False
        if piv != c:
            for j in range(4):
                M[c, j], M[piv, j] = M[piv, j], M[c, j]
        for r in range(c + 1, 3):
            f = M[r, c] / M[c, c]
            for j in range(c, 4):
                M[r, j] -= f * M[c, j]
    for i in range(2, -1, -1):
        s = M[i, 3]
        for j in range(i + 1, 3):
            s -= M[i, j] * B[iout, j]
        B[iout, i] = s / M[i, i]
    return True


@jit
def prelude(cst, pairs, x_eng, n, v, vc, W, Wc, a, paper, Lr, t0, dt, settle_rate, settled_path, kg, codes, LC, oc,
            active, was_settled, x_state, s_state, tau_est, dv_corr, dvc_corr, W_el, W_visc, Q_t, W_t,
            y, T, t_loc, in_c, settled, status, turned, fl, ints, buf, m33, v3, M34):
    """Step start for rows 0..k-1 (pair index pairs[r]): y, T, in_c, and the
    settled path for the resting rows (its record bookkeeping into the per-pair
    arrays fl (NF, P) and turned (P,), see settled_row). oc (P, NOC): onset
    constants per pair; was_settled (P,): on the settled path in the last
    step. ints counts settled rows [0], Newton iterations [1], RK4 substeps
    [2] and ends [3]."""
    k = pairs.shape[0]
    for r in range(k):
        p = pairs[r]
        nr = n[r]
        tangent_basis(nr, T[r])
        act = active[p]
        for i in range(3):
            y[r, V + i] = v[r, i] - dv_corr[p, i]
            y[r, VC + i] = vc[r, i] - dvc_corr[p, i]
        x0 = x_state[p] if act else x_eng[r]
        settle = act and (t0 - fl[F_TONSET, p]) > cst[C_SETTLE] * tau_est[p]
        if settle:
            # a row alone (state.relax): after a settled step toward x_eng, else toward x_eng less the
            # sub-cycled lead and never deeper
            if was_settled[p]:
                x0 = x0 + settle_rate * (x_eng[r] - x0)
            else:
                lead = -0.5 * dt * (y[r, V] * nr[0] + y[r, V + 1] * nr[1] + y[r, V + 2] * nr[2])
                x0 = x0 + settle_rate * min(x_eng[r] - lead - x0, 0.0)
        y[r, X] = x0
        # tangential displacement onto the current tangent plane, same length
        s0, s1, s2 = s_state[p, 0], s_state[p, 1], s_state[p, 2]
        sn = s0 * nr[0] + s1 * nr[1] + s2 * nr[2]
        a0, a1, a2 = s0 - sn * nr[0], s1 - sn * nr[1], s2 - sn * nr[2]
        ls = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        lt = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        if lt > 0:
            f = ls / lt
            y[r, S], y[r, S + 1], y[r, S + 2] = a0 * f, a1 * f, a2 * f
        else:
            y[r, S] = y[r, S + 1] = y[r, S + 2] = 0.0
        for i in range(3):
            y[r, P + i] = 0.0
            y[r, PI + i] = 0.0
            y[r, G + i] = Lr[r, L_G0 + i]
            y[r, PD + i] = 0.0
        if Lr[r, L_ON] != 0.0:  # v_rel at the internal overlap's point, not the engine's (LEVER_DOC)
            d0 = max(x0, 0.0) - Lr[r, L_XREF]
            for i in range(3):
                y[r, V + i] += y[r, G + i] * d0
        y[r, WEL], y[r, WVI], y[r, Q], y[r, WT] = W_el[p], W_visc[p], Q_t[p], W_t[p]
        t_loc[r] = 0.0
        in_c[r] = act
        settled[r] = False
        status[r] = ST_DONE
        if settled_path and settle and x0 > 0:
            if settled_row(cst, r, p, codes[kg[r]], LC[kg[r]], oc, n, T, W, Wc, a, paper[r], t0, dt, y, turned, fl,
                           ints, buf, m33, v3, M34):
                settled[r] = True
                t_loc[r] = dt


# per-pair float arrays of the record bookkeeping, rows of fl (NF, P)
F_TAU1, F_XTURN, F_XMAX, F_WELC, F_WVIC, F_FMAX, F_XATF, F_FMIN, F_FMAXR, F_TONSET, F_H = range(11)
NF = 11


@jit_inline
def settled_row(cst, r, p, code, lc, oc, n, T, W, Wc, a, paper, t0, dt, y, turned, fl, ints, buf, m33, v3, M34):
    """One backward-Euler step of the law over the whole engine step for a
    resting row (ContactManager._settled for one row); returns True when it
    took it (y written), False to leave the row to sub-cycling. Row r of
    the (k, ...) arrays, pair p of the per-pair ones (indexed, not sliced:
    a slice costs more than this whole step). buf (6,), m33 (4, 3, 3),
    v3 (8, 3), M34 (3, 4): scratch."""
    x0 = y[r, X]
    nWn = 0.0
    for i in range(3):
        for j in range(3):
            nWn += n[r, i] * W[r, i, j] * n[r, j]
    forces(code, lc, oc, p, x0, 0.0, buf)
    F_el = buf[0]
    vx = math.sqrt(max(F_el, 0.0) * x0 * nWn)
    vn = y[r, V] * n[r, 0] + y[r, V + 1] * n[r, 1] + y[r, V + 2] * n[r, 2]
    if not (abs(vn) <= cst[C_SPEED] * vx and vx > 0):
        return False
    Ww = Wc if paper else W
    wo = VC if paper else V
    # M = [n^T W; T Ww] B^T with B = [n; t1; t2], on scalars (kept in registers)
    n0, n1, n2 = n[r, 0], n[r, 1], n[r, 2]
    a0, a1, a2 = T[r, 0, 0], T[r, 0, 1], T[r, 0, 2]  # t1
    b0, b1, b2 = T[r, 1, 0], T[r, 1, 1], T[r, 1, 2]  # t2
    s00 = n0 * W[r, 0, 0] + n1 * W[r, 1, 0] + n2 * W[r, 2, 0]
    s01 = n0 * W[r, 0, 1] + n1 * W[r, 1, 1] + n2 * W[r, 2, 1]
    s02 = n0 * W[r, 0, 2] + n1 * W[r, 1, 2] + n2 * W[r, 2, 2]
    s10 = a0 * Ww[r, 0, 0] + a1 * Ww[r, 1, 0] + a2 * Ww[r, 2, 0]
    s11 = a0 * Ww[r, 0, 1] + a1 * Ww[r, 1, 1] + a2 * Ww[r, 2, 1]
    s12 = a0 * Ww[r, 0, 2] + a1 * Ww[r, 1, 2] + a2 * Ww[r, 2, 2]
    s20 = b0 * Ww[r, 0, 0] + b1 * Ww[r, 1, 0] + b2 * Ww[r, 2, 0]
    s21 = b0 * Ww[r, 0, 1] + b1 * Ww[r, 1, 1] + b2 * Ww[r, 2, 1]
    s22 = b0 * Ww[r, 0, 2] + b1 * Ww[r, 1, 2] + b2 * Ww[r, 2, 2]
    M00, M01, M02 = s00 * n0 + s01 * n1 + s02 * n2, s00 * a0 + s01 * a1 + s02 * a2, s00 * b0 + s01 * b1 + s02 * b2
    M10, M11, M12 = s10 * n0 + s11 * n1 + s12 * n2, s10 * a0 + s11 * a1 + s12 * a2, s10 * b0 + s11 * b1 + s12 * b2
    M20, M21, M22 = s20 * n0 + s21 * n1 + s22 * n2, s20 * a0 + s21 * a1 + s22 * a2, s20 * b0 + s21 * b1 + s22 * b2
    # z = (n.v, t1.w, t2.w) now and free of contact force at the step end
    e0, e1, e2 = y[r, V] + dt * a[r, 0], y[r, V + 1] + dt * a[r, 1], y[r, V + 2] + dt * a[r, 2]
    zf0 = e0 * n0 + e1 * n1 + e2 * n2
    e0, e1, e2 = y[r, wo] + dt * a[r, 0], y[r, wo + 1] + dt * a[r, 1], y[r, wo + 2] + dt * a[r, 2]
    zf1 = e0 * a0 + e1 * a1 + e2 * a2
    zf2 = e0 * b0 + e1 * b1 + e2 * b2
    z0 = vn
    z1 = y[r, wo] * a0 + y[r, wo + 1] * a1 + y[r, wo + 2] * a2
    z2 = y[r, wo] * b0 + y[r, wo + 1] * b1 + y[r, wo + 2] * b2
    s2a = a0 * y[r, S] + a1 * y[r, S + 1] + a2 * y[r, S + 2]
    s2b = b0 * y[r, S] + b1 * y[r, S + 1] + b2 * y[r, S + 2]
    delta = cst[C_FD] * x0 / dt
    tol = cst[C_VTOL] * vx
    mu = lc[LC_MU]
    conv = False
    xd_e = x_e = Fn = Fc = Fa = Fb = sea = seb = 0.0
    kt0 = kt1 = bt0 = bt1 = 0.0
    nmax = int(cst[C_NEWTON])
    for it in range(nmax + 1):
        xd_e = -z0
        x_e = x0 + dt * xd_e
        forces(code, lc, oc, p, x_e, xd_e, buf)
        Fn, Fc = buf[0], buf[1]
        kt0, kt1, bt0, bt1 = buf[2], buf[3], buf[4], buf[5]
        sea = s2a + dt * z1
        seb = s2b + dt * z2
        Fa = -(bt0 * z1 + kt0 * sea)
        Fb = -(bt1 * z2 + kt1 * seb)
        Fa, Fb = coulomb(mu, Fn, Fa, Fb)
        R0 = z0 - zf0 - dt * (M00 * Fn + M01 * Fa + M02 * Fb)
        R1 = z1 - zf1 - dt * (M10 * Fn + M11 * Fa + M12 * Fb)
        R2 = z2 - zf2 - dt * (M20 * Fn + M21 * Fa + M22 * Fb)
        ints[1] += 1
        conv = max(abs(R0), abs(R1), abs(R2)) <= tol
        if conv or it == nmax:
            break
        # forward difference dF_n/dx dt + dF_n/dx' (only when another iteration follows)
        forces(code, lc, oc, p, x_e + dt * delta, xd_e + delta, buf)
        D0 = max((buf[0] - Fn) / delta, 0.0)
        D1 = bt0 + kt0 * dt
        D2 = bt1 + kt1 * dt
        # Newton: (I + dt M D) dz = R, in the scratch of _solve3
        m33[3, 0, 0], m33[3, 0, 1], m33[3, 0, 2] = 1.0 + dt * M00 * D0, dt * M01 * D1, dt * M02 * D2
        m33[3, 1, 0], m33[3, 1, 1], m33[3, 1, 2] = dt * M10 * D0, 1.0 + dt * M11 * D1, dt * M12 * D2
        m33[3, 2, 0], m33[3, 2, 1], m33[3, 2, 2] = dt * M20 * D0, dt * M21 * D1, 1.0 + dt * M22 * D2
        v3[3, 0], v3[3, 1], v3[3, 2] = R0, R1, R2
        if not _solve3(m33, 3, v3, 3, 4, M34):
            return False
        z0 -= v3[4, 0]
        z1 -= v3[4, 1]
        z2 -= v3[4, 2]
    if not (conv and x_e > 0 and Fn > 0 and abs(xd_e) <= cst[C_SPEED] * vx):
        return False
    # the step's result: the law's force at the end state, held over the step
    f0 = Fn * n0 + Fa * a0 + Fb * b0
    f1 = Fn * n1 + Fa * a1 + Fb * b1
    f2 = Fn * n2 + Fa * a2 + Fb * b2
    dx = x_e - x0  # Fc: the elastic part F_n(x_e, 0), from the last evaluation
    u0 = y[r, V] + dt * (W[r, 0, 0] * f0 + W[r, 0, 1] * f1 + W[r, 0, 2] * f2 + a[r, 0])
    u1 = y[r, V + 1] + dt * (W[r, 1, 0] * f0 + W[r, 1, 1] * f1 + W[r, 1, 2] * f2 + a[r, 1])
    u2 = y[r, V + 2] + dt * (W[r, 2, 0] * f0 + W[r, 2, 1] * f1 + W[r, 2, 2] * f2 + a[r, 2])
    for i in range(3):
        y[r, VC + i] += dt * (Wc[r, i, 0] * f0 + Wc[r, i, 1] * f1 + Wc[r, i, 2] * f2 + a[r, i])
    un = u0 * n0 + u1 * n1 + u2 * n2
    wt = (f0 - Fn * n0) * (u0 - un * n0) + (f1 - Fn * n1) * (u1 - un * n1) + (f2 - Fn * n2) * (u2 - un * n2)
    y[r, X] = x_e
    y[r, V], y[r, V + 1], y[r, V + 2] = u0, u1, u2
    y[r, S], y[r, S + 1], y[r, S + 2] = sea * a0 + seb * b0, sea * a1 + seb * b1, sea * a2 + seb * b2
    y[r, P], y[r, P + 1], y[r, P + 2] = f0 * dt, f1 * dt, f2 * dt
    h2 = 0.5 * dt * dt
    y[r, PI], y[r, PI + 1], y[r, PI + 2] = h2 * f0, h2 * f1, h2 * f2
    y[r, WEL] += Fc * dx
    y[r, WVI] += (Fn - Fc) * dx
    y[r, Q] += (bt0 * z1 * z1 + bt1 * z2 * z2) * dt
    y[r, WT] -= wt * dt
    # record bookkeeping, as one substep at the end state
    if not turned[p] and xd_e <= 0:
        turned[p] = True
        fl[F_TAU1, p] = t0 + dt - fl[F_TONSET, p]
        fl[F_XTURN, p] = x_e
        fl[F_WELC, p] = y[r, WEL]
        fl[F_WVIC, p] = y[r, WVI]
    if Fn > fl[F_FMAX, p]:
        fl[F_XATF, p] = x_e
        fl[F_FMAX, p] = Fn
    fl[F_XMAX, p] = max(fl[F_XMAX, p], x_e)
    if Fn >= cst[C_FRATIO] * fl[F_FMAX, p]:
        ratio = math.hypot(Fa, Fb) / Fn
        fl[F_FMIN, p] = min(fl[F_FMIN, p], ratio)
        fl[F_FMAXR, p] = max(fl[F_FMAXR, p], ratio)
    ints[0] += 1
    return True


@jit
def free_flight(n, a, Lr, y, rem):
    """Advance one row (y (NY,)) without contact force to the next onset
    (x >= 0 with closing speed) or by rem [s]; returns the time to the onset
    (inf: none within rem). As ContactManager._free_flight for one row; a
    moving contact point (Lr on) adds g (max(x_new, 0) - max(x_old, 0)) to v (LEVER_DOC)."""
    x0 = y[X]
    xd0 = _xdot(y, n)
    c = -0.5 * (a[0] * n[0] + a[1] * n[1] + a[2] * n[2])  # x(t) = x0 + xd0 t + c t^2
    tc = math.inf
    stays = False
    imm = (x0 >= 0 and xd0 > 0) or (x0 > 0 and xd0 == 0)
    if imm:
        tc = 0.0
    else:
        D = xd0 * xd0 - 4.0 * c * x0
        sq = math.sqrt(max(D, 0.0))
        if xd0 > 0:
            t_up = -2.0 * x0 / (sq + xd0)
        elif c != 0:
            t_up = (sq - xd0) / (2.0 * c)
        else:
            t_up = math.nan
        up = x0 < 0 and D >= 0 and (xd0 > 0 or c > 0)
        if up and t_up >= 0:
            tc = t_up
        back = x0 >= 0 and xd0 <= 0 and c > 0
        if back:
            stays = x0 - xd0 * xd0 / (4.0 * c) >= 0
            tc = -xd0 / (2.0 * c) if stays else t_up
    if not tc <= rem:
        tc = math.inf
    tadv = tc if tc < math.inf else rem
    y[X] = x0 + xd0 * tadv + c * tadv * tadv
    if Lr[L_ON] != 0.0:
        for i in range(3):
            y[V + i] += y[G + i] * (max(y[X], 0.0) - max(x0, 0.0))
    for i in range(3):
        y[V + i] += a[i] * tadv
        y[VC + i] += a[i] * tadv
        y[PI + i] += y[P + i] * tadv
    if stays and tc < math.inf:  # exactly at the turn: closing speed 0, not slightly negative
        vn = y[V] * n[0] + y[V + 1] * n[1] + y[V + 2] * n[2]
        for i in range(3):
            y[V + i] -= vn * n[i]
    return tc


@jit
def integrate_row(cst, code, lc, oc, n, T, W, Wc, a, paper, Lr, p, y, t_loc, t0, dt, h_p, turned, fl, ints, buf, work,
                  rows4):
    """RK4 sub-cycling of one contact row from t_loc to the end of the step
    or to the contact's end (ContactManager._integrate for one row). Returns
    (ended, ended_by code, new t_loc). buf (6,), work (5, NY), rows4 (4, NY): scratch."""
    Y, Y1, Yt, tmp = rows4[0], rows4[1], rows4[2], rows4[3]
    for j in range(NY):
        Y[j] = y[j]
    fz = lc[LC_FZ] != 0.0
    riter, rtol = int(cst[C_RITER]), cst[C_RTOL]
    rem = dt - t_loc
    nsub = max(1, int(math.ceil(rem / h_p - 1e-9)))
    hs = rem / nsub
    for i in range(nsub):
        Fn0, Ft0 = rk4(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, Y, hs, Y1, work, buf, False)
        ints[2] += 1
        # peak force and friction ratio at the substep start
        if Fn0 > fl[F_FMAX, p]:
            fl[F_XATF, p] = Y[X]
            fl[F_FMAX, p] = Fn0
        if Fn0 >= cst[C_FRATIO] * fl[F_FMAX, p] and Fn0 > 0:
            ratio = Ft0 / Fn0
            fl[F_FMIN, p] = min(fl[F_FMIN, p], ratio)
            fl[F_FMAXR, p] = max(fl[F_FMAXR, p], ratio)
        xd0, xd1 = _xdot(Y, n), _xdot(Y1, n)
        lo = 0.0
        # first maximum compression inside this substep
        if not turned[p] and xd0 > 0 and xd1 <= 0:
            th = _root(0, code, lc, oc, p, n, T, W, Wc, a, paper, Lr, Y, hs, 0.0, 1.0, xd0, xd1, 1.0, 1.0, fz, tmp,
                       work, buf, riter, rtol)
            rk4(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, Y, th * hs, Yt, work, buf, True)
            turned[p] = True
            fl[F_TAU1, p] = t0 + t_loc + th * hs - fl[F_TONSET, p]
            fl[F_XTURN, p] = Yt[X]
            fl[F_XMAX, p] = max(fl[F_XMAX, p], Yt[X])
            fl[F_WELC, p] = Yt[WEL]
            fl[F_WVIC, p] = Yt[WVI]
            lo = th
        fl[F_XMAX, p] = max(fl[F_XMAX, p], Y1[X])
        # separation
        end = xd1 < 0 and Y1[X] < 0
        if fz and xd1 < 0 and indicator(code, lc, oc, p, max(Y1[X], 0.0), xd1) < 0:
            end = True
        if end:
            rk4(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, Y, lo * hs, Yt, work, buf, True)  # Ylo
            xs = Yt[X] if Yt[X] > 0 else 1.0
            Bs = abs(indicator(code, lc, oc, p, max(Yt[X], 0.0), _xdot(Yt, n)))
            if not Bs > 0:
                Bs = 1.0
            g_lo = _gfun(1, code, lc, oc, p, n, Yt, xs, Bs, fz)
            g_hi = _gfun(1, code, lc, oc, p, n, Y1, xs, Bs, fz)
            if not g_lo > 0:  # a substep that starts already past the event: end at its start
                g_lo = 1e-300
            th = _root(1, code, lc, oc, p, n, T, W, Wc, a, paper, Lr, Y, hs, lo, 1.0, g_lo, g_hi, xs, Bs, fz, tmp,
                       work, buf, riter, rtol)
            rk4(code, lc, oc, p, n, T, W, Wc, a, paper, Lr, Y, th * hs, Yt, work, buf, True)  # Ye
            by_force = False
            if fz:
                xde = _xdot(Yt, n)
                gb = indicator(code, lc, oc, p, max(Yt[X], 0.0), xde) / Bs if xde < 0 else math.inf
                by_force = gb < Yt[X] / xs
            for j in range(NY):
                y[j] = Yt[j]
            ints[3] += 1
            return True, END_FORCE if by_force else END_OVERLAP, t_loc + th * hs
        for j in range(NY):
            Y[j] = Y1[j]
        t_loc += hs
    for j in range(NY):
        y[j] = Y[j]
    return False, 0, dt


@jit
def advance(cst, pairs, n, T, W, Wc, a, paper, Lr, kg, codes, LC, oc, t0, dt, h, y, t_loc, in_c, status, ended_by,
            turned, fl, ints, buf, work, rows4):
    """Move every row through the rest of its step (module docstring, 2):
    status[r] = ST_ONSET (free flight reached an onset at t_loc[r]: the
    caller begins the contact, sets in_c[r], and calls again), ST_ENDED (the
    contact ended at t_loc[r], by ended_by[r]: the caller writes the record,
    clears in_c[r], and calls again) or ST_DONE (the step is over). Returns
    the number of rows stopped for the caller."""
    k = pairs.shape[0]
    stopped = 0
    for r in range(k):
        status[r] = ST_DONE
        if t_loc[r] >= dt:
            continue
        p = pairs[r]
        if not in_c[r]:
            tc = free_flight(n[r], a[r], Lr[r], y[r], dt - t_loc[r])
            if tc < math.inf:
                t_loc[r] += tc
                status[r] = ST_ONSET
                stopped += 1
            else:
                t_loc[r] = dt
            continue
        ended, by, tl = integrate_row(cst, codes[kg[r]], LC[kg[r]], oc, n[r], T[r], W[r], Wc[r], a[r], paper[r], Lr[r], p,
                                      y[r], t_loc[r], t0, dt, h[p], turned, fl, ints, buf, work, rows4)
        t_loc[r] = tl
        if ended:
            status[r] = ST_ENDED
            ended_by[r] = by
            stopped += 1
    return stopped


@jit
def finale(pairs, n, W, Wc, settled, in_c, y, dt, timing, kg, LC, active, x_state, xdot_state, s_state, vc_state,
           W_el, W_visc, Q_t, W_t, phase, outside, settled_state, Jst, dv_corr, dvc_corr, impulse, couple):
    """Write back the rows' state (ContactManager._step_group's end): the
    timing correction J = int (dt/2 - t) f dt / dt (0 for settled rows),
    the step's impulse P + J - J_previous into impulse (k, 3) [N s], and the
    angular impulse of the moving contact point n x PD / 2 into the pairs'
    couple (P, 3) [N m s] (LEVER_DOC; ContactManager.couple, written per pair
    like the other state)."""
    for r in range(pairs.shape[0]):
        p = pairs[r]
        lc = LC[kg[r]]
        rmin = min(lc[LC_RA], lc[LC_RB])
        msf_kp = int(lc[LC_KPMODE]) == KP_MSF
        yr = y[r]
        active[p] = in_c[r]
        x_state[p] = yr[X]
        xd = _xdot(yr, n[r])
        xdot_state[p] = xd
        for i in range(3):
            s_state[p, i] = yr[S + i]
            vc_state[p, i] = yr[VC + i]
        W_el[p], W_visc[p], Q_t[p], W_t[p] = yr[WEL], yr[WVI], yr[Q], yr[WT]
        phase[p] = 1 if xd < 0 else 0
        if msf_kp and in_c[r] and max(yr[X], 0.0) / rmin >= 2.0:
            outside[p] = True
        settled_state[p] = settled[r]
        corr = timing and not settled[r]
        J0 = yr[PI] / dt - 0.5 * yr[P] if corr else 0.0
        J1 = yr[PI + 1] / dt - 0.5 * yr[P + 1] if corr else 0.0
        J2 = yr[PI + 2] / dt - 0.5 * yr[P + 2] if corr else 0.0
        impulse[r, 0] = yr[P] + J0 - Jst[p, 0]
        impulse[r, 1] = yr[P + 1] + J1 - Jst[p, 1]
        impulse[r, 2] = yr[P + 2] + J2 - Jst[p, 2]
        nr = n[r]
        couple[p, 0] = 0.5 * (nr[1] * yr[PD + 2] - nr[2] * yr[PD + 1])
        couple[p, 1] = 0.5 * (nr[2] * yr[PD] - nr[0] * yr[PD + 2])
        couple[p, 2] = 0.5 * (nr[0] * yr[PD + 1] - nr[1] * yr[PD])
        Jst[p, 0], Jst[p, 1], Jst[p, 2] = J0, J1, J2
        for i in range(3):
            dv_corr[p, i] = W[r, i, 0] * J0 + W[r, i, 1] * J1 + W[r, i, 2] * J2
            dvc_corr[p, i] = Wc[r, i, 0] * J0 + Wc[r, i, 1] * J1 + Wc[r, i, 2] * J2


@jit
def check(pair, P, x, n, point, v, vc, W, Wc, a, active, Jst, seen, n_unit, point_state):
    """Validate the kinematics of one step (ContactManager.step's contract):
    returns (code, row): 0 ok; 1 a pair index outside [0, P); 2 a pair listed
    twice; 3 a non-finite value (row); 4 a normal that is not a unit vector;
    5 a required pair (in contact, or with a timing correction) not listed.
    seen (P,) bool: scratch. When valid, n_unit (k, 3) gets the normals
    renormalised and point_state (P, 3) the rows' contact points."""
    k = pair.shape[0]
    for q in range(P):
        seen[q] = False
    for r in range(k):
        q = pair[r]
        if q < 0 or q >= P:
            return 1, r
        if seen[q]:
            return 2, r
        seen[q] = True
        # NaN and inf propagate into the sum: one test per row, element by element only if it fails
        # (a finite sum that overflowed is not an error)
        tot = x[r]
        for i in range(3):
            tot += n[r, i] + point[r, i] + v[r, i] + vc[r, i] + a[r, i]
            for j in range(3):
                tot += W[r, i, j] + Wc[r, i, j]
        if not math.isfinite(tot):
            ok = math.isfinite(x[r])
            for i in range(3):
                ok = ok and math.isfinite(n[r, i]) and math.isfinite(point[r, i]) and math.isfinite(v[r, i])
                ok = ok and math.isfinite(vc[r, i]) and math.isfinite(a[r, i])
                for j in range(3):
                    ok = ok and math.isfinite(W[r, i, j]) and math.isfinite(Wc[r, i, j])
            if not ok:
                return 3, r
        nn = math.sqrt(n[r, 0] ** 2 + n[r, 1] ** 2 + n[r, 2] ** 2)
        if abs(nn - 1.0) > 1e-6:
            return 4, r
        for i in range(3):
            n_unit[r, i] = n[r, i] / nn
            point_state[q, i] = point[r, i]
    for q in range(P):
        if (active[q] or Jst[q, 0] != 0.0 or Jst[q, 1] != 0.0 or Jst[q, 2] != 0.0) and not seen[q]:
            return 5, q
    return 0, -1


@jit_inline
def _area(lc, x):
    """(41): S_x = pi k_pa k_pb sqrt(R_a R_b) x [m^2], k_p in the law's mode (clamped)."""
    mode = int(lc[LC_KPMODE])
    return math.pi * _kp(x, lc[LC_RA], mode) * _kp(x, lc[LC_RB], mode) * lc[LC_SRA] * lc[LC_SRB] * x


@jit
def peak_pressures(code, lc, oc, p, x_m, x_F, F_max, buf):
    """(20), (41) for a finished contact: P_c = 1.5 F_n(x_m, 0)/S(x_m) at the
    maximum compression x_m, and 1.5 F_max/S(x_F) at the peak force [Pa]
    (0 where x <= 0); as engines._contacts._pc."""
    Pc = 0.0
    if x_m > 0:
        forces(code, lc, oc, p, x_m, 0.0, buf)
        xa = min(x_m, 2.0 * math.sqrt(lc[LC_RA] * lc[LC_RB]) * (1.0 - 1e-12))
        Pc = 1.5 * buf[0] / _area(lc, xa)
    PcF = 1.5 * F_max / _area(lc, x_F) if x_F > 0 else 0.0
    return Pc, PcF


@njit(cache=True)
def required(active, Jst):
    """Indices of the pairs in contact or with a timing correction to remove
    (ContactManager.required_pairs), (m,) int64."""
    P = active.shape[0]
    out = np.empty(P, np.int64)
    m = 0
    for q in range(P):
        if active[q] or Jst[q, 0] != 0.0 or Jst[q, 1] != 0.0 or Jst[q, 2] != 0.0:
            out[m] = q
            m += 1
    return out[:m].copy()


@jit
def approach_rates(pair, v, dv_corr, a, n, xd0_new, an_new):
    """ContactManager._own_gaps' inputs for own_gaps, per row (k,):
    xd0_new = -(v - dv_corr[pair]) . n [m/s], the approach rate with the last
    timing correction taken out, and an_new = -a . n [m/s^2]. Each dot product
    summed as (u0 n0 + u2 n2) + u1 n1, the order numpy's einsum('ij,ij->i')
    sums three products in (its SIMD loop adds the lanes pairwise; measured
    equal on 10^6 random rows), so the compiled rows match the numpy form."""
    for i in range(pair.shape[0]):
        p = pair[i]
        u0, u1, u2 = v[i, 0] - dv_corr[p, 0], v[i, 1] - dv_corr[p, 1], v[i, 2] - dv_corr[p, 2]
        n0, n1, n2 = n[i, 0], n[i, 1], n[i, 2]
        xd0_new[i] = -((u0 * n0 + u2 * n2) + u1 * n1)
        an_new[i] = -((a[i, 0] * n0 + a[i, 2] * n2) + a[i, 1] * n1)


@jit
def own_gaps(pair, x, xm_state, active, listed, own_gap, xdot, xd0, an, off, xd0_new, an_new, dt, settle_rate,
             touch_tol, out):
    """ContactManager._own_gaps per row (its docstring; the same arithmetic in
    the same order): the gaps (k,) [m] the step starts from into ``out``; the
    per-pair bound ``off`` and the step start's ``xd0``, ``an`` (P,) updated
    in place from ``xd0_new``, ``an_new`` (k,) (computed by the caller, so the
    dot products stay numpy's). The pairs are distinct (check). Returns the
    number of rows that kept the manager's gap."""
    kept = 0
    half_dt = 0.5 * dt
    decay = 1.0 - settle_rate
    for i in range(pair.shape[0]):
        p = pair[i]
        xm = xm_state[p]
        act = active[p]
        lst = listed[p]
        lead = half_dt * (abs(xdot[p] - xd0[p]) + abs(an[p]) * dt)
        o = 0.0
        if lst:
            o = off[p] * (1.0 if act else decay) + lead
        own = own_gap[p] and not act and lst and abs(x[i] - xm) <= 2.0 * o + touch_tol
        off[p] = o if (act or own) else 0.0
        xd0[p] = xd0_new[i]
        an[p] = an_new[i]
        if own:
            g = xm + settle_rate * (x[i] - xm)
            out[i] = g if (g < 0.0 or g != g) else 0.0  # np.minimum(g, 0.0), NaN kept
            kept += 1
        else:
            out[i] = x[i]
    return kept


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__)


# --------------------------------------------- a lying side's end, row by row (issue 13) ---
# The walkers' resting step evaluated every law group's normal force and elastic energy in
# Python, one group at a time (engines._contacts.state.relax, ContactManager._resting). For the
# rows whose law is a lying side's end (CODE_SIDE, no ring: engines._narrow.SideEndLaw) these
# give the numpy methods' values bit for bit, all groups in one call: the same operations in the
# same order as SideEndLaw._parts (an array of approaches), _width_one (one approach, the
# numpy path of a call with one row) and MSFLaw.normal_force, and elastic_energy's 8-point sum
# as numpy sums a row of 8 (pairwise: ((0+1)+(2+3))+((4+5)+(6+7))); tests/test_rest_cost_paths.py.


@jit_inline
def _side_width_one(lc, x):
    """W_end [m] of engines._narrow.SideEndLaw._width_one at x [m] (its association of the sum)."""
    if x <= 0.0:
        return 0.0
    e, L, rise = lc[LC_SE], lc[LC_SL], lc[LC_SRISE]
    a = 2.0 * math.sqrt(max(x * (2.0 * lc[LC_SRW] - x), 0.0))
    rho0 = math.sqrt(max(x * (2.0 * e - x), 0.0))
    d, half = x - lc[LC_SDROP], 0.5 * L
    if rise > 0.0:
        ell = min(max(d / rise, 0.0), half)
    elif rise < 0.0:
        ell = half - min(max(d / rise, 0.0), half)
    else:
        ell = half if d > 0.0 else 0.0
    return 0.5 * ((1.0 - ell / L) * a + rho0 + max(rho0, ell))


@jit_inline
def _side_force(lc, E, eta, x, xd, one):
    """MSFLaw.contact_normal_force of a SideEndLaw at x [m], x' [m/s] (one: the numpy path of one
    row, _width_one; else the array path, _parts); of an MSFLaw point contact in kp mode msf
    when lc[LC_SE] is 0 (no side: its psi(x) sqrt(x), (37) with (29), as MSFLaw.normal_force)."""
    x = max(x, 0.0)
    if lc[LC_SE] == 0.0:
        F = (_kp(x, lc[LC_RA], KP_MSF) * lc[LC_SRA] + _kp(x, lc[LC_RB], KP_MSF) * lc[LC_SRB]) * math.sqrt(x) * (
            2.0 * eta * xd + (2.0 / 3.0) * E * x)
        return max(F, 0.0) if lc[LC_FZ] != 0.0 else F
    if one:
        W = _side_width_one(lc, x)
    else:
        wa, b = _side_parts(lc, x)
        W = 0.5 * (wa + b)
    F = W * (2.0 * eta * xd + (2.0 / 3.0) * E * x)
    return max(F, 0.0) if lc[LC_FZ] != 0.0 else F


@jit
def side_normal_forces(LC, kg, oc, p, x, one, out):
    """F_n(x, 0) [N] into out (k,) of rows p (k,) at x [m] (k,): their kernel groups kg (k,)
    (CODE_SIDE, no ring; or CODE_MSF in kp mode msf, with LC_SE 0), onset constants oc[p] (E,
    eta_E); one (k,) bool: the row was alone in its group's numpy call."""
    for r in range(x.shape[0]):
        q = p[r]
        out[r] = _side_force(LC[kg[r]], oc[q, 0], oc[q, 1], x[r], 0.0, one[r])


@jit
def side_elastic_energy(LC, kg, oc, p, x, s2, s, w, acc, out):
    """engines._contacts.state.elastic_energy [J] into out (k,) of rows p (k,) at x [m] (k,):
    their kernel groups kg (k,) (as side_normal_forces'), onset constants oc[p]; s2, s, w (8,): the
    Gauss-Legendre nodes squared, nodes and weights on [0, 1]; acc (8,) scratch."""
    for r in range(x.shape[0]):
        q = p[r]
        lc = LC[kg[r]]
        xr = x[r]
        for j in range(8):
            F = _side_force(lc, oc[q, 0], oc[q, 1], xr * s2[j], 0.0, False)
            acc[j] = F * (2.0 * xr * s[j]) * w[j]
        out[r] = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
