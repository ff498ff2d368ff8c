"""Two spheres closing within a step: the contact geometry at first touch.

The contact manager integrates a contact along the normal it is given at
the step start (x' = -(v . n) with n fixed over the step). For two spheres
that is the line of centres at the step start; when they close with a
tangential relative velocity w_t and a gap g at the step start, the line
of centres turns before they touch, and the normal at first touch differs
from it by up to atan(|w_t| t* / (R1 + R2)). Two glass beads (R = 0.25 mm)
closing at 60 m/s in a 0.1 ms step travel 24 radii: the step-start line is
close to head-on whatever the impact parameter (measured: a 53 deg impact
was solved as a 80 deg one, a bead left at (-28.6, -7.4) m/s instead of
(-13.4, -21.9) m/s).

Free flight of both centres over the step (their relative acceleration,
gravity on both, cancels; a_ext is a correction of order a t*^2) gives the
time of first touch t* >= 0 as the smaller root of

    |e + w t|^2 = S^2,    e = c1 - c2,  w = c1' - c2',  S = R1 + R2,

t* = c / (-b + sqrt(b^2 - a c)) with a = w.w, b = e.w < 0, c = e.e - S^2 > 0
(the cancellation-free form). The adapters then hand the manager the
geometry at that touch: the normal n* = (e + w t*)/|e + w t*| (from body 2
to body 1), the approach x* = (w . n*) t* (< 0: the manager's free flight
x(t) = x* - (w . n*) t reaches 0 at t*), and each body's surface point on
n* from its own centre (c1 - R1 n*, c2 + R2 n*), so the lever arms, W and
the contact-point velocity are those of the touch. Spheres that miss
(b^2 < a c) get the geometry of their closest approach t_c = -b/a: n_c
along e + w t_c, x = S - |e + w t_c| < 0, and w . n_c = 0, so the manager
sees no approach. A touch or a closest approach after the step's end
(t > dt) takes the geometry at the step's end instead: n_dt along e + w dt
and x = S - |e + w dt| + (w . n_dt) dt, the tangent at dt of the gap
S - |e + w t| (concave in t: the tangent never lies below it, so the
manager's x(t) = x - (w . n_dt) t is the true gap at dt and never opens
later than it). The touch or approach of a later step is not this step's:
a row read at a closest approach 14.6 ms (14.6 steps) ahead, x = -12 um
where the spheres were 0.56 mm apart at the step's end, was closed inside
an island step by a floor bounce of one sphere, and the contact that
began held its force into the next step with the spheres 0.45 mm apart
(a 4-sphere pile in MuJoCo gained 7.8e-7 J, scripts/pile.py --n 4 --side 2
--steps 100). Pairs in contact (x >= 0) or not closing (b >= 0) keep
the step-start geometry; so do collinear motions (n* = n up to rounding:
a cradle, a stack).

:func:`sweep` is the numpy form (the adapters' numpy paths);
:func:`sweep_scalar` the compiled one (the adapters' kernels), the same
arithmetic.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from msf_contact._jitcache import guard as _guard


@njit(cache=True, error_model="numpy")
def sweep_scalar(e0, e1, e2, w0, w1, w2, S, dt):
    """(swept, n0, n1, n2, x) for one pair (module docstring): e = c1 - c2
    [m], w = c1' - c2' [m/s], S = R1 + R2 [m], dt [s] the step. swept
    False: keep the step-start geometry (the other outputs are then
    meaningless)."""
    b = e0 * w0 + e1 * w1 + e2 * w2
    ee = e0 * e0 + e1 * e1 + e2 * e2
    c = ee - S * S
    if not (b < 0.0 and c > 0.0):
        return False, 0.0, 0.0, 0.0, 0.0
    a = w0 * w0 + w1 * w1 + w2 * w2
    disc = b * b - a * c
    if disc >= 0.0:
        t = c / (-b + math.sqrt(disc))
    else:
        t = -b / a
    late = t > dt
    if late:
        t = dt
    d0, d1, d2 = e0 + w0 * t, e1 + w1 * t, e2 + w2 * t
    ld = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if not ld > 0.0:
        return False, 0.0, 0.0, 0.0, 0.0
    n0, n1, n2 = d0 / ld, d1 / ld, d2 / ld
    if late:
        x = (S - ld) + (w0 * n0 + w1 * n1 + w2 * n2) * t
    elif disc >= 0.0:
        x = (w0 * n0 + w1 * n1 + w2 * n2) * t
    else:
        x = S - ld
    return True, n0, n1, n2, x


def sweep(e, w, S, dt):
    """Vectorised :func:`sweep_scalar`: e, w (k, 3), S (k,), dt [s]. Returns
    (swept (k,) bool, n (k, 3), x (k,)); rows not swept hold zeros."""
    e = np.asarray(e, dtype=float).reshape(-1, 3)
    w = np.asarray(w, dtype=float).reshape(-1, 3)
    S = np.asarray(S, dtype=float).reshape(-1)
    k = e.shape[0]
    swept = np.zeros(k, bool)
    n = np.zeros((k, 3))
    x = np.zeros(k)
    for i in range(k):  # per row, the same float operations as the compiled form
        s, n0, n1, n2, xx = sweep_scalar(e[i, 0], e[i, 1], e[i, 2], w[i, 0], w[i, 1], w[i, 2], S[i], dt)
        swept[i], n[i, 0], n[i, 1], n[i, 2], x[i] = s, n0, n1, n2, xx
    return swept, n, x


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__)
