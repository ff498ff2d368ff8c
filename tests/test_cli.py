"""The msf-contact command line against its contract (issue 2 "Command line"
and "Bad input"): values against the library called directly, never against
hard-coded numbers."""

import json
import math
import subprocess
import sys

import pytest

from experiments import cli
from msf_contact import (
    CONTRACT_KEYS,
    Body,
    ContactPair,
    Curvature,
    Material,
    closed_forms as cf,
    make_law,
    preset,
    simulate_impact,
)
from msf_contact.geometry import peak_pressure_closed
from msf_contact.identification import ImpactMeasurement, identify_printed

#: Issue 2 acceptance of the identification round trip.
ROUNDTRIP_RTOL = 1e-4
#: The CLI and a direct call run the same deterministic computation, and JSON
#: keeps Python floats exactly (repr round trip): equality, with a margin of a
#: few ulps for an arithmetic re-ordering.
SAME_RTOL = 1e-14


def run(capsys, *argv):
    """main(argv) in-process; returns (exit code, stdout, stderr)."""
    try:
        code = cli.main(list(argv))
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def _no_constants(name):
    raise ValueError(f"{name} is not JSON")


def run_json(capsys, *argv):
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    return json.loads(out, parse_constant=_no_constants)  # strict JSON: no NaN/Infinity


def direct(ball, plate, R, V, law="msf", angle=90.0, spin=0.0, mass=None, **opts):
    law_obj = make_law(law, ContactPair(ball, plate), Curvature.sphere_on_plane(R), **opts)
    return simulate_impact(law_obj, Body.sphere(ball, R, mass), Body.half_space(plate), V, angle, spin)


# ------------------------------------------------------------------ impact ---
def test_impact_json_has_the_contract_keys_and_the_reference_values(capsys):
    d = run_json(capsys, "impact", "--ball", "golf-core", "--radius", "0.02", "--speed", "3")
    assert set(CONTRACT_KEYS) <= set(d)
    assert d["inputs"]["speed"] == 3.0 and d["inputs"]["body1"]["radius"] == 0.02
    assert d["inputs"]["materials"]["ball"]["name"] == "golf-core"
    assert d["engine"] == "reference" and d["law"] == "msf"
    rec = direct(preset("golf-core"), Material.rigid_body(), 0.02, 3.0).to_dict()
    for k in CONTRACT_KEYS:
        if rec[k] is None:
            assert d[k] is None, k
        else:
            assert d[k] == pytest.approx(rec[k], rel=SAME_RTOL, abs=0.0), k


def test_impact_oblique_with_presets_and_spin(capsys):
    d = run_json(capsys, "impact", "--ball", "Steel", "--plate", "aluminium", "--radius", "0.005",
                 "--speed", "2", "--angle", "30", "--spin", "-40", "--tangential", "paper", "--mu", "0.3")
    rec = direct(preset("steel"), preset("aluminium"), 0.005, 2.0, angle=30.0, spin=-40.0).to_dict()
    rec_paper = simulate_impact(
        make_law("msf", ContactPair(preset("steel"), preset("aluminium")), Curvature.sphere_on_plane(0.005), mu=0.3),
        Body.sphere(preset("steel"), 0.005), Body.half_space(preset("aluminium")), 2.0, 30.0, -40.0,
        tangential="paper").to_dict()
    for k in ("cor_n", "cor_t", "spin_out", "W_diss_t", "tau"):
        assert d[k] == pytest.approx(rec_paper[k], rel=SAME_RTOL), k
    assert d["cor_t"] != rec["cor_t"]  # the flags reached the solver: contact-point mode differs
    assert d["parameters"]["mu"] == 0.3 and d["inputs"]["tangential"] == "paper"


def test_impact_material_flags_and_mass(capsys):
    d = run_json(capsys, "impact", "--ball-E", "2e7", "--ball-tan-delta", "0.05", "--ball-nu", "0.4",
                 "--mass", "0.02", "--plate-E", "1e9", "--plate-tan-delta", "0.01", "--kp-mode", "msf-small",
                 "--omega", "5000", "--separation", "overlap-zero", "--convention", "hertz")
    ball = Material("b", 2e7, 0.05, 0.4, preset(cli.DEFAULT_BALL).density)
    plate = Material("p", 1e9, 0.01, **{k: v for k, v in cli.PLATE_BASE.items() if k != "tan_delta"})
    law = make_law("msf", ContactPair(ball, plate, "hertz"), Curvature.sphere_on_plane(cli.DEFAULT_RADIUS),
                   kp_mode="msf-small", omega=5000.0, separation="overlap-zero")
    rec = simulate_impact(law, Body.sphere(ball, cli.DEFAULT_RADIUS, 0.02), Body.half_space(plate),
                          cli.DEFAULT_SPEED).to_dict()
    for k in ("cor_n", "tau", "x_max", "F_max", "omega_x"):
        assert d[k] == pytest.approx(rec[k], rel=SAME_RTOL), k
    assert d["omega_x"] == 5000.0 and d["ended_by"] == "overlap-zero"
    assert d["inputs"]["body1"]["mass"] == 0.02


@pytest.mark.parametrize("law", ["hertz", "kuwabara-kono", "hunt-crossley", "spring-dashpot"])
def test_comparison_laws_with_their_defaults(capsys, law):
    """Defaults: A of (99) with k_p = 1 and tau of (95) as printed, the
    Hunt-Crossley target (89), the spring-dashpot's own (84)."""
    d = run_json(capsys, "impact", "--law", law, "--ball", "polyurethane", "--speed", "2")
    ball, rigid = preset("polyurethane"), Material.rigid_body()
    R, V = cli.DEFAULT_RADIUS, 2.0
    m = Body.sphere(ball, R).mass
    opts = {}
    if law == "kuwabara-kono":
        tau = cf.tau_95_as_printed(m, V, ball.E_storage, R, 1.0, cf.cor_89(ball.tan_delta))
        opts["A"] = float(cf.brilliantov_A_99(ball.tan_delta, ball.nu, 1.0, tau))
        assert d["parameters"]["A"] == pytest.approx(opts["A"], rel=SAME_RTOL)
    if law == "hunt-crossley":
        opts["cor"] = float(cf.cor_89(ball.tan_delta))
        assert d["parameters"]["cor"] == pytest.approx(opts["cor"], rel=SAME_RTOL)
    rec = direct(ball, rigid, R, V, law=law, **opts).to_dict()
    for k in ("cor_n", "tau", "x_max", "F_max"):
        assert d[k] == pytest.approx(rec[k], rel=SAME_RTOL), k


def test_law_parameters_given_explicitly(capsys):
    d = run_json(capsys, "impact", "--law", "kuwabara-kono", "--A", "2e-6")
    assert d["parameters"]["A"] == 2e-6
    d = run_json(capsys, "impact", "--law", "hunt-crossley", "--hc-cor", "0.6")
    assert d["parameters"]["cor"] == 0.6
    d = run_json(capsys, "impact", "--law", "spring-dashpot", "--k", "1e5", "--c", "0")
    assert d["parameters"]["k"] == 1e5
    # an undamped linear spring: elastic, half a period pi sqrt(m/k)
    m = Body.sphere(preset(cli.DEFAULT_BALL), cli.DEFAULT_RADIUS).mass
    assert d["cor_n"] == pytest.approx(1.0, rel=1e-9)  # reference solver tolerance (1e-11) with margin
    assert d["tau"] == pytest.approx(math.pi * math.sqrt(m / 1e5), rel=1e-9)


def test_table_output_has_units_and_values(capsys):
    code, out, _ = run(capsys, "impact", "--ball", "glass", "--radius", "0.003")
    assert code == 0
    rec = direct(preset("glass"), Material.rigid_body(), 0.003, cli.DEFAULT_SPEED).to_dict()
    lines = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines()[1:] if ln.strip()}
    for key, unit in (("cor_n", "-"), ("tau", "s"), ("x_max", "m"), ("F_max", "N"), ("Pc_max", "Pa"),
                      ("W_diss_n", "J"), ("omega_x", "rad/s")):
        value, got_unit = lines[key]
        assert float(value) == pytest.approx(rec[key], rel=5e-6)  # printed with 6 significant digits
        assert got_unit == unit
    assert lines["cor_t"][0] == "-"  # None: a normal impact has no tangential COR


# ------------------------------------------------------------- closed form ---
def test_closed_form_engine_msf_equals_the_closed_forms(capsys):
    d = run_json(capsys, "impact", "--engine", "closed-form", "--ball", "golf-core", "--speed", "4")
    ball = preset("golf-core")
    R, V = cli.DEFAULT_RADIUS, 4.0
    m, E, td = Body.sphere(ball, R).mass, ball.E_storage, ball.tan_delta
    k_p = cf.kp_for_mode("msf", m, V, E, td, R)
    cor = cf.cor_89(td)
    tau = cf.tau_95_as_printed(m, V, E, R, k_p, cor)
    x_m = cf.x_max_90(m, V, E, td, R, k_p)
    assert d["engine"] == "closed-form"
    assert set(CONTRACT_KEYS) <= set(d)
    assert d["cor_n"] == pytest.approx(cor, rel=SAME_RTOL)
    assert d["x_max"] == pytest.approx(x_m, rel=SAME_RTOL)
    assert d["tau"] == pytest.approx(tau, rel=SAME_RTOL)
    assert d["omega_x"] == pytest.approx(math.pi / tau, rel=SAME_RTOL)  # (87)
    assert d["tau1"] / d["tau2"] == pytest.approx(cor, rel=SAME_RTOL)  # (62)
    assert d["tau1"] + d["tau2"] == pytest.approx(tau, rel=SAME_RTOL)
    assert d["closed_forms"]["tau_95"] == pytest.approx(cf.tau_95(m, V, E, R, k_p, cor), rel=SAME_RTOL)
    assert d["W_diss_n"] == pytest.approx(0.5 * m * V**2 * (1 - cor**2), rel=SAME_RTOL)
    law = make_law("msf", ContactPair(ball, Material.rigid_body()), Curvature.sphere_on_plane(R))
    assert d["Pc_max"] == pytest.approx(float(peak_pressure_closed(x_m, 0.0, E, 0.0, law.geom, "msf")),
                                        rel=SAME_RTOL)
    assert d["F_max"] is None  # no closed form for the viscoelastic peak


def test_closed_form_engine_hertz(capsys):
    d = run_json(capsys, "impact", "--engine", "closed-form", "--law", "hertz", "--ball", "steel")
    ball = preset("steel")
    R, V = cli.DEFAULT_RADIUS, cli.DEFAULT_SPEED
    m = Body.sphere(ball, R).mass
    assert d["cor_n"] == 1.0
    assert d["x_max"] == pytest.approx(cf.hertz_x_max(m, V, ball.E_storage, R), rel=SAME_RTOL)
    assert d["tau"] == pytest.approx(cf.hertz_tau(m, V, ball.E_storage, R), rel=SAME_RTOL)
    assert d["F_max"] == pytest.approx(cf.hertz_F_max(m, V, ball.E_storage, R), rel=SAME_RTOL)


def test_closed_form_engine_refuses_laws_without_closed_forms(capsys):
    code, _, err = run(capsys, "impact", "--engine", "closed-form", "--law", "kuwabara-kono")
    assert code == cli.EXIT_BAD_INPUT
    assert "--engine closed-form" in err and "kuwabara-kono" in err


# --------------------------------------------------------------- bad input ---
#: (argv after "impact", substrings the message must hold: parameter, value, bound)
BAD_IMPACT = [
    (["--ball-E", "-1e6"], ["--ball-E", "-1000000.0", "> 0"]),
    (["--spin", "-inf"], ["--spin", "-inf", "infinite"]),
    (["--ball-E", "0"], ["--ball-E", "0.0", "> 0"]),
    (["--plate-E", "-5"], ["--plate-E", "-5.0", "> 0"]),
    (["--radius", "0"], ["--radius", "0.0", "> 0"]),
    (["--radius", "-0.01"], ["--radius", "-0.01", "> 0"]),
    (["--mass", "-1"], ["--mass", "-1.0", "> 0"]),
    (["--density", "0"], ["--density", "0.0", "> 0"]),
    (["--ball-tan-delta", "-0.1"], ["--ball-tan-delta", "-0.1", ">= 0"]),
    (["--ball-tan-delta", "0.5", "--strict"], ["tg(beta)", "0.5", "1/3", "(100)"]),
    (["--speed", "500"], ["speed", "500.0", "sound speed"]),
    (["--speed", "0"], ["--speed", "0.0", "> 0"]),
    (["--ball", "natural-rubber", "--mass", "1", "--speed", "5.2"], ["x_max", "2R", "0.02", "(15)"]),
    (["--speed", "nan"], ["--speed", "nan", "NaN"]),
    (["--radius", "inf"], ["--radius", "inf", "infinite"]),
    (["--ball-E", "nan"], ["--ball-E", "nan", "NaN"]),
    (["--angle", "120"], ["--angle", "120.0", "(0, 90]"]),
    (["--ball-nu", "0.5"], ["--ball-nu", "0.5", "(-1, 0.5)"]),
    (["--omega", "-3"], ["--omega", "-3.0", "> 0"]),
    (["--omega", "fast"], ["--omega", "'fast'", "self-consistent"]),
    (["--mu", "-0.2"], ["--mu", "-0.2", "> 0"]),
    (["--A", "1e-6"], ["--A", "kuwabara-kono", "msf"]),
    (["--law", "hertz", "--kp-mode", "msf"], ["--kp-mode", "msf"]),
    (["--law", "hunt-crossley", "--hc-cor", "1.5"], ["--hc-cor", "1.5", "[0.001, 1]"]),
    (["--law", "kuwabara-kono", "--A", "-1"], ["--A", "-1.0", ">= 0"]),
    (["--plate-tan-delta", "0.1"], ["--plate-tan-delta", "--plate-E"]),
    (["--mass", "0.1", "--density", "1000"], ["--mass", "--density"]),
]


@pytest.mark.parametrize("argv, needles", BAD_IMPACT, ids=[" ".join(a) for a, _ in BAD_IMPACT])
def test_bad_impact_input(capsys, argv, needles):
    code, out, err = run(capsys, "impact", *argv)
    assert code == cli.EXIT_BAD_INPUT
    assert out == ""  # refused before any result
    assert err.startswith("msf-contact: error: ")
    for needle in needles:
        assert needle in err, (needle, err)


@pytest.mark.parametrize("argv, flag", [
    (["--law", "coulomb"], "--law"), (["--ball", "unobtainium"], "--ball"), (["--plate", "wood"], "--plate"),
    (["--engine", "bullet"], "--engine"), (["--kp-mode", "flat"], "--kp-mode"),
])
def test_unknown_names(capsys, argv, flag):
    code, _, err = run(capsys, "impact", *argv)
    assert code == 2
    assert f"argument {flag}: invalid choice: '{argv[1]}'" in err


def test_not_a_number(capsys):
    code, _, err = run(capsys, "impact", "--speed", "fast")
    assert code == 2
    assert "argument --speed: 'fast' is not a number" in err


def test_tan_delta_above_the_bound_warns_without_strict(capsys):
    code, out, err = run(capsys, "impact", "--ball-tan-delta", "0.4", "--json")
    assert code == 0
    assert "msf-contact: warning:" in err and "(100)" in err and "0.4" in err
    assert err.count("warning") == 1
    assert json.loads(out)["parameters"]["tan_delta_eff"] == 0.4


# ---------------------------------------------------------------- identify ---
def test_identify_round_trip(capsys):
    ball = Material("ball", 40e6, 0.15, 0.45, 1100.0)
    R, V = 0.015, 2.0
    rec = direct(ball, Material.rigid_body(), R, V)
    m = Body.sphere(ball, R).mass
    d = run_json(capsys, "identify", "--tau", repr(rec.tau), "--cor", repr(rec.cor_n), "--speed", "2",
                 "--radius", "0.015", "--mass", repr(m))
    assert d["numerical"]["E_storage"] == pytest.approx(40e6, rel=ROUNDTRIP_RTOL)
    assert d["numerical"]["tan_delta"] == pytest.approx(0.15, rel=ROUNDTRIP_RTOL)
    printed = identify_printed(ImpactMeasurement(rec.tau, rec.cor_n, V, R, m))
    assert d["printed"]["E_storage"] == pytest.approx(printed.E_storage, rel=SAME_RTOL)
    assert d["printed"]["E_loss_as_printed"] == pytest.approx(printed.E_loss_as_printed, rel=SAME_RTOL)
    assert d["printed"]["tan_delta"] == pytest.approx(printed.tan_delta, rel=SAME_RTOL)


def test_identify_table(capsys):
    code, out, _ = run(capsys, "identify", "--tau", "7e-4", "--cor", "0.7", "--speed", "1", "--radius", "0.01",
                       "--mass", "0.005", "--kp-mode", "hertz")
    assert code == 0
    printed = identify_printed(ImpactMeasurement(7e-4, 0.7, 1.0, 0.01, 0.005), "hertz")
    rows = {ln[:28].strip(): ln[28:].split() for ln in out.splitlines()[2:]}
    for label, want in (("E' [Pa]", printed.E_storage), ("E'' [Pa]", printed.E_loss),
                        ("E'' (97) as printed [Pa]", printed.E_loss_as_printed), ("tg(beta) [-]", printed.tan_delta)):
        assert float(rows[label][0]) == pytest.approx(want, rel=5e-6), label  # 6 significant digits
    assert rows["E'' (97) as printed [Pa]"][1] == "-"  # no numerical counterpart


@pytest.mark.parametrize("argv, needles", [
    (["--cor", "1.0"], ["cor", "1.0", "(0, 1)"]),
    (["--cor", "0.3"], ["cor", "0.3", "1/3", "(100)"]),
    (["--cor", "nan"], ["--cor", "nan", "NaN"]),
    (["--tau", "-1e-3"], ["--tau", "-0.001", "> 0"]),
    (["--mass", "0"], ["--mass", "0.0", "> 0"]),
    (["--radius", "inf"], ["--radius", "inf", "infinite"]),
    (["--cor", "0.5", "--strict"], ["tg(beta)", "(88)", "0.517093986", "1/3"]),
])
def test_bad_identify_input(capsys, argv, needles):
    base = {"--tau": "7e-4", "--cor": "0.7", "--speed": "1", "--radius": "0.01", "--mass": "0.005"}
    for flag, value in zip(argv[::2], argv[1::2]):
        base[flag] = value
    args = [x for kv in base.items() for x in kv] + [a for a in argv if a == "--strict"]
    code, out, err = run(capsys, "identify", *args)
    assert code == cli.EXIT_BAD_INPUT
    assert out == ""
    for needle in needles:
        assert needle in err, (needle, err)


# -------------------------------------------------------------- registries ---
def test_registered_engine_and_command_are_reachable(capsys, monkeypatch):
    """Other issues add engines and subcommands through the registries."""
    seen = {}

    def fake_engine(setup):
        seen["setup"] = setup
        return cli.run_reference(setup)

    monkeypatch.setitem(cli.ENGINES, "fake", cli.Engine(
        fake_engine, "test engine", lambda p: p.add_argument("--fake-step", type=float, default=1e-3)))
    monkeypatch.setitem(cli.COMMANDS, "hello", cli.Command(
        "say hello", lambda p: p.add_argument("--who", default="world"), lambda a: print(f"hello {a.who}") or 0))
    d = run_json(capsys, "impact", "--engine", "fake", "--fake-step", "2e-3")
    assert seen["setup"].args.fake_step == 2e-3 and d["inputs"]["engine"] == "fake"
    assert set(CONTRACT_KEYS) <= set(d)
    code, out, _ = run(capsys, "hello", "--who", "MSF")
    assert (code, out) == (0, "hello MSF\n")


# -------------------------------------------------------------- subprocess ---
def test_console_script_and_module_entry_points():
    exe = [sys.executable, "-m", "experiments.cli"]
    p = subprocess.run(exe + ["impact", "--json", "--ball", "ptfe"], capture_output=True, text=True, check=False)
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    rec = direct(preset("ptfe"), Material.rigid_body(), cli.DEFAULT_RADIUS, cli.DEFAULT_SPEED).to_dict()
    assert d["cor_n"] == pytest.approx(rec["cor_n"], rel=SAME_RTOL)
    bad = subprocess.run(exe + ["impact", "--radius", "-1"], capture_output=True, text=True, check=False)
    assert bad.returncode == 2
    assert "Traceback" not in bad.stderr and "--radius = -1.0 m must be > 0" in bad.stderr


def test_help_does_not_import_heavy_packages():
    code = ("import sys; from experiments import cli; "
            "sys.argv = ['msf-contact', '--help']\n"
            "try:\n    cli.main()\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in ('matplotlib', 'mujoco', 'pybullet', 'pandas') if m in sys.modules))")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert p.stdout.strip().splitlines()[-1] == "[]"
    assert "impact" in p.stdout and "identify" in p.stdout
