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
import warnings

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


#: A pair not on MSF (set_mode, a sphere through a box handed to the engine) is shown to
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

    def _through(self, i: int, deep: bool, x: float, reach: float) -> None:
        """A sphere deeper in a box than its own radius (``deep``: the
        engine's x or the contact's own approach > R, its centre past the
        box's surface: the bodies passed through each other,
        a diverging model or a step far too large for the speeds) has no
        contact law: the engine's own contact takes pair i
        (``self._handoff``; counted in ``edge_handoffs``, a RuntimeWarning the
        first time per pair; an MSF contact in progress ends without a
        record) until a gap opens that a step cannot close (x < -``reach``
        [m]: the surfaces' relative speed over a step and 1 mm; released at
        x < 0, the contact's own integration found a new one inside the
        step at the same speeds). Measured: a paddle on a
        diverging servo (tests/test_held_link.py, kp 1e4 at 2 ms) swept
        through the ball at 1e4 rad/s, the contact's x = 0.6 m with the
        engine's a 0.2 m gap, and MSF's force drove the model to inf where
        the engine's contact let the ball go. The
        adapter's ``_engine_contact_changed(i)`` switches the engine's
        contact."""
        if deep and not self._handoff[i]:
            self._handoff[i] = True
            self.edge_handoffs += 1
            self.manager.interrupt([i], f"the sphere passed through the box (handed to {self.name}'s contact)")
            if self.edge_handoffs_of.setdefault(i, 0) == 0:
                warnings.warn(f"pair {i} {self.pair_names[i]}: the sphere is {x:.3g} m deep in the box at "
                              f"t = {self.now:.6g} s, deeper than its radius (the bodies passed through each "
                              f"other: a diverging model, or a step too large for the speeds); no contact law "
                              f"holds there, so {self.name}'s own contact takes the pair until a gap opens "
                              "(adapter.edge_handoffs counts these; take a smaller time step)", RuntimeWarning,
                              stacklevel=4)
            self.edge_handoffs_of[i] += 1
            self._engine_contact_changed(i)
        elif self._handoff[i] and x < -reach:
            self._handoff[i] = False
            self._have_last[i] = False
            self._engine_contact_changed(i)

    def _mask(self, kin: ContactKinematics) -> ContactKinematics:
        """Rows of pairs not on MSF (``self._mode`` != 0: the engine's contact
        or off; ``self._handoff``: a sphere through a box, handed to the engine) are shown to
        the manager as far (FAR_GAP) and separating (FAR_SPEED), so it neither
        starts nor continues a contact for them."""
        if not (self._mode.any() or self._handoff.any()):  # every pair on MSF (the usual case)
            return kin
        off = (self._mode[kin.pair] != 0) | self._handoff[kin.pair]
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
