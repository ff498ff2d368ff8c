"""The dense jet's island energy check (engines/_contacts/balance.py), and the
same question answered from MuJoCo's own state: the numbers docs/jet.md quotes.

    .venv/bin/python scripts/jet_islands.py                 # the check as it is
    .venv/bin/python scripts/jet_islands.py --no-discard    # islands with a parked bead checked too (as before)

The jet is tests/test_jet_pp.py's ``dense_spec`` (0.25 mm glass beads at
30 +- 9 m/s overtaking each other in flight, MuJoCo, dt = 0.1 ms, 24 plate
impacts). Printed:

- the island check: island steps checked and discarded (a bead of the island
  placed between the step and the next step start: the pool parks a bead
  whose impact is over by setting it moving at the park velocity), the
  largest rise of kinetic + potential + stored energy of a checked island
  against its allowance, and the flagged ones;
- independently of balance.py, from MuJoCo's qpos/qvel: C = the beads'
  total kinetic (translation + rotation) + potential energy less what the
  pool put in by placing beads (launch, park, repin; read just before and
  after each placement). Contacts only dissipate, so between step starts
  at which no contact is in progress and no timing correction is pending
  (nothing stored, no velocity offset) C may not rise, and it must have
  fallen by the records' dissipation W_diss_n + W_diss_t.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import warnings

import numpy as np

import engines._contacts.balance as balance
from engines._contacts.manager import ContactManager
from experiments.scenarios.jet import make_pool

#: a bead moved by the step when its centre advanced by dt v_end (MuJoCo's
#: semi-implicit Euler) to within this [m] (round-off of positions ~1e-2 m)
ADVANCE_ATOL = 1e-9


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--no-discard", action="store_true",
                    help="check the islands whose bead was placed too (the check before IslandBalance.forget)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
    from test_jet_pp import dense_spec  # the test's jet

    if args.no_discard:
        balance.IslandBalance.forget = lambda self, pairs: None
    checked = []  # (t_start [s], rise of E + S [J], allowed [J])
    close = balance.IslandBalance.close

    def spy_close(self, mgr, t):
        for pp, keys, E0, _q0, S0, scale in self._open:
            T1, U1, q1, _m = (np.asarray(a, float) for a in self.probe(keys))
            rise = float(T1.sum() + U1.sum()) + self.stored(mgr, pp) - (E0 + S0)
            checked.append((t, rise, balance.ENERGY_GAIN_RTOL * scale
                            + 0.5 * mgr.dt * float(np.sum(np.abs(q1 - _q0)))))
        return close(self, mgr, t)

    # the ledger of the beads' energy: E(t) of all beads (kinetic, translation + rotation, + potential) at
    # each step start, and what the pool put in by placing beads (launch, park, repin) between steps
    ledger = {"placed": 0.0, "starts": []}  # starts: (t [s], quiet, sum E - E_0 - placed [J])

    def energy(b, idx):
        qv, c = b._qvel[idx], b.centres(idx)  # noqa: SLF001 - MuJoCo's own qvel, sphere i is row i (engines/mujoco/pool.py)
        return float(np.sum(0.5 * b.mass[idx] * np.sum(qv[:, :3] ** 2, axis=1)
                            + 0.2 * b.mass[idx] * b.radius[idx] ** 2 * np.sum(qv[:, 3:] ** 2, axis=1)
                            + b.mass[idx] * pool.spec.gravity * c[:, 2]))

    step = ContactManager.step

    def spy_step(mgr, kin):
        b = pool.bodies
        quiet = not (mgr.active.any() or np.any(mgr.J))  # no contact in progress, no correction pending
        E = energy(b, np.arange(b.n))
        ledger.setdefault("E0", E)
        ledger["starts"].append((float(kin.t), quiet, E - ledger["E0"] - ledger["placed"]))
        return step(mgr, kin)

    balance.IslandBalance.close = spy_close
    ContactManager.step = spy_step
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with make_pool("mujoco", dense_spec(), 0) as pool:
            place = pool.bodies.place

            def spy_place(idx, pos, vel):
                idx = np.atleast_1d(np.asarray(idx, dtype=np.int64))
                E = energy(pool.bodies, idx)
                place(idx, pos, vel)
                ledger["placed"] += energy(pool.bodies, idx) - E

            pool.bodies.place = spy_place
            pool.run(24, sink=rows.extend)
            bal, dt = pool.bodies.adapter.manager._balance, pool.spec.dt  # noqa: SLF001
    g = np.array(checked)
    i = int(np.argmax(g[:, 1]))
    print(f"island steps checked {bal.checked}, discarded (a bead placed) {bal.discarded}, flagged {len(bal.gains)}; "
          f"largest rise of kinetic + potential + stored {g[i, 1]:.3g} J (allowed {g[i, 2]:.3g} J) at "
          f"t = {g[i, 0]:.5f} s; records flagged: "
          f"{sum('island energy' in r['outside_validity'] for r in rows)} of {len(rows)}")
    for t, pp, gain, allowed in bal.gains:
        print(f"  flagged: t = {t:.5f} s, pairs {pp}: rise {gain:.3g} J (allowed {allowed:.3g} J)")
    # C = E - E_0 - placed is what the engine + MSF did to the beads' energy; contacts only dissipate, so
    # between step starts with nothing stored (quiet) C may not rise, and it falls by the records' dissipation
    q = [(t, C) for t, quiet, C in ledger["starts"] if quiet]
    dC = np.diff([C for _t, C in q])
    t_last, C_last = q[-1]
    W = sum(r["W_diss_n"] + r["W_diss_t"] for r in rows
            if (r["t_onset"] + r["tau"] if r["kind"] == "impact" else r["t_end"]) < t_last)
    print(f"MuJoCo's state (not balance.py): {len(q)} quiet step starts; the beads' energy less what placing "
          f"put in: largest rise between quiet starts {dC.max():.3g} J; at t = {t_last:.5f} s {C_last:.6g} J "
          f"against the records' dissipation -{W:.6g} J (placing put in {ledger['placed']:.3g} J)")

if __name__ == "__main__":
    main()
