"""UpdateResult.sample_models: parameter sets drawn from the update's fitted covariance
(within bounds), and the Caltech truss cover of the updated model's residual plus that
spread, which must bound the true plant's error at every grid frequency."""

from __future__ import annotations

import dataclasses

import control
import matplotlib
import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.updating import update

matplotlib.use("Agg")

NOMINAL = dict(k1=1000.0, k2=2000.0, m1=1.0, m2=2.0, c1=0.6, c2=0.4)
F = np.linspace(0.5, 12.0, 120)


def chain(bounds=(1e-6, 1e6), **values) -> rc.PhysicalModel:
    vals = {**NOMINAL, **values}
    params = [rc.Parameter(n, v, bounds=bounds) for n, v in vals.items()]

    def dynamics(th, _struct):
        M = np.diag([th["m1"], th["m2"]])
        K = np.array([[th["k1"] + th["k2"], -th["k2"]], [-th["k2"], th["k2"]]])
        C = np.array([[th["c1"] + th["c2"], -th["c2"]], [-th["c2"], th["c2"]]])
        Mi = np.linalg.inv(M)
        A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ C]])
        B = np.vstack([np.zeros((2, 2)), Mi])
        Cy = np.hstack([np.eye(2), np.zeros((2, 2))])
        return control.ss(A, B, Cy, np.zeros((2, 2)), inputs=["f1", "f2"], outputs=["x1", "x2"])

    return rc.PhysicalModel(params=params, dynamics=dynamics, name="2-dof chain")


@pytest.fixture(scope="module")
def noisy_update():
    """An update of three correlated parameters on noisy data (non-trivial covariance)."""
    model = chain()
    truth = model.with_values(k1=1040.0, k2=1950.0, m2=2.05)
    g = truth.freqresp(F).response
    rng = np.random.default_rng(4)
    noise = np.exp(0.02 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F, g * noise, inputs=["f1", "f2"], outputs=["x1", "x2"])
    return update(model, data, params=["k1", "k2", "m2"], select=False, drift_bands=0)


def test_sample_covariance_matches_the_fitted_covariance(noisy_update):
    upd = noisy_update
    n = 2000
    draws = upd.sample_parameters(n, seed=0)
    assert draws.shape == (n, 3)
    cov = upd.fit.covariance
    se = np.sqrt(np.diag(cov))
    corr = cov / np.outer(se, se)
    assert np.max(np.abs(corr - np.eye(3))) > 0.2  # the test needs real correlations
    # mean within 4 standard errors of the mean
    np.testing.assert_array_less(np.abs(draws.mean(axis=0) - upd.fit.x_array), 4 * se / np.sqrt(n))
    # each covariance entry within 4 sampling standard deviations (Wishart: var S_ij =
    # (S_ij^2 + S_ii S_jj) / (n - 1))
    S = np.cov(draws.T)
    sd = np.sqrt((cov**2 + np.outer(np.diag(cov), np.diag(cov))) / (n - 1))
    np.testing.assert_array_less(np.abs(S - cov), 4 * sd)
    # and the standard errors are the update's
    np.testing.assert_allclose(np.sqrt(np.diag(S)), [upd.std_errors[k] for k in upd.fit.names], rtol=0.1)


def test_sample_models_are_physical_models_with_the_drawn_values(noisy_update):
    upd = noisy_update
    models = upd.sample_models(5, seed=3)
    draws = upd.sample_parameters(5, seed=3)
    assert len(models) == 5 and all(isinstance(m, rc.PhysicalModel) for m in models)
    for m, row in zip(models, draws):
        for name, v in zip(upd.fit.names, row):
            assert m.param(name).value == v
        assert m.param("c1").value == upd.model.param("c1").value  # untouched parameters stay
    # reproducible, and different seeds differ
    np.testing.assert_array_equal(upd.sample_parameters(7, seed=1), upd.sample_parameters(7, seed=1))
    assert not np.array_equal(upd.sample_parameters(7, seed=1), upd.sample_parameters(7, seed=2))


def test_samples_respect_bounds_by_rejection(noisy_update):
    upd = noisy_update
    k1 = upd.model.param("k1").value
    se = upd.std_errors["k1"]
    tight = upd.model.with_params(
        [dataclasses.replace(upd.model.param("k1"), bounds=(k1 - 0.5 * se, k1 + 10 * se))]
    )
    bounded = dataclasses.replace(upd, model=tight)
    draws = bounded.sample_parameters(500, seed=0)
    col = draws[:, bounded.fit.names.index("k1")]
    assert col.min() >= k1 - 0.5 * se and col.max() <= k1 + 10 * se
    # truncation of a normal below -0.5 sigma: the mean moves up by phi(0.5) / Phi(0.5) = 0.509 sigma
    assert np.mean(col) - k1 == pytest.approx(0.509 * se, rel=0.15)
    # a bound that leaves (almost) nothing: a clear error, no endless loop
    squeezed = dataclasses.replace(
        upd,
        model=upd.model.with_params(
            [dataclasses.replace(upd.model.param("k1"), bounds=(k1 - 1e-6 * se, k1 + 1e-6 * se))]
        ),
    )
    with pytest.raises(rc.FitError, match=r"fell within the parameter bounds"):
        squeezed.sample_parameters(50, seed=0, max_draws=20)


def test_sample_models_bad_input(noisy_update):
    for bad in (0, -3, 2.5, True, "10"):
        with pytest.raises(rc.FitError, match=r"n must be a positive integer"):
            noisy_update.sample_models(bad)


@pytest.mark.slow
def test_caltech_cover_of_residual_and_spread_bounds_the_truth():
    """Weights from the updated model's measured residual and parameter spread
    cover the true plant's error at every grid frequency (beside the seed's eq. 14)."""
    res = rc.examples.caltech_truss_weights(seed=0, n_models=10, order=4, measurement_model=False)
    cov = res.updated
    assert cov.margin >= 1.0
    assert res.truth_margin >= 1.0
    assert len(cov.sources) == 11 and cov.sources[0] == "data"
    # the truth's error, recomputed here independently of the example's own check
    f = cov.f_hz
    g_t = res.truth.freqresp(f).response
    g_u = res.update.model.freqresp(f).response
    err = np.linalg.svd(g_t - g_u, compute_uv=False)[:, 0]
    w = np.abs(control.frequency_response(cov.weight, 2 * np.pi * f).frdata[0, 0])
    assert np.all(w >= err)
    # the spread alone is far smaller than the residual: the data, not the parameters, set W
    assert cov.source_errors[1:].max() < cov.source_errors[0].max()
    assert res.plot().axes
