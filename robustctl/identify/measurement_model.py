"""``fit_measurement_model``: the project's yardstick, the best linear description of what was
measured, in one call.

The procedure: (1) a common-denominator rational fit (VF or Chebyshev) of the band, or the
Caltech route of one SIMO fit per input joined by :func:`combine_simo` and reduced by
:func:`group_modes`; (2) optionally, for white-noise tests estimated by :func:`robustctl.estimate_frf`,
a few fixed-point steps that undo the estimator's window leakage (see :mod:`.leakage`); (3) the
residue of each mode given its physical rank (1 per mode, or the group's count) and refined
together with the poles by nonlinear least squares (:mod:`.modal_refine`); (4) the
complex-log cost of MACE eq. 5. With ``n_modes=None`` the order is chosen from the cost
versus order with a parsimony rule.
"""

from __future__ import annotations

import html
import warnings
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from ..checks import UNSET, as_frequency_data, band_data, renamed_keyword
from ..errors import FitError
from ..frd import FrequencyData
from ..lti import rebuild_statespace, statespace_state
from ..modes import Mode
from ..table import Table
from ..threads import limit_blas
from .cost import LogCost, channel_cost
from .grouping import group_modes
from .leakage import EstimatorSettings, estimator_settings, leakage_factor
from .modal_refine import ZETA_MIN, refine_modes
from .rational import IdentifyWarning, RationalFit, fit_rational
from .realization import residue_factors
from .refine import refine_residues

__all__ = ["Mode", "MeasurementModel", "fit_measurement_model"]

#: fixed-point steps of the leakage correction
LEAKAGE_STEPS = 4


@dataclass(frozen=True, eq=False)
class MeasurementModel:
    """A measurement model: state space, modes and complex-log cost against the data.

    Attributes
    ----------
    sys : control.StateSpace
        Real modal realisation with the data's signal names.
    modes : tuple of Mode
        Complex modes sorted by frequency (real poles, if any, are in ``sys`` and ``fit`` only).
    cost : LogCost
        MACE eq. 5 of ``sys`` against ``data`` (per channel and total).
    fit : RationalFit
        The underlying pole-residue model (ranks as realised).
    data : FrequencyData
        The band data the model was scored on (leakage-corrected when ``leakage_corrected``).
    raw_data : FrequencyData
        The band data as measured.
    leakage_corrected : bool
        Whether the estimator's window leakage was undone before fitting.
    order_scan : tuple of (int, float)
        ``(n_modes, total cost)`` of every order tried by the automatic order selection.
    """

    sys: Any
    modes: tuple[Mode, ...]
    cost: LogCost
    fit: RationalFit
    data: FrequencyData
    raw_data: FrequencyData
    leakage_corrected: bool = False
    order_scan: tuple[tuple[int, float], ...] = ()

    def statespace(self):
        """The real modal ``control.StateSpace`` (the state-space protocol, :func:`rc.as_statespace`)."""
        return self.sys

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(self.fit.inputs)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self.fit.outputs)

    def summary(self) -> str:
        """A few sentences in plain words."""
        lo, hi = self.band_hz
        lines = [
            f"MeasurementModel of {len(self.outputs)} outputs x {len(self.inputs)} inputs on "
            f"{lo:.4g}-{hi:.4g} Hz: {self.n_modes} modes, {self.sys.nstates} states.",
            f"Complex-log cost J = {self.cost.total:.4g} (MACE eq. 5), rms log-magnitude error "
            f"{self.cost.rms_db_total:.3g} dB.",
        ]
        if self.leakage_corrected:
            lines.append("The data were corrected for the H1 estimator's window leakage before fitting.")
        if self.order_scan:
            lines.append(
                "Orders tried (n_modes: J): " + ", ".join(f"{n}: {j:.3g}" for n, j in self.order_scan) + "."
            )
        return "\n".join(lines)

    def __reduce__(self):
        """Pickle the state space as matrices and names (python-control's StateSpace holds a lambda)."""
        state = {f.name: getattr(self, f.name) for f in fields(self)}
        state["sys"] = statespace_state(self.sys)
        return (_rebuild_measurement_model, (state,))

    @property
    def n_modes(self) -> int:
        """Number of modes (sum of mode ranks)."""
        return int(sum(m.rank for m in self.modes))

    @property
    def band_hz(self) -> tuple[float, float]:
        return self.fit.band_hz

    def freqresp(self, f_hz: Any) -> FrequencyData:
        """Model response at ``f_hz`` (Hz)."""
        return self.fit.freqresp(f_hz)

    def table(self) -> Table:
        """One row per mode: frequency, damping, rank, largest residue entry."""
        rows = [
            (k, m.f_hz, 100 * m.zeta, m.rank, float(np.max(np.abs(m.residue))))
            for k, m in enumerate(self.modes, start=1)
        ]
        cols = ("mode", "f (Hz)", "damping (%)", "rank", "max |residue|")
        title = (
            f"Measurement model: {self.n_modes} modes, band {self.band_hz[0]:.4g}-{self.band_hz[1]:.4g} Hz, "
            f"rms log-magnitude error {self.cost.rms_db_total:.3g} dB"
        )
        return Table(cols, rows, title=title)

    def plot(self, max_channels: int = 9):
        """Data and model per channel, magnitude and phase (matplotlib Figure)."""
        from ..plots import bode_grid

        model = self.fit.freqresp(self.data.f_hz)
        label = "data (leakage-corrected)" if self.leakage_corrected else "data"
        return bode_grid(
            [self.data, model],
            [label, f"model ({self.n_modes} modes)"],
            max_channels=max_channels,
            phase=True,
            title=f"Measurement model, rms error {self.cost.rms_db_total:.3g} dB",
        )

    def _repr_html_(self) -> str:
        summary = "".join(f"<p>{html.escape(line)}</p>" for line in self.summary().splitlines())
        return summary + self.table()._repr_html_() + self.cost.table()._repr_html_()

    def __repr__(self) -> str:
        return (
            f"MeasurementModel({self.n_modes} modes, {self.sys.nstates} states, "
            f"rms error {self.cost.rms_db_total:.3g} dB, J = {self.cost.total:.4g})"
        )


# ---------------------------------------------------------------------------- procedure
def _settings(fd: FrequencyData, correct_leakage: Any) -> EstimatorSettings | None:
    if correct_leakage is False:
        return None
    st = estimator_settings(fd.meta)
    if correct_leakage is True and st is None:
        raise FitError(
            "correct_leakage=True needs the estimator settings (fs_hz, nperseg, window) in data.meta, "
            "as recorded by rc.estimate_frf; pass correct_leakage=False for other data."
        )
    if correct_leakage not in (True, "auto"):
        raise FitError(f"correct_leakage must be True, False or 'auto'; got {correct_leakage!r}.")
    return st


def _fit_once(band: FrequencyData, order: int, groups: Any, kw: dict) -> RationalFit:
    """The rational fit: common denominator, or one SIMO fit per input (Caltech) when grouping."""
    return fit_rational(band, order, common_denominator=groups is None, **kw)


def _modal(fit: RationalFit, groups: Any, rank_tol: float, refine: bool) -> RationalFit:
    """Physical structure: SVD groups (Caltech) or one rank-1 mode per pole, then (optionally) the
    joint nonlinear refinement of poles and shapes (:func:`refine_modes`)."""
    if groups is not None:
        fit = group_modes(fit, groups, rank_tol=rank_tol)
    else:
        fit = refine_residues(replace(fit, ranks=np.ones(len(fit.poles), dtype=int)))
    return refine_modes(fit) if refine else fit


def _fit_corrected(band: FrequencyData, order: int, groups: Any, st, kw: dict, rank_tol: float, refine: bool):
    """Fit, then undo leakage in LEAKAGE_STEPS fixed-point steps; returns (final fit, data used).

    With ``refine`` each step re-refines the current modal model on the newly corrected data
    (warm start); without, the rational fit is redone and the modal structure imposed at the end.
    """
    if st is None or refine:
        fit = _modal(_fit_once(band, order, groups, kw), groups, rank_tol, refine)
    else:
        fit = _fit_once(band, order, groups, kw)
    data = band
    for _ in range(LEAKAGE_STEPS if st is not None else 0):
        data = band.replace(response=band.response * leakage_factor(fit, band.f_hz, st),
                            meta={**band.meta, "leakage_corrected": True})
        if refine:
            fit = refine_modes(refine_residues(replace(fit, data=data)))
        else:
            fit = _fit_once(data, order, groups, kw)
    if st is not None and not refine:
        fit = _modal(fit, groups, rank_tol, refine)
    return fit, data


def _score(fit: RationalFit, data: FrequencyData) -> LogCost:
    return channel_cost(data.response, fit.response(data.f_hz), fit.outputs, fit.inputs)


def _final_prediction_error(fit: RationalFit, cost: LogCost) -> float:
    """Akaike's final prediction error ``J (N + p) / (N - p)``: the cost penalised by the model's
    real parameter count ``p`` (per complex pole 2 + 2 rank (n_out + n_in), per real pole
    1 + n_out n_in, plus D) against the ``N`` real residuals, so fitting noise does not pay."""
    n_out, n_in = fit.d.shape
    cplx = fit.poles.imag != 0
    p = np.sum(np.where(cplx, 2 + 2 * fit.ranks * (n_out + n_in), 1 + n_out * n_in)) + n_out * n_in
    n = 2 * cost.n_freq * n_out * n_in
    return cost.total * (n + p) / (n - p) if p < n else np.inf


def _spurious(fit: RationalFit) -> bool:
    """True when a mode's damping sits at the refinement's lower bound ``ZETA_MIN``: an undamped
    line that fits noise or estimator artefacts next to a real peak, not structure."""
    cplx = fit.poles.imag != 0
    return bool(np.any(fit.zeta[cplx] < 1.5 * ZETA_MIN))


def _select_order(band, groups, st, kw, rank_tol, max_modes, parsimony, target_db, refine):
    """Cost versus order: the smallest n_modes without spurious modes whose final prediction
    error is within ``parsimony`` of the best such (or the smallest meeting ``target_db``); the
    scan stops after three orders without a 5 % gain."""
    scan, results, best, stale = [], {}, np.inf, 0
    for n in range(1, max_modes + 1):
        try:
            fit, data = _fit_corrected(band, 2 * n, groups, st, kw, rank_tol, refine)
        except FitError:
            break
        cost = _score(fit, data)
        fpe = _final_prediction_error(fit, cost)
        scan.append((n, cost.total))
        results[n] = (fit, data, cost, fpe)
        if target_db is not None and cost.rms_db_total <= target_db:
            return results[n][:3], tuple(scan)
        stale = 0 if fpe < 0.95 * best else stale + 1
        best = min(best, fpe)
        if stale >= 3:
            break
    if not results:
        raise FitError("no order could be fitted; check the band (too few points?) and the data.")
    clean = {n: r for n, r in results.items() if not _spurious(r[0])} or results
    best_clean = min(r[3] for r in clean.values())
    chosen = min(n for n, r in clean.items() if r[3] <= (1 + parsimony) * best_clean)
    return results[chosen][:3], tuple(scan)


def _modes(fit: RationalFit) -> tuple[Mode, ...]:
    out = []
    for p, f, z, r, k in zip(fit.poles, fit.f_hz, fit.zeta, fit.residues, fit.ranks):
        if p.imag == 0 or k == 0:
            continue
        c, b = residue_factors(r, int(k))
        mode = Mode(float(f), float(z), r, complex(p), int(k), output_shape=c, input_shape=b)
        out.append(mode)
    return tuple(out)


@limit_blas
def fit_measurement_model(
    data: Any,
    n_modes: int | None = None,
    band: tuple[float, float] | None = None,
    method: str = "vf",
    groups: Any = None,
    point_weights: Any = "auto",
    correct_leakage: bool | str = False,
    rank_tol: float = 0.1,
    max_modes: int = 24,
    parsimony: float = 0.1,
    target_db: float | None = None,
    max_iter: int | None = None,
    refine: bool = True,
    *,
    weights: Any = UNSET,
) -> MeasurementModel:
    """Identify a measurement model of frequency-response data in one call.

    Parameters
    ----------
    data : FrequencyData (or what :func:`fit_rational` accepts)
        Measured response, Hz.
    n_modes : int, optional
        Number of lightly damped modes (the fit has ``2 n_modes`` poles; with ``groups`` this
        is the modes per SIMO fit). ``None``: chosen automatically from the cost versus order:
        among the orders without spurious modes (damping at the refinement's lower bound
        ``ZETA_MIN``), the smallest whose final prediction error (the cost penalised by
        the parameter count, Akaike) is within ``parsimony`` (relative) of the best.
    band : (f_lo, f_hi), optional
        Band in Hz.
    method : {"vf", "chebyshev"}
        Pole identification (see :func:`fit_rational`).
    groups : optional
        Use the Caltech route: one SIMO fit of ``n_modes`` modes per input, combined, then
        grouped by :func:`group_modes` with this ``groups`` argument (e.g. ``(2, 1, 2, 1)``).
    point_weights : "auto", None, "coherence" or array_like
        Data-point weights of the fits on the squared log error
        (:func:`robustctl.checks.point_weights`; default coherence weights when the data carry
        coherence). ``weights=`` is the deprecated name. The reported ``cost`` is unweighted.
    correct_leakage : False, True or "auto"
        Undo the H1 estimator's window leakage (see :mod:`robustctl.identify.leakage`). It
        assumes white (flat-spectrum) ZOH excitation, as in the Caltech random-noise tests, and
        the estimator settings in ``data.meta``; "auto" applies it when those settings are
        there. Off by default: with coloured or swept inputs (e.g. the DaISy records) the
        white-noise leakage model is wrong and makes the fit worse.
    rank_tol : float
        With ``groups``: relative singular-value threshold of automatic mode counts in
        :func:`group_modes`. Without: unused, every pole is one physical mode with a rank-1
        residue ``c b^T`` refined by least squares (:func:`refine_residues`).
    max_modes : int
        Largest ``n_modes`` tried by the automatic selection.
    parsimony : float
        Relative cost slack of the automatic selection (0.1: within 10 % of the best).
    target_db : float, optional
        Required rms log-magnitude error (dB); a :class:`FitError` says so when it is missed.
    max_iter : int, optional
        Iteration cap of each pole identification (default: that of :func:`fit_rational`).
    refine : bool
        Refine poles and mode shapes together by nonlinear least squares with the rank
        structure imposed (:func:`refine_modes`); this is what resolves near-coincident modes.

    Returns
    -------
    MeasurementModel
    """
    max_modes, parsimony = _check_selection(max_modes, parsimony)
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    fd = as_frequency_data(data)
    band_fd = band_data(fd, band)
    st = _settings(fd, correct_leakage)
    kw = dict(method=method, point_weights=point_weights, max_iter=max_iter)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifyWarning)
        if n_modes is None:
            (fit, used, cost), scan = _select_order(
                band_fd, groups, st, kw, rank_tol, max_modes, parsimony, target_db, refine
            )
        else:
            fit, used = _fit_corrected(band_fd, 2 * _check_modes(n_modes), groups, st, kw, rank_tol, refine)
            cost, scan = _score(fit, used), ()
    if target_db is not None and cost.rms_db_total > target_db:
        raise FitError(
            f"the measurement model reaches {cost.rms_db_total:.3g} dB rms log-magnitude error, above the "
            f"target {target_db:g} dB; raise n_modes (or leave it None), narrow the band or relax target_db."
        )
    return MeasurementModel(fit.statespace(), _modes(fit), cost, fit, used, band_fd, st is not None, scan)


def _check_selection(max_modes: Any, parsimony: Any) -> tuple[int, float]:
    """Validated settings of the automatic order selection."""
    integer = isinstance(max_modes, (int, np.integer)) and not isinstance(max_modes, (bool, np.bool_))
    if not integer or max_modes < 1:
        raise FitError(
            f"max_modes must be a positive integer (the largest n_modes tried); got {max_modes!r}."
        )
    try:
        parsimony = float(parsimony)
    except (TypeError, ValueError):
        parsimony = float("nan")
    if not (np.isfinite(parsimony) and parsimony >= 0):
        raise FitError(
            f"parsimony must be a finite relative cost slack >= 0 (0.1: within 10 % of the best order); "
            f"got {parsimony!r}."
        )
    return int(max_modes), parsimony


def _check_modes(n_modes: Any) -> int:
    if isinstance(n_modes, (bool, np.bool_)) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise FitError(f"n_modes must be a positive integer (or None for automatic); got {n_modes!r}.")
    return int(n_modes)


def _rebuild_measurement_model(state: dict) -> MeasurementModel:
    state = dict(state, sys=rebuild_statespace(state["sys"]))
    return MeasurementModel(**state)
