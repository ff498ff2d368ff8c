"""The pybullet shapes' acceptance numbers docs/engines.md quotes (issue 13):
the cases of tests/test_narrow_pybullet.py, measured and printed.

    .venv/bin/python scripts/pybullet_shapes.py

Prints, each against its reference: the ellipsoid (30, 20, 20) mm on each
principal axis against the reference solver (COR, tau); the capsule end-on
against the sphere of its radius; the capsule flat and tilted (peak force,
E_out/E_in); the box on a corner (against the edge-radius sphere and the
reference), a face and an edge (E_out/E_in, COR against the reference with
m/4, m/2); the icosphere against the analytic sphere in three orientations;
a sphere on a cylinder's side against the reference.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import pybullet as pb  # noqa: E402
import trimesh  # noqa: E402
import test_narrow_pybullet as T  # noqa: E402

from engines.base import PairSpec  # noqa: E402
from engines.pybullet.adapter import PybulletAdapter  # noqa: E402
from engines.pybullet.narrow import ellipsoid_vertices  # noqa: E402
from msf_contact import Body, ContactPair, Curvature, make_law, simulate_impact  # noqa: E402
from msf_contact.shapes import Ellipsoid  # noqa: E402


def rel(a, b):
    return a / b - 1.0


def ellipsoids():
    for axes in [(0.02, 0.02, 0.03), (0.03, 0.02, 0.02), (0.02, 0.03, 0.02)]:
        m, inertia, law = T.ellipsoid_case(axes)
        ref = simulate_impact(law, Body(T.RUBBER, min(axes), m, inertia[0]), Body.half_space(T.STEEL), 1.0)
        for label, curv in (("analytic curvature", Ellipsoid(axes)), ("mesh local fit", None)):
            rec, _ = T.drop(law, dict(kind=pb.GEOM_MESH, vertices=ellipsoid_vertices(axes).tolist()), m, inertia,
                            axes[2] + 1e-4, curvature=curv)
            print(f"ellipsoid {axes} ({label}): COR {rel(rec.cor_n, ref.cor_n):+.2e}, tau {rel(rec.tau, ref.tau):+.2e}")


def capsules():
    r, h, m = 0.01, 0.05, 0.05
    law = make_law("msf", ContactPair(T.RUBBER, T.STEEL), Curvature.sphere_on_plane(r))
    cap, _ = T.drop(law, dict(kind=pb.GEOM_CAPSULE, radius=r, height=2 * h), m, 0.4 * m * r * r, h + r + 1e-4)
    sph, _ = T.drop(law, dict(kind=pb.GEOM_SPHERE, radius=r), m, 0.4 * m * r * r, h + r + 1e-4, shape_pos=(0, 0, -h))
    print("capsule end-on vs sphere: " + ", ".join(f"{k} {rel(getattr(cap, k), getattr(sph, k)):+.1e}"
                                                   for k in ("cor_n", "tau", "x_max", "F_max")))
    m = T.RUBBER.density * (math.pi * r * r * 2 * h + 4 / 3 * math.pi * r**3)
    inertia = (m * (3 * r * r + 4 * h * h) / 12, m * (3 * r * r + 4 * h * h) / 12, m * r * r / 2)
    for tilt in (0.0, 0.01, 0.2, 1.0, 5.0):
        orn = pb.getQuaternionFromEuler([0, math.radians(90 - tilt), 0])
        c, u, plane = T.scene(dict(kind=pb.GEOM_CAPSULE, radius=r, height=2 * h), m, inertia,
                              r + h * math.sin(math.radians(tilt)) + 1e-4, orn=orn)
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law)])
        E0 = T._free_energy(c, u, m, inertia)
        ad.step(150)
        print(f"capsule tilted {tilt} deg: peak force {max(x.F_max for x in ad.records):.2f} N, "
              f"E_out/E_in {T._free_energy(c, u, m, inertia) / E0:.4f}, contacts {len(ad.records)}")
        pb.disconnect(c)


def boxes():
    h, rho, v = 0.01, 1e-3, 0.2
    law = make_law("msf", ContactPair(T.STEEL, T.STEEL), Curvature.sphere_on_plane(rho))
    axis = np.array([1.0, 1.0, 1.0]) / math.sqrt(3) - np.array([0, 0, 1.0])
    axis /= np.linalg.norm(axis)
    m, inertia, orn = T._box(h, rho, v, quat=[axis[0], axis[1], axis[2], 0.0])
    z = h * math.sqrt(3) + 1e-6
    box, _ = T.drop(law, dict(kind=pb.GEOM_BOX, halfExtents=[h] * 3), m, inertia, z, orn=orn, v=v, dt=1e-4,
                    edge_radius=rho)
    centre = (h * math.sqrt(3) - rho) / math.sqrt(3)
    sph, _ = T.drop(law, dict(kind=pb.GEOM_SPHERE, radius=rho), m, inertia, z, orn=orn, v=v, dt=1e-4,
                    shape_pos=(centre, centre, centre))
    ref = simulate_impact(law, Body(T.STEEL, rho, m, 0.4 * m * rho * rho), Body.half_space(T.STEEL), v)
    print("box corner vs edge-radius sphere: " + ", ".join(f"{k} {rel(getattr(box, k), getattr(sph, k)):+.1e}"
                                                           for k in ("cor_n", "tau", "x_max", "F_max"))
          + f"; vs reference COR {rel(box.cor_n, ref.cor_n):+.2e}, tau {rel(box.tau, ref.tau):+.2e}")
    for euler, corners in (((0, 0, 0), 4), ((math.pi / 4, 0, 0), 2)):
        m, inertia, orn = T._box(h, rho, v, euler=euler)
        zz = h * (math.sqrt(2) if corners == 2 else 1.0) + 1e-6
        c, u, plane = T.scene(dict(kind=pb.GEOM_BOX, halfExtents=[h] * 3), m, inertia, zz, orn=orn, v=v, dt=1e-4)
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law)], edge_radii={(u, -1): rho})
        E0 = T._free_energy(c, u, m, [inertia] * 3)
        ad.step(300)
        share = Body(T.STEEL, rho, m / corners, 0.4 * m / corners * rho * rho)
        ref = simulate_impact(law, share, Body.half_space(T.STEEL), v)
        vz = pb.getBaseVelocity(u, physicsClientId=c)[0][2]
        print(f"box on {'a face' if corners == 4 else 'an edge'}: {len(ad.records)} corners, "
              f"E_out/E_in {T._free_energy(c, u, m, [inertia] * 3) / E0:.4f}, COR vs reference (m/{corners}) "
              f"{rel(vz / v, ref.cor_n):+.2e}")
        pb.disconnect(c)


def icosphere():
    R = 0.02
    m = T.RUBBER.density * 4 / 3 * math.pi * R**3
    ico = trimesh.creation.icosphere(subdivisions=3, radius=R)
    law = make_law("msf", ContactPair(T.RUBBER, T.STEEL), Curvature.sphere_on_plane(R))
    sph, _ = T.drop(law, dict(kind=pb.GEOM_SPHERE, radius=R), m, 0.4 * m * R * R, R + 1e-4)
    for euler in ((0, 0, 0), (10, 20, 30), (33, 7, 51)):
        orn = pb.getQuaternionFromEuler([math.radians(a) for a in euler])
        mesh, _ = T.drop(law, dict(kind=pb.GEOM_MESH, vertices=ico.vertices.tolist()), m, 0.4 * m * R * R, R + 1e-4,
                         orn=orn)
        print(f"icosphere {len(ico.faces)} faces, euler {euler}: COR {rel(mesh.cor_n, sph.cor_n):+.2e}, "
              f"tau {rel(mesh.tau, sph.tau):+.2e}")


def cylinder():
    R, r = 0.01, 0.02
    m = T.RUBBER.density * 4 / 3 * math.pi * R**3

    def cyl(c):
        sh = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=r, height=0.2, physicsClientId=c)
        return pb.createMultiBody(0.0, sh, baseOrientation=pb.getQuaternionFromEuler([0, math.pi / 2, 0]),
                                  physicsClientId=c)

    law = make_law("msf", ContactPair(T.RUBBER, T.STEEL), Curvature(R, R, r, math.inf))
    rec, _ = T.drop(law, dict(kind=pb.GEOM_SPHERE, radius=R), m, 0.4 * m * R * R, r + R + 1e-4, fixed=cyl)
    ref = simulate_impact(law, Body.sphere(T.RUBBER, R, m), Body.half_space(T.STEEL), 1.0)
    print(f"sphere on a cylinder's side: COR {rel(rec.cor_n, ref.cor_n):+.2e}, tau {rel(rec.tau, ref.tau):+.2e}")


if __name__ == "__main__":
    for case in (ellipsoids, capsules, boxes, icosphere, cylinder):
        case()
