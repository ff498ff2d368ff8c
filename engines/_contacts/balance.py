"""The energy balance of an island over one engine step (issue 10 item 4,
"never silent"): an island of contacts solved together
(:mod:`.islands`) that ends a step with more kinetic + potential + stored
energy than it began with, beyond a named tolerance, is flagged on its
records and warned once, naming the pairs, dt and what to change.

What is compared. The island's bodies (their keys, :meth:`ContactManager.set_coupling`)
carry E_b = kinetic + gravitational potential energy, read by the adapter's
energy probe (:meth:`ContactManager.set_energy_probe`) at the start of the
step and at the start of the next one, both with the manager's timing
corrections taken out of the engine's velocities (the corrections are a
velocity offset for one step, engines._contacts). The contacts hold
S = sum over the island's rows in contact of E_el(x) + W_t - Q_t: the
elastic energy int_0^x F_n(x', 0) dx' of the normal force at the internal
overlap x (a state function, so a contact begun already overlapping, whose
work W_el since onset never saw the energy from 0 to x, counts it), plus the
work against the tangential force less its viscous part (the stored
tangential energy plus what slip dissipated). Inside the step the island
integrates

    dKE = -(dW_el + dW_visc + dW_t)          (the contacts' forces on the bodies)

and dW_el = dE_el along the step's continuous x, so E + S changes by
-(dW_visc + dQ_t) <= 0: viscous and slip losses only (a contact that ends
at force zero leaves its elastic energy in the surface, which recovers and
dissipates it, state.RECOVERY_DOC: E_el(x_r) is counted while it falls, a
loss, and a contact resuming on that surface takes it back). A contact that
ends keeps its W_t - Q_t in S (``ContactManager.W_tq_finished``, summed over
the pair's finished contacts): MSF's tangential spring F_t = -k(x) s - b s'
has a stiffness that grows with the overlap, so it stores k' x' |s|^2 / 2
that no tangential work put in and gives it back as the overlap falls; over
a rubber contact W_t - Q_t ends negative (the reference solver, rubber on
steel, R = 10 mm, 0.2 m/s at 20 deg: W_t 1.02e-5 J, Q_t 1.10e-5 J). That is
the law's exchange between its normal and tangential motion, not work the
integration missed; dropped at the end it read as a gain of up to 3.3e-5 J
in one step of the 8-sphere pile (scripts/pile.py), and flagged islands. A
rise is work the island's integration did not see: an onset found already
overlapping (its stored energy F dx from 0 to x was never worked), the
settle relaxation of a resting row's x toward the engine's, a contact of
another island or a held force acting on the island's bodies a step late, a
drive or the engine's own contact. The rows whose contact begins inside the
step give their last contact's S back first (it is reset at onset).

Tolerance. ``ENERGY_GAIN_RTOL`` (1e-3, the per-contact bound) of the
island's kinetic + stored energy at the step start, and at least 0.5 m
V_ONSET_MIN^2 per body (the manager's smallest onset speed: touching bodies
at rest exchange round-off, 1e-34 J measured in a resting cradle), plus the engines'
semi-implicit (symplectic) Euler step: it moves a body by dt v_end, not by
the mean velocity, so its position leads the exact one by dt/2 times its
velocity change within the step, and gravity's potential is off by
dt/2 |m g . dv| per body (``q`` of the probe: the gravity power m g . v, so
the bound is dt/2 |q_end - q_start|). Islands holding a link of a chain
(joint springs and drives do work the probe does not see) are not checked
where the adapter gives no probe value for it (MuJoCo's adapter); pybullet's
gives a multibody's account as the work its contacts' loads did on it less
the timing corrections' offset energy, so its island's E + S is the
contacts' own balance (engines.pybullet.adapter._energy_probe). Nor is an
island whose body jumped between the step and the next step start (placed
or reset by the caller, seen by the adapters' jump detection:
:meth:`IslandBalance.forget`; the jet's pool parks a particle whose impact
is over by setting it moving at the park velocity, which read as a gain of
up to its whole kinetic energy).
"""

from __future__ import annotations

import warnings

import numpy as np

from msf_contact._validate import ValidityWarning

from .state import ENERGY_GAIN_RTOL, V_ONSET_MIN, TakenOnset, elastic_energy

#: A gain this many times the largest one warned so far is warned again: the first gain of a run is often
#: small (a contact found a few um deep), and a later gain of joules must not hide behind it on stderr
#: (a rubber cube dropped on a free cube in MuJoCo: 1.4 mJ warned at t = 0.152 s, then 2.96 J at t = 0.165 s
#: only on the records). Ten keeps a run's stderr to a few lines per decade of gain.
REWARN_FACTOR = 10.0


class IslandBalance:
    """Per-step energy bookkeeping of a manager's islands (see the module docstring).

    probe(keys (b,) int) -> (T (b,) [J], U (b,) [J], q (b,) [W], m (b,) [kg]):
    kinetic and gravitational potential energy of each body with the timing
    corrections taken out, gravity's power m g . v on it, and its mass; NaN
    for a body it cannot account for (the island is then not checked)."""

    def __init__(self, probe):
        self.probe = probe
        self._open: list[tuple] = []  # (pairs (k,), keys (b,), E0, q0, S0 + reset work, scale)
        #: islands found with an energy gain: (t [s], pairs, gain [J], allowed [J])
        self.gains: list[tuple[float, tuple, float, float]] = []
        self.warned = False
        #: the largest gain warned so far [J] (a larger one by REWARN_FACTOR is warned again)
        self.warned_gain = 0.0
        self.checked = 0  #: island steps checked
        self.discarded = 0  #: island steps not checked: a body jumped before the step's end was read (forget)
        #: island steps not checked because the probe gave no value for one of their bodies (a link of a
        #: chain), and the pairs of those islands; the adapters say so (PybulletAdapter.island_energy_unchecked)
        self.unchecked = 0
        self.unchecked_pairs: set[int] = set()

    @staticmethod
    def finished(mgr, pp) -> float:
        """W_t - Q_t of the finished contacts of the rows pp, summed over the
        run [J] (ContactManager.W_tq_finished; module docstring)."""
        return float(np.sum(mgr.W_tq_finished[np.asarray(pp)]))

    @staticmethod
    def stored(mgr, pp) -> float:
        """S of the rows pp (module docstring) [J]: for each row in contact, the
        elastic energy of its normal force at its internal overlap plus W_t - Q_t."""
        return float(np.sum(IslandBalance.stored_rows(mgr, pp)))

    @staticmethod
    def stored_rows(mgr, pp) -> np.ndarray:
        """S of each row of pp (k,) [J] (:meth:`stored` summed per row: for a row not in contact,
        the elastic energy E_el(x_r) its surface still holds while it recovers from a force-zero end,
        state.RECOVERY_DOC, else 0)."""
        pp = np.asarray(pp)
        out = np.zeros(pp.size)
        on = np.flatnonzero(mgr.active[pp])
        x_r = mgr.residual_rows(pp)
        rec = np.flatnonzero(x_r > 0.0)  # a surface still recovering from a force-zero end: its E_el(x_r)
        if on.size == 0 and rec.size == 0:
            return out
        q = pp[on]
        out[on] = mgr.W_t[q] - mgr.Q_t[q]
        rows = np.concatenate([on, rec])
        xe = np.concatenate([np.maximum(mgr.x[q], 0.0), x_r[rec]])
        gid = mgr._group_of[pp[rows]]
        for g in np.unique(gid):
            sel = np.flatnonzero(gid == g)
            at = mgr._pos[pp[rows[sel]]]
            o = TakenOnset(mgr._onset[g], lambda arr: arr[at])
            out[rows[sel]] += elastic_energy(mgr._groups[g], xe[sel], o)
        return out

    def open_many(self, mgr, pp, io, keys, ko) -> None:
        """:meth:`open` for several islands at once, with one probe call: island i
        has rows pp[io[i]:io[i+1]] and bodies keys[ko[i]:ko[i+1]] (the islands'
        bodies are distinct); S0 of each from :meth:`stored_rows`."""
        if io.size < 2:
            return
        probed = [np.asarray(a, dtype=float) for a in self.probe(keys)]
        # S0 only of the islands the probe accounts for (open leaves the others unchecked, S0 unread: a
        # robot's links, every step of a walker at rest; each row's energy is its own, so the islands'
        # sums are the same as over all rows)
        fin = np.logical_and.reduce([np.isfinite(a) for a in probed])
        ok = np.logical_and.reduceat(fin, ko[:-1]) if fin.size else np.zeros(io.size - 1, bool)
        S = np.zeros(io.size - 1)
        if np.all(ok):
            S = np.add.reduceat(self.stored_rows(mgr, pp), io[:-1]) if pp.size else S
        elif np.any(ok):
            sel = np.flatnonzero(ok)
            rows = np.concatenate([np.arange(io[i], io[i + 1]) for i in sel])
            S[sel] = np.add.reduceat(self.stored_rows(mgr, pp[rows]), np.r_[0, np.cumsum(np.diff(io)[sel])[:-1]])
        for i in range(io.size - 1):
            b = slice(ko[i], ko[i + 1])
            self.open(mgr, pp[io[i]:io[i + 1]], keys[b], float(S[i]), [a[b] for a in probed])

    def open(self, mgr, pp, keys, S0: float, probed=None) -> None:
        """An island of rows pp (k,) on bodies keys (b,) begins its step
        (before it is integrated); S0 its rows' stored energy now; probed: the
        probe's (T, U, q, m) of keys if read already."""
        T0, U0, q0, m = (np.asarray(a, dtype=float) for a in (self.probe(keys) if probed is None else probed))
        if not all(np.all(np.isfinite(a)) for a in (T0, U0, q0, m)):  # a body the probe cannot account for
            self.unchecked += 1
            self.unchecked_pairs.update(int(p) for p in np.asarray(pp).reshape(-1))
            return
        # the scale of the relative tolerance: kinetic energy and the normal energy stored in contact, at
        # least the kinetic energy of the bodies at the manager's smallest onset speed (round-off below it)
        scale = (float(T0.sum()) + abs(float(np.sum(mgr.W_el[pp][mgr.active[pp]])))
                 + 0.5 * float(m.sum()) * V_ONSET_MIN**2 / ENERGY_GAIN_RTOL)
        self._open.append((np.asarray(pp).copy(), np.asarray(keys).copy(), float(T0.sum() + U0.sum()), q0,
                           S0 + self.finished(mgr, pp), scale))

    def forget(self, pairs) -> None:
        """Drop the open islands holding any of ``pairs`` (k,) (indices): their
        bodies' state jumped between the step and the next step start (a
        reset, a placement: ContactManager.interrupt, from the adapters' jump
        detection), so a body's energy there was set from outside the step
        (the jet's pool parks a bead whose impact is over by setting it
        moving at the park velocity: up to its whole kinetic energy). Such an
        island is not checked; counted in ``discarded``."""
        pairs = np.asarray(pairs)
        keep = [o for o in self._open if not np.any(np.isin(o[0], pairs))]
        self.discarded += len(self._open) - len(keep)
        self._open = keep

    def close(self, mgr, t_start: float) -> None:
        """At the start of the next step (the engine has applied the step):
        compare each island's E + S with its start; flag and warn on a gain."""
        if not self._open:
            return
        opened, self._open = self._open, []
        # one probe call and one stored-energy pass for all the islands (their bodies are distinct)
        ko = np.cumsum([0] + [o[1].size for o in opened])
        io = np.cumsum([0] + [o[0].size for o in opened])
        probed = [np.asarray(a, dtype=float) for a in self.probe(np.concatenate([o[1] for o in opened]))]
        pp_all = np.concatenate([o[0] for o in opened])
        S1 = np.add.reduceat(self.stored_rows(mgr, pp_all), io[:-1]) if pp_all.size else np.zeros(len(opened))
        for i, (pp, keys, E0, q0, S0, scale) in enumerate(opened):
            T1, U1, q1, _m = (a[ko[i]:ko[i + 1]] for a in probed)
            if not all(np.all(np.isfinite(a)) for a in (T1, U1, q1)):
                continue
            self.checked += 1
            gain = (float(T1.sum() + U1.sum()) + float(S1[i]) + self.finished(mgr, pp)) - (E0 + S0)
            allowed = ENERGY_GAIN_RTOL * scale + 0.5 * mgr.dt * float(np.sum(np.abs(q1 - q0)))
            if gain > allowed:
                self._flag(mgr, pp, t_start, gain, allowed)

    def _flag(self, mgr, pp, t, gain, allowed) -> None:
        names = [f"{int(p)} ({mgr.pair_names[int(p)][0]}, {mgr.pair_names[int(p)][1]})" for p in pp]
        note = (f"island energy gained: pairs {', '.join(names)}, dt = {mgr.dt:g} s: kinetic + potential + stored "
                f"energy rose by {gain:.3g} J in the step ending at t = {t + mgr.dt:.6g} s (allowed {allowed:.3g} J): "
                "work the island did not integrate (a contact found already overlapping, a force of another "
                "island or a drive acting a step late); take a smaller dt")
        self.gains.append((float(t), tuple(int(p) for p in pp), float(gain), float(allowed)))
        for p in pp:
            mgr.flag_contact(int(p), note, t)
        if not self.warned or gain > REWARN_FACTOR * self.warned_gain:
            again = (f"; {len(self.gains) - 1} island step(s) gained before, the largest warned "
                     f"{self.warned_gain:.3g} J" if self.warned else "")
            self.warned = True
            self.warned_gain = max(self.warned_gain, float(gain))
            warnings.warn(note + f" (warned again only for a gain {REWARN_FACTOR:g} times the largest warned{again}; "
                          "every one is flagged on its records and listed in ContactManager.island_energy_gains)",
                          ValidityWarning, stacklevel=3)


class DeepOnsets:
    """Never silent about a contact found deep at its onset (both adapters):
    a contact of the pairs ``mask`` that began in a step already overlapping
    by an x whose elastic energy int_0^x F_n(x', 0) dx' (never worked for:
    the module docstring) exceeds ENERGY_GAIN_RTOL of its approach energy
    1/2 m v_n^2 (at least 1/2 m V_ONSET_MIN^2) is flagged in its
    outside_validity and warned once per pair, in the step it began. Which
    pairs: those no other check covers in that step (links of chains, whose
    island the energy check leaves out, and narrow-phase points, whose
    detection has no closed form behind it); ``count`` counts them."""

    def __init__(self):
        self.count = 0
        self._warned: set[int] = set()
        self._flagged_at: dict[int, float] = {}

    def check(self, mgr, mask, t0: float, why: str, names, stacklevel: int = 3) -> list[int]:
        """Flag the contacts of the pairs ``mask`` (P,) bool that began in
        [t0, t0 + dt) that deep; ``why`` the sentence saying what put them
        there and what to change; names: each pair's name for the warning.
        Returns the pairs flagged now."""
        new = np.flatnonzero(mask & (mgr.x_onset > 0.0) & (mgr.t_onset >= t0) & (mgr.t_onset < t0 + mgr.dt))
        out = []
        for p in new.tolist():
            if self._flagged_at.get(p) == float(mgr.t_onset[p]):
                continue
            x = float(mgr.x_onset[p])
            g = mgr._group_of[p]
            pos = mgr._pos[p]
            onset = {k: v[pos:pos + 1] for k, v in mgr._onset[g].items()}
            with np.errstate(all="ignore"):  # a contact found metres deep: its energy may overflow (flagged)
                stored = float(elastic_energy(mgr._groups[g], np.array([x]), onset)[0])  # as ContactManager.stored_energy
            approach = 0.5 * float(mgr.m_eff[p]) * max(float(mgr.v_n_in[p]) ** 2, V_ONSET_MIN ** 2)
            if stored <= ENERGY_GAIN_RTOL * approach:  # (a NaN or inf energy is flagged)
                continue
            self._flagged_at[p] = float(mgr.t_onset[p])
            note = (f"contact found {x:.3g} m deep at its onset (dt = {mgr.dt:g} s): its elastic energy there, "
                    f"{stored:.3g} J, was never worked for ({stored / approach:.3g} of its approach energy "
                    f"{approach:.3g} J): {why}")
            mgr.flag_contact(p, note, float(mgr.t_onset[p]))
            self.count += 1
            out.append(p)
            if p not in self._warned:
                self._warned.add(p)
                warnings.warn(f"pair {p} {names[p]}: {note} (warned once per pair; adapter.deep_onsets counts "
                              "them)", ValidityWarning, stacklevel=stacklevel)
        return out
