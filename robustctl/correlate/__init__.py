"""robustctl.correlate: where the model fails (compare), why (diagnose), fix it (update).

One import line per module, so each stage can be added independently.
"""

from .comparison import Comparison, compare
from .diagnosis import CandidateResult, Diagnosis, diagnose
from .optimize import LMResult, levenberg_marquardt
from .residual import Residual, Sensitivities, alignment, log_ratio, orthogonality, sensitivities
from .updating import UpdateResult, update
from .verification import Verification, verify

__all__ = [
    "Residual",
    "Sensitivities",
    "sensitivities",
    "alignment",
    "orthogonality",
    "log_ratio",
    "LMResult",
    "levenberg_marquardt",
    "Comparison",
    "compare",
    "update",
    "UpdateResult",
    "verify",
    "Verification",
    "diagnose",
    "Diagnosis",
    "CandidateResult",
]
