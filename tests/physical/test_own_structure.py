"""The user's own structure: rc.frame_model, geometry and mode shapes of frames and matrix models."""

import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import ModelError

E, RHO, A, I_Z, L = 70e9, 2700.0, 1e-4, 1e-9, 1.0


def cantilever(theta, n_el=12):
    fr = rc.Frame(name="cantilever")
    fr.add_node("root", (0.0, 0.0, 0.0))
    fr.add_node("tip", (L, 0.0, 0.0))
    fr.add_beam("beam", "root", "tip", E=theta["E"], G=theta["E"] / 2.6, rho=RHO, A=A, Iy=I_Z, Iz=I_Z,
                J=2 * I_Z, n_elements=n_el)
    fr.fix("root")
    fr.add_force_input("F", "tip", "z")
    fr.add_output("a_tip", "tip", "z")
    return fr


def test_frame_model_has_named_parameters_and_the_euler_bernoulli_frequency():
    model = rc.frame_model(cantilever, [rc.Parameter("E", E, "Pa", bounds=(50e9, 90e9))], band_hz=(0, 200))
    assert model.param_names == ("E", "zeta_modal")
    assert model.inputs == ("F",) and model.outputs == ("a_tip",)
    f1 = 1.8751**2 / (2 * np.pi) * np.sqrt(E * I_Z / (RHO * A * L**4))  # Euler-Bernoulli cantilever
    shapes = model.mode_shapes(n_modes=2)
    assert shapes.f_hz[0] == pytest.approx(f1, rel=1e-3)
    # the first bending shape along the span, against the analytic cantilever shape
    g = model.geometry()
    x = g.xyz[:, 0]
    w = shapes.shapes[0, :, 2]
    b = 1.8751 / L
    sigma = (np.cosh(b * L) + np.cos(b * L)) / (np.sinh(b * L) + np.sin(b * L))
    exact = np.cosh(b * x) - np.cos(b * x) - sigma * (np.sinh(b * x) - np.sin(b * x))
    assert np.allclose(w / w[np.argmax(np.abs(w))], exact / exact[np.argmax(np.abs(exact))], atol=2e-3)
    # a stiffer beam moves the frequency by sqrt(E ratio): the parameter reaches the build
    assert model.mode_shapes(n_modes=1, E=1.21 * E).f_hz[0] == pytest.approx(1.1 * shapes.f_hz[0], rel=1e-9)


def test_frame_geometry_lines_and_sensors():
    g = rc.frame_model(cantilever, [rc.Parameter("E", E, "Pa")]).geometry()
    assert g.n_nodes == 13 and len(g.lines) == 12
    node, direction = g.sensors["a_tip"]
    assert np.allclose(g.xyz[g.index([node])[0]], (L, 0, 0)) and np.allclose(direction, (0, 0, 1))


def test_a_fixed_frame_is_a_model_too_and_matches_its_own_matrices():
    frame = cantilever({"E": E}, n_el=4)
    model = rc.frame_model(frame, damping=0.02)
    sm = frame.matrices()
    ref = rc.structural_model(sm.mass, sm.stiffness, inputs={"F": sm.input_matrix[:, 0]},
                              outputs={"a_tip": (sm.output_matrix[0], "acceleration")}, damping=0.02)
    f = np.array([3.0, 17.0, 60.0])
    assert np.allclose(model.freqresp(f).response, ref.freqresp(f).response, rtol=1e-9)
    assert model.values["zeta_modal"] == 0.02


def test_matrix_model_with_nodes_draws_the_two_mass_chain():
    k, m = 1e4, 1.0
    K = k * np.array([[2.0, -1.0], [-1.0, 1.0]])
    model = rc.structural_model(m * np.eye(2), K, inputs={"F": "2:X"},
                                outputs={"x2": ("2:X", "displacement")},
                                dof_labels=["1:X", "2:X"], nodes={0: (0, 0, 0), 1: (1, 0, 0), 2: (2, 0, 0)},
                                lines=[(0, 1), (1, 2)])
    g = model.geometry()
    assert g.sensors["x2"][0] == 2
    ms = model.mode_shapes()
    # analytic: w^2 = k/m (3 -+ sqrt 5)/2, shape (1, (1 +- sqrt 5)/2)
    lam = k / m * (3 - np.sqrt(5)) / 2
    assert ms.f_hz[0] == pytest.approx(np.sqrt(lam) / (2 * np.pi), rel=1e-12)
    s = ms.shapes[0, :, 0]
    assert s[0] == 0 and s[2] / s[1] == pytest.approx((1 + np.sqrt(5)) / 2, rel=1e-10)


def test_models_without_coordinates_say_how_to_give_them():
    model = rc.structural_model(np.eye(1), np.eye(1), inputs={"F": "dof 1"},
                                outputs={"x": ("dof 1", "displacement")})
    with pytest.raises(ModelError, match="nodes="):
        model.geometry()
    with pytest.raises(ModelError, match="Frame or a function"):
        rc.frame_model(42)
