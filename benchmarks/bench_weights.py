"""Benchmark: ``rc.fit_magnitude`` (the D-scale / weight fit of D-K iteration and covers).

Cases: D-scale-like magnitude curves (products of three seeded random first-order
factors, each changing the level by at most 20 dB, 0.01-100 Hz) on 50, 100 and 200
log-spaced points, fitted at orders 2, 4 and 6, plain (log-Chebyshev) and as an upper
bound; plus the Caltech seed's eq. 14 recovered from
its own curve. Reported: CPU time per call (process time, best of 2: robust to other jobs
on a shared machine), LPs per call, the fit's max log error against the curve's true order
(a curve of order <= the fit's must come out exact), and whether every result is stable,
minimum phase and (upper bound) covering. There is no Python counterpart of MATLAB's
``fitmagfrd`` to time against; the target is the time D-K can afford (dozens of calls).

Run: ``python -m benchmarks weights``.
"""

from __future__ import annotations

import time

import numpy as np

from robustctl.lti import freqresp_array
from robustctl.robust import caltech_additive_weight, fit_magnitude_details

TARGETS = {
    "median_cpu_ms_per_fit": "<= 100",
    "eq14_recovery_error_db": "< 0.01",
    "exact_cases_max_error_db": "< 0.1",
    "all_stable_minimum_phase": "== 1",
    "all_upper_bounds_cover": "== 1",
}


def curve(f_hz: np.ndarray, order: int, seed: int) -> np.ndarray:
    """|G| of a seeded random stable, minimum-phase G of the given order (a D-scale-like shape)."""
    rng = np.random.default_rng(seed)
    s = 2j * np.pi * f_hz
    g = np.ones_like(s)
    for _ in range(order):  # each factor changes the level by at most 20 dB (a D-scale's range)
        z = 2 * np.pi * 10 ** rng.uniform(-1.5, 1.5)
        p = z * 10 ** rng.uniform(-1.0, 1.0)
        g *= (s + z) / (s + p)
    return np.abs(g)


def _timed(fn, *args, **kwargs):
    best, out = np.inf, None
    for _ in range(2):
        c0 = time.process_time()
        out = fn(*args, **kwargs)
        best = min(best, time.process_time() - c0)
    return best, out


def run() -> dict:
    rows, ok_stable, ok_cover, exact_err = [], True, True, 0.0
    for n_pts in (50, 100, 200):
        f = np.geomspace(0.01, 100.0, n_pts)
        for order in (2, 4, 6):
            mag = curve(f, min(order, 3), seed=order + n_pts)
            for upper in (False, True):
                t, fit = _timed(fit_magnitude_details, f, mag, order, upper_bound=upper)
                W = fit.system
                ok_stable &= bool(np.all(W.poles().real < 0) and np.all(W.zeros().real < 0))
                got = np.abs(freqresp_array(W, f)[:, 0, 0])
                if upper:
                    ok_cover &= bool(np.all(got >= mag))
                elif order >= 3:
                    exact_err = max(exact_err, fit.max_error_db)
                rows.append((n_pts, order, upper, 1e3 * t, fit.n_lp, fit.max_error_db))
    f = np.geomspace(0.01, 1000.0, 120)
    t14, fit14 = _timed(
        lambda: fit_magnitude_details(
            f, np.abs(freqresp_array(caltech_additive_weight(), f)[:, 0, 0]), 3, tol_db=1e-3
        )
    )
    cpu = np.array([r[3] for r in rows])
    metrics = {
        "median_cpu_ms_per_fit": round(float(np.median(cpu)), 1),
        "max_cpu_ms_per_fit": round(float(cpu.max()), 1),
        "median_lps_per_fit": float(np.median([r[4] for r in rows])),
        "cpu_ms_by_points_50_100_200": [
            round(float(np.median([r[3] for r in rows if r[0] == n])), 1) for n in (50, 100, 200)
        ],
        "eq14_recovery_error_db": float(f"{fit14.max_error_db:.3g}"),
        "eq14_cpu_ms": round(1e3 * t14, 1),
        "exact_cases_max_error_db": float(f"{exact_err:.3g}"),
        "all_stable_minimum_phase": int(ok_stable),
        "all_upper_bounds_cover": int(ok_cover),
        "n_fits": len(rows),
    }
    passed = bool(
        metrics["median_cpu_ms_per_fit"] <= 100
        and metrics["eq14_recovery_error_db"] < 0.01
        and exact_err < 0.1
        and ok_stable
        and ok_cover
    )
    return {
        "name": "weights",
        "description": "rc.fit_magnitude: 50-200 points, orders 2/4/6, plain and upper bound; "
        "eq. 14 recovery",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": passed,
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["weights"]))
