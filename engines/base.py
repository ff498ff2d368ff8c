"""The engine adapter contract (the data that crosses it: :mod:`engines.contract`)
and the registry of engines by name.

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

import numpy as np

from ._contacts import ContactManager
from .contract import (  # the contract's data, re-exported: the adapters import it from here
    RADIUS_RTOL,
    STEPS_PER_CONTACT_MIN,
    ContactForces,
    ContactKinematics,
    ContactReport,
    PairSpec,
    as_array,
    check_law_curvature,
)
from .registry import ENGINES, get_engine

__all__ = ["EngineAdapter", "ENGINES", "get_engine", "RADIUS_RTOL", "STEPS_PER_CONTACT_MIN", "ContactForces",
           "ContactKinematics", "ContactReport", "PairSpec", "as_array", "check_law_curvature"]


#: A pair not on MSF (set_mode) is shown to
#: the contact manager as this gap [m], separating at this speed [m/s].
FAR_GAP = 1.0
FAR_SPEED = 1.0


class EngineAdapter(abc.ABC):
    """Base of the MuJoCo and pybullet adapters; see the module docstring."""

    name: str = ""

    def __init__(self, pairs: list[PairSpec]):
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

    #: names of each pair's bodies [(body1, body2)], set by the adapter
    pair_names: list[tuple[str, str]] = []

    def _mask(self, kin: ContactKinematics) -> ContactKinematics:
        """Rows of pairs not on MSF (``self._mode`` != 0: the engine's contact
        or off) are shown to the manager as far (FAR_GAP) and separating
        (FAR_SPEED), so it neither starts nor continues a contact for them."""
        if not self._mode.any():  # every pair on MSF (the usual case)
            return kin
        off = self._mode[kin.pair] != 0
        if np.any(off):
            kin.x = np.where(off, -FAR_GAP, kin.x)
            kin.v_rel = np.where(off[:, None], kin.normal * FAR_SPEED, kin.v_rel)
            kin.v_com_rel = np.where(off[:, None], kin.normal * FAR_SPEED, kin.v_com_rel)
            kin.a_ext = np.where(off[:, None], 0.0, kin.a_ext)
        return kin

    def contact_forces(self) -> list[ContactReport]:
        """The MSF contact forces of the last engine step, one
        :class:`engines.contract.ContactReport` per pair that exerted a force
        in it (SI units; step-averaged: what the engine applied). The last
        step is the one the adapter last computed: after ``adapter.step()``
        or ``mj_step`` the step just taken; after an ``mj_forward`` the step
        that starts at the current state (``ContactReport.t`` says which)."""
        out, kin = getattr(self, "_last_out", None), getattr(self, "_last_kin", None)
        if out is None or kin is None:
            return []
        force = np.asarray(out.force, dtype=float).reshape(-1, 3)
        reports = []
        for k in np.flatnonzero(np.any(force != 0.0, axis=1)):
            p = int(out.pair[k])
            n = np.asarray(kin.normal[k], dtype=float)
            F = force[k].copy()
            Fn = float(F @ n)
            reports.append(ContactReport(
                pair=p, body1=self.pair_names[p][0], body2=self.pair_names[p][1], t=float(kin.t),
                point=np.asarray(out.point[k], dtype=float).copy(), normal=n.copy(), force=F, F_n=Fn,
                F_t=F - Fn * n, overlap=float(self.manager.x[p]) if self.manager.active[p] else 0.0))
        return reports
