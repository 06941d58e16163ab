"""Benchmark: ``fit_measurement_model`` against the number of channels and of modes (the
measurement-model part of the scale benchmark; the diagnose part is ``bench_scale.py``).

The case is built here with numpy: ``n_modes`` modes in 20.6-388 Hz (log-spread with jitter,
clipped 3 % inside the 20-400 Hz band of the data; three of them doubled into close pairs
0.4-0.8 % apart), damping 0.3-2 %, a force-to-acceleration modal sum
``sum_k c_k b_k^T (-w^2)/(w_k^2 - w^2 + 2 j zeta_k w_k w)`` with random Gaussian shapes,
``n_out`` accelerometers x 2 shakers, 1,000 equally spaced lines, 1 % complex Gaussian noise.
Each fit (fixed ``n_modes``) runs in a fresh subprocess with one BLAS thread: wall and CPU
time, peak resident memory (``getrusage``), modes found (every true mode has a distinct
nearest fitted mode), the largest frequency (%) and damping (relative) errors and the
rms log-magnitude error (dB).

Sweeps: channels 10 / 25 / 50 / 100 (x 2 inputs) at 40 modes; modes 10 / 20 / 40 at 100 x 2
channels. The exponents are least-squares slopes of ``log CPU time`` and ``log peak memory``
against ``log channels`` and ``log modes``. Target (issue "size of real structures"): 40 modes
on 100 x 2 channels under 30 s (wall and CPU) and 1 GB with every mode found, and a CPU time
about linear in the channels (exponent below 1.2). Wall times depend on the load of the shared
machine (the target holds only on a quiet one); the CPU times are the steadier figure.

Run: ``python -m benchmarks scale_identify`` (writes ``results/scale_identify.json``).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
CHANNELS = (10, 25, 50, 100)
MODES = (10, 20, 40)
N_IN = 2
N_FREQ = 1000
F_BAND = (20.0, 400.0)
TARGET_S, TARGET_MB = 30.0, 1024.0


def modal_case(n_out: int, n_modes: int, n_in: int = N_IN, n_freq: int = N_FREQ, noise: float = 0.01,
               seed: int = 3):
    """The synthetic modal test: (FrequencyData, true f_hz, true zeta)."""
    import robustctl as rc

    rng = np.random.default_rng(seed)
    f_lo, f_hi = F_BAND
    n_pairs = 3 if n_modes >= 12 else 1
    n_single = n_modes - n_pairs
    jitter = np.exp(rng.uniform(-0.2, 0.2, n_single) * np.log(f_hi / f_lo) / n_single)
    f = np.sort(np.clip(np.geomspace(f_lo * 1.03, f_hi / 1.03, n_single) * jitter, f_lo * 1.03, f_hi / 1.03))
    at = np.linspace(2, n_single - 3, n_pairs).round().astype(int)
    f = np.sort(np.concatenate([f, f[at] * (1 + rng.uniform(0.004, 0.008, n_pairs))]))
    zeta = np.exp(rng.uniform(np.log(0.003), np.log(0.02), n_modes))
    c = rng.normal(size=(n_out, n_modes)) * np.sqrt(zeta)
    b = rng.normal(size=(n_modes, n_in)) * np.sqrt(zeta)[:, None]
    fr = np.linspace(f_lo, f_hi, n_freq)
    w, wk = 2 * np.pi * fr[:, None], 2 * np.pi * f[None, :]
    h = -(w**2) / (wk**2 - w**2 + 2j * zeta[None, :] * wk * w)
    g = np.einsum("km,om,mi->koi", h, c, b)
    g = g * (1 + noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)) / np.sqrt(2))
    return rc.FrequencyData(fr, g), f, zeta


def case(n_out: int, n_modes: int) -> dict:
    """One fit in this process: times, peak memory and accuracy."""
    import resource
    import time
    import warnings

    import robustctl as rc

    data, f_true, z_true = modal_case(n_out, n_modes)
    warm, *_ = modal_case(2, 4, n_freq=200, seed=9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rc.fit_measurement_model(warm, n_modes=4, progress=False)  # imports outside the timing
        base_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        t0, c0 = time.perf_counter(), time.process_time()
        with rc.blas_threads(1):
            mm = rc.fit_measurement_model(data, n_modes=n_modes, progress=False)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    f = np.array([m.f_hz for m in mm.modes])
    z = np.array([m.zeta for m in mm.modes])
    idx = [int(np.argmin(np.abs(f - ft))) for ft in f_true] if f.size else []
    found = len(set(idx))
    return {
        "n_out": n_out, "n_in": N_IN, "n_modes": n_modes, "n_freq": N_FREQ,
        "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
        "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "peak_before_fit_mb": round(base_mb, 1),
        "modes_found": found, "n_modes_fitted": mm.n_modes,
        "max_freq_err_pct": round(float(np.max(np.abs(f[idx] / f_true - 1))) * 100, 4) if found else None,
        "max_zeta_rel_err": round(float(np.max(np.abs(z[idx] / z_true - 1))), 4) if found else None,
        "rms_db": round(float(mm.cost.rms_db_total), 3),
    }


def _run(n_out: int, n_modes: int) -> dict:
    """:func:`case` in a fresh subprocess (its own time and peak memory)."""
    from benchmarks.scale_cases import in_fresh_process

    return in_fresh_process("bench_scale_identify", {"n_out": n_out, "n_modes": n_modes}, n_out, n_modes)


def exponent(rows: list[dict], x: str, y: str) -> float | None:
    """Least-squares slope of ``log y`` against ``log x``."""
    pts = [(r[x], r[y]) for r in rows if r.get(y) and r[y] > 0]
    if len(pts) < 2:
        return None
    return round(float(np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0]), 2)


def run() -> dict:
    load = os.getloadavg()
    vs_ch = [_run(n, 40) for n in CHANNELS]
    vs_modes = [r for r in vs_ch if r["n_out"] == 100] + [_run(100, m) for m in MODES if m != 40]
    vs_modes = sorted(vs_modes, key=lambda r: r["n_modes"])
    big = next(r for r in vs_ch if r["n_out"] == 100)
    metrics = {
        "modes_40_channels_100x2_wall_s": big.get("wall_s"),
        "modes_40_channels_100x2_cpu_s": big.get("cpu_s"),
        "modes_40_channels_100x2_peak_mb": big.get("peak_mb"),
        "modes_40_channels_100x2_all_found": big.get("modes_found") == 40,
        "modes_40_channels_100x2_max_freq_err_pct": big.get("max_freq_err_pct"),
        "cpu_exponent_vs_channels": exponent(vs_ch, "n_out", "cpu_s"),
        "memory_exponent_vs_channels": exponent(vs_ch, "n_out", "peak_mb"),
        "cpu_exponent_vs_modes": exponent(vs_modes, "n_modes", "cpu_s"),
        "memory_exponent_vs_modes": exponent(vs_modes, "n_modes", "peak_mb"),
        "vs_channels_40_modes": vs_ch,
        "vs_modes_100x2_channels": vs_modes,
        "load_average_at_start": [round(v, 2) for v in load],
    }
    targets = {"modes_40_channels_100x2_wall_s": f"< {TARGET_S}",
               "modes_40_channels_100x2_cpu_s": f"< {TARGET_S}",
               "cpu_exponent_vs_channels": "< 1.2",
               "modes_40_channels_100x2_peak_mb": f"< {TARGET_MB}",
               "modes_40_channels_100x2_all_found": "== True"}
    return {
        "name": "scale_identify",
        "description": "fit_measurement_model (fixed n_modes) on numpy modal tests: 10-100 outputs x 2 "
                       "inputs at 40 modes, 10-40 modes at 100 x 2, 1,000 lines, 1 % noise: time, peak "
                       "memory, accuracy, fitted exponents",
        "metrics": metrics,
        "targets": targets,
    }


if __name__ == "__main__":
    if len(sys.argv) == 3:
        print(json.dumps(case(int(sys.argv[1]), int(sys.argv[2]))))
    else:
        print(json.dumps(run(), indent=2))
