"""Generalised symmetric eigenproblem K phi = w^2 M phi for structural models.

Dense LAPACK (``scipy.linalg.eigh``) for small models; sparse shift-invert Lanczos
(``scipy.sparse.linalg.eigsh``) for large ones, with a *negative* shift so that free-free
structures (singular K, rigid-body modes at 0 Hz) do not make the shifted matrix singular.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ModelError

__all__ = ["solve_modes", "check_structural_matrices"]

#: Above this many DOFs (and when fewer than a third of the modes are wanted) the sparse
#: shift-invert solver is used.
SPARSE_THRESHOLD = 600

#: Modes with ``w^2`` below this share of the largest are refined in extended precision
#: (:func:`_refine_low_modes`): a dense solve leaves them a relative error of about
#: ``eps * w_max^2 / w^2``, 2e-13 at the boundary, far more (1e-9 in ``w``) for the lowest.
LOW_SHARE = 1e-3

#: Pairs of modes whose coupling exceeds this share of their eigenvalue gap are rotated as a
#: cluster (a small eigenproblem); the others by first-order perturbation, whose error, of the
#: share's square, the second pass removes.
CLUSTER_SHARE = 1e-4

#: Most multiply-adds (nonzeros of K and M, plus three times ``n_dof`` per mode pair, per pass)
#: spent on the refinement; above it (models of thousands of DOFs with hundreds of low modes)
#: the modes stay as LAPACK gave them.
REFINE_WORK = 6e7


def _absmax(a) -> float:
    return float(abs(a).max()) if sp.issparse(a) else float(np.abs(np.asarray(a)).max(initial=0.0))


def _dense(a) -> np.ndarray:
    return a.toarray() if sp.issparse(a) else np.asarray(a, dtype=float)


def _check_square_symmetric(name: str, mat) -> tuple[int, int]:
    shape = mat.shape
    if len(shape) != 2 or shape[0] != shape[1]:
        raise ModelError(f"the {name} matrix must be square; got shape {shape}.")
    values = mat.data if sp.issparse(mat) else np.asarray(mat, dtype=float)
    if not np.all(np.isfinite(values)):
        raise ModelError(f"the {name} matrix contains NaN or inf.")
    scale = max(float(np.abs(values).max(initial=0.0)), 1e-300)
    asym = mat - mat.T
    worst = float(abs(asym).max()) if sp.issparse(asym) else float(np.abs(asym).max(initial=0.0))
    if worst > 1e-9 * scale:
        raise ModelError(
            f"the {name} matrix is not symmetric (max asymmetry {worst:.3g}); "
            "structural matrices must be symmetric."
        )
    return shape


def _is_positive_definite(mass) -> bool:
    if not sp.issparse(mass) or mass.shape[0] < 3:
        try:
            np.linalg.cholesky(mass.toarray() if sp.issparse(mass) else np.asarray(mass, dtype=float))
        except np.linalg.LinAlgError:
            return False
        return True
    diag = mass.diagonal()
    if np.any(diag <= 0):
        return False
    off = sp.csr_matrix(mass, copy=True)
    off.setdiag(0.0)
    off.eliminate_zeros()
    if off.nnz == 0:  # a lumped (diagonal) mass matrix: positive diagonal suffices
        return True
    return _sparse_pivots_positive(mass, float(diag.max()))


def _sparse_pivots_positive(mass, scale: float) -> bool:
    """Whether a sparse symmetric matrix is positive definite, from the pivots of its
    symmetric-mode LU without pivoting (``P^T M P = L D L^T``: Sylvester's law of inertia,
    Golub & Van Loan, *Matrix Computations*, 4th ed., Thm. 8.1.17). ``O(nnz(L))``, where the
    former shift-invert Lanczos check of the smallest eigenvalue needed thousands of ARPACK
    iterations on a lumped mass matrix with clustered entries."""
    try:
        lu = spla.splu(sp.csc_matrix(mass), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular
        return False
    pivots = lu.U.diagonal()
    return bool(np.all(pivots > 1e-12 * scale))


def check_structural_matrices(mass, stiffness) -> None:
    """Refuse non-square, non-symmetric, non-finite or non-positive-definite mass matrices.

    Sparse matrices are checked without densifying them.

    Raises
    ------
    ModelError
        Naming the first problem found and how to fix it.
    """
    mass = mass if sp.issparse(mass) else np.asarray(mass, dtype=float)
    stiffness = stiffness if sp.issparse(stiffness) else np.asarray(stiffness, dtype=float)
    shape_m = _check_square_symmetric("mass", mass)
    shape_k = _check_square_symmetric("stiffness", stiffness)
    if shape_m != shape_k:
        raise ModelError(f"mass {shape_m} and stiffness {shape_k} differ in size.")
    _check_mass_definite(mass)


def _check_mass_definite(mass) -> None:
    """Refuse a singular or indefinite mass matrix (already square, symmetric, finite)."""
    if not _is_positive_definite(mass):
        raise ModelError(
            "the mass matrix is singular or not positive definite: every DOF needs mass "
            "(add rotary inertia, remove massless DOFs, or condense them statically)."
        )


def _clean_eigenvalues(lam: np.ndarray, k_scale: float) -> np.ndarray:
    """Rigid-body eigenvalues come out as tiny +/- numbers: set them to zero; refuse a
    genuinely negative one (an unstable structure, e.g. buckled under a preload)."""
    tol = 1e-8 * max(k_scale, 1e-300)
    if np.any(lam < -tol):
        raise ModelError(
            f"the stiffness has a negative eigenvalue ({lam.min():.3g} rad^2/s^2): the structure "
            "is unstable (compressive preload beyond buckling, or a negative spring)."
        )
    # Rounding leaves rigid-body eigenvalues near 1e-15 * k_scale; real suspension modes
    # (0.05 Hz under a 1e4 Hz element) sit far above 1e-12 * k_scale, so only those go to 0.
    return np.where(lam <= 1e-12 * max(k_scale, 1e-300), 0.0, lam)


def solve_modes(
    mass,
    stiffness,
    *,
    n_modes: int | None = None,
    band_hz: tuple[float, float] | None = None,
    sparse: bool | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Mass-normalised modes of ``K phi = w^2 M phi``.

    Parameters
    ----------
    mass, stiffness : array_like or sparse, shape (n_dof, n_dof)
        Symmetric mass (positive definite) and stiffness (positive semi-definite).
    n_modes : int, optional
        Number of lowest modes to return (all when ``None`` and no band is given).
    band_hz : (float, float), optional
        Keep the modes whose natural frequency lies in ``[lo, hi]`` Hz.
    sparse : bool, optional
        Force the sparse shift-invert (True) or dense (False) solver.

    Returns
    -------
    omega : ndarray, shape (n,)
        Natural frequencies in rad/s, ascending (0 for rigid-body modes).
    phi : ndarray, shape (n_dof, n)
        Mode shapes normalised so that ``phi.T M phi = I``.
    """
    check_structural_matrices(mass, stiffness)
    mass = mass if sp.issparse(mass) else np.asarray(mass, dtype=float)
    stiffness = stiffness if sp.issparse(stiffness) else np.asarray(stiffness, dtype=float)
    n_dof = mass.shape[0]
    if n_modes is not None and not 1 <= int(n_modes) <= n_dof:
        raise ModelError(f"n_modes must lie in 1..{n_dof}; got {n_modes}.")
    if band_hz is not None and not 0 <= band_hz[0] < band_hz[1]:
        raise ModelError(f"band_hz must be (lo, hi) with 0 <= lo < hi in Hz; got {band_hz}.")
    wanted = n_dof if n_modes is None else int(n_modes)
    use_sparse = sparse if sparse is not None else (n_dof > SPARSE_THRESHOLD and wanted < n_dof // 3)
    if use_sparse:
        lam, phi = _sparse_modes(mass, stiffness, n_modes, band_hz, n_dof)
    else:
        lam, phi = sla.eigh(_dense(stiffness), _dense(mass))
        lam, phi = _refine_low_modes(lam, phi, stiffness, mass, _wanted(lam, n_modes, band_hz))
    k_scale = float(_absmax(stiffness) / max(_absmax(mass), 1e-300))
    lam = _clean_eigenvalues(lam, k_scale)
    omega = np.sqrt(lam)
    keep = np.ones(omega.size, dtype=bool)
    if band_hz is not None:
        f = omega / (2 * np.pi)
        keep &= (f >= band_hz[0]) & (f <= band_hz[1])
        if not np.any(keep):
            raise ModelError(
                f"no mode lies in the band {band_hz} Hz; the computed modes span "
                f"{f.min():.4g}-{f.max():.4g} Hz."
            )
    omega, phi = omega[keep], phi[:, keep]
    if n_modes is not None:
        omega, phi = omega[:n_modes], phi[:, :n_modes]
    return omega, phi


def _refine_low_modes(lam: np.ndarray, phi: np.ndarray, stiffness, mass,
                      wanted: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The low modes of a dense solve, made exact to the extended precision's round-off.

    LAPACK's ``eigh`` gives each eigenvalue an absolute error of about ``eps * w_max^2``; a mode
    far below the highest has a relative error ``eps * w_max^2 / w^2`` (1e-9 in ``w`` for the
    Caltech truss's 1.1 Hz mode under a 9.8 kHz one), and which error depends on the BLAS
    kernel: two machines gave frequency responses 1e-7 apart near the lowest resonance. Here the
    modes with ``w^2 < LOW_SHARE * w_max^2`` are refined by two passes of Rayleigh-Ritz
    correction in ``numpy.longdouble`` (no BLAS, so the same sums on any kernel):

    1. ``Kr = P^T K P`` and ``Mr = P^T M P`` of the current shapes ``P`` (``K`` and ``M`` as
       sparse matrices when they are mostly zeros, as an assembled model's are);
    2. mass-normalise, ``C = S Kr S`` with ``S = I - F/2``, ``F = Mr - I``, to first order in
       ``F`` (``|F| ~ eps``: ``C = Kr - (F D + D F) / 2``, ``D`` the diagonal of ``Kr``);
    3. rotate clusters (pairs coupled beyond ``CLUSTER_SHARE`` of their gap, repeated
       eigenvalues among them) by the eigenvectors of their block of ``C``, shifted by its mean
       diagonal so the small eigenproblem's error is of the coupling, not of ``w^2``;
    4. correct the rest to first order, ``P <- P S R (I + T) = P (R + R T - F R / 2)``,
       ``T_ij = C_ij / (c_j - c_i)``, eigenvalues ``c_i + sum_j C_ij^2 / (c_i - c_j)`` (second
       order; Golub & Van Loan, *Matrix Computations*, 4th ed., sec. 8.1.2).

    The products dropped in 2 and 4 (``F`` with the off-diagonal of ``Kr``, ``F T``) are of
    order ``eps^2 w_max^2``, below the extended precision. Only the ``wanted`` modes are refined
    (the band or number of modes a model keeps, with a margin); a low mode left out couples to a
    kept one as the unrefined ones do, moving its eigenvalue at second order only.

    The coupling to an unrefined mode ``j`` (``w_j^2 >= LOW_SHARE w_max^2``), about
    ``eps * w_max^2`` against a gap of nearly ``w_j^2``, moves a low eigenvalue by less than
    ``eps^2 w_max^2 / LOW_SHARE`` and its shape by ``eps / LOW_SHARE`` (2e-13): negligible. A
    repeated eigenvalue's shapes stay a basis of its space chosen by the kernel; the frequency
    response does not depend on which.

    Parameters
    ----------
    lam : ndarray, shape (n,)
        Eigenvalues ``w^2`` (rad^2/s^2), ascending.
    phi : ndarray, shape (n_dof, n)
        Mass-normalised shapes.
    stiffness, mass : ndarray or sparse, shape (n_dof, n_dof)
        ``K`` and ``M`` (N/m, kg and their rotational counterparts).
    wanted : ndarray of bool, shape (n,), optional
        The modes worth refining (default all).

    Returns
    -------
    lam, phi
        As given, the low modes refined, ascending.
    """
    top = float(lam.max(initial=0.0))
    low = np.flatnonzero((lam < LOW_SHARE * top) & (np.ones(lam.size, bool) if wanted is None else wanted))
    m = low.size
    K, M = (_as_sparse_if_sparse(a) for a in (stiffness, mass))
    nnz = [a.nnz if sp.issparse(a) else a.size for a in (K, M)]
    if m == 0 or (sum(nnz) + 3 * phi.shape[0] * m) * m > REFINE_WORK:
        return lam, phi
    ld = np.longdouble
    K, M = (a.astype(ld) for a in (K, M))
    P = phi[:, low].astype(ld)
    eye = np.eye(m, dtype=ld)
    for _ in range(2):
        Kr, Mr = P.T @ (K @ P), P.T @ (M @ P)
        F = (Mr + Mr.T) / 2 - eye
        Kr = (Kr + Kr.T) / 2
        d = np.diag(Kr).copy()
        # S Kr S with S = I - F / 2: to first order in F (|F| ~ eps), the products of F with the
        # off-diagonal part of Kr (itself ~eps * w_max^2) fall below the extended precision
        C = Kr - (F * d[None, :] + d[:, None] * F) / 2
        C, clusters = _rotate_clusters(C)
        c = np.diag(C).copy()
        gap = c[None, :] - c[:, None]  # gap[i, j] = c_j - c_i
        coupled = np.abs(C) >= CLUSTER_SHARE * np.abs(gap)  # clusters and the diagonal
        T = np.where(coupled, 0, C / np.where(coupled, 1, gap))
        lam_low = c - np.sum(np.where(coupled, 0, C * T), axis=1)
        # P <- P S R (I + T) = P (R + R T - F R / 2) to first order in the small F and T
        RT, FR = T.copy(), F.copy()
        R = eye.copy()
        for idx, V in clusters:
            R[np.ix_(idx, idx)] = V
            RT[idx, :] = V @ T[idx, :]
            FR[:, idx] = F[:, idx] @ V
        P = P @ (R + RT - FR / 2)
    lam, phi = lam.copy(), phi.copy()
    lam[low] = lam_low.astype(float)
    phi[:, low] = P.astype(float)
    order = np.argsort(lam, kind="stable")
    return lam[order], phi[:, order]


def _as_sparse_if_sparse(a):
    """``a`` as CSR when it is sparse or mostly zeros (an assembled FE matrix), else dense."""
    if sp.issparse(a):
        return sp.csr_matrix(a)
    a = np.asarray(a, dtype=float)
    return sp.csr_matrix(a) if np.count_nonzero(a) < 0.25 * a.size else a


def _rotate_clusters(C: np.ndarray) -> tuple[np.ndarray, list]:
    """``R^T C R`` and the clusters ``[(indices, V), ...]`` of the orthogonal ``R`` (identity off
    the clusters) diagonalising each cluster of the nearly diagonal symmetric ``C``: indices joined
    where ``|C_ij| >= CLUSTER_SHARE |C_jj - C_ii|``. Each cluster's block, less its mean diagonal,
    is rounded to double and solved by ``eigh``."""
    from scipy.sparse.csgraph import connected_components

    c = np.diag(C)
    coupled = np.abs(C) >= CLUSTER_SHARE * np.abs(c[None, :] - c[:, None])
    n_comp, label = connected_components(sp.csr_matrix(coupled.astype(np.int8)), directed=False)
    clusters = []
    if n_comp == C.shape[0]:
        return C, clusters
    C = C.copy()
    for k in range(n_comp):
        idx = np.flatnonzero(label == k)
        if idx.size < 2:
            continue
        block = C[np.ix_(idx, idx)]
        shift = np.mean(np.diag(block))
        _, V = np.linalg.eigh((block - shift * np.eye(idx.size, dtype=C.dtype)).astype(float))
        V = V.astype(C.dtype)
        C[:, idx] = C[:, idx] @ V
        C[idx, :] = V.T @ C[idx, :]
        clusters.append((idx, V))
    return C, clusters


def _wanted(lam: np.ndarray, n_modes: int | None, band_hz) -> np.ndarray:
    """The modes a model keeps (``n_modes`` lowest, or those in ``band_hz``), with a margin of two
    modes and 2 % in frequency, so that rounding at the edges does not decide which are refined."""
    keep = np.ones(lam.size, dtype=bool)
    f = np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)
    if band_hz is not None:
        keep &= (f >= band_hz[0] / 1.02) & (f <= band_hz[1] * 1.02)
    if n_modes is not None:
        keep &= np.arange(lam.size) < int(n_modes) + 2
    return keep


def _sparse_modes(mass, stiffness, n_modes, band_hz, n_dof):
    M = sp.csc_matrix(mass)
    K = sp.csc_matrix(stiffness)
    # A negative shift keeps K - sigma M positive definite even with rigid-body modes.
    diag_ratio = K.diagonal().max() / max(M.diagonal().max(), 1e-300)
    sigma = -1e-6 * diag_ratio - 1.0
    k = min(n_modes or 20, n_dof - 2)
    # a fixed start vector: ARPACK's default continues one random sequence through the process,
    # so the modes' last digits would depend on the eigenproblems solved before
    v0 = np.linspace(1.0, 2.0, n_dof)
    for _ in range(12):  # bounded: k doubles each time, capped by n_dof
        lam, phi = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", v0=v0)
        order = np.argsort(lam)
        lam, phi = lam[order], phi[:, order]
        enough = band_hz is None or np.sqrt(max(lam.max(), 0)) / (2 * np.pi) > band_hz[1]
        if enough or k >= n_dof - 2:
            return lam, phi
        k = min(2 * k, n_dof - 2)
    return lam, phi
