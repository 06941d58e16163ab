"""The results of ``rc.diagnose``: :class:`CandidateResult` and :class:`Diagnosis`, and the
family-wide significance level and default channel levels they report."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...measure.noise import NO_NOISE_SENTENCE, format_p
from ...plots import log_frequency_axis, new_figure
from ...table import Table, result_html

#: Family-wise significance level of the candidates' tests (Holm-adjusted p-values are compared with it).
ALPHA = 0.01
#: A channel this far (dB) below its row's and column's largest model response is ignored.
#: Default negligible-channel level of diagnose (dB): stricter than compare's and update's
#: :data:`~robustctl.correlate.residual.NEGLIGIBLE_DB` (-80 dB), because a channel the model
#: leaves nearly decoupled carries noise no effect explains and would blur the F-tests. Pass
#: ``min_channel_db=`` to change it;
#: ``rc.update(..., min_channel_db=-60.0)`` reproduces diagnose's cost (so does
#: ``point_weights=diag.point_weights`` where no coherence-weight bias applies,
#: :func:`robustctl.measure.noise.point_weight_bias`: an array of weights is taken as given).
DECOUPLED_DB = -60.0
#: Smallest share of the null-fit residual an effect must explain to be proposed.
MIN_GAIN = 0.25
#: Share of the model-error part of the misfit (the parameters-only fit's excess dispersion over
#: the noise) a significant effect must remove to be *the answer* when the model with it is still
#: beyond the noise (:mod:`robustctl.correlate.diagnosis.answer`).
ANSWER_SHARE = 0.9
_DB = 20.0 / math.log(10.0)


# ============================================================================ results
@dataclass(frozen=True, eq=False)
class CandidateResult:
    """One candidate effect, scored.

    Attributes
    ----------
    effect : Effect
        The effect with its estimated values (fitted when ``fitted``, otherwise the linear
        screening estimate).
    fraction : float
        Share of the residual left by the update parameters that the candidate explains to
        first order (``cos^2`` of the principal angle; 0..1).
    angle_deg : float
        The principal angle in degrees between the projected residual and the projected
        secant (90: orthogonal, nothing explained).
    fitted : bool
        Whether the local fit was run.
    cost : float
        MACE cost ``J`` after the local fit (or the linear prediction).
    reduction : float
        ``1 - J / J_nominal``: cost reduction against the nominal model (0..1).
    gain : float
        ``1 - J / J_update``: share of the residual left by updating alone that the effect
        removes (0..1).
    f_stat, p_value : float
        The test statistic (``Delta J`` over the variance along the fitted change: of the noise,
        or of the misfit left when that is larger, :func:`_candidate_test`) and its family-wise
        p-value (Holm's step-down adjustment over every screened candidate, so the best
        candidate's p-value is uniform or conservative when no effect is missing); NaN when not
        fitted or without a noise model.
    significant : bool
        ``p_value < level``, ``gain >= min_gain`` and not at a bound.
    update_values : dict
        Update-parameter values of the local fit.
    where : str
        Where the explained error lies ("phase error, 3.1-5.5 Hz").
    sentence : str
        A plain sentence.
    equivalent : tuple of str
        Names of candidates whose secant is identical (e.g. a delay on every output and one
        on every input): the data cannot tell them apart; they are not ranked separately.
    level : float
        The family-wise level ``alpha`` the adjusted ``p_value`` is compared with; NaN without a
        noise model.
    min_gain : float
        The practical threshold on ``gain``.
    note : str
        What the effect is physically when it can be named (a delay of half a sample in data
        whose input was held: the DAC zero-order hold).
    p_raw : float
        The unadjusted p-value of the candidate's own test.
    scale : str
        What the test measured the cost drop against: ``"noise"`` (the data's noise model) or
        ``"misfit"`` (the misfit the candidate leaves, larger than the noise: model error).
    at_bound : bool
        The fit ended at a bound of the effect's parameter (far from neutral): the model form is
        likely wrong, and the candidate is never proposed.
    incomplete : bool
        Significant, but the model with it is still beyond the noise and it removes less than
        :data:`ANSWER_SHARE` of the model error: the closest candidate, not the answer.
    z_vs_best, p_vs_best : float
        Vuong's (1989) statistic of the best candidate against this one and its one-sided
        p-value ("the best explains the data no better"), the variance of the pointwise
        differences estimated from the data (:func:`_rival_test`); NaN for the best.
    """

    effect: Any
    fraction: float
    angle_deg: float
    fitted: bool
    cost: float
    reduction: float
    gain: float
    f_stat: float = math.nan
    p_value: float = math.nan
    significant: bool = False
    update_values: dict = field(default_factory=dict)
    where: str = ""
    sentence: str = ""
    equivalent: tuple[str, ...] = ()
    level: float = math.nan
    min_gain: float = MIN_GAIN
    note: str = ""
    p_raw: float = math.nan
    scale: str = ""
    at_bound: bool = False
    z_vs_best: float = math.nan
    p_vs_best: float = math.nan
    incomplete: bool = False

    @property
    def name(self) -> str:
        return self.effect.name

    @property
    def kind(self) -> str:
        return self.effect.kind

    @property
    def location(self) -> str | None:
        return self.effect.location

    @property
    def values(self) -> dict[str, float]:
        return self.effect.values


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Result of :func:`diagnose`: candidate effects ranked by what they explain.

    Attributes
    ----------
    ranking : tuple of CandidateResult
        Fitted candidates by gain, then the others by their screening fraction.
    best : Effect or None
        The top significant effect with its fitted values (``model.with_effect(best)``),
        or None when the data support no candidate.
    cost_nominal : float
        MACE cost ``J`` of the model as given.
    cost_update : float
        ``J`` after fitting the update parameters alone (the null model).
    update_params : tuple of str
    update_values : dict
        Null-fit values of the update parameters.
    n, n_eff : int, float
        Residual length and effective number of independent points.
    rho : float
        Lag-one autocorrelation of the null-fit residual along frequency.
    alpha : float
        The per-candidate level of the best candidate's raw p-value, ``family_alpha / m`` over the
        ``m`` screened candidates (Bonferroni; Holm's step-down for the others).
    unexplained : str
        Where the null-fit residual sits (band, channels, magnitude or phase).
    ignored_channels : tuple of (output, input)
        Channels the model leaves decoupled, weighted 0 (see ``_residual``).
    point_weights : ndarray (n_freq, n_out, n_in)
        The data-point weights used, zero on ignored channels (``rc.update(...,
        min_channel_db=)`` at diagnose's level gives the same cost; these weights handed on do
        too unless the coherence weights' bias applied, which an array of weights does not get).
    residual_update : ndarray (n_freq, n_out, n_in), complex
        The weighted residual left after fitting the update parameters alone (the null fit).
    f_hz : ndarray (n_freq,)
        Frequencies of the residuals, Hz.
    explained : dict of str to ndarray
        For the two top candidates, the part of ``residual_update`` each one's fit explains
        (same shape), plotted by :meth:`plot`.
    band : (float, float) or None
    n_evals : int
        Model evaluations spent.
    time_s : float
    noise_source : str
        Where the noise estimate behind the p-values came from; ``""``: none (no significance
        claims are made, p-values are NaN).
    estimator_note : str
        How the model was seen: through the H1 estimator, or as the plain FRF and why
        (:func:`robustctl.measure.estimator.experiment_view`).
    indistinguishable : Indistinguishable or None
        The fitted candidates the data in this band cannot tell from the top one (equal cost
        within the noise, nearly collinear fitted changes), with where their fitted models
        differ; None when the top candidate is clearly the best explanation.
    stopped_by_budget : bool
        A ``time_budget_s`` stopped the null fit, a local fit or the polishing before
        convergence: the ranking depends on the machine's speed (:mod:`robustctl.budget`).
    family_alpha : float
        The family-wise level the adjusted p-values are compared with (``alpha`` of the call).
    dispersion : float
        The null fit's residual over its noise expectation (mean squared normalised residual on
        the testable points; 1 within the noise, NaN without a noise model).
    p_null : float
        Chi-square p-value of "the parameters-only fit is within the noise" (:func:`_null_test`);
        below ``family_alpha`` the candidates were tested against the misfit left (model error).
    channel_verdict : str
        When no candidate is proposed and the misfit is beyond the noise: the output row (or input
        column) that holds most of it, with what to check; ``""`` otherwise.
    input_held : bool
        Whether the data say their input was a held (DAC) command: only then is a half-sample
        delay named the zero-order hold.
    verdict : str
        ``"within the noise"`` (nothing is missing), ``"answer"`` (``best``, or the chain's
        ``effects``, bring the model within the noise or remove nearly all of the model error),
        ``"incomplete"`` (significant effects leave the misfit beyond the noise: ``best`` is None,
        ``closest`` is the closest candidate), ``"unexplained"`` (beyond the noise, nothing
        significant) or ``"no noise model"`` (:data:`~.answer.VERDICTS`).
    closest : Effect or None
        When the verdict is ``"incomplete"``: the significant effect (fitted) that explains most,
        but not all, of the misfit.
    completeness : Completeness or None
        The completeness test of the proposed or closest effect (:func:`~.answer.completeness`).
    left : tuple of MisfitBand
        Where the misfit left sits (bands, the modes of the model there and the locations they
        move) when the verdict is ``"incomplete"`` or ``"unexplained"``.
    dispersion_left : float
        The misfit left over the noise (1 within the noise) with the proposed or closest effects.
    model_error_removed : float
        Share of the model-error part of the parameters-only fit's misfit they remove (0..1).
    best_fit_values : dict
        The update parameters' values fitted with the proposed (or closest) effect.
    chain : tuple of ChainStep
        The effects proposed one after another, each on the model updated with those before
        (``diagnose(..., chain=True)``); one step without a chain.
    effects : tuple of Effect
        The answer's effects in chain order (empty unless the verdict is ``"answer"``):
        ``diag.with_effects(model)`` applies them.
    chain_exhausted : bool
        An incomplete chain ended because nothing more was significant on the model with its
        effects: the missing effect is probably not among the candidates.
    lead : Effect or None
        The effect the next step of a chain starts from: the closest one, or, when nothing is
        significant, a candidate explaining :data:`~.answer.CHAIN_TRY_GAIN` of the residual.
    chain_limit : int
        The most effects the call chained (1: ``chain=False``).
    screening : dict
        How the (first step's) candidates were screened: ``"candidates"`` in all, and how many by
        each stage -- ``"exact"`` (secant screening on the model), ``"closed form"`` (point effects
        fitted in closed form on the reduced modal model) and ``"first order"`` (point effects only
        scored by their first-order share of the misfit, below the closed form's
        :data:`~.screening.PRESCREEN_KEEP` best); ``"rule"`` says how the locations were chosen.
    """

    ranking: tuple[CandidateResult, ...]
    best: Any
    cost_nominal: float
    cost_update: float
    update_params: tuple[str, ...]
    update_values: dict
    n: int
    n_eff: float
    rho: float
    alpha: float
    unexplained: str
    band: tuple[float, float] | None
    n_evals: int
    time_s: float
    ignored_channels: tuple[tuple[str, str], ...] = ()
    point_weights: np.ndarray = field(repr=False, default=None)
    residual_update: np.ndarray = field(repr=False, default=None)
    f_hz: np.ndarray = field(repr=False, default=None)
    explained: dict = field(repr=False, default_factory=dict)
    noise_source: str = ""
    estimator_note: str = ""
    indistinguishable: Any = None
    stopped_by_budget: bool = False
    family_alpha: float = ALPHA
    dispersion: float = math.nan
    p_null: float = math.nan
    channel_verdict: str = ""
    input_held: bool = False
    verdict: str = ""
    closest: Any = None
    completeness: Any = None
    left: tuple = ()
    dispersion_left: float = math.nan
    model_error_removed: float = 0.0
    best_fit_values: dict = field(default_factory=dict)
    chain: tuple = ()
    effects: tuple = ()
    chain_exhausted: bool = False
    lead: Any = None
    chain_limit: int = 1
    screening: dict = field(default_factory=dict)

    @property
    def lead_result(self) -> CandidateResult | None:
        """The CandidateResult of :attr:`lead` (or None)."""
        if self.lead is None:
            return None
        return next((r for r in self.ranking if r.effect is self.lead), None)

    @property
    def closest_result(self) -> CandidateResult | None:
        """The CandidateResult of :attr:`closest` (or None)."""
        if self.closest is None:
            return None
        return next((r for r in self.ranking if r.effect is self.closest), None)

    def with_effects(self, model: Any) -> Any:
        """``model`` with the answer's effects (the chain's, in order) at their fitted sizes.

        Raises
        ------
        ModelError
            When the verdict is not ``"answer"``: an incomplete explanation is not applied silently
            (apply ``closest`` by hand with ``model.with_effect(diag.closest)`` to try it).
        """
        from ...errors import ModelError

        effects = self.effects or ((self.best,) if self.best is not None else ())
        if not effects:
            raise ModelError(
                f"the diagnosis's verdict is {self.verdict!r}: no effect is the answer to apply; "
                "model.with_effect(diag.closest) applies the closest one to try it."
            )
        for e in effects:
            model = model.with_effect(e)
        return model

    @property
    def weights(self) -> np.ndarray:
        """Deprecated name of :attr:`point_weights` (weights on the squared error)."""
        return self.point_weights

    @property
    def model_error(self) -> bool:
        """Whether the parameters-only fit is beyond the noise: ``p_null < family_alpha`` and a
        dispersion above :data:`MODEL_ERROR_DISPERSION`."""
        return bool(np.isfinite(self.p_null) and self.p_null < self.family_alpha
                    and self.dispersion > MODEL_ERROR_DISPERSION)

    @property
    def best_result(self) -> CandidateResult | None:
        """The CandidateResult of :attr:`best` (or None)."""
        if self.best is None:
            return None
        return next((r for r in self.ranking if r.effect is self.best), None)

    def table(self, n: int = 12) -> Table:
        """The top ``n`` candidates: rank, effect, value, fraction, cost reduction, gain, p, significance."""
        rows = []
        for k, r in enumerate(self.ranking[:n], start=1):
            rows.append(
                (
                    k,
                    r.name,
                    r.effect.describe_value(),
                    100 * r.fraction,
                    100 * r.reduction if r.fitted else None,
                    100 * r.gain if r.fitted else None,
                    format_p(r.p_value) if r.fitted and np.isfinite(r.p_value) else None,
                    format_p(r.p_vs_best) if r.fitted and np.isfinite(r.p_vs_best) else None,
                    r.significant,
                )
            )
        return Table(
            (
                "rank",
                "effect",
                "size",
                "first-order share (%)",
                "cost reduction (%)",
                "explains (%)",
                "p-value",
                "best better (p)",
                "significant",
            ),
            rows,
            title=f"Diagnosis: {len(self.ranking)} candidates, update cost {self.cost_update:.4g} "
            f"(nominal {self.cost_nominal:.4g}), n_eff = {self.n_eff:.0f}",
            digits=3,
        )

    def summary(self) -> str:
        """A few plain sentences: the proposal (or why none), and where the residual sits."""
        lines = [
            f"Nominal cost J = {self.cost_nominal:.4g}; updating {len(self.update_params)} parameter(s) "
            f"alone brings it to {self.cost_update:.4g} "
            f"({100 * (1 - self.cost_update / self.cost_nominal):.0f}% lower)."
            if self.cost_nominal > 0
            else "The model matches the data exactly."
        ]
        if self.estimator_note:
            lines.append(self.estimator_note[:1].upper() + self.estimator_note[1:] + ".")
        if self.stopped_by_budget:
            lines.append("The time budget stopped some fits before convergence: the ranking may differ "
                         "from an unhurried run (time_budget_s=None).")
        if self.noise_source:
            lines.append(f"Noise model: {self.noise_source}.")
        else:
            lines.append(NO_NOISE_SENTENCE[:1].upper() + NO_NOISE_SENTENCE[1:] + ".")
        if self.model_error:
            lines.append(
                f"The parameters-only fit leaves {self.dispersion:.3g} x the noise variance "
                f"({format_p(self.p_null)}): model error; each candidate is tested against the misfit "
                "it leaves where that exceeds the noise."
            )
        best = self.best_result
        if self.verdict == "answer" and len(self.effects) > 1:
            lines.append(f"Proposed: {len(self.effects)} effects at once, each found on the model updated "
                         "with those before it:")
            lines.extend("  " + step.describe(k) for k, step in enumerate(self.chain, start=1))
            lines.append(self._left_sentence("them"))
        elif best is not None:
            lines.append("Proposed: " + best.sentence)
            if self.completeness is not None:
                lines.append(self._left_sentence("it"))
            others = [r for r in self.ranking if r.fitted and r is not best][:2]
            for r in others:
                lines.append("Next: " + r.sentence)
        elif self.verdict == "incomplete":
            lines.extend(self._incomplete_lines())
        else:
            test = (
                f"Holm-adjusted tests at {self.family_alpha:.2g} family-wise"
                if self.noise_source
                else "no noise estimate"
            )
            lines.append(
                "No candidate effect is significant: none explains enough of what updating leaves "
                f"({test}, and at least {100 * MIN_GAIN:.0f}% of the residual)."
            )
            if self.ranking:
                lines.append("Closest: " + self.ranking[0].sentence)
            lines.append("The unexplained residual sits in " + self.unexplained + ".")
            if self.channel_verdict:
                lines.append(self.channel_verdict)
            elif self.left:
                lines.append("It is not one channel's (a cable or a calibration would be there at every "
                             "frequency): it sits at " + "; ".join(b.describe() for b in self.left) + ".")
            if self.lead is not None and self.chain_limit <= 1:
                lines.append("Two effects may act at once, one masking the other: diagnose(..., chain=True) "
                             "tries the closest one and proposes the next on the model with it.")
            elif self.chain_exhausted and self.lead is not None:
                lines.append("Chaining the closest candidates did not bring the model within the noise: the "
                             "missing effect is probably not among the candidates.")
        if self.indistinguishable is not None:
            lines.append(self.indistinguishable.sentence())
        if self.ignored_channels:
            chans = ", ".join(f"{o} <- {i}" for o, i in self.ignored_channels[:6])
            more = "" if len(self.ignored_channels) <= 6 else f" and {len(self.ignored_channels) - 6} more"
            lines.append(
                f"Ignored {len(self.ignored_channels)} channel(s) the model leaves decoupled "
                f"(negligible against their row and column): {chans}{more}; pass "
                "the same min_channel_db to rc.update for the same cost."
            )
        return "\n".join(lines)

    def chain_table(self) -> Table:
        """The chain of effects, one row per step: the effect and its size, the share of what the
        model before it leaves that it explains, its p-value and the misfit over the noise before
        and after it, and the verdict of the whole diagnosis in the title."""
        rows = [
            (k, step.name, step.effect.describe_value(), 100 * step.gain,
             format_p(step.p_value) if np.isfinite(step.p_value) else None,
             step.dispersion_before, step.dispersion_after)
            for k, step in enumerate(self.chain, start=1)
        ]
        return Table(
            ("step", "effect", "size", "explains (%)", "p-value", "misfit before (x noise)",
             "misfit after (x noise)"),
            rows, title=f"Verdict: {self.verdict or 'none'}", digits=3,
        )

    def _left_sentence(self, pronoun: str) -> str:
        if not np.isfinite(self.dispersion_left):
            return ""
        if self.dispersion_left <= MODEL_ERROR_DISPERSION:
            return (f"With {pronoun} the model is within the noise "
                    f"({self.dispersion_left:.3g} x its variance).")
        return (f"With {pronoun} the model leaves {self.dispersion_left:.3g} x the noise variance, "
                f"{100 * self.model_error_removed:.0f}% of the model error removed.")

    def _incomplete_lines(self) -> list[str]:
        r = self.closest_result
        lines = []
        if len(self.chain) > 1:
            lines.append(f"Closest, incomplete: a chain of {len(self.chain)} significant effects, each on "
                         "the model updated with those before it:")
            lines.extend("  " + step.describe(k) for k, step in enumerate(self.chain, start=1))
            pronoun = "them"
        else:
            lines.append("Closest, incomplete: " + (r.sentence if r is not None else self.closest.name))
            pronoun = "it"
        lines.append(
            f"With {pronoun} the model still leaves {self.dispersion_left:.3g} x the noise variance "
            f"({100 * self.model_error_removed:.0f}% of the model error removed; the answer must reach the "
            f"noise or remove {100 * ANSWER_SHARE:.0f}%), so it is not proposed as the answer."
        )
        if self.left:
            lines.append("The rest sits at " + "; ".join(b.describe() for b in self.left) + ".")
        if self.chain_exhausted:
            lines.append(
                "No further candidate is significant on the model with " + pronoun + ": the missing effect "
                f"is probably not among the {len(self.ranking)} candidates (look at the structure named "
                "above: a joint, an attached mass or resonator, a boundary)."
            )
        elif self.chain_limit <= 1:
            lines.append("Another effect may act with it: diagnose(..., chain=True) proposes the next one on "
                         "the model with it.")
        return lines

    def __str__(self) -> str:
        return self.summary() + "\n\n" + str(self.table())

    def __repr__(self) -> str:
        best = "none significant" if self.best is None else repr(self.best.name)
        return (
            f"Diagnosis({len(self.ranking)} candidates, best {best}, cost {self.cost_nominal:.4g} nominal, "
            f"{self.cost_update:.4g} after updating {len(self.update_params)} parameter(s); "
            "str() or .summary() / .table() for details)"
        )

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def plot(self, n: int = 12):
        """Bar chart of the candidates and the residual left by updating over frequency.

        Returns
        -------
        matplotlib.figure.Figure
        """
        fig = new_figure(10.0, 6.5)
        ax1, ax2 = fig.subplots(2, 1)
        top = self.ranking[:n][::-1]
        vals = [100 * (r.gain if r.fitted else r.fraction) for r in top]
        colors = ["tab:green" if r.significant else ("tab:blue" if r.fitted else "tab:gray") for r in top]
        ax1.barh(range(len(top)), vals, color=colors)
        ax1.set_yticks(range(len(top)), [r.name for r in top], fontsize=8)
        ax1.set_xlabel("share of the residual left by updating that the effect explains (%)")
        ax1.axvline(100 * MIN_GAIN, color="k", lw=0.8, ls=":")
        ax1.set_title("Diagnosis: candidate effects")
        _status_legend(ax1, colors)
        if self.residual_update is not None:
            e = self.residual_update
            ax2.semilogy(self.f_hz, np.sum(np.abs(e) ** 2, axis=(1, 2)), label="residual after updating")
            for label, de in self.explained.items():
                ax2.semilogy(self.f_hz, np.sum(np.abs(de) ** 2, axis=(1, 2)), label=f"explained by {label}")
            log_frequency_axis(ax2, self.f_hz)
            ax2.set_ylabel("|log error|^2 summed over channels (-)")
            ax2.legend(fontsize=8)
        return fig


def _status_legend(ax: Any, colors: list[str]) -> None:
    """A legend naming only the bar colours drawn (significant / fitted / screening only)."""
    from matplotlib.patches import Patch

    names = {"tab:green": "significant", "tab:blue": "fitted, not significant", "tab:gray": "screening only"}
    handles = [Patch(color=c, label=label) for c, label in names.items() if c in colors]
    ax.legend(handles=handles, fontsize=7, loc="lower right")


#: Smallest dispersion (residual over its noise expectation) of the parameters-only fit called model
#: error, besides a significant chi-square: a coherence-based noise model's sigma is estimated from
#: the coherence (biased low where it is low), so an exact truth's dispersion exceeds 1 a little,
#: which a chi-square over thousands of points calls significant.
MODEL_ERROR_DISPERSION = 1.5
#: Share of the model-error part of the misfit (the parameters-only fit's excess dispersion over
#: the noise) a significant effect must remove to be *the answer* when the model with it is still
#: beyond the noise (:mod:`.answer`).
ANSWER_SHARE = 0.9

