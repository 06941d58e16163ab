"""H-infinity norm and H-infinity synthesis (Riccati and LMI routes) with their assumption checks.

Holds
    ``norm``        -- ``rc.hinfnorm`` by the Hamiltonian level-set iteration (Bruinsma &
                       Steinbuch 1990; Boyd, Balakrishnan & Kabamba 1989, Theorem 1).
    ``synthesis``   -- ``rc.hinfsyn`` and :class:`HinfResult`: gamma iteration verified on the
                       closed loop (Zhou, Doyle & Glover 1996, ch. 16-17).
    ``dgkf``        -- the Riccati kernel: normalisation, loop shifting, gamma test, central
                       controller (Zhou, Doyle & Glover 1996, Theorem 17.1, eqs. 17.7-17.8;
                       Safonov, Limebeer & Chiang 1989).
    ``lmi``         -- the LMI route for singular problems (Gahinet & Apkarian 1994, Theorem 4.3).
    ``assumptions`` -- (A1)-(A4) of Zhou, Doyle & Glover 1996, sec. 17.1, checked before any Riccati.

May import
    ``robust.uncertainty``, ``robust.plant``/``robust.partitioned``, ``robust.mu`` and the floors
    below ``robust``.
"""

from .norm import hinfnorm
from .synthesis import HinfResult, hinfsyn

__all__ = ["hinfnorm", "hinfsyn", "HinfResult"]
