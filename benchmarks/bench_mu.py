"""Benchmark: ``rc.mu`` (batched D-scaling upper bound + power-iteration lower bound) against the
per-frequency LMI route (cvxpy + Clarabel).

Case: a 6x6 frequency response with three 1x1 complex scalar blocks and one 3x3 full block
(mussv ``[[1,0],[1,0],[1,0],[3,3]]``) at 1000 log-spaced frequencies, from a seeded random
lightly damped 12-state system plus a random feedthrough. Timings are warm, best of 5, in
process CPU time (robust to other jobs on a shared machine; wall-clock next to it). The gap
to the LMI optimum is measured at 12 frequencies spread over the grid (the 1000-frequency LMI
run would take minutes; bisection to 1e-5 relative); the LMI solves run in a worker process
with a deadline. A mixed real/complex variant (first scalar block real) is timed as well (no
target).

Prior art: python-control has no mu; dkpy (PyPI) is not installed in the shared
environment and may not be added to it, so it is not run here.

Run: ``python -m benchmarks mu``.
"""

from __future__ import annotations

import multiprocessing as mp
import time

import control
import numpy as np

import robustctl as rc
from robustctl.robust.mu.layout import layout_of
from robustctl.robust.mu.lmi import lmi_upper_bound
from robustctl.robust.uncertainty.blocks import as_block_structure
from robustctl.threads import get_blas_threads

N_FREQ = 1000
N_LMI = 12
REPEAT = 5
LMI_DEADLINE_S = 600.0
BLOCKS = [[1, 0], [1, 0], [1, 0], [3, 3]]
MIXED = [[-1, 0], [1, 0], [1, 0], [3, 3]]
TARGETS = {
    "t_upper_lower_cpu_s": "< 0.2",
    "max_gap_to_lmi_pct": "< 1",
}


def case(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and the 6x6 response (1000, 6, 6)."""
    rng = np.random.default_rng(seed)
    n_modes = 6
    f_modes = np.geomspace(0.5, 50.0, n_modes)
    A = np.zeros((2 * n_modes, 2 * n_modes))
    for k, f in enumerate(f_modes):
        w, z = 2 * np.pi * f, rng.uniform(0.01, 0.05)
        A[2 * k: 2 * k + 2, 2 * k: 2 * k + 2] = [[-z * w, w], [-w, -z * w]]
    B = rng.standard_normal((2 * n_modes, 6))
    C = rng.standard_normal((6, 2 * n_modes))
    D = 0.3 * rng.standard_normal((6, 6))
    f_hz = np.geomspace(0.1, 100.0, N_FREQ)
    return f_hz, rc.freqresp(control.ss(A, B, C, D), f_hz).response


def _timed(fn, repeat: int = REPEAT) -> tuple[float, float, object]:
    cpu, wall, out = np.inf, np.inf, None
    fn()
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return cpu, wall, out


def _lmi_worker(M: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[list[float], float]:
    lay = layout_of(as_block_structure(BLOCKS))
    out, t0 = [], time.perf_counter()
    for Mk, lo in zip(M, lower):
        beta, _, _ = lmi_upper_bound(Mk, lay, bracket=(float(lo), float(np.linalg.norm(Mk, 2))), rel_tol=1e-5)
        out.append(beta)
    return out, (time.perf_counter() - t0) / len(M)


def lmi_reference(M: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, float]:
    """LMI bounds at the given frequencies (in a worker process with a deadline), time per frequency."""
    ctx = mp.get_context("spawn")
    with ctx.Pool(1) as pool:
        job = pool.apply_async(_lmi_worker, (M, lower, upper))
        betas, per_freq = job.get(timeout=LMI_DEADLINE_S)
    return np.array(betas), per_freq


def run() -> dict:
    """Time the bounds on 1000 frequencies and compare with the LMI at a subset."""
    f_hz, M = case()
    with rc.blas_threads(get_blas_threads()):
        cpu, wall, res = _timed(lambda: rc.mu(M, BLOCKS, f_hz))
        cpu_up, wall_up, _ = _timed(lambda: rc.mu(M, BLOCKS, f_hz, lower=False))
        cpu_mixed, wall_mixed, res_mixed = _timed(lambda: rc.mu(M, MIXED, f_hz))
    idx = np.unique(np.linspace(0, N_FREQ - 1, N_LMI).astype(int))
    idx[np.argmin(np.abs(idx - int(np.argmax(res.upper))))] = int(np.argmax(res.upper))  # include the peak
    lmi, lmi_per_freq = lmi_reference(M[idx], res.lower[idx], res.upper[idx])
    gap = res.upper[idx] / lmi - 1.0
    ratio = res.lower / res.upper
    metrics = {
        "t_upper_lower_cpu_s": round(cpu, 4),
        "t_upper_lower_wall_s": round(wall, 4),
        "t_upper_only_cpu_s": round(cpu_up, 4),
        "max_gap_to_lmi_pct": float(f"{100 * gap.max():.3g}"),
        "min_gap_to_lmi_pct": float(f"{100 * gap.min():.3g}"),
        "lmi_s_per_frequency": round(lmi_per_freq, 3),
        "lmi_vs_batched_per_frequency_ratio": round(lmi_per_freq / (cpu / N_FREQ), 0),
        "peak_upper": round(res.peak, 5),
        "peak_lower": round(res.lower_peak, 5),
        "median_lower_over_upper": round(float(np.median(ratio)), 5),
        "min_lower_over_upper": round(float(np.min(ratio)), 5),
        "newton_iterations": res.info["newton_iterations"],
        "power_iterations": res.info["power_iterations"],
        "mixed_t_upper_lower_cpu_s": round(cpu_mixed, 4),
        "mixed_t_upper_lower_wall_s": round(wall_mixed, 4),
        "mixed_fraction_with_lower_bound": round(float(np.mean(res_mixed.lower > 0)), 3),
        "n_frequencies": N_FREQ,
        "n_lmi_frequencies": int(idx.size),
        "dkpy": "not installed (shared venv may not be changed); not run",
    }
    passed = bool(cpu < 0.2 and gap.max() < 0.01)
    return {
        "name": "mu",
        "description": "rc.mu upper+lower bounds, 6x6, blocks [[1,0],[1,0],[1,0],[3,3]], 1000 frequencies "
                       "(warm, best of 5, CPU time) vs the per-frequency LMI (cvxpy + Clarabel) "
                       "at 12 frequencies",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": passed,
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["mu"]))
