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
4. **Significance.** Against the data's noise model (:mod:`robustctl.measure.noise`, the same one
   compare's verdicts use): under "the effect is absent" the cost drop of the local fit is
   noise projected on one direction, ``Delta J ~ v chi2_1`` with ``v`` the noise variance
   along the fitted change (window bin correlation included); a Bonferroni level
   ``alpha / m`` over the ``m`` screened candidates, plus a practical threshold
   (``min_gain``): an effect must explain a real share of what updating leaves. Without a
   noise model no significance claims are made (p-values NaN; the best candidate is
   proposed on its share alone, and the result says so).

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

from ..checks import UNSET, finite_number, integer, positive_number, renamed_keyword
from ..errors import FitError, ModelError, RobustctlError
from ..executors import check_executor, parallel_map_shared, process_pool, resolve_workers
from ..frd import FrequencyData, as_frequency_data
from ..measure.estimator import estimator_settings
from ..measure.noise import NO_NOISE_SENTENCE, format_p, noise_model
from ..table import Table, result_html
from ..threads import limit_blas
from .optimize import _bounds, levenberg_marquardt, marquardt_step
from .residual import Residual, check_determined, physical_model, sensitivities

__all__ = ["diagnose", "Diagnosis", "CandidateResult", "Indistinguishable", "effective_points"]

#: Significance level of the partial F-test before the Bonferroni correction.
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
        The test statistic (``Delta J`` over the noise variance along the fitted change; a
        chi-square with one degree of freedom under "absent") and its p-value (NaN when not
        fitted or without a noise model).
    significant : bool
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
        The per-candidate p-value threshold (Bonferroni); NaN without a noise model.
    min_gain : float
        The practical threshold on ``gain``.
    note : str
        What the effect is physically when it can be named (a delay of half a sample: the
        DAC zero-order hold).
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
        Per-candidate level after the Bonferroni correction.
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

    @property
    def weights(self) -> np.ndarray:
        """Deprecated name of :attr:`point_weights` (weights on the squared error)."""
        return self.point_weights

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
        if self.noise_source:
            lines.append(f"Noise model: {self.noise_source}.")
        else:
            lines.append(NO_NOISE_SENTENCE[:1].upper() + NO_NOISE_SENTENCE[1:] + ".")
        best = self.best_result
        if best is not None:
            lines.append("Proposed: " + best.sentence)
            others = [r for r in self.ranking if r.fitted and r is not best][:2]
            for r in others:
                lines.append("Next: " + r.sentence)
        else:
            test = (
                f"chi-square against the noise at {self.alpha:.2g} per candidate"
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
        from ..plots import log_frequency_axis, new_figure

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
    res_u: Residual, null: _Null, screen: dict[str, Any], max_iter: int, budget: float
) -> dict[str, Any]:
    """Short bounded local fit of one candidate with the update parameters (step 3).

    Gauss-Newton/Marquardt on ``[alpha_update, v]`` with the update parameters' Jacobian
    frozen at the null fit and the candidate's column refreshed each iteration by a secant
    (two evaluations per iteration instead of ``p + 1``). A point where the model cannot
    be evaluated (e.g. the gravity preload does not converge) counts as a failed step.
    """
    t0 = time.perf_counter()
    effect = screen["effect"]
    pname, par = effect.param_names[0], effect.parameters[0]
    discrete = effect.kind == "gravity"
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
                             budget - (time.perf_counter() - t0), counter[0])
    cut = False
    for _ in range(int(max_iter)):
        if time.perf_counter() - t0 > budget:
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
                  r: np.ndarray, max_iter: int, budget: float, evals: int) -> dict[str, Any]:
    """The local fit of a discrete candidate (gravity switched on or off): a full LM fit of the
    update parameters with the switch set (their sensitivities refreshed each iteration).

    The null fit's Jacobian, which the secant fits of :func:`_fit_one` keep, belongs to the
    other state: gravity changes the pendulum modes by factors, so a fit on the frozen Jacobian
    stops at once and the true switch ranked below springs that mimic it (a hanging chain:
    the switch explained 34 % of the residual, refitted 99.9 %)."""
    cost = float(r @ r)
    x = dict(zip(names, (float(a) for a in u)))
    out = dict(x=x, cost=cost, vector=r, evals=evals, value=v, cut=False)
    if budget <= 0:
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
                cut="time budget" in lm.stop_reason)


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


def _polish(
    res_u: Residual, null: _Null, screens: list[dict], top: list[int], fits: list[dict], executor: Any,
    budget: float,
) -> tuple[list[dict], int]:
    """Full LM fits of the contenders (step 3b): the local fits freeze the update parameters'
    sensitivities at the null fit, which may have bent them to mimic the missing effect, so
    two candidates whose local fits end close may rank in the wrong order (on the Caltech truss
    below 30 Hz the true taut wires stopped at half their tension, behind stiffer diagonals).
    Contenders -- fits within :data:`CONTENDER_RATIO` of the best cost -- are refitted with
    refreshed sensitivities (:func:`levenberg_marquardt`, up to :data:`POLISH_ITER` iterations) from
    their local fit; a clear winner costs nothing more. Returns the fits and the evaluations.
    """
    costs = [f["cost"] for f in fits]
    if len(fits) < 2 or not null.names:
        return fits, 0
    best = min(costs)
    todo = [i for i, c in enumerate(costs) if c <= CONTENDER_RATIO * best
            and screens[top[i]]["effect"].kind != "gravity"]
    if len(todo) < 2:
        return fits, 0

    done = parallel_map_shared(_polish_task, (res_u, null.names, budget / len(todo)),
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
                value=float(x[pname]), cut="time budget" in lm.stop_reason)


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


def _check_budget(deadline: float, budget: float, stage: str) -> float:
    """Seconds left before ``deadline``; a FitError naming the stage when none are (the
    budget covers the whole call: a partial ranking would be a wrong answer without warning)."""
    left = deadline - time.perf_counter()
    if left <= 0:
        raise FitError(
            f"time_budget_s={budget:g} s ran out during {stage}; raise time_budget_s, pass fewer "
            "candidates= or a narrower band=."
        )
    return left


def _screen_all(
    res_u: Residual, model_u: Any, null: _Null, cands: list, executor, deadline: float, budget: float
) -> tuple:
    """Screen every candidate (step 2): the screens, indistinguishable twins, and the
    order of the others by the fraction they explain."""
    r_perp = _project(null.Q, null.j)
    shared = (res_u, model_u, null.j, null.Q, r_perp, _wall_deadline(deadline), budget, len(cands))
    screens = parallel_map_shared(_screen_task, shared, cands, executor, desc="screening")
    twins = _equivalent(screens)
    order = sorted(
        (k for k in range(len(screens)) if k not in twins),
        key=lambda k: (-round(screens[k]["fraction"], 9), k),
    )
    return screens, twins, order


def _wall_deadline(deadline: float) -> float:
    """``deadline`` (a ``time.perf_counter`` instant) on the wall clock (``time.time``), which
    other processes share."""
    return time.time() + (deadline - time.perf_counter())


def _screen_task(shared: tuple, effect: Any) -> dict:
    """One candidate's screening (:func:`parallel_map_shared` task; ``shared`` from
    :func:`_screen_all`)."""
    res_u, model_u, j_u, Q, r_perp, wall_deadline, budget, n = shared
    if time.time() > wall_deadline:
        _check_budget(time.perf_counter() - 1.0, budget, f"the screening of {n} candidates")
    return _screen_one(res_u, model_u, j_u, Q, r_perp, effect)


def _null_fit(
    res0: Residual,
    upd: tuple[str, ...],
    max_iter: int,
    executor: Executor | None,
    budget: float,
    j0: np.ndarray,
) -> tuple[_Null, int]:
    """Bounded LM fit of the update parameters alone (step 1), from the nominal residual ``j0``.

    It starts where :func:`~robustctl.correlate.updating.update` would (its coarse multi-start,
    ``_coarse_start``): with parameters 20-50 % off, modes have moved by several bandwidths and
    LM from the model's values stops in a local minimum of the complex-log cost, which leaves
    the parameter error in the residual for the candidates to mimic (a wrong effect ranks first).
    """
    from .updating import _coarse_start

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
    null.cut = "time budget" in lm.stop_reason
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
        if not np.isfinite(r.p_value):
            verdict = NO_NOISE_SENTENCE
        elif r.significant:
            verdict = f"significant ({format_p(r.p_value)} < {r.level:.2g})"
        elif r.p_value < r.level:
            verdict = (
                f"beyond the noise ({format_p(r.p_value)}) but below the {100 * r.min_gain:.0f}% needed "
                "to propose it"
            )
        else:
            verdict = f"not significant ({format_p(r.p_value)} >= {r.level:.2g})"
        return (
            f"{head} explains {100 * r.gain:.3g}% of the residual left by updating ({r.where}); "
            f"cost {100 * r.reduction:.3g}% below the nominal model; {verdict}."
        )
    return (
        f"{head} would explain about {100 * r.fraction:.3g}% of the residual left by updating to first "
        "order (not fitted)."
    )


def _hold_note(effect: Any, fs_hz: float | None) -> str:
    """Name a delay of about half a sample (data sampled at ``fs_hz``) as the DAC's hold."""
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
    from ..physical.effects import Effect

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
    time_budget_s: float = 600.0,
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
        Number of best-screened candidates given the local fit.
    max_iter, update_iter : int
        LM iteration caps of the local fits and of the null fit.
    alpha : float
        Level of the test against the noise before the Bonferroni correction over the screened
        candidates.
    min_gain : float
        Smallest share (0..1) of the null-fit residual an effect must remove to be proposed.
    time_budget_s : float
        Wall-clock budget (s) for the fits: a safety cap, not a stopping rule (a RuntimeWarning
        says when it stopped a fit, since the ranking then depends on the machine's load).
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
    time_budget_s = positive_number(time_budget_s, "time_budget_s", FitError, unit="s, the whole call")
    max_iter = integer(max_iter, "max_iter", FitError, lo=1)
    update_iter = integer(update_iter, "update_iter", FitError, lo=1)
    deadline = t0 + time_budget_s
    params = renamed_keyword(params, update_params, "params", "update_params")
    point_weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    model = physical_model(model, "diagnose")
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
            candidates = _default_candidates(model, res0, deadline, time_budget_s, ex)
        return _diagnose(
            t0, res0, ignored, upd, candidates, j_nominal, ex, n_fit, max_iter, update_iter, alpha, min_gain,
            time_budget_s, deadline,
        )


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
            from ..physical.effects.catalogue import candidates as all_candidates

            n = len(all_candidates(model, calibrate=False))
        else:
            n = len(candidates)
        if workers == "auto" and SCREEN_EVALS * n * t_eval < PARALLEL_MIN_WORK_S:
            n = 0
    return process_pool(workers, n, PARALLEL_MIN_CANDIDATES)


def _default_candidates(model: Any, res0: Residual, deadline: float, budget: float, executor: Any) -> list:
    """``rc.effects.candidates`` of the model on the band, calibrated within the time budget."""
    from ..physical.effects import candidates as all_candidates

    left = _check_budget(deadline, budget, "the residual set-up")
    try:
        cands = all_candidates(model, band=res0.band, time_budget_s=left, executor=executor)
    except FitError as exc:
        raise FitError(str(exc).replace(f"time_budget_s={left:g}", f"time_budget_s={budget:g}")) from None
    return _check_candidates(model, cands)


def _diagnose(
    t0, res0, ignored, upd, cands, j_nominal, executor, n_fit, max_iter, update_iter, alpha, min_gain,
    time_budget_s, deadline,
) -> Diagnosis:
    """:func:`diagnose` once the arguments are checked, the candidates made and the executor chosen."""
    model = res0.model
    evals = 1
    cost_nominal = float(j_nominal @ j_nominal)
    # 1. null fit of the update parameters
    null, n_null = _null_fit(res0, upd, update_iter, executor, time_budget_s / 3, j_nominal)
    evals += n_null
    x_u, j_u, cost_u = null.x, null.j, null.cost
    model_u = model.with_values(**x_u) if x_u else model
    res_u = _residual_for(res0, model_u)
    # 2. secant screening
    _check_budget(deadline, time_budget_s, "the null fit")
    screens, twins, order = _screen_all(res_u, model_u, null, cands, executor, deadline, time_budget_s)
    evals += sum(s["evals"] for s in screens)
    top = [k for k in order[:n_fit] if screens[k]["fraction"] > 0]
    # 3. local fits
    remaining = _check_budget(deadline, time_budget_s, "the screening")
    fits = parallel_map_shared(
        _fit_task, (res_u, null, max_iter, remaining / max(len(top), 1)), [screens[k] for k in top],
        executor, desc="local fits",
    )
    evals += sum(f["evals"] for f in fits)
    remaining = deadline - time.perf_counter()
    if remaining > 0:  # a budget the local fits used up is reported by the warning below
        fits, n_polish = _polish(res_u, null, screens, top, fits, executor, remaining)
        evals += n_polish
    _warn_if_hurried(null.cut, sum(bool(f.get("cut")) for f in fits), time_budget_s)
    # 4. significance and words
    e_u = res0.unstack(j_u)
    n_eff, rho = effective_points(e_u)
    level = alpha / len(cands)
    settings = estimator_settings(res0.data.meta)
    stats = dict(
        cost_u=cost_u,
        cost_nominal=cost_nominal,
        n_eff=n_eff,
        p=len(upd),
        level=level,
        min_gain=min_gain,
        upd=upd,
        row_noise=_row_noise(res0),
        # data whose hold was divided out (meta["hold_divided"]) have no half-sample delay left:
        # a delay found there is not the hold
        fs_hz=None if settings is None or settings.hold_divided else settings.fs_hz,
    )
    results, explained = _score(res0, screens, order, top, fits, twins, j_u, stats)
    best = _best(results, res0.noise is not None, min_gain)
    fitted = _fitted_models(screens, top, fits)
    group = _indistinguishable(res0, results, fitted, j_u, stats["row_noise"], alpha)
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
        alpha=level,
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
    )


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
    least ``min_gain`` of the residual (proposed without a significance claim)."""
    if have_noise:
        return next((r.effect for r in results if r.significant), None)
    return next((r.effect for r in results if r.fitted and r.gain >= min_gain), None)


def _row_noise(res: Residual) -> np.ndarray | None:
    """Noise variance of each row of the weighted residual vector (see update), or None."""
    if res.noise is None:
        return None
    v = (res.point_weights * res.noise.sigma**2 * res.noise.dof_factor).ravel()
    return np.concatenate([v, v])


def _warn_if_hurried(null_cut: bool, n_cut: int, budget: float) -> None:
    """Say so when the wall-clock budget, not convergence, stopped a fit: the ranking then
    depends on the machine's speed and load (a fit cut short understates its candidate)."""
    if not null_cut and not n_cut:
        return
    what = ["the null fit"] if null_cut else []
    what += [f"{n_cut} local fit{'s' if n_cut > 1 else ''}"] if n_cut else []
    warnings.warn(
        f"diagnose: the time budget ({budget:g} s) stopped {' and '.join(what)} before convergence; "
        "the ranking may differ from an unhurried run. Raise time_budget_s (or pass fewer candidates).",
        RuntimeWarning,
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
    """CandidateResults: fitted ones by gain (F-test, sentence), then the rest by fraction."""
    results, explained = [], {}

    def twins_of(k: int) -> tuple[str, ...]:
        return tuple(screens[t]["effect"].name for t, i in twins.items() if i == k)

    for k, fit in zip(top, fits):
        s = screens[k]
        effect = s["effect"].with_values(**{s["effect"].param_names[0]: fit["value"]})
        gain = _reduction(fit["cost"], st["cost_u"])
        delta = j_u - fit["vector"]
        f_stat, p_val = _noise_test(st["cost_u"] - fit["cost"], delta, st["row_noise"])
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
                significant=bool(
                    p_val < st["level"]
                    and gain >= st["min_gain"]
                    and st["cost_u"] - fit["cost"] > 1e-10 * st["cost_nominal"]
                ),
                update_values={n: v for n, v in fit["x"].items() if n in st["upd"]},
                where=_where(res0, delta),
                equivalent=twins_of(k),
                level=st["level"] if st["row_noise"] is not None else math.nan,
                min_gain=st["min_gain"],
                note=_hold_note(effect, st["fs_hz"]),
            )
        )
        explained[effect.name] = res0.unstack(delta)
    order_fit = sorted(range(len(results)), key=lambda i: (-round(results[i].gain, 9), i))
    results = [results[i] for i in order_fit]
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


def _noise_test(drop: float, delta: np.ndarray, row_noise: np.ndarray | None) -> tuple[float, float]:
    """``T = Delta J / v_delta`` and its chi-square(1) p-value; NaNs without a noise model.

    Under "the effect is absent" the fitted change ``delta`` of the weighted residual is noise
    projected on one direction: ``Delta J ~ v_delta chi2_1`` with ``v_delta = sum delta_i^2 v_i /
    sum delta_i^2`` the noise variance along it (``v_i`` from the noise model, with the window's
    bin correlation; :mod:`robustctl.measure.noise`).
    """
    if row_noise is None:
        return math.nan, math.nan
    from scipy.stats import chi2

    d2 = np.asarray(delta, dtype=float) ** 2
    total = float(d2.sum())
    if total <= 0 or drop <= 0:
        return 0.0, 1.0
    v = float(d2 @ row_noise) / total
    t = drop / max(v, 1e-300)
    return t, float(chi2.sf(t, 1))


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
