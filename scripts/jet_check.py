"""The jet's records against msf_contact's reference solver (issue 10 item 5):
the numbers docs/jet.md quotes.

    .venv/bin/python scripts/jet_check.py reference     # plate impacts: cor_t, spin_out, W_diss_t, cor_n
    .venv/bin/python scripts/jet_check.py dense         # particle-particle records of the dense jet (MuJoCo)
    .venv/bin/python scripts/jet_check.py pp-rate       # impacts per CPU-second with particle-particle contacts
    .venv/bin/python scripts/jet_check.py pp-rate --warmup 100 --impacts 150 --broad off   # every pair read
    .venv/bin/python scripts/jet_check.py pp-rows       # sha256 of the rows of three particle-particle jets

``reference``: the jet of tests/test_jet.py (0.2 and 0.3 mm glass beads at
30 +- 3 m/s on polyurethane, 45 deg axis, 20 deg cone, 2e4 particles/s,
dt = 0.1 ms, a pool of 6 per class, 40 impacts) in MuJoCo and pybullet;
each row against :func:`msf_contact.simulate_impact` at the row's
``speed_in``, ``angle_deg`` and ``spin_in``: the largest relative error of
cor_t, spin_out and W_diss_t, the largest absolute error of cor_n, and the
ranges of the inputs.

``dense``: the dense jet of tests/test_jet_pp.py (beads overtaking each
other in flight, MuJoCo, 24 plate impacts): every particle-particle row
with its closing speed, cor_n against :func:`simulate_impact` for the
sphere-sphere pair, W_diss_n, W_diss_t, whether it began in an island and
whether it was alone (no other contact of either bead within half a step).

``pp-rate``: ``make bench``'s ``jet_pp`` jet: plate impacts per CPU-second
and CPU per step after ``--warmup`` impacts (the onset tables of the
bead-bead law are built in the first particle-particle contact: warm up
past it), with the MuJoCo adapter's broad phase automatic, on or off
(``--broad``; engines/mujoco/_broadphase.py) and its ``broad_late`` and
``broad_missed`` counts.

``pp-rows``: the sha256 of the JSON rows (sorted keys) of ``jet_pp``'s jet
(60 impacts), the normal jet of docs/jet.md (40) and the dense jet (24):
two trees giving the same hashes give the same rows to the bit (the jets
use only make_pool and run; copy the script into a tree without it).
"""

from __future__ import annotations

import argparse
import math
import warnings

from experiments.scenarios.jet import JetSpec, Nozzle, Particles, Plate, make_pool
from msf_contact import Body, ValidityWarning, preset, simulate_impact

ENGINES = ("mujoco", "pybullet")


def tests_jet_spec() -> JetSpec:
    """The jet of tests/test_jet.py's ``small_spec``."""
    return JetSpec(Nozzle.aimed((0.0, 0.0), (math.sqrt(0.5), 0.0, -math.sqrt(0.5)), 0.02, 20.0, 1e-3),
                   Particles(preset("glass"), (2.0e-4, 3.0e-4), (0.5, 0.5), 30.0, 3.0, 2e4),
                   Plate(preset("polyurethane")), dt=1e-4, pool=6)


def run_rows(engine: str, spec: JetSpec, impacts: int, seed=0):
    rows: list[dict] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        with make_pool(engine, spec, seed) as pool:
            pool.run(impacts, sink=rows.extend)
    return pool, rows


def reference(impacts: int = 40) -> None:
    spec = tests_jet_spec()
    laws = spec.plate_laws()
    plate = Body.half_space(spec.plate.material)
    print("| engine | impacts | speed_in [m/s] | angle [deg] | x_max/R | cor_t | spin_out | W_diss_t | cor_n (abs) |")
    print("|---|---:|---|---|---|---:|---:|---:|---:|")
    for engine in ENGINES:
        _, rows = run_rows(engine, spec, impacts)
        imp = [r for r in rows if r["kind"] == "impact"]
        worst = dict.fromkeys(("cor_t", "spin_out", "W_diss_t", "cor_n"), 0.0)
        for r in imp:
            ball = Body.sphere(spec.particles.material, r["radius"])
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ValidityWarning)
                ref = simulate_impact(laws[r["cls"]], ball, plate, r["speed_in"], r["angle_deg"], r["spin_in"],
                                      tangential=spec.tangential)
            for k in ("cor_t", "spin_out", "W_diss_t"):
                worst[k] = max(worst[k], abs(r[k] - getattr(ref, k)) / abs(getattr(ref, k)))
            worst["cor_n"] = max(worst["cor_n"], abs(r["cor_n"] - ref.cor_n))

        def rng(key, f=lambda r, k: r[k]):
            v = [f(r, key) for r in imp]
            return f"{min(v):.3g}-{max(v):.3g}"

        print(f"| {engine} | {len(imp)} | {rng('speed_in')} | {rng('angle_deg')} | "
              f"{rng('x', lambda r, _: r['x_max'] / r['radius'])} | {worst['cor_t']:.2g} | {worst['spin_out']:.2g} | "
              f"{worst['W_diss_t']:.2g} | {worst['cor_n']:.2g} |")


def dense(impacts: int = 24) -> None:
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_jet_pp import ALONE_WINDOW, R, dense_spec  # the test's jet and its window

    spec = dense_spec()
    _, rows = run_rows("mujoco", spec, impacts)
    law = spec.pp_laws()[(0, 0)]
    b = Body.sphere(spec.particles.material, R)
    spans: dict[int, list] = {}
    for r in rows:
        if r["kind"] == "impact":
            spans.setdefault(r["particle"], []).append((r["t_onset"], r["t_onset"] + r["tau"]))
        else:
            for i in (r["p1"], r["p2"]):
                spans.setdefault(i, []).append((r["t_onset"], r["t_end"]))
    pp = [r for r in rows if r["kind"] == "particle-particle"]
    print(f"{len(pp)} particle-particle records, {sum(r['kind'] == 'impact' for r in rows)} plate impacts")
    print("| beads | t_onset [ms] | v_n_in [m/s] | cor_n | reference | difference | W_diss_n [J] | W_diss_t [J] "
          "| island | alone |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---|---|")
    for r in pp:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            ref = simulate_impact(law, b, b, r["v_n_in"], 90.0)
        others = [s for i in (r["p1"], r["p2"]) for s in spans[i] if s != (r["t_onset"], r["t_end"])]
        alone = all(abs(s[0] - r["t_onset"]) > ALONE_WINDOW for s in others)
        print(f"| {r['p1']}, {r['p2']} | {r['t_onset'] * 1e3:.4f} | {r['v_n_in']:.3f} | {r['cor_n']:.6f} | "
              f"{ref.cor_n:.6f} | {r['cor_n'] - ref.cor_n:+.1e} | {r['W_diss_n']:.3g} | {r['W_diss_t']:.3g} | "
              f"{r['island']} | {alone} |")


def pp_spec(which: str = "bench") -> JetSpec:
    """``bench``: experiments/configs/jet.toml's jet (45 deg, 20 deg cone, 30 +- 3 m/s, 1e5 particles/s,
    dt = 0.1 ms) with one size class (0.25 mm) and particle-particle contacts (benchmarks.jet._pp_profile's);
    ``normal``: the jet aimed normal to the plate of docs/jet.md's known limits; ``dense``: the dense jet
    of tests/test_jet_pp.py."""
    if which == "bench":
        a = math.radians(45.0)
        return JetSpec(Nozzle.aimed((0.0, 0.0), (math.cos(a), 0.0, -math.sin(a)), 0.02, 20.0, 1e-3),
                       Particles(preset("glass"), (2.5e-4,), (1.0,), 30.0, 3.0, 1e5), Plate(preset("polyurethane")),
                       particle_particle=True, dt=1e-4)
    if which == "normal":
        return JetSpec(Nozzle.aimed((0, 0), (0, 0, -1), 0.02, 5.0, 1e-3),
                       Particles(preset("glass"), (2.5e-4,), (1.0,), 30.0, 3.0, 1e5), Plate(preset("polyurethane")),
                       particle_particle=True)
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_jet_pp import dense_spec  # the test's jet

    return dense_spec()


def pp_rate(impacts: int = 300, warmup: int = 0, broad: str = "auto") -> None:
    """Impacts per CPU-second of the pool (its own time.process_time) of pp_spec("bench") in MuJoCo after
    ``warmup`` impacts, CPU per step, the pool size and the particle-particle records; ``broad``: the
    adapter's broad phase (auto, on, off)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        with make_pool("mujoco", pp_spec("bench"), 0) as pool:
            pool.adapter.broad_phase = {"auto": None, "on": True, "off": False}[broad]
            pool.run(warmup)
            i0, c0, s0 = pool.counts.impacts, pool.cpu_s, pool.counts.steps
            pool.run(i0 + impacts)
    c = pool.counts
    di, dc, ds = c.impacts - i0, pool.cpu_s - c0, c.steps - s0
    print(f"{di} plate impacts after {i0} ({c.pp_impacts} particle-particle records in all), pool {pool.n} "
          f"({len(pool.pp_pairs)} particle-particle pairs), broad phase {broad}: {dc:.2f} s CPU, "
          f"{1e3 * dc / ds:.2f} ms per step ({ds} steps): {di / dc:.1f} impacts per CPU-second; "
          f"broad_late {pool.adapter.broad_late}, broad_missed {pool.adapter.broad_missed}")


def pp_rows() -> None:
    """sha256 of the rows of the three jets of pp_spec (module docstring)."""
    import hashlib
    import json

    for which, impacts in (("bench", 60), ("normal", 40), ("dense", 24)):
        h = hashlib.sha256()
        n = 0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            with make_pool("mujoco", pp_spec(which), 0) as pool:
                def sink(rows):
                    nonlocal n
                    for r in rows:
                        h.update(json.dumps(r, sort_keys=True, allow_nan=True).encode())
                        n += 1

                pool.run(impacts, sink=sink)
        print(f"{which}: {pool.counts.impacts} plate impacts, {pool.counts.pp_impacts} particle-particle, {n} rows, "
              f"{pool.counts.steps} steps: sha256 {h.hexdigest()}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("reference", "dense", "pp-rate", "pp-rows"))
    ap.add_argument("--impacts", type=int, default=300, help="pp-rate: plate impacts timed")
    ap.add_argument("--warmup", type=int, default=0, help="pp-rate: plate impacts before the timing")
    ap.add_argument("--broad", choices=("auto", "on", "off"), default="auto", help="pp-rate: the broad phase")
    a = ap.parse_args(argv)
    if a.what == "reference":
        reference()
    elif a.what == "dense":
        dense()
    elif a.what == "pp-rows":
        pp_rows()
    else:
        pp_rate(a.impacts, a.warmup, a.broad)


if __name__ == "__main__":
    main()
