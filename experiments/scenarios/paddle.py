"""A paddle on a driven hinge striking a falling ball (robotics, ball sport).

The paddle is a box link on a hinge (axis +y through the origin, the paddle
along +x), in MuJoCo (:func:`engines.mujoco.scenes.paddle_and_ball`) and in
pybullet (:func:`engines.pybullet.scenes.paddle_and_ball`). The ball falls
at ``ball_speed`` onto the face at ``hit_at`` from the hinge while the
paddle swings up with ``u`` [m/s] at that point (hinge rate -u/hit_at).
Between ball and paddle: MSF through the adapters (the paddle is a link of
an articulated chain), or the engine's own contact with its default or its
calibrated parameters (:mod:`experiments.calibrate`, fitted at
``calibration_speed`` on a fixed plate).

Drives: ``free`` (no actuator force: the paddle is a free link of effective
mass I_hinge / hit_at^2 at the hit point) and ``driven`` (MuJoCo: velocity
actuator of gain ``drive_kv``; pybullet: velocity motor with at most
``drive_torque``), stiff enough to hold the swing rate through the contact.

The prediction in every record is the reference solver's for a ball on a
translating half-space of the paddle's effective mass M (inf when driven)
at the closing speed w = ball_speed + u: with COR e(w, M), the ball leaves
at v = (-m v_b + M u + M e w) / (m + M) (v = u + e w for M = inf). It
leaves out the paddle's turn during the contact and, in pybullet, the face
standing ht above the hinge axis (a tangential share ht/hit_at of u).

Configuration (TOML)::

    scenario = "paddle"
    [impact]   # the pair (plate = the paddle's face) and law: `msf-contact impact` flags
    ball = "natural-rubber"
    plate = "steel"
    radius = 0.02
    [paddle]   # length, half_width, half_thickness [m], mass [kg], hit_at [m], drive_kv, drive_torque
    [strike]   # ball_speed [m/s], paddle_speeds [m/s], drives, dt [s], phases, integrator (MuJoCo)
    [engines]  # run: mujoco, pybullet, mujoco-builtin, pybullet-builtin; builtin: default, calibrated;
               # calibration_speed [m/s]
"""

from __future__ import annotations

import functools
import itertools
import math
from pathlib import Path

from ..config import ConfigError, Field, validate
from . import Scenario
from .ball_on_plate import _flag_names, _impact_parser, parse_cell_args, to_argv

ENGINES = ("mujoco", "pybullet", "mujoco-builtin", "pybullet-builtin")
DRIVES = ("free", "driven")
BUILTIN = ("default", "calibrated")
RESERVED = ("speed", "angle", "spin", "engine", "dt", "gap", "integrator", "solref", "solimp", "restitution",
            "contact_stiffness", "contact_damping", "gravity", "json")
#: A strike gives up after this many Hertz contact durations past the flight over the gap.
MAX_DURATIONS = 200.0
#: A built-in contact still pressing this many Hertz durations after its onset
#: carries the ball (e.g. pybullet's default restitution 0): the strike ends
#: there, recorded as ``carried``, with the ball's velocity then.
CARRY_DURATIONS = 10.0
#: A strike rebounds when the ball leaves the paddle at more than this share
#: of the closing speed (relative COR (v_z - u_after)/w): below it the ball
#: rests on the face (pybullet's default restitution 0 on a driven paddle at
#: u = 0 leaves v_z ~ 1e-5 m/s, whose "direction" arctan(v_x/v_z) read +90
#: degrees). The lowest real rebound here is MuJoCo's default contact, ~0.1.
REBOUND_COR_MIN = 0.01

SCHEMA = {
    "": {"scenario": Field("str", required=True), "title": Field("str", default="Paddle striking a ball")},
    "paddle": {
        "length": Field("float", default=0.3, lo=0.0, lo_open=True, help="along +x from the hinge [m]"),
        "half_width": Field("float", default=0.05, lo=0.0, lo_open=True, help="[m]"),
        "half_thickness": Field("float", default=0.005, lo=0.0, lo_open=True, help="[m]"),
        "mass": Field("float", default=0.5, lo=0.0, lo_open=True, help="[kg]"),
        "hit_at": Field("float", default=0.2, lo=0.0, lo_open=True, help="hit point from the hinge [m]"),
        "drive_kv": Field("float", default=1e4, lo=0.0, lo_open=True,
                          help="MuJoCo velocity actuator gain of the driven paddle [N m s/rad]"),
        "drive_torque": Field("float", default=1000.0, lo=0.0, lo_open=True,
                              help="pybullet motor torque limit of the driven paddle [N m]"),
    },
    "strike": {
        "ball_speed": Field("float", default=1.0, lo=0.0, lo_open=True, help="ball's fall speed [m/s]"),
        "paddle_speeds": Field("list[float]", default=[0.0, 0.5, 1.0, 2.0, 4.0], lo=0.0,
                               help="upward speed of the paddle's hit point [m/s]"),
        "drives": Field("list[str]", default=list(DRIVES), choices=DRIVES),
        "dt": Field("list[float]", default=[1e-4, 1e-3], lo=0.0, hi=0.01, lo_open=True, help="[s]"),
        "phases": Field("int", default=4, lo=1, hi=64, help="onset phases per strike (mean and spread)"),
        "integrator": Field("str", default="implicitfast", choices=("euler", "rk4", "implicitfast"),
                            help="MuJoCo's (implicitfast keeps a stiff velocity actuator stable)"),
    },
    "engines": {
        "run": Field("list[str]", default=list(ENGINES), choices=ENGINES),
        "builtin": Field("list[str]", default=list(BUILTIN), choices=BUILTIN,
                         help="parameters of the built-in contact: engine defaults and/or calibrated"),
        "calibration_speed": Field("float", default=2.0, lo=0.0, lo_open=True,
                                   help="closing speed at which the built-in contact is calibrated [m/s]"),
    },
}


def load(raw: dict, path: str) -> dict:
    impact = raw.get("impact", {})
    if not isinstance(impact, dict):
        raise ConfigError(f"{path}: [impact] must be a table")
    cfg = validate({k: v for k, v in raw.items() if k != "impact"}, SCHEMA, path)
    for k in RESERVED:
        if k in impact:
            raise ConfigError(f"{path}: [impact.{k}] is set by the paddle scenario ([strike]); remove it")
    cfg["impact"] = impact
    cfg["impact_argv"] = to_argv(impact, _flag_names(_impact_parser()), path, "impact")
    p, s = cfg["paddle"], cfg["strike"]
    if p["hit_at"] >= p["length"]:
        raise ConfigError(f"{path}: [paddle.hit_at] = {p['hit_at']!r} m must be < [paddle.length] = "
                          f"{p['length']!r} m (on the paddle)")
    for key in ("paddle_speeds", "dt"):
        if len(set(s[key])) != len(s[key]):
            raise ConfigError(f"{path}: [strike.{key}] repeats a value")
    fastest = s["ball_speed"] + max(s["paddle_speeds"])
    for v, key in ((fastest, "strike.paddle_speeds"), (cfg["engines"]["calibration_speed"],
                                                       "engines.calibration_speed")):
        try:
            _setup(tuple(cfg["impact_argv"]), v)
        except ValueError as exc:
            raise ConfigError(f"{path}: [{key}] closing speed {v:g} m/s: {exc}") from None
    return cfg


def cells(cfg: dict) -> list[dict]:
    s, e = cfg["strike"], cfg["engines"]
    base = {"scenario": "paddle", "argv": cfg["impact_argv"], "paddle": cfg["paddle"],
            "ball_speed": s["ball_speed"], "phases": s["phases"], "integrator": s["integrator"],
            "calibration_speed": e["calibration_speed"]}
    out = []
    for dt, eng, drive, u in itertools.product(s["dt"], e["run"], s["drives"], s["paddle_speeds"]):
        variants = e["builtin"] if eng.endswith("-builtin") else ["msf"]
        for var in variants:
            out.append(dict(base, dt=dt, engine=eng, contact=var, drive=drive, u=float(u)))
    return out


@functools.lru_cache(maxsize=16)
def _setup(argv: tuple, speed: float):
    import warnings

    from .. import impact

    args = parse_cell_args(list(argv) + ["--speed", repr(float(speed))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return impact.build_impact(args)


@functools.lru_cache(maxsize=16)
def _calibrated(argv: tuple, speed: float, dt: float, phases: int, integrator: str, form: str) -> dict:
    from ..calibrate import Problem, calibrate

    s = _setup(argv, speed)
    p = Problem(s.law, s.ball, s.plate, speed, dt, phases=phases, integrator=integrator)
    _, fits = calibrate(p, (form,))
    return fits[form].params


# ------------------------------------------------------------ prediction ---
def predicted_rebound(law, ball, face, v_ball: float, u: float, m_eff: float) -> dict:
    """The reference solver's rebound of the ball (upward velocity [m/s]) off
    a translating face of effective mass ``m_eff`` [kg] (inf: driven) moving
    up at ``u`` [m/s], the ball falling at ``v_ball`` [m/s]."""
    import warnings

    from msf_contact.solver import Body, simulate_impact

    w = v_ball + u
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = simulate_impact(law, ball, Body(face.material, math.inf, m_eff), w)
    e, m = rec.cor_n, ball.mass
    v = u + e * w if math.isinf(m_eff) else (-m * v_ball + m_eff * u + m_eff * e * w) / (m + m_eff)
    return {"v_out": v, "cor": e, "tau": rec.tau, "m_eff": m_eff}


# ----------------------------------------------------------------- MuJoCo ---
def _mujoco_model(ball, pad: dict, v_ball: float, u: float, drive: str, dt: float, gap: float, integrator: str,
                  builtin: dict | None):
    import mujoco

    from engines.mujoco import scenes

    kv = pad["drive_kv"] if drive == "driven" else 0.0
    opts = None if builtin is None else dict(builtin, condim=1)
    model, data = scenes.paddle_and_ball(ball, v_ball, paddle_mass=pad["mass"],
                                         paddle_half_size=(pad["length"] / 2, pad["half_width"],
                                                           pad["half_thickness"]),
                                         hit_x=pad["hit_at"], gap=gap, dt=dt, integrator=integrator,
                                         actuator="velocity", kv=kv, builtin=opts)
    omega = -u / pad["hit_at"]
    data.qvel[model.jnt_dofadr[model.joint("hinge").id]] = omega
    data.ctrl[0] = omega
    mujoco.mj_forward(model, data)
    return model, data, scenes.hinge_inertia(model) / pad["hit_at"] ** 2


def _mujoco_state(model, data) -> tuple[float, float, float]:
    """(ball vx, ball vz, hinge rate) now."""
    bq = model.jnt_dofadr[model.joint("ball_free").id]
    return float(data.qvel[bq]), float(data.qvel[bq + 2]), float(data.qvel[model.jnt_dofadr[model.joint("hinge").id]])


def _mujoco_ball(model, data) -> dict:
    """The ball's centre x, z [m] and spin about +y [rad/s] now (for momentum bookkeeping)."""
    bq = model.jnt_qposadr[model.joint("ball_free").id]
    bv = model.jnt_dofadr[model.joint("ball_free").id]
    return {"x": float(data.qpos[bq]), "z": float(data.qpos[bq + 2]), "wy": float(data.qvel[bv + 4])}


def strike_mujoco(law, ball, pad: dict, v_ball: float, u: float, drive: str, dt: float, gap: float,
                  integrator: str, builtin: dict | None) -> dict:
    """One strike in MuJoCo; MSF through the adapter (``builtin`` None) or
    MuJoCo's own contact (``builtin``: solref, solimp)."""
    import mujoco
    import numpy as np

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, run_until_separated
    from msf_contact import closed_forms as cf

    model, data, m_eff = _mujoco_model(ball, pad, v_ball, u, drive, dt, gap, integrator, builtin)
    w = v_ball + u
    tau_h = float(cf.hertz_tau(ball.mass, w, law.moduli.E, law.geom.R))
    max_steps = int(math.ceil((gap / w + MAX_DURATIONS * tau_h) / dt)) + 10
    carry_steps = int(math.ceil(CARRY_DURATIONS * tau_h / dt))
    out = {"m_eff": m_eff}
    if builtin is None:
        rec = run_until_separated(MujocoAdapter(model, data, [PairSpec("ball", "paddle", law)]), max_steps)
        out.update(cor_n=float(rec.cor_n), tau=float(rec.tau))
    else:
        g_ball, g_pad = model.geom("ball").id, model.geom("paddle").id
        b_pad = int(model.geom_bodyid[g_pad])
        res, jac = np.zeros(6), np.zeros((3, model.nv))
        n_force, onset, carried = 0, None, False
        for k in range(max_steps):
            mujoco.mj_step(model, data)
            F = 0.0
            for c in range(data.ncon):
                con = data.contact[c]
                if {int(con.geom[0]), int(con.geom[1])} == {g_ball, g_pad} and con.efc_address >= 0:
                    mujoco.mj_contactForce(model, data, c, res)
                    F += float(res[0])
            onset = k if onset is None and F > 0 else onset
            if onset is not None and k - onset >= carry_steps:
                carried = True
                mujoco.mj_forward(model, data)
                break
            if F > 0:
                n_force += 1
                continue
            if onset is not None:
                mujoco.mj_forward(model, data)
                n = data.geom_xmat[g_pad].reshape(3, 3)[:, 2]
                point = data.geom_xpos[g_ball] - ball.radius * n
                mujoco.mj_jac(model, data, jac, None, point, b_pad)
                vx, vz, _ = _mujoco_state(model, data)
                if float((np.array([vx, 0.0, vz]) - jac @ data.qvel) @ n) > 0:
                    break
        else:
            raise RuntimeError(f"the ball did not reach the paddle within {max_steps} steps of dt = {dt!r} s")
        out.update(tau=n_force * dt, carried=carried)
    vx, vz, rate = _mujoco_state(model, data)
    return dict(out, vx=vx, vz=vz, u_after=-rate * pad["hit_at"], **_mujoco_ball(model, data))


# --------------------------------------------------------------- pybullet ---
def strike_pybullet(law, ball, pad: dict, v_ball: float, u: float, drive: str, dt: float, gap: float,
                    builtin) -> dict:
    """One strike in pybullet; MSF through the adapter (``builtin`` None) or
    pybullet's own contact (``builtin``: a BuiltinContact)."""
    import numpy as np
    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter, scenes
    from engines.pybullet import builtin as pbb
    from msf_contact import closed_forms as cf

    paddle = scenes.Paddle(pad["length"], pad["half_width"], pad["half_thickness"], pad["mass"])
    d = pad["hit_at"]
    omega = -u / d
    driven = drive == "driven"
    scene = scenes.paddle_and_ball(ball, paddle, d, v_ball, dt=dt, gap=gap, motor_velocity=omega if driven else 0.0,
                                   motor_force=pad["drive_torque"] if driven else 0.0)
    c = scene.client
    (ub, _), (up, lp) = scene.body1, scene.body2
    w = v_ball + u
    tau_h = float(cf.hertz_tau(ball.mass, w, law.moduli.E, law.geom.R))
    max_steps = int(math.ceil((gap / w + MAX_DURATIONS * tau_h) / dt)) + 10
    carry_steps = int(math.ceil(CARRY_DURATIONS * tau_h / dt))
    out = {"m_eff": paddle.effective_mass(d)}
    try:
        pb.resetJointState(up, lp, 0.0, targetVelocity=omega, physicsClientId=c)
        if builtin is None:
            with PybulletAdapter(c, [PairSpec(scene.body1, scene.body2, law)]) as ad:
                for _ in range(max_steps):
                    ad.step()
                    if ad.records:
                        break
                else:
                    raise RuntimeError(f"the MSF strike did not end within {max_steps} steps of dt = {dt!r} s")
                out.update(cor_n=float(ad.records[0].cor_n), tau=float(ad.records[0].tau), **_pybullet_state(c, ub, up, lp, d))
        else:
            pbb.apply(c, (scene.body1, scene.body2), builtin)
            n_force, onset, carried = 0, None, False
            for k in range(max_steps):
                pb.stepSimulation(physicsClientId=c)
                F = sum(cp[9] for cp in pb.getContactPoints(ub, up, -1, lp, physicsClientId=c))
                onset = k if onset is None and F > 0 else onset
                if onset is not None and k - onset >= carry_steps:
                    carried = True
                    break
                if F > 0:
                    n_force += 1
                    continue
                if onset is not None:
                    ls = pb.getLinkState(up, lp, computeLinkVelocity=1, computeForwardKinematics=1,
                                         physicsClientId=c)
                    rot = np.array(pb.getMatrixFromQuaternion(ls[5])).reshape(3, 3)
                    n = rot[:, 2]
                    pos_b = np.array(pb.getBasePositionAndOrientation(ub, physicsClientId=c)[0])
                    point = pos_b - ball.radius * n
                    v_pt = np.array(ls[6]) + np.cross(ls[7], point - np.array(ls[0]))
                    v_b = np.array(pb.getBaseVelocity(ub, physicsClientId=c)[0])
                    if float((v_b - v_pt) @ n) > 0:
                        break
            else:
                raise RuntimeError(f"the ball did not reach the paddle within {max_steps} steps of dt = {dt!r} s")
            out.update(tau=n_force * dt, carried=carried, **_pybullet_state(c, ub, up, lp, d))
    finally:
        scene.close()
    return out


def _pybullet_state(c: int, ub: int, up: int, lp: int, d: float) -> dict:
    """Ball velocity (vx, vz) [m/s], centre (x, z) [m], spin wy [rad/s] and the
    paddle's hit-point speed u_after [m/s] now."""
    import pybullet as pb

    v, w = pb.getBaseVelocity(ub, physicsClientId=c)
    pos = pb.getBasePositionAndOrientation(ub, physicsClientId=c)[0]
    rate = pb.getJointState(up, lp, physicsClientId=c)[1]
    return {"vx": float(v[0]), "vz": float(v[2]), "u_after": -float(rate) * d, "x": float(pos[0]),
            "z": float(pos[2]), "wy": float(w[1])}


# ------------------------------------------------------------------- cell ---
def _rebounded(r: dict, phases: int) -> bool:
    """A strike with a rebound: the ball leaves upward (v_z > 0), away from
    the paddle faster than REBOUND_COR_MIN of the closing speed, and was not
    carried by the paddle in every onset phase."""
    return r["vz"] > 0 and r["cor_rel"] > REBOUND_COR_MIN and r["carried"] < phases


def run_cell(cell: dict) -> list[dict]:
    import numpy as np

    from ..calibrate import phase_gaps

    argv = tuple(cell["argv"])
    pad, v_b, u, dt = cell["paddle"], cell["ball_speed"], cell["u"], cell["dt"]
    w = v_b + u
    s = _setup(argv, w)
    eng, contact, drive = cell["engine"], cell["contact"], cell["drive"]
    params = None
    builtin = None
    if eng == "mujoco-builtin":
        from ..engine_cli import MUJOCO_DEFAULT_SOLIMP, MUJOCO_DEFAULT_SOLREF

        params = ({"solref": list(MUJOCO_DEFAULT_SOLREF), "solimp": list(MUJOCO_DEFAULT_SOLIMP)}
                  if contact == "default" else
                  _calibrated(argv, cell["calibration_speed"], dt, cell["phases"], cell["integrator"],
                              "mujoco-solref"))
        builtin = {"solref": tuple(params["solref"]), "solimp": tuple(params["solimp"])}
    elif eng == "pybullet-builtin":
        from engines.pybullet.builtin import BuiltinContact

        if contact == "default":
            params = {"restitution": None, "restitution_settings": False}
            builtin = BuiltinContact(restitution_settings=False)
        else:
            params = _calibrated(argv, cell["calibration_speed"], dt, cell["phases"], cell["integrator"],
                                 "pybullet-restitution")
            builtin = BuiltinContact(restitution=params["restitution"])
    runs = []
    for g in phase_gaps(w, 90.0, dt, cell["phases"]):
        if eng.startswith("mujoco"):
            runs.append(strike_mujoco(s.law, s.ball, pad, v_b, u, drive, dt, g, cell["integrator"], builtin))
        else:
            runs.append(strike_pybullet(s.law, s.ball, pad, v_b, u, drive, dt, g, builtin))
    m_eff = runs[0]["m_eff"]
    pred = predicted_rebound(s.law, s.ball, s.plate, v_b, u, math.inf if drive == "driven" else m_eff)
    vx = np.array([r["vx"] for r in runs])
    vz = np.array([r["vz"] for r in runs])
    speed = np.hypot(vx, vz)
    direction = np.degrees(np.arctan2(vx, vz))
    rec = {
        "engine": eng, "contact": contact, "params": params,
        "vx": float(vx.mean()), "vz": float(vz.mean()),
        "rebound_speed": float(speed.mean()), "rebound_speed_min": float(speed.min()),
        "rebound_speed_max": float(speed.max()),
        "direction_deg": float(direction.mean()), "direction_deg_min": float(direction.min()),
        "direction_deg_max": float(direction.max()),
        "u_after": float(np.mean([r["u_after"] for r in runs])),
        "cor_rel": float(np.mean([(r["vz"] - r["u_after"]) / w for r in runs])),
        "tau": float(np.mean([r["tau"] for r in runs])),
        "m_eff": m_eff, "m_ball": s.ball.mass,
        "pred_v_out": pred["v_out"], "pred_cor": pred["cor"], "pred_tau": pred["tau"],
        "cor_n": float(np.mean([r["cor_n"] for r in runs])) if "cor_n" in runs[0] else None,
        "carried": int(sum(bool(r.get("carried")) for r in runs)),
    }
    return [rec]


# ----------------------------------------------------------------- report ---
#: line format and marker of each (engine, contact): the curves that agree (MSF in both engines, the
#: calibrated built-ins) stay visible over each other, MuJoCo's wide with large hollow markers,
#: pybullet's thin with small filled ones on top
STYLE = {("mujoco", "msf"): ("C0-", {"marker": "o", "ms": 9, "mfc": "none", "lw": 2.4}),
         ("pybullet", "msf"): ("C1-", {"marker": "s", "ms": 4, "lw": 1.0}),
         ("mujoco-builtin", "default"): ("C0:", {"marker": "x", "ms": 6}),
         ("mujoco-builtin", "calibrated"): ("C0--", {"marker": "^", "ms": 9, "mfc": "none", "lw": 2.0}),
         ("pybullet-builtin", "default"): ("C1:", {"marker": "+", "ms": 6}),
         ("pybullet-builtin", "calibrated"): ("C1--", {"marker": "v", "ms": 4, "lw": 1.0})}


def _label(eng, contact):
    return f"MSF in {eng}" if contact == "msf" else f"{eng} ({contact})"


def report(out: Path, rows: list[dict], cfg: dict) -> tuple[str, list[str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import add_figure, figure_links

    s, p = cfg["strike"], cfg["paddle"]
    figs: list[str] = []
    lines = [f"# {cfg['']['title']}\n\n",
             f"Pair: {', '.join(f'{k} = {v}' for k, v in cfg['impact'].items())}. Paddle {p['length']:g} m x "
             f"{2 * p['half_width']:g} m x {2 * p['half_thickness']:g} m, {p['mass']:g} kg, hit {p['hit_at']:g} m "
             f"from the hinge; ball falling at {s['ball_speed']:g} m/s; paddle speed u at the hit point (upward). "
             f"Means over {s['phases']} onset phases (range in brackets). Prediction: the reference solver with "
             "the paddle's effective mass at the hit point (inf when driven), no turn of the face. Built-in "
             f"'calibrated' = fitted at {cfg['engines']['calibration_speed']:g} m/s closing speed "
             "(experiments/calibrate.py). Direction: angle of the rebound from vertical, + away from the hinge. "
             "Carried: onset phases in which the built-in contact still pressed 10 Hertz durations after onset "
             "(the ball rides on the paddle; its velocity then is shown).\n\n"]
    for dt, drive in itertools.product(s["dt"], s["drives"]):
        sel = [r for r in rows if r["cell.dt"] == dt and r["cell.drive"] == drive]
        if not sel:
            continue
        lines.append(f"## {drive} paddle, dt = {dt:g} s\n\n"
                     "| u [m/s] | contact | rebound speed [m/s] | predicted v_z [m/s] | v_z vs prediction | "
                     "direction [deg] | relative COR | tau [ms] | paddle u after [m/s] | carried |\n"
                     "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|\n")
        for r in sorted(sel, key=lambda r: (r["cell.u"], ENGINES.index(r["cell.engine"]), r["cell.contact"])):
            if _rebounded(r, s["phases"]):
                err = f"{100.0 * (r['vz'] - r['pred_v_out']) / abs(r['pred_v_out']):+.2f}%"
                direction = f"{r['direction_deg']:+.2f}"
            else:  # no rebound (the ball does not leave upward, or rides on the paddle): no value to compare
                err = direction = "no rebound"
            lines.append(f"| {r['cell.u']:g} | {_label(r['cell.engine'], r['cell.contact'])} | "
                         f"{r['rebound_speed']:.4f} [{r['rebound_speed_min']:.4f}..{r['rebound_speed_max']:.4f}] | "
                         f"{r['pred_v_out']:.4f} | {err} | {direction} | {r['cor_rel']:.4f} | "
                         f"{1e3 * r['tau']:.3f} | {r['u_after']:.4f} | {r['carried']}/{s['phases']} |\n")
        lines.append("\n")
        fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
        keys = sorted({(r["cell.engine"], r["cell.contact"]) for r in sel}, key=lambda k: (ENGINES.index(k[0]), k[1]))
        for key in keys:
            pts = sorted((r["cell.u"], r) for r in sel if (r["cell.engine"], r["cell.contact"]) == key)
            us = [u for u, _ in pts]
            ls, mk = STYLE[key]
            axes[0].plot(us, [r["rebound_speed"] for _, r in pts], ls, label=_label(*key), **mk)
            axes[0].fill_between(us, [r["rebound_speed_min"] for _, r in pts],
                                 [r["rebound_speed_max"] for _, r in pts], color=ls[:2], alpha=0.1)
            axes[1].plot(us, [r["direction_deg"] if _rebounded(r, s["phases"]) else float("nan") for _, r in pts],
                         ls, label=_label(*key), **mk)
        for eng in ("mujoco", "pybullet"):
            pts = sorted((r["cell.u"], r) for r in sel if r["cell.engine"] == eng)
            if pts:
                axes[0].plot([u for u, _ in pts], [r["pred_v_out"] for _, r in pts], "k", lw=0.8, alpha=0.6,
                             label=f"prediction ({eng} paddle)" if eng == "mujoco" else None)
        axes[0].set_ylabel("ball rebound speed [m/s]")
        axes[1].set_ylabel("rebound direction from vertical [deg]")
        for ax in axes:
            ax.set_xlabel("paddle speed at the hit point [m/s]")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        fig.suptitle(f"{drive} paddle, dt = {dt:g} s, ball falling at {s['ball_speed']:g} m/s")
        add_figure(fig, out, f"paddle_{drive}_dt{dt:g}.png", figs)
    lines.append(figure_links(figs))
    return "".join(lines), figs


SCENARIO = Scenario("paddle", "a paddle on a driven hinge striking a ball: MSF vs built-in contact",
                    load, cells, run_cell, report)
