"""Reference impact solver: an isolated collision integrated to tight tolerance.

(Over 600 lines because it is one algorithm that a reader checks as a whole:
the equations of motion, the stick-slip segments, the event location and the
record share the state layout; the isolated normal integration is in
``_normal.py``.)

Planar model (the plane of incidence holds the normal n, from body 2 toward
body 1, and the tangent t along the incident tangential velocity; spins are
about n x t). Body 2 is a half-space (infinite mass and radius, fixed) or a
sphere. Equations, with m the reduced mass (section 4), l_i = R_i - x/2 the
lever arm of the contact point (mid-overlap, as the engines place it) and
F_t the tangential force on body 1 from the law:

    m x''  = -F_n(x, x')                         (45)/(49)
    m vt'  =  F_t                                (45)
    J_1 w1' = -l_1 F_t,  J_2 w2' = -l_2 F_t       (45), M = F_t l_x (47)

The tangential displacement s fed to the law is, in ``paper`` mode, the
relative centre-of-mass displacement since onset (49); in ``contact-point``
mode (default) the integral of the contact point's relative tangential
velocity u = vt - w1 l1 - w2 l2 (DEM practice).

Tolerances: see ``_normal.RTOL``; COR, tau, x_max, F_max converge to 1e-6.
Integration: ``_normal.dop853`` (scipy's DOP853 scheme without solve_ivp's
per-step overhead) on a right-hand side of floats; MSFLaw's own forces are
evaluated inline with the math module (:func:`_scalar_kernels`). With the
polished self-consistent root (``_scaling.self_consistent``) an impact costs
~10 ms instead of ~90 ms (issue 5).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from ._normal import ATOL_SCALED, RTOL, dop853
from ._validate import (DENSITY_MIN, MEAN_DENSITY_MAX, RADIUS_MAX, RADIUS_MIN, SPEED_MIN, ValidityWarning, check_between,
                        check_choice, check_finite, check_positive, check_range, small_strain_note)
from .geometry import area
from .laws import ForceLaw, MSFLaw
from .materials import Material
from .record import ImpactRecord

TANGENTIAL_MODES = ("contact-point", "paper")
#: f = |F_t|/F_n is reported only while F_n >= this share of F_max: at
#: force-zero separation F_n -> 0 with F_t != 0 and f diverges.
F_RATIO_FLOOR = 0.01


@dataclass(frozen=True)
class Body:
    """A colliding body. radius [m] (inf: half-space), mass [kg] (inf: fixed),
    inertia [kg m^2] about the spin axis (default solid sphere 2/5 m R^2;
    :meth:`sphere` gives hollow balls).

    Finite radii lie in [RADIUS_MIN, RADIUS_MAX] and a finite sphere's mean
    density m / (4/3 pi R^3) in [DENSITY_MIN, MEAN_DENSITY_MAX]
    (``msf_contact._validate``: bounds of plausibility, so that no derived
    scale overflows)."""

    material: Material
    radius: float
    mass: float
    inertia: float | None = None

    def __post_init__(self):
        check_positive("radius", self.radius, allow_inf=True, unit="m")
        check_positive("mass", self.mass, allow_inf=True, unit="kg")
        if not math.isinf(self.radius):
            check_between("radius", self.radius, RADIUS_MIN, RADIUS_MAX, "m",
                          "bounds of plausibility, msf_contact._validate.RADIUS_MIN/MAX; inf is a half-space")
            if not math.isinf(self.mass):
                rho = self.mass / (4.0 / 3.0 * math.pi * self.radius**3)
                if not DENSITY_MIN <= rho <= MEAN_DENSITY_MAX:
                    raise ValueError(
                        f"mass = {self.mass!r} kg with radius = {self.radius!r} m is a mean density of {rho:.6g} kg/m^3, "
                        f"outside [{DENSITY_MIN:g}, {MEAN_DENSITY_MAX:g}] kg/m^3 (bounds of plausibility, "
                        "msf_contact._validate.DENSITY_MIN/MEAN_DENSITY_MAX)")
        if self.inertia is not None:
            check_positive("inertia", self.inertia, allow_inf=True, unit="kg m^2")
            if not (math.isinf(self.mass) or math.isinf(self.radius)) and self.inertia > self.mass * self.radius**2:
                raise ValueError(f"inertia = {self.inertia!r} kg m^2 exceeds m R^2 = {self.mass * self.radius**2:.6g} "
                                 "kg m^2, the inertia of all the mass on the surface (a thin shell has 2/3 m R^2)")

    @property
    def J(self) -> float:
        if self.inertia is not None:
            return self.inertia
        if math.isinf(self.mass) or math.isinf(self.radius):  # a fixed body, or a half-space (it does not turn)
            return math.inf
        return 0.4 * self.mass * self.radius**2

    @staticmethod
    def sphere(material: Material, radius: float, mass: float | None = None, *,
               wall: float | None = None) -> "Body":
        """A solid sphere, or with ``wall`` [m] a hollow one (a shell of that
        thickness, inner radius R - wall); mass [kg] from the density and the
        solid or shell volume when not given. Inertia about a diameter:
        2/5 m R^2 solid; hollow 2/5 m (R^5 - r^5)/(R^3 - r^3), which tends to
        the thin shell's 2/3 m R^2 (a table-tennis ball: R = 20 mm, wall
        0.4 mm, 2.7 g). The contact law stays the solid sphere's: a thin
        shell's own flexure is not modelled.
        """
        check_between("radius", radius, RADIUS_MIN, RADIUS_MAX, "m",
                      "bounds of plausibility, msf_contact._validate.RADIUS_MIN/MAX")
        if wall is None:
            if mass is None:
                mass = 4.0 / 3.0 * math.pi * radius**3 * material.density
            return Body(material, radius, mass)
        check_positive("wall", wall, unit="m")
        if wall > radius:
            raise ValueError(f"wall = {wall!r} m exceeds the radius = {radius!r} m (a solid sphere: omit wall)")
        r = radius - wall
        if mass is None:
            mass = 4.0 / 3.0 * math.pi * (radius**3 - r**3) * material.density
        # (R^5 - r^5)/(R^3 - r^3) as a ratio of sums, without cancellation for thin walls
        q = r / radius
        ratio = (1 + q + q**2 + q**3 + q**4) / (1 + q + q**2)
        return Body(material, radius, mass, inertia=0.4 * mass * radius**2 * ratio)

    @staticmethod
    def half_space(material: Material) -> "Body":
        return Body(material, math.inf, math.inf)


#: Largest contact strain P_c/E' (peak pressure (20) over the effective
#: storage modulus) of the linear viscoelastic material the model assumes:
#: E' and E'' independent of amplitude are rarely measured beyond 0.2, and
#: filled elastomers soften from ~1 % (Payne effect).
STRAIN_MAX = 0.2


def outside_validity(law: ForceLaw, x_max: float, Pc_max: float | None, f_max: float | None = None) -> list[str]:
    """The reasons an impact left the model's validity, from its results:
    x_max [m] over R beyond ``_validate.SMALL_STRAIN_X_OVER_R``, contact strain P_c,max/E'
    [Pa/Pa] beyond :data:`STRAIN_MAX`, friction ratio f_max [-] above the
    Coulomb cap mu. For the reference solver, the closed forms and the
    engines' records alike (each adds its own: energy gain, omega dt)."""
    notes = []
    strain = small_strain_note(x_max, law.geom.R)
    if strain:
        notes.append(strain)
    E = law.moduli.E
    if Pc_max is not None and math.isfinite(E) and Pc_max / E > STRAIN_MAX:
        notes.append(f"contact strain P_c,max/E' = {Pc_max / E:.4g} > {STRAIN_MAX:g}: beyond linear viscoelasticity "
                     "(msf_contact.solver.STRAIN_MAX)")
    if f_max is not None and law.mu is not None and f_max > law.mu * (1.0 + F_CAP_RTOL):
        notes.append(f"friction ratio f_max = {f_max:.6g} above the Coulomb cap mu = {law.mu:g}")
    return notes


def reduced_mass(m1: float, m2: float) -> float:
    """1/m = 1/m1 + 1/m2 (section 4); a fixed body (inf) leaves m1."""
    if math.isinf(m2):
        return m1
    if math.isinf(m1):
        return m2
    return m1 * m2 / (m1 + m2)


def check_impact_inputs(law: ForceLaw, body1: Body, body2: Body, speed, angle_deg, spin, strict=False):
    """All bad-input checks of an impact, before any work (issue 2)."""
    check_positive("speed", speed, unit="m/s")
    check_range("angle (degrees to the plate)", angle_deg, 0.0, 90.0, lo_open=True)
    check_finite("spin", spin)
    if math.isinf(body1.mass):
        raise ValueError("body 1 (the projectile) must have a finite mass")
    if math.isinf(body1.radius):
        raise ValueError("body 1 (the projectile) must have a finite radius")
    c = law.pair.sound_speed()
    if speed >= c:
        raise ValueError(f"speed = {speed!r} m/s is at or above the sound speed sqrt(E'/rho) = {c:.4g} m/s "
                         "of the softer body (the paper's model needs a subsonic impact, section 1)")
    a = math.radians(angle_deg)
    vn0 = speed * math.sin(a)
    if vn0 < SPEED_MIN:
        raise ValueError(f"speed = {speed!r} m/s at angle {angle_deg!r} deg: normal speed {vn0:g} m/s is below "
                         f"{SPEED_MIN:g} m/s (msf_contact._validate.SPEED_MIN: the impact's scales underflow)")
    with np.errstate(over="ignore", divide="ignore"):  # an infinite scale is refused just below
        xs = float(np.atleast_1d(law.hertz_scale(vn0, reduced_mass(body1.mass, body2.mass)))[0])
    R_min = min(body1.radius, body2.radius)
    if not xs < 2.0 * R_min:
        raise ValueError(f"speed = {speed!r} m/s: the elastic approach of this law, {xs:.4g} m, reaches 2R = "
                         f"{2.0 * R_min:.4g} m, the ball's diameter (the stiffness E' or k is too low for the "
                         "speed and mass)")
    if abs(spin) * body1.radius >= c:
        raise ValueError(f"spin = {spin!r} rad/s gives a surface speed |spin| R = {abs(spin) * body1.radius:.6g} m/s at "
                         f"or above the sound speed sqrt(E'/rho) = {c:.4g} m/s of the softer body (|spin| < "
                         f"{c / body1.radius:.6g} rad/s; the model needs subsonic contact-point speeds, section 1)")


def simulate_impact(
    law: ForceLaw,
    body1: Body,
    body2: Body,
    speed: float,
    angle_deg: float = 90.0,
    spin: float = 0.0,
    tangential: str = "contact-point",
    n_samples: int = 0,
    strict: bool = False,
) -> ImpactRecord:
    """One isolated impact of body 1 on body 2, returned as an impact record.

    speed [m/s] relative impact speed; angle_deg the paper's alpha (to the
    plate, 90 = normal); spin [rad/s] body 1's initial spin, positive for
    rolling in the direction of incidence. ``n_samples`` > 0 adds force-time
    curves (``record.inputs['curves']``).
    """
    check_choice("tangential", tangential, TANGENTIAL_MODES)
    check_impact_inputs(law, body1, body2, speed, angle_deg, spin, strict)
    a = math.radians(angle_deg)
    vn0 = speed * math.sin(a)  # (section 4): V_0x = V0 sin(alpha)
    vt0 = speed * math.cos(a) if angle_deg < 90.0 else 0.0
    m = reduced_mass(body1.mass, body2.mass)
    J1, J2 = body1.J, body2.J
    R1, R2 = body1.radius, body2.radius
    inv_J2 = 0.0 if math.isinf(J2) else 1.0 / J2
    onset = law.onset_reference([vn0], [m])
    o1 = {k: np.atleast_1d(v)[:1] for k, v in onset.items()}
    xs = float(law.hertz_scale(vn0, m))
    ts = xs / vn0
    paper = tangential == "paper"
    vscale = max(abs(vt0), abs(spin) * R1, vn0)

    mu = law.mu

    normal, kb, indicator, forces = _scalar_kernels(law, o1)
    inf1, inf2 = math.isinf(R1), math.isinf(R2)

    def lever(x, R):
        return 0.0 if math.isinf(R) else R - 0.5 * max(x, 0.0)

    def u_of(x, vt, w1, w2):
        return vt - w1 * lever(x, R1) - w2 * lever(x, R2)

    def make_rhs(mode):
        """mode 0: sticking (spring-dashpot of the law); +-1: sliding with
        the Coulomb force -mode mu F_n (the spring displacement is held)."""

        def rhs(t, y):
            x, vx, s, vt, w1, w2, Wc, Wb, Q = y
            xp = max(x, 0.0)
            l1 = 0.0 if inf1 else R1 - 0.5 * xp  # lever(x, R1)
            l2 = 0.0 if inf2 else R2 - 0.5 * xp
            u = vt if paper else vt - w1 * l1 - w2 * l2  # u_of(x, vt, w1, w2)
            if mode == 0:
                Fn, Fc, k, b = forces(x, vx)
                Ft, q, sdot = -(k * s + b * u), b * u * u, u
            else:
                Fn, Fc = normal(x, vx)
                cap = mu * max(Fn, 0.0)
                Ft, q, sdot = -mode * cap, 0.0, 0.0
                if kv_slide:  # the spring-dashpot in series with the slider: k s + b s' = mode mu F_n
                    k, b = kb(x)
                    if b > 0.0:
                        sdot = (mode * cap - k * s) / b
                        q = b * sdot * sdot
            return (vx, -Fn / m, sdot, Ft / m, -l1 * Ft / J1, -l2 * Ft * inv_J2, Fc * vx, (Fn - Fc) * vx, q)

        return rhs

    def ev_turn(t, y):
        return y[1]

    ev_turn.direction = -1

    def ev_overlap(t, y):
        return y[0]

    ev_overlap.terminal, ev_overlap.direction = True, -1

    def ev_force(t, y):
        if y[1] >= 0:
            return 1.0
        return indicator(max(y[0], 0.0), y[1])

    ev_force.terminal, ev_force.direction = True, -1

    def ev_limit(t, y):
        return law.x_limit - y[0]

    ev_limit.terminal = True

    def ev_slip(t, y):  # sticking -> sliding where the trial force reaches mu F_n
        x, vx, s, vt, w1, w2 = y[:6]
        u = vt if paper else u_of(x, vt, w1, w2)
        k, b = kb(x)
        return mu * max(normal(x, vx)[0], 0.0) - abs(k * s + b * u)

    ev_slip.terminal, ev_slip.direction = True, -1

    def s_cap(x, vx):
        """Elastic tangential displacement on the Coulomb cap, mu F_n / k [m]."""
        k, _ = kb(x)
        return mu * max(normal(x, vx)[0], 0.0) / k if k > 0 else 0.0

    h_fd = 1e-7 * ts  # finite-difference step of d(s_cap)/dt along the motion

    def make_ev_stick(mode):
        """Sliding -> sticking where the slip rate mode (u - s') vanishes.
        With tangential damping (``kv_slide``) s is the spring-dashpot's own
        displacement, integrated while sliding, and the slip rate vanishes
        where the trial force mode (k s + b u) falls back to mu F_n. Without
        damping the elastic part s_el = mode s_cap follows the cap, the rest
        is slip."""

        if kv_slide:
            def ev_kv(t, y):
                x, vx, s, vt, w1, w2 = y[:6]
                k, b = kb(x)
                u = vt if paper else u_of(x, vt, w1, w2)
                return mode * (k * s + b * u) - mu * max(normal(x, vx)[0], 0.0)

            ev_kv.terminal, ev_kv.direction = True, -1
            return ev_kv

        def ev(t, y):
            x, vx, s, vt, w1, w2 = y[:6]
            ax = -normal(x, vx)[0] / m
            dcap = (s_cap(x + vx * h_fd, vx + ax * h_fd) - s_cap(max(x - vx * h_fd, 0.0), vx - ax * h_fd)) / (2 * h_fd)
            return mode * (vt if paper else u_of(x, vt, w1, w2)) - dcap

        ev.terminal, ev.direction = True, -1
        return ev

    Escale = m * speed**2
    atol = np.array([xs, vn0, xs * vscale / vn0, vscale, vscale / R1, vscale / R1, Escale, Escale, Escale]) * ATOL_SCALED
    y = np.array((0.0, vn0, 0.0, vt0, spin, 0.0, 0.0, 0.0, 0.0))
    kv_slide = False
    if mu is not None:
        k_s, b_s = kb(xs)
        # relaxation rate k/b of the tangential spring-dashpot, times the time scale
        kv_slide = b_s > 0.0 and k_s * ts <= KV_SLIDE_STIFFNESS_MAX * b_s
    mode = 0
    if mu is not None:  # initial mode: trial force against mu F_n just after onset
        x_eps = 1e-9 * xs
        k0, b0 = kb(x_eps)
        u0 = vt0 if paper else u_of(0.0, vt0, spin, 0.0)
        if abs(b0 * u0) > mu * max(normal(x_eps, vn0)[0], 0.0):
            mode = int(np.sign(u0))
    dense = _Piecewise()
    t0, t_stop = 0.0, 1e3 * ts
    tau1 = y_turn = None
    tau = ended_by = y_end = None
    grazing = False  # the last switch came at once after the one before (see ZENO_SEGMENT)
    for _segment in range(MAX_SEGMENTS):
        events = [ev_turn, ev_overlap] + ([ev_force] if law.separation == "force-zero" else [])
        if law.x_limit is not None:
            events.append(ev_limit)
        if mu is not None and not grazing:
            events.append(ev_slip if mode == 0 else make_ev_stick(mode))
        t_end = min(t0 + GRAZING_HOLD * ts, t_stop) if grazing else t_stop
        sol = dop853(make_rhs(mode), (t0, t_end), y, rtol=RTOL, atol=atol, events=events, first_step=1e-6 * ts,
                     max_steps=MAX_STEPS)
        if sol.status == -1:
            raise RuntimeError(f"impact integration failed: {sol.message}")
        dense.add(t0, float(sol.t[-1]), sol.sol, mode)
        if grazing and sol.status == 0 and t_end < t_stop:  # held through the grazing point: switch events back on
            t0, y, grazing = t_end, np.array(sol.y[:, -1]), False
            continue
        if ev_limit in events and len(sol.t_events[events.index(ev_limit)]):
            raise ValueError(f"the approach reached 2R = {law.x_limit:.6g} m: k_p = sqrt(2 - x/R) of (15) has no "
                             "real value beyond; the impact is outside the msf geometry (use a lower speed)")
        if tau1 is None and len(sol.t_events[0]):
            tau1, y_turn = float(sol.t_events[0][0]), sol.y_events[0][0]
        ends = [(float(sol.t_events[k][0]), name, sol.y_events[k][0])
                for k, (ev, name) in enumerate(zip(events, [None] * len(events)))
                for name in [{id(ev_overlap): "overlap-zero", id(ev_force): "force-zero"}.get(id(ev))]
                if name and len(sol.t_events[k])]
        if ends:
            tau, ended_by, y_end = min(ends, key=lambda e: e[0])
            break
        if sol.status == 0:  # horizon reached: never separated
            tau, ended_by, y_end = float(sol.t[-1]), "capture", sol.y[:, -1]
            break
        # a stick/slip switch; one right after the previous switch is a grazing point (slip rate or
        # cap margin touching zero): the new mode is held for GRAZING_HOLD t_s without switching
        t_switch = float(sol.t_events[-1][0])
        grazing = t_switch - t0 <= ZENO_SEGMENT * ts
        t0, y = t_switch, np.array(sol.y_events[-1][0])
        x, vx, sv, vt, w1, w2 = y[:6]
        u = vt if paper else u_of(x, vt, w1, w2)
        if mode == 0:
            k, b = kb(x)
            trial = k * sv + b * u  # the force would be -trial; slide along its sign
            mode = int(np.sign(trial)) if trial != 0.0 else (int(np.sign(u)) or 1)
        else:
            if not kv_slide:
                y[2] = mode * s_cap(x, vx) * (1.0 - 1e-9)
            mode = 0
    else:
        raise RuntimeError(f"more than MAX_SEGMENTS = {MAX_SEGMENTS} stick-slip transitions in one impact "
                           f"(the work bound of the reference solver)")
    if tau1 is None:
        raise RuntimeError("the impact never reached maximum compression")
    sol = dense
    x_end, vx_end, s_end, vt_end, w1_end, w2_end, Wc_end, Wb_end, Q_end = y_end
    x_max = float(y_turn[0])

    outside = []
    if law.outside(np.array([x_max]))[0]:
        raise ValueError(f"x_max = {x_max:.6g} m >= 2R = {2 * law.geom.R:.6g} m: k_p = sqrt(2 - x/R) of (15) "
                         "has no real value; the impact is outside the msf geometry (use a lower speed)")
    if ended_by == "capture":
        outside.append("the bodies never separated (over-damped): outside the model's validity (100)")

    # peak force, pressures and friction ratio on a dense grid + refinement
    tt = np.linspace(0.0, tau, max(n_samples, 2001))
    Y = sol.sol(tt)
    X = np.maximum(Y[0], 0.0)
    o_n = {k: np.broadcast_to(v, X.shape) for k, v in o1.items()}
    Fn_t = law.contact_normal_force(X, Y[1], o_n)
    U_t = Y[3] if paper else Y[3] - Y[4] * np.where(np.isinf(R1), 0, R1 - 0.5 * X) - Y[5] * (
        0.0 if math.isinf(R2) else R2 - 0.5 * X)
    Ft_t, _ = law.tangential_force(X, np.stack([Y[2], np.zeros_like(X)], -1),
                                   np.stack([U_t, np.zeros_like(X)], -1), o_n)
    modes = dense.modes(tt)
    Ft_t[:, 0] = np.where(modes == 0, Ft_t[:, 0], -modes * (mu or 0.0) * np.maximum(Fn_t, 0.0))
    k_pk = int(np.argmax(Fn_t))

    def Fn_at(t):
        x, vx = sol.sol(t)[:2].tolist()
        return normal(x, vx)[0]

    F_max = _refine_max(Fn_at, tt, k_pk, float(Fn_t[k_pk]))
    S_m = float(area(x_max, law.geom, law.kp_mode))
    Fn_xm = float(law.contact_normal_force(np.array([x_max]), np.array([0.0]), o1)[0])
    Pc_max = 1.5 * Fn_xm / S_m  # (20), (41) at x_max
    x_at_F = float(X[k_pk])
    Pc_at_F = 1.5 * float(Fn_t[k_pk]) / float(area(x_at_F, law.geom, law.kp_mode)) if x_at_F > 0 else 0.0
    mask = Fn_t >= F_RATIO_FLOOR * F_max
    ratio = np.abs(Ft_t[:, 0][mask]) / Fn_t[mask]
    f_min = float(np.min(ratio)) if ratio.size else None
    f_max = float(np.max(ratio)) if ratio.size else None

    outside += outside_validity(law, x_max, Pc_max, f_max)
    v_out_n = max(-float(vx_end), 0.0)
    Wc1, Wb1 = float(y_turn[6]), float(y_turn[7])
    u_in = u_of(0.0, vt0, spin, 0.0)
    u_out = u_of(float(x_end), float(vt_end), float(w1_end), float(w2_end))
    J2_term = 0.0 if math.isinf(J2) else 0.5 * J2 * float(w2_end) ** 2
    KE_t_in = 0.5 * m * vt0**2 + 0.5 * J1 * spin**2
    KE_t_out = 0.5 * m * float(vt_end) ** 2 + 0.5 * J1 * float(w1_end) ** 2 + J2_term
    tol = 1e-9 * Escale
    if KE_t_out > KE_t_in + tol:
        outside.append(
            "tangential and rotational energy grew: the paper tangential mode (49) drives the spin "
            "by the torque without feeding it back into the tangential force"
            if paper else "tangential and rotational energy grew: numerical or model error")
    if 0.5 * m * v_out_n**2 > 0.5 * m * vn0**2 + tol:
        warnings.warn("normal energy increased in the impact: numerical or model error", ValidityWarning, stacklevel=2)

    return ImpactRecord(
        cor_n=v_out_n / vn0,
        cor_t=(float(vt_end) / vt0) if vt0 != 0 else None,
        cor_t_contact=(-u_out / u_in) if abs(u_in) > 1e-12 * vscale else None,
        cor_tau_ratio=tau1 / (tau - tau1) if tau > tau1 else 0.0,
        tau=tau, tau1=tau1, tau2=tau - tau1, x_max=x_max, F_max=F_max,
        Pc_max=Pc_max, Pc_at_Fmax=Pc_at_F,
        W_el_comp=Wc1, W_visc_comp=Wb1,
        W_el_rest=-(float(Wc_end) - Wc1), W_visc_rest=float(Wb_end) - Wb1,
        W_diss_n=0.5 * m * (vn0**2 - v_out_n**2),
        W_diss_t=KE_t_in - KE_t_out, Q_t=float(Q_end),
        spin_in=spin, spin_out=float(w1_end), f_min=f_min, f_max=f_max,
        omega_x=_opt(onset, "omega_x"), omega_y=_opt(onset, "omega_y"),
        ended_by=ended_by, law=law.name, engine="reference", dt=None,
        parameters=law.parameters(),
        inputs=_inputs(body1, body2, speed, angle_deg, spin, tangential, m, n_samples, tt, Fn_t, Ft_t, X),
        outside_validity=outside,
    )


#: Work bound: stick-slip segments of one impact (random valid impacts need
#: fewer than 20; a grazing point costs two).
MAX_SEGMENTS = 400
#: Work bound: DOP853 steps of one segment (an impact takes ~100-3,000).
MAX_STEPS = 200_000
#: A segment shorter than this many t_s (= x_s/V_n, ~ tau/3) that ends in
#: another switch marks a grazing point: the slip rate (or the margin to the
#: cap) touches zero without changing sign, e.g. where the cap mu F_n
#: vanishes at force-zero separation, and the two modes would alternate at
#: one instant forever (Zeno). The mode switched to is then held for
#: GRAZING_HOLD t_s; at a grazing point both modes give the same force to
#: first order, so the hold changes the impulse by O(mu F_n GRAZING_HOLD t_s).
ZENO_SEGMENT = 1e-9
GRAZING_HOLD = 1e-6
#: Sliding with tangential damping b > 0 (the msf law's (36)-(37)): while the
#: contact slides, the tangential spring k and dashpot b in series with the
#: slider obey k s + b s' = mu F_n, so the force never exceeds the cap and
#: sticking resumes where the trial force k s + b u falls back to it
#: (elastic-viscous-plastic element; a DEM return map gives the same). The
#: relaxation rate k/b makes the sliding phase stiff for nearly elastic
#: pairs; when (k/b) t_s exceeds this bound (t_s = x_s/V_n, ~ tau/3), the
#: limit b -> 0 is used instead (s follows the cap mu F_n/k); its force at
#: the restart of sticking exceeds the cap by b d(s_cap)/dt, O(1/((k/b) t_s))
#: < 0.1 % relative. 1000 keeps a sliding phase at a few hundred DOP853 steps.
KV_SLIDE_STIFFNESS_MAX = 1000.0
#: f_max above mu (1 + this) is reported as outside validity (event location
#: and the dense grid are good to ~1e-9; this leaves room for the 2001-point grid).
F_CAP_RTOL = 1e-6


class _Piecewise:
    """Dense output over the integration segments (stick and slip phases)."""

    def __init__(self):
        self.t0, self.t1, self.fns, self.mode = [], [], [], []

    def add(self, t0, t1, fn, mode):
        self.t0.append(t0)
        self.t1.append(t1)
        self.fns.append(fn)
        self.mode.append(mode)

    def _index(self, t):
        return np.clip(np.searchsorted(np.asarray(self.t1), t, side="left"), 0, len(self.fns) - 1)

    def sol(self, t):
        t = np.asarray(t, dtype=float)
        if t.ndim == 0:
            return self.fns[int(self._index(t))](float(t))
        out = np.empty((9, t.size))
        idx = self._index(t)
        for i in np.unique(idx):
            sel = idx == i
            out[:, sel] = self.fns[i](t[sel])
        return out

    def modes(self, t):
        return np.asarray(self.mode)[self._index(np.asarray(t, dtype=float))]


def _msf_inline(law: ForceLaw) -> bool:
    """True when the law's forces are MSFLaw's own, so :func:`_scalar_kernels`
    may evaluate them with the math module (the condition of the engines'
    inlined MSF, ``engines._contacts._msf_inline``, plus the indicator)."""
    t = type(law)
    return (isinstance(law, MSFLaw) and law.geom.footprint is None and t.normal_force is MSFLaw.normal_force
            and t.separation_indicator is MSFLaw.separation_indicator and t.shear_lengths is MSFLaw.shear_lengths
            and t.tangential_stiffness is MSFLaw.tangential_stiffness and t.psi is ForceLaw.psi
            and t.kp is ForceLaw.kp and t.contact_normal_force is ForceLaw.contact_normal_force)


#: x/R is clamped just below 2 in the msf k_p, as ``geometry.kp_clamped``.
_KP_RATIO_MAX = 2.0 - 1e-12


def _scalar_kernels(law: ForceLaw, o1: dict):
    """Float functions of one contact for the integrator's right-hand side:

    - normal(x, x') -> (F_n after the separation rule, its elastic part F_n(x, 0)) [N],
    - kb(x) -> (tangential stiffness [N/m], damping [N s/m]) along the first axis,
    - indicator(x, x') -> B of F_n = S(x) B,
    - forces(x, x') -> normal(x, x') + kb(x) in one call (k_p evaluated once).

    x [m] >= 0, x' [m/s]; o1 the onset dict, (1,) arrays. For MSFLaw's own
    forces the same expressions in the same order as MSFLaw.normal_force,
    .separation_indicator and .tangential_stiffness with the math module (a
    call costs ~1 us instead of ~30 us through numpy); any other law through
    its own (n,) methods with n = 1.
    """
    if not _msf_inline(law):

        def normal(x, vx):
            xa = np.array([max(x, 0.0)])
            Fn = float(law.contact_normal_force(xa, np.array([vx]), o1)[0])
            Fc = float(law.normal_force(xa, np.array([0.0]), o1)[0])
            return Fn, Fc

        def kb(x):
            k, b = law.tangential_stiffness(np.array([max(x, 0.0)]), o1)
            return float(k[0, 0]), float(b[0, 0])

        def indicator(x, vx):
            return float(law.separation_indicator(np.array([x]), np.array([vx]), o1)[0])

        def forces(x, vx):
            return normal(x, vx) + kb(x)

        return normal, kb, indicator, forces

    g = law.geom
    R_a, R_b, k_ha = g.R_a, g.R_b, g.k_ha
    sq_a, sq_b = math.sqrt(R_a), math.sqrt(R_b)
    E, eta, G, eta_G = (float(o1[k][0]) for k in ("E", "eta_E", "G", "eta_Gy"))
    clamp = law.separation == "force-zero"
    if law.kp_mode == "msf":
        def kp(x, R):
            return math.sqrt(2.0 - min(x / R, _KP_RATIO_MAX))
    else:
        kp_const = math.sqrt(2.0) if law.kp_mode == "msf-small" else 1.0

        def kp(x, R):
            return kp_const

    def normal(x, vx):
        x = max(x, 0.0)
        base = (kp(x, R_a) * sq_a + kp(x, R_b) * sq_b) * math.sqrt(x)
        el = (2.0 / 3.0) * E * x
        F = base * (2.0 * eta * vx + el)
        return (max(F, 0.0) if clamp else F), base * el

    def kb(x):
        x = max(x, 0.0)
        P_bx = k_ha * x + 2.0 * kp(x, R_b) * math.sqrt(R_b * x)
        return G * P_bx, eta_G * P_bx

    def indicator(x, vx):
        return 2.0 * eta * vx + (2.0 / 3.0) * E * x

    same_radii = R_a == R_b

    def forces(x, vx):
        x = max(x, 0.0)
        kp_a = kp(x, R_a)
        kp_b = kp_a if same_radii else kp(x, R_b)
        base = (kp_a * sq_a + kp_b * sq_b) * math.sqrt(x)
        el = (2.0 / 3.0) * E * x
        F = base * (2.0 * eta * vx + el)
        P_bx = k_ha * x + 2.0 * kp_b * math.sqrt(R_b * x)
        return (max(F, 0.0) if clamp else F), base * el, G * P_bx, eta_G * P_bx

    return normal, kb, indicator, forces


def _opt(d, key):
    return float(d[key][0]) if key in d else None


def _refine_max(f, tt, k, best):
    from scipy.optimize import minimize_scalar

    lo, hi = tt[max(k - 1, 0)], tt[min(k + 1, len(tt) - 1)]
    if hi <= lo:
        return best
    r = minimize_scalar(lambda t: -f(t), bounds=(lo, hi), method="bounded",
                        options={"xatol": 1e-15 + 1e-12 * hi})
    return max(best, -float(r.fun))


def _inputs(b1, b2, speed, angle, spin, tangential, m, n_samples, tt, Fn, Ft, X):
    d = {
        "speed": speed, "angle_deg": angle, "spin": spin, "tangential": tangential,
        "mass_reduced": m, "body1": {"material": b1.material.name, "radius": b1.radius, "mass": b1.mass},
        "body2": {"material": b2.material.name, "radius": b2.radius, "mass": b2.mass},
    }
    if n_samples > 0:
        d["curves"] = {"t": tt.tolist(), "F_n": np.asarray(Fn).tolist(), "F_t": np.asarray(Ft[:, 0]).tolist(),
                       "x": np.asarray(X).tolist()}
    return d
