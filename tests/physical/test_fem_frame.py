"""Frame assembly: beam frequencies against Euler-Bernoulli theory, supports, rigid links,
massless-DOF condensation, inputs/outputs, strain gauges, without(), and input validation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from robustctl.errors import ModelError
from robustctl.physical.eigen import solve_modes
from robustctl.physical.fem import Frame
from robustctl.physical.structure_base import StructuralMatrices, Structure

E, G, RHO = 7.0e10, 2.7e10, 2700.0
R_OUT = 0.01
A = np.pi * R_OUT**2
I = np.pi * R_OUT**4 / 4
J = 2 * I
L = 1.0
PROPS = dict(E=E, G=G, rho=RHO, A=A, Iy=I, Iz=I, J=J)
CANTILEVER_BL = np.array([1.875104069, 4.694091133, 7.854757438])
FREE_FREE_BL = np.array([4.730040745, 7.853204624, 10.99560784])


def euler_bernoulli_hz(beta_l):
    return beta_l**2 / (2 * np.pi * L**2) * np.sqrt(E * I / (RHO * A))


def beam_frame(clamped: bool, n_elements: int = 10, axis=(1.0, 0.0, 0.0)) -> Frame:
    fr = Frame()
    fr.add_node("root", (0, 0, 0))
    fr.add_node("tip", tuple(L * np.asarray(axis)))
    fr.add_beam("beam", "root", "tip", n_elements=n_elements, **PROPS)
    if clamped:
        fr.fix("root")
    return fr


# ---------------------------------------------------------------- Euler-Bernoulli checks
@pytest.mark.parametrize("sparse", [False, True])
@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 0, 1), (0.6, -0.48, 0.64)])
def test_cantilever_first_three_bending_frequencies(sparse, axis):
    f, _ = beam_frame(True, axis=axis).modes(n_modes=6, sparse=sparse)
    # circular section: each bending frequency appears twice (two planes)
    assert np.allclose(f[0::2], f[1::2], rtol=1e-8)
    assert np.max(np.abs(f[0::2] / euler_bernoulli_hz(CANTILEVER_BL) - 1)) < 0.005


@pytest.mark.parametrize("sparse", [False, True])
def test_free_free_beam_six_rigid_modes_and_bending(sparse):
    f, phi = beam_frame(False).modes(n_modes=12, sparse=sparse)
    assert np.all(f[:6] < 1e-3)
    assert f[6] > 10.0
    assert np.max(np.abs(f[6:12:2] / euler_bernoulli_hz(FREE_FREE_BL) - 1)) < 0.005
    m = beam_frame(False).matrices()
    assert np.allclose(phi.T @ m.mass @ phi, np.eye(12), atol=1e-8)


def test_cantilever_torsion_and_axial_frequencies():
    fr = beam_frame(True)
    f, phi = fr.modes()
    m = fr.matrices()
    labels = np.array(m.dof_labels)
    rx = np.char.endswith(labels, " rx")
    ux = np.char.endswith(labels, " ux")
    # identify the modes by where their kinetic energy lives
    energy_rx = np.einsum("ij,ij->j", phi[rx], (m.mass @ phi)[rx])
    energy_ux = np.einsum("ij,ij->j", phi[ux], (m.mass @ phi)[ux])
    f_torsion = f[np.flatnonzero(energy_rx > 0.9)[0]]
    f_axial = f[np.flatnonzero(energy_ux > 0.9)[0]]
    assert np.isclose(f_torsion, np.sqrt(G * J / (RHO * 2 * I)) / (4 * L), rtol=0.005)
    assert np.isclose(f_axial, np.sqrt(E / RHO) / (4 * L), rtol=0.005)


def test_matrices_dense_by_default_sparse_on_request_and_contract_fields():
    fr = beam_frame(True)
    fr.add_force_input("F", "tip", "z")
    fr.add_output("a", "tip", "z")
    m = fr.matrices()
    assert isinstance(m, StructuralMatrices) and isinstance(fr, Structure)
    assert isinstance(m.stiffness, np.ndarray) and m.n_dof == 60
    ms = fr.matrices(sparse=True)
    assert sp.issparse(ms.stiffness) and np.allclose(ms.stiffness.toarray(), m.stiffness)
    assert m.inputs == ("F",) and m.outputs == ("a",) and m.output_kinds == ("acceleration",)
    assert m.dof_labels[0] == "tip ux" or m.dof_labels[0].endswith("ux")
    fr.scale_modal_damping(1.0, 5.0, 2.0)
    assert fr.matrices().modal_damping_bands == ((1.0, 5.0, 2.0),)


# ---------------------------------------------------------------- statics and I/O
def _static(m: StructuralMatrices) -> np.ndarray:
    """Static gain output/input = C K^-1 B."""
    return m.output_matrix @ np.linalg.solve(np.asarray(m.stiffness), m.input_matrix)


def test_tip_force_static_deflection_rotation_and_root_strain():
    P = 1.0
    fr = beam_frame(True)
    fr.add_force_input("F", "tip", "z")
    fr.add_output("w", "tip", "z", kind="displacement")
    fr.add_output("ry", "tip", "ry", kind="displacement")
    fr.add_strain_output("root_strain", "beam", kind="bending_y", position=0.0, fiber=R_OUT)
    fr.add_strain_output("axial", "beam[3]", kind="axial")
    g = _static(fr.matrices())[:, 0]
    assert np.isclose(g[0], P * L**3 / (3 * E * I), rtol=1e-9)
    assert np.isclose(g[1], -P * L**2 / (2 * E * I), rtol=1e-9)  # ry = -dw/dx
    # a load towards +z bends the beam concave-up (w'' > 0): the +z fiber at the root is in
    # compression, strain = -M c / (E I) with M = P L
    assert np.isclose(g[2], -P * L * R_OUT / (E * I), rtol=1e-9)
    assert abs(g[3]) < 1e-12


@pytest.mark.parametrize("position", [0.25, 0.5, 0.83])
def test_strain_along_a_subdivided_member_in_both_planes(position):
    """Tip loads along y and z: strain -c M(x)/(E I) with M = P (L - x) at x = position L."""
    fr = beam_frame(True, axis=(0, 0, 1))  # a vertical member: default orient is global X
    fr.add_force_input("Fx", "tip", "x")
    fr.add_force_input("Fy", "tip", "y")
    # local axes of a vertical member: x = +Z, z = component of global X -> +X, y = z cross x
    fr.add_strain_output("bz", "beam", kind="bending_z", position=position, fiber=R_OUT)
    fr.add_strain_output("by", "beam", kind="bending_y", position=position, fiber=R_OUT)
    g = _static(fr.matrices())
    expected = -R_OUT * (L - position * L) / (E * I)
    ey = np.cross([1.0, 0, 0], [0, 0, 1.0])  # local y in global axes: (0, -1, 0)
    assert np.isclose(g[1, 0], expected, rtol=1e-9)  # load along local z bends about y
    assert np.isclose(g[0, 1], expected * ey[1], rtol=1e-9)  # load along global y = -local y
    assert abs(g[0, 0]) < 1e-15 and abs(g[1, 1]) < 1e-15


def test_axial_strain_output_and_pair_input():
    fr = beam_frame(True)
    fr.add_pair_input("coil", "root", "tip")
    fr.add_force_input("Fx", "tip", (2.0, 0.0, 0.0))  # a 3-vector is normalised to unit force
    fr.add_strain_output("eps", "beam", kind="axial", position=0.5)
    fr.add_output("x", "tip", "x", kind="displacement")
    g = _static(fr.matrices())
    # the pair input pushes the tip away from the clamped root: +1 N on the tip
    assert np.isclose(g[0, 0], 1.0 / (E * A), rtol=1e-9)
    assert np.isclose(g[1, 1], L / (E * A), rtol=1e-9)
    assert np.isclose(g[1, 0], g[1, 1])


def test_torque_input_and_relative_output():
    fr = beam_frame(True)
    fr.add_force_input("T", "tip", "rx", kind="torque")
    fr.add_output("twist", "tip", "rx", kind="displacement")
    fr.add_relative_output("dz", "root", "tip", "z")
    g = _static(fr.matrices())
    assert np.isclose(g[0, 0], L / (G * J), rtol=1e-9)
    assert abs(g[1, 0]) < 1e-15


def test_rigid_link_transmits_motion():
    """An offset slave reads the master's translation plus theta x r, and a link between
    coincident nodes makes two beams behave as one."""
    fr = beam_frame(True)
    fr.add_node("arm", (L, 0.0, 0.2))
    fr.add_rigid_link("tip", "arm")
    fr.add_force_input("F", "tip", "z")
    fr.add_output("arm_x", "arm", "x", kind="displacement")
    fr.add_output("tip_ry", "tip", "ry", kind="displacement")
    fr.add_output("arm_z", "arm", "z", kind="displacement")
    fr.add_output("tip_z", "tip", "z", kind="displacement")
    g = _static(fr.matrices())[:, 0]
    assert np.isclose(g[0], 0.2 * g[1])  # u_arm = u_tip + ry * 0.2 along x
    assert np.isclose(g[2], g[3])
    # split beam joined by a link at coincident nodes == continuous beam
    split = Frame()
    split.add_node("root", (0, 0, 0))
    split.add_node("mid_a", (0.5, 0, 0))
    split.add_node("mid_b", (0.5, 0, 0))
    split.add_node("tip", (1.0, 0, 0))
    split.add_beam("a", "root", "mid_a", n_elements=5, **PROPS)
    split.add_beam("b", "mid_b", "tip", n_elements=5, **PROPS)
    split.add_rigid_link("mid_a", "mid_b")
    split.fix("root")
    f_split, _ = split.modes(n_modes=8)
    f_one, _ = beam_frame(True).modes(n_modes=8)
    assert np.allclose(f_split, f_one, rtol=1e-9)


def test_rigid_link_offset_mass_equals_parallel_axis_inertia():
    """A point mass m on a link at distance h from the tip of a clamped beam, compared with
    the 6x6 rigid-body mass it puts on the tip (m at the tip, m h^2 about the tip)."""
    m, h = 2.0, 0.3
    linked = beam_frame(True)
    linked.add_node("bob", (L, 0, h))
    linked.add_rigid_link("tip", "bob")
    linked.add_mass("bob", m)
    M = linked.matrices().mass
    plain = beam_frame(True)
    plain.add_mass("tip", m, inertia=(m * h**2, m * h**2, 0.0))
    M0 = plain.matrices().mass
    D = M - M0
    labels = linked.matrices().dof_labels
    i = {lab: k for k, lab in enumerate(labels)}
    # remaining differences are the coupling terms m h between translation and rotation
    assert np.isclose(D[i["tip ux"], i["tip ry"]], m * h)
    assert np.isclose(D[i["tip uy"], i["tip rx"]], -m * h)
    D[i["tip ux"], i["tip ry"]] = D[i["tip ry"], i["tip ux"]] = 0
    D[i["tip uy"], i["tip rx"]] = D[i["tip rx"], i["tip uy"]] = 0
    assert np.abs(D).max() < 1e-12


def massless_chain(k1: float, k2: float, m: float) -> Frame:
    """ground --k1-- n (no mass) --k2-- body (m), motion along z."""
    fr = Frame()
    fr.add_node("n", (0, 0, 0))
    fr.add_node("body", (0, 0, 1.0))
    fr.add_spring("n", k1, "z")
    fr.add_spring("n", k2, "z", node2="body")
    fr.add_mass("body", m)
    fr.fix("body", ["x", "y"])
    return fr


def test_massless_node_is_condensed_and_its_signals_still_work():
    """One mode sqrt(k1 k2/(k1+k2)/m); a sensor on the massless node reads k2/(k1+k2) of
    the body's motion (statically: the force on the body over k1); a force on the massless
    node reaches the body through the springs."""
    k1, k2, m = 4.0e4, 1.0e4, 2.0
    fr = massless_chain(k1, k2, m)
    fr.add_force_input("F_n", "n", "z")
    fr.add_force_input("F_b", "body", "z")
    fr.add_output("z_b", "body", "z", kind="displacement")
    mats = fr.matrices()
    assert mats.n_dof == 1 and mats.dof_labels == ("body uz",)
    f, _ = fr.modes()
    k_series = k1 * k2 / (k1 + k2)
    assert np.isclose(f[0], np.sqrt(k_series / m) / (2 * np.pi))
    assert np.allclose(_static(mats), [[1 / k1, 1 / k_series]])
    sparse = fr.matrices(sparse=True)  # a 1-DOF sparse model goes through solve_modes too
    w, _ = solve_modes(sparse.mass, sparse.stiffness)
    assert np.isclose(w[0], 2 * np.pi * f[0])
    sensed = massless_chain(k1, k2, m)
    sensed.add_force_input("F_b", "body", "z")
    sensed.add_output("z_n", "n", "z", kind="displacement")
    sensed.add_output("a_n", "n", "z", kind="acceleration")
    ms = sensed.matrices()
    assert np.allclose(_static(ms), [[1 / k1], [1 / k1]])
    assert np.allclose(ms.output_matrix, k2 / (k1 + k2))


def test_input_and_output_on_the_same_massless_dof_is_refused():
    fr = massless_chain(4.0e4, 1.0e4, 2.0)
    fr.add_force_input("F_n", "n", "z")
    fr.add_output("z_n", "n", "z", kind="displacement")
    with pytest.raises(ModelError, match="both act on DOFs without mass"):
        fr.matrices()


def test_massless_dof_without_stiffness_support_is_an_error():
    fr = Frame()
    fr.add_node("a", (0, 0, 0))
    fr.add_node("b", (1, 0, 0))
    fr.add_spring("a", 10.0, "x", node2="b")  # floating: no mass anywhere, no support
    fr.add_mass("b", 1.0)
    fr.fix("b")
    fr.add_dashpot("a", 1.0, "x")
    with pytest.raises(ModelError, match="no mass"):
        fr.matrices()


def test_rotations_of_rod_only_nodes_are_removed_and_signals_there_refused():
    fr = Frame()
    fr.add_node("a", (0, 0, 0))
    fr.add_node("b", (1, 0, 0))
    fr.add_rod("r", "a", "b", E=E, rho=RHO, A=A)
    fr.fix("a")
    fr.add_spring("b", 1e3, "y")
    fr.add_spring("b", 1e3, "z")
    assert fr.matrices().n_dof == 3
    fr.add_output("rot", "b", "rz", kind="displacement")
    with pytest.raises(ModelError, match="neither mass nor stiffness"):
        fr.matrices()


# ---------------------------------------------------------------- Structure contract
def suspended_frame(with_suspension: bool = True, gravity: bool = True) -> Frame:
    fr = Frame(gravity=9.81 if gravity else None)
    fr.add_node("a", (0, 0, 0))
    fr.add_node("b", (1.0, 0, 0))
    fr.add_beam("bus", "a", "b", n_elements=4, **PROPS)
    fr.add_mass("b", 1.0, inertia=(1e-3, 1e-3, 1e-3))
    if with_suspension:
        for n in ("a", "b"):
            fr.add_node(f"hook_{n}", tuple(fr.node_xyz(n) + [0, 0, 2.0]), tags=("suspension",))
            fr.add_rod("rods", f"hook_{n}", n, E=2e11, rho=7800, A=1e-6, n_elements=3, tags=("suspension",))
            fr.fix(f"hook_{n}")
        fr.add_spring("a", 50.0, "y", tags=("suspension",))
        fr.add_dashpot("a", 2.0, "z", tags=("suspension",))
    fr.add_force_input("F", "b", "z")
    fr.add_output("acc", "b", "z")
    return fr


def test_without_suspension_and_gravity_equals_frame_built_without_them():
    reduced = suspended_frame().without("suspension", "gravity")
    scratch = suspended_frame(with_suspension=False, gravity=False)
    m1, m2 = reduced.matrices(), scratch.matrices()
    assert m1.dof_labels == m2.dof_labels
    for name in ("mass", "stiffness", "damping", "input_matrix", "output_matrix"):
        assert np.allclose(getattr(m1, name), getattr(m2, name), rtol=0, atol=1e-12)
    assert not reduced.gravity_enabled and suspended_frame().gravity_enabled
    assert "hook_a" not in reduced.locations() and "rods" not in reduced.element_groups()
    # the set form used by PhysicalModel works too, and the original is untouched
    assert suspended_frame().without({"suspension"}).matrices().n_dof == m2.n_dof
    full = suspended_frame()
    assert full.matrices().n_dof > m2.n_dof and np.abs(full.matrices().damping).max() > 0


def test_without_gravity_only_keeps_suspension_but_drops_preload():
    fr = suspended_frame().without("gravity")
    assert fr.preload() is None
    assert all(v == 0 for v in fr.axial_forces().values())
    f, _ = fr.modes(n_modes=3)
    assert f[0] < 1e-3  # pendulum modes need the gravity preload


def test_scale_group_stiffness_and_add_mass_spring_via_contract():
    f0, _ = beam_frame(True).modes(n_modes=4)
    fr = beam_frame(True).scale_group_stiffness("beam", 2.0)
    f1, _ = fr.modes(n_modes=4)
    assert np.allclose(f1, f0 * np.sqrt(2.0))
    assert beam_frame(True).locations()[:2] == ("root", "tip")
    assert beam_frame(True).element_groups() == ("beam",)
    fr = beam_frame(True)
    fr.add_mass("tip", 0.5)
    fr.add_spring("tip", 1e3, "y")
    fr.add_dashpot("tip", 3.0, "y")
    m = fr.matrices()
    iy = m.dof_labels.index("tip uy")
    assert np.isclose(m.damping[iy, iy], 3.0)
    assert np.isclose(m.stiffness[iy, iy] - beam_frame(True).matrices().stiffness[iy, iy], 1e3)


def test_group_tension_stiffens_bending():
    f0, _ = beam_frame(True).modes(n_modes=2)
    f1, _ = beam_frame(True).add_group_tension("beam", 500.0).modes(n_modes=2)
    f2, _ = beam_frame(True).add_group_tension("beam", -500.0).modes(n_modes=2)
    assert f1[0] > f0[0] > f2[0]
    assert beam_frame(True).add_group_tension("beam", 500.0).axial_forces()["beam[0]"] == 500.0


def test_springs_between_nodes_along_a_vector():
    fr = Frame()
    fr.add_node("a", (0, 0, 0))
    fr.add_node("b", (1, 0, 0))
    fr.add_mass("a", 1.0)
    fr.add_mass("b", 1.0)
    fr.add_spring("a", 100.0, (1, 1, 0), node2="b")
    fr.add_spring("a", 1e4, "x")
    fr.add_spring("a", 1e4, "y")
    fr.add_spring("a", 1e4, "z")
    fr.add_spring("b", 1e4, "z")
    fr.add_spring("b", 1e4, (1, -1, 0))
    f, _ = fr.modes()
    # body b moves along (1,1,0)/sqrt2 against 100 N/m with a effectively fixed (1e4 springs)
    assert np.isclose(f.min(), np.sqrt(100.0 / 1.0) / (2 * np.pi), rtol=0.02)


# ---------------------------------------------------------------- validation
def test_bad_input_raises_clear_model_errors():
    fr = Frame()
    fr.add_node("a", (0, 0, 0))
    fr.add_node("b", (1, 0, 0))
    with pytest.raises(ModelError, match="duplicate node name 'a'"):
        fr.add_node("a", (2, 0, 0))
    with pytest.raises(ModelError, match="unknown node 'c'.*add_node"):
        fr.add_beam("g", "a", "c", **PROPS)
    fr.add_node("a2", (0, 0, 0))
    with pytest.raises(ModelError, match="zero-length element"):
        fr.add_beam("g", "a", "a2", **PROPS)
    with pytest.raises(ModelError, match="E must be positive"):
        fr.add_beam("g", "a", "b", **{**PROPS, "E": -1.0})
    with pytest.raises(ModelError, match="A must be positive"):
        fr.add_rod("g", "a", "b", E=E, rho=RHO, A=0.0)
    with pytest.raises(ModelError, match="rho must be positive"):
        fr.add_rod("g", "a", "b", E=E, rho=-RHO, A=A)
    with pytest.raises(ModelError, match="mass at 'a' must be positive"):
        fr.add_mass("a", -1.0)
    with pytest.raises(ModelError, match="must not be negative"):
        fr.add_spring("a", -5.0, "x")
    with pytest.raises(ModelError, match="unknown direction 'w'"):
        fr.add_spring("a", 5.0, "w")
    with pytest.raises(ModelError, match="unknown direction"):
        fr.add_output("y", "a", "up")
    with pytest.raises(ModelError, match="unknown DOF 'q'"):
        fr.fix("a", ["x", "q"])
    with pytest.raises(ModelError, match="kind must be one of"):
        fr.add_output("y", "a", "x", kind="jerk")
    with pytest.raises(ModelError, match="does not match kind"):
        fr.add_force_input("u", "a", "rx")
    with pytest.raises(ModelError, match="unknown element group 'nope'"):
        fr.scale_group_stiffness("nope", 2.0)
    with pytest.raises(ModelError, match="parallel to the element axis"):
        fr.add_beam("g", "a", "b", orient=(1, 0, 0), **PROPS)
    with pytest.raises(ModelError, match="inertia"):
        fr.add_mass("a", 1.0, inertia=(1.0, -1.0, 1.0))
    with pytest.raises(ModelError, match="direction vector must not be zero"):
        fr.add_force_input("u", "a", (0, 0, 0))
    fr.add_force_input("u", "a", "x")
    with pytest.raises(ModelError, match="duplicate input name 'u'"):
        fr.add_force_input("u", "b", "x")
    with pytest.raises(ModelError, match="needs a direction"):
        fr.add_spring("a", 1.0)
    with pytest.raises(ModelError, match="no nodes"):
        Frame().matrices()


def test_rigid_link_errors():
    fr = Frame()
    for n, x in (("a", 0.0), ("b", 1.0), ("c", 2.0)):
        fr.add_node(n, (x, 0, 0))
    fr.add_rigid_link("a", "b")
    with pytest.raises(ModelError, match="already the slave"):
        fr.add_rigid_link("c", "b")
    fr.add_rigid_link("b", "a")
    fr.add_mass("a", 1.0)
    with pytest.raises(ModelError, match="loop"):
        fr.matrices()
    fr2 = Frame()
    fr2.add_node("a", (0, 0, 0))
    fr2.add_node("b", (1, 0, 0))
    fr2.add_rigid_link("a", "b")
    fr2.fix("b")
    fr2.add_mass("a", 1.0)
    with pytest.raises(ModelError, match="fix its master 'a'"):
        fr2.matrices()


def test_without_returns_an_independent_copy():
    full = suspended_frame()
    before = full.matrices()
    reduced = full.without("gravity")
    reduced.add_mass("a", 5.0).scale_group_stiffness("bus", 3.0).add_node("extra", (9, 9, 9))
    reduced.add_beam("bus", "a", "extra", **PROPS)
    after = full.matrices()
    assert np.array_equal(before.mass, after.mass) and np.array_equal(before.stiffness, after.stiffness)
    assert "extra" not in full.locations() and len(full.element_names("bus")) == 4
    assert reduced.element_names("bus")[-1] == "bus[4]"
