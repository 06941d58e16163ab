"""The smoothed largest eigenvalue of the scaled mu LMI and its exact derivatives.

With ``A = D_L M D_R^{-1}`` and ``G^`` the scaled G-scales, the upper bound of mu is
``beta^2 = lambda_max(H)``, ``H = A^H A + j (G^ A - A^H G^^H)`` (Fan, Tits & Doyle 1991,
Thm 2.1, in scaled coordinates). ``lambda_max`` is not smooth where it is multiple (which
the optimum usually is), so it is replaced by

    F_tau(H) = tau log tr exp(H / tau),   lambda_max <= F_tau <= lambda_max + tau log n,

whose gradient is ``tr(W dH)`` with ``W = Q diag(w) Q^H`` (``w`` the softmax weights of the
eigenvalues) and whose Hessian follows from the Daleckii-Krein formula for spectral
functions (Lewis & Sendov 2001, "Twice differentiable spectral functions", SIAM J. Matrix
Anal. Appl. 23(2)): ``sum_kl Gamma_kl Re(Hh_a[k,l] Hh_b[l,k]) - g_a g_b / tau +
tr(W d2H_ab)`` with ``Gamma_kl = (w_k - w_l) / (lambda_k - lambda_l)`` (``w_k / tau`` on
ties) and ``Hh_a = Q^H dH_a Q``. The parameters are the coefficients of the generators in
:class:`robustctl.robust.mu.layout.Layout`: ``A(theta) = exp(E_L) A exp(-E_R)``,
``G^(theta) = G^ + dG``.
"""

from __future__ import annotations

import numpy as np

from .layout import Layout

__all__ = ["derivatives", "herm", "hmatrix", "smoothed"]


def herm(X: np.ndarray) -> np.ndarray:
    return np.swapaxes(X, -1, -2).conj()


def hmatrix(A: np.ndarray, G: np.ndarray | None) -> np.ndarray:
    """``H = A^H A + j (G A - A^H G^H)`` (the LMI in scaled coordinates)."""
    H = herm(A) @ A
    if G is not None:
        X = 1j * (G @ A)
        H = H + X + herm(X)
    return H


def smoothed(lam: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``F_tau = lambda_max + tau log sum exp((lambda - lambda_max)/tau)`` and softmax weights."""
    e = np.exp((lam - lam[:, -1:]) / tau[:, None])
    z = e.sum(axis=1)
    return lam[:, -1] + tau * np.log(z), e / z[:, None]


def _flat(X: np.ndarray) -> np.ndarray:
    """(..., k, n, m) -> (..., k, n*m)."""
    return X.reshape(X.shape[:-2] + (-1,))


def _pair_trace(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``out[f, a, b] = tr(X[f, a] Y[f, b])`` for stacks of matrices (batched matmul)."""
    return _flat(X) @ np.swapaxes(_flat(np.swapaxes(Y, -1, -2)), -1, -2)


def _diagonal_terms(A, Bm, Q, lay: Layout):
    """Fast path for block-identity generators (every D parameter scales one block).

    ``A_a = (l_a 1^T - 1 r_a^T) o A`` elementwise (``l_a``, ``r_a`` the block's 0/1 row and
    column masks), and ``Q^H Bm A_a Q = (Q^H Bm)[:, out_a] (A Q)[out_a, :] -
    (Q^H Bm A)[:, in_a] Q[in_a, :]``: two thin products per parameter.
    """
    l, r = lay.diagonal
    Ad = (l[:, :, None] - r[:, None, :])[None] * A[:, None]
    Pm = herm(Q) @ Bm
    AQ, PmA = A @ Q, Pm @ A
    Xq = np.empty((A.shape[0], lay.n_d, lay.n_in, lay.n_in), complex)
    for a, (o, i) in enumerate(lay.param_slices):
        Xq[:, a] = Pm[:, :, o] @ AQ[:, o, :] - PmA[:, :, i] @ Q[:, i, :]

    def cross_of(Y):
        return l @ (A * np.swapaxes(Y, 1, 2)) @ r.T

    return Ad, Xq, cross_of


def derivatives(A, G, lam, Q, w, tau, lay: Layout):
    """Gradient (na, k) and Hessian (na, k, k) of ``F_tau`` in the local coordinates.

    First derivatives of the eigenvalues and the Daleckii-Krein second derivative of the
    spectral function ``F_tau`` (Lewis & Sendov 2001), plus the curvature of ``H`` itself
    along the generators (``A(theta) = exp(E_L) A exp(-E_R)``, ``G^(theta) = G^ + dG``).
    """
    nd = lay.n_d
    Bm = herm(A) if G is None else herm(A) + 1j * G
    Ad = Xq = cross_of = None
    if nd and lay.diagonal is not None:
        Ad, Xq, cross_of = _diagonal_terms(A, Bm, Q, lay)
    elif nd:
        LA = lay.gen_left[None] @ A[:, None]
        Ad = LA - A[:, None] @ lay.gen_right[None]
        Xq = herm(Q)[:, None] @ (Bm[:, None] @ Ad) @ Q[:, None]

        def cross_of(Y):
            return _pair_trace(LA, lay.gen_right[None] @ Y[:, None])
    if lay.n_g:
        Xg = herm(Q)[:, None] @ (1j * (lay.gen_g[None] @ A[:, None])) @ Q[:, None]
        Xq = Xg if Xq is None else np.concatenate([Xq, Xg], axis=1)
    Hh = Xq + herm(Xq)
    g = (np.diagonal(Hh, axis1=2, axis2=3).real * w[:, None, :]).sum(axis=2)
    dl = lam[:, :, None] - lam[:, None, :]
    small = np.abs(dl) < 1e-7 * tau[:, None, None]
    gam = np.where(small, (w[:, :, None] + w[:, None, :]) / (2 * tau[:, None, None]),
                   (w[:, :, None] - w[:, None, :]) / np.where(small, 1.0, dl))
    hess = (_flat(Hh * gam[:, None]) @ np.swapaxes(_flat(Hh).conj(), 1, 2)).real
    hess -= g[:, :, None] * g[:, None, :] / tau[:, None, None]
    if nd:
        _add_curvature(hess, A, Ad, Q, w, Bm, cross_of, lay)
    return g, hess


def _add_curvature(hess, A, Ad, Q, w, Bm, cross_of, lay: Layout) -> None:
    """Add ``tr(W d2H)`` (``W = Q diag(w) Q^H``) for the D-D and D-G parameter pairs."""
    nd = lay.n_d
    W = (Q * w[:, None, :]) @ herm(Q)
    AW = Ad @ W[:, None]
    dd = 2.0 * (_flat(AW) @ np.swapaxes(_flat(Ad).conj(), 1, 2)).real
    Y = W @ Bm
    PL, PR = A @ Y, Y @ A
    tll = (_flat(np.swapaxes(PL, 1, 2)) @ lay.ll_flat.T).reshape((-1, nd, nd))
    trr = (_flat(np.swapaxes(PR, 1, 2)) @ lay.rr_flat.T).reshape((-1, nd, nd))
    cross = cross_of(Y)
    t = 0.5 * (tll + np.swapaxes(tll, 1, 2) + trr + np.swapaxes(trr, 1, 2)) - cross - np.swapaxes(cross, 1, 2)
    hess[:, :nd, :nd] += dd + 2.0 * t.real
    if lay.n_g:
        dg = 2.0 * (1j * (_flat(AW) @ lay.g_flat_t)).real
        hess[:, :nd, nd:] += dg
        hess[:, nd:, :nd] += np.swapaxes(dg, 1, 2)
