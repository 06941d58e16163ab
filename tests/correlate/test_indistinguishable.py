"""diagnose says when the band cannot tell candidates apart: candidates whose best
fits are equal within the noise (Vuong's test) and change the residual the same way are one
group, with where their fitted models differ -- computed from their own predictions."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.updating import move_test
from robustctl.physical import effects as fx

FS = 200.0
UPDATE = ("E_aluminium", "m_platform_1", "m_platform_2", "m_offset", "zeta_modal")


def _hold(model):
    return model.add_io_stage(rc.electronics.zero_order_hold_stage(model.inputs, FS))


def _experiment(truth, nperseg: int, n_samples: int, seed: int = 0) -> rc.FrequencyData:
    """One SIMO white-noise experiment per input, 1 % output noise, H1 estimates."""
    ss = truth.statespace()
    exps = []
    for k, name in enumerate(ss.input_labels):
        u, y = rc.simulate_experiment(ss, fs=FS, n_samples=n_samples, seed=seed + k, inputs=[name])
        y = y + np.random.default_rng([seed, k]).standard_normal(y.shape) * 0.01 * y.std(axis=0)
        exps.append(rc.estimate_frf(u, y, FS, nperseg=nperseg, inputs=[name], outputs=list(ss.output_labels)))
    return rc.combine_experiments(exps)


def _stiff_chain(k_ground: float = 30.0) -> rc.PhysicalModel:
    """Three 1-kg masses joined by stiff springs (40 kN/m) on a soft ground spring: the lowest mode
    (0.5 Hz) moves the chain almost rigidly, the internal modes lie at 31.8 and 55 Hz."""
    ki = 4e4 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    k = rc.Parameter("k_ground", k_ground, "N/m", (k_ground / 10, 10 * k_ground), meaning="ground spring")
    return rc.structural_model(
        np.eye(3), lambda th: ki + np.diag([th["k_ground"], 0.0, 0.0]),
        inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"v1": ("dof 1", "velocity"), "v3": ("dof 3", "velocity")},
        damping=0.02, params=[k], name="stiff chain",
    )


def test_grounded_springs_on_a_stiff_chain_are_one_group_below_its_internal_modes():
    chain = _stiff_chain()
    truth = chain.with_effect(fx.SuspensionSpring("dof 3", stiffness=24.0))
    data = _experiment(truth, nperseg=4096, n_samples=65536)
    diag = rc.diagnose(_hold(chain), data, band=(0.3, 5.0), params=())
    group = diag.indistinguishable
    assert group is not None, diag.summary()
    assert set(group.names) == {f"suspension spring at dof {k}" for k in (1, 2, 3)}
    assert all(abs(z) < 2.58 for z in group.z) and min(group.cosine) > 0.99
    # they differ most at the first internal mode (31.8 Hz), found from their own predictions
    f_internal = np.sort(np.abs(np.linalg.eigvals(chain.statespace().A)))[2] / (2 * np.pi)
    assert group.peak_hz == pytest.approx(f_internal, rel=0.03)
    assert "These explain the data equally well in this band" in diag.summary()
    assert f"most at {group.peak_hz:.3g} Hz" in diag.summary()


def test_a_clear_winner_is_reported_alone():
    m3 = np.diag([2.0, 1.0, 0.5])
    kc = 1e3 * np.array([[1.0, -1.0, 0.0], [-1.0, 2.0, -1.0], [0.0, -1.0, 1.0]])
    k = rc.Parameter("k_ground", 4e3, "N/m", (1e3, 1e4), meaning="ground spring of mass 1")
    chain = rc.structural_model(
        m3, lambda th: kc + np.diag([th["k_ground"], 0.0, 0.0]), inputs={"F1": "dof 1", "F3": "dof 3"},
        outputs={"v2": ("dof 2", "velocity"), "v3": ("dof 3", "velocity")}, damping=0.02, params=[k],
    )
    data = _experiment(chain.with_effect(fx.AddedMass("dof 3", mass=0.15)), nperseg=1024, n_samples=32768)
    diag = rc.diagnose(_hold(chain), data, band=(1.0, 40.0))
    assert diag.best is not None and diag.best.location == "dof 3"
    assert diag.best.values["added_mass__dof_3"] == pytest.approx(0.15, rel=0.02)
    assert diag.indistinguishable is None and "equally well" not in diag.summary()


@pytest.mark.slow
def test_caltech_taut_wires_rank_first_below_30_hz_and_their_twin_is_named():
    """Below 30 Hz the local fits left the true taut wires at half their tension, behind stiffer
    diagonals; the full fit of the contenders ranks them first at the true 15 N. Tension along the
    diagonals fits as well within the noise: one group, told apart only at the local modes."""
    model = rc.examples.caltech_truss()
    data, _ = rc.examples.caltech_truss_experiment(seed=0)
    band = (0.5, 29.8)
    by_name = {c.name: c for c in fx.candidates(model, band=band)}
    names = ("stiffness change of diagonals", "taut wires (tension) along diagonals",
             "suspension pendulum at node platform_1", "taut wires (tension) along longerons_story_1")
    diag = rc.diagnose(model, data, [by_name[n] for n in names], band=band, params=UPDATE)
    top = diag.ranking[0]
    assert top.name == "taut wires (tension) along longerons_story_1" and top.significant
    assert top.values["tension__longerons_story_1"] == pytest.approx(15.0, rel=0.02)
    group = diag.indistinguishable
    assert group is not None and group.names[:2] == (top.name, "taut wires (tension) along diagonals")
    assert "stiffness change of diagonals" not in group.names  # the full fits tell it apart
    assert 30.0 < group.differ_lo_hz < 35.0 and 40.0 < group.differ_hi_hz < 46.0
    assert "widen the band or measure there" in diag.summary()


def test_move_test_is_chi_square_in_the_noise_covariance():
    cov = np.array([[4.0, 1.9], [1.9, 1.0]])  # strongly correlated: moves along the ridge are cheap
    t, dof, p = move_test(np.array([2.0, 1.0]), cov)
    assert dof == 2 and t == pytest.approx(np.array([2.0, 1.0]) @ np.linalg.solve(cov, [2.0, 1.0]))
    assert p == pytest.approx(np.exp(-t / 2))  # chi-square(2) survival
    t_across, _, p_across = move_test(np.array([2.0, -1.0]), cov)
    assert t_across > 30 * t and p_across < 1e-6  # the same sizes across the ridge are significant
