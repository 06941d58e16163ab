"""Realisation checks and transformations of a discrete controller before it is written: pole
radius, coefficient dynamic range, state scaling for fixed-point arithmetic, second-order sections."""

from __future__ import annotations

import warnings
from typing import Any

import control
import numpy as np
import scipy.linalg as sla

from ..balanced import hammarling_factor
from ..errors import DataError, ModelError
from ..lti import freqresp_array

__all__ = [
    "spectral_radius",
    "dynamic_range",
    "balance_diagonal",
    "balance_gramian",
    "sos_sections",
    "select_channel",
]


def spectral_radius(A: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


def dynamic_range(*mats: np.ndarray) -> float:
    """``max |coef| / min nonzero |coef|`` over all entries (1 when there is at most one value)."""
    values = np.abs(np.concatenate([np.asarray(m, dtype=float).reshape(-1) for m in mats]))
    values = values[values > 0]
    if not values.size:
        return 1.0
    with np.errstate(over="ignore"):
        return float(values.max() / values.min())  # inf when the ratio overflows float64


def balance_diagonal(A, B, C):
    """Diagonal similarity ``T = diag(2^k)`` equalising row and column norms of ``[[A, |B|], [|C|, 0]]``
    (LAPACK gebal without permutation; powers of two, so the scaling itself is exact)."""
    n = A.shape[0]
    if n == 0:
        return A, B, C
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n] = A
    aug[:n, n] = np.linalg.norm(B, axis=1)
    aug[n, :n] = np.linalg.norm(C, axis=0)
    _, (scale, _) = sla.matrix_balance(aug, permute=False, separate=True)
    d = scale[:n] / scale[n]
    return A * d[None, :] / d[:, None], B / d[:, None], C * d[None, :]


def balance_gramian(A, B, C):
    """Balanced realisation of a stable, minimal discrete system: equal, diagonal controllability
    and observability Gramians ``P = Q = Sigma`` (square-root method, Laub et al. 1987; Gramian
    factors by Hammarling's method, SLICOT SB03OD, falling back to a clipped eigendecomposition)."""
    n = A.shape[0]
    if n == 0:
        return A, B, C
    if spectral_radius(A) >= 1:
        raise ModelError("balance='balanced' needs a stable discrete controller; use balance='diagonal'.")
    Lc, Lo = _gramian_factor(A, B, observability=False), _gramian_factor(A, C, observability=True)
    U, s, Vt = np.linalg.svd(Lo.T @ Lc)
    if s[-1] <= 1e-12 * s[0]:
        raise ModelError(
            f"balance='balanced' needs a minimal controller; its smallest Hankel singular value is "
            f"{s[-1]:.3g} (largest {s[0]:.3g}). Reduce it first (rc.balanced_truncation) "
            "or use balance='diagonal'."
        )
    Tr = Lc @ Vt.T / np.sqrt(s)
    Tl = (U / np.sqrt(s)).T @ Lo.T
    return Tl @ A @ Tr, Tl @ B, C @ Tr


def _gramian_factor(A: np.ndarray, B: np.ndarray, observability: bool) -> np.ndarray:
    """``L`` with ``L L^T = P`` (``A P A^T - P + B B^T = 0``) or, for ``observability`` and
    ``B = C``, ``L L^T = Q`` (``A^T Q A - Q + C^T C = 0``)."""
    L = hammarling_factor(A, B, observability, dico="D")
    if L is not None and np.all(np.isfinite(L)):
        return L
    rhs = B.T @ B if observability else B @ B.T
    X = sla.solve_discrete_lyapunov(A.T if observability else A, rhs)
    w, V = np.linalg.eigh((X + X.T) / 2)
    return V * np.sqrt(np.clip(w, 0, None))


def select_channel(ss: Any, channel: Any) -> tuple[int, int]:
    if channel is None:
        if ss.ninputs == ss.noutputs == 1:
            return 0, 0
        raise DataError(
            f"second-order sections are SISO; the controller is {ss.noutputs}x{ss.ninputs}. Pick one channel "
            f"with channel=(output, input), e.g. channel=({ss.output_labels[0]!r}, {ss.input_labels[0]!r})."
        )
    if not isinstance(channel, (tuple, list)) or len(channel) != 2:
        raise DataError(f"channel must be a pair (output, input) of names or indices; got {channel!r}.")
    out = []
    for item, labels, what in zip(channel, (ss.output_labels, ss.input_labels), ("output", "input")):
        if isinstance(item, str) and item not in labels and item.isdigit():  # an index typed as text
            item = int(item)
        if isinstance(item, str) and item in labels:
            out.append(list(labels).index(item))
        elif isinstance(item, (int, np.integer)) and not isinstance(item, bool) and 0 <= item < len(labels):
            out.append(int(item))
        else:
            raise DataError(f"channel {what} {item!r} is not one of {list(labels)} (or an index).")
    return out[0], out[1]


def sos_sections(Kd: Any) -> tuple[np.ndarray, float]:
    """Second-order sections of a SISO discrete system and their max relative response error.

    The channel is first reduced to a minimal realisation (``control.minreal``, which drops the
    modes a MIMO controller's other channels need). Poles are then the eigenvalues of ``A``,
    zeros the finite generalized eigenvalues of the system pencil
    ``([[A, B], [C, D]], diag(I, 0))`` (Emami-Naeini & Van Dooren 1982), the gain the
    least-squares fit of the response on 64 points of the unit circle; ``scipy.signal.zpk2sos``
    pairs them. The error is ``max |H_sos - K_d| / max |K_d|`` over 2000 frequencies up to
    Nyquist, against the full channel.
    """
    from scipy.signal import sosfreqz, zpk2sos

    fine = np.linspace(0.0005, 0.4995, 2000) / Kd.dt
    ref = freqresp_array(Kd, fine)[:, 0, 0]
    if not np.any(ref):
        return np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0]]), 0.0
    M = _minimal(Kd)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (M.A, M.B, M.C, M.D))
    n = A.shape[0]
    if n == 0:
        sos = np.array([[float(D[0, 0]), 0.0, 0.0, 1.0, 0.0, 0.0]])
    else:
        poles = np.linalg.eigvals(A)
        pencil = np.block([[A, B], [C, D]])
        E = np.zeros_like(pencil)
        E[:n, :n] = np.eye(n)
        zeros = sla.eigvals(pencil, E)
        zeros = zeros[np.isfinite(zeros) & (np.abs(zeros) < 1e8)]
        f = np.linspace(0.01, 0.49, 64) / Kd.dt
        zz = np.exp(2j * np.pi * f * Kd.dt)
        shape = np.prod(zz[:, None] - zeros[None, :], axis=1) / np.prod(zz[:, None] - poles[None, :], axis=1)
        g = freqresp_array(M, f)[:, 0, 0]
        sos = zpk2sos(zeros, poles, float(np.real(np.vdot(shape, g) / np.vdot(shape, shape))))
    _, h = sosfreqz(sos, worN=2 * np.pi * fine * Kd.dt)
    return sos, float(np.max(np.abs(h - ref)) / np.max(np.abs(ref)))


def _minimal(Kd: Any):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return control.minreal(Kd, verbose=False)
    except Exception:  # no slycot, or a degenerate case: keep the channel as it is
        return Kd
