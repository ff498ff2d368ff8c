"""Objects dropped into pybullet_data's ``tray/traybox.urdf`` (a fixed link of
five boxes, as pybullet's own grasping environments use it) with MSF
(natural rubber on steel) on every object-tray shape pair, ``(uid, link,
k)`` for each of the tray's shapes, and rubber on rubber between the
objects (spheres; ``--no-pp`` leaves those pairs out). Printed: the
objects' translational kinetic plus potential energy (start, largest, end,
the largest rise in a step), their heights at the end, the records and how
many are flagged, the warnings. Nothing is written.

    .venv/bin/python scripts/tray_drop.py --obj sphere_small.urdf --n 5
    .venv/bin/python scripts/tray_drop.py --obj cube_small.urdf --n 5 --no-pp
    .venv/bin/python scripts/tray_drop.py --n 3 --mesh-slots 4     # random_urdfs meshes: refused (docs/engines.md)
    .venv/bin/python scripts/tray_drop.py --obj sphere_small.urdf --builtin
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    import numpy as np
    import pybullet as p
    import pybullet_data

    from engines.base import PairSpec
    from engines.pybullet import PybulletAdapter
    from msf_contact import ContactPair, Curvature, make_law, preset

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--obj", default=None, help="a pybullet_data URDF for every object (default: random_urdfs meshes)")
    ap.add_argument("--n", type=int, default=3, help="how many objects")
    ap.add_argument("--steps", type=int, default=2000, help="steps of 1 ms")
    ap.add_argument("--no-pp", action="store_true", help="no MSF pairs between the objects")
    ap.add_argument("--mesh-slots", type=int, default=None, help="mesh_slots for every object")
    ap.add_argument("--builtin", action="store_true", help="pybullet's own contact instead of MSF")
    a = ap.parse_args(argv)
    if a.n < 1 or a.steps < 1:
        ap.error(f"--n = {a.n} and --steps = {a.steps} must be >= 1")

    c = p.connect(p.DIRECT)
    p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
    p.setGravity(0, 0, -9.81, physicsClientId=c)
    p.setTimeStep(1e-3, physicsClientId=c)
    tray = p.loadURDF("tray/traybox.urdf", [0, 0, 0], useFixedBase=True, physicsClientId=c)
    n_tray = len(p.getCollisionShapeData(tray, -1, physicsClientId=c))
    rng = np.random.default_rng(0)
    objs = []
    for k in range(a.n):
        i = int(rng.integers(0, 1000))
        objs.append(p.loadURDF(a.obj or f"random_urdfs/{i:03d}/{i:03d}.urdf",
                               [0.12 * (k % 3) - 0.12, 0.12 * (k // 3) - 0.06, 0.15 + 0.05 * k],
                               p.getQuaternionFromEuler(rng.uniform(-1, 1, 3)), physicsClientId=c))

    def radius(o):  # a sphere's own radius; else the law of a 20 mm sphere (a box's corners take their own)
        sd = p.getCollisionShapeData(o, -1, physicsClientId=c)[0]
        return sd[3][0] if sd[2] == p.GEOM_SPHERE else 0.02

    rubber, steel = preset("natural-rubber"), preset("steel")
    pairs = [PairSpec((o, -1), (tray, -1, k), make_law("msf", ContactPair(rubber, steel),
                                                       Curvature.sphere_on_plane(radius(o))))
             for o in objs for k in range(n_tray)]
    if not a.no_pp:
        pairs += [PairSpec((o1, -1), (o2, -1), make_law("msf", ContactPair(rubber, rubber),
                                                        Curvature.two_spheres(radius(o1), radius(o2))))
                  for i1, o1 in enumerate(objs) for o2 in objs[i1 + 1:]]

    def energy():
        e = 0.0
        for o in objs:
            m = p.getDynamicsInfo(o, -1, physicsClientId=c)[0]
            v = p.getBaseVelocity(o, physicsClientId=c)[0]
            e += 0.5 * m * float(np.dot(v, v)) + m * 9.81 * p.getBasePositionAndOrientation(o, physicsClientId=c)[0][2]
        return e

    kw = {"mesh_slots": {(o, -1): a.mesh_slots for o in objs}} if a.mesh_slots else {}
    try:
        adapter = None if a.builtin else PybulletAdapter(c, pairs, **kw)
    except ValueError as exc:
        print(f"refused: {exc}")
        return 1
    E = [energy()]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(a.steps):
            p.stepSimulation(physicsClientId=c) if adapter is None else adapter.step(1)
            E.append(energy())
    E = np.array(E)
    print(f"translational KE + PE [J]: start {E[0]:.4f}, largest {E.max():.4f}, end {E[-1]:.4f}; "
          f"largest rise in a step {np.diff(E).max():.3g}")
    print("heights at the end [m]:", [round(p.getBasePositionAndOrientation(o, physicsClientId=c)[0][2], 4)
                                      for o in objs])
    if adapter is not None:
        print(f"records {len(adapter.records)}, flagged {sum(1 for r in adapter.records if r.outside_validity)}")
    print(f"warnings {len(caught)}")
    for w in caught[:5]:
        print("  ", str(w.message)[:240])
    return 0


if __name__ == "__main__":
    sys.exit(main())
