"""Fast frequency responses, conversions to python-control, the complex-log kernel.

All FRF arrays have the shape (n_freq, n_out, n_in); surface frequencies are in Hz,
s-domain math in rad/s.

The frequency response ``G(s) = C (sI - A)^{-1} B + D`` is evaluated block by block:

* ``A`` is split into the decoupled diagonal blocks of its sparsity pattern (a modal,
  block-diagonal ``A`` splits into its 1x1 and 2x2 modes; a dense ``A`` is one block) and
  balanced by a diagonal similarity (LAPACK ``gebal``; for 1x1/2x2 blocks the closed form
  ``|a12| = |a21|``);
* a block whose eigenvector matrix is well conditioned is diagonalised,
  ``C_k (sI - A_k)^{-1} B_k = (C_k V) diag(1 / (s - lambda)) (V^{-1} B_k)``, and all such
  blocks are summed in one matrix product over every frequency (O(n) per frequency and
  channel);
* a defective or nearly defective block (condition number of ``V`` above
  ``COND_LIMIT``, or modal residues much larger than the block's input/output gains,
  ``GROWTH_LIMIT``, whose cancellation would cost accuracy) uses the complex Schur form
  of the unbalanced block, ``A_k = Z T Z^H``, and a triangular solve vectorised over
  frequencies (O(n^2) per frequency), which is backward stable.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import control
import numpy as np

from .checks import match_channels
from .errors import DataError, FitError, ModelError
from .frd import FrequencyData, as_frequencies
from .threads import limit_blas

_EPS = float(np.finfo(float).eps)

__all__ = [
    "freqresp",
    "freqresp_array",
    "as_statespace",
    "statespace_state",
    "rebuild_statespace",
    "log_ratio",
    "DB_PER_NEPER",
    "pole_frequency_damping",
    "zpk_statespace",
    "is_stable",
    "zoh",
    "spectral_abscissa",
    "roundoff_margin",
]

#: dB per neper, ``20 / ln 10``: the real part of :func:`log_ratio` (nepers) times this is
#: the log-magnitude error in dB.
DB_PER_NEPER = 20.0 / np.log(10.0)

#: Smallest magnitude used in a log ratio, so an exact zero gives a large finite error.
_TINY = 1e-300


def log_ratio(g_data: np.ndarray, g_model: np.ndarray) -> np.ndarray:
    """Complex log error ``log(G_data / G_model)`` (MACE eq. 5), elementwise on arrays.

    The one kernel behind every complex-log error in robustctl (correlate's residual,
    identify's scores, :func:`robustctl.cost.log_error`).

    Parameters
    ----------
    g_data, g_model : ndarray, complex
        Responses of equal (or broadcastable) shape, in matching units.

    Returns
    -------
    ndarray, complex
        Real part ``ln|G_data| - ln|G_model|`` (nepers; x 20/ln 10 for dB); imaginary part the
        phase error in rad, wrapped to (-pi, pi]. Magnitudes are floored at 1e-300.
    """
    mag_d = np.maximum(np.abs(g_data), _TINY)
    mag_m = np.maximum(np.abs(g_model), _TINY)
    return (np.log(mag_d) - np.log(mag_m)) + 1j * np.angle(g_data * np.conj(g_model))


def pole_frequency_damping(poles: Any) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequency and damping ratio of continuous-time poles.

    ``f_hz = |p| / (2 pi)`` and ``zeta = -Re p / |p|`` (``p = -zeta w_n + j w_n sqrt(1 - zeta^2)``).

    Parameters
    ----------
    poles : array_like, complex
        Poles in rad/s, any shape.

    Returns
    -------
    f_hz : ndarray
        Natural frequency of each pole, Hz.
    zeta : ndarray
        Damping ratio of each pole (ratio, not %); 0 for a pole at the origin.
    """
    p = np.asarray(poles, dtype=complex)
    mag = np.abs(p)
    return mag / (2 * np.pi), -p.real / np.maximum(mag, np.finfo(float).tiny)


#: eigenvector condition number above which a block is treated as (nearly) defective
COND_LIMIT = 1e6
#: modal residue growth (relative to the block's I/O gains) above which a block is not diagonalised
GROWTH_LIMIT = 1e4
#: Largest single dense block diagonalised with an explicit inverse of its eigenvectors.
DENSE_INV_MAX = 64


# ---------------------------------------------------------------------------- conversions
def _as_statespace(sys: Any, name: str = "sys"):
    try:
        ss = control.ss(sys)
    except Exception as exc:  # python-control raises several types
        raise ModelError(
            f"{name}: cannot convert {type(sys).__name__} to a state space ({exc}); pass a "
            "control.StateSpace, a transfer function or a robustctl PhysicalModel."
        ) from exc
    if not isinstance(ss, control.StateSpace):  # control.ss(None) gives a NonlinearIOSystem
        raise ModelError(
            f"{name}: cannot convert {sys!r} to a state space; pass a control.StateSpace, a transfer "
            "function or a robustctl PhysicalModel."
        )
    return ss


def as_statespace(
    sys: Any, inputs: Sequence[str] | None = None, outputs: Sequence[str] | None = None, *, name: str = "sys"
):
    """``sys`` as a ``control.StateSpace`` with named signals: the one system coercion.

    Parameters
    ----------
    sys : system
        A ``control.StateSpace`` (returned as is), anything with a ``.statespace()`` method
        (PhysicalModel, MeasurementModel, RationalFit, BalancedTruncation), or anything
        ``control.ss`` converts (a transfer function, a ``(A, B, C, D)`` tuple).
    inputs, outputs : sequence of str, optional
        New signal names (one per input / output); default: keep the system's names.
    name : str
        What the caller calls ``sys`` (its argument name), used in error messages.

    Returns
    -------
    control.StateSpace

    Raises
    ------
    ModelError
        ``sys`` is measured data (FrequencyData), cannot be converted, or has NaN/inf in its
        matrices; names that are not one distinct non-empty string per signal.
    """
    if isinstance(sys, FrequencyData) or type(sys).__name__ == "FrequencyResponseData":
        raise ModelError(
            f"{name} is a {type(sys).__name__}, which is measured data, not a model; it has no state space. "
            "Pass a "
            "PhysicalModel, MeasurementModel, control.StateSpace or transfer function."
        )
    if isinstance(sys, control.StateSpace):
        ss = sys
    elif hasattr(sys, "statespace") and callable(sys.statespace):
        ss = _as_statespace(sys.statespace(), name)
    else:
        ss = _as_statespace(sys, name)
    if not all(np.isfinite(np.asarray(m, dtype=float)).all() for m in (ss.A, ss.B, ss.C, ss.D)):
        raise ModelError(f"{name} has NaN or inf in its state-space matrices; check the model's parameters.")
    if inputs is None and outputs is None:
        return ss
    ins = list(ss.input_labels) if inputs is None else _names(inputs, ss.ninputs, "inputs")
    outs = list(ss.output_labels) if outputs is None else _names(outputs, ss.noutputs, "outputs")
    return control.ss(ss.A, ss.B, ss.C, ss.D, ss.dt, inputs=ins, outputs=outs, states=ss.state_labels)


def statespace_state(ss: Any) -> dict:
    """A picklable description of a ``control.StateSpace``: matrices, dt and signal names.

    python-control 0.10's StateSpace holds a lambda and does not pickle; results store this
    and rebuild with :func:`rebuild_statespace`.
    """
    return {
        "A": np.asarray(ss.A), "B": np.asarray(ss.B), "C": np.asarray(ss.C), "D": np.asarray(ss.D),
        "dt": ss.dt, "inputs": list(ss.input_labels), "outputs": list(ss.output_labels),
        "states": list(ss.state_labels), "name": ss.name,
    }


def rebuild_statespace(state: dict):
    """The ``control.StateSpace`` described by :func:`statespace_state`."""
    return control.ss(
        state["A"], state["B"], state["C"], state["D"], state["dt"], inputs=state["inputs"],
        outputs=state["outputs"], states=state["states"], name=state["name"],
    )


def _names(names: Sequence[str] | str, count: int, what: str) -> list[str]:
    names = [names] if isinstance(names, str) else names
    names = names.tolist() if isinstance(names, np.ndarray) else names
    if isinstance(names, (bytes, dict)) or not isinstance(names, Sequence):
        raise ModelError(f"{what} must be a list of {count} signal names (str); got {names!r}.")
    if not all(isinstance(n, str) and n and "\x00" not in n for n in names):
        raise ModelError(f"{what} must be non-empty strings (no NUL characters); got {list(names)!r}.")
    if len(names) != count or len(set(names)) != count:
        raise ModelError(f"give {count} distinct {what} names; got {list(names)}.")
    return list(names)


# ---------------------------------------------------------------------------- kernel
def schur_blocks(A: np.ndarray) -> list[np.ndarray]:
    """The decoupled diagonal blocks of ``A`` (connected components of its sparsity graph).

    Returned batched by size: a list of integer arrays of shape (n_blocks, block_size).
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    n = A.shape[0]
    nnz = np.count_nonzero(A)
    if n <= 2 or nnz == n * n:  # tiny or fully dense: one block
        return [np.arange(n)[None, :]]
    upper, lower = np.diagonal(A, 1) != 0, np.diagonal(A, -1) != 0
    band_nnz = np.count_nonzero(np.diagonal(A)) + np.count_nonzero(upper) + np.count_nonzero(lower)
    if nnz == band_nnz:  # tridiagonal (e.g. a modal form): contiguous blocks, O(n)
        starts = np.concatenate([[0], np.flatnonzero(~(upper | lower)) + 1])
        sizes = np.diff(np.concatenate([starts, [n]]))
        return [starts[sizes == k][:, None] + np.arange(k)[None, :] for k in np.unique(sizes)]
    nz = A != 0
    n_comp, labels = connected_components(csr_matrix(nz | nz.T), directed=False)
    if n_comp == 1:
        return [np.arange(n)[None, :]]
    order = np.argsort(labels, kind="stable")
    comps = np.split(order, np.flatnonzero(np.diff(labels[order])) + 1)
    by_size: dict[int, list[np.ndarray]] = {}
    for idx in comps:
        by_size.setdefault(idx.size, []).append(idx)
    return [np.array(group) for group in by_size.values()]


def small_block_scaling(A: np.ndarray, blocks: list[np.ndarray]) -> np.ndarray:
    """Diagonal scaling that balances every 2x2 block: ``|a12| = |a21|`` (the gebal goal, in closed form)."""
    scale = np.ones(A.shape[0])
    for idx in blocks:
        if idx.shape[1] == 2:
            b, c = np.abs(A[idx[:, 0], idx[:, 1]]), np.abs(A[idx[:, 1], idx[:, 0]])
            both = (b > 0) & (c > 0)
            scale[idx[both, 1]] = np.sqrt(c[both] / b[both])
    return scale


def _solve_with_cond(V: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, float]:
    """``V^{-1} B`` and the 1-norm condition number of ``V`` (inf when singular)."""
    from scipy.linalg import lapack, lu_factor, lu_solve

    anorm = np.abs(V).sum(axis=0).max()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # singular V: reported through the condition number
        lu, piv = lu_factor(V, check_finite=False)
    rcond, info = lapack.zgecon(lu, anorm)
    if info != 0 or not rcond > 0:
        return np.zeros((V.shape[0], B.shape[1]), complex), np.inf
    return lu_solve((lu, piv), B.astype(complex), check_finite=False), 1.0 / rcond


def _batched_inv_solve(V: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``V_k^{-1} B_k`` and the 1-norm condition numbers of a stack of small matrices."""
    try:
        Vinv = np.linalg.inv(V)
    except np.linalg.LinAlgError:  # one of them is singular: do them one by one
        out = [_solve_with_cond(v, b) for v, b in zip(V, B)]
        return np.array([o[0] for o in out]), np.array([o[1] for o in out])
    cond = np.abs(V).sum(axis=1).max(axis=1) * np.abs(Vinv).sum(axis=1).max(axis=1)
    cond[~np.isfinite(cond)] = np.inf
    return Vinv @ B, cond


def modal_terms(A: np.ndarray, B: np.ndarray, C: np.ndarray, blocks: list[np.ndarray], io_B=None, io_C=None):
    """Eigen-decompose the blocks, batched by size.

    A block is diagonalised only when its eigenvector matrix is well conditioned
    (``cond_1(V) <= COND_LIMIT``) and its modal residues do not grow far beyond its
    input/output gains (``sum_i |C v_i| |w_i B| <= GROWTH_LIMIT |C_k| |B_k|``, measured with
    ``io_B``/``io_C``, the unbalanced matrices): large residues of opposite sign cancel and
    cost relative accuracy, as for nearly defective blocks.

    Returns ``(lam, CV, W, bad)``: eigenvalues, ``C V`` columns and ``V^{-1} B`` rows of the
    well-conditioned blocks, and the index arrays of the other blocks.
    """
    io_B = B if io_B is None else io_B
    io_C = C if io_C is None else io_C
    if len(blocks) == 1 and blocks[0].shape[0] == 1 and A.shape[0] <= DENSE_INV_MAX:
        return _modal_terms_dense(A, B, C, io_B, io_C)
    lam, cv, w, bad = [], [], [], []
    for idx in blocks:  # idx: (n_blocks, k)
        full = idx.shape == (1, A.shape[0])
        Ak = A[None] if full else A[idx[:, :, None], idx[:, None, :]]
        ev, V = np.linalg.eig(Ak)
        if idx.shape[1] > 32:  # one large block: LU once, condition number from LAPACK gecon
            W, cond = _solve_with_cond(V[0], B[idx[0]])
            W, cond = W[None], np.array([cond])
        else:
            W, cond = _batched_inv_solve(V, B[idx])
        CVb = np.einsum("pbk,bkj->bpj", C[:, idx], V)  # (nb, p, k)
        residues = (np.linalg.norm(CVb, axis=1) * np.linalg.norm(W, axis=2)).sum(axis=1)
        gains = np.linalg.norm(io_C[:, idx], axis=(0, 2)) * np.linalg.norm(io_B[idx], axis=(1, 2))
        with np.errstate(divide="ignore", invalid="ignore"):
            growth = np.where(residues > 0, residues / gains, 0.0)
        ok = (cond <= COND_LIMIT) & (growth <= GROWTH_LIMIT)
        bad.extend(idx[~ok])
        if np.any(ok):
            lam.append(ev[ok].reshape(-1))
            cv.append(np.transpose(CVb[ok], (1, 0, 2)).reshape(C.shape[0], -1))
            w.append(W[ok].reshape(-1, B.shape[1]))
    if lam:
        return np.concatenate(lam), np.concatenate(cv, axis=1), np.concatenate(w, axis=0), bad
    return np.zeros(0, complex), np.zeros((C.shape[0], 0), complex), np.zeros((0, B.shape[1]), complex), bad


def _modal_terms_dense(A: np.ndarray, B: np.ndarray, C: np.ndarray, io_B: np.ndarray, io_C: np.ndarray):
    """:func:`modal_terms` for one dense block of order <= ``DENSE_INV_MAX``, without the
    batching (same tests), in real arithmetic as far as possible.

    LAPACK ``dgeev`` returns the real eigenvector matrix ``X`` whose column pairs
    ``(x, y)`` hold ``v = x + j y`` for ``lambda = a + j b`` (and ``conj(v)`` for
    ``conj(lambda)``); ``X`` brings ``A`` to the real block-diagonal form with blocks
    ``[[a, b], [-b, a]]``, so ``V^{-1}`` follows from the real ``X^{-1}`` (rows ``r1, r2``):
    the left eigenvector of ``lambda`` is ``(r1 - j r2) / 2``. ``X^{-1} B`` and ``C X`` are
    real products, and the condition number is that of ``X`` (within a factor 2 of that of
    ``V``: the two differ by a scaled unitary 2x2 change of basis per pair).
    """
    from scipy.linalg import lapack

    wr, wi, _, X, info = lapack.dgeev(A, compute_vl=0)
    if info == 0:
        lu, piv, info = lapack.dgetrf(X)
    if info == 0:
        Xinv, info = lapack.dgetri(lu, piv)
    if info == 0:
        cond = np.abs(X).sum(axis=0).max() * np.abs(Xinv).sum(axis=0).max()
        CX, WX = C @ X, Xinv @ B
        CV, W = CX.astype(complex), WX.astype(complex)
        pos = np.flatnonzero(wi > 0)  # the first column of each pair (LAPACK: positive imaginary part first)
        if pos.size:
            CV[:, pos] += 1j * CX[:, pos + 1]
            CV[:, pos + 1] = CV[:, pos].conj()
            W[pos] = 0.5 * (WX[pos] - 1j * WX[pos + 1])
            W[pos + 1] = W[pos].conj()
        residues = float(np.sqrt(abs2(CV).sum(axis=0) * abs2(W).sum(axis=1)).sum())
        gains = float(np.sqrt(np.vdot(io_C, io_C) * np.vdot(io_B, io_B)))
        growth = residues / gains if residues > 0 else 0.0
        if cond <= COND_LIMIT and growth <= GROWTH_LIMIT:
            return wr + 1j * wi, CV, W, []
    empty = np.zeros(0, complex), np.zeros((C.shape[0], 0), complex), np.zeros((0, B.shape[1]), complex)
    return (*empty, [np.arange(A.shape[0])])


def abs2(z: np.ndarray) -> np.ndarray:
    """``|z|^2`` of a complex array (no square root)."""
    return z.real * z.real + z.imag * z.imag


def _diag_response(lam: np.ndarray, CV: np.ndarray, W: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``sum_i CV[:, i] W[i, :] / (s - lam_i)`` at every point s, as matrix products.

    On the imaginary axis (continuous systems) conjugate pairs are combined into real
    second-order terms ``(2 Re(r) s - 2 Re(r conj(lam))) / (s^2 - 2 Re(lam) s + |lam|^2)``
    evaluated in real arithmetic, which halves the work and keeps the sum exactly real-symmetric.
    """
    p, m = CV.shape[0], W.shape[1]
    res = (CV.T[:, :, None] * W[:, None, :]).reshape(lam.size, p * m)  # residues r_i
    if np.any(s.real != 0):
        return ((1.0 / (s[:, None] - lam[None, :])) @ res).reshape(s.size, p, m)
    w = s.imag[:, None]
    g_re = np.zeros((s.size, p * m))
    g_im = np.zeros((s.size, p * m))
    real = lam.imag == 0
    if np.any(real):  # r / (j w - l) = r (-l - j w) / (l^2 + w^2)
        lr, rr = lam.real[real], res[real].real
        q = 1.0 / (lr[None, :] ** 2 + w**2)
        g_re += (q * -lr[None, :]) @ rr
        g_im -= w * (q @ rr)
    pos = lam.imag > 0
    if np.any(pos):
        pr, pi = _pair_terms(lam[pos], res[pos], s.imag)
        g_re += pr
        g_im += pi
    return (g_re + 1j * g_im).reshape(s.size, p, m)


#: Entries (frequencies x pairs) of each work buffer of :func:`_pair_terms`: four of them stay
#: in a core's L2 cache, and the GEMMs stay below the size where a threaded BLAS splits them
#: (256 frequencies at 200 pairs: 17 ms for 2,000 frequencies and 3x3 channels where 100 pairs
#: took 3 ms; at this size the time grows linearly with the pairs).
PAIR_CHUNK_ENTRIES = 16384


def _pair_terms(lp: np.ndarray, rp: np.ndarray, w: np.ndarray, chunk: int | None = None):
    """Real and imaginary parts of ``sum_k (A_k j w + B_k) / (|l_k|^2 - w^2 - 2 j Re(l_k) w)``.

    The conjugate pair (l, conj l) with residue r gives ``A = 2 Re r`` and
    ``B = -2 Re(r conj l)``. Evaluated in frequency chunks with preallocated buffers
    (:data:`PAIR_CHUNK_ENTRIES` per buffer by default), in real arithmetic: eight passes over
    (chunk x pairs) plus two GEMMs. The relative rounding error near a resonance is about
    eps / (2 zeta), zeta the mode's damping.
    """
    n_pairs, pm = rp.shape
    if chunk is None:
        chunk = max(16, min(256, PAIR_CHUNK_ENTRIES // max(n_pairs, 1)))
    Ar = 2.0 * rp.real
    Br = -2.0 * (rp * lp.conj()[:, None]).real
    BA = np.concatenate([Br, Ar], axis=1)  # (pairs, 2 pm)
    mod2, sig2 = np.abs(lp) ** 2, -2.0 * lp.real
    g_re, g_im = np.empty((w.size, pm)), np.empty((w.size, pm))
    a, b, q, t = (np.empty((min(chunk, w.size), n_pairs)) for _ in range(4))
    for start in range(0, w.size, chunk):
        wc = w[start : start + chunk, None]
        n = wc.shape[0]
        a_, b_, q_, t_ = a[:n], b[:n], q[:n], t[:n]
        np.subtract(mod2, wc * wc, out=a_)  # Re(den); rounding eps w^2 is eps / (2 zeta) of |den|
        np.multiply(wc, sig2, out=b_)  # Im(den) = -2 Re(l) w
        np.multiply(a_, a_, out=q_)
        np.multiply(b_, b_, out=t_)
        q_ += t_
        np.reciprocal(q_, out=q_)
        a_ *= q_  # Re(1/den)
        b_ *= q_  # -Im(1/den)   (den = a + j b)
        X, Y = a_ @ BA, b_ @ BA  # [a B, a A], [b B, b A]
        g_re[start : start + n] = X[:, :pm] + wc * Y[:, pm:]
        g_im[start : start + n] = wc * X[:, pm:] - Y[:, :pm]
    return g_re, g_im


def schur_factors(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple:
    """What :func:`schur_eval` needs of ``(A, B, C)``: the complex Schur form ``A = Z T Z^H``
    with ``Z^H B`` and ``C Z``, computed once (on the transposed system when ``C`` has fewer
    rows than ``B`` has columns, so that the back-substitution carries fewer columns)."""
    from scipy.linalg import schur

    transposed = C.shape[0] < B.shape[1]
    if transposed:
        A, B, C = A.T, C.T, B.T
    T, Z = schur(A.astype(complex), output="complex")
    return T, Z.conj().T @ B, C @ Z, transposed


def schur_eval(factors: tuple, s: np.ndarray) -> np.ndarray:
    """``C (sI - A)^{-1} B`` at the points ``s`` from :func:`schur_factors`, by a
    frequency-vectorised back-substitution in the triangular ``T``; shape (n_s, p, m)."""
    T, Bz, CZ, transposed = factors
    n = T.shape[0]
    X = np.empty((s.size, n, Bz.shape[1]), dtype=complex)
    if s.size < n:  # few points, a large block: one LAPACK triangular solve per point
        from scipy.linalg.lapack import ztrtrs

        M = np.asfortranarray(-T)
        d = np.diag(T)
        for k, sk in enumerate(s):
            M[np.diag_indices(n)] = sk - d
            X[k], _ = ztrtrs(M, Bz)
    else:  # many points: a back-substitution vectorised over them, one row at a time
        diag = s[:, None] - np.diag(T)[None, :]
        for i in range(n - 1, -1, -1):  # (sI - T) X = Bz, upper triangular
            rhs = Bz[i][None, :] + np.einsum("j,fjm->fm", T[i, i + 1 :], X[:, i + 1 :, :])
            X[:, i, :] = rhs / diag[:, i : i + 1]
    out = np.einsum("pj,fjm->fpm", CZ, X)
    return np.transpose(out, (0, 2, 1)) if transposed else out


def _schur_response(A: np.ndarray, B: np.ndarray, C: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``C (sI - A)^{-1} B`` via the complex Schur form and a frequency-vectorised back-substitution."""
    return schur_eval(schur_factors(A, B, C), s)


@limit_blas
def _response(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``C (sI - A)^{-1} B + D`` at complex points ``s`` (rad/s or z), shape (n_s, p, m)."""
    from scipy.linalg import matrix_balance

    p, m = D.shape
    out = np.broadcast_to(D.astype(complex), (s.size, p, m)).copy()
    if A.shape[0] == 0 or p == 0 or m == 0:
        return out
    blocks = schur_blocks(A)  # the sparsity pattern does not change under diagonal scaling
    if max(b.shape[1] for b in blocks) <= 2:
        scale = small_block_scaling(A, blocks)
    else:
        _, (scale, _) = matrix_balance(A, permute=False, separate=True)
    Ab = A * (scale[None, :] / scale[:, None])  # D^-1 A D, D = diag(scale)
    Bb, Cb = B / scale[:, None], C * scale[None, :]
    lam, CV, W, bad = modal_terms(Ab, Bb, Cb, blocks, io_B=B, io_C=C)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if lam.size:
            out += _diag_response(lam, CV, W, s)
        for idx in bad:  # the Schur form of the unbalanced block keeps small entries accurate
            out += _schur_response(A[np.ix_(idx, idx)], B[idx], C[:, idx], s)
    finite = np.all(np.isfinite(out), axis=(1, 2))
    if not np.all(finite):
        k = int(np.flatnonzero(~finite)[0])
        gap = float(np.min(np.abs(np.linalg.eigvals(A) - s[k])))
        if gap > 1e-8 * max(1.0, abs(s[k])):  # no pole there: the arithmetic overflowed
            raise ModelError(
                f"the response at s = {s[k]:.6g} (point {k}) overflows the floating-point range; "
                "the frequency is far beyond the model's dynamics. Evaluate at frequencies in a "
                "physical range."
            )
        raise ModelError(
            f"the system has a pole at s = {s[k]:.6g} on the frequency grid (point {k}); "
            "the response is infinite there. Evaluate at other frequencies."
        )
    return out


def _evaluation_points(ss: Any, f: np.ndarray) -> np.ndarray:
    """s = j 2 pi f for continuous systems, z = exp(j 2 pi f dt) for sampled ones."""
    dt = ss.dt
    if dt is True:
        raise ModelError("the system is discrete with an unspecified sampling time (dt=True); set dt in s.")
    w = 2.0 * np.pi * f
    if dt in (0, None):
        return 1j * w
    return np.exp(1j * w * float(dt))


def _matrices(ss: Any) -> tuple[np.ndarray, ...]:
    mats = tuple(np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    if not all(np.all(np.isfinite(m)) for m in mats):
        raise ModelError("the state-space matrices contain NaN or inf; check the model's parameters.")
    return mats


def freqresp_array(sys: Any, f_hz: Any) -> np.ndarray:
    """The frequency response as a bare array of shape (n_freq, n_out, n_in).

    Like :func:`freqresp` but without building a FrequencyData, and ``f_hz`` may be any
    finite frequencies in Hz (zero, negative or unsorted included).
    """
    ss = as_statespace(sys)
    f = np.asarray(f_hz, dtype=float).reshape(-1)
    if not np.all(np.isfinite(f)):
        raise DataError("f_hz contains NaN or inf; frequencies must be finite numbers in Hz.")
    return _response(*_matrices(ss), _evaluation_points(ss, f))


def freqresp(sys: Any, f_hz: Any) -> FrequencyData:
    """Frequency response ``G(j 2 pi f) = C (j 2 pi f I - A)^{-1} B + D`` as FrequencyData.

    Parameters
    ----------
    sys : control.StateSpace, PhysicalModel, or anything ``control.ss`` converts
        Continuous (s in rad/s) or sampled (z = exp(j 2 pi f dt)) system.
    f_hz : array_like
        Frequencies in Hz, positive and strictly increasing.

    Returns
    -------
    FrequencyData
        With the system's input and output names.

    Notes
    -----
    Diagonalises (balanced) ``A`` block by block when its eigenvectors are well
    conditioned (O(n) per frequency and channel); defective or nearly defective blocks use
    the complex Schur form (O(n^2) per frequency). See the module docstring.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> g = rc.freqresp(control.tf([1], [1, 0.2, 1]), [0.1, 0.159, 1.0])
    """
    ss = as_statespace(sys)
    f = as_frequencies(f_hz)
    g = _response(*_matrices(ss), _evaluation_points(ss, f))
    return FrequencyData(f, g, inputs=list(ss.input_labels), outputs=list(ss.output_labels))


# ---------------------------------------------------------------------------- log error
def align_channels(data: FrequencyData, model: FrequencyData) -> FrequencyData:
    """``model`` with its channels in ``data``'s order (:func:`robustctl.checks.match_channels`)."""
    out_idx = match_channels(model.outputs, data.outputs, "outputs")
    in_idx = match_channels(model.inputs, data.inputs, "inputs")
    g = model.response[:, out_idx][:, :, in_idx]
    return model.replace(response=g, outputs=data.outputs, inputs=data.inputs, coherence=None)


# ---------------------------------------------------------------------------- sampling
def zoh(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of ``x' = A x + B u`` with sample time ``dt``.

    ``expm([[A, B], [0, 0]] dt) = [[Ad, Bd], [0, I]]`` (Franklin, Powell & Workman, *Digital
    Control of Dynamic Systems*, 3rd ed., sec. 4.3.3; Van Loan 1978): ``x[k+1] = Ad x[k] + Bd u[k]``
    for an input held constant over each sample. The one ZOH of robustctl (simulated
    experiments, the estimator's sampled impulse response, controller export).

    Parameters
    ----------
    A : ndarray (n, n)
        State matrix, rad/s.
    B : ndarray (n, m)
        Input matrix.
    dt : float
        Sample time, s.

    Returns
    -------
    Ad : ndarray (n, n)
    Bd : ndarray (n, m)
    """
    from scipy.linalg import expm

    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n] = A * dt
    M[:n, n:] = B * dt
    E = expm(M)
    return E[:n, :n], E[:n, n:]


# ---------------------------------------------------------------------------- stability
def spectral_abscissa(sys: Any) -> float:
    """The largest real part of the poles of a continuous system, rad/s; ``-inf`` without states.

    Parameters
    ----------
    sys : system with an ``A`` matrix, or a square array_like ``A``
        A continuous-time state space (``control.StateSpace`` or anything with ``A``) or its
        state matrix. Not coerced: inner code passes what it built.

    Returns
    -------
    float
        ``max Re eig(A)``; NaN when ``A`` holds NaN or inf (no eigenvalues to speak of).
    """
    A = np.asarray(getattr(sys, "A", sys))
    if A.size == 0:
        return -np.inf
    if not np.all(np.isfinite(A)):
        return np.nan
    return float(np.max(np.linalg.eigvals(A).real))


def is_stable(sys: Any, margin: float = 0.0, *, dt: Any = None) -> bool:
    """True when every pole lies inside the stability region by ``margin``.

    The one stability test of robustctl: continuous time ``max Re eig(A) < -margin``;
    discrete time (a system with ``dt`` set, or an array ``A`` with ``dt`` given)
    ``max |eig(A)| < 1 - margin``. Strict; a system without states is stable. Each caller
    passes its tolerance explicitly (:func:`roundoff_margin` for "beyond round-off").

    Parameters
    ----------
    sys : system with an ``A`` matrix, or a square array_like ``A``
        See :func:`spectral_abscissa`.
    margin : float
        Required distance of the poles from the imaginary axis, rad/s (0: open left half
        plane), or, in discrete time, from the unit circle (dimensionless). A negative margin
        accepts poles up to ``-margin`` beyond the boundary.
    dt : float or True, optional
        Sampling time for an array ``A`` (default: the system's ``dt``; 0/None: continuous).

    Returns
    -------
    bool
        False also when ``A`` holds NaN or inf.
    """
    if dt is None:
        dt = getattr(sys, "dt", 0)
    if dt in (0, None):
        return bool(spectral_abscissa(sys) < -margin)
    A = np.asarray(getattr(sys, "A", sys))
    if A.size == 0:
        return True
    if not np.all(np.isfinite(A)):
        return False
    return bool(np.max(np.abs(np.linalg.eigvals(A))) < 1.0 - margin)


def roundoff_margin(A: Any) -> float:
    """``64 eps max(1, ||A||_1)``: a pole this close to the stability boundary is on it to round-off.

    Eigenvalues are backward stable, accurate to about ``eps ||A||`` (Golub & Van Loan 2013,
    sec. 7.2.2); a sampled undamped mode sits at ``|z| = 1 - 3e-16``. The margin for
    :func:`is_stable` where "stable" must mean "stable beyond round-off" (norms that would
    otherwise be 1e14 instead of infinite).
    """
    A = np.asarray(getattr(A, "A", A), dtype=float)
    norm1 = float(np.abs(A).sum(axis=0).max()) if A.size else 1.0  # np.linalg.norm(A, 1), same operations
    return 64.0 * _EPS * max(1.0, norm1)


# ---------------------------------------------------------------------------- construction
def series_matrices(p1, p2):
    """Cascade ``p2 * p1`` of ``(A, B, C, D)`` tuples (``p1`` acts first; states ``[x1; x2]``)."""
    A1, B1, C1, D1 = p1
    A2, B2, C2, D2 = p2
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.block([[A1, np.zeros((n1, n2))], [B2 @ C1, A2]])
    return A, np.vstack([B1, B2 @ D1]), np.hstack([D2 @ C1, C2]), D2 @ D1


def conjugate_pairs(r: np.ndarray) -> list[np.ndarray]:
    """Real roots singly, complex roots as conjugate pairs (upper half-plane member kept)."""
    r = np.asarray(r, dtype=complex)
    tol = 1e-8 * (1.0 + np.abs(r))
    real = np.sort(r[np.abs(r.imag) <= tol].real)
    cplx = r[r.imag > tol]
    return [np.array([v]) for v in real] + [np.array([v, np.conj(v)]) for v in cplx]


def _poly(group: list[np.ndarray]) -> np.ndarray:
    roots = np.concatenate(group) if group else np.zeros(0)
    return np.real(np.poly(roots)) if roots.size else np.array([1.0])


def _section(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, ...]:
    """State space of ``num / den`` (den monic, degree 1 or 2, deg num <= deg den), scaled."""
    n = den.size - 1
    num = np.concatenate([np.zeros(n + 1 - num.size), num])
    d = num[0]
    if n == 1:
        a0 = den[1]
        return np.array([[-a0]]), np.array([[1.0]]), np.array([[num[1] - d * a0]]), np.array([[d]])
    a1, a0 = den[1], den[2]
    wn = np.sqrt(abs(a0)) or 1.0
    A = np.array([[0.0, wn], [-a0 / wn, -a1]])
    c2 = num[1] - d * a1
    c1 = (num[2] - d * a0) / wn
    return A, np.array([[0.0], [1.0]]), np.array([[c1, c2]]), np.array([[d]])


def zpk_statespace(zeros: Any, poles: Any, gain: float, *, name: str | None = None):
    """A real SISO ``control.StateSpace`` of ``gain prod(s - z) / prod(s - p)`` as a cascade.

    Parameters
    ----------
    zeros, poles : array_like, complex
        Roots in rad/s, closed under conjugation; at most as many zeros as poles (proper).
    gain : float
        The factor ``k`` of the zero-pole-gain form.
    name : str, optional
        Name of the system.

    Returns
    -------
    control.StateSpace
        First- and second-order sections in series (no polynomial coefficients formed).
    """
    zg, pg = conjugate_pairs(np.asarray(zeros)), conjugate_pairs(np.asarray(poles))
    if sum(g.size for g in zg) > sum(g.size for g in pg):
        raise FitError("more zeros than poles: the weight would be improper.")
    if not pg:
        return control.ss([], [], [], [[float(gain)]], name=name)
    dens, nums = _assign(zg, pg)
    sections = []
    for den, num in zip(dens, nums):
        A, B, C, D = _section(_poly(num), _poly(den))
        # unit gain at the section's pole magnitude keeps the cascade's internal gains balanced
        wp = float(np.abs(np.concatenate(den)).max()) or 1.0
        zeros_k = np.concatenate(num) if num else np.zeros(0)
        h = zpk_response(zeros_k, np.concatenate(den), np.array([1j * wp]))
        g = 1.0 / max(abs(complex(h[0])), 1e-300)
        sections.append((A, B, C * g, D * g, g))
    scale = float(gain) / float(np.prod([sec[4] for sec in sections]))
    per = abs(scale) ** (1.0 / len(sections))
    sys = None
    for i, (A, B, C, D, _) in enumerate(sections):
        f = per * (np.sign(scale) if i == 0 and scale != 0 else 1.0)
        sec = (A, B, C * f, D * f)
        sys = sec if sys is None else series_matrices(sys, sec)
    A, B, C, D = sys
    return control.ss(A, B, C, D, name=name)


def _assign(
    zg: list[np.ndarray], pg: list[np.ndarray]
) -> tuple[list[list[np.ndarray]], list[list[np.ndarray]]]:
    """Sections of at most two poles, each with the zeros nearest to its poles in magnitude.

    Complex pole pairs make second-order sections, real poles first-order ones; a complex
    zero pair takes the nearest complex pole pair without zeros, or else merges the two
    real poles nearest to it into one section. Real zeros then go, nearest first, to
    sections with room (a zero count not above the pole count keeps each section proper).
    """
    dens = [[g] for g in pg]
    nums: list[list[np.ndarray]] = [[] for _ in dens]

    def size(k: int) -> int:
        return sum(x.size for x in dens[k])

    def room(k: int) -> int:
        return size(k) - sum(x.size for x in nums[k])

    def dist(z: np.ndarray, k: int) -> float:
        return abs(np.log(np.abs(z[0]) + 1e-300) - np.log(np.abs(np.concatenate(dens[k])).max() + 1e-300))

    for z in [g for g in zg if g.size == 2]:
        free = [k for k in range(len(dens)) if size(k) == 2 and room(k) == 2]
        if not free:
            reals = sorted(
                (k for k in range(len(dens)) if size(k) == 1 and room(k) == 1), key=lambda k: dist(z, k)
            )
            if len(reals) < 2:  # not expected while zeros <= poles
                raise FitError("cannot place a complex zero pair: the weight would be improper.")
            a, b = reals[:2]
            dens[a] = dens[a] + dens[b]
            nums[a] = nums[a] + nums[b]
            del dens[b], nums[b]
            free = [a if a < b else a - 1]
        k = min(free, key=lambda k: dist(z, k))
        nums[k].append(z)
    for z in sorted([g for g in zg if g.size == 1], key=lambda g: -abs(g[0])):
        open_ = [k for k in range(len(dens)) if room(k) >= 1]
        k = min(open_, key=lambda k: dist(z, k))
        nums[k].append(z)
    return dens, nums


# ---------------------------------------------------------------------------- public
def zpk_response(zeros: np.ndarray, poles: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``prod(s - z) / prod(s - p)`` at the points ``s`` (no gain), complex, the shape of ``s``."""
    out = np.ones(s.shape, dtype=complex)
    for z in zeros:
        out *= s - z
    for p in poles:
        out /= s - p
    return out
