"""The structured singular value: bounds over frequency, their bookkeeping and the usual analyses.

Holds
    ``bounds``   -- ``rc.mu``: ``mu(M) = 1 / min{||Delta|| : det(I - M Delta) = 0}``
                    (Packard & Doyle 1993, Automatica 29(1), eq. 3.1; Zhou, Doyle & Glover 1996, ch. 10).
    ``upper``    -- D- and G-scaled upper bound, batched over frequency (Fan, Tits & Doyle 1991,
                    IEEE TAC 36(1), Thm 2.1; Packard & Doyle 1993, eq. 8.5).
    ``smooth``   -- the smoothed largest eigenvalue of the scaled LMI and its exact derivatives.
    ``lmi``      -- the same bound as an LMI generalized eigenvalue problem (cvxpy + Clarabel).
    ``lower``    -- power-iteration lower bound (Packard & Doyle 1993, Thm 7.2; Young & Doyle 1997).
    ``layout``   -- where each block sits in ``M`` and ``Delta`` (Packard & Doyle 1993, eq. 8.1).
    ``result``   -- :class:`MuResult`.
    ``robust_analysis`` -- robust stability, robust performance, worst-case gain
                    (Skogestad & Postlethwaite 2005, sec. 8.8-8.10; Zhou, Doyle & Glover 1996, sec. 10.3).

May import
    ``robust.uncertainty`` and the floors below ``robust``.

The function :func:`robustctl.mu` is exported by ``robustctl`` itself; ``robustctl.robust.mu``
is this package.
"""

from .bounds import MuResult, mu
from .robust_analysis import WorstCaseGain, robust_performance, robust_stability, worst_case_gain

__all__ = ["MuResult", "mu", "WorstCaseGain", "robust_performance", "robust_stability", "worst_case_gain"]
