"""The jet's specification: nozzle, particles, plate, histogram bins and
:class:`JetSpec` (frozen, validated; the model's validity at the fastest
particle, :meth:`JetSpec.check_validity`), with the jet's constants."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from msf_contact import ValidityWarning


ENGINES = ("mujoco", "pybullet")
ARRIVALS = ("uniform", "poisson")
PLATE_KINDS = ("plane", "box")

#: The fastest particle must need at least this many engine steps from the
#: nozzle exit to the plate: the first step after an emission carries a wrong
#: external-acceleration estimate in the adapters (module docstring), which
#: must not meet a contact.
MIN_FLIGHT_STEPS = 3.0
#: Speeds are drawn from a normal distribution truncated at this many
#: standard deviations (so v_max = mean + 3 sd is the fastest particle the
#: validity checks cover).
SPEED_TRUNCATION_SD = 3.0
#: Radii drawn from a normal distribution are binned over mean +- this many sd.
RADIUS_TRUNCATION_SD = 3.0
#: Smallest angle of the cone's directions to the plate [deg]: below it a
#: particle travels more than 11 times the nozzle height to the plate.
MIN_CONE_ANGLE_DEG = 5.0
#: Pool size per class when not given: this safety factor times the mean
#: number of particles of the class busy at once (flight + contact + record
#: latency + parking), plus POOL_EXTRA.
POOL_SAFETY = 1.5
POOL_EXTRA = 2
#: Engine steps a particle waits after its contact for its record
#: (engines.base: a record appears about two steps after the contact ends).
RECORD_LATENCY_STEPS = 4
#: Parked particles sit this far upstream of the nozzle [m], on a grid
#: spaced PARK_SPACING_RADII largest radii apart, and are re-pinned to their
#: slot once they have drifted PARK_DRIFT [m].
PARK_DISTANCE = 1.0
PARK_SPACING_RADII = 6.0
PARK_DRIFT = 0.2
#: A particle still in flight after this many times the longest flight time
#: (plus 20 steps) is counted lost and parked.
FLIGHT_TIMEOUT_FACTOR = 3.0
#: With particle-particle contacts a particle leaves the exit only when every
#: other particle out of the park is farther than this many steps times its
#: velocity jump at emission (beyond touching): that first step's acceleration
#: estimate must not see a contact (module docstring).
PP_CLEARANCE_STEPS = 1.5
#: Engines whose adapters give a sphere-sphere contact the geometry of first
#: touch (engines._sweep: the normal where the spheres meet within the step,
#: each body's own contact point on it), which the jet's particle-particle
#: contacts need (docs/jet.md "Particle-particle contacts").
PP_ENGINES = ("mujoco",)
PP_ENGINES_WHY = (
    "pybullet's adapter applies a pair's force at one contact point for both bodies, so it cannot take the "
    "normal of first touch when two beads close with a tangential velocity within a step (each body needs its "
    "own point on that normal); measured: a 53 deg bead-bead collision at 60 m/s, dt = 0.1 ms, solved as a "
    "80 deg one (a bead left at (-28.2, -9.7) m/s instead of (-13.4, -21.9) m/s). Use engine mujoco")
#: Direction vectors must be unit to this tolerance.
UNIT_TOL = 1e-3


# --------------------------------------------------------------------------
# Specification
# --------------------------------------------------------------------------
def _unit(name: str, v) -> np.ndarray:
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} = {list(v)!r} must be 3 finite numbers")
    n = float(np.linalg.norm(a))
    if abs(n - 1.0) > UNIT_TOL:
        raise ValueError(f"{name} = {list(v)!r} has norm {n:.6g}; it must be a unit vector "
                         f"(|norm - 1| <= {UNIT_TOL:g})")
    return a / n


@dataclass(frozen=True)
class Nozzle:
    """position: exit centre [m] (3,), above the plate (z > 0); direction:
    unit axis (3,) pointing at the plate (z component < 0); half_angle: cone
    half-angle [deg]; directions are uniform in solid angle inside the cone;
    diameter: exit diameter [m] (particles start uniformly over the exit disk)."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    half_angle: float = 20.0
    diameter: float = 0.0

    def __post_init__(self):
        p = np.asarray(self.position, dtype=float).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"nozzle.position = {self.position!r} m must be 3 finite numbers")
        if p[2] <= 0:
            raise ValueError(f"nozzle.position z = {p[2]!r} m must be > 0 (above the plate surface z = 0)")
        d = _unit("nozzle.direction", self.direction)
        if not 0.0 <= self.half_angle < 90.0:
            raise ValueError(f"nozzle.half_angle = {self.half_angle!r} deg must be in [0, 90)")
        if not (math.isfinite(self.diameter) and self.diameter >= 0):
            raise ValueError(f"nozzle.diameter = {self.diameter!r} m must be >= 0")
        a0 = math.degrees(math.asin(min(1.0, -d[2]))) if d[2] < 0 else -90.0
        if a0 - self.half_angle < MIN_CONE_ANGLE_DEG:
            raise ValueError(
                f"nozzle: the axis is {a0:.4g} deg to the plate and the cone half-angle {self.half_angle:g} deg; "
                f"every direction of the cone must be at least {MIN_CONE_ANGLE_DEG:g} deg to the plate "
                f"(axis angle - half_angle >= {MIN_CONE_ANGLE_DEG:g})")
        object.__setattr__(self, "position", tuple(float(v) for v in p))
        object.__setattr__(self, "direction", tuple(float(v) for v in d))

    @staticmethod
    def aimed(aim, direction, standoff: float, half_angle: float = 20.0, diameter: float = 0.0) -> "Nozzle":
        """The nozzle whose axis meets the plate at ``aim`` [m] (x, y) after
        ``standoff`` [m] along the axis."""
        if not (math.isfinite(standoff) and standoff > 0):
            raise ValueError(f"nozzle.standoff = {standoff!r} m must be > 0")
        d = _unit("nozzle.direction", direction)
        a = np.asarray(aim, dtype=float).reshape(-1)
        if a.shape != (2,) or not np.all(np.isfinite(a)):
            raise ValueError(f"nozzle.aim = {aim!r} m must be 2 finite numbers (x, y on the plate)")
        p = np.array([a[0], a[1], 0.0]) - standoff * d
        return Nozzle(tuple(p), tuple(d), half_angle, diameter)

    @property
    def axis(self) -> np.ndarray:
        return np.asarray(self.direction)

    @property
    def standoff(self) -> float:
        """Distance from the exit to the plate along the axis [m]."""
        return self.position[2] / -self.direction[2]

    @property
    def aim(self) -> np.ndarray:
        """Where the axis meets the plate [m] (3,)."""
        return np.asarray(self.position) + self.standoff * self.axis

    @property
    def axis_angle(self) -> float:
        """Angle of the axis to the plate [deg]."""
        return math.degrees(math.asin(-self.direction[2]))

    def basis(self) -> tuple[np.ndarray, np.ndarray]:
        """Two unit vectors e1, e2 normal to the axis (e1 x e2 = axis)."""
        d = self.axis
        e = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        e1 = np.cross(e, d)
        e1 /= np.linalg.norm(e1)
        return e1, np.cross(d, e1)


@dataclass(frozen=True)
class Particles:
    """material: msf_contact Material; radii [m] of the size classes (each
    class is one law object: the MSF law needs the curvature) with their
    probabilities; speed_mean, speed_sd [m/s] of a normal distribution
    truncated at SPEED_TRUNCATION_SD; feed_rate [particles/s]; arrival:
    "uniform" (every 1/feed_rate s) or "poisson"."""

    material: Any
    radii: tuple[float, ...]
    probabilities: tuple[float, ...]
    speed_mean: float = 30.0
    speed_sd: float = 3.0
    feed_rate: float = 1e5
    arrival: str = "uniform"

    def __post_init__(self):
        r = tuple(float(v) for v in self.radii)
        p = tuple(float(v) for v in self.probabilities)
        if not r:
            raise ValueError("particles.radius is empty: give at least one size class")
        if len(p) != len(r):
            raise ValueError(f"particles.probability has {len(p)} values; expected {len(r)} (one per radius)")
        for i, v in enumerate(r):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"particles.radius[{i}] = {v!r} m must be > 0")
        if len(set(r)) != len(r):
            raise ValueError(f"particles.radius = {list(r)!r} repeats a radius: merge the classes")
        if any(not (math.isfinite(v) and v >= 0) for v in p) or sum(p) <= 0:
            raise ValueError(f"particles.probability = {list(p)!r} must be >= 0 with a positive sum")
        s = sum(p)
        object.__setattr__(self, "radii", r)
        object.__setattr__(self, "probabilities", tuple(v / s for v in p))
        if not (math.isfinite(self.speed_mean) and self.speed_mean > 0):
            raise ValueError(f"particles.speed_mean = {self.speed_mean!r} m/s must be > 0")
        if not (math.isfinite(self.speed_sd) and self.speed_sd >= 0):
            raise ValueError(f"particles.speed_sd = {self.speed_sd!r} m/s must be >= 0")
        if self.speed_mean - SPEED_TRUNCATION_SD * self.speed_sd <= 0:
            raise ValueError(
                f"particles.speed_sd = {self.speed_sd!r} m/s: the slowest particle speed_mean - "
                f"{SPEED_TRUNCATION_SD:g} sd = {self.speed_mean - SPEED_TRUNCATION_SD * self.speed_sd:.6g} m/s "
                "must be > 0 (bound: speed_sd < speed_mean / 3)")
        if not (math.isfinite(self.feed_rate) and self.feed_rate > 0):
            raise ValueError(f"particles.feed_rate = {self.feed_rate!r} particles/s must be > 0")
        if self.arrival not in ARRIVALS:
            raise ValueError(f"particles.arrival = {self.arrival!r} is not one of {', '.join(ARRIVALS)}")

    @staticmethod
    def binned_normal(material, radius_mean: float, radius_sd: float, classes: int, **kw) -> "Particles":
        """Radii from a normal distribution (mean, sd [m]) truncated at
        RADIUS_TRUNCATION_SD sd and at 0, binned into ``classes`` equal-width
        classes: class radius = bin centre, probability = the bin's mass."""
        from scipy.stats import norm

        if not (math.isfinite(radius_mean) and radius_mean > 0):
            raise ValueError(f"particles.radius_mean = {radius_mean!r} m must be > 0")
        if not (math.isfinite(radius_sd) and radius_sd >= 0):
            raise ValueError(f"particles.radius_sd = {radius_sd!r} m must be >= 0")
        if int(classes) != classes or classes < 1:
            raise ValueError(f"particles.classes = {classes!r} must be a whole number >= 1")
        if radius_sd == 0 or classes == 1:
            return Particles(material, (radius_mean,), (1.0,), **kw)
        lo = max(radius_mean - RADIUS_TRUNCATION_SD * radius_sd, 0.0)
        hi = radius_mean + RADIUS_TRUNCATION_SD * radius_sd
        edges = np.linspace(lo, hi, int(classes) + 1)
        cdf = norm.cdf(edges, radius_mean, radius_sd)
        return Particles(material, tuple(0.5 * (edges[1:] + edges[:-1])), tuple(np.diff(cdf)), **kw)

    @property
    def v_max(self) -> float:
        """Fastest particle [m/s]."""
        return self.speed_mean + SPEED_TRUNCATION_SD * self.speed_sd

    @property
    def v_min(self) -> float:
        return self.speed_mean - SPEED_TRUNCATION_SD * self.speed_sd

    def mass(self, i: int) -> float:
        """Mass of a particle of class i [kg] (solid sphere)."""
        return 4.0 / 3.0 * math.pi * self.radii[i] ** 3 * self.material.density


@dataclass(frozen=True)
class Plate:
    """material: the plate's (coating's) Material; kind: "plane" (infinite
    half-space; ``size`` is the mapped area) or "box" (a fixed box whose top
    face, ``size`` [m] (2,) wide, is the plate; a sphere may not reach its
    edges); thickness of the box [m]; strength: the coating's strength [Pa]
    against which Pc_max is compared. The plate's centre is the origin."""

    material: Any
    kind: str = "plane"
    size: tuple[float, float] = (0.04, 0.04)
    thickness: float = 0.005
    strength: float = 10e6

    def __post_init__(self):
        if self.kind not in PLATE_KINDS:
            raise ValueError(f"plate.kind = {self.kind!r} is not one of {', '.join(PLATE_KINDS)}")
        s = tuple(float(v) for v in self.size)
        if len(s) != 2 or any(not (math.isfinite(v) and v > 0) for v in s):
            raise ValueError(f"plate.size = {list(self.size)!r} m must be two lengths > 0")
        object.__setattr__(self, "size", s)
        if not (math.isfinite(self.thickness) and self.thickness > 0):
            raise ValueError(f"plate.thickness = {self.thickness!r} m must be > 0")
        if not (math.isfinite(self.strength) and self.strength > 0):
            raise ValueError(f"plate.strength = {self.strength!r} Pa must be > 0")


@dataclass(frozen=True)
class Bins:
    """Fixed-size aggregate grids: angle bins over (0, 90] deg; the energy map
    over the plate's ``size`` in map_bins (nx, ny) cells; Pc_max bins
    log-spaced over pc_range [Pa]: 200 over 4 decades is 50 a decade, so a
    narrow spread of Pc_max fills a readable histogram (``make demo``'s jet,
    Pc_max 6.5-10.8 MPa over 804 impacts: 12 bins filled, 3 at 10 a decade;
    issue 12)."""

    angle_bins: int = 18
    map_bins: tuple[int, int] = (40, 40)
    pc_range: tuple[float, float] = (1e5, 1e9)
    pc_bins: int = 200

    def __post_init__(self):
        if int(self.angle_bins) != self.angle_bins or not 1 <= self.angle_bins <= 900:
            raise ValueError(f"aggregates.angle_bins = {self.angle_bins!r} must be a whole number in [1, 900]")
        mb = tuple(int(v) for v in self.map_bins)
        if len(mb) != 2 or any(v < 1 or v > 2000 for v in mb):
            raise ValueError(f"aggregates.map_bins = {list(self.map_bins)!r} must be two whole numbers in [1, 2000]")
        object.__setattr__(self, "map_bins", mb)
        lo, hi = (float(v) for v in self.pc_range)
        if not (0 < lo < hi < math.inf):
            raise ValueError(f"aggregates.pc_range = {list(self.pc_range)!r} Pa must be 0 < low < high")
        object.__setattr__(self, "pc_range", (lo, hi))
        if int(self.pc_bins) != self.pc_bins or not 1 <= self.pc_bins <= 1000:
            raise ValueError(f"aggregates.pc_bins = {self.pc_bins!r} must be a whole number in [1, 1000]")


@dataclass(frozen=True)
class JetSpec:
    """Everything a jet needs. law, law_options: a registry law of
    msf_contact and its options (e.g. ``{"omega": "self-consistent"}``),
    used for every particle-plate pair and, with ``particle_particle``, for
    pairs among pool members. dt: engine time step [s] (contacts of a few
    microseconds are sub-cycled by the adapters). gravity [m/s^2] along -z
    (0: off; over a flight of ~1 ms it changes the speed by ~1e-4 relative).
    pool: particles per size class (None: from the feed rate, POOL_SAFETY)."""

    nozzle: Nozzle
    particles: Particles
    plate: Plate
    law: str = "msf"
    law_options: dict = field(default_factory=dict)
    tangential: str = "contact-point"
    particle_particle: bool = False
    dt: float = 1e-4
    gravity: float = 0.0
    pool: int | None = None
    bins: Bins = field(default_factory=Bins)

    def __post_init__(self):
        from msf_contact.laws import get_law

        try:
            get_law(self.law)
        except ValueError as exc:
            raise ValueError(f"law.name: {exc}") from None
        if self.tangential not in ("contact-point", "paper"):
            raise ValueError(f"contact.tangential = {self.tangential!r} is not one of 'contact-point', 'paper'")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"run.dt = {self.dt!r} s must be > 0")
        if not (math.isfinite(self.gravity) and self.gravity >= 0):
            raise ValueError(f"run.gravity = {self.gravity!r} m/s^2 must be >= 0")
        if self.pool is not None and (int(self.pool) != self.pool or self.pool < 1):
            raise ValueError(f"run.pool = {self.pool!r} must be a whole number >= 1 (particles per size class)")
        gap = self.min_flight_distance()
        bound = gap / (MIN_FLIGHT_STEPS * self.particles.v_max)
        if self.dt > bound:
            raise ValueError(
                f"run.dt = {self.dt!r} s: the fastest particle ({self.particles.v_max:.4g} m/s) must need at least "
                f"{MIN_FLIGHT_STEPS:g} engine steps over the {gap:.4g} m from the nozzle to the plate "
                f"(bound: dt <= {bound:.4g} s; or raise the stand-off)")
        if self.plate.kind == "box":
            self._check_footprint()

    # -- geometry ------------------------------------------------------------
    @property
    def R_max(self) -> float:
        return max(self.particles.radii)

    def min_flight_distance(self) -> float:
        """Shortest free flight from the exit disk to a touch of the plate [m]:
        the exit's lowest point, height h, along the steepest direction."""
        nz = self.nozzle
        tilt = math.radians(90.0 - nz.axis_angle)  # axis from the normal
        h = nz.position[2] - 0.5 * nz.diameter * math.sin(tilt) - self.R_max
        if h <= 0:
            raise ValueError(f"nozzle: the exit (height {nz.position[2]:.4g} m, diameter {nz.diameter:g} m) is within "
                             f"one particle radius ({self.R_max:g} m) of the plate; raise nozzle.standoff")
        steep = math.radians(min(90.0, nz.axis_angle + nz.half_angle))
        return h / math.sin(steep)

    def max_flight_distance(self) -> float:
        """Longest free flight from the exit to the plate [m]."""
        nz = self.nozzle
        h = nz.position[2] + 0.5 * nz.diameter
        return h / math.sin(math.radians(nz.axis_angle - nz.half_angle))

    def footprint(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper (x, y) corner [m] of a box that holds every impact
        point of the cone on the plate (bounding the exit disk and the cone)."""
        nz = self.nozzle
        e1, e2 = nz.basis()
        pts = []
        rim = [np.cos(t) * e1 + np.sin(t) * e2 for t in np.linspace(0, 2 * np.pi, 73)]
        ca, sa = math.cos(math.radians(nz.half_angle)), math.sin(math.radians(nz.half_angle))
        for r in rim:
            start = np.asarray(nz.position) + 0.5 * nz.diameter * r
            for q in rim + [np.zeros(3)]:
                d = ca * nz.axis + sa * q if np.any(q) else nz.axis
                s = -start[2] / d[2]
                pts.append(start + s * d)
        pts = np.array(pts)[:, :2]
        return pts.min(axis=0), pts.max(axis=0)

    def _check_footprint(self):
        lo, hi = self.footprint()
        half = 0.5 * np.asarray(self.plate.size)
        # a sphere's centre must stay over the face, one radius plus a step's travel inside
        margin = 2.0 * self.R_max + self.particles.v_max * self.dt
        if np.any(lo < -half + margin) or np.any(hi > half - margin):
            raise ValueError(
                f"plate.size = {list(self.plate.size)!r} m: the jet's footprint on the plate spans x in "
                f"[{lo[0]:.4g}, {hi[0]:.4g}] m, y in [{lo[1]:.4g}, {hi[1]:.4g}] m; a box plate must hold it "
                f"with a margin of {margin:.3g} m to its edges (a sphere on a box edge is not a smooth contact)")

    # -- laws and bodies -------------------------------------------------------
    def pair(self):
        from msf_contact.materials import ContactPair

        return ContactPair(self.particles.material, self.plate.material)

    def _make(self, pair, curv):
        from msf_contact.laws import make_law

        try:
            return make_law(self.law, pair, curv, **self.law_options)
        except TypeError as exc:
            raise ValueError(f"law: {exc} (law {self.law!r}; the [law] keys other than name are its options)") from None

    def plate_laws(self) -> list:
        """One law per size class, particle (body 1) on the plate (body 2)."""
        import warnings

        from msf_contact.geometry import Curvature

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)  # validity: check_validity
            return [self._make(self.pair(), Curvature.sphere_on_plane(R)) for R in self.particles.radii]

    def pp_laws(self) -> dict[tuple[int, int], Any]:
        """Laws between particles of classes (i, j), body 1 of class i."""
        import warnings

        from msf_contact.geometry import Curvature
        from msf_contact.materials import ContactPair

        m = self.particles.material
        r = self.particles.radii
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            return {(i, j): self._make(ContactPair(m, m), Curvature.two_spheres(r[i], r[j]))
                    for i in range(len(r)) for j in range(len(r))}

    def check_validity(self) -> list[dict]:
        """The model's validity at the fastest particle of every size class
        (normal impact at v_max, reference solver). Raises ValueError naming
        the bound: tg(beta) of the pair <= 1/3 (100) for the MSF law, v_max
        below the sound speed, x_max < 2R. Returns one dict per class
        (radius, mass, v_max, x_max/R, tau, cor_n, Pc_max, tan_delta,
        sound_speed)."""
        import warnings

        from msf_contact._validate import TAN_DELTA_MAX
        from msf_contact.solver import Body, simulate_impact

        pair = self.pair()
        tg = pair.moduli().tan_delta
        if self.law == "msf" and tg > TAN_DELTA_MAX:
            raise ValueError(f"tg(beta) of the pair (91) = {tg:.4g} exceeds 1/3: outside the MSF validity (100) "
                             f"(particles.material {self.particles.material.name!r} on plate.material "
                             f"{self.plate.material.name!r})")
        c = pair.sound_speed()
        v = self.particles.v_max
        if v >= c:
            raise ValueError(f"particles: the fastest speed speed_mean + {SPEED_TRUNCATION_SD:g} sd = {v:.4g} m/s is "
                             f"at or above the sound speed sqrt(E'/rho) = {c:.4g} m/s of the softer body "
                             f"(bound v < {c:.4g})")
        out = []
        plate = Body.half_space(self.plate.material)
        for i, (R, law) in enumerate(zip(self.particles.radii, self.plate_laws())):
            ball = Body.sphere(self.particles.material, R)
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", ValidityWarning)  # the record lists it
                    rec = simulate_impact(law, ball, plate, v, 90.0)
            except ValueError as exc:
                raise ValueError(f"particles.radius[{i}] = {R:g} m at {v:.4g} m/s: {exc}") from None
            if rec.x_max >= 2 * R:
                raise ValueError(f"particles.radius[{i}] = {R:g} m at {v:.4g} m/s: x_max = {rec.x_max:.4g} m reaches "
                                 f"2R = {2 * R:.4g} m (bound x_max < 2R)")
            out.append({"class": i, "radius": R, "mass": ball.mass, "v_max": v, "x_max_over_R": rec.x_max / R,
                        "tau": rec.tau, "cor_n": rec.cor_n, "Pc_max": rec.Pc_max, "tan_delta": tg,
                        "sound_speed": c, "outside_validity": list(rec.outside_validity)})
        return out

    def busy_time(self) -> float:
        """Time a pool member is out of the park per emission [s], for the pool
        size: the longest flight at the mean speed, plus the contact, the
        record latency and one step to park."""
        return self.max_flight_distance() / self.particles.speed_mean + (RECORD_LATENCY_STEPS + 2) * self.dt

    def pool_sizes(self) -> list[int]:
        """Particles per size class: ``pool``, or POOL_SAFETY times the mean
        number of the class out of the park at once plus POOL_EXTRA (an
        emission that finds no free particle waits, ``JetCounts.pool_waits``)."""
        if self.pool is not None:
            return [int(self.pool)] * len(self.particles.radii)
        busy = self.busy_time()
        return [int(math.ceil(POOL_SAFETY * self.particles.feed_rate * p * busy)) + POOL_EXTRA
                for p in self.particles.probabilities]

    def flight_timeout(self) -> float:
        return FLIGHT_TIMEOUT_FACTOR * self.max_flight_distance() / self.particles.v_min + 20 * self.dt

    def park_velocity(self) -> np.ndarray:
        """Velocity of parked particles [m/s] (3,): the mean jet velocity."""
        return self.particles.speed_mean * self.nozzle.axis

    def park_positions(self, n: int) -> np.ndarray:
        """n parking slots [m] (n, 3): a square grid normal to the axis,
        PARK_DISTANCE upstream of the nozzle, spaced PARK_SPACING_RADII
        largest radii apart and, for particle-particle contacts, so far that
        the jump of a particle's velocity when it is parked (at most 2 v_max)
        cannot look like a contact with its neighbour (module docstring)."""
        e1, e2 = self.nozzle.basis()
        side = int(math.ceil(math.sqrt(n)))
        s = max(PARK_SPACING_RADII * self.R_max,
                2 * self.R_max + 2 * PP_CLEARANCE_STEPS * 2 * self.particles.v_max * self.dt)
        k = np.arange(n)
        c = np.asarray(self.nozzle.position) - PARK_DISTANCE * self.nozzle.axis
        return c + ((k % side) - 0.5 * side)[:, None] * s * e1 + ((k // side) - 0.5 * side)[:, None] * s * e2
