"""Rank-constrained residue refinement for fixed poles (alternating least squares).

A physical mode has a rank-1 residue ``c b^T`` (Caltech eq. 9) and a group of ``k`` modes at
one pole a rank-``k`` residue ``C B`` (eq. 10). Truncating a least-squares residue by SVD gives
such factors but not the best ones; with the poles fixed, the model is linear in ``C`` for
fixed ``B`` and in ``B`` for fixed ``C``, so alternating weighted least squares (relative
weighting ``sqrt(w)/|g|``, the log-like error of MACE eq. 5) lowers the cost monotonically.
Real poles keep their residues; the feedthrough is refitted in every half step.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..checks import coherence_weights
from ..threads import limit_blas
from .poles import basis_gram, evaluate, n_states
from .rational_fit import RationalFit
from .realization import residue_factors

__all__ = ["refine_residues"]


def _row_weights(fit: RationalFit, weights: np.ndarray | None) -> np.ndarray:
    """Row weights ``sqrt(w) / |G_data|`` of the relative (log-like) residual, shape of the data;
    ``w`` defaults to the coherence weights (or 1 without coherence)."""
    data = fit.data
    if weights is None:
        weights = np.ones(data.shape) if data.coherence is None else coherence_weights(data.coherence)
    return np.sqrt(np.broadcast_to(weights, data.shape)) / np.maximum(np.abs(data.response), 1e-300)


def _factor_map(factors: list[np.ndarray], n_rows: int) -> np.ndarray:
    """Real maps ``M_i`` (one per input ``i``) from the real partial-fraction basis (then the
    constant) to the unknown columns of one output: per term with input factor ``b`` the columns
    ``phi b + psi conj(b) = c1 Re b + c2 Im b`` and ``j (phi b - psi conj(b)) = -c1 Im b + c2 Re b``
    (``c1 = phi + psi``, ``c2 = j (phi - psi)``, :func:`.poles.partial_fraction_basis`), then one
    feedthrough column per input. ``factors[g]`` has shape (k_g, n_in); returns (n_in, n_rows, u)."""
    n_in = factors[0].shape[1] if factors else 0
    n_terms = sum(b.shape[0] for b in factors)
    out = np.zeros((n_in, n_rows, 2 * n_terms + n_in))
    col = 0
    for g, b in enumerate(factors):
        for m in range(b.shape[0]):
            re, im = b[m].real, b[m].imag
            out[:, 2 * g, col], out[:, 2 * g + 1, col] = re, im
            out[:, 2 * g, col + 1], out[:, 2 * g + 1, col + 1] = -im, re
            col += 2
    out[np.arange(n_in), n_rows - 1, col + np.arange(n_in)] = 1.0
    return out


def _solve_outputs(gram: np.ndarray, rhs: np.ndarray, factors: list[np.ndarray]):
    """Given input factors ``B_g`` (k_g, n_in), the weighted least-squares ``C_g`` rows and ``D`` of
    every output at once, from the basis Gram matrices ``gram[o, i]`` and right-hand sides
    ``rhs[o, i]`` of each channel (:func:`.poles.basis_gram`): the normal equations of output ``o``
    are ``sum_i M_i^T gram[o, i] M_i x = sum_i M_i^T rhs[o, i]`` (``M_i``: :func:`_factor_map`),
    solved column-scaled with a 1e-12 ridge."""
    maps = _factor_map(factors, gram.shape[-1])
    normal = np.einsum("iau,oiav->ouv", maps, np.matmul(gram, maps[None]))
    right = np.einsum("iau,oia->ou", maps, rhs)
    scale = 1.0 / np.sqrt(np.maximum(np.einsum("oii->oi", normal), 1e-300))
    scaled = normal * scale[:, :, None] * scale[:, None, :] + 1e-12 * np.eye(normal.shape[-1])
    x = np.linalg.solve(scaled, (right * scale)[:, :, None])[:, :, 0] * scale
    n_c = x.shape[1] - maps.shape[0]
    cs = x[:, :n_c:2] + 1j * x[:, 1:n_c:2]  # (n_out, sum k)
    splits = np.cumsum([b.shape[0] for b in factors])[:-1]
    return np.split(cs, splits, axis=1), x[:, n_c:]


@limit_blas
def refine_residues(fit: RationalFit, weights: np.ndarray | None = None, sweeps: int = 8) -> RationalFit:
    """Refit the complex poles' residues as rank-``ranks`` products ``C B`` to ``fit.data``.

    Parameters
    ----------
    fit : RationalFit
        Poles, ranks and starting residues; ``fit.data`` holds the data to fit.
    weights : ndarray, optional
        Weights on squared residuals (default: coherence-based, as :func:`fit_rational`).
    sweeps : int
        Alternations (each solves for all ``C`` then all ``B``).

    Returns
    -------
    RationalFit
        Same poles and ranks, refined residues and ``D`` (``fit`` itself when a shape solve is
        singular and would leave inf or NaN).
    """
    if fit.data is None or sweeps < 1:
        return fit
    cplx = np.flatnonzero((fit.poles.imag != 0) & (fit.ranks > 0))
    s = 2j * np.pi * fit.data.f_hz
    rw = _row_weights(fit, weights)
    real = np.flatnonzero(fit.poles.imag == 0)
    fixed = evaluate(s, fit.poles[real], fit.residues[real], np.zeros_like(fit.d))
    target = fit.data.response - fixed
    poles = fit.poles[cplx]
    factors = [residue_factors(fit.residues[g], int(fit.ranks[g])) for g in cplx]
    bs = [f[1] for f in factors]
    # the Gram matrices and right-hand sides of every channel: fixed poles, so shared by all sweeps
    k, n_out, n_in = target.shape
    w2 = (rw**2).reshape(k, -1)
    gram, phi = basis_gram(s, poles, w2, with_basis=True)
    gram = gram.reshape(n_out, n_in, *(2 * [n_states(poles) + 1]))
    basis = np.hstack([phi, np.ones((k, 1))])
    rhs = (np.conj(basis).T @ (w2 * target.reshape(k, -1))).real.T.reshape(n_out, n_in, -1)
    gram_t, rhs_t = np.swapaxes(gram, 0, 1), np.swapaxes(rhs, 0, 1)
    for _ in range(int(sweeps)):
        cs, d = _solve_outputs(gram, rhs, bs)
        bts, _ = _solve_outputs(gram_t, rhs_t, [c.T for c in cs])
        bs = [b.T for b in bts]
    cs, d = _solve_outputs(gram, rhs, bs)
    residues = np.array(fit.residues)
    for g, c, b in zip(cplx, cs, bs):
        residues[g] = c @ b
    if not (np.all(np.isfinite(residues)) and np.all(np.isfinite(d))):  # a singular shape solve
        return fit
    return replace(fit, residues=residues, d=d)
