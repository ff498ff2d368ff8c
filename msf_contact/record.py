"""The impact record of spec section 8: one per finished contact, from the
reference solver or an engine, in one format."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

#: Keys the command line promises in ``msf-contact impact --json`` (issue 2).
CONTRACT_KEYS = (
    "cor_n", "cor_t", "tau", "tau1", "tau2", "x_max", "F_max", "Pc_max",
    "W_diss_n", "W_diss_t", "spin_out", "omega_x",
)


@dataclass
class ImpactRecord:
    """One impact. SI units; None where a quantity does not apply (e.g. cor_t
    of a normal impact), never NaN.

    cor_n: normal COR v_n,out / v_n,in [-].
    cor_t: tangential COR of the centre of mass, v_t,out / v_t,in [-] (paper's V_ty/V_0y).
    cor_t_contact: tangential COR of the contact point, -u_out/u_in [-] (DEM convention).
    cor_tau_ratio: k_x as tau1/tau2, (62) [-].
    tau, tau1, tau2: contact, compression and restitution durations [s].
    x_max: maximum approach [m]. F_max: peak normal force [N].
    Pc_max: peak contact pressure (20) at maximum approach [Pa] ((42) diverges
        as x -> 0+ with x' > 0, so the peak over time is not finite).
    Pc_at_Fmax: (20) at the instant of peak force [Pa].
    W_el_comp, W_visc_comp, W_el_rest, W_visc_rest: works of the elastic and
        viscous normal forces in compression and restitution, (53)-(56) [J].
    W_diss_n: normal kinetic energy lost [J]. W_diss_t: tangential and
        rotational kinetic energy lost [J]. Q_t: work of the tangential viscous
        force (80) [J].
    spin_in, spin_out: body 1's angular velocity about the axis that makes
        rolling in the direction of incidence positive [rad/s].
    f_min, f_max: extremes of f = |F_t|/F_n (4) while F_n >= 1% of F_max [-].
    omega_x, omega_y: the collision frequencies used (46) [rad/s].
    ended_by: "force-zero", "overlap-zero" or "capture".
    outside_validity: reasons the impact left the model's validity, one
        sentence each (empty if none): x_max/R above the small-strain bound,
        x_max at 2R, |F_t|/F_n above the friction cap, energy gained (paper
        mode, or a push from outside the contact in an engine), a non-finite
        result; from the engines also a body turning more than pi/4 per step
        whose contact depends on its orientation, and a held link the step
        does not resolve (a stiff servo, a constraint over too few steps;
        docs/engines.md, known limits).
    law, parameters: the law and all its parameters. engine, dt: what produced it.
    inputs: the impact's inputs (speeds, angle, spin, bodies).
    """

    cor_n: float
    cor_t: float | None
    cor_t_contact: float | None
    cor_tau_ratio: float
    tau: float
    tau1: float
    tau2: float
    x_max: float
    F_max: float
    Pc_max: float
    Pc_at_Fmax: float
    W_el_comp: float
    W_visc_comp: float
    W_el_rest: float
    W_visc_rest: float
    W_diss_n: float
    W_diss_t: float
    Q_t: float
    spin_in: float
    spin_out: float
    f_min: float | None
    f_max: float | None
    omega_x: float | None
    omega_y: float | None
    ended_by: str
    law: str
    engine: str
    dt: float | None
    parameters: dict[str, Any] = field(default_factory=dict)
    inputs: dict[str, Any] = field(default_factory=dict)
    outside_validity: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """The record as plain JSON-able values. JSON has no NaN or inf: they
        become None, and none is dropped silently. Infinities in ``inputs``
        and ``parameters`` are a rigid body's modulus or a half-space's radius
        and mass (null there means inf). Any NaN, and any non-finite result,
        is named in ``non_finite`` (dotted paths) and in ``outside_validity``."""
        d = asdict(self)
        found: list[tuple[str, float]] = []
        out = _clean(d, "", found)
        bad = [(path, v) for path, v in found
               if math.isnan(v) or path.split(".")[0] not in ("inputs", "parameters")]
        if bad:
            out["non_finite"] = [path for path, _ in bad]
            out["outside_validity"] = list(out["outside_validity"]) + [
                f"{path} is not finite ({v!r}): a numerical failure, written as null" for path, v in bad]
        return out

    def to_json(self, **kw) -> str:
        return json.dumps(self.to_dict(), **kw)


def _clean(v, path: str = "", found: list | None = None):
    """Replace non-finite floats by None (JSON has no NaN/inf) recursively;
    each one replaced is appended to ``found`` as (dotted path, value)."""
    if isinstance(v, dict):
        return {k: _clean(x, f"{path}.{k}" if path else str(k), found) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_clean(x, f"{path}[{i}]", found) for i, x in enumerate(v)]
    if isinstance(v, float) and not math.isfinite(v):
        if found is not None:
            found.append((path, v))
        return None
    if hasattr(v, "item") and callable(v.item):  # numpy scalar
        return _clean(v.item(), path, found)
    return v
