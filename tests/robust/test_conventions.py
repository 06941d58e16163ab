"""Conventions a control engineer can't get wrong: d2c round trips and refusals, the LQG sign,
ncfsyn's pointer to d2c."""

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


def test_ncfsyn_on_a_discrete_plant_points_at_d2c_which_exists():
    Gd = control.c2d(control.ss(control.tf([1.0], [1.0, 0.4, 4.0])), 0.02)
    with pytest.raises(SynthesisError, match=r"rc\.d2c\(G\)") as err:
        rc.ncfsyn(Gd)
    assert hasattr(rc, "d2c") and "discretize" in str(err.value)
    Ks = rc.ncfsyn(rc.d2c(Gd))  # the advice works
    assert Ks.K.isctime()


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
