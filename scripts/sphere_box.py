"""Numbers docs/engines.md quotes for a sphere on a box with rounded edges
(issue 13, engines._narrow.SphereOnBox), MuJoCo unless said:

    .venv/bin/python scripts/sphere_box.py drop            # a steel ball on an edge and a corner vs the reference
    .venv/bin/python scripts/sphere_box.py table [dt]      # a rubber ball rolling off a tilted table's edge
    .venv/bin/python scripts/sphere_box.py roof [dt]       # a rubber ball rolled over the ridge of a box at 45 deg
    .venv/bin/python scripts/sphere_box.py plate           # 100 steel spheres on a box plate, pybullet: CPU time

``drop``: R 10 mm at 0.2 m/s, dt 0.1 ms, on a fixed steel box (half-size
20 mm, edge radius 1 mm), against msf_contact's reference solver with the
curvature (R, R, rho, inf) or (R, R, rho, rho). ``table``: the box's top
face tilted 2 deg, the ball set on it 10 mm from the edge, 700 steps.
``roof``: the box turned 45 deg about x, the ball launched up one face to
cross the ridge at 0.1 m/s. Each prints the energy account's largest rise
(kinetic + potential + ContactManager.stored_energy), the normal force's
largest change in a step, the records and the warnings.
"""

from __future__ import annotations

import math
import sys
import time
import warnings

import numpy as np

R, H, RHO, G = 0.01, 0.02, 1e-3, 9.81


def _ball_xml(dt, gravity, box_orient, c0, m):
    I = 0.4 * m * R * R
    return (f'<mujoco><option timestep="{dt!r}" gravity="0 0 -{gravity!r}"><flag autoreset="disable"/></option>'
            f'<worldbody><geom name="box" type="box" size="{H} {H} {H}" {box_orient}/>'
            f'<body name="b" pos="{" ".join(repr(float(v)) for v in c0)}"><freejoint/>'
            f'<inertial pos="0 0 0" mass="{m!r}" diaginertia="{I!r} {I!r} {I!r}"/>'
            f'<geom name="g" type="sphere" size="{R}" mass="0"/></body></worldbody>'
            '<contact><exclude body1="world" body2="b"/></contact></mujoco>')


def drop() -> None:
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, run_until_separated
    from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact

    steel = preset("steel")
    m = steel.density * 4 / 3 * math.pi * R ** 3
    a = np.ones(3) / math.sqrt(3.0)
    ax = np.cross(a, [0.0, 0.0, 1.0])
    ang = math.asin(float(np.linalg.norm(ax)))
    corner = [math.cos(ang / 2), *(math.sin(ang / 2) * ax / np.linalg.norm(ax))]
    edge = [math.cos(math.pi / 8), math.sin(math.pi / 8), 0.0, 0.0]
    for name, q, curv in (("edge", edge, Curvature(R, R, RHO, math.inf)), ("corner", corner, Curvature(R, R, RHO, RHO))):
        model = mujoco.MjModel.from_xml_string(_ball_xml(1e-4, 0.0, f'quat="{" ".join(repr(float(c)) for c in q)}"',
                                                         [0, 0, 0.1], m))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        top = (H - RHO) * float(np.abs(data.geom_xmat[0].reshape(3, 3)[2, :]).sum()) + RHO
        data.qpos[2], data.qvel[2] = top + R + 1e-5, -0.2
        mujoco.mj_forward(model, data)
        law = make_law("msf", ContactPair(steel, steel), Curvature.sphere_on_plane(R))
        ad = MujocoAdapter(model, data, [PairSpec("g", "box", law)])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            rec = run_until_separated(ad, 20000)
        ref = simulate_impact(make_law("msf", ContactPair(steel, steel), curv), Body.sphere(steel, R, m),
                              Body.half_space(steel), 0.2)
        print(f"{name}: COR {rec.cor_n:.7f} (reference {ref.cor_n:.7f}, {rec.cor_n / ref.cor_n - 1:+.2g}), tau "
              f"{rec.tau / ref.tau - 1:+.2g}, F_max {rec.F_max:.2f} N ({ref.F_max:.2f}), law "
              f"{ad._sphere_box[0].law.curvature}, warnings {len(caught)}, handoffs {ad.edge_handoffs}")


def _roll(model, data, m, steps):
    """Step the ball's adapter ``steps`` times; the energy account, the normal forces, the adapter."""
    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from msf_contact import ContactPair, Curvature, make_law, preset

    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))
    ad = MujocoAdapter(model, data, [PairSpec("g", "box", law)])
    E, F, I = [], [], 0.4 * m * R * R
    import mujoco

    with installed(ad), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(steps):
            mujoco.mj_step(model, data)
            rep = ad.contact_forces()
            F.append(rep[0].F_n if rep else 0.0)
            if not np.any(ad.manager.J != 0.0):
                v = data.qvel - ad.velocity_offset()
                E.append(0.5 * m * float(v[:3] @ v[:3]) + 0.5 * I * float(v[3:] @ v[3:]) + m * G * data.qpos[2]
                         + ad.manager.stored_energy())
    E, F = np.array(E), np.array(F)
    rise = max(float(np.max(E[j:] - E[j])) for j in range(E.size))
    print(f"E0 {E[0]:.6g} J, end {E[-1]:.6g} J, largest rise {rise:.3g} J; m g {m * G:.4g} N; records "
          f"{len(ad.records)}, flagged {sum(1 for r in ad.records if r.outside_validity)}, CORs "
          f"{[round(r.cor_n, 3) for r in ad.records]}; island gains {len(ad.manager.island_energy_gains)}; law changes "
          f"{ad._sphere_box[0].changes}; warnings {[str(w.message)[:100] for w in caught]}")
    return F


def table(dt: float = 1e-3) -> None:
    import mujoco

    from msf_contact import preset

    m = preset("natural-rubber").density * 4 / 3 * math.pi * R ** 3
    tilt = math.radians(2.0)
    c0 = (H + R) * np.array([0.0, -math.sin(tilt), math.cos(tilt)]) + (H - RHO - 0.01) * np.array(
        [0.0, math.cos(tilt), math.sin(tilt)])
    model = mujoco.MjModel.from_xml_string(_ball_xml(dt, G, 'euler="-2 0 0"', c0, m))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    F = _roll(model, data, m, int(round(0.7 / dt)))
    on = F[int(round(0.1 / dt)):]
    on = on[:int(np.argmax(on < 0.8 * m * G))]
    print(f"from the face onto the edge: largest |dF| a step {np.max(np.abs(np.diff(on))):.4g} N "
          f"({np.max(np.abs(np.diff(on))) / (m * G):.3%} of m g)")


def roof(dt: float = 1e-3) -> None:
    import mujoco

    from msf_contact import preset

    m = preset("natural-rubber").density * 4 / 3 * math.pi * R ** 3
    s2 = 1 / math.sqrt(2)
    n2, t = np.array([0, -s2, s2]), np.array([0, s2, s2])
    c0 = (H + R) * n2 + (H - RHO - 0.005) * t
    v0 = math.sqrt(0.1 ** 2 + (10 / 7) * G * ((H - RHO) * math.sqrt(2) + RHO + R - c0[2]))
    model = mujoco.MjModel.from_xml_string(_ball_xml(dt, G, 'euler="45 0 0"', c0, m))
    data = mujoco.MjData(model)
    data.qvel[:3] = v0 * t
    data.qvel[3:6] = np.cross(n2, v0 * t) / R  # rolling
    mujoco.mj_forward(model, data)
    print(f"launched at {v0:.4f} m/s")
    _roll(model, data, m, int(round(0.3 / dt)))


def plate() -> None:
    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter, scenes
    from msf_contact import ContactPair, Curvature, make_law, preset

    c = scenes.new_client(1e-3, G)
    box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.5, 0.5, 0.05], physicsClientId=c)
    plate_uid = pb.createMultiBody(0.0, box, basePosition=[0, 0, -0.05], physicsClientId=c)
    r = 0.005
    law = make_law("msf", ContactPair(preset("steel"), preset("steel")), Curvature.sphere_on_plane(r))
    sh = pb.createCollisionShape(pb.GEOM_SPHERE, radius=r, physicsClientId=c)
    rng = np.random.default_rng(1)
    uids = []
    for _ in range(100):
        u = pb.createMultiBody(0.004, sh, basePosition=[rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4),
                                                          r + rng.uniform(0.001, 0.05)], physicsClientId=c)
        scenes._free_dynamics(c, u)  # noqa: SLF001 - the scenes' settings for a free body
        pb.setCollisionFilterGroupMask(u, -1, 0, 0, physicsClientId=c)
        uids.append(u)
    ad = PybulletAdapter(c, [PairSpec((u, -1), (plate_uid, -1), law) for u in uids])
    t = time.process_time()
    ad.step(1000)
    print(f"100 spheres on a box plate, 1,000 steps: {time.process_time() - t:.2f} CPU-s, {len(ad.records)} records")
    pb.disconnect(c)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else ""
    arg = [float(a) for a in sys.argv[2:3]]
    runs = {"drop": drop, "table": table, "roof": roof, "plate": plate}
    if what not in runs:
        raise SystemExit(__doc__)
    runs[what](*arg)
