"""Benchmark: ``rc.diagnose`` against the size of the structure (DOFs), full and reduced path.

Cases (:mod:`benchmarks.scale_cases`): a spring grid (plate-like, one out-of-plane DOF per
node, sparse ``M``, ``K``) of 100 to 2,000 DOFs with 2 force inputs and 8 acceleration
outputs, update parameters ``k_scale`` and ``zeta_modal``, the default candidates
(``rc.effects.candidates``: an added mass, a grounded spring and a dashpot at every DOF, I/O
effects, modal damping groups), data = the exact FRF of the truth by sparse direct solves (a 0.03 kg
mass hidden at the second sensor's node, a 2 % stiffness error, structural damping of loss
factor 0.02) plus 1 % complex noise, 400
frequencies from 0.8 to 6 times the first mode. Each run is a fresh subprocess: wall time, CPU
time and the peak resident memory of it and of its worker processes (``getrusage``).

Paths: the default (``rc.diagnose`` reduces structures of at least
:data:`robustctl.physical.reduction.REDUCE_MIN_DOF` DOFs: in-band modes + residual modes, the
point candidates scored in closed form on the reduced modal model and the leaders fitted by the
exact path), the reduced path forced on a 200-DOF grid, and the
full dense path (all modes) forced where it runs in reasonable time; the ranking at 200 DOFs is
compared between the two. Exponents are least-squares slopes of ``log time`` and ``log memory``
against ``log DOFs``.

Path "fe" (:mod:`benchmarks.bench_fe20k` runs it): the grid of :data:`FE_REF_DOF` nodes meshed
finer, imported through an OP4 file (:func:`fe_model`).

Run: ``python -m benchmarks.bench_scale`` (writes ``benchmarks/results/scale.json``);
``SCALE_SIZES=400,1000`` limits the sizes of the default path, ``SCALE_FULL=100,200`` those of
the full path; ``--add run.json`` adds one run's JSON line (``_run(n, path)``) measured apart.
Times are wall-clock on a shared machine; ``cpu_s`` (this process and its workers) is the
steadier figure.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SIZES = (500, 1000, 2000)
FULL_SIZES = (100, 200)
TARGET_S = 60.0
TARGET_MB = 2048.0
N_OUT = 8
HIDDEN_KG = 0.03


#: The FE case's mesh: the grid of this many nodes refined (``scale_cases.grid_matrices``'
#: ``node_scale``), so its modes in the band are those of the 2,000-DOF case.
FE_REF_DOF = 2000


def fe_model(n_dof: int, node_scale: float, tmp: str):
    """The grid as a user's imported FE model: ``M``, ``K`` written to an ASCII OP4 file
    (``rc.write_nastran_matrices``, pyNastran's writer) and read back with
    ``rc.load_nastran_matrices`` (one property group ``grid`` = all of ``K``: parameter
    ``k_grid``, the stiffness factor), DOFs named ``"<node>:T3"``, modal damping ``ZETA``."""
    import robustctl as rc
    from benchmarks.scale_cases import ZETA, grid_matrices, grid_shape, sensor_layout

    nx, ny = grid_shape(n_dof)
    M, K = grid_matrices(nx, ny, node_scale)
    ins, outs = sensor_layout(nx, ny, N_OUT)
    path = str(Path(tmp) / f"grid{n_dof}.op4")
    rc.write_nastran_matrices(path, {"MAA": M, "KAA": K})
    labels = [f"{i + 1}:T3" for i in range(n_dof)]
    return rc.load_nastran_matrices(
        path, mass="MAA", stiffness="KAA", groups={"grid": "KAA"}, dof_labels=labels,
        inputs={f"F{k + 1}": f"{d + 1}:T3" for k, d in enumerate(ins)},
        outputs={f"a{k + 1}": (f"{d + 1}:T3", "acceleration") for k, d in enumerate(outs)},
        damping=ZETA, name=f"{nx}x{ny} grid (OP4)")


#: The seam case's soft joint: the seam (``scale_cases.seam_stiffness``) this many times as stiff as
#: modelled in the truth (the panels 2 % stiffer), beside the hidden mass.
SEAM_FACTOR = 0.4


def fe_seam_model(n_dof: int, node_scale: float, tmp: str):
    """The grid as two panels joined by a bolted seam, as a user's FE model with property groups:
    ``MAA``, ``KAA`` and the partitions ``KPANEL`` (the panels' springs and the ground springs) and
    ``KSEAM`` (the springs crossing the grid's middle, ``scale_cases.seam_stiffness``) written to an
    ASCII OP4 file and read with ``rc.load_nastran_matrices(..., groups={"panels": "KPANEL",
    "seam": "KSEAM"}, fixed_groups=["seam"])``: ``k_panels`` is the update's stiffness factor, the
    seam is left to the diagnosis (a ``stiffness change of seam`` candidate)."""
    import robustctl as rc
    from benchmarks.scale_cases import ZETA, grid_matrices, grid_shape, seam_stiffness, sensor_layout

    nx, ny = grid_shape(n_dof)
    M, K = grid_matrices(nx, ny, node_scale)
    Ks = seam_stiffness(nx, ny)
    ins, outs = sensor_layout(nx, ny, N_OUT)
    path = str(Path(tmp) / f"seam{n_dof}.op4")
    rc.write_nastran_matrices(path, {"MAA": M, "KAA": K, "KPANEL": (K - Ks).tocsr(), "KSEAM": Ks})
    labels = [f"{i + 1}:T3" for i in range(n_dof)]
    return rc.load_nastran_matrices(
        path, mass="MAA", stiffness="KAA", groups={"panels": "KPANEL", "seam": "KSEAM"},
        fixed_groups=["seam"], dof_labels=labels,
        inputs={f"F{k + 1}": f"{d + 1}:T3" for k, d in enumerate(ins)},
        outputs={f"a{k + 1}": (f"{d + 1}:T3", "acceleration") for k, d in enumerate(outs)},
        damping=ZETA, name=f"{nx}x{ny} two panels and a seam (OP4)")


def case(n_dof: int, path: str) -> dict:
    """One diagnose run in this process (``path``: "default", "reduced" or "full" on
    ``scale_cases.grid_model``; "fe": the mesh of :data:`FE_REF_DOF` nodes refined to ``n_dof``,
    imported through an OP4 file, :func:`fe_model`; "fe_seam": that mesh as two panels and a
    seam, :func:`fe_seam_model`, the truth with the seam :data:`SEAM_FACTOR` times as stiff as
    modelled beside the hidden mass, ``scale_cases.seam_data``)."""
    import resource
    import tempfile
    import time

    import robustctl as rc
    import robustctl.physical.reduction as red
    from benchmarks.scale_cases import grid_data, grid_model, hidden_node, noise_model, seam_data

    if path == "reduced":
        red.REDUCE_MIN_DOF = 0
    elif path == "full":
        red.REDUCE_MIN_DOF = 10**9
    node_scale = FE_REF_DOF / n_dof if path in ("fe", "fe_seam") else 1.0
    c_start = time.process_time()
    if path in ("fe", "fe_seam"):
        with tempfile.TemporaryDirectory() as tmp:
            model = (fe_model if path == "fe" else fe_seam_model)(n_dof, node_scale, tmp)
        true_name = f"added mass at node {hidden_node(n_dof, N_OUT) + 1}:T3"
    else:
        model = grid_model(n_dof, N_OUT)
        true_name = f"added mass at dof {hidden_node(n_dof, N_OUT) + 1}"
    f1 = 3.39  # first mode of the grid family (Hz): springs to ground dominate it
    f = np.linspace(0.8 * f1, 6.0 * f1, 400)
    if path == "fe_seam":
        data = seam_data(n_dof, f, N_OUT, added_mass=HIDDEN_KG, seam_factor=SEAM_FACTOR,
                         node_scale=node_scale)
    else:
        data = grid_data(n_dof, f, N_OUT, added_mass=HIDDEN_KG, node_scale=node_scale)
    setup_cpu = time.process_time() - c_start
    t0, c0 = time.perf_counter(), os.times()
    diag = rc.diagnose(model, data, noise=noise_model(f, N_OUT))
    c1 = os.times()
    wall = time.perf_counter() - t0
    cpu = sum(getattr(c1, k) - getattr(c0, k) for k in ("user", "system", "children_user", "children_system"))
    names = [r.name for r in diag.ranking]
    extra = {}
    if path == "fe_seam":
        extra = _seam_report(diag, names, true_name, model)
    return {
        "n_dof": n_dof,
        "path": path,
        "time_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "setup_cpu_s": round(setup_cpu, 2),
        "peak_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
        "peak_workers_mb": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1),
        "n_candidates": len(diag.ranking) + sum(len(r.equivalent) for r in diag.ranking),
        "evaluations": diag.n_evals,
        "top": names[0],
        "rank_of_true_effect": names.index(true_name) + 1 if true_name in names else None,
        "true_effect_significant": any(r.significant for r in diag.ranking if r.name == true_name),
        "ranking": names[:20],
        "load_average": [round(x, 2) for x in os.getloadavg()],
        **extra,
    }


def _seam_report(diag, names: list[str], mass_name: str, model) -> dict:
    """The seam case's figures: the chain (each effect's name and fitted values), the verdict,
    the rank of each hidden effect in the first step's ranking and in the chain, and how the
    point candidates were screened (``diag.screening``)."""
    seam_name = "stiffness change of seam"
    chain = [{"name": c.effect.name, "values": {k: round(float(v), 5) for k, v in c.effect.values.items()},
              "gain": round(float(c.gain), 4), "p_value": float(c.p_value)} for c in diag.chain]
    chain_names = [c["name"] for c in chain]
    return {
        "verdict": diag.verdict,
        "chain": chain,
        "update_values": {k: round(float(v), 5) for k, v in diag.best_fit_values.items()},
        "rank_of_mass_first_step": names.index(mass_name) + 1 if mass_name in names else None,
        "rank_of_seam_first_step": names.index(seam_name) + 1 if seam_name in names else None,
        "mass_in_chain": mass_name in chain_names,
        "seam_in_chain": seam_name in chain_names,
        "seam_factor_true": SEAM_FACTOR,
        "screening": dict(getattr(diag, "screening", {}) or {}),
    }


def _run(n_dof: int, path: str) -> dict:
    """:func:`case` in a fresh subprocess (its own time and peak memory)."""
    from benchmarks.scale_cases import in_fresh_process

    return in_fresh_process("bench_scale", {"n_dof": n_dof, "path": path}, n_dof, path)


def _exponent(rows: list[dict], key: str) -> float | None:
    pts = [(r["n_dof"], r[key]) for r in rows if key in r and r[key] > 0]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return round(float(np.polyfit(x, y, 1)[0]), 2)


def _sizes(name: str, default: tuple[int, ...]) -> tuple[int, ...]:
    text = os.environ.get(name)
    return default if not text else tuple(int(s) for s in text.split(","))


def run() -> dict:
    sizes, full_sizes = _sizes("SCALE_SIZES", SIZES), _sizes("SCALE_FULL", FULL_SIZES)
    default = [_run(n, "default") for n in sizes]
    full = [_run(n, "full") for n in full_sizes]
    reduced_200 = _run(200, "reduced")
    if not any(r["n_dof"] == 200 for r in full):
        full.append(_run(200, "full"))
    return assemble(default, full, reduced_200)


def assemble(default: list[dict], full: list[dict], reduced_200: dict) -> dict:
    """The result JSON from the runs (also used to add a run measured separately:
    ``python -m benchmarks.bench_scale --add run.json``)."""
    default = sorted(default, key=lambda r: r["n_dof"])
    full = sorted(full, key=lambda r: r["n_dof"])
    full_200 = next((r for r in full if r["n_dof"] == 200), {})
    big = next((r for r in default if r["n_dof"] == 2000), None)
    reduced = [reduced_200] + [r for r in default if "error" not in r]
    metrics = {
        "default_path": default,
        "full_path": full,
        "reduced_path_200_dof": reduced_200,
        "time_exponent_reduced": _exponent(reduced, "time_s"),
        "cpu_exponent_reduced": _exponent(reduced, "cpu_s"),
        "memory_exponent_reduced": _exponent(reduced, "peak_mb"),
        "time_exponent_full": _exponent(full, "time_s"),
        "cpu_exponent_full": _exponent(full, "cpu_s"),
        "memory_exponent_full": _exponent(full, "peak_mb"),
        "same_ranking_200_dof_reduced_vs_full": reduced_200.get("ranking") == full_200.get("ranking"),
        "same_top_200_dof_reduced_vs_full": reduced_200.get("top") == full_200.get("top"),
    }
    if big is not None and "error" not in big:
        metrics.update({
            "dof_2000_time_s": big["time_s"],
            "dof_2000_peak_mb": round(big["peak_mb"] + big["peak_workers_mb"], 1),
            "dof_2000_rank_of_true_effect": big["rank_of_true_effect"],
        })
    targets = {"dof_2000_time_s": f"< {TARGET_S}", "dof_2000_peak_mb": f"< {TARGET_MB}",
               "dof_2000_rank_of_true_effect": "== 1", "same_top_200_dof_reduced_vs_full": "== True"}
    passed = bool(big is not None and "error" not in big and big["time_s"] < TARGET_S
                  and metrics["dof_2000_peak_mb"] < TARGET_MB and big["rank_of_true_effect"] == 1
                  and metrics["same_top_200_dof_reduced_vs_full"])
    return {
        "name": "scale",
        "description": "rc.diagnose on spring grids of 100-2000 DOFs (2 inputs x 8 outputs, default "
                       "candidates, one hidden added mass): time and peak memory against size, "
                       "reduced and full path",
        "metrics": metrics,
        "targets": targets,
        "passed": passed,
    }


def main() -> None:
    out = HERE / "results" / "scale.json"
    if len(sys.argv) > 2 and sys.argv[1] == "--add":  # a run measured on its own, added
        old = json.loads(out.read_text())["metrics"]
        row = json.loads(Path(sys.argv[2]).read_text().strip().splitlines()[-1])
        key = "full_path" if row["path"] == "full" else "default_path"
        rows = [r for r in old[key] if r["n_dof"] != row["n_dof"]] + [row]
        parts = {"default_path": old["default_path"], "full_path": old["full_path"], key: rows}
        result = assemble(parts["default_path"], parts["full_path"], old["reduced_path_200_dof"])
    else:
        result = run()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
