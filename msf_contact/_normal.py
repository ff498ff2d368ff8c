"""Integration of an isolated normal impact m x'' = -F_n(x, x').

Private: used by the laws (self-consistent frequency) and by the reference
solver. The force is written F_n = S(x) * B(x, x') with S >= 0 vanishing at
x = 0 and B the *separation indicator*: the force-zero rule ends the
contact where B changes sign in restitution, a smooth event even where
S(x) ~ sqrt(x) is not.

Also the integrator of the reference solver, :func:`dop853`: scipy's DOP853
scheme (tableau, error norm, step-size control, event location) without
solve_ivp's per-step overhead, ~3x cheaper per step for these small systems
(issue 5; tests/test_solver_speed_paths.py holds it to solve_ivp).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import DOP853 as _DOP853
from scipy.optimize import brentq, minimize_scalar

#: Relative tolerance of the reference integration. COR, tau, x_max and
#: F_max must converge to 1e-6 relative (issue 2); 1e-11 leaves 5 orders.
RTOL = 1e-11
#: Absolute tolerance in units of the scales x_s, v_0 (see below).
ATOL_SCALED = 1e-13

SEPARATIONS = ("force-zero", "overlap-zero")


@dataclass(frozen=True)
class NormalSolution:
    """Result of one normal impact. Times [s], lengths [m], speeds [m/s], N."""

    tau: float  #: contact duration
    tau1: float  #: compression time (x' = 0)
    x_max: float  #: maximum approach
    v_out: float  #: separation speed (>= 0, away from the surface)
    F_max: float  #: peak normal force
    t: np.ndarray  #: dense samples of time (k,)
    x: np.ndarray  #: approach at t (k,)
    xdot: np.ndarray  #: approach rate at t (k,)
    ended_by: str  #: "force-zero", "overlap-zero" or "capture" (never separated)
    v_in: float  #: impact speed
    dense: object = None  #: scipy dense output (t -> [x, x']) over the contact

    @property
    def cor(self) -> float:
        return self.v_out / self.v_in


def integrate_normal(
    force: Callable[[float, float], float],
    indicator: Callable[[float, float], float],
    mass: float,
    v0: float,
    x_scale: float,
    separation: str = "force-zero",
    n_samples: int = 0,
    x_limit: float | None = None,
) -> NormalSolution:
    """Integrate from x = 0, x' = v0 > 0 until separation.

    force(x, xdot) -> F_n [N] (signed; clamped at 0 here in force-zero mode),
    indicator(x, xdot) -> B (sign of the force bracket), mass [kg], v0 [m/s],
    x_scale [m]: a length of the order of x_max (sets the tolerances and the
    time horizon). x_limit [m]: the largest approach the law is defined for
    (2R for the msf k_p of (15)); reaching it raises ValueError.
    """
    clamp = separation == "force-zero"
    t_scale = x_scale / v0

    def rhs(t, s):
        x, v = s
        F = force(max(x, 0.0), v)
        if clamp and F < 0.0:
            F = 0.0
        return (v, -F / mass)

    def ev_turn(t, s):
        return s[1]

    ev_turn.direction = -1

    def ev_overlap(t, s):
        return s[0]

    ev_overlap.terminal = True
    ev_overlap.direction = -1

    def ev_force(t, s):
        # only in restitution (x' < 0); +1 in compression so no false root
        return indicator(max(s[0], 0.0), s[1]) if s[1] < 0 else 1.0

    ev_force.terminal = True
    ev_force.direction = -1

    def ev_limit(t, s):
        return x_limit - s[0]

    ev_limit.terminal = True
    events = [ev_turn, ev_overlap] + ([ev_force] if clamp else [])
    if x_limit is not None:
        events.append(ev_limit)
    t_end = 1e3 * t_scale
    sol = dop853(rhs, (0.0, t_end), (0.0, v0), rtol=RTOL, atol=(ATOL_SCALED * x_scale, ATOL_SCALED * v0),
                 events=events, first_step=1e-6 * t_scale)
    if sol.status == -1:
        raise RuntimeError(f"normal impact integration failed: {sol.message}")
    if x_limit is not None and len(sol.t_events[-1]):
        raise ValueError(
            f"the approach reached x = {x_limit:.6g} m = 2R before maximum compression: k_p = sqrt(2 - x/R) "
            "of (15) has no real value beyond; the impact is outside the msf geometry (lower the speed)"
        )
    t_turn = sol.t_events[0]
    if len(t_turn) == 0:
        raise RuntimeError("normal impact never reached maximum compression")
    tau1 = float(t_turn[0])
    x_max = float(sol.y_events[0][0][0])
    ended = None
    t_end_c = None
    v_end = None
    for k, name in ((1, "overlap-zero"), (2, "force-zero")):
        if k < len(sol.t_events) and events[k] in (ev_overlap, ev_force) and len(sol.t_events[k]):
            tk = float(sol.t_events[k][0])
            if t_end_c is None or tk < t_end_c:
                t_end_c, ended, v_end = tk, name, float(sol.y_events[k][0][1])
    if ended is None:
        # captured: never separated within the horizon (overdamped)
        t_end_c, ended, v_end = float(sol.t[-1]), "capture", 0.0
    # peak force: the largest on the accepted steps, refined on the dense output
    xs, vs = sol.y
    F_steps = np.array([force(max(a, 0.0), b) for a, b in zip(xs.tolist(), vs.tolist())])
    F_max = _refine_peak(force, sol, int(np.argmax(F_steps)), float(np.max(np.maximum(F_steps, 0.0))))
    if n_samples > 0:
        t = np.linspace(0.0, t_end_c, n_samples)
        xx, vv = sol.sol(t)
        xx = np.maximum(xx, 0.0)
        Fs = np.array([force(a, b) for a, b in zip(xx.tolist(), vv.tolist())])
        F_max = max(F_max, float(np.max(Fs)))
    else:
        t, xx, vv = sol.t, np.maximum(xs, 0.0), vs
    return NormalSolution(
        tau=t_end_c, tau1=tau1, x_max=x_max, v_out=max(-v_end, 0.0), F_max=F_max,
        t=np.asarray(t), x=np.asarray(xx), xdot=np.asarray(vv), ended_by=ended, v_in=v0, dense=sol.sol,
    )


#: Peak-time resolution of the force maximum, relative to the step bracket
#: around it: F is flat at its peak, so F_max is then exact to rounding.
PEAK_XATOL = 1e-14


def _refine_peak(force, sol, k, F_guess):
    """The force maximum [N] between the accepted steps k - 1 and k + 1 around
    the largest step sample k (F is unimodal in an impact), by a bounded
    Brent search on the dense output; never below F_guess."""
    ts = sol.t
    lo, hi = float(ts[max(k - 1, 0)]), float(ts[min(k + 1, len(ts) - 1)])
    if hi <= lo:
        return F_guess

    def minus_force(t):
        x, v = sol.sol(t).tolist()
        return -force(max(x, 0.0), v)

    res = minimize_scalar(minus_force, bounds=(lo, hi), method="bounded",
                          options={"xatol": PEAK_XATOL * max(hi, 1e-300)})
    return max(F_guess, float(-res.fun))


# ----------------------------------------------------------- integrator ---
#: scipy's RungeKutta step-size control (scipy/integrate/_ivp/rk.py), kept
#: identical so that :func:`dop853` takes the steps solve_ivp's DOP853 takes.
_SAFETY, _MIN_FACTOR, _MAX_FACTOR = 0.9, 0.2, 10.0
_ERROR_EXPONENT = -1.0 / (_DOP853.error_estimator_order + 1)
_NS = _DOP853.n_stages  # 12 stages; K has a 13th row for f(t + h, y_new)
_A, _B, _C = _DOP853.A, _DOP853.B, _DOP853.C
_E3, _E5, _D = _DOP853.E3, _DOP853.E5, _DOP853.D
_A_EXTRA, _C_EXTRA = _DOP853.A_EXTRA, _DOP853.C_EXTRA
#: Row s < 12: [1, A[s, :s], 0...] (stage s); row 12: [1, B] (the new y); times h
#: except column 0 in each step.
_COEF = np.zeros((_NS + 1, _NS + 2))
_COEF[:_NS, 1:_NS + 1] = _A
_COEF[_NS, 1:_NS + 1] = _B
#: The two error estimates of DOP853 (E5, E3) as rows, applied to K (13, n) at once.
_E53 = np.stack((_E5, _E3))
#: Event roots to within 4 machine epsilons, as solve_ivp's solve_event_equation.
_EVENT_XTOL = 4 * np.finfo(float).eps


def _dense_weights(x):
    """DOP853 dense-output weights at the step fraction x (scalar or (m,)):
    (x, x u, x^2 u, x^2 u^2, x^3 u^2, x^3 u^3, x^4 u^3) with u = 1 - x, shape x.shape + (7,)."""
    u = 1.0 - x
    w1 = x * u
    w2 = w1 * x
    w3 = w2 * u
    w4 = w3 * x
    w5 = w4 * u
    return np.stack((x, w1, w2, w3, w4, w5, w5 * x), axis=-1)


class Trajectory:
    """Result of :func:`dop853`, shaped like solve_ivp's: ``t`` (k,) [time unit
    of the problem], ``y`` (n, k) at the accepted steps (the last point is a
    terminal event's root), ``t_events``/``y_events`` per event, ``status``
    (0 end of span, 1 terminal event, -1 failure), ``message``, and
    :meth:`sol`, the DOP853 dense output (7th order) over the whole span."""

    def __init__(self, fun, n):
        self._fun = fun
        self._steps = []  # (t_old, t_new, y_old, y_new, K (13, n)) per accepted step
        self._F = []  # interpolation coefficients per step, built on first use
        self._t_new = []
        self.n = n
        self.t_events, self.y_events = [], []
        self.status, self.message = None, ""
        self.t = self.y = None

    def _add(self, t_old, t_new, y_old, y_new, K):
        self._steps.append((t_old, t_new, y_old, y_new, K))
        self._F.append(None)
        self._t_new.append(t_new)

    def _coefficients(self, i):
        """Dop853DenseOutput's F (7, n) of step i: three extra stages of the
        extended tableau, as scipy's DOP853._dense_output_impl."""
        F = self._F[i]
        if F is None:
            t_old, t_new, y_old, y_new, K13 = self._steps[i]
            h = t_new - t_old
            K = np.empty((_NS + 4, self.n))
            K[: _NS + 1] = K13
            for s, (a, c) in enumerate(zip(_A_EXTRA, _C_EXTRA), start=_NS + 1):
                dy = np.dot(K[:s].T, a[:s]) * h
                K[s] = self._fun(t_old + c * h, (y_old + dy).tolist())
            F = np.empty((7, self.n))
            delta_y = y_new - y_old
            F[0] = delta_y
            F[1] = h * K[0] - delta_y
            F[2] = 2 * delta_y - h * (K[_NS] + K[0])
            F[3:] = h * np.dot(_D, K)
            self._F[i] = F
        return F

    def _step_value(self, i, t):
        """y(t) (n,) on step i for a scalar t."""
        t_old, t_new, y_old, _, _ = self._steps[i]
        return y_old + _dense_weights((t - t_old) / (t_new - t_old)) @ self._coefficients(i)

    def sol(self, t):
        """Dense output: y (n,) for a scalar t, (n, m) for t of shape (m,)."""
        t = np.asarray(t, dtype=float)
        last = len(self._steps) - 1
        seg = np.clip(np.searchsorted(self._t_bounds, t, side="left") - 1, 0, last)
        if t.ndim == 0:
            return self._step_value(int(seg), float(t))
        used = np.unique(seg)
        F = np.stack([self._coefficients(i) for i in used.tolist()])  # (k, 7, n)
        pick = np.searchsorted(used, seg)
        t_old, t_new = self._t_bounds[:-1][seg], self._t_bounds[1:][seg]
        W = _dense_weights((t - t_old) / (t_new - t_old))  # (m, 7)
        y_old = np.stack([self._steps[i][2] for i in used.tolist()])[pick]
        return (y_old + np.einsum("mk,mkn->mn", W, F[pick])).T

    def _finish(self, ts, ys, status, message=""):
        self.t = np.array(ts)
        self.y = np.array(ys).T
        self._t_bounds = np.array([self._steps[0][0]] + self._t_new) if self._steps else np.array(ts[:1])
        self.status, self.message = status, message
        return self


def _crossed(g_old, g_new, direction):
    """The event went through zero in its direction over the step, as solve_ivp's find_active_events."""
    up = g_old <= 0 <= g_new
    down = g_old >= 0 >= g_new
    return (up and direction >= 0) or (down and direction <= 0)


def dop853(fun, t_span, y0, *, rtol, atol, first_step, events=(), max_steps=None):
    """Integrate y' = fun(t, y) with scipy's DOP853 scheme and events.

    The same Runge-Kutta pair, error norm, step-size control, event location
    (brentq on the dense output to 4 machine epsilons) and event semantics
    (``terminal``, ``direction`` attributes) as ``solve_ivp(method="DOP853")``,
    without its per-step overhead: ``fun(t, y)`` gets y as a list of floats
    and returns a sequence of floats, and the dense output of a step is built
    only where an event or :meth:`Trajectory.sol` needs it. Units are those of
    the problem; atol is a scalar or (n,) in the units of y. ``max_steps``
    bounds the work: more accepted steps end with status -1 and a message
    naming the bound.
    """
    t, t_bound = float(t_span[0]), float(t_span[1])
    y = np.array(y0, dtype=float)
    n = y.size
    atol = np.broadcast_to(np.asarray(atol, dtype=float), (n,))
    out = Trajectory(fun, n)
    f = np.array(fun(t, y.tolist()), dtype=float)
    h_abs = float(first_step)
    directions = [getattr(e, "direction", 0) for e in events]
    terminal = [bool(getattr(e, "terminal", False)) for e in events]
    out.t_events = [[] for _ in events]
    out.y_events = [[] for _ in events]
    g = [e(t, y.tolist()) for e in events]
    ts, ys = [t], [y]
    # Stage s of a step is Ky[:s + 1]^T @ [1, h A[s, :s]] with Ky = [y, K_0, ..., K_12]:
    # one dot product per stage; the views are made once.
    Ky = np.empty((_NS + 2, n))
    K = Ky[1:]
    stage_in = [Ky[: s + 1].T for s in range(_NS + 1)]
    coef = np.empty_like(_COEF)
    coef_rows = [coef[s, : s + 1] for s in range(_NS + 1)]
    c_rows = _C.tolist()
    while True:
        if max_steps is not None and len(ts) > max_steps:
            return out._finish(ts, ys, -1, f"more than max_steps = {max_steps} steps (the integration's work bound)")
        min_step = 10 * abs(np.nextafter(t, np.inf) - t)
        h_abs = max(h_abs, min_step)
        rejected = False
        Ky[0] = y
        K[0] = f
        while True:
            if h_abs < min_step:
                return out._finish(ts, ys, -1, "Required step size is less than spacing between numbers.")
            t_new = t + h_abs
            if t_new > t_bound:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            np.multiply(_COEF, h, out=coef)
            coef[:, 0] = 1.0
            for s in range(1, _NS):
                K[s] = fun(t + c_rows[s] * h, np.dot(stage_in[s], coef_rows[s]).tolist())
            y_new = np.dot(stage_in[_NS], coef_rows[_NS])
            y_list = y_new.tolist()
            K[_NS] = fun(t_new, y_list)
            scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
            err = np.dot(_E53, K) / scale
            e5, e3 = np.einsum("ij,ij->i", err, err).tolist()
            if e5 == 0.0 and e3 == 0.0:
                error_norm = 0.0
            else:
                error_norm = h_abs * e5 / math.sqrt((e5 + 0.01 * e3) * n)
            if error_norm < 1.0:
                factor = _MAX_FACTOR if error_norm == 0.0 else min(_MAX_FACTOR, _SAFETY * error_norm**_ERROR_EXPONENT)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                break
            h_abs *= max(_MIN_FACTOR, _SAFETY * error_norm**_ERROR_EXPONENT)
            rejected = True
        out._add(t, t_new, y, y_new, K.copy())
        f = K[-1].copy()
        t_old, t, y = t, t_new, y_new
        status = 0 if t == t_bound else None
        if events:
            g_new = [e(t, y_list) for e in events]
            active = [k for k, (a, b, d) in enumerate(zip(g, g_new, directions)) if _crossed(a, b, d)]
            if active:
                i = len(out._steps) - 1
                roots = sorted(
                    (brentq(lambda tt, e=events[k]: e(tt, out._step_value(i, tt).tolist()), t_old, t,
                            xtol=_EVENT_XTOL, rtol=_EVENT_XTOL), k) for k in active)
                if any(terminal[k] for k in active):
                    first = next(j for j, (_, k) in enumerate(roots) if terminal[k])
                    roots = roots[: first + 1]
                    status = 1
                for r, k in roots:
                    out.t_events[k].append(r)
                    out.y_events[k].append(out._step_value(i, r))
                if status == 1:
                    t = roots[-1][0]
                    y = out._step_value(i, t)
            g = g_new
        ts.append(t)
        ys.append(y)
        if status is not None:
            out.t_events = [np.array(v) for v in out.t_events]
            out.y_events = [np.array(v) if v else np.empty((0, n)) for v in out.y_events]
            return out._finish(ts, ys, status, "A termination event occurred." if status == 1 else "")
