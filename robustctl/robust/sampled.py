"""A generalized plant at the controller's sample rate: ``rc.sampled_plant(P, dt, delay=True)``.

For a design at the real-time computer's rate (200-500 Hz for the structures here) the
continuous partitioned plant ``P: [w; u] -> [z; y]`` is sampled with a zero-order hold on
its inputs (exact, ``expm([[A, B], [0, 0]] dt)``; Franklin, Powell & Workman 1998,
"Digital Control of Dynamic Systems", eq. 4.58), the outputs sampled at the same instants,
and, when asked, a one-sample computation delay put in front of the control inputs
(``u_applied(k) = u(k - 1)``: the command computed from ``y(k)`` is applied at the next
sample; FPW sec. 4.3.4). The exogenous inputs are held too, which is exact for signals
that a DAC produces and an approximation for continuous disturbances (state it in a report).

The result is a :class:`~robustctl.interconnect.PartitionedPlant` with ``dt`` and the
plant's signal names, ready for :func:`hinfsyn` and :func:`h2syn`, whose controllers
then run at ``dt`` as they are (``rc.export_controller(K, ...)`` takes them without
discretising again).
"""

from __future__ import annotations

from typing import Any

import control
import numpy as np

from ..checks import flag, positive_number
from ..errors import SynthesisError
from ..interconnect import PartitionedPlant
from ..lti import zoh
from .partitioned import as_partitioned

__all__ = ["sampled_plant"]


def sampled_plant(P: Any, dt: float, *, delay: bool = False, nmeas: int | None = None,
                  ncon: int | None = None) -> PartitionedPlant:
    """The continuous generalized plant sampled with a zero-order hold (and a computation delay).

    Parameters
    ----------
    P : PartitionedPlant, GeneralizedPlant, control.StateSpace
        A continuous-time generalized plant ``[z; y] = P [w; u]`` (``nmeas``/``ncon`` needed
        unless ``P`` carries them).
    dt : float
        Sampling period in s (1 / the controller's sample rate).
    delay : bool
        Put one sample of computation delay in front of the control inputs: ``ncon`` more
        states ``x_u(k + 1) = u(k)`` whose values drive the plant (the controller then sees
        ``y(k)`` and its command acts from ``k + 1``).
    nmeas, ncon : int, optional
        Number of measurements (last outputs) and control inputs (last inputs) when ``P`` is a
        bare state space.

    Returns
    -------
    PartitionedPlant
        Discrete, with ``dt`` and the plant's names (the delay states are named ``"<u> delayed"``).

    Raises
    ------
    SynthesisError
        A plant that is already discrete, a non-positive ``dt``, a non-boolean ``delay``.

    See Also
    --------
    hinfsyn, h2syn
    """
    dt = positive_number(dt, "dt", SynthesisError, unit="s")
    delay = flag(delay, "delay", SynthesisError)
    plant = as_partitioned(P, nmeas, ncon, who="sampled_plant", allow_discrete=True)
    if plant.P.dt not in (0, None):
        raise SynthesisError(
            "sampled_plant samples a continuous-time plant; this one is already discrete "
            f"(dt = {plant.P.dt})."
        )
    A, B, C, D = (np.asarray(m, dtype=float) for m in (plant.P.A, plant.P.B, plant.P.C, plant.P.D))
    Ad, Bd = zoh(A, B, dt)
    states = list(plant.P.state_labels)
    if delay:
        nw, nu, n = plant.nw, plant.ncon, A.shape[0]
        Bw, Bu = Bd[:, :nw], Bd[:, nw:]
        Ad = np.block([[Ad, Bu], [np.zeros((nu, n)), np.zeros((nu, nu))]])
        Bd = np.block([[Bw, np.zeros((n, nu))], [np.zeros((nu, nw)), np.eye(nu)]])
        C = np.hstack([C, D[:, nw:]])
        D = np.hstack([D[:, :nw], np.zeros((D.shape[0], nu))])
        states += [f"{u} delayed" for u in plant.u_names]
    Pd = control.ss(Ad, Bd, C, D, dt, inputs=list(plant.P.input_labels), outputs=list(plant.P.output_labels),
                    states=states, name="sampled plant")
    return PartitionedPlant(Pd, plant.nmeas, plant.ncon)
