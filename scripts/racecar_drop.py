"""pybullet_data's racecar.urdf dropped on plane.urdf with MSF on its four
wheels (issue 13; docs/engines.md "A URDF cylinder and plane.urdf in
pybullet"), the numbers the docs quote.

    .venv/bin/python scripts/racecar_drop.py [--z 0.2] [--steps 1500] [--implicit] [--builtin] [--mujoco]

Natural rubber on steel, dt = 1 ms, base released at rest at height --z
[m] (0.2: the wheels 0.2 m above the floor). --implicit loads the URDF with
URDF_USE_IMPLICIT_CYLINDER (pybullet's cylinder shape; without it each
wheel is a 64-vertex convex hull, which the adapter takes for its
cylinder); --builtin steps pybullet's own contact instead. Prints every
100 steps the energy E (kinetic + gravitational potential of all links,
plus ContactManager.stored_energy with MSF), the base's velocity and spin
and the wheel centres' heights [m], then the largest one-step rise of E
and the warnings (first line of each).

--mujoco: the same drop in MuJoCo, which loads racecar.urdf with its
wheels as cylinder geoms but fuses the base (no floating joint in the
URDF) into the world: the links of base_link, chassis and the rest become
one free body of their mass (4.33 kg) with the chassis' inertia at its
inertial origin (0.14, 0, 0.05) m, an approximation of pybullet's tree;
the floor a plane. E there: MuJoCo's kinetic + potential energy of the
state after the step.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import pybullet as pb  # noqa: E402
import pybullet_data  # noqa: E402
import test_narrow_pybullet as T  # noqa: E402

WHEELS = ("left_rear", "right_rear", "left_front", "right_front")


def mujoco_car(z: float):
    """(model, data, wheel geom ids) of racecar.urdf in MuJoCo as a free body at base height z [m] over a plane."""
    import mujoco

    m0 = mujoco.MjModel.from_xml_path(str(Path(pybullet_data.getDataPath()) / "racecar" / "racecar.urdf"))
    path = Path("/tmp") / f"racecar_mujoco_{id(m0)}.xml"
    mujoco.mj_saveLastXML(str(path), m0)
    raw = path.read_text()
    path.unlink()
    names = iter(WHEELS)  # the wheels are the URDF's four cylinders, in its order
    raw = re.sub(r'<geom size="0.05 0.0225"', lambda _: f'<geom name="{next(names)}" size="0.05 0.0225"', raw)
    body = raw.split("<worldbody>")[1].split("</worldbody>")[0]
    xml = ('<mujoco model="racecar"><compiler angle="radian"/><option timestep="0.001"/><worldbody>'
           '<geom name="floor" type="plane" size="5 5 0.1"/>'
           f'<body name="car" pos="0 0 {z}"><freejoint/><inertial pos="0.14 0 0.05" mass="4.33" '
           'diaginertia="0.010609 0.050409 0.05865"/>' + body + "</body></worldbody></mujoco>")
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, w) for w in WHEELS]


def run_mujoco(a) -> None:
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter
    from msf_contact import ContactPair, Curvature, make_law

    model, data, gid = mujoco_car(a.z)
    law = make_law("msf", ContactPair(T.RUBBER, T.STEEL), Curvature.sphere_on_plane(0.05))
    ad = None if a.builtin else MujocoAdapter(model, data, [PairSpec(w, "floor", law) for w in WHEELS])
    probe = mujoco.MjData(model)

    def energy():
        probe.qpos[:], probe.qvel[:] = data.qpos, data.qvel
        mujoco.mj_forward(model, probe)  # the state's energy now (data.energy is the last step start's)
        return float(probe.energy[0] + probe.energy[1]) + (0.0 if a.builtin else ad.manager.stored_energy())

    E0 = E_prev = energy()
    rise, at, t0 = 0.0, -1, time.process_time()
    for i in range(a.steps):
        mujoco.mj_step(model, data) if a.builtin else ad.step(1)
        E = energy()
        if E - E_prev > rise:
            rise, at = E - E_prev, i
        E_prev = E
        if i % 100 == 0 or i == a.steps - 1:
            print(f"step {i}: E {E:.5f} J, v {np.round(data.qvel[:3], 3)}, w {np.round(data.qvel[3:6], 2)}, "
                  f"wheel z {np.round(data.geom_xpos[gid, 2], 5)}")
    print(f"E {E0:.4f} -> {E:.4f} J; largest one-step rise {rise:.3g} J at step {at}; "
          f"{time.process_time() - t0:.1f} s CPU" + ("" if a.builtin else f"; deep onsets {ad.deep_onsets}"))


def run_pybullet(a) -> None:
    c, car, floor, ad, wheels = T._racecar(a.z, pb.URDF_USE_IMPLICIT_CYLINDER if a.implicit else 0)
    if a.builtin:
        ad.close()  # pybullet's contact back on for the wheels
    try:
        def energy():
            return T._multibody_energy(c, car) + (0.0 if a.builtin else ad.manager.stored_energy())

        E0 = E_prev = energy()
        rise, at, t0 = 0.0, -1, time.process_time()
        for i in range(a.steps):
            pb.stepSimulation(physicsClientId=c) if a.builtin else ad.step(1)
            E = energy()
            if E - E_prev > rise:
                rise, at = E - E_prev, i
            E_prev = E
            if i % 100 == 0 or i == a.steps - 1:
                v, w = pb.getBaseVelocity(car, physicsClientId=c)
                wz = [pb.getLinkState(car, j, physicsClientId=c)[0][2] for j in wheels]
                print(f"step {i}: E {E:.5f} J, v {np.round(v, 3)}, w {np.round(w, 2)}, wheel z {np.round(wz, 5)}")
        print(f"E {E0:.4f} -> {E:.4f} J; largest one-step rise {rise:.3g} J at step {at}; "
              f"{time.process_time() - t0:.1f} s CPU" + ("" if a.builtin else f"; deep onsets {ad.deep_onsets}"))
    finally:
        pb.disconnect(c)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--z", type=float, default=0.2, help="base height at release [m]")
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--implicit", action="store_true", help="URDF_USE_IMPLICIT_CYLINDER")
    ap.add_argument("--builtin", action="store_true", help="the engine's own contact")
    ap.add_argument("--mujoco", action="store_true", help="the drop in MuJoCo (see the module docstring)")
    a = ap.parse_args(argv)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (run_mujoco if a.mujoco else run_pybullet)(a)
    for x in caught:
        print("warning:", str(x.message).split(" (warned")[0][:300])


if __name__ == "__main__":
    main()
