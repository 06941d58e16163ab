"""What the H1 (Welch) estimator makes of a system: its expected estimate, window statistics.

A Welch H1 estimate (:func:`robustctl.estimate_frf`) of a system excited by a white,
zero-order-held (ZOH) input has the exact expected value

    E[H1](theta) = sum_{k=0}^{N-1} h[k] r_w[k] / r_w[0] exp(-j theta k),   theta = 2 pi f / fs,

with ``h`` the sampled (ZOH) impulse response and ``r_w[k] = sum_n w[n] w[n+k]`` the
autocorrelation of the ``N``-point window: the estimator sees the impulse response through a
lag window. Lightly damped modes whose impulse response outlives the window look broadened
(window leakage; with 200 Hz and 4096-point Hamming windows a 1.8 %-damped mode at 1.17 Hz
looks about 50 % more damped), and the ZOH adds a half-sample delay and a sinc droop.

This module is shared by ``identify`` (the leakage correction of a measurement model) and
``correlate`` (compare/update/diagnose see a physical model "as the estimator sees it"), so
neither imports the other. It also holds the window statistics the noise model needs:
Welch's (1967) effective number of averages of overlapped segments and the correlation of
the estimates at neighbouring frequency bins.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from typing import Any

import control
import numpy as np
import scipy.linalg as sla

from ..errors import DataError
from ..frd import PLAIN_NOTE, Experiment
from ..lti import as_statespace, freqresp, zoh
from ..threads import limit_blas
from .impact_view import TruncationSettings, expected_h1_impact_modal, on_record_bins, truncation_settings

__all__ = [
    "EstimatorSettings",
    "estimator_settings",
    "hold_response",
    "lag_window",
    "expected_h1",
    "expected_h1_modal",
    "estimator_view",
    "effective_averages",
    "bin_correlation",
    "HOLD_TAG",
    "resolve_estimator",
    "resolve_view",
    "split_hold",
    "model_view",
    "welch_window",
    "MAX_NPERSEG",
    "expected_h1_measured",
    "sampled_hold_response",
    "discrete_view",
    "experiment_view",
    "impact_settings",
    "expected_h1_impact",
]

#: tag of the zero-order-hold stage (:func:`robustctl.physical.electronics.zero_order_hold_stage`)
HOLD_TAG = "zero_order_hold"


class EstimatorSettings(tuple):
    """``(fs_hz, nperseg, window)`` of a Welch H1 estimate, plus optional ``noverlap``.

    ``input_kind`` says how the input reached the structure: ``"held"`` (a DAC command through
    a zero-order hold: the sampled experiment is exact, aliasing included) or ``"measured"`` (a
    measured continuous force or voltage: the band-limited response, no hold, no aliasing).
    ``leakage`` (random excitation with known Welch settings) applies the window's lag window;
    without it a held input is seen through the exact sampled response alone (periodic
    excitation with whole periods, stepped sine). The defaults are the held, random view.

    ``impact`` (an impact test, :func:`robustctl.estimate_frf_impact`): the model is seen through
    the exponential window of time constant ``exp_tau_s`` (s; None: none) and, when ``record``
    (:class:`~robustctl.measure.impact_view.TruncationSettings`) is known, the record end
    (eq. W2 of :mod:`robustctl.measure.impact_view`).
    """

    def __new__(cls, values: tuple, noverlap: int | None = None, hold_divided: bool = False,
                input_kind: str = "held", leakage: bool = True, *, impact: bool = False,
                exp_tau_s: float | None = None, record: TruncationSettings | None = None):
        obj = super().__new__(cls, values)
        obj.noverlap = noverlap
        obj.hold_divided = hold_divided
        if input_kind not in ("held", "measured"):
            raise DataError(f"input_kind must be 'held' or 'measured'; got {input_kind!r}.")
        obj.input_kind = input_kind
        obj.leakage = bool(leakage)
        obj.impact = bool(impact)
        obj.exp_tau_s = None if exp_tau_s is None else float(exp_tau_s)
        obj.record = record
        return obj

    def __reduce__(self):
        return (_rebuild_settings, (tuple(self), self.noverlap, self.hold_divided, self.input_kind,
                                    self.leakage, self.impact, self.exp_tau_s, self.record))

    def __eq__(self, other: Any) -> bool:
        same = tuple.__eq__(self, other)
        if same is not True or not isinstance(other, EstimatorSettings):
            return same
        mine = (self.input_kind, self.leakage, self.hold_divided, self.impact, self.exp_tau_s, self.record)
        return mine == (other.input_kind, other.leakage, other.hold_divided, other.impact, other.exp_tau_s,
                        other.record)

    def __hash__(self) -> int:
        return tuple.__hash__(self)

    @property
    def fs_hz(self) -> float:
        return self[0]

    @property
    def nperseg(self) -> int:
        return self[1]

    @property
    def window(self) -> Any:
        return self[2]

    def describe(self) -> str:
        """``"4096-pt hamming at 200 Hz"`` (held, random: the legacy wording), else with what is applied:
        ``"window leakage of 2048-pt hamming at 200 Hz, measured input (no hold)"``."""
        if self.impact:
            return _describe_impact(self)
        if not self.leakage:
            return f"the sampled zero-order-hold response at {self.fs_hz:g} Hz (no window leakage)"
        win = self.window if isinstance(self.window, str) else str(self.window)
        if isinstance(self.window, tuple) and self.window and self.window[0] == USER_WINDOW:
            win = USER_WINDOW
        text = f"{self.nperseg}-pt {win} at {self.fs_hz:g} Hz"
        if self.input_kind == "measured":
            return f"window leakage of {text}, measured input (no hold)"
        return text


def _rebuild_settings(values, noverlap, hold_divided, input_kind, leakage, impact, exp_tau_s, record):
    return EstimatorSettings(values, noverlap, hold_divided, input_kind, leakage, impact=impact,
                             exp_tau_s=exp_tau_s, record=record)


def _describe_impact(st: EstimatorSettings) -> str:
    """``"the impact H1 with its exponential window (tau = 0.2 s: poles moved by -5 1/s) and the
    record end (0.5 s)"``."""
    parts = []
    if st.exp_tau_s is not None:
        parts.append(f"its exponential window (tau = {st.exp_tau_s:.4g} s: poles moved by "
                     f"-{1.0 / st.exp_tau_s:.4g} 1/s)")
    if st.record is not None:
        parts.append(f"the record end ({st.record.record_s:.4g} s)")
    return "the impact H1 with " + " and ".join(parts)


def impact_settings(experiment: Experiment, meta: Mapping[str, Any] | None, f_hz: Any = None
                    ) -> tuple[EstimatorSettings | None, str]:
    """What an impact test's description establishes: ``(settings or None, why not)``.

    The exponential window (``experiment.exp_window_tau_s``) and, when the data record the hits
    (``meta`` of :func:`robustctl.estimate_frf_impact`: ``n_samples``, ``hit_times_s``,
    ``hit_weights``) and ``f_hz`` are the record's DFT bins, the record end (eq. W2 of
    :mod:`robustctl.measure.impact_view`), else, for a file that states its ``fs_hz`` and
    ``pretrigger_s``, one hit at ``pretrigger_s`` in a record as long as one over the bins'
    spacing. A recorded ``meta["exp_window_tau_s"]`` counts as stated when the description is
    silent; two different values are refused.
    """
    tau = experiment.exp_window_tau_s
    recorded = meta.get("exp_window_tau_s") if isinstance(meta, Mapping) else None
    if recorded is not None:
        ok = isinstance(recorded, (int, float, np.integer, np.floating)) and not isinstance(recorded, bool)
        if not ok or not (np.isfinite(recorded) and recorded > 0):
            raise _settings_error("exp_window_tau_s", recorded, "a positive, finite time constant in s")
        recorded = float(recorded)
        if tau is not None and not np.isclose(recorded, tau, rtol=1e-9, atol=0.0):
            raise DataError(
                f"the experiment states an exponential window tau = {tau:g} s but data.meta records "
                f"exp_window_tau_s = {recorded:g} s; correct one of them (data.replace(...))."
            )
        tau = recorded
    record = truncation_settings(meta)
    if record is None:
        record = _described_record(experiment, f_hz)
    if record is not None and f_hz is not None and not on_record_bins(f_hz, record):
        record = None
    if tau is None and record is None:
        return None, "impact excitation without an exponential window or a recorded record length"
    fs = experiment.fs_hz if experiment.fs_hz is not None else (record.fs_hz if record else None)
    n = None if record is None else int(round(record.record_s * record.fs_hz))
    st = EstimatorSettings((fs, n, "exponential" if tau is not None else "boxcar"), None, False, "measured",
                           False, impact=True, exp_tau_s=tau, record=record)
    return st, ""


def _described_record(e: Experiment, f_hz: Any) -> TruncationSettings | None:
    """The record of a described impact test: one hit at ``pretrigger_s`` (s) in a record of
    ``1 / df`` s (``df`` the spacing of the DFT bins ``f_hz``, Hz) sampled at ``fs_hz``; None when
    any of them is unknown."""
    if e.pretrigger_s is None or e.fs_hz is None or f_hz is None:
        return None
    f = np.asarray(f_hz, dtype=float)
    if f.size < 2:
        return None
    df = float(np.min(np.diff(f)))
    if not df > 0 or e.pretrigger_s >= 1.0 / df:
        return None
    return TruncationSettings(e.fs_hz, 1.0 / df, (e.pretrigger_s,), (1.0,))


def estimator_settings(meta: Mapping[str, Any] | None) -> EstimatorSettings | None:
    """Settings recorded by :func:`robustctl.estimate_frf` in ``FrequencyData.meta``, or None.

    Data joined by ``combine_experiments`` carries them per experiment; they are used when
    every experiment agrees. Data marked ``meta["leakage_corrected"]`` (a measurement model's
    corrected data) have none: the estimator's effects are gone. ``meta["hold_divided"]`` (set by
    :func:`robustctl.examples.make_experiment`) records that the estimate was divided by the
    zero-order hold's response.
    """
    if not isinstance(meta, Mapping) or meta.get("leakage_corrected"):
        return None  # data already corrected for the estimator (rc.fit_measurement_model's)
    subs = meta.get("experiments")
    hold = bool(meta.get("hold_divided", False))
    if subs and "fs_hz" not in meta:
        found = {estimator_settings(m) for m in subs if isinstance(m, Mapping)}
        if len(found) != 1 or None in found:
            return None
        one = found.pop()
        return EstimatorSettings(tuple(one), one.noverlap, hold or one.hold_divided)
    if not all(key in meta for key in ("fs_hz", "nperseg", "window")):
        return None  # not a Welch estimate's record (a user's file, an impact test ...)
    fs = _recorded_fs(meta["fs_hz"])
    window, n, nov = welch_window(meta)
    return EstimatorSettings((fs, n, window), nov, hold)


#: Longest Welch window accepted from recorded settings (samples): the estimator's view of a
#: model costs a few FFTs of twice this length, so a damaged ``nperseg`` cannot exhaust memory.
MAX_NPERSEG = 2**22
#: ``meta["window"]`` of an estimate made with a window array; its values are in ``window_values``.
USER_WINDOW = "user array"


def _settings_error(key: str, value: Any, want: str) -> DataError:
    return DataError(
        f"data.meta[{key!r}] = {value!r} is not a usable H1 estimator setting ({want}); the record is "
        "damaged. Repair or remove the key (data.replace(meta=...)): data without fs_hz, nperseg and "
        "window are used without the estimator's view."
    )


def _recorded_int(value: Any, key: str, lo: int, hi: int) -> int:
    ok = isinstance(value, (int, np.integer)) or (isinstance(value, float) and value.is_integer())
    if not ok or isinstance(value, (bool, np.bool_)) or not lo <= value <= hi:
        raise _settings_error(key, value, f"an integer in [{lo}, {hi}]")
    return int(value)


def _recorded_fs(value: Any) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not ok or not (np.isfinite(value) and value > 0):
        raise _settings_error("fs_hz", value, "a positive, finite sampling frequency in Hz")
    return float(value)


def welch_window(meta: Mapping[str, Any]) -> tuple[Any, int, int | None]:
    """``(window, nperseg, noverlap or None)`` recorded in ``meta``, checked.

    The window is a ``scipy.signal.get_window`` spec (a name or a tuple), or for an estimate
    made with a window array ``("user array", w_0, ..., w_{N-1})`` from ``meta["window_values"]``.

    Raises
    ------
    DataError
        A value that no estimate could have recorded (a damaged or hand-edited record), naming
        the key; or a window array whose values were not recorded.
    """
    n = _recorded_int(meta["nperseg"], "nperseg", 2, MAX_NPERSEG)
    nov = meta.get("noverlap")
    if nov is not None:
        nov = _recorded_int(nov, "noverlap", 0, n - 1)
    win = meta["window"]
    if isinstance(win, list):
        win = tuple(win)
    if win == USER_WINDOW:
        values = meta.get("window_values")
        try:
            arr = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if values is None or arr.size != n or not np.all(np.isfinite(arr)):
            raise _settings_error(
                "window", win, f"a window array needs its {n} values in data.meta['window_values']"
            )
        return (USER_WINDOW, *arr.tolist()), n, nov
    named = isinstance(win, str) or (isinstance(win, tuple) and bool(win) and isinstance(win[0], str))
    if not named:
        raise _settings_error("window", win, "a scipy.signal.get_window name or (name, parameter) tuple")
    try:
        window_values(win, n, " in the estimator settings")
    except DataError as exc:
        raise _settings_error("window", win, f"a scipy.signal.get_window spec; {exc}") from None
    return win, n, nov


def hold_response(f_hz: Any, fs: float) -> np.ndarray:
    """Frequency response of a zero-order hold, ``(1 - e^{-sT}) / (sT)`` at ``s = j 2 pi f``.

    ``T = 1 / fs`` (s): a delay of half a sample and a sinc droop
    (Franklin, Powell & Workman, *Digital Control*, sec. 4.3.4).
    """
    x = 2j * np.pi * np.asarray(f_hz, dtype=float) / float(fs)
    return (1.0 - np.exp(-x)) / x


def window_values(window: Any, n: int, where: str = "") -> np.ndarray:
    """The ``n`` values of a Welch window: the one window lookup of robustctl.

    Parameters
    ----------
    window : str, tuple
        A ``scipy.signal.get_window`` spec (a name or ``(name, parameter)``; the periodic
        window, as Welch averaging uses), or a recorded user array ``(USER_WINDOW, w0, w1, ...)``.
    n : int
        Segment length ``nperseg``, samples.
    where : str
        Where the spec came from, for the error (e.g. ``" in the estimator settings"``).

    Returns
    -------
    ndarray (n,)

    Raises
    ------
    DataError
        An unknown window, or a recorded array of another length.
    """
    from scipy.signal import get_window

    if isinstance(window, tuple) and window and window[0] == USER_WINDOW:
        values = np.asarray(window[1:], dtype=float)
        if values.size != n:
            raise DataError(f"the recorded window array has {values.size} values, not nperseg = {n}.")
        return values
    try:
        return get_window(window, n, fftbins=True)
    except (ValueError, TypeError) as exc:
        raise DataError(f"unknown window {window!r}{where}: {exc}. Use e.g. 'hamming' or 'hann'.") from exc


def lag_window(window: Any, n: int) -> np.ndarray:
    """``r_w[k] / r_w[0]``, k = 0..n-1: the normalised autocorrelation of the window."""
    return _lag_window_cached(window, int(n)).copy()


@lru_cache(maxsize=16)
def _lag_window_cached(window: Any, n: int) -> np.ndarray:
    w = window_values(window, n, " in the estimator settings")
    spec = np.fft.rfft(w, 2 * n)
    r = np.fft.irfft(np.abs(spec) ** 2, 2 * n)[:n]
    return r / r[0]


def effective_averages(n_averages: int, window: Any, nperseg: int, noverlap: int | None) -> float:
    """Welch's (1967) effective number of independent averages of overlapped segments.

    ``var ratio = (1/K) [1 + 2 sum_{j=1}^{K-1} (1 - j/K) c(j S)^2]`` with ``S`` the step
    between segments and ``c(l) = sum_n w[n] w[n+l] / sum_n w[n]^2`` the window's overlap
    correlation (Welch 1967, eq. 12; Harris 1978); the result is ``1 / var ratio``.
    """
    k = int(n_averages)
    if k <= 1 or noverlap is None or noverlap <= 0:
        return float(max(k, 1))
    step = int(nperseg) - int(noverlap)
    r = lag_window(window, int(nperseg))
    j = np.arange(1, k)
    lags = j * step
    c = np.where(lags < nperseg, r[np.minimum(lags, nperseg - 1)], 0.0)
    ratio = (1.0 + 2.0 * np.sum((1.0 - j / k) * c**2)) / k
    return float(1.0 / ratio)


def bin_correlation(window: Any, nperseg: int, max_lag: int = 4) -> np.ndarray:
    """Correlation of the H1 estimation errors at bins 0..max_lag apart.

    The windowed DFT of white noise at bins ``m`` apart has the correlation
    ``rho_m = sum_n w[n]^2 e^{-j 2 pi m n / N} / sum_n w[n]^2``; the H1 error is a product
    of the noise and input spectra (``N U* / |U|^2``), so its correlation is ``|rho_m|^2``
    (1 at lag 0). Hamming, 4096 points: 0.39 at one bin, 0.018 at two.
    """
    w2 = window_values(window, int(nperseg), " in the estimator settings") ** 2
    spec = np.fft.fft(w2)
    rho = np.abs(spec[: max_lag + 1]) / abs(spec[0])
    return rho**2


# ---------------------------------------------------------------------------- expected H1
def _modal(sys: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Poles, residues (n, n_out, n_in) and D of a state space, or None when defective.

    A second-order modal form (:func:`_second_order_modal`, what ``modal_dynamics`` builds) is
    decomposed mode by mode in closed form; any other by ``eig`` with a conditioning check."""
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    if A.size == 0:
        return np.zeros(0, complex), np.zeros((0,) + D.shape, complex), D
    fast = _second_order_modal(A, B, C)
    if fast is not None:
        return fast[0], fast[1], D
    lam, V = np.linalg.eig(A)
    lu = sla.lu_factor(V, check_finite=False)
    # the 1-norm condition number from the LU (LAPACK zgecon, O(n^2)); an SVD costs more than eig
    rcond, info = sla.lapack.zgecon(lu[0], float(np.max(np.sum(np.abs(V), axis=0))), norm="1")
    if info != 0 or not rcond * 1e10 >= 1.0:
        return None
    W = sla.lu_solve(lu, B.astype(complex), check_finite=False)
    CV = C @ V
    res = np.einsum("ok,ki->koi", CV, W)
    return lam, res, D


#: Smallest relative separation ``|lambda_+ - lambda_-| / |lambda|`` of a mode's two poles for the
#: closed-form decomposition (a nearly critically damped or rigid mode goes to ``eig``).
_DISTINCT_POLES = 1e-6


def _second_order_modal(A: np.ndarray, B: np.ndarray, C: np.ndarray):
    """Poles and residues of ``A = [[0, I], [-diag(w^2), -diag(c)]]`` (modal coordinates ``q`` and
    their rates), or None for any other ``A``.

    Mode ``k`` is ``(C_q[:, k] + C_v[:, k] s) B_v[k] / (s^2 + c_k s + w_k^2)``: poles
    ``lambda = (-c +- sqrt(c^2 - 4 w^2)) / 2`` and residue ``(C_q + C_v lambda) B_v / (lambda - lambda')``
    at each (the partial fractions of a second-order system), so the decomposition costs
    ``O(n)`` instead of a dense eigenproblem and its condition number."""
    n2 = A.shape[0]
    if n2 % 2 or n2 < 2 or not np.all(B[: n2 // 2] == 0):
        return None
    n = n2 // 2
    k_diag, c_diag = np.diag(A[n:, :n]).copy(), np.diag(A[n:, n:]).copy()
    structured = (
        not np.any(A[:n, :n]) and np.array_equal(A[:n, n:], np.eye(n))
        and np.array_equal(A[n:, :n], np.diag(k_diag)) and np.array_equal(A[n:, n:], np.diag(c_diag))
    )
    if not structured:
        return None
    w2, c = -k_diag, -c_diag
    root = np.sqrt((c * c - 4.0 * w2).astype(complex))
    lam_p, lam_m = (-c + root) / 2.0, (-c - root) / 2.0
    scale = np.maximum(np.abs(lam_p), np.abs(lam_m))
    if np.any(np.abs(lam_p - lam_m) <= _DISTINCT_POLES * np.maximum(scale, 1e-300)):
        return None
    cq, cv, bv = C[:, :n], C[:, n:], B[n:]
    poles = np.concatenate([lam_p, lam_m])
    res = np.concatenate([
        np.einsum("ok,ki->koi", cq + cv * lam_p[None], bv.astype(complex)) / (lam_p - lam_m)[:, None, None],
        np.einsum("ok,ki->koi", cq + cv * lam_m[None], bv.astype(complex)) / (lam_m - lam_p)[:, None, None],
    ])
    return poles, res


def _zoh_impulse_modal(poles, residues, d, fs: float, n: int) -> np.ndarray:
    """Sampled ZOH impulse response ``h[k]`` (n, n_out, n_in): ``h[0] = D``, ``h[k] = C Ad^(k-1) Bd``.

    Poles and residues form conjugate-closed sets (or real ones); the sum is real.
    """
    t = 1.0 / fs
    h = np.zeros((n,) + np.shape(d))
    h[0] = d
    if len(poles) == 0:
        return h
    poles = np.asarray(poles, dtype=complex)
    flat = np.asarray(residues).reshape(len(poles), -1)
    # one pole of each conjugate pair (x 2) and the real poles: the sum is real
    upper = poles.imag > 0
    real = poles.imag == 0
    keep = upper | real
    poles, flat = poles[keep], flat[keep] * np.where(upper[keep], 2.0, 1.0)[:, None]
    zp = np.exp(poles * t)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(np.abs(poles) > 0, (zp - 1.0) / poles, t)
    # zp**k, k = 0..n-2, by a running product (|zp| < 1 for stable poles: no overflow), each
    # pole's along a contiguous row (numpy's running product down the columns of a broadcast
    # array is several times slower, with the same products)
    powers = np.empty((zp.size, n - 1), dtype=complex)
    powers[:, 0] = 1.0
    if n > 2:
        np.cumprod(np.broadcast_to(zp[:, None], (zp.size, n - 2)), axis=1, out=powers[:, 1:])
    seq = np.empty((n - 1, zp.size), dtype=complex)
    np.multiply(powers.T, gain[None, :], out=seq)
    h[1:] = np.real(seq @ flat).reshape((n - 1,) + np.shape(d))
    return h


def _zoh_impulse_loop(sys: Any, fs: float, n: int) -> np.ndarray:
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    Ad, X = zoh(A, B, 1.0 / fs)
    h = np.zeros((n,) + D.shape)
    h[0] = D
    for k in range(1, n):
        h[k] = C @ X
        X = Ad @ X
    return h


def windowed_spectrum(h: np.ndarray, f_hz: np.ndarray, settings: EstimatorSettings) -> np.ndarray:
    """The expected H1 of a sampled impulse response: ``sum_k h[k] r_w[k]/r_w[0] e^{-j theta k}``.

    The one kernel behind every expected H1 (module docstring of
    :mod:`robustctl.identify.leakage`): the lag window (:func:`lag_window`) on ``h``, then the
    DFT at the bins (``f_hz`` on the ``fs / N`` grid) or the direct DTFT off the grid.

    Parameters
    ----------
    h : ndarray (N, n_out, n_in)
        Sampled (ZOH) impulse response, ``N = settings.nperseg``.
    f_hz : ndarray (K,)
        Frequencies, Hz, not above Nyquist.
    settings : EstimatorSettings
        Sampling rate, segment length and window of the estimate.

    Returns
    -------
    ndarray (K, n_out, n_in), complex
    """
    fs, n, window = settings
    f = np.asarray(f_hz, dtype=float)
    if np.any(f > fs / 2 * (1 + 1e-12)):
        raise DataError(f"frequencies must not exceed the Nyquist frequency {fs / 2:g} Hz of the estimate.")
    h = h * lag_window(window, n)[:, None, None]
    bins = f * n / fs
    idx = np.rint(bins).astype(int)
    if np.allclose(bins, idx, atol=1e-6):
        return np.fft.rfft(h, n, axis=0)[idx]
    phase = np.exp(-2j * np.pi * np.outer(f / fs, np.arange(n)))  # off-grid: direct DTFT
    return np.einsum("fk,koi->foi", phase, h)


@limit_blas
def expected_h1_modal(poles, residues, d, f_hz: Any, settings: EstimatorSettings) -> np.ndarray:
    """Expected H1 of ``sum_k residue_k / (s - pole_k) + d`` at ``f_hz`` (Hz); (K, n_out, n_in).

    ``poles`` are closed under conjugation (every complex pole with its conjugate) or hold one
    pole of each pair, the one with ``Im p > 0`` (as :class:`robustctl.identify.RationalFit`
    keeps them): the sum runs over the upper poles, twice, and the real ones. The one ZOH
    impulse sum behind every expected H1 of a pole-residue model.
    """
    h = _zoh_impulse_modal(poles, residues, np.asarray(d, dtype=float), settings.fs_hz, settings.nperseg)
    return windowed_spectrum(h, f_hz, settings)


@limit_blas
def expected_h1(sys: Any, f_hz: Any, settings: EstimatorSettings) -> np.ndarray:
    """Expected H1 estimate of a continuous state space at ``f_hz`` (Hz) for white ZOH excitation.

    The system (anything :func:`robustctl.as_statespace` accepts) is diagonalised, or
    sampled step by step when its modes are defective.

    Returns
    -------
    ndarray, complex, shape (K, n_out, n_in)
    """
    ss = as_statespace(sys)
    modal = _modal(ss)
    if modal is not None:
        return expected_h1_modal(*modal, f_hz, settings)
    return windowed_spectrum(_zoh_impulse_loop(ss, settings.fs_hz, settings.nperseg), f_hz, settings)


@limit_blas
def expected_h1_impact(sys: Any, f_hz: Any, settings: EstimatorSettings) -> np.ndarray:
    """Expected impact H1 of a continuous system (eq. W2 of :mod:`robustctl.measure.impact_view`):
    the system at ``s + 1/tau`` minus the record end's tail of every pole.

    A system whose modes are defective (rigid-body double poles) is evaluated at ``s + 1/tau``
    through its shifted state matrix ``A - I/tau`` without the tail.

    Returns
    -------
    ndarray, complex, shape (K, n_out, n_in)
    """
    ss = as_statespace(sys)
    f = np.asarray(f_hz, dtype=float)
    modal = _modal(ss)
    if modal is not None:
        return expected_h1_impact_modal(*modal, f, settings.exp_tau_s, settings.record)
    if settings.exp_tau_s is None:
        return freqresp(ss, f).response
    import control

    A = np.asarray(ss.A, dtype=float) - np.eye(ss.nstates) / settings.exp_tau_s
    return freqresp(control.ss(A, ss.B, ss.C, ss.D), f).response


def _lagged_spectrum(two_sided: np.ndarray, f_hz: np.ndarray, settings: EstimatorSettings) -> np.ndarray:
    """``sum_{|m| < N} h[m] r_w[|m|] / r_w[0] e^{-j theta m}`` at ``f_hz``; ``two_sided`` has length 2N,
    lag m >= 0 at index m and lag -m at index 2N - m."""
    fs, n, window = settings
    f = np.asarray(f_hz, dtype=float)
    if np.any(f > fs / 2 * (1 + 1e-12)):
        raise DataError(f"frequencies must not exceed the Nyquist frequency {fs / 2:g} Hz of the estimate.")
    lag = lag_window(window, n)
    w2 = np.concatenate([lag, [0.0], lag[:0:-1]])
    h = two_sided * w2[:, None, None]
    bins = f * n / fs
    idx = np.rint(bins).astype(int)
    if np.allclose(bins, idx, atol=1e-6):
        return np.fft.rfft(h, 2 * n, axis=0)[2 * idx]  # h is real; 2 idx <= n below Nyquist
    m = np.concatenate([np.arange(n), np.arange(-n, 0)])
    phase = np.exp(-2j * np.pi * np.outer(f / fs, m))
    return np.einsum("fk,koi->foi", phase, h)


#: Oversampling of the Nyquist interval for the smooth part of the measured-input view.
_GRID_FACTOR = 4
#: Rows of the fine grid computed at a time (the temporaries of a chunk stay in cache).
_GRID_CHUNK = 1024
#: Poles at least this many times the Nyquist frequency (in modulus) above it enter the
#: measured-input view through their power series (:func:`_far_pole_series`) ...
_FAR_POLE = 4.0
#: ... summed to this order: each pole's truncation error is at most
#: ``|r / p| (1 / _FAR_POLE)^(order + 1) / (1 - 1 / _FAR_POLE)``, 2e-13 of its static response.
_FAR_ORDER = 21


def _far_pole_series(omega: np.ndarray, poles: np.ndarray, flat: np.ndarray, omega_max: float,
                     second: bool = False) -> Any:
    """``sum_p r_p / (j omega - p)`` for poles far beyond ``|omega| <= omega_max`` (rad/s), by the
    geometric series ``-sum_k (j omega)^k sum_p r_p / p^(k+1)``: the residues are summed once per
    power, so the cost is ``_FAR_ORDER`` columns instead of one per pole. Terms are scaled by
    ``omega_max^k`` (``|j omega / omega_max| <= 1``); shape ``(omega.size, flat.shape[1])``.
    ``second=True`` also returns its second derivative in ``omega``, the series differentiated
    term by term."""
    inv = 1.0 / poles
    coef = np.empty((_FAR_ORDER + 1, flat.shape[1]), complex)
    term = inv.copy()  # omega_max^k / p^(k+1)
    for k in range(_FAR_ORDER + 1):
        coef[k] = term @ flat
        term = term * (omega_max * inv)
    x = 1j * np.asarray(omega, dtype=float) / omega_max
    powers = np.cumprod(np.concatenate([np.ones((x.size, 1), complex),
                                        np.broadcast_to(x[:, None], (x.size, _FAR_ORDER))], axis=1), axis=1)
    value = -(powers @ coef)
    if not second:
        return value
    k = np.arange(2, _FAR_ORDER + 1)
    # d^2/domega^2 (j omega / omega_max)^k = -k (k - 1) / omega_max^2 (j omega / omega_max)^(k - 2)
    return value, (powers[:, : k.size] @ (coef[2:] * (k * (k - 1))[:, None])) / omega_max**2


#: The local form of the measured-input view (:func:`_measured_local`) is used when the window's
#: ends are this close to zero: ``n (w[0]^2 + w[n-1]^2) / (2 sum w^2)``, the weight of the lag
#: window's kink at lag 0 over the segment (Hann 4e-13, Blackman 3e-12; Hamming 0.016, boxcar 1).
_SMOOTH_ENDS = 1e-7
#: ... and every frequency is at most this fraction of the Nyquist frequency (the jump of the alias
#: sum at the Nyquist frequency stays out of the window's main lobe by 10 % of the band).
_LOCAL_MAX_NYQUIST = 0.9
#: Lags per block of the exact time sequence ``e^{p T m}`` (powers by blocks: two small ``exp``
#: tables and one product instead of an ``exp`` per lag and pole).
_POWER_BLOCK = 64


@lru_cache(maxsize=16)
def _lag_curvature(window: Any, n: int) -> float | None:
    """``c2`` of the lag window near lag 0, ``r_w[m] / r_w[0] = 1 - c2 m^2 + O(|m|^3)``, or None when
    the window's ends are not zero (:data:`_SMOOTH_ENDS`): its lag window then has a kink
    ``-c1 |m|`` whose effect on a smooth response is not local (Hamming, boxcar).

    ``c2`` is fitted to the lags 1..3 with the cubic term (``1 - r[m] = c1 m + c2 m^2 + c3 m^3``);
    Hann, 4096 points: 3.92184e-7 against ``2 pi^2 / (3 N^2)`` = 3.92183e-7 of the continuous window."""
    w = window_values(window, n, " in the estimator settings")
    kink = n * (w[0] ** 2 + w[-1] ** 2) / (2.0 * float(np.sum(w * w)))
    if not kink <= _SMOOTH_ENDS or n < 8:
        return None
    r = _lag_window_cached(window, n)
    m = np.arange(1.0, 4.0)
    c = np.linalg.solve(np.stack([m, m**2, m**3], axis=1), 1.0 - r[1:4])
    return float(c[1])


def _powers(z_log: np.ndarray, n: int) -> np.ndarray:
    """``exp(m z_log)`` for ``m = 0..n-1`` (n, len(z_log)): ``exp`` of whole blocks of
    :data:`_POWER_BLOCK` lags times ``exp`` of the lags inside a block (rounding 1e-15)."""
    b = _POWER_BLOCK
    inner = np.exp(np.outer(np.arange(b), z_log))
    outer = np.exp(np.outer(np.arange(0, n, b), z_log))
    return (outer[:, None, :] * inner[None, :, :]).reshape(-1, z_log.size)[:n]


def _measured_local(poles: np.ndarray, flat: np.ndarray, D: np.ndarray, f: np.ndarray,
                    settings: EstimatorSettings, c2: float) -> np.ndarray:
    """The measured-input view by its local form (:func:`expected_h1_measured`).

    ``h = h_ii - a + h_above``: the poles below the Nyquist frequency as the exact one-sided
    sequence ``h_ii[m] = T r e^{p T m}`` (halved at ``m = 0``), through the lag window and the DFT;
    their alias sums ``a`` and the poles above the Nyquist frequency are smooth on the band, and a
    smooth ``S(theta)`` seen through a lag window ``1 - c2 m^2 + ...`` of a window with zero ends
    is ``S + c2 S''`` (``sum_m m^2 s[m] e^{-j theta m} = -S''``), evaluated at ``f`` directly:
    ``O(K P)`` instead of a transform of every pole over an ``8 N``-point grid. Against that grid
    (16 x finer), 1.3e-13 of the peak on the satellite (Hann, 4096 points, 106 poles in or near
    the band)."""
    fs, n, _ = settings
    T = 1.0 / fs
    below = np.abs(poles.imag) < np.pi * fs
    far = ~below & (np.abs(poles) >= _FAR_POLE * np.pi * fs)
    near = ~below & ~far
    two = np.zeros((2 * n,) + D.shape)
    two[0] = D
    pb = poles[below]
    if pb.size:  # real: one pole of each conjugate pair, twice, and the real poles
        half = below & (poles.imag >= 0)
        weight = np.where(poles[half].imag > 0, 2.0 * T, T)
        seq = _powers(poles[half] * T, n) * weight[None, :]
        seq[0] *= 0.5
        two[:n] += np.real(seq @ flat[half]).reshape((n,) + D.shape)
    out = _lagged_spectrum(two, f, settings).reshape(f.size, -1)
    th = (2.0 * np.pi * f / fs)[:, None]
    if np.any(near):  # r / (j theta fs - p) and its second derivative in theta, -2 fs^2 r / (...)^3
        x = 1.0 / (1j * th * fs - poles[None, near])
        out += (x - (2.0 * c2 * fs * fs) * (x * x * x)) @ flat[near]
    if np.any(far):
        s0, s2 = _far_pole_series(th[:, 0] * fs, poles[far], flat[far], np.pi * fs, second=True)
        out += s0 + (c2 * fs * fs) * s2
    if pb.size:  # a = r [cot((theta - beta) / 2) / (2 j fs) - 1 / (j theta fs - p)], as in the grid path
        e = np.exp(-1j * th) * np.exp(pb / fs)[None, :]
        cot = 1j * (1.0 + e) / (1.0 - e)
        x = 1.0 / (1j * th * fs - pb[None, :])
        # d^2/dtheta^2 cot((theta - beta) / 2) = cot (1 + cot^2) / 2
        alias = (cot + (0.5 * c2) * cot * (1.0 + cot * cot)) / (2j * fs)
        alias += (2.0 * c2 * fs * fs) * (x * x * x) - x
        out -= alias @ flat[below]
    return out.reshape((f.size,) + D.shape)


@limit_blas
def expected_h1_measured(sys: Any, f_hz: Any, settings: EstimatorSettings) -> np.ndarray:
    """Expected H1 of a continuous system driven by a measured, band-limited white input.

    The sampled input and output of a structure driven by a measured continuous force (no
    hold) are related, below the Nyquist frequency, by ``G(j 2 pi f)`` itself: the discrete
    impulse response is the two-sided inverse transform ``h[m] = (1/2 pi) int_{-pi}^{pi}
    G(j theta fs) e^{j theta m} d theta``, no aliasing, no hold, a feedthrough stays ``D``. The
    Welch estimate sees it through the lag window (module notes), two-sided:

        E[H1](theta) = sum_{|m| < N} h[m] r_w[|m|] / r_w[0] e^{-j theta m}.

    Per pole ``p`` below the Nyquist frequency, ``h = h_ii - a`` with ``h_ii[m] = T r e^{p T m}``
    (``m >= 0``, halved at ``m = 0``: Poisson's sum at the jump) exact and ``a`` the inverse
    transform of the smooth alias sum ``sum_{q != 0} r / (j (theta + 2 pi q) fs - p) =
    r [cot((theta - beta) / 2) / (2 j fs) - 1 / (j theta fs - p)]``, ``beta = -j p / fs``, taken
    by an FFT over ``8 N`` points; a pole above the Nyquist frequency is transformed by the FFT
    directly (one beyond :data:`_FAR_POLE` times it through the power series of
    :func:`_far_pole_series`: all such poles at the cost of a few). The alias sum is Poisson's
    summation of the sampled impulse response (Oppenheim & Schafer, *Discrete-Time Signal
    Processing*, 3rd ed., sec. 4.2); the lag window is that of the module notes (the expectation
    of the windowed cross-spectrum of a white input).

    With a window whose ends are zero (Hann, Blackman: :func:`_lag_curvature`) and frequencies
    below :data:`_LOCAL_MAX_NYQUIST` of the Nyquist frequency, the smooth parts (the alias sums and
    the poles above the Nyquist frequency) are seen through the lag window locally, ``S + c2 S''``
    at the frequencies themselves (:func:`_measured_local`), and no grid is needed: 1.3e-13 of the
    peak from the grid path on the satellite test structure, 5-10 x faster. Other windows (Hamming,
    boxcar: a kink of the lag window at lag 0 spreads the alias sum's jump at the Nyquist frequency
    over the band) take the grid.

    Returns
    -------
    ndarray, complex, shape (K, n_out, n_in)
    """
    ss = as_statespace(sys)
    fs, n, window = settings
    T = 1.0 / fs
    modal = _modal(ss)
    D = np.asarray(ss.D, dtype=float)
    f = np.asarray(f_hz, dtype=float)
    c2 = _lag_curvature(window, int(n)) if modal is not None and f.size else None
    if c2 is not None and np.all(f > 0) and np.all(f <= _LOCAL_MAX_NYQUIST * fs / 2):
        poles, res, _ = modal
        return _measured_local(poles, res.reshape(len(poles), -1), D, f, settings, c2)
    big = _GRID_FACTOR * 2 * n
    theta = 2.0 * np.pi * np.arange(big // 2 + 1) / big
    two = np.zeros((2 * n,) + D.shape)
    two[0] = D
    if modal is None:  # defective modes: transform the response itself on the fine grid

        g = freqresp(ss, theta[1:] * fs / (2 * np.pi)).response - D
        g = np.concatenate([g[:1].real, g], axis=0)  # theta = 0: the first point's real part
        g[-1] = g[-1].real
        c = np.fft.irfft(g, big, axis=0)
    else:
        poles, res, _ = modal
        below = np.abs(poles.imag) < np.pi * fs
        far = ~below & (np.abs(poles) >= _FAR_POLE * np.pi * fs)
        near = ~below & ~far
        flat = res.reshape(len(poles), -1)
        grid = np.zeros((theta.size, flat.shape[1]), complex)
        if np.any(far):
            grid += _far_pole_series(theta * fs, poles[far], flat[far], np.pi * fs)
        pb = poles[below]
        eb = np.exp(pb / fs)
        with np.errstate(divide="ignore", invalid="ignore"):
            for lo in range(0, theta.size, _GRID_CHUNK):  # chunks of rows: temporaries stay small
                th = theta[lo:lo + _GRID_CHUNK, None]
                if np.any(near):
                    grid[lo:lo + _GRID_CHUNK] += (1.0 / (1j * th * fs - poles[None, near])) @ flat[near]
                if pb.size:
                    # cot((theta - beta) / 2) = j (1 + e) / (1 - e), e = e^{-j theta} e^{j beta}
                    # (= e^{p / fs}; |e| <= 1 for a stable pole)
                    e = np.exp(-1j * th) * eb[None, :]
                    cot = 1j * (1.0 + e) / (1.0 - e)
                    alias = cot / (2j * fs) - 1.0 / (1j * th * fs - pb[None, :])
                    grid[lo:lo + _GRID_CHUNK] -= alias @ flat[below]
        # (big/2 + 1, n_out * n_in)
        grid[-1] = grid[-1].real  # theta = pi: the mean of the two sides of the jump
        c = np.fft.irfft(grid, big, axis=0).reshape((big,) + D.shape)
        if np.any(below):
            m = np.arange(n)
            pb = poles[below]
            seq = np.exp(np.outer(m, pb * T)) * T
            seq[0] *= 0.5
            two[:n] += np.real(seq @ flat[below]).reshape((n,) + D.shape)
    two[:n] += c[:n]
    two[n + 1:] += c[big - n + 1:]
    return _lagged_spectrum(two, np.asarray(f_hz, dtype=float), settings)


def sampled_hold_response(sys: Any, f_hz: Any, fs: float) -> np.ndarray:
    """The exact sampled response of a continuous system behind a zero-order hold at ``f_hz``.

    ``G_zoh(z) = C (z I - A_d)^{-1} B_d + D`` with ``[[A_d, B_d], [0, I]] = expm([[A, B], [0, 0]] T)``
    at ``z = e^{j 2 pi f / fs}`` (Franklin, Powell & Workman, *Digital Control*, sec. 4.3):
    the H1 estimate of a held input without leakage (periodic excitation with whole periods,
    stepped sine), aliasing and the hold's half-sample delay included.
    """
    ss = as_statespace(sys)
    d = control.c2d(ss, 1.0 / float(fs), method="zoh")
    return freqresp(d, f_hz).response


def discrete_view(sys: Any, f_hz: Any, settings: EstimatorSettings | None) -> np.ndarray:
    """A sampled system (``dt > 0``) as the estimate sees it: ``G(e^{j 2 pi f dt})``, through the
    lag window when the estimate has leakage (``h[0] = D``, ``h[m] = C A^{m-1} B``)."""
    ss = as_statespace(sys)
    f = np.asarray(f_hz, dtype=float)
    if settings is None or not settings.leakage:
        return freqresp(ss, f).response
    n = settings.nperseg
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    two = np.zeros((2 * n,) + D.shape)
    two[0] = D
    X = B.copy()
    for k in range(1, n):
        two[k] = C @ X
        X = A @ X
    return _lagged_spectrum(two, f, settings)


def estimator_view(sys: Any, f_hz: Any, settings: EstimatorSettings, *, hold: bool = False) -> np.ndarray:
    """A continuous system "as the H1 estimator sees it".

    ``hold=False``: ``E[H1 of sys] / hold(f)``, the expected estimate divided by the
    zero-order hold's response -- window leakage only, so no hold is silently added to the
    model. ``hold=True``: ``E[H1 of sys]`` itself, the exact sampled experiment with a DAC's
    hold (aliasing and the direct feedthrough's timing included); used when the user added
    the hold deliberately (:func:`robustctl.physical.electronics.zero_order_hold_stage`) and
    ``sys`` is the model without that stage. Data divided by the hold
    (``meta["hold_divided"]``) are compared with ``hold=False``.

    An impact test (``settings.impact``) is seen through its exponential window and record end:
    :func:`expected_h1_impact`. A measured input (``settings.input_kind == "measured"``) has no
    hold and no aliasing:
    :func:`expected_h1_measured`, window leakage alone. A sampled model (``dt > 0``) is
    evaluated at ``z = e^{j 2 pi f dt}`` (:func:`discrete_view`).
    """
    f = np.asarray(f_hz, dtype=float)
    if _is_discrete(sys):
        return discrete_view(sys, f, settings)
    if settings.impact:
        g = expected_h1_impact(sys, f, settings)
        return g * hold_response(f, settings.fs_hz)[:, None, None] if hold and settings.fs_hz else g
    if settings.input_kind == "measured":  # a hold stage the user added stays in the model, exactly
        g = expected_h1_measured(sys, f, settings)
        return g * hold_response(f, settings.fs_hz)[:, None, None] if hold else g
    g = expected_h1(sys, f, settings) if settings.leakage else sampled_hold_response(sys, f, settings.fs_hz)
    if hold:
        return g
    return g / hold_response(f, settings.fs_hz)[:, None, None]


def _is_discrete(sys: Any) -> bool:
    dt = getattr(sys, "dt", None)
    return dt not in (None, 0) and dt is not False


# ---------------------------------------------------------------------------- models seen
def _sees_estimator(model: Any) -> bool:
    """False for a fit to the H1 estimates themselves: a MeasurementModel fitted without the
    leakage correction already contains the estimator's leakage."""
    src = getattr(model, "source", model)
    return bool(getattr(src, "leakage_corrected", True))


def experiment_view(
    experiment: Any, meta: Mapping[str, Any] | None = None, f_hz: Any = None
) -> tuple[EstimatorSettings | None, str]:
    """What the experiment description establishes about the estimate: ``(settings or None, note)``.

    * window leakage: random excitation with known ``fs_hz``, ``nperseg`` and ``window``;
    * the exact sampled zero-order hold (aliasing, half-sample delay): a held input with known
      ``fs_hz``, applied to the model unless the data were divided by the hold
      (``hold_divided``; :func:`model_view`);
    * nothing else: a measured input has no hold and no aliasing; periodic excitation with
      whole periods per segment, bursts and stepped sines have no window leakage;
    * an impact test: its exponential window and record end (:func:`impact_settings`) at the
      frequencies ``f_hz`` (Hz; the record's DFT bins for the record end).

    ``note`` says in words what is applied (``"model seen through ..."``) or why nothing is
    (:data:`robustctl.frd.PLAIN_NOTE` when the data do not describe their experiment).
    """
    e = experiment if isinstance(experiment, Experiment) else Experiment.from_dict(experiment)
    if e.input_kind is None and e.excitation is None:
        return None, PLAIN_NOTE
    if isinstance(meta, Mapping) and meta.get("leakage_corrected"):
        return None, "compared as the plain FRF: the data were corrected for the estimator's leakage"
    leakage = e.excitation == "random" and e.welch_known
    held = e.input_kind == "held" and e.fs_hz is not None
    if e.excitation == "impact" and not held:
        st, why = impact_settings(e, meta, f_hz)
        if st is not None:
            return st, f"model seen through {st.describe()}"
    if not leakage and not held:
        if e.excitation == "random":
            why = "the random-excitation estimate's settings (fs, nperseg, window) are not stated"
        elif e.excitation == "periodic" and not e.whole_periods:
            why = "periodic excitation without whole periods per segment stated"
        elif e.excitation is None:
            why = "the excitation is not stated"
        elif e.excitation == "impact":
            why = "an impact test without an exponential window or a recorded record length"
        else:
            why = f"{e.excitation.replace('_', ' ')} excitation has no window leakage"
            if e.excitation == "periodic":
                why = "periodic excitation with whole periods per segment has no window leakage"
                if e.window not in (None, "boxcar", "rectangular", "rect", "ones"):
                    why += (f" (but a {e.window} window mixes neighbouring lines of a periodic excitation; "
                            "estimate with window='boxcar')")
        kind = "the input kind is not stated"
        if e.input_kind == "measured":
            kind = "a measured input has no hold"
        return None, f"compared as the plain FRF: {why}; {kind}"
    window, n = e.window, e.nperseg
    if leakage and window == USER_WINDOW:
        values = (meta or {}).get("window_values") if isinstance(meta, Mapping) else None
        if values is None:
            leakage = False
            if not held:
                return None, "compared as the plain FRF: the estimate's window array is not recorded"
        else:
            window, n, _ = welch_window({"window": window, "nperseg": n, "window_values": values})
    st = EstimatorSettings(
        (e.fs_hz, n, window), e.noverlap, e.hold_divided, "held" if held else "measured", leakage
    )
    note = f"model seen through the H1 estimator: {st.describe()}"
    if not held and e.input_kind is None:
        note = note.replace(", measured input (no hold)", "")
        note += "; the input kind is not stated, so no zero-order hold is applied"
    return st, note


def resolve_estimator(spec: Any, data: Any, model: Any) -> EstimatorSettings | None:
    """The H1 estimator settings to see ``model`` through, or None (the one rule of compare,
    update, diagnose, verify and ``rc.log_cost``).

    ``"auto"``: what the data's experiment description establishes (:func:`experiment_view`),
    unless the model is itself a fit to the estimates; ``True``: required; ``False``/``None``:
    off; an :class:`EstimatorSettings`: those. ``data`` is the FrequencyData (a bare ``meta``
    mapping, as before the experiment description, is read as a held, random-excitation record).
    """
    return resolve_view(spec, data, model)[0]


def resolve_view(spec: Any, data: Any, model: Any) -> tuple[EstimatorSettings | None, str]:
    """:func:`resolve_estimator` with the note saying what was applied (or why nothing was)."""
    if isinstance(spec, EstimatorSettings):
        return spec, f"model seen through the H1 estimator: {spec.describe()}"
    if spec is None or spec is False:
        return None, "compared as the plain FRF (estimator=False)"
    experiment = getattr(data, "experiment", None)
    meta = getattr(data, "meta", data)
    if experiment is None:  # a meta mapping alone: the settings it records, held
        st = estimator_settings(meta)
        found = (st, "" if st is None else f"model seen through the H1 estimator: {st.describe()}")
    else:
        found = experiment_view(experiment, meta, getattr(data, "f_hz", None))
    if isinstance(spec, str) and spec == "auto":
        if not _sees_estimator(model):
            return None, "compared as the plain FRF: the model is a fit to the estimates themselves"
        return found
    if spec is True:
        if found[0] is None:
            raise DataError(
                "estimator=True needs an experiment description that establishes the estimator's effects "
                f"({found[1]}); describe the data (data.replace(experiment=rc.Experiment(input_kind=..., "
                "excitation=..., fs_hz=..., nperseg=..., window=...))) or pass estimator=False."
            )
        return found
    raise DataError(f"estimator must be 'auto', True, False or EstimatorSettings; got {spec!r}.")


def split_hold(model: Any) -> tuple[Any, bool]:
    """``(model without its zero-order-hold stage, whether it had one)``.

    With the hold added deliberately (``electronics.zero_order_hold_stage``, tagged
    :data:`HOLD_TAG`), the estimator view samples the bare model through an exact hold
    instead of the stage's rational approximation (aliasing and a feedthrough's timing).
    """
    stages = getattr(model, "io_stages", ())
    has = any(HOLD_TAG in getattr(s, "tags", ()) for s in stages) and hasattr(model, "without")
    return (model.without(HOLD_TAG) if has else model), has


def model_view(bare: Any, has_hold: bool, f_hz: Any, settings: EstimatorSettings, **overrides: float):
    """The response of a (split) model as the estimator sees it, shape (K, n_out, n_in), in the
    model's channel order: :func:`estimator_view` of ``bare.statespace(**overrides)``.

    A held input's hold is part of the experiment the data describe: it is applied whether or
    not the model carries a hold stage (unless the data were divided by the hold,
    ``hold_divided``); a measured input has none, so only a hold stage the user added is.
    """
    if overrides and hasattr(bare, "param_names"):
        overrides = {k: v for k, v in overrides.items() if k in bare.param_names}
    if hasattr(bare, "param_names") and hasattr(bare, "statespace"):
        sys = bare.statespace(**overrides)
    else:
        sys = as_statespace(bare)
    if settings.input_kind == "held":  # the experiment had the hold: keep it, unless it was divided out
        return estimator_view(sys, f_hz, settings, hold=not settings.hold_divided)
    return estimator_view(sys, f_hz, settings, hold=has_hold)
