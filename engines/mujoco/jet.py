"""Abrasive jet in MuJoCo: the pool driver of
:class:`experiments.scenarios.jet.JetPool` (same API as
:mod:`engines.pybullet.jet`).

The scene: ``n`` free spheres (geoms ``"p0"``, ``"p1"``, ...) with the
particles' masses and solid-sphere inertias, and the plate (geom
``"plate"``: a plane, or a box whose top face is z = 0). MuJoCo's own
contact is off for the whole model (``<flag contact="disable"/>``, and the
particles carry contype = conaffinity = 0), so every force between the
bodies comes from :class:`engines.mujoco.MujocoAdapter`: pair i is
(particle i, plate), and with particle-particle contacts the pool's
``pp_pairs`` follow. Particles are moved by writing their free joints'
``qpos``/``qvel`` between steps (through (n, 7) and (n, 6) views of them).

MuJoCo refuses a moving body whose mass or any principal inertia is below
``mjMINVAL`` (1e-15 in SI units here): a solid glass sphere needs
R >= 0.19 mm. :func:`check_spec` refuses smaller particles with the bound
before anything is built.

MuJoCo also treats any |qacc| above ``mjMAXVAL`` (1e10) as a divergence and
by default resets the whole simulation ("Nan, Inf or huge value in QACC").
For a 0.2 mm glass bead that is a real, not a diverging, value: the
step-averaged tangential force of an impact, ~0.02 N at a 0.1 ms step,
gives F R / J ~ 1e9-1e10 rad/s^2 (J ~ 1e-15 kg m^2). The jet's model
therefore sets ``<flag autoreset="disable"/>`` and checks instead, after
every step, that the state is finite (RuntimeError otherwise).
"""

from __future__ import annotations

import contextlib
import math

import mujoco
import numpy as np

from engines.base import PairSpec
from experiments.scenarios.jet import JetPool, JetSpec

from .adapter import MujocoAdapter, installed

#: MuJoCo's smallest mass and inertia of a moving body (mjMINVAL in
#: mjmodel.h) [kg], [kg m^2]: the compiler refuses anything below.
MJ_MINVAL = 1e-15


def _f(v: float) -> str:
    return repr(float(v))


def _vec(*v: float) -> str:
    return " ".join(_f(a) for a in v)


def check_spec(spec: JetSpec) -> None:
    """Refuse particles MuJoCo cannot hold: mass and inertia 2/5 m R^2 of each
    size class must exceed MJ_MINVAL (ValueError naming the class and bound)."""
    for i, R in enumerate(spec.particles.radii):
        m = spec.particles.mass(i)
        J = 0.4 * m * R * R
        if m <= MJ_MINVAL or J <= MJ_MINVAL:
            rho = spec.particles.material.density
            R_min = (MJ_MINVAL / (0.4 * 4.0 / 3.0 * math.pi * rho)) ** 0.2
            raise ValueError(f"particles.radius[{i}] = {R:g} m: MuJoCo needs the inertia 2/5 m R^2 = {J:.3g} kg m^2 "
                             f"above mjMINVAL = {MJ_MINVAL:g} (bound for density {rho:g} kg/m^3: R > {R_min:.3g} m)")


class MujocoJet(JetPool):
    """The jet in MuJoCo (see :class:`experiments.scenarios.jet.JetPool`).
    ``integrator``: "euler" (default), "rk4" or "implicitfast"."""

    engine = "mujoco"

    def __init__(self, spec: JetSpec, seed=0, *, validate: bool = True, integrator: str = "euler"):
        check_spec(spec)
        names = {"euler": "Euler", "rk4": "RK4", "implicitfast": "implicitfast"}
        if integrator not in names:
            raise ValueError(f"integrator = {integrator!r} is not one of {', '.join(names)}")
        self._integrator = names[integrator]
        self._stack = contextlib.ExitStack()
        super().__init__(spec, seed, validate=validate)

    def _build(self) -> None:
        spec = self.spec
        pl = spec.plate
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
        xml = (f'<mujoco model="jet"><option timestep="{_f(spec.dt)}" integrator="{self._integrator}" '
               f'gravity="0 0 {_f(-spec.gravity)}"><flag contact="disable" autoreset="disable"/></option>'
               f"<worldbody>{plate}{''.join(bodies)}</worldbody></mujoco>")
        # compile before the passive hook is installed (engines.mujoco.adapter.installed)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        jid = np.array([self.model.joint(f"p{i}").id for i in range(self.n)])
        if not (np.array_equal(self.model.jnt_qposadr[jid], 7 * np.arange(self.n))
                and np.array_equal(self.model.jnt_dofadr[jid], 6 * np.arange(self.n))
                and self.model.nq == 7 * self.n and self.model.nv == 6 * self.n):
            raise RuntimeError("the jet's model does not hold particle i's free joint at qpos[7i:7i+7], "
                               "qvel[6i:6i+6]")
        # views (n, 7) and (n, 6) of MuJoCo's own qpos and qvel: particle i is row i
        self._qpos = self.data.qpos.reshape(self.n, 7)
        self._qvel = self.data.qvel.reshape(self.n, 6)
        self._qvel[:, :3] = self.spec.park_velocity()
        mujoco.mj_forward(self.model, self.data)
        pairs = [PairSpec(f"p{i}", "plate", self.laws[int(self.cls[i])], spec.tangential) for i in range(self.n)]
        if self.pp_pairs:
            pp = spec.pp_laws()
            pairs += [PairSpec(f"p{i}", f"p{j}", pp[(int(self.cls[i]), int(self.cls[j]))], spec.tangential)
                      for i, j in self.pp_pairs]
        self.adapter = MujocoAdapter(self.model, self.data, pairs)
        self._stack.enter_context(installed(self.adapter))

    def _place(self, idx, pos, vel) -> None:
        self._qpos[idx, :3] = pos
        self._qpos[idx, 3:] = (1.0, 0.0, 0.0, 0.0)
        self._qvel[idx, :3] = vel
        self._qvel[idx, 3:] = 0.0

    def _centres(self, idx) -> np.ndarray:
        return self._qpos[idx, :3]

    def _step(self) -> None:
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
