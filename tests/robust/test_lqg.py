"""rc.lqg against the separate LQR and Kalman gains of scipy's Riccati solvers."""

import control
import numpy as np
import pytest
import scipy.linalg

import robustctl as rc
from robustctl.errors import SynthesisError


def two_mass_plant(dt=0):
    """Two masses on springs: force u1 and disturbance d on mass 1, position sensors on both."""
    k, c, m = 4.0, 0.02, 1.0
    A = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-2 * k / m, k / m, -c, 0], [k / m, -k / m, 0, -c]])
    B = np.array([[0, 0], [0, 0], [1, 0.5], [0, 1.0]])  # inputs u1, d
    C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 1.0, 0, 0]])  # y1, y2, p (tip)
    G = control.ss(A, B, C, np.zeros((3, 2)), inputs=["u1", "d"], outputs=["y1", "y2", "p"])
    return control.c2d(G, dt) if dt else G


def test_lqg_equals_separate_lqr_and_kalman_continuous():
    G = two_mass_plant()
    Q, R, W, V = 10.0, 0.1, 2.0, np.diag([1e-3, 2e-3])
    kw = dict(controls=["u1"], measurements=["y1", "y2"], disturbances=["d"], performance=["p"])
    res = rc.lqg(G, Q, R, W, V, **kw)
    A, B, C = G.A, G.B, G.C
    Bu, Bd, Cy, Cp = B[:, :1], B[:, 1:], C[:2], C[2:]
    X = scipy.linalg.solve_continuous_are(A, Bu, Cp.T @ (Q * Cp), np.array([[R]]))
    Kr = (Bu.T @ X) / R
    Y = scipy.linalg.solve_continuous_are(A.T, Cy.T, Bd @ (W * Bd.T), V)
    Lk = Y @ Cy.T @ np.linalg.inv(V)
    np.testing.assert_allclose(res.lqr_gain, Kr, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(res.kalman_gain, Lk, rtol=1e-8, atol=1e-10)
    # the controller is the observer-based one: x_hat' = (A - Bu Kr - Lk Cy) x_hat + Lk y, u = -Kr x_hat
    Kref = control.ss(A - Bu @ Kr - Lk @ Cy, Lk, -Kr, 0)
    f = np.array([0.01, 0.3, 0.45, 2.0])
    np.testing.assert_allclose(rc.lti.freqresp_array(res.K, f), rc.lti.freqresp_array(Kref, f), rtol=1e-8)
    # cost = trace(Q Cp Y Cp') + trace(X Lk V Lk') (the two-Riccati LQG cost)
    J = float(np.trace(Q * Cp @ Y @ Cp.T) + np.trace(X @ Lk @ V @ Lk.T))
    assert res.cost == pytest.approx(J, rel=1e-8)
    assert rc.h2norm(res.closed_loop) ** 2 == pytest.approx(res.cost, rel=1e-8)
    assert list(res.K.input_labels) == ["y1", "y2"] and list(res.K.output_labels) == ["u1"]
    assert rc.is_stable(res.closed_loop)


def test_lqg_equals_separate_lqr_and_kalman_discrete():
    dt = 0.05
    G = two_mass_plant(dt)
    Q, R, W, V = 10.0, 0.1, 2.0, np.diag([1e-3, 2e-3])
    res = rc.lqg(G, Q, R, W, V, measurements=["y1", "y2"], disturbances=["d"], performance=["p"])
    A, B, C = (np.asarray(m) for m in (G.A, G.B, G.C))
    Bu, Bd, Cy, Cp = B[:, :1], B[:, 1:], C[:2], C[2:]
    X = scipy.linalg.solve_discrete_are(A, Bu, Cp.T @ (Q * Cp), np.array([[R]]))
    Kr = np.linalg.solve(R + Bu.T @ X @ Bu, Bu.T @ X @ A)
    Y = scipy.linalg.solve_discrete_are(A.T, Cy.T, Bd @ (W * Bd.T), V)
    Lx = Y @ Cy.T @ np.linalg.inv(Cy @ Y @ Cy.T + V)  # filtered (current) estimator gain
    np.testing.assert_allclose(res.lqr_gain, Kr, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(res.kalman_gain, Lx, rtol=1e-8, atol=1e-10)
    assert res.K.dt == dt
    assert np.max(np.abs(np.linalg.eigvals(res.closed_loop.A))) < 1
    assert rc.h2norm(res.closed_loop) ** 2 == pytest.approx(res.cost, rel=1e-8)


def test_lqg_state_weights_and_state_noise():
    G = two_mass_plant()
    n = 4
    kw = dict(controls=["u1"], measurements=["y1", "y2"])
    res = rc.lqg(G, np.eye(n), 1.0, 0.5 * np.eye(n), 1e-2 * np.eye(2), **kw)
    X = scipy.linalg.solve_continuous_are(G.A, G.B[:, :1], np.eye(n), np.eye(1))
    np.testing.assert_allclose(res.lqr_gain, G.B[:, :1].T @ X, rtol=1e-8, atol=1e-10)
    assert "LQG" in res.summary() and "cost" in str(res.table())


def test_lqg_refuses_bad_weights_and_names():
    G = two_mass_plant()
    kw = dict(controls=["u1"], measurements=["y1", "y2"], disturbances=["d"], performance=["p"])
    with pytest.raises(SynthesisError, match="positive definite"):
        rc.lqg(G, 1.0, 0.0, 1.0, np.eye(2), **kw)
    with pytest.raises(SynthesisError, match="2x2"):
        rc.lqg(G, 1.0, 1.0, 1.0, np.eye(3), **kw)
    with pytest.raises(SynthesisError, match="not a signal"):
        rc.lqg(G, 1.0, 1.0, 1.0, np.eye(2), controls=["thrust"], measurements=["y1", "y2"])
    with pytest.raises(SynthesisError, match="semidefinite"):
        rc.lqg(G, -1.0, 1.0, 1.0, np.eye(2), **kw)


def test_lqg_names_an_unstabilisable_plant():
    # an unstable mode the control cannot move
    A, B, C = [[1.0, 0.0], [0.0, -1.0]], [[1.0, 0.0], [0.0, 1.0]], [[1.0, 1.0], [1.0, 1.0]]
    G = control.ss(A, B, C, np.zeros((2, 2)), inputs=["d", "u"], outputs=["p", "y"])
    with pytest.raises(SynthesisError, match="stabilisable"):
        rc.lqg(G, 1.0, 1.0, 1.0, 1.0, disturbances=["d"], performance=["p"])
