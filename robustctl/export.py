"""Discretise a controller and export it as coefficient files for a real-time computer.

:func:`discretize` maps a continuous controller ``K(s)`` to a sampled ``K_d(z)`` (Tustin with
optional prewarping, or the exact zero-order-hold equivalent); :func:`export_controller`
discretises, checks (stability of ``K_d``, discretisation error at the crossover, coefficient
dynamic range) and writes JSON, CSV, a C header, a MATLAB ``.mat`` or second-order sections;
:func:`load_controller` reads any of them back. The file layouts are in
:mod:`robustctl.controller_files`.

References
----------
G. F. Franklin, J. D. Powell, M. L. Workman, *Digital Control of Dynamic Systems*, 3rd ed.,
Addison-Wesley 1998: ch. 4 (zero-order-hold equivalent ``Phi = e^{AT}``,
``Gamma = int_0^T e^{A eta} d eta B``) and ch. 6 (Tustin's bilinear rule and prewarping).
C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE TAC 23(3), 1978
(``Phi`` and ``Gamma`` from one exponential of ``[[A, B], [0, 0]] T``).
"""

from __future__ import annotations

import datetime
import html
import warnings
from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg as sla

from . import controller_files as files
from .errors import DataError, ModelError
from .frd import _jsonable, write_atomically
from .lti import as_statespace, freqresp_array
from .table import Table

__all__ = ["discretize", "export_controller", "load_controller", "ExportReport"]

#: relative discretisation error at the crossover above which export_controller warns
ERROR_WARN = 0.1
#: stability margin: |z| of the largest discrete pole must stay below this
MAX_SPECTRAL_RADIUS = 1.0
_METHODS = ("tustin", "zoh")
_BALANCE = ("diagonal", "balanced")


# ---------------------------------------------------------------------------- argument checks
def _positive(value: Any, name: str, fix: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise DataError(f"{name} must be a positive number; got {value!r}. {fix}")
    if not (np.isfinite(value) and value > 0):
        raise DataError(f"{name} must be a positive finite number; got {value!r}. {fix}")
    return float(value)


def _flag(value: Any, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise DataError(f"{name} must be True or False; got {value!r}.")
    return bool(value)


def _choice(value: Any, name: str, options: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value.lower() not in options:
        raise DataError(f"{name} must be one of {', '.join(map(repr, options))}; got {value!r}.")
    return value.lower()


def _unwrap(K: Any) -> tuple[Any, dict]:
    """A synthesis result (anything with ``.K``) -> its controller and design figures."""
    import control

    if isinstance(K, control.StateSpace) or not hasattr(K, "K"):
        return as_statespace(K), {}
    design = {}
    for key, attr in (("gamma", "gamma"), ("mu", "mu_peak")):
        value = getattr(K, attr, None)
        if isinstance(value, (int, float, np.floating)) and np.isfinite(value):
            design[key] = float(value)
    return as_statespace(K.K), design


def _is_discrete(ss: Any) -> bool:
    if ss.dt is True:
        raise ModelError(
            "the controller is discrete with an unspecified sampling time (dt=True); set dt in s."
        )
    return ss.dt not in (0, None)


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
    n, m = B.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = A * T, B * T
    E = sla.expm(big)
    return E[:n, :n], E[:n, n:], C.copy(), D.copy()


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
    import control

    ss, _ = _unwrap(K)
    method = _choice(method, "method", _METHODS)
    if _is_discrete(ss):
        if fs is not None and abs(_positive(fs, "fs", "") * ss.dt - 1.0) > 1e-12:
            raise DataError(
                f"K is already discrete with fs = {1 / ss.dt:.12g} Hz; got fs = {fs!r}. Pass fs=None "
                "(or the same rate): resampling a discrete controller is not supported."
            )
        return ss
    if fs is None:
        raise DataError("fs is required to discretise a continuous controller: pass the sample rate in Hz.")
    fs = _positive(fs, "fs", "Pass the real-time loop's sample rate in Hz.")
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
            f0 = _positive(prewarp_hz, "prewarp_hz", "Give the frequency to match in Hz.")
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
        name=ss.name,
    )


# ---------------------------------------------------------------------------- checks
def _spectral_radius(A: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


def _peak_gain_hz(K: Any, fs: float) -> float:
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


def dynamic_range(*mats: np.ndarray) -> float:
    """``max |coef| / min nonzero |coef|`` over all entries (1 when there is at most one value)."""
    values = np.abs(np.concatenate([np.asarray(m, dtype=float).reshape(-1) for m in mats]))
    values = values[values > 0]
    return float(values.max() / values.min()) if values.size else 1.0


def _balance_diagonal(A, B, C):
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


def _balance_gramian(A, B, C):
    """Balanced realisation of a stable, minimal discrete system (square-root method, Laub et al.
    1987): equal, diagonal controllability and observability Gramians ``P = Q = Sigma``."""
    n = A.shape[0]
    if n == 0:
        return A, B, C
    if _spectral_radius(A) >= 1:
        raise ModelError("balance='balanced' needs a stable discrete controller; use balance='diagonal'.")
    P = sla.solve_discrete_lyapunov(A, B @ B.T)
    Q = sla.solve_discrete_lyapunov(A.T, C.T @ C)
    Lc, Lo = _psd_factor(P), _psd_factor(Q)
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


def _psd_factor(X: np.ndarray) -> np.ndarray:
    w, V = np.linalg.eigh((X + X.T) / 2)
    return V * np.sqrt(np.clip(w, 0, None))


# ---------------------------------------------------------------------------- report
@dataclass(frozen=True, eq=False)
class ExportReport:
    """What :func:`export_controller` wrote and what it checked.

    Attributes
    ----------
    path : pathlib.Path
        The file written.
    format : str
        ``"json"``, ``"csv"``, ``"h"``, ``"mat"`` or ``"sos"``.
    fs_hz : float
        Sample rate, Hz.
    method, prewarp_hz : str or None, float or None
        Discretisation used (None when K was already discrete).
    n_states, n_inputs, n_outputs : int
        Sizes of the exported realisation.
    spectral_radius : float
        Largest ``|z|`` of the discrete poles; ``stable`` is ``spectral_radius < 1``.
    crossover_hz : float or None
        Frequency where the discretisation error was evaluated (the given crossover or the
        frequency of the largest controller gain).
    discretization_error : float or None
        ``||K_d(e^{j w T}) - K(j w)||_2 / ||K(j w)||_2`` there (None when K was discrete).
    dynamic_range, dynamic_range_balanced : float, float or None
        ``max|coef| / min nonzero |coef|`` of A, B, C, D before and after balancing.
    balance : str or None
        ``"diagonal"``, ``"balanced"`` or None.
    sos_error : float or None
        SOS only: max relative deviation of the sections' response from the channel's, over
        frequency.
    channel : tuple of str or None
        SOS only: (output, input) exported.
    gamma, mu : float or None
        The design's figures when K came from a synthesis result.
    controller : control.StateSpace
        The discrete realisation written (the SOS channel for ``.sos``).
    """

    path: Path
    format: str
    fs_hz: float
    method: str | None
    prewarp_hz: float | None
    n_states: int
    n_inputs: int
    n_outputs: int
    spectral_radius: float
    stable: bool
    crossover_hz: float | None
    discretization_error: float | None
    dynamic_range: float
    dynamic_range_balanced: float | None
    balance: str | None
    sos_error: float | None
    channel: tuple[str, str] | None
    gamma: float | None
    mu: float | None
    controller: Any

    def table(self) -> Table:
        """The checks as a two-column table."""
        rows = [
            ("file", str(self.path)),
            ("format", self.format),
            ("fs (Hz)", self.fs_hz),
            ("method", self.method or "already discrete"),
            ("prewarp (Hz)", self.prewarp_hz),
            ("states / inputs / outputs", f"{self.n_states} / {self.n_inputs} / {self.n_outputs}"),
            ("max |pole| (z)", self.spectral_radius),
            ("stable", self.stable),
            ("error evaluated at (Hz)", self.crossover_hz),
            ("relative discretisation error", self.discretization_error),
            ("coefficient dynamic range", self.dynamic_range),
            (f"dynamic range after {self.balance or 'no'} balancing", self.dynamic_range_balanced),
            ("SOS max relative error", self.sos_error),
            ("gamma", self.gamma),
            ("mu peak", self.mu),
        ]
        return Table(("check", "value"), [r for r in rows if r[1] is not None], title="controller export")

    def summary(self) -> str:
        """One paragraph: what was written and whether it is safe to run."""
        err = (
            f"; discretisation error {100 * self.discretization_error:.3g} % at {self.crossover_hz:.4g} Hz"
            if self.discretization_error is not None
            else ""
        )
        dr = f"; coefficient dynamic range {self.dynamic_range:.3g}"
        if self.dynamic_range_balanced is not None:
            dr += f" -> {self.dynamic_range_balanced:.3g} after {self.balance} balancing"
        state = "stable" if self.stable else "UNSTABLE"
        return (
            f"{self.path.name}: {self.n_states}-state {self.n_outputs}x{self.n_inputs} controller at "
            f"{self.fs_hz:g} Hz, {state} (max |z| = {self.spectral_radius:.6f}){err}{dr}."
        )

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __repr__(self) -> str:
        return f"ExportReport({self.summary()})"


# ---------------------------------------------------------------------------- export
def _format(path: Path, format: str | None) -> str:
    if format is None:
        suffix = path.suffix.lower()
        if suffix[1:] not in files.FORMATS:
            raise DataError(
                f"cannot tell the format of {path.name!r} from its extension; use one of "
                f"{', '.join('.' + f for f in files.FORMATS)} or pass format=."
            )
        return suffix[1:]
    fmt = _choice(format, "format", files.FORMATS)
    if path.suffix.lower() != "." + fmt:
        raise DataError(
            f"format={fmt!r} but the file name {path.name!r} ends in {path.suffix!r}; "
            f"name it *.{fmt} so load_controller can read it back."
        )
    return fmt


def _channel(ss: Any, channel: Any) -> tuple[int, int]:
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
        if isinstance(item, str) and item in labels:
            out.append(list(labels).index(item))
        elif isinstance(item, (int, np.integer)) and not isinstance(item, bool) and 0 <= item < len(labels):
            out.append(int(item))
        else:
            raise DataError(f"channel {what} {item!r} is not one of {list(labels)} (or an index).")
    return out[0], out[1]


def _sos(Kd: Any) -> tuple[np.ndarray, float]:
    """Second-order sections of a SISO discrete system and their max relative response error.

    Poles are the eigenvalues of ``A``, zeros the finite generalized eigenvalues of the system
    pencil ``([[A, B], [C, D]], diag(I, 0))``; the gain is the least-squares fit of the
    response on 64 points of the unit circle; then ``scipy.signal.zpk2sos``.
    """
    from scipy.signal import sosfreqz, zpk2sos

    A, B, C, D = (np.asarray(m, dtype=float) for m in (Kd.A, Kd.B, Kd.C, Kd.D))
    n = A.shape[0]
    poles = np.linalg.eigvals(A) if n else np.zeros(0)
    pencil = np.block([[A, B], [C, D]])
    E = np.zeros_like(pencil)
    E[:n, :n] = np.eye(n)
    zeros = sla.eigvals(pencil, E) if n else np.zeros(0)
    zeros = zeros[np.isfinite(zeros) & (np.abs(zeros) < 1e8)]
    f = np.linspace(0.01, 0.49, 64) / Kd.dt
    g = freqresp_array(Kd, f)[:, 0, 0]
    zz = np.exp(2j * np.pi * f * Kd.dt)
    shape = np.prod(zz[:, None] - zeros[None, :], axis=1) / np.prod(zz[:, None] - poles[None, :], axis=1)
    k = float(np.real(np.vdot(shape, g) / np.vdot(shape, shape)))
    sos = zpk2sos(zeros, poles, k) if n else np.array([[float(D[0, 0]), 0, 0, 1, 0, 0]])
    fine = np.linspace(0.0005, 0.4995, 2000) / Kd.dt
    _, h = sosfreqz(sos, worN=2 * np.pi * fine * Kd.dt)
    ref = freqresp_array(Kd, fine)[:, 0, 0]
    return sos, float(np.max(np.abs(h - ref)) / max(np.max(np.abs(ref)), np.finfo(float).tiny))


def _provenance(user: Any) -> dict:
    from . import __version__

    if user is not None and not isinstance(user, dict):
        raise DataError(f"provenance must be a dict of JSON-able values; got {type(user).__name__}.")
    prov = {
        "software": f"robustctl {__version__}",
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
    return {**prov, **_jsonable(user or {})}


def export_controller(
    K: Any,
    path: str | PathLike,
    fs: float | None = None,
    format: str | None = None,
    *,
    method: str = "tustin",
    prewarp_hz: float | None = None,
    overwrite: bool = False,
    provenance: dict | None = None,
    crossover_hz: float | None = None,
    balance: bool | str = False,
    on_unstable: str = "warn",
    units: dict | None = None,
    channel: tuple | None = None,
    prefix: str | None = None,
) -> ExportReport:
    """Discretise ``K``, check it, and write it as a coefficient file.

    Parameters
    ----------
    K : control.StateSpace, a synthesis result with ``.K`` (its ``gamma`` / ``mu_peak`` are
        recorded), or anything :func:`robustctl.lti.as_statespace` accepts
        Continuous (discretised with ``fs``, ``method``, ``prewarp_hz``) or already discrete.
    path : str or path-like
        Output file; an existing file is never replaced unless ``overwrite=True``. Written to a
        temporary file in the same folder and moved into place (no partial files).
    fs : float, optional
        Sample rate in Hz (required for a continuous K).
    format : {"json", "csv", "h", "mat", "sos"}, optional
        Default: from the extension. ``json``: matrices, ``fs``, names, units, method, design
        figures, checks, provenance; ``csv``: one coefficient per line (layout in the file's
        comment header); ``h``: C header with double and float arrays, size macros and an
        inline step function; ``mat``: MATLAB ``A, B, C, D, Ts, InputName, OutputName``
        (``ss(A,B,C,D,Ts)``); ``sos``: second-order sections (scipy.signal layout) of one SISO
        channel.
    method, prewarp_hz
        See :func:`discretize`.
    overwrite : bool
        Replace an existing file.
    provenance : dict, optional
        Your information (project, plant version, author...), stored with ``software`` and
        ``date_utc``.
    crossover_hz : float, optional
        Where to evaluate the discretisation error (Hz, below fs/2). Default: the frequency of
        the controller's largest gain. A relative error above 10 % warns.
    balance : bool or {"diagonal", "balanced"}
        Rescale the states before writing (the transfer function is unchanged). ``True`` or
        ``"diagonal"``: an exact power-of-two diagonal similarity equalising the row/column
        norms of ``[[A, B], [C, 0]]``; ``"balanced"``: the balanced realisation (equal diagonal
        discrete Gramians; stable and minimal K only). Both reported as coefficient dynamic range.
    on_unstable : {"warn", "raise", "ignore"}
        What to do when a discrete pole has ``|z| >= 1`` (an integrator or an unstable design).
    units : dict, optional
        Signal name -> unit (e.g. ``{"accel_1": "m/s^2", "force_1": "N"}``).
    channel : (output, input), optional
        SOS only: the channel of a MIMO controller to export (names or indices).
    prefix : str, optional
        C header only: prefix of the macros and arrays (default: the file stem, upper case).

    Returns
    -------
    ExportReport

    Raises
    ------
    DataError
        Bad argument, existing file, MIMO controller for ``sos`` without ``channel``.
    ModelError
        Unstable discrete controller with ``on_unstable="raise"``; Tustin singular.
    """
    path = _as_path(path)
    fmt = _format(path, format)
    overwrite = _flag(overwrite, "overwrite")
    on_unstable = _choice(on_unstable, "on_unstable", ("warn", "raise", "ignore"))
    method = _choice(method, "method", _METHODS)
    balance = _balance_choice(balance)
    if units is not None and not isinstance(units, dict):
        raise DataError(f"units must be a dict mapping signal names to unit strings; got {units!r}.")
    if channel is not None and fmt != "sos":
        raise DataError(f"channel applies to format 'sos' only; got format {fmt!r}.")
    if prefix is not None and fmt != "h":
        raise DataError(f"prefix applies to format 'h' (C header) only; got format {fmt!r}.")
    ss, design = _unwrap(K)
    was_continuous = not _is_discrete(ss)
    Kd = discretize(ss, fs, method, prewarp_hz)
    fs_hz = 1.0 / Kd.dt
    chan = None
    if fmt == "sos":
        o, i = _channel(Kd, channel)
        ss, Kd = ss[o, i], Kd[o, i]
        chan = (Kd.output_labels[0], Kd.input_labels[0])
    rho = _spectral_radius(np.asarray(Kd.A, dtype=float))
    _stability(rho, on_unstable)
    f_err, err = _error_check(ss, Kd, fs_hz, crossover_hz, was_continuous, method)
    mats = [np.asarray(m, dtype=float) for m in (Kd.A, Kd.B, Kd.C, Kd.D)]
    dr_before, dr_after = dynamic_range(*mats), None
    if balance is not None:
        A, B, C = (_balance_diagonal if balance == "diagonal" else _balance_gramian)(*mats[:3])
        mats = [A, B, C, mats[3]]
        dr_after = dynamic_range(*mats)
    sos, sos_err = _sos(_with(Kd, mats)) if fmt == "sos" else (None, None)
    meta = {
        "discretization": {
            "method": method if was_continuous else None,
            "prewarp_hz": prewarp_hz if was_continuous else None,
        },
        "design": design,
        "checks": {
            "spectral_radius": rho,
            "stable": rho < MAX_SPECTRAL_RADIUS,
            "error_at_hz": f_err,
            "relative_discretization_error": err,
            "dynamic_range": dr_before,
            "balance": balance,
            "dynamic_range_balanced": dr_after,
            "sos_max_relative_error": sos_err,
        },
        "provenance": _provenance(provenance),
    }
    ctrl = files.ControllerData(
        *mats,
        Kd.dt,
        tuple(Kd.input_labels),
        tuple(Kd.output_labels),
        tuple(Kd.state_labels),
        units=_jsonable(units or {}),
        meta=_jsonable(meta),
    )
    writer = files.WRITERS["." + fmt]
    prefix = files.c_prefix(path, prefix) if fmt == "h" else None  # from the final name, not the temp file
    write_atomically(path, lambda tmp: writer(ctrl, tmp, prefix=prefix, sos=sos), overwrite)
    return ExportReport(
        path=path,
        format=fmt,
        fs_hz=fs_hz,
        method=method if was_continuous else None,
        prewarp_hz=prewarp_hz if was_continuous else None,
        n_states=mats[0].shape[0],
        n_inputs=mats[3].shape[1],
        n_outputs=mats[3].shape[0],
        spectral_radius=rho,
        stable=rho < MAX_SPECTRAL_RADIUS,
        crossover_hz=f_err,
        discretization_error=err,
        dynamic_range=dr_before,
        dynamic_range_balanced=dr_after,
        balance=balance,
        sos_error=sos_err,
        channel=chan,
        gamma=design.get("gamma"),
        mu=design.get("mu"),
        controller=ctrl.statespace(),
    )


def _as_path(path: Any) -> Path:
    try:
        return Path(path)
    except TypeError:
        raise DataError(f"path must be a file name (str or path-like); got {type(path).__name__}.") from None


def _balance_choice(balance: Any) -> str | None:
    if isinstance(balance, (bool, np.bool_)):
        return "diagonal" if balance else None
    return _choice(balance, "balance", _BALANCE)


def _stability(rho: float, on_unstable: str) -> None:
    if rho < MAX_SPECTRAL_RADIUS or on_unstable == "ignore":
        return
    msg = (
        f"the discrete controller has a pole with |z| = {rho:.6g} >= 1 (not asymptotically stable); "
        "check the design, or pass on_unstable='ignore' if that is intended (e.g. an integrator)."
    )
    if on_unstable == "raise":
        raise ModelError(msg)
    warnings.warn(msg, RuntimeWarning, stacklevel=3)


def _error_check(K, Kd, fs_hz: float, crossover_hz: Any, was_continuous: bool, method: str):
    if crossover_hz is not None:
        crossover_hz = _positive(crossover_hz, "crossover_hz", "Give the loop's crossover in Hz.")
        if crossover_hz >= fs_hz / 2:
            raise DataError(
                f"crossover_hz = {crossover_hz:g} Hz must lie below the Nyquist frequency "
                f"{fs_hz / 2:g} Hz; raise fs."
            )
    if not was_continuous:
        return crossover_hz, None
    f = crossover_hz if crossover_hz is not None else _peak_gain_hz(K, fs_hz)
    err = discretization_error(K, Kd, f)
    if err > ERROR_WARN:
        fix = (
            "raise fs or prewarp there (prewarp_hz=)"
            if method == "tustin"
            else "raise fs or use method='tustin'"
        )
        warnings.warn(
            f"the discretised controller differs from K by {100 * err:.3g} % at {f:.4g} Hz; {fix}.",
            RuntimeWarning,
            stacklevel=3,
        )
    return f, err


def _with(Kd: Any, mats: list[np.ndarray]):
    import control

    return control.ss(*mats, Kd.dt, inputs=list(Kd.input_labels), outputs=list(Kd.output_labels))


def load_controller(path: str | PathLike):
    """Read a controller written by :func:`export_controller` (or a user's ``.mat`` with A, B, C, D, Ts).

    Parameters
    ----------
    path : str or path-like
        ``.json``, ``.csv``, ``.mat``, ``.h`` (the header layout written by
        :func:`export_controller`) or ``.sos`` (returned as a cascade realisation of the sections).

    Returns
    -------
    control.StateSpace
        Discrete with ``dt = 1/fs`` (continuous, dt = 0, when a ``.mat``/``.json`` says Ts = 0),
        with the stored signal names.

    Raises
    ------
    DataError
        Missing file, unknown extension, or content that is corrupt or inconsistent (the
        message names the field).
    """
    path = _as_path(path)
    reader = files.READERS.get(path.suffix.lower())
    if reader is None:
        raise DataError(
            f"cannot read {path.name!r}: supported extensions are "
            f"{', '.join('.' + f for f in files.FORMATS)}."
        )
    if not path.is_file():
        raise DataError(f"cannot load {str(path)!r}: no such file.")
    try:
        return reader(path).statespace()
    except DataError as exc:
        raise DataError(f"{path.name}: {exc}") from exc
