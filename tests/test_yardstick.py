"""D-K on the Caltech truss and the measurement-model yardstick (robustctl.robust.yardstick)."""

from __future__ import annotations

import control
import numpy as np
import pytest

from robustctl.errors import SynthesisError
from robustctl.lti import as_statespace, freqresp_array


def caltech_recipe(nominal, level: float = 1.0):
    """The yardstick's recipe: level 1 asks for more than robust performance allows, which
    separates the models."""
    from robustctl.examples import caltech_design_plant

    return caltech_design_plant(nominal, level=level)


@pytest.fixture(scope="module")
def caltech():
    from robustctl.examples import caltech_truss, caltech_truss_experiment

    data, truth = caltech_truss_experiment(seed=0)
    return data, truth, caltech_truss()


@pytest.mark.slow
def test_dk_on_the_caltech_truss_certifies_robust_stability_and_stabilises_the_truth(caltech):
    from robustctl.robust.dk import dksyn
    from robustctl.robust.mu import mu

    data, truth, model = caltech
    gp = caltech_recipe(model, level=0.3)   # robust performance reachable (mu ~ 0.8)
    dk = dksyn(gp, max_iter=2, progress=False)
    ub = gp.uncertainty_blocks
    H = freqresp_array(dk.closed_loop, dk.mu.f_hz)[:, :ub.n_out, :ub.n_in]
    rs = mu(H, ub, f_hz=dk.mu.f_hz)
    assert rs.peak < 1.0                                  # robust stability certified
    assert dk.mu_peak < dk.history[0].mu_peak             # D-K improved robust performance
    cl = control.feedback(as_statespace(truth), dk.K, sign=1)   # u = K y, y = G u
    assert np.all(np.linalg.eigvals(cl.A).real < 0)


def test_yardstick_refuses_bad_input(caltech):
    from robustctl.robust.yardstick import yardstick

    data, _, model = caltech
    with pytest.raises(SynthesisError, match="at least two"):
        yardstick(data, {"nominal": model}, caltech_recipe)
    with pytest.raises(SynthesisError, match="recipe"):
        yardstick(data, {"a": model, "b": model}, "not callable")
    with pytest.raises(SynthesisError, match="reference"):
        yardstick(data, {"a": model, "b": model}, caltech_recipe, reference="c")


@pytest.mark.slow
def test_yardstick_scores_each_controller_on_the_data(caltech):
    """MACE's yardstick on the demo's hidden-effect data: one design per model, scored on the
    measured FRFs; the Nyquist verdict on the data agrees with the closed loop on the truth."""
    from robustctl.correlate import update
    from robustctl.identify import fit_measurement_model
    from robustctl.physical.effects import GroupTension
    from robustctl.robust.yardstick import yardstick

    data, truth, model = caltech
    mm = fit_measurement_model(data, n_modes=6, band=(0.5, 5.5), correct_leakage=True)
    upd = update(model.with_effect(GroupTension("longerons_story_1", tension=5.0)), data, band=(0.5, 50),
                 progress=False)
    yard = yardstick(data, {"nominal": model, "updated": upd.model, "measurement": mm}, caltech_recipe,
                     band=(0.5, 5.5), max_iter=2, progress=False)
    assert yard.reference == "measurement" and yard.gap_db("measurement") == 0.0
    for lab in yard.labels:
        on_truth = control.feedback(as_statespace(truth), yard.designs[lab].K, sign=1)
        assert yard.stability[lab].stable is bool(np.all(np.linalg.eigvals(on_truth.A).real < 0))
        assert yard.attenuation_db[lab] > 3.0
        assert yard.mu_cross[yard.labels.index(lab)].min() > 0
    # the score is the loop closed on the data: recompute one by hand
    K = yard.designs["measurement"].K
    band = (data.f_hz >= 0.5) & (data.f_hz <= 5.5)
    G = data.response[band]
    T = np.linalg.solve(np.eye(3)[None] - G @ freqresp_array(K, data.f_hz[band]), G)
    rms = lambda X: np.sqrt(np.mean(np.sum(np.abs(X) ** 2, axis=(1, 2))))  # noqa: E731
    assert yard.attenuation_db["measurement"] == pytest.approx(20 * np.log10(rms(G) / rms(T)), rel=1e-9)
    i = yard.labels.index("measurement")
    assert yard.mu_cross[i, i] == pytest.approx(yard.designs["measurement"].mu_peak, rel=0.02)
    assert "gap (dB)" in str(yard.table()) and "measurement" in yard.summary()
    assert yard.plot() is not None
