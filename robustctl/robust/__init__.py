"""robustctl.robust (see DESIGN.md)."""

# --- mu analysis (mu helper) ---
from .blocks import Block, BlockStructure, as_block_structure
from .mu import MuResult, mu
from .mu_analysis import WorstCaseGain, robust_performance, robust_stability, worst_case_gain

__all__ = [
    # --- mu analysis (mu helper) ---
    "Block",
    "BlockStructure",
    "as_block_structure",
    "mu",
    "MuResult",
    "robust_stability",
    "robust_performance",
    "worst_case_gain",
    "WorstCaseGain",
]
