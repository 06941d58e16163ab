"""Reference checks of the measured-input view's fast paths (robustctl/measure/estimator.py): the
closed-form decomposition of a second-order modal state space and the power series of poles far
above the Nyquist frequency give what the dense eigendecomposition and the per-pole grid give."""

import numpy as np
import pytest
import satellite_corpus as sc

from robustctl.measure import estimator as est


@pytest.fixture(scope="module")
def satellite_ss():
    return sc.nominal_model().statespace()


def test_second_order_modal_form_matches_the_dense_eigendecomposition(satellite_ss):
    A, B, C = (np.asarray(m, dtype=float) for m in (satellite_ss.A, satellite_ss.B, satellite_ss.C))
    poles, res = est._second_order_modal(A, B, C)
    lam, V = np.linalg.eig(A)
    ref = np.einsum("ok,ki->koi", C @ V, np.linalg.solve(V, B.astype(complex)))
    # pair each closed-form pole with the nearest dense one; residues agree to round-off
    for p, r in zip(poles, res):
        k = int(np.argmin(np.abs(lam - p)))
        assert abs(lam[k] - p) <= 1e-9 * abs(p)
        assert np.max(np.abs(ref[k] - r)) <= 1e-7 * np.max(np.abs(r)) + 1e-12
    # another form (a similarity transform) is not mistaken for it
    T = np.eye(A.shape[0]) + 0.01 * np.tri(A.shape[0], k=-1)
    assert est._second_order_modal(np.linalg.solve(T, A @ T), np.linalg.solve(T, B), C @ T) is None


def test_far_pole_series_matches_the_grid_it_replaces(satellite_ss, monkeypatch):
    data = sc.measure(()).data
    settings, _ = est.experiment_view(data.experiment, data.meta)
    monkeypatch.setattr(est, "_SMOOTH_ENDS", -1.0)  # the grid path, whatever the window
    est._lag_curvature.cache_clear()
    fast = est.expected_h1_measured(satellite_ss, data.f_hz, settings)
    monkeypatch.setattr(est, "_FAR_POLE", np.inf)
    monkeypatch.setattr(est, "_second_order_modal", lambda A, B, C: None)
    slow = est.expected_h1_measured(satellite_ss, data.f_hz, settings)
    est._lag_curvature.cache_clear()
    assert np.max(np.abs(fast - slow)) <= 1e-11 * np.max(np.abs(slow))
    # and the view differs from the plain FRF by the leakage it models (the check can fail)
    g = sc.truth_frf(data.f_hz)
    assert np.max(np.abs(fast - g)) > 1e-3 * np.max(np.abs(g))


def test_local_form_of_a_smooth_window_matches_the_grid(satellite_ss, monkeypatch):
    """Hann: the alias sums and the poles above Nyquist seen through the lag window as S + c2 S''
    at the frequencies themselves agree with the 8N-point grid path to round-off; Hamming (ends not
    zero: a kink of the lag window at lag 0) keeps the grid."""
    data = sc.measure(()).data
    settings, _ = est.experiment_view(data.experiment, data.meta)
    assert settings.window == "hann"
    assert est._lag_curvature("hann", 4096) == pytest.approx(2 * np.pi**2 / (3 * 4096**2), rel=1e-5)
    assert est._lag_curvature("hamming", 4096) is None
    local = est.expected_h1_measured(satellite_ss, data.f_hz, settings)
    monkeypatch.setattr(est, "_SMOOTH_ENDS", -1.0)
    est._lag_curvature.cache_clear()
    try:
        grid = est.expected_h1_measured(satellite_ss, data.f_hz, settings)
    finally:
        est._lag_curvature.cache_clear()
    assert np.max(np.abs(local - grid)) <= 1e-11 * np.max(np.abs(grid))
    assert np.max(np.abs(local - grid) / np.abs(grid)) <= 1e-9


@pytest.mark.parametrize("k_top", [1e4, 1e6])  # the second: a mode near 280 Hz, above Nyquist (100 Hz)
def test_local_form_is_the_band_limited_response_through_the_hann_lag_window(k_top):
    """Independent computation: the two-sided impulse response from the response itself on a 2^20-point
    grid through the Hann lag window (numpy), against the local form on the bins below 0.9 Nyquist."""
    M, K = np.diag([1.0, 0.5]), np.array([[3e4 + k_top, -k_top], [-k_top, k_top]])
    w2, phi = np.linalg.eigh(np.linalg.solve(np.sqrt(M), np.linalg.solve(np.sqrt(M), K).T))
    phi = np.linalg.solve(np.sqrt(M), phi)  # mass-normalised
    zeta, fs, n = 0.002, 200.0, 512
    wn = np.sqrt(w2)
    b, c = phi.T @ np.array([1.0, 0.0]), phi  # force at dof 1; displacements of both dofs

    def frf(f):
        s = 2j * np.pi * np.asarray(f)[:, None]
        return np.einsum("om,fm,m->fo", c, 1.0 / (s**2 + 2 * zeta * wn * s + w2), b)[:, :, None]

    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.diag(w2), -np.diag(2 * zeta * wn)]])
    sys = (A, np.vstack([np.zeros((2, 1)), b[:, None]]), np.hstack([c, np.zeros((2, 2))]), np.zeros((2, 1)))
    import control

    st = est.EstimatorSettings((fs, n, "hann"), 256, input_kind="measured")
    f = np.arange(1, int(0.9 * n / 2)) * fs / n
    g = est.expected_h1_measured(control.ss(*sys), f, st)
    big = 2**20
    grid_f = np.arange(big // 2 + 1) * fs / big
    H = np.concatenate([frf([1e-6]).real, frf(grid_f[1:])])
    H[-1] = H[-1].real
    h = np.fft.irfft(H, big, axis=0)
    w = np.hanning(n + 1)[:n]  # the periodic Hann window
    r = np.correlate(w, w, "full")[n - 1:]
    lag = r / r[0]
    two = np.zeros((2 * n,) + h.shape[1:])
    two[:n] = h[:n] * lag[:, None, None]
    two[n + 1:] = h[big - n + 1:] * lag[:0:-1][:, None, None]
    ref = np.fft.fft(two, axis=0)[2 * np.arange(1, f.size + 1)]
    assert np.max(np.abs(np.log(g / ref))) < 1e-6
    assert np.max(np.abs(np.log(frf(f) / ref))) > 0.05  # the leakage is real


@pytest.mark.parametrize("n", [2, 3, 64])
def test_zoh_impulse_sum_of_poles_matches_stepping_the_sampled_state_space(n):
    """The pole-residue ZOH impulse response (running powers of each pole) against stepping
    ``x[k+1] = Ad x[k]`` of the exact ZOH discretisation: two lightly damped modes, a real pole
    and a 2 x 2 feedthrough, at the shortest lengths (no running product, one step) and at 64."""
    import control

    w1, w2 = 2 * np.pi * 3.0, 2 * np.pi * 11.0
    A = np.zeros((5, 5))
    A[0, 1] = A[2, 3] = 1.0
    A[1, :2] = [-(w1**2), -0.04 * w1]
    A[3, 2:4] = [-(w2**2), -0.02 * w2]
    A[4, 4] = -30.0
    B = np.array([[0, 0], [1, 0.5], [0, 0], [0.3, 1], [1, 1]])
    C = np.array([[w1**2, 0, 0.5 * w2**2, 0, 2.0], [0, 1.0, w2**2, 0, -1.0]])
    D = np.array([[0.1, 0.0], [0.0, -0.2]])
    sys = control.ss(A, B, C, D)
    poles, res, d = est._modal(sys)
    h = est._zoh_impulse_modal(poles, res, d, 100.0, n)
    ref = est._zoh_impulse_loop(sys, 100.0, n)
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
