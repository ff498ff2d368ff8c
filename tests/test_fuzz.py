"""Property-based hardening (issue 12, What 1-2): random and extreme numbers,
NaN, inf, huge and tiny values and wrong types in every flag of the command
line and every key of the scenario files, and in the public API. Each input
either runs, in bounded time, to finite outputs, or is refused with one
line (exit code 2 for input, 1 for a failed run), never a traceback or a
usage dump.

Cheap by construction: in-process calls of the CLI's ``main``, derandomized,
a few dozen examples per property; the failures found are kept below as
explicit regression cases (``CORPUS``)."""

import json
import math
import tomllib
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from experiments import cli
from experiments.runner import get_scenario

ROOT = Path(__file__).resolve().parent.parent

#: Numbers a user or a script can type; hypothesis adds its own floats.
EXTREMES = ["nan", "-nan", "inf", "-inf", "1e300", "-1e300", "1e-300", "-1e-300", "0", "-0", "1e-12", "1e9",
            "5e-324", "1.7976931348623157e308", "abc", "", "1,2", "0x10", "1e", "--", "true"]
numbers = st.one_of(st.sampled_from(EXTREMES), st.floats(allow_nan=True, allow_infinity=True).map(repr),
                    st.floats(-1e3, 1e3).map(repr))

#: ``impact`` flags that take a number, with the engine that reads them
#: (reference: the cheap one; the engines' own flags are in ENGINE_CASES).
IMPACT_NUMBER_FLAGS = ["--radius", "--mass", "--ball-E", "--ball-tan-delta", "--ball-nu", "--density",
                       "--plate-E", "--plate-tan-delta", "--plate-nu", "--plate-density", "--speed", "--angle",
                       "--spin", "--mu", "--omega"]
LAW_FLAGS = {"--A": "kuwabara-kono", "--hc-cor": "hunt-crossley", "--k": "spring-dashpot", "--c": "spring-dashpot"}
IDENTIFY_FLAGS = ["--tau", "--cor", "--speed", "--radius", "--mass", "--omega", "--plate-E", "--plate-tan-delta",
                  "--plate-nu", "--plate-density"]
IDENTIFY_BASE = {"--tau": "2.7e-3", "--cor": "0.73", "--speed": "1", "--radius": "0.02", "--mass": "0.031"}


def call(capsys, *argv):
    """main(argv) in-process: (exit code, stdout, stderr lines that are not warnings)."""
    try:
        code = cli.main(list(argv))
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    errors = [ln for ln in err.splitlines() if ln.strip() and ": warning: " not in ln]
    return code, out, errors


def assert_answered(code, out, errors, argv):
    """Runs to finite output (exit 0) or is refused in one line (exit 2 input, 1 run failure)."""
    assert code in (0, 1, 2), (argv, code)
    if code == 0:
        assert not errors, (argv, errors)
        d = json.loads(out, parse_constant=lambda c: pytest.fail(f"{argv}: {c} in the JSON"))
        for k in ("cor_n", "tau", "x_max", "F_max", "Pc_max", "W_diss_n"):
            v = d.get(k)
            assert v is None or (isinstance(v, (int, float)) and math.isfinite(v)), (argv, k, v)
    else:
        assert len(errors) == 1, (argv, errors)
        assert errors[0].startswith("msf-contact: error: ") or errors[0].startswith("msf-contact impact: error: ") \
            or errors[0].startswith("msf-contact identify: error: "), (argv, errors)
        assert "Traceback" not in errors[0] and "usage:" not in errors[0]


FUZZ = settings(max_examples=20, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
#: identify solves up to ~20 impacts per accepted input (~0.5 s): fewer examples.
FUZZ_SLOW = settings(FUZZ, max_examples=8)


@FUZZ
@given(flag=st.sampled_from(IMPACT_NUMBER_FLAGS), value=numbers,
       engine=st.sampled_from(["reference", "closed-form"]))
def test_impact_flag_answered(capsys, flag, value, engine):
    argv = ["impact", "--engine", engine, flag, value, "--json"]
    assert_answered(*call(capsys, *argv), argv)


@FUZZ
@given(flag=st.sampled_from(sorted(LAW_FLAGS)), value=numbers)
def test_law_flag_answered(capsys, flag, value):
    argv = ["impact", "--law", LAW_FLAGS[flag], flag, value, "--json"]
    assert_answered(*call(capsys, *argv), argv)


@FUZZ_SLOW
@given(flag=st.sampled_from(IDENTIFY_FLAGS), value=numbers)
def test_identify_flag_answered(capsys, flag, value):
    args = dict(IDENTIFY_BASE)
    args[flag] = value
    argv = ["identify", *[x for kv in args.items() for x in kv], "--json"]
    code, out, errors = call(capsys, *argv)
    assert code in (0, 1, 2), (argv, code)
    if code:
        assert len(errors) == 1 and errors[0].startswith("msf-contact"), (argv, errors)
    else:
        json.loads(out, parse_constant=lambda c: pytest.fail(f"{argv}: {c} in the JSON"))


#: The engines' own flags (each engine run costs ~0.1-1 s, so explicit cases).
ENGINE_CASES = [
    ("mujoco", "--dt", "1e-12"), ("pybullet", "--dt", "1e-12"), ("mujoco", "--gap", "1e9"),
    ("pybullet", "--gap", "1e9"), ("mujoco", "--dt", "nan"), ("mujoco", "--dt", "-1"), ("mujoco", "--gap", "-1"),
    ("mujoco-builtin", "--solref", "nan,1"), ("mujoco-builtin", "--solref", "1"), ("mujoco-builtin", "--solimp", "2,2,2"),
    ("pybullet-builtin", "--restitution", "inf"), ("pybullet-builtin", "--contact-stiffness", "-1"),
    ("mujoco", "--gravity", "1e300"), ("mujoco", "--integrator", "nope"), ("reference", "--ball", "nosuch"),
    ("reference", "--plate", "nosuch"), ("reference", "--law", "nosuch"), ("nosuch", "--dt", "1e-3"),
]


@pytest.fixture(scope="module")
def warm_engines():
    """One impact in each engine first: numba compiles the contact kernels
    on the first call of a fresh clone (~15-60 s), which is not the work
    the time bound is about."""
    from engines.base import get_engine
    from msf_contact import Body, ContactPair, Curvature, Material, make_law, preset

    ball, plate = preset("polyurethane"), Material.rigid_body()
    law = make_law("msf", ContactPair(ball, plate), Curvature.sphere_on_plane(0.01))
    for name in ("mujoco", "pybullet"):
        get_engine(name)(law, Body.sphere(ball, 0.01), Body.half_space(plate), 1.0)


@pytest.mark.mujoco
@pytest.mark.parametrize("engine, flag, value", ENGINE_CASES)
def test_engine_flag_answered(capsys, warm_engines, engine, flag, value):
    argv = ["impact", "--engine", engine, flag, value, "--json"]
    assert_answered(*call(capsys, *argv), argv)


#: Regression corpus: inputs that once hung, dumped usage, raised a traceback or printed absurd values.
CORPUS = [
    ["impact", "--radius", "1e300"], ["impact", "--spin", "1e300"], ["impact", "--mass", "1e-300"],
    ["impact", "--ball-E", "1e300"], ["impact", "--engine", "closed-form", "--ball-tan-delta", "1.5"],
    ["impact", "--ball", "nosuch"], ["impact", "--ball"], ["impact", "--engine", "mujoco-builtin", "--solref", "nan,1"],
    ["impact", "--law", "spring-dashpot", "--k", "5e-324"], ["impact", "--law", "hunt-crossley", "--hc-cor", "1e-300"],
    ["impact", "--radius", "abc"], ["impact", "--engine", "mujoco", "--dt", "1e-12"],
    ["impact", "--engine", "pybullet", "--gap", "1e9"],
    ["identify", *[x for kv in IDENTIFY_BASE.items() for x in kv], "--tau", "1e-300"],
    ["identify", *[x for kv in IDENTIFY_BASE.items() for x in kv], "--omega", "0.25"],  # took 23 s
]


@pytest.mark.parametrize("argv", CORPUS, ids=" ".join)
def test_corpus_refused_in_one_line(capsys, warm_engines, argv):
    """Each once hung, dumped usage, raised a traceback or printed absurd values."""
    code, out, errors = call(capsys, *argv, "--json")
    assert code == 2, (argv, code, out)
    assert_answered(code, out, errors, argv)


# ------------------------------------------------------------ public API ---
api_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                        st.sampled_from([1e300, -1e300, 1e-300, 0.0, 5e-324, 1e-12, 1e9]), st.floats(1e-3, 1e3))


@FUZZ
@given(E=api_numbers, tan_delta=api_numbers, radius=api_numbers, mass=api_numbers, speed=api_numbers,
       angle=api_numbers, spin=api_numbers, law=st.sampled_from(["msf", "hertz", "hunt-crossley", "spring-dashpot"]))
def test_public_api_answers(E, tan_delta, radius, mass, speed, angle, spin, law):
    """Material, Body, make_law and simulate_impact on extreme numbers: a
    finite record in bounded time, or a ValueError in one line before any work."""
    import warnings

    from msf_contact import Body, ContactPair, Curvature, Material, make_law, simulate_impact

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # validity warnings: the record says what they say
            mat = Material("m", E, tan_delta, 0.4, 1000.0)
            ball = Body.sphere(mat, radius, mass)
            opts = {"cor": 0.7} if law == "hunt-crossley" else {}
            lw = make_law(law, ContactPair(mat, Material.rigid_body()), Curvature.sphere_on_plane(radius), **opts)
            rec = simulate_impact(lw, ball, Body.half_space(Material.rigid_body()), speed, angle, spin)
    except ValueError as exc:
        assert "\n" not in str(exc)
        return
    except RuntimeError as exc:  # a run failure, said in one line
        assert "\n" not in str(exc)
        return
    d = rec.to_dict()
    assert "non_finite" not in d, d["non_finite"]
    assert 0 <= d["cor_n"] <= 1 + 1e-9


# ------------------------------------------------------------- scenarios ---
def _leaves(d, prefix=()):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _leaves(v, prefix + (k,))
        else:
            yield prefix + (k,)


CONFIGS = sorted((ROOT / "experiments" / "configs").glob("*.toml"))
KEYS = [(p.name, path) for p in CONFIGS for path in _leaves(tomllib.loads(p.read_text())) if path != ("scenario",)]
toml_values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(
    [1e300, -1e300, 1e-300, 0, -1, 10**30, "", "nosuch", True, [], [float("nan")], [1e300], {"x": 1}]))


@FUZZ
@given(key=st.sampled_from(KEYS), value=toml_values)
def test_every_scenario_key_validated(key, value):
    """Each key of each shipped configuration, set to an extreme or wrong
    value: the scenario loads (and plans its cells) or refuses in one line
    naming the file and the key."""
    name, path = key
    raw = tomllib.loads((ROOT / "experiments" / "configs" / name).read_text())
    node = raw
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    scenario = get_scenario(raw["scenario"])
    try:
        cfg = scenario.load(raw, name)
        cells = list(scenario.cells(cfg))
    except ValueError as exc:
        msg = str(exc)
        assert "\n" not in msg and name in msg, (key, value, msg)
        return
    assert len(cells) >= 1


def test_an_unexpected_exception_is_one_line_and_exit_1(capsys, monkeypatch):
    """A bug in a command (here a KeyError) ends in one line and exit code 1,
    not a traceback; MSF_CONTACT_TRACEBACK=1 re-raises it."""
    def broken(args):
        raise KeyError("x")

    from dataclasses import replace

    monkeypatch.setitem(cli.COMMANDS, "impact", replace(cli.COMMANDS["impact"], run=broken))
    code, out, errors = call(capsys, "impact")
    assert code == 1 and len(errors) == 1 and errors[0].startswith("msf-contact: error: KeyError")
    monkeypatch.setenv("MSF_CONTACT_TRACEBACK", "1")
    with pytest.raises(KeyError):
        cli.main(["impact"])
