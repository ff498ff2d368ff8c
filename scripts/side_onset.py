"""The onset of engines._narrow.SideEndLaw (a lying capsule's or cylinder's
side carried by its two ends, the MSF line law): the compiled path
(``onset``, engines._impact_kernel) against the Python integration it
replaced (``onset_reference``, msf_contact._normal), the numbers
docs/engines.md and docs/benchmarks.md quote.

    .venv/bin/python scripts/side_onset.py            # cost and difference per onset, 48 cases
    .venv/bin/python scripts/side_onset.py --robots   # benchmarks.robots' measure, compiled then Python onsets

The 48 cases: natural rubber on steel, r 10 mm, a cylinder's side (edge
radius 1 mm) and a capsule's, 58 mm straight, half of a 6 g body per end;
lying flat, tilted 0.01 rad (either end the lower), 0.05 rad, 0.3 rad
(either end the lower); 0.01, 0.1, 1 and 3 m/s. Printed: the median and
largest wall time of each path per onset [ms] and the largest relative
difference over every onset constant.

``--robots``: ant.xml and humanoid.xml as ``python -m benchmarks.run --only
robots`` measures them (1,000 steps of seeded torques; only the torque
phase is timed), first with the compiled onset, then with SideEndLaw's
onset on the Python integration (main's form before it), each in this
process one after the other: per model the MSF and built-in mean and median
wall time per step [ms].
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time


def cases() -> None:
    from engines._narrow import SideEndLaw
    from msf_contact import ContactPair, Curvature, make_law, preset

    rubber, steel = preset("natural-rubber"), preset("steel")
    r, rho, L = 0.01, 1e-3, 0.058
    m = rubber.density * math.pi * r * r * L
    law = make_law("msf", ContactPair(rubber, steel), Curvature.sphere_on_plane(r))
    fast, slow, worst = [], [], 0.0
    for rounded in (True, False):
        end = SideEndLaw(law, r, rho if rounded else r, L, rounded)
        end.set_pose(0.0, 0.0)
        end.onset([1.0], [m / 2])  # numba's compilation or cache load, not timed
        for tilt, rise in ((0.0, 0.0), (0.01, math.sin(0.01)), (0.01, -math.sin(0.01)), (0.05, math.sin(0.05)),
                           (0.3, math.sin(0.3)), (0.3, -math.sin(0.3))):
            end.set_pose(tilt, rise)
            for v in (0.01, 0.1, 1.0, 3.0):
                t = time.perf_counter()
                got = end.onset([v], [m / 2])
                fast.append(time.perf_counter() - t)
                t = time.perf_counter()
                want = end.onset_reference([v], [m / 2])
                slow.append(time.perf_counter() - t)
                worst = max(worst, max(abs(got[k][0] / want[k][0] - 1.0) for k in want if want[k][0] != 0.0))
    print(f"{len(fast)} onsets: compiled median {1e3 * statistics.median(fast):.2f} ms, largest "
          f"{1e3 * max(fast):.2f} ms; Python median {1e3 * statistics.median(slow):.1f} ms, largest "
          f"{1e3 * max(slow):.1f} ms; largest relative difference {worst:.2g}")


def robots() -> None:
    import os
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/ is not installed
    from benchmarks.robots import measure
    from engines._narrow import SideEndLaw
    from msf_contact.laws import MSFLaw

    print(f"load (1 min) {os.getloadavg()[0]:.1f}")
    compiled = SideEndLaw._onset_one_engine
    for label, path in (("compiled", compiled), ("python", MSFLaw._onset_one_engine)):
        SideEndLaw._onset_one_engine = path
        for name in ("ant.xml", "humanoid.xml"):
            r = measure(name, 1000)
            print(f"{label} {name}: MSF mean {1e3 * r['msf_step_s']:.2f} ms, median "
                  f"{1e3 * r['msf_step_median_s']:.2f} ms; built-in mean {1e3 * r['builtin_step_s']:.3f} ms, "
                  f"median {1e3 * r['builtin_step_median_s']:.3f} ms; {r['msf_records']} records", flush=True)
    SideEndLaw._onset_one_engine = compiled
    print(f"load (1 min) {os.getloadavg()[0]:.1f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robots", action="store_true", help="the robots benchmark with each onset path")
    a = ap.parse_args(argv)
    robots() if a.robots else cases()
    return 0


if __name__ == "__main__":
    sys.exit(main())
