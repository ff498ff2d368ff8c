"""A smooth mesh (an icosphere) against the analytic sphere it stands for
(issue 13), in MuJoCo or pybullet:

    .venv/bin/python scripts/mesh_roll.py mujoco|pybullet roll|spin|drop [steps] [sphere]

An icosphere of 642 vertices (trimesh, subdivisions 3; hull edges up to
0.165 R), R = 30 mm, 0.1 kg (solid sphere's inertia), natural rubber on
steel, a plain ``PairSpec`` with the law of the sphere of R on a plane (the
adapters' default mesh slots: one, engines._narrow.default_mesh_slots),
dt = 1 ms. ``sphere`` runs the analytic sphere instead.

- ``roll``: set 10 um above the plane and launched rolling at 0.6 m/s
  (omega = v / R about the horizontal axis), gravity on.
- ``spin``: gravity off, falling at 1 m/s onto the plane while turning at
  30 rad/s about a horizontal axis (the point moves ~2 mm over the
  contact: on a faceted mesh the deepest vertex changes within it), one
  bounce.
- ``drop``: the lead's user check (/work/usercheck/mj_shapes.py mesh):
  dropped from 0.3 m turned by Euler (17, 11, 5) deg, gravity on.

Printed, and returned by ``run(engine, scene, steps, geom)``: the energy
account E (kinetic + gravitational + the contacts' stored energy,
ContactManager.stored_energy, read at steps without a pending timing
correction), its largest rise over any interval (``gain_J``), the records,
how many are flagged and their normal CORs.

Main before the smooth point (engines._narrow.smooth_point; main dff70d0):
MuJoCo roll 9.6 mJ gained by step 38 (records COR 1.97, 1.44, 19.0; the
finite-difference a_ext 60-75 m/s^2 at each change of vertex).
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np

R, MASS, DT, G = 0.03, 0.1, 1e-3, 9.81
#: The rolling scene's speed [m/s] and the spin scene's fall [m/s] and spin [rad/s].
V_ROLL, V_FALL, W_SPIN = 0.6, 1.0, 30.0


def _law():
    from msf_contact import ContactPair, Curvature, make_law, preset

    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))


def _icosphere():
    import trimesh

    return trimesh.creation.icosphere(subdivisions=3, radius=R)


def _start(scene: str):
    """(height of the centre [m], Euler angles [deg], linear velocity (3,), angular velocity (3,) world, gravity)."""
    if scene == "roll":
        return R + 1e-5, (17.0, 11.0, 5.0), np.array([V_ROLL, 0.0, 0.0]), np.array([0.0, V_ROLL / R, 0.0]), G
    if scene == "spin":
        return R + 1e-4, (17.0, 11.0, 5.0), np.array([0.0, 0.0, -V_FALL]), np.array([W_SPIN, 0.0, 0.0]), 0.0
    if scene == "drop":
        return 0.3, (17.0, 11.0, 5.0), np.zeros(3), np.zeros(3), G
    raise ValueError(f"scene = {scene!r} must be roll, spin or drop")


def _mujoco(scene: str, steps: int, geom: str):
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter

    z, eul, v, w, g = _start(scene)
    ico = _icosphere()
    asset = (f'<mesh name="ico" vertex="{" ".join(repr(float(c)) for c in ico.vertices.ravel())}" '
             f'face="{" ".join(str(int(f)) for f in ico.faces.ravel())}"/>')
    shape = 'type="mesh" mesh="ico"' if geom == "mesh" else f'type="sphere" size="{R}"'
    I = 0.4 * MASS * R * R
    xml = (f'<mujoco><option timestep="{DT}" gravity="0 0 {-g}"/><asset>{asset}</asset><worldbody>'
           '<geom name="floor" type="plane" size="2 2 0.1"/>'
           f'<body name="obj" pos="0 0 {z!r}" euler="{eul[0]} {eul[1]} {eul[2]}"><freejoint/>'
           f'<inertial pos="0 0 0" mass="{MASS}" diaginertia="{I!r} {I!r} {I!r}"/>'
           f'<geom name="obj" {shape} mass="0"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    d.qvel[:3] = v
    d.qvel[3:6] = d.xmat[1].reshape(3, 3).T @ w  # a free joint's angular velocity is in body axes
    mujoco.mj_forward(m, d)
    ad = MujocoAdapter(m, d, [PairSpec("obj", "floor", _law())])

    def energy():
        vv = d.qvel[:3]
        wb = d.qvel[3:6]
        return 0.5 * MASS * float(vv @ vv) + 0.5 * I * float(wb @ wb) + MASS * g * float(d.qpos[2])

    return ad, ad.step, energy


def _pybullet(scene: str, steps: int, geom: str):
    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter, scenes

    z, eul, v, w, g = _start(scene)
    c = scenes.new_client(DT, g if g else None)
    plate = scenes.add_plate(c)
    kw = (dict(shapeType=pb.GEOM_MESH, vertices=_icosphere().vertices.tolist()) if geom == "mesh"
          else dict(shapeType=pb.GEOM_SPHERE, radius=R))
    sh = pb.createCollisionShape(physicsClientId=c, **kw)
    orn = pb.getQuaternionFromEuler([math.radians(a) for a in eul])
    u = pb.createMultiBody(MASS, sh, basePosition=[0, 0, z], baseOrientation=orn, physicsClientId=c)
    I = 0.4 * MASS * R * R
    pb.changeDynamics(u, -1, mass=MASS, localInertiaDiagonal=[I, I, I], physicsClientId=c)
    scenes._free_dynamics(c, u)
    pb.resetBaseVelocity(u, v.tolist(), w.tolist(), physicsClientId=c)
    ad = PybulletAdapter(c, [PairSpec((u, -1), (plate, -1), _law())])

    def energy():
        (pos, _), (vv, ww) = pb.getBasePositionAndOrientation(u, physicsClientId=c), pb.getBaseVelocity(
            u, physicsClientId=c)
        return 0.5 * MASS * float(np.dot(vv, vv)) + 0.5 * I * float(np.dot(ww, ww)) + MASS * g * pos[2]

    return ad, ad.step, energy


def run(engine: str, scene: str, steps: int, geom: str = "mesh") -> dict:
    """The scene (module docstring) for ``steps`` steps of ``engine`` with the
    icosphere (geom "mesh") or the analytic sphere ("sphere")."""
    ad, step, energy = (_mujoco if engine == "mujoco" else _pybullet)(scene, steps, geom)
    E = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            for _ in range(steps):
                step()
                if not np.any(ad.manager.J != 0.0):
                    E.append(energy() + ad.manager.stored_energy())
        finally:
            if engine == "pybullet":
                import pybullet as pb

                pb.disconnect(ad.client)
    E = np.array(E)
    gain = max(float(np.max(E[j:] - E[j])) for j in range(E.size)) if E.size else 0.0
    recs = ad.records
    return dict(engine=engine, scene=scene, geom=geom, steps=steps, E0_J=float(E[0]) if E.size else math.nan,
                gain_J=gain, records=len(recs), flagged=sum(1 for r in recs if r.outside_validity),
                cor_n=[float(r.cor_n) for r in recs], tau=[float(r.tau) for r in recs],
                warnings=[str(x.message)[:200] for x in caught])


if __name__ == "__main__":
    a = sys.argv[1:]
    out = run(a[0], a[1], int(a[2]) if len(a) > 2 else 300, "sphere" if "sphere" in a else "mesh")
    for k, val in out.items():
        print(f"{k}: {val}")
