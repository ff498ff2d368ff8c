"""Engines by name, resolved on first use.

The registry names where an engine's functions live (``"module:attr"``)
instead of importing them, so this module, :mod:`engines.base` and
:mod:`engines.pool` never import an adapter (no import circle between the
contract and the engines that implement it) and ``msf-contact --help``
loads no engine.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable

#: Engines for the command line: name -> "module:function" running one
#: isolated impact and returning an ImpactRecord. Resolved (imported) on the
#: first :func:`get_engine` of the name, so `msf-contact --help` stays fast
#: and this module never imports an adapter (no import circle).
ENGINES: dict[str, str] = {
    "mujoco": "engines.mujoco:run_impact",
    "mujoco-builtin": "engines.mujoco:run_builtin_impact",
    "pybullet": "engines.pybullet:run_impact",
    "pybullet-builtin": "engines.pybullet:run_builtin_registered",
}


def resolve(target: str) -> Any:
    """The object named by ``"package.module:attribute"`` (imported on demand)."""
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def get_engine(name: str) -> Callable[..., Any]:
    """The isolated-impact function of engine ``name`` (see :data:`ENGINES`)."""
    if name not in ENGINES:
        raise ValueError(f"engine = {name!r} is unknown; valid names: {', '.join(ENGINES)}")
    return resolve(ENGINES[name])
