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
internal x is relaxed by ``settle_rate`` per step toward the engine's less
the lead of the step about to be integrated, so the remaining offset (the
lead above) vanishes and the engine body rests at the static overlap; a move
that would store elastic energy is taken only as far as the island's other
rows release energy in the same step (:data:`.state.RELAX_DOC`).

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
(:mod:`.islands`); a contact alone takes the path described here.

Gaps between steps. The engine's position leads the integrated one by
dt/2 times the step's velocity change (semi-implicit Euler moves a body by
dt v_end), so a pair not in contact that was a candidate in the last step
keeps the manager's gap, relaxed toward the engine's by settle_rate and
never past touching (:meth:`ContactManager._own_gaps`, for the pairs the
adapters mark in ``own_gap``: free spheres, and in MuJoCo a free body's
narrow-phase points on a fixed body); a contact that ended at force zero
with x > 0 restarts from touching. Otherwise a light body rattling between
two contacts begins its next contact already up to the lead deep, with
elastic energy no force worked for.

Moving contact point. When the adapter gives ``ContactKinematics.lever``
(free bodies in both adapters) the contact point moves with the overlap
inside the step: W(d), the contact-point velocity's kinematic change and
the couple of the moved point on both bodies (:data:`.state.LEVER_DOC`), so
the lever arm is the reference solver's R - x/2 also for a contact that
lies wholly inside one step (0.25 mm glass beads 40-60 % deep: cor_t,
spin_out, W_diss_t within 0.02 % of the reference, docs/engines.md).
The contacts of an island move their points as a row alone does (each
row's own terms; the cross terms of one row's moved point in another's
coupling, J_p1 M^-1 J_q^T, are left out: they vanish with the other rows'
forces; a row off its body's centre keeps its point frozen there,
islands.island_lever). Known limits: without ``lever`` (links of articulated bodies) W is
frozen at the step-start geometry (lever arm R, an O(x_max/R) difference in
spin and cor_t); the normal's turn within a step (sphere on sphere) and the
settled path keep the step-start point. One contact per pair (smooth convex
shapes).

Where the code is. Two implementations of this one algorithm:

- :mod:`.reference` (numpy, vectorised over the rows of a law group) is
  the readable reference: the equations above written once, in the
  order of this docstring;
- :mod:`engines._kernel` (numba, the same steps per row in scalar
  arithmetic) is what runs for the five registry laws of
  :mod:`msf_contact.laws`; :mod:`.compiled` drives it.

A law the kernel does not know runs on the numpy path, and
``ContactManager(compiled=False)`` runs every law there. They are tested
equal in tests/test_kernel.py: the same scenes run both ways give the same
records, forces and per-pair state, to 1e-9 relative for one contact row
(``SAME_RTOL``: round-off and root finding) and to twice the contact's own
accuracy for several rows at once (``BATCH_RTOL``: the numpy path steps a
batch with its finest row's internal step). A change to one path is a
change to both.

Modules: :mod:`.state` (constants, the state vector's layout, helpers
both paths share), :mod:`.manager` (:class:`ContactManager`: per-pair
state and the step's dispatch), :mod:`.reference`, :mod:`.compiled`,
:mod:`.records` (onsets and impact records), :mod:`.islands` (contacts
that share a moving body, integrated together), :mod:`.balance` (an
island's energy over each step: a gain is flagged and warned).
"""

from .compiled import kernel_law
from .manager import ContactManager
from .reference import _Batch, _find_root
from .state import (
    F_RATIO_FLOOR,
    MAX_SEGMENTS,
    NY,
    PENDING_MAX_STEPS,
    ROOT_ITER,
    ROOT_TOL,
    SETTLE_AFTER_DURATIONS,
    SETTLE_RATE,
    SETTLED_FD_REL,
    SETTLED_NEWTON_MAX,
    SETTLED_SPEED_RATIO,
    SETTLED_VTOL,
    SUBSTEPS_PER_CONTACT,
    SUBSTEPS_PER_TANGENTIAL,
    TANGENTIAL_MODES,
    V_ONSET_MIN,
    _pc,
    _skew,
    _tangent_basis,
    closing_distance,
    effective_inverse_inertia_free,
    onset_speed_floor,
)

__all__ = [
    "ContactManager", "kernel_law", "closing_distance", "effective_inverse_inertia_free", "onset_speed_floor",
    "F_RATIO_FLOOR", "MAX_SEGMENTS", "NY", "PENDING_MAX_STEPS", "ROOT_ITER", "ROOT_TOL", "SETTLE_AFTER_DURATIONS",
    "SETTLE_RATE", "SETTLED_FD_REL", "SETTLED_NEWTON_MAX", "SETTLED_SPEED_RATIO", "SETTLED_VTOL",
    "SUBSTEPS_PER_CONTACT", "SUBSTEPS_PER_TANGENTIAL", "TANGENTIAL_MODES", "V_ONSET_MIN",
    "_Batch", "_find_root", "_pc", "_skew", "_tangent_basis",
]
