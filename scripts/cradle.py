"""Newton's cradles with gaps between the balls, MSF between neighbours, in
MuJoCo or pybullet, against the chain reference (issue 10: "contacts solved
together").

    .venv/bin/python scripts/cradle.py --engine mujoco --joint hinge --n 5 --dt 1e-3 --gap 1e-4

N steel balls (R = 10 mm) in a row along x, ``--gap`` [m] between
neighbours, MSF pairs only between neighbours, stepped one engine step at a
time (MuJoCo: the user's own ``mj_step`` loop with the adapter's hook
installed; pybullet: ``adapter.step(1)``). ``--joint``:

- ``free``: free bodies, no gravity; ball 0 thrown at ``--v0`` [m/s] from
  ``--first-gap`` [m] (default: ``--gap``, so that with small gaps the strike
  begins in the very first step);
- ``slide``: each ball on a slide joint along x, otherwise as ``free``;
- ``hinge``: the classic demo, each ball on a rod of L = 0.15 m (a hinge
  about y at its top, gravity 9.81 m/s^2); ball 0 released at ``--angle``
  [deg] strikes at v0 = sqrt(2 g L (1 - cos angle)) (0.628 m/s at 30 deg).

Reported (one JSON line, ``--json``; else a few lines):

- ``gain``: the largest rise of E, from the start of the step the strike
  begins in until the velocities are read, above its value there [J], and
  relative to the kinetic energy of the strike, E = kinetic + potential +
  the contacts' stored energy (``ContactManager.stored_energy``), with the
  manager's timing corrections J taken out of the engine's velocities
  (qdot - M^-1 sum_p J_p^T J_p, the J_p at the pair's last contact
  points). Under gravity (hinge) the potential is taken at z - (dt/2) v
  (semi-implicit Euler moves a body by dt v_end; scripts/pile.py); the
  swing's own integration error is E's largest rise over the same steps
  with the balls far apart (``swing_drift``);
- ``v``: the balls' centre velocities along x right after the strike (the
  first step start with no contact in progress and no correction left after
  the last ball's contact; for the hinge that is the balls' speed at the
  bottom of the swing), ``ref``: the chain reference
  (``msf_contact.chain.simulate_chain``, free balls on a line) for the same
  strike speed, and ``err``: max |v - ref| / v0;
- the records' count, the island energy flags and the warnings.

The hinged balls turn with their rods (omega = v / L): their contact
points slide past each other at omega R (0.042 m/s at 0.628 m/s), and
MSF's tangential force, which the chain reference (collinear, no rotation)
does not have, takes a share of the strike; ``--mu`` caps it at mu F_n
(``--mu 1e-9``: frictionless, the chain's case; docs/engines.md).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import warnings

import numpy as np

from msf_contact import Body, ContactPair, Curvature, make_law, preset
from msf_contact.chain import simulate_chain

R = 0.01  #: ball radius [m]
L = 0.15  #: rod length of the hinged cradle [m]
G = 9.81  #: gravity of the hinged cradle [m/s^2]
STEEL = preset("steel")
BALL = Body.sphere(STEEL, R)
#: steps after the last contact's end before the velocities are read (the timing correction J is
#: removed in the step after a contact's last one)
AFTER_STEPS = 2


def law(mu=None):
    return make_law("msf", ContactPair(STEEL, STEEL), Curvature.two_spheres(R, R),
                    **({} if mu is None else {"mu": mu}))


class _Mujoco:
    def __init__(self, n, dt, gap, joint, v0, first_gap, angle, integrator, mu):
        import mujoco

        from engines.base import PairSpec
        from engines.mujoco import MujocoAdapter

        self.mj = mujoco
        bodies = ""
        for i in range(n):
            x = 0.0 if i == 0 else (2 * R + first_gap) + (i - 1) * (2 * R + gap)
            if joint == "free":
                j, z = "<freejoint/>", 0.0
            elif joint == "slide":
                j, z = '<joint type="slide" axis="1 0 0"/>', 0.0
            else:
                j, z = '<joint type="hinge" axis="0 1 0"/>', -L
            rod = ('<geom type="capsule" fromto="0 0 0 0 0 %r" size="0.0005" mass="1e-6" contype="0" '
                   'conaffinity="0"/>' % (-L + R)) if joint == "hinge" else ""
            bodies += (f'<body name="b{i}" pos="{x!r} 0 0.2">{j}'
                       f'<geom name="s{i}" type="sphere" size="{R!r}" pos="0 0 {z!r}" mass="{BALL.mass!r}" '
                       f'contype="0" conaffinity="0"/>{rod}</body>')
        g = G if joint == "hinge" else 0.0
        xml = (f'<mujoco><option timestep="{dt!r}" gravity="0 0 {-g!r}" integrator="{integrator}"/>'
               f'<worldbody>{bodies}</worldbody></mujoco>')
        self.model = m = mujoco.MjModel.from_xml_string(xml)
        self.data = d = mujoco.MjData(m)
        if joint == "hinge":
            d.qpos[0] = math.radians(angle)  # ball 0 swings in from -x (a turn about +y)
        else:
            d.qvel[0] = v0
        mujoco.mj_forward(m, d)
        self.law = law(mu)
        self.adapter = MujocoAdapter(m, d, [PairSpec(f"s{i}", f"s{i + 1}", self.law) for i in range(n - 1)])
        self.manager = self.adapter.manager
        self.n, self.joint, self.dt = n, joint, dt
        self.geoms = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"s{i}") for i in range(n)]
        self.sbody = [int(m.geom_bodyid[gi]) for gi in self.geoms]
        self._ctx = self._installed()

    @contextlib.contextmanager
    def _installed(self):
        from engines.mujoco import installed

        with installed(self.adapter):
            yield

    def step(self):
        self.mj.mj_step(self.model, self.data)

    def _qdot(self):
        """qvel with the manager's timing corrections taken out: qdot - M^-1 sum_p J_p^T J_p."""
        mj, m, d, mgr, ad = self.mj, self.model, self.data, self.manager, self.adapter
        q = d.qvel.copy()
        Q = np.zeros(m.nv)
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for p in np.flatnonzero(np.any(mgr.J != 0.0, axis=1)):
            b1, b2 = self.sbody[p], self.sbody[p + 1]
            mj.mj_jac(m, d, jp, jr, ad._p1[p], b1)
            Q += jp.T @ mgr.J[p]
            mj.mj_jac(m, d, jp, jr, ad._p2[p], b2)
            Q -= jp.T @ mgr.J[p]
        if np.any(Q):
            dq = np.zeros(m.nv)
            mj.mj_solveM(m, d, dq.reshape(1, -1), Q.reshape(1, -1))
            q -= dq
        return q

    def velocities(self):
        """The balls' centre velocities along x [m/s] (n,), corrections taken out."""
        mj, m, d = self.mj, self.model, self.data
        q = self._qdot()
        out = np.empty(self.n)
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        for i, gi in enumerate(self.geoms):
            mj.mj_jac(m, d, jp, jr, d.geom_xpos[gi], self.sbody[i])
            out[i] = jp[0] @ q
        return out

    def energy(self):
        """Kinetic (corrections out) + potential at z - (dt/2) v + stored [J]."""
        mj, m, d = self.mj, self.model, self.data
        q = self._qdot()
        Mq = np.zeros(m.nv)
        mj.mj_mulM(m, d, Mq, q)
        T = 0.5 * float(q @ Mq)
        U = 0.0
        if self.joint == "hinge":
            jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
            for b in range(1, m.nbody):
                mj.mj_jac(m, d, jp, jr, d.xipos[b], b)
                vz = float(jp[2] @ q)
                U += m.body_mass[b] * G * (d.xipos[b, 2] - 0.5 * self.dt * vz)
        return T + U + self.manager.stored_energy()

    def close(self):
        pass


class _Pybullet:
    def __init__(self, n, dt, gap, joint, v0, first_gap, angle, integrator, mu):
        import pybullet as pb

        from engines.base import PairSpec
        from engines.pybullet import PybulletAdapter, scenes

        self.pb = pb
        g = G if joint == "hinge" else None
        self.c = c = scenes.new_client(dt, g)
        self.uids = []
        for i in range(n):
            x = 0.0 if i == 0 else (2 * R + first_gap) + (i - 1) * (2 * R + gap)
            if joint == "free":
                self.uids.append(scenes.add_sphere(c, BALL, [x, 0.0, 0.2], [v0 if i == 0 else 0.0, 0, 0]))
                continue
            kind = pb.JOINT_PRISMATIC if joint == "slide" else pb.JOINT_REVOLUTE
            axis = [1, 0, 0] if joint == "slide" else [0, 1, 0]
            at = [0, 0, 0] if joint == "slide" else [0, 0, -L]
            # the collision frame is relative to the link (joint) frame (scenes.paddle_and_ball)
            sph = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, collisionFramePosition=at, physicsClientId=c)
            uid = pb.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=-1, basePosition=[x, 0.0, 0.2],
                linkMasses=[BALL.mass], linkCollisionShapeIndices=[sph], linkVisualShapeIndices=[-1],
                linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
                linkInertialFramePositions=[at], linkInertialFrameOrientations=[[0, 0, 0, 1]],
                linkParentIndices=[0], linkJointTypes=[kind], linkJointAxis=[axis], physicsClientId=c)
            pb.changeDynamics(uid, 0, localInertiaDiagonal=[BALL.J] * 3, physicsClientId=c)
            scenes._free_dynamics(c, uid, 0)
            pb.setJointMotorControl2(uid, 0, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0, physicsClientId=c)
            if i == 0:
                if joint == "slide":
                    pb.resetJointState(uid, 0, 0.0, v0, physicsClientId=c)
                else:
                    pb.resetJointState(uid, 0, math.radians(angle), 0.0, physicsClientId=c)
            self.uids.append(uid)
        link = -1 if joint == "free" else 0
        self.law = law(mu)
        specs = [PairSpec((self.uids[i], link), (self.uids[i + 1], link), self.law) for i in range(n - 1)]
        self.adapter = PybulletAdapter(c, specs)
        self.manager = self.adapter.manager
        self.n, self.joint, self.dt, self.link = n, joint, dt, link
        self._ctx = contextlib.ExitStack()
        self._ctx.callback(pb.disconnect, c)
        self._ctx.enter_context(self.adapter)

    def step(self):
        self.adapter.step(1)

    def _state(self):
        pb, c = self.pb, self.c
        pos, v, w = [], [], []
        for u in self.uids:
            if self.link < 0:
                p = pb.getBasePositionAndOrientation(u, physicsClientId=c)[0]
                vv, ww = pb.getBaseVelocity(u, physicsClientId=c)
            else:
                s = pb.getLinkState(u, 0, computeLinkVelocity=1, physicsClientId=c)
                p, vv, ww = s[0], s[6], s[7]
            pos.append(p), v.append(vv), w.append(ww)
        return np.array(pos), np.array(v), np.array(w)

    def _corrected(self):
        """Positions and centre velocities (n, 3) with the manager's timing corrections taken out
        (+J at body 1's contact point, -J at body 2's): a free ball or slide by J / m (the rows are
        collinear: no turn), a ball on a rod by its hinge, d(theta dot) = (y x (p - pivot)) . J /
        I_hinge, I_hinge = m L^2 + J_ball."""
        pos, v, _ = self._state()
        v = v.copy()
        mgr = self.manager
        I_h = BALL.mass * L * L + BALL.J
        y = np.array([0.0, 1.0, 0.0])
        for p in np.flatnonzero(np.any(mgr.J != 0.0, axis=1)):
            n = mgr._normal[p]
            for i, sign, pt in ((p, 1.0, pos[p] - R * n), (p + 1, -1.0, pos[p + 1] + R * n)):
                if self.joint == "hinge":
                    pivot = pos[i] + np.array([0.0, 0.0, L])  # the balls stay within 1e-3 rad of hanging
                    dth = sign * float(np.cross(y, pt - pivot) @ mgr.J[p]) / I_h
                    v[i] -= dth * np.cross(y, pos[i] - pivot)
                else:
                    v[i, 0] -= sign * mgr.J[p, 0] / BALL.mass
        return pos, v

    def velocities(self):
        """The balls' centre velocities along x [m/s] (n,), corrections taken out."""
        return self._corrected()[1][:, 0]

    def energy(self):
        """Kinetic (corrections out) + potential at z - (dt/2) v + stored [J]; a ball on a rod turns
        with it (omega = |v| / L)."""
        pos, v = self._corrected()
        v2 = np.einsum("ij,ij->i", v, v)
        T = float(np.sum(0.5 * BALL.mass * v2 + (0.5 * BALL.J * v2 / (L * L) if self.joint == "hinge" else 0.0)))
        U = float(np.sum(BALL.mass * G * (pos[:, 2] - 0.5 * self.dt * v[:, 2]))) if self.joint == "hinge" else 0.0
        return T + U + self.manager.stored_energy()

    def close(self):
        self._ctx.close()


def run(engine="mujoco", n=5, dt=1e-3, gap=1e-4, joint="free", v0=None, first_gap=None, angle=30.0,
        integrator="Euler", mu=None, max_steps=None) -> dict:
    """Step the cradle through the strike; the quantities of the module docstring (a dict)."""
    if engine not in ("mujoco", "pybullet"):
        raise ValueError(f"engine = {engine!r} is not one of ('mujoco', 'pybullet')")
    if joint not in ("free", "slide", "hinge"):
        raise ValueError(f"joint = {joint!r} is not one of ('free', 'slide', 'hinge')")
    if joint == "hinge":
        v0 = math.sqrt(2 * G * L * (1 - math.cos(math.radians(angle))))
    elif v0 is None:
        v0 = 1.0
    first_gap = gap if first_gap is None else first_gap
    cls = _Mujoco if engine == "mujoco" else _Pybullet
    sc = cls(n, dt, gap, joint, v0, first_gap, angle, integrator, mu)
    x0 = [-(2 * R + first_gap)] + [(2 * R + gap) * i for i in range(n - 1)]
    ref = simulate_chain([BALL] * n, x0, [v0] + [0.0] * (n - 1), [sc.law] * (n - 1))
    # steps: through the strike (a quarter swing for the hinge), then until its last contact ended
    t_hit = (math.pi / 2 * math.sqrt(L / G) if joint == "hinge" else first_gap / v0)
    limit = max_steps or int((t_hit + ref.t_end + 0.02) / dt) + 10
    mgr = sc.manager
    out = {"engine": engine, "joint": joint, "n": n, "dt": dt, "gap": gap, "first_gap": first_gap, "v0": v0,
           "integrator": integrator, "mu": mu}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with sc._ctx:
            E0 = sc.energy()
            Emax, k_max = E0, 0
            E_hit = None  # E at the start of the step the strike begins in
            last_pair_done, after, steps = False, 0, 0
            records = []
            v = None
            E, k_hit = E0, 0
            for k in range(limit):
                E_before = E
                sc.step()
                steps += 1
                E = sc.energy()
                if E_hit is None and (mgr.active.any() or np.any(mgr.J) or len(mgr.records) or len(records)):
                    E_hit, k_hit = E_before, k
                    Emax = E_hit
                if E_hit is not None and E > Emax:
                    Emax, k_max = E, k + 1
                records += sc.adapter.pop_records()
                last_pair_done = last_pair_done or any(r.inputs.get("pair") == n - 2 for r in records)
                quiet = not mgr.active.any() and not np.any(mgr.J)
                if last_pair_done and quiet:
                    after += 1
                    if after >= AFTER_STEPS:
                        v = sc.velocities()
                        break
            records += sc.adapter.pop_records()
            E_end = sc.energy()
        sc.close()
    T0 = 0.5 * BALL.mass * v0 * v0
    gains = getattr(mgr, "island_energy_gains", [])
    E_hit = E0 if E_hit is None else E_hit
    out.update(steps=steps, E0=E0, E_hit=E_hit, E_end=E_end, gain=Emax - E_hit, gain_rel=(Emax - E_hit) / T0,
               gain_step=k_max, hit_step=k_hit,
               v=None if v is None else [float(a) for a in v], ref=[float(a) for a in ref.velocities],
               err=None if v is None else float(np.max(np.abs(v - ref.velocities)) / v0),
               records=len(records), island_gains=len(gains),
               deep_onsets=int(getattr(sc.adapter, "deep_onsets", 0)),
               warnings=sorted({str(w.message)[:300] for w in caught}))
    return out


def swing_drift(engine, n, dt, angle, integrator, k0, k1) -> float:
    """E's largest rise over steps k0..k1 above its value at step k0 of the hinged cradle with
    its balls far apart (no contact): the swing's own integration error there [J]."""
    sc = (_Mujoco if engine == "mujoco" else _Pybullet)(n, dt, 0.5, "hinge", 0.0, 0.5, angle, integrator, None)
    with sc._ctx:
        for _ in range(k0):
            sc.step()
        E0 = sc.energy()
        rise = 0.0
        for _ in range(k1 - k0):
            sc.step()
            rise = max(rise, sc.energy() - E0)
    sc.close()
    return rise


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--engine", default="mujoco", choices=["mujoco", "pybullet"])
    ap.add_argument("--joint", default="free", choices=["free", "slide", "hinge"])
    ap.add_argument("--n", type=int, default=5)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--gap", type=float, default=1e-4)
    ap.add_argument("--first-gap", type=float, default=None)
    ap.add_argument("--v0", type=float, default=None, help="strike speed of free and slide cradles [m/s] (1)")
    ap.add_argument("--angle", type=float, default=30.0, help="release angle of the hinged cradle [deg]")
    ap.add_argument("--integrator", default="Euler", help="MuJoCo's integrator (Euler, RK4, implicitfast)")
    ap.add_argument("--mu", type=float, default=None, help="Coulomb cap of the tangential force (None: none)")
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args(argv)
    out = run(a.engine, a.n, a.dt, a.gap, a.joint, a.v0, a.first_gap, a.angle, a.integrator, a.mu)
    if a.joint == "hinge":
        out["swing_drift"] = swing_drift(a.engine, a.n, a.dt, a.angle, a.integrator, out["hit_step"], out["steps"])
    if a.json:
        print(json.dumps(out))
        return
    print(f"{a.engine} {a.joint} n={a.n} dt={a.dt} gap={a.gap} ({a.integrator}, mu {a.mu}): v0 {out['v0']:.4f} m/s, "
          f"{out['steps']} steps")
    print(f"  energy: E0 {out['E0']:.6e} J, largest rise {out['gain']:.3e} J ({out['gain_rel']:.2e} of the strike's "
          f"kinetic energy) at step {out['gain_step']}" + (f"; swing drift alone {out['swing_drift']:.3e} J"
                                                            if "swing_drift" in out else ""))
    print("  after the strike:", out["v"], "\n  chain reference: ", [round(x, 6) for x in out["ref"]],
          f"\n  max |v - ref| / v0 = {out['err']}")
    print(f"  records {out['records']}, island energy gains flagged {out['island_gains']}, deep onsets "
          f"{out['deep_onsets']}, warnings {out['warnings']}")


if __name__ == "__main__":
    main()
