"""Independent cross-check of the frame FEM against pyfe3d (a dev-only dependency).

The same 3-D frame -- rectangular members (Iy != Iz, so the element orientation matters),
lumped masses, clamped feet -- is built with robustctl's :class:`Frame` and with pyfe3d's
``BeamC`` (a Timoshenko element with consistent mass and rotary inertia). With the gravity
preload, pyfe3d takes one linear static step ``K u = M a_g`` and forms its ``KG`` from the
element displacements; robustctl's ``max_gravity_iterations=1`` is the same procedure.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.sparse import coo_matrix

from robustctl.physical import elements as el
from robustctl.physical.fem import Frame

pyfe3d = pytest.importorskip("pyfe3d")
from pyfe3d import DOF, INT, BeamC, BeamCData, BeamCProbe  # noqa: E402
from pyfe3d.beamprop import BeamProp  # noqa: E402

E, G, RHO = 7.0e10, 2.7e10, 2700.0
B, H = 0.02, 0.03
A = B * H
IY = B * H**3 / 12  # about local y: bending in the local x-z plane
IZ = H * B**3 / 12
J = H * B**3 * (1 / 3 - 0.21 * B / H * (1 - B**4 / (12 * H**4)))
NODES = {
    "a0": (0, 0, 0), "b0": (2, 0, 0), "c0": (2, 1.5, 0), "d0": (0, 1.5, 0),
    "a1": (0, 0, 2.5), "b1": (2, 0, 2.5), "c1": (2, 1.5, 2.5), "d1": (0, 1.5, 2.5),
}  # fmt: skip
MEMBERS = [
    ("column", "a0", "a1"), ("column", "b0", "b1"), ("column", "c0", "c1"), ("column", "d0", "d1"),
    ("girder", "a1", "b1"), ("girder", "b1", "c1"), ("girder", "c1", "d1"), ("girder", "d1", "a1"),
    ("brace", "a0", "b1"), ("brace", "b1", "d1"),
]  # fmt: skip


def robustctl_frame(gravity: bool) -> Frame:
    fr = Frame(gravity=9.81 if gravity else None, max_gravity_iterations=1)
    for name, xyz in NODES.items():
        fr.add_node(name, xyz)
    for group, n1, n2 in MEMBERS:
        fr.add_beam(
            group, n1, n2, E=E, G=G, rho=RHO, A=A, Iy=IY, Iz=IZ, J=J, n_elements=4, rotary_inertia=True
        )
    fr.add_mass("c1", 50.0)
    fr.add_mass("a1", 30.0)
    for n in ("a0", "b0", "c0", "d0"):
        fr.fix(n)
    return fr


def pyfe3d_frequencies(fr: Frame, gravity: bool, shear_modulus: float, n: int = 10) -> np.ndarray:
    """First ``n`` frequencies (Hz) of the same mesh built with pyfe3d's BeamC."""
    names = list(fr._nodes)
    idx = {name: i for i, name in enumerate(names)}
    X = np.array([fr._nodes[name].xyz for name in names])
    x = X.ravel().copy()
    n_dof, ne, data, probe = DOF * len(names), len(fr._elements), BeamCData(), BeamCProbe()
    Kr, Kc, Kv = np.zeros(144 * ne, INT), np.zeros(144 * ne, INT), np.zeros(144 * ne)
    Mr, Mc, Mv = np.zeros(144 * ne, INT), np.zeros(144 * ne, INT), np.zeros(144 * ne)
    Gr, Gc, Gv = np.zeros(144 * ne, INT), np.zeros(144 * ne, INT), np.zeros(144 * ne)
    prop = BeamProp()
    prop.A, prop.E, prop.G, prop.Iyy, prop.Izz, prop.J = A, E, G, IY, IZ, J
    prop.G12 = prop.G13 = shear_modulus
    prop.GJ = G * J
    prop.intrho, prop.intrhoy2, prop.intrhoz2 = RHO * A, RHO * IZ, RHO * IY
    beams = []
    for k, e in enumerate(fr._elements.values()):
        be = BeamC(probe)
        be.n1, be.n2 = idx[e.n1], idx[e.n2]
        be.c1, be.c2 = DOF * idx[e.n1], DOF * idx[e.n2]
        # pyfe3d takes a vector in the element x-y plane: robustctl's local y axis
        R = el.beam_axes(X[idx[e.n1]][None], X[idx[e.n2]][None])[0]
        be.update_rotation_matrix(*R[1], x)
        be.update_probe_xe(x)
        be.init_k_KC0 = be.init_k_M = be.init_k_KG = k * data.KC0_SPARSE_SIZE
        be.update_KC0(Kr, Kc, Kv, prop)
        be.update_M(Mr, Mc, Mv, prop, 0)
        beams.append(be)
    K = coo_matrix((Kv, (Kr, Kc)), shape=(n_dof, n_dof)).toarray()
    M = coo_matrix((Mv, (Mr, Mc)), shape=(n_dof, n_dof)).toarray()
    for m in fr._masses:
        i = DOF * idx[m.node]
        M[i : i + 3, i : i + 3] += m.mass * np.eye(3)
    free = np.ones(n_dof, bool)
    for f in fr._fixes:
        free[DOF * idx[f.node] + np.array(f.dofs)] = False
    Kff = K[np.ix_(free, free)]
    if gravity:
        accel = np.zeros(n_dof)
        accel[2::6] = -9.81
        u = np.zeros(n_dof)
        u[free] = np.linalg.solve(Kff, (M @ accel)[free])
        for be in beams:
            be.update_probe_ue(u)
            be.update_KG(Gr, Gc, Gv, prop)
        Kff = Kff + coo_matrix((Gv, (Gr, Gc)), shape=(n_dof, n_dof)).toarray()[np.ix_(free, free)]
    lam = sla.eigh(Kff, M[np.ix_(free, free)], eigvals_only=True, subset_by_index=[0, n - 1])
    return np.sqrt(lam) / (2 * np.pi)


@pytest.mark.parametrize("gravity", [False, True])
def test_first_ten_frequencies_match_pyfe3d_slender_timoshenko(gravity):
    fr = robustctl_frame(gravity)
    f_ours, _ = fr.modes(n_modes=10)
    f_ref = pyfe3d_frequencies(fr, gravity, shear_modulus=G)
    assert np.max(np.abs(f_ours / f_ref - 1)) < 1e-3


@pytest.mark.parametrize("gravity", [False, True])
def test_frequencies_match_pyfe3d_to_rounding_without_shear_flexibility(gravity):
    """With a huge transverse shear modulus pyfe3d's element is Euler-Bernoulli (Rayleigh
    mass): the two codes then agree to rounding, geometric stiffness included."""
    fr = robustctl_frame(gravity)
    f_ours, _ = fr.modes(n_modes=10)
    f_ref = pyfe3d_frequencies(fr, gravity, shear_modulus=1e6 * E)
    assert np.max(np.abs(f_ours / f_ref - 1)) < 1e-6


def test_gravity_preload_changes_the_frequencies_it_is_checked_on():
    """Guard: the preload case must not be trivially equal to the unloaded one."""
    f0, _ = robustctl_frame(False).modes(n_modes=3)
    f1, _ = robustctl_frame(True).modes(n_modes=3)
    assert np.max(np.abs(f1 / f0 - 1)) > 0.01
