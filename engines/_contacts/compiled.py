"""The compiled path of :class:`engines._contacts.ContactManager`: the rows of
every law the kernel knows (:func:`kernel_law`) go through one call of
:mod:`engines._kernel` per stop (onset or separation); ``law.onset`` and
the records stay in Python (:mod:`.records`). The numpy path
(:mod:`.reference`) is its readable reference."""

from __future__ import annotations

import math

import numpy as np

from msf_contact.laws import ForceLaw, HertzLaw, HuntCrossleyLaw, KuwabaraKonoLaw, MSFLaw, SpringDashpotLaw

from .. import _kernel as K
from .._narrow import RimArcLaw, SideEndLaw
from .state import (
    _P, F_RATIO_FLOOR, MAX_SEGMENTS, NY, ROOT_ITER, ROOT_TOL, SETTLE_AFTER_DURATIONS, SETTLED_FD_REL,
    SETTLED_NEWTON_MAX, SETTLED_SPEED_RATIO, SETTLED_VTOL, _Rows,
)

#: The tuning constants of :mod:`.state`, in the order of engines._kernel's C_* indices.
_KCST = np.array([SETTLED_SPEED_RATIO, SETTLED_NEWTON_MAX, SETTLED_VTOL, SETTLED_FD_REL, F_RATIO_FLOOR, ROOT_ITER,
                  ROOT_TOL, SETTLE_AFTER_DURATIONS], dtype=float)
_KP_MODES = {"msf": K.KP_MSF, "msf-small": K.KP_SMALL, "hertz": K.KP_HERTZ}
_KERNEL_CODES = {MSFLaw: K.CODE_MSF, HertzLaw: K.CODE_HERTZ, KuwabaraKonoLaw: K.CODE_KK,
                 HuntCrossleyLaw: K.CODE_HC, SpringDashpotLaw: K.CODE_SD}
#: The methods whose registry versions the kernel compiles: a subclass that
#: overrides any of them runs on the numpy path.
_KERNEL_METHODS = ("normal_force", "separation_indicator", "tangential_stiffness", "tangential_force",
                   "contact_normal_force", "kp", "psi", "shear_lengths", "outside")


def kernel_law(law: ForceLaw):
    """(code, constants (NLC,)) of the compiled kernel for this law, or None
    when the kernel does not know it (a class outside the registry, or a
    registry class with a force method overridden): that law runs on the
    numpy path. An engines._narrow.SideEndLaw (a lying side's line law) is
    CODE_SIDE with the constants of its current pose (tilt, rise: set_pose;
    its adapter refreshes them every step, ContactManager.refresh_law): its
    width and shear lengths as SideEndLaw's in engines._kernel.forces; a
    RimArcLaw (a slot of a cylinder's rim ring) is CODE_SIDE with its ring
    constants (LC_SRING set)."""
    if type(law) is SideEndLaw or type(law) is RimArcLaw:
        code = K.CODE_SIDE
    else:
        base = next((c for c in _KERNEL_CODES if isinstance(law, c)), None)
        if base is None:
            return None
        t = type(law)
        if any(getattr(t, m, None) is not getattr(base, m, None) for m in _KERNEL_METHODS):
            return None
        if law.kp_mode not in _KP_MODES or law.geom.footprint is not None:  # another line contact: numpy path
            return None
        code = _KERNEL_CODES[base]
    g = law.geom
    lc = np.zeros(K.NLC)
    lc[K.LC_RA], lc[K.LC_RB], lc[K.LC_KHA], lc[K.LC_KHB] = g.R_a, g.R_b, g.k_ha, g.k_hb
    lc[K.LC_MU] = math.nan if law.mu is None else float(law.mu)
    lc[K.LC_K] = float(getattr(law, "K", 0.0))
    lc[K.LC_A] = float(getattr(law, "A", 0.0))
    lc[K.LC_GM], lc[K.LC_RM] = law.moduli.G, g.R
    lc[K.LC_FZ] = 1.0 if law.separation == "force-zero" else 0.0
    lc[K.LC_KPMODE] = _KP_MODES[law.kp_mode]
    lc[K.LC_SRA], lc[K.LC_SRB] = math.sqrt(g.R_a), math.sqrt(g.R_b)
    if code == K.CODE_SIDE:  # SideEndLaw._width_one's constants at the pose
        law.fill_kernel_constants(lc)
    return code, lc


class CompiledPath:
    """ContactManager's compiled path (mixed into :class:`engines._contacts.ContactManager`)."""

    def _step_compiled(self, p, x_eng, n, v, vc, W, Wc, a, t0, info, L=None):
        """_step_group for the rows of every law the kernel knows, in one
        call of the compiled kernel (engines._kernel); law.onset and the
        records stay here, called for the rows the kernel stops at."""
        kg, codes, LC = self._kg_of_pair[p], self._kcodes, self._kLC
        dt = self.dt
        k = p.shape[0]
        paper = self._paper[p]
        y = np.empty((k, NY))
        T = np.empty((k, 2, 3))
        t_loc = np.empty(k)
        in_c = np.empty(k, bool)
        settled = np.empty(k, bool)
        status = np.empty(k, np.int8)
        ended_by = np.zeros(k, np.int8)
        ints = np.zeros(4, np.int64)
        fl, oc = self._fl, self._oc
        if L is None:  # no moving contact point (state.LEVER_DOC): a zero buffer the kernel only reads
            if self._L0.shape[0] < k:
                self._L0 = np.zeros((k, K.NL))
            L = self._L0[:k]
        K.prelude(_KCST, p, x_eng, n, v, vc, W, Wc, a, paper, L, t0, dt, self.settle_rate, self.settled_path, kg, codes,
                  LC, oc, self.active, self.settled, self.x, self.s, self.tau_est, self.dv_corr, self.dvc_corr, self.W_el,
                  self.W_visc, self.Q_t, self.W_t, y, T, t_loc, in_c, settled, status, self.turned, fl, ints,
                  *self._scr_settled)
        for _ in range(MAX_SEGMENTS):
            info["segments"] += 1
            stopped = K.advance(_KCST, p, n, T, W, Wc, a, paper, L, kg, codes, LC, oc, t0, dt, self.h, y, t_loc, in_c,
                                status, ended_by, self.turned, fl, ints, *self._scr_rk4)
            if not stopped:
                break
            ended = np.flatnonzero(status == K.ST_ENDED)
            for r, pr, tl, eb in zip(ended.tolist(), p[ended].tolist(), t_loc[ended].tolist(),
                                     ended_by[ended].tolist()):
                self._end(pr, y[r], t0 + tl, "force-zero" if eb == K.END_FORCE else "overlap-zero", n[r])
            in_c[ended] = False
            new_all = np.flatnonzero(status == K.ST_ONSET)
            if new_all.size:
                grp = self._group_of[p[new_all]]
                rows = _Rows(n, W, a)
                for g in (grp[:1] if np.all(grp == grp[0]) else np.unique(grp)):
                    new = new_all[grp == g]
                    self._begin(g, self._groups[g], p, new, y, rows, t0 + t_loc[new])
                    store, pp = self._onset[g], p[new]
                    pos = self._pos[pp]
                    for j, key in enumerate(K.ONSET_KEYS[self._kernel_law[g][0]]):
                        oc[pp, j] = store[key][pos]
                in_c[new_all] = True
                info["onsets"] += int(new_all.size)
        else:
            raise RuntimeError(f"more than {MAX_SEGMENTS} contact onsets/separations in one step of {dt!r} s")
        impulse = np.empty((k, 3))
        K.finale(p, n, W, Wc, settled, in_c, y, dt, self.timing_correction, kg, LC, self.active, self.x, self.xdot,
                 self.s, self.vc, self.W_el, self.W_visc, self.Q_t, self.W_t, self.phase, self.outside,
                 self.settled, self.J, self.dv_corr, self.dvc_corr, impulse, self.couple)
        info["settled"] += int(ints[0])
        info["settled_iterations"] += int(ints[1])
        info["substeps"] += int(ints[2])
        info["ends"] += int(ints[3])
        if self.history:
            Pn = np.einsum("ki,ki->k", y[:, _P], n) / dt
            for r in np.flatnonzero(np.any(y[:, _P] != 0.0, axis=1)):
                self._hist.setdefault(int(p[r]), []).append((t0, float(Pn[r])))
        return impulse
