"""The H-infinity norm of a state-space system by the Hamiltonian level-set iteration.

``||G||_inf = sup_w sigma_max(G(jw))`` is computed by the quadratically convergent
algorithm of Bruinsma & Steinbuch (1990, "A fast algorithm to compute the H-infinity norm
of a transfer function matrix", *Systems & Control Letters* 14, 287-293), a refinement of
the bisection of Boyd, Balakrishnan & Kabamba (1989, "A bisection method for computing the
H-infinity norm of a transfer matrix and related problems", *Math. Control Signals
Systems* 2, 207-219). Both rest on one fact (BBK Theorem 1): for ``gamma > sigma_max(D)``,
``gamma`` is a singular value of ``G(jw)`` if and only if ``jw`` is an eigenvalue of the
Hamiltonian matrix

.. math::

    H(\\gamma) = \\begin{bmatrix} A + B R^{-1} D^T C & \\gamma B R^{-1} B^T \\\\
                 -\\gamma C^T S^{-1} C & -(A + B R^{-1} D^T C)^T \\end{bmatrix},
    \\quad R = \\gamma^2 I - D^T D,\\; S = \\gamma^2 I - D D^T

(the off-diagonal blocks carry one factor ``gamma`` each, a symplectic diagonal similarity
of the textbook form that balances them).

Robustness for lightly damped structures:

* the starting lower bound is the largest singular value found at ``w = 0``, at
  ``w = inf`` (``sigma_max(D)``) and at the peaks of the modes whose peaks alone,
  ``||R_i|| / |Re p_i|``, are largest, each located by parabolic (Newton-like) steps on
  ``1 / sigma_max^2``, which is exactly quadratic in ``w`` near an isolated mode (three
  rounds of three samples reach about ``1e-13`` relative at a lightly damped peak), so
  that the first Hamiltonian test usually already certifies the norm and it costs one
  eigenvalue computation of order ``2 n``;
* the imaginary-axis test is generous (relative tolerance ``1e-6`` plus an absolute
  ``1e-10 ||H||``; LAPACK ``geev`` balances ``H`` first): a spurious "crossing" costs at
  most one evaluation of ``sigma_max`` at the midpoints between crossings, which then
  shows no level crossing and ends the iteration, whereas a missed crossing would return a
  wrong norm (the interval below the first crossing needs no evaluation: ``sigma_max(0)``
  is part of the lower bound);
* frequency responses come from the modal decomposition of :mod:`robustctl.lti` (balanced,
  well-conditioned blocks diagonalised; the others by a Schur form), accurate to about
  ``eps / zeta`` at a mode of damping ``zeta``.

Discrete-time systems are mapped to continuous time by the bilinear (Moebius) map
``z = (1 + s) / (1 - s)``, which maps the unit circle onto the imaginary axis and keeps the
norm; the peak frequency is mapped back, ``theta = 2 arctan(w)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.linalg import lapack as _lapack

from ...checks import positive_number
from ...errors import ModelError, RobustctlError
from ...lti import (
    abs2,
    as_statespace,
    modal_terms,
    roundoff_margin,
    schur_blocks,
    schur_eval,
    schur_factors,
    small_block_scaling,
)
from ...threads import limit_blas

__all__ = ["hinfnorm"]

#: Iteration cap of the Hamiltonian level-set loop (it converges quadratically, in 1-4 steps).
MAX_ITER = 40
#: Number of best modal peaks refined by a local search before the first Hamiltonian test.
N_REFINE = 3
#: Largest number of rounds of the modal peak search (lightly damped modes need three).
PEAK_ROUNDS = 8
#: The modal peak search stops when its parabola predicts a relative gain in sigma_max^2 below this.
PEAK_RTOL = 1e-12
#: The modal peak search drops a band whose parabola predicts a peak this far (relative, in
#: sigma_max^2) below the best value found (the Hamiltonian test catches a wrong prediction).
PEAK_PRUNE = 2e-2
#: Relative and absolute (times ||H||) tolerances on |Re(lambda)| of an imaginary-axis eigenvalue.
IMAG_RTOL = 1e-6
IMAG_ATOL = 1e-10
#: Largest order computed without touching the BLAS thread pools (see hinfnorm_matrices).
SMALL_N = 32
#: Frequencies per batch of the modal response (keeps the (batch x n) work array cache-sized).
CHUNK = 256


# ---------------------------------------------------------------------------- frequency response
class _SigmaMax:
    """``w -> sigma_max(G(jw))`` for many frequencies, with the modal decomposition done once.

    The well-conditioned modes are kept as residue matrices ``R_i = (C v_i)(w_i^T B)``
    (flattened to rows of ``R``, shape (n, p m)), so that ``G(jw) = D + sum_i R_i / (jw - lam_i)``
    is one complex matrix product per batch of frequencies.
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> None:
        self.D = D
        self.shape = D.shape
        self.has_d = bool(D.any())
        self.evaluations = 0
        n = A.shape[0]
        self.poles = np.zeros(0, complex)
        self.lam = np.zeros(0, complex)
        self.R = np.zeros((0, D.size), complex)
        self.bad: list[tuple] = []  # Schur factors of the blocks not diagonalised
        if n == 0 or D.size == 0:
            return
        blocks = schur_blocks(A)
        if max(b.shape[1] for b in blocks) <= 2:
            scale = small_block_scaling(A, blocks)
        else:  # LAPACK gebal scaling only (no permutation), as scipy.linalg.matrix_balance
            _, lo, hi, scale, _ = _lapack.dgebal(A, scale=1, permute=0)
        if (scale == 1.0).all():  # (a well-scaled A, e.g. an orthogonal change of a modal form)
            Ab, Bb, Cb = A, B, C
        else:
            Ab = A * (scale[None, :] / scale[:, None])
            Bb, Cb = B / scale[:, None], C * scale[None, :]
        self.lam, CV, W, bad = modal_terms(Ab, Bb, Cb, blocks, io_B=B, io_C=C)
        self.R = (CV.T[:, :, None] * W[:, None, :]).reshape(self.lam.size, D.size)
        poles = [self.lam]
        for idx in bad:
            sub = np.ix_(idx, idx)
            self.bad.append(schur_factors(A[sub], B[idx], C[:, idx]))
            poles.append(np.linalg.eigvals(A[sub]))
        self.poles = np.concatenate(poles) if self.bad else self.lam

    def peak_estimates(self) -> np.ndarray:
        """``||R_i|| / |Re p_i|`` per pole (of a stable system): ``sup_w ||R_i / (jw - p_i)||``,
        the peak of mode ``i`` alone (``R_i`` has rank one, ``||R_i||_2 = ||R_i||_F``); ``inf`` for
        the poles of blocks kept in Schur form, which have no residues."""
        est = np.sqrt(abs2(self.R).sum(axis=1)) / -self.lam.real
        return np.append(est, np.full(self.poles.size - est.size, np.inf)) if self.bad else est

    def response(self, w: np.ndarray) -> np.ndarray:
        """``G(jw)``, shape (n_w, p, m), for a 1-D float array ``w`` (rad/s) of a stable system."""
        s = 1j * w
        if self.lam.size:  # sum_i R_i / (s - lam_i), in frequency chunks (no pole on the axis)
            if s.size <= CHUNK:
                out = (1.0 / (s[:, None] - self.lam)) @ self.R
            else:
                out = np.empty((s.size, self.D.size), complex)
                for start in range(0, s.size, CHUNK):
                    np.matmul(1.0 / (s[start : start + CHUNK, None] - self.lam), self.R,
                              out=out[start : start + CHUNK])
            if self.has_d:
                out += self.D.reshape(-1)
            out = out.reshape(s.size, *self.shape)
        else:
            out = np.broadcast_to(self.D.astype(complex), (s.size, *self.shape)).copy()
        if self.bad:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                for factors in self.bad:
                    out += schur_eval(factors, s)
        return out

    def __call__(self, w: Any) -> np.ndarray:
        w = np.asarray(w, dtype=float)
        if w.ndim != 1:
            w = w.reshape(-1)
        self.evaluations += w.size
        return _sigma_max(self.response(w))


def _sigma_max(G: np.ndarray) -> np.ndarray:
    """Largest singular value of each matrix of a stack (n, p, m), via the smaller Gram matrix.

    ``lambda_max(G^H G)`` is accurate to ``eps lambda_max``, so ``sigma_max`` is accurate to ``eps``
    relative (the small singular values, which squaring would spoil, are not needed). Gram
    matrices of order 2 and 3 use closed forms (:func:`_lambda_max_2`, :func:`_lambda_max_3`),
    larger ones LAPACK ``heevd``.
    """
    if G.shape[1] == 1 and G.shape[2] == 1:
        return np.abs(G.reshape(-1))
    if G.shape[1] == 1 or G.shape[2] == 1:
        return np.sqrt(abs2(G.reshape(G.shape[0], -1)).sum(axis=1))
    Gh = np.conj(np.swapaxes(G, 1, 2))
    gram = Gh @ G if G.shape[2] <= G.shape[1] else G @ Gh
    if gram.shape[1] == 2:
        lam = _lambda_max_2(gram)
    elif gram.shape[1] == 3 and gram.shape[0] >= 32:  # its ~40 array operations beat LAPACK from ~30 on
        lam = _lambda_max_3(gram)
    else:
        lam = np.linalg.eigvalsh(gram)[:, -1]
    return np.sqrt(np.maximum(lam, 0.0))


def _lambda_max_2(M: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of Hermitian 2x2 matrices ``[[a, b], [b*, c]]``:
    ``(a + c) / 2 + sqrt(((a - c) / 2)^2 + |b|^2)``."""
    a, c = M[:, 0, 0].real, M[:, 1, 1].real
    return 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + abs2(M[:, 0, 1]))


def _lambda_max_3(M: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of Hermitian 3x3 matrices by the trigonometric solution of the cubic.

    With ``q = tr M / 3``, ``p^2 = ||M - q I||_F^2 / 6`` and ``r = det((M - q I) / p) / 2``,
    ``lambda_max = q + 2 p cos(arccos(r) / 3)`` (Smith 1961, "Eigenvalues of a symmetric 3x3
    matrix", *Comm. ACM* 4, 168). It is accurate to ``eps ||M||`` except where the two largest
    eigenvalues (nearly) coincide, ``r -> -1``, where ``arccos`` amplifies rounding to
    ``sqrt(eps)``: those matrices (``1 + r < 1e-4``), and tiny ones, go to LAPACK ``heevd``.
    """
    m = M.reshape(-1, 9)
    d0, d1, d2 = m[:, 0].real, m[:, 4].real, m[:, 8].real
    tr = d0 + d1 + d2  # >= 0 (a Gram matrix); the cubic is solved for M / tr: no overflow in det
    inv = 1.0 / (tr + (tr <= 1e-290))  # (no scaling for tr ~ 0, where 1 / tr would overflow)
    q = tr * inv * (1.0 / 3.0)
    b0, b1, b2 = d0 * inv - q, d1 * inv - q, d2 * inv - q
    m01, m02, m12 = m[:, 1] * inv, m[:, 2] * inv, m[:, 5] * inv
    a01, a02, a12 = abs2(m01), abs2(m02), abs2(m12)
    p2 = (b0 * b0 + b1 * b1 + b2 * b2 + 2.0 * (a01 + a02 + a12)) * (1.0 / 6.0)
    det = b0 * b1 * b2 - b0 * a12 - b1 * a02 - b2 * a01 + 2.0 * (m01 * m12 * m02.conj()).real
    flat = p2 <= 1e-300  # M = (tr / 3) I (or M = 0)
    p = np.sqrt(p2 + flat)
    r = np.minimum(np.maximum(det / (2.0 * p2 * p + flat), -1.0), 1.0)
    lam = (q + 2.0 * p * np.cos(np.arccos(r) * (1.0 / 3.0)) * ~flat) / inv
    close = (r < 1e-4 - 1.0) & ~flat | (tr <= 1e-290) & (tr > 0)
    if close.any():
        lam[close] = np.linalg.eigvalsh(M[close])[:, -1]
    return lam


# ---------------------------------------------------------------------------- lower bounds
def _refine(
    sigma: _SigmaMax, lo: np.ndarray, hi: np.ndarray, n_grid: int = 33, n_zoom: int = 3, n_first: int = 17
) -> tuple[np.ndarray, np.ndarray]:
    """Local maxima of ``sigma_max`` in the bands ``[lo_k, hi_k]`` (rad/s), all bands at once.

    A vectorised zoom search: ``n_first`` points per band, then the band shrinks to the two
    grid cells around its best point and is sampled by ``n_grid`` points, ``n_zoom - 1``
    times (by default a final spacing of ``1/4096`` of the band), then one parabolic step
    through the best point and its two neighbours (near a smooth peak the error of
    ``sigma_max`` is then about ``1e-14`` relative). Each round is one call of ``sigma``,
    whose cost at small orders is a fixed overhead, hence few rounds of many points. Returns
    ``(sigma, w)``: the best value and frequency per band.
    """
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    best_s, best_w = np.full(lo.size, -np.inf), 0.5 * (lo + hi)
    rows = np.arange(lo.size)
    n_pts = n_first
    for _ in range(n_zoom):
        w = lo[:, None] + (hi - lo)[:, None] * _unit_grid(n_pts)[None, :]
        s = sigma(w.ravel()).reshape(w.shape)
        k = np.argmax(s, axis=1)
        s_k = s[rows, k]
        better = s_k > best_s
        best_s[better], best_w[better] = s_k[better], w[rows[better], k[better]]
        step = (hi - lo) / (n_pts - 1)
        lo, hi = np.maximum(lo, best_w - step), np.minimum(hi, best_w + step)
        n_pts = n_grid
    inner = (k > 0) & (k < w.shape[1] - 1)
    if inner.any():  # parabola through the last grid's best point and its neighbours
        r, kk = rows[inner], k[inner]
        s0, sm, sp = s[r, kk], s[r, kk - 1], s[r, kk + 1]
        h = w[r, 1] - w[r, 0]
        curv = sm - 2.0 * s0 + sp
        concave = curv < 0
        shift = 0.5 * h * (sm - sp) / np.where(concave, curv, -1.0) * concave
        w_vertex = w[r, kk] + np.minimum(np.maximum(shift, -h), h)
        s_vertex = sigma(w_vertex)
        better = s_vertex > best_s[r]
        best_s[r[better]], best_w[r[better]] = s_vertex[better], w_vertex[better]
    return best_s, best_w


_GRIDS: dict[int, np.ndarray] = {}


def _unit_grid(n: int) -> np.ndarray:
    """``linspace(0, 1, n)``, cached."""
    if n not in _GRIDS:
        _GRIDS[n] = np.linspace(0.0, 1.0, n)
    return _GRIDS[n]


def _modal_peaks(sigma: _SigmaMax, keep: int = N_REFINE) -> tuple[float, float]:
    """Largest ``sigma_max`` found at the modal peaks and at ``w = 0``: ``(value, w)`` (rad/s).

    Every pole pair ``p = -a + j c`` (and every real pole, ``c = 0``) is a band; the
    ``keep`` bands whose modes alone peak highest, ``||R_i|| / |Re p_i|``
    (:meth:`_SigmaMax.peak_estimates`; a pole of a block kept in Schur form always qualifies), are
    sampled at ``c - a, c, c + a`` (as ``|w|``: ``sigma_max`` is even in ``w`` for a real
    system), together with ``w = 0``, in one call of ``sigma``. Each band is then refined
    by parabolic steps on ``y = 1 / sigma_max^2``, which is exactly quadratic in ``w`` near
    an isolated mode, ``|R / (j w - p)|^{-2} = ((w - c)^2 + a^2) / |R|^2``, so that the
    vertex of the parabola through three samples ``v - h, v, v + h`` is a Newton-like step
    to the peak; the next three samples are centred on that vertex with
    ``h = max(|step|, 1e-4 a)``. A band stops when the parabola predicts a gain in
    ``sigma_max^2`` below ``PEAK_RTOL`` relative (its best sample is then that accurate),
    after ``PEAK_ROUNDS`` rounds at most; a step is at most ``max(2 h, a)`` long (a Newton
    step from a small, accurate stencil may reach a peak that a wide one mislocated), a band
    whose parabola is not convex steps ``2 h`` towards its best sample, and a band whose
    parabola peaks ``PEAK_PRUNE`` (in ``sigma_max^2``) below the best sample so far is
    dropped. A lightly damped mode takes three rounds. Every sample is a valid lower bound of
    the norm; the largest is returned.
    A peak this search misses (between modes, or of a mode ranked below ``keep``) is found
    by the Hamiltonian test, at the cost of one more level-set step.

    The refinement runs on Python floats: at these sizes each numpy call costs more than
    its arithmetic.
    """
    upper = sigma.poles.imag >= 0
    p, est = sigma.poles[upper], sigma.peak_estimates()[upper]
    if p.size > keep:  # the modes whose peaks alone are largest
        top = np.argpartition(est, p.size - keep)[p.size - keep :]
        p = p[top]
    c, a = p.imag, np.abs(p.real)
    pts = np.abs(c[:, None] + a[:, None] * _STENCIL)
    s_all = sigma(np.append(pts.reshape(-1), 0.0))
    j = int(np.argmax(s_all))
    best_s, best_w = float(s_all[j]), (0.0 if j == pts.size else float(pts.flat[j]))
    bands = list(zip(c.tolist(), a.tolist(), a.tolist(), s_all[:-1].reshape(c.size, 3).tolist()))
    for _ in range(PEAK_ROUNDS - 1):
        moving = []
        # a band whose parabola peaks below sqrt(1 - PEAK_PRUNE) best_s is dropped
        y_cut = 1.0 / ((1.0 - PEAK_PRUNE) * best_s * best_s) if best_s > 0.0 else np.inf
        for w, aw, h, (s_m, s_0, s_p) in bands:
            if not s_m > 0.0 or not s_0 > 0.0 or not s_p > 0.0:
                continue  # a zero response (an uncontrollable or unobservable mode): nothing to refine
            y_m, y_0, y_p = 1.0 / (s_m * s_m), 1.0 / (s_0 * s_0), 1.0 / (s_p * s_p)
            curv = y_m - 2.0 * y_0 + y_p
            if curv > 0.0:
                slope = 0.5 * (y_m - y_p)
                gain = 0.5 * slope * slope / curv  # y_0 - y at the vertex of the parabola
                if gain <= PEAK_RTOL * y_0 or y_0 - gain > y_cut:
                    continue
                reach = max(2.0, aw / h)  # trust region: 2 h, or the half-power half-width a
                step = h * min(max(slope / curv, -reach), reach)
            else:
                step = 2.0 * h if s_p > s_m else -2.0 * h
            moving.append((w + step, aw, max(abs(step), 1e-4 * aw)))
        if not moving:
            break
        pts = np.array([abs(w + h * d) for w, _, h in moving for d in (-1.0, 0.0, 1.0)])
        s_new = sigma(pts)
        j = int(np.argmax(s_new))
        if s_new[j] > best_s:
            best_s, best_w = float(s_new[j]), float(pts[j])
        s_list = s_new.tolist()
        bands = [(w, aw, h, s_list[3 * i : 3 * i + 3]) for i, (w, aw, h) in enumerate(moving)]
    return best_s, best_w


def _initial_bound(sigma: _SigmaMax, D: np.ndarray) -> tuple[float, float]:
    """Lower bound ``(gamma_lb, w_peak)``: the modal peaks (:func:`_modal_peaks`), ``w = 0``
    and ``w = inf`` (``sigma_max(D)``)."""
    gamma = float(_sigma_max(D[None].astype(complex))[0]) if D.any() else 0.0
    w_peak = np.inf
    if sigma.poles.size:
        s_pk, w_pk = _modal_peaks(sigma)
        if s_pk > gamma:
            gamma, w_peak = s_pk, w_pk
    return gamma, w_peak


_STENCIL = np.array([-1.0, 0.0, 1.0])


# ---------------------------------------------------------------------------- Hamiltonian test
class _Hamiltonian:
    """``gamma -> H(gamma)`` of the module docstring (BBK 1989, Theorem 1), the products that do
    not depend on ``gamma`` formed once. ``gamma`` must exceed ``sigma_max(D)``.

    With ``D = 0`` it is ``[[A, B B^T / gamma], [-C^T C / gamma, -A^T]]``; the matrix is built
    in Fortran order so that LAPACK ``geev`` works in place.
    """

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> None:
        self.A, self.B, self.C, self.D = A, B, C, D
        self.n = A.shape[0]
        self.zero_d = not np.any(D)
        if self.zero_d:
            self.BBt, self.CtC = B @ B.T, C.T @ C
        else:
            self.DtD, self.DDt, self.DtC = D.T @ D, D @ D.T, D.T @ C

    def __call__(self, gamma: float) -> np.ndarray:
        n = self.n
        H = np.empty((2 * n, 2 * n), order="F")
        if self.zero_d:
            H[:n, :n] = self.A
            np.multiply(self.BBt, 1.0 / gamma, out=H[:n, n:])
            np.multiply(self.CtC, -1.0 / gamma, out=H[n:, :n])
        else:
            B, C = self.B, self.C
            R = gamma**2 * np.eye(B.shape[1]) - self.DtD
            S = gamma**2 * np.eye(C.shape[0]) - self.DDt
            H[:n, :n] = self.A + B @ np.linalg.solve(R, self.DtC)
            H[:n, n:] = gamma * B @ np.linalg.solve(R, B.T)
            H[n:, :n] = -gamma * C.T @ np.linalg.solve(S, C)
        H[n:, n:] = -H[:n, :n].T
        return H


def hamiltonian(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, gamma: float) -> np.ndarray:
    """The Hamiltonian ``H(gamma)`` of the module docstring (BBK 1989, Theorem 1).

    ``gamma`` must exceed ``sigma_max(D)``.
    """
    return _Hamiltonian(A, B, C, D)(gamma)


def imaginary_axis_frequencies(H: np.ndarray) -> np.ndarray:
    """Sorted non-negative frequencies ``w`` (rad/s) of the eigenvalues of ``H`` near ``jw``.

    An eigenvalue counts as imaginary when ``|Re lambda| <= IMAG_RTOL |lambda| + IMAG_ATOL ||H||_1``
    (a generous test; see the module docstring for why). LAPACK ``dgeev`` (balancing, Hessenberg
    QR, no eigenvectors) overwrites ``H``.
    """
    if H.size == 0:
        return np.zeros(0)
    scale = float(np.abs(H).sum(axis=0).max())
    wr, wi, _, _, info = _lapack.dgeev(H, compute_vl=0, compute_vr=0, overwrite_a=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"LAPACK dgeev: the QR algorithm did not converge (info={info}).")
    on_axis = np.abs(wr) <= IMAG_RTOL * np.hypot(wr, wi) + IMAG_ATOL * scale
    return np.unique(np.abs(wi[on_axis])) if on_axis.any() else _EMPTY


_EMPTY = np.zeros(0)


# ---------------------------------------------------------------------------- the iteration
def _level_set_iteration(
    ham: _Hamiltonian,
    sigma: _SigmaMax,
    gamma: float,
    w_peak: float,
    tol: float,
) -> tuple[float, float, int]:
    """Bruinsma-Steinbuch (1990) iteration from the lower bound ``gamma``; returns (norm, w_peak, steps)."""
    for step in range(1, MAX_ITER + 1):
        level = gamma * (1.0 + 2.0 * tol)
        edges = imaginary_axis_frequencies(ham(level))  # sorted, distinct
        # sigma_max - level keeps its sign between consecutive edges (every crossing is an
        # edge); it is negative on [0, edges[0]] (sigma_max(0) <= gamma: w = 0 is sampled by
        # the initial bound) and beyond edges[-1] (sigma_max(inf) = sigma_max(D) <= gamma),
        # so only the intervals between two edges can rise above the level
        if edges.size < 2:
            return gamma, w_peak, step
        mids = 0.5 * (edges[:-1] + edges[1:])
        s = sigma(mids)
        k = int(np.argmax(s))
        if not s[k] > level:  # no interval where sigma_max exceeds the level: certified
            return gamma, w_peak, step
        above = np.flatnonzero(s > level)
        s_ref, w_ref = _refine(sigma, edges[above], edges[above + 1])
        j = int(np.argmax(s_ref))
        gamma, w_peak = (
            (float(s_ref[j]), float(w_ref[j])) if s_ref[j] > s[k] else (float(s[k]), float(mids[k]))
        )
    return gamma, w_peak, MAX_ITER


def _hinfnorm_kernel(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, tol: float
) -> tuple[float, float]:
    """:func:`hinfnorm_matrices` without the BLAS thread limit."""
    if B.shape[1] == 0 or C.shape[0] == 0:
        return 0.0, 0.0
    sigma = _SigmaMax(A, B, C, D)
    if sigma.poles.size and np.max(sigma.poles.real) >= 0:
        k = int(np.argmax(sigma.poles.real))
        return np.inf, float(abs(sigma.poles[k].imag))
    if A.shape[0] == 0:
        return float(np.linalg.norm(D, 2)), np.inf
    gamma, w_peak = _initial_bound(sigma, D)
    if gamma == 0.0:  # G = 0 at 0, infinity and every modal frequency: G is identically zero
        return 0.0, 0.0
    gamma, w_peak, _ = _level_set_iteration(_Hamiltonian(A, B, C, D), sigma, gamma, w_peak, tol)
    return float(gamma), float(w_peak)


_hinfnorm_limited = limit_blas(_hinfnorm_kernel)


def hinfnorm_matrices(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, tol: float = 1e-6
) -> tuple[float, float]:
    """H-infinity norm and peak frequency (rad/s) of a continuous-time ``(A, B, C, D)``.

    The numerical kernel of :func:`hinfnorm` (arrays in, no checks of shapes or values).
    Returns ``(inf, w)`` with ``w = |Im p|`` of the most unstable pole when ``A`` is not
    Hurwitz, and ``w = inf`` when the peak is at infinite frequency.

    Up to ``SMALL_N`` states it runs without the BLAS thread limit of
    :mod:`robustctl.threads`: its matrices (order ``2 n <= 64``) stay below OpenBLAS's size
    threshold for threaded level-3 kernels, and setting the thread pools through
    threadpoolctl costs about a millisecond, more than the whole computation.
    """
    if A.shape[0] <= SMALL_N:
        return _hinfnorm_kernel(A, B, C, D, tol)
    return _hinfnorm_limited(A, B, C, D, tol)


def discrete_to_continuous(A, B, C, D) -> tuple[np.ndarray, ...]:
    """Bilinear map ``z = (1 + s) / (1 - s)``: the same H-infinity norm, frequency ``w = tan(theta / 2)``."""
    n = A.shape[0]
    Ip = np.eye(n) + A
    Bs = np.linalg.solve(Ip, B)
    CIinv = np.linalg.solve(Ip.T, C.T).T
    Ac = np.linalg.solve(Ip, A - np.eye(n))
    return Ac, np.sqrt(2.0) * Bs, np.sqrt(2.0) * CIinv, D - C @ Bs


def continuous_to_discrete(Ac, Bc, Cc, Dc) -> tuple[np.ndarray, ...]:
    """Inverse of the bilinear map ``z = (1 + s) / (1 - s)``: ``s = (z - 1) / (z + 1)``.

    ``A = (I - Ac)^-1 (I + Ac)``, ``B = sqrt(2) (I - Ac)^-1 Bc``, ``C = sqrt(2) Cc (I - Ac)^-1``,
    ``D = Dc + Cc (I - Ac)^-1 Bc`` (Tustin's map with T = 2; the realisation inverse of
    :func:`discrete_to_continuous`). Raises ``np.linalg.LinAlgError`` for a pole at ``s = 1``.
    """
    n = Ac.shape[0]
    Im = np.eye(n) - Ac
    if n and np.linalg.cond(Im) > 1e12:
        raise np.linalg.LinAlgError("a pole at s = 1 maps to z = infinity")
    Bs = np.linalg.solve(Im, Bc)
    CIinv = np.linalg.solve(Im.T, Cc.T).T
    A = np.linalg.solve(Im, np.eye(n) + Ac)
    return A, np.sqrt(2.0) * Bs, np.sqrt(2.0) * CIinv, Dc + Cc @ Bs


def _check_tol(tol: Any) -> float:
    tol = positive_number(tol, "tol", RobustctlError)
    if tol > 0.1:
        raise RobustctlError(f"tol must be a relative tolerance in (0, 0.1]; got {tol!r}. Use e.g. tol=1e-6.")
    return tol


def hinfnorm(sys: Any, tol: float = 1e-6) -> tuple[float, float]:
    """H-infinity norm ``sup_w sigma_max(G(jw))`` and its peak frequency in Hz.

    Bruinsma & Steinbuch (1990) Hamiltonian iteration (see the module docstring), started
    from the modal peaks so that lightly damped modes (damping ratio down to ``1e-6`` and
    below) are found without a frequency grid.

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction, PhysicalModel, ...
        Anything :func:`robustctl.lti.as_statespace` accepts; continuous or discrete time
        (a discrete system needs its sampling time ``dt`` in s).
    tol : float
        Relative accuracy of the norm: the returned value ``g`` satisfies
        ``g <= ||G||_inf <= g (1 + 2 tol)`` (in practice it is accurate to about 1e-10,
        because the peak found is refined by a local search).

    Returns
    -------
    norm : float
        The H-infinity norm (``inf`` when the system is unstable: a pole with
        ``Re p >= 0``, or ``|z| >= 1`` in discrete time, to round-off: ``|z| >= 1 - 64 eps
        max(1, ||A||_1)``, as for a sampled undamped mode; uncontrollable or unobservable
        unstable modes count too).
    f_peak_hz : float
        Frequency (Hz) where ``sigma_max`` peaks (``inf`` when the peak is at infinite
        frequency, i.e. the norm is ``sigma_max(D)``; for an unstable system the frequency
        of the most unstable pole).

    Raises
    ------
    ModelError
        NaN/inf in the matrices or a discrete system without a sampling time.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> g, f_peak = rc.hinfnorm(control.tf([1], [1, 0.02, 1]))  # zeta = 0.01
    >>> round(g, 4), round(f_peak, 5)  # 1 / (2 zeta sqrt(1 - zeta^2)) at sqrt(1 - 2 zeta^2) / (2 pi) Hz
    (50.0025, 0.15914)
    """
    if type(tol) is not float or not 0.0 < tol <= 0.1:
        tol = _check_tol(tol)
    ss = as_statespace(sys, name="sys")  # checks that the matrices are finite
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    dt = ss.dt
    if dt in (0, None):
        gamma, w = hinfnorm_matrices(A, B, C, D, tol)
        return gamma, w / (2.0 * np.pi)
    if dt is True:
        raise ModelError("hinfnorm: the discrete system has no sampling time (dt=True); set dt in s.")
    dt = float(dt)
    poles = np.linalg.eigvals(A) if A.size else np.zeros(0)
    # a pole on the unit circle to round-off (a sampled undamped mode, |z| = 1 - 3e-16) is
    # on it: the norm is infinite, not the 1e14 of the bilinear map
    if poles.size and np.max(np.abs(poles)) >= 1.0 - roundoff_margin(A):
        k = int(np.argmax(np.abs(poles)))
        return np.inf, abs(float(np.angle(poles[k]))) / (2.0 * np.pi * dt)
    gamma, w = hinfnorm_matrices(*discrete_to_continuous(A, B, C, D), tol)
    theta = 2.0 * np.arctan(w) if np.isfinite(w) else np.pi
    return gamma, theta / (2.0 * np.pi * dt)
