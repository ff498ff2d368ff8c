"""msf-contact: the Method of the Specific Forces (Goloshchapov 2015) contact
law, its comparison laws, closed forms and reference impact solver.

numpy and scipy only; never imports an engine. Equation numbers "(N)" are
the paper's; ``shared/spec/MSF-MODEL.md`` is the contract.
"""

from . import closed_forms
from ._validate import ValidityWarning
from .geometry import KP_MODES, ContactGeometry, Curvature
from .laws import LAWS, ForceLaw, HertzLaw, HuntCrossleyLaw, KuwabaraKonoLaw, MSFLaw, SpringDashpotLaw, get_law, make_law
from .materials import ContactPair, Material, PronySeries, TabulatedMasterCurve, WLF, preset, preset_names
from .record import CONTRACT_KEYS, ImpactRecord
from .chain import ChainResult, simulate_chain
from .solver import Body, reduced_mass, simulate_impact
from .statics import column_loads, static_overlap
from .viscoelastic import Relaxation, exact_normal_impact, viscoelastic_impact

__all__ = [
    "Body", "CONTRACT_KEYS", "ChainResult", "ContactGeometry", "ContactPair", "Curvature", "ForceLaw", "HertzLaw",
    "HuntCrossleyLaw", "ImpactRecord", "KP_MODES", "KuwabaraKonoLaw", "LAWS", "MSFLaw", "Material",
    "PronySeries", "Relaxation", "SpringDashpotLaw", "TabulatedMasterCurve", "ValidityWarning", "WLF", "closed_forms",
    "column_loads", "exact_normal_impact", "get_law", "make_law", "preset", "preset_names", "reduced_mass", "simulate_chain",
    "simulate_impact", "static_overlap", "viscoelastic_impact",
]
__version__ = "0.1.0"
