"""Element matrices: symmetry, definiteness, rigid-body invariance and closed-form checks."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from robustctl.errors import ModelError
from robustctl.physical import elements as el

E, G, RHO = 7.0e10, 2.7e10, 2700.0
A, IY, IZ, J = 6e-4, 4.5e-8, 2.0e-8, 5.0e-8


def _random_elements(rng, ne=5):
    x1 = rng.normal(size=(ne, 3))
    x2 = x1 + rng.normal(size=(ne, 3))
    orient = rng.normal(size=(ne, 3))
    return x1, x2, orient


def _global_beam(x1, x2, orient):
    R = el.beam_axes(x1, x2, orient)
    L = np.linalg.norm(x2 - x1, axis=1)
    ones = np.ones_like(L)
    K = el.beam_to_global(
        el.beam_local_stiffness(L, E * ones, G * ones, A * ones, IY * ones, IZ * ones, J * ones), R
    )
    M = el.beam_to_global(el.beam_local_mass(L, RHO * ones, A * ones, IY * ones, IZ * ones), R)
    Mr = el.beam_to_global(
        el.beam_local_mass(L, RHO * ones, A * ones, IY * ones, IZ * ones, rotary_inertia=True), R
    )
    Kg = el.beam_to_global(el.beam_local_geometric(L), R)
    return K, M, Mr, Kg, L


def _rigid_modes(x1, x2):
    """Six rigid-body displacement fields (12-vectors) of a two-node element."""
    modes = []
    for i in range(3):
        t = np.zeros(12)
        t[[i, 6 + i]] = 1.0
        modes.append(t)
    for i in range(3):
        w = np.eye(3)[i]
        r = np.zeros(12)
        r[0:3], r[3:6] = np.cross(w, x1), w
        r[6:9], r[9:12] = np.cross(w, x2), w
        modes.append(r)
    return np.array(modes).T


def test_beam_axes_are_orthonormal_right_handed_and_respect_orient():
    rng = np.random.default_rng(0)
    x1, x2, orient = _random_elements(rng)
    R = el.beam_axes(x1, x2, orient)
    for k in range(len(R)):
        assert np.allclose(R[k] @ R[k].T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(R[k]), 1.0)
        e = (x2[k] - x1[k]) / np.linalg.norm(x2[k] - x1[k])
        assert np.allclose(R[k, 0], e)
        assert abs(R[k, 1] @ orient[k]) < 1e-12  # orient lies in the local x-z plane


def test_beam_matrices_symmetric_and_definite():
    rng = np.random.default_rng(1)
    K, M, Mr, Kg, _ = _global_beam(*_random_elements(rng))
    for stack in (K, M, Mr, Kg):
        assert np.allclose(stack, np.transpose(stack, (0, 2, 1)), atol=1e-9 * np.abs(stack).max())
    for k in range(len(K)):
        lam = np.linalg.eigvalsh(K[k])
        assert np.sum(np.abs(lam) < 1e-9 * lam.max()) == 6  # exactly the six rigid-body modes
        assert lam.min() > -1e-9 * lam.max()
        assert np.linalg.eigvalsh(M[k]).min() > 0
        assert np.linalg.eigvalsh(Mr[k]).min() > 0


def test_rigid_body_motion_gives_zero_elastic_force_and_exact_kinetic_energy():
    rng = np.random.default_rng(2)
    x1, x2, orient = _random_elements(rng)
    K, M, _, Kg, L = _global_beam(x1, x2, orient)
    for k in range(len(K)):
        rb = _rigid_modes(x1[k], x2[k])
        assert np.abs(K[k] @ rb).max() < 1e-9 * np.abs(K[k]).max()
        # a rigid translation has kinetic energy of the whole element mass rho A L
        t = rb[:, 0]
        assert np.isclose(t @ M[k] @ t, RHO * A * L[k], rtol=1e-12)
        # geometric stiffness: no work in a rigid translation
        assert np.abs(Kg[k] @ rb[:, :3]).max() < 1e-12 * np.abs(Kg[k]).max()


def test_rod_matrices_symmetric_rigid_invariant_and_transverse_only_geometric_stiffness():
    rng = np.random.default_rng(3)
    x1, x2, _ = _random_elements(rng, 4)
    K, M, Kg = el.rod_matrices(x1, x2, np.full(4, E), np.full(4, A), np.full(4, RHO))
    _, Ml, _ = el.rod_matrices(x1, x2, np.full(4, E), np.full(4, A), np.full(4, RHO), lumped=np.ones(4, bool))
    for k in range(4):
        rb = _rigid_modes(x1[k], x2[k])
        rb3 = np.concatenate([rb[0:3], rb[6:9]])
        assert np.abs(K[k] @ rb3).max() < 1e-9 * np.abs(K[k]).max()
        for mat in (K[k], M[k], Kg[k], Ml[k]):
            assert np.allclose(mat, mat.T)
        e = (x2[k] - x1[k]) / np.linalg.norm(x2[k] - x1[k])
        stretch = np.concatenate([-e, e])
        L = np.linalg.norm(x2[k] - x1[k])
        assert np.isclose(stretch @ K[k] @ stretch, 4 * E * A / L)
        assert abs(stretch @ Kg[k] @ stretch) < 1e-12  # tension does not stiffen stretching
        assert np.isclose(np.sum(M[k][:3, :3] + M[k][:3, 3:]), 3 * RHO * A * L / 2)
        assert np.allclose(Ml[k], np.eye(6) * RHO * A * L / 2)


@pytest.mark.parametrize("plane", ["v", "w"])
def test_cantilever_tip_load_matches_closed_form(plane):
    """One Hermite element is exact for a tip-loaded cantilever: delta = P L^3/(3 E I),
    slope P L^2 / (2 E I), with rz = +dv/dx and ry = -dw/dx."""
    L, P = 1.3, 50.0
    k = el.beam_local_stiffness(np.array([L]), [E], [G], [A], [IY], [IZ], [J])[0]
    free = np.arange(6, 12)
    f = np.zeros(12)
    load, rot, inertia, sign = (7, 11, IZ, 1.0) if plane == "v" else (8, 10, IY, -1.0)
    f[load] = P
    u = np.zeros(12)
    u[free] = np.linalg.solve(k[np.ix_(free, free)], f[free])
    assert np.isclose(u[load], P * L**3 / (3 * E * inertia), rtol=1e-12)
    assert np.isclose(u[rot], sign * P * L**2 / (2 * E * inertia), rtol=1e-12)
    # axial and torsion
    f = np.zeros(12)
    f[6], f[9] = P, P
    u[free] = np.linalg.solve(k[np.ix_(free, free)], f[free])
    assert np.isclose(u[6], P * L / (E * A)) and np.isclose(u[9], P * L / (G * J))


def test_geometric_stiffness_gives_euler_buckling_load():
    """Pinned-pinned column of 8 elements: (K + lambda K_g) has lambda_cr = pi^2 E I / L^2."""
    L, n = 2.0, 8
    Le = np.full(n, L / n)
    k = el.beam_local_stiffness(
        Le, np.full(n, E), np.full(n, G), np.full(n, A), np.full(n, IY), np.full(n, IZ), np.full(n, J)
    )
    g = el.beam_local_geometric(Le)
    dofs = np.array([[1, 5, 7, 11]])  # v and rz of both nodes: bending in x-y (Iz)
    N = 2 * (n + 1)
    K, Kg = np.zeros((N, N)), np.zeros((N, N))
    for e in range(n):
        idx = np.arange(2 * e, 2 * e + 4)
        K[np.ix_(idx, idx)] += k[e][np.ix_(dofs[0], dofs[0])]
        Kg[np.ix_(idx, idx)] += g[e][np.ix_(dofs[0], dofs[0])]
    free = np.setdiff1d(np.arange(N), [0, N - 2])  # v = 0 at both ends, rotations free
    lam = sla.eigh(K[np.ix_(free, free)], Kg[np.ix_(free, free)], eigvals_only=True)
    assert np.isclose(lam.min(), np.pi**2 * E * IZ / L**2, rtol=1e-3)


@pytest.mark.parametrize("plane", ["v", "w"])
def test_curvature_row_reads_a_constant_curvature_field(plane):
    """v = x^2/2 (rz = x) or w = x^2/2 (ry = -x): curvature 1 everywhere on the element."""
    L = 0.7
    u = np.zeros(12)
    if plane == "v":
        u[[7, 11]] = L**2 / 2, L
    else:
        u[[8, 10]] = L**2 / 2, -L
    for xi in (0.0, 0.3, 1.0):
        assert np.isclose(el.hermite_curvature_row(L, xi, plane) @ u, 1.0)


def test_rotary_inertia_adds_the_cross_section_inertia():
    L = np.array([0.5])
    m0 = el.beam_local_mass(L, [RHO], [A], [IY], [IZ])[0]
    m1 = el.beam_local_mass(L, [RHO], [A], [IY], [IZ], rotary_inertia=True)[0]
    # rotating both ends about local z with v = x rz (a rigid rotation) adds rho Iz L
    u = np.zeros(12)
    u[[7, 5, 11]] = L[0], 1.0, 1.0
    assert np.isclose(u @ (m1 - m0) @ u, RHO * IZ * L[0])


def test_element_errors_say_what_is_wrong():
    with pytest.raises(ModelError, match="zero length"):
        el.beam_axes(np.zeros((1, 3)), np.zeros((1, 3)))
    with pytest.raises(ModelError, match="parallel to the element axis"):
        el.beam_axes(np.zeros((1, 3)), np.array([[0, 0, 1.0]]), np.array([[0, 0, 2.0]]))
    with pytest.raises(ModelError, match="zero length"):
        el.rod_matrices(np.ones((1, 3)), np.ones((1, 3)), [E], [A], [RHO])


def test_default_orient_avoids_vertical_members():
    x1 = np.zeros((2, 3))
    x2 = np.array([[0, 0, 1.0], [1.0, 0, 0]])
    R = el.beam_axes(x1, x2)  # no error for a vertical member
    assert np.all(np.isfinite(R))
