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
    ``elements``    -- uncertain real parameters, complex scalars and unmodelled dynamics
                       (MATLAB ``ureal``/``ucomplex``/``ultidyn``).
    ``lft_algebra`` -- the LFT interconnection rule (Zhou, Doyle & Glover 1996, sec. 10.2) and the
                       structured Kalman reduction of repeated blocks (Beck & Doyle 1999).
    ``system``      -- :class:`UncertainSystem`: arithmetic, LFT, sampling, substitution, response.
    ``parametric``  -- the update's parameters and a physical model as uncertain systems.

May import
    The floors below ``robust`` (``errors`` ... ``identify``) and nothing else of ``robust``:
    it is the lowest floor of ``robust/`` (see ``ROBUST_FLOORS`` in ``tests/test_architecture.py``).
"""

from .blocks import Block, BlockStructure, as_block_structure
from .cover import UncertaintyCover, cover_additive, cover_multiplicative, cover_remainder, error_envelope
from .elements import UncertainComplex, UncertainDynamics, UncertainReal, ucomplex, ultidyn, ureal
from .magfit import MagnitudeFit, fit_magnitude, fit_magnitude_details
from .parametric import LFTAccuracyWarning, from_uncertain_model, physical_uncertain, uncertain_parameters
from .system import LFTData, UncertainSystem, append, as_uncertain, hstack, vstack
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
    "ureal",
    "ucomplex",
    "ultidyn",
    "UncertainReal",
    "UncertainComplex",
    "UncertainDynamics",
    "UncertainSystem",
    "LFTData",
    "as_uncertain",
    "append",
    "hstack",
    "vstack",
    "uncertain_parameters",
    "physical_uncertain",
    "from_uncertain_model",
    "LFTAccuracyWarning",
]
