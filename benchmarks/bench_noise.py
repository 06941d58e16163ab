"""Benchmark: the noise model of an H1 estimate and the verdicts built on it (issue 12).

1. **Variance formula** -- Bendat & Piersol's random error of ``|H1|`` and phase,
   ``sqrt(1 - g2) / (|g| sqrt(2 n_d))`` with Welch's effective averages, against a Monte-Carlo
   of 200 seeds of ``rc.simulate_experiment`` + ``rc.estimate_frf`` (12 Hz, 5 %-damped
   oscillator, 256-point Hamming windows, 31 averages, output noise): the median ratio of
   observed to predicted standard deviation of ``ln|H1|`` and of the phase over the points
   where the predicted error is below 0.2 (the formula's small-error regime). Target: within
   15 % of 1.
2. **Calibration** -- the true Caltech truss against its own simulated data
   (``rc.examples.caltech_truss_experiment``), 0.5-50 Hz, seen through the H1 estimator: the
   mean normalised squared error (1 for a residual that is pure noise) and the verdict
   (within the noise in every channel and band); the nominal truss must be beyond it.
3. **Cost of the estimator view** -- CPU time of ``estimator_view`` (expected H1, 4096-point
   window) against a plain ``freqresp`` of the 60-state truss on the same 1014 points.

Run: ``python -m benchmarks noise``.
"""

from __future__ import annotations

import time

import control
import numpy as np

import robustctl as rc
from robustctl.measure.estimator import EstimatorSettings, estimator_view

N_SEEDS = 200
TARGETS = {
    "std_ratio_magnitude": "0.85 .. 1.15",
    "std_ratio_phase": "0.85 .. 1.15",
    "truth_mean_normalised_sq_error": "0.8 .. 1.2",
    "truth_within_noise": "== True",
    "nominal_within_noise": "== False",
}


def _monte_carlo() -> tuple[float, float]:
    wn = 2 * np.pi * 12.0
    sys = control.ss([[0, 1], [-(wn**2), -2 * 0.05 * wn]], [[0], [1]], [[wn**2, 0]], [[0]])
    logs, sig = [], []
    for seed in range(N_SEEDS):
        u, y = rc.simulate_experiment(sys, fs=200.0, n_samples=256 * 16, seed=seed, noise_rms=0.3)
        d = rc.estimate_frf(u, y, 200.0, nperseg=256)
        logs.append(np.log(d.response[:, 0, 0]))
        sig.append(rc.noise_model(d).sigma[:, 0, 0])
    logs, sig = np.array(logs), np.array(sig)
    predicted = np.sqrt(np.mean(sig**2, axis=0))
    small = predicted < 0.2
    mag = np.median(logs.real.std(axis=0)[small] / predicted[small])
    ph_dev = np.angle(np.exp(1j * (logs.imag - logs.imag.mean(axis=0))))
    ph = np.median(ph_dev.std(axis=0)[small] / predicted[small])
    return float(mag), float(ph)


def _cpu(fn, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def run() -> dict:
    """Monte-Carlo of the variance formula, calibration on the Caltech truth, cost of the view."""
    mag, ph = _monte_carlo()
    data, truth = rc.examples.caltech_truss_experiment(seed=0)
    band = (0.5, 50.0)
    cmp_truth = rc.compare(truth, data, band=band)
    cmp_nominal = rc.compare(rc.examples.caltech_truss(), data, band=band)
    ss = truth.statespace()
    f = data.band(*band).f_hz
    st = EstimatorSettings((200.0, 4096, "hamming"), 2048)
    estimator_view(ss, f, st)  # warm (window cache)
    t_view = _cpu(lambda: estimator_view(ss, f, st))
    t_plain = _cpu(lambda: rc.freqresp(ss, f))
    metrics = {
        "std_ratio_magnitude": round(mag, 3),
        "std_ratio_phase": round(ph, 3),
        "truth_mean_normalised_sq_error": round(cmp_truth.noise_test.overall_ratio, 3),
        "truth_within_noise": bool(cmp_truth.within_noise),
        "nominal_within_noise": bool(cmp_nominal.within_noise),
        "nominal_failing_cells": len(cmp_nominal.noise_test.failing),
        "cells": len(cmp_truth.noise_test.cells),
        "estimator_view_cpu_ms": round(1e3 * t_view, 2),
        "freqresp_cpu_ms": round(1e3 * t_plain, 2),
        "view_cost_ratio": round(t_view / max(t_plain, 1e-9), 2),
        "n_states": ss.nstates,
    }
    passed = bool(
        0.85 <= mag <= 1.15 and 0.85 <= ph <= 1.15
        and 0.8 <= metrics["truth_mean_normalised_sq_error"] <= 1.2
        and metrics["truth_within_noise"] and not metrics["nominal_within_noise"]
    )
    return {
        "name": "noise",
        "description": "H1 noise model vs Monte-Carlo (200 seeds); true Caltech truss within the noise, "
                       "nominal beyond; CPU cost of the estimator view vs freqresp",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": passed,
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["noise"]))
