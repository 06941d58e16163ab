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
from .poles import evaluate, lstsq_normal
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


def _solve_outputs(s, target, rw, poles, bs):
    """Given input factors B_g (k_g, n_in), least-squares C_g rows and D per output."""
    n_in = target.shape[2]
    phi = 1.0 / (s[:, None] - poles[None, :])
    psi = 1.0 / (s[:, None] - np.conj(poles)[None, :])
    cols = []
    for g, b in enumerate(bs):
        for m in range(b.shape[0]):
            u = phi[:, g, None] * b[m][None, :]
            v = psi[:, g, None] * np.conj(b[m])[None, :]
            cols += [u + v, 1j * (u - v)]
    eye = np.eye(n_in)
    cols += [np.broadcast_to(eye[j], (s.size, n_in)) + 0j for j in range(n_in)]
    basis = np.stack(cols, axis=-1)  # (K, n_in, n_unknowns)
    n_c = len(cols) - n_in
    cs, d = [], np.zeros((target.shape[1], n_in))
    for o in range(target.shape[1]):
        a = (basis * rw[:, o, :, None]).reshape(-1, basis.shape[-1])
        y = (target[:, o, :] * rw[:, o, :]).reshape(-1)
        x = lstsq_normal(np.concatenate([a.real, a.imag]), np.concatenate([y.real, y.imag]))
        cs.append(x[:n_c:2] + 1j * x[1:n_c:2])
        d[o] = x[n_c:]
    cs = np.array(cs)  # (n_out, sum k)
    splits = np.cumsum([b.shape[0] for b in bs])[:-1]
    return np.split(cs, splits, axis=1), d


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
        Same poles and ranks, refined residues and ``D``.
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
    t_in, rw_in = np.transpose(target, (0, 2, 1)), np.transpose(rw, (0, 2, 1))
    for _ in range(int(sweeps)):
        cs, d = _solve_outputs(s, target, rw, poles, bs)
        bts, _ = _solve_outputs(s, t_in, rw_in, poles, [c.T for c in cs])
        bs = [b.T for b in bts]
    cs, d = _solve_outputs(s, target, rw, poles, bs)
    residues = np.array(fit.residues)
    for g, c, b in zip(cplx, cs, bs):
        residues[g] = c @ b
    return replace(fit, residues=residues, d=d)
