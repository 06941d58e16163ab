"""Benchmark: a design sweep (one D-K run per weight choice) serial against a local dask cluster.

Eight variants of Skogestad & Postlethwaite's distillation D-K problem (the performance weight's
integrator moved to 1e-6 ... 1e-3 rad/s), each forced through the same three D-K iterations
(``patience=10``: no stall stop, so the designs cost about the same), run by ``rc.design_sweep``
serially and with ``executor=Client(LocalCluster(2 processes, 1 thread each)).get_executor()``.

Reported separately:

* the cluster's start-up (LocalCluster + Client, once; a long-lived cluster is the use case),
* a one-design warm-up on the cluster (imports on the workers),
* the sweep's wall time serial and on the cluster, and their ratio (bounded by 2 on 2 workers),
* the shortest and longest design of the serial sweep (wall seconds, from the D-K history),
* the CPU seconds of the serial sweep and of the two workers during the cluster sweep
  (``Client.run(time.process_time)`` before and after): their ratio shows what shipping and
  scheduling add (a worker's event loop also ticks while it waits, so on a loaded machine,
  where the sweep's wall time stretches, the ratio grows with it),
* the load average before the run: on a loaded machine the wall-clock ratio says little.

Both runs must give the same peak mu per design. Run: ``python -m benchmarks sweep``.
"""

from __future__ import annotations

import os
import time

import numpy as np

import robustctl as rc

EPSILONS = tuple(float(e) for e in np.geomspace(1e-6, 1e-3, 8))
MAX_ITER = 3
TARGETS = {"same_mu_serial_and_dask": "== True", "speedup_2_workers": ">= 1.2"}


def recipes() -> dict:
    return {f"eps {e:.2g}": (rc.examples.distillation_plant(eps=e), 2, 2, rc.examples.DISTILLATION_BLOCKS)
            for e in EPSILONS}


def _worker_cpu(client) -> float:
    """CPU seconds used so far by the cluster's worker processes (summed)."""
    return float(sum(client.run(time.process_time).values()))


def _timed_serial(r: dict) -> tuple[object, float, float]:
    c0, t0 = time.process_time(), time.perf_counter()
    sweep = rc.design_sweep(r, max_iter=MAX_ITER, patience=10, progress=False)
    return sweep, time.perf_counter() - t0, time.process_time() - c0


def run() -> dict:
    import distributed

    r = recipes()
    load_before = os.getloadavg()
    serial, t_serial, cpu_serial = _timed_serial(r)
    t0 = time.perf_counter()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        t_start = time.perf_counter() - t0
        executor = client.get_executor()
        t0 = time.perf_counter()
        rc.design_sweep({"warm-up": r[next(iter(r))]}, max_iter=1, executor=executor, progress=False)
        t_warm = time.perf_counter() - t0
        cpu0, t0 = _worker_cpu(client), time.perf_counter()
        spread = rc.design_sweep(r, max_iter=MAX_ITER, patience=10, executor=executor, progress=False)
        t_dask = time.perf_counter() - t0
        cpu_dask = _worker_cpu(client) - cpu0
    same = all(abs(spread.results[k].mu_peak - serial.results[k].mu_peak) <= 1e-9 * serial.results[k].mu_peak
               for k in r)
    per_design = [sum(it.time_s for it in serial.results[k].history) for k in r]
    metrics = {
        "n_designs": len(r),
        "dk_iterations_each": MAX_ITER,
        "serial_design_s_min_max": [round(min(per_design), 2), round(max(per_design), 2)],
        "cluster_startup_s": round(t_start, 2),
        "cluster_warmup_s": round(t_warm, 2),
        "serial_wall_s": round(t_serial, 2),
        "dask_2_workers_wall_s": round(t_dask, 2),
        "speedup_2_workers": round(t_serial / t_dask, 2),
        "serial_cpu_s": round(cpu_serial, 2),
        "dask_workers_cpu_s": round(cpu_dask, 2),
        "dask_cpu_overhead_ratio": round(cpu_dask / cpu_serial, 2),
        "load_average_before": [round(x, 2) for x in load_before],
        "same_mu_serial_and_dask": bool(same),
        "mu_peaks": {k: round(v.mu_peak, 4) for k, v in serial.results.items()},
    }
    from benchmarks.run import target_met

    return {
        "name": "sweep",
        "description": f"rc.design_sweep of {len(r)} distillation D-K designs ({MAX_ITER} iterations each), "
                       "serial vs a local dask cluster of 2 processes (cluster start-up reported apart)",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": all(target_met(metrics[k], t) for k, t in TARGETS.items()),
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["sweep"]))
