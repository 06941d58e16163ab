"""The assembly's reuse of geometry and gravity preloads across frames gives the
same matrices and preload as a cold rebuild, and is really taken where it should be."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.physical import fem


def _cold(build):
    """``build()`` with the assembly's geometry and preload stores emptied first."""
    for store in (fem._GEOMETRY, fem._PRELOADS):
        with store._lock:
            store._store.clear()
    return build()


def _dense(a):
    return a.toarray() if hasattr(a, "toarray") else np.asarray(a)


@pytest.fixture(scope="module")
def truss():
    return rc.examples.caltech_truss()


def _effects():
    fx = rc.effects
    return [
        fx.SuspensionSpring("platform_2", direction="x", stiffness=2.0e3),
        fx.Dashpot("platform_1", direction="y", damping=30.0),
        fx.AddedMass("platform_2", mass=0.4),
        fx.GroupTension("longerons_story_1", tension=15.0),
        fx.GroupStiffness("diagonals", change=0.2),
    ]


@pytest.mark.parametrize("k", range(5))
def test_reused_assembly_equals_a_cold_rebuild(truss, k):
    effect = _effects()[k]
    model = effect.apply(truss)
    truss.build_structure().matrices()  # warm the stores with the nominal frame
    warm = model.build_structure(E_aluminium=truss.param("E_aluminium").value * 1.01)
    mats = warm.matrices()
    cold = _cold(lambda: model.build_structure(E_aluminium=truss.param("E_aluminium").value * 1.01))
    ref = cold.matrices()
    for a, b in ((mats.mass, ref.mass), (mats.stiffness, ref.stiffness), (mats.damping, ref.damping),
                 (mats.input_matrix, ref.input_matrix), (mats.output_matrix, ref.output_matrix)):
        np.testing.assert_allclose(_dense(a), _dense(b), rtol=1e-12, atol=0)
    np.testing.assert_allclose(warm.preload().axial_forces, cold.preload().axial_forces, rtol=1e-12)
    # the effect is in the matrices: not a stale copy of the nominal frame's
    nominal = truss.build_structure(E_aluminium=truss.param("E_aluminium").value * 1.01).matrices()
    changed = [not np.array_equal(_dense(getattr(mats, f)), _dense(getattr(nominal, f)))
               for f in ("mass", "stiffness", "damping")]
    assert any(changed)


def test_geometry_and_preload_are_shared_where_nothing_they_read_changed(truss):
    base = truss.build_structure()
    base.matrices()
    damped = rc.effects.Dashpot("platform_1", direction="y", damping=30.0).apply(truss).build_structure()
    damped.matrices()
    assert fem._geometry(damped) is fem._geometry(base)
    assert damped.preload() is base.preload()  # a dashpot leaves the static sag alone
    sprung = rc.effects.SuspensionSpring("platform_2", direction="x", stiffness=2.0e3).apply(truss)
    s = sprung.build_structure()
    assert fem._geometry(s) is fem._geometry(base)
    assert s.preload() is not base.preload()
    assert not np.allclose(s.preload().axial_forces, base.preload().axial_forces, rtol=1e-9, atol=0)
    stiff = rc.effects.GroupStiffness("diagonals", change=0.2).apply(truss).build_structure()
    assert fem._geometry(stiff) is not fem._geometry(base)


def test_a_dashpot_reuses_the_modes_and_gives_the_cold_response(truss, monkeypatch):
    """A dashpot leaves M and K alone: the eigensolution is taken from the cache and only
    ``Phi^T Cs Phi`` is recomputed; the state space equals one built with no cache at all."""
    from robustctl.physical import modal

    effect = rc.effects.Dashpot("platform_1", direction="y", damping=0.0)
    model = effect.apply(truss)
    model.statespace()  # the modes of the undamped frame are now cached
    solves = []
    real = modal.solve_modes
    monkeypatch.setattr(modal, "solve_modes", lambda *a, **k: solves.append(1) or real(*a, **k))
    warm = model.statespace(**{effect.param_names[0]: 30.0})
    assert solves == []  # no eigensolution for another dashpot size
    monkeypatch.setattr(modal._ModeCache, "get", lambda self, key, compute: compute())  # no mode cache
    fresh = rc.effects.Dashpot("platform_1", direction="y", damping=30.0).apply(truss)
    cold = fresh.statespace()  # a new model object: no dynamics cache either
    assert solves == [1]
    np.testing.assert_array_equal(warm.A, cold.A)
    np.testing.assert_array_equal(warm.C, cold.C)
    undamped = model.statespace()
    assert not np.allclose(warm.A, undamped.A)  # the dashpot is in the model, not a stale copy


def test_a_frame_rebuilt_with_other_masses_shares_the_geometry_by_value(truss):
    """Updating a point mass rebuilds the frame node by node (new objects): the geometry is
    found by the values of the frozen parts, and the matrices equal a cold assembly's."""
    base = truss.build_structure(m_offset=truss.param("m_offset").value * 1.1)
    base.matrices()
    heavier = truss.build_structure(m_offset=truss.param("m_offset").value * 1.3)
    assert fem._geometry(heavier) is fem._geometry(base)
    stiffer = truss.build_structure(E_aluminium=truss.param("E_aluminium").value * 1.05)
    assert fem._geometry(stiffer) is not fem._geometry(base)  # E is in the elements: new geometry
    mats = heavier.matrices()
    ref = _cold(lambda: truss.build_structure(m_offset=truss.param("m_offset").value * 1.3)).matrices()
    for a, b in ((mats.mass, ref.mass), (mats.stiffness, ref.stiffness)):
        np.testing.assert_array_equal(_dense(a), _dense(b))
    assert not np.array_equal(_dense(mats.mass), _dense(base.matrices().mass))


def test_sparse_modes_do_not_depend_on_the_eigenproblems_solved_before():
    """ARPACK's default start vector continues one random sequence through the process: the
    same sparse eigenproblem, solved before and after another one, must give the same bits
    (frequencies and shapes), and the frequencies of a spring chain match its closed form."""
    import scipy.sparse as sp

    from robustctl.physical.eigen import solve_modes

    def chain(n: int, k: float):
        main = np.full(n, 2.0 * k)
        K = sp.diags([main, -k * np.ones(n - 1), -k * np.ones(n - 1)], [0, -1, 1], format="csc")
        return sp.identity(n, format="csc"), K

    M, K = chain(800, 1.0)
    first = solve_modes(M, K, n_modes=6, sparse=True)
    solve_modes(*chain(700, 3.0), n_modes=9, sparse=True)
    again = solve_modes(M, K, n_modes=6, sparse=True)
    assert np.array_equal(first[0], again[0]) and np.array_equal(first[1], again[1])
    # fixed-fixed chain: omega_j = 2 sin(j pi / (2 (n + 1)))
    j = np.arange(1, 7)
    assert np.allclose(first[0], 2 * np.sin(j * np.pi / 1602), rtol=1e-9)
