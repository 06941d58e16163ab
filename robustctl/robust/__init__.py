"""robustctl.robust (see DESIGN.md)."""

from ..lti import zpk_statespace
from .blocks import Block, BlockStructure, as_block_structure
from .controller_reduction import (
    ControllerReduction,
    coprime_reduction,
    weighted_balanced_truncation,
)
from .controller_reduction import reduce_controller as reduce_controller

# weights (uncertainty and performance weights, magnitude fits, covers)
from .cover import UncertaintyCover, cover_additive, cover_multiplicative, cover_remainder, error_envelope

# D-K iteration and the measurement-model yardstick (dk.py, yardstick.py)
from .dk import DKIteration, DKResult, Reduction, dksyn
from .dk_plant import DesignReduction

# H2/LQG, discrete synthesis, loop shaping, margins, controller reduction (toolbox)
from .h2 import H2Result as H2Result
from .h2 import h2norm as h2norm
from .h2 import h2syn as h2syn

# H-infinity norm and synthesis (hinf helper)
from .hinf_norm import hinfnorm
from .hinf_synthesis import HinfResult, hinfsyn
from .loop_shaping import LoopShapingResult as LoopShapingResult
from .loop_shaping import ncfsyn as ncfsyn
from .loop_shaping import stability_margin as stability_margin
from .lqg_design import LQGResult as LQGResult
from .lqg_design import lqg as lqg
from .magfit import MagnitudeFit, fit_magnitude, fit_magnitude_details
from .margins import DiskMargin as DiskMargin
from .margins import DiskMarginResult as DiskMarginResult
from .margins import disk_gain_phase as disk_gain_phase
from .margins import diskmargin as diskmargin
from .margins import nugap as nugap
from .mu_analysis import WorstCaseGain, robust_performance, robust_stability, worst_case_gain

# --- mu analysis (mu helper) ---
from .mu_bounds import MuResult, mu
from .plant import GeneralizedPlant, PlantWeight, generalized_plant, mixed_sensitivity
from .sampled import sampled_plant as sampled_plant
from .sweep import DesignSweep, design_sweep
from .weights import CALTECH_MULTIPLICATIVE, caltech_additive_weight, makeweight
from .yardsticks import NyquistVerdict, Yardstick, YardstickWarning, nyquist_stability, yardstick

#: H2/LQG, discrete synthesis, loop shaping, margins and controller reduction (re-exported by
#: ``robustctl``).
TOOLBOX_NAMES = [
    "h2norm",
    "h2syn",
    "H2Result",
    "lqg",
    "LQGResult",
    "sampled_plant",
    "diskmargin",
    "disk_gain_phase",
    "DiskMargin",
    "DiskMarginResult",
    "nugap",
    "ncfsyn",
    "LoopShapingResult",
    "stability_margin",
    "reduce_controller",
]

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
    # weights
    "makeweight",
    "fit_magnitude",
    "fit_magnitude_details",
    "MagnitudeFit",
    "zpk_statespace",
    "cover_additive",
    "cover_multiplicative",
    "cover_remainder",
    "error_envelope",
    "UncertaintyCover",
    "caltech_additive_weight",
    "CALTECH_MULTIPLICATIVE",
    # H-infinity norm and synthesis
    "hinfnorm",
    "hinfsyn",
    "HinfResult",
    # D-K iteration and yardstick
    "dksyn",
    "DKResult",
    "DKIteration",
    "Reduction",
    "DesignReduction",
    "yardstick",
    "Yardstick",
    "NyquistVerdict",
    "YardstickWarning",
    "nyquist_stability",
    "design_sweep",
    "DesignSweep",
    # H2/LQG, discrete synthesis, loop shaping, margins, controller reduction
    *TOOLBOX_NAMES,
    "weighted_balanced_truncation",
    "coprime_reduction",
    "ControllerReduction",
]
