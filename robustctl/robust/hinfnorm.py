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

* the starting lower bound is the largest singular value at the modal peaks (``|Im p|``
  and ``|p|`` of every pole), at ``w = 0`` and at ``w = inf`` (``sigma_max(D)``), and the
  best few are refined by a bounded scalar search (Brent) inside the half-power band of
  their mode, so that the first Hamiltonian test usually already certifies the norm;
* the imaginary-axis test is generous (relative tolerance ``1e-6`` plus an absolute
  ``1e-10 ||H||``; LAPACK ``geev`` balances ``H`` first): a spurious "crossing" costs one
  evaluation of ``sigma_max`` at the midpoints, which then shows no level crossing and
  ends the iteration, whereas a missed crossing would return a wrong norm;
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
import scipy.linalg

from ..checks import positive_number
from ..errors import ModelError, RobustctlError
from ..lti import (
    _blocks,
    _matrices,
    _modal_terms,
    _schur_response,
    _small_block_scaling,
    as_statespace,
)
from ..threads import limit_blas

__all__ = ["hinfnorm"]

#: Iteration cap of the Hamiltonian level-set loop (it converges quadratically, in 1-4 steps).
MAX_ITER = 40
#: Number of best candidate peaks refined by a local search before the first Hamiltonian test.
N_REFINE = 3
#: Relative and absolute (times ||H||) tolerances on |Re(lambda)| of an imaginary-axis eigenvalue.
IMAG_RTOL = 1e-6
IMAG_ATOL = 1e-10


# ---------------------------------------------------------------------------- frequency response
class _SigmaMax:
    """``w -> sigma_max(G(jw))`` for many frequencies, with the modal decomposition done once."""

    def __init__(self, A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> None:
        self.D = D
        self.evaluations = 0
        n = A.shape[0]
        self.poles = np.zeros(0, complex)
        self.lam = np.zeros(0, complex)
        self.bad: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        if n == 0 or D.size == 0:
            return
        blocks = _blocks(A)
        if max(b.shape[1] for b in blocks) <= 2:
            scale = _small_block_scaling(A, blocks)
        else:
            _, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
        Ab = A * (scale[None, :] / scale[:, None])
        Bb, Cb = B / scale[:, None], C * scale[None, :]
        self.lam, self.CV, self.W, bad = _modal_terms(Ab, Bb, Cb, blocks, io_B=B, io_C=C)
        poles = [self.lam]
        for idx in bad:
            sub = np.ix_(idx, idx)
            self.bad.append((A[sub], B[idx], C[:, idx]))
            poles.append(np.linalg.eigvals(A[sub]))
        self.poles = np.concatenate(poles)

    def response(self, w: np.ndarray) -> np.ndarray:
        """``G(jw)``, shape (n_w, p, m)."""
        s = 1j * np.asarray(w, dtype=float).reshape(-1)
        out = np.broadcast_to(self.D.astype(complex), (s.size, *self.D.shape)).copy()
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if self.lam.size:
                for start in range(0, s.size, 64):  # sum_i CV_i W_i / (s - lam_i), in frequency chunks
                    r = 1.0 / (s[start:start + 64, None] - self.lam[None, :])
                    out[start:start + 64] += (self.CV[None, :, :] * r[:, None, :]) @ self.W
            for Ak, Bk, Ck in self.bad:
                out += _schur_response(Ak, Bk, Ck, s)
        return out

    def __call__(self, w: Any) -> np.ndarray:
        w = np.atleast_1d(np.asarray(w, dtype=float))
        self.evaluations += w.size
        return _sigma_max(self.response(w))


def _sigma_max(G: np.ndarray) -> np.ndarray:
    """Largest singular value of each matrix of a stack (n, p, m), via the smaller Gram matrix.

    ``lambda_max(G^H G)`` is accurate to ``eps lambda_max``, so ``sigma_max`` is accurate to ``eps``
    relative (the small singular values, which squaring would spoil, are not needed).
    """
    if G.shape[1] == 1 or G.shape[2] == 1:
        return np.linalg.norm(G.reshape(G.shape[0], -1), axis=1)
    Gh = np.conj(np.swapaxes(G, 1, 2))
    gram = Gh @ G if G.shape[2] <= G.shape[1] else G @ Gh
    if gram.shape[1] == 2:  # closed form for 2x2 Hermitian [[a, b], [b*, c]]
        a, c, b = gram[:, 0, 0].real, gram[:, 1, 1].real, gram[:, 0, 1]
        lam = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + np.abs(b) ** 2)
    else:
        lam = np.linalg.eigvalsh(gram)[:, -1]
    return np.sqrt(np.maximum(lam, 0.0))


# ---------------------------------------------------------------------------- lower bounds
def _candidates(poles: np.ndarray) -> np.ndarray:
    """Frequencies (rad/s) of the modal peaks: ``0``, ``|Im p|`` and ``|p|`` of every pole."""
    w = np.concatenate([[0.0], np.abs(poles.imag), np.abs(poles)])
    return np.unique(w[np.isfinite(w)])


def _refine(sigma: _SigmaMax, lo: np.ndarray, hi: np.ndarray, n_grid: int = 17, n_zoom: int = 4):
    """Local maxima of ``sigma_max`` in the bands ``[lo_k, hi_k]`` (rad/s), all bands at once.

    A vectorised zoom search: ``n_grid`` points per band, then the band shrinks to the two
    grid cells around its best point, ``n_zoom`` times (a final spacing of ``16^-1 8^-(n_zoom-1)``
    of the band), then one parabolic step through the best point and its two neighbours
    (near a smooth peak the error of ``sigma_max`` is then about ``1e-14`` relative).
    Returns ``(sigma, w)``: the best value and frequency per band.
    """
    lo, hi = np.asarray(lo, dtype=float).copy(), np.asarray(hi, dtype=float).copy()
    rows = np.arange(lo.size)
    best_s, best_w = np.full(lo.size, -np.inf), 0.5 * (lo + hi)
    t = np.linspace(0.0, 1.0, n_grid)
    for _ in range(n_zoom):
        w = lo[:, None] + (hi - lo)[:, None] * t[None, :]
        s = sigma(w.ravel()).reshape(w.shape)
        k = np.argmax(s, axis=1)
        better = s[rows, k] > best_s
        best_s = np.where(better, s[rows, k], best_s)
        best_w = np.where(better, w[rows, k], best_w)
        step = (hi - lo) / (n_grid - 1)
        lo, hi = np.maximum(lo, best_w - step), np.minimum(hi, best_w + step)
    inner = (k > 0) & (k < n_grid - 1)
    if np.any(inner):  # parabola through the last grid's best point and its neighbours
        r, kk = rows[inner], k[inner]
        s0, sm, sp = s[r, kk], s[r, kk - 1], s[r, kk + 1]
        h = w[r, 1] - w[r, 0]
        curv = sm - 2.0 * s0 + sp
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(curv < 0, 0.5 * h * (sm - sp) / curv, 0.0)
        w_vertex = w[r, kk] + np.clip(shift, -h, h)
        s_vertex = sigma(w_vertex)
        better = s_vertex > best_s[r]
        best_s[r[better]], best_w[r[better]] = s_vertex[better], w_vertex[better]
    return best_s, best_w


def _pole_bands(w: np.ndarray, poles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Search bands around the frequencies ``w`` (rad/s): a few half-power bandwidths of the nearest pole."""
    if poles.size == 0:
        return w.copy(), w.copy()
    k = np.argmin(np.abs(np.abs(poles.imag)[None, :] - w[:, None]), axis=1)
    half = np.maximum(4.0 * np.abs(poles[k].real), 1e-3 * w)
    return np.maximum(0.0, w - half), w + half


def _initial_bound(sigma: _SigmaMax, D: np.ndarray) -> tuple[float, float]:
    """Lower bound ``(gamma_lb, w_peak)`` from the modal peaks, 0 and infinity, locally refined."""
    gamma, w_peak = (float(np.linalg.norm(D, 2)) if D.size else 0.0), np.inf
    w = _candidates(sigma.poles)
    s = sigma(w)
    top = np.argsort(s)[::-1][:N_REFINE]
    if s[top[0]] > gamma:
        gamma, w_peak = float(s[top[0]]), float(w[top[0]])
    lo, hi = _pole_bands(w[top], sigma.poles)
    s_ref, w_ref = _refine(sigma, lo, hi)
    k = int(np.argmax(s_ref))
    if s_ref[k] > gamma:
        gamma, w_peak = float(s_ref[k]), float(w_ref[k])
    return gamma, w_peak


# ---------------------------------------------------------------------------- Hamiltonian test
def hamiltonian(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, gamma: float) -> np.ndarray:
    """The Hamiltonian ``H(gamma)`` of the module docstring (BBK 1989, Theorem 1).

    ``gamma`` must exceed ``sigma_max(D)``.
    """
    m, p = B.shape[1], C.shape[0]
    R = gamma**2 * np.eye(m) - D.T @ D
    S = gamma**2 * np.eye(p) - D @ D.T
    RinvDtC = np.linalg.solve(R, D.T @ C)
    Ah = A + B @ RinvDtC
    top = np.hstack([Ah, gamma * B @ np.linalg.solve(R, B.T)])
    bottom = np.hstack([-gamma * C.T @ np.linalg.solve(S, C), -Ah.T])
    return np.vstack([top, bottom])


def imaginary_axis_frequencies(H: np.ndarray) -> np.ndarray:
    """Sorted non-negative frequencies ``w`` (rad/s) of the eigenvalues of ``H`` near ``jw``.

    An eigenvalue counts as imaginary when ``|Re lambda| <= IMAG_RTOL |lambda| + IMAG_ATOL ||H||_1``
    (a generous test; see the module docstring for why).
    """
    ev = scipy.linalg.eigvals(H, overwrite_a=True, check_finite=False)
    scale = float(np.abs(H).sum(axis=0).max()) if H.size else 0.0
    on_axis = np.abs(ev.real) <= IMAG_RTOL * np.abs(ev) + IMAG_ATOL * scale
    return np.unique(np.abs(ev[on_axis].imag))


# ---------------------------------------------------------------------------- the iteration
def _level_set_iteration(
    A: np.ndarray,
    B: np.ndarray,
    C: np.ndarray,
    D: np.ndarray,
    sigma: _SigmaMax,
    gamma: float,
    w_peak: float,
    tol: float,
) -> tuple[float, float, int]:
    """Bruinsma-Steinbuch (1990) iteration from the lower bound ``gamma``; returns (norm, w_peak, steps)."""
    for step in range(1, MAX_ITER + 1):
        level = gamma * (1.0 + 2.0 * tol)
        w_cross = imaginary_axis_frequencies(hamiltonian(A, B, C, D, level))
        if w_cross.size == 0:
            return gamma, w_peak, step
        edges = np.unique(np.concatenate([[0.0], w_cross]))
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


@limit_blas
def hinfnorm_matrices(
    A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, tol: float = 1e-6
) -> tuple[float, float]:
    """H-infinity norm and peak frequency (rad/s) of a continuous-time ``(A, B, C, D)``.

    The numerical kernel of :func:`hinfnorm` (arrays in, no checks of shapes or values).
    Returns ``(inf, w)`` with ``w = |Im p|`` of the most unstable pole when ``A`` is not
    Hurwitz, and ``w = inf`` when the peak is at infinite frequency.
    """
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
    gamma, w_peak, _ = _level_set_iteration(A, B, C, D, sigma, gamma, w_peak, tol)
    return float(gamma), float(w_peak)


def _discrete_to_continuous(A, B, C, D) -> tuple[np.ndarray, ...]:
    """Bilinear map ``z = (1 + s) / (1 - s)``: the same H-infinity norm, frequency ``w = tan(theta / 2)``."""
    n = A.shape[0]
    Ip = np.eye(n) + A
    Bs = np.linalg.solve(Ip, B)
    CIinv = np.linalg.solve(Ip.T, C.T).T
    Ac = np.linalg.solve(Ip, A - np.eye(n))
    return Ac, np.sqrt(2.0) * Bs, np.sqrt(2.0) * CIinv, D - C @ Bs


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
        ``Re p >= 0``, or ``|z| >= 1`` in discrete time; uncontrollable or unobservable
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
    tol = _check_tol(tol)
    ss = as_statespace(sys, name="sys")
    A, B, C, D = _matrices(ss)
    dt = ss.dt
    if dt in (0, None):
        gamma, w = hinfnorm_matrices(A, B, C, D, tol)
        return gamma, w / (2.0 * np.pi)
    if dt is True:
        raise ModelError("hinfnorm: the discrete system has no sampling time (dt=True); set dt in s.")
    dt = float(dt)
    poles = np.linalg.eigvals(A) if A.size else np.zeros(0)
    if poles.size and np.max(np.abs(poles)) >= 1.0:
        k = int(np.argmax(np.abs(poles)))
        return np.inf, abs(float(np.angle(poles[k]))) / (2.0 * np.pi * dt)
    gamma, w = hinfnorm_matrices(*_discrete_to_continuous(A, B, C, D), tol)
    theta = 2.0 * np.arctan(w) if np.isfinite(w) else np.pi
    return gamma, theta / (2.0 * np.pi * dt)
