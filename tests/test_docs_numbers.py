"""Numbers quoted in README.md and docs/ recomputed by the command written
beside them, at the precision quoted (issue 12: tests pin what the docs
claim). The cheap ones (a few seconds in all); the rest name their command
or test beside the number."""

import re
from pathlib import Path

import pytest

from tests.test_cli import run_json

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()

#: README row label -> the engine and extra flags of its command.
ROWS = {
    "MSF, reference solver": ("reference",),
    "MSF, closed forms (89), (90), (95)": ("closed-form",),
    "MSF in MuJoCo (dt 1 ms)": ("mujoco",),
    "MSF in pybullet (dt 1 ms)": ("pybullet",),
    "MuJoCo built-in (default solref)": ("mujoco-builtin",),
    "pybullet built-in (restitution 0.7)": ("pybullet-builtin", "--restitution", "0.7"),
}
DEMO_FLAGS = ("--ball", "natural-rubber", "--plate", "steel", "--radius", "0.02", "--dt", "1e-3", "--gap", "0.0003")


def cor_table():
    """{label: {speed: quoted COR}} from the README's table."""
    head, *_ = re.findall(r"^\| engine \|(.*)\|$", README, flags=re.M)
    speeds = [float(h.strip().split()[0]) for h in head.split("|")]
    table = {}
    for label, cells in re.findall(r"^\| ([^|]+?) \|((?: [0-9.]+ \|)+)$", README, flags=re.M):
        table[label] = dict(zip(speeds, (c.strip() for c in cells.strip(" |").split("|"))))
    return table


def test_readme_table_lists_every_row():
    assert set(cor_table()) == set(ROWS)


@pytest.mark.mujoco
@pytest.mark.parametrize("label", sorted(ROWS))
def test_readme_cor_table_at_the_quoted_precision(capsys, label):
    engine, *extra = ROWS[label]
    for speed, quoted in cor_table()[label].items():
        d = run_json(capsys, "impact", "--engine", engine, *DEMO_FLAGS, *extra, "--speed", repr(speed))
        assert f"{d['cor_n']:.4f}" == quoted, (label, speed)


def test_readme_tour_prints_what_it_says(capsys):
    block = re.search(r"```python\n(.*?)```", README, flags=re.S).group(1)
    quoted = re.search(r"^prints `([^`]+)`", README, flags=re.M).group(1)
    exec(compile(block, "README.md", "exec"), {})
    assert capsys.readouterr().out.strip() == quoted


def test_readme_convention_and_hunt_crossley_numbers(capsys):
    """README, Units and conventions: the two --convention durations, their
    ratio (1 - nu^2)^(-2/5) and Hunt-Crossley's 0.7885 for --hc-cor 0.8."""
    tau = {c: run_json(capsys, "impact", "--law", "hertz", "--ball-nu", "0.3", "--convention", c)["tau"]
           for c in ("msf", "hertz")}
    assert f"tau {tau['msf'] * 1e3:.6f} ms against {tau['hertz'] * 1e3:.6f} ms" in " ".join(README.split())
    assert tau["msf"] / tau["hertz"] == pytest.approx((1 - 0.3**2) ** -0.4, rel=1e-9)
    assert "3.8 % longer at nu = 0.3 and 11.6 % at nu = 0.49" in " ".join(README.split())
    assert f"{100 * ((1 - 0.3**2) ** -0.4 - 1):.1f} {100 * ((1 - 0.49**2) ** -0.4 - 1):.1f}" == "3.8 11.6"
    hc = run_json(capsys, "impact", "--law", "hunt-crossley", "--hc-cor", "0.8")["cor_n"]
    assert "`--hc-cor 0.8` gives 0.7885" in " ".join(README.split())
    assert f"{hc:.4f}" == "0.7885"


def _flat(text: str) -> str:
    """The text with its line breaks and runs of spaces as single spaces."""
    return " ".join(text.split())


@pytest.mark.mujoco
def test_readme_builtin_duration_and_penetration_against_msf(capsys):
    """README, What the demo shows: MuJoCo's default contact lasts 38-39 ms
    and penetrates 3.5-29 mm where MSF predicts 2.1-3.1 ms and 0.49-2.6 mm
    (the demo's impacts at 0.5 and 4 m/s, the ends of its sweep)."""
    got = {(e, v): run_json(capsys, "impact", "--engine", e, *DEMO_FLAGS, "--speed", repr(v))
           for e in ("mujoco-builtin", "reference") for v in (0.5, 4.0)}
    b05, b4, m05, m4 = got["mujoco-builtin", 0.5], got["mujoco-builtin", 4.0], got["reference", 0.5], got["reference", 4.0]
    quoted = (f"lasts {b4['tau'] * 1e3:.0f}-{b05['tau'] * 1e3:.0f} ms and penetrates "
              f"{b05['x_max'] * 1e3:.1f}-{b4['x_max'] * 1e3:.0f} mm where MSF predicts "
              f"{m4['tau'] * 1e3:.1f}-{m05['tau'] * 1e3:.1f} ms and {m05['x_max'] * 1e3:.2f}-{m4['x_max'] * 1e3:.1f} mm")
    assert quoted in _flat(README), quoted


THEORY = (ROOT / "docs" / "theory.md").read_text()


def test_theory_elliptic_table():
    """docs/theory.md 2a: (37) with k_p = 1 against Hertz's exact ellipse at
    the same approach, and Hertz's axis ratio, for each R_b/R_a of the table
    (the first column, R_b/R_a = 1, is the sphere: 0 and 1 by definition)."""
    import math

    from msf_contact.curvature import hertz_elliptic

    rows = {m.group(1).strip(): [c.strip() for c in m.group(2).strip().rstrip("|").split("|")]
            for m in re.finditer(r"^\| ([^|]+) \|((?:[^|\n]+\|)+)$", THEORY, flags=re.M)}
    ratios = [float(c) for c in rows["R_b/R_a"]]
    Ra, d = 0.02, 1e-5
    for k, q in enumerate(ratios[1:], start=1):
        h = hertz_elliptic(1 / (2 * q * Ra), 1 / (2 * Ra), d, 1.0)
        paper = 2 / 3 * (math.sqrt(Ra) + math.sqrt(q * Ra)) * d**1.5
        assert rows["(37) force / Hertz - 1"][k] == f"{100 * (paper / h.P - 1):+.2g} %", q
        assert rows["Hertz's axis ratio a/b"][k] == f"{max(h.a, h.b) / min(h.a, h.b):#.3g}", q
        assert rows["(26)'s sqrt(R_b/R_a)"][k] == f"{math.sqrt(q):#.3g}", q


def test_theory_capsule_line_contact():
    """docs/theory.md, line contact: a capsule (natural rubber on steel,
    R = 10 mm, L = 50 mm, 50 g, 1 m/s) lying flat and tilted 1 degree, the
    reference solver's peak force and COR at the quoted precision."""
    import math

    from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact
    from msf_contact.curvature import SideFootprint

    rubber, steel = preset("natural-rubber"), preset("steel")
    rec = {}
    for tilt in (0.0, 1.0):
        law = make_law("msf", ContactPair(rubber, steel),
                       Curvature.side_on_plane(SideFootprint(0.01, 0.05, math.radians(tilt))))
        rec[tilt] = simulate_impact(law, Body(rubber, 0.01, 0.05), Body.half_space(steel), 1.0)
    text = _flat(THEORY)
    assert f"peak force {rec[0.0].F_max:.1f} N lying flat" in text
    assert f"{rec[1.0].F_max:.1f} at 1 deg" in text
    assert f"COR {rec[0.0].cor_n:.3f} flat, {rec[1.0].cor_n:.3f} at 1 deg" in text


def test_theory_cradles():
    """docs/theory.md 5: the elastic Hertz cradle of 3 steel balls (R = 10 mm,
    touching, 1 m/s) leaves at -0.071, 0.076, 0.995 of v0; MSF cradles keep
    0.960 (3 balls) and 0.911 (5 balls) of the kinetic energy."""
    import numpy as np

    from tests.test_chain import cradle, hertz, msf

    v = cradle(hertz(), 3, 1.0).velocities
    text = _flat(THEORY)
    assert f"3 balls: {v[0]:.3f}, {v[1]:.3f}, {v[2]:.3f} of v0" in text
    keep = {n: float(np.sum(cradle(msf(), n, 1.0).velocities ** 2)) for n in (3, 5)}
    assert f"keeps {keep[3]:.3f} of its kinetic energy, 5 balls {keep[5]:.3f}" in text


def test_calibration_reference_numbers(capsys):
    """docs/calibration.md: the MSF reference the fits aim at (natural rubber,
    R = 0.02 m, on steel, 1 m/s): its COR, tau and the ball's mass."""
    d = run_json(capsys, "impact", "--ball", "natural-rubber", "--plate", "steel", "--radius", "0.02", "--speed", "1")
    text = _flat((ROOT / "docs" / "calibration.md").read_text())
    assert f"MSF reference: COR = {d['cor_n']:.4f}, tau = {d['tau'] * 1e3:.3f} ms" in text
    assert f"m = {d['inputs']['body1']['mass']:.4f} kg" in text


@pytest.mark.mujoco
def test_jet_doc_tangential_table(capsys):
    """docs/jet.md, tangential results at the jet's particles: a 0.25 mm glass
    bead at 30 m/s, 49 deg on polyurethane and on PTFE: x_max/R and cor_t of
    the reference solver and of MuJoCo at dt = 1e-4 s, at the quoted digits."""
    text = (ROOT / "docs" / "jet.md").read_text()
    for plate, label in (("polyurethane", "polyurethane"), ("ptfe", "PTFE")):
        row = re.search(rf"^\s*\| {label} \|((?: [0-9.]+ \|)+)$", text, flags=re.M)
        assert row, label
        cells = [c.strip() for c in row.group(1).strip(" |").split("|")]
        flags = ("--ball", "glass", "--plate", plate, "--radius", "2.5e-4", "--speed", "30", "--angle", "49",
                 "--dt", "1e-4")
        ref = run_json(capsys, "impact", "--engine", "reference", *flags)
        muj = run_json(capsys, "impact", "--engine", "mujoco", *flags)
        assert cells[0] == f"{ref['x_max'] / 2.5e-4:.2f}", label
        assert cells[1] == f"{ref['cor_t']:.4f}" and cells[2] == f"{muj['cor_t']:.4f}", label
