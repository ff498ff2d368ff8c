"""Where a gymnasium walker's MSF step goes: the CPU time per ``mj_step`` in
its two phases (seeded random actions, then zero actions: the walker comes
to rest), medians, with MSF on every body-floor pair (scripts/gym_check.py's
``gym_msf``), and with ``--profile`` a cProfile of the rest phase.

    .venv/bin/python scripts/gym_prof.py Humanoid-v5 --torque-steps 200 --rest-steps 200 --seed 5
    .venv/bin/python scripts/gym_prof.py Ant-v5 --profile

The profile's own cost falls on the rest phase only and is not small: the
resting step is many short Python calls, and cProfile multiplied it by
about four (Humanoid-v5 seed 5 on main dff70d0: 24.3 ms a step profiled
against 5-8 ms unprofiled, the moving phase 9.3 ms in the same run), so the
phase medians are printed from an unprofiled run and the profile only says
where the time goes in proportion (docs/benchmarks.md, robots).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def run(name: str, torque: int, rest: int, seed: int, profile: cProfile.Profile | None = None):
    """(per mj_step CPU [s] (torque + rest,), the adapter) of one run; ``profile`` enabled over the rest phase."""
    import numpy as np

    from engines.mujoco import MujocoAdapter, installed
    from scripts.gym_check import gym_msf

    env, model, data, pairs = gym_msf(name)
    rng = np.random.default_rng(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ad = MujocoAdapter(model, data, pairs)
        per = np.empty(torque + rest)
        with installed(ad):
            for i in range(torque + rest):
                a = rng.uniform(-1, 1, env.action_space.shape) if i < torque else np.zeros(env.action_space.shape)
                if i == torque and profile is not None:
                    profile.enable()
                t0 = time.process_time()
                env.step(a)
                per[i] = time.process_time() - t0
        if profile is not None:
            profile.disable()
    return per / env.unwrapped.frame_skip, ad


def main(argv=None) -> int:
    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("env")
    ap.add_argument("--torque-steps", type=int, default=200)
    ap.add_argument("--rest-steps", type=int, default=200)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--profile", action="store_true", help="then a cProfile of the rest phase (its own run)")
    ap.add_argument("--lines", type=int, default=30, help="profile lines printed")
    a = ap.parse_args(argv)
    T = a.torque_steps
    per, _ = run(a.env, T, a.rest_steps, a.seed)
    print(f"{a.env} seed {a.seed}: CPU per mj_step, medians: moving {np.median(per[:T]) * 1e3:.2f} ms, "
          f"at rest {np.median(per[T:]) * 1e3:.2f} ms (unprofiled)")
    if a.profile:
        pr = cProfile.Profile(time.process_time)
        per, _ = run(a.env, T, a.rest_steps, a.seed, pr)
        print(f"profiled run: at rest {np.median(per[T:]) * 1e3:.2f} ms (cProfile's cost included)")
        pstats.Stats(pr).sort_stats("cumulative").print_stats(a.lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
