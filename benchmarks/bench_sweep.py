"""Benchmark: a design sweep (one D-K run per weight choice) serial against a local dask cluster.

Four variants of Skogestad & Postlethwaite's distillation D-K problem (the performance weight's
integrator moved to 1e-6 ... 1e-3 rad/s), three D-K iterations each, run by ``rc.design_sweep``
serially and with ``executor=Client(LocalCluster(2 processes)).get_executor()``. Reported: wall
times, the speed-up (bounded by 2 on 2 workers, less the cluster's start-up and shipping), and that
both give the same peak mu. The cluster is started before timing (a long-lived cluster is the
use case).

Run: ``python -m benchmarks sweep``.
"""

from __future__ import annotations

import time

import robustctl as rc

EPSILONS = (1e-6, 1e-5, 1e-4, 1e-3)
TARGETS = {"same_mu_serial_and_dask": "== True", "speedup_2_workers": ">= 1.2"}


def recipes() -> dict:
    return {f"eps {e:g}": (rc.examples.distillation_plant(eps=e), 2, 2, rc.examples.DISTILLATION_BLOCKS)
            for e in EPSILONS}


def run() -> dict:
    import distributed

    r = recipes()
    t0 = time.perf_counter()
    serial = rc.design_sweep(r, max_iter=3, progress=False)
    t_serial = time.perf_counter() - t0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        executor = client.get_executor()
        rc.design_sweep({"warm-up": r[next(iter(r))]}, max_iter=1, executor=executor, progress=False)
        t0 = time.perf_counter()
        spread = rc.design_sweep(r, max_iter=3, executor=executor, progress=False)
        t_dask = time.perf_counter() - t0
    same = all(abs(spread.results[k].mu_peak - serial.results[k].mu_peak) <= 1e-9 * serial.results[k].mu_peak
               for k in r)
    metrics = {
        "n_designs": len(r),
        "serial_wall_s": round(t_serial, 2),
        "dask_2_workers_wall_s": round(t_dask, 2),
        "speedup_2_workers": round(t_serial / t_dask, 2),
        "same_mu_serial_and_dask": bool(same),
        "mu_peaks": {k: round(v.mu_peak, 4) for k, v in serial.results.items()},
    }
    from benchmarks.run import target_met

    return {
        "name": "sweep",
        "description": "rc.design_sweep of 4 distillation D-K designs (3 iterations), serial vs a local "
                       "dask cluster of 2 processes",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": all(target_met(metrics[k], t) for k, t in TARGETS.items()),
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["sweep"]))
