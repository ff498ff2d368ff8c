"""Fixed-size aggregates of plate impacts (:class:`JetAggregates`: memory
independent of their number) and Finnie's angle function drawn next to
them (:func:`finnie`)."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from .spec import Bins


# --------------------------------------------------------------------------
# Finnie's angle function
# --------------------------------------------------------------------------
def finnie(angle_deg) -> np.ndarray:
    """Finnie's angle function of ductile erosion, normalised to its maximum
    (1 at 16.85 deg): f(a) = sin(2a) - 3 sin^2(a) for tan(a) <= 1/3
    (a <= 18.43 deg), cos^2(a)/3 above.

    I. Finnie, "Erosion of surfaces by solid particles", Wear 3 (1960) 87-103,
    the volume removed by one particle cutting a ductile surface (with the
    ratio of vertical to horizontal force K = 2 and the contact depth ratio
    l/y = 2 of that paper, which give the 1/3 and the 3 above). Shown for
    comparison with the dissipated energy against angle; it is a cutting
    model, not a consequence of the MSF law.
    """
    a = np.radians(np.asarray(angle_deg, dtype=float))
    low = np.sin(2 * a) - 3.0 * np.sin(a) ** 2
    high = np.cos(a) ** 2 / 3.0
    f = np.where(np.tan(a) <= 1.0 / 3.0, low, high)
    a_max = 0.5 * math.atan(2.0 / 3.0)  # d/da (sin 2a - 3 sin^2 a) = 0
    return f / (math.sin(2 * a_max) - 3.0 * math.sin(a_max) ** 2)


# --------------------------------------------------------------------------
# Aggregates (fixed size)
# --------------------------------------------------------------------------
class JetAggregates:
    """Fixed-size aggregates of plate impacts (memory independent of their number).

    Arrays (all sums, so aggregates of chunks add up):
    angle_edges [deg] (na + 1,); per angle bin: n, cor_n sum and sum of
    squares, cor_t count and sum, W (W_diss_n + W_diss_t) [J], W_n, W_t,
    E_in (incoming kinetic energy) [J], W/E_in sum [-];
    map_edges_x, map_edges_y [m]; map_W [J] (nx, ny) and map_n (nx, ny);
    off_map_W [J], off_map_n; pc_edges [Pa] (npc + 1,), pc_counts (npc + 2,)
    with under- and overflow at both ends; n_above_strength; Pc_max_max [Pa];
    per size class n and W [J]; totals.
    """

    _ARRAYS = ("a_n", "a_cor", "a_cor2", "a_nt", "a_cort", "a_W", "a_Wn", "a_Wt", "a_E", "a_frac", "map_W", "map_n",
               "pc_counts", "cls_n", "cls_W")
    _SCALARS = ("n", "W_n", "W_t", "E_in", "off_map_W", "off_map_n", "n_above_strength", "Pc_max_max",
                "n_outside_validity", "n_repeat")

    def __init__(self, bins: Bins, plate_size, strength: float, n_classes: int):
        self.bins = bins
        self.strength = float(strength)
        na = bins.angle_bins
        nx, ny = bins.map_bins
        self.angle_edges = np.linspace(0.0, 90.0, na + 1)
        hx, hy = 0.5 * float(plate_size[0]), 0.5 * float(plate_size[1])
        self.map_edges_x = np.linspace(-hx, hx, nx + 1)
        self.map_edges_y = np.linspace(-hy, hy, ny + 1)
        self.pc_edges = np.geomspace(bins.pc_range[0], bins.pc_range[1], bins.pc_bins + 1)
        for k in ("a_n", "a_nt"):
            setattr(self, k, np.zeros(na, np.int64))
        for k in ("a_cor", "a_cor2", "a_cort", "a_W", "a_Wn", "a_Wt", "a_E", "a_frac"):
            setattr(self, k, np.zeros(na))
        self.map_W = np.zeros((nx, ny))
        self.map_n = np.zeros((nx, ny), np.int64)
        self.pc_counts = np.zeros(bins.pc_bins + 2, np.int64)
        self.cls_n = np.zeros(n_classes, np.int64)
        self.cls_W = np.zeros(n_classes)
        self.n = self.off_map_n = self.n_above_strength = self.n_outside_validity = self.n_repeat = 0
        self.W_n = self.W_t = self.E_in = self.off_map_W = self.Pc_max_max = 0.0

    @property
    def cell_area(self) -> float:
        """Area of one map cell [m^2]."""
        return float(np.diff(self.map_edges_x)[0] * np.diff(self.map_edges_y)[0])

    #: The per-impact values the aggregates read (keys of the impact rows, :meth:`JetPool.run`).
    COLUMNS = ("angle_deg", "cor_n", "cor_t", "W_diss_n", "W_diss_t", "E_in", "x", "y", "Pc_max", "cls",
               "outside_validity", "repeat")

    def add(self, rows: Sequence[dict]) -> None:
        """Add plate-impact rows (dicts with the keys ``COLUMNS``, as the impact
        rows of :meth:`JetPool.run`; cor_t may be None)."""
        if not rows:
            return
        cols = {k: [r[k] for r in rows] for k in self.COLUMNS}
        cols["cor_t"] = [np.nan if v is None else v for v in cols["cor_t"]]
        cols["outside_validity"] = [bool(v) for v in cols["outside_validity"]]
        self.add_columns({k: np.asarray(v) for k, v in cols.items()})

    def add_columns(self, cols: dict[str, np.ndarray]) -> None:
        """Add k plate impacts given as columns (k,) under the keys ``COLUMNS``:
        angle_deg [deg], cor_n, cor_t (NaN: none), W_diss_n, W_diss_t, E_in [J],
        x, y [m], Pc_max [Pa], cls, outside_validity and repeat (bool)."""
        ang = np.asarray(cols["angle_deg"], dtype=float)
        if ang.size == 0:
            return
        cor = np.asarray(cols["cor_n"], dtype=float)
        cort = np.asarray(cols["cor_t"], dtype=float)
        Wn = np.asarray(cols["W_diss_n"], dtype=float)
        Wt = np.asarray(cols["W_diss_t"], dtype=float)
        E = np.asarray(cols["E_in"], dtype=float)
        x = np.asarray(cols["x"], dtype=float)
        y = np.asarray(cols["y"], dtype=float)
        pc = np.asarray(cols["Pc_max"], dtype=float)
        cls = np.asarray(cols["cls"], dtype=int)
        W = Wn + Wt
        na = self.bins.angle_bins
        ia = np.clip(np.searchsorted(self.angle_edges, ang, side="left") - 1, 0, na - 1)  # (a0, a1] bins
        np.add.at(self.a_n, ia, 1)
        np.add.at(self.a_cor, ia, cor)
        np.add.at(self.a_cor2, ia, cor * cor)
        ok = np.isfinite(cort)
        np.add.at(self.a_nt, ia[ok], 1)
        np.add.at(self.a_cort, ia[ok], cort[ok])
        np.add.at(self.a_W, ia, W)
        np.add.at(self.a_Wn, ia, Wn)
        np.add.at(self.a_Wt, ia, Wt)
        np.add.at(self.a_E, ia, E)
        np.add.at(self.a_frac, ia, W / E)
        nx, ny = self.bins.map_bins
        ix = np.searchsorted(self.map_edges_x, x, side="right") - 1
        iy = np.searchsorted(self.map_edges_y, y, side="right") - 1
        on = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        np.add.at(self.map_W, (ix[on], iy[on]), W[on])
        np.add.at(self.map_n, (ix[on], iy[on]), 1)
        self.off_map_W += float(W[~on].sum())
        self.off_map_n += int((~on).sum())
        ip = np.searchsorted(self.pc_edges, pc, side="right")  # 0: underflow, npc + 1: overflow
        np.add.at(self.pc_counts, ip, 1)
        self.n_above_strength += int((pc > self.strength).sum())
        self.Pc_max_max = max(self.Pc_max_max, float(pc.max()))
        np.add.at(self.cls_n, cls, 1)
        np.add.at(self.cls_W, cls, W)
        self.n += int(ang.size)
        self.W_n += float(Wn.sum())
        self.W_t += float(Wt.sum())
        self.E_in += float(E.sum())
        self.n_outside_validity += int(np.count_nonzero(cols["outside_validity"]))
        self.n_repeat += int(np.count_nonzero(cols["repeat"]))

    def merge(self, other: "JetAggregates") -> None:
        for k in self._ARRAYS:
            getattr(self, k).__iadd__(getattr(other, k))
        for k in self._SCALARS:
            if k == "Pc_max_max":
                self.Pc_max_max = max(self.Pc_max_max, other.Pc_max_max)
            else:
                setattr(self, k, getattr(self, k) + getattr(other, k))

    def to_dict(self) -> dict:
        d = {k: getattr(self, k).tolist() for k in self._ARRAYS}
        d.update({k: getattr(self, k) for k in self._SCALARS})
        d.update(strength=self.strength, plate_size=[float(self.map_edges_x[-1] * 2), float(self.map_edges_y[-1] * 2)],
                 bins={"angle_bins": self.bins.angle_bins, "map_bins": list(self.bins.map_bins),
                       "pc_range": list(self.bins.pc_range), "pc_bins": self.bins.pc_bins})
        return d

    @staticmethod
    def from_dict(d: dict) -> "JetAggregates":
        b = d["bins"]
        a = JetAggregates(Bins(b["angle_bins"], tuple(b["map_bins"]), tuple(b["pc_range"]), b["pc_bins"]),
                          d["plate_size"], d["strength"], len(d["cls_n"]))
        for k in JetAggregates._ARRAYS:
            getattr(a, k)[...] = np.asarray(d[k], dtype=getattr(a, k).dtype)
        for k in JetAggregates._SCALARS:
            setattr(a, k, d[k])
        return a

    # -- derived ---------------------------------------------------------------
    def energy_density(self) -> np.ndarray:
        """Dissipated energy per unit area of the plate [J/m^2] (nx, ny): the wear proxy."""
        return self.map_W / self.cell_area

    def by_angle(self) -> dict[str, np.ndarray]:
        """Per angle bin: centre [deg], n, mean and sd of cor_n, mean cor_t,
        mean dissipated energy per impact [J], mean dissipated fraction W/E_in."""
        n = self.a_n.astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = self.a_cor / n
            sd = np.sqrt(np.maximum(self.a_cor2 / n - mean**2, 0.0))
            return {"centre": 0.5 * (self.angle_edges[1:] + self.angle_edges[:-1]), "n": self.a_n,
                    "cor_n": mean, "cor_n_sd": sd, "cor_t": self.a_cort / self.a_nt.astype(float),
                    "W": self.a_W / n, "W_n": self.a_Wn / n, "W_t": self.a_Wt / n, "fraction": self.a_frac / n}
