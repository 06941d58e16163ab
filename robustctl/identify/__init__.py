"""robustctl.identify: measurement models from frequency-response data.

Rational fits with one common denominator (Chebyshev/Sanathanan-Koerner as in the Caltech
paper, or relaxed vector fitting), conversion to real modal state space, the Caltech
SIMO-to-MIMO combination and SVD grouping of modes, balanced truncation with its error bound,
the estimator-leakage correction, and the one-call measurement model scored by the
complex-log cost (MACE eq. 5): spare-pole fits with mode selection by contribution (exactly
``n_modes`` modes, fillers apart), block variable-projection refinement that scales with the
channels and modes, and the automatic order from a one-pass stabilisation diagram. The
modes listed are the poles the data support (:mod:`.significance`: significance against the
noise, phase collinearity, one per peak, stability across orders); every other pole is a filler.
"""

from ..balanced import BalancedTruncation, balanced_truncation
from ..modes import Mode
from .cost import LogCost, channel_cost
from .grouping import cluster_modes, combine_simo, group_modes
from .leakage import estimator_settings, expected_h1, leakage_factor
from .measurement_model import MeasurementModel, fit_measurement_model
from .rational import fit_rational
from .rational_fit import IdentifyWarning, RationalFit
from .significance import PoleEvidence, pole_evidence
from .stabilisation import StabilisationDiagram

__all__ = [
    "fit_rational",
    "RationalFit",
    "IdentifyWarning",
    "combine_simo",
    "group_modes",
    "cluster_modes",
    "balanced_truncation",
    "BalancedTruncation",
    "fit_measurement_model",
    "MeasurementModel",
    "Mode",
    "LogCost",
    "channel_cost",
    "estimator_settings",
    "expected_h1",
    "leakage_factor",
    "StabilisationDiagram",
    "PoleEvidence",
    "pole_evidence",
]
