"""Benchmark: ``rc.dksyn`` against the order of a structural plant (the D-K part of the scale
benchmark; the diagnose part is ``bench_scale.py``, identification ``bench_scale_identify.py``).

The plant is built here with numpy: a fixed-free chain of ``n`` equal masses (springs between
neighbours; ``numpy.linalg.eigh`` for the modes), first mode 0.5 Hz, 1 % modal damping, forces
at the first and the middle mass, displacements at a third of the chain and at its tip, scaled
to unit static gain; ``n`` = 20, 40, 80, 160 modes (44 to 324 states of the generalized plant).
Weights: performance ``makeweight(3, (1 Hz, 1), 0.01)`` on the sensors, unit input
disturbances, control weight 0.1, sensor noise 0.01, input multiplicative uncertainty
``makeweight(0.2, (3 Hz, 1), 2)``. ``dksyn`` with its defaults (``design_order="auto"``:
plants above 200 states are designed on a balanced truncation, the fewest states whose bound
``2 sum sigma_tail`` is within 1 % of the largest Hankel singular value, no fixed cap, with the
truncation error covered by an additive block, the controller closed around the full plant and
its mu verified there; a controller that does not stabilise the full plant makes D-K retry at a
higher order from the loop's small-gain tolerance, each order tried recorded as
``design_tried``). Each run is a fresh subprocess with one BLAS thread: wall and CPU time, peak resident
memory, plant states, design-plant states and bound, controller states, the verified mu with
the full plant, and whether the full closed loop is stable (numpy eigenvalues).

The exponents are least-squares slopes of ``log CPU time`` and ``log peak memory`` against
``log plant states``. Target (issue "size of real structures"): at 160 modes D-K completes with
a verified mu (or refuses naming the violated assumption). Wall times depend on the load of the
shared machine; CPU times are the steadier figure.

Run: ``python -m benchmarks scale_dk`` (writes ``results/scale_dk.json``);
``python -m benchmarks.bench_scale_dk 160 > row.json`` measures one size apart and
``python -m benchmarks.bench_scale_dk --add row.json`` puts it into the result.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
MODES = (20, 40, 80, 160)


def chain_plant(n_modes: int, f1: float = 0.5, zeta: float = 0.01):
    """The chain's ``control.StateSpace`` (2 forces -> 2 displacements, modal form, unit DC scale)."""
    import control

    n = n_modes
    K = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    K[-1, -1] = 1.0
    lam, phi = np.linalg.eigh(K)
    wk = np.sqrt(lam * (2 * np.pi * f1) ** 2 / lam[0])
    ins, outs = [0, n // 2], [n // 3, n - 1]
    A = np.zeros((2 * n, 2 * n))
    B = np.zeros((2 * n, 2))
    C = np.zeros((2, 2 * n))
    for k in range(n):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0, 1], [-wk[k] ** 2, -2 * zeta * wk[k]]]
        B[2 * k + 1] = phi[ins, k]
        C[:, 2 * k] = phi[outs, k]
    dc = np.abs(C @ np.linalg.solve(-A, B)).max()
    return control.ss(A, B, C / dc, np.zeros((2, 2)))


def design_plant(n_modes: int):
    """The generalized plant of the chain with the benchmark's weights."""
    from robustctl.robust.plant import generalized_plant
    from robustctl.robust.uncertainty.weights import makeweight

    return generalized_plant(chain_plant(n_modes), performance=makeweight(3.0, (1.0, 1.0), 0.01),
                             disturbances=1.0, control_weight=0.1, noise=0.01,
                             input_mult=makeweight(0.2, (3.0, 1.0), 2.0))


def case(n_modes: int) -> dict:
    """One D-K run in this process."""
    import resource
    import time

    import robustctl as rc

    gp = design_plant(n_modes)
    t0, c0 = time.perf_counter(), time.process_time()
    row = {"n_modes": n_modes, "plant_states": int(gp.P.nstates),
           "load_average": [round(v, 2) for v in os.getloadavg()]}
    try:
        with rc.blas_threads(1):
            dk = rc.dksyn(gp, progress=False)
    except rc.RobustctlError as exc:
        row.update({"refused": f"{type(exc).__name__}: {exc}"})
        dk = None
    row.update({"wall_s": round(time.perf_counter() - t0, 2), "cpu_s": round(time.process_time() - c0, 2),
                "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)})
    if dk is not None:
        red = dk.design_reduction
        row.update({
            "mu_verified_full_plant": round(float(dk.mu_peak), 4),
            "full_loop_stable": bool(np.linalg.eigvals(np.asarray(dk.closed_loop.A)).real.max() < 0),
            "controller_states": int(dk.K.nstates),
            "iterations": len(dk.history),
            "design_states": int(red.order_after) if red else int(gp.P.nstates),
            "design_bound": round(float(red.bound), 4) if red else 0.0,
            "design_mu": round(float(red.mu_peak_design), 4) if red else None,
            "error_weight": round(float(red.error_weight), 5) if red else None,
            "design_tried": [[int(r), round(float(b), 4), why] for r, b, why in red.tried] if red else [],
        })
    return row


def _run(n_modes: int) -> dict:
    """:func:`case` in a fresh subprocess (its own time and peak memory)."""
    from benchmarks.scale_cases import in_fresh_process

    return in_fresh_process("bench_scale_dk", {"n_modes": n_modes}, n_modes)


def _exponent(rows: list[dict], x: str, y: str) -> float | None:
    pts = [(r[x], r[y]) for r in rows if r.get(y) and r.get(x)]
    if len(pts) < 2:
        return None
    return round(float(np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0]), 2)


def run() -> dict:
    load = os.getloadavg()
    return assemble([_run(n) for n in MODES], [round(v, 2) for v in load])


def assemble(rows: list[dict], load: list[float]) -> dict:
    """The result from the runs (also used to add a run measured apart: ``--add row.json``)."""
    rows = sorted(rows, key=lambda r: r["n_modes"])
    big = next((r for r in rows if r["n_modes"] == 160), {})
    metrics = {
        "modes_160_completed_verified": bool(big.get("full_loop_stable")) and "mu_verified_full_plant" in big,
        "modes_160_mu_verified": big.get("mu_verified_full_plant"),
        "modes_160_cpu_s": big.get("cpu_s"),
        "modes_160_wall_s": big.get("wall_s"),
        "modes_160_controller_states": big.get("controller_states"),
        "modes_160_design_states": big.get("design_states"),
        "cpu_exponent_vs_plant_states": _exponent(rows, "plant_states", "cpu_s"),
        "memory_exponent_vs_plant_states": _exponent(rows, "plant_states", "peak_mb"),
        "runs": rows,
        "load_average_at_start": load,
    }
    return {
        "name": "scale_dk",
        "description": "rc.dksyn on numpy chain plants of 20-160 modes (44-324 states; 2 forces, 2 "
                       "displacements; performance, control, noise, disturbance and input-multiplicative "
                       "weights): time, memory, controller order, mu verified with the full plant",
        "metrics": metrics,
        "targets": {"modes_160_completed_verified": "== True"},
    }


def _add(path: str) -> None:
    """Replace one run of ``results/scale_dk.json`` by the JSON line in ``path`` (``case(n)``'s output,
    measured apart) and recompute the metrics; the file keeps its machine and load records."""
    out = HERE / "results" / "scale_dk.json"
    old = json.loads(out.read_text())
    row = json.loads(Path(path).read_text().strip().splitlines()[-1])
    rows = [r for r in old["metrics"]["runs"] if r["n_modes"] != row["n_modes"]] + [row]
    new = assemble(rows, old["metrics"]["load_average_at_start"])
    new["metrics"]["added_run_load_average"] = row.get("load_average")
    result = {**old, **new}
    result["passed"] = bool(new["metrics"]["modes_160_completed_verified"])
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result["metrics"], indent=2))


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--add":
        _add(sys.argv[2])
    elif len(sys.argv) == 2:
        print(json.dumps(case(int(sys.argv[1]))))
    else:
        print(json.dumps(run(), indent=2))
