"""The result of ``rc.update``: :class:`UpdateResult` (fitted values, their covariance and its
samples, drift and verdict tables)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..checks import check_seed
from ..errors import FitError, ModelError
from ..measure.noise import NO_NOISE_SENTENCE, format_p
from ..physical.uncertain import parametric_lft
from ..plots import annotated_matrix, colorbar, new_figure, plain_log_axis
from ..table import Table, result_html
from .optimize import LMResult
from .parameter_drift import Drift, move_test
from .verdict import ALPHA, NoiseTest


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
        before, after = self.initial_model.param(worst[0]).value, self.model.param(worst[0]).value
        pct = f", {100 * (after - before) / before:+.3g} %" if before else ""
        head = (
            f"Parameter moves against the noise: m^T C^-1 m = {t:.3g} on {dof} dof ({format_p(p)}); "
            f"largest {worst[0]} by {worst[1]:+.2g} SE{pct}: "
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

    def uncertain(self, n_sigma: float = 2.0, params: Any = None, *, f_hz: Any = None, form: str = "auto",
                  order: int | None = None):
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
        form : {"auto", "modes"}
            ``"modes"``: one real scalar per retained mode's frequency (and damping) movement
            instead of per parameter axis (large or reduced models; see
            :func:`~robustctl.physical.uncertain.parametric_lft`); cover what it misses with
            :func:`robustctl.robust.uncertainty.cover.cover_remainder`.
        order : int, optional
            Reduce the model to this many states (balanced truncation) first, e.g. 12 for the
            Caltech truss's six design modes.

        Returns
        -------
        UncertainModel

        Raises
        ------
        FitError
            No updated parameter, or a name in ``params`` that was not updated.
        """
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
            return parametric_lft(self.model, chosen, center, cov, n_sigma=float(n_sigma), f_hz=f_hz,
                                  form=form, order=order)
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
        fig = fig or new_figure(13.0, 4.0)
        ax1, ax2, ax3 = fig.subplots(1, 3)
        ax1.semilogy(range(len(self.history)), self.history, "o-")
        plain_log_axis(ax1, "y")
        ax1.xaxis.get_major_locator().set_params(integer=True)
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


