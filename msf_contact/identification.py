"""Identification of E', E'' and tg(beta) from a measured impact, paper (96)-(97).

A sphere of (effective) mass m [kg] and radius R [m] strikes a half-space
(rigid unless a plate material is given) at the normal speed V [m/s]; the
measured contact duration tau_x [s] and normal restitution k_x [-] give the
effective storage modulus E' (9), loss modulus E'' (91) and tg(beta) (48).

Two inverses:

- :func:`identify_printed`: (96) and (97) as printed, next to the consistent
  E'' = tg(beta)(88) E'(96) (the printed (97) is three times that, spec 5).
  The spec lists why these closed forms do not reproduce the model.
- :func:`identify_numerical`: root finding on the reference solver, so that
  the MSF law (43) with the chosen omega and k_p modes reproduces the measured
  (tau_x, k_x) to the solver's tolerance.

How the numerical inverse works. In ``self-consistent`` mode the measured
duration fixes the collision frequency directly: omega_x = pi / tau_x (87),
(46). With omega_x known, one impact is a single integration at a fixed
frequency (no fixed-point search), and the pair (E', tg(beta)) that gives
(tau_x, k_x) at that omega_x is self-consistent by construction. For each
trial tg(beta) the storage modulus follows from tau_x by a secant on
log tau(log E') (tau ~ E'^(-2/5), the Hertz scaling, starts it); the outer
root in tg(beta) on [0, 1/3] (bound (100)) matches k_x. The result is then
checked by one full self-consistent solve (:meth:`MSFLaw.self_consistent`),
whose residuals are returned. A fixed omega_x (a DMA frequency) works the
same way with that omega_x in place of pi/tau_x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from . import closed_forms as cf
from ._validate import E_MAX, E_MIN, TAN_DELTA_MAX, check_choice, check_finite, check_positive, check_tan_delta
from .geometry import KP_MODES, Curvature
from .laws import MSFLaw
from .materials import ContactPair, Material

#: Smallest normal restitution the MSF damped-oscillation solution admits,
#: k_x >= (pi - 1)/(pi + 1) = 0.517093..., the bound (100) (tg(beta) <= 1/3).
COR_MIN = (math.pi - 1.0) / (math.pi + 1.0)

#: Tolerance of the inner match of the duration, |ln(tau/tau_x)|: the
#: reference integration (``_normal.RTOL`` = 1e-11) leaves noise of 1e-11 to
#: a few 1e-11 in tau (measured up to 1.5e-11 at x_m/R = 0.4), so 1e-10 asks
#: no more than the solver gives and leaves the 1e-4 round trip of issue 2
#: six orders of margin.
TAU_LOG_TOL = 1e-10
#: Absolute tolerance of the outer root in tg(beta): the integration noise of
#: k_x (~1e-11) over |dk_x/dtg| ~ 1-3.
TAN_DELTA_XTOL = 1e-11
#: A measured k_x this far above the model's k_x at tg(beta) = 1/3 is taken
#: as the bound itself (integration noise of k_x ~1e-11, times 100).
COR_NOISE = 1e-9
#: Secant iterations allowed for the inner duration match; it converges in
#: 3-5 from the Hertz scaling.
MAX_TAU_ITERATIONS = 40

OMEGA_MODES = ("self-consistent",)


@dataclass(frozen=True)
class ImpactMeasurement:
    """One measured normal impact of a sphere on a half-space.

    tau: contact duration tau_x [s]; cor: normal restitution k_x [-];
    speed: normal impact speed V [m/s]; radius: sphere radius R [m];
    mass: (effective) mass m [kg].

    ``cor`` must lie in (0, 1) (k_x = 1 is elastic and leaves tg(beta) = 0
    with (96) singular). The bound (100), tg(beta) <= 1/3, is checked by each
    inverse in its own terms: (88) gives k_x >= (pi-1)/(pi+1) = 0.517094
    (:data:`COR_MIN`), the numerically integrated law gives a lower k_x at
    tg(beta) = 1/3 (0.428631 with a constant k_p, measured with the
    reference solver; 0.4247-0.4281 in ``msf`` mode at x_m/R = 0.25-0.04),
    so :func:`identify_numerical` accepts down to that and says where it
    stops.
    """

    tau: float
    cor: float
    speed: float
    radius: float
    mass: float

    def __post_init__(self):
        check_positive("tau (contact duration)", self.tau, unit="s")
        check_positive("speed", self.speed, unit="m/s")
        check_positive("radius", self.radius, unit="m")
        check_positive("mass", self.mass, unit="kg")
        check_finite("cor", self.cor)
        if not 0.0 < self.cor < 1.0:
            raise ValueError(
                f"cor = {self.cor!r} is outside (0, 1): a restitution of a damped impact; "
                "cor = 1 is elastic (tg(beta) = 0) and (96) is singular"
            )
        # the modulus the measurement implies (elastic Hertz inversion of tau) within the plausible range
        x_m = self.tau * self.speed / cf.HERTZ_TAU_FACTOR
        log_E = (math.log(15.0 / 16.0 * self.mass) + 2.0 * math.log(self.speed) - 0.5 * math.log(self.radius)
                 - 2.5 * math.log(x_m)) if x_m > 0 else math.inf
        E = math.exp(min(log_E, 709.0))  # beyond e^709 a float overflows; the bound below refuses it anyway
        if not E_MIN <= E <= E_MAX:
            raise ValueError(
                f"tau = {self.tau!r} s with speed = {self.speed!r} m/s, radius = {self.radius!r} m and mass = "
                f"{self.mass!r} kg implies E' ~ {E:.3g} Pa (elastic Hertz inversion), outside [{E_MIN:g}, "
                f"{E_MAX:g}] Pa (bounds of plausibility, msf_contact._validate.E_MIN/E_MAX)")
        if not x_m < 2.0 * self.radius:
            raise ValueError(f"tau = {self.tau!r} s at speed = {self.speed!r} m/s implies an approach of ~{x_m:.3g} m, "
                             f"beyond the ball's diameter 2R = {2 * self.radius:.3g} m")


@dataclass(frozen=True)
class PrintedIdentification:
    """(96)-(97) evaluated as printed. Moduli [Pa], k_p [-]."""

    E_storage: float  #: E' of (96) [Pa]
    E_loss_as_printed: float  #: E'' of (97) as printed [Pa] (= 3 tg(beta) E')
    E_loss: float  #: E'' = tg(beta)(88) E'(96), consistent with (48) [Pa]
    tan_delta: float  #: tg(beta) of (88) [-]
    k_p: float  #: correlation coefficient used in (96)-(97) [-]
    kp_mode: str


@dataclass(frozen=True)
class NumericalIdentification:
    """The numerical inverse. Effective values of the pair (9), (91) and the
    ball's own values (equal to them on a rigid plate).

    residual_tau: tau_model / tau_x - 1 [-]; residual_cor: k_model - k_x [-],
    both from one full self-consistent (or fixed-omega) reference solve with
    the identified material.
    """

    E_storage: float  #: effective E' [Pa]
    E_loss: float  #: effective E'' [Pa]
    tan_delta: float  #: effective tg(beta) [-]
    ball_E_storage: float  #: the ball's E' [Pa]
    ball_E_loss: float  #: the ball's E'' [Pa]
    ball_tan_delta: float  #: the ball's tg(beta) [-]
    omega_x: float  #: collision frequency of the model impact (46) [rad/s]
    tau_model: float  #: contact duration of the model impact [s]
    cor_model: float  #: normal restitution of the model impact [-]
    x_max_model: float  #: maximum approach of the model impact [m]
    residual_tau: float
    residual_cor: float
    n_solves: int  #: reference integrations used (the check solve excluded)
    kp_mode: str
    omega_mode: str


def _kp_guess(kp_mode: str) -> float:
    return {"hertz": 1.0, "msf-small": math.sqrt(2.0), "msf": math.sqrt(2.0)}[kp_mode]


def identify_printed(meas: ImpactMeasurement, kp_mode: str = "msf", strict: bool = False) -> PrintedIdentification:
    """E' of (96), E'' of (97) as printed and consistent, tg(beta) of (88).

    k_p: 1 (``hertz``), sqrt(2) (``msf-small``) or, in ``msf`` mode,
    sqrt(2 - x_m/R) at x_m of (90) with the identified E' and tg(beta),
    a fixed point (15). k_x < (pi-1)/(pi+1) gives tg(beta) > 1/3: a
    ``ValidityWarning`` naming (100), or with ``strict`` a ``ValueError``.
    """
    check_choice("kp_mode", kp_mode, KP_MODES)
    m, V, R, tau, k = meas.mass, meas.speed, meas.radius, meas.tau, meas.cor
    tan_delta = float(cf.tan_delta_88(k))
    if k < COR_MIN:
        check_tan_delta(
            f"tg(beta) of (88) at cor = {k!r} (below (pi-1)/(pi+1) = {COR_MIN:.9f})", tan_delta, strict=strict
        )
    k_p = _kp_guess(kp_mode)
    for _ in range(100):
        E = float(cf.E_storage_96(m, V, R, k_p, tau, k))
        new = float(cf.kp_for_mode(kp_mode, m, V, E, tan_delta, R))
        if abs(new - k_p) <= 1e-15 * new:
            break
        k_p = new
    E = float(cf.E_storage_96(m, V, R, k_p, tau, k))
    return PrintedIdentification(
        E_storage=E,
        E_loss_as_printed=float(cf.E_loss_97_as_printed(m, V, R, k_p, tau, k)),
        E_loss=float(cf.E_loss_97(m, V, R, k_p, tau, k)),
        tan_delta=tan_delta,
        k_p=k_p,
        kp_mode=kp_mode,
    )


def _ball_from_effective(E: float, tan_delta: float, plate: Material) -> tuple[float, float]:
    """Invert the series rules (9), (91) for the ball on a given plate:
    the ball's (E', tg(beta))."""
    if plate.rigid:
        return E, tan_delta
    E_loss = tan_delta * E
    if E >= plate.E_storage:
        raise ValueError(
            f"identified effective E' = {E:.6g} Pa is not below the plate's E' = {plate.E_storage:.6g} Pa: "
            "no ball modulus gives it by (9)"
        )
    if E_loss > 0 and E_loss >= plate.E_loss:
        raise ValueError(
            f"identified effective E'' = {E_loss:.6g} Pa is not below the plate's E'' = {plate.E_loss:.6g} Pa: "
            "no ball loss modulus gives it by (91)"
        )
    E_b = E * plate.E_storage / (plate.E_storage - E)
    E_loss_b = 0.0 if E_loss == 0 else E_loss * plate.E_loss / (plate.E_loss - E_loss)
    return E_b, E_loss_b / E_b


#: A fixed omega_x of the numerical inverse within these factors of the
#: impact's own frequency pi/tau (three decades either side).
OMEGA_SPAN_MIN, OMEGA_SPAN_MAX = 1e-3, 1e3


def identify_numerical(
    meas: ImpactMeasurement,
    *,
    kp_mode: str = "msf",
    omega: str | float = "self-consistent",
    separation: str = "force-zero",
    plate: Material | None = None,
    ball_nu: float = 0.3,
) -> NumericalIdentification:
    """E' and tg(beta) such that the reference solver, with the MSF law (43)
    in the given k_p, omega and separation modes, reproduces (tau_x, k_x).

    ``plate``: the half-space's material (default rigid); the effective values
    are found first, then the ball's by inverting (9), (91). ``ball_nu`` only
    enters the shear moduli of the check solve (not the normal impact).
    Raises ``ValueError`` when k_x is below what the model gives at
    tg(beta) = 1/3 (the bound (100)).
    """
    check_choice("kp_mode", kp_mode, KP_MODES)
    if isinstance(omega, str):
        check_choice("omega", omega, OMEGA_MODES)
        omega_x = math.pi / meas.tau  # (87), (46): the collision's own frequency
    else:
        check_positive("omega", omega, unit="rad/s")
        omega_x = float(omega)
        w_own = math.pi / meas.tau
        if not OMEGA_SPAN_MIN * w_own <= omega_x <= OMEGA_SPAN_MAX * w_own:
            raise ValueError(f"omega = {omega_x!r} rad/s is outside [{OMEGA_SPAN_MIN:g}, {OMEGA_SPAN_MAX:g}] x pi/tau = "
                             f"[{OMEGA_SPAN_MIN * w_own:.4g}, {OMEGA_SPAN_MAX * w_own:.4g}] rad/s, the impact's own "
                             "frequency (46), (87): a fixed omega_x this far from it makes E'' = tg E' of the "
                             "collision meaningless and the inverse's damping extreme")
    plate = plate if plate is not None else Material.rigid_body()
    m, V, R = meas.mass, meas.speed, meas.radius
    curv = Curvature.sphere_on_plane(R)
    trial_plate = Material.rigid_body()
    n_solves = 0

    def solve(E: float, tan_delta: float):
        nonlocal n_solves
        n_solves += 1
        law = MSFLaw(ContactPair(Material("trial", E, 0.0, ball_nu, 1.0), trial_plate), curv,
                     omega=omega_x, kp_mode=kp_mode, separation=separation)
        return law.solve_normal(V, m, {"E": np.array([E]), "eta_E": np.array([tan_delta * E / omega_x])})

    # Hertz inversion of the duration as the first E' (k_p of the mode at small x/R)
    k_p0 = _kp_guess(kp_mode)
    x_m0 = meas.tau * V / cf.HERTZ_TAU_FACTOR
    E_last = [15.0 * m * V**2 / (16.0 * k_p0 * math.sqrt(R) * x_m0**2.5)]
    log_tau_x = math.log(meas.tau)

    def match_tau(tan_delta: float):
        """E' with tau(E', tg) = tau_x at fixed omega_x; secant in log E'."""
        a = math.log(E_last[0])
        sol_a = solve(math.exp(a), tan_delta)
        fa = math.log(sol_a.tau) - log_tau_x
        if abs(fa) <= TAU_LOG_TOL:
            return math.exp(a), sol_a
        b = a + fa / 0.4  # tau ~ E'^(-2/5)
        for _ in range(MAX_TAU_ITERATIONS):
            sol_b = solve(math.exp(b), tan_delta)
            fb = math.log(sol_b.tau) - log_tau_x
            if abs(fb) <= TAU_LOG_TOL:
                E_last[0] = math.exp(b)
                return math.exp(b), sol_b
            slope = (fb - fa) / (b - a) if b != a else -0.4
            if not slope < 0:  # the duration falls with E'; guard against noise
                slope = -0.4
            a, fa = b, fb
            b = b - fb / slope
        raise RuntimeError(
            f"duration match did not converge for tg(beta) = {tan_delta!r} "
            f"(|ln tau/tau_x| = {abs(fb):.3g} after {MAX_TAU_ITERATIONS} steps)"
        )

    cache: dict[float, tuple[float, object]] = {}

    def g(tan_delta: float) -> float:
        if tan_delta == 0.0:
            return 1.0 - meas.cor  # elastic: k_x = 1
        E, sol = match_tau(tan_delta)
        cache[tan_delta] = (E, sol)
        return sol.cor - meas.cor

    g_hi = g(TAN_DELTA_MAX)
    if g_hi > COR_NOISE:
        cor_lo = cache[TAN_DELTA_MAX][1].cor
        raise ValueError(
            f"cor = {meas.cor!r} is below {cor_lo:.9f}, the restitution the MSF model gives at "
            f"tg(beta) = 1/3 (the bound (100)) with tau = {meas.tau!r} s: no tg(beta) in [0, 1/3] fits"
        )
    if g_hi >= 0:  # at the bound itself, within the integration noise
        tan_delta = TAN_DELTA_MAX
    else:
        tan_delta = brentq(g, 0.0, TAN_DELTA_MAX, xtol=TAN_DELTA_XTOL, rtol=4 * np.finfo(float).eps)
    E, _ = cache[tan_delta] if tan_delta in cache else match_tau(tan_delta)
    E_loss = tan_delta * E
    E_b, tan_delta_b = _ball_from_effective(E, tan_delta, plate)
    ball = Material("identified", E_b, tan_delta_b, ball_nu, 1.0)

    # the check: one full reference solve with the identified material
    law = MSFLaw(ContactPair(ball, plate), curv, omega=omega, kp_mode=kp_mode, separation=separation)
    if isinstance(omega, str):
        w, sol, _ = law.self_consistent(V, m)
    else:
        w = omega_x
        mod = law.moduli
        sol = law.solve_normal(V, m, {"E": np.array([mod.E]), "eta_E": np.array([mod.E_loss / w])})
    if law.outside(np.array([sol.x_max]))[0]:
        raise ValueError(
            f"the identified impact has x_max = {sol.x_max:.6g} m >= 2R = {2 * R:.6g} m: outside the msf k_p (15)"
        )
    return NumericalIdentification(
        E_storage=E, E_loss=E_loss, tan_delta=tan_delta,
        ball_E_storage=E_b, ball_E_loss=tan_delta_b * E_b, ball_tan_delta=tan_delta_b,
        omega_x=float(w), tau_model=sol.tau, cor_model=sol.cor, x_max_model=sol.x_max,
        residual_tau=sol.tau / meas.tau - 1.0, residual_cor=sol.cor - meas.cor,
        n_solves=n_solves, kp_mode=kp_mode, omega_mode=omega if isinstance(omega, str) else "fixed",
    )
