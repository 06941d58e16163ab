"""robustctl.robust.uncertainty: uncertain elements and systems, their LFTs and robust analysis.

Modules: :mod:`.elements` (``ureal``, ``ucomplex``, ``ultidyn``), :mod:`.lft_algebra` (the
LFT interconnection rule, Zhou, Doyle & Glover 1996 sec. 10.2, and the structured Kalman
reduction of Beck & Doyle 1999), :mod:`.system` (``UncertainSystem``: arithmetic, LFT,
sampling, substitution, frequency response), :mod:`.robust_margin` (robust-stability margin
and worst-case gain of an uncertain system by mixed mu, Packard & Doyle 1993, Young & Doyle
1997). Imports: the robust stage's block structures and mu bounds, and the floors below.
"""

from .elements import UncertainComplex, UncertainDynamics, UncertainReal, ucomplex, ultidyn, ureal
from .parametric import LFTAccuracyWarning, from_uncertain_model, physical_uncertain, uncertain_parameters
from .robust_margin import RobustStabilityMargin, WorstCaseResult, destabilizing_system, robstab, wcgain
from .system import LFTData, UncertainSystem, append, as_uncertain, hstack, vstack

__all__ = [
    "ureal",
    "ucomplex",
    "ultidyn",
    "UncertainReal",
    "UncertainComplex",
    "UncertainDynamics",
    "UncertainSystem",
    "LFTData",
    "as_uncertain",
    "append",
    "hstack",
    "vstack",
    "robstab",
    "RobustStabilityMargin",
    "wcgain",
    "WorstCaseResult",
    "destabilizing_system",
    "uncertain_parameters",
    "physical_uncertain",
    "from_uncertain_model",
    "LFTAccuracyWarning",
]
