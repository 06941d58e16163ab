"""D-K iteration on a sampled plant through the bilinear (Tustin) map.

``s = (2/T)(z - 1)/(z + 1)`` maps the unit circle onto the imaginary axis and the unit disc
onto the open left half plane. A sampled generalized plant ``P_d`` and its Tustin original
``P_c = d2c(P_d, "tustin")`` (:func:`~robustctl.robust.continuous_equivalent.d2c`) therefore
take the same values, ``P_d(e^{j w T}) = P_c(j W)`` with ``W = (2/T) tan(w T / 2)``, and the
map commutes with the lower LFT (it is a change of the frequency variable in every transfer
function of the loop). So ``K_c`` stabilises ``P_c`` exactly when ``K_d = c2d(K_c, "tustin")``
stabilises ``P_d``, and ``mu(Fl(P_d, K_d)(e^{j w T})) = mu(Fl(P_c, K_c)(j W))`` at every
frequency: the peak of mu, and every certificate built on it, is the same (Zhou, Doyle &
Glover 1996, sec. 21.3; Franklin, Powell & Workman 1998, sec. 6.3.2). D-K on ``P_c`` is D-K on
``P_d``; only the frequency axis is warped, ``f_d = arctan(pi f_c T) / (pi T)``, below the
Nyquist frequency ``1 / (2 T)``.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import control
import numpy as np

from ...errors import ModelError, SynthesisError
from ..continuous_equivalent import d2c
from ..plant import GeneralizedPlant
from .verify import closed_loop

__all__ = ["tustin_original", "sampled_result", "warped_hz"]


def tustin_original(plant: GeneralizedPlant) -> GeneralizedPlant:
    """The continuous plant whose Tustin map is the sampled ``plant`` (same partition, blocks, names).

    Raises
    ------
    SynthesisError
        A pole at ``z = -1`` (no proper Tustin original) or an unspecified sample time.
    """
    try:
        Pc = d2c(plant.P, method="tustin")
    except ModelError as exc:
        raise SynthesisError(
            f"dksyn designs a sampled plant through the Tustin map (rc.d2c(P, method='tustin')); {exc}"
        ) from exc
    return GeneralizedPlant(Pc, plant.nmeas, plant.ncon, blocks=plant.blocks)


def warped_hz(f_c_hz: Any, dt: float) -> np.ndarray:
    """Frequencies (Hz) of the sampled system at which it takes its Tustin original's values at
    ``f_c_hz``: ``arctan(pi f_c dt) / (pi dt)`` (below the Nyquist frequency ``1 / (2 dt)``)."""
    return np.arctan(np.pi * np.asarray(f_c_hz, dtype=float) * dt) / (np.pi * dt)


def _sampled(S: Any, dt: float) -> Any:
    """``c2d(S, dt, "tustin")`` with ``S``'s signal and state names."""
    Sd = control.c2d(S, dt, method="tustin")
    return control.ss(Sd.A, Sd.B, Sd.C, Sd.D, dt, inputs=list(S.input_labels), outputs=list(S.output_labels),
                      states=list(S.state_labels))


def sampled_result(res: Any, plant: GeneralizedPlant) -> Any:
    """A DKResult of the Tustin original mapped back to the sampled ``plant``.

    The controller and D-scales are sampled with the Tustin map, the closed loop is
    ``Fl(P_d, K_d)``, and the mu result's frequencies are warped to the sampled system's
    (:func:`warped_hz`); its values are unchanged (module docstring). The ``history``
    stays the original's (frequencies in the original's Hz).
    """
    dt = float(plant.P.dt)
    K = _sampled(res.K, dt)
    m = res.mu
    mu = replace(m, f_hz=warped_hz(m.f_hz, dt), f_peak_hz=float(warped_hz(m.f_peak_hz, dt)),
                 f_worst_hz=float(warped_hz(m.f_worst_hz, dt)),
                 info={**m.info, "sampled": f"frequencies warped from the Tustin original (dt={dt:g} s)"})
    return replace(res, K=K, closed_loop=closed_loop(plant.P, K, plant.nmeas, plant.ncon), mu=mu,
                   d_scales=tuple(_sampled(d, dt) for d in res.d_scales))
