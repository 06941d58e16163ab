"""executor= on a real distributed engine: a local dask cluster of processes gives the serial answer."""

import numpy as np
import pytest

import robustctl as rc
from robustctl.executors import parallel_map

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


@pytest.fixture(scope="module")
def dask_client():
    """A local dask cluster of 2 worker processes (one thread each), shared by the module's tests."""
    distributed = pytest.importorskip("distributed", reason="install robustctl[distributed] for dask")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        yield client


def _square(x):
    return x * x


def test_parallel_map_keeps_order_and_refuses_a_non_executor():
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(3) as ex:
        assert parallel_map(_square, range(20), ex) == [i * i for i in range(20)]
    assert parallel_map(_square, [3, 1], None) == [9, 1]
    with pytest.raises(rc.RobustctlError, match="executor must be a concurrent.futures.Executor"):
        parallel_map(_square, [1], "threads")


def _pid_and_payload(shared, item):
    import os

    return os.getpid(), id(shared), shared["offset"] + item


def test_parallel_map_shared_keeps_order_and_sends_the_payload_once_per_worker():
    from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

    from robustctl.executors import parallel_map_shared

    shared = {"offset": 100, "ballast": np.zeros(10_000)}
    with ProcessPoolExecutor(2) as ex:
        out = parallel_map_shared(_pid_and_payload, shared, range(37), ex)
    assert [r[2] for r in out] == [100 + i for i in range(37)]
    per_worker = {}
    for pid, ident, _ in out:  # one unpickled payload per worker, whatever chunks it ran
        per_worker.setdefault(pid, set()).add(ident)
    assert all(len(ids) == 1 for ids in per_worker.values())
    with ThreadPoolExecutor(2) as ex:  # threads share it in memory
        assert {r[1] for r in parallel_map_shared(_pid_and_payload, shared, range(5), ex)} == {id(shared)}
    assert [r[2] for r in parallel_map_shared(_pid_and_payload, shared, [3, 1], None)] == [103, 101]


class _Payload:
    offset = 7


def _pid_and_object(shared, item):
    import os

    return os.getpid(), id(shared), shared.offset + item


def test_the_same_payload_object_is_unpickled_once_per_worker_across_calls():
    from concurrent.futures import ProcessPoolExecutor

    from robustctl.executors import parallel_map_shared

    payload = _Payload()
    with ProcessPoolExecutor(1) as ex:  # one worker: every chunk of both calls runs there
        first = parallel_map_shared(_pid_and_object, payload, range(6), ex)
        second = parallel_map_shared(_pid_and_object, payload, range(6), ex)
        other = parallel_map_shared(_pid_and_object, _Payload(), range(3), ex)
    assert [r[2] for r in second] == [7 + i for i in range(6)]
    assert len({r[1] for r in first + second}) == 1  # the worker kept its copy
    assert {r[1] for r in other}.isdisjoint({r[1] for r in first})  # another object: a new copy


def test_workers_auto_stays_serial_on_one_core_or_few_tasks(monkeypatch):
    import importlib

    parallel = importlib.import_module("robustctl.executors")

    monkeypatch.setattr(parallel, "available_cores", lambda: 1)
    assert parallel.resolve_workers("auto", 500, 24) == 1
    monkeypatch.setattr(parallel, "available_cores", lambda: 4)
    assert parallel.resolve_workers("auto", 10, 24) == 1  # too few tasks to pay for the workers
    assert parallel.resolve_workers("auto", 500, 24) == 4
    monkeypatch.setattr(parallel, "available_cores", lambda: 64)
    assert parallel.resolve_workers("auto", 500, 24) == parallel.MAX_AUTO_WORKERS
    assert parallel.resolve_workers(3, 2, 24) == 2 and parallel.resolve_workers(None, 500, 24) == 1
    with parallel.process_pool("auto", 10, 24) as pool:
        assert pool is None
    for bad in (0, -2, 1.5, True, "two"):
        with pytest.raises(rc.RobustctlError, match="workers must be"):
            parallel.resolve_workers(bad, 10, 1)


def test_diagnose_refuses_a_string_executor_before_any_work():
    model = _chain()
    data = model.freqresp(F_HZ)
    with pytest.raises(rc.RobustctlError, match="executor must be"):
        rc.diagnose(model, data, executor="threads")


@pytest.mark.slow
def test_diagnose_on_a_local_dask_cluster_matches_serial(dask_client):
    model = _chain()
    truth = model.with_values(k_ground=4.2e3).with_effect(rc.effects.AddedMass("dof 3", mass=0.05))
    rng = np.random.default_rng(0)
    g = truth.freqresp(F_HZ).response
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs)

    serial = rc.diagnose(model, data)
    spread = rc.diagnose(model, data, executor=dask_client.get_executor())
    assert spread.best.name == serial.best.name
    assert [c.name for c in spread.ranking[:5]] == [c.name for c in serial.ranking[:5]]
    for a, b in zip(spread.ranking[:5], serial.ranking[:5]):
        assert a.cost == pytest.approx(b.cost, rel=1e-9)
        assert a.p_value == pytest.approx(b.p_value, rel=1e-6, nan_ok=True)
    assert spread.best.values == pytest.approx(serial.best.values, rel=1e-9)


def _distillation(eps):
    return (rc.examples.distillation_plant(eps=eps), 2, 2, rc.examples.DISTILLATION_BLOCKS)


@pytest.mark.slow
def test_design_sweep_on_a_local_dask_cluster_matches_serial(dask_client):
    recipes = {"eps 1e-6": _distillation(1e-6), "eps 1e-4": _distillation(1e-4)}
    # the book's units, unscaled, so that iteration 1 is Skogestad & Postlethwaite Table 8.2's 1.1818
    serial = rc.design_sweep(recipes, max_iter=2, autoscale=False)
    assert serial.results["eps 1e-6"].history[0].mu_peak == pytest.approx(1.1818, abs=0.005)
    spread = rc.design_sweep(recipes, max_iter=2, autoscale=False, executor=dask_client.get_executor())
    assert spread.labels == serial.labels and spread.best == serial.best
    for k in recipes:
        assert spread.results[k].mu_peak == pytest.approx(serial.results[k].mu_peak, rel=1e-9)
    assert "best" in serial.table().title and serial.plot() is not None


def test_design_sweep_refuses_bad_recipes():
    with pytest.raises(rc.SynthesisError, match="non-empty mapping"):
        rc.design_sweep([])
    with pytest.raises(rc.RobustctlError, match="executor must be"):
        rc.design_sweep({"a": _distillation(1e-6)}, executor="dask")


def _lightly_damped_4x4():
    """A 4x4 system of five lightly damped modes (0.8-31 Hz, 1-3 % damping) with random shapes."""
    import control

    rng = np.random.default_rng(11)
    f_n, zeta = np.array([0.8, 2.5, 6.0, 14.0, 31.0]), np.array([0.01, 0.02, 0.015, 0.03, 0.01])
    w = 2 * np.pi * f_n
    A = np.zeros((10, 10))
    for k, (wk, zk) in enumerate(zip(w, zeta)):
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[0.0, 1.0], [-wk**2, -2 * zk * wk]]
    B = np.zeros((10, 4))
    B[1::2] = rng.standard_normal((5, 4))
    C = np.zeros((4, 10))
    C[:, 1::2] = rng.standard_normal((4, 5))
    return control.ss(A, B, C, 0.5 * rng.standard_normal((4, 4)))


@pytest.mark.slow
def test_mu_over_a_large_grid_on_a_local_dask_cluster_matches_serial(dask_client):
    """mu's frequency grid split into 8 chunks on 2 dask worker processes: the same bounds as
    the same chunks computed serially (to rounding), and as the unchunked serial run."""
    G = _lightly_damped_4x4()
    f_hz = np.geomspace(0.1, 100.0, 800)
    blocks = [[1, 0], [1, 0], [2, 2]]  # two complex scalars and a full 2x2 block
    whole = rc.mu(G, blocks, f_hz)
    chunked = rc.mu(G, blocks, f_hz, chunk=100)
    spread = rc.mu(G, blocks, f_hz, chunk=100, executor=dask_client.get_executor())
    assert spread.info["n_chunks"] == chunked.info["n_chunks"] == 8
    np.testing.assert_allclose(spread.upper, chunked.upper, rtol=1e-12)
    np.testing.assert_allclose(spread.lower, chunked.lower, rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(spread.d_scales, chunked.d_scales, rtol=1e-9)
    np.testing.assert_allclose(spread.upper, whole.upper, rtol=1e-3)
    assert spread.peak == pytest.approx(whole.peak, rel=1e-3)
    assert spread.f_peak_hz == whole.f_peak_hz
    # the bounds bracket mu: spectral radius <= lower <= upper <= largest singular value
    M = rc.freqresp(G, f_hz).response
    sigma = np.linalg.svd(M, compute_uv=False)[:, 0]
    rho = np.abs(np.linalg.eigvals(M)).max(axis=1)
    assert np.all(spread.upper <= sigma * (1 + 1e-9))
    assert np.all(spread.lower <= spread.upper * (1 + 1e-9))
    assert np.all(spread.upper >= rho * (1 - 1e-9))
    assert np.median(spread.lower / spread.upper) > 0.9  # a lower bound that works, not zeros


def test_process_pool_carries_systems_with_lambdas():
    """A ProcessPoolExecutor gets python-control systems (which hold a lambda and do not pickle
    with the standard pickle) and local functions through cloudpickle: same answers as serial."""
    from concurrent.futures import ProcessPoolExecutor

    import control

    from robustctl.executors import parallel_map

    systems = [control.ss([[-k]], [[1.0]], [[1.0]], [[0.0]]) for k in (1.0, 2.0, 4.0)]
    scale = 3.0

    def dc_gain_times_scale(sys):  # a local function: standard pickle refuses it
        return control.ss(sys.A, sys.B, scale * sys.C, sys.D)

    with ProcessPoolExecutor(2) as pool:
        out = parallel_map(dc_gain_times_scale, systems, pool, progress=False)
    assert [float(control.dcgain(s)) for s in out] == [3.0, 1.5, 0.75]


def test_auto_workers_fork_only_on_linux(monkeypatch):
    """macOS offers fork but its system libraries are not fork-safe: "auto" stays serial there
    (and on Windows), and an explicit worker count uses the platform's default start method."""
    import importlib

    parallel = importlib.import_module("robustctl.executors")
    monkeypatch.setattr(parallel, "available_cores", lambda: 4)
    monkeypatch.setattr(parallel.sys, "platform", "darwin")
    assert parallel.resolve_workers("auto", 100, 10) == 1
    assert parallel.resolve_workers(3, 100, 10) == 3
    monkeypatch.setattr(parallel.sys, "platform", "linux")
    expected = 4 if "fork" in parallel.multiprocessing.get_all_start_methods() else 1
    assert parallel.resolve_workers("auto", 100, 10) == expected
    assert parallel.resolve_workers("auto", 5, 10) == 1  # too few tasks
