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

import math
import sys
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..budget import Deadline, as_deadline
from ..checks import UNSET, check_seed, flag, integer, positive_number, probability, renamed_keyword
from ..errors import FitError, RobustctlError
from ..executors import check_executor
from ..frd import FrequencyData
from ..measure.noise import NO_NOISE_SENTENCE, format_p, noise_model
from ..physical.reduction import for_data
from ..table import Table, result_html
from .optimize import LMResult, levenberg_marquardt
from .residual import (
    NEGLIGIBLE_DB,
    Residual,
    Sensitivities,
    _check_names,
    alignment,
    check_determined,
    normalized,
    orthogonality,
    physical_model,
    sensitivities,
)
from .verdict import ALPHA, NoiseTest, noise_test

__all__ = ["UpdateResult", "update", "select_parameters", "superparameter", "move_test"]


# ---------------------------------------------------------------------------- selection
def superparameter(name_a: str, name_b: str, da: np.ndarray, db: np.ndarray) -> str:
    """The combination of two parameters with parallel relative sensitivities the data fix.

    If ``dJ_a ~ c dJ_b`` (relative sensitivities, MACE eq. 7) the residual depends on
    ``c ln a + ln b``, i.e. on ``a^c * b``; returned as a readable expression
    (``"a * b"``, ``"b / a"``, ``"a^0.5 * b"``).
    """
    c = float(da @ db) / max(float(db @ db), 1e-300)
    if abs(abs(c) - 1.0) < 0.1:
        return f"{name_a} * {name_b}" if c > 0 else f"{name_b} / {name_a}"
    if c > 0:
        return f"{name_a}^{c:.2g} * {name_b}"
    return f"{name_b} / {name_a}^{-c:.2g}"


def select_parameters(
    names: Sequence[str],
    j0: np.ndarray,
    dJ: np.ndarray,
    *,
    min_alignment: float = 0.01,
    max_orthogonality: float = 0.95,
    min_singular: float = 0.02,
    keep: Sequence[str] = (),
) -> tuple[tuple[str, ...], list[str], list[str]]:
    """MACE's two tests (eqs. 8-9) as an automatic selection.

    Parameters
    ----------
    names : sequence of str
        Candidate parameters, in the column order of ``dJ``.
    j0, dJ : ndarray
        Initial residual (n,) and sensitivities (n, p) (relative, MACE eq. 7).
    min_alignment : float
        Drop a parameter whose ``|j0^T dJ_i|`` is below this fraction of the largest.
    max_orthogonality : float
        Of a pair with ``|dJn_i^T dJn_k|`` above this, keep the better-aligned.
    min_singular : float
        After the pairwise test, while the smallest singular value of the kept normalised
        sensitivities is below this (a rank loss among three or more), drop the
        least-aligned parameter of the near-null combination.
    keep : sequence of str
        Parameters exempt from test 1 and considered first in test 2 (they win ties): the
        parameters of an effect added after ``rc.diagnose``, which already fitted them, so
        the remaining error is nearly orthogonal to them by construction.

    Returns
    -------
    selected : tuple of str
        Kept parameters, by decreasing alignment.
    notes : list of str
        Why each parameter was dropped, in words.
    suggestions : list of str
        Superparameter suggestions.
    """
    names = list(names)
    a = alignment(j0, dJ)
    amax = float(a.max()) if a.size else 0.0
    if amax <= 0:
        raise FitError(
            "no candidate parameter changes the residual (all sensitivities are zero); check that "
            "the parameters enter the model and that the band holds the modes they move."
        )
    O = orthogonality(dJ)
    notes, suggestions, kept = [], [], []
    order = sorted(range(len(names)), key=lambda i: (names[i] not in keep, -a[i]))
    for i in order:
        name = names[i]
        if a[i] < min_alignment * amax and name not in keep:
            notes.append(
                f"{name}: dropped by the alignment test (|j0^T dJ| = {a[i] / amax:.2%} of the largest): "
                "the initial error is insensitive to it."
            )
            continue
        clash = [k for k in kept if O[i, names.index(k)] > max_orthogonality]
        if clash:
            other = clash[0]
            k = names.index(other)
            combo = superparameter(other, name, dJ[:, k], dJ[:, i])
            notes.append(
                f"{name}: dropped by the orthogonality test ({O[i, k]:.3f} with {other}, which is better "
                "aligned with the initial error)."
            )
            suggestions.append(
                f"{other} and {name} move the residual the same way (orthogonality {O[i, k]:.3f}); the data "
                f"fix only the combination {combo}. {other} was kept; to update both, tie them into the "
                f"superparameter {combo}."
            )
            continue
        kept.append(name)
    while len(kept) > 1:
        cols = [names.index(k) for k in kept]
        _, s, vt = np.linalg.svd(normalized(dJ[:, cols]), full_matrices=False)
        if s[-1] >= min_singular * np.sqrt(len(kept)):
            break
        involved = [kept[m] for m in np.flatnonzero(np.abs(vt[-1]) > 0.3)]
        drop = min(involved, key=lambda n: (n in keep, a[names.index(n)]))
        kept.remove(drop)
        notes.append(
            f"{drop}: dropped because {', '.join(involved)} together move the residual in only "
            f"{len(involved) - 1} independent direction(s) (smallest singular value {s[-1]:.2g}); a "
            "superparameter of this group may be what the data determine."
        )
    return tuple(kept), notes, suggestions


# ---------------------------------------------------------------------------- drift
@dataclass(frozen=True)
class Drift:
    """Sub-band estimates of one parameter (model-form check).

    ``bands`` (Hz), ``values`` and ``std_errors`` (parameter units) per sub-band;
    ``flagged`` when two sub-bands disagree by more than ``k`` combined standard errors
    and by more than the relative floor.
    """

    name: str
    bands: tuple[tuple[float, float], ...]
    values: tuple[float, ...]
    std_errors: tuple[float, ...]
    flagged: bool


def _row_mask(residual: Residual, keep_freq: np.ndarray) -> np.ndarray:
    per_freq = residual.data.n_out * residual.data.n_in
    half = np.repeat(keep_freq, per_freq)
    return np.concatenate([half, half])


def _row_noise(residual: Residual) -> np.ndarray | None:
    """Variance of each row of the residual vector from the noise model, or None.

    A row is ``sqrt(W) Re e`` or ``sqrt(W) Im e``: variance ``W sigma^2``, inflated by the
    Satterthwaite factor of the window's bin correlation (neighbouring rows are not
    independent).
    """
    nm = residual.noise
    if nm is None:
        return None
    v = (residual.point_weights * nm.sigma**2 * nm.dof_factor).ravel()
    return np.concatenate([v, v])


def _noise_covariance(residual: Residual, fit: LMResult) -> np.ndarray | None:
    """Covariance of the fitted parameters from the noise model (parameter units), or None.

    The sandwich ``(J^T J)^-1 J^T diag(v) J (J^T J)^-1`` with ``v`` the rows' noise variances
    (Gauss-Newton estimate under heteroscedastic noise; White 1980), computed with unit-norm
    columns so parameters of very different units do not spoil the conditioning.

    Known limitation (conservative): the meat treats the rows as independent, each inflated by
    the noise-only factor ``dof_factor``. At lightly damped resonances, where the information
    is, the H1 error is mostly leakage, whose errors at neighbouring bins correlate negatively
    (about -0.35 at one bin on the Caltech truss, against +0.30 for output noise; see
    :mod:`robustctl.measure.noise`) and across the outputs of one input; the variance of ``J^T r`` over
    40 seeds was 0.12-0.84 of this meat's, and the standard errors are 1.25-2.4 x the scatter
    of the estimates over seeds (Caltech truss and the user chain of the tests). A meat from
    the residuals themselves (Newey-West over the two lags at which a Hamming window's bins
    correlate, all channels of a bin together) is right on average but, with the information in
    a few peak bins, varies by a factor of 2-3 from seed to seed.
    """
    v = _row_noise(residual)
    if v is None or not len(fit.names):
        return None
    J = np.asarray(fit.jacobian, dtype=float)
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    Js = J / norms
    inv = np.linalg.pinv(Js.T @ Js)
    return inv @ ((Js * v[:, None]).T @ Js) @ inv / np.outer(norms, norms)


def _std_errors(cov: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    """Square roots of the covariance diagonal by parameter name."""
    return {n: float(np.sqrt(max(cov[k, k], 0.0))) for k, n in enumerate(names)}


def move_test(move: np.ndarray, cov: np.ndarray) -> tuple[float, int, float]:
    """Joint test of a parameter move against its noise covariance.

    Under "the initial values are the truth" a consistent estimator moves the parameters by
    ``N(0, C)``, so ``T = m^T C^+ m`` is chi-square with ``r = rank(C)`` degrees of freedom
    (Wald 1943; Seber & Wild, *Nonlinear Regression*, sec. 5.2). Individual moves of one or two
    standard errors are then expected (about 32 % of parameters exceed one SE on noise alone);
    the joint test says whether the data moved the parameters beyond that.

    Parameters
    ----------
    move : ndarray (p,)
        Updated minus initial values (parameter units).
    cov : ndarray (p, p)
        Noise covariance of the estimates (parameter units squared).

    Returns
    -------
    (T, r, p_value) : (float, int, float)
    """
    from scipy.stats import chi2

    m = np.asarray(move, dtype=float)
    scale = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    scale = np.where(scale > 0, scale, 1.0)
    c = cov / np.outer(scale, scale)  # a correlation matrix: pinv is well conditioned
    z = m / scale
    w, vec = np.linalg.eigh(0.5 * (c + c.T))
    keep = w > 1e-10 * max(float(w.max()), 1e-300)
    r = int(keep.sum())
    if r == 0:
        return 0.0, 0, 1.0
    t = float(np.sum((vec[:, keep].T @ z) ** 2 / w[keep]))
    return t, r, float(chi2.sf(t, r))


def _drift_threshold(k_sigma: float | None, n_params: int, n_bands: int, alpha: float) -> float:
    """``k_sigma``, or with a noise model the Bonferroni normal quantile over all band pairs."""
    if k_sigma is not None:
        return float(k_sigma)
    from scipy.stats import norm

    n_tests = max(n_params * n_bands * (n_bands - 1) // 2, 1)
    return float(norm.isf(alpha / (2 * n_tests)))


def _drift(
    residual: Residual,
    fit: LMResult,
    n_bands: int,
    k_sigma: float | None,
    rel_floor: float,
    alpha: float = ALPHA,
) -> tuple[Drift, ...]:
    """One Gauss-Newton step from the full-band optimum on each sub-band's rows.

    At the optimum ``x`` the sub-band estimate is ``x - (J_b^T J_b)^-1 J_b^T r_b`` to first
    order, with covariance ``s_b^2 (J_b^T J_b)^-1`` -- or, with a noise model, the sandwich
    ``(J_b^T J_b)^-1 J_b^T diag(v) J_b (J_b^T J_b)^-1`` with the rows' noise variances ``v``
    (the same noise as compare's verdicts, on the same testable points): no new model
    evaluations. Two sub-band estimates
    disagree when they differ by more than ``k`` combined standard errors, ``k`` the
    Bonferroni normal quantile at family-wise ``alpha`` when ``k_sigma`` is None.
    """
    v_rows = _row_noise(residual)
    if k_sigma is None and v_rows is None:
        k_sigma = 3.0
    k_sigma = _drift_threshold(k_sigma, len(fit.names), n_bands, alpha)
    f = residual.f_hz
    if n_bands < 2 or f.size < 4 * n_bands:
        return ()
    edges = np.array_split(np.arange(f.size), n_bands)
    est, ses, bands = [], [], []
    for idx in edges:
        keep = np.zeros(f.size, dtype=bool)
        keep[idx] = True
        rows = _row_mask(residual, keep)
        if residual.noise is not None:  # noise-dominated points say nothing (as in the verdicts)
            ok = residual.noise.testable.ravel()
            rows = rows & np.concatenate([ok, ok])
        J, r = fit.jacobian[rows], fit.vector[rows]
        norms = np.linalg.norm(J, axis=0)
        norms = np.where(norms > 0, norms, 1.0)
        Js = J / norms  # unit-norm columns: parameters of very different units
        step = -np.linalg.lstsq(Js, r, rcond=None)[0] / norms
        rr = r + J @ step
        inv = np.linalg.pinv(Js.T @ Js)
        if v_rows is None:
            s2 = float(rr @ rr) / max(J.shape[0] - J.shape[1], 1)
            cov = s2 * inv / np.outer(norms, norms)
        else:
            meat = (Js * v_rows[rows][:, None]).T @ Js
            cov = inv @ meat @ inv / np.outer(norms, norms)
        est.append(fit.x_array + step)
        ses.append(np.sqrt(np.clip(np.diag(cov), 0, None)))
        bands.append((float(f[idx[0]]), float(f[idx[-1]])))
    est, ses = np.array(est), np.array(ses)
    out = []
    for p, name in enumerate(fit.names):
        v, s = est[:, p], ses[:, p]
        ref = max(abs(fit.x[name]), 1e-300)
        # a sub-band that cannot pin the parameter to 20 % says nothing: its one linear step
        # from the full-band optimum would leave the range where the linearisation holds
        usable = s < 0.2 * ref
        flagged = False
        for i in np.flatnonzero(usable):
            for k in np.flatnonzero(usable):
                if k <= i:
                    continue
                diff = abs(v[i] - v[k])
                if diff > k_sigma * np.hypot(s[i], s[k]) and diff > rel_floor * ref:
                    flagged = True
        out.append(Drift(name, tuple(bands), tuple(map(float, v)), tuple(map(float, s)), flagged))
    return tuple(out)


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class UpdateResult:
    """Result of :func:`update`.

    Attributes
    ----------
    model : PhysicalModel
        The updated model.
    initial_model : PhysicalModel
    history : tuple of float
        Cost J (MACE eq. 5) at the start and after each iteration.
    cost_before, cost_after : float
    reduction : float
        Fractional cost reduction ``1 - cost_after / cost_before``.
    candidates : tuple of str
        Parameters considered (columns of ``alignment`` / ``orthogonality``).
    alignment : ndarray (n_candidates,)
        MACE test 1, ``|j0^T dJ|`` with relative sensitivities (Fig. 3).
    orthogonality : ndarray (n_candidates, n_candidates)
        MACE test 2, ``|dJn^T dJn|`` (Fig. 4).
    selected : tuple of str
        Parameters updated.
    fit : LMResult
        The Levenberg-Marquardt run (Jacobian, covariance, stop reason).
    std_errors : dict
        Standard errors of the updated parameters (parameter units): from the noise model when
        there is one (sandwich covariance with the window's bin correlation), else from the
        residual's scatter (``fit.std_errors``).
    drift : tuple of Drift
        Sub-band estimates (model-form check).
    notes, suggestions, warnings : tuple of str
        Selection decisions, superparameter suggestions, and things to look at.
    band : (float, float) or None
    time_s : float
        Wall-clock time (s).
    n_evals : int
        Model evaluations (frequency responses) over all passes.
    noise_before, noise_after : NoiseTest or None
        Chi-square verdicts of the misfit against the data's noise before and after the update
        (None without a noise model: no significance claims).
    estimator_note : str
        How the model was seen: through the H1 estimator, or as the plain FRF and why
        (:func:`robustctl.measure.estimator.experiment_view`).
    noise_covariance : ndarray (n_selected, n_selected) or None
        Covariance of the updated values from the noise model (parameter units, order of
        ``selected``); None without a noise model. Behind :attr:`moves_se` and
        :attr:`move_test`.
    stopped_by_budget : bool
        A ``time_budget_s`` stopped the optimisation early (:mod:`robustctl.budget`; also in
        ``warnings``).
    """

    model: Any
    initial_model: Any
    history: tuple[float, ...]
    cost_before: float
    cost_after: float
    candidates: tuple[str, ...]
    alignment: np.ndarray
    orthogonality: np.ndarray
    selected: tuple[str, ...]
    fit: LMResult = field(repr=False)
    std_errors: dict[str, float] = field(default_factory=dict)
    drift: tuple[Drift, ...] = ()
    notes: tuple[str, ...] = ()
    suggestions: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    band: tuple[float, float] | None = None
    time_s: float = 0.0
    n_evals: int = 0
    noise_before: NoiseTest | None = None
    noise_after: NoiseTest | None = None
    estimator_note: str = ""
    noise_covariance: np.ndarray | None = field(default=None, repr=False)
    stopped_by_budget: bool = False

    @property
    def moves_se(self) -> dict[str, float]:
        """Each updated parameter's move (after - before) in standard errors (NaN without SE).

        On noise alone a consistent estimator moves each parameter by about ``N(0, 1)`` SE: about
        a third of them beyond one SE, one in 370 beyond three; :attr:`move_test` is the joint
        verdict.
        """
        out = {}
        for name in self.selected:
            se = self.std_errors.get(name, math.nan)
            move = self.model.param(name).value - self.initial_model.param(name).value
            out[name] = move / se if se and np.isfinite(se) and se > 0 else math.nan
        return out

    @property
    def move_test(self) -> tuple[float, int, float] | None:
        """``(T, dof, p)``: the joint move ``m^T C^+ m`` against chi-square(dof) (:func:`move_test`),
        or None without a noise model. ``p >= alpha``: no parameter moved beyond what the noise
        alone would do, i.e. the data do not contradict the initial values."""
        if self.noise_covariance is None or not self.selected:
            return None
        before, after = self.initial_model, self.model
        move = np.array([after.param(n).value - before.param(n).value for n in self.selected])
        return move_test(move, self.noise_covariance)

    def move_sentence(self, alpha: float = ALPHA) -> str:
        """The joint move test in words (``""`` without a noise model)."""
        test = self.move_test
        if test is None:
            return ""
        t, dof, p = test
        worst = max(self.moves_se.items(), key=lambda kv: abs(kv[1]) if np.isfinite(kv[1]) else -1.0)
        head = (
            f"Parameter moves against the noise: m^T C^-1 m = {t:.3g} on {dof} dof ({format_p(p)}); "
            f"largest {worst[0]} by {worst[1]:+.2g} SE: "
        )
        if p >= alpha:
            return head + f"no parameter moved significantly (at {alpha:g}): the data do not contradict " \
                "the initial values."
        return head + f"the data moved the parameters beyond the noise (p < {alpha:g})."

    @property
    def n_iter(self) -> int:
        """Levenberg-Marquardt iterations over all passes."""
        return len(self.history) - 1

    @property
    def reduction(self) -> float:
        return 0.0 if self.cost_before == 0 else 1.0 - self.cost_after / self.cost_before

    @property
    def values(self) -> dict[str, float]:
        """Updated values of the selected parameters."""
        return dict(self.fit.x)

    def sample_parameters(self, n: int, seed: Any = 0, *, max_draws: int = 100) -> np.ndarray:
        """Parameter sets drawn from the fit's normal approximation, within the bounds.

        The updated values are Gauss-Newton estimates with covariance ``s^2 (J^T J)^+``
        (``fit.covariance``: the standard errors and their correlations, parameter units);
        draws follow ``N(values, covariance)`` (a symmetric square root by eigenvalues, so a
        singular covariance is fine) truncated to each parameter's bounds by rejection:
        a draw outside a bound is discarded (at most ``max_draws * n`` draws in total).

        Parameters
        ----------
        n : int
            Number of parameter sets (>= 1).
        seed : int, numpy Generator or None
            Random seed (default 0: the same draws on every call; None draws fresh entropy).
        max_draws : int
            Rejection cap, in multiples of ``n``.

        Returns
        -------
        ndarray (n, n_selected)
            Columns in the order of ``selected``.

        Raises
        ------
        FitError
            ``n`` not a positive integer, no updated parameter, or too many draws fall outside
            the bounds (the fit ended near a bound: widen it or fix that parameter).
        """
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise FitError(f"n must be a positive integer (number of parameter sets); got {n!r}.")
        names = self.fit.names
        if not names:
            raise FitError("the update changed no parameter: there is no spread to sample.")
        mean = self.fit.x_array
        cov = 0.5 * (self.fit.covariance + self.fit.covariance.T)
        lam, vec = np.linalg.eigh(cov)
        root = vec * np.sqrt(np.clip(lam, 0.0, None))
        lo = np.array([self.model.param(k).bounds[0] for k in names], dtype=float)
        hi = np.array([self.model.param(k).bounds[1] for k in names], dtype=float)
        rng = np.random.default_rng(check_seed(seed, error=FitError))
        kept, drawn = [], 0
        while sum(len(k) for k in kept) < n and drawn < max_draws * n:
            batch = mean + rng.standard_normal((n, len(names))) @ root.T
            drawn += n
            kept.append(batch[np.all((batch >= lo) & (batch <= hi), axis=1)])
        out = np.concatenate(kept)[:n]
        if out.shape[0] < n:
            raise FitError(
                f"only {out.shape[0]} of {drawn} draws fell within the parameter bounds of {list(names)}; "
                "the fit lies at or near a bound. Widen that bound or leave the parameter out of the update."
            )
        return out

    def uncertain(self, n_sigma: float = 2.0, params: Any = None, *, f_hz: Any = None):
        """The updated model with its parameters as real uncertain scalars (an LFT).

        The selected parameters (or ``params``, a subset; the others stay at their updated
        values) vary over the ``n_sigma`` box of the fit's covariance along its principal
        axes (correlations included): ``theta = theta_hat + sum_k delta_k a_k``, ``delta_k``
        real in [-1, 1], one repeated real scalar block per axis
        (:func:`robustctl.physical.uncertain.parametric_lft`: exact where the state-space
        matrices are affine in the parameters, else first order, with its error against
        models sampled in the box stated). ``rc.generalized_plant(upd.uncertain(), ...)``
        puts the blocks first in ``.blocks``; ``rc.dksyn`` then runs D-G-K on them.

        Parameters
        ----------
        n_sigma : float
            Half-width of the box in standard deviations.
        params : sequence of str, optional
            The parameters to make uncertain (default: all updated ones).
        f_hz : array_like, optional
            Frequencies (Hz) of the LFT's error check.

        Returns
        -------
        UncertainModel

        Raises
        ------
        FitError
            No updated parameter, or a name in ``params`` that was not updated.
        """
        from ..errors import ModelError
        from ..physical.uncertain import parametric_lft

        names = tuple(self.fit.names)
        if not names:
            raise FitError("the update changed no parameter: there is no uncertainty to model.")
        chosen = names if params is None else tuple(params)
        unknown = [p for p in chosen if p not in names]
        if unknown or not chosen:
            raise FitError(f"params must be among the updated parameters {list(names)}; got {list(chosen)}.")
        idx = [names.index(p) for p in chosen]
        cov = np.asarray(self.fit.covariance, dtype=float)[np.ix_(idx, idx)]
        center = np.asarray(self.fit.x_array, dtype=float)[idx]
        try:
            return parametric_lft(self.model, chosen, center, cov, n_sigma=float(n_sigma), f_hz=f_hz)
        except ModelError as exc:
            raise FitError(f"cannot build the uncertain model: {exc}") from exc

    def sample_models(self, n: int, seed: Any = 0, *, max_draws: int = 100) -> tuple[Any, ...]:
        """Models with parameters drawn from the fitted covariance (see :meth:`sample_parameters`).

        Their spread about ``model`` is the parameter uncertainty the data leave; a cover of
        the measured residual plus this spread (``rc.cover_additive(upd.model, [data,
        *upd.sample_models(50)])``) is an honest uncertainty weight for the updated model.

        Returns
        -------
        tuple of PhysicalModel
            ``model.with_values(...)`` for each drawn set.
        """
        draws = self.sample_parameters(n, seed, max_draws=max_draws)
        names = self.fit.names
        return tuple(self.model.with_values(**dict(zip(names, map(float, row)))) for row in draws)

    def table(self) -> Table:
        """Before/after parameter table with standard errors and the selection tests."""
        a_max = float(self.alignment.max()) if self.alignment.size else 1.0
        drift = {d.name: d.flagged for d in self.drift}
        moves = self.moves_se
        rows = []
        for k, name in enumerate(self.candidates):
            p0 = self.initial_model.param(name)
            after = self.model.param(name).value
            sel = name in self.selected
            rows.append(
                (
                    name,
                    p0.unit,
                    p0.value,
                    after,
                    100.0 * (after - p0.value) / p0.value if p0.value else float("nan"),
                    self.std_errors.get(name, float("nan")) if sel else float("nan"),
                    moves.get(name, float("nan")) if sel else float("nan"),
                    self.alignment[k] / a_max if a_max > 0 else 0.0,
                    sel,
                    drift.get(name, False) if sel else None,
                )
            )
        return Table(
            (
                "parameter",
                "unit",
                "before",
                "after",
                "change (%)",
                "std error",
                "move (SE)",
                "alignment (rel.)",
                "updated",
                "drifts",
            ),
            rows,
            title=f"model update: cost {self.cost_before:.4g} -> {self.cost_after:.4g} "
            f"({self.reduction:.1%} lower, {self.n_iter} iterations)",
        )

    def drift_table(self) -> Table:
        """Sub-band estimates of every updated parameter."""
        rows = []
        for d in self.drift:
            for (lo, hi), v, s in zip(d.bands, d.values, d.std_errors):
                rows.append((d.name, lo, hi, v, s, d.flagged))
        return Table(
            ("parameter", "lo (Hz)", "hi (Hz)", "estimate", "std error", "flagged"),
            rows,
            title="sub-band estimates (model-form check)",
        )

    def summary(self) -> str:
        """The update in plain words."""
        lines = [
            f"Updated {len(self.selected)} of {len(self.candidates)} candidate parameters "
            f"({', '.join(self.selected)}): cost {self.cost_before:.4g} -> {self.cost_after:.4g} "
            f"({self.reduction:.1%} lower) in {self.n_iter} iterations, {self.n_evals} model "
            f"evaluations, {self.time_s:.1f} s; {self.fit.stop_reason}."
        ]
        for name in self.selected:
            p0 = self.initial_model.param(name).value
            p1 = self.model.param(name).value
            change = f"{100 * (p1 - p0) / p0:+.2f}%, " if p0 else ""
            lines.append(
                f"  {name}: {p0:.5g} -> {p1:.5g} {self.model.param(name).unit} "
                f"({change}+- {self.std_errors.get(name, 0):.2g})"
            )
        if self.estimator_note:
            lines.append(self.estimator_note[:1].upper() + self.estimator_note[1:] + ".")
        if self.noise_after is None:
            lines.append(NO_NOISE_SENTENCE[:1].upper() + NO_NOISE_SENTENCE[1:] + ".")
        else:
            lines.append("After the update: " + self.noise_after.sentence())
        if self.move_test is not None:
            lines.append(self.move_sentence())
        lines += [f"Note: {n}" for n in self.notes]
        lines += [f"Suggestion: {s}" for s in self.suggestions]
        lines += [f"Warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def __repr__(self) -> str:
        return (
            f"UpdateResult(selected={list(self.selected)}, cost {self.cost_before:.4g} -> "
            f"{self.cost_after:.4g}, reduction={self.reduction:.1%}, warnings={len(self.warnings)})"
        )

    def plot(self, fig: Any = None) -> Any:
        """Cost per iteration, alignment bar chart (Fig. 3) and orthogonality matrix (Fig. 4)."""
        from ..plots import annotated_matrix, colorbar, new_figure

        fig = fig or new_figure(13.0, 4.0)
        ax1, ax2, ax3 = fig.subplots(1, 3)
        ax1.semilogy(range(len(self.history)), self.history, "o-")
        ax1.set_xlabel("iteration")
        ax1.set_ylabel("cost J (MACE eq. 5)")
        ax1.set_title(f"cost: {self.reduction:.1%} lower")
        a = self.alignment / (self.alignment.max() or 1.0)
        colors = ["C0" if n in self.selected else "0.7" for n in self.candidates]
        ax2.bar(range(len(a)), a, color=colors)
        ax2.set_xticks(range(len(a)))
        ax2.set_xticklabels(self.candidates, rotation=60, ha="right", fontsize=7)
        ax2.set_ylabel("alignment (relative, -)")
        ax2.set_title("alignment |j0^T dJ| (MACE eq. 8)")
        _alignment_legend(ax2, [n in self.selected for n in self.candidates])
        names = self.candidates
        im = annotated_matrix(ax3, self.orthogonality, names, names, fmt=".1f", max_cells=15 * 15)  # n <= 15
        ax3.set_title("orthogonality |dJn^T dJn|")
        colorbar(fig, im, ax3, "orthogonality (-)")
        return fig


def _alignment_legend(ax: Any, selected: list[bool]) -> None:
    """A legend naming only the bar colours actually drawn (updated / not updated)."""
    from matplotlib.patches import Patch

    handles = [Patch(color="C0", label="updated")] if any(selected) else []
    if not all(selected):
        handles.append(Patch(color="0.7", label="not updated"))
    ax.legend(handles=handles, fontsize=7)


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


def _coarse_start(
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
    if isinstance(noise, str) and noise == "auto":
        from ..frd import as_frequency_data

        noise = noise_model(as_frequency_data(data), measurement_model=measurement_model)
    residual = Residual(for_data(model, data, band), data, band=band, point_weights=point_weights,
                        min_channel_db=min_channel_db,
                        estimator=estimator, noise=noise)
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
    x0, n_coarse = _coarse_start(residual, tuple(selected), sens, effect_params)
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
    if residual.dropped:
        notes.append(
            "left out as negligible (decoupled) channels: "
            + ", ".join(f"{o} <- {i} ({lv:.0f} dB)" for o, i, lv in residual.dropped)
            + "."
        )
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
    from ..lti import log_ratio

    d = residual.data
    e = log_ratio(d.response, residual.model_response(**values))
    keep = np.any(residual.weights > 0, axis=0)
    return noise_test(e, residual.noise, d.f_hz, d.outputs, d.inputs, keep, alpha=alpha)
