"""Impact-hammer testing: estimate_frf_impact and the exponential window's damping correction.

Hits are simulated by :func:`robustctl.examples.impact_test_case` (half-sine pulses, exact sum of
modal impulse responses, sensor noise): 8 modes at 200-2000 Hz with 0.05-0.3 % damping, 0.5 s
records at 8192 Hz, so the lightest modes are far from decayed at the record end (leakage).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import robustctl as rc
from robustctl.identify import IdentifyWarning

FS = 8192.0
BAND = (150.0, 2200.0)


@pytest.fixture(scope="module")
def hits():
    return rc.examples.impact_test_case(seed=0, zeta_range=(0.0005, 0.003), duration_s=0.5)


def _fit(data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifyWarning)
        return rc.fit_measurement_model(data.band(*BAND), progress=False, **kw)


def _matched(mm, truth):
    f = np.array([m.f_hz for m in mm.modes])
    z = np.array([m.zeta for m in mm.modes])
    idx = [int(np.argmin(np.abs(f - ft))) for ft in truth.f_hz]
    assert len(set(idx)) == len(idx)
    return f[idx], z[idx]


def test_exponential_window_modes_and_damping_recovered(hits):
    """'auto' applies an exponential window (the response has not decayed); the identified
    damping, corrected by zeta -= 1/(tau w_n), matches the truth within 3 % for every mode,
    with fixed and automatic order."""
    force, resp, truth = hits
    data = rc.estimate_frf_impact(force, resp, fs=FS)
    tau = data.meta["exp_window_tau_s"]
    assert tau is not None and 0.05 < tau < 0.2
    for kw in (dict(n_modes=8), dict()):
        mm = _fit(data, **kw)
        assert mm.window_tau_s == tau and mm.n_modes == 8
        f, z = _matched(mm, truth)
        np.testing.assert_allclose(f, truth.f_hz, rtol=1e-4)
        np.testing.assert_allclose(z, truth.zeta, rtol=0.03)
    # the window's own damping: without the correction every mode is too damped by 1/(tau w_n)
    raw = _fit(data, n_modes=8, correct_window=False)
    f, z_raw = _matched(raw, truth)
    np.testing.assert_allclose(z_raw - 1 / (tau * 2 * np.pi * f), truth.zeta, rtol=0.03)


def test_rectangular_window_leakage_case(hits):
    """No window: the truncated responses leak; the automatic order still finds every mode within
    0.1 % in frequency, but the damping is biased by leakage far more than with the window."""
    force, resp, truth = hits
    rect = rc.estimate_frf_impact(force, resp, fs=FS, exp_window=None)
    assert rect.meta["exp_window_tau_s"] is None
    mm = _fit(rect)
    f, z_rect = _matched(mm, truth)
    np.testing.assert_allclose(f, truth.f_hz, rtol=1e-3)
    _, z_exp = _matched(_fit(rc.estimate_frf_impact(force, resp, fs=FS), n_modes=8), truth)
    assert np.max(np.abs(z_rect / truth.zeta - 1)) > 5 * np.max(np.abs(z_exp / truth.zeta - 1))


def test_h1_over_hits_matches_the_true_frf_and_coherence_is_high(hits):
    """With a long enough record (decayed, no window) H1 over hits equals the true FRF within
    3 % at the resonances below 1.5 kHz, where the coherence over hits is above 0.99."""
    force, resp, truth = rc.examples.impact_test_case(seed=1, duration_s=2.0, noise_rms=1e-4)
    data = rc.estimate_frf_impact(force, resp, fs=FS, exp_window="auto")
    assert data.meta["exp_window_tau_s"] is None and data.meta["n_hits"] == 5
    peaks = [int(np.argmin(np.abs(data.f_hz - f))) for f in truth.f_hz if f < 1500]
    ref = truth.response(data.f_hz[peaks])
    np.testing.assert_allclose(data.response[peaks], ref, rtol=0.03)
    assert np.all(data.coherence[peaks] > 0.99)


def test_double_hit_and_overload_are_warned_naming_the_hit(hits):
    force, resp, _ = hits
    force, resp = force.copy(), resp.copy()
    start = int(np.argmax(force[2]))
    force[2, start + 200 : start + 202] = 0.5 * force[2].max()  # a second tap 24 ms later
    with pytest.warns(rc.ImpactWarning, match=r"double hit\(s\) in hit\(s\) \[2\]"):
        data = rc.estimate_frf_impact(force, resp, fs=FS)
    assert data.meta["double_hits"] == [2]
    top = 0.3 * np.abs(resp[4]).max()
    resp[4] = np.clip(resp[4], -top, top)  # a clipped accelerometer
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        rc.estimate_frf_impact(force, resp, fs=FS)
        rc.estimate_frf_impact(force, resp, fs=FS, force_range=0.5)
    messages = [str(w.message) for w in seen if issubclass(w.category, rc.ImpactWarning)]
    assert any("overload in hit(s) [4]" in m for m in messages)
    assert any("overload in hit(s) [0, 1, 2, 3, 4]" in m for m in messages)


def test_bad_impact_input_is_refused_with_the_fix(hits):
    force, resp, _ = hits
    with pytest.raises(rc.DataError, match="one response record per hit"):
        rc.estimate_frf_impact(force, resp[:3], fs=FS)
    with pytest.raises(rc.DataError, match="positive time constant"):
        rc.estimate_frf_impact(force, resp, fs=FS, exp_window=-0.1)
    with pytest.raises(rc.DataError, match="identically zero"):
        rc.estimate_frf_impact(np.zeros_like(force), resp, fs=FS)
    with pytest.warns(rc.ImpactWarning, match="1 hit"):
        rc.estimate_frf_impact(force[0], resp[0], fs=FS)
