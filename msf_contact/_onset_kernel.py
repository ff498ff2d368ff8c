"""Compiled onset constants of the MSF law's engine path (numba).

:meth:`msf_contact.laws.MSFLaw.onset` for the engines' usual case (the
self-consistent omega_x, ``msf`` k_p on a sphere, frequency-independent
moduli, every row's eps = x_0/2R inside the onset table,
``_scaling.EPS_NODES``) is a chain of some forty numpy operations on a few
rows: ~90 us per call, a third of a jet impact's cost. :func:`onset_rows`
does the same arithmetic per row in one compiled pass, in the numpy form's
order of operations:

- the table (``_scaling.EpsTable``, a scipy ``CubicSpline``): the interval
  i with x_i <= eps < x_i+1 (the last one closed on the right) and the
  polynomial summed as scipy's ``evaluate_poly1`` does, c3 + c2 s + c1 s^2
  + c0 s^3 with the powers of s = eps - x_i built by repeated products;
- omega_x = 3 tg(beta)/gamma/t_0, or pi/(T_tau t_0) where gamma = 0 (46),
  (87); x_max = x_0 X_max;
- the shear lengths (36) at x_max with the msf k_p of (15), omega_y, omega_z
  of (84)/(86) and the loss moduli over them.

:func:`stiffness_rows` is MSFLaw.tangential_stiffness on the same terms
(the engines call it at every onset).

x_0 = (m V^2/K)^(2/5) itself is computed by the caller with numpy (its
``power`` is not libm's ``pow`` on every CPU; the two differ by an ulp):
with that, every other operation is a correctly rounded +, -, *, / or sqrt,
so the compiled rows equal the numpy form bit for bit
(tests/test_laws.py). This module imports nothing from the engines.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from ._jitcache import guard as _guard

#: Rows of the (NKEYS, n) result, in the order of MSFLaw._onset_dict's keys.
KEYS = ("omega_x", "omega_y", "omega_z", "E", "eta_E", "G", "eta_Gy", "eta_Gz", "x_max_pred", "v_n0", "mass")
NKEYS = len(KEYS)
#: The spline's columns used (EpsTable's order: gamma, tau, tau1, x_max, cor, F_max, dtau_dgamma).
_GAMMA, _TAU, _XMAX = 0, 1, 3
#: onset_rows' answers: done; a row outside the table (or NaN); tg(beta) of G above 1 (no damped
#: oscillation in y). The caller then takes the numpy path, which handles or refuses them.
OK, OUT_OF_TABLE, NO_OSCILLATION = 0, 1, 2


@njit(cache=True, error_model="numpy", inline="always")
def _poly(c, i, col, s):
    """scipy's evaluate_poly1 at s in interval i of column col (c (4, n_int, ncol))."""
    res = 0.0
    z = 1.0
    k = c.shape[0]
    for kp in range(k):
        res = res + c[k - kp - 1, i, col] * z
        if kp < k - 1:
            z *= s
    return res


@njit(cache=True, error_model="numpy", inline="always")
def _shear(x_in, R_a, R_b, k_ha, k_hb):
    """(36) at x_in [m] with the msf k_p of (15) clamped below x/R = 2, as
    MSFLaw.shear_lengths and geometry.kp_clamped compute it: (P_bx, P_ax) [m]
    (np.maximum's and np.minimum's NaN rules kept; np.maximum(-0.0, 0) is 0.0)."""
    x = x_in if (x_in > 0.0 or x_in != x_in) else 0.0  # np.maximum(x, 0.0): -0.0 gives 0.0 there too
    rb, ra = x / R_b, x / R_a
    cap = 2.0 - 1e-12
    kpb = math.sqrt(2.0 - (rb if (rb <= cap or rb != rb) else cap))  # np.minimum(ratio, cap)
    kpa = math.sqrt(2.0 - (ra if (ra <= cap or ra != ra) else cap))
    return k_ha * x + 2.0 * kpb * math.sqrt(R_b * x), k_hb * x + 2.0 * kpa * math.sqrt(R_a * x)


@njit(cache=True, error_model="numpy")
def stiffness_rows(x, G, eta_y, eta_z, R_a, R_b, k_ha, k_hb, k, b):
    """MSFLaw.tangential_stiffness (msf k_p on a sphere) per row: k = (G P_bx,
    G P_ax) [N/m], b = (eta_Gy P_bx, eta_Gz P_ax) [N s/m] into k, b (n, 2)
    from x, G, eta_y, eta_z (n,)."""
    for r in range(x.shape[0]):
        P_bx, P_ax = _shear(x[r], R_a, R_b, k_ha, k_hb)
        k[r, 0] = G[r] * P_bx
        k[r, 1] = G[r] * P_ax
        b[r, 0] = eta_y[r] * P_bx
        b[r, 1] = eta_z[r] * P_ax


@njit(cache=True, error_model="numpy")
def onset_rows(v, m, x0, two_R, tg, nodes, c, E, E_loss, G, G_loss, tg_G, k_ha, k_hb, R_a, R_b, out):
    """The onset constants of rows (n,) into out (NKEYS, n) (module docstring).

    v [m/s], m [kg], x0 [m] (n,): onset speeds, masses, x_0 = (m V^2/K)^(2/5);
    two_R = 2R [m]; tg = tg(beta) of E; nodes (N,), c (4, N - 1, 7): the
    table's spline (knots and coefficients); E, E_loss, G, G_loss [Pa]; tg_G
    = G_loss/G; k_ha, k_hb [-], R_a, R_b [m]: the geometry. Returns OK, or
    OUT_OF_TABLE / NO_OSCILLATION (out then undefined)."""
    n = v.shape[0]
    if tg_G > 1.0:
        return NO_OSCILLATION
    lo, hi = nodes[0], nodes[nodes.shape[0] - 1]
    last = nodes.shape[0] - 2
    q = math.sqrt(1.0 - tg_G * tg_G)
    c3 = 3.0 * tg
    for r in range(n):
        x0r = x0[r]
        eps = x0r / two_R
        if not (lo <= eps <= hi):
            return OUT_OF_TABLE
        i = last
        if eps != hi:
            i = 0
            while eps >= nodes[i + 1]:
                i += 1
        s = eps - nodes[i]
        gam = _poly(c, i, _GAMMA, s)
        t0 = x0r / v[r]
        if gam > 0:
            w_x = c3 / gam / t0
        else:
            w_x = math.pi / (_poly(c, i, _TAU, s) * t0)
        x_m = x0r * _poly(c, i, _XMAX, s)
        P_bx, P_ax = _shear(x_m, R_a, R_b, k_ha, k_hb)  # (36) at x_max
        # (84)/(86): omega^2 = C/m / 2 (1 + sqrt(1 - tg^2))
        w_y = math.sqrt(G * P_bx / m[r] / 2.0 * (1.0 + q))
        w_z = math.sqrt(G * P_ax / m[r] / 2.0 * (1.0 + q))
        out[0, r] = w_x
        out[1, r] = w_y
        out[2, r] = w_z
        out[3, r] = E
        out[4, r] = E_loss / w_x
        out[5, r] = G
        out[6, r] = G_loss / w_y
        out[7, r] = G_loss / w_z
        out[8, r] = x_m
        out[9, r] = v[r]
        out[10, r] = m[r]
    return OK


# numba's cache keyed on every source compiled in (msf_contact._jitcache)
_guard(__name__)
