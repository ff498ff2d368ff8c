"""MJCF scenes for the MuJoCo adapter: a ball over a fixed plate, two free
spheres in flight, a paddle on a driven hinge and a ball.

Conventions shared by every scene:

- The plate's (or lower body's) surface is the plane z = 0 with its normal
  +z (body 2 -> body 1); body 1 starts ``gap`` [m] above it.
- ``speed`` [m/s] is the impact speed, ``angle_deg`` the paper's alpha
  (to the plate; 90 = normal): v = (speed cos(alpha), 0, -speed sin(alpha)),
  the incidence direction t = +x.
- ``spin`` [rad/s] is body 1's angular velocity about n x t = +y, positive
  for rolling in the direction of incidence (the reference solver's sign).
- Masses and inertias come from :class:`msf_contact.solver.Body` through an
  explicit ``<inertial>`` (solid sphere 2/5 m R^2 unless given), so the
  engine and the reference solver integrate the same bodies.
- Gravity is off unless ``gravity`` [m/s^2] (a magnitude along -z) is given,
  as in the reference solver's isolated impact.
- MuJoCo's own contact between the pair is switched off with
  ``<contact><exclude>`` between the two bodies (``builtin=None``); that is
  the one mechanism this package uses, and :class:`MujocoAdapter` refuses a
  model in which MuJoCo would still generate a contact for a managed pair.
  With ``builtin={"solref": ..., "solimp": ...}`` the exclusion is left out
  and both geoms carry the same ``solref``/``solimp`` with equal
  ``priority`` and ``solmix`` (so MuJoCo's mixing returns exactly the given
  values, see :mod:`engines.mujoco.builtin`).

Every builder returns ``(model, data)`` with ``mj_forward`` already called.
Geom names: ``"ball"`` (body 1), ``"plate"`` or ``"ball2"`` or ``"paddle"``.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from msf_contact._validate import check_choice, check_finite, check_positive, check_range
from msf_contact.solver import Body

INTEGRATORS = {
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
}
PLATES = ("plane", "box")
#: Half-extent of a box plate and of the plane's drawing, in ball radii: large
#: enough that an oblique ball stays over the face during its contact.
PLATE_HALF_WIDTH_RADII = 50.0


def _f(v: float) -> str:
    """A float for MJCF, exactly (repr round-trips)."""
    return repr(float(v))


def _vec(*v: float) -> str:
    return " ".join(_f(a) for a in v)


def check_common(dt: float, integrator: str, gap: float, gravity: float | None) -> None:
    check_positive("dt", dt, unit="s")
    check_choice("integrator", integrator, INTEGRATORS)
    check_finite("gap", gap)
    if gap < 0:
        raise ValueError(f"gap = {gap!r} m must be >= 0 (the surfaces start apart or touching)")
    if gravity is not None:
        check_finite("gravity", gravity)


def initial_velocity(speed: float, angle_deg: float) -> tuple[float, float]:
    """(tangential +x, normal -z) components of the impact velocity [m/s]."""
    check_positive("speed", speed, unit="m/s")
    check_range("angle_deg (degrees to the plate)", angle_deg, 0.0, 90.0, lo_open=True)
    a = math.radians(angle_deg)
    vt = speed * math.cos(a) if angle_deg < 90.0 else 0.0
    return vt, speed * math.sin(a)


def _option(dt: float, integrator: str, gravity: float | None, builtin: dict | None = None) -> str:
    """The <option> element; with the adapter's forces (builtin None) MuJoCo's
    autoreset is off: a light ball's real acceleration in a short step can
    exceed mjMAXVAL, and the adapter checks the state itself
    (``MujocoAdapter._bad_acceleration``)."""
    g = 0.0 if gravity is None else -float(gravity)
    name = {"euler": "Euler", "rk4": "RK4", "implicitfast": "implicitfast"}[integrator]
    flag = '<flag autoreset="disable"/>' if builtin is None else ""
    return f'<option timestep="{_f(dt)}" integrator="{name}" gravity="0 0 {_f(g)}">{flag}</option>'


def _inertial(body: Body) -> str:
    J = body.J
    return f'<inertial pos="0 0 0" mass="{_f(body.mass)}" diaginertia="{_vec(J, J, J)}"/>'


def _contact_attrs(builtin: dict | None) -> str:
    """Geom attributes for MuJoCo's own contact: same solref/solimp on both
    geoms, equal priority and solmix, so the mixed values are the given ones."""
    if builtin is None:
        return ""
    solref = builtin.get("solref")
    solimp = builtin.get("solimp")
    parts = ['priority="0"', 'solmix="1"', f'condim="{int(builtin.get("condim", 1))}"']
    if solref is not None:
        parts.append(f'solref="{_vec(*solref)}"')
    if solimp is not None:
        parts.append(f'solimp="{_vec(*solimp)}"')
    if "friction" in builtin:
        parts.append(f'friction="{_vec(*builtin["friction"])}"')
    return " ".join(parts)


def _finish(xml: str) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def _free_sphere(name: str, body: Body, pos, vel, spin: float, attrs: str) -> str:
    # free-joint qvel: linear velocity in the world frame, angular velocity in
    # the body frame (identity orientation at t = 0, so the same here)
    return (
        f'<body name="{name}" pos="{_vec(*pos)}">'
        f'<freejoint name="{name}_free"/>{_inertial(body)}'
        f'<geom name="{name}" type="sphere" size="{_f(body.radius)}" mass="0" {attrs}/>'
        "</body>"
    ), list(vel) + [0.0, spin, 0.0]


def ball_on_plate(
    ball: Body,
    speed: float,
    angle_deg: float = 90.0,
    spin: float = 0.0,
    *,
    gap: float = 0.0,
    dt: float = 1e-4,
    integrator: str = "euler",
    gravity: float | None = None,
    plate: str = "plane",
    builtin: dict | None = None,
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """A free ball (geom ``"ball"``) ``gap`` above a fixed plate (geom
    ``"plate"``: an infinite plane, or a box whose top face is z = 0)."""
    check_common(dt, integrator, gap, gravity)
    check_choice("plate", plate, PLATES)
    check_positive("ball radius", ball.radius, unit="m")
    vt, vn = initial_velocity(speed, angle_deg)
    check_finite("spin", spin)
    R = ball.radius
    L = PLATE_HALF_WIDTH_RADII * R
    attrs = _contact_attrs(builtin)
    if plate == "plane":
        plate_xml = f'<geom name="plate" type="plane" size="{_vec(L, L, R)}" {attrs}/>'
    else:
        plate_xml = f'<geom name="plate" type="box" pos="0 0 {_f(-R)}" size="{_vec(L, L, R)}" {attrs}/>'
    ball_xml, qvel = _free_sphere("ball", ball, (0.0, 0.0, R + gap), (vt, 0.0, -vn), spin, attrs)
    exclude = "" if builtin is not None else '<contact><exclude body1="world" body2="ball"/></contact>'
    xml = (f'<mujoco model="ball_on_plate">{_option(dt, integrator, gravity, builtin)}'
           f"<worldbody>{plate_xml}{ball_xml}</worldbody>{exclude}</mujoco>")
    model, data = _finish(xml)
    data.qvel[:] = qvel
    mujoco.mj_forward(model, data)
    return model, data


def two_spheres(
    ball: Body,
    ball2: Body,
    speed: float,
    angle_deg: float = 90.0,
    spin: float = 0.0,
    *,
    gap: float = 0.0,
    dt: float = 1e-4,
    integrator: str = "euler",
    gravity: float | None = None,
    builtin: dict | None = None,
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Two free spheres in flight: ``"ball2"`` at rest with its top at z = 0,
    ``"ball"`` approaching with the relative velocity of the impact, placed
    so that the line of centres is z when the surfaces touch."""
    check_common(dt, integrator, gap, gravity)
    for name, b in (("ball", ball), ("ball2", ball2)):
        check_positive(f"{name} radius", b.radius, unit="m")
        check_positive(f"{name} mass", b.mass, unit="kg")
    vt, vn = initial_velocity(speed, angle_deg)
    check_finite("spin", spin)
    attrs = _contact_attrs(builtin)
    # start upstream by the flight over the gap, so the centres line up along z at touch
    x0 = -vt * gap / vn
    b1, q1 = _free_sphere("ball", ball, (x0, 0.0, ball.radius + gap), (vt, 0.0, -vn), spin, attrs)
    b2, q2 = _free_sphere("ball2", ball2, (0.0, 0.0, -ball2.radius), (0.0, 0.0, 0.0), 0.0, attrs)
    exclude = "" if builtin is not None else '<contact><exclude body1="ball" body2="ball2"/></contact>'
    xml = (f'<mujoco model="two_spheres">{_option(dt, integrator, gravity, builtin)}'
           f"<worldbody>{b1}{b2}</worldbody>{exclude}</mujoco>")
    model, data = _finish(xml)
    data.qvel[:] = q1 + q2
    mujoco.mj_forward(model, data)
    return model, data


def paddle_and_ball(
    ball: Body,
    speed: float,
    *,
    paddle_mass: float = 0.5,
    paddle_half_size: tuple[float, float, float] = (0.1, 0.05, 0.005),
    hit_x: float = 0.15,
    gap: float = 0.0,
    dt: float = 1e-4,
    integrator: str = "euler",
    gravity: float | None = None,
    actuator: str = "position",
    kp: float = 1.0,
    kv: float = 0.0,
    builtin: dict | None = None,
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """A paddle (box geom ``"paddle"``, half sizes ``paddle_half_size`` [m],
    mass ``paddle_mass`` [kg]) on a hinge about +y through the origin,
    extending along +x with its top face at z = 0, driven by a ``position``
    actuator (gain ``kp`` [N m/rad], damping ``kv`` [N m s/rad]) or a
    ``velocity`` actuator (gain ``kv``); the ball falls normally onto the face
    at x = ``hit_x``. The paddle is an articulated link: its effective mass at
    the hit point is I_hinge / hit_x^2 (I_hinge about the hinge axis)."""
    check_common(dt, integrator, gap, gravity)
    check_choice("actuator", actuator, ("position", "velocity"))
    check_positive("paddle_mass", paddle_mass, unit="kg")
    hx, hy, hz = (float(v) for v in paddle_half_size)
    check_positive("paddle_half_size", [hx, hy, hz], unit="m")
    check_range("hit_x (along the paddle)", hit_x, 0.0, 2 * hx, lo_open=True, hi_open=True)
    _, vn = initial_velocity(speed, 90.0)
    R = ball.radius
    attrs = _contact_attrs(builtin)
    Ixx = paddle_mass / 3.0 * (hy**2 + hz**2)
    Iyy = paddle_mass / 3.0 * (hx**2 + hz**2)
    Izz = paddle_mass / 3.0 * (hx**2 + hy**2)
    if actuator == "position":
        act = f'<position name="drive" joint="hinge" kp="{_f(kp)}" kv="{_f(kv)}"/>'
    else:
        act = f'<velocity name="drive" joint="hinge" kv="{_f(kv)}"/>'
    paddle = (
        '<body name="paddle" pos="0 0 0"><joint name="hinge" type="hinge" axis="0 1 0"/>'
        f'<inertial pos="{_vec(hx, 0.0, -hz)}" mass="{_f(paddle_mass)}" diaginertia="{_vec(Ixx, Iyy, Izz)}"/>'
        f'<geom name="paddle" type="box" pos="{_vec(hx, 0.0, -hz)}" size="{_vec(hx, hy, hz)}" mass="0" {attrs}/>'
        "</body>"
    )
    ball_xml, qvel = _free_sphere("ball", ball, (hit_x, 0.0, R + gap), (0.0, 0.0, -vn), 0.0, attrs)
    exclude = "" if builtin is not None else '<contact><exclude body1="paddle" body2="ball"/></contact>'
    xml = (f'<mujoco model="paddle_and_ball">{_option(dt, integrator, gravity, builtin)}'
           f"<worldbody>{paddle}{ball_xml}</worldbody><actuator>{act}</actuator>{exclude}</mujoco>")
    model, data = _finish(xml)
    bq = model.jnt_dofadr[model.joint("ball_free").id]
    data.qvel[bq:bq + 6] = qvel
    mujoco.mj_forward(model, data)
    return model, data


def hinge_inertia(model: mujoco.MjModel) -> float:
    """The paddle's moment of inertia about its hinge [kg m^2] (from the model)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    dof = model.jnt_dofadr[model.joint("hinge").id]
    return float(M[dof, dof])
