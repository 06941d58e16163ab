"""robustctl.robust (see DESIGN.md)."""

# H-infinity norm and synthesis (hinf helper)
from .hinfnorm import hinfnorm
from .hinfsyn import HinfResult, hinfsyn

__all__ = [
    # H-infinity norm and synthesis
    "hinfnorm",
    "hinfsyn",
    "HinfResult",
]
