"""Element matrices of the frame FEM, vectorised over many elements at once.

Two elements:

* the 3-D Euler-Bernoulli frame element (2 nodes, 12 DOFs ``[u v w rx ry rz]`` per node in
  element axes): axial, Saint-Venant torsion and bending in the two principal planes, with
  consistent mass (optionally with the rotary inertia of the cross-section, a Rayleigh
  beam) and the geometric (stress) stiffness of a constant axial force ``N``
  (Przemieniecki, *Theory of Matrix Structural Analysis*, 1968, eqs. 5.116, 11.34, 15.31;
  Cook et al., *Concepts and Applications of FEA*, 4th ed., sec. 18.3);
* the rod (truss) element (2 nodes, 3 translations each, in global axes): axial stiffness,
  consistent or lumped mass, and the geometric stiffness ``N/L (I - e e^T)`` that makes a
  tensioned rod a pendulum suspension or a vibrating string (Cook et al., eq. 18.3-6).

Every function takes arrays of shape ``(ne,)`` (one value per element) and returns
stacks of matrices ``(ne, 12, 12)`` or ``(ne, 6, 6)``. Units are SI: m, Pa, kg/m^3, N.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError

__all__ = [
    "beam_axes",
    "default_orient",
    "beam_local_stiffness",
    "beam_local_mass",
    "beam_local_geometric",
    "beam_to_global",
    "rod_matrices",
    "hermite_curvature_row",
]

# Bending blocks for the DOFs (v1, theta1, v2, theta2) with theta = dv/dx. Entry (i, j) is
# coefficient * L**power; the power counts the rotation DOFs among (i, j).
_POWER = np.array([[0, 1, 0, 1], [1, 2, 1, 2], [0, 1, 0, 1], [1, 2, 1, 2]])
_K_BEND = np.array([[12, 6, -12, 6], [6, 4, -6, 2], [-12, -6, 12, -6], [6, 2, -6, 4]], float)
_M_BEND = np.array([[156, 22, 54, -13], [22, 4, 13, -3], [54, 13, 156, -22], [-13, -3, -22, 4]], float)
_G_BEND = np.array([[36, 3, -36, 3], [3, 4, -3, -1], [-36, -3, 36, -3], [3, -1, -3, 4]], float)
_AXIAL = np.array([[1.0, -1.0], [-1.0, 1.0]])
_AXIAL_MASS = np.array([[2.0, 1.0], [1.0, 2.0]])

# Element-axis DOF indices of the two bending planes. In the x-y plane rz = +dv/dx; in the
# x-z plane ry = -dw/dx, hence the sign flip S = diag(1, -1, 1, -1) on that block.
_V_PLANE = np.array([1, 5, 7, 11])
_W_PLANE = np.array([2, 4, 8, 10])
_W_SIGN = np.array([1.0, -1.0, 1.0, -1.0])


def _bending(L: np.ndarray, coeff: np.ndarray) -> np.ndarray:
    """Stack ``coeff * L**power`` over elements, shape (ne, 4, 4)."""
    return coeff[None] * L[:, None, None] ** _POWER[None]


def _place_bending(out: np.ndarray, block_v: np.ndarray, block_w: np.ndarray) -> None:
    out[:, _V_PLANE[:, None], _V_PLANE[None, :]] += block_v
    out[:, _W_PLANE[:, None], _W_PLANE[None, :]] += block_w * np.outer(_W_SIGN, _W_SIGN)[None]


def _place_pair(out: np.ndarray, i: int, block: np.ndarray) -> None:
    """Add a 2x2-per-element block on DOF ``i`` of node 1 and node 2."""
    idx = np.array([i, i + 6])
    out[:, idx[:, None], idx[None, :]] += block


def default_orient(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """A vector for the element x-z plane: global Z, or global X for near-vertical elements.

    Parameters
    ----------
    x1, x2 : ndarray, shape (ne, 3)
        End coordinates in m.

    Returns
    -------
    ndarray, shape (ne, 3)
    """
    e = (x2 - x1) / np.linalg.norm(x2 - x1, axis=1, keepdims=True)
    orient = np.tile([0.0, 0.0, 1.0], (len(e), 1))
    vertical = np.abs(e[:, 2]) > 0.9
    orient[vertical] = [1.0, 0.0, 0.0]
    return orient


def beam_axes(x1: np.ndarray, x2: np.ndarray, orient: np.ndarray | None = None) -> np.ndarray:
    """Direction cosines of the element axes.

    Local x runs from node 1 to node 2; local z is the part of ``orient`` normal to x (so
    ``orient`` lies in the local x-z plane); local y = z cross x completes a right-handed set.

    Parameters
    ----------
    x1, x2 : ndarray, shape (ne, 3)
        End coordinates in m.
    orient : ndarray, shape (ne, 3), optional
        Orientation vectors (global axes); :func:`default_orient` when omitted.

    Returns
    -------
    R : ndarray, shape (ne, 3, 3)
        Rows are the local x, y, z unit vectors in global axes, so ``u_local = R @ u_global``.
    """
    d = np.asarray(x2, float) - np.asarray(x1, float)
    L = np.linalg.norm(d, axis=1)
    if np.any(L <= 0):
        raise ModelError("an element has zero length: its two nodes coincide; move one node.")
    ex = d / L[:, None]
    if orient is None:
        orient = default_orient(x1, x2)
    orient = np.asarray(orient, float)
    z = orient - np.sum(orient * ex, axis=1, keepdims=True) * ex
    nz = np.linalg.norm(z, axis=1)
    bad = nz <= 1e-6 * np.maximum(np.linalg.norm(orient, axis=1), 1e-300)
    if np.any(bad):
        raise ModelError(
            f"the orientation vector {orient[bad][0].tolist()} is parallel to the element axis "
            f"{ex[bad][0].tolist()}; give orient= a vector that is not along the member."
        )
    ez = z / nz[:, None]
    ey = np.cross(ez, ex)
    return np.stack([ex, ey, ez], axis=1)


def beam_local_stiffness(L, E, G, A, Iy, Iz, J) -> np.ndarray:
    """Elastic stiffness of the Euler-Bernoulli frame element in element axes.

    Parameters
    ----------
    L : array (ne,)  length, m
    E, G : array (ne,)  Young's and shear moduli, Pa
    A : array (ne,)  area, m^2
    Iy, Iz : array (ne,)  second moments about local y (bending in x-z) and z (x-y), m^4
    J : array (ne,)  torsion constant, m^4

    Returns
    -------
    ndarray (ne, 12, 12) in N/m, N, N m/rad (Przemieniecki eq. 5.116).
    """
    L, E, G, A, Iy, Iz, J = (np.asarray(a, float) for a in (L, E, G, A, Iy, Iz, J))
    k = np.zeros((L.size, 12, 12))
    _place_pair(k, 0, (E * A / L)[:, None, None] * _AXIAL)
    _place_pair(k, 3, (G * J / L)[:, None, None] * _AXIAL)
    kb = _bending(L, _K_BEND) / L[:, None, None] ** 3
    _place_bending(k, (E * Iz)[:, None, None] * kb, (E * Iy)[:, None, None] * kb)
    return k


def beam_local_mass(L, rho, A, Iy, Iz, *, rotary_inertia: bool = False) -> np.ndarray:
    """Consistent mass of the frame element in element axes (kg, kg m, kg m^2).

    Translations use the cubic Hermite shape functions (``rho A L / 420`` matrix,
    Przemieniecki eq. 11.34); axial motion and torsion the linear ones with the polar
    moment ``Iy + Iz``. With ``rotary_inertia`` the cross-section's rotary inertia
    ``rho I / (30 L) [36 3L ...]`` is added to the bending blocks (Rayleigh beam).
    """
    L, rho, A, Iy, Iz = (np.asarray(a, float) for a in (L, rho, A, Iy, Iz))
    m = np.zeros((L.size, 12, 12))
    _place_pair(m, 0, (rho * A * L / 6)[:, None, None] * _AXIAL_MASS)
    _place_pair(m, 3, (rho * (Iy + Iz) * L / 6)[:, None, None] * _AXIAL_MASS)
    mb = (rho * A * L / 420)[:, None, None] * _bending(L, _M_BEND)
    _place_bending(m, mb, mb)
    if rotary_inertia:
        g = _bending(L, _G_BEND) / (30 * L)[:, None, None]
        _place_bending(m, (rho * Iz)[:, None, None] * g, (rho * Iy)[:, None, None] * g)
    return m


def beam_local_geometric(L) -> np.ndarray:
    """Geometric stiffness of the frame element per newton of axial tension (element axes).

    ``K_g = N/(30 L) [36 3L -36 3L; 3L 4L^2 -3L -L^2; ...]`` in both bending planes, the
    Hessian of ``1/2 int N (v'^2 + w'^2) dx`` with cubic shape functions (Cook et al.
    eq. 18.3-7). Multiply by the axial force ``N`` in N (tension positive).
    """
    L = np.asarray(L, float)
    kg = np.zeros((L.size, 12, 12))
    g = _bending(L, _G_BEND) / (30 * L)[:, None, None]
    _place_bending(kg, g, g)
    return kg


def beam_to_global(mat_local: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Rotate element-axis matrices to global axes: ``T^T k T`` with ``T = diag(R, R, R, R)``."""
    ne = mat_local.shape[0]
    k = mat_local.reshape(ne, 4, 3, 4, 3)
    out = np.einsum("epi,eapbq,eqj->eaibj", R, k, R, optimize=True)
    return out.reshape(ne, 12, 12)


def rod_matrices(x1, x2, E, A, rho, *, lumped=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stiffness, mass and unit geometric stiffness of rod elements in global axes.

    Parameters
    ----------
    x1, x2 : array (ne, 3)  end coordinates, m
    E : array (ne,)  Young's modulus, Pa
    A : array (ne,)  area, m^2
    rho : array (ne,)  density, kg/m^3
    lumped : array of bool (ne,), optional
        Lumped (half the mass at each end) instead of consistent mass.

    Returns
    -------
    K, M, Kg1 : ndarray (ne, 6, 6)
        DOFs ``[ux1 uy1 uz1 ux2 uy2 uz2]``. ``K = EA/L [e e^T]``; consistent
        ``M = rho A L/6 [2I I; I 2I]`` (lumped ``rho A L/2 I``) -- the rod's mass moves with
        all three translations; ``Kg1 = 1/L [P -P; -P P]`` with ``P = I - e e^T`` is the
        geometric stiffness per newton of tension.
    """
    d = np.asarray(x2, float) - np.asarray(x1, float)
    L = np.linalg.norm(d, axis=1)
    if np.any(L <= 0):
        raise ModelError("a rod has zero length: its two nodes coincide; move one node.")
    e = d / L[:, None]
    eet = e[:, :, None] * e[:, None, :]
    K = np.kron(_AXIAL, np.ones((3, 3)))[None] * np.tile(eet, (1, 2, 2))
    K *= (np.asarray(E, float) * np.asarray(A, float) / L)[:, None, None]
    P = np.eye(3)[None] - eet
    Kg1 = np.kron(_AXIAL, np.ones((3, 3)))[None] * np.tile(P, (1, 2, 2)) / L[:, None, None]
    m = np.asarray(rho, float) * np.asarray(A, float) * L
    consistent = np.kron(_AXIAL_MASS / 6, np.eye(3))[None] * m[:, None, None]
    lumped_m = np.eye(6)[None] * (m / 2)[:, None, None]
    if lumped is None:
        lumped = np.zeros(L.size, bool)
    M = np.where(np.asarray(lumped, bool)[:, None, None], lumped_m, consistent)
    return K, M, Kg1


def hermite_curvature_row(L: float, xi: float, plane: str) -> np.ndarray:
    """Row of 12 giving the curvature ``v''`` (plane ``"v"``) or ``w''`` (``"w"``) at ``xi``.

    Second derivatives of the cubic Hermite functions (1/m): ``N1'' = (12 xi - 6)/L^2``,
    ``N2'' = (6 xi - 4)/L``, ``N3'' = (6 - 12 xi)/L^2``, ``N4'' = (6 xi - 2)/L``; in the x-z
    plane the rotation entries change sign because ``ry = -w'``.
    """
    row = np.zeros(12)
    vals = np.array([(12 * xi - 6) / L**2, (6 * xi - 4) / L, (6 - 12 * xi) / L**2, (6 * xi - 2) / L])
    if plane == "v":
        row[_V_PLANE] = vals
    else:
        row[_W_PLANE] = vals * _W_SIGN
    return row
