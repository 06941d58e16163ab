"""robustctl.robust (see DESIGN.md)."""

# D-K iteration and the measurement-model yardstick (dk.py, yardstick.py)
from .dk import DKIteration, DKResult, Reduction, dksyn
from .yardstick import NyquistVerdict, Yardstick, nyquist_stability, yardstick

__all__ = [
    # D-K iteration and yardstick
    "dksyn",
    "DKResult",
    "DKIteration",
    "Reduction",
    "yardstick",
    "Yardstick",
    "NyquistVerdict",
    "nyquist_stability",
]
