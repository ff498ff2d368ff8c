"""Dimensionless MSF normal impact: what makes the self-consistent omega cheap.

With frequency-independent moduli the MSF normal law (37) reads

    F_n = K f(x) [x^(3/2) + (3 tg(beta)/omega_x) x' x^(1/2)],   K = 2/3 E' psi_0,

psi_0 = psi at x = 0 (29) and f(x) = psi(x)/psi_0 (1 for constant k_p; for
the ``msf`` k_p of (15) on a sphere f = sqrt(1 - x/(2R))). With
x_0 = (m V^2/K)^(2/5), t_0 = x_0/V, X = x/x_0 and T = t/t_0:

    X'' = -f [X^(3/2) + gamma X' X^(1/2)],  X(0) = 0, X'(0) = 1,
    gamma = 3 tg(beta) / (omega_x t_0),  f = sqrt(1 - eps X),  eps = x_0/(2R).

The collision is self-consistent (46), (87) when omega_x tau = pi, i.e.
gamma = 3 tg(beta) T_tau(gamma, eps)/pi: a scalar root in gamma that
depends on (tg(beta), eps, separation) only. For constant k_p (eps = 0) the
restitution is therefore a function of tg(beta) alone, the property the
paper's (89) approximates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from . import _normal
from ._normal import integrate_normal


@dataclass(frozen=True)
class UnitImpact:
    """A dimensionless normal impact (units x_0, t_0, V, K x_0^(3/2))."""

    gamma: float
    tau: float
    tau1: float
    x_max: float
    cor: float
    F_max: float


@lru_cache(maxsize=8192)
def unit_impact(gamma: float, eps: float, separation: str) -> UnitImpact:
    """Integrate X'' = -f (X^1.5 + gamma X' X^0.5) from X = 0, X' = 1."""

    def force(x, v):
        f = math.sqrt(max(1.0 - eps * x, 1e-300)) if eps else 1.0
        return f * math.sqrt(x) * (x + gamma * v)

    def ind(x, v):
        return x + gamma * v

    s = integrate_normal(force, ind, 1.0, 1.0, 1.0, separation, x_limit=(1.0 / eps) if eps else None)
    return UnitImpact(gamma, s.tau, s.tau1, s.x_max, s.cor, s.F_max)


#: The polish accepts gamma when |gamma - 3 tg T_tau(gamma)/pi| <=
#: ROOT_TOL_PER_RTOL * RTOL * gamma, RTOL the integration's (``_normal.RTOL``,
#: read at call time): the residual carries integration noise up to ~0.3 RTOL
#: (measured: 3e-12 at RTOL = 1e-11), so a tighter test would chase noise, and
#: the root is then as well defined as the bracketed one (brentq to 4 machine
#: epsilons on the same noisy function), i.e. to ~RTOL relative.
ROOT_TOL_PER_RTOL = 1.0
#: Polish steps before falling back to the bracketed root: the spline seed is
#: within 1e-6 relative (measured <= 6e-8, often already within tolerance) and
#: one Newton step with the tabulated slope (also ~1e-6) leaves ~1e-13, so six
#: steps mean the seed is not in the root's basin.
MAX_POLISH_STEPS = 6
#: Relative step of the central difference dT_tau/dgamma at the table nodes:
#: truncation ~1e-10, integration noise ~3e-12/1e-5 = 3e-7 relative; the slope
#: only sets the Newton step, whose error is (slope error) x (seed error).
DGAMMA_REL = 1e-5


@lru_cache(maxsize=4096)
def self_consistent(tan_delta: float, eps: float, separation: str) -> UnitImpact:
    """The unit impact whose gamma satisfies gamma = 3 tg T_tau(gamma)/pi.

    For 0 < eps <= EPS_NODES[-1] the root is seeded from the cubic spline of
    :func:`eps_table` and polished by Newton/secant steps on the integrated
    T_tau until the residual is within ROOT_TOL_PER_RTOL * RTOL (one or two
    integrations); the first call for a (tg, separation) builds that table
    (15 bracketed roots and their slopes, ~0.5 s on one core). Elsewhere, and
    if the polish does not converge, the bracketed root
    :func:`self_consistent_bracketed`.
    """
    if tan_delta == 0.0:
        return unit_impact(0.0, eps, separation)
    if 0.0 < eps <= EPS_NODES[-1]:
        r = _polish(tan_delta, eps, separation, eps_table(tan_delta, separation))
        if r is not None:
            return r
    return self_consistent_bracketed(tan_delta, eps, separation)


def _polish(tan_delta: float, eps: float, separation: str, table: "EpsTable") -> UnitImpact | None:
    """Newton from the spline's gamma with its slope, then secant steps; the
    unit impact at the first gamma whose residual is within tolerance, or None."""
    c = 3.0 * tan_delta / math.pi
    tol = ROOT_TOL_PER_RTOL * _normal.RTOL
    seed = table(eps)
    gamma = float(seed["gamma"])
    slope = 1.0 - c * float(seed["dtau_dgamma"])  # g'(gamma) of g = gamma - c T_tau(gamma)
    prev = None
    for _ in range(MAX_POLISH_STEPS):
        if not gamma > 0.0:
            return None
        r = unit_impact(gamma, eps, separation)
        g = gamma - c * r.tau
        if abs(g) <= tol * gamma:
            return r
        if prev is not None and g != prev[1]:
            slope = (g - prev[1]) / (gamma - prev[0])
        prev = (gamma, g)
        gamma = gamma - g / slope
    return None


@lru_cache(maxsize=4096)
def self_consistent_bracketed(tan_delta: float, eps: float, separation: str) -> UnitImpact:
    """As :func:`self_consistent`, by brentq on a bracket found by doubling
    (~10 integrations): the general path, and the one the table is built with."""
    if tan_delta == 0.0:
        return unit_impact(0.0, eps, separation)

    def g(gamma):
        return gamma - 3.0 * tan_delta * unit_impact(gamma, eps, separation).tau / math.pi

    lo, hi = 0.0, 3.0 * tan_delta * unit_impact(0.0, eps, separation).tau / math.pi
    k = 0
    while g(hi) < 0.0:
        lo, hi = hi, 2.0 * hi
        k += 1
        if k > 60:
            raise RuntimeError(f"no self-consistent omega_x for tan_delta = {tan_delta!r}")
    gamma = brentq(g, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    return unit_impact(gamma, eps, separation)


#: Nodes in eps = x_0/(2R) of the onset table used by engines in ``msf``
#: k_p mode; x/R of real impacts stays below ~0.1. Between nodes a cubic
#: spline is accurate to ~1e-6 relative for eps <= 0.2 (tests/test_laws.py).
EPS_NODES = (0.0, 2.5e-4, 1e-3, 3e-3, 1e-2, 2e-2, 4e-2, 7e-2, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4)


class EpsTable:
    """gamma, tau, x_max, cor of the self-consistent impact against eps for one
    (tg(beta), separation), interpolated (cubic spline) between EPS_NODES, and
    dtau_dgamma, the slope dT_tau/dgamma there (the Newton step of the polish).
    Built from bracketed roots (:func:`self_consistent_bracketed`)."""

    def __init__(self, tan_delta: float, separation: str):
        self.nodes = np.array(EPS_NODES)
        rows = [self_consistent_bracketed(tan_delta, float(e), separation) for e in self.nodes]
        self._names = ("gamma", "tau", "tau1", "x_max", "cor", "F_max", "dtau_dgamma")
        cols = [[getattr(r, name) for r in rows] for name in self._names[:-1]]
        cols.append([_dtau_dgamma(r.gamma, float(e), separation) for r, e in zip(rows, self.nodes)])
        # one spline of the 7 columns (each column its own not-a-knot spline, as 7 splines would
        # be): one evaluation per call instead of seven
        self._f = CubicSpline(self.nodes, np.array(cols).T, axis=0)
        #: the spline's knots (N,) and coefficients (4, N - 1, 7), contiguous: what the compiled
        #: onset (msf_contact._onset_kernel) evaluates, as scipy's PPoly does
        self.knots = np.ascontiguousarray(self._f.x, dtype=float)
        self.coefficients = np.ascontiguousarray(self._f.c, dtype=float)

    def __call__(self, eps) -> dict[str, np.ndarray]:
        eps = np.asarray(eps, dtype=float)
        if np.any(eps > self.nodes[-1]):
            raise ValueError(
                f"eps = x_0/(2R) = {float(np.max(eps)):.4g} exceeds the onset table's range "
                f"{self.nodes[-1]}: the impact is too deep for the msf geometry"
            )
        val = self._f(eps)
        return {k: val[..., j] for j, k in enumerate(self._names)}


def _dtau_dgamma(gamma: float, eps: float, separation: str) -> float:
    """dT_tau/dgamma at gamma by a central difference (DGAMMA_REL); 0 at gamma = 0."""
    if gamma == 0.0:
        return 0.0
    h = DGAMMA_REL * gamma
    return (_unit_tau(gamma + h, eps, separation) - _unit_tau(gamma - h, eps, separation)) / (2.0 * h)


def _unit_tau(gamma: float, eps: float, separation: str) -> float:
    return unit_impact(gamma, eps, separation).tau


@lru_cache(maxsize=256)
def eps_table(tan_delta: float, separation: str) -> EpsTable:
    return EpsTable(tan_delta, separation)
