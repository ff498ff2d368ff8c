"""Abrasive jet (issue 4, item 2): the pool drivers in MuJoCo and pybullet,
the aggregates, the scenario on the runner, and bad configurations."""

import gc
import json
from pathlib import Path
import math
import textwrap
import tracemalloc
import warnings

import numpy as np
import pytest

from experiments import runner
from experiments.config import ConfigError
from experiments.scenarios.jet import (
    Bins,
    ChunkWriter,
    Emitter,
    JetAggregates,
    JetSpec,
    Nozzle,
    Particles,
    Plate,
    finnie,
    make_pool,
)
from msf_contact import Body, ValidityWarning, preset, simulate_impact

#: Engine cor_n against the reference solver at the record's own normal speed
#: and the particle's mass: the brief's 0.5 %. Measured: ~2e-5 (the engines
#: take omega_x from the scaled onset table, the reference solves it).
COR_RTOL = 5e-3
#: The energy map is a re-binning of the records' W_diss_n + W_diss_t: equal
#: up to summation order (float64, a few hundred terms).
SUM_RTOL = 1e-12
#: The incoming normal speed from the ballistic flight against the manager's
#: own closing speed at onset (both exact for a free flight without
#: gravity): round-off only.
VN_RTOL = 1e-9
#: Traced memory (tracemalloc) may grow by at most this much per impact
#: between N and 4N impacts [B]: keeping one row dict per impact (~2.5 kB)
#: or one ImpactRecord (~5 kB) would exceed it several times over. Measured:
#: ~100-250 B/impact of numpy temporaries retained inside msf_contact's
#: reductions (np.any), flat in the 10,000-impact runs (docs/jet.md).
MEMORY_PER_IMPACT_BOUND = 600.0
#: Issue 10's acceptance for deep oblique contacts: cor_t, spin_out and
#: W_diss_t within 2 % of the reference solver (relative), cor_n within 1e-4
#: (absolute); the same bounds as tests/test_oblique.py for isolated impacts.
TANGENTIAL_RTOL = 0.02
COR_N_ATOL = 1e-4

ENGINES = [pytest.param("mujoco", marks=pytest.mark.mujoco), pytest.param("pybullet", marks=pytest.mark.pybullet)]
N_IMPACTS = 40


def small_spec(**kw) -> JetSpec:
    """Two size classes, a small pool (recycled several times in a run)."""
    args = dict(
        nozzle=Nozzle.aimed((0.0, 0.0), (math.sqrt(0.5), 0.0, -math.sqrt(0.5)), 0.02, 20.0, 1e-3),
        particles=Particles(preset("glass"), (2.0e-4, 3.0e-4), (0.5, 0.5), 30.0, 3.0, 2e4),
        plate=Plate(preset("polyurethane")),
        dt=1e-4,
        pool=6,
    )
    args.update(kw)
    return JetSpec(**args)


def run_pool(engine, spec, impacts, seed=0):
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        pool = make_pool(engine, spec, seed)
        try:
            nb0 = _bodies(pool)
            pool.run(impacts, sink=rows.extend)
            nb1 = _bodies(pool)
        finally:
            pool.close()
    return pool, rows, (nb0, nb1)


def _bodies(pool):
    if pool.engine == "mujoco":
        return pool.bodies.model.nbody
    import pybullet as pb

    return pb.getNumBodies(physicsClientId=pool.bodies.client)


@pytest.fixture(scope="module", params=ENGINES)
def jet_run(request):
    """One run per engine, shared by the checks below."""
    return request.param, *run_pool(request.param, small_spec(), N_IMPACTS)


# ------------------------------------------------------------------ physics ---
def test_finnie_angle_function_against_its_closed_form():
    a = np.array([0.0, 10.0, 18.434948822922, 45.0, 90.0])
    f_max = math.sin(math.atan(2 / 3)) - 3 * math.sin(0.5 * math.atan(2 / 3)) ** 2
    want = np.array([0.0, (math.sin(math.radians(20)) - 3 * math.sin(math.radians(10)) ** 2) / f_max,
                     0.3 / f_max, 0.5 / 3 / f_max, 0.0])
    np.testing.assert_allclose(finnie(a), want, rtol=1e-12, atol=1e-15)
    # maximum 1 at tan(2a) = 2/3 (16.85 deg); continuous at tan(a) = 1/3
    fine = np.linspace(0.01, 89.99, 100001)
    assert abs(fine[np.argmax(finnie(fine))] - math.degrees(0.5 * math.atan(2 / 3))) < 1e-3
    edge = math.degrees(math.atan(1 / 3))
    assert abs(float(finnie(edge - 1e-9)) - float(finnie(edge + 1e-9))) < 1e-8


def test_pool_recycles_a_fixed_set_of_bodies_with_at_most_one_record_per_emission(jet_run):
    engine, pool, rows, (nb0, nb1) = jet_run
    impacts = [r for r in rows if r["kind"] == "impact"]
    assert nb0 == nb1 == pool.n + 1  # the particles and the plate (MuJoCo: the world body holds it)
    assert pool.n == 12  # pool = 6 per class, 2 classes
    assert len(impacts) == pool.counts.impacts == N_IMPACTS
    emissions = [r["emission"] for r in impacts]
    assert len(set(emissions)) == len(emissions), "an emission produced two records"
    assert pool.counts.emitted == N_IMPACTS + pool.counts.lost
    uses = np.bincount([r["particle"] for r in impacts], minlength=pool.n)
    assert uses.max() >= 3, "the pool was not recycled"
    assert not any(r["repeat"] for r in impacts)
    # every record's particle had the class of its law (curvature = particle radius)
    for r in impacts:
        assert r["radius"] == pool.spec.particles.radii[r["cls"]]


def test_records_agree_with_the_reference_solver(jet_run):
    engine, pool, rows, _ = jet_run
    impacts = [r for r in rows if r["kind"] == "impact"]
    plate = Body.half_space(preset("polyurethane"))
    laws = pool.spec.plate_laws()
    for r in impacts[::8]:
        ball = Body.sphere(preset("glass"), r["radius"])
        assert ball.mass == pytest.approx(r["mass"], rel=1e-12)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            ref = simulate_impact(laws[r["cls"]], ball, plate, r["v_n_in_record"], 90.0)
        err = (r["cor_n"] - ref.cor_n) / (COR_RTOL * ref.cor_n)
        assert abs(err) <= 1.0, f"{engine}: cor_n {r['cor_n']} vs reference {ref.cor_n}"
        # the normal dissipation is the normal kinetic energy lost
        W_n = 0.5 * r["mass"] * r["v_n_in_record"] ** 2 * (1 - r["cor_n"] ** 2)
        assert r["W_diss_n"] == pytest.approx(W_n, rel=1e-6)


def test_tangential_outputs_agree_with_the_reference_solver(jet_run):
    """Issue 10 item 5: the jet's oblique impacts (25-65 deg, 0.2 and 0.3 mm
    glass beads at ~30 m/s, x_max/R ~ 0.3-0.5, the whole contact inside one
    0.1 ms step) report cor_t, spin_out and W_diss_t within 2 % of
    msf_contact's reference solver for the same speed, angle and spin in,
    and cor_n within 1e-4, in both engines (docs/jet.md)."""
    engine, pool, rows, _ = jet_run
    impacts = [r for r in rows if r["kind"] == "impact"]
    assert len(impacts) == N_IMPACTS
    plate = Body.half_space(preset("polyurethane"))
    laws = pool.spec.plate_laws()
    for r in impacts:
        assert not r["deflected"] and not r["repeat"]  # first impacts: the row's inputs are exact
        ball = Body.sphere(preset("glass"), r["radius"])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            ref = simulate_impact(laws[r["cls"]], ball, plate, r["speed_in"], r["angle_deg"], r["spin_in"],
                                  tangential=pool.spec.tangential)
        assert abs(ref.spin_out) > 1e4  # a real tangential result, not a vanishing one
        for key in ("cor_t", "spin_out", "W_diss_t"):
            err = abs(r[key] - getattr(ref, key)) / abs(getattr(ref, key))
            assert err <= TANGENTIAL_RTOL, f"{engine}: {key} {r[key]} vs reference {getattr(ref, key)}"
        assert abs(r["cor_n"] - ref.cor_n) <= COR_N_ATOL, f"{engine}: cor_n {r['cor_n']} vs {ref.cor_n}"


def test_angles_points_and_energy_map_are_consistent_with_the_records(jet_run):
    engine, pool, rows, _ = jet_run
    impacts = [r for r in rows if r["kind"] == "impact"]
    ang = np.array([r["angle_deg"] for r in impacts])
    assert np.all((ang > 0) & (ang <= 90))
    # the cone (axis 45 deg, half-angle 20 deg) bounds the angles
    assert ang.min() >= 25 - 1e-9 and ang.max() <= 65 + 1e-9
    for r in impacts:
        assert r["v_n_in"] == pytest.approx(r["v_n_in_record"], rel=VN_RTOL)
        assert math.sin(math.radians(r["angle_deg"])) * r["speed_in"] == pytest.approx(r["v_n_in"], rel=1e-12)
        # the record's point is the contact point at the start of the onset step:
        # at most one step's tangential travel from the exact (ballistic) point
        vt = math.sqrt(max(r["speed_in"] ** 2 - r["v_n_in"] ** 2, 0.0))
        d = math.hypot(r["x"] - r["x_record"], r["y"] - r["y_record"])
        assert d <= vt * pool.spec.dt * (1 + 1e-9) + 1e-12
    a = pool.aggregates
    W = sum(r["W_diss_n"] + r["W_diss_t"] for r in impacts)
    assert a.map_W.sum() + a.off_map_W == pytest.approx(W, rel=SUM_RTOL)
    assert a.map_n.sum() + a.off_map_n == len(impacts) == a.n == a.a_n.sum() == a.pc_counts.sum()
    assert a.a_W.sum() == pytest.approx(W, rel=SUM_RTOL)
    assert a.n_above_strength == sum(r["Pc_max"] > pool.spec.plate.strength for r in impacts)
    # energy per area integrates back to the energy on the map
    assert a.energy_density().sum() * a.cell_area == pytest.approx(a.map_W.sum(), rel=SUM_RTOL)
    # the aggregates survive their JSON form (the cells' summary rows)
    b = JetAggregates.from_dict(json.loads(json.dumps(a.to_dict())))
    assert b.to_dict() == a.to_dict()


def test_same_seed_gives_identical_aggregates(jet_run):
    engine = jet_run[0]
    pool2, _, _ = run_pool(engine, small_spec(), N_IMPACTS)
    assert pool2.aggregates.to_dict() == jet_run[1].aggregates.to_dict()


def test_a_different_seed_draws_different_particles():
    spec = small_spec()
    a = [Emitter(spec, 0).next() for _ in range(1)]
    e0, e1, e0b = Emitter(spec, [0, 0]), Emitter(spec, [0, 1]), Emitter(spec, [0, 0])
    s0 = [e0.next() for _ in range(20)]
    s1 = [e1.next() for _ in range(20)]
    s0b = [e0b.next() for _ in range(20)]
    assert a and all(np.array_equal(x.v, y.v) and x.cls == y.cls for x, y in zip(s0, s0b))
    assert not all(np.array_equal(x.v, y.v) for x, y in zip(s0, s1))
    # speeds stay in mean +- 3 sd, directions inside the cone
    for e in s0 + s1:
        v = np.linalg.norm(e.v)
        assert 21.0 - 1e-12 <= v <= 39.0 + 1e-12
        cos = float(e.v @ spec.nozzle.axis) / v
        assert cos >= math.cos(math.radians(20.0)) - 1e-12


def _reference_emissions(spec, seed, n):
    """The emission draws written plainly with numpy (Generator.choice for the
    class, array arithmetic for the direction and the start point): what
    Emitter's scalar code must reproduce exactly."""
    sp, nz = spec.particles, spec.nozzle
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    e1, e2 = nz.basis()
    out, t_poisson = [], 0.0
    for k in range(n):
        if sp.arrival == "uniform":
            t = (k + 0.5) / sp.feed_rate
        else:
            t_poisson += rng.exponential(1.0 / sp.feed_rate)
            t = t_poisson
        cls = int(rng.choice(len(sp.radii), p=sp.probabilities)) if len(sp.radii) > 1 else 0
        v = sp.speed_mean
        if sp.speed_sd > 0:
            while True:
                z = rng.standard_normal()
                if abs(z) <= 3.0:
                    break
            v = sp.speed_mean + z * sp.speed_sd
        cos_a = 1.0 - rng.random() * (1.0 - math.cos(math.radians(nz.half_angle)))
        sin_a = math.sqrt(max(0.0, 1.0 - cos_a * cos_a))
        phi = 2.0 * math.pi * rng.random()
        d = cos_a * nz.axis + sin_a * (math.cos(phi) * e1 + math.sin(phi) * e2)
        r = 0.5 * nz.diameter * math.sqrt(rng.random())
        psi = 2.0 * math.pi * rng.random()
        p = np.asarray(nz.position) + r * (math.cos(psi) * e1 + math.sin(psi) * e2)
        out.append((t, cls, p, v * d))
    return out


@pytest.mark.parametrize("arrival, radii, sd", [("uniform", (2.0e-4, 2.5e-4, 3.0e-4), 3.0),
                                                ("poisson", (2.0e-4, 3.0e-4), 3.0), ("uniform", (2.5e-4,), 0.0)])
def test_emitter_reproduces_the_plain_numpy_draws_exactly(arrival, radii, sd):
    probs = (0.25, 0.5, 0.25)[:len(radii)] if len(radii) == 3 else (1.0,) * len(radii)
    spec = small_spec(particles=Particles(preset("glass"), radii, probs, 30.0, sd, 2e4, arrival))
    em = Emitter(spec, [0, 7])
    for t, cls, p, v in _reference_emissions(spec, [0, 7], 3000):
        e = em.next()
        assert (e.t, e.cls) == (t, cls)
        assert np.array_equal(e.p, p) and np.array_equal(e.v, v)


@pytest.mark.mujoco
def test_aggregates_without_a_sink_equal_those_with_rows():
    """Without a sink the pool builds no rows: the aggregates, fed from the
    records directly, are the same, and the same as adding the rows."""
    spec = small_spec()
    pool_rows, rows, _ = run_pool("mujoco", spec, 30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        with make_pool("mujoco", spec, 0) as pool:
            pool.run(30)
    assert pool.counts == pool_rows.counts
    assert pool.aggregates.to_dict() == pool_rows.aggregates.to_dict()
    again = JetAggregates(spec.bins, spec.plate.size, spec.plate.strength, 2)
    again.add([r for r in rows if r["kind"] == "impact"])
    want, got = pool.aggregates.to_dict(), again.to_dict()
    assert got.pop("bins") == want.pop("bins")
    for k in want:  # summed in other groupings: equal to round-off
        np.testing.assert_allclose(np.asarray(got[k], float), np.asarray(want[k], float), rtol=SUM_RTOL, err_msg=k)


@pytest.mark.mujoco
def test_memory_stays_flat_as_impacts_grow():
    spec = small_spec(particles=Particles(preset("glass"), (2.5e-4,), (1.0,), 30.0, 3.0, 4000.0), pool=6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        with make_pool("mujoco", spec, 3) as pool:
            pool.run(30)  # every pool member used: per-pair state allocated, tables and caches built
            tracemalloc.start()
            try:
                n = 10
                pool.run(30 + n)
                gc.collect()
                m1, _ = tracemalloc.get_traced_memory()
                pool.run(30 + 4 * n)
                gc.collect()
                m4, _ = tracemalloc.get_traced_memory()
            finally:
                tracemalloc.stop()
    growth = (m4 - m1) / (3 * n)
    assert growth < MEMORY_PER_IMPACT_BOUND, f"traced memory grew {growth:.0f} B per impact"


@pytest.mark.mujoco
def test_pool_waits_when_too_small_and_still_delivers_every_impact():
    spec = small_spec(particles=Particles(preset("glass"), (2.5e-4,), (1.0,), 30.0, 3.0, 2e5), pool=2)
    pool, rows, _ = run_pool("mujoco", spec, 10)
    impacts = [r for r in rows if r["kind"] == "impact"]
    assert pool.counts.pool_waits > 0
    assert len(impacts) == 10 and len({r["emission"] for r in impacts}) == 10
    # an emission that waited leaves the nozzle when it leaves: no particle starts inside the plate
    assert all(r["t_onset"] > r["t_emit"] for r in impacts)


def test_chunk_writer_writes_atomic_chunks(tmp_path):
    w = ChunkWriter(tmp_path / "jet_records", size=3)
    w([{"i": i} for i in range(7)])
    w.flush()
    names = sorted(p.name for p in (tmp_path / "jet_records").iterdir())
    assert names == ["chunk_00000.jsonl", "chunk_00001.jsonl", "chunk_00002.jsonl"]
    back = [json.loads(line) for n in names for line in (tmp_path / "jet_records" / n).read_text().splitlines()]
    assert back == [{"i": i} for i in range(7)]


# ------------------------------------------------------------- bad input ---
def _cfg(tmp_path, text):
    p = tmp_path / "jet.toml"
    p.write_text('scenario = "jet"\n' + textwrap.dedent(text))
    return p


@pytest.mark.parametrize("text, key, bound", [
    ("[run]\ndt = 1e-3\n", "[run.dt]", "dt <="),
    ("[particles]\nspeed_mean = 150.0\nspeed_sd = 5.0\n[run]\ndt = 1e-5\n", "[particles]", "sound speed"),
    ("[particles]\nspeed_sd = 12.0\n", "[particles.speed_sd]", "speed_sd < speed_mean / 3"),
    ("[nozzle]\nhalf_angle = 42.0\n", "[nozzle]", "half_angle >= 5"),
    ("[nozzle]\ndirection = [1.0, 0.0, -1.0]\n", "[nozzle.direction]", "unit vector"),
    ("[particles]\nradius = [1.0e-4]\n", "[particles.radius[0]]", "mjMINVAL"),
    ("[plate]\nkind = \"box\"\nsize = [0.02, 0.02]\n", "[plate.size]", "margin"),
    ("[particles]\nradius = [2e-4, 3e-4]\nprobability = [1.0]\n", "[particles.probability]", "expected 2"),
    ("[law]\nname = \"msf\"\nbogus = 1\n", "[law]", "bogus"),
    ("[law]\nname = \"nope\"\n", "[law.name]", "valid names"),
    ("[run]\nimpacts = 0\n", "[run.impacts]", ">= 1"),
    ("[run]\nspeed = 3\n", "[run.speed]", "valid keys"),
    ("[nozzle]\nposition = [0.0, 0.0, 0.01]\nstandoff = 0.02\n", "[nozzle.position]", "exclusive"),
])
def test_config_errors_name_the_file_key_and_bound(tmp_path, text, key, bound):
    p = _cfg(tmp_path, text)
    with pytest.raises(ConfigError) as exc:
        runner.load_config(p)
    msg = str(exc.value)
    assert str(p) in msg and key in msg and bound in msg, msg


def test_spec_refuses_a_time_step_that_skips_the_free_flight():
    with pytest.raises(ValueError, match=r"run.dt = .* dt <= "):
        small_spec(dt=5e-4)
    with pytest.raises(ValueError, match="aggregates.map_bins"):
        Bins(map_bins=(0, 3))


# ---------------------------------------------------------------- runner ---
RUN_CFG = """
[particles]
radius = [2.5e-4]
probability = [1.0]
feed_rate = 2.0e4
[run]
engines = ["mujoco"]
impacts = 24
chunk = 12
pool = 8
"""


@pytest.mark.mujoco
def test_run_report_and_resume_without_duplicates(tmp_path, monkeypatch):
    import pandas as pd

    cfg = _cfg(tmp_path, RUN_CFG)
    out = runner.run(cfg, tmp_path / "out", quiet=True)
    df = pd.read_csv(out / "records.csv")
    imp = df[df["kind"] == "impact"]
    assert len(imp) == 24 and len(df[df["kind"] == "summary"]) == 2
    # chunks are independent bursts with their own seeds: the emissions of a chunk are unique
    assert not imp.duplicated(["cell.chunk", "emission"]).any()
    for name in ("jet_energy_map.png", "jet_angle.png", "jet_pc_hist.png"):
        assert (out / "figures" / name).stat().st_size > 0
    report = (out / "report.md").read_text()
    assert "| mujoco | 24 |" in report
    # the report is rebuilt from the saved cells only
    (out / "report.md").unlink()
    for p in (out / "figures").iterdir():
        p.unlink()
    runner.report(out, quiet=True)
    assert (out / "report.md").read_text() == report
    # a lost cell is redone, finished ones are reused: every impact exactly once
    cells = sorted((out / "cells").glob("*.json"))
    first = json.loads(cells[0].read_text())
    cells[0].unlink()
    runner.run(cfg, out, quiet=True)
    m = json.loads((out / "manifest.json").read_text())
    assert m["cells"] == {"total": 2, "skipped": 1, "ran": 1}
    again = json.loads(cells[0].read_text())
    assert [r for r in again["records"] if r["kind"] == "impact"] == [
        r for r in first["records"] if r["kind"] == "impact"]  # deterministic: the same impacts again
    df2 = pd.read_csv(out / "records.csv")
    assert len(df2[df2["kind"] == "impact"]) == 24

    _coinciding_engines_stay_visible(out, tmp_path, monkeypatch)


def _coinciding_engines_stay_visible(out, tmp_path, monkeypatch):
    """Issue 12: in make demo's jet the two engines' Pc_max histograms agree
    bin for bin and MuJoCo's was hidden under pybullet's (jet_angle.png
    likewise). The run's summaries again as a second engine (the demo's case,
    exactly): every figure passes check_figure, which refuses a curve lying
    wholly under another (tests/test_robustness.py), and the histogram gives
    each engine its own panel."""
    from experiments._io import check_figure
    from experiments.scenarios.jet import reporting
    from experiments.sweep import cell_key, collect

    scenario, cfg, _ = runner.load_config(out / "config.toml")
    summary = [r for r in collect(out, {cell_key(c) for c in scenario.cells(cfg)}) if r.get("kind") == "summary"]
    assert summary
    saved = {}

    def keep(fig, path, **kw):
        check_figure(fig, Path(path).name)
        saved[Path(path).name] = [[t.get_text() for t in (ax.get_legend().get_texts() if ax.get_legend() else [])]
                                  for ax in fig.axes]

    monkeypatch.setattr("experiments._io.save_figure_atomic", keep)
    reporting.report(tmp_path / "two", summary + [dict(r, engine="pybullet") for r in summary], cfg)
    hist = saved["jet_pc_hist.png"]
    assert len(hist) == 2 and hist[0][0].startswith("mujoco") and hist[1][0].startswith("pybullet")
    assert any(t.startswith("mujoco") for t in saved["jet_angle.png"][0])
