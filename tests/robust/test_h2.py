"""rc.h2norm and rc.h2syn against closed forms, SLICOT (AB13BD, SB10HD via python-control) and LMIs."""

import control
import numpy as np
import pytest
import scipy.linalg

import robustctl as rc
from robustctl.errors import SynthesisError


def random_plant(n, nw, nu, nz, ny, dt, seed, d11=False):
    """A random generalized plant with D12, D21 of full rank (D11, D22 too when asked)."""
    rng = np.random.default_rng(seed)
    np.random.seed(seed)  # control.rss/drss draw from numpy's global generator
    G = control.drss(n, nz + ny, nw + nu) if dt else control.rss(n, nz + ny, nw + nu)
    D = np.zeros((nz + ny, nw + nu))
    D[:nz, nw:] = rng.standard_normal((nz, nu))
    D[nz:, :nw] = rng.standard_normal((ny, nw))
    if d11:
        D[:nz, :nw] = rng.standard_normal((nz, nw))
        D[nz:, nw:] = rng.standard_normal((ny, nu))
    return control.ss(G.A, G.B, G.C, D, dt)


# ---------------------------------------------------------------------------- h2norm
@pytest.mark.parametrize("a", [0.01, 1.0, 250.0])
def test_h2norm_first_order_closed_form(a):
    # ||1/(s+a)||_2^2 = int_0^inf e^(-2at) dt = 1/(2a)
    assert rc.h2norm(control.tf([1.0], [1.0, a])) == pytest.approx(1 / np.sqrt(2 * a), rel=1e-10)


@pytest.mark.parametrize("wn, zeta", [(3.0, 0.05), (100.0, 0.001), (0.2, 0.7)])
def test_h2norm_second_order_closed_form(wn, zeta):
    # ||wn^2 / (s^2 + 2 zeta wn s + wn^2)||_2^2 = wn / (4 zeta)
    g = rc.h2norm(control.tf([wn**2], [1.0, 2 * zeta * wn, wn**2]))
    assert g == pytest.approx(np.sqrt(wn / (4 * zeta)), rel=1e-9)


def test_h2norm_discrete_first_order_with_feedthrough_closed_form():
    # d + b/(z - a): Markov parameters d, b, b a, b a^2, ... -> d^2 + b^2 / (1 - a^2)
    a, b, d, dt = 0.9, 0.3, 0.5, 0.01
    g = rc.h2norm(control.ss([[a]], [[1.0]], [[b]], [[d]], dt))
    assert g == pytest.approx(np.sqrt(d**2 + b**2 / (1 - a**2)), rel=1e-12)


@pytest.mark.parametrize("shape", [(3, 2), (2, 4)])  # (outputs, inputs): either Gramian outside
@pytest.mark.parametrize("dt", [0, 0.05])
@pytest.mark.parametrize("n", [3, 12, 30])
def test_h2norm_matches_slycot_ab13bd_and_python_control(n, dt, shape):
    from slycot import ab13bd

    p, m = shape
    np.random.seed(n)
    G = control.drss(n, p, m) if dt else control.rss(n, p, m)
    if not dt:
        G = control.ss(G.A, G.B, G.C, np.zeros((p, m)))
    ours = rc.h2norm(G)
    ref = ab13bd("D" if dt else "C", "H", n, m, p, G.A, G.B, G.C, G.D)
    assert ours == pytest.approx(ref, rel=1e-8)
    assert ours == pytest.approx(control.norm(G, 2), rel=1e-8)


def test_h2norm_infinite_for_feedthrough_unstable_and_boundary_poles():
    assert rc.h2norm(control.tf([1.0, 2.0], [1.0, 1.0])) == np.inf  # continuous D = 1
    assert rc.h2norm(control.tf([1.0], [1.0, -1.0])) == np.inf  # unstable
    assert rc.h2norm(control.tf([1.0], [1.0, 0.0, 1.0])) == np.inf  # undamped mode
    s = control.tf("s")
    assert rc.h2norm(control.ss(control.sample_system(1 / (s**2 + 1), 0.1))) == np.inf
    assert rc.h2norm(control.ss([], [], [], [[3.0, 4.0]], 0.1)) == pytest.approx(5.0)  # static, discrete
    assert rc.h2norm(control.ss([], [], [], [[0.0]])) == 0.0


def test_h2norm_refuses_data():
    with pytest.raises(rc.ModelError):
        rc.h2norm(rc.FrequencyData(np.array([1.0]), np.ones((1, 1, 1), complex)))


# ---------------------------------------------------------------------------- h2syn
def test_h2syn_python_control_test_plant():
    # python-control's robust_test.py::TestH2 (Octave's SB10HD answer): K = ss(-3, 1, -1, 0)
    P = control.ss(-1, [[1, 1]], [[1], [1]], [[0, 1], [1, 0]])
    res = rc.h2syn(P, 1, 1)
    np.testing.assert_allclose([res.K.A[0, 0], res.K.B[0, 0], res.K.C[0, 0], res.K.D[0, 0]],
                               [-3.0, 1.0, -1.0, 0.0], atol=1e-10)
    assert res.norm == pytest.approx(0.0, abs=1e-10)  # x = y - w is known exactly: z = x + u = 0


@pytest.mark.parametrize("n", [4, 10])
def test_h2syn_matches_slycot_sb10hd(n):
    P = random_plant(n, 3, 2, 3, 2, 0, seed=n)
    res = rc.h2syn(P, 2, 2)
    K = control.h2syn(P, 2, 2)
    ref = control.norm(P.lft(K), 2)
    assert res.norm == pytest.approx(ref, rel=1e-8)
    assert res.info["norm_riccati"] == pytest.approx(ref, rel=1e-8)
    assert rc.is_stable(res.closed_loop)
    assert rc.h2norm(res.closed_loop) == pytest.approx(res.norm, rel=1e-10)
    assert list(res.K.input_labels) == list(P.output_labels[-2:])
    assert list(res.K.output_labels) == list(P.input_labels[-2:])


@pytest.mark.parametrize("d22", [False, True])
def test_h2syn_closed_loop_is_the_lower_lft_with_the_plant_names(d22):
    # Fl(P, K) by hand for a strictly proper K (Dk = 0): u = Ck xk, y = C2 x + D21 w + D22 Ck xk
    P = random_plant(5, 2, 1, 2, 1, 0, seed=11, d11=False)
    D = np.array(P.D)
    if d22:
        D[2:, 2:] = 0.7
    P = control.ss(P.A, P.B, P.C, D, inputs=["w1", "w2", "u"], outputs=["z1", "z2", "y"])
    res = rc.h2syn(P, 1, 1)
    A, B1, B2 = (np.asarray(P.A), np.asarray(P.B)[:, :2], np.asarray(P.B)[:, 2:])
    C1, C2, D12, D21, D22 = (np.asarray(P.C)[:2], np.asarray(P.C)[2:], D[:2, 2:], D[2:, :2], D[2:, 2:])
    Ak, Bk, Ck, Dk = (np.asarray(m) for m in (res.K.A, res.K.B, res.K.C, res.K.D))
    assert not Dk.any()
    A_cl = np.block([[A, B2 @ Ck], [Bk @ C2, Ak + Bk @ D22 @ Ck]])
    B_cl = np.vstack([B1, Bk @ D21])
    C_cl = np.hstack([C1, D12 @ Ck])
    cl = res.closed_loop
    for got, want in ((cl.A, A_cl), (cl.B, B_cl), (cl.C, C_cl), (cl.D, np.zeros((2, 2)))):
        np.testing.assert_allclose(np.asarray(got), want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    assert list(cl.input_labels) == ["w1", "w2"] and list(cl.output_labels) == ["z1", "z2"]
    # its H2 norm from scipy's Lyapunov solver is the one reported
    Lc = scipy.linalg.solve_continuous_lyapunov(A_cl, -B_cl @ B_cl.T)
    assert res.norm == pytest.approx(np.sqrt(np.trace(C_cl @ Lc @ C_cl.T)), rel=1e-9)


@pytest.mark.parametrize("dt", [0, 0.1])
def test_h2syn_equals_lmi_optimum(dt):
    from lmi_reference import h2_lmi

    P = random_plant(3, 2, 1, 2, 1, dt, seed=7, d11=bool(dt))
    res = rc.h2syn(P, 1, 1)
    ref = h2_lmi(P, 1, 1, discrete=bool(dt))
    assert res.norm == pytest.approx(ref, rel=2e-4)  # the LMI solver's accuracy
    assert res.closed_loop.dt == P.dt
    if dt:
        assert np.max(np.abs(np.linalg.eigvals(res.closed_loop.A))) < 1


def test_h2syn_discrete_beats_predictor_and_zero_feedthrough_controllers():
    # the certainty-equivalent controller uses y(k) at time k: dropping its Dk must not help
    P = random_plant(6, 3, 2, 3, 2, 0.05, seed=3, d11=True)
    res = rc.h2syn(P, 2, 2)
    K0 = control.ss(res.K.A, res.K.B, res.K.C, 0 * res.K.D, P.dt)
    cl0 = P.lft(K0)
    worse = rc.h2norm(cl0)
    assert res.norm < worse


def test_h2syn_refuses_bad_plants():
    P = control.ss(-1, [[1, 1]], [[1], [1]], [[1, 1], [1, 0]])  # D11 != 0, continuous
    with pytest.raises(SynthesisError, match="D11"):
        rc.h2syn(P, 1, 1)
    P = control.ss(-1, [[1, 1]], [[1], [1]], [[0, 0], [1, 0]])  # D12 = 0
    with pytest.raises(SynthesisError, match=r"\(A2\)") as err:
        rc.h2syn(P, 1, 1)
    assert "lmi" not in str(err.value)
    P = control.ss(1, [[1, 0]], [[1], [1]], [[0, 1], [1, 0]], 0.1)  # discrete, unstable mode not driven
    with pytest.raises(SynthesisError, match="stabilisable"):
        rc.h2syn(P, 1, 1)
    with pytest.raises(SynthesisError, match="nmeas"):
        rc.h2syn(control.ss(-1, [[1, 1]], [[1], [1]], [[0, 1], [1, 0]]))


def test_h2_result_reports():
    P = random_plant(4, 2, 1, 2, 1, 0, seed=1)
    res = rc.h2syn(P, 1, 1)
    text = str(res.table())
    assert "H2 norm" in text and f"{res.norm:.6g}"[:5] in text
    assert "H2-optimal" in res.summary()
    fig = res.plot()
    assert fig.axes


def test_toolbox_results_pickle():
    import pickle

    P = random_plant(4, 2, 1, 2, 1, 0, seed=1)
    for res in (rc.h2syn(P, 1, 1), rc.ncfsyn(control.tf([1.0], [1.0, 1.0])),
                rc.lqg(control.ss([[-1.0]], [[1.0, 1.0]], [[1.0], [1.0]], [[0.0, 0.0], [0.0, 0.0]],
                                  inputs=["d", "u"], outputs=["p", "y"]),
                       1.0, 1.0, 1.0, 1.0, disturbances=["d"], performance=["p"])):
        back = pickle.loads(pickle.dumps(res))
        np.testing.assert_array_equal(np.asarray(back.K.A), np.asarray(res.K.A))
        assert list(back.K.input_labels) == list(res.K.input_labels)
