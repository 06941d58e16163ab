"""Models travel to process and cluster executors: they pickle by value (closures included)
and their caches are safe under threads."""

import pickle
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.residual import Residual, sensitivities
from robustctl.physical import effects as fx


def _chain():
    return rc.structural_model(
        lambda th: np.diag([1.0, th["m2"]]),
        1e3 * np.array([[3.0, -1.0], [-1.0, 1.0]]),
        inputs={"F": "dof 1"},
        outputs={"a2": ("dof 2", "acceleration")},
        params=[rc.Parameter("m2", 0.5, "kg", (0.1, 2.0))],
        damping=0.02,
    )


def test_example_model_with_effect_round_trips_through_pickle():
    model = rc.examples.caltech_truss().with_effect(fx.OutputDelay(delay=2e-3))
    clone = pickle.loads(pickle.dumps(model))
    f = np.linspace(0.5, 50.0, 40)
    assert clone.param_names == model.param_names
    np.testing.assert_array_equal(clone.freqresp(f).response, model.freqresp(f).response)


def test_sensitivities_on_a_process_pool_equal_serial_ones():
    model = _chain()
    data = model.freqresp(np.linspace(1.0, 20.0, 60), m2=0.55)
    residual = Residual(model, data)
    j0, serial = sensitivities(residual, ["m2", "zeta_modal"])
    with ProcessPoolExecutor(2) as pool:
        _, parallel = sensitivities(residual, ["m2", "zeta_modal"], executor=pool)
    np.testing.assert_allclose(parallel, serial, rtol=1e-12, atol=0)


def test_model_cache_is_consistent_under_threads():
    model = _chain()
    values = np.linspace(0.3, 1.5, 24)
    expected = [model.freqresp([5.0], m2=v).response[0, 0, 0] for v in values]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda v: model.freqresp([5.0], m2=v).response[0, 0, 0], values))
    assert got == pytest.approx(expected, rel=1e-13)
