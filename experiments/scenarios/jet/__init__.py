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

Modules, by responsibility: :mod:`.spec` (the specification and the jet's
constants), :mod:`.emission` (the emission sequence), :mod:`.pool` (the
jet in an engine, chunked records, memory profile), :mod:`.aggregates`
(fixed-size aggregates, Finnie's function), :mod:`.scenario` (TOML
configuration, cells) and :mod:`.reporting` (figures, tables). Every public
name is importable from this package.

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

from .. import Scenario
from .aggregates import JetAggregates, finnie
from .emission import Emitter
from .pool import IMPACT_BUFFER, POSITION_CHECK_STEPS, ChunkWriter, JetCounts, JetPool, make_pool, memory_profile, rss_kb
from .reporting import reference_by_angle, report
from .scenario import SCHEMA, cells, load, run_cell, spec_from_config
from .spec import (
    ARRIVALS,
    ENGINES,
    FLIGHT_TIMEOUT_FACTOR,
    MIN_CONE_ANGLE_DEG,
    MIN_FLIGHT_STEPS,
    PARK_DISTANCE,
    PARK_DRIFT,
    PARK_SPACING_RADII,
    PLATE_KINDS,
    POOL_EXTRA,
    POOL_SAFETY,
    PP_CLEARANCE_STEPS,
    PP_ENGINES,
    PP_ENGINES_WHY,
    RADIUS_TRUNCATION_SD,
    RECORD_LATENCY_STEPS,
    SPEED_TRUNCATION_SD,
    UNIT_TOL,
    Bins,
    JetSpec,
    Nozzle,
    Particles,
    Plate,
)

__all__ = [
    "ARRIVALS", "ENGINES", "FLIGHT_TIMEOUT_FACTOR", "MIN_CONE_ANGLE_DEG", "MIN_FLIGHT_STEPS", "PARK_DISTANCE",
    "PARK_DRIFT", "PARK_SPACING_RADII", "PLATE_KINDS", "POOL_EXTRA", "POOL_SAFETY", "PP_CLEARANCE_STEPS", "PP_ENGINES",
    "PP_ENGINES_WHY", "RADIUS_TRUNCATION_SD", "RECORD_LATENCY_STEPS", "SPEED_TRUNCATION_SD", "UNIT_TOL",
    "IMPACT_BUFFER",
    "POSITION_CHECK_STEPS", "Bins", "JetSpec", "Nozzle", "Particles", "Plate", "JetAggregates", "finnie", "Emitter",
    "ChunkWriter", "JetCounts", "JetPool", "make_pool", "memory_profile", "rss_kb", "reference_by_angle", "report",
    "SCHEMA", "cells", "load", "run_cell", "spec_from_config", "SCENARIO",
]

SCENARIO = Scenario("jet", "abrasive jet: a nozzle, a recycled pool of particles, MSF particle-plate contacts in "
                           "MuJoCo or pybullet; impact maps, COR and dissipation against angle, Pc_max against "
                           "the coating's strength", load, cells, run_cell, report)
