"""docs/exact.md is what scripts/make_exact_comparison.py computes today.

Cheap: the hash of the comparison's inputs printed in the doc, and one row
(an SLS at tan delta ~0.3, 1 m/s: exact, msf, kuwabara-kono) recomputed
and compared with the printed numbers to their printed precision."""

from pathlib import Path

import pytest
from _scripts import load_script

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "exact.md"


@pytest.fixture(scope="module")
def mc():
    return load_script("make_exact_comparison")


def _row(text: str, first: str, second: str) -> list[str]:
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) > 2 and cells[0] == first and cells[1] == second:
            return cells
    raise AssertionError(f"no row {first!r}, {second!r} in {DOC}")


def test_doc_inputs_are_current(mc):
    assert f"Inputs hash: `{mc.case_hash()}`" in DOC.read_text(encoding="utf-8"), "run `make exact`"


def test_doc_row_is_recomputed(mc):
    text = DOC.read_text(encoding="utf-8")
    name, v = "SLS tan-peak 0.3", 1.0
    r = mc.run_case(mc.sls(0.3), mc.NU, mc.DENSITY, v, laws=("msf", "kuwabara-kono"))
    cells = _row(text, name, "1")
    # printed: tan d 4 significant digits, COR 6 decimals, tau 7 significant, errors 0.01 %
    assert abs(float(cells[2]) / r["tan_imp"] - 1) <= 5e-4
    assert abs(float(cells[4]) - r["exact"]["cor"]) <= 5e-7 + 1e-9
    assert abs(float(cells[5]) / r["exact"]["tau"] - 1) <= 5e-7
    n = len(mc.LAWS)
    for law in ("msf", "kuwabara-kono"):
        for k, q in enumerate(("cor", "tau")):
            printed = float(cells[6 + k * n + mc.LAWS.index(law)].rstrip("%"))
            assert abs(printed - 100 * mc.rel_err(r, law, q)) <= 0.005 + 1e-6, (law, q)


def test_doc_elastomer_row_is_recomputed(mc):
    """The real elastomer (NBR preset) at 1 m/s: exact COR and tau, and the COR error of MSF and of
    its offered correction, recomputed against the printed table."""
    text = DOC.read_text(encoding="utf-8")
    rel, nu, rho = mc.materials()[mc.ELASTOMER]
    r = mc.run_case(rel, nu, rho, 1.0, laws=("msf", "msf-hertz/2"))
    cells = _row(text, mc.ELASTOMER, "1")
    assert abs(float(cells[4]) - r["exact"]["cor"]) <= 5e-7 + 1e-9
    assert abs(float(cells[5]) / r["exact"]["tau"] - 1) <= 5e-7
    for law in ("msf", "msf-hertz/2"):
        printed = float(cells[6 + mc.LAWS.index(law)].rstrip("%"))
        assert abs(printed - 100 * mc.rel_err(r, law, "cor")) <= 0.005 + 1e-6, law
