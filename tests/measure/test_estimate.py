"""H1 Welch estimates, coherence, combine_experiments and simulated experiments."""

from __future__ import annotations

import warnings

import control
import numpy as np
import pytest
from scipy import signal

import robustctl as rc
from robustctl.errors import DataError, ModelError
from robustctl.lti import zoh as _zoh
from robustctl.measure.estimate import (
    BURN_IN_TOL,
    _final_state,
    _simulate_blocks,
    _simulate_loop,
    _simulate_modal,
)

FS = 200.0


def two_mode_system(zeta: float = 0.05, feedthrough: float = 1.0) -> control.StateSpace:
    """Two modes (5 and 15 Hz) seen by two velocity-like outputs plus a direct feedthrough."""
    A = np.zeros((4, 4))
    B = np.zeros((4, 1))
    C = np.zeros((2, 4))
    phi = np.array([[1.0, 0.6], [0.8, -1.0]])
    for i, (f, b) in enumerate(zip((5.0, 15.0), (1.0, 0.7))):
        w = 2 * np.pi * f
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[0, 1], [-w * w, -2 * zeta * w]]
        B[2 * i + 1, 0] = b
        C[:, 2 * i + 1] = phi[:, i] * 2 * zeta * w
    D = np.full((2, 1), feedthrough)
    return control.ss(A, B, C, D, inputs=["force"], outputs=["acc1", "acc2"])


def mimo_system(seed: int = 3) -> control.StateSpace:
    """A 2x2 modal system (modes 4, 9, 17 Hz, 5 % damping) with a feedthrough."""
    rng = np.random.default_rng(seed)
    freqs = (4.0, 9.0, 17.0)
    n = 2 * len(freqs)
    A = np.zeros((n, n))
    for i, f in enumerate(freqs):
        w = 2 * np.pi * f
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[0, 1], [-w * w, -0.1 * w]]
    B = np.zeros((n, 2))
    B[1::2] = rng.uniform(0.5, 1.5, (len(freqs), 2)) * 20
    C = np.zeros((2, n))
    C[:, 1::2] = rng.uniform(-1, 1, (2, len(freqs)))
    return control.ss(A, B, C, np.eye(2), inputs=["u1", "u2"], outputs=["y1", "y2"])


def zoh_response(sys: control.StateSpace, f_hz: np.ndarray) -> np.ndarray:
    """Exact response of the ZOH-sampled system (what a sampled experiment measures)."""
    sd = control.sample_system(sys, 1.0 / FS, "zoh")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        resp = control.frequency_response(sd, 2 * np.pi * f_hz)
    return np.transpose(np.asarray(resp.frdata), (2, 0, 1))


# ------------------------------------------------------------------ accuracy
def test_caltech_settings_two_mode_accuracy():
    sys = two_mode_system()
    u, y = rc.simulate_experiment(sys, noise_rms=0.003, seed=0)
    assert u.shape == (81920, 1) and y.shape == (81920, 2)
    data = rc.estimate_frf(u, y, fs=FS, inputs=["force"], outputs=["acc1", "acc2"])
    assert data.meta["n_averages"] == 39
    assert data.meta["nperseg"] == 4096 and data.meta["noverlap"] == 2048
    assert data.n_freq == 2048
    np.testing.assert_allclose(data.f_hz[[0, -1]], [FS / 4096, FS / 2])
    err = np.log(data.response / zoh_response(sys, data.f_hz))
    good = data.coherence > 0.99
    assert good.mean() > 0.9
    assert np.max(np.abs(err.real[good])) * 20 / np.log(10) < 0.2  # dB
    assert np.degrees(np.max(np.abs(err.imag[good]))) < 2.0


def test_matches_scipy_welch_siso():
    sys = two_mode_system(zeta=0.02, feedthrough=0.0)
    u, y = rc.simulate_experiment(sys, n_samples=16384, noise_rms=0.01, seed=4)
    data = rc.estimate_frf(u, y, fs=FS, nperseg=1024, noverlap=256, window="hann")
    _, puu = signal.welch(u[:, 0], FS, window="hann", nperseg=1024, noverlap=256)
    for o in range(2):
        _, puy = signal.csd(u[:, 0], y[:, o], FS, window="hann", nperseg=1024, noverlap=256)
        _, coh = signal.coherence(u[:, 0], y[:, o], FS, window="hann", nperseg=1024, noverlap=256)
        np.testing.assert_allclose(data.response[:, o, 0], puy[1:] / puu[1:], rtol=1e-10)
        np.testing.assert_allclose(data.coherence[:, o, 0], coh[1:], rtol=1e-9, atol=1e-12)
    assert data.meta["n_averages"] == 1 + (16384 - 1024) // 768


def test_mimo_h1_is_least_squares_over_segments():
    """H1 with several inputs = least-squares fit of Y_k = H U_k over the segments k."""
    sys = mimo_system()
    u, y = rc.simulate_experiment(sys, n_samples=8192, noise_rms=0.05, seed=1)
    nper, step = 512, 256
    data = rc.estimate_frf(u, y, fs=FS, nperseg=nper, window="hann")
    win = signal.get_window("hann", nper)
    starts = range(0, u.shape[0] - nper + 1, step)

    def ffts(x):
        return np.array([np.fft.rfft((x[s : s + nper] - x[s : s + nper].mean(0)) * win[:, None], axis=0)
                         for s in starts])

    U, Y = ffts(u), ffts(y)
    for k in (3, 40, 100, 200):
        Ht, *_ = np.linalg.lstsq(U[:, k, :], Y[:, k, :], rcond=None)
        np.testing.assert_allclose(data.response[k - 1], Ht.T, rtol=1e-9)
        resid = Y[:, k, :] - U[:, k, :] @ Ht
        # each channel's coherence sets its least-squares variance: var(H_oi) / |H_oi|^2 =
        # (1 - g2) / (n g2) with sum|resid_o|^2 [(U^H U)^-1]_ii = var(H_oi) n (partial coherence)
        inv = np.real(np.diag(np.linalg.inv(U[:, k, :].conj().T @ U[:, k, :])))
        var = np.sum(np.abs(resid) ** 2, axis=0)[:, None] * inv[None, :]  # (n_out, n_in)
        gamma2 = np.abs(Ht.T) ** 2 / (np.abs(Ht.T) ** 2 + var)
        np.testing.assert_allclose(data.coherence[k - 1], gamma2, rtol=1e-9)
    assert data.meta["coherence"] == "partial"


def test_simultaneous_and_one_at_a_time_agree_with_truth():
    sys = mimo_system()
    u, y = rc.simulate_experiment(sys, noise_rms=0.01, seed=5)
    mimo = rc.estimate_frf(u, y, fs=FS)
    parts = []
    for k in range(2):
        uk, yk = rc.simulate_experiment(sys, noise_rms=0.01, seed=10 + k, inputs=[k])
        parts.append(rc.estimate_frf(uk, yk, fs=FS, inputs=[f"u{k + 1}"]))
    simo = rc.combine_experiments(parts)
    assert simo.shape == mimo.shape and simo.inputs == ("u1", "u2")
    truth = zoh_response(sys, mimo.f_hz)
    band = (mimo.f_hz > 1) & (mimo.f_hz < 30)
    scale = np.abs(truth[band]).max(axis=0)
    for est in (mimo, simo):
        rel = np.abs(est.response[band] - truth[band]) / scale
        good = est.coherence[band] > 0.95  # leakage lowers the coherence at the resonance peaks
        assert np.median(rel) < 0.005 and rel[good].max() < 0.1


# ------------------------------------------------------------------ combine_experiments
def _siso(f, name="u1", outputs=("y1",), coh=True):
    g = np.ones((len(f), len(outputs), 1), complex)
    return rc.FrequencyData(f, g, inputs=[name], outputs=outputs, coherence=np.ones(g.shape) if coh else None)


def test_combine_checks_grids_names():
    f = np.arange(1.0, 6.0)
    both = rc.combine_experiments([_siso(f, "a"), _siso(f, "b", coh=False)])
    assert both.inputs == ("a", "b") and both.coherence is None
    with pytest.raises(DataError, match="different frequency grid"):
        rc.combine_experiments([_siso(f, "a"), _siso(f * 1.01, "b")])
    with pytest.raises(DataError, match=r"experiment 1.s outputs \[.y2.\] do not match the experiment 0.s"):
        rc.combine_experiments([_siso(f, "a"), _siso(f, "b", outputs=("y2",))])
    with pytest.raises(DataError, match="input names repeat"):
        rc.combine_experiments([_siso(f, "a"), _siso(f, "a")])
    with pytest.raises(DataError, match="at least one"):
        rc.combine_experiments([])
    with pytest.raises(DataError, match="not a FrequencyData"):
        rc.combine_experiments([_siso(f), np.ones(3)])


# ------------------------------------------------------------------ simulate_experiment
def test_simulation_is_exact_zoh():
    """After the random stationary start has decayed, y equals dlsim of the ZOH system from rest."""
    sys = two_mode_system(zeta=0.05, feedthrough=0.3)
    u, y = rc.simulate_experiment(sys, n_samples=12000, seed=7)
    sd = control.sample_system(sys, 1.0 / FS, "zoh")
    _, y_ref, _ = signal.dlsim((sd.A, sd.B, sd.C, sd.D, 1.0 / FS), u)
    np.testing.assert_allclose(y[6000:], y_ref[6000:], rtol=0, atol=1e-9 * np.abs(y_ref).max())
    assert np.abs(y[:50] - y_ref[:50]).max() > 1e-3  # started in the stationary state, not at rest


def test_modal_and_loop_simulations_agree():
    sys = mimo_system()
    A, B, C, D = (np.asarray(m) for m in (sys.A, sys.B, sys.C, sys.D))
    Ad, Bd = _zoh(A, B, 1 / FS)
    sd = control.sample_system(sys, 1.0 / FS, "zoh")
    np.testing.assert_allclose(Ad, sd.A, atol=1e-12)
    np.testing.assert_allclose(Bd, sd.B, atol=1e-12)
    rng = np.random.default_rng(0)
    u = rng.standard_normal((3000, 2))
    x0 = rng.standard_normal(A.shape[0])
    y1 = _simulate_modal(Ad, Bd, C, D, u, x0)
    y2 = _simulate_loop(Ad, Bd, C, D, u, x0)
    np.testing.assert_allclose(y1, y2, atol=1e-10 * np.abs(y2).max())


@pytest.mark.parametrize("n, p, m, N", [(6, 2, 1, 1000), (10, 3, 2, 777), (4, 1, 1, 5), (40, 28, 2, 3001)])
def test_block_simulation_is_the_recursion(n, p, m, N):
    """Blocks of Markov parameters and block-to-block states give the sample-by-sample
    recursion to round-off, for records shorter than a block and with a partial last block."""
    rng = np.random.default_rng(n + N)
    A = rng.standard_normal((n, n))
    A /= 1.05 * np.abs(np.linalg.eigvals(A)).max()
    B, C, D = rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m))
    u, x0 = rng.standard_normal((N, m)), rng.standard_normal(n)
    y_ref = _simulate_loop(A, B, C, D, u, x0)
    np.testing.assert_allclose(_simulate_blocks(A, B, C, D, u, x0), y_ref, rtol=0,
                               atol=1e-13 * np.abs(y_ref).max())
    _, y_scipy, _ = signal.dlsim((A, B, C, D, 1.0), u, x0=x0)  # an independent reference
    np.testing.assert_allclose(_simulate_blocks(A, B, C, D, u, x0), y_scipy.reshape(N, p), rtol=0,
                               atol=1e-12 * np.abs(y_scipy).max())
    x = x0.copy()
    for k in range(N):
        x = A @ x + B @ u[k]
    np.testing.assert_allclose(_final_state(A, B, u, x0), x, rtol=0, atol=1e-13 * np.abs(x).max())


def test_identical_filters_on_several_channels_give_one_record_in_any_basis():
    """Three equal filters of two lags 0.1 % apart behind one lightly damped mode: a repeated,
    nearly defective eigenvalue whose eigenvector matrix is ill-conditioned (the modal route's
    round-off is eps * cond, and its basis the BLAS kernel's choice). The records of the system
    and of a permuted realization agree to round-off (3e-15 of the peak here; the modal route
    left them 4e-13 apart)."""
    wn, zeta = 2 * np.pi * 3.0, 0.05
    plant = control.ss([[0, 1], [-wn**2, -2 * zeta * wn]], [[0], [1]], [[1, 0], [0.5, 0.1], [0.2, 1]], 0)
    lag = [control.tf([1.0], [1 / (2 * np.pi * f), 1]) for f in (40.0, 40.04)]
    filt = control.ss(lag[0] * lag[1])
    sys = control.append(filt, filt, filt) * plant
    perm = np.random.default_rng(3).permutation(sys.nstates)
    P = np.eye(sys.nstates)[perm]
    sys2 = control.ss(P @ sys.A @ P.T, P @ sys.B, sys.C @ P.T, sys.D)
    mu, V = np.linalg.eig(_zoh(np.asarray(sys.A), np.asarray(sys.B), 1 / FS)[0])
    assert 1e3 < np.linalg.cond(V) < 1e8  # the case takes the block route (the modal one before)
    _, y1 = rc.simulate_experiment(sys, n_samples=8192, seed=4)
    _, y2 = rc.simulate_experiment(sys2, n_samples=8192, seed=4)
    # the start's basis-dependent part weighs BURN_IN_TOL and decays within 4,096 samples
    np.testing.assert_allclose(y2, y1, rtol=0, atol=10 * BURN_IN_TOL * np.abs(y1).max())
    np.testing.assert_allclose(y2[4096:], y1[4096:], rtol=0, atol=3e-14 * np.abs(y1).max())


def test_defective_system_falls_back_and_is_exact():
    A = np.array([[-3.0, 1.0, 0.0], [0.0, -3.0, 1.0], [0.0, 0.0, -3.0]])  # Jordan block
    sys = control.ss(A, [[0], [0], [1]], [[1, 0, 0]], [[0]])
    Ad, Bd = _zoh(A, np.array([[0], [0], [1.0]]), 1 / FS)
    u, y = rc.simulate_experiment(sys, n_samples=4000, seed=2)
    sd = control.sample_system(sys, 1.0 / FS, "zoh")
    _, y_ref, _ = signal.dlsim((sd.A, sd.B, sd.C, sd.D, 1.0 / FS), u)
    np.testing.assert_allclose(y[2000:], y_ref[2000:], atol=1e-9 * np.abs(y_ref).max())
    assert Ad.shape == (3, 3)


def test_inputs_rms_and_noise():
    sys = mimo_system()
    u, y = rc.simulate_experiment(sys, n_samples=20000, input_rms=[2.0], seed=3, inputs=["u2"])
    assert u.shape == (20000, 1)
    assert abs(u.std() / 2.0 - 1) < 0.03
    u_ref, y_ref = rc.simulate_experiment(sys[:, 1], n_samples=20000, input_rms=2.0, seed=3)
    np.testing.assert_allclose(y, y_ref, rtol=1e-12, atol=1e-12)
    _, y_noisy = rc.simulate_experiment(
        sys, n_samples=20000, input_rms=[2.0], seed=3, inputs=[1], noise_rms=[0.1, 0.5]
    )
    np.testing.assert_allclose((y_noisy - y).std(axis=0), [0.1, 0.5], rtol=0.03)


def test_simulate_refuses_bad_input():
    sys = two_mode_system()
    with pytest.raises(ModelError, match="continuous-time"):
        rc.simulate_experiment(control.sample_system(sys, 0.01), n_samples=100)
    with pytest.raises(ModelError, match="unstable"):
        rc.simulate_experiment(control.ss([[0.5]], [[1]], [[1]], [[0]]), n_samples=100)
    with pytest.raises(DataError, match="fs must be positive and finite"):
        rc.simulate_experiment(sys, fs=-1.0)
    with pytest.raises(DataError, match="n_samples must be an integer"):
        rc.simulate_experiment(sys, n_samples=1.5)
    with pytest.raises(DataError, match="unknown input 'shaker'"):
        rc.simulate_experiment(sys, n_samples=100, inputs=["shaker"])
    with pytest.raises(DataError, match="noise_rms has 3 values for 2 channels"):
        rc.simulate_experiment(sys, n_samples=100, noise_rms=[0.1, 0.1, 0.1])
    with pytest.raises(DataError, match="input_rms must be finite and positive"):
        rc.simulate_experiment(sys, n_samples=100, input_rms=0.0)


# ------------------------------------------------------------------ estimate_frf bad input
@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(0)
    u = rng.standard_normal((5000, 1))
    return u, np.hstack([u, 2 * u + 0.1 * rng.standard_normal((5000, 1))])


def test_estimate_refuses_bad_input(record):
    u, y = record
    bad = u.copy()
    bad[10] = np.nan
    with pytest.raises(DataError, match="u contains NaN or inf .first at sample 10"):
        rc.estimate_frf(bad, y, FS, nperseg=256)
    bad = y.copy()
    bad[3, 1] = np.inf
    with pytest.raises(DataError, match="y contains NaN or inf"):
        rc.estimate_frf(u, bad, FS, nperseg=256)
    with pytest.raises(DataError, match="u has 5000 samples but y has 4999"):
        rc.estimate_frf(u, y[:-1], FS, nperseg=256)
    with pytest.raises(DataError, match=r"more channels than samples.*pass y\.T"):
        rc.estimate_frf(u, y.T, FS, nperseg=256)
    with pytest.raises(DataError, match=r"noverlap \(256\) must be smaller than nperseg \(256\)"):
        rc.estimate_frf(u, y, FS, nperseg=256, noverlap=256)
    with pytest.raises(DataError, match="shorter than one window"):
        rc.estimate_frf(u[:4000], y[:4000], FS)
    with pytest.raises(DataError, match="fs must be positive and finite"):
        rc.estimate_frf(u, y, 0.0, nperseg=256)
    with pytest.raises(DataError, match="complex"):
        rc.estimate_frf(u + 1j, y, FS, nperseg=256)
    with pytest.raises(DataError, match="outputs has 1 names"):
        rc.estimate_frf(u, y, FS, nperseg=256, outputs=["a"])
    with pytest.raises(DataError, match="unknown window"):
        rc.estimate_frf(u, y, FS, nperseg=256, window="nonsense")


def test_estimate_refuses_dependent_or_silent_inputs(record):
    u, y = record
    with pytest.raises(DataError, match="linearly dependent"):
        rc.estimate_frf(np.hstack([u, 3 * u]), y, FS, nperseg=256)
    with pytest.raises(DataError, match="'u2' carries no signal"):
        rc.estimate_frf(np.hstack([u, 0 * u]), y, FS, nperseg=256)
    with pytest.raises(DataError, match="need at least 3 averages"):
        rng = np.random.default_rng(1)
        rc.estimate_frf(rng.standard_normal((300, 3)), y[:300], FS, nperseg=256)


def test_estimate_siso_one_dimensional_and_names(record):
    u, y = record
    data = rc.estimate_frf(u[:, 0], y[:, 1], FS, nperseg=500, noverlap=0, inputs="F", outputs="a")
    assert data.inputs == ("F",) and data.outputs == ("a",)
    assert data.meta["n_averages"] == 10 and data.meta["coherence"] == "ordinary"
    assert np.allclose(data.response[:, 0, 0], 2.0, rtol=0.05)
