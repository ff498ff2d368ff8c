"""Compiled (numba) per-step work of the MuJoCo adapter's free group.

The same arithmetic as the numpy methods of
:class:`engines.mujoco.adapter._FreeGroup` and the a_ext bookkeeping of
:class:`engines.mujoco.adapter.MujocoAdapter`, written per pair with scalar
loops and compiled, reading the MjData arrays (numpy views) directly:

1. :func:`free_kinematics_into`: detection (sphere-plane, sphere-sphere;
   :mod:`engines._geometry`), v_rel from ``cvel``, the a_ext estimate and its
   state, the candidate test (:func:`engines._contacts.closing_distance`),
   W, W_com and v_com_rel of the candidates;
2. :func:`after_step`: :func:`engines.mujoco.adapter.held_forces` for the
   rows with a force, and :func:`free_forces`: what :func:`apply` adds to
   ``qfrc_passive`` (or to an impulse vector) in every hook call of the
   step: the free joints' generalised force (force; torque about the joint
   anchor in body axes);
3. :func:`velocity_change` and :func:`held_dv`: the change of every pair's
   v_rel this step's impulses cause, for the next step's a_ext.

The group's constants are packed into two arrays built once by the adapter:
``gi`` (k, NGI) int64 with the columns ``I_*`` and ``gf`` (k, NGF) float64
with the columns ``F_*``. Equality with the numpy path:
tests/test_mujoco_kernels.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engines import _broad, _sweep
from engines._sweep import sweep_scalar
from msf_contact._jitcache import guard as _guard

# columns of gi (int64): geoms, bodies, the bodies' root bodies (subtree_com),
# free joints and their first dofs, flags, pair index
I_G1, I_G2, I_B1, I_B2, I_ROOT1, I_ROOT2, I_JNT1, I_JNT2, I_DOF1, I_DOF2, I_PLANE, I_FREE2, I_PAIR = range(13)
NGI = 13
# columns of gf (float64): radii [m] (R2 nan: plane), inverse masses [1/kg] (0: fixed body 2),
# first-step a_ext [m/s^2] (3), inverse principal inertias of bodies 1 and 2 [1/(kg m^2)] (3 each)
F_R1, F_R2, F_INV_M1, F_INV_M2, F_A0, F_INVI1, F_INVI2 = 0, 1, 2, 3, 4, 7, 10
NGF = 13

#: error codes of free_kinematics_into (the adapter then calls the numpy detection, which raises)
ERR_NONE, ERR_NONFINITE, ERR_COINCIDENT = 0, 1, 2


@njit(cache=True, error_model="numpy", inline="always")
def _nonneg(v):
    """np.maximum(v, 0.0) (nan stays nan)."""
    return 0.0 if v < 0.0 else v


@njit(cache=True, error_model="numpy", inline="always")
def _iinv(X, b, i, j, iI0, iI1, iI2):
    """(R diag(1/I) R^T)_ij as (R * (1/I)) @ R^T sums it (R = X[b] row-major (9,), indexed in
    place: a row slice costs a reference count per call)."""
    return (((X[b, 3 * i] * iI0) * X[b, 3 * j] + (X[b, 3 * i + 1] * iI1) * X[b, 3 * j + 1])
            + (X[b, 3 * i + 2] * iI2) * X[b, 3 * j + 2])


@njit(cache=True, error_model="numpy", inline="always")
def _inverse_inertia(W, k, X, b, iI0, iI1, iI2, r0, r1, r2, inv_m, add):
    """W[k] (+)= 1/m Id - [r]x I^-1 [r]x with I^-1 = R diag(1/I) R^T (R = X[b]
    row-major (9,), 1/I = iI): the products of the numpy path's matmuls
    (R * (1/I)) @ R^T, [r]x @ I^-1, (.) @ [r]x, without the terms with
    the zeros of [r]x (adding an exact zero changes nothing)."""
    I00, I01, I02 = _iinv(X, b, 0, 0, iI0, iI1, iI2), _iinv(X, b, 0, 1, iI0, iI1, iI2), _iinv(X, b, 0, 2, iI0, iI1, iI2)
    I10, I11, I12 = _iinv(X, b, 1, 0, iI0, iI1, iI2), _iinv(X, b, 1, 1, iI0, iI1, iI2), _iinv(X, b, 1, 2, iI0, iI1, iI2)
    I20, I21, I22 = _iinv(X, b, 2, 0, iI0, iI1, iI2), _iinv(X, b, 2, 1, iI0, iI1, iI2), _iinv(X, b, 2, 2, iI0, iI1, iI2)
    # A = [r]x I^-1, rows of [r]x: (0, -r2, r1), (r2, 0, -r0), (-r1, r0, 0)
    A00, A01, A02 = -r2 * I10 + r1 * I20, -r2 * I11 + r1 * I21, -r2 * I12 + r1 * I22
    A10, A11, A12 = r2 * I00 + -r0 * I20, r2 * I01 + -r0 * I21, r2 * I02 + -r0 * I22
    A20, A21, A22 = -r1 * I00 + r0 * I10, -r1 * I01 + r0 * I11, -r1 * I02 + r0 * I12
    # B = A [r]x, columns of [r]x: (0, r2, -r1), (-r2, 0, r0), (r1, -r0, 0); W = 1/m Id - B
    B00, B01, B02 = A01 * r2 + A02 * -r1, A00 * -r2 + A02 * r0, A00 * r1 + A01 * -r0
    B10, B11, B12 = A11 * r2 + A12 * -r1, A10 * -r2 + A12 * r0, A10 * r1 + A11 * -r0
    B20, B21, B22 = A21 * r2 + A22 * -r1, A20 * -r2 + A22 * r0, A20 * r1 + A21 * -r0
    if add:
        W[k, 0, 0] += inv_m - B00
        W[k, 0, 1] += -B01
        W[k, 0, 2] += -B02
        W[k, 1, 0] += -B10
        W[k, 1, 1] += inv_m - B11
        W[k, 1, 2] += -B12
        W[k, 2, 0] += -B20
        W[k, 2, 1] += -B21
        W[k, 2, 2] += inv_m - B22
    else:
        W[k, 0, 0] = inv_m - B00
        W[k, 0, 1] = -B01
        W[k, 0, 2] = -B02
        W[k, 1, 0] = -B10
        W[k, 1, 1] = inv_m - B11
        W[k, 1, 2] = -B12
        W[k, 2, 0] = -B20
        W[k, 2, 1] = -B21
        W[k, 2, 2] = inv_m - B22


@njit(cache=True, error_model="numpy", _nrt=False)
def free_kinematics_into(gi, gf, geom_xpos, geom_xmat, cvel, subtree_com, xipos, ximat, required,
                         last_v, last_dv, have_last, dt, factor, coincident_rtol, push, last_r, last_gap,
                         hold, hold_n, hold_x, pair, x, nrm, point, v_rel, v_com, W, W_com, a_ext, p1, p2, scratch):
    """:func:`free_kinematics_rows_into` over every pair of the group (no broad phase)."""
    return free_kinematics_rows_into(gi, gf, gi[:, 0], -1, geom_xpos, geom_xmat, cvel, subtree_com, xipos, ximat,
                                     required, last_v, last_dv, have_last, dt, factor, coincident_rtol, push, last_r,
                                     last_gap, hold, hold_n, hold_x, pair, x, nrm, point, v_rel, v_com, W, W_com,
                                     a_ext, p1, p2, scratch)


@njit(cache=True, error_model="numpy", _nrt=False)
def free_kinematics_rows_into(gi, gf, rows, nrows, geom_xpos, geom_xmat, cvel, subtree_com, xipos, ximat, required,
                              last_v, last_dv, have_last, dt, factor, coincident_rtol, push, last_r, last_gap,
                              hold, hold_n, hold_x, pair, x, nrm, point, v_rel, v_com, W, W_com, a_ext, p1, p2,
                              scratch):
    """Kinematics of the group's pairs ``rows[:nrows]`` (group positions, ascending: the
    broad phase's, :func:`broad_rows`; nrows < 0: every pair of the group) and the rows of
    its candidates. A pair not among the rows is left as it is (its a_ext state too: the
    broad phase clears ``have_last`` of a pair it stops listing).

    gi, gf: the group's constants (module docstring); MjData arrays as they
    are; required (P,) bool; last_v, last_dv (P, 3), have_last (P,): the
    a_ext state, updated for every pair of the group; dt [s]; factor: the
    adapter's CANDIDATE_FACTOR; coincident_rtol: engines._geometry's; push
    (P,) [m]: a pair's extra reach from its bodies' other contacts; last_r
    (P, 6) [m], last_gap (P,) bool: a sphere-sphere pair's lever arms of the
    last step (body 1's, body 2's contact point from its root's centre of
    mass) and whether it was at a gap then (the adapter's ``_last_r``);
    hold (P,) bool, hold_n (P, 3), hold_x (P,) [m]: a sphere-sphere contact
    shorter than a step that is in progress or has a correction to remove
    keeps the normal of its onset and the manager's approach (the adapter's
    ``_held_geometry``).

    Into the caller's arrays (each with at least k = len(gi) rows; the
    adapter keeps them from step to step, so nothing is allocated, boxed or
    freed per step): pair (k,) int64, x (k,), normal, point, v_rel,
    v_com_rel (k, 3), W, W_com (k, 3, 3), a_ext (k, 3): the n candidates in
    group order in their first n rows; p1, p2 (k, 3): every pair's contact
    points on body 1 and body 2; scratch (k, 4). Returns (err, n); err !=
    ERR_NONE: a state the numpy detection refuses (nothing updated).

    Compiled without numba's reference counting (as engines._kernel): it
    allocates nothing, and a call from Python then unboxes its arrays without
    a reference-counted wrapper each.
    """
    k = gi.shape[0] if nrows < 0 else nrows
    xs = scratch[:, 0]
    ns = scratch[:, 1:4]
    # detection first, for all pairs: refuse before changing any state
    plane_g = -1
    pn0, pn1, pn2 = 0.0, 0.0, 1.0
    # (MjData rows are indexed in place, not sliced: a slice costs a reference count)
    for t in range(k):
        g = t if nrows < 0 else rows[t]
        ig1, ig2 = gi[g, I_G1], gi[g, I_G2]
        c0, c1, c2 = geom_xpos[ig1, 0], geom_xpos[ig1, 1], geom_xpos[ig1, 2]
        o0, o1, o2 = geom_xpos[ig2, 0], geom_xpos[ig2, 1], geom_xpos[ig2, 2]
        R = gf[g, F_R1]
        if not (np.isfinite(c0) and np.isfinite(c1) and np.isfinite(c2)
                and np.isfinite(o0) and np.isfinite(o1) and np.isfinite(o2)):
            return ERR_NONFINITE, 0
        if gi[g, I_PLANE]:
            g2 = gi[g, I_G2]
            if g2 != plane_g:  # the plane's unit normal, once per plane in a row of pairs
                u0, u1, u2 = geom_xmat[g2, 2], geom_xmat[g2, 5], geom_xmat[g2, 8]
                if not (np.isfinite(u0) and np.isfinite(u1) and np.isfinite(u2)):
                    return ERR_NONFINITE, 0
                ln = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
                if not ln > 0.0:
                    return ERR_NONFINITE, 0
                pn0, pn1, pn2 = u0 / ln, u1 / ln, u2 / ln
                plane_g = g2
            n0, n1, n2 = pn0, pn1, pn2
            dist = (c0 - o0) * n0 + (c1 - o1) * n1 + (c2 - o2) * n2
            xx = R - dist
        else:
            R2 = gf[g, F_R2]
            e0, e1, e2 = c0 - o0, c1 - o1, c2 - o2
            dist = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
            if dist <= coincident_rtol * (R + R2):
                return ERR_COINCIDENT, 0
            n0, n1, n2 = e0 / dist, e1 / dist, e2 / dist
            xx = R + R2 - dist
            ph = gi[g, I_PAIR]
            if hold[ph]:
                m0, m1, m2 = hold_n[ph, 0], hold_n[ph, 1], hold_n[ph, 2]
                xw = hold_x[ph]
                xs[g] = xw
                ns[g, 0], ns[g, 1], ns[g, 2] = m0, m1, m2
                s1 = R - 0.5 * (xw if xw > 0.0 else 0.0)
                s2 = R2 - 0.5 * (xw if xw > 0.0 else 0.0)
                p1[g, 0], p1[g, 1], p1[g, 2] = c0 - s1 * m0, c1 - s1 * m1, c2 - s1 * m2
                p2[g, 0], p2[g, 1], p2[g, 2] = o0 + s2 * m0, o1 + s2 * m1, o2 + s2 * m2
                continue
            if xx < 0.0:
                # closing within the step: the geometry at first touch (engines._sweep), from the
                # velocities of the two centres
                b1, b2 = gi[g, I_B1], gi[g, I_B2]
                r1, r2 = gi[g, I_ROOT1], gi[g, I_ROOT2]
                f0, f1, f2 = c0 - subtree_com[r1, 0], c1 - subtree_com[r1, 1], c2 - subtree_com[r1, 2]
                h0, h1, h2 = o0 - subtree_com[r2, 0], o1 - subtree_com[r2, 1], o2 - subtree_com[r2, 2]
                w0 = ((cvel[b1, 3] + (cvel[b1, 1] * f2 - cvel[b1, 2] * f1))
                      - (cvel[b2, 3] + (cvel[b2, 1] * h2 - cvel[b2, 2] * h1)))
                w1 = ((cvel[b1, 4] + (cvel[b1, 2] * f0 - cvel[b1, 0] * f2))
                      - (cvel[b2, 4] + (cvel[b2, 2] * h0 - cvel[b2, 0] * h2)))
                w2 = ((cvel[b1, 5] + (cvel[b1, 0] * f1 - cvel[b1, 1] * f0))
                      - (cvel[b2, 5] + (cvel[b2, 0] * h1 - cvel[b2, 1] * h0)))
                sw, m0, m1, m2, xw = sweep_scalar(e0, e1, e2, w0, w1, w2, R + R2, dt)
                if sw:
                    xs[g] = xw
                    ns[g, 0], ns[g, 1], ns[g, 2] = m0, m1, m2
                    p1[g, 0], p1[g, 1], p1[g, 2] = c0 - R * m0, c1 - R * m1, c2 - R * m2
                    p2[g, 0], p2[g, 1], p2[g, 2] = o0 + R2 * m0, o1 + R2 * m1, o2 + R2 * m2
                    continue
        xs[g] = xx
        ns[g, 0], ns[g, 1], ns[g, 2] = n0, n1, n2
        # Detection.of_sphere: body 1's surface point at the overlap's middle, body 2's across the gap
        s1 = R - 0.5 * (xx if xx > 0.0 else 0.0)
        s2 = xx if xx < 0.0 else 0.0
        q0, q1, q2 = c0 - s1 * n0, c1 - s1 * n1, c2 - s1 * n2
        p1[g, 0], p1[g, 1], p1[g, 2] = q0, q1, q2
        p2[g, 0], p2[g, 1], p2[g, 2] = q0 + s2 * n0, q1 + s2 * n1, q2 + s2 * n2
    n = 0
    for t in range(k):
        g = t if nrows < 0 else rows[t]
        b1, b2 = gi[g, I_B1], gi[g, I_B2]
        r1, r2 = gi[g, I_ROOT1], gi[g, I_ROOT2]
        # angular (0:3), linear velocity at the subtree com (3:6)
        wa0, wa1, wa2, ua0, ua1, ua2 = cvel[b1, 0], cvel[b1, 1], cvel[b1, 2], cvel[b1, 3], cvel[b1, 4], cvel[b1, 5]
        wb0, wb1, wb2, ub0, ub1, ub2 = cvel[b2, 0], cvel[b2, 1], cvel[b2, 2], cvel[b2, 3], cvel[b2, 4], cvel[b2, 5]
        c10, c11, c12 = subtree_com[r1, 0], subtree_com[r1, 1], subtree_com[r1, 2]
        c20, c21, c22 = subtree_com[r2, 0], subtree_com[r2, 1], subtree_com[r2, 2]
        q10, q11, q12 = p1[g, 0], p1[g, 1], p1[g, 2]
        q20, q21, q22 = p2[g, 0], p2[g, 1], p2[g, 2]
        d10, d11, d12 = q10 - c10, q11 - c11, q12 - c12
        d20, d21, d22 = q20 - c20, q21 - c21, q22 - c22
        vr0 = (ua0 + (wa1 * d12 - wa2 * d11)) - (ub0 + (wb1 * d22 - wb2 * d21))
        vr1 = (ua1 + (wa2 * d10 - wa0 * d12)) - (ub1 + (wb2 * d20 - wb0 * d22))
        vr2 = (ua2 + (wa0 * d11 - wa1 * d10)) - (ub2 + (wb0 * d21 - wb1 * d20))
        p = gi[g, I_PAIR]
        xx = xs[g]
        gap = not gi[g, I_PLANE] and xx < 0.0
        if have_last[p]:
            a0 = vr0 - last_v[p, 0] - last_dv[p, 0]
            a1 = vr1 - last_v[p, 1] - last_dv[p, 1]
            a2 = vr2 - last_v[p, 2] - last_dv[p, 2]
            if gap and last_gap[p]:
                # the points moved on the spheres (the adapter's _last_r): v_rel of the last step
                # read at this step's points, with this step's spins
                e10, e11, e12 = d10 - last_r[p, 0], d11 - last_r[p, 1], d12 - last_r[p, 2]
                e20, e21, e22 = d20 - last_r[p, 3], d21 - last_r[p, 4], d22 - last_r[p, 5]
                a0 -= (wa1 * e12 - wa2 * e11) - (wb1 * e22 - wb2 * e21)
                a1 -= (wa2 * e10 - wa0 * e12) - (wb2 * e20 - wb0 * e22)
                a2 -= (wa0 * e11 - wa1 * e10) - (wb0 * e21 - wb1 * e20)
            a0, a1, a2 = a0 / dt, a1 / dt, a2 / dt
        else:
            a0, a1, a2 = gf[g, F_A0], gf[g, F_A0 + 1], gf[g, F_A0 + 2]
        last_v[p, 0], last_v[p, 1], last_v[p, 2] = vr0, vr1, vr2
        last_dv[p, 0], last_dv[p, 1], last_dv[p, 2] = 0.0, 0.0, 0.0
        have_last[p] = True
        last_gap[p] = gap
        if gap:
            last_r[p, 0], last_r[p, 1], last_r[p, 2] = d10, d11, d12
            last_r[p, 3], last_r[p, 4], last_r[p, 5] = d20, d21, d22
        n0, n1, n2 = ns[g, 0], ns[g, 1], ns[g, 2]
        xd = -(vr0 * n0 + vr1 * n1 + vr2 * n2)
        xdd = -(a0 * n0 + a1 * n1 + a2 * n2)
        reach = factor * (_nonneg(xd) * dt + 0.5 * _nonneg(xdd) * dt * dt)  # closing_distance
        if not (xx > -(reach + push[p]) or required[p]):
            continue
        pair[n] = p
        x[n] = xx
        nrm[n, 0], nrm[n, 1], nrm[n, 2] = n0, n1, n2
        point[n, 0], point[n, 1], point[n, 2] = 0.5 * (q10 + q20), 0.5 * (q11 + q21), 0.5 * (q12 + q22)
        v_rel[n, 0], v_rel[n, 1], v_rel[n, 2] = vr0, vr1, vr2
        a_ext[n, 0], a_ext[n, 1], a_ext[n, 2] = a0, a1, a2
        x10, x11, x12 = xipos[b1, 0], xipos[b1, 1], xipos[b1, 2]
        x20, x21, x22 = xipos[b2, 0], xipos[b2, 1], xipos[b2, 2]
        _inverse_inertia(W, n, ximat, b1, gf[g, F_INVI1], gf[g, F_INVI1 + 1], gf[g, F_INVI1 + 2],
                         q10 - x10, q11 - x11, q12 - x12, gf[g, F_INV_M1], False)
        if gi[g, I_FREE2]:
            _inverse_inertia(W, n, ximat, b2, gf[g, F_INVI2], gf[g, F_INVI2 + 1], gf[g, F_INVI2 + 2],
                             q20 - x20, q21 - x21, q22 - x22, gf[g, F_INV_M2], True)
        wc = gf[g, F_INV_M1] + gf[g, F_INV_M2]
        W_com[n, 0, 0], W_com[n, 0, 1], W_com[n, 0, 2] = wc, 0.0, 0.0
        W_com[n, 1, 0], W_com[n, 1, 1], W_com[n, 1, 2] = 0.0, wc, 0.0
        W_com[n, 2, 0], W_com[n, 2, 1], W_com[n, 2, 2] = 0.0, 0.0, wc
        d10, d11, d12 = x10 - c10, x11 - c11, x12 - c12
        d20, d21, d22 = x20 - c20, x21 - c21, x22 - c22
        v_com[n, 0] = (ua0 + (wa1 * d12 - wa2 * d11)) - (ub0 + (wb1 * d22 - wb2 * d21))
        v_com[n, 1] = (ua1 + (wa2 * d10 - wa0 * d12)) - (ub1 + (wb2 * d20 - wb0 * d22))
        v_com[n, 2] = (ua2 + (wa0 * d11 - wa1 * d10)) - (ub2 + (wb0 * d21 - wb1 * d20))
        n += 1
    return ERR_NONE, n


@njit(cache=True, error_model="numpy")
def free_forces(gi, group_of, pair, force, hit, keep, only_unheld, p1, p2, xipos):
    """What :func:`apply` adds for the rows of the group's pairs among
    ``pair`` (n,) (group position group_of[pair], -1: not in the group)
    with a force (``hit`` (n,)), and if ``only_unheld`` of those not held
    (``keep`` (n,)); forces on body 1 ``force`` (n, 3) [N]. Returns (bodies
    (m, 3) int64 rows [body, free joint, first dof], F (m, 3) [N], r (m, 3)
    [m]): first every body 1 (+F), then every free body 2 (-F), each at its
    contact point, the lever arm r from its centre of mass in world axes
    (held fixed over the step)."""
    m1, m2 = _free_counts(gi, group_of, pair, hit, keep, only_unheld)
    bodies = np.empty((m1 + m2, 3), np.int64)
    F = np.empty((m1 + m2, 3))
    arm = np.empty((m1 + m2, 3))
    free_forces_into(gi, group_of, pair, force, hit, keep, only_unheld, p1, p2, xipos, m1, bodies, F, arm)
    return bodies, F, arm


@njit(cache=True, error_model="numpy", _nrt=False)
def _free_counts(gi, group_of, pair, hit, keep, only_unheld):
    """(bodies 1, free bodies 2) that :func:`free_forces` lists."""
    m1 = 0
    m2 = 0
    for r in range(pair.shape[0]):
        g = group_of[pair[r]]
        if g >= 0 and hit[r] and not (only_unheld and keep[r]):
            m1 += 1
            m2 += gi[g, I_FREE2] != 0
    return m1, m2


@njit(cache=True, error_model="numpy", _nrt=False)
def free_forces_into(gi, group_of, pair, force, hit, keep, only_unheld, p1, p2, xipos, m1, bodies, F, arm):
    """:func:`free_forces` into the caller's arrays (m1: the bodies 1 of :func:`_free_counts`;
    each array at least as long as the rows written, nothing allocated); returns the rows written."""
    j1 = 0
    j2 = m1
    for r in range(pair.shape[0]):
        g = group_of[pair[r]]
        if g < 0 or not hit[r] or (only_unheld and keep[r]):
            continue
        b = gi[g, I_B1]
        bodies[j1, 0], bodies[j1, 1], bodies[j1, 2] = b, gi[g, I_JNT1], gi[g, I_DOF1]
        F[j1, 0], F[j1, 1], F[j1, 2] = force[r, 0], force[r, 1], force[r, 2]
        arm[j1, 0], arm[j1, 1], arm[j1, 2] = p1[g, 0] - xipos[b, 0], p1[g, 1] - xipos[b, 1], p1[g, 2] - xipos[b, 2]
        j1 += 1
        if gi[g, I_FREE2]:
            b = gi[g, I_B2]
            bodies[j2, 0], bodies[j2, 1], bodies[j2, 2] = b, gi[g, I_JNT2], gi[g, I_DOF2]
            F[j2, 0], F[j2, 1], F[j2, 2] = -force[r, 0], -force[r, 1], -force[r, 2]
            arm[j2, 0], arm[j2, 1] = p2[g, 0] - xipos[b, 0], p2[g, 1] - xipos[b, 1]
            arm[j2, 2] = p2[g, 2] - xipos[b, 2]
            j2 += 1
    return j2


@njit(cache=True, error_model="numpy")
def apply(q, xipos, xanchor, xmat, bodies, F, r):
    """Add the forces F (m, 3) [N] at the points xipos[body] + r of the rows
    of ``bodies`` (free_forces) to the generalised force q (nv,): F on the
    linear dofs, (anchor-to-point x F) in body axes on the angular ones."""
    for j in range(bodies.shape[0]):
        b, jn, a = bodies[j, 0], bodies[j, 1], bodies[j, 2]
        e0 = xipos[b, 0] + r[j, 0] - xanchor[jn, 0]
        e1 = xipos[b, 1] + r[j, 1] - xanchor[jn, 1]
        e2 = xipos[b, 2] + r[j, 2] - xanchor[jn, 2]
        f0, f1, f2 = F[j, 0], F[j, 1], F[j, 2]
        c0 = e1 * f2 - e2 * f1
        c1 = e2 * f0 - e0 * f2
        c2 = e0 * f1 - e1 * f0
        q[a] += f0
        q[a + 1] += f1
        q[a + 2] += f2
        for i in range(3):  # xmat^T (e x F)
            q[a + 3 + i] += (xmat[b, i] * c0 + xmat[b, 3 + i] * c1) + xmat[b, 6 + i] * c2


@njit(cache=True, error_model="numpy", inline="always")
def _moved(dq, a):
    for i in range(6):
        if dq[a + i] != 0.0:
            return True
    return False


@njit(cache=True, error_model="numpy")
def velocity_change(gi, dq, xmat, xanchor, p1, p2, last_dv):
    """:func:`velocity_change_rows` over every pair of the group."""
    velocity_change_rows(gi, gi[:, 0], -1, dq, xmat, xanchor, p1, p2, last_dv)


@njit(cache=True, error_model="numpy")
def velocity_change_rows(gi, rows, nrows, dq, xmat, xanchor, p1, p2, last_dv):
    """last_dv[pair] = J_p dq for the group's pairs ``rows[:nrows]`` (nrows < 0: every pair)
    whose bodies moved (dq (nv,) the change of the generalised velocities), each body at its
    own contact point: v(point) = dq_lin + (xmat dq_ang) x (point - anchor)."""
    for t in range(gi.shape[0] if nrows < 0 else nrows):
        g = t if nrows < 0 else rows[t]
        free2 = gi[g, I_FREE2] != 0
        if not (_moved(dq, gi[g, I_DOF1]) or (free2 and _moved(dq, gi[g, I_DOF2]))):
            continue
        o0, o1, o2 = 0.0, 0.0, 0.0
        for side in range(2):
            if side == 1 and not free2:
                break
            b, a = gi[g, I_B1 + side], gi[g, I_DOF1 + side]
            R, anc = xmat[b], xanchor[gi[g, I_JNT1 + side]]
            pt = p1[g] if side == 0 else p2[g]
            w0 = (R[0] * dq[a + 3] + R[1] * dq[a + 4]) + R[2] * dq[a + 5]
            w1 = (R[3] * dq[a + 3] + R[4] * dq[a + 4]) + R[5] * dq[a + 5]
            w2 = (R[6] * dq[a + 3] + R[7] * dq[a + 4]) + R[8] * dq[a + 5]
            e0, e1, e2 = pt[0] - anc[0], pt[1] - anc[1], pt[2] - anc[2]
            sign = 1.0 if side == 0 else -1.0
            o0 += sign * (dq[a] + (w1 * e2 - w2 * e1))
            o1 += sign * (dq[a + 1] + (w2 * e0 - w0 * e2))
            o2 += sign * (dq[a + 2] + (w0 * e1 - w1 * e0))
        p = gi[g, I_PAIR]
        last_dv[p, 0], last_dv[p, 1], last_dv[p, 2] = o0, o1, o2


@njit(cache=True, error_model="numpy", inline="always")
def _norm3(a0, a1, a2):
    return math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)


@njit(cache=True, error_model="numpy")
def sphere_reach(bg, bb, broot, bR, bmove, bjnt, bdof, geom_xpos, cvel, subtree_com, xanchor, prev_v, prev_w, dq,
                 push_g, fresh, gravity, dt, factor, lookahead, c, r, base):
    """The broad phase's spheres (engines._broad) of the free group's sphere-sphere pairs: for
    each sphere i of them (geom bg[i] on body bb[i], root broot[i], radius bR[i]; bmove[i]: on a
    free joint bjnt[i] with first dof bdof[i], else welded to the world) its centre c[i] and
    r[i] = R_i + lookahead M_i [m], M_i a bound on its share of the candidate test of
    :func:`free_kinematics_rows_into`: a pair at a gap is a candidate only if

        -x < factor (x' dt + x'' dt^2 / 2) + push,

    with x the gap (at the step start, or the sweep's x of first touch or closest approach:
    at most 2 |w| dt shorter, w the centres' relative velocity, engines._sweep), x' <= |v_rel|
    at the contact points, x'' dt <= |a_ext| dt and push <= push_i + push_j + TOUCH_TOL. In a
    frame moving at any velocity v_ref (the median of the centres' velocities: where the
    parked and the flying beads are, the bound is only a matter of cost),

        |w| <= V_i + V_j,  |v_rel| <= V_i + V_j,  V_i = |v_c,i - v_ref| + |omega_i| R_i,

    and a_ext dt = v_rel - last v_rel - last dv (the relative acceleration of the two bodies,
    gravity on both cancelling) is at most A_i + A_j with

        A_i = |v_c,i - v_c,i' - g dt| + (|omega_i| + |omega_i'| + |omega_i - omega_i'|)(R_i + rho_i)
              + |dq_lin,i| + |dq_ang,i| (|c_i - anchor_i| + R_i),

    primes the last step's, rho_i = |c_i - subtree com| (the lever arm of the last step's
    point, engines.mujoco._kernels's gap correction), dq the last step's impulses' velocity
    change (:func:`velocity_change_rows`; a fixed sphere: a_ext = the first-step value, g,
    inside |0 - 0 - g dt|; ``fresh[i]``: body i jumped at this step's start, so every pair of
    it takes the first-step value, 0 or g: A_i = |g| dt). So a pair can be a candidate only
    if its gap is below base_i + base_j + max(push_i, push_j) + TOUCH_TOL, base_i = dt
    ((factor + 2) V_i + factor A_i / 2) and push_i = push_g[i] (the pair's push is the larger
    of its bodies' ones: islands.push_reach; :func:`broad_rows`). r_i = R_i + lookahead base_i:
    ``lookahead`` (> 1) lists a pair earlier than its first possible candidate step at the
    bodies' speeds, so that its a_ext state (last v_rel, last dv) is read a step before it is
    needed, as without a broad phase (the push of the next step is known after this step's
    manager step: BroadPhase.ahead). prev_v, prev_w (m, 3): the last call's centre velocities
    and spins, updated; base (m,) [m]."""
    m = bg.shape[0]
    vc = np.empty((m, 3))
    for i in range(m):
        g, b, rt = bg[i], bb[i], broot[i]
        c[i, 0], c[i, 1], c[i, 2] = geom_xpos[g, 0], geom_xpos[g, 1], geom_xpos[g, 2]
        e0, e1, e2 = c[i, 0] - subtree_com[rt, 0], c[i, 1] - subtree_com[rt, 1], c[i, 2] - subtree_com[rt, 2]
        w0, w1, w2 = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        vc[i, 0] = cvel[b, 3] + (w1 * e2 - w2 * e1)
        vc[i, 1] = cvel[b, 4] + (w2 * e0 - w0 * e2)
        vc[i, 2] = cvel[b, 5] + (w0 * e1 - w1 * e0)
    vref = np.zeros(3)
    if m:
        for a in range(3):
            vref[a] = np.median(vc[:, a])
    for i in range(m):
        g, b, rt = bg[i], bb[i], broot[i]
        R = bR[i]
        w0, w1, w2 = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        wn = _norm3(w0, w1, w2)
        V = _norm3(vc[i, 0] - vref[0], vc[i, 1] - vref[1], vc[i, 2] - vref[2]) + wn * R
        rho = _norm3(c[i, 0] - subtree_com[rt, 0], c[i, 1] - subtree_com[rt, 1], c[i, 2] - subtree_com[rt, 2])
        A = (_norm3(vc[i, 0] - prev_v[i, 0] - gravity[0] * dt, vc[i, 1] - prev_v[i, 1] - gravity[1] * dt,
                    vc[i, 2] - prev_v[i, 2] - gravity[2] * dt)
             + (wn + _norm3(prev_w[i, 0], prev_w[i, 1], prev_w[i, 2])
                + _norm3(w0 - prev_w[i, 0], w1 - prev_w[i, 1], w2 - prev_w[i, 2])) * (R + rho))
        if fresh[i]:
            A = _norm3(gravity[0], gravity[1], gravity[2]) * dt
        elif bmove[i]:
            a = bdof[i]
            j = bjnt[i]
            arm = _norm3(c[i, 0] - xanchor[j, 0], c[i, 1] - xanchor[j, 1], c[i, 2] - xanchor[j, 2]) + R
            A += _norm3(dq[a], dq[a + 1], dq[a + 2]) + _norm3(dq[a + 3], dq[a + 4], dq[a + 5]) * arm
        base[i] = dt * ((factor + 2.0) * V + 0.5 * factor * A)
        r[i] = R + lookahead * base[i]
        prev_v[i, 0], prev_v[i, 1], prev_v[i, 2] = vc[i, 0], vc[i, 1], vc[i, 2]
        prev_w[i, 0], prev_w[i, 1], prev_w[i, 2] = w0, w1, w2


@njit(cache=True, error_model="numpy")
def _list_pairs(keys, krow, nsph, c, r, push, tol, mark, stamp, out, n, new):
    """Append to out[:n] the sphere-sphere rows of the pairs of spheres c, r within tol plus the
    larger push (engines._broad.pushed_pairs), found by their key i nsph + j in ``keys`` (rows
    ``krow``), that this call (``stamp``) has not listed yet; returns the new count."""
    pairs = _broad.pushed_pairs(c, r, push, tol)
    for t in range(pairs.shape[0]):
        key = pairs[t, 0] * nsph + pairs[t, 1]
        q = np.searchsorted(keys, key)
        while q < keys.shape[0] and keys[q] == key:
            g = krow[q]
            if mark[g] != stamp:
                new[g] = mark[g] != stamp - 1
                mark[g] = stamp
                out[n] = g
                n += 1
            q += 1
    return n


@njit(cache=True, error_model="numpy")
def broad_rows(gi, fixed_rows, keys, krow, nsph, c, r, push, tol, req, group_of, is_ss, have_last, mark, stamp,
               prev_rows, nprev, out, new):
    """The group's rows to read this step (ascending, into out; returns their number): every
    row of ``fixed_rows`` (the pairs that are not sphere-sphere ones), the sphere-sphere rows
    whose spheres' broad-phase spheres (c (nsph, 3), r (nsph,): :func:`sphere_reach`) overlap
    within tol plus the larger of their pushes (push (nsph,) [m]: engines._broad.pushed_pairs)
    and those the manager requires (``req``: the
    pairs in contact or with a timing correction to remove; group_of (P,) their group rows, -1
    outside the group; is_ss (k,): the sphere-sphere rows). The sphere-sphere rows are found
    by their key i nsph + j (i < j: the spheres' positions) in ``keys`` (sorted), whose rows
    are ``krow``. A row listed in the last call (prev_rows[:nprev]) and not now gets
    have_last False (its a_ext starts afresh when it is listed again); new[g]: row g was not
    listed in the last call. mark (k,) int64: the stamp of the call that last listed each
    row (this call's: ``stamp``, the last one's stamp - 1)."""
    n = 0
    for t in range(fixed_rows.shape[0]):
        g = fixed_rows[t]
        new[g] = mark[g] != stamp - 1
        mark[g] = stamp
        out[n] = g
        n += 1
    for t in range(req.shape[0]):
        g = group_of[req[t]]
        if g >= 0 and is_ss[g] and mark[g] != stamp:
            new[g] = mark[g] != stamp - 1
            mark[g] = stamp
            out[n] = g
            n += 1
    n = _list_pairs(keys, krow, nsph, c, r, push, tol, mark, stamp, out, n, new)
    out[:n].sort()
    for t in range(nprev):
        g = prev_rows[t]
        if mark[g] != stamp:
            have_last[gi[g, I_PAIR]] = False
    prev_rows[:n] = out[:n]
    return n


@njit(cache=True, error_model="numpy")
def ahead_rows(keys, krow, nsph, c, r, push, tol, mark, stamp, prev_rows, nprev, out, new):
    """Append to out[:nprev] (the rows :func:`broad_rows` listed in this call, stamp ``stamp``)
    the sphere-sphere rows whose spheres c, r overlap within tol plus the larger of their
    pushes (engines._broad.pushed_pairs) and are not listed yet, marking them listed (and in
    prev_rows); returns the new number of rows."""
    n = _list_pairs(keys, krow, nsph, c, r, push, tol, mark, stamp, out, nprev, new)
    prev_rows[nprev:n] = out[nprev:n]
    return n


@njit(cache=True, error_model="numpy")
def held_dv(last_dv, pair, keep, W, force, dt):
    """last_dv[pair] += W P, P = force dt, for the held rows ``keep`` (the
    pair's own held force, left out of its a_ext like the others')."""
    for r in range(pair.shape[0]):
        if not keep[r]:
            continue
        p = pair[r]
        P0, P1, P2 = force[r, 0] * dt, force[r, 1] * dt, force[r, 2] * dt
        for i in range(3):
            last_dv[p, i] += (W[r, i, 0] * P0 + W[r, i, 1] * P1) + W[r, i, 2] * P2


@njit(cache=True, error_model="numpy")
def after_step(gi, group_of, pair, force, active, settled, t_onset, tau_est, t_next, settle_after, steps_min,
               mgr_dt, p1, p2, xipos, W, last_dv, dt):
    """After the manager's step, for its rows ``pair`` (n,) with forces on
    body 1 ``force`` (n, 3) [N] and inverse inertias W (n, 3, 3): which rows
    have a force (``hit``) and which of them hold it into the next step
    (``keep``: :func:`engines.mujoco.adapter.held_forces` from the
    manager's active, settled, t_onset, tau_est; t_next = the step's end),
    and :func:`free_forces` of the group's rows with a force. When every
    force is held (no impulse leaves the next step's a_ext, so there is no
    cross term), also :func:`held_dv`; else the adapter calls it after
    :func:`velocity_change`.

    Returns (hit, keep, n_hit, n_unheld, bodies, F, r)."""
    n = pair.shape[0]
    hit = np.empty(n, np.bool_)
    keep = np.empty(n, np.bool_)
    n_hit, n_unheld = held_rows(pair, force, active, settled, t_onset, tau_est, t_next, settle_after, steps_min,
                                mgr_dt, hit, keep)
    bodies, F, arm = free_forces(gi, group_of, pair, force, hit, keep, False, p1, p2, xipos)
    if not n_unheld:
        held_dv(last_dv, pair, keep, W, force, dt)
    return hit, keep, n_hit, n_unheld, bodies, F, arm


@njit(cache=True, error_model="numpy", _nrt=False)
def held_rows(pair, force, active, settled, t_onset, tau_est, t_next, settle_after, steps_min, mgr_dt, hit, keep):
    """:func:`after_step`'s hit and keep (n,) into the caller's arrays; returns (n_hit, n_unheld)."""
    n_hit = 0
    n_kept = 0
    for r in range(pair.shape[0]):
        h = force[r, 0] != 0.0 or force[r, 1] != 0.0 or force[r, 2] != 0.0
        p = pair[r]
        kp = h and active[p] and (settled[p] or (t_next - t_onset[p]) > settle_after * tau_est[p]
                                  or tau_est[p] >= steps_min * mgr_dt)
        hit[r] = h
        keep[r] = kp
        n_hit += h
        n_kept += kp
    return n_hit, n_hit - n_kept


@njit(cache=True, error_model="numpy", _nrt=False)
def after_step_into(gi, group_of, pair, force, active, settled, t_onset, tau_est, t_next, settle_after, steps_min,
                    mgr_dt, p1, p2, xipos, W, last_dv, dt, hit, keep, bodies, F, arm):
    """:func:`after_step` into the caller's arrays (hit, keep (n,); bodies, F, arm at least
    2 n rows: nothing allocated); returns (n_hit, n_unheld, m), m the rows of bodies, F, arm
    written."""
    n_hit, n_unheld = held_rows(pair, force, active, settled, t_onset, tau_est, t_next, settle_after, steps_min,
                                mgr_dt, hit, keep)
    m1, _ = _free_counts(gi, group_of, pair, hit, keep, False)
    m = free_forces_into(gi, group_of, pair, force, hit, keep, False, p1, p2, xipos, m1, bodies, F, arm)
    if not n_unheld:
        held_dv(last_dv, pair, keep, W, force, dt)
    return n_hit, n_unheld, m


@njit(cache=True, error_model="numpy")
def required_mask(active, Jst, out):
    """out (P,) bool = the pairs in contact or with a timing correction to
    remove (engines._kernel.required, ContactManager.required_pairs, as a
    mask written in place: the adapter's ``required``)."""
    for q in range(active.shape[0]):
        out[q] = active[q] or Jst[q, 0] != 0.0 or Jst[q, 1] != 0.0 or Jst[q, 2] != 0.0


#: the bits of a double but its sign; the bit pattern of +inf (a NaN's, sign cleared, lie above it)
_ABS_BITS, _INF_BITS = 0x7FFFFFFFFFFFFFFF, 0x7FF0000000000000


@njit(cache=True, error_model="numpy", inline="always")
def _as_float(bits):
    """The double whose bit pattern is the int64 ``bits``."""
    return np.array([bits], np.int64).view(np.float64)[0]


@njit(cache=True, error_model="numpy", inline="always")
def _image_tol(qvel, h, vtol, v0, copy):
    """vtol h (1 + max |qvel|), the tolerance of :func:`off_image` (NaN when qvel holds a NaN);
    with ``copy``, v0 = qvel in the same pass."""
    # max |qvel| as the largest bit pattern of |qvel| (int64 view, sign bit cleared): non-negative
    # doubles order as their bit patterns and a NaN lies above inf, so the integer maximum, which
    # vectorises where a float one may not (NaN), is the float maximum exactly, and above _INF_BITS
    # when a NaN is there
    bits = qvel.view(np.int64)
    m = 0
    for i in range(bits.shape[0]):
        b = bits[i] & _ABS_BITS
        m = b if b > m else m
        if copy:
            v0[i] = qvel[i]
    return vtol * h * (1.0 + _as_float(m)) if m <= _INF_BITS else np.nan


@njit(cache=True, error_model="numpy", inline="always")
def _off_at(q_img, qpos, q0, i, tq):
    """Whether coordinate i of qpos is off the image (:func:`off_image`'s test)."""
    return abs(q_img[i] - qpos[i]) > tq + 1e-13 * (1.0 + abs(q0[i]))


@njit(cache=True, error_model="numpy")
def off_image(q_img, qpos, q0, qvel, h, vtol, bad):
    """Whether any coordinate of qpos is off the step's image q_img (nq,):
    |q_img - qpos| > vtol h (1 + max |qvel|) + 1e-13 (1 + |q0|), the test of
    engines.mujoco._stepping.StepTracker for the semi-implicit integrators,
    in one pass; bad (nq,) bool: which (a NaN anywhere compares False, as
    numpy's: a NaN in qvel makes every tolerance NaN)."""
    tq = _image_tol(qvel, h, vtol, qvel, False)
    off = False
    for i in range(qpos.shape[0]):
        b = _off_at(q_img, qpos, q0, i, tq)
        bad[i] = b
        off |= b
    return off


@njit(cache=True, error_model="numpy")
def off_image_start(q_img, qpos, q0, qvel, v0, h, vtol, bad):
    """:func:`off_image` (its answer and ``bad``), and then the next step's
    start state taken: q0 = q_img = qpos (nq,) (q_img is the base the next
    image is integrated from) and v0 = qvel (nv,), what
    engines.mujoco._stepping.StepTracker._start copies after the test
    whatever its answer. The copies are made in the test's pass, each
    coordinate after it was tested (one pass over the arrays instead of
    three: 6.3 -> 4.3 us at nq = 7,000, nv = 6,000 measured in a loop)."""
    tq = _image_tol(qvel, h, vtol, v0, True)
    off = False
    for i in range(qpos.shape[0]):
        b = _off_at(q_img, qpos, q0, i, tq)
        bad[i] = b
        off |= b
        c = qpos[i]
        q0[i] = c
        q_img[i] = c
    return off


@njit(cache=True, error_model="numpy", inline="always")
def _skew_into(S, i, v0, v1, v2):
    """S[i] = [v]x."""
    S[i, 0, 0], S[i, 0, 1], S[i, 0, 2] = 0.0, -v2, v1
    S[i, 1, 0], S[i, 1, 1], S[i, 1, 2] = v2, 0.0, -v0
    S[i, 2, 0], S[i, 2, 1], S[i, 2, 2] = -v1, v0, 0.0


@njit(cache=True, error_model="numpy", inline="always")
def _mat3(S, o, a, b, sign, add):
    """S[o] (+)= sign S[a] @ S[b]."""
    for i in range(3):
        for j in range(3):
            s = (S[a, i, 0] * S[b, 0, j] + S[a, i, 1] * S[b, 1, j]) + S[a, i, 2] * S[b, 2, j]
            S[o, i, j] = (S[o, i, j] + sign * s) if add else sign * s


@njit(cache=True, error_model="numpy")
def lever_free(gi, gf, group_of, pair, x, normal, a_ext, settled, x_last, cvel, xipos, ximat, p1, p2, dt, out, S):
    """The adapter's ``_lever`` for the free group (engines._contacts.state.LEVER_DOC,
    lever_terms_free): for the rows of ``pair`` (k,) in the group whose pair
    the manager did not settle in the last step, W01, W11 (row-major) and g0
    into out (k, 21) (zeros elsewhere), from the lever arms p_i - xipos_i
    (p1, p2 (P, 3) the pairs' contact points), the world inverse inertias
    R diag(1/I) R^T (gf's F_INVI*; zero for a fixed body 2) and cvel's
    angular velocities; a_ext (k, 3) of those rows less g0 (max(x, 0) -
    x_last)/dt, and x_last (P,) [m] set to max(x, 0) of the rows (0 for
    the other pairs). The same products as the numpy path, summed per entry
    in matmul's order (round-off apart: tests/test_mujoco_kernels.py).
    S (9, 3, 3): scratch. Returns the number of such (live) rows; without
    one, out and a_ext are left as they are."""
    k = pair.shape[0]
    live = 0
    for r in range(k):
        p = pair[r]
        live += group_of[p] >= 0 and not settled[p]
    if live:
        for r in range(k):
            for c in range(21):
                out[r, c] = 0.0
    for r in range(k):
        if not live:
            break
        p = pair[r]
        g = group_of[p]
        xp = _nonneg(x[r])
        xl = x_last[p]
        if g < 0 or settled[p]:
            continue
        b1, b2 = gi[g, I_B1], gi[g, I_B2]
        n0, n1, n2 = normal[r, 0], normal[r, 1], normal[r, 2]
        # S[0], S[1]: the world inverse inertias; S[2] = [n]x, S[3] = [r1]x, S[4] = [r2]x
        for i in range(3):
            for j in range(3):
                S[0, i, j] = _iinv(ximat, b1, i, j, gf[g, F_INVI1], gf[g, F_INVI1 + 1], gf[g, F_INVI1 + 2])
        free2 = gi[g, I_FREE2] != 0
        for i in range(3):
            for j in range(3):
                S[1, i, j] = (_iinv(ximat, b2, i, j, gf[g, F_INVI2], gf[g, F_INVI2 + 1], gf[g, F_INVI2 + 2])
                              if free2 else 0.0)
        _skew_into(S, 2, n0, n1, n2)
        _skew_into(S, 3, p1[p, 0] - xipos[b1, 0], p1[p, 1] - xipos[b1, 1], p1[p, 2] - xipos[b1, 2])
        _skew_into(S, 4, p2[p, 0] - xipos[b2, 0], p2[p, 1] - xipos[b2, 1], p2[p, 2] - xipos[b2, 2])
        # W01 = (-[r1]x I1 [n]x + [r2]x I2 [n]x)/2
        _mat3(S, 5, 3, 0, -1.0, False)  # -[r1]x I1
        _mat3(S, 6, 5, 2, 1.0, False)  # -[r1]x I1 [n]x
        _mat3(S, 5, 4, 1, 1.0, False)  # [r2]x I2
        _mat3(S, 6, 5, 2, 1.0, True)
        # W11 = -[n]x (I1 + I2) [n]x / 4
        for i in range(3):
            for j in range(3):
                S[7, i, j] = S[0, i, j] + S[1, i, j]
        _mat3(S, 8, 2, 7, 1.0, False)
        _mat3(S, 5, 8, 2, 1.0, False)
        for i in range(3):
            for j in range(3):
                out[r, 3 * i + j] = 0.5 * S[6, i, j]
                out[r, 9 + 3 * i + j] = -0.25 * S[5, i, j]
        w0 = cvel[b1, 0] + (cvel[b2, 0] if free2 else 0.0)
        w1 = cvel[b1, 1] + (cvel[b2, 1] if free2 else 0.0)
        w2 = cvel[b1, 2] + (cvel[b2, 2] if free2 else 0.0)
        g0 = 0.5 * (w1 * n2 - w2 * n1)
        g1 = 0.5 * (w2 * n0 - w0 * n2)
        g2 = 0.5 * (w0 * n1 - w1 * n0)
        out[r, 18], out[r, 19], out[r, 20] = g0, g1, g2
        f = (xp - xl) / dt
        a_ext[r, 0] -= g0 * f
        a_ext[r, 1] -= g1 * f
        a_ext[r, 2] -= g2 * f
    for q in range(x_last.shape[0]):
        x_last[q] = 0.0
    for r in range(k):
        x_last[pair[r]] = _nonneg(x[r])
    return live


@njit(cache=True, error_model="numpy")
def add_couples(q, xmat, b, dof, tq):
    """q[dof + 3 + i] += (xmat[b]^T tq)_i for each row: world torques tq (m, 3)
    [N m] on the free bodies b (m,) whose free joints' first dofs are dof (m,),
    in body axes, as the adapter's numpy form (np.add.at of
    einsum('kji,kj->ki', xmat, tq): the products summed in order, the rows
    added in order)."""
    for r in range(b.shape[0]):
        k, a = b[r], dof[r]
        t0, t1, t2 = tq[r, 0], tq[r, 1], tq[r, 2]
        for i in range(3):
            q[a + 3 + i] += (xmat[k, i] * t0 + xmat[k, 3 + i] * t1) + xmat[k, 6 + i] * t2


@njit(cache=True, error_model="numpy")
def geom_changed(size, pos, quat, ids, shape0) -> int:
    """The first k whose geom ids[k] has a size (3), pos (3) or quat (4) in the model (``size``, ``pos``,
    ``quat``: MjModel's geom_size, geom_pos, geom_quat) other than shape0[k] (the adapter's _geom_shape
    at its construction), -1 if none: the adapter's np.array_equal test of the two (a NaN differs, -0.0
    equals 0.0) without the (k, 10) copy (~60-120 us at k = 1,000 in every step() call)."""
    for k in range(ids.shape[0]):
        g = ids[k]
        for i in range(3):
            if size[g, i] != shape0[k, i] or pos[g, i] != shape0[k, 3 + i]:
                return k
        for i in range(4):
            if quat[g, i] != shape0[k, 6 + i]:
                return k
    return -1


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__, _sweep, _broad)
