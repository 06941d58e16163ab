"""The steps of :func:`~robustctl.identify.fit_measurement_model` between data and modal model.

1. A rational fit with spare poles (``2 (n + spare)`` for ``n`` modes, vector fitting with the
   QR/Gram channel compression of Deschrijver et al. 2008, linear in the channels), or the
   Caltech route (one SIMO fit per input, SVD grouping, Balas & Doyle eqs. 9-10).
2. Mode selection (:mod:`.selection`): exactly ``n`` modes by contribution, out-of-band and
   heavily damped poles kept as fillers (listed apart), the rest dropped; rank-1 residues
   ``c b^T`` (Caltech eq. 9) refitted by alternating least squares.
3. Joint refinement of poles and shapes (:func:`.modal_refine.refine_modes_auto`: all at once
   on small problems, block by block on large ones), within the time budget.
   Without estimator settings, a close pair the rational fit merged (the residual stays above
   the noise across one mode's band) gets the weakest mode's pole (:func:`_swap_for_pair`).
4. Optionally the H1 leakage correction (:mod:`.leakage`) in a few fixed-point steps; for impact
   records the truncation at the record end (eq. T1) is in the refinement's model, fitted to
   the raw data (without refinement: a fixed point until the corrected data settle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..budget import Deadline
from ..errors import FitError
from ..frd import FrequencyData
from ..lti import log_ratio
from .grouping import group_modes
from .leakage import (
    EstimatorSettings,
    TruncationSettings,
    corrected_response,
    leakage_factor,
    leaks,
    truncated_residues,
)
from .leaked_refine import refine_through_estimator
from .modal_refine import DENSE_MAX_ENTRIES, ZETA_MIN, refine_modes_auto
from .poles import TIE_MARGIN, first_lowest, fit_residues
from .rational import fit_rational
from .rational_fit import RationalFit
from .realization import residue_rank
from .refine import _row_weights, refine_residues
from .selection import classify_poles, mode_counts, pole_contributions, split_pole
from .stabilisation import distinct_modes

__all__ = [
    "FitSettings",
    "spare_pairs",
    "select_modes",
    "modal_model",
    "fit_with_leakage",
    "fit_best",
    "shift_poles",
]

#: spare pole pairs beyond spare_pairs(n) tried by fit_best on small problems
EXTRA_SPARE = 2
#: fixed-point steps of the leakage correction
LEAKAGE_STEPS = 4
#: most fixed-point steps of an impact record's truncation correction (each removes the share
#: ``|exp(p (T - t_h))|`` of the error, up to 0.5 for modes far from decayed: 12 steps leave 2e-4)
TRUNCATION_STEPS = 12
#: rms relative change of the corrected data below which the truncation fixed point has converged
TRUNCATION_TOL = 1e-4
#: most swaps of the weakest mode for a second pole at a mode the data show to be a merged pair
MAX_SWAPS = 2
#: mean weighted residual energy over a mode's half-power band, in units of the band's median
#: per-point energy, from which the residual there shows an unmodelled mode (a chi-square with
#: 2 n_channels degrees of freedom per point rarely reaches 3 times its median over a few points)
EXCESS_RESIDUAL = 3.0


def spare_pairs(n_modes: int) -> int:
    """Spare pole pairs of the rational fit behind ``n_modes`` modes: ``max(2, ceil(n / 5))``."""
    return max(2, math.ceil(n_modes / 5))


@dataclass(frozen=True)
class FitSettings:
    """Settings shared by the steps (validated by the caller)."""

    groups: Any
    settings: Any  # EstimatorSettings or None
    fit_kw: dict
    rank_tol: float
    refine: bool
    deadline: Deadline | None = None  # the opt-in time budget (robustctl.budget), shared by the steps
    spare: bool = True
    progress: bool = False
    extra_spare: int = 0  # pole pairs beyond spare_pairs(n) (fit_best's candidate starts)

    def expired(self) -> bool:
        return self.deadline is not None and self.deadline.expired()


def rational_fit(band: FrequencyData, n_modes: int, run: FitSettings) -> RationalFit:
    """Step 1: common-denominator fit with spare poles, or one SIMO fit per input (Caltech)."""
    left = run.deadline  # fit_rational shares the call's Deadline
    if run.groups is not None:
        return fit_rational(band, 2 * n_modes, common_denominator=False, time_budget_s=left, **run.fit_kw)
    spare = spare_pairs(n_modes) + run.extra_spare if run.spare else 0
    # large problems: also start VF where the data change (small ones try several candidate fits)
    start = "lin" if _small(band, n_modes) else "data"
    return fit_rational(band, 2 * (n_modes + spare), time_budget_s=left, start_poles=start, **run.fit_kw)


def _splits(modes: np.ndarray, counts: np.ndarray, key: np.ndarray, n_modes: int) -> np.ndarray:
    """Which selected poles to split into close pairs: those counting 2, largest contribution first,
    while the total stays within ``n_modes``."""
    split = np.zeros(modes.size, dtype=bool)
    total = modes.size
    for j in np.argsort(-key[modes], kind="stable"):
        if counts[modes[j]] == 2 and total < n_modes:
            split[j], total = True, total + 1
    return split


def select_modes(fit: RationalFit, n_modes: int, prefer: np.ndarray | None = None) -> tuple[RationalFit, int]:
    """Step 2: keep exactly ``n_modes`` modes and the fillers; poles ordered modes (by frequency)
    then fillers; modes get rank-1 residues, fillers their numerical rank. A pole whose residue
    has rank 2 (:func:`.selection.mode_counts`) stands for a close pair and is split in two
    (:func:`.selection.split_pole`); two poles on one peak with one shape (window leakage) are one
    mode (:func:`.stabilisation.distinct_modes`). ``prefer`` (bool per pole) ranks those poles first (the
    stabilisation diagram's physical poles).

    Returns the new fit and the number of mode poles (the first ones)."""
    data = fit.data
    s = 2j * np.pi * data.f_hz
    rw = _row_weights(fit, None)
    contrib = pole_contributions(s, data.response, rw, fit.poles, fit.residues)
    key = contrib if prefer is None else contrib + np.where(prefer, 1e6, 0.0)
    counts = mode_counts(fit.residues, fit.poles)
    cplx = np.flatnonzero(fit.poles.imag != 0)
    duplicate = ~np.isin(np.arange(fit.poles.size), distinct_modes(cplx, fit.poles, fit.residues, key))
    exclude = duplicate & (fit.poles.imag != 0)
    cls = classify_poles(fit.poles, key, fit.band_hz, n_modes, counts=counts, exclude=exclude)
    split = _splits(cls.modes, counts, key, n_modes)
    poles, residues = [], []
    for j, k in enumerate(cls.modes):
        if split[j]:
            p2, r2 = split_pole(fit.poles[k], fit.residues[k])
            poles += list(p2)
            residues += list(r2)
        else:
            poles.append(fit.poles[k])
            residues.append(fit.residues[k])
    n = len(poles)
    poles = np.array(poles + list(fit.poles[cls.fillers]))
    order = np.r_[np.argsort(np.abs(poles[:n]), kind="stable"), n : poles.size]
    poles = poles[order]
    residues, d = fit_residues(s, data.response, rw, poles)
    # a filler keeps the numerical rank of its residue: it stands for out-of-band dynamics and
    # residual flexibility, not for one mode, and its realisation must reproduce its term exactly
    filler_ranks = [residue_rank(r.real if p.imag == 0 else r, 1e-8) for p, r in zip(poles[n:], residues[n:])]
    ranks = np.array([1] * n + filler_ranks, dtype=int)
    new = replace(fit, poles=poles, residues=residues, d=d, ranks=ranks)
    return refine_residues(new, sweeps=2), n


def _grouped(fit: RationalFit, run: FitSettings) -> tuple[RationalFit, int]:
    """Caltech route: SVD grouping; complex poles are the modes, real poles the fillers."""
    fit = group_modes(fit, run.groups, rank_tol=run.rank_tol)
    order = np.argsort(fit.poles.imag == 0, kind="stable")
    fit = replace(fit, poles=fit.poles[order], residues=fit.residues[order], ranks=fit.ranks[order])
    return fit, int(np.sum(fit.poles.imag != 0))


def modal_model(
    fit: RationalFit, n_modes: int, run: FitSettings, prefer: np.ndarray | None = None, truncation=None
) -> tuple[RationalFit, int]:
    """Steps 2-3 on a rational fit: the modal structure, then the refinement (if asked and in time).
    With ``truncation`` (an impact record that leaks) the refinement fits the truncated record's
    response (eq. T1) to ``fit.data``, the raw data, starting from residues fitted the same way."""
    fit, n_mode_poles = _grouped(fit, run) if run.groups is not None else select_modes(fit, n_modes, prefer)
    if run.refine and not run.expired():
        if truncation is not None:
            fit = _truncated_start(fit, truncation)
        fit = refine_modes_auto(fit, deadline=run.deadline, progress=run.progress, truncation=truncation)
    return fit, n_mode_poles


def _truncated_start(fit: RationalFit, truncation) -> RationalFit:
    """Residues of ``fit``'s poles fitted to the raw data with the leaked basis (eq. T1), modes
    cut to their ranks (rank 1) by the alternating least squares' start: the refinement's start."""
    s = 2j * np.pi * fit.data.f_hz
    residues, d = truncated_residues(s, fit.data.response, _row_weights(fit, None), fit.poles, truncation)
    return replace(fit, residues=residues, d=d)


def _residual_excess(fit: RationalFit, n_mode_poles: int) -> np.ndarray:
    """Per mode: the mean over the bins within its half-power band ``f (1 +- 3 zeta)`` (at least
    the two nearest bins) of the weighted residual energy ``sum_channels |rw (G - g)|^2`` (MACE
    eq. 5's relative error), over the median of that energy over the band: about 1 where the
    model explains the data to the noise, large where a mode is missing (a close pair merged)."""
    data = fit.data
    e = np.sum(np.abs(_row_weights(fit, None) * (fit.response(data.f_hz) - data.response)) ** 2, axis=(1, 2))
    floor = max(float(np.median(e)), np.finfo(float).tiny)
    out = np.zeros(n_mode_poles)
    f, zeta = fit.f_hz, fit.zeta
    for j in range(n_mode_poles):
        near = np.abs(data.f_hz - f[j]) <= 3 * zeta[j] * f[j]
        near[np.argsort(np.abs(data.f_hz - f[j]))[:2]] = True
        out[j] = float(np.mean(e[near])) / floor
    return out


def _swap_for_pair(fit: RationalFit, n_mode_poles: int, run: FitSettings) -> RationalFit:
    """Resolve a close pair the rational fit merged, keeping ``n_mode_poles`` modes.

    A vector fit started from spread poles can settle with one pole on two modes closer than
    their bandwidth whose summed residue is nearly rank 1 (the residue-rank split of
    :func:`select_modes` cannot see them) and spend the pole the second mode needs on noise; the
    residual then stays well above the noise across that mode's half-power band
    (:func:`_residual_excess`). The weakest mode (smallest contribution) is dropped, the
    mode with the largest excess split into two poles ``p (1 -+ delta)``, residues and shapes
    refitted and the model refined; the swap is kept when the weighted complex-log cost (MACE
    eq. 5) falls, so the ``n`` modes are those that explain the data best. At most
    ``MAX_SWAPS`` swaps, each a refinement, within the time budget."""
    if n_mode_poles < 2 or fit.data is None:
        return fit
    data = fit.data
    s = 2j * np.pi * data.f_hz
    rw = _row_weights(fit, None)
    cost = _log_cost(fit, data)
    tried: list[float] = []
    for _ in range(MAX_SWAPS):
        if run.expired():
            break
        excess = _residual_excess(fit, n_mode_poles)
        for f0 in tried:  # one try per place
            excess[np.abs(fit.f_hz[:n_mode_poles] / f0 - 1) < 1e-3] = 0.0
        j = int(np.argmax(excess))
        if excess[j] < EXCESS_RESIDUAL:
            break
        tried.append(float(fit.f_hz[j]))
        contrib = pole_contributions(s, data.response, rw, fit.poles, fit.residues)[:n_mode_poles]
        contrib[j] = np.inf
        weak = int(np.argmin(contrib))
        p0 = fit.poles[j]
        delta = max(0.25 * float(fit.zeta[j]), 1e-4)  # as split_pole: a quarter of the damping ratio
        pair = p0.real + 1j * p0.imag * np.array([1 - delta, 1 + delta])
        keep = np.setdiff1d(np.arange(fit.poles.size), [j, weak])
        modes = np.concatenate([pair, fit.poles[keep[keep < n_mode_poles]]])
        poles = np.concatenate([modes[np.argsort(np.abs(modes), kind="stable")], fit.poles[n_mode_poles:]])
        residues, d = fit_residues(s, data.response, rw, poles)
        trial = replace(fit, poles=poles, residues=residues, d=d)
        trial = refine_residues(trial, sweeps=2)
        trial = refine_modes_auto(trial, deadline=run.deadline, progress=run.progress)
        trial_cost = _log_cost(trial, data)
        if trial_cost < cost * (1 - TIE_MARGIN):  # a swap that ties the current model is not kept
            fit, cost = trial, trial_cost
    return fit


def _small(band: FrequencyData, n_modes: int) -> bool:
    """Whether the dense joint refinement of ``n_modes`` modes is affordable on ``band``."""
    n_out, n_in = band.response.shape[1:]
    n_par = (n_modes + spare_pairs(n_modes)) * (2 + 2 * (n_out + n_in)) + n_out * n_in
    return band.f_hz.size * n_out * n_in * n_par <= DENSE_MAX_ENTRIES


def fit_best(
    band: FrequencyData, n_modes: int, run: FitSettings, first: RationalFit | None = None, prefer=None
) -> tuple[RationalFit, int, FrequencyData]:
    """:func:`fit_with_leakage` with spare poles; on small problems (dense refinement affordable)
    the route with exactly ``2 n_modes`` poles is tried too and the better modal start (before
    refinement) goes on: the one that gives ``n_modes`` modes, of the two (or if neither does)
    the lower weighted complex-log cost (MACE eq. 5).

    Without a leakage fixed point (no estimator settings) the small problem's candidates are
    finished instead (refined) and the lowest final weighted cost wins, with ``EXTRA_SPARE`` more
    spare pairs tried too: a vector fit with few data points per pole can land on a poor local
    solution at one order and not at the next (the DaISy CD-player arm: 38 bins, 6 modes; 16
    poles give 2.10 dB where coherence > 0.9, 20 poles 1.32 dB), and the modes are chosen and
    refined the same way from each start, the extra poles staying as fillers."""
    if run.groups is not None or not _small(band, n_modes) or run.expired():
        return fit_with_leakage(band, n_modes, run, first, prefer)
    if run.settings is None:
        return _best_finished(band, n_modes, run, first, prefer)
    staged = []
    for r, start, pref in ((run, first, prefer), (replace(run, spare=False), None, None)):
        start = rational_fit(band, n_modes, r) if start is None else start
        modal, n_found = select_modes(start, n_modes, pref)
        staged.append(((n_found != n_modes, _log_cost(modal, band)), r, start, pref))
    _, r, start, pref = staged[first_lowest([item[0] for item in staged])]
    return fit_with_leakage(band, n_modes, r, start, pref)


def _best_finished(band: FrequencyData, n_modes: int, run: FitSettings, first, prefer):
    """The candidates of :func:`fit_best` refined; exactly ``n_modes`` modes first, then the lowest
    weighted complex-log cost. Stops trying when the time budget runs out."""
    routes = [(run, first, prefer), (replace(run, spare=False), None, None)]
    routes += [(replace(run, extra_spare=k), None, None) for k in range(1, EXTRA_SPARE + 1)]
    done = []
    for r, start, pref in routes:
        if done and run.expired():
            break
        fit, n_found, used = fit_with_leakage(band, n_modes, r, start, pref)
        done.append(((n_found != n_modes, _log_cost(fit, used)), (fit, n_found, used)))
    return done[first_lowest([item[0] for item in done])][1]


def _log_cost(fit: RationalFit, data: FrequencyData) -> float:
    """Weighted complex-log cost ``sum w |log(g / G)|^2`` (the weights of the fit, MACE eq. 5)."""
    w = (_row_weights(replace(fit, data=data), None) * np.abs(data.response)) ** 2
    return float(np.sum(w * np.abs(log_ratio(data.response, fit.response(data.f_hz))) ** 2))


def fit_with_leakage(
    band: FrequencyData, n_modes: int, run: FitSettings, first: RationalFit | None = None, prefer=None
) -> tuple[RationalFit, int, FrequencyData]:
    """Steps 1-4: fit (or start from ``first``), modal structure, leakage fixed point.

    With ``refine`` each leakage step re-refines the modal model on the newly corrected data
    (warm start); without, the rational fit is redone and the modal structure imposed at the end.
    Returns (fit, number of mode poles, data used).
    """
    st = run.settings
    fit = rational_fit(band, n_modes, run) if first is None else first
    if isinstance(st, TruncationSettings) and run.refine:
        return _fit_truncated(band, fit, n_modes, run, prefer)
    n_mode_poles = 0
    if st is None or run.refine:
        fit, n_mode_poles = modal_model(fit, n_modes, run, prefer)
    if st is None and run.refine and run.groups is None:
        fit = _swap_for_pair(fit, n_mode_poles, run)
    if isinstance(st, EstimatorSettings) and run.refine and not run.expired():
        return _through_estimator(band, fit, n_mode_poles, st, run)
    data = band
    for _ in range(_leakage_steps(fit, band, st)):
        if run.expired():
            break
        previous = data.response
        corrected = corrected_response(fit, band, st, _row_weights(fit, None))
        if not np.all(np.isfinite(corrected)):  # the model's correction overflowed: keep the last step
            break
        data = band.replace(response=corrected, meta={**band.meta, "leakage_corrected": True})
        if _converged(previous, data.response, st):
            break
        if run.refine:
            try:
                fit = refine_modes_auto(refine_residues(replace(fit, data=data)), deadline=run.deadline,
                                        progress=run.progress)
            except ValueError:  # two poles merged onto one peak: a singular step; keep the last model
                break
        else:
            fit = rational_fit(data, n_modes, run)
    if st is not None and not run.refine:
        fit, n_mode_poles = modal_model(fit, n_modes, run)
    return fit, n_mode_poles, data


def _through_estimator(band: FrequencyData, fit: RationalFit, n_mode_poles: int, st: EstimatorSettings, run):
    """A white-noise H1 test's modal model: poles and shapes fitted so that the model's expected H1
    matches the raw data (:func:`.leaked_refine.refine_through_estimator`), then the mode shapes
    (rank 1) refitted on the data corrected by that model (``data * M / E[H1 of M]``, on which the
    model is scored and its modes judged); then one joint rank-1 refinement on those data (the
    in-band real fillers' residues refitted too: the vector fit's, held, were decided by where
    that fit stopped) and the data corrected once more by its result."""
    fit = replace(fit, data=band)
    moved = refine_through_estimator(fit, band, st, _row_weights(fit, None))
    factor = leakage_factor(moved, band.f_hz, st)
    if not (np.all(np.isfinite(moved.poles)) and np.all(np.isfinite(factor))):
        moved, factor = fit, leakage_factor(fit, band.f_hz, st)
    data = band.replace(response=band.response * factor, meta={**band.meta, "leakage_corrected": True})
    fit = refine_residues(replace(moved, data=data), sweeps=2)
    if run.refine and not run.expired():  # rank-1 poles and shapes together, one step from there
        try:
            refined = refine_modes_auto(fit, deadline=run.deadline, progress=run.progress, real_residues=True)
        except ValueError:  # two poles merged onto one peak: a singular step; keep the last model
            refined = fit
        factor = leakage_factor(refined, band.f_hz, st)
        if np.all(np.isfinite(factor)):
            data = band.replace(response=band.response * factor, meta=data.meta)
            fit = refine_residues(replace(refined, data=data), sweeps=2)
    return fit, n_mode_poles, data


def _fit_truncated(band: FrequencyData, fit: RationalFit, n_modes: int, run: FitSettings, prefer):
    """An impact record's modal model: the modes refined against the raw data with the record-end
    truncation in the model (eq. T1 in the refinement, :func:`.modal_refine.refine_modes`), when
    the record leaks; the data used are the raw data plus the fitted model's tail (the corrected
    data, on which the model is scored and its modes judged)."""
    fit = replace(fit, data=band)
    leaky = leaks(select_modes(fit, n_modes, prefer)[0], band, run.settings)
    fit, n_mode_poles = modal_model(fit, n_modes, run, prefer, truncation=run.settings if leaky else None)
    if not leaky:
        return fit, n_mode_poles, band
    corrected = corrected_response(fit, band, run.settings)
    if not np.all(np.isfinite(corrected)):
        raise FitError(
            f"the record-truncation correction of the {n_modes}-mode model is not finite (a tail term "
            "left the floating-point range); pass correct_window=False, lower n_modes or narrow the band."
        )
    data = band.replace(response=corrected, meta={**band.meta, "leakage_corrected": True})
    return replace(fit, data=data), n_mode_poles, data


def _leakage_steps(fit: RationalFit, band: FrequencyData, st) -> int:
    """Fixed-point steps: none without settings or when an impact record has decayed."""
    if st is None or not leaks(fit, band, st):
        return 0
    return TRUNCATION_STEPS if isinstance(st, TruncationSettings) else LEAKAGE_STEPS


def _converged(previous: np.ndarray, current: np.ndarray, st) -> bool:
    """Truncation fixed point: the corrected data moved by less than ``TRUNCATION_TOL`` (rms of the
    relative change over the band)."""
    if not isinstance(st, TruncationSettings):
        return False
    change = np.abs(current - previous) / np.maximum(np.abs(current), np.finfo(float).tiny)
    return float(np.sqrt(np.mean(change**2))) < TRUNCATION_TOL


def shift_poles(fit: RationalFit, sigma: float) -> RationalFit:
    """Add ``sigma`` (1/s) to every pole's real part, keeping it below ``-ZETA_MIN |p|``.

    An exponential window ``exp(-t/tau)`` on an impulse response moves every pole by ``-1/tau``
    (``r e^{pt} e^{-t/tau} = r e^{(p - 1/tau) t}``), so ``sigma = 1/tau`` undoes it: the damping
    ratio falls by ``1/(tau w_n)`` (Ewins, *Modal Testing*, sec. 3.11)."""
    p = fit.poles + sigma
    p = np.where(p.real < -ZETA_MIN * np.abs(p), p, -ZETA_MIN * np.abs(p) + 1j * p.imag)
    return replace(fit, poles=p.astype(complex))
