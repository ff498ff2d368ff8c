"""Generate docs/validation.md and the measured numbers in docs/errata.md.

Usage:  .venv/bin/python scripts/make_validation.py docs/validation.md   (= make docs)

Runs the computations of ``msf_contact.validation`` once, writes the
validation report to the given path, and refreshes the generated blocks
(``<!-- generated:NAME -->`` ... ``<!-- /generated:NAME -->``) of
``errata.md`` in the same folder when that file exists. Every file is
written atomically (a temporary file in the same folder, then os.replace),
so an interrupted run never leaves a half-written document.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from experiments._io import write_text_atomic as write_atomic
from msf_contact import validation as val


def fill_blocks(text: str, blocks: dict[str, str]) -> str:
    """Replace the body of each <!-- generated:NAME --> ... <!-- /generated:NAME --> block."""
    for name, body in blocks.items():
        pat = re.compile(rf"(<!-- generated:{name} -->\n).*?(<!-- /generated:{name} -->)", re.S)
        if not pat.search(text):
            raise ValueError(f"errata.md has no generated block {name!r}")
        text = pat.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", nargs="?", default="docs/validation.md", help="validation report path")
    args = ap.parse_args(argv)
    out = Path(args.out)
    comps = val.msf_comparisons()
    tables = val.all_rows(comps)
    errata = val.errata_numbers(comps)
    write_atomic(out, val.render_validation(tables, comps, errata))
    errata_path = out.parent / "errata.md"
    if errata_path.exists():
        write_atomic(errata_path, fill_blocks(errata_path.read_text(encoding="utf-8"),
                                              val.render_errata_blocks(comps, errata)))
    n_fail = sum(1 for rows in tables.values() for r in rows if r.passed is False)
    print(f"wrote {out}" + (f" and {errata_path}" if errata_path.exists() else "") + f"; failing checks: {n_fail}")
    return 1 if n_fail else 0


if __name__ == "__main__":
    sys.exit(main())
