"""A driven paddle (a MuJoCo mocap body; a pybullet mass-0 body moved with
resetBasePositionAndOrientation) pressing a rubber ball slowly onto a steel floor, then holding it
(engines._kinematic): the islands' energy account with the paddle's work credited, each
contact's force against the elastic law at its internal overlap (on the way down and at rest),
and the overlaps' sum against the paddle's travel.

    PYTHONPATH=. .venv/bin/python scripts/kinematic_squeeze.py [mujoco|pybullet] [V_mm_s] [dt]
"""
from __future__ import annotations

import sys
import warnings

import numpy as np

from engines.base import PairSpec
from msf_contact import Body, ContactPair, Curvature, make_law, preset
from msf_contact.statics import elastic_force

R = 0.02  # ball radius [m]
HALF = 0.01  # the box paddle's half thickness [m]
GAP = 5e-4  # the paddle face's height above the ball's top at the start [m]


def _normal_forces(ad) -> dict:
    """{pair: F_n [N]} of the last step (adapter.contact_forces)."""
    return {r.pair: float(r.F_n) for r in ad.contact_forces()}


def _elastic(law, st) -> float:
    o = {k: np.array([v]) for k, v in st["onset"].items() if v is not None}
    return float(elastic_force(law, [st["x"]], o)[0])


def run(engine: str = "mujoco", V: float = 5e-3, dt: float = 1e-3, shape: str = "box", press: float = 2e-3,
        hold: float = 0.1, gravity: float = 9.81) -> dict:
    """Drive the paddle down at V [m/s] from GAP above the ball's top by press + GAP, then hold it
    for ``hold`` s. Returns the last step's numbers and the press's largest viscous share
    |F - F_n(x, 0)| / F_n(x, 0) of the paddle's contact (where F_n(x, 0) > 1 N)."""
    rub, st = preset("natural-rubber"), preset("steel")
    ball = Body.sphere(rub, R)
    pair = ContactPair(rub, st)
    law = make_law("msf", pair, Curvature.sphere_on_plane(R))
    n_press, n_hold = int(round((press + GAP) / V / dt)), int(round(hold / dt))
    z0 = 2 * R + GAP + HALF  # the paddle's centre
    share = 0.0
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        if engine == "mujoco":
            import mujoco

            from engines.mujoco import MujocoAdapter

            xml = f"""<mujoco><option timestep="{dt}" gravity="0 0 {-gravity}"/>
            <worldbody>
              <geom name="floor" type="plane" size="1 1 0.1" contype="0" conaffinity="0"/>
              <body name="paddle" mocap="true" pos="0 0 {z0}">
                <geom name="pad" type="box" size="0.05 0.05 {HALF}" contype="0" conaffinity="0"/></body>
              <body name="ball" pos="0 0 {R}"><freejoint/>
                <geom name="ball" type="sphere" size="{R}" mass="{ball.mass}" contype="0" conaffinity="0"/></body>
            </worldbody></mujoco>"""
            model = mujoco.MjModel.from_xml_string(xml)
            data = mujoco.MjData(model)
            ad = MujocoAdapter(model, data, [PairSpec("ball", "pad", law), PairSpec("ball", "floor", law)])

            def move(dz):
                data.mocap_pos[0, 2] += dz

            def face():
                return float(data.mocap_pos[0, 2]) - HALF

            step = ad.step
        else:
            import pybullet as pb

            from engines.pybullet import PybulletAdapter

            c = pb.connect(pb.DIRECT)
            pb.setGravity(0, 0, -gravity, physicsClientId=c)
            pb.setTimeStep(dt, physicsClientId=c)
            floor = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=c),
                                       physicsClientId=c)
            pad = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.05, 0.05, HALF],
                                                                  physicsClientId=c),
                                     basePosition=[0, 0, z0], physicsClientId=c)
            u = pb.createMultiBody(ball.mass, pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c),
                                   basePosition=[0, 0, R], physicsClientId=c)
            pb.changeDynamics(u, -1, linearDamping=0, angularDamping=0, physicsClientId=c)
            ad = PybulletAdapter(c, [PairSpec((u, -1), (pad, -1), law), PairSpec((u, -1), (floor, -1), law)])
            z = [z0]

            def move(dz):
                z[0] += dz
                pb.resetBasePositionAndOrientation(pad, [0, 0, z[0]], [0, 0, 0, 1], physicsClientId=c)

            def face():
                return z[0] - HALF

            step = ad.step
        mgr = ad.manager
        try:
            for k in range(n_press + n_hold):
                if k < n_press:
                    move(-V * dt)
                step()
                s0 = mgr.state(0)
                if k < n_press and s0 is not None:
                    el = _elastic(law, s0)
                    if el > 1.0:
                        Fn = _normal_forces(ad).get(0, 0.0)
                        share = max(share, abs(Fn - el) / el)
            st0, st1 = mgr.state(0), mgr.state(1)
            out = {"engine": engine, "V": V, "dt": dt}
            out["in_contact"] = st0 is not None and st1 is not None
            if out["in_contact"]:
                Fn = _normal_forces(ad)
                out.update(x_pad=st0["x"], x_floor=st1["x"], F_pad=Fn[0], F_floor=Fn[1],
                           F_pad_elastic=_elastic(law, st0), F_floor_elastic=_elastic(law, st1),
                           weight=ball.mass * gravity, x_sum_minus_squeeze=st0["x"] + st1["x"] - (2 * R - face()))
            out["island_gains"] = len(mgr.island_energy_gains)
            out["islands_checked"] = mgr._balance.checked if mgr._balance is not None else 0
            out["press_viscous_share_max"] = share
            out["records"] = len(ad.pop_records())
        finally:
            if engine != "mujoco":
                pb.disconnect(c)
    out["warnings"] = sorted({str(x.message)[:200] for x in w})
    return out


if __name__ == "__main__":
    engine = sys.argv[1] if len(sys.argv) > 1 else "mujoco"
    V = float(sys.argv[2]) * 1e-3 if len(sys.argv) > 2 else 5e-3
    dt = float(sys.argv[3]) if len(sys.argv) > 3 else 1e-3
    for k, v in run(engine, V, dt).items():
        print(f"{k}: {v}")
