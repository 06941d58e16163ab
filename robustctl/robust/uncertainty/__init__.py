"""Uncertainty descriptions of the design half: block structures, weights, magnitude fits, covers.

Holds
    ``blocks``  -- :class:`BlockStructure` of ``Delta = diag(Delta_1, ...)`` in ``det(I - M Delta)``
                   (Packard & Doyle 1993, Automatica 29(1), eq. 3.1).
    ``weights`` -- MATLAB's ``makeweight`` and the Caltech seed's additive weight
                   (Skogestad & Postlethwaite 2005, sec. 7.4; Zhou, Doyle & Glover 1996, sec. 9.1).
    ``magfit``  -- stable minimum-phase rational fits to a magnitude curve, log-Chebyshev
                   (Packard & Doyle 1993, sec. 9; MATLAB's ``fitmagfrd``).
    ``cover``   -- additive and multiplicative weights covering measured and modelled errors
                   (Caltech seed eqs. 1-3; MATLAB's ``ucover``).

May import
    The floors below ``robust`` (``errors`` ... ``identify``) and nothing else of ``robust``:
    it is the lowest floor of ``robust/`` (see ``ROBUST_FLOORS`` in ``tests/test_architecture.py``).
"""

from .blocks import Block, BlockStructure, as_block_structure
from .cover import UncertaintyCover, cover_additive, cover_multiplicative, cover_remainder, error_envelope
from .magfit import MagnitudeFit, fit_magnitude, fit_magnitude_details
from .weights import CALTECH_MULTIPLICATIVE, caltech_additive_weight, makeweight

__all__ = [
    "Block",
    "BlockStructure",
    "as_block_structure",
    "UncertaintyCover",
    "cover_additive",
    "cover_multiplicative",
    "cover_remainder",
    "error_envelope",
    "MagnitudeFit",
    "fit_magnitude",
    "fit_magnitude_details",
    "CALTECH_MULTIPLICATIVE",
    "caltech_additive_weight",
    "makeweight",
]
