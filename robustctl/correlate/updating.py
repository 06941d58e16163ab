"""Fix the physics: ``rc.update`` (MACE's model updating, eqs. 5-9, Figs. 3-4).

1. The residual ``j`` of the complex-log cost (eqs. 5-6) and its finite-difference
   sensitivities ``dJ`` to every candidate parameter (eq. 7), scaled to relative changes.
2. Test 1, alignment with the initial cost ``|j0^T dJ|`` (eq. 8, Fig. 3): parameters the
   initial error is insensitive to are dropped.
3. Test 2, orthogonality ``|dJn^T dJn|`` of the normalised sensitivities (eq. 9, Fig. 4):
   of two parameters with (nearly) parallel sensitivities only the better-aligned one is
   kept, and the superparameter the data actually determine is suggested in words.
4. Bounded Levenberg-Marquardt on the kept parameters, the sensitivities refreshed every
   iteration ("their range of validity is often quite small"), stopped when the cost no
   longer changes.
5. Standard errors from the Jacobian and the residual variance, and a model-form check:
   the parameters re-estimated on sub-bands should agree within their standard errors;
   estimates that drift with frequency mean a wrong model form (a missing effect), not a
   wrong value.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from typing import Any

import numpy as np

from ..budget import Deadline, as_deadline
from ..checks import UNSET, flag, integer, positive_number, probability, renamed_keyword
from ..errors import FitError, RobustctlError
from ..executors import check_executor
from ..frd import FrequencyData
from ..lti import log_ratio
from ..measure.noise import NO_NOISE_SENTENCE
from ..physical.reduction import for_data
from .optimize import LMResult, levenberg_marquardt
from .parameter_drift import Drift, _drift, _noise_covariance, _std_errors
from .parameter_drift import move_test as move_test
from .parameter_selection import select_parameters
from .parameter_selection import superparameter as superparameter
from .residual import (
    NEGLIGIBLE_DB,
    Residual,
    Sensitivities,
    _check_names,
    alignment,
    check_data,
    check_determined,
    normalized,
    orthogonality,
    physical_model,
    sensitivities,
)
from .update_result import UpdateResult
from .update_result import _alignment_legend as _alignment_legend
from .verdict import ALPHA, NoiseTest, noise_test

__all__ = ["UpdateResult", "update", "select_parameters", "superparameter", "move_test"]


# ---------------------------------------------------------------------------- update
def _warnings(fit: LMResult, drift: tuple[Drift, ...], reduction: float,
              before: NoiseTest | None = None, after: NoiseTest | None = None) -> list[str]:
    """Things to look at; with a noise model "cannot explain" means "still beyond the noise"."""
    out = []
    if not fit.success:
        out.append(f"the optimisation did not converge ({fit.stop_reason}); raise max_iter or time_budget_s.")
    for name in fit.active:
        out.append(
            f"{name} ended on a bound: the data push it beyond its admissible range, which usually "
            "means the model form is wrong rather than the value."
        )
    for d in drift:
        if d.flagged:
            vals = ", ".join(
                f"{lo:.3g}-{hi:.3g} Hz: {v:.5g} +- {s:.2g}"
                for (lo, hi), v, s in zip(d.bands, d.values, d.std_errors)
            )
            out.append(
                f"{d.name} drifts across frequency bands ({vals}): the estimates disagree beyond their "
                "standard errors, a sign of a missing effect (model-form error); try rc.diagnose."
            )
    if after is not None:
        if not after.within:
            worst = after.failing[0]
            out.append(
                f"after the update the misfit is still beyond the noise in {len(after.failing)} of "
                f"{len(after.cells)} channel-bands (worst {worst.channel} at {worst.lo_hz:.3g}-"
                f"{worst.hi_hz:.3g} Hz): the parameters cannot explain the error; try rc.diagnose."
            )
    elif reduction < 0.1:
        out.append(
            f"the cost fell by only {reduction:.1%}: the parameters cannot explain the error "
            f"({NO_NOISE_SENTENCE} on whether the rest is noise)."
        )
    return out


def _sens_at(
    residual: Residual, names: list[str], fit: LMResult, executor: Executor | None, progress: bool
) -> np.ndarray:
    """Relative sensitivities (n, p) of ``names`` at the fit's optimum, reusing its Jacobian."""
    dJ = np.zeros((residual.n, len(names)))
    fitted = {n: k for k, n in enumerate(fit.names)}
    others = [n for n in names if n not in fitted]
    if others:
        sens = sensitivities(residual, others, at=fit.x, j0=fit.vector, executor=executor, progress=progress)
        for k, n in enumerate(others):
            dJ[:, names.index(n)] = sens.dJ[:, k]
    for n, k in fitted.items():
        dJ[:, names.index(n)] = fit.jacobian[:, k] * (fit.x[n] if fit.x[n] != 0 else 1.0)
    return dJ


def _predicted_reduction(
    r: np.ndarray, dJ: np.ndarray, p: int, f_crit: float = 10.0, fitted: np.ndarray | None = None
) -> np.ndarray:
    """Whether adding each column would reduce the cost significantly (a partial F-test).

    A Gauss-Newton step along column ``i`` that re-fits the already ``fitted`` columns too lowers
    ``J = r^T r`` by ``(r^T d_i)^2 / |d_i|^2``, ``d_i`` the part of ``dJ_i`` orthogonal to the
    fitted columns (all of ``dJ_i`` without them); on pure noise this is about
    ``s^2 = J / (n - p)``. A parameter joins a later pass only if the reduction exceeds
    ``f_crit * s^2`` (F(1, n-p) of 10: chance probability below 0.2 %) and 0.1 % of ``J``.
    """
    cost = float(r @ r)
    s2 = cost / max(r.size - p, 1)
    if fitted is not None and fitted.shape[1]:
        q = np.linalg.qr(fitted)[0]
        dJ = dJ - q @ (q.T @ dJ)
    norms2 = np.sum(dJ**2, axis=0)
    red = np.where(norms2 > 0, (r @ dJ) ** 2 / np.where(norms2 > 0, norms2, 1.0), 0.0)
    return (red > f_crit * s2) & (red > 1e-3 * cost)


def _well_conditioned(dJ: np.ndarray, min_singular: float = 0.02) -> bool:
    """The rank test of :func:`select_parameters` on columns ``dJ``: the smallest singular value
    of the normalised columns is at least ``min_singular * sqrt(p)``."""
    if dJ.shape[1] < 2:
        return True
    s = np.linalg.svd(normalized(dJ), compute_uv=False)
    return bool(s[-1] >= min_singular * np.sqrt(dJ.shape[1]))


def _passes(
    residual: Residual,
    names: tuple[str, ...],
    selected: tuple[str, ...],
    passes: int,
    max_iter: int,
    budget: Deadline,
    ftol: float,
    max_orth: float,
    min_align: float,
    executor: Executor | None,
    progress: bool,
    start: Sensitivities | None = None,
    x0: dict[str, float] | None = None,
) -> tuple[LMResult, tuple[float, ...], list[str], int]:
    """Optimise ``selected`` (from the sensitivities ``start`` at the model's values, or from
    ``x0``); then repeat the tests on the remaining error and add parameters.

    A later pass adds a parameter the tests now pass (aligned with the remaining error,
    orthogonal to the selected ones) if it would lower the cost significantly. It also
    re-admits a parameter the orthogonality test dropped: that test is linear and blind to the
    noise, and two parameters 0.95-0.99 parallel (masses and springs of a chain: the frequencies
    fix only their ratio, the response level the masses) are still separated by data whose noise
    is small. One joins when the part of its sensitivity orthogonal to the selected ones would
    lower the cost significantly (the partial F-test of :func:`_predicted_reduction`, with the
    selected ones re-fitted) and the selection stays of full rank (:func:`_well_conditioned`, the
    rank test of :func:`select_parameters`: exact superparameters stay out); its standard error
    then says how well the data separate it."""
    kw = dict(max_iter=max_iter, ftol=ftol, executor=executor, progress=progress)
    if x0:
        fit = levenberg_marquardt(residual, selected, x0=x0, time_budget_s=budget, **kw)
        history = [float(start[0] @ start[0]), *fit.history] if start is not None else list(fit.history)
    else:
        fit = levenberg_marquardt(residual, selected, time_budget_s=budget, start=start, **kw)
        history = list(fit.history)
    notes, n_evals = [], fit.n_evals
    for k in range(2, int(passes) + 1):
        if budget.expired() or len(selected) == len(names) or fit.cost <= 0:
            break
        dJ = _sens_at(residual, list(names), fit, executor, progress)
        n_evals += len(names) - len(fit.names)
        new, _, _ = select_parameters(
            names, fit.vector, dJ, min_alignment=min_align, max_orthogonality=max_orth
        )
        O = orthogonality(dJ)
        cols = [names.index(m) for m in selected]
        gain = _predicted_reduction(fit.vector, dJ, len(selected), fitted=dJ[:, cols])
        added = [
            n
            for n in new
            if n not in selected
            and all(O[names.index(n), names.index(m)] <= max_orth for m in selected)
            and gain[names.index(n)]
        ]
        clashing = [n for n in names if n not in selected and n not in added and gain[names.index(n)]]
        readmitted = []
        for n in sorted(clashing, key=lambda n: -abs(float(fit.vector @ dJ[:, names.index(n)]))):
            if _well_conditioned(dJ[:, [names.index(m) for m in (*selected, *added, *readmitted, n)]]):
                readmitted.append(n)
        if not added and not readmitted:
            break
        if added:
            notes.append(
                f"pass {k}: added {', '.join(added)}, aligned with the error left after pass {k - 1} "
                f"(cost {fit.cost:.4g})."
            )
        for n in readmitted:
            i = names.index(n)
            worst = max(selected, key=lambda m: O[i, names.index(m)])
            notes.append(
                f"pass {k}: re-admitted {n} (orthogonality {O[i, names.index(worst)]:.3f} with {worst}): "
                f"the part of its sensitivity independent of the selected parameters lowers the cost "
                f"{fit.cost:.4g} beyond the noise (partial F-test), so the data separate them; its "
                "standard error says how well."
            )
        added = added + readmitted
        selected = tuple(selected) + tuple(added)
        fit = levenberg_marquardt(residual, selected, x0={**fit.x}, time_budget_s=budget, **kw)
        history += list(fit.history[1:])
        n_evals += fit.n_evals
    return fit, tuple(history), notes, n_evals


def _check_update_settings(
    max_iter: Any, ftol: Any, time_budget_s: Any, min_alignment: Any, max_orthogonality: Any
) -> None:
    """The iteration cap, tolerance, budget and selection thresholds of :func:`update`."""
    integer(max_iter, "max_iter", FitError, lo=1)
    positive_number(ftol, "ftol", FitError)
    Deadline(time_budget_s, error=FitError)  # None or seconds >= 0
    probability(min_alignment, "min_alignment", FitError)
    probability(max_orthogonality, "max_orthogonality", FitError)


#: Multiples of an effect parameter's distance from neutral tried as starting values.
START_MULTIPLES = (0.1, 0.3, 3.0, 10.0)
#: Factors on a physical parameter's value tried as starting values (+-50 % errors and beyond).
START_FACTORS = (0.5, 0.7, 1.4, 2.0)


def _trial_values(par: Any, effect: bool) -> list[float]:
    """Coarse starting values of one parameter: decades for an effect (from neutral), factors
    for a physical parameter, within its bounds (none when its value is zero or neutral)."""
    v, lo, hi = float(par.value), *(float(b) for b in par.bounds)
    neutral = float(par.neutral or 0.0) if effect else 0.0
    if v == neutral:
        return []
    mults = START_MULTIPLES if effect else START_FACTORS
    return list(dict.fromkeys(float(np.clip(neutral + m * (v - neutral), lo, hi)) for m in mults))


def coarse_start(
    residual: Residual, selected: tuple[str, ...], sens: Sensitivities, effect_params: tuple[str, ...]
) -> tuple[dict[str, float], int]:
    """Starting values for parameters far from their best value (a coarse multi-start).

    The complex-log cost is multimodal once a mode crosses another or moves by several
    half-power bandwidths, so a parameter 40 % off or an effect added at a size a decade off
    (a hand guess) leads Levenberg-Marquardt into a local minimum. One parameter at a time
    (coordinate-wise, accepting improvements), each is tried at :data:`START_MULTIPLES` of an
    effect's distance from neutral or :data:`START_FACTORS` of a physical value, scored by
    ``|P j|^2`` -- the cost left after re-fitting the other selected parameters linearly
    (``P`` projects out their sensitivity columns, MACE eq. 8) -- and the best becomes the
    start. Returns ``({name: start}, evaluations)``; empty when the model's values are best.
    """
    j0, dJ = sens
    model, x0, n = residual.model, {}, 0
    j_best = j0
    for name in selected:
        trials = _trial_values(model.param(name), name in effect_params)
        if not trials:
            continue
        others = [k for k, nm in enumerate(sens.names) if nm != name and nm in selected]
        Q = np.linalg.qr(dJ[:, others])[0] if others else np.zeros((j0.size, 0))
        best = float(np.sum((j_best - Q @ (Q.T @ j_best)) ** 2))
        for trial in trials:
            n += 1
            try:
                j = residual.vector(**{**x0, name: trial})
            except RobustctlError:
                continue
            score = float(np.sum((j - Q @ (Q.T @ j)) ** 2))
            if np.isfinite(score) and score < best:
                best, j_best, x0[name] = score, j, trial
    return x0, n


def update(
    model: Any,
    data: FrequencyData,
    params: Sequence[str] | None = None,
    band: Sequence[float] | None = None,
    max_iter: int = 20,
    executor: Executor | None = None,
    point_weights: Any = "auto",
    *,
    select: bool = True,
    passes: int = 3,
    min_alignment: float = 0.01,
    max_orthogonality: float = 0.95,
    drift_bands: int = 3,
    drift_sigma: float | None = None,
    drift_floor: float = 0.01,
    time_budget_s: float | None = None,
    ftol: float = 1e-5,
    progress: bool | None = None,
    min_channel_db: float | None = NEGLIGIBLE_DB,
    weights: Any = UNSET,
    estimator: Any = "auto",
    noise: Any = "auto",
    measurement_model: Any = None,
    alpha: float = ALPHA,
) -> UpdateResult:
    """Update physical parameters so the model matches measured FRFs (MACE eqs. 5-9).

    Parameters
    ----------
    model : PhysicalModel
    data : FrequencyData
        Measured responses (Hz); signal names must match the model's.
    params : sequence of str, optional
        Candidate parameters; default every free parameter of the model (including those of
        effects added with ``model.with_effect``).
    band : (lo_hz, hi_hz), optional
        Band of the cost, Hz (MACE: 0.1-60 Hz).
    max_iter : int
        Levenberg-Marquardt iteration cap.
    executor : concurrent.futures.Executor, optional
        Runs the sensitivity evaluations in parallel.
    point_weights : "auto", None, "coherence" or array
        Data-point weights on the squared log error (:func:`robustctl.checks.point_weights`);
        ``weights=`` is the deprecated name.
    weights
        Deprecated name of ``point_weights``.
    measurement_model : system, optional
        A measurement model fitted to the data (``rc.fit_measurement_model``), whose residual
        gives the noise model when the data carry no coherence
        (:func:`robustctl.measure.noise.noise_model`).
    select : bool
        Apply the alignment and orthogonality tests (eqs. 8-9); ``False`` updates every
        candidate.
    min_alignment, max_orthogonality :
        Thresholds of the tests (see :func:`select_parameters`).
    passes : int
        Selection/optimisation passes. The tests are linear in the initial error, so a
        parameter masked by larger errors (a 2 % sensor gain under a 5 % stiffness error)
        fails test 1 at the start; after each pass the tests are repeated on the remaining
        error and newly aligned, orthogonal parameters join the update if they would lower
        the cost significantly (partial F-test, see :func:`_predicted_reduction`).
    drift_bands : int
        Sub-bands for the model-form check (0 or 1 switches it off).
    drift_sigma, drift_floor :
        A parameter drifts when two sub-band estimates differ by more than ``drift_sigma``
        combined standard errors and by more than ``drift_floor`` (relative). ``drift_sigma``
        None (default): with a noise model, the standard errors come from the noise and the
        threshold is the Bonferroni normal quantile at family-wise ``alpha``; without one, 3.
    time_budget_s : float or None
        Optional wall-clock budget of the optimisation (s), by :mod:`robustctl.budget`'s
        policy: None (default) lets ``max_iter`` and ``passes`` bound it; a budget that stops
        it sets ``stopped_by_budget``, says so in ``warnings`` and issues a BudgetWarning.
    ftol : float
        Stop when the relative cost change of an iteration falls below this (MACE: "halted
        when the change in cost is below a desired threshold").
    progress : bool, optional
        tqdm bars (default: when stderr is a terminal).
    min_channel_db : float or None
        Negligible (decoupled) channels get weight 0; see
        :class:`~robustctl.correlate.residual.Residual`.
    estimator : "auto", True, False or EstimatorSettings
        See the model through the H1 estimator (as :func:`robustctl.compare`).
    noise : "auto", NoiseModel or None
        The data's noise model (as :func:`robustctl.compare`); ``measurement_model`` supplies
        it for data without coherence.
    alpha : float
        Family-wise false-alarm rate of the noise verdicts and the drift test.

    Returns
    -------
    UpdateResult

    Raises
    ------
    DataError
        Signal names/counts that differ, a band outside the data.
    ModelError
        Unknown parameter names.
    FitError
        No parameter moves the residual, or none survives the selection; ``passes < 1`` or
        ``drift_bands < 0``.
    """
    t0 = time.perf_counter()
    check_executor(executor)
    for what, value, least in (("passes", passes, 1), ("drift_bands", drift_bands, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise FitError(f"{what} must be an integer >= {least}; got {value!r}.")
    _check_update_settings(max_iter, ftol, time_budget_s, min_alignment, max_orthogonality)
    deadline = as_deadline(time_budget_s, FitError)
    own_clock = not isinstance(time_budget_s, Deadline)  # diagnose's polish shares its own
    if drift_sigma is not None:
        drift_sigma = positive_number(drift_sigma, "drift_sigma", FitError)
    drift_floor = positive_number(drift_floor, "drift_floor", FitError, allow_zero=True)
    select = flag(select, "select", FitError)
    progress = sys.stderr.isatty() if progress is None else flag(progress, "progress", FitError)
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    model = physical_model(model, "update")
    checked = check_data(data, band, noise, measurement_model)
    residual = Residual.of_checked(for_data(model, checked.full, checked.band), checked, point_weights,
                                   min_channel_db, estimator)
    if params is None:
        params = [p.name for p in model.free_params]
        if not params:
            raise FitError(
                "the model has no free parameters; name the parameters to update with params=[...]."
            )
    names = _check_names(model, params)
    check_determined(residual, len(names), "update")
    sens = sensitivities(residual, names, executor=executor, progress=progress)
    j0, dJ = sens
    effect_params = tuple(n for n in names if "effect" in model.param(n).tags)
    if select:
        selected, notes, suggestions = select_parameters(
            names, j0, dJ, min_alignment=min_alignment, max_orthogonality=max_orthogonality,
            keep=effect_params,
        )
    else:
        selected, notes, suggestions = names, [], []
    if not selected:
        raise FitError("no parameter passed the selection tests; lower min_alignment or give params=[...].")
    x0, n_coarse = coarse_start(residual, tuple(selected), sens, effect_params)
    if x0:
        notes.append(
            "started "
            + ", ".join(f"{k} at {v:.4g} (model {model.param(k).value:.4g})" for k, v in x0.items())
            + ": a lower cost than the model's value once the other parameters are re-fitted."
        )
    fit, history, extra, n_evals = _passes(
        residual,
        names,
        tuple(selected),
        passes,
        max_iter,
        deadline,
        ftol,
        max_orthogonality,
        min_alignment,
        executor,
        progress,
        start=sens,
        x0={**{n: model.param(n).value for n in selected}, **x0} if x0 else None,
    )
    notes += extra
    negligible = [f"{o} <- {i} ({lv:.0f} dB)" for o, i, lv in residual.dropped if lv > -np.inf]
    dead = [f"{o} <- {i}" for o, i, lv in residual.dropped if lv == -np.inf]
    if negligible:
        notes.append("left out as negligible (decoupled) channels: " + ", ".join(negligible) + ".")
    if dead:
        notes.append("left out as identically zero in the data (a dead or disconnected sensor or actuator? "
                     "check the cable): " + ", ".join(dead) + ".")
    selected = fit.names
    # a superparameter suggestion is moot once a later pass updated both parameters
    suggestions = [
        t for t in suggestions
        if not any(t.startswith(f"{a} and {b} move") for a in selected for b in selected if a != b)
    ]
    drift = _drift(residual, fit, drift_bands, drift_sigma, drift_floor, alpha) if len(selected) else ()
    reduction = 1.0 - fit.cost / history[0] if history[0] > 0 else 0.0
    before, after = (_verdict(residual, x, alpha) for x in ({}, fit.x))
    noise_cov = _noise_covariance(residual, fit)
    if own_clock and deadline.hit:
        deadline.warn("update's optimisation")
    return UpdateResult(
        model=model.with_values(**fit.x),
        initial_model=model,
        history=history,
        cost_before=history[0],
        cost_after=fit.cost,
        candidates=names,
        alignment=alignment(j0, dJ),
        orthogonality=orthogonality(dJ),
        selected=tuple(selected),
        fit=fit,
        std_errors=dict(fit.std_errors) if noise_cov is None else _std_errors(noise_cov, fit.names),
        noise_covariance=noise_cov,
        drift=drift,
        notes=tuple(notes),
        suggestions=tuple(suggestions),
        warnings=tuple(_warnings(fit, drift, reduction, before, after)),
        band=residual.band,
        time_s=time.perf_counter() - t0,
        n_evals=n_evals + sens.n_evals + n_coarse + (2 if after is not None else 0),
        noise_before=before,
        noise_after=after,
        estimator_note=residual.describe_estimator(),
        stopped_by_budget=deadline.hit,
    )


def _verdict(residual: Residual, values: dict[str, float], alpha: float) -> NoiseTest | None:
    """The chi-square verdict of the residual at ``values`` (compare's test, same cells).

    It tests the log error itself, without the coherence weights' bias (``Residual.bias``):
    that bias is in the weighted *mean* of the error a fit sees; ``|e / sigma|^2`` is a second
    moment, which the offset would only raise."""
    if residual.noise is None:
        return None
    d = residual.data
    e = log_ratio(d.response, residual.model_response(**values))
    keep = np.any(residual.weights > 0, axis=0)
    return noise_test(e, residual.noise, d.f_hz, d.outputs, d.inputs, keep, alpha=alpha)
