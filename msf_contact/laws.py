"""Contact force laws behind one interface, vectorised over n contacts.

(Over 600 lines because the five laws and their registry are read side by
side: each law is a short class under the one contract below.)

The contract (:class:`ForceLaw`), what an implementer must do:

1. Take the pair (:class:`~msf_contact.materials.ContactPair`), the surface
   curvature (:class:`~msf_contact.geometry.Curvature`) and its own options
   in ``__init__``; validate them there with ``ValueError``.
2. ``onset(v_n0, mass)``: per-contact constants fixed when a contact begins
   (n,) arrays in a dict, e.g. the MSF collision frequency omega_x.
3. ``normal_force(x, xdot, onset)``: signed normal force [N] (n,),
   repulsive positive; the separation rule (clamping) is applied by
   :meth:`ForceLaw.contact_normal_force`, shared by every caller.
4. ``separation_indicator(x, xdot, onset)``: B with F_n = S(x) B, S >= 0;
   the force-zero rule ends a contact where B < 0 in restitution.
5. ``tangential_force(x, s, sdot, onset, F_n)``: force on body 1 along the
   two contact axes (a, b) [N] (n, 2), opposing the tangential
   displacement s [m] (n, 2) of body 1 relative to body 2, capped at
   mu F_n if ``mu`` is set.
6. ``parameters()``: everything needed to reproduce the law (for records).

Forces never contain NaN for x >= 0: k_p is clamped in ``msf`` mode at
x/R -> 2 and ``outside(x)`` flags such contacts for the caller to report.
"""

from __future__ import annotations

import abc
import copy
import functools
import math
from typing import ClassVar

import numpy as np
from scipy.optimize import brentq

from . import _onset_kernel, _scaling
from . import closed_forms as cf
from ._normal import SEPARATIONS, integrate_normal
from ._validate import check_choice, check_finite, check_positive, check_range, check_tan_delta
from .geometry import KP_MODES, ContactGeometry, Curvature, kp_clamped, shear_lengths, width
from .materials import ContactPair

OMEGA_MODES = ("self-consistent", "paper")


def _arr(v, n=None):
    a = np.atleast_1d(np.asarray(v, dtype=float))
    if n is not None and a.shape[0] != n:
        a = np.broadcast_to(a, (n,)).copy()
    return a


class ForceLaw(abc.ABC):
    """Base of all laws. See the module docstring for the contract."""

    name: ClassVar[str] = ""
    #: True if the law has the correlation coefficient k_p setting.
    has_kp: ClassVar[bool] = False

    def __init__(
        self,
        pair: ContactPair,
        curvature: Curvature,
        *,
        separation: str = "force-zero",
        mu: float | None = None,
        kp_mode: str = "hertz",
    ):
        self.pair = pair
        self.curvature = curvature
        self.separation = check_choice("separation", separation, SEPARATIONS)
        if mu is not None:
            check_positive("mu", mu)
        self.mu = mu
        self.kp_mode = check_choice("kp_mode", kp_mode, KP_MODES)
        self.geom = ContactGeometry.of(pair, curvature)
        self.moduli = pair.moduli()
        if self.geom.footprint is not None and (self.kp_mode != "msf" or self.name != "msf"):
            raise ValueError(
                f"a line contact (footprint {self.geom.footprint}) has only the msf law with kp_mode 'msf' "
                f"(docs/theory.md section 2a); got law {self.name!r}, kp_mode {self.kp_mode!r}")

    # -- contract ---------------------------------------------------------
    @abc.abstractmethod
    def onset(self, v_n0, mass) -> dict[str, np.ndarray]:
        """Per-contact constants at onset. v_n0: approach speed [m/s] (n,), mass [kg] (n,)."""

    def onset_reference(self, v_n0, mass) -> dict[str, np.ndarray]:
        """As onset(), solved to the reference solver's accuracy (laws with a
        fast approximate onset override it)."""
        return self.onset(v_n0, mass)

    @abc.abstractmethod
    def normal_force(self, x, xdot, onset) -> np.ndarray:
        """Signed normal force [N] (n,)."""

    @abc.abstractmethod
    def separation_indicator(self, x, xdot, onset) -> np.ndarray:
        """Bracket B of F_n = S(x) B (n,)."""

    @abc.abstractmethod
    def tangential_stiffness(self, x, onset) -> tuple[np.ndarray, np.ndarray]:
        """Tangential (stiffness [N/m], damping [N s/m]) along axes a and b, each (n, 2)."""

    def with_curvature(self, curvature: Curvature) -> "ForceLaw":
        """The same law (materials, options) for another contact curvature:
        an engine's contact point whose principal radii differ from this
        law's (a tumbling ellipsoid or mesh, a cylinder's rim at another
        tilt). The options are kept as they are; what depends on the
        curvature (``geom``) is rebuilt and checked as in the constructor."""
        new = copy.copy(self)
        ForceLaw.__init__(new, self.pair, curvature, separation=self.separation, mu=self.mu, kp_mode=self.kp_mode)
        new._check_curvature()
        return new

    def _check_curvature(self) -> None:
        """Checks of a subclass on the curvature (the constructor's), run by :meth:`with_curvature`."""

    def parameters(self) -> dict:
        m = self.moduli
        return {
            "law": self.name, "separation": self.separation, "mu": self.mu,
            "kp_mode": self.kp_mode, "modulus_convention": self.pair.convention,
            "E_eff": m.E, "E_loss_eff": m.E_loss, "G_eff": m.G, "G_loss_eff": m.G_loss,
            "tan_delta_eff": m.tan_delta, "D1": m.D1, "D2": m.D2,
            "R_a": self.geom.R_a, "R_b": self.geom.R_b, "k_ha": self.geom.k_ha, "k_hb": self.geom.k_hb,
            "body1": self.pair.body1.name, "body2": self.pair.body2.name,
        }

    # -- shared mechanics -------------------------------------------------
    def contact_normal_force(self, x, xdot, onset) -> np.ndarray:
        """Normal force after the separation rule: force-zero clamps at 0
        (no adhesion); overlap-zero lets it be tensile. (n,) [N]."""
        F = self.normal_force(x, xdot, onset)
        return np.maximum(F, 0.0) if self.separation == "force-zero" else F

    def tangential_force(self, x, s, sdot, onset, F_n=None):
        """Force on body 1 along the contact axes (n, 2) [N]:
        F = -(b s' + k s), capped at mu F_n when mu is set.

        Returns (F_t (n, 2), sliding (n,) bool)."""
        k, b = self.tangential_stiffness(x, onset)
        s = np.asarray(s, dtype=float).reshape(-1, 2)
        sdot = np.asarray(sdot, dtype=float).reshape(-1, 2)
        F = -(b * sdot + k * s)
        sliding = np.zeros(F.shape[0], bool)
        if self.mu is not None and F_n is not None:
            cap = self.mu * np.maximum(np.asarray(F_n, dtype=float), 0.0)
            mag = np.hypot(F[:, 0], F[:, 1])
            sliding = mag > cap
            scale = np.where(sliding, cap / np.where(mag > 0, mag, 1.0), 1.0)
            F = F * scale[:, None]
        return F, sliding

    def kp(self, x, R):
        """k_p (n,) in this law's mode, clamped below x/R = 2 (see outside())."""
        return kp_clamped(x, R, self.kp_mode)[0]

    def outside(self, x) -> np.ndarray:
        """(n,) True where the contact is outside the model's geometry (x >= 2R in msf mode)."""
        x = np.asarray(x, dtype=float)
        if self.kp_mode != "msf":
            return np.zeros(x.shape, bool)
        return (x / min(self.geom.R_a, self.geom.R_b)) >= 2.0

    def psi(self, x):
        """(29): psi = k_pa sqrt(R_a) + k_pb sqrt(R_b) [m^1/2] (n,)."""
        g = self.geom
        return self.kp(x, g.R_a) * math.sqrt(g.R_a) + self.kp(x, g.R_b) * math.sqrt(g.R_b)

    def width(self, x):
        """W = psi sqrt(x) = (a + b)/2 [m] (n,), (29) with (26); a line contact's
        from its footprint (``geometry.width``)."""
        if self.geom.footprint is None:
            return self.psi(x) * np.sqrt(x)
        return width(x, self.geom, self.kp_mode)

    def hertz_scale(self, v_n0, mass) -> np.ndarray:
        """Elastic Hertz x_max [m] for these speeds and masses (a length scale);
        a line contact's: the elastic x_max of its own (37), 1/2 m v^2 = int 2/3 E' W x dx."""
        if self.geom.footprint is None:
            return cf.hertz_x_max(mass, v_n0, self.moduli.E, self.geom.R)
        return np.vectorize(self._elastic_x_max)(v_n0, mass)

    def _elastic_x_max(self, v, m):
        from scipy.integrate import quad

        E = self.moduli.E

        def excess(x):
            work = quad(lambda s: (2.0 / 3.0) * E * s * float(self.width(np.array([s]))[0]), 0.0, x)[0]
            return work - 0.5 * m * v * v

        hi = min(float(cf.hertz_x_max(m, v, E, self.geom.R_a)), 0.999 * self.x_limit)  # the side's sphere
        while excess(hi) < 0.0 and hi < 0.999 * self.x_limit:  # a softer contact (a rim alone) reaches deeper
            hi = min(2.0 * hi, 0.999 * self.x_limit)
        return brentq(excess, 0.0, hi, xtol=1e-15, rtol=1e-12)

    def solve_normal(self, v0: float, mass: float, onset: dict, n_samples: int = 0):
        """The isolated normal impact of one contact under this law (reference)."""
        o = {k: np.atleast_1d(v)[:1] for k, v in onset.items()}

        def force(x, v):
            return float(self.normal_force(np.array([x]), np.array([v]), o)[0])

        def ind(x, v):
            return float(self.separation_indicator(np.array([x]), np.array([v]), o)[0])

        xs = float(self.hertz_scale(v0, mass))
        return integrate_normal(force, ind, mass, v0, xs, self.separation, n_samples, x_limit=self.x_limit)

    @property
    def x_limit(self) -> float | None:
        """Largest approach the law is defined for [m]: 2 min(R_a, R_b) with the
        msf k_p of (15), else None."""
        return 2.0 * min(self.geom.R_a, self.geom.R_b) if self.kp_mode == "msf" else None

    def _mindlin(self, x, n):
        """Hertz-Mindlin no-slip tangential stiffness 8 G a, a = sqrt(R x) [N/m] (n, 2)."""
        a = np.sqrt(self.geom.R * np.maximum(x, 0.0))
        k = 8.0 * self.moduli.G * a
        return np.repeat(k[:, None], 2, axis=1), np.zeros((n, 2))


def self_consistent_omega(omega_h: float, tau_of, v: float, m: float) -> float:
    """The root omega_x [rad/s] of omega_x tau(omega_x) = pi, (46) with (87):
    brentq on log omega_x (to 1e-13) in a bracket omega_h e^(+-k), k = 1, 2,
    ... 21, around omega_h = pi / (a contact duration without damping).
    tau_of(omega) -> the contact duration [s] of the collision (v [m/s],
    m [kg]) solved with eta'_E = E''/omega (MSFLaw.self_consistent's
    integration, or engines._narrow.SideEndLaw's compiled one)."""

    def g(log_w):
        return math.log(math.exp(log_w) * tau_of(math.exp(log_w)) / math.pi)

    lo, hi = math.log(omega_h) - 1.0, math.log(omega_h) + 1.0
    glo, ghi = g(lo), g(hi)
    k = 0
    while glo * ghi > 0 and k < 20:
        lo, hi = lo - 1.0, hi + 1.0
        glo, ghi = g(lo), g(hi)
        k += 1
    if glo * ghi > 0:
        raise RuntimeError(f"no self-consistent omega_x found for v = {v!r} m/s, m = {m!r} kg")
    return math.exp(brentq(g, lo, hi, xtol=1e-13, rtol=1e-13))


# ---------------------------------------------------------------- MSF -------
class MSFLaw(ForceLaw):
    """Method of the Specific Forces, (37)/(43)/(47).

    F_n = psi (2 eta'_E x' sqrt(x) + 2/3 E' x^(3/2)), eta'_E = E''/omega_x (46);
    F_ty = -(eta'_G P_bx y' + G' P_bx y), F_tz likewise with P_ax (36), (37).

    omega: ``"self-consistent"`` (default, omega_x = pi/tau of the collision
    solved with this law), ``"paper"`` (tau from (95) with k_x of (89)), or a
    number [rad/s] (fixed, e.g. a DMA frequency). omega_y, omega_z from the
    equivalent tangential oscillator (84)/(86) at the predicted x_max.
    """

    name = "msf"
    has_kp = True
    #: onset() of the table's rows in one compiled pass (msf_contact._onset_kernel, bit for bit
    #: the numpy form); False on a law (or the class): the numpy form, which it is tested against
    compiled_onset: ClassVar[bool] = True

    def __init__(self, pair, curvature, *, omega="self-consistent", kp_mode="msf",
                 separation="force-zero", mu=None, temperature=None, strict=False):
        super().__init__(pair, curvature, separation=separation, mu=mu, kp_mode=kp_mode)
        if isinstance(omega, str):
            check_choice("omega", omega, OMEGA_MODES)
        else:
            check_positive("omega", omega, unit="rad/s")
            omega = float(omega)
        self.omega = omega
        self._check_curvature()
        self.temperature = temperature
        self.strict = strict
        if not pair.frequency_dependent:
            check_tan_delta("tan_delta (effective, (91))", self.moduli.tan_delta, strict=strict)

    def _check_curvature(self) -> None:
        if self.omega == "paper" and self.geom.footprint is not None:
            raise ValueError("omega = 'paper' takes tau from the sphere's closed form (95); a line contact "
                             "(footprint) needs omega = 'self-consistent' or a fixed number")

    def parameters(self):
        p = super().parameters()
        p.update(omega_mode=self.omega if isinstance(self.omega, str) else "fixed",
                 omega_fixed=None if isinstance(self.omega, str) else self.omega,
                 temperature=self.temperature)
        return p

    # -- per-contact moduli (frequency-dependent materials) -----------------
    def _moduli_at(self, omega):
        if not self.pair.frequency_dependent:
            return self.moduli
        return self.pair.at(omega, self.temperature).moduli()

    def _onset_dict(self, omega_x, mod, v, m, x_m):
        """Onset constants from omega_x [rad/s], moduli, speeds [m/s], masses [kg]
        and the predicted x_max [m]; all (n,) arrays (or scalars)."""
        omega_x, v, m, x_m = (np.atleast_1d(np.asarray(a, dtype=float)) for a in (omega_x, v, m, x_m))
        P_bx, P_ax = self.shear_lengths(x_m)
        tg_G = mod.G_loss / mod.G if mod.G > 0 else 0.0
        w_y = cf.omega_y_equivalent(m, P_bx, mod.G, tg_G)  # (84)/(86)
        w_z = cf.omega_y_equivalent(m, P_ax, mod.G, tg_G)
        n = v.shape[0]

        def full(a):
            """a broadcast to a new (n,) float array (by assignment: the cheapest broadcast)."""
            out = np.empty(n)
            out[...] = a
            return out

        return dict(omega_x=full(omega_x), omega_y=full(w_y), omega_z=full(w_z), E=full(mod.E),
                    eta_E=full(mod.E_loss / omega_x), G=full(mod.G), eta_Gy=full(mod.G_loss / w_y),
                    eta_Gz=full(mod.G_loss / w_z), x_max_pred=full(x_m), v_n0=full(v), mass=full(m))

    def _solve_with_omega(self, omega, v, m):
        mod = self._moduli_at(omega)
        o = {"E": np.array([mod.E]), "eta_E": np.array([mod.E_loss / omega])}
        return self.solve_normal(v, m, o), mod

    # -- dimensionless fast path (msf_contact._scaling) ----------------------
    @property
    def scalable(self) -> bool:
        """True when the normal impact is one dimensionless family: moduli
        independent of frequency and k_p constant, or the msf k_p on a sphere."""
        return (not self.pair.frequency_dependent and self.geom.footprint is None
                and (self.kp_mode != "msf" or self.geom.sphere))

    def _scale_K(self) -> float:
        """K = 2/3 E' psi_0 [N/m^1.5] of the dimensionless impact (see _scaling)."""
        kp0 = 1.0 if self.kp_mode == "hertz" else math.sqrt(2.0)
        return 2.0 / 3.0 * self.moduli.E * kp0 * (math.sqrt(self.geom.R_a) + math.sqrt(self.geom.R_b))

    def _scales(self, v, m):
        """x_0 [m], t_0 [s], eps [-] of the dimensionless impact (see _scaling)."""
        x0 = (m * v**2 / self._scale_K()) ** 0.4
        eps = x0 / (2.0 * self.geom.R) if self.kp_mode == "msf" else np.zeros_like(x0)
        return x0, x0 / v, eps

    def _onset_scaled(self, v, m, exact: bool):
        tg = self.moduli.tan_delta
        x0, t0, eps = self._scales(v, m)
        if isinstance(self.omega, float):
            gam = 3.0 * tg / (self.omega * t0)
            xm = np.array([_scaling.unit_impact(float(g), float(e), self.separation).x_max
                           for g, e in zip(gam, eps)])
            return np.full(v.shape, self.omega), x0 * xm
        if self.kp_mode == "msf" and not exact and bool(np.all(eps <= _scaling.EPS_NODES[-1])):
            # every row in the table (the engines' usual case): the same values without the row selection
            tab = _scaling.eps_table(tg, self.separation)(eps)
            gam, tau, xm = tab["gamma"], tab["tau"], tab["x_max"]
            omega = np.where(gam > 0, 3.0 * tg / np.where(gam > 0, gam, 1.0) / t0, math.pi / (tau * t0))
            return omega, x0 * xm
        gam, tau, xm = (np.empty_like(eps) for _ in range(3))
        in_table = np.zeros(eps.shape, bool)
        if self.kp_mode == "msf" and not exact:
            in_table = eps <= _scaling.EPS_NODES[-1]
            if np.any(in_table):
                tab = _scaling.eps_table(tg, self.separation)(eps[in_table])
                gam[in_table], tau[in_table], xm[in_table] = tab["gamma"], tab["tau"], tab["x_max"]
        for i in np.flatnonzero(~in_table):
            try:
                r = _scaling.self_consistent(tg, float(eps[i]), self.separation)
            except ValueError:
                raise ValueError(
                    f"at v_n0 = {v[i]:.6g} m/s the approach reaches 2R = {2 * self.geom.R:.6g} m before maximum "
                    "compression: k_p = sqrt(2 - x/R) of (15) has no real value beyond; outside the msf geometry"
                ) from None
            gam[i], tau[i], xm[i] = r.gamma, r.tau, r.x_max
        omega = np.where(gam > 0, 3.0 * tg / np.where(gam > 0, gam, 1.0) / t0, math.pi / (tau * t0))
        return omega, x0 * xm

    def _onset_compiled(self, v, m) -> dict | None:
        """_onset_scaled and _onset_dict for the table's rows in one compiled pass
        (msf_contact._onset_kernel, bit for bit the numpy form); None when a row is
        outside the table or G's loss factor exceeds 1 (the numpy path then
        handles or refuses it)."""
        x0 = (m * v**2 / self._scale_K()) ** 0.4  # numpy's power, as _scales
        table = _scaling.eps_table(self.moduli.tan_delta, self.separation)
        mod, g = self.moduli, self.geom
        tg_G = mod.G_loss / mod.G if mod.G > 0 else 0.0
        out = np.empty((_onset_kernel.NKEYS, v.shape[0]))
        if _onset_kernel.onset_rows(v, m, x0, 2.0 * g.R, mod.tan_delta, table.knots, table.coefficients, mod.E,
                                    mod.E_loss, mod.G, mod.G_loss, tg_G, g.k_ha, g.k_hb, g.R_a, g.R_b, out):
            return None
        return dict(zip(_onset_kernel.KEYS, out))

    def onset_one(self, v: float, m: float) -> dict:
        """Onset constants for one contact by direct integration of the
        dimensional equation (no scaling): the slow, general path."""
        if self.omega == "paper":
            omega, mod = self._omega_paper(v, m)
            kp = cf.kp_for_mode(self.kp_mode, m, v, mod.E, mod.tan_delta, self.geom.R)
            x_m = float(cf.x_max_90(m, v, mod.E, mod.tan_delta, self.geom.R, kp))
            return self._onset_dict(omega, mod, v, m, x_m)
        if isinstance(self.omega, float):
            sol, mod = self._solve_with_omega(self.omega, v, m)
            return self._onset_dict(self.omega, mod, v, m, sol.x_max)
        omega, sol, mod = self.self_consistent(v, m)
        return self._onset_dict(omega, mod, v, m, sol.x_max)

    def _onset(self, v_n0, mass, exact: bool):
        v = _arr(v_n0)
        m = _arr(mass, v.shape[0])
        check_positive("onset normal speed v_n0", v, unit="m/s")
        check_positive("mass", m, unit="kg")
        if self.scalable and self.omega != "paper":
            if self.compiled_onset and not exact and self.kp_mode == "msf" and isinstance(self.omega, str):
                out = self._onset_compiled(v, m)
                if out is not None:
                    return out
            omega, x_m = self._onset_scaled(v, m, exact)
            return self._onset_dict(omega, self.moduli, v, m, x_m)
        one = self.onset_one if exact else self._onset_one_engine
        rows = [one(float(a), float(b)) for a, b in zip(v, m)]
        return {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}

    def _onset_one_engine(self, v: float, m: float) -> dict:
        """:meth:`onset_one` on the engines' path (:meth:`onset`): the same
        here; a subclass with a faster solve of the same equations overrides
        it (engines._narrow.SideEndLaw: compiled), :meth:`onset_reference`
        keeps :meth:`onset_one`."""
        return self.onset_one(v, m)

    def onset(self, v_n0, mass):
        """Onset constants (n,) arrays: omega_x, omega_y, omega_z [rad/s], E, G [Pa],
        eta_E, eta_Gy, eta_Gz [Pa s], x_max_pred [m], v_n0 [m/s], mass [kg].

        Engines' path: in ``msf`` k_p mode the self-consistent omega_x is
        interpolated in eps = x_0/2R (``_scaling.EpsTable``, ~1e-6 relative)."""
        return self._onset(v_n0, mass, exact=False)

    def onset_reference(self, v_n0, mass):
        """As :meth:`onset`, with every self-consistent root solved exactly."""
        return self._onset(v_n0, mass, exact=True)

    def _omega_paper(self, v, m):
        """tau from (95) as printed, with k_x from (89); iterated for
        frequency-dependent materials."""
        omega = math.pi / float(cf.hertz_tau(m, v, self.moduli.E, self.geom.R))
        for _ in range(50):
            mod = self._moduli_at(omega)
            kp = cf.kp_for_mode(self.kp_mode, m, v, mod.E, mod.tan_delta, self.geom.R)
            tau = float(cf.tau_95_as_printed(m, v, mod.E, self.geom.R, kp, cf.cor_89(mod.tan_delta)))
            new = math.pi / tau
            if abs(new - omega) <= 1e-12 * omega:
                return new, mod
            omega = new
        return omega, mod

    def self_consistent(self, v: float, m: float):
        """omega_x with omega_x * tau(omega_x) = pi, tau the contact duration of
        this collision solved with this law (46), (87). Returns (omega, NormalSolution, moduli)."""
        if self.geom.footprint is None:
            omega_h = math.pi / float(cf.hertz_tau(m, v, self.moduli.E, self.geom.R))
        else:  # a line contact: the elastic contact's own duration brackets the root
            omega_h = math.pi / self.solve_normal(v, m, {"E": np.array([self.moduli.E]),
                                                         "eta_E": np.zeros(1)}).tau

        omega = self_consistent_omega(omega_h, lambda w: self._solve_with_omega(w, v, m)[0].tau, v, m)
        sol, mod = self._solve_with_omega(omega, v, m)
        return omega, sol, mod

    # -- forces -------------------------------------------------------------
    def normal_force(self, x, xdot, onset):
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        xdot = np.asarray(xdot, dtype=float)
        if self.geom.footprint is not None:  # (37) as W (2 eta x' + 2/3 E' x), W = (a + b)/2
            return self.width(x) * (2.0 * onset["eta_E"] * xdot + (2.0 / 3.0) * onset["E"] * x)
        sx = np.sqrt(x)
        # (37): F_n = 2 eta psi x' sqrt(x) + 2/3 E' psi x^(3/2)
        return self.psi(x) * sx * (2.0 * onset["eta_E"] * xdot + (2.0 / 3.0) * onset["E"] * x)

    def separation_indicator(self, x, xdot, onset):
        return 2.0 * onset["eta_E"] * np.asarray(xdot) + (2.0 / 3.0) * onset["E"] * np.asarray(x)

    def shear_lengths(self, x):
        """(36): (P_bx, P_ax) [m], each (n,)."""
        g = self.geom
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        if g.footprint is not None:
            return shear_lengths(x, g, self.kp_mode)
        P_bx = g.k_ha * x + 2.0 * self.kp(x, g.R_b) * np.sqrt(g.R_b * x)
        P_ax = g.k_hb * x + 2.0 * self.kp(x, g.R_a) * np.sqrt(g.R_a * x)
        return P_bx, P_ax

    def tangential_stiffness(self, x, onset):
        if self.compiled_onset and self.kp_mode == "msf" and self.geom.footprint is None:
            # rows of one length: compiled (msf_contact._onset_kernel.stiffness_rows, bit for bit)
            cols = (x, onset["G"], onset["eta_Gy"], onset["eta_Gz"])
            if all(type(c) is np.ndarray and c.dtype == np.float64 and c.ndim == 1 for c in cols) and \
                    x.shape[0] == cols[1].shape[0] == cols[2].shape[0] == cols[3].shape[0]:
                g = self.geom
                k, b = np.empty((x.shape[0], 2)), np.empty((x.shape[0], 2))
                _onset_kernel.stiffness_rows(*cols, g.R_a, g.R_b, g.k_ha, g.k_hb, k, b)
                return k, b
        P_bx, P_ax = self.shear_lengths(x)
        G = np.asarray(onset["G"], dtype=float)
        # the two columns assigned into (n, 2) arrays: np.stack's values, at a third of its cost for a few rows
        kx, ky = G * P_bx, G * P_ax
        bx, by = onset["eta_Gy"] * P_bx, onset["eta_Gz"] * P_ax
        n = np.broadcast_shapes(np.shape(kx), np.shape(ky), np.shape(bx), np.shape(by))
        k, b = np.empty(n + (2,)), np.empty(n + (2,))
        k[..., 0], k[..., 1], b[..., 0], b[..., 1] = kx, ky, bx, by
        return k.reshape(-1, 2), b.reshape(-1, 2)


# ------------------------------------------------------- comparison laws -----
class _HertzFamily(ForceLaw):
    """Comparison laws use k_p = 1 and the pair's effective modulus: the
    elastic part is (29) with k_p = 1, i.e. Hertz (30) for a sphere."""

    def __init__(self, pair, curvature, *, separation="force-zero", mu=None):
        super().__init__(pair, curvature, separation=separation, mu=mu, kp_mode="hertz")
        self.K = 2.0 / 3.0 * self.moduli.E * (math.sqrt(self.geom.R_a) + math.sqrt(self.geom.R_b))

    def tangential_stiffness(self, x, onset):
        x = np.atleast_1d(np.asarray(x, dtype=float))
        return self._mindlin(x, x.shape[0])


class HertzLaw(_HertzFamily):
    """Elastic Hertz (30): F_n = 2/3 E (sqrt(R_a) + sqrt(R_b)) x^(3/2) (= 4/3 E sqrt(R) x^(3/2)
    for a sphere); tangential Hertz-Mindlin 8 G sqrt(R x) with the optional Coulomb cap."""

    name = "hertz"

    def onset(self, v_n0, mass):
        v = _arr(v_n0)
        return {"v_n0": v, "mass": _arr(mass, v.shape[0])}

    def normal_force(self, x, xdot, onset):
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        return self.K * x**1.5

    def separation_indicator(self, x, xdot, onset):
        return np.asarray(x, dtype=float)


class KuwabaraKonoLaw(_HertzFamily):
    """Kuwabara-Kono / Brilliantov et al. 1996: F_n = K (x^(3/2) + 3/2 A x' x^(1/2)),
    K = 2/3 E psi (= rho = 4/3 E sqrt(R) for a sphere); A [s] the dissipative constant."""

    name = "kuwabara-kono"

    def __init__(self, pair, curvature, *, A, separation="force-zero", mu=None):
        super().__init__(pair, curvature, separation=separation, mu=mu)
        check_finite("A", A)
        if A < 0:
            raise ValueError(f"A = {A!r} s must be >= 0")
        self.A = float(A)

    def parameters(self):
        p = super().parameters()
        p["A"] = self.A
        return p

    def onset(self, v_n0, mass):
        v = _arr(v_n0)
        return {"v_n0": v, "mass": _arr(mass, v.shape[0])}

    def normal_force(self, x, xdot, onset):
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        return self.K * np.sqrt(x) * (x + 1.5 * self.A * np.asarray(xdot))

    def separation_indicator(self, x, xdot, onset):
        return np.asarray(x) + 1.5 * self.A * np.asarray(xdot)


#: Hunt-Crossley damping recipes: ``flores`` chi = 8 (1 - e)/(5 e v0)
#: (Flores et al. 2011), a closed-form approximation whose impact rebounds
#: below e (0.8 gives 0.7885 with force-zero separation); ``exact`` the chi
#: whose impact rebounds with e itself (:func:`hunt_crossley_alpha`).
HC_DAMPINGS = ("flores", "exact")
#: Smallest target restitution of the Hunt-Crossley law: alpha ~ 1/e, so the
#: damping force at onset is ~1/e times the elastic one; below 1e-3 the
#: impact is a plastic capture the law is not meant for, and the numbers
#: (alpha up to 1e300 for e = 1e-300) overflow.
HC_COR_MIN = 1e-3
#: brentq tolerance on alpha = chi v0 of the exact recipe (relative).
HC_ALPHA_RTOL = 1e-14


@functools.lru_cache(maxsize=256)
def hunt_crossley_alpha(cor: float) -> float:
    """alpha = chi v0 [-] for which the Hunt-Crossley impact rebounds with
    restitution ``cor`` = e exactly. m x'' = -K x^(3/2) (1 + chi x') gives
    v dv/(1 + chi v) = -(K/m) x^(3/2) dx, and x returns to 0, so the
    integral of v/(1 + chi v) from -e v0 to v0 vanishes:

        alpha (1 + e) = ln((1 + alpha)/(1 - alpha e))

    (the exact relation behind the approximations of Hunt-Crossley, Lankarani-
    Nikravesh and Flores, whose first order is alpha = 8 (1 - e)/(5 e)).
    Its root has alpha e < 1, so the force 1 + chi x' stays positive and
    both separation rules end at x = 0 together. Solved by brentq on
    (0, 1/e); the reference solver returns e to ~1e-11 (tests)."""
    check_range("cor (Hunt-Crossley target restitution)", cor, 0.0, 1.0, lo_open=True)
    if cor == 1.0:
        return 0.0
    e = float(cor)
    if e >= 0.5:  # alpha <= 1.43: the log form, free of cancellation for small alpha

        def miss(a):
            return math.log1p(a) - math.log1p(-a * e) - a * (1.0 + e)
    else:  # alpha e -> 1 as e -> 0: the exponentiated form, 1 - alpha e = (1 + alpha) exp(-alpha (1 + e))

        def miss(a):
            return a * e - 1.0 + (1.0 + a) * math.exp(-a * (1.0 + e))

    # both forms are alpha^2 (e^2 - 1)/2 + O(alpha^3) < 0 below the root and > 0 at alpha = 1/e
    hi = (1.0 - 1e-15) / e if e >= 0.5 else 1.0 / e
    if miss(hi) <= 0:  # e so small that alpha = 1/e to double precision (the exp term underflows)
        return hi
    lo = min(1.5 * (1.0 - e * e) / (1.0 + e**3), 0.5 * hi)  # near the root of the cubic truncation
    for _ in range(200):
        if miss(lo) < 0:
            break
        lo *= 0.5
    else:
        raise ValueError(f"cor = {cor!r}: no Hunt-Crossley damping found for this restitution")
    return brentq(miss, lo, hi, xtol=1e-300, rtol=HC_ALPHA_RTOL)


class HuntCrossleyLaw(_HertzFamily):
    """Hunt & Crossley (1975): F_n = K x^(3/2) (1 + chi x'), chi = alpha/v0
    with v0 the onset speed and alpha from the target restitution e
    (0 < e <= 1) by the ``damping`` recipe (:data:`HC_DAMPINGS`): ``flores``
    (default, Flores et al. 2011) alpha = 8 (1 - e)/(5 e), which rebounds
    below e (0.8 gives 0.7885); ``exact`` the alpha whose impact rebounds
    with e (:func:`hunt_crossley_alpha`)."""

    name = "hunt-crossley"

    def __init__(self, pair, curvature, *, cor, damping="flores", separation="force-zero", mu=None):
        super().__init__(pair, curvature, separation=separation, mu=mu)
        check_range("cor (Hunt-Crossley target restitution)", cor, HC_COR_MIN, 1.0)
        check_choice("damping", damping, HC_DAMPINGS)
        self.cor = float(cor)
        self.damping = damping
        self.alpha = (8.0 * (1 - self.cor) / (5.0 * self.cor) if damping == "flores"
                      else hunt_crossley_alpha(self.cor))

    def parameters(self):
        p = super().parameters()
        p["cor"] = self.cor
        p["damping"] = self.damping
        p["alpha"] = self.alpha
        return p

    def onset(self, v_n0, mass):
        v = _arr(v_n0)
        check_positive("onset normal speed v_n0", v, unit="m/s")
        return {"v_n0": v, "mass": _arr(mass, v.shape[0]), "chi": self.alpha / v}

    def normal_force(self, x, xdot, onset):
        x = np.maximum(np.asarray(x, dtype=float), 0.0)
        return self.K * x**1.5 * (1.0 + onset["chi"] * np.asarray(xdot))

    def separation_indicator(self, x, xdot, onset):
        return 1.0 + onset["chi"] * np.asarray(xdot)


class SpringDashpotLaw(_HertzFamily):
    """Linear spring-dashpot: F_n = k x + c x'. k [N/m], c [N s/m]; when not
    given, the paper's equivalent constants (84) with k_p = 1 at the onset
    speed (C_x, B_x with x_m of (90) and omega_x of the equivalent oscillator)."""

    name = "spring-dashpot"

    def __init__(self, pair, curvature, *, k=None, c=None, separation="force-zero", mu=None):
        super().__init__(pair, curvature, separation=separation, mu=mu)
        if k is not None:
            check_positive("k (spring-dashpot stiffness)", k, unit="N/m")
        if c is not None:
            check_finite("c (spring-dashpot damping)", c)
            if c < 0:
                raise ValueError(f"c = {c!r} N s/m must be >= 0")
        self.k, self.c = k, c

    def parameters(self):
        p = super().parameters()
        p.update(k=self.k, c=self.c)
        return p

    def hertz_scale(self, v_n0, mass):
        """Length scale [m]: the elastic amplitude v sqrt(m/k) of the linear
        spring when k is given, else the Hertz x_max."""
        if self.k is None:
            return super().hertz_scale(v_n0, mass)
        return np.asarray(v_n0) * np.sqrt(np.asarray(mass) / self.k)

    def onset(self, v_n0, mass):
        v = _arr(v_n0)
        m = _arr(mass, v.shape[0])
        mod, R = self.moduli, self.geom.R
        x_m = cf.x_max_90(m, v, mod.E, mod.tan_delta, R, 1.0)
        w = cf.omega_x_equivalent(m, x_m, mod.E, mod.tan_delta, R, 1.0)
        B, C, _, _ = cf.equivalent_parameters_84(x_m, mod.E, mod.E_loss, mod.G, mod.G_loss, R, 1.0, w, w, 0.0)
        k = np.full(v.shape, self.k) if self.k is not None else C
        c = np.full(v.shape, self.c) if self.c is not None else B
        return {"v_n0": v, "mass": m, "k": k, "c": c}

    def normal_force(self, x, xdot, onset):
        return onset["k"] * np.maximum(np.asarray(x, dtype=float), 0.0) + onset["c"] * np.asarray(xdot)

    def separation_indicator(self, x, xdot, onset):
        return self.normal_force(x, xdot, onset)


# ------------------------------------------------------------- registry -----
LAWS: dict[str, type[ForceLaw]] = {
    cls.name: cls for cls in (MSFLaw, HertzLaw, KuwabaraKonoLaw, HuntCrossleyLaw, SpringDashpotLaw)
}


def get_law(name_or_class) -> type[ForceLaw]:
    """A law class by registry name, or the class itself; the error lists the names."""
    if isinstance(name_or_class, type) and issubclass(name_or_class, ForceLaw):
        return name_or_class
    try:
        return LAWS[name_or_class]
    except (KeyError, TypeError):
        raise ValueError(f"unknown law {name_or_class!r}; valid names: {', '.join(LAWS)}") from None


def make_law(name_or_class, pair: ContactPair, curvature: Curvature, **options) -> ForceLaw:
    """Construct a law from the registry with its options."""
    return get_law(name_or_class)(pair, curvature, **options)
