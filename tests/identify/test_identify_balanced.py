"""balanced_truncation: reference checks against python-control/SLICOT, the eq. 13 bound on a
lightly damped system with dozens of modes, and bad input."""

from __future__ import annotations

import control
import numpy as np
import pytest
from test_identify_support import random_modal_system

import robustctl as rc
from robustctl.balanced import _factor_scipy, gramian_factor


@pytest.fixture(scope="module")
def big():
    return random_modal_system(40, 3, 3, f_lo=1.0, f_hi=50.0, seed=3)  # 80 states, 0.5-2 % damping


def test_gramian_factors_reproduce_the_gramians(big):
    a, b, c = big.A, big.B, big.C
    for lo, gram in (
        (gramian_factor(a, b), control.gram(big, "c")),
        (gramian_factor(a, c, True), control.gram(big, "o")),
    ):
        np.testing.assert_allclose(lo @ lo.T, gram, rtol=1e-8, atol=1e-10 * np.abs(gram).max())
    fallback = _factor_scipy(a, b, False)
    np.testing.assert_allclose(
        fallback @ fallback.T, control.gram(big, "c"), atol=1e-8 * np.abs(control.gram(big, "c")).max()
    )


def test_hankel_singular_values_and_reduced_model_match_slicot(big):
    red = rc.balanced_truncation(big, 30)
    np.testing.assert_allclose(red.hsv, control.hsvd(big), rtol=1e-8)
    ref = control.balred(big, 30)
    f = np.linspace(0.5, 60, 400)
    np.testing.assert_allclose(
        rc.freqresp(red.sys, f).response, rc.freqresp(ref, f).response, rtol=1e-6, atol=1e-9
    )


@pytest.mark.parametrize("order", [10, 40, 70])
def test_error_bound_holds_on_a_dense_grid(big, order):
    red = rc.balanced_truncation(big, order)
    f = np.concatenate([np.linspace(0.01, 60, 6000), np.abs(np.linalg.eigvals(big.A)) / (2 * np.pi)])
    f = np.unique(f)
    d = rc.freqresp(big, f).response - rc.freqresp(red.sys, f).response
    err = max(np.linalg.norm(dk, 2) for dk in d)
    assert err <= red.bound * (1 + 1e-9)
    assert err >= red.hsv[order]  # and the lower bound sigma_{m+1} (Glover) is not beaten


def test_bad_input():
    unstable = control.ss([[0.1, 0], [0, -1]], [[1], [1]], [[1, 1]], [[0]])
    with pytest.raises(rc.ModelError, match="asymptotically stable"):
        rc.balanced_truncation(unstable, 1)
    stable = control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]])
    with pytest.raises(rc.FitError, match="order must be an integer"):
        rc.balanced_truncation(stable, 0)
    with pytest.raises(rc.FitError, match="order must be an integer"):
        rc.balanced_truncation(stable, 3)


def test_hammarling_factor_uses_slicot_and_matches_the_gramians():
    """SB03OD is really called (it silently never was: a wrong argument order fell back to scipy)."""
    pytest.importorskip("slycot", reason="slycot comes with the dev extra")
    import scipy.linalg as sla

    from robustctl.balanced import hammarling_factor

    rng = np.random.default_rng(4)
    A = rng.standard_normal((8, 8)) - 6 * np.eye(8)
    B, C = rng.standard_normal((8, 2)), rng.standard_normal((3, 8))
    P = sla.solve_continuous_lyapunov(A, -B @ B.T)
    Q = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    Lc, Lo = hammarling_factor(A, B, False), hammarling_factor(A, C, True)
    assert Lc is not None and Lo is not None
    np.testing.assert_allclose(Lc @ Lc.T, P, atol=1e-10 * np.abs(P).max())
    np.testing.assert_allclose(Lo @ Lo.T, Q, atol=1e-10 * np.abs(Q).max())
