"""Integration of an isolated normal impact m x'' = -F_n(x, x').

Private: used by the laws (self-consistent frequency) and by the reference
solver. The force is written F_n = S(x) * B(x, x') with S >= 0 vanishing at
x = 0 and B the *separation indicator*: the force-zero rule ends the
contact where B changes sign in restitution, a smooth event even where
S(x) ~ sqrt(x) is not.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp

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
    sol = solve_ivp(
        rhs,
        (0.0, t_end),
        (0.0, v0),
        method="DOP853",
        rtol=RTOL,
        atol=(ATOL_SCALED * x_scale, ATOL_SCALED * v0),
        events=events,
        dense_output=True,
        first_step=1e-6 * t_scale,
    )
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
    # peak force on the accepted steps, refined on dense samples if requested
    xs, vs = sol.y
    F_steps = np.array([force(max(a, 0.0), b) for a, b in zip(xs, vs)])
    F_max = float(np.max(np.maximum(F_steps, 0.0)))
    if n_samples > 0:
        t = np.linspace(0.0, t_end_c, n_samples)
        xx, vv = sol.sol(t)
        xx = np.maximum(xx, 0.0)
        Fs = np.array([force(a, b) for a, b in zip(xx, vv)])
        F_max = max(F_max, float(np.max(Fs)))
    else:
        t, xx, vv = sol.t, np.maximum(xs, 0.0), vs
    F_max = _refine_peak(force, sol, t_end_c, F_max)
    return NormalSolution(
        tau=t_end_c, tau1=tau1, x_max=x_max, v_out=max(-v_end, 0.0), F_max=F_max,
        t=np.asarray(t), x=np.asarray(xx), xdot=np.asarray(vv), ended_by=ended, v_in=v0, dense=sol.sol,
    )


def _refine_peak(force, sol, t_end, F_guess):
    from scipy.optimize import minimize_scalar

    ts = np.linspace(0, t_end, 400)
    xx, vv = sol.sol(ts)
    Fs = np.array([force(max(a, 0.0), b) for a, b in zip(xx, vv)])
    k = int(np.argmax(Fs))
    lo, hi = ts[max(k - 1, 0)], ts[min(k + 1, len(ts) - 1)]
    res = minimize_scalar(
        lambda t: -force(max(float(sol.sol(t)[0]), 0.0), float(sol.sol(t)[1])),
        bounds=(lo, hi), method="bounded", options={"xatol": 1e-14 * max(t_end, 1e-300)},
    )
    return max(F_guess, float(-res.fun))
