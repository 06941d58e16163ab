"""Pole identification by relaxed vector fitting with pole flipping (Gustavsen & Semlyen 1999,
Gustavsen 2006 relaxation, Deschrijver et al. 2008 fast QR formulation).

Each iteration fits ``sigma(s) g(s) ~ p(s)`` linearly for every channel, where ``sigma`` and
``p`` are partial-fraction expansions over the current poles, ``sigma`` sharing the poles and
its coefficients across all channels (one common denominator). The channel unknowns are
eliminated per channel (a Schur complement of its normal equations; a QR factorisation in the
last, accurate steps), so the cost grows linearly with the number of channels. The channel
Gram matrices come from first moments of the partial fractions (:func:`.poles.basis_gram`), so
a step costs O(K n) per channel for the data and O(n^3) for the elimination, not O(K n^2).
The zeros of ``sigma`` are the new poles; unstable ones are reflected. With ``spacing="data"``
the iteration starts twice, from poles where the data change and from the linear spread.
"""

from __future__ import annotations

import numpy as np

from ..budget import Deadline
from .poles import (
    BestPoles,
    GramWeights,
    basis_gram,
    first_lowest,
    partial_fraction_basis,
    pole_change,
    reflect_unstable,
    split_poles,
)

__all__ = ["initial_poles", "data_poles", "vf_poles"]

#: relaxation: below this |d_sigma| the constant of sigma is fixed (Gustavsen 2006, sec. III).
D_SIGMA_TOL = 1e-8
#: relocations use the fast Gram elimination while poles still move by more than this (relative)
GRAM_UNTIL = 1e-6


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


#: share of the starting poles spread linearly over the band by :func:`data_poles` (the rest
#: follow the data's features)
LINEAR_SHARE = 0.25


def data_poles(s: np.ndarray, g: np.ndarray, order: int) -> np.ndarray:
    """Starting poles placed where the data change: complex pairs ``-w/100 + j w`` at equal steps
    of the feature coordinate ``x(w) = (1 - a) F(w)/F(w_hi) + a (w - w_lo)/(w_hi - w_lo)``, with
    ``F`` the cumulative channel mean of ``|log(g_{k+1}/g_k)|`` (each mode adds about pi of phase
    and its rise and fall in log magnitude) and ``a = LINEAR_SHARE``; plus one real pole at the
    band centre for an odd ``order``. Dense modes at one end of a wide band (log-spaced low
    modes, a cluster) get dense starting poles, which linearly spaced ones (Gustavsen & Semlyen
    1999) leave to many more relocations or miss.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable ``j w``, increasing ``w``.
    g : ndarray, complex, shape (K, n_channels)
        Data.
    order : int
        Number of poles.
    """
    w = np.abs(s)
    mag = np.maximum(np.abs(g), 1e-300)
    step = np.abs(np.log(mag[1:] / mag[:-1]) + 1j * np.angle(g[1:] * np.conj(g[:-1])))
    feature = np.concatenate([[0.0], np.cumsum(np.mean(step, axis=1))])
    span = max(float(w[-1] - w[0]), 1e-300)
    share = LINEAR_SHARE if feature[-1] > 0 else 1.0  # flat data: the linear spread
    x = share * (w - w[0]) / span + (1 - share) * feature / max(float(feature[-1]), 1e-300)
    n_pairs = order // 2
    wk = np.interp((np.arange(n_pairs) + 0.5) / max(n_pairs, 1), x, w)
    poles = list(-wk / 100.0 + 1j * wk)
    if order % 2:
        poles.append(-0.5 * (w[0] + w[-1]) + 0j)
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


def _channel_blocks(phi: np.ndarray, g: np.ndarray, rw: np.ndarray) -> tuple[list[np.ndarray], float]:
    """QR path: R22 blocks of each channel's ``[rw B, -rw g, -rw g Phi]`` (real-stacked, ``B = [Phi, 1]``)
    with sigma unknowns ordered ``[d, c]``, and the weighted cost of the current poles (the squared
    ``R[m, m]`` entries: the part of ``rw g`` the current basis cannot fit)."""
    k, n = phi.shape
    base = np.hstack([phi, np.ones((k, 1))])
    blocks, cost = [], 0.0
    for gc, wc in zip(g.T, rw.T):
        m = np.hstack([base * wc[:, None], -(gc * wc)[:, None], -phi * (gc * wc)[:, None]])
        m = np.concatenate([m.real, m.imag], axis=0)
        r = np.linalg.qr(m, mode="r")
        blocks.append(r[n + 1 :, n + 1 :])
        cost += r[n + 1, n + 1] ** 2
    return blocks, float(cost)


def _gram_normal(
    s: np.ndarray, poles: np.ndarray, g: np.ndarray, rw: np.ndarray, blocks: np.ndarray | None = None
) -> tuple[np.ndarray, float] | None:
    """Gram path: ``sum_c S_c`` with ``S_c`` the Schur complement of the sigma unknowns ``[d, c]`` in
    ``Re(M_c^H M_c)``. Every channel block is ``Re(B^H diag(v) B)`` for a per-channel weight vector
    ``v`` (``rw^2``, ``rw^2 g``, ``rw^2 |g|^2``), formed from first moments of the partial
    fractions (:func:`.poles.basis_gram`, O(K n) per channel). The channel eliminations
    ``Y_c = L_c^{-1} G12_c`` are stacked so that ``sum_c Y_c^T Y_c`` is one matrix product, and the
    sigma unknowns stay in ``B``'s order ``[c, d]`` until the summed matrix is permuted (the sign
    of ``G12`` cancels in ``Y^T Y``). Returns None when a Cholesky factorisation fails
    (ill-conditioned basis); the caller then takes the QR path. ``blocks``: those Gram matrices
    (:func:`_gram_weights`) when already formed; their first two thirds are scaled in place."""
    n = int(np.sum(np.where(poles.imag != 0, 2, 1)))
    n_ch = g.shape[1]
    if blocks is None:
        blocks = basis_gram(s, poles, _gram_weights(g, rw))
    g11, g12, g22 = blocks.reshape(3, n_ch, n + 1, n + 1)
    scale = 1.0 / np.sqrt(np.einsum("cii->ci", g11))
    g11 *= scale[:, :, None]
    g11 *= scale[:, None, :]
    try:
        chol = np.linalg.cholesky(g11)
    except np.linalg.LinAlgError:
        return None
    g12 *= scale[:, :, None]
    y = np.linalg.solve(chol, g12).reshape(n_ch * (n + 1), n + 1)
    total = g22.sum(axis=0) - y.T @ y
    cost = float(np.sum(g22[:, n, n]) - np.sum(y[:, n] ** 2))
    perm = np.r_[n, :n]  # sigma unknowns [c, d] -> [d, c]
    return total[perm][:, perm], cost


def _gram_weights(g: np.ndarray, rw: np.ndarray) -> np.ndarray:
    """The weight columns ``[rw^2, rw^2 g, rw^2 |g|^2]`` of :func:`_gram_normal`'s Gram blocks."""
    w2 = rw**2
    return np.hstack([w2, w2 * g, w2 * np.abs(g) ** 2])


class StepWeights:
    """What every relocation of a vector fit on the data ``g``, ``rw`` (shape (K, n_channels))
    uses unchanged: the Gram weight columns (:func:`_gram_weights`, prepared by
    :class:`.poles.GramWeights`) and the scale of the relaxation row (the weighted data norm over
    ``K``). Formed once per fit (or per order scan) instead of once per relocation."""

    def __init__(self, g: np.ndarray, rw: np.ndarray):
        self.gram = GramWeights(_gram_weights(g, rw), reuse=True)  # vf_step is done with its blocks
        self.scale = np.sqrt(np.sum(np.abs(rw * g) ** 2)) / g.shape[0]


def _constraint(phi: np.ndarray, scale: float) -> np.ndarray:
    """Relaxation row ``Re sum_k sigma(s_k) = K`` for unknowns ``[d, c]``, weighted by ``scale``."""
    return np.concatenate([[phi.shape[0]], np.sum(phi, axis=0).real]) * scale


def _fix_small_d(x: np.ndarray, solve_c) -> np.ndarray:
    if abs(x[0]) >= D_SIGMA_TOL:
        return x
    d = D_SIGMA_TOL * (1.0 if x[0] >= 0 else -1.0)  # relaxation degenerate: fix d_sigma, solve for c
    return np.concatenate([[d], solve_c(d)])


def _solve_sigma_qr(blocks: list[np.ndarray], con: np.ndarray, target: float) -> np.ndarray:
    a = np.vstack(blocks + [con[None, :]])
    rhs = np.zeros(a.shape[0])
    rhs[-1] = target
    x = np.linalg.lstsq(a, rhs, rcond=None)[0]
    stacked = a[:-1]
    return _fix_small_d(x, lambda d: np.linalg.lstsq(stacked[:, 1:], -stacked[:, 0] * d, rcond=None)[0])


def _solve_sigma_gram(normal: np.ndarray, con: np.ndarray, target: float) -> np.ndarray:
    x = np.linalg.solve(normal + np.outer(con, con), con * target)
    return _fix_small_d(x, lambda d: np.linalg.solve(normal[1:, 1:], -normal[1:, 0] * d))


def vf_step(
    s: np.ndarray,
    g: np.ndarray,
    rw: np.ndarray,
    poles: np.ndarray,
    stable: bool = True,
    gram: bool = False,
    weights: StepWeights | None = None,
) -> tuple[np.ndarray, float]:
    """One relaxed VF pole relocation; ``g`` and ``rw`` have shape (K, n_channels).

    Returns the new poles and the weighted cost ``sum |rw (g - G)|^2`` of the *current* poles'
    least-squares fit. ``gram=True`` forms the channel eliminations from one Gram product (several
    times faster, accurate to about sqrt(eps) in the poles); the default QR path is accurate to eps.
    ``weights``: :class:`StepWeights` of these ``g``, ``rw`` when already formed.
    """
    if weights is None:
        weights = StepWeights(g, rw)
    normal = None
    if gram:  # the basis for the constraint from the Gram blocks' atoms (one set of divisions)
        blocks, phi = basis_gram(s, poles, weights.gram, with_basis=True)
        normal = _gram_normal(s, poles, g, rw, blocks)
    else:
        phi = partial_fraction_basis(s, poles)
    scale = weights.scale
    con = _constraint(phi, scale)
    x = None
    if normal is not None:
        try:
            x, cost = _solve_sigma_gram(normal[0], con, s.size * scale), normal[1]
        except np.linalg.LinAlgError:  # singular normal equations (spare poles on exact data): QR path
            x = None
    if x is None:
        blocks, cost = _channel_blocks(phi, g, rw)
        x = _solve_sigma_qr(blocks, con, s.size * scale)
    a, b = _sigma_realisation(poles)
    zeros = np.linalg.eigvals(a - np.outer(b, x[1:]) / x[0])
    new = split_poles(zeros)
    return (reflect_unstable(new)[0] if stable else new), cost


def vf_poles(
    s: np.ndarray,
    g: np.ndarray,
    rw: np.ndarray,
    order: int,
    max_iter: int = 20,
    tol: float = 1e-8,
    stable: bool = True,
    spacing: str = "lin",
    start: np.ndarray | None = None,
    deadline: Deadline | None = None,
    weights: StepWeights | None = None,
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
    spacing : {"data", "lin", "log"}
        Starting poles over the band: ``"data"`` runs the iteration twice, from poles
        where the data change (:func:`data_poles`) and from the linear spread, and keeps the
        poles of lower weighted cost (the two starts win on different data: log-spaced dense
        low modes need the first, some measured FRFs end in a better fixed point from the
        second); ``"lin"`` (default) or ``"log"``: one run from :func:`initial_poles`.
    start : ndarray, complex, optional
        Starting poles (scaled like ``s``; one per conjugate pair), e.g. the previous order's
        poles plus new ones, instead of the spread of :func:`initial_poles`.
    deadline : Deadline, optional
        Opt-in time budget (:class:`robustctl.budget.Deadline`): once it has expired the best
        poles so far are returned (``converged`` False).
    weights : StepWeights, optional
        :class:`StepWeights` of these ``g``, ``rw`` when already formed (an order scan forms them
        once for all its orders).

    Returns
    -------
    poles, iterations, converged
    """
    w = np.abs(s)
    weights = StepWeights(g, rw) if weights is None else weights
    if start is not None:
        return _relocate(s, g, rw, start, max_iter, tol, stable, deadline, weights)[:3]
    if spacing != "data":
        poles = initial_poles(order, float(w.min()), float(w.max()), spacing)
        return _relocate(s, g, rw, poles, max_iter, tol, stable, deadline, weights)[:3]
    # two starts, the lower weighted cost wins: where the data change, and the linear spread
    runs = [_relocate(s, g, rw, data_poles(s, g, order), max_iter, tol, stable, deadline, weights)]
    if deadline is None or not deadline.expired():
        lin = initial_poles(order, float(w.min()), float(w.max()), "lin")
        runs.append(_relocate(s, g, rw, lin, max_iter, tol, stable, deadline, weights))
    return runs[first_lowest([run[3] for run in runs])][:3]


def _relocate(
    s: np.ndarray,
    g: np.ndarray,
    rw: np.ndarray,
    poles: np.ndarray,
    max_iter: int,
    tol: float,
    stable: bool,
    deadline: Deadline | None,
    weights: StepWeights | None = None,
) -> tuple[np.ndarray, int, bool, float]:
    """The VF iteration of :func:`vf_poles` from ``poles``: (poles, iterations, converged, cost),
    ``cost`` the weighted cost of the best poles seen (the returned ones up to the last step)."""
    weights = StepWeights(g, rw) if weights is None else weights
    best = BestPoles(s, g, rw)
    change = np.inf
    for it in range(1, max_iter + 1):
        if deadline is not None and it > 1 and deadline.expired():
            return best.best, it - 1, False, best.best_cost
        new, cost = vf_step(s, g, rw, poles, stable, gram=change > GRAM_UNTIL, weights=weights)
        stalled = best.record(poles, cost)
        change = pole_change(poles, new)
        poles = new
        if change < tol:
            return poles, it, True, best.best_cost
        if stalled:
            return best.best, it, True, best.best_cost
    return best.best, max_iter, False, best.best_cost
