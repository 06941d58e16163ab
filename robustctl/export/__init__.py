"""Discretise a controller and export it as coefficient files for a real-time computer.

:func:`discretize` maps a continuous controller ``K(s)`` to a sampled ``K_d(z)`` (Tustin with
optional prewarping, or the exact zero-order-hold equivalent); :func:`export_controller`
discretises, checks (stability of ``K_d``, discretisation error at the crossover, coefficient
dynamic range) and writes JSON, CSV, a C header, a MATLAB ``.mat`` or second-order sections;
:func:`load_controller` reads any of them back.

Modules: ``discretize`` (the maps s -> z), ``realization`` (pole radius, coefficient dynamic
range, balancing, second-order sections), ``files`` (the file layouts), ``report``
(:class:`ExportReport`), ``controller`` (export and load).
"""

from .controller import export_controller, load_controller
from .realization import dynamic_range
from .report import ExportReport
from .sampling import discretization_error, discretize

__all__ = [
    "discretize",
    "export_controller",
    "load_controller",
    "ExportReport",
    "discretization_error",
    "dynamic_range",
]
