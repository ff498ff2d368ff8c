"""Numbers quoted in README.md recomputed by the command written beside them,
at the precision quoted (issue 12: tests pin what the docs claim)."""

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
