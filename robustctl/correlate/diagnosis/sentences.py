"""The sentences of ``rc.diagnose``: where a residual change lies (band, outputs, magnitude or
phase), the phrase naming an effect, one sentence per candidate."""

from __future__ import annotations

from typing import Any

import numpy as np

from ...measure.noise import NO_NOISE_SENTENCE, format_p
from ..residual import Residual
from .results import CandidateResult


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
    """The effect with its size in words: "a 3.6 ms output delay", "0.3 kg of added mass at ..."
    (each effect class words its own, :meth:`~robustctl.physical.effects.Effect.phrase`)."""
    return effect.phrase()


def _values_text(effect: Any) -> str:
    """The effect's fitted values with their units (``"4.58 kg, 0.001 Hz"``)."""
    return ", ".join(f"{p.value:.3g} {p.unit}".strip() for p in effect.parameters)


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
                f"at a bound of its parameters ({_values_text(r.effect)}): the model form is likely "
                "wrong, so it is not proposed"
            )
        elif not np.isfinite(r.p_value):
            verdict = NO_NOISE_SENTENCE
        elif r.significant and r.incomplete:
            verdict = (f"significant ({format_p(r.p_value)} < {r.level:.2g}{against}) but incomplete: the "
                       "model with it is still beyond the noise")
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
    if fs_hz is None or not getattr(effect, "dac_hold", False):
        return ""
    delay = float(next(iter(effect.values.values()), 0.0))
    half = 0.5 / fs_hz
    if not 0.7 * half <= delay <= 1.3 * half:
        return ""
    return (
        f"about half a sample at {fs_hz:g} Hz ({1e3 * half:.3g} ms): the DAC zero-order hold, not an unknown "
        "delay; add it as a known stage, rc.electronics.zero_order_hold_stage(...)"
    )


def _with_sentence(r: CandidateResult) -> CandidateResult:
    from dataclasses import replace

    return replace(r, sentence=_sentence(r))


