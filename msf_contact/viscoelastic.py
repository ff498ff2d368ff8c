"""The exact linear-viscoelastic normal impact of a sphere: ground truth for MSF.

A rigid sphere (radius R, mass m) strikes a linear-viscoelastic half-space
(or, equivalently under Hertz's half-space hypothesis, a viscoelastic sphere
strikes a rigid plate) at speed v0. The material is given by its uniaxial
relaxation modulus

    E(t) = E_inf + sum_i E_i exp(-t / tau_i)  [+ eta delta(t)]          (R1)

(a Prony series, :class:`~msf_contact.materials.PronySeries`; the optional
dashpot eta makes Kelvin-Voigt and its generalisations), with a constant
Poisson ratio nu, so that the contact modulus is E*(t) = E(t) / (1 - nu^2).

Method of dimensionality reduction (Popov & Hess 2015, ch. 2 and 6; the
viscoelastic form of Kuerschner & Popov 2013, used by Willert 2020,
Front. Mech. Eng. 10.3389/fmech.2020.00003): the half-space is replaced by
a row of independent viscoelastic elements of modulus E*(t) per unit length
under the profile g(x) = x^2 / R. An element at |x| enters the contact
when the indentation d reaches g(x) and carries q(x, t) = int_{t_x}^t
E*(t - s) d'(s) ds. This gives, exactly,

- loading (contact radius a(t) = sqrt(R d) growing; Lee & Radok 1960):

      F(t) = int_0^t E*(t - s) P'(s) ds,   P(d) = 4/3 sqrt(R) d^(3/2),   (R2)

- unloading (a shrinking; Ting 1966): the edge elements leave when their
  force vanishes, q(a(t), t) = 0, so a(t) = a(t1) with t1 <= t_m solving

      int_{t1}^t E*(t - s) d'(s) ds = 0,   F(t) = int_0^{t1} E*(t - s) P'(s) ds,   (R3)

- separation: t1 reaches 0, i.e. the centre element unloads,
  int_0^t E*(t - s) d'(s) ds = 0. The surface is then still indented (it
  recovers later); the sphere leaves with the speed it has.

With (R1) every hereditary integral is a sum of exponential memories,
integrated as ODEs: z_i' = P' - z_i / tau_i, y_i' = d' - y_i / tau_i, so
F = [E_inf P + sum E_i z_i + eta P'] / (1 - nu^2) in loading, and in
unloading (R3) is a root t1 of a function that is monotone in t1, solved on
the dense output of the loading phase. Equation of motion m d'' = -F.

Checks (tests/test_viscoelastic.py): the elastic limit is Hertz's impact to
1e-6; a plain discretised MDR foundation (springs and Maxwell branches that
detach where their force would pull), independent of Ting's formula, gives
the same COR and its energy audit balances; the small-damping COR of a
Kelvin-Voigt material matches the published first-order coefficient of
Ramirez, Poeschel, Brilliantov & Schwager (1999, Phys. Rev. E 60, 4465).

Limits: small strain (the half-space and Hertz geometry), quasi-static
(no waves), no adhesion, constant Poisson ratio, normal impact only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from . import closed_forms as cf
from ._validate import check_choice, check_finite, check_positive, check_range, small_strain_note
from .materials import Material, PronySeries
from .record import ImpactRecord

#: Relative tolerance of the ODE integration: as the reference solver
#: (``_normal.RTOL``), so COR, tau, x_max and F_max converge to ~1e-9.
RTOL = 1e-11
#: Absolute tolerance in units of each state's scale (d: x_s, v: v0, z: P(x_s)).
ATOL_SCALED = 1e-13
#: A Prony term with tau_i below this share of the Hertz time x_s/v0 makes
#: the memory ODE stiff: the implicit Radau method is used instead of DOP853.
STIFF_RATIO = 1e-2
#: Relative tolerance of the implicit method (Radau's dense output is of lower
#: order than DOP853's; 1e-10 keeps COR to ~1e-8 on the SLS cases).
RTOL_STIFF = 1e-10
#: Root of (R3) for t1, to this many units of round-off in t.
T1_XTOL = 4 * np.finfo(float).eps
METHODS = ("auto", "DOP853", "Radau")


@dataclass(frozen=True)
class Relaxation:
    """Uniaxial relaxation modulus (R1): E(t) = E_inf + sum E_i exp(-t/tau_i) + eta delta(t).

    E_inf [Pa] >= 0, E_i [Pa] (k,), tau_i [s] (k,), eta [Pa s] >= 0 (a
    parallel dashpot; 0 for a Prony series). At least E_inf > 0 or a
    branch; an instantaneous modulus E_0 = E_inf + sum E_i > 0 unless eta > 0.
    """

    E_inf: float
    E_i: tuple[float, ...] = ()
    tau_i: tuple[float, ...] = ()
    eta: float = 0.0
    source: str = field(default="", compare=False)

    def __post_init__(self):
        check_finite("Relaxation.E_inf", self.E_inf)
        if self.E_inf < 0:
            raise ValueError(f"Relaxation.E_inf = {self.E_inf!r} Pa must be >= 0")
        if len(self.E_i) != len(self.tau_i):
            raise ValueError(f"Relaxation needs as many E_i as tau_i, got {len(self.E_i)} and {len(self.tau_i)}")
        if self.E_i:
            check_positive("Relaxation.E_i", self.E_i, unit="Pa")
            check_positive("Relaxation.tau_i", self.tau_i, unit="s")
        check_finite("Relaxation.eta", self.eta)
        if self.eta < 0:
            raise ValueError(f"Relaxation.eta = {self.eta!r} Pa s must be >= 0")
        if self.E_inf + sum(self.E_i) <= 0:
            raise ValueError("Relaxation has no stiffness: E_inf + sum(E_i) must be > 0")

    # -- constructors ----------------------------------------------------
    @staticmethod
    def from_prony(p: PronySeries, source: str = "") -> "Relaxation":
        """The relaxation modulus of a generalised Maxwell master curve (same E_i, tau_i)."""
        return Relaxation(p.E_inf, tuple(p.E_i), tuple(p.tau_i), source=source)

    @staticmethod
    def standard_linear_solid(E_inf: float, E_1: float, tau_1: float) -> "Relaxation":
        """Zener solid: a spring E_inf parallel to a Maxwell branch (E_1, tau_1)."""
        return Relaxation(E_inf, (E_1,), (tau_1,), source="standard linear solid")

    @staticmethod
    def kelvin_voigt(E: float, eta: float) -> "Relaxation":
        """Kelvin-Voigt solid: spring E [Pa] parallel to a dashpot eta [Pa s]."""
        return Relaxation(E, (), (), eta=eta, source="Kelvin-Voigt")

    @staticmethod
    def of_material(material: Material) -> "Relaxation":
        """From a Material: its PronySeries master curve, or an elastic material
        (tan_delta = 0, no master curve) as a spring E'. Anything else has no
        defined relaxation modulus and is refused."""
        mc = material.master_curve
        if isinstance(mc, PronySeries):
            return Relaxation.from_prony(mc, source=material.source)
        if mc is None and material.tan_delta == 0.0 and not material.rigid:
            return Relaxation(material.E_storage, source=material.source)
        raise ValueError(
            f"material {material.name!r} has no relaxation modulus: give it a PronySeries master curve "
            f"(or tan_delta = 0 for an elastic body); got master_curve={type(mc).__name__}, "
            f"tan_delta={material.tan_delta!r}")

    # -- properties ------------------------------------------------------
    @property
    def E_0(self) -> float:
        """Instantaneous modulus E(0+) [Pa] (infinite with a dashpot)."""
        return math.inf if self.eta > 0 else self.E_inf + sum(self.E_i)

    def moduli(self, omega: float) -> tuple[float, float]:
        """Storage and loss moduli (E', E'') [Pa] at angular frequency omega [rad/s]."""
        wt = omega * np.asarray(self.tau_i, dtype=float)
        Ei = np.asarray(self.E_i, dtype=float)
        storage = self.E_inf + float(np.sum(Ei * wt**2 / (1 + wt**2)))
        loss = float(np.sum(Ei * wt / (1 + wt**2))) + self.eta * omega
        return storage, loss

    def tan_delta(self, omega: float) -> float:
        s, l_ = self.moduli(omega)
        return l_ / s

    def shifted(self, factor: float) -> "Relaxation":
        """Time-temperature shift: tau_i -> a_T tau_i, eta -> a_T eta (WLF's a_T = factor)."""
        check_positive("a_T (time shift)", factor)
        return Relaxation(self.E_inf, self.E_i, tuple(t * factor for t in self.tau_i),
                          self.eta * factor, self.source)

    def prony(self) -> PronySeries:
        """This modulus as the project's PronySeries master curve (no dashpot, E_inf > 0)."""
        if self.eta > 0 or not self.E_i or self.E_inf <= 0:
            raise ValueError("only a Relaxation with E_inf > 0, branches and no dashpot is a PronySeries")
        return PronySeries(self.E_inf, tuple(self.E_i), tuple(self.tau_i))


@dataclass(frozen=True)
class ExactSolution:
    """One exact normal impact. Times [s], lengths [m], speeds [m/s], forces [N].

    t (k,), d (k,) approach, v (k,) approach rate, F (k,) contact force,
    a (k,) contact radius, on a grid over [0, tau]; W_comp, W_rest: work of
    the contact force on the half-space in compression and returned in
    restitution [J].
    """

    v_in: float
    v_out: float
    tau: float
    tau1: float
    x_max: float
    F_max: float
    a_max: float
    x_out: float  #: residual indentation of the surface at separation [m]
    W_comp: float
    W_rest: float
    t: np.ndarray
    d: np.ndarray
    v: np.ndarray
    F: np.ndarray
    a: np.ndarray
    method: str
    ended_by: str

    @property
    def cor(self) -> float:
        return self.v_out / self.v_in


def _scales(rel: Relaxation, E_star_factor: float, R: float, m: float, v0: float):
    """Hertz x_max [m] and time x_s/v0 [s] with the instantaneous (or, with a
    dashpot, the sum of the spring) contact modulus: scales, not results."""
    E_ref = (rel.E_inf + sum(rel.E_i)) * E_star_factor
    xs = float(cf.hertz_x_max(m, v0, E_ref, R))
    return xs, xs / v0


def exact_normal_impact(relaxation: Relaxation, nu: float, radius: float, mass: float, speed: float,
                        *, method: str = "auto", n_samples: int = 401) -> ExactSolution:
    """The exact normal impact (R2), (R3) of a rigid sphere on a viscoelastic half-space.

    relaxation: E(t) (R1); nu: Poisson ratio [-] (constant); radius: the
    sphere's (effective) radius R [m]; mass [kg]; speed v0 > 0 [m/s];
    method: "DOP853", "Radau" or "auto" (Radau when a tau_i is below
    STIFF_RATIO times the Hertz time); n_samples >= 2: points of the curves.
    """
    check_range("nu", nu, -1.0, 0.5, lo_open=True, hi_open=True)
    check_positive("radius", radius, unit="m")
    check_positive("mass", mass, unit="kg")
    check_positive("speed", speed, unit="m/s")
    check_choice("method", method, METHODS)
    if n_samples < 2:
        raise ValueError(f"n_samples = {n_samples!r} must be >= 2")
    R, m, v0 = float(radius), float(mass), float(speed)
    c = 1.0 / (1.0 - nu**2)  # E* = E / (1 - nu^2)
    E_inf, eta = relaxation.E_inf * c, relaxation.eta * c
    Ei = np.asarray(relaxation.E_i, dtype=float) * c
    taui = np.asarray(relaxation.tau_i, dtype=float)
    k = Ei.size
    xs, ts = _scales(relaxation, c, R, m, v0)
    stiff = k > 0 and float(np.min(taui)) < STIFF_RATIO * ts
    if method == "auto":
        method = "Radau" if stiff else "DOP853"
    rtol = RTOL if method == "DOP853" else RTOL_STIFF
    sqR = math.sqrt(R)
    Ps = 4.0 / 3.0 * sqR * xs**1.5
    inv_tau = 1.0 / taui if k else taui

    def P(d):
        return 4.0 / 3.0 * sqR * max(d, 0.0) ** 1.5

    # ---- loading, (R2): y = [d, v, z_1..z_k, y_1..y_k] -----------------------
    def rhs_load(t, y):
        d, v = y[0], y[1]
        z, w = y[2:2 + k], y[2 + k:]
        h = 2.0 * sqR * math.sqrt(max(d, 0.0)) * v  # P'(t) = 2 a d'
        F = E_inf * P(d) + float(Ei @ z) + eta * h
        out = np.empty_like(y)
        out[0], out[1] = v, -F / m
        out[2:2 + k] = h - z * inv_tau
        out[2 + k:] = v - w * inv_tau
        return out

    def ev_turn(t, y):
        return y[1]

    ev_turn.terminal, ev_turn.direction = True, -1
    atol_load = np.concatenate(([xs, v0], np.full(k, Ps), np.full(k, xs))) * ATOL_SCALED
    y0 = np.zeros(2 + 2 * k)
    y0[1] = v0
    load = solve_ivp(rhs_load, (0.0, 1e3 * ts), y0, method=method, rtol=rtol, atol=atol_load,
                     events=ev_turn, dense_output=True, first_step=1e-6 * ts)
    if load.status != 1:
        raise RuntimeError(f"loading phase never reached maximum compression: {load.message}")
    t_m = float(load.t_events[0][0])
    y_m = load.y_events[0][0]
    x_max = float(y_m[0])
    hist = load.sol

    # ---- unloading, (R3): y = [d, v, y_1..y_k] ----------------------------------
    def G_and_state(t1, t, d, v, w):
        """(R3) residual at t1 and the loading state there."""
        s = hist(t1)
        decay = np.exp(-(t - t1) * inv_tau)
        G = E_inf * (d - s[0]) + float(Ei @ (w - decay * s[2 + k:])) + eta * v
        return G, s, decay

    def t1_of(t, d, v, w):
        g0, _, _ = G_and_state(0.0, t, d, v, w)
        if g0 <= 0.0:
            return 0.0
        gm, _, _ = G_and_state(t_m, t, d, v, w)
        if gm >= 0.0:
            return t_m
        return brentq(lambda s: G_and_state(s, t, d, v, w)[0], 0.0, t_m, xtol=T1_XTOL * t_m, rtol=T1_XTOL)

    def force_unload(t, d, v, w):
        t1 = t1_of(t, d, v, w)
        if t1 <= 0.0:
            return 0.0, 0.0
        s = hist(t1)
        decay = np.exp(-(t - t1) * inv_tau)
        return E_inf * P(s[0]) + float(Ei @ (decay * s[2:2 + k])), t1

    def rhs_unload(t, y):
        d, v, w = y[0], y[1], y[2:]
        F, _ = force_unload(t, d, v, w)
        out = np.empty_like(y)
        out[0], out[1] = v, -F / m
        out[2:] = v - w * inv_tau
        return out

    def ev_sep(t, y):
        """Force of the centre element, int_0^t E*(t - s) d'(s) ds: separation at its zero."""
        return E_inf * y[0] + float(Ei @ y[2:]) + eta * y[1]

    ev_sep.terminal, ev_sep.direction = True, -1
    y1 = np.concatenate(([y_m[0], 0.0], y_m[2 + k:]))
    atol_un = np.concatenate(([xs, v0], np.full(k, xs))) * ATOL_SCALED
    un = solve_ivp(rhs_unload, (t_m, t_m + 1e3 * ts), y1, method=method, rtol=rtol, atol=atol_un,
                   events=ev_sep, dense_output=True, first_step=1e-6 * ts)
    if un.status == 1:
        tau = float(un.t_events[0][0])
        y_end = un.y_events[0][0]
        ended = "force-zero"
    else:
        raise RuntimeError(f"unloading phase never separated: {un.message}")
    v_out = max(-float(y_end[1]), 0.0)

    # ---- curves, peak force, works ---------------------------------------------
    tt = np.linspace(0.0, tau, n_samples)

    def state(t):
        if t <= t_m:
            s = hist(t)
            d, v = float(s[0]), float(s[1])
            h = 2.0 * sqR * math.sqrt(max(d, 0.0)) * v
            return d, v, E_inf * P(d) + float(Ei @ s[2:2 + k]) + eta * h, math.sqrt(R * max(d, 0.0))
        s = un.sol(t)
        d, v = float(s[0]), float(s[1])
        F, t1 = force_unload(t, d, v, s[2:])
        return d, v, F, math.sqrt(R * max(float(hist(t1)[0]), 0.0)) if t1 > 0 else 0.0

    rows = np.array([state(float(t)) for t in tt])
    i = int(np.argmax(rows[:, 2]))
    lo, hi = tt[max(i - 1, 0)], tt[min(i + 1, n_samples - 1)]
    from scipy.optimize import minimize_scalar

    res = minimize_scalar(lambda t: -state(t)[2], bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-14 * tau})
    F_max = max(float(rows[i, 2]), float(-res.fun))
    W_comp = 0.5 * m * v0**2
    W_rest = 0.5 * m * v_out**2
    return ExactSolution(
        v_in=v0, v_out=v_out, tau=tau, tau1=t_m, x_max=x_max, F_max=F_max, a_max=math.sqrt(R * x_max),
        x_out=float(y_end[0]), W_comp=W_comp, W_rest=W_rest, t=tt, d=rows[:, 0], v=rows[:, 1], F=rows[:, 2],
        a=rows[:, 3], method=method, ended_by=ended,
    )


def viscoelastic_impact(body1, body2, speed: float, *, temperature: float | None = None,
                        method: str = "auto", n_samples: int = 0) -> ImpactRecord:
    """The exact normal impact of body 1 on body 2 as an :class:`ImpactRecord`.

    One body is rigid (``Material.rigid_body()``), the other carries the
    relaxation modulus (:meth:`Relaxation.of_material`: a PronySeries master
    curve, or elastic). Under Hertz's half-space hypothesis the viscoelastic
    ball on a rigid plate and the rigid ball on a viscoelastic half-space
    are the same problem; R = R1 R2 / (R1 + R2), m the reduced mass.
    temperature [K]: shifts the tau_i by the material's WLF a_T.

    Fields without meaning for a hereditary law (the elastic/viscous split
    of the works (53)-(56), the paper's pressure (20), the collision
    frequency omega_x) are None; W_diss_n is the kinetic energy lost.
    Above x_max/R = SMALL_STRAIN_X_OVER_R the record says so in
    ``outside_validity``, as the reference solver's.
    """
    from .solver import reduced_mass  # the record's conventions, no engine

    check_positive("speed", speed, unit="m/s")
    m1, m2 = body1.material, body2.material
    if m1.rigid == m2.rigid:
        raise ValueError("the exact viscoelastic impact needs exactly one rigid body (the other viscoelastic): "
                         f"got {m1.name!r} (rigid={m1.rigid}) and {m2.name!r} (rigid={m2.rigid})")
    soft = m2 if m1.rigid else m1
    c_bar = math.sqrt(soft.E_storage / soft.density)
    if speed >= c_bar:
        raise ValueError(f"speed = {speed!r} m/s is at or above the bar-wave speed sqrt(E'/rho) = {c_bar:.4g} m/s "
                         f"of {soft.name!r}: the quasi-static impact needs a subsonic speed (as simulate_impact)")
    rel = Relaxation.of_material(soft)
    if temperature is not None:
        if soft.wlf is None:
            raise ValueError(f"material {soft.name!r} has no WLF shift; temperature cannot be applied")
        # tau_i(T) = a_T tau_i(T_ref): the convention of Material.at, E(omega, T) = E_ref(omega a_T)
        rel = rel.shifted(10.0 ** soft.wlf.log10_aT(temperature))
    R = 1.0 / sum(0.0 if math.isinf(b.radius) else 1.0 / b.radius for b in (body1, body2))
    m = reduced_mass(body1.mass, body2.mass)
    s = exact_normal_impact(rel, soft.nu, R, m, speed, method=method, n_samples=max(n_samples, 401))
    inputs = {"speed": speed, "angle_deg": 90.0, "spin": 0.0, "mass_reduced": m, "radius_effective": R,
              "temperature": temperature,
              "body1": {"material": m1.name, "radius": body1.radius, "mass": body1.mass},
              "body2": {"material": m2.name, "radius": body2.radius, "mass": body2.mass}}
    if n_samples > 0:
        inputs["curves"] = {"t": s.t.tolist(), "F_n": s.F.tolist(), "x": s.d.tolist(), "a": s.a.tolist()}
    params = {"law": "viscoelastic-exact", "E_inf": rel.E_inf, "E_i": list(rel.E_i), "tau_i": list(rel.tau_i),
              "eta": rel.eta, "nu": soft.nu, "modulus_convention": "hertz (E* = E(t)/(1 - nu^2))",
              "method": s.method, "x_out": s.x_out, "a_max": s.a_max, "source": rel.source}
    return ImpactRecord(
        cor_n=s.cor, cor_t=None, cor_t_contact=None,
        cor_tau_ratio=s.tau1 / (s.tau - s.tau1), tau=s.tau, tau1=s.tau1, tau2=s.tau - s.tau1,
        x_max=s.x_max, F_max=s.F_max, Pc_max=None, Pc_at_Fmax=None,
        W_el_comp=None, W_visc_comp=None, W_el_rest=None, W_visc_rest=None,
        W_diss_n=0.5 * m * (speed**2 - s.v_out**2), W_diss_t=0.0, Q_t=0.0, spin_in=0.0, spin_out=0.0,
        f_min=None, f_max=None, omega_x=None, omega_y=None, ended_by=s.ended_by,
        law="viscoelastic-exact", engine="reference", dt=None, parameters=params, inputs=inputs,
        outside_validity=[note for note in (small_strain_note(s.x_max, R),) if note],
    )


# ------------------------------------------------------ MSF's damping option --
#: E'' factor that makes MSF's normal damping that of Lee & Radok for a
#: Kelvin-Voigt solid: (37) has 2 eta' psi x' sqrt(x) = 4 eta' sqrt(R) x' sqrt(x)
#: with eta' = E''/omega, (R2) gives eta P' = 2 eta sqrt(R) x' sqrt(x).
LEE_RADOK_LOSS_FACTOR = 0.5


@dataclass(frozen=True)
class ScaledLoss:
    """A master curve whose loss modulus is scaled: (E', factor E'') at each omega.

    curve: anything with ``moduli(omega) -> (E', E'')`` (PronySeries,
    TabulatedMasterCurve); factor >= 0."""

    curve: object
    factor: float

    def __post_init__(self):
        check_finite("ScaledLoss.factor", self.factor)
        if self.factor < 0:
            raise ValueError(f"ScaledLoss.factor = {self.factor!r} must be >= 0")

    def moduli(self, omega: float) -> tuple[float, float]:
        s, l_ = self.curve.moduli(omega)
        return s, self.factor * l_


def with_loss_scaled(material: Material, factor: float = LEE_RADOK_LOSS_FACTOR) -> Material:
    """The material with its loss modulus E'' (and G'') scaled by ``factor``.

    An opt-in correction for MSF measured in docs/exact.md: with factor 1/2
    and the Hertz elastic part (``convention="hertz"``, ``kp_mode="hertz"``)
    MSF's damping is Lee & Radok's for a Kelvin-Voigt solid. MSF itself is
    unchanged; this only changes the material a user hands it."""
    from dataclasses import replace

    check_finite("factor", factor)
    if factor < 0:
        raise ValueError(f"factor = {factor!r} must be >= 0")
    curve = material.master_curve
    return replace(material, name=f"{material.name} (E'' x {factor:g})", tan_delta=material.tan_delta * factor,
                   master_curve=None if curve is None else ScaledLoss(curve, factor))
