"""robustctl.robust (see DESIGN.md)."""

from .blocks import Block, BlockStructure, as_block_structure

# H-infinity norm and synthesis (hinf helper)
from .hinfnorm import hinfnorm
from .hinfsyn import HinfResult, hinfsyn

# --- mu analysis (mu helper) ---
from .mu import MuResult, mu
from .mu_analysis import WorstCaseGain, robust_performance, robust_stability, worst_case_gain
from .plant import GeneralizedPlant, PlantWeight, generalized_plant, mixed_sensitivity

__all__ = [
    "Block",
    "BlockStructure",
    "as_block_structure",
    # generalized plant (plant.py)
    "GeneralizedPlant",
    "PlantWeight",
    "generalized_plant",
    "mixed_sensitivity",
    # --- mu analysis (mu helper) ---
    "mu",
    "MuResult",
    "robust_stability",
    "robust_performance",
    "worst_case_gain",
    "WorstCaseGain",
    # H-infinity norm and synthesis
    "hinfnorm",
    "hinfsyn",
    "HinfResult",
]
