"""Sweeps: a grid of independent cells run on local processes or on Dask.

Each cell is a JSON-serialisable dict; its key is a hash of that dict. A
finished cell is written atomically to ``DIR/cells/<key>.json`` as soon as
its result arrives, so an interrupted sweep resumes where it stopped:
completed cells are skipped on re-run and every cell ends up exactly once.
``collect`` rebuilds the record table from the cell files.

Backends: ``workers=1`` runs in this process; ``workers>1`` uses a
``ProcessPoolExecutor``; ``dask="local"`` a ``distributed.LocalCluster``,
``dask="tcp://host:port"`` an existing scheduler. The same function and the
same cells give identical records on every backend (the cell functions are
deterministic; seeds are part of the cell).
"""

from __future__ import annotations

import hashlib
import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any, Callable, Iterable

from ._io import write_json_atomic

CellFn = Callable[[dict], list[dict]]


def cell_key(cell: dict) -> str:
    """Stable 16-hex key of a cell (sorted-key JSON, SHA-256)."""
    blob = json.dumps(cell, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def cells_dir(out: Path) -> Path:
    return Path(out) / "cells"


def done_keys(out: Path) -> set[str]:
    d = cells_dir(out)
    if not d.is_dir():
        return set()
    return {p.stem for p in d.glob("*.json")}


def _save(out: Path, cell: dict, records: list[dict]) -> None:
    write_json_atomic(cells_dir(out) / f"{cell_key(cell)}.json", {"cell": cell, "records": records})


def _progress(total: int, quiet: bool, desc: str):
    if quiet:
        return None
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="cell", file=sys.stderr, dynamic_ncols=True)


def run_sweep(
    fn: CellFn,
    cells: Iterable[dict],
    out: Path,
    *,
    workers: int = 1,
    dask: str | None = None,
    quiet: bool = False,
    desc: str = "sweep",
) -> dict[str, int]:
    """Run every cell not yet done; returns counts {total, skipped, ran}."""
    cells = list(cells)
    keys = [cell_key(c) for c in cells]
    if len(set(keys)) != len(keys):
        raise ValueError("the sweep has duplicate cells (two cells with identical parameters)")
    done = done_keys(out)
    todo = [c for c, k in zip(cells, keys) if k not in done]
    bar = _progress(len(todo), quiet, desc)
    try:
        if dask is not None:
            _run_dask(fn, todo, out, dask, workers, bar)
        elif workers <= 1:
            for c in todo:
                _save(out, c, fn(c))
                if bar:
                    bar.update()
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                futs = {pool.submit(fn, c): c for c in todo}
                for f in as_completed(futs):
                    _save(out, futs[f], f.result())
                    if bar:
                        bar.update()
    finally:
        if bar:
            bar.close()
    return {"total": len(cells), "skipped": len(cells) - len(todo), "ran": len(todo)}


def _run_dask(fn, todo, out, address, workers, bar):
    try:
        from distributed import Client, LocalCluster, as_completed as das_completed
    except ImportError as exc:  # pragma: no cover - dask is a declared dependency
        raise RuntimeError("--dask needs the 'distributed' package (pip install 'dask[distributed]')") from exc
    cluster = None
    if address == "local":
        cluster = LocalCluster(n_workers=max(workers, 1), threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    else:
        client = Client(address)
    try:
        futs = client.map(fn, todo, pure=False)
        by_future = dict(zip(futs, todo))
        for f in das_completed(futs):
            _save(out, by_future[f], f.result())
            if bar:
                bar.update()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def collect(out: Path, keys: set[str] | None = None) -> list[dict[str, Any]]:
    """The records of the finished cells (only those in ``keys`` if given: a
    folder reused with another configuration keeps its old cells), each with
    its cell's parameters under ``cell.*`` and the cell key, sorted by key.
    A cell's nested tables (dict values, e.g. the jet's whole configuration)
    are not copied onto its records: they stay once in ``cells/<key>.json``
    (and the configuration in ``manifest.json``)."""
    rows = []
    for p in sorted(cells_dir(out).glob("*.json")):
        if keys is not None and p.stem not in keys:
            continue
        blob = json.loads(p.read_text())
        params = {f"cell.{k}": v for k, v in blob["cell"].items() if not isinstance(v, dict)}
        for i, rec in enumerate(blob["records"]):
            row = dict(params)
            row["cell_key"] = p.stem
            row["record_index"] = i
            row.update(rec)
            rows.append(row)
    return rows
