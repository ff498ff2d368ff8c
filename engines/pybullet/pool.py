"""The recycled pool of spheres (:class:`engines.pool.SpherePool`) in pybullet.

The scene, in its own DIRECT client: ``n`` free spheres with the spheres'
masses and solid-sphere inertias (no damping, no sleeping, the velocity
clamp lifted, as in :mod:`engines.pybullet.scenes`) and the fixed plate (a
plane, or a box whose top face is z = 0). pybullet's own collisions are off
for every sphere (collision filter group and mask 0), so every force
between the bodies comes from :class:`engines.pybullet.PybulletAdapter`:
pair i is (sphere i, plate), and with contacts between spheres the pool's
``pp_pairs`` follow. Spheres are moved with
``resetBasePositionAndOrientation``/``resetBaseVelocity`` between steps.
pybullet computes in double precision and takes small inertias as given:
nothing pybullet-specific to refuse (:meth:`SpherePool.check_spheres`).
"""

from __future__ import annotations

import numpy as np

from engines.pool import SphereScene, SpherePool

from . import scenes
from .adapter import PybulletAdapter

import pybullet as pb  # noqa: E402  (after the package, which imports it quietly)

_IDENTITY = (0.0, 0.0, 0.0, 1.0)
_ZERO3 = (0.0, 0.0, 0.0)


class PybulletSpherePool(SpherePool):
    """The pool in pybullet (see :class:`engines.pool.SpherePool`)."""

    engine = "pybullet"

    def __init__(self, scene: SphereScene):
        self.client = None
        super().__init__(scene)

    def _body(self, i: int):
        return (int(self.uid[i]), -1)

    def _build(self) -> None:
        sc = self.scene
        c = scenes.new_client(sc.dt, sc.gravity if sc.gravity > 0 else None)
        self.client = c
        pl = sc.plate
        if pl.kind == "plane":
            shape = pb.createCollisionShape(pb.GEOM_PLANE, planeNormal=[0, 0, 1], physicsClientId=c)
            plate = pb.createMultiBody(0.0, shape, basePosition=[0, 0, 0], physicsClientId=c)
        else:
            h = [0.5 * pl.size[0], 0.5 * pl.size[1], 0.5 * pl.thickness]
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=h, physicsClientId=c)
            plate = pb.createMultiBody(0.0, shape, basePosition=[0, 0, -0.5 * pl.thickness], physicsClientId=c)
        v = self._v_park.tolist()
        shapes = {}
        self.uid = np.zeros(self.n, int)
        for i in range(self.n):
            R, m = float(self.radius[i]), float(self.mass[i])
            if R not in shapes:
                shapes[R] = pb.createCollisionShape(pb.GEOM_SPHERE, radius=R, physicsClientId=c)
            u = pb.createMultiBody(m, shapes[R], basePosition=self.park[i].tolist(), physicsClientId=c)
            J = 0.4 * m * R * R
            pb.changeDynamics(u, -1, mass=m, localInertiaDiagonal=[J, J, J], physicsClientId=c)
            scenes._free_dynamics(c, u)  # noqa: SLF001 - the scenes' own settings for a free body
            pb.setCollisionFilterGroupMask(u, -1, 0, 0, physicsClientId=c)
            pb.resetBaseVelocity(u, v, [0.0, 0.0, 0.0], physicsClientId=c)
            self.uid[i] = u
        self.adapter = PybulletAdapter(c, self.pairs_of((plate, -1)))

    def place(self, idx, pos, vel) -> None:
        c = self.client
        for u, p, v in zip(self.uid[np.asarray(idx, int)].tolist(), np.asarray(pos, float).tolist(),
                           np.asarray(vel, float).tolist()):
            pb.resetBasePositionAndOrientation(u, p, _IDENTITY, physicsClientId=c)
            pb.resetBaseVelocity(u, v, _ZERO3, physicsClientId=c)
        if getattr(self, "adapter", None) is not None:
            self.adapter.placed(self.uid[np.asarray(idx, int)].tolist())

    def centres(self, idx) -> np.ndarray:
        c = self.client
        return np.array([pb.getBasePositionAndOrientation(u, physicsClientId=c)[0]
                         for u in self.uid[np.asarray(idx, int)].tolist()], float).reshape(-1, 3)

    def step(self) -> None:
        self.adapter.step(1)

    @property
    def time(self) -> float:
        return self.adapter.time

    def close(self) -> None:
        if getattr(self, "adapter", None) is not None:
            self.adapter.close()  # gives the pairs back; the client is ours to disconnect
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
