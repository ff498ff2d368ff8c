"""Reference for coupled contacts: a collinear chain of spheres, one ODE.

N spheres on one axis (body 0 first), contact k between bodies k and k + 1
with its own law, and optionally a fixed plate after the last body (a
sphere pressed between a sphere and a plate). Every contact's force acts on
both its bodies at every instant: the ground truth for Newton's cradles,
stacks and a ball on a plate struck by another, where an engine must solve
the contacts of an island together (issue 10).

Equations (displacements d_i of the centres along the axis, [m]):

    m_i d_i''  = F_{i-1} - F_i + m_i a              (45) for each body
    x_k        = x_k(0) + d_k - d_{k+1}             approach of contact k
    F_k        = law_k.contact_normal_force(x_k, x_k', onset_k)  while in contact, else 0

(for the plate contact d_{N} = 0; a [m/s^2] a uniform acceleration along the
axis, e.g. gravity toward the plate). Integrated as one ODE with the
reference solver's integrator and tolerances (``_normal.dop853``, ``RTOL``,
``ATOL_SCALED`` in the scales x_s, v_s of the fastest first contact).

Contact episodes follow the engines' rules (``engines/_contacts.py``) so the
two are comparable: a contact begins where x >= 0 with a closing speed (an
event x = 0 crossed upward, or x' = 0 crossed upward in overlap after a
force-zero end); its onset constants are ``law.onset_reference`` at the
closing speed then, raised to :func:`onset_speed_floor`, with the reduced
mass of its two bodies (the diagonal block 1/(n W n) of the engines); it
ends by force-zero (the separation indicator B < 0 in restitution) or by
overlap-zero (x back to 0). Contacts touching at t = 0 (x >= 0) begin at
t = 0 with their closing speed then (0 for a touching cradle: the floor).

Energy: the works W_el = int F_el x' dt and W_visc = int (F_n - F_el) x' dt
of every contact are integrated with the motion, so kinetic + potential +
sum W = E_0 holds to the integration tolerance (checked in the result), and
the energy E = kinetic + potential + elastic energy stored in the open
contacts never exceeds E_0 for laws whose damping dissipates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ._normal import ATOL_SCALED, RTOL, dop853
from ._validate import check_finite, check_positive, small_strain_note
from .geometry import area
from .laws import ForceLaw
from .record import ImpactRecord
from .solver import Body, _refine_max, _scalar_kernels, reduced_mass

#: Smallest onset speed used for the onset constants [m/s] with no external
#: closing acceleration: the engines' floor (``engines._contacts``), so a
#: contact that begins at rest (a touching cradle) has the same constants here.
V_ONSET_MIN = 1e-6
#: Guard on the number of contact onsets and ends in one chain impact.
MAX_EVENTS = 2000
#: Horizon of a segment without contact events when no end time is given,
#: in units of the first contact's time scale x_s/v_s.
HORIZON_SCALES = 1e4
#: Energy bookkeeping closes to this share of the initial energy scale
#: (RTOL 1e-11 per step over ~1e3-1e4 steps; checked in every result).
ENERGY_CLOSURE_RTOL = 1e-7


def onset_speed_floor(law: ForceLaw, m_eff, a_n) -> np.ndarray:
    """Smallest onset speed used for the onset constants [m/s] (n,).

    sqrt(2 a_n x_s): the speed gained falling through the static overlap x_s,
    where the elastic force 2/3 E' psi(0) x_s^(3/2) of (29) balances m a_n
    (a_n [m/s^2]: external closing acceleration along the normal, m_eff [kg]);
    at least V_ONSET_MIN. A contact that begins slower is settling under a_n:
    its damping is then that of a contact at this speed, not an unbounded one.
    """
    m = np.asarray(m_eff, dtype=float)
    a = np.maximum(np.asarray(a_n, dtype=float), 0.0)
    K = 2.0 / 3.0 * law.moduli.E * float(law.psi(np.zeros(1))[0])
    x_s = (m * a / K) ** (2.0 / 3.0)
    return np.maximum(np.sqrt(2.0 * a * x_s), V_ONSET_MIN)


@dataclass
class ChainResult:
    """Outcome of :func:`simulate_chain`. SI units.

    t_end: time the integration stopped [s]; stopped_by: "separated" (no
        contact open and no neighbours closing, no acceleration), "t_end"
        or "horizon".
    positions, velocities: centres and velocities of the bodies at t_end [m],
        [m/s] (N,).
    records: one ImpactRecord per contact episode, in the order they ended
        (engine "reference-chain"; inputs["contact"] the contact index k,
        inputs["t_onset"], ["v_n_in"], ["v_n_onset_used"], ["mass_effective"]);
        episodes still open at t_end are not in it (``open_contacts``).
    t, energy: accepted integration times [s] (m,) and E = kinetic +
        potential + elastic energy stored in the open contacts [J] (m,).
    energy_initial: E at t = 0 [J]; energy_gain_max: max(E - E_0) / E_scale
        [-], E_scale = max(E_0, sum of the initial kinetic energies).
    momentum: total momentum at t = 0 and at t_end [kg m/s] (2,), the plate's
        share excluded.
    energy_closure: |kinetic + potential + works - E_0| / E_scale at t_end [-].
    open_contacts: contact indices still in contact at t_end.
    """

    t_end: float
    stopped_by: str
    positions: np.ndarray
    velocities: np.ndarray
    records: list[ImpactRecord]
    t: np.ndarray
    energy: np.ndarray
    energy_initial: float
    energy_gain_max: float
    momentum: np.ndarray
    energy_closure: float
    open_contacts: list[int] = field(default_factory=list)


def simulate_chain(
    bodies: Sequence[Body],
    positions,
    velocities,
    laws: Sequence[ForceLaw],
    plate: float | None = None,
    accel: float = 0.0,
    t_end: float | None = None,
    v_onset_min: float = V_ONSET_MIN,
) -> ChainResult:
    """Integrate a collinear chain of spheres as one ODE (module docstring).

    bodies: N >= 1 spheres (:class:`Body`, finite radius and mass), in order
        along the axis. positions [m] (N,): centres, increasing. velocities
        [m/s] (N,). laws: one ForceLaw per contact: N - 1 between neighbours
        (k between bodies k and k + 1), plus one more for the plate.
    plate: position of a fixed plate's surface after the last body [m]
        (None: no plate). accel: uniform acceleration of every body along the
        axis [m/s^2] (toward the plate when positive). t_end: stop time [s];
        required with accel != 0 (a body under gravity never stops).
    v_onset_min: the onset-speed floor with no external acceleration [m/s].
    """
    N = len(bodies)
    if N < 1:
        raise ValueError("bodies is empty: give at least one Body")
    u0 = check_finite("positions", positions).astype(float).reshape(-1)
    v0 = check_finite("velocities", velocities).astype(float).reshape(-1)
    if u0.size != N or v0.size != N:
        raise ValueError(f"positions has {u0.size} and velocities {v0.size} entries; expected {N} (len(bodies))")
    for i, b in enumerate(bodies):
        if not isinstance(b, Body) or math.isinf(b.radius) or math.isinf(b.mass):
            raise ValueError(f"bodies[{i}] = {b!r} must be a Body of finite radius and mass (the plate is `plate`)")
    if N > 1 and np.any(np.diff(u0) <= 0):
        raise ValueError(f"positions = {u0!r} m must increase along the chain")
    C = N - 1 + (plate is not None)
    if len(laws) != C:
        raise ValueError(f"laws has {len(laws)} entries; expected {C} (one per contact"
                         f"{', the last for the plate' if plate is not None else ''})")
    for k, law in enumerate(laws):
        if not isinstance(law, ForceLaw):
            raise ValueError(f"laws[{k}] = {law!r} is not a msf_contact ForceLaw")
    check_finite("accel", accel)
    check_positive("v_onset_min", v_onset_min, unit="m/s")
    if plate is not None:
        check_finite("plate", plate)
    if t_end is not None:
        check_positive("t_end", t_end, unit="s")
    elif accel != 0.0:
        raise ValueError(f"accel = {accel!r} m/s^2 needs an end time t_end: bodies under a uniform acceleration "
                         "never stop interacting")
    m = np.array([b.mass for b in bodies])
    R = np.array([b.radius for b in bodies])
    # contact k: bodies (k, k + 1), the last one's second body the plate (-1)
    ends = [(k, k + 1) for k in range(N - 1)] + ([(N - 1, -1)] if plate is not None else [])
    x0 = np.array([u0[i] + R[i] - (u0[j] - R[j]) if j >= 0 else u0[i] + R[i] - plate for i, j in ends])
    m_c = np.array([reduced_mass(m[i], m[j] if j >= 0 else math.inf) for i, j in ends])
    # external closing acceleration of each contact: only the plate contact has one
    a_n = np.array([0.0 if j >= 0 else accel for i, j in ends])

    # scales: the fastest closing contact (or the largest speed) sets x_s, v_s
    xdot0 = np.array([v0[i] - (v0[j] if j >= 0 else 0.0) for i, j in ends])
    v_s = max(float(np.max(np.abs(v0))), float(np.max(np.abs(xdot0), initial=0.0)), v_onset_min)
    k_s = int(np.argmax(np.abs(xdot0))) if C else 0
    x_s = float(laws[k_s].hertz_scale(v_s, m_c[k_s])) if C else 1e-6
    t_s = x_s / v_s
    E_scale = max(float(np.sum(0.5 * m * v0**2)), 1e-300)
    atol = np.concatenate([np.full(N, x_s), np.full(N, v_s), np.full(2 * C, E_scale)]) * ATOL_SCALED

    # state y = (d (N), v (N), W_el (C), W_visc (C)); W_el counts from the episode's onset
    iD, iV, iE, iW = 0, N, 2 * N, 2 * N + C

    def approach(y, k):
        i, j = ends[k]
        return x0[k] + y[iD + i] - (y[iD + j] if j >= 0 else 0.0)

    def rate(y, k):
        i, j = ends[k]
        return y[iV + i] - (y[iV + j] if j >= 0 else 0.0)

    active = [False] * C
    onset: list[dict | None] = [None] * C
    kern: list = [None] * C
    episode: list[dict | None] = [None] * C
    records: list[ImpactRecord] = []

    def begin(k, y, t):
        law = laws[k]
        vn = max(rate(y, k), 0.0)
        floor = float(onset_speed_floor(law, m_c[k], a_n[k]))
        if a_n[k] <= 0.0:
            floor = max(floor, v_onset_min)
        v_used = max(vn, floor)
        o = law.onset_reference([v_used], [m_c[k]])
        o1 = {key: np.atleast_1d(val)[:1] for key, val in o.items()}
        onset[k] = o1
        kern[k] = _scalar_kernels(law, o1)
        active[k] = True
        y[iE + k] = 0.0
        episode[k] = dict(t_onset=t, v_in=vn, v_used=v_used, x_max=max(approach(y, k), 0.0), onset=o1,
                          turned=False, tau1=None, Wc=0.0, Wb=0.0, Wb0=float(y[iW + k]), F_max=0.0, x_at_F=0.0)

    def rhs(t, y):
        dy = [0.0] * (2 * N + 2 * C)
        for i in range(N):
            dy[iD + i] = y[iV + i]
            dy[iV + i] = accel
        for k in range(C):
            if not active[k]:
                continue
            i, j = ends[k]
            x, xd = approach(y, k), rate(y, k)
            Fn, Fc = kern[k][0](x, xd)
            dy[iV + i] -= Fn / m[i]
            if j >= 0:
                dy[iV + j] += Fn / m[j]
            dy[iE + k] = Fc * xd
            dy[iW + k] = (Fn - Fc) * xd
        return dy

    def energy(y):
        d, v = y[iD:iD + N], y[iV:iV + N]
        return float(np.sum(0.5 * m * v**2) - accel * np.sum(m * d) + np.sum(y[iE:iE + C]))

    y = np.concatenate([np.zeros(N), v0, np.zeros(2 * C)])
    released = 0.0  # elastic energy left in contacts at their force-zero ends [J]
    for k in range(C):  # touching or overlapped at t = 0: in contact from the start
        if x0[k] >= 0.0:
            begin(k, y, 0.0)
    E0 = energy(y)
    p0 = float(np.sum(m * v0))
    ts, Es = [0.0], [E0]
    t = 0.0
    horizon = t_end if t_end is not None else HORIZON_SCALES * t_s
    stopped_by = "horizon"
    for _n in range(MAX_EVENTS):
        if t_end is None and not any(active) and accel == 0.0 and all(
                rate(y, k) <= 0.0 for k in range(C)):
            stopped_by = "separated"
            break
        events, tags = [], []
        for k in range(C):
            if active[k]:
                events.append(_event(lambda tt, yy, k=k: rate(yy, k), -1, terminal=False))
                tags.append(("turn", k))
                events.append(_event(lambda tt, yy, k=k: _overlap_g(approach(yy, k), rate(yy, k)), -1))
                tags.append(("overlap-zero", k))
                if laws[k].separation == "force-zero":
                    events.append(_event(lambda tt, yy, k=k: _force_g(kern[k][2], approach(yy, k), rate(yy, k)), -1))
                    tags.append(("force-zero", k))
            else:  # begins where x >= 0 with a closing speed: min(x, x') crosses 0 upward
                events.append(_event(lambda tt, yy, k=k: min(approach(yy, k), rate(yy, k)), +1))
                tags.append(("onset", k))
        t_stop = t + horizon if t_end is None else t_end
        sol = dop853(rhs, (t, t_stop), y, rtol=RTOL, atol=atol, events=events, first_step=1e-6 * t_s)
        if sol.status == -1:
            raise RuntimeError(f"chain integration failed at t = {t!r} s: {sol.message}")
        ts.extend(sol.t[1:].tolist())
        Es.extend(energy(yy) for yy in sol.y.T[1:])
        _track(sol, tags, episode, active, approach, rate, kern, ts)
        t, y = float(sol.t[-1]), np.array(sol.y[:, -1])
        if sol.status == 0:
            stopped_by = "t_end" if t_end is not None else "horizon"
            break
        # the terminal event that stopped the segment
        fired = [(float(sol.t_events[q][-1]), q) for q in range(len(events))
                 if events[q].terminal and len(sol.t_events[q])]
        _, q = max(fired)
        kind, k = tags[q]
        if kind == "onset":
            begin(k, y, t)
        elif kind in ("overlap-zero", "force-zero"):
            records.append(_record(laws[k], k, ends[k], episode[k], y, t, kind, m_c[k], approach(y, k),
                                   rate(y, k), float(y[iE + k]), float(y[iW + k])))
            active[k] = False
            released += float(y[iE + k])
            y[iE + k] = 0.0
    else:
        raise RuntimeError(f"more than {MAX_EVENTS} contact onsets and ends in one chain impact")
    d, v = y[iD:iD + N], y[iV:iV + N]
    E_all = energy(y) + float(np.sum(y[iW:iW + C])) + released
    closure = abs(E_all - E0) / E_scale
    E = np.array(Es)
    p_end = float(np.sum(m * v))
    if plate is None and accel == 0.0 and abs(p_end - p0) > 1e-9 * max(abs(p0), float(np.sum(m * np.abs(v0)))):
        raise RuntimeError(f"momentum not conserved: {p0!r} -> {p_end!r} kg m/s (integration error)")
    return ChainResult(
        t_end=t, stopped_by=stopped_by, positions=u0 + d, velocities=v.copy(), records=records,
        t=np.array(ts), energy=E, energy_initial=E0, energy_gain_max=float(np.max(E - E0)) / E_scale,
        momentum=np.array([p0, p_end]), energy_closure=closure,
        open_contacts=[k for k in range(C) if active[k]],
    )


def _event(fn, direction, terminal=True):
    fn.direction, fn.terminal = direction, terminal
    return fn


def _overlap_g(x, xd):
    """Overlap-zero event function: x, except a contact touching at rest
    (x = x' = 0, a touching cradle before the strike reaches it), which has
    not ended: the smallest positive float there, so only x < 0 is an end."""
    return x if (x != 0.0 or xd != 0.0) else 5e-324


def _force_g(indicator, x, xd):
    """Force-zero event function: B in restitution (x' < 0), +1 in compression."""
    return indicator(max(x, 0.0), xd) if xd < 0 else 1.0


def _track(sol, tags, episode, active, approach, rate, kern, ts):
    """Per open episode over a segment: the first maximum compression (tau1,
    the works at it), x_max and the peak force on the accepted steps."""
    for q, (kind, k) in enumerate(tags):
        if kind != "turn" or not active[k]:
            continue
        ep = episode[k]
        if not ep["turned"] and len(sol.t_events[q]):
            yt = sol.y_events[q][0]
            ep.update(turned=True, tau1=float(sol.t_events[q][0]) - ep["t_onset"])
            ep["x_turn"] = approach(yt, k)
            ep["Wc"], ep["Wb"] = _works_at(yt, k, len(active), ep)
    cols = sol.y.shape[1]
    for k in range(len(active)):
        if not active[k]:
            continue
        ep = episode[k]
        F = [kern[k][0](approach(sol.y[:, c], k), rate(sol.y[:, c], k))[0] for c in range(cols)]
        ep["x_max"] = max(ep["x_max"], max(approach(sol.y[:, c], k) for c in range(cols)))
        c = int(np.argmax(F))
        if F[c] > ep["F_max"]:  # the peak on the accepted steps, refined on the dense output (solver._refine_max)
            def force_at(tt, k=k):
                yy = sol.sol(tt)
                return kern[k][0](approach(yy, k), rate(yy, k))[0]

            ep["F_max"] = _refine_max(force_at, sol.t, c, F[c])
            ep["x_at_F"] = approach(sol.y[:, c], k)


def _works_at(y, k, C, ep):
    """(W_el, W_visc) of the episode of contact k at state y [J]."""
    N2 = y.size - 2 * C
    return float(y[N2 + k]), float(y[N2 + C + k]) - ep["Wb0"]


def _record(law, k, ends_k, ep, y, t, ended_by, m_c, x_end, xd_end, W_el, W_visc_total):
    """The ImpactRecord of one finished episode of contact k (engine "reference-chain")."""
    v_out = max(-xd_end, 0.0)
    vin = ep["v_in"] if ep["v_in"] > 0 else ep["v_used"]
    tau = t - ep["t_onset"]
    tau1 = ep["tau1"] if ep["turned"] else tau
    x_m = ep["x_turn"] if ep["turned"] else ep["x_max"]
    W_visc = W_visc_total - ep["Wb0"]
    o1 = ep["onset"]
    S = float(area(x_m, law.geom, law.kp_mode)) if x_m > 0 else 0.0
    Fxm = float(law.contact_normal_force(np.array([x_m]), np.array([0.0]), o1)[0]) if x_m > 0 else 0.0
    Sf = float(area(ep["x_at_F"], law.geom, law.kp_mode)) if ep["x_at_F"] > 0 else 0.0
    outside = []
    if law.outside(np.array([ep["x_max"]]))[0]:
        outside.append(f"x_max = {ep['x_max']:.6g} m reached 2R: k_p = sqrt(2 - x/R) of (15) was clamped")
    strain = small_strain_note(x_m, law.geom.R)
    if strain:
        outside.append(strain)
    return ImpactRecord(
        cor_n=v_out / vin, cor_t=None, cor_t_contact=None,
        cor_tau_ratio=tau1 / (tau - tau1) if tau > tau1 else 0.0,
        tau=tau, tau1=tau1, tau2=tau - tau1, x_max=x_m, F_max=ep["F_max"],
        Pc_max=1.5 * Fxm / S if S > 0 else 0.0, Pc_at_Fmax=1.5 * ep["F_max"] / Sf if Sf > 0 else 0.0,
        W_el_comp=ep["Wc"], W_visc_comp=ep["Wb"], W_el_rest=-(W_el - ep["Wc"]), W_visc_rest=W_visc - ep["Wb"],
        W_diss_n=W_el + W_visc, W_diss_t=0.0, Q_t=0.0, spin_in=0.0, spin_out=0.0, f_min=None, f_max=None,
        omega_x=_opt(ep, "omega_x"), omega_y=_opt(ep, "omega_y"), ended_by=ended_by, law=law.name,
        engine="reference-chain", dt=None, parameters=law.parameters(),
        inputs={"contact": k, "bodies": list(ends_k), "t_onset": ep["t_onset"], "t_end": t, "v_n_in": ep["v_in"],
                "v_n_onset_used": ep["v_used"], "mass_effective": m_c, "x_end": x_end},
        outside_validity=outside,
    )


def _opt(ep, key):
    o = ep["onset"]
    return float(o[key][0]) if key in o else None
