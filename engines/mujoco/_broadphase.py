"""The MuJoCo adapter's broad phase for its free group's sphere-sphere pairs.

Without it the compiled free group reads every pair every step
(engines.mujoco._kernels.free_kinematics_into): the jet's 266 beads with
particle-particle contacts are 35,245 pairs, ~8 ms a step, when a few dozen
can meet. With it (:class:`BroadPhase`, made by the adapter when the group
has at least BROAD_MIN_PAIRS sphere-sphere pairs; ``adapter.broad_phase``
switches it) each step reads the pairs that are not sphere-sphere ones (a
sphere on the plate), the sphere-sphere pairs the manager requires (in
contact, or a timing correction to remove) and those whose spheres the
broad phase finds within reach (engines._broad, the reach bound of
engines.mujoco._kernels.sphere_reach, LOOKAHEAD steps ahead), in the
group's order. A pair's a_ext estimate needs its relative velocity of the
last step; a pair the broad phase stops listing has it cleared
(``have_last``), and one listed again starts from the first-step value, as
after a jump. LOOKAHEAD lists a pair at least a step before it can be a
candidate at the bodies' speeds of the listing step, so its estimate is
the one the all-pairs path reads; a pair that is a candidate in the step it
is first listed (a body much faster than a step before) is counted in
``adapter.broad_late`` (tests and docs/jet.md: none in the jets measured),
its first a_ext the first-step value.

The rows a step reads and the step's records are the same as without the
broad phase (the pairs of a body the user drives, a mocap body, whose motion
the adapter puts into their push and not into cvel, are read every step): tests/test_broad_phase.py (bit for bit, MuJoCo, random spheres
and a particle-particle jet).
"""

from __future__ import annotations

import mujoco
import numpy as np

from engines._contacts.islands import TOUCH_TOL

#: The adapter makes a broad phase for a free group with at least this many
#: sphere-sphere pairs (``adapter.broad_phase`` None: automatic). Below it
#: reading every pair costs a few microseconds.
BROAD_MIN_PAIRS = 1000
#: ... and at least this many sphere-sphere pairs per sphere: every pair of a
#: pool (n - 1)/2 (the jet: 132), not a list of neighbours (benchmarks.pile's
#: lattice: 2.7), whose pairs are mostly in contact and read anyway.
BROAD_PAIRS_PER_SPHERE = 8.0


def sphere_pairs(gi: np.ndarray, gf: np.ndarray) -> np.ndarray:
    """The free group's sphere-sphere rows (k,) bool (gi, gf: its packed constants)."""
    from engines.mujoco import _kernels as K

    return (gi[:, K.I_PLANE] == 0) & ~np.isnan(gf[:, K.F_R2])


def wanted(gi: np.ndarray, gf: np.ndarray) -> bool:
    """Whether ``adapter.broad_phase`` None (automatic) makes a broad phase for the free group
    (BROAD_MIN_PAIRS, BROAD_PAIRS_PER_SPHERE)."""
    from engines.mujoco import _kernels as K

    ss = sphere_pairs(gi, gf)
    n = int(np.count_nonzero(ss))
    if n < BROAD_MIN_PAIRS:
        return False
    spheres = np.unique(np.concatenate([gi[ss, K.I_G1], gi[ss, K.I_G2]])).size
    return n >= BROAD_PAIRS_PER_SPHERE * spheres
#: A sphere-sphere pair is listed while its gap is within LOOKAHEAD times
#: what the candidate test can reach in one step (sphere_reach): a step
#: ahead at constant speeds, so its a_ext state is there when it is needed.
LOOKAHEAD = 2.0
#: The broad phase's overlap tolerance [m]: the candidate test's own
#: TOUCH_TOL (push_reach) twice over, for the round-off of the two ways of
#: computing a centre distance.
BROAD_TOL = 2.0 * TOUCH_TOL


class BroadPhase:
    """The free group's sphere-sphere pairs and the broad phase's state (module docstring).

    gi: the group's packed integer constants (engines.mujoco._kernels); gf: its float ones;
    model: the MjModel."""

    def __init__(self, model, gi: np.ndarray, gf: np.ndarray, P: int):
        from engines.mujoco import _kernels as K

        self.K = K
        k = gi.shape[0]
        sphere = sphere_pairs(gi, gf)
        ss = np.flatnonzero(sphere)
        self.fixed_rows = np.flatnonzero(~sphere).astype(np.int64)
        self.is_ss = sphere
        g1, g2 = gi[ss, K.I_G1], gi[ss, K.I_G2]
        geoms, inv = np.unique(np.concatenate([g1, g2]), return_inverse=True)
        m = geoms.size
        a, b = inv[:ss.size], inv[ss.size:]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        key = lo.astype(np.int64) * m + hi
        order = np.argsort(key, kind="stable")
        self.keys = np.ascontiguousarray(key[order], dtype=np.int64)
        self.krow = np.ascontiguousarray(ss[order], dtype=np.int64)
        self.n_pairs = int(ss.size)
        # each sphere: geom, body, root, radius, on a free joint (its joint and first dof) or welded
        self.geom = geoms.astype(np.int64)
        self.body = model.geom_bodyid[geoms].astype(np.int64)
        self.root = model.body_rootid[self.body].astype(np.int64)
        self.radius = model.geom_size[geoms, 0].astype(float)
        jnt = model.body_jntadr[self.body]
        self.move = ((model.body_jntnum[self.body] == 1) & (jnt >= 0)
                     & (model.jnt_type[np.maximum(jnt, 0)] == mujoco.mjtJoint.mjJNT_FREE))
        self.jnt = np.where(self.move, jnt, 0).astype(np.int64)
        self.dof = np.where(self.move, model.jnt_dofadr[self.jnt], 0).astype(np.int64)
        self.prev_v = np.zeros((m, 3))
        self.prev_w = np.zeros((m, 3))
        self.have_prev = False
        self.c = np.zeros((m, 3))
        self.r = np.zeros(m)
        self.base = np.zeros(m)  # the reach without the push (sphere_reach)
        self.factor = 2.0  # the adapter's CANDIDATE_FACTOR (rows)
        self.call = None  # (rows found, hold arrays, push) of this step's kernel call (the adapter's)
        self.push_g = np.zeros(m)
        self.no_push = np.zeros(m)
        self.dq = np.zeros(model.nv)  # the last step's impulses' velocity change (_after_forces)
        self.dq_set = False
        self.mark = np.full(k, -2, np.int64)
        self.stamp = 0
        self.prev_rows = np.empty(k, np.int64)
        self.nprev = 0
        self.out = np.empty(k, np.int64)
        self.new = np.zeros(k, np.bool_)
        self.all_rows = np.arange(k, dtype=np.int64)
        self.on_body = np.zeros(model.nbody, bool)
        self.tree = model.body_treeid[self.body].astype(np.int64)
        self.fresh = np.zeros(m, bool)
        self.dV = np.zeros(model.nbody)
        # the velocity change at a surface point per unit impulse: 1/m + a^2 / I_min, a = the geom's
        # centre's distance from the body's centre of mass + R (0 for a sphere welded to the world)
        arm = np.linalg.norm(model.geom_pos[geoms] - model.body_ipos[self.body], axis=1) + self.radius
        I_min = model.body_inertia[self.body].min(axis=1)
        self.kick = np.where(self.move, 1.0 / model.body_mass[self.body] + arm ** 2 / np.where(I_min > 0, I_min, 1.0),
                             0.0)

    def rows(self, ad, required: np.ndarray, factor: float) -> tuple[np.ndarray, int]:
        """(rows, n): the group's rows ad's kernel reads this step, rows[:n] (n = -1: all of
        them, the first step and when the broad phase was off in the last one); factor: the
        adapter's CANDIDATE_FACTOR."""
        K, d, m = self.K, ad.data, ad.model
        dt = ad.timestep
        self.factor = factor
        g = np.array(m.opt.gravity, dtype=float)
        if m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY:
            g = np.zeros(3)
        push = self._push_of(ad)
        dq = self.dq if self.dq_set else np.zeros_like(self.dq)
        self.dq_set = False
        fresh = self.fresh
        fresh[:] = False
        t_jump, trees = ad._jumped
        if t_jump == float(d.time):  # bodies placed at this step's start: their pairs' a_ext restarts
            if trees is None:
                fresh[:] = True
            else:
                fresh[np.isin(self.tree, trees)] = True
        K.sphere_reach(self.geom, self.body, self.root, self.radius, self.move, self.jnt, self.dof, d.geom_xpos,
                       d.cvel, d.subtree_com, d.xanchor, self.prev_v, self.prev_w, dq, push, fresh, g, dt,
                       factor, LOOKAHEAD, self.c, self.r, self.base)
        self.stamp += 1
        if not self.have_prev:  # the first step: no last velocities to bound a_ext with: every row
            self.have_prev = True
            self.mark[:] = self.stamp
            self.prev_rows[:] = self.all_rows
            self.nprev = self.all_rows.size
            return self.all_rows, -1
        req = np.flatnonzero(required)
        if ad._kin is not None:  # a body the user drives (engines._kinematic): its motion is in its pairs' push
            req = np.concatenate([req, np.asarray(ad._kin.rows, dtype=np.int64)])  # only; its pairs are read
        n = K.broad_rows(ad._gi, self.fixed_rows, self.keys, self.krow, self.geom.size, self.c, self.r, push, BROAD_TOL,
                         req, ad._group_of, self.is_ss, ad._have_last, self.mark, self.stamp,
                         self.prev_rows, self.nprev, self.out, self.new)
        self.nprev = n
        return self.out, n

    def _push_of(self, ad) -> np.ndarray:
        """Each sphere's push [m] (islands.push_reach, the adapter's ``_push_budget`` of its body: 0
        for a body the push of the last step's rows does not reach; a pair's push is the larger of
        its bodies' ones plus TOUCH_TOL)."""
        push = self.push_g
        push[:] = 0.0
        budget = ad._push_budget
        if budget.size:
            on = self.move & (self.root < budget.size)
            push[on] = budget[self.root[on]]
        return push

    def gap_rows(self, ad, kin) -> int:
        """After the manager's step, before push_reach: add to this step's rows the sphere-sphere
        rows whose x can be above minus the largest push budget of this step's rows ``kin``,
        factor dt max |v_rel| (push_reach's paths: every pair whose x is above it, read; the
        others are NaN). Returns the new number of rows."""
        u = np.asarray(kin.v_rel, dtype=float).reshape(-1, 3)
        if not u.shape[0]:
            return self.nprev
        bmax = self.factor * ad.timestep * float(np.sqrt((u * u).sum(axis=1)).max())
        # the x push_reach takes is the kernel's, for a pair closing within the step the sweep's (at most
        # 2 |w| dt below the step-start gap, w <= V_i + V_j: inside sphere_reach's base)
        r = self.radius + self.base + 0.5 * bmax
        self.nprev = self.K.ahead_rows(self.keys, self.krow, self.geom.size, self.c, r, self.no_push, BROAD_TOL,
                                       self.mark, self.stamp, self.prev_rows, self.nprev, self.out, self.new)
        return self.nprev

    def ahead(self, ad, kin, out) -> int:
        """After the manager's step (ad._push now the next step's, from this step's rows ``kin``; the
        step's forces ``out``, ContactForces): add to this step's rows (self.out after the rows(...)
        ones, marked as read) the sphere-sphere rows whose spheres come within reach in the next
        step: sphere_reach's bound without its push (``base``), with each body's velocity change of
        this step's forces (at most dV = sum |F| dt (1/m + a^2/I_min) over its rows, a the lever arm
        of its contact point) added to its speed bound V and twice to its a_ext bound A, plus the
        next step's push. Returns the new number of rows."""
        push = self._push_of(ad)
        dV = self.dV
        dV[:] = 0.0
        pair = np.asarray(out.pair, dtype=np.int64)
        if pair.size:
            P = np.sqrt((np.asarray(out.force, dtype=float).reshape(-1, 3) ** 2).sum(axis=1)) * ad.timestep
            on = P > 0.0
            if np.any(on):
                body = ad._side_body[pair[on]]
                np.add.at(dV, body.ravel(), np.repeat(P[on], 2))
        dV = dV[self.body] * self.kick
        r = self.radius + LOOKAHEAD * (self.base + ad.timestep * (2.0 * self.factor + 2.0) * dV)
        self.nprev = self.K.ahead_rows(self.keys, self.krow, self.geom.size, self.c, r, push, BROAD_TOL, self.mark,
                                       self.stamp, self.prev_rows, self.nprev, self.out, self.new)
        return self.nprev

    def reset(self) -> None:
        """Forget the last step (the broad phase switched off: the next step reads every row)."""
        self.have_prev = False
        self.dq_set = False
