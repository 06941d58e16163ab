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

from .pipeline import diagnose
from .results import ALPHA, DECOUPLED_DB, MIN_GAIN, MODEL_ERROR_DISPERSION, CandidateResult, Diagnosis
from .rivals import COLLINEAR, DIFFER_NP, MEASURABLE, N_DIFFER_BANDS, Indistinguishable
from .screening import (
    CONTENDER_RATIO,
    POLISH_ITER,
    PROBE_MIN_COEF,
    SCREEN_MULTIPLES,
    TIE_MAX_FACTOR,
    TIE_SHARE,
    UNITS_NEAREST,
)
from .significance import CHANNEL_SHARE, MISFIT_HALF_WIDTH, effective_points
from .workers import PARALLEL_MIN_CANDIDATES, PARALLEL_MIN_WORK_S, SCREEN_EVALS

__all__ = [
    "diagnose",
    "Diagnosis",
    "CandidateResult",
    "Indistinguishable",
    "effective_points",
    "ALPHA",
    "DECOUPLED_DB",
    "MIN_GAIN",
    "MODEL_ERROR_DISPERSION",
    "COLLINEAR",
    "DIFFER_NP",
    "MEASURABLE",
    "N_DIFFER_BANDS",
    "CONTENDER_RATIO",
    "POLISH_ITER",
    "PROBE_MIN_COEF",
    "SCREEN_MULTIPLES",
    "TIE_MAX_FACTOR",
    "TIE_SHARE",
    "UNITS_NEAREST",
    "CHANNEL_SHARE",
    "MISFIT_HALF_WIDTH",
    "PARALLEL_MIN_CANDIDATES",
    "PARALLEL_MIN_WORK_S",
    "SCREEN_EVALS",
]
