"""Reduced coordinates for large second-order structural models: modes in and near the band,
static and inertia (attachment) vectors for the rest, and low-rank changes in that basis.

A structure with thousands of DOFs ``M q'' + Cs q' + K q = b u`` (sparse symmetric ``M``,
``K``; modal damping ``zeta`` on every mode as :func:`~robustctl.physical.modal.modal_dynamics`
defines it) is projected, once per parameter point, on the Ritz basis

.. math::

    W = [\\Phi_c,\\; A_1,\\; A_2], \\quad A_1 = K_\\sigma^{-1} b, \\quad A_2 = K_\\sigma^{-1} M A_1,
    \\quad K_\\sigma = K - \\sigma M,

``Phi_c`` the modes up to ``f_cut = margin * f_max`` (shift-invert Lanczos, ``eigsh``, the
factorisation of ``K_sigma`` reused) and ``A_1``, ``A_2`` the first two Krylov (attachment)
vectors of the inputs, M-orthogonalised against ``Phi_c`` -- the *modal truncation
augmentation* of Dickens, Nakagawa & Wittbrodt (1997), which carries the residual (static)
flexibility ``K^-1 - Phi_c Omega_c^-2 Phi_c^T`` of the truncated modes at the inputs and its
first inertia correction, and unlike a feedthrough it keeps velocity and acceleration outputs
proper. The Rayleigh-Ritz problem ``(W^T K W) psi = w^2 (W^T M W) psi`` gives the retained
modes (the exact ``Phi_c`` and ``2 m`` residual modes above ``f_cut``), each with the model's
damping ratio; everything else (damping bands, ``Phi^T Cs Phi``, output kinds) is that of
:mod:`robustctl.physical.modal`.

Memory is ``O(n_dof (r + m))`` plus the sparse factor of ``K_sigma``: no dense ``n_dof x n_dof``
matrix is formed. A structure that differs from a reduced one only at a few DOFs (an added
mass, a grounded spring or a dashpot at a node: the effects :func:`robustctl.diagnose` scores by
the thousand) is not reduced again: the basis is augmented by the attachment vectors
``K_sigma^{-1} E_J`` of the changed DOFs ``J`` and the small projected problem is re-solved
(structural dynamic modification, Avitabile 2003; the Ritz basis makes the change exact at
statics and the rank-``|J|`` update of ``W^T M W`` and ``W^T K W`` costs ``O(n_dof r)``).
A structure that is a reduced one scaled (``alpha_M M``, ``alpha_K K``: an update parameter on
the whole stiffness, or on one property group beside a group the diagnosis changes, whose
difference from a scale lies on that group's DOFs) takes the reduced one's modes, factor and
attachment blocks scaled (:func:`_scaled_basis`): no Lanczos run or factorisation. Which reduction
a structure is taken as a change or a scale of is fixed by the model and the structure alone (a
root reduction at the model's own parameter values, its scales, a candidate's anchor: the model
it modifies; :class:`_Reducer`), never by the evaluations made before, so that serial work,
threads and worker processes give the same results bit for bit.

Error estimate (per channel, in the band): for modal truncation with static correction the
truncated modes contribute ``sum_k c phi_k phi_k^T b / (w_k^2 - w^2 + 2 j zeta w_k w)``, of
which the correction keeps ``1 / w_k^2``; with ``rho = w / w_cut < 1`` each term's error is at
most ``e(rho) = |1 / (1 - rho^2 + 2 j zeta rho) - 1|`` of its static part, and by
Cauchy-Schwarz ``|sum_k (c phi_k)(phi_k^T b) / w_k^2| <= sqrt(R^out_oo R^in_ii)`` with
``R = K_sigma^{-1} - Phi_c (Omega_c^2 - sigma)^{-1} Phi_c^T`` at the sensor and actuator DOFs
(times ``w`` or ``w^2`` for velocity and acceleration outputs):
:func:`reduction_error` returns it. The augmented basis also matches the inertia term, so the
error observed is well below the estimate (tests/test_reduction.py).

References
----------
Dickens, J. M., Nakagawa, J. M. & Wittbrodt, M. J. (1997). A critique of mode acceleration
and modal truncation augmentation methods for modal response analysis. *Computers &
Structures* 62(6), 985-998.
Avitabile, P. (2003). Twenty years of structural dynamic modification -- a review. *Sound and
Vibration* 37(1), 14-27.
Craig, R. R. & Kurdila, A. J. (2006). *Fundamentals of Structural Dynamics*, 2nd ed., Wiley,
sec. 11.4 (mode-acceleration / static correction).
"""

from __future__ import annotations

import contextlib
import gc
import hashlib
import threading
import uuid
import weakref
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import SimpleNamespace
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..checks import positive_number
from ..errors import ModelError
from .eigen import _clean_eigenvalues, check_structural_matrices
from .matrices import MatrixStructure
from .modal import ModalData, _check_mats, _damped
from .model import _DynamicsCache

__all__ = ["band_limited", "reduction_error", "REDUCE_MIN_DOF", "CUT_MARGIN"]

#: Structures with fewer DOFs keep the full (dense, all-modes) path of
#: :func:`~robustctl.physical.modal.modal_dynamics`: the examples (Caltech truss 138 DOFs, MACE
#: bus 213) keep their results bit for bit.
REDUCE_MIN_DOF = 300
#: Modes are computed up to ``CUT_MARGIN`` times the highest frequency of interest; the
#: residual modes stand for the rest (error estimate ``e(1 / CUT_MARGIN)``, see the module).
CUT_MARGIN = 3.0
#: A structure differing from a reduced one at no more than this many DOFs is treated as a
#: low-rank modification of it (structural dynamic modification) rather than reduced anew: each
#: changed DOF adds one attachment vector (a solve with the base's factor), against a Lanczos run
#: for a new reduction; 24 holds a transducer mass at every sensor and drive point of a test.
LOW_RANK_MAX_DOFS = 24
#: A change at more DOFs than :data:`LOW_RANK_MAX_DOFS` but no more than this many (and no more
#: than :data:`GROUP_MAX_SHARE` of the structure's DOFs) -- an element group such as a seam, a
#: bolted flange or a joint line, the ``stiffness change of <group>`` candidates diagnose fits
#: -- is a low-rank modification as well: its ``|J|`` attachment vectors are solved once per set
#: of DOFs and base (:func:`_attachment`, kept with the base), so each further size of the change
#: costs a Ritz problem of ``r + |J|`` instead of a Lanczos run (15 s at 20,000 DOFs).
GROUP_MAX_DOFS = 400
#: The largest share of a structure's DOFs a group change may touch and stay a modification.
GROUP_MAX_SHARE = 0.2
#: Attachment blocks kept per base (:func:`_attachment`): a candidate's DOF sets across its fit.
_ATTACH_KEEP = 8
_ATTACH_LOCK = threading.Lock()
#: A full garbage collection after this many reduced evaluations. A candidate's model (its
#: stages are closures that refer back to it) is a reference cycle that lives through several
#: young-generation collections, so it reaches the oldest generation, which Python collects
#: rarely: a diagnosis of thousands of candidates kept every candidate's state space (3 MB at
#: 300 modes), 1 GB per worker at 2,000 DOFs; collecting every 64 keeps it at the live set.
COLLECT_EVERY = 64
#: Reduced bases kept per model (parameter points: the null fit's, the polishing fits').
_KEEP = 4
#: Undamped modal data kept per model (:meth:`_Reducer.modal_data`), by structure.
_MODAL_KEEP = 4
#: A structure softer than the root by a scale ``rho = alpha_K / alpha_M < 1`` that brings more modes
#: into the cut than :func:`_extend` takes is the reduction of the root scaled by the rung ``2 **
#: (-j RUNG_LOG2)`` at or below ``rho`` (a fresh reduction, made once per rung) scaled up: an update
#: parameter's coarse search over stiffness factors (0.5, 0.7, ...) costs a Lanczos run per rung, not
#: per factor, and each scaled-up basis holds every mode below the cut.
RUNG_LOG2 = 0.5


@dataclass
class _Basis:
    """One parameter point's reduction (everything ``O(n_dof r)``)."""

    mass: Any
    stiffness: Any
    damping: Any
    input_matrix: np.ndarray
    output_matrix: np.ndarray
    lu: Any  # splu of K - sigma M (a _ScaledFactor of a scaled root's; None: made again by _factor)
    sigma: float
    V: np.ndarray  # (n, r) M-orthonormal Ritz vectors, K-orthogonal
    lam: np.ndarray  # (r,) Ritz values w^2 (rad/s)^2
    n_exact: int  # leading Ritz vectors that are exact modes
    lam_cut: float  # largest exact eigenvalue w_cut^2
    resid_in: np.ndarray  # (m,) residual flexibility b_i^T R b_i (m/N)
    resid_out: np.ndarray  # (p,) c_o R c_o^T
    Vb: np.ndarray = None  # (r, m) V^T b
    c_v: np.ndarray = None  # (p, r) c V
    VCV: np.ndarray | None = None  # (r, r) V^T Cs V, None without dashpots
    attached: Any = None  # OrderedDict DOF set -> projected attachment block (_attachment)
    complete_to: float = 0.0  # every mode of the structure up to this w^2 ((rad/s)^2) is in V exactly
    scale: tuple | None = None  # (s, rho, d_m) of a scaled root (_scaled_basis; lu a _ScaledFactor of it)


def _max_changed(n: int) -> int:
    """The most DOFs a change of an ``n``-DOF structure may touch and be a low-rank modification
    (:data:`LOW_RANK_MAX_DOFS`, or a group's :data:`GROUP_MAX_DOFS` within :data:`GROUP_MAX_SHARE`)."""
    return max(LOW_RANK_MAX_DOFS, min(GROUP_MAX_DOFS, int(GROUP_MAX_SHARE * n)))


def _factor(base: _Basis) -> Any:
    """The base's sparse factor of ``K - sigma M``, made again where it did not travel (a basis
    unpickled in a worker process: the same ``splu`` call as :func:`_reduce`, the same factor)."""
    if base.lu is None:
        base.lu = spla.splu((base.stiffness - base.sigma * base.mass).tocsc())
    return base.lu


def _csc(a: Any) -> sp.csc_matrix:
    return sp.csc_matrix(a) if sp.issparse(a) else sp.csc_matrix(np.asarray(a, dtype=float))


def _m_orthonormal(X: np.ndarray, M: Any, V: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Columns of ``X`` M-orthogonalised against ``V`` (twice: Gram-Schmidt with
    re-orthogonalisation) and M-orthonormalised among themselves, dependent ones dropped: those
    below ``tol`` of the largest, and all when what is left of ``X`` is rounding (below 1e-16 of its
    squared M-norm before: ``X`` in the span of ``V``, a basis that holds every mode)."""
    before = float(np.max(np.einsum("ij,ij->j", X, np.asarray(M @ X)), initial=0.0))
    for _ in range(2):
        X = X - V @ (V.T @ (M @ X))
    G = X.T @ (M @ X)
    G = 0.5 * (G + G.T)
    d, U = np.linalg.eigh(G)
    keep = d > max(tol * float(d.max(initial=0.0)), 1e-16 * before, 1e-300)
    return X @ (U[:, keep] / np.sqrt(d[keep]))


def _count_below(K: Any, M: Any, lam: float) -> int | None:
    """How many eigenvalues of ``K phi = w^2 M phi`` lie below ``lam``: the negative pivots of
    the symmetric factorisation of ``K - lam M`` (Sylvester's law of inertia; Golub & Van
    Loan, *Matrix Computations*, 4th ed., Thm. 8.1.17), so that one Lanczos run asks for the
    right number of modes. None when the unpivoted factorisation breaks down."""
    try:
        lu = spla.splu((K - lam * M).tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:
        return None
    d = lu.U.diagonal()
    if not np.all(np.isfinite(d)):
        return None
    return int(np.count_nonzero(d < 0))


#: A reduction asking for at least this share of a structure's modes (a softened rung of
#: :class:`_Reducer`: 724 of 2,000 at half the stiffness) of no more than :data:`DENSE_MAX_DOF` DOFs
#: takes them from a dense symmetric-definite eigensolver (LAPACK ``dsygvx``, the ``k`` lowest
#: modes): a shift-invert Lanczos run for that many modes costs twice as much (5.3 s against 2.0 s
#: at 2,000 DOFs).
DENSE_SHARE = 0.25
#: The largest structure whose modes :func:`_reduce` may take from a dense eigensolver (its dense
#: ``M`` and ``K``: 2 x 8 n^2 bytes, 400 MB at 5,000 DOFs).
DENSE_MAX_DOF = 5_000


def _dense_modes(M: Any, K: Any, k: int, lam_cut: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The ``k`` lowest eigenpairs ``(lam, phi)`` of ``K phi = lam M phi`` by a dense solve (twice as
    many while the highest is not above ``lam_cut``, (rad/s)^2, as the Lanczos loop of
    :func:`_reduce`), or None when ``M`` is not positive definite (a massless DOF: the caller's
    Lanczos run copes)."""
    n = M.shape[0]
    Kd, Md = K.toarray(), M.toarray()
    while True:
        try:
            lam, phi = sla.eigh(Kd, Md, subset_by_index=(0, k - 1), driver="gvx")
        except (np.linalg.LinAlgError, ValueError):
            return None
        if lam[-1] > lam_cut or k >= n:
            return lam, phi
        k = min(2 * k, n)


def _reduce(mats: Any, f_cut_hz: float) -> _Basis:
    """The Ritz basis of one structure: exact modes below ``f_cut_hz`` plus two attachment
    (Krylov) blocks of the inputs (module docstring)."""
    M, K = _csc(mats.mass), _csc(mats.stiffness)
    check_structural_matrices(M, K)
    n = M.shape[0]
    k_scale = float(abs(K).max() / max(abs(M).max(), 1e-300))
    sigma = -1e-6 * k_scale - 1.0  # K - sigma M positive definite, rigid-body modes included
    try:
        lu = spla.splu((K - sigma * M).tocsc())
    except RuntimeError as exc:
        raise ModelError(
            f"the shifted stiffness K - sigma M is singular ({exc}); check the matrices."
        ) from None
    op = spla.LinearOperator((n, n), matvec=lu.solve, dtype=float)
    lam_cut = (2 * np.pi * f_cut_hz) ** 2
    # a fixed start vector (ARPACK's default is random): the same structure gives the same
    # basis in every process, so worker processes reproduce the serial result
    v0 = np.linspace(1.0, 2.0, n)
    below = _count_below(K, M, lam_cut)
    k = min(max(12, n // 50) if below is None else below + 4, n - 2)
    dense = _dense_modes(M, K, k, lam_cut) if n <= DENSE_MAX_DOF and k >= DENSE_SHARE * n else None
    while dense is None:
        lam, phi = spla.eigsh(K, k=k, M=M, sigma=sigma, which="LM", OPinv=op, v0=v0)
        order = np.argsort(lam)
        lam, phi = lam[order], phi[:, order]
        if lam[-1] > lam_cut or k >= n - 2:
            break
        k = min(2 * k, n - 2)
    if dense is not None:
        lam, phi = dense
    lam = _clean_eigenvalues(lam, k_scale)
    keep = lam <= lam_cut
    keep[: max(1, int(np.count_nonzero(keep)))] = True
    lam, phi = lam[keep], phi[:, keep]
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))  # mass-normalised
    return _attach(mats, M, K, lu, sigma, lam, phi, lam_cut)


def _attach(mats: Any, M: Any, K: Any, lu: Any, sigma: float, lam: np.ndarray, phi: np.ndarray,
            complete_to: float) -> _Basis:
    """The Ritz basis from the exact modes ``(lam, phi)`` (mass-normalised) and the factor ``lu``
    of ``K - sigma M``: the attachment (Krylov) blocks of the inputs, the Ritz problem, the
    residual flexibilities (module docstring). ``complete_to`` ((rad/s)^2): every mode below it is
    among ``lam``."""
    b = np.asarray(mats.input_matrix, dtype=float)
    c = np.asarray(mats.output_matrix, dtype=float)
    A1 = lu.solve(b)
    A2 = lu.solve(np.asarray(M @ A1))
    X = _m_orthonormal(np.hstack([A1, A2]), M, phi)
    Kx = X.T @ (K @ X)
    mu, U = np.linalg.eigh(0.5 * (Kx + Kx.T))
    V = np.hstack([phi, X @ U])
    lam_all = np.concatenate([lam, mu])
    shifted = 1.0 / (lam - sigma)
    static_b = np.einsum("ij,ij->j", b, A1) - np.sum((phi.T @ b) ** 2 * shifted[:, None], axis=0)
    Ac = lu.solve(c.T)
    static_c = np.einsum("ij,ij->j", c.T, Ac) - np.sum((c @ phi) ** 2 * shifted[None, :], axis=1)
    Cs = None if mats.damping is None else _csc(mats.damping)
    # rounding of the difference: a floor of 1e-12 of the static flexibility itself
    floor_b = 1e-12 * np.abs(np.einsum("ij,ij->j", b, A1))
    floor_c = 1e-12 * np.abs(np.einsum("ij,ij->j", c.T, Ac))
    return _Basis(M, K, Cs, b, c, lu, sigma, V, lam_all, int(lam.size), float(lam[-1]),
                  np.maximum(static_b, floor_b), np.maximum(static_c, floor_c), V.T @ b, c @ V,
                  None if Cs is None else V.T @ np.asarray(Cs @ V), complete_to=float(complete_to))


#: A structure whose matrices differ from a reduced one's everywhere (an update parameter: a
#: stiffness scale, a material constant) reuses that reduction's exact modes as a Ritz basis
#: when the Ritz pairs below the cut are eigenpairs to this relative residual ``|K x - lam M x| /
#: (|K x| + lam |M x|)`` and Sylvester's count confirms that no mode is missing below the cut:
#: the basis is then that of a fresh reduction, without the Lanczos run (a uniform stiffness
#: scale passes; a softened structure whose modes come down into the cut does not).
REUSE_TOL = 1e-7


def _scale_and_change(new: Any, old: Any, rows: set, spread_tol: float | None = None) -> tuple | None:
    """``(alpha, change)`` with ``new = alpha old + change``: ``alpha`` the median ratio of the
    entries, ``change`` (csc) the entries of ``new - alpha old`` above 1e-9 of ``new``'s largest,
    their rows and columns added to ``rows``. None when the sparsity patterns differ, ``alpha <=
    0``, or (``spread_tol``) an entry left out exceeds ``spread_tol`` times ``new``'s largest."""
    both = new.multiply(old).tocoo()
    ref = old.multiply(old).tocoo()
    if both.nnz == 0 or ref.nnz != both.nnz:
        return None
    alpha = float(np.median(both.data / ref.data))
    if not alpha > 0:
        return None
    d = sp.coo_matrix(new - alpha * old)
    top = max(float(abs(new).max()), 1e-300)
    big = np.abs(d.data) > 1e-9 * top
    if spread_tol is not None and np.any(np.abs(d.data[~big]) > spread_tol * top):
        return None
    rows.update(d.row[big].tolist())
    rows.update(d.col[big].tolist())
    return alpha, sp.csc_matrix((d.data[big], (d.row[big], d.col[big])), shape=new.shape)


class _ScaledFactor:
    """The factor of ``c (K0 - sigma M0)`` from the root reduction ``root``'s factor of ``K0 - sigma M0``
    (:func:`_factor`): each solve is the root's divided by ``c`` (no new factorisation)."""

    def __init__(self, root: _Basis, c: float) -> None:
        self.root, self.c = root, float(c)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return _factor(self.root).solve(rhs) / self.c


#: Entries of a structure left over when its change is taken out, up to this fraction of its largest
#: entry, count as the rounding of a scale (:func:`_scale_split`); the change itself is what exceeds
#: 1e-9 of it, as in :func:`_scale_and_change`.
SCALE_ROUNDING = 1e-12


def _same_io(base: _Basis, mats: Any) -> bool:
    """Whether ``mats`` has the base's input and output matrices."""
    return (np.array_equal(np.asarray(mats.input_matrix, dtype=float), base.input_matrix)
            and np.array_equal(np.asarray(mats.output_matrix, dtype=float), base.output_matrix))


def _scale_split(root: _Basis, mats: Any,
                 io: bool = False) -> tuple[float, float, tuple[np.ndarray, list]] | None:
    """``(alpha_M, alpha_K, change)`` with ``mats`` = the root's mass and stiffness times ``alpha_M``,
    ``alpha_K`` plus a change at no more than :func:`_max_changed` DOFs: ``change = (J, [dM, dK, dC])``
    as :func:`_changed_dofs` gives it (``dM``, ``dK`` the entries of ``M - alpha_M M0``, ``K - alpha_K
    K0`` above 1e-9 of the largest, ``dC`` the difference from the root's damping); None when the
    inputs or outputs differ (unless ``io``), the patterns differ, an entry left out exceeds
    :data:`SCALE_ROUNDING` of the largest, or the change touches more DOFs. A function of ``root``
    and ``mats`` alone."""
    M, K = _csc(mats.mass), _csc(mats.stiffness)
    n = root.mass.shape[0]
    if M.shape != root.mass.shape:
        return None
    if not io and not _same_io(root, mats):
        return None
    alphas, changes, rows = [], [], set()
    for new, old in ((M, root.mass), (K, root.stiffness)):
        split = _scale_and_change(new, old, rows, spread_tol=SCALE_ROUNDING)
        if split is None or len(rows) > _max_changed(n):
            return None
        alphas.append(split[0])
        changes.append(split[1])
    if mats.damping is None and root.damping is None:
        d_c = None
    else:
        zero = sp.csc_matrix((n, n))
        d_c = sp.csc_matrix(_csc(mats.damping if mats.damping is not None else zero)
                            - (root.damping if root.damping is not None else zero))
        d_c.eliminate_zeros()
        coo = d_c.tocoo()
        rows.update(coo.row.tolist())
        rows.update(coo.col.tolist())
        if len(rows) > _max_changed(n):
            return None
    dofs = np.array(sorted(rows), dtype=int)
    blocks = [np.asarray(c[dofs][:, dofs].toarray(), dtype=float) if c is not None
              else np.zeros((dofs.size, dofs.size)) for c in (*changes, d_c)]
    return alphas[0], alphas[1], (dofs, blocks)


def _scaled_matrices(root: _Basis, a_m: float, a_k: float) -> tuple[Any, Any, Any]:
    """The root's mass and stiffness times ``a_m``, ``a_k`` (csc) and a stand-in for its matrices'
    inputs, outputs and damping (what :func:`_attach` and :func:`_reuse_or_extend` read)."""
    Ms = root.mass if a_m == 1.0 else (root.mass * a_m).tocsc()
    Ks = root.stiffness if a_k == 1.0 else (root.stiffness * a_k).tocsc()
    io = SimpleNamespace(mass=Ms, stiffness=Ks, damping=root.damping, input_matrix=root.input_matrix,
                         output_matrix=root.output_matrix)
    return Ms, Ks, io


def _with_io(base: _Basis, mats: Any) -> _Basis:
    """``base``'s structure with the inputs and outputs of ``mats``: its exact modes, factor and shift
    with the attachment (Krylov) blocks of the new inputs (:func:`_attach`: a few solves)."""
    io = SimpleNamespace(input_matrix=mats.input_matrix, output_matrix=mats.output_matrix,
                         damping=base.damping)
    n = base.n_exact
    return _attach(io, base.mass, base.stiffness, _factor(base), base.sigma, base.lam[:n], base.V[:, :n],
                   base.complete_to)


def _scaled_basis(root: _Basis, a_m: float, a_k: float, point: bool, lam_cut: float) -> _Basis | None:
    """The reduction of ``a_m M0``, ``a_k K0`` (``M0``, ``K0`` the root reduction ``root``'s matrices)
    read off the root's, or None when the scale brought modes into the cut ``lam_cut`` ((rad/s)^2)
    that the root lacks; a function of its arguments alone (the same in every process, whatever was
    evaluated before). ``point``: the change to go on top touches no more than
    :data:`LOW_RANK_MAX_DOFS` DOFs.

    Scaling ``M0`` by ``a_m`` and ``K0`` by ``a_k`` scales every eigenvalue by ``rho = a_k / a_m``
    and every mass-normalised shape by ``1 / sqrt(a_m)``, and ``K - rho sigma M = a_k (K0 - sigma
    M0)``: the root's exact modes (scaled), its factor (each solve divided by ``a_k``), its
    attachment vectors of the inputs (a multiple of the same Krylov vectors, hence the same Ritz
    vectors) and the projected attachment blocks of changed DOFs (:func:`_attachment`, made on the
    root and scaled: ``X_J``, ``X^T b``, ``c X`` by ``1 / sqrt(a_m)``, ``V^T K X``, ``X^T K X`` by
    ``rho``, the damping blocks by ``1 / a_m``) are the scaled structure's reduction with the shift
    ``rho sigma``: no Ritz step, factorisation or solve. A mode the scale lifts over the cut stays
    exact when the change is a group's (over :data:`LOW_RANK_MAX_DOFS` DOFs), so that the
    attachment blocks stay the root's (a larger basis than a fresh reduction's, as accurate against
    the full model); with a point change or none (``point``) it is left out and the inputs'
    attachment vectors are solved again with the scaled factor (a few solves: a fresh reduction's
    basis but for its shift). The basis holds every mode up to ``rho`` times the root's
    ``complete_to``; when that falls below the cut, Sylvester's count (:func:`_count_below`) must
    find no mode missing there, else None (the caller reduces the scaled structure another way)."""
    if a_m == 1.0 and a_k == 1.0:
        return root
    rho = a_k / a_m
    lam = root.lam * rho
    complete_to = root.complete_to * rho
    Ms, Ks, io = _scaled_matrices(root, a_m, a_k)
    if not complete_to >= lam_cut:  # the scale may have brought modes into the cut
        below = _count_below(Ks, Ms, lam_cut)
        if below is None or below != int(np.count_nonzero(lam[: root.n_exact] <= lam_cut)):
            return None
        complete_to = lam_cut
    s = 1.0 if a_m == 1.0 else 1.0 / np.sqrt(a_m)
    d_m = 1.0 if a_m == 1.0 else 1.0 / a_m

    def sc(x, f):
        return x if (x is None or f == 1.0) else x * f

    lu = _ScaledFactor(root, a_k)
    above = lam[: root.n_exact] > lam_cut
    if np.any(above) and point:
        # modes lifted over the cut, and a change whose attachment vectors are few (a point effect,
        # or none): the modes a fresh reduction keeps, the inputs' attachment vectors solved again
        # with the scaled factor (a few solves); the result is a fresh reduction's but for its shift
        keep = ~above
        if not np.any(keep):
            return None
        phi = sc(root.V[:, : root.n_exact][:, keep], s)
        # every mode up to the cut is kept, none above it
        return _attach(io, Ms, Ks, lu, root.sigma * rho, lam[: root.n_exact][keep], phi,
                       min(complete_to, lam_cut))
    return replace(root, mass=Ms, stiffness=Ks, lu=lu, sigma=root.sigma * rho, V=sc(root.V, s),
                   lam=lam, lam_cut=root.lam_cut * rho, resid_in=root.resid_in / a_k,
                   resid_out=root.resid_out / a_k, Vb=sc(root.Vb, s), c_v=sc(root.c_v, s),
                   VCV=sc(root.VCV, d_m), attached=None, complete_to=float(complete_to),
                   scale=(float(s), float(rho), float(d_m)))


def _shift_factor(M: Any, K: Any) -> tuple[float, float, Any] | None:
    """The stiffness scale ``max|K| / max|M|`` ((rad/s)^2), the shift ``sigma`` below every mode (rigid-body
    modes included) and the sparse LU of ``K - sigma M``; None when the factorisation fails."""
    k_scale = float(abs(K).max() / max(abs(M).max(), 1e-300))
    sigma = -1e-6 * k_scale - 1.0
    try:
        return k_scale, sigma, spla.splu((K - sigma * M).tocsc())
    except RuntimeError:
        return None


def _ritz(phi0: np.ndarray, M: Any, K: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Rayleigh-Ritz of ``(K, M)`` on the basis ``phi0``: the Ritz values ((rad/s)^2), their vectors in
    ``phi0``'s coordinates and each pair's relative residual ``|K x - lam M x| / (|K x| + |lam| |M x|)``;
    None when the reduced pencil is not symmetric positive definite."""
    KP, MP = np.asarray(K @ phi0), np.asarray(M @ phi0)
    Kr, Mr = phi0.T @ KP, phi0.T @ MP
    try:
        lam, psi = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T))
    except (np.linalg.LinAlgError, ValueError):
        return None
    Kx, Mx = KP @ psi, MP @ psi
    scale = np.linalg.norm(Kx, axis=0) + np.abs(lam) * np.linalg.norm(Mx, axis=0)
    return lam, psi, np.linalg.norm(Kx - Mx * lam, axis=0) / np.maximum(scale, 1e-300)


def _reuse(base: _Basis, mats: Any, lam_cut: float, ritz: Any = None) -> _Basis | None:
    """The reduction of ``mats`` from ``base``'s exact modes (:data:`REUSE_TOL`) up to the cut
    ``lam_cut`` ((rad/s)^2), the same modes a fresh reduction keeps, or None. ``ritz``: the
    Rayleigh-Ritz step of ``mats`` on those modes (:func:`_ritz`), when the caller has it."""
    M, K = _csc(mats.mass), _csc(mats.stiffness)
    if M.shape != base.mass.shape:
        return None
    phi0, lam0 = base.V[:, : base.n_exact], base.lam[: base.n_exact]
    if ritz is None:
        if (M - base.mass).count_nonzero() == 0 and (K - base.stiffness).count_nonzero() == 0:  # new I/O only
            return _attach(mats, M, K, _factor(base), base.sigma, lam0, phi0, base.complete_to)
        check_structural_matrices(M, K)
        ritz = _ritz(phi0, M, K)
    if ritz is None:
        return None
    lam, psi, rel = ritz
    keep = lam <= lam_cut
    if not np.all(rel[keep] <= REUSE_TOL) or not np.any(keep):
        return None
    if _count_below(K, M, lam_cut) != int(np.count_nonzero(keep)):  # a mode came into the cut
        return None
    lam, psi = lam[keep], psi[:, keep]
    shifted = _shift_factor(M, K)
    if shifted is None:
        return None
    k_scale, sigma, lu = shifted
    phi = phi0 @ psi
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))
    return _attach(mats, M, K, lu, sigma, lam, phi, lam_cut)


#: :func:`_extend` completes a reused basis when at most this share of the cut's modes (and at
#: least 8) came into the cut; more, and a fresh reduction costs about the same.
EXTEND_MAX_SHARE = 0.25


def _extend(base: _Basis, mats: Any, lam_cut: float, ritz: Any = None) -> _Basis | None:
    """The reduction of a structure whose modes below the cut include ``base``'s exact modes, made
    eigenpairs to :data:`REUSE_TOL` by the Rayleigh-Ritz step of :func:`_reuse` (a uniformly
    softer structure, an update parameter's step down), plus the few modes that came into the cut
    ``lam_cut`` ((rad/s)^2); None when the base's modes are not eigenpairs of it or more than
    :data:`EXTEND_MAX_SHARE` of the modes are new.

    The base holds every mode below its cut, so the new ones lie between the largest Ritz value
    ``lam_top`` and ``lam_cut``; Sylvester's count (:func:`_count_below`) says how many, ``m``. A
    shift-invert Lanczos run about the middle of that interval for its ``m + 8`` nearest modes
    finds them (any mode outside the interval is farther from the shift than every mode in it):
    a factor and a handful of modes instead of all of them. The basis is then that of a fresh
    reduction (the same exact modes, attachment vectors from its own factor). ``ritz``: as for
    :func:`_reuse`."""
    M, K = _csc(mats.mass), _csc(mats.stiffness)
    if M.shape != base.mass.shape:
        return None
    phi0 = base.V[:, : base.n_exact]
    if ritz is None:
        check_structural_matrices(M, K)
        ritz = _ritz(phi0, M, K)
    if ritz is None:
        return None
    lam, psi, rel = ritz
    if not np.all(rel <= REUSE_TOL) or not lam[-1] < lam_cut:
        return None
    total = _count_below(K, M, lam_cut)
    missing = None if total is None else total - lam.size
    if missing is None or missing <= 0 or missing > max(8, EXTEND_MAX_SHARE * lam.size):
        return None
    n = M.shape[0]
    mid = 0.5 * (float(lam[-1]) + lam_cut)
    try:
        lu_mid = spla.splu((K - mid * M).tocsc())
        op = spla.LinearOperator((n, n), matvec=lu_mid.solve, dtype=float)
        lam_new, phi_new = spla.eigsh(K, k=min(missing + 8, n - 2), M=M, sigma=mid, which="LM", OPinv=op,
                                      v0=np.linspace(1.0, 2.0, n))
    except (RuntimeError, spla.ArpackError):
        return None
    inside = (lam_new > lam[-1] + 1e-7 * lam_cut) & (lam_new <= lam_cut)  # not the top mode again
    if int(np.count_nonzero(inside)) != missing:
        return None
    shifted = _shift_factor(M, K)
    if shifted is None:
        return None
    k_scale, sigma, lu = shifted
    lam_all = np.concatenate([lam, _clean_eigenvalues(lam_new[inside], k_scale)])
    order = np.argsort(lam_all, kind="stable")
    phi = np.hstack([phi0 @ psi, phi_new[:, inside]])[:, order]
    phi = phi / np.sqrt(np.einsum("ij,ij->j", phi, M @ phi))
    return _attach(mats, M, K, lu, sigma, lam_all[order], phi, lam_cut)


def _reuse_or_extend(base: _Basis, mats: Any, lam_cut: float) -> _Basis | None:
    """:func:`_reuse`, else :func:`_extend`, from one Rayleigh-Ritz step of ``mats`` on the base's
    exact modes (the same inputs give both the same step)."""
    M, K = _csc(mats.mass), _csc(mats.stiffness)
    if M.shape != base.mass.shape:
        return None
    if (M - base.mass).count_nonzero() == 0 and (K - base.stiffness).count_nonzero() == 0:
        return _reuse(base, mats, lam_cut)  # new I/O only: the base's own modes
    check_structural_matrices(M, K)
    ritz = _ritz(base.V[:, : base.n_exact], M, K)
    if ritz is None:
        return None
    out = _reuse(base, mats, lam_cut, ritz)
    return out if out is not None else _extend(base, mats, lam_cut, ritz)


def _changed_dofs(base: _Basis, mats: Any) -> tuple[np.ndarray, list] | None:
    """The DOFs ``J`` where ``mats`` differ from the base's matrices and the changes ``(dM, dK,
    dC)`` there (dense ``|J| x |J|`` blocks), or None when they differ elsewhere too (inputs,
    outputs, more than :data:`LOW_RANK_MAX_DOFS` DOFs)."""
    if mats.mass.shape != base.mass.shape:
        return None
    if not (np.array_equal(np.asarray(mats.input_matrix, dtype=float), base.input_matrix)
            and np.array_equal(np.asarray(mats.output_matrix, dtype=float), base.output_matrix)):
        return None
    n = base.mass.shape[0]
    diffs = []
    rows: set[int] = set()
    for new, old in ((mats.mass, base.mass), (mats.stiffness, base.stiffness), (mats.damping, base.damping)):
        if new is None and old is None:
            diffs.append(None)
            continue
        d = sp.coo_matrix(_csc(new if new is not None else sp.csc_matrix((n, n)))
                          - (old if old is not None else sp.csc_matrix((n, n))))
        nz = d.data != 0
        d = (d.row[nz], d.col[nz], d.data[nz])
        rows.update(d[0].tolist())
        rows.update(d[1].tolist())
        if len(rows) > _max_changed(n):
            return None
        diffs.append(d)
    dofs = np.array(sorted(rows), dtype=int)
    where = {int(k): i for i, k in enumerate(dofs)}
    blocks = []
    for d in diffs:
        block = np.zeros((dofs.size, dofs.size))
        if d is not None:
            for r, c, v in zip(*d):
                block[where[int(r)], where[int(c)]] += v
        blocks.append(block)
    return dofs, blocks


def _ritz_modal(base: _Basis, mats: Any, change: tuple[np.ndarray, list]):
    """Undamped modal data of ``mats`` in the base's Ritz basis ``V``, augmented by the
    attachment vectors ``X`` of the changed DOFs ``J`` (none: the base structure itself).

    With ``W = [V, X]`` M0-orthonormal (``V^T K0 V = diag(lam)``), the projected matrices are
    ``W^T M W = I + W_J^T dM W_J`` and ``W^T K W = [[diag(lam), V^T K0 X], [., X^T K0 X]] +
    W_J^T dK W_J``: ``O(n_dof r |J|)`` to form, ``O((r + |J|)^3)`` to solve; the modal input
    and output matrices follow from ``V^T b``, ``c V`` kept with the base (the ``n_dof x r``
    mode shapes are never formed)."""
    dofs, (dM, dK, dC) = change
    V = base.V
    Vb, cV = base.Vb, base.c_v
    if dofs.size:
        XJ, VKX, XKX, Xb, cX, VCX, XCX = _attachment(base, dofs)
        WJ = np.hstack([V[dofs], XJ])
        r, q = V.shape[1], XJ.shape[1]
        Kr = np.zeros((r + q, r + q))
        Kr[np.diag_indices(r)] = base.lam
        Kr[:r, r:] = VKX
        Kr[r:, :r] = Kr[:r, r:].T
        Kr[r:, r:] = XKX
        Kr += WJ.T @ dK @ WJ
        if np.any(dM):
            Mr = np.eye(r + q) + WJ.T @ dM @ WJ
            lam, psi = sla.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T))
        else:  # W^T M W = I: LAPACK's generalized driver (sygvd) is syevd after an identity transform
            lam, psi = sla.eigh(0.5 * (Kr + Kr.T), driver="evd")
        Wb = np.vstack([Vb, Xb])
        cW = np.hstack([cV, cX])
        WCW = None
        if base.damping is not None or np.any(dC):
            WCW = np.zeros((r + q, r + q))
            if base.VCV is not None:
                WCW[:r, :r] = base.VCV
            WCW[:r, r:] = VCX
            WCW[r:, :r] = WCW[:r, r:].T
            WCW[r:, r:] = XCX
            WCW += WJ.T @ dC @ WJ
    else:
        lam, psi, Wb, cW, WCW = base.lam, None, Vb, cV, base.VCV
    k_scale = float(abs(base.stiffness).max() / max(abs(base.mass).max(), 1e-300))
    lam = _clean_eigenvalues(lam, k_scale)
    order = np.argsort(lam, kind="stable")
    lam = lam[order]
    if psi is None:
        input_shapes, output_shapes = Wb[order], cW[:, order]
        cs = None if WCW is None else WCW[np.ix_(order, order)]
    else:
        psi = psi[:, order]
        input_shapes, output_shapes = psi.T @ Wb, cW @ psi
        cs = None if WCW is None else psi.T @ WCW @ psi
    return ModalData(
        omega=np.sqrt(lam),
        zeta=np.zeros(lam.size),
        input_shapes=input_shapes,
        output_shapes=output_shapes,
        output_kinds=tuple(mats.output_kinds),
        inputs=tuple(mats.inputs),
        outputs=tuple(mats.outputs),
        modal_concentrated_damping=cs,
    )


def _attachment(base: _Basis, dofs: np.ndarray) -> tuple:
    """The attachment block of the DOFs ``dofs`` on ``base``, projected: ``X = K_sigma^-1 E_J``
    M-orthonormalised against the Ritz vectors ``V`` (static correction vectors of the changed
    DOFs), returned as ``(X_J, V^T K X, X^T K X, X^T b, c X, V^T Cs X, X^T Cs X)`` (the last two
    zero without dashpots): everything :func:`_ritz_modal` needs, ``O((r + |J|) |J|)`` numbers.

    Made once per DOF set and base (``|J|`` solves with the base's factor and ``O(n_dof r |J|)``
    products; the ``n_dof x |J|`` block itself is not kept) and kept with the base
    (:data:`_ATTACH_KEEP` sets, least recently used dropped): a candidate fitted over several sizes,
    an element group's change above all, pays for its attachment vectors once. A scaled root
    (:func:`_scaled_basis`) takes the root's block, scaled: the same numbers whatever was evaluated
    before."""
    if base.scale is not None:  # a scaled root: the root's block, scaled (_scaled_basis)
        s, rho, d_m = base.scale
        XJ, VKX, XKX, Xb, cX, VCX, XCX = _attachment(base.lu.root, dofs)
        return (XJ * s, VKX * rho, XKX * rho, Xb * s, cX * s, VCX * d_m, XCX * d_m)
    key = dofs.tobytes()
    with _ATTACH_LOCK:
        cache = base.attached
        if cache is not None and key in cache:
            cache.move_to_end(key)
            return cache[key]
    V = base.V
    E = np.zeros((V.shape[0], dofs.size))
    E[dofs, np.arange(dofs.size)] = 1.0
    X = _m_orthonormal(_factor(base).solve(E), base.mass, V)
    KX = np.asarray(base.stiffness @ X)
    # without dashpots in the structure the damping blocks are zero (a dashpot candidate adds its own)
    CsX = np.zeros_like(X) if base.damping is None else np.asarray(base.damping @ X)
    block = (X[dofs], V.T @ KX, X.T @ KX, X.T @ base.input_matrix, base.output_matrix @ X,
             V.T @ CsX, X.T @ CsX)
    with _ATTACH_LOCK:
        if base.attached is None:
            base.attached = OrderedDict()
        base.attached[key] = block
        while len(base.attached) > _ATTACH_KEEP:
            base.attached.popitem(last=False)
    return block


def _content_key(mats: Any) -> bytes:
    """A digest of a structure's matrices (mass, stiffness, damping, inputs, outputs: their values
    and sparse layout), the key of its own reduction in :class:`_Reducer`."""
    h = hashlib.blake2b(digest_size=20)
    for a in (mats.mass, mats.stiffness, mats.damping):
        if a is None:
            h.update(b"none")
            continue
        a = _csc(a)
        h.update(np.asarray(a.shape, dtype=np.int64).tobytes())
        for part in (a.indptr, a.indices, a.data):
            h.update(np.ascontiguousarray(part).tobytes())
    h.update(_io_key(mats))
    return h.digest()


def _io_key(mats: Any) -> bytes:
    """A digest of a structure's input and output matrices."""
    h = hashlib.blake2b(digest_size=20)
    for a in (mats.input_matrix, mats.output_matrix):
        a = np.ascontiguousarray(np.asarray(a, dtype=float))
        h.update(np.asarray(a.shape, dtype=np.int64).tobytes())
        h.update(a.tobytes())
    return h.digest()


class _Reducer:
    """The reduced bases of one model: each evaluation's basis a function of the model and the
    structure evaluated alone (never of what was evaluated before), so that serial work, threads and
    worker processes give the same results bit for bit.

    The *root* is the reduction (:func:`_reduce`) of the model's structure at its own parameter
    values, ``root_mats`` (made once, when first needed). A structure is then, in this order:

    1. the root plus a change at a few DOFs (:func:`_changed_dofs`): the root with that change;
    2. the root scaled (``alpha_M M0``, ``alpha_K K0``: an update parameter on the whole stiffness, or
       on one property group beside the diagnosis's change) plus such a change (:func:`_scale_split`):
       the scaled root (:func:`_scaled_basis`, no solve), or, when the scale brought modes into the
       cut, the scaled structure's own reduction from the root's modes (:func:`_reuse_or_extend`),
       with that change;
    3. (``anchor``: the structure of the model without its last effect, a candidate's model; for an
       effect that adds DOFs, the model with it at sizes rounded down to a power of two) a change at
       a few DOFs of the anchor's own reduction (4.);
    4. its own reduction: from the root's modes when they are its eigenpairs
       (:func:`_reuse_or_extend`), else a fresh Lanczos run.

    Each basis made is kept (least recently used dropped, :data:`_KEEP`) under a key that determines
    it: the scale factors, or the digest of the structure's matrices (:func:`_content_key`); a basis
    dropped and made again is the same bit for bit (the Lanczos start vector is fixed, the sparse
    factor the same ``splu`` call). Thread-safe; pickled with the root and its attachment blocks (no
    factor) and the most recently used basis when it cost a reduction.

    Parameters
    ----------
    f_cut_hz : float
        Exact modes are kept up to this frequency (Hz).
    root_mats : StructuralMatrices, optional
        The model's structure at its parameter values; None: no root (every structure is reduced
        on its own, step 4 without the root's modes).
    """

    def __init__(self, f_cut_hz: float, root_mats: Any = None) -> None:
        self.f_cut_hz = float(f_cut_hz)
        self._root_mats = root_mats
        self._root: _Basis | None = None
        self._memo: OrderedDict[tuple, _Basis] = OrderedDict()
        self._refused: OrderedDict[tuple, None] = OrderedDict()  # keys whose basis is None
        self._lock = threading.Lock()
        self._building: dict[tuple, threading.Lock] = {}
        self._evaluations = 0
        self._modal: OrderedDict[tuple, Any] = OrderedDict()  # structure digest -> modal data
        self._token = uuid.uuid4().hex

    @property
    def _bases(self) -> OrderedDict:
        """The bases held: the root (key ``"root"``) first, then the others, least recently used first."""
        with self._lock:
            out = OrderedDict() if self._root is None else OrderedDict(root=self._root)
            out.update(self._memo)
        return out

    def __reduce__(self):
        # the root travels (without its factor, which does not pickle: the same splu call makes it
        # again, bit for bit) with its attachment blocks, and the most recently used basis when it
        # cost a Ritz step or a Lanczos run (a scaled root is cheap to make again): a worker process
        # then starts without a Lanczos run of its own (23 s at 20,000 DOFs) or a seam's attachment
        # vectors (250 solves); every copy of one reducer in a process is one object
        # (:func:`_restored_reducer`)
        with self._lock:
            root = self._root
            last = next(reversed(self._memo.items()), None)
        if last is not None and (last[1].scale is not None or isinstance(last[1].lu, _ScaledFactor)):
            last = None  # a scaled root: made again from the root in no time

        def bare(b):
            with _ATTACH_LOCK:
                attached = None if b.attached is None else OrderedDict(b.attached)
            return replace(b, lu=None, attached=attached)

        return _restored_reducer, (self._token, self.f_cut_hz, self._root_mats if root is None else None,
                                   None if root is None else bare(root),
                                   None if last is None else (last[0], bare(last[1])))

    # ------------------------------------------------------------------ the bases
    def _root_basis(self) -> _Basis | None:
        """The root reduction (made once), or None without root matrices or when they cannot be
        reduced."""
        if self._root is None and self._root_mats is not None:
            with self._lock:
                lock = self._building.setdefault(("root",), threading.Lock())
            with lock:
                if self._root is None and self._root_mats is not None:
                    with contextlib.suppress(ModelError):  # else each structure is reduced on its own
                        self._root = _reduce(self._root_mats, self.f_cut_hz)
                    self._root_mats = None  # the root holds the matrices (or is not to be had)
        return self._root

    def _held(self, key: tuple) -> tuple[bool, _Basis | None]:
        """``(True, basis)`` when ``key``'s basis is kept (marked most recently used), ``(True, None)``
        when its build was refused, else ``(False, None)``; the caller holds ``self._lock``."""
        if key in self._memo:
            self._memo.move_to_end(key)
            return True, self._memo[key]
        return key in self._refused, None

    def _memoized(self, key: tuple, build: Any, keep: int = _KEEP) -> _Basis | None:
        """The basis ``build()`` kept under ``key`` (made once while it is kept; two threads asking
        for it at once wait for one build); ``keep``: how many bases of the kind of ``key`` (its first
        item) are kept, least recently used dropped."""
        with self._lock:
            held, base = self._held(key)
            if held:
                return base
            lock = self._building.setdefault(key, threading.Lock())
        with lock:
            with self._lock:
                held, base = self._held(key)
                if held:
                    return base
            base = build()
            with self._lock:
                self._building.pop(key, None)
                if base is None:
                    self._refused[key] = None
                    while len(self._refused) > 64:
                        self._refused.popitem(last=False)
                else:
                    self._memo[key] = base
                    same = [k for k in self._memo if (k[0] == "rung") == (key[0] == "rung")]
                    for k in same[: max(0, len(same) - keep)]:
                        del self._memo[k]
        return base

    def _scaled(self, root: _Basis, a_m: float, a_k: float, point: bool, lam_cut: float) -> _Basis | None:
        """The reduction of the root scaled (step 2 of the class docstring)."""
        if a_m == 1.0 and a_k == 1.0:
            return root
        base = self._memoized(("scaled", a_m, a_k, bool(point)),
                              lambda: _scaled_basis(root, a_m, a_k, point, lam_cut))
        if base is None:
            def own():  # the scaled structure's own reduction, from the root's modes
                return _reuse_or_extend(root, _scaled_matrices(root, a_m, a_k)[2], lam_cut)

            base = self._memoized(("scaled own", a_m, a_k), own)
        rho = a_k / a_m
        if base is None and 0.0 < rho < 1.0:
            # softer by more than an extension takes: a rung of the ladder below it, scaled up
            j = max(1, int(np.ceil(-np.log2(rho) / RUNG_LOG2)))
            if 2.0 ** (-j * RUNG_LOG2) > rho:  # rounding of the logarithm
                j += 1
            rung = 2.0 ** (-j * RUNG_LOG2)
            below = self._memoized(("rung", j),
                                   lambda: _reduce(_scaled_matrices(root, 1.0, rung)[2], self.f_cut_hz), 2)
            base = self._memoized(("scaled rung", j, a_m, a_k, bool(point)),
                                  lambda: _scaled_basis(below, a_m, a_k / rung, point, lam_cut))
        return base

    def basis_and_dofs(self, mats: Any, anchor: Any = None) -> tuple[_Basis, tuple]:
        """The basis of ``mats`` and its change there ``(J, [dM, dK, dC])`` (class docstring);
        ``anchor``: a callable giving the matrices of the structure ``mats`` modifies, or None."""
        return self._locate(mats, anchor)[:2]

    def _locate(self, mats: Any, anchor: Any = None) -> tuple[_Basis, tuple, bool]:
        """:meth:`basis_and_dofs` and whether the basis is the root's or a scale of it (steps 1 and 2
        of the class docstring: a function of ``mats`` alone, whatever the anchor; steps 3 and 4 are
        not, as a structure reduced on its own without an anchor may be an anchor's change with
        one)."""
        lam_cut = (2 * np.pi * self.f_cut_hz) ** 2
        root = self._root_basis()
        if root is not None:
            change = _changed_dofs(root, mats)
            if change is not None:
                return root, change, True
            split = _scale_split(root, mats, io=True)
            if split is not None:
                a_m, a_k, change = split
                base = self._scaled(root, a_m, a_k, change[0].size <= LOW_RANK_MAX_DOFS, lam_cut)
                if base is not None and not _same_io(root, mats):  # an I/O effect: the new inputs' blocks
                    io_key = _io_key(mats)
                    scaled = base
                    base = self._memoized(("io", a_m, a_k, change[0].size <= LOW_RANK_MAX_DOFS, io_key),
                                          lambda: _with_io(scaled, mats))
                if base is not None:
                    return base, change, True
        if anchor is not None:
            held = anchor()
            if held.mass.shape != mats.mass.shape:  # an effect that adds DOFs: itself at a rung of sizes
                held = anchor(True)
            if held.mass.shape == mats.mass.shape:
                try:
                    base = self.own_basis(held)
                except ModelError:  # an anchor that cannot be reduced: mats on its own
                    base = None
                change = None if base is None else _changed_dofs(base, mats)
                if change is not None:
                    return base, change, False
        return self.own_basis(mats), (np.zeros(0, dtype=int), [np.zeros((0, 0))] * 3), False

    def own_basis(self, mats: Any) -> _Basis:
        """A reduction of ``mats`` itself (its modes below the cut, not a modification of another
        structure's): the root or the root scaled when ``mats`` is one of them, else from the
        root's modes (:func:`_reuse_or_extend`) when they are its eigenpairs, else by a Lanczos run
        of its own; kept under the digest of ``mats``. The point screening of a chain's next step
        (the model with an earlier step's effect) scores its thousands of point effects in closed
        form on it (:func:`point_modal`)."""
        lam_cut = (2 * np.pi * self.f_cut_hz) ** 2
        root = self._root_basis()
        if root is not None:
            change = _changed_dofs(root, mats)
            if change is not None and change[0].size == 0:
                return root
            split = _scale_split(root, mats, io=True)
            if split is not None and split[2][0].size == 0:
                base = self._scaled(root, split[0], split[1], True, lam_cut)
                if base is not None and not _same_io(root, mats):
                    scaled = base
                    base = self._memoized(("io", split[0], split[1], True, _io_key(mats)),
                                          lambda: _with_io(scaled, mats))
                if base is not None:
                    return base

        def build():
            base = None if root is None else _reuse_or_extend(root, mats, lam_cut)
            return _reduce(mats, self.f_cut_hz) if base is None else base

        return self._memoized(("own", _content_key(mats)), build)

    def modal_data(self, mats: Any, anchor: Any = None):
        """The undamped modal data of ``mats`` (:func:`_ritz_modal` on its basis and change), kept
        for the last :data:`_MODAL_KEEP` structures by the digest of their matrices and signals
        when the basis is the root's or a scale of it (a function of ``mats`` alone, whatever the
        anchor and whatever was evaluated before): a candidate that leaves
        the structure as it is -- an I/O, setup or damping effect, scored by the hundred on a
        chain's next step, whose model carries an earlier step's change at a seam's DOFs -- takes
        it without a Ritz problem. The arrays are read-only (shared by the evaluations)."""
        key = (_content_key(mats), tuple(mats.output_kinds), tuple(mats.inputs), tuple(mats.outputs))
        with self._lock:
            self._evaluations += 1
            collect = self._evaluations % COLLECT_EVERY == 0
            held = self._modal.get(key)
            if held is not None:
                self._modal.move_to_end(key)
        if collect:
            gc.collect()
        if held is not None:
            return held
        base, change, rooted = self._locate(mats, anchor)
        out = _ritz_modal(base, mats, change)
        if rooted:
            for a in (out.omega, out.zeta, out.input_shapes, out.output_shapes,
                      out.modal_concentrated_damping):
                if isinstance(a, np.ndarray):
                    a.flags.writeable = False
            with self._lock:
                self._modal[key] = out
                while len(self._modal) > _MODAL_KEEP:
                    self._modal.popitem(last=False)
        return out


#: The reducers unpickled in this process, by the token of the original: a model sent to a worker
#: with every parallel call (``parallel_map_shared`` payloads) finds the bases of the earlier calls.
_RESTORED: weakref.WeakValueDictionary = weakref.WeakValueDictionary()
_RESTORED_LOCK = threading.Lock()


def _restored_reducer(token: str, f_cut_hz: float, root_mats: Any, root: _Basis | None,
                      last: tuple | None) -> _Reducer:
    """The copy of the reducer ``token`` in this process (made once), given the root and the basis
    ``last = (key, basis)`` unless it holds them (the same bases: a function of their keys)."""
    with _RESTORED_LOCK:
        reducer = _RESTORED.get(token)
        if reducer is None:
            reducer = _Reducer(f_cut_hz, root_mats)
            reducer._token = token
            _RESTORED[token] = reducer
    with reducer._lock:
        if root is not None and reducer._root is None:
            reducer._root, reducer._root_mats = root, None
        if last is not None and last[0] not in reducer._memo:
            reducer._memo[last[0]] = last[1]
    return reducer


def _reduced_dynamics(full: Any, f_cut_hz: float, min_dof: int, root_mats: Any = None):
    """A dynamics callable like ``full`` (a :class:`~robustctl.physical.modal.ModalDynamics`)
    that reduces structures of at least ``min_dof`` DOFs (see the module docstring), about the
    root structure ``root_mats`` (:class:`_Reducer`). It takes the keyword ``anchor`` (a callable
    giving the matrices of the structure without the model's last effect, :class:`_Reducer`)."""
    reducer = _Reducer(f_cut_hz, root_mats)

    def dynamics(theta: Mapping[str, float], structure: Any, anchor: Any = None):
        if structure is None:
            raise ModelError("modal_dynamics needs a structure; build the model with a structure callable.")
        mats = structure.matrices()
        if mats.n_dof < min_dof:
            return full(theta, structure)
        _check_mats(mats)
        undamped = reducer.modal_data(mats, anchor)
        damped = _damped(undamped, full.damping(theta), mats.modal_damping_bands, full.rigid_body_damping)
        return damped.statespace()

    dynamics.reducer = reducer  # type: ignore[attr-defined]
    dynamics.full = full  # type: ignore[attr-defined]
    dynamics.min_dof = min_dof  # type: ignore[attr-defined]
    dynamics.takes_anchor = True  # type: ignore[attr-defined]
    return dynamics


def band_limited(model: Any, f_max_hz: float, *, margin: float | None = None, min_dof: int | None = None):
    """``model`` evaluated in reduced coordinates valid up to ``f_max_hz`` (module docstring).

    Parameters
    ----------
    model : PhysicalModel
        A model of :func:`robustctl.structural_model` keeping all modes (no ``n_modes``,
        ``band_hz`` or ``residual_flexibility``); any other model is returned unchanged, as is
        one already band-limited.
    f_max_hz : float
        Highest frequency of interest (Hz), e.g. the top of the data's band.
    margin : float, optional
        Exact modes are kept up to ``margin * f_max_hz`` (default :data:`CUT_MARGIN`); the
        estimate of :func:`reduction_error` scales as ``e(1 / margin)``.
    min_dof : int, optional
        Structures with fewer DOFs keep the full dense path, with the same results as before
        (default :data:`REDUCE_MIN_DOF`).

    Returns
    -------
    PhysicalModel
        Same parameters, stages and signals; frequency responses within the estimate of
        :func:`reduction_error` below ``f_max_hz``.
    """
    f_max_hz = positive_number(f_max_hz, "f_max_hz", ModelError, unit="Hz")
    margin = positive_number(CUT_MARGIN if margin is None else margin, "margin", ModelError)
    min_dof = REDUCE_MIN_DOF if min_dof is None else min_dof
    if margin <= 1.0:
        raise ModelError(f"margin must exceed 1 (modes are kept up to margin * f_max_hz); got {margin!r}.")
    dyn = model.dynamics
    if getattr(dyn, "reducer", None) is not None or not getattr(dyn, "reducible", False):
        return model
    if model.structure is None:
        return model
    try:  # the root of the reductions: the structure at the model's values (_Reducer)
        root = model.build_structure().matrices()
    except ModelError:
        root = None
    if root is not None and root.n_dof < min_dof:
        root = None
    # no per-model cache of state spaces: the reducer keeps the bases, a re-evaluation costs a
    # small eigen-solve, and diagnose holds thousands of candidate models (3 MB per state space
    # of 300 modes each)
    return model._copy(dynamics=_reduced_dynamics(dyn, margin * f_max_hz, int(min_dof), root),
                       _cache=_DynamicsCache(0))


def reduction_error(model: Any, f_hz: Any, **overrides: float) -> np.ndarray | None:
    """Error estimate ``|G_reduced - G_full|`` of a band-limited model's structural response.

    ``e(w / w_cut) sqrt(R^out_oo R^in_ii)`` times ``w^k`` (``k`` = 0, 1, 2 for displacement,
    velocity, acceleration outputs), with ``e(rho) = |1 / (1 - rho^2 + 2 j zeta rho) - 1|``,
    ``w_cut`` the highest exact mode kept and ``R`` the residual flexibility of the truncated
    modes at the sensor and actuator DOFs (module docstring; Craig & Kurdila 2006, sec. 11.4,
    the static-correction error; the inertia term the attachment vectors add makes the actual
    error smaller). Infinite at and above ``w_cut / sqrt(2)``.

    Parameters
    ----------
    model : PhysicalModel
        A model from :func:`band_limited`.
    f_hz : array_like
        Frequencies (Hz).
    **overrides : float
        Parameter values, as for ``model.freqresp``.

    Returns
    -------
    ndarray, shape (n_freq, n_out, n_in), or None
        In the output's units per input unit (before the model's I/O stages); None for a
        model on the full path (not band-limited, or below its DOF threshold).
    """
    dyn = model.dynamics
    reducer = getattr(dyn, "reducer", None)
    if reducer is None:
        return None
    struct = model.build_structure(**overrides)
    mats = struct.matrices()
    if mats.n_dof < dyn.min_dof:
        return None
    base, _ = reducer.basis_and_dofs(mats)
    zeta = np.max(np.atleast_1d(dyn.full.damping(model._theta(overrides))))
    w = 2 * np.pi * np.asarray(f_hz, dtype=float).reshape(-1)
    rho = w / np.sqrt(base.lam_cut)
    e = np.abs(1.0 / (1.0 - rho**2 + 2j * zeta * rho) - 1.0)
    e = np.where(rho < 1 / np.sqrt(2), e, np.inf)
    power = np.array([{"displacement": 0, "velocity": 1}.get(k, 2) for k in mats.output_kinds])
    scale = np.sqrt(base.resid_out[:, None] * base.resid_in[None, :])
    return (e[:, None, None] * w[:, None, None] ** power[None, :, None]) * scale[None]


def for_data(model: Any, data: Any, band: Any = None) -> Any:
    """:func:`band_limited` to the top of ``band`` (Hz), or of the data's frequencies: the model
    ``rc.diagnose`` and ``rc.update`` evaluate (unchanged below :data:`REDUCE_MIN_DOF` DOFs)."""
    try:  # a malformed band or data is refused by the caller's own checks, in its words
        top = float(band[1]) if band is not None else float(np.max(data.f_hz))
    except (TypeError, ValueError, IndexError, AttributeError, KeyError):
        return model
    if not np.isfinite(top) or top <= 0:
        return model
    return band_limited(model, top)


# ============================================================================ point modifications
@dataclass
class PointChange:
    """The change one point effect makes per unit of its parameter: ``dofs`` (the DOFs ``J``)
    and the dense ``|J| x |J|`` blocks of mass (kg), stiffness (N/m) and damping (N s/m) there,
    with the reduction's residual flexibility at ``J`` when the closed form is to include it."""

    dofs: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    #: The static residual flexibility ``R_JJ`` (m/N) of the reduction at ``J``
    #: (:meth:`PointModal.residual_blocks`), or None (left out of the closed form).
    residual: np.ndarray | None = None


class PointModal:
    """The reduced modal model of one parameter point, and point changes of it in closed form.

    With the damped Ritz-modal model ``Z(w) eta = V^T b u``, ``Z(w) = diag(w_k^2) - w^2 I + j w D``
    (``D = diag(2 zeta_k w_k)`` and the rigid-body rate; :func:`_ritz_modal`, MACE eqs. 2-4), the
    structural response is ``H(w) = k(w) c V Z^{-1} V^T b`` (``k`` = 1, ``j w``, ``-w^2`` for
    displacement, velocity, acceleration outputs). The structure's compliance is that modal sum
    plus the static residual flexibility of what the reduction leaves out,

    .. math::

        G(w) \\approx V Z(w)^{-1} V^T + R, \\quad R = K_\\sigma^{-1} - V (\\Lambda - \\sigma)^{-1} V^T

    (the mode-acceleration / static correction, Craig & Kurdila 2006, sec. 11.4; ``V`` is
    ``K_sigma``-orthogonal, so ``R`` is what ``K_sigma^-1`` holds beyond the Ritz basis, and ``R b =
    0`` since the inputs' attachment vectors are in it). A point effect of size ``v`` adds ``v
    E_J B(w) E_J^T`` to the dynamic stiffness, ``B(w) = dK - w^2 dM + j w dC``; by the
    Sherman-Morrison-Woodbury identity (structural dynamic modification, Avitabile 2003)

    .. math::

        H_v(w) = H(w) - \\tilde A(w) \\left(I + v B(w) S(w)\\right)^{-1} v B(w) \\tilde B(w),

    with ``A~ = k c (V Z^{-1} U^T + R E_J)`` (n_out x |J|), ``B~ = U Z^{-1} V^T b`` (|J| x n_in)
    and ``S = U Z^{-1} U^T + R_JJ`` (|J| x |J|), ``U = V[J, :]``: ``O(n_freq r |J| (n_out + n_in))``
    per effect and a ``|J| x |J|`` solve per frequency and size, instead of a new reduction and
    eigen-solve. ``c R`` at every DOF (:attr:`resid_c`) costs one solve per output; ``R_JJ`` one
    solve per DOF (:meth:`residual_blocks`, kept with the change: :attr:`PointChange.residual`), and
    without it the closed form leaves it out.

    The changed DOFs' local flexibility matters: on a membrane the static deflection under a point
    load grows with the mesh's refinement (logarithmically), all of it above any cut, and it is what
    tells a sensor's own node from its neighbour's (the sensor sees the mass's inertia force through
    ``R`` at its own DOF) and what keeps a large mass from pinning the reduced modes. What is still
    left out against the exact reduced evaluation (which augments the basis by the changed DOFs'
    attachment vectors and damps the changed modes by the model's ratios) is the residual's
    inertia, ``O(w^2 / w_cut^2)`` of it, and the change of the modal damping: small in the band.
    Built by :func:`point_modal`; only a diagonal ``D`` (no concentrated damping in the model)
    is handled.
    """

    def __init__(self, f_hz: np.ndarray, V: np.ndarray, omega: np.ndarray, damp: np.ndarray,
                 cphi: np.ndarray, phib: np.ndarray, kinds: tuple, outputs: tuple, inputs: tuple,
                 resid_c: np.ndarray | None = None, factor: Any = None,
                 shift_inv: np.ndarray | None = None) -> None:
        self.f_hz = np.asarray(f_hz, dtype=float)
        w = 2 * np.pi * self.f_hz
        self.w = w
        self.V = V  # (n_dof, r), modes in the order of omega
        self.zinv = 1.0 / (omega[None, :] ** 2 - w[:, None] ** 2 + 1j * w[:, None] * damp[None, :])
        self._zinv_parts = None  # Z^-1's real and imaginary parts, contiguous (made when first needed)
        k = np.ones((w.size, len(kinds)), dtype=complex)
        for o, kind in enumerate(kinds):
            if kind == "velocity":
                k[:, o] = 1j * w
            elif kind != "displacement":
                k[:, o] = -(w**2)
        self.k_out = k  # (n_f, p)
        self.cphi = cphi  # (p, r)
        self.phib = phib  # (r, m)
        self.outputs, self.inputs = tuple(outputs), tuple(inputs)
        self.H = self.k_out[:, :, None] * np.einsum("or,fr,ri->foi", cphi, self.zinv, phib, optimize=True)
        #: ``c R`` (p, n_dof), m/N: the outputs' static residual flexibility to every DOF, or None
        self.resid_c = resid_c
        self._factor = factor  # the factor of K - sigma M (not pickled: the parent adds R_JJ)
        self._shift_inv = shift_inv  # (r,) 1 / (lam_k - sigma) in V's order

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_factor": None, "_zinv_parts": None}

    def residual_blocks(self, dofs: list[np.ndarray], block: int = 256) -> list[np.ndarray] | None:
        """``R_JJ = E_J^T K_sigma^-1 E_J - U (Lambda - sigma)^-1 U^T`` (m/N) for each DOF set of
        ``dofs`` (class docstring), by solves with the reduction's factor (``block`` right-hand sides
        at a time); None without the factor. Rounding is floored at 1e-12 of the static flexibility
        (the residual is positive semi-definite)."""
        if self._factor is None or self._shift_inv is None:
            return None
        n = self.V.shape[0]
        single = sorted({int(d[0]) for d in dofs if d.size == 1})
        diag: dict[int, float] = {}
        for start in range(0, len(single), block):
            part = np.array(single[start:start + block], dtype=int)
            E = np.zeros((n, part.size))
            E[part, np.arange(part.size)] = 1.0
            full = np.asarray(self._factor.solve(E))[part, np.arange(part.size)]
            U = self.V[part]
            modal = np.einsum("jr,r,jr->j", U, self._shift_inv, U)
            diag.update(zip(part.tolist(), np.maximum(full - modal, 1e-12 * np.abs(full)).tolist()))
        out = []
        for d in dofs:
            if d.size == 1:
                out.append(np.full((1, 1), diag[int(d[0])]))
                continue
            E = np.zeros((n, d.size))
            E[d, np.arange(d.size)] = 1.0
            full = np.asarray(self._factor.solve(E))[d]
            U = self.V[d]
            r = full - (U * self._shift_inv) @ U.T
            r = 0.5 * (r + r.T)
            lam, vec = np.linalg.eigh(r)
            floor = 1e-12 * float(np.max(np.abs(np.diag(full)), initial=0.0))
            out.append((vec * np.maximum(lam, floor)) @ vec.T)
        return out

    def with_residuals(self, changes: list[PointChange]) -> list[PointChange]:
        """``changes`` with their :attr:`PointChange.residual` (:meth:`residual_blocks`); unchanged
        without the factor."""
        blocks = self.residual_blocks([c.dofs for c in changes])
        if blocks is None:
            return list(changes)
        return [replace(c, residual=r) for c, r in zip(changes, blocks)]

    def terms(self, change: PointChange) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A~, B~, S, B)`` of one change (class docstring): shapes (n_f, p, q), (n_f, q, m),
        (n_f, q, q), (n_f, q, q) with ``q = |J|``; the residual terms where the model (``c R``) and
        the change (``R_JJ``) carry them."""
        U = self.V[change.dofs]  # (q, r)
        if U.shape[0] == 1:  # one DOF u: Z^-1 times [diag(u) c^T, diag(u) V^T b, u * u], real products
            u = U[0]
            p, m = self.cphi.shape[0], self.phib.shape[1]  # R: (r, p + m + 1)
            R = np.hstack([u[:, None] * self.cphi.T, u[:, None] * self.phib, (u * u)[:, None]])
            if self._zinv_parts is None:
                self._zinv_parts = tuple(np.ascontiguousarray(x) for x in (self.zinv.real, self.zinv.imag))
            zr, zi = self._zinv_parts
            ZR = (zr @ R) + 1j * (zi @ R)  # (n_f, p + m + 1)
            cg = ZR[:, :p, None]  # (n_f, p, 1)
            Bt = ZR[:, None, p:p + m]  # (n_f, 1, m)
            S = ZR[:, p + m:, None]  # (n_f, 1, 1)
        else:
            ZU = self.zinv[:, None, :] * U[None]  # (n_f, q, r)
            cg = self.cphi @ ZU.transpose(0, 2, 1)  # (n_f, p, q)
            Bt = ZU @ self.phib
            S = ZU @ U.T
        if self.resid_c is not None:
            cg = cg + self.resid_c[:, change.dofs][None]
        At = self.k_out[:, :, None] * cg
        if change.residual is not None:
            S = S + change.residual[None]
        w = self.w[:, None, None]
        B = change.stiffness[None] - w**2 * change.mass[None] + 1j * w * change.damping[None]
        return At, Bt, S, B

    def responses(self, terms: tuple, values: np.ndarray) -> np.ndarray:
        """``H_v`` for each size in ``values`` (shape (n_v,)): (n_v, n_f, n_out, n_in)."""
        At, Bt, S, B = terms
        v = np.asarray(values, dtype=float)[:, None, None, None]
        q = S.shape[-1]
        if q == 1:
            vb = v[..., 0, 0] * B[None, :, 0, 0]  # (n_v, n_f)
            g = vb / (1.0 + vb * S[None, :, 0, 0])
            out = g[:, :, None, None] * (At[:, :, 0, None] * Bt[:, None, 0, :])[None]
            return np.subtract(self.H[None], out, out=out)
        vB = v * B[None]  # (n_v, n_f, q, q)
        lhs = np.eye(q)[None, None] + vB @ S[None]
        X = np.linalg.solve(lhs, vB @ Bt[None])  # (n_v, n_f, q, m)
        return self.H[None] - At[None] @ X


def point_modal(model: Any, f_hz: Any, residual: bool = True, **overrides: float) -> PointModal | None:
    """The :class:`PointModal` of a band-limited model at its values (``overrides`` as for
    ``model.freqresp``), or None when the model is on the full path, carries concentrated
    damping, or its structure cannot be reduced. A structure the reducer holds only as a
    modification of another (a chain's next step: the model with an earlier effect) is reduced on
    its own first (:meth:`_Reducer.own_basis`). ``residual``: with the outputs' static residual
    flexibility ``c R`` at every DOF (one solve per output) and the factor for the changed DOFs'
    (:meth:`PointModal.residual_blocks`); False leaves the residual out."""
    dyn = model.dynamics
    reducer = getattr(dyn, "reducer", None)
    if reducer is None or model.structure is None:
        return None
    theta = model._theta(overrides)
    mats = model._structure(theta).matrices()
    if mats.n_dof < dyn.min_dof or mats.damping is not None:
        return None
    base, change = reducer.basis_and_dofs(mats)
    if change[0].size:  # a modification of a reduced structure (a chain's next step): reduce it
        base = reducer.own_basis(mats)
        change = (np.zeros(0, dtype=int), [np.zeros((0, 0))] * 3)
    undamped = _ritz_modal(base, mats, change)
    damped = _damped(undamped, dyn.full.damping(theta), mats.modal_damping_bands, dyn.full.rigid_body_damping)
    k_scale = float(abs(base.stiffness).max() / max(abs(base.mass).max(), 1e-300))
    order = np.argsort(_clean_eigenvalues(base.lam, k_scale), kind="stable")
    w = damped.omega
    damp = 2 * damped.zeta * w + np.where(w == 0, damped.rigid_body_rate, 0.0)
    V = base.V[:, order]
    resid_c = factor = shift_inv = None
    if residual:
        factor = _factor(base)
        shift_inv = 1.0 / (base.lam[order] - base.sigma)
        c = base.output_matrix
        full = np.asarray(factor.solve(np.ascontiguousarray(c.T))).T  # (p, n) c K_sigma^-1
        resid_c = full - (base.c_v[:, order] * shift_inv) @ V.T
    return PointModal(np.asarray(f_hz, dtype=float).reshape(-1), V, w, damp,
                      damped.output_shapes, damped.input_shapes, tuple(mats.output_kinds),
                      tuple(mats.outputs), tuple(mats.inputs), resid_c, factor, shift_inv)


def point_change(effect: Any, model: Any, base_struct: Any, base_mats: Any) -> PointChange | None:
    """The change per unit size of a point effect (one whose class declares a ``point_unit``: a
    constant mass, grounded spring or dashpot, linear in its one parameter) on ``model``'s structure
    ``base_struct`` (matrices ``base_mats``), or None for any other effect or one that changes
    more than :data:`LOW_RANK_MAX_DOFS` DOFs. A single-DOF location of a
    :class:`~robustctl.physical.matrices.MatrixStructure` is read off directly; otherwise (a frame
    node, several DOFs) the effect is applied at unit size and the matrices compared."""
    unit = getattr(effect, "point_unit", None)
    if unit is None or len(effect.param_names) != 1:
        return None
    if (isinstance(base_struct, MatrixStructure) and getattr(effect, "direction", None) is None
            and effect.location in base_struct.locations()):  # one DOF; else (several) compare matrices
        j = base_struct._dof(effect.location)
        return PointChange(np.array([j]), *(np.full((1, 1), float(v)) for v in unit))
    pname = effect.param_names[0]
    try:
        mats = effect.with_values(**{pname: 0.0}).apply(model).build_structure(**{pname: 1.0}).matrices()
    except ModelError:  # an unknown location: the exact path reports it
        return None
    dummy = _Basis(_csc(base_mats.mass), _csc(base_mats.stiffness),
                   None if base_mats.damping is None else _csc(base_mats.damping),
                   np.asarray(base_mats.input_matrix, dtype=float),
                   np.asarray(base_mats.output_matrix, dtype=float), None, 0.0, np.zeros((0, 0)),
                   np.zeros(0), 0, 0.0, np.zeros(0), np.zeros(0))
    change = _changed_dofs(dummy, mats)
    if change is None or change[0].size == 0:
        return None
    dofs, (dM, dK, dC) = change
    return PointChange(dofs, dM, dK, dC)

