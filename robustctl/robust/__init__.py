"""robustctl.robust (see DESIGN.md)."""

# weights (uncertainty and performance weights, magnitude fits, covers)
from .cover import UncertaintyCover, cover_additive, cover_multiplicative, error_envelope
from .magfit import MagnitudeFit, fit_magnitude, fit_magnitude_details, zpk_statespace
from .weights import CALTECH_MULTIPLICATIVE, caltech_additive_weight, makeweight

__all__ = [
    # weights
    "makeweight",
    "fit_magnitude",
    "fit_magnitude_details",
    "MagnitudeFit",
    "zpk_statespace",
    "cover_additive",
    "cover_multiplicative",
    "error_envelope",
    "UncertaintyCover",
    "caltech_additive_weight",
    "CALTECH_MULTIPLICATIVE",
]
