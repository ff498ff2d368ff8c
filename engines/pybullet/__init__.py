"""pybullet back-end: the laws through external forces
(:class:`PybulletAdapter`), pybullet's own contact for comparison
(:mod:`.builtin`), and the isolated impact of the command line
(:func:`run_impact` and :func:`run_builtin_registered`, the engines
``pybullet`` and ``pybullet-builtin`` of :data:`engines.base.ENGINES`)."""

from __future__ import annotations

import math
import os
import sys


def _import_pybullet_quietly():
    """pybullet prints its build time on stdout (from C) when imported; send
    that to stderr so `msf-contact impact --json` prints JSON only."""
    if "pybullet" in sys.modules:
        return
    sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no file descriptor 1 (embedded interpreters)
        import pybullet  # noqa: F401
        return
    try:
        os.dup2(2, 1)
        import pybullet  # noqa: F401
    finally:
        os.dup2(saved, 1)
        os.close(saved)


_import_pybullet_quietly()

from engines.contract import PairSpec, check_step_budget
from msf_contact.laws import ForceLaw
from msf_contact.record import ImpactRecord
from msf_contact.solver import TANGENTIAL_MODES, Body, check_impact_inputs, reduced_mass
from msf_contact._validate import check_choice, check_finite, check_positive

from . import builtin as _builtin
from . import scenes
from .adapter import PybulletAdapter

__all__ = ["PybulletAdapter", "run_impact", "run_builtin_impact", "run_builtin_registered", "scenes"]

#: The run stops with an error when the contact has not ended after this
#: many times the elastic Hertz contact duration at the impact speed (plus
#: the flight across the gap): a viscoelastic contact in the model's validity
#: lasts about 1-1.5 times it.
MAX_TIME_FACTOR = 50.0
#: Steps run after the record is made (the bodies are then apart).
AFTER_STEPS = 2


def _check(law, body1: Body, body2: Body, speed, angle_deg, spin, dt, gap, gravity):
    check_positive("dt", dt, unit="s")
    check_finite("gap", gap)
    if gap < 0:
        raise ValueError(f"gap = {gap!r} m must be >= 0 (the bodies may not start overlapping)")
    if gravity is not None:
        check_finite("gravity", gravity)
    if not isinstance(body1, Body) or not isinstance(body2, Body):
        raise ValueError(f"body1, body2 must be msf_contact.Body, got {type(body1).__name__}, "
                         f"{type(body2).__name__}")
    if math.isinf(body1.radius):
        raise ValueError("body1 (the projectile) must be a sphere with a finite radius; a plane is body 2")
    if math.isinf(body2.radius) and not math.isinf(body2.mass):
        raise ValueError(f"body2 is a half-space (radius inf) with mass = {body2.mass!r} kg: the plate of an "
                         "isolated impact is fixed (mass inf)")
    if math.isfinite(body2.radius) and math.isinf(body2.mass):
        raise ValueError("body2 is a sphere of infinite mass: give a finite mass (two spheres in flight) or a "
                         "half-space (radius inf)")
    if law is not None:
        if not isinstance(law, ForceLaw):
            raise ValueError(f"law must be a constructed msf_contact ForceLaw, got {law!r}")
        check_impact_inputs(law, body1, body2, speed, angle_deg, spin)
    else:
        check_positive("speed", speed, unit="m/s")


def _scene(body1, body2, speed, angle_deg, spin, dt, gap, gravity):
    if math.isinf(body2.radius):
        return scenes.ball_on_plate(body1, speed, angle_deg, spin, dt=dt, gap=gap, gravity=gravity)
    return scenes.two_spheres(body1, body2, speed, angle_deg, spin, dt=dt, gap=gap, gravity=gravity)


def _max_time(law_or_none, body1, body2, speed, angle_deg, dt, gap):
    vn = speed * math.sin(math.radians(angle_deg))
    m = reduced_mass(body1.mass, body2.mass)
    if law_or_none is not None:
        xs = float(law_or_none.hertz_scale(vn, m))
        t_c = 3.2 * xs / vn  # Hertz duration 3.21 x_max / v0
    else:
        t_c = 1.0
    return gap / vn + MAX_TIME_FACTOR * t_c + 10 * dt


def run_impact(law: ForceLaw, body1: Body, body2: Body, speed: float, angle_deg: float = 90.0, spin: float = 0.0,
               *, tangential: str = "contact-point", dt: float = 1e-4, gap: float = 0.0,
               gravity: float | None = None, builtin: dict | None = None) -> ImpactRecord:
    """One isolated impact of body 1 on body 2 in pybullet, as an impact record.

    Same meaning as :func:`msf_contact.simulate_impact`: speed [m/s] the
    relative impact speed, angle_deg the paper's alpha (90 = normal), spin
    [rad/s] body 1's spin (positive: rolling in the direction of incidence).
    Body 2 is a fixed plate (radius inf) or a free sphere (two spheres in
    flight). dt [s] the engine step; gap [m] the distance between the
    surfaces at t = 0 (it sets where in a step the contact begins); gravity
    [m/s^2] along -z, off by default (isolated impact). ``builtin`` (a dict,
    see :class:`.builtin.BuiltinContact`) runs pybullet's own contact instead
    of the law.
    """
    check_choice("tangential", tangential, TANGENTIAL_MODES)
    _check(law, body1, body2, speed, angle_deg, spin, dt, gap, gravity)
    if builtin is not None:
        return run_builtin_impact(body1, body2, speed, angle_deg, spin, dt=dt, gap=gap, gravity=gravity,
                                  builtin=builtin, law=law)
    limit = check_step_budget(math.ceil(_max_time(law, body1, body2, speed, angle_deg, dt, gap) / dt), dt, gap,
                              "gap/V_n and the contact's duration bound")
    scene = _scene(body1, body2, speed, angle_deg, spin, dt, gap, gravity)
    with scene, PybulletAdapter(scene.client, [PairSpec(scene.body1, scene.body2, law, tangential)]) as ad:
        ad.manager.history = True  # the record carries the step-averaged force-time curve
        for _ in range(limit):
            ad.step()
            if ad.records:
                break
        else:
            raise RuntimeError(f"the contact did not end within {limit} steps of dt = {dt!r} s "
                               f"(max time {limit * dt:.6g} s)")
        rec = ad.records[0]
    rec.inputs = dict(rec.inputs or {}, speed=speed, angle_deg=angle_deg, spin=spin, tangential=tangential,
                      gap=gap, gravity=gravity, mass_reduced=reduced_mass(body1.mass, body2.mass),
                      body1={"material": body1.material.name, "radius": body1.radius, "mass": body1.mass},
                      body2={"material": body2.material.name, "radius": body2.radius, "mass": body2.mass})
    return rec


def run_builtin_impact(body1: Body, body2: Body, speed: float, angle_deg: float = 90.0, spin: float = 0.0, *,
                       dt: float = 1e-4, gap: float = 0.0, gravity: float | None = None,
                       builtin: dict | _builtin.BuiltinContact | None = None,
                       law: ForceLaw | None = None) -> ImpactRecord:
    """The same isolated impact with pybullet's own contact (:mod:`.builtin`)."""
    _check(law, body1, body2, speed, angle_deg, spin, dt, gap, gravity)
    contact = builtin if isinstance(builtin, _builtin.BuiltinContact) else _builtin.BuiltinContact.of(builtin)
    max_time = _max_time(law, body1, body2, speed, angle_deg, dt, gap)
    check_step_budget(math.ceil(max_time / dt), dt, gap, "gap/V_n and the contact's duration bound")
    scene = _scene(body1, body2, speed, angle_deg, spin, dt, gap, gravity)
    try:
        _builtin.apply(scene.client, (scene.body1, scene.body2), contact)
        rec = _builtin.measure_impact(scene, contact, max_time=max_time)
    finally:
        scene.close()
    rec.inputs.update(speed=speed, angle_deg=angle_deg, spin=spin, gap=gap, gravity=gravity)
    return rec


def run_builtin_registered(law, body1, body2, speed, angle_deg=90.0, spin=0.0, *, tangential="contact-point",
                            dt=1e-4, gap=0.0, gravity=None, builtin=None):
    """``pybullet-builtin`` for the command line: run_impact's signature; the law is not used."""
    return run_builtin_impact(body1, body2, speed, angle_deg, spin, dt=dt, gap=gap, gravity=gravity,
                              builtin=builtin or {}, law=law)

