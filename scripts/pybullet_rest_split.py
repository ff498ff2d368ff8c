"""Where the pybullet robots' rest gains come from (issue 13): the benchmark's
robot (benchmarks.robots_pybullet.run_model) under a torque seed, and for
every rest step whose contacts' own balance (RestEnergy.contacts) rises
above its bound, that rise split per contact and per term:

    g_p = dE_el,p + d(W_t - Q_t)_p + W_n,p + W_t,p

(dE_el: the elastic energy of the normal force at the internal approach;
W_t - Q_t: the tangential work less its viscous part, finished contacts'
included; W_n, W_t: the work the pair's load did on the bodies in pybullet's
step, normal and tangential parts, +-F . (v_start + v_end)/2 dt at the
material points as PybulletAdapter.last_step_work), with the contact's
internal approach x and the engine's x_e at the step start (x - x_e: the
drift) and whether the trial's held joints were the real step's.

    .venv/bin/python scripts/pybullet_rest_split.py [--model humanoid.xml] [--seeds 13 1 2 3 4] [--top 5]
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

from engines._contacts.balance import IslandBalance  # noqa: E402


def pair_work(ad, n_pairs: int) -> np.ndarray:
    """(P, 2) [J]: the normal and tangential work of each pair's load in the
    last step (PybulletAdapter.last_step_work per pair, split along the pair's
    normal of that step)."""
    out = np.zeros((n_pairs, 2))
    if ad._last_loads is None:
        return out
    ph, F, point, couples, b0 = ad._last_loads
    kin = ad._last_kin
    nrm = {int(p): kin.normal[r] for r, p in enumerate(np.asarray(kin.pair, int).tolist())}
    end = {}
    for q, i in enumerate(ph.tolist()):
        n = nrm[int(i)]
        Fn = float(F[q] @ n) * n
        for side, sign in ((0, 1.0), (1, -1.0)):
            j = int(ad._slot[i, side])
            if ad._b_fixed[j]:
                continue
            if j not in end:
                end[j] = ad._pose(ad._body_list[j])
            e = end[j]
            local = b0.rot[j].T @ (point[q] - b0.com[j])
            v0 = b0.v[j] + np.cross(b0.w[j], point[q] - b0.com[j])
            v1 = e.v + np.cross(e.w, e.rot @ local)
            vm = (v0 + v1) * 0.5 * ad._dt
            out[i, 0] += sign * float(Fn @ vm)
            out[i, 1] += sign * float((F[q] - Fn) @ vm)
    return out


def stored_split(mgr) -> np.ndarray:
    """(P, 2) [J]: each pair's elastic normal energy (at x, or its recovering
    surface's) and its W_t - Q_t (in progress plus finished)."""
    pp = np.arange(len(mgr.pairs))
    S = IslandBalance.stored_rows(mgr, pp)
    wt = np.where(mgr.active, mgr.W_t - mgr.Q_t, 0.0) + mgr.W_tq_finished
    return np.column_stack([S - np.where(mgr.active, mgr.W_t - mgr.Q_t, 0.0), wt])


class Split:
    """run_model observer: per rest step, the per-pair split of the contacts' balance."""

    def __init__(self):
        self.rows = []  # (step, rise, allowed, [(pair, g, dE_el, dWtQ, W_n, W_t, x, x_e, settled, island)])
        self.drift = []  # (phase, step, pair, x - x_e) of pairs in contact at the step start
        self._S0 = None
        self._x0 = None
        self._last_gains = 0

    def before(self, ad, acc, phase):
        mgr = ad.manager
        self._S0 = stored_split(mgr)
        self._x0 = mgr.x.copy()
        self._act0 = mgr.active.copy()
        self._miss0 = list(ad.limit_trial_misses)

    def after(self, ad, acc, phase, step):
        mgr = ad.manager
        P = len(mgr.pairs)
        kin = ad._last_kin
        xe = np.full(P, np.nan)
        xe[np.asarray(kin.pair, int)] = kin.x
        for p in np.flatnonzero(self._act0 & np.isfinite(xe)):
            self.drift.append((phase, step, int(p), float(self._x0[p] - xe[p])))
        if phase != "rest":
            return
        dS = stored_split(mgr) - self._S0
        W = pair_work(ad, P)
        g = dS.sum(axis=1) + W.sum(axis=1)
        if len(acc.contact_gains) > self._last_gains:
            self._last_gains = len(acc.contact_gains)
            s, rise, allowed = acc.contact_gains[-1]
            order = np.argsort(-g)
            per = [(int(p), float(g[p]), float(dS[p, 0]), float(dS[p, 1]), float(W[p, 0]), float(W[p, 1]),
                    float(self._x0[p]), float(xe[p]), bool(mgr.settled[p]), bool(mgr.in_island[p]))
                   for p in order[:8] if abs(g[p]) > 0]
            self.rows.append((s, float(rise), float(allowed), float(g.sum()), per,
                              [a - b for a, b in zip(ad.limit_trial_misses, self._miss0)]))


def main():
    from benchmarks.robots_pybullet import run_model

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="ant.xml")
    ap.add_argument("--seeds", type=int, nargs="+", default=[13, 1, 2, 3, 4])
    ap.add_argument("--top", type=int, default=5)
    ap.add_argument("--steps", type=int, default=1000)
    args = ap.parse_args()
    for seed in args.seeds:
        sp = Split()
        r = run_model(args.model, args.steps, True, seed=seed, observer=sp)
        names = r["adapter"].pair_names
        print(f"== {args.model} seed {seed}: contacts' rise {r['rest_contacts_rise_J']:.3g} J, "
              f"{r['rest_contact_gain_steps']} steps above the bound, largest {r['rest_largest_contact_gain_J']:.3g} J")
        d = np.array([abs(v[3]) for v in sp.drift if v[0] == "torque"])
        dr = np.array([abs(v[3]) for v in sp.drift if v[0] == "rest"])
        for lab, a in (("torques", d), ("rest", dr)):
            if a.size:
                print(f"   |x - x_e| at step starts in contact, {lab}: median {np.median(a):.3g} m, 90 % "
                      f"{np.quantile(a, 0.9):.3g} m, max {a.max():.3g} m ({a.size} contact-steps)")
        tot = {"dE_el": 0.0, "dWtQ": 0.0, "W_n": 0.0, "W_t": 0.0}
        for s, rise, allowed, gsum, per, miss in sp.rows:
            for p, gp, a, b, c, e, *_ in per:
                if gp > 0:
                    tot["dE_el"] += a
                    tot["dWtQ"] += b
                    tot["W_n"] += c
                    tot["W_t"] += e
        print("   over the steps above the bound, the gaining contacts' terms summed [J]: "
              + ", ".join(f"{k} {v:.3g}" for k, v in tot.items()))
        for s, rise, allowed, gsum, per, miss in sorted(sp.rows, key=lambda t: -t[1])[:args.top]:
            print(f"   rest step {s}: rise {rise:.3g} J (allowed {allowed:.3g}, per-pair sum {gsum:.3g}); trial missed "
                  f"(held not tried, tried not held) {miss} in this step")
            for p, gp, a, b, c, e, x, xe, st, isl in per[:4]:
                print(f"      pair {p} {names[p][0]}: g {gp:.3g} = dE_el {a:.3g} + dWtQ {b:.3g} + W_n {c:.3g} + W_t "
                      f"{e:.3g}; x {x * 1e3:.3f} mm, x_e {xe * 1e3:.3f} mm, settled {st}, island {isl}")


if __name__ == "__main__":
    main()
