"""Controller order reduction that looks at the loop.

Holds
    ``controller`` -- ``rc.reduce_controller``: frequency-weighted balanced truncation with
                      closed-loop weights (Enns 1984; Zhou, Doyle & Glover 1996, ch. 7) and
                      coprime-factor reduction of unstable controllers (Zhou, Doyle & Glover 1996,
                      ch. 19).

May import
    ``robust.analysis`` (coprime factors, stability margin), ``robust.hinf`` and everything they
    may import.
"""

from .controller import (
    ControllerReduction,
    coprime_reduction,
    reduce_controller,
    weighted_balanced_truncation,
)

__all__ = ["ControllerReduction", "coprime_reduction", "reduce_controller", "weighted_balanced_truncation"]
