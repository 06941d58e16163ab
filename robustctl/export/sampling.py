"""Continuous controller -> sampled controller: Tustin (optionally prewarped) and zero-order hold.

References
----------
G. F. Franklin, J. D. Powell, M. L. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
Addison-Wesley 1998: ch. 4 (zero-order-hold equivalent ``Phi = e^{AT}``,
``Gamma = int_0^T e^{A eta} d eta B``) and ch. 6 (Tustin's bilinear rule and prewarping).
C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE TAC 23(3), 1978
(``Phi`` and ``Gamma`` from one exponential of ``[[A, B], [0, 0]] T``).
"""

from __future__ import annotations

from typing import Any

import control
import numpy as np

from ..errors import DataError, ModelError
from ..lti import freqresp_array, zoh
from .arguments import choice, is_discrete, positive, unwrap

__all__ = ["discretize", "discretization_error", "peak_gain_hz"]

METHODS = ("tustin", "zoh")


# ---------------------------------------------------------------------------- discretisation
def _tustin(A, B, C, D, T: float, c: float):
    """Bilinear map ``s = c (z - 1) / (z + 1)``, ``c = 2/T`` (``w0 / tan(w0 T / 2)`` when prewarped).

    With ``M = (I - A/c)^{-1}`` (FPW ch. 6; scipy's ``cont2discrete`` 'bilinear' realisation with
    ``dt = 2/c``): ``A_d = M (I + A/c)``, ``B_d = (2/c) M B``, ``C_d = C M``,
    ``D_d = D + C M B / c``.
    """
    n = A.shape[0]
    ima = np.eye(n) - A / c
    if n and np.linalg.cond(ima) > 1e12:
        raise ModelError(
            f"the controller has a pole at s = {c:.6g} rad/s, where Tustin's map is singular; "
            "change fs or prewarp_hz slightly, or use method='zoh'."
        )
    Ad = np.linalg.solve(ima, np.eye(n) + A / c)
    Bd = np.linalg.solve(ima, B) * (2.0 / c)
    Cd = np.linalg.solve(ima.T, C.T).T
    Dd = D + 0.5 * (C @ Bd) if n else D.copy()
    return Ad, Bd, Cd, Dd


def _zoh(A, B, C, D, T: float):
    """Zero-order hold: ``expm([[A, B], [0, 0]] T) = [[Phi, Gamma], [0, I]]`` (FPW ch. 4; Van Loan 1978)."""
    Ad, Bd = zoh(A, B, T)
    return Ad, Bd, C.copy(), D.copy()


def discretize(K: Any, fs: float | None, method: str = "tustin", prewarp_hz: float | None = None):
    """The sampled equivalent ``K_d(z)`` of a continuous controller ``K(s)``, ``dt = 1/fs``.

    Parameters
    ----------
    K : control.StateSpace, TransferFunction, synthesis result with ``.K``, or anything
        :func:`robustctl.lti.as_statespace` accepts
        Continuous (s in rad/s). An already discrete system is returned unchanged when ``fs``
        is None or equals its sample rate.
    fs : float or None
        Sample rate in Hz.
    method : {"tustin", "zoh"}
        ``"tustin"``: bilinear ``s = (2/T)(z - 1)/(z + 1)`` (FPW ch. 6); stable maps to
        stable, the frequency axis is warped as ``w_d = (2/T) arctan(w T / 2)``.
        ``"zoh"``: exact step-invariant equivalent ``Phi = e^{AT}``,
        ``Gamma = int_0^T e^{A eta} d eta B`` (FPW ch. 4), via one matrix exponential.
    prewarp_hz : float, optional
        Tustin only: use ``s = (w0 / tan(w0 T/2)) (z - 1)/(z + 1)`` with ``w0 = 2 pi prewarp_hz``,
        so ``K_d(e^{j w0 T}) = K(j w0)`` exactly at that frequency (e.g. the crossover or a
        notch). Must lie below the Nyquist frequency ``fs/2``.

    Returns
    -------
    control.StateSpace
        Discrete, ``dt = 1/fs``, with K's input, output and state names.

    Raises
    ------
    DataError
        fs missing, not positive, or different from a discrete K's rate; bad method or prewarp.
    ModelError
        Tustin's map is singular (a pole of K at ``s = 2/T``).

    Examples
    --------
    >>> import control, robustctl as rc
    >>> Kd = rc.discretize(control.tf([10], [1, 10]), fs=1000, method="zoh")
    """
    ss, _ = unwrap(K)
    method = choice(method, "method", METHODS)
    if is_discrete(ss):
        if fs is not None and abs(positive(fs, "fs", "") * ss.dt - 1.0) > 1e-12:
            raise DataError(
                f"K is already discrete with fs = {1 / ss.dt:.12g} Hz; got fs = {fs!r}. Pass fs=None "
                "(or the same rate): resampling a discrete controller is not supported."
            )
        return ss
    if fs is None:
        raise DataError("fs is required to discretise a continuous controller: pass the sample rate in Hz.")
    fs = positive(fs, "fs", "Pass the real-time loop's sample rate in Hz.")
    T = 1.0 / fs
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    if not all(np.all(np.isfinite(m)) for m in (A, B, C, D)):
        raise ModelError("the controller's matrices contain NaN or inf.")
    if prewarp_hz is not None and method != "tustin":
        raise DataError(
            f"prewarp_hz applies to method='tustin' only; got method={method!r}. Drop prewarp_hz."
        )
    if method == "zoh":
        mats = _zoh(A, B, C, D, T)
    else:
        c = 2.0 / T
        if prewarp_hz is not None:
            f0 = positive(prewarp_hz, "prewarp_hz", "Give the frequency to match in Hz.")
            if f0 >= fs / 2:
                raise DataError(
                    f"prewarp_hz = {f0:g} Hz must lie below the Nyquist frequency fs/2 = {fs / 2:g} Hz."
                )
            w0 = 2 * np.pi * f0
            c = w0 / np.tan(w0 * T / 2)
        mats = _tustin(A, B, C, D, T, c)
    return control.ss(
        *mats,
        T,
        inputs=list(ss.input_labels),
        outputs=list(ss.output_labels),
        states=list(ss.state_labels),
        name=f"{ss.name}$sampled",
    )


def peak_gain_hz(K: Any, fs: float) -> float:
    """Frequency (Hz, below Nyquist) of the largest singular value of ``K(j w)``: a log grid
    from ``1e-5 fs`` to ``0.499 fs`` plus the controller's own pole frequencies."""
    grid = np.geomspace(1e-5 * fs, 0.499 * fs, 600)
    poles = np.linalg.eigvals(K.A) if K.nstates else np.zeros(0)
    extra = np.abs(poles) / (2 * np.pi)
    f = np.unique(np.concatenate([grid, extra[(extra > grid[0]) & (extra < grid[-1])]]))
    gains = np.linalg.norm(freqresp_array(K, f), ord=2, axis=(1, 2))
    return float(f[np.argmax(gains)])


def discretization_error(K: Any, Kd: Any, f_hz: float) -> float:
    """Relative error ``||K_d(e^{j w T}) - K(j w)||_2 / ||K(j w)||_2`` at ``f_hz`` (spectral norms;
    the absolute error when ``K(j w) = 0``)."""
    g = freqresp_array(K, [f_hz])[0]
    gd = freqresp_array(Kd, [f_hz])[0]
    ref = np.linalg.norm(g, 2)
    err = np.linalg.norm(gd - g, 2)
    return float(err / ref) if ref > 0 else float(err)
