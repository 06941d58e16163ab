"""Validation of a rational-fit request: data, band, order and per-frequency weights.

Everything the fitting kernels need is gathered in :class:`FitProblem` (plain arrays, rad/s),
so the kernels never see bad input. Every refusal is a :class:`~robustctl.errors.FitError` or
:class:`~robustctl.errors.DataError` whose message says what to change.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..checks import band_mask, coherence_weights, point_weights
from ..errors import DataError, FitError
from ..frd import FrequencyData, as_frequency_data

__all__ = ["FitProblem", "as_frequency_data", "prepare_problem", "coherence_weights"]

# band, point weights and coercion follow the one rule of robustctl.checks


@dataclass(frozen=True)
class FitProblem:
    """A validated fit request.

    Attributes
    ----------
    f_hz : ndarray, shape (K,)
        Frequencies inside the band, Hz.
    s : ndarray, complex, shape (K,)
        Laplace variable ``j 2 pi f`` on the band, rad/s.
    g : ndarray, complex, shape (K, n_out, n_in)
        Measured response inside the band.
    w : ndarray, shape (K, n_out, n_in)
        Non-negative weights on the *squared* residuals (inverse variances):
        :func:`robustctl.checks.point_weights`.
    order : int
        Number of poles (states of a SISO realisation).
    inputs, outputs : tuple of str
        Signal names.
    """

    f_hz: np.ndarray
    s: np.ndarray
    g: np.ndarray
    w: np.ndarray
    order: int
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    data: FrequencyData

    @property
    def band_hz(self) -> tuple[float, float]:
        return float(self.f_hz[0]), float(self.f_hz[-1])

    @property
    def n_channels(self) -> int:
        return self.g.shape[1] * self.g.shape[2]


def _check_order(order: Any) -> int:
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)):
        raise FitError(f"order must be a positive integer number of poles (2 per mode); got {order!r}.")
    if order <= 0:
        raise FitError(
            f"order must be a positive number of poles (2 per lightly damped mode); got {order}. "
            "Use order=2*n_modes."
        )
    return int(order)


def _check_channels(g: np.ndarray, outputs: tuple[str, ...], inputs: tuple[str, ...]) -> None:
    peak = np.max(np.abs(g), axis=0)
    if not np.any(peak > 0):
        raise DataError("the response is identically zero inside the band; there is nothing to fit.")
    zero = np.argwhere(peak == 0)
    if zero.size:
        names = [f"{outputs[i]}<-{inputs[j]}" for i, j in zero]
        raise DataError(
            f"channels {names} are identically zero inside the band; the relative (log) fit needs "
            "non-zero data. Drop them with data.select(...) or fit the inputs separately."
        )


def prepare_problem(data: Any, order: Any, band: Any = None, weights: Any = "auto") -> FitProblem:
    """Validate ``data``, ``order``, ``band`` and the point ``weights`` and return a :class:`FitProblem`."""
    fd = as_frequency_data(data)
    n = _check_order(order)
    mask = band_mask(fd.f_hz, band)
    f = fd.f_hz[mask]
    g = np.array(fd.response[mask])
    _check_channels(g, fd.outputs, fd.inputs)
    if f.size <= n:
        raise FitError(
            f"the band holds {f.size} frequency points but a fit with {n} poles has {2 * n + 1} real "
            f"unknowns per channel and needs at least {n + 1} points; widen the band or lower the order."
        )
    w = point_weights(weights, fd, mask)
    # tiny entries would blow up the relative weighting 1/|g|: floor them per channel
    floor = 1e-12 * np.max(np.abs(g), axis=0, keepdims=True)
    g = np.where(np.abs(g) < floor, floor, g)
    band_data = fd.points(mask)  # checked by as_frequency_data above: not validated again
    return FitProblem(f, 2j * np.pi * f, g, w, n, fd.inputs, fd.outputs, band_data)
