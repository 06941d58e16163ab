"""Synthetic large structures for the scale benchmark and tests: a spring grid (plate-like).

An ``nx x ny`` grid of point masses with one out-of-plane DOF each, springs to the four
neighbours and a soft spring to ground at every node (sparse symmetric M, K), 2 force inputs
and ``n_out`` acceleration outputs, the model's modal damping ``zeta_modal`` and a stiffness
scale ``k_scale`` as update parameters. The data are the exact FRF of the truth (an added
mass hidden at one node, a 2 % stiffness error) computed with numpy (dense generalised
eigen-solution, modal sum) plus 1 % complex log-normal noise.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

import robustctl as rc

K_SPRING = 1.0e4  # N/m between neighbours
K_GROUND = 50.0  # N/m to ground at every node
MASS = 0.1  # kg per node
ZETA = 0.01


def grid_shape(n_dof: int) -> tuple[int, int]:
    """A near-square grid with ``n_dof`` nodes (nx * ny == n_dof)."""
    nx = int(np.floor(np.sqrt(n_dof)))
    while n_dof % nx:
        nx -= 1
    return nx, n_dof // nx


def grid_matrices(nx: int, ny: int, node_scale: float = 1.0) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Mass (kg) and unit-scale stiffness (N/m) of the grid, sparse.

    ``node_scale`` multiplies each node's mass and ground spring (its share of the area): with
    ``node_scale = n_ref / n`` the grid is the ``n_ref``-node grid's membrane meshed ``n / n_ref``
    times finer (the neighbour springs of a membrane do not depend on the mesh size), so its
    low modes converge and the number of modes in a band stays that of ``n_ref`` nodes, as in an
    FE model refined for stresses rather than for the test band."""
    n = nx * ny
    idx = np.arange(n).reshape(ny, nx)
    pairs = np.concatenate([
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1),
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], axis=1),
    ])
    i, j = pairs[:, 0], pairs[:, 1]
    rows = np.concatenate([i, j, i, j])
    cols = np.concatenate([i, j, j, i])
    vals = K_SPRING * np.concatenate([np.ones(2 * i.size), -np.ones(2 * i.size)])
    K = (sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()
         + node_scale * K_GROUND * sp.identity(n, format="csr"))
    # a gentle mass gradient breaks the grid's symmetry (no repeated frequencies)
    m = node_scale * MASS * (1.0 + 0.3 * np.linspace(0.0, 1.0, n) ** 2)
    return sp.diags(m).tocsr(), K.tocsr()


def seam_pairs(nx: int, ny: int) -> np.ndarray:
    """The neighbour springs crossing the grid's middle (between rows ``ny // 2 - 1`` and
    ``ny // 2``): the line of a bolted seam joining two panels, ``nx`` node pairs (0-based)."""
    idx = np.arange(nx * ny).reshape(ny, nx)
    return np.stack([idx[ny // 2 - 1], idx[ny // 2]], axis=1)


def seam_stiffness(nx: int, ny: int) -> sp.csr_matrix:
    """The seam's part of the grid's stiffness (N/m): its :func:`seam_pairs` springs, sparse."""
    pairs = seam_pairs(nx, ny)
    i, j = pairs[:, 0], pairs[:, 1]
    n = nx * ny
    rows, cols = np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i])
    vals = K_SPRING * np.concatenate([np.ones(2 * i.size), -np.ones(2 * i.size)])
    return sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()


def seam_frf(n_dof: int, f_hz: np.ndarray, n_out: int = 8, added_mass: float = 0.03,
             seam_factor: float = 0.5, k_error: float = 0.02, node_scale: float = 1.0) -> np.ndarray:
    """The truth of the seam case (n_freq, n_out, 2): the grid with ``added_mass`` (kg) at
    :func:`hidden_node`, its panels ``1 + k_error`` times as stiff as modelled and its seam
    (:func:`seam_stiffness`) ``seam_factor`` times, structural damping of loss factor ``2 ZETA``
    (:func:`sparse_frf`)."""
    nx, ny = grid_shape(n_dof)
    M, K = grid_matrices(nx, ny, node_scale)
    Ks = seam_stiffness(nx, ny)
    ins, outs = sensor_layout(nx, ny, n_out)
    j = hidden_node(n_dof, n_out)
    M = (M + sp.csr_matrix(([added_mass], ([j], [j])), shape=M.shape)).tocsr()
    K = (1.0 + k_error) * (K - Ks) + seam_factor * Ks
    return sparse_frf(M, K, ins, outs, f_hz, 2 * ZETA)


def seam_data(n_dof: int, f_hz: np.ndarray, n_out: int = 8, noise: float = 0.01, seed: int = 0,
              added_mass: float = 0.03, seam_factor: float = 0.5, node_scale: float = 1.0):
    """:func:`seam_frf` plus ``noise`` complex log-normal noise, as FrequencyData."""
    g = seam_frf(n_dof, f_hz, n_out, added_mass=added_mass, seam_factor=seam_factor, node_scale=node_scale)
    rng = np.random.default_rng(seed)
    g = g * np.exp(noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    return rc.FrequencyData(f_hz, g, inputs=["F1", "F2"], outputs=[f"a{k + 1}" for k in range(n_out)])


def sensor_layout(nx: int, ny: int, n_out: int) -> tuple[list[int], list[int]]:
    """Input and output nodes (0-based) spread over the grid."""
    n = nx * ny
    inputs = [int(0.21 * n + 0.3 * nx), int(0.67 * n + 0.7 * nx) % n]
    outs = [int(k) for k in np.linspace(0.05 * n, 0.95 * n, n_out).astype(int)]
    outs = [o if o not in inputs else o + 1 for o in outs]
    return inputs, outs


def grid_model(n_dof: int, n_out: int = 4, node_scale: float = 1.0):
    """The PhysicalModel of the grid (``k_scale`` multiplies K; ``zeta_modal``)."""
    nx, ny = grid_shape(n_dof)
    M, K = grid_matrices(nx, ny, node_scale)
    ins, outs = sensor_layout(nx, ny, n_out)
    par = rc.Parameter("k_scale", 1.0, "", (0.5, 2.0), meaning="stiffness scale")
    return rc.structural_model(
        M, lambda th: th["k_scale"] * K,
        inputs={f"F{k + 1}": f"dof {d + 1}" for k, d in enumerate(ins)},
        outputs={f"a{k + 1}": (f"dof {d + 1}", "acceleration") for k, d in enumerate(outs)},
        damping=ZETA, params=[par], name=f"{nx}x{ny} spring grid",
    )


def hidden_node(n_dof: int, n_out: int = 4) -> int:
    """The 0-based node of the hidden added mass: at the second output's node, where it shows."""
    nx, ny = grid_shape(n_dof)
    _, outs = sensor_layout(nx, ny, n_out)
    return outs[1]


def sparse_frf(M: Any, K: Any, inputs: list[int], outputs: list[int], f_hz: np.ndarray,
               loss_factor: float) -> np.ndarray:
    """Acceleration FRF ``-w^2 q_o / F_i`` (m/s^2/N) of ``M q'' + K (1 + j eta) q = F`` by one
    sparse direct solve per frequency: shape (n_freq, n_out, n_in).

    Structural (hysteretic) damping with loss factor ``eta`` (``loss_factor``) is what a lab
    structure's material and joints show (a complex modulus; Ewins, *Modal Testing*, 2nd ed.,
    sec. 2.4): every mode has the equivalent viscous ratio ``eta / 2`` at its resonance, the
    modal-damping model's assumption, and no dense matrix is formed. The complex matrix
    ``K (1 + j eta) - w^2 M`` is factorised with SuperLU (``splu``, symmetric ordering of
    ``A + A^T``) at each frequency; memory is the factor's, time ``n_freq`` factorisations."""
    import scipy.sparse.linalg as spla

    M, K = sp.csc_matrix(M), sp.csc_matrix(K)
    n = M.shape[0]
    b = np.zeros((n, len(inputs)), dtype=complex)
    b[inputs, np.arange(len(inputs))] = 1.0
    Kc = (K * (1.0 + 1j * loss_factor)).tocsc()
    out = np.empty((len(f_hz), len(outputs), len(inputs)), dtype=complex)
    for k, f in enumerate(np.asarray(f_hz, dtype=float)):
        w2 = (2 * np.pi * f) ** 2
        lu = spla.splu((Kc - w2 * M).tocsc(), permc_spec="MMD_AT_PLUS_A")
        out[k] = -w2 * lu.solve(b)[outputs]
    return out


def exact_frf(n_dof: int, f_hz: np.ndarray, n_out: int = 4, added_mass: float = 0.05,
              k_error: float = 0.02, node_scale: float = 1.0) -> np.ndarray:
    """The truth's acceleration FRF (n_freq, n_out, 2): the grid with ``added_mass`` (kg) at
    :func:`hidden_node` and its stiffness ``1 + k_error`` times the model's, structural damping
    of loss factor ``2 ZETA`` (:func:`sparse_frf`: sparse solves, no dense matrix)."""
    nx, ny = grid_shape(n_dof)
    M, K = grid_matrices(nx, ny, node_scale)
    ins, outs = sensor_layout(nx, ny, n_out)
    j = hidden_node(n_dof, n_out)
    M = (M + sp.csr_matrix(([added_mass], ([j], [j])), shape=M.shape)).tocsr()
    return sparse_frf(M, (1.0 + k_error) * K, ins, outs, f_hz, 2 * ZETA)


def grid_data(n_dof: int, f_hz: np.ndarray, n_out: int = 4, noise: float = 0.01, seed: int = 0,
              added_mass: float = 0.05, node_scale: float = 1.0):
    """Exact FRF of the truth plus ``noise`` complex log-normal noise, as FrequencyData."""
    g = exact_frf(n_dof, f_hz, n_out, added_mass=added_mass, node_scale=node_scale)
    rng = np.random.default_rng(seed)
    g = g * np.exp(noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    inputs = ["F1", "F2"]
    outputs = [f"a{k + 1}" for k in range(n_out)]
    return rc.FrequencyData(f_hz, g, inputs=inputs, outputs=outputs)


def noise_model(f_hz: np.ndarray, n_out: int = 4, noise: float = 0.01):
    """The data's known log noise."""
    return rc.NoiseModel(f_hz, np.full((f_hz.size, n_out, 2), noise), f"synthetic log noise of {noise}")


def in_fresh_process(module: str, labels: dict, *args: Any) -> dict:
    """``benchmarks.<module>.case(*args)`` run in a fresh Python process, so that its wall time,
    CPU time and peak memory are its own; returns the case's JSON dict, or ``labels`` with the
    last line of the error when the process fails."""
    root = str(Path(__file__).resolve().parent.parent)
    call = ", ".join(repr(a) for a in args)
    code = (f"import json, sys; sys.path.insert(0, {root!r}); "
            f"from benchmarks.{module} import case; print(json.dumps(case({call})))")
    env = dict(os.environ, PYTHONPATH=root)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False)
    if out.returncode != 0:
        return {**labels, "error": out.stderr.strip().splitlines()[-1:]}
    return json.loads(out.stdout.strip().splitlines()[-1])
