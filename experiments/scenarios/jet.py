"""Abrasive jet: a nozzle shoots particles at a plate (or coating); every
particle-plate contact is an MSF (or other registry law) contact inside
MuJoCo or pybullet, and a fixed pool of bodies is recycled so that memory
does not grow with the number of impacts.

The paper names abrasive-jet wear as its application. Per impact this
scenario keeps the impact record of the engine (cor_n, cor_t, tau, x_max,
F_max, Pc_max, W_diss_n, W_diss_t, ...), the impact point on the plate and
the impact angle to the plate; in memory only fixed-size aggregates
(:class:`JetAggregates`): COR and dissipated energy against the impact angle,
the map of dissipated energy per unit area [J/m^2] (the wear proxy), and the
histogram of the peak contact pressure Pc_max against the coating's strength.
Finnie's (1960) angle function is drawn next to the dissipated energy against
angle for comparison (:func:`finnie`).

Geometry and units (SI throughout): the plate's surface is z = 0 with its
normal +z; the nozzle sits above it and points down. Angles to the plate in
degrees (90 = normal incidence).

Layers:

- :class:`JetSpec` (frozen, validated): nozzle, particles, plate, law, time
  step. :meth:`JetSpec.check_validity` checks the model's validity for every
  size class at the fastest particle: tg(beta) <= 1/3 (100), the impact speed
  below the sound speed, x_max < 2R (reference solver), and refuses with a
  message naming the bound.
- :class:`JetPool`: the jet's driver (emission schedule, flight checks,
  record bookkeeping, aggregates) over an engine's recycled pool of spheres
  (:class:`engines.pool.SpherePool`: the bodies, the park, the adapter;
  MuJoCo or pybullet); use :func:`make_pool`.
- The scenario ``jet`` for ``msf-contact run`` (TOML, see
  ``experiments/configs/jet.toml``): one cell per (engine, chunk of impacts).

Why the pool parks particles with the mean jet velocity. The adapters
estimate the external acceleration of a contact from the change of the
relative velocity over the last step, so teleporting a particle to the
nozzle with a new velocity looks, for one step, like an acceleration
(v_new - v_old)/dt. Parked particles therefore move with the mean jet
velocity (their position is re-pinned, their velocity kept), so the jump at
emission is only the dispersion of speeds and directions; and the time step
is refused unless the fastest particle needs at least
``MIN_FLIGHT_STEPS`` steps from the nozzle to the plate, so that the one
step with a wrong estimate is spent in free flight.
"""

from __future__ import annotations

import bisect
import json
import math
import os
import resource
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from engines.pool import DONE, FLIGHT, PARKED, PlateShape, SphereScene, sphere_pool_class
from msf_contact import ValidityWarning

from ..config import ConfigError, Field, build_material, material_fields, validate
from . import Scenario, register

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
#: Why particle-particle contacts are experimental (measured; docs/jet.md).
PP_LIMIT = (
    "particle-particle contacts are experimental: the adapters estimate a contact's external acceleration "
    "from the change of its relative velocity over the last step, so the impulse of a particle-particle "
    "contact looks, on the same particle's plate pair in the next step, like an acceleration of ~1e5-1e6 "
    "m/s^2 (a rebounding bead meeting an incoming one drove a plate impact to 110 m/s in a test); the "
    "estimate must exclude the impulses of the adapter's other pairs (engines/*/adapter.py)")
#: Direction vectors must be unit to this tolerance.
UNIT_TOL = 1e-3


# --------------------------------------------------------------------------
# Finnie's angle function
# --------------------------------------------------------------------------
def finnie(angle_deg) -> np.ndarray:
    """Finnie's angle function of ductile erosion, normalised to its maximum
    (1 at 16.85 deg): f(a) = sin(2a) - 3 sin^2(a) for tan(a) <= 1/3
    (a <= 18.43 deg), cos^2(a)/3 above.

    I. Finnie, "Erosion of surfaces by solid particles", Wear 3 (1960) 87-103,
    the volume removed by one particle cutting a ductile surface (with the
    ratio of vertical to horizontal force K = 2 and the contact depth ratio
    l/y = 2 of that paper, which give the 1/3 and the 3 above). Shown for
    comparison with the dissipated energy against angle; it is a cutting
    model, not a consequence of the MSF law.
    """
    a = np.radians(np.asarray(angle_deg, dtype=float))
    low = np.sin(2 * a) - 3.0 * np.sin(a) ** 2
    high = np.cos(a) ** 2 / 3.0
    f = np.where(np.tan(a) <= 1.0 / 3.0, low, high)
    a_max = 0.5 * math.atan(2.0 / 3.0)  # d/da (sin 2a - 3 sin^2 a) = 0
    return f / (math.sin(2 * a_max) - 3.0 * math.sin(a_max) ** 2)


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
    log-spaced over pc_range [Pa]."""

    angle_bins: int = 18
    map_bins: tuple[int, int] = (40, 40)
    pc_range: tuple[float, float] = (1e5, 1e9)
    pc_bins: int = 40

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


# --------------------------------------------------------------------------
# Aggregates (fixed size)
# --------------------------------------------------------------------------
class JetAggregates:
    """Fixed-size aggregates of plate impacts (memory independent of their number).

    Arrays (all sums, so aggregates of chunks add up):
    angle_edges [deg] (na + 1,); per angle bin: n, cor_n sum and sum of
    squares, cor_t count and sum, W (W_diss_n + W_diss_t) [J], W_n, W_t,
    E_in (incoming kinetic energy) [J], W/E_in sum [-];
    map_edges_x, map_edges_y [m]; map_W [J] (nx, ny) and map_n (nx, ny);
    off_map_W [J], off_map_n; pc_edges [Pa] (npc + 1,), pc_counts (npc + 2,)
    with under- and overflow at both ends; n_above_strength; Pc_max_max [Pa];
    per size class n and W [J]; totals.
    """

    _ARRAYS = ("a_n", "a_cor", "a_cor2", "a_nt", "a_cort", "a_W", "a_Wn", "a_Wt", "a_E", "a_frac", "map_W", "map_n",
               "pc_counts", "cls_n", "cls_W")
    _SCALARS = ("n", "W_n", "W_t", "E_in", "off_map_W", "off_map_n", "n_above_strength", "Pc_max_max",
                "n_outside_validity", "n_repeat")

    def __init__(self, bins: Bins, plate_size, strength: float, n_classes: int):
        self.bins = bins
        self.strength = float(strength)
        na = bins.angle_bins
        nx, ny = bins.map_bins
        self.angle_edges = np.linspace(0.0, 90.0, na + 1)
        hx, hy = 0.5 * float(plate_size[0]), 0.5 * float(plate_size[1])
        self.map_edges_x = np.linspace(-hx, hx, nx + 1)
        self.map_edges_y = np.linspace(-hy, hy, ny + 1)
        self.pc_edges = np.geomspace(bins.pc_range[0], bins.pc_range[1], bins.pc_bins + 1)
        for k in ("a_n", "a_nt"):
            setattr(self, k, np.zeros(na, np.int64))
        for k in ("a_cor", "a_cor2", "a_cort", "a_W", "a_Wn", "a_Wt", "a_E", "a_frac"):
            setattr(self, k, np.zeros(na))
        self.map_W = np.zeros((nx, ny))
        self.map_n = np.zeros((nx, ny), np.int64)
        self.pc_counts = np.zeros(bins.pc_bins + 2, np.int64)
        self.cls_n = np.zeros(n_classes, np.int64)
        self.cls_W = np.zeros(n_classes)
        self.n = self.off_map_n = self.n_above_strength = self.n_outside_validity = self.n_repeat = 0
        self.W_n = self.W_t = self.E_in = self.off_map_W = self.Pc_max_max = 0.0

    @property
    def cell_area(self) -> float:
        """Area of one map cell [m^2]."""
        return float(np.diff(self.map_edges_x)[0] * np.diff(self.map_edges_y)[0])

    #: The per-impact values the aggregates read (keys of the impact rows, :meth:`JetPool.run`).
    COLUMNS = ("angle_deg", "cor_n", "cor_t", "W_diss_n", "W_diss_t", "E_in", "x", "y", "Pc_max", "cls",
               "outside_validity", "repeat")

    def add(self, rows: Sequence[dict]) -> None:
        """Add plate-impact rows (dicts with the keys ``COLUMNS``, as the impact
        rows of :meth:`JetPool.run`; cor_t may be None)."""
        if not rows:
            return
        cols = {k: [r[k] for r in rows] for k in self.COLUMNS}
        cols["cor_t"] = [np.nan if v is None else v for v in cols["cor_t"]]
        cols["outside_validity"] = [bool(v) for v in cols["outside_validity"]]
        self.add_columns({k: np.asarray(v) for k, v in cols.items()})

    def add_columns(self, cols: dict[str, np.ndarray]) -> None:
        """Add k plate impacts given as columns (k,) under the keys ``COLUMNS``:
        angle_deg [deg], cor_n, cor_t (NaN: none), W_diss_n, W_diss_t, E_in [J],
        x, y [m], Pc_max [Pa], cls, outside_validity and repeat (bool)."""
        ang = np.asarray(cols["angle_deg"], dtype=float)
        if ang.size == 0:
            return
        cor = np.asarray(cols["cor_n"], dtype=float)
        cort = np.asarray(cols["cor_t"], dtype=float)
        Wn = np.asarray(cols["W_diss_n"], dtype=float)
        Wt = np.asarray(cols["W_diss_t"], dtype=float)
        E = np.asarray(cols["E_in"], dtype=float)
        x = np.asarray(cols["x"], dtype=float)
        y = np.asarray(cols["y"], dtype=float)
        pc = np.asarray(cols["Pc_max"], dtype=float)
        cls = np.asarray(cols["cls"], dtype=int)
        W = Wn + Wt
        na = self.bins.angle_bins
        ia = np.clip(np.searchsorted(self.angle_edges, ang, side="left") - 1, 0, na - 1)  # (a0, a1] bins
        np.add.at(self.a_n, ia, 1)
        np.add.at(self.a_cor, ia, cor)
        np.add.at(self.a_cor2, ia, cor * cor)
        ok = np.isfinite(cort)
        np.add.at(self.a_nt, ia[ok], 1)
        np.add.at(self.a_cort, ia[ok], cort[ok])
        np.add.at(self.a_W, ia, W)
        np.add.at(self.a_Wn, ia, Wn)
        np.add.at(self.a_Wt, ia, Wt)
        np.add.at(self.a_E, ia, E)
        np.add.at(self.a_frac, ia, W / E)
        nx, ny = self.bins.map_bins
        ix = np.searchsorted(self.map_edges_x, x, side="right") - 1
        iy = np.searchsorted(self.map_edges_y, y, side="right") - 1
        on = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        np.add.at(self.map_W, (ix[on], iy[on]), W[on])
        np.add.at(self.map_n, (ix[on], iy[on]), 1)
        self.off_map_W += float(W[~on].sum())
        self.off_map_n += int((~on).sum())
        ip = np.searchsorted(self.pc_edges, pc, side="right")  # 0: underflow, npc + 1: overflow
        np.add.at(self.pc_counts, ip, 1)
        self.n_above_strength += int((pc > self.strength).sum())
        self.Pc_max_max = max(self.Pc_max_max, float(pc.max()))
        np.add.at(self.cls_n, cls, 1)
        np.add.at(self.cls_W, cls, W)
        self.n += int(ang.size)
        self.W_n += float(Wn.sum())
        self.W_t += float(Wt.sum())
        self.E_in += float(E.sum())
        self.n_outside_validity += int(np.count_nonzero(cols["outside_validity"]))
        self.n_repeat += int(np.count_nonzero(cols["repeat"]))

    def merge(self, other: "JetAggregates") -> None:
        for k in self._ARRAYS:
            getattr(self, k).__iadd__(getattr(other, k))
        for k in self._SCALARS:
            if k == "Pc_max_max":
                self.Pc_max_max = max(self.Pc_max_max, other.Pc_max_max)
            else:
                setattr(self, k, getattr(self, k) + getattr(other, k))

    def to_dict(self) -> dict:
        d = {k: getattr(self, k).tolist() for k in self._ARRAYS}
        d.update({k: getattr(self, k) for k in self._SCALARS})
        d.update(strength=self.strength, plate_size=[float(self.map_edges_x[-1] * 2), float(self.map_edges_y[-1] * 2)],
                 bins={"angle_bins": self.bins.angle_bins, "map_bins": list(self.bins.map_bins),
                       "pc_range": list(self.bins.pc_range), "pc_bins": self.bins.pc_bins})
        return d

    @staticmethod
    def from_dict(d: dict) -> "JetAggregates":
        b = d["bins"]
        a = JetAggregates(Bins(b["angle_bins"], tuple(b["map_bins"]), tuple(b["pc_range"]), b["pc_bins"]),
                          d["plate_size"], d["strength"], len(d["cls_n"]))
        for k in JetAggregates._ARRAYS:
            getattr(a, k)[...] = np.asarray(d[k], dtype=getattr(a, k).dtype)
        for k in JetAggregates._SCALARS:
            setattr(a, k, d[k])
        return a

    # -- derived ---------------------------------------------------------------
    def energy_density(self) -> np.ndarray:
        """Dissipated energy per unit area of the plate [J/m^2] (nx, ny): the wear proxy."""
        return self.map_W / self.cell_area

    def by_angle(self) -> dict[str, np.ndarray]:
        """Per angle bin: centre [deg], n, mean and sd of cor_n, mean cor_t,
        mean dissipated energy per impact [J], mean dissipated fraction W/E_in."""
        n = self.a_n.astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self.a_cor / n
            sd = np.sqrt(np.maximum(self.a_cor2 / n - mean**2, 0.0))
            return {"centre": 0.5 * (self.angle_edges[1:] + self.angle_edges[:-1]), "n": self.a_n,
                    "cor_n": mean, "cor_n_sd": sd, "cor_t": self.a_cort / self.a_nt.astype(float),
                    "W": self.a_W / n, "W_n": self.a_Wn / n, "W_t": self.a_Wt / n, "fraction": self.a_frac / n}


# --------------------------------------------------------------------------
# The pool driver (engine-agnostic part)
# --------------------------------------------------------------------------
#: On a plane plate without particle-particle contacts the positions of the
#: particles in flight are read every this many steps (the checks for a
#: particle that flew off upward or passed through the plate are safety
#: checks there: timeouts are checked every step, and a particle is parked
#: after its record, not on its position); a box plate or particle-particle
#: contacts read them every step (an edge of the box must not be reached).
POSITION_CHECK_STEPS = 10
#: Plate impacts held (as columns) before they are added to the aggregates,
#: whose np.add.at calls have a fixed cost per call [impacts].
IMPACT_BUFFER = 4096


class _ImpactBuffer:
    """The last plate impacts (at most IMPACT_BUFFER), kept as the column
    dicts of their steps and added to ``aggregates`` together when full and
    on :meth:`flush`."""

    def __init__(self, aggregates: JetAggregates, size: int = IMPACT_BUFFER):
        self.aggregates = aggregates
        self.size = size
        self.count = 0
        self._parts: list[dict] = []

    def append(self, cols: dict) -> None:
        self._parts.append(cols)
        self.count += len(cols["angle_deg"])
        if self.count >= self.size:
            self.flush()

    def flush(self) -> None:
        if self._parts:
            parts, self._parts, self.count = self._parts, [], 0
            self.aggregates.add_columns({k: np.concatenate([np.asarray(c[k]) for c in parts])
                                         for k in JetAggregates.COLUMNS})


@dataclass(slots=True)
class _Emission:
    """One particle leaving the nozzle: time [s], class, start [m] and
    velocity [m/s] (3-tuples of floats)."""

    t: float
    cls: int
    p: tuple[float, float, float]
    v: tuple[float, float, float]
    waited: bool = False
    blocked: bool = False


class Emitter:
    """The deterministic sequence of emissions of a seed: arrival times
    (uniform or Poisson at the feed rate), size class, speed (truncated
    normal), direction (uniform in solid angle in the cone), start point
    (uniform over the exit disk). Independent of the engine, so both engines
    see the same particles for the same seed.

    Per emission the draws are, in this order: an exponential gap (Poisson
    arrivals only), one uniform for the class (more than one class; the
    inverse of the classes' cumulative probabilities, as
    ``Generator.choice`` with ``p``), standard normals until one lies within
    SPEED_TRUNCATION_SD (speed_sd > 0), and four uniforms (cone angle and
    azimuth, exit radius and azimuth). Scalar draws and float arithmetic."""

    def __init__(self, spec: JetSpec, seed):
        self.spec = spec
        seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.rng = np.random.default_rng(seq)
        self.e1, self.e2 = spec.nozzle.basis()
        self.count = 0
        self._t = 0.0
        self._offset = 0.0
        sp, nz = spec.particles, spec.nozzle
        cdf = np.asarray(sp.probabilities, dtype=float).cumsum()
        cdf /= cdf[-1]
        self._cdf = cdf.tolist()
        self._axis = tuple(nz.direction)
        self._b1, self._b2 = tuple(self.e1.tolist()), tuple(self.e2.tolist())
        self._cos_half = math.cos(math.radians(nz.half_angle))
        self._r_exit = 0.5 * nz.diameter
        self._exit = tuple(nz.position)

    def shift(self, delay: float) -> None:
        """Delay every later emission by ``delay`` [s]."""
        self._offset += float(delay)

    def next(self) -> _Emission:
        sp, rng = self.spec.particles, self.rng
        if sp.arrival == "uniform":
            t = (self.count + 0.5) / sp.feed_rate + self._offset
        else:
            self._t += rng.exponential(1.0 / sp.feed_rate)
            t = self._t + self._offset
        cls = bisect.bisect_right(self._cdf, rng.random()) if len(self._cdf) > 1 else 0
        v = sp.speed_mean
        if sp.speed_sd > 0:
            while True:
                z = rng.standard_normal()
                if abs(z) <= SPEED_TRUNCATION_SD:
                    break
            v = sp.speed_mean + z * sp.speed_sd
        u1, u2, u3, u4 = rng.random(4).tolist()  # the same stream as four scalar draws
        cos_a = 1.0 - u1 * (1.0 - self._cos_half)
        sin_a = math.sqrt(max(0.0, 1.0 - cos_a * cos_a))
        phi = 2.0 * math.pi * u2
        r = self._r_exit * math.sqrt(u3)
        psi = 2.0 * math.pi * u4
        cp, sp_, cq, sq = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2), (x0, x1, x2) = self._axis, self._b1, self._b2, self._exit
        self.count += 1
        return _Emission(t, cls, (x0 + r * (cq * b0 + sq * c0), x1 + r * (cq * b1 + sq * c1), x2 + r * (cq * b2 + sq * c2)),
                         (v * (cos_a * a0 + sin_a * (cp * b0 + sp_ * c0)), v * (cos_a * a1 + sin_a * (cp * b1 + sp_ * c1)),
                          v * (cos_a * a2 + sin_a * (cp * b2 + sp_ * c2))))


@dataclass
class JetCounts:
    """Counters of a pool run."""

    emitted: int = 0
    impacts: int = 0  # plate records
    pp_impacts: int = 0  # particle-particle records
    pp_W: float = 0.0  # energy dissipated in particle-particle contacts [J]
    lost: int = 0  # parked without an impact (left the domain or timed out)
    pool_waits: int = 0  # emissions delayed for want of a free particle of their class
    blocked: int = 0  # emissions delayed because another particle was at the exit (particle-particle contacts)
    steps: int = 0


class JetPool:
    """A fixed pool of particles recycled through a jet, in one engine.

    engine: "mujoco" or "pybullet"; spec: the :class:`JetSpec`; seed: int or
    sequence of ints (the emission sequence, :class:`Emitter`); validate: run
    :meth:`JetSpec.check_validity` first (the result is in ``validity``);
    ``options``: the engine pool's own (MuJoCo: ``integrator``).

    :meth:`run` advances until a number of plate impacts is reached, calling
    ``sink(rows)`` with the per-impact rows of every engine step (plain
    dicts, see :meth:`_collect`) and adding them to ``aggregates``
    (:class:`JetAggregates`); only those fixed-size aggregates and the pool's
    own arrays stay in memory. Records are popped from the adapter every step.

    The bodies are an :class:`engines.pool.SpherePool` (``bodies``: the
    engine's recycled spheres, the park, the plate and the adapter; pair i
    = (particle i, plate), then the particle-particle pairs); this class
    adds the jet: emission from the nozzle, flight checks, the records'
    conversion to impacts and the aggregates.
    """

    def __init__(self, engine: str, spec: JetSpec, seed=0, *, validate: bool = True, **options):
        pool_class = sphere_pool_class(engine)
        _check_spheres(pool_class, spec)
        self.engine = engine
        self.spec = spec
        self.validity = spec.check_validity() if validate else None
        if spec.particle_particle:
            import warnings

            warnings.warn(PP_LIMIT, UserWarning, stacklevel=2)
        sizes = spec.pool_sizes()
        cls = np.repeat(np.arange(len(sizes)), sizes)
        n = int(cls.size)
        self.emission_id = np.full(n, -1, np.int64)
        self.t_emit = np.zeros(n)
        self.p_emit = np.zeros((n, 3))
        self.v_emit = np.zeros((n, 3))
        self.deflected = np.zeros(n, bool)  # touched another particle since emission
        self.emitter = Emitter(spec, seed)
        self._pending: _Emission | None = None
        self.counts = JetCounts()
        self.aggregates = JetAggregates(spec.bins, spec.plate.size, spec.plate.strength, len(sizes))
        self._g = np.array([0.0, 0.0, -spec.gravity])
        v_park = spec.park_velocity()
        self._v_park = v_park
        self._impacts = _ImpactBuffer(self.aggregates)
        self._timeout = spec.flight_timeout()
        self._z_away = spec.nozzle.position[2] + 0.5 * PARK_DISTANCE  # a particle above this flew off upward
        repin_after = PARK_DRIFT / (float(np.linalg.norm(v_park)) + 1e-300)
        if spec.gravity > 0:
            repin_after = min(repin_after, math.sqrt(2 * PARK_DRIFT / spec.gravity))
        self.cpu_s = 0.0
        self.wall_s = 0.0
        scene = SphereScene(
            cls=cls, radius=np.asarray(spec.particles.radii)[cls],
            mass=np.array([spec.particles.mass(int(c)) for c in cls]), laws=spec.plate_laws(),
            park=spec.park_positions(n), park_velocity=v_park, repin_after=repin_after,
            plate=PlateShape(spec.plate.kind, spec.plate.size, spec.plate.thickness), dt=spec.dt,
            gravity=spec.gravity, tangential=spec.tangential,
            pp_laws=spec.pp_laws() if spec.particle_particle else None)
        self.bodies = pool_class(scene, **options)
        b = self.bodies
        self.n, self.cls, self.radius, self.mass, self.state = b.n, b.cls, b.radius, b.mass, b.state
        self.pp_pairs = b.pp_pairs
        self._half_mass = 0.5 * self.mass

    @property
    def adapter(self):
        return self.bodies.adapter

    @property
    def time(self) -> float:
        return self.bodies.time

    def close(self) -> None:
        self.bodies.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    # -- the loop ------------------------------------------------------------------
    @property
    def in_flight(self) -> int:
        return self.bodies.in_flight

    def run(self, impacts: int, sink: Callable[[list[dict]], None] | None = None, progress: bool | None = False,
            max_steps: int | None = None) -> JetCounts:
        """Advance until ``impacts`` plate impacts in total (counting earlier
        calls) and no particle in flight. Emission stops once impacts plus
        particles in flight reach the target. ``progress``: a tqdm bar on
        stderr (None: only on a terminal). RuntimeError after ``max_steps``
        steps of this call (default: ten times the steps the feed rate
        needs, plus 1000). Without a sink no row dicts are built (the
        aggregates read the records directly); the aggregates are complete
        when run returns."""
        if int(impacts) != impacts or impacts < 0:
            raise ValueError(f"impacts = {impacts!r} must be a whole number >= 0")
        dt = self.spec.dt
        if max_steps is None:
            need = max(0, impacts - self.counts.impacts) / (self.spec.particles.feed_rate * dt)
            max_steps = int(10 * need) + 1000 + int(10 * self._timeout / dt)
        bar = None
        if progress or progress is None:
            from tqdm import tqdm

            bar = tqdm(total=int(impacts), initial=self.counts.impacts, desc=f"jet {self.engine}", unit="impact",
                       file=sys.stderr, disable=None if progress is None else False, dynamic_ncols=True, leave=False)
        c0, w0 = time.process_time(), time.perf_counter()
        steps = 0
        bodies = self.bodies
        try:
            while True:
                t = bodies.time
                self._emit(t, impacts)
                if self._pending is None and self.counts.impacts >= impacts and bodies.in_flight == 0:
                    break
                bodies.repin(t)
                bodies.step()
                self.counts.steps += 1
                steps += 1
                n_plate, rows = self._collect(rows=sink is not None)
                if rows:
                    sink(rows)
                if bar is not None and n_plate:
                    bar.update(n_plate)
                self._check_flight()
                bodies.park_done()
                if steps >= max_steps:
                    raise RuntimeError(f"the jet did not reach {impacts} impacts within {max_steps} steps "
                                       f"({self.counts.impacts} impacts, {self.in_flight} particles out)")
        finally:
            self._impacts.flush()
            self.cpu_s += time.process_time() - c0
            self.wall_s += time.perf_counter() - w0
            if bar is not None:
                bar.close()
        return self.counts

    def _emit(self, t: float, target: int) -> None:
        """Place every emission due by time t (started at the exit at its own
        time, advanced ballistically to t); draw emissions only while impacts
        plus particles in flight stay below ``target``. An emission that finds
        no free particle of its class waits (counted in ``pool_waits``). The
        emissions of one call are placed in the engine together."""
        dt = self.spec.dt
        flying = int(np.count_nonzero(self.state == FLIGHT))
        launch: list[tuple[int, _Emission, float]] = []
        try:
            while True:
                if self._pending is None:
                    if self.counts.impacts + flying >= target:
                        return
                    self._pending = self.emitter.next()
                e = self._pending
                if e.t > t + 1e-9 * dt:
                    return
                free = self.bodies.free[e.cls]
                if not free:
                    if not e.waited:
                        self.counts.pool_waits += 1
                        e.waited = True
                    return
                late = t - e.t
                if late > dt:
                    # late by more than the step it fell into (a pool wait, or a pause between
                    # run() calls): it leaves now, and the whole schedule moves with it
                    self.emitter.shift(late)
                    e.t, late = t, 0.0
                if self.spec.particle_particle:
                    self._launch(launch)  # _clear reads the engine's centres
                    launch = []
                    p = np.asarray(e.p) + np.asarray(e.v) * late + 0.5 * self._g * late * late
                    v = np.asarray(e.v) + self._g * late
                    if not self._clear(p, v, float(self.spec.particles.radii[e.cls])):
                        if not e.blocked:
                            self.counts.blocked += 1
                            e.blocked = True
                        return
                launch.append((free.popleft(), e, late))
                self._pending = None
                flying += 1
        finally:
            self._launch(launch)

    def _launch(self, launch: list[tuple[int, _Emission, float]]) -> None:
        """Put particles i at their emissions, ``late`` [s] after leaving the exit."""
        if not launch:
            return
        idx = np.array([i for i, _, _ in launch])
        a = np.array([(e.t, *e.p, *e.v, late) for _, e, late in launch])  # (k, 8)
        p0, v0, late = a[:, 1:4], a[:, 4:7], a[:, 7:8]
        if self.spec.gravity > 0:
            self.bodies.launch(idx, p0 + v0 * late + 0.5 * self._g * late * late, v0 + self._g * late)
        else:
            self.bodies.launch(idx, p0 + v0 * late, v0)
        self.emission_id[idx] = self.counts.emitted + np.arange(idx.size)
        self.t_emit[idx] = a[:, 0]
        self.p_emit[idx] = p0
        self.v_emit[idx] = v0
        self.deflected[idx] = False
        self.counts.emitted += int(idx.size)

    def _clear(self, p: np.ndarray, v: np.ndarray, R: float) -> bool:
        """With particle-particle contacts: may a particle of radius R start at
        p [m] with velocity v [m/s]? Not if it would overlap a particle out of
        the park, or come within PP_CLEARANCE_STEPS steps of its velocity jump
        from the park (the adapters' one-step acceleration estimate)."""
        out = np.flatnonzero(self.state != PARKED)
        if out.size == 0:
            return True
        d = np.linalg.norm(self.bodies.centres(out) - p, axis=1) - self.radius[out] - R
        reach = PP_CLEARANCE_STEPS * float(np.linalg.norm(v - self._v_park)) * self.spec.dt
        return bool(np.all(d > reach))

    def _check_flight(self) -> None:
        """Particles that timed out without an impact (every step) or left the
        domain (positions read every POSITION_CHECK_STEPS steps on a plane
        plate without particle-particle contacts, else every step): lost."""
        fl = np.flatnonzero(self.state == FLIGHT)
        if fl.size == 0:
            return
        t = self.bodies.time
        lost = (t - self.t_emit[fl]) > self._timeout
        box = self.spec.plate.kind == "box"
        if box or self.spec.particle_particle or self.counts.steps % POSITION_CHECK_STEPS == 0:
            c = self.bodies.centres(fl)
            lost |= c[:, 2] > self._z_away  # flew off upward
            if c[:, 2].min() < -self.radius[fl].max():
                i = int(fl[np.argmin(c[:, 2])])
                raise RuntimeError(f"particle {i} passed through the plate (centre z = {c[:, 2].min():.4g} m): "
                                   "the contact was missed")
            if box:
                half = 0.5 * np.asarray(self.spec.plate.size)
                margin = (2.0 * self.radius[fl] + 2.0 * np.linalg.norm(self.v_emit[fl], axis=1) * self.spec.dt)
                lost |= np.any(np.abs(c[:, :2]) > half - margin[:, None], axis=1)
        if np.any(lost):
            idx = fl[lost]
            idx = idx[~self.bodies.required()[idx]]
            if idx.size:
                self.counts.lost += int(idx.size)
                self.bodies.park_now(idx, t)

    # -- records -> rows -------------------------------------------------------------
    def _collect(self, rows: bool) -> tuple[int, list[dict]]:
        """Pop the adapter's records: add the plate impacts to the aggregates
        (through the impact buffer) and count them; with ``rows``, also return
        one row dict per record (kind "impact" or "particle-particle").
        Returns (plate impacts, rows).

        The plate impacts of one step are converted together. A particle's
        first impact after emission is ballistic from the exit, so the
        incoming velocity is v_emit + g (t_onset - t_emit) and the impact
        point is the centre at t_onset minus R n (exact, while the record's
        own point is the contact point at the start of the onset step). After
        a particle-particle contact, or for a repeated impact, the record's
        speeds and point are used."""
        recs = self.adapter.pop_records()
        if not recs:
            return 0, []
        out: list[dict | None] = []
        plate, where, idx, repeat, deflected, flat = [], [], [], [], [], []
        state, defl, n = self.state, self.deflected, self.n
        in_order = bool(self.pp_pairs)  # flags per record in order: a pp record may precede a plate one
        for rec in recs:
            d = rec.inputs
            pair = int(d["pair"])
            if pair < n:
                if in_order:
                    # a repeat: the particle's record arrived before (also earlier in this step) or it was parked
                    repeat.append(state[pair] != FLIGHT or pair in idx)
                    deflected.append(bool(defl[pair]))
                idx.append(pair)
                plate.append(rec)
                where.append(len(out))
                out.append(None)
                flat += d["normal"]
                flat += d["point"]
                flat += (d["t_onset"], d["v_n_in"], d["v_t_in"], rec.cor_n, np.nan if rec.cor_t is None else rec.cor_t,
                         rec.W_diss_n, rec.W_diss_t, rec.Pc_max)
                continue
            i, j = self.pp_pairs[pair - n]
            defl[[i, j]] = True
            self.counts.pp_impacts += 1
            self.counts.pp_W += rec.W_diss_n + rec.W_diss_t
            if rows:
                out.append({"kind": "particle-particle", "p1": i, "p2": j, "emission1": int(self.emission_id[i]),
                            "emission2": int(self.emission_id[j]), "t_onset": d["t_onset"], "v_n_in": d["v_n_in"],
                            "cor_n": rec.cor_n, "W_diss_n": rec.W_diss_n, "W_diss_t": rec.W_diss_t,
                            "engine": self.engine})
        if not plate:
            return 0, out if rows else []
        k = len(plate)
        if in_order:
            repeat, deflected = np.array(repeat, bool), np.array(deflected, bool)
            idx = np.array(idx)
        else:
            twice = len(set(idx)) < k
            idx = np.array(idx)
            repeat, deflected = state[idx] != FLIGHT, defl[idx]
            if twice:  # a second record of a particle within the step is a repeat too
                for m in range(1, k):
                    repeat[m] |= bool(np.any(idx[:m] == idx[m]))
        first = ~(repeat | deflected)
        f = np.array(flat, dtype=float).reshape(k, 14)
        normal, p_rec = f[:, 0:3], f[:, 3:6]
        t_on, vn_rec, vt_rec = f[:, 6], f[:, 7], f[:, 8]
        # ballistic from the exit (first impacts)
        s = (t_on - self.t_emit[idx])[:, None]
        v_emit = self.v_emit[idx]
        if self.spec.gravity > 0:
            v_in = v_emit + self._g * s
            centre = self.p_emit[idx] + v_emit * s + 0.5 * self._g * s * s
        else:
            v_in, centre = v_emit, self.p_emit[idx] + v_emit * s
        speed = np.sqrt((v_in * v_in).sum(axis=1))
        vn = -(v_in * normal).sum(axis=1)
        point = centre - self.radius[idx][:, None] * normal
        # the angle to the plate [deg] with math's asin/atan2 (numpy's may differ in the last bit)
        if first.all():
            angle = np.array([math.degrees(math.asin(min(1.0, max(0.0, a / b))))
                              for a, b in zip(vn.tolist(), speed.tolist())])
        else:  # the record's own speeds and point for the others
            point = np.where(first[:, None], point, p_rec)
            speed = np.where(first, speed, np.hypot(vn_rec, vt_rec))
            vn = np.where(first, vn, vn_rec)
            angle = np.array([math.degrees(math.asin(min(1.0, max(0.0, a / b)))) if fi else math.degrees(math.atan2(a, c))
                              for fi, a, b, c in zip(first.tolist(), vn.tolist(), speed.tolist(), vt_rec.tolist())])
        E_in = self._half_mass[idx] * speed * speed
        state[idx] = DONE
        self.counts.impacts += k
        self._impacts.append({
            "angle_deg": angle, "cor_n": f[:, 9], "cor_t": f[:, 10], "W_diss_n": f[:, 11], "W_diss_t": f[:, 12],
            "E_in": E_in, "x": point[:, 0], "y": point[:, 1], "Pc_max": f[:, 13], "cls": self.cls[idx],
            "outside_validity": [bool(r.outside_validity) for r in plate], "repeat": repeat})
        if not rows:
            return k, []
        cols = zip(idx.tolist(), self.cls[idx].tolist(), self.radius[idx].tolist(), self.mass[idx].tolist(),
                   self.emission_id[idx].tolist(), self.t_emit[idx].tolist(), t_on.tolist(), speed.tolist(),
                   vn.tolist(), vn_rec.tolist(), angle.tolist(), point[:, 0].tolist(), point[:, 1].tolist(),
                   p_rec[:, 0].tolist(), p_rec[:, 1].tolist(), E_in.tolist(), repeat.tolist(), deflected.tolist())
        for m, rec, (i, c, R, mass, em, te, ton, sp, vn_, vnr, ang, x, y, xr, yr, E, rep, defl) in zip(
                where, plate, cols):
            out[m] = {
                "kind": "impact", "engine": self.engine, "emission": em, "particle": i, "cls": c, "radius": R,
                "mass": mass, "t_emit": te, "t_onset": ton, "speed_in": sp, "v_n_in": vn_, "v_n_in_record": vnr,
                "angle_deg": ang, "x": x, "y": y, "x_record": xr, "y_record": yr, "E_in": E, "cor_n": rec.cor_n,
                "cor_t": rec.cor_t, "cor_t_contact": rec.cor_t_contact, "tau": rec.tau, "x_max": rec.x_max,
                "F_max": rec.F_max, "Pc_max": rec.Pc_max, "W_diss_n": rec.W_diss_n, "W_diss_t": rec.W_diss_t,
                "Q_t": rec.Q_t, "spin_out": rec.spin_out, "omega_x": rec.omega_x, "ended_by": rec.ended_by,
                "outside_validity": "; ".join(rec.outside_validity), "repeat": rep, "deflected": defl,
            }
        return k, out


def make_pool(engine: str, spec: JetSpec, seed=0, **kw) -> JetPool:
    """The jet in an engine ("mujoco" or "pybullet"): :class:`JetPool`."""
    return JetPool(engine, spec, seed, **kw)


def _check_spheres(pool_class, spec: JetSpec) -> None:
    """The engine's own limits on the particles (MuJoCo: mjMINVAL), per size class."""
    radii = spec.particles.radii
    pool_class.check_spheres(radii, [spec.particles.mass(i) for i in range(len(radii))], label="particles.radius")


class ChunkWriter:
    """A sink that writes rows in chunks of ``size`` rows, each chunk its own
    JSON-lines file ``directory/chunk_00012.jsonl`` written atomically
    (experiments._io); only the current chunk is held in memory."""

    def __init__(self, directory: str | os.PathLike, size: int = 1000):
        if int(size) != size or size < 1:
            raise ValueError(f"size = {size!r} rows must be a whole number >= 1")
        self.directory = Path(directory)
        self.size = int(size)
        self.index = 0
        self.paths: list[str] = []
        self._buf: list[str] = []

    def __call__(self, rows: list[dict]) -> None:
        for r in rows:
            self._buf.append(json.dumps(r, sort_keys=True, allow_nan=False))
            if len(self._buf) >= self.size:
                self.flush()

    def flush(self) -> None:
        from .._io import write_text_atomic

        if not self._buf:
            return
        p = write_text_atomic(self.directory / f"chunk_{self.index:05d}.jsonl", "\n".join(self._buf) + "\n")
        self.paths.append(str(p))
        self.index += 1
        self._buf = []


def rss_kb() -> tuple[int, int]:
    """(current resident set size, peak resident set size) of this process [kB]."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    try:
        with open("/proc/self/statm") as fh:
            cur = int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") // 1024
    except OSError:
        cur = peak
    return cur, peak


def memory_profile(engine: str, spec: JetSpec, checkpoints: Sequence[int] = (2000, 5000, 10000), seed=0,
                   trace: bool = False, sink=None) -> list[dict]:
    """Run one continuous jet and measure memory at each checkpoint (cumulative
    impacts): current and peak RSS [kB] and, with ``trace``, tracemalloc's
    traced memory [B] (slower). Returns one dict per checkpoint with impacts,
    steps, the pool's CPU seconds, impacts per CPU second since the start
    (``impacts_per_cpu_s``: the first steps include loading or compiling the
    engines' numba kernels) and since the previous checkpoint
    (``interval_impacts_per_cpu_s``)."""
    import gc
    import tracemalloc

    out = []
    if trace:
        tracemalloc.start()
    try:
        with make_pool(engine, spec, seed) as pool:
            n0, c0 = 0, 0.0
            for n in checkpoints:
                pool.run(int(n), sink=sink)
                gc.collect()
                cur, peak = rss_kb()
                di, dc = pool.counts.impacts - n0, pool.cpu_s - c0
                d = {"engine": engine, "impacts": pool.counts.impacts, "steps": pool.counts.steps,
                     "rss_kb": cur, "peak_rss_kb": peak, "cpu_s": pool.cpu_s,
                     "impacts_per_cpu_s": pool.counts.impacts / pool.cpu_s if pool.cpu_s > 0 else None,
                     "interval_impacts_per_cpu_s": di / dc if dc > 0 else None}
                n0, c0 = pool.counts.impacts, pool.cpu_s
                if trace:
                    d["traced_bytes"], d["traced_peak_bytes"] = tracemalloc.get_traced_memory()
                out.append(d)
    finally:
        if trace:
            tracemalloc.stop()
    return out


# --------------------------------------------------------------------------
# Configuration (TOML)
# --------------------------------------------------------------------------
_DIR45 = [math.sqrt(0.5), 0.0, -math.sqrt(0.5)]

SCHEMA = {
    "": {"scenario": Field("str", required=True),
         "title": Field("str", default="Abrasive jet: glass beads on a polyurethane coating")},
    "nozzle": {
        "aim": Field("list[float]", default=[0.0, 0.0], help="where the axis meets the plate (x, y) [m]"),
        "direction": Field("list[float]", default=_DIR45, help="unit axis (3), pointing at the plate"),
        "standoff": Field("float", lo=0.0, lo_open=True, help="distance from the exit to the plate along the axis [m]"),
        "position": Field("list[float]", help="exit centre (3) [m]; instead of aim and standoff"),
        "half_angle": Field("float", default=20.0, lo=0.0, hi=90.0, hi_open=True, help="cone half-angle [deg]"),
        "diameter": Field("float", default=1e-3, lo=0.0, help="exit diameter [m]"),
    },
    "particles": {
        **material_fields("particles"),
        "radius": Field("list[float]", lo=0.0, lo_open=True, help="radii of the size classes [m]"),
        "probability": Field("list[float]", lo=0.0, help="probabilities of the size classes"),
        "radius_mean": Field("float", lo=0.0, lo_open=True, help="normal distribution of radii: mean [m]"),
        "radius_sd": Field("float", lo=0.0, help="normal distribution of radii: sd [m]"),
        "classes": Field("int", default=5, lo=1, hi=50, help="classes the normal distribution is binned into"),
        "speed_mean": Field("float", default=30.0, lo=0.0, lo_open=True, help="[m/s]"),
        "speed_sd": Field("float", default=3.0, lo=0.0, help="[m/s]"),
        "feed_rate": Field("float", default=1e5, lo=0.0, lo_open=True, help="[particles/s]"),
        "arrival": Field("str", default="uniform", choices=ARRIVALS),
    },
    "plate": {
        **material_fields("plate"),
        "kind": Field("str", default="plane", choices=PLATE_KINDS),
        "size": Field("list[float]", default=[0.04, 0.04], lo=0.0, lo_open=True, help="[m] (2)"),
        "thickness": Field("float", default=0.005, lo=0.0, lo_open=True, help="box thickness [m]"),
        "strength": Field("float", default=10e6, lo=0.0, lo_open=True, help="coating strength [Pa]"),
    },
    "contact": {
        "particle_particle": Field("bool", default=False, help="MSF contacts among pool members"),
        "tangential": Field("str", default="contact-point", choices=("contact-point", "paper")),
    },
    "run": {
        "engines": Field("list[str]", default=list(ENGINES), choices=ENGINES),
        "impacts": Field("int", default=1000, lo=1, help="plate impacts per engine"),
        "chunk": Field("int", default=500, lo=1, help="impacts per cell (an independent burst, own seed)"),
        "seed": Field("int", default=0, lo=0),
        "dt": Field("float", default=1e-4, lo=0.0, lo_open=True, help="engine time step [s]"),
        "gravity": Field("float", default=0.0, lo=0.0, help="[m/s^2] along -z"),
        "pool": Field("int", default=0, lo=0, help="particles per size class (0: from the feed rate)"),
    },
    "aggregates": {
        "angle_bins": Field("int", default=18, lo=1, hi=900),
        "map_bins": Field("list[int]", default=[40, 40], lo=1, hi=2000),
        "pc_range": Field("list[float]", default=[1e5, 1e9], lo=0.0, lo_open=True, help="[Pa]"),
        "pc_bins": Field("int", default=40, lo=1, hi=1000),
    },
}


def spec_from_config(cfg: dict) -> JetSpec:
    """A :class:`JetSpec` from a validated configuration (ValueError naming
    the key on a bad combination)."""
    nz, pa, pl, ru, ag, co = (cfg[k] for k in ("nozzle", "particles", "plate", "run", "aggregates", "contact"))
    if len(nz["direction"]) != 3:
        raise ValueError(f"nozzle.direction = {nz['direction']!r} must have 3 components")
    if nz["position"] is not None:
        if nz["standoff"] is not None:
            raise ValueError("nozzle.position and nozzle.standoff are exclusive: give the exit position, "
                             "or aim and standoff")
        if len(nz["position"]) != 3:
            raise ValueError(f"nozzle.position = {nz['position']!r} must have 3 components")
        nozzle = Nozzle(tuple(nz["position"]), tuple(nz["direction"]), nz["half_angle"], nz["diameter"])
    else:
        if len(nz["aim"]) != 2:
            raise ValueError(f"nozzle.aim = {nz['aim']!r} must have 2 components (x, y)")
        nozzle = Nozzle.aimed(nz["aim"], nz["direction"], 0.02 if nz["standoff"] is None else nz["standoff"],
                              nz["half_angle"], nz["diameter"])
    mat_p = cfg["_materials"]["particles"]
    mat_pl = cfg["_materials"]["plate"]
    kw = dict(speed_mean=pa["speed_mean"], speed_sd=pa["speed_sd"], feed_rate=pa["feed_rate"], arrival=pa["arrival"])
    if pa["radius_mean"] is not None:
        if pa["radius"] is not None:
            raise ValueError("particles.radius and particles.radius_mean are exclusive: discrete classes, or a "
                             "normal distribution binned into classes")
        particles = Particles.binned_normal(mat_p, pa["radius_mean"], pa["radius_sd"] or 0.0, pa["classes"], **kw)
    else:
        radii = pa["radius"] if pa["radius"] is not None else [2.0e-4, 2.5e-4, 3.0e-4]
        probs = pa["probability"] if pa["probability"] is not None else (
            [0.25, 0.5, 0.25] if pa["radius"] is None else [1.0] * len(radii))
        particles = Particles(mat_p, tuple(radii), tuple(probs), **kw)
    if len(pl["size"]) != 2:
        raise ValueError(f"plate.size = {pl['size']!r} must have 2 components")
    plate = Plate(mat_pl, pl["kind"], tuple(pl["size"]), pl["thickness"], pl["strength"])
    if len(ag["map_bins"]) != 2:
        raise ValueError(f"aggregates.map_bins = {ag['map_bins']!r} must have 2 components")
    if len(ag["pc_range"]) != 2:
        raise ValueError(f"aggregates.pc_range = {ag['pc_range']!r} must have 2 components")
    bins = Bins(ag["angle_bins"], tuple(ag["map_bins"]), tuple(ag["pc_range"]), ag["pc_bins"])
    law = dict(cfg["law"])
    name = law.pop("name", "msf")
    return JetSpec(nozzle, particles, plate, law=name, law_options=law, tangential=co["tangential"],
                   particle_particle=co["particle_particle"], dt=ru["dt"], gravity=ru["gravity"],
                   pool=ru["pool"] or None, bins=bins)


def _materials(cfg: dict, path: str) -> dict:
    return {"particles": build_material(cfg["particles"], path, "particles", "glass"),
            "plate": build_material(cfg["plate"], path, "plate", "polyurethane")}


def load(raw: dict, path: str) -> dict:
    law = raw.get("law", {})
    if not isinstance(law, dict):
        raise ConfigError(f"{path}: [law] must be a table (name = \"msf\" and the law's options)")
    if "name" in law and not isinstance(law["name"], str):
        raise ConfigError(f"{path}: [law.name] = {law['name']!r} must be a string (a registry law)")
    cfg = validate({k: v for k, v in raw.items() if k != "law"}, {k: v for k, v in SCHEMA.items()}, path)
    cfg["law"] = dict(law)
    cfg["_materials"] = _materials(cfg, path)
    try:
        spec = spec_from_config(cfg)
        spec.plate_laws()
        if spec.particle_particle:
            spec.pp_laws()
        cfg["_validity"] = spec.check_validity()
        for e in cfg["run"]["engines"]:
            _engine_check(e, spec)
    except ValueError as exc:
        raise ConfigError(_config_message(path, str(exc))) from None
    if len(set(cfg["run"]["engines"])) != len(cfg["run"]["engines"]):
        raise ConfigError(f"{path}: [run.engines] = {cfg['run']['engines']!r} repeats an engine")
    return cfg


def _config_message(path: str, msg: str) -> str:
    """"run.dt = ..." -> "PATH: [run.dt] = ..." (the file, the key, the bound)."""
    import re

    m = re.match(r"^([a-z_]+\.[a-z_]+(?:\[\d+\])?)(?::)? (.*)$", msg, re.S)
    if m and (m.group(1).split(".")[0] in SCHEMA or m.group(1).startswith("law.")):
        return f"{path}: [{m.group(1)}] {m.group(2)}"
    m = re.match(r"^([a-z_]+): (.*)$", msg, re.S)
    if m and (m.group(1) in SCHEMA or m.group(1) == "law"):
        return f"{path}: [{m.group(1)}] {m.group(2)}"
    return f"{path}: {msg}"


def _engine_check(engine: str, spec: JetSpec) -> None:
    _check_spheres(sphere_pool_class(engine), spec)


def _cell_config(cfg: dict) -> dict:
    """What a cell needs to rebuild the spec (JSON; no title, no engine list)."""
    keep = {k: cfg[k] for k in ("nozzle", "particles", "plate", "contact", "aggregates", "law")}
    keep["run"] = {k: cfg["run"][k] for k in ("seed", "dt", "gravity", "pool")}
    return json.loads(json.dumps(keep))


def cells(cfg: dict) -> list[dict]:
    """One cell per (engine, chunk): chunk c is an independent burst of
    ``run.chunk`` impacts (the last one what is left) with the seed
    (run.seed, c); the same seeds in every engine."""
    total, size = cfg["run"]["impacts"], cfg["run"]["chunk"]
    n_chunks = int(math.ceil(total / size))
    conf = _cell_config(cfg)
    return [{"scenario": "jet", "engine": e, "chunk": c, "impacts": min(size, total - c * size), "config": conf}
            for e in cfg["run"]["engines"] for c in range(n_chunks)]


def _cfg_from_cell(cell: dict) -> dict:
    cfg = json.loads(json.dumps(cell["config"]))
    cfg["_materials"] = _materials(cfg, "cell")
    return cfg


def run_cell(cell: dict) -> list[dict]:
    """One burst of ``cell["impacts"]`` plate impacts in one engine: a
    summary row (kind "summary": the fixed-size aggregates, counters, CPU
    time, memory) and one row per impact (kind "impact") or particle-particle
    contact (kind "particle-particle")."""
    import warnings

    cfg = _cfg_from_cell(cell)
    spec = spec_from_config(cfg)
    rows: list[dict] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)  # checked in load(), reported per impact
        with make_pool(cell["engine"], spec, [cfg["run"]["seed"], cell["chunk"]]) as pool:
            pool.run(cell["impacts"], sink=rows.extend, progress=None)
    cur, peak = rss_kb()
    c = pool.counts
    summary = {"kind": "summary", "engine": cell["engine"], "chunk": cell["chunk"], "impacts": c.impacts,
               "emitted": c.emitted, "lost": c.lost, "pp_impacts": c.pp_impacts, "pp_W": c.pp_W,
               "pool_waits": c.pool_waits, "steps": c.steps, "pool_size": pool.n, "cpu_s": pool.cpu_s,
               "wall_s": pool.wall_s, "rss_kb": cur, "peak_rss_kb": peak, "validity": pool.validity,
               "aggregates": pool.aggregates.to_dict()}
    return [summary] + rows


# --------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------
def _merged(rows) -> dict[str, tuple[JetAggregates, dict]]:
    out: dict[str, tuple[JetAggregates, dict]] = {}
    for r in sorted((r for r in rows if r.get("kind") == "summary"), key=lambda r: (r["engine"], r["chunk"])):
        a = JetAggregates.from_dict(r["aggregates"])
        if r["engine"] not in out:
            out[r["engine"]] = (a, {k: r[k] for k in ("impacts", "emitted", "lost", "pp_impacts", "pp_W", "pool_waits",
                                                      "steps", "cpu_s", "wall_s")}
                                | {"chunks": 1, "pool_size": r["pool_size"], "peak_rss_kb": r["peak_rss_kb"],
                                   "validity": r["validity"]})
        else:
            agg, tot = out[r["engine"]]
            agg.merge(a)
            for k in ("impacts", "emitted", "lost", "pp_impacts", "pp_W", "pool_waits", "steps", "cpu_s", "wall_s"):
                tot[k] += r[k]
            tot["chunks"] += 1
            tot["peak_rss_kb"] = max(tot["peak_rss_kb"], r["peak_rss_kb"])
    return out


def reference_by_angle(spec: JetSpec, angles=None) -> dict | None:
    """cor_n and cor_t of the reference solver (msf_contact.simulate_impact)
    over impact angles [deg] for the most probable size class at the mean
    speed, for comparison with the engines' binned means (None if the
    solver refuses the impact)."""
    import warnings

    from msf_contact.solver import Body, simulate_impact

    sp = spec.particles
    k = int(np.argmax(sp.probabilities))
    if angles is None:
        lo = max(1.0, spec.nozzle.axis_angle - spec.nozzle.half_angle)
        angles = np.linspace(lo, min(90.0, spec.nozzle.axis_angle + spec.nozzle.half_angle), 9)
    law = spec.plate_laws()[k]
    ball, plate = Body.sphere(sp.material, sp.radii[k]), Body.half_space(spec.plate.material)
    cor_n, cor_t = [], []
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            for a in angles:
                r = simulate_impact(law, ball, plate, sp.speed_mean, float(a), tangential=spec.tangential)
                cor_n.append(r.cor_n)
                cor_t.append(np.nan if r.cor_t is None else r.cor_t)
    except ValueError:
        return None
    return {"angle": np.asarray(angles), "cor_n": np.array(cor_n), "cor_t": np.array(cor_t),
            "label": f"R = {sp.radii[k] * 1e3:g} mm, {sp.speed_mean:g} m/s"}


def report(out: Path, rows: list[dict], cfg: dict) -> tuple[str, list[str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .._io import save_figure_atomic

    merged = _merged(rows)
    spec = spec_from_config(cfg)
    figs: list[str] = []
    L = [f"# {cfg['']['title']}\n\n"]
    nz, sp, pl = spec.nozzle, spec.particles, spec.plate
    L.append(
        f"Nozzle at ({nz.position[0]:.4g}, {nz.position[1]:.4g}, {nz.position[2]:.4g}) m, axis {nz.axis_angle:.3g} deg "
        f"to the plate, stand-off {nz.standoff * 1e3:.4g} mm, cone half-angle {nz.half_angle:g} deg, exit diameter "
        f"{nz.diameter * 1e3:g} mm. Particles: {sp.material.name}, speed {sp.speed_mean:g} +- {sp.speed_sd:g} m/s "
        f"(normal, truncated at {SPEED_TRUNCATION_SD:g} sd), feed {sp.feed_rate:g} particles/s ({sp.arrival}). "
        f"Plate: {pl.material.name} ({pl.kind}, {pl.size[0] * 1e3:g} x {pl.size[1] * 1e3:g} mm mapped), strength "
        f"{pl.strength / 1e6:g} MPa. Law {spec.law!r} {spec.law_options or ''}, tangential {spec.tangential}, "
        f"particle-particle contacts {'on' if spec.particle_particle else 'off'}; engine step dt = {spec.dt:g} s "
        "(contacts sub-cycled), gravity "
        f"{spec.gravity:g} m/s^2. Impact angles are to the plate (90 deg = normal).\n\n")
    validity = cfg.get("_validity") or next((t["validity"] for _, t in merged.values() if t["validity"]), None)
    if validity:
        L.append("## Size classes and validity at the fastest particle (normal impact, reference solver)\n\n"
                 "| class | R [mm] | probability | mass [kg] | v_max [m/s] | x_max/R | tau [us] | COR | Pc_max [MPa] |"
                 " tg(beta) | sound speed [m/s] |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
        for v, p in zip(validity, sp.probabilities):
            L.append(f"| {v['class']} | {v['radius'] * 1e3:.4g} | {p:.3f} | {v['mass']:.3e} | {v['v_max']:.4g} | "
                     f"{v['x_max_over_R']:.3f} | {v['tau'] * 1e6:.3g} | {v['cor_n']:.4f} | {v['Pc_max'] / 1e6:.3g} | "
                     f"{v['tan_delta']:.3g} | {v['sound_speed']:.4g} |\n")
        L.append("\nValid: tg(beta) <= 1/3 (100), v_max below the sound speed, x_max < 2R (checked before the "
                 "run).\n\n")
    if not merged:
        L.append("No finished cells.\n")
        return "".join(L), figs
    L.append("## Summary per engine\n\n| engine | impacts | emitted | lost | pool | chunks | mean COR | "
             "W_diss total [J] | W/E_in | Pc_max > strength | max Pc_max [MPa] | outside validity | repeats | "
             "particle-particle | CPU [s] | impacts/CPU-s | peak RSS [MB] |\n"
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    for e, (a, t) in sorted(merged.items()):
        cor = float(a.a_cor.sum() / max(a.n, 1))
        W = a.W_n + a.W_t
        L.append(f"| {e} | {a.n} | {t['emitted']} | {t['lost']} | {t['pool_size']} | {t['chunks']} | {cor:.4f} | "
                 f"{W:.4e} | {W / a.E_in if a.E_in else 0:.4f} | {a.n_above_strength / max(a.n, 1):.2%} | "
                 f"{a.Pc_max_max / 1e6:.4g} | {a.n_outside_validity} | {a.n_repeat} | {t['pp_impacts']} | "
                 f"{t['cpu_s']:.1f} | {a.n / t['cpu_s'] if t['cpu_s'] else 0:.0f} | "
                 f"{t['peak_rss_kb'] / 1024:.0f} |\n")
    L.append("\nW_diss = W_diss_n + W_diss_t of the records; E_in the incoming kinetic energy; peak RSS of the "
             "process that ran the cells (kB from getrusage, shown in MB).\n\n")
    # angle table
    engines = sorted(merged)
    L.append("## COR and dissipated energy against the impact angle\n\n| angle [deg] | "
             + " | ".join(f"{e} n | {e} COR | {e} cor_t | {e} W [uJ] | {e} W/E_in" for e in engines)
             + " | Finnie f/f_max |\n|---:" + "|---:" * (5 * len(engines) + 1) + "|\n")
    ba = {e: merged[e][0].by_angle() for e in engines}
    centres = ba[engines[0]]["centre"]
    for k, c in enumerate(centres):
        if not any(ba[e]["n"][k] for e in engines):
            continue
        cells_ = []
        for e in engines:
            b = ba[e]
            if b["n"][k]:
                cells_.append(f"{b['n'][k]} | {b['cor_n'][k]:.4f} | "
                              f"{'-' if not np.isfinite(b['cor_t'][k]) else format(b['cor_t'][k], '.4f')} | "
                              f"{b['W'][k] * 1e6:.4g} | {b['fraction'][k]:.4f}")
            else:
                cells_.append("0 | - | - | - | -")
        L.append(f"| {c:.1f} | " + " | ".join(cells_) + f" | {float(finnie(c)):.3f} |\n")
    xr = max((v["x_max_over_R"] for v in validity or []), default=float("nan"))
    L.append("\nThe angle figure also shows the reference solver (most probable class, mean speed). The engines' "
             f"tangential results (cor_t, spin, W_diss_t) depart from it here (x_max/R up to {xr:.2f}): the "
             "adapters hold the lever arm at R over a step where the reference solver uses R - x/2, and pybullet "
             "caps a body's rotation per step (docs/jet.md, known limits); cor_n and W_diss_n agree with it. "
             "Finnie's angle function (Finnie 1960, ductile cutting) for comparison: it is the volume cut per unit "
             "kinetic energy, normalised; the MSF contact has no cutting, so its dissipation follows the normal "
             "component instead.\n\n")
    # figures
    colors = {e: f"C{i}" for i, e in enumerate(engines)}
    fig, axes = plt.subplots(1, len(engines), figsize=(5.2 * len(engines), 4.4), squeeze=False)
    for ax, e in zip(axes[0], engines):
        a = merged[e][0]
        ex, ey = a.map_edges_x * 1e3, a.map_edges_y * 1e3
        im = ax.pcolormesh(ex, ey, a.energy_density().T, shading="flat", cmap="inferno")
        fig.colorbar(im, ax=ax, label="dissipated energy per area [J/m^2]")
        aim = nz.aim * 1e3
        ax.plot(aim[0], aim[1], "c+", ms=10, label="nozzle axis")
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title(f"{e}: {a.n} impacts ({a.off_map_n} off the map)")
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    save_figure_atomic(fig, out / "figures" / "jet_energy_map.png", dpi=110)
    plt.close(fig)
    figs.append("jet_energy_map.png")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    fa = np.linspace(0.5, 90, 180)
    for e in engines:
        b = ba[e]
        m = b["n"] > 0
        axes[0].errorbar(b["centre"][m], b["cor_n"][m], yerr=b["cor_n_sd"][m], fmt="o-", color=colors[e], ms=4,
                         capsize=2, label=f"{e}: cor_n (mean, sd)")
        mt = m & np.isfinite(b["cor_t"])
        axes[0].plot(b["centre"][mt], b["cor_t"][mt], "s--", color=colors[e], ms=4, label=f"{e}: cor_t (mean)")
        frac = b["fraction"][m]
        axes[1].plot(b["centre"][m], frac / np.nanmax(frac), "o-", color=colors[e], ms=4,
                     label=f"{e}: W/E_in (max {np.nanmax(frac):.3f})")
        Wm = b["W"][m]
        axes[1].plot(b["centre"][m], Wm / np.nanmax(Wm), "^:", color=colors[e], ms=4,
                     label=f"{e}: W per impact (max {np.nanmax(Wm) * 1e6:.3g} uJ)")
    axes[1].plot(fa, finnie(fa), "k-", lw=1.5, label="Finnie (1960) f(a)/f_max")
    ref = reference_by_angle(spec)
    if ref is not None:
        axes[0].plot(ref["angle"], ref["cor_n"], "k-", lw=1, label=f"reference solver, {ref['label']}: cor_n")
        axes[0].plot(ref["angle"], ref["cor_t"], "k--", lw=1, label="reference solver: cor_t")
    axes[0].set_ylabel("coefficient of restitution [-]")
    axes[1].set_ylabel("normalised to the maximum [-]")
    for ax in axes:
        ax.set_xlabel("impact angle to the plate [deg]")
        ax.set_xlim(0, 90)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure_atomic(fig, out / "figures" / "jet_angle.png", dpi=110)
    plt.close(fig)
    figs.append("jet_angle.png")
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for e in engines:
        a = merged[e][0]
        ax.stairs(a.pc_counts[1:-1], a.pc_edges / 1e6, color=colors[e],
                  label=f"{e}: {a.n_above_strength / max(a.n, 1):.1%} above strength")
    ax.axvline(pl.strength / 1e6, color="k", ls="--", label=f"coating strength {pl.strength / 1e6:g} MPa")
    ax.set_xscale("log")
    ax.set_xlabel("peak contact pressure Pc_max (20) [MPa]")
    ax.set_ylabel("impacts per bin")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure_atomic(fig, out / "figures" / "jet_pc_hist.png", dpi=110)
    plt.close(fig)
    figs.append("jet_pc_hist.png")
    L.append("## Figures\n\n")
    for name in figs:
        L.append(f"![{name}](figures/{name})\n\n")
    L.append("Per-impact records: `records.csv` rows with `kind == \"impact\"` (point on the plate x, y [m], angle "
             "to the plate angle_deg [deg], and the impact record's outputs); the `summary` rows hold the "
             "fixed-size aggregates of each chunk.\n")
    return "".join(L), figs


register(Scenario("jet", "abrasive jet: a nozzle, a recycled pool of particles, MSF particle-plate contacts in "
                         "MuJoCo or pybullet; impact maps, COR and dissipation against angle, Pc_max against "
                         "the coating's strength", load, cells, run_cell, report))
