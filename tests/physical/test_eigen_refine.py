"""The low modes of a stiff structure: accurate, and the same whatever order LAPACK sums in.

A dense ``eigh`` leaves an eigenvalue an absolute error of about ``eps * w_max^2``; a mode far
below the highest gets a relative error ``eps * w_max^2 / w^2`` whose value depends on the BLAS
kernel. ``solve_modes`` refines the low modes in extended precision. The reference here is an
independent method: Sturm-count bisection of the tridiagonal pencil of a spring-mass chain in
50-digit decimal arithmetic.
"""

from decimal import Decimal, getcontext

import numpy as np
import pytest

from robustctl.physical.eigen import LOW_SHARE, solve_modes

pytestmark = pytest.mark.skipif(
    np.finfo(np.longdouble).eps >= np.finfo(float).eps,
    reason="numpy.longdouble is double on this platform: no extended-precision refinement",
)


def chain(n: int = 20, k: float = 1e3, stiff: float = 1e8, light: float = 0.1):
    """A fixed-free chain of ``n`` unit masses on springs ``k``, the last mass ``light`` on a
    spring ``stiff``: ``w_max^2 / w_min^2`` near 3e8, as a truss's stiff diagonals against its
    first bending mode. Tridiagonal K, diagonal M (N/m, kg)."""
    springs = np.full(n, k)
    springs[-1] = stiff
    masses = np.ones(n)
    masses[-1] = light
    K = np.zeros((n, n))
    for i, s in enumerate(springs):  # spring i joins DOF i-1 (ground for i = 0) and DOF i
        K[i, i] += s
        if i > 0:
            K[i - 1, i - 1] += s
            K[i - 1, i] = K[i, i - 1] = -s
    return K, np.diag(masses)


def sturm_eigenvalues(K: np.ndarray, M: np.ndarray, count: int) -> list[Decimal]:
    """The ``count`` lowest eigenvalues of the tridiagonal pencil ``(K, M)`` (diagonal ``M``)
    by bisection on the Sturm count of ``K - lam M = L D L^T``, in 50-digit decimals."""
    getcontext().prec = 50
    a = [Decimal(float(v)) for v in np.diag(K)]
    b = [Decimal(float(v)) for v in np.diag(K, 1)]
    m = [Decimal(float(v)) for v in np.diag(M)]

    def below(lam: Decimal) -> int:  # how many eigenvalues lie below lam
        neg, d = 0, Decimal(1)
        for i in range(len(a)):
            d = a[i] - lam * m[i] - (b[i - 1] * b[i - 1] / d if i else 0)
            if d == 0:
                d = Decimal("1e-60")
            neg += d < 0
        return neg

    top = sum(abs(v) for v in a) * 4 / min(m)
    out = []
    for j in range(count):
        lo, hi = Decimal(0), top
        for _ in range(200):
            mid = (lo + hi) / 2
            if below(mid) > j:
                hi = mid
            else:
                lo = mid
            if hi - lo <= hi * Decimal("1e-30"):
                break
        out.append((lo + hi) / 2)
    return out


def test_low_modes_of_a_stiff_chain_match_an_independent_high_precision_solution():
    K, M = chain()
    omega, phi = solve_modes(M, K)
    lam = omega**2
    low = np.flatnonzero(lam < LOW_SHARE * lam.max())
    assert low.size >= 15  # the case exercises the refinement
    ref = np.array([float(v) for v in sturm_eigenvalues(K, M, low.size)])
    rel = np.abs(lam[low] - ref) / ref
    assert lam.max() / lam[0] > 1e8
    # the extended precision's bound, eps_ld * w_max^2 / w^2 (twice it): 3.7e-11 for the lowest
    # mode, where a plain dense solve errs by 8.4e-10 (its bound eps * w_max^2 / w^2 is 3.8e-8)
    assert np.all(rel <= 2 * np.finfo(np.longdouble).eps * lam.max() / ref)
    np.testing.assert_allclose(phi.T @ M @ phi, np.eye(lam.size), atol=1e-13)
    resid = K @ phi[:, low] - (M @ phi[:, low]) * lam[low]
    assert np.abs(resid).max() < 1e-12 * np.abs(K).max()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_low_modes_do_not_depend_on_the_order_of_the_dofs(seed):
    """Renumbering the DOFs (an exact permutation of K and M) changes LAPACK's round-off as
    another BLAS kernel does; the refined frequencies and the shapes' outputs stay put."""
    rng = np.random.default_rng(seed)
    K, M = chain(n=30, k=float(rng.uniform(5e2, 2e3)), stiff=float(rng.uniform(5e7, 2e8)))
    K = K + np.diag(rng.uniform(0, 1.0, K.shape[0]))  # springs to ground: no exact pattern
    perm = rng.permutation(K.shape[0])
    w1, phi1 = solve_modes(M, K)
    w2, phi2 = solve_modes(M[np.ix_(perm, perm)], K[np.ix_(perm, perm)])
    low = np.flatnonzero(w1**2 < LOW_SHARE * (w1**2).max())
    # within twice eps_ld * w_max^2 / w^2 (a plain dense solve: 3e-9 apart at the lowest mode)
    bound = 2 * np.finfo(np.longdouble).eps * (w1**2).max() / w1[low] ** 2
    assert np.all(np.abs(w2[low] ** 2 - w1[low] ** 2) / w1[low] ** 2 <= bound)
    # each mode's tip-to-root participation, sign-free: phi_tip * phi_root
    prod1 = phi1[-1, low] * phi1[0, low]
    prod2 = phi2[np.argsort(perm)][-1, low] * phi2[np.argsort(perm)][0, low]
    np.testing.assert_allclose(prod2, prod1, rtol=1e-11, atol=1e-15)
