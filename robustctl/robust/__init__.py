"""robustctl.robust (see DESIGN.md)."""

from .blocks import Block, BlockStructure, as_block_structure
from .plant import GeneralizedPlant, PlantWeight, generalized_plant, mixed_sensitivity

__all__ = [
    "Block",
    "BlockStructure",
    "as_block_structure",
    # generalized plant (plant.py)
    "GeneralizedPlant",
    "PlantWeight",
    "generalized_plant",
    "mixed_sensitivity",
]
