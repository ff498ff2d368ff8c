"""MuJoCo's own soft contact, run on the same isolated impact for comparison.

Both geoms get the same ``solref`` and ``solimp`` with equal ``priority``
(0) and ``solmix`` (1). MuJoCo mixes the two geoms' values: with different
priorities the higher one wins, otherwise a solmix-weighted average, and if
either solref is in the direct (negative) format the element-wise minimum
(MuJoCo docs, "solref, solimp" under contact parameters). With identical
values on both geoms every rule returns the given values, so the contact
uses exactly what the user set.

What to expect (MuJoCo docs, modeling "solref"): the constraint makes the
penetration r follow r'' = -d b r' - d k r with impedance d from ``solimp``.
In the (timeconst, dampratio) format b = 2/(d_w timeconst) and
k = d(r)/(d_w^2 timeconst^2 dampratio^2), so with a constant impedance
(solimp d0 = d_width) the contact is a linear oscillator whose damping ratio
is ``dampratio``, whatever the mass and the impact speed: the restitution
depends on the damping ratio alone. Contact ends when the (unilateral)
force returns to zero, before the overlap does, so the linear-oscillator
formula exp(-zeta pi / sqrt(1 - zeta^2)) (overlap-zero end) is only an
approximation; :func:`linear_oscillator_cor` with end="force-zero" is the
exact limit (measured at dt = timeconst/1000, Euler: within 0.09% for
zeta = 0.1, 0.2, 0.4, where the overlap-zero formula is 2%, 9% and 43% low).

The record: cor_n from the normal velocities before and after; tau from the
steps in which the contact's normal force (``mj_contactForce``) is non-zero
(resolution dt); x_max from the largest penetration (-contact.dist); F_max
the largest normal force. Quantities the built-in model does not have
(works of elastic and viscous forces, pressures, omega_x) are None.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from msf_contact._validate import check_choice, check_finite
from msf_contact.record import ImpactRecord
from msf_contact.solver import Body, reduced_mass

from ..contract import check_step_budget
from . import scenes

#: MuJoCo's default impedance (solimp) when none is given.
DEFAULT_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)
#: A run gives up after this many estimated contact durations past the
#: flight over the gap (the contact never ended: a capture).
MAX_DURATIONS = 200.0
#: f = |F_t|/F_n is reported only while F_n >= this share of F_max (as the reference solver).
F_RATIO_FLOOR = 0.01


def check_builtin(builtin) -> tuple[tuple[float, float], tuple[float, ...]]:
    """(solref, solimp) from a dict with "solref" (2 numbers) and optional
    "solimp" (3 or 5 numbers); ValueError naming what is wrong."""
    if not isinstance(builtin, dict):
        raise ValueError(f"builtin = {builtin!r} must be a dict with 'solref' (and optionally 'solimp')")
    unknown = set(builtin) - {"solref", "solimp", "condim", "friction"}
    if unknown:
        raise ValueError(f"builtin has unknown keys {sorted(unknown)}; valid: solref, solimp, condim, friction")
    if "solref" not in builtin:
        raise ValueError("builtin['solref'] is missing: give (timeconst, dampratio) or (-stiffness, -damping)")
    solref = tuple(float(v) for v in builtin["solref"])
    if len(solref) != 2:
        raise ValueError(f"builtin['solref'] = {builtin['solref']!r} must have 2 numbers")
    check_finite("solref", solref)
    if not ((solref[0] > 0 and solref[1] > 0) or (solref[0] < 0 and solref[1] <= 0)):
        raise ValueError(f"solref = {solref!r} must be (timeconst > 0, dampratio > 0) or "
                         "(-stiffness < 0, -damping <= 0)")
    solimp = tuple(float(v) for v in builtin.get("solimp", DEFAULT_SOLIMP))
    if len(solimp) not in (3, 5):
        raise ValueError(f"builtin['solimp'] = {builtin.get('solimp')!r} must have 3 or 5 numbers")
    check_finite("solimp", solimp)
    for k, v in enumerate(solimp[:2]):
        if not 0.0 < v < 1.0:
            raise ValueError(f"solimp[{k}] = {v!r} (impedance) must be in (0, 1)")
    return solref, solimp


def _duration_estimate(solref) -> float:
    """Half a period of MuJoCo's contact oscillator [s] (an upper bound scale)."""
    if solref[0] > 0:
        tc, zeta = solref
        return math.pi * tc * max(zeta, 1.0)
    return math.pi / math.sqrt(-solref[0])


def builtin_impact(
    body1: Body,
    body2: Body,
    speed: float,
    angle_deg: float = 90.0,
    spin: float = 0.0,
    *,
    builtin: dict,
    dt: float = 1e-4,
    gap: float = 0.0,
    gravity: float | None = None,
    integrator: str = "euler",
    plate: str = "plane",
) -> ImpactRecord:
    """The isolated impact of body 1 on body 2 with MuJoCo's own soft contact
    (``builtin``: dict with solref, solimp, optional condim (default 1:
    frictionless) and friction). Body 2 with an infinite radius is a fixed
    plate, otherwise a free sphere."""
    solref, solimp = check_builtin(builtin)
    scenes.check_common(dt, integrator, gap, gravity)
    if math.isinf(body1.mass) or math.isinf(body1.radius):
        raise ValueError("body1 (the ball) must have a finite mass and radius")
    opts = {"solref": solref, "solimp": solimp, "condim": int(builtin.get("condim", 1))}
    if "friction" in builtin:
        opts["friction"] = tuple(builtin["friction"])
    if math.isinf(body2.radius):
        model, data = scenes.ball_on_plate(body1, speed, angle_deg, spin, gap=gap, dt=dt, integrator=integrator,
                                           gravity=gravity, plate=plate, builtin=opts)
        other = "plate"
    else:
        model, data = scenes.two_spheres(body1, body2, speed, angle_deg, spin, gap=gap, dt=dt,
                                         integrator=integrator, gravity=gravity, builtin=opts)
        other = "ball2"
    g1, g2 = model.geom("ball").id, model.geom(other).id
    b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
    m = reduced_mass(body1.mass, body2.mass)
    vt0, vn0 = scenes.initial_velocity(speed, angle_deg)
    n = np.array([0.0, 0.0, 1.0])
    t = np.array([1.0, 0.0, 0.0])
    axis = np.cross(n, t)
    R1, R2 = body1.radius, body2.radius

    def rel(b):
        res = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, b, res, 0)
        return res

    max_steps = check_step_budget(math.ceil((gap / vn0 + MAX_DURATIONS * _duration_estimate(solref)) / dt) + 1000,
                                  dt, gap, f"gap/V_n + {MAX_DURATIONS:g} durations of the solref")
    forces, frictions, depths, times = [], [], [], []
    started = ended = False
    res6 = np.zeros(6)
    for _ in range(max_steps):
        mujoco.mj_step(model, data)
        # data.contact / efc_force belong to the state at the start of this step
        Fn = Ft = 0.0
        depth = 0.0
        for c in range(data.ncon):
            con = data.contact[c]
            if {int(con.geom[0]), int(con.geom[1])} != {g1, g2} or con.efc_address < 0:
                continue
            mujoco.mj_contactForce(model, data, c, res6)
            Fn += float(res6[0])
            Ft += float(np.hypot(res6[1], res6[2]))
            depth = max(depth, -float(con.dist))
        if Fn > 0.0:
            if not started:
                started = True
            forces.append(Fn)
            frictions.append(Ft)
            depths.append(depth)
            times.append(float(data.time) - dt)
        elif started:
            mujoco.mj_forward(model, data)
            v = rel(b1)[3:] - rel(b2)[3:]
            if float(v @ n) > 0.0:
                ended = True
                break
    if not ended:
        raise RuntimeError(f"the built-in contact did not end within {max_steps} steps of dt = {dt!r} s "
                           f"(solref = {solref}): a capture or a contact far longer than expected")
    w1 = rel(b1)[:3]
    w2 = rel(b2)[:3]
    v = rel(b1)[3:] - rel(b2)[3:]
    v_out_n = float(v @ n)
    vt_out = float(v @ t)
    tau = len(forces) * dt
    k_max = int(np.argmax(forces))
    tau1 = (k_max + 1) * dt
    tau2 = tau - tau1
    F = np.array(forces)
    mask = F >= F_RATIO_FLOOR * F.max()
    ratio = np.array(frictions)[mask] / F[mask]
    J1, J2 = body1.J, body2.J
    spin_out = float(w1 @ axis)
    u_in = vt0 - spin * R1
    lever2 = 0.0 if math.isinf(R2) else R2
    u_out = vt_out - spin_out * R1 - float(w2 @ axis) * lever2
    KE_t_in = 0.5 * m * vt0**2 + 0.5 * J1 * spin**2
    J2_term = 0.0 if math.isinf(J2) else 0.5 * J2 * float(w2 @ axis) ** 2
    KE_t_out = 0.5 * m * vt_out**2 + 0.5 * J1 * spin_out**2 + J2_term
    return ImpactRecord(
        cor_n=max(v_out_n, 0.0) / vn0,
        cor_t=vt_out / vt0 if vt0 != 0 else None,
        cor_t_contact=-u_out / u_in if abs(u_in) > 1e-12 * speed else None,
        cor_tau_ratio=tau1 / tau2 if tau2 > 0 else 0.0,
        tau=tau, tau1=tau1, tau2=tau2, x_max=float(max(depths)), F_max=float(F.max()),
        Pc_max=None, Pc_at_Fmax=None,
        W_el_comp=None, W_visc_comp=None, W_el_rest=None, W_visc_rest=None,
        W_diss_n=0.5 * m * (vn0**2 - v_out_n**2), W_diss_t=KE_t_in - KE_t_out, Q_t=None,
        spin_in=float(spin), spin_out=spin_out,
        f_min=float(ratio.min()) if ratio.size else None, f_max=float(ratio.max()) if ratio.size else None,
        omega_x=None, omega_y=None, ended_by="force-zero", law="mujoco-soft", engine="mujoco-builtin", dt=dt,
        parameters={"law": "mujoco-soft", "solref": list(solref), "solimp": list(solimp),
                    "condim": opts["condim"], "friction": list(opts.get("friction", (1.0, 0.005, 0.0001))),
                    "mixing": "same solref/solimp on both geoms, priority 0, solmix 1",
                    "integrator": integrator, "t_onset": times[0]},
        inputs={"speed": speed, "angle_deg": angle_deg, "spin": spin, "gap": gap, "gravity": gravity,
                "mass_reduced": m,
                "body1": {"material": body1.material.name, "radius": R1, "mass": body1.mass},
                "body2": {"material": body2.material.name, "radius": R2, "mass": body2.mass}},
    )


def linear_oscillator_cor(dampratio: float, end: str = "overlap-zero") -> float:
    """COR of a linear spring-dashpot x'' + 2 zeta w x' + w^2 x = 0 with damping
    ratio zeta = ``dampratio`` < 1.

    end = "overlap-zero": the contact ends when x returns to 0,
    exp(-zeta pi / sqrt(1 - zeta^2)). end = "force-zero": it ends when the
    force w^2 x + 2 zeta w x' returns to 0 (a unilateral contact, MuJoCo's),
    at w_d t = atan2(-2 zeta sqrt(1-zeta^2), 1 - 2 zeta^2) + pi, with the
    speed then |x'(t)| / x'(0)."""
    check_choice("end", end, ("overlap-zero", "force-zero"))
    z = float(dampratio)
    if not 0.0 <= z < 1.0:
        raise ValueError(f"dampratio = {dampratio!r} must be in [0, 1) for a bouncing oscillator")
    wd = math.sqrt(1.0 - z * z)
    if end == "overlap-zero":
        return math.exp(-z * math.pi / wd)
    th = math.atan2(-2.0 * z * wd, 1.0 - 2.0 * z * z) + math.pi  # w_d t at force zero
    t = th / wd  # in units of 1/w_n
    return -math.exp(-z * t) * (wd * math.cos(th) - z * math.sin(th)) / wd
