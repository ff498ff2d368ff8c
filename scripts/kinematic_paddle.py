"""A paddle driven kinematically by the user (a MuJoCo mocap body; a pybullet mass-0 body moved
with resetBasePositionAndOrientation) strikes a resting free
rubber ball: the ball should leave at V (1 + e), e the reference solver's for an infinite-mass
paddle (engines._kinematic).

    PYTHONPATH=. .venv/bin/python scripts/kinematic_paddle.py [mujoco|pybullet] [V] [dt] [box|sphere]
"""
from __future__ import annotations

import math
import sys
import warnings

import numpy as np

from engines.base import PairSpec
from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact

R = 0.02  # the ball's radius [m]
PAD = 0.05  # the sphere paddle's radius [m]; the box paddle is 0.2 x 0.2 x 0.02 m
START = 0.2  # the paddle face's distance from the ball's surface at the start [m]
RUN = 0.3  # the distance the paddle travels [m]
TURN_NEAR = 2e-3  # a turning paddle turns from this distance to the ball on [m] (mujoco_paddle)


def _law(shape: str):
    rub, st = preset("natural-rubber"), preset("steel")
    curv = Curvature.sphere_on_plane(R) if shape == "box" else Curvature.two_spheres(R, PAD)
    return make_law("msf", ContactPair(rub, st), curv), Body.sphere(rub, R)


def reference(V: float, shape: str = "box") -> float:
    """e of the reference solver for the ball on an infinite-mass paddle of that shape (the law's
    curvature; the paddle's mass infinite: a half-space body)."""
    law, ball = _law(shape)
    return float(simulate_impact(law, ball, Body.half_space(preset("steel")), speed=V).cor_n)


def mujoco_paddle(V: float, dt: float = 1e-3, shape: str = "box", omega: float = 0.0, side: float = 0.0) -> dict:
    """The mocap paddle along +x at V [m/s] (``data.mocap_pos[0, 0] += V dt`` before each
    ``mj_step``) into the ball at rest, gravity off; with omega [rad/s] it also turns about the
    world z axis through its centre from TURN_NEAR before the ball on (mocap_quat composed each
    step: its face, 10 mm from the centre, then slides along +y at 0.01 omega where the ball
    touches), with side [m/s] it also moves along +y (from -side START / V: centred on the ball
    when it touches)."""
    import mujoco

    from engines.mujoco import MujocoAdapter, installed

    law, ball = _law(shape)
    half = 0.01 if shape == "box" else PAD
    geom = (f'<geom name="pad" type="box" size="0.1 0.1 {half}"/>' if shape == "box"
            else f'<geom name="pad" type="sphere" size="{PAD}"/>')
    xml = f"""<mujoco><option timestep="{dt}" gravity="0 0 0"/>
    <worldbody>
      <body name="paddle" mocap="true" pos="{-R - START - half} {-side * START / V} 0" zaxis="1 0 0">{geom}</body>
      <body name="ball" pos="0 0 0"><freejoint/><geom name="ball" type="sphere" size="{R}" mass="{ball.mass}"/></body>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    ad = MujocoAdapter(model, data, [PairSpec("ball", "pad", law)])
    q = np.zeros(4)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        with installed(ad):
            for _ in range(int(round(RUN / V / dt))):
                data.mocap_pos[0, 0] += V * dt  # the user's kinematic drive
                data.mocap_pos[0, 1] += side * dt
                if omega and data.mocap_pos[0, 0] + half > -R - TURN_NEAR:
                    mujoco.mju_axisAngle2Quat(q, np.array([0.0, 0.0, 1.0]), omega * dt)
                    mujoco.mju_mulQuat(data.mocap_quat[0], q, data.mocap_quat[0].copy())
                mujoco.mj_step(model, data)
    return {"v_out": float(data.qvel[0]), "v_side": float(np.linalg.norm(data.qvel[1:3])),
            "v_y": float(data.qvel[1]), "spin": data.qvel[3:6].copy(),
            "records": ad.pop_records(), "warnings": [str(x.message) for x in w], "adapter": ad}


def pybullet_paddle(V: float, dt: float = 1e-3, shape: str = "box", side: float = 0.0) -> dict:
    """The mass-0 paddle moved along +x at V with resetBasePositionAndOrientation between
    ``adapter.step()`` calls (a mass-0 body moves only when the user moves it: the adapter reads
    its motion from its pose, engines._kinematic); with side [m/s] it also moves along +y, as in
    :func:`mujoco_paddle`."""
    import pybullet as pb

    from engines.pybullet import PybulletAdapter

    law, ball = _law(shape)
    c = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, 0, physicsClientId=c)
        pb.setTimeStep(dt, physicsClientId=c)
        half = 0.01 if shape == "box" else PAD
        shp = (pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[half, 0.1, 0.1], physicsClientId=c)
               if shape == "box" else pb.createCollisionShape(pb.GEOM_SPHERE, radius=PAD, physicsClientId=c))
        x, y = -R - START - half, -side * START / V
        pad = pb.createMultiBody(0.0, shp, basePosition=[x, y, 0], physicsClientId=c)
        bs = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c)
        u = pb.createMultiBody(ball.mass, bs, basePosition=[0, 0, 0], physicsClientId=c)
        pb.changeDynamics(u, -1, linearDamping=0, angularDamping=0, physicsClientId=c)
        ad = PybulletAdapter(c, [PairSpec((u, -1), (pad, -1), law)])
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            for _ in range(int(round(RUN / V / dt))):
                x += V * dt
                y += side * dt
                pb.resetBasePositionAndOrientation(pad, [x, y, 0], [0, 0, 0, 1], physicsClientId=c)
                ad.step()
        v, spin = pb.getBaseVelocity(u, physicsClientId=c)
        return {"v_out": float(v[0]), "v_side": float(math.hypot(v[1], v[2])), "v_y": float(v[1]),
                "spin": np.asarray(spin, dtype=float), "records": ad.pop_records(),
                "warnings": [str(x.message) for x in w], "adapter": ad}
    finally:
        pb.disconnect(c)


def accelerating(a: float, dt: float, engine: str = "mujoco", V0: float = 0.5, gap: float = 5e-3) -> dict:
    """A box paddle driven at x(t) = x0 + V0 t + a t^2 / 2 (its pose set from the step's start
    time before each step), its face ``gap`` from the ball at t = 0, into the ball at rest: the
    ball's velocity when the strike's record appears (before the accelerating paddle catches it
    again) and the record."""
    law, ball = _law("box")
    x0 = -R - gap - 0.01  # the paddle's centre; its half thickness is 0.01 m
    out = {}
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        if engine == "mujoco":
            import mujoco

            from engines.mujoco import MujocoAdapter

            xml = f"""<mujoco><option timestep="{dt}" gravity="0 0 0"/><worldbody>
              <body name="paddle" mocap="true" pos="{x0} 0 0" zaxis="1 0 0">
                <geom name="pad" type="box" size="0.1 0.1 0.01"/></body>
              <body name="ball"><freejoint/><geom name="ball" type="sphere" size="{R}" mass="{ball.mass}"/></body>
              </worldbody></mujoco>"""
            model = mujoco.MjModel.from_xml_string(xml)
            data = mujoco.MjData(model)
            ad = MujocoAdapter(model, data, [PairSpec("ball", "pad", law)])

            def place(x):
                data.mocap_pos[0, 0] = x

            def ball_v():
                return float(data.qvel[0])
        else:
            import pybullet as pb

            from engines.pybullet import PybulletAdapter

            c = pb.connect(pb.DIRECT)
            pb.setGravity(0, 0, 0, physicsClientId=c)
            pb.setTimeStep(dt, physicsClientId=c)
            pad = pb.createMultiBody(0.0, pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.01, 0.1, 0.1],
                                                                  physicsClientId=c),
                                     basePosition=[x0, 0, 0], physicsClientId=c)
            u = pb.createMultiBody(ball.mass, pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c),
                                   physicsClientId=c)
            pb.changeDynamics(u, -1, linearDamping=0, angularDamping=0, physicsClientId=c)
            ad = PybulletAdapter(c, [PairSpec((u, -1), (pad, -1), law)])

            def place(x):
                pb.resetBasePositionAndOrientation(pad, [x, 0, 0], [0, 0, 0, 1], physicsClientId=c)

            def ball_v():
                return float(pb.getBaseVelocity(u, physicsClientId=c)[0][0])
        try:
            for k in range(int(round(0.05 / dt))):
                t = k * dt  # the step's start time
                place(x0 + V0 * t + 0.5 * a * t * t)
                ad.step()
                if ad.records:
                    out = {"v_out": ball_v(), "record": ad.records[0]}
                    break
        finally:
            if engine != "mujoco":
                pb.disconnect(c)
    out["warnings"] = [str(x.message) for x in w]
    return out


if __name__ == "__main__":
    engine = sys.argv[1] if len(sys.argv) > 1 else "mujoco"
    V = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
    dt = float(sys.argv[3]) if len(sys.argv) > 3 else 1e-3
    shape = sys.argv[4] if len(sys.argv) > 4 else "box"
    out = (mujoco_paddle if engine == "mujoco" else pybullet_paddle)(V, dt, shape)
    e = reference(V, shape)
    print(f"{engine} {shape} V = {V} m/s, dt = {dt} s: ball leaves at {out['v_out']:.6f} m/s, V (1 + e_ref) = "
          f"{V * (1 + e):.6f} (e_ref {e:.5f}; relative {out['v_out'] / (V * (1 + e)) - 1:+.2e}); records "
          f"{[round(r.cor_n, 5) for r in out['records']]}; warnings {len(out['warnings'])}")
    for m in sorted(set(out["warnings"])):
        print("  ", m[:300])
