"""The paddle scenario (experiments/scenarios/paddle.py): a paddle on a
hinge striking a falling ball, MSF through the adapters and the built-in
contact, against the reference solver with the paddle's effective mass."""

from __future__ import annotations

import math

import pytest

from experiments.config import ConfigError, validate
from experiments.scenarios import paddle as P

#: A free paddle's strike vs the reference solver with the effective mass
#: I/d^2 at the hit point: the face turns by ~u tau / d during the contact
#: (0.02 rad at u = 2 m/s), outside the reference model; measured +0.06%
#: (MuJoCo) and +0.07% (pybullet) at u = 2 m/s, dt = 1e-4 s; kept 3x.
FREE_RTOL = 2e-3
#: Angular momentum about the hinge axis of ball + free paddle, relative to
#: m d (v_b + u): the forces are equal and opposite at one point, so both
#: engines keep it to round-off (measured 1e-15); 1e-9 leaves room for
#: float64 accumulation over the steps.
ANGULAR_MOMENTUM_RTOL = 1e-9
#: A drive-held paddle vs the reference with an infinite paddle mass. The
#: drive is an actuator force, not a constraint: within the 2.7 ms contact
#: the paddle's own inertia takes part and the drive restores the swing a
#: little later (the manager sees the drive force one step late, as a_ext).
#: Measured +0.96% at 27 steps per contact and -3.0% at 1 ms in both engines,
#: against 0.005% for a free 1000 kg paddle. Bound: 2% at 1e-4 s, a limit of
#: the model (no drive dynamics in the reference), documented in docs/calibration.md.
DRIVEN_RTOL = 2e-2

ARGV = ("--ball", "natural-rubber", "--plate", "steel", "--radius", "0.02")
PAD = validate({"scenario": "paddle"}, P.SCHEMA, "<test>")["paddle"]
VB = 1.0


def strike(engine, u, drive, dt=1e-4):
    s = P._setup(ARGV, VB + u)
    gap = 0.5 * (VB + u) * dt
    if engine == "mujoco":
        r = P.strike_mujoco(s.law, s.ball, PAD, VB, u, drive, dt, gap, "implicitfast", None)
    else:
        r = P.strike_pybullet(s.law, s.ball, PAD, VB, u, drive, dt, gap, None)
    m_eff = math.inf if drive == "driven" else r["m_eff"]
    return r, P.predicted_rebound(s.law, s.ball, s.plate, VB, u, m_eff), s


def rel(got, want):
    return abs(got - want) / abs(want)


ENGINES = [pytest.param("mujoco", marks=pytest.mark.mujoco), pytest.param("pybullet", marks=pytest.mark.pybullet)]


@pytest.mark.parametrize("engine", ENGINES)
def test_free_paddle_matches_reference_with_effective_mass_and_rebound_grows(engine):
    speeds = []
    for u in (0.0, 1.0, 2.0):
        r, pred, s = strike(engine, u, "free")
        assert rel(r["vz"], pred["v_out"]) <= FREE_RTOL, (u, r["vz"], pred["v_out"])
        speeds.append(math.hypot(r["vx"], r["vz"]))
        # angular momentum about the hinge (+y through the origin): ball orbit + spin + paddle
        d = PAD["hit_at"]
        I_hinge = r["m_eff"] * d * d
        L0 = s.ball.mass * d * VB + I_hinge * (-u / d)
        L1 = (s.ball.mass * (r["z"] * r["vx"] - r["x"] * r["vz"]) + s.ball.J * r["wy"]
              + I_hinge * (-r["u_after"] / d))
        assert abs(L1 - L0) <= ANGULAR_MOMENTUM_RTOL * s.ball.mass * d * (VB + u), (engine, u, L0, L1)
    assert speeds[0] < speeds[1] < speeds[2]


@pytest.mark.parametrize("engine", ENGINES)
def test_driven_paddle_is_near_the_infinite_mass_reference(engine):
    r, pred, _ = strike(engine, 1.0, "driven")
    assert abs(r["u_after"] - 1.0) <= 1e-3  # the drive held the swing
    assert rel(r["vz"], pred["v_out"]) <= DRIVEN_RTOL, (r["vz"], pred["v_out"])


@pytest.mark.mujoco
@pytest.mark.pybullet
def test_scenario_cells_default_vs_calibrated_builtin(tmp_path):
    """A tiny sweep: the calibrated built-in contacts land near the reference
    prediction for a free paddle, MuJoCo's default solref (0.02, 1: critically
    damped) far below it."""
    from experiments.runner import run

    cfg = tmp_path / "p.toml"
    cfg.write_text('scenario = "paddle"\n[impact]\nball = "natural-rubber"\nplate = "steel"\nradius = 0.02\n'
                   '[strike]\npaddle_speeds = [0.0, 1.0]\ndrives = ["free"]\ndt = [1e-4]\nphases = 2\n'
                   '[engines]\nrun = ["mujoco-builtin", "pybullet-builtin"]\ncalibration_speed = 1.5\n')
    out = run(cfg, tmp_path / "out", quiet=True)
    import json

    rows = [json.loads(x) for x in (out / "records.jsonl").read_text().splitlines()]
    for r in rows:
        err = rel(r["vz"], r["pred_v_out"])
        if r["cell.contact"] == "calibrated":
            assert err <= 0.01, (r["cell.engine"], r["cell.u"], r["vz"], r["pred_v_out"])
        elif r["cell.engine"] == "mujoco-builtin":
            assert r["cor_rel"] < 0.5 * r["pred_cor"]
    assert (out / "figures" / "paddle_free_dt0.0001.png").is_file()


def test_bad_config_named(tmp_path):
    from experiments.runner import load_config

    cfg = tmp_path / "bad.toml"
    cfg.write_text('scenario = "paddle"\n[impact]\nball = "natural-rubber"\n[paddle]\nlength = 0.2\nhit_at = 0.25\n')
    with pytest.raises(ConfigError, match=r"\[paddle.hit_at\] = 0.25 m must be < \[paddle.length\]"):
        load_config(cfg)
    cfg.write_text('scenario = "paddle"\n[strike]\nphases = 100\n')
    with pytest.raises(ConfigError, match=r"\[strike.phases\] = 100 is above the bound <= 64"):
        load_config(cfg)
    cfg.write_text('scenario = "paddle"\n[impact]\nspeed = 3.0\n')
    with pytest.raises(ConfigError, match=r"\[impact.speed\] is set by the paddle scenario"):
        load_config(cfg)


def test_a_ball_resting_on_the_face_is_no_rebound():
    """Issue 12: a driven paddle at u = 0 under pybullet's default
    restitution 0 leaves the ball at v_z ~ 1e-5 m/s (0/4 phases carried); the
    report printed "-100.00 %" and a direction of "+90.00" degrees for it
    (the angle of a vanishing vector). Below REBOUND_COR_MIN of the closing
    speed it is "no rebound"; MuJoCo's default contact (relative COR ~0.12,
    the lowest real rebound here) still counts."""
    resting = {"vz": 1e-5, "vx": 1e-5, "cor_rel": 1e-5, "carried": 0}
    assert not P._rebounded(resting, 4)
    low = {"vz": 0.12, "vx": 0.0, "cor_rel": 0.12, "carried": 0}
    assert P._rebounded(low, 4)
    assert not P._rebounded(dict(low, carried=4), 4)
