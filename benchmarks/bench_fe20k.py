"""Benchmark: ``rc.diagnose`` on an imported sparse FE model of 2,000 and 20,000 DOFs.

The model (:func:`benchmarks.bench_scale.fe_model`): the spring grid of
:mod:`benchmarks.scale_cases` meshed from 2,000 nodes (the ``scale`` benchmark's largest case,
the same structure) to 20,000 (each node's mass and ground spring scaled by ``2000 / n``: the
same membrane on a 10x finer mesh, so the modes in the band are the 2,000-node grid's), its
sparse ``M`` and ``K`` written to an ASCII OP4 file with pyNastran and read back with
``rc.load_nastran_matrices`` (parameters ``k_grid``, the stiffness factor, and ``zeta_modal``),
2 shakers and 8 accelerometers, the default candidates (an added mass, a grounded spring and a
dashpot at every DOF: 60,000 at 20,000 DOFs, I/O effects, modal damping groups). Data: the truth
(a 0.03 kg mass hidden at the second sensor's node, a 2 % stiffness error, structural damping of
loss factor 0.02) by a sparse direct solve per frequency (``scale_cases.sparse_frf``) plus 1 %
complex noise, 400 frequencies over 0.8-6 times the first mode.

Each run is a fresh subprocess (``scale_cases.in_fresh_process``): wall time of ``rc.diagnose``,
its CPU time with its worker processes, peak resident memory of the process and of its workers
(``getrusage``), the rank of the hidden mass, the load average at its end. Targets (issue 37):
20,000 DOFs in under 300 s and 4 GB on 2 cores, 2,000 DOFs in under 60 s.

Run: ``python -m benchmarks fe20k`` (writes ``benchmarks/results/fe20k.json``);
``FE20K_SIZES=2000`` limits the sizes.
"""

from __future__ import annotations

import os

SIZES = (2000, 20000)
TARGET_S = {2000: 60.0, 20000: 300.0}
TARGET_MB = 4096.0


def _run(n_dof: int) -> dict:
    from benchmarks.scale_cases import in_fresh_process

    return in_fresh_process("bench_scale", {"n_dof": n_dof, "path": "fe"}, n_dof, "fe")


def run() -> dict:
    text = os.environ.get("FE20K_SIZES")
    sizes = SIZES if not text else tuple(int(s) for s in text.split(","))
    rows = [_run(n) for n in sizes]
    metrics: dict = {"runs": rows}
    targets: dict = {}
    for r in rows:
        if "error" in r:
            continue
        n = r["n_dof"]
        metrics[f"dof_{n}_time_s"] = r["time_s"]
        metrics[f"dof_{n}_cpu_s"] = r["cpu_s"]
        metrics[f"dof_{n}_peak_mb"] = round(r["peak_mb"] + r["peak_workers_mb"], 1)
        metrics[f"dof_{n}_rank_of_true_effect"] = r["rank_of_true_effect"]
        targets[f"dof_{n}_time_s"] = f"< {TARGET_S.get(n, 300.0)}"
        targets[f"dof_{n}_peak_mb"] = f"< {TARGET_MB}"
        targets[f"dof_{n}_rank_of_true_effect"] = "== 1"
    return {
        "name": "fe20k",
        "description": "rc.diagnose on an OP4-imported sparse FE model (spring-grid membrane, 2 shakers x 8 "
                       "accelerometers, default candidates, one hidden 0.03 kg mass) of 2,000 and 20,000 DOF",
        "metrics": metrics,
        "targets": targets,
    }
