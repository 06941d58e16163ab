"""Gravity preload (MACE's stress-stiffening iteration): pendulum and violin modes from
geometric stiffness alone, member forces, unsupported directions, buckling."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from robustctl.errors import ModelError
from robustctl.physical import gravity
from robustctl.physical.fem import Frame

g = 9.81
STEEL = dict(E=2.0e11, rho=7800.0)


def pendulum(length: float, mass: float, direction=(0.0, 0.0, -1.0), **frame_kw) -> Frame:
    fr = Frame(gravity=g, gravity_direction=direction, **frame_kw)
    d = np.asarray(direction, float)
    fr.add_node("hook", tuple(-length * d))
    fr.add_node("bob", (0.0, 0.0, 0.0))
    fr.add_rod("wire", "hook", "bob", E=2.0e11, rho=100.0, A=1e-7)  # 10 g/km: a light wire
    fr.add_mass("bob", mass)
    fr.fix("hook")
    return fr


@pytest.mark.parametrize("direction", [(0, 0, -1), (0, -1, 0), (0.6, 0.0, -0.8)])
def test_pendulum_frequency_from_geometric_stiffness(direction):
    L = 2.0
    fr = pendulum(L, 1.5, direction)
    f, _ = fr.modes()
    assert np.allclose(f[:2], np.sqrt(g / L) / (2 * np.pi), rtol=0.01)
    assert f[2] > 10 * f[1]  # the axial (bounce) mode of the wire
    assert np.isclose(fr.axial_forces()["wire[0]"], 1.5 * g, rtol=1e-4)
    assert fr.preload().converged and fr.preload().unbalanced_fraction < 1e-12
    # static sag: the wire stretches by T L / (E A)
    sag = fr.static_deflection()["bob"][:3]
    assert np.allclose(
        sag, np.asarray(direction) / np.linalg.norm(direction) * 1.5 * g * L / (2e11 * 1e-7), rtol=1e-4
    )


def test_no_pendulum_without_gravity():
    f, _ = pendulum(2.0, 1.5).without("gravity").modes()
    assert np.all(f[:2] < 1e-6)


def test_one_step_differential_stiffness_equals_the_iteration_for_a_determinate_suspension():
    f1, _ = pendulum(2.0, 1.5, max_gravity_iterations=1).modes()
    fr = pendulum(2.0, 1.5)
    f50, _ = fr.modes()
    assert np.allclose(f1, f50, rtol=1e-9)
    fr.max_gravity_iterations = 1  # changing the setting rebuilds the model
    assert fr.preload().iterations == 1 and not fr.preload().converged
    with pytest.raises(ModelError, match="max_gravity_iterations must be an integer >= 1"):
        fr.max_gravity_iterations = 0


def string(n_elements: int, tension: float, *, beam: bool = False) -> Frame:
    fr = Frame()
    fr.add_node("a", (0, 0, 0))
    fr.add_node("b", (1.0, 0, 0))
    if beam:  # a thin wire as a beam: bending stiffness negligible against the tension
        r = 2e-4
        A, I = np.pi * r**2, np.pi * r**4 / 4
        fr.add_beam("s", "a", "b", G=8e10, A=A, Iy=I, Iz=I, J=2 * I, n_elements=n_elements, **STEEL)
    else:
        fr.add_rod("s", "a", "b", A=np.pi * 4e-8, n_elements=n_elements, **STEEL)
    # pinned ends: a clamped thin wire has a bending boundary layer (width sqrt(EI/T) ~ 1 mm)
    # that the elements cannot resolve, and a string's ends are hinges anyway
    fr.fix("a", ["x", "y", "z", "rx"] if beam else "all")
    fr.fix("b", ["y", "z"] if beam else "all")
    fr.add_group_tension("s", tension)
    return fr


@pytest.mark.parametrize("beam", [False, True])
def test_taut_string_violin_modes(beam):
    T = 200.0
    mu = STEEL["rho"] * np.pi * 4e-8
    fr = string(30, T, beam=beam)
    f, _ = fr.modes(n_modes=6)
    expected = np.array([1, 2, 3]) / 2.0 * np.sqrt(T / mu)
    assert np.allclose(f[0::2], f[1::2], rtol=1e-6)  # two transverse planes
    assert np.max(np.abs(f[0::2] / expected - 1)) < 0.01


def test_violin_modes_of_a_wire_tensioned_by_gravity():
    """A vertical wire holding a heavy body (guided laterally): tension m g from the preload
    iteration, violin modes (n/2L) sqrt(m g / mu) within 1 %."""
    m, L, A = 50.0, 1.5, 1e-6
    fr = Frame(gravity=g)
    fr.add_node("top", (0, 0, L))
    fr.add_node("body", (0, 0, 0))
    fr.add_rod("wire", "top", "body", A=A, n_elements=30, **STEEL)
    fr.add_mass("body", m)
    fr.fix("top")
    fr.fix("body", ["x", "y"])
    f, phi = fr.modes(n_modes=8)
    labels = np.array(fr.matrices().dof_labels)
    lateral = np.sum(phi[np.char.endswith(labels, "ux")] ** 2, axis=0) > 0.5 * np.sum(phi**2, axis=0)
    mu = STEEL["rho"] * A
    expected = np.array([1, 2, 3]) / (2 * L) * np.sqrt(m * g / mu)
    assert np.max(np.abs(f[lateral][:3] / expected - 1)) < 0.01
    N = np.array(list(fr.axial_forces().values()))
    assert np.all(m * g < N) and np.isclose(N.max(), (m + mu * L * 29.5 / 30) * g, rtol=1e-6)


def test_hanging_beam_carries_the_weight_below_each_element():
    """Element axial force = weight of everything below its midpoint (rho A g s + m g)."""
    L, n, A, m = 2.0, 8, 3e-4, 4.0
    fr = Frame(gravity=g)
    fr.add_node("top", (0, 0, 0))
    fr.add_node("end", (0, 0, -L))
    I = 1e-8
    fr.add_beam("rod", "top", "end", G=8e10, A=A, Iy=I, Iz=I, J=2 * I, n_elements=n, **STEEL)
    fr.add_mass("end", m)
    fr.fix("top")
    N = np.array(list(fr.axial_forces().values()))
    below = L - (np.arange(n) + 0.5) * L / n
    assert np.allclose(N, STEEL["rho"] * A * g * below + m * g, rtol=1e-9)


def test_free_structure_in_gravity_has_no_preload_and_does_not_crash():
    """Free fall: the whole load is unbalanced, no member is stressed, modes are unchanged."""

    def free(grav):
        fr = Frame(gravity=g if grav else None)
        for i, x in enumerate((0.0, 1.0, 2.0)):
            fr.add_node(f"n{i}", (x, 0, 0.3 * i))
        kw = dict(G=8e10, A=1e-4, Iy=1e-9, Iz=2e-9, J=1e-9, **STEEL)
        fr.add_beam("a", "n0", "n1", n_elements=3, **kw)
        fr.add_beam("b", "n1", "n2", n_elements=3, **kw)
        fr.add_mass("n2", 1.0)
        return fr

    fr = free(True)
    f, _ = fr.modes(n_modes=10)
    f0, _ = free(False).modes(n_modes=10)
    assert np.all(f[:6] < 1e-3)
    assert np.allclose(f[6:], f0[6:], rtol=1e-8)
    assert np.abs(list(fr.axial_forces().values())).max() < 1e-9
    assert np.isclose(fr.preload().unbalanced_fraction, 1.0)


def test_suspended_platform_pendulum_and_rotary_pendulum():
    """A platform hung on three vertical rods at radius r: two swinging modes at sqrt(g/L)
    and a rotary pendulum at sqrt(m g r^2 / (L I_z)) (MACE's "suspension rotary pendulum")."""
    L, r, m, Iz = 3.0, 0.5, 20.0, 1.2
    fr = Frame(gravity=g)
    fr.add_node("c", (0, 0, 0))
    for k in range(3):
        ang = 2 * np.pi * k / 3
        p = np.array([r * np.cos(ang), r * np.sin(ang), 0.0])
        fr.add_node(f"p{k}", tuple(p))
        fr.add_node(f"h{k}", tuple(p + [0, 0, L]), tags=("suspension",))
        fr.add_rigid_link("c", f"p{k}")
        fr.add_rod("rods", f"h{k}", f"p{k}", E=2e11, rho=10.0, A=1e-6, tags=("suspension",))
        fr.fix(f"h{k}")
    fr.add_mass("c", m, inertia=(2.0, 2.0, Iz))
    f, _ = fr.modes(n_modes=3)
    assert np.allclose(f[:2], np.sqrt(g / L) / (2 * np.pi), rtol=0.01)
    assert np.isclose(f[2], np.sqrt(m * g * r**2 / (L * Iz)) / (2 * np.pi), rtol=0.01)
    assert fr.without("suspension", "gravity").modes(n_modes=6)[0].max() < 1e-3


@pytest.mark.parametrize("offset", [(0.0, 0.0, -0.4), (0.3, 0.0, -0.4)])
def test_body_below_a_pivot_on_a_rigid_link_is_a_compound_pendulum(offset):
    """A body (m, I_cg) rigidly linked below a pin: f = sqrt(m g h / (I_cg + m h^2)) / (2 pi)
    for swinging about x, from the geometric stiffness of the loaded link alone."""
    m, Icg = 3.0, 0.05
    r = np.asarray(offset)
    fr = Frame(gravity=g)
    fr.add_node("pin", (0.0, 0.0, 0.0))
    fr.add_node("cg", tuple(r))
    fr.add_rigid_link("pin", "cg")
    fr.add_mass("cg", m, inertia=(Icg, Icg, Icg))
    fr.fix("pin", ["x", "y", "z"])
    f, _ = fr.modes()
    h = -r[2]
    if r[0] == 0:
        expected = np.sqrt(m * g * h / (Icg + m * h**2)) / (2 * np.pi)
        assert np.allclose(f[1:], expected, rtol=1e-9) and f[0] < 1e-6  # free spin about z
        assert np.isclose(fr.axial_forces()["pin->cg"], m * g)
    else:  # the link is inclined: it carries only the weight's component along it
        assert f[0] < 1e-6 and np.all(f[1:] > 0)
    assert np.all(fr.without("gravity").modes()[0] < 1e-6)


def column(mass: float, n_elements: int = 8) -> tuple[Frame, float]:
    """A standing cantilever column with a top mass; returns it and its Euler load."""
    L, r = 1.0, 0.004
    I = np.pi * r**4 / 4
    fr = Frame(gravity=g)
    fr.add_node("base", (0, 0, 0))
    fr.add_node("top", (0, 0, L))
    fr.add_beam(
        "col", "base", "top", G=8e10, A=np.pi * r**2, Iy=I, Iz=I, J=2 * I, n_elements=n_elements, **STEEL
    )
    fr.add_mass("top", mass)
    fr.fix("base")
    return fr, np.pi**2 * STEEL["E"] * I / (4 * L**2)


def test_compression_softens_and_beyond_buckling_is_refused():
    fr, p_cr = column(1.0)
    f_loaded, _ = fr.modes(n_modes=1)
    f_free, _ = fr.without("gravity").modes(n_modes=1)
    P = 1.0 * g
    # Rayleigh estimate for a tip-loaded cantilever column: f^2 ~ f0^2 (1 - P/P_cr)
    assert np.isclose(f_loaded[0] / f_free[0], np.sqrt(1 - P / p_cr), rtol=0.02)
    heavy, p_cr = column(1.3 * p_cr / g)
    with pytest.raises(ModelError, match="buckling"):
        heavy.matrices()


def test_iteration_is_capped_and_reports_its_history():
    fr, _ = column(1.0)
    res = fr.preload()
    assert res.converged and 1 <= res.iterations <= 50 and len(res.history) == res.iterations
    with pytest.raises(ModelError, match="max_iter must be at least 1"):
        gravity.preload_iteration(
            sp.eye(2), sp.eye(2), np.ones(2), lambda u: u, lambda n: sp.eye(2), max_iter=0
        )


def test_free_spin_about_a_wire_is_a_zero_frequency_mode_not_a_crash():
    fr = pendulum(1.0, 2.0)
    fr.add_mass("bob", 1e-9, inertia=(0.1, 0.1, 0.1))
    f, _ = fr.modes()
    assert np.sum(f < 1e-6) == 3  # the body turns freely on the wire's pin joint
    assert np.sum(np.isclose(f, np.sqrt(g / 1.0) / (2 * np.pi), rtol=0.01)) == 2


# ---------------------------------------------------------------- the static solver
def _singular_system(n=40, n_null=3, seed=0):
    rng = np.random.default_rng(seed)
    M = np.diag(rng.uniform(1, 3, n))
    Z = rng.normal(size=(n, n_null))
    P = np.eye(n) - Z @ np.linalg.solve(Z.T @ Z, Z.T)
    Q = rng.normal(size=(n, n))
    K = P @ (Q @ Q.T + n * np.eye(n)) @ P
    return 0.5 * (K + K.T), M, rng.normal(size=n)


@pytest.mark.parametrize("dense_limit", [10_000, 5])
def test_solve_static_matches_the_pseudo_inverse_in_the_mass_metric(dense_limit, monkeypatch):
    monkeypatch.setattr(gravity, "DENSE_LIMIT", dense_limit)
    K, M, f = _singular_system()
    lam, phi = sla.eigh(K, M)
    flex = lam > 1e-8 * lam.max()
    u_ref = phi[:, flex] @ ((phi[:, flex].T @ f) / lam[flex])
    removed_ref = M @ phi[:, ~flex] @ (phi[:, ~flex].T @ f)
    u, removed = gravity.solve_static(sp.csr_matrix(K), sp.csr_matrix(M), f)
    assert np.allclose(u, u_ref, rtol=1e-8, atol=1e-10 * np.abs(u_ref).max())
    assert np.allclose(removed, removed_ref, atol=1e-10 * np.abs(f).max())
    assert gravity.null_space(sp.csr_matrix(K), sp.csr_matrix(M)).shape[1] == 3


def test_solve_static_on_a_supported_structure_is_the_plain_solution():
    K, M, f = _singular_system(n_null=0)
    u, removed = gravity.solve_static(sp.csr_matrix(K), sp.csr_matrix(M), f)
    assert np.allclose(u, np.linalg.solve(K, f)) and not np.any(removed)


def test_soft_suspension_modes_of_a_stiff_body_are_not_mistaken_for_rigid_body_modes():
    """A stiff 0.2 m beam (element modes ~ 1e4 Hz) hung on a 20 m wire: the 0.11 Hz pendulum
    modes are real modes, not rounding, and solve_modes must keep them."""
    fr = Frame(gravity=g)
    fr.add_node("hook", (0.1, 0.0, 20.0))
    for name, x in (("a", 0.0), ("mid", 0.1), ("b", 0.2)):
        fr.add_node(name, (x, 0.0, 0.0))
    r = 0.01
    A, I = np.pi * r**2, np.pi * r**4 / 4
    kw = dict(G=8e10, A=A, Iy=I, Iz=I, J=2 * I, n_elements=2, **STEEL)
    fr.add_beam("body", "a", "mid", **kw)
    fr.add_beam("body", "mid", "b", **kw)
    fr.add_rod("wire", "hook", "mid", E=2e11, rho=100.0, A=1e-6)
    fr.fix("hook")
    f, _ = fr.modes(n_modes=5)
    # the body turns freely about the pin at its centre of mass: three rigid rotations
    assert np.all(f[:3] < 1e-3)
    assert np.allclose(f[3:], np.sqrt(g / 20.0) / (2 * np.pi), rtol=0.01)


def _hung_tower(gravity_on: bool = True, suspended: bool = True) -> Frame:
    fr = Frame(gravity=g if gravity_on else None)
    kw = dict(G=8e10, A=1e-4, Iy=1e-8, Iz=1e-8, J=2e-8, **STEEL)
    for k in range(4):
        for j in range(3):
            ang = 2 * np.pi * j / 3
            fr.add_node(f"n{k}{j}", (0.3 * np.cos(ang), 0.3 * np.sin(ang), -0.3 * k))
    for k in range(4):
        for j in range(3):
            fr.add_beam("batten", f"n{k}{j}", f"n{k}{(j + 1) % 3}", **kw)
            if k < 3:
                fr.add_beam("longeron", f"n{k}{j}", f"n{k + 1}{j}", **kw)
    if suspended:
        fr.add_node("hook", (0.0, 0.0, 1.0))
        for j in range(3):
            fr.add_rod("rods", "hook", f"n0{j}", E=2e11, rho=7800.0, A=1e-5, n_elements=3)
        fr.fix("hook")
    return fr


@pytest.mark.parametrize("suspended", [True, False])
def test_sparse_static_path_agrees_with_the_dense_one(suspended, monkeypatch):
    """The preconditioned-CG path for large models (forced here on a small one) gives the
    same member forces and modes, for a suspended and for a free-falling structure."""
    dense = _hung_tower(suspended=suspended)
    N_dense = np.array(list(dense.axial_forces().values()))
    f_dense, _ = dense.modes(n_modes=10)
    monkeypatch.setattr(gravity, "DENSE_LIMIT", 10)
    sparse_fr = _hung_tower(suspended=suspended)
    N_sparse = np.array(list(sparse_fr.axial_forces().values()))
    f_sparse, _ = sparse_fr.modes(n_modes=10)
    W = g * float(np.sum(sparse_fr.matrices().mass.diagonal()))  # a scale for the forces
    assert np.abs(N_sparse - N_dense).max() < 1e-9 * W
    assert np.allclose(f_sparse, f_dense, rtol=1e-8, atol=1e-8)
    assert np.isclose(sparse_fr.preload().unbalanced_fraction, 0.0 if suspended else 1.0, atol=1e-9)


def test_rounding_floor_of_the_forces_ends_the_iteration_but_divergence_still_raises():
    """Static solutions accurate to ~1e-8 of the forces make the changes flip at that level
    (the MACE bus stalled at 9.9e-7 N against a 1e-6 N tolerance for 50 steps and raised);
    the iteration accepts a change that stops falling within 100x the tolerance. A change
    that stays large (buckling, slow divergence) is still refused."""
    K, M, f = sp.eye(2, format="csr"), sp.eye(2, format="csr"), np.array([100.0, 50.0])
    flip = iter(np.tile([3e-7, -3e-7], 100))

    def noisy(u, N_used=None):  # a converged force of 100 N with +-3e-7 N of rounding
        return np.array([100.0 + next(flip), 50.0])

    res = gravity.preload_iteration(K, M, f, noisy, lambda n: sp.csr_matrix((2, 2)), tol=1e-9)
    assert res.converged and res.iterations <= 4
    assert abs(res.axial_forces[0] - 100.0) < 1e-6

    growing = iter(100.0 * 1.5 ** np.arange(100))
    with pytest.raises(ModelError, match="did not converge"):
        gravity.preload_iteration(K, M, f, lambda u, N_used=None: np.array([next(growing), 0.0]),
                                  lambda n: sp.csr_matrix((2, 2)), tol=1e-9)
    assert gravity._stalled_at_rounding([1.0, 1e-7, 1e-7], 1e-8)
    assert not gravity._stalled_at_rounding([1.0, 1e-7, 1e-7], 1e-10)  # 1000x the tolerance
    assert not gravity._stalled_at_rounding([1.0, 1e-6, 5e-7], 1e-8)  # still falling


def test_supported_structure_iterates_densely_with_the_bits_of_the_general_path(monkeypatch):
    """A small supported structure skips the null space, the regularised mass and the inertia
    relief and iterates on dense matrices: its preload (Caltech truss: beams, rods, ten rigid
    links, 4 iterations) equals the general sparse path's bit for bit."""
    import robustctl as rc
    from robustctl.physical import frame_assembly, frame_cache

    def preload(general: bool):
        monkeypatch.setattr(frame_assembly, "_PRELOADS", frame_cache._LRU(4))
        if general:  # null_space's eigen-decomposition decides: no null mode, the sparse loop
            monkeypatch.setattr(gravity, "_clearly_definite", lambda K: False)
        frame = rc.examples.caltech_truss().build_structure()
        result = frame.preload()
        monkeypatch.undo()
        return frame, result

    frame, fast = preload(general=False)
    _, ref = preload(general=True)
    assert fast.iterations == ref.iterations >= 3 and fast.converged
    for a in ("axial_forces", "displacement", "unbalanced_load"):
        assert np.array_equal(getattr(fast, a), getattr(ref, a))
    assert fast.history == ref.history and fast.unbalanced_fraction == 0.0
    assert not np.any(fast.unbalanced_load) and np.abs(fast.axial_forces).max() > 1.0


def test_link_force_rows_equal_the_rows_of_the_whole_matrix_product():
    """A rigid link's force needs ``(K + K_g(N)) u`` on its slave node's translations only:
    ``_SlaveRows`` sums the same triplets in the same order as the full CSR matrix, so the rows
    are the full product's bit for bit (Caltech truss: beams, rods, ten rigid links)."""
    import robustctl as rc
    from robustctl.physical.frame_assembly import _SlaveRows
    from robustctl.physical.frame_cache import _full_triplets, _geometry
    from robustctl.physical.frame_kernels import _G, _K, _Pattern, _point_triplets

    frame = rc.examples.caltech_truss().build_structure()
    geo = _geometry(frame)
    full = _full_triplets(geo, _point_triplets(frame, geo.index))
    masters, slaves = geo.links
    assert slaves.size == 10
    n = 6 * len(geo.names)
    dofs = (6 * slaves[:, None] + np.arange(3)).ravel()
    rng = np.random.default_rng(3)
    n_elem = rng.normal(scale=50.0, size=int(full.tag.max()) + 1)
    x = rng.normal(size=n)
    whole = _Pattern(full.rows, full.cols, n).matrix(full.vals[:, _K] + full.vals[:, _G] * n_elem[full.tag])
    assert np.array_equal(_SlaveRows(full, dofs, n).times(n_elem, x), (whole @ x)[dofs])
