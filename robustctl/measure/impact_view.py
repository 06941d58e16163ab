"""What an impact test's H1 estimator makes of a model: the exponential window and the record end.

An impact record of length ``T`` sampled every ``dt``, hit ``h`` at ``t_h`` with a force pulse
``f_h`` (Laplace transform ``P_h(z) = int f_h(t) exp(-z t) dt``), is windowed from the hit by
``exp(-(t - t_h)/tau)`` on force and response (:func:`robustctl.estimate_frf_impact`). A mode
``r / (s - p)`` of the structure answers ``y(t) = r int exp(p (t - u)) f(u) du``; multiplying by
the window gives ``r int exp(q (t - u)) f_w(u) du`` with ``f_w`` the windowed force and

    q = p - 1/tau:                                                                    (W1)

the windowed response is the windowed force through the structure with every pole moved left by
``1/tau`` -- the model evaluated at ``s + 1/tau`` (Fladung & Rost, "Application and correction
of the exponential window for frequency response functions", *Mech. Syst. Signal Process.*
11(1), 1997; Ewins, *Modal Testing*, 2nd ed., sec. 3.11). A force window that keeps the
whole pulse (:func:`robustctl.estimate_frf_impact` zeroes only what follows it) removes force
noise and leaves ``f_w`` unchanged. The record ends at ``T``; at the DFT bins ``w_k = 2 pi k / T``
what it cuts off, divided by the force spectrum and averaged over the hits with their force
energies ``w_h``, is per unit residue

    tail_q(s) = dt sum_h w_h E_h(q, s) / (1 - exp((q - s) dt)),                          (T1)
    E_h(q, s) = exp((q - s) L_h + (q^2 - s^2) sigma_h^2 / 2),   L_h = T - t_h,

``E_h`` being the cumulant expansion of ``exp((q - s) T) P_h(q) / P_h(s)`` to second order in the
pulse's rms duration ``sigma_h`` (the sampled, geometric form of the tail: the record is a sum
over samples). So the expected H1 of a model ``D + sum_p R_p / (s - p)`` is exactly

    E[H1](s) = D + sum_p R_p [1 / (s - q_p) - tail_{q_p}(s)],   s = j w_k,                (W2)

with ``q_p`` from (W1) (``tau = inf`` without an exponential window: the rectangular record's
truncation alone). Its derivative with respect to the pole (the modal refinement's analytic
Jacobian) is

    d tail_q / dq = dt sum_h w_h E_h [(L_h + q sigma_h^2) / (1 - e) + dt e / (1 - e)^2],
    e = exp((q - s) dt).                                                              (T1')

This module holds the record description and the kernels; ``estimator`` applies them to a model
(compare, diagnose and update see the model this way), ``identify`` fits poles through them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "TruncationSettings",
    "truncation_settings",
    "record_tails",
    "on_record_bins",
    "expected_h1_impact_modal",
    "exp_window_correlation",
]

#: bin lags of the exponential window's error correlation kept: up to where it falls below this
CORRELATION_FLOOR = 1e-3
#: and at most this many bins
MAX_CORRELATION_LAG = 256


@dataclass(frozen=True)
class TruncationSettings:
    """Record length, hit times and hit weights of an impact H1 estimate (eq. T1).

    Attributes
    ----------
    fs_hz : float
        Sampling frequency, Hz.
    record_s : float
        Record length ``T``, s.
    hit_times_s : tuple of float
        Force-pulse centroid ``t_h`` of every hit from the record start, s.
    hit_weights : tuple of float
        Share of every hit in the H1 average (its force energy; they sum to 1).
    hit_spreads_s : tuple of float
        RMS duration of every hit's force pulse about its centroid, s (the second-order term of
        the pulse in eq. T1); empty: impulses.
    """

    fs_hz: float
    record_s: float
    hit_times_s: tuple[float, ...]
    hit_weights: tuple[float, ...]
    hit_spreads_s: tuple[float, ...] = ()


def truncation_settings(meta: Mapping[str, Any] | None) -> TruncationSettings | None:
    """The truncation settings recorded by :func:`robustctl.estimate_frf_impact`, or None (other
    data, or data already corrected: ``meta["leakage_corrected"]``)."""
    if not isinstance(meta, Mapping) or meta.get("leakage_corrected"):
        return None
    try:
        fs, n = float(meta["fs_hz"]), int(meta["n_samples"])
        times = tuple(float(t) for t in meta["hit_times_s"])
        weights = np.asarray(meta["hit_weights"], dtype=float)
    except (KeyError, TypeError, ValueError):
        return None
    if len(times) != weights.size or weights.size == 0 or not weights.sum() > 0:
        return None
    if not (np.isfinite(fs) and fs > 0 and n > 0 and np.all(np.isfinite(times)) and np.all(weights >= 0)):
        return None
    try:
        spreads = tuple(float(v) for v in meta.get("hit_spreads_s") or ())
    except (TypeError, ValueError):
        spreads = ()
    if len(spreads) != len(times) or not all(np.isfinite(spreads)):
        spreads = ()
    return TruncationSettings(fs, n / fs, times, tuple(weights / weights.sum()), spreads)


def record_tails(s: np.ndarray, q: np.ndarray, settings: Any, derivative: bool = False):
    """``tail_q(s)`` of eq. T1 for every pole in ``q``, shape ``(K,) + q.shape``; with
    ``derivative`` also ``d tail_q / dq`` (eq. T1'), same shape.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable at the data's frequencies (the record's DFT bins), rad/s.
    q : ndarray, complex
        Poles as the windowed record sees them (eq. W1), rad/s; any shape.
    settings : TruncationSettings
        Sampling frequency (Hz), record length (s), hit times (s), weights and pulse spreads (s).
    """
    q = np.asarray(q, dtype=complex)
    s = np.asarray(s, dtype=complex)
    dt = 1.0 / settings.fs_hz
    cut = settings.record_s - np.asarray(settings.hit_times_s, dtype=float)  # L_h, s
    weights = np.asarray(settings.hit_weights, dtype=float)
    spread = np.asarray(getattr(settings, "hit_spreads_s", ()) or np.zeros(cut.size), dtype=float)
    shape = (s.size,) + (1,) * q.ndim
    x = q[None] - s.reshape(shape)  # (K, *q.shape), 1/s
    quad = (q[None] ** 2 - (s**2).reshape(shape))[..., None] * (0.5 * spread**2)  # (..., n_hits)
    decay = np.exp(x[..., None] * cut + quad)  # E_h
    share = decay @ weights
    one_minus = -np.expm1(x * dt)
    terms = dt * share / one_minus
    if not derivative:
        return terms
    e = np.exp(x * dt)
    d_share = (decay * (cut + q[None, ..., None] * spread**2)) @ weights
    return terms, dt * (d_share / one_minus + share * dt * e / one_minus**2)


def on_record_bins(f_hz: Any, settings: TruncationSettings) -> bool:
    """Whether ``f_hz`` (Hz) are DFT bins ``k / T`` of the record, where eq. T1 holds."""
    bins = np.asarray(f_hz, dtype=float) * settings.record_s
    return bool(np.allclose(bins, np.rint(bins), rtol=0.0, atol=1e-6))


def expected_h1_impact_modal(
    poles: Any, residues: Any, d: Any, f_hz: Any, tau_s: float | None, record: TruncationSettings | None
) -> np.ndarray:
    """Expected impact H1 (eq. W2) of ``d + sum_p residue_p / (s - pole_p)``, (K, n_out, n_in).

    Parameters
    ----------
    poles : array_like, complex, shape (n,)
        Every pole of the structure (conjugates included), rad/s.
    residues : array_like, complex, shape (n, n_out, n_in)
        Their residues.
    d : array_like, shape (n_out, n_in)
        Feedthrough (a windowed force times ``d`` is the windowed response: unchanged).
    f_hz : array_like, shape (K,)
        Frequencies, Hz (the record's DFT bins when ``record`` is given).
    tau_s : float or None
        Exponential-window time constant, s (None: no exponential window).
    record : TruncationSettings or None
        The record's length and hits for the record-end tail (None: no tail, an infinitely long
        record).
    """
    s = 2j * np.pi * np.asarray(f_hz, dtype=float)
    p = np.asarray(poles, dtype=complex)
    q = p - (0.0 if tau_s is None else 1.0 / float(tau_s))  # eq. W1
    r = np.asarray(residues, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        basis = 1.0 / (s[:, None] - q[None, :])
        if record is not None:
            basis = basis - record_tails(s, q, record)
    g = np.einsum("kp,poi->koi", basis, r) + np.asarray(d, dtype=float)[None]
    return g


def exp_window_correlation(tau_s: float, n_samples: int, fs_hz: float) -> np.ndarray:
    """Correlation ``r_m`` of the H1 errors at DFT bins ``m = 0, 1, ...`` apart under an
    exponential window ``exp(-t/tau)`` on an ``n_samples`` record at ``fs_hz``.

    Output noise through the window has, at bins ``m`` apart, the correlation
    ``rho_m = sum_n w[n]^2 e^{-j 2 pi m n / N} / sum_n w[n]^2`` and the H1 error its square
    ``r_m = |rho_m|^2`` (as for a Welch window, :func:`robustctl.measure.estimator.bin_correlation`);
    for ``w = exp(-t/tau)`` and ``tau`` short against the record, ``r_m ~ 1 / (1 + (pi m tau /
    T)^2)``: with the window at 1 % at the end of the record, 0.69 at one bin, 0.36 at two,
    falling slowly. Kept while ``r_m >= CORRELATION_FLOOR`` (at most ``MAX_CORRELATION_LAG``
    lags). A shift of the window's start (the hit time) scales ``w`` and leaves ``r_m`` unchanged.

    Parameters
    ----------
    tau_s : float
        Window time constant, s.
    n_samples : int
        Record length, samples.
    fs_hz : float
        Sampling frequency, Hz.

    Returns
    -------
    ndarray, shape (n_lags + 1,)
        ``r_0 = 1, r_1, ...``.
    """
    t = np.arange(int(n_samples)) / float(fs_hz)
    spec = np.fft.fft(np.exp(-2.0 * t / float(tau_s)))
    r = (np.abs(spec[: min(int(n_samples) // 2, MAX_CORRELATION_LAG) + 1]) / abs(spec[0])) ** 2
    low = np.flatnonzero(r < CORRELATION_FLOOR)
    return r[: low[0]] if low.size else r
