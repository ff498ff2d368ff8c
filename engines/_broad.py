"""A broad phase for many spheres: which pairs can meet within a step.

The adapters list a pair of spheres as a candidate for the contact manager
while its gap is within what it can close in the step (CANDIDATE_FACTOR
times the closing speed and acceleration, plus the push of the bodies'
other contacts: ``closing_distance``, ``push_reach``). Testing that for
every pair of n spheres costs n(n-1)/2 tests a step (the jet's 266 beads:
35,245 pairs, ~8 ms a step in MuJoCo, almost all of it for pairs whose
beads are far apart or parked). The broad phase gives each sphere a
*reach* M_i >= 0 [m] such that a pair can be a candidate only if

    |c_i - c_j| - R_i - R_j < M_i + M_j + TOUCH_TOL,

i.e. the spheres of radius R_i + M_i about the centres overlap, and finds
those pairs by sort and sweep (:func:`overlapping_pairs`: the centres'
intervals sorted on the axis of their largest extent, each compared with
the intervals that start before it ends; O(n log n + pairs found) for
spread spheres). A pair's push is the larger of its bodies' (push_reach),
not a sum: :func:`pushed_pairs` adds, for the few pushed spheres, every
sphere within reach plus that push. How an adapter bounds M_i from its own candidate test is
the adapter's (engines.mujoco._kernels.sphere_reach); the property the
adapter relies on, that every pair the all-pairs test lists is among the
overlapping ones, is tested over random spheres in tests/test_broad_phase.py.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from msf_contact._jitcache import guard as _guard


@njit(cache=True, error_model="numpy")
def overlapping_pairs(c, r, tol):
    """The pairs (i, j), i < j, of spheres with centres c (m, 3) [m] and radii
    r (m,) [m] that overlap by more than -tol: |c_i - c_j| < r_i + r_j + tol
    (tol >= 0 [m]). Returns (k, 2) int64, rows (i, j) with i < j, in no
    particular order. Non-finite centres or radii: every pair (the caller's
    narrow test then sees them)."""
    m = c.shape[0]
    finite = True
    for i in range(m):
        if not (np.isfinite(c[i, 0]) and np.isfinite(c[i, 1]) and np.isfinite(c[i, 2]) and np.isfinite(r[i])):
            finite = False
            break
    if not finite:
        out = np.empty((m * (m - 1) // 2, 2), np.int64)
        k = 0
        for i in range(m):
            for j in range(i + 1, m):
                out[k, 0], out[k, 1] = i, j
                k += 1
        return out
    if m < 2:
        return np.empty((0, 2), np.int64)
    # the axis of the largest extent of the centres
    ax = 0
    ext = -1.0
    for a in range(3):
        lo, hi = c[0, a], c[0, a]
        for i in range(1, m):
            lo = min(lo, c[i, a])
            hi = max(hi, c[i, a])
        if hi - lo > ext:
            ext, ax = hi - lo, a
    lo_end = np.empty(m)
    for i in range(m):
        lo_end[i] = c[i, ax] - r[i]
    order = np.argsort(lo_end)
    cap = 4 * m
    out = np.empty((cap, 2), np.int64)
    k = 0
    for a in range(m):
        i = order[a]
        hi_i = c[i, ax] + r[i] + tol
        for b in range(a + 1, m):
            j = order[b]
            if lo_end[j] > hi_i:
                break
            e0, e1, e2 = c[i, 0] - c[j, 0], c[i, 1] - c[j, 1], c[i, 2] - c[j, 2]
            s = r[i] + r[j] + tol
            if e0 * e0 + e1 * e1 + e2 * e2 < s * s:
                if k == cap:
                    cap *= 2
                    grown = np.empty((cap, 2), np.int64)
                    grown[:k] = out[:k]
                    out = grown
                out[k, 0], out[k, 1] = min(i, j), max(i, j)
                k += 1
    return out[:k]


@njit(cache=True, error_model="numpy")
def pushed_pairs(c, r, push, tol):
    """The pairs (i, j), i < j, with |c_i - c_j| < r_i + r_j + max(push_i, push_j) + tol: those
    of :func:`overlapping_pairs` (push 0) and, for each sphere with push_i > 0 (a body a
    contact of the last step can push, few of them), every sphere within r_i + push_i + r_j +
    tol of it. A pair may be listed twice. push (m,) >= 0 [m]."""
    base = overlapping_pairs(c, r, tol)
    m = c.shape[0]
    k = 0
    for i in range(m):
        if push[i] > 0.0:
            k += 1
    if k == 0:
        return base
    extra = np.empty((k * m, 2), np.int64)
    e = 0
    for i in range(m):
        if not push[i] > 0.0:
            continue
        for j in range(m):
            if j == i:
                continue
            s = r[i] + r[j] + max(push[i], push[j]) + tol
            d0, d1, d2 = c[i, 0] - c[j, 0], c[i, 1] - c[j, 1], c[i, 2] - c[j, 2]
            if not d0 * d0 + d1 * d1 + d2 * d2 < s * s and np.isfinite(s) and np.isfinite(d0 + d1 + d2):
                continue
            extra[e, 0], extra[e, 1] = min(i, j), max(i, j)
            e += 1
    out = np.empty((base.shape[0] + e, 2), np.int64)
    out[:base.shape[0]] = base
    out[base.shape[0]:] = extra[:e]
    return out


def all_pairs(c, r, tol, push=None):
    """The same pairs as :func:`overlapping_pairs` (push None) or :func:`pushed_pairs` by testing
    every pair (numpy; the tests' reference): (k, 2) int64 rows (i, j), i < j, in row-major
    order."""
    c = np.asarray(c, dtype=float).reshape(-1, 3)
    r = np.asarray(r, dtype=float).reshape(-1)
    i, j = np.triu_indices(c.shape[0], 1)
    d2 = ((c[i] - c[j]) ** 2).sum(axis=1)
    s = r[i] + r[j] + tol
    if push is not None:
        push = np.asarray(push, dtype=float).reshape(-1)
        s = s + np.maximum(push[i], push[j])
    on = d2 < s * s
    return np.stack([i[on], j[on]], axis=1).astype(np.int64)


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__)
