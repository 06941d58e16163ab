"""Benchmark: ``rc.update`` of 5 parameters on the Caltech truss, 9 channels x 600 frequencies.

Truth: the nominal truss with Young's modulus +3 %, platform-1 mass -4 %, offset mass +5 %,
modal damping +10 % and accelerometer scaling +2 % (no missing effect).

* Case A, noise-free: the truth's frequency response on 600 linearly spaced points,
  0.5-30 Hz. Timed serially, with a 2-thread ``ThreadPoolExecutor`` and with a 2-process
  ``ProcessPoolExecutor`` (which needs a picklable model; the examples' closures are not,
  which is reported). Side by side: ``scipy.optimize.least_squares`` (trust-region
  reflective, 2-point finite differences) on the same residual and parameters.
* Case B, a simulated Caltech experiment (``rc.examples.make_experiment``: one
  white-noise SIMO run per actuator, 1 % sensor noise, 4096-point Welch estimate), the
  600 estimate points from 0.5 Hz up. Its own estimation error is a floor; the reduction
  is reported next to that of the truth model. The Hamming-window leakage of the estimate
  widens the lightly damped peaks, so the damping comes out biased by a few % (and is
  flagged as drifting across bands); the target is on the other four parameters.

Target: case A serial < 5 s. Run ``python -m benchmarks.bench_update`` (writes
``benchmarks/results/update.json``).
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import numpy as np
import scipy.optimize

import robustctl as rc

TARGET_S = 5.0
N_FREQ = 600
ERRORS = {
    "E_aluminium": 0.03,
    "m_platform_1": -0.04,
    "m_offset": 0.05,
    "zeta_modal": 0.10,
    "k_accelerometer": 0.02,
}


def _truth_values(model) -> dict[str, float]:
    return {n: model.param(n).value * (1 + e) for n, e in ERRORS.items()}


def _max_error_pct(result, truth: dict[str, float]) -> float:
    return max(abs(100 * (result.model.param(n).value / v - 1)) for n, v in truth.items())


def _timed_update(model, data, **kw):
    t0 = time.perf_counter()
    out = rc.update(model, data, params=list(ERRORS), **kw)
    return out, time.perf_counter() - t0


def _scipy_reference(model, data) -> dict:
    res = rc.Residual(model, data)
    names = list(ERRORS)
    x0 = np.array([model.param(n).value for n in names])
    lo = np.array([model.param(n).bounds[0] for n in names])
    hi = np.array([model.param(n).bounds[1] for n in names])
    t0 = time.perf_counter()
    ref = scipy.optimize.least_squares(
        lambda x: res.vector(**dict(zip(names, x))), x0, x_scale=x0, bounds=(lo, hi), ftol=1e-10, xtol=1e-10
    )
    return {
        "time_s": time.perf_counter() - t0,
        "cost": float(2 * ref.cost),
        "nfev": int(ref.nfev),
        "x": dict(zip(names, ref.x)),
    }


def _case_a(model) -> dict:
    truth = _truth_values(model)
    data = model.freqresp(np.linspace(0.5, 30.0, N_FREQ), **truth)
    serial, t_serial = _timed_update(model, data)
    with ThreadPoolExecutor(max_workers=2) as pool:
        threads, t_threads = _timed_update(model, data, executor=pool)
    try:
        with ProcessPoolExecutor(max_workers=2) as pool:
            _, t_proc = _timed_update(model, data, executor=pool)
        proc = round(t_proc, 3)
    except Exception as exc:  # noqa: BLE001 - reported, not raised
        proc = f"not run: {type(exc).__name__}: {str(exc)[:80]}"
    ref = _scipy_reference(model, data)
    ref_err = max(abs(100 * (ref["x"][n] / v - 1)) for n, v in truth.items())
    return {
        "time_serial_s": round(t_serial, 3),
        "time_2_threads_s": round(t_threads, 3),
        "time_2_processes_s": proc,
        "speedup_2_threads": round(t_serial / t_threads, 3),
        "iterations": serial.n_iter,
        "model_evaluations": serial.n_evals,
        "ms_per_evaluation": round(1e3 * t_serial / serial.n_evals, 2),
        "cost_before": round(serial.cost_before, 4),
        "cost_after": float(f"{serial.cost_after:.3g}"),
        "cost_reduction_pct": round(100 * serial.reduction, 4),
        "max_parameter_error_pct": float(f"{_max_error_pct(serial, truth):.3g}"),
        "same_history_with_threads": serial.history == threads.history,
        "selected": list(serial.selected),
        "scipy_least_squares_time_s": round(ref["time_s"], 3),
        "scipy_least_squares_nfev": ref["nfev"],
        "scipy_least_squares_cost": float(f"{ref['cost']:.3g}"),
        "scipy_least_squares_max_parameter_error_pct": float(f"{ref_err:.3g}"),
        "time_ratio_update_over_scipy": round(t_serial / ref["time_s"], 3),
    }


def _case_b(model) -> dict:
    truth = _truth_values(model)
    data, _ = rc.examples.make_experiment(model, None, param_errors=ERRORS, noise_rms=0.01, seed=0)
    f = data.f_hz
    band = (0.5, float(f[np.searchsorted(f, 0.5) + N_FREQ - 1]))
    upd, t = _timed_update(model, data, band=band, point_weights="coherence")
    j_truth = rc.compare(model.with_values(**truth), data, band=band, point_weights="coherence").cost
    return {
        "time_serial_s": round(t, 3),
        "n_frequencies": int(np.count_nonzero((f >= band[0]) & (f <= band[1]))),
        "cost_before": round(upd.cost_before, 4),
        "cost_after": round(upd.cost_after, 4),
        "cost_of_truth_model": round(j_truth, 4),
        "cost_reduction_pct": round(100 * upd.reduction, 3),
        "share_of_attainable_reduction_pct": round(
            100 * (upd.cost_before - upd.cost_after) / (upd.cost_before - j_truth), 3
        ),
        "max_parameter_error_pct_without_damping": round(
            _max_error_pct(upd, {n: v for n, v in truth.items() if n != "zeta_modal"}), 3
        ),
        "zeta_modal_error_pct": round(
            100 * (upd.model.param("zeta_modal").value / truth["zeta_modal"] - 1), 3
        ),
        "warnings": list(upd.warnings),
    }


def run() -> dict:
    """Update 5 parameters of the Caltech truss on noise-free and on estimated data."""
    with rc.blas_threads(1):
        model = rc.examples.caltech_truss()
        model.statespace()  # first build (imports, caches) outside the timings
        a = _case_a(model)
        b = _case_b(model)
    metrics = {
        "n_parameters": len(ERRORS),
        "n_channels": 9,
        "n_frequencies": N_FREQ,
        **{f"noise_free_{k}": v for k, v in a.items()},
        **{f"estimated_{k}": v for k, v in b.items()},
        "cpu_count": os.cpu_count(),
    }
    targets = {
        "noise_free_time_serial_s": f"< {TARGET_S}",
        "noise_free_cost_reduction_pct": ">= 90",
        "noise_free_max_parameter_error_pct": "< 2",
        "estimated_max_parameter_error_pct_without_damping": "< 2",
    }
    passed = bool(
        a["time_serial_s"] < TARGET_S
        and a["cost_reduction_pct"] >= 90
        and a["max_parameter_error_pct"] < 2
        and b["max_parameter_error_pct_without_damping"] < 2
    )
    return {
        "name": "update",
        "description": "rc.update of 5 parameters, Caltech truss, 9 channels x 600 frequencies "
        "(serial, 2 threads, 2 processes; scipy least_squares side by side; simulated experiment)",
        "metrics": metrics,
        "targets": targets,
        "passed": passed,
    }


def main() -> None:
    result = run()
    out = Path(__file__).parent / "results" / "update.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
