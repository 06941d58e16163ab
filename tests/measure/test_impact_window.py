"""Impact tests as a laboratory runs them: the exponential and force windows in the experiment
description, the model seen through them, and the per-channel decay check.

The hammer data are written here with numpy/scipy, not with robustctl's simulator: the 10-mass
mast of ``tests/lab_corpus.py`` (a numpy truth, 1 % modal damping, modes 2.0-28.7 Hz) struck at
its tip by half-sine pulses (10 ms) at random times; each mode's response to the pulse in closed
form (``J`` below) on a 16x finer grid, a causal linear-phase FIR anti-aliasing filter on force
and responses (scipy), sampled at 256 Hz in 4 s records in which the first modes still ring, then
white noise (0.05 % of the peak force, 1 % of each response's rms).
"""

from __future__ import annotations

import json
import pickle
import warnings
from pathlib import Path

import control
import lab_corpus as lc
import numpy as np
import pytest
from scipy.signal import firwin, lfilter

import robustctl as rc
from robustctl.cli import main
from robustctl.measure.estimator import impact_settings
from robustctl.measure.impact import ringing_channels
from robustctl.measure.impact_view import (
    exp_window_correlation,
    expected_h1_impact_modal,
    record_tails,
    truncation_settings,
)
from robustctl.measure.noise import noise_model

FS = 256.0
BAND = (1.0, 80.0)


def _pulse_response(poles, weights, d, t, start, width, amp):
    """Exact response ``sum_p w_p int exp(p (t - u)) f(u) du + d f(t)`` to ``f = amp sin(pi (t -
    start) / width)`` on ``[start, start + width]``: with ``a = pi / width`` and ``v = t - start``,
    ``(a e^{pv} - a cos av - p sin av) / (a^2 + p^2)`` during the pulse and ``a (e^{pv} +
    e^{p (v - width)}) / (a^2 + p^2)`` after it (solutions of ``J' = p J + sin(a v)``, ``J(0) = 0``)."""
    a = np.pi / width
    v = np.clip(t - start, 0.0, None)[:, None]
    p = poles[None, :]
    during = (a * np.exp(p * v) - a * np.cos(a * v) - p * np.sin(a * v)) / (a**2 + p**2)
    after = a * (np.exp(p * v) + np.exp(p * (v - width))) / (a**2 + p**2)
    J = np.where(v <= width, during, after) * (t >= start)[:, None]
    f = np.where((t >= start) & (t <= start + width), amp * np.sin(a * np.clip(t - start, 0, width)), 0.0)
    return f, amp * np.real(J @ weights.T) + f[:, None] * d[None, :]


def hammer(structure, *, n=1024, n_hits=6, width=0.01, over=16, noise=(5e-4, 0.01), seed=0, modify=None):
    """Force (n_hits, n) and responses (n_hits, n, n_out) of hammer hits on the first input."""
    A, B, C, D = structure.state_space(modify=modify)
    lam, V = np.linalg.eig(A)
    weights = (C @ V) * np.linalg.solve(V, B[:, 0])[None, :]  # (n_out, n_modes)
    rng = np.random.default_rng(seed)
    t = np.arange(n * over) / (FS * over)
    taps = firwin(20 * over + 1, 0.8 / over)  # anti-aliasing: causal, linear phase, 0.8 x Nyquist
    forces, responses = [], []
    for _ in range(n_hits):
        f, y = _pulse_response(lam, weights, D[:, 0], t, 0.05 + rng.uniform(0, 0.01), width,
                               100.0 * (1 + 0.2 * rng.standard_normal()))
        forces.append(lfilter(taps, 1.0, f)[::over])
        responses.append(lfilter(taps, 1.0, y, axis=0)[::over])
    F, Y = np.array(forces), np.array(responses)
    F += noise[0] * np.max(np.abs(F[0])) * rng.standard_normal(F.shape)
    Y += noise[1] * np.std(Y[0], axis=0) * rng.standard_normal(Y.shape)
    return F, Y


def _mass(dof, kg):
    def modify(M, K):
        M = M.copy()
        M[dof, dof] += kg
        return M, K

    return modify


@pytest.fixture(scope="module")
def mast():
    return lc.mast()


def _estimate(structure, **kw):
    F, Y = hammer(structure, **kw)
    return rc.estimate_frf_impact(F, Y, FS, inputs=list(structure.inputs), outputs=list(structure.outputs))


@pytest.fixture(scope="module")
def null_data(mast):
    return _estimate(mast, seed=3)


def test_the_window_is_recorded_as_numbers_in_the_experiment(null_data):
    """'auto' windows are recorded as the numbers used: tau = (T - t_hit) / ln 100 for the
    latest hit (the window falls to 1 % at the record end), and a force window in s."""
    e, meta = null_data.experiment, null_data.meta
    assert e.excitation == "impact" and e.input_kind == "measured" and e.n_averages == 6
    start = int(np.ceil((0.05 + 0.01) * FS))  # no hit starts later than 60 ms (+ filter delay)
    assert e.exp_window_tau_s == meta["exp_window_tau_s"]
    assert 4.0 / np.log(100) * 0.95 < e.exp_window_tau_s < (1024 - start) / FS / np.log(100) + 0.01
    assert isinstance(meta["force_window_s"], float) and meta["force_window_s"] == e.force_window_s
    assert 4 / FS <= e.force_window_s < 0.2
    assert meta["ringing_channels"] == [0, 1, 2]  # the 2 Hz mode keeps 78 % after 4 s


def test_exact_truth_is_within_the_noise_only_as_the_windowed_estimator_sees_it(mast, null_data):
    """Compared at s + 1/tau with the record end (eq. W2), the exact truth is within the noise;
    compared as the plain FRF (the state before), the window's damping is far beyond it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        seen = rc.compare(mast.model(), null_data, band=BAND)
        plain = rc.compare(mast.model(), null_data, band=BAND, estimator=False)
    assert seen.within_noise, seen.summary()
    assert "exponential window" in seen.estimator_note
    assert plain.within_noise is False
    assert plain.cost > 20 * seen.cost
    paired = [m for m in seen.modes if np.isfinite(m.f_model) and np.isfinite(m.f_data)]
    assert len(paired) >= 5 and all(abs(m.f_data / m.f_model - 1) < 2e-3 for m in paired)


def test_diagnose_proposes_nothing_for_the_exact_truth(mast, null_data):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = rc.diagnose(mast.model(), null_data, band=BAND, workers=1)
    assert diag.best is None, diag.summary()
    assert all(r.p_value > 1e-3 for r in diag.ranking if r.fitted)


def test_a_hidden_added_mass_measured_by_impact_is_found(mast):
    """1.5 kg at dof 5 of the mast, hammer data with the exponential window: named first,
    significant, and its size recovered within 3 standard errors by the update."""
    data = _estimate(mast, seed=3, modify=_mass(4, 1.5))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = rc.diagnose(mast.model(), data, band=BAND, workers=1)
        assert diag.best is not None and diag.best.name == "added mass at dof 5", diag.summary()
        assert diag.best_result.significant
        upd = rc.update(mast.model().with_effect(diag.best), data, band=BAND)
    value, se = upd.model.param("added_mass__dof_5").value, upd.std_errors["added_mass__dof_5"]
    assert abs(value - 1.5) < 3 * se and se < 0.01  # 1.4998 +- 0.0035 kg


ONE_POLE = -2 * np.pi * 4 * 0.002 + 2j * np.pi * 4  # 4 Hz, 0.2 %
ONE_RESIDUE = 1.0 + 0.5j


@pytest.fixture(scope="module")
def one_mode():
    """Three noise-free hits on one mode, 2 s records (the decay is cut at 60 %), tau = 1.5 s."""
    poles = np.array([ONE_POLE, np.conj(ONE_POLE)])
    weights = np.array([[ONE_RESIDUE, np.conj(ONE_RESIDUE)]])
    n, over = 512, 16
    t = np.arange(n * over) / (FS * over)
    taps = firwin(20 * over + 1, 0.8 / over)
    F, Y = [], []
    for start in (0.05, 0.055, 0.058):
        f, y = _pulse_response(poles, weights, np.zeros(1), t, start, 0.01, 1.0)
        F.append(lfilter(taps, 1.0, f)[::over])
        Y.append(lfilter(taps, 1.0, y, axis=0)[::over])
    return rc.estimate_frf_impact(np.array(F), np.array(Y), FS, exp_window=1.5)


def test_expected_impact_h1_matches_a_windowed_record_of_one_mode(one_mode):
    """Reference check of eq. W2: one mode (4 Hz, 0.2 %), a 10 ms pulse, no noise, a record that
    cuts the decay at 60 % of its amplitude; at 1-12 Hz the H1 through an exponential
    window equals the mode at s + 1/tau minus the record-end tail to 2.5e-3 (the pulse's second-
    order expansion in eq. T1 errs by about 1e-3 per 10 Hz from the mode), and without the
    tail it errs ten times more."""
    data = one_mode
    assert data.experiment.exp_window_tau_s == 1.5
    record = truncation_settings(data.meta)
    assert record is not None and record.record_s == 2.0
    band = (data.f_hz > 1) & (data.f_hz < 12)
    f, g = data.f_hz[band], data.response[band]
    poles = np.array([ONE_POLE, np.conj(ONE_POLE)])
    residues = np.array([ONE_RESIDUE, np.conj(ONE_RESIDUE)])[:, None, None]
    exact = expected_h1_impact_modal(poles, residues, np.zeros((1, 1)), f, 1.5, record)
    no_tail = expected_h1_impact_modal(poles, residues, np.zeros((1, 1)), f, 1.5, None)
    err, err_no_tail = np.max(np.abs(np.log(g / exact))), np.max(np.abs(np.log(g / no_tail)))
    assert err < 2.5e-3 and err_no_tail > 10 * err
    # the tail kernel at a pole far inside the record: exp((q - s)(T - t_h)) tiny
    assert np.all(np.abs(record_tails(2j * np.pi * f, np.array([-50.0 + 10j]), record)) < 1e-12)


class _FittedMode:
    """A measurement model of the one mode whose fit removed the window (and the record end)."""

    def __init__(self, window_tau_s):
        p, r = ONE_POLE, ONE_RESIDUE
        tf = control.tf([2 * r.real, -2 * (r * np.conj(p)).real], [1.0, -2 * p.real, abs(p) ** 2])
        self.sys = control.ss(tf, inputs=["force"], outputs=["y1"])
        self.window_tau_s, self.leakage_corrected = window_tau_s, True

    def statespace(self):
        return self.sys


def test_the_residual_noise_model_sees_the_measurement_model_through_the_window(one_mode):
    """Data without coherence: the noise from a measurement model's residual. A model whose fit
    removed the window (tau = 1.5 s) and the record end is seen through both again: the residual
    is the eq. T1 expansion's 1e-3; compared plainly, the window's damping would pass for noise."""
    data = one_mode.band(1.0, 12.0).replace(coherence=None)
    seen = noise_model(data, measurement_model=_FittedMode(1.5))
    plain = noise_model(data, measurement_model=_FittedMode(None))
    assert np.median(seen.sigma) < 2e-3
    assert np.median(plain.sigma) > 10 * np.median(seen.sigma)


def test_decay_is_judged_per_channel():
    """A strong channel that has decayed does not hide a weak one that still rings: the window
    is applied and the ringing channel named (the envelope over all channels saw nothing)."""
    n = 1024
    t = np.arange(n) / FS
    quick = 100.0 * np.exp(-8.0 * t) * np.sin(2 * np.pi * 20 * t)  # decays to 1e-14
    slow = 0.5 * np.exp(-0.1 * t) * np.sin(2 * np.pi * 3 * t)  # keeps 67 %, 0.5 % of the strong peak
    y = np.stack([quick, slow], axis=-1)
    assert list(ringing_channels(y)) == [False, True]
    assert np.max(np.abs(y).max(axis=1)[int(0.9 * n):]) < 0.01 * np.abs(y).max()  # the old envelope test
    force = np.zeros(n)
    force[:3] = [0.5, 1.0, 0.5]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobustctlWarning)
        data = rc.estimate_frf_impact(np.tile(force, (3, 1)), np.tile(y, (3, 1, 1)), FS)
    assert data.meta["ringing_channels"] == [1]
    assert data.experiment.exp_window_tau_s == pytest.approx(n / FS / np.log(100))


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".mat", ".uff"])
def test_the_windows_round_trip_through_every_file_format(tmp_path, suffix):
    data = rc.FrequencyData(
        np.arange(1.0, 6.0), np.exp(1j * np.arange(5.0)), outputs=["a1"], inputs=["F"],
        experiment=rc.Experiment("measured", "impact", fs_hz=256.0, n_averages=6,
                                 exp_window_tau_s=0.8575934, force_window_s=0.03515625, pretrigger_s=0.0975),
    )
    path = tmp_path / f"hammer{suffix}"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobustctlWarning)
        data.save(path)
    back = rc.load_frd(path)
    assert back.experiment == data.experiment
    if suffix == ".uff":  # without the sidecar, ID line 2 (80 characters) alone keeps the windows
        (tmp_path / "hammer.uff.json").unlink()
        compact = rc.load_frd(path).experiment
        assert compact.exp_window_tau_s == 0.8575934 and compact.force_window_s == 0.03515625
        assert compact.replace(pretrigger_s=0.0975) == data.experiment


def test_the_window_given_as_its_end_value_and_bad_values_are_refused():
    e = rc.Experiment("measured", "impact", exp_window_end=0.01, record_s=4.0)
    assert e.exp_window_tau_s == pytest.approx(4.0 / np.log(100))
    with pytest.raises(rc.DataError, match="record_s"):
        rc.Experiment(exp_window_end=0.01)
    with pytest.raises(rc.DataError, match="exp_window_tau_s must be a positive"):
        rc.Experiment(exp_window_tau_s=-1.0)
    with pytest.raises(rc.DataError, match="in \\(0, 1\\)"):
        rc.Experiment(exp_window_end=1.5, record_s=4.0)
    assert rc.Experiment.from_dict({"excitation": "impact"}).exp_window_tau_s is None  # older files


def test_the_command_line_describes_a_bare_hammer_file(null_data, tmp_path):
    """A file from another analyser that does not say how it was made (no experiment, no meta):
    told on the command line the exponential window, the sampling rate and the hit's time in the
    record, the model is seen at s + 1/tau with the record end of one hit (eq. W2) and the exact
    truth is within the noise; told the window alone (no record end: the 2 Hz mode's tail is
    about 1 % near its peak), or nothing, it is beyond the noise."""
    spec = tmp_path / "mast_model.py"
    tests = str(Path(__file__).resolve().parents[1])  # where lab_corpus.py lives
    spec.write_text(f"import sys\nsys.path.insert(0, {tests!r})\nimport lab_corpus\n"
                    "model = lab_corpus.mast().model()\n")
    bare = rc.FrequencyData(null_data.f_hz, null_data.response, inputs=null_data.inputs,
                            outputs=null_data.outputs, coherence=null_data.coherence)
    path = bare.save(tmp_path / "hammer.csv")
    tau = null_data.experiment.exp_window_tau_s

    def compare(*options):
        out = tmp_path / f"out{len(options)}"
        argv = ["compare", str(spec), str(path), "--band", *map(str, BAND), "--out", str(out), *options]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main(argv) == 0
        return json.loads((out / "summary.json").read_text())

    pre = null_data.experiment.pretrigger_s
    told = compare("--input-kind", "measured", "--excitation", "impact", "--n-averages", "6", "--fs", "256",
                   "--exp-window-tau", repr(tau), "--force-window", "0.03", "--pretrigger", repr(pre))
    assert told["within_noise"] is True
    assert "exponential window" in told["view"] and "record end" in told["view"]
    assert told["experiment"]["exp_window_tau_s"] == tau and told["experiment"]["force_window_s"] == 0.03
    window_only = compare("--input-kind", "measured", "--excitation", "impact", "--n-averages", "6",
                          "--exp-window-tau", repr(tau))
    assert window_only["within_noise"] is False and "record end" not in window_only["view"]
    plain = compare("--input-kind", "measured", "--excitation", "impact", "--n-averages", "6", "--fs", "256")
    assert plain["within_noise"] is False and plain["cost"] > 20 * told["cost"]


def test_a_window_stated_twice_must_agree_and_the_view_survives_pickling(one_mode):
    e = rc.Experiment("measured", "impact", fs_hz=256.0, exp_window_tau_s=0.5)
    with pytest.raises(rc.DataError, match="exp_window_tau_s = 0.6"):
        impact_settings(e, {"exp_window_tau_s": 0.6})
    with pytest.raises(rc.DataError, match="exp_window_tau_s"):
        impact_settings(e.replace(exp_window_tau_s=None), {"exp_window_tau_s": "0.5"})
    st, _ = impact_settings(e, {"exp_window_tau_s": 0.5})
    assert st.impact and st.exp_tau_s == 0.5 and st.record is None
    seen, _ = impact_settings(one_mode.experiment, one_mode.meta, one_mode.f_hz)
    assert seen.record == truncation_settings(one_mode.meta) and seen.exp_tau_s == 1.5
    assert pickle.loads(pickle.dumps(seen)) == seen  # diagnose's worker processes get it whole
    off_grid, _ = impact_settings(one_mode.experiment, one_mode.meta, one_mode.f_hz[:4] + 0.1)
    assert off_grid.record is None  # eq. T1 holds at the record's DFT bins only


def test_the_exponential_window_correlates_neighbouring_bins(null_data):
    """Reference: for w = a^n, a = exp(-2 dt / tau), sum_n a^n e^{-j 2 pi m n / N} =
    (1 - a^N) / (1 - a e^{-j 2 pi m / N}), so |rho_m| = (1 - a) / |1 - a e^{-j 2 pi m / N}|."""
    tau, n = null_data.experiment.exp_window_tau_s, null_data.meta["n_samples"]
    r = exp_window_correlation(tau, n, FS)
    a = np.exp(-2.0 / FS / tau)
    m = np.arange(r.size)
    np.testing.assert_allclose(r, ((1 - a) / np.abs(1 - a * np.exp(-2j * np.pi * m / n))) ** 2, rtol=1e-9)
    assert r[1] == pytest.approx(0.69, abs=0.02) and r[-1] >= 1e-3
    nm = noise_model(null_data)  # the Satterthwaite factors of correlated bins (module notes of noise)
    assert nm.dof_factor == pytest.approx(1 + 2 * np.sum(r[1:] ** 2)) and nm.dof_factor > 2
    assert nm.chi2_factor == pytest.approx(1 + 2 * np.sum(r[1:])) and nm.chi2_factor > nm.dof_factor
