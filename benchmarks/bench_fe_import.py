"""Benchmark: importing a user's Nastran model.

* A 10,000-DOF stiffness in an ASCII OP4 file with 20 property-group partitions (a banded
  lattice of springs, 20 groups of equal size) and a diagonal mass: the read time
  (:func:`robustctl.read_nastran_matrices`), the model build with 20 superparameters and the
  20 lowest modes (:func:`robustctl.load_nastran_matrices`), and the peak Python memory of each.
* A 200-mode OP2 eigenvector result over 1,667 grid points (10,002 DOFs): read time and peak
  memory (:func:`robustctl.read_nastran_modes`), the modal model with 3 inputs and 3 outputs
  (:func:`robustctl.load_nastran_modes`) and its FRF at 2,000 frequencies (also with the first
  100 modes, the size of ``bench_freqresp``'s modal system).

Files are written with pyNastran's writers first (not timed). Times are wall-clock without
tracing; peak memory is ``tracemalloc``'s peak of Python allocations (numpy buffers included),
MiB, from a second, traced call.

Run: ``python -m benchmarks fe_import`` (writes ``benchmarks/results/fe_import.json``).
"""

from __future__ import annotations

import json
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import scipy.sparse as sp

import robustctl as rc

N_DOF = 10_000
N_GROUPS = 20
N_MODES = 200
N_FREQ = 2_000


def _measure(fn):
    """Wall time of ``fn()`` (without tracing), then its peak traced memory on a second call, MiB."""
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    tracemalloc.start()
    fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return out, dt, peak / 2**20


def _lattice(n: int, n_groups: int):
    """Springs between DOF i and i+1 and i+7 (a banded SPD stiffness, grounded at both ends),
    each spring in group ``i * n_groups // n``."""
    rng = np.random.default_rng(0)
    parts = []
    for g in range(n_groups):
        rows, cols, vals = [], [], []
        for i in range(g * n // n_groups, (g + 1) * n // n_groups):
            for j in (i + 1, i + 7):
                k = 1e6 * (1 + 0.2 * rng.random())
                if j >= n:
                    rows.append(i), cols.append(i), vals.append(k)
                    continue
                rows += [i, j, i, j]
                cols += [i, j, j, i]
                vals += [k, k, -k, -k]
        parts.append(sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr())
    parts[0] = parts[0] + sp.csr_matrix(([1e6], ([0], [0])), shape=(n, n))
    return parts


def run() -> dict:
    from robustctl.physical.nastran_import import _pynastran, write_nastran_matrices, write_nastran_modes

    t0 = time.perf_counter()
    _pynastran()  # the first import of pyNastran, timed on its own
    t_import = time.perf_counter() - t0
    tmp = Path(tempfile.mkdtemp(prefix="bench_fe_import_"))
    parts = _lattice(N_DOF, N_GROUPS)
    K = sum(parts[1:], parts[0])
    M = sp.identity(N_DOF, format="csr") * 0.5
    op4 = tmp / "model.op4"
    t0 = time.perf_counter()
    write_nastran_matrices(op4, {"MAA": M, "KAA": K, **{f"KG{g:02d}": p for g, p in enumerate(parts)}})
    t_write_op4 = time.perf_counter() - t0
    labels = [f"{1 + i // 6}:{('T1', 'T2', 'T3', 'R1', 'R2', 'R3')[i % 6]}" for i in range(N_DOF)]

    (mats, _), t_read_op4, mem_read_op4 = _measure(lambda: rc.read_nastran_matrices(op4))
    groups = {f"g{g:02d}": f"KG{g:02d}" for g in range(N_GROUPS)}
    model, t_build, mem_build = _measure(
        lambda: rc.load_nastran_matrices(
            op4, inputs=["1:T1"], outputs=["1000:T1"], groups=groups, dof_labels=labels, n_modes=20
        )
    )
    agree = float(abs(mats["KAA"] - K).max() / abs(K).max())

    n_grid = -(-N_DOF // 6)
    rng = np.random.default_rng(1)
    modes = rc.ModeShapes(
        f_hz=np.sort(rng.uniform(1.0, 500.0, N_MODES)),
        node_ids=np.arange(1, n_grid + 1),
        shapes=rng.standard_normal((N_MODES, n_grid, 6)),
        generalized_mass=np.ones(N_MODES),
    )
    op2 = tmp / "modes.op2"
    t0 = time.perf_counter()
    write_nastran_modes(op2, modes)
    t_write_op2 = time.perf_counter() - t0
    read, t_read_op2, mem_read_op2 = _measure(lambda: rc.read_nastran_modes(op2))
    ins, outs = ["1:T1", "200:T2", "900:T3"], ["5:T1", "600:T2", "1500:T3"]
    modal, t_modal, mem_modal = _measure(lambda: rc.load_nastran_modes(op2, inputs=ins, outputs=outs))
    f_hz = np.geomspace(0.5, 600.0, N_FREQ)
    modal.freqresp(f_hz)  # warm the cache
    t0 = time.perf_counter()
    modal.freqresp(f_hz)
    t_frf = time.perf_counter() - t0
    shape_err = float(np.max(np.abs(read.shapes - modes.shapes.astype(np.float32))))
    half = rc.fe_modal_model(read, ins, outs, n_modes=N_MODES // 2)  # the freqresp benchmark's 100 modes
    half.freqresp(f_hz)
    t0 = time.perf_counter()
    half.freqresp(f_hz)
    t_frf_half = time.perf_counter() - t0

    metrics = {
        "pynastran_import_s": round(t_import, 2),
        "op4_n_dof": N_DOF,
        "op4_groups": N_GROUPS,
        "op4_file_mib": round(op4.stat().st_size / 2**20, 1),
        "op4_write_s": round(t_write_op4, 2),
        "op4_read_s": round(t_read_op4, 3),
        "op4_read_peak_mib": round(mem_read_op4, 1),
        "op4_build_20_groups_20_modes_s": round(t_build, 3),
        "op4_build_peak_mib": round(mem_build, 1),
        "op4_read_back_rel_error": agree,
        "op2_modes": N_MODES,
        "op2_grids": n_grid,
        "op2_file_mib": round(op2.stat().st_size / 2**20, 1),
        "op2_write_s": round(t_write_op2, 2),
        "op2_read_s": round(t_read_op2, 3),
        "op2_read_peak_mib": round(mem_read_op2, 1),
        "op2_modal_model_s": round(t_modal, 3),
        "op2_modal_model_peak_mib": round(mem_modal, 1),
        "op2_frf_2000pt_3x3_s": round(t_frf, 4),
        "op2_frf_2000pt_3x3_first_100_modes_s": round(t_frf_half, 4),
        "op2_shape_read_back_max_error": shape_err,
    }
    for f in tmp.iterdir():
        f.unlink()
    tmp.rmdir()
    return {
        "name": "fe_import",
        "description": "Nastran import: 10,000-DOF OP4 stiffness with 20 group partitions (read, build with "
        "20 superparameters and 20 modes) and a 200-mode OP2 (read, modal model, 2,000-point FRF)",
        "metrics": metrics,
        "targets": {"op4_read_back_rel_error": "< 1e-12", "op2_shape_read_back_max_error": "== 0"},
        "passed": bool(agree < 1e-12 and shape_err == 0.0),
    }


def main() -> None:
    result = run()
    out = Path(__file__).parent / "results" / "fe_import.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
