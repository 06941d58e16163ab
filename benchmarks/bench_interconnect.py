"""Benchmark: named ``rc.lft`` / ``rc.feedback`` against python-control, and the generalized plant.

Systems: random stable plants (seeded ``control.rss``) of 10, 50 and 200 states with
3 exogenous inputs, 2 controls, 3 regulated outputs and 2 measurements, closed by a random
stable 2 x 2 controller of 10 states with a feedthrough. ``rc.lft`` (keeps the names) is
timed against ``StateSpace.lft`` (drops them) and ``rc.feedback`` against
``control.feedback``; the frequency responses of both realisations are compared on 200
log-spaced frequencies (0.01-100 Hz) with ``rc.freqresp``. Last, the Caltech truss
generalized plant (eq. 14 additive weight, 4 % input and output multiplicative
uncertainty, performance on the sensors) is built and its closed loop formed.

Timings are warm, best of 5, process CPU time, the two tools timed in turns. Targets:
responses equal to 1e-10 (relative, worst element) and the named operations no slower
than 2x python-control's unnamed ones.

Run: ``python -m benchmarks interconnect``.
"""

from __future__ import annotations

import time

import control
import numpy as np

import robustctl as rc

ORDERS = (10, 50, 200)
REPEAT = 5
TARGETS = {
    "max_rel_diff_lft": "< 1e-10",
    "max_rel_diff_feedback": "< 1e-10",
    "time_ratio_lft_worst": "<= 2",
    "time_ratio_feedback_worst": "<= 2",
}


def _named_plant(n: int, seed: int):
    np.random.seed(seed)  # control.rss draws from numpy's global generator
    base = control.rss(n, 5, 5)
    D = 0.2 * np.random.default_rng(seed).standard_normal((5, 5))
    return control.ss(base.A, base.B, base.C, D, inputs=["w1", "w2", "w3", "u1", "u2"],
                      outputs=["z1", "z2", "z3", "y1", "y2"])


def _controller(seed: int):
    np.random.seed(seed)
    base = control.rss(10, 2, 2)
    return control.ss(base.A, base.B, base.C, 0.1 * np.eye(2), inputs=["y1", "y2"], outputs=["u1", "u2"])


def _best_cpu(fns, repeat: int = REPEAT) -> list[tuple[float, object]]:
    best, outs = [np.inf] * len(fns), [None] * len(fns)
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            fn()
            c0 = time.process_time()
            outs[k] = fn()
            best[k] = min(best[k], time.process_time() - c0)
    return list(zip(best, outs))


def _rel(a, b, f_hz) -> float:
    ga, gb = rc.lti.freqresp_array(a, f_hz), rc.lti.freqresp_array(b, f_hz)
    return float(np.max(np.abs(ga - gb)) / np.max(np.abs(gb)))


def _case(n: int) -> dict:
    f_hz = np.geomspace(0.01, 100.0, 200)
    P, K = _named_plant(n, n), _controller(1000 + n)
    (t_ours, ours), (t_pc, theirs) = _best_cpu([lambda: rc.lft(P, K), lambda: P.lft(K)])
    G = control.ss(P.A, P.B[:, 3:], P.C[3:], P.D[3:, 3:], inputs=["u1", "u2"], outputs=["y1", "y2"])
    (t_fb, fb), (t_pcfb, pcfb) = _best_cpu([lambda: rc.feedback(G, K), lambda: control.feedback(G, K)])
    assert list(ours.input_labels) == ["w1", "w2", "w3"]
    return {
        "n": n, "t_lft_ms": 1e3 * t_ours, "t_control_lft_ms": 1e3 * t_pc,
        "rel_lft": _rel(ours, theirs, f_hz), "t_feedback_ms": 1e3 * t_fb,
        "t_control_feedback_ms": 1e3 * t_pcfb, "rel_feedback": _rel(fb, pcfb, f_hz),
    }


def _caltech() -> dict:
    G = rc.examples.caltech_truss().statespace()
    Wa = control.tf(8 * np.poly([-6, -12, -24]), np.poly([-0.6, -400, -400]))
    Wp = control.tf([1.0], [1 / (2 * np.pi * 6.0), 1.0])
    c0 = time.process_time()
    gp = rc.generalized_plant(G, additive=Wa, input_mult=0.04, output_mult=0.04, performance=Wp,
                              disturbances=1.0, noise=0.01)
    t_build = time.process_time() - c0
    return {"states": gp.P.nstates, "nw": gp.nw, "nz": gp.nz, "build_ms": 1e3 * t_build,
            "blocks": gp.blocks.mussv().tolist()}


def run() -> dict:
    cases = [_case(n) for n in ORDERS]
    truss = _caltech()
    metrics: dict = {
        "max_rel_diff_lft": float(f"{max(c['rel_lft'] for c in cases):.3g}"),
        "max_rel_diff_feedback": float(f"{max(c['rel_feedback'] for c in cases):.3g}"),
        "time_ratio_lft_worst": round(max(c["t_lft_ms"] / c["t_control_lft_ms"] for c in cases), 2),
        "time_ratio_feedback_worst": round(
            max(c["t_feedback_ms"] / c["t_control_feedback_ms"] for c in cases), 2
        ),
    }
    for c in cases:
        n = c["n"]
        metrics[f"lft_ms_n{n}"] = round(c["t_lft_ms"], 3)
        metrics[f"control_lft_ms_n{n}"] = round(c["t_control_lft_ms"], 3)
        metrics[f"feedback_ms_n{n}"] = round(c["t_feedback_ms"], 3)
        metrics[f"control_feedback_ms_n{n}"] = round(c["t_control_feedback_ms"], 3)
    metrics["caltech_plant_states"] = truss["states"]
    metrics["caltech_plant_build_ms"] = round(truss["build_ms"], 2)
    metrics["caltech_plant_blocks"] = str(truss["blocks"])
    passed = bool(
        metrics["max_rel_diff_lft"] < 1e-10 and metrics["max_rel_diff_feedback"] < 1e-10
        and metrics["time_ratio_lft_worst"] <= 2 and metrics["time_ratio_feedback_worst"] <= 2
    )
    return {
        "name": "interconnect",
        "description": "named rc.lft / rc.feedback vs python-control (10, 50, 200 states); Caltech truss "
                       "generalized plant build; warm, best of 5, CPU time",
        "metrics": metrics,
        "targets": TARGETS,
        "passed": passed,
    }


if __name__ == "__main__":
    from benchmarks.run import main

    raise SystemExit(main(["interconnect"]))
