"""The isolated normal impact of a kernel law, compiled (numba): the onset of
:class:`engines._narrow.SideEndLaw` (a lying side's MSF line law, which has
no dimensionless family to tabulate: its W(x) mixes sqrt(x), x and the
pose's kinks) solves its self-consistent omega_x of (46) with this.

:func:`impact` is :func:`msf_contact._normal.integrate_normal` for a law of
:mod:`engines._kernel` (``forces``/``indicator`` with the law's constants
``lc`` and onset constants E', eta'_E): m x'' = -F_n(x, x') from x = 0,
x' = v0 until separation, integrated with the same scheme as
:func:`msf_contact._normal.dop853` (scipy's DOP853 tableau, error norm and
step-size control; the same rtol, atol, first step and horizon; the events
located on the DOP853 dense output to 4 machine epsilons, by bisection in
place of brentq). So it takes the same steps and gives the same tau, x_max
and v_out up to the rounding of the sums' order (tests/test_narrow_mujoco.py
holds SideEndLaw.onset to onset_reference, the Python integration). What
the onset does not need is left out: the samples and the peak force.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from msf_contact import _normal as N

from . import _kernel as K
from msf_contact._jitcache import guard as _guard

_A, _B, _C = np.ascontiguousarray(N._A), np.ascontiguousarray(N._B), np.ascontiguousarray(N._C)
_E3, _E5, _D = np.ascontiguousarray(N._E3), np.ascontiguousarray(N._E5), np.ascontiguousarray(N._D)
_A_EXTRA, _C_EXTRA = np.ascontiguousarray(N._A_EXTRA), np.ascontiguousarray(N._C_EXTRA)
_NS = N._NS
_SAFETY, _MIN_FACTOR, _MAX_FACTOR, _ERROR_EXPONENT = N._SAFETY, N._MIN_FACTOR, N._MAX_FACTOR, N._ERROR_EXPONENT
_RTOL, _ATOL_SCALED, _EVENT_XTOL = N.RTOL, N.ATOL_SCALED, N._EVENT_XTOL
#: Bisection steps of an event root: the bracket (one accepted step) halves
#: to 4 machine epsilons of t well before this bound.
_ROOT_ITER = 200

# results of impact(): out[...] and the status it returns
R_TAU, R_TAU1, R_XMAX, R_VOUT, R_ENDED = range(5)
NR = 5
OK, FAILED, LIMIT, NO_TURN = 0, 1, 2, 3
# ended_by codes in out[R_ENDED]
ENDED_FORCE, ENDED_OVERLAP, ENDED_CAPTURE = 0.0, 1.0, 2.0
# events, as integrate_normal's: maximum compression, overlap zero, force zero, the law's x limit
EV_TURN, EV_OVERLAP, EV_FORCE, EV_LIMIT = range(4)


@njit(cache=True)
def _accel(code, lc, oc, mass, x, v, buf):
    """x'' = -F_n / m [m/s^2]: integrate_normal's rhs (the force at max(x, 0), clamped at 0 in force-zero mode)."""
    K.forces(code, lc, oc, 0, max(x, 0.0), v, buf)
    F = buf[0]
    if lc[K.LC_FZ] != 0.0 and F < 0.0:
        F = 0.0
    return -F / mass


@njit(cache=True)
def _event(k, code, lc, oc, x, v, x_limit):
    """Event function k at (x, v), as integrate_normal's ev_*."""
    if k == EV_TURN:
        return v
    if k == EV_OVERLAP:
        return x
    if k == EV_FORCE:
        return K.indicator(code, lc, oc, 0, max(x, 0.0), v) if v < 0.0 else 1.0
    return x_limit - x


@njit(cache=True)
def _dense(Fd, y_old, th, out):
    """DOP853 dense output at the step fraction th: y_old + weights(th) . F (msf_contact._normal._dense_weights)."""
    u = 1.0 - th
    w1 = th * u
    w2 = w1 * th
    w3 = w2 * u
    w4 = w3 * th
    w5 = w4 * u
    w6 = w5 * th
    for j in range(2):
        out[j] = y_old[j] + (th * Fd[0, j] + w1 * Fd[1, j] + w2 * Fd[2, j] + w3 * Fd[3, j] + w4 * Fd[4, j]
                             + w5 * Fd[5, j] + w6 * Fd[6, j])


@njit(cache=True)
def impact(code, lc, oc, mass, v0, x_scale, x_limit, out):
    """Integrate one normal impact (module docstring). code, lc: the law
    (engines._kernel); oc (1, NOC): E' [Pa], eta'_E [Pa s] in columns 0, 1
    (others unused); mass [kg], v0 [m/s] > 0, x_scale [m] (the law's
    hertz_scale), x_limit [m] (<= 0: none). Writes out (NR,): tau, tau1 [s],
    x_max [m], v_out [m/s] (>= 0), the ended_by code; returns OK, FAILED
    (step size underflow), LIMIT (x reached x_limit) or NO_TURN."""
    buf = np.empty(6)
    fz = lc[K.LC_FZ] != 0.0
    n_ev = 4 if x_limit > 0.0 else 3
    direction = np.array([-1.0, -1.0, -1.0, 0.0])
    terminal = np.array([False, True, True, True])
    use = np.array([True, True, fz, x_limit > 0.0])
    t_scale = x_scale / v0
    t_bound = 1e3 * t_scale
    atol0, atol1 = _ATOL_SCALED * x_scale, _ATOL_SCALED * v0
    t = 0.0
    y = np.array([0.0, v0])
    Kst = np.empty((_NS + 4, 2))  # DOP853's 13 stages and the dense output's 3 extra
    f0, f1 = y[1], _accel(code, lc, oc, mass, y[0], y[1], buf)
    h_abs = 1e-6 * t_scale
    g = np.empty(4)
    g_new = np.empty(4)
    for k in range(n_ev):
        g[k] = _event(k, code, lc, oc, y[0], y[1], x_limit)
    y_new = np.empty(2)
    ys = np.empty(2)
    Fd = np.empty((7, 2))
    t_ev = np.full(4, np.nan)
    x_ev = np.full(4, np.nan)
    v_ev = np.full(4, np.nan)
    while True:
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        h_abs = max(h_abs, min_step)
        rejected = False
        Kst[0, 0], Kst[0, 1] = f0, f1
        while True:
            if h_abs < min_step:
                return FAILED
            t_new = t + h_abs
            if t_new > t_bound:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            for s in range(1, _NS):
                d0 = 0.0
                d1 = 0.0
                for j in range(s):
                    d0 += Kst[j, 0] * _A[s, j]
                    d1 += Kst[j, 1] * _A[s, j]
                xs, vs = y[0] + h * d0, y[1] + h * d1
                Kst[s, 0], Kst[s, 1] = vs, _accel(code, lc, oc, mass, xs, vs, buf)
            d0 = 0.0
            d1 = 0.0
            for j in range(_NS):
                d0 += Kst[j, 0] * _B[j]
                d1 += Kst[j, 1] * _B[j]
            y_new[0], y_new[1] = y[0] + h * d0, y[1] + h * d1
            Kst[_NS, 0], Kst[_NS, 1] = y_new[1], _accel(code, lc, oc, mass, y_new[0], y_new[1], buf)
            e5 = 0.0
            e3 = 0.0
            for i in range(2):
                sc = (atol0 if i == 0 else atol1) + max(abs(y[i]), abs(y_new[i])) * _RTOL
                a5 = 0.0
                a3 = 0.0
                for j in range(_NS + 1):
                    a5 += _E5[j] * Kst[j, i]
                    a3 += _E3[j] * Kst[j, i]
                e5 += (a5 / sc) ** 2
                e3 += (a3 / sc) ** 2
            if e5 == 0.0 and e3 == 0.0:
                error_norm = 0.0
            else:
                error_norm = h_abs * e5 / math.sqrt((e5 + 0.01 * e3) * 2.0)
            if error_norm < 1.0:
                if error_norm == 0.0:
                    factor = _MAX_FACTOR
                else:
                    factor = min(_MAX_FACTOR, _SAFETY * error_norm ** _ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(_MIN_FACTOR, _SAFETY * error_norm ** _ERROR_EXPONENT)
            rejected = True
        t_old = t
        y_old0, y_old1 = y[0], y[1]
        t = t_new
        y[0], y[1] = y_new[0], y_new[1]
        f0, f1 = Kst[_NS, 0], Kst[_NS, 1]
        done = t == t_bound
        first_root = math.inf
        dense_ready = False
        for k in range(n_ev):
            if not use[k]:
                continue
            g_new[k] = _event(k, code, lc, oc, y[0], y[1], x_limit)
            a, b = g[k], g_new[k]
            crossed = ((a <= 0.0 <= b) and direction[k] >= 0.0) or ((a >= 0.0 >= b) and direction[k] <= 0.0)
            g[k] = b
            if not crossed:
                continue
            if not dense_ready:  # Dop853DenseOutput's F of this step (three extra stages)
                for s in range(_NS + 1, _NS + 4):
                    a_row = _A_EXTRA[s - _NS - 1]
                    d0 = 0.0
                    d1 = 0.0
                    for j in range(s):
                        d0 += Kst[j, 0] * a_row[j]
                        d1 += Kst[j, 1] * a_row[j]
                    xs, vs = y_old0 + h * d0, y_old1 + h * d1
                    Kst[s, 0], Kst[s, 1] = vs, _accel(code, lc, oc, mass, xs, vs, buf)
                for j in range(2):
                    dy = y[j] - (y_old0 if j == 0 else y_old1)
                    Fd[0, j] = dy
                    Fd[1, j] = h * Kst[0, j] - dy
                    Fd[2, j] = 2.0 * dy - h * (Kst[_NS, j] + Kst[0, j])
                    for r in range(4):
                        acc = 0.0
                        for q in range(_NS + 4):
                            acc += _D[r, q] * Kst[q, j]
                        Fd[3 + r, j] = h * acc
                dense_ready = True
            y_o = np.array([y_old0, y_old1])
            lo, hi, g_lo = t_old, t, a
            for _ in range(_ROOT_ITER):  # bisection of the sign change to 4 eps (brentq's xtol, rtol)
                if hi - lo <= _EVENT_XTOL + _EVENT_XTOL * abs(lo):
                    break
                mid = 0.5 * (lo + hi)
                _dense(Fd, y_o, (mid - t_old) / h, ys)
                gm = _event(k, code, lc, oc, ys[0], ys[1], x_limit)
                if (gm <= 0.0) == (g_lo <= 0.0) and gm != 0.0:
                    lo, g_lo = mid, gm
                else:
                    hi = mid
            root = hi if g_lo != 0.0 else lo
            _dense(Fd, y_o, (root - t_old) / h, ys)
            if math.isnan(t_ev[k]):
                t_ev[k], x_ev[k], v_ev[k] = root, ys[0], ys[1]
            if terminal[k] and root < first_root:
                first_root = root
        # a terminal event ends the integration; non-terminal roots after it do not count
        if first_root < math.inf:
            for k in range(n_ev):
                if not math.isnan(t_ev[k]) and t_ev[k] > first_root:
                    t_ev[k] = np.nan
            done = True
        if done:
            break
    if not math.isnan(t_ev[EV_LIMIT]):
        return LIMIT
    if math.isnan(t_ev[EV_TURN]):
        return NO_TURN
    out[R_TAU1], out[R_XMAX] = t_ev[EV_TURN], x_ev[EV_TURN]
    ended, t_end, v_end = ENDED_CAPTURE, t, 0.0
    if not math.isnan(t_ev[EV_OVERLAP]):
        ended, t_end, v_end = ENDED_OVERLAP, t_ev[EV_OVERLAP], v_ev[EV_OVERLAP]
    if not math.isnan(t_ev[EV_FORCE]) and (ended == ENDED_CAPTURE or t_ev[EV_FORCE] < t_end):
        ended, t_end, v_end = ENDED_FORCE, t_ev[EV_FORCE], v_ev[EV_FORCE]
    out[R_TAU], out[R_VOUT], out[R_ENDED] = t_end, max(-v_end, 0.0), ended
    return OK


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__, K, N)
