"""H2 norm, H2-optimal output feedback and LQG design.

Holds
    ``synthesis``  -- ``rc.h2norm`` from the Gramians (Zhou, Doyle & Glover 1996, sec. 4.4) and
                      ``rc.h2syn`` by two Riccati equations (Zhou, Doyle & Glover 1996, ch. 14).
    ``lqg_design`` -- ``rc.lqg`` from noise intensities, the H2 problem of the MACE controllers
                      (Glaese & Miller, seed paper; Zhou, Doyle & Glover 1996, ch. 14).

May import
    ``robust.hinf`` (assumption checks, LFT matrices), ``robust.mu`` (frequency grids),
    the floors below them and the floors below ``robust``.
"""

from .lqg_design import LQGResult, lqg
from .synthesis import H2Result, h2norm, h2syn

__all__ = ["H2Result", "h2norm", "h2syn", "LQGResult", "lqg"]
