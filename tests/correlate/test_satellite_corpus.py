"""Reference checks of the independent satellite corpus (tests/satellite_corpus.py)."""

import numpy as np
import pytest
import satellite_corpus as sc


def test_nominal_frame_model_reproduces_numpy_truth():
    """rc.Frame in rc.PhysicalModel and the numpy beam assembly are the same structure."""
    f = np.linspace(2.0, 80.0, 157)
    g = sc.truth_frf(f)
    gm = sc.nominal_model().freqresp(f).response
    assert sc.truth_matrices()[0].shape == (120, 120)
    assert np.max(np.abs(gm - g)) / np.max(np.abs(g)) < 1e-7


def test_simulation_is_the_exact_steady_state_of_a_sine():
    """A 7.3 Hz sine (first-order hold on the fine grid) settles to |G| and arg G of the modal sum."""
    f0, fs_fine, every = 7.3, sc.FS * sc.OVERSAMPLE, sc.OVERSAMPLE
    n = int(60 * sc.FS) * every + 1
    t = np.arange(n) / fs_fine
    force = np.column_stack([np.sin(2 * np.pi * f0 * t), 0.5 * np.cos(2 * np.pi * f0 * t)])
    y = sc.simulate(force, 1 / fs_fine, (), every=every)
    tc = t[::every]
    g = sc.truth_frf([f0])[0]
    expected = g[:, 0] / 1j + 0.5 * g[:, 1]  # complex amplitude at f0 of each sensor
    last = tc >= 10.0  # 50 s = 365 whole periods; the suspension transients (< 1 Hz) lie far off f0
    w = np.hanning(last.sum())
    got = 2 * (w[:, None] * y[last] * np.exp(-2j * np.pi * f0 * tc[last])[:, None]).sum(0) / w.sum()
    err = np.abs(got - expected).max() / np.abs(expected).max()
    assert err < 1e-4


@pytest.mark.parametrize("effects", [(), ("hinge_1axis",), ("resonator",)])
def test_mimo_h1_of_the_truth_is_within_its_coherence_error(effects):
    """The H1 scatter about the exact FRF matches the coherence's random error (B&P eq. 9.52);
    each hidden effect changes the FRF far beyond it."""
    case = sc.measure(effects, seed=1)
    d = case.data
    err = np.abs(np.log(d.response / sc.truth_frf(d.f_hz, effects)))
    c = d.coherence
    pred = np.sqrt((1 - c) / (case.description["n_averages"] * c))
    assert 0.7 < np.median(err / pred) < 1.3
    if effects:
        shift = np.abs(np.log(sc.truth_frf(d.f_hz, effects) / sc.truth_frf(d.f_hz)))
        assert np.mean((shift / pred) ** 2) > 10.0  # chi-square per point far above 1
