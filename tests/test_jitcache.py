"""numba's cache=True is keyed on a kernel's own file only (numba's docs;
numba/numba#1833): msf_contact._jitcache.guard flushes a module's cached
kernels when a module they compile in changes. Checked on a two-module
package in fresh interpreters (the stale answer without the guard shows the
test can fail), and every kernel module of the project is checked to list
each project module it imports from."""
import ast
import importlib
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

KERNEL_MODULES = sorted(
    ".".join(p.relative_to(ROOT).with_suffix("").parts)
    for pkg in ("engines", "msf_contact") for p in (ROOT / pkg).rglob("*.py")
    if re.search(r"cache=True|^@(jit|jit_inline)\b", p.read_text(), re.M) and p.name != "_jitcache.py")

DEP = "from numba import njit\n\n\n@njit(cache=True)\ndef f():\n    return {value}\n"
MAIN = textwrap.dedent("""\
    from numba import njit
    from {pkg} import dep
    {guard}

    @njit(cache=True)
    def g():
        return dep.f() + 0
    {call}
    """)


def _package(root: Path, name: str, guarded: bool) -> None:
    pkg = root / name
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "dep.py").write_text(DEP.format(value=1))
    (pkg / "main.py").write_text(MAIN.format(
        pkg=name, guard="from msf_contact._jitcache import guard" if guarded else "",
        call="guard(__name__, dep)" if guarded else ""))


def _run(root: Path) -> list[int]:
    code = "from guarded import main as a; from plain import main as b; print(a.g(), b.g())"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), str(ROOT)]))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=root)
    return [int(v) for v in out.stdout.split()]


def test_a_change_in_a_compiled_in_module_recompiles_the_kernel(tmp_path):
    _package(tmp_path, "guarded", True)
    _package(tmp_path, "plain", False)
    assert _run(tmp_path) == [1, 1]            # compiled and cached
    assert _run(tmp_path) == [1, 1]            # loaded from the cache
    for name in ("guarded", "plain"):
        (tmp_path / name / "dep.py").write_text(DEP.format(value=22))  # new size: numba re-stamps dep.py
    guarded, plain = _run(tmp_path)
    assert guarded == 22
    assert plain == 1, "numba's own cache no longer goes stale: the guard may be dropped"


@pytest.mark.parametrize("name", KERNEL_MODULES)
def test_each_kernel_module_lists_every_project_module_it_imports(name):
    module = importlib.import_module(name)
    listed = {Path(p).resolve() for p in getattr(module, "__jit_sources__", ())}
    assert listed, f"{name} uses numba's cache but does not call msf_contact._jitcache.guard"
    tree = ast.parse(Path(module.__file__).read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = importlib.util.resolve_name("." * node.level + (node.module or ""), module.__package__)
            targets = [base] + [f"{base}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            continue
        for t in targets:  # a module imported whole or a name from it: its source is compiled in
            imported = sys.modules.get(t)
            if t.split(".")[0] not in ("engines", "msf_contact") or t == "msf_contact._jitcache" or imported is None:
                continue
            origin = getattr(imported, "__file__", None) or ""
            if origin.endswith(".py") and not origin.endswith("__init__.py"):
                assert Path(origin).resolve() in listed, f"{name} imports {t} but its guard does not hash it"
