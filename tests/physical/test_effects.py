"""Physical effects: exact reference responses, neutrality, locations, candidates, bad input."""

import math

import numpy as np
import pytest
import scipy.linalg as sla

import robustctl as rc
from robustctl.physical import effects as fx

F_HZ = np.array([0.3, 1.0, 2.0, 5.0, 12.0, 30.0])
M2 = np.diag([2.0, 1.0])
KG = 1e3 * np.array([[1.0, -1.0], [-1.0, 1.0]])  # spring between the two masses
K2 = 1e3 * np.diag([3.0, 0.0]) + KG
KGEO = np.array([[2.0, -1.0], [-1.0, 1.0]])  # geometric stiffness per newton (1/m)


def _chain(damping=0.0):
    return rc.structural_model(
        M2, K2, inputs={"F": "dof 2"},
        outputs={"x1": ("dof 1", "displacement"), "x2": ("dof 2", "displacement")},
        damping=damping, stiffness_groups={"coupling": KG}, geometric_stiffness={"coupling": KGEO},
        name="2-dof chain",
    )


@pytest.fixture(scope="module")
def chain():
    return _chain()


def _direct_frf(M, K, C, b, f_hz):
    """(K - w^2 M + j w C)^-1 b, shape (nf, n)."""
    return np.array([np.linalg.solve(K - (2 * np.pi * f) ** 2 * M + 2j * np.pi * f * C, b) for f in f_hz])


def _freqs_hz(M, K):
    return np.sort(np.sqrt(np.abs(sla.eigh(K, M, eigvals_only=True)))) / (2 * np.pi)


def _model_freqs_hz(model):
    poles = np.linalg.eigvals(model.statespace().A)
    return np.sort(np.abs(poles[poles.imag > 0])) / (2 * np.pi)


# ---------------------------------------------------------------------------- I/O effects
@pytest.mark.parametrize(
    "effect, ratio",
    [
        (fx.SensorLowPass(order=1, time_constant=2e-3), lambda s: 1 / (1 + s * 2e-3)),
        (fx.SensorLowPass(order=2, time_constant=4e-3, damping=0.4),
         lambda s: 1 / (1 + 2 * 0.4 * s * 4e-3 + (s * 4e-3) ** 2)),
        (fx.ActuatorLowPass(order=1, time_constant=5e-3), lambda s: 1 / (1 + s * 5e-3)),
        (fx.SensorGain("x2", error=0.07), lambda s: 1.07 + 0 * s),
    ],
)
def test_io_effect_multiplies_the_response_by_its_exact_transfer_function(chain, effect, ratio):
    g0 = chain.freqresp(F_HZ).response[:, 1, 0]
    g = chain.with_effect(effect).freqresp(F_HZ).response[:, 1, 0]
    np.testing.assert_allclose(g / g0, ratio(2j * np.pi * F_HZ), rtol=1e-9)


def test_output_delay_is_a_pade_phase_lag_of_omega_tau(chain):
    tau = 3.6e-3
    g0 = chain.freqresp(F_HZ).response
    g = chain.with_effect(fx.OutputDelay(delay=tau)).freqresp(F_HZ).response
    ratio = g / g0
    np.testing.assert_allclose(np.abs(ratio), 1.0, atol=1e-12)  # all-pass
    np.testing.assert_allclose(np.angle(ratio[:, :, 0]), -2 * np.pi * F_HZ[:, None] * tau * np.ones((1, 2)),
                               atol=1e-6)  # Pade order 3 at w tau <= 0.7: error ~(w tau)^7


def test_sensor_misalignment_rotates_the_two_readings(chain):
    a = 0.02
    g0 = chain.freqresp(F_HZ).response[:, :, 0]
    g = chain.with_effect(fx.SensorMisalignment("x1", partner="x2", angle=a)).freqresp(F_HZ).response[:, :, 0]
    R = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    np.testing.assert_allclose(g, g0 @ R.T, rtol=1e-10)


# ---------------------------------------------------------------------------- structural effects
def test_added_mass_and_spring_move_the_eigenfrequencies_to_the_matrix_solution(chain):
    m_mass = chain.with_effect(fx.AddedMass("dof 2", mass=0.3))
    np.testing.assert_allclose(_model_freqs_hz(m_mass), _freqs_hz(M2 + np.diag([0, 0.3]), K2), rtol=1e-9)
    m_spring = chain.with_effect(fx.SuspensionSpring("dof 1", stiffness=500.0))
    np.testing.assert_allclose(_model_freqs_hz(m_spring), _freqs_hz(M2, K2 + np.diag([500.0, 0])), rtol=1e-9)


def test_group_stiffness_and_tension_add_the_group_and_geometric_matrices(chain):
    m = chain.with_effect(fx.GroupStiffness("coupling", change=0.25))
    np.testing.assert_allclose(_model_freqs_hz(m), _freqs_hz(M2, K2 + 0.25 * KG), rtol=1e-9)
    m = chain.with_effect(fx.GroupTension("coupling", tension=40.0))
    np.testing.assert_allclose(_model_freqs_hz(m), _freqs_hz(M2, K2 + 40.0 * KGEO), rtol=1e-9)


def test_dashpot_gives_the_direct_damped_response(chain):
    c = 3.0
    m = chain.with_effect(fx.Dashpot("dof 1", damping=c))  # modal damping is 0: only the dashpot
    g = m.freqresp(F_HZ).response[:, :, 0]
    ref = _direct_frf(M2, K2, np.diag([c, 0.0]), np.array([0.0, 1.0]), F_HZ)
    np.testing.assert_allclose(g, ref, rtol=1e-8)


def test_modal_damping_change_scales_only_the_modes_in_its_band():
    model = _chain(damping=0.02)
    f = _model_freqs_hz(model)
    m = model.with_effect(fx.ModalDamping(lo_hz=0.9 * f[1], hi_hz=1.1 * f[1], change=1.0))
    poles = np.linalg.eigvals(m.statespace().A)
    poles = poles[poles.imag > 0][np.argsort(np.abs(poles[poles.imag > 0]))]
    zeta = -poles.real / np.abs(poles)
    np.testing.assert_allclose(zeta, [0.02, 0.04], rtol=1e-9)


def _zetas(model):
    poles = np.linalg.eigvals(model.statespace().A)
    poles = poles[poles.imag > 0][np.argsort(np.abs(poles[poles.imag > 0]))]
    return -poles.real / np.abs(poles)


def test_modal_damping_by_mode_number_follows_its_mode_where_a_band_loses_it():
    """Twice the coupling stiffness moves mode 2 from 7.74 to 9.66 Hz: a 3 % band at its nominal
    frequency no longer holds it (refused), ``modes=(2, 2)`` still doubles its damping and only its."""
    model = rc.structural_model(M2, lambda th: 1e3 * np.diag([3.0, 0.0]) + th["k"] * KG / 1e3,
                                inputs={"F": "dof 2"}, outputs={"x2": ("dof 2", "displacement")},
                                damping=0.02, params=[rc.Parameter("k", 1e3, "N/m", (1e2, 1e4))])
    f2 = _model_freqs_hz(model)[1]
    stiff = model.with_values(k=2e3)
    assert _model_freqs_hz(stiff)[1] / f2 == pytest.approx(9.6629 / 7.7416, rel=1e-4)
    by_number = fx.ModalDamping(modes=(2, 2), change=1.0)
    assert by_number.location == "mode 2" and by_number.param_names == ("modal_damping_change__modes_2_2",)
    np.testing.assert_allclose(_zetas(stiff.with_effect(by_number)), [0.02, 0.04], rtol=1e-9)
    np.testing.assert_allclose(_zetas(model.with_effect(by_number)), [0.02, 0.04], rtol=1e-9)
    band = fx.ModalDamping(lo_hz=0.97 * f2, hi_hz=1.03 * f2, change=1.0)
    with pytest.raises(rc.ModelError, match="contains no kept mode"):
        stiff.with_effect(band).statespace()
    with pytest.raises(rc.ModelError, match="needs 3 elastic modes"):
        model.with_effect(fx.ModalDamping(modes=(2, 3), change=1.0)).statespace()
    for bad in [(0, 1), (2, 1), (1.5, 2), "12"]:
        with pytest.raises(rc.ModelError, match="first <= last"):
            fx.ModalDamping(modes=bad)
    # the candidates name their groups by mode number: the octave group (4.0 and 7.7 Hz), and
    # each mode alone (10 % apart or more: no close pair)
    cands = [c for c in fx.candidates(model) if c.kind == "modal_damping"]
    assert sorted(c.modes for c in cands) == [(1, 1), (1, 2), (2, 2)]


def test_tension_on_the_caltech_longerons_equals_adding_it_to_the_frame():
    model = rc.examples.caltech_truss(n_elements_per_member=1, diagonals=False)
    with rc.blas_threads(1):
        with_effect = model.with_effect(fx.GroupTension("longerons_story_1", tension=12.0)).build_structure()
        direct = model.build_structure().add_group_tension("longerons_story_1", 12.0)
        np.testing.assert_allclose(with_effect.matrices().stiffness, direct.matrices().stiffness, rtol=1e-12)
        off = model.with_effect(fx.GravityStiffening(enabled=False, switch=1.0)).build_structure()
        assert not off.gravity_enabled
        pend = model.with_effect(fx.Pendulum("platform_2", stiffness=50.0)).build_structure()
        springs = model.build_structure().add_spring("platform_2", 50.0, "x")
        springs = springs.add_spring("platform_2", 50.0, "y")
        np.testing.assert_allclose(pend.matrices().stiffness, springs.matrices().stiffness, rtol=1e-12)


@pytest.mark.parametrize(
    "effect",
    [fx.OutputDelay(), fx.InputDelay(), fx.SensorLowPass(order=2), fx.SensorGain("x1"),
     fx.SensorMisalignment("x1", partner="x2"), fx.AddedMass("dof 1"), fx.SuspensionSpring("dof 2"),
     fx.Dashpot("dof 1"), fx.GroupStiffness("coupling"), fx.GroupTension("coupling"),
     fx.ModalDamping(lo_hz=1.0, hi_hz=100.0)],
)
def test_an_effect_at_its_neutral_value_changes_nothing(chain, effect):
    assert effect.is_neutral
    g0 = chain.freqresp(F_HZ).response
    m = chain.with_effect(effect)
    assert np.array_equal(m.freqresp(F_HZ).response, g0)
    for p in effect.parameters:
        assert p.neutral == p.value and "effect" in p.tags and p.name in m.param_names
        assert p.bounds[0] <= p.neutral <= p.bounds[1] and p.abs_step > 0


# ---------------------------------------------------------------------------- naming, values
def test_names_parameters_and_values_are_plain_and_unique_per_location():
    e = fx.AddedMass("p2 c", mass=0.1)
    assert e.name == "added mass at node p2 c" and e.param_names == ("added_mass__p2_c",)
    assert e.values == {"added_mass__p2_c": 0.1}
    assert e.with_values(added_mass__p2_c=0.2).mass == 0.2 == e.with_values(mass=0.2).mass
    assert fx.AddedMass("dof 3").name == "added mass at dof 3"
    assert fx.OutputDelay().name == "output delay" and fx.OutputDelay().domain == "io"
    assert fx.SuspensionSpring("n1", direction="x").param_names == ("suspension_spring__n1_x",)
    assert "longerons" in fx.GroupTension("longerons_story_1").description
    assert "3.6 ms" in fx.OutputDelay(delay=3.6e-3).describe_value()


def test_without_suspension_drops_a_suspension_spring_effect(chain):
    m = chain.with_effect(fx.SuspensionSpring("dof 1", stiffness=500.0))
    assert "suspension_spring__dof_1" not in m.without("suspension").param_names
    np.testing.assert_allclose(m.without("suspension").freqresp(F_HZ).response, chain.freqresp(F_HZ).response)


# ---------------------------------------------------------------------------- candidates
def test_candidates_span_every_dof_and_group_with_calibrated_steps(chain):
    cands = fx.candidates(chain)
    kinds = {c.kind for c in cands}
    assert {"output_delay", "sensor_lowpass", "sensor_gain", "added_mass", "suspension_spring",
            "dashpot", "group_stiffness", "group_tension", "modal_damping"} <= kinds
    assert "gravity" not in kinds  # the user's matrices have no gravity preload
    assert {c.location for c in cands if c.kind == "added_mass"} == {"dof 1", "dof 2"}
    names = [n for c in cands for n in c.param_names]
    assert len(names) == len(set(names))
    # a calibrated step moves the most affected w^2 by ~SHIFT_TARGET (first order)
    mass = next(c for c in cands if c.kind == "added_mass" and c.location == "dof 2")
    w0 = 2 * np.pi * _freqs_hz(M2, K2)
    w1 = 2 * np.pi * _freqs_hz(M2 + np.diag([0, mass.typical_size]), K2)
    assert np.max(np.abs(w1**2 / w0**2 - 1)) == pytest.approx(fx.SHIFT_TARGET, rel=0.1)


def test_candidates_of_an_io_only_model_are_io_effects():
    model = rc.modal_model([2.0, 5.0], 0.02, [[1.0, 0.5]], [[1.0, -0.3]], inputs=["u"], outputs=["y"])
    cands = fx.candidates(model)
    assert cands and all(c.domain == "io" for c in cands)
    assert [c.kind for c in fx.candidates(model, kinds=["output_delay"])] == ["output_delay"]


def test_candidates_on_the_caltech_truss_name_nodes_and_groups():
    model = rc.examples.caltech_truss(n_elements_per_member=1, diagonals=False)
    cands = fx.candidates(model, band=(0.5, 6.0))
    tension = [c for c in cands if c.kind == "group_tension"]
    assert {c.location for c in tension} == {"longerons_story_1", "longerons_story_2"}
    assert [c.name for c in cands if c.kind == "gravity"] == ["gravity stiffening switched off"]
    assert any(c.kind == "added_mass" and c.location == "platform_2" for c in cands)
    assert any(c.kind == "pendulum" and c.location == "platform_2" for c in cands)  # gravity is on
    # the clamped ceiling nodes carry no point effect, only the support's own flexibility
    ceiling = ("ceiling_1", "ceiling_2", "ceiling_3")
    assert all(c.location not in ceiling for c in cands if c.kind != "support_flexibility")
    assert sorted(c.location for c in cands if c.kind == "support_flexibility") == list(ceiling)


# ---------------------------------------------------------------------------- bad input
def test_structural_effect_on_a_model_without_structure_is_refused():
    model = rc.modal_model([2.0], 0.02, [[1.0]], [[1.0]], inputs=["u"], outputs=["y"])
    with pytest.raises(rc.ModelError, match="no structural description"):
        model.with_effect(fx.AddedMass("dof 1", mass=1.0))


def test_bad_locations_and_values_are_refused_with_the_fix(chain):
    with pytest.raises(rc.ModelError, match="unknown location 'dof 7'.*dof 1"):
        chain.with_effect(fx.AddedMass("dof 7", mass=1.0))
    with pytest.raises(rc.ModelError, match="unknown element group 'bracing'"):
        chain.with_effect(fx.GroupTension("bracing", tension=1.0))
    with pytest.raises(rc.ModelError, match="unknown output 'S9'"):
        chain.with_effect(fx.SensorGain("S9", error=0.1))
    with pytest.raises(rc.ModelError, match="outside the admissible range"):
        fx.AddedMass("dof 1", mass=-1.0)
    with pytest.raises(rc.ModelError, match="two different sensors"):
        chain.with_effect(fx.SensorMisalignment("x1", partner="x1", angle=0.1))
    with pytest.raises(rc.ModelError, match="no gravity preload"):
        chain.with_effect(fx.GravityStiffening(enabled=True, switch=1.0))
    with pytest.raises(rc.ModelError, match="already has parameter"):
        chain.with_effect(fx.OutputDelay(delay=1e-3)).with_effect(fx.OutputDelay(delay=2e-3))
    with pytest.raises(rc.ModelError, match="has no parameter 'weight'"):
        fx.AddedMass("dof 1").with_values(weight=1.0)
    with pytest.raises(rc.ModelError, match="order 1 or 2"):
        fx.SensorLowPass(order=3)
    with pytest.raises(rc.ModelError, match="unknown effect kinds"):
        fx.candidates(chain, kinds=["levitation"])


def test_candidates_at_given_locations_only(chain):
    cands = fx.candidates(chain, locations=["dof 2"])
    assert {c.location for c in cands if c.kind in ("added_mass", "dashpot")} == {"dof 2"}
    with pytest.raises(rc.ModelError, match="unknown location 'dof 5'"):
        fx.candidates(chain, locations=["dof 5"])
    calibrated = fx.calibrate(chain, [fx.AddedMass("dof 1"), fx.OutputDelay()])
    assert calibrated[0].scale is not None and calibrated[1].scale is None


def test_a_stiffness_group_without_geometric_stiffness_gets_no_tension_candidate():
    """A user's matrices name a stiffness group but give no geometric stiffness: the group's
    stiffness change is a candidate, its tension is not (it cannot be built), so the default
    diagnose candidates build; adding the tension by hand says what is missing."""
    model = rc.structural_model(M2, K2, inputs={"F": "dof 2"}, outputs={"x2": ("dof 2", "displacement")},
                                stiffness_groups={"coupling": KG})
    cands = fx.candidates(model)
    assert [c.location for c in cands if c.kind == "group_stiffness"] == ["coupling"]
    assert not [c for c in cands if c.kind == "group_tension"]
    with pytest.raises(rc.ModelError, match="no geometric stiffness"):
        model.with_effect(fx.GroupTension("coupling", tension=1.0))
    # with geometric stiffness (the module's chain) the tension is a candidate
    assert [c.location for c in fx.candidates(_chain()) if c.kind == "group_tension"] == ["coupling"]


def test_calibration_modes_of_a_large_structure_without_a_band_are_the_dense_lowest_elastic_ones():
    """Above REDUCE_MIN_DOF DOFs and without a band, the calibration's modes (the lowest 12 elastic
    ones) come from Lanczos, not a dense eigh (O(n^2) memory: 18 GB at 20,000 DOFs): the same
    frequencies as scipy's dense solution to 1e-9 and the same squared shapes."""
    import scipy.sparse as sp

    from robustctl.physical.effects.catalogue import _modes

    n = 400  # a chain of springs grounded at one end, graded masses
    K = sp.diags([np.full(n, 2e4), np.full(n - 1, -1e4), np.full(n - 1, -1e4)], [0, -1, 1]).tolil()
    K[n - 1, n - 1] = 1e4
    m = 0.1 * (1 + 0.5 * np.linspace(0, 1, n))
    model = rc.structural_model(sp.diags(m).tocsr(), K.tocsr(), inputs={"F": "dof 3"},
                                outputs={"a": ("dof 5", "acceleration")}, damping=0.01)
    omega, phi, _, number = _modes(model, None)
    lam, vec = sla.eigh(K.toarray(), np.diag(m), subset_by_index=(0, 11))
    assert np.allclose(omega, np.sqrt(lam), rtol=1e-9)
    assert np.allclose(phi**2, vec**2, rtol=1e-6, atol=1e-9 * np.max(vec**2))
    assert number.tolist() == list(range(1, 13))
