"""The noise model of an FRF estimate, the estimator's view of a model, units sanity."""

from __future__ import annotations

import warnings

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.measure.estimator import (
    EstimatorSettings,
    bin_correlation,
    effective_averages,
    estimator_settings,
    estimator_view,
    expected_h1,
    hold_response,
)
from robustctl.measure.noise import LEAKAGE_NOTE, averages_of, chi2_verdict, format_p

FS = 200.0


def _oscillator(f_n: float = 12.0, zeta: float = 0.05) -> control.StateSpace:
    wn = 2 * np.pi * f_n
    return control.ss([[0, 1], [-(wn**2), -2 * zeta * wn]], [[0], [1]], [[wn**2, 0]], [[0]])


# ---------------------------------------------------------------------------- the variance formula
def test_predicted_std_of_log_h1_matches_monte_carlo_of_estimate_frf():
    """B&P Table 9.6 with Welch's effective averages against 200 seeds of estimate_frf."""
    sys = _oscillator()
    n, k = 256, 16
    logs, sig = [], []
    for seed in range(200):
        u, y = rc.simulate_experiment(sys, fs=FS, n_samples=n * k, seed=seed, noise_rms=0.3)
        d = rc.estimate_frf(u, y, FS, nperseg=n)
        logs.append(np.log(d.response[:, 0, 0]))
        sig.append(rc.noise_model(d).sigma[:, 0, 0])
    logs, sig = np.array(logs), np.array(sig)
    predicted = np.sqrt(np.mean(sig**2, axis=0))
    observed_mag = logs.real.std(axis=0)
    observed_ph = np.angle(np.exp(1j * (logs.imag - logs.imag.mean(axis=0)))).std(axis=0)
    small = predicted < 0.2  # the formula's small-error regime (B&P: epsilon <= 0.2)
    assert small.sum() > 30
    for observed in (observed_mag, observed_ph):
        ratio = np.median(observed[small] / predicted[small])
        assert ratio == pytest.approx(1.0, abs=0.15)
    # the estimate records its averages and the model reads Welch's overlap correction
    assert d.meta["n_averages"] == 31 and d.meta["n_inputs"] == 1
    assert averages_of(d)[0] == pytest.approx(effective_averages(31, "hamming", n, n // 2))


def test_welch_effective_averages_against_the_closed_form():
    # Hann, 50 % overlap: overlap correlation c = 1/6 exactly (Harris 1978), K/(1 + 2 (1 - 1/K) c^2)
    for k in (2, 10, 39):
        expected = k / (1 + 2 * (1 - 1 / k) * (1 / 6) ** 2)
        assert effective_averages(k, "hann", 4096, 2048) == pytest.approx(expected, rel=2e-3)
    assert effective_averages(10, "hann", 512, 0) == 10.0  # no overlap: independent segments
    # Hamming bins one apart: |rho_1|^2 with rho_1 = 0.2484 / 0.3974 (w^2's Fourier series)
    assert bin_correlation("hamming", 4096)[1] == pytest.approx((0.2484 / 0.3974) ** 2, rel=2e-3)


def test_averages_survive_combine_band_select_and_save(tmp_path):
    data, _ = rc.examples.make_experiment(_chain(), None, noise_rms=0.01, n_samples=8192, nperseg=512)
    nd = averages_of(data)
    assert nd.shape == (2,) and np.all(nd > 20)
    part = data.band(1.0, 20.0).select(outputs=["v3"], inputs=["F3"])
    assert averages_of(part) == pytest.approx(nd[1:])
    path = data.save(tmp_path / "d.npz")
    back = rc.load_frd(path)
    np.testing.assert_allclose(rc.noise_model(back).sigma, rc.noise_model(data).sigma)
    assert estimator_settings(back.meta) == estimator_settings(data.meta)
    assert estimator_settings(back.meta).hold_divided


def test_noise_model_sources_and_refusals():
    sys = _oscillator()
    u, y = rc.simulate_experiment(sys, fs=FS, n_samples=8192, noise_rms=0.1)
    d = rc.estimate_frf(u, y, FS, nperseg=512)
    nm = rc.noise_model(d)
    assert "coherence" in nm.source and nm.kind == "coherence" and nm.dof_factor > 1.2
    bare = d.replace(coherence=None)
    assert rc.noise_model(bare) is None
    mm = rc.fit_measurement_model(bare, n_modes=1, band=(2.0, 40.0))
    res = rc.noise_model(bare.band(2.0, 40.0), measurement_model=mm)
    assert res.source == "noise estimated from the residual of a 1-mode measurement model" + LEAKAGE_NOTE
    # a user's file without the Welch settings: the residual's scale alone, below it at the peak
    alone = rc.noise_model(rc.FrequencyData(d.f_hz, d.response).band(2.0, 40.0), measurement_model=mm)
    assert alone.source == "noise estimated from the residual of a 1-mode measurement model"
    assert np.all(res.sigma >= alone.sigma) and np.max(res.sigma / alone.sigma) > 1.05
    # coherence without recorded averages: only an explicit n_averages makes a model
    plain = rc.FrequencyData(d.f_hz, d.response, coherence=d.coherence)
    assert rc.noise_model(plain) is None
    np.testing.assert_allclose(rc.noise_model(plain, n_averages=averages_of(d)).sigma, nm.sigma)
    with pytest.raises(rc.DataError, match="n_averages"):
        rc.noise_model(plain, n_averages=0)
    with pytest.raises(rc.DataError, match="sigma"):
        rc.NoiseModel(d.f_hz, np.zeros(d.n_freq), "zero")


def test_p_values_are_bounds_never_zero():
    assert format_p(0.0) == "p < 1e-300"
    assert format_p(1e-320) == "p < 1e-300"
    assert format_p(3e-7) == "p = 3.0e-07"
    assert format_p(0.25) == "p = 0.25"
    # chi-square of pure unit noise: ratio near 1, p uniform-ish; of 3x the noise: p tiny
    rng = np.random.default_rng(0)
    z = rng.standard_normal(500) + 1j * rng.standard_normal(500)
    ratio, dof, p = chi2_verdict(z, 1.0)
    assert ratio == pytest.approx(1.0, abs=0.15) and dof == 1000 and p > 0.01
    assert chi2_verdict(3 * z, 1.0)[2] < 1e-100


# ---------------------------------------------------------------------------- estimator view
def test_expected_h1_of_a_state_space_matches_the_step_by_step_sampling_and_the_rational_fit():
    from robustctl.identify import expected_h1 as fit_expected_h1
    from robustctl.identify import fit_rational
    from robustctl.measure.estimator import _zoh_impulse_loop
    from robustctl.measure.estimator import windowed_spectrum as _spectrum

    sys = _oscillator(7.0, 0.01)
    st = EstimatorSettings((FS, 1024, "hamming"), 512)
    f = np.arange(1, 512) * FS / 1024
    g = expected_h1(sys, f, st)
    loop = _spectrum(_zoh_impulse_loop(sys, FS, 1024), f, st)
    np.testing.assert_allclose(g, loop, rtol=1e-9, atol=1e-12 * np.abs(loop).max())
    fit = fit_rational(rc.freqresp(sys, f), order=2)
    np.testing.assert_allclose(fit_expected_h1(fit, f, st), g, rtol=1e-4, atol=1e-6 * np.abs(g).max())
    # the mean of many H1 estimates is the expected H1 (leakage broadens the 1 %-damped peak)
    mean = np.mean([rc.estimate_frf(*rc.simulate_experiment(sys, FS, 1024 * 20, seed=s), FS,
                                    nperseg=1024).response[:-1] for s in range(16)], axis=0)
    near = np.abs(f - 7.0) < 0.6
    plain = rc.freqresp(sys, f).response
    err_view = np.median(np.abs(np.log(mean[near] / g[near])))
    err_plain = np.median(np.abs(np.log(mean[near] / plain[near])))
    assert err_plain > 0.1 and err_view < 0.3 * err_plain  # the bias is real, and the view has it


def test_the_view_removes_the_hold_and_a_deliberate_hold_stage_is_sampled_exactly():
    model = _chain()
    st = EstimatorSettings((FS, 1024, "hamming"), 512)
    f = np.arange(3, 200) * FS / 1024
    bare = expected_h1(model.statespace(), f, st)
    view = estimator_view(model.statespace(), f, st)
    np.testing.assert_allclose(view, bare / hold_response(f, FS)[:, None, None])
    # the rational hold stage agrees with (1 - e^{-sT}) / (sT) to 1e-5 up to fs / 3
    g = rc.freqresp(rc.electronics.zero_order_hold(FS, 4), f).response[:, 0, 0]
    assert np.max(np.abs(np.log(g / hold_response(f, FS)))) < 1e-4
    held = model.add_io_stage(rc.electronics.zero_order_hold_stage(model.inputs, FS))
    described = rc.Experiment(input_kind="held", excitation="random", fs_hz=FS, nperseg=1024,
                              window="hamming")
    res = rc.Residual(held, rc.FrequencyData(f, bare, inputs=model.inputs, outputs=model.outputs,
                                             experiment=described))
    np.testing.assert_allclose(res.model_response(), bare, rtol=1e-10)
    assert res.describe_estimator() == "model seen through the H1 estimator: 1024-pt hamming at 200 Hz"
    # the same settings without the description: the plain FRF, and the result says so
    plain = rc.Residual(held, rc.FrequencyData(f, bare, inputs=model.inputs, outputs=model.outputs,
                                               meta={"fs_hz": FS, "nperseg": 1024, "window": "hamming"}))
    np.testing.assert_allclose(plain.model_response(), held.freqresp(f).response, rtol=1e-12)
    assert plain.describe_estimator() == rc.frd.PLAIN_NOTE


# ---------------------------------------------------------------------------- units sanity
def test_magnitude_only_and_db_data_are_refused():
    model = _chain()
    g = model.freqresp(np.linspace(1, 30, 50))
    mag = g.replace(response=np.abs(g.response))
    db = g.replace(response=20 * np.log10(np.abs(g.response)))
    for bad, words in ((mag, "magnitude without phase"), (db, "dB")):
        for call in (lambda d: rc.compare(model, d), lambda d: rc.update(model, d),
                     lambda d: rc.diagnose(model, d, [rc.effects.SensorGain("v3")])):
            with pytest.raises(rc.DataError, match=words):
                call(bad)


def test_a_units_slip_of_two_pi_is_warned():
    model = _chain()
    f = np.linspace(0.3, 60.0, 600)
    g = model.freqresp(f).response
    slipped = rc.FrequencyData(f * 2 * np.pi, g, inputs=model.inputs, outputs=model.outputs)
    with pytest.warns(UserWarning, match="2 pi"):
        cmp = rc.compare(model, slipped)
    assert any("2 pi" in w for w in cmp.warnings) and "2 pi" in cmp.summary()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rc.compare(model, model.freqresp(f))  # right units: no warning


def test_modes_moved_by_a_parameter_error_are_no_units_slip():
    """Every mode 19 % high (a stiffness 42 % off) and two of them pairing with the model's at
    2 pi by chance: the scale 1.19 pairs all four, so no units slip is claimed."""
    fm = np.array([1.0, 2.0, 5.3, 10.6])
    shapes = np.array([[1.0, -0.8, 0.6, 0.5]])

    def modal(f):
        return rc.modal_model(f, 0.02, shapes, shapes, inputs=["F"], outputs=["a"])

    model, truth = modal(fm), modal(1.19 * fm)
    assert sum(np.any(np.abs(np.log(1.19 * fm / (2 * np.pi * x))) < 0.05) for x in fm) == 2
    f = np.linspace(0.3, 30.0, 2000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cmp = rc.compare(model, truth.freqresp(f))
    assert not any("2 pi" in w for w in cmp.warnings)
    assert len(cmp.data_modes) == 4  # the data's modes were found: the check had material


def test_a_dense_model_spectrum_above_the_band_is_no_units_slip():
    """A frame's model has many modes above the band (searched up to 8 x its top): at 2 pi each
    data mode finds one there by density alone. With every mode 22 % high the scale 1.22 pairs
    as many data modes, so no units slip is claimed."""
    fm = np.concatenate([[5.0, 8.5, 14.0, 20.0], np.geomspace(40.0, 400.0, 80)])
    rng = np.random.default_rng(0)
    shapes = rng.uniform(0.3, 1.0, (1, fm.size)) * np.where(np.arange(fm.size) < 4, 1.0, 0.2)

    def modal(f):
        return rc.modal_model(f, 0.02, shapes, shapes, inputs=["F"], outputs=["a"])

    model, truth = modal(fm), modal(1.22 * fm)
    f = np.linspace(1.0, 30.0, 3000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cmp = rc.compare(model, truth.freqresp(f))
    assert not any("2 pi" in w for w in cmp.warnings)
    assert len(cmp.data_modes) == 4


# ---------------------------------------------------------------------------- helpers
def _chain() -> rc.PhysicalModel:
    """Three masses on a grounded spring, forces at dofs 1 and 3, velocity sensors at 2 and 3."""
    m3 = np.diag([2.0, 1.0, 0.5])
    kc = 1e3 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    k_par = rc.Parameter("k_ground", 4e3, "N/m", (1e3, 1e4), meaning="ground spring of mass 1")
    return rc.structural_model(
        m3, lambda th: kc + np.diag([th["k_ground"], 0.0, 0.0]),
        inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"v2": ("dof 2", "velocity"), "v3": ("dof 3", "velocity")},
        damping=0.02, params=[k_par], name="3-mass chain",
    )


def test_the_noise_model_of_a_simultaneous_mimo_estimate_fits_each_channels_scatter():
    """Two simultaneous inputs, one weak cross channel: its H1 error is set by the noise
    relative to that input's own contribution (partial coherence), not by the output's
    multiple coherence (0.999, which put its sigma 5 x too low). The normalised residual of
    every channel scatters with RMS about 1."""
    K = 1e3 * np.array([[3.0, -0.2], [-0.2, 1.0]])
    model = rc.structural_model(np.diag([1.0, 0.5]), K, inputs={"F1": "dof 1", "F2": "dof 2"},
                                outputs={"a1": ("dof 1", "acceleration"), "a2": ("dof 2", "acceleration")},
                                damping=0.03)
    data, truth = rc.examples.make_experiment(model, noise_rms=0.02, seed=4, n_samples=40960, nperseg=1024,
                                              simultaneous=True, band=(1.0, 40.0))
    assert data.meta["coherence"] == "partial"
    noise = rc.noise_model(data)
    from robustctl.measure.estimator import estimator_settings, estimator_view

    seen = estimator_view(truth.statespace(), data.f_hz, estimator_settings(data.meta))  # as compare does
    e = np.log(data.response / seen)
    z = np.concatenate([(e.real / noise.sigma)[..., None], (e.imag / noise.sigma)[..., None]], axis=-1)
    rms = np.sqrt(np.mean(z**2, axis=(0, 3)))  # per channel (n_out, n_in)
    np.testing.assert_allclose(rms, 1.0, atol=0.25)
    # the cross channels are the weak ones: their coherence is visibly below the direct ones'
    assert np.median(data.coherence[:, 0, 1]) < np.median(data.coherence[:, 0, 0])


# ---------------------------------------------------------------------------- placeholder coherence
def _numpy_h1(noise: float = 0.05, seed: int = 0) -> tuple[rc.FrequencyData, int]:
    """A SIMO H1 estimate made with scipy alone (two filtered outputs of one random input, 50 %
    overlapped Hann segments) and its number of averages."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    n, nper = 2**15, 512
    u = rng.standard_normal(n)
    y = np.stack([signal.lfilter(*signal.butter(2, [0.1, 0.2], "bandpass"), u),
                  signal.lfilter(*signal.butter(2, 0.3), u)], axis=1)
    y += noise * y.std(axis=0) * rng.standard_normal(y.shape)
    f, puu = signal.welch(u, FS, nperseg=nper)
    g, coh = [], []
    for k in range(2):
        _, puy = signal.csd(u, y[:, k], FS, nperseg=nper)
        _, pyy = signal.welch(y[:, k], FS, nperseg=nper)
        g.append(puy / puu)
        coh.append(np.abs(puy) ** 2 / (puu * pyy))
    keep = slice(1, None)  # no DC
    g = np.stack(g, axis=1)[keep, :, None]
    coh = np.clip(np.stack(coh, axis=1)[keep, :, None], 0.0, 1.0)
    data = rc.FrequencyData(f[keep], g, inputs=["u"], outputs=["y1", "y2"], coherence=coh)
    return data, 2 * n // nper - 1


def test_coherence_of_one_or_zero_everywhere_is_a_placeholder_not_an_estimate():
    """Coherence 1 at every point would make the H1 random error 0 (a truth 1e6 x 'beyond the
    noise'); coherence 0 everywhere is a channel of noise. Both are warned; a channel of ones is
    not tested, ones everywhere give no noise model; a real estimate is not flagged."""
    data, n_avg = _numpy_h1()
    with warnings.catch_warnings():
        warnings.simplefilter("error", rc.DataWarning)
        nm = rc.noise_model(data, n_averages=n_avg)  # a real estimate: no warning
        assert rc.noise_model(_numpy_h1(noise=1e-4)[0], n_averages=n_avg) is not None
    assert nm.testable[:, 0, 0].sum() > 100 and nm.testable[:, 1, 0].sum() > 100
    coh = np.array(data.coherence)
    coh[:, 0, 0] = 1.0
    with pytest.warns(rc.DataWarning, match=r"coherence is 1 at every point of y1 <- u: a placeholder"):
        one = rc.noise_model(data.replace(coherence=coh), n_averages=n_avg)
    assert not one.testable[:, 0, 0].any()
    np.testing.assert_array_equal(one.testable[:, 1, 0], nm.testable[:, 1, 0])
    with pytest.warns(rc.DataWarning, match="coherence is 1 at every point of every channel"):
        assert rc.noise_model(data.replace(coherence=np.ones(data.shape)), n_averages=n_avg) is None
    coh = np.array(data.coherence)
    coh[:, 1, 0] = 0.0
    with pytest.warns(rc.DataWarning, match=r"coherence is 0 at every point of y2 <- u"):
        zero = rc.noise_model(data.replace(coherence=coh), n_averages=n_avg)
    assert not zero.testable[:, 1, 0].any()
