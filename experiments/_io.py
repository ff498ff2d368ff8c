"""Atomic output: every result file is written to a temporary file in the
same folder and renamed, so an interrupted run leaves no half-written file."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Any


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temp file + os.replace)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def write_json_atomic(path: str | os.PathLike, obj: Any) -> Path:
    return write_text_atomic(path, json.dumps(obj, indent=2, sort_keys=True, allow_nan=False) + "\n")


def add_figure(fig, out: str | os.PathLike, name: str, figs: list[str], dpi: int = 110) -> None:
    """A report figure: laid out, saved atomically as ``out/figures/name``,
    closed, and its name appended to ``figs``."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    save_figure_atomic(fig, Path(out) / "figures" / name, dpi=dpi)
    plt.close(fig)
    figs.append(name)


def figure_links(figs: list[str]) -> str:
    """Markdown image links to the report's figures (``figures/<name>``)."""
    return "".join(f"![{name}](figures/{name})\n\n" for name in figs)


def save_figure_atomic(fig, path: str | os.PathLike, **kw) -> Path:
    """Save a matplotlib figure atomically (PNG by default)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, **kw)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
