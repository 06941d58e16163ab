"""Embedded example structures (see DESIGN.md): the seeds' test articles as physical models.

* :func:`caltech_truss` -- the Caltech two-story hanging truss (Balas & Doyle): three
  voice coils in, three accelerometers out.
* :func:`mace_beam` -- a MACE-like suspended bus (Glaese & Miller) with gimbals, reaction
  wheels, servo loops and electronics; ``.without("suspension", "gravity")`` is its 0-g model.
* :func:`make_experiment`, :func:`caltech_truss_experiment`, :func:`mace_beam_experiment` --
  truth generators: simulated test data of a model with a hidden physical effect and
  parameter errors.
* :func:`caltech_additive_weight` -- the seed's additive weight (eq. 14);
  :func:`caltech_truss_weights` -- weights computed from the truss's residuals beside it.
"""

from .caltech_truss import caltech_truss, truss_modes
from .caltech_weights import CaltechWeights, caltech_additive_weight, caltech_truss_weights
from .experiments import caltech_truss_experiment, mace_beam_experiment, make_experiment
from .mace_beam import mace_beam, mace_modes

__all__ = ["caltech_truss", "truss_modes", "mace_beam", "mace_modes"]
__all__ += ["make_experiment", "caltech_truss_experiment", "mace_beam_experiment"]
__all__ += ["caltech_additive_weight", "caltech_truss_weights", "CaltechWeights"]
