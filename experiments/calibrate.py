"""Calibration of the engines' own contact to the MSF law at one impact speed.

"What solref gives my material?" Given a ball, a plate, an impact speed V
and the engine time step dt the user will run at, find the built-in contact
parameters whose engine runs reproduce the reference solver's
(:func:`msf_contact.solver.simulate_impact`) coefficient of restitution
cor_n and contact duration tau at V:

``mujoco-solref``
    MuJoCo's (timeconst, dampratio) are fitted; solimp is held at a constant
    impedance d0 = d_width = 0.95 (:data:`CONSTANT_SOLIMP`), which makes the
    contact a linear oscillator r'' = -(2/timeconst) r' - r/(timeconst
    dampratio)^2 (MuJoCo docs, "solref"): damping ratio = dampratio, natural
    frequency w_n = 1/(timeconst dampratio), for every mass and speed. The
    initial guess is that oscillator ended where its force returns to zero
    (:func:`engines.mujoco.builtin.linear_oscillator_cor`, end="force-zero"):
    dampratio from the COR, timeconst from tau. The same contact in MuJoCo's
    direct form is solref = (-w_n^2, -2/timeconst) [1/s^2, 1/s] (with
    d = d_max the impedance cancels), reported alongside.
``pybullet-restitution``
    pybullet's pair restitution e (sqrt(e) on each body, with the settings
    that let it act, :mod:`engines.pybullet.builtin`): a velocity target, so
    the COR is e and the contact lasts one step; tau cannot be matched.
``pybullet-spring``
    pybullet's pair contact stiffness k [N/m] and damping d [N s/m], fitted
    to (cor_n, tau) with the reduced mass of the pair; pybullet integrates
    the spring implicitly, which damps it numerically, so the COR can be out
    of reach (then the fit says so, with the largest COR it can give).

Onset phase. Where in a time step the contact begins changes a built-in
contact's COR (MuJoCo at 27 steps per contact: +-1%; at dt = 1 ms, 3 steps
per contact: 0.59 to 1.01, measured). The engines' figures here are
therefore means over ``phases`` onset phases, uniform in the step
(:func:`phase_gaps`); the spread is reported with them. The fit matches the
mean; the 1% acceptance is on the mean.

Every fit is against the engine's own runs at the given dt (the formulas are
the starting point only): a root finder (:func:`scipy.optimize.brentq`) on
the damping parameter at a fixed stiffness, and a fixed-point update of the
stiffness from the measured tau, alternated until both match.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.optimize import brentq

from msf_contact._validate import check_choice, check_positive, check_range
from msf_contact.geometry import Curvature
from msf_contact.laws import ForceLaw, make_law
from msf_contact.materials import ContactPair, Material
from msf_contact.record import ImpactRecord
from msf_contact.solver import Body, check_impact_inputs, reduced_mass, simulate_impact

from .arguments import DEFAULT_BALL, DEFAULT_RADIUS, DEFAULT_SPEED, add_material_arguments, material, number, to_json
from .impact import check_x_max

#: MuJoCo solimp held during the fit: constant impedance d0 = d_width = 0.95
#: (width 1 mm, midpoint 0.5, power 2 irrelevant when d0 = d_width).
CONSTANT_SOLIMP = (0.95, 0.95, 0.001, 0.5, 2.0)
#: Onset phases averaged per engine figure (uniform in one step).
DEFAULT_PHASES = 8
#: The fitted mean COR is converged to this relative error: 10x inside the
#: 1% acceptance, well above brentq's own resolution.
COR_RTOL = 1e-3
#: The fitted mean tau is converged to this relative error, or to the
#: resolution of a phase-averaged step count, dt / phases, if coarser.
TAU_RTOL = 5e-3
#: Outer iterations (damping solve, stiffness update) before giving up on tau.
MAX_OUTER = 8
#: Bracketing: the damping parameter is scaled by this factor per step, at
#: most BRACKET_STEPS times, to find a sign change of COR - target.
BRACKET_FACTOR = 1.5
BRACKET_STEPS = 24
#: MuJoCo clamps timeconst to 2 dt (its default "refsafe" flag).
MUJOCO_MIN_TIMECONST_STEPS = 2.0
FORMS = ("mujoco-solref", "pybullet-restitution", "pybullet-spring")


# ------------------------------------------------------------- problem ---
@dataclass(frozen=True)
class Problem:
    """What is calibrated: a law between a ball and a plate at one impact.

    law: the MSF (or another) law of the pair; ball: the ball (finite mass);
    plate: the plate (a fixed half-space); speed [m/s] the calibration speed;
    dt [s] the engine step the user runs at; angle_deg to the plate (90 =
    normal, the calibration); phases: onset phases averaged per engine
    figure; integrator: MuJoCo's.
    """

    law: ForceLaw
    ball: Body
    plate: Body
    speed: float
    dt: float
    angle_deg: float = 90.0
    phases: int = DEFAULT_PHASES
    integrator: str = "euler"

    def __post_init__(self):
        check_positive("dt", self.dt, unit="s")
        if not isinstance(self.phases, int) or self.phases < 1:
            raise ValueError(f"phases = {self.phases!r} must be a whole number >= 1")
        check_choice("integrator", self.integrator, ("euler", "rk4", "implicitfast"))
        if not math.isinf(self.plate.mass):
            raise ValueError(f"plate mass = {self.plate.mass!r} kg: calibration is against a fixed plate (inf)")
        check_impact_inputs(self.law, self.ball, self.plate, self.speed, self.angle_deg, 0.0)

    @property
    def mass(self) -> float:
        """Reduced mass of the pair [kg] (the ball's, on a fixed plate)."""
        return reduced_mass(self.ball.mass, self.plate.mass)


def problem_of(ball: Material, plate: Material, radius: float, speed: float, dt: float, *,
               mass: float | None = None, law_options: dict | None = None, **kw) -> Problem:
    """A :class:`Problem` for an MSF ball of ``radius`` [m] on a plate (both
    materials; ``mass`` [kg] overrides the density's), law options passed to
    :func:`msf_contact.laws.make_law` (default: the paper's self-consistent
    MSF)."""
    check_positive("radius", radius, unit="m")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        law = make_law("msf", ContactPair(ball, plate), Curvature.sphere_on_plane(radius), **(law_options or {}))
    return Problem(law, Body.sphere(ball, radius, mass), Body.half_space(plate), float(speed), float(dt), **kw)


def reference(p: Problem, speed: float | None = None, angle_deg: float | None = None) -> ImpactRecord:
    """The reference solver's impact (the calibration target at p.speed)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate_impact(p.law, p.ball, p.plate, p.speed if speed is None else speed,
                               p.angle_deg if angle_deg is None else angle_deg)


# ------------------------------------------------------ phase averages ---
def phase_gaps(speed: float, angle_deg: float, dt: float, phases: int) -> list[float]:
    """Gaps [m] that start the contact at the middles of ``phases`` equal
    parts of one step: the flight over gap k lasts (k + 1/2)/phases dt."""
    vn = speed * math.sin(math.radians(angle_deg))
    return [(k + 0.5) / phases * vn * dt for k in range(phases)]


@dataclass(frozen=True)
class PhaseStats:
    """An engine impact over onset phases: means, and the COR's and tau's
    extremes. Units as the impact record (SI); None where not defined."""

    cor_n: float
    cor_n_min: float
    cor_n_max: float
    tau: float
    tau_min: float
    tau_max: float
    x_max: float
    F_max: float
    cor_t: float | None
    spin_out: float | None
    phases: int

    @staticmethod
    def of(records: list[ImpactRecord]) -> "PhaseStats":
        def mean(key):
            vals = [getattr(r, key) for r in records]
            return None if any(v is None for v in vals) else float(np.mean(vals))

        cor = [r.cor_n for r in records]
        tau = [r.tau for r in records]
        return PhaseStats(float(np.mean(cor)), float(min(cor)), float(max(cor)), float(np.mean(tau)),
                          float(min(tau)), float(max(tau)), mean("x_max"), mean("F_max"), mean("cor_t"),
                          mean("spin_out"), len(records))


def mujoco_builtin(p: Problem, solref, solimp=CONSTANT_SOLIMP, *, speed: float | None = None,
                   angle_deg: float | None = None, friction: float | None = None) -> PhaseStats:
    """MuJoCo's own contact with ``solref``, ``solimp`` on the problem's
    impact (or at ``speed``, ``angle_deg``), over the onset phases. With
    ``friction`` (a Coulomb coefficient) the contact has condim 3, otherwise
    it is frictionless (condim 1)."""
    from engines.mujoco import run_builtin_impact

    v = p.speed if speed is None else speed
    a = p.angle_deg if angle_deg is None else angle_deg
    builtin = {"solref": tuple(solref), "solimp": tuple(solimp)}
    if friction is not None:
        builtin.update(condim=3, friction=(friction, 0.005, 0.0001))
    recs = [run_builtin_impact(p.ball, p.plate, v, a, builtin=builtin, dt=p.dt, gap=g, integrator=p.integrator)
            for g in phase_gaps(v, a, p.dt, p.phases)]
    return PhaseStats.of(recs)


def pybullet_builtin(p: Problem, contact: dict, *, speed: float | None = None, angle_deg: float | None = None,
                     friction: float | None = None) -> PhaseStats:
    """pybullet's own contact (``contact``: restitution and/or
    contact_stiffness, contact_damping) over the onset phases; ``friction``
    sets both bodies' lateral friction (pybullet multiplies them: each gets
    sqrt(friction))."""
    from engines.pybullet import run_builtin_impact

    v = p.speed if speed is None else speed
    a = p.angle_deg if angle_deg is None else angle_deg
    c = dict(contact)
    if friction is not None:
        c["lateral_friction"] = math.sqrt(friction)
    recs = [run_builtin_impact(p.ball, p.plate, v, a, dt=p.dt, gap=g, builtin=c)
            for g in phase_gaps(v, a, p.dt, p.phases)]
    return PhaseStats.of(recs)


# ---------------------------------------------------- oscillator guesses ---
def force_zero_duration(dampratio: float) -> float:
    """Contact duration of the unilateral linear oscillator x'' + 2 z w x' +
    w^2 x = 0 that ends where its force returns to zero, in units of 1/w
    (see :func:`engines.mujoco.builtin.linear_oscillator_cor`)."""
    check_range("dampratio", dampratio, 0.0, 1.0, hi_open=True)
    z = float(dampratio)
    wd = math.sqrt(1.0 - z * z)
    return (math.atan2(-2.0 * z * wd, 1.0 - 2.0 * z * z) + math.pi) / wd


def dampratio_for_cor(cor: float) -> float:
    """Damping ratio of the force-zero linear oscillator with this COR."""
    from engines.mujoco.builtin import linear_oscillator_cor

    check_range("cor", cor, 0.0, 1.0, lo_open=True, hi_open=True)
    return brentq(lambda z: linear_oscillator_cor(z, "force-zero") - cor, 0.0, 0.999, xtol=1e-12)


def mujoco_guess(cor: float, tau: float) -> tuple[float, float]:
    """(timeconst [s], dampratio) of MuJoCo's oscillator with constant
    impedance giving this COR and duration tau [s]: w_n = 1/(timeconst z)."""
    z = dampratio_for_cor(cor)
    w = force_zero_duration(z) / tau
    return 1.0 / (w * z), z


def spring_guess(cor: float, tau: float, mass: float) -> tuple[float, float]:
    """(k [N/m], d [N s/m]) of a linear spring-dashpot of mass [kg] with this
    COR and duration tau [s] (force-zero end)."""
    z = dampratio_for_cor(cor)
    w = force_zero_duration(z) / tau
    return mass * w * w, 2.0 * z * mass * w


# ----------------------------------------------------------------- fits ---
@dataclass
class Fit:
    """One calibration. form: one of :data:`FORMS`; params: what to give the
    engine; fitted / held: the names of the parameters fitted and the values
    held; target_cor, target_tau [s]: the reference solver's; stats: the
    engine's phase-averaged impact with ``params``; cor_ok / tau_ok: the fit
    reached COR_RTOL / its tau tolerance; evaluations: engine figures
    computed (each ``phases`` runs); note: what could not be matched."""

    form: str
    params: dict
    fitted: tuple[str, ...]
    held: dict
    target_cor: float
    target_tau: float
    speed: float
    dt: float
    phases: int
    stats: PhaseStats
    cor_ok: bool
    tau_ok: bool
    tau_rtol: float
    evaluations: int
    equivalent: dict = field(default_factory=dict)
    note: str = ""

    @property
    def cor_error(self) -> float:
        """(engine mean COR - target) / target."""
        return (self.stats.cor_n - self.target_cor) / self.target_cor

    @property
    def tau_error(self) -> float:
        return (self.stats.tau - self.target_tau) / self.target_tau

    def to_dict(self) -> dict:
        d = asdict(self)
        d["fitted"] = list(self.fitted)
        d["cor_error"] = self.cor_error
        d["tau_error"] = self.tau_error
        return d


class _Counter:
    def __init__(self, fn):
        self.fn, self.n, self.cache = fn, 0, {}

    def __call__(self, *key):
        if key not in self.cache:
            self.n += 1
            self.cache[key] = self.fn(*key)
        return self.cache[key]


def _solve_damping(stats_of, target: float, c0: float, c_min: float, c_max: float) -> tuple[float, bool]:
    """The damping parameter c in [c_min, c_max] whose mean COR is the target
    (COR falls with c), bracketing from c0 by BRACKET_FACTOR (below
    1e-3 c0 the bracket jumps to c_min). Returns (c, reached); not reached:
    the end of the range nearest the target."""

    def f(c):
        return stats_of(c).cor_n - target

    def solve(a, b):
        return brentq(f, a, b, xtol=1e-10 * max(abs(a), abs(b)), rtol=1e-10, maxiter=60), True

    c = min(max(c0, c_min), c_max)
    fc = f(c)
    if fc == 0.0:
        return c, True
    if fc > 0:  # COR too high: more damping
        a = c
        for _ in range(BRACKET_STEPS):
            b = min(a * BRACKET_FACTOR, c_max)
            if f(b) <= 0:
                return solve(a, b)
            if b >= c_max:
                return c_max, False
            a = b
        return a, False
    b = c
    for _ in range(BRACKET_STEPS):
        a = b / BRACKET_FACTOR
        if a < max(c_min, 1e-3 * c0):
            a = c_min
        if f(a) >= 0:
            return solve(a, b)
        if a <= c_min:
            return c_min, False
        b = a
    return b, False


def _tau_rtol(p: Problem, tau: float) -> float:
    return max(TAU_RTOL, p.dt / (p.phases * tau))


def calibrate_mujoco(p: Problem, solimp=CONSTANT_SOLIMP, target: ImpactRecord | None = None) -> Fit:
    """MuJoCo solref (timeconst, dampratio) with solimp held (module docstring)."""
    ref = target or reference(p)
    tc, z = mujoco_guess(ref.cor_n, ref.tau)
    tc_min = MUJOCO_MIN_TIMECONST_STEPS * p.dt
    ev = _Counter(lambda tc_, z_: mujoco_builtin(p, (tc_, z_), solimp))
    tol = _tau_rtol(p, ref.tau)
    note = ""
    tau_ok = cor_ok = False
    for _ in range(MAX_OUTER):
        tc = max(tc, tc_min)
        z, cor_ok = _solve_damping(lambda c: ev(tc, c), ref.cor_n, z, 1e-6, 10.0)
        s = ev(tc, z)
        if abs(s.tau / ref.tau - 1.0) <= tol:
            tau_ok = True
            break
        new = tc * ref.tau / s.tau
        if new < tc_min and tc <= tc_min:
            note = (f"tau = {ref.tau:.4g} s needs timeconst < 2 dt = {tc_min:.4g} s, which MuJoCo clamps to 2 dt "
                    "(refsafe): the COR is matched, tau is not; use a smaller dt")
            break
        tc = new
    else:
        note = f"tau not converged within {MAX_OUTER} outer iterations (engine tau is quantised to dt)"
    s = ev(tc, z)
    if not cor_ok:
        note = (note + "; " if note else "") + (f"COR {ref.cor_n:.4g} out of reach at timeconst {tc:.4g} s "
                                                f"(engine gives {s.cor_n:.4g})")
    w = 1.0 / (tc * z)
    return Fit("mujoco-solref", {"solref": [tc, z], "solimp": list(solimp)}, ("timeconst", "dampratio"),
               {"solimp": list(solimp)}, ref.cor_n, ref.tau, p.speed, p.dt, p.phases, s,
               cor_ok and abs(s.cor_n / ref.cor_n - 1) <= COR_RTOL, tau_ok, tol, ev.n,
               equivalent={"solref_direct": [-w * w, -2.0 / tc], "natural_frequency": w,
                           "guess": list(mujoco_guess(ref.cor_n, ref.tau))}, note=note)


def calibrate_pybullet_restitution(p: Problem, target: ImpactRecord | None = None) -> Fit:
    """pybullet's pair restitution: e = the target COR, verified by engine runs
    (and corrected by a root finder should the engine not return e)."""
    ref = target or reference(p)
    ev = _Counter(lambda e: pybullet_builtin(p, {"restitution": e}))
    e = ref.cor_n
    s = ev(e)
    cor_ok = abs(s.cor_n / ref.cor_n - 1) <= COR_RTOL
    if not cor_ok:
        e, cor_ok = brentq(lambda x: ev(x).cor_n - ref.cor_n, 0.0, 1.0, xtol=1e-10), True
        s = ev(e)
    return Fit("pybullet-restitution", {"restitution": e}, ("restitution",),
               dict(_pybullet_settings()), ref.cor_n, ref.tau, p.speed, p.dt, p.phases, s, cor_ok,
               False, _tau_rtol(p, ref.tau), ev.n,
               note="a velocity target: the contact lasts one step, tau cannot be matched")


def _pybullet_settings() -> dict:
    from engines.pybullet.builtin import RESTITUTION_BODY, RESTITUTION_ENGINE

    return {"engine": dict(RESTITUTION_ENGINE), "body": dict(RESTITUTION_BODY)}


def calibrate_pybullet_spring(p: Problem, target: ImpactRecord | None = None) -> Fit:
    """pybullet's pair contact stiffness k and damping d (module docstring)."""
    ref = target or reference(p)
    k, d = spring_guess(ref.cor_n, ref.tau, p.mass)
    ev = _Counter(lambda k_, d_: pybullet_builtin(p, {"contact_stiffness": k_, "contact_damping": d_}))
    tol = _tau_rtol(p, ref.tau)
    note = ""
    tau_ok = cor_ok = False
    for _ in range(MAX_OUTER):
        d, cor_ok = _solve_damping(lambda c: ev(k, c), ref.cor_n, d, 0.0, 1e3 * d + 1.0)
        s = ev(k, d)
        if not cor_ok:
            note = (f"COR {ref.cor_n:.4g} is out of reach with k = {k:.4g} N/m at dt = {p.dt:g} s: pybullet's "
                    f"implicit spring alone (d = {d:g}) gives {s.cor_n:.4g}; use the restitution form or a "
                    "smaller dt")
            break
        if abs(s.tau / ref.tau - 1.0) <= tol:
            tau_ok = True
            break
        k *= (s.tau / ref.tau) ** 2
    else:
        note = f"tau not converged within {MAX_OUTER} outer iterations (engine tau is quantised to dt)"
    s = ev(k, d)
    return Fit("pybullet-spring", {"contact_stiffness": k, "contact_damping": d},
               ("contact_stiffness", "contact_damping"), {"restitution": None, **_pybullet_settings()},
               ref.cor_n, ref.tau, p.speed, p.dt, p.phases, s,
               cor_ok and abs(s.cor_n / ref.cor_n - 1) <= COR_RTOL, tau_ok, tol, ev.n,
               equivalent={"reduced_mass": p.mass, "guess": list(spring_guess(ref.cor_n, ref.tau, p.mass))},
               note=note)


_CALIBRATORS = {"mujoco-solref": calibrate_mujoco, "pybullet-restitution": calibrate_pybullet_restitution,
                "pybullet-spring": calibrate_pybullet_spring}


def calibrate(p: Problem, forms=FORMS) -> tuple[ImpactRecord, dict[str, Fit]]:
    """The reference impact and one :class:`Fit` per form in ``forms``."""
    for f in forms:
        check_choice("form", f, FORMS)
    ref = reference(p)
    return ref, {f: _CALIBRATORS[f](p, target=ref) for f in forms}


def builtin_params(fit: Fit) -> dict:
    """The engine's ``builtin`` dict for a fit (run_builtin_impact's argument)."""
    return dict(fit.params)


# ------------------------------------------------------------ command line ---
def add_calibrate_arguments(p) -> None:
    """`msf-contact calibrate`: the pair, the speed and the engine step."""
    add_material_arguments(p, "ball", f"default {DEFAULT_BALL}")
    add_material_arguments(p, "plate", "omitted: a rigid plate")
    p.add_argument("--radius", type=number, default=DEFAULT_RADIUS, metavar="R",
                   help=f"ball radius [m] (default {DEFAULT_RADIUS})")
    p.add_argument("--mass", type=number, default=None, metavar="KG", help="ball mass [kg] (default: from density)")
    p.add_argument("--speed", type=number, default=DEFAULT_SPEED, metavar="V",
                   help=f"calibration (normal impact) speed [m/s] (default {DEFAULT_SPEED})")
    p.add_argument("--dt", type=number, default=1e-4, metavar="SECONDS",
                   help="the engine time step the parameters are for [s] (default 1e-4)")
    p.add_argument("--phases", type=int, default=DEFAULT_PHASES,
                   help=f"onset phases averaged per engine figure (default {DEFAULT_PHASES})")
    p.add_argument("--integrator", choices=("euler", "rk4", "implicitfast"), default="euler",
                   help="MuJoCo integrator (default euler)")
    p.add_argument("--form", action="append", choices=FORMS, default=None,
                   help="what to fit (repeatable; default all: " + ", ".join(FORMS) + ")")
    p.add_argument("--json", action="store_true", help="print one JSON object (SI units)")


def cmd_calibrate(args) -> int:
    check_positive("--radius", args.radius, unit="m")
    check_positive("--speed", args.speed, unit="m/s")
    check_positive("--dt", args.dt, unit="s")
    if args.phases < 1:
        raise ValueError(f"--phases = {args.phases!r} must be >= 1")
    if args.mass is not None:
        check_positive("--mass", args.mass, unit="kg")
    ball = material(args, "ball", DEFAULT_BALL)
    plate = material(args, "plate", None)
    p = problem_of(ball, plate, args.radius, args.speed, args.dt, mass=args.mass, phases=args.phases,
                   integrator=args.integrator)
    check_x_max(p.law, p.mass, args.speed)
    ref, fits = calibrate(p, tuple(args.form or FORMS))
    if args.json:
        print(to_json({"reference": {k: getattr(ref, k) for k in ("cor_n", "tau", "x_max", "F_max")},
                           "ball": ball.name, "plate": plate.name, "radius": args.radius, "mass": p.ball.mass,
                           "speed": args.speed, "dt": args.dt, "phases": args.phases,
                           "fits": {k: f.to_dict() for k, f in fits.items()}}))
        return 0
    print(f"calibration to MSF: ball {ball.name}, R = {args.radius:g} m, m = {p.ball.mass:.6g} kg, plate "
          f"{plate.name}; V = {args.speed:g} m/s, dt = {args.dt:g} s; engine figures: means over {args.phases} "
          "onset phases")
    print(f"  reference solver: COR = {ref.cor_n:.6g}, tau = {ref.tau:.6g} s")
    for f in fits.values():
        st = f.stats
        if f.form == "mujoco-solref":
            what = (f"solref = \"{f.params['solref'][0]:.6g} {f.params['solref'][1]:.6g}\" solimp = "
                    f"\"{' '.join(f'{x:g}' for x in f.params['solimp'])}\"  (direct form solref = "
                    f"\"{f.equivalent['solref_direct'][0]:.6g} {f.equivalent['solref_direct'][1]:.6g}\")")
        elif f.form == "pybullet-restitution":
            what = f"restitution = {f.params['restitution']:.6g} (pair; sqrt on each body, restitution settings)"
        else:
            what = (f"contactStiffness = {f.params['contact_stiffness']:.6g} N/m, contactDamping = "
                    f"{f.params['contact_damping']:.6g} N s/m (pair values)")
        print(f"  {f.form}: {what}")
        print(f"    engine: COR = {st.cor_n:.6g} ({100 * f.cor_error:+.2f}%, single impacts {st.cor_n_min:.4g}.."
              f"{st.cor_n_max:.4g}), tau = {st.tau:.6g} s ({100 * f.tau_error:+.1f}%)"
              f"{'' if f.cor_ok else '  COR NOT MATCHED'}{'' if f.tau_ok or f.form == 'pybullet-restitution' else '  tau not matched'}")
        if f.note:
            print(f"    note: {f.note}")
    return 0
