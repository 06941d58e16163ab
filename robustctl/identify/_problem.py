"""Validation of a rational-fit request: data, band, order and per-frequency weights.

Everything the fitting kernels need is gathered in :class:`FitProblem` (plain arrays, rad/s),
so the kernels never see bad input. Every refusal is a :class:`~robustctl.errors.FitError` or
:class:`~robustctl.errors.DataError` whose message says what to change.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DataError, FitError
from ..frd import FrequencyData

__all__ = ["FitProblem", "as_frequency_data", "prepare_problem", "coherence_weights"]

#: cap of the coherence weight c / (1 - c): coherence above 0.99 counts as 0.99.
COHERENCE_WEIGHT_CAP = 99.0


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
        Non-negative weights on the *squared* residuals (inverse variances).
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


def as_frequency_data(data: Any) -> FrequencyData:
    """Accept FrequencyData, a ``control.FrequencyResponseData`` or a ``(f_hz, response)`` pair."""
    if isinstance(data, FrequencyData):
        return data
    if isinstance(data, tuple) and len(data) == 2:
        return FrequencyData(*data)
    if hasattr(data, "omega") and hasattr(data, "fresp"):
        return FrequencyData.from_control(data)
    raise DataError(
        f"data must be a FrequencyData, a control.FrequencyResponseData or a tuple (f_hz, response); "
        f"got {type(data).__name__}."
    )


def coherence_weights(coherence: np.ndarray) -> np.ndarray:
    """Inverse-variance weights ``c / (1 - c)`` of an H1 estimate, capped at coherence 0.99.

    The variance of ``log |G_hat|`` of a Welch estimate is proportional to ``(1 - c) / c``
    (Bendat & Piersol), so ``c / (1 - c)`` weights each squared log residual by its inverse
    variance.
    """
    c = np.clip(np.asarray(coherence, dtype=float), 0.0, 0.99)
    return c / (1.0 - c)


def _check_order(order: Any) -> int:
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)):
        raise FitError(f"order must be a positive integer number of poles (2 per mode); got {order!r}.")
    if order <= 0:
        raise FitError(
            f"order must be a positive number of poles (2 per lightly damped mode); got {order}. "
            "Use order=2*n_modes."
        )
    return int(order)


def _band_mask(f_hz: np.ndarray, band: Any) -> np.ndarray:
    if band is None:
        return np.ones(f_hz.size, dtype=bool)
    try:
        lo, hi = (float(b) for b in band)
    except (TypeError, ValueError) as exc:
        raise FitError(f"band must be a pair (f_lo_hz, f_hi_hz); got {band!r}.") from exc
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo >= hi:
        raise FitError(f"band ({lo:g}, {hi:g}) Hz is empty or not finite; give f_lo_hz < f_hi_hz.")
    mask = (f_hz >= lo) & (f_hz <= hi)
    if not np.any(mask):
        raise FitError(
            f"band ({lo:g}, {hi:g}) Hz holds no data points; the data span {f_hz[0]:g}-{f_hz[-1]:g} Hz."
        )
    return mask


def _weights(data: FrequencyData, weights: Any, mask: np.ndarray) -> np.ndarray:
    shape = data.response.shape
    if weights is None:
        w = np.ones(shape) if data.coherence is None else coherence_weights(data.coherence)
    else:
        w = np.asarray(weights, dtype=float)
        if w.ndim == 1 and w.size == shape[0]:
            w = w[:, None, None]
        try:
            w = np.broadcast_to(w, shape)
        except ValueError as exc:
            raise FitError(
                f"weights of shape {np.shape(weights)} do not fit the data of shape {shape}; give one "
                "weight per frequency (n_freq,) or per entry (n_freq, n_out, n_in)."
            ) from exc
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise FitError("weights must be finite and non-negative; remove NaN/inf or negative weights.")
    w = np.array(w[mask], dtype=float)
    if not np.any(w > 0):
        raise FitError("all weights inside the band are zero; nothing would be fitted.")
    return w


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


def prepare_problem(data: Any, order: Any, band: Any = None, weights: Any = None) -> FitProblem:
    """Validate ``data``, ``order``, ``band`` and ``weights`` and return a :class:`FitProblem`."""
    fd = as_frequency_data(data)
    n = _check_order(order)
    mask = _band_mask(fd.f_hz, band)
    f = fd.f_hz[mask]
    g = np.array(fd.response[mask])
    _check_channels(g, fd.outputs, fd.inputs)
    if f.size <= n:
        raise FitError(
            f"the band holds {f.size} frequency points but a fit with {n} poles has {2 * n + 1} real "
            f"unknowns per channel and needs at least {n + 1} points; widen the band or lower the order."
        )
    w = _weights(fd, weights, mask)
    # tiny entries would blow up the relative weighting 1/|g|: floor them per channel
    floor = 1e-12 * np.max(np.abs(g), axis=0, keepdims=True)
    g = np.where(np.abs(g) < floor, floor, g)
    band_data = fd.replace(
        f_hz=f, response=fd.response[mask], coherence=None if fd.coherence is None else fd.coherence[mask]
    )
    return FitProblem(f, 2j * np.pi * f, g, w, n, fd.inputs, fd.outputs, band_data)
