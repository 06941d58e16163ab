"""Gravity preload: MACE's iterative stress-stiffening procedure.

Gravity is applied to the 1-g finite-element model as a static load; the member axial forces
it produces enter the geometric (stress) stiffness ``K_g(N)``; the static solution is
repeated with ``K + K_g(N)`` until the axial forces stop changing (Glaese & Miller, "Derivation
of zero-gravity structural control models ...", section "1-g model": "Gravity is
mathematically applied to the structure in an iterative procedure, and the resulting
stresses are used to modify the stiffness matrix"). The converged ``K + K_g`` then carries
the pendulum stiffness of suspended bodies (``T/L`` for a rod under tension ``T``), the
violin modes of taut suspension rods and the stiffening of rigid-body modes.

Static solutions of structures that are free in some direction (rigid-body modes, or
mechanisms such as a pendulum before its tension is known) are solved in the range of the
stiffness matrix: the part of the load that would accelerate a rigid-body/mechanism mode is
removed first (inertia relief: in free fall a uniform gravity field produces no stress).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import ModelError

__all__ = ["PreloadResult", "null_space", "solve_static", "preload_iteration"]

#: Eigenvalues of (K, M) below ``NULL_TOL * max(diag K / diag M)`` count as rigid-body or
#: mechanism modes. Rounding leaves them near 1e-16 of that scale; a real suspension at
#: 0.05 Hz on a structure whose stiffest element is at 1e5 Hz is still at 2.5e-13.
NULL_TOL = 1e-13

#: Above this many DOFs the static solver uses sparse factorisations (as ``solve_modes``).
DENSE_LIMIT = 600


@dataclass(frozen=True)
class PreloadResult:
    """Outcome of the gravity preload iteration.

    Attributes
    ----------
    axial_forces : ndarray (ne,)
        Converged axial force per element in N (tension positive), added group tensions
        included.
    displacement : ndarray (n_dof,)
        Static deflection of the free DOFs (m, rad) under gravity.
    iterations : int
        Static solutions carried out.
    converged : bool
        Whether the change of the axial forces fell below the tolerance.
    history : tuple of float
        Largest axial-force change (N) at each iteration.
    unbalanced_load : ndarray (n_dof,)
        Load (N, N m) removed because no support resists it (rigid-body or mechanism
        direction); zero for a properly supported structure.
    unbalanced_fraction : float
        Norm of ``unbalanced_load`` over the norm of the gravity load.
    """

    axial_forces: np.ndarray
    displacement: np.ndarray
    iterations: int
    converged: bool
    history: tuple[float, ...]
    unbalanced_load: np.ndarray
    unbalanced_fraction: float = 0.0


def regularised_mass(M) -> sp.csr_matrix:
    """``M`` with a unit-scale mass on DOFs that have none, so ``(K, M)`` is a definite pencil."""
    M = sp.csr_matrix(M)
    d = M.diagonal()
    ref = d[d > 0].mean() if np.any(d > 0) else 1.0
    fill = np.where(d > 1e-14 * ref, 0.0, ref)
    return (M + sp.diags(fill)).tocsr()


def _lambda_ref(K, Mreg) -> float:
    ratio = np.abs(K.diagonal()) / Mreg.diagonal()
    return float(max(ratio.max(), 1e-300))


def null_space(
    K, M, *, tol: float = NULL_TOL, max_modes: int | None = None, Mreg: sp.csr_matrix | None = None
) -> np.ndarray:
    """M-orthonormal basis of the rigid-body and mechanism modes of ``K``.

    Parameters
    ----------
    K, M : sparse or dense (n, n)
        Symmetric positive semi-definite stiffness (N/m) and mass (kg); DOFs without
        mass are given a reference mass (:func:`regularised_mass`).
    tol : float
        Relative threshold on the eigenvalues, see :data:`NULL_TOL`.
    max_modes : int, optional
        Cap on the modes examined (default: all DOFs).
    Mreg : sparse (n, n), optional
        ``regularised_mass(M)`` when the caller already has it.

    Returns
    -------
    Z : ndarray (n, r)
        ``Z.T Mreg Z = I`` and ``K Z ~ 0``; ``r = 0`` for a supported structure.
    """
    K = sp.csr_matrix(K)
    Mreg = regularised_mass(M) if Mreg is None else Mreg
    n = K.shape[0]
    if n <= DENSE_LIMIT and _clearly_definite(K.toarray()):
        return np.zeros((n, 0))
    lam_ref = _lambda_ref(K, Mreg)
    cap = n if max_modes is None else min(n, max_modes)
    k = min(cap, 24)
    while True:  # bounded: k doubles up to cap
        lam, vec = _lowest_modes(K, Mreg, k)
        null = lam <= tol * lam_ref
        if not null.all() or k >= cap:
            return vec[:, null]
        k = min(2 * k, cap)


def _clearly_definite(K: np.ndarray) -> bool:
    """A Cholesky factor whose pivots all keep more than 1e-10 of their diagonal: the matrix
    is definite beyond doubt (a singular one leaves a pivot near 1e-16). When this says no,
    the eigen-decomposition decides."""
    d = np.diag(K)
    if np.any(d <= 0):
        return False
    try:
        L = sla.cholesky(K, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return False
    return bool(np.min(np.diag(L) ** 2 / d) > 1e-10)


def _lowest_modes(K, Mreg, k):
    n = K.shape[0]
    if n <= DENSE_LIMIT or k >= n - 1:
        return sla.eigh(K.toarray(), Mreg.toarray(), subset_by_index=[0, k - 1])
    sigma = -NULL_TOL * _lambda_ref(K, Mreg) - 1.0
    lam, vec = spla.eigsh(K.tocsc(), k=k, M=Mreg.tocsc(), sigma=sigma, which="LM")
    order = np.argsort(lam)
    return lam[order], vec[:, order]


def solve_static(
    K, M, f, Z: np.ndarray | None = None, *, Mreg: sp.csr_matrix | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Static deflection ``K u = f`` of a possibly unsupported structure.

    The load component on the null space ``Z`` (rigid-body/mechanism modes, M-orthonormal)
    is removed (inertia relief, ``f_p = f - M Z Z^T f``) and ``u`` is sought with
    ``Z^T M u = 0``. With ``Z`` empty this is the ordinary solution.

    Parameters
    ----------
    K, M : sparse or dense (n, n)
        Stiffness (N/m) and mass (kg).
    f : ndarray (n,)
        Load in N, N m.
    Z : ndarray (n, r), optional
        Null-space basis from :func:`null_space` (computed when omitted).
    Mreg : sparse (n, n), optional
        ``regularised_mass(M)`` when the caller already has it (the preload iteration solves
        with the same mass every step).

    Returns
    -------
    u : ndarray (n,)
        Displacements in m, rad.
    f_removed : ndarray (n,)
        The load that was removed.

    Raises
    ------
    ModelError
        When ``K`` is not positive semi-definite (a compressive preload beyond buckling).
    """
    K = sp.csr_matrix(K)
    Mreg = regularised_mass(M) if Mreg is None else Mreg
    if Z is None:
        Z = null_space(K, M)
    MZ = Mreg @ Z
    f_removed = MZ @ (Z.T @ f)
    f_p = f - f_removed
    lam_ref = _lambda_ref(K, Mreg)
    if K.shape[0] <= DENSE_LIMIT:
        u = _solve_definite(K.toarray() + lam_ref * (MZ @ MZ.T), f_p)
    else:
        u = _sparse_projected_solve(K, Mreg, Z, f_p, lam_ref, float(np.linalg.norm(f)))
    return u, f_removed


def _solve_definite(A: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``A^-1 f`` by Cholesky for a dense ``A`` that must be positive definite. ``A + 0.0``: a
    stored ``-0.0`` reads as the ``+0.0`` a sparse sum (which drops zeros) or ``MZ MZ^T`` adds."""
    try:
        return sla.cho_solve(sla.cho_factor(A + 0.0), f)
    except np.linalg.LinAlgError:
        raise _unstable_error() from None


def _unstable_error() -> ModelError:
    return ModelError(
        "the preloaded stiffness K + K_g is not positive definite: a compressive preload "
        "exceeds the buckling load of a member (or a spring is negative). Check the gravity "
        "direction and the supports (a standing column needs enough bending stiffness), or "
        "reduce the added group tension/compression."
    )


def _sparse_projected_solve(K, Mreg, Z, f_p, lam_ref, f_norm):
    """Preconditioned CG on ``K u = f_p`` in the M-complement of ``Z`` (large models).

    The preconditioner is ``Pi (K + sigma M)^-1 Pi^T`` with ``Pi = I - Z Z^T M``: symmetric,
    as CG needs, and equal to the pseudo-inverse up to the small shift ``sigma``. The
    residual is judged against the whole load ``f_norm`` (a free-falling structure leaves
    only rounding in ``f_p``)."""
    sigma = 1e-8 * lam_ref
    try:
        lu = spla.splu((K + sigma * Mreg).tocsc())
    except RuntimeError:
        raise _unstable_error() from None

    def project(x):  # onto the M-complement of Z
        return x - Z @ (Z.T @ (Mreg @ x))

    def project_t(r):  # its transpose, for loads: removes the part that excites Z
        return r - Mreg @ (Z @ (Z.T @ r))

    b = project_t(f_p)
    if np.linalg.norm(b) <= 1e-12 * max(f_norm, 1e-300):
        return np.zeros_like(b)
    prec = spla.LinearOperator(K.shape, matvec=lambda r: project(lu.solve(project_t(r))))
    u, info = spla.cg(K, b, x0=prec @ b, M=prec, rtol=1e-12, atol=1e-12 * f_norm, maxiter=200)
    if info != 0:
        raise ModelError(
            "the static solution under gravity did not converge: the preloaded stiffness is "
            "indefinite (a compressive preload beyond buckling) or nearly singular in a "
            "direction that is not a rigid-body mode. Check the supports and compressed members."
        )
    return project(u)


def preload_iteration(
    K_elastic,
    M,
    f,
    axial_force: Callable[[np.ndarray], np.ndarray],
    geometric: Callable[[np.ndarray], object],
    *,
    n_fixed: np.ndarray | None = None,
    tol: float = 1e-8,
    max_iter: int = 50,
) -> PreloadResult:
    """Iterate ``(K + K_g(N)) u = f``, ``N = N(u)`` until the axial forces converge.

    Parameters
    ----------
    K_elastic, M : sparse (n, n)
        Elastic stiffness and mass of the free DOFs.
    f : ndarray (n,)
        Gravity load ``M a_g`` in N, N m.
    axial_force : callable ``(u, N_used) -> N``
        Element axial forces (N, tension positive) caused by the displacements ``u``, which
        solved ``(K + K_g(N_used)) u = f`` (``N_used`` is None on the first step). Forces
        found from equilibrium residuals (rigid links) need ``N_used``.
    geometric : callable ``N -> K_g``
        Geometric stiffness (sparse, n x n) of the element forces ``N``.
    n_fixed : ndarray (ne,), optional
        Axial forces that do not come from ``u`` (added wire tension), in N.
    tol : float
        Convergence when ``max |N_k - N_{k-1}| <= tol * max(max|N_k|, tiny)``.
    max_iter : int
        Cap on static solutions; ``max_iter=1`` is the classical one-step differential
        stiffness (NASTRAN SOL 4 style), returned with ``converged=False`` unless the
        forces happen to need no update.

    Returns
    -------
    PreloadResult

    Raises
    ------
    ModelError
        If the iteration does not converge within ``max_iter`` (the preload is near a
        buckling load) or the preloaded stiffness becomes indefinite.
    """
    if max_iter < 1:
        raise ModelError(f"max_iter must be at least 1; got {max_iter}.")
    K_elastic = sp.csr_matrix(K_elastic)
    # a small supported structure (null_space's own definiteness test) iterates on dense
    # matrices: no rigid-body or mechanism mode, so no inertia relief and no regularised mass
    K_dense = K_elastic.toarray() if K_elastic.shape[0] <= DENSE_LIMIT else None
    supported = K_dense is not None and _clearly_definite(K_dense)
    if supported:
        Mreg, lam_ref, Z0 = None, None, np.zeros((K_elastic.shape[0], 0))
    else:
        Mreg = regularised_mass(M)
        lam_ref = _lambda_ref(K_elastic, Mreg)
        Z0 = null_space(K_elastic, M, Mreg=Mreg)
    n_add = np.zeros(0) if n_fixed is None else np.asarray(n_fixed, float)
    N = n_add.copy() if n_add.size else None
    history: list[float] = []
    weight = float(np.abs(f).sum()) or 1.0
    u = np.zeros(K_elastic.shape[0])
    removed = np.zeros_like(u)
    for it in range(1, max_iter + 1):
        if supported:
            u = _solve_definite(K_dense if N is None else K_dense + geometric(N).toarray(), f)
        else:
            Kt = K_elastic if N is None else (K_elastic + geometric(N)).tocsr()
            Z = _surviving_null_space(Kt, Z0, lam_ref)
            u, removed = solve_static(Kt, M, f, Z, Mreg=Mreg)
        N_new = axial_force(u, N) + (n_add if n_add.size else 0.0)
        change = float(np.abs(N_new - (0.0 if N is None else N)).max(initial=0.0))
        history.append(change)
        N = N_new
        scale = tol * max(float(np.abs(N).max(initial=0.0)), 1e-3 * weight)
        if change <= scale or _stalled_at_rounding(history, scale):
            return _result(N, u, it, True, history, removed, f)
    if max_iter == 1:  # the one-step differential stiffness asked for: no convergence test
        return _result(N, u, 1, False, history, removed, f)
    raise ModelError(
        f"the gravity preload iteration did not converge in {max_iter} steps (last axial-force "
        f"change {history[-1]:.3g} N): the structure is close to buckling under its own weight, "
        "or very flexible. Stiffen the compressed members, check the supports, or raise "
        "max_gravity_iterations."
    )


#: A preload iteration whose force change stops falling within this factor of the tolerance
#: has reached the rounding floor of its static solutions (:func:`_stalled_at_rounding`).
STALL_FACTOR = 100.0


def _stalled_at_rounding(history: list[float], scale: float) -> bool:
    """True when the axial-force change has stopped falling (by 10 % or more a step) within
    ``STALL_FACTOR`` of the tolerance ``scale`` (N).

    The fixed point converges linearly until the changes reach the rounding level of the
    static solutions (about ``cond(K) eps`` of the forces); there they flip between equal
    values (the MACE bus: 9.9e-7, 9.9e-7, 4.9e-7 N against a tolerance of 1.0e-6 N, up to 50
    iterations, or a "did not converge" error for a well-posed structure). A change that no
    longer falls at that level is the attainable accuracy, not a sign of buckling, which
    shows as changes that stay large or grow.
    """
    return len(history) >= 3 and history[-1] <= STALL_FACTOR * scale and history[-1] > 0.9 * history[-2]


def _surviving_null_space(Kt, Z0, lam_ref) -> np.ndarray:
    """The part of the elastic null space ``Z0`` that the geometric stiffness left free."""
    if Z0.shape[1] == 0:
        return Z0
    small = Z0.T @ (Kt @ Z0)
    w, V = np.linalg.eigh(0.5 * (small + small.T))
    if np.any(w < -1e-9 * lam_ref):
        raise _unstable_error()
    return Z0 @ V[:, w <= NULL_TOL * lam_ref]


def _result(N, u, it, converged, history, removed, f) -> PreloadResult:
    return PreloadResult(
        axial_forces=np.asarray(N, float),
        displacement=u,
        iterations=it,
        converged=converged,
        history=tuple(history),
        unbalanced_load=removed,
        unbalanced_fraction=float(np.linalg.norm(removed) / max(np.linalg.norm(f), 1e-300)),
    )
