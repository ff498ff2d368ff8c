"""Materials and the effective parameters of a pair, paper sections 2.1 and 6.

A :class:`Material` carries the dynamic (storage) modulus E' [Pa], the loss
factor tg(beta) = E''/E' [-] (48), the Poisson ratio and the density. Shear
moduli default to G = E / (2 (1 + nu)) with the same loss factor (spec 1).
A rigid body has infinite E' and E'' (it neither deforms nor dissipates).

Frequency/temperature dependence (paper section 6): a :class:`PronySeries`
or a :class:`TabulatedMasterCurve` at a reference temperature, with a
:class:`WLF` shift log10 a_T = -C1 (T - Tref) / (C2 + T - Tref).
``Material.at(omega, T)`` returns the material evaluated at that angular
frequency and temperature.

:class:`ContactPair` combines two materials by the series rules (9), (91)
and the deformation split (10); the optional ``"hertz"`` convention uses
E* = [(1-nu1^2)/E1 + (1-nu2^2)/E2]^-1 instead of (9).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ._validate import (DENSITY_MAX, DENSITY_MIN, E_MAX, E_MIN, check_between, check_choice, check_finite,
                        check_positive, check_range, check_tan_delta)

MODULUS_CONVENTIONS = ("msf", "hertz")


# --------------------------------------------------------------------------
# Frequency / temperature dependence (paper section 6)
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class WLF:
    """Williams-Landel-Ferry shift: log10 a_T = -C1 (T - Tref)/(C2 + T - Tref).

    Temperatures in kelvin (or any scale, consistently); C2 in the same unit.
    """

    C1: float
    C2: float
    T_ref: float

    def __post_init__(self):
        check_positive("WLF.C1", self.C1)
        check_positive("WLF.C2", self.C2)
        check_finite("WLF.T_ref", self.T_ref)

    def log10_aT(self, T: float) -> float:
        dT = float(T) - self.T_ref
        if self.C2 + dT <= 0:
            raise ValueError(
                f"temperature T = {T!r} is below the WLF singularity T_ref - C2 = {self.T_ref - self.C2:g}"
            )
        return -self.C1 * dT / (self.C2 + dT)


@dataclass(frozen=True)
class PronySeries:
    """Generalised Maxwell (Prony) master curve at the reference temperature.

    E'(w)  = E_inf + sum_i E_i (w tau_i)^2 / (1 + (w tau_i)^2)
    E''(w) =         sum_i E_i (w tau_i)   / (1 + (w tau_i)^2)

    E_inf [Pa], E_i [Pa] (k,), tau_i [s] (k,).
    """

    E_inf: float
    E_i: tuple[float, ...]
    tau_i: tuple[float, ...]

    def __post_init__(self):
        check_positive("PronySeries.E_inf", self.E_inf)
        if len(self.E_i) != len(self.tau_i) or len(self.E_i) == 0:
            raise ValueError(
                f"PronySeries needs as many E_i as tau_i (>= 1), got {len(self.E_i)} and {len(self.tau_i)}"
            )
        check_positive("PronySeries.E_i", self.E_i)
        check_positive("PronySeries.tau_i", self.tau_i)

    def moduli(self, omega: float) -> tuple[float, float]:
        wt = omega * np.asarray(self.tau_i)
        Ei = np.asarray(self.E_i)
        storage = self.E_inf + float(np.sum(Ei * wt**2 / (1 + wt**2)))
        loss = float(np.sum(Ei * wt / (1 + wt**2)))
        return storage, loss


@dataclass(frozen=True)
class TabulatedMasterCurve:
    """E'(w), E''(w) tabulated against angular frequency [rad/s] at T_ref.

    Interpolated linearly in log-log; outside the table the end values hold
    (a flagged extrapolation would be a guess about the material).
    """

    omega: tuple[float, ...]
    storage: tuple[float, ...]
    loss: tuple[float, ...]

    def __post_init__(self):
        n = len(self.omega)
        if n < 2 or len(self.storage) != n or len(self.loss) != n:
            raise ValueError("TabulatedMasterCurve needs >= 2 rows of equal length (omega, storage, loss)")
        check_positive("TabulatedMasterCurve.omega", self.omega)
        check_positive("TabulatedMasterCurve.storage", self.storage)
        check_positive("TabulatedMasterCurve.loss", self.loss)
        if np.any(np.diff(self.omega) <= 0):
            raise ValueError("TabulatedMasterCurve.omega must increase strictly")

    def moduli(self, omega: float) -> tuple[float, float]:
        lw = np.log(np.asarray(self.omega))
        x = math.log(omega)
        s = math.exp(np.interp(x, lw, np.log(self.storage)))
        l_ = math.exp(np.interp(x, lw, np.log(self.loss)))
        return s, l_


# --------------------------------------------------------------------------
# Material
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class Material:
    """One body's material.

    Attributes
    ----------
    name: label.
    E_storage: dynamic (storage) modulus E' [Pa]; ``math.inf`` for a rigid body.
    tan_delta: loss factor tg(beta) = E''/E' [-], (48).
    nu: Poisson ratio [-], in (-1, 0.5).
    density: [kg/m^3].
    G_storage: shear storage modulus G' [Pa]; default E'/(2(1+nu)).
    source: where the numbers come from, or "illustrative".
    master_curve: optional PronySeries or TabulatedMasterCurve; when set,
        E_storage/tan_delta are its values at ``omega_ref``.
    wlf: optional WLF shift for the master curve.
    """

    name: str
    E_storage: float
    tan_delta: float
    nu: float
    density: float
    G_storage: float | None = None
    source: str = "illustrative"
    master_curve: PronySeries | TabulatedMasterCurve | None = field(default=None, compare=False)
    wlf: WLF | None = field(default=None, compare=False)

    def __post_init__(self):
        check_positive(f"{self.name}.E_storage", self.E_storage, allow_inf=True, unit="Pa")
        if not math.isinf(self.E_storage):
            check_between(f"{self.name}.E_storage", self.E_storage, E_MIN, E_MAX, "Pa",
                          "bounds of plausibility, msf_contact._validate.E_MIN/E_MAX; inf is a rigid body")
        check_finite(f"{self.name}.tan_delta", self.tan_delta)
        if self.tan_delta < 0:
            raise ValueError(f"{self.name}.tan_delta = {self.tan_delta!r} must be >= 0")
        check_range(f"{self.name}.nu", self.nu, -1.0, 0.5, lo_open=True, hi_open=True)
        check_positive(f"{self.name}.density", self.density, allow_inf=True, unit="kg/m^3")
        if not math.isinf(self.density):
            check_between(f"{self.name}.density", self.density, DENSITY_MIN, DENSITY_MAX, "kg/m^3",
                          "bounds of plausibility, msf_contact._validate.DENSITY_MIN/MAX")
        if self.G_storage is not None:
            check_positive(f"{self.name}.G_storage", self.G_storage, allow_inf=True, unit="Pa")

    # -- derived moduli ----------------------------------------------------
    @property
    def rigid(self) -> bool:
        return math.isinf(self.E_storage)

    @property
    def E_loss(self) -> float:
        """Loss modulus E'' = tg(beta) E' [Pa], (48); infinite for a rigid body."""
        return math.inf if self.rigid else self.tan_delta * self.E_storage

    @property
    def G(self) -> float:
        """Shear storage modulus G' [Pa]."""
        if self.G_storage is not None:
            return self.G_storage
        return math.inf if self.rigid else self.E_storage / (2.0 * (1.0 + self.nu))

    @property
    def G_loss(self) -> float:
        """Shear loss modulus G'' = tg(beta) G' [Pa], (48)."""
        return math.inf if math.isinf(self.G) else self.tan_delta * self.G

    def at(self, omega: float, temperature: float | None = None) -> "Material":
        """This material at angular frequency ``omega`` [rad/s] (and temperature).

        Without a master curve the material is frequency-independent and is
        returned unchanged.
        """
        if self.master_curve is None:
            return self
        check_positive("omega", omega, unit="rad/s")
        w = float(omega)
        if temperature is not None:
            if self.wlf is None:
                raise ValueError(f"material {self.name!r} has no WLF shift; temperature cannot be applied")
            w = w * 10.0 ** self.wlf.log10_aT(temperature)
        storage, loss = self.master_curve.moduli(w)
        G = storage / (2.0 * (1.0 + self.nu))
        return replace(self, E_storage=storage, tan_delta=loss / storage, G_storage=G)

    @staticmethod
    def rigid_body(name: str = "rigid") -> "Material":
        """A body that neither deforms nor dissipates (E' = E'' = inf)."""
        return Material(name, math.inf, 0.0, 0.3, math.inf, source="idealisation")


def rigid() -> Material:
    return Material.rigid_body()


# --------------------------------------------------------------------------
# Presets. Elastic constants are handbook values; loss factors of metals and
# glass are small and spread widely in the literature, marked illustrative.
# --------------------------------------------------------------------------
_PRESETS: dict[str, Material] = {
    m.name: m
    for m in (
        Material("steel", 210e9, 1e-3, 0.30, 7850.0,
                 source="E, nu, density: handbook values for carbon steel; loss factor illustrative"),
        Material("aluminium", 70e9, 1e-3, 0.33, 2700.0,
                 source="E, nu, density: Chung & Ooi 2011 (aluminium alloy); loss factor illustrative"),
        Material("magnesium", 40e9, 1e-3, 0.35, 1800.0,
                 source="E, nu, density: Chung & Ooi 2011 (magnesium alloy); loss factor illustrative"),
        Material("alumina", 380e9, 1e-3, 0.23, 4000.0,
                 source="E, nu, density: handbook values for Al2O3; loss factor illustrative"),
        Material("glass", 63e9, 2e-3, 0.23, 2500.0,
                 source="E, nu, density: soda-lime glass handbook values; loss factor illustrative"),
        Material("natural-rubber", 5e6, 0.10, 0.49, 930.0,
                 source="illustrative dynamic values for a filled natural rubber at ~1 kHz"),
        Material("polyurethane", 30e6, 0.12, 0.48, 1200.0,
                 source="illustrative dynamic values for a cast polyurethane coating at ~1 kHz"),
        Material("ptfe", 0.5e9, 0.08, 0.46, 2200.0,
                 source="E, nu, density: handbook values for PTFE; loss factor illustrative"),
        Material("golf-core", 60e6, 0.09, 0.49, 1130.0,
                 source="illustrative polybutadiene golf-ball core"),
    )
}


def _nbr_stewart_anand_2024() -> Material:
    """Nitrile rubber (NBR), a published five-term Prony series (linear limit).

    Source, exactly what was taken: E. M. Stewart and L. Anand, "A large
    deformation viscoelasticity theory for elastomeric materials and its
    numerical implementation in the open-source finite element program
    FEniCSx", Int. J. Solids Struct. 303 (2024) 113023,
    doi:10.1016/j.ijsolstr.2024.113023; their NBR parameter set ("from
    Linder et al. (2011) for NBR": C. Linder, M. Tkachuk, C. Miehe, J. Mech.
    Phys. Solids 59 (2011) 2134) as printed in the authors' published code,
    github.com/ericstewart36/finite_viscoelasticity, notebook
    FV10_NBR_beam_impulse_oscillation.ipynb (commit be678d6): equilibrium
    shear modulus G_eq = 400 kPa (Arruda-Boyce, locking stretch 10; its
    small-strain factor 1.006 is dropped), non-equilibrium branches
    G_i = 535.7, 76.20, 120.5, 21.3, 22.9 kPa with tau_i = 1e-3, 10, 100,
    1e3, 1e4 s, bulk modulus K = 1000 G_eq, density 1.3e-6 kg/mm^3. The
    paper's table itself was not reachable; the authors' quasi-static
    examples (FV08, FV09) use tau_1 = 1 s instead of 1e-3 s, their dynamic
    ones (FV10, FV11) 1e-3 s, which is taken here. No reference temperature
    or WLF constants are given (isothermal, room temperature).

    Linear limit: nu = (3K - 2G)/(2(3K + G)) with K/G = 1000, and
    E = 2 (1 + nu) G for every branch. E_storage, tan_delta: the series at
    omega = 2 pi 100 Hz, the scale of a 20 mm ball's impact.
    """
    nu = (3 * 1000 - 2) / (2 * (3 * 1000 + 1))
    to_E = 2 * (1 + nu) * 1e3  # kPa of shear -> Pa of Young's modulus
    curve = PronySeries(E_inf=400.0 * to_E, E_i=tuple(g * to_E for g in (535.7, 76.20, 120.5, 21.3, 22.9)),
                        tau_i=(1e-3, 10.0, 100.0, 1e3, 1e4))
    storage, loss = curve.moduli(2 * math.pi * 100.0)
    return Material("nbr", storage, loss / storage, nu, 1300.0, master_curve=curve,
                    source="Stewart & Anand 2024, IJSS 303:113023 (NBR set after Linder et al. 2011), "
                           "via the authors' code FV10_NBR_beam_impulse_oscillation.ipynb; linear limit, "
                           "E', tan delta at 100 Hz")


_PRESETS["nbr"] = _nbr_stewart_anand_2024()


def preset(name: str) -> Material:
    """A preset material by name; the error lists the valid names."""
    key = name.strip().lower()
    if key in ("rigid", "rigid-plate"):
        return Material.rigid_body()
    try:
        return _PRESETS[key]
    except KeyError:
        raise ValueError(
            f"unknown material {name!r}; valid names: {', '.join(sorted(_PRESETS) + ['rigid'])}"
        ) from None


def preset_names() -> list[str]:
    return sorted(_PRESETS) + ["rigid"]


# --------------------------------------------------------------------------
# A pair: effective parameters (9), (10), (91)
# --------------------------------------------------------------------------
def series(a: float, b: float) -> float:
    """Series combination a b / (a + b) of (9), with inf meaning 'the other'
    and 0 + 0 meaning 0."""
    if math.isinf(a):
        return b
    if math.isinf(b):
        return a
    if a + b == 0.0:
        return 0.0
    return a * b / (a + b)


@dataclass(frozen=True)
class EffectiveModuli:
    """Effective moduli of a pair [Pa] and deformation coefficients [-]."""

    E: float  #: E' of (9) (or E* with the hertz convention) [Pa]
    E_loss: float  #: E'' of (91) [Pa]
    G: float  #: G' of (9) [Pa]
    G_loss: float  #: G'' [Pa]
    D1: float  #: deformation share of the softer body, (10)
    D2: float  #: deformation share of the harder body, (10)

    @property
    def tan_delta(self) -> float:
        """tg(beta) = E''/E', (91)."""
        return self.E_loss / self.E


@dataclass(frozen=True)
class ContactPair:
    """Two materials in contact. ``body1``/``body2`` are the roles in the
    caller's scene (e.g. ball, plate); softer/harder (paper's 1/2) is decided
    by E'.
    """

    body1: Material
    body2: Material
    convention: str = "msf"

    def __post_init__(self):
        check_choice("modulus convention", self.convention, MODULUS_CONVENTIONS)
        if self.body1.rigid and self.body2.rigid:
            raise ValueError("both bodies are rigid: at least one must have a finite E_storage")

    def at(self, omega: float, temperature: float | None = None) -> "ContactPair":
        return replace(self, body1=self.body1.at(omega, temperature), body2=self.body2.at(omega, temperature))

    @property
    def frequency_dependent(self) -> bool:
        return self.body1.master_curve is not None or self.body2.master_curve is not None

    @property
    def body1_is_softer(self) -> bool:
        return self.body1.E_storage <= self.body2.E_storage

    def moduli(self) -> EffectiveModuli:
        b1, b2 = self.body1, self.body2
        E1, E2 = b1.E_storage, b2.E_storage
        if self.convention == "hertz":
            inv = sum(0.0 if m.rigid else (1 - m.nu**2) / m.E_storage for m in (b1, b2))
            E = 1.0 / inv
        else:
            E = series(E1, E2)  # (9)
        E_loss = series(b1.E_loss, b2.E_loss)  # (91)
        if self.convention == "hertz":
            E_loss = E_loss * E / series(E1, E2)  # same tg(beta) as (91)
        G = series(b1.G, b2.G)
        G_loss = series(b1.G_loss, b2.G_loss)
        # (10): D_soft = E'_hard/(E'_1+E'_2), D_hard = E'_soft/(E'_1+E'_2)
        soft, hard = (E1, E2) if E1 <= E2 else (E2, E1)
        if math.isinf(hard):
            D1, D2 = 1.0, 0.0
        else:
            D1, D2 = hard / (soft + hard), soft / (soft + hard)
        return EffectiveModuli(E=E, E_loss=E_loss, G=G, G_loss=G_loss, D1=D1, D2=D2)

    def check_validity(self, strict: bool = False) -> None:
        """Warn (or, strict, raise) when tg(beta) of the pair exceeds 1/3 (100)."""
        check_tan_delta("tan_delta (effective, (91))", self.moduli().tan_delta, strict=strict)

    def sound_speed(self) -> float:
        """Smallest longitudinal bar-wave speed sqrt(E'/rho) of the two bodies [m/s];
        the paper requires impact speeds below it (section 1)."""
        speeds = [math.sqrt(m.E_storage / m.density) for m in (self.body1, self.body2) if not m.rigid]
        return min(speeds)
