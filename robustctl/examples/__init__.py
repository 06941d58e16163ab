"""Embedded example structures (see DESIGN.md): the seeds' test articles as physical models.

* :func:`caltech_truss` -- the Caltech two-story hanging truss (Balas & Doyle): three
  voice coils in, three accelerometers out.
* :func:`mace_beam` -- a MACE-like suspended bus (Glaese & Miller) with gimbals, reaction
  wheels, servo loops and electronics; ``.without("suspension", "gravity")`` is its 0-g model.
* :func:`make_experiment`, :func:`caltech_truss_experiment`, :func:`mace_beam_experiment` --
  truth generators: simulated test data of a model with a hidden physical effect and
  parameter errors.
* :func:`modal_test_case`, :func:`impact_test_case` -- synthetic modal tests at the size of
  real ones (many channels and modes, close pairs; shaker FRF or hammer hits).
* :func:`caltech_additive_weight` -- the seed's additive weight (eq. 14);
  :func:`caltech_truss_weights` -- weights computed from the truss's residuals beside it.
* :func:`distillation_plant`, :func:`caltech_design_plant` -- mu-synthesis examples
  (Skogestad & Postlethwaite's D-K example; the Caltech seed's design plant);
  :func:`two_mass_spring_plant` -- Wie & Bernstein's benchmark with the spring as a real block;
  :class:`ModelCoverRecipe` -- the yardstick's recipe in which each model pays for its error.
"""

from .caltech_truss_model import caltech_truss, truss_modes
from .caltech_weights import CaltechWeights, caltech_additive_weight, caltech_truss_weights
from .experiments import caltech_truss_experiment, mace_beam_experiment, make_experiment
from .mace_beam_model import mace_beam, mace_modes
from .modal_test import ModalTruth, impact_test_case, modal_test_case
from .robust_design import (
    DISTILLATION_BLOCKS,
    TWO_MASS_BLOCKS,
    ModelCoverRecipe,
    ParametricComparison,
    caltech_design_plant,
    caltech_parametric_plants,
    distillation_plant,
    himat_plant,
    performance_scale,
    six_modes,
    two_mass_spring_plant,
)

__all__ = ["caltech_truss", "truss_modes", "mace_beam", "mace_modes"]
__all__ += ["make_experiment", "caltech_truss_experiment", "mace_beam_experiment"]
__all__ += ["modal_test_case", "impact_test_case", "ModalTruth"]
__all__ += ["caltech_additive_weight", "caltech_truss_weights", "CaltechWeights"]
__all__ += ["distillation_plant", "DISTILLATION_BLOCKS", "caltech_design_plant", "six_modes"]
__all__ += ["ModelCoverRecipe"]
__all__ += ["two_mass_spring_plant", "TWO_MASS_BLOCKS", "himat_plant"]
__all__ += ["caltech_parametric_plants", "ParametricComparison", "performance_scale"]
