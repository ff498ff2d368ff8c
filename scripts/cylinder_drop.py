"""A cylinder dropped on a plane nearly flat on its end, as a user does it
(issue 13), in MuJoCo or pybullet:

    .venv/bin/python scripts/cylinder_drop.py mujoco [tilt_deg] [steps]
    .venv/bin/python scripts/cylinder_drop.py pybullet [tilt_deg] [steps]
    .venv/bin/python scripts/cylinder_drop.py mujoco|pybullet sweep

A puck or a can: radius 50 mm, half-height 22.5 mm, 0.1 kg, its axis
tilted by ``tilt_deg`` about the world x axis, its centre 0.1 m above the
plane, natural rubber on steel, a plain ``PairSpec(obj, floor,
make_law("msf", ..., Curvature.sphere_on_plane(0.02)))``, the default edge
radius (msf_contact.shapes.DEFAULT_EDGE_RADIUS, 1 mm), dt = 1 ms (MuJoCo: a
cylinder geom on a plane geom; pybullet: a GEOM_CYLINDER multibody on
``plane.urdf``, whose collision shape is a 200 x 200 x 10 m box). It lands
on its rim ring (engines._narrow.CylinderOnPlane, RimRing) and comes to
rest on its end. Printed: the energy account (kinetic + gravitational of the
physical velocities plus the contacts' stored energy,
ContactManager.stored_energy, read at steps without a pending timing
correction), its largest rise over any interval and in one step, the
largest kinetic energy against the drop's m g h, the records, how many are
flagged and how many carry the stand-in note (engines._narrow.contact_law),
the island energy gains flagged, and at the end the four slots' approaches
(the manager's) against the static overlap of the ring law (:func:`static_ring`).

``sweep``: the same cylinder at 1 m/s tilted 0-5 deg (:func:`sweep`), the
largest record's peak force at each tilt. ``run(engine, ...)`` and
``sweep`` are what tests/test_cylinder_on_plane.py calls with fewer steps
or a start just above the plane (``gap``).
"""

from __future__ import annotations

import math
import sys
import time
import warnings

import numpy as np

#: The user's cylinder: radius, half-height [m], mass [kg], drop height of its centre [m].
RADIUS, HALF, MASS, HEIGHT = 0.05, 0.0225, 0.1, 0.1
G, DT = 9.81, 1e-3
#: What the stand-in point law writes in a record's outside_validity (engines._narrow.contact_law).
STAND_IN = "model's stand-in"


def law():
    from msf_contact import ContactPair, Curvature, make_law, preset

    return make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))


def _start(tilt_deg: float, height: float | None, gap: float | None):
    """(centre height [m], downward speed [m/s]): from rest at ``height``, or
    (``gap`` given) the same drop's state when the rim's lowest point is
    ``gap`` [m] above the plane (free fall has no torque; ``height`` None:
    from rest there)."""
    t = math.radians(tilt_deg)
    drop = HALF * math.cos(t) + RADIUS * math.sin(t)  # the centre above the sharp rim's lowest point
    if gap is None:
        return height, 0.0
    z = drop + gap
    return z, 0.0 if height is None else math.sqrt(2.0 * G * (height - z))


def static_ring(ad_law, mass: float = MASS, g: float = G, n: int = 4, onset: dict | None = None) -> float:
    """The static overlap [m] of the ring standing flat: each of its n arcs
    carries m g / n (symmetry), with msf_contact's line law of the arc
    (``SideFootprint(rho, 2 pi (R - rho) / n, caps="flat")``, the materials
    of ``ad_law``) and the onset constants ``onset`` (a slot's, from its
    contact's onset: E' at its omega_x)."""
    from msf_contact import Curvature, make_law
    from msf_contact.geometry import SideFootprint
    from msf_contact.statics import static_overlap

    rho = ad_law.end_radius
    fp = SideFootprint(rho, 2.0 * math.pi * (RADIUS - rho) / n, 0.0, "flat")
    ref = make_law("msf", ad_law.pair, Curvature.side_on_plane(fp), omega=ad_law.omega)
    return float(static_overlap(ref, [mass * g / n], onset)[0])


def run(engine: str, tilt_deg: float = 0.0, steps: int = 1500, *, gap: float | None = None,
        height: float | None = HEIGHT, speed: float | None = None) -> dict:
    """The drop (module docstring) for ``steps`` steps of DT: a dict of the
    printed numbers. gap [m]: start with the rim's lowest point that far
    above the plane at the drop's speed there (None: from rest at
    ``height``; ``height`` None with a gap: from rest at the gap).
    speed [m/s]: the start's downward speed instead. ``drop_energy_J``: m g
    times the fall of the centre from the start to where the sharp rim
    touches, plus the start's kinetic energy; ``peak_N`` the largest
    record's F_max; ``rebound`` the kinetic energy at the end (translation
    and rotation) less the gravitational energy gained since the start,
    over the start's kinetic energy (E_out/E_in of a bounce)."""
    z0, v0 = _start(tilt_deg, height, gap)
    v0 = v0 if speed is None else float(speed)
    runner = _mujoco if engine == "mujoco" else _pybullet
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = runner(steps, z0, v0, tilt_deg)
    E = np.asarray(out.pop("E"))
    ke_end, ke_start = out.pop("ke_end_J"), out.pop("ke_start_J")
    out["rebound"] = (ke_end + MASS * G * (out["z_end_m"] - z0)) / ke_start if ke_start > 0.0 else math.nan
    out["drop_energy_J"] = MASS * G * (z0 - _start(tilt_deg, None, 0.0)[0]) + 0.5 * MASS * v0 * v0
    out["E_start_J"] = MASS * G * z0 + 0.5 * MASS * v0 * v0  # the account at t = 0
    out["E0_J"], out["E_end_J"] = float(E[0]), float(E[-1])
    out["gain_J"] = float(np.max(E - np.minimum.accumulate(E)))
    out["step_gain_J"] = float(np.max(np.diff(E), initial=0.0))
    out["warnings"] = sorted({str(w.message)[:160] for w in caught})
    return out


def _finish(out: dict, ad, st) -> dict:
    mgr = ad.manager
    recs = ad.records
    out.update(records=len(recs), flagged=sum(1 for r in recs if r.outside_validity),
               peak_N=max((r.F_max for r in recs), default=0.0),
               stand_in=sum(1 for r in recs if r.outside_validity and STAND_IN in r.outside_validity),
               island_gains=len(mgr.island_energy_gains), mode_end=st.mode)
    slots = np.arange(st.ring.n)
    if st.mode == "ring" and np.all(mgr.active[slots]):
        out["x_internal_m"] = mgr.x[slots].tolist()
        out["x_engine_m"] = st.ring.rim.x.tolist()
        out["x_static_m"] = [static_ring(st.ring.law[int(s)], onset={key: v[mgr._pos[[int(s)]]] for key, v in
                                                                     mgr._onset[mgr._group_of[int(s)]].items()})
                             for s in slots]
    return out


def _mujoco(steps, z0, v0, tilt_deg) -> dict:
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import mechanical_energy

    xml = (f'<mujoco><option timestep="{DT}"/><worldbody><geom name="floor" type="plane" size="2 2 0.1"/>'
           f'<body name="obj" pos="0 0 {z0!r}" euler="{tilt_deg!r} 0 0"><freejoint/>'
           f'<geom name="obj" type="cylinder" size="{RADIUS} {HALF}" mass="{MASS}"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[2] = -v0
    ad = MujocoAdapter(m, d, [PairSpec("obj", "floor", law())])
    st = ad._line[0]
    E, K = [], []
    ke_start = 0.5 * MASS * v0 * v0
    wall = time.perf_counter()
    with installed(ad):
        for _ in range(steps):
            mujoco.mj_step(m, d)
            v = d.qvel - ad.velocity_offset()
            K.append(0.5 * MASS * float(v[:3] @ v[:3]))
            if not np.any(ad.manager.J != 0.0):
                E.append(mechanical_energy(m, d, v) + ad.manager.stored_energy())
    v = d.qvel - ad.velocity_offset()
    ke_end = mechanical_energy(m, d, v) - MASS * G * float(d.qpos[2])
    out = {"engine": "mujoco", "steps": steps, "E": E, "ke_max_J": max(K), "z_end_m": float(d.qpos[2]),
           "ke_start_J": ke_start, "ke_end_J": ke_end,
           "step_ms": 1e3 * (time.perf_counter() - wall) / steps}
    return _finish(out, ad, st)


def _pybullet(steps, z0, v0, tilt_deg) -> dict:
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
        col = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=RADIUS, height=2 * HALF, physicsClientId=c)
        orn = pb.getQuaternionFromEuler([math.radians(tilt_deg), 0.0, 0.0])
        u = pb.createMultiBody(MASS, col, -1, [0, 0, z0], orn, physicsClientId=c)
        pb.resetBaseVelocity(u, [0, 0, -v0], [0, 0, 0], physicsClientId=c)
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law())])
        st = ad._narrow[0].line
        info = pb.getDynamicsInfo(u, -1, physicsClientId=c)
        m, I = float(info[0]), np.array(info[2], dtype=float)
        E, K = [], []
        ke_start = 0.5 * MASS * v0 * v0
        wall = time.perf_counter()
        for _ in range(steps):
            ad.step(1)
            pos, q = pb.getBasePositionAndOrientation(u, physicsClientId=c)
            v, w = (np.array(a, dtype=float) for a in pb.getBaseVelocity(u, physicsClientId=c))
            wl = np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3).T @ w
            K.append(0.5 * m * float(v @ v))
            if not np.any(ad.manager.J != 0.0):
                E.append(m * G * pos[2] + 0.5 * m * v @ v + 0.5 * wl @ (I * wl) + ad.manager.stored_energy())
        out = {"engine": "pybullet", "steps": steps, "E": E, "ke_max_J": max(K), "z_end_m": float(pos[2]),
               "ke_start_J": ke_start, "ke_end_J": 0.5 * m * v @ v + 0.5 * wl @ (I * wl),
               "step_ms": 1e3 * (time.perf_counter() - wall) / steps}
        return _finish(out, ad, st)
    finally:
        pb.disconnect(c)


#: The tilts of :func:`sweep` [deg] (tests/test_cylinder_on_plane.py's).
SWEEP_TILTS = (0.0, 0.001, 0.01, 0.1, 0.5, 1.0, 2.0, 5.0)


def sweep(engine: str, steps: int = 40) -> list:
    """The user's cylinder at 1 m/s, 10 um above the plane, at each of
    SWEEP_TILTS: (tilt [deg], largest record's F_max [N], E_out/E_in, island
    gains flagged) each, over ``steps`` steps."""
    rows = []
    for tilt in SWEEP_TILTS:
        out = run(engine, tilt, steps, gap=1e-5, height=None, speed=1.0)
        rows.append((tilt, out["peak_N"], out["rebound"], out["island_gains"]))
    return rows


def main(argv) -> None:
    engine = argv[1] if len(argv) > 1 else "mujoco"
    if len(argv) > 2 and argv[2] == "sweep":
        for tilt, peak, reb, gains in sweep(engine):
            print(f"tilt {tilt:g} deg: peak {peak:.4f} N, E_out/E_in {reb:.4f}, island gains {gains}")
        return
    tilt = float(argv[2]) if len(argv) > 2 else 0.0
    steps = int(argv[3]) if len(argv) > 3 else 1500
    for key, val in run(engine, tilt, steps).items():
        print(f"{key}: {val}")


if __name__ == "__main__":
    main(sys.argv)
