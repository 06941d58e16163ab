"""The LQG-beside-mu demo: scoring a controller on data as the yardstick does, and the MACE comparison."""

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.demo_lqg import lqg_beside_mu, score_on_data


def test_score_on_exact_data_matches_direct_closed_loop():
    # a stable 2 x 2 structure measured exactly; a static rate feedback u = -0.5 y (s = -1)
    G = control.ss(control.tf([[[1.0, 0.0], [0.2, 0.0]], [[0.2, 0.0], [1.0, 0.0]]],
                              [[[1.0, 0.1, 4.0], [1.0, 0.1, 4.0]], [[1.0, 0.2, 9.0], [1.0, 0.2, 9.0]]]))
    G = control.ss(G.A, G.B, G.C, G.D, inputs=["u1", "u2"], outputs=["y1", "y2"])
    f = np.geomspace(0.01, 50, 4000)
    data = rc.freqresp(G, f)
    K = control.ss([], [], [], 0.5 * np.eye(2), inputs=["y1", "y2"], outputs=["u1", "u2"])
    score = score_on_data(data, K, G, G, band=(0.2, 1.0), sign=-1.0)
    H = rc.lti.freqresp_array(G, f)
    T = np.linalg.solve(np.eye(2)[None] + H * 0.5, H)
    m = (f >= 0.2) & (f <= 1.0)
    rms = lambda X: np.sqrt(np.mean(np.sum(np.abs(X[m]) ** 2, axis=(1, 2))))  # noqa: E731
    assert score.attenuation_db == pytest.approx(20 * np.log10(rms(H) / rms(T)), rel=1e-10)
    assert score.verdict.stable is True
    assert rc.is_stable(control.feedback(G, K, sign=-1))


@pytest.mark.slow
def test_lqg_beside_mu_on_the_mace_bus():
    res = lqg_beside_mu(seed=0)
    lq, mu = res.rows["LQG (nominal model)"], res.rows["mu (nominal model)"]
    # the mu controller is scored exactly as the yardstick scores it
    assert mu["attenuation_db"] == pytest.approx(res.yardstick.attenuation_db["nominal"], rel=1e-9)
    assert mu["stable"] == res.yardstick.stability["nominal"].label
    # LQG: the closed loop on its design model is verified (h2syn), robust performance is not
    assert rc.is_stable(res.lqg.closed_loop) and lq["order"] == 12
    assert mu["mu_peak"] < 1 < lq["mu_peak"]
    assert lq["disk_phase_deg"] > 0  # stable on the full nominal model too
    assert "LQG" in res.summary() and "attenuation" in str(res.table()) and res.plot().axes
