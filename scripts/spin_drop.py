"""A spinning box dropped on a plane in MuJoCo at a large step (issue 13):
a 1 kg box 0.10 x 0.06 x 0.04 m, its centre 0.2 m above the plane, spinning
at ``w`` rad/s about an axis, natural rubber on steel (the plain
``Curvature.sphere_on_plane(0.02)`` PairSpec; the corners' edge radius
msf_contact.shapes.DEFAULT_EDGE_RADIUS), Euler.

    .venv/bin/python scripts/spin_drop.py              # the table behind BOX_TURN_PER_STEP_MAX
    .venv/bin/python scripts/spin_drop.py --trace      # the (1, 1, 1) drop at 20 rad/s, 10 ms, step by step

The table: every contact step (a corner force or a contact in progress) of
drops at dt = 5 and 10 ms, 5 / 15 / 25 rad/s about 10 random axes (seed 2),
binned by the box's |omega| dt at the step's start, counting the steps
whose rise of kinetic + gravitational + the contacts' stored energy
exceeded dt/2 |dP_g| (the semi-implicit step's gravity term) + 1e-3 of the
energy by more than 1e-3 of the drop's energy (engines.mujoco.adapter.
BOX_TURN_PER_STEP_MAX).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

HALF = (0.05, 0.03, 0.02)  # half-extents [m]
MASS, HEIGHT, G = 1.0, 0.2, 9.81
BINS = (0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0, np.inf)


def drop(axis, w: float, dt: float, t_end: float = 0.4, trace: bool = False):
    """One drop; returns [(|omega| dt at the step start, excess / E0, the step's start time [s])] of
    its contact steps, the adapter and whether MuJoCo reset a bad acceleration."""
    import mujoco

    from engines.base import PairSpec
    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import mechanical_energy
    from msf_contact import ContactPair, Curvature, make_law, preset

    xml = (f'<mujoco><option timestep="{dt}" integrator="Euler" gravity="0 0 {-G}"/><worldbody>'
           '<geom name="floor" type="plane" size="2 2 0.1"/>'
           f'<body name="box" pos="0 0 {HEIGHT}"><freejoint/>'
           f'<geom name="box" type="box" size="{HALF[0]} {HALF[1]} {HALF[2]}" mass="{MASS}"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[3:6] = np.asarray(axis, float) / np.linalg.norm(axis) * w
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(0.02))
    rows, bad = [], False
    ad = MujocoAdapter(m, d, [PairSpec("box", "floor", law)])
    with installed(ad):
        v = d.qvel.copy()
        E = E0 = mechanical_energy(m, d, v)
        for k in range(round(t_end / dt)):
            wdt = float(np.linalg.norm(v[3:])) * dt
            P0 = -G * MASS * v[2]
            mujoco.mj_step(m, d)
            if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
                bad = True
                if trace:
                    print(f"step {k + 1}: MuJoCo reset a bad acceleration")
                break
            v = d.qvel - ad.velocity_offset()
            E1 = mechanical_energy(m, d, v) + ad.manager.stored_energy()
            contact = bool((ad.last_forces is not None and np.any(ad.last_forces.force != 0))
                           or np.any(ad.manager.active))
            allowed = 0.5 * dt * abs(-G * MASS * v[2] - P0) + 1e-3 * E
            if contact:
                rows.append((wdt, (E1 - E - allowed) / E0, k * dt))
            if trace:
                print(f"step {k + 1}: |omega| dt {wdt:.3f} -> {np.linalg.norm(v[3:]) * dt:.3f}, E {E1:.4g} J, "
                      f"contact {contact}, fast turns flagged {ad.fast_turns}")
            E = E1
    return rows, ad, bad


def table() -> None:
    rng = np.random.default_rng(2)
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the flags are what is counted
        for dt in (0.01, 0.005):
            for w in (5.0, 15.0, 25.0):
                for a in rng.normal(size=(10, 3)):
                    rows += drop(a, w, dt)[0]
    r = np.array(rows)
    print("| |omega| dt at the step start [rad] | contact steps | excess > 1e-3 E0 | > 1e-2 E0 | largest excess / E0 |")
    print("|---|---|---|---|---|")
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        s = r[(r[:, 0] >= lo) & (r[:, 0] < hi)]
        if len(s):
            print(f"| {lo:g}-{hi:g} | {len(s)} | {int(np.sum(s[:, 1] > 1e-3))} | {int(np.sum(s[:, 1] > 1e-2))} | "
                  f"{s[:, 1].max():.3g} |")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if "--trace" in argv:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            drop((1.0, 1.0, 1.0), 20.0, 0.01, t_end=0.7, trace=True)
    else:
        table()
    return 0


if __name__ == "__main__":
    sys.exit(main())
