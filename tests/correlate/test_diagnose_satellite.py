"""Verdicts of diagnose on the independent satellite (tests/satellite_corpus.py: numpy beams, two
shakers with measured forces, scipy MIMO H1) and on a cheap numpy chain for the seed sweep:

* an effect the candidates cannot express is never *the answer*: the hinge of an array root
  with only point masses to choose from is "incomplete" or "unexplained", and the verdict names
  the array's modes, not a cable;
* an attached resonator (a mode no candidate adds) gets advice pointing at the structure;
* two masses at once are found one after the other (the chain) and the model is within the noise;
* exact truths over many seeds propose nothing (at least 99 %).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import satellite_corpus as sc
import verdict_corpus as vc

import robustctl as rc
from robustctl.physical import effects as fx


@pytest.fixture(scope="module")
def satellite():
    return sc.nominal_model()


@pytest.fixture(scope="module")
def mass_candidates(satellite):
    return [c for c in fx.candidates(satellite) if c.kind == "added_mass"]


def _diagnose(model, data, cands, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.diagnose(model, data, candidates=cands, workers=1, **kw)


def _where_text(diag):
    return " ".join(b.describe() for b in diag.left)


@pytest.mark.slow
def test_a_hinge_without_a_joint_candidate_is_not_answered_by_a_mass(satellite, mass_candidates):
    """The +y array's root hinge (1500 N m/rad about x) with point masses as the only candidates:
    no mass is proposed as the answer; the misfit left is placed on the +y array's modes."""
    diag = _diagnose(satellite, sc.measure(("hinge_1axis",)).data, mass_candidates)
    assert diag.best is None and diag.effects == ()
    assert diag.verdict in ("incomplete", "unexplained"), diag.summary()
    assert diag.dispersion_left > 10.0  # far beyond the noise, with or without the closest mass
    assert "array_py" in _where_text(diag), diag.summary()
    assert "check its cable" not in diag.summary()
    if diag.verdict == "incomplete":
        assert "Closest, incomplete" in diag.summary()
        assert "probably not among the" in diag.summary()


@pytest.mark.slow
def test_an_attached_resonator_is_placed_on_the_structure_not_on_a_cable(satellite, mass_candidates):
    """A 1 kg box on a 12 Hz mount at bus_pmp adds a mode no candidate has: nothing is the answer,
    and the advice names the band around 12 Hz and the modes there instead of a cable."""
    diag = _diagnose(satellite, sc.measure(("resonator",)).data, mass_candidates)
    assert diag.best is None and diag.verdict in ("incomplete", "unexplained"), diag.summary()
    assert diag.channel_verdict == "" and "check its cable" not in diag.summary()
    assert any(b.lo_hz <= 12.5 and b.hi_hz >= 11.5 for b in diag.left), _where_text(diag)


@pytest.mark.slow
def test_two_masses_at_once_are_chained_to_both(satellite, mass_candidates):
    """0.15 kg more at the boom tip and a 0.25 kg harness at bus_mmp: the chain names both, each
    within 10 % of its size, and the model with both is within the noise."""
    diag = _diagnose(satellite, sc.measure(("harness", "tip_mass")).data, mass_candidates)
    assert diag.verdict == "answer", diag.summary()
    found = {e.location: next(iter(e.values.values())) for e in diag.effects}
    assert set(found) == {"boom_3", "bus_mmp"}, diag.summary()
    assert found["boom_3"] == pytest.approx(sc.TIP_MASS, rel=0.1)
    assert found["bus_mmp"] == pytest.approx(sc.HARNESS[1], rel=0.1)
    assert diag.dispersion_left < 1.5
    assert len(diag.chain) == 2 and "2 effects at once" in diag.summary()
    # one step alone is honest about it: significant, but not the answer
    single = _diagnose(satellite, sc.measure(("harness", "tip_mass")).data, mass_candidates, chain=False)
    assert single.verdict in ("incomplete", "unexplained") and single.best is None, single.summary()
    assert single.lead is not None and single.lead.location in ("boom_3", "bus_mmp")
    assert "chain=True" in single.summary()


@pytest.mark.slow
def test_an_exact_in_library_effect_is_the_answer(satellite, mass_candidates):
    diag = _diagnose(satellite, sc.measure(("tip_mass",)).data, mass_candidates)
    assert diag.verdict == "answer" and diag.best.location == "boom_3", diag.summary()
    assert next(iter(diag.best.values.values())) == pytest.approx(sc.TIP_MASS, rel=0.1)
    assert len(diag.chain) == 1 and diag.dispersion_left < 1.5
    assert "within the noise" in diag.summary()


F_CHAIN = np.arange(2.0, 40.0, 0.25)


@pytest.mark.slow
def test_exact_truths_over_many_seeds_propose_nothing():
    """100 seeds of the exact 4-mass chain (periodic H1, 5 % noise) with every default candidate:
    nothing proposed in at least 99 of them, and every verdict without a proposal says so."""
    model = vc.chain_model()
    cands = fx.candidates(model)
    M, K, B, C, kinds = vc.chain_matrices()
    g = vc.modal_frf(M, K, B, C, kinds, F_CHAIN)
    proposed, words = 0, set()
    for seed in range(100):
        data = vc.periodic_h1(g, n_avg=32, noise=0.05, seed=1000 + seed, inputs=model.inputs,
                              outputs=model.outputs, f_hz=F_CHAIN)
        diag = _diagnose(model, data, cands)
        proposed += diag.best is not None or diag.closest is not None  # an answer, or a closest one
        words.add(diag.verdict)
    assert proposed <= 1
    assert "within the noise" in words and words <= {"within the noise", "answer", "incomplete"}


# ---------------------------------------------------------------------------- fast numpy chains
F_FAST = np.arange(2.0, 40.0, 0.125)


def _chain_h1(model, seed=5, **truth):
    M, K, B, C, kinds = vc.chain_matrices(s_k=1.03, **truth)
    g = vc.modal_frf(M, K, B, C, kinds, F_FAST)
    return vc.periodic_h1(g, n_avg=32, noise=0.05, seed=seed, inputs=model.inputs, outputs=model.outputs,
                          f_hz=F_FAST)


def test_two_masses_on_a_chain_are_chained_and_one_step_says_incomplete():
    model = vc.chain_model()
    cands = fx.calibrate(model, [fx.AddedMass(f"dof {k}") for k in (1, 2, 3, 4)])
    data = _chain_h1(model, added={2: 0.12, 4: 0.06})
    diag = _diagnose(model, data, cands)
    assert diag.verdict == "answer", diag.summary()
    found = {e.location: next(iter(e.values.values())) for e in diag.effects}
    assert set(found) == {"dof 2", "dof 4"}, diag.summary()
    assert found["dof 2"] == pytest.approx(0.12, rel=0.15) and found["dof 4"] == pytest.approx(0.06, rel=0.15)
    assert diag.dispersion_left < 1.5 and len(diag.chain) == 2
    assert {n for e in diag.effects for n in e.param_names} <= set(diag.with_effects(model).param_names)
    single = _diagnose(model, data, cands, chain=False)
    assert single.best is None and single.verdict in ("incomplete", "unexplained"), single.summary()
    assert "chain=True" in single.summary()
    with pytest.raises(rc.RobustctlError, match="no effect is the answer"):
        single.with_effects(model)


def test_a_spring_explained_by_masses_only_is_never_the_answer():
    """A grounded spring at dof 3 with point masses as the only candidates: a mass may soak up part of
    it, but the verdict is not "answer" and the misfit left is placed at the chain's modes."""
    model = vc.chain_model()
    cands = fx.calibrate(model, [fx.AddedMass(f"dof {k}") for k in (1, 2, 3, 4)])
    diag = _diagnose(model, _chain_h1(model, spring={3: 3e3}), cands)
    assert diag.best is None and diag.verdict in ("incomplete", "unexplained"), diag.summary()
    assert diag.left and all(b.modes for b in diag.left[:1])
    assert "check its cable" not in diag.summary()
    with_spring = _diagnose(model, _chain_h1(model, spring={3: 3e3}),
                            cands + fx.calibrate(model, [fx.SuspensionSpring("dof 3")]))
    assert with_spring.verdict == "answer" and with_spring.best.kind == "suspension_spring", \
        with_spring.summary()
