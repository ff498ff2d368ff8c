"""A box spinning through its corner contacts at a large step is flagged and
warned before it gains energy (issue 13; engines.mujoco.adapter.
BOX_TURN_PER_STEP_MAX, MujocoAdapter._check_fast_turns; scripts/spin_drop.py)."""
import warnings

import numpy as np

from _scripts import load_script


def _drop(w: float, dt: float, t_end: float):
    """scripts/spin_drop.py's box (1 kg, 0.10 x 0.06 x 0.04 m, from 0.2 m) spinning at w rad/s about
    (1, 1, 1), Euler at dt: (its contact steps (|omega| dt, excess / E0), the adapter, MuJoCo's reset,
    the fast-turn warnings)."""
    spin = load_script("spin_drop")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rows, ad, bad = spin.drop((1.0, 1.0, 1.0), w, dt, t_end=t_end)
    return rows, ad, bad, [w_ for w_ in caught if "fast turn" in str(w_.message)]


def test_a_box_spinning_at_20_rad_s_at_10_ms_is_warned_before_its_gain():
    """At 10 ms the box meets the plane turning 0.19 rad a step, above
    BOX_TURN_PER_STEP_MAX: its first corner contact is flagged and warned
    (naming omega dt and the dt that would resolve it) in the step it
    begins, before the contact step that gains more than the drop's energy
    (0.25 rad a step, 1.36 -> 8.47 J measured) and long before MuJoCo's
    NaN acceleration (its step 67, measured)."""
    rows, ad, bad, warned = _drop(20.0, 0.01, 0.25)
    assert warned and "omega| dt = 0.19" in str(warned[0].message) and "take dt <=" in str(warned[0].message)
    t_gain = next(t for _, excess, t in rows if excess > 1.0)  # the contact step that gains the drop's energy
    flagged = [r for r in ad.records if any("fast turn" in n for n in r.outside_validity)]
    assert ad.fast_turns >= 1 and flagged and min(r.inputs["t_onset"] for r in flagged) < t_gain
    assert not bad  # 0.25 s: before the blow-up


def test_the_same_box_at_2_ms_is_not_flagged():
    """The same drop at 2 ms (0.04 rad a step at the first contact): no
    corner contact turns more than BOX_TURN_PER_STEP_MAX a step, none is
    flagged, and no contact step rises more than 1e-2 of the drop's energy
    above the semi-implicit step's term (scripts/spin_drop.py's measure)."""
    rows, ad, bad, warned = _drop(20.0, 0.002, 0.3)
    assert rows and not warned and ad.fast_turns == 0 and not bad
    assert max(e for _, e, _ in rows) < 1e-2
