"""robustctl.correlate: where the model fails (compare), why (diagnose), fix it (update).

One import line per module, so each stage can be added independently.
"""

from .comparison import Comparison as Comparison
from .comparison import compare as compare
from .diagnosis import CandidateResult
from .diagnosis import Diagnosis as Diagnosis
from .diagnosis import diagnose as diagnose
from .optimize import LMResult, levenberg_marquardt
from .residual import Residual, Sensitivities, alignment, log_ratio, orthogonality, sensitivities
from .updating import UpdateResult as UpdateResult
from .updating import update as update
from .verification import Verification as Verification
from .verification import verify as verify

#: The three stages and their results, in pipeline order (re-exported by ``robustctl``).
STAGE_NAMES = [
    "compare",
    "Comparison",
    "update",
    "UpdateResult",
    "verify",
    "Verification",
    "diagnose",
    "Diagnosis",
]

__all__ = [
    "Residual",
    "Sensitivities",
    "sensitivities",
    "alignment",
    "orthogonality",
    "log_ratio",
    "LMResult",
    "levenberg_marquardt",
    *STAGE_NAMES,
    "CandidateResult",
]
