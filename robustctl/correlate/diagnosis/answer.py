"""Is a significant effect *the answer*? The completeness test of ``rc.diagnose`` and the steps of
a chain of effects.

A candidate that is significant (it explains a real share of what updating leaves, beyond the
noise) is not yet the missing physics: a wrong effect can soak up part of a misfit it does not
explain (an added mass standing in for a hinge). It is the answer only when, with it fitted, the
model is within the noise (the chi-square of :func:`~.significance._null_test`), or when it removes at
least :data:`ANSWER_SHARE` of the *model-error part* of the misfit: the excess of the
parameters-only fit's dispersion over the noise, ``(d_u - d_c) / (d_u - 1)`` with ``d`` the mean
squared normalised residual (1 within the noise). Otherwise the verdict is "incomplete": the effect
is the closest candidate, the result says how much misfit it leaves and where
(:func:`~.localize.misfit_bands`), and -- when no further candidate is significant on the model with
it -- that the missing effect is probably not among the candidates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..residual import Residual
from .localize import MisfitBand, misfit_bands
from .results import ANSWER_SHARE, MODEL_ERROR_DISPERSION
from .significance import _null_test

#: Share of the residual left by updating a candidate must explain to lead a chain's next step when
#: nothing is significant (a second effect's misfit can hide a first one's significance); such a
#: tentative step is kept only when the chain ends within the noise.
CHAIN_TRY_GAIN = 0.5
#: An answer that removes :data:`~.results.ANSWER_SHARE` of the model error but leaves more than this
#: many times the noise variance does not end a chain: its next step looks for a second, smaller effect
#: (a hinge's own damping once the hinge is found) and is kept only if that effect is the answer on the
#: model with the first, or is significant, removes :data:`CHAIN_STEP_SHARE` of the model error the
#: first leaves and leaves at most this many times the noise variance itself.
CHAIN_PAST_ANSWER = 2.0
#: Share of the model-error part of the misfit an answer leaves, ``(d_a - d_e) / (d_a - 1)``, that a
#: significant second effect must remove to join the answer when it does not bring the model within the
#: noise itself (an added mass found once a soft seam is, leaving a damping law's small uniform misfit).
CHAIN_STEP_SHARE = 0.5
#: Most effects one diagnosis chains (``chain=True``): each is proposed on the model updated with
#: the ones before.
MAX_CHAIN = 4

#: The verdict words of a diagnosis.
VERDICTS = {
    "within the noise": "the parameters-only fit is within the noise: nothing is missing",
    "answer": "the proposed effect(s) bring the model within the noise (or remove nearly all of "
              "the model error)",
    "incomplete": "the closest effect(s) are significant but leave the misfit beyond the noise",
    "unexplained": "the misfit is beyond the noise and no candidate is significant",
    "no noise model": "no noise model: the best candidate is ranked on its share alone",
}


def beyond_noise(dispersion: float, p: float, alpha: float) -> bool:
    """Whether a fit's residual is beyond the noise: a chi-square p-value below ``alpha`` and a
    dispersion above :data:`MODEL_ERROR_DISPERSION` (the rule of ``Diagnosis.model_error``)."""
    return bool(np.isfinite(p) and p < alpha and dispersion > MODEL_ERROR_DISPERSION)


def model_error_share(d_before: float, d_after: float) -> float:
    """Share of the model-error part of a misfit an effect removes: ``(d_u - d_c) / (d_u - 1)``
    clipped to 0..1 (1 when there was no model error to remove)."""
    if not (np.isfinite(d_before) and np.isfinite(d_after)) or d_before <= 1.0:
        return 1.0
    return float(min(1.0, max(0.0, (d_before - d_after) / (d_before - 1.0))))


@dataclass(frozen=True)
class Completeness:
    """The completeness test of one fitted effect (or of a chain's last model).

    Attributes
    ----------
    dispersion : float
        The misfit left over its noise expectation (1 within the noise): "N x the noise".
    p_value : float
        Chi-square p-value of "the model with it is within the noise".
    share : float
        Share of the model-error part of the parameters-only fit's misfit it removes (0..1).
    complete : bool
        Within the noise, or ``share >= ANSWER_SHARE``.
    bands : tuple of MisfitBand
        Where the misfit left sits (bands, the model's modes there and their regions); empty when
        complete.
    """

    dispersion: float
    p_value: float
    share: float
    complete: bool
    bands: tuple[MisfitBand, ...] = ()

    def where(self) -> str:
        """The bands of the misfit left, in words."""
        return "; ".join(b.describe() for b in self.bands)


def completeness(
    res: Residual, vec: np.ndarray, d_null: float, alpha: float, model: Any = None
) -> Completeness:
    """The completeness test of the residual ``vec`` of a fitted model (``model``: where the modes
    of the misfit left are looked up) against the parameters-only fit's dispersion ``d_null``."""
    disp, p = _null_test(res, vec)
    share = model_error_share(d_null, disp)
    complete = not beyond_noise(disp, p, alpha) or share >= ANSWER_SHARE
    bands = () if complete else misfit_bands(res, vec, model)
    return Completeness(disp, p, share, complete, bands)


@dataclass(frozen=True, eq=False)
class ChainStep:
    """One effect of a chain: proposed on the model updated with the ones before it.

    Attributes
    ----------
    effect : Effect
        The effect with its size fitted jointly with the chain's later effects and the update
        parameters (``model.with_effect(step.effect)``).
    sentence : str
        The diagnosis's sentence on it.
    gain : float
        Share of the residual left by updating (with the effects before) that it removes.
    p_value : float
        Its family-wise p-value in that step.
    dispersion_before, dispersion_after : float
        The misfit over the noise before the step (parameters and earlier effects updated) and
        with this effect fitted too.
    update_values : dict
        The update parameters' values fitted with it.
    tentative : bool
        Not significant on its own step (another effect's misfit masked it): taken because it
        explained :data:`CHAIN_TRY_GAIN` of the residual, and kept because the chain ends within
        the noise.
    """

    effect: Any
    sentence: str
    gain: float
    p_value: float
    dispersion_before: float
    dispersion_after: float
    update_values: dict = field(default_factory=dict)
    tentative: bool = False

    @property
    def name(self) -> str:
        return self.effect.name

    def describe(self, k: int) -> str:
        if math.isfinite(self.dispersion_after):
            misfit = f"misfit {self.dispersion_before:.3g} -> {self.dispersion_after:.3g} x the noise"
        else:
            misfit = f"misfit {self.dispersion_before:.3g} x the noise before it"
        note = " (masked by the next one until it was applied)" if self.tentative else ""
        return (f"{k}. {self.effect.name} = {self.effect.describe_value()} (jointly re-fitted): explains "
                f"{100 * self.gain:.3g}% of what the model before it leaves{note}; {misfit}")
