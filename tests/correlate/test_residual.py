"""Residual (MACE eqs. 5-6), finite-difference sensitivities (eq. 7), alignment and
orthogonality (eqs. 8-9) and the Levenberg-Marquardt core, checked against analytic
derivatives of a 2-DOF spring-mass chain and against scipy.optimize.least_squares."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import control
import numpy as np
import pytest
import scipy.optimize

import robustctl as rc
from robustctl.correlate import (
    Residual,
    alignment,
    levenberg_marquardt,
    orthogonality,
    sensitivities,
)

NOMINAL = dict(k1=1000.0, k2=2000.0, m1=1.0, m2=2.0, c1=0.6, c2=0.4, ga=1.0, gb=1.0)


def _matrices(th):
    M = np.diag([th["m1"], th["m2"]])
    K = np.array([[th["k1"] + th["k2"], -th["k2"]], [-th["k2"], th["k2"]]])
    C = np.array([[th["c1"] + th["c2"], -th["c2"]], [-th["c2"], th["c2"]]])
    return M, K, C


def chain_model(**values) -> rc.PhysicalModel:
    """Ground-k1-m1-k2-m2 chain, forces f1, f2 in, displacements x1, x2 out (times ga*gb)."""
    vals = {**NOMINAL, **values}
    params = [
        rc.Parameter(n, v, bounds=(0.0, np.inf) if n[0] in "kmc" else (0.1, 10.0), rel_step=1e-6)
        for n, v in vals.items()
    ]

    def dynamics(th, _struct):
        M, K, C = _matrices(th)
        Mi = np.linalg.inv(M)
        A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ C]])
        B = np.vstack([np.zeros((2, 2)), Mi])
        Cy = th["ga"] * th["gb"] * np.hstack([np.eye(2), np.zeros((2, 2))])
        return control.ss(A, B, Cy, np.zeros((2, 2)), inputs=["f1", "f2"], outputs=["x1", "x2"])

    return rc.PhysicalModel(params=params, dynamics=dynamics, name="2-dof chain")


def analytic_receptance(th, f_hz):
    M, K, C = _matrices(th)
    s = 2j * np.pi * np.asarray(f_hz)
    return np.array([np.linalg.inv(K + sk * C + sk**2 * M) for sk in s])


F_HZ = np.linspace(0.5, 12.0, 120)


@pytest.fixture(scope="module")
def model():
    return chain_model()


@pytest.fixture(scope="module")
def truth_data():
    th = {**NOMINAL, "k1": 1050.0, "k2": 1940.0, "m2": 2.04}
    return rc.FrequencyData(F_HZ, analytic_receptance(th, F_HZ), inputs=["f1", "f2"], outputs=["x1", "x2"])


def test_cost_is_direct_sum_of_squared_log_ratios(model, truth_data):
    res = Residual(model, truth_data, band=(1.0, 10.0))
    keep = (F_HZ >= 1.0) & (F_HZ <= 10.0)
    g_m = analytic_receptance(NOMINAL, F_HZ[keep])
    direct = np.sum(np.abs(np.log(truth_data.response[keep] / g_m)) ** 2)
    assert res.cost() == pytest.approx(direct, rel=1e-9)
    assert res.n == 2 * keep.sum() * 4
    j = res.vector()
    assert np.allclose(res.unstack(j), res.complex())


def test_channel_order_of_data_may_differ(model, truth_data):
    swapped = truth_data.select(outputs=["x2", "x1"], inputs=["f2", "f1"])
    assert Residual(model, swapped).cost() == pytest.approx(Residual(model, truth_data).cost(), rel=1e-12)


def test_sensitivities_match_analytic_derivatives(model, truth_data):
    res = Residual(model, truth_data)
    names = ["k1", "k2", "m2", "c1"]
    j0, dJ = sensitivities(res, names)
    H = analytic_receptance(NOMINAL, F_HZ)
    s = 2j * np.pi * F_HZ
    dmat = {
        "k1": lambda sk: np.array([[1.0, 0.0], [0.0, 0.0]]),
        "k2": lambda sk: np.array([[1.0, -1.0], [-1.0, 1.0]]),
        "m2": lambda sk: sk**2 * np.array([[0.0, 0.0], [0.0, 1.0]]),
        "c1": lambda sk: sk * np.array([[1.0, 0.0], [0.0, 0.0]]),
    }
    for col, name in enumerate(names):
        # j = log Gd - log Gm, d log Gm / d a = -(H dZ H)/H  =>  dj/d ln a = a (H dZ H)/H
        dlog = np.array([Hk @ dmat[name](sk) @ Hk for Hk, sk in zip(H, s)]) / H
        expected = NOMINAL[name] * dlog.ravel()
        expected = np.concatenate([expected.real, expected.imag])
        # forward differences (rel. step 1e-6): O(step) truncation error near the resonances
        assert np.linalg.norm(dJ[:, col] - expected) < 1e-4 * np.linalg.norm(expected), name
    assert np.allclose(j0, res.vector())


def test_sensitivity_scaling_kinds_and_executor(model, truth_data):
    res = Residual(model, truth_data)
    sens = sensitivities(res, ["k1", "c2"], origin={"c2": 0.0}, at={"c2": 0.4})
    assert sens.kind == ("relative", "secant")
    # secant column = j(trial) - j(origin), the whole change
    expected = res.vector(c2=0.4) - res.vector(c2=0.0)
    assert np.allclose(sens.dJ[:, 1], expected)
    assert sens.base["c2"] == 0.0 and sens.trial[1] == 0.4
    assert np.allclose(sens.jacobian()[:, 0] * 1000.0, sens.dJ[:, 0])
    with ThreadPoolExecutor(2) as ex:
        par = sensitivities(res, ["k1", "c2"], origin={"c2": 0.0}, at={"c2": 0.4}, executor=ex)
    assert np.array_equal(par.dJ, sens.dJ)
    zero = chain_model(c2=0.0)
    unit = sensitivities(Residual(zero, truth_data), ["c2"], steps={"c2": 1e-4})
    assert unit.kind == ("unit",) and unit.scale[0] == 1.0


def test_alignment_and_orthogonality_properties(model, truth_data):
    res = Residual(model, truth_data)
    j0, dJ = sensitivities(res, ["k1", "k2", "m2", "ga", "gb"])
    O = orthogonality(dJ)
    assert np.allclose(np.diag(O), 1.0)
    assert np.allclose(O, O.T)
    assert np.all((O >= 0) & (O <= 1))
    # ga and gb only enter as the product ga*gb: identical relative sensitivities
    assert O[3, 4] > 0.999
    a = alignment(j0, dJ)
    assert a.shape == (5,) and np.all(a >= 0)
    assert a[0] == pytest.approx(abs(j0 @ dJ[:, 0]))


def test_lm_recovers_known_parameters_exactly(model, truth_data):
    res = Residual(model, truth_data)
    fit = levenberg_marquardt(res, ["k1", "k2", "m2"], max_iter=30)
    assert fit.success, fit.stop_reason
    assert fit.x["k1"] == pytest.approx(1050.0, rel=1e-6)
    assert fit.x["k2"] == pytest.approx(1940.0, rel=1e-6)
    assert fit.x["m2"] == pytest.approx(2.04, rel=1e-6)
    assert fit.cost < 1e-12 * fit.cost0
    assert all(b <= a * (1 + 1e-12) for a, b in zip(fit.history, fit.history[1:]))


def test_lm_agrees_with_scipy_least_squares(model):
    rng = np.random.default_rng(1)
    th = {**NOMINAL, "k1": 980.0, "k2": 2070.0, "c1": 0.7}
    g = analytic_receptance(th, F_HZ)
    noise = np.exp(0.02 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F_HZ, g * noise, inputs=["f1", "f2"], outputs=["x1", "x2"])
    res = Residual(model, data)
    names = ["k1", "k2", "c1"]
    fit = levenberg_marquardt(res, names, max_iter=40)
    x0 = np.array([NOMINAL[n] for n in names])
    ref = scipy.optimize.least_squares(
        lambda x: res.vector(**dict(zip(names, x))), x0, x_scale=x0, xtol=1e-14, ftol=1e-14, gtol=1e-14
    )
    assert np.allclose(fit.x_array, ref.x, rtol=1e-5)
    assert fit.cost == pytest.approx(2 * ref.cost, rel=1e-8)
    # standard errors from the Jacobian and residual variance: plausible size
    se = np.array([fit.std_errors[n] for n in names])
    assert np.all(se > 0) and np.all(se < 0.01 * fit.x_array)


def test_lm_respects_bounds_and_reports_active(model, truth_data):
    res = Residual(model, truth_data)
    fit = levenberg_marquardt(res, ["k1", "k2"], bounds={"k1": (900.0, 1020.0)}, max_iter=30)
    assert fit.x["k1"] == pytest.approx(1020.0)
    assert "k1" in fit.active
    assert fit.cost < fit.cost0


def test_lm_caps_iterations_and_time(model, truth_data):
    res = Residual(model, truth_data)
    fit = levenberg_marquardt(res, ["k1", "k2", "m2"], max_iter=1)
    assert fit.n_iter == 1 and not fit.success and "cap" in fit.stop_reason
    fit = levenberg_marquardt(res, ["k1", "k2", "m2"], time_budget_s=0.0)
    assert "time budget" in fit.stop_reason and fit.n_iter == 0 and fit.stopped_by_budget


def test_lm_reuses_start_sensitivities_without_changing_the_fit(model, truth_data):
    res = Residual(model, truth_data)
    names = ["k1", "k2", "m2"]
    sens = sensitivities(res, ["c1", *names])  # e.g. the ones MACE's selection tests used
    plain = levenberg_marquardt(res, names, max_iter=30)
    reused = levenberg_marquardt(res, names, max_iter=30, start=sens)
    assert reused.history == plain.history and reused.x == plain.x
    assert np.array_equal(reused.jacobian, plain.jacobian)
    assert reused.n_evals == plain.n_evals - 1 - len(names)
    with pytest.raises(rc.FitError, match="other values of"):
        levenberg_marquardt(res, names, x0={"k1": 1010.0}, start=sens)
    with pytest.raises(rc.FitError, match="miss"):
        levenberg_marquardt(res, [*names, "c2"], start=sens)


# ---------------------------------------------------------------------- bad input
def test_bad_signal_names_and_counts(model, truth_data):
    renamed = truth_data.replace(outputs=["a1", "a2"])
    with pytest.raises(rc.DataError, match=r"outputs .* do not match the data"):
        Residual(model, renamed)
    fewer = truth_data.select(outputs=["x1"])
    with pytest.raises(rc.DataError, match=r"model has 2 outputs .* data has 1") as err:
        Residual(model, fewer)
    assert "model.select(outputs=['x1'])" in str(err.value)  # the fix is on the model's side


def test_band_outside_data(model, truth_data):
    with pytest.raises(rc.DataError, match=r"holds 0 data point.*span 0.5-12 Hz"):
        Residual(model, truth_data, band=(20.0, 40.0))
    with pytest.raises(rc.DataError, match=r"f_lo_hz < f_hi_hz"):
        Residual(model, truth_data, band=(5.0, 2.0))


def test_bad_weights(model, truth_data):
    with pytest.raises(rc.DataError, match=r"no coherence"):
        Residual(model, truth_data, point_weights="coherence")
    with pytest.raises(rc.DataError, match=r"point_weights of shape \(7,\) do not fit"):
        Residual(model, truth_data, point_weights=np.ones(7))


def test_unknown_names_and_bad_bounds(model, truth_data):
    res = Residual(model, truth_data)
    with pytest.raises(rc.ModelError, match=r"unknown parameter\(s\) \['E_steel'\]"):
        sensitivities(res, ["k1", "E_steel"])
    with pytest.raises(rc.ModelError, match=r"unknown parameter"):
        levenberg_marquardt(res, ["nope"])
    with pytest.raises(rc.FitError, match=r"bounds exclude the starting point: k1 = 1000"):
        levenberg_marquardt(res, ["k1"], bounds={"k1": (1100.0, 1200.0)})


def test_negligible_channels_are_dropped(model, truth_data):
    g = truth_data.response.copy()
    g[:, 0, 1] *= 1e-7  # a decoupled axis: 140 dB below its row and column
    res = Residual(model, truth_data.replace(response=g))
    assert [(o, i) for o, i, _ in res.dropped] == [("x1", "f2")]
    assert res.dropped[0][2] < -80.0
    assert np.all(res.weights[:, 0, 1] == 0) and np.all(res.weights[:, 1, 1] == 1)
    assert Residual(model, truth_data.replace(response=g), min_channel_db=None).dropped == []
    g[:, 0, 1] = 0.0
    with pytest.raises(rc.DataError, match=r"x1 <- f2 is identically zero"):
        Residual(model, truth_data.replace(response=g), min_channel_db=None)
    assert Residual(model, truth_data.replace(response=g)).dropped[0][:2] == ("x1", "f2")


def _fragile(limit: float) -> rc.PhysicalModel:
    """The chain whose build refuses k1 > limit (as a gravity iteration may fail to converge)."""
    base = chain_model()

    def dynamics(th, struct):
        if th["k1"] > limit:
            raise rc.ModelError(f"cannot build with k1 = {th['k1']}")
        return base.dynamics(th, struct)

    return rc.PhysicalModel(params=base.params, dynamics=dynamics, name="fragile chain")


def test_failed_model_builds_are_survived(model, truth_data):
    ref = sensitivities(Residual(model, truth_data), ["k1"]).dJ
    res = Residual(_fragile(1000.0), truth_data)  # the forward step fails: mirrored step
    sens = sensitivities(res, ["k1"])
    assert sens.trial[0] < 1000.0
    assert np.linalg.norm(sens.dJ - ref) < 1e-4 * np.linalg.norm(ref)
    fit = levenberg_marquardt(Residual(_fragile(1040.0), truth_data), ["k1", "k2", "m2"], max_iter=15)
    assert fit.x["k1"] <= 1040.0 and fit.cost < fit.cost0
    with pytest.raises(rc.FitError, match=r"cannot be evaluated for the finite difference of 'k1'"):
        sensitivities(res, ["k1"], origin={"k1": 999.0}, at={"k1": 1001.0})


def test_cost_matches_lti_log_cost(model, truth_data):
    """One number for MACE eq. 5 across the package: point weights act on the squared error."""
    w = np.linspace(0.5, 2.0, F_HZ.size)[:, None, None] * np.ones((1, 2, 2))
    res = Residual(model, truth_data, band=(1.0, 10.0), point_weights=w[(F_HZ >= 1.0) & (F_HZ <= 10.0)])
    ref = rc.log_cost(model.statespace(), truth_data, band=(1.0, 10.0), point_weights=w)
    assert res.cost() == pytest.approx(ref, rel=1e-10)
    with pytest.warns(DeprecationWarning, match="point_weights"):  # the old keyword, one release
        old = Residual(model, truth_data, band=(1.0, 10.0), weights=w[(F_HZ >= 1.0) & (F_HZ <= 10.0)])
    assert old.cost() == pytest.approx(ref, rel=1e-10)
