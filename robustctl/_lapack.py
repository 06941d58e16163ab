"""Lean LAPACK calls for the small dense matrices of the synthesis hot paths.

Each function makes the LAPACK driver call that its ``numpy.linalg`` / ``scipy.linalg``
counterpart makes (``dgesv``, ``dgesdd``, ``dgeev``, ``dgees``), with the same optimal
workspace (queried once per shape and cached), so the numbers are those of the counterpart
(bit for bit where both link the same LAPACK build), without the per-call wrapper costs (type
dispatch, error-state contexts, workspace queries): on a 4 x 4 matrix the wrappers cost 3-9
times the factorisation itself, which dominated ``rc.h2syn`` at low orders. Real (float64)
2-D input (:func:`svdvals` also complex).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.linalg import lapack

__all__ = ["solve", "svdvals", "svd_thin", "eigvals", "real_schur"]

_LWORK: dict[tuple, int] = {}


def _lwork(key: tuple, query) -> int:
    lw = _LWORK.get(key)
    if lw is None:
        work, info = query()
        if info != 0:  # pragma: no cover - a workspace query does not fail for valid sizes
            raise np.linalg.LinAlgError(f"LAPACK workspace query failed (info = {info}).")
        lw = _LWORK[key] = max(1, int(np.real(work)))
    return lw


def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.linalg.solve(a, b)`` for square ``a`` (n x n) and 2-D ``b`` (n x k), by LAPACK ``dgesv``.

    Raises
    ------
    numpy.linalg.LinAlgError
        ``a`` is exactly singular (numpy's message).
    """
    if a.shape[0] == 0 or b.shape[1] == 0:
        return np.zeros(b.shape)
    _, _, x, info = lapack.dgesv(a, b)
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return x


def svdvals(a: np.ndarray) -> np.ndarray:
    """``np.linalg.svd(a, compute_uv=False)`` (descending singular values) by LAPACK ``dgesdd``
    (``zgesdd`` for a complex ``a``, e.g. a PBH test matrix ``[A - lambda I, B]``).

    Raises
    ------
    numpy.linalg.LinAlgError
        The SVD did not converge (numpy's message).
    """
    m, n = a.shape
    if m == 0 or n == 0:
        return np.zeros(0)
    if np.iscomplexobj(a):
        lw = _lwork(("zgesdd", m, n, 0), lambda: lapack.zgesdd_lwork(m, n, compute_uv=0, full_matrices=0))
        _, s, _, info = lapack.zgesdd(a, compute_uv=0, full_matrices=0, lwork=lw)
    else:
        lw = _lwork(("gesdd", m, n, 0), lambda: lapack.dgesdd_lwork(m, n, compute_uv=0, full_matrices=0))
        _, s, _, info = lapack.dgesdd(a, compute_uv=0, full_matrices=0, lwork=lw)
    if info != 0:
        raise np.linalg.LinAlgError("SVD did not converge")
    return s


def svd_thin(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``np.linalg.svd(a, full_matrices=False)``: ``(u, s, vt)`` by LAPACK ``dgesdd`` (nonempty ``a``).

    Raises
    ------
    numpy.linalg.LinAlgError
        The SVD did not converge (numpy's message).
    """
    m, n = a.shape
    lw = _lwork(("gesdd", m, n, 1), lambda: lapack.dgesdd_lwork(m, n, compute_uv=1, full_matrices=0))
    u, s, vt, info = lapack.dgesdd(a, compute_uv=1, full_matrices=0, lwork=lw)
    if info != 0:
        raise np.linalg.LinAlgError("SVD did not converge")
    return u, s, vt


def eigvals(a: np.ndarray) -> np.ndarray:
    """``np.linalg.eigvals(a)`` by LAPACK ``dgeev``: real when every eigenvalue is, else complex.

    Raises
    ------
    numpy.linalg.LinAlgError
        ``a`` has NaN/inf entries, or the QR algorithm did not converge (numpy's messages).
    """
    n = a.shape[0]
    if n == 0:
        return np.zeros(0)
    if not np.isfinite(a).all():
        raise np.linalg.LinAlgError("Array must not contain infs or NaNs")
    lw = _lwork(("geev", n), lambda: lapack.dgeev_lwork(n, compute_vl=0, compute_vr=0))
    wr, wi, _, _, info = lapack.dgeev(a, compute_vl=0, compute_vr=0, lwork=lw)
    if info != 0:
        raise np.linalg.LinAlgError("Eigenvalues did not converge")
    if not wi.any():
        return wr
    w = np.empty(n, complex)
    w.real, w.imag = wr, wi
    return w


def _lhp(re: float, im: float) -> bool:
    return re < 0.0


def _no_sort(re: float, im: float) -> None:
    return None


def _gees_query(a: np.ndarray) -> tuple[float, int]:
    out = lapack.dgees(_no_sort, a, lwork=-1)
    return out[-2][0], out[-1]


def real_schur(a: np.ndarray, sort_lhp: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(T, Z, Re eig, sdim)``: the real Schur form ``a = Z T Z^T`` by LAPACK ``dgees``.

    The call ``scipy.linalg.schur(a, output="real", sort="lhp" or None)`` makes, with the same
    workspace, and the real parts of the eigenvalues ``dgees`` returns (read off the
    standardised diagonal blocks). ``sort_lhp`` moves the eigenvalues with ``Re < 0`` first;
    ``sdim`` is their number (0 unsorted).

    Raises
    ------
    ValueError
        ``a`` has NaN/inf entries (scipy's message).
    numpy.linalg.LinAlgError
        The QR algorithm did not converge, or the sorted eigenvalues could not be reordered.
    """
    n = a.shape[0]
    if n == 0 or not np.isfinite(a).all():  # scipy's own results and messages for these
        T, Z, *rest = scipy.linalg.schur(a, output="real", sort="lhp" if sort_lhp else None)
        return T, Z, np.zeros(0), (rest[0] if rest else 0)
    lw = _lwork(("gees", n), lambda: _gees_query(a))
    select = _lhp if sort_lhp else _no_sort
    T, sdim, wr, _, Z, _, info = lapack.dgees(select, a, lwork=lw, sort_t=int(sort_lhp))
    if info != 0:
        raise np.linalg.LinAlgError(f"real Schur form failed (LAPACK dgees info = {info}).")
    return T, Z, wr, sdim
