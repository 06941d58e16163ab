"""robustctl.robust: the design half -- uncertainty, the generalized plant, synthesis, analysis.

Floors inside ``robust/`` (lowest first; a module imports from its own floor without a
circle and from the floors below, never up; ``tests/test_architecture.py`` checks it):

0. ``uncertainty/`` -- block structures, weights, magnitude fits, covers, uncertain elements and
   systems; ``conventions`` -- the one loop sign of synthesis, analysis and margins
1. ``plant``, ``partitioned``, ``sampled`` -- the generalized plant, its one coercion, its
   sampled-data form; ``continuous_equivalent`` -- d2c; ``mu/`` -- structured singular value
   bounds and analyses
2. ``hinf/`` -- H-infinity norm and synthesis (Riccati, LMI), assumptions
3. ``h2/`` -- H2 norm and synthesis, LQG
4. ``analysis/`` -- disk margins, nu-gap, coprime factors, loop shaping, robust-stability margin
   and worst-case gain of uncertain systems
5. ``reduction/`` -- controller reduction
6. ``dk/`` -- D-K and D-G-K iteration, design sweeps
7. ``yardsticks`` -- controllers designed on several models scored on the data

Each sub-package's docstring says what it holds, what it may import and which book
equations its modules implement. The public names are re-exported here and by ``robustctl``;
``robustctl.mu`` is the function, ``robustctl.robust.mu`` the sub-package.
"""

from ..lti import zpk_statespace
from . import analysis as analysis
from . import dk as dk
from . import h2 as h2
from . import hinf as hinf
from . import mu as mu
from . import reduction as reduction
from . import uncertainty as uncertainty
from .analysis import (
    DiskMargin as DiskMargin,
)
from .analysis import (
    DiskMarginResult as DiskMarginResult,
)
from .analysis import (
    LoopShapingResult as LoopShapingResult,
)
from .analysis import (
    disk_gain_phase as disk_gain_phase,
)
from .analysis import (
    diskmargin as diskmargin,
)
from .analysis import (
    ncfsyn as ncfsyn,
)
from .analysis import (
    nugap as nugap,
)
from .analysis import (
    stability_margin as stability_margin,
)
from .dk import DesignReduction, DesignSweep, DKIteration, DKResult, Reduction, design_sweep, dksyn
from .h2 import H2Result as H2Result
from .h2 import LQGResult as LQGResult
from .h2 import h2norm as h2norm
from .h2 import h2syn as h2syn
from .h2 import lqg as lqg
from .hinf import HinfResult, hinfnorm, hinfsyn
from .mu import MuResult, WorstCaseGain, robust_performance, robust_stability, worst_case_gain
from .plant import GeneralizedPlant, PlantWeight, generalized_plant, mixed_sensitivity
from .reduction import ControllerReduction, coprime_reduction, weighted_balanced_truncation
from .reduction import reduce_controller as reduce_controller
from .sampled import sampled_plant as sampled_plant
from .uncertainty import (
    CALTECH_MULTIPLICATIVE,
    Block,
    BlockStructure,
    MagnitudeFit,
    UncertaintyCover,
    as_block_structure,
    caltech_additive_weight,
    cover_additive,
    cover_multiplicative,
    cover_remainder,
    error_envelope,
    fit_magnitude,
    fit_magnitude_details,
    makeweight,
)
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
