"""``rc.diagnose``: argument checks and the pipeline null fit -> screening -> fits -> tests."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from concurrent.futures import Executor, Future
from dataclasses import replace
from typing import Any

import numpy as np

from ...budget import Deadline
from ...checks import UNSET, finite_number, flag, integer, renamed_keyword
from ...errors import FitError, ModelError
from ...executors import check_executor, parallel_map_shared, resolve_workers
from ...frd import FrequencyData
from ...measure.estimator import estimator_settings
from ...threads import limit_blas
from ..optimize import levenberg_marquardt
from ..residual import check_data, check_determined, physical_model
from .answer import (
    CHAIN_PAST_ANSWER,
    CHAIN_STEP_SHARE,
    CHAIN_TRY_GAIN,
    MAX_CHAIN,
    ChainStep,
    beyond_noise,
    completeness,
    model_error_share,
)
from .localize import misfit_bands
from .results import ALPHA, ANSWER_SHARE, DECOUPLED_DB, MIN_GAIN, Diagnosis
from .rivals import _indistinguishable
from .screening import (
    _fit_task,
    _noise_cost,
    _null_fit,
    _polish,
    _residual,
    _residual_for,
    _screen_all,
    _to_fit,
    _with_models,
)
from .sentences import _where, _with_sentence
from .significance import _channel_verdict, _null_test, _row_noise, _score, _testable_rows, effective_points
from .workers import (
    _alongside,
    _check_budget,
    _check_candidates,
    _default_candidates,
    _evaluated,
    _new_defaults,
    _pool,
    _warn_if_hurried,
)


def _check_update(model: Any, update_params: Sequence[str] | None) -> tuple[str, ...]:
    if update_params is None:
        return tuple(p.name for p in model.free_params)
    if isinstance(update_params, str):
        update_params = (update_params,)
    names = tuple(update_params)
    unknown = [n for n in names if n not in model.param_names]
    if unknown:
        raise ModelError(f"unknown update parameter(s) {unknown}; the model has {list(model.param_names)}.")
    return names



# ============================================================================ diagnose
@limit_blas
def diagnose(
    model: Any,
    data: FrequencyData,
    candidates: Sequence[Any] | None = None,
    band: tuple[float, float] | None = None,
    executor: Executor | None = None,
    params: Sequence[str] | None = None,
    *,
    point_weights: Any = "auto",
    min_channel_db: float | None = DECOUPLED_DB,
    n_fit: int = 4,
    max_iter: int = 8,
    update_iter: int = 10,
    alpha: float = ALPHA,
    min_gain: float = MIN_GAIN,
    time_budget_s: float | None = None,
    update_params: Any = UNSET,
    weights: Any = UNSET,
    estimator: Any = "auto",
    noise: Any = "auto",
    measurement_model: Any = None,
    workers: Any = "auto",
    chain: Any = True,
) -> Diagnosis:
    """Rank physical effects by how much of the model-data residual each explains.

    Parameters
    ----------
    model : PhysicalModel
    data : FrequencyData
        Measured responses (Hz); channels named as the model's signals.
    candidates : sequence of Effect, optional
        Default ``rc.effects.candidates(model, band=band)``. Each must apply to the model.
    band : (float, float), optional
        Band in Hz (default: all data).
    executor : concurrent.futures.Executor, optional
        Screens and fits candidates in parallel (a thread pool works with any model; a
        process pool needs a picklable model). Overrides ``workers``.
    params : sequence of str, optional
        Parameters the update may change (default: the model's free parameters); what they
        can absorb is projected out before the effects are scored (as ``params=`` of
        :func:`update`; ``update_params=`` is the deprecated name).
    update_params
        Deprecated name of ``params``.
    point_weights : "auto", None, "coherence" or array
        Data-point weights on the squared log error (:func:`robustctl.checks.point_weights`;
        ``weights=`` is the deprecated name). ``"auto"`` (default) uses the coherence when
        the data carry it: ``W = g2 / (1 - g2)`` is the inverse variance of the log estimate,
        so noisy bins (low coherence, at anti-resonances and far from the excited modes) do
        not drown the systematic error.
    weights
        Deprecated name of ``point_weights``.
    measurement_model : system, optional
        Supplies the noise model of data without coherence, as for :func:`robustctl.update`.
    min_channel_db : float or None
        Channels the model or data leave decoupled (this many dB below their row and column)
        get weight 0, by the rule of :func:`compare` and :func:`update`; the default
        :data:`DECOUPLED_DB` (-60 dB) is stricter than theirs (-80 dB). With the same value
        the costs agree.
    n_fit : int
        Number of best-screened candidates given the local fit (and up to as many more whose
        screening share ties with the best's within :data:`TIE_SHARE`).
    max_iter, update_iter : int
        LM iteration caps of the local fits and of the null fit.
    alpha : float
        Family-wise level: the candidates' p-values are Holm-adjusted over the screened candidates
        and compared with it.
    min_gain : float
        Smallest share (0..1) of the null-fit residual an effect must remove to be proposed.
    time_budget_s : float or None
        Optional wall-clock budget (s) of the whole call, by :mod:`robustctl.budget`'s policy.
        None (default): the iteration caps (``max_iter``, ``update_iter``, the polishing's
        ``POLISH_ITER``) bound the work and the ranking depends only on the inputs. A number:
        when it ends the null fit, a local fit or the polishing early, the fits keep what they
        reached, the result has ``stopped_by_budget=True``, its summary says so and a
        BudgetWarning is issued; when it ends before every candidate is calibrated and
        screened, a FitError is raised (a ranking of some candidates could name a wrong effect).
    estimator : "auto", True, False or EstimatorSettings
        See the model through the H1 estimator (as :func:`robustctl.compare`).
    noise : "auto", NoiseModel or None
        The data's noise model behind the p-values (:func:`robustctl.noise_model`;
        ``measurement_model`` supplies it for data without coherence). Without one, the
        ranking is still given but no significance claims are made (p-values NaN) and the best
        candidate is proposed only on its share of the residual.
    workers : "auto", int or None
        Worker processes for the screening, local fits and polishing when no ``executor`` is
        given. ``"auto"`` (default): one per available core when the screening promises at least
        :data:`PARALLEL_MIN_WORK_S` of work (:data:`SCREEN_EVALS` evaluations per candidate, timed
        on the nominal model) for :data:`PARALLEL_MIN_CANDIDATES` or more candidates and the
        platform can fork, otherwise serial; an int: that many processes;
        ``1`` or None: serial, in this process. The result equals the serial one (each candidate
        is computed alone, the model and data travel to each worker once); the model must be
        picklable (cloudpickle) for more than one worker.
    chain : bool or int
        Several effects at once. A significant effect that leaves the model beyond the noise
        (verdict ``"incomplete"``, :mod:`.answer`) is applied with its fitted size, and the next
        effect is proposed on the model updated with it (its size re-fitted with the update
        parameters), until the misfit is within the noise, nothing more is significant, or
        ``chain`` effects (True: :data:`~.answer.MAX_CHAIN`) are found; ``diag.chain`` lists them.
        An answer that leaves over :data:`~.answer.CHAIN_PAST_ANSWER` x the noise is chained too: a
        next effect joins it when it is significant, removes :data:`~.answer.CHAIN_STEP_SHARE` of
        the model error the answer leaves and leaves at most that much itself (an added mass once a
        soft seam is found).
        False: one step.

    Returns
    -------
    Diagnosis
        ``verdict`` is one of ``"within the noise"``, ``"answer"`` (``best``, and ``effects`` for
        a chain), ``"incomplete"`` (``best`` is None; ``closest`` and ``left`` say what the
        closest candidates explain and where the rest sits), ``"unexplained"`` or
        ``"no noise model"``.

    Raises
    ------
    DataError
        Data that do not match the model's channels, a band outside the data.
    ModelError
        A candidate that does not apply to the model (wrong domain, unknown location),
        unknown update parameters.

    Examples
    --------
    >>> diag = rc.diagnose(model, data, band=(0.5, 20))                  # doctest: +SKIP
    >>> diag.table(); diag.best                                           # doctest: +SKIP
    >>> upd = rc.update(model.with_effect(diag.best), data)              # doctest: +SKIP
    """
    t0 = time.perf_counter()
    check_executor(executor)
    resolve_workers(workers, 0, 1)  # a bad value fails before any work
    deadline = Deadline(time_budget_s, error=FitError)
    max_iter = integer(max_iter, "max_iter", FitError, lo=1)
    update_iter = integer(update_iter, "update_iter", FitError, lo=1)
    params = renamed_keyword(params, update_params, "params", "update_params")
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    model = physical_model(model, "diagnose")
    checked = check_data(data, band, noise, measurement_model)
    model = _evaluated(model, checked.full, checked.band)
    res0, ignored = _residual(model, checked, point_weights, min_channel_db, estimator)
    upd = _check_update(model, params)
    check_determined(res0, len(upd) + 1, "diagnose (the free parameters and one candidate's)")
    if candidates is not None:
        candidates = _check_candidates(model, list(candidates))
    alpha, min_gain = finite_number(alpha, "alpha", FitError), finite_number(min_gain, "min_gain", FitError)
    if not 0 < alpha < 1 or not 0 <= min_gain < 1:
        raise FitError(f"alpha must lie in (0, 1) and min_gain in [0, 1); got {alpha!r}, {min_gain!r}.")
    if isinstance(n_fit, bool) or not isinstance(n_fit, (int, np.integer)) or n_fit < 0:
        raise FitError(
            f"n_fit is the number of best-screened candidates given a local fit: a whole number >= 0; "
            f"got {n_fit!r}."
        )
    t_eval = time.perf_counter()
    j_nominal = res0.vector()
    t_eval = time.perf_counter() - t_eval
    n_chain = _check_chain(chain)
    with _pool(workers, executor, candidates, model, t_eval) as ex:
        defaults = candidates is None
        with _alongside(ex) as submit:
            first_cands = submit(_default_candidates, model, res0, deadline, ex) if defaults else candidates
            first = _diagnose(
                t0, res0, ignored, upd, first_cands, j_nominal, ex, n_fit, max_iter, update_iter, alpha,
                min_gain, deadline,
            )
            candidates = first_cands.result() if defaults else candidates
        steps = [first]
        while len(steps) < n_chain and steps[-1].lead is not None and not deadline.expired():
            past_answer = any(s.verdict == "answer" for s in steps)
            used = {s.lead.name for s in steps}
            nxt_model = _chain_model(steps, res0.model)
            res_n, ign_n = _residual(nxt_model, checked, point_weights, min_channel_db, estimator)
            if defaults:
                candidates = candidates + _new_defaults(nxt_model, res_n, candidates, deadline, ex)
            rest = [c for c in candidates if c.name not in used and _applies(c, nxt_model)]
            if not rest:
                break
            upd_n = tuple(dict.fromkeys(upd + tuple(n for s in steps for n in s.lead.param_names)))
            steps.append(_diagnose(
                time.perf_counter(), res_n, ign_n, upd_n, rest, res_n.vector(), ex, n_fit, max_iter,
                update_iter, alpha, min_gain, deadline, coarse=False,
            ))
            if past_answer and not _joins_answer(steps[-1]):
                steps.pop()  # nothing significant beyond the answer: the chain ends with it
                break
            if past_answer and steps[-1].best is None:
                break  # a second effect that leaves little: nothing more is looked for in what is left
            if steps[-1].verdict in ("answer", "within the noise") and steps[-1].lead is None:
                break
        return _pruned(_chained(steps, time.perf_counter() - t0, n_chain), steps, res0, upd, alpha,
                       update_iter, deadline)


def _joins_answer(step: Diagnosis) -> bool:
    """Whether a step taken past an answer joins it: its effect is the answer of the model with the
    earlier effects, or it is significant (the closest, verdict "incomplete"), removes
    :data:`~.answer.CHAIN_STEP_SHARE` of the model error the answer left and leaves at most
    :data:`~.answer.CHAIN_PAST_ANSWER` x the noise (what an answer may leave without the chain looking
    further). A candidate that absorbs part of a misfit no candidate models (a gain error on one
    sensor standing in for the DAC hold's droop) leaves more and is not named."""
    if step.best is not None:
        return True
    comp = step.completeness
    return (step.closest is not None and comp is not None and comp.share >= CHAIN_STEP_SHARE
            and comp.dispersion <= CHAIN_PAST_ANSWER)


def _chain_past(comp: Any, alpha: float) -> bool:
    """Whether an answer's completeness test leaves so much misfit (significant, and over
    :data:`~.answer.CHAIN_PAST_ANSWER` x the noise) that a chain goes on to a second effect."""
    return (comp is not None and comp.dispersion > CHAIN_PAST_ANSWER
            and beyond_noise(comp.dispersion, comp.p_value, alpha))


def _check_chain(chain: Any) -> int:
    """The most effects a diagnosis chains: ``True`` -> :data:`MAX_CHAIN`, ``False`` -> 1, or an int."""
    if isinstance(chain, (bool, np.bool_)):
        return MAX_CHAIN if flag(chain, "chain", FitError) else 1
    return integer(chain, "chain (True, False or the most effects to chain)", FitError, lo=1)


def _applies(effect: Any, model: Any) -> bool:
    """Whether ``effect`` can be added to ``model``: a chain's next step leaves out the candidates
    an earlier step made moot (a second joint spring at a joint the first already made flexible)."""
    try:
        effect.check(model)
    except ModelError:
        return False
    return True


def _chain_model(steps: list[Diagnosis], model: Any) -> Any:
    """``model`` with every step's lead effect applied, at the values of the last step's fit (the
    update parameters and the earlier effects re-fitted with its lead): the next step's model."""
    for s in steps:
        model = s.lead.apply(model)
    values = {n: v for n, v in steps[-1].best_fit_values.items() if n in model.param_names}
    return model.with_values(**values) if values else model


def _pruned(diag: Diagnosis, steps: list[Diagnosis], res0: Any, upd: tuple[str, ...], alpha: float,
            update_iter: int, deadline: Deadline) -> Diagnosis:
    """A complete chain without its needless tentative steps (backward elimination, the exit test of
    a stepwise fit: Draper & Smith, *Applied Regression Analysis*, 3rd ed., sec. 15.2).

    A step taken on a tentative lead (nothing significant yet) stays in the answer only if the chain
    without it, re-fitted with the update parameters, is no longer complete (within the noise or
    removing :data:`ANSWER_SHARE` of the model error): an effect the data do not need is not named.
    """
    if diag.verdict != "answer" or len(diag.chain) < 2 or not any(c.tentative for c in diag.chain):
        return diag
    kept = list(diag.chain)
    comp_kept = None
    for link in [c for c in kept if c.tentative]:
        others = [c for c in kept if c is not link]
        model = res0.model
        for c in others:
            model = c.effect.apply(model)
        names = tuple(dict.fromkeys(tuple(upd) + tuple(n for c in others for n in c.effect.param_names)))
        fit = levenberg_marquardt(_residual_for(res0, model), names, max_iter=update_iter,
                                  time_budget_s=deadline)
        comp = completeness(res0, _residual_for(res0, model.with_values(**fit.x)).vector(),
                            diag.dispersion, alpha)
        if comp.complete:
            values = dict(fit.x)
            kept = [replace(c, effect=c.effect.with_values(
                **{n: values[n] for n in c.effect.param_names if n in values})) for c in others]
            comp_kept = comp
    if comp_kept is None:
        return diag
    effects = tuple(c.effect for c in kept)
    found = [s.best_result for s in steps if s.best_result is not None and s.best_result.effect.name
             == effects[0].name] if len(kept) == 1 else []
    one: dict[str, Any] = {}
    if found:  # one effect left: the diagnosis names it as a single answer, ranked first
        best = replace(found[0], effect=effects[0])
        one = {"ranking": (best, *(r for r in diag.ranking if r.effect.name != best.effect.name)),
               "completeness": comp_kept}
    return replace(diag, chain=tuple(kept), effects=effects, best=effects[0],
                   dispersion_left=comp_kept.dispersion, model_error_removed=comp_kept.share, **one)


def _chained(steps: list[Diagnosis], time_s: float, n_chain: int) -> Diagnosis:
    """The first step's diagnosis with the chain, the overall verdict and the effects.

    The chain is the answer when its last model is within the noise or its effects together remove
    :data:`ANSWER_SHARE` of the model error. Otherwise only its leading run of significant steps is
    kept ("incomplete"); steps taken on a tentative lead (nothing significant, a candidate explaining
    :data:`~.answer.CHAIN_TRY_GAIN` of the residual: an effect masked by another one) are dropped. A
    last step past an answer that is significant but not complete (:func:`_joins_answer`) is kept,
    and the chain's misfit is the one left with it."""
    first, last = steps[0], steps[-1]
    links = [_link(s) for s in steps if s.lead is not None or s.best is not None]
    # a significant effect past an answer joined it (:func:`_joins_answer`) though it is not complete
    joined = last.closest is not None and any(s.verdict == "answer" for s in steps[:-1])
    if len(steps) == 1:
        one = first.best is not None or first.closest is not None
        return replace(first, chain=tuple(links[:1]) if one else (),
                       effects=(first.best,) if first.best is not None else (), time_s=time_s,
                       chain_limit=n_chain)
    complete = last.verdict in ("answer", "within the noise")
    final = last.completeness if last.verdict == "answer" or joined else None
    disp_end = final.dispersion if final is not None else last.dispersion
    share = model_error_share(first.dispersion, disp_end)
    if complete or share >= ANSWER_SHARE:
        kept = links if last.best is not None or joined else links[:len(steps) - 1]
        joint = last.best_fit_values  # the earlier effects re-fitted with the last one
        kept = [replace(link, effect=link.effect.with_values(
            **{n: joint[n] for n in link.effect.param_names if n in joint})) for link in kept]
        effects = tuple(link.effect for link in kept)
        return replace(first, chain=tuple(kept), verdict="answer", effects=effects, best=effects[0],
                       closest=None, left=(), dispersion_left=disp_end, model_error_removed=share,
                       time_s=time_s, chain_limit=n_chain)
    run = 0
    while run < len(steps) and steps[run].verdict == "incomplete":
        run += 1
    if run == 0:
        return replace(first, chain=(), time_s=time_s, chain_limit=n_chain, chain_exhausted=True)
    comp = steps[run - 1].completeness
    return replace(
        first, chain=tuple(links[:run]), verdict="incomplete", effects=(), best=None, closest=first.closest,
        left=comp.bands, dispersion_left=comp.dispersion,
        model_error_removed=model_error_share(first.dispersion, comp.dispersion),
        chain_exhausted=run < len(steps), time_s=time_s, chain_limit=n_chain,
    )


def _link(s: Diagnosis) -> ChainStep:
    """One step of a chain from its diagnosis: the proposed, closest or tentative effect."""
    r = s.best_result if s.best is not None else s.lead_result
    comp = s.completeness if s.best is not None or s.closest is not None else None
    return ChainStep(
        effect=r.effect, sentence=r.sentence, gain=r.gain, p_value=r.p_value,
        dispersion_before=s.dispersion, dispersion_after=comp.dispersion if comp is not None else math.nan,
        update_values=dict(s.best_fit_values), tentative=s.best is None and s.closest is None,
    )


def _diagnose(
    t0, res0, ignored, upd, cands, j_nominal, executor, n_fit, max_iter, update_iter, alpha, min_gain,
    deadline: Deadline, coarse: bool = True,
) -> Diagnosis:
    """:func:`diagnose` once the arguments are checked, the candidates made and the executor chosen
    (``cands`` may be a Future: the default candidates calibrated beside the null fit). ``coarse``:
    the null fit starts from a coarse multi-start (False for a chain's next step, whose model holds
    the values the previous step fitted)."""
    model = res0.model
    evals = 1
    cost_nominal = float(j_nominal @ j_nominal)
    # 1. null fit of the update parameters
    null, n_null = _null_fit(res0, upd, update_iter, executor, deadline, j_nominal, coarse=coarse)
    evals += n_null
    x_u, j_u, cost_u = null.x, null.j, null.cost
    model_u = model.with_values(**x_u) if x_u else model
    res_u = _residual_for(res0, model_u)
    # 2. secant screening (the default candidates may have been calibrated beside the null fit)
    cands = cands.result() if isinstance(cands, Future) else cands
    _check_budget(deadline, "the null fit")
    screens, twins, order = _screen_all(res_u, model_u, null, cands, executor, deadline)
    evals += sum(s["evals"] for s in screens)
    top = _to_fit(screens, order, n_fit)
    _with_models(screens, top, model_u)
    # 3. local fits
    fits = parallel_map_shared(
        _fit_task, (res_u, null, max_iter, deadline), [screens[k] for k in top], executor, desc="local fits",
    )
    evals += sum(f["evals"] for f in fits)
    polished = not deadline.expired()
    if polished:  # a budget the local fits used up is reported by the warning below
        fits, n_polish = _polish(res_u, null, screens, top, fits, executor, deadline, _noise_cost(res0))
        evals += n_polish
    n_cut = sum(bool(f.get("cut")) for f in fits)
    stopped = bool(null.cut or n_cut or not polished)
    if stopped:
        _warn_if_hurried(null.cut, n_cut, deadline.budget_s, polished)
    # 4. significance and words
    e_u = res0.unstack(j_u)
    n_eff, rho = effective_points(e_u)
    m = len(cands)
    settings = estimator_settings(res0.data.meta)
    held = _input_held(res0.data)
    stats = dict(
        cost_u=cost_u,
        cost_nominal=cost_nominal,
        n_eff=n_eff,
        p=len(upd),
        alpha=alpha,
        m=m,
        min_gain=min_gain,
        upd=upd,
        row_noise=_row_noise(res0),
        testable=_testable_rows(res0),
        # a delay of half a sample is the DAC's hold only in data whose input was held and whose
        # hold was not divided out (meta["hold_divided"])
        fs_hz=(_sample_rate(res0.data, settings)
               if held and not _hold_divided(res0.data, settings) else None),
    )
    results, explained = _score(res0, screens, order, top, fits, twins, j_u, stats)
    best = _best(results, res0.noise is not None, min_gain)
    fitted = _fitted_models(screens, top, fits)
    group = _indistinguishable(res0, results, fitted, j_u, stats["row_noise"], alpha)
    dispersion, p_null = _null_test(res0, j_u)
    beyond = beyond_noise(dispersion, p_null, alpha)
    # 5. the answer, or the closest and where the rest sits
    closest, comp, best_fit_values, left, lead = None, None, dict(x_u), (), None
    if best is not None:
        fit = fitted[best.name]
        best_fit_values = {n: v for n, v in fit["model"].values.items() if n in upd}
        lead = best
        if res0.noise is not None:
            comp = completeness(res0, fit["vector"], dispersion, alpha, fit["model"])
            if not comp.complete:
                closest, best, left = best, None, comp.bands
                results = [_with_sentence(replace(r, incomplete=True)) if r.effect is closest else r
                           for r in results]
    if res0.noise is None:
        word = "no noise model"
    elif best is not None:
        word = "answer"
    elif closest is not None:
        word = "incomplete"
    else:
        word = "unexplained" if beyond else "within the noise"
    verdict = _channel_verdict(res0, j_u) if best is None and closest is None and beyond else ""
    if word == "unexplained":
        left = misfit_bands(res0, j_u, model_u)
        top = next((r for r in results if r.fitted and not r.at_bound and r.gain >= CHAIN_TRY_GAIN), None)
        if top is not None:  # a tentative lead for a chain: an effect another one may mask
            lead = top.effect
            best_fit_values = {n: v for n, v in fitted[top.name]["model"].values.items() if n in upd}
    if word not in ("incomplete", "unexplained") and not (word == "answer" and _chain_past(comp, alpha)):
        lead = None  # nothing to chain: answered, within the noise, or no noise model to judge by
    return Diagnosis(
        ranking=tuple(results),
        best=best,
        cost_nominal=cost_nominal,
        cost_update=cost_u,
        update_params=upd,
        update_values=x_u,
        n=res0.n,
        n_eff=n_eff,
        rho=rho,
        alpha=alpha / m,
        unexplained=_where(res0, j_u, unweight=False, pairs=True),
        band=res0.band,
        n_evals=evals,
        time_s=time.perf_counter() - t0,
        ignored_channels=ignored,
        point_weights=res0.point_weights,
        residual_update=e_u,
        f_hz=res0.f_hz,
        explained=explained,
        noise_source="" if res0.noise is None else res0.noise.source,
        estimator_note=res0.describe_estimator(),
        indistinguishable=group,
        stopped_by_budget=stopped,
        family_alpha=alpha,
        dispersion=dispersion,
        p_null=p_null,
        channel_verdict=verdict,
        input_held=held,
        verdict=word,
        closest=closest,
        completeness=comp,
        left=left,
        dispersion_left=comp.dispersion if comp is not None else dispersion,
        model_error_removed=comp.share if comp is not None else 0.0,
        best_fit_values=best_fit_values,
        lead=lead,
        screening=_screening_counts(screens),
    )


def _screening_counts(screens: list[dict]) -> dict:
    """How many candidates each screening stage scored, and how the point effects' locations were
    chosen (:attr:`Diagnosis.screening`)."""
    from .screening import PRESCREEN_KEEP

    counts = {"candidates": len(screens), "exact": 0, "closed form": 0, "first order": 0}
    for sc in screens:
        counts[sc.get("stage", "exact")] += 1
    rule = "every candidate screened on the model"
    if counts["closed form"]:
        rule = "point effects at every location fitted in closed form on the reduced modal model"
    if counts["first order"]:
        rule = (f"point effects at every location scored by their first-order share of the misfit (the "
                f"misfit's modes' kinetic and strain energy at the location, with the mode-shape change); "
                f"the {PRESCREEN_KEEP} best fitted in closed form on the reduced modal model")
    return {**counts, "rule": rule}


def _input_held(data: FrequencyData) -> bool:
    """Whether the data say their input was a held (DAC) command: the experiment description's
    input kind (``data.experiment.input_kind``, or ``meta["input_kind"]`` /
    ``meta["experiment"]["input_kind"]``) is ``"held"``. Data that do not say are not held: a
    measured force or voltage is how most modal tests are run."""
    exp = getattr(data, "experiment", None)
    kind = getattr(exp, "input_kind", None) if exp is not None else None
    if kind is None:
        meta = dict(data.meta)
        kind = meta.get("input_kind")
        sub = meta.get("experiment")
        if kind is None and isinstance(sub, dict):
            kind = sub.get("input_kind")
        subs = meta.get("experiments")
        if kind is None and isinstance(subs, (list, tuple)) and subs:
            kinds = {m.get("input_kind") for m in subs if isinstance(m, dict)}
            kind = kinds.pop() if len(kinds) == 1 else None
    return kind == "held"


def _hold_divided(data: FrequencyData, settings: Any) -> bool:
    """Whether the estimate was divided by the hold's response (no half-sample delay is left)."""
    exp = getattr(data, "experiment", None)
    return bool((settings is not None and settings.hold_divided) or getattr(exp, "hold_divided", False))


def _sample_rate(data: FrequencyData, settings: Any) -> float | None:
    """The data's sample rate (Hz): the estimator settings', else the experiment description's."""
    if settings is not None:
        return settings.fs_hz
    exp = getattr(data, "experiment", None)
    for src in (exp, getattr(exp, "estimator", None)):
        fs = getattr(src, "fs_hz", None)
        if fs:
            return float(fs)
    fs = dict(data.meta).get("fs_hz")
    try:
        return float(fs) if fs else None
    except (TypeError, ValueError):
        return None


def _fitted_models(screens: list[dict], top: list[int], fits: list[dict]) -> dict[str, dict]:
    """Each fitted candidate's residual vector and fitted model (update values and its size)."""
    out = {}
    for k, fit in zip(top, fits):
        s = screens[k]
        pname = s["effect"].param_names[0]
        own = {pname: fit["value"], **fit.get("extra", {})}
        values = {**fit["x"], **own}
        # keyed by the fitted effect's name (a retuned resonator's carries its fitted frequency)
        out[s["effect"].with_values(**own).name] = dict(vector=fit["vector"],
                                                        model=s["model"].with_values(**values))
    return out


def _best(results: list, have_noise: bool, min_gain: float) -> Any:
    """The top significant candidate; without a noise model, the top fitted one that explains at
    least ``min_gain`` of the residual (proposed without a significance claim). A candidate at its
    bound is never the answer."""
    if have_noise:
        return next((r.effect for r in results if r.significant), None)
    return next((r.effect for r in results if r.fitted and r.gain >= min_gain and not r.at_bound), None)


