"""Embedded example structures (see DESIGN.md): the seeds' test articles as physical models.

* :func:`caltech_truss` -- the Caltech two-story hanging truss (Balas & Doyle): three
  voice coils in, three accelerometers out.
"""

from .caltech_truss import caltech_truss, truss_modes

__all__ = ["caltech_truss", "truss_modes"]
