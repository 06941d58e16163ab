"""The noise model of a frequency response estimate: how far ``ln G_data`` scatters at each point.

Every verdict of the correlate stage ("within the noise", p-values, drift) is a statement
about the complex-log residual ``e = ln(G_data / G_model)`` measured in units of its own
scatter. :func:`noise_model` gives that scatter:

* **from coherence and the number of averages** (data made by :func:`robustctl.estimate_frf`):
  the normalised random error of ``|H1|`` and the standard deviation of its phase (rad) are
  both ``sqrt(1 - g2) / (|g| sqrt(2 n_d))`` (Bendat & Piersol, *Random Data*, 4th ed.,
  sec. 9.2.3, Table 9.6), the standard deviation of ``Re ln H1`` (nepers) and of ``Im ln H1``
  (rad). ``n_d`` is the effective number of averages of the overlapped windows (Welch 1967;
  :func:`robustctl.measure.estimator.effective_averages`); with ``q`` simultaneous inputs and the
  partial coherence of each channel, ``n_d - q + 1`` (Bendat & Piersol, sec. 9.3.3).
* **from the residual of a measurement model** (data without coherence): a robust local
  scale (1.4826 x the running median absolute value of ``Re e`` and ``Im e`` over 33 points)
  of ``ln(G_data / G_mm)`` per channel; for a random test whose Welch settings and averages
  the data record, plus (in quadrature) the error the window leakage of the model's identified
  modes causes (:mod:`robustctl.measure.expected_coherence`). The leakage error lives in the
  few bins of a resonance, where a running median over 33 points does not see it: on the
  Caltech truss without coherence it is 3-7 x that median at 1.0-1.2 Hz, and the exact truth
  was beyond the noise (2.6 x in S3 <- A3, 0.54-5.4 Hz) until it was added.
* otherwise **none**: results then say "no noise estimate: no significance claims".

Neighbouring frequency bins of a windowed estimate are correlated. The H1 error has two
sources with different correlations: output noise (independent of the input), whose errors at
bins ``m`` apart have the complex correlation ``r_m = |rho_m|^2`` of
:func:`robustctl.measure.estimator.bin_correlation` (``rho_m`` that of the window's DFT of white
noise; Hamming: ``r_1 = 0.39``), and the leakage of a lightly damped response (the output in
a window not explained by that window's input: the decay of what came before and the
response cut off at its end), a smooth function of frequency times ``conj(U)``, whose errors
correlate like the input spectrum itself, up to ``|rho_m| = sqrt(r_m)`` (Caltech truss at
its resonances, where leakage dominates the coherence loss: about -0.35 at one bin against
+0.30 between them). A sum of squared normalised residuals over contiguous bins is then more
variable than for independent points by the Satterthwaite (1946) factor
``1 + 2 sum_m |corr_m|^2``, which lies between ``1 + 2 sum_m r_m^2`` (noise only,
``dof_factor``) and ``1 + 2 sum_m r_m`` (leakage only, ``chi2_factor``). The verdicts use the
upper bound, valid whatever the mix: with the noise-only factor the true Caltech truss failed
a Bonferroni family at alpha 0.01 on 2 of 40 seeds (cell ratios scattered 1.19 x more than
assumed), with the bound on none.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..checks import COHERENCE_CAP, match_channels, neighbour_coherence, user_stacklevel
from ..errors import DataError, DataWarning
from ..frd import FrequencyData, as_frequency_data
from ..lti import as_statespace, freqresp, log_ratio
from .estimator import (
    USER_WINDOW,
    EstimatorSettings,
    bin_correlation,
    effective_averages,
    estimator_settings,
    estimator_view,
    impact_settings,
    welch_window,
)
from .expected_coherence import expected_coherence, expected_coherence_modal, leakage_sigma
from .impact_view import exp_window_correlation, on_record_bins, truncation_settings

__all__ = [
    "coherence_weight_bias",
    "point_weight_bias",
    "NoiseModel", "noise_model", "residual_noise", "averages_of", "checked_noise_model", "checked_averages",
    "own_coherence_weights", "neighbour_coherence", "coherence_placeholders", "NO_NOISE_SENTENCE",
    "chi2_verdict", "plug_in_scores", "cell_chi2_factor", "format_p",
]

#: what a result says when it has no noise estimate
NO_NOISE_SENTENCE = "no noise estimate: no significance claims"

#: half-width (points) of the running robust scale of a measurement model's residual
RESIDUAL_HALF_WIDTH = 16

#: what a residual noise model adds to its source sentence when the window leakage is added
LEAKAGE_NOTE = ", plus the window leakage it implies at the resonances"

#: largest sigma (nepers / rad) a point may have to be tested: beyond it (coherence below about
#: 1 / (1 + 2 n_d 0.25)) the estimate is noise-dominated, ln H1 is far from Gaussian and biased
#: (Bendat & Piersol's error formulas assume small errors), so such points say nothing
SIGMA_TESTABLE = 0.5

#: false-alarm probability of "the coherence is not zero": a point is tested only when its
#: estimated coherence (its neighbours', :func:`neighbour_coherence`; so is its sigma against
#: :data:`SIGMA_TESTABLE`) exceeds the level that zero true coherence reaches with this
#: probability, ``1 - p^(1 / (n_d - 1))`` (Carter, Knapp & Nuttall 1973): at zero true
#: coherence the estimate is about 1/n_d, and the B&P error formula, fed such an estimate,
#: would claim a small error where the estimate is pure noise
COHERENCE_NULL_P = 1e-4

#: smallest sigma (nepers / rad): coherence 1 would otherwise claim a perfect estimate
SIGMA_FLOOR = 1e-4

#: distance from 1 (and from 0) within which a channel's coherence at *every* point is not an
#: H1 estimate of noisy data but a placeholder: a file's column of ones (or zeros), noise-free
#: simulated data. An estimate from ``n_d`` averages of a measurement with any noise is below
#: ``1 - 1e-12`` wherever the noise reaches 1e-6 of the signal in amplitude (``1 - g2 ~ N/S``)
PLACEHOLDER_COHERENCE_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """Standard deviation of the complex-log estimate at every data point.

    Attributes
    ----------
    f_hz : ndarray (nf,)
        Frequencies (Hz) the model describes.
    sigma : ndarray (nf, n_out, n_in)
        Standard deviation of ``Re ln G_data`` (nepers) and of ``Im ln G_data`` (rad), each.
    source : str
        Where the estimate came from, as a sentence fragment for results.
    averages : ndarray (n_in,) or None
        Effective number of averages per input column (coherence-based models).
    dof_factor : float
        ``1 + 2 sum_m r_m^2`` (``r_m``: :func:`robustctl.measure.estimator.bin_correlation`), the
        Satterthwaite factor of output noise alone (1: independent points); the sandwich
        covariances of update and diagnose scale their rows' noise variance by it.
    chi2_factor : float or None
        ``1 + 2 sum_m r_m``: the Satterthwaite factor of sums of squares over contiguous bins
        whatever the mix of noise and leakage (the module notes), used by the chi-square
        verdicts (:func:`chi2_verdict`). None: ``dof_factor``.
    kind : str
        ``"coherence"`` or ``"residual"``.
    testable : ndarray of bool (nf, n_out, n_in) or None
        Points where the log-normal error model holds (coherence significantly above zero
        and ``sigma <= SIGMA_TESTABLE``); verdicts use only these. None: every point.
    bin_r : ndarray or None
        ``r_m`` (``m = 0, 1, ..``), the output noise's H1 error correlation at bins ``m``
        apart (:func:`_correlation`); None: independent bins.
    force_share : ndarray (nf, n_out, n_in) or None
        Share of each point's variance ``2 sigma^2`` that the force channel's noise makes
        (an impact test's eq. N1, :func:`robustctl.measure.impact._force_noise`), in [0, 1].
    force_corr : ndarray or None
        Bound ``|D(m)| / D(0)`` on the correlation of that error at bins ``m`` apart.
    """

    f_hz: np.ndarray
    sigma: np.ndarray = field(repr=False)
    source: str
    averages: np.ndarray | None = None
    dof_factor: float = 1.0
    kind: str = "coherence"
    testable: np.ndarray | None = field(default=None, repr=False)
    chi2_factor: float | None = None
    bin_r: np.ndarray | None = field(default=None, repr=False)
    force_share: np.ndarray | None = field(default=None, repr=False)
    force_corr: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        f = np.asarray(self.f_hz, dtype=float).reshape(-1)
        sigma = np.asarray(self.sigma, dtype=float)
        if sigma.ndim == 1:
            sigma = sigma[:, None, None]
        if sigma.ndim != 3 or sigma.shape[0] != f.size:
            raise DataError(
                f"sigma must have shape (n_freq, n_out, n_in) with n_freq = {f.size}; got {sigma.shape}."
            )
        if not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
            raise DataError("sigma (standard deviation of ln G, nepers/rad) must be finite and positive.")
        # given ``testable`` (a coherence model's, chosen from the neighbours' coherence) is kept
        # as is: gating it again on the point's own sigma would select on its own error
        ok = sigma <= SIGMA_TESTABLE if self.testable is None else np.asarray(self.testable, dtype=bool)
        object.__setattr__(self, "f_hz", f)
        object.__setattr__(self, "sigma", sigma)
        object.__setattr__(self, "testable", ok)
        if self.chi2_factor is None:
            object.__setattr__(self, "chi2_factor", float(self.dof_factor))

    def band(self, mask: np.ndarray) -> NoiseModel:
        """The model on the points selected by a boolean mask over ``f_hz``."""
        mask = np.asarray(mask, dtype=bool)
        share = None if self.force_share is None else self.force_share[mask]
        return NoiseModel(self.f_hz[mask], self.sigma[mask], self.source, self.averages, self.dof_factor,
                          self.kind, self.testable[mask], self.chi2_factor, self.bin_r, share,
                          self.force_corr)

    def on(self, f_hz: np.ndarray) -> NoiseModel:
        """The model on the data points ``f_hz`` (a subset of its own grid)."""
        f = np.asarray(f_hz, dtype=float)
        idx = np.searchsorted(self.f_hz, f)
        idx = np.clip(idx, 0, self.f_hz.size - 1)
        if not np.allclose(self.f_hz[idx], f, rtol=1e-9, atol=0):
            raise DataError(
                "the noise model was made on another frequency grid; build it from the same data."
            )
        share = None if self.force_share is None else self.force_share[idx]
        return NoiseModel(f, self.sigma[idx], self.source, self.averages, self.dof_factor, self.kind,
                          self.testable[idx], self.chi2_factor, self.bin_r, share, self.force_corr)

    def normalised(self, error: np.ndarray) -> np.ndarray:
        """``error / sigma`` (complex): unit variance in each of the real and imaginary parts."""
        return np.asarray(error) / self.sigma

    def __repr__(self) -> str:
        return f"NoiseModel({self.kind}: {self.source}; median sigma {np.median(self.sigma):.3g})"


# ---------------------------------------------------------------------------- averages
def _experiment_metas(meta: dict, n_in: int) -> list[dict] | None:
    """One meta dict per input column, or None."""
    subs = meta.get("experiments")
    owner = meta.get("experiment_of_input")
    if isinstance(subs, (list, tuple)) and subs and isinstance(owner, (list, tuple)):
        if len(owner) != n_in or not all(0 <= int(k) < len(subs) for k in owner):
            return None
        picked = [subs[int(k)] for k in owner]
        return picked if all(isinstance(m, dict) for m in picked) else None
    if isinstance(subs, (list, tuple)) and subs:
        cols: list[dict] = []
        for m in subs:
            if not isinstance(m, dict):
                return None
            k = int(m.get("n_inputs", 1))
            cols += [m] * k
        return cols if len(cols) == n_in else None
    if "n_averages" in meta:
        return [meta] * n_in
    return None


def _described_metas(data: Any) -> list[dict] | None:
    """The averages an experiment description states (``data.experiment``), for data whose
    ``meta`` does not record them (an impact test, a file described on the command line)."""
    e = getattr(data, "experiment", None)
    if e is None or e.n_averages is None:
        return None
    m: dict = {"n_averages": e.n_averages}
    if e.welch_known and e.noverlap is not None and e.window != USER_WINDOW:
        m.update(nperseg=e.nperseg, noverlap=e.noverlap, window=e.window)
    return [m] * data.n_in


def _settings_meta(data: Any) -> dict:
    """``data.meta``, with the Welch settings of ``data.experiment`` when ``meta`` lacks them."""
    meta = dict(data.meta)
    e = getattr(data, "experiment", None)
    if e is not None and e.welch_known and e.window != USER_WINDOW and "fs_hz" not in meta:
        meta.update(fs_hz=e.fs_hz, nperseg=e.nperseg, window=e.window)
    return meta


def averages_of(data: Any) -> np.ndarray | None:
    """Effective number of independent averages per input column, or None when unknown.

    Reads ``meta["n_averages"]`` (and ``nperseg``, ``noverlap``, ``window`` for Welch's
    overlap correction) as :func:`robustctl.estimate_frf` records them, or
    ``meta["experiments"][k]`` for data joined by :func:`robustctl.combine_experiments`;
    ``q`` simultaneous inputs (partial coherence per channel) leave ``n_d - q + 1``.
    """
    return checked_averages(as_frequency_data(data))


def checked_averages(data: FrequencyData) -> np.ndarray | None:
    """:func:`averages_of` of data that are a FrequencyData already (not coerced again).

    Parameters
    ----------
    data : FrequencyData
        The estimate, as coerced at a public entry point.

    Returns
    -------
    ndarray (n_in,) or None
        Effective number of averages per input column; None when unknown.
    """
    metas = _experiment_metas(dict(data.meta), data.n_in)
    if metas is None:
        metas = _described_metas(data)
    if metas is None:
        return None
    out = []
    for m in metas:
        try:
            k = int(m["n_averages"])
        except (KeyError, TypeError, ValueError):
            return None
        nd = float(k)
        if all(key in m for key in ("nperseg", "noverlap", "window")):
            win, nperseg, noverlap = welch_window(m)  # checked: a damaged record is refused, named
            nd = effective_averages(k, win, nperseg, noverlap)
        q = int(m.get("n_inputs", 1))
        out.append(max(nd - q + 1, 1.0))
    return np.asarray(out)


def _correlation(data: Any) -> np.ndarray | None:
    """``r_m``, the H1 error correlation at bins ``m`` apart (module notes), or None when the
    bins are independent or the estimate's window is not known: a Welch window's
    (:func:`robustctl.measure.estimator.bin_correlation`) or an impact test's exponential
    window (:func:`robustctl.measure.impact_view.exp_window_correlation`)."""
    st = estimator_settings(_settings_meta(data))
    if st is not None:
        return bin_correlation(st.window, st.nperseg)
    e = getattr(data, "experiment", None)
    if e is None or e.excitation != "impact":
        return None
    st, _ = impact_settings(e, data.meta, data.f_hz)
    if st is None or st.exp_tau_s is None:
        return None
    if st.record is not None:
        fs, n = st.record.fs_hz, st.record.record_s * st.record.fs_hz
    elif e.fs_hz is not None and data.n_freq > 1:
        fs, n = e.fs_hz, e.fs_hz / float(np.min(np.diff(data.f_hz)))
    else:
        return None
    return exp_window_correlation(st.exp_tau_s, int(round(n)), fs)


def _dof_factor(r: np.ndarray | None) -> float:
    """``1 + 2 sum_m r_m^2``: the Satterthwaite factor of output noise alone (module notes)."""
    return 1.0 if r is None else float(1.0 + 2.0 * np.sum(r[1:] ** 2))


def _chi2_factor(r: np.ndarray | None) -> float:
    """``1 + 2 sum_m r_m``: the Satterthwaite factor of sums of squares over contiguous bins
    whatever the mix of output noise and leakage (module notes; ``r_m`` the H1 error correlation
    of output noise, :func:`robustctl.measure.estimator.bin_correlation`, whose square root bounds that
    of leakage errors)."""
    return 1.0 if r is None else float(1.0 + 2.0 * np.sum(r[1:]))


# ---------------------------------------------------------------------------- noise_model
def _sigma_of(g2: np.ndarray, nd: np.ndarray) -> np.ndarray:
    """Bendat & Piersol's random error of ``ln H1``: ``sqrt((1 - g2) / (2 n_d g2))``."""
    return np.sqrt((1.0 - g2) / (2.0 * nd[None, None, :] * g2))


#: Degrees of freedom the plug-in coherence costs (see :func:`_from_coherence`).
PLUG_IN_DOF = 2.0


def coherence_placeholders(coherence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Channels whose coherence is 1 (``ones``) or 0 (``zeros``) at every point, within
    :data:`PLACEHOLDER_COHERENCE_TOL`: a placeholder, not an estimate. Coherence 1 everywhere
    would give an H1 random error of zero (Bendat & Piersol Table 9.6), coherence 0 everywhere a
    channel of noise only (a disconnected sensor).

    Parameters
    ----------
    coherence : ndarray (nf, n_out, n_in)
        Coherence in [0, 1].

    Returns
    -------
    ones, zeros : ndarray of bool (n_out, n_in)
    """
    g2 = np.asarray(coherence, dtype=float)
    return (np.all(g2 >= 1.0 - PLACEHOLDER_COHERENCE_TOL, axis=0),
            np.all(g2 <= PLACEHOLDER_COHERENCE_TOL, axis=0))


def _warn_placeholders(data: Any, ones: np.ndarray, zeros: np.ndarray) -> None:
    """A :class:`~robustctl.errors.DataWarning` naming the channels of :func:`coherence_placeholders`."""
    def names(mask):
        return ", ".join(f"{data.outputs[o]} <- {data.inputs[i]}" for o, i in np.argwhere(mask))

    if np.all(ones):
        warnings.warn(
            "the data's coherence is 1 at every point of every channel: an H1 estimate of a measurement "
            "with noise is never exactly 1 (its random error would be zero), so it is a placeholder (a "
            "column of ones in a file, noise-free simulated data). The noise is not taken from it: give "
            "the estimate's real coherence, a measurement_model, or data.replace(coherence=None).",
            DataWarning, stacklevel=user_stacklevel(),
        )
    elif np.any(ones):
        warnings.warn(
            f"the data's coherence is 1 at every point of {names(ones)}: a placeholder, not an H1 "
            "estimate (its random error would be zero); those channels are left out of the noise test. "
            "Give the estimate's real coherence for them.",
            DataWarning, stacklevel=user_stacklevel(),
        )
    if np.any(zeros):
        warnings.warn(
            f"the data's coherence is 0 at every point of {names(zeros)}: those channels are noise only "
            "(a disconnected or overloaded sensor, an input that never reached the structure) or their "
            "coherence is missing; they carry no weight and are left out of the noise test. Check the "
            "channel, or drop it with data.select(...).",
            DataWarning, stacklevel=user_stacklevel(),
        )


def _from_coherence(data: Any, nd: np.ndarray) -> NoiseModel:
    """The noise model from each bin's own estimated coherence.

    With ``n`` averages the H1 error of a bin, given the input, is complex normal with variance
    ``s^2 / S_uu`` and independent of the residual power ``R = (1 - g2) S_yy``, which is
    ``s^2`` times a Gamma(``n - 1``) variable; the plug-in ``(1 - g2) / (n g2)`` therefore
    gives ``|e|^2 / sigma^2 = n Exp(1) / Gamma(n - 1)``, of mean ``n / (n - 2)`` (1.33 at 8
    averages; the normal-theory ratio of Bendat & Piersol sec. 9.2.3 assumes the true
    coherence). ``n_d - 2`` in place of ``n_d`` makes ``E |e|^2 / sigma^2 = 1``.
    """
    g2 = np.clip(np.asarray(data.coherence, dtype=float), 1e-12, 1.0)
    sigma = np.maximum(_sigma_of(g2, np.maximum(nd - PLUG_IN_DOF, 1.0)), SIGMA_FLOOR)
    nb = np.clip(neighbour_coherence(g2), 1e-12, 1.0)  # which points to test: independent of their error
    null_level = 1.0 - COHERENCE_NULL_P ** (1.0 / np.maximum(nd - 1.0, 1.0))
    testable = (nb > null_level[None, None, :]) & (_sigma_of(nb, nd) <= SIGMA_TESTABLE)
    testable &= ~coherence_placeholders(data.coherence)[0][None]
    nd_txt = ", ".join(f"{v:.3g}" for v in np.unique(np.round(nd, 2)))
    source = (
        f"the H1 random error from coherence and {nd_txt} effective averages (Bendat & Piersol "
        "Table 9.6)"
    )
    r = _correlation(data)
    share, corr = _force_noise_share(data, sigma)
    return NoiseModel(data.f_hz, sigma, source, nd, _dof_factor(r), "coherence", testable, _chi2_factor(r),
                      r, share, corr)


def _force_noise_share(data: Any, sigma: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The share of each point's variance ``2 sigma^2`` the force channel's noise makes, and that
    error's bin correlation, from an impact test's ``meta["force_noise"]`` (eq. N1 of
    :func:`robustctl.measure.impact._force_noise`); ``(None, None)`` without it or off its grid."""
    rec = data.meta.get("force_noise")
    e = getattr(data, "experiment", None)
    if not isinstance(rec, dict) or e is None or e.excitation != "impact" or data.n_in != 1:
        return None, None
    try:
        f = np.asarray(rec["f_hz"], dtype=float)
        v = np.asarray(rec["rel_var"], dtype=float)
        corr = np.asarray(rec["corr"], dtype=float).reshape(-1)
    except (KeyError, TypeError, ValueError):
        return None, None
    if f.shape != v.shape or f.size == 0 or corr.size == 0 or not np.all(np.isfinite(v)):
        return None, None
    idx = np.clip(np.searchsorted(f, data.f_hz), 0, f.size - 1)
    if not np.allclose(f[idx], data.f_hz, rtol=1e-9, atol=0):
        return None, None
    share = np.clip(v[idx][:, None, None] / (2.0 * sigma**2), 0.0, 1.0)
    return share, np.clip(corr, 0.0, 1.0)


def cell_chi2_factor(noise: NoiseModel, idx: np.ndarray, o: int, i: int) -> float:
    """Satterthwaite factor ``tr(C^2) / n`` of a sum of squares over the points ``idx`` (indices on
    the noise model's grid) of one channel, with the force noise's band-wide correlation.

    Each normalised error is the sum of an output-noise part, share ``1 - phi``, correlated
    ``sqrt(r_m)`` at bins ``m`` apart (:attr:`NoiseModel.bin_r`), and a force-noise part, share
    ``phi`` (:attr:`NoiseModel.force_share`), correlated at most ``force_corr[m]``;
    ``|C_jl| <= sqrt((1 - phi_j)(1 - phi_l)) sqrt(r_m) + sqrt(phi_j phi_l) force_corr[m]``. Never
    below the model's ``chi2_factor``.

    Parameters
    ----------
    noise : NoiseModel
    idx : ndarray of int
        The points of the sum.
    o, i : int
        Output and input index of the channel.

    Returns
    -------
    float
    """
    base = max(float(noise.chi2_factor), 1.0)
    if noise.force_share is None or noise.force_corr is None or idx.size == 0:
        return base
    phi = noise.force_share[idx, o, i]
    lag = np.abs(idx[:, None] - idx[None, :])
    fc = np.asarray(noise.force_corr)
    rf = np.where(lag < fc.size, fc[np.minimum(lag, fc.size - 1)], 0.0)
    if noise.bin_r is None:
        rn = (lag == 0).astype(float)
    else:
        r = np.sqrt(np.clip(np.asarray(noise.bin_r, dtype=float), 0.0, 1.0))
        rn = np.where(lag < r.size, r[np.minimum(lag, r.size - 1)], 0.0)
    q = np.sqrt(1.0 - phi)
    p = np.sqrt(phi)
    c = q[:, None] * q[None, :] * rn + p[:, None] * p[None, :] * rf
    return max(base, float(np.sum(c**2)) / idx.size)


def _running_scale(x: np.ndarray, half: int) -> np.ndarray:
    """1.4826 x running median of ``|x|`` over axes 0 and 1 (a robust local standard deviation).

    ``x`` has shape (nf, 2, n_out, n_in): real and imaginary parts pooled.
    """
    n = x.shape[0]
    out = np.empty(x.shape[:1] + x.shape[2:])
    for k in range(n):
        lo, hi = max(0, k - half), min(n, k + half + 1)
        out[k] = 1.4826 * np.median(np.abs(x[lo:hi]), axis=(0, 1))
    return out


def _impact_seen(data: Any, measurement_model: Any) -> EstimatorSettings | None:
    """The impact view of what a measurement model's fit removed: the exponential window
    (``window_tau_s``) and, when ``leakage_corrected``, the record end (eq. W2 of
    :mod:`robustctl.measure.impact_view`); None when it removed neither or the data are no
    impact test."""
    e = getattr(data, "experiment", None)
    if e is None or e.excitation != "impact":
        return None
    tau = getattr(measurement_model, "window_tau_s", None)
    corrected = bool(getattr(measurement_model, "leakage_corrected", False))
    record = truncation_settings(data.meta) if corrected else None
    if record is not None and not on_record_bins(data.f_hz, record):
        record = None
    if tau is None and record is None:
        return None
    return EstimatorSettings((e.fs_hz, None, "exponential"), None, False, "measured", False, impact=True,
                             exp_tau_s=tau, record=record)


def _from_residual(data: Any, measurement_model: Any) -> NoiseModel:
    """The noise from a measurement model's residual, the model seen as the impact estimator saw
    it when the fit removed the exponential window or the record end (:func:`_impact_seen`)."""
    sys = as_statespace(measurement_model)
    out_idx = match_channels(sys.output_labels, data.outputs, "outputs")
    in_idx = match_channels(sys.input_labels, data.inputs, "inputs")
    seen = _impact_seen(data, measurement_model)
    g = freqresp(sys, data.f_hz).response if seen is None else estimator_view(sys, data.f_hz, seen)
    g = g[:, out_idx][:, :, in_idx]
    modes = getattr(measurement_model, "n_modes", None)
    article = "an" if modes and str(modes)[0] in "8" or modes in (11, 18) else "a"
    what = f"{article} {modes}-mode measurement model" if modes else "a measurement model"
    nm = residual_noise(data, g, what)
    leak = _leakage_of(data, measurement_model, sys, out_idx, in_idx) if seen is None else None
    if leak is None:
        return nm
    return replace(nm, sigma=np.sqrt(nm.sigma**2 + leak**2), source=nm.source + LEAKAGE_NOTE)


def _leakage_of(data: Any, measurement_model: Any, sys: Any, out_idx: Any, in_idx: Any) -> np.ndarray | None:
    """The window leakage's share of the H1 error (:func:`leakage_sigma`) of a random test whose
    Welch settings and averages the data record, seen on the measurement model's identified modes
    (a system's every pole when it lists none: a filler pole of a fit, barely damped, would leak
    without bound); None for any other estimate (an impact test, a user's file without
    settings) or an unstable model."""
    st = estimator_settings(_settings_meta(data))
    nd = checked_averages(data)
    if st is None or not st.leakage or nd is None or np.any(data.f_hz > st.fs_hz / 2):
        return None
    modes = getattr(measurement_model, "modes", None)
    try:
        if modes and all(m.pole is not None and m.residue is not None for m in modes):
            p = np.array([m.pole for m in modes], dtype=complex)
            r = np.array([m.residue for m in modes], dtype=complex)
            g2 = expected_coherence_modal(np.concatenate([p, p.conj()]), np.concatenate([r, r.conj()]),
                                          np.zeros(r.shape[1:]), data.f_hz, st)
        else:
            g2 = expected_coherence(sys, data.f_hz, st)
    except DataError:
        return None
    return leakage_sigma(g2[:, out_idx][:, :, in_idx], nd)


def residual_noise(data: Any, model_response: np.ndarray, what: str = "a model") -> NoiseModel:
    """The noise model from a model's residual: the robust local scale (1.4826 x the running
    median absolute value over ``2 RESIDUAL_HALF_WIDTH + 1`` points, Re and Im pooled) of
    ``ln(G_data / G_model)`` per channel.

    Parameters
    ----------
    data : FrequencyData
        The estimate (Hz).
    model_response : ndarray, complex, shape (n_freq, n_out, n_in)
        The model's response at ``data.f_hz``, channels as in ``data``.
    what : str
        The model, for the noise model's ``source`` sentence.

    Returns
    -------
    NoiseModel
    """

    e = log_ratio(data.response, model_response)
    both = np.stack([e.real, e.imag], axis=1)  # (nf, 2, n_out, n_in): pool Re and Im
    sigma = _running_scale(both, RESIDUAL_HALF_WIDTH)
    sigma = np.maximum(sigma, SIGMA_FLOOR)
    r = _correlation(data)
    return NoiseModel(data.f_hz, sigma, f"noise estimated from the residual of {what}", None,
                      _dof_factor(r), "residual", None, _chi2_factor(r))


def noise_model(data: Any, *, measurement_model: Any = None, n_averages: Any = None) -> NoiseModel | None:
    """The noise model of an FRF estimate (see the module notes), or None when none can be made.

    Parameters
    ----------
    data : FrequencyData
        The estimate (Hz).
    measurement_model : system, optional
        A measurement model fitted to ``data`` (``rc.fit_measurement_model``) whose residual
        gives the noise when the data carry no coherence.
    n_averages : int or array_like (n_in,), optional
        Effective number of averages when the data's ``meta`` does not record them.

    Returns
    -------
    NoiseModel or None
        From coherence when the data carry coherence and the averages are known; else from
        the measurement model's residual; else None.
    """
    data = as_frequency_data(data)
    nd = None
    if data.coherence is not None:
        nd = checked_averages(data) if n_averages is None else _check_averages(n_averages, data.n_in)
    return checked_noise_model(data, nd, measurement_model)


def checked_noise_model(
    data: FrequencyData, averages: np.ndarray | None, measurement_model: Any = None
) -> NoiseModel | None:
    """:func:`noise_model` of data that are a FrequencyData already, with their averages known.

    Parameters
    ----------
    data : FrequencyData
        The estimate (Hz), as coerced at a public entry point (not coerced again).
    averages : ndarray (n_in,) or None
        Effective number of averages per input column (:func:`checked_averages`, or the
        user's ``n_averages`` checked); None when unknown.
    measurement_model : system, optional
        As for :func:`noise_model`.

    Returns
    -------
    NoiseModel or None
        From coherence when the data carry coherence and ``averages`` are known (channels
        whose coherence is 1 everywhere are not tested; coherence 1 in every channel is no noise
        model: :func:`coherence_placeholders`, with a DataWarning); else from the measurement
        model's residual; else None.
    """
    if data.coherence is not None and averages is not None:
        ones, zeros = coherence_placeholders(data.coherence)
        _warn_placeholders(data, ones, zeros)
        if not np.all(ones):
            return _from_coherence(data, averages)
    if measurement_model is not None:
        return _from_residual(data, measurement_model)
    return None


def _check_averages(value: Any, n_in: int) -> np.ndarray:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.size == 1:
        arr = np.full(n_in, arr[0])
    if arr.size != n_in or not np.all(np.isfinite(arr)) or np.any(arr < 1):
        raise DataError(
            f"n_averages must be a number >= 1 or one per input ({n_in}); got {value!r}."
        )
    return arr


# ---------------------------------------------------------------------------- tests and words
def plug_in_scores(t: np.ndarray, averages: float) -> np.ndarray:
    """Exponential scores of the normalised squared errors of a coherence noise model.

    With ``n = n_d`` averages a bin's ``t = |z|^2 / 2`` (``z = e / sigma``, ``sigma`` from the
    bin's own coherence with ``n - 2`` averages, :func:`_from_coherence`) is not ``Exp(1)``, as
    it would be with the true coherence, but ``(n - 2) Exp(1) / Gamma(n - 1)``: ``(n - 2) / (n - 1)``
    times an ``F(2, 2 (n - 1))`` variable, whose survival function is ``(1 + t / (n - 2))^-(n - 1)``.
    Its mean is 1, but its variance ``2 (n - 2) / (n - 3) - 1`` is 2 at 5 averages (1 for
    ``Exp(1)``) and infinite at 3: a chi-square test of ``sum t`` over a section flags the exact
    model far more often than its alpha (impact tests, one average per hit). The score

    ``x = (n - 1) ln(1 + t / (n - 2))``                                                 (S1)

    is ``-ln`` of that survival function, exactly ``Exp(1)`` at every ``n`` (a probability
    integral transform), and ``x -> t`` as ``n -> inf``.

    Parameters
    ----------
    t : ndarray
        ``|e / sigma|^2 / 2`` (dimensionless, mean 1 for the right model).
    averages : float
        Effective number of averages ``n_d`` of the column (``NoiseModel.averages``).

    Returns
    -------
    ndarray
        ``x``, shape of ``t``: independent ``Exp(1)`` variables for the right model.
    """
    n = float(averages)
    k = max(n - PLUG_IN_DOF, 1.0)  # the averages sigma was computed with
    m = max(n - 1.0, 1.0)  # the Gamma shape of the residual power
    return m * np.log1p(np.asarray(t, dtype=float) / k)


def chi2_verdict(
    z: np.ndarray, dof_factor: float, averages: float | None = None
) -> tuple[float, float, float]:
    """Chi-square test of normalised complex residuals ``z`` (unit variance per real part).

    ``S = sum |z|^2`` over ``n`` complex points has mean ``2n``; with correlated neighbouring
    bins it is approximately ``c chi2_nu`` (Satterthwaite 1946) with ``c = dof_factor`` (a
    noise model's ``chi2_factor``) and ``nu = 2n / c``. With ``averages`` (a coherence noise
    model's ``n_d`` of the column) the test sums the exact scores :func:`plug_in_scores`
    (``2 sum x`` in place of ``S``), which hold the false-alarm rate at few averages; the ratio
    reported is ``S / 2n`` either way. Returns ``(S / 2n, nu, p)``, ``p`` the upper-tail
    probability.
    """
    from scipy.stats import chi2

    z = np.asarray(z)
    n = z.size
    if n == 0:
        return float("nan"), 0.0, float("nan")
    z2 = np.abs(z) ** 2
    s = float(np.sum(z2))
    stat = s if averages is None else 2.0 * float(np.sum(plug_in_scores(z2 / 2.0, averages)))
    c = max(float(dof_factor), 1.0)
    nu = 2.0 * n / c
    return s / (2.0 * n), nu, float(chi2.sf(stat / c, nu))


def format_p(p: float) -> str:
    """A p-value in words: ``"p = 0.031"``, ``"p = 2.1e-05"`` or a bound ``"p < 1e-300"``, never 0."""
    if not np.isfinite(p):
        return "p = n/a"
    if p < 1e-300:
        return "p < 1e-300"
    if p < 1e-3:
        return f"p = {p:.1e}"
    return f"p = {p:.2g}"


def coherence_weight_bias(coherence: np.ndarray, n_averages: Any) -> np.ndarray:
    """What coherence weights add to ``Re ln H1``: ``c = (1 - g2) / ((n_d - 2) g2)``, nepers.

    With ``W = g2 / (1 - g2)`` (:func:`robustctl.checks.coherence_weights`) computed from each bin's own
    estimate, a weighted least-squares fit of ``ln G_model`` to ``ln H1`` solves
    ``sum W Re(conj(dE) e) = 0`` with ``e = ln(H1 / G)``, and ``W e`` has a non-zero mean at the
    true model. Write ``H1 = G (1 + eps)``: given the input spectrum, ``eps`` is circular complex
    Gaussian with ``E|eps|^2 = G_nn / (n_d |G|^2 G_uu)`` (averaged spectra), independent of the
    residual spectrum ``G_nn_hat ~ G_nn chi2_{2(n_d-1)} / (2 n_d)``, and
    ``W = |G|^2 |1 + eps|^2 G_uu / G_nn_hat``. Since ``ln(1 + eps)`` holds only powers
    ``eps^k`` (``E[eps^k] = E[|eps|^2 eps^k] = 0``, ``E[conj(eps) eps^k] = delta_k1 E|eps|^2``),

    ``E[|1 + eps|^2 ln(1 + eps)] = E|eps|^2``, so
    ``E[W e] = |G|^2 G_uu E[1 / G_nn_hat] E|eps|^2 = 1 / (n_d - 2)``                  (1)

    at every bin, whatever its coherence (``E[1 / chi2_nu] = 1 / (nu - 2)``); the imaginary part
    (phase) is unbiased. Subtracting ``c = 1 / ((n_d - 2) W) = 2 s^2 n_d / (n_d - 2)`` from
    ``Re e``, ``s^2 = (1 - g2) / (2 n_d g2)`` the B&P variance of each part of ``ln H1``
    (:mod:`robustctl.measure.noise`), makes ``sum W (e - c)`` unbiased: ``W c = 1 / (n_d - 2)`` exactly.
    To leading order ``c`` equals the weighted mean ``E[W e] / E[W] = 2 s^2 / (1 + 2 s^2)`` of a
    bin's log error, but that formula evaluated on the own coherence leaves 5-40 % of the bias
    at ``g2 <= 0.6`` (Monte Carlo, ``tests/test_cohbias.py``), eq. (1) none.

    ``g2`` is clipped as for the weights (at :data:`robustctl.checks.COHERENCE_CAP`) and, below, where ``s``
    exceeds :data:`robustctl.measure.noise.SIGMA_TESTABLE` (0.5): there ``|eps|`` often exceeds 1, the
    series behind eq. (1) diverges and the point is noise (``W`` is small; ``c`` stays
    bounded, at most ``0.5 n_d / (n_d - 2)``). ``n_d <= 3`` (no finite ``E[1 / G_nn_hat]``)
    uses ``n_d - 2 = 1``.

    Parameters
    ----------
    coherence : ndarray (nf, n_out, n_in)
        Ordinary (or multiple) coherence, dimensionless.
    n_averages : float or ndarray (n_in,)
        Effective number of averages per input column (:func:`robustctl.measure.noise.averages_of`).

    Returns
    -------
    ndarray, shape of ``coherence``
        ``c >= 0`` (nepers), to subtract from ``Re ln(G_data / G_model)``.
    """
    g2 = np.asarray(coherence, dtype=float)
    nd = np.asarray(n_averages, dtype=float)
    nd = nd.reshape((1,) * (g2.ndim - 1) + (-1,)) if nd.ndim else nd
    floor = 1.0 / (1.0 + 2.0 * nd * SIGMA_TESTABLE**2)  # g2 where s = SIGMA_TESTABLE
    g2 = np.clip(g2, floor, COHERENCE_CAP)
    return (1.0 - g2) / (np.maximum(nd - 2.0, 1.0) * g2)


def own_coherence_weights(spec: Any, data: FrequencyData) -> bool:
    """Whether point weights ``spec`` are the data's own coherence weights (``"auto"`` on data
    with coherence, or ``"coherence"``): the weights :func:`point_weight_bias` corrects for.

    Parameters
    ----------
    spec : None, "auto", "coherence" or array_like
        Point weights as in :func:`robustctl.checks.point_weights`.
    data : FrequencyData

    Returns
    -------
    bool
    """
    return isinstance(spec, str) and spec in ("auto", "coherence") and data.coherence is not None


def point_weight_bias(
    spec: Any, data: Any, mask: np.ndarray | None = None, n_averages: Any = None
) -> np.ndarray | None:
    """The offset :func:`coherence_weight_bias` of ``Re ln(G_data / G_model)`` that point weights
    ``spec`` (as in :func:`robustctl.checks.point_weights`) see, on the banded points; None when
    there is none.

    It applies only where the weights are the data's own coherence weights (``"auto"`` on data
    with coherence, or ``"coherence"``) and the number of averages is known (``n_averages``,
    else the data's ``meta``: :func:`averages_of`). Uniform weights and arrays
    of weights (whatever they were made from) are taken as they are: None.
    """
    if not own_coherence_weights(spec, data):
        return None
    if n_averages is None:
        n_averages = checked_averages(data)
        if n_averages is None:
            return None
    mask = np.ones(data.n_freq, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    return coherence_weight_bias(data.coherence[mask], n_averages)
