"""Engines of `msf-contact impact --engine` beyond the reference solver and
the closed forms: the MuJoCo and pybullet adapters and their built-in
contact. Registered into experiments.cli.ENGINES by :func:`load_engines`."""

from __future__ import annotations

_LOADED = False


def load_engines() -> None:
    """Register the engine adapters' impact runners (idempotent)."""
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
