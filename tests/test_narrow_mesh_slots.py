"""The default number of contact slots of a mesh (issue 13;
engines._narrow.default_mesh_slots): a mesh whose convex hull has a flat
face it can rest on (pybullet_data's duck_vhacd.obj) is carried by
COARSE_MESH_SLOTS slots, as a box by its corners; a smooth mesh (an
icosphere) by one. Before (main 7ce0dab) every mesh had one slot by default:
the duck rocking on its flat face had that slot's point jump between the
face's vertices, 30-40 mm apart, during a contact, and its records were
flagged "energy gained in a contact" (COR 1.4-2.1)."""

import math
import warnings

import numpy as np
import pytest
import trimesh

from msf_contact import ContactPair, Curvature, make_law, preset

from engines._narrow import COARSE_MESH_SLOTS, default_mesh_slots, flat_face
from engines.base import PairSpec


def test_a_hull_with_a_flat_face_takes_several_slots_a_smooth_mesh_one():
    """An icosphere of 162 or 642 vertices (hull triangles at most 0.33 and
    0.17 of its radius) one slot; a box mesh (its faces 4 coplanar vertices,
    as wide as 1.4 its half-diagonal) and a 32-sided prism (its caps)
    COARSE_MESH_SLOTS; the flat face found is the box's widest, its
    diagonal. A lone hull triangle wider than FLAT_FACE_SHARE of the radius
    counts as a face (pybullet_data's teddy2_VHACD_CHs.obj: triangles of
    0.72 m on 0.85 m, no 4 coplanar): the icosahedron and the 42-vertex
    icosphere (edges 1.05 and 0.62 r) take COARSE_MESH_SLOTS."""
    for sub in (2, 3):
        assert default_mesh_slots(trimesh.creation.icosphere(subdivisions=sub, radius=0.02).vertices) == 1
    for sub in (0, 1):
        V = trimesh.creation.icosphere(subdivisions=sub, radius=0.02).vertices
        assert flat_face(V)[0] == 0.0 and default_mesh_slots(V) == COARSE_MESH_SLOTS
    box = trimesh.creation.box([0.02, 0.03, 0.04])
    width, normal = flat_face(box.vertices)
    assert width == pytest.approx(math.hypot(0.03, 0.04)) and abs(abs(normal[0]) - 1.0) < 1e-9
    assert default_mesh_slots(box.vertices) == COARSE_MESH_SLOTS
    assert default_mesh_slots(trimesh.creation.cylinder(0.05, 0.045, sections=32).vertices) == COARSE_MESH_SLOTS


@pytest.mark.pybullet
def test_the_duck_rocking_on_its_flat_face_gains_no_energy_by_default():
    """pybullet_data's duck_vhacd.urdf (a 208-vertex hull, its flat face
    41.5 mm wide) set 0.2 mm above plane.urdf on that face, turning at
    (3, 0.9, 0) rad/s, rubber on steel with a plain PairSpec (no mesh_slots),
    250 steps of 1 ms: no record flagged, no warning, and the energy account
    (kinetic + potential + stored) never rises. Main's one slot: one record
    flagged (COR 2.1) by step 250."""
    pb = pytest.importorskip("pybullet")
    import pybullet_data

    from engines.pybullet import PybulletAdapter

    c = pb.connect(pb.DIRECT)
    try:
        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
        pb.setGravity(0, 0, -9.81, physicsClientId=c)
        pb.setTimeStep(1e-3, physicsClientId=c)
        plane = pb.loadURDF("plane.urdf", physicsClientId=c)
        u = pb.loadURDF("duck_vhacd.urdf", [0, 0, 0.5], physicsClientId=c)
        V = np.array(pb.getMeshData(u, -1, physicsClientId=c)[1])
        _, n = flat_face(V)
        sd = pb.getCollisionShapeData(u, -1, physicsClientId=c)[0]
        Rs = np.array(pb.getMatrixFromQuaternion(sd[6])).reshape(3, 3)
        nb = Rs @ n  # the face's outward normal in the base frame: turned to -z
        axis = np.cross(nb, [0.0, 0.0, -1.0])
        ang = math.atan2(float(np.linalg.norm(axis)), -float(nb[2]))
        axis /= np.linalg.norm(axis)
        q = [*(math.sin(ang / 2) * axis), math.cos(ang / 2)]
        R = np.array(pb.getMatrixFromQuaternion(q)).reshape(3, 3)
        low = float(np.min((R @ (Rs @ V.T + np.asarray(sd[5])[:, None]))[2]))
        pb.resetBasePositionAndOrientation(u, [0, 0, -low + 2e-4], q, physicsClientId=c)
        pb.resetBaseVelocity(u, [0, 0, 0], [3.0, 0.9, 0.0], physicsClientId=c)
        law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
        ad = PybulletAdapter(c, [PairSpec((u, -1), (plane, -1), law)])
        assert ad.manager.x.size == COARSE_MESH_SLOTS
        m, I = pb.getDynamicsInfo(u, -1, physicsClientId=c)[0], np.array(pb.getDynamicsInfo(u, -1, physicsClientId=c)[2])

        def energy():
            (pos, orn), (v, w) = (pb.getBasePositionAndOrientation(u, physicsClientId=c),
                                  pb.getBaseVelocity(u, physicsClientId=c))
            wl = np.array(pb.getMatrixFromQuaternion(orn)).reshape(3, 3).T @ np.array(w)
            return 0.5 * m * float(np.dot(v, v)) + 0.5 * float(wl @ (I * wl)) + m * 9.81 * pos[2]

        E = []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(250):
                ad.step()
                if not np.any(ad.manager.J != 0.0):
                    E.append(energy() + ad.manager.stored_energy())
    finally:
        pb.disconnect(c)
    E = np.array(E)
    assert len(ad.records) > 5 and not any(r.outside_validity for r in ad.records) and not caught
    assert max(float(np.max(E[j:] - E[j])) for j in range(E.size)) <= 1e-12
