"""Benchmark: ``rc.freqresp`` against ``control.frequency_response``.

System: 200 states (100 lightly damped modes, 0.2-150 Hz, damping 0.5-2 %), 3 inputs,
3 outputs, seeded random B and C; 2000 log-spaced frequencies from 0.1 to 200 Hz. It is
evaluated twice: in real modal form (2x2 blocks ``[[sigma, w_d], [-w_d, sigma]]``, block
diagonal), and hidden by a random orthogonal change of coordinates (dense A). Timings are
warm, best of 3 (the two tools timed in turns), both under the same BLAS thread setting
(robustctl's); the speed-ups are ratios of process CPU time (robust to other jobs on a
shared machine), wall-clock ratios are reported next to them. Targets: >= 50x faster in
modal form, >= 10x with the dense A, max elementwise relative difference < 1e-9 in both.

Run: ``python -m benchmarks freqresp``.
"""

from __future__ import annotations

import time
import warnings

import control
import numpy as np

import robustctl as rc
from robustctl.threads import get_blas_threads

N_MODES = 100
N_IO = 3
N_FREQ = 2000
REPEAT = 3
TARGETS = {
    "speedup_modal": ">= 50",
    "speedup_dense": ">= 10",
    "max_rel_diff_modal": "< 1e-9",
    "max_rel_diff_dense": "< 1e-9",
}


def systems(seed: int = 0) -> tuple[control.StateSpace, control.StateSpace]:
    """The modal-form system and the same system in random orthogonal coordinates."""
    rng = np.random.default_rng(seed)
    f_modes = np.geomspace(0.2, 150.0, N_MODES)
    zeta = rng.uniform(0.005, 0.02, N_MODES)
    n = 2 * N_MODES
    A = np.zeros((n, n))
    for k, (f, z) in enumerate(zip(f_modes, zeta)):
        w = 2 * np.pi * f
        sigma, wd = -z * w, w * np.sqrt(1 - z * z)
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[sigma, wd], [-wd, sigma]]
    B = rng.standard_normal((n, N_IO))
    C = rng.standard_normal((N_IO, n))
    D = np.zeros((N_IO, N_IO))
    names = {"inputs": [f"u{k + 1}" for k in range(N_IO)], "outputs": [f"y{k + 1}" for k in range(N_IO)]}
    modal = control.ss(A, B, C, D, **names)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    dense = control.ss(Q @ A @ Q.T, Q @ B, C @ Q.T, D, **names)
    return modal, dense


def _best_of_interleaved(fns, repeat: int = REPEAT) -> list[dict]:
    """Time the functions in turns ``repeat`` times, each call right after a warm-up call.

    Returns per function the best wall time, the best CPU time of this process
    (``time.process_time``: immune to other processes taking the cores, which shared
    machines do) and the last output. Interleaving keeps a change of machine load from
    favouring one side of a ratio.
    """
    outs = [None] * len(fns)
    wall, cpu = [np.inf] * len(fns), [np.inf] * len(fns)
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            fn()  # warm: caches hold this tool's data, not the other tool's
            c0, t0 = time.process_time(), time.perf_counter()
            outs[k] = fn()
            wall[k] = min(wall[k], time.perf_counter() - t0)
            cpu[k] = min(cpu[k], time.process_time() - c0)
    return [{"wall": w, "cpu": c, "out": o} for w, c, o in zip(wall, cpu, outs)]


def _control_response(sys: control.StateSpace, f_hz: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        resp = control.frequency_response(sys, 2 * np.pi * f_hz)
    return np.asarray(resp.frdata)


def compare(sys: control.StateSpace, f_hz: np.ndarray) -> dict[str, float]:
    """Timings (s) of both tools, their ratios and the max elementwise relative difference."""
    ours, ref = _best_of_interleaved([lambda: rc.freqresp(sys, f_hz), lambda: _control_response(sys, f_hz)])
    g_ref = np.transpose(ref["out"], (2, 0, 1))
    rel = np.abs(ours["out"].response - g_ref) / np.abs(g_ref)
    return {
        "t_rc": ours["cpu"], "t_control": ref["cpu"], "speedup": ref["cpu"] / ours["cpu"],
        "wall_rc": ours["wall"], "wall_control": ref["wall"], "speedup_wall": ref["wall"] / ours["wall"],
        "max_rel": float(rel.max()),
    }


def run() -> dict:
    """Time and compare both forms of the 200-state system."""
    f_hz = np.geomspace(0.1, 200.0, N_FREQ)
    modal, dense = systems()
    with rc.blas_threads(get_blas_threads()):
        m = compare(modal, f_hz)
        d = compare(dense, f_hz)
    metrics = {
        "speedup_modal": round(m["speedup"], 1),
        "speedup_dense": round(d["speedup"], 1),
        "max_rel_diff_modal": float(f"{m['max_rel']:.3g}"),
        "max_rel_diff_dense": float(f"{d['max_rel']:.3g}"),
        "rc_modal_cpu_ms": round(1e3 * m["t_rc"], 3),
        "control_modal_cpu_ms": round(1e3 * m["t_control"], 3),
        "rc_dense_cpu_ms": round(1e3 * d["t_rc"], 3),
        "control_dense_cpu_ms": round(1e3 * d["t_control"], 3),
        "speedup_modal_wall_clock": round(m["speedup_wall"], 1),
        "speedup_dense_wall_clock": round(d["speedup_wall"], 1),
        "rc_modal_wall_ms": round(1e3 * m["wall_rc"], 3),
        "rc_dense_wall_ms": round(1e3 * d["wall_rc"], 3),
        "n_states": modal.nstates,
        "n_frequencies": N_FREQ,
    }
    passed = bool(
        m["speedup"] >= 50 and d["speedup"] >= 10 and m["max_rel"] < 1e-9 and d["max_rel"] < 1e-9
    )
    return {
        "name": "freqresp",
        "description": "rc.freqresp vs control.frequency_response, 200 states, 3x3, 2000 frequencies, "
                       "modal form and dense (random orthogonal coordinates); warm, best of 3",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": passed,
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["freqresp"]))
