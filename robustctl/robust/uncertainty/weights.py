"""Weighting functions: MATLAB's ``makeweight`` and the seed's additive weight.

Uncertainty and performance weights are stable, minimum-phase LTI systems whose magnitude
shapes a bound over frequency (Skogestad-Postlethwaite sec. 7.4; Zhou-Doyle-Glover
sec. 9.1). Fitted weights (``fit_magnitude``) live in :mod:`.magfit`, covers of measured
or modelled errors (``cover_additive``, ``cover_multiplicative``) in :mod:`.cover`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ...checks import optional_text, positive_number
from ...errors import FitError
from ...lti import zpk_statespace

__all__ = ["makeweight", "caltech_additive_weight", "CALTECH_MULTIPLICATIVE"]

#: The Caltech seed's input and output multiplicative uncertainty level ("selected to be 4%").
CALTECH_MULTIPLICATIVE = 0.04


def _positive(value: Any, what: str) -> float:
    return positive_number(value, what, FitError)


def makeweight(dc_gain: float, crossover: Sequence[float], hf_gain: float, order: int = 1, *, name=None):
    """A first-order (or ``order``-th power) weight through three magnitude specifications.

    MATLAB's ``makeweight(dcgain, [freq, mag], hfgain)``: ``|W(0)| = dc_gain``,
    ``|W(j 2 pi f_c)| = gain`` at ``crossover = (f_c, gain)``, ``|W(j inf)| = hf_gain``.
    With ``order = n`` the weight is ``W = W1^n`` where ``W1`` is the first-order weight
    through the n-th roots of the three gains (a steeper transition, same three values).

    The first-order shape is ``W1(s) = (h s + d p) / (s + p)``; its magnitude
    ``|W1(jw)|^2 = (h^2 w^2 + d^2 p^2) / (w^2 + p^2)`` equals ``g^2`` at ``w_c = 2 pi f_c``
    when ``p = w_c sqrt((g^2 - h^2) / (d^2 - g^2))`` (real only if ``g`` lies strictly
    between ``d`` and ``h``).

    Parameters
    ----------
    dc_gain : float
        Low-frequency gain (absolute, not dB), > 0.
    crossover : (f_hz, gain)
        Frequency (Hz) and magnitude the weight passes through.
    hf_gain : float
        High-frequency gain, > 0.
    order : int
        1 to 10.
    name : str, optional
        System name.

    Returns
    -------
    control.StateSpace
        Stable, minimum phase, biproper, SISO; ``order`` states.

    Raises
    ------
    FitError
        Non-positive or non-finite values; a crossover gain not strictly between the dc and
        hf gains (``dc < gain < hf`` or ``dc > gain > hf``); a bad order.

    Examples
    --------
    >>> import robustctl as rc
    >>> Wp = rc.makeweight(100.0, (1.0, 1.0), 0.5)  # performance: 40 dB at dc, 0 dB at 1 Hz
    """
    optional_text(name, "name", FitError)
    d = _positive(dc_gain, "dc_gain")
    h = _positive(hf_gain, "hf_gain")
    try:
        f_c, g = crossover
    except (TypeError, ValueError):
        raise FitError(f"crossover must be a pair (f_hz, gain); got {crossover!r}.") from None
    f_c = _positive(f_c, "crossover frequency (crossover[0], Hz)")
    g = _positive(g, "crossover gain (crossover[1])")
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= 10:
        raise FitError(f"order must be an integer from 1 to 10; got {order!r}.")
    if not (d < g < h or d > g > h):
        raise FitError(
            f"the crossover gain {g:g} (crossover[1]) must lie strictly between dc_gain {d:g} and "
            f"hf_gain {h:g} (dc < gain < hf for a high-pass weight, dc > gain > hf for a low-pass one)."
        )
    d1, g1, h1 = d ** (1.0 / order), g ** (1.0 / order), h ** (1.0 / order)
    w_c = 2.0 * np.pi * f_c
    p = w_c * np.sqrt((g1**2 - h1**2) / (d1**2 - g1**2))
    # W1 = h (s + d p / h) / (s + p): zero at -d p / h, pole at -p
    return zpk_statespace(np.full(order, -d1 * p / h1), np.full(order, -p), h, name=name)


def caltech_additive_weight(*, name: str = "W_additive"):
    """The Caltech seed's additive uncertainty weight (Balas-Doyle, eq. 14).

    ``W_a(s) = 8.0 (s + 6)(s + 12)(s + 24) / ((s + 0.6)(s + 400)^2)`` (s in rad/s):
    0.144 at dc (the low-frequency variation below 0.5 Hz), rising through the design band
    0.5-5.5 Hz to cover the unmodelled local modes above it, 8 at high frequency.

    Parameters
    ----------
    name : str
        Name of the returned system.

    Returns
    -------
    control.StateSpace
        Three states, stable and minimum phase.
    """
    optional_text(name, "name", FitError)
    return zpk_statespace([-6.0, -12.0, -24.0], [-0.6, -400.0, -400.0], 8.0, name=name)
