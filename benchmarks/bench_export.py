"""Benchmark: controller export accuracy (and time) against the tools a user would otherwise use.

Controllers (the ones of ``tests/test_export.py``): a 12-state 2x2 LQG controller of a six-mode
structure (fs = 200 Hz) and an 8-state 2x2 resonant controller with 0.2 % damping and
feedthrough (fs = 1000 Hz).

* ``rc.discretize`` against ``scipy.signal.cont2discrete`` (bilinear and zoh): max relative
  difference of the matrices (both take well under a millisecond; no timing is compared);
* every file format: max relative difference of the reloaded controller's discrete frequency
  response (400 frequencies up to Nyquist) from the exported one; SOS against the channel;
* the C header compiled with the machine's ``cc`` (-O2) and run on 3000 samples, against
  ``scipy.signal.dlsim``: max error relative to the output peak, double and float;
* the coefficient dynamic range ``max|coef| / min nonzero |coef|`` before and after balancing.

Targets: discretisation matches scipy to 1e-12; json/csv/mat/h reload exactly (0.0); SOS within
1e-9; C double within 1e-9 and float within 1e-4 of dlsim.

Run: ``python -m benchmarks export``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
from scipy.signal import cont2discrete, dlsim

import robustctl as rc
from robustctl.lti import freqresp_array

ROOT = Path(__file__).resolve().parent.parent
C_CLIENT = ROOT / "tests" / "c_client" / "run_controller.c"
TIMEOUT_S = 120
TARGETS = {
    "discretize_vs_scipy_max_rel": "< 1e-12",
    "round_trip_json_csv_mat_h_max_rel": "== 0",
    "round_trip_sos_max_rel": "< 1e-9",
    "c_double_max_rel": "< 1e-9",
    "c_float_max_rel": "< 1e-4",
}


def _controllers():
    sys.path.insert(0, str(ROOT / "tests"))
    from test_export import light_controller, lqg_controller

    return {"lqg": (lqg_controller(), 200.0), "light": (light_controller(), 1000.0)}


def _discretize_vs_scipy(K, fs: float) -> dict:
    out = {}
    for ours, theirs in (("tustin", "bilinear"), ("zoh", "zoh")):
        Kd = rc.discretize(K, fs, ours)
        ref = cont2discrete((K.A, K.B, K.C, K.D), 1 / fs, theirs)
        rel = max(
            np.max(np.abs(m - r)) / max(np.max(np.abs(r)), 1e-300)
            for m, r in zip((Kd.A, Kd.B, Kd.C, Kd.D), ref[:4])
        )
        out[ours] = float(rel)
    return out


def _response_rel(K1, K2) -> float:
    f = np.linspace(0.001, 0.499, 400) / K1.dt
    g1, g2 = freqresp_array(K1, f), freqresp_array(K2, f)
    return float(np.max(np.abs(g1 - g2)) / np.max(np.abs(g1)))


def _round_trips(K, fs: float, folder: Path) -> dict:
    out = {}
    for fmt in ("json", "csv", "mat", "h", "sos"):
        kw = {"channel": (0, 0)} if fmt == "sos" else {}
        rep = rc.export_controller(K, folder / f"k.{fmt}", fs=fs, **kw)
        out[fmt] = _response_rel(rep.controller, rc.load_controller(rep.path))
    return out


def _c_client(K, fs: float, folder: Path, balance) -> dict | None:
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        return None
    rep = rc.export_controller(K, folder / "kctl.h", fs=fs, balance=balance, overwrite=True)
    exe = folder / "run_controller"
    subprocess.run(
        [cc, "-std=c99", "-O2", "-I", str(folder), str(C_CLIENT), "-o", str(exe), "-lm"],
        check=True,
        capture_output=True,
        timeout=TIMEOUT_S,
    )
    rng = np.random.default_rng(11)
    t = np.arange(3000) / fs
    u = rng.normal(size=(t.size, K.ninputs)) + np.sin(2 * np.pi * 3.0 * t)[:, None] + (t > 1)[:, None]
    np.savetxt(folder / "u.txt", u, fmt="%.17g")
    text = subprocess.run(
        [str(exe), str(folder / "u.txt")], check=True, capture_output=True, text=True, timeout=TIMEOUT_S
    ).stdout
    y = np.array([[float(v) for v in line.split()] for line in text.splitlines()])
    Kd = rep.controller
    _, y_ref, _ = dlsim((Kd.A, Kd.B, Kd.C, Kd.D, Kd.dt), u)
    p, scale = K.noutputs, np.max(np.abs(y_ref))
    return {
        "double": float(np.max(np.abs(y[:, :p] - y_ref)) / scale),
        "float": float(np.max(np.abs(y[:, p:] - y_ref)) / scale),
        "dynamic_range": rep.dynamic_range,
        "dynamic_range_balanced": rep.dynamic_range_balanced,
    }


def run() -> dict:
    """Measure discretisation, round trips, the C client and the dynamic ranges."""
    metrics: dict = {}
    worst = {"disc": 0.0, "exact": 0.0, "sos": 0.0, "double": 0.0, "float": 0.0}
    with warnings.catch_warnings(), tempfile.TemporaryDirectory() as tmp:
        warnings.simplefilter("ignore", RuntimeWarning)
        for name, (K, fs) in _controllers().items():
            disc = _discretize_vs_scipy(K, fs)
            for method, rel in disc.items():
                metrics[f"{name}_{method}_vs_scipy_max_rel"] = float(f"{rel:.3g}")
                worst["disc"] = max(worst["disc"], rel)
            folder = Path(tmp) / name
            folder.mkdir()
            for fmt, rel in _round_trips(K, fs, folder).items():
                metrics[f"{name}_round_trip_{fmt}_max_rel"] = float(f"{rel:.3g}")
                key = "sos" if fmt == "sos" else "exact"
                worst[key] = max(worst[key], rel)
            for balance in (False, "diagonal", "balanced"):
                c = _c_client(K, fs, folder, balance)
                if c is None:
                    continue
                tag = f"{name}_{balance or 'plain'}"
                metrics[f"{tag}_c_double_max_rel"] = float(f"{c['double']:.3g}")
                metrics[f"{tag}_c_float_max_rel"] = float(f"{c['float']:.3g}")
                metrics[f"{tag}_dynamic_range"] = float(
                    f"{(c['dynamic_range_balanced'] or c['dynamic_range']):.3g}"
                )
                worst["double"] = max(worst["double"], c["double"])
                worst["float"] = max(worst["float"], c["float"])
    metrics = {
        "discretize_vs_scipy_max_rel": float(f"{worst['disc']:.3g}"),
        "round_trip_json_csv_mat_h_max_rel": worst["exact"],
        "round_trip_sos_max_rel": float(f"{worst['sos']:.3g}"),
        "c_double_max_rel": float(f"{worst['double']:.3g}"),
        "c_float_max_rel": float(f"{worst['float']:.3g}"),
        **metrics,
    }
    passed = bool(
        worst["disc"] < 1e-12
        and worst["exact"] == 0
        and worst["sos"] < 1e-9
        and worst["double"] < 1e-9
        and worst["float"] < 1e-4
    )
    return {
        "name": "export",
        "description": "discretize vs scipy cont2discrete; file round trips (response, 400 freqs); C header "
        "client vs dlsim (3000 samples, double/float); coefficient dynamic range with balancing",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": passed,
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["export"]))
