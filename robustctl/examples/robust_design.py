"""Design examples for mu-synthesis: the book's distillation column and the Caltech truss plant.

* :func:`distillation_plant` -- Skogestad & Postlethwaite, *Multivariable Feedback Control*
  (2nd ed. 2005), sec. 8.12.4: the ill-conditioned distillation column with diagonal input
  uncertainty and a performance weight, the textbook's D-K example (Table 8.2).
* :func:`caltech_design_plant` -- the Caltech seed's design problem: six modes, eq. 14's
  additive weight, 4 % input and output multiplicative uncertainty, input disturbances
  and a band-pass performance weight on the sensors.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["distillation_plant", "DISTILLATION_BLOCKS", "caltech_design_plant", "six_modes"]

#: mussv blocks of the distillation example: two 1x1 input-uncertainty blocks, the 2x2 performance block.
DISTILLATION_BLOCKS = [[1, 1], [1, 1], [2, 2]]


def distillation_plant(eps: float = 1e-6):
    """Skogestad & Postlethwaite sec. 8.12.4 as a plant ``[di; w; u] -> [wI u; wP e; -e]``.

    ``e = G (u + di) + w`` with ``G = 1/(75 s + 1) [[87.8, -86.4], [108.2, -109.6]]``,
    ``wI = (s + 0.2)/(0.5 s + 1) = 2 - 3.6/(s + 2)`` and ``wP = 0.5 (10 s + 1)/(10 s + 10 eps)``
    (the book's ``(s/2 + 0.05)/s`` with its integrator moved to ``-eps``). Use with
    :data:`DISTILLATION_BLOCKS`, ``nmeas = ncon = 2``.

    Parameters
    ----------
    eps : float
        Where the performance weight's integrator is moved (rad/s).

    Returns
    -------
    control.StateSpace
        6 states; inputs ``di1 di2 w1 w2 u1 u2``, outputs ``zi1 zi2 zp1 zp2 y1 y2``.
    """
    import control

    G0 = np.array([[87.8, -86.4], [108.2, -109.6]])
    I2, Z2 = np.eye(2), np.zeros((2, 2))
    A = np.block([[-I2 / 75, Z2, Z2], [Z2, -2 * I2, Z2], [G0, Z2, -eps * I2]])
    B = np.block([[I2 / 75, Z2, I2 / 75], [Z2, Z2, I2], [Z2, I2, Z2]])
    C = np.block([[Z2, -3.6 * I2, Z2], [0.5 * G0, Z2, 0.5 * (0.1 - eps) * I2], [-G0, Z2, Z2]])
    D = np.block([[Z2, Z2, 2 * I2], [Z2, 0.5 * I2, Z2], [Z2, -I2, Z2]])
    return control.ss(A, B, C, D, inputs=["di1", "di2", "w1", "w2", "u1", "u2"],
                      outputs=["zi1", "zi2", "zp1", "zp2", "y1", "y2"])


def six_modes(model: Any):
    """The six global modes (12 states) of a truss model by balanced truncation (seed eq. 11-13)."""
    import control

    from ..identify.balanced import balanced_truncation
    from ..lti import as_statespace

    G = as_statespace(model)
    if G.nstates <= 12:
        return G
    bt = balanced_truncation(G, 12)
    return control.ss(bt.sys.A, bt.sys.B, bt.sys.C, bt.sys.D, inputs=list(G.input_labels),
                      outputs=list(G.output_labels))


def caltech_design_plant(nominal: Any, level: float = 0.3, band_hz: tuple[float, float] = (0.3, 8.0)):
    """The Caltech design plant around ``nominal``'s six modes (a yardstick recipe).

    Seed eq. 14 additive weight, 4 % input and output multiplicative uncertainty (full 3x3
    blocks), unit input disturbances, and on the sensors the band-pass performance weight
    ``level * w2 s / ((s + w1)(s + w2))`` with corners ``band_hz``.

    Parameters
    ----------
    nominal : system
        The truss model (60 states: reduced to six modes) or a six-mode model.
    level : float
        Performance weight gain in the band: 0.3 is reachable with robust performance
        (mu ~ 0.8), 1 asks for more.
    band_hz : (f1, f2)
        Corner frequencies of the performance weight (Hz).

    Returns
    -------
    GeneralizedPlant
    """
    import control

    from ..robust.plant import generalized_plant
    from ..robust.weights import caltech_additive_weight

    w1, w2 = 2 * np.pi * band_hz[0], 2 * np.pi * band_hz[1]
    wp = control.ss(control.tf([level * w2, 0.0], np.polymul([1.0, w1], [1.0, w2])))
    return generalized_plant(six_modes(nominal), additive=caltech_additive_weight(), input_mult=0.04,
                             output_mult=0.04, performance=wp, disturbances=1.0)
