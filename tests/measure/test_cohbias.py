"""Coherence weights' own-error bias: ``W = g2 / (1 - g2)`` from each bin's own
coherence carries ``|1 + eps|^2`` of the bin's own error, so a weighted log fit sees ``Re ln H1``
raised; :func:`robustctl.measure.noise.coherence_weight_bias` is what to subtract."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.measure.noise import coherence_weight_bias, point_weight_bias


def _h1(rng, g2_true: float, n_d: int, n_bins: int) -> tuple[np.ndarray, np.ndarray]:
    """H1 estimates of ``H = 1`` over ``n_bins`` independent bins: ``n_d`` segments of complex
    Gaussian input and output noise at true coherence ``g2_true``; returns (ln H1, own g2)."""
    def cn(scale: float) -> np.ndarray:
        shape = (n_bins, n_d)
        return scale * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)

    u = cn(1.0)
    y = u + cn(np.sqrt(1.0 / g2_true - 1.0))
    guy, guu, gyy = np.sum(y * u.conj(), 1), np.sum(np.abs(u) ** 2, 1), np.sum(np.abs(y) ** 2, 1)
    return np.log(guy / guu), np.abs(guy) ** 2 / (guu * gyy)


@pytest.mark.parametrize("g2_true", [0.3, 0.6, 0.9])
def test_the_bias_formula_removes_what_own_coherence_weights_add_to_the_log_magnitude(g2_true):
    rng = np.random.default_rng(12)
    n_d, n_bins = 20, 40000
    e, g2 = _h1(rng, g2_true, n_d, n_bins)
    w = rc.checks.coherence_weights(g2)
    c = coherence_weight_bias(g2[:, None, None], n_d)[:, 0, 0]
    mc_sd = np.sqrt(np.sum(w**2) * np.var(e.real)) / np.sum(w)  # sd of a weighted mean over the bins
    raw = np.sum(w * e.real) / np.sum(w)  # the weighted fit of a constant log level
    fixed = np.sum(w * (e.real - c)) / np.sum(w)
    s2 = (1 - g2_true) / (2 * n_d * g2_true)
    # the raw weighted level is biased by about 2 s^2 / (1 + 2 s^2), far beyond the Monte Carlo noise
    assert raw == pytest.approx(2 * s2 / (1 + 2 * s2), rel=0.15) and raw > 8 * mc_sd
    # eq. (1) removes it to within the Monte Carlo noise (the leading-order 2 s^2 / (1 + 2 s^2),
    # evaluated on the own coherence, leaves part of it)
    assert abs(fixed) < 3 * mc_sd and abs(fixed) < 0.05 * raw
    # the phase is not biased, and neither is the unweighted mean
    assert abs(np.sum(w * e.imag) / np.sum(w)) < 3 * mc_sd
    assert abs(np.mean(e.real)) < 3 * np.std(e.real) / np.sqrt(n_bins)
    # W c = 1 / (n_d - 2) exactly where the coherence is neither capped nor noise
    g2c = g2[(g2 > 0.2) & (g2 < 0.99)]
    wc = g2c / (1 - g2c) * coherence_weight_bias(g2c[:, None, None], n_d)[:, 0, 0]
    assert np.allclose(wc, 1 / (n_d - 2))


def test_the_bias_applies_only_to_own_coherence_weights_with_known_averages():
    f = np.linspace(1, 10, 50)
    g = np.exp(1j * f)[:, None, None] * np.ones((1, 1, 2))
    coh = np.full(g.shape, 0.8)
    meta = {"n_averages": 12}
    data = rc.FrequencyData(f, g, coherence=coh, meta=meta)
    c = point_weight_bias("auto", data)
    assert c.shape == g.shape and np.allclose(c, 0.2 / (10 * 0.8))
    assert np.allclose(point_weight_bias("coherence", data, mask=f < 5), 0.025)
    for spec in (None, np.ones(50)):
        assert point_weight_bias(spec, data) is None  # uniform and given weights: unchanged
    assert point_weight_bias("auto", data.replace(meta={})) is None  # n_d unknown
    assert point_weight_bias("auto", data.replace(coherence=None)) is None
    # a noise-only bin (s > 0.5) gets the bounded value at s = 0.5: 2 (0.25) n_d / (n_d - 2)
    low = coherence_weight_bias(np.full((1, 1, 1), 1e-6), 12)
    assert low[0, 0, 0] == pytest.approx(0.5 * 12 / 10)


@pytest.mark.slow
def test_the_true_caltech_truss_updated_on_its_own_data_moves_nothing_and_warns_of_nothing():
    """Over 40 seeds the coherence weights' bias moved E and the masses by -1.0 to -1.2 SE on
    average (seeds 1 and 4 warned); corrected, by 0.00-0.11 SE, none beyond 2.4 SE, no warnings."""
    z_all = []
    for seed in (1, 4, 8):  # 1 and 4 warned before; 8 moved E by -1.9 SE
        data, truth = rc.examples.caltech_truss_experiment(seed=seed)
        upd = rc.update(truth, data, band=(0.5, 29.8))
        assert upd.warnings == (), (seed, upd.warnings)
        assert upd.noise_before.within and upd.noise_after.within
        z = upd.moves_se
        assert max(abs(v) for v in z.values()) < 2.0, (seed, z)
        z_all += [z[n] for n in ("E_aluminium", "m_platform_1", "m_platform_2", "m_offset") if n in z]
    # the bias was about -1.1 SE in each of these; left: noise only
    assert abs(np.mean(z_all)) < 0.5, z_all
