"""Physical models: frame FEM, modal state space, electronics, PhysicalModel."""

from . import electronics
from .builders import frame_model, modal_model, structural_model
from .fem import Frame
from .gravity import PreloadResult
from .matrices import MatrixStructure
from .modal import ModalData, modal_decomposition, modal_dynamics, modal_statespace
from .model import PhysicalModel, Stage
from .parameters import Parameter
from .structure_base import StructuralMatrices, Structure

__all__ = ["Frame", "PreloadResult", "PhysicalModel", "Stage", "Parameter", "StructuralMatrices", "Structure"]
__all__ += [
    "electronics",
    "frame_model",
    "structural_model",
    "modal_model",
    "MatrixStructure",
    "ModalData",
    "modal_decomposition",
    "modal_dynamics",
    "modal_statespace",
]
