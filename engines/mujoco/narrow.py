"""MuJoCo's own narrow phase for managed pairs, without force (issue 13).

The adapter's model excludes a managed pair (``<contact><exclude>``), so
MuJoCo makes no contact of its own there. To find the pair's contact points
anyway, :class:`NarrowPhase` keeps a private copy of the model in which only
the managed geoms collide and nothing is excluded, with a detection margin
so that points about to touch are listed too, and runs ``mj_kinematics`` and
``mj_collision`` on a private MjData at the current ``qpos``. Nothing is
written to the user's MjData: detection is forceless by construction. The
points are MuJoCo's (a box on a plane: its corners; a capsule: its segment's
end spheres; a mesh: its vertices' contact), each with the signed distance,
the point midway between the surfaces and the normal.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

#: Smallest detection margin [m]: float rounding of a resting contact.
MARGIN_FLOOR = 1e-6


class NarrowPhase:
    """Forceless detection for geom pairs ``pairs`` [(geom1, geom2), ...] of
    ``model`` (geom ids; body 1's geom first)."""

    def __init__(self, model: mujoco.MjModel, pairs: list[tuple[int, int]]):
        self.model = copy.deepcopy(model)
        m = self.model
        self.data = mujoco.MjData(m)
        self.geoms = np.array(sorted({g for pr in pairs for g in pr}), dtype=int)
        m.geom_contype[:] = 0
        m.geom_conaffinity[:] = 0
        m.geom_contype[self.geoms] = 1
        m.geom_conaffinity[self.geoms] = 1
        m.exclude_signature[:] = -1  # no body pair matches: nothing excluded here
        m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        m.geom_gap[:] = 0.0
        self._index = {}
        for i, (g1, g2) in enumerate(pairs):
            self._index.setdefault((int(g1), int(g2)), []).append(i)
        self.pairs = [(int(a), int(b)) for a, b in pairs]

    def detect(self, data: mujoco.MjData, margin, columns: bool = True) -> list[tuple[np.ndarray, np.ndarray,
                                                                                      np.ndarray]]:
        """Per pair: (x [m] (k,), point [m] (k, 3), normal (k, 3)) of the k
        points MuJoCo finds within ``margin`` [m] (per managed geom (G,) or
        one number): x = -dist the approach (negative: a gap), the point
        midway between the surfaces, the unit normal from body 2 to body 1.
        columns: the contact list read as arrays (False: contact by contact,
        the reference; the same values, tests/test_rest_cost_paths.py)."""
        m, d = self.model, self.data
        d.qpos[:] = data.qpos
        if m.nmocap:
            d.mocap_pos[:] = data.mocap_pos
            d.mocap_quat[:] = data.mocap_quat
        m.geom_margin[self.geoms] = np.maximum(margin, MARGIN_FLOOR)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        if not columns:
            return self._found_each(d)
        found = [[] for _ in self.pairs]
        nc = int(d.ncon)
        c = d.contact
        # the contact list's columns read at once (each contact's fields alone cost a Python object each)
        g1, g2 = c.geom1[:nc].tolist(), c.geom2[:nc].tolist()
        signs = [[] for _ in self.pairs]
        index = self._index
        for j in range(nc):
            a, b = g1[j], g2[j]
            # MuJoCo's normal (frame row 0) points from geom1 to geom2
            for key, sg in (((a, b), -1.0), ((b, a), 1.0)):
                for i in index.get(key, ()):
                    found[i].append(j)
                    signs[i].append(sg)
        if nc:
            dist, pos, frame = c.dist[:nc], c.pos[:nc], c.frame[:nc, :3]
        out = []
        for rows, sg in zip(found, signs):
            if rows:
                r = np.array(rows)
                out.append((-dist[r], pos[r], np.array(sg)[:, None] * frame[r]))
            else:
                out.append((np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))))
        return out

    def _found_each(self, d: mujoco.MjData) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """:meth:`detect`'s result from the contacts of ``d`` read one by one."""
        found = [[] for _ in self.pairs]
        for c in d.contact[:d.ncon]:
            a, b = int(c.geom1), int(c.geom2)
            # MuJoCo's normal (frame row 0) points from geom1 to geom2
            for key, sign in (((a, b), -1.0), ((b, a), 1.0)):
                for i in self._index.get(key, ()):
                    found[i].append((-float(c.dist), np.array(c.pos), sign * np.array(c.frame[:3])))
        out = []
        for rows in found:
            if rows:
                x, pos, nrm = zip(*rows)
                out.append((np.array(x), np.array(pos), np.array(nrm)))
            else:
                out.append((np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))))
        return out
