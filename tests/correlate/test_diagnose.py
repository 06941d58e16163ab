"""rc.diagnose on small exact models: ranking, recovered values, significance, API, bad input."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.diagnosis import effective_points
from robustctl.physical import effects as fx

F_HZ = np.linspace(0.5, 40.0, 400)
M3 = np.diag([2.0, 1.0, 0.5])
KC = 1e3 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])  # the two coupling springs
KGEO = np.array([[1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])


def _chain():
    """Three masses on a grounded spring (parameter k_ground), 2 sensors, 2 actuators."""
    k_par = rc.Parameter("k_ground", 4e3, "N/m", (1e3, 1e4), meaning="ground spring of mass 1")

    def stiffness(th):
        return KC + np.diag([th["k_ground"], 0.0, 0.0])

    return rc.structural_model(
        M3, stiffness, inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"a2": ("dof 2", "acceleration"), "a3": ("dof 3", "acceleration")},
        damping=0.02, params=[k_par], stiffness_groups={"coupling": KC},
        geometric_stiffness={"coupling": KGEO}, name="3-mass chain",
    )


def _data(model, hidden=None, k_error=0.03, noise=0.01, seed=0):
    truth = model.with_values(k_ground=model.param("k_ground").value * (1 + k_error))
    if hidden is not None:
        truth = truth.with_effect(hidden)
    g = truth.freqresp(F_HZ).response
    rng = np.random.default_rng(seed)
    g = g * np.exp(noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    return rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs)


#: the synthetic log noise of _data is known: 0.01 in the real and in the imaginary part
KNOWN = rc.NoiseModel(F_HZ, np.full((F_HZ.size, 2, 2), 0.01), "synthetic log noise of 0.01 (known)")


@pytest.fixture(scope="module")
def chain():
    return _chain()


@pytest.fixture(scope="module")
def cands(chain):
    return fx.candidates(chain)


@pytest.mark.parametrize(
    "hidden",
    [fx.OutputDelay(delay=4e-3), fx.AddedMass("dof 3", mass=0.05),
     fx.SuspensionSpring("dof 2", stiffness=150.0), fx.GroupTension("coupling", tension=60.0),
     fx.SensorGain("a3", error=0.08)],
    ids=lambda e: e.kind,
)
def test_diagnose_ranks_the_hidden_effect_first_and_recovers_it(chain, cands, hidden):
    diag = rc.diagnose(chain, _data(chain, hidden), cands, params=["k_ground", "zeta_modal"], noise=KNOWN)
    top = diag.ranking[0]
    assert (top.kind, top.location) == (hidden.kind, hidden.location)
    assert diag.best is not None and diag.best.name == hidden.name
    (true_value,) = hidden.values.values()
    (fitted,) = diag.best.values.values()
    assert fitted == pytest.approx(true_value, rel=0.1)  # short local fit; rc.update refines
    assert top.significant and top.gain > 0.8 and top.p_value < 1e-6
    assert hidden.name.split(" ")[0] in top.sentence and "%" in top.sentence


def test_parameter_errors_alone_give_no_significant_effect(chain, cands):
    diag = rc.diagnose(chain, _data(chain, None, k_error=0.05), cands,
                       params=["k_ground", "zeta_modal"], noise=KNOWN)
    assert diag.best is None and diag.best_result is None
    assert diag.cost_update < 0.05 * diag.cost_nominal  # the update parameter explains the error
    text = diag.summary()
    assert "No candidate effect is significant" in text and "sits in" in text


def test_a_delay_on_all_outputs_is_flagged_as_indistinguishable_from_one_on_all_inputs(chain, cands):
    diag = rc.diagnose(chain, _data(chain, fx.OutputDelay(delay=4e-3)), cands, noise=KNOWN)
    top = diag.ranking[0]
    assert top.kind == "output_delay" and "input delay" in top.equivalent
    assert "input delay" not in [r.name for r in diag.ranking]
    assert "cannot tell it from" in top.sentence


def test_diagnosis_table_summary_html_and_plot(chain, cands):
    diag = rc.diagnose(chain, _data(chain, fx.AddedMass("dof 3", mass=0.05)), cands, noise=KNOWN)
    table = diag.table()
    assert table.rows[0][1] == "added mass at dof 3" and table.rows[0][-1] is True
    assert "Proposed: 0.0" in diag.summary() and "kg of added mass at dof 3 explains" in diag.summary()
    assert "<table" in diag._repr_html_()
    fig = diag.plot()
    assert len(fig.axes) == 2
    assert diag.n_eff <= diag.n and 0 <= diag.rho < 1 and diag.n_evals > len(cands)


def test_executor_gives_the_same_ranking(chain, cands):
    data = _data(chain, fx.SuspensionSpring("dof 2", stiffness=150.0))
    serial = rc.diagnose(chain, data, cands[:12], noise=KNOWN)
    with ThreadPoolExecutor(max_workers=2) as pool:
        par = rc.diagnose(chain, data, cands[:12], executor=pool, noise=KNOWN)
    assert [r.name for r in par.ranking] == [r.name for r in serial.ranking]
    np.testing.assert_allclose([r.gain for r in par.ranking], [r.gain for r in serial.ranking], rtol=1e-9)


@pytest.mark.parametrize("start", ["fork", "spawn"])
def test_worker_processes_give_the_serial_result(chain, cands, start, monkeypatch):
    """workers=2 (processes forked on Linux, spawned elsewhere; the model and data sent once per
    worker) equals workers=1 to the last digit: same ranking, costs, fitted values, p-values
    and evaluation count."""
    import importlib

    if start == "spawn":  # what macOS and Windows do
        monkeypatch.setattr(importlib.import_module("robustctl.executors"), "_fork_is_safe", lambda: False)
    data = _data(chain, fx.AddedMass("dof 3", mass=0.05))
    serial = rc.diagnose(chain, data, cands, noise=KNOWN, workers=1)
    par = rc.diagnose(chain, data, cands, noise=KNOWN, workers=2)
    assert [r.name for r in par.ranking] == [r.name for r in serial.ranking]
    assert serial.ranking[0].name == "added mass at dof 3"
    for a, b in zip(par.ranking, serial.ranking):
        assert (a.cost, a.fraction, a.fitted, a.values) == (b.cost, b.fraction, b.fitted, b.values)
        assert a.p_value == b.p_value or (np.isnan(a.p_value) and np.isnan(b.p_value))
    assert par.n_evals == serial.n_evals and par.best.values == serial.best.values
    with pytest.raises(rc.RobustctlError, match="workers must be"):
        rc.diagnose(chain, data, cands, workers=0)


def test_default_candidates_calibrated_beside_the_null_fit_give_the_serial_result(chain, monkeypatch):
    """With worker processes the default candidates are calibrated by a second thread while the main
    thread runs the null fit: the result equals the serial one to the last digit."""
    import importlib
    import threading

    pipeline = importlib.import_module("robustctl.correlate.diagnosis.pipeline")
    seen = []

    def calibrate(*args):
        seen.append(threading.current_thread() is threading.main_thread())
        return calibrate.original(*args)

    calibrate.original = pipeline._default_candidates
    monkeypatch.setattr(pipeline, "_default_candidates", calibrate)
    data = _data(chain, fx.AddedMass("dof 3", mass=0.05))
    serial = rc.diagnose(chain, data, noise=KNOWN, workers=1, chain=False)
    par = rc.diagnose(chain, data, noise=KNOWN, workers=2, chain=False)
    assert seen == [True, False]  # serial: in order on the main thread; workers: beside it
    assert serial.ranking[0].name == "added mass at dof 3"
    same = [(r.name, r.cost, r.values) for r in serial.ranking]
    assert [(r.name, r.cost, r.values) for r in par.ranking] == same
    assert par.n_evals == serial.n_evals and par.update_values == serial.update_values


def test_a_model_that_cannot_be_pickled_is_diagnosed_in_this_process(chain, cands):
    """Worker processes need the model pickled; one holding a lock is diagnosed serially, with
    a RuntimeWarning saying why, and gives the serial answer."""
    import threading

    lock = threading.Lock()
    k_par = chain.param("k_ground")

    def stiffness(th):
        with lock:  # an unpicklable object in the build closure
            return KC + np.diag([th["k_ground"], 0.0, 0.0])

    model = rc.structural_model(
        M3, stiffness, inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"a2": ("dof 2", "acceleration"), "a3": ("dof 3", "acceleration")},
        damping=0.02, params=[k_par], name="3-mass chain with a lock",
    )
    data = _data(chain, fx.AddedMass("dof 3", mass=0.05))
    some = [c for c in cands if c.domain == "io" or c.kind == "added_mass"]
    with pytest.warns(RuntimeWarning, match="cannot be sent to worker processes") as caught:
        par = rc.diagnose(model, data, some, noise=KNOWN, workers=2)
    assert sum("worker processes" in str(w.message) for w in caught) == 1  # said once, not per stage
    serial = rc.diagnose(model, data, some, noise=KNOWN, workers=1)
    assert par.ranking[0].name == serial.ranking[0].name == "added mass at dof 3"
    assert [r.cost for r in par.ranking] == [r.cost for r in serial.ranking]


def test_workers_auto_starts_no_process_for_a_small_diagnosis(chain, cands, monkeypatch):
    """22 candidates at about a millisecond each: forking would cost more than the screening."""
    import importlib
    import types

    parallel = importlib.import_module("robustctl.executors")

    def refuse(*args, **kwargs):
        raise AssertionError("a process pool was started")

    monkeypatch.setattr(parallel, "ProcessPoolExecutor", refuse)
    monkeypatch.setattr(parallel, "available_cores", lambda: 4)
    # the nominal evaluation timed at 1 ms whatever the machine's load: the rule, not the clock
    pipeline = importlib.import_module("robustctl.correlate.diagnosis.pipeline")
    ticks = iter(np.arange(0.0, 1e3, 1e-3))
    monkeypatch.setattr(pipeline, "time", types.SimpleNamespace(perf_counter=lambda: next(ticks)))
    diag = rc.diagnose(chain, _data(chain, fx.AddedMass("dof 3", mass=0.05)), cands, noise=KNOWN)
    assert diag.ranking[0].name == "added mass at dof 3"
    with pytest.raises(AssertionError, match="pool was started"):  # asked for: started
        rc.diagnose(chain, _data(chain), cands, noise=KNOWN, workers=2)


def test_effective_points_of_white_and_correlated_residuals():
    rng = np.random.default_rng(1)
    white = rng.standard_normal((2000, 2, 2)) + 1j * rng.standard_normal((2000, 2, 2))
    n_eff, rho = effective_points(white)
    assert n_eff == pytest.approx(white.size * 2, rel=0.1) and rho < 0.05
    x = np.zeros((2000, 1, 1), dtype=complex)
    for k in range(1, 2000):  # AR(1), rho = 0.8: n_eff = n (1 - 0.8) / (1 + 0.8)
        x[k] = 0.8 * x[k - 1] + rng.standard_normal() + 1j * rng.standard_normal()
    n_eff, rho = effective_points(x)
    assert rho == pytest.approx(0.8, abs=0.05) and n_eff == pytest.approx(4000 * 0.2 / 1.8, rel=0.3)


# ---------------------------------------------------------------------------- bad input
def test_bad_input_is_refused_with_the_fix(chain, cands):
    data = _data(chain)
    with pytest.raises(rc.DataError, match="holds 0 data point"):
        rc.diagnose(chain, data, cands, band=(100.0, 200.0))
    with pytest.raises(rc.ModelError, match="unknown location 'dof 9'"):
        rc.diagnose(chain, data, [fx.AddedMass("dof 9")])
    with pytest.raises(rc.ModelError, match="unknown update parameter"):
        rc.diagnose(chain, data, cands, params=["E_steel"])
    with pytest.raises(rc.ModelError, match="must be Effect objects"):
        rc.diagnose(chain, data, ["output delay"])
    modal = rc.modal_model([2.0, 5.0], 0.02, [[1.0, 0.5]], [[1.0, -0.3]], inputs=["u"], outputs=["y"])
    g = modal.freqresp(F_HZ)
    with pytest.raises(rc.ModelError, match="no structural description"):
        rc.diagnose(modal, g, [fx.AddedMass("dof 1")])
    with pytest.raises(rc.DataError, match="FrequencyData"):
        rc.diagnose(chain, g.response, cands)
    with pytest.raises(rc.FitError, match="n_fit is the number"):
        rc.diagnose(chain, data, cands, n_fit=-1)


def test_a_resonator_whose_frequency_is_fitted_to_its_floor_is_at_its_bound():
    # a mass on a 1 mHz mount is no resonator in a 0.5-50 Hz band: in 1 g its weight preloads the
    # structure like a tension, and it once ranked first in place of the taut wires it mimicked
    from robustctl.correlate.diagnosis.significance import _at_bound

    screened = fx.AttachedResonator("n1", direction="z", frequency=1.73)
    freq = screened.param_names[1]
    lo = screened.parameters[1].bounds[0]
    fitted = screened.with_values(mass=4.58, frequency=lo)
    assert _at_bound(fitted, 4.58, {freq: lo}, screened)
    assert not _at_bound(fitted, 4.58, {freq: 1.8}, screened)
    assert not _at_bound(fitted, 4.58)
    assert _at_bound(fitted, screened.parameters[0].bounds[1])
