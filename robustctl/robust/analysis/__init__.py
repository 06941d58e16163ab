"""Loop analysis and loop shaping: disk margins, the nu-gap, coprime factors, Glover-McFarlane.

Holds
    ``coprime``      -- normalized coprime factorizations (Zhou, Doyle & Glover 1996, ch. 13;
                        McFarlane & Glover 1990).
    ``margins``      -- disk margins (Seiler, Packard & Gahinet 2020, IEEE CSM 40(5), eqs. 7, 9, 11)
                        and the nu-gap (Vinnicombe 2001).
    ``robust_margin`` -- robust-stability margin and worst-case gain of an uncertain system by
                        mixed mu, with destabilising and worst values (Packard & Doyle 1993;
                        Young & Doyle 1997).
    ``loop_shaping`` -- ``rc.ncfsyn`` and the normalized-coprime stability margin
                        (McFarlane & Glover 1990; Zhou, Doyle & Glover 1996, ch. 18).

May import
    ``robust.h2``, ``robust.hinf``, ``robust.mu``, the floors below them and the floors below
    ``robust``.
"""

from .loop_shaping import LoopShapingResult, ncfsyn, stability_margin
from .margins import DiskMargin, DiskMarginResult, disk_gain_phase, diskmargin, nugap
from .robust_margin import RobustStabilityMargin, WorstCaseResult, destabilizing_system, robstab, wcgain

__all__ = [
    "LoopShapingResult",
    "ncfsyn",
    "stability_margin",
    "DiskMargin",
    "DiskMarginResult",
    "disk_gain_phase",
    "diskmargin",
    "nugap",
    "RobustStabilityMargin",
    "WorstCaseResult",
    "destabilizing_system",
    "robstab",
    "wcgain",
]
