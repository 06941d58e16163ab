"""Expected value of a Welch H1 estimate of a model, and the leakage correction it enables.

For a zero-order-hold, white (flat-spectrum) excitation and an H1 estimate from windowed
segments of ``N`` samples, the expected estimate is exactly

    E[H1](theta) = sum_{k=0}^{N-1} h[k] r_w[k] / r_w[0] exp(-j theta k),   theta = 2 pi f / fs,

where ``h`` is the sampled (ZOH) impulse response of the system and ``r_w[k] = sum_n w[n]
w[n+k]`` the window's autocorrelation: the estimator sees the impulse response through a lag
window. Lightly damped modes whose impulse response outlives the window are therefore
broadened (with the Caltech settings, 200 Hz and 4096-point Hamming windows, a 1.8 %-damped
mode at 1.17 Hz looks about 50 % more damped). Fitting ``data * M(jw) / E[H1 of M]`` instead of
``data`` for the current model ``M`` removes that bias (and the ZOH half-sample delay) in a
few fixed-point steps.

Impact records with a rectangular window (a response truncated at the record end, see
:func:`robustctl.estimate_frf_impact`) leak differently: one hit at ``t_h`` and a record of
length ``T`` give, at the DFT bins, the DFT of the impulse response cut ``T - t_h`` after the hit,

    H1(w) = H(jw) - tail(w),   tail(w) = sum_p dt r_p exp((p - jw)(T - t_h)) / (1 - exp((p - jw) dt)),

summed over the poles ``p`` (and conjugates) with residues ``r_p`` of the sampled (impulse-
invariant) response and averaged over the hits with their force energies (eq. T1). The tail is
no rational function of ``jw`` (the factor ``exp(-jw (T - t_h))`` turns by a full circle every
``1/(T - t_h)`` Hz), so a rational fit of leaked data spends extra poles and biases the damping.
With the modal refinement the tail is part of the model: the refinement fits ``H(jw) - tail``
of the current poles and shapes to the raw data (:mod:`.tail`: eq. T1 with the force pulse's
rms duration, and its pole derivative), so the truncation is undone exactly where the poles are
decided. Without it, fitting ``data + tail(M)`` for the current model ``M`` undoes it in a few
fixed-point steps (each step removes the ratio ``|exp(p (T - t_h))|`` of the remaining error:
the decay left at the record end), which converges slowly for lightly damped low modes (0.03 %
at 200 Hz keeps 70 % after 0.5 s) and, starting from a leaked fit, can settle on the wrong modes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import FitError
from ..measure.estimator import EstimatorSettings, estimator_settings, expected_h1_modal
from ..measure.impact_view import TruncationSettings, truncation_settings
from ..threads import limit_blas
from .modal_refine import ZETA_MIN
from .poles import coefficients_to_residues, lstsq_normal, partial_fraction_basis
from .rational_fit import RationalFit
from .tail import tail_terms

__all__ = [
    "EstimatorSettings",
    "estimator_settings",
    "expected_h1",
    "leakage_factor",
    "TruncationSettings",
    "truncation_settings",
    "record_tail",
    "corrected_response",
    "truncated_residues",
    "leaks",
    "tail_share",
]

#: damping ratio below which a pole sits at the modal refinement's lower bound ``ZETA_MIN``
BOUND_ZETA = 1.5 * ZETA_MIN

#: relative size of the record-end tail below which an impact record counts as decayed
TAIL_NEGLIGIBLE = 1e-3


@limit_blas
def expected_h1(model: RationalFit, f_hz: np.ndarray, settings: EstimatorSettings) -> np.ndarray:
    """Expected H1 estimate of ``model`` at ``f_hz`` (Hz) for white ZOH excitation; (K, n_out, n_in).

    :func:`robustctl.measure.estimator.expected_h1_modal` of the fit's poles (one of each
    conjugate pair, as :class:`RationalFit` keeps them), residues and feedthrough; frequencies
    at or above Nyquist are refused with a FitError.
    """
    fs = settings.fs_hz
    f = np.asarray(f_hz, dtype=float)
    if np.any(f >= fs / 2):
        raise FitError(f"frequencies must lie below the Nyquist frequency {fs / 2:g} Hz (leakage model).")
    return expected_h1_modal(model.poles, model.residues, model.d, f, settings)


def leakage_factor(model: RationalFit, f_hz: np.ndarray, settings: EstimatorSettings) -> np.ndarray:
    """``M(jw) / E[H1 of M]``: multiply measured H1 data by this to undo window leakage and ZOH."""
    expected = expected_h1(model, f_hz, settings)
    m = model.response(f_hz)
    tiny = np.finfo(float).tiny
    return m / np.where(np.abs(expected) > tiny, expected, tiny)


def _tail_terms(s: np.ndarray, poles: np.ndarray, settings: TruncationSettings) -> np.ndarray:
    """``dt sum_h w_h exp((q - s)(T - t_h)) / (1 - exp((q - s) dt))`` for every pole ``q`` and its
    conjugate: (K, n_p, 2), the tail of eq. T1 per unit residue (:func:`.tail.tail_terms`)."""
    return tail_terms(s, poles, settings)


def record_tail(model: RationalFit, f_hz: np.ndarray, settings: TruncationSettings) -> np.ndarray:
    """``tail(w)`` of eq. T1 for ``model``: what the record end cuts off, (K, n_out, n_in)."""
    s = 2j * np.pi * np.asarray(f_hz, dtype=float)
    terms = _tail_terms(s, model.poles, settings)
    real = model.poles.imag == 0
    out = np.einsum("kp,poi->koi", np.where(real, 0.0, 1.0) * terms[:, :, 0], model.residues)
    out += np.einsum("kp,poi->koi", np.where(real, 0.0, 1.0) * terms[:, :, 1], np.conj(model.residues))
    return out + np.einsum("kp,poi->koi", np.where(real, 1.0, 0.0) * terms[:, :, 0], model.residues.real)


def truncated_residues(
    s: np.ndarray, g: np.ndarray, row_weight: np.ndarray, poles: np.ndarray, settings: TruncationSettings
) -> tuple[np.ndarray, np.ndarray]:
    """Residues and feedthrough for fixed poles that fit the *truncated* data ``g`` directly:
    linear least squares on the basis ``1/(s - p) - tail_p(s)`` of eq. T1 (the leaked response of
    each pole), one solve per channel with the relative row weights of MACE eq. 5.

    This solves the truncation exactly for given poles (no fixed-point contraction), which keeps
    the correction stable for lightly damped poles whose decay barely starts within the record.
    """
    terms = _tail_terms(s, poles, settings)
    tails = []
    for p, (tp, tc) in zip(poles, terms.transpose(1, 2, 0)):
        tails += [tp] if p.imag == 0 else [tp + tc, 1j * (tp - tc)]
    basis = partial_fraction_basis(s, poles) - (np.stack(tails, axis=1) if tails else 0.0)
    basis = np.hstack([basis, np.ones((s.size, 1))])
    _, n_out, n_in = g.shape
    x = np.zeros((basis.shape[1], n_out, n_in))
    for i in range(n_out):
        for j in range(n_in):
            a = basis * row_weight[:, i, j][:, None]
            b = g[:, i, j] * row_weight[:, i, j]
            x[:, i, j] = lstsq_normal(np.concatenate([a.real, a.imag]), np.concatenate([b.real, b.imag]))
    residues = coefficients_to_residues(x[:-1], poles).reshape(len(poles), n_out, n_in)
    return residues, x[-1]


def corrected_response(
    model: RationalFit, band, settings, row_weight: np.ndarray | None = None
) -> np.ndarray:
    """``band``'s response with the estimator's leakage undone for ``model``: times
    :func:`leakage_factor` (Welch settings) or plus :func:`record_tail` (impact truncation; with
    ``row_weight`` the residues are first refitted to the raw data by :func:`truncated_residues`).
    Only complex poles get a tail. Those whose damping sits at the modal refinement's bound
    (``BOUND_ZETA``) do not: the data do not determine their decay, and a nearly undamped spurious
    pole would manufacture its own peak in the corrected data. Nor do real poles: they are
    fillers for out-of-band dynamics and residual flexibility, not decays the record saw (a slow
    real filler with a large residue would add a large, meaningless tail)."""
    if not isinstance(settings, TruncationSettings):
        return band.response * leakage_factor(model, band.f_hz, settings)
    if row_weight is not None:
        s = 2j * np.pi * band.f_hz
        res, d = truncated_residues(s, band.response, row_weight, model.poles, settings)
        model = replace(model, residues=res, d=d)
    zeta = -model.poles.real / np.maximum(np.abs(model.poles), np.finfo(float).tiny)
    trusted = (model.poles.imag != 0) & (zeta > BOUND_ZETA)
    model = replace(model, poles=model.poles[trusted], residues=model.residues[trusted])
    return band.response + record_tail(model, band.f_hz, settings)


def tail_share(model: RationalFit, band, settings: TruncationSettings) -> float:
    """Largest ``|tail| / |model|`` of eq. T1 over the band: how much the record end cuts off."""
    tail = np.abs(record_tail(model, band.f_hz, settings))
    model_abs = np.maximum(np.abs(model.response(band.f_hz)), np.finfo(float).tiny)
    return float(np.max(tail / model_abs))


def leaks(model: RationalFit, band, settings) -> bool:
    """Whether the correction matters: always for Welch settings; for impact records when the
    tail reaches ``TAIL_NEGLIGIBLE`` of the model's response somewhere in the band."""
    if not isinstance(settings, TruncationSettings):
        return True
    return tail_share(model, band, settings) >= TAIL_NEGLIGIBLE
