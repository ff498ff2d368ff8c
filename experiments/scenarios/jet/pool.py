"""The jet in an engine (:class:`JetPool`, :func:`make_pool`): emission,
flight checks and the records' conversion to impacts over an engine's
recycled pool of spheres (:class:`engines.pool.SpherePool`); the records
written in chunks (:class:`ChunkWriter`) and the memory profile of a long
run (:func:`memory_profile`)."""

from __future__ import annotations

import json
import math
import os
import resource
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from engines.pool import DONE, FLIGHT, PARKED, PlateShape, SphereScene, sphere_pool_class

from .aggregates import JetAggregates
from .emission import Emitter, _Emission
from .spec import PARK_DISTANCE, PARK_DRIFT, PP_CLEARANCE_STEPS, PP_ENGINES, PP_ENGINES_WHY, JetSpec


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
                            "emission2": int(self.emission_id[j]), "t_onset": d["t_onset"], "t_end": d["t_end"],
                            "v_n_in": d["v_n_in"], "v_t_in": d["v_t_in"], "cor_n": rec.cor_n, "cor_t": rec.cor_t, "W_diss_n": rec.W_diss_n,
                            "W_diss_t": rec.W_diss_t, "island": bool(d.get("island", False)),
                            "outside_validity": "; ".join(rec.outside_validity), "engine": self.engine})
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
                "Q_t": rec.Q_t, "spin_in": rec.spin_in, "spin_out": rec.spin_out, "omega_x": rec.omega_x,
                "ended_by": rec.ended_by,
                "outside_validity": "; ".join(rec.outside_validity), "repeat": rep, "deflected": defl,
            }
        return k, out


def make_pool(engine: str, spec: JetSpec, seed=0, **kw) -> JetPool:
    """The jet in an engine ("mujoco" or "pybullet"): :class:`JetPool`."""
    return JetPool(engine, spec, seed, **kw)


def _check_spheres(pool_class, spec: JetSpec) -> None:
    """The engine's own limits on the particles (MuJoCo: mjMINVAL), per size
    class, and particle-particle contacts only where they are supported
    (spec.PP_ENGINES)."""
    if spec.particle_particle and pool_class.engine not in PP_ENGINES:
        raise ValueError(f"contact.particle_particle = true is not supported in {pool_class.engine} "
                         f"(supported: {', '.join(PP_ENGINES)}): {PP_ENGINES_WHY}")
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
        from ..._io import write_text_atomic

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
