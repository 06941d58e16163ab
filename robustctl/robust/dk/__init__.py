"""mu-synthesis by D-K and D-G-K iteration, and sweeps of D-K designs.

Holds
    ``iteration``    -- ``rc.dksyn`` and :class:`DKResult`: H-infinity K steps alternating with
                        D-scale fits, ``mu <= inf_D sigma_max(D M D^-1)`` (Packard & Doyle 1993,
                        eq. 8.1; Zhou, Doyle & Glover 1996, sec. 11.3; Skogestad & Postlethwaite
                        2005, sec. 8.12.1).
    ``scales``       -- D-scale fits, their orders and fallbacks, autoscaling.
    ``dgk``          -- G-scales of mixed-mu synthesis (Fan, Tits & Doyle 1991, Thm 2.1; Young 1996).
    ``design_plant`` -- balanced truncation of large plants before synthesis (Zhou, Doyle & Glover
                        1996, Theorem 7.9).
    ``reduce``       -- controller reduction after D-K, checked by the truncated loop's mu.
    ``verify``       -- the closed loop, its frequency grids and its verified mu peak.
    ``sampled_design`` -- D-K on a sampled plant through the Tustin map, which keeps stability
                        and mu (Zhou, Doyle & Glover 1996, sec. 21.3).
    ``sweep``        -- ``rc.design_sweep``: one D-K run per weight choice over any executor.

May import
    every other sub-package of ``robust`` except ``yardsticks``, and the floors below ``robust``.
"""

from .design_plant import DesignReduction
from .iteration import DKIteration, DKResult, Reduction, dksyn
from .sweep import DesignSweep, design_sweep

__all__ = ["DesignReduction", "DKIteration", "DKResult", "Reduction", "dksyn", "DesignSweep", "design_sweep"]
