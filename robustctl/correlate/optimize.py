"""Bounded Levenberg-Marquardt on a :class:`~robustctl.correlate.residual.Residual`.

MACE updates the model by a least-squares minimisation of ``J = j^T j`` (eq. 5),
recomputing the finite-difference sensitivities (eq. 7) every iteration "because their
range of validity is often quite small", and stops when the cost no longer changes.
This module is that loop: a Marquardt-scaled damped Gauss-Newton step on the
parameters selected, projected onto their bounds, with the Jacobian refreshed after every
accepted step, an iteration cap and a wall-clock budget.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..budget import Deadline, as_deadline
from ..errors import FitError, ModelError, RobustctlError
from .residual import Residual, Sensitivities, _check_names, sensitivities

__all__ = ["LMResult", "levenberg_marquardt", "marquardt_step"]


@dataclass(frozen=True, eq=False)
class LMResult:
    """Outcome of :func:`levenberg_marquardt`.

    Attributes
    ----------
    names : tuple of str
        The parameters fitted, in column order.
    x, x0 : dict
        Final and starting values (parameter units).
    cost, cost0 : float
        Final and initial ``J = j^T j`` (MACE eq. 5).
    history : tuple of float
        Cost at the start and after each iteration.
    x_history : tuple of dict
        Parameter values at the start and after each iteration.
    jacobian : ndarray (n, p)
        ``d j / d alpha`` per unit parameter at ``x`` (finite differences).
    covariance : ndarray (p, p)
        ``s^2 (J^T J)^+`` with ``s^2 = cost / (n - p)`` (parameter units squared).
    std_errors : dict
        Square roots of the covariance diagonal (parameter units).
    n_iter, n_evals : int
        Iterations done, residual evaluations spent.
    stop_reason : str
        Why the loop stopped, in words.
    success : bool
        True unless the iteration cap or the time budget stopped it.
    stopped_by_budget : bool
        A ``time_budget_s`` stopped it (:mod:`robustctl.budget`; the caller reports it).
    time_s : float
        Wall-clock time spent (s).
    vector : ndarray (n,)
        Residual vector at ``x``.
    active : tuple of str
        Parameters that ended on a bound.
    """

    names: tuple[str, ...]
    x: dict[str, float]
    x0: dict[str, float]
    cost: float
    cost0: float
    history: tuple[float, ...]
    x_history: tuple[dict[str, float], ...]
    jacobian: np.ndarray
    covariance: np.ndarray
    std_errors: dict[str, float]
    n_iter: int
    n_evals: int
    stop_reason: str
    success: bool
    time_s: float
    vector: np.ndarray = field(repr=False)
    active: tuple[str, ...] = ()
    stopped_by_budget: bool = False

    @property
    def x_array(self) -> np.ndarray:
        return np.array([self.x[n] for n in self.names])

    @property
    def reduction(self) -> float:
        """Fractional cost reduction ``1 - cost / cost0``."""
        return 0.0 if self.cost0 == 0 else 1.0 - self.cost / self.cost0


def parameter_bounds(model: Any, names: tuple[str, ...], bounds: Any) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the parameters ``names``: the model's, replaced where ``bounds``
    gives them."""
    lo = np.array([model.param(n).bounds[0] for n in names], dtype=float)
    hi = np.array([model.param(n).bounds[1] for n in names], dtype=float)
    if bounds is None:
        return lo, hi
    if isinstance(bounds, Mapping):
        for key, (b_lo, b_hi) in bounds.items():
            if key not in names:
                raise ModelError(
                    f"bounds given for {key!r}, which is not among the parameters {list(names)}."
                )
            k = names.index(key)
            lo[k], hi[k] = float(b_lo), float(b_hi)
    else:
        arr = np.asarray(bounds, dtype=float)
        if arr.shape != (len(names), 2):
            raise FitError(
                f"bounds must be a mapping name -> (lo, hi) or an array of shape ({len(names)}, 2); "
                f"got shape {arr.shape}."
            )
        lo, hi = arr[:, 0].copy(), arr[:, 1].copy()
    bad = [n for n, a, b in zip(names, lo, hi) if not a < b]
    if bad:
        raise FitError(f"bounds of {bad} are empty (lower >= upper); give lower < upper.")
    return lo, hi


def _start(model: Any, names: tuple[str, ...], x0: Any, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    if x0 is None:
        x = np.array([model.param(n).value for n in names], dtype=float)
    elif isinstance(x0, Mapping):
        x = np.array([float(x0.get(n, model.param(n).value)) for n in names])
    else:
        x = np.asarray(x0, dtype=float).reshape(-1)
        if x.size != len(names):
            raise FitError(f"x0 has {x.size} values for {len(names)} parameters {list(names)}.")
    outside = [
        f"{n} = {v:g} not in [{a:g}, {b:g}]" for n, v, a, b in zip(names, x, lo, hi) if not a <= v <= b
    ]
    if outside:
        raise FitError(
            "the bounds exclude the starting point: "
            + "; ".join(outside)
            + ". Widen the bounds or start inside them."
        )
    if not np.all(np.isfinite(x)):
        raise FitError("x0 must be finite.")
    return x


def _from_start(
    start: Sensitivities, model: Any, names: tuple[str, ...], x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Residual vector and per-unit Jacobian (columns in ``names`` order) at ``x`` from ``start``."""
    missing = [n for n in names if n not in start.names]
    point = {**model.values, **dict(zip(names, (float(v) for v in x)))}
    moved = [k for k, v in point.items() if start.base.get(k) != v]
    if missing or moved or "secant" in start.kind:
        why = (
            f"they miss {missing}"
            if missing
            else f"they were taken at other values of {moved}"
            if moved
            else "they are secants from origin="
        )
        raise FitError(
            "start= must be the sensitivities (without origin=) of every fitted parameter at the "
            f"starting point; {why}. Compute them with "
            "sensitivities(residual, names, at=x0) or leave start out."
        )
    cols = [start.names.index(n) for n in names]
    return np.asarray(start.j0, dtype=float), start.jacobian()[:, cols]


@dataclass
class _State:
    x: np.ndarray
    r: np.ndarray
    cost: float
    lam: float
    n_evals: int = 0


def marquardt_step(J: np.ndarray, r: np.ndarray, lam: float) -> np.ndarray:
    """The damped Gauss-Newton (Marquardt, 1963) step ``d`` minimising
    ``|J d + r|^2 + lam |D d|^2`` with ``D = diag(J^T J)^(1/2)`` (Nocedal & Wright eq. 10.34),
    solved as one stacked least-squares problem. The one implementation used by
    :func:`levenberg_marquardt` and by ``rc.diagnose``'s local fits."""
    d2 = np.sum(J**2, axis=0)
    d2 = np.maximum(d2, 1e-12 * max(d2.max(initial=0.0), 1e-300))
    A = np.vstack([J, np.diag(np.sqrt(lam * d2))])
    b = np.concatenate([-r, np.zeros(J.shape[1])])
    return np.linalg.lstsq(A, b, rcond=None)[0]


def _solve_step(J: np.ndarray, r: np.ndarray, lam: float, free: np.ndarray) -> np.ndarray:
    """Damped Gauss-Newton step on the free columns (:func:`marquardt_step`)."""
    step = np.zeros(J.shape[1])
    if not np.any(free):
        return step
    step[free] = marquardt_step(J[:, free], r, lam)
    return step


def _projected_step(J, r, lam, z, zlo, zhi) -> np.ndarray:
    """Step whose components pushing into an active bound are frozen, then clipped."""
    free = np.ones(J.shape[1], dtype=bool)
    for _ in range(J.shape[1] + 1):
        step = _solve_step(J, r, lam, free)
        blocked = ((z <= zlo) & (step < 0)) | ((z >= zhi) & (step > 0))
        blocked &= free
        if not np.any(blocked):
            break
        free &= ~blocked
    return np.clip(z + step, zlo, zhi) - z


def _covariance(J: np.ndarray, cost: float) -> np.ndarray:
    """``s^2 (J^T J)^+`` computed with unit-norm columns (parameters of very different units)."""
    n, p = J.shape
    s2 = cost / max(n - p, 1)
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    Js = J / norms
    return s2 * np.linalg.pinv(Js.T @ Js) / np.outer(norms, norms)


def _search_step(
    residual: Residual,
    names: tuple[str, ...],
    st: _State,
    Jz: np.ndarray,
    scale: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    xtol: float,
    max_inner: int,
    deadline: Deadline,
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray] | None:
    """Raise the damping until a projected step lowers the cost: ``(x, r, cost, dz)`` or None.

    A trial point where the model cannot be built (a RobustctlError) counts as a rejection.
    """
    lo, hi = bounds
    z = st.x / scale
    for _ in range(int(max_inner)):
        if deadline.expired():
            return None
        dz = _projected_step(Jz, st.r, st.lam, z, lo / scale, hi / scale)
        if np.linalg.norm(dz) <= xtol * (np.linalg.norm(z) + xtol):
            return None
        x_new = np.clip((z + dz) * scale, lo, hi)
        st.n_evals += 1
        try:
            r_new = residual.vector(**dict(zip(names, (float(v) for v in x_new))))
        except RobustctlError:
            st.lam *= 10.0
            continue
        c_new = float(r_new @ r_new)
        if np.isfinite(c_new) and c_new < st.cost:
            return x_new, r_new, c_new, dz
        st.lam *= 10.0
    return None


def levenberg_marquardt(
    residual: Residual,
    names: Sequence[str],
    x0: Mapping[str, float] | Sequence[float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | Any = None,
    max_iter: int = 20,
    time_budget_s: float | Deadline | None = None,
    *,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
    gtol: float = 1e-12,
    lam0: float = 1e-3,
    max_inner: int = 12,
    executor: Executor | None = None,
    progress: bool = False,
    callback: Callable[[int, dict[str, float], float], None] | None = None,
    start: Sensitivities | None = None,
) -> LMResult:
    """Minimise MACE's cost ``J = j^T j`` (eq. 5) over named parameters.

    Each iteration refreshes the finite-difference sensitivities (eq. 7) at the current
    point, solves the Marquardt-damped normal equations in parameters normalised by
    their starting magnitude, projects the step onto the bounds (components pushing
    into an active bound are frozen), and accepts it if the cost falls; otherwise the
    damping grows tenfold (at most ``max_inner`` times per iteration).

    Parameters
    ----------
    residual : Residual
    names : sequence of str
        Parameters to fit.
    x0 : mapping or sequence, optional
        Starting values (parameter units); default the model's values.
    bounds : mapping name -> (lo, hi) or array (p, 2), optional
        Default: each Parameter's bounds. Must contain ``x0``.
    max_iter : int
        Iteration cap (each costs ``p`` to ``p + max_inner`` residual evaluations).
    time_budget_s : float, Deadline or None
        Optional wall-clock budget in s (or a caller's shared Deadline), checked before each
        evaluation batch (:mod:`robustctl.budget`); None: ``max_iter`` and ``max_inner`` alone
        bound the work. A stop by the budget sets ``stopped_by_budget``.
    ftol, xtol, gtol : float
        Stop when the relative cost decrease, the relative step, or the scaled
        gradient ``max |J^T r| / J`` falls below these.
    lam0 : float
        Initial damping.
    max_inner : int
        Damping increases allowed per iteration before giving up.
    executor : concurrent.futures.Executor, optional
        Parallel sensitivity evaluations.
    progress : bool
        tqdm bar over iterations (only on a terminal).
    callback : callable ``(iteration, x, cost)``, optional
        Called after each iteration.
    start : Sensitivities, optional
        :func:`~robustctl.correlate.residual.sensitivities` of (at least) ``names`` already
        computed at the starting point (e.g. for MACE's selection tests): their residual
        and Jacobian columns are reused instead of re-evaluated (saves ``1 + p`` evaluations).

    Returns
    -------
    LMResult

    Raises
    ------
    ModelError
        Unknown parameter names.
    FitError
        Bounds that exclude the start, malformed ``x0`` or bounds, or a non-finite cost.
    """
    from tqdm import tqdm

    t_start = time.perf_counter()
    model = residual.model
    names = _check_names(model, names)
    if int(max_iter) < 0:
        raise FitError(f"max_iter must be >= 0; got {max_iter}.")
    lo, hi = parameter_bounds(model, names, bounds)
    x = _start(model, names, x0, lo, hi)
    scale = np.where(np.abs(x) > 0, np.abs(x), 1.0)

    def overrides(xv: np.ndarray) -> dict[str, float]:
        return dict(zip(names, (float(v) for v in xv)))

    if start is None:
        r, jac_at_x, n_evals = residual.vector(**overrides(x)), None, 1
    else:
        (r, jac_at_x), n_evals = _from_start(start, model, names, x), 0
    cost = float(r @ r)
    if not np.isfinite(cost):
        raise FitError("the cost at the starting point is not finite; check the model and data.")
    st = _State(x=x, r=r, cost=cost, lam=lam0, n_evals=n_evals)
    history, x_hist = [cost], [overrides(x)]
    reason, success, n_iter = "iteration cap reached", False, 0

    def jacobian() -> np.ndarray:
        sens = sensitivities(residual, names, at=overrides(st.x), j0=st.r, executor=executor)
        st.n_evals += sens.n_evals
        return sens.jacobian()

    deadline = as_deadline(time_budget_s, FitError)
    show = bool(progress) and sys.stderr.isatty()
    bar = tqdm(total=max_iter, desc="Levenberg-Marquardt", disable=not show, leave=False)
    try:
        for it in range(int(max_iter)):
            if deadline.expired():
                reason = f"time budget of {deadline.budget_s:g} s used up"
                break
            if st.cost <= 1e-28 * residual.n:
                reason, success = "converged: the residual vanished (exact fit)", True
                break
            if jac_at_x is None:
                jac_at_x = jacobian()
            Jz = jac_at_x * scale
            grad = Jz.T @ st.r
            if np.max(np.abs(grad)) <= gtol * max(st.cost, 1e-300):
                reason, success = "converged: gradient below gtol", True
                break
            z = st.x / scale
            trial = _search_step(residual, names, st, Jz, scale, (lo, hi), xtol, max_inner, deadline)
            accepted = trial is not None
            if accepted:
                x_new, r_new, c_new, dz = trial
            n_iter = it + 1
            bar.update(1)
            if not accepted:
                if deadline.hit:
                    reason = f"time budget of {deadline.budget_s:g} s used up"
                else:
                    reason, success = "converged: no step reduces the cost further", True
                history.append(st.cost)
                x_hist.append(overrides(st.x))
                break
            rel = (st.cost - c_new) / max(st.cost, 1e-300)
            rel_step = np.linalg.norm(dz) / (np.linalg.norm(z) + xtol)
            st.x, st.r, st.cost = x_new, r_new, c_new
            st.lam = max(st.lam / 10.0, 1e-12)
            jac_at_x = None
            history.append(st.cost)
            x_hist.append(overrides(st.x))
            if callback is not None:
                callback(n_iter, overrides(st.x), st.cost)
            if rel < ftol:
                reason, success = f"converged: relative cost change {rel:.2g} < ftol", True
                break
            if rel_step < xtol:
                reason, success = f"converged: relative step {rel_step:.2g} < xtol", True
                break
    finally:
        bar.close()
    if jac_at_x is None:
        jac_at_x = jacobian()
    cov = _covariance(jac_at_x, st.cost)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    active = tuple(n for n, v, a, b in zip(names, st.x, lo, hi) if v <= a or v >= b)
    return LMResult(
        names=names,
        x=overrides(st.x),
        x0=x_hist[0],
        cost=st.cost,
        cost0=history[0],
        history=tuple(history),
        x_history=tuple(x_hist),
        jacobian=jac_at_x,
        covariance=cov,
        std_errors=dict(zip(names, (float(s) for s in se))),
        n_iter=n_iter,
        n_evals=st.n_evals,
        stop_reason=reason,
        success=success,
        time_s=time.perf_counter() - t_start,
        vector=st.r,
        active=active,
        stopped_by_budget=deadline.hit,
    )
