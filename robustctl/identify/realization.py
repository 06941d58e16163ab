"""Pole-residue model -> real modal state space (one 2x2 block per complex pair and retained
residue rank; one 1x1 block per real pole and rank). This is step 6 of the Caltech algorithm,
done through partial fractions rather than the ill-conditioned polynomial coefficients.

For a pair ``p = sigma + j omega`` with residue ``R = sum_i gamma_i beta_i`` (SVD terms
``gamma_i`` a column, ``beta_i`` a row), each term is realised by

    A_i = [[sigma, -omega], [omega, sigma]],  B_i = [[Re beta_i], [Im beta_i]],
    C_i = [2 Re gamma_i, -2 Im gamma_i],

which gives ``gamma_i beta_i / (s - p) + conj(...) / (s - conj p)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import control
import numpy as np

__all__ = ["residue_rank", "residue_factors", "modal_matrices", "modal_statespace"]


def residue_rank(residue: np.ndarray, rtol: float = 1e-8) -> int:
    """Numerical rank of a residue matrix: singular values above ``rtol * sigma_1``."""
    sv = np.linalg.svd(np.atleast_2d(residue), compute_uv=False)
    if sv.size == 0 or sv[0] == 0:
        return 0
    return int(np.count_nonzero(sv > rtol * sv[0]))


def residue_factors(residue: np.ndarray, rank: int) -> tuple[np.ndarray, np.ndarray]:
    """Best rank-``rank`` factors ``C (n_out, rank)``, ``B (rank, n_in)`` with ``C B ~ R``
    (the seed's eqs. 9-10: ``C = U sqrt(S)``, ``B = sqrt(S) V^*``, balanced split)."""
    u, sv, vh = np.linalg.svd(np.atleast_2d(residue), full_matrices=False)
    root = np.sqrt(sv[:rank])
    return u[:, :rank] * root, root[:, None] * vh[:rank]


def _block(p: complex, c: np.ndarray, b: np.ndarray):
    if p.imag == 0:
        return np.array([[p.real]]), b.real[None, :], c.real[:, None]
    a = np.array([[p.real, -p.imag], [p.imag, p.real]])
    return a, np.vstack([b.real, b.imag]), np.column_stack([2 * c.real, -2 * c.imag])


def modal_matrices(
    poles: np.ndarray, residues: np.ndarray, d: np.ndarray, ranks: Sequence[int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """Real block-diagonal ``(A, B, C, D)`` and state names ``m<k>[.<i>].re|im`` (or ``.r``)."""
    n_out, n_in = np.shape(d)
    blocks, bs, cs, names = [], [], [], []
    for k, (p, r, rank) in enumerate(zip(poles, residues, ranks), start=1):
        cmat, bmat = residue_factors(r.real if p.imag == 0 else r, int(rank))
        for i in range(int(rank)):
            a, b, c = _block(p, cmat[:, i], bmat[i])
            blocks.append(a)
            bs.append(b)
            cs.append(c)
            tag = f"m{k}" if rank == 1 else f"m{k}.{i + 1}"
            names += [f"{tag}.r"] if p.imag == 0 else [f"{tag}.re", f"{tag}.im"]
    n = len(names)
    a_full = np.zeros((n, n))
    k0 = 0
    for a in blocks:
        m = a.shape[0]
        a_full[k0 : k0 + m, k0 : k0 + m] = a
        k0 += m
    b_full = np.vstack(bs) if bs else np.zeros((0, n_in))
    c_full = np.hstack(cs) if cs else np.zeros((n_out, 0))
    return a_full, b_full, c_full, np.asarray(d, dtype=float), names


def modal_statespace(
    poles: np.ndarray,
    residues: np.ndarray,
    d: np.ndarray,
    ranks: Sequence[int],
    inputs: Sequence[str],
    outputs: Sequence[str],
    name: str | None = None,
):
    """The modal realisation as a ``control.StateSpace`` with named inputs, outputs and states."""
    a, b, c, dd, states = modal_matrices(poles, residues, d, ranks)
    return control.ss(
        a, b, c, dd, inputs=list(inputs), outputs=list(outputs), states=states or None, name=name
    )
