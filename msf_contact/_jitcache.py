"""Keep numba's on-disk kernel cache true to the sources it was compiled from.

numba's ``cache=True`` keys a cached kernel on the stamp (mtime, size) of
its own source file only. A kernel that calls a jitted function of another
module, or reads another module's constants (numba freezes globals at
compile time), is not recompiled when that other module changes: numba's
documentation says so ("Cache invalidation fails to recognize changes in
functions defined in a different file ... This carries the risk that 'old'
function code might be used in the calculations"; numba/numba#1833, the
fix still open as numba/numba#8396). For us that is a silent wrong answer
after a ``git pull`` or an upgrade: ``engines._island_kernel`` compiles in
``engines._kernel``'s force laws, ``engines._impact_kernel`` those and
``msf_contact._normal``'s constants. (Found on a working tree whose stale
island kernels made gymnasium's Ant-v5 blow up where fresh ones do not.)

:func:`guard`, called at the end of each kernel module, hashes the module's
source with the sources it compiles in and, when the hash differs from the
one stored beside the module's cache index, empties the index of every
cached kernel of the module (numba's ``Cache.flush``), so they compile
afresh on first call. Each module lists its sources in
``__jit_sources__``; ``tests/test_jitcache.py`` checks the list covers every
project module it imports from.
"""
from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

__all__ = ["guard"]


def _digest(files: list[Path]) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(str(f.name).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def guard(module_name: str, *sources) -> str:
    """Flush the cached kernels of module ``module_name`` when its source or
    any of ``sources`` (modules, or paths of files) changed since they were
    cached. Call it at the end of the module, before any of its kernels has
    run. Returns the hex digest of the sources. Sets the module's
    ``__jit_sources__`` (tuple of paths, the module's own first)."""
    module = sys.modules[module_name]
    own = Path(module.__file__).resolve()
    files = [own] + [Path(getattr(s, "__file__", s)).resolve() for s in sources]
    module.__jit_sources__ = tuple(str(f) for f in files)
    digest = _digest(files)
    caches = {}
    for obj in vars(module).values():
        cache = getattr(obj, "_cache", None)  # numba Dispatcher's FunctionCache (NullCache without cache=True)
        path = getattr(cache, "_cache_path", None)
        if path is not None and getattr(obj, "py_func", None) is not None \
                and getattr(obj.py_func, "__module__", None) == module_name:
            caches.setdefault(path, []).append(cache)
    for path, group in caches.items():
        stamp = Path(path) / f"{own.stem}.sources.sha256"
        try:
            if stamp.read_text() == digest:
                continue
        except OSError:
            pass
        for cache in group:
            cache.flush()
        try:
            _write_atomic(stamp, digest)
        except OSError:  # a read-only cache: nothing stale can be stored there either
            pass
    return digest
