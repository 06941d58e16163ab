"""rc.verify (MACE model verification): the same physical change applied to the updated
model must keep its accuracy on the perturbed structure's data."""

from __future__ import annotations

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.verification import apply_perturbation, verify

F = np.linspace(0.5, 15.0, 500)
NOM = dict(k1=1000.0, k2=1000.0, k3=1000.0, m1=1.0, m2=1.0, m3=1.0, c=0.4)


def chain3(**values) -> rc.PhysicalModel:
    """Ground-k1-m1-k2-m2-k3-m3, forces f1..f3 in, displacements x1..x3 out."""
    vals = {**NOM, **values}
    params = [rc.Parameter(n, x, bounds=(0.0, np.inf)) for n, x in vals.items()]

    def dynamics(th, _struct):
        k = [th["k1"], th["k2"], th["k3"]]
        K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
        Mi = np.diag([1 / th["m1"], 1 / th["m2"], 1 / th["m3"]])
        A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ K, -th["c"] * Mi]])
        B = np.vstack([np.zeros((3, 3)), Mi])
        Cy = np.hstack([np.eye(3), np.zeros((3, 3))])
        return control.ss(A, B, Cy, np.zeros((3, 3)), inputs=["f1", "f2", "f3"], outputs=["x1", "x2", "x3"])

    return rc.PhysicalModel(params=params, dynamics=dynamics, name="3-dof chain")


class AddMassTo3:
    """An Effect-like perturbation: ``.name`` and ``.apply(model)``."""

    name = "0.6 kg added to mass 3"

    def apply(self, model):
        return model.with_values(m3=model.param("m3").value + 0.6)


def test_correct_update_holds_under_added_mass():
    truth = chain3(k2=1100.0)
    nominal, perturbed = truth.freqresp(F), truth.with_values(m3=1.6).freqresp(F)
    updated = chain3(k2=1100.0)
    ver = verify(updated, perturbed, AddMassTo3(), reference_data=nominal)
    assert ver.holds and ver.perturbation == "0.6 kg added to mass 3"
    assert ver.max_freq_error_pct < 0.2  # peak-picking resolution of the data
    tab = ver.table()
    assert len(tab.rows) == 3
    # predicted and measured shifts of the first mode agree (it drops ~13 %)
    m = ver.modes[0]
    assert m.shift_model_pct == pytest.approx(m.shift_data_pct, abs=0.3)
    assert m.shift_model_pct < -10
    assert "holds" in ver.summary() and "<table>" in ver._repr_html_()


def test_compensating_wrong_parameters_fail_verification():
    """Stiffness and damping x1.1 with a sensor gain x1.1 give exactly the FRFs of masses / 1.1: the
    nominal data cannot tell them apart, an added mass can (MACE's reason to verify)."""
    truth = chain3(k1=1100.0, k2=1100.0, k3=1100.0, c=0.44)
    nominal = truth.freqresp(F)
    nominal = nominal.replace(response=1.1 * nominal.response)
    perturbed = truth.with_values(m3=1.6).freqresp(F)
    perturbed = perturbed.replace(response=1.1 * perturbed.response)
    wrong = chain3(m1=1 / 1.1, m2=1 / 1.1, m3=1 / 1.1)
    assert rc.compare(wrong, nominal).cost_per_point < 1e-20
    ver = verify(wrong, perturbed, AddMassTo3(), reference_data=nominal)
    assert not ver.holds
    assert ver.cost_ratio > 1e6
    assert "accuracy lost" in ver.reasons[0]
    assert "does NOT hold" in ver.table().title


def test_perturbation_kinds_and_frequency_criterion():
    truth = chain3(k2=1100.0)
    perturbed = truth.with_values(m3=1.6).freqresp(F)
    # dict overrides and a callable give the same perturbed model
    a = verify(chain3(k2=1100.0), perturbed, {"m3": 1.6})
    b = verify(chain3(k2=1100.0), perturbed, lambda m: m.with_values(m3=1.6))
    assert a.cost_per_point == pytest.approx(b.cost_per_point)
    assert np.isnan(a.cost_ratio) and a.holds
    # a model 5 % too stiff everywhere fails the 4 % frequency criterion (MACE's 0-g claim)
    stiff = chain3(k1=1100.0 * 1.1, k2=1100.0 * 1.1, k3=1100.0 * 1.1)
    c = verify(stiff, perturbed, {"m3": 1.6})
    assert not c.holds and c.max_freq_error_pct > 4.0


def test_real_added_mass_effect_on_structural_model():
    K = 1e3 * np.array([[2.0, -1.0], [-1.0, 1.0]])
    p = [rc.Parameter("k", 1.0, bounds=(0.1, 10.0))]
    model = rc.structural_model(
        np.eye(2),
        lambda th: th["k"] * K,
        inputs={"F": "dof 2"},
        outputs={"x2": ("dof 2", "displacement"), "x1": ("dof 1", "displacement")},
        params=p,
    )
    effect = rc.effects.AddedMass("dof 2", mass=0.3)
    f = np.linspace(1.0, 15.0, 400)
    perturbed = effect.apply(model.with_values(k=1.05)).freqresp(f)
    good = verify(
        model.with_values(k=1.05), perturbed, effect, reference_data=model.with_values(k=1.05).freqresp(f)
    )
    bad = verify(model, perturbed, effect)
    assert good.holds and good.perturbation.startswith("added mass")
    assert bad.max_freq_error_pct > good.max_freq_error_pct


def test_verify_bad_input():
    m = chain3()
    data = m.freqresp(F)
    with pytest.raises(rc.ModelError, match=r"cannot apply a perturbation of type int"):
        verify(m, data, 3)
    with pytest.raises(rc.ModelError, match=r"unknown parameter 'm9'"):
        verify(m, data, {"m9": 1.0})
    with pytest.raises(rc.ModelError, match=r"dict is empty"):
        apply_perturbation(m, {})
    with pytest.raises(rc.DataError, match=r"holds 0 data point"):
        verify(m, data, {"m3": 1.2}, band=(40.0, 50.0))
    # a NaN or negative tolerance used to make every check fail silently ("accuracy lost")
    for kw in (dict(cost_ratio_tol=float("nan")), dict(freq_tol_pct=-4.0), dict(cost_floor=-1.0)):
        with pytest.raises(rc.DataError, match=next(iter(kw))):
            verify(m, data, {"m3": 1.2}, **kw)
