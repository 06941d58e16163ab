"""Physical models: frame FEM, modal state space, electronics, PhysicalModel."""

from .model import PhysicalModel, Stage
from .parameters import Parameter
from .structure_base import StructuralMatrices, Structure

__all__ = ["PhysicalModel", "Stage", "Parameter", "StructuralMatrices", "Structure"]
