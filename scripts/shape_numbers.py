"""Numbers docs/engines.md quotes for issue 13's MuJoCo side that no
benchmark prints:

    .venv/bin/python scripts/shape_numbers.py line      # a lying cylinder: two rim points vs the line law (both engines)
    .venv/bin/python scripts/shape_numbers.py profile   # cProfile of the MSF humanoid (200 steps)
    .venv/bin/python scripts/shape_numbers.py objects [pybullet]   # the objects' MSF energy gain (MuJoCo, or pybullet) against its bound

``line``: natural rubber on steel, a cylinder r 10 mm, 60 mm long, edge
radius 1 mm, falling flat at 1 m/s: the reference solver's line law over
its side (geometry.SideFootprint with the rim's arcs, "rounded"), the same
cylinder in MuJoCo and in pybullet at dt = 1 ms (its two ends carrying the
line law, engines._narrow.SideEndLaw), and one of the two rim points alone (the rim
torus at alpha = 0: 1 mm and 10 mm) carrying half the mass, as the
engines had it before. ``profile``: the 20 most expensive calls
(cumulative) of 200 steps of humanoid.xml with seeded torques after 20
warm-up steps.
"""

from __future__ import annotations

import sys
import warnings


def line() -> None:
    import math

    from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact
    from msf_contact.geometry import SideFootprint

    rubber, steel = preset("natural-rubber"), preset("steel")
    r, h, rho, v = 0.01, 0.03, 1e-3, 1.0
    m = rubber.density * math.pi * r * r * 2 * h
    pair = ContactPair(rubber, steel)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fp = SideFootprint(r, 2 * h - 2 * rho, 0.0, "rounded", rho)
        side = make_law("msf", pair, Curvature.side_on_plane(fp))
        a = simulate_impact(side, Body(rubber, r, m, 0.5 * m * r * r), Body.half_space(steel), v)
        rim = make_law("msf", pair, Curvature(rho, r, math.inf, math.inf))
        b = simulate_impact(rim, Body(rubber, rho, m / 2, 0.4 * m / 2 * rho * rho), Body.half_space(steel), v)
        eng = _mujoco_lying_cylinder(pair, r, h, m, v)
        pyb = _pybullet_lying_cylinder(pair, r, h, rho, m, v)
    print(f"line law over the side: COR {a.cor_n:.5f}, tau {a.tau * 1e3:.4f} ms, x_max {a.x_max * 1e3:.3f} mm, "
          f"F_max {a.F_max:.2f} N")
    print(f"MuJoCo, its ends carrying the line law: COR {eng[0]:.5f}, tau {eng[1] * 1e3:.4f} ms, "
          f"F_max {eng[2]:.2f} N in all")
    print(f"pybullet, its ends carrying the line law: COR {pyb[0]:.7f} (reference {a.cor_n:.7f}), "
          f"tau {pyb[1] * 1e3:.5f} ms, F_max {pyb[2]:.2f} N in all")
    print(f"two rim points, m/2 each: COR {b.cor_n:.3f}, tau {b.tau * 1e3:.2f} ms, x_max {b.x_max * 1e3:.2f} mm, "
          f"F_max {2 * b.F_max:.1f} N in all; outside validity: {b.outside_validity[:1]}")


def _mujoco_lying_cylinder(pair, r, h, m, v):
    """(COR of the body, tau [s], summed peak force [N]) of the cylinder dropped flat in MuJoCo."""
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter
    from msf_contact import Curvature, make_law

    I = (m * (3 * r * r + 4 * h * h) / 12, m * r * r / 2)
    xml = ('<mujoco><option timestep="0.001" gravity="0 0 0"/><worldbody>'
           '<geom name="plate" type="plane" size="1 1 0.1"/>'
           f'<body name="b" pos="0 0 {r + 1e-4!r}" euler="0 90 0"><freejoint/>'
           f'<inertial pos="0 0 0" mass="{m!r}" diaginertia="{I[0]!r} {I[0]!r} {I[1]!r}"/>'
           f'<geom name="g" type="cylinder" size="{r} {h}" mass="0"/></body></worldbody>'
           '<contact><exclude body1="world" body2="b"/></contact></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qvel[2] = -v
    ad = MujocoAdapter(model, data, [PairSpec("g", "plate", make_law("msf", pair, Curvature.sphere_on_plane(r)))])
    ad.step(100)
    return float(data.qvel[2]) / v, ad.records[0].tau, sum(rec.F_max for rec in ad.records[:2])


def _pybullet_lying_cylinder(pair, r, h, rho, m, v):
    """(COR of the body, tau [s], summed peak force [N]) of the cylinder dropped flat in pybullet."""
    import math

    import pybullet as pb

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter, scenes
    from msf_contact import Curvature, make_law

    c = scenes.new_client(1e-3)
    try:
        plane = scenes.add_plate(c)
        sh = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=r, height=2 * h, physicsClientId=c)
        u = pb.createMultiBody(m, sh, basePosition=[0, 0, r + 1e-4],
                               baseOrientation=pb.getQuaternionFromEuler([0, math.pi / 2, 0]), physicsClientId=c)
        I = m * (3 * r * r + 4 * h * h) / 12
        pb.changeDynamics(u, -1, localInertiaDiagonal=[I, I, m * r * r / 2], physicsClientId=c)
        scenes._free_dynamics(c, u)
        pb.resetBaseVelocity(u, [0, 0, -v], [0, 0, 0], physicsClientId=c)
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), make_law("msf", pair, Curvature.sphere_on_plane(r)))],
                             edge_radii={(u, -1): rho})
        ad.step(100)
        vz = pb.getBaseVelocity(u, physicsClientId=c)[0][2]
        return vz / v, ad.records[0].tau, sum(rec.F_max for rec in ad.records[:2])
    finally:
        pb.disconnect(c)


def objects(engine: str = "mujoco") -> None:
    """experiments/configs/objects.toml's drops, MSF in one engine (mujoco or pybullet): the
    energy gain of experiments.scenarios.objects.msf_energy against
    ENERGY_GAIN_RTOL E0, and the islands the contacts' own check flagged."""
    import tomllib
    from pathlib import Path

    from engines._contacts.state import ENERGY_GAIN_RTOL
    from experiments.scenarios.objects import run_cell

    cfg = tomllib.loads((Path(__file__).parents[1] / "experiments" / "configs" / "objects.toml").read_text())
    for obj in cfg["objects"]["run"]:
        cell = {"object": obj, "engine": engine, "objects": cfg["objects"], "materials": cfg["materials"],
                "drop": dict(cfg["drop"], sample=cfg["drop"]["dt"])}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            (r,) = run_cell(cell)
        print(f"{obj}: E0 {r['E0']:.4f} J, gain {r['energy_gain']:.3g} J ({100 * r['energy_gain_rel']:.4f} %), "
              f"bound {ENERGY_GAIN_RTOL * r['E0']:.3g} J, above: {r['energy_gain_above_bound']}, impacts "
              f"{r['impacts']}, outside {r['outside']}, E end {r['E_end']:.4f} J, laws {r.get('laws')}, "
              f"step {r['step_s'] * 1e3:.3g} ms", flush=True)


def profile() -> None:
    import cProfile
    import os
    import pstats

    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import load_with_msf_floor
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "humanoid.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(13)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    warnings.simplefilter("ignore")
    with installed(adapter):
        for _ in range(20):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
        prof = cProfile.Profile()
        prof.enable()
        for _ in range(200):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
        prof.disable()
    pstats.Stats(prof).sort_stats("cumulative").print_stats(20)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else ""
    if what not in ("line", "profile", "objects"):
        sys.exit("usage: scripts/shape_numbers.py line|profile|objects")
    if what == "objects" and len(sys.argv) > 2:
        objects(sys.argv[2])
    else:
        {"line": line, "profile": profile, "objects": objects}[what]()
