"""Boxes on boxes as a user stacks them (issue 13), in MuJoCo or pybullet:

    .venv/bin/python scripts/box_stack.py mujoco|pybullet drop|land|edge|overhang|cross|rest|stack3 [steps]

Natural rubber on steel, plain ``PairSpec``s with
``make_law("msf", ..., Curvature.sphere_on_plane(0.02))`` on every box-floor
and box-box pair (the edge radius msf_contact.shapes.DEFAULT_EDGE_RADIUS,
1 mm), dt = 1 ms; a box on a free box is engines._narrow.BoxOnBox (the
lower box's face as the plane of the upper box's corners).

- ``drop``: the lead's scenes (/work/usercheck/mj_pairs.py box box 0.2,
  /work/usercheck/pb_stack.py cube_small.urdf 0.2): MuJoCo, a 0.2 kg box
  (half-extent 25 mm) falling 35 mm onto the floor and a 0.1 kg box dropped
  on it from 0.2 m turned by Euler (90, 7, 3) deg; pybullet,
  ``cube_small.urdf`` resting on ``plane.urdf`` and another dropped on it
  from 0.2 m turned by (0.2, 0.1, 0.3) rad (cube_small.urdf's inertia is
  1 kg m^2, 600 times a 0.1 kg 50 mm cube's 4.2e-5: it hardly turns; the
  other scenes' pybullet boxes are createMultiBody boxes of 0.1 kg with the
  cube's own inertia, as MuJoCo's).
- ``land``: the MuJoCo drop's upper box (Euler (90, 7, 3) deg, 0.1 kg)
  1 mm above a resting box at its speed from 0.2 m (1.8 m/s), both
  engines (tests/test_box_stack.py: the landing without the fall).
- ``edge``: the drop's upper box from 0.2 m with its centre 30 mm off the
  lower box's (over its edge): it lands overhanging, tips off, and its
  edges may cross the lower box's (BoxOnBox's crossing).
- ``overhang``: a box set flat 0.2 mm above a resting box, its centre
  OVERHANG = 20 mm off along x (two corners 20 mm beyond the lower box's
  face, its centre of mass over it): it rests on its two corners over the
  face and on the face's edge, where BoxOnBox carries the two corners past
  the edge (at the face's nearest points under the box).
- ``rest``: a box set 0.2 mm above another (its lowest sharp corner 0.2 mm
  above the lower box's top face; the lower box 0.2 mm above the floor),
  tilted (1, 0.5, 0) deg, from rest: its four corners come to rest on the lower box's face;
  printed against the rigid box's statics under its weight
  (box_drop.static_face).
- ``stack3``: three such boxes set 0.2 mm apart (the top one tilted
  (-1, -0.5, 0) deg): all rest.

Printed: the energy account (kinetic of the physical velocities +
gravitational + the contacts' stored energy, ContactManager.stored_energy,
read at steps without a pending timing correction) and its largest rise
over any interval (``gain_J``), the records and how many are flagged, the
island energy gains, the deepest corner, and for ``rest`` / ``stack3`` the
upper boxes' corners (manager's and engine's approaches, the static
overlaps). ``run(engine, scene, steps)`` is what tests/test_box_stack.py calls.
"""

from __future__ import annotations

import math
import sys
import warnings

from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import box_drop  # noqa: E402  (scripts/box_drop.py: the law and the rigid box's statics)

HALF, G, DT = 0.025, 9.81, 1e-3
#: Each box's mass [kg] in the rest and stack scenes (pybullet's cube_small.urdf: 0.1 kg).
MASS = 0.1
#: Start gap between the boxes [m] and the tilt [deg] of the rest scenes (as box_drop's rest test).
GAP, TILT_DEG = 2e-4, (1.0, 0.5, 0.0)
#: The crossing scene: the gap between the sharp edges [m] and B's speed toward A [m/s] (no gravity).
CROSS_GAP, CROSS_SPEED = 5e-4, 0.5
#: The overhang scene: the upper box's centre this far off the lower box's along x [m]: its +x corners
#: 20 mm beyond the lower box's face, its centre of mass still over it (20 < 25 mm).
OVERHANG = 0.02
#: The landing scene: the upper box's lowest sharp corner this far above the lower box [m], its Euler
#: angles [deg] (the drop's, MuJoCo's "xyz").
LAND_GAP, LAND_EULER_DEG = 1e-3, (90.0, 7.0, 3.0)


def _quat_wxyz(euler_deg) -> np.ndarray:
    import mujoco

    q = np.zeros(4)
    mujoco.mju_euler2Quat(q, np.radians(euler_deg), "xyz")
    return q


def _scene(scene: str) -> list:
    """(name, centre [m] (3,), quaternion wxyz (4,), mass [kg], downward speed [m/s]) of each box, bottom first."""
    import mujoco

    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    if scene == "drop":
        return [("A", (0.0, 0.0, 0.06), _quat_wxyz((0.0, 90.0, 0.0)), 0.2, 0.0),
                ("B", (0.004, 0.003, 0.2), _quat_wxyz((90.0, 7.0, 3.0)), 0.1, 0.0)]
    if scene == "cross":  # no gravity: B (45 deg about x) closing on A (45 deg about y) edge across edge
        r = 2 * math.sqrt(2) * HALF  # the sharp edges touch at this centres' distance
        return [("A", (0.0, 0.0, 0.1), _quat_wxyz((0.0, 45.0, 0.0)), MASS, 0.0),
                ("B", (0.0, 0.0, 0.1 + r + CROSS_GAP), _quat_wxyz((45.0, 0.0, 0.0)), MASS, CROSS_SPEED)]
    if scene == "edge":  # the drop's upper box over the lower box's edge (its centre 30 mm off A's)
        return [("A", (0.0, 0.0, HALF), _quat_wxyz((0.0, 0.0, 0.0)), MASS, 0.0),
                ("B", (0.03, 0.003, 0.2), _quat_wxyz((90.0, 7.0, 3.0)), MASS, 0.0)]
    if scene == "overhang":  # a box set flat over a resting box's edge (its centre OVERHANG off A's, still over A)
        flat = _quat_wxyz((0.0, 0.0, 0.0))
        return [("A", (0.0, 0.0, HALF + GAP), flat, MASS, 0.0),
                ("B", (OVERHANG, 0.0, 3 * HALF + 2 * GAP), flat, MASS, 0.0)]
    if scene == "land":  # the drop's upper box LAND_GAP above the lower one, at its speed from 0.2 m
        q = _quat_wxyz(LAND_EULER_DEG)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, q)
        z = 2 * HALF + LAND_GAP - float(((signs * HALF) @ R.reshape(3, 3).T[:, 2]).min())
        return [("A", (0.0, 0.0, HALF), _quat_wxyz((0.0, 0.0, 0.0)), MASS, 0.0),
                ("B", (0.004, 0.003, z), q, MASS, math.sqrt(2 * G * (0.2 - z)))]
    levels = {"rest": 2, "stack3": 3}[scene]
    out, top = [], 0.0  # top: the highest point of the boxes below [m]
    for i in range(levels):
        tilt = (0.0, 0.0, 0.0) if i == 0 else tuple(t * (1 if i % 2 else -1) for t in TILT_DEG)
        q = _quat_wxyz(tilt)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, q)
        z = (signs * HALF) @ R.reshape(3, 3).T[:, 2]  # the sharp corners' heights about the centre
        centre = top + GAP - float(z.min())
        out.append((f"box{i}", (0.0, 0.0, centre), q, MASS, 0.0))
        top = centre + float(z.max())
    return out


def run(engine: str, scene: str, steps: int) -> dict:
    """The scene (module docstring) for ``steps`` steps of DT: a dict of the printed numbers."""
    runner = _mujoco if engine == "mujoco" else _pybullet
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = runner(scene, steps)
    E = np.asarray(out.pop("E"))
    out["E0_J"], out["E_end_J"], out["E_max_J"] = float(E[0]), float(E[-1]), float(E.max())
    out["gain_J"] = float(np.max(E - np.minimum.accumulate(E)))
    rise = np.diff(E)
    out["largest_step_rise_J"] = float(rise.max()) if rise.size else 0.0
    out["warnings"] = sorted({str(w.message)[:200] for w in caught})
    return out


def _finish(out: dict, ad, boxes: list, masses: list, coms: list, poses: list) -> dict:
    """The end's numbers per box-on-box pair (``boxes``: (first slot, BoxOnBox) bottom first; ``poses``:
    each box's (centre [m] (3,), rotation (3, 3)) at the end of the last step, where the manager's
    approaches are: the engine's corners are taken there, and the statics from there)."""
    mgr = ad.manager
    recs = ad.records
    out.update(records=len(recs), flagged=sum(1 for r in recs if r.outside_validity),
               island_gains=len(mgr.island_energy_gains))
    box_pairs = set()
    for first, bb in boxes:
        box_pairs.update(range(first, first + bb.n))
    out["box_records"] = [r for r in recs if r.inputs.get("pair") in box_pairs]  # the box-box pairs' records
    out["interfaces"] = []
    for level, (first, bb) in enumerate(boxes):
        slots = first + np.arange(bb.n)
        upper = level + 1
        row = {"active": mgr.active[slots].tolist(), "which": bb.which, "face": list(bb.face),
               "crossing": bb.crossing, "moved": [bool(mv) for mv in bb.moved],
               "points_m": bb.points().tolist()}  # at the last step's start; a moved slot: on the face's edge
        if np.all(mgr.active[slots]):
            row["x_engine_start_m"] = bb.corners.x[bb.corner].tolist()  # at the last step's start
            bb.box.corners = bb.corners_at(*poses[upper], *poses[level])  # body 1 is the upper box
            above = float(sum(masses[upper:]))  # the weight this face carries
            row["x_internal_m"] = mgr.x[slots].tolist()
            row["x_engine_m"] = bb.corners.x[bb.corner].tolist()
            row["x_static_m"] = box_drop.static_face(mgr, bb.box, slots, coms[upper], above, G, first).tolist()
            row["load_N"] = above * G
            row["onsets"] = [{k: float(v[mgr._pos[p]]) for k, v in mgr._onset[mgr._group_of[p]].items()}
                             for p in slots]
        out["interfaces"].append(row)
    return out


def _mujoco(scene: str, steps: int) -> dict:
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import mechanical_energy

    spec = _scene(scene)
    bodies = "".join(
        f'<body name="{n}" pos="{" ".join(repr(float(c)) for c in p)}" quat="{" ".join(repr(float(c)) for c in q)}">'
        f'<freejoint/><geom name="{n}" type="box" size="{HALF} {HALF} {HALF}" mass="{m}"/></body>'
        for n, p, q, m, _ in spec)
    grav = "0 0 0" if scene == "cross" else f"0 0 {-G}"
    xml = (f'<mujoco><option timestep="{DT}" integrator="Euler" gravity="{grav}"/><worldbody>'
           f'<geom name="floor" type="plane" size="2 2 0.1"/>{bodies}</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(model)
    for i, row in enumerate(spec):
        d.qvel[6 * i + 2] = -row[4]
    names = [s[0] for s in spec]
    pairs = [PairSpec(n, "floor", box_drop.law()) for n in names]
    pairs += [PairSpec(names[i + 1], names[i], box_drop.law()) for i in range(len(names) - 1)]
    ad = MujocoAdapter(model, d, pairs)
    n_floor = len(names) * 4
    boxes = [(n_floor + 4 * i, ad._box[len(names) + i]) for i in range(len(names) - 1)]
    E, deepest = [], -math.inf
    with installed(ad):
        for _ in range(steps):
            mujoco.mj_step(model, d)
            for _, bb in boxes:
                if bb.corners is not None:
                    deepest = max(deepest, float(np.max(bb.corners.x)))
            if not np.any(ad.manager.J != 0.0):
                E.append(mechanical_energy(model, d, d.qvel - ad.velocity_offset()) + ad.manager.stored_energy())
    v = d.qvel - ad.velocity_offset()
    mujoco.mj_kinematics(model, d)  # the poses at the end of the last step (mj_step leaves its start's)
    out = {"engine": "mujoco", "scene": scene, "steps": steps, "E": E, "deepest_box_corner_m": deepest,
           "z_end_m": [float(d.xpos[1 + i][2]) for i in range(len(names))],
           "speed_end": float(max(np.linalg.norm(v[6 * i:6 * i + 3]) + HALF * np.linalg.norm(v[6 * i + 3:6 * i + 6])
                                  for i in range(len(names))))}
    return _finish(out, ad, boxes, [s[3] for s in spec], [d.xpos[1 + i].copy() for i in range(len(names))],
                   [(d.xpos[1 + i].copy(), d.xmat[1 + i].reshape(3, 3).copy()) for i in range(len(names))])


def _pybullet(scene: str, steps: int) -> dict:
    import pybullet as pb
    import pybullet_data

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter

    c = pb.connect(pb.DIRECT)
    try:
        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
        g = 0.0 if scene == "cross" else G
        pb.setGravity(0, 0, -g, physicsClientId=c)
        pb.setTimeStep(DT, physicsClientId=c)
        plane = pb.loadURDF("plane.urdf", physicsClientId=c)
        if scene == "drop":  # the lead's pb_stack.py
            spec = [("A", (0.0, 0.0, 0.0255), pb.getQuaternionFromEuler([0, 0, 0]), MASS, 0.0),
                    ("B", (0.004, 0.003, 0.2), pb.getQuaternionFromEuler([0.2, 0.1, 0.3]), MASS, 0.0)]
        else:
            spec = [(n, p, (q[1], q[2], q[3], q[0]), m, v) for n, p, q, m, v in _scene(scene)]
        if scene == "drop":
            uids = [pb.loadURDF("cube_small.urdf", list(p), list(q), physicsClientId=c) for _, p, q, _, _ in spec]
        else:  # the box's own inertia (cube_small.urdf gives 1 kg m^2 for its 0.1 kg: it hardly turns)
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[HALF] * 3, physicsClientId=c)
            uids = [pb.createMultiBody(m, shape, -1, list(p), list(q), physicsClientId=c) for _, p, q, m, _ in spec]
        for u, row in zip(uids, spec):
            pb.resetBaseVelocity(u, [0.0, 0.0, -row[4]], [0.0, 0.0, 0.0], physicsClientId=c)
        pairs = [PairSpec((u, -1), (plane, -1), box_drop.law()) for u in uids]
        pairs += [PairSpec((uids[i + 1], -1), (uids[i], -1), box_drop.law()) for i in range(len(uids) - 1)]
        ad = PybulletAdapter(c, pairs)
        boxes = [(ad._narrow[len(uids) + i].first, ad._narrow[len(uids) + i].box) for i in range(len(uids) - 1)]
        dyn = [pb.getDynamicsInfo(u, -1, physicsClientId=c) for u in uids]

        def state():
            e, coms, speed = 0.0, [], 0.0
            for u, info in zip(uids, dyn):
                m, inertia = float(info[0]), np.array(info[2], dtype=float)
                pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
                v, w = (np.array(a, dtype=float) for a in pb.getBaseVelocity(u, physicsClientId=c))
                wl = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3).T @ w
                e += m * g * pos[2] + 0.5 * m * v @ v + 0.5 * wl @ (inertia * wl)
                coms.append(np.array(pos))
                speed = max(speed, float(np.linalg.norm(v) + HALF * np.linalg.norm(w)))
            return e, coms, speed

        E, deepest = [], -math.inf
        for _ in range(steps):
            ad.step(1)
            for _, bb in boxes:
                if bb.corners is not None:
                    deepest = max(deepest, float(np.max(bb.corners.x)))
            if not np.any(ad.manager.J != 0.0):
                E.append(state()[0] + ad.manager.stored_energy())
        _, coms, speed = state()
        out = {"engine": "pybullet", "scene": scene, "steps": steps, "E": E, "deepest_box_corner_m": deepest,
               "z_end_m": [float(p[2]) for p in coms], "speed_end": speed}
        poses = []
        for u in uids:
            pos, orn = pb.getBasePositionAndOrientation(u, physicsClientId=c)
            poses.append((np.array(pos), np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3)))
        return _finish(out, ad, boxes, [float(i[0]) for i in dyn], coms, poses)
    finally:
        pb.disconnect(c)


def main(argv) -> None:
    engine = argv[1] if len(argv) > 1 else "mujoco"
    scene = argv[2] if len(argv) > 2 else "drop"
    steps = int(argv[3]) if len(argv) > 3 else 2000
    out = run(engine, scene, steps)
    for key, val in out.items():
        if key == "box_records":
            for r in val:
                print(f"box-box record: pair {r.inputs['pair']} COR {r.cor_n:.6g} tau {r.tau:.6g} s x_max "
                      f"{r.x_max:.4g} m R ({r.parameters['R_a']:.4g}, {r.parameters['R_b']:.4g}) m")
        elif key == "interfaces":
            for i, row in enumerate(val):
                print(f"interface {i}: " + ", ".join(f"{k}={v}" for k, v in row.items() if k != "onsets"))
        else:
            print(f"{key}: {val}")


if __name__ == "__main__":
    main(sys.argv)
