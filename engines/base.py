"""The engine adapter contract and the data that crosses it.

An adapter puts force laws from :mod:`msf_contact` between pairs of bodies
of a MuJoCo or pybullet model. The engine-agnostic work (per-contact state,
onset constants, sub-cycling, impact records) is done by
:class:`engines._contacts.ContactManager`; an adapter only reads the engine
and writes forces.

What an adapter (:class:`EngineAdapter`) must do:

1. Take an engine model plus a list of :class:`PairSpec` (body/geom names
   and the law of each pair); refuse unknown names and non-smooth pairs
   with ``ValueError`` before stepping.
2. Switch the engine's own contact response off for those pairs, so no
   force is counted twice.
3. Each engine step, fill a :class:`ContactKinematics` for every pair that
   is in contact or will close its gap within the step (x > -closing
   distance, ``engines._contacts.closing_distance``) plus every pair in
   ``manager.required_pairs`` (in contact, or with a timing correction still
   to remove), with the inverse effective inertia at the contact point from
   the engine's own inertia (works for links of articulated chains). Across
   a gap, each body's Jacobian is taken at its own surface point
   (``Detection.point1``/``point2``).
4. Call ``manager.step`` once per engine step, also when there is no
   candidate (it completes finished records), and apply the returned
   :class:`ContactForces` (step-averaged, equal and opposite; a fixed body
   takes none) through the engine's own mechanism (MuJoCo: passive forces in
   ``mjcb_passive``; pybullet: ``applyExternalForce``), identical for every
   integrator stage inside one step. The forces include the manager's timing
   correction, so for one step after a contact the engine's velocities are
   offset; read post-impact results from the records.
5. Expose the finished impacts as :class:`msf_contact.ImpactRecord` (same
   format as the reference solver) in ``records``; a record appears about
   two steps after its contact ends (``manager.pending_count``).

Conventions: world frame, SI units; the contact normal ``n`` points from
body 2 toward body 1; ``x`` is the approach (overlap) of the undeformed
surfaces, positive in contact; relative velocities are body 1's contact
point minus body 2's.
"""

from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from msf_contact.laws import ForceLaw

#: Below this many engine steps per contact an explicit force cannot resolve
#: the contact (spec section 6); the manager always integrates internally,
#: with at least this many internal steps per contact duration.
STEPS_PER_CONTACT_MIN = 50


@dataclass(frozen=True)
class PairSpec:
    """A pair of bodies (or geoms) and the law between them.

    body1, body2: names in the engine model (MuJoCo geom or body name;
        pybullet (body unique id, link index) or a name the adapter maps).
    law: a constructed :class:`msf_contact.laws.ForceLaw`.
    tangential: "contact-point" (default) or "paper" (spec section 4).
    """

    body1: Any
    body2: Any
    law: ForceLaw
    tangential: str = "contact-point"


@dataclass
class ContactKinematics:
    """What an adapter reads from the engine for n candidate contacts.

    pair: index into the adapter's pair list (n,) int.
    x: approach [m] (n,); negative: a gap that may close within the step.
    normal: unit normal from body 2 to body 1 (n, 3).
    point: contact point, mid-overlap [m] (n, 3).
    v_rel: velocity of body 1's material point at ``point`` minus body 2's [m/s] (n, 3).
    v_com_rel: velocity of body 1's centre of mass minus body 2's [m/s] (n, 3)
        (the "paper" tangential mode integrates its tangential part).
    W: inverse effective inertia at the contact point [1/kg] (n, 3, 3): the
        change of v_rel per unit impulse applied +P on body 1 and -P on body 2
        at ``point``; W = J M^-1 J^T with J the difference of the bodies'
        translational point Jacobians.
    W_com: change of v_com_rel per unit impulse [1/kg] (n, 3, 3) (the
        translational part only; (1/m1 + 1/m2) I for two free bodies).
    a_ext: relative acceleration of the contact points from everything but
        these contacts (gravity, actuators, other contacts) [m/s^2] (n, 3).
    t: engine time at the start of the step [s].
    """

    pair: np.ndarray
    x: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    v_rel: np.ndarray
    v_com_rel: np.ndarray
    W: np.ndarray
    W_com: np.ndarray
    a_ext: np.ndarray
    t: float


@dataclass
class ContactForces:
    """What the manager returns for the step: step-averaged force on body 1
    (body 2 takes the opposite) [N] (n, 3), applied at ``point`` [m] (n, 3),
    for the contacts of the kinematics with the same order; rows of zeros for
    candidates that did not touch."""

    force: np.ndarray
    point: np.ndarray
    pair: np.ndarray


class EngineAdapter(abc.ABC):
    """Base of the MuJoCo and pybullet adapters; see the module docstring."""

    name: str = ""

    def __init__(self, pairs: list[PairSpec]):
        from ._contacts import ContactManager

        if not pairs:
            raise ValueError("pairs is empty: give at least one PairSpec")
        self.pairs = list(pairs)
        self.manager = ContactManager(self.pairs, dt=self.timestep, engine=self.name)

    @property
    @abc.abstractmethod
    def timestep(self) -> float:
        """The engine's time step [s]."""

    @abc.abstractmethod
    def step(self, n: int = 1) -> None:
        """Advance the engine n steps with the pairs' laws acting."""

    @property
    def records(self) -> list:
        """Finished impacts (msf_contact.ImpactRecord), oldest first."""
        return self.manager.records

    def pop_records(self) -> list:
        """Finished impacts since the last call, and forget them (memory stays flat)."""
        return self.manager.pop_records()


#: Registry of engines for the command line: name -> function running one
#: isolated impact and returning an ImpactRecord. Filled by the adapters'
#: modules (engines.mujoco, engines.pybullet) on import.
ENGINES: dict[str, Callable[..., Any]] = {}


def register_engine(name: str, fn: Callable[..., Any]) -> None:
    ENGINES[name] = fn


def get_engine(name: str) -> Callable[..., Any]:
    if name not in ENGINES:
        # import on demand so `msf-contact --help` stays fast
        if name.startswith("mujoco"):
            import engines.mujoco  # noqa: F401
        elif name.startswith("pybullet"):
            import engines.pybullet  # noqa: F401
    try:
        return ENGINES[name]
    except KeyError:
        raise ValueError(
            f"unknown engine {name!r}; valid names: mujoco, mujoco-builtin, pybullet, pybullet-builtin"
        ) from None


#: The law's radii must be the engine shapes' (float32/float64 round trips only).
RADIUS_RTOL = 1e-9


def check_law_curvature(label: str, pair: PairSpec, R1: float, R2: float) -> None:
    """Refuse a pair whose law was built for other radii than the engine's
    shapes: R1 body 1's sphere radius [m], R2 body 2's (inf for a plane or box face)."""
    curv = pair.law.curvature
    for name, want, got in (("R1a", R1, curv.R1a), ("R1b", R1, curv.R1b),
                            ("R2a", R2, curv.R2a), ("R2b", R2, curv.R2b)):
        same = (math.isinf(want) and math.isinf(got)) or (
            math.isfinite(want) and math.isfinite(got) and abs(got - want) <= RADIUS_RTOL * want)
        if not same:
            raise ValueError(f"{label}: the law's curvature {name} = {got!r} m does not match the engine shape's "
                             f"radius {want!r} m of {pair.body1 if name[1] == '1' else pair.body2!r}")


def as_array(a, shape) -> np.ndarray:
    """Float array of the given trailing shape (leading n)."""
    return np.asarray(a, dtype=float).reshape((-1,) + tuple(shape))

