"""The code shown in README.md and docs/engines.md runs and means what it says."""

import math
import re
from pathlib import Path

import pytest

from msf_contact import Body, ContactPair, Curvature, make_law, preset, simulate_impact

ROOT = Path(__file__).resolve().parent.parent
#: An engine at a 1 ms step against the reference solver (issue 3: 0.5%).
ENGINE_COR_RTOL = 5e-3


def python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)


@pytest.mark.mujoco
def test_engines_doc_example_bounces_like_the_reference(capsys):
    (block,) = python_blocks(ROOT / "docs" / "engines.md")
    ns: dict = {}
    exec(compile(block, "docs/engines.md", "exec"), ns)
    records = ns["adapter"].records
    assert len(records) >= 3
    ball, plate = preset("natural-rubber"), preset("steel")
    law = make_law("msf", ContactPair(ball, plate), Curvature.sphere_on_plane(0.02))
    first = records[0]
    v_in = first.inputs["v_n_in"]
    assert v_in == pytest.approx(math.sqrt(2 * 9.81 * (0.3 - 0.02)), rel=1e-2)  # free fall to the floor
    want = simulate_impact(law, Body(ball, 0.02, 0.0312), Body.half_space(plate), v_in)
    assert first.cor_n == pytest.approx(want.cor_n, rel=ENGINE_COR_RTOL)
    # what the doc says it prints, at the quoted precision: the first three bounces
    quoted = re.search(r"the first three with COR ([0-9.]+) and tau ([0-9.]+)-([0-9.]+) ms",
                       " ".join((ROOT / "docs" / "engines.md").read_text().split()))
    assert quoted, "docs/engines.md: the sentence under the example changed"
    assert {f"{r.cor_n:.3f}" for r in records[:3]} == {quoted.group(1)}
    taus = [r.tau * 1e3 for r in records[:3]]
    assert (f"{min(taus):.1f}", f"{max(taus):.1f}") == quoted.group(2, 3)
    # each bounce loses energy
    speeds = [r.inputs["v_n_in"] for r in records[:4]]
    assert all(b < a for a, b in zip(speeds, speeds[1:]))
