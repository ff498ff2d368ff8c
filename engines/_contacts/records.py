"""Onsets and impact records of :class:`engines._contacts.ContactManager`:
the onset constants and bookkeeping of a new contact (:meth:`Records._begin`,
both paths), the :class:`msf_contact.ImpactRecord` of a finished one
(:meth:`Records._end`, in the reference solver's format) and its
completion once the engine has applied the contact's last impulse
(body probe, ``spin_out``)."""

from __future__ import annotations

import math
import warnings

import numpy as np

from msf_contact import closed_forms as cf
from msf_contact._validate import ValidityWarning, small_strain_note
from msf_contact.geometry import area
from msf_contact.record import ImpactRecord

from .. import _kernel as K
from .state import (
    ENERGY_GAIN_RTOL, _Q, _WEL, _WT, _WVI, _X, PENDING_MAX_STEPS, V_ONSET_MIN, elastic_energy, ROTATION_PER_STEP_MAX,
    SUBSTEPS_PER_CONTACT, SUBSTEPS_PER_TANGENTIAL, _duration_estimate, _pc, _plain, _Rows, onset_speed_floor,
    onset_stiffness, surface_recovery_rate_one,
)

#: Pairs whose leaving the small-strain range (x_max/R, 2R) is warned one by
#: one on stderr; past it one more warning says the rest are only in their
#: records' outside_validity. Ten lines name a scene's typical culprits; a jet
#: of deep beads otherwise printed one line per pooled pair (270 in make bench).
STRAIN_WARN_PAIRS = 10


#: An onset speed past the law's range is brought below it to this share of
#: itself [-] (Records._onset_in_range: a bisection on the law's own refusal).
ONSET_CAP_RTOL = 1e-6


def _as_rows(val, k: int) -> np.ndarray:
    """val as a float (k,) array: itself when it is one already (np.broadcast_to's
    Python costs more than the rest of an onset's bookkeeping), else broadcast."""
    if type(val) is np.ndarray and val.dtype == np.float64 and val.shape == (k,):
        return val
    return np.broadcast_to(np.asarray(val, dtype=float), (k,))


class Records:
    """Onsets and records (mixed into :class:`engines._contacts.ContactManager`)."""

    def _onset_in_range(self, law, pp, v, m):
        """law.onset(v, m) for the new contacts of pairs pp (k,) at onset speeds v
        (k,) [m/s] and effective masses m (k,) [kg]; a contact whose speed takes
        the msf approach past 2R before maximum compression (the law raises: k_p
        = sqrt(2 - x/R) of (15) has no real value beyond) gets the constants of
        the largest speed the law accepts (bisection to ONSET_CAP_RTOL), its
        k_p is clamped as it deepens (ForceLaw.kp) and it is flagged: its
        record's outside_validity says so, and stderr once per pair, naming
        the pair, dt and what to change. A robot's run is not ended by one
        deep contact. Returns (onset dict, capped (k,) bool, speeds used (k,))."""
        try:
            return law.onset(v, m), np.zeros(v.shape, bool), v
        except ValueError as exc:  # only the refusal at 2R is capped; bad input still raises
            if law.x_limit is None or "2R" not in str(exc) or not np.all(np.isfinite(v)):
                raise
        v = np.array(v, dtype=float)
        capped = np.zeros(v.shape, bool)
        for i in range(v.size):
            try:
                law.onset(v[i:i + 1], m[i:i + 1])
                continue
            except ValueError:
                pass
            hi, lo = float(v[i]), 0.5 * float(v[i])
            for _ in range(64):  # a speed the law accepts (the approach scales as v^(4/5))
                try:
                    law.onset(np.array([lo]), m[i:i + 1])
                    break
                except ValueError:
                    hi, lo = lo, 0.5 * lo
            else:
                raise ValueError(f"pair {int(pp[i])}: the law refuses every onset speed down to {lo:.3g} m/s "
                                 f"(mass {float(m[i]):.4g} kg)")
            while hi - lo > ONSET_CAP_RTOL * hi:
                mid = 0.5 * (lo + hi)
                try:
                    law.onset(np.array([mid]), m[i:i + 1])
                    lo = mid
                except ValueError:
                    hi = mid
            q = int(pp[i])
            if not self._capped_warned[q]:
                self._capped_warned[q] = True
                warnings.warn(
                    f"pair {q} ({self.pair_names[q][0]}, {self.pair_names[q][1]}), dt = {self.dt:g} s: a contact "
                    f"began at {v[i]:.4g} m/s, where the msf approach passes 2R = {law.x_limit:.4g} m before maximum "
                    f"compression (k_p = sqrt(2 - x/R) of (15) has no real value beyond): its onset constants are "
                    f"those of {lo:.4g} m/s, the largest the law accepts, k_p is clamped as it deepens, and its "
                    "record is flagged. If the speed is not physical (a body gaining energy, a coarse dt), take a "
                    "smaller dt; else give the pair a larger radius, a stiffer material or kp_mode 'hertz' "
                    "(warned once per pair)", ValidityWarning, stacklevel=4)
            v[i], capped[i] = lo, True
        return law.onset(v, m), capped, v

    def pop_records(self) -> list[ImpactRecord]:
        """Completed impacts since the last call, and forget them (see ``pending_count``)."""
        self._finish_pending()
        out, self.records = self.records, []
        return out

    @property
    def pending_count(self) -> int:
        """Finished contacts whose record waits for the body-level probe: with a
        probe installed, a record is completed at the start of the second step
        after the contact ended, once the timing correction has left the
        engine's velocities (``spin_out`` is then the physical spin)."""
        return len(self._pending)

    def _begin(self, g, law, p, new, y, batch, t_abs):
        """Onset of the contacts at rows new: law.onset for all of them at once
        (the per-row arithmetic and bookkeeping around it compiled:
        engines._kernel.onset_pre, onset_post)."""
        pp = p[new]
        k = pp.size
        self.W_in[pp] = batch.W[new]
        m, vn, a_n = np.empty(k), np.empty(k), np.empty(k)
        bad = K.onset_pre(new, batch.n, batch.W, batch.a, y, m, vn, a_n)
        if bad >= 0:
            nWn = np.einsum("ki,kij,kj->k", batch.n[new], batch.W[new], batch.n[new])
            raise ValueError(f"n.W.n = {nWn!r} 1/kg must be > 0 (both bodies fixed, or W is wrong)")
        K_floor = self._floor_K.get(g)
        if K_floor is None:
            K_floor = self._floor_K[g] = onset_stiffness(law)
        v_used = np.maximum(vn, onset_speed_floor(law, m, a_n, K_floor))
        o, capped, v_used = self._onset_in_range(law, pp, v_used, m)
        # store per pair (group arrays created on first use)
        store = self._onset[g]
        size = self._group_size[g]
        pos = self._pos[pp]
        o_new = {}
        for key, val in o.items():
            val = _as_rows(val, k)  # a law's scalar or list broadcast
            o_new[key] = val
            if key not in store:
                store[key] = np.full(size, np.nan)
            store[key][pos] = val
        if not isinstance(batch, _Rows):  # the numpy path's batch carries its rows' onset constants
            batch.onset = {key: arr[self._pos[p]] for key, arr in store.items()}
        # duration estimate -> internal step, and the bookkeeping
        tau_n = _as_rows(_duration_estimate(law, o, m, v_used), k)
        x_est = cf.hertz_x_max(m, v_used, law.moduli.E, law.geom.R)
        k_t, _ = law.tangential_stiffness(x_est, o_new)
        K.onset_post(pp, new, batch.n, batch.W, y, _as_rows(t_abs, k), vn, v_used,
                     m, tau_n, np.asarray(k_t, dtype=float).reshape(k, 2), float(SUBSTEPS_PER_CONTACT),
                     float(SUBSTEPS_PER_TANGENTIAL), self._point, self.in_island, self._island_contact,
                     self.tau_est, self.v_n_in, self.v_n_used, self.m_eff, self.n_in, self.p_in, self.u_in,
                     self.vc_in, self.x_onset, self.turned, self.outside, self._fl, np.empty((2, 3)))
        # a contact that resumes in the step in which its pair's last contact ended at force zero still
        # overlapping resumes on the surface that end left indented (state.RECOVERY_DOC: inside a step the free
        # flight takes that surface at the body, so nothing restarts and no energy is created): its onset's
        # x_surface_onset is that surface's indentation, the body's x, at most the end's overlap x_res
        res = (self.x_res[pp] > 0.0) & (self.t_res[pp] >= self._t_now)
        if res.any():
            q = pp[res]
            self.x_surface_onset[q] = np.minimum(np.maximum(self.x_onset[q], 0.0), self.x_res[q])
        if capped.any():  # an onset past the law's range: flagged from the start
            self.outside[pp[capped]] = True
        for q in pp.tolist():  # a note left for this contact while the pair was apart (note_next_contact)
            self._gain_note[q], self._next_note[q] = self._next_note[q], None
        if self._probe is not None:
            for q in pp:
                self.body_in[int(q)] = dict(self._probe(int(q)) or {})
        else:
            for q in pp:
                self.body_in[int(q)] = None

    def _end(self, p, ye, t_end, ended_by, n):
        """Close the contact of pair p with the state ye (NY,) at time t_end
        (scalar arithmetic on Python floats: this runs once per impact)."""
        law = self.pairs[p].law
        g = self._group_of[p]
        pos = self._pos[p]
        onset = {k: float(v[pos]) for k, v in self._onset[g].items()}
        yl, nl = ye.tolist(), n.tolist()
        # the pair's per-contact floats of the kernel's block (manager: self._fl, rows K.F_*) in one read
        fl = self._fl[:, p].tolist()
        turned = bool(self.turned[p])
        x_max, F_max, x_at_F, f_min = fl[K.F_XMAX], fl[K.F_FMAX], fl[K.F_XATF], fl[K.F_FMIN]
        W_el_comp, W_visc_comp = fl[K.F_WELC], fl[K.F_WVIC]
        v = yl[1:4]
        xd_end = -(v[0] * nl[0] + v[1] * nl[1] + v[2] * nl[2])
        v_out = max(-xd_end, 0.0)
        v_n_in, v_n_used = float(self.v_n_in[p]), float(self.v_n_used[p])
        vin = v_n_in if v_n_in > 0 else v_n_used
        tau = t_end - fl[K.F_TONSET]
        tau1 = fl[K.F_TAU1] if turned else tau
        u_in = self.u_in[p].tolist()
        u_out = [v[i] + xd_end * nl[i] for i in range(3)]
        lu = math.sqrt(u_in[0] ** 2 + u_in[1] ** 2 + u_in[2] ** 2)
        vct = self.vc_in[p].tolist()
        lv = math.sqrt(vct[0] ** 2 + vct[1] ** 2 + vct[2] ** 2)
        scale = max(vin, lu, lv)
        cor_t_contact = (-(u_out[0] * u_in[0] + u_out[1] * u_in[1] + u_out[2] * u_in[2]) / lu**2
                         if lu > 1e-12 * scale else None)
        vc_end = yl[7:10]
        cor_t = ((vc_end[0] * vct[0] + vc_end[1] * vct[1] + vc_end[2] * vct[2]) / lv**2
                 if lv > 1e-12 * scale else None)
        x_m = fl[K.F_XTURN] if turned else x_max
        outside = []
        x_lim = law.x_limit
        if self.outside[p] or (x_lim is not None and x_max >= x_lim):
            if x_lim is not None and x_max >= x_lim:
                outside.append(f"x_max = {x_max:.6g} m reached 2R: k_p = sqrt(2 - x/R) of (15) was clamped")
            else:  # an onset past the law's range (_onset_in_range)
                outside.append(f"onset speed {self.v_n_in[p]:.6g} m/s past the law's range (the msf approach would "
                               f"pass 2R before maximum compression): onset constants of {self.v_n_used[p]:.6g} m/s")
        strain = small_strain_note(x_m, law.geom.R)
        if strain:
            outside.append(strain)
        if outside and not self._strain_warned[p]:
            # the record says it; stderr says it too, once per pair, for the first STRAIN_WARN_PAIRS pairs,
            # then once that more pairs are flagged (a jet of deep beads flagged 270 pairs, one line each)
            self._strain_warned[p] = True
            n_warned = int(np.count_nonzero(self._strain_warned))
            if n_warned <= STRAIN_WARN_PAIRS:
                warnings.warn(f"pair {p} ({self.pair_names[p][0]}, {self.pair_names[p][1]}), dt = {self.dt:g} s: "
                              + "; ".join(outside) + " (warned once per pair; every record carries it in "
                              "outside_validity)", ValidityWarning, stacklevel=2)
            elif n_warned == STRAIN_WARN_PAIRS + 1:
                warnings.warn(f"pair {p} ({self.pair_names[p][0]}, {self.pair_names[p][1]}), dt = {self.dt:g} s: "
                              + "; ".join(outside) + f" -- more than {STRAIN_WARN_PAIRS} pairs have left the "
                              "small-strain range; the others are not warned one by one: every record carries its "
                              "note in outside_validity (count them there)", ValidityWarning, stacklevel=2)
        stand_in = getattr(law, "validity_note", None)  # a contact no law carries, by a stand-in curvature
        if stand_in:
            outside.append(stand_in)
        if self._gain_note[p]:
            outside.append(self._gain_note[p])
        gain = self._energy_gain(p, vin, v_out, lu, yl[_WT], v, yl[_WEL] + yl[_WVI])
        if gain:
            outside.append(gain)
            warnings.warn(gain, ValidityWarning, stacklevel=2)
        kl = self._kernel_law[g]
        if kl is not None and kl[0] != K.CODE_SIDE:  # a line contact's area: the numpy path's
            Pc, Pc_F = K.peak_pressures(kl[0], kl[1], self._oc, p, x_m, x_at_F, F_max,
                                        self._scr_rk4[0])
        else:
            Pc = _pc(law, x_m, {k: np.array([v]) for k, v in onset.items()})
            S = float(area(self.x_at_F[p], law.geom, law.kp_mode)) if self.x_at_F[p] > 0 else 0.0
            # a line footprint's width closes at x = 2R (a box corner driven past it onto its edge, flagged
            # outside the small-strain range): its area there is 0 and the peak pressure unbounded
            Pc_F = 1.5 * self.F_max[p] / S if S > 0.0 else (math.inf if self.x_at_F[p] > 0 else 0.0)
        W_el, W_vi = yl[_WEL], yl[_WVI]
        self.W_tq_finished[p] += yl[_WT] - yl[_Q]  # engines._contacts.balance: kept past the contact's end
        # the surface left indented at a force-zero end recovers (state.RECOVERY_DOC)
        k_rec = surface_recovery_rate_one(onset) if ended_by == "force-zero" else 0.0
        self.x_res[p] = yl[_X] if (k_rec > 0.0 and yl[_X] > 0.0) else 0.0
        self.t_res[p], self.k_res[p] = t_end, k_rec
        params = self._params.get(g)
        if params is None:
            params = self._params[g] = law.parameters()
        rec = ImpactRecord(
            cor_n=v_out / vin,
            cor_t=cor_t,
            cor_t_contact=cor_t_contact,
            cor_tau_ratio=tau1 / (tau - tau1) if tau > tau1 else 0.0,
            tau=float(tau), tau1=float(tau1), tau2=float(tau - tau1),
            x_max=x_m, F_max=F_max, Pc_max=Pc, Pc_at_Fmax=float(Pc_F),
            W_el_comp=W_el_comp, W_visc_comp=W_visc_comp,
            W_el_rest=-(W_el - W_el_comp), W_visc_rest=W_vi - W_visc_comp,
            W_diss_n=W_el + W_vi, W_diss_t=yl[_WT], Q_t=yl[_Q],
            spin_in=None, spin_out=None,
            f_min=f_min if math.isfinite(f_min) else None,
            f_max=fl[K.F_FMAXR] if math.isfinite(f_min) else None,
            omega_x=onset.get("omega_x"), omega_y=onset.get("omega_y"),
            ended_by=ended_by, law=law.name, engine=self.engine, dt=self.dt,
            parameters=dict(params),
            inputs={
                "pair": p, "body1": self.pair_names[p][0], "body2": self.pair_names[p][1],
                "t_onset": fl[K.F_TONSET], "t_end": float(t_end),
                "v_n_in": v_n_in, "v_n_onset_used": v_n_used,
                "v_t_in": lu, "mass_effective": float(self.m_eff[p]), "tangential": self.pairs[p].tangential,
                "internal_step": fl[K.F_H], "tau_estimate": float(self.tau_est[p]),
                "x_max_overall": x_max, "x_onset": float(self.x_onset[p]), "onset": onset,
                # the recovering surface of the last contact at the onset step's start (state.RECOVERY_DOC)
                "x_surface_onset": float(self.x_surface_onset[p]),
                "point": self.p_in[p].tolist(), "normal": self.n_in[p].tolist(),
                "island": bool(self._island_contact[p]),  # began inside an island (engines._contacts.islands)
            },
            outside_validity=outside,
        )
        self.active[p] = False
        # spin axis n x t of the incidence (rolling in the direction of incidence positive)
        # (at exactly 90 deg the centre's tangential velocity is zero: the contact point's slip
        # -spin x R then points backward, so the tangent of incidence is -u_in, as the reference solver's)
        t_dir = vct if lv > 0 else [-c for c in u_in]
        lt = lv if lv > 0 else lu
        if lt > 0:
            a0 = self.n_in[p].tolist()
            t = [c / lt for c in t_dir]
            axis = np.array([a0[1] * t[2] - a0[2] * t[1], a0[2] * t[0] - a0[0] * t[2], a0[0] * t[1] - a0[1] * t[0]])
        else:
            axis = np.zeros(3)
        bi = self.body_in[p]
        if bi is not None:
            rec.inputs["body_in"] = {k: _plain(v) for k, v in bi.items()}
            if "omega1" in bi and lt > 0:
                rec.spin_in = float(np.asarray(bi["omega1"], dtype=float) @ axis)
        if self._probe is None:
            self._publish(p, rec)
        else:  # completed once the engine has applied the contact's last impulse (see pending_count)
            self._pending.append([p, rec, axis if lt > 0 else None, 0])

    def _energy_gain(self, p, vin, v_out, lu, W_t, v_end, W_n) -> str | None:
        """The reason a finished contact of pair p ended with more kinetic
        energy than it began with, beyond ENERGY_GAIN_RTOL, or None: normal
        (v_out > v_in) or tangential (negative W_diss_t). Checked for a
        contact alone (in an island, energy passes between the contacts) that
        began at a closing speed of its own (not the onset floor).

        A normal COR above 1 is energy gained only if the relative motion of
        the contact points gained it: where n W t != 0 (a link hit at a lever
        arm while sliding) the friction impulse changes the normal velocity
        too, and a contact that dissipated most of its energy can leave along
        n faster than it came (gymnasium's Ant-v5: an ankle sliding at 5 m/s,
        COR 1.019 with 1.38 J of its 1.63 J dissipated, the friction impulse
        giving +1.49 m/s of the normal velocity change against the normal
        force's +0.76 m/s; docs/engines.md). So the normal check also asks
        that the energy of the relative motion, 1/2 v . W^-1 v (v the contact
        points' relative velocity (3,), W their inverse inertia at onset,
        W^+ where the bodies cannot move: a planar walker; the kinetic energy
        the bodies have in the directions the contact acts, Stronge's
        energetic view of impact), rose by more than the bound beyond what
        the contact's forces took from it (W_diss_n + W_diss_t): that excess
        is work done from outside the contact (a_ext)."""
        if self._island_contact[p]:
            return None
        if not (self.v_n_in[p] > 0 and self.v_n_in[p] >= self.v_n_used[p]):
            return self._deep_start_gain(p, v_out)
        m = float(self.m_eff[p])
        E_in = 0.5 * m * (vin * vin + lu * lu)
        dE_n = 0.5 * m * (v_out * v_out - vin * vin)
        normal = dE_n > ENERGY_GAIN_RTOL * E_in
        if normal:  # the relative motion's energy (docstring): the friction's share is no gain
            v_in = self.u_in[p] - self.v_n_in[p] * self.n_in[p]
            K = np.linalg.pinv(self.W_in[p])
            ve = np.asarray(v_end, dtype=float)
            E0 = 0.5 * float(v_in @ K @ v_in)
            normal = 0.5 * float(ve @ K @ ve) - E0 + W_n + W_t > ENERGY_GAIN_RTOL * E0
        if not normal and -W_t <= ENERGY_GAIN_RTOL * E_in:
            return None
        names = self.pair_names[p]
        what = (f"normal COR {v_out / vin:.6g} > 1" if normal
                else f"tangential energy grew by {-W_t:.3g} J")
        return (f"energy gained in a contact: pair {p} ({names[0]}, {names[1]}), dt = {self.dt:g} s: "
                f"{what} (more than {ENERGY_GAIN_RTOL:g} of its {E_in:.3g} J): work from outside the contact "
                "(a_ext), e.g. another stiff contact on the same body acting a step late; give the adapter's "
                "coupling blocks (ContactManager.set_coupling) or take a smaller dt")

    def _deep_start_gain(self, p, v_out) -> str | None:
        """The reason a contact of pair p that began already overlapping, at
        no closing speed of its own (a body placed, reset or written into
        overlap: its onset is the manager's floor, so :meth:`_energy_gain`'s
        COR check has no approach speed to compare), left with more normal
        kinetic energy than it came with, beyond ENERGY_GAIN_RTOL of its
        approach energy 1/2 m max(v_in, V_ONSET_MIN)^2, from the elastic
        energy of its overlap at the onset (int_0^x0 F_n(x', 0) dx', never
        worked for: engines._contacts.balance), or None. A body placed at
        its static overlap and left there ends no contact and is not
        flagged; one placed deeper is launched by that energy (a rubber
        ball, R = 50 mm, placed 20 mm into a steel floor in MuJoCo rose 2 m,
        flagged before only as x_max/R = 0.4 above the small-strain bound;
        pybullet_data's soccerball.urdf, R = 0.5 m, loaded 0.2 m into
        plane.urdf left with 14.5 kJ). Links (DeepOnsets flags them in their
        step) are not flagged twice."""
        x0 = float(self.x_onset[p])
        note = self._gain_note[p]
        if x0 <= 0.0 or (note and "deep at its onset" in note):
            return None
        m = float(self.m_eff[p])
        v0 = float(self.v_n_in[p])
        v0 = v0 if v0 > 0.0 else 0.0
        E_in = 0.5 * m * max(v0, V_ONSET_MIN) ** 2
        gain = 0.5 * m * (v_out * v_out - v0 * v0)
        if not gain > ENERGY_GAIN_RTOL * E_in:
            return None
        g, pos = self._group_of[p], self._pos[p]
        with np.errstate(all="ignore"):  # metres deep: the energy may overflow (still flagged)
            E_el = float(elastic_energy(self._groups[g], np.array([x0]),
                                        {k: v[pos:pos + 1] for k, v in self._onset[g].items()})[0])
        names = self.pair_names[p]
        return (f"energy gained in a contact: pair {p} ({names[0]}, {names[1]}), dt = {self.dt:g} s: it began "
                f"{x0:.3g} m deep at {v0:.3g} m/s and left at {v_out:.3g} m/s, {gain:.3g} J gained from the "
                f"elastic energy of that overlap, {E_el:.3g} J, which no force worked for: a body placed, reset or "
                "written overlapping the other (start bodies clear of each other, or at their static overlap: "
                "msf_contact.static_overlap), a contact point found inside the other body (a narrow phase's: "
                "check the pair's shapes), or a body moved into overlap within a step (take a smaller dt)")

    def interrupt(self, pairs, why: str) -> int:
        """The engine's state jumped for the bodies of ``pairs`` (pair
        indices (k,); a reset, or positions or velocities set by the user):
        forget every contact of those pairs that was in progress at the start
        of the last step, those still active and those that ended in it
        (their records are dropped: half a contact is no impact), with their
        timing corrections; complete the records of their contacts that ended
        earlier without the body-level output (``why`` says why). Returns the
        number of contacts dropped."""
        sel = np.zeros(len(self.pairs), bool)
        sel[np.asarray(pairs, dtype=int)] = True
        idx = np.flatnonzero(sel)  # (index arrays: boolean masks over all pairs cost ~1 ms a call for the jet's 35,511)
        dropped = int(np.count_nonzero(self.active[idx]))
        keep = []
        for entry in self._pending:
            p, rec, _axis, waited = entry
            if not sel[p]:
                keep.append(entry)
            elif waited == 0:  # ended in the last step
                dropped += 1
            else:
                rec.inputs["body_out"] = None
                rec.inputs["body_out_unavailable"] = why
                self._publish(p, rec)
        self._pending = keep
        if self._hist:
            for p in idx.tolist():
                self._hist.pop(p, None)
        self.active[idx] = False
        self.settled[idx] = False
        self.J[idx] = 0.0
        self.dv_corr[idx] = 0.0
        self.dvc_corr[idx] = 0.0
        self._held_force[idx] = 0.0
        self.in_island[idx] = False
        self._island_of[idx] = -1
        self._listed[idx] = False
        if self._balance is not None:  # a state jump is not an island's work (engines._contacts.balance)
            self._balance.forget(idx)
        self._off[idx] = 0.0
        self.x_res[idx] = 0.0  # the surfaces' recovery (state.RECOVERY_DOC) was before the jump
        return dropped

    def _rotation_note(self, p: int, rec: ImpactRecord) -> str | None:
        """The ``outside_validity`` reason for pair p's record when a body whose
        contact depends on its orientation (not exempt by ``orientation_free``)
        turned more than ROTATION_PER_STEP_MAX per engine step, at the
        contact's start or after its end (the probe's ``omega1``/``omega2``
        [rad/s] in ``body_in``/``body_out``), else None."""
        free = self.orientation_free[p]
        if free[0] and free[1]:  # neither body's orientation matters: nothing to flag
            return None
        worst = (0.0, 0)
        for key in ("body_in", "body_out"):
            body = rec.inputs.get(key) or {}
            for i in (0, 1):
                w = body.get(f"omega{i + 1}")
                if w is not None and not self.orientation_free[p, i]:
                    speed = math.sqrt(sum(float(c) * float(c) for c in w))
                    worst = max(worst, (speed, i))
        speed, i = worst
        if speed * self.dt <= ROTATION_PER_STEP_MAX:
            return None
        return (f"rotation per step: {self.pair_names[p][i]} (pair {p}) turns |omega| dt = {speed * self.dt:.3g} rad "
                f"per engine step (|omega| = {speed:.4g} rad/s, dt = {self.dt:g} s), above pi/4: pybullet limits a "
                f"turn per step to pi/4 and the contact sub-cycle holds the step-start contact geometry, so the "
                f"orientation this contact depends on is not resolved (take dt <= "
                f"{ROTATION_PER_STEP_MAX / speed:.3g} s)")

    def _publish(self, p: int, rec: ImpactRecord) -> None:
        """Move a completed record to ``records`` (with its force history when
        kept), flagging a rotation per step beyond ROTATION_PER_STEP_MAX
        (warned once per pair)."""
        note = self._rotation_note(p, rec)
        if note:
            rec.outside_validity.append(note)
            if not self._rotation_warned[p]:
                self._rotation_warned[p] = True
                warnings.warn(note, ValidityWarning, stacklevel=3)
        hist = self._hist.pop(p, None)
        if self.history and hist:
            t_on = float(rec.inputs.get("t_onset", 0.0))
            rec.inputs["curves"] = {"t": [t - t_on for t, _ in hist], "F_n": [f for _, f in hist],
                                    "kind": "step-averaged", "dt": self.dt}
        self.records.append(rec)

    def _finish_pending(self, at_step_start: bool = False):
        """Complete the records whose pair has no timing correction in the engine
        any more (its velocities are the physical ones): read the probe, move
        them to ``records``. At a step start a record that waited
        PENDING_MAX_STEPS steps (a new contact of the same pair keeps a
        correction going) is completed without the body-level output."""
        keep = []
        probe = self._probe if at_step_start or self._probe_batch is None else None
        J = self.J
        for entry in self._pending:
            if at_step_start:
                entry[3] += 1
            p, rec, axis, waited = entry
            if waited >= 1:
                j0, j1, j2 = J[p].tolist()  # J[p].any() on Python floats (NaN counts as non-zero in both)
                clean = not (j0 or j1 or j2)
            else:
                clean = False
            if clean:
                if self._probe is not None:
                    if probe is None:  # the first record of a batch between steps
                        probe = self._probe_batch()
                    bo = dict(probe(p) or {})
                    rec.inputs["body_out"] = {k: _plain(v) for k, v in bo.items()}
                    if "omega1" in bo and axis is not None:
                        rec.spin_out = float(np.asarray(bo["omega1"], dtype=float) @ axis)
                self._publish(p, rec)
            elif waited > PENDING_MAX_STEPS:
                rec.inputs["body_out"] = None
                rec.inputs["body_out_unavailable"] = (
                    "the pair was in contact again before its bodies' post-impact state could be read")
                self._publish(p, rec)
            else:
                keep.append(entry)
        self._pending = keep
