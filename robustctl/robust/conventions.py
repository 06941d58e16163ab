"""The one loop sign of robustctl: every controller is ``u = +K y``.

Synthesis (:func:`~robustctl.robust.hinf.synthesis.hinfsyn`, ``h2syn``, ``lqg``, ``dksyn``,
``ncfsyn``) returns and analysis (``diskmargin``, ``stability_margin``, the yardstick,
:meth:`UncertainSystem.feedback <robustctl.robust.uncertainty.system.UncertainSystem.feedback>`
with ``sign=+1``) takes the controller of the lower LFT ``Fl(P, K)``: the measurement ``y``
enters ``K`` and ``u = K y`` drives the plant, positive feedback (Zhou, Doyle & Glover 1996,
ch. 14-17; python-control's ``hinfsyn``/``h2syn``; RobustAndOptimalControl.jl). A controller
written the textbook way, ``u = -K y`` (MATLAB ``feedback(G*K, I)``, ``diskmargin(G, K)``,
an LQR ``u = -K_r x``), is the same loop with ``-K``: pass ``sign=-1`` where a function takes
a controller. A loop transfer function ``L`` on its own is always read in negative feedback,
closed loop ``(I + L)^-1`` (``L = -G K`` for ``u = +K y``).

The plant decides what ``y`` is: :func:`~robustctl.robust.plant.generalized_plant` measures
the sensors ``y = G u + ...``, so its controller closes ``u = +K G u`` (``diskmargin(G, K)``);
:func:`~robustctl.robust.plant.mixed_sensitivity` measures the tracking error ``e = r - G u``
(MATLAB ``augw``), so its controller acts on ``-G`` (``diskmargin(G, K, sign=-1)``).
"""

from __future__ import annotations

from ..errors import RobustctlWarning

__all__ = ["LOOP_SIGN", "loop_sign_words", "LoopSignWarning"]

#: ``u = LOOP_SIGN * K y`` for every controller robustctl designs or takes by default
LOOP_SIGN = 1.0


class LoopSignWarning(RobustctlWarning):
    """A loop closed with the assumed sign is unstable while the other sign would be stable."""


def loop_sign_words(sign: float) -> str:
    """``"u = +K y (sign=+1)"`` or ``"u = -K y (sign=-1)"``."""
    return "u = +K y (sign=+1)" if sign > 0 else "u = -K y (sign=-1)"
