"""Bring-your-own models: MatrixStructure, structural_model and modal_model."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import ModelError
from robustctl.physical.matrices import MatrixStructure
from robustctl.physical.modal import modal_decomposition, modal_dynamics
from robustctl.physical.model import PhysicalModel, Stage
from robustctl.physical.parameters import Parameter

M_KG, K_NM = 2.0, 8.0e3


def chain_k(n: int = 3, k: float = K_NM) -> np.ndarray:
    """Fixed-free chain: ground - m1 - m2 - ... - mn, equal springs k."""
    K = np.zeros((n, n))
    K[0, 0] = k
    for i in range(1, n):
        K[np.ix_([i - 1, i], [i - 1, i])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return K


def analytic_chain_hz(n: int = 3, m: float = M_KG, k: float = K_NM) -> np.ndarray:
    """omega_j = 2 sqrt(k/m) sin((2j - 1) pi / (2 (2n + 1))) for the fixed-free chain."""
    j = np.arange(1, n + 1)
    return 2 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1))) / (2 * np.pi)


IO = {
    "inputs": {"F3": "dof 3", "F1": [1.0, 0.0, 0.0]},
    "outputs": {
        "x1": ("dof 1", "displacement"),
        "v2": ("dof 2", "velocity"),
        "a3": ("dof 3", "acceleration"),
    },
}


def poles_hz(sys) -> np.ndarray:
    p = np.linalg.eigvals(np.asarray(sys.A))
    return np.sort(np.abs(p[p.imag > 0])) / (2 * np.pi)


def test_structural_model_matches_analytic_chain_frequencies():
    model = rc.structural_model(M_KG * np.eye(3), chain_k(), damping=0.0, **IO)
    assert model.param_names == ("zeta_modal",)
    assert model.inputs == ("F3", "F1") and model.outputs == ("x1", "v2", "a3")
    assert np.allclose(poles_hz(model.statespace()), analytic_chain_hz(), rtol=1e-12)
    d = modal_decomposition(model.build_structure().matrices())
    assert np.allclose(d.f_hz, analytic_chain_hz(), rtol=1e-12)


def test_structural_model_response_with_dashpot_and_damping_parameter():
    cs = np.zeros((3, 3))
    cs[2, 2] = 3.0
    model = rc.structural_model(M_KG * np.eye(3), chain_k(), concentrated_damping=cs, **IO)
    f = np.logspace(0, 2, 60)
    got = model.freqresp(f, zeta_modal=0.03).response
    d = modal_decomposition(model.build_structure().matrices())
    M, K = M_KG * np.eye(3), chain_k()
    C = M @ d.shapes @ np.diag(2 * 0.03 * d.omega) @ d.shapes.T @ M + cs
    b = np.array([[0, 1.0], [0, 0], [1.0, 0]])
    for fk, g in zip(f, got):
        s = 2j * np.pi * fk
        q = np.linalg.solve(K + s * C + s * s * M, b)
        ref = np.array([q[0], s * q[1], s * s * q[2]])
        assert np.allclose(g, ref, rtol=1e-9, atol=0)


def test_callable_matrices_follow_parameters():
    params = [Parameter("k", K_NM, "N/m", bounds=(1.0, 1e6)), Parameter("m", M_KG, "kg", bounds=(0.1, 10))]
    model = rc.structural_model(
        lambda th: th["m"] * np.eye(3), lambda th: chain_k(k=th["k"]), params=params, damping=0.0, **IO
    )
    assert set(model.param_names) == {"k", "m", "zeta_modal"}
    assert np.allclose(poles_hz(model.statespace(k=4 * K_NM)), 2 * analytic_chain_hz(), rtol=1e-12)
    assert np.allclose(poles_hz(model.statespace(m=4 * M_KG)), analytic_chain_hz() / 2, rtol=1e-12)
    assert np.allclose(poles_hz(model.statespace()), analytic_chain_hz(), rtol=1e-12)


def test_per_mode_damping_is_fixed_and_truncation_keeps_lowest_modes():
    model = rc.structural_model(M_KG * np.eye(3), chain_k(), damping=[0.01, 0.02, 0.05], **IO)
    assert model.param_names == ()
    p = np.linalg.eigvals(np.asarray(model.statespace().A))
    p = p[p.imag > 0][np.argsort(np.abs(p[p.imag > 0]))]
    assert np.allclose(-p.real / np.abs(p), [0.01, 0.02, 0.05], rtol=1e-10)
    trunc = rc.structural_model(M_KG * np.eye(3), chain_k(), n_modes=2, **IO)
    assert trunc.statespace().nstates == 4
    assert np.allclose(poles_hz(trunc.statespace()), analytic_chain_hz()[:2], rtol=1e-6)


def test_modal_model_reproduces_the_analytic_modal_sum():
    f_modes = np.array([1.5, 4.0, 11.0])
    zeta = 0.02
    b = np.array([[0.4, -0.3, 0.2], [0.1, 0.5, -0.6]])  # (n_in, n_modes)
    c = np.array([[1.0, 0.7, -0.2]])  # (n_out, n_modes)
    model = rc.modal_model(f_modes, zeta, b, c, inputs=["u1", "u2"], outputs=["acc"])
    assert model.param_names == ("zeta_modal",)
    f = np.logspace(-0.5, 1.5, 80)
    s = 2j * np.pi * f
    w = 2 * np.pi * f_modes
    ref = np.zeros((f.size, 1, 2), complex)
    for k in range(3):
        ref[:, 0, :] += np.outer(s**2 / (s**2 + 2 * zeta * w[k] * s + w[k] ** 2), c[0, k] * b[:, k])
    got = model.freqresp(f).response
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-10
    with pytest.raises(ModelError, match="has no structural description"):
        model.add_structure_stage(Stage("mass", lambda th, st: st))


def test_modal_model_round_trip_equals_structural_model():
    model = rc.structural_model(M_KG * np.eye(3), chain_k(), damping=0.01, **IO)
    mats = model.build_structure().matrices()
    d = modal_decomposition(mats)
    modal = rc.modal_model(
        d.f_hz, [0.01, 0.01, 0.01], d.input_shapes.T, d.output_shapes,
        inputs=model.inputs, outputs=model.outputs, output_kind=mats.output_kinds,
    )
    assert modal.param_names == ("zeta_mode_1", "zeta_mode_2", "zeta_mode_3")
    f = np.logspace(0, 2, 50)
    assert np.allclose(modal.freqresp(f).response, model.freqresp(f).response, rtol=1e-9, atol=0)
    changed = modal.statespace(zeta_mode_2=0.2)
    p = np.linalg.eigvals(np.asarray(changed.A))
    assert np.any(np.isclose(-p.real / np.abs(p), 0.2))


def test_electronics_stage_applies_to_both_kinds_of_model():
    tau = Parameter("tau", 3.6e-3, "s", bounds=(0, 0.1), neutral=0.0)
    stage = rc.electronics.delay_stage("a3", "tau")
    model = rc.structural_model(M_KG * np.eye(3), chain_k(), **IO).add_io_stage(stage, [tau])
    f = np.array([5.0, 20.0])
    base = rc.structural_model(M_KG * np.eye(3), chain_k(), **IO).freqresp(f).response
    got = model.freqresp(f).response
    assert np.allclose(np.abs(got), np.abs(base), rtol=1e-10)
    assert np.allclose(model.freqresp(f, tau=0.0).response, base, rtol=1e-12)


# ------------------------------------------------------------------ MatrixStructure and effects
def test_point_effects_change_the_matrices():
    st = MatrixStructure(M_KG * np.eye(3), chain_k(), **IO)
    st.add_mass("dof 2", 0.5).add_spring("dof 3", 100.0).add_dashpot("dof 1", 2.0)
    mats = st.matrices()
    assert mats.mass[1, 1] == M_KG + 0.5 and mats.stiffness[2, 2] == K_NM + 100.0
    assert mats.damping[0, 0] == 2.0 and mats.dof_labels == ("dof 1", "dof 2", "dof 3")
    assert st.locations() == ("dof 1", "dof 2", "dof 3")


def test_structure_stage_added_mass_matches_generalised_eigenproblem():
    base = rc.structural_model(M_KG * np.eye(3), chain_k(), damping=0.0, **IO)
    stage = Stage("added mass", lambda th, st: st.add_mass("dof 3", th["dm"]), ("effect",))
    model = base.add_structure_stage(stage, [Parameter("dm", 1.0, "kg", bounds=(0, 5), neutral=0.0)])
    M = M_KG * np.eye(3)
    M[2, 2] += 1.0
    ref = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, chain_k())).real)) / (2 * np.pi)
    assert np.allclose(poles_hz(model.statespace()), ref, rtol=1e-12)
    assert np.allclose(poles_hz(model.statespace(dm=0.0)), analytic_chain_hz(), rtol=1e-12)


def test_groups_tension_and_tagged_suspension():
    k_top = np.zeros((3, 3))
    k_top[np.ix_([1, 2], [1, 2])] = K_NM * np.array([[1.0, -1.0], [-1.0, 1.0]])
    k_susp = np.zeros((3, 3))
    k_susp[2, 2] = 500.0
    c_susp = 0.1 * k_susp / 500.0
    kg = k_top / K_NM  # geometric stiffness per newton of tension (1/m)
    model = rc.structural_model(
        M_KG * np.eye(3), chain_k() + k_susp, concentrated_damping=c_susp, damping=0.0,
        stiffness_groups={"spring_2_3": k_top}, geometric_stiffness={"spring_2_3": kg},
        tagged={"suspension": (k_susp, c_susp)}, **IO,
    )
    st = model.build_structure()
    assert st.element_groups() == ("spring_2_3",) and st.tags() == ("suspension",)
    stiffer = st.scale_group_stiffness("spring_2_3", 2.0).matrices().stiffness
    assert np.allclose(stiffer, chain_k() + k_susp + k_top)
    tensioned = model.build_structure().add_group_tension("spring_2_3", 300.0).matrices().stiffness
    assert np.allclose(tensioned, chain_k() + k_susp + 300.0 * kg)
    zero_g = model.without("suspension", "gravity")
    assert np.allclose(poles_hz(zero_g.statespace()), analytic_chain_hz(), rtol=1e-12)
    mats = zero_g.build_structure().matrices()
    assert np.allclose(mats.damping, 0.0) and np.allclose(mats.stiffness, chain_k())


def test_damping_change_reuses_the_eigensolution(monkeypatch):
    import robustctl.physical.modal as modal

    calls = []
    real = modal.solve_modes

    def counting(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(modal, "solve_modes", counting)
    model = rc.structural_model(M_KG * np.eye(3), chain_k(), **IO)
    a, b = model.statespace(zeta_modal=0.02), model.statespace(zeta_modal=0.05)
    assert len(calls) == 1 and not np.allclose(np.asarray(a.A), np.asarray(b.A))
    p = np.linalg.eigvals(np.asarray(b.A))
    assert np.allclose(-p.real / np.abs(p), 0.05)
    changed = rc.structural_model(M_KG * np.eye(3), 2 * chain_k(), **IO)
    assert np.allclose(poles_hz(changed.statespace()), np.sqrt(2) * analytic_chain_hz(), rtol=1e-3)
    assert len(calls) == 2  # different matrices: solved again


def test_modal_dynamics_without_damping_parameter_uses_default():
    st = MatrixStructure(M_KG * np.eye(3), chain_k(), **IO)
    model = PhysicalModel((), modal_dynamics(default_damping=0.05), structure=lambda th: st)
    p = np.linalg.eigvals(np.asarray(model.statespace().A))
    assert np.allclose(-p.real / np.abs(p), 0.05)


# ------------------------------------------------------------------ bad input
def _bad(**changes):
    args = {"mass": M_KG * np.eye(3), "stiffness": chain_k(), **IO}
    args.update(changes)
    return lambda: rc.structural_model(args.pop("mass"), args.pop("stiffness"), **args)


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (_bad(mass=np.array([[1.0, 0.2, 0], [0, 1, 0], [0, 0, 1]])), "mass matrix is not symmetric"),
        (_bad(mass=np.diag([1.0, 0.0, 1.0])), "mass matrix is singular"),
        (_bad(mass=np.diag([1.0, -1.0, 1.0])), "negative diagonal entry at 'dof 2'"),
        (_bad(stiffness=-chain_k()), "negative diagonal entry"),
        (_bad(stiffness=chain_k() - 3e3 * np.eye(3)), "not positive semi-definite"),
        (_bad(stiffness=np.eye(2)), "model has 3 DOFs"),
        (_bad(inputs={"F": [1.0, 0.0]}), "has 2 entries; it needs one finite entry per DOF"),
        (_bad(inputs={"F": "dof 9"}), "unknown location 'dof 9'"),
        (_bad(inputs={}), "at least one input"),
        (_bad(outputs={"x": ("dof 1", "strain")}), "kind one of"),
        (_bad(outputs={"x": [0, 0, 1.0]}), "must be \\(vector or DOF label, kind\\)"),
        (_bad(band_hz=(100.0, 200.0)), "no mode lies in the band"),
        (_bad(damping=1.5), "damping ratio must lie in \\[0, 1\\)"),
        (_bad(dof_labels=("a", "b")), "dof_labels must be 3 unique names"),
        (_bad(geometric_stiffness={"g": np.eye(3)}), "not a stiffness group"),
        (_bad(tagged={"s": (np.eye(3),) * 4}), "must be \\(dK,\\), \\(dK, dC\\) or \\(dK, dC, dM\\)"),
        (lambda: rc.modal_model([1.0, 2.0], 0.01, [[1.0, 2.0, 3.0]], [[1.0, 1.0]], inputs=["u"],
                                outputs=["y"]), "shapes_at_inputs has shape \\(1, 3\\)"),
        (lambda: rc.modal_model([1.0, -2.0], 0.01, [[1.0, 2.0]], [[1.0, 1.0]], inputs=["u"],
                                outputs=["y"]), "finite frequencies >= 0 Hz"),
        (lambda: rc.modal_model([1.0, 2.0], 0.01, [[1.0, 2.0]], [[1.0, 1.0]], inputs=["u", "v"],
                                outputs=["y"]), "give 1 unique input names"),
        (lambda: rc.modal_model([1.0, 2.0], [0.01], [[1.0, 2.0]], [[1.0, 1.0]], inputs=["u"],
                                outputs=["y"]), "1 values for 2 kept modes"),
    ],
)
def test_bad_input_raises_clear_model_error(build, match):
    with pytest.raises(ModelError, match=match):
        build()


def test_bad_effects_on_matrix_structure():
    st = MatrixStructure(M_KG * np.eye(3), chain_k(), stiffness_groups={"g": chain_k()}, **IO)
    with pytest.raises(ModelError, match="unknown element group 'h'"):
        st.scale_group_stiffness("h", 2.0)
    with pytest.raises(ModelError, match="tension is not applicable"):
        st.add_group_tension("g", 10.0)
    with pytest.raises(ModelError, match="takes direction=None"):
        st.add_spring("dof 1", 10.0, direction="z")
    with pytest.raises(ModelError, match="unknown location 'node 4'"):
        st.add_mass("node 4", 1.0)
    with pytest.raises(ModelError, match="finite and >= 0"):
        st.scale_group_stiffness("g", -1.0)
    bare = MatrixStructure(M_KG * np.eye(3), chain_k(), tagged={"s": (None, np.eye(3))}, **IO)
    with pytest.raises(ModelError, match="no concentrated damping to remove it from"):
        bare.without(["s"])


def test_build_may_read_optional_parameters_with_get():
    """theta.get(name, default) inside a build: absent -> default, present -> recorded for the cache."""
    import control

    def dynamics(theta, structure):
        return control.ss([], [], [], [[theta.get("k", 0.0) + theta.get("dropped", 10.0)]])

    model = PhysicalModel((Parameter("k", 1.0, "1", (0.0, 5.0), meaning="a gain"),), dynamics)
    assert float(model.statespace().D[0, 0]) == 11.0
    assert float(model.statespace(k=3.0).D[0, 0]) == 13.0  # k was read: not served from the cache


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rel_step": float("nan")}, "rel_step must be a finite number > 0"),
        ({"rel_step": "a gain"}, "rel_step must be a finite number > 0"),
        ({"abs_step": float("inf")}, "abs_step a finite number >= 0"),
    ],
)
def test_parameter_refuses_bad_steps(kwargs, match):
    # a NaN rel_step gave NaN finite-difference steps
    with pytest.raises(ModelError, match=match):
        Parameter("k", 1.0, **kwargs)


def test_parameter_takes_one_tag_as_a_bare_string():
    # tags="gravity" became one tag per letter
    assert Parameter("g", 9.81, tags="gravity").tags == ("gravity",)


def test_constant_matrices_are_validated_once_and_builds_stay_independent(monkeypatch):
    import robustctl.physical.matrices as matrices

    calls = []
    real = matrices._check_definite
    monkeypatch.setattr(matrices, "_check_definite", lambda *a: (calls.append(1), real(*a))[1])
    base = rc.structural_model(M_KG * np.eye(3), chain_k(), **IO)
    dm = Parameter("dm", 0.0, "kg", (0.0, 10.0), meaning="added mass")
    model = base.add_structure_stage(Stage("mass", lambda th, s: s.add_mass("dof 1", th["dm"])), [dm])
    heavy = poles_hz(model.statespace(dm=5.0))
    again = poles_hz(model.statespace(dm=0.0, zeta_modal=0.02))  # the added mass must not leak
    assert np.allclose(again, analytic_chain_hz(), rtol=1e-6) and heavy[0] < again[0]
    assert len(calls) == 1
