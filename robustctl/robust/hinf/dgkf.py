"""Riccati (DGKF / Glover-Doyle) kernel of H-infinity synthesis: scalings, gamma test, central controller.

Notation of Zhou, Doyle & Glover (ZDG), *Robust and Optimal Control* (1996), ch. 16-17, for
a plant ``P = [A, B1, B2; C1, D11, D12; C2, D21, D22]`` with ``m1 = dim w``, ``m2 = dim u``,
``p1 = dim z``, ``p2 = dim y``:

* :func:`normalise` rotates ``z`` and ``w`` (orthogonal, norm preserving) and rescales ``u``
  and ``y`` so that ``D12 = [0; I]`` and ``D21 = [0, I]`` (ZDG sec. 17.2, by SVD);
  ``D22`` is removed by loop shifting (Safonov, Limebeer & Chiang 1989, *Int. J. Control*
  50: design ``K0`` for ``D22 = 0`` and use ``K = K0 (I + D22 K0)^-1``), done by the caller;
* :func:`gamma_test` is the existence test of Glover & Doyle (1988, *Syst. Control Lett.* 11,
  167-172; ZDG Theorem 17.1 in the general form with ``D11 != 0``):
  ``gamma > max(sigma_max[D1111, D1112], sigma_max[D1111; D1121])`` (Parrott), the
  Hamiltonians ``H_X``, ``H_Y`` have no imaginary-axis eigenvalues, their stabilising
  solutions satisfy ``X >= 0``, ``Y >= 0``, and ``rho(X Y) < gamma^2``, where

  .. math::

     H_X = \\begin{bmatrix} A & 0 \\\\ -C_1^T C_1 & -A^T \\end{bmatrix}
         - \\begin{bmatrix} B \\\\ -C_1^T D_{1\\bullet} \\end{bmatrix} R^{-1}
           \\begin{bmatrix} D_{1\\bullet}^T C_1 & B^T \\end{bmatrix},\\quad
     R = D_{1\\bullet}^T D_{1\\bullet} - \\begin{bmatrix} \\gamma^2 I_{m_1} & 0 \\\\ 0 & 0 \\end{bmatrix}

  with ``B = [B1, B2]``, ``D1. = [D11, D12]``, and ``H_Y`` the same for the dual plant;
  one test costs two real Schur decompositions of order ``2n``;
* :func:`central_controller` is the ``Q = 0`` controller of the same theorem (ZDG eq.
  17.7-17.8 / Glover & Doyle 1988, Theorem 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["Normalised", "GammaTest", "normalise", "parrott_bound", "gamma_test", "central_controller"]

#: A Hamiltonian eigenvalue with ``|Re| <= IMAG_RTOL |lambda| + IMAG_ATOL ||H||_1`` is on the imaginary axis.
#: (Relative to ``|lambda|``: slow but well-damped modes, e.g. a weight's pole at 5e-4 rad/s, are not on it.)
IMAG_RTOL = 1e-9
IMAG_ATOL = 1e-13
#: ``X1`` of the stable subspace ``[X1; X2]`` with reciprocal condition below this is singular.
RCOND_MIN = 1e-14
#: ``X >= 0`` holds when ``lambda_min(X) >= -PSD_TOL * max(1, ||X||)``.
PSD_TOL = 1e-8


@dataclass(frozen=True)
class Normalised:
    """A plant scaled so that ``D12 = [0; I]``, ``D21 = [0, I]`` and ``D22 = 0``.

    The original control is ``u = u_scale @ u_n`` and the scaled measurement
    ``y_n = y_scale @ y``; ``z`` and ``w`` are rotated by orthogonal matrices, which keeps
    every H-infinity norm.
    """

    A: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    C1: np.ndarray
    C2: np.ndarray
    D11: np.ndarray
    D12: np.ndarray
    D21: np.ndarray
    u_scale: np.ndarray
    y_scale: np.ndarray

    @property
    def sizes(self) -> tuple[int, int, int, int]:
        """``(m1, m2, p1, p2)``."""
        return self.B1.shape[1], self.B2.shape[1], self.C1.shape[0], self.C2.shape[0]


@dataclass(frozen=True)
class GammaTest:
    """Outcome of one gamma test: ``feasible``, a ``reason`` when not, and ``X``, ``Y`` when solved."""

    gamma: float
    feasible: bool
    reason: str = ""
    X: np.ndarray | None = None
    Y: np.ndarray | None = None


class _InfeasibleError(Exception):
    """A gamma test failed for the stated reason."""


# ---------------------------------------------------------------------------- scalings
def normalise(A, B1, B2, C1, C2, D11, D12, D21) -> Normalised:
    """Scale ``D12`` to ``[0; I]`` and ``D21`` to ``[0, I]`` (ZDG sec. 17.2); ``D22`` is dropped.

    ``D12 = U diag(s) V^T``: ``z -> [U_perp, U_range]^T z``, ``u = V diag(1/s) u_n``;
    ``D21 = U2 [diag(s2), 0] V2^T``: ``w = [V2_perp, V2_range] w_n``, ``y_n = diag(1/s2) U2^T y``.
    ``D12`` must have full column rank and ``D21`` full row rank (checked by the caller).
    """
    m2, p2 = B2.shape[1], C2.shape[0]
    U, s, Vt = np.linalg.svd(D12)
    theta_z = np.vstack([U[:, m2:].T, U[:, :m2].T])
    u_scale = Vt.T / s[None, :]
    U2, s2, V2t = np.linalg.svd(D21)
    V2 = V2t.T
    theta_w = np.hstack([V2[:, p2:], V2[:, :p2]])
    y_scale = U2.T / s2[:, None]
    return Normalised(
        A=A,
        B1=B1 @ theta_w,
        B2=B2 @ u_scale,
        C1=theta_z @ C1,
        C2=y_scale @ C2,
        D11=theta_z @ D11 @ theta_w,
        D12=np.vstack([np.zeros((C1.shape[0] - m2, m2)), np.eye(m2)]),
        D21=np.hstack([np.zeros((p2, B1.shape[1] - p2)), np.eye(p2)]),
        u_scale=u_scale,
        y_scale=y_scale,
    )


def _d11_blocks(p: Normalised) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``D1111, D1112, D1121, D1122`` (rows split at ``p1 - m2``, columns at ``m1 - p2``)."""
    m1, m2, p1, p2 = p.sizes
    r, c = p1 - m2, m1 - p2
    D = p.D11
    return D[:r, :c], D[:r, c:], D[r:, :c], D[r:, c:]


def _norm2(M: np.ndarray) -> float:
    return float(np.linalg.norm(M, 2)) if M.size else 0.0


def parrott_bound(p: Normalised) -> float:
    """``max(sigma_max[D1111, D1112], sigma_max[D1111; D1121])``: no controller achieves less (Parrott)."""
    D1111, D1112, D1121, _ = _d11_blocks(p)
    return max(_norm2(np.hstack([D1111, D1112])), _norm2(np.vstack([D1111, D1121])))


# ---------------------------------------------------------------------------- Riccati
def _schur_eigs(T: np.ndarray) -> np.ndarray:
    """Eigenvalues of a real quasi-triangular Schur factor, from its 1x1 and 2x2 diagonal blocks."""
    n = T.shape[0]
    ev = np.empty(n, complex)
    i = 0
    while i < n:
        if i + 1 < n and T[i + 1, i] != 0.0:
            a, b, c, d = T[i, i], T[i, i + 1], T[i + 1, i], T[i + 1, i + 1]
            mean, disc = 0.5 * (a + d), np.sqrt(complex(0.25 * (a - d) ** 2 + b * c))
            ev[i], ev[i + 1] = mean + disc, mean - disc
            i += 2
        else:
            ev[i] = T[i, i]
            i += 1
    return ev


def stabilising_solution(H: np.ndarray, what: str) -> np.ndarray:
    """``X = Ric(H) = X2 X1^-1`` from the stable invariant subspace ``[X1; X2]`` of a Hamiltonian.

    ``H`` is first balanced by a diagonal similarity ``Hb = S^-1 H S`` (LAPACK ``gebal``; the
    stable subspace of ``H`` is ``S`` times that of ``Hb``), which keeps eigenvalues accurate
    when the scalings of D12/D21 make ``B2 B2^T`` or ``C2^T C2`` huge (cheap control weights).
    Ordered real Schur form of ``Hb`` (LAPACK ``gees`` with the left half plane first), then
    the checks of ZDG sec. 13.1: exactly ``n`` stable eigenvalues, none on the imaginary axis
    (``|Re lambda| <= IMAG_RTOL |lambda| + IMAG_ATOL ||Hb||_1``), ``X1`` invertible. Raises
    ``_InfeasibleError``.
    """
    n = H.shape[0] // 2
    if n == 0:  # a static plant: no state, no Riccati equation
        return np.zeros((0, 0))
    if not np.all(np.isfinite(H)):
        raise _InfeasibleError(f"{what}: the Hamiltonian has NaN/inf entries")
    Hb, (sc, _) = scipy.linalg.matrix_balance(H, permute=False, separate=True)
    T, Z, sdim = scipy.linalg.schur(Hb, output="real", sort="lhp", check_finite=False)
    Z = Z * sc[:, None]  # back to the coordinates of H
    ev = _schur_eigs(T)
    scale = max(float(np.abs(Hb).sum(axis=0).max()), np.finfo(float).tiny)
    if np.any(np.abs(ev.real) <= IMAG_RTOL * np.abs(ev) + IMAG_ATOL * scale):
        raise _InfeasibleError(f"{what}: Hamiltonian eigenvalues on the imaginary axis")
    if sdim != n:
        raise _InfeasibleError(f"{what}: {sdim} stable Hamiltonian eigenvalues instead of {n}")
    X1, X2 = Z[:n, :n], Z[n:, :n]
    lu, piv = scipy.linalg.lu_factor(X1, check_finite=False)
    rcond = scipy.linalg.lapack.dgecon(lu, np.abs(X1).sum(axis=0).max())[0] if n else 1.0
    if not rcond > RCOND_MIN:
        raise _InfeasibleError(f"{what}: no stabilising solution (X1 singular, rcond {rcond:.1e})")
    X = scipy.linalg.lu_solve((lu, piv), X2.T, trans=1, check_finite=False).T  # X2 X1^-1
    return 0.5 * (X + X.T)


def _x_hamiltonian(A, B1, B2, C1, D11, D12, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``H_X`` of the module docstring and the pieces ``(R, B, D1.^T C1)`` needed for ``F``."""
    m1 = B1.shape[1]
    B = np.hstack([B1, B2])
    D1 = np.hstack([D11, D12])
    R = D1.T @ D1
    R[:m1, :m1] -= gamma**2 * np.eye(m1)
    DC = D1.T @ C1
    RinvDC = np.linalg.solve(R, DC)
    RinvBt = np.linalg.solve(R, B.T)
    Ax = A - B @ RinvDC
    H = np.block([[Ax, -B @ RinvBt], [-C1.T @ C1 + DC.T @ RinvDC, -Ax.T]])
    return H, R, B, DC


def _riccati_and_gain(A, B1, B2, C1, D11, D12, gamma: float, what: str) -> tuple[np.ndarray, np.ndarray]:
    """``X = Ric(H_X) >= 0`` and ``F = -R^-1 (D1.^T C1 + B^T X)`` (ZDG sec. 17.1)."""
    H, R, B, DC = _x_hamiltonian(A, B1, B2, C1, D11, D12, gamma)
    X = stabilising_solution(H, what)
    lam = np.linalg.eigvalsh(X) if X.size else np.zeros(1)
    if lam[0] < -PSD_TOL * max(1.0, float(np.abs(lam).max())):
        raise _InfeasibleError(f"{what} is not positive semidefinite (lambda_min = {lam[0]:.3g})")
    F = -np.linalg.solve(R, DC + B.T @ X)
    return X, F


def _solve_xy(p: Normalised, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``X, F`` and (by duality) ``Y, L`` at ``gamma``; raises ``_InfeasibleError``."""
    X, F = _riccati_and_gain(p.A, p.B1, p.B2, p.C1, p.D11, p.D12, gamma, "X")
    Y, Lt = _riccati_and_gain(p.A.T, p.C1.T, p.C2.T, p.B1.T, p.D11.T, p.D21.T, gamma, "Y")
    return X, F, Y, Lt.T


def _spectral_radius_ok(X: np.ndarray, Y: np.ndarray, gamma: float) -> float:
    rho = float(np.max(np.abs(np.linalg.eigvals(X @ Y)))) if X.size else 0.0
    if not rho < gamma**2 * (1.0 - 1e-10):
        raise _InfeasibleError(f"rho(XY) = {rho:.4g} >= gamma^2 = {gamma**2:.4g}")
    return rho


def gamma_test(p: Normalised, gamma: float, bound: float | None = None) -> GammaTest:
    """Is there a controller with ``||Fl(P, K)||_inf < gamma``? (Glover & Doyle 1988; ZDG Thm 17.1.)

    ``bound``: the Parrott bound of ``p`` when already known (computed otherwise).
    """
    bound = parrott_bound(p) if bound is None else bound
    if not gamma > bound * (1.0 + 1e-12):
        return GammaTest(gamma, False, f"gamma <= Parrott bound {bound:.6g} of D11")
    try:
        X, _, Y, _ = _solve_xy(p, gamma)
        _spectral_radius_ok(X, Y, gamma)
    except _InfeasibleError as exc:
        return GammaTest(gamma, False, str(exc))
    except np.linalg.LinAlgError as exc:
        return GammaTest(gamma, False, f"linear algebra failure ({exc})")
    return GammaTest(gamma, True, "", X, Y)


# ---------------------------------------------------------------------------- controller
def _solve(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    return np.linalg.solve(M, B) if M.size else np.zeros((M.shape[0], B.shape[1]))


def central_controller(p: Normalised, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The central (``Q = 0``) controller ``(Ak, Bk, Ck, Dk)`` for the normalised plant at ``gamma``.

    Glover & Doyle (1988), Theorem 3 / ZDG sec. 17.1, with ``D11 != 0``::

        D^11 = -D1121 D1111^T (g^2 I - D1111 D1111^T)^-1 D1112 - D1122
        D^12 D^12^T = I - D1121 (g^2 I - D1111^T D1111)^-1 D1121^T
        D^21^T D^21 = I - D1112^T (g^2 I - D1111 D1111^T)^-1 D1112
        Z = (I - g^-2 Y X)^-1,   B^2 = Z (B2 + L12) D^12,   C^2 = -D^21 (C2 + F12)
        B^1 = -Z L2 + B^2 D^12^-1 D^11,   C^1 = F2 + D^11 D^21^-1 C^2
        A^ = A + B F + B^1 D^21^-1 C^2,   K = [A^, B^1; C^1, D^11]

    Returns the controller in the normalised coordinates ``u_n = K y_n``; raises
    ``np.linalg.LinAlgError`` or ``_InfeasibleError`` when ``gamma`` is not achievable.
    """
    m1, m2, p1, p2 = p.sizes
    n = p.A.shape[0]
    X, F, Y, L = _solve_xy(p, gamma)
    _spectral_radius_ok(X, Y, gamma)
    D1111, D1112, D1121, D1122 = _d11_blocks(p)
    g2 = gamma**2
    r, c = p1 - m2, m1 - p2
    M_r = g2 * np.eye(r) - D1111 @ D1111.T
    M_c = g2 * np.eye(c) - D1111.T @ D1111
    Dh11 = -D1121 @ D1111.T @ _solve(M_r, D1112) - D1122
    Dh12 = np.linalg.cholesky(np.eye(m2) - D1121 @ _solve(M_c, D1121.T))
    Dh21 = np.linalg.cholesky(np.eye(p2) - D1112.T @ _solve(M_r, D1112)).T
    F12 = F[c:m1]  # rows of F1 = F[:m1] that meet the measured part of w
    F2 = F[m1:]
    L12 = L[:, r:p1]  # columns of L1 = L[:, :p1] that meet the controlled part of z
    L2 = L[:, p1:]
    Z = np.linalg.inv(np.eye(n) - (Y @ X) / g2)
    Bh2 = Z @ (p.B2 + L12) @ Dh12
    Ch2 = -Dh21 @ (p.C2 + F12)
    Bh1 = -Z @ L2 + Bh2 @ np.linalg.solve(Dh12, Dh11)
    Ch1 = F2 + Dh11 @ np.linalg.solve(Dh21, Ch2)
    B = np.hstack([p.B1, p.B2])
    Ah = p.A + B @ F + Bh1 @ np.linalg.solve(Dh21, Ch2)
    return Ah, Bh1, Ch1, Dh11
