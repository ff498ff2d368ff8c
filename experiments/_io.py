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


#: Relative slack of an axis span within which a data point counts as inside
#: (points exactly on a limit, and rounding of the limits).
FIGURE_SLACK = 1e-6

#: Smallest fraction of an axis span (of its decades on a log axis) that the
#: data's extent must cover (issue 12: jet_angle.png spanned 0-90 deg for data
#: at 27-62, 0.39 of the span; jet_pc_hist.png 0.1-1000 MPa for data at
#: 6-13 MPa, 0.08 of the decades). 0.3 leaves room for margins, legends kept
#: outside, and a marked reference value (a coating strength) beside the data,
#: while refusing an axis set from a fixed range rather than from the data.
DATA_SPAN_MIN = 0.3


def _artist_points(ax):
    """(n, 2) data coordinates of what ax draws in data coordinates: line
    vertices, scatter offsets, errorbar and line collections, bars and
    stairs. Artists in axes coordinates (axvline, axhline) are skipped."""
    import numpy as np
    from matplotlib.collections import Collection, LineCollection
    from matplotlib.patches import Rectangle, StepPatch

    pts = []
    for line in ax.get_lines():
        if line.get_transform() == ax.transData and line.get_visible():
            pts.append(np.asarray(line.get_xydata(), dtype=float).reshape(-1, 2))
    for col in ax.collections:
        if not isinstance(col, Collection) or not col.get_visible():
            continue
        if isinstance(col, LineCollection):
            pts += [np.asarray(seg, dtype=float).reshape(-1, 2) for seg in col.get_segments()]
        elif col.get_offset_transform() == ax.transData:
            pts.append(np.asarray(col.get_offsets(), dtype=float).reshape(-1, 2))
    for patch in ax.patches:
        if isinstance(patch, Rectangle) and patch.get_transform().contains_branch(ax.transData):
            x, y, w, h = patch.get_x(), patch.get_y(), patch.get_width(), patch.get_height()
            pts.append(np.array([[x, y], [x + w, y + h]], dtype=float))
        elif isinstance(patch, StepPatch):
            values, edges, baseline = patch.get_data()
            nz = np.flatnonzero(np.asarray(values) > 0)
            if nz.size:  # the bins that hold data
                pts.append(np.array([[edges[nz[0]], 0.0], [edges[nz[-1] + 1], float(np.max(values))]]))
    pts = [p for p in pts if p.size]
    return np.concatenate(pts) if pts else np.empty((0, 2))


def _reference_values(ax):
    """(x values, y values) [data units] of the reference lines an axes marks
    with axvline / axhline: a Line2D drawn in the x- (or y-) axis blended
    transform, whose data-coordinate x (y) is constant. They are not data
    (:func:`_artist_points` skips them) but a marked value (a strength, a
    limit) is a reason for the axis to reach it."""
    import numpy as np

    xs, ys = [], []
    for line in ax.get_lines():
        if not line.get_visible():
            continue
        tr = line.get_transform()
        if tr == ax.get_xaxis_transform():
            xs += list(np.asarray(line.get_xdata(), dtype=float).ravel())
        elif tr == ax.get_yaxis_transform():
            ys += list(np.asarray(line.get_ydata(), dtype=float).ravel())
    return np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)


def _area_points(ax):
    """(n, 2) data-coordinate vertices of filled areas an axes draws in data
    coordinates (fill_between bands, PolyCollections): data for the span of
    an axis, though not points a legend must leave uncovered."""
    import numpy as np
    from matplotlib.collections import LineCollection, PolyCollection

    pts = [np.asarray(p.vertices, dtype=float).reshape(-1, 2)
           for col in ax.collections
           if isinstance(col, PolyCollection) and not isinstance(col, LineCollection) and col.get_visible()
           and col.get_transform().contains_branch(ax.transData) for p in col.get_paths()]
    pts = [p for p in pts if p.size]
    return np.concatenate(pts) if pts else np.empty((0, 2))


def _span_fraction(v, lo: float, hi: float, log: bool) -> float:
    """Fraction of the axis span [lo, hi] covered by the extent of values v:
    of the span on a linear axis, of the decades on a log axis (positive
    values only). 1.0 (nothing to judge) when v is empty or one value."""
    import numpy as np

    if log:
        v = v[v > 0]
        if v.size < 2 or lo <= 0:
            return 1.0
        ext, span = np.log10(v.max() / v.min()), np.log10(hi / lo)
    else:
        ext, span = v.max() - v.min() if v.size else 0.0, hi - lo
    if ext <= 0 or span <= 0:
        return 1.0
    return float(ext / span)


#: Alpha at or above which a curve drawn later covers an earlier one (below
#: it the earlier curve shows through, tinted).
COVER_ALPHA_MIN = 0.7


def _solid(ls) -> bool:
    return ls in ("-", "solid")


def _no(style) -> bool:
    """No line or no marker: matplotlib's 'None', '', ' ' or None."""
    return style is None or (isinstance(style, str) and style.strip() in ("", "None", "none"))


def _line_covers(a, b) -> bool:
    """Line2D b, drawn after a over the same data, hides a: b is opaque enough
    (COVER_ALPHA_MIN), a's line is under a line of b at least as wide, solid
    or dashed alike, and a's markers (if any) under markers of b of the same
    shape, no smaller, filled unless a's are hollow too."""
    if (b.get_alpha() if b.get_alpha() is not None else 1.0) < COVER_ALPHA_MIN:
        return False
    if not _no(a.get_linestyle()):
        if _no(b.get_linestyle()) or b.get_linewidth() < a.get_linewidth():
            return False
        if not (_solid(b.get_linestyle()) or b.get_linestyle() == a.get_linestyle()):
            return False
    if not _no(a.get_marker()):
        if b.get_marker() != a.get_marker() or b.get_markersize() < a.get_markersize():
            return False
        if _no(b.get_markerfacecolor()) and not _no(a.get_markerfacecolor()):
            return False
    return True


def _same(u, v) -> bool:
    import numpy as np

    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    return u.shape == v.shape and u.size > 0 and bool(np.allclose(u, v, rtol=1e-12, atol=0.0, equal_nan=True))


def _hidden_curve(ax) -> tuple[str, str] | None:
    """(hidden, covering) labels of the first curve of ax that a later one
    draws over entirely (issue 12: in jet_pc_hist.png the two engines'
    histograms coincided and MuJoCo's was hidden under pybullet's): the same
    data, and a style that covers it (:func:`_line_covers`; for stairs the
    same edges and values under a line at least as wide). Errorbar caps
    (markers '_' or '|' without a line) are left out; a curve seen as
    distinct only by its colour is not distinct when the other lies on it."""
    from matplotlib.patches import StepPatch

    lines = [ln for ln in ax.get_lines() if ln.get_visible() and ln.get_transform() == ax.transData
             and not (_no(ln.get_linestyle()) and ln.get_marker() in ("_", "|"))]
    for i, a in enumerate(lines):
        for b in lines[i + 1:]:
            if _same(a.get_xdata(), b.get_xdata()) and _same(a.get_ydata(), b.get_ydata()) and _line_covers(a, b):
                return a.get_label(), b.get_label()
    steps = [p for p in ax.patches if isinstance(p, StepPatch) and p.get_visible()]
    for i, a in enumerate(steps):
        for b in steps[i + 1:]:
            (va, ea, _), (vb, eb, _) = a.get_data(), b.get_data()
            if (_same(va, vb) and _same(ea, eb) and b.get_linewidth() >= a.get_linewidth()
                    and (b.get_alpha() if b.get_alpha() is not None else 1.0) >= COVER_ALPHA_MIN):
                return a.get_label(), b.get_label()
    return None


def check_figure(fig, name: str) -> None:
    """Refuse a report figure that hides data or whose axes are not set by
    the data (issue 12): every point an axes draws lies inside its limits; on
    each axis the extent of what is drawn (data and filled bands, plus values
    marked with axvline / axhline) covers at least :data:`DATA_SPAN_MIN` of the axis span
    (of its decades on a log axis); no legend inside an axes covers a point;
    no curve lies wholly under a later one with the same data and a covering
    style (:func:`_hidden_curve`: give coinciding engines their own markers,
    widths or panels). Raises ValueError naming the figure, the axes and the
    offending value."""
    import numpy as np

    fig.canvas.draw()
    for i, ax in enumerate(fig.axes):
        pts = _artist_points(ax)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if not len(pts):
            continue
        label = f"figure {name}, axes {i} ({ax.get_title() or ax.get_ylabel()!r})"
        hidden = _hidden_curve(ax)
        if hidden:
            raise ValueError(f"{label}: the curve {hidden[0]!r} lies wholly under {hidden[1]!r} (the same data, "
                             "a covering style); give each its own marker or width, or its own panel")
        refs = _reference_values(ax)
        area = _area_points(ax)
        area = area[np.all(np.isfinite(area), axis=1)]
        for k, (lim, scale) in enumerate(((ax.get_xlim(), ax.get_xscale()), (ax.get_ylim(), ax.get_yscale()))):
            lo, hi = sorted(lim)
            v = pts[:, k]
            if scale == "log":
                bad = v[(v <= 0) | (v < lo * (1 - FIGURE_SLACK)) | (v > hi * (1 + FIGURE_SLACK))]
            else:
                slack = FIGURE_SLACK * (hi - lo)
                bad = v[(v < lo - slack) | (v > hi + slack)]
            if bad.size:
                raise ValueError(f"{label}: data at {'xy'[k]} = {bad[0]:.6g} outside the axis [{lo:.6g}, {hi:.6g}]")
            drawn = np.concatenate([v, area[:, k], refs[k][np.isfinite(refs[k])]])
            frac = _span_fraction(drawn, lo, hi, scale == "log")
            if frac < DATA_SPAN_MIN:
                raise ValueError(
                    f"{label}: the data span {'xy'[k]} = [{drawn.min():.6g}, {drawn.max():.6g}], "
                    f"{frac:.0%} of the {'decades of the ' if scale == 'log' else ''}axis [{lo:.6g}, {hi:.6g}] "
                    f"(at least {DATA_SPAN_MIN:.0%}); set the limits from the data")
        legend = ax.get_legend()
        if legend is not None and legend.get_visible():
            box = legend.get_window_extent()
            axbox = ax.get_window_extent()
            if box.overlaps(axbox):
                disp = ax.transData.transform(pts)
                inside = ((disp[:, 0] > box.x0) & (disp[:, 0] < box.x1) & (disp[:, 1] > box.y0)
                          & (disp[:, 1] < box.y1))
                if np.any(inside):
                    j = int(np.flatnonzero(inside)[0])
                    raise ValueError(f"{label}: the legend covers data at ({pts[j, 0]:.6g}, {pts[j, 1]:.6g}); "
                                     "place it outside the axes")


def save_figure_atomic(fig, path: str | os.PathLike, **kw) -> Path:
    """Save a matplotlib figure atomically (PNG by default), after
    :func:`check_figure`."""
    path = Path(path)
    check_figure(fig, path.name)
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
