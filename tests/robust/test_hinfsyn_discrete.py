"""Discrete-time rc.hinfsyn against the discrete bounded-real LMI and SLICOT SB10DD; sampled plants."""

import control
import numpy as np
import pytest
from test_h2 import random_plant

import robustctl as rc
from robustctl.errors import SynthesisError


def sb10dd_gamma(P, nmeas, ncon, hi, steps=40):
    """Smallest gamma (bisection) for which SB10DD returns a controller that passes the closed-loop check."""
    from slycot import sb10dd

    A, B, C, D = (np.asarray(m, dtype=float) for m in (P.A, P.B, P.C, P.D))

    def ok(g):
        try:
            _, Ak, Bk, Ck, Dk, *_ = sb10dd(A.shape[0], B.shape[1], C.shape[0], ncon, nmeas, g, A, B, C, D)
        except Exception:  # slycot raises several types for an infeasible gamma
            return False
        cl = P.lft(control.ss(Ak, Bk, Ck, Dk, P.dt))
        return np.max(np.abs(np.linalg.eigvals(cl.A))) < 1 and rc.hinfnorm(cl)[0] <= g * (1 + 1e-6)

    lo = 0.0
    for _ in range(steps):
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


@pytest.mark.parametrize("seed", [2, 3])
def test_discrete_hinfsyn_gamma_matches_lmi_and_sb10dd(seed):
    from lmi_reference import hinf_discrete_lmi

    P = random_plant(4, 2, 1, 2, 1, 0.1, seed=seed, d11=True)
    res = rc.hinfsyn(P, 1, 1)
    g_lmi = hinf_discrete_lmi(P, 1, 1)
    g_sb = sb10dd_gamma(P, 1, 1, 10 * res.gamma)
    assert res.gamma_opt == pytest.approx(g_lmi, rel=1e-2)
    assert res.gamma_opt == pytest.approx(g_sb, rel=1e-2)
    # the closed loop verified in discrete time
    cl = res.closed_loop
    assert cl.dt == P.dt and res.K.dt == P.dt
    assert np.max(np.abs(np.linalg.eigvals(cl.A))) < 1
    assert rc.hinfnorm(cl)[0] <= res.info["gamma_design"] * (1 + 1e-6)
    # res.gamma is the upper end of a hinfnorm bracket (info["norm_tol"]); hinfnorm's g at tol 1e-6 the lower
    norm = rc.hinfnorm(cl, tol=1e-6)[0]
    assert norm <= res.gamma <= norm * (1 + 2e-6) * (1 + 2 * res.info["norm_tol"])


def test_discrete_hinfsyn_closed_loop_on_unit_circle_grid():
    P = random_plant(5, 2, 1, 2, 1, 0.01, seed=5, d11=True)
    res = rc.hinfsyn(P, 1, 1)
    f = np.linspace(0, 50, 4001)  # up to fs / 2
    z = np.exp(2j * np.pi * f * 0.01)
    Acl, Bcl, Ccl, Dcl = (np.asarray(m) for m in (res.closed_loop.A, res.closed_loop.B,
                                                  res.closed_loop.C, res.closed_loop.D))
    n = Acl.shape[0]
    peak = max(np.linalg.norm(Ccl @ np.linalg.solve(zk * np.eye(n) - Acl, Bcl) + Dcl, 2) for zk in z)
    assert peak <= res.gamma * (1 + 1e-9)
    assert peak >= 0.98 * res.gamma  # the grid comes close to the verified peak


def mass_spring_plant():
    """A lightly damped mode with a performance weight and small control/noise weights (continuous)."""
    G = control.tf([4.0], [1.0, 0.04, 4.0])
    W1 = control.tf([0.5, 1.0], [1.0, 0.05])
    return control.augw(G, w1=W1, w2=control.tf(0.1, 1))


def test_sampled_plant_with_delay_designs_and_verifies():
    P = rc.PartitionedPlant(control.ss(mass_spring_plant()), 1, 1)
    dt = 0.005  # 200 Hz
    Pd = rc.sampled_plant(P, dt)
    Pdd = rc.sampled_plant(P, dt, delay=True)
    assert Pdd.P.nstates == P.P.nstates + 1 and Pdd.P.dt == dt
    assert list(Pdd.P.input_labels) == list(P.P.input_labels)
    # the delayed plant's response is the undelayed one times z^-1 on the control channel
    f = np.array([0.1, 0.3, 1.0, 10.0])
    z = np.exp(2j * np.pi * f * dt)
    H, Hd = rc.lti.freqresp_array(Pd.P, f), rc.lti.freqresp_array(Pdd.P, f)
    np.testing.assert_allclose(Hd[:, :, 1], H[:, :, 1] / z[:, None], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Hd[:, :, 0], H[:, :, 0], rtol=1e-9, atol=1e-12)
    r0 = rc.hinfsyn(Pd)
    r1 = rc.hinfsyn(Pdd)
    rc_ = rc.hinfsyn(P)
    assert r1.gamma_opt >= r0.gamma_opt * (1 - 1e-3)  # a delay cannot help
    assert r0.gamma_opt == pytest.approx(rc_.gamma_opt, rel=0.05)  # 200 Hz is fast for a 0.3 Hz mode
    assert list(r1.K.input_labels) == P.y_names and r1.K.dt == dt


def test_discrete_controller_exports_as_is(tmp_path):
    P = random_plant(4, 2, 1, 2, 1, 0.01, seed=3, d11=True)
    res = rc.hinfsyn(P, 1, 1)
    rep = rc.export_controller(res.K, tmp_path / "k.json", on_unstable="ignore")  # H-inf K may be unstable
    assert rep is not None
    K2 = rc.load_controller(tmp_path / "k.json")
    K2 = K2.K if hasattr(K2, "K") else K2
    f = np.array([0.5, 3.0, 20.0])
    np.testing.assert_allclose(rc.lti.freqresp_array(K2, f), rc.lti.freqresp_array(res.K, f), rtol=1e-9)


def test_discrete_hinfsyn_refuses_pole_at_nyquist():
    P = control.ss([[-1.0]], [[1.0, 1.0]], [[1.0], [1.0]], [[0.0, 1.0], [1.0, 0.0]], 0.1)
    with pytest.raises(SynthesisError, match="z = -1"):
        rc.hinfsyn(P, 1, 1)
    with pytest.raises(SynthesisError, match="already discrete"):
        rc.sampled_plant(rc.PartitionedPlant(P, 1, 1), 0.1)


def test_discrete_lmi_route_agrees_with_riccati_route():
    P = random_plant(4, 2, 1, 2, 1, 0.1, seed=3, d11=True)
    a, b = rc.hinfsyn(P, 1, 1), rc.hinfsyn(P, 1, 1, method="lmi")
    assert b.gamma_opt == pytest.approx(a.gamma_opt, rel=2e-3)  # bisection tolerance 1e-3 + LMI accuracy
    assert b.K.dt == P.dt and b.info["closed_loop_spectral_radius"] < 1
    assert rc.hinfnorm(b.closed_loop)[0] <= b.info["gamma_design"] * (1 + 1e-6)


def test_discrete_result_reports_spectral_radius_and_plots_to_nyquist():
    P = random_plant(4, 2, 1, 2, 1, 0.01, seed=3, d11=True)
    res = rc.hinfsyn(P, 1, 1)
    text = str(res.table())
    assert "spectral radius" in text and "slowest closed-loop pole" not in text
    ax = res.plot().axes[0]
    assert ax.get_xlim()[1] >= 50.0 * 0.99  # fs / 2 = 50 Hz
