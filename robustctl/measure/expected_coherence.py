"""The coherence a Welch H1 estimate of a noise-free system is expected to have: window leakage.

A lightly damped mode whose impulse response outlives the Welch window leaks: each segment's
output holds the decay of what the input did before the segment, which that segment's input
does not explain. The estimate's coherence drops at the resonances although no noise was added,
and its random error grows there (Bendat & Piersol, *Random Data*, 4th ed., sec. 9.2.3:
``sigma^2 = (1 - g2) / (2 n_d g2)`` for the real and the imaginary part of ``ln H1``), whatever
the output noise.

For a white, zero-order-held input of unit variance, a sampled impulse response ``h`` (the ZOH
response of :func:`robustctl.measure.estimator.expected_h1`) and an ``N``-point window ``w`` with
autocorrelation ``r_w[l] = sum_n w[n] w[n + l]``, the windowed spectra of one segment have

    E[U_w^* Y_w](theta) = sum_{l=0}^{N-1} h[l] r_w[l] exp(-j theta l)                     (C1)
    E[|Y_w|^2](theta)  = sum_{|l|<N} R_h(l) r_w[|l|] exp(-j theta l)                      (C2)
    E[|U_w|^2]         = r_w[0]                                                          (C3)

with ``R_h(l) = sum_k h[k + l] h[k]`` the impulse response's autocorrelation (steady state: the
whole past). The expected coherence is ``|C1|^2 / (C2 C3)`` (the ratio of the expectations, the
large-``n_d`` limit; Cauchy-Schwarz keeps it in [0, 1]). With ``x[k+1] = A_d x[k] + B_d u[k]``,
``y = C x + D u`` and ``P = A_d P A_d^T + B_d B_d^T`` (discrete Lyapunov):

    R_h(0) = C P C^T + D D^T,    R_h(l) = C A_d^l P C^T + C A_d^(l-1) B_d D^T   (l >= 1)   (C4)

and for a diagonalisable system with ZOH poles ``z_p`` and sampled residues ``a_p``
(``h[k] = sum_p a_p z_p^(k-1)``, ``k >= 1``):

    R_h(l) = D h[l] + sum_p a_p c_p z_p^l,    c_p = sum_q a_q / (1 - z_p z_q)               (C5)

Each input column is taken alone (a single-input experiment, or simultaneous inputs
uncorrelated with equal spectra: another input's leakage is then counted in neither).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg as sla

from ..errors import DataError
from ..lti import as_statespace, zoh
from ..threads import limit_blas
from .estimator import EstimatorSettings, _modal, windowed_spectrum

__all__ = ["expected_coherence", "expected_coherence_modal", "leakage_sigma"]


def _autocorrelation_modal(poles: np.ndarray, residues: np.ndarray, d: np.ndarray, fs: float,
                           n: int) -> tuple[np.ndarray, np.ndarray]:
    """``h[l]`` and ``R_h(l)``, ``l = 0..n-1`` (each (n, n_out, n_in)), by eq. C5."""
    t = 1.0 / fs
    poles = np.asarray(poles, dtype=complex)
    flat = np.asarray(residues, dtype=complex).reshape(len(poles), -1)
    dflat = np.asarray(d, dtype=float).reshape(-1)
    z = np.exp(poles * t)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(np.abs(poles) > 0, (z - 1.0) / poles, t)
    a = flat * gain[:, None]  # h[k] = sum_p a_p z_p^(k-1), k >= 1
    c = (1.0 / (1.0 - np.outer(z, z))) @ a  # c_p, per channel (eq. C5)
    powers = np.empty((n, z.size), dtype=complex)
    powers[0] = 1.0
    if n > 1:
        powers[1:] = np.cumprod(np.broadcast_to(z, (n - 1, z.size)), axis=0)
    h = np.empty((n, flat.shape[1]))
    h[0] = dflat
    h[1:] = np.real(powers[:-1] @ a)
    r = np.real(powers @ (a * c)) + dflat[None, :] * h
    r[0] = dflat**2 + np.real(np.sum(a * c, axis=0))
    shape = (n,) + np.shape(d)
    return h.reshape(shape), r.reshape(shape)


def _autocorrelation_state(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, fs: float,
                           n: int) -> tuple[np.ndarray, np.ndarray]:
    """``h[l]`` and ``R_h(l)`` by eq. C4, for a system that is not diagonalisable."""
    Ad, Bd = zoh(A, B, 1.0 / fs)
    n_out, n_in = D.shape
    h = np.empty((n, n_out, n_in))
    r = np.empty((n, n_out, n_in))
    h[0] = D
    X = np.empty((A.shape[0], n_out, n_in))  # A_d^(l-1) (A_d P_i C^T + B_d,i D_i^T), per input i
    for i in range(n_in):
        P = sla.solve_discrete_lyapunov(Ad, np.outer(Bd[:, i], Bd[:, i]))
        r[0, :, i] = np.einsum("on,nm,om->o", C, P, C) + D[:, i] ** 2
        X[:, :, i] = Ad @ P @ C.T + np.outer(Bd[:, i], D[:, i])
    G = Bd.copy()  # A_d^(l-1) B_d
    for k in range(1, n):
        h[k] = C @ G
        r[k] = np.einsum("on,noi->oi", C, X)
        G = Ad @ G
        X = np.einsum("nm,moi->noi", Ad, X)
    return h, r


def _coherence(h: np.ndarray, r: np.ndarray, f_hz: Any, settings: EstimatorSettings) -> np.ndarray:
    """``|C1|^2 / (C2 C3)`` from ``h`` and ``R_h`` (module notes)."""
    cross = windowed_spectrum(h, f_hz, settings)  # eq. C1 / r_w[0]
    power = 2.0 * np.real(windowed_spectrum(r, f_hz, settings)) - r[0][None]  # eq. C2 / r_w[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        g2 = np.where(power > 0, np.abs(cross) ** 2 / power, 1.0)
    return np.clip(g2, 0.0, 1.0)


@limit_blas
def expected_coherence_modal(poles: Any, residues: Any, d: Any, f_hz: Any,
                             settings: EstimatorSettings) -> np.ndarray:
    """:func:`expected_coherence` of ``sum_k residue_k / (s - pole_k) + d``.

    Parameters
    ----------
    poles : array_like (P,), complex
        Stable poles (rad/s), closed under conjugation.
    residues : array_like (P, n_out, n_in), complex
        Their residues, conjugate with their poles.
    d : array_like (n_out, n_in)
        Feedthrough.
    f_hz, settings
        As for :func:`expected_coherence`.

    Returns
    -------
    ndarray (K, n_out, n_in)
    """
    poles = np.asarray(poles, dtype=complex)
    if poles.size and np.max(poles.real) >= 0:
        raise DataError("the expected coherence needs stable poles: the impulse response must decay.")
    h, r = _autocorrelation_modal(poles, residues, np.asarray(d, dtype=float), float(settings.fs_hz),
                                  int(settings.nperseg))
    return _coherence(h, r, f_hz, settings)


@limit_blas
def expected_coherence(sys: Any, f_hz: Any, settings: EstimatorSettings) -> np.ndarray:
    """Coherence the Welch H1 estimate of the noise-free ``sys`` is expected to have (window leakage).

    Parameters
    ----------
    sys : system
        A stable continuous system (anything :func:`robustctl.as_statespace` accepts).
    f_hz : array_like (K,)
        Frequencies, Hz, not above Nyquist.
    settings : EstimatorSettings
        Sampling rate, segment length and window of the estimate.

    Returns
    -------
    ndarray (K, n_out, n_in)
        ``|C1|^2 / (C2 C3)`` of the module notes, in [0, 1]; 1 where the response is zero.

    Raises
    ------
    DataError
        When ``sys`` has a pole on or right of the imaginary axis (the steady state of eq. C2
        does not exist).
    """
    ss = as_statespace(sys)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    modal = _modal(ss)
    if modal is not None:
        return expected_coherence_modal(*modal, f_hz, settings)  # checks the poles' stability
    if np.max(np.linalg.eigvals(A).real) >= 0:
        raise DataError("the expected coherence needs a stable system: its impulse response must decay.")
    h, r = _autocorrelation_state(A, B, C, D, float(settings.fs_hz), int(settings.nperseg))
    return _coherence(h, r, f_hz, settings)


def leakage_sigma(g2: Any, n_averages: Any) -> np.ndarray:
    """Standard deviation (nepers / rad) of ``Re ln H1`` and ``Im ln H1`` from window leakage alone.

    ``sqrt((1 - g2) / (2 n_d g2))`` (Bendat & Piersol, sec. 9.2.3).

    Parameters
    ----------
    g2 : array_like (K, n_out, n_in)
        The expected coherence (:func:`expected_coherence`, :func:`expected_coherence_modal`).
    n_averages : array_like (n_in,)
        Effective number of averages per input column (:func:`robustctl.measure.noise.averages_of`).

    Returns
    -------
    ndarray (K, n_out, n_in)
    """
    g2 = np.asarray(g2, dtype=float)
    nd = np.asarray(n_averages, dtype=float).reshape(1, 1, -1)
    with np.errstate(divide="ignore"):
        return np.sqrt((1.0 - g2) / (2.0 * nd * np.maximum(g2, 1e-300)))
