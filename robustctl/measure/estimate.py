"""From time data to FrequencyData: H1 Welch estimates, coherence, simulated experiments.

The defaults reproduce the Caltech truss identification experiments (Balas & Doyle,
``seeds/caltech-balas-doyle-identification.txt``): 200 Hz sampling, 409.6 s records
(81,920 samples) of white-noise excitation, one single-input/multi-output experiment per
actuator, 4096-point Hamming windows overlapping by 2048 points (39 averages).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..checks import check_seed, flag, integer, match_channels, positive_number
from ..errors import DataError, ModelError, RobustctlWarning
from ..frd import EXCITATIONS, INPUT_KINDS, Experiment, FrequencyData, combined_experiment
from ..lti import as_statespace, zoh
from ..threads import limit_blas
from .estimator import USER_WINDOW, window_values

__all__ = ["estimate_frf", "combine_experiments", "simulate_experiment", "advised_nperseg", "HeldCommand"]

#: the largest record simulate_experiment will produce (samples), a memory guard
MAX_SAMPLES = 50_000_000
#: fewest Welch averages for a usable H1 estimate (random error ~ 1/sqrt(n_avg), Bendat & Piersol 9.90)
MIN_AVERAGES = 8


class EstimateWarning(RobustctlWarning):
    """An FRF estimate whose settings leave it noisier than advised (fewer than
    :data:`MIN_AVERAGES` Welch averages)."""


def advised_nperseg(n_samples: int, min_averages: int = MIN_AVERAGES, longest: int = 4096) -> int:
    """Segment length for a record of ``n_samples``: the Caltech 4096 (``longest``) when it gives at
    least ``min_averages`` averages with 50 % overlap, else the largest power of two that does
    (at least 16). ``n_avg = 1 + (n - L) // (L / 2) >= m`` holds for ``L <= 2 n / (m + 1)``.

    Parameters
    ----------
    n_samples : int
        Record length, samples.
    min_averages : int
        Fewest Welch averages wanted (the H1 random error falls as ``1 / sqrt(averages)``).
    longest : int
        Longest segment, samples (Caltech's 4096).

    Returns
    -------
    int
        The segment length ``nperseg``, a power of two.
    """
    limit = 2 * int(n_samples) / (min_averages + 1)
    length = 16
    while length * 2 <= min(limit, longest):
        length *= 2
    return length


# ---------------------------------------------------------------------------- helpers
class HeldCommand(np.ndarray):
    """A sampled command that a DAC held over each sample (zero-order hold).

    :func:`simulate_experiment` returns its excitation as a ``HeldCommand`` so that
    :func:`estimate_frf` records ``input_kind="held"`` without being told; any array
    operation keeps the mark (``np.asarray(u)`` drops it). ``fs_hz`` is the hold's rate.
    """

    fs_hz: float | None = None

    def __new__(cls, values: Any, fs_hz: float | None = None) -> HeldCommand:
        obj = np.asarray(values).view(cls)
        obj.fs_hz = fs_hz
        return obj

    def __array_finalize__(self, obj: Any) -> None:
        self.fs_hz = getattr(obj, "fs_hz", None)

    def __array_wrap__(self, arr: Any, context: Any = None, return_scalar: bool = False) -> Any:
        if np.ndim(arr) == 0:  # reductions give plain numbers, not 0-d marked arrays
            return np.asarray(arr)[()]
        return super().__array_wrap__(arr, context, return_scalar)

    def __reduce__(self):
        return (HeldCommand, (np.asarray(self), self.fs_hz))


def _input_kind(value: Any, u: Any) -> str:
    """``"held"`` for a :class:`HeldCommand` unless told otherwise, else ``"measured"``."""
    if value is None or (isinstance(value, str) and value == "auto"):
        return "held" if isinstance(u, HeldCommand) else "measured"
    if not isinstance(value, str) or value not in INPUT_KINDS:
        raise DataError(
            f"input_kind must be 'measured' (a measured force or voltage), 'held' (a DAC command through a "
            f"zero-order hold) or 'auto'; got {value!r}."
        )
    return value


def _excitation(value: Any, whole_periods: Any, period: Any, nperseg: int) -> tuple[str, bool | None]:
    if not isinstance(value, str) or value not in EXCITATIONS:
        raise DataError(f"excitation must be one of {list(EXCITATIONS)}; got {value!r}.")
    if period is not None:
        period = integer(period, "period (samples per period of the excitation)", DataError, lo=1)
        whole = nperseg % period == 0
        if whole_periods is not None and bool(whole_periods) != whole:
            raise DataError(
                f"whole_periods={whole_periods!r} contradicts period={period} with nperseg={nperseg} "
                f"(nperseg % period = {nperseg % period}); give one of them."
            )
        whole_periods = whole
    if whole_periods is not None:
        whole_periods = flag(whole_periods, "whole_periods")
        if value != "periodic":
            raise DataError(f"whole_periods/period describe periodic excitation; excitation is {value!r}.")
    return value, whole_periods


#: Largest signal magnitude: squares summed over a window stay far below the float64 limit.
_MAX_SIGNAL = 1e100
#: Smallest peak of a non-zero signal: its squares stay far above the float64 underflow.
_MIN_SIGNAL = 1e-100


def _as_signals(x: Any, name: str) -> np.ndarray:
    """A real (n_samples, n_channels) float array; 1-D input is one channel."""
    arr = np.asarray(x)
    if arr.dtype == object or not (np.issubdtype(arr.dtype, np.number) or arr.dtype == bool):
        raise DataError(f"{name} must be a numeric array of shape (n_samples, n_channels).")
    if np.iscomplexobj(arr):
        raise DataError(f"{name} is complex; time signals must be real.")
    arr = arr.astype(float)
    if arr.size == 0:
        raise DataError(f"{name} is empty (no samples); pass the recorded time signal.")
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise DataError(f"{name} must have shape (n_samples, n_channels); got shape {arr.shape}.")
    if arr.shape[0] < arr.shape[1]:
        raise DataError(
            f"{name} has shape {arr.shape}: more channels than samples. Time runs down the first "
            f"axis; pass {name}.T if your array is (n_channels, n_samples)."
        )
    if not np.all(np.isfinite(arr)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(arr), axis=1))[0])
        raise DataError(f"{name} contains NaN or inf (first at sample {bad}); repair or cut the record.")
    peak = float(np.max(np.abs(arr))) if arr.size else 0.0
    if peak > _MAX_SIGNAL:
        raise DataError(
            f"{name} reaches {peak:.3g}; its spectra (squares summed over a window) would overflow "
            f"beyond {_MAX_SIGNAL:g}. Rescale the record (other units) to magnitudes near 1."
        )
    tiny = [k for k in range(arr.shape[1]) if 0 < np.max(np.abs(arr[:, k])) < _MIN_SIGNAL]
    if tiny:
        raise DataError(
            f"{name} channel {tiny[0]} peaks at {np.max(np.abs(arr[:, tiny[0]])):.3g}, below "
            f"{_MIN_SIGNAL:g}: its spectra would underflow to zero. Rescale the record (other units) to "
            "magnitudes near 1."
        )
    return arr


def _window(window: Any, nperseg: int) -> np.ndarray:
    if isinstance(window, (str, tuple)):
        return window_values(window, nperseg)
    try:
        win = np.asarray(window, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise DataError(
            f"window must be a scipy.signal.get_window name (e.g. 'hamming'), a (name, parameter) tuple or "
            f"an array of nperseg = {nperseg} weights; got {window!r}."
        ) from None
    if win.size != nperseg:
        raise DataError(f"a window array must hold nperseg = {nperseg} values; got {win.size}.")
    if not np.all(np.isfinite(win)):
        raise DataError(f"the window array holds {int(np.sum(~np.isfinite(win)))} NaN or inf values.")
    if not np.any(win):
        raise DataError("the window array is all zero; it would hide every sample.")
    return win


def _segment_settings(n_samples: int, nperseg: Any, noverlap: Any) -> tuple[int, int, int]:
    """Validated ``(nperseg, noverlap, n_averages)`` (Welch, 1967)."""
    if isinstance(nperseg, str) and nperseg == "auto":
        nperseg = advised_nperseg(n_samples)
    nperseg = integer(nperseg, "nperseg (samples per window, or 'auto')", DataError, lo=2)
    noverlap = nperseg // 2 if noverlap is None else noverlap
    noverlap = integer(noverlap, "noverlap (samples shared by neighbouring windows)", DataError, lo=0)
    if noverlap >= nperseg:
        raise DataError(
            f"noverlap ({noverlap}) must be smaller than nperseg ({nperseg}); "
            f"the usual choice is nperseg // 2 = {nperseg // 2}."
        )
    if n_samples < nperseg:
        raise DataError(
            f"the record has {n_samples} samples, shorter than one window (nperseg={nperseg}); "
            "record longer or choose a smaller nperseg (coarser frequency resolution)."
        )
    n_avg = 1 + (n_samples - nperseg) // (nperseg - noverlap)
    if n_avg < MIN_AVERAGES:
        import warnings

        warnings.warn(
            f"nperseg={nperseg} leaves {n_avg} averages on a {n_samples}-sample record; the H1 estimate's "
            f"random error falls as 1/sqrt(averages) and {MIN_AVERAGES} or more are advised: use "
            f"nperseg={advised_nperseg(n_samples)} (or nperseg='auto').",
            EstimateWarning,
            stacklevel=4,
        )
    return nperseg, noverlap, n_avg


def _spectra(x: np.ndarray, win: np.ndarray, nperseg: int, step: int, n_avg: int, detrend: bool):
    """One-sided windowed FFTs of every segment, shape (n_avg, n_freq, n_channels)."""
    idx = np.arange(nperseg)[None, :] + step * np.arange(n_avg)[:, None]
    seg = x[idx]  # (n_avg, nperseg, n_ch)
    if detrend:
        seg = seg - seg.mean(axis=1, keepdims=True)
    return np.fft.rfft(seg * win[None, :, None], axis=1)


def _check_input_power(guu: np.ndarray, f: np.ndarray, inputs: tuple[str, ...]) -> None:
    """Refuse silent or linearly dependent inputs (H1 needs Guu invertible)."""
    diag = np.real(np.diagonal(guu, axis1=1, axis2=2))
    scale = diag.max(axis=0)
    for k, name in enumerate(inputs):
        if scale[k] <= 0:
            raise DataError(
                f"input {name!r} carries no signal (all zero, or constant: each segment's mean is removed); "
                "drop it or excite it."
            )
    dn = 1.0 / np.sqrt(np.maximum(diag, 1e-300 * scale))
    corr = guu * dn[:, :, None] * dn[:, None, :]
    lam_min = np.linalg.eigvalsh(corr)[:, 0] if len(inputs) > 1 else np.real(corr[:, 0, 0])
    bad = np.flatnonzero(lam_min < 1e-10)
    if bad.size:
        raise DataError(
            f"the inputs are linearly dependent at {bad.size} frequencies (first {f[bad[0]]:.4g} Hz), "
            "so the H1 estimate is undefined; excite the inputs with independent signals or run one "
            "experiment per input and join them with combine_experiments()."
        )


# ---------------------------------------------------------------------------- estimate_frf
@limit_blas
def estimate_frf(
    u: Any,
    y: Any,
    fs: float,
    nperseg: int | str = 4096,
    noverlap: int | None = None,
    window: Any = "hamming",
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    *,
    detrend: bool = True,
    units: Mapping[str, str] | None = None,
    input_kind: str | None = "auto",
    excitation: str = "random",
    whole_periods: bool | None = None,
    period: int | None = None,
) -> FrequencyData:
    """H1 frequency-response estimate from averaged cross-spectra (Welch's method).

    For every frequency the H1 estimate is ``H = G_yu G_uu^{-1}`` (Bendat & Piersol,
    *Random Data*, eq. 7.27), with ``G_uu`` (n_in x n_in) and ``G_yu`` (n_out x n_in) the
    averaged cross-spectral matrices of windowed, overlapping segments. With one input
    this is ``G_yu / G_uu`` and the coherence is the ordinary coherence
    ``|G_yu|^2 / (G_uu G_yy)``. With several simultaneous inputs the coherence of channel
    ``(o, i)`` is the partial coherence of output ``o`` with input ``i`` given the other inputs,
    ``1 / (1 + G_nn,o [G_uu^-1]_ii / |H_oi|^2)`` with ``G_nn,o = (1 - g2_o:u) G_yy,oo`` the
    output's unexplained spectrum (``g2_o:u = (H G_uu H^H)_oo / G_yy,oo``, the multiple
    coherence, eq. 7.35). It is what sets
    the random error of that channel: the least-squares covariance of a row of ``H`` is
    ``G_nn G_uu^-1 / n_d``, so ``var(H_oi) / |H_oi|^2 = (1 - g2) / (n_d g2)`` with this ``g2``,
    the single-input formula (Bendat & Piersol sec. 9.3), which the noise model and the
    coherence weights apply. The multiple coherence, the same for every input of an output,
    overstated the accuracy of a weak cross channel (5 % log error at a coherence of 0.999).

    Parameters
    ----------
    u : array_like, shape (n_samples,) or (n_samples, n_in)
        Input signals (e.g. V), sampled simultaneously with ``y``.
    y : array_like, shape (n_samples,) or (n_samples, n_out)
        Output signals (e.g. m/s^2).
    fs : float
        Sampling frequency in Hz.
    nperseg : int or "auto"
        Window length in samples (default 4096, as Caltech); resolution ``fs / nperseg`` Hz.
        ``"auto"``: :func:`advised_nperseg` of the record length (4096 when it gives at least 8
        averages, else the largest power of two that does). Fewer than 8 averages is warned
        about, with the advised length.
    noverlap : int, optional
        Overlap of consecutive windows in samples; default ``nperseg // 2``.
    window : str, tuple or array_like
        A ``scipy.signal.get_window`` spec or an array of ``nperseg`` weights.
    inputs, outputs : sequence of str, optional
        Signal names (default ``u1..``, ``y1..``).
    detrend : bool
        Remove each segment's mean before windowing (as ``scipy.signal.welch``).
    units : mapping, optional
        Units of the signals by name, e.g. ``{"A1": "V", "S1": "m/s^2"}``; carried into
        ``FrequencyData.units`` (axis labels, UFF ordinate types). Unknown names are refused.
    input_kind : {"auto", "measured", "held"}
        How the input reached the structure: ``"measured"`` (a measured continuous force or
        voltage, the laboratory default), ``"held"`` (a DAC command held over each sample).
        ``"auto"``: ``"held"`` for the excitation :func:`simulate_experiment` returns (a
        :class:`HeldCommand`), else ``"measured"``.
    excitation : {"random", "periodic", "burst", "impact", "stepped_sine"}
        The excitation signal (default ``"random"``): what the estimator's view of a model
        applies (window leakage for random excitation, none for periodic excitation with whole
        periods per segment).
    whole_periods : bool, optional
        Periodic excitation: each segment holds a whole number of periods.
    period : int, optional
        Periodic excitation: samples per period; sets ``whole_periods = nperseg % period == 0``.

    Returns
    -------
    FrequencyData
        The estimate at ``k fs / nperseg`` Hz, k = 1 .. nperseg // 2 (DC dropped), with
        coherence; ``meta`` records the settings and the number of averages, ``experiment``
        (:class:`~robustctl.frd.Experiment`) how the data were made.

    Examples
    --------
    >>> import robustctl as rc, control
    >>> sys = control.ss([[0, 1], [-(2 * 3.1416 * 5) ** 2, -3.0]], [[0], [1]], [[1, 0]], [[0]])
    >>> u, y = rc.simulate_experiment(sys, n_samples=8192)
    >>> data = rc.estimate_frf(u, y, fs=200.0, nperseg=1024)
    """
    kind = _input_kind(input_kind, u)
    u = _as_signals(u, "u")
    y = _as_signals(y, "y")
    if u.shape[0] != y.shape[0]:
        raise DataError(
            f"u has {u.shape[0]} samples but y has {y.shape[0]}; inputs and outputs must be "
            "sampled together (same length)."
        )
    fs = positive_number(fs, "fs", unit="sampling frequency, Hz")
    detrend = flag(detrend, "detrend")
    nperseg, noverlap, n_avg = _segment_settings(u.shape[0], nperseg, noverlap)
    excitation, whole_periods = _excitation(excitation, whole_periods, period, nperseg)
    n_in = u.shape[1]
    if n_avg < n_in:
        raise DataError(
            f"{n_in} simultaneous inputs need at least {n_in} averages, but the record gives {n_avg}; "
            "use a longer record or a shorter nperseg."
        )
    win = _window(window, nperseg)
    f = np.fft.rfftfreq(nperseg, 1.0 / fs)[1:]
    U = _spectra(u, win, nperseg, nperseg - noverlap, n_avg, detrend)[:, 1:]
    Y = _spectra(y, win, nperseg, nperseg - noverlap, n_avg, detrend)[:, 1:]
    guu = np.einsum("kfi,kfj->fij", U, U.conj()) / n_avg  # G_uu[f, i, j] = E[U_i conj(U_j)]
    gyu = np.einsum("kfo,kfi->foi", Y, U.conj()) / n_avg  # G_yu[f, o, i] = E[Y_o conj(U_i)]
    gyy = np.einsum("kfo,kfo->fo", Y, Y.conj()).real / n_avg
    names_in = FrequencyData(f[:1], np.ones((1, 1, n_in)), inputs=inputs).inputs
    _check_input_power(guu, f, names_in)
    silent = np.flatnonzero(gyy.max(axis=0) <= 0)
    if silent.size:
        names_out = FrequencyData(f[:1], np.ones((1, y.shape[1], 1)), outputs=outputs).outputs
        raise DataError(
            f"output {names_out[silent[0]]!r} carries no signal (all zero, or constant: each segment's mean "
            "is removed), so its estimate would be 0 with coherence 0; is the sensor connected? Drop the "
            "channel or check the recording."
        )
    # H guu = gyu  <=>  guu^T H^T = gyu^T
    H = np.linalg.solve(np.transpose(guu, (0, 2, 1)), np.transpose(gyu, (0, 2, 1))).transpose(0, 2, 1)
    explained = np.einsum("foi,foi->fo", H, gyu.conj()).real
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.where(gyy > 0, explained / gyy, 0.0)
    coh = np.repeat(np.clip(coh, 0.0, 1.0)[:, :, None], n_in, axis=2)
    if n_in > 1:
        coh = _partial_coherence(H, guu, gyy, explained)
    meta = {
        "method": "H1 (Welch averaged cross-spectra)",
        "coherence": "ordinary" if n_in == 1 else "partial",
        "fs_hz": fs,
        "nperseg": nperseg,
        "noverlap": noverlap,
        "window": window if isinstance(window, (str, tuple)) else USER_WINDOW,
        "detrend": bool(detrend),
        "n_averages": n_avg,
        "n_inputs": n_in,
        "n_samples": int(u.shape[0]),
        "resolution_hz": fs / nperseg,
    }
    if not isinstance(window, (str, tuple)):
        meta["window_values"] = win.tolist()  # so the estimator's view of a model can be formed
    experiment = Experiment(
        input_kind=kind, excitation=excitation, fs_hz=fs, window=meta["window"], nperseg=nperseg,
        noverlap=noverlap, n_averages=n_avg, whole_periods=whole_periods,
    )
    data = FrequencyData(f, H, inputs=names_in, outputs=outputs, coherence=coh, meta=meta,
                         experiment=experiment)
    return data.replace(units=_check_units(units, data))


def _partial_coherence(H: np.ndarray, guu: np.ndarray, gyy: np.ndarray, explained: np.ndarray) -> np.ndarray:
    """Coherence of each channel of a multiple-input H1 estimate (see :func:`estimate_frf`).

    ``g2_oi = 1 / (1 + G_nn,o [G_uu^-1]_ii / |H_oi|^2)``, ``G_nn,o = G_yy,oo - (H G_uu H^H)_oo``:
    the partial coherence of output ``o`` with input ``i`` given the other inputs (Bendat &
    Piersol sec. 7.3); with one input, the ordinary coherence. Shape (nf, n_out, n_in)."""
    gnn = np.maximum(gyy - explained, 0.0)  # (nf, n_out)
    inv_diag = np.real(np.diagonal(np.linalg.inv(guu), axis1=1, axis2=2))  # (nf, n_in)
    noise = gnn[:, :, None] * np.maximum(inv_diag, 0.0)[:, None, :]
    power = np.abs(H) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.where(power > 0, power / (power + noise), 0.0)
    return np.clip(np.nan_to_num(coh), 0.0, 1.0)


def _check_units(units: Mapping[str, str] | None, data: FrequencyData) -> dict[str, str]:
    """``units`` as a dict of strings keyed by the data's signal names."""
    if units is None:
        return {}
    if not isinstance(units, Mapping):
        raise DataError(f"units must be a mapping signal name -> unit string; got {type(units).__name__}.")
    unknown = sorted(set(units) - set(data.inputs + data.outputs))
    if unknown:
        raise DataError(
            f"units names signals {unknown} that the estimate does not have; its signals are "
            f"{list(data.inputs + data.outputs)}."
        )
    return {str(k): str(v) for k, v in units.items()}


# ---------------------------------------------------------------------------- combine
def combine_experiments(experiments: Sequence[FrequencyData]) -> FrequencyData:
    """Join single-input (SIMO) experiments into one MIMO FrequencyData.

    The Caltech procedure runs one experiment per actuator, each giving a column of the
    transfer matrix; this stacks those columns along the input axis, in the order given.

    Parameters
    ----------
    experiments : sequence of FrequencyData
        Estimates on the same frequency grid (Hz) with the same outputs, and distinct inputs.

    Returns
    -------
    FrequencyData
        Shape (n_freq, n_out, sum of n_in); coherence kept when every experiment has it;
        ``meta["experiments"]`` holds each experiment's meta.
    """
    exps = list(experiments) if not isinstance(experiments, FrequencyData) else [experiments]
    if not exps:
        raise DataError("combine_experiments needs at least one FrequencyData; got an empty list.")
    for k, e in enumerate(exps):
        if not isinstance(e, FrequencyData):
            raise DataError(f"experiment {k} is a {type(e).__name__}, not a FrequencyData.")
    ref = exps[0]
    for k, e in enumerate(exps[1:], start=1):
        if e.f_hz.shape != ref.f_hz.shape or not np.allclose(e.f_hz, ref.f_hz, rtol=1e-12, atol=0):
            raise DataError(
                f"experiment {k} has a different frequency grid ({e.n_freq} points, "
                f"{e.f_hz[0]:g}-{e.f_hz[-1]:g} Hz) from experiment 0 ({ref.n_freq} points, "
                f"{ref.f_hz[0]:g}-{ref.f_hz[-1]:g} Hz); estimate all with the same fs and nperseg."
            )
        if e.outputs != ref.outputs:  # the one channel-name policy; same names are reordered
            idx = match_channels(e.outputs, ref.outputs, "outputs", sides=(f"experiment {k}", "experiment 0"))
            exps[k] = e.select(outputs=[e.outputs[i] for i in idx]).replace(outputs=ref.outputs)
    inputs = [name for e in exps for name in e.inputs]
    if len(set(inputs)) != len(inputs):
        dup = sorted({n for n in inputs if inputs.count(n) > 1})
        raise DataError(
            f"input names repeat across experiments: {dup}; name each experiment's input "
            "(estimate_frf(..., inputs=[...])) so the columns can be told apart."
        )
    response = np.concatenate([e.response for e in exps], axis=2)
    coh = None
    if all(e.coherence is not None for e in exps):
        coh = np.concatenate([e.coherence for e in exps], axis=2)
    units: dict[str, str] = {}
    for e in exps:
        units.update(e.units)
    meta = {
        "combined_from": len(exps),
        "experiments": [dict(e.meta) for e in exps],
        "experiment_of_input": [k for k, e in enumerate(exps) for _ in range(e.n_in)],
    }
    return FrequencyData(ref.f_hz, response, inputs=inputs, outputs=ref.outputs, coherence=coh,
                         units=units, meta=meta, experiment=combined_experiment([e.experiment for e in exps]))


# ---------------------------------------------------------------------------- simulation
def _pick_inputs(inputs: Any, names: Sequence[str]) -> list[int]:
    if inputs is None:
        return list(range(len(names)))
    if isinstance(inputs, (str, int, np.integer)):
        inputs = [inputs]
    idx = []
    for item in inputs:
        if isinstance(item, (int, np.integer)) and not isinstance(item, bool):
            if not -len(names) <= item < len(names):
                raise DataError(f"input index {item} is out of range for a system with {len(names)} inputs.")
            idx.append(int(item) % len(names))
        elif item in names:
            idx.append(list(names).index(item))
        else:
            raise DataError(f"unknown input {item!r}; the system has inputs {list(names)}.")
    if len(set(idx)) != len(idx) or not idx:
        raise DataError(f"inputs={inputs!r} must name distinct inputs (at least one).")
    return idx


def _per_channel(value: Any, count: int, what: str, allow_zero: bool) -> np.ndarray:
    items = value if isinstance(value, (list, tuple, np.ndarray)) else [value]
    arr = np.asarray(items)
    if arr.dtype.kind not in "iuf" or arr.size == 0:  # text, complex, bool, None: not a level
        raise DataError(f"{what} must be a real number or one per channel; got {value!r}.")
    arr = arr.astype(float).reshape(-1)
    if arr.size == 1:
        arr = np.full(count, arr[0])
    if arr.size != count:
        raise DataError(
            f"{what} has {arr.size} values for {count} channels; give a scalar or one per channel."
        )
    if not np.all(np.isfinite(arr)) or np.any(arr < 0) or (not allow_zero and np.any(arr == 0)):
        sign = "non-negative" if allow_zero else "positive"
        raise DataError(f"{what} must be finite and {sign}; got {value!r}.")
    return arr


#: relative diagonal loading of the stationary covariance before its square root (a variance
#: 1e-12 of the largest adds nothing measurable to the record)
STATE_JITTER = 1e-12

#: weight ``rho^K`` left on the coordinate-dependent part of the stationary start after ``K``
#: samples of simulated past excitation (:func:`_past_state`)
BURN_IN_TOL = 1e-8

#: above this condition number of the eigenvectors of ``Ad`` the simulation runs the recursion in
#: blocks (:func:`_simulate_blocks`), not through decoupled modes: their round-off,
#: ``eps * cond``, stays below 1e-13 of the record, the same on every BLAS kernel
MODAL_COND_LIMIT = 1e3

#: at most this many samples of simulated past excitation (a system with ``1 - rho < 2e-5`` keeps
#: a weight ``rho^K > BURN_IN_TOL`` on the coordinate-dependent part)
BURN_IN_MAX = 1 << 20


def _covariance_root(P: np.ndarray) -> np.ndarray:
    """The symmetric square root ``S = V sqrt(max(w, 0) + j) V^T`` of ``P = V diag(w) V^T``.

    ``j = STATE_JITTER * max(diag P)``. Unique (each eigenvector appears twice, so neither its sign
    nor the basis of a repeated eigenvalue matters) and continuous in ``P``: a change ``dP`` moves
    ``S`` by at most about ``|dP| / sqrt(j)``, 1e-6 of ``sqrt(max(diag P))`` for a round-off
    ``|dP| = 1e-12 max(diag P)``. A Cholesky factor is unique too, but of a ``P`` that is singular
    to round-off (a lightly damped system's) it moved 1 % under a 1e-13 change of the input matrix.

    Parameters
    ----------
    P : ndarray, shape (n, n)
        Symmetric covariance, possibly indefinite by round-off.

    Returns
    -------
    ndarray, shape (n, n)
        ``S`` with ``S S^T = V (max(w, 0) + j) V^T``.
    """
    from scipy.linalg import eigh

    w, V = eigh(P)
    jitter = STATE_JITTER * max(float(np.max(np.diag(P))), np.finfo(float).tiny)
    return (V * np.sqrt(np.clip(w, 0.0, None) + jitter)) @ V.T


def _drawn_state(Ad: np.ndarray, Bd: np.ndarray, rms: np.ndarray, rng) -> np.ndarray:
    """A draw ``L z`` from the stationary state distribution ``P = Ad P Ad^T + Bd S Bd^T``.

    ``L`` is the Cholesky factor of ``P`` (plus ``STATE_JITTER`` times its largest diagonal entry on
    the diagonal): unique and continuous in ``P``, so the draw is the same on every machine for a
    well-conditioned ``P``. An eigenvector factor is not: each column's sign (and the basis of a
    repeated eigenvalue, as of a symmetric structure) is the LAPACK kernel's choice, which gave
    another record, up to 12 % apart in an FRF bin, under another OpenBLAS kernel. Only a ``P``
    that is indefinite beyond the jitter falls back to the eigenvector factor, its columns' signs
    fixed by their largest entry. A draw in the state basis is not the same state in another
    realization of the system: :func:`_past_state` is (``simulate_experiment(start="past")``).
    """
    from scipy.linalg import eigh, solve_discrete_lyapunov

    Q = (Bd * rms**2) @ Bd.T
    P = solve_discrete_lyapunov(Ad, Q)
    P = (P + P.T) / 2
    z = rng.standard_normal(P.shape[0])
    jitter = STATE_JITTER * max(float(np.max(np.diag(P))), np.finfo(float).tiny)
    try:
        return np.linalg.cholesky(P + jitter * np.eye(P.shape[0])) @ z
    except np.linalg.LinAlgError:
        w, V = eigh(P)
        V = V * np.sign(V[np.argmax(np.abs(V), axis=0), np.arange(V.shape[1])])
        return V @ (np.sqrt(np.clip(w, 0.0, None)) * z)


def _past_state(Ad: np.ndarray, Bd: np.ndarray, rms: np.ndarray, rng) -> np.ndarray:
    """A draw from the stationary state distribution ``P = Ad P Ad^T + Bd S Bd^T``.

    The state the system would be in after white excitation since ever:
    ``x0 = sum_{k<K} Ad^k Bd w_k + Ad^K S_P z``, ``w_k`` the excitation ``k + 1`` samples before
    the record (``S = diag(rms**2)``), ``S_P`` the square root :func:`_covariance_root` of ``P``
    and ``K`` the samples after which ``rho^K <= BURN_IN_TOL`` (``rho`` the spectral radius of
    ``Ad``; at most ``BURN_IN_MAX``). Its covariance is exactly ``P``. The sum is the same state
    in any realization of the system -- another state basis ``T x`` gives ``T x0``, the same
    record -- and the square root's part, which depends on the basis, weighs ``rho^K``. A draw
    ``L z`` in the state basis alone does not: MACE's closed-loop realization differs between
    OpenBLAS kernels by a change of basis among its near-repeated modes, and ``L z`` gave its
    records up to 7 % apart (median FRF entry) between kernels.

    Parameters
    ----------
    Ad : ndarray, shape (n, n)
        Sampled state matrix, spectral radius < 1.
    Bd : ndarray, shape (n, m)
        Sampled input matrix.
    rms : ndarray, shape (m,)
        RMS of each white input (its units).
    rng : numpy.random.Generator
        Draws ``z`` (``n`` standard normal values); the past excitation comes from a generator it
        spawns, so the draws after this one do not depend on ``K``.

    Returns
    -------
    ndarray, shape (n,)
        The initial state, in the units of ``Bd @ rms``.

    Raises
    ------
    ModelError
        The stationary covariance is not finite.
    """
    from scipy.linalg import solve_discrete_lyapunov

    n = Ad.shape[0]
    z = rng.standard_normal(n)
    past = rng.spawn(1)[0]
    with np.errstate(over="ignore", invalid="ignore"):  # refused below
        Q = (Bd * rms**2) @ Bd.T
    P = solve_discrete_lyapunov(Ad, Q) if np.all(np.isfinite(Q)) else Q
    if not np.all(np.isfinite(P)):
        raise ModelError("the stationary state covariance is not finite; the system is too close to "
                         "instability for a stationary start.")
    tail = _covariance_root((P + P.T) / 2) @ z
    mu, V = np.linalg.eig(Ad)
    rho = float(np.max(np.abs(mu)))
    K = BURN_IN_MAX if rho**BURN_IN_MAX > BURN_IN_TOL else int(np.ceil(np.log(BURN_IN_TOL) / np.log(rho)))
    W = past.standard_normal((K, Bd.shape[1])) * rms  # row k: k + 1 samples before the record
    if np.linalg.cond(V) > MODAL_COND_LIMIT:  # the recursion in blocks, oldest sample first
        return _final_state(Ad, Bd, W[::-1], tail)
    Vinv = np.linalg.inv(V)
    # modal state after K samples: mu^K q0 + G-weighted sums sum_k mu^k w_k, by blocks of
    # ``block`` samples, mu^(k0 + i) = mu^k0 mu^i
    block = min(K, 4096)
    powers = mu[:, None] ** np.arange(block)[None, :]
    H = np.zeros((n, Bd.shape[1]), dtype=complex)
    for k0 in range(0, K, block):
        Wb = W[k0:k0 + block]
        H += mu[:, None] ** k0 * (powers[:, :Wb.shape[0]] @ Wb)
    q = mu**K * (Vinv @ tail) + np.sum((Vinv @ Bd) * H, axis=1)
    return np.real(V @ q)


#: The stationary starts of :func:`simulate_experiment`: the state after simulated past
#: excitation (:func:`_past_state`, the default: the same in any realization of the system) and
#: the draw in the state basis (:func:`_drawn_state`).
STARTS = {"draw": _drawn_state, "past": _past_state}


def _simulate_modal(Ad, Bd, C, D, u, x0) -> np.ndarray | None:
    """y = C x + D u with x[k+1] = Ad x[k] + Bd u[k], via decoupled first-order filters.

    Returns None when the eigenvector matrix of ``Ad`` is ill-conditioned (``MODAL_COND_LIMIT``).
    """
    from scipy.signal import lfilter

    mu, V = np.linalg.eig(Ad)
    if np.linalg.cond(V) > MODAL_COND_LIMIT:
        return None
    Vinv = np.linalg.inv(V)
    CV = C @ V
    y = u @ D.T
    z0 = Vinv @ x0
    G_all = Vinv @ Bd  # (n, m)
    chunk = 32
    for start in range(0, mu.size, chunk):
        sl = slice(start, start + chunk)
        G = u @ G_all[sl].T  # (N, k) modal forcing
        Z = np.empty_like(G)
        for j in range(G.shape[1]):
            a = [1.0, -mu[sl][j]]
            Z[:, j] = lfilter([0.0, 1.0], a, G[:, j], zi=[z0[sl][j]])[0]
        y += np.real(Z @ CV[:, sl].T)
    return y


def _simulate_loop(Ad, Bd, C, D, u, x0) -> np.ndarray:
    """The plain recursion, one sample at a time (the reference of :func:`_simulate_blocks`)."""
    X = np.empty((u.shape[0], Ad.shape[0]))
    x = x0.copy()
    BU = u @ Bd.T
    for k in range(u.shape[0]):
        X[k] = x
        x = Ad @ x + BU[k]
    return X @ C.T + u @ D.T


def _block_length(n_out: int, n_in: int) -> int:
    """Samples per block of :func:`_simulate_blocks`: a power of two, 8-256, whose Toeplitz map
    ``(L n_out) x (L n_in)`` holds at most 2**22 entries (32 MB)."""
    fit = int(np.sqrt((1 << 22) / max(n_out * n_in, 1)))
    return int(min(256, max(8, 1 << max(fit.bit_length() - 1, 0))))


def _input_map(Ad: np.ndarray, Bd: np.ndarray, L: int) -> tuple[np.ndarray, np.ndarray]:
    """``(Ad^L, R)``: the state after ``L`` samples is ``Ad^L x + R u_block.ravel()``, with
    ``R = [Ad^(L-1) Bd, ..., Ad Bd, Bd]`` and ``u_block`` (L, m) in time order."""
    G = [Bd]
    for _ in range(L - 1):
        G.append(Ad @ G[-1])
    AL = Ad
    for _ in range(L.bit_length() - 1):  # L is a power of two
        AL = AL @ AL
    return AL, np.hstack(G[::-1])


def _final_state(Ad: np.ndarray, Bd: np.ndarray, u: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """The state after ``x[k+1] = Ad x[k] + Bd u[k]`` over all rows of ``u`` from ``x0``, in
    blocks of :func:`_block_length` samples (the first ``len(u) mod L`` samples one by one)."""
    L = _block_length(1, u.shape[1])
    r = u.shape[0] % L
    x = np.array(x0, dtype=float)
    for k in range(r):
        x = Ad @ x + Bd @ u[k]
    if u.shape[0] > r:
        AL, R = _input_map(Ad, Bd, L)
        blocks = u[r:].reshape(-1, L * u.shape[1])
        for b0 in range(0, blocks.shape[0], 4096):  # bounded memory: a million-sample past
            for z in blocks[b0:b0 + 4096] @ R.T:
                x = AL @ x + z
    return x


def _simulate_blocks(Ad, Bd, C, D, u, x0) -> np.ndarray:
    """y = C x + D u with x[k+1] = Ad x[k] + Bd u[k], exact in blocks of ``L`` samples.

    Within a block, ``y[i] = C Ad^i x_b + D u[i] + sum_{j<i} C Ad^(i-1-j) Bd u[j]``: the
    state at the block's start ``x_b`` through ``C Ad^i``, the inputs through the block's
    Toeplitz matrix of Markov parameters; between blocks ``x_(b+1) = Ad^L x_b + R u_block``
    (:func:`_input_map`). Only products of the system's own matrices: no eigenvector basis,
    whose round-off ``eps * cond(V)`` the modal route (:func:`_simulate_modal`) carries, and
    which for a repeated eigenvalue (identical filters on several channels) depends on the BLAS
    kernel. Trailing zeros pad the last block.
    """
    N, m = u.shape
    p, n = C.shape
    L = _block_length(p, m)
    nb = -(-N // L)
    Ub = np.zeros((nb * L, m))
    Ub[:N] = u
    Ub = Ub.reshape(nb, L * m)
    AL, R = _input_map(Ad, Bd, L)
    CA = [C]
    for _ in range(L - 1):
        CA.append(CA[-1] @ Ad)
    markov = [D] + [CAi @ Bd for CAi in CA[:-1]]  # markov[k]: from u[j] to y[j + k]
    T = np.zeros((L, p, L, m))
    for k in range(L):
        idx = np.arange(L - k)
        T[idx + k, :, idx, :] = markov[k]
    X = np.empty((nb, n))
    x = np.array(x0, dtype=float)
    Z = Ub @ R.T
    for b in range(nb):
        X[b] = x
        x = AL @ x + Z[b]
    Y = X @ np.vstack(CA).T + Ub @ T.reshape(L * p, L * m).T
    return Y.reshape(nb * L, p)[:N]


@limit_blas
def simulate_experiment(
    sys: Any,
    fs: float = 200.0,
    n_samples: int = 81920,
    input_rms: float | Sequence[float] = 1.0,
    noise_rms: float | Sequence[float] = 0.0,
    seed: int | None = 0,
    inputs: Any = None,
    start: str = "past",
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate a white-noise identification experiment on a continuous-time system.

    The excitation is sampled Gaussian white noise held constant over each sample
    (zero-order hold), so the sampled response is exact: ``x[k+1] = Ad x[k] + Bd u[k]``,
    ``y[k] = C x[k] + D u[k]`` with ``[[Ad, Bd], [0, I]] = expm([[A, B], [0, 0]] / fs)``.
    The record starts in the stationary state (a draw with covariance the solution of
    ``P = Ad P Ad^T + Bd S Bd^T``, see ``start``), so there is no start-up transient; marginally
    stable systems start at rest. Defaults are the Caltech settings (200 Hz, 81,920 samples).

    The zero-order hold is part of the simulated experiment, as of a real one driven by a
    DAC: an H1 estimate of ``u -> y`` (:func:`estimate_frf`) carries the hold's half-sample
    delay (2.5 ms at 200 Hz) and sinc droop, ``(1 - e^{-sT}) / (sT)``. The excitation is
    returned as a :class:`HeldCommand`, so :func:`estimate_frf` records
    ``experiment.input_kind = "held"`` and ``rc.compare``, ``rc.diagnose`` and ``rc.update``
    see a continuous model through the exact sampled hold (aliasing included). Dividing the
    estimate by ``rc.estimator.hold_response(f_hz, fs)``, as ``rc.examples.make_experiment``
    does, is recorded as ``experiment.hold_divided``. An anti-alias filter in the measurement
    chain is added as a known stage (``rc.electronics.anti_alias_stage``).

    Parameters
    ----------
    sys : control.StateSpace, PhysicalModel or anything ``control.ss`` accepts
        A continuous-time, stable system (s-domain, rad/s).
    fs : float
        Sampling frequency in Hz.
    n_samples : int
        Record length in samples.
    input_rms : float or sequence of float
        RMS of each excited input, in input units.
    noise_rms : float or sequence of float
        RMS of additive white sensor noise on each output, in output units (0: none).
    seed : int or None
        Seed of ``numpy.random.default_rng``; draws are u, then the initial state, then noise.
    inputs : sequence of str or int, optional
        The inputs to excite (names or indices), default all. One SIMO experiment per
        actuator (as Caltech) is ``inputs=[k]``.
    start : {"past", "draw"}
        The stationary start. ``"past"`` (default): the state after simulated past excitation, the
        same state in any realization of ``sys``, so the record does not depend on the basis a
        computation (an OpenBLAS kernel) gave the system: MACE's records under two kernels differ by
        about 1e-6. ``"draw"``: a draw ``L z`` in the system's state basis (Cholesky factor of
        ``P``): another record in another basis (MACE's under two kernels: 2-7 %). Both have
        covariance ``P``.

    Returns
    -------
    u : HeldCommand, shape (n_samples, n_excited)
        The excitation of the chosen inputs, in the order given: an ndarray marked as held
        (:class:`HeldCommand`), so that :func:`estimate_frf` records ``input_kind="held"``.
    y : ndarray, shape (n_samples, n_out)
        The outputs, noise included.
    """
    ss = as_statespace(sys)
    if ss.dt not in (0, None):
        raise ModelError(
            f"simulate_experiment needs a continuous-time system; this one has dt={ss.dt}. "
            "Pass the continuous model; sampling is done here (zero-order hold)."
        )
    fs = positive_number(fs, "fs", unit="sampling frequency, Hz")
    n_samples = integer(n_samples, "n_samples", lo=2, hi=MAX_SAMPLES)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    if not all(np.all(np.isfinite(m)) for m in (A, B, C, D)):
        raise ModelError(
            "the system's state-space matrices hold NaN or inf; simulate a finite system "
            "(check the model that produced it)."
        )
    idx = _pick_inputs(inputs, list(ss.input_labels))
    B, D = B[:, idx], D[:, idx]
    rms_u = _per_channel(input_rms, len(idx), "input_rms", allow_zero=False)
    rms_y = _per_channel(noise_rms, C.shape[0], "noise_rms", allow_zero=True)
    if start not in STARTS:
        raise DataError(f"start must be one of {sorted(STARTS)}; got {start!r}.")
    rng = np.random.default_rng(check_seed(seed))
    u = rng.standard_normal((n_samples, len(idx))) * rms_u
    n = A.shape[0]
    if n == 0:
        y = u @ D.T
    else:
        Ad, Bd = zoh(A, B, 1.0 / float(fs))
        rho = np.max(np.abs(np.linalg.eigvals(Ad)))
        if rho > 1.0 + 1e-9:
            raise ModelError(
                f"the system is unstable (spectral radius of the sampled A is {rho:.6g} > 1); an "
                "open-loop white-noise experiment would diverge. Stabilise it (close a loop) first."
            )
        x0 = STARTS[start](Ad, Bd, rms_u, rng) if rho < 1.0 - 1e-12 else np.zeros(n)
        y = _simulate_modal(Ad, Bd, C, D, u, x0)
        if y is None:
            y = _simulate_blocks(Ad, Bd, C, D, u, x0)
    if np.any(rms_y > 0):
        y = y + rng.standard_normal(y.shape) * rms_y
    return HeldCommand(u, float(fs)), y
