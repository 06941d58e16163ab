"""Pole identification by the Chebyshev-polynomial Sanathanan-Koerner iteration of the Caltech
paper (Balas & Doyle, eq. 4 and the six-step algorithm; Dailey & Lukich 1987; Adcock 1987).

The model is ``g(s) = n(s)/d(s)`` with real polynomials written in the basis

    P_m(s) = j^m T_m(-j s / w_s),   so that   P_m(j w) = j^m T_m(w / w_s),

where ``T_m`` is the Chebyshev polynomial and ``w_s`` the top of the band: the band (and its
mirror image, the negative frequencies of a real system) maps onto the scaled imaginary axis
``[-1, 1]`` where the ``T_m`` are bounded by 1 and well conditioned. ``P_m`` has real
coefficients in ``s`` because ``T_m`` has the parity of ``m``.

Each iteration (steps 2-5) solves the linearised problem ``min ||A x||, |x| = 1`` whose rows are
``r_k (g_k d(s_k) - n(s_k))`` split into real and imaginary parts, with
``r_k = sqrt(w_k) / |g_k d_prev(s_k)|`` (constant relative accuracy, SK re-weighting). The
numerators of all channels share ``d`` (the SIMO/MIMO extension); they are eliminated per
channel by a QR factorisation, leaving a small problem in the denominator coefficients.
"""

from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as cheb

from .poles import BestPoles, pole_change, reflect_unstable, split_poles

__all__ = ["chebyshev_basis", "chebyshev_roots", "chebyshev_poles"]

#: SK steps without cost progress before stopping (SK creeps through plateaus)
PATIENCE = 25


def chebyshev_basis(x: np.ndarray, degree: int) -> np.ndarray:
    """``P_m(j w) = j^m T_m(x)`` for ``m = 0..degree`` at ``x = w / w_s``; shape (K, degree+1)."""
    t = cheb.chebvander(np.asarray(x, dtype=float), degree)
    return t * (1j ** np.arange(degree + 1))


def chebyshev_roots(coef: np.ndarray) -> np.ndarray:
    """Roots in the scaled ``s`` variable (``s / w_s``) of ``sum_m coef_m P_m(s)`` (step 6).

    With ``x = -j s / w_s`` the polynomial is ``sum_m (coef_m j^m) T_m(x)``; its roots come from
    the colleague matrix (numpy ``chebroots``) and map back by ``s / w_s = j x``.
    """
    c = np.asarray(coef, dtype=float)
    nz = np.flatnonzero(np.abs(c) > 1e-14 * np.max(np.abs(c)))
    c = c[: nz[-1] + 1]
    if c.size < 2:
        return np.zeros(0, dtype=complex)
    x = cheb.chebroots(c * (1j ** np.arange(c.size)))
    return 1j * x


def _denominator_blocks(basis: np.ndarray, g: np.ndarray, rw: np.ndarray, n_num: int) -> list[np.ndarray]:
    """R22 blocks (denominator part) of each channel's QR of ``[rw P_num, -rw g P_den]``."""
    blocks = []
    num = basis[:, :n_num]
    for gc, wc in zip(g.T, rw.T):
        m = np.hstack([num * wc[:, None], -basis * (gc * wc)[:, None]])
        m = np.concatenate([m.real, m.imag], axis=0)
        r = np.linalg.qr(m, mode="r")
        blocks.append(r[n_num:, n_num:])
    return blocks


def _sk_step(basis: np.ndarray, g: np.ndarray, rw: np.ndarray, n_num: int) -> np.ndarray:
    """Steps 2-3: denominator coefficients minimising ``x^T A x`` with ``|d| = 1``."""
    stacked = np.vstack(_denominator_blocks(basis, g, rw, n_num))
    return np.linalg.svd(stacked, full_matrices=False)[2][-1]


def chebyshev_poles(
    s: np.ndarray,
    g: np.ndarray,
    rw: np.ndarray,
    order: int,
    max_iter: int = 20,
    tol: float = 1e-8,
    stable: bool = True,
) -> tuple[np.ndarray, int, bool]:
    """Common poles by the Chebyshev/SK iteration (Caltech steps 1-6).

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable ``j w`` scaled so that the band top is ``1j``.
    g : ndarray, complex, shape (K, n_channels)
        Data.
    rw : ndarray, shape (K, n_channels)
        Row weights ``sqrt(w)/|g|`` (per-frequency weight times relative normalisation).
    order : int
        Denominator degree (number of poles); the numerators have the same degree (proper).
    max_iter : int
        Iteration cap (step 5 loop).
    tol : float
        Stop when the largest relative pole change falls below ``tol``, or when the weighted
        cost of the best poles has not improved for a few steps (:class:`BestPoles`; noisy
        data with spare poles make the iteration wander): the best poles seen are returned.
    stable : bool
        Reflect unstable roots into the left half plane.

    Returns
    -------
    poles (scaled, stable, one per conjugate pair), iterations, converged
    """
    x = s.imag
    basis = chebyshev_basis(x, order)
    d_eval = np.ones(s.size)
    poles = None
    best = BestPoles(s, g, rw, patience=PATIENCE)
    for it in range(1, max_iter + 1):
        coef = _sk_step(basis, g, rw / d_eval[:, None], order + 1)
        d = basis @ coef
        d_eval = np.abs(d) / np.sqrt(np.mean(np.abs(d) ** 2))
        d_eval = np.maximum(d_eval, 1e-12)
        new = split_poles(chebyshev_roots(coef))
        new = reflect_unstable(new)[0] if stable else new
        change = pole_change(poles, new)
        poles = new
        stalled = best.update(poles)
        if change < tol:
            return poles, it, True
        if stalled:
            return best.best, it, True
    return best.best, max_iter, False
