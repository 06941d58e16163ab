"""Conventions a control engineer can't get wrong: d2c round trips and refusals, the LQG sign,
ncfsyn on a sampled plant."""

from __future__ import annotations

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import ModelError, SynthesisError


def _plant():
    rng = np.random.default_rng(2)
    A = np.array([[-0.3, 4.0, 0, 0], [-4.0, -0.3, 0, 0], [0, 0, -1.5, 0.7], [0, 0, 0, -6.0]])
    B, C, D = rng.standard_normal((4, 2)), rng.standard_normal((2, 4)), rng.standard_normal((2, 2))
    return control.ss(A, B, C, D, inputs=["u1", "u2"], outputs=["y1", "y2"])


@pytest.mark.parametrize("method", ["zoh", "tustin"])
def test_d2c_inverts_c2d(method):
    G = _plant()
    Gd = control.c2d(G, 0.05, method=method)  # python-control / scipy do the forward map
    Gc = rc.d2c(Gd, method=method)
    w = np.geomspace(0.01, 50.0, 40)
    H = np.stack([np.asarray(Gc(1j * x)) for x in w])
    H0 = np.stack([np.asarray(G(1j * x)) for x in w])
    assert np.abs(H - H0).max() <= 1e-10 * np.abs(H0).max()
    assert Gc.isctime() and list(Gc.input_labels) == ["u1", "u2"] and list(Gc.output_labels) == ["y1", "y2"]
    # the poles come back where they were (within the Nyquist band)
    assert np.allclose(np.sort_complex(np.linalg.eigvals(Gc.A)), np.sort_complex(np.linalg.eigvals(G.A)),
                       rtol=1e-10, atol=0)


def test_d2c_refuses_what_cannot_be_mapped():
    neg = control.ss([[-0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1)  # rings at the Nyquist rate
    with pytest.raises(ModelError, match="negative real axis"):
        rc.d2c(neg)
    delay = control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1)  # one-sample delay: pole at z = 0
    with pytest.raises(ModelError, match="pure delay"):
        rc.d2c(delay)
    # Tustin maps z = -0.5 fine, but not z = -1
    assert rc.d2c(neg, method="tustin").A[0, 0] == pytest.approx((2 / 0.1) * (-1.5 / 0.5))
    with pytest.raises(ModelError, match="z = -1"):
        rc.d2c(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1), method="tustin")
    with pytest.raises(ModelError, match="discrete system"):
        rc.d2c(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]))


def _four_block_margin_on_the_circle(G, K, dt, n=20001):
    """b(G, K) = 1 / max ||[I; K](I - G K)^-1 [I, G]|| on z = exp(j w dt), 0 <= w <= pi / dt, by numpy."""
    A, B, C, D, Ak, Bk, Ck, Dk = (np.asarray(x, float) for x in (G.A, G.B, G.C, G.D, K.A, K.B, K.C, K.D))
    z = np.exp(1j * np.linspace(0.0, np.pi, n))[:, None, None]
    g = C @ np.linalg.solve(z * np.eye(len(A)) - A, np.broadcast_to(B, (n, *B.shape))) + D
    k = Ck @ np.linalg.solve(z * np.eye(len(Ak)) - Ak, np.broadcast_to(Bk, (n, *Bk.shape))) + Dk
    p = g.shape[1]
    S = np.linalg.inv(np.eye(p) - g @ k)
    four = np.concatenate([S, k @ S], axis=1) @ np.concatenate(
        [np.broadcast_to(np.eye(p), (n, p, p)), g], axis=2)
    return 1.0 / np.linalg.norm(four, 2, axis=(1, 2)).max()


def test_ncfsyn_on_a_sampled_plant_designs_through_the_tustin_map():
    # a lightly damped plant sampled with a zero-order hold at 50 Hz, shaped by an integrator-like
    # weight sampled at the same rate
    dt = 0.02
    Gd = control.c2d(control.ss(control.tf([1.0], [1.0, 0.4, 4.0])), dt)
    W1d = control.c2d(control.ss(control.tf([1.0, 2.0], [1.0, 0.01])), dt, method="tustin")
    res = rc.ncfsyn(Gd, W1d)
    assert res.K.dt == dt and res.Ks.dt == dt
    # the same design as the continuous one through the same map: margins equal
    cont = rc.ncfsyn(rc.d2c(Gd, method="tustin"), rc.d2c(W1d, method="tustin"))
    assert res.b_opt == pytest.approx(cont.b_opt, rel=1e-12)
    assert res.b_achieved == pytest.approx(cont.b_achieved, rel=1e-12)
    # independently, on the unit circle with numpy: the sampled shaped loop's margin is b_achieved,
    # and the sampled loop G, K is stable (every closed-loop pole inside the unit circle)
    b = _four_block_margin_on_the_circle(res.shaped, res.Ks, dt)
    assert b == pytest.approx(res.b_achieved, rel=1e-4)
    assert 0.2 < b < 1.0
    cl = control.feedback(Gd, res.K, sign=+1)
    assert np.max(np.abs(np.linalg.eigvals(np.asarray(cl.A)))) < 1.0


def test_ncfsyn_on_a_sampled_plant_refuses_what_the_map_cannot_take():
    Gd = control.c2d(control.ss(control.tf([1.0], [1.0, 0.4, 4.0])), 0.02)
    with pytest.raises(SynthesisError, match="sampled at the same"):
        rc.ncfsyn(Gd, control.tf([1.0, 2.0], [1.0, 0.01]))  # a continuous weight
    with pytest.raises(SynthesisError, match="z = -1"):
        rc.ncfsyn(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    assert rc.ncfsyn(Gd, 2.0).K.dt == 0.02  # a constant weight is fine


def test_lqg_states_its_loop_sign_and_it_is_the_negated_textbook_controller():
    G = control.ss(control.tf([1.0], [1.0, 0.2, 1.0]))
    A, B, C = (np.asarray(x, float) for x in (G.A, G.B, G.C))
    P = control.ss(A, np.hstack([B, B]), np.vstack([C, C]), 0, inputs=["w", "u"], outputs=["p", "y"])
    res = rc.lqg(P, 1.0, 0.1, 1.0, 0.01, controls=["u"], measurements=["y"], disturbances=["w"],
                 performance=["p"])
    assert "u = +K y" in res.summary()
    # the textbook controller u = -Kr x_hat, x_hat' = (A - B Kr - L C) x_hat + L y, from scipy's Riccati
    Kr, L = res.lqr_gain, res.kalman_gain
    textbook = control.ss(A - B @ Kr - L @ C, L, Kr, 0)  # y -> Kr x_hat; u = -(this) y
    for w in (0.1, 1.0, 7.0):
        assert np.asarray(res.K(1j * w)) == pytest.approx(-np.asarray(textbook(1j * w)), rel=1e-9)
