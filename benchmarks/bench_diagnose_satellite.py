"""Benchmark: ``rc.diagnose`` on a user's 120-DOF frame, the independent satellite of
``tests/satellite_corpus.py`` (numpy beams, two shakers with measured forces, scipy MIMO H1 with
4096-point Hann windows, 1249 frequencies x 12 channels), with the default candidates (about 250).

Why it cost 30-70 x the Caltech truss per candidate: every evaluation sees the model through the
H1 estimator of a *measured* random force (:func:`robustctl.measure.estimator.expected_h1_measured`),
a transform over an ``8 N`` = 32768-point grid of every pole (240 of them: the user's model keeps
all 120 modes), and its modal decomposition was a dense ``eig`` plus an SVD condition number of
the 240 x 240 state matrix. The Caltech data are held (DAC) inputs on a 40-state model. Now the
modal form is decomposed in closed form, the 134 poles beyond 4 x the Nyquist frequency enter
through a 22-term power series, and with a Hann window no grid is needed at all (the smooth parts
seen through the lag window locally, ``S + c2 S''``: 10 ms per evaluation instead of 85 ms). A
second cause was the frame's joints: penalty ties 1e5 x stiffer than the members zeroed three
suspension modes, so every joint candidate took the defective-modes path (a 16384-point frequency
response, 0.24 s per evaluation); the twin node now follows the joint exactly. The same run times
the old estimator path (the three switched off) for the ratio, and checks that the ranking, the
costs and the verdict are the same.

Run: ``python -m benchmarks.bench_diagnose_satellite`` (writes
``benchmarks/results/diagnose_satellite.json``).
"""

from __future__ import annotations

import json
import os
import sys
import time
import warnings
from pathlib import Path

import robustctl as rc
from robustctl.measure import estimator

TARGET_S = 30.0


def _cpu() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _timed(model, data, workers):
    t0, c0 = time.perf_counter(), _cpu()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = rc.diagnose(model, data, workers=workers, chain=False)
    return diag, time.perf_counter() - t0, _cpu() - c0


def _old_path():
    """Switch the closed-form modal decomposition, the far-pole series and the local form off (the
    old path)."""
    saved = (estimator._FAR_POLE, estimator._second_order_modal, estimator._SMOOTH_ENDS)
    estimator._FAR_POLE = float("inf")
    estimator._second_order_modal = lambda A, B, C: None
    estimator._SMOOTH_ENDS = -1.0
    estimator._lag_curvature.cache_clear()
    return saved


def main() -> dict:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import satellite_corpus as sc

    model = sc.nominal_model()
    out = {"target_s": TARGET_S, "load_average": os.getloadavg()[0]}
    for case in ((), ("hinge_1axis",)):
        key = "+".join(case) or "null"
        data = sc.measure(case).data
        new, wall, cpu = _timed(model, data, 1)
        saved = _old_path()
        try:
            old, wall_old, cpu_old = _timed(model, data, 1)
        finally:
            estimator._FAR_POLE, estimator._second_order_modal, estimator._SMOOTH_ENDS = saved
            estimator._lag_curvature.cache_clear()
        same = len(new.ranking) == len(old.ranking) and all(
            a.name == b.name and abs(a.cost - b.cost) <= 1e-8 * max(abs(b.cost), 1.0)
            for a, b in zip(new.ranking, old.ranking)
        ) and new.verdict == old.verdict
        out[key] = {
            "candidates": len(new.ranking), "verdict": new.verdict, "n_evals": new.n_evals,
            "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
            "old_wall_s": round(wall_old, 2), "old_cpu_s": round(cpu_old, 2),
            "cpu_ratio_old_over_new": round(cpu_old / cpu, 2), "same_ranking_and_verdict": bool(same),
        }
        print(key, out[key], flush=True)
    path = Path(__file__).resolve().parent / "results" / "diagnose_satellite.json"
    path.write_text(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
