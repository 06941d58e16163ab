"""Verdicts on data robustctl did not make: the corpus of ``tests/lab_corpus.py``.

The truths are numpy matrices, their responses exact steady states of measured forces and held
commands (random, periodic, impact), the estimates made by ``rc.estimate_frf`` told how the
data were made. The exact truth must be within the noise by default, through every file
format and the command line alike.
"""

import json
import sys
import textwrap
import warnings
from pathlib import Path

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import lab_corpus as lc  # noqa: E402

ALL = sorted(lc.CASES)


@pytest.fixture(scope="module")
def cases():
    return {name: lc.case(name) for name in ALL}


# ---------------------------------------------------------------------------- the corpus
@pytest.mark.parametrize("name", ALL)
def test_every_exact_truth_is_within_the_noise_by_default(cases, name):
    truth, data, desc = cases[name]
    st = lc.STRUCTURES[desc["key"]]()
    f = data.band(*desc["band"]).f_hz
    exact = st.frf(f)
    assert np.max(np.abs(np.log(truth.freqresp(f).response / exact))) < 1e-7  # the model is the truth
    assert data.experiment.input_kind == desc["input_kind"]
    assert data.experiment.excitation == desc["excitation"]
    cmp = rc.compare(truth, data, band=desc["band"])
    assert cmp.noise is not None and cmp.within_noise, cmp.summary()


def test_the_corpus_covers_measured_held_random_periodic_and_impact(cases):
    kinds = {(c.description["input_kind"], c.description["excitation"]) for c in cases.values()}
    assert {("measured", "random"), ("held", "random"), ("measured", "periodic"), ("held", "periodic"),
            ("measured", "impact")} <= kinds
    assert len({c.description["key"] for c in cases.values()}) == 5


def test_held_data_need_the_hold_and_random_data_the_leakage(cases):
    """The plain FRF of held commands misses the hold (far beyond the noise); a random estimate
    of lightly damped modes misses the leakage; what the description establishes restores both."""
    for name in ("frame_held_random", "hub_held_random", "beam_held_periodic"):
        truth, data, desc = cases[name]
        assert not rc.compare(truth, data, band=desc["band"], estimator=False).within_noise
    truth, data, desc = cases["mast_measured_random"]
    plain = rc.compare(truth, data, band=desc["band"], estimator=False)
    seen = rc.compare(truth, data, band=desc["band"])
    assert seen.cost < plain.cost and "window leakage" in seen.estimator_note


# ---------------------------------------------------------------------------- the view
def _chain():
    M = np.diag([1.0, 0.5])
    K = 1e4 * np.array([[3.0, -1.0], [-1.0, 1.0]])
    return rc.structural_model(M, K, inputs={"F": "dof 1"}, outputs={"a1": ("dof 1", "acceleration")},
                               damping=0.02)


def test_a_measured_force_is_not_divided_by_a_hold():
    """A driving-point accelerometer (a direct feedthrough) under a continuous white force: the
    old view (a white held input, divided by the hold) put the exact truth at J = 325; the
    measured view keeps D as D and leaves the truth within the noise, at the plain FRF's cost."""
    model = _chain()
    fs, n = 200.0, 2**17
    rng = np.random.default_rng(0)
    f = np.fft.rfftfreq(n, 1 / fs)
    U = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    U[0] = 0
    U[f >= 0.45 * fs] = 0
    Y = np.zeros_like(U)
    Y[1:] = model.freqresp(f[1:]).response[:, 0, 0] * U[1:]
    u, y = np.fft.irfft(U, n), np.fft.irfft(Y, n)
    y = y + 0.02 * np.std(y) * rng.standard_normal(n)
    data = rc.estimate_frf(u, y, fs=fs, nperseg=2048, inputs=["F"], outputs=["a1"])
    assert data.experiment.input_kind == "measured" and data.experiment.excitation == "random"
    seen = rc.compare(model, data, band=(1, 80))
    plain = rc.compare(model, data, band=(1, 80), estimator=False)
    held_view = rc.estimator.EstimatorSettings((fs, 2048, "hamming"), 1024, hold_divided=True)
    old = rc.compare(model, data, band=(1, 80), estimator=held_view)
    assert seen.within_noise and old.cost > 100 and not old.within_noise
    assert seen.cost == pytest.approx(plain.cost, rel=0.2)


@pytest.mark.parametrize("k_top", [1e4, 1e6])  # the second: a mode near 280 Hz, above Nyquist (100 Hz)
def test_the_measured_view_is_the_band_limited_response_through_the_lag_window(k_top):
    """Independent computation: the two-sided impulse response from the response itself on a
    2^20-point grid, through the Hamming lag window; the view's exact poles and alias sum agree,
    a direct feedthrough stays D and a mode above Nyquist is not aliased."""
    from robustctl.measure.estimator import EstimatorSettings, expected_h1_measured, lag_window

    M, K = np.diag([1.0, 0.5]), np.array([[3e4 + k_top, -k_top], [-k_top, k_top]])
    model = rc.structural_model(M, K, inputs={"F": "dof 1"},
                                outputs={"a1": ("dof 1", "acceleration"), "x2": ("dof 2", "displacement")},
                                damping=0.002)
    fs, n = 200.0, 512
    st = EstimatorSettings((fs, n, "hamming"), 256, input_kind="measured")
    f = np.arange(1, n // 2) * fs / n
    g = expected_h1_measured(model.statespace(), f, st)
    big = 2**20
    grid_f = np.arange(big // 2 + 1) * fs / big
    H = np.concatenate([model.freqresp([1e-6]).response.real, model.freqresp(grid_f[1:]).response])
    H[-1] = H[-1].real
    h = np.fft.irfft(H, big, axis=0)
    lag = lag_window("hamming", n)
    two = np.zeros((2 * n,) + h.shape[1:])
    two[:n] = h[:n] * lag[:, None, None]
    two[n + 1:] = h[big - n + 1:] * lag[:0:-1][:, None, None]
    ref = np.fft.fft(two, axis=0)[2 * np.arange(1, n // 2)]
    assert np.max(np.abs(np.log(g / ref))) < 1e-4
    assert np.max(np.abs(np.log(model.freqresp(f).response / ref))) > 0.5  # the leakage is real


def test_a_sampled_truth_is_evaluated_on_the_unit_circle_and_a_wrong_rate_refused(cases):
    truth, data, desc = cases["beam_held_periodic"]
    st = lc.two_span_beam()
    cont = control.ss(*st.state_space(), inputs=list(st.inputs), outputs=list(st.outputs))
    cmp = rc.compare(control.c2d(cont, 1 / 200.0, "zoh"), data, band=desc["band"])
    assert cmp.within_noise
    truth, data, desc = cases["frame_held_random"]
    fr = lc.frame_3d()
    cont = control.ss(*fr.state_space(), inputs=list(fr.inputs), outputs=list(fr.outputs))
    assert rc.compare(control.c2d(cont, 1 / 200.0, "zoh"), data, band=desc["band"]).within_noise
    with pytest.raises(rc.ModelError, match="sampled at 400 Hz .* the data were sampled at 200 Hz"):
        rc.compare(control.c2d(cont, 1 / 400.0, "zoh"), data, band=desc["band"])


def test_frequencies_in_rad_per_s_are_refused_or_warned(cases):
    truth, data, desc = cases["beam_held_periodic"]
    with pytest.raises(rc.DataError, match="beyond the Nyquist frequency 100 Hz .* rad/s"):
        rc.FrequencyData(data.f_hz * 2 * np.pi, data.response, experiment=data.experiment)
    with pytest.warns(UserWarning, match="bands are in Hz, not rad/s"):
        rc.compare(truth, data, band=(2 * np.pi * 2, 2 * np.pi * 90))


def test_a_fit_with_fewer_frequencies_than_parameters_is_refused(cases):
    truth, data, desc = cases["mast_measured_random"]
    with pytest.raises(rc.DataError, match="update fits 3 free parameters but the band .* 1 informative"):
        rc.update(truth, data, band=(10.0, 10.1))
    with pytest.raises(rc.DataError, match="diagnose .* holds 1 informative"):
        rc.diagnose(truth, data, [rc.effects.OutputDelay()], band=(10.0, 10.1))


def test_undescribed_data_are_compared_plainly_and_every_result_says_so(cases):
    truth, data, desc = cases["frame_held_random"]
    bare = rc.FrequencyData(data.f_hz, data.response, inputs=data.inputs, outputs=data.outputs,
                            coherence=data.coherence, meta=data.meta)
    assert bare.experiment == rc.Experiment()
    cmp = rc.compare(truth, bare, band=desc["band"])
    note = "compared as the plain FRF: the data do not say how they were estimated"
    assert cmp.estimator_note == note and "Compared as the plain FRF" in cmp.summary()
    np.testing.assert_allclose(cmp.cost, rc.compare(truth, data, band=desc["band"], estimator=False).cost)
    upd = rc.update(truth, bare, band=(5.0, 20.0), max_iter=1)
    assert upd.estimator_note == note


# ---------------------------------------------------------------------------- files and CLI
@pytest.mark.parametrize("name", ["frame_measured_random", "beam_held_periodic", "grid_impact"])
def test_every_file_format_gives_the_in_memory_verdict(cases, tmp_path, name):
    truth, data, desc = cases[name]
    ref = rc.compare(truth, data, band=desc["band"])
    for ext in ("npz", "csv", "uff", "mat"):
        back = rc.load_frd(data.save(tmp_path / f"d.{ext}"))
        assert back.experiment == data.experiment, ext
        cmp = rc.compare(truth, back, band=desc["band"])
        assert cmp.cost == pytest.approx(ref.cost, rel=1e-9), ext
        assert cmp.within_noise == ref.within_noise and cmp.estimator_note == ref.estimator_note, ext


MODEL_PY = textwrap.dedent(
    """
    import sys
    sys.path.insert(0, {tests!r})
    import lab_corpus

    model = lab_corpus.STRUCTURES[{key!r}]().model()
    """
)


def _cli_compare(tmp_path, key, path, band, *options):
    spec = tmp_path / f"{key}_model.py"
    spec.write_text(MODEL_PY.format(tests=str(Path(__file__).resolve().parents[1]), key=key))
    out = tmp_path / f"out_{path.suffix[1:]}"
    argv = ["compare", str(spec), str(path), "--band", str(band[0]), str(band[1]), "--out", str(out)]
    argv += list(options)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(argv) == 0
    return json.loads((out / "summary.json").read_text())


def test_the_command_line_gives_the_in_memory_verdict_and_describes_bare_files(cases, tmp_path):
    truth, data, desc = cases["hub_held_random"]
    ref = rc.compare(truth, data, band=desc["band"])
    for ext in ("uff", "csv"):
        summary = _cli_compare(tmp_path, "hub", data.save(tmp_path / f"hub.{ext}"), desc["band"])
        assert summary["cost"] == pytest.approx(ref.cost, rel=1e-9) and summary["within_noise"] is True
        assert summary["view"] == ref.estimator_note
    # a file that does not say how it was made: plain (beyond the noise), until the options say it
    bare = rc.FrequencyData(data.f_hz, data.response, inputs=data.inputs, outputs=data.outputs,
                            coherence=data.coherence)
    path = bare.save(tmp_path / "bare.csv")
    plain = _cli_compare(tmp_path, "hub", path, desc["band"])
    assert plain["within_noise"] is not True and plain["cost"] > 100 * ref.cost  # no hold, no noise model
    assert "do not say" in plain["view"]
    e = data.experiment
    told = _cli_compare(tmp_path, "hub", path, desc["band"], "--input-kind", "held", "--excitation", "random",
                        "--fs", "100", "--window", "hamming", "--nperseg", "1024", "--noverlap", "512",
                        "--n-averages", str(e.n_averages))
    assert told["within_noise"] is True and told["cost"] == pytest.approx(ref.cost, rel=1e-9)
    assert told["experiment"] == e.to_dict()
    spec = tmp_path / "hub_model.py"
    assert main(["compare", str(spec), str(data.save(tmp_path / "hub2.npz")), "--input-kind", "measured",
                 "--out", str(tmp_path / "x")]) == 2  # contradicts the file


# ---------------------------------------------------------------------------- the description
def test_the_experiment_description_is_checked_and_recorded_by_every_estimator():
    with pytest.raises(rc.DataError, match="input_kind must be one of"):
        rc.Experiment(input_kind="voltage")
    with pytest.raises(rc.DataError, match="noverlap .* must be smaller"):
        rc.Experiment(nperseg=8, noverlap=8)
    rng = np.random.default_rng(1)
    u, y = rng.standard_normal(4096), rng.standard_normal(4096)
    with pytest.raises(rc.DataError, match="whole_periods/period describe periodic"):
        rc.estimate_frf(u, y, 100.0, nperseg=256, period=128)
    d = rc.estimate_frf(u, y, 100.0, nperseg=256, excitation="periodic", period=128)
    assert d.experiment.whole_periods is True and d.experiment.input_kind == "measured"
    d96 = rc.estimate_frf(u, y, 100.0, nperseg=256, excitation="periodic", period=96)
    assert d96.experiment.whole_periods is False
    sys_ = control.ss([[0, 1], [-400.0, -2.0]], [[0], [1]], [[1, 0]], [[0]])
    uh, yh = rc.simulate_experiment(sys_, fs=100.0, n_samples=4096)
    assert isinstance(uh, rc.HeldCommand)
    assert rc.estimate_frf(uh, yh, 100.0, nperseg=256).experiment.input_kind == "held"
    told = rc.estimate_frf(uh, yh, 100.0, nperseg=256, input_kind="measured")
    assert told.experiment.input_kind == "measured"
    data, _ = rc.examples.make_experiment(_chain(), None, n_samples=8192, nperseg=512)
    assert data.experiment.input_kind == "held" and data.experiment.hold_divided
    hits = lc.impact_test(lc.plate_grid(), n_hits=4)
    assert hits.experiment.excitation == "impact" and hits.experiment.n_averages == 4


def test_the_noise_model_is_calibrated_on_few_averages(cases):
    """Eight hammer hits: with the plug-in coherence the squared normalised error of the exact
    truth has mean n / (n - 2) = 1.33 unless the two degrees of freedom are paid; paid, about 1."""
    truth, data, desc = cases["grid_impact"]
    band = data.band(*desc["band"])
    nm = rc.noise_model(band)
    assert nm.averages.tolist() == [8.0]
    z = rc.log_error(truth, band) / nm.sigma
    ratio = np.mean(np.abs(z) ** 2) / 2
    assert 0.85 < ratio < 1.15


@pytest.mark.parametrize(
    "experiment, applied, words",
    [
        (rc.Experiment(), None, "the data do not say how they were estimated"),
        (rc.Experiment("measured", "random", 200.0, "hann", 512), ("measured", True),
         "measured input (no hold)"),
        (rc.Experiment("held", "random", 200.0, "hann", 512), ("held", True), "512-pt hann at 200 Hz"),
        (rc.Experiment("held", "periodic", 200.0, "boxcar", 512, whole_periods=True), ("held", False),
         "sampled zero-order-hold response"),
        (rc.Experiment("measured", "periodic", 200.0, "boxcar", 512, whole_periods=True), None,
         "whole periods per segment has no window leakage; a measured input has no hold"),
        (rc.Experiment("measured", "periodic", 200.0, "boxcar", 512), None, "without whole periods"),
        (rc.Experiment("measured", "random", 200.0), None, "settings (fs, nperseg, window) are not stated"),
        (rc.Experiment(None, "random", 200.0, "hann", 512), ("measured", True), "input kind is not stated"),
        (rc.Experiment("measured", "impact", 256.0), None, "impact test without an exponential window"),
        (rc.Experiment("held", "stepped_sine", 100.0), ("held", False), "no window leakage"),
    ],
)
def test_the_view_applies_exactly_what_the_description_establishes(experiment, applied, words):
    settings, note = rc.estimator.experiment_view(experiment)
    if applied is None:
        assert settings is None and note.startswith("compared as the plain FRF")
    else:
        assert (settings.input_kind, settings.leakage) == applied and note.startswith("model seen through")
    assert words in note


def test_diagnose_names_an_added_mass_in_data_made_with_a_measured_force():
    """The mast with 6 kg added at its sixth mass, measured with a continuous random force: seen
    through the measured view, diagnose proposes that mass and its size."""
    st = lc.mast()

    def add_mass(M, K):
        M = M.copy()
        M[5, 5] += 6.0
        return M, K

    data = lc.measure(st, input_kind="measured", excitation="random", fs=100.0, nperseg=1024, modify=add_mass,
                      seed=1)
    diag = rc.diagnose(st.model(), data, band=(1.0, 40.0), time_budget_s=120)
    assert "measured input (no hold)" in diag.summary()
    best = diag.best_result
    assert best is not None and best.kind == "added_mass" and best.effect.location == "dof 6"
    assert best.significant
    assert next(iter(best.effect.values.values())) == pytest.approx(6.0, rel=0.03)


def test_the_sampling_frequency_is_fs_or_fs_hz():
    e = rc.Experiment(input_kind="measured", excitation="random", fs=200.0, window="hamming", nperseg=2048)
    assert e == rc.Experiment("measured", "random", 200.0, "hamming", 2048) and e.fs == e.fs_hz == 200.0
    assert rc.Experiment.from_dict({"fs": 50.0}).fs_hz == 50.0
    with pytest.raises(rc.DataError, match="give the sampling frequency once"):
        rc.Experiment(fs=100.0, fs_hz=200.0)
