"""robustctl.identify: measurement models from frequency-response data.

Rational fits with one common denominator (Chebyshev/Sanathanan-Koerner as in the Caltech
paper, or relaxed vector fitting), conversion to real modal state space, the Caltech
SIMO-to-MIMO combination and SVD grouping of modes, balanced truncation with its error bound,
and the one-call measurement model scored by the complex-log cost (MACE eq. 5).
"""

from .cost import LogCost, log_cost
from .grouping import cluster_modes, combine_simo, group_modes
from .rational import IdentifyWarning, RationalFit, fit_rational

__all__ = [
    "fit_rational",
    "RationalFit",
    "IdentifyWarning",
    "combine_simo",
    "group_modes",
    "cluster_modes",
    "LogCost",
    "log_cost",
]
