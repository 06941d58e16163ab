"""Worker and time-budget plumbing of ``rc.diagnose``: when to start worker processes, the
budget checks and warnings, the model evaluated on the data's band."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from ...budget import BudgetWarning, Deadline
from ...errors import FitError, ModelError
from ...executors import process_pool, resolve_workers
from ...physical.effects import Effect
from ...physical.reduction import for_data
from ..residual import Residual

#: ``workers="auto"`` starts worker processes only for at least this many candidates ...
PARALLEL_MIN_CANDIDATES = 8
#: ... and when their screening promises at least this much work (s): :data:`SCREEN_EVALS`
#: evaluations per candidate at the cost of the nominal one (below it, starting processes
#: costs more than it saves).
PARALLEL_MIN_WORK_S = 2.0
#: Model evaluations a candidate's screening costs on average (the secant; the size probes of some).
SCREEN_EVALS = 1.5
def _check_budget(deadline: Deadline, stage: str) -> None:
    """A FitError naming the stage when the budget is used up before every candidate is screened.

    Why an error and not a flagged result: a ranking of the candidates screened so far could
    propose a wrong effect first (the true one not yet screened), and no flag repairs that.
    After the screening a budget only cuts fits short, and the result says so."""
    if deadline.expired():
        raise FitError(
            f"time_budget_s={deadline.budget_s:g} s ran out during {stage}; raise time_budget_s, leave it "
            "None (the fits are capped in iterations), pass fewer candidates= or a narrower band=."
        )


def _check_candidates(model: Any, cands: Sequence[Any]) -> list[Any]:
    out = []
    for c in cands:
        if not isinstance(c, Effect):
            raise ModelError(
                f"candidates must be Effect objects (rc.effects.*); got {type(c).__name__}. "
                "List them with rc.effects.candidates(model)."
            )
        c.check(model)
        out.append(c)
    if not out:
        raise ModelError("no candidate effects to test; pass candidates=rc.effects.candidates(model).")
    return out

def _evaluated(model: Any, data: Any, band: Any) -> Any:
    """The model as diagnose evaluates it: in reduced coordinates up to the band for a large
    structure (:func:`robustctl.physical.reduction.for_data`), else as given."""
    return for_data(model, data, band)


def _pool(workers: Any, executor: Any, candidates: list | None, model: Any, t_eval: float):
    """The executor of a diagnosis: the caller's, or worker processes for ``workers`` (see
    :func:`diagnose`). ``"auto"`` starts them only when the screening promises enough work:
    :data:`SCREEN_EVALS` evaluations per candidate of ``t_eval`` s (the nominal model's) for at
    least :data:`PARALLEL_MIN_WORK_S` (the default candidates are counted without calibration)."""
    if executor is not None:
        return contextlib.nullcontext(executor)
    n = 0
    if resolve_workers(workers, 10**6, 1) > 1:
        if candidates is None:
            from ...physical.effects.catalogue import candidates as all_candidates

            n = len(all_candidates(model, calibrate=False))
        else:
            n = len(candidates)
        if workers == "auto" and SCREEN_EVALS * n * t_eval < PARALLEL_MIN_WORK_S:
            n = 0
    return process_pool(workers, n, PARALLEL_MIN_CANDIDATES)


def _default_candidates(model: Any, res0: Residual, deadline: Deadline, executor: Any) -> list:
    """``rc.effects.candidates`` of the model on the band, calibrated within the time budget."""
    from ...physical.effects import candidates as all_candidates

    cands = all_candidates(model, band=res0.band, time_budget_s=deadline, executor=executor)
    return _check_candidates(model, cands)


@contextlib.contextmanager
def _alongside(executor: Any) -> Iterator[Callable[..., Future]]:
    """``submit(fn, *args)``: a call run beside the caller's own work, returning a Future.

    With diagnose's own worker processes (``workers=``), the default candidates are calibrated on
    the workers by a thread of this process while its main thread runs the null fit, whose
    Levenberg-Marquardt steps (between its parallel Jacobians) would leave the workers idle: the
    two do not depend on each other, and each candidate's calibration is computed alone, so the
    result is the same as one after the other. The workers are started before the thread (a fork
    copies only the calling thread, which must not be this one). With any other executor (or
    none) the call runs at once, in order, as before."""
    if not getattr(executor, "_robustctl_own", False):
        def at_once(fn: Callable[..., Any], *args: Any) -> Future:
            done: Future = Future()
            done.set_result(fn(*args))
            return done

        yield at_once
        return
    executor.submit(int).result()  # a forking pool starts all its workers at its first task
    with ThreadPoolExecutor(1, thread_name_prefix="robustctl-candidates") as side:
        yield side.submit


def _new_defaults(model: Any, res: Residual, known: list, deadline: Deadline, executor: Any) -> list:
    """The default candidates of a chain's next model that its first model did not have, calibrated:
    an effect can open places for others (a joint an earlier step made flexible can carry a dashpot,
    :class:`~robustctl.physical.effects.FrameJointDamping`)."""
    from ...physical.effects import candidates as all_candidates

    names = {c.name for c in known}
    kinds = {c.kind for c in all_candidates(model, band=res.band, calibrate=False) if c.name not in names}
    if not kinds:
        return []
    fresh = all_candidates(model, band=res.band, kinds=sorted(kinds), time_budget_s=deadline,
                           executor=executor)
    fresh = [c for c in fresh if c.name not in names]
    return _check_candidates(model, fresh) if fresh else []  # none left once calibrated: nothing new


def _warn_if_hurried(null_cut: bool, n_cut: int, budget: float, polished: bool = True) -> None:
    """Say so when the wall-clock budget, not convergence, stopped a fit: the ranking then
    depends on the machine's speed and load (a fit cut short understates its candidate).
    A :class:`~robustctl.budget.BudgetWarning` (also a RuntimeWarning)."""
    what = ["the null fit"] if null_cut else []
    what += [f"{n_cut} local fit{'s' if n_cut > 1 else ''}"] if n_cut else []
    what += [] if polished else ["the polishing of the contenders"]
    if not what:
        return
    warnings.warn(
        f"diagnose: the time budget ({budget:g} s) stopped {' and '.join(what)} before convergence; "
        "the ranking may differ from an unhurried run (stopped_by_budget=True). Raise time_budget_s or "
        "leave it None (the fits are capped in iterations).",
        BudgetWarning,
        stacklevel=3,
    )


