"""Which physical effect is the model missing? ``rc.diagnose`` (MACE test 1, generalised).

MACE (Glaese & Miller) keep an update parameter when its sensitivity is aligned with the
initial cost vector (test 1, ``|j0^T dJ|``, eq. 8). ``diagnose`` asks the same question of
*effects the model does not have yet*, after removing what the model's own update
parameters can already explain:

1. **Null fit.** A short bounded Levenberg-Marquardt fit of the update parameters alone
   (default: the model's free parameters) gives ``j_u`` and the sensitivity matrix
   ``dJ_u`` at the fitted point.
2. **Secant screening.** Each candidate effect is added at its neutral value (where it
   vanishes) and its sensitivity is the *secant* from neutral to its typical size ``s``
   (``Effect.scale``): ``d = j(s) - j(0)`` -- a derivative at "absent" can be zero.
   Projecting out ``span(dJ_u)`` (``P = I - Q Q^T``, ``Q`` an orthonormal basis), the
   fraction of the remaining residual the candidate explains is ``cos^2`` of the principal
   angle between ``P j_u`` and ``P d`` (with the fitted coefficient clipped to the
   parameter bounds, so an added mass cannot be negative). A large effect (a spring that
   moves a mode by a factor of 4 changes its ``w^2`` 750 times more than the step) is far
   outside the secant's linear range, so a candidate whose linear estimate lies beyond its
   secant step (``|c| >`` :data:`PROBE_MIN_COEF`: the data ask for more of it than the step
   measured) is also evaluated at 10, 100 and 1000 steps (walking outwards while the share
   explained grows, with the update parameters re-fitted linearly) and scored by the best
   size (:func:`_probe_sizes`). One whose estimate lies inside the step is not walked out:
   the data ask for less of it than the secant already covers (on the Caltech truss 265 of
   285 candidates, whose probes never raised a share; a large effect's secant points far out).
3. **Local fit.** The best few candidates are fitted together with the update parameters
   (bounded LM, few iterations) from the screening estimate; the cost reduction against
   the nominal model and the *gain* ``1 - J_c / J_u`` against the null fit are reported.
   Contenders -- local fits within :data:`CONTENDER_RATIO` of the best cost -- are then
   polished by a full LM fit with refreshed sensitivities (:func:`_polish`): the local fits
   freeze the update parameters' sensitivities at the null fit and can stop short (on the
   Caltech truss below 30 Hz the true taut wires stopped at half their tension, behind
   stiffer diagonals).
4. **Significance.** Under "the effect is absent" the cost drop of a candidate's fit is the
   residual projected on one direction, ``Delta J ~ v chi2_1`` (a likelihood-ratio test with one
   degree of freedom), ``v`` the variance along the fitted change: the data's noise model's
   (:mod:`robustctl.measure.noise`, the bins' correlation included) or, when larger, that of the misfit
   the candidate leaves (model error: the parameters-only fit beyond the noise; then an
   ``F(1, nu)`` reference, :func:`_candidate_test`). The p-values are adjusted over the ``m``
   screened candidates by Holm's step-down (the best one's by Bonferroni's ``m p``), so the
   best candidate's p-value is uniform or conservative when nothing is missing and the
   family-wise false-proposal rate is at most ``alpha``; a practical threshold (``min_gain``)
   asks an effect to explain a real share of what updating leaves, and a fit ending at a bound
   of its parameter is never proposed ("the model form is likely wrong"). Each rival is
   compared with the best by Vuong's test against the misfit it leaves (:func:`_rival_test`).
   Without a noise model no significance claims are made (p-values NaN; the best candidate is
   proposed on its share alone, and the result says so). When nothing is proposed and the
   misfit is beyond the noise, the output row or input column holding most of it is named
   (:func:`_channel_verdict`): a cable, sign or location to check.

5. **Indistinguishable candidates.** Fitted candidates whose best-fit costs differ by no more
   than the noise explains (Vuong's 1989 test for non-nested models at ``alpha``) and whose
   fitted changes of the whitened residual are nearly collinear are one explanation as far as
   this band goes; the result names the group and where the fitted models' responses differ
   beyond the noise outside the band (:class:`Indistinguishable`): widen the band or measure there.

``n_eff`` (reported): the AR(1) effective number of independent residual entries,
``n (1 - rho) / (1 + rho)`` with ``rho`` the lag-one autocorrelation along frequency of the
null-fit residual (Bartlett 1946); a systematic, unexplained model error gives ``rho`` near 1.
"""

from __future__ import annotations

import contextlib
import copy
import math
import time
import warnings
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...budget import BudgetWarning, Deadline
from ...checks import UNSET, finite_number, integer, renamed_keyword
from ...errors import FitError, ModelError, RobustctlError
from ...executors import check_executor, parallel_map_shared, process_pool, resolve_workers
from ...frd import FrequencyData, as_frequency_data
from ...measure.estimator import estimator_settings
from ...measure.noise import NO_NOISE_SENTENCE, format_p, noise_model
from ...table import Table, result_html
from ...threads import limit_blas
from ..optimize import _bounds, levenberg_marquardt, marquardt_step
from ..residual import Residual, check_determined, physical_model, sensitivities

__all__ = ["diagnose", "Diagnosis", "CandidateResult", "Indistinguishable", "effective_points"]

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
#: ``workers="auto"`` starts worker processes only for at least this many candidates ...
PARALLEL_MIN_CANDIDATES = 8
#: ... and when their screening promises at least this much work (s): :data:`SCREEN_EVALS`
#: evaluations per candidate at the cost of the nominal one (below it, starting processes
#: costs more than it saves).
PARALLEL_MIN_WORK_S = 2.0
#: Model evaluations a candidate's screening costs on average (the secant; the size probes of some).
SCREEN_EVALS = 1.5
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
        if best is not None:
            lines.append("Proposed: " + best.sentence)
            others = [r for r in self.ranking if r.fitted and r is not best][:2]
            for r in others:
                lines.append("Next: " + r.sentence)
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
        from ...plots import log_frequency_axis, new_figure

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


# ============================================================================ statistics
def effective_points(e: np.ndarray) -> tuple[float, float]:
    """Effective number of independent real residual entries, ``n (1 - rho) / (1 + rho)``.

    Parameters
    ----------
    e : ndarray, complex, shape (n_freq, n_out, n_in)
        Complex log residual.

    Returns
    -------
    n_eff : float
    rho : float
        Pooled lag-one autocorrelation along frequency of the real and imaginary parts
        (each channel's mean removed), clipped to [0, 0.995].
    """
    parts = np.concatenate([e.real.reshape(e.shape[0], -1), e.imag.reshape(e.shape[0], -1)], axis=1)
    n = parts.size
    if parts.shape[0] < 3:
        return float(n), 0.0
    x = parts - parts.mean(axis=0)
    den = float(np.sum(x * x))
    rho = float(np.sum(x[1:] * x[:-1]) / den) if den > 0 else 0.0
    rho = min(max(rho, 0.0), 0.995)
    return n * (1.0 - rho) / (1.0 + rho), rho


# ============================================================================ helpers
def _residual_for(base: Residual, model: Any) -> Residual:
    """The same data, band and weights with another model (channels are unchanged)."""
    res = copy.copy(base)
    res.model = model
    return res


def _orthonormal(J: np.ndarray) -> np.ndarray:
    if J.size == 0 or J.shape[1] == 0:
        return np.zeros((J.shape[0], 0))
    norms = np.linalg.norm(J, axis=0)
    Jn = J[:, norms > 0] / norms[norms > 0]
    if Jn.shape[1] == 0:
        return np.zeros((J.shape[0], 0))
    U, s, _ = np.linalg.svd(Jn, full_matrices=False)
    return U[:, s > 1e-8 * s[0]]


def _project(Q: np.ndarray, x: np.ndarray) -> np.ndarray:
    return x - Q @ (Q.T @ x) if Q.shape[1] else x


def _screen_one(
    res_u: Residual, model_u: Any, j_u: np.ndarray, Q: np.ndarray, r_perp: np.ndarray, effect: Any
) -> dict[str, Any]:
    """Secant of one candidate from neutral to its typical size, projected (step 2)."""
    neutral = effect.with_values(**effect.neutral_values)
    m_c = neutral.apply(model_u)
    res_c = _residual_for(res_u, m_c)
    if _is_switch(effect) and effect.kind != "gravity":
        return _screen_switch(res_c, m_c, j_u, Q, r_perp, effect)
    pname = effect.param_names[0]
    lo, hi = effect.parameters[0].bounds
    step = effect.typical_size
    v0 = effect.parameters[0].neutral
    trial = v0 + step if v0 + step <= hi else v0 - step
    try:
        sens = sensitivities(res_c, [pname], at={pname: trial}, origin={pname: v0}, j0=j_u)
    except RobustctlError as exc:  # e.g. the gravity preload does not converge with the effect
        return dict(
            effect=effect,
            model=m_c,
            fraction=0.0,
            angle=90.0,
            value=v0,
            d=np.zeros_like(j_u),
            evals=1,
            error=str(exc),
        )
    d = sens.dJ[:, 0]
    d_perp = _project(Q, d)
    dd, rr = float(d_perp @ d_perp), float(r_perp @ r_perp)
    if dd <= 0 or rr <= 0:
        return dict(effect=effect, model=m_c, fraction=0.0, angle=90.0, value=v0, d=d, evals=sens.n_evals)
    coef = -float(d_perp @ r_perp) / dd  # in units of the secant (trial - v0)
    cos2 = float(d_perp @ r_perp) ** 2 / (dd * rr)
    value = v0 + coef * (trial - v0)
    clipped = min(max(value, lo), hi)
    if effect.kind == "gravity":
        clipped = hi if coef > 0.5 else lo
    c_clip = (clipped - v0) / (trial - v0)
    left = r_perp + d_perp * c_clip
    fraction = max(0.0, 1.0 - float(left @ left) / rr)
    angle = math.degrees(math.acos(min(1.0, math.sqrt(cos2))))
    evals = sens.n_evals
    if effect.kind != "gravity" and abs(coef) > PROBE_MIN_COEF:  # a switch has no sizes to probe
        probed, value_p, n_p = _probe_sizes(res_c, pname, (v0, lo, hi), trial - v0, coef, Q, rr, fraction)
        evals += n_p
        if probed > fraction:
            fraction, clipped = probed, value_p
    return dict(effect=effect, model=m_c, fraction=fraction, angle=angle, value=clipped, d=d, evals=evals)


def _screen_switch(
    res_c: Residual, m_c: Any, j_u: np.ndarray, Q: np.ndarray, r_perp: np.ndarray, effect: Any
) -> dict[str, Any]:
    """Screen a switched effect (a test-setup error: swapped cables, a sign flip, a units slip, a
    sensor on another node) at each of its states (``effect.states``): the share of the residual
    left by updating that the state removes once the update parameters are re-fitted linearly,
    ``1 - |P j(state)|^2 / |P j_u|^2``; the best state is kept. ``d`` is its change ``j - j_u``."""
    pname = effect.param_names[0]
    v0 = float(effect.parameters[0].neutral)
    rr = float(r_perp @ r_perp)
    best = dict(effect=effect, model=m_c, fraction=0.0, angle=90.0, value=v0, d=np.zeros_like(j_u), evals=0)
    for v in _likely_states(res_c, j_u, effect):
        best["evals"] += 1
        try:
            j = res_c.vector(**{pname: float(v)})
        except RobustctlError:
            continue
        if not np.all(np.isfinite(j)) or rr <= 0:
            continue
        share = 1.0 - float(np.sum(_project(Q, j) ** 2)) / rr
        if share > best["fraction"]:
            d = j - j_u
            dp = _project(Q, d)
            nd = float(np.linalg.norm(dp))
            cos = abs(float(dp @ r_perp)) / (nd * math.sqrt(rr)) if nd > 0 else 0.0
            angle = math.degrees(math.acos(min(1.0, cos)))
            best.update(fraction=share, value=float(v), d=d, angle=angle)
    return best


#: Units-slip factors evaluated per channel, nearest the channel's offset first (the null fit's
#: parameters may absorb part of a slip, so the nearest factor to what is left can be the wrong one).
UNITS_NEAREST = 2


def _likely_states(res: Residual, j_u: np.ndarray, effect: Any) -> tuple[float, ...]:
    """The states of a switched effect worth evaluating: for a units slip the :data:`UNITS_NEAREST`
    factors nearest the channel's mean log-magnitude offset (``exp`` of the weighted mean of
    ``Re ln(G_data / G)`` over its row or column: a slip ``f`` makes it ``ln f``, less what the
    null fit's parameters absorbed); every state otherwise."""
    states = tuple(effect.states)
    if effect.kind not in ("sensor_units", "actuator_units") or len(states) < 2:
        return states
    names = res.data.outputs if effect.side == "output" else res.data.inputs
    if effect.location not in names:
        return states
    k = names.index(effect.location)
    w2 = res.point_weights
    e_w = res.unstack(j_u)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(res.weights > 0, e_w / np.where(res.weights > 0, res.weights, 1.0), 0.0)
    sel = (slice(None), k, slice(None)) if effect.side == "output" else (slice(None), slice(None), k)
    total = float(np.sum(w2[sel]))
    if total <= 0:
        return states
    offset = float(np.sum(w2[sel] * e[sel].real)) / total
    return tuple(sorted(states, key=lambda f: abs(math.log(f) - offset))[:UNITS_NEAREST])


#: Multiples of the calibrated step (a 2 % change of the most affected modal ``w^2``) at
#: which each candidate is also evaluated in screening: an effect that moves a mode by a
#: factor of 4 changes its ``w^2`` by 1500 %, far outside the secant's linear range.
SCREEN_MULTIPLES = (10.0, 100.0, 1000.0)
#: A candidate is probed at :data:`SCREEN_MULTIPLES` only when its secant's linear estimate
#: ``|c|`` (in units of the secant step) exceeds this: the data then ask for more of the effect
#: than the step measured, the sign of a large effect (the chain's large-error cases: 2 to 55).
PROBE_MIN_COEF = 1.0


def _probe_sizes(
    res_c: Residual,
    pname: str,
    span: tuple,
    step: float,
    coef: float,
    Q: np.ndarray,
    rr: float,
    linear_share: float = 0.0,
) -> tuple[float, float, int]:
    """Screen a candidate at sizes spanning decades (large effects are far from linear).

    The candidate is evaluated at ``v0 + m * step`` for ``m`` in :data:`SCREEN_MULTIPLES`
    (in the direction of the secant's linear estimate, within the bounds), each with the
    update parameters re-fitted linearly: the share explained is ``1 - |P j(v)|^2 / |P j_u|^2``
    (``P`` projects out the update parameters' sensitivities, as in step 2). The probe walks
    outwards while the share grows, starting from ``linear_share`` (the secant's prediction):
    an effect the secant already describes costs one evaluation more, a large one a few.
    Returns ``(share, value, evaluations)``; the share is 0 when nothing was evaluated.
    """
    v0, lo, hi = span
    sign = 1.0 if coef >= 0 else -1.0
    best, best_v, n, last = 0.0, v0, 0, float(linear_share)
    for m in SCREEN_MULTIPLES:
        v = float(np.clip(v0 + sign * m * step, lo, hi))
        if v == v0 or (n and v == best_v):
            break
        n += 1
        try:
            j = res_c.vector(**{pname: v})
        except RobustctlError:  # e.g. a mass so large the preload fails: stop walking out
            break
        if not np.all(np.isfinite(j)):
            break
        share = 1.0 - float(np.sum(_project(Q, j) ** 2)) / rr
        if share > best:
            best, best_v = share, v
        if share < last:
            break
        last = share
    return max(best, 0.0), best_v, n


@dataclass
class _Null:
    """The null fit: update parameters, their values, bounds and frozen Jacobian."""

    names: tuple[str, ...]
    x: dict[str, float]
    x0: dict[str, float]
    lo: np.ndarray
    hi: np.ndarray
    jac: np.ndarray  # d j / d alpha per unit parameter, (n, p)
    j: np.ndarray
    cost: float
    cut: bool = False  # the time budget stopped the fit

    @property
    def Q(self) -> np.ndarray:  # noqa: N802 - the orthonormal basis of span(jac)
        if not hasattr(self, "_Q"):
            self._Q = _orthonormal(self.jac)
        return self._Q


def _fit_one(
    res_u: Residual, null: _Null, screen: dict[str, Any], max_iter: int, budget: Deadline
) -> dict[str, Any]:
    """Short bounded local fit of one candidate with the update parameters (step 3).

    Gauss-Newton/Marquardt on ``[alpha_update, v]`` with the update parameters' Jacobian
    frozen at the null fit and the candidate's column refreshed each iteration by a secant
    (two evaluations per iteration instead of ``p + 1``). A point where the model cannot
    be evaluated (e.g. the gravity preload does not converge) counts as a failed step.
    """
    effect = screen["effect"]
    pname, par = effect.param_names[0], effect.parameters[0]
    discrete = _is_switch(effect)
    res_c = _residual_for(res_u, screen["model"])
    names = null.names
    lo_v, hi_v = (screen["value"], screen["value"]) if discrete else par.bounds
    counter = [0]

    def evaluate(uu: np.ndarray, vv: float) -> np.ndarray | None:
        counter[0] += 1
        try:
            r = res_c.vector(**dict(zip(names, (float(x) for x in uu))), **{pname: vv})
        except RobustctlError:
            return None
        return r if np.all(np.isfinite(r)) else None

    starts = [np.array([null.x[n] for n in names], dtype=float)]
    if null.x0 and any(null.x0[n] != null.x[n] for n in names):
        starts.append(np.array([null.x0[n] for n in names], dtype=float))
    start = _start_value(effect, screen["value"], discrete, evaluate, null.Q, starts)
    if start is None:  # no trial size can be evaluated: nothing gained
        return dict(x=dict(null.x), cost=null.cost, vector=null.j, evals=counter[0], value=float(par.neutral))
    u, v, r = start
    cost, lam = float(r @ r), 1e-2
    if discrete and names:
        return _fit_switched(res_c.model.with_values(**{pname: v}), res_u, names, u, v, r, max_iter,
                             budget, counter[0])
    cut = False
    for _ in range(int(max_iter)):
        if budget.expired():
            cut = True
            break
        cols = [null.jac]
        if not discrete:
            h = max(0.05 * abs(v - float(par.neutral)), 0.1 * effect.typical_size)
            h = h if v + h <= hi_v else -h
            r_h = evaluate(u, v + h)
            if r_h is None:
                break
            cols.append(((r_h - r) / h)[:, None])
        A = np.hstack(cols)
        if A.shape[1] == 0:
            break
        new = _marquardt_try(
            A,
            r,
            cost,
            lam,
            lambda st, u=u, v=v: (
                np.clip(u + st[: len(names)], null.lo, null.hi),
                v if discrete else float(np.clip(v + st[-1], lo_v, hi_v)),
            ),
            evaluate,
        )
        if new is None:
            break
        (u_new, v_new), r, c_new, lam = new
        rel, u, v, cost = (cost - c_new) / cost, u_new, v_new, c_new
        if rel < 1e-3:
            break
    return dict(x=dict(zip(names, (float(x) for x in u))), cost=cost, vector=r, evals=counter[0], value=v,
                cut=cut)


def _fit_switched(model_on: Any, res_u: Residual, names: tuple[str, ...], u: np.ndarray, v: float,
                  r: np.ndarray, max_iter: int, budget: Deadline, evals: int) -> dict[str, Any]:
    """The local fit of a discrete candidate (gravity switched on or off): a full LM fit of the
    update parameters with the switch set (their sensitivities refreshed each iteration).

    The null fit's Jacobian, which the secant fits of :func:`_fit_one` keep, belongs to the
    other state: gravity changes the pendulum modes by factors, so a fit on the frozen Jacobian
    stops at once and the true switch ranked below springs that mimic it (a hanging chain:
    the switch explained 34 % of the residual, refitted 99.9 %)."""
    cost = float(r @ r)
    x = dict(zip(names, (float(a) for a in u)))
    out = dict(x=x, cost=cost, vector=r, evals=evals, value=v, cut=False)
    if budget.expired():
        return dict(out, cut=True)
    try:
        lm = levenberg_marquardt(_residual_for(res_u, model_on), names, x0=x, max_iter=max_iter,
                                 time_budget_s=budget)
    except RobustctlError:
        return out
    out["evals"] += lm.n_evals
    if not lm.cost < cost:
        return out
    return dict(out, x={n: float(lm.x[n]) for n in names}, cost=float(lm.cost), vector=lm.vector,
                cut=lm.stopped_by_budget)


def _fit_task(shared: tuple, screen: dict[str, Any]) -> dict[str, Any]:
    """One local fit (:func:`parallel_map_shared` task): ``shared = (res_u, null, max_iter, budget)``."""
    res_u, null, max_iter, budget = shared
    return _fit_one(res_u, null, screen, max_iter, budget)


#: A local fit whose cost is within this factor of the best one's is a contender: it is polished
#: by a full Levenberg-Marquardt fit before the ranking (:func:`_polish`).
CONTENDER_RATIO = 2.0
#: Iteration cap of the polishing fits (each refreshes all sensitivities; they stop earlier once
#: the relative cost change is below 1e-4). On the Caltech truss below 30 Hz two reached the
#: converged costs to four digits; on a 3-D frame with 5 % sensor noise and E, floor masses off
#: by 15 % and 10 %, two left the true spring 20 % above its converged cost, behind a mimicking
#: spring whose lead the Vuong test then called significant (z = 7.8; converged: true first, the
#: mimic behind by z = 8.6).
POLISH_ITER = 8


def _noise_cost(res: Residual) -> float | None:
    """The cost the noise alone gives, ``E[J] = sum W sigma^2`` over both parts (None without a
    noise model)."""
    if res.noise is None:
        return None
    return float(2.0 * np.sum(res.point_weights * res.noise.sigma**2))


def _polish(
    res_u: Residual, null: _Null, screens: list[dict], top: list[int], fits: list[dict], executor: Any,
    budget: Deadline, noise_cost: float | None = None,
) -> tuple[list[dict], int]:
    """Full LM fits of the contenders (step 3b): the local fits freeze the update parameters'
    sensitivities at the null fit, which may have bent them to mimic the missing effect, so
    two candidates whose local fits end close may rank in the wrong order (on the Caltech truss
    below 30 Hz the true taut wires stopped at half their tension, behind stiffer diagonals).
    Contenders -- fits within :data:`CONTENDER_RATIO` of the best cost -- are refitted with
    refreshed sensitivities (:func:`levenberg_marquardt`, up to :data:`POLISH_ITER` iterations) from
    their local fit. A clear winner is polished alone when its local fit leaves more than
    :data:`MODEL_ERROR_DISPERSION` x the noise's cost (``noise_cost``): its test is against the
    misfit it leaves, so a fit stopped short (a large effect's local fit on the frozen sensitivities)
    would understate it. Returns the fits and the evaluations.
    """
    costs = [f["cost"] for f in fits]
    if not fits or not null.names:
        return fits, 0
    best = min(costs)
    todo = [i for i, c in enumerate(costs) if c <= CONTENDER_RATIO * best
            and not _is_switch(screens[top[i]]["effect"])]
    if len(todo) < 2:
        lead = int(np.argmin(costs))
        short = noise_cost is not None and best > MODEL_ERROR_DISPERSION * noise_cost
        if not (short and lead in todo):
            return fits, 0
        todo = [lead]

    done = parallel_map_shared(_polish_task, (res_u, null.names, budget),
                               [(screens[top[i]], fits[i]) for i in todo], executor, desc="polishing fits")
    out = list(fits)
    for i, new in zip(todo, done):
        out[i] = new
    return out, sum(f["evals"] for f in done)


def _polish_task(shared: tuple, item: tuple) -> dict:
    """One contender's full LM fit from its local fit (:func:`parallel_map_shared` task;
    ``shared = (res_u, update names, budget)``, ``item = (screen, local fit)``)."""
    res_u, names, budget = shared
    s, fit = item
    pname = s["effect"].param_names[0]
    res_c = _residual_for(res_u, s["model"])
    try:
        lm = levenberg_marquardt(res_c, names + (pname,), x0={**fit["x"], pname: fit["value"]},
                                 max_iter=POLISH_ITER, ftol=1e-4, time_budget_s=budget)
    except RobustctlError:
        return dict(fit, evals=0)
    if not lm.cost < fit["cost"]:
        return dict(fit, evals=lm.n_evals)
    x = dict(lm.x)
    return dict(x={n: x[n] for n in names}, cost=float(lm.cost), vector=lm.vector, evals=lm.n_evals,
                value=float(x[pname]), cut=lm.stopped_by_budget)


#: Multiples of an effect's typical size tried as starting values of its local fit.
_START_MULTIPLES = (1.0, 3.0, 10.0, 30.0, 100.0)


def _start_value(effect: Any, v_lin: float, discrete: bool, evaluate, Q: np.ndarray, starts: list):
    """Starting point of a local fit: update values and a candidate size.

    Structural effects are far from linear in their parameter (a mass moves lightly
    damped resonances by several half-power bandwidths), so the linear estimate of the
    screening may sit in the wrong basin; and the null fit may have bent the update
    parameters to mimic the missing effect. The trials are the screening estimate and
    multiples of the typical size, each from the null-fit and from the model's own update
    values (``starts``), scored by ``|P j|^2``: the cost left once the update parameters are
    re-fitted linearly (``P`` projects out their sensitivities). Returns ``(u, v, j)`` or None.
    """
    par = effect.parameters[0]
    trials = [float(v_lin)]
    if not discrete:
        neutral = float(par.neutral)
        sign = 1.0 if v_lin >= neutral else -1.0
        lo, hi = par.bounds
        trials += [float(np.clip(neutral + sign * m * effect.typical_size, lo, hi)) for m in _START_MULTIPLES]
    best = None
    for u in starts:
        for v in dict.fromkeys(trials):  # unique, in order
            r = evaluate(u, v)
            if r is None:
                continue
            score = float(np.sum(_project(Q, r) ** 2))
            if best is None or score < best[0]:
                best = (score, u, v, r)
    return None if best is None else best[1:]


def _marquardt_try(A, r, cost, lam, to_point, evaluate, tries: int = 4):
    """Up to ``tries`` damped steps with growing damping; the first that lowers the cost.

    Returns ``(point, r_new, cost_new, lam_next)`` or None.
    """
    for _ in range(tries):
        point = to_point(marquardt_step(A, r, lam))
        r_new = evaluate(*point)
        if r_new is not None:
            c_new = float(r_new @ r_new)
            if c_new < cost:
                return point, r_new, c_new, max(lam / 10.0, 1e-6)
        lam *= 10.0
    return None


def _equivalent(screens: list[dict[str, Any]]) -> dict[int, int]:
    """Candidates whose secant equals an earlier one's (to 1e-6): index -> earlier index.

    A delay or filter on *every* output acts exactly like one on every input (scalar factors
    commute), so such pairs are indistinguishable; the earlier (sensor-side) one is kept.
    Distances come from one Gram matrix, ``|d_i - d_k|^2 = |d_i|^2 + |d_k|^2 - 2 d_i.d_k``
    (a pair that passes is confirmed directly: the expansion cancels digits).
    """
    twins: dict[int, int] = {}
    shapes = {s["d"].shape for s in screens}
    if len(screens) < 2 or len(shapes) != 1:
        return twins
    D = np.array([s["d"] for s in screens], dtype=float)
    sq = np.einsum("ij,ij->i", D, D)
    dist2 = sq[:, None] + sq[None, :] - 2.0 * (D @ D.T)
    for k in range(1, len(screens)):
        if sq[k] == 0:
            continue
        for i in np.flatnonzero(dist2[k, :k] <= 1e-10 * sq[k]):
            if i not in twins and np.linalg.norm(D[i] - D[k]) <= 1e-6 * math.sqrt(sq[k]):
                twins[k] = int(i)
                break
    return twins


def _residual(model: Any, data: FrequencyData, band, weights, min_db, estimator="auto",
              noise="auto") -> tuple[Residual, tuple]:
    """The residual, with channels the model leaves decoupled weighted 0.

    A channel whose model response stays ``min_db`` dB below both the largest
    channel of its output row and of its input column (decoupled by symmetry, e.g. a
    torque about one axis seen by a gyro about another) gives a log error of the data's
    noise against a numerically zero model: no effect can explain it, so it would only
    blur the statistics. It is left out and listed in ``Diagnosis.ignored_channels``.
    """
    res = Residual(model, data, band=band, point_weights=weights, min_channel_db=min_db,
                   estimator=estimator, noise=noise)
    return res, tuple((o, i) for o, i, _level in res.dropped)


#: Candidates screened within this factor of the best screening share are fitted too, beyond
#: ``n_fit`` (up to :data:`TIE_MAX_FACTOR` x ``n_fit``): screening shares of near-ties say little
#: about the fits (a first-order share overrates a candidate far outside its linear range).
TIE_SHARE = 0.95
#: Cap of the fits with near-tied screening shares, as a multiple of ``n_fit``.
TIE_MAX_FACTOR = 2


def _to_fit(screens: list[dict], order: list[int], n_fit: int) -> list[int]:
    """The candidates given a local fit: the ``n_fit`` best screened, and those tied with the best
    screening share within :data:`TIE_SHARE` (at most ``TIE_MAX_FACTOR * n_fit`` in all)."""
    top = [k for k in order[:n_fit] if screens[k]["fraction"] > 0]
    if not top:
        return top
    level = TIE_SHARE * screens[order[0]]["fraction"]
    more = [k for k in order[n_fit:TIE_MAX_FACTOR * n_fit] if screens[k]["fraction"] >= level]
    return top + more


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


def _screen_all(
    res_u: Residual, model_u: Any, null: _Null, cands: list, executor, deadline: Deadline
) -> tuple:
    """Screen every candidate (step 2): the screens, indistinguishable twins, and the
    order of the others by the fraction they explain."""
    r_perp = _project(null.Q, null.j)
    shared = (res_u, model_u, null.j, null.Q, r_perp, deadline, len(cands))
    screens = parallel_map_shared(_screen_task, shared, cands, executor, desc="screening")
    for s in screens:  # each candidate's model, rebuilt here on model_u (see _screen_task)
        s["model"] = s["effect"].with_values(**s["effect"].neutral_values).apply(model_u)
    twins = _equivalent(screens)
    order = sorted(
        (k for k in range(len(screens)) if k not in twins),
        key=lambda k: (-round(screens[k]["fraction"], 9), k),
    )
    return screens, twins, order


def _screen_task(shared: tuple, effect: Any) -> dict:
    """One candidate's screening (:func:`parallel_map_shared` task; ``shared`` from
    :func:`_screen_all`)."""
    res_u, model_u, j_u, Q, r_perp, deadline, n = shared
    _check_budget(deadline, f"the screening of {n} candidates")
    out = _screen_one(res_u, model_u, j_u, Q, r_perp, effect)
    # not sent back: a model pickled alone carries its own copy of the structure's matrices
    # (1.2 GB for 6,000 candidates of a 2,000-DOF grid); _screen_all rebuilds it on model_u
    out.pop("model", None)
    return out


def _null_fit(
    res0: Residual,
    upd: tuple[str, ...],
    max_iter: int,
    executor: Executor | None,
    budget: Deadline,
    j0: np.ndarray,
) -> tuple[_Null, int]:
    """Bounded LM fit of the update parameters alone (step 1), from the nominal residual ``j0``.

    It starts where :func:`~robustctl.correlate.updating.update` would (its coarse multi-start,
    ``_coarse_start``): with parameters 20-50 % off, modes have moved by several bandwidths and
    LM from the model's values stops in a local minimum of the complex-log cost, which leaves
    the parameter error in the residual for the candidates to mimic (a wrong effect ranks first).
    """
    from ..updating import _coarse_start

    lo, hi = _bounds(res0.model, upd, None)
    if not upd:
        return _Null((), {}, {}, lo, hi, np.zeros((res0.n, 0)), j0, float(j0 @ j0)), 0
    start = sensitivities(res0, upd, j0=j0, executor=executor)
    x0, n_coarse = _coarse_start(res0, upd, start, ())
    x_model = {n: res0.model.param(n).value for n in upd}
    kw = dict(max_iter=max_iter, executor=executor, time_budget_s=budget)
    if x0:
        lm = levenberg_marquardt(res0, upd, x0={**x_model, **x0}, **kw)
    else:
        lm = levenberg_marquardt(res0, upd, start=start, **kw)
    null = _Null(upd, dict(lm.x), x_model, lo, hi, lm.jacobian, lm.vector, lm.cost)
    null.cut = lm.stopped_by_budget
    return null, start.n_evals + n_coarse + lm.n_evals


def _where(res: Residual, delta: np.ndarray, unweight: bool = True, pairs: bool = False) -> str:
    """Where a residual (change) lies: magnitude or phase, frequency band, outputs.

    ``unweight`` divides by the residual weights first (a model change in plain log units);
    otherwise the weighted residual is described (where the data say the error is).
    ``pairs`` names the channels (output <- input) holding most of it.
    """
    e = res.unstack(delta)
    if unweight and np.any(res.weights != 1):
        e = e / np.maximum(res.weights, 1e-12)
    mag, ph = float(np.sum(e.real**2)), float(np.sum(e.imag**2))
    total = mag + ph
    if total <= 0:
        return "nowhere"
    part = (
        "phase error"
        if ph > 0.7 * total
        else "magnitude error"
        if mag > 0.7 * total
        else "magnitude and phase error"
    )
    f = res.f_hz
    per_f = np.sum(np.abs(e) ** 2, axis=(1, 2))
    cum = np.cumsum(per_f) / per_f.sum()
    lo = float(f[min(np.searchsorted(cum, 0.1), f.size - 1)])
    hi = float(f[min(np.searchsorted(cum, 0.9), f.size - 1)])
    if hi >= f[-1] - 1e-9 * f[-1] or np.searchsorted(cum, 0.9) >= f.size - 2:
        band = f"above {lo:.3g} Hz"
    else:
        band = f"{lo:.3g}-{hi:.3g} Hz"
    if pairs:
        return f"{part}, {band}, {_channel_shares(res, e)}"
    per_out = np.sum(np.abs(e) ** 2, axis=(0, 2))
    share = per_out / per_out.sum()
    chans = ""
    if res.data.n_out > 1 and share.max() > 0.6:
        chans = f" on {res.data.outputs[int(np.argmax(share))]}"
    return f"{part}, {band}{chans}"


def _channel_shares(res: Residual, e: np.ndarray, n: int = 3) -> str:
    """``"mostly S1 <- A2 (41%), S3 <- A1 (22%)"``: the channels with the largest shares."""
    per = np.sum(np.abs(e) ** 2, axis=0)
    share = per / per.sum()
    order = np.argsort(share, axis=None)[::-1][:n]
    items = []
    for idx in order:
        o, i = np.unravel_index(idx, share.shape)
        if share[o, i] < 0.05:
            break
        items.append(f"{res.data.outputs[o]} <- {res.data.inputs[i]} ({100 * share[o, i]:.0f}%)")
    return "mostly " + ", ".join(items) if items else "spread over all channels"


def _phrase(effect: Any) -> str:
    """The effect with its size in words: "a 3.6 ms output delay", "0.3 kg of added mass at ..."."""
    size = effect.describe_value()
    if effect.kind == "gravity":
        return effect.name
    if effect.kind in ("sensor_units", "actuator_units"):
        return f"a units slip {size} on {effect.side} {effect.location}"
    if getattr(effect, "switch", False):
        return f"{effect.name} ({effect.description})"
    if effect.kind == "joint_spring":
        return f"a {effect.name} ({size})"
    if effect.kind in ("sensor_lowpass", "actuator_lowpass"):
        return f"a {effect.name} at {size}"
    if effect.kind == "added_mass":
        return f"{size} of {effect.name}"
    if effect.kind == "group_tension":
        return f"{_article(size)} {size} tension along {effect.location} (taut wires or cables)"
    return f"{_article(size)} {size} {effect.name}"


def _sentence(r: CandidateResult) -> str:
    head = _phrase(r.effect)
    head = head[:1].upper() + head[1:]
    if r.equivalent:
        head += f" (the data cannot tell it from: {', '.join(r.equivalent)})"
    if r.note:
        head += f" ({r.note})"
    if r.fitted:
        vs = ""
        if np.isfinite(r.p_vs_best):
            vs = f"; the best explains the data better by z = {r.z_vs_best:.3g} ({format_p(r.p_vs_best)})"
        against = "; tested against the misfit it leaves" if r.scale == "misfit" else ""
        if r.at_bound:
            verdict = (
                f"at its bound ({r.effect.describe_value()}): the model form is likely wrong, so it is "
                "not proposed"
            )
        elif not np.isfinite(r.p_value):
            verdict = NO_NOISE_SENTENCE
        elif r.significant:
            verdict = f"significant ({format_p(r.p_value)} < {r.level:.2g}{against})"
        elif r.p_value < r.level:
            verdict = (
                f"beyond the noise ({format_p(r.p_value)}{against}) but below the {100 * r.min_gain:.0f}% "
                "needed to propose it"
            )
        else:
            verdict = f"not significant ({format_p(r.p_value)} >= {r.level:.2g}{against})"
        return (
            f"{head} explains {100 * r.gain:.3g}% of the residual left by updating ({r.where}); "
            f"cost {100 * r.reduction:.3g}% below the nominal model; {verdict}{vs}."
        )
    return (
        f"{head} would explain about {100 * r.fraction:.3g}% of the residual left by updating to first "
        "order (not fitted)."
    )


def _hold_note(effect: Any, fs_hz: float | None) -> str:
    """Name a delay of about half a sample (data sampled at ``fs_hz``) as the DAC's hold;
    ``fs_hz`` is None unless the data say their input was held (:func:`_input_held`)."""
    if fs_hz is None or effect.kind not in ("output_delay", "input_delay"):
        return ""
    delay = float(next(iter(effect.values.values()), 0.0))
    half = 0.5 / fs_hz
    if not 0.7 * half <= delay <= 1.3 * half:
        return ""
    return (
        f"about half a sample at {fs_hz:g} Hz ({1e3 * half:.3g} ms): the DAC zero-order hold, not an unknown "
        "delay; add it as a known stage, rc.electronics.zero_order_hold_stage(...)"
    )


def _article(size: str) -> str:
    return "an" if size[:1] == "8" or size[:2] in ("11", "18") else "a"


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


def _check_candidates(model: Any, cands: Sequence[Any]) -> list[Any]:
    from ...physical.effects import Effect

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

    Returns
    -------
    Diagnosis

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
    model = _evaluated(physical_model(model, "diagnose"), data, band)
    if isinstance(noise, str) and noise == "auto":
        noise = noise_model(as_frequency_data(data), measurement_model=measurement_model)
    res0, ignored = _residual(model, data, band, point_weights, min_channel_db, estimator, noise)
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
    with _pool(workers, executor, candidates, model, t_eval) as ex:
        if candidates is None:
            candidates = _default_candidates(model, res0, deadline, ex)
        return _diagnose(
            t0, res0, ignored, upd, candidates, j_nominal, ex, n_fit, max_iter, update_iter, alpha, min_gain,
            deadline,
        )


def _evaluated(model: Any, data: Any, band: Any) -> Any:
    """The model as diagnose evaluates it: in reduced coordinates up to the band for a large
    structure (:func:`robustctl.physical.reduction.for_data`), else as given."""
    from ...physical.reduction import for_data

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


def _diagnose(
    t0, res0, ignored, upd, cands, j_nominal, executor, n_fit, max_iter, update_iter, alpha, min_gain,
    deadline: Deadline,
) -> Diagnosis:
    """:func:`diagnose` once the arguments are checked, the candidates made and the executor chosen."""
    model = res0.model
    evals = 1
    cost_nominal = float(j_nominal @ j_nominal)
    # 1. null fit of the update parameters
    null, n_null = _null_fit(res0, upd, update_iter, executor, deadline, j_nominal)
    evals += n_null
    x_u, j_u, cost_u = null.x, null.j, null.cost
    model_u = model.with_values(**x_u) if x_u else model
    res_u = _residual_for(res0, model_u)
    # 2. secant screening
    _check_budget(deadline, "the null fit")
    screens, twins, order = _screen_all(res_u, model_u, null, cands, executor, deadline)
    evals += sum(s["evals"] for s in screens)
    top = _to_fit(screens, order, n_fit)
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
    beyond = bool(np.isfinite(p_null) and p_null < alpha and dispersion > MODEL_ERROR_DISPERSION)
    verdict = _channel_verdict(res0, j_u) if best is None and beyond else ""
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
    )


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
        values = {**fit["x"], pname: fit["value"]}
        out[s["effect"].name] = dict(vector=fit["vector"], model=s["model"].with_values(**values))
    return out


def _best(results: list, have_noise: bool, min_gain: float) -> Any:
    """The top significant candidate; without a noise model, the top fitted one that explains at
    least ``min_gain`` of the residual (proposed without a significance claim). A candidate at its
    bound is never the answer."""
    if have_noise:
        return next((r.effect for r in results if r.significant), None)
    return next((r.effect for r in results if r.fitted and r.gain >= min_gain and not r.at_bound), None)


def _testable_rows(res: Residual) -> np.ndarray:
    """Rows of the residual vector where the noise model holds (``NoiseModel.testable``: coherence
    significantly above zero, ``sigma`` small enough for ``ln H1`` to be near Gaussian); all rows
    without a noise model. Elsewhere the log error is heavy-tailed, and a candidate that moves a
    weak cross channel (a tiny misalignment) would fit its outliers."""
    if res.noise is None:
        return np.ones(res.n, dtype=bool)
    ok = np.broadcast_to(res.noise.testable, res.data.shape).ravel()
    return np.concatenate([ok, ok])


def _row_noise(res: Residual) -> np.ndarray | None:
    """Noise variance of each row of the weighted residual vector, or None.

    The variance of a projection of the residual on a smooth direction is that of its rows times
    the Satterthwaite factor of contiguous bins, ``1 + 2 sum_m r_m`` (the noise model's
    ``chi2_factor``: output noise and leakage alike, :mod:`robustctl.measure.noise`), not the smaller
    factor of output noise alone (``dof_factor``), which underrated the variance along a fitted
    change and made p-values anti-conservative."""
    if res.noise is None:
        return None
    v = (res.point_weights * res.noise.sigma**2 * res.noise.chi2_factor).ravel()
    return np.concatenate([v, v])


#: Half-width (points along frequency) of the running mean that estimates the local variance of a
#: misfit (:func:`_local_variance`).
MISFIT_HALF_WIDTH = 8


def _local_variance(vec: np.ndarray, shape: tuple) -> np.ndarray:
    """Local variance of each row of a residual vector: the running mean over
    ``2 MISFIT_HALF_WIDTH + 1`` frequencies of its squares, real and imaginary parts pooled
    (a heteroscedasticity-consistent scale, White 1980, smoothed along frequency)."""
    from scipy.ndimage import uniform_filter1d

    half = vec.size // 2
    nf = shape[0]
    sq = vec[:half].reshape(nf, -1) ** 2 + vec[half:].reshape(nf, -1) ** 2
    loc = 0.5 * uniform_filter1d(sq, 2 * MISFIT_HALF_WIDTH + 1, axis=0, mode="nearest")
    v = loc.ravel()
    return np.concatenate([v, v])


def _misfit_variance(left: np.ndarray, res: Residual) -> tuple[np.ndarray, float]:
    """Per-row variance of the misfit ``left`` and its AR(1) inflation ``kappa = (1 + rho) / (1 - rho)``
    (``rho`` the lag-one autocorrelation along frequency, :func:`effective_points`): the variance
    of a projection of an AR(1) sequence on a smooth direction is ``kappa`` times that of its
    rows (Bartlett 1946)."""
    _, rho = effective_points(res.unstack(left))
    return _local_variance(left, res.data.shape), (1.0 + rho) / (1.0 - rho)


def _misfit_along(left: np.ndarray, delta: np.ndarray, res: Residual) -> tuple[float, float]:
    """Variance of the misfit ``left`` projected on the unit direction ``delta / |delta|``, and the
    effective number of points behind it: ``(v, nu)``.

    The misfit is modelled as a random field whose rows have the local variance ``s^2``
    (:func:`_local_variance`), correlated along frequency like an AR(1) sequence (inflation
    ``kappa``, :func:`_misfit_variance`) and across channels and real/imaginary parts by the
    correlation matrix ``R`` of the normalised misfit (a model error at one resonance shows in
    every channel that sees the mode): ``v = kappa sum_f a_f^T R a_f / |delta|^2`` with
    ``a_f = delta_f s_f`` (a sandwich estimate of the projection's variance, White 1980, with the
    separable correlation). ``nu``: the participation number of ``delta^2`` over ``kappa`` and
    the largest eigenvalue of ``R``."""
    local, kappa = _misfit_variance(left, res)
    nf = res.data.shape[0]

    def cols(x: np.ndarray) -> np.ndarray:  # (nf, 2 n_channels): real parts, then imaginary parts
        return np.concatenate([x[: x.size // 2].reshape(nf, -1), x[x.size // 2:].reshape(nf, -1)], axis=1)

    sd = np.sqrt(np.maximum(cols(local), 0.0))
    sd = np.where(sd > 1e-9 * max(float(sd.max()), 1e-300), sd, 0.0)  # round-off of the running mean
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = np.where(sd > 0, cols(left) / np.where(sd > 0, sd, 1.0), 0.0)
    g = z.T @ z / nf
    dg = np.sqrt(np.maximum(np.diag(g), 1e-300))
    R = g / np.outer(dg, dg)
    R[np.diag(g) <= 0] = 0.0
    R[:, np.diag(g) <= 0] = 0.0
    a = cols(delta) * sd
    d2 = np.asarray(delta, dtype=float) ** 2
    total = float(d2.sum())
    v = kappa * float(np.einsum("fi,ij,fj->", a, R, a)) / total
    lam = max(1.0, float(np.linalg.eigvalsh(R)[-1])) if R.size else 1.0
    nu = max(1.0, total**2 / float(d2 @ d2) / (kappa * lam))
    return v, nu


def _candidate_test(
    drop: float, delta: np.ndarray, left: np.ndarray, row_noise: np.ndarray | None, res: Residual
) -> tuple[float, float, str]:
    """Test of one fitted candidate: ``(T, p, scale)``.

    Under "the effect is absent" the cost drop ``Delta J`` of a one-parameter fit is the residual
    projected on the fitted change ``delta``: ``Delta J ~ v chi2_1`` with ``v = sum delta_i^2 v_i /
    sum delta_i^2`` the variance along it (a likelihood-ratio test with one degree of freedom;
    a parameter held at a bound makes it a conservative chi-bar-square). Two variances are at
    hand: the noise model's (``row_noise``, with the bins' correlation) and the misfit the
    candidate leaves (``left``, correlated along frequency and across channels,
    :func:`_misfit_along`). The larger is used: within the noise the two agree; with model
    error (the parameters-only fit beyond the noise) the misfit is the scale against which a
    candidate must stand out, and its estimate carries ``nu`` effective points, so ``T`` is then
    referred to ``F(1, nu)``. NaNs without a noise model.
    """
    if row_noise is None:
        return math.nan, math.nan, ""
    from scipy.stats import chi2, f

    d2 = np.asarray(delta, dtype=float) ** 2
    total = float(d2.sum())
    if total <= 0 or drop <= 0:
        return 0.0, 1.0, "noise"
    v_noise = float(d2 @ row_noise) / total
    v_mis, nu = _misfit_along(left, delta, res)
    if v_mis <= v_noise:
        t = drop / max(v_noise, 1e-300)
        return t, float(chi2.sf(t, 1)), "noise"
    t = drop / v_mis
    return t, float(f.sf(t, 1, nu)), "misfit"


def _rival_test(best_vec: np.ndarray, vec: np.ndarray, row_noise: np.ndarray | None, res: Residual):
    """Vuong's (1989) test of the best candidate against a rival: ``(z, p)``, ``p`` one-sided
    ("the best explains the data no better").

    ``m_i = r_rival,i^2 - r_best,i^2`` is the pointwise difference of the two fits' squared
    residuals (log-likelihood ratio terms); ``z = sum m_i / sqrt(kappa n s_m^2)`` with ``s_m^2`` their
    sample variance (Vuong's eq. 5.6: the variance is estimated from the data, so a rival that
    loses only on a few points is not separated by them) and ``kappa`` the AR(1) inflation of
    ``m`` along frequency. NaNs without a noise model."""
    if row_noise is None:
        return math.nan, math.nan
    from scipy.stats import norm

    m = vec**2 - best_vec**2
    n = m.size
    x = m.reshape(2, res.data.shape[0], -1).transpose(1, 0, 2).reshape(res.data.shape[0], -1)
    xc = x - x.mean(axis=0)
    den = float(np.sum(xc * xc))
    rho = min(max(float(np.sum(xc[1:] * xc[:-1]) / den), 0.0), 0.995) if den > 0 else 0.0
    kappa = (1.0 + rho) / (1.0 - rho)
    var = float(np.var(m)) * n * kappa
    z = float(m.sum()) / math.sqrt(max(var, 1e-300))
    return z, float(norm.sf(z))


def _holm(p_raw: list[float], m: int) -> list[float]:
    """Holm's (1979) step-down adjustment of ``p_raw`` within a family of ``m >= len(p_raw)``
    tests (the others count as not rejected): ``p_(k) = max_{j <= k} min(1, (m - j + 1) p_(j))``.
    Controls the family-wise error rate, so the smallest adjusted p-value (the best candidate's,
    Bonferroni's ``m p``) is conservative under "no effect is missing"."""
    out = [math.nan] * len(p_raw)
    finite = sorted((p, i) for i, p in enumerate(p_raw) if np.isfinite(p))
    run = 0.0
    for j, (p, i) in enumerate(finite):
        run = max(run, min(1.0, (m - j) * p))
        out[i] = run
    return out


def _at_bound(effect: Any, value: float) -> bool:
    """Whether a fitted value sits at a bound of the effect's parameter away from neutral (a
    +200 % gain error at the gain's upper bound: the data ask for more than the effect allows)."""
    if _is_switch(effect):
        return False
    par = effect.parameters[0]
    lo, hi = par.bounds
    for b in (lo, hi):
        if np.isfinite(b) and b != par.neutral and abs(value - b) <= 1e-6 * max(abs(b - par.neutral), 1e-300):
            return True
    return False


def _is_switch(effect: Any) -> bool:
    """An effect with discrete states (gravity on/off, swapped cables, a sign flip, a units slip,
    a sensor on another node): screened at its states, fitted with the state fixed."""
    return effect.kind == "gravity" or bool(getattr(effect, "switch", False))


def _null_test(res: Residual, j_u: np.ndarray) -> tuple[float, float]:
    """``(dispersion, p)``: is the parameters-only fit within the noise? The normalised residual
    on the testable points against a chi-square with the noise model's Satterthwaite factor
    (:func:`robustctl.measure.noise.chi2_verdict`); NaNs without a noise model."""
    if res.noise is None:
        return math.nan, math.nan
    from scipy.stats import chi2

    base = (res.point_weights * res.noise.sigma**2).ravel()
    ok = ((res.point_weights > 0) & res.noise.testable).ravel()
    ok = np.concatenate([ok, ok]) & (np.concatenate([base, base]) > 0)
    if not ok.any():
        return math.nan, math.nan
    z2 = j_u[ok] ** 2 / np.concatenate([base, base])[ok]
    c = max(float(res.noise.chi2_factor), 1.0)
    s, n = float(z2.sum()), int(ok.sum())
    return s / n, float(chi2.sf(s / c, n / c))


#: Smallest dispersion (residual over its noise expectation) of the parameters-only fit called model
#: error, besides a significant chi-square: a coherence-based noise model's sigma is estimated from
#: the coherence (biased low where it is low), so an exact truth's dispersion exceeds 1 a little,
#: which a chi-square over thousands of points calls significant.
MODEL_ERROR_DISPERSION = 1.5

#: Share of the null fit's excess misfit one output row (input column) must hold to be named.
CHANNEL_SHARE = 0.5


def _channel_verdict(res: Residual, j_u: np.ndarray) -> str:
    """Name the output row (or input column) that holds most of an unexplained misfit."""
    e = res.unstack(j_u)
    per = np.abs(e) ** 2
    if res.noise is not None:  # the excess over the noise expectation
        per = np.maximum(per - 2 * res.point_weights * res.noise.sigma**2, 0.0)
    rows, cols = per.sum(axis=(0, 2)), per.sum(axis=(0, 1))
    total = float(per.sum())
    if total <= 0:
        return ""
    d = res.data
    if d.n_out > 1 and rows.max() / total > CHANNEL_SHARE and rows.max() / total > 1.5 / d.n_out:
        k = int(np.argmax(rows))
        return (
            f"The misfit sits in output {d.outputs[k]}'s row ({100 * rows[k] / total:.0f}% of it); no "
            "candidate explains it: check its cable, sign and location (node and direction), and its "
            "calibration."
        )
    if d.n_in > 1 and cols.max() / total > CHANNEL_SHARE and cols.max() / total > 1.5 / d.n_in:
        k = int(np.argmax(cols))
        return (
            f"The misfit sits in input {d.inputs[k]}'s column ({100 * cols[k] / total:.0f}% of it); no "
            "candidate explains it: check its cable, sign and location (node and direction), and the "
            "force measurement's calibration."
        )
    return ""


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


def _score(
    res0: Residual,
    screens: list[dict],
    order: list[int],
    top: list[int],
    fits: list[dict],
    twins: dict[int, int],
    j_u: np.ndarray,
    st: dict[str, Any],
) -> tuple[list, dict]:
    """CandidateResults: fitted ones by gain (tests, sentence), then the rest by fraction.

    Each fitted candidate is tested alone (:func:`_candidate_test`); the p-values are then
    adjusted over the ``m`` screened candidates (:func:`_holm`), and each rival is compared with the
    best (:func:`_rival_test`)."""
    from dataclasses import replace

    results, explained = [], {}
    row_noise = st["row_noise"]

    def twins_of(k: int) -> tuple[str, ...]:
        return tuple(screens[t]["effect"].name for t, i in twins.items() if i == k)

    raw = []
    for k, fit in zip(top, fits):
        s = screens[k]
        effect = s["effect"].with_values(**{s["effect"].param_names[0]: fit["value"]})
        gain = _reduction(fit["cost"], st["cost_u"])
        delta = j_u - fit["vector"]
        ok = st["testable"]  # the test counts the points where ln H1 is near Gaussian (noise module)
        left = fit["vector"] * ok
        f_stat, p_val, scale = _candidate_test(float(j_u[ok] @ j_u[ok] - left @ left), delta * ok, left,
                                               row_noise, res0)
        raw.append(p_val)
        results.append(
            CandidateResult(
                effect=effect,
                fraction=s["fraction"],
                angle_deg=s["angle"],
                fitted=True,
                cost=fit["cost"],
                reduction=_reduction(fit["cost"], st["cost_nominal"]),
                gain=gain,
                f_stat=f_stat,
                p_value=p_val,
                update_values={n: v for n, v in fit["x"].items() if n in st["upd"]},
                where=_where(res0, delta),
                equivalent=twins_of(k),
                level=st["alpha"] if row_noise is not None else math.nan,
                min_gain=st["min_gain"],
                note=_hold_note(effect, st["fs_hz"]),
                p_raw=p_val,
                scale=scale,
                at_bound=_at_bound(effect, float(fit["value"])),
            )
        )
        explained[effect.name] = res0.unstack(delta)
    adjusted = _holm(raw, st["m"])
    vectors = {results[i].name: fits[i]["vector"] for i in range(len(results))}
    results = [
        replace(
            r,
            p_value=p,
            significant=bool(
                np.isfinite(p)
                and p < st["alpha"]
                and r.gain >= st["min_gain"]
                and not r.at_bound
                and st["cost_u"] - r.cost > 1e-10 * st["cost_nominal"]
            ),
        )
        for r, p in zip(results, adjusted)
    ]
    order_fit = sorted(range(len(results)),
                       key=lambda i: (results[i].at_bound, -round(results[i].gain, 9), i))
    results = [results[i] for i in order_fit]
    if results:
        lead = next((r for r in results if not r.at_bound), results[0])
        for i, r in enumerate(results):
            if r is not lead:
                z, p = _rival_test(vectors[lead.name], vectors[r.name], row_noise, res0)
                results[i] = replace(r, z_vs_best=z, p_vs_best=p)
    explained = {r.name: explained[r.name] for r in results[:2]}
    for k in order:
        if k in top:
            continue
        s = screens[k]
        effect = s["effect"].with_values(**{s["effect"].param_names[0]: s["value"]})
        cost = st["cost_u"] * (1 - s["fraction"])
        results.append(
            CandidateResult(
                effect=effect,
                fraction=s["fraction"],
                angle_deg=s["angle"],
                fitted=False,
                cost=cost,
                reduction=_reduction(cost, st["cost_nominal"]),
                gain=s["fraction"],
                equivalent=twins_of(k),
                min_gain=st["min_gain"],
                note=_hold_note(effect, st["fs_hz"]),
            )
        )
    return [_with_sentence(r) for r in results], explained


def _with_sentence(r: CandidateResult) -> CandidateResult:
    from dataclasses import replace

    return replace(r, sentence=_sentence(r))


def _reduction(cost: float, reference: float) -> float:
    return max(0.0, 1.0 - cost / reference) if reference > 0 else 0.0


# ============================================================================ indistinguishable
#: Smallest cosine between two candidates' fitted changes of the (noise-whitened) residual for
#: them to count as the same explanation: nearly collinear predicted changes.
COLLINEAR = 0.9
#: Smallest divergence (nepers, RMS over channels) that counts as "the models differ" (0.2 dB).
DIFFER_NP = 0.023
#: Fraction of a channel's peak response below which a divergence counts less (-30 dB).
MEASURABLE = 10 ** (-30 / 20)
#: At most this many stretches where fitted models differ are named.
N_DIFFER_BANDS = 3


@dataclass(frozen=True)
class Indistinguishable:
    """Candidates that explain the data equally well in the band (:func:`_indistinguishable`).

    Attributes
    ----------
    names : tuple of str
        The group, best-ranked first.
    z : tuple of float
        Vuong's statistic of each member against the first (0 for the first).
    cosine : tuple of float
        Cosine between each member's fitted change of the whitened residual and the first's.
    differ_lo_hz, differ_hi_hz, peak_hz : float
        Where the fitted models' responses diverge beyond the noise, outside the band (Hz);
        ``differ_lo_hz`` NaN when they agree within the noise everywhere on the grid examined
        (``differ_hi_hz`` is then its upper end, ``peak_hz`` where they differ most).
    peak_db : float
        The largest divergence there (RMS over channels, dB).
    stretches : tuple of (float, float)
        The frequency stretches (Hz) where they differ beyond the noise, nearest first.
    """

    names: tuple[str, ...]
    z: tuple[float, ...]
    cosine: tuple[float, ...]
    differ_lo_hz: float = math.nan
    differ_hi_hz: float = math.nan
    peak_hz: float = math.nan
    peak_db: float = math.nan
    stretches: tuple[tuple[float, float], ...] = ()

    def sentence(self) -> str:
        """``"These explain the data equally well in this band: ...; they differ at ..."``."""
        head = "These explain the data equally well in this band: " + "; ".join(self.names)
        if not np.isfinite(self.differ_lo_hz):
            return (
                f"{head}. Their fitted models differ by at most {self.peak_db:.2g} dB up to "
                f"{self.differ_hi_hz:.3g} Hz (most at {self.peak_hz:.3g} Hz), within the noise: these "
                "sensors and actuators can hardly tell them apart; measure elsewhere on the structure."
            )
        parts = [f"{a:.3g}" if f"{a:.3g}" == f"{b:.3g}" else f"{a:.3g}-{b:.3g}" for a, b in self.stretches]
        where = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]
        return (
            f"{head}. Their fitted models differ at {where} Hz (up to {self.peak_db:.2g} dB at "
            f"{self.peak_hz:.3g} Hz) -- widen the band or measure there."
        )


def _vuong(r_a: np.ndarray, r_b: np.ndarray, row_noise: np.ndarray | None) -> float:
    """Vuong's (1989) statistic for two non-nested fits: ``z = (J_a - J_b) / (2 sqrt(sum v_i d_i^2))``,
    ``d = r_a - r_b``. Both fits explaining the data equally well, ``z ~ N(0, 1)`` (the cost
    difference is the noise projected on ``d``). Without a noise model, ``v_i`` is the pooled
    residual variance of the better fit."""
    d = r_a - r_b
    v = np.full(d.shape, float(r_b @ r_b) / max(r_b.size, 1)) if row_noise is None else row_noise
    den = 2.0 * math.sqrt(max(float((d * d) @ v), 1e-300))
    return (float(r_a @ r_a) - float(r_b @ r_b)) / den


def _whitened(x: np.ndarray, row_noise: np.ndarray | None) -> np.ndarray:
    return x if row_noise is None else x / np.sqrt(np.maximum(row_noise, 1e-300))


def _cosine(a: np.ndarray, b: np.ndarray) -> float:
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    return float(a @ b) / (na * nb) if na > 0 and nb > 0 else 0.0


def _indistinguishable(
    res0: Residual, ranking: list, fitted: dict[str, dict], j_u: np.ndarray, row_noise, alpha: float
) -> Indistinguishable | None:
    """The fitted candidates the data cannot tell from the best one, or None.

    Two candidates are one explanation when (a) their best-fit costs differ by no more than the
    noise explains -- Vuong's (1989) test for non-nested models, ``|z| < z_{alpha/2}`` -- and
    (b) the changes they make to the (noise-whitened) residual are nearly collinear (cosine >=
    :data:`COLLINEAR`): they remove the same error the same way. Where they differ is then found
    from their own predictions (:func:`_where_they_differ`).
    """
    from scipy.stats import norm

    fits = [r for r in ranking if r.fitted and r.name in fitted]
    if len(fits) < 2:
        return None
    best = fits[0]
    r_best = fitted[best.name]["vector"]
    d_best = _whitened(j_u - r_best, row_noise)
    z_crit = float(norm.isf(alpha / 2))
    names, zs, coss = [best.name], [0.0], [1.0]
    for r in fits[1:]:
        vec = fitted[r.name]["vector"]
        z = _vuong(vec, r_best, row_noise)
        cos = _cosine(_whitened(j_u - vec, row_noise), d_best)
        if abs(z) < z_crit and cos >= COLLINEAR:
            names.append(r.name)
            zs.append(z)
            coss.append(cos)
    if len(names) < 2:
        return None
    where = _where_they_differ(res0, [fitted[n]["model"] for n in names])
    return Indistinguishable(tuple(names), tuple(zs), tuple(coss), *where)


def _where_they_differ(res0: Residual, models: list) -> tuple:
    """Outside the band, where the fitted models' responses diverge beyond the noise.

    The models are evaluated on a grid from a tenth of the band's lower edge up to the data's
    Nyquist frequency when the estimator settings are known (else four times the band's upper
    edge); the divergence at each frequency is the RMS over channels and over the members of
    ``|ln(G_k / G_0)|`` against the first, scaled down where ``|G_0|`` is less than
    :data:`MEASURABLE` of its channel's peak (an anti-resonance: a measurement there is noise, and
    a zero shifted by a hair gives a large log ratio). The stretches beyond the band where it
    exceeds ``max(sigma_med, DIFFER_NP)`` (``sigma_med`` the median noise of one testable point of
    the band -- a stretch of such points tells the models apart -- and :data:`DIFFER_NP`, 0.2 dB)
    are reported, the nearest first (above the band, else below it; at most
    :data:`N_DIFFER_BANDS`): ``(lo, hi, peak frequency, peak dB, stretches)`` with ``lo``/``hi``
    the span of the stretches; if nowhere, ``(NaN, grid end, peak frequency, peak dB, ())`` of the
    largest divergence outside the band.
    """
    lo, hi = float(res0.f_hz[0]), float(res0.f_hz[-1])
    fs = None if res0.estimator is None else res0.estimator.fs_hz
    top = 0.5 * fs if fs else 4.0 * hi
    grid = np.geomspace(max(lo / 10.0, 1e-3), max(top, 1.01 * hi), 600)
    div = _divergence(models, grid)
    thr = DIFFER_NP
    if res0.noise is not None:
        ok = res0.noise.testable
        if np.any(ok):
            thr = max(thr, float(np.median(res0.noise.sigma[ok])))
    outside = (grid > hi) | (grid < lo)
    over = outside & (div > thr)
    if not over.any():  # nowhere beyond the noise: say how little they differ, and where most
        k = int(np.flatnonzero(outside)[np.argmax(div[outside])]) if outside.any() else int(np.argmax(div))
        return math.nan, float(grid[-1]), float(grid[k]), float(_DB * div[k]), ()
    side = over & (grid > hi) if np.any(over & (grid > hi)) else over
    edges = np.flatnonzero(np.diff(np.concatenate([[0], side.astype(int), [0]])))
    runs = list(zip(edges[::2], edges[1::2] - 1))
    runs = runs[:N_DIFFER_BANDS] if np.any(over & (grid > hi)) else runs[::-1][:N_DIFFER_BANDS]
    stretches = tuple((float(grid[a]), float(grid[b])) for a, b in runs)
    idx = np.concatenate([np.arange(a, b + 1) for a, b in runs])
    k = int(idx[np.argmax(div[idx])])
    span = [f for st in stretches for f in st]
    return min(span), max(span), float(grid[k]), float(_DB * div[k]), stretches


def _divergence(models: list, grid: np.ndarray) -> np.ndarray:
    """RMS over channels and members of ``|ln(G_k / G_0)|``, discounted at anti-resonances."""
    g0 = models[0].freqresp(grid).response
    level = np.abs(g0) / np.maximum(np.max(np.abs(g0), axis=0), 1e-300)
    seen = np.minimum(1.0, level / MEASURABLE)
    div = np.zeros(grid.size)
    for m in models[1:]:
        g = m.freqresp(grid).response
        with np.errstate(divide="ignore", invalid="ignore"):
            e = np.log(g / g0)
        e = np.where(np.isfinite(e), e, 0.0) * seen
        div += np.mean(np.abs(e) ** 2, axis=(1, 2))
    return np.sqrt(div / (len(models) - 1))
