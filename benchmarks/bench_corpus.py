"""Benchmark: ``rc.compare`` on the independently made laboratory corpus (``tests/lab_corpus.py``).

Five structures built in numpy (3-D frame, 12-DOF plate grid, hub with two arms, 10-mass mast,
two-span beam), measured forces and held commands, random and periodic excitation, an impact
test; H1 by ``rc.estimate_frf``. Per case: the exact truth's cost and verdict with the view the
experiment description establishes (default) and as the plain FRF, and the CPU time of one
compare each way (best of 3). The view of a measured random estimate (``expected_h1_measured``:
exact poles plus an FFT of the alias sum on 8 N points) is also timed against the held view
(``expected_h1``) on the mast. Targets: every truth within the noise by default; compare
under 1 s per case.

Run: ``python -m benchmarks corpus`` (writes ``benchmarks/results/corpus.json``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import robustctl as rc

from .bench_noise import _cpu

TARGET_S = 1.0


def _corpus():
    tests = str(Path(__file__).resolve().parent.parent / "tests")
    if tests not in sys.path:
        sys.path.insert(0, tests)
    import lab_corpus

    return lab_corpus


def run() -> dict:
    """Every case: truth verdicts with and without the view, CPU time per compare."""
    from robustctl.measure.estimator import EstimatorSettings, expected_h1, expected_h1_measured

    lc = _corpus()
    metrics: dict = {}
    all_within, slowest = True, 0.0
    for name in sorted(lc.CASES):
        truth, data, desc = lc.case(name)
        band = desc["band"]
        seen = rc.compare(truth, data, band=band)
        plain = rc.compare(truth, data, band=band, estimator=False)
        t_seen = _cpu(lambda: rc.compare(truth, data, band=band))  # noqa: B023
        t_plain = _cpu(lambda: rc.compare(truth, data, band=band, estimator=False))  # noqa: B023
        all_within &= bool(seen.within_noise)
        slowest = max(slowest, t_seen)
        metrics[name] = {
            "points": int(data.band(*band).n_freq), "channels": f"{data.n_out}x{data.n_in}",
            "J_default": round(float(seen.cost), 4), "within_default": seen.within_noise,
            "J_plain": round(float(plain.cost), 4), "within_plain": plain.within_noise,
            "compare_cpu_s": round(t_seen, 3), "compare_plain_cpu_s": round(t_plain, 3),
            "view": seen.estimator_note,
        }
    truth, data, desc = lc.case("mast_measured_random")
    f = data.band(*desc["band"]).f_hz
    ss = truth.statespace()
    meas = EstimatorSettings((100.0, 1024, "hamming"), 512, input_kind="measured")
    held = EstimatorSettings((100.0, 1024, "hamming"), 512)
    expected_h1_measured(ss, f, meas)
    metrics["mast_view_measured_cpu_ms"] = round(1e3 * _cpu(lambda: expected_h1_measured(ss, f, meas)), 2)
    metrics["mast_view_held_cpu_ms"] = round(1e3 * _cpu(lambda: expected_h1(ss, f, held)), 2)
    metrics["mast_freqresp_cpu_ms"] = round(1e3 * _cpu(lambda: rc.freqresp(ss, f)), 2)
    metrics["every_truth_within_noise"] = all_within
    metrics["slowest_compare_cpu_s"] = round(slowest, 3)
    return {
        "name": "corpus",
        "description": "rc.compare of each exact truth of the independent laboratory corpus against its "
                       "data: default view (from the experiment description) vs plain FRF; CPU time",
        "metrics": metrics,
        "targets": {"every_truth_within_noise": "== True", "slowest_compare_cpu_s": f"<= {TARGET_S}"},
        "passed": bool(all_within and slowest <= TARGET_S),
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["corpus"]))
