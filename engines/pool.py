"""A recycled pool of free spheres over a fixed plate, in one engine.

A stream of particles (thousands to millions of impacts) must not build a
body per particle, or memory grows with the number of impacts. A
:class:`SpherePool` builds ``n`` free spheres once, the fixed plate (a
plane, or a box whose top face is z = 0, normal +z) and an adapter
(:class:`engines.base.EngineAdapter`) whose pair i is (sphere i, plate) for
i < n and, with ``pp_laws``, the pairs between spheres (``pp_pairs``, i < j)
after them; the engine's own contact is off for all bodies, so every force
between them comes from the pairs' laws.

A sphere's life: *parked* (on its own slot far from everything, in the
free list of its size class), *launched* (:meth:`SpherePool.launch`: placed
at a position with a velocity, state FLIGHT), marked DONE by the user once
its contact is over, and parked again (:meth:`SpherePool.park_done`) once
the contact manager no longer needs it (no contact, no timing correction
left: ``manager.required_pairs``).

Why the park moves. The adapters estimate the external acceleration of a
contact from the change of the relative velocity over the last step, so
moving a sphere to a new velocity looks, for one step, like an acceleration
(v_new - v_old)/dt. Parked spheres therefore move with a common park
velocity (the user chooses it close to the launch velocities) and are put
back on their slot, velocity kept, once ``repin_after`` [s] has passed
(:meth:`SpherePool.repin`); the jump at launch is then small, and the user
keeps the first step after a launch in free flight.

This module knows nothing of where the spheres come from or go (the
abrasive jet of :mod:`experiments.scenarios.jet` is one user). The engine
back ends implement :meth:`SpherePool._build`, :meth:`SpherePool.place`,
:meth:`SpherePool.centres`, :meth:`SpherePool.step`, ``time`` and
``close``: :class:`engines.mujoco.pool.MujocoSpherePool` and
:class:`engines.pybullet.pool.PybulletSpherePool`, found by engine name in
:data:`SPHERE_POOLS` (:func:`sphere_pool_class`, :func:`make_sphere_pool`;
imported on first use).
"""

from __future__ import annotations

import abc
import math
from collections import deque
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np

from .contract import PairSpec
from .registry import resolve

#: States of a sphere: parked (free), out of the park, its contact done
#: (waiting until the manager no longer needs it).
PARKED, FLIGHT, DONE = 0, 1, 2
PLATE_KINDS = ("plane", "box")

#: Back ends by engine name: "module:class", imported on first use.
SPHERE_POOLS: dict[str, str] = {
    "mujoco": "engines.mujoco.pool:MujocoSpherePool",
    "pybullet": "engines.pybullet.pool:PybulletSpherePool",
}


@dataclass(frozen=True)
class PlateShape:
    """The fixed plate: ``kind`` "plane" or "box" (top face z = 0),
    ``size`` its (x, y) extent [m], ``thickness`` of a box [m]."""

    kind: str = "plane"
    size: tuple[float, float] = (0.04, 0.04)
    thickness: float = 0.005

    def __post_init__(self):
        if self.kind not in PLATE_KINDS:
            raise ValueError(f"plate kind = {self.kind!r} is not one of {', '.join(PLATE_KINDS)}")


@dataclass(eq=False)
class SphereScene:
    """What a pool builds (arrays are not copied).

    cls: size class of each sphere (n,) int in [0, len(laws)).
    radius [m] (n,), mass [kg] (n,): solid spheres (inertia 2/5 m R^2).
    laws: one :class:`msf_contact.laws.ForceLaw` per class, the sphere
        (body 1) on the plate (body 2).
    park: the spheres' slots [m] (n, 3); park_velocity [m/s] (3,) of parked spheres.
    repin_after: a parked sphere is put back on its slot after this long [s].
    plate: :class:`PlateShape`. dt: engine step [s]. gravity [m/s^2] along -z (0: off).
    tangential: the pairs' tangential mode ("contact-point" or "paper").
    pp_laws: None (no contacts between spheres) or the law of every pair of
        classes, ``pp_laws[(ci, cj)]`` with body 1 of class ci.
    """

    cls: np.ndarray
    radius: np.ndarray
    mass: np.ndarray
    laws: Sequence[Any]
    park: np.ndarray
    park_velocity: np.ndarray
    repin_after: float
    plate: PlateShape
    dt: float
    gravity: float = 0.0
    tangential: str = "contact-point"
    pp_laws: dict[tuple[int, int], Any] | None = None

    @property
    def n(self) -> int:
        return int(np.asarray(self.cls).size)

    def pp_pairs(self) -> list[tuple[int, int]]:
        """The pairs of spheres (i, j), i < j, with a law (none without pp_laws)."""
        return [(i, j) for i in range(self.n) for j in range(i + 1, self.n)] if self.pp_laws is not None else []


class SpherePool(abc.ABC):
    """A fixed set of spheres recycled through the park, in one engine (module docstring).

    Attributes the user reads: ``n``, ``cls``, ``radius``, ``mass``,
    ``park``, ``pp_pairs``, ``state`` (n,) int8 of PARKED/FLIGHT/DONE (the
    user sets DONE), ``free`` (one deque of parked sphere indices per
    class; the user pops from it and launches), ``adapter``.
    """

    engine: ClassVar[str] = ""

    @classmethod
    def check_spheres(cls, radii: Sequence[float], masses: Sequence[float], label: str = "radius") -> None:
        """Refuse spheres the engine cannot hold (ValueError naming ``label[i]``
        and the bound) before anything is built; radii [m], masses [kg]."""

    def __init__(self, scene: SphereScene):
        self.scene = scene
        self.cls = np.asarray(scene.cls)
        self.n = scene.n
        self.radius = np.asarray(scene.radius, dtype=float)
        self.mass = np.asarray(scene.mass, dtype=float)
        self.park = np.asarray(scene.park, dtype=float)
        self.pp_pairs = scene.pp_pairs()
        self.state = np.full(self.n, PARKED, np.int8)
        self.t_pinned = np.zeros(self.n)
        self.free = [deque(np.flatnonzero(self.cls == c).tolist()) for c in range(len(scene.laws))]
        self._v_park = np.asarray(scene.park_velocity, dtype=float)
        self._v_park_rows = np.tile(self._v_park, (self.n, 1))  # (n, 3), indexed like park
        self._repin_after = scene.repin_after
        self._pin_min = 0.0  # at most the smallest t_pinned of the parked spheres [s]
        self.adapter = None
        self._build()

    # -- what an engine back end implements ---------------------------------------
    @abc.abstractmethod
    def _build(self) -> None:
        """The scene: the spheres at ``park`` moving with the park velocity,
        the plate, and ``self.adapter`` with the pairs (module docstring)."""

    @abc.abstractmethod
    def place(self, idx: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """Set the centres [m] (k, 3) and velocities [m/s] (k, 3) of spheres
        idx (k,), zero spin, identity orientation."""

    @abc.abstractmethod
    def centres(self, idx: np.ndarray) -> np.ndarray:
        """Centres [m] (k, 3) of spheres idx (k,)."""

    @abc.abstractmethod
    def step(self) -> None:
        """One engine step through the adapter."""

    @property
    @abc.abstractmethod
    def time(self) -> float:
        """Engine time [s]."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the engine (idempotent)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    # -- the park --------------------------------------------------------------------
    @property
    def in_flight(self) -> int:
        """Spheres out of the park (FLIGHT or DONE)."""
        return int(np.count_nonzero(self.state != PARKED))

    def launch(self, idx: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """Place parked spheres idx (k,) (already taken from ``free``) at pos
        [m] (k, 3) with vel [m/s] (k, 3): state FLIGHT."""
        self.place(idx, pos, vel)
        self.state[idx] = FLIGHT

    def repin(self, t: float) -> None:
        """Put parked spheres that were pinned ``repin_after`` ago back on their
        slot (velocity: the park velocity); t [s] the engine time."""
        if t - self._pin_min < self._repin_after:  # no parked sphere is due (_pin_min <= their t_pinned)
            return
        parked = self.state == PARKED
        idx = np.flatnonzero(parked & (t - self.t_pinned >= self._repin_after))
        if idx.size:
            self.place(idx, self.park[idx], self._v_park_rows[idx])
            self.t_pinned[idx] = t
        self._pin_min = float(self.t_pinned[parked].min()) if np.any(parked) else math.inf

    def park_now(self, idx: np.ndarray, t: float) -> None:
        """Park spheres idx (k,) at engine time t [s] and return them to their free lists."""
        self.place(idx, self.park[idx], self._v_park_rows[idx])
        self.state[idx] = PARKED
        self.t_pinned[idx] = t
        self._pin_min = min(self._pin_min, t)
        for i, c in zip(idx.tolist(), self.cls[idx].tolist()):
            self.free[c].append(i)

    def required(self) -> np.ndarray:
        """Mask (n,) of the spheres in a contact or with a timing correction
        still in the engine (``manager.required_pairs``, also of pairs between spheres)."""
        req = np.asarray(self.adapter.manager.required_pairs, dtype=int)
        out = np.zeros(self.n, bool)
        out[req[req < self.n]] = True
        for p in req[req >= self.n].tolist():
            out[list(self.pp_pairs[p - self.n])] = True
        return out

    def park_done(self) -> None:
        """Park the DONE spheres the manager no longer needs."""
        done = np.flatnonzero(self.state == DONE)
        if done.size:
            ok = done[~self.required()[done]]
            if ok.size:
                self.park_now(ok, self.time)

    def pairs_of(self, plate) -> list:
        """The adapter's pairs (engines.contract.PairSpec) given the back end's
        names: ``plate`` the plate's and ``self._body(i)`` sphere i's."""
        sc = self.scene
        pairs = [PairSpec(self._body(i), plate, sc.laws[int(self.cls[i])], sc.tangential) for i in range(self.n)]
        if self.pp_pairs:
            pairs += [PairSpec(self._body(i), self._body(j), sc.pp_laws[(int(self.cls[i]), int(self.cls[j]))],
                               sc.tangential) for i, j in self.pp_pairs]
        return pairs

    def _body(self, i: int) -> Any:
        """Sphere i's name in the adapter's pairs (back ends with pairs_of)."""
        raise NotImplementedError


def sphere_pool_class(engine: str) -> type[SpherePool]:
    """The back end of ``engine`` ("mujoco" or "pybullet"), imported on first use."""
    if engine not in SPHERE_POOLS:
        raise ValueError(f"engine = {engine!r} is not one of {', '.join(SPHERE_POOLS)}")
    return resolve(SPHERE_POOLS[engine])


def make_sphere_pool(engine: str, scene: SphereScene, **options) -> SpherePool:
    """The pool of ``scene`` in ``engine``; ``options`` are the back end's own
    (MuJoCo: ``integrator``)."""
    return sphere_pool_class(engine)(scene, **options)
