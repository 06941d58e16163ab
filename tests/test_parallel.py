"""executor= on a real distributed engine: a local dask cluster of processes gives the serial answer."""

import numpy as np
import pytest

import robustctl as rc
from robustctl.parallel import parallel_map

F_HZ = np.linspace(0.5, 40.0, 300)


def _chain():
    """Three masses on a grounded spring (k_ground), two sensors, two actuators."""
    m = np.diag([2.0, 1.0, 0.5])
    kc = 1e3 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    k_par = rc.Parameter("k_ground", 4e3, "N/m", (1e3, 1e4), meaning="ground spring of mass 1")
    return rc.structural_model(
        m, lambda th: kc + np.diag([th["k_ground"], 0.0, 0.0]),
        inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"a2": ("dof 2", "acceleration"), "a3": ("dof 3", "acceleration")},
        damping=0.02, params=[k_par], name="3-mass chain",
    )


def _square(x):
    return x * x


def test_parallel_map_keeps_order_and_refuses_a_non_executor():
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(3) as ex:
        assert parallel_map(_square, range(20), ex) == [i * i for i in range(20)]
    assert parallel_map(_square, [3, 1], None) == [9, 1]
    with pytest.raises(rc.RobustctlError, match="executor must be a concurrent.futures.Executor"):
        parallel_map(_square, [1], "threads")


def test_diagnose_refuses_a_string_executor_before_any_work():
    model = _chain()
    data = model.freqresp(F_HZ)
    with pytest.raises(rc.RobustctlError, match="executor must be"):
        rc.diagnose(model, data, executor="threads")


@pytest.mark.slow
def test_diagnose_on_a_local_dask_cluster_matches_serial():
    distributed = pytest.importorskip("distributed", reason="install robustctl[distributed] for dask")
    model = _chain()
    truth = model.with_values(k_ground=4.2e3).with_effect(rc.effects.AddedMass("dof 3", mass=0.05))
    rng = np.random.default_rng(0)
    g = truth.freqresp(F_HZ).response
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs)

    serial = rc.diagnose(model, data)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        spread = rc.diagnose(model, data, executor=client.get_executor())
    assert spread.best.name == serial.best.name
    assert [c.name for c in spread.ranking[:5]] == [c.name for c in serial.ranking[:5]]
    for a, b in zip(spread.ranking[:5], serial.ranking[:5]):
        assert a.cost == pytest.approx(b.cost, rel=1e-9)
        assert a.p_value == pytest.approx(b.p_value, rel=1e-6, nan_ok=True)
    assert spread.best.values == pytest.approx(serial.best.values, rel=1e-9)


def _distillation(eps):
    return (rc.examples.distillation_plant(eps=eps), 2, 2, rc.examples.DISTILLATION_BLOCKS)


@pytest.mark.slow
def test_design_sweep_on_a_local_dask_cluster_matches_serial():
    distributed = pytest.importorskip("distributed", reason="install robustctl[distributed] for dask")
    recipes = {"eps 1e-6": _distillation(1e-6), "eps 1e-4": _distillation(1e-4)}
    serial = rc.design_sweep(recipes, max_iter=2)
    # iteration 1 of the book's example (Skogestad & Postlethwaite Table 8.2): 1.1818
    assert serial.results["eps 1e-6"].history[0].mu_peak == pytest.approx(1.1818, abs=0.005)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        spread = rc.design_sweep(recipes, max_iter=2, executor=client.get_executor())
    assert spread.labels == serial.labels and spread.best == serial.best
    for k in recipes:
        assert spread.results[k].mu_peak == pytest.approx(serial.results[k].mu_peak, rel=1e-9)
    assert "best" in serial.table().title and serial.plot() is not None


def test_design_sweep_refuses_bad_recipes():
    with pytest.raises(rc.SynthesisError, match="non-empty mapping"):
        rc.design_sweep([])
    with pytest.raises(rc.RobustctlError, match="executor must be"):
        rc.design_sweep({"a": _distillation(1e-6)}, executor="dask")
