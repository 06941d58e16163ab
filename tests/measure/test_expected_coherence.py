"""The coherence window leakage leaves in a Welch H1 estimate of a noise-free system, against
scipy's coherence of a long simulated record, and the closed form against the state-space sums."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.signal as sig

import robustctl as rc
from robustctl.errors import DataError
from robustctl.lti import zoh
from robustctl.measure.estimator import EstimatorSettings, _modal
from robustctl.measure.expected_coherence import (
    _autocorrelation_modal,
    _autocorrelation_state,
    expected_coherence,
    leakage_sigma,
)


def _two_modes(zeta: float):
    """Two lightly damped modes (2 and 7 Hz), one input, two outputs, as a numpy state space."""
    w = 2 * np.pi * np.array([2.0, 7.0])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.diag(w**2), -np.diag(2 * zeta * w)]])
    B = np.array([[0.0], [0.0], [1.0], [0.6]])
    C = np.array([[1.0, 0.5, 0.0, 0.0], [0.3, -1.0, 0.0, 0.0]]) * 100.0
    return A, B, C, np.zeros((2, 1))


@pytest.mark.parametrize("zeta, window, nperseg", [(0.01, "hann", 256), (0.004, "hamming", 512)])
def test_leakage_coherence_is_what_a_simulated_welch_estimate_shows(zeta, window, nperseg):
    fs = 50.0
    A, B, C, D = _two_modes(zeta)
    f = np.arange(2, nperseg // 2 + 1) * fs / nperseg  # above the detrended DC bins
    g2 = expected_coherence(control.ss(A, B, C, D), f, EstimatorSettings((fs, nperseg, window), nperseg // 2))
    Ad, Bd = zoh(A, B, 1 / fs)
    u = np.random.default_rng(3).standard_normal(1_000_000)
    for o in range(2):
        num, den = sig.ss2tf(Ad, Bd, C[[o]], D[[o]])
        y = sig.lfilter(num[0], den, u)
        _, c = sig.coherence(u, y, fs=fs, window=window, nperseg=nperseg, noverlap=nperseg // 2)
        c = c[2:]
        # the estimate's bias is (1 - g2)^2 / n_d and its scatter (1 - g2) sqrt(2 / n_d) g
        # (Bendat & Piersol 9.2.2): n_d ~ 10^4 segments here, 6 sigma
        tol = 6 * (1 - g2[:, o, 0]) * np.sqrt(2 / (len(u) / nperseg)) + 1e-3
        assert np.all(np.abs(c - g2[:, o, 0]) < tol)
        assert g2[:, o, 0].min() < 0.5  # the resonances leak: a test that can fail


def test_closed_form_autocorrelation_equals_the_state_space_sums():
    A, B, C, D = _two_modes(0.02)
    D = np.array([[0.2], [-0.1]])
    sys = control.ss(A, B, C, D)
    h1, r1 = _autocorrelation_modal(*_modal(rc.as_statespace(sys)), 40.0, 300)
    h2, r2 = _autocorrelation_state(A, B, C, D, 40.0, 300)
    np.testing.assert_allclose(h1, h2, atol=1e-12 * np.abs(h2).max())
    np.testing.assert_allclose(r1, r2, atol=1e-12 * np.abs(r2).max())
    # and R_h(l) is the sum of h[k + l] h[k] over a record long enough to have decayed
    long_h, _ = _autocorrelation_state(A, B, C, D, 40.0, 40_000)
    direct = np.array([np.sum(long_h[lag:, 0, 0] * long_h[: len(long_h) - lag, 0, 0]) for lag in (0, 1, 37)])
    np.testing.assert_allclose(r1[[0, 1, 37], 0, 0], direct, rtol=1e-10)


def test_leakage_sigma_is_bendat_and_piersols_error_and_an_unstable_system_is_refused():
    g2 = np.array([0.5, 0.9, 1.0]).reshape(3, 1, 1)
    np.testing.assert_allclose(leakage_sigma(g2, [20.0])[:, 0, 0],
                               np.sqrt((1 - g2[:, 0, 0]) / (2 * 20.0 * g2[:, 0, 0])), rtol=1e-14)
    with pytest.raises(DataError, match="stable"):
        expected_coherence(control.ss([[0.1]], [[1.0]], [[1.0]], [[0.0]]), [1.0],
                           EstimatorSettings((10.0, 64, "hann"), 32))
