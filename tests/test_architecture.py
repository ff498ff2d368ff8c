"""The layers of docs/architecture.md: import-linter's contracts (pyproject.toml,
run by ``make test``) check the layers and circles between sibling modules and
packages; this test checks, with grimp (the graph import-linter builds, with
function-level imports), that no module imports itself back through any chain."""

import grimp

#: The packages of the repository (scripts/ is not a package: its imports
#: are plain scripts on top of everything).
ROOTS = ("msf_contact", "engines", "experiments", "benchmarks")


def test_no_import_circle_between_modules():
    graph = grimp.build_graph(*ROOTS, cache_dir=None)
    circles = sorted((a, b) for a in graph.modules for b in graph.find_modules_directly_imported_by(a)
                     if b != a and graph.chain_exists(importer=b, imported=a))
    assert not circles, "imports that close a circle (importer, imported): " + ", ".join(f"{a} -> {b}"
                                                                                          for a, b in circles)

