"""The record-end tail of an impact record (eq. T1 of :mod:`.leakage`) per unit residue, and the
leaked partial-fraction terms the modal refinement fits to the raw (truncated) data.

One hit at ``t_h`` and a record of length ``T`` sampled every ``dt`` give, at the DFT bins, the
response of a pole ``q`` with unit residue minus its tail

    tail_q(s) = dt sum_h w_h E_h(q, s) / (1 - exp((q - s) dt)),                          (T1)
    E_h(q, s) = exp((q - s) L_h + (q^2 - s^2) sigma_h^2 / 2),   L_h = T - t_h,

and its derivative with respect to the pole (for the analytic Jacobian of the refinement)

    d tail_q / dq = dt sum_h w_h E_h [(L_h + q sigma_h^2) / (1 - e) + dt e / (1 - e)^2],
    e = exp((q - s) dt).                                                              (T1')

The hit is a force pulse ``f(t)`` of finite length, and what the record cuts off, divided by the
force spectrum, is ``exp((q - s) T) P(q) / P(s)`` with ``P(z) = int f(t) exp(-z t) dt``; ``E_h``
is the cumulant expansion of that ratio to second order, with the pulse's centroid ``t_h`` and
its rms duration ``sigma_h``. The first order alone (``sigma_h = 0``) errs by
``(q^2 - s^2) sigma_h^2 / 2``, which grows with the distance from the mode: with a two-sample
pulse at 8192 Hz, 0.2 % of the tail 8 Hz off an 1830 Hz mode, enough to bias a fitted damping
by several percent.

This module holds only the kernels (no settings parsing), so that the refinement and the
leakage correction share them without importing each other.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..measure.impact_view import record_tails

__all__ = ["tail_terms", "leaked_terms", "complex_tails"]


def tail_terms(s: np.ndarray, poles: np.ndarray, settings: Any, derivative: bool = False):
    """``tail_q(s)`` of eq. T1 for every pole ``q`` and its conjugate, (K, n_p, 2); with
    ``derivative`` also ``d tail_q / dq`` (eq. T1'), same shape
    (:func:`robustctl.measure.impact_view.record_tails`).

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable at the data's frequencies, rad/s.
    poles : ndarray, complex, shape (n_p,)
        Poles, rad/s.
    settings : TruncationSettings
        Sampling frequency (Hz), record length (s), hit times (s) and hit weights.
    """
    p = np.asarray(poles, dtype=complex)
    return record_tails(s, np.stack([p, np.conj(p)], axis=-1), settings, derivative)


def leaked_terms(s: np.ndarray, poles: np.ndarray, settings: Any | None):
    """The partial fractions ``a = 1/(s - p)``, ``ab = 1/(s - conj p)`` of every pole, minus their
    tails when ``settings`` is given (the response a truncated record sees), and their
    derivatives ``da = d a/dp``, ``dab = d ab/d conj(p)``; each (K, n_p)."""
    a = 1.0 / (s[:, None] - poles[None, :])
    ab = 1.0 / (s[:, None] - np.conj(poles)[None, :])
    da, dab = a**2, ab**2
    if settings is not None:
        t, dt = tail_terms(s, poles, settings, derivative=True)
        a, ab = a - t[..., 0], ab - t[..., 1]
        da, dab = da - dt[..., 0], dab - dt[..., 1]
    return a, ab, da, dab


def complex_tails(s: np.ndarray, poles: np.ndarray, residues: np.ndarray, settings: Any | None) -> np.ndarray:
    """``sum_p tail_p(s) R_p + tail_conj(p)(s) conj(R_p)`` over the complex poles (real poles are
    fillers for out-of-band dynamics, no decay the record saw); (K, n_out, n_in), zero without
    ``settings``."""
    out = np.zeros((s.size,) + residues.shape[1:], dtype=complex)
    cplx = np.flatnonzero(np.asarray(poles).imag != 0)
    if settings is None or cplx.size == 0:
        return out
    t = tail_terms(s, poles[cplx], settings)
    out += np.einsum("kp,poi->koi", t[:, :, 0], residues[cplx])
    return out + np.einsum("kp,poi->koi", t[:, :, 1], np.conj(residues[cplx]))
