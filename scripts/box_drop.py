"""A box dropped on a plane as a user does it (issue 13), in MuJoCo or pybullet:

    .venv/bin/python scripts/box_drop.py mujoco [steps] [Euler|implicitfast|RK4] [edge_radius]
    .venv/bin/python scripts/box_drop.py pybullet [steps] [-] [edge_radius]

A 5 cm, 0.1 kg box (MuJoCo: a box geom; pybullet: ``cube_small.urdf`` on
``plane.urdf``, whose collision shape is a 200 x 200 x 10 m box) turned by
the Euler angles (17, 11, 5) deg (MuJoCo's "xyz"), its centre 0.3 m above
the plane, natural rubber on steel, a plain
``PairSpec(box, floor, make_law("msf", ..., Curvature.sphere_on_plane(0.02)))``
(the edge radius msf_contact.shapes.DEFAULT_EDGE_RADIUS, 1 mm, unless
given), dt = 1 ms. It lands on a corner at 2.3 m/s, tumbles and comes to
rest on a face (engines._narrow.BoxOnPlane). Printed: the energy account
(kinetic + gravitational of the physical velocities plus the contacts'
stored energy, ContactManager.stored_energy, read at steps without a
pending timing correction) and its largest rise over any interval, the
records and how many are flagged, the deepest corner, and at the end the
four corners' approaches (the manager's and the engine's, from the box's
pose) against the static overlaps of the rigid box (:func:`static_face`).

``run(engine, ...)`` is what tests/test_box_on_plane.py calls with fewer
steps or a start just above the plane (``gap``).
"""

from __future__ import annotations

import math
import sys
import time
import warnings

import numpy as np

#: The user's box: half-extent [m], mass [kg], Euler angles [deg] ("xyz"), centre height [m].
HALF, MASS, EULER_DEG, HEIGHT = 0.025, 0.1, (17.0, 11.0, 5.0), 0.3
G, DT = 9.81, 1e-3
#: The rigid box's statics (static_face): Newton iterations, the residual's bound (force per weight,
#: moment per weight x half-extent: float rounding of the laws' forces) and the Jacobian's step (in
#: units of the mean overlap).
STATIC_ITER, STATIC_TOL, STATIC_FD = 30, 1e-12, 1e-4


def _quat_wxyz(euler_deg) -> np.ndarray:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_euler2Quat(q, np.radians(euler_deg), "xyz")
    return q


def _start(euler_deg, height: float | None, gap: float | None):
    """(centre height [m], downward speed [m/s]): the user's drop from rest
    at ``height``, or (``gap`` given) the same drop's state when the lowest
    sharp corner is ``gap`` [m] above the plane (free fall has no torque: the
    orientation is the start's; ``height`` None: from rest there)."""
    import mujoco

    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, _quat_wxyz(euler_deg))
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    drop = -float(np.min((signs * HALF) @ R.reshape(3, 3).T[:, 2]))  # centre above its lowest corner
    if gap is None:
        return height, 0.0
    z = drop + gap
    return z, 0.0 if height is None else math.sqrt(2.0 * G * (height - z))


def law():
    from msf_contact import ContactPair, Curvature, make_law, preset

    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))


def static_face(mgr, box, slots, com, mass: float = MASS, g: float = G, first: int = 0) -> np.ndarray:
    """The approaches [m] (4,) of the corners ``slots`` of a rigid box resting
    on them: x_i = x_i0 + z + a u_i + b v_i (x_i0 the engine's approaches, (u,
    v) the corners' lowest points in the plane about the centre of mass
    ``com`` [m] (3,); a rigid body's small displacement z and tilts a, b)
    with sum F_i = m g and sum F_i (u_i, v_i) = 0 (the weight through the
    centre of mass; tangential forces at rest sum to zero and act in the
    plane, so they add no moment about its axes), F_i the elastic force of
    each contact's law and onset constants (msf_contact.statics.elastic_force:
    the law at x' = 0, (37)). ``first``: the manager's pair index of the
    box's slot 0 (slots are the manager's indices)."""
    from msf_contact.curvature import tangent_basis
    from msf_contact.statics import elastic_force

    c = box.corners
    t1, t2 = tangent_basis(c.normal)
    k = box.corner[np.asarray(slots) - first]
    x0 = c.x[k]
    uv = np.stack([(c.lowest[k] - com) @ t1, (c.lowest[k] - com) @ t2], axis=1)
    laws = [mgr._groups[mgr._group_of[p]] for p in slots]
    onsets = [{key: v[mgr._pos[[p]]] for key, v in mgr._onset[mgr._group_of[p]].items()} for p in slots]

    scale = float(np.mean(np.abs(x0)))  # the unknowns in units of the overlap, the tilts per half-extent

    def xs(q):
        return x0 + scale * (q[0] + uv @ q[1:] / HALF)

    def residual(q):
        F = np.array([float(elastic_force(lw, [max(x, 0.0)], o)[0]) for lw, x, o in zip(laws, xs(q), onsets)])
        return [(F.sum() - mass * g) / (mass * g), *(F @ uv / (mass * g * HALF))]

    q = np.zeros(3)  # Newton with a central-difference Jacobian (the residual is smooth where all four touch)
    for _ in range(STATIC_ITER):
        r = np.asarray(residual(q))
        if np.max(np.abs(r)) < STATIC_TOL:
            return xs(q)
        J = np.stack([(np.asarray(residual(q + h)) - np.asarray(residual(q - h))) / (2 * STATIC_FD)
                      for h in np.eye(3) * STATIC_FD], axis=1)
        q = q - np.linalg.solve(J, r)
    raise RuntimeError(f"the rigid box's statics did not solve: residual {residual(q)}")


def run(engine: str, steps: int = 1500, *, integrator: str = "Euler", edge_radius: float | None = None,
        gap: float | None = None, euler_deg=EULER_DEG, height: float | None = HEIGHT) -> dict:
    """The drop (module docstring) for ``steps`` steps of DT: a dict of the
    printed numbers. gap [m]: start with the lowest corner that far above
    the plane at the drop's speed there (None: from rest at ``height``;
    ``height`` None with a gap: from rest at the gap)."""
    z0, v0 = _start(euler_deg, height, gap)
    q = _quat_wxyz(euler_deg)
    runner = _mujoco if engine == "mujoco" else _pybullet
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = runner(steps, z0, v0, q, integrator, edge_radius)
    E = np.asarray(out.pop("E"))
    out["E0_J"], out["E_end_J"] = float(E[0]), float(E[-1])
    out["gain_J"] = float(np.max(E - np.minimum.accumulate(E)))
    out["warnings"] = sorted({str(w.message)[:160] for w in caught})
    return out


def _finish(out: dict, ad, box, com, speed: float) -> dict:
    """The end's numbers; ``speed`` [m/s]: the centre's speed + the half-extent x the angular speed.
    ``speed_normal_end`` [m/s]: the motion that changes the corners' approaches (the centre's speed
    along the normal + half-extent x the angular speed about axes in the plane)."""
    mgr = ad.manager
    n = box.corners.normal
    v, w = np.asarray(out["v_end"]), np.asarray(out["w_end"])
    out["speed_normal_end"] = float(abs(v @ n) + HALF * np.linalg.norm(w - (w @ n) * n))
    slots = np.arange(box.n)
    recs = ad.records
    out.update(records=len(recs), flagged=sum(1 for r in recs if r.outside_validity),
               island_gains=len(mgr.island_energy_gains), speed_end=speed,
               active_end=mgr.active[slots].tolist(), axes_end=box.axis.tolist())
    if np.all(mgr.active[slots]):
        out["x_internal_m"] = mgr.x[slots].tolist()
        out["x_engine_m"] = box.corners.x[box.corner].tolist()
        out["x_static_m"] = static_face(mgr, box, slots, com).tolist()
        out["onsets"] = [{key: float(v[mgr._pos[p]]) for key, v in mgr._onset[mgr._group_of[p]].items()}
                         for p in slots]
    return out


def _mujoco(steps, z0, v0, q, integrator, edge_radius) -> dict:
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import mechanical_energy

    xml = (f'<mujoco><option timestep="{DT}" integrator="{integrator}"/><worldbody>'
           '<geom name="floor" type="plane" size="2 2 0.1"/>'
           f'<body name="obj" pos="0 0 {z0!r}" quat="{" ".join(repr(float(c)) for c in q)}"><freejoint/>'
           f'<geom name="obj" type="box" size="{HALF} {HALF} {HALF}" mass="{MASS}"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[2] = -v0
    kw = {} if edge_radius is None else {"edge_radii": {"obj": edge_radius}}
    ad = MujocoAdapter(m, d, [PairSpec("obj", "floor", law())], **kw)
    box = ad._box[0]
    E, deepest = [], -math.inf
    wall = time.perf_counter()
    with installed(ad):
        for _ in range(steps):
            mujoco.mj_step(m, d)
            deepest = max(deepest, float(np.max(box.corners.x)))
            if not np.any(ad.manager.J != 0.0):
                E.append(mechanical_energy(m, d, d.qvel - ad.velocity_offset()) + ad.manager.stored_energy())
    out = {"engine": "mujoco", "integrator": integrator, "steps": steps, "E": E, "deepest_corner_m": deepest,
           "step_ms": 1e3 * (time.perf_counter() - wall) / steps, "z_end_m": float(d.qpos[2])}
    v = d.qvel - ad.velocity_offset()
    out["v_end"], out["w_end"] = v[:3].tolist(), v[3:6].tolist()
    return _finish(out, ad, box, d.xpos[1].copy(), float(np.linalg.norm(v[:3]) + HALF * np.linalg.norm(v[3:])))


def _pybullet(steps, z0, v0, q, integrator, edge_radius) -> dict:
    import pybullet as pb
    import pybullet_data

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter

    c = pb.connect(pb.DIRECT)
    try:
        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
        pb.setGravity(0, 0, -G, physicsClientId=c)
        pb.setTimeStep(DT, physicsClientId=c)
        plane = pb.loadURDF("plane.urdf", physicsClientId=c)
        u = pb.loadURDF("cube_small.urdf", [0, 0, z0], [q[1], q[2], q[3], q[0]], physicsClientId=c)
        pb.resetBaseVelocity(u, [0, 0, -v0], [0, 0, 0], physicsClientId=c)
        kw = {} if edge_radius is None else {"edge_radii": {(u, -1): edge_radius}}
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law())], **kw)
        box = ad._narrow[0].box
        info = pb.getDynamicsInfo(u, -1, physicsClientId=c)
        m, I = float(info[0]), np.array(info[2], dtype=float)

        def energy():
            pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
            v, w = (np.array(a, dtype=float) for a in pb.getBaseVelocity(u, physicsClientId=c))
            wl = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3).T @ w
            return m * G * pos[2] + 0.5 * m * v @ v + 0.5 * wl @ (I * wl), np.array(pos), v, w

        E, deepest = [], -math.inf
        wall = time.perf_counter()
        for _ in range(steps):
            ad.step(1)
            deepest = max(deepest, float(np.max(box.corners.x)))
            if not np.any(ad.manager.J != 0.0):
                E.append(energy()[0] + ad.manager.stored_energy())
        out = {"engine": "pybullet", "integrator": "-", "steps": steps, "E": E, "deepest_corner_m": deepest,
               "step_ms": 1e3 * (time.perf_counter() - wall) / steps}
        _, pos, v, w = energy()
        out["z_end_m"] = float(pos[2])
        out["v_end"], out["w_end"] = v.tolist(), w.tolist()
        return _finish(out, ad, box, pos, float(np.linalg.norm(v) + HALF * np.linalg.norm(w)))
    finally:
        pb.disconnect(c)


def main(argv) -> None:
    engine = argv[1] if len(argv) > 1 else "mujoco"
    steps = int(argv[2]) if len(argv) > 2 else 1500
    integ = argv[3] if len(argv) > 3 and argv[3] != "-" else "Euler"
    rho = float(argv[4]) if len(argv) > 4 else None
    out = run(engine, steps, integrator=integ, edge_radius=rho)
    for key, val in out.items():
        if key != "onsets":
            print(f"{key}: {val}")


if __name__ == "__main__":
    main(sys.argv)
