"""Rest at the static overlaps (issue 10: "settle with no energy gain at any
step and rest at the static overlaps, both engines, dt = 1 ms").

The static overlap x_s of a contact carrying the normal force F is the root
of F_n(x_s, 0) = F: at rest the approach rate vanishes and with it the
viscous term of (37), so the force-approach law is the elastic one,
(2/3) E' psi(x) x^(3/2) ((43) for a sphere: (4/3) k_p E' sqrt(R) x^(3/2))
(msf_contact.statics). In a vertical column of spheres on a plate each
contact carries the weight of the spheres above it, exactly.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from msf_contact import Body, ContactPair, Curvature, column_loads, make_law, preset, static_overlap
from test_multi_contact import _engine_available
from test_pile import ENERGY_ROUNDOFF
from engines._contacts.state import ENERGY_GAIN_RTOL
from _scripts import load_script

R, G, DT = 0.01, 9.81, 1e-3
STEEL, RUBBER = preset("steel"), preset("natural-rubber")


# ------------------------------------------------------------ the definition --
def test_static_overlap_solves_the_elastic_law():
    """x_s against (43) written out here: (4/3) k_p E' sqrt(R) x^(3/2) with
    k_p = sqrt(2 - x/R) (15) at x_s gives back the force; with k_p = 1
    (kp_mode "hertz") x_s is Hertz's closed form (30) inverted,
    (3 F / (4 E' sqrt(R)))^(2/3)."""
    F = np.array([0.0, 1e-3, 0.04, 0.36, 5.0])
    for mode in ("msf", "hertz"):
        law = make_law("msf", ContactPair(RUBBER, STEEL), Curvature.sphere_on_plane(R), kp_mode=mode)
        o = law.onset(np.full(F.size, 0.01), np.full(F.size, 0.004))
        x = static_overlap(law, F, o)
        E = o["E"]
        kp = np.sqrt(2.0 - x / R) if mode == "msf" else np.ones(F.size)
        np.testing.assert_allclose(4.0 / 3.0 * kp * E * math.sqrt(R) * x**1.5, F, rtol=1e-10, atol=0.0)
        if mode == "hertz":
            np.testing.assert_allclose(x, (3.0 * F / (4.0 * E * math.sqrt(R))) ** (2.0 / 3.0), rtol=1e-10)


def test_column_loads_are_the_weights_above():
    np.testing.assert_allclose(column_loads([1.0, 2.0, 3.0], 9.81), [58.86, 49.05, 29.43], rtol=1e-15)


@pytest.mark.parametrize("call, match", [
    (lambda law, o: static_overlap(law, [-1.0], o), "force"),
    (lambda law, o: static_overlap(law, [np.nan], o), "force"),
    (lambda law, o: static_overlap(law, [1e9], o), "exceeds"),
    (lambda law, o: column_loads([1.0, 0.0], 9.81), "masses"),
    (lambda law, o: column_loads([], 9.81), "masses"),
    (lambda law, o: column_loads([1.0], -9.81), "gravity"),
])
def test_static_bad_input(call, match):
    law = make_law("msf", ContactPair(RUBBER, STEEL), Curvature.sphere_on_plane(R))
    o = law.onset(np.array([0.01]), np.array([0.004]))
    with pytest.raises(ValueError, match=match):
        call(law, o)


# ------------------------------------------------------------ recovery -------
#: The law's force along the recovering surface against its elastic part [-]: x_r(t) = x_e exp(-k t)
#: and x_r' = -k x_r put (37) at zero to round-off (the two terms cancel, ~1e-16 relative); 1e-12
#: leaves the exponential's own round-off a wide margin and catches any other rate (E'/(2 eta'_E): 0.5).
RECOVERY_RTOL = 1e-12


@pytest.mark.parametrize("mode", ["msf", "msf-small", "hertz"])
def test_surface_recovers_at_the_laws_zero_force(mode):
    """engines._contacts.state.RECOVERY_DOC: a contact that ends at F_n = 0
    with x_e > 0 leaves the surface indented, free (F_n = 0), and (37) at
    zero force gives x_r' = -E' x_r / (3 eta'_E) for every k_p mode
    (psi and sqrt(x) cancel). Along surface_recovery_rate's exponential
    (residual_indentation) the law's normal force stays zero against its
    elastic part, and the rate is omega_x / (3 tg beta) ((46): eta'_E =
    E''/omega_x)."""
    from engines._contacts.state import residual_indentation, surface_recovery_rate

    law = make_law("msf", ContactPair(RUBBER, STEEL), Curvature.sphere_on_plane(R), kp_mode=mode)
    o = law.onset(np.array([0.004]), np.array([0.05]))
    k = float(surface_recovery_rate(o, [0])[0])
    E, eta, w = float(o["E"][0]), float(o["eta_E"][0]), float(o["omega_x"][0])
    np.testing.assert_allclose(k, w / (3.0 * (eta * w / E)), rtol=1e-12)  # omega_x / (3 tg beta)
    x_e, t_e = 3e-5, 0.25
    t = t_e + np.linspace(0.0, 5.0 / k, 11)
    x_r = residual_indentation(np.full(t.size, x_e), np.full(t.size, k), np.full(t.size, t_e), t)
    oo = {key: np.repeat(val, t.size) for key, val in o.items()}
    F = law.normal_force(x_r, -k * x_r, oo)
    F_el = law.normal_force(x_r, np.zeros(t.size), oo)
    assert np.all(F_el > 0) and np.all(np.abs(F) <= RECOVERY_RTOL * F_el), F / F_el
    np.testing.assert_allclose(x_r[-1], x_e * np.exp(-5.0), rtol=1e-12)
    # before the end: nothing recovered; no residual: none
    assert residual_indentation([x_e], [k], [t_e], t_e - 1.0)[0] == x_e
    assert residual_indentation([0.0], [k], [t_e], t_e + 1e-3)[0] == 0.0
    # a law without a Kelvin-Voigt element of that form keeps no residual
    hertz = make_law("hertz", ContactPair(RUBBER, STEEL), Curvature.sphere_on_plane(R))
    assert surface_recovery_rate(hertz.onset(np.array([0.004]), np.array([0.05])), [0])[0] == 0.0


# ------------------------------------------------------------ columns --------
#: Columns of spheres (R = 10 mm), bottom first, placed touching each other and the plate at rest.
#: "rs": a steel ball on a rubber ball: on main f9780ae it never came to rest (5-10 mm/s after 3 s,
#: the rubber ball's two rows, settled one by one, exchanged their forces a step late:
#: engines._contacts.resting), E rose by up to 3.8e-6 J in a step beyond (dt/2)|dq|; "rsr": rubber,
#: steel, rubber, the same. On main 8b8082b (resting rows in RK4 islands, issue 13) both rest, but
#: the engine's bottom overlap 4.9 um (9 %) deeper than x_s (ENGINE_RTOL).
COLUMNS = ("rs", "rsr")
#: Steps run (0.4 s): the columns are at rest (every sphere < REST_SPEED) from step ~150 in both engines.
COLUMN_STEPS = 400
#: A sphere slower than this is at rest [m/s] (scripts/pile.py REST_SPEED: < 1 um in a step).
REST_SPEED = 1e-3
#: The internal overlap at rest against x_s [-]: the settled step's force balance is exact to
#: m SETTLED_VTOL v_x / dt (engines._contacts.state, ~1e-9 of the weight); 1e-6 leaves the
#: residual motion of the last steps (below 1e-9 m/s at step 400) a wide margin.
INTERNAL_RTOL = 1e-6
#: The engine's own overlap (from the sphere centres) at rest against x_s [-]. Measured after the
#: fix: within 2.2e-3 (0.13 um of 62 um, "rs"'s rubber on the plate); 5e-3 is half a micrometre on
#: the rubber contacts and excludes what main f9780ae gave: 4.9 um (8 %) on the bottom contact,
#: g dt^2 / 2, a sphere touching the plate at rest left to fall freely for its first step.
ENGINE_RTOL = 5e-3


def _column_module():
    return load_script("column")


@pytest.mark.parametrize("column", COLUMNS)
@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
def test_column_rests_at_static_overlaps(engine, column):
    """A column placed touching on a steel plate, dt = 1 ms (scripts/column.py):
    the energy E of scripts/pile.py (kinetic + potential at z - dt v/2 + the
    contacts' stored energy, read at each step start) never rises by more
    than round-off plus (dt/2)|dq| (q = gravity's power m g . v on the
    spheres: a settled step is backward Euler, which is exact in kinetic +
    potential at z + stored, and the two measures differ by dt q / 2; the
    island check allows the same term), no island is flagged, every sphere
    comes to rest, and each contact's internal overlap and the engine's own
    overlap (from the centres) rest at x_s of the weight above it
    (column_loads)."""
    _engine_available(engine)
    out = _column_module().run(engine, column, COLUMN_STEPS, DT)
    assert out["E_max_step_rise_beyond_dq_J"] <= ENERGY_ROUNDOFF, out
    assert out["island_steps_flagged"] == 0, out
    assert out["v_max_end_m_s"] < REST_SPEED and all(out["in_contact"]), out
    np.testing.assert_allclose(out["x_internal_m"], out["x_static_m"], rtol=INTERNAL_RTOL, atol=0.0)
    np.testing.assert_allclose(out["x_engine_m"], out["x_static_m"], rtol=ENGINE_RTOL, atol=0.0)


# ------------------------------------------------------------ held geometry --
#: Steps of the rolling steel pair below: its tilt reaches 2.5 degrees (the top sphere's centre
#: 0.9 mm off the vertical), enough for a frozen normal to leave a gap, before it rolls off.
ROLL_STEPS = 60
#: Largest gap between the engine's spheres while the pair carries force [m]: what the engines'
#: step leaves (the normal frozen over a step, second order in the ~40 um a step the contact point
#: moves along the sphere, and the engine's lead over the island's integration): measured 1.1 um in
#: MuJoCo; a held onset normal and approach let it grow with the tilt (13.3 um at step 60 before).
ROLL_GAP_MAX = 3e-6


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
def test_resting_steel_pair_reads_the_engines_geometry(engine):
    """A steel ball (R = 10 mm) set on a steel ball resting on a steel plate,
    rolling off at 2 cm/s, dt = 1 ms: the pair's contact is shorter than a
    step (tau ~ 0.1 ms) and rests (older than SETTLE_AFTER_DURATIONS
    durations). MuJoCo's adapter held such a contact's onset normal and the
    manager's approach for as long as it lasted (a sub-step impact's
    geometry, MujocoAdapter._held_geometry), so it never read the engine's
    spheres again: the pair kept 0.32 N at the manager's 81 nm overlap while
    the engine's spheres moved 13 um apart by step 60 (37 um by step 100;
    in the 32-sphere pile, 68.7 um). The pair may carry force only while the
    engine's spheres are within ROLL_GAP_MAX of touching."""
    from test_multi_contact import Scene

    steel = Body.sphere(STEEL, R)
    laws = [make_law("msf", ContactPair(STEEL, STEEL), Curvature.sphere_on_plane(R)),
            make_law("msf", ContactPair(STEEL, STEEL), Curvature.two_spheres(R, R))]
    _engine_available(engine)
    sc = Scene(engine, [steel, steel], [[0, 0, R], [0, 0, 3 * R]], [[0, 0, 0], [0.02, 0, 0]],
               [(0, -1), (1, 0)], laws, G, DT)
    gaps = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with sc._ctx:
            for _ in range(ROLL_STEPS):
                sc.adapter.step(1)
                F = {r.pair: r.F_n for r in sc.adapter.contact_forces()}
                pos = sc.state()[0]
                if F.get(1, 0.0) > 0.0:
                    gaps.append(float(np.linalg.norm(pos[1] - pos[0])) - 2 * R)
            tilt = math.degrees(math.atan2(pos[1][0] - pos[0][0], pos[1][2] - pos[0][2]))
    assert len(gaps) > ROLL_STEPS // 2 and tilt > 2.0, (len(gaps), tilt)
    assert max(gaps) <= ROLL_GAP_MAX, max(gaps)


# ------------------------------------------------------------ a placed pile --
#: scripts/pile_placed.py: nine spheres (R = 10 mm; seven natural rubber, two steel) placed at rest in
#: scripts/pile.py's box two spheres wide: four columns of two in the corners, 10 um from two walls each,
#: and a steel sphere in the middle on the four lower ones (contacts 62 degrees from the vertical,
#: pushing them into the walls), each layer PLACED_DROP above its place, dt = 1 ms. At rest
#: (scripts/pile.py REST_DOC) from step 704 (MuJoCo) and 606 (pybullet); the run stops PLACED_REST_STEPS
#: later (~7 s of CPU each).
PLACED_STEPS, PLACED_REST_STEPS = 900, 50
#: Each layer this far above touching [m]: placed exactly touching, a pair at x = 0 and at rest chattered
#: in pybullet (more than MAX_SEGMENTS onsets and ends in a step); 10 um is a fall of 1.4 ms.
PLACED_DROP = 1e-5
#: The engine's overlaps (from the sphere centres) at rest against the static overlaps of the forces the
#: contacts carry, largest over the contacts [m]. Measured 4.7 um (MuJoCo) and 4.9 um (pybullet): the
#: engine's lead over the internal overlap that the settle-in leaves, frozen by the settled steps (each
#: settled stretch entered closing at x' leaves the engine (dt/2) x' deeper; docs/engines.md, "what
#: moves the engine's lead": 0.2 um with the settled step taken in the engine's frame, not landed). The
#: bound is twice what was measured, the order of one free step's g dt^2 (9.8 um): it catches a step
#: left out of the integration, not the lead itself (issue 10's acceptance is not met by this).
PLACED_ENGINE_ATOL = 1e-5
#: The same, median over the contacts carrying >= 10 % of a mean sphere's weight [-]: measured 6.0 %
#: (MuJoCo) and 9.2 % (pybullet).
PLACED_ENGINE_MEDIAN_RTOL = 0.2
#: The internal overlaps against the same, largest over the contacts [m]: the settled steps' balance is
#: exact to ~1e-9 of the force; the run stops 50 steps into the rest with the last 0.3-0.4 mm/s of
#: vibration (measured 17 nm MuJoCo, 42 nm pybullet; the median over the loaded contacts 2.7e-4 / 1.9e-4).
PLACED_INTERNAL_ATOL = 2e-7
#: support / weight at rest [-]: measured 0.9950 / 0.9964 (the last vibration).
PLACED_SUPPORT_RTOL = 1e-2


@pytest.mark.parametrize("engine", [pytest.param("mujoco", marks=pytest.mark.mujoco),
                                    pytest.param("pybullet", marks=pytest.mark.pybullet)])
def test_placed_pile_rests_at_static_overlaps(engine):
    """Issue 10: a pile of nine spheres placed in the box
    (scripts/pile_placed.py) settles with no island step flagged and its
    energy E never rising in a step beyond (dt/2)|dq| by more than the
    island check's ENERGY_GAIN_RTOL of E (measured: none beyond it, both
    engines; the largest rise 1.2e-6 J at step 54 is within (dt/2)|dq|), no
    contact begun deep, comes to rest
    (scripts/pile.py REST_DOC), and rests with the walls and floor carrying
    its weight, each contact's internal overlap at the static overlap of the
    force it carries, and the engine's within PLACED_ENGINE_ATOL of it."""
    _engine_available(engine)
    out = load_script("pile_placed").run(engine, PLACED_STEPS, DT, PLACED_DROP, PLACED_REST_STEPS)
    assert out["exploded_at_step"] is None and out["island_steps_flagged"] == 0, out
    assert out["E_max_step_rise_beyond_dq_J"] <= ENERGY_GAIN_RTOL * out["E_start_J"], out
    assert out["at_rest_from_step"] is not None and out["deep_onsets"] == 0, out
    assert out["support_over_weight"] == pytest.approx(1.0, abs=PLACED_SUPPORT_RTOL), out
    assert out["overlap_vs_static_max_abs_m"] <= PLACED_INTERNAL_ATOL, out
    assert out["engine_overlap_vs_static_max_abs_m"] <= PLACED_ENGINE_ATOL, out
    assert out["engine_overlap_vs_static_median_rel"] <= PLACED_ENGINE_MEDIAN_RTOL, out
