"""Upper bound of the structured singular value with D- and G-scales, batched over frequency.

For every frequency the bound is (Fan, Tits & Doyle 1991, IEEE TAC 36(1), Thm 2.1; Young,
Newlin & Doyle 1995; Packard & Doyle 1993, eq. 8.5 for the complex case)

    mu(M) <= beta   if   M^H X_L M + j (G M - M^H G^H) - beta^2 X_R <= 0

for some ``X = D^H D > 0`` commuting with ``Delta`` and some Hermitian ``G`` on the real
blocks. With ``A = D_L M D_R^{-1}`` and ``G^ = D_R^{-H} G D_L^{-1}`` this reads
``beta^2 >= lambda_max(H)``, ``H = A^H A + j (G^ A - A^H G^^H)``; without real blocks
``beta = sigma_max(D_L M D_R^{-1})``. Every ``(D, G^)`` gives a valid bound; the best one
(the LMI optimum) is sought in two stages:

1. a balancing start for all frequencies at once: Osborne's iteration (exact coordinate
   descent on the Frobenius norm of the block-norm matrix) and the Perron scaling
   (Packard & Doyle 1993, sec. 9.1: ``d_i = sqrt(y_i / x_i)`` from the Perron vectors of the
   block-norm matrix), the better of the two per frequency;
2. an exact refinement: trust-region Newton steps on the smoothed maximum eigenvalue
   ``F_tau(H) = tau log tr exp(H / tau)`` (``lambda_max <= F_tau <= lambda_max + tau log n``,
   :mod:`robustctl.robust.mu.smooth`) in local coordinates ``D <- exp(E) D``,
   ``G^ <- G^ + dG``, with the exact gradient and Hessian from one batched
   eigendecomposition per step (the Daleckii-Krein formula for the second derivative of a
   spectral function). ``tau`` is relative to the current ``lambda_max`` (the stage restarts
   when the bound has fallen by 4x, so bounds that tend to 0 are followed). A stage ends at a
   frequency when the full Newton step's decrement ``g^T |Hess|^-1 g`` (not that of the
   step cut to the trust region) is below ``STAGE_TOL * tau``. The exact ``lambda_max`` at
   every accepted point is a valid bound; the smallest is kept.

With real blocks the optimum is often approached only as some scales tend to 0 or infinity
(the Hessian's smallest eigenvalue falls towards 0 on the way; the LMI optimum is then an
infimum), so the trust region grows after accepted steps up to ``MAX_STEP`` (progress stays
geometric instead of a fixed step per iteration) and a second, finer stage follows
(:data:`TAU_STAGES_REAL`). On a 6x6 response with blocks ``[[-1,0],[-1,0],[1,0],[3,3]]`` at
1000 frequencies the bound was up to 0.75 % above the LMI optimum with one stage, a fixed
radius of 2 and the cut step's decrement as the stopping rule, and is within 0.05 % now.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...budget import as_deadline
from .layout import Layout
from .smooth import derivatives as _derivatives
from .smooth import herm as _herm
from .smooth import hmatrix as _hmatrix
from .smooth import smoothed as _smoothed

__all__ = ["UpperBound", "upper_bound", "block_norms", "balancing_start"]

#: smoothing parameters of the Newton stages (relative to lambda_max at the stage start). At a
#: stationary point of F_tau, lambda_max exceeds its minimum by at most tau log(n) (0.36 %
#: for n = 6 and tau = 2e-3, i.e. 0.18 % in beta); measured gaps are far smaller.
TAU_STAGES = (2e-3,)
#: the stages with real blocks (module docstring): the second takes beta to within 0.2 % of the
#: LMI optimum (0.05 % on the 6x6 benchmark, 0.15 % at worst on random 4x4 mixed cases)
TAU_STAGES_REAL = (2e-3, 2e-4)
#: Newton decrement (relative to tau) that ends a stage
STAGE_TOL = 0.3
MAX_NEWTON = 150
#: first trust radius of a stage (log units) and the largest it may grow to after accepted steps
#: (steps grow where the optimum lies towards infinite scales, so progress stays geometric)
START_STEP = 2.0
MAX_STEP = 30.0


@dataclass(frozen=True)
class UpperBound:
    """Raw result of :func:`upper_bound` (arrays over frequency).

    ``upper`` (nf,); ``dblocks``: per block (nf, m, m) D-scales with ``A = D_L M D_R^{-1}``;
    ``gblocks``: per block (nf, r, r) Hermitian G-scales of the LMI (zero for complex
    blocks); ``a0``/``w0`` (nf, n_in): the principal right/left input directions of the scaled
    problem mapped back to ``M``, used to start the lower bound; ``iterations``: Newton steps.
    """

    upper: np.ndarray
    dblocks: list[np.ndarray]
    gblocks: list[np.ndarray]
    a0: np.ndarray
    w0: np.ndarray
    iterations: int


# ---------------------------------------------------------------------------- balancing start
def block_norms(M: np.ndarray, lay: Layout) -> np.ndarray:
    """Frobenius norms of the blocks ``M[out_i, in_j]``, shape (nf, k, k)."""
    k = lay.n_blocks
    B = np.empty((M.shape[0], k, k))
    for i, o in enumerate(lay.out):
        for j, c in enumerate(lay.inp):
            B[:, i, j] = np.sqrt(np.sum(np.abs(M[:, o, c]) ** 2, axis=(1, 2)))
    return B


def _osborne(B2: np.ndarray, sweeps: int = 12) -> np.ndarray:
    """log d minimising ``sum_ij B2_ij d_i^2 / d_j^2`` (off-diagonal) by exact coordinate steps."""
    nf, k, _ = B2.shape
    off = B2 * (1.0 - np.eye(k))
    off = off + 1e-14 * (1.0 - np.eye(k))  # B2 is normalised to max 1
    x = np.zeros((nf, k))
    for _ in range(sweeps):
        for i in range(k - 1):
            e = np.exp(2.0 * x)
            a = np.sum(off[:, i, :] / e, axis=1)  # row i: B_ij^2 / d_j^2 (times d_i^2)
            b = np.sum(off[:, :, i] * e, axis=1)  # column i: B_ji^2 d_j^2 (over d_i^2)
            x[:, i] = 0.25 * np.log(b / a)
    return x - x[:, -1:]


def _perron(B: np.ndarray) -> np.ndarray:
    """log d of the Perron scaling ``d_i = sqrt(y_i / x_i)`` of the block-norm matrix."""
    k = B.shape[1]
    Bp = B + 1e-12  # B is normalised to max 1; positive entries make the Perron root simple
    x = np.ones(B.shape[:2]) / np.sqrt(k)
    y = x.copy()
    for _ in range(30):  # power iteration: Bp is positive, the Perron root is simple
        x = np.einsum("fij,fj->fi", Bp, x)
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        y = np.einsum("fji,fj->fi", Bp, y)
        y /= np.linalg.norm(y, axis=1, keepdims=True)
    x = 0.5 * (np.log(y) - np.log(x))
    return x - x[:, -1:]


def _scaled_norm(M: np.ndarray, lay: Layout, logd: np.ndarray) -> np.ndarray:
    """``sigma_max(D_L M D_R^{-1})`` with scalar D-scales ``exp(logd)``."""
    sl, sr = np.zeros((M.shape[0], lay.n_out)), np.zeros((M.shape[0], lay.n_in))
    for i, (o, c) in enumerate(zip(lay.out, lay.inp)):
        sl[:, o] = logd[:, i : i + 1]
        sr[:, c] = logd[:, i : i + 1]
    A = np.exp(sl)[:, :, None] * M * np.exp(-sr)[:, None, :]
    return np.sqrt(np.maximum(np.linalg.eigvalsh(_herm(A) @ A)[:, -1], 0.0))


def balancing_start(M: np.ndarray, lay: Layout) -> tuple[np.ndarray, np.ndarray]:
    """Scalar D-scales (log, (nf, k)) from Osborne or Perron, whichever bounds lower; and that bound."""
    B = block_norms(M, lay)
    top = B.max(axis=(1, 2))
    B = B / np.where(top > 0, top, 1.0)[:, None, None]  # the scaling does not depend on |M|
    cands = [_osborne(B**2), _perron(B)]
    bounds = [_scaled_norm(M, lay, x) for x in cands]
    pick = bounds[1] < bounds[0]
    return np.where(pick[:, None], cands[1], cands[0]), np.minimum(bounds[0], bounds[1])


# ---------------------------------------------------------------------------- Newton refinement
def _newton_step(g: np.ndarray, hess: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``-|Hess|^{-1} g`` (the Hessian's eigenvalues made positive), cut to ``|s|_inf <= radius``.

    A positive definite Hessian (the usual case) is solved directly; otherwise its
    eigenvalues are replaced by their absolute values (floored at 1e-8 of the largest).
    """
    scale = np.maximum(np.abs(hess).max(axis=(1, 2)), 1e-12)
    reg = hess + (1e-10 * scale)[:, None, None] * np.eye(hess.shape[1])
    try:
        np.linalg.cholesky(reg)
        s = -np.linalg.solve(reg, g[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        ev, V = np.linalg.eigh(hess)
        ev = np.maximum(np.abs(ev), 1e-8 * scale[:, None])
        s = -(V @ ((np.swapaxes(V, 1, 2) @ g[:, :, None])[:, :, 0] / ev)[:, :, None])[:, :, 0]
    full_dec = -np.einsum("fa,fa->f", g, s)
    big = np.abs(s).max(axis=1)
    return s * np.minimum(1.0, radius / np.maximum(big, 1e-300))[:, None], full_dec


def _expm_blocks(theta_d: np.ndarray, lay: Layout, sign: float) -> tuple[np.ndarray, np.ndarray]:
    """``exp(sign E_L)`` and ``exp(sign E_R)`` for block-diagonal Hermitian generators."""
    EL = np.einsum("fa,aij->fij", sign * theta_d, lay.gen_left)
    ER = np.einsum("fa,aij->fij", sign * theta_d, lay.gen_right)
    outs = []
    for E, sls in ((EL, lay.out), (ER, lay.inp)):
        X = np.zeros_like(E)
        for s, m in zip(sls, lay.dsize):
            if m == 1:
                idx = np.arange(s.start, s.stop)
                X[:, idx, idx] = np.exp(E[:, idx, idx].real)
            else:
                ev, V = np.linalg.eigh(E[:, s, s])
                X[:, s, s] = (V * np.exp(ev)[:, None, :]) @ _herm(V)
        outs.append(X)
    return outs[0], outs[1]


def _step_scales(theta_d: np.ndarray, lay: Layout) -> tuple[np.ndarray, np.ndarray]:
    """``exp(E_L)`` and ``exp(-E_R)`` of a step: vectors (diagonal case) or matrices."""
    if lay.diagonal is not None:
        l, r = lay.diagonal
        return np.exp(theta_d @ l), np.exp(-(theta_d @ r))
    return _expm_blocks(theta_d, lay, 1.0)[0], _expm_blocks(theta_d, lay, -1.0)[1]


def _scale(left: np.ndarray | None, X: np.ndarray, right: np.ndarray | None) -> np.ndarray:
    """``left @ X @ right`` where each factor is a stack of matrices, of diagonals (vectors) or None."""
    if left is not None:
        X = left[:, :, None] * X if left.ndim == 2 else left @ X
    if right is not None:
        X = X * right[:, None, :] if right.ndim == 2 else X @ right
    return X


class _State:
    """Per-frequency Newton state: scaled matrix, scales, eigendecomposition and derivatives."""

    def __init__(self, A, G, DL, DRi, tau, lay):
        self.A, self.G, self.DL, self.DRi, self.tau = A, G, DL, DRi, tau
        self.lam, self.Q = np.linalg.eigh(_hmatrix(A, G))
        self.F, self.w = _smoothed(self.lam, tau)
        k = lay.n_d + lay.n_g
        if k == 0:  # nothing to optimise (a single scalar block)
            self.g, self.hess = np.zeros((A.shape[0], 0)), np.zeros((A.shape[0], 0, 0))
        else:
            self.g, self.hess = _derivatives(A, G, self.lam, self.Q, self.w, tau, lay)

    def accept(self, acc, ok, At, Gt, lam, Q, Ft, w, left, right_inv, tau, lay) -> None:
        """Move the frequencies ``acc`` (``ok`` among the trial points) to their trial points."""
        G = None if Gt is None else Gt[ok]
        self.g[acc], self.hess[acc] = _derivatives(At[ok], G, lam[ok], Q[ok], w[ok], tau[acc], lay)
        self.A[acc], self.lam[acc], self.Q[acc] = At[ok], lam[ok], Q[ok]
        self.F[acc], self.w[acc] = Ft[ok], w[ok]
        self.DL[acc] = _scale(left[ok], self.DL[acc], None)
        self.DRi[acc] = _scale(None, self.DRi[acc], right_inv[ok])
        if G is not None:
            self.G[acc] = G

    def take(self, idx):
        """Copy of the fields at the frequencies ``idx`` (for in-place updates)."""
        return {k: getattr(self, k)[idx] for k in ("A", "G", "DL", "DRi", "lam", "Q", "F", "w", "g", "hess")
                if getattr(self, k) is not None}


def upper_bound(M: np.ndarray, lay: Layout, *, time_budget_s: Any = None,
                max_newton: int = MAX_NEWTON) -> UpperBound:
    """D-(G-)scaled upper bound of mu at every frequency of ``M`` (nf, n_out, n_in).

    Parameters
    ----------
    M : ndarray, complex, (nf, n_out, n_in)
    lay : Layout
    time_budget_s : float, Deadline or None
        Optional wall-clock limit of the Newton stage (:mod:`robustctl.budget`; the bound stays
        valid when it stops early); None: ``max_newton`` alone bounds it.
    max_newton : int
        Iteration cap of the Newton stage.
    """
    nf = M.shape[0]
    logd, sig0 = balancing_start(M, lay)
    norm = np.where(sig0 > 0, sig0, 1.0)
    dblocks = [np.exp(logd[:, i])[:, None, None] * np.eye(m)[None] for i, m in enumerate(lay.dsize)]
    DL, _ = lay.assemble(dblocks)
    _, DRi = lay.assemble(dblocks, inverse=True)
    A = DL @ (M / norm[:, None, None]) @ DRi
    G = np.zeros((nf, lay.n_in, lay.n_out), complex) if lay.has_real else None
    stage = np.zeros(nf, int)
    tau = np.full(nf, (TAU_STAGES_REAL if lay.has_real else TAU_STAGES)[0])
    st = _State(A, G, DL, DRi, tau, lay)
    lam_ref = np.maximum(st.lam[:, -1], 1e-300)  # tau is relative to lambda_max at the stage start
    best = st.lam[:, -1].copy()
    best_DL, best_DRi = DL.copy(), DRi.copy()
    best_G = None if G is None else G.copy()
    stages = TAU_STAGES_REAL if lay.has_real else TAU_STAGES
    radius = np.full(nf, START_STEP)  # trust region on the step (inf-norm, log units)
    active = (sig0 > 0) & (best > 0) & (lay.n_d + lay.n_g > 0)
    deadline, it = as_deadline(time_budget_s), 0
    while active.any() and it < max_newton and not deadline.expired():
        it += 1
        idx = np.flatnonzero(active)
        cur = st.take(idx)
        s, full_dec = _newton_step(cur["g"], cur["hess"], radius[idx])
        size = np.abs(s).max(axis=1) if s.shape[1] else np.zeros(idx.size)
        dec = -np.einsum("fa,fa->f", cur["g"], s)
        left, right_inv = _step_scales(s[:, : lay.n_d], lay)
        At = _scale(left, cur["A"], right_inv)
        Gt = None if G is None else cur["G"] + np.einsum("fa,aij->fij", s[:, lay.n_d:], lay.gen_g)
        lam, Q = np.linalg.eigh(_hmatrix(At, Gt))
        Ft, w = _smoothed(lam, tau[idx])
        ok = Ft <= cur["F"] - 1e-4 * dec
        radius[idx] = np.where(ok, np.minimum(MAX_STEP, np.maximum(radius[idx], 2.0 * size)), 0.25 * size)
        acc = idx[ok]
        if acc.size:
            st.accept(acc, ok, At, Gt, lam, Q, Ft, w, left, right_inv, tau, lay)
            b = acc[lam[ok, -1] < best[acc]]
            best[b] = st.lam[b, -1]
            best_DL[b], best_DRi[b] = st.DL[b], st.DRi[b]
            if G is not None:
                best_G[b] = st.G[b]
        # stage control: a small Newton decrement (or a collapsed trust region) ends a stage
        stalled = radius[idx] < 1e-9
        done = ((full_dec < STAGE_TOL * tau[idx]) & ok) | stalled
        adv = idx[done]
        stage[adv] += 1
        # lambda_max fell far below the stage's reference: restart the stage with tau relative to it
        shrunk = idx[ok & ~done & (lam[:, -1] < 0.25 * lam_ref[idx]) & (lam[:, -1] > 0)]
        fin = adv[stage[adv] >= len(stages)]
        active[fin] = False
        active[best <= 0] = False
        nxt = np.concatenate([adv[stage[adv] < len(stages)], shrunk])
        if nxt.size:
            lam_ref[nxt] = np.maximum(st.lam[nxt, -1], 1e-300)
            tau[nxt] = np.array(stages)[np.minimum(stage[nxt], len(stages) - 1)] * lam_ref[nxt]
            radius[nxt] = START_STEP
            _restage(st, nxt, tau, lay)
    return _finish(M, lay, best, best_DL, best_DRi, best_G, norm, it)


def _restage(st: _State, idx: np.ndarray, tau: np.ndarray, lay: Layout) -> None:
    """Recompute the smoothed value and derivatives at ``idx`` for their new ``tau``."""
    F, w = _smoothed(st.lam[idx], tau[idx])
    G = None if st.G is None else st.G[idx]
    g, h = _derivatives(st.A[idx], G, st.lam[idx], st.Q[idx], w, tau[idx], lay)
    st.F[idx], st.w[idx], st.g[idx], st.hess[idx] = F, w, g, h


def _hermitian_factor(D: np.ndarray) -> np.ndarray:
    """The Hermitian positive definite ``sqrt(D^H D)`` (same ``X = D^H D``, hence the same bound)."""
    if D.shape[-1] == 1:
        return np.abs(D).astype(complex)
    ev, V = np.linalg.eigh(_herm(D) @ D)
    return (V * np.sqrt(np.maximum(ev, 0.0))[:, None, :]) @ _herm(V)


def _finish(M, lay, best, DL, DRi, G, norm, iterations) -> UpperBound:
    """Unscale: the bound, per-block D (normalised, last block 1) and G of the LMI, top vectors."""
    nf = M.shape[0]
    upper = norm * np.sqrt(np.maximum(best, 0.0))
    dblocks = [DL[:, o, o] if m > 1 else DL[:, o.start : o.start + 1, o.start : o.start + 1]
               for o, m in zip(lay.out, lay.dsize)]
    last = dblocks[-1]
    c = np.abs(np.linalg.det(last)) ** (1.0 / last.shape[-1])
    c = np.where(c > 0, c, 1.0)
    dblocks = [_hermitian_factor(d / c[:, None, None]) for d in dblocks]
    gblocks = []
    for o, i, kind in zip(lay.out, lay.inp, lay.kinds):
        r = i.stop - i.start
        if kind != "real" or G is None:
            gblocks.append(np.zeros((nf, r, r), complex) if kind != "full" else np.zeros((nf, 1, 1), complex))
            continue
        Dk = DL[:, o, o]
        gk = _herm(Dk) @ G[:, i, o] @ Dk * (norm / c**2)[:, None, None]
        gblocks.append(0.5 * (gk + _herm(gk)))
    A = DL @ (M / norm[:, None, None]) @ DRi
    H = _hmatrix(A, G)
    _, Q = np.linalg.eigh(H)
    q = Q[:, :, -1:]
    a0 = DRi @ q  # input direction of M: M a0 ~ beta b
    w0 = np.linalg.solve(_herm(DRi), q)  # D_R^H q: the matching left direction
    return UpperBound(upper, dblocks, gblocks, a0[:, :, 0], w0[:, :, 0], iterations)
