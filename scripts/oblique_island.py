"""Deep oblique impacts solved in an island (issue 10 item 3, islands):
the numbers docs/engines.md quotes ("Known limits", the moving contact point).

    .venv/bin/python scripts/oblique_island.py

The scenes of tests/test_islands.py (``bead_scene``, imported from there so
the test and this table run the same code): glass beads (R = 0.25 mm) at
50 m/s, 45 degrees onto polyurethane, dt = 1e-4 s (x_max/R = 0.5, the
contact ~13 us inside one step), MSF, contact-point mode:

- ``alone``: one bead (a row alone: the manager's own path);
- ``touching``: two beads side by side along y, touching, the same motion:
  an island of three rows whose bead-bead row carries no force;
- ``colliding``: the two beads closing at 4 m/s along y, meeting 30 % into
  their plate contacts (their impact, 0.75 N peak, couples the island).

Per scene and engine, for the compiled islands and the numpy reference
(``manager.island_compiled``): bead 1's cor_t, spin_out and W_diss_t
against :func:`msf_contact.simulate_impact` (relative errors) and cor_n's
absolute error. Prints a markdown table.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_islands import _bead_laws, _plate_records, bead_scene, run_beads  # noqa: E402

SCENES = (("alone", 1, 0.0), ("touching", 2, 0.0), ("colliding", 2, 2.0))


def main() -> None:
    ref = _bead_laws()[3]
    print(f"reference: cor_t {ref.cor_t:.6f}, spin_out {ref.spin_out:.1f} rad/s, W_diss_t {ref.W_diss_t:.4e} J, "
          f"cor_n {ref.cor_n:.6f}")
    print("| scene | engine | islands | island rows | cor_t err | spin_out err | W_diss_t err | cor_n err |")
    print("|---|---|---|---|---|---|---|---|")
    for engine in ("mujoco", "pybullet"):
        for name, n, vy in SCENES:
            for compiled in ((True,) if n == 1 else (True, False)):
                sc = bead_scene(engine, n, vy)
                sc.adapter.manager.island_compiled = compiled
                records, island_rows = run_beads(sc)
                rec = _plate_records(records)[0]
                err = {k: 100.0 * (getattr(rec, k) / getattr(ref, k) - 1.0) for k in ("cor_t", "spin_out", "W_diss_t")}
                print(f"| {name} | {engine} | {'compiled' if compiled else 'numpy'} | {island_rows} | "
                      f"{err['cor_t']:+.3f} % | {err['spin_out']:+.3f} % | {err['W_diss_t']:+.3f} % | "
                      f"{rec.cor_n - ref.cor_n:+.1e} |")


if __name__ == "__main__":
    main()
