"""The contact manager's state saved and put back, so that an adapter can
take a step again (issue 13: pybullet's limit trial, a step solved again
with the joints its own forces hold, engines.pybullet.adapter).

:func:`save` copies every attribute of a :class:`ContactManager` that a
step changes (arrays, lists, dicts, the island energy check's bookkeeping);
:func:`restore` puts them back: arrays in place, so that the views of the
record bookkeeping (``t_onset``, ``h``, ... are rows of one (NF, P) array
the compiled kernel writes) stay views. The laws, the adapter's callbacks
and the finished records' objects are kept by reference: a step does not
change a law (refresh_law is called by an adapter between steps), and a
record made in a step taken again is dropped with the list it was appended
to. What cannot be taken back: warnings already issued.
"""

from __future__ import annotations

import numpy as np

from .balance import DeepOnsets, IslandBalance

_OBJECTS = (IslandBalance, DeepOnsets)  # helper objects whose own state a step changes


def _copy(v):
    if isinstance(v, np.ndarray):
        return v.copy()
    if isinstance(v, list):
        return [_copy(e) for e in v]
    if isinstance(v, tuple):
        return tuple(_copy(e) for e in v)
    if isinstance(v, dict):
        return {k: _copy(e) for k, e in v.items()}
    if isinstance(v, set):
        return set(v)
    if isinstance(v, _OBJECTS):
        return ("__object__", v, {k: _copy(e) for k, e in vars(v).items()})
    return v  # numbers, strings, laws, callables, records: by reference


def _put(obj, name, saved) -> None:
    cur = getattr(obj, name, None)
    if isinstance(saved, np.ndarray):
        if isinstance(cur, np.ndarray) and cur.shape == saved.shape and cur.dtype == saved.dtype:
            cur[...] = saved  # in place: views of it stay views
            return
        setattr(obj, name, saved.copy())
        return
    if isinstance(saved, tuple) and len(saved) == 3 and isinstance(saved[0], str) and saved[0] == "__object__":
        for k, e in saved[2].items():
            _put(saved[1], k, e)
        setattr(obj, name, saved[1])
        return
    setattr(obj, name, _copy(saved))


def save(mgr) -> dict:
    """The state of ``mgr`` (a ContactManager) that its ``step`` changes, copied."""
    return {k: _copy(v) for k, v in vars(mgr).items()}


def restore(mgr, state: dict) -> None:
    """Put ``state`` (from :func:`save` of the same manager) back into ``mgr``;
    ``state`` stays usable for another restore."""
    for k in [k for k in vars(mgr) if k not in state]:  # attributes a step added
        delattr(mgr, k)
    for k, v in state.items():
        _put(mgr, k, v)
