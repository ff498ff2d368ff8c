"""pybullet scenes for isolated impacts and articulated contacts.

Every scene lives in its own DIRECT (headless) client, so adapters and
tests never share engine state. Conventions shared with the MuJoCo scenes:

- z is up; the plate's surface is the plane z = 0 with normal +z, so the
  contact normal (body 2 -> body 1) of a ball on the plate is +z;
- the paper's angle alpha is measured from the plate (90 = normal impact);
  the incident tangential velocity is along +x, so the spin axis n x t is +y
  and a positive ``spin`` is rolling in the direction of incidence;
- ``gap`` is the distance between the surfaces at t = 0 [m];
- no gravity unless given; no linear or angular damping (pybullet's default
  0.04 would drain energy the law did not dissipate); sleeping disabled (a
  body at rest under an external force must not be frozen); the per-body
  velocity clamp (``maxJointVelocity``, default 100 rad/s, also applied to a
  base's spin) lifted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as pb

from msf_contact._validate import check_choice, check_finite, check_positive, check_range
from msf_contact.solver import Body

#: Speed clamp put in place of pybullet's default 100 (rad/s or m/s) [1/s]:
#: far above any impact the laws are valid for, so it never acts.
MAX_COORDINATE_VELOCITY = 1e6
#: Half thickness of a box plate [m] (its top face is the plate surface).
PLATE_HALF_THICKNESS = 0.05
#: Half width of a box plate [m]: large against any ball in these scenes.
PLATE_HALF_WIDTH = 1.0


@dataclass
class Scene:
    """A built scene. ``client`` is the pybullet physics client id; bodies are
    (body unique id, link index) tuples as :class:`engines.base.PairSpec` takes them."""

    client: int
    dt: float
    body1: tuple[int, int]
    body2: tuple[int, int]
    #: extra named handles (e.g. the paddle's joint index)
    info: dict

    def close(self) -> None:
        if pb.isConnected(self.client):
            pb.disconnect(self.client)

    def __enter__(self) -> "Scene":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False


def new_client(dt: float, gravity: float | None = None) -> int:
    """A DIRECT client with time step dt [s], one step per stepSimulation
    (numSubSteps 0), gravity -gravity along z [m/s^2] (off when None)."""
    check_positive("dt", dt, unit="s")
    if gravity is not None:
        check_finite("gravity", gravity)
    c = pb.connect(pb.DIRECT)
    pb.setTimeStep(dt, physicsClientId=c)
    pb.setPhysicsEngineParameter(numSubSteps=0, physicsClientId=c)
    g = 0.0 if gravity is None else float(gravity)
    pb.setGravity(0.0, 0.0, -g, physicsClientId=c)
    return c


def _free_dynamics(client: int, body: int, link: int = -1) -> None:
    pb.changeDynamics(body, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                      maxJointVelocity=MAX_COORDINATE_VELOCITY,
                      activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, physicsClientId=client)


def add_sphere(client: int, body: Body, position, velocity=(0, 0, 0), angular_velocity=(0, 0, 0)) -> int:
    """A free sphere with the Body's mass and inertia (solid sphere 2/5 m R^2
    unless the Body gives its own, which is then used about every axis)."""
    if math.isinf(body.radius) or math.isinf(body.mass):
        raise ValueError(f"a free sphere needs a finite radius and mass, got radius = {body.radius!r} m, "
                         f"mass = {body.mass!r} kg")
    shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=body.radius, physicsClientId=client)
    uid = pb.createMultiBody(body.mass, shape, basePosition=list(position), physicsClientId=client)
    J = body.J
    pb.changeDynamics(uid, -1, mass=body.mass, localInertiaDiagonal=[J, J, J], physicsClientId=client)
    _free_dynamics(client, uid)
    pb.resetBaseVelocity(uid, list(velocity), list(angular_velocity), physicsClientId=client)
    return uid


def add_plate(client: int, kind: str = "plane") -> int:
    """A fixed plate (mass 0) whose surface is z = 0: an infinite plane or a box."""
    if kind == "plane":
        shape = pb.createCollisionShape(pb.GEOM_PLANE, planeNormal=[0, 0, 1], physicsClientId=client)
        return pb.createMultiBody(0.0, shape, basePosition=[0, 0, 0], physicsClientId=client)
    if kind == "box":
        h = [PLATE_HALF_WIDTH, PLATE_HALF_WIDTH, PLATE_HALF_THICKNESS]
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=h, physicsClientId=client)
        return pb.createMultiBody(0.0, shape, basePosition=[0, 0, -PLATE_HALF_THICKNESS], physicsClientId=client)
    raise ValueError(f"plate kind = {kind!r}; valid kinds: plane, box")


def incidence(speed: float, angle_deg: float) -> np.ndarray:
    """Incident velocity of body 1 relative to the plate [m/s] (3,): the
    paper's alpha from the plate, tangential part along +x, normal along -z."""
    check_positive("speed", speed, unit="m/s")
    check_range("angle (degrees to the plate)", angle_deg, 0.0, 90.0, lo_open=True)
    a = math.radians(angle_deg)
    vt = speed * math.cos(a) if angle_deg < 90.0 else 0.0
    return np.array([vt, 0.0, -speed * math.sin(a)])


def ball_on_plate(body1: Body, speed: float, angle_deg: float = 90.0, spin: float = 0.0, *,
                  dt: float, gap: float = 0.0, gravity: float | None = None, plate: str = "plane") -> Scene:
    """A ball (body 1) over a fixed plate with its surface ``gap`` [m] above
    the plate, moving at ``speed`` [m/s] at ``angle_deg`` to the plate, with
    ``spin`` [rad/s] about +y (positive: rolling in the direction of incidence)."""
    check_finite("gap", gap)
    if gap < 0:
        raise ValueError(f"gap = {gap!r} m must be >= 0 (the bodies may not start overlapping)")
    check_finite("spin", spin)
    c = new_client(dt, gravity)
    plate_id = add_plate(c, plate)
    ball = add_sphere(c, body1, [0.0, 0.0, body1.radius + gap], incidence(speed, angle_deg), [0.0, spin, 0.0])
    return Scene(c, dt, (ball, -1), (plate_id, -1), {"plate": plate})


def two_spheres(body1: Body, body2: Body, speed: float, angle_deg: float = 90.0, spin: float = 0.0, *,
                dt: float, gap: float = 0.0, drift=(0.0, 0.0, 0.0), gravity: float | None = None) -> Scene:
    """Two free spheres in flight: body 1 above body 2 (normal +z at the
    contact), relative velocity of the paper's incidence; the centre of mass
    moves with ``drift`` [m/s] (3,), so the collision happens in flight."""
    check_finite("gap", gap)
    if gap < 0:
        raise ValueError(f"gap = {gap!r} m must be >= 0 (the bodies may not start overlapping)")
    m1, m2 = body1.mass, body2.mass
    v_rel = incidence(speed, angle_deg)
    drift = np.asarray(drift, dtype=float)
    v1 = drift + m2 / (m1 + m2) * v_rel
    v2 = drift - m1 / (m1 + m2) * v_rel
    c = new_client(dt, gravity)
    b2 = add_sphere(c, body2, [0.0, 0.0, 0.0], v2)
    b1 = add_sphere(c, body1, [0.0, 0.0, body1.radius + body2.radius + gap], v1, [0.0, spin, 0.0])
    return Scene(c, dt, (b1, -1), (b2, -1), {})


@dataclass(frozen=True)
class Paddle:
    """A rectangular paddle on a revolute joint about +y through the origin.

    length along +x from the hinge, half_width along y, half_thickness along
    z [m]; mass [kg]; the flat top face (normal +z) is at z = half_thickness.
    """

    length: float = 0.3
    half_width: float = 0.05
    half_thickness: float = 0.01
    mass: float = 0.5

    def __post_init__(self):
        for name in ("length", "half_width", "half_thickness", "mass"):
            check_positive(f"paddle {name}", getattr(self, name))

    @property
    def inertia_com(self) -> np.ndarray:
        """Principal inertia of the box about its centre [kg m^2] (3,)."""
        a, b, c = self.length / 2, self.half_width, self.half_thickness
        m = self.mass
        return m / 3.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])

    def hinge_inertia(self) -> float:
        """Moment of inertia about the hinge axis (+y through the origin) [kg m^2]."""
        return float(self.inertia_com[1] + self.mass * ((self.length / 2) ** 2 + 0.0))

    def effective_mass(self, d: float) -> float:
        """Effective mass [kg] along z at a point a distance d [m] from the hinge
        on the top face: J / d^2 with J about the hinge, the point's lever
        (d, 0, half_thickness) seen by a z force being d."""
        check_positive("distance from the hinge", d, unit="m")
        return self.hinge_inertia() / d**2


def paddle_and_ball(body1: Body, paddle: Paddle, hit_at: float, speed: float, *, dt: float, gap: float = 0.0,
                    motor_velocity: float = 0.0, motor_force: float = 0.0,
                    gravity: float | None = None) -> Scene:
    """A ball falling at ``speed`` [m/s] onto the top face of a paddle (a box
    link of a multibody on a revolute joint about +y, fixed base), at distance
    ``hit_at`` [m] from the hinge along the paddle. The joint motor
    (VELOCITY_CONTROL) drives towards ``motor_velocity`` [rad/s] with at most
    ``motor_force`` [N m]; 0 leaves the hinge free (pybullet's default motor
    with its non-zero force would otherwise hold the joint)."""
    check_range("hit_at (distance from the hinge)", hit_at, 0.0, paddle.length, lo_open=True, hi_open=True)
    check_finite("motor_velocity", motor_velocity)
    check_finite("motor_force", motor_force)
    if motor_force < 0:
        raise ValueError(f"motor_force = {motor_force!r} N m must be >= 0")
    c = new_client(dt, gravity)
    half = [paddle.length / 2, paddle.half_width, paddle.half_thickness]
    # the collision frame is relative to the link (joint) frame, not the inertial frame
    box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, collisionFramePosition=[paddle.length / 2, 0, 0],
                                  physicsClientId=c)
    uid = pb.createMultiBody(
        baseMass=0.0, baseCollisionShapeIndex=-1, basePosition=[0, 0, 0],
        linkMasses=[paddle.mass], linkCollisionShapeIndices=[box], linkVisualShapeIndices=[-1],
        linkPositions=[[0, 0, 0]], linkOrientations=[[0, 0, 0, 1]],
        linkInertialFramePositions=[[paddle.length / 2, 0, 0]], linkInertialFrameOrientations=[[0, 0, 0, 1]],
        linkParentIndices=[0], linkJointTypes=[pb.JOINT_REVOLUTE], linkJointAxis=[[0, 1, 0]],
        physicsClientId=c)
    pb.changeDynamics(uid, 0, localInertiaDiagonal=list(paddle.inertia_com), physicsClientId=c)
    _free_dynamics(c, uid, 0)
    pb.setJointMotorControl2(uid, 0, pb.VELOCITY_CONTROL, targetVelocity=motor_velocity, force=motor_force,
                             physicsClientId=c)
    ball = add_sphere(c, body1, [hit_at, 0.0, paddle.half_thickness + body1.radius + gap], [0.0, 0.0, -speed])
    return Scene(c, dt, (ball, -1), (uid, 0), {"paddle": paddle, "hit_at": hit_at, "joint": 0})


#: pybullet_data's KUKA iiwa posture for kuka_paddle [rad] (joints 1-7): elbow
#: bent, the flange up and 0.57 m out from the base axis.
KUKA_POSTURE = (0.0, 0.6, 0.0, -1.2, 0.0, 0.6, 0.0)
#: The KUKA motors' gains in kuka_paddle (pybullet_envs' kuka.py uses these):
#: POSITION_CONTROL positionGain, velocityGain [-], maximum force [N m] (the URDF's effort limit).
KUKA_POSITION_GAIN, KUKA_VELOCITY_GAIN, KUKA_MAX_FORCE = 0.3, 1.0, 300.0


def kuka_paddle(body1: Body, speed: float, *, dt: float, holder: str = "constraint", paddle: Paddle = Paddle(),
                hit_x: float = 0.1, gap: float = 0.0, gravity: float | None = None) -> Scene:
    """A ball falling at ``speed`` [m/s] onto a paddle held by an arm
    (issue 11): pybullet_data's ``kuka_iiwa/model.urdf`` (fixed base) at
    KUKA_POSTURE, every joint held there by a POSITION_CONTROL motor
    (KUKA_POSITION_GAIN, KUKA_VELOCITY_GAIN, KUKA_MAX_FORCE). ``holder``:

    - ``"constraint"``: the paddle (a free box, ``paddle``'s sizes and mass,
      top face horizontal) is held on the flange (link 6) by a JOINT_FIXED
      ``createConstraint``, 30 mm above it; the ball hits ``hit_x`` [m] from
      the paddle's centre along +x;
    - ``"motor"``: no arm; the paddle is the hinged link of
      :func:`paddle_and_ball`, held at 0 by a POSITION_CONTROL motor on its
      hinge with the same gains, hit ``paddle.length / 2`` from the hinge.

    Body 1 is the ball, body 2 the paddle; pybullet's own contact between
    the paddle and the arm is off."""
    import pybullet_data

    check_choice("holder", holder, ("constraint", "motor"))
    if holder == "motor":
        sc = paddle_and_ball(body1, paddle, paddle.length / 2, speed, dt=dt, gap=gap, gravity=gravity)
        pb.setJointMotorControl2(sc.body2[0], 0, pb.POSITION_CONTROL, targetPosition=0.0, targetVelocity=0.0,
                                 force=KUKA_MAX_FORCE, positionGain=KUKA_POSITION_GAIN,
                                 velocityGain=KUKA_VELOCITY_GAIN, physicsClientId=sc.client)
        sc.info["holder"] = "motor"
        return sc
    check_range("hit_x (from the paddle's centre)", abs(hit_x), 0.0, paddle.length / 2, hi_open=True)
    c = new_client(dt, gravity)
    pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=c)
    arm = pb.loadURDF("kuka_iiwa/model.urdf", useFixedBase=True, physicsClientId=c)
    for j, q in enumerate(KUKA_POSTURE):
        pb.resetJointState(arm, j, q, 0.0, physicsClientId=c)
        _free_dynamics(c, arm, j)
    pb.setJointMotorControlArray(arm, list(range(len(KUKA_POSTURE))), pb.POSITION_CONTROL,
                                 targetPositions=list(KUKA_POSTURE), targetVelocities=[0.0] * len(KUKA_POSTURE),
                                 forces=[KUKA_MAX_FORCE] * len(KUKA_POSTURE),
                                 positionGains=[KUKA_POSITION_GAIN] * len(KUKA_POSTURE),
                                 velocityGains=[KUKA_VELOCITY_GAIN] * len(KUKA_POSTURE), physicsClientId=c)
    flange = len(KUKA_POSTURE) - 1
    fpos, forn = pb.getLinkState(arm, flange, computeForwardKinematics=True, physicsClientId=c)[4:6]
    half = [paddle.length / 2, paddle.half_width, paddle.half_thickness]
    centre = np.array(fpos) + [0.0, 0.0, 0.03 + paddle.half_thickness]
    box = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=c)
    pad = pb.createMultiBody(paddle.mass, box, basePosition=list(centre), physicsClientId=c)
    pb.changeDynamics(pad, -1, localInertiaDiagonal=list(paddle.inertia_com), physicsClientId=c)
    _free_dynamics(c, pad)
    for j in range(-1, pb.getNumJoints(arm, physicsClientId=c)):
        pb.setCollisionFilterPair(arm, pad, j, -1, 0, physicsClientId=c)
    # the paddle's pose in the flange's link frame: the constraint holds it there
    inv_p, inv_o = pb.invertTransform(fpos, forn)
    rel_p, rel_o = pb.multiplyTransforms(inv_p, inv_o, list(centre), [0, 0, 0, 1])
    cid = pb.createConstraint(arm, flange, pad, -1, pb.JOINT_FIXED, [0, 0, 0], rel_p, [0, 0, 0],
                              parentFrameOrientation=rel_o, physicsClientId=c)
    ball = add_sphere(c, body1, [centre[0] + hit_x, centre[1], centre[2] + paddle.half_thickness + body1.radius + gap],
                      [0.0, 0.0, -speed])
    return Scene(c, dt, (ball, -1), (pad, -1), {"paddle": paddle, "arm": arm, "constraint": cid,
                                                   "holder": "constraint", "hit_x": hit_x})
