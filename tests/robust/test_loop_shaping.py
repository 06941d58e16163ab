"""rc.ncfsyn against the closed-form optimal margin sqrt(1 - ||[Nt, Mt]||_H^2); normalized coprime factors."""

import control
import numpy as np
import pytest
import scipy.linalg

import robustctl as rc
from robustctl.errors import SynthesisError
from robustctl.lti import freqresp_array
from robustctl.robust.analysis.coprime import left_ncf, right_ncf

s = control.tf("s")


def _mats(G):
    G = control.ss(G)
    return tuple(np.asarray(x, dtype=float) for x in (G.A, G.B, G.C, G.D))


def _plants():
    np.random.seed(4)
    R = control.rss(6, 2, 2)
    return [
        1 / (s + 1),
        4 / (s**2 + 0.04 * s + 4),  # a lightly damped mode
        (s - 1) / ((s + 2) * (s - 3)),  # unstable, non-minimum phase
        control.ss(R.A, R.B, R.C, 0.3 * np.random.randn(2, 2)),  # MIMO with feedthrough
    ]


@pytest.mark.parametrize("k", range(4))
def test_coprime_factors_are_normalized_and_factor_the_plant(k):
    A, B, C, D = _mats(_plants()[k])
    p, m = D.shape
    f = np.array([0.01, 0.2, 1.0, 30.0])
    G = freqresp_array(control.ss(A, B, C, D), f)
    r = freqresp_array(control.ss(*right_ncf(A, B, C, D)), f)
    lf = freqresp_array(control.ss(*left_ncf(A, B, C, D)), f)
    for i in range(f.size):
        M, N = r[i][:m], r[i][m:]
        Nt, Mt = lf[i][:, :m], lf[i][:, m:]
        np.testing.assert_allclose(M.conj().T @ M + N.conj().T @ N, np.eye(m), atol=1e-10)
        np.testing.assert_allclose(Mt @ Mt.conj().T + Nt @ Nt.conj().T, np.eye(p), atol=1e-10)
        np.testing.assert_allclose(N @ np.linalg.inv(M), G[i], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(np.linalg.solve(Mt, Nt), G[i], rtol=1e-9, atol=1e-12)


def _closed_form_b_opt(G):
    """sqrt(1 - ||[Nt, Mt]||_H^2), the Hankel norm from the factor's own Gramians."""
    Al, Bl, Cl, _ = left_ncf(*_mats(G))
    P = scipy.linalg.solve_continuous_lyapunov(Al, -Bl @ Bl.T)
    Q = scipy.linalg.solve_continuous_lyapunov(Al.T, -Cl.T @ Cl)
    hankel = np.sqrt(np.max(np.linalg.eigvals(P @ Q).real))
    return np.sqrt(1 - hankel**2)


@pytest.mark.parametrize("k", range(4))
def test_ncfsyn_achieves_the_closed_form_optimum(k):
    G = _plants()[k]
    res = rc.ncfsyn(G, factor=1.0 + 1e-7)
    b = _closed_form_b_opt(G)
    assert res.b_opt == pytest.approx(b, rel=1e-9)
    assert abs(res.b_achieved - b) <= 1e-6 * b
    # the closed loop, formed independently (positive feedback u = K y), is stable
    cl = control.feedback(control.ss(G), res.K, sign=+1)
    assert rc.is_stable(cl)
    assert rc.robust.analysis.stability_margin(G, res.K) == pytest.approx(res.b_achieved, rel=1e-9)


def test_first_order_plant_margin_is_cos_pi_over_8():
    # G = 1/(s+1): X = Z = sqrt(2) - 1, b_opt = (1 + (sqrt(2) - 1)^2)^-1/2 = cos(pi/8)
    assert rc.ncfsyn(1 / (s + 1)).b_opt == pytest.approx(np.cos(np.pi / 8), rel=1e-12)


def test_weighted_design_and_nugap_robustness():
    G = 4 / (s**2 + 0.04 * s + 4) * (1 / (0.05 * s + 1))
    W1 = (s + 0.5) / (s + 1e-3) * 2  # near-integral action
    res = rc.ncfsyn(G, W1)
    assert 1 / res.gamma <= res.b_achieved * (1 + 1e-9) <= res.b_opt * (1 + 1e-9)
    assert res.K.ninputs == 1 and res.K.nstates == res.shaped.nstates + 1
    assert rc.is_stable(control.feedback(control.ss(G), res.K, sign=+1))
    # Vinnicombe: b(G, K) > nugap(G, G2) guarantees that K stabilises G2 (shaped plants compared)
    G2 = 4.6 / (s**2 + 0.08 * s + 4.4) * (1 / (0.06 * s + 1))
    gap, _ = rc.nugap(res.shaped, G2 * W1)
    assert gap < res.b_achieved
    assert rc.is_stable(control.feedback(control.ss(G2), res.K, sign=+1))
    assert "margin" in res.summary() and "b_opt" in str(res.table())
    assert res.plot().axes


def test_ncfsyn_refuses_bad_input():
    with pytest.raises(SynthesisError, match="factor"):
        rc.ncfsyn(1 / (s + 1), factor=0.9)
    with pytest.raises(SynthesisError, match="W1"):
        rc.ncfsyn(1 / (s + 1), np.eye(2))
    with pytest.raises(SynthesisError, match="continuous"):  # a sampled weight on a continuous plant
        rc.ncfsyn(1 / (s + 1), control.c2d(control.ss(1 / (s + 2)), 0.1))
    with pytest.raises(SynthesisError, match="sampled at the same"):  # and the reverse
        rc.ncfsyn(control.c2d(1 / (s + 1), 0.1), 1 / (s + 2))
