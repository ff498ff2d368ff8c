"""Calibration of the engines' own contact to MSF (experiments/calibrate.py)
and the calibration scenario: issue 4, "Calibrated built-in contact matches
MSF's COR within 1% at the calibration speed", and where it departs."""

from __future__ import annotations

import json
import math

import pytest

from engines.mujoco.builtin import linear_oscillator_cor
from experiments import calibrate as cal
from experiments.config import ConfigError
from msf_contact.materials import preset

#: The issue's acceptance: calibrated COR within 1% of MSF's at the calibration speed.
ACCEPT_COR_RTOL = 0.01
#: The force-zero oscillator inverse: brentq at xtol 1e-12 on a smooth function.
INVERSE_ATOL = 1e-9
#: MuJoCo's direct solref form (-w^2, -2/timeconst) is the same oscillator when
#: the impedance is constant (d = d_max cancels): equal to float round-off.
DIRECT_FORM_RTOL = 1e-9
#: MSF's contact duration scales as V^-1/5 (Hertz, (87)/(93)); the viscous
#: share and k_p(x) shift it slightly: measured 0.733 for 5x against 5^-0.2 = 0.725.
TAU_SCALING_RTOL = 0.02
#: MuJoCo's calibrated tau does not depend on speed (a linear oscillator),
#: so at 5x the calibration speed it departs from MSF's by 1 - 1/0.733 = -36%
#: (measured +36.3%); the test asks for more than 25%.
TAU_DEPARTURE_MIN = 0.25
#: ... while the COR stays: MSF's self-consistent COR moves by 0.18% from 1 to
#: 5 m/s (measured), MuJoCo's by nothing; half a percent bounds the departure.
COR_DEPARTURE_MAX = 0.005

RUBBER, STEEL = preset("natural-rubber"), preset("steel")
R, V = 0.02, 1.0


def problem(dt, **kw):
    return cal.problem_of(RUBBER, STEEL, R, V, dt, **kw)


def rel(got, want):
    return abs(got - want) / abs(want)


# ------------------------------------------------------------ formulas ---
@pytest.mark.parametrize("z", [0.02, 0.1, 0.3, 0.6])
def test_oscillator_inverse_and_duration(z):
    assert abs(cal.dampratio_for_cor(linear_oscillator_cor(z, "force-zero")) - z) <= INVERSE_ATOL
    # the force-zero end comes before half a damped period, pi / sqrt(1 - z^2)
    assert 0.0 < cal.force_zero_duration(z) < math.pi / math.sqrt(1 - z * z)
    assert cal.force_zero_duration(0.0) == pytest.approx(math.pi, abs=1e-12)


def test_bad_input_named():
    with pytest.raises(ValueError, match="dt"):
        problem(0.0)
    with pytest.raises(ValueError, match="phases"):
        problem(1e-4, phases=0)
    with pytest.raises(ValueError, match="form"):
        cal.calibrate(problem(1e-4), ("bullet",))
    with pytest.raises(ValueError, match="cor"):
        cal.dampratio_for_cor(1.5)


# ------------------------------------------------------ the acceptance ---
@pytest.mark.mujoco
@pytest.mark.parametrize("dt", [1e-4, 1e-3])
def test_mujoco_calibrated_cor_within_1pct(dt):
    p = problem(dt)
    ref = cal.reference(p)
    fit = cal.calibrate_mujoco(p, target=ref)
    assert fit.cor_ok and fit.tau_ok, fit.note
    # fresh engine runs, over twice the phases the fit saw: not fitted to its own sample
    check = cal.mujoco_builtin(cal.problem_of(RUBBER, STEEL, R, V, dt, phases=16), fit.params["solref"],
                               fit.params["solimp"])
    assert rel(check.cor_n, ref.cor_n) <= ACCEPT_COR_RTOL, (check.cor_n, ref.cor_n)
    assert rel(check.tau, ref.tau) <= fit.tau_rtol + dt / ref.tau
    # the direct form reported alongside is the same contact
    direct = cal.mujoco_builtin(p, fit.equivalent["solref_direct"], fit.params["solimp"])
    assert rel(direct.cor_n, fit.stats.cor_n) <= DIRECT_FORM_RTOL


@pytest.mark.pybullet
@pytest.mark.parametrize("dt", [1e-4, 1e-3])
def test_pybullet_calibrated_cor_within_1pct(dt):
    p = problem(dt, phases=4)
    ref = cal.reference(p)
    fit = cal.calibrate_pybullet_restitution(p, target=ref)
    assert fit.cor_ok and rel(fit.stats.cor_n, ref.cor_n) <= ACCEPT_COR_RTOL
    assert fit.stats.tau == pytest.approx(dt)  # a velocity target acts within one step


@pytest.mark.pybullet
def test_pybullet_spring_matches_cor_and_tau_at_fine_step_only():
    """Stiffness/damping reach COR and tau at 27 steps per contact; at 1 ms
    pybullet's implicit spring alone dissipates more than MSF (COR 0.36 < 0.73,
    measured), and the fit says so instead of returning a wrong number."""
    fine = cal.calibrate_pybullet_spring(problem(1e-4, phases=4))
    assert fine.cor_ok and fine.tau_ok
    assert rel(fine.stats.cor_n, fine.target_cor) <= ACCEPT_COR_RTOL
    coarse = cal.calibrate_pybullet_spring(problem(1e-3, phases=4))
    assert not coarse.cor_ok and "out of reach" in coarse.note
    assert coarse.params["contact_damping"] == 0.0 and coarse.stats.cor_n < coarse.target_cor


# ------------------------------------------------------ the departure ---
@pytest.mark.mujoco
def test_calibrated_mujoco_departs_in_tau_not_cor_at_5x_speed():
    p = problem(1e-4)
    fit = cal.calibrate_mujoco(p)
    ref1, ref5 = cal.reference(p), cal.reference(p, speed=5 * V)
    eng5 = cal.mujoco_builtin(p, fit.params["solref"], fit.params["solimp"], speed=5 * V)
    assert rel(ref5.tau / ref1.tau, 5.0 ** -0.2) <= TAU_SCALING_RTOL
    assert abs(eng5.tau - fit.stats.tau) <= p.dt  # MuJoCo's duration does not move with speed
    assert (eng5.tau - ref5.tau) / ref5.tau >= TAU_DEPARTURE_MIN
    assert rel(eng5.cor_n, ref5.cor_n) <= COR_DEPARTURE_MAX


@pytest.mark.mujoco
def test_onset_phase_spread_grows_at_robotics_step():
    """A single impact's COR depends on where in the step the contact
    begins: +-1% at 27 steps per contact, tens of % at 1 ms (measured
    0.67..0.88): why the calibration matches a phase mean."""
    fine = cal.calibrate_mujoco(problem(1e-4)).stats
    coarse = cal.calibrate_mujoco(problem(1e-3)).stats
    assert (fine.cor_n_max - fine.cor_n_min) / fine.cor_n < 0.03
    assert (coarse.cor_n_max - coarse.cor_n_min) / coarse.cor_n > 0.15


# ------------------------------------------------------ scenario and cli ---
SMALL = """scenario = "calibration"
[impact]
ball = "natural-rubber"
plate = "steel"
radius = 0.02
[calibration]
speed = 1.0
dt = [1e-4]
phases = 2
forms = ["mujoco-solref", "pybullet-restitution"]
[departure]
speed_factors = [0.5, 1.0, 2.0]
angles = [90.0, 45.0]
msf_engines = []
"""


@pytest.mark.mujoco
@pytest.mark.pybullet
def test_scenario_report_states_the_fitted_numbers(tmp_path):
    from experiments.runner import run

    cfg = tmp_path / "cal.toml"
    cfg.write_text(SMALL)
    out = run(cfg, tmp_path / "out", quiet=True)
    rows = [json.loads(x) for x in (out / "records.jsonl").read_text().splitlines()]
    fit = next(r for r in rows if r["cell.kind"] == "fit" and r["engine"] == "mujoco-solref")
    assert rel(fit["stats"]["cor_n"], fit["target_cor"]) <= ACCEPT_COR_RTOL
    md = (out / "report.md").read_text()
    tc, z = fit["params"]["solref"]
    assert f"solref = ({tc:.6g}, {z:.6g})" in md
    assert (out / "figures" / "speed_departure_dt0.0001.png").is_file()
    assert (out / "figures" / "angle_departure_dt0.0001.png").is_file()


@pytest.mark.parametrize("text, needle", [
    (SMALL.replace('radius = 0.02', 'radius = 0.02\nspeed = 2.0'), r"\[impact.speed\] is set by"),
    (SMALL.replace("dt = [1e-4]", "dt = [0.5]"), r"\[calibration.dt\[0\]\] = 0.5 is above the bound <= 0.01"),
    (SMALL.replace("phases = 2", "phases = 0"), r"\[calibration.phases\] = 0 is below the bound >= 1"),
    (SMALL.replace('forms = ["mujoco-solref", "pybullet-restitution"]', 'forms = ["bullet"]'), r"forms\[0\]"),
    (SMALL.replace("speed = 1.0", "speed = 1.0\nsped = 2"), r"\[calibration.sped\] is not a known key"),
])
def test_bad_config_names_file_key_and_bound(tmp_path, text, needle):
    from experiments.runner import load_config

    cfg = tmp_path / "bad.toml"
    cfg.write_text(text)
    with pytest.raises(ConfigError, match=needle) as e:
        load_config(cfg)
    assert str(cfg) in str(e.value)


@pytest.mark.mujoco
def test_cli_calibrate_json(capsys):
    from experiments.cli import main

    assert main(["calibrate", "--ball", "natural-rubber", "--plate", "steel", "--radius", "0.02", "--speed", "1",
                 "--dt", "1e-4", "--form", "mujoco-solref", "--phases", "2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    f = d["fits"]["mujoco-solref"]
    assert rel(f["stats"]["cor_n"], d["reference"]["cor_n"]) <= ACCEPT_COR_RTOL
    assert f["fitted"] == ["timeconst", "dampratio"] and len(f["params"]["solref"]) == 2
