"""The contact manager: per-contact state and one engine step of the
candidate contacts (:meth:`ContactManager.step`), dispatched to the
compiled path (:mod:`.compiled`, :mod:`engines._kernel`) or the numpy
reference (:mod:`.reference`); onsets and records in :mod:`.records`.
The algorithm: the package docstring (:mod:`engines._contacts`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np

from msf_contact.laws import ForceLaw
from msf_contact.record import ImpactRecord

from .. import _kernel as K
from ..contract import STEPS_PER_CONTACT_MIN, ContactForces, ContactKinematics, PairSpec, as_array
from .compiled import CompiledPath, kernel_law
from .records import Records
from .reference import NumpyPath
from .balance import IslandBalance
from .gaps import KeptGapCheck
from .island_compiled import island_blocks, step_islands
from .islands import TOUCH_TOL, island_lever, islands, step_island
from .resting import settle_island
from .state import (
    L_G0, L_ON, L_W01, L_W11, L_XREF, NL, NY, SETTLE_AFTER_DURATIONS, SETTLE_RATE, SETTLED_SPEED_RATIO, TANGENTIAL_MODES,
    ENERGY_APPROACH_RTOL, TakenOnset, approach_of_energy, elastic_energy, residual_indentation, side_forces,
    side_kernel_rows,
    _cross, _dot, _name, _tangent_basis,
)


class ContactManager(CompiledPath, NumpyPath, Records):
    """Per-contact state, sub-cycled integration and impact records for the
    pairs of one adapter (see the module docstring).

    pairs: the adapter's PairSpecs (one contact per pair: smooth convex
    shapes touch at one point). dt: the engine step [s]. engine: name written
    into the records. settle_rate: share of the engine-internal offset of x
    removed per step in a resting contact (0 disables). settled_path: take the
    settled path for long, slow contacts (False: sub-cycle every contact, the
    plain implementation the settled path is tested against). compiled: run
    the groups whose law the compiled kernel knows (:func:`kernel_law`) in
    :mod:`engines._kernel` (False: the numpy path for every group, the
    implementation the kernel is tested against).

    Adapter hooks (optional, :meth:`set_body_probe`): a function
    ``probe(pair_index) -> dict`` returning body-level quantities, read at
    onset and when a finished contact's record is completed (at the next
    :meth:`step`, or when ``records``/``pop_records`` are read, i.e. after
    the engine applied the contact's last impulse). Key ``"omega1"``: body
    1's angular velocity in world axes [rad/s] (3,), gives spin_in/spin_out
    about n x t (t the incident tangential direction; rolling in the
    direction of incidence is positive, as in the reference solver);
    ``"omega1"`` and ``"omega2"`` give the bodies' rotation per step, checked
    for the bodies :meth:`set_orientation_free` does not exempt; other
    keys are stored in ``record.inputs["body_in"]`` / ``["body_out"]``.
    """

    def __init__(self, pairs: list[PairSpec], dt: float, engine: str, *, settle_rate: float = SETTLE_RATE,
                 timing_correction: bool = True, settled_path: bool = True, compiled: bool = True):
        if not pairs:
            raise ValueError("pairs is empty: give at least one PairSpec")
        dt = float(dt)
        if not math.isfinite(dt) or dt <= 0:
            raise ValueError(f"dt = {dt!r} s must be finite and > 0")
        #: keep each contact's step-averaged normal force per engine step and put it
        #: in its record (inputs["curves"]); for isolated impacts, off for jets
        self.history = False
        self._hist: dict[int, list[tuple[float, float]]] = {}
        if not 0.0 <= settle_rate <= 1.0:
            raise ValueError(f"settle_rate = {settle_rate!r} must be in [0, 1]")
        for i, p in enumerate(pairs):
            if not isinstance(p.law, ForceLaw):
                raise ValueError(f"pairs[{i}].law = {p.law!r} is not a msf_contact ForceLaw")
            if p.tangential not in TANGENTIAL_MODES:
                raise ValueError(f"pairs[{i}].tangential = {p.tangential!r} is not one of {TANGENTIAL_MODES}")
        self.pairs = list(pairs)
        #: each pair's body names (body1, body2), written into the records (an adapter sets
        #: the engine's names; default: the PairSpec's identifiers as text)
        self.pair_names = [(_name(p.body1), _name(p.body2)) for p in self.pairs]
        self.dt = dt
        self.engine = str(engine)
        self.settle_rate = float(settle_rate)
        self.timing_correction = bool(timing_correction)
        self.settled_path = bool(settled_path)
        P = len(pairs)
        self._paper = np.array([p.tangential == "paper" for p in pairs])
        # group pairs by law object (vectorised per law)
        self._groups: dict[int, ForceLaw] = {}
        self._group_of = np.empty(P, int)
        self._pos = np.empty(P, int)  # position of a pair inside its group's onset arrays
        sizes: dict[int, int] = {}
        for i, p in enumerate(pairs):
            g = id(p.law)
            self._groups.setdefault(g, p.law)
            self._group_of[i] = g
            self._pos[i] = sizes.get(g, 0)
            sizes[g] = self._pos[i] + 1
        self._group_size = sizes
        self._onset: dict[int, dict[str, np.ndarray]] = {g: {} for g in self._groups}
        #: per law group: (code, constants) of the compiled kernel, or None (numpy path)
        self.compiled = bool(compiled)
        self._kernel_law = {g: (kernel_law(law) if self.compiled else None) for g, law in self._groups.items()}
        #: islands whose rows' laws all have a kernel code go through the compiled island kernel
        #: (engines._contacts.island_compiled; False: every island through the numpy step_island,
        #: the reference it is tested against)
        self.island_compiled = self.compiled
        # the kernel's laws: pair -> index into _kcodes/_kLC (-1: numpy path); all of them in one kernel call
        kgs = [g for g in self._groups if self._kernel_law[g] is not None]
        self._kcodes = np.array([self._kernel_law[g][0] for g in kgs], dtype=np.int64)
        self._kLC = np.array([self._kernel_law[g][1] for g in kgs], dtype=float).reshape(len(kgs), K.NLC)
        kidx = {g: j for j, g in enumerate(kgs)}
        self._kidx = kidx  # law group -> its row in _kcodes/_kLC
        self._slot_pos = {(i, int(self._group_of[i])): int(self._pos[i]) for i in range(P)}  # set_law
        self._kg_of_pair = np.array([kidx.get(g, -1) for g in self._group_of], dtype=np.int64)
        self._all_kernel = bool(np.all(self._kg_of_pair >= 0))
        #: the lying sides' ends' forces and energies of every law group in one compiled call
        #: (state.side_forces, side_energies; False: group by group, the reference they are tested against)
        self._batched_laws = True
        self._coupling: tuple[np.ndarray, Callable] | None = None  # set_coupling
        self._together: np.ndarray | None = None  # set_together: pairs solved together also at rest (None: all)
        self._balance: IslandBalance | None = None  # set_energy_probe
        self._probe: Callable[[int], dict] | None = None
        self._probe_batch: Callable[[], Callable[[int], dict]] | None = None
        #: (P, 2) bool: the contact of the pair does not depend on the orientation of body 1 / body 2
        #: (a sphere centred on its centre of mass, or a fixed body); the others' rotation per step is
        #: checked against ROTATION_PER_STEP_MAX (set_orientation_free)
        self.orientation_free = np.zeros((P, 2), bool)
        self._rotation_warned = np.zeros(P, bool)
        self._strain_warned = np.zeros(P, bool)  # x_max/R or 2R note said on stderr once per pair
        self._capped_warned = np.zeros(P, bool)  # an onset past the law's range said once per pair
        self._init_state(P)
        self.records: list[ImpactRecord] = []
        self._pending: list[list] = []  # [pair, record, spin axis, steps waited]
        self.last_step_info: dict[str, Any] = {}

    def _init_state(self, P):
        z, z3 = np.zeros(P), np.zeros((P, 3))
        # the per-pair record bookkeeping lives in one (NF, P) array (the compiled
        # kernel updates it in place); the attributes below are its rows
        self._fl = np.zeros((K.NF, P))
        fl = self._fl
        self.active = np.zeros(P, bool)  #: in contact (P,)
        self.x = z.copy()  #: internal approach [m] (P,)
        self.xdot = z.copy()  #: approach rate at the end of the last step [m/s] (P,)
        self.s = z3.copy()  #: tangential displacement, world, in the contact plane [m] (P, 3)
        self.phase = np.zeros(P, np.int8)  #: 0 compression (x' > 0), 1 restitution
        self.turned = np.zeros(P, bool)  #: maximum compression passed at least once
        self.t_onset = fl[K.F_TONSET]  #: onset time [s]
        self.v_n_in = z.copy()  #: closing speed at onset [m/s]
        self.v_n_used = z.copy()  #: onset speed given to law.onset (>= floor) [m/s]
        self.m_eff = z.copy()  #: 1/(n W n) at onset [kg]
        self.tau_est = z.copy()  #: estimated duration of the normal impact [s]
        self.h = fl[K.F_H]  #: internal step [s]
        self.n_in = z3.copy()  #: normal at onset (P, 3)
        self.W_in = np.zeros((P, 3, 3))  #: inverse inertia of the contact points at onset [1/kg] (P, 3, 3)
        self.p_in = z3.copy()  #: contact point at the start of the onset step [m] (P, 3)
        self._point = z3.copy()  #: contact points of the current step's rows [m] (P, 3)
        self.u_in = z3.copy()  #: contact-point tangential velocity at onset [m/s] (P, 3)
        self.vc_in = z3.copy()  #: centre-of-mass relative tangential velocity at onset [m/s] (P, 3)
        self.vc = z3.copy()  #: centre-of-mass relative velocity at the end of the last step [m/s] (P, 3)
        self.x_max = fl[K.F_XMAX]  #: maximum approach so far [m]
        #: approach at onset [m]: 0 for a contact begun at touching; > 0 for one found already
        #: overlapping (its elastic energy up to there was never worked for: engines._contacts.balance)
        self.x_onset = z.copy()
        #: the recovering surface of the pair's last contact if it ended at force zero with x > 0
        #: (state.RECOVERY_DOC): its overlap there [m] (0: none), the end time [s], the rate E'/(3 eta'_E) [1/s]
        self.x_res, self.t_res, self.k_res = z.copy(), z.copy(), z.copy()
        #: x_r(t0) of the step the pair's current contact began in [m] (0: a restart from touching), or
        #: for a contact resumed inside the step its last contact ended in at force zero, the overlap it
        #: resumed at (at most that end's): its onset may lie that deep without storing energy no force
        #: worked for (state.RECOVERY_DOC)
        self.x_surface_onset = z.copy()
        self._t_now = 0.0  # the time of the current (or last) step start [s]
        self.x_turn = fl[K.F_XTURN]  #: approach at the first maximum compression [m]
        self.tau1 = fl[K.F_TAU1]  #: compression time [s]
        self.F_max = fl[K.F_FMAX]  #: peak normal force [N]
        self.x_at_F = fl[K.F_XATF]  #: approach at the peak force [m]
        self.f_min = fl[K.F_FMIN]  #: min |F_t|/F_n [-]
        self.f_min[:] = np.inf
        self.f_max = fl[K.F_FMAXR]  #: max |F_t|/F_n [-]
        self.W_el = z.copy()  #: work of the elastic normal force so far [J]
        self.W_visc = z.copy()  #: work of the viscous normal force so far [J]
        self.W_el_comp = fl[K.F_WELC]
        self.W_visc_comp = fl[K.F_WVIC]
        self.Q_t = z.copy()  #: tangential viscous work (80) [J]
        self.W_t = z.copy()  #: work done against the tangential force [J]
        #: W_t - Q_t of the pair's finished contacts, summed [J] (engines._contacts.balance)
        self.W_tq_finished = z.copy()
        self.outside = np.zeros(P, bool)
        self.settled = np.zeros(P, bool)  #: took the settled path in the last step (P,)
        #: solved in an island of several contacts in the last step (P,): the adapters keep such a
        #: pair's force out of the held forces of a_ext (the island couples it explicitly)
        self.in_island = np.zeros(P, bool)
        self._island_of = np.full(P, -1, np.int64)  # island label of the pair in the last step (-1: none)
        self._listed = np.zeros(P, bool)  # a candidate row in the last step (its x is the manager's)
        self._xd0 = z.copy()  # approach rate at the last step's start, engine's less dv_corr [m/s] (_own_gaps)
        self._an = z.copy()  # a_ext along n in the last step [m/s^2] (_own_gaps)
        self._off = z.copy()  # bound on the engine's lead over the manager's x [m] (_own_gaps)
        #: pairs whose gap the manager may keep between steps (_own_gaps): the adapters set it for free
        #: spheres on planes, fixed or free spheres, whose integrated gap (n and W frozen over a step) is
        #: second order; a link's point moves with its joints and the engine's gap is taken (P,)
        self.own_gap = np.zeros(P, bool)
        #: pairs whose resting island may take one settled step (engines._contacts.resting) when it is
        #: also own_gap: free bodies; the MuJoCo adapter clears it for links of a chain (own_gap there; pybullet's
        #: links are never own_gap), which keep the RK4
        #: island (MuJoCo's humanoid at rest: a settled island step of its limbs, then the RK4 island,
        #: a contact's force 62 -> 246 N in one step and 93 mJ gained, issue 13) (P,)
        self.settle_rigid = np.ones(P, bool)
        self._gain_note: list[str | None] = [None] * P  # an island energy gain seen during the pair's contact
        #: a note for the pair's next contact's record (note_next_contact: a kept gap flagged, gaps.KeptGapCheck)
        self._next_note: list[str | None] = [None] * P
        self._kept_check = KeptGapCheck(P)
        self._island_contact = np.zeros(P, bool)  # the pair's current contact was in an island at some step
        self._held_force = np.zeros((P, 3))  #: the step-averaged forces held into the next step [N] (P, 3)
        self.J = z3.copy()  #: timing-correction impulse applied in the last step, removed in the next [N s] (P, 3)
        self._normal = z3.copy()  # the unit normal of the pair's last step (refresh_law's tangent axes; 0: none yet)
        self.dv_corr = z3.copy()  #: W J: the engine's contact-point velocity offset it causes [m/s] (P, 3)
        self.dvc_corr = z3.copy()  #: W_com J [m/s] (P, 3)
        #: angular impulse n x PD / 2 of the moving contact point in the last step, on both bodies [N m s] (P, 3)
        self.couple = z3.copy()
        self._L0 = np.zeros((P, K.NL))  #: the compiled path's rows without a moving contact point (all zero)
        #: max(x, 0) of the engine geometry where the timing correction J was applied [m] (P,)
        self.x_J = z.copy()
        self.body_in: list[dict | None] = [None] * P
        self._oc = np.full((P, K.NOC), np.nan)  #: onset constants per pair for the compiled kernel
        # the kernel's scratch (it allocates nothing itself)
        self._seen = np.zeros(P, bool)
        self._scr_settled = (np.empty(6), np.empty((4, 3, 3)), np.empty((8, 3)), np.empty((3, 4)))
        self._scr_rk4 = (np.empty(6), np.empty((5, NY)), np.empty((4, NY)))
        self._params: dict[int, dict] = {}  # law.parameters() per group, copied into each record
        self._floor_K: dict[int, float] = {}  # state.onset_stiffness per group (the onset speed floor)

    @property
    def active_count(self) -> int:
        return int(np.count_nonzero(self.active))

    @property
    def active_pairs(self) -> np.ndarray:
        """Pair indices in contact."""
        return np.flatnonzero(self.active)

    @property
    def required_pairs(self) -> np.ndarray:
        """Pair indices an adapter must list as candidates in the next step,
        whatever their gap: those in contact and those with a timing
        correction to remove."""
        return K.required(self.active, self.J)

    def set_body_probe(self, probe: Callable[[int], dict] | None,
                       batch: Callable[[], Callable[[int], dict]] | None = None) -> None:
        """Install the adapter's body-level probe (see the class docstring).
        batch: optional; returns a probe valid for one batch of calls made
        between engine steps (records completed when they are read), so the
        adapter brings the engine's derived quantities up to date once per
        batch instead of once per record."""
        if probe is not None and not callable(probe):
            raise ValueError(f"probe = {probe!r} must be callable or None")
        if batch is not None and not callable(batch):
            raise ValueError(f"batch = {batch!r} must be callable or None")
        self._probe = probe
        self._probe_batch = batch

    def set_orientation_free(self, mask) -> None:
        """Which bodies' orientation the pairs' contacts do not depend on:
        mask (P, 2) bool, True for a sphere centred on its body's centre of
        mass or a fixed body. For the others the records flag a rotation per
        engine step |omega| dt above ROTATION_PER_STEP_MAX (read from the
        body probe's ``omega1``/``omega2`` at the contact's start and after its
        end; engines._contacts.state)."""
        m = np.asarray(mask, dtype=bool)
        if m.shape != (len(self.pairs), 2):
            raise ValueError(f"mask has shape {m.shape}; expected ({len(self.pairs)}, 2)")
        self.orientation_free = m.copy()

    def state(self, pair_index: int) -> dict | None:
        """Current state of the pair's contact, or None when not in contact."""
        p = int(pair_index)
        if not 0 <= p < len(self.pairs):
            raise ValueError(f"pair_index = {pair_index!r} is outside [0, {len(self.pairs) - 1}]")
        if not self.active[p]:
            return None
        g = self._group_of[p]
        onset = {k: float(v[self._pos[p]]) for k, v in self._onset[g].items()}
        return {
            "x": float(self.x[p]), "xdot": float(self.xdot[p]), "s": self.s[p].copy(),
            "phase": "restitution" if self.phase[p] else "compression",
            "x_max": float(self.x_max[p]), "F_max": float(self.F_max[p]), "t_onset": float(self.t_onset[p]),
            "v_n_in": float(self.v_n_in[p]), "v_n_used": float(self.v_n_used[p]),
            "v_t_in": float(np.linalg.norm(self.u_in[p])), "m_eff": float(self.m_eff[p]),
            "omega_x": onset.get("omega_x"), "omega_y": onset.get("omega_y"), "onset": onset,
            "tau_est": float(self.tau_est[p]), "h": float(self.h[p]),
            "W_el": float(self.W_el[p]), "W_visc": float(self.W_visc[p]), "Q_t": float(self.Q_t[p]),
        }

    def step(self, kin: ContactKinematics) -> ContactForces:
        """Integrate the candidate contacts over one engine step; return the
        step-averaged forces on body 1 at the contact points."""
        self._t_now = float(kin.t)
        if self._balance is not None:  # the islands of the last step, now that the engine applied it
            self._balance.close(self, float(kin.t) - self.dt)
        self._finish_pending(at_step_start=True)
        pair = np.asarray(kin.pair, dtype=int).reshape(-1)
        k = pair.shape[0]
        x = as_array(kin.x, ()).reshape(-1)
        n = as_array(kin.normal, (3,))
        point = as_array(kin.point, (3,))
        v = as_array(kin.v_rel, (3,))
        vc = as_array(kin.v_com_rel, (3,))
        W = as_array(kin.W, (3, 3))
        Wc = as_array(kin.W_com, (3, 3))
        a = as_array(kin.a_ext, (3,))
        for name, arr in (("x", x), ("normal", n), ("point", point), ("v_rel", v), ("v_com_rel", vc),
                          ("W", W), ("W_com", Wc), ("a_ext", a)):
            if arr.shape[0] != k:
                raise ValueError(f"kinematics.{name} has {arr.shape[0]} rows; expected {k} (len(pair))")
        n_unit = np.empty((k, 3))  # the normals renormalised (they are unit to 1e-6)
        code, row = K.check(pair, len(self.pairs), x, n, point, v, vc, W, Wc, a, self.active, self.J, self._seen,
                            n_unit, self._point)
        if code:
            self._invalid(code, row, pair, x, n, point, v, vc, W, Wc, a)
        n = n_unit
        self._normal[pair] = n
        x = self._own_gaps(pair, x, n, v, a, W)
        L = None
        lev = getattr(kin, "lever", None)
        if lev is not None:
            lev = as_array(lev, (NL - 2,))
            if lev.shape[0] != k:
                raise ValueError(f"kinematics.lever has {lev.shape[0]} rows; expected {k} (len(pair))")
            if not np.all(np.isfinite(lev)):
                raise ValueError(f"kinematics.lever is not finite: {lev!r}")
            L = np.empty((k, NL))
            L[:, L_ON] = np.any(lev != 0.0, axis=1)  # an all-zero row: the point frozen, no extra work
            L[:, L_XREF] = np.maximum(x, 0.0)  # the point is mid-overlap, each body's surface point at a gap
            L[:, L_W01:] = lev
            self.couple[pair] = 0.0
            J_old = self.J[pair].copy()
            # the engine's velocity offset of the last step's timing correction J, applied at the point
            # of x_J, read at this step's point (e = x_J - x_ref away): J(0) M^-1 J(e)^T J = W J + e W01 J
            # (LEVER_DOC; first order in e), in place of the last step's W J. After an island step
            # dv_corr also holds the cross terms W_pq J_q: its own part, the last step's W J =
            # J(e) M^-1 J(e)^T J = (W + e (W01 + W01^T) + e^2 W11) J, is brought to W J + e W01 J
            # by adding -(e W01^T + e^2 W11) J (the cross terms' own lever left out, as in step_island)
            on = (L[:, L_ON] != 0.0) & np.any(J_old != 0.0, axis=1)
            if np.any(on):
                q = pair[on]
                e = self.x_J[q] - L[on, L_XREF]
                W01 = L[on, L_W01:L_W01 + 9].reshape(-1, 3, 3)
                was = self.in_island[q]
                alone = np.einsum("kij,kj->ki", W[on], J_old[on]) + e[:, None] * np.einsum("kij,kj->ki", W01, J_old[on])
                W11 = L[on, L_W11:L_W11 + 9].reshape(-1, 3, 3)
                shift = -e[:, None] * (np.einsum("kji,kj->ki", W01, J_old[on])
                                       + e[:, None] * np.einsum("kij,kj->ki", W11, J_old[on]))
                self.dv_corr[q] = np.where(was[:, None], self.dv_corr[q] + shift, alone)
                # and g0 = J1 qdot carries J1 M^-1 J(e)^T J = W01^T J + e W11 J of it
                L[on, L_G0:L_G0 + 3] -= (np.einsum("kji,kj->ki", W01, J_old[on])
                                         + e[:, None] * np.einsum("kij,kj->ki", W11, J_old[on]))
        t0 = float(kin.t)
        info = {"rows": k, "substeps": 0, "segments": 0, "onsets": 0, "ends": 0, "settled": 0,
                "settled_iterations": 0, "island_rows": 0}
        if self._coupling is not None:
            self._cross_corrections(pair)
        self.in_island[:] = False
        self._island_of[:] = -1
        multi = self._island_rows(pair, t0, n, v, W) if self._coupling is not None and k > 1 else None
        if multi is not None:
            out = self._step_with_islands(multi, pair, x, n, point, v, vc, W, Wc, a, t0, info, L)
        else:
            out = self._step_rows(pair, x, n, point, v, vc, W, Wc, a, t0, info, L)
        if L is not None:
            # the last step's timing correction is removed in this step's force at this step's point;
            # it was applied at the point of x_J: put the removal there (LEVER_DOC: PD = d (-J),
            # d = x_J - x_ref), so that it takes back the angular impulse it gave. Not for island rows:
            # the island energy check (engines._contacts.balance) takes J out at this step's points
            # (the adapters' energy probes); moved there, the 8-sphere pile (scripts/pile.py --n 8
            # --side 2 --steps 150, MuJoCo) rose 2.4e-8 J in a step where it now stays at round-off
            own = (L[:, L_ON] != 0.0) & ~self.in_island[pair]
            if np.any(own):
                q = pair[own]
                PD = -(self.x_J[q] - L[own, L_XREF])[:, None] * J_old[own]
                self.couple[q] += 0.5 * _cross(n[own], PD)
            self.x_J[pair] = L[:, L_XREF]
            out.torque = self.couple[pair] / self.dt
        self.x_res[pair[self.active[pair]]] = 0.0  # a contact resumed: the surface is its x (state.RECOVERY_DOC)
        self._listed[:] = False
        self._listed[pair] = True
        if self._coupling is not None:  # the forces the adapters hold into the next step's a_ext
            self._held_force[:] = 0.0
            held = self.held(pair, t0 + self.dt)
            self._held_force[pair[held]] = out.force[held]
        return out

    def stored_energy(self) -> float:
        """Energy held in and exchanged by the pairs' contacts [J], the measure
        the islands' energy check uses (:mod:`engines._contacts.balance`): for
        each contact in progress the elastic energy of its normal force at the
        internal approach, int_0^x F_n(x', 0) dx', plus the work done against
        its tangential force less that force's viscous part, W_t - Q_t; plus
        W_t - Q_t of every finished contact (``W_tq_finished``: MSF's
        tangential stiffness grows with the approach, so a contact exchanges
        energy between its normal and tangential motion and may end with W_t -
        Q_t of either sign). W_t - Q_t holds what Coulomb slip dissipated too
        (the work against a sliding force is not viscous), so after sliding
        contacts this exceeds the energy held by those losses (a tumbling PTFE
        cube ends 31 mJ above its mechanical energy, experiments objects).
        Kinetic plus potential energy plus this changes only by the contacts'
        viscous normal and tangential losses (it falls) and by the work of
        external forces; a rise is work the integration did not see. Not
        k |s|^2 / 2 for the tangential spring: that rises by |s|^2 dk / 2 with
        no work as k grows with the approach (tests/test_stored_energy.py)."""
        pp = np.arange(len(self.pairs))
        return IslandBalance.stored(self, pp) + IslandBalance.finished(self, pp)

    def refresh_law(self, law: ForceLaw, before: ForceLaw | None = None) -> None:
        """The compiled kernel's constants of ``law`` taken again from it: a
        law whose constants change between steps (engines._narrow.SideEndLaw's
        pose, set_pose) is refreshed after each change so that the compiled
        path computes what its numpy methods do. A law no pair has: nothing.

        ``before``: the law as it was before the change (a copy). Its pairs in
        contact then keep their elastic energy, not their approach: x moves to
        the approach at which ``law`` stores what ``before`` stored at x
        (state.approach_of_energy). A change of a law's constants is no force
        acting on the bodies, so it may not change the energy the contact holds:
        a capsule side's end share W_end grows as the side turns flat at a
        fixed approach of the end (SideEndLaw), and the pose held through a
        contact in motion is taken up when the contact settles; gymnasium's
        Hopper-v5 turned its foot from 3.9 to 0.63 deg over 111 ms of such a
        contact, its end's force at x = 2.06 mm went from 249 N to 754 N in
        one step and RestEnergy rose 0.33 J (issue 13, docs/engines.md). The
        tangential spring keeps its energy k |s|^2 / 2 along each of the law's
        axes the same way (s scaled by sqrt(k_before / k_now)). The
        surface still recovering after a force-zero end keeps its approach
        x_r (it decays at E'/(3 eta'_E), ~1 ms for rubber)."""
        g = id(law)
        if g not in self._groups:
            return
        k = self._kidx.get(g)
        if k is not None:
            self._kernel_law[g] = kl = kernel_law(law)
            self._kLC[k] = kl[1]
        if before is None:
            return
        rows = np.flatnonzero((self._group_of == g) & self.active & (self.x > 0.0))
        if rows.size == 0:
            return
        at = self._pos[rows]
        o = TakenOnset(self._onset[g], lambda arr: arr[at])
        x = self.x[rows]
        E = elastic_energy(before, x, o)
        moved = np.abs(elastic_energy(law, x, o) - E) > ENERGY_APPROACH_RTOL * E  # a pose that changed nothing: skip
        if not np.any(moved):
            return
        m = np.flatnonzero(moved)
        q, om = rows[m], {key: arr[m] for key, arr in o.items()}
        self.x[q] = x1 = approach_of_energy(law, E[m], x[m], om)
        # the tangential spring likewise keeps k |s|^2 / 2 along each of the law's axes (its stiffness
        # follows the law's constants too: the Hopper's foot end's held 142 N became 444 N at the same s)
        n = self._normal[q]
        ok = np.linalg.norm(n, axis=1) > 0.0
        if not np.any(ok):
            return
        q, n, x0, x1 = q[ok], n[ok], x[m][ok], x1[ok]
        om = {key: arr[ok] for key, arr in om.items()}
        k0, _ = before.tangential_stiffness(x0, om)
        k1, _ = law.tangential_stiffness(x1, om)
        t1, t2 = _tangent_basis(n)
        T = np.stack([t1, t2], axis=1)  # (k, 2, 3): the law's axes a, b as the kernels take them
        s2 = np.einsum("kai,ki->ka", T, self.s[q])
        s2 *= np.sqrt(np.where(k1 > 0.0, k0 / np.where(k1 > 0.0, k1, 1.0), 1.0))
        self.s[q] = np.einsum("ka,kai->ki", s2, T) + _dot(self.s[q], n)[:, None] * n

    def set_law(self, pair_index: int, law: ForceLaw) -> None:
        """Give pair ``pair_index`` the law ``law`` from its next onset on (a
        curvature per contact point: an adapter whose narrow phase finds the
        point where the pair's law was not built for, issue 13). Only between
        contacts: a pair in contact keeps its law (ValueError); a finished
        contact's record was made with its own law. The pair joins ``law``'s
        group (created on first use, compiled when the kernel knows it)."""
        p = int(pair_index)
        if not 0 <= p < len(self.pairs):
            raise ValueError(f"pair_index = {pair_index!r} is outside [0, {len(self.pairs) - 1}]")
        if not isinstance(law, ForceLaw):
            raise ValueError(f"law = {law!r} is not a msf_contact ForceLaw")
        g = id(law)
        if self._group_of[p] == g:
            return
        if self.active[p]:
            raise ValueError(f"pair {p} is in contact: its law changes only between contacts")
        self.x_res[p] = 0.0  # the recovering surface (state.RECOVERY_DOC) was the last contact's point's
        if g not in self._groups:
            self._groups[g] = law
            self._onset[g] = {}
            self._group_size[g] = 0
            self._kernel_law[g] = kernel_law(law) if self.compiled else None
            if self._kernel_law[g] is not None:
                code, lc = self._kernel_law[g]
                self._kcodes = np.append(self._kcodes, np.int64(code))
                self._kLC = np.vstack([self._kLC, np.asarray(lc, dtype=float).reshape(1, K.NLC)])
                self._kidx[g] = self._kcodes.size - 1
        pos = self._slot_pos.get((p, g))
        if pos is None:  # a new place in the group's onset arrays for this pair
            pos = self._slot_pos[(p, g)] = self._group_size[g]
            self._group_size[g] = pos + 1
            store = self._onset[g]
            for key in store:
                store[key] = np.append(store[key], np.nan)
        self._group_of[p] = g
        self._pos[p] = pos
        self._kg_of_pair[p] = self._kidx.get(g, -1)
        self._all_kernel = bool(np.all(self._kg_of_pair >= 0))
        self.pairs[p] = dataclasses.replace(self.pairs[p], law=law)
    def _own_gaps(self, pair, x, n, v, a, W=None) -> np.ndarray:
        """The gaps (k,) [m] the step starts from: a pair not in contact that was
        a candidate in the last step (and that the adapter marks in ``own_gap``)
        keeps the manager's own gap from the end of that step, relaxed toward the engine's x by settle_rate
        and never past touching (a bouncing row's kept gap ratchets so: gaps.KEPT_GAP_DOC, which also flags
        a kept gap the engine's bodies are found inside). The engine's semi-implicit Euler moves a body by dt v_end, so
        after a step in which its velocity changed by dv its gap leads the
        integrated one by up to dt |dv| / 2 (a light ball rattling between two
        stiff contacts: up to 0.4 mm at 1 ms); taken as is, a contact would
        begin already that deep, with elastic energy no force worked for
        (engines._contacts.balance; tests/test_pile.py). Only where the two differ
        by no more than twice that lead, dt/2 (|x'_end - x'_start| + |a_n| dt) a
        step, summed over the steps the manager's x was used (in contact, or a
        kept gap, whose sum decays by settle_rate), plus TOUCH_TOL: a larger
        difference is not the integrator's (a narrow phase's point beyond its
        margin, a face or point that changed) and the engine's gap is taken.
        A contact that ended at force zero with x > 0 (a viscoelastic surface
        not yet recovered) restarts from min(g, x_r(t0)), g the kept gap and
        x_r the surface's recovery since the end (state.RECOVERY_DOC), not
        from the engine's x (the objects scenario's cylinder on its side: its
        ends, chattering at 1 ms, began up to 7 um deep, 0.17 mJ a step; issue
        13) and no longer from touching (the offset g - 0 between the
        engine's and the internal x was never paid back)."""
        # compiled (engines._kernel.own_gaps: one pass, no (k,) temporaries; the same arithmetic), the
        # two dot products too (engines._kernel.approach_rates: in einsum's order)
        k = pair.shape[0]
        xd0_new, an_new = np.empty(k), np.empty(k)
        K.approach_rates(pair, v, self.dv_corr, a, n, xd0_new, an_new)
        out = np.empty_like(x)
        # x~ = x - (dt/2) x'_0: the engine's x less its half-step lead, the gap the integration follows
        # (gaps.KEPT_GAP_DOC); sh: the rows on which it is exact (a free sphere on a fixed body)
        xt = x - 0.5 * self.dt * xd0_new
        sh = self._shadow_rows(pair)
        # the rows the never-silent check may concern (gaps.KeptGapCheck: a kept gap with the engine's
        # bodies inside each other beyond their half-step lead), with the manager's gap before the step
        cand = np.flatnonzero(xt > 0.0)
        if cand.size:
            q = pair[cand]
            # the rows whose kept gap follows x~ (sh): a link's point moves with its joints, whose limits,
            # drives and pushes act inside the step the free flight does not see, a box's corner with its
            # turn (the adapters' DeepOnsets flags what those leave)
            cand = cand[~self.active[q] & self._listed[q] & sh[cand]]
            xm_before = self.x[pair[cand]]
        K.own_gaps(pair, x, self.x, self.active, self._listed, self.own_gap, self.xdot, self._xd0, self._an,
                   self._off, xd0_new, an_new, self.dt, self.settle_rate, TOUCH_TOL, out)
        if cand.size and W is not None:  # kept: out is the kept gap (<= 0), not the engine's x
            kept = out[cand] != x[cand]
            self._kept_check.check(self, pair[cand], kept, xt[cand], xm_before, xd0_new[cand], n[cand], W[cand])
        # the kept overlaps the kernel clamped to touching (out = 0 where x != 0: a kept gap g >= 0) of
        # pairs whose surface is still recovering start from min(g, x_r(t0), x) (state.RECOVERY_DOC; g in
        # the kernel's arithmetic; never deeper than the engine's own overlap x)
        off = ~self.active[pair]
        self.x_surface_onset[pair[off]] = 0.0
        rec = np.flatnonzero(off & (self.x_res[pair] > 0.0) & (out == 0.0) & (x > 0.0))
        if rec.size:
            q = pair[rec]
            x_r = np.minimum(residual_indentation(self.x_res[q], self.k_res[q], self.t_res[q], self._t_now), x[rec])
            xm = self.x[q]
            out[rec] = np.minimum(xm + self.settle_rate * (x[rec] - xm), x_r)
            self.x_surface_onset[q] = x_r
        return out

    def _shadow_rows(self, pair) -> np.ndarray:
        """(k,) bool: the rows on which x~ is the gap the integration follows (gaps.KEPT_GAP_DOC): a free sphere (own_gap,
        settle_rigid, its orientation free) on a fixed body (a coupling key -1; without coupling blocks,
        set_coupling, each body has one pair and any such row)."""
        sh = self.own_gap[pair] & self.settle_rigid[pair] & self.orientation_free[pair].all(axis=1)
        if self._coupling is None:
            return sh
        return sh & (self._coupling[0][pair] < 0).any(axis=1)

    def residual_rows(self, pp, t: float | None = None) -> np.ndarray:
        """x_r(t) [m] (k,) of the pairs pp: the recovering surface of each one's last
        contact (state.RECOVERY_DOC), 0 for a pair in contact or with none; t [s]
        defaults to the current step's start."""
        pp = np.asarray(pp)
        t = self._t_now if t is None else t
        x_r = residual_indentation(self.x_res[pp], self.k_res[pp], self.t_res[pp], t)
        return np.where(self.active[pp], 0.0, x_r)

    def held(self, pair, t_next: float) -> np.ndarray:
        """Which of the pairs ``pair`` (k,) hold their force into the next step
        (starting at ``t_next``), for the adapters' a_ext: in contact at the end
        of this step, not in an island (whose forces are coupled explicitly),
        and either resting (older than SETTLE_AFTER_DURATIONS estimated
        durations, or on the settled path) or resolved by the engine step (an
        estimated duration of at least STEPS_PER_CONTACT_MIN steps). Their
        step-averaged force is the prediction of their force over the next
        step, so it stays in the other pairs' a_ext; an impact shorter than
        that (the whole contact, or most of it, inside a step) has already
        given its impulse and is left out."""
        act = self.active[pair]
        resting = (t_next - self.t_onset[pair]) > SETTLE_AFTER_DURATIONS * self.tau_est[pair]
        resolved = self.tau_est[pair] >= STEPS_PER_CONTACT_MIN * self.dt
        return act & (self.settled[pair] | resting | resolved)

    def _step_rows(self, pair, x, n, point, v, vc, W, Wc, a, t0, info, L=None) -> ContactForces:
        """Each row on its own (the compiled kernel or the numpy path per law);
        L (k, NL): the rows' moving contact points (state.LEVER_DOC) or None."""
        k = pair.shape[0]
        if self._all_kernel:
            force = self._step_compiled(pair, x, n, v, vc, W, Wc, a, t0, info, L)
            force /= self.dt
        else:
            force = np.zeros((k, 3))
            krows = np.flatnonzero(self._kg_of_pair[pair] >= 0)
            if krows.size:
                P = self._step_compiled(pair[krows], x[krows], n[krows], v[krows], vc[krows], W[krows], Wc[krows],
                                        a[krows], t0, info, None if L is None else L[krows])
                force[krows] = P / self.dt
            for g, law in self._groups.items():
                if self._kernel_law[g] is not None:
                    continue
                rows = np.flatnonzero(self._group_of[pair] == g)
                if rows.size == 0:
                    continue
                P = self._step_group(g, law, pair[rows], x[rows], n[rows], v[rows], vc[rows], W[rows], Wc[rows],
                                     a[rows], t0, info, None if L is None else L[rows])
                force[rows] = P / self.dt
        self.last_step_info = info
        return ContactForces(force=force, point=point.copy(), pair=pair.copy())

    # ------------------------------------------------------------ islands --
    def set_coupling(self, keys, blocks: Callable | None) -> None:
        """Solve contacts that share a moving body together (engines._contacts.islands).

        keys: (P, 2) int, a key per body of each pair (-1: fixed; the links of
        one articulated tree share their root's key). blocks(pp, pq) -> (W
        (b, 3, 3), Wc (b, 3, 3)): the cross inverse inertias J_p M^-1 J_q^T and
        J_c,p M^-1 J_q^T [1/kg] between the current step's contact points of
        the pairs pp (b,) and pq (b,) (p != q), called from inside ``step``.
        None switches it off (each contact on its own, the others through a_ext)."""
        if blocks is None:
            self._coupling = None
            return
        keys = np.asarray(keys, dtype=np.int64)
        if keys.shape != (len(self.pairs), 2):
            raise ValueError(f"keys has shape {keys.shape}; expected ({len(self.pairs)}, 2)")
        if not callable(blocks):
            raise ValueError(f"blocks = {blocks!r} must be callable or None")
        self._coupling = (keys, blocks)

    def set_together(self, together) -> None:
        """together: (P,) bool, the pairs whose connected contacts
        (set_coupling) are solved as one island also when all of them rest
        (engines._contacts.islands.islands); a connected set of resting
        contacts only that holds a pair not together takes the settled path
        one row at a time. None (the default): every pair, a body's resting
        contacts are solved in its island as its others (issue 13)."""
        if together is None:
            self._together = None
            return
        t = np.asarray(together, dtype=bool)
        if t.shape != (len(self.pairs),):
            raise ValueError(f"together has shape {t.shape}; expected ({len(self.pairs)},)")
        self._together = t

    def set_energy_probe(self, probe: Callable | None) -> None:
        """Check every island's energy over each step (engines._contacts.balance):
        probe(keys (b,) int) -> (T, U, q, m) (b,) each: kinetic [J] and gravitational
        potential [J] energy of the bodies with the manager's timing corrections
        taken out of their velocities, gravity's power m g . v [W] and the mass
        [kg]; NaN for a body it cannot account for. None switches the check off."""
        if probe is not None and not callable(probe):
            raise ValueError(f"probe = {probe!r} must be callable or None")
        self._balance = None if probe is None else IslandBalance(probe)

    @property
    def island_energy_gains(self) -> list:
        """Islands found with an energy gain: (t [s], pairs, gain [J], allowed [J])
        each (engines._contacts.balance; empty without an energy probe)."""
        return [] if self._balance is None else list(self._balance.gains)

    def flag_contact(self, p: int, note: str, t: float) -> None:
        """Put ``note`` in the outside_validity of pair p's contact that was in
        progress at time t [s]: the one still active, or its record if it ended
        since."""
        if self.active[p]:
            self._gain_note[p] = note
            return
        for rec in [e[1] for e in self._pending] + self.records[::-1]:
            if rec.inputs.get("pair") == p and rec.inputs.get("t_end", -np.inf) >= t:
                if note not in rec.outside_validity:
                    rec.outside_validity.append(note)
                return

    def note_next_contact(self, p: int, note: str) -> None:
        """Put ``note`` in the outside_validity of pair p's next contact (a pair
        not in contact: gaps.KeptGapCheck); the latest note is kept."""
        self._next_note[p] = note

    @property
    def kept_gap_flags(self) -> list:
        """Kept gaps the engine's bodies were found inside (gaps.KeptGapCheck):
        (t [s], pair, engine's overlap less its half-step lead [m], the
        manager's gap [m], that overlap's elastic energy [J], approach energy [J])
        per flagged row-step."""
        return list(self._kept_check.flags)

    def _cross_corrections(self, pair) -> None:
        """Bring dv_corr, dvc_corr (the engine's velocity offsets the last
        step's timing corrections J left, removed from what a row reads) to
        every row's full offset sum_q W_pq J_q, with the coupling blocks at
        this step's points, before the rows are stepped.

        Each path writes a row's offset at the end of its step from the
        corrections it knows: its own W J (a row alone, or stepped row by row
        in a resting component) or its island's sum_q W_pq J_q. Missing were
        (a) a row not listed in the last step: its offset was that of an
        older step (stale), and its own J is zero (a pair with J != 0 is
        always listed); (b) the cross terms W_pq J_q of rows q that were not
        in p's island in the last step (a row newly listed beside a body that
        just had a contact, the rows of a resting component). With them
        missing a row began its step from the engine's velocity with a
        neighbour's correction left in (a rubber ball in the 8-sphere pile
        read 0.055 m/s too fast toward the floor after a sphere-sphere
        impact on it, and as the manager keeps its own gap (_own_gaps) the
        contact began while the engine's spheres were still 55 um apart;
        tests/test_pile.py)."""
        stale = pair[~self._listed[pair]]
        self.dv_corr[stale] = 0.0
        self.dvc_corr[stale] = 0.0
        hasJ = np.any(self.J[pair] != 0.0, axis=1)
        if not np.any(hasJ):
            return
        keys = self._coupling[0][pair]
        lab = self._island_of[pair]
        by_key: dict[int, list[int]] = {}
        for r in range(pair.size):
            for b in keys[r]:
                if b >= 0:
                    by_key.setdefault(int(b), []).append(r)
        cp, cq = [], []
        for j in np.flatnonzero(hasJ).tolist():
            near = set()
            for b in keys[j]:
                if b >= 0:
                    near.update(by_key[int(b)])
            for i in sorted(near):
                if i != j and not (lab[i] >= 0 and lab[i] == lab[j]):
                    cp.append(i)
                    cq.append(j)
        if not cp:
            return
        cp, cq = np.array(cp, dtype=np.int64), np.array(cq, dtype=np.int64)
        Wpq, Wcpq = self._coupling[1](pair[cp], pair[cq])
        Wpq, Wcpq = as_array(Wpq, (3, 3)), as_array(Wcpq, (3, 3))
        Jq = self.J[pair[cq]]
        np.add.at(self.dv_corr, pair[cp], np.einsum("bij,bj->bi", Wpq, Jq))
        np.add.at(self.dvc_corr, pair[cp], np.einsum("bij,bj->bi", Wcpq, Jq))

    def _island_rows(self, pair, t0, n, v, W):
        """Island label per row for the rows in islands of two or more (others -1), or None."""
        keys = self._coupling[0][pair]
        kk = keys[keys >= 0]
        if kk.size < 2 or not np.any(np.bincount(kk) > 1):
            return None
        act = self.active[pair]
        age_ok = self._resting(pair, t0, n, v, W)
        lab = islands(pair, act, age_ok, keys, None if self._together is None else self._together[pair])
        counts = np.bincount(lab, minlength=pair.size)
        multi = np.where(counts[lab] > 1, lab, -1)
        self._rest_rows = age_ok
        return multi if np.any(multi >= 0) else None

    def _resting(self, pair, t0, n, v, W):
        """(k,) rows in a resting contact: older than SETTLE_AFTER_DURATIONS
        estimated durations and approaching slower than SETTLED_SPEED_RATIO v_x
        (the settled path's criterion); a resting contact that is hit is not."""
        act = self.active[pair]
        rest = act & ((t0 - self.t_onset[pair]) > SETTLE_AFTER_DURATIONS * self.tau_est[pair])
        if np.any(rest):
            r = np.flatnonzero(rest)
            vn = np.abs(_dot(v[r] - self.dv_corr[pair[r]], n[r]))
            xr = np.maximum(self.x[pair[r]], 0.0)
            nWn = np.einsum("ki,kij,kj->k", n[r], W[r], n[r])
            F = np.zeros(r.size)
            grp = self._group_of[pair[r]]
            side = side_kernel_rows(self, pair[r]) if self._batched_laws else np.zeros(r.size, bool)
            if np.any(side):  # the lying sides' ends of every group at once (the same values as below)
                _, inv, cnt = np.unique(grp, return_inverse=True, return_counts=True)
                F[side] = side_forces(self, pair[r][side], xr[side], (cnt[inv] == 1)[side])
            for g in np.unique(grp[~side]):
                sel = self._group_of[pair[r]] == g
                at = self._pos[pair[r][sel]]
                o = TakenOnset(self._onset[g], lambda arr: arr[at])
                F[sel] = self._groups[g].contact_normal_force(xr[sel], np.zeros(int(sel.sum())), o)
            vx = np.sqrt(np.maximum(F, 0.0) * xr * nWn)
            rest[r] = vn <= SETTLED_SPEED_RATIO * vx
        return rest

    def _step_with_islands(self, multi, pair, x, n, point, v, vc, W, Wc, a, t0, info, L=None) -> ContactForces:
        """Rows alone as _step_rows, islands by engines._contacts.islands, both
        with their moving contact points L (k, NL) or None."""
        k = pair.shape[0]
        force = np.zeros((k, 3))
        alone = np.flatnonzero(multi < 0)
        if alone.size:
            out = self._step_rows(pair[alone], x[alone], n[alone], point[alone], v[alone], vc[alone], W[alone],
                                  Wc[alone], a[alone], t0, info, None if L is None else L[alone])
            force[alone] = out.force
        keys_all = self._coupling[0]
        R, io, cio, cp, cq, Wpq, Wcpq, a_R = island_blocks(self, pair, multi, a)
        L = None if L is None else island_lever(L[R], n[R], W[R])  # by R's order from here
        pp_all = pair[R]
        info["island_rows"] += int(R.size)
        self.in_island[pp_all] = True
        self._island_of[pp_all] = multi[R]
        self._island_contact[pp_all] = True  # contacts that begin in it: Records._begin
        if self._balance is not None:  # each island's bodies, for one probe call
            bk = [np.unique(k[k >= 0]) for k in np.split(keys_all[pp_all], io[1:-1])]
            self._balance.open_many(self, pp_all, io, np.concatenate(bk), np.cumsum([0] + [b.size for b in bk]))
        # resting islands of free bodies (own_gap: the adapters' free spheres and free bodies on fixed
        # ones; links keep the RK4 island): every contact resting, the gaps listed beside them open (they
        # must stay open over the step: settle_island checks), one settled step of all their rows
        # (engines._contacts.resting), else RK4 below
        done = np.zeros(io.size - 1, bool)
        if self.settled_path and R.size:
            quiet = (self._rest_rows[R] | ~self.active[pp_all]) & self.own_gap[pp_all] & self.settle_rigid[pp_all]
            rest = np.logical_and.reduceat(quiet, io[:-1]) & np.logical_or.reduceat(self._rest_rows[R], io[:-1])
            for i in np.flatnonzero(rest):
                r = R[io[i]:io[i + 1]]
                e = slice(cio[i], cio[i + 1])
                P = settle_island(self, pair[r], x[r], n[r], v[r], vc[r], W[r], Wc[r], a_R[io[i]:io[i + 1]], t0,
                                  info, cp[e] - io[i], cq[e] - io[i], Wpq[e], Wcpq[e],
                                  None if L is None else L[io[i]:io[i + 1]])
                if P is not None:
                    force[r] = P / self.dt
                    done[i] = True
        # the compiled path for the islands whose every row's law the kernel knows (island_compiled)
        kern = np.zeros(io.size - 1, bool)
        if self.island_compiled:
            kern = np.logical_and.reduceat(self._kg_of_pair[pp_all] >= 0, io[:-1]) if R.size else kern
        kern &= ~done
        if np.any(kern):
            sel = np.flatnonzero(kern)
            rows = np.concatenate([np.arange(io[i], io[i + 1]) for i in sel])
            sizes = np.diff(io)[sel]
            io_k = np.r_[0, np.cumsum(sizes)].astype(np.int64)
            ent = np.concatenate([np.arange(cio[i], cio[i + 1]) for i in sel]).astype(np.int64)
            remap = np.full(R.size, -1, np.int64)
            remap[rows] = np.arange(rows.size)
            ncb = np.diff(cio)[sel]
            cio_k = np.r_[0, np.cumsum(ncb)].astype(np.int64)
            r = R[rows]
            P = step_islands(self, pair[r], x[r], n[r], v[r], vc[r], W[r], Wc[r], a_R[rows], t0, info, io_k, cio_k,
                             remap[cp[ent]], remap[cq[ent]], Wpq[ent], Wcpq[ent], self._rest_rows[r],
                             None if L is None else L[rows])
            force[r] = P / self.dt
        for i in np.flatnonzero(~kern & ~done):  # the numpy reference, island by island
            r = R[io[i]:io[i + 1]]
            e = slice(cio[i], cio[i + 1])
            P = step_island(self, pair[r], x[r], n[r], v[r], vc[r], W[r], Wc[r], a_R[io[i]:io[i + 1]], t0, info,
                            cp[e] - io[i], cq[e] - io[i], Wpq[e], Wcpq[e], self._rest_rows[r],
                            None if L is None else L[io[i]:io[i + 1]])
            force[r] = P / self.dt
        self.last_step_info = info
        return ContactForces(force=force, point=point.copy(), pair=pair.copy())

    def _invalid(self, code, row, pair, x, n, point, v, vc, W, Wc, a):
        """Raise the ValueError for what :func:`engines._kernel.check` found."""
        if code == 1:
            raise ValueError(f"kinematics.pair = {pair!r} has indices outside [0, {len(self.pairs) - 1}]")
        if code == 2:
            raise ValueError(f"kinematics.pair = {pair!r} lists a pair twice (one contact per pair)")
        if code == 3:
            for name, arr in (("x", x), ("normal", n), ("point", point), ("v_rel", v), ("v_com_rel", vc),
                              ("W", W), ("W_com", Wc), ("a_ext", a)):
                if not np.all(np.isfinite(arr[row])):
                    raise ValueError(f"kinematics.{name} is not finite: {arr!r}")
        if code == 4:
            raise ValueError(f"kinematics.normal must be unit vectors, norms {np.linalg.norm(n, axis=1)!r}")
        if code == 5:
            missing = np.flatnonzero((self.active | np.any(self.J != 0.0, axis=1)) & ~np.isin(
                np.arange(len(self.pairs)), pair))
            raise ValueError(f"kinematics.pair = {pair!r} lacks pairs {missing!r} that are in contact or have a "
                             "timing correction to remove: list manager.required_pairs every step")
        raise RuntimeError(f"engines._kernel.check returned an unknown code {code!r}")
