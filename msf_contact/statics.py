"""Static overlaps: where a resting contact of the model sits (issue 10).

At rest the approach rate x' vanishes, so the viscous term of the normal
force (37) (2 eta'_E psi x' sqrt(x)) vanishes with it and the force is the
elastic part alone, the force-approach law

    F_n(x, 0) = (2/3) E' psi(x) x^(3/2),   psi = k_pa sqrt(R_a) + k_pb sqrt(R_b)  (29),

for a sphere (R_a = R_b = R) (43) at zero rate: F_n(x, 0) = (4/3) k_p E'
sqrt(R) x^(3/2), with k_p in the law's mode (``msf``: sqrt(2 - x/R) at the
current x, (15); ``hertz``: 1, Hertz (30)), and for a line contact W(x)
(2/3) E' x (37) with its footprint width. E' is the storage modulus the
contact carries (a contact's onset constants: with a master curve, E' at
its collision frequency omega_x, (46)). The *static overlap* x_s of a
contact that carries the normal force F is the root of

    F_n(x_s, 0) = F,

unique because F_n(x, 0) increases with x over the law's range (x < 2R in
the ``msf`` mode). F is what the static balance of the bodies requires:
in a vertical column of spheres on a plate each contact carries the weight
of the spheres above it (:func:`column_loads`, exact); in a pile the
balance is hyperstatic (more contacts than equations), so the contacts'
own normal forces are taken (the engines' ``contact_forces``).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from .laws import ForceLaw

#: Relative tolerance of the static overlap's root [-]: far below anything an engine resolves
#: (1e-12 of a 0.1 mm overlap is 1e-16 m, float64 round-off of the centres' positions).
STATIC_XTOL_REL = 1e-12


def elastic_force(law: ForceLaw, x, onset: dict) -> np.ndarray:
    """The law's normal force at zero approach rate, F_n(x, 0) [N] (n,): the
    elastic part of (37) ((43) for a sphere). x [m] (n,); onset: the
    contacts' onset constants (law.onset), each (n,) (the storage modulus
    E' of the contact)."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    return law.contact_normal_force(x, np.zeros(x.size), onset)


def static_overlap(law: ForceLaw, force, onset: dict) -> np.ndarray:
    """The static overlap x_s [m] (n,) of contacts carrying the normal forces
    ``force`` [N] (n,): the root of F_n(x_s, 0) = force (the module
    docstring), to STATIC_XTOL_REL. onset: the contacts' onset constants
    (law.onset, or an engine manager's per-contact ones), each (n,).
    A zero force gives 0; a negative force, or one the law cannot carry
    within its range (x < 2 min(R_a, R_b) in the msf k_p mode), is a
    ValueError."""
    F = np.atleast_1d(np.asarray(force, dtype=float))
    if not np.all(np.isfinite(F)) or np.any(F < 0):
        raise ValueError(f"force = {F!r} N must be finite and >= 0")
    o = {k: np.broadcast_to(np.asarray(v, dtype=float), F.shape).copy() for k, v in onset.items()}
    cap = law.x_limit
    out = np.zeros(F.size)
    for i in np.flatnonzero(F > 0):
        oi = {k: v[i:i + 1] for k, v in o.items()}

        def miss(x, i=i, oi=oi):
            return float(elastic_force(law, x, oi)[0]) - F[i]

        top = None if cap is None else cap * (1.0 - 1e-12)  # the last approach inside the range
        hi = 1e-9
        while miss(hi) < 0.0:
            if top is not None and hi >= top:
                raise ValueError(f"force[{i}] = {F[i]!r} N exceeds what the law carries below its range "
                                 f"x < {cap!r} m (F_n(x, 0) = {miss(hi) + F[i]!r} N there)")
            hi = 2.0 * hi if top is None else min(2.0 * hi, top)
        out[i] = brentq(miss, 0.0, hi, xtol=STATIC_XTOL_REL * hi, rtol=STATIC_XTOL_REL)
    return out


def column_loads(masses, gravity: float) -> np.ndarray:
    """Normal forces [N] (n,) of a vertical column of n bodies resting on a
    plate, masses [kg] (n,) listed from the bottom up, gravity [m/s^2]: the
    contact below body k carries the weight of bodies k..n-1 (static
    balance of each body along the vertical; exact for a column: one
    contact below and one above each body)."""
    m = np.atleast_1d(np.asarray(masses, dtype=float))
    if m.ndim != 1 or m.size == 0 or not np.all(np.isfinite(m)) or np.any(m <= 0):
        raise ValueError(f"masses = {m!r} kg must be a non-empty 1-d array of finite values > 0")
    g = float(gravity)
    if not np.isfinite(g) or g <= 0:
        raise ValueError(f"gravity = {gravity!r} m/s^2 must be finite and > 0")
    return g * np.cumsum(m[::-1])[::-1]


__all__ = ["STATIC_XTOL_REL", "column_loads", "elastic_force", "static_overlap"]
