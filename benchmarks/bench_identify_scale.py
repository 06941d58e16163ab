"""Benchmark: identification at the size of real modal tests (issue 15), side by side with
scikit-rf's VectorFitting.

1. The scale case (``rc.examples.modal_test_case(seed=0)``): 2 shakers x 28 accelerometers,
   25 modes in 50-450 Hz with three close pairs, 0.2-2 % damping, 800 points, H1 random error
   of coherence 0.95-0.99. ``fit_measurement_model`` with ``n_modes=25`` and with the automatic
   order; scikit-rf ``VectorFitting`` with 25 and 40 complex pole pairs on the same FRF (the 56
   responses padded with zeros into an 8x8 "network"). Reported: largest frequency error of the
   25 true modes (nearest in-band pole, %), largest damping error (relative), rms log-magnitude
   error (dB) where coherence > 0.9, wall and CPU time.
2. The impact case (``rc.examples.impact_test_case``, 8 modes at 200-2000 Hz, 0.05-0.3 %
   damping, 0.5 s records, 5 hits): ``estimate_frf_impact`` with the automatic exponential
   window and with none (leakage), automatic order.
3. The real pyFRF hammer test (``../shared/data/pyfrf_impact_hammer``, 5 hits, 25.6 kHz, 12 listed
   peaks): the default route against scikit-rf VectorFitting (30 pole pairs) on the plain H1:
   rms dB against the H1, listed peaks found within 0.3 %, time.
4. Time of a fixed-order fit against the number of channels (1-64 outputs, one input, 15
   modes) and of modes (5-50, 2 x 8 channels), plotted to ``results/identify_scale.png``.

Timings: robustctl runs with one BLAS thread (its default); CPU time of the process is
reported next to the wall time because the 2-core machine is shared (the targets use CPU
time, robust to other jobs). scikit-rf runs in a subprocess with a deadline (``SKRF_TIMEOUT_S``).
Targets: scale case frequencies within 0.1 %, rms < 1 dB, fixed order < 5 s, automatic
< 15 s and < 2 dB; impact automatic order < 10 s; hammer default route < 1 dB with the 12 peaks.

Run: ``python -m benchmarks identify_scale``.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import resource
import time
import warnings
from pathlib import Path

import numpy as np

import robustctl as rc
from robustctl.identify import IdentifyWarning, channel_cost

SKRF_TIMEOUT_S = 600.0
RESULTS = Path(__file__).resolve().parent / "results"
TARGETS = {
    "scale_fixed_max_freq_err_pct": "< 0.1",
    "scale_fixed_rms_db_coh_gt_0.9": "< 1",
    "scale_fixed_cpu_s": "< 5",
    "scale_auto_max_freq_err_pct": "< 0.1",
    "scale_auto_cpu_s": "< 15",
    "scale_auto_rms_db_coh_gt_0.9": "< 2",
    "impact_exp_auto_cpu_s": "< 10",
    "hammer_default_rms_db": "< 1",
    "hammer_default_peaks_found": "== 12",
}
#: the pyFRF hammer test (../shared/data next to the repository, or ROBUSTCTL_SHARED_DATA)
HAMMER = Path(os.environ.get("ROBUSTCTL_SHARED_DATA",
                           Path(__file__).resolve().parents[1] / ".." / "shared" / "data"))
HAMMER_PEAKS_HZ = np.array([810, 851, 900, 2640, 3035, 3669, 4128, 4164, 4392, 5031, 5074, 5969.0])
HAMMER_BAND = (700.0, 6200.0)
#: scikit-rf's pole pairs on the hammer test (the issue's 30- and 60-pole fits count pairs)
HAMMER_SKRF_PAIRS = (30, 60)


# ---------------------------------------------------------------------------- helpers
def _timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, round(time.perf_counter() - w0, 2), round(time.process_time() - c0, 2)


def _errors(f_fit, z_fit, truth) -> tuple[float, float]:
    """Largest frequency error (%) and relative damping error of the nearest fitted pole."""
    idx = [int(np.argmin(np.abs(f_fit - ft))) for ft in truth.f_hz]
    ferr = np.abs(f_fit[idx] / truth.f_hz - 1).max() * 100
    zerr = np.abs(z_fit[idx] / truth.zeta - 1).max()
    return round(float(ferr), 4), round(float(zerr), 3)


def _ours(data, truth, **kw) -> dict:
    def fit():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifyWarning)
            return rc.fit_measurement_model(data, progress=False, **kw)

    mm, wall, cpu = _timed(fit)
    f = np.array([m.f_hz for m in mm.modes])
    z = np.array([m.zeta for m in mm.modes])
    ferr, zerr = _errors(f, z, truth)
    high = data.coherence > 0.9
    rms = channel_cost(data.response, mm.fit.response(data.f_hz), mask=high).rms_db_total
    return {
        "n_modes": mm.n_modes,
        "n_fillers": len(mm.fillers),
        "max_freq_err_pct": ferr,
        "max_zeta_rel_err": zerr,
        "rms_db_coh_gt_0.9": round(float(rms), 3),
        "wall_s": wall,
        "cpu_s": cpu,
    }


def _skrf_worker(f_hz, g, n_pairs, queue) -> None:
    import skrf
    from skrf.vectorFitting import VectorFitting
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)  # the same BLAS setting as robustctl (threads thrash on a shared 2-core machine)
    logging.getLogger("skrf").setLevel(logging.ERROR)
    warnings.simplefilter("ignore")
    k, n_ch = g.shape
    n = int(np.ceil(np.sqrt(n_ch)))
    s = np.zeros((k, n * n), dtype=complex)
    s[:, :n_ch] = g
    net = skrf.Network(frequency=skrf.Frequency.from_f(f_hz, unit="hz"), s=s.reshape(k, n, n))
    t0, c0 = time.perf_counter(), time.process_time()
    vf = VectorFitting(net)
    vf.vector_fit(n_poles_real=0, n_poles_cmplx=n_pairs, fit_constant=True, enforce_dc=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    model = np.array([vf.get_model_response(c // n, c % n, f_hz) for c in range(n_ch)]).T
    queue.put((model, np.asarray(vf.poles), wall, cpu))


def _skrf(data, truth, n_pairs: int) -> dict:
    """scikit-rf VectorFitting in a subprocess with a deadline."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    g = data.response.reshape(data.n_freq, -1)
    proc = ctx.Process(target=_skrf_worker, args=(data.f_hz, g, n_pairs, queue))
    proc.start()
    try:
        model, poles, wall, _ = queue.get(timeout=SKRF_TIMEOUT_S)
    except Exception as exc:  # noqa: BLE001 - a timeout or a failure of the third-party fit
        proc.terminate()
        return {"n_pairs": n_pairs, "failed": f"{type(exc).__name__}: {exc}"[:200]}
    finally:
        proc.join(timeout=10)
    p = poles[poles.imag > 0]  # rad/s
    f = np.abs(p) / (2 * np.pi)
    z = -p.real / np.abs(p)
    inband = (f >= data.f_hz[0]) & (f <= data.f_hz[-1])
    ferr, zerr = _errors(f[inband], z[inband], truth)
    high = data.coherence > 0.9
    rms = channel_cost(data.response, model.reshape(data.response.shape), mask=high).rms_db_total
    return {
        "n_pairs": n_pairs,
        "max_freq_err_pct": ferr,
        "max_zeta_rel_err": zerr,
        "rms_db_coh_gt_0.9": round(float(rms), 3),
        "wall_s": round(wall, 2),
    }


# ---------------------------------------------------------------------------- parts
def _scale_case() -> dict:
    data, truth = rc.examples.modal_test_case(seed=0)
    warm = rc.examples.modal_test_case(n_out=2, n_modes=4, n_pairs=0, n_freq=200, seed=9)
    _ours(*warm, n_modes=4)  # imports and caches outside the timings
    return {
        "ours_fixed_25": _ours(data, truth, n_modes=25),
        "ours_auto": _ours(data, truth),
        "skrf_25_pairs": _skrf(data, truth, 25),
        "skrf_40_pairs": _skrf(data, truth, 40),
    }


def _impact_case() -> dict:
    force, resp, truth = rc.examples.impact_test_case(seed=0, zeta_range=(0.0005, 0.003), duration_s=0.5)
    out = {}
    for name, win in (("exp", "auto"), ("rect", None)):
        data = rc.estimate_frf_impact(force, resp, fs=8192.0, exp_window=win).band(150, 2200)
        out[f"{name}_auto"] = _ours(data, truth)
        out[f"{name}_fixed_8"] = _ours(data, truth, n_modes=8)
    return out


def _hammer_case() -> dict:
    """The real pyFRF hammer test: the default route (estimate_frf_impact + fit_measurement_model,
    automatic order) and scikit-rf VectorFitting (30 pole pairs) on the same band of the plain H1
    (rectangular window over the 5 hits): rms log-magnitude error against that H1 (dB), how many of
    the 12 listed peaks have a pole within 0.3 %, and the time."""
    folder = HAMMER / "pyfrf_impact_hammer"
    if not (folder / "measurements_1.npy").exists():
        return {"skipped": f"no data at {folder}"}
    recs = [np.load(folder / f"measurements_{k}.npy") for k in range(1, 6)]
    fs = 25600.0
    force, resp = np.array([r[1] for r in recs]), np.array([r[2] for r in recs])
    F, X = np.fft.rfft(force, axis=1), np.fft.rfft(resp, axis=1)
    f = np.fft.rfftfreq(force.shape[1], 1 / fs)
    band = (f >= HAMMER_BAND[0]) & (f <= HAMMER_BAND[1])
    f, h1 = f[band], (np.sum(np.conj(F) * X, axis=0) / np.sum(np.abs(F) ** 2, axis=0))[band]

    def miss(g):
        return round(float(np.sqrt(np.mean((20 * np.log10(np.abs(g / h1))) ** 2))), 3)

    def found(f_poles):
        return int(sum(np.min(np.abs(np.asarray(f_poles) / p - 1)) < 0.003 for p in HAMMER_PEAKS_HZ))

    def ours():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", IdentifyWarning)
            fd = rc.estimate_frf_impact(force, resp, fs=fs)
            return rc.fit_measurement_model(fd, band=HAMMER_BAND, progress=False)

    mm, wall, cpu = _timed(ours)
    out = {"ours_default": {
        "rms_db": miss(mm.freqresp(f).response[:, 0, 0]), "peaks_found": found([m.f_hz for m in mm.modes]),
        "n_modes": mm.n_modes, "corrections": list(mm.corrections), "wall_s": wall, "cpu_s": cpu,
        # the process's peak resident memory so far (the hammer case alone with run_hammer)
        "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}}
    ctx = mp.get_context("spawn")
    for n_pairs in HAMMER_SKRF_PAIRS:  # each in a fresh process, one BLAS thread
        queue = ctx.Queue()
        proc = ctx.Process(target=_skrf_worker, args=(f, h1[:, None], n_pairs, queue))
        proc.start()
        key = f"skrf_{n_pairs}_pairs"
        try:
            model, poles, wall, cpu_skrf = queue.get(timeout=SKRF_TIMEOUT_S)
            p = poles[poles.imag > 0]
            out[key] = {"rms_db": miss(model[:, 0]), "peaks_found": found(np.abs(p) / (2 * np.pi)),
                        "wall_s": round(wall, 2), "cpu_s": round(cpu_skrf, 2),
                        "ours_cpu_over_skrf_cpu": round(cpu / max(cpu_skrf, 1e-9), 2)}
        except Exception as exc:  # noqa: BLE001 - a timeout or a failure of the third-party fit
            proc.terminate()
            out[key] = {"failed": f"{type(exc).__name__}: {exc}"[:200]}
        finally:
            proc.join(timeout=10)
    return out


def blas_kernel() -> list[str]:
    """The BLAS libraries loaded and the kernel each chose (threadpoolctl's ``architecture``):
    round-off, and so the last digits of every figure, depend on it."""
    from threadpoolctl import threadpool_info

    libs = {f"{p.get('internal_api')} {p.get('version')} {p.get('architecture')}" for p in threadpool_info()}
    return sorted(libs)


def run_hammer() -> dict:
    """Only the real hammer test (ours and scikit-rf in one run), merged into
    ``results/identify_scale.json`` under ``hammer_*`` (the other cases keep their last run)."""
    import json
    from datetime import datetime, timezone

    with rc.blas_threads(1):
        hammer = _hammer_case()
    path = RESULTS / "identify_scale.json"
    result = json.loads(path.read_text())
    result["metrics"].update(_hammer_metrics(hammer))
    result["metrics"]["hammer_run_utc"] = datetime.now(timezone.utc).isoformat(timespec="seconds")
    result["metrics"]["hammer_load_average_1_5_15"] = [round(x, 2) for x in os.getloadavg()]
    path.write_text(json.dumps(result, indent=2, default=str) + "\n")
    return hammer


def _hammer_metrics(hammer: dict) -> dict:
    ours = hammer.get("ours_default", {})
    out = {
        "hammer_default_rms_db": ours.get("rms_db"),
        "hammer_default_peaks_found": ours.get("peaks_found"),
        "hammer_default_cpu_s": ours.get("cpu_s"),
        "hammer_default_peak_mb": ours.get("peak_mb"),
        "hammer_blas_kernel": blas_kernel(),
        "hammer_case": hammer,
    }
    for n_pairs in HAMMER_SKRF_PAIRS:
        sk = hammer.get(f"skrf_{n_pairs}_pairs", {})
        out[f"hammer_skrf_{n_pairs}_rms_db"] = sk.get("rms_db")
        out[f"hammer_skrf_{n_pairs}_peaks_found"] = sk.get("peaks_found")
        out[f"hammer_skrf_{n_pairs}_cpu_s"] = sk.get("cpu_s")
        out[f"hammer_ours_cpu_over_skrf_{n_pairs}_cpu"] = sk.get("ours_cpu_over_skrf_cpu")
    return out


def _scaling() -> dict:
    channels, modes = {}, {}
    for n_out in (1, 4, 16, 64):
        data, truth = rc.examples.modal_test_case(n_in=1, n_out=n_out, n_modes=15, n_pairs=1, seed=11)
        channels[n_out] = _ours(data, truth, n_modes=15)
    for n in (5, 10, 20, 35, 50):
        data, truth = rc.examples.modal_test_case(
            n_in=2, n_out=8, n_modes=n, n_pairs=1, n_freq=max(400, 30 * n), f_range=(20.0, 20.0 + 20 * n),
            seed=12,
        )
        modes[n] = _ours(data, truth, n_modes=n)
    return {"vs_channels_1_input_15_modes": channels, "vs_modes_2x8": modes}


def _plot(scaling: dict) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panels = (
        ("vs_channels_1_input_15_modes", "outputs (1 input, 15 modes)"),
        ("vs_modes_2x8", "modes (2 x 8 channels)"),
    )
    for ax, (key, label) in zip(axes, panels):
        x = np.array(list(scaling[key]), dtype=float)
        for metric, style in (("cpu_s", "o-"), ("wall_s", "s--")):
            y = [scaling[key][k][metric] for k in scaling[key]]
            ax.loglog(x, y, style, label=metric.replace("_s", " time"))
        ax.set_xlabel(label)
        ax.set_ylabel("fit_measurement_model, fixed order (s)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle("Identification time against channels and modes")
    fig.tight_layout()
    path = RESULTS / "identify_scale.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path.relative_to(RESULTS.parent.parent))


def run() -> dict:
    t0 = time.perf_counter()
    with rc.blas_threads(1):
        scale = _scale_case()
        impact = _impact_case()
        hammer = _hammer_case()
        scaling = _scaling()
    fixed, auto = scale["ours_fixed_25"], scale["ours_auto"]
    metrics = {
        "scale_fixed_max_freq_err_pct": fixed["max_freq_err_pct"],
        "scale_fixed_rms_db_coh_gt_0.9": fixed["rms_db_coh_gt_0.9"],
        "scale_fixed_cpu_s": fixed["cpu_s"],
        "scale_fixed_wall_s": fixed["wall_s"],
        "scale_auto_n_modes": auto["n_modes"],
        "scale_auto_max_freq_err_pct": auto["max_freq_err_pct"],
        "scale_auto_cpu_s": auto["cpu_s"],
        "scale_auto_wall_s": auto["wall_s"],
        "scale_auto_rms_db_coh_gt_0.9": auto["rms_db_coh_gt_0.9"],
        "impact_exp_auto_cpu_s": impact["exp_auto"]["cpu_s"],
        **_hammer_metrics(hammer),
        "scale_case": scale,
        "impact_case": impact,
        "scaling": scaling,
        "plot": _plot(scaling),
        "benchmark_wall_time_s": round(time.perf_counter() - t0, 1),
        "cpu_count": os.cpu_count(),
    }
    return {
        "name": "identify_scale",
        "description": "fit_measurement_model on a 2x28-channel, 25-mode synthetic modal test (fixed and "
        "automatic order) vs scikit-rf VectorFitting; impact hits with exponential/rectangular windows; "
        "time against channels and modes; the real pyFRF hammer test by the default impact route vs "
        "scikit-rf",
        "metrics": metrics,
        "targets": TARGETS,
    }


if __name__ == "__main__":
    import json
    import sys

    if sys.argv[1:] == ["hammer"]:
        print(json.dumps(run_hammer(), indent=2, default=str))
    else:
        print(json.dumps(run()["metrics"], indent=2, default=str))
