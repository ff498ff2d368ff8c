"""The jet's report: aggregates merged per engine, the reference solver's
values against angle, figures and tables (:func:`report`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from msf_contact import ValidityWarning

from .aggregates import JetAggregates, finnie
from .scenario import spec_from_config
from .spec import SPEED_TRUNCATION_SD, JetSpec


# --------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------
def _engine_style(j: int) -> dict:
    """Marker and width of the j-th engine's curves in a figure where the
    engines may coincide: the first wide with large hollow markers, the
    others thinner with smaller filled markers of their own shape on top."""
    marks = ("o", "x", "+", "^")
    if j == 0:
        return {"marker": marks[0], "ms": 8, "mfc": "none", "lw": 2.6}
    return {"marker": marks[j % len(marks)], "ms": 5, "lw": 1.0}


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

    from ..._io import save_figure_atomic

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
             "results agree with it, the tangential ones (cor_t, spin, W_diss_t) included, though the beads sink "
             f"to x_max/R = {xr:.2f} within one step: the sub-cycle moves the contact point with the overlap "
             "(lever arm R - x/2; docs/engines.md, deep and oblique contacts). "
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
    fig, axes = plt.subplots(1, 2, figsize=(15, 4.6))
    # the angle axis spans the data (bins with impacts), not 0-90 deg
    spans = [ba[e]["centre"][ba[e]["n"] > 0] for e in engines]
    spans = np.concatenate([s for s in spans if s.size]) if any(s.size for s in spans) else np.array([0.5, 90.0])
    a_lo, a_hi = max(float(spans.min()) - 5.0, 0.0), min(float(spans.max()) + 5.0, 90.0)
    fa = np.linspace(max(a_lo, 0.5), a_hi, 180)
    # the engines often coincide (same law, same sub-cycle): each engine its own marker and width, the
    # first drawn wide with hollow markers, the next thin with small filled ones on top (not hidden: check_figure)
    for j, e in enumerate(engines):
        b = ba[e]
        st = _engine_style(j)
        m = b["n"] > 0
        axes[0].errorbar(b["centre"][m], b["cor_n"][m], yerr=b["cor_n_sd"][m], fmt="-", color=colors[e], capsize=2,
                         label=f"{e}: cor_n (mean, sd)", **st)
        mt = m & np.isfinite(b["cor_t"])
        axes[0].plot(b["centre"][mt], b["cor_t"][mt], "--", color=colors[e], label=f"{e}: cor_t (mean)", **st)
        frac = b["fraction"][m]
        axes[1].plot(b["centre"][m], frac / np.nanmax(frac), "-", color=colors[e],
                     label=f"{e}: W/E_in (max {np.nanmax(frac):.3f})", **st)
        Wm = b["W"][m]
        axes[1].plot(b["centre"][m], Wm / np.nanmax(Wm), ":", color=colors[e],
                     label=f"{e}: W per impact (max {np.nanmax(Wm) * 1e6:.3g} uJ)", **st)
    axes[1].plot(fa, finnie(fa), "k-", lw=1.5, label="Finnie (1960) f(a)/f_max")
    ref = reference_by_angle(spec)
    if ref is not None:
        ra = np.asarray(ref["angle"], dtype=float)
        keep = (ra >= a_lo) & (ra <= a_hi)
        axes[0].plot(ra[keep], np.asarray(ref["cor_n"], dtype=float)[keep], "k-", lw=1,
                     label=f"reference solver, {ref['label']}: cor_n")
        axes[0].plot(ra[keep], np.asarray(ref["cor_t"], dtype=float)[keep], "k--", lw=1,
                     label="reference solver: cor_t")
    axes[0].set_ylabel("coefficient of restitution [-]")
    axes[1].set_ylabel("normalised to the maximum [-]")
    for ax in axes:
        ax.set_xlabel("impact angle to the plate [deg]")
        ax.set_xlim(a_lo, a_hi)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside the data
    fig.tight_layout()
    save_figure_atomic(fig, out / "figures" / "jet_angle.png", dpi=110)
    plt.close(fig)
    figs.append("jet_angle.png")
    # one panel per engine (their histograms often coincide bin for bin: one curve would hide the other),
    # x from the filled bins and the coating strength, not the histogram's whole log grid
    fig, axes = plt.subplots(len(engines), 1, figsize=(10, 1.2 + 2.4 * len(engines)), sharex=True, sharey=True,
                             squeeze=False)
    filled = [pl.strength / 1e6]
    for e in engines:
        a = merged[e][0]
        nz = np.flatnonzero(np.asarray(a.pc_counts[1:-1]) > 0)
        if nz.size:
            filled += [a.pc_edges[nz[0]] / 1e6, a.pc_edges[nz[-1] + 1] / 1e6]
    counts = [np.asarray(merged[e][0].pc_counts) for e in engines]
    for ax, e in zip(axes[:, 0], engines):
        a = merged[e][0]
        ax.stairs(a.pc_counts[1:-1], a.pc_edges / 1e6, color=colors[e], lw=1.5,
                  label=f"{e}: {a.n} impacts, {a.n_above_strength / max(a.n, 1):.1%} above strength")
        ax.axvline(pl.strength / 1e6, color="k", ls="--", label=f"coating strength {pl.strength / 1e6:g} MPa")
        ax.set_xscale("log")
        ax.set_ylabel("impacts per bin")
        ax.set_title(e, fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    if len(engines) > 1 and all(c.shape == counts[0].shape for c in counts):
        n_bins = int(np.count_nonzero(np.any([c != counts[0] for c in counts], axis=0)))
        fig.suptitle(f"Pc_max histograms: the engines' counts differ in {n_bins} of the {counts[0].size - 2} bins "
                     "and 2 out-of-range bins", fontsize=9)
    ax = axes[-1, 0]
    ax.set_xlim(min(filled) / 1.3, max(filled) * 1.3)
    fmt = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")  # plain MPa numbers on the log axis
    ax.xaxis.set_major_formatter(fmt)
    ax.xaxis.set_minor_formatter(fmt)
    ax.set_xlabel("peak contact pressure Pc_max (20) [MPa]")
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
