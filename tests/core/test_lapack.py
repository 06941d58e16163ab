"""robustctl._lapack: the LAPACK calls of numpy.linalg / scipy.linalg without their wrappers."""

import numpy as np
import pytest
import scipy.linalg

from robustctl import _lapack


def _tight(got, want, tol=1e-12):
    scale = max(1.0, float(np.max(np.abs(want), initial=0.0)))
    np.testing.assert_allclose(got, want, rtol=tol, atol=tol * scale)


@pytest.mark.parametrize("shape", [(1, 1), (2, 1), (1, 3), (4, 4), (7, 3), (3, 7), (30, 30)])
def test_singular_values_and_thin_svd_match_numpy(shape):
    rng = np.random.default_rng(sum(shape))
    a = rng.standard_normal(shape)
    _tight(_lapack.svdvals(a), np.linalg.svd(a, compute_uv=False))
    c = a + 1j * rng.standard_normal(shape)
    _tight(_lapack.svdvals(c), np.linalg.svd(c, compute_uv=False))
    u, s, vt = _lapack.svd_thin(a)
    _tight(s, np.linalg.svd(a, compute_uv=False))
    _tight((u * s) @ vt, a)  # a factorisation of a, orthonormal factors
    _tight(u.T @ u, np.eye(min(shape)))
    assert _lapack.svdvals(np.zeros((0, 3))).shape == (0,)


@pytest.mark.parametrize("n", [1, 3, 8, 40])
def test_solve_eigvals_and_schur_match_numpy_and_scipy(n):
    rng = np.random.default_rng(n)
    a = rng.standard_normal((n, n))
    b = rng.standard_normal((n, 2))
    _tight(_lapack.solve(a, b), np.linalg.solve(a, b))
    ev, ref = _lapack.eigvals(a), np.linalg.eigvals(a)
    assert ev.dtype == ref.dtype
    _tight(np.sort_complex(ev), np.sort_complex(ref))
    for sort in (False, True):
        T, Z, wr, sdim = _lapack.real_schur(a, sort_lhp=sort)
        _tight(Z @ T @ Z.T, a)
        _tight(np.sort(wr), np.sort(ref.real))
        if sort:
            T2, Z2, sdim2 = scipy.linalg.schur(a, output="real", sort="lhp")
            assert sdim == sdim2 == int(np.sum(ref.real < 0))
            assert np.all(wr[:sdim] < 0) and np.all(wr[sdim:] >= 0)
        else:
            T2, Z2 = scipy.linalg.schur(a, output="real")
        _tight(T, T2)


def test_real_eigenvalues_stay_real_and_failures_raise_numpys_errors():
    assert _lapack.eigvals(np.diag([1.0, -2.0])).dtype == np.float64
    with pytest.raises(np.linalg.LinAlgError, match="Singular matrix"):
        _lapack.solve(np.zeros((2, 2)), np.ones((2, 1)))
    with pytest.raises(np.linalg.LinAlgError):
        _lapack.eigvals(np.array([[np.nan, 0.0], [0.0, 1.0]]))
    with pytest.raises(ValueError):
        _lapack.real_schur(np.array([[np.inf, 0.0], [0.0, 1.0]]))
    T, Z, wr, sdim = _lapack.real_schur(np.zeros((0, 0)), sort_lhp=True)
    assert T.shape == Z.shape == (0, 0) and sdim == 0
