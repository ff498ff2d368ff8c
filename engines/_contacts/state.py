"""Constants, the layout of the internal state vector and the helpers both
integration paths of :class:`engines._contacts.ContactManager` share (the
numpy reference, :mod:`.reference`, and the compiled kernel,
:mod:`engines._kernel`, take their tuning constants from here)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from msf_contact import closed_forms as cf
from msf_contact.geometry import area
from msf_contact.laws import ForceLaw, MSFLaw

from ..contract import STEPS_PER_CONTACT_MIN

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
#: the contact's own oscillation, so it adds no visible dynamics; RELAX_DOC).
SETTLE_RATE = 0.1

RELAX_DOC = """The resting relaxation of the internal overlap x (issue 10, the pile).

The internal state (x, x', s) of a contact is what its force comes from; the
engine's geometry x_e only corrects drift. Two differences are expected:

- The lead. The engines' semi-implicit Euler moves a body by dt v_end, so
  over a sub-cycled step (timing-corrected impulse, W and a_ext constant)
  the engine's x_e advances (dt/2)(x'_end - x'_start) more than the
  integrated x: e = x_e - x changes by (dt/2) dx' a step, and
  c = e - (dt/2) x' stays constant. Over a settled step (backward Euler,
  the engine's own update) e stays constant. A contact begun closing at
  x'_0 rests with e = -(dt/2) x'_0 < 0: the engine's body above the
  static overlap, which is what the relaxation removes.
- Drift: the a_ext estimate (the adapters' finite difference), the
  sphere-sphere normal frozen over a step.

Each step a resting row's x moves by settle_rate min(x_e - l - x, 0), with
l = -(dt/2) n.v (= (dt/2) x', the lead of the step about to be sub-cycled)
after a sub-cycled step and l = 0 after a settled one: only c, the part
of e that does not come and go with the row's own motion, is relaxed, and
only toward a smaller overlap. Both matter for the energy. Following the
engine's x up stores elastic energy no force worked for (a gain, up to
6e-6 J a step in the 8-sphere pile, and islands flagged); following
(dt/2) x' down while the contact opens and not up while it closes
ratchets e upward, so the engine rested deeper than the internal x (the
sub-cycled and settled rests of one ball 0.12 % apart). A correction
toward a smaller overlap only releases stored energy (a loss, counted by
the island check as any other). What is left: a c > 0 (the engine deeper
than x) from drift is not followed; its size at rest is measured in
docs/engines.md (the pile section)."""
RECOVERY_DOC = """The free surface's recovery after a contact ends at force zero (issue 10).

MSF's normal force is a nonlinear Kelvin-Voigt element (the paper's Figure
5b): F_n = 2 eta'_E psi x' sqrt(x) + (2/3) E' psi x^(3/2) ((37); (43) for a
sphere). With the default "force-zero" separation a contact ends in
restitution where F_n returns to zero while the surfaces still overlap
(x_e > 0: the softer surface lags behind the receding body, spec section 4,
Schwager and Poeschel 2008). The indented surface is then free, F_n = 0, and
the same law says how it recovers:

    x_r' = -E' x_r / (3 eta'_E),   x_r(t) = x_e exp(-(t - t_e) E' / (3 eta'_E))   (37) at F_n = 0

(psi and sqrt(x) cancel: the rate holds for every k_p mode; eta'_E =
E''/omega_x (46), so the rate is omega_x / (3 tg beta): 500-4,400 1/s for
natural rubber on steel, R = 10 mm, at the pile's onset speeds; for steel on
steel ~1e7 1/s, recovered within a microsecond). The body and the
recovering surface are apart while the body's approach x_b < x_r; they meet
again at x_b = x_r with the surface still indented, and the new contact
continues the elastic element from there: its force is continuous in x, not
restarted from touching. The elastic energy int_0^x_r F_n(x', 0) dx' stays in
the indented surface and its dashpot dissipates it as x_r falls (a loss).

In the manager. A contact ended by force at x_e > 0 keeps (x_e, t_e, rate)
per pair (``x_res``, ``t_res``, ``k_res``; _end). Inside a step the free
flight after such an end takes a closing body at x >= 0 as in contact (the
surface at the body; engines._contacts.reference._free_flight), so nothing
is restarted there; such a contact's ``x_surface_onset`` is the overlap it
resumes at (at most the end's x_e: Records._begin), so it does not read as
an onset found deep (scripts/pile.py's ``deep_onsets``: every onset that
read as deep in the 5- and 32-sphere low pours, 9 and 21 in MuJoCo, 75 and
20 in pybullet, was such a resumption; docs/engines.md). Between steps (ContactManager._own_gaps) a pair not in
contact whose kept gap g is an overlap starts the step from min(g, x_r(t0), x_e)
(x_e the engine's own overlap: the surface is never deeper than the body the
engine shows; the ant's feet, chain links whose kept gap led the engine's by
~0.1 mm, restarted 34 um deep with the foot 61 um above the floor, and its
rest gained 0.18 J, tests/test_robots_mujoco.py):
the body's own approach while it is behind the recovering surface (x_r(t0)
>= g: the contact then resumes at the body's overlap, the engine's and the
internal approach stay equal), the surface's where the surface has
recovered past the body's kept gap within the step (it met the body inside
the step: starting there stores no energy the surface did not hold). Before,
it restarted at touching (x = 0): every such restart put the body's whole
overlap g between the engine's x and the internal one, which the resting
relaxation (RELAX_DOC: toward smaller overlaps only) never paid back, and a
poured pile rested with engine overlaps 11-32 um deeper than the static
ones (docs/engines.md). The surface's energy E_el(x_r(t)) is counted in the
stored energy of the island check and the pile's E
(engines._contacts.balance) until the pair's next contact begins (it then
holds E_el(x) <= E_el(x_r(t0))). Laws without (E, eta_E) onset constants (not
a Kelvin-Voigt element in that form) and contacts ended at x <= 0 keep no
residual: x_r = 0, the restart at touching as before."""


def surface_recovery_rate(onset: dict, pos) -> np.ndarray:
    """E' / (3 eta'_E) [1/s] of RECOVERY_DOC for the onset constants ``onset``
    (key -> (n,) arrays) at positions ``pos``; 0 (no residual kept) where the
    law has no "E", "eta_E" constants or eta_E <= 0."""
    pos = np.atleast_1d(np.asarray(pos))
    if "E" not in onset or "eta_E" not in onset:
        return np.zeros(pos.size)
    E, eta = np.asarray(onset["E"], dtype=float)[pos], np.asarray(onset["eta_E"], dtype=float)[pos]
    ok = (eta > 0) & np.isfinite(E) & np.isfinite(eta)
    return np.where(ok, E / (3.0 * np.where(ok, eta, 1.0)), 0.0)


def surface_recovery_rate_one(onset: dict) -> float:
    """:func:`surface_recovery_rate` of one contact whose onset constants
    ``onset`` are Python floats (key -> float), in the same float arithmetic
    (E' / (3 eta'_E) [1/s], 0.0 where the law has no "E", "eta_E" or eta_E <=
    0): Records._end calls it once per impact, where the array form's numpy
    calls on one element cost more than the rest of the end's bookkeeping."""
    E, eta = onset.get("E"), onset.get("eta_E")
    if E is None or eta is None or not (eta > 0.0 and math.isfinite(E) and math.isfinite(eta)):
        return 0.0
    return E / (3.0 * eta)


def residual_indentation(x_res, k_res, t_res, t) -> np.ndarray:
    """x_r(t) = x_e exp(-(t - t_e) k) [m] of RECOVERY_DOC (n,): x_res the overlap
    at the force-zero end [m] (0: none), k_res the rate E'/(3 eta'_E) [1/s],
    t_res the end time [s], t the time [s] (>= t_res)."""
    x_res = np.asarray(x_res, dtype=float)
    return np.where(x_res > 0, x_res * np.exp(-np.asarray(k_res) * np.maximum(t - np.asarray(t_res), 0.0)), 0.0)


#: f = |F_t|/F_n is tracked while F_n >= this share of the running peak F_n
#: (the reference solver uses 1% of the final peak: F_RATIO_FLOOR).
F_RATIO_FLOOR = 0.01
#: A contact alone that ends with more kinetic energy than it began with by
#: more than this share is flagged and warned (ContactManager records): the
#: sub-cycle's own COR error is <= 1.3e-5 (docs/engines.md), two orders below this.
ENERGY_GAIN_RTOL = 1e-3
#: Largest rotation of a body per engine step, |omega| dt [rad], for which
#: the engines resolve the orientation a contact depends on: pi/4.
#: Both engines turn a body once per step by the exponential map of its
#: angular velocity. Bullet's btMultiBody::stepPositionsMultiDof (pybullet)
#: limits that turn where |omega| dt > ANGULAR_MOTION_THRESHOLD = pi/4
#: (LinearMath/btTransformUtil.h); above it the orientation no longer
#: follows the angular velocity (measured with pybullet 3.2.x: 100 rad/s at
#: dt = 10 ms turns 55.6 degrees per step, not 57.3). MuJoCo's
#: quaternion integration has no such limit, but the contact sub-cycle holds
#: the step-start geometry (contact point, lever arms, W) over the step
#: (LEVER_DOC: the bodies' turn inside the step is left out), so the bound
#: is the same for both engines: a turn of pi/4 moves a contact point at
#: lever arm r by 0.77 r within one step.
#: Only a body whose contact depends on its orientation is checked (the
#: adapters' ``set_orientation_free``): a sphere centred on its centre of
#: mass touches at the same point however it turns, so the spin of a jet bead
#: (~1e5 rad/s at dt = 1e-4 s, 10 rad per step) leaves its records valid.
#: The contact's own frequency needs no such bound: every impact is
#: sub-cycled (omega_x h ~ pi/SUBSTEPS_PER_CONTACT), and the only path at the
#: engine step, the settled path of resting contacts, is backward Euler
#: (stable at any omega dt; steel at 2 ms has omega dt ~ 30).
ROTATION_PER_STEP_MAX = math.pi / 4
#: A sphere counts as centred on its body's centre of mass (its contact then
#: does not depend on the body's orientation) when the two are closer than
#: this share of its radius: float32 round-off of pybullet's shape data; a
#: turn then moves the contact point by less than 1e-6 R.
CENTRED_RTOL = 1e-6
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
_G = slice(20, 23)  # g = J1 qdot [m/s per m]: the contact-point velocity's rate of change with the overlap
_PD = slice(23, 26)  # int_0^t (x - x_ref) f dt' [N m s]: the force's moment about the moving contact point
NY = 26

LEVER_DOC = """The contact point moves with the overlap (engines._contacts, issue 10 item 3).

The engine gives the contact point p0 and W = J0 M^-1 J0^T at the step-start
geometry (the engine's overlap x_e; the point is the middle of the overlap,
each body's own surface point at a gap: engines._geometry.Detection.of_sphere).
Inside the step the overlap changes by d = max(x, 0) - max(x_e, 0) and the
point moves with it: on body 1 by +d n/2 from its centre, on body 2 by -d n/2
(for spheres the lever arms are R_i - max(x, 0)/2, as in the reference
solver, msf_contact.solver (45), (47)); d' = x' while x > 0, else 0.
For rigid bodies the contact-point Jacobian is then J(d) = J0 + d J1 with
J1 = -[n]x (Jr_1 + Jr_2)/2 (Jr_i the rotational Jacobians; a point p + e of
a body has the velocity Jacobian Jp - [e]x Jr). The relative contact-point
velocity v = J(d) qdot obeys, with qdot' = M^-1 (J(d)^T f + Q_ext),

    v' = W(d) f + a_ext + d' g,   W(d) = W + d (W01 + W01^T) + d^2 W11,
    g' = (W01^T + d W11) f,       g = J1 qdot,  g(0) = g0,

W01 = J0 M^-1 J1^T, W11 = J1 M^-1 J1^T (the adapters give W01, W11, g0 per
row; for free bodies :func:`lever_terms_free`). The generalised impulse on
the bodies is J0^T P + J1^T PD with PD = int d f dt: the force P at p0 and,
on both bodies alike, the angular impulse n x PD / 2 (world axes) -- the
torque of f about the moved point, (r_i0 +- d n/2) x (+-f). Free flight
moves the point only where x > 0: v += g d. Left out: the
bodies' orientation change inside the step (a sphere's contact point does
not depend on it), the normal's turn (sphere-sphere: n follows c1 - c2;
second order for the impacts of the acceptance, a plane keeps n), the
coupling of W_com (J_com M^-1 J1^T = 0 for free bodies) and the settled
path (a resting contact's d over a step is ~0). In an island
(engines._contacts.islands) every row moves its own point by these
formulas; the cross terms through another row's moved point (J_p1 M^-1
J_q^T f_q in v_p' and g_p', and d_q in W_pq) are left out: they are
O(d) times the other rows' forces, zero where those carry none."""


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


def onset_speed_floor(law: ForceLaw, m_eff, a_n, K: float | None = None) -> np.ndarray:
    """Smallest onset speed used for the onset constants [m/s] (n,).

    sqrt(2 a_n x_s): the speed gained falling through the static overlap x_s,
    where the elastic force 2/3 E' psi(0) x_s^(3/2) of (29) balances m a_n
    (a_n: external closing acceleration along the normal); at least
    V_ONSET_MIN. A contact that begins slower is settling under a_n: its
    damping is then that of a contact at this speed, not an unbounded one.
    K [N/m^1.5]: the law's 2/3 E' psi(0) (:func:`onset_stiffness`) if the caller keeps it.
    """
    m = np.asarray(m_eff, dtype=float)
    a = np.maximum(np.asarray(a_n, dtype=float), 0.0)
    if K is None:
        K = onset_stiffness(law)
    x_s = (m * a / K) ** (2.0 / 3.0)
    return np.maximum(np.sqrt(2.0 * a * x_s), V_ONSET_MIN)


def onset_stiffness(law: ForceLaw) -> float:
    """2/3 E' psi(0) of (29) [N/m^1.5]: the law's elastic stiffness at x -> 0
    (:func:`onset_speed_floor`)."""
    return 2.0 / 3.0 * law.moduli.E * float(law.psi(np.zeros(1))[0])


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


def _cross(a, b):
    """np.cross of two (k, 3) arrays, the same products and differences (equal bit for bit)
    without np.cross's axis handling (~3x its cost for a few rows)."""
    out = np.empty(a.shape)
    a0, a1, a2, b0, b1, b2 = a[:, 0], a[:, 1], a[:, 2], b[:, 0], b[:, 1], b[:, 2]
    out[:, 0] = a1 * b2 - a2 * b1
    out[:, 1] = a2 * b0 - a0 * b2
    out[:, 2] = a0 * b1 - a1 * b0
    return out


def _msf_inline(law: ForceLaw) -> bool:
    """True when the law's normal and tangential forces are MSFLaw's own, so
    :meth:`_Batch.rhs` may evaluate them inline (one k_p and one sqrt(x) for
    F_n, its elastic part and the shear lengths, instead of six k_p calls)."""
    t = type(law)
    return (law.geom.footprint is None and t.normal_force is MSFLaw.normal_force and t.shear_lengths is MSFLaw.shear_lengths
            and t.tangential_stiffness is MSFLaw.tangential_stiffness and t.psi is ForceLaw.psi
            and t.kp is ForceLaw.kp and t.contact_normal_force is ForceLaw.contact_normal_force)


class _Rows:
    """The rows' normals, inverse inertias and external accelerations for
    :meth:`ContactManager._begin` on the compiled path (the part of _Batch it
    reads), and for the islands' free flight (ContactManager._free_flight)
    the rows' moving contact points: L (k, NL) or None (LEVER_DOC)."""

    def __init__(self, n, W, a, L=None):
        self.n, self.W, self.a = n, W, a
        self.onset: dict = {}
        self.on = None if L is None else L[:, L_ON] != 0.0
        self.lever = self.on is not None and bool(np.any(self.on))


def _pc(law, x_m, o1):
    """(20), (41): P_c = 1.5 F_n(x_max, 0)/S(x_max), as the reference solver."""
    if x_m <= 0:
        return 0.0
    F = float(law.contact_normal_force(np.array([x_m]), np.array([0.0]), o1)[0])
    return 1.5 * F / float(area(min(x_m, 2 * law.geom.R * (1 - 1e-12)), law.geom, law.kp_mode))


def _name(b):
    return b if isinstance(b, (str, int, float)) else repr(b)


def _plain(v):
    if type(v) is np.ndarray:  # the probes' (3,) arrays, twice per record: tolist is item at ndim 0
        return v.tolist()
    a = np.asarray(v)
    return a.tolist() if a.ndim else a.item() if hasattr(a, "item") else v


#: Columns of a row's moving-contact-point data (LEVER_DOC), as engines._kernel's L_*.
L_ON, L_XREF, L_W01, L_W11, L_G0, NL = 0, 1, 2, 11, 20, 23


def lever_terms_free(n, r1, Iinv1, w1, r2, Iinv2, w2) -> np.ndarray:
    """W01, W11 (row-major) and g0 of LEVER_DOC for pairs of free rigid bodies
    (k, 21): n (k, 3) unit normal from body 2 to body 1; r_i (k, 3) [m] from
    body i's centre of mass to the contact point; Iinv_i (k, 3, 3) [1/(kg m^2)]
    inverse inertia in world axes (zeros for a fixed body or one that does not
    turn); w_i (k, 3) [rad/s] angular velocities.

    With Jr_i = the body's angular velocity, J0 = [v1 - [r1]x w1] - [v2 - [r2]x w2]
    and J1 = -[n]x (w1 + w2)/2:
    W01 = (-[r1]x Iinv1 [n]x + [r2]x Iinv2 [n]x)/2, W11 = -[n]x (Iinv1 + Iinv2) [n]x / 4,
    g0 = (w1 + w2) x n / 2."""
    nx = _skew(n)
    W01 = 0.5 * (-_skew(r1) @ Iinv1 @ nx + _skew(r2) @ Iinv2 @ nx)
    W11 = -0.25 * (nx @ (Iinv1 + Iinv2) @ nx)
    g0 = 0.5 * np.cross(w1 + w2, n)
    k = n.shape[0]
    return np.concatenate([W01.reshape(k, 9), W11.reshape(k, 9), g0], axis=1)


def initial_state(mgr, p, x_eng, n, v, vc, resting, io=None) -> np.ndarray:
    """The state y (k, NY) of island rows p (k,) at the step start: the
    engine's velocities less the last step's timing corrections (own and the
    neighbours'), x the manager's for rows in contact (relaxed toward the
    engine's x_eng for resting rows (k,) bool), the tangential displacement
    re-projected onto the current tangent plane, the works carried on.
    Shared by the numpy path (reference.NumpyPath._step_group), step_island
    and the compiled islands (engines._contacts.island_compiled). io
    (n_isl + 1,): the rows' islands (island i: rows io[i]..io[i+1]-1), whose
    relaxation may move elastic energy between its rows (relax); None: every
    row on its own."""
    k = p.size
    act = mgr.active[p]
    v = v - mgr.dv_corr[p]
    vc = vc - mgr.dvc_corr[p]
    y = np.zeros((k, NY))
    x0 = np.where(act, mgr.x[p], x_eng)
    settle = act & resting
    if np.any(settle):
        x0 = relax(mgr, p, x0, x_eng, n, v, settle, io)
    y[:, _X] = x0
    y[:, _V] = v
    y[:, _VC] = vc
    s = mgr.s[p]
    s_t = s - _dot(s, n)[:, None] * n
    ls, lt = np.linalg.norm(s, axis=1), np.linalg.norm(s_t, axis=1)
    y[:, _S] = np.where((lt > 0)[:, None], s_t * (ls / np.where(lt > 0, lt, 1.0))[:, None], 0.0)
    y[:, _WEL], y[:, _WVI], y[:, _Q], y[:, _WT] = mgr.W_el[p], mgr.W_visc[p], mgr.Q_t[p], mgr.W_t[p]
    return y


def lever_start(y, L) -> None:
    """The moving contact point's start (LEVER_DOC), in place on the
    step-start state y (k, NY) from initial_state: g = g0, and v_rel moved
    from the engine's point (overlap x_ref) to the internal overlap's point,
    v += g0 (max(x, 0) - x_ref) for the rows with a lever. L (k, NL) or None
    (every point frozen: nothing to do). Shared by the numpy path
    (reference.NumpyPath._step_group), step_island and the compiled islands
    (the rows' compiled kernel does the same in engines._kernel.prelude)."""
    if L is None:
        return
    y[:, _G] = L[:, L_G0:L_G0 + 3]
    on = L[:, L_ON] != 0.0
    y[on, _V] += y[on, _G] * (np.maximum(y[on, _X], 0.0) - L[on, L_XREF])[:, None]


#: Gauss-Legendre nodes and weights on [0, 1] for the elastic energy (elastic_energy).
_GL_S, _GL_W = np.polynomial.legendre.leggauss(8)
_GL_S, _GL_W = 0.5 * (_GL_S + 1.0), 0.5 * _GL_W


class TakenOnset(Mapping):
    """The onset constants ``src`` (a mapping key -> array) with ``take`` applied to each
    value when the law reads it (and kept): the values a dict comprehension
    {key: take(val)} would hold, made only for the keys read (a law's normal force
    reads two of the onset's keys; :func:`elastic_energy` is called for every law group
    of an island each step)."""

    __slots__ = ("_src", "_take", "_done")

    def __init__(self, src, take):
        self._src, self._take, self._done = src, take, {}

    def __getitem__(self, key):
        done = self._done
        if key not in done:
            done[key] = self._take(self._src[key])
        return done[key]

    def __iter__(self):
        return iter(self._src)

    def __len__(self) -> int:
        return len(self._src)

    def __contains__(self, key) -> bool:
        return key in self._src


def elastic_energy(law, x, onset) -> np.ndarray:
    """Elastic energy of the law's normal force at overlap x [m] (k,): int_0^x
    F_n(x', 0) dx' [J] (the rate-free force is the elastic part, as the
    settled path's F_n(x_e, 0)), by 8-point Gauss-Legendre after x' = x s^2
    (F ~ x'^(3/2) near 0 becomes ~ s^3 x: smooth; exact to ~1e-12 for Hertz)."""
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return np.zeros(0)
    xs = x[:, None] * _GL_S[None, :] ** 2  # (k, 8)
    o = TakenOnset(onset, lambda val: np.repeat(np.asarray(val, dtype=float), _GL_S.size))
    F = law.contact_normal_force(xs.reshape(-1), np.zeros(xs.size), o).reshape(xs.shape)
    return np.sum(F * (2.0 * x[:, None] * _GL_S[None, :]) * _GL_W[None, :], axis=1)


_GL_S2 = _GL_S**2  # elastic_energy's x' = x s^2 (numpy's value of the power)


def side_kernel_rows(mgr, pp) -> np.ndarray:
    """(k,) bool: the rows pp (k,) in contact whose law the compiled kernel has as a lying side's
    end (CODE_SIDE, no ring: engines._narrow.SideEndLaw) or as an MSF point contact in kp mode
    msf (CODE_MSF: a sphere, a capsule's end, an ellipsoid), whose normal force and elastic energy
    :func:`side_forces` and :func:`side_energies` give for all their groups in one call."""
    from .. import _kernel as K

    kg = mgr._kg_of_pair[pp]
    ok = kg >= 0
    if np.any(ok):
        k = kg[ok]
        c, lc = mgr._kcodes[k], mgr._kLC[k]
        ok[ok] = (((c == K.CODE_SIDE) & (lc[:, K.LC_SRING] == 0.0) & (lc[:, K.LC_SE] > 0.0))
                  | ((c == K.CODE_MSF) & (lc[:, K.LC_KPMODE] == K.KP_MSF) & (lc[:, K.LC_SE] == 0.0)))
    return ok & mgr.active[pp]


def side_forces(mgr, pp, x, one) -> np.ndarray:
    """F_n(x, 0) [N] (k,) of rows pp (k,) of :func:`side_kernel_rows` at x [m] (k,): each group's
    ``contact_normal_force`` bit for bit (engines._kernel.side_normal_forces; one (k,) bool: the
    row alone in its group's call, which takes SideEndLaw._width_one's sum)."""
    from .. import _kernel as K

    out = np.empty(pp.size)
    K.side_normal_forces(mgr._kLC, mgr._kg_of_pair[pp], mgr._oc, np.ascontiguousarray(pp, dtype=np.int64),
                         np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(one, dtype=np.bool_), out)
    return out


def side_energies(mgr, pp, x) -> np.ndarray:
    """:func:`elastic_energy` [J] (k,) of rows pp (k,) of :func:`side_kernel_rows` at x [m] (k,),
    bit for bit, every group in one call (engines._kernel.side_elastic_energy)."""
    from .. import _kernel as K

    out = np.empty(pp.size)
    K.side_elastic_energy(mgr._kLC, mgr._kg_of_pair[pp], mgr._oc, np.ascontiguousarray(pp, dtype=np.int64),
                          np.ascontiguousarray(x, dtype=float), _GL_S2, _GL_S, _GL_W, np.empty(8), out)
    return out


#: relative tolerance of approach_of_energy's Newton iteration on the elastic
#: energy (two orders above the double's round-off of E_el's 8-point sum)
ENERGY_APPROACH_RTOL = 1e-12
#: its iteration cap (E_el is convex and increasing in x: Newton converges
#: monotonically from its second iterate; 3-6 iterations measured)
ENERGY_APPROACH_MAX = 50


def approach_of_energy(law, E, x0, onset) -> np.ndarray:
    """The approach x [m] (k,) at which ``law`` stores the elastic energy E [J]
    (k,), E_el(x) = E (:func:`elastic_energy`), by Newton from x0 (k,) [m]
    with dE_el/dx = F_n(x, 0) (x0 > 0 where E > 0); E <= 0 gives 0. Used when a law's constants
    change under a contact in progress (ContactManager.refresh_law): the
    contact keeps its energy, not its approach."""
    E = np.asarray(E, dtype=float)
    x = np.maximum(np.asarray(x0, dtype=float).copy(), 0.0)
    pos = E > 0.0
    x[~pos] = 0.0
    for _ in range(ENERGY_APPROACH_MAX):
        r = np.flatnonzero(pos)
        if r.size == 0:
            break
        o = {key: np.asarray(val, dtype=float)[r] for key, val in onset.items()}
        err = elastic_energy(law, x[r], o) - E[r]
        F = law.contact_normal_force(x[r], np.zeros(r.size), o)
        ok = np.abs(err) <= ENERGY_APPROACH_RTOL * E[r]
        xn = np.where(F > 0.0, x[r] - err / np.where(F > 0.0, F, 1.0), 2.0 * x[r])  # F = 0 only at x = 0
        x[r] = np.where(ok, x[r], np.where(xn > 0.0, xn, 0.5 * x[r]))
        pos[r[ok]] = False
    return x


def relax(mgr, p, x0, x_eng, n, v, settle, io=None) -> np.ndarray:
    """The resting relaxation of RELAX_DOC for rows p (k,): x0 (k,) [m] the
    manager's x, x_eng (k,) the engine's, n (k, 3), v (k, 3) [m/s] the
    relative velocities less the timing corrections' offsets, settle (k,)
    bool: the rows relaxed. Each settle row's x moves by settle_rate
    (x_eng - l - x0) (l the sub-cycled lead); the elastic energy this puts in
    (E_el(x0 + dx) - E_el(x0), E_el(x) = int_0^x F_n(x', 0) dx', dx > 0) is
    allowed only as far as the island's other rows give energy up in the
    same step (dx < 0), so the relaxation never adds energy to an island:
    the positive moves are scaled down to the negative ones' energy (by the
    exact energies: E_el is convex, so a move scaled by s stores at most s
    times the full move's energy; with the first-order F_n(x0, 0) dx, as
    before, each pair of moves gained F_n' dx^2 / 2, 1e-9 to 7e-9 J a step
    in a settling steel-on-rubber column). Without io (rows alone): only toward a
    smaller overlap, except after a settled step (RELAX_DOC). Returns x (k,) [m]."""
    lead = np.where(mgr.settled[p], 0.0, -0.5 * mgr.dt * _dot(v, n))
    dx = np.where(settle, mgr.settle_rate * (x_eng - lead - x0), 0.0)
    up = dx > 0
    if not np.any(up):
        return x0 + dx
    if io is None:  # rows alone: up only after a settled step (RELAX_DOC)
        return x0 + np.where(up & ~mgr.settled[p], 0.0, dx)
    dS = np.zeros(p.size)  # the elastic energy each move stores [J] (< 0: releases)
    mv = np.flatnonzero(dx != 0)
    side = side_kernel_rows(mgr, p[mv]) if mgr._batched_laws else np.zeros(mv.size, bool)
    if np.any(side):  # the lying sides' ends of every group at once (the same values as below)
        sel = mv[side]
        pp = p[sel]
        E = side_energies(mgr, np.concatenate([pp, pp]),
                          np.concatenate([np.maximum(x0[sel] + dx[sel], 0.0), np.maximum(x0[sel], 0.0)]))
        dS[sel] = E[:sel.size] - E[sel.size:]
        mv = mv[~side]
    gid = mgr._group_of[p[mv]]
    for g in np.unique(gid):
        sel = mv[gid == g]
        # both ends of each move in one call (each row's energy is its own: the same values)
        at = mgr._pos[p[sel]]
        o = TakenOnset(mgr._onset[g], lambda arr: arr[np.concatenate([at, at])])
        law, xa = mgr._groups[g], np.maximum(x0[sel], 0.0)
        E = elastic_energy(law, np.concatenate([np.maximum(x0[sel] + dx[sel], 0.0), xa]), o)
        dS[sel] = E[:sel.size] - E[sel.size:]
    isl = np.repeat(np.arange(io.size - 1), np.diff(io))
    gain = np.bincount(isl, np.where(up, dS, 0.0), minlength=io.size - 1)
    give = -np.bincount(isl, np.where(up, 0.0, dS), minlength=io.size - 1)
    scale = np.where(gain > give, give / np.where(gain > 0, gain, 1.0), 1.0)
    return x0 + np.where(up, scale[isl] * dx, dx)
