"""MuJoCo back end: the force laws of :mod:`msf_contact` through the
``mjcb_passive`` hook (:mod:`.adapter`), the scenes (:mod:`.scenes`) and
MuJoCo's own soft contact for comparison (:mod:`.builtin`).

Engines of the registry (:data:`engines.base.ENGINES`, resolved by name):

- ``"mujoco"``: :func:`run_impact`, one isolated impact with a law;
- ``"mujoco-builtin"``: :func:`run_builtin_impact`, the same impact with
  MuJoCo's soft contact (``builtin={"solref": ..., "solimp": ...}``).
"""

from __future__ import annotations

import math

import mujoco

from msf_contact import closed_forms as cf
from msf_contact._validate import check_choice
from msf_contact.laws import ForceLaw
from msf_contact.record import ImpactRecord
from msf_contact.solver import TANGENTIAL_MODES, Body, check_impact_inputs, reduced_mass

from ..base import PairSpec
from ..contract import check_step_budget
from . import scenes
from .adapter import MujocoAdapter, installed
from .builtin import builtin_impact

#: A run gives up (RuntimeError) after the flight over the gap plus this many
#: elastic (Hertz) contact durations without the contact ending and the ball
#: moving away: a capture, or a contact far longer than any law here gives.
MAX_DURATIONS = 200.0
#: Steps run between checks for the end of the contact.
CHUNK = 8


def _other(model) -> str:
    return "plate" if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate") >= 0 else "ball2"


def run_impact(
    law: ForceLaw,
    body1: Body,
    body2: Body,
    speed: float,
    angle_deg: float = 90.0,
    spin: float = 0.0,
    *,
    tangential: str = "contact-point",
    dt: float = 1e-4,
    gap: float = 0.0,
    gravity: float | None = None,
    integrator: str = "euler",
    builtin: dict | None = None,
    plate: str = "plane",
) -> ImpactRecord:
    """One isolated impact of body 1 (a ball) on body 2 in MuJoCo, as an
    :class:`~msf_contact.ImpactRecord` in the reference solver's format.

    Body 2 with an infinite radius is a fixed plate (``plate``: "plane" or
    "box", its top face), otherwise a free sphere (two spheres in flight).
    ``speed`` [m/s], ``angle_deg`` (paper's alpha, 90 = normal), ``spin``
    [rad/s] (positive: rolling in the direction of incidence), ``dt`` [s] the
    engine step, ``gap`` [m] between the surfaces at t = 0 (sets where in a
    step the contact begins), ``gravity`` [m/s^2] along -n (off by default,
    as in the reference solver). With ``builtin`` (solref, solimp) the law
    must be None and MuJoCo's own contact runs instead
    (:func:`run_builtin_impact`). The run stops at the first step after the
    contact has ended with the ball moving away; RuntimeError if that does
    not happen within MAX_DURATIONS elastic contact durations.
    """
    if builtin is not None:
        if law is not None:
            raise ValueError("law and builtin are exclusive: builtin runs MuJoCo's own contact (pass law=None)")
        return run_builtin_impact(body1, body2, speed, angle_deg, spin, builtin=builtin, dt=dt, gap=gap,
                                  gravity=gravity, integrator=integrator, plate=plate)
    if not isinstance(law, ForceLaw):
        raise ValueError(f"law = {law!r} must be a constructed msf_contact ForceLaw")
    check_choice("tangential", tangential, TANGENTIAL_MODES)
    scenes.check_common(dt, integrator, gap, gravity)
    check_impact_inputs(law, body1, body2, speed, angle_deg, spin)
    if math.isinf(body2.radius):
        if not math.isinf(body2.mass):
            raise ValueError(f"body2 mass = {body2.mass!r} kg: a plate (infinite radius) is fixed here; "
                             "give mass = inf")
        model, data = scenes.ball_on_plate(body1, speed, angle_deg, spin, gap=gap, dt=dt, integrator=integrator,
                                           gravity=gravity, plate=plate)
    else:
        model, data = scenes.two_spheres(body1, body2, speed, angle_deg, spin, gap=gap, dt=dt,
                                         integrator=integrator, gravity=gravity)
    m = reduced_mass(body1.mass, body2.mass)
    _, vn0 = scenes.initial_velocity(speed, angle_deg)
    tau_h = float(cf.hertz_tau(m, vn0, law.moduli.E, law.geom.R))
    max_steps = check_step_budget(math.ceil((gap / vn0 + MAX_DURATIONS * tau_h) / dt) + 10, dt, gap,
                                  f"gap/V_n + {MAX_DURATIONS:g} Hertz durations")
    adapter = MujocoAdapter(model, data, [PairSpec("ball", _other(model), law, tangential)])
    adapter.manager.history = True  # the record carries the step-averaged force-time curve
    rec = run_until_separated(adapter, max_steps)
    inputs = dict(rec.inputs or {})
    inputs.update(speed=speed, angle_deg=angle_deg, spin=spin, tangential=tangential, gap=gap, gravity=gravity,
                  integrator=integrator, mass_reduced=m, steps=adapter.steps,
                  body1={"material": body1.material.name, "radius": body1.radius, "mass": body1.mass},
                  body2={"material": body2.material.name, "radius": body2.radius, "mass": body2.mass})
    rec.inputs = inputs
    return rec


def run_until_separated(adapter: MujocoAdapter, max_steps: int, pair: int = 0) -> ImpactRecord:
    """Step until the first contact of ``pair`` has ended (a record exists),
    the manager has removed its last timing correction (the pair is no longer
    in ``manager.required_pairs``, so the engine's velocities are the
    contact's outgoing ones) and body 1 moves away from body 2 along the
    contact normal; return that record. RuntimeError after ``max_steps``."""
    with installed(adapter):
        while adapter.steps < max_steps:
            adapter.step(min(CHUNK, max_steps - adapter.steps))
            recs = [r for r in adapter.records if int(r.inputs.get("pair", 0)) == pair]
            if recs and pair not in adapter.manager.required_pairs and adapter.separating(pair):
                return recs[0]
    raise RuntimeError(f"the contact did not end within {max_steps} steps of dt = {adapter.timestep!r} s "
                       "(a capture, or a contact far longer than expected)")


#: The same isolated impact with MuJoCo's own soft contact
#: (:func:`engines.mujoco.builtin.builtin_impact`).
run_builtin_impact = builtin_impact


__all__ = ["MujocoAdapter", "installed", "run_impact", "run_builtin_impact", "run_until_separated", "scenes",
           "builtin_impact"]
