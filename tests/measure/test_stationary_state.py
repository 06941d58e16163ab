"""The stationary initial state of a simulated record: the same state in any realization.

Issue 36: MACE's closed-loop realization differs between OpenBLAS kernels by a change of basis
among near-repeated modes, and its stationary covariance is indefinite by round-off; a draw
``L z`` in the state basis (Cholesky, with an eigenvector fallback) gave records 7 % apart. The
systems here are made with numpy/scipy only.
"""
import numpy as np
import pytest
from scipy.linalg import block_diag, eigh, expm, solve_discrete_lyapunov

from robustctl.errors import ModelError
from robustctl.measure.estimate import BURN_IN_TOL, STATE_JITTER, _past_state


def _sampled_modes(f_hz, zeta, fs=200.0):
    """ZOH-sampled ``(Ad, Bd)`` of decoupled modes ``s^2 + 2 zeta w s + w^2`` forced in velocity
    (state: position and velocity of each mode)."""
    blocks = [np.array([[0.0, 1.0], [-(2 * np.pi * f) ** 2, -4 * np.pi * z * f]]) for f, z in zip(f_hz, zeta)]
    a = block_diag(*blocks)
    n = a.shape[0]
    b = np.zeros((n, 1))
    b[1::2, 0] = 1.0
    m = expm(np.block([[a, b], [np.zeros((1, n + 1))]]) / fs)
    return m[:n, :n], m[:n, n:]


def _badly_scaled(n, seed):
    """A random change of basis whose rows span three decades (a non-normal ``T Ad T^-1``)."""
    t = np.eye(n) + 0.5 * np.random.default_rng(seed).standard_normal((n, n))
    return t * np.logspace(0, 3, n)[:, None]


def test_the_stationary_start_is_the_same_state_in_any_basis_and_continuous():
    # five modes within 4e-5 Hz at 3 Hz, 0.2 % damping (1 - rho^2 = 3.8e-4), in badly scaled
    # coordinates: scipy's Lyapunov solution is indefinite by round-off, lambda_min = -1.9e-11
    # max(diag P) (MACE's: -5e-14 to -5e-11), beyond the 1e-12 loading of a Cholesky factor
    ad0, bd0 = _sampled_modes([3.0, 3.00001, 3.00002, 3.00003, 3.00004], [0.002] * 5)
    n = ad0.shape[0]
    rms = np.array([1.5])

    def start(t, bd=bd0, rms=rms):
        """The start drawn in basis ``t x``, returned in the modal basis."""
        x = _past_state(t @ ad0 @ np.linalg.inv(t), t @ bd, rms, np.random.default_rng(7))
        return np.linalg.solve(t, x)

    t0 = _badly_scaled(n, 0)
    ad, bd = t0 @ ad0 @ np.linalg.inv(t0), t0 @ bd0
    p = solve_discrete_lyapunov(ad, (bd * rms**2) @ bd.T)
    assert np.linalg.eigvalsh((p + p.T) / 2)[0] < -STATE_JITTER * np.max(np.diag(p))
    x0 = start(t0)
    scale = np.linalg.norm(x0)

    # other bases (a permutation, another badly scaled one, the modal one): the same state, to
    # round-off and the 1e-8 weight left on the basis-dependent part (a Cholesky draw moved by
    # its own size)
    for t in (t0[np.random.default_rng(1).permutation(n)], _badly_scaled(n, 5), np.eye(n)):
        assert np.linalg.norm(start(t) - x0) < 1e-6 * scale

    # a 1e-13 relative change of the input matrix or level moves it by round-off only (a Cholesky
    # factor of the round-off-singular covariance moved 1 %)
    e = np.random.default_rng(3).standard_normal(bd0.shape)
    for bd2, rms2 in [(bd0 * (1 + 1e-13 * e), rms), (bd0, rms * (1 + 1e-13))]:
        assert np.linalg.norm(start(t0, bd2, rms2) - x0) < 1e-6 * scale


def test_the_stationary_start_is_the_sum_of_the_past_excitation_and_a_damped_draw():
    # reference: x0 = Ad^K S z + sum_{k<K} Ad^k Bd w_k by the plain recursion, S the symmetric
    # square root of P (numpy), z and then the past excitation from the generator's streams
    ad, bd = _sampled_modes([3.0, 11.0], [0.1, 0.05])
    t = _badly_scaled(4, 4)
    ad, bd = t @ ad @ np.linalg.inv(t), t @ bd
    rms = np.array([0.7])
    x0 = _past_state(ad, bd, rms, np.random.default_rng(5))
    rng = np.random.default_rng(5)
    z = rng.standard_normal(4)
    past = rng.spawn(1)[0]
    p = solve_discrete_lyapunov(ad, (bd * rms**2) @ bd.T)
    w, v = eigh((p + p.T) / 2)
    x = (v * np.sqrt(np.clip(w, 0, None) + STATE_JITTER * np.max(np.diag(p)))) @ v.T @ z
    rho = np.max(np.abs(np.linalg.eigvals(ad)))
    k = int(np.ceil(np.log(BURN_IN_TOL) / np.log(rho)))
    wk = past.standard_normal((k, 1)) * rms
    for i in range(k - 1, -1, -1):
        x = ad @ x + bd @ wk[i]
    np.testing.assert_allclose(x0, x, rtol=1e-9, atol=1e-12 * np.linalg.norm(x))


@pytest.mark.slow
def test_the_stationary_draws_have_the_lyapunov_covariance():
    # two modes, 20 % and 30 % damping, at 200 Hz; 20,000 draws against the series sum
    ad, bd = _sampled_modes([5.0, 20.0], [0.2, 0.3])
    rms = np.array([2.0])
    p, term = np.zeros((4, 4)), (bd * rms**2) @ bd.T
    for _ in range(5000):
        p, term = p + term, ad @ term @ ad.T
    rng = np.random.default_rng(11)
    n_draws = 20000
    x = np.array([_past_state(ad, bd, rms, rng) for _ in range(n_draws)])
    cov = x.T @ x / n_draws
    # standard error of each entry of a Gaussian sample covariance with known zero mean
    se = np.sqrt((np.outer(np.diag(p), np.diag(p)) + p**2) / n_draws)
    assert np.max(np.abs(cov - p) / se) < 4.5
    assert np.max(np.abs(np.mean(x, axis=0)) / np.sqrt(np.diag(p) / n_draws)) < 4.5


def test_a_non_finite_covariance_is_refused():
    ad = np.array([[0.5, 0.0], [0.0, 0.5]])
    with pytest.raises(ModelError, match="not finite"):  # an input variance that overflows
        _past_state(ad, np.array([[1e200], [1.0]]), np.array([1.0]), np.random.default_rng(0))


def test_simulate_experiment_with_the_past_start_gives_one_record_in_any_realization():
    """``start="past"`` (the default): the same record from a system and from it in a badly scaled
    basis (to the sum's round-off, 1e-6 of the largest output); ``start="draw"`` gives another
    record there (its draw is made in the state basis); an unknown start is refused."""
    import control

    import robustctl as rc

    modes = [1.9, 2.3, 2.30004, 7.1]
    a = block_diag(*[np.array([[0.0, 1.0], [-(2 * np.pi * f) ** 2, -4 * np.pi * 0.003 * f]]) for f in modes])
    b = np.zeros((8, 1))
    b[1::2, 0] = 1.0
    c = np.zeros((2, 8))
    c[0, ::2], c[1, ::4] = 1.0, 1.0
    t = _badly_scaled(8, 3)
    ti = np.linalg.inv(t)
    one = control.ss(a, b, c, np.zeros((2, 1)))
    other = control.ss(t @ a @ ti, t @ b, c @ ti, np.zeros((2, 1)))
    kw = dict(fs=50.0, n_samples=4096, seed=4)
    _, y1 = rc.simulate_experiment(one, **kw)
    _, y2 = rc.simulate_experiment(other, **kw)
    assert np.max(np.abs(y1 - y2)) < 1e-6 * np.max(np.abs(y1))
    _, p1 = rc.simulate_experiment(one, start="past", **kw)
    np.testing.assert_array_equal(p1, y1)
    _, d1 = rc.simulate_experiment(one, start="draw", **kw)
    _, d2 = rc.simulate_experiment(other, start="draw", **kw)
    assert np.max(np.abs(d1[:200] - d2[:200])) > 1e-3 * np.max(np.abs(d1))
    with pytest.raises(rc.DataError, match="start must be one of"):
        rc.simulate_experiment(one, start="rest", **kw)
