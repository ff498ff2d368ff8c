"""The recycled pool of spheres (:class:`engines.pool.SpherePool`) in MuJoCo.

The scene: ``n`` free spheres (geoms ``"p0"``, ``"p1"``, ...) with the
spheres' masses and solid-sphere inertias, and the plate (geom ``"plate"``:
a plane, or a box whose top face is z = 0). MuJoCo's own contact is off for
the whole model (``<flag contact="disable"/>``, and the spheres carry
contype = conaffinity = 0), so every force between the bodies comes from
:class:`engines.mujoco.MujocoAdapter`: pair i is (sphere i, plate), and with
contacts between spheres the pool's ``pp_pairs`` follow. Spheres are moved
by writing their free joints' ``qpos``/``qvel`` between steps (through
(n, 7) and (n, 6) views of them).

MuJoCo refuses a moving body whose mass or any principal inertia is below
``mjMINVAL`` (1e-15 in SI units here): a solid glass sphere needs
R >= 0.19 mm. :meth:`MujocoSpherePool.check_spheres` refuses smaller
spheres with the bound before anything is built.

MuJoCo also treats any |qacc| above ``mjMAXVAL`` (1e10) as a divergence and
by default resets the whole simulation ("Nan, Inf or huge value in QACC").
For a 0.2 mm glass bead that is a real, not a diverging, value: the
step-averaged tangential force of an impact, ~0.02 N at a 0.1 ms step,
gives F R / J ~ 1e9-1e10 rad/s^2 (J ~ 1e-15 kg m^2). The pool's model
therefore sets ``<flag autoreset="disable"/>`` and checks instead, after
every step, that the state is finite (RuntimeError otherwise).
"""

from __future__ import annotations

import contextlib
import math

import mujoco
import numpy as np

from engines.pool import SphereScene, SpherePool

from .adapter import MujocoAdapter, installed

#: MuJoCo's smallest mass and inertia of a moving body (mjMINVAL in
#: mjmodel.h) [kg], [kg m^2]: the compiler refuses anything below.
MJ_MINVAL = 1e-15
INTEGRATORS = {"euler": "Euler", "rk4": "RK4", "implicitfast": "implicitfast"}


def _f(v: float) -> str:
    return repr(float(v))


def _vec(*v: float) -> str:
    return " ".join(_f(a) for a in v)


class MujocoSpherePool(SpherePool):
    """The pool in MuJoCo (see :class:`engines.pool.SpherePool`).
    ``integrator``: "euler" (default), "rk4" or "implicitfast"."""

    engine = "mujoco"

    @classmethod
    def check_spheres(cls, radii, masses, label: str = "radius") -> None:
        """Refuse spheres MuJoCo cannot hold: mass and inertia 2/5 m R^2 of
        each must exceed MJ_MINVAL (ValueError naming ``label[i]`` and the bound)."""
        for i, (R, m) in enumerate(zip(radii, masses)):
            J = 0.4 * m * R * R
            if m <= MJ_MINVAL or J <= MJ_MINVAL:
                rho = m / (4.0 / 3.0 * math.pi * R ** 3)
                R_min = (MJ_MINVAL / (0.4 * 4.0 / 3.0 * math.pi * rho)) ** 0.2
                raise ValueError(f"{label}[{i}] = {R:g} m: MuJoCo needs the inertia 2/5 m R^2 = {J:.3g} kg m^2 "
                                 f"above mjMINVAL = {MJ_MINVAL:g} (bound for density {rho:g} kg/m^3: "
                                 f"R > {R_min:.3g} m)")

    def __init__(self, scene: SphereScene, *, integrator: str = "euler"):
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator = {integrator!r} is not one of {', '.join(INTEGRATORS)}")
        self.check_spheres(scene.radius, scene.mass)
        self._integrator = INTEGRATORS[integrator]
        self._stack = contextlib.ExitStack()
        super().__init__(scene)

    def _body(self, i: int) -> str:
        return f"p{i}"

    def _build(self) -> None:
        sc = self.scene
        pl = sc.plate
        hx, hy = 0.5 * pl.size[0], 0.5 * pl.size[1]
        if pl.kind == "plane":
            plate = f'<geom name="plate" type="plane" size="{_vec(hx, hy, 0.01)}"/>'
        else:
            plate = (f'<geom name="plate" type="box" pos="0 0 {_f(-0.5 * pl.thickness)}" '
                     f'size="{_vec(hx, hy, 0.5 * pl.thickness)}"/>')
        bodies = []
        for i in range(self.n):
            m, R = float(self.mass[i]), float(self.radius[i])
            J = 0.4 * m * R * R
            bodies.append(f'<body name="p{i}" pos="{_vec(*self.park[i])}"><freejoint name="p{i}"/>'
                          f'<inertial pos="0 0 0" mass="{_f(m)}" diaginertia="{_vec(J, J, J)}"/>'
                          f'<geom name="p{i}" type="sphere" size="{_f(R)}" contype="0" conaffinity="0" mass="0"/>'
                          "</body>")
        xml = (f'<mujoco model="pool"><option timestep="{_f(sc.dt)}" integrator="{self._integrator}" '
               f'gravity="0 0 {_f(-sc.gravity)}"><flag contact="disable" autoreset="disable"/></option>'
               f"<worldbody>{plate}{''.join(bodies)}</worldbody></mujoco>")
        # compile before the passive hook is installed (engines.mujoco.adapter.installed)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        jid = np.array([self.model.joint(f"p{i}").id for i in range(self.n)])
        if not (np.array_equal(self.model.jnt_qposadr[jid], 7 * np.arange(self.n))
                and np.array_equal(self.model.jnt_dofadr[jid], 6 * np.arange(self.n))
                and self.model.nq == 7 * self.n and self.model.nv == 6 * self.n):
            raise RuntimeError("the pool's model does not hold sphere i's free joint at qpos[7i:7i+7], "
                               "qvel[6i:6i+6]")
        # views (n, 7) and (n, 6) of MuJoCo's own qpos and qvel: sphere i is row i
        self._qpos = self.data.qpos.reshape(self.n, 7)
        self._qvel = self.data.qvel.reshape(self.n, 6)
        self._qvel[:, :3] = self._v_park
        mujoco.mj_forward(self.model, self.data)
        self.adapter = MujocoAdapter(self.model, self.data, self.pairs_of("plate"))
        self._stack.enter_context(installed(self.adapter))

    def place(self, idx, pos, vel) -> None:
        self._qpos[idx, :3] = pos
        self._qpos[idx, 3:] = (1.0, 0.0, 0.0, 0.0)
        self._qvel[idx, :3] = vel
        self._qvel[idx, 3:] = 0.0

    def centres(self, idx) -> np.ndarray:
        return self._qpos[idx, :3]

    def step(self) -> None:
        self.adapter.step(1)
        # one sum each is finite when every entry is (the full check only when a sum is not)
        d = self.data
        if not math.isfinite(float(d.qvel.sum()) + float(d.qpos.sum())):
            if not (np.all(np.isfinite(d.qvel)) and np.all(np.isfinite(d.qpos))):
                raise RuntimeError(f"MuJoCo's state is not finite at t = {d.time:.6g} s")

    @property
    def time(self) -> float:
        return float(self.data.time)

    def close(self) -> None:
        self._stack.close()
