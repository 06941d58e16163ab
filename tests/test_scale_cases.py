"""The scale benchmark's truth: the sparse-solve FRF against a dense modal sum."""

import numpy as np
import scipy.linalg as sla

from benchmarks.scale_cases import grid_matrices, sensor_layout, sparse_frf


def test_sparse_frf_equals_dense_modal_frf_with_structural_damping():
    # 10 x 20 grid (200 DOFs), refined-mesh scaling; the modal sum of K (1 + j eta) - w^2 M with
    # mass-normalised modes of the dense generalised eigenproblem
    M, K = grid_matrices(10, 20, node_scale=0.5)
    ins, outs = sensor_layout(10, 20, 6)
    eta = 0.02
    lam, phi = sla.eigh(K.toarray(), M.toarray())
    wk = np.sqrt(lam)
    f = np.concatenate([np.linspace(0.5, 60.0, 37), wk[[0, 7, 50]] / (2 * np.pi)])  # and at resonances
    w = 2 * np.pi * f[:, None]
    h = -(w**2) / (wk[None, :] ** 2 * (1 + 1j * eta) - w**2)
    dense = np.einsum("fk,ok,ik->foi", h, phi[outs], phi[ins])
    got = sparse_frf(M, K, ins, outs, f, eta)
    assert got.shape == (f.size, 6, 2)
    assert np.max(np.abs(got - dense) / np.abs(dense)) < 1e-10


def test_refined_mesh_keeps_the_low_modes():
    # node_scale = n_ref / n: the 2x-refined grid's first modes approach the coarse grid's
    # (ground-spring mode sqrt(K_GROUND / MASS) and the membrane modes above it)
    Mc, Kc = grid_matrices(8, 10)
    Mf, Kf = grid_matrices(16, 20, node_scale=0.25)
    lc = sla.eigh(Kc.toarray(), Mc.toarray(), eigvals_only=True)[:4]
    lf = sla.eigh(Kf.toarray(), Mf.toarray(), eigvals_only=True)[:4]
    assert np.allclose(lf, lc, rtol=0.05)
    assert np.sqrt(lf[0]) / (2 * np.pi) > 3.0
