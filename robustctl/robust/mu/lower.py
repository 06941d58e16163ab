"""Lower bound of the structured singular value by power iteration, batched over frequency.

Any structured ``Q`` with ``||Q_i|| <= 1`` for which ``M Q`` has an eigenvalue ``lambda``
that the structure can rotate onto the positive real axis gives ``mu(M) >= |lambda| /
max_i ||Q_i||``, with the destabilising ``Delta = Q e^{-j arg lambda} / |lambda|``
(``det(I - M Delta) = 0``, ``||Delta|| = 1 / lower``). For a purely complex structure
every eigenvalue qualifies and ``mu(M) = max_Q rho(M Q)`` (Packard & Doyle 1993, Thm 7.2);
with real blocks only real eigenvalues do (Young & Doyle 1997, IEEE TAC 42(1), Thm 1).

``Q`` is sought with the power iteration of Packard & Doyle (1993, sec. 9.2), extended to
real blocks in the spirit of Young & Doyle (1997): with ``M`` mapping ``a -> b`` and
``M^H`` mapping ``z -> w``,

    beta b = M a,     z_i = Z_i(b, w),     alpha w = M^H z,     a_i = A_i(b, w),

where for a full block ``z_i = (|w_i| / |b_i|) b_i``, ``a_i = (|b_i| / |w_i|) w_i``; for a
repeated complex scalar ``delta_i = conj(w_i^H b_i) / |w_i^H b_i|``, ``a_i = delta_i b_i``,
``z_i = conj(delta_i) w_i``; for a repeated real scalar ``delta_i = Re(w_i^H b_i) /
|w_i^H b_i|`` (in [-1, 1], +-1 when aligned). At a fixed point ``M Q b = beta b`` and the
eigenvalue conditions of a local maximum of the spectral radius hold. The iteration is
started from the upper bound's principal vectors and from a seeded random vector; the bound
is then certified exactly from the eigenvalues of ``M Q`` (so it is valid whether or not
the iteration converged).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .layout import Layout

__all__ = ["LowerBound", "lower_bound"]

#: iteration caps and relative tolerances on beta: complex structures converge quickly; with
#: real blocks the vectors must settle tightly for the eigenvalue of M Q to come out real
MAX_POWER = {"complex": 60, "mixed": 300}
POWER_TOL = {"complex": 1e-6, "mixed": 1e-11}
#: relative imaginary part below which an eigenvalue counts as real (mixed structures)
REAL_TOL = 1e-7


@dataclass(frozen=True)
class LowerBound:
    """Raw result of :func:`lower_bound`: ``lower`` (nf,), ``delta`` (nf, n_in, n_out)
    destabilising perturbations (zero where ``lower == 0``), ``iterations``."""

    lower: np.ndarray
    delta: np.ndarray
    iterations: int


class _Index:
    """Vectorised block bookkeeping: membership matrices and scalar-block pairings."""

    def __init__(self, lay: Layout):
        k = lay.n_blocks
        self.p_out = np.zeros((lay.n_out, k))
        self.p_in = np.zeros((lay.n_in, k))
        for j, (o, i) in enumerate(zip(lay.out, lay.inp)):
            self.p_out[o, j] = 1.0
            self.p_in[i, j] = 1.0
        self.blk_out = np.argmax(self.p_out, axis=1)
        self.blk_in = np.argmax(self.p_in, axis=1)
        full = np.array([kind == "full" for kind in lay.kinds])
        self.real = np.array([kind == "real" for kind in lay.kinds])
        self.full_out, self.full_in = full[self.blk_out], full[self.blk_in]
        # scalar blocks are square: the t-th input of block j pairs with its t-th output
        self.in_of_out = np.zeros(lay.n_out, int)
        self.out_of_in = np.zeros(lay.n_in, int)
        for o, i, kind in zip(lay.out, lay.inp, lay.kinds):
            if kind != "full":
                self.in_of_out[o] = np.arange(i.start, i.stop)
                self.out_of_in[i] = np.arange(o.start, o.stop)

    def norms(self, x: np.ndarray, side: str) -> np.ndarray:
        p = self.p_out if side == "out" else self.p_in
        return np.sqrt(np.abs(x) ** 2 @ p)

    def scalar_phase(self, b: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``delta_i`` of the scalar blocks, (nf, k) (1 on full blocks)."""
        c = (w[:, self.in_of_out].conj() * b) @ self.p_out
        mag = np.abs(c)
        unit = np.where(mag > 0, c.conj() / np.where(mag > 0, mag, 1.0), 1.0)
        return np.where(self.real, unit.real, unit)


def _step(M, MH, a, w, ix: _Index):
    """One sweep of the power iteration; returns (a, w, beta, b, delta)."""
    b = (M @ a[:, :, None])[:, :, 0]
    beta = np.linalg.norm(b, axis=1)
    b = b / np.where(beta > 0, beta, 1.0)[:, None]
    nb, nw = ix.norms(b, "out"), ix.norms(w, "in")
    ratio = nw / np.where(nb > 0, nb, 1.0)
    delta = ix.scalar_phase(b, w)
    z = np.where(ix.full_out, ratio[:, ix.blk_out] * b, delta.conj()[:, ix.blk_out] * w[:, ix.in_of_out])
    w = (MH @ z[:, :, None])[:, :, 0]
    w = w / np.maximum(np.linalg.norm(w, axis=1), 1e-300)[:, None]
    nw = ix.norms(w, "in")
    inv = nb / np.where(nw > 0, nw, 1.0)
    delta = ix.scalar_phase(b, w)
    a = np.where(ix.full_in, inv[:, ix.blk_in] * w, delta[:, ix.blk_in] * b[:, ix.out_of_in])
    a = a / np.maximum(np.linalg.norm(a, axis=1), 1e-300)[:, None]
    return a, w, beta, b, delta


def _structured_q(b, w, delta, ix: _Index, lay: Layout, vertex: bool) -> tuple[np.ndarray, np.ndarray]:
    """``Q`` (nf, n_in, n_out) with ``||Q_i|| <= 1`` from the iteration's vectors, and ``max_i ||Q_i||``."""
    nf = b.shape[0]
    Q = np.zeros((nf, lay.n_in, lay.n_out), complex)
    qn = np.zeros(nf)
    nb, nw = ix.norms(b, "out"), ix.norms(w, "in")
    for j, (o, i, kind) in enumerate(zip(lay.out, lay.inp, lay.kinds)):
        if kind == "full":  # rank one w_i b_i^H / (|w_i| |b_i|): norm 1 (0 if a vector vanishes)
            prod = nw[:, j] * nb[:, j]
            ok = prod > 0
            Q[:, i, o] = w[:, i, None] * b[:, o].conj()[:, None, :] / np.where(ok, prod, 1.0)[:, None, None]
            qn = np.maximum(qn, ok.astype(float))
        else:
            d = delta[:, j]
            if vertex and kind == "real":
                d = np.where(d.real >= 0, 1.0, -1.0)
            Q[:, i, o] = d[:, None, None] * np.eye(i.stop - i.start)
            qn = np.maximum(qn, np.abs(d))
    return Q, qn


def _rayleigh(MQ: np.ndarray, x: np.ndarray, steps: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Rayleigh-quotient iteration on ``M Q`` from ``x``: eigenvalue estimates and relative residuals."""
    n = MQ.shape[1]
    x = x / np.maximum(np.linalg.norm(x, axis=1), 1e-300)[:, None]
    lam = np.einsum("fi,fij,fj->f", x.conj(), MQ, x)
    eye = np.eye(n)
    for _ in range(steps):
        shift = lam * (1 + 1e-13) + 1e-300  # never exactly singular
        try:
            y = np.linalg.solve(MQ - shift[:, None, None] * eye, x[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            break
        x = y / np.maximum(np.linalg.norm(y, axis=1), 1e-300)[:, None]
        lam = np.einsum("fi,fij,fj->f", x.conj(), MQ, x)
    res = np.linalg.norm((MQ @ x[:, :, None])[:, :, 0] - lam[:, None] * x, axis=1)
    return lam, res / np.maximum(np.linalg.norm(MQ, axis=(1, 2)), 1e-300)


def _admissible(lam: np.ndarray, scale: np.ndarray, lay: Layout) -> np.ndarray:
    """``|lambda|`` where the structure can rotate ``lambda`` onto the positive axis, else 0."""
    mag = np.abs(lam)
    mag = np.where(mag > 1e-10 * scale, mag, 0.0)  # not roundoff
    if lay.has_real:
        mag = np.where(np.abs(lam.imag) <= REAL_TOL * np.maximum(mag, 1e-300), mag, 0.0)
    return mag


def _certify(M, Q, qn, b, beta, lay: Layout):
    """An admissible eigenvalue of ``M Q``: the lower bound and its ``Delta``.

    The eigenvalue near the power iteration's ``beta`` is refined by Rayleigh-quotient
    iteration from its vector ``b``; where that fails (residual, admissibility, or it lands
    on a smaller eigenvalue) all eigenvalues are computed and the best admissible one taken.
    """
    MQ = M @ Q
    scale = np.linalg.norm(MQ, axis=(1, 2))
    lam, res = _rayleigh(MQ, b)
    best = _admissible(lam, scale, lay)
    redo = (res > 1e-12) | (best < (1 - 1e-6) * beta)
    if redo.any():
        every = np.linalg.eigvals(MQ[redo])
        mag = _admissible(every, scale[redo, None], lay)
        k = np.argmax(mag, axis=1)
        rows = np.arange(k.size)
        take = mag[rows, k] > best[redo]
        idx = np.flatnonzero(redo)[take]
        lam[idx], best[idx] = every[rows, k][take], mag[rows, k][take]
    lower = np.where(qn > 0, best / np.where(qn > 0, qn, 1.0), 0.0)
    rot = np.where(lam.real >= 0, 1.0, -1.0) if lay.has_real else np.exp(-1j * np.angle(lam))
    factor = np.where(best > 0, rot / np.where(best > 0, best, 1.0), 0.0)
    return lower, Q * factor[:, None, None]


def _power(M: np.ndarray, a: np.ndarray, w: np.ndarray, ix: _Index, lay: Layout, max_iter: int, tol: float):
    """Run the power iteration from ``(a, w)`` and certify: (lower, Delta, iterations)."""
    nf = M.shape[0]
    MH = np.swapaxes(M, 1, 2).conj()
    a = a / np.maximum(np.linalg.norm(a, axis=1), 1e-300)[:, None]
    w = w / np.maximum(np.linalg.norm(w, axis=1), 1e-300)[:, None]
    b = np.zeros((nf, lay.n_out), complex)
    delta = np.ones((nf, lay.n_blocks), complex)
    beta_old = np.zeros(nf)
    active = np.arange(nf)
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        sub = (M[active], MH[active], a[active], w[active])
        b_old = b[active]
        a[active], w[active], beta, b[active], delta[active] = _step(*sub, ix)
        moving = np.abs(beta - beta_old[active]) > tol * np.maximum(beta, 1e-300)
        if lay.has_real:  # no phase freedom: the vectors themselves must settle
            moving |= np.linalg.norm(b[active] - b_old, axis=1) > np.sqrt(tol)
        beta_old[active] = beta
        active = active[moving]
        if active.size == 0:
            break
    lower, delta_out = np.zeros(nf), np.zeros((nf, lay.n_in, lay.n_out), complex)
    for vertex in (False, True) if lay.has_real else (False,):
        lo, dl = _certify(M, *_structured_q(b, w, delta, ix, lay, vertex=vertex), b, beta_old, lay)
        better = lo > lower
        lower[better], delta_out[better] = lo[better], dl[better]
    return lower, delta_out, it


def lower_bound(M: np.ndarray, lay: Layout, a0: np.ndarray | None = None, w0: np.ndarray | None = None,
                upper: np.ndarray | None = None, *, seed: int = 0, max_iter: int | None = None,
                tol: float | None = None, index: np.ndarray | None = None) -> LowerBound:
    """Power-iteration lower bound of mu at every frequency of ``M`` (nf, n_out, n_in).

    Parameters
    ----------
    M : ndarray, complex, (nf, n_out, n_in)
    lay : Layout
    a0, w0 : ndarray, (nf, n_in), optional
        Start vectors (e.g. from the upper bound's principal directions).
    upper : ndarray (nf,), optional
        A known upper bound: a seeded random restart is run only where the first run stays
        more than 0.1 % below it (everywhere when not given, or without start vectors).
    seed : int
        Seed of the random start. Frequency ``k`` draws its own start from ``(seed, index[k])``,
        so its bound does not depend on which other frequencies share the call (how a grid is
        split into chunks for an executor).
    max_iter : int, optional
        Iteration cap (default :data:`MAX_POWER`).
    tol : float, optional
        A frequency stops iterating when ``beta`` changes by less than ``tol`` (relative;
        default :data:`POWER_TOL`).
    index : ndarray of int (nf,), optional
        The frequencies' positions in the whole grid (default ``0 .. nf-1``).
    """
    nf = M.shape[0]
    kind = "mixed" if lay.has_real else "complex"
    max_iter = MAX_POWER[kind] if max_iter is None else max_iter
    tol = POWER_TOL[kind] if tol is None else tol
    ix = _Index(lay)
    lower, delta, iters = np.zeros(nf), np.zeros((nf, lay.n_in, lay.n_out), complex), 0
    if a0 is not None and w0 is not None:
        lower, delta, iters = _power(M, a0.copy(), w0.copy(), ix, lay, max_iter, tol)
    redo = np.ones(nf, bool) if upper is None or a0 is None else lower < (1 - 1e-3) * upper
    if redo.any():
        pos = np.arange(nf) if index is None else np.asarray(index)
        rnd = np.empty((2, int(redo.sum()), lay.n_in), complex)
        for j, k in enumerate(np.flatnonzero(redo)):
            rng = np.random.default_rng([seed, int(pos[k])])
            rnd[:, j] = rng.standard_normal((2, lay.n_in)) + 1j * rng.standard_normal((2, lay.n_in))
        lo, dl, it = _power(M[redo], rnd[0], rnd[1], ix, lay, max_iter, tol)
        idx = np.flatnonzero(redo)
        better = lo > lower[idx]
        lower[idx[better]], delta[idx[better]] = lo[better], dl[better]
        iters = max(iters, it)
    return LowerBound(lower, delta, iters)
