"""The standard assumptions of H-infinity synthesis, checked before any Riccati equation is solved.

For ``P = [A, B1, B2; C1, D11, D12; C2, D21, D22]`` (Zhou, Doyle & Glover 1996, sec. 17.1,
assumptions (A1)-(A4); Glover & Doyle 1988):

(A1) ``(A, B2)`` stabilisable and ``(C2, A)`` detectable (PBH rank tests at every
     eigenvalue with ``Re >= 0``);
(A2) ``D12`` full column rank and ``D21`` full row rank;
(A3) ``P12 = (A, B2, C1, D12)`` has no invariant zero on the imaginary axis:
     ``[A - jwI, B2; C1, D12]`` has full column rank for all ``w``. With ``D12`` of full
     column rank this is "``(A - B2 D12^+ C1, (I - D12 D12^+) C1)`` has no unobservable
     mode on the imaginary axis" (column and row operations on the Rosenbrock matrix);
(A4) ``P21 = (A, B1, C2, D21)`` has no invariant zero on the imaginary axis (the dual:
     ``(A - B1 D21^+ C2, B1 (I - D21^+ D21))`` has no uncontrollable mode there).

Every violation raises :class:`~robustctl.errors.SynthesisError` naming the assumption,
the offending frequency or rank, and a fix.
"""

from __future__ import annotations

import numpy as np

from ..._lapack import eigvals, svd_thin, svdvals
from ...errors import SynthesisError

__all__ = ["check_assumptions", "rank_tol"]

#: An eigenvalue counts as on the imaginary axis when ``|Re| <= max(AXIS_RTOL |lambda|, err)``, with
#: ``err = EIG_ERR_FACTOR eps ||A||_2`` the eigensolver's accuracy (see :func:`_eig_error`).
AXIS_RTOL = 1e-9
EIG_ERR_FACTOR = 100.0
#: A PBH matrix loses rank when its smallest singular value is below ``PBH_RTOL`` times its norm.
PBH_RTOL = 1e-9
_EPS = float(np.finfo(float).eps)


def _norm2(M: np.ndarray) -> float:
    """Spectral norm ``||M||_2`` (the largest singular value; 0 for an empty matrix).

    The same number as ``np.linalg.norm(M, 2)`` (which takes the largest of the same singular
    values) by the same LAPACK call without numpy's wrappers (:mod:`robustctl._lapack`).
    """
    return float(svdvals(M)[0]) if M.size else 0.0


def rank_tol(M: np.ndarray, scale: float) -> float:
    """Singular values of ``M`` below this count as zero (relative to the plant's scale)."""
    return 1e-10 * max(scale, _norm2(M), 1e-300)


def pbh_loses_rank(M: np.ndarray) -> bool:
    """True when the PBH test matrix ``M`` is rank deficient (smallest singular value below
    ``PBH_RTOL`` of the largest)."""
    s = svdvals(M)
    return bool(s.size == 0 or s[-1] <= PBH_RTOL * max(s[0], 1e-300))


def _hz(w: float) -> str:
    return f"{abs(w):.6g} rad/s ({abs(w) / (2 * np.pi):.6g} Hz)"


def _eig_error(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues of ``A`` and the eigensolver's absolute accuracy ``EIG_ERR_FACTOR eps ||A||_2``.

    A backward-stable eigensolver moves a well-conditioned eigenvalue by about
    ``eps ||A||`` (Golub & Van Loan 2013, sec. 7.2.2), whatever its own size. The former
    absolute tolerance ``1e-12 ||A||_1`` (45 times this) misread the distillation weight's
    pole at -1e-5 rad/s as on the axis once D-scales made ``||A||`` large. (Per-eigenvalue
    condition numbers ``1 / |y^H x|`` are not used: for the repeated poles of identical
    channel weights the paired eigenvectors are arbitrary and ``y^H x`` can vanish, which put
    the Caltech plant's -400 rad/s weight poles "on the axis".)
    """
    ev = eigvals(A)
    err = EIG_ERR_FACTOR * _EPS * _norm2(A)
    return ev, np.full(ev.shape, err)


def _unreachable_modes(A: np.ndarray, B: np.ndarray, region: str, eig=None) -> list[complex]:
    """Eigenvalues of ``A`` in ``region`` ('rhp': Re >= 0, 'axis': Re = 0) where [A - sI, B] drops rank.

    ``eig``: ``_eig_error(A)`` when the caller has it (``A`` and ``A.T`` share their eigenvalues
    and 2-norm).
    """
    n = A.shape[0]
    if n == 0:
        return []
    ev, err = _eig_error(A) if eig is None else eig
    tol = np.maximum(AXIS_RTOL * np.abs(ev), err)
    pick = ev.real >= -tol if region == "rhp" else np.abs(ev.real) <= tol
    bad = []
    for lam in ev[pick]:
        if lam.imag < 0:
            continue  # the conjugate is tested
        if pbh_loses_rank(np.hstack([A - lam * np.eye(n), B])):
            bad.append(complex(lam))
    return bad


def _check_stabilisable(A, B2, C2) -> None:
    eig = _eig_error(A) if A.size else None
    bad = _unreachable_modes(A, B2, "rhp", eig)
    if bad:
        lam = bad[0]
        raise SynthesisError(
            f"assumption (A1) violated: (A, B2) is not stabilisable -- the plant mode at s = {lam:.6g} "
            f"(|s| = {_hz(abs(lam))}) has Re(s) >= 0 and the control inputs u cannot move it. Fix: "
            "remove the unstable/undamped uncontrollable states (e.g. an integrator in a weight on a "
            "signal u does not drive: make the weight stable, e.g. 1/(s+eps)), or add an actuator."
        )
    bad = _unreachable_modes(A.T, C2.T, "rhp", eig)
    if bad:
        lam = bad[0]
        raise SynthesisError(
            f"assumption (A1) violated: (C2, A) is not detectable -- the plant mode at s = {lam:.6g} "
            f"(|s| = {_hz(abs(lam))}) has Re(s) >= 0 and the measurements y do not see it. Fix: make "
            "unstable/integrating weights stable (e.g. 1/(s+eps) instead of 1/s), or add a sensor."
        )


def _numerical_rank(M: np.ndarray, scale: float) -> int:
    """Singular values of ``M`` above :func:`rank_tol` (one SVD gives both them and ``||M||_2``)."""
    if not M.size:
        return 0
    s = svdvals(M)
    return int(np.sum(s > 1e-10 * max(scale, float(s[0]), 1e-300)))


def check_ranks(D12, D21, scale: float) -> None:
    """Assumption (A2): ``D12`` of full column rank and ``D21`` of full row rank, else a
    SynthesisError that says the fix."""
    m2, p2 = D12.shape[1], D21.shape[0]
    rank12 = _numerical_rank(D12, scale)
    if rank12 < m2:
        raise SynthesisError(
            f"assumption (A2) violated: D12 (z <- u, {D12.shape[0]}x{m2}) has rank {rank12} < ncon = {m2}: "
            "some control input is not penalised at high frequency, so the controller gain is unbounded. "
            "Fix: add a small weight on u (e.g. a constant W2 = 1e-3 on every control input in "
            "the regulated outputs), or use method='lmi'."
        )
    rank21 = _numerical_rank(D21, scale)
    if rank21 < p2:
        raise SynthesisError(
            f"assumption (A2) violated: D21 (y <- w, {p2}x{D21.shape[1]}) has rank {rank21} < nmeas = {p2}: "
            "some measurement is noise free, which asks for infinite-bandwidth estimation. Fix: add "
            "small sensor noise (an exogenous input entering every measurement with a small constant "
            "weight, e.g. 1e-3), or use method='lmi'."
        )


def _pinv(M: np.ndarray) -> np.ndarray:
    """``np.linalg.pinv(M)`` (default cutoff ``1e-15 sigma_1``) by the same operations, without
    its wrapper's overhead (a third of a small matrix's cost)."""
    if not M.size:
        return np.zeros((M.shape[1], M.shape[0]))
    u, s, vt = svd_thin(M)
    large = s > 1e-15 * s[0]  # s descending: s[0] = max(s)
    if large.all():
        s = 1 / s
    else:
        s = np.divide(1, s, where=large, out=s)
        s[~large] = 0
    return np.matmul(vt.T, s[:, None] * u.T)


def _check_axis_zeros(A, B1, B2, C1, C2, D12, D21) -> None:
    D12p = _pinv(D12)
    A12 = A - B2 @ D12p @ C1
    C12 = (np.eye(D12.shape[0]) - D12 @ D12p) @ C1
    bad = _unreachable_modes(A12.T, C12.T, "axis")
    if bad:
        w = bad[0].imag
        raise SynthesisError(
            f"assumption (A3) violated: P12 (z <- u) has an invariant zero on the imaginary axis at "
            f"w = {_hz(w)}: [A - jwI, B2; C1, D12] loses column rank, typically an undamped mode (or an "
            "integrator) that the regulated outputs z cannot see. Fix: give the mode a little damping, "
            "or weight it in z (a performance output that sees it), or use method='lmi'."
        )
    D21p = _pinv(D21)
    A21 = A - B1 @ D21p @ C2
    B21 = B1 @ (np.eye(D21.shape[1]) - D21p @ D21)
    bad = _unreachable_modes(A21, B21, "axis")
    if bad:
        w = bad[0].imag
        raise SynthesisError(
            f"assumption (A4) violated: P21 (y <- w) has an invariant zero on the imaginary axis at "
            f"w = {_hz(w)}: [A - jwI, B1; C2, D21] loses row rank, typically an undamped mode (or an "
            "integrator) that the exogenous inputs w cannot excite. Fix: give the mode a little damping, "
            "or let a disturbance reach it (an input-disturbance channel in w), or use method='lmi'."
        )


def check_assumptions(m: dict[str, np.ndarray], *, ranks: bool = True, axis_zeros: bool = True) -> None:
    """Raise :class:`SynthesisError` for the first violated assumption (A1)-(A4) of the partitioned ``m``.

    ``ranks=False`` and ``axis_zeros=False`` skip (A2)-(A4) (the LMI route does not need them).
    """
    A, B1, B2, C1, C2 = m["A"], m["B1"], m["B2"], m["C1"], m["C2"]
    _check_stabilisable(A, B2, C2)
    if not ranks:
        return
    scale = (
        max(_norm2(M) for M in (m["D11"], m["D12"], m["D21"], B2, C2, B1, C1) if M.size)
        if A.size or m["D11"].size
        else 1.0
    )
    check_ranks(m["D12"], m["D21"], 1e-6 * scale)
    if axis_zeros:
        _check_axis_zeros(A, B1, B2, C1, C2, m["D12"], m["D21"])
