"""Physical models: frame FEM, modal state space, electronics, PhysicalModel."""

from .fem import Frame
from .gravity import PreloadResult
from .model import PhysicalModel, Stage
from .parameters import Parameter
from .structure_base import StructuralMatrices, Structure

__all__ = ["Frame", "PreloadResult", "PhysicalModel", "Stage", "Parameter", "StructuralMatrices", "Structure"]
