"""Reference checks of the measured-input view's fast paths (robustctl/measure/estimator.py): the
closed-form decomposition of a second-order modal state space and the power series of poles far
above the Nyquist frequency give what the dense eigendecomposition and the per-pole grid give."""

import numpy as np
import pytest
import satellite_corpus as sc

from robustctl.measure import estimator as est


@pytest.fixture(scope="module")
def satellite_ss():
    return sc.nominal_model().statespace()


def test_second_order_modal_form_matches_the_dense_eigendecomposition(satellite_ss):
    A, B, C = (np.asarray(m, dtype=float) for m in (satellite_ss.A, satellite_ss.B, satellite_ss.C))
    poles, res = est._second_order_modal(A, B, C)
    lam, V = np.linalg.eig(A)
    ref = np.einsum("ok,ki->koi", C @ V, np.linalg.solve(V, B.astype(complex)))
    # pair each closed-form pole with the nearest dense one; residues agree to round-off
    for p, r in zip(poles, res):
        k = int(np.argmin(np.abs(lam - p)))
        assert abs(lam[k] - p) <= 1e-9 * abs(p)
        assert np.max(np.abs(ref[k] - r)) <= 1e-7 * np.max(np.abs(r)) + 1e-12
    # another form (a similarity transform) is not mistaken for it
    T = np.eye(A.shape[0]) + 0.01 * np.tri(A.shape[0], k=-1)
    assert est._second_order_modal(np.linalg.solve(T, A @ T), np.linalg.solve(T, B), C @ T) is None


def test_far_pole_series_matches_the_grid_it_replaces(satellite_ss, monkeypatch):
    data = sc.measure(()).data
    settings, _ = est.experiment_view(data.experiment, data.meta)
    fast = est.expected_h1_measured(satellite_ss, data.f_hz, settings)
    monkeypatch.setattr(est, "_FAR_POLE", np.inf)
    monkeypatch.setattr(est, "_second_order_modal", lambda A, B, C: None)
    slow = est.expected_h1_measured(satellite_ss, data.f_hz, settings)
    assert np.max(np.abs(fast - slow)) <= 1e-11 * np.max(np.abs(slow))
    # and the view differs from the plain FRF by the leakage it models (the check can fail)
    g = sc.truth_frf(data.f_hz)
    assert np.max(np.abs(fast - g)) > 1e-3 * np.max(np.abs(g))
