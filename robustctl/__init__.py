"""robustctl: a workbench for robust control of flexible structures.

``import robustctl as rc`` gives the whole public API, flat.
"""

from . import examples
from .errors import DataError, FitError, ModelError, RobustctlError, SynthesisError
from .frd import FrequencyData
from .lti import freqresp
from .physical import Parameter, PhysicalModel, Stage, StructuralMatrices, Structure

__version__ = "0.1.0"

__all__ = [
    "examples",
    "RobustctlError",
    "DataError",
    "ModelError",
    "FitError",
    "SynthesisError",
    "FrequencyData",
    "freqresp",
    "Parameter",
    "PhysicalModel",
    "Stage",
    "StructuralMatrices",
    "Structure",
]
