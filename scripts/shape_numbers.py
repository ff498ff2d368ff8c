"""Numbers docs/engines.md quotes for issue 13's MuJoCo side that no
benchmark prints:

    .venv/bin/python scripts/shape_numbers.py line      # a lying cylinder: two rim points vs the line law
    .venv/bin/python scripts/shape_numbers.py profile   # cProfile of the MSF humanoid (200 steps)

``line``: natural rubber on steel, a cylinder r 10 mm, 60 mm long, edge
radius 1 mm, falling flat at 1 m/s, in the reference solver: the line law
over its straight side (geometry.SideFootprint, flat caps) against one of
the two rim points MuJoCo lists (the rim torus at alpha = 0: 1 mm and
10 mm) carrying half the mass. ``profile``: the 20 most expensive calls
(cumulative) of 200 steps of humanoid.xml with seeded torques after 20
warm-up steps.
"""

from __future__ import annotations

import sys
import warnings


def line() -> None:
    import math

    from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact
    from msf_contact.geometry import SideFootprint

    rubber, steel = preset("natural-rubber"), preset("steel")
    r, h, rho, v = 0.01, 0.03, 1e-3, 1.0
    m = rubber.density * math.pi * r * r * 2 * h
    pair = ContactPair(rubber, steel)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        side = make_law("msf", pair, Curvature.side_on_plane(SideFootprint(r, 2 * h - 2 * rho, 0.0, "flat")))
        a = simulate_impact(side, Body(rubber, r, m, 0.5 * m * r * r), Body.half_space(steel), v)
        rim = make_law("msf", pair, Curvature(rho, r, math.inf, math.inf))
        b = simulate_impact(rim, Body(rubber, rho, m / 2, 0.4 * m / 2 * rho * rho), Body.half_space(steel), v)
    print(f"line law over the side: COR {a.cor_n:.3f}, tau {a.tau * 1e3:.2f} ms, x_max {a.x_max * 1e3:.2f} mm, "
          f"F_max {a.F_max:.1f} N")
    print(f"two rim points, m/2 each: COR {b.cor_n:.3f}, tau {b.tau * 1e3:.2f} ms, x_max {b.x_max * 1e3:.2f} mm, "
          f"F_max {2 * b.F_max:.1f} N in all; outside validity: {b.outside_validity[:1]}")


def profile() -> None:
    import cProfile
    import os
    import pstats

    import mujoco
    import numpy as np
    import pybullet_data

    from engines.mujoco import MujocoAdapter, installed
    from engines.mujoco.robots import load_with_msf_floor
    from msf_contact import ContactPair, preset

    path = os.path.join(pybullet_data.getDataPath(), "mjcf", "humanoid.xml")
    model, data, pairs = load_with_msf_floor(path, ContactPair(preset("natural-rubber"), preset("steel")))
    adapter = MujocoAdapter(model, data, pairs)
    rng = np.random.default_rng(13)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    warnings.simplefilter("ignore")
    with installed(adapter):
        for _ in range(20):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
        prof = cProfile.Profile()
        prof.enable()
        for _ in range(200):
            data.ctrl[:] = rng.uniform(lo, hi)
            mujoco.mj_step(model, data)
        prof.disable()
    pstats.Stats(prof).sort_stats("cumulative").print_stats(20)


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else ""
    if what not in ("line", "profile"):
        sys.exit("usage: scripts/shape_numbers.py line|profile")
    line() if what == "line" else profile()
