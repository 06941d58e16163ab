"""The shared ground: one band rule, one meaning of point weights, one channel-name
policy, one system coercion, one cost, one result convention -- the same at every entry point."""

from __future__ import annotations

import pickle
import warnings

import control
import matplotlib
import numpy as np
import pytest

import robustctl as rc
from robustctl import checks
from robustctl.physical import electronics

matplotlib.use("Agg")
fx = rc.effects

F_HZ = np.linspace(0.5, 40.0, 300)
M3 = np.diag([2.0, 1.0, 0.5])
KC = 1e3 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])


def _chain() -> rc.PhysicalModel:
    """Three masses on a grounded spring (k_ground), 2 force inputs, 2 accelerometers."""
    k_par = rc.Parameter("k_ground", 4e3, "N/m", (1e3, 1e4), meaning="ground spring of mass 1")
    return rc.structural_model(
        M3, lambda th: KC + np.diag([th["k_ground"], 0.0, 0.0]),
        inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"a2": ("dof 2", "acceleration"), "a3": ("dof 3", "acceleration")},
        damping=0.02, params=[k_par], name="3-mass chain",
    )


@pytest.fixture(scope="module")
def chain():
    return _chain()


@pytest.fixture(scope="module")
def data(chain):
    """The chain with a 3 % stiffer ground spring, 1 % log noise and a made-up coherence."""
    truth = chain.with_values(k_ground=4.12e3)
    g = truth.freqresp(F_HZ).response
    rng = np.random.default_rng(1)
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    coh = np.clip(0.6 + 0.4 * rng.random(g.shape), 0, 1)
    return rc.FrequencyData(F_HZ, g, inputs=chain.inputs, outputs=chain.outputs, coherence=coh)


# ---------------------------------------------------------------------------- same error, same words
def _entry_points(chain, data):
    """Every public entry point that takes a band and/or point weights, as (name, call(**kw))."""
    cand = [fx.SensorGain("a3")]
    return {
        "compare": lambda **kw: rc.compare(chain, data, **kw),
        "update": lambda **kw: rc.update(chain, data, **kw),
        "diagnose": lambda **kw: rc.diagnose(chain, data, cand, **kw),
        "verify": lambda **kw: rc.verify(chain, data, {"k_ground": 4e3}, **kw),
        "log_cost": lambda **kw: rc.log_cost(chain, data, **kw),
        "fit_rational": lambda **kw: rc.fit_rational(data, 6, **kw),
        "fit_measurement_model": lambda **kw: rc.fit_measurement_model(data, n_modes=3, **kw),
    }


BAD_BANDS = [
    ((3.0, 2.0), r"^band \(3, 2\) Hz is empty or not finite; give finite f_lo_hz < f_hi_hz in Hz\.$"),
    ((np.nan, 5.0), r"^band \(nan, 5\) Hz is empty or not finite; give finite f_lo_hz < f_hi_hz in Hz\.$"),
    ((50.0, 60.0), r"^band \(50, 60\) Hz holds 0 data points; the data span 0\.5-40 Hz\. Choose a band"),
    ("ab", r"^band must be a pair \(f_lo_hz, f_hi_hz\) of finite frequencies in Hz; got 'ab'\.$"),
    ((1.0, 2.0, 3.0), r"^band must be a pair \(f_lo_hz, f_hi_hz\) of finite frequencies in Hz; got"),
    ((-5.0, 5.0), r"^band \(-5, 5\) Hz starts below 0 Hz: .* give 0 <= f_lo_hz < f_hi_hz in Hz\.$"),
]


BAD_BAND_IDS = ["reversed", "nan", "outside", "text", "triple", "negative"]


@pytest.mark.parametrize("entry", list(_entry_points(None, None)) + ["FrequencyData.band", "candidates"])
@pytest.mark.parametrize("band, message", BAD_BANDS, ids=BAD_BAND_IDS)
def test_every_entry_point_refuses_a_bad_band_in_the_same_words(chain, data, entry, band, message):
    calls = _entry_points(chain, data)
    calls["FrequencyData.band"] = lambda band: data.band(*band) if len(band) == 2 else data.band(*band[:2])
    calls["candidates"] = lambda band: fx.candidates(chain, band=band)
    if entry == "FrequencyData.band" and (isinstance(band, str) or len(band) != 2):
        pytest.skip("FrequencyData.band takes the two ends as separate arguments")
    if entry == "candidates" and band == (50.0, 60.0):
        pytest.skip("candidates has no data, so no band lies outside it")
    with pytest.raises(rc.DataError, match=message):
        calls[entry](band=band)


BAD_WEIGHTS = [
    (np.full(F_HZ.size, -1.0), r"^point_weights must be finite and non-negative with at least one positive"),
    (np.r_[np.nan, np.ones(F_HZ.size - 1)], r"^point_weights must be finite and non-negative"),
    (np.zeros(F_HZ.size), r"^point_weights must be finite and non-negative with at least one positive"),
    (np.ones(7), r"^point_weights of shape \(7,\) do not fit the banded data of shape \(300, 2, 2\)"),
    ("coherent", r"^point_weights must be None, 'auto', 'coherence' or an array of weights on the squared"),
]


@pytest.mark.parametrize("entry", list(_entry_points(None, None)))
@pytest.mark.parametrize("weights, message", BAD_WEIGHTS, ids=["negative", "nan", "zero", "shape", "text"])
def test_every_entry_point_refuses_bad_point_weights_in_the_same_words(chain, data, entry, weights, message):
    with pytest.raises(rc.DataError, match=message):
        _entry_points(chain, data)[entry](point_weights=weights)


def test_coherence_weights_without_coherence_are_refused_everywhere_alike(chain, data):
    bare = data.replace(coherence=None)
    msg = r"^point_weights='coherence' but the data carry no coherence"
    for call in _entry_points(chain, bare).values():
        with pytest.raises(rc.DataError, match=msg):
            call(point_weights="coherence")


@pytest.mark.parametrize("entry", ["compare", "update", "diagnose", "verify", "log_cost", "log_error"])
def test_every_entry_point_refuses_mismatched_names_in_the_same_words(chain, data, entry):
    renamed = data.replace(outputs=["acc2", "acc3"])
    calls = _entry_points(chain, renamed)
    calls["log_error"] = lambda: rc.log_error(chain, renamed)
    msg = (r"^the model's outputs \['a2', 'a3'\] do not match the data's \['acc2', 'acc3'\]; rename the "
           r"model's signals \(rc\.as_statespace\(sys, outputs=\[\.\.\.\]\)\) or the data's")
    with pytest.raises(rc.DataError, match=msg):
        calls[entry]()


def test_default_names_match_by_position_only_with_equal_counts(chain, data):
    """python-control's u[0]/y[0] on either side: by position; FrequencyData's u1/y1 are names."""
    sys = control.ss(chain.statespace())  # keep names
    unnamed = control.ss(sys.A, sys.B, sys.C, sys.D)  # u[0], u[1] / y[0], y[1]
    j_named = rc.log_cost(sys, data)
    assert rc.log_cost(unnamed, data) == pytest.approx(j_named, rel=1e-12)
    assert rc.compare(unnamed, data).cost == pytest.approx(rc.compare(sys, data).cost, rel=1e-12)
    unnamed_data = rc.freqresp(unnamed, F_HZ).replace(response=data.response, coherence=data.coherence)
    assert unnamed_data.inputs == ("u[0]", "u[1]")
    assert rc.log_cost(sys, unnamed_data) == pytest.approx(j_named, rel=1e-12)
    plain = rc.FrequencyData(data.f_hz, data.response, coherence=data.coherence)  # u1, u2 / y1, y2
    with pytest.raises(rc.DataError, match=r"the model's outputs \['a2', 'a3'\] do not match the data's"):
        rc.log_cost(sys, plain)
    with pytest.raises(rc.DataError, match=r"^the model has 1 outputs \['y\[0\]'\] but the data has 2"):
        rc.log_cost(unnamed[0, :], data)
    # the same names in another order are reordered, not matched by position
    swapped = data.select(outputs=["a3", "a2"], inputs=["F3", "F1"])
    assert rc.log_cost(sys, swapped) == pytest.approx(j_named, rel=1e-12)


# ---------------------------------------------------------------------------- one cost
def test_compare_update_diagnose_log_cost_give_one_cost(chain, data):
    band = (2.0, 30.0)
    w = np.linspace(0.5, 2.0, F_HZ.size)  # on the full grid: W on the squared error everywhere
    for weights in ("auto", None, w):
        j_log = rc.log_cost(chain, data, band=band, point_weights=weights)
        j_cmp = rc.compare(chain, data, band=band, point_weights=weights).cost
        upd = rc.update(chain, data, params=["k_ground"], band=band, point_weights=weights, max_iter=1,
                        passes=1, drift_bands=0)
        diag = rc.diagnose(chain, data, [fx.SensorGain("a3")], band=band, point_weights=weights, n_fit=0,
                           update_iter=1)
        assert j_cmp == pytest.approx(j_log, rel=1e-12)
        assert upd.cost_before == pytest.approx(j_log, rel=1e-12)
        assert diag.cost_nominal == pytest.approx(j_log, rel=1e-12)
        # the diagnosis's weights reproduce the cost when handed on
        assert rc.log_cost(chain, data, band=band, point_weights=diag.point_weights) == pytest.approx(j_log)
    # "auto" is the one coherence formula: W = g2/(1-g2), g2 <= 0.999, mean 1 on the band
    keep = (F_HZ >= 2) & (F_HZ <= 30)
    g2 = np.clip(data.coherence[keep], 0, rc.checks.COHERENCE_CAP)
    W = g2 / (1 - g2) / np.mean(g2 / (1 - g2))
    err = rc.log_error(chain, data, band=band)
    direct = float(np.sum(W * np.abs(err) ** 2))
    assert rc.log_cost(chain, data, band=band) == pytest.approx(direct, rel=1e-12)


def test_measurement_model_cost_is_the_same_number_everywhere(data):
    mm = rc.fit_measurement_model(data, n_modes=3, band=(0.5, 30.0))
    j = mm.cost.total
    assert rc.log_cost(mm, mm.data, point_weights=None) == pytest.approx(j, rel=1e-10)
    cmp = rc.compare(mm, mm.data, point_weights=None, min_channel_db=None)
    assert cmp.cost == pytest.approx(j, rel=1e-10)
    assert isinstance(cmp.log_cost, rc.LogCost) and isinstance(mm.cost, rc.LogCost)
    np.testing.assert_allclose(cmp.log_cost.per_channel, mm.cost.per_channel, rtol=1e-10)


# ---------------------------------------------------------------------------- one system protocol
def _systems(chain):
    mm = rc.fit_measurement_model(chain.freqresp(F_HZ), n_modes=3)
    ss = chain.statespace()
    return {
        "PhysicalModel": chain,
        "MeasurementModel": mm,
        "StateSpace": ss,
        "TransferFunction": control.ss2tf(ss),
        "BalancedTruncation": rc.balanced_truncation(ss, 6),
    }


@pytest.fixture(scope="module")
def systems(chain):
    return _systems(chain)


@pytest.mark.parametrize("kind", ["PhysicalModel", "MeasurementModel", "StateSpace", "TransferFunction",
                                  "BalancedTruncation"])
def test_every_function_that_takes_a_system_takes_each_kind(chain, data, systems, kind):
    sys = systems[kind]
    ref = rc.as_statespace(sys)
    assert isinstance(ref, control.StateSpace)
    g = rc.freqresp(sys, F_HZ)
    np.testing.assert_allclose(g.response, rc.freqresp(ref, F_HZ).response, rtol=1e-10)
    n = ref.ninputs
    if kind != "TransferFunction":  # ss2tf drops the signal names: rename before comparing
        assert g.inputs == data.inputs and g.outputs == data.outputs
    else:
        # from the chain's own 6 states: the 12-state ref converted again is a 30-state
        # realisation with inexact cancellations near s = 0, stable or not by rounding
        sys = control.ss2tf(rc.as_statespace(systems["StateSpace"], inputs=data.inputs, outputs=data.outputs))
        sys = rc.as_statespace(sys, inputs=data.inputs, outputs=data.outputs)
    j = rc.log_cost(sys, data)
    assert np.isfinite(j) and j == pytest.approx(rc.compare(sys, data, min_channel_db=None).cost, rel=1e-9)
    assert rc.log_error(sys, data).shape == data.shape
    red = rc.balanced_truncation(sys, 4)
    assert red.sys.nstates == 4 and red.sys.ninputs == n
    cmp = rc.compare(chain, data, measurement_model=sys)
    assert cmp.mode_source == "measurement model" and len(cmp.modes) >= 1


def test_update_and_diagnose_need_parameters(data, systems):
    for call in (rc.update, rc.diagnose):
        with pytest.raises(rc.ModelError, match=r"needs a PhysicalModel; got StateSpace"):
            call(systems["StateSpace"], data)


# ---------------------------------------------------------------------------- results
def test_results_pickle_and_share_one_convention(chain, data, systems):
    mm = systems["MeasurementModel"]
    back = pickle.loads(pickle.dumps(mm))
    np.testing.assert_array_equal(back.sys.A, mm.sys.A)
    assert back.sys.input_labels == mm.sys.input_labels and back.cost.total == mm.cost.total
    np.testing.assert_allclose(rc.freqresp(back, F_HZ).response, rc.freqresp(mm, F_HZ).response)
    red = pickle.loads(pickle.dumps(systems["BalancedTruncation"]))
    assert red.sys.nstates == 6 and red.bound == systems["BalancedTruncation"].bound
    cmp = rc.compare(chain, data)
    assert pickle.loads(pickle.dumps(cmp)).cost == cmp.cost
    upd = rc.update(chain, data, params=["k_ground"], passes=1, drift_bands=0, max_iter=2)
    diag = rc.diagnose(chain, data, [fx.SensorGain("a3")], n_fit=1, update_iter=2)
    ver = rc.verify(upd.model, data, {"k_ground": 4.1e3})
    assert pickle.loads(pickle.dumps(upd)).cost_after == upd.cost_after
    assert pickle.loads(pickle.dumps(diag)).cost_nominal == diag.cost_nominal
    assert pickle.loads(pickle.dumps(ver)).comparison.cost == ver.comparison.cost
    assert pickle.loads(pickle.dumps(mm.cost)).total == mm.cost.total
    fit = mm.fit
    back_fit = pickle.loads(pickle.dumps(fit))
    np.testing.assert_array_equal(back_fit.response(F_HZ), fit.response(F_HZ))
    assert f"{fit.order} poles, {fit.n_modes} modes" in fit.summary()
    assert fit.summary().endswith(f"{fit.cost().rms_db_total:.3g} dB.")
    for result in (mm, fit, systems["BalancedTruncation"], cmp, mm.cost, upd, diag, ver):
        assert str(result.table())
        assert isinstance(result.summary(), str) and result.summary()
        assert "<table>" in result._repr_html_()
        assert result.plot() is not None
    assert "MeasurementModel of 2 outputs x 2 inputs" in mm.summary()
    assert all(isinstance(m, rc.Mode) for m in mm.modes)
    assert all(isinstance(m, rc.Mode) for m in cmp.data_modes)


def test_old_spellings_still_work_for_one_release(chain, data):
    j = rc.log_cost(chain, data, point_weights=None)
    with pytest.warns(DeprecationWarning, match=r"log_cost\(model, data\)"):
        assert rc.log_cost(data, chain, point_weights=None) == pytest.approx(j, rel=1e-14)
    with pytest.warns(DeprecationWarning, match="call it point_weights="):
        assert rc.compare(chain, data, weights=None).cost == pytest.approx(
            rc.compare(chain, data, point_weights=None).cost, rel=1e-14)
    with pytest.warns(DeprecationWarning, match="call it params="):
        rc.diagnose(chain, data, [fx.SensorGain("a3")], update_params=["k_ground"], n_fit=0, update_iter=1)
    with pytest.raises(rc.DataError, match="give point_weights= only"):
        rc.compare(chain, data, point_weights=None, weights=None if False else "coherence")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rc.log_error(chain, data)  # the new order warns about nothing


def test_anything_to_frequency_data(chain, data):
    ss = chain.statespace()
    pair = (data.f_hz, data.response)
    frd = data.to_control()
    j = rc.log_cost(ss, data, point_weights=None)
    renamed = rc.as_statespace(ss, inputs=["u1", "u2"], outputs=["y1", "y2"])  # a pair's default names
    assert rc.log_cost(renamed, pair, point_weights=None) == pytest.approx(j, rel=1e-10)
    assert rc.log_cost(ss, frd, point_weights=None) == pytest.approx(j, rel=1e-10)  # names kept
    assert rc.compare(chain, frd).cost == pytest.approx(rc.compare(chain, data, point_weights=None).cost)
    with pytest.raises(rc.DataError, match=r"^data must be a FrequencyData, a control.FrequencyResponseData"):
        rc.compare(chain, np.ones(3))
    with pytest.raises(rc.ModelError, match="is measured data, not a model"):
        rc.as_statespace(data)


# ---------------------------------------------------------------------------- generic validators
@pytest.mark.parametrize("check, bad", [
    (lambda v: rc.checks.flag(v, "overwrite"), "False"),
    (lambda v: rc.checks.flag(v, "overwrite"), 1),
    (lambda v: rc.checks.positive_number(v, "tol"), float("nan")),
    (lambda v: rc.checks.positive_number(v, "tol"), -1.0),
    (lambda v: rc.checks.positive_number(v, "tol"), True),
    (lambda v: rc.checks.integer(v, "passes", lo=1), 2.5),
    (lambda v: rc.checks.integer(v, "passes", lo=1), 0),
    (lambda v: rc.checks.probability(v, "alpha"), 1.5),
    (lambda v: rc.checks.finite_number(v, "x"), "3"),
])
def test_generic_validators_refuse_with_the_argument_named(check, bad):
    with pytest.raises(rc.RobustctlError, match=r"^(overwrite|tol|passes|alpha|x) must be"):
        check(bad)


def test_save_refuses_a_truthy_string_flag(data, tmp_path):
    path = data.save(tmp_path / "d.npz")
    with pytest.raises(rc.DataError, match=r"^overwrite must be True or False; got 'False'\.$"):
        data.save(path, overwrite="False")
    assert rc.load_frd(path).n_freq == data.n_freq


# ---------------------------------------------------------------------------- PhysicalModel
def test_a_shared_structure_is_refused_not_counted_twice(chain):
    shared = chain.build_structure()
    model = rc.PhysicalModel(params=chain.params, dynamics=chain.dynamics, structure=lambda th: shared,
                             name="shared")
    mass = fx.AddedMass("dof 3", mass=0.2)
    fresh = chain.with_effect(mass)
    first = model.with_effect(mass)
    np.testing.assert_allclose(first.freqresp(F_HZ).response, fresh.freqresp(F_HZ).response, rtol=1e-9)
    with pytest.raises(rc.ModelError, match="returned the same MatrixStructure object as an earlier build"):
        first.with_values(k_ground=5e3).statespace()  # would carry the first build's 0.2 kg too
    # a callable that returns a fresh object every time (the builders' template.copy()) builds freely
    for k in (4e3, 5e3, 6e3):
        assert fresh.with_values(k_ground=k).statespace().nstates == chain.statespace().nstates


def _frame_with_node():
    frame = rc.Frame()
    frame.add_node("a", (0.0, 0.0, 0.0))
    return frame


@pytest.mark.parametrize(
    "call, error",
    [
        (lambda: rc.makeweight("10", 1.0, 0.1), rc.RobustctlError),
        (lambda: rc.electronics.lowpass1("10"), rc.ModelError),
        (lambda: rc.electronics.lowpass1(True), rc.ModelError),
        (lambda: rc.electronics.notch(10.0, "0.1", 1.0), rc.ModelError),
        (lambda: rc.electronics.pade_delay("1e-3", 2), rc.ModelError),
        (lambda: rc.electronics.sensor_gain_error(control.ss([], [], [], [[1.0]]), "y[0]", True),
         rc.ModelError),
        (lambda: _frame_with_node().add_mass("a", True), rc.ModelError),
        (lambda: _frame_with_node().add_mass("a", "2.0"), rc.ModelError),
        (lambda: rc.fit_magnitude([1.0, 10.0], [1.0, 2.0], order=True), rc.FitError),
        (lambda: rc.fit_magnitude([1.0, 10.0], [1.0, 2.0], order=2.0), rc.FitError),
    ],
)
def test_scalar_arguments_refuse_strings_and_booleans_alike(call, error):
    with pytest.raises(error, match="number|integer|positive and finite"):
        call()


def test_scalar_checks_still_take_numpy_numbers():
    assert rc.electronics.lowpass1(np.float64(10.0)).nstates == 1
    frame = _frame_with_node().add_mass("a", np.float32(2.0))
    assert frame is not None


# ---------------------------------------------------------------------------- physical scalars
@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: rc.Frame().add_node("a", ("0", 0, 0)), "coordinates of node 'a' must be 3 numbers"),
        (lambda: rc.Frame().add_node("a", (True, 0, 0)), "coordinates of node 'a' must be 3 numbers"),
        (lambda: rc.Frame(gravity=9.81).set_gravity("no"), "enabled must be True or False"),
        (lambda: rc.Frame(gravity=9.81).set_gravity(1), "enabled must be True or False"),
        (lambda: electronics.butterworth_lowpass(True, 10.0), "order must be an integer in 1..20"),
        (lambda: electronics.pade_delay(1e-3, 2.5), "Pade order must be an integer in 1..10"),
        (lambda: electronics.pade_delay(1e-3, "2"), "Pade order must be an integer in 1..10"),
        (lambda: electronics.lowpass1("10"), "the low-pass cutoff must be a positive number"),
    ],
)
def test_physical_scalars_are_checked_by_the_shared_rules(call, match):
    """Strings, booleans and fractions where a number, a flag or an order is meant are refused
    (``checks.is_real_number``, ``checks.flag``, ``checks.is_whole_number``), as ``makeweight`` does."""
    with pytest.raises(rc.ModelError, match=match):
        call()


def test_a_frame_still_takes_numpy_coordinates_and_whole_float_orders():
    fr = rc.Frame()
    fr.add_node("a", np.array([0, 1, 2], dtype=np.int64))
    np.testing.assert_array_equal(fr.node_xyz("a"), [0.0, 1.0, 2.0])
    a = electronics.pade_delay(1e-3, 2.0)
    b = electronics.pade_delay(1e-3, np.int64(2))
    np.testing.assert_array_equal(a.A, b.A)
    assert checks.is_whole_number(3.0) and not checks.is_whole_number(3.5)
    assert not checks.is_whole_number(True) and not checks.is_whole_number(float("inf"))
