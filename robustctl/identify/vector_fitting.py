"""Pole identification by relaxed vector fitting with pole flipping (Gustavsen & Semlyen 1999,
Gustavsen 2006 relaxation, Deschrijver et al. 2008 fast QR formulation).

Each iteration fits ``sigma(s) g(s) ~ p(s)`` linearly for every channel, where ``sigma`` and
``p`` are partial-fraction expansions over the current poles, ``sigma`` sharing the poles and
its coefficients across all channels (one common denominator). The channel unknowns are
eliminated by a QR factorisation per channel, so the cost grows linearly with the number of
channels. The zeros of ``sigma`` are the new poles; unstable ones are reflected.
"""

from __future__ import annotations

import numpy as np

from .poles import BestPoles, partial_fraction_basis, pole_change, reflect_unstable, split_poles

__all__ = ["initial_poles", "vf_poles"]

#: relaxation: below this |d_sigma| the constant of sigma is fixed (Gustavsen 2006, sec. III).
D_SIGMA_TOL = 1e-8


def initial_poles(order: int, w_lo: float, w_hi: float, spacing: str = "lin") -> np.ndarray:
    """Starting poles: complex pairs ``-w/100 + j w`` spread over ``[w_lo, w_hi]`` (rad/s), plus
    one real pole at ``-(w_lo + w_hi)/2`` when ``order`` is odd (Gustavsen & Semlyen 1999)."""
    n_pairs = order // 2
    if spacing == "log" and w_lo > 0:
        w = np.geomspace(w_lo, w_hi, max(n_pairs, 1))[:n_pairs]
    else:
        w = np.linspace(w_lo, w_hi, max(n_pairs, 1))[:n_pairs]
    poles = list(-w / 100.0 + 1j * w)
    if order % 2:
        poles.append(-0.5 * (w_lo + w_hi) + 0j)
    return np.array(poles, dtype=complex)


def _sigma_realisation(poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real (A, b) of the partial-fraction basis: column coefficients c give c^T (sI-A)^{-1} b."""
    n = int(np.sum(np.where(poles.imag != 0, 2, 1)))
    a = np.zeros((n, n))
    b = np.zeros(n)
    k = 0
    for p in poles:
        if p.imag == 0:
            a[k, k], b[k] = p.real, 1.0
            k += 1
        else:
            # basis pair (1/(s-p)+1/(s-p*), j/(s-p)-j/(s-p*)) = (2,0)-scaled rotation block
            a[k : k + 2, k : k + 2] = [[p.real, p.imag], [-p.imag, p.real]]
            b[k : k + 2] = [2.0, 0.0]
            k += 2
    return a, b


def _channel_blocks(phi: np.ndarray, g: np.ndarray, rw: np.ndarray) -> list[np.ndarray]:
    """R22 blocks of the QR of each channel's [rw*phi, rw, -rw*g*phi, -rw*g] (real-stacked)."""
    k, n = phi.shape
    base = np.hstack([phi, np.ones((k, 1))])
    blocks = []
    for gc, wc in zip(g.T, rw.T):
        m = np.hstack([base * wc[:, None], -base * (gc * wc)[:, None]])
        m = np.concatenate([m.real, m.imag], axis=0)
        r = np.linalg.qr(m, mode="r")
        blocks.append(r[n + 1 :, n + 1 :])
    return blocks


def _solve_sigma(blocks: list[np.ndarray], phi: np.ndarray, scale: float) -> np.ndarray:
    """Relaxed sigma coefficients [c; d] from the stacked R22 blocks and the constraint
    ``Re sum_k sigma(s_k) = K`` (weighted by ``scale``)."""
    k, n = phi.shape
    con = np.concatenate([np.sum(phi, axis=0).real, [k]]) * scale
    a = np.vstack(blocks + [con[None, :]])
    rhs = np.zeros(a.shape[0])
    rhs[-1] = k * scale
    x = np.linalg.lstsq(a, rhs, rcond=None)[0]
    if abs(x[-1]) < D_SIGMA_TOL:  # relaxation degenerate: fix d_sigma and solve for c
        d = D_SIGMA_TOL * (1.0 if x[-1] >= 0 else -1.0)
        stacked = np.vstack(blocks)
        c = np.linalg.lstsq(stacked[:, :n], -stacked[:, n] * d, rcond=None)[0]
        x = np.concatenate([c, [d]])
    return x


def vf_step(
    s: np.ndarray, g: np.ndarray, rw: np.ndarray, poles: np.ndarray, stable: bool = True
) -> np.ndarray:
    """One relaxed VF pole relocation. ``g`` and ``rw`` have shape (K, n_channels)."""
    phi = partial_fraction_basis(s, poles)
    blocks = _channel_blocks(phi, g, rw)
    scale = np.sqrt(np.sum(np.abs(rw * g) ** 2)) / s.size
    x = _solve_sigma(blocks, phi, scale)
    a, b = _sigma_realisation(poles)
    zeros = np.linalg.eigvals(a - np.outer(b, x[:-1]) / x[-1])
    new = split_poles(zeros)
    return reflect_unstable(new)[0] if stable else new


def vf_poles(
    s: np.ndarray,
    g: np.ndarray,
    rw: np.ndarray,
    order: int,
    max_iter: int = 20,
    tol: float = 1e-8,
    stable: bool = True,
    spacing: str = "lin",
) -> tuple[np.ndarray, int, bool]:
    """Common poles of all channels by relaxed, fast vector fitting.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable ``j w`` scaled so that the band top is ``1j``.
    g : ndarray, complex, shape (K, n_channels)
        Data.
    rw : ndarray, shape (K, n_channels)
        Row weights (multiplying each complex residual).
    order : int
        Number of poles.
    max_iter : int
        Iteration cap.
    tol : float
        Stop when the largest relative pole change falls below ``tol``, or when the weighted
        cost of the best poles has not improved for a few steps (:class:`BestPoles`; noisy
        data with spare poles make the iteration wander): the best poles seen are returned.
    stable : bool
        Reflect unstable poles after every relocation (pole flipping).
    spacing : {"lin", "log"}
        Spacing of the starting poles over the band.

    Returns
    -------
    poles, iterations, converged
    """
    w = np.abs(s)
    poles = initial_poles(order, float(w.min()), float(w.max()), spacing)
    best = BestPoles(s, g, rw)
    for it in range(1, max_iter + 1):
        new = vf_step(s, g, rw, poles, stable)
        change = pole_change(poles, new)
        poles = new
        stalled = best.update(poles)
        if change < tol:
            return poles, it, True
        if stalled:
            return best.best, it, True
    return best.best, max_iter, False
