"""Impact-hammer tests: FRF estimates from repeated hits, with force and exponential windows.

Each hit is one average of an H1 estimate (Ewins, *Modal Testing*, sec. 3.11; Bendat &
Piersol eq. 7.27 with one segment per hit): ``H = sum_k conj(F_k) Y_k / sum_k |F_k|^2`` and the
coherence over hits ``|sum conj(F) Y|^2 / (sum |F|^2 sum |Y|^2)``. No detrending (the segment
mean of a transient is signal, not drift); the pre-trigger mean (DC offset) is removed.

* **Force window**: the force is kept from the record start to the end of the pulse plus a
  margin and zeroed after (with a short cosine taper), which removes the noise the force
  channel adds over the rest of the record.
* **Exponential window** ``exp(-(t - t0)/tau)`` (1 at the hit time ``t0``, a pure exponential
  over the whole record, so that the anti-aliasing filter's precursor before ``t0`` is weighted
  as the relation below needs) on force and response makes a response that has not died out by
  the end of the record decay (no leakage). It adds ``1/tau`` to every pole's decay rate, i.e.
  ``zeta_meas = zeta_true + 1/(tau w_n)`` (eq. W1 of :mod:`robustctl.measure.impact_view`);
  ``tau`` is recorded in ``meta["exp_window_tau_s"]`` and ``experiment.exp_window_tau_s``:
  :func:`robustctl.fit_measurement_model` undoes it on the identified modes, and compare,
  diagnose and update see the model through it. Whether "auto" applies it is decided per
  response channel (:func:`ringing_channels`).
* **Force noise**: the force channel's noise kept by the force window (the pre-trigger, the
  pulse and its margin) is a relative H1 error common to every output and correlated over about
  ``n / (window length)`` bins (eq. N1 of :func:`_force_noise`), recorded in
  ``meta["force_noise"]`` for the noise test.
* **Double hits** (a second force pulse after the first has ended) and **overloads** (a
  channel at its range, or clipped: several consecutive samples at the record's extreme) are
  warned about, naming the hit.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..checks import positive_number
from ..errors import DataError, RobustctlWarning
from ..frd import Experiment, FrequencyData

__all__ = ["estimate_frf_impact", "ImpactWarning", "ringing_channels"]

#: the force pulse is where |force| exceeds this fraction of the hit's peak
PULSE_LEVEL = 0.05
#: a response that keeps more than this fraction of its peak envelope at the end leaks
DECAY_LEVEL = 0.01
#: the force has settled after its pulse below this fraction of the peak (or its noise)
SETTLED_LEVEL = 1e-3


class ImpactWarning(RobustctlWarning):
    """An impact record deserves a look (double hit, overload, too few hits)."""


def _as_hits(x: Any, name: str, n_hits: int | None) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :, None]
    elif arr.ndim == 2:
        arr = arr[:, :, None] if n_hits is None or arr.shape[0] == n_hits else arr[None]
    if arr.ndim != 3:
        raise DataError(
            f"{name} must have shape (n_samples,), (n_hits, n_samples) or (n_hits, n_samples, n_channels); "
            f"got {np.shape(x)}."
        )
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{name} contains NaN or inf; repair or drop that hit.")
    return arr


def _pulse(f: np.ndarray) -> tuple[int, int, float]:
    """Start, end (exclusive) and peak of the main force pulse of one hit."""
    a = np.abs(f)
    k = int(np.argmax(a))
    peak = float(a[k])
    if peak == 0:
        raise DataError("a force record is identically zero; that hit carries no impact.")
    low = a < PULSE_LEVEL * peak
    before = np.flatnonzero(low[:k])
    after = np.flatnonzero(low[k:])
    start = int(before[-1] + 1) if before.size else 0
    end = int(k + after[0]) if after.size else f.size
    return start, end, peak


def _double_hit(f: np.ndarray, end: int, peak: float, ratio: float, fs: float) -> float | None:
    """Time (s) of a second pulse above ``ratio * peak`` after the first one ended, or None."""
    later = np.flatnonzero(np.abs(f[end:]) > ratio * peak)
    return None if later.size == 0 else float((end + later[0]) / fs)


def _overloaded(x: np.ndarray, level: float | None) -> bool:
    """At the range ``level`` or clipped: three consecutive samples at the record's extreme."""
    a = np.abs(x)
    top = float(a.max())
    if level is not None:
        return bool(top >= 0.999 * level)
    if top == 0:
        return False
    at = a >= top * (1 - 1e-9)
    return bool(np.any(at[:-2] & at[1:-1] & at[2:]))


def _force_window(n: int, end: int, margin: int) -> np.ndarray:
    w = np.ones(n)
    taper = max(2, margin)
    stop = min(n, end + margin)
    if stop < n:
        ramp = 0.5 * (1 + np.cos(np.pi * np.arange(1, taper + 1) / taper))
        w[stop : stop + taper] = ramp[: max(0, min(taper, n - stop))]
        w[stop + taper :] = 0.0
    return w


def ringing_channels(y: np.ndarray) -> np.ndarray:
    """Which channels of one hit have not decayed, shape (n_channels,) bool.

    A channel rings when its own envelope keeps more than DECAY_LEVEL of its own peak in the last
    10 % of the record. Each channel is judged against itself: a strong channel that has decayed
    does not hide a weaker one that still rings (an envelope over all channels would).

    Parameters
    ----------
    y : ndarray, shape (n_samples, n_channels)
        Responses of one hit (any unit).
    """
    a = np.abs(y)
    tail = a[int(0.9 * a.shape[0]) :].max(axis=0)
    return tail > DECAY_LEVEL * a.max(axis=0)


def _auto_tau(n: int, start: int, fs: float) -> float:
    """``tau`` (s) making the window fall to DECAY_LEVEL at the record end."""
    return (n - start) / fs / np.log(1 / DECAY_LEVEL)


def estimate_frf_impact(
    force: Any,
    response: Any,
    fs: float,
    *,
    exp_window: float | str | None = "auto",
    force_window: float | str | None = "auto",
    double_hit_ratio: float = 0.1,
    force_range: float | None = None,
    response_range: float | Sequence[float] | None = None,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
) -> FrequencyData:
    """H1 FRF from repeated hammer hits, one hit per average, with force and exponential windows.

    Parameters
    ----------
    force : array_like, shape (n_hits, n_samples) or (n_samples,)
        Hammer force of every hit, N; one record per hit, all of the same length.
    response : array_like, shape (n_hits, n_samples, n_out), (n_hits, n_samples) or (n_samples,)
        Responses (e.g. m/s^2), sampled with the force.
    fs : float
        Sampling frequency, Hz.
    exp_window : "auto", float or None
        Time constant ``tau`` (s) of the exponential window from the hit; "auto": the window
        falls to 1 % at the record end, applied when any response channel of any hit has not
        decayed below 1 % of its own peak by then (:func:`ringing_channels`, recorded in
        ``meta["ringing_channels"]``; else no window); None: rectangular (leakage if the
        response has not decayed). The time constant used (None when not applied) is recorded
        in ``meta["exp_window_tau_s"]`` and ``experiment.exp_window_tau_s``, so compare,
        diagnose and update see the model at ``s + 1/tau`` (:mod:`robustctl.measure.impact_view`);
        :func:`robustctl.fit_measurement_model` corrects the damping it adds,
        ``zeta_true = zeta_meas - 1/(tau w_n)``.
    force_window : "auto", float or None
        Length (s) kept after the end of the force pulse before a cosine taper to zero; "auto":
        until the force has settled below its noise (4 x the pre-trigger rms, at least 0.1 % of
        the peak) for ``max(8, 2 x pulse length)`` samples, the longest any hit needs (at least
        the pulse's duration and 4 samples), so an anti-aliasing filter's ringing is kept; None:
        no force window. The length
        used, s, is recorded in ``meta["force_window_s"]`` and ``experiment.force_window_s``.
    double_hit_ratio : float
        A second force pulse above this fraction of the hit's peak, after the first has ended,
        is a double hit (warned; the hit is still used).
    force_range, response_range : float, optional
        Ranges of the acquisition channels (same units as the data); a record reaching 99.9 % of
        its range is an overload. Without them, three consecutive samples at a record's extreme
        count as clipping.
    inputs, outputs : sequence of str, optional
        Signal names (default ``force``; ``y1 ..``).

    Returns
    -------
    FrequencyData
        ``(n_freq, n_out, 1)`` at ``k fs / n_samples`` Hz (DC dropped), coherence over hits,
        ``meta`` with ``method``, ``fs_hz``, ``n_hits``, ``exp_window_tau_s``,
        ``force_window_s``, ``resolution_hz``, ``double_hits`` and ``overloads`` (hit indices),
        ``hit_times_s`` (force-pulse centroids), ``hit_spreads_s`` (their rms durations) and
        ``hit_weights`` (force-energy shares): with
        them :func:`robustctl.fit_measurement_model` undoes the truncation of a response that
        has not decayed by the record end (:mod:`robustctl.identify.leakage`, eq. T1);
        ``force_noise``: the relative H1 error the force channel's noise makes and its bin
        correlation (eq. N1 of :func:`_force_noise`, from the pre-trigger's noise; None without
        8 pre-trigger samples), which the noise test counts
        (:func:`robustctl.measure.noise.cell_chi2_factor`).

    Warns
    -----
    ImpactWarning
        Double hits, overloads, fewer than 3 hits (no meaningful coherence).
    """
    fs = positive_number(fs, "fs", unit="sampling frequency, Hz")
    f = _as_hits(force, "force", None)[:, :, 0]
    y = _as_hits(response, "response", f.shape[0])
    if y.shape[:2] != f.shape:
        raise DataError(
            f"response has {y.shape[0]} hits of {y.shape[1]} samples but force has {f.shape[0]} of "
            f"{f.shape[1]}; give one response record per hit, sampled with the force."
        )
    if not 0 < double_hit_ratio < 1:
        raise DataError(f"double_hit_ratio must lie in (0, 1); got {double_hit_ratio!r}.")
    n_hits, n = f.shape
    pulses = [_pulse(fk) for fk in f]
    doubles = [
        k
        for k, (fk, (_, end, peak)) in enumerate(zip(f, pulses))
        if _double_hit(fk, end, peak, double_hit_ratio, fs) is not None
    ]
    y_range = _range(response_range)
    overloads = [k for k in range(n_hits) if _overloaded(f[k], force_range) or _overloaded(y[k], y_range)]
    _warn(doubles, overloads, n_hits)
    fw, yw = _offsets_removed(f, y, pulses)
    force_noise_var = _force_noise_variance(fw, pulses)
    mult = np.ones((n_hits, n))  # what each hit's force record is multiplied by
    margin = _force_margin(force_window, fw, pulses, fs)
    if margin is not None:
        for k, (_, end, _) in enumerate(pulses):
            mult[k] *= _force_window(n, end, margin)
            fw[k] *= mult[k]
    ringing = np.any([ringing_channels(yk) for yk in yw], axis=0)
    tau = _window_tau(exp_window, ringing, pulses, n, fs)
    if tau is not None:
        t = np.arange(n) / fs
        for k, (start, _, _) in enumerate(pulses):
            win = np.exp(-(t - start / fs) / tau)  # a pure exponential, also before the hit (eq. W1)
            fw[k] *= win
            mult[k] *= win
            yw[k] *= win[:, None]
    energy = np.sum(fw**2, axis=1)
    centroid = np.sum(np.arange(n) * np.abs(fw), axis=1) / np.maximum(np.sum(np.abs(fw), axis=1), 1e-300)
    spreads = [_spread(fk[start:end]) / fs for fk, (start, end, _) in zip(fw, pulses)]
    F = np.fft.rfft(fw, axis=1)[:, 1:]
    Y = np.fft.rfft(yw, axis=1)[:, 1:, :]
    sff = np.sum(np.abs(F) ** 2, axis=0)
    syf = np.sum(np.conj(F)[:, :, None] * Y, axis=0)
    syy = np.sum(np.abs(Y) ** 2, axis=0)
    h = syf / np.maximum(sff, 1e-300)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.where(syy > 0, np.abs(syf) ** 2 / (sff[:, None] * syy), 0.0)
    freqs = np.fft.rfftfreq(n, 1.0 / fs)[1:]
    quiet = [start // 2 if start >= 8 else 0 for start, _, _ in pulses]  # the offsets' samples
    force_noise = _force_noise(force_noise_var, mult, quiet, F, sff, freqs)
    meta = {
        "method": "H1 impact (one average per hit)",
        "fs_hz": fs,
        "n_hits": n_hits,
        "n_samples": n,
        "exp_window_tau_s": tau,
        "force_window_s": None if margin is None else margin / fs,
        "ringing_channels": [int(c) for c in np.flatnonzero(ringing)],
        "resolution_hz": fs / n,
        "double_hits": doubles,
        "overloads": overloads,
        "hit_times_s": [float(c / fs) for c in centroid],
        "hit_spreads_s": [float(v) for v in spreads],
        "hit_weights": [float(e / energy.sum()) for e in energy],
        "force_noise": force_noise,
    }
    return FrequencyData(
        freqs,
        h[:, :, None],
        inputs=list(inputs) if inputs is not None else ["force"],
        outputs=outputs,
        coherence=np.clip(coh, 0.0, 1.0)[:, :, None],
        meta=meta,
        experiment=Experiment(input_kind="measured", excitation="impact", fs_hz=fs, n_averages=n_hits,
                              exp_window_tau_s=tau, force_window_s=None if margin is None else margin / fs,
                              pretrigger_s=float(np.dot(meta["hit_weights"], meta["hit_times_s"]))),
    )


def _force_noise_variance(f: np.ndarray, pulses) -> float | None:
    """Variance (N^2) of the force channel's noise: the pooled (unbiased) variance of the first half
    of each hit's pre-trigger (clear of an anti-aliasing filter's precursor), None when no hit has
    8 pre-trigger samples."""
    quiet = [f[k, : start // 2] for k, (start, _, _) in enumerate(pulses) if start >= 8]
    if not quiet:
        return None
    return float(np.mean([np.var(q, ddof=1) for q in quiet]))


def _force_noise(var: float | None, mult: np.ndarray, quiet: list[int], F: np.ndarray, sff: np.ndarray,
                 freqs: np.ndarray) -> dict | None:
    """The H1 error the force channel's noise makes, band-wide correlated (eq. N1).

    White force noise ``m`` of variance ``s2``, less its mean over the first ``h_k`` samples (the
    DC offset removed, :func:`_offsets_removed`), times the window ``w_k`` of hit ``k`` (the force
    window times the exponential window), has the DFT ``M_k`` with

    ``E[M_k(j) conj(M_k(l))] / s2 = W2(j - l) - B(j) conj(A(l)) - A(j) conj(B(l)) + A(j) conj(A(l)) / h``

    (``W2``, ``A``, ``B``: the DFTs of ``w^2``, ``w`` and ``w`` over the first ``h`` samples,
    ``/ h``): a short force window correlates it over about ``n / (window length)`` bins, the
    offset's error over every bin. It enters H1 as the relative error
    ``-sum_k conj(F_k) M_k / sum_k |F_k|^2`` of every output alike, of complex variance

    ``v(f) = sum_k |F_k|^2 E|M_k(f)|^2 / (sum_k |F_k|^2)^2``                            (N1)

    and a correlation at bins ``m`` apart bounded by the largest ``|E[M_k(j) conj(M_k(j + m))]| /
    sqrt(E|M_k(j)|^2 E|M_k(j + m)|^2)`` over bins and hits. The coherence counts ``v`` in each
    bin's variance, but a sum over a band of bins dominated by it varies like a few independent
    points, not like its number of bins.

    Returns
    -------
    dict or None
        ``{"f_hz": [...], "rel_var": [...], "corr": [...]}`` (Hz, dimensionless, the bound for
        ``m = 0, 1, ..`` up to its last value of 0.05 or more); None without a noise estimate.
    """
    if var is None or not var > 0:
        return None
    n = mult.shape[1]
    A = np.fft.fft(mult, axis=1)
    W2 = np.fft.fft(mult**2, axis=1)
    B = np.zeros_like(A)
    for k, h in enumerate(quiet):
        if h > 0:
            B[k] = np.fft.fft(np.where(np.arange(n) < h, mult[k], 0.0)) / h
    inv_h = np.array([1.0 / h if h > 0 else 0.0 for h in quiet])[:, None]
    bins = np.arange(1, freqs.size + 1)

    def cov(j: np.ndarray, m: int) -> np.ndarray:  # E[M_k(j) conj(M_k(j + m))] / s2, (n_hits, len(j))
        lag = W2[:, (-m) % n][:, None]
        Aj, Al, Bj, Bl = A[:, j], A[:, (j + m) % n], B[:, j], B[:, (j + m) % n]
        return lag - Bj * np.conj(Al) - Aj * np.conj(Bl) + inv_h * Aj * np.conj(Al)

    d = np.real(cov(bins, 0))
    v = var * np.sum(np.abs(F) ** 2 * d, axis=0) / np.maximum(sff, 1e-300) ** 2
    corr = [1.0]
    for m in range(1, freqs.size):
        j = bins[: freqs.size - m]
        c = np.abs(cov(j, m)) / np.sqrt(np.maximum(d[:, : j.size] * d[:, m:m + j.size], 1e-300))
        corr.append(float(np.max(c)))
        if m >= 8 and max(corr[-8:]) < 0.05:
            break
    corr_arr = np.array(corr)
    corr_arr = corr_arr[: int(np.flatnonzero(corr_arr >= 0.05)[-1]) + 1]
    return {"f_hz": [float(x) for x in freqs], "rel_var": [float(x) for x in v],
            "corr": [float(x) for x in corr_arr]}


def _spread(pulse: np.ndarray) -> float:
    """RMS duration (samples) of a force pulse about its own centroid, ``|f|``-weighted."""
    a = np.abs(pulse)
    if a.size < 2 or not a.sum() > 0:
        return 0.0
    k = np.arange(a.size)
    mean = float(k @ a / a.sum())
    return float(np.sqrt(((k - mean) ** 2) @ a / a.sum()))


def _range(value: Any) -> float | None:
    if value is None:
        return None
    return float(np.min(np.asarray(value, dtype=float)))


def _offsets_removed(f: np.ndarray, y: np.ndarray, pulses) -> tuple[np.ndarray, np.ndarray]:
    """Copies of force and response with each hit's DC offset removed: the mean of the first half
    of the pre-trigger samples (the second half may hold the precursor of a linear-phase
    anti-aliasing filter, which is signal)."""
    fw, yw = np.array(f), np.array(y)
    for k, (start, _, _) in enumerate(pulses):
        if start >= 8:  # the first half of the pre-trigger: clear of an anti-aliasing filter's precursor
            fw[k] -= f[k, : start // 2].mean()
            yw[k] -= y[k, : start // 2].mean(axis=0)
    return fw, yw


def _force_margin(force_window: Any, f: np.ndarray, pulses, fs: float) -> int | None:
    """Samples kept after each pulse's end: the given length, or with "auto" the longest any hit
    needs (:func:`_settled`), one number for every hit; None without a force window."""
    if force_window is None:
        return None
    if isinstance(force_window, str) and force_window == "auto":
        return max(_settled(fk, pulse) for fk, pulse in zip(f, pulses))
    length = _positive_seconds(force_window, "force_window")
    return max(1, int(round(length * fs)))


def _settled(f: np.ndarray, pulse: tuple[int, int, float]) -> int:
    """Samples after the pulse's end until the force has settled: the start of the first run of
    ``max(8, 2 x pulse length)`` samples all below the force's noise (4 x the rms of the first half
    of the pre-trigger, at least SETTLED_LEVEL of the peak). The ringing of an anti-aliasing filter
    after the pulse is force: a window that cut it would bias the estimate. At least 4 samples and
    the pulse's own duration."""
    start, end, peak = pulse
    noise = float(np.std(f[: start // 2])) if start >= 8 else 0.0
    level = max(SETTLED_LEVEL * peak, 4.0 * noise)
    run = max(8, 2 * (end - start))
    quiet = np.abs(f[end:]) < level
    loud = np.flatnonzero(~quiet)
    gaps = np.diff(np.concatenate([[-1], loud, [quiet.size]])) - 1  # quiet samples after each loud one
    first = int(np.flatnonzero(gaps >= run)[0]) if np.any(gaps >= run) else len(gaps) - 1
    settle = 0 if first == 0 else int(loud[first - 1]) + 1
    return max(4, end - start, settle)


def _positive_seconds(value: Any, name: str, what: str = "time") -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = float("nan")
    if isinstance(value, (bool, np.bool_)) or not (np.isfinite(x) and x > 0):
        raise DataError(f"{name} must be 'auto', None or a positive {what} in s; got {value!r}.")
    return x


def _window_tau(exp_window: Any, ringing: np.ndarray, pulses, n: int, fs: float) -> float | None:
    """One time constant for every hit: the given one, or with "auto" (when any channel of any hit
    rings, :func:`ringing_channels`) the shortest the hits need: the latest hit's."""
    if exp_window is None:
        return None
    if not (isinstance(exp_window, str) and exp_window == "auto"):
        return _positive_seconds(exp_window, "exp_window", "time constant")
    if not np.any(ringing):
        return None
    return min(_auto_tau(n, start, fs) for start, _, _ in pulses)


def _warn(doubles: list[int], overloads: list[int], n_hits: int) -> None:
    if doubles:
        warnings.warn(
            f"double hit(s) in hit(s) {doubles}: a second force pulse after the first; the input spectrum "
            "has notches there. Repeat those hits (or drop them) for a clean estimate.",
            ImpactWarning,
            stacklevel=3,
        )
    if overloads:
        warnings.warn(
            f"overload in hit(s) {overloads}: a channel reached its range or clipped. Hit softer or raise "
            "the range, and repeat those hits.",
            ImpactWarning,
            stacklevel=3,
        )
    if n_hits < 3:
        warnings.warn(
            f"{n_hits} hit(s): the coherence over hits means little below 3 (it is 1 for one hit); "
            "average 5 or more hits.",
            ImpactWarning,
            stacklevel=3,
        )
