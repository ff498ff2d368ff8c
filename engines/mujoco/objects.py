"""Objects from ``pybullet_data`` dropped on a plane in MuJoCo (issue 13):
a cube (``cube_small.urdf``), a mesh (``duck_vhacd.urdf``: MuJoCo loads the
OBJ and collides its convex hull) or any single-link URDF with a box,
cylinder, sphere or mesh collision shape, and primitive shapes given
directly (a cylinder: ``pybullet_data`` has no cylinder object).

The URDF gives the collision geometry and the mass. Its inertia is not used:
the objects in ``pybullet_data`` carry a placeholder (1 kg m^2 for a 0.1 kg,
5 cm cube or duck, 10^4 times the solid's), so the inertia is the solid's of
uniform density (MuJoCo's ``inertiafromgeom``, what pybullet's ``loadURDF``
also does unless told to read the file's).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

FLOOR = "floor"
OBJECT = "object"

#: Collision shapes a description may have (MuJoCo's geom types).
KINDS = ("box", "cylinder", "sphere", "mesh")


def urdf_object(path: str) -> dict:
    """The description of the single-link URDF at ``path`` for
    :func:`object_on_plane`: kind, size (MuJoCo's: box half-extents; cylinder
    radius and half-length; sphere radius), mesh file and scale, mass [kg].
    ValueError for several links, several collision shapes, an offset
    collision origin or a shape other than box, cylinder, sphere, mesh."""
    root = ET.parse(path).getroot()
    links = root.findall("link")
    if len(links) != 1:
        raise ValueError(f"{path}: {len(links)} links; an object here is one rigid link")
    link = links[0]
    mass_el = link.find("inertial/mass")
    if mass_el is None:
        raise ValueError(f"{path}: no <inertial><mass>: the object's mass is needed")
    cols = link.findall("collision")
    if len(cols) != 1:
        raise ValueError(f"{path}: {len(cols)} <collision> elements; one shape is supported")
    origin = cols[0].find("origin")
    if origin is not None and (np.any(np.array(origin.get("xyz", "0 0 0").split(), float) != 0)
                               or np.any(np.array(origin.get("rpy", "0 0 0").split(), float) != 0)):
        raise ValueError(f"{path}: the collision origin is offset; only a shape at the link's frame is supported")
    geo = cols[0].find("geometry")
    out = {"mass": float(mass_el.get("value")), "source": os.path.basename(path)}
    if geo.find("box") is not None:
        out.update(kind="box", size=[0.5 * float(s) for s in geo.find("box").get("size").split()])
    elif geo.find("cylinder") is not None:
        c = geo.find("cylinder")
        out.update(kind="cylinder", size=[float(c.get("radius")), 0.5 * float(c.get("length"))])
    elif geo.find("sphere") is not None:
        out.update(kind="sphere", size=[float(geo.find("sphere").get("radius"))])
    elif geo.find("mesh") is not None:
        mesh = geo.find("mesh")
        scale = [float(s) for s in mesh.get("scale", "1 1 1").split()]
        out.update(kind="mesh", file=os.path.join(os.path.dirname(os.path.abspath(path)), mesh.get("filename")),
                   scale=scale)
    else:
        raise ValueError(f"{path}: collision geometry {[c.tag for c in geo]} is not a box, cylinder, sphere or mesh")
    if not out["mass"] > 0:
        raise ValueError(f"{path}: mass = {out['mass']!r} kg must be > 0")
    return out


def object_on_plane(obj: dict, *, dt: float, height: float, quat=(1.0, 0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0),
                    omega=(0.0, 0.0, 0.0), msf: bool = True, friction: float = 1.0,
                    integrator: str = "implicitfast"):
    """(model, data): the object ``obj`` (:func:`urdf_object` or a dict with
    kind, size, mass) as a free body named and with a geom named ``"object"``,
    its lowest point ``height`` [m] above a floor plane ``"floor"`` at z = 0,
    turned by ``quat`` (w, x, y, z), moving at ``velocity`` [m/s] (3,) and
    turning at ``omega`` [rad/s] (3,, world axes). msf: MuJoCo's own contact
    between the object and the floor excluded (for an MSF pair (object,
    floor)); otherwise MuJoCo's contact with its default solref/solimp and
    ``friction``. ``mj_forward`` has been called."""
    if obj.get("kind") not in KINDS:
        raise ValueError(f"object kind = {obj.get('kind')!r} must be one of {KINDS}")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt = {dt!r} s must be finite and > 0")
    if not height >= 0:
        raise ValueError(f"height = {height!r} m must be >= 0 (the lowest point above the floor)")
    spec = mujoco.MjSpec()
    spec.option.timestep = float(dt)
    spec.option.integrator = {"euler": mujoco.mjtIntegrator.mjINT_EULER, "rk4": mujoco.mjtIntegrator.mjINT_RK4,
                              "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST}[integrator]
    spec.worldbody.add_geom(name=FLOOR, type=mujoco.mjtGeom.mjGEOM_PLANE, size=[5.0, 5.0, 0.1],
                            friction=[friction, 0.005, 0.0001])
    body = spec.worldbody.add_body(name=OBJECT, pos=[0.0, 0.0, 1.0], quat=list(quat))
    body.add_freejoint()
    kind = obj["kind"]
    geom = dict(name=OBJECT, mass=float(obj["mass"]), friction=[friction, 0.005, 0.0001])
    if kind == "mesh":
        spec.add_mesh(name="object_mesh", file=obj["file"], scale=list(obj.get("scale", [1.0, 1.0, 1.0])))
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname="object_mesh", **geom)
    else:
        size = list(obj["size"]) + [0.0] * (3 - len(obj["size"]))
        body.add_geom(type=getattr(mujoco.mjtGeom, f"mjGEOM_{kind.upper()}"), size=size, **geom)
    if msf:
        spec.add_exclude(bodyname1="world", bodyname2=OBJECT)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # put the lowest point at the height: the geom's support along -z
    data.qpos[2] += float(height) - lowest_point(model, data)
    data.qvel[:3] = velocity
    rot = data.xmat[model.body(OBJECT).id].reshape(3, 3)
    data.qvel[3:6] = rot.T @ np.asarray(omega, dtype=float)  # a free joint's angular velocity is in body axes
    mujoco.mj_forward(model, data)
    return model, data


def lowest_point(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The lowest z [m] of the object's geom at the current pose: its
    vertices (mesh), corners (box), rim (cylinder) or sphere."""
    g = model.geom(OBJECT).id
    pos, rot = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3)
    t = int(model.geom_type[g])
    size = model.geom_size[g]
    if t == mujoco.mjtGeom.mjGEOM_MESH:
        k = int(model.geom_dataid[g])
        v = model.mesh_vert[int(model.mesh_vertadr[k]):int(model.mesh_vertadr[k]) + int(model.mesh_vertnum[k])]
        return float(np.min(pos[2] + v @ rot[2]))
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        return float(pos[2] - np.abs(rot[2]) @ size)
    if t == mujoco.mjtGeom.mjGEOM_CYLINDER:
        a = rot[2, 2]  # the axis's z component
        return float(pos[2] - size[0] * math.sqrt(max(1.0 - a * a, 0.0)) - size[1] * abs(a))
    return float(pos[2] - size[0])


def com_height(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Height of the object's centre of mass [m] at the current qpos."""
    b = model.body(OBJECT).id
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, data.qpos[3:7])
    return float(data.qpos[2] + (R.reshape(3, 3) @ model.body_ipos[b])[2])


__all__ = ["FLOOR", "KINDS", "OBJECT", "com_height", "lowest_point", "object_on_plane", "urdf_object"]
