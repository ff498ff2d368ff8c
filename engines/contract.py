"""The data that crosses the adapter contract (:mod:`engines.base`):
what an adapter reads from the engine (:class:`ContactKinematics`), what the
contact manager returns (:class:`ContactForces`), the pairs
(:class:`PairSpec`) and the checks every adapter makes on them.

The lowest module of :mod:`engines` (it imports only :mod:`msf_contact`):
the contact manager (:mod:`engines._contacts`) and the adapter base
(:mod:`engines.base`) both build on it. Conventions as in
:mod:`engines.base`: world frame, SI units, normal from body 2 to body 1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from msf_contact.laws import ForceLaw

#: Below this many engine steps per contact an explicit force cannot resolve
#: the contact (spec section 6); the manager always integrates internally,
#: with at least this many internal steps per contact duration.
STEPS_PER_CONTACT_MIN = 50


@dataclass(frozen=True)
class PairSpec:
    """A pair of bodies (or geoms) and the law between them.

    body1, body2: names in the engine model (MuJoCo geom or body name;
        pybullet (body unique id, link index) or a name the adapter maps).
    law: a constructed :class:`msf_contact.laws.ForceLaw`.
    tangential: "contact-point" (default) or "paper" (spec section 4).
    """

    body1: Any
    body2: Any
    law: ForceLaw
    tangential: str = "contact-point"


@dataclass
class ContactKinematics:
    """What an adapter reads from the engine for n candidate contacts.

    pair: index into the adapter's pair list (n,) int.
    x: approach [m] (n,); negative: a gap that may close within the step.
    normal: unit normal from body 2 to body 1 (n, 3).
    point: contact point, mid-overlap [m] (n, 3).
    v_rel: velocity of body 1's material point at ``point`` minus body 2's [m/s] (n, 3).
    v_com_rel: velocity of body 1's centre of mass minus body 2's [m/s] (n, 3)
        (the "paper" tangential mode integrates its tangential part).
    W: inverse effective inertia at the contact point [1/kg] (n, 3, 3): the
        change of v_rel per unit impulse applied +P on body 1 and -P on body 2
        at ``point``; W = J M^-1 J^T with J the difference of the bodies'
        translational point Jacobians.
    W_com: change of v_com_rel per unit impulse [1/kg] (n, 3, 3) (the
        translational part only; (1/m1 + 1/m2) I for two free bodies).
    a_ext: relative acceleration of the contact points from everything but
        these contacts (gravity, actuators, other contacts) [m/s^2] (n, 3).
    t: engine time at the start of the step [s].
    lever: optional (n, 21): how the contact point moves with the overlap,
        W01 = J0 M^-1 J1^T and W11 = J1 M^-1 J1^T [1/(kg m)], [1/(kg m^2)]
        row-major and g0 = J1 qdot [1/s] (engines._contacts.state.LEVER_DOC;
        free bodies: engines._contacts.state.lever_terms_free). None: the
        point is frozen at ``point`` over the step.
    """

    pair: np.ndarray
    x: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    v_rel: np.ndarray
    v_com_rel: np.ndarray
    W: np.ndarray
    W_com: np.ndarray
    a_ext: np.ndarray
    t: float
    lever: np.ndarray | None = None


@dataclass
class ContactForces:
    """What the manager returns for the step: step-averaged force on body 1
    (body 2 takes the opposite) [N] (n, 3), applied at ``point`` [m] (n, 3),
    for the contacts of the kinematics with the same order; rows of zeros for
    candidates that did not touch. torque (n, 3) [N m], when the kinematics
    gave ``lever``: a step-averaged couple in world axes applied to body 1
    AND body 2 alike (the force's moment about the contact point that moved
    with the overlap, engines._contacts.state.LEVER_DOC); None otherwise."""

    force: np.ndarray
    point: np.ndarray
    pair: np.ndarray
    torque: np.ndarray | None = None


@dataclass(frozen=True)
class ContactReport:
    """One MSF contact's force over one engine step, in SI units (what
    :meth:`engines.base.EngineAdapter.contact_forces` returns).

    pair: index into the adapter's pairs; body1, body2: their names (MuJoCo
        geom names; pybullet "body name/link name").
    t: engine time at the start of the step [s].
    point: contact point, mid-overlap, at the step start [m] (3,).
    normal: unit normal from body 2 to body 1 at the step start (3,).
    force: step-averaged force on body 1 [N] (3,) (body 2 takes -force),
        = F_n normal + F_t.
    F_n: its normal component [N] (positive: pushing the bodies apart).
    F_t: its tangential part [N] (3,).
    overlap: the approach x of the undeformed surfaces at the end of the
        step [m] (the manager's; 0 if the contact ended within the step).
    """

    pair: int
    body1: str
    body2: str
    t: float
    point: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    F_n: float
    F_t: np.ndarray
    overlap: float


#: The law's radii must be the engine shapes' (float32/float64 round trips only).
RADIUS_RTOL = 1e-9


def check_law_curvature(label: str, pair: PairSpec, R1: float, R2: float) -> None:
    """Refuse a pair whose law was built for other radii than the engine's
    shapes: R1 body 1's sphere radius [m], R2 body 2's (inf for a plane or box face)."""
    curv = pair.law.curvature
    for name, want, got in (("R1a", R1, curv.R1a), ("R1b", R1, curv.R1b),
                            ("R2a", R2, curv.R2a), ("R2b", R2, curv.R2b)):
        same = (math.isinf(want) and math.isinf(got)) or (
            math.isfinite(want) and math.isfinite(got) and abs(got - want) <= RADIUS_RTOL * want)
        if not same:
            raise ValueError(f"{label}: the law's curvature {name} = {got!r} m does not match the engine shape's "
                             f"radius {want!r} m of {pair.body1 if name[1] == '1' else pair.body2!r}")


def as_array(a, shape) -> np.ndarray:
    """Float array of the given trailing shape (leading n)."""
    return np.asarray(a, dtype=float).reshape((-1,) + tuple(shape))



#: Work bound of one isolated engine impact (``run_impact`` of each engine):
#: engine steps up to the end of the contact. The default dt = 1e-4 s needs
#: ~10-1,000; at ~10 us a step the bound is ~10 s of stepping. Refused
#: before the first step, so that --dt 1e-12 or --gap 1e9 cannot hang.
MAX_IMPACT_STEPS = 1_000_000


def check_step_budget(steps: float, dt: float, gap: float, why: str) -> int:
    """Refuse an impact run whose step count ``steps`` (dt [s], gap [m] and
    ``why``, the time it has to cover) exceeds :data:`MAX_IMPACT_STEPS`."""
    if not steps <= MAX_IMPACT_STEPS:
        raise ValueError(f"dt = {dt!r} s with gap = {gap!r} m needs {steps:.3g} engine steps ({why}), above the "
                         f"work bound MAX_IMPACT_STEPS = {MAX_IMPACT_STEPS:,} (engines.contract): raise dt or "
                         "lower gap")
    return int(steps)
