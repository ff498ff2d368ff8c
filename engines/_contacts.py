"""Engine-agnostic contact management: per-contact state, sub-cycling, records.

An adapter calls :meth:`ContactManager.step` once per engine step with the
kinematics of its candidate contacts (:class:`engines.base.ContactKinematics`)
and applies the returned step-averaged forces (spec section 6).

Sub-cycling. A contact lasting fewer than ~50 engine steps cannot be resolved
by an explicit force, so every candidate contact is integrated here over the
engine step [t, t + dt] with the inverse effective inertia W at the contact
(frozen over the step):

    x'  = -(v . n)                                   approach rate
    v'  = W f + a_ext,      f = F_n n + F_t           relative contact-point velocity
    s'  = v_t  (contact-point mode)  or  v_com,t  (paper mode; v_com' = W_com f + a_ext)

with F_n = law.contact_normal_force(x, x', onset) and F_t from
law.tangential_force in a tangent basis (t1, t2) of n. Classical RK4 with
an internal step h <= tau_est / (4 STEPS_PER_CONTACT_MIN). The step is split
exactly where the contact begins (x crosses 0 with closing speed; free
motion before it is solved in closed form), at maximum compression (x' = 0,
for tau1, x_max and the split of the works) and where it ends (force-zero:
the separation indicator B < 0 in restitution; or x returns to 0), by
root finding on a partial RK4 step from the substep's start (as accurate as a
full step). After a separation the free relative motion continues for the
rest of the step and a new contact may begin (micro-bounces).

Forces. The engine gets the impulse P = int f dt of the step as the force
P/dt at the contact point; with W and a_ext constant over the step this
reproduces the internal velocity at the end of the step exactly, in any
integrator that holds an applied force constant over the step. A constant
force moves the engine's bodies as if the impulse were centred on mid-step;
the actual impulse is not (a bounce early in a step should move the body
back for the rest of it). Timing correction: an extra impulse
J = int (dt/2 - t) f dt / dt is added in this step and removed in the next
one: zero net velocity change, a position change dt W J that puts the
engine's bodies where the impulse's timing puts them. Without it the
engine's position after an impact depends on where in the step the impact
fell (by up to v dt), gravity turns that into +-% of energy per bounce, and
a settled body rests off its static overlap. The price: for one step after
a contact step the engine's velocities carry W J (``dv_corr``), which the
manager removes from what it reads; a finished contact's record is
completed (body probe, spin_out) once that step is over.

Authority. While a contact lasts, its approach x is advanced here and the
engine's x is not used (with a semi-implicit integrator the engine's
position still leads the internal one by (dt/2) times the velocity change
since onset); only v, n, W, a_ext are read from the engine at each step
start. The tangential displacement s is kept as a world vector in the
contact plane, re-projected onto the current tangent plane each step and
rescaled to its length (DEM practice).

Resting contacts. A contact that lasts longer than SETTLE_AFTER_DURATIONS
estimated durations is a resting (or rolling, or pressed) contact: its
internal x is relaxed toward the engine's by ``settle_rate`` per step, so the
remaining offset (the lead above) vanishes and the engine body rests at the
static overlap.

Settled path. Such a contact whose approach rate is also small
(SETTLED_SPEED_RATIO) is not sub-cycled: the law is applied once per
engine step as backward Euler over the whole step (the force of the law at
the end state x + dt x'+, s + dt s'+, with the Coulomb cap; solved by
Newton for all settled contacts at once, :meth:`ContactManager._settled`).
The engine's semi-implicit Euler then reaches exactly that end state, so the
step is unconditionally stable (steel on steel at 2 ms, omega dt ~ 30),
gains no energy, and rests at the exact balance F_n(x_s, 0) = m a_n. Its
force is constant over the step, so it needs no timing correction. A
contact that is hit (rate above the criterion at the step start or in the
solution) or whose solve fails goes back to sub-cycling in the same step.
Onset speeds below :func:`onset_speed_floor` are raised to it for
the onset constants only (omega_x, Hunt-Crossley chi, ...): a contact that
begins at a vanishing closing speed would otherwise get a vanishing omega_x
and an unbounded damping E''/omega_x.

Islands. With the adapter's coupling blocks (:meth:`ContactManager.set_coupling`)
contacts that share a moving body within a step are integrated together
(:mod:`engines._islands`); a contact alone takes the path described here.

Known limits. W is frozen over a step at the step-start geometry: the
lever arm of a sub-cycled impact is R, not the mid-overlap R - x/2 the
reference solver uses (an O(x_max/R) difference in spin and cor_t, 0.3-1 %
for a PTFE ball at 1 m/s). One contact per pair (smooth convex shapes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from msf_contact import closed_forms as cf
from msf_contact._validate import small_strain_note
from msf_contact.geometry import area
from msf_contact.laws import ForceLaw, HertzLaw, HuntCrossleyLaw, KuwabaraKonoLaw, MSFLaw, SpringDashpotLaw
from msf_contact.record import ImpactRecord

from . import _kernel as K
from .contract import STEPS_PER_CONTACT_MIN, ContactForces, ContactKinematics, PairSpec, as_array

TANGENTIAL_MODES = ("contact-point", "paper")

#: Internal RK4 steps per contact duration: 4 x 50. RK4 converges as h^4
#: (h^1.5 over the first substep, where F ~ t^(1/2) for MSF): at 200 steps
#: per duration the COR error is ~1e-6, far below the 0.02% acceptance.
SUBSTEPS_PER_CONTACT = 4 * STEPS_PER_CONTACT_MIN
#: Internal RK4 steps per half period pi/sqrt(k_t w_t) of the tangential
#: oscillation (stiffness k_t at the Hertz x_max, w_t the largest tangential
#: eigenvalue of W): RK4 error ~ (pi/100)^4 ~ 1e-6 per period.
SUBSTEPS_PER_TANGENTIAL = 100
#: Smallest onset speed used for the onset constants [m/s], with no external
#: acceleration along the normal (with one, the floor is sqrt(2 a_n x_static)).
V_ONSET_MIN = 1e-6
#: A contact older than this many estimated durations is resting/rolling
#: (an impact lasts one); only then is its x relaxed toward the engine's.
SETTLE_AFTER_DURATIONS = 3.0
#: A contact older than SETTLE_AFTER_DURATIONS durations takes the settled path
#: (one implicit force evaluation per engine step instead of sub-cycling) while
#: its approach rate stays below this share of v_x = sqrt(F_el(x) x / m), the
#: speed whose kinetic energy m v^2/2 equals the elastic energy F x/2 of a
#: linear spring at the same force and overlap: at 0.1 the normal motion
#: carries <= 1% of the energy stored in the contact, so the contact is a
#: small perturbation about its equilibrium that the implicit step resolves
#: (a ball resting under gravity: v_x = sqrt(g x_s), 3 mm/s for rubber with
#: x_s = 0.1 mm). A hit (a larger rate at the step start, or in the implicit
#: solution) sends the contact back to sub-cycling.
SETTLED_SPEED_RATIO = 0.1
#: Newton iterations of the settled path's implicit step (the first one is the
#: law linearised at the current state). A resting contact converges in 2-3;
#: a row that has not converged is sub-cycled instead.
SETTLED_NEWTON_MAX = 8
#: Convergence of the settled path: the velocity residual of the implicit
#: step below this share of v_x (the force balance is then exact to
#: m SETTLED_VTOL v_x / dt, ~1e-9 m g for a resting ball).
SETTLED_VTOL = 1e-8
#: Relative step of the forward differences dF_n/dx (x) and dF_n/dx' (v_x) in
#: the settled path's Jacobian. Only Newton's rate depends on it; the
#: converged force is the law's own at the end state.
SETTLED_FD_REL = 1e-7
#: Default share of the engine-internal offset of x removed per step for a
#: resting contact (10%: the offset decays over ~20 steps, slowly against
#: the contact's own oscillation, so it adds no visible dynamics).
SETTLE_RATE = 0.1
#: f = |F_t|/F_n is tracked while F_n >= this share of the running peak F_n
#: (the reference solver uses 1% of the final peak: F_RATIO_FLOOR).
F_RATIO_FLOOR = 0.01
#: Root finding on a substep: iterations and tolerance in substep fractions.
ROOT_ITER = 60
ROOT_TOL = 1e-13
#: Steps a finished contact's record waits for its bodies' post-impact state.
PENDING_MAX_STEPS = 3
#: Guard on the number of onset/separation segments inside one engine step.
MAX_SEGMENTS = 10000

# layout of the internal state vector y (k, NY)
_X, _V, _S, _VC, _P = 0, slice(1, 4), slice(4, 7), slice(7, 10), slice(10, 13)
_WEL, _WVI, _Q, _WT = 13, 14, 15, 16
_PI = slice(17, 20)  # int_0^t P dt' [N s^2]: first moment of the force, for the timing correction
NY = 20


def effective_inverse_inertia_free(m1, I1_world, r1, m2, I2_world, r2) -> np.ndarray:
    """Inverse effective inertia [1/kg] at a contact point between two free rigid bodies.

    W = sum_i [ (1/m_i) Id - [r_i]x I_i^-1 [r_i]x ]: the change of the relative
    contact-point velocity per unit impulse +P on body 1 and -P on body 2.
    m_i [kg] (inf: fixed body, contributes nothing); I_i_world [kg m^2] (3, 3)
    inertia about the centre of mass in world axes (None or inf: no rotation);
    r_i [m] (3,) from the body's centre of mass to the contact point.
    Broadcasts over a leading batch dimension: (n, 3, 3) for (n,) inputs.
    """
    W = np.zeros(np.broadcast_shapes(np.shape(r1), np.shape(r2))[:-1] + (3, 3))
    for name, m, I, r in (("body 1", m1, I1_world, r1), ("body 2", m2, I2_world, r2)):
        m = np.asarray(m, dtype=float)
        if np.any(np.isnan(m)) or np.any(m <= 0):
            raise ValueError(f"{name} mass = {m!r} kg must be > 0 (inf for a fixed body)")
        if np.all(np.isinf(m)):
            continue
        if np.any(np.isinf(m)):
            raise ValueError(f"{name} mass mixes fixed (inf) and free bodies in one batch; call per group")
        inv_m = 1.0 / m
        W = W + inv_m[..., None, None] * np.eye(3)
        if I is None or np.all(np.isinf(np.asarray(I, dtype=float))):
            continue
        r = np.asarray(r, dtype=float)
        rx = _skew(r)
        Iinv = np.linalg.inv(np.asarray(I, dtype=float))
        W = W - rx @ Iinv @ rx
    return W


def _skew(r):
    r = np.asarray(r, dtype=float)
    z = np.zeros(r.shape[:-1])
    return np.stack([np.stack([z, -r[..., 2], r[..., 1]], -1),
                     np.stack([r[..., 2], z, -r[..., 0]], -1),
                     np.stack([-r[..., 1], r[..., 0], z], -1)], -2)


def closing_distance(xdot, xddot, dt: float, safety: float = 2.0) -> np.ndarray:
    """How far a gap can close within one step [m] (n,): safety (x' dt + x'' dt^2/2)
    for closing rate x' [m/s] and acceleration x'' [m/s^2] (both positive closing).
    An adapter lists a pair as a candidate when x > -closing_distance."""
    xd = np.maximum(np.asarray(xdot, dtype=float), 0.0)
    xdd = np.maximum(np.asarray(xddot, dtype=float), 0.0)
    return safety * (xd * dt + 0.5 * xdd * dt * dt)


def onset_speed_floor(law: ForceLaw, m_eff, a_n) -> np.ndarray:
    """Smallest onset speed used for the onset constants [m/s] (n,).

    sqrt(2 a_n x_s): the speed gained falling through the static overlap x_s,
    where the elastic force 2/3 E' psi(0) x_s^(3/2) of (29) balances m a_n
    (a_n: external closing acceleration along the normal); at least
    V_ONSET_MIN. A contact that begins slower is settling under a_n: its
    damping is then that of a contact at this speed, not an unbounded one.
    """
    m = np.asarray(m_eff, dtype=float)
    a = np.maximum(np.asarray(a_n, dtype=float), 0.0)
    K = 2.0 / 3.0 * law.moduli.E * float(law.psi(np.zeros(1))[0])
    x_s = (m * a / K) ** (2.0 / 3.0)
    return np.maximum(np.sqrt(2.0 * a * x_s), V_ONSET_MIN)


def _duration_estimate(law: ForceLaw, onset: dict, m, v) -> np.ndarray:
    """Contact duration estimate [s] (n,) that sets the internal step.

    MSF with omega_x from the collision itself (self-consistent, paper):
    pi/omega_x (87). A linear spring (onset "k"): pi sqrt(m/k). Otherwise
    the elastic Hertz duration with the law's elastic stiffness at x -> 0
    (2/3 E' psi(0) of (29)); damping changes it by well under the factor 4
    of margin in SUBSTEPS_PER_CONTACT.
    """
    if "omega_x" in onset and isinstance(getattr(law, "omega", None), str):
        return math.pi / np.asarray(onset["omega_x"], dtype=float)
    if "k" in onset:
        return math.pi * np.sqrt(np.asarray(m, dtype=float) / np.asarray(onset["k"], dtype=float))
    g = law.geom
    k_p = float(law.psi(np.zeros(1))[0]) / (math.sqrt(g.R_a) + math.sqrt(g.R_b))
    return cf.hertz_tau(np.asarray(m, dtype=float), np.asarray(v, dtype=float), law.moduli.E, g.R, k_p)


def _tangent_basis(n):
    """Orthonormal t1, t2 (k, 3) with t1 x t2 = n."""
    e = np.where((np.abs(n[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    t1 = e - np.einsum("ij,ij->i", e, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    return t1, np.cross(n, t1)


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


def _msf_inline(law: ForceLaw) -> bool:
    """True when the law's normal and tangential forces are MSFLaw's own, so
    :meth:`_Batch.rhs` may evaluate them inline (one k_p and one sqrt(x) for
    F_n, its elastic part and the shear lengths, instead of six k_p calls)."""
    t = type(law)
    return (t.normal_force is MSFLaw.normal_force and t.shear_lengths is MSFLaw.shear_lengths
            and t.tangential_stiffness is MSFLaw.tangential_stiffness and t.psi is ForceLaw.psi
            and t.kp is ForceLaw.kp and t.contact_normal_force is ForceLaw.contact_normal_force)


@dataclass
class _Batch:
    """Constants of k contact rows of one law over one engine step."""

    law: ForceLaw
    n: np.ndarray  # (k, 3)
    t1: np.ndarray  # (k, 3)
    t2: np.ndarray  # (k, 3)
    W: np.ndarray  # (k, 3, 3)
    Wc: np.ndarray  # (k, 3, 3)
    a: np.ndarray  # (k, 3)
    paper: np.ndarray  # (k,) bool
    onset: dict = field(default_factory=dict)  # key -> (k,)

    def __post_init__(self):
        self.T = np.stack([self.t1, self.t2], axis=1)  # tangent basis (k, 2, 3)
        self.any_paper = bool(np.any(self.paper))
        self.inline = _msf_inline(self.law)

    @property
    def plain_tangential(self) -> bool:
        """The law uses ForceLaw.tangential_force unchanged (so it may be inlined)."""
        return type(self.law).tangential_force is ForceLaw.tangential_force

    def sub(self, idx) -> "_Batch":
        return _Batch(self.law, self.n[idx], self.t1[idx], self.t2[idx], self.W[idx], self.Wc[idx],
                      self.a[idx], self.paper[idx], {k: v[idx] for k, v in self.onset.items()})

    def _forces(self, x, xd):
        """F_n after the separation rule, its elastic part F_n(x, 0) (k,) [N],
        and the tangential stiffness and damping (k, 2) of the law."""
        law, o = self.law, self.onset
        if self.inline:
            # MSFLaw.normal_force, .shear_lengths, .tangential_stiffness with shared k_p and sqrt(x)
            g = law.geom
            kpa = law.kp(x, g.R_a)
            kpb = kpa if g.R_b == g.R_a else law.kp(x, g.R_b)
            base = (kpa * math.sqrt(g.R_a) + kpb * math.sqrt(g.R_b)) * np.sqrt(x)
            el = (2.0 / 3.0) * o["E"] * x
            F = base * (2.0 * o["eta_E"] * xd + el)
            Fn = np.maximum(F, 0.0) if law.separation == "force-zero" else F
            Fc = base * el
            P_bx = g.k_ha * x + 2.0 * kpb * np.sqrt(g.R_b * x)
            P_ax = g.k_hb * x + 2.0 * kpa * np.sqrt(g.R_a * x)
            G = o["G"]
            k = np.stack([G * P_bx, G * P_ax], axis=-1)
            b = np.stack([o["eta_Gy"] * P_bx, o["eta_Gz"] * P_ax], axis=-1)
            return Fn, Fc, k, b
        Fn = law.contact_normal_force(x, xd, o)
        Fc = law.normal_force(x, np.zeros_like(xd), o)
        k, b = law.tangential_stiffness(x, o)
        return Fn, Fc, k, b

    def rhs(self, y):
        """dy/dt (k, NY), F_n (k,), |F_t| (k,)."""
        law, n = self.law, self.n
        x = np.maximum(y[:, _X], 0.0)
        v, vc = y[:, _V], y[:, _VC]
        xd = -_dot(v, n)
        Fn, Fc, k, b = self._forces(x, xd)
        vt = v + xd[:, None] * n
        sd = np.where(self.paper[:, None], vc - _dot(vc, n)[:, None] * n, vt) if self.any_paper else vt
        s2 = np.einsum("kij,kj->ki", self.T, y[:, _S])
        sd2 = np.einsum("kij,kj->ki", self.T, sd)
        if self.plain_tangential:
            # ForceLaw.tangential_force inlined: one stiffness evaluation gives F_t and the power b s'^2
            Ft2 = -(b * sd2 + k * s2)
            if law.mu is not None:
                cap = law.mu * np.maximum(Fn, 0.0)
                mag = np.hypot(Ft2[:, 0], Ft2[:, 1])
                Ft2 = Ft2 * np.where(mag > cap, cap / np.where(mag > 0, mag, 1.0), 1.0)[:, None]
        else:
            Ft2, _ = law.tangential_force(x, s2, sd2, self.onset, Fn)
        Ft = np.einsum("ki,kij->kj", Ft2, self.T)
        f = Fn[:, None] * n + Ft
        dy = np.empty_like(y)
        dy[:, _X] = xd
        dy[:, _V] = np.einsum("kij,kj->ki", self.W, f) + self.a
        dy[:, _S] = sd
        dy[:, _VC] = np.einsum("kij,kj->ki", self.Wc, f) + self.a
        dy[:, _P] = f
        dy[:, _WEL] = Fc * xd
        dy[:, _WVI] = (Fn - Fc) * xd
        dy[:, _Q] = np.einsum("ki,ki->k", b * sd2, sd2)
        dy[:, _WT] = -_dot(Ft, vt)
        dy[:, _PI] = y[:, _P]
        return dy, Fn, np.hypot(Ft2[:, 0], Ft2[:, 1])

    def rk4(self, y, h):
        """One RK4 step of lengths h (k,). Returns (y_new, F_n at y, |F_t| at y)."""
        hh = h[:, None]
        hh2 = 0.5 * hh
        k1, Fn, Ft = self.rhs(y)
        k2, _, _ = self.rhs(y + hh2 * k1)
        k3, _, _ = self.rhs(y + hh2 * k2)
        k4, _, _ = self.rhs(y + hh * k3)
        return y + hh / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4), Fn, Ft

    def xdot(self, y):
        return -_dot(y[:, _V], self.n)

    def indicator(self, y):
        x = np.maximum(y[:, _X], 0.0)
        return self.law.separation_indicator(x, self.xdot(y), self.onset)


def _find_root(g, lo, hi, g_lo, g_hi):
    """Vectorised Illinois regula falsi on [lo, hi] (k,) with g(lo) > 0 >= g(hi).
    g(theta (k,)) -> (k,). Returns theta (k,).

    A row is done when its bracket is narrower than ROOT_TOL, or when hi is
    the root to rounding: g(hi) == 0, or the secant step lands on hi (the
    linear model puts the root within an ulp of hi). Without the last two
    tests a row whose g(hi) is exactly 0 (the usual end of an overlap-zero
    contact) stalls the secant and falls back to ~30 bisections for nothing."""
    lo, hi, g_lo, g_hi = lo.copy(), hi.copy(), g_lo.copy(), g_hi.copy()
    side = np.zeros(lo.shape, int)
    done = (hi - lo <= ROOT_TOL) | (g_hi == 0)
    for _ in range(ROOT_ITER):
        if np.all(done):
            break
        den = g_lo - g_hi
        th = np.where(den > 0, lo + g_lo * (hi - lo) / np.where(den > 0, den, 1.0), 0.5 * (lo + hi))
        done |= (den > 0) & (th >= hi)
        if np.all(done):
            break
        # fall back to bisection when the secant stalls at an end
        stalled = (th <= lo) | (th >= hi)
        th = np.where(stalled, 0.5 * (lo + hi), th)
        gt = g(th)
        pos = gt > 0
        live = ~done
        # Illinois: halve the value at the end that stays
        g_hi = np.where(live & pos & (side == 1), 0.5 * g_hi, g_hi)
        g_lo = np.where(live & ~pos & (side == -1), 0.5 * g_lo, g_lo)
        lo, g_lo = np.where(live & pos, th, lo), np.where(live & pos, gt, g_lo)
        hi, g_hi = np.where(live & ~pos, th, hi), np.where(live & ~pos, gt, g_hi)
        side = np.where(live, np.where(pos, 1, -1), side)
        done |= (hi - lo <= ROOT_TOL) | (g_hi == 0)
    return hi


#: The tuning constants above, in the order of engines._kernel's C_* indices.
_KCST = np.array([SETTLED_SPEED_RATIO, SETTLED_NEWTON_MAX, SETTLED_VTOL, SETTLED_FD_REL, F_RATIO_FLOOR, ROOT_ITER,
                  ROOT_TOL, SETTLE_AFTER_DURATIONS], dtype=float)
_KP_MODES = {"msf": K.KP_MSF, "msf-small": K.KP_SMALL, "hertz": K.KP_HERTZ}
_KERNEL_CODES = {MSFLaw: K.CODE_MSF, HertzLaw: K.CODE_HERTZ, KuwabaraKonoLaw: K.CODE_KK,
                 HuntCrossleyLaw: K.CODE_HC, SpringDashpotLaw: K.CODE_SD}
#: The methods whose registry versions the kernel compiles: a subclass that
#: overrides any of them runs on the numpy path.
_KERNEL_METHODS = ("normal_force", "separation_indicator", "tangential_stiffness", "tangential_force",
                   "contact_normal_force", "kp", "psi", "shear_lengths", "outside")


def kernel_law(law: ForceLaw):
    """(code, constants (NLC,)) of the compiled kernel for this law, or None
    when the kernel does not know it (a class outside the registry, or a
    registry class with a force method overridden): that law runs on the
    numpy path."""
    base = next((c for c in _KERNEL_CODES if isinstance(law, c)), None)
    if base is None:
        return None
    t = type(law)
    if any(getattr(t, m, None) is not getattr(base, m, None) for m in _KERNEL_METHODS):
        return None
    if law.kp_mode not in _KP_MODES:
        return None
    g = law.geom
    lc = np.zeros(K.NLC)
    lc[K.LC_RA], lc[K.LC_RB], lc[K.LC_KHA], lc[K.LC_KHB] = g.R_a, g.R_b, g.k_ha, g.k_hb
    lc[K.LC_MU] = math.nan if law.mu is None else float(law.mu)
    lc[K.LC_K] = float(getattr(law, "K", 0.0))
    lc[K.LC_A] = float(getattr(law, "A", 0.0))
    lc[K.LC_GM], lc[K.LC_RM] = law.moduli.G, g.R
    lc[K.LC_FZ] = 1.0 if law.separation == "force-zero" else 0.0
    lc[K.LC_KPMODE] = _KP_MODES[law.kp_mode]
    lc[K.LC_SRA], lc[K.LC_SRB] = math.sqrt(g.R_a), math.sqrt(g.R_b)
    return _KERNEL_CODES[base], lc


class _Rows:
    """The rows' normals, inverse inertias and external accelerations for
    :meth:`ContactManager._begin` on the compiled path (the part of _Batch it reads)."""

    def __init__(self, n, W, a):
        self.n, self.W, self.a = n, W, a
        self.onset: dict = {}


class ContactManager:
    """Per-contact state, sub-cycled integration and impact records for the
    pairs of one adapter (see the module docstring).

    pairs: the adapter's PairSpecs (one contact per pair: smooth convex
    shapes touch at one point). dt: the engine step [s]. engine: name written
    into the records. settle_rate: share of the engine-internal offset of x
    removed per step in a resting contact (0 disables). settled_path: take the
    settled path for long, slow contacts (False: sub-cycle every contact, the
    plain implementation the settled path is tested against). compiled: run
    the groups whose law the compiled kernel knows (:func:`kernel_law`) in
    :mod:`engines._kernel` (False: the numpy path for every group, the
    implementation the kernel is tested against).

    Adapter hooks (optional, :meth:`set_body_probe`): a function
    ``probe(pair_index) -> dict`` returning body-level quantities, read at
    onset and when a finished contact's record is completed (at the next
    :meth:`step`, or when ``records``/``pop_records`` are read, i.e. after
    the engine applied the contact's last impulse). Key ``"omega1"``: body
    1's angular velocity in world axes [rad/s] (3,), gives spin_in/spin_out
    about n x t (t the incident tangential direction; rolling in the
    direction of incidence is positive, as in the reference solver); other
    keys are stored in ``record.inputs["body_in"]`` / ``["body_out"]``.
    """

    def __init__(self, pairs: list[PairSpec], dt: float, engine: str, *, settle_rate: float = SETTLE_RATE,
                 timing_correction: bool = True, settled_path: bool = True, compiled: bool = True):
        if not pairs:
            raise ValueError("pairs is empty: give at least one PairSpec")
        dt = float(dt)
        if not math.isfinite(dt) or dt <= 0:
            raise ValueError(f"dt = {dt!r} s must be finite and > 0")
        #: keep each contact's step-averaged normal force per engine step and put it
        #: in its record (inputs["curves"]); for isolated impacts, off for jets
        self.history = False
        self._hist: dict[int, list[tuple[float, float]]] = {}
        if not 0.0 <= settle_rate <= 1.0:
            raise ValueError(f"settle_rate = {settle_rate!r} must be in [0, 1]")
        for i, p in enumerate(pairs):
            if not isinstance(p.law, ForceLaw):
                raise ValueError(f"pairs[{i}].law = {p.law!r} is not a msf_contact ForceLaw")
            if p.tangential not in TANGENTIAL_MODES:
                raise ValueError(f"pairs[{i}].tangential = {p.tangential!r} is not one of {TANGENTIAL_MODES}")
        self.pairs = list(pairs)
        self.dt = dt
        self.engine = str(engine)
        self.settle_rate = float(settle_rate)
        self.timing_correction = bool(timing_correction)
        self.settled_path = bool(settled_path)
        P = len(pairs)
        self._paper = np.array([p.tangential == "paper" for p in pairs])
        # group pairs by law object (vectorised per law)
        self._groups: dict[int, ForceLaw] = {}
        self._group_of = np.empty(P, int)
        self._pos = np.empty(P, int)  # position of a pair inside its group's onset arrays
        sizes: dict[int, int] = {}
        for i, p in enumerate(pairs):
            g = id(p.law)
            self._groups.setdefault(g, p.law)
            self._group_of[i] = g
            self._pos[i] = sizes.get(g, 0)
            sizes[g] = self._pos[i] + 1
        self._group_size = sizes
        self._onset: dict[int, dict[str, np.ndarray]] = {g: {} for g in self._groups}
        #: per law group: (code, constants) of the compiled kernel, or None (numpy path)
        self.compiled = bool(compiled)
        self._kernel_law = {g: (kernel_law(law) if self.compiled else None) for g, law in self._groups.items()}
        # the kernel's laws: pair -> index into _kcodes/_kLC (-1: numpy path); all of them in one kernel call
        kgs = [g for g in self._groups if self._kernel_law[g] is not None]
        self._kcodes = np.array([self._kernel_law[g][0] for g in kgs], dtype=np.int64)
        self._kLC = np.array([self._kernel_law[g][1] for g in kgs], dtype=float).reshape(len(kgs), K.NLC)
        kidx = {g: j for j, g in enumerate(kgs)}
        self._kg_of_pair = np.array([kidx.get(g, -1) for g in self._group_of], dtype=np.int64)
        self._all_kernel = bool(np.all(self._kg_of_pair >= 0))
        self._coupling: tuple[np.ndarray, Callable] | None = None  # set_coupling
        self._probe: Callable[[int], dict] | None = None
        self._probe_batch: Callable[[], Callable[[int], dict]] | None = None
        self._init_state(P)
        self.records: list[ImpactRecord] = []
        self._pending: list[list] = []  # [pair, record, spin axis, steps waited]
        self.last_step_info: dict[str, Any] = {}

    # ------------------------------------------------------------ state --
    def _init_state(self, P):
        z, z3 = np.zeros(P), np.zeros((P, 3))
        # the per-pair record bookkeeping lives in one (NF, P) array (the compiled
        # kernel updates it in place); the attributes below are its rows
        self._fl = np.zeros((K.NF, P))
        fl = self._fl
        self.active = np.zeros(P, bool)  #: in contact (P,)
        self.x = z.copy()  #: internal approach [m] (P,)
        self.xdot = z.copy()  #: approach rate at the end of the last step [m/s] (P,)
        self.s = z3.copy()  #: tangential displacement, world, in the contact plane [m] (P, 3)
        self.phase = np.zeros(P, np.int8)  #: 0 compression (x' > 0), 1 restitution
        self.turned = np.zeros(P, bool)  #: maximum compression passed at least once
        self.t_onset = fl[K.F_TONSET]  #: onset time [s]
        self.v_n_in = z.copy()  #: closing speed at onset [m/s]
        self.v_n_used = z.copy()  #: onset speed given to law.onset (>= floor) [m/s]
        self.m_eff = z.copy()  #: 1/(n W n) at onset [kg]
        self.tau_est = z.copy()  #: estimated duration of the normal impact [s]
        self.h = fl[K.F_H]  #: internal step [s]
        self.n_in = z3.copy()  #: normal at onset (P, 3)
        self.p_in = z3.copy()  #: contact point at the start of the onset step [m] (P, 3)
        self._point = z3.copy()  #: contact points of the current step's rows [m] (P, 3)
        self.u_in = z3.copy()  #: contact-point tangential velocity at onset [m/s] (P, 3)
        self.vc_in = z3.copy()  #: centre-of-mass relative tangential velocity at onset [m/s] (P, 3)
        self.vc = z3.copy()  #: centre-of-mass relative velocity at the end of the last step [m/s] (P, 3)
        self.x_max = fl[K.F_XMAX]  #: maximum approach so far [m]
        self.x_turn = fl[K.F_XTURN]  #: approach at the first maximum compression [m]
        self.tau1 = fl[K.F_TAU1]  #: compression time [s]
        self.F_max = fl[K.F_FMAX]  #: peak normal force [N]
        self.x_at_F = fl[K.F_XATF]  #: approach at the peak force [m]
        self.f_min = fl[K.F_FMIN]  #: min |F_t|/F_n [-]
        self.f_min[:] = np.inf
        self.f_max = fl[K.F_FMAXR]  #: max |F_t|/F_n [-]
        self.W_el = z.copy()  #: work of the elastic normal force so far [J]
        self.W_visc = z.copy()  #: work of the viscous normal force so far [J]
        self.W_el_comp = fl[K.F_WELC]
        self.W_visc_comp = fl[K.F_WVIC]
        self.Q_t = z.copy()  #: tangential viscous work (80) [J]
        self.W_t = z.copy()  #: work done against the tangential force [J]
        self.outside = np.zeros(P, bool)
        self.settled = np.zeros(P, bool)  #: took the settled path in the last step (P,)
        #: solved in an island of several contacts in the last step (P,): the adapters keep such a
        #: pair's force out of the held forces of a_ext (the island couples it explicitly)
        self.in_island = np.zeros(P, bool)
        self._held_force = np.zeros((P, 3))  #: the step-averaged forces held into the next step [N] (P, 3)
        self.J = z3.copy()  #: timing-correction impulse applied in the last step, removed in the next [N s] (P, 3)
        self.dv_corr = z3.copy()  #: W J: the engine's contact-point velocity offset it causes [m/s] (P, 3)
        self.dvc_corr = z3.copy()  #: W_com J [m/s] (P, 3)
        self.body_in: list[dict | None] = [None] * P
        self._oc = np.full((P, K.NOC), np.nan)  #: onset constants per pair for the compiled kernel
        # the kernel's scratch (it allocates nothing itself)
        self._seen = np.zeros(P, bool)
        self._scr_settled = (np.empty(6), np.empty((4, 3, 3)), np.empty((8, 3)), np.empty((3, 4)))
        self._scr_rk4 = (np.empty(6), np.empty((5, NY)), np.empty((4, NY)))
        self._params: dict[int, dict] = {}  # law.parameters() per group, copied into each record

    @property
    def active_count(self) -> int:
        return int(np.count_nonzero(self.active))

    @property
    def active_pairs(self) -> np.ndarray:
        """Pair indices in contact."""
        return np.flatnonzero(self.active)

    @property
    def required_pairs(self) -> np.ndarray:
        """Pair indices an adapter must list as candidates in the next step,
        whatever their gap: those in contact and those with a timing
        correction to remove."""
        return K.required(self.active, self.J)

    def set_body_probe(self, probe: Callable[[int], dict] | None,
                       batch: Callable[[], Callable[[int], dict]] | None = None) -> None:
        """Install the adapter's body-level probe (see the class docstring).
        batch: optional; returns a probe valid for one batch of calls made
        between engine steps (records completed when they are read), so the
        adapter brings the engine's derived quantities up to date once per
        batch instead of once per record."""
        if probe is not None and not callable(probe):
            raise ValueError(f"probe = {probe!r} must be callable or None")
        if batch is not None and not callable(batch):
            raise ValueError(f"batch = {batch!r} must be callable or None")
        self._probe = probe
        self._probe_batch = batch

    def state(self, pair_index: int) -> dict | None:
        """Current state of the pair's contact, or None when not in contact."""
        p = int(pair_index)
        if not 0 <= p < len(self.pairs):
            raise ValueError(f"pair_index = {pair_index!r} is outside [0, {len(self.pairs) - 1}]")
        if not self.active[p]:
            return None
        g = self._group_of[p]
        onset = {k: float(v[self._pos[p]]) for k, v in self._onset[g].items()}
        return {
            "x": float(self.x[p]), "xdot": float(self.xdot[p]), "s": self.s[p].copy(),
            "phase": "restitution" if self.phase[p] else "compression",
            "x_max": float(self.x_max[p]), "F_max": float(self.F_max[p]), "t_onset": float(self.t_onset[p]),
            "v_n_in": float(self.v_n_in[p]), "v_n_used": float(self.v_n_used[p]),
            "v_t_in": float(np.linalg.norm(self.u_in[p])), "m_eff": float(self.m_eff[p]),
            "omega_x": onset.get("omega_x"), "omega_y": onset.get("omega_y"), "onset": onset,
            "tau_est": float(self.tau_est[p]), "h": float(self.h[p]),
            "W_el": float(self.W_el[p]), "W_visc": float(self.W_visc[p]), "Q_t": float(self.Q_t[p]),
        }

    def pop_records(self) -> list[ImpactRecord]:
        """Completed impacts since the last call, and forget them (see ``pending_count``)."""
        self._finish_pending()
        out, self.records = self.records, []
        return out

    @property
    def pending_count(self) -> int:
        """Finished contacts whose record waits for the body-level probe: with a
        probe installed, a record is completed at the start of the second step
        after the contact ended, once the timing correction has left the
        engine's velocities (``spin_out`` is then the physical spin)."""
        return len(self._pending)

    # ------------------------------------------------------------- step --
    def step(self, kin: ContactKinematics) -> ContactForces:
        """Integrate the candidate contacts over one engine step; return the
        step-averaged forces on body 1 at the contact points."""
        self._finish_pending(at_step_start=True)
        pair = np.asarray(kin.pair, dtype=int).reshape(-1)
        k = pair.shape[0]
        x = as_array(kin.x, ()).reshape(-1)
        n = as_array(kin.normal, (3,))
        point = as_array(kin.point, (3,))
        v = as_array(kin.v_rel, (3,))
        vc = as_array(kin.v_com_rel, (3,))
        W = as_array(kin.W, (3, 3))
        Wc = as_array(kin.W_com, (3, 3))
        a = as_array(kin.a_ext, (3,))
        for name, arr in (("x", x), ("normal", n), ("point", point), ("v_rel", v), ("v_com_rel", vc),
                          ("W", W), ("W_com", Wc), ("a_ext", a)):
            if arr.shape[0] != k:
                raise ValueError(f"kinematics.{name} has {arr.shape[0]} rows; expected {k} (len(pair))")
        n_unit = np.empty((k, 3))  # the normals renormalised (they are unit to 1e-6)
        code, row = K.check(pair, len(self.pairs), x, n, point, v, vc, W, Wc, a, self.active, self.J, self._seen,
                            n_unit, self._point)
        if code:
            self._invalid(code, row, pair, x, n, point, v, vc, W, Wc, a)
        n = n_unit
        t0 = float(kin.t)
        info = {"rows": k, "substeps": 0, "segments": 0, "onsets": 0, "ends": 0, "settled": 0,
                "settled_iterations": 0, "island_rows": 0}
        self.in_island[:] = False
        multi = self._island_rows(pair, t0, n, v, W) if self._coupling is not None and k > 1 else None
        if multi is not None:
            out = self._step_with_islands(multi, pair, x, n, point, v, vc, W, Wc, a, t0, info)
        else:
            out = self._step_rows(pair, x, n, point, v, vc, W, Wc, a, t0, info)
        if self._coupling is not None:  # the forces the adapters hold into the next step's a_ext
            self._held_force[:] = 0.0
            held = self.held(pair, t0 + self.dt)
            self._held_force[pair[held]] = out.force[held]
        return out

    def held(self, pair, t_next: float) -> np.ndarray:
        """Which of the pairs ``pair`` (k,) hold their force into the next step
        (starting at ``t_next``), for the adapters' a_ext: in contact at the end
        of this step, not in an island (whose forces are coupled explicitly),
        and either resting (older than SETTLE_AFTER_DURATIONS estimated
        durations, or on the settled path) or resolved by the engine step (an
        estimated duration of at least STEPS_PER_CONTACT_MIN steps). Their
        step-averaged force is the prediction of their force over the next
        step, so it stays in the other pairs' a_ext; an impact shorter than
        that (the whole contact, or most of it, inside a step) has already
        given its impulse and is left out."""
        act = self.active[pair] & ~self.in_island[pair]
        resting = (t_next - self.t_onset[pair]) > SETTLE_AFTER_DURATIONS * self.tau_est[pair]
        resolved = self.tau_est[pair] >= STEPS_PER_CONTACT_MIN * self.dt
        return act & (self.settled[pair] | resting | resolved)

    def _step_rows(self, pair, x, n, point, v, vc, W, Wc, a, t0, info) -> ContactForces:
        """Each row on its own (the compiled kernel or the numpy path per law)."""
        k = pair.shape[0]
        if self._all_kernel:
            force = self._step_compiled(pair, x, n, v, vc, W, Wc, a, t0, info)
            force /= self.dt
        else:
            force = np.zeros((k, 3))
            krows = np.flatnonzero(self._kg_of_pair[pair] >= 0)
            if krows.size:
                P = self._step_compiled(pair[krows], x[krows], n[krows], v[krows], vc[krows], W[krows], Wc[krows],
                                        a[krows], t0, info)
                force[krows] = P / self.dt
            for g, law in self._groups.items():
                if self._kernel_law[g] is not None:
                    continue
                rows = np.flatnonzero(self._group_of[pair] == g)
                if rows.size == 0:
                    continue
                P = self._step_group(g, law, pair[rows], x[rows], n[rows], v[rows], vc[rows], W[rows], Wc[rows],
                                     a[rows], t0, info)
                force[rows] = P / self.dt
        self.last_step_info = info
        return ContactForces(force=force, point=point.copy(), pair=pair.copy())

    # ------------------------------------------------------------ islands --
    def set_coupling(self, keys, blocks: Callable | None) -> None:
        """Solve contacts that share a moving body together (engines._islands).

        keys: (P, 2) int, a key per body of each pair (-1: fixed; the links of
        one articulated tree share their root's key). blocks(pp, pq) -> (W
        (b, 3, 3), Wc (b, 3, 3)): the cross inverse inertias J_p M^-1 J_q^T and
        J_c,p M^-1 J_q^T [1/kg] between the current step's contact points of
        the pairs pp (b,) and pq (b,) (p != q), called from inside ``step``.
        None switches it off (each contact on its own, the others through a_ext)."""
        if blocks is None:
            self._coupling = None
            return
        keys = np.asarray(keys, dtype=np.int64)
        if keys.shape != (len(self.pairs), 2):
            raise ValueError(f"keys has shape {keys.shape}; expected ({len(self.pairs)}, 2)")
        if not callable(blocks):
            raise ValueError(f"blocks = {blocks!r} must be callable or None")
        self._coupling = (keys, blocks)

    def _island_rows(self, pair, t0, n, v, W):
        """Island label per row for the rows in islands of two or more (others -1), or None."""
        from ._islands import islands

        keys = self._coupling[0][pair]
        kk = keys[keys >= 0]
        if kk.size < 2 or not np.any(np.bincount(kk) > 1):
            return None
        act = self.active[pair]
        age_ok = self._resting(pair, t0, n, v, W)
        lab = islands(pair, act, age_ok, keys)
        counts = np.bincount(lab, minlength=pair.size)
        multi = np.where(counts[lab] > 1, lab, -1)
        self._rest_rows = age_ok
        return multi if np.any(multi >= 0) else None

    def _resting(self, pair, t0, n, v, W):
        """(k,) rows in a resting contact: older than SETTLE_AFTER_DURATIONS
        estimated durations and approaching slower than SETTLED_SPEED_RATIO v_x
        (the settled path's criterion); a resting contact that is hit is not."""
        act = self.active[pair]
        rest = act & ((t0 - self.t_onset[pair]) > SETTLE_AFTER_DURATIONS * self.tau_est[pair])
        if np.any(rest):
            r = np.flatnonzero(rest)
            vn = np.abs(_dot(v[r] - self.dv_corr[pair[r]], n[r]))
            xr = np.maximum(self.x[pair[r]], 0.0)
            nWn = np.einsum("ki,kij,kj->k", n[r], W[r], n[r])
            F = np.zeros(r.size)
            for g in np.unique(self._group_of[pair[r]]):
                sel = self._group_of[pair[r]] == g
                o = {key: arr[self._pos[pair[r][sel]]] for key, arr in self._onset[g].items()}
                F[sel] = self._groups[g].contact_normal_force(xr[sel], np.zeros(int(sel.sum())), o)
            vx = np.sqrt(np.maximum(F, 0.0) * xr * nWn)
            rest[r] = vn <= SETTLED_SPEED_RATIO * vx
        return rest

    def _step_with_islands(self, multi, pair, x, n, point, v, vc, W, Wc, a, t0, info) -> ContactForces:
        from ._islands import step_island

        k = pair.shape[0]
        force = np.zeros((k, 3))
        alone = np.flatnonzero(multi < 0)
        if alone.size:
            out = self._step_rows(pair[alone], x[alone], n[alone], point[alone], v[alone], vc[alone], W[alone],
                                  Wc[alone], a[alone], t0, info)
            force[alone] = out.force
        keys_all, blocks = self._coupling
        for lab in np.unique(multi[multi >= 0]):
            r = np.flatnonzero(multi == lab)
            pp = pair[r]
            keys = keys_all[pp]
            # the row pairs of the island that share a moving body
            cp, cq = [], []
            for i in range(r.size):
                for j in range(r.size):
                    if i != j and np.any((keys[i][:, None] == keys[j][None, :]) & (keys[i][:, None] >= 0)):
                        cp.append(i)
                        cq.append(j)
            cp, cq = np.array(cp, dtype=np.int64), np.array(cq, dtype=np.int64)
            Wpq, Wcpq = blocks(pp[cp], pp[cq])
            Wpq = as_array(Wpq, (3, 3))
            Wcpq = as_array(Wcpq, (3, 3))
            # a neighbour's force held last step is in this row's a_ext as its prediction; the island
            # now couples that neighbour explicitly, so take the prediction out (no double count)
            a_r = a[r].copy()
            Fh = self._held_force[pp[cq]]
            if np.any(Fh):
                np.add.at(a_r, cp, -np.einsum("bij,bj->bi", Wpq, Fh))
            info["island_rows"] += int(r.size)
            self.in_island[pp] = True
            P = step_island(self, pp, x[r], n[r], v[r], vc[r], W[r], Wc[r], a_r, t0, info, cp, cq, Wpq, Wcpq,
                            self._rest_rows[r])
            force[r] = P / self.dt
        self.last_step_info = info
        return ContactForces(force=force, point=point.copy(), pair=pair.copy())

    def _invalid(self, code, row, pair, x, n, point, v, vc, W, Wc, a):
        """Raise the ValueError for what :func:`engines._kernel.check` found."""
        if code == 1:
            raise ValueError(f"kinematics.pair = {pair!r} has indices outside [0, {len(self.pairs) - 1}]")
        if code == 2:
            raise ValueError(f"kinematics.pair = {pair!r} lists a pair twice (one contact per pair)")
        if code == 3:
            for name, arr in (("x", x), ("normal", n), ("point", point), ("v_rel", v), ("v_com_rel", vc),
                              ("W", W), ("W_com", Wc), ("a_ext", a)):
                if not np.all(np.isfinite(arr[row])):
                    raise ValueError(f"kinematics.{name} is not finite: {arr!r}")
        if code == 4:
            raise ValueError(f"kinematics.normal must be unit vectors, norms {np.linalg.norm(n, axis=1)!r}")
        if code == 5:
            missing = np.flatnonzero((self.active | np.any(self.J != 0.0, axis=1)) & ~np.isin(
                np.arange(len(self.pairs)), pair))
            raise ValueError(f"kinematics.pair = {pair!r} lacks pairs {missing!r} that are in contact or have a "
                             "timing correction to remove: list manager.required_pairs every step")
        raise RuntimeError(f"engines._kernel.check returned an unknown code {code!r}")

    # ---------------------------------------------------- one law group --
    def _step_compiled(self, p, x_eng, n, v, vc, W, Wc, a, t0, info):
        """_step_group for the rows of every law the kernel knows, in one
        call of the compiled kernel (engines._kernel); law.onset and the
        records stay here, called for the rows the kernel stops at."""
        kg, codes, LC = self._kg_of_pair[p], self._kcodes, self._kLC
        dt = self.dt
        k = p.shape[0]
        paper = self._paper[p]
        y = np.empty((k, NY))
        T = np.empty((k, 2, 3))
        t_loc = np.empty(k)
        in_c = np.empty(k, bool)
        settled = np.empty(k, bool)
        status = np.empty(k, np.int8)
        ended_by = np.zeros(k, np.int8)
        ints = np.zeros(4, np.int64)
        fl, oc = self._fl, self._oc
        K.prelude(_KCST, p, x_eng, n, v, vc, W, Wc, a, paper, t0, dt, self.settle_rate, self.settled_path, kg, codes,
                  LC, oc, self.active, self.x, self.s, self.tau_est, self.dv_corr, self.dvc_corr, self.W_el,
                  self.W_visc, self.Q_t, self.W_t, y, T, t_loc, in_c, settled, status, self.turned, fl, ints,
                  *self._scr_settled)
        for _ in range(MAX_SEGMENTS):
            info["segments"] += 1
            stopped = K.advance(_KCST, p, n, T, W, Wc, a, paper, kg, codes, LC, oc, t0, dt, self.h, y, t_loc, in_c,
                                status, ended_by, self.turned, fl, ints, *self._scr_rk4)
            if not stopped:
                break
            for r in np.flatnonzero(status == K.ST_ENDED):
                self._end(int(p[r]), y[r], float(t0 + t_loc[r]),
                          "force-zero" if ended_by[r] == K.END_FORCE else "overlap-zero", n[r])
                in_c[r] = False
            new_all = np.flatnonzero(status == K.ST_ONSET)
            if new_all.size:
                grp = self._group_of[p[new_all]]
                rows = _Rows(n, W, a)
                for g in (grp[:1] if np.all(grp == grp[0]) else np.unique(grp)):
                    new = new_all[grp == g]
                    self._begin(g, self._groups[g], p, new, y, rows, t0 + t_loc[new])
                    store, pp = self._onset[g], p[new]
                    for j, key in enumerate(K.ONSET_KEYS[self._kernel_law[g][0]]):
                        oc[pp, j] = store[key][self._pos[pp]]
                in_c[new_all] = True
                info["onsets"] += int(new_all.size)
        else:
            raise RuntimeError(f"more than {MAX_SEGMENTS} contact onsets/separations in one step of {dt!r} s")
        impulse = np.empty((k, 3))
        K.finale(p, n, W, Wc, settled, in_c, y, dt, self.timing_correction, kg, LC, self.active, self.x, self.xdot,
                 self.s, self.vc, self.W_el, self.W_visc, self.Q_t, self.W_t, self.phase, self.outside,
                 self.settled, self.J, self.dv_corr, self.dvc_corr, impulse)
        info["settled"] += int(ints[0])
        info["settled_iterations"] += int(ints[1])
        info["substeps"] += int(ints[2])
        info["ends"] += int(ints[3])
        if self.history:
            Pn = np.einsum("ki,ki->k", y[:, _P], n) / dt
            for r in np.flatnonzero(np.any(y[:, _P] != 0.0, axis=1)):
                self._hist.setdefault(int(p[r]), []).append((t0, float(Pn[r])))
        return impulse

    def _step_group(self, g, law, p, x_eng, n, v, vc, W, Wc, a, t0, info):
        dt = self.dt
        k = p.shape[0]
        t1, t2 = _tangent_basis(n)
        batch = _Batch(law, n, t1, t2, W, Wc, a, self._paper[p])
        act = self.active[p].copy()
        # the engine's velocities include last step's timing correction: remove it
        v = v - self.dv_corr[p]
        vc = vc - self.dvc_corr[p]
        y = np.zeros((k, NY))
        # internal x for contacts in progress (relaxed toward the engine's when resting)
        x0 = np.where(act, self.x[p], x_eng)
        settle = act & ((t0 - self.t_onset[p]) > SETTLE_AFTER_DURATIONS * self.tau_est[p])
        x0 = np.where(settle, x0 + self.settle_rate * (x_eng - x0), x0)
        y[:, _X] = x0
        y[:, _V] = v
        y[:, _VC] = vc
        # tangential displacement: onto the current tangent plane, same length
        s = self.s[p]
        s_t = s - _dot(s, n)[:, None] * n
        ls, lt = np.linalg.norm(s, axis=1), np.linalg.norm(s_t, axis=1)
        y[:, _S] = np.where((lt > 0)[:, None], s_t * (ls / np.where(lt > 0, lt, 1.0))[:, None], 0.0)
        y[:, _WEL], y[:, _WVI], y[:, _Q], y[:, _WT] = self.W_el[p], self.W_visc[p], self.Q_t[p], self.W_t[p]
        onset = self._onset[g]
        if onset:
            batch.onset = {key: arr[self._pos[p]] for key, arr in onset.items()}
        t_loc = np.zeros(k)
        in_c = act
        settled = np.zeros(k, bool)
        if self.settled_path and np.any(settle & (x0 > 0)):
            done = self._settled(g, law, p, np.flatnonzero(settle & (x0 > 0)), y, batch, t0, info)
            settled[done] = True
            t_loc[done] = dt  # nothing left of the step for these rows
        for _ in range(MAX_SEGMENTS):
            info["segments"] += 1
            rem = dt - t_loc
            free = ~in_c & (rem > 0)
            if np.any(free):
                fi = np.flatnonzero(free)
                tc = self._free_flight(y, fi, batch, rem[fi])
                t_loc[fi] = np.where(np.isfinite(tc), t_loc[fi] + tc, dt)
                new = fi[np.isfinite(tc)]
                if new.size:
                    self._begin(g, law, p, new, y, batch, t0 + t_loc[new])
                    in_c[new] = True
                    info["onsets"] += int(new.size)
            rem = dt - t_loc
            ci = np.flatnonzero(in_c & (rem > 0))
            if ci.size == 0:
                break
            ended = self._integrate(g, law, p, ci, y, batch, t_loc, t0, info)
            in_c[ended] = False
        else:
            raise RuntimeError(f"more than {MAX_SEGMENTS} contact onsets/separations in one step of {dt!r} s")
        # write back
        self.active[p] = in_c
        self.x[p] = y[:, _X]
        self.xdot[p] = batch.xdot(y)
        self.s[p] = y[:, _S]
        self.vc[p] = y[:, _VC]
        self.W_el[p], self.W_visc[p], self.Q_t[p], self.W_t[p] = y[:, _WEL], y[:, _WVI], y[:, _Q], y[:, _WT]
        self.phase[p] = np.where(self.xdot[p] < 0, 1, 0)
        self.outside[p] |= law.outside(np.maximum(y[:, _X], 0.0)) & in_c
        # timing correction: the engine applies the impulse as a constant force over the step;
        # J = int (dt/2 - t) f dt / dt, added now and removed next step, moves the engine's
        # position as if the impulse had its actual timing inside the step (zero velocity change)
        J = y[:, _PI] / dt - 0.5 * y[:, _P] if self.timing_correction else np.zeros((k, 3))
        J[settled] = 0.0  # a force held over the whole step: its timing is the engine's
        self.settled[p] = settled
        if self.history:
            Pn = np.einsum("ki,ki->k", y[:, _P], batch.n) / dt
            for r in np.flatnonzero(np.any(y[:, _P] != 0.0, axis=1)):
                self._hist.setdefault(int(p[r]), []).append((t0, float(Pn[r])))
        impulse = y[:, _P] + J - self.J[p]
        self.J[p] = J
        self.dv_corr[p] = np.einsum("kij,kj->ki", W, J)
        self.dvc_corr[p] = np.einsum("kij,kj->ki", Wc, J)
        return impulse

    def _settled(self, g, law, p, rows, y, batch, t0, info):
        """The settled path (module docstring) for candidate rows (contacts past
        SETTLE_AFTER_DURATIONS durations, x > 0). Rows whose approach rate is
        below SETTLED_SPEED_RATIO v_x take one backward-Euler step of the law
        over the whole engine step; returns the rows done (their y written),
        the others are left to sub-cycling.

        Unknowns z = (n.v+, t1.w+, t2.w+) at the step end, w the velocity the
        tangential spring follows (v, or v_com in paper mode); the end state
        x+ = x + dt x'+ (x'+ = -n.v+), s+ = s + dt T w+; the force
        phi(z) = (F_n(x+, x'+), F_t(x+, s+, T w+) capped at mu F_n) from the
        law; z = z_free + dt M phi(z) with M = [n^T W; T W_w] B^T, B = [n; T].
        Newton from the current velocities (its first step is the law
        linearised at the current state); Jacobian I + dt M D with
        D = diag(dF_n/dx dt + dF_n/dx', b + k dt) (Coulomb cap and k(x)
        left out: a quasi-Newton step that still converges).

        Why backward Euler of the whole law: the engine integrates the returned
        constant force with v+ = v + dt (W f + a), x+ = x + dt x'+ (semi-implicit
        Euler), so the force is the law's at the state the engine will reach.
        For a force that is monotone in x and x' (the elastic part has a convex
        potential; the damping is >= 0) that step is unconditionally stable and
        never gains energy at any dt, and its fixed point is the exact static
        balance F_n(x_s, 0) = m a_n."""
        dt = self.dt
        b = batch.sub(rows)
        o = b.onset
        k = rows.size
        n, T = b.n, b.T
        x0 = y[rows, _X]
        v, vc = y[rows, _V], y[rows, _VC]
        nWn = np.einsum("ki,kij,kj->k", n, b.W, n)
        F_el = law.contact_normal_force(x0, np.zeros(k), o)
        vx = np.sqrt(np.maximum(F_el, 0.0) * x0 * nWn)
        slow = (np.abs(_dot(v, n)) <= SETTLED_SPEED_RATIO * vx) & (vx > 0)
        if not np.all(slow):
            keep = np.flatnonzero(slow)
            if keep.size == 0:
                return rows[:0]
            rows, b, k, n, T = rows[keep], b.sub(keep), keep.size, n[keep], T[keep]
            o = b.onset
            x0, v, vc, nWn, vx = x0[keep], v[keep], vc[keep], nWn[keep], vx[keep]
        a, W, Wc = b.a, b.W, b.Wc
        paper = b.paper[:, None]
        Ww = np.where(paper[..., None], Wc, W) if b.any_paper else W
        w = np.where(paper, vc, v) if b.any_paper else v
        Bm = np.concatenate([n[:, None, :], T], axis=1)  # (k, 3, 3): rows n, t1, t2
        Sel = np.concatenate([np.einsum("ki,kij->kj", n, W)[:, None, :], np.einsum("kai,kij->kaj", T, Ww)], axis=1)
        M = Sel @ Bm.transpose(0, 2, 1)
        z_free = np.concatenate([_dot(v + dt * a, n)[:, None], np.einsum("kai,ki->ka", T, w + dt * a)], axis=1)
        z = np.concatenate([_dot(v, n)[:, None], np.einsum("kai,ki->ka", T, w)], axis=1)
        s2 = np.einsum("kai,ki->ka", T, y[rows, _S])
        o2 = {q: np.concatenate([a_, a_]) for q, a_ in o.items()}
        delta = SETTLED_FD_REL * x0 / dt
        tol = SETTLED_VTOL * vx
        eye = np.eye(3)
        conv = np.zeros(k, bool)
        for it in range(SETTLED_NEWTON_MAX + 1):
            xd_e = -z[:, 0]
            x_e = x0 + dt * xd_e
            F2 = law.contact_normal_force(np.concatenate([x_e, x_e + dt * delta]),
                                          np.concatenate([xd_e, xd_e + delta]), o2)
            Fn = F2[:k]
            kt, bt = law.tangential_stiffness(x_e, o)
            s_e = s2 + dt * z[:, 1:]
            if b.plain_tangential:
                Ft = -(bt * z[:, 1:] + kt * s_e)
                if law.mu is not None:
                    cap = law.mu * np.maximum(Fn, 0.0)
                    mag = np.hypot(Ft[:, 0], Ft[:, 1])
                    Ft = Ft * np.where(mag > cap, cap / np.where(mag > 0, mag, 1.0), 1.0)[:, None]
            else:
                Ft, _ = law.tangential_force(x_e, s_e, z[:, 1:], o, Fn)
            phi = np.concatenate([Fn[:, None], Ft], axis=1)
            R = z - z_free - dt * np.einsum("kij,kj->ki", M, phi)
            conv = np.max(np.abs(R), axis=1) <= tol
            info["settled_iterations"] += 1
            if np.all(conv) or it == SETTLED_NEWTON_MAX:
                break
            D = np.concatenate([np.maximum((F2[k:] - Fn) / delta, 0.0)[:, None], bt + kt * dt], axis=1)
            J = eye + dt * M * D[:, None, :]
            z = z - np.linalg.solve(J, R[..., None])[..., 0]
        ok = conv & (x_e > 0) & (Fn > 0) & (np.abs(xd_e) <= SETTLED_SPEED_RATIO * vx)
        if not np.all(ok):
            j = np.flatnonzero(ok)
            rows, n, T, x0, v, vc, a, W, Wc = rows[j], n[j], T[j], x0[j], v[j], vc[j], a[j], W[j], Wc[j]
            x_e, xd_e, Fn, Ft, s_e, z, kt, bt = x_e[j], xd_e[j], Fn[j], Ft[j], s_e[j], z[j], kt[j], bt[j]
            o = {q: a_[j] for q, a_ in o.items()}
        if rows.size == 0:
            return rows
        # the step's result: the law's force at the end state, held over the step
        f = Fn[:, None] * n + np.einsum("ka,kai->ki", Ft, T)
        v1 = v + dt * (np.einsum("kij,kj->ki", W, f) + a)
        Fc = law.normal_force(x_e, np.zeros(rows.size), o)
        dx = x_e - x0
        y[rows, _X] = x_e
        y[rows, _V] = v1
        y[rows, _VC] = vc + dt * (np.einsum("kij,kj->ki", Wc, f) + a)
        y[rows, _S] = np.einsum("ka,kai->ki", s_e, T)
        y[rows, _P] = f * dt
        y[rows, _PI] = 0.5 * dt * dt * f
        y[rows, _WEL] += Fc * dx
        y[rows, _WVI] += (Fn - Fc) * dx
        y[rows, _Q] += np.einsum("ka,ka->k", bt * z[:, 1:], z[:, 1:]) * dt
        y[rows, _WT] -= _dot(f - Fn[:, None] * n, v1 - _dot(v1, n)[:, None] * n) * dt
        # record bookkeeping, as one substep at the end state
        pp = p[rows]
        turn = ~self.turned[pp] & (xd_e <= 0)
        if np.any(turn):
            q = pp[turn]
            self.turned[q] = True
            self.tau1[q] = t0 + dt - self.t_onset[q]
            self.x_turn[q] = x_e[turn]
            self.W_el_comp[q] = y[rows[turn], _WEL]
            self.W_visc_comp[q] = y[rows[turn], _WVI]
        better = Fn > self.F_max[pp]
        self.x_at_F[pp] = np.where(better, x_e, self.x_at_F[pp])
        self.F_max[pp] = np.maximum(self.F_max[pp], Fn)
        self.x_max[pp] = np.maximum(self.x_max[pp], x_e)
        okr = Fn >= F_RATIO_FLOOR * self.F_max[pp]
        ratio = np.where(okr, np.hypot(Ft[:, 0], Ft[:, 1]) / Fn, 0.0)
        self.f_min[pp] = np.where(okr, np.minimum(self.f_min[pp], ratio), self.f_min[pp])
        self.f_max[pp] = np.where(okr, np.maximum(self.f_max[pp], ratio), self.f_max[pp])
        info["settled"] += int(rows.size)
        return rows

    def _free_flight(self, y, fi, batch, rem):
        """Advance rows fi without contact force to the next onset (x >= 0 with
        closing speed) or by rem. Returns the time advanced to onset (inf: none)."""
        n, a = batch.n[fi], batch.a[fi]
        x0 = y[fi, _X]
        xd0 = -_dot(y[fi, _V], n)
        c = -0.5 * _dot(a, n)  # x(t) = x0 + xd0 t + c t^2
        tc = np.full(fi.shape, np.inf)
        imm = ((x0 >= 0) & (xd0 > 0)) | ((x0 > 0) & (xd0 == 0))
        tc[imm] = 0.0
        D = xd0 * xd0 - 4.0 * c * x0
        sq = np.sqrt(np.maximum(D, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_up = np.where(xd0 > 0, -2.0 * x0 / (sq + xd0), (sq - xd0) / (2.0 * c))
            # starting overlapped and separating, pulled back: closing speed 0 before x reaches 0
            t_turn = -xd0 / (2.0 * c)
        up = (x0 < 0) & (D >= 0) & ((xd0 > 0) | (c > 0))
        tc = np.where(~imm & up & (t_up >= 0), t_up, tc)
        back = ~imm & (x0 >= 0) & (xd0 <= 0) & (c > 0)
        stays = back & (x0 - xd0 * xd0 / (4.0 * np.where(c > 0, c, 1.0)) >= 0)
        tc = np.where(stays, t_turn, tc)
        tc = np.where(back & ~stays, t_up, tc)
        tc = np.where(tc <= rem, tc, np.inf)
        tadv = np.where(np.isfinite(tc), tc, rem)
        y[fi, _X] = x0 + xd0 * tadv + c * tadv * tadv
        y[fi, _V] += a * tadv[:, None]
        y[fi, _VC] += a * tadv[:, None]
        y[fi, _PI] += y[fi, _P] * tadv[:, None]
        if np.any(stays & np.isfinite(tc)):  # exactly at the turn: closing speed 0, not slightly negative
            j = fi[stays & np.isfinite(tc)]
            y[j, _V] -= (_dot(y[j, _V], batch.n[j]))[:, None] * batch.n[j]
        return tc

    def _begin(self, g, law, p, new, y, batch, t_abs):
        """Onset of the contacts at rows new: law.onset for all of them at once."""
        pp = p[new]
        n = batch.n[new]
        W = batch.W[new]
        nWn = np.einsum("ki,kij,kj->k", n, W, n)
        if np.any(nWn <= 0):
            raise ValueError(f"n.W.n = {nWn!r} 1/kg must be > 0 (both bodies fixed, or W is wrong)")
        m = 1.0 / nWn
        v = y[new, _V]
        vn = np.maximum(-_dot(v, n), 0.0)
        a_n = -_dot(batch.a[new], n)
        v_used = np.maximum(vn, onset_speed_floor(law, m, a_n))
        o = law.onset(v_used, m)
        # store per pair (group arrays created on first use)
        store = self._onset[g]
        size = self._group_size[g]
        o_new = {}
        for key, val in o.items():
            val = np.broadcast_to(np.asarray(val, dtype=float), (pp.size,))
            o_new[key] = val
            if key not in store:
                store[key] = np.full(size, np.nan)
            store[key][self._pos[pp]] = val
        if not isinstance(batch, _Rows):  # the numpy path's batch carries its rows' onset constants
            batch.onset = {key: arr[self._pos[p]] for key, arr in store.items()}
        # duration estimate -> internal step
        tau_n = _duration_estimate(law, o, m, v_used)
        x_est = cf.hertz_x_max(m, v_used, law.moduli.E, law.geom.R)
        k_t, _ = law.tangential_stiffness(x_est, o_new)
        T = np.eye(3) - n[:, :, None] * n[:, None, :]
        w_t = np.linalg.eigvalsh(T @ W @ T)[:, -1]
        with np.errstate(divide="ignore"):
            tau_t = np.where(k_t.max(axis=1) * w_t > 0, math.pi / np.sqrt(k_t.max(axis=1) * w_t), np.inf)
        self.tau_est[pp] = tau_n
        self.h[pp] = np.minimum(tau_n / SUBSTEPS_PER_CONTACT, tau_t / SUBSTEPS_PER_TANGENTIAL)
        # bookkeeping
        self.t_onset[pp] = t_abs
        self.v_n_in[pp] = vn
        self.v_n_used[pp] = v_used
        self.m_eff[pp] = m
        self.n_in[pp] = n
        self.p_in[pp] = self._point[pp]
        self.u_in[pp] = v - _dot(v, n)[:, None] * n
        vc = y[new, _VC]
        self.vc_in[pp] = vc - _dot(vc, n)[:, None] * n
        self.x_max[pp] = np.maximum(y[new, _X], 0.0)
        self.x_turn[pp] = 0.0
        self.turned[pp] = False
        self.tau1[pp] = 0.0
        self.F_max[pp] = 0.0
        self.x_at_F[pp] = 0.0
        self.f_min[pp] = np.inf
        self.f_max[pp] = 0.0
        self.W_el_comp[pp] = 0.0
        self.W_visc_comp[pp] = 0.0
        self.outside[pp] = False
        y[new, _S] = 0.0
        y[new, _WEL] = y[new, _WVI] = y[new, _Q] = y[new, _WT] = 0.0
        if self._probe is not None:
            for q in pp:
                self.body_in[int(q)] = dict(self._probe(int(q)) or {})
        else:
            for q in pp:
                self.body_in[int(q)] = None

    def _integrate(self, g, law, p, ci, y, batch, t_loc, t0, info):
        """RK4 over rows ci until the end of the step or until some contact
        ends (then return their row indices: they continue as free motion)."""
        dt = self.dt
        b = batch.sub(ci)
        pp = p[ci]
        rem = dt - t_loc[ci]
        nsub = int(max(1, np.max(np.ceil(rem / self.h[pp] - 1e-9))))
        h = rem / nsub
        Y = y[ci]
        force_zero = law.separation == "force-zero"
        ended_rows = np.zeros(0, int)
        for i in range(nsub):
            Y1, Fn0, Ft0 = b.rk4(Y, h)
            info["substeps"] += 1
            # peak force and friction ratio at the substep start
            better = Fn0 > self.F_max[pp]
            self.x_at_F[pp] = np.where(better, Y[:, _X], self.x_at_F[pp])
            self.F_max[pp] = np.maximum(self.F_max[pp], Fn0)
            ok = (Fn0 >= F_RATIO_FLOOR * self.F_max[pp]) & (Fn0 > 0)
            ratio = np.where(ok, Ft0 / np.where(ok, Fn0, 1.0), 0.0)
            self.f_min[pp] = np.where(ok, np.minimum(self.f_min[pp], ratio), self.f_min[pp])
            self.f_max[pp] = np.where(ok, np.maximum(self.f_max[pp], ratio), self.f_max[pp])
            xd0, xd1 = b.xdot(Y), b.xdot(Y1)
            # first maximum compression inside this substep
            lo = np.zeros(ci.size)
            turn = ~self.turned[pp] & (xd0 > 0) & (xd1 <= 0)
            if np.any(turn):
                j = np.flatnonzero(turn)
                bj = b.sub(j)
                th = _find_root(lambda th: bj.xdot(bj.rk4(Y[j], th * h[j])[0]),
                                np.zeros(j.size), np.ones(j.size), xd0[j], xd1[j])
                Yt = bj.rk4(Y[j], th * h[j])[0]
                q = pp[j]
                self.turned[q] = True
                self.tau1[q] = t0 + t_loc[ci[j]] + th * h[j] - self.t_onset[q]
                self.x_turn[q] = Yt[:, _X]
                self.x_max[q] = np.maximum(self.x_max[q], Yt[:, _X])
                self.W_el_comp[q] = Yt[:, _WEL]
                self.W_visc_comp[q] = Yt[:, _WVI]
                lo[j] = th
            self.x_max[pp] = np.maximum(self.x_max[pp], Y1[:, _X])
            # separation
            end = (xd1 < 0) & (Y1[:, _X] < 0)
            if force_zero:
                end |= (xd1 < 0) & (b.indicator(Y1) < 0)
            if np.any(end):
                j = np.flatnonzero(end)
                bj = b.sub(j)
                Y0j = Y[j]
                Ylo = bj.rk4(Y0j, lo[j] * h[j])[0]
                xs = np.where(Ylo[:, _X] > 0, Ylo[:, _X], 1.0)
                Bs = np.abs(bj.indicator(Ylo))
                Bs = np.where(Bs > 0, Bs, 1.0)

                def gfun(yy, bj=bj, xs=xs, Bs=Bs):
                    gx = yy[:, _X] / xs
                    if not force_zero:
                        return gx
                    gb = np.where(bj.xdot(yy) < 0, bj.indicator(yy) / Bs, 1.0)
                    return np.minimum(gx, gb)

                g_lo = gfun(Ylo)
                g_hi = gfun(Y1[j])
                # a substep that starts already past the event (should not happen): end at its start
                g_lo = np.where(g_lo > 0, g_lo, 1e-300)
                th = _find_root(lambda th: gfun(bj.rk4(Y0j, th * h[j])[0]), lo[j], np.ones(j.size), g_lo, g_hi)
                Ye = bj.rk4(Y0j, th * h[j])[0]
                gx = Ye[:, _X] / xs
                by_force = np.zeros(j.size, bool)
                if force_zero:
                    by_force = np.where(bj.xdot(Ye) < 0, bj.indicator(Ye) / Bs, np.inf) < gx
                Y1 = Y1.copy()
                Y1[j] = Ye
                t_end = t_loc[ci[j]] + th * h[j]
                for r, jj in enumerate(j):
                    self._end(int(pp[jj]), Ye[r], float(t0 + t_end[r]),
                              "force-zero" if by_force[r] else "overlap-zero", b.n[jj])
                info["ends"] += int(j.size)
                t_loc[ci] += h
                t_loc[ci[j]] = t_end
                Y = Y1
                ended_rows = ci[j]
                break
            Y = Y1
            t_loc[ci] += h
        else:
            t_loc[ci] = dt  # exact end of step (no rounding drift)
        y[ci] = Y
        return ended_rows

    # ------------------------------------------------------------ records --
    def _end(self, p, ye, t_end, ended_by, n):
        """Close the contact of pair p with the state ye (NY,) at time t_end
        (scalar arithmetic on Python floats: this runs once per impact)."""
        law = self.pairs[p].law
        g = self._group_of[p]
        onset = {k: float(v[self._pos[p]]) for k, v in self._onset[g].items()}
        yl, nl = ye.tolist(), n.tolist()
        v = yl[1:4]
        xd_end = -(v[0] * nl[0] + v[1] * nl[1] + v[2] * nl[2])
        v_out = max(-xd_end, 0.0)
        vin = self.v_n_in[p] if self.v_n_in[p] > 0 else self.v_n_used[p]
        tau = t_end - self.t_onset[p]
        tau1 = self.tau1[p] if self.turned[p] else tau
        u_in = self.u_in[p].tolist()
        u_out = [v[i] + xd_end * nl[i] for i in range(3)]
        lu = math.sqrt(u_in[0] ** 2 + u_in[1] ** 2 + u_in[2] ** 2)
        vct = self.vc_in[p].tolist()
        lv = math.sqrt(vct[0] ** 2 + vct[1] ** 2 + vct[2] ** 2)
        scale = max(vin, lu, lv)
        cor_t_contact = (-(u_out[0] * u_in[0] + u_out[1] * u_in[1] + u_out[2] * u_in[2]) / lu**2
                         if lu > 1e-12 * scale else None)
        vc_end = yl[7:10]
        cor_t = ((vc_end[0] * vct[0] + vc_end[1] * vct[1] + vc_end[2] * vct[2]) / lv**2
                 if lv > 1e-12 * scale else None)
        x_m = float(self.x_turn[p]) if self.turned[p] else float(self.x_max[p])
        outside = []
        x_lim = law.x_limit
        if self.outside[p] or (x_lim is not None and self.x_max[p] >= x_lim):
            outside.append(f"x_max = {self.x_max[p]:.6g} m reached 2R: k_p = sqrt(2 - x/R) of (15) was clamped")
        strain = small_strain_note(x_m, law.geom.R)
        if strain:
            outside.append(strain)
        kl = self._kernel_law[g]
        if kl is not None:
            Pc, Pc_F = K.peak_pressures(kl[0], kl[1], self._oc, p, x_m, float(self.x_at_F[p]), float(self.F_max[p]),
                                        self._scr_rk4[0])
        else:
            Pc = _pc(law, x_m, {k: np.array([v]) for k, v in onset.items()})
            Pc_F = (1.5 * self.F_max[p] / float(area(self.x_at_F[p], law.geom, law.kp_mode))
                    if self.x_at_F[p] > 0 else 0.0)
        W_el, W_vi = yl[_WEL], yl[_WVI]
        params = self._params.get(g)
        if params is None:
            params = self._params[g] = law.parameters()
        rec = ImpactRecord(
            cor_n=v_out / vin,
            cor_t=cor_t,
            cor_t_contact=cor_t_contact,
            cor_tau_ratio=tau1 / (tau - tau1) if tau > tau1 else 0.0,
            tau=float(tau), tau1=float(tau1), tau2=float(tau - tau1),
            x_max=x_m, F_max=float(self.F_max[p]), Pc_max=Pc, Pc_at_Fmax=float(Pc_F),
            W_el_comp=float(self.W_el_comp[p]), W_visc_comp=float(self.W_visc_comp[p]),
            W_el_rest=-(W_el - float(self.W_el_comp[p])), W_visc_rest=W_vi - float(self.W_visc_comp[p]),
            W_diss_n=W_el + W_vi, W_diss_t=yl[_WT], Q_t=yl[_Q],
            spin_in=None, spin_out=None,
            f_min=None if not math.isfinite(self.f_min[p]) else float(self.f_min[p]),
            f_max=float(self.f_max[p]) if math.isfinite(self.f_min[p]) else None,
            omega_x=onset.get("omega_x"), omega_y=onset.get("omega_y"),
            ended_by=ended_by, law=law.name, engine=self.engine, dt=self.dt,
            parameters=dict(params),
            inputs={
                "pair": p, "body1": _name(self.pairs[p].body1), "body2": _name(self.pairs[p].body2),
                "t_onset": float(self.t_onset[p]), "t_end": float(t_end),
                "v_n_in": float(self.v_n_in[p]), "v_n_onset_used": float(self.v_n_used[p]),
                "v_t_in": lu, "mass_effective": float(self.m_eff[p]), "tangential": self.pairs[p].tangential,
                "internal_step": float(self.h[p]), "tau_estimate": float(self.tau_est[p]),
                "x_max_overall": float(self.x_max[p]), "onset": onset,
                "point": self.p_in[p].tolist(), "normal": self.n_in[p].tolist(),
            },
            outside_validity=outside,
        )
        self.active[p] = False
        # spin axis n x t of the incidence (rolling in the direction of incidence positive)
        t_dir = vct if lv > 0 else u_in
        lt = lv if lv > 0 else lu
        if lt > 0:
            a0 = self.n_in[p].tolist()
            t = [c / lt for c in t_dir]
            axis = np.array([a0[1] * t[2] - a0[2] * t[1], a0[2] * t[0] - a0[0] * t[2], a0[0] * t[1] - a0[1] * t[0]])
        else:
            axis = np.zeros(3)
        bi = self.body_in[p]
        if bi is not None:
            rec.inputs["body_in"] = {k: _plain(v) for k, v in bi.items()}
            if "omega1" in bi and lt > 0:
                rec.spin_in = float(np.asarray(bi["omega1"], dtype=float) @ axis)
        if self._probe is None:
            self._publish(p, rec)
        else:  # completed once the engine has applied the contact's last impulse (see pending_count)
            self._pending.append([p, rec, axis if lt > 0 else None, 0])

    def interrupt(self, pairs, why: str) -> int:
        """The engine's state jumped for the bodies of ``pairs`` (pair
        indices (k,); a reset, or positions or velocities set by the user):
        forget every contact of those pairs that was in progress at the start
        of the last step, those still active and those that ended in it
        (their records are dropped: half a contact is no impact), with their
        timing corrections; complete the records of their contacts that ended
        earlier without the body-level output (``why`` says why). Returns the
        number of contacts dropped."""
        sel = np.zeros(len(self.pairs), bool)
        sel[np.asarray(pairs, dtype=int)] = True
        dropped = int(np.count_nonzero(self.active & sel))
        keep = []
        for entry in self._pending:
            p, rec, _axis, waited = entry
            if not sel[p]:
                keep.append(entry)
            elif waited == 0:  # ended in the last step
                dropped += 1
            else:
                rec.inputs["body_out"] = None
                rec.inputs["body_out_unavailable"] = why
                self._publish(p, rec)
        self._pending = keep
        for p in np.flatnonzero(sel):
            self._hist.pop(int(p), None)
        self.active[sel] = False
        self.settled[sel] = False
        self.J[sel] = 0.0
        self.dv_corr[sel] = 0.0
        self.dvc_corr[sel] = 0.0
        return dropped

    def _publish(self, p: int, rec: ImpactRecord) -> None:
        """Move a completed record to ``records`` (with its force history when kept)."""
        hist = self._hist.pop(p, None)
        if self.history and hist:
            t_on = float(rec.inputs.get("t_onset", 0.0))
            rec.inputs["curves"] = {"t": [t - t_on for t, _ in hist], "F_n": [f for _, f in hist],
                                    "kind": "step-averaged", "dt": self.dt}
        self.records.append(rec)

    def _finish_pending(self, at_step_start: bool = False):
        """Complete the records whose pair has no timing correction in the engine
        any more (its velocities are the physical ones): read the probe, move
        them to ``records``. At a step start a record that waited
        PENDING_MAX_STEPS steps (a new contact of the same pair keeps a
        correction going) is completed without the body-level output."""
        keep = []
        probe = self._probe if at_step_start or self._probe_batch is None else None
        for entry in self._pending:
            if at_step_start:
                entry[3] += 1
            p, rec, axis, waited = entry
            clean = waited >= 1 and not np.any(self.J[p])
            if clean:
                if self._probe is not None:
                    if probe is None:  # the first record of a batch between steps
                        probe = self._probe_batch()
                    bo = dict(probe(p) or {})
                    rec.inputs["body_out"] = {k: _plain(v) for k, v in bo.items()}
                    if "omega1" in bo and axis is not None:
                        rec.spin_out = float(np.asarray(bo["omega1"], dtype=float) @ axis)
                self._publish(p, rec)
            elif waited > PENDING_MAX_STEPS:
                rec.inputs["body_out"] = None
                rec.inputs["body_out_unavailable"] = (
                    "the pair was in contact again before its bodies' post-impact state could be read")
                self._publish(p, rec)
            else:
                keep.append(entry)
        self._pending = keep


def _pc(law, x_m, o1):
    """(20), (41): P_c = 1.5 F_n(x_max, 0)/S(x_max), as the reference solver."""
    if x_m <= 0:
        return 0.0
    F = float(law.contact_normal_force(np.array([x_m]), np.array([0.0]), o1)[0])
    return 1.5 * F / float(area(min(x_m, 2 * law.geom.R * (1 - 1e-12)), law.geom, law.kp_mode))


def _name(b):
    return b if isinstance(b, (str, int, float)) else repr(b)


def _plain(v):
    a = np.asarray(v)
    return a.tolist() if a.ndim else a.item() if hasattr(a, "item") else v
