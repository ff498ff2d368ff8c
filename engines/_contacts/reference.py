"""The numpy path of :class:`engines._contacts.ContactManager`: the readable
reference of the compiled kernel (:mod:`engines._kernel`).

The algorithm of the package docstring written once, vectorised over the
rows of one law group: :class:`_Batch` holds a group's constants and the
right-hand side dy/dt of the contact ODE (the law's F_n and F_t, W f +
a_ext, the works), :func:`_find_root` locates onsets, maximum compression
and separations, and :class:`NumpyPath` (methods of ContactManager) steps a
group through one engine step: free flight, sub-cycled RK4, the settled
path. The kernel repeats the same steps per row in scalar arithmetic; a law
the kernel does not know (a class outside the registry, or one with a
force method overridden) runs here, and ``ContactManager(compiled=False)``
runs every law here (tests/test_kernel.py asserts both paths agree).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from msf_contact.laws import ForceLaw

from .resting import book_records
from .state import (
    initial_state, lever_start,
    _G, _P, _PD, _PI, _Q, _S, _V, _VC, _WEL, _WT, _WVI, _X, F_RATIO_FLOOR, L_ON, L_W01, L_W11, L_XREF, MAX_SEGMENTS, NY, ROOT_ITER, ROOT_TOL,
    SETTLE_AFTER_DURATIONS, SETTLED_FD_REL, SETTLED_NEWTON_MAX, SETTLED_SPEED_RATIO, SETTLED_VTOL, _dot,
    _msf_inline, _tangent_basis,
)


@dataclass
class _Batch:
    """Constants of k contact rows of one law over one engine step."""

    law: ForceLaw
    n: np.ndarray  # (k, 3)
    t1: np.ndarray  # (k, 3)
    t2: np.ndarray  # (k, 3)
    W: np.ndarray  # (k, 3, 3)
    Wc: np.ndarray  # (k, 3, 3)
    a: np.ndarray  # (k, 3)
    paper: np.ndarray  # (k,) bool
    onset: dict = field(default_factory=dict)  # key -> (k,)
    L: np.ndarray | None = None  # (k, NL): the moving contact point (state.LEVER_DOC), None: none

    def __post_init__(self):
        self.T = np.stack([self.t1, self.t2], axis=1)  # tangent basis (k, 2, 3)
        self.any_paper = bool(np.any(self.paper))
        self.inline = _msf_inline(self.law)
        self.lever = self.L is not None and bool(np.any(self.L[:, L_ON] != 0.0))
        if self.lever:
            k = self.L.shape[0]
            self.W01 = self.L[:, L_W01:L_W01 + 9].reshape(k, 3, 3)
            self.W11 = self.L[:, L_W11:L_W11 + 9].reshape(k, 3, 3)
            self.on = self.L[:, L_ON] != 0.0

    @property
    def plain_tangential(self) -> bool:
        """The law uses ForceLaw.tangential_force unchanged (so it may be inlined)."""
        return type(self.law).tangential_force is ForceLaw.tangential_force

    def sub(self, idx) -> "_Batch":
        return _Batch(self.law, self.n[idx], self.t1[idx], self.t2[idx], self.W[idx], self.Wc[idx],
                      self.a[idx], self.paper[idx], {k: v[idx] for k, v in self.onset.items()},
                      None if self.L is None else self.L[idx])

    def _forces(self, x, xd):
        """F_n after the separation rule, its elastic part F_n(x, 0) (k,) [N],
        and the tangential stiffness and damping (k, 2) of the law."""
        law, o = self.law, self.onset
        if self.inline:
            # MSFLaw.normal_force, .shear_lengths, .tangential_stiffness with shared k_p and sqrt(x)
            g = law.geom
            kpa = law.kp(x, g.R_a)
            kpb = kpa if g.R_b == g.R_a else law.kp(x, g.R_b)
            base = (kpa * math.sqrt(g.R_a) + kpb * math.sqrt(g.R_b)) * np.sqrt(x)
            el = (2.0 / 3.0) * o["E"] * x
            F = base * (2.0 * o["eta_E"] * xd + el)
            Fn = np.maximum(F, 0.0) if law.separation == "force-zero" else F
            Fc = base * el
            P_bx = g.k_ha * x + 2.0 * kpb * np.sqrt(g.R_b * x)
            P_ax = g.k_hb * x + 2.0 * kpa * np.sqrt(g.R_a * x)
            G = o["G"]
            k = np.stack([G * P_bx, G * P_ax], axis=-1)
            b = np.stack([o["eta_Gy"] * P_bx, o["eta_Gz"] * P_ax], axis=-1)
            return Fn, Fc, k, b
        Fn = law.contact_normal_force(x, xd, o)
        Fc = law.normal_force(x, np.zeros_like(xd), o)
        k, b = law.tangential_stiffness(x, o)
        return Fn, Fc, k, b

    def rhs(self, y):
        """dy/dt (k, NY), F_n (k,), |F_t| (k,)."""
        law, n = self.law, self.n
        x = np.maximum(y[:, _X], 0.0)
        v, vc = y[:, _V], y[:, _VC]
        xd = -_dot(v, n)
        Fn, Fc, k, b = self._forces(x, xd)
        vt = v + xd[:, None] * n
        sd = np.where(self.paper[:, None], vc - _dot(vc, n)[:, None] * n, vt) if self.any_paper else vt
        s2 = np.einsum("kij,kj->ki", self.T, y[:, _S])
        sd2 = np.einsum("kij,kj->ki", self.T, sd)
        if self.plain_tangential:
            # ForceLaw.tangential_force inlined: one stiffness evaluation gives F_t and the power b s'^2
            Ft2 = -(b * sd2 + k * s2)
            if law.mu is not None:
                cap = law.mu * np.maximum(Fn, 0.0)
                mag = np.hypot(Ft2[:, 0], Ft2[:, 1])
                Ft2 = Ft2 * np.where(mag > cap, cap / np.where(mag > 0, mag, 1.0), 1.0)[:, None]
        else:
            Ft2, _ = law.tangential_force(x, s2, sd2, self.onset, Fn)
        Ft = np.einsum("ki,kij->kj", Ft2, self.T)
        f = Fn[:, None] * n + Ft
        dy = np.empty_like(y)
        dy[:, _X] = xd
        if self.lever:
            # the contact point moves with the overlap (state.LEVER_DOC): v' = W(d) f + a + x' g,
            # g' = (W01^T + d W11) f, PD' = d f, d = max(x, 0) - max(x_ref, 0), d' = x' in contact:
            # a row in contact is at x < 0 only within round-off of its onset (+-1e-22 m from the
            # onset's root) or in RK4 stages past its end (cut at the end's root); taking d' = x' there
            # too keeps the slope continuous (switched off at x <= 0, the first stage's d' hung on
            # the sign of that round-off: the compiled and numpy islands differed by 6e-6 in a pile step)
            on = self.on[:, None]
            d = (np.maximum(y[:, _X], 0.0) - self.L[:, L_XREF])[:, None]
            A = np.einsum("kij,kj->ki", self.W01, f)
            B = np.einsum("kji,kj->ki", self.W01, f)
            C = np.einsum("kij,kj->ki", self.W11, f)
            ex = d * (A + B + d * C) + xd[:, None] * y[:, _G]
            Wf = np.einsum("kij,kj->ki", self.W, f)
            dy[:, _V] = np.where(on, Wf + ex + self.a, Wf + self.a)
            dy[:, _G] = np.where(on, B + d * C, 0.0)
            dy[:, _PD] = np.where(on, d * f, 0.0)
        else:
            dy[:, _V] = np.einsum("kij,kj->ki", self.W, f) + self.a
            dy[:, _G] = 0.0
            dy[:, _PD] = 0.0
        dy[:, _S] = sd
        dy[:, _VC] = np.einsum("kij,kj->ki", self.Wc, f) + self.a
        dy[:, _P] = f
        dy[:, _WEL] = Fc * xd
        dy[:, _WVI] = (Fn - Fc) * xd
        dy[:, _Q] = np.einsum("ki,ki->k", b * sd2, sd2)
        dy[:, _WT] = -_dot(Ft, vt)
        dy[:, _PI] = y[:, _P]
        return dy, Fn, np.hypot(Ft2[:, 0], Ft2[:, 1])

    def rk4(self, y, h):
        """One RK4 step of lengths h (k,), then the slip of the tangential
        spring (:meth:`slip`). Returns (y_new, F_n at y, |F_t| at y)."""
        hh = h[:, None]
        hh2 = 0.5 * hh
        k1, Fn, Ft = self.rhs(y)
        k2, _, _ = self.rhs(y + hh2 * k1)
        k3, _, _ = self.rhs(y + hh2 * k2)
        k4, _, _ = self.rhs(y + hh * k3)
        return self.slip(y, y + hh / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), h), Fn, Ft

    def slip(self, y0, y1, h):
        """Coulomb slip of the tangential spring over a step y0 -> y1 of
        lengths h (k,) [s]: where the trial force -(k s + b s') at the end
        exceeds the cap mu F_n, the spring-dashpot keeps only what the capped
        force F holds, k s + b (s - s0)/h = -F (backward Euler), and the rest
        of the displacement is slip, as the reference solver's slide phase.
        Without it s would keep the slip and the force would stay on the cap
        after the motion reverses (spin_out 117.8 against the reference's
        128.1 rad/s, Hertz law at 89 deg, issue 12). Laws with their own
        ``tangential_force`` are left as they are."""
        law = self.law
        if law.mu is None or not self.plain_tangential:
            return y1
        x = np.maximum(y1[:, _X], 0.0)
        v, vc = y1[:, _V], y1[:, _VC]
        xd = -_dot(v, self.n)
        Fn, _, k, b = self._forces(x, xd)
        vt = v + xd[:, None] * self.n
        sd = np.where(self.paper[:, None], vc - _dot(vc, self.n)[:, None] * self.n, vt) if self.any_paper else vt
        s1 = np.einsum("kij,kj->ki", self.T, y1[:, _S])
        sd1 = np.einsum("kij,kj->ki", self.T, sd)
        Ftr = -(b * sd1 + k * s1)
        cap = law.mu * np.maximum(Fn, 0.0)
        mag = np.hypot(Ftr[:, 0], Ftr[:, 1])
        over = (mag > cap) & (h > 0)
        if not np.any(over):
            return y1
        s0 = np.einsum("kij,kj->ki", self.T, y0[:, _S])
        F = Ftr * (cap / np.where(mag > 0, mag, 1.0))[:, None]
        bh = b / np.where(h > 0, h, 1.0)[:, None]
        den = k + bh
        s_new = np.where(den > 0, (bh * s0 - F) / np.where(den > 0, den, 1.0), s1)
        y1 = y1.copy()
        y1[over, _S] = np.einsum("ki,kij->kj", s_new[over], self.T[over])
        return y1

    def xdot(self, y):
        return -_dot(y[:, _V], self.n)

    def indicator(self, y):
        x = np.maximum(y[:, _X], 0.0)
        return self.law.separation_indicator(x, self.xdot(y), self.onset)


def _find_root(g, lo, hi, g_lo, g_hi):
    """Vectorised Illinois regula falsi on [lo, hi] (k,) with g(lo) > 0 >= g(hi).
    g(theta (k,)) -> (k,). Returns theta (k,).

    A row is done when its bracket is narrower than ROOT_TOL, or when hi is
    the root to rounding: g(hi) == 0, or the secant step lands on hi (the
    linear model puts the root within an ulp of hi). Without the last two
    tests a row whose g(hi) is exactly 0 (the usual end of an overlap-zero
    contact) stalls the secant and falls back to ~30 bisections for nothing."""
    lo, hi, g_lo, g_hi = lo.copy(), hi.copy(), g_lo.copy(), g_hi.copy()
    side = np.zeros(lo.shape, int)
    done = (hi - lo <= ROOT_TOL) | (g_hi == 0)
    for _ in range(ROOT_ITER):
        if np.all(done):
            break
        den = g_lo - g_hi
        th = np.where(den > 0, lo + g_lo * (hi - lo) / np.where(den > 0, den, 1.0), 0.5 * (lo + hi))
        done |= (den > 0) & (th >= hi)
        if np.all(done):
            break
        # fall back to bisection when the secant stalls at an end
        stalled = (th <= lo) | (th >= hi)
        th = np.where(stalled, 0.5 * (lo + hi), th)
        gt = g(th)
        pos = gt > 0
        live = ~done
        # Illinois: halve the value at the end that stays
        g_hi = np.where(live & pos & (side == 1), 0.5 * g_hi, g_hi)
        g_lo = np.where(live & ~pos & (side == -1), 0.5 * g_lo, g_lo)
        lo, g_lo = np.where(live & pos, th, lo), np.where(live & pos, gt, g_lo)
        hi, g_hi = np.where(live & ~pos, th, hi), np.where(live & ~pos, gt, g_hi)
        side = np.where(live, np.where(pos, 1, -1), side)
        done |= (hi - lo <= ROOT_TOL) | (g_hi == 0)
    return hi


class NumpyPath:
    """ContactManager's numpy path (mixed into :class:`engines._contacts.ContactManager`,
    whose per-pair state it reads and writes)."""

    def _step_group(self, g, law, p, x_eng, n, v, vc, W, Wc, a, t0, info, L=None):
        dt = self.dt
        k = p.shape[0]
        t1, t2 = _tangent_basis(n)
        batch = _Batch(law, n, t1, t2, W, Wc, a, self._paper[p], L=L)
        act = self.active[p].copy()
        # the step-start state: timing corrections removed, resting x relaxed, s re-projected
        settle = act & ((t0 - self.t_onset[p]) > SETTLE_AFTER_DURATIONS * self.tau_est[p])
        y = initial_state(self, p, x_eng, n, v, vc, settle)
        x0 = y[:, _X]
        lever_start(y, L)  # v_rel at the internal overlap's point, not the engine's (state.LEVER_DOC)
        onset = self._onset[g]
        if onset:
            batch.onset = {key: arr[self._pos[p]] for key, arr in onset.items()}
        t_loc = np.zeros(k)
        in_c = act
        settled = np.zeros(k, bool)
        if self.settled_path and np.any(settle & (x0 > 0)):
            done = self._settled(g, law, p, np.flatnonzero(settle & (x0 > 0)), y, batch, t0, info)
            settled[done] = True
            t_loc[done] = dt  # nothing left of the step for these rows
        for _ in range(MAX_SEGMENTS):
            info["segments"] += 1
            rem = dt - t_loc
            free = ~in_c & (rem > 0)
            if np.any(free):
                fi = np.flatnonzero(free)
                tc = self._free_flight(y, fi, batch, rem[fi])
                t_loc[fi] = np.where(np.isfinite(tc), t_loc[fi] + tc, dt)
                new = fi[np.isfinite(tc)]
                if new.size:
                    self._begin(g, law, p, new, y, batch, t0 + t_loc[new])
                    in_c[new] = True
                    info["onsets"] += int(new.size)
            rem = dt - t_loc
            ci = np.flatnonzero(in_c & (rem > 0))
            if ci.size == 0:
                break
            ended = self._integrate(g, law, p, ci, y, batch, t_loc, t0, info)
            in_c[ended] = False
        else:
            raise RuntimeError(f"more than {MAX_SEGMENTS} contact onsets/separations in one step of {dt!r} s")
        # write back
        self.active[p] = in_c
        self.x[p] = y[:, _X]
        self.xdot[p] = batch.xdot(y)
        self.s[p] = y[:, _S]
        self.vc[p] = y[:, _VC]
        self.W_el[p], self.W_visc[p], self.Q_t[p], self.W_t[p] = y[:, _WEL], y[:, _WVI], y[:, _Q], y[:, _WT]
        self.phase[p] = np.where(self.xdot[p] < 0, 1, 0)
        self.outside[p] |= law.outside(np.maximum(y[:, _X], 0.0)) & in_c
        # timing correction: the engine applies the impulse as a constant force over the step;
        # J = int (dt/2 - t) f dt / dt, added now and removed next step, moves the engine's
        # position as if the impulse had its actual timing inside the step (zero velocity change)
        J = y[:, _PI] / dt - 0.5 * y[:, _P] if self.timing_correction else np.zeros((k, 3))
        J[settled] = 0.0  # a force held over the whole step: its timing is the engine's
        self.settled[p] = settled
        if self.history:
            Pn = np.einsum("ki,ki->k", y[:, _P], batch.n) / dt
            for r in np.flatnonzero(np.any(y[:, _P] != 0.0, axis=1)):
                self._hist.setdefault(int(p[r]), []).append((t0, float(Pn[r])))
        impulse = y[:, _P] + J - self.J[p]
        self.couple[p] = 0.5 * np.cross(batch.n, y[:, _PD])  # n x PD / 2 (state.LEVER_DOC)
        self.J[p] = J
        self.dv_corr[p] = np.einsum("kij,kj->ki", W, J)
        self.dvc_corr[p] = np.einsum("kij,kj->ki", Wc, J)
        return impulse

    def _settled(self, g, law, p, rows, y, batch, t0, info):
        """The settled path (module docstring) for candidate rows (contacts past
        SETTLE_AFTER_DURATIONS durations, x > 0). Rows whose approach rate is
        below SETTLED_SPEED_RATIO v_x take one backward-Euler step of the law
        over the whole engine step; returns the rows done (their y written),
        the others are left to sub-cycling.

        Unknowns z = (n.v+, t1.w+, t2.w+) at the step end, w the velocity the
        tangential spring follows (v, or v_com in paper mode); the end state
        x+ = x + dt x'+ (x'+ = -n.v+), s+ = s + dt T w+; the force
        phi(z) = (F_n(x+, x'+), F_t(x+, s+, T w+) capped at mu F_n) from the
        law; z = z_free + dt M phi(z) with M = [n^T W; T W_w] B^T, B = [n; T].
        Newton from the current velocities (its first step is the law
        linearised at the current state); Jacobian I + dt M D with
        D = diag(dF_n/dx dt + dF_n/dx', b + k dt) (Coulomb cap and k(x)
        left out: a quasi-Newton step that still converges).

        Why backward Euler of the whole law: the engine integrates the returned
        constant force with v+ = v + dt (W f + a), x+ = x + dt x'+ (semi-implicit
        Euler), so the force is the law's at the state the engine will reach.
        For a force that is monotone in x and x' (the elastic part has a convex
        potential; the damping is >= 0) that step is unconditionally stable and
        never gains energy at any dt, and its fixed point is the exact static
        balance F_n(x_s, 0) = m a_n."""
        dt = self.dt
        b = batch.sub(rows)
        o = b.onset
        k = rows.size
        n, T = b.n, b.T
        x0 = y[rows, _X]
        v, vc = y[rows, _V], y[rows, _VC]
        nWn = np.einsum("ki,kij,kj->k", n, b.W, n)
        F_el = law.contact_normal_force(x0, np.zeros(k), o)
        vx = np.sqrt(np.maximum(F_el, 0.0) * x0 * nWn)
        slow = (np.abs(_dot(v, n)) <= SETTLED_SPEED_RATIO * vx) & (vx > 0)
        if not np.all(slow):
            keep = np.flatnonzero(slow)
            if keep.size == 0:
                return rows[:0]
            rows, b, k, n, T = rows[keep], b.sub(keep), keep.size, n[keep], T[keep]
            o = b.onset
            x0, v, vc, nWn, vx = x0[keep], v[keep], vc[keep], nWn[keep], vx[keep]
        a, W, Wc = b.a, b.W, b.Wc
        paper = b.paper[:, None]
        Ww = np.where(paper[..., None], Wc, W) if b.any_paper else W
        w = np.where(paper, vc, v) if b.any_paper else v
        Bm = np.concatenate([n[:, None, :], T], axis=1)  # (k, 3, 3): rows n, t1, t2
        Sel = np.concatenate([np.einsum("ki,kij->kj", n, W)[:, None, :], np.einsum("kai,kij->kaj", T, Ww)], axis=1)
        M = Sel @ Bm.transpose(0, 2, 1)
        z_free = np.concatenate([_dot(v + dt * a, n)[:, None], np.einsum("kai,ki->ka", T, w + dt * a)], axis=1)
        z = np.concatenate([_dot(v, n)[:, None], np.einsum("kai,ki->ka", T, w)], axis=1)
        s2 = np.einsum("kai,ki->ka", T, y[rows, _S])
        o2 = {q: np.concatenate([a_, a_]) for q, a_ in o.items()}
        delta = SETTLED_FD_REL * x0 / dt
        tol = SETTLED_VTOL * vx
        eye = np.eye(3)
        conv = np.zeros(k, bool)
        for it in range(SETTLED_NEWTON_MAX + 1):
            xd_e = -z[:, 0]
            x_e = x0 + dt * xd_e
            F2 = law.contact_normal_force(np.concatenate([x_e, x_e + dt * delta]),
                                          np.concatenate([xd_e, xd_e + delta]), o2)
            Fn = F2[:k]
            kt, bt = law.tangential_stiffness(x_e, o)
            s_e = s2 + dt * z[:, 1:]
            if b.plain_tangential:
                Ft = -(bt * z[:, 1:] + kt * s_e)
                if law.mu is not None:
                    cap = law.mu * np.maximum(Fn, 0.0)
                    mag = np.hypot(Ft[:, 0], Ft[:, 1])
                    Ft = Ft * np.where(mag > cap, cap / np.where(mag > 0, mag, 1.0), 1.0)[:, None]
            else:
                Ft, _ = law.tangential_force(x_e, s_e, z[:, 1:], o, Fn)
            phi = np.concatenate([Fn[:, None], Ft], axis=1)
            R = z - z_free - dt * np.einsum("kij,kj->ki", M, phi)
            conv = np.max(np.abs(R), axis=1) <= tol
            info["settled_iterations"] += 1
            if np.all(conv) or it == SETTLED_NEWTON_MAX:
                break
            D = np.concatenate([np.maximum((F2[k:] - Fn) / delta, 0.0)[:, None], bt + kt * dt], axis=1)
            J = eye + dt * M * D[:, None, :]
            z = z - np.linalg.solve(J, R[..., None])[..., 0]
        ok = conv & (x_e > 0) & (Fn > 0) & (np.abs(xd_e) <= SETTLED_SPEED_RATIO * vx)
        if not np.all(ok):
            j = np.flatnonzero(ok)
            rows, n, T, x0, v, vc, a, W, Wc = rows[j], n[j], T[j], x0[j], v[j], vc[j], a[j], W[j], Wc[j]
            x_e, xd_e, Fn, Ft, s_e, z, kt, bt = x_e[j], xd_e[j], Fn[j], Ft[j], s_e[j], z[j], kt[j], bt[j]
            o = {q: a_[j] for q, a_ in o.items()}
        if rows.size == 0:
            return rows
        # the step's result: the law's force at the end state, held over the step
        f = Fn[:, None] * n + np.einsum("ka,kai->ki", Ft, T)
        v1 = v + dt * (np.einsum("kij,kj->ki", W, f) + a)
        Fc = law.normal_force(x_e, np.zeros(rows.size), o)
        dx = x_e - x0
        y[rows, _X] = x_e
        y[rows, _V] = v1
        y[rows, _VC] = vc + dt * (np.einsum("kij,kj->ki", Wc, f) + a)
        y[rows, _S] = np.einsum("ka,kai->ki", s_e, T)
        y[rows, _P] = f * dt
        y[rows, _PI] = 0.5 * dt * dt * f
        y[rows, _WEL] += Fc * dx
        y[rows, _WVI] += (Fn - Fc) * dx
        y[rows, _Q] += np.einsum("ka,ka->k", bt * z[:, 1:], z[:, 1:]) * dt
        y[rows, _WT] -= _dot(f - Fn[:, None] * n, v1 - _dot(v1, n)[:, None] * n) * dt
        # record bookkeeping, as one substep at the end state
        book_records(self, p[rows], x_e, xd_e, Fn, Ft, y[rows], t0)
        info["settled"] += int(rows.size)
        return rows

    def _free_flight(self, y, fi, batch, rem):
        """Advance rows fi without contact force to the next onset (x >= 0 with
        closing speed) or by rem. Returns the time advanced to onset (inf: none)."""
        n, a = batch.n[fi], batch.a[fi]
        x0 = y[fi, _X]
        xd0 = -_dot(y[fi, _V], n)
        c = -0.5 * _dot(a, n)  # x(t) = x0 + xd0 t + c t^2
        tc = np.full(fi.shape, np.inf)
        imm = ((x0 >= 0) & (xd0 > 0)) | ((x0 > 0) & (xd0 == 0))
        tc[imm] = 0.0
        D = xd0 * xd0 - 4.0 * c * x0
        sq = np.sqrt(np.maximum(D, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_up = np.where(xd0 > 0, -2.0 * x0 / (sq + xd0), (sq - xd0) / (2.0 * c))
            # starting overlapped and separating, pulled back: closing speed 0 before x reaches 0
            t_turn = -xd0 / (2.0 * c)
        up = (x0 < 0) & (D >= 0) & ((xd0 > 0) | (c > 0))
        tc = np.where(~imm & up & (t_up >= 0), t_up, tc)
        back = ~imm & (x0 >= 0) & (xd0 <= 0) & (c > 0)
        stays = back & (x0 - xd0 * xd0 / (4.0 * np.where(c > 0, c, 1.0)) >= 0)
        tc = np.where(stays, t_turn, tc)
        tc = np.where(back & ~stays, t_up, tc)
        tc = np.where(tc <= rem, tc, np.inf)
        tadv = np.where(np.isfinite(tc), tc, rem)
        y[fi, _X] = x0 + xd0 * tadv + c * tadv * tadv
        if getattr(batch, "lever", False):  # the moving contact point (state.LEVER_DOC): v += g (max(x_new, 0) - max(x_old, 0))
            j = fi[batch.on[fi]]
            y[j, _V] += y[j, _G] * (np.maximum(y[j, _X], 0.0) - np.maximum(x0[batch.on[fi]], 0.0))[:, None]
        y[fi, _V] += a * tadv[:, None]
        y[fi, _VC] += a * tadv[:, None]
        y[fi, _PI] += y[fi, _P] * tadv[:, None]
        if np.any(stays & np.isfinite(tc)):  # exactly at the turn: closing speed 0, not slightly negative
            j = fi[stays & np.isfinite(tc)]
            y[j, _V] -= (_dot(y[j, _V], batch.n[j]))[:, None] * batch.n[j]
        return tc

    def _integrate(self, g, law, p, ci, y, batch, t_loc, t0, info):
        """RK4 over rows ci until the end of the step or until some contact
        ends (then return their row indices: they continue as free motion)."""
        dt = self.dt
        b = batch.sub(ci)
        pp = p[ci]
        rem = dt - t_loc[ci]
        nsub = int(max(1, np.max(np.ceil(rem / self.h[pp] - 1e-9))))
        h = rem / nsub
        Y = y[ci]
        force_zero = law.separation == "force-zero"
        ended_rows = np.zeros(0, int)
        for i in range(nsub):
            Y1, Fn0, Ft0 = b.rk4(Y, h)
            info["substeps"] += 1
            # peak force and friction ratio at the substep start
            better = Fn0 > self.F_max[pp]
            self.x_at_F[pp] = np.where(better, Y[:, _X], self.x_at_F[pp])
            self.F_max[pp] = np.maximum(self.F_max[pp], Fn0)
            ok = (Fn0 >= F_RATIO_FLOOR * self.F_max[pp]) & (Fn0 > 0)
            ratio = np.where(ok, Ft0 / np.where(ok, Fn0, 1.0), 0.0)
            self.f_min[pp] = np.where(ok, np.minimum(self.f_min[pp], ratio), self.f_min[pp])
            self.f_max[pp] = np.where(ok, np.maximum(self.f_max[pp], ratio), self.f_max[pp])
            xd0, xd1 = b.xdot(Y), b.xdot(Y1)
            # first maximum compression inside this substep
            lo = np.zeros(ci.size)
            turn = ~self.turned[pp] & (xd0 > 0) & (xd1 <= 0)
            if np.any(turn):
                j = np.flatnonzero(turn)
                bj = b.sub(j)
                th = _find_root(lambda th: bj.xdot(bj.rk4(Y[j], th * h[j])[0]),
                                np.zeros(j.size), np.ones(j.size), xd0[j], xd1[j])
                Yt = bj.rk4(Y[j], th * h[j])[0]
                q = pp[j]
                self.turned[q] = True
                self.tau1[q] = t0 + t_loc[ci[j]] + th * h[j] - self.t_onset[q]
                self.x_turn[q] = Yt[:, _X]
                self.x_max[q] = np.maximum(self.x_max[q], Yt[:, _X])
                self.W_el_comp[q] = Yt[:, _WEL]
                self.W_visc_comp[q] = Yt[:, _WVI]
                lo[j] = th
            self.x_max[pp] = np.maximum(self.x_max[pp], Y1[:, _X])
            # separation
            end = (xd1 < 0) & (Y1[:, _X] < 0)
            if force_zero:
                end |= (xd1 < 0) & (b.indicator(Y1) < 0)
            if np.any(end):
                j = np.flatnonzero(end)
                bj = b.sub(j)
                Y0j = Y[j]
                Ylo = bj.rk4(Y0j, lo[j] * h[j])[0]
                xs = np.where(Ylo[:, _X] > 0, Ylo[:, _X], 1.0)
                Bs = np.abs(bj.indicator(Ylo))
                Bs = np.where(Bs > 0, Bs, 1.0)

                def gfun(yy, bj=bj, xs=xs, Bs=Bs):
                    gx = yy[:, _X] / xs
                    if not force_zero:
                        return gx
                    gb = np.where(bj.xdot(yy) < 0, bj.indicator(yy) / Bs, 1.0)
                    return np.minimum(gx, gb)

                g_lo = gfun(Ylo)
                g_hi = gfun(Y1[j])
                # a substep that starts already past the event (should not happen): end at its start
                g_lo = np.where(g_lo > 0, g_lo, 1e-300)
                th = _find_root(lambda th: gfun(bj.rk4(Y0j, th * h[j])[0]), lo[j], np.ones(j.size), g_lo, g_hi)
                Ye = bj.rk4(Y0j, th * h[j])[0]
                gx = Ye[:, _X] / xs
                by_force = np.zeros(j.size, bool)
                if force_zero:
                    by_force = np.where(bj.xdot(Ye) < 0, bj.indicator(Ye) / Bs, np.inf) < gx
                Y1 = Y1.copy()
                Y1[j] = Ye
                t_end = t_loc[ci[j]] + th * h[j]
                for r, jj in enumerate(j):
                    self._end(int(pp[jj]), Ye[r], float(t0 + t_end[r]),
                              "force-zero" if by_force[r] else "overlap-zero", b.n[jj])
                info["ends"] += int(j.size)
                t_loc[ci] += h
                t_loc[ci[j]] = t_end
                Y = Y1
                ended_rows = ci[j]
                break
            Y = Y1
            t_loc[ci] += h
        else:
            t_loc[ci] = dt  # exact end of step (no rounding drift)
        y[ci] = Y
        return ended_rows
