"""The contact manager's state saved and put back (engines._contacts.snapshot,
issue 13): a step taken again from the restored state is the same step, bit
for bit, also the one in which a contact ends (its record dropped with the
step and made again), and the record views of the compiled kernel's
bookkeeping stay views. pybullet's second limit trial takes a step again this
way (PybulletAdapter(limit_retrial=True), tests/test_robots_pybullet.py)."""

from __future__ import annotations

import numpy as np

from engines._contacts import ContactManager
from engines._contacts import snapshot
from engines.base import ContactKinematics, PairSpec
from msf_contact import ContactPair, Curvature, make_law, preset

DT = 1e-4
R = 0.01
M = 0.05  # [kg]
G = np.array([0.0, 0.0, -9.81])


def _ball(mgr, z, v, t):
    """One manager step of a ball (radius R, mass M) at height z [m], velocity v
    (3,) [m/s] over a plate at z = 0; returns (force (3,) [N], z, v) after a
    semi-implicit Euler step of the ball with that force and gravity."""
    n = np.array([[0.0, 0.0, 1.0]])
    W = np.eye(3)[None] / M
    kin = ContactKinematics(pair=np.array([0]), x=np.array([R - z]), normal=n, point=np.array([[0.0, 0.0, 0.0]]),
                            v_rel=v[None].copy(), v_com_rel=v[None].copy(), W=W, W_com=W.copy(), a_ext=G[None].copy(),
                            t=t)
    out = mgr.step(kin)
    F = out.force[0].copy() if out.pair.size else np.zeros(3)
    v = v + (F / M + G) * DT
    return F, z + v[2] * DT, v


def _arrays(mgr):
    return {k: v.copy() for k, v in vars(mgr).items() if isinstance(v, np.ndarray)}


def _differ(mgr, arrays) -> list[str]:
    """The names of the manager's arrays that differ from ``arrays`` (NaN equal to NaN)."""
    return [k for k, a in arrays.items() if not np.array_equal(getattr(mgr, k), a, equal_nan=a.dtype.kind == "f")]


def test_a_step_taken_again_from_the_saved_state_is_the_same_step():
    """A rubber ball dropped at 0.5 m/s with a tangential speed: at every step
    of its impact (and the step it ends in) the manager's state is saved, the
    step taken, the state put back and the step taken again: same force, same
    state arrays, same number of records; the views t_onset, x_max of the
    kernel's bookkeeping still views of it after the restore."""
    law = make_law("msf", ContactPair(preset("natural-rubber"), preset("steel")), Curvature.sphere_on_plane(R))
    mgr = ContactManager([PairSpec("ball", "plate", law)], DT, "fake")
    z, v, t = R + 2e-5, np.array([0.1, 0.0, -0.5]), 0.0
    checked = ended = 0
    for _ in range(400):
        z0, v0 = z, v.copy()
        state = snapshot.save(mgr)
        before = _arrays(mgr)
        records = len(mgr.records) + len(mgr._pending)
        F1, z1, v1 = _ball(mgr, z0, v0, t)
        after1, n1 = _arrays(mgr), len(mgr.records) + len(mgr._pending)
        snapshot.restore(mgr, state)
        assert _differ(mgr, before) == []
        assert len(mgr.records) + len(mgr._pending) == records
        F2, z2, v2 = _ball(mgr, z0, v0, t)
        np.testing.assert_array_equal(F1, F2)
        assert (z1, n1) == (z2, len(mgr.records) + len(mgr._pending))
        assert _differ(mgr, after1) == []
        assert np.shares_memory(mgr.t_onset, mgr._fl) and np.shares_memory(mgr.x_max, mgr._fl)
        checked += int(np.any(F1 != 0.0))
        ended += int(n1 > records)
        z, v, t = z1, v1, t + DT
        if len(mgr.records) == 1:
            break
    assert checked > 10 and ended >= 1 and len(mgr.records) == 1
    assert mgr.records[0].cor_n > 0.5  # a rubber ball's bounce (the record made in the step taken again)
