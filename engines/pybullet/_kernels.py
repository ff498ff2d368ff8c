"""Compiled (numba) array work of :class:`engines.pybullet.PybulletAdapter`.

The same quantities as the adapter's numpy path (``compiled=False``),
written per pair with scalar arithmetic: ~0.1 ms a step per thousand
resting pairs (measured at N = 1,000 and 10,000), against ~1.3 ms of the
pybullet calls (two reads and one force per body) that are left besides
``manager.step`` and ``stepSimulation``:

- :func:`rotations`: rotation matrices of the bodies' quaternions (as
  ``getMatrixFromQuaternion``);
- :func:`fast_rows`: detection (sphere-plane, sphere-sphere), v_rel, a_ext
  bookkeeping, candidate selection and W, W_com of the pairs of a free
  sphere and a plane or a fixed or free sphere (the adapter's "fast" pairs),
  written in pair order;
- :func:`cross_dv_free`, :func:`add_own_dv`: the cross-pair correction of
  the next step's a_ext (free bodies' share, and held pairs' own W P);
- :func:`body_loads`: the forces of the step summed per free body, for one
  ``applyExternalForce`` per body.

Equality with the numpy path is tested in tests/test_pybullet_kernels.py.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from msf_contact._jitcache import guard as _guard

#: fast_rows' status: done, or two sphere centres coincide (no normal).
OK, COINCIDENT = 0, 1


@njit(cache=True)
def rotations(q):
    """(B, 3, 3) rotation matrices of unit quaternions (x, y, z, w) (B, 4)."""
    B = q.shape[0]
    R = np.empty((B, 3, 3))
    for b in range(B):
        x, y, z, w = q[b, 0], q[b, 1], q[b, 2], q[b, 3]
        R[b, 0, 0] = 1 - 2 * (y * y + z * z)
        R[b, 0, 1] = 2 * (x * y - z * w)
        R[b, 0, 2] = 2 * (x * z + y * w)
        R[b, 1, 0] = 2 * (x * y + z * w)
        R[b, 1, 1] = 1 - 2 * (x * x + z * z)
        R[b, 1, 2] = 2 * (y * z - x * w)
        R[b, 2, 0] = 2 * (x * z - y * w)
        R[b, 2, 1] = 2 * (y * z + x * w)
        R[b, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


@njit(cache=True, inline="always")
def _add_free_W(W, k, rot, j, inv_m, inv_I, r):
    """W[k] += 1/m Id - [r]x I^-1 [r]x (3, 3) of body j, I^-1 = R diag(inv_I) R^T."""
    i0, i1, i2 = inv_I[j, 0], inv_I[j, 1], inv_I[j, 2]
    m00 = rot[j, 0, 0] * i0 * rot[j, 0, 0] + rot[j, 0, 1] * i1 * rot[j, 0, 1] + rot[j, 0, 2] * i2 * rot[j, 0, 2]
    m01 = rot[j, 0, 0] * i0 * rot[j, 1, 0] + rot[j, 0, 1] * i1 * rot[j, 1, 1] + rot[j, 0, 2] * i2 * rot[j, 1, 2]
    m02 = rot[j, 0, 0] * i0 * rot[j, 2, 0] + rot[j, 0, 1] * i1 * rot[j, 2, 1] + rot[j, 0, 2] * i2 * rot[j, 2, 2]
    m10 = rot[j, 1, 0] * i0 * rot[j, 0, 0] + rot[j, 1, 1] * i1 * rot[j, 0, 1] + rot[j, 1, 2] * i2 * rot[j, 0, 2]
    m11 = rot[j, 1, 0] * i0 * rot[j, 1, 0] + rot[j, 1, 1] * i1 * rot[j, 1, 1] + rot[j, 1, 2] * i2 * rot[j, 1, 2]
    m12 = rot[j, 1, 0] * i0 * rot[j, 2, 0] + rot[j, 1, 1] * i1 * rot[j, 2, 1] + rot[j, 1, 2] * i2 * rot[j, 2, 2]
    m20 = rot[j, 2, 0] * i0 * rot[j, 0, 0] + rot[j, 2, 1] * i1 * rot[j, 0, 1] + rot[j, 2, 2] * i2 * rot[j, 0, 2]
    m21 = rot[j, 2, 0] * i0 * rot[j, 1, 0] + rot[j, 2, 1] * i1 * rot[j, 1, 1] + rot[j, 2, 2] * i2 * rot[j, 1, 2]
    m22 = rot[j, 2, 0] * i0 * rot[j, 2, 0] + rot[j, 2, 1] * i1 * rot[j, 2, 1] + rot[j, 2, 2] * i2 * rot[j, 2, 2]
    r0, r1, r2 = r[0], r[1], r[2]
    # T = [r]x I^-1, rows of [r]x: (0, -r2, r1), (r2, 0, -r0), (-r1, r0, 0)
    t00, t01, t02 = -r2 * m10 + r1 * m20, -r2 * m11 + r1 * m21, -r2 * m12 + r1 * m22
    t10, t11, t12 = r2 * m00 - r0 * m20, r2 * m01 - r0 * m21, r2 * m02 - r0 * m22
    t20, t21, t22 = -r1 * m00 + r0 * m10, -r1 * m01 + r0 * m11, -r1 * m02 + r0 * m12
    # W -= T [r]x, columns of [r]x: (0, r2, -r1), (-r2, 0, r0), (r1, -r0, 0)
    W[k, 0, 0] -= t01 * r2 - t02 * r1
    W[k, 0, 1] -= -t00 * r2 + t02 * r0
    W[k, 0, 2] -= t00 * r1 - t01 * r0
    W[k, 1, 0] -= t11 * r2 - t12 * r1
    W[k, 1, 1] -= -t10 * r2 + t12 * r0
    W[k, 1, 2] -= t10 * r1 - t11 * r0
    W[k, 2, 0] -= t21 * r2 - t22 * r1
    W[k, 2, 1] -= -t20 * r2 + t22 * r0
    W[k, 2, 2] -= t20 * r1 - t21 * r0
    W[k, 0, 0] += inv_m[j]
    W[k, 1, 1] += inv_m[j]
    W[k, 2, 2] += inv_m[j]


@njit(cache=True)
def fast_rows(f, j1, j2, s1, r1, plane, s2, size2, com, rot, v, w, b_free, inv_m, inv_I,
              last_v_rel, last_dv, have_last, last_a_ext, pt, required, grav, dt, factor, push, gaps,
              o_pair, o_x, o_n, o_pt, o_v, o_vc, o_W, o_Wc, o_a):
    """Candidate rows of the fast pairs f (F,) (pair indices, ascending) and
    the a_ext bookkeeping of all of them (the adapter's ``_fast_rows``).

    Per fast pair q: body slots j1, j2; body 1's sphere centre s1 (3,) in its
    inertial frame and radius r1; ``plane``: body 2 is a plane with normal
    size2 (3,) in its inertial axes, else a sphere of radius size2[0] centred
    at s2. Bodies: com, rot, v, w (B, ...); b_free, inv_m, inv_I (B, 3).
    Per pair (P, ...), updated in place: last_v_rel, last_dv (zeroed),
    have_last, last_a_ext, pt. required (P,) bool; grav (3,) [m/s^2]; push
    (P,) [m]: a pair's extra reach from its bodies' other contacts; gaps
    (P,) [m]: every fast pair's x written (islands.push_reach's paths).
    Writes the candidates to o_* (rows 0..k-1, in the order of f) and returns
    (k, status, the first offending fast row or -1)."""
    k = 0
    c1 = np.empty(3)
    c2 = np.empty(3)
    nrm = np.empty(3)
    p = np.empty(3)
    ra = np.empty(3)
    rb = np.empty(3)
    vr = np.empty(3)
    a = np.empty(3)
    for q in range(f.shape[0]):
        i = f[q]
        b1, b2 = j1[q], j2[q]
        for d in range(3):
            c1[d] = com[b1, d] + (rot[b1, d, 0] * s1[q, 0] + rot[b1, d, 1] * s1[q, 1] + rot[b1, d, 2] * s1[q, 2])
            c2[d] = com[b2, d] + (rot[b2, d, 0] * s2[q, 0] + rot[b2, d, 1] * s2[q, 1] + rot[b2, d, 2] * s2[q, 2])
        R1 = r1[q]
        if plane[q]:
            for d in range(3):
                nrm[d] = rot[b2, d, 0] * size2[q, 0] + rot[b2, d, 1] * size2[q, 1] + rot[b2, d, 2] * size2[q, 2]
            nn = math.sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2])
            for d in range(3):
                nrm[d] /= nn
            dist = (c1[0] - c2[0]) * nrm[0] + (c1[1] - c2[1]) * nrm[1] + (c1[2] - c2[2]) * nrm[2]
            x = R1 - dist
        else:
            R2 = size2[q, 0]
            for d in range(3):
                nrm[d] = c1[d] - c2[d]
            dist = math.sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2])
            if dist <= 1e-12 * (R1 + R2):  # engines._geometry.COINCIDENT_RTOL
                return k, COINCIDENT, q
            for d in range(3):
                nrm[d] /= dist
            x = R1 + R2 - dist
        gaps[i] = x
        # the middle of the overlap (of the gap): engines._geometry.Detection.of_sphere; on a
        # plane, body 1's own point (its surface point at a gap, as MuJoCo's adapter), so that
        # the lever arm is R1 - max(x, 0)/2 at every x (the timing correction is removed at
        # the lever it was applied at; LEVER_DOC)
        lift = R1 - 0.5 * max(x, 0.0)
        gap = 0.0 if plane[q] else min(x, 0.0)
        for d in range(3):
            p1 = c1[d] - lift * nrm[d]
            p[d] = 0.5 * (p1 + (p1 + gap * nrm[d]))
            ra[d] = p[d] - com[b1, d]
            rb[d] = p[d] - com[b2, d]
        vr[0] = (v[b1, 0] + (w[b1, 1] * ra[2] - w[b1, 2] * ra[1])) - (v[b2, 0] + (w[b2, 1] * rb[2] - w[b2, 2] * rb[1]))
        vr[1] = (v[b1, 1] + (w[b1, 2] * ra[0] - w[b1, 0] * ra[2])) - (v[b2, 1] + (w[b2, 2] * rb[0] - w[b2, 0] * rb[2]))
        vr[2] = (v[b1, 2] + (w[b1, 0] * ra[1] - w[b1, 1] * ra[0])) - (v[b2, 2] + (w[b2, 0] * rb[1] - w[b2, 1] * rb[0]))
        fd = (1.0 if b_free[b1] else 0.0) - (1.0 if b_free[b2] else 0.0)
        for d in range(3):
            if have_last[i]:
                a[d] = (vr[d] - last_v_rel[i, d] - last_dv[i, d]) / dt
            else:
                a[d] = grav[d] * fd
            last_a_ext[i, d] = a[d]
            last_v_rel[i, d] = vr[d]
            last_dv[i, d] = 0.0
            pt[i, d] = p[d]
        have_last[i] = True
        # engines._contacts.closing_distance of the closing rate and acceleration
        xd = max(-(vr[0] * nrm[0] + vr[1] * nrm[1] + vr[2] * nrm[2]), 0.0)
        xdd = max(-(a[0] * nrm[0] + a[1] * nrm[1] + a[2] * nrm[2]), 0.0)
        reach = factor * (xd * dt + 0.5 * xdd * dt * dt)
        if not (x > -(reach + push[i]) or required[i]):
            continue
        o_pair[k] = i
        o_x[k] = x
        for d in range(3):
            o_n[k, d] = nrm[d]
            o_pt[k, d] = p[d]
            o_v[k, d] = vr[d]
            o_vc[k, d] = v[b1, d] - v[b2, d]
            o_a[k, d] = a[d]
            for e in range(3):
                o_W[k, d, e] = 0.0
                o_Wc[k, d, e] = 0.0
            o_Wc[k, d, d] = inv_m[b1] + inv_m[b2]
        _add_free_W(o_W, k, rot, b1, inv_m, inv_I, ra)
        if b_free[b2]:
            _add_free_W(o_W, k, rot, b2, inv_m, inv_I, rb)
        k += 1
    return k, OK, -1


@njit(cache=True)
def cross_dv_free(ph, P, slot, pt, com, rot, inv_m, inv_I, b_free, b_link, last_dv, moved):
    """The free bodies' share of the adapter's ``_cross_dv``: the impulses P
    (k, 3) on body 1 of the (not held) pairs ph (k,), summed per body as
    impulse and angular impulse about the centre of mass, move each free
    body by dv = lin/m, dw = R diag(inv_I) R^T ang; every pair touching a
    moved free body gets last_dv = its bodies' contact-point velocity change
    (body 1's minus body 2's). ``moved`` (B,) bool is set for every body the
    impulses reach (the adapter does links of multibodies itself)."""
    B = com.shape[0]
    lin = np.zeros((B, 3))
    ang = np.zeros((B, 3))
    for q in range(ph.shape[0]):
        i = ph[q]
        for side in range(2):
            j = slot[i, side]
            s = 1.0 if side == 0 else -1.0
            r0, r1_, r2 = pt[i, 0] - com[j, 0], pt[i, 1] - com[j, 1], pt[i, 2] - com[j, 2]
            lin[j, 0] += s * P[q, 0]
            lin[j, 1] += s * P[q, 1]
            lin[j, 2] += s * P[q, 2]
            ang[j, 0] += s * (r1_ * P[q, 2] - r2 * P[q, 1])
            ang[j, 1] += s * (r2 * P[q, 0] - r0 * P[q, 2])
            ang[j, 2] += s * (r0 * P[q, 1] - r1_ * P[q, 0])
    dv = np.zeros((B, 3))
    dw = np.zeros((B, 3))
    free = np.zeros(B, np.bool_)
    for j in range(B):
        moved[j] = (lin[j, 0] != 0.0 or lin[j, 1] != 0.0 or lin[j, 2] != 0.0
                    or ang[j, 0] != 0.0 or ang[j, 1] != 0.0 or ang[j, 2] != 0.0)
        if not (moved[j] and b_free[j]):
            continue
        free[j] = True
        loc = np.empty(3)
        for e in range(3):  # R^T ang, scaled by the principal inverse inertia
            loc[e] = inv_I[j, e] * (rot[j, 0, e] * ang[j, 0] + rot[j, 1, e] * ang[j, 1] + rot[j, 2, e] * ang[j, 2])
        for d in range(3):
            dv[j, d] = lin[j, d] * inv_m[j]
            dw[j, d] = rot[j, d, 0] * loc[0] + rot[j, d, 1] * loc[1] + rot[j, d, 2] * loc[2]
    for i in range(slot.shape[0]):
        a1, a2 = slot[i, 0], slot[i, 1]
        if not (free[a1] or free[a2]):
            continue
        u0, u1, u2 = pt[i, 0] - com[a1, 0], pt[i, 1] - com[a1, 1], pt[i, 2] - com[a1, 2]
        t0, t1, t2 = pt[i, 0] - com[a2, 0], pt[i, 1] - com[a2, 1], pt[i, 2] - com[a2, 2]
        last_dv[i, 0] = ((dv[a1, 0] + (dw[a1, 1] * u2 - dw[a1, 2] * u1))
                         - (dv[a2, 0] + (dw[a2, 1] * t2 - dw[a2, 2] * t1)))
        last_dv[i, 1] = ((dv[a1, 1] + (dw[a1, 2] * u0 - dw[a1, 0] * u2))
                         - (dv[a2, 1] + (dw[a2, 2] * t0 - dw[a2, 0] * t2)))
        last_dv[i, 2] = ((dv[a1, 2] + (dw[a1, 0] * u1 - dw[a1, 1] * u0))
                         - (dv[a2, 2] + (dw[a2, 0] * t1 - dw[a2, 1] * t0)))


@njit(cache=True)
def add_own_dv(ph, W, P, last_dv):
    """last_dv[ph[q]] += W[q] @ P[q]: a held pair's own velocity change."""
    for q in range(ph.shape[0]):
        i = ph[q]
        for d in range(3):
            last_dv[i, d] += W[q, d, 0] * P[q, 0] + W[q, d, 1] * P[q, 1] + W[q, d, 2] * P[q, 2]


@njit(cache=True)
def body_loads(ph, F, point, slot, com, b_push):
    """Forces of the step per pushed body (b_push (B,): free bases; links
    and fixed bodies are the adapter's): +F (k, 3) at ``point`` (k, 3) on
    body 1 of pairs ph, -F on body 2. Returns, in slot order, the bodies
    with one force (slots (m,), force (m, 3), its point (m, 3)) and those
    with several (slots (s,), summed force (s, 3), summed torque about the
    centre of mass (s, 3))."""
    B = com.shape[0]
    count = np.zeros(B, np.int64)
    force = np.zeros((B, 3))
    torque = np.zeros((B, 3))
    at = np.zeros((B, 3))
    for q in range(ph.shape[0]):
        i = ph[q]
        for side in range(2):
            j = slot[i, side]
            if not b_push[j]:
                continue
            s = 1.0 if side == 0 else -1.0
            f0, f1, f2 = s * F[q, 0], s * F[q, 1], s * F[q, 2]
            r0, r1, r2 = point[q, 0] - com[j, 0], point[q, 1] - com[j, 1], point[q, 2] - com[j, 2]
            count[j] += 1
            force[j, 0] += f0
            force[j, 1] += f1
            force[j, 2] += f2
            torque[j, 0] += r1 * f2 - r2 * f1
            torque[j, 1] += r2 * f0 - r0 * f2
            torque[j, 2] += r0 * f1 - r1 * f0
            at[j, 0], at[j, 1], at[j, 2] = point[q, 0], point[q, 1], point[q, 2]
    m = 0
    s_ = 0
    for j in range(B):
        if count[j] == 1:
            m += 1
        elif count[j] > 1:
            s_ += 1
    one, F1, P1 = np.empty(m, np.int64), np.empty((m, 3)), np.empty((m, 3))
    many, Fm, Tm = np.empty(s_, np.int64), np.empty((s_, 3)), np.empty((s_, 3))
    m = 0
    s_ = 0
    for j in range(B):
        if count[j] == 1:
            one[m] = j
            for d in range(3):
                F1[m, d] = force[j, d]
                P1[m, d] = at[j, d]
            m += 1
        elif count[j] > 1:
            many[s_] = j
            for d in range(3):
                Fm[s_, d] = force[j, d]
                Tm[s_, d] = torque[j, d]
            s_ += 1
    return one, F1, P1, many, Fm, Tm


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__)
