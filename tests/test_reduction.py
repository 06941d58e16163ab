"""Reduced coordinates of large structural models (robustctl.physical.reduction).

The truth is computed here with numpy/scipy: a dense generalised eigen-solution of the full
sparse grid and the modal sum, independent of robustctl's modal code.
"""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

import robustctl as rc
import robustctl.physical.reduction as red
from robustctl.errors import ModelError

N_X, N_Y = 10, 20  # 200 DOFs
ZETA = 0.01
F_HZ = np.linspace(3.0, 20.0, 300)


def _grid():
    n = N_X * N_Y
    idx = np.arange(n).reshape(N_Y, N_X)
    pairs = np.concatenate([
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1),
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], axis=1),
    ])
    i, j = pairs[:, 0], pairs[:, 1]
    K = sp.coo_matrix((1e4 * np.concatenate([np.ones(2 * i.size), -np.ones(2 * i.size)]),
                       (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))), shape=(n, n)).tocsr()
    K = K + 50.0 * sp.identity(n, format="csr")
    M = sp.diags(0.1 * (1.0 + 0.3 * np.linspace(0.0, 1.0, n) ** 2)).tocsr()
    return M, K


INS, OUTS = [45, 133], [10, 57, 102, 150, 188]


def _model(kind="acceleration"):
    M, K = _grid()
    par = rc.Parameter("k_scale", 1.0, "", (0.5, 2.0), meaning="stiffness scale")
    return rc.structural_model(
        M, lambda th: th["k_scale"] * K,
        inputs={f"F{k}": f"dof {d + 1}" for k, d in enumerate(INS)},
        outputs={f"y{k}": (f"dof {d + 1}", kind) for k, d in enumerate(OUTS)},
        damping=ZETA, params=[par], name="grid",
    )


def _numpy_frf(M, K, f_hz, kind="acceleration"):
    lam, phi = sla.eigh(K.toarray(), M.toarray())
    wk = np.sqrt(lam)
    w = 2 * np.pi * f_hz[:, None]
    factor = {"displacement": 1.0, "velocity": 1j * w, "acceleration": -(w**2)}[kind]
    h = factor / (wk**2 - w**2 + 2j * ZETA * wk * w)
    return np.einsum("fk,ok,ik->foi", h, phi[OUTS], phi[INS])


@pytest.mark.parametrize("kind", ["displacement", "acceleration"])
def test_reduced_response_within_its_error_estimate(kind):
    model = _model(kind)
    reduced = red.band_limited(model, F_HZ[-1], min_dof=0)
    M, K = _grid()
    truth = _numpy_frf(M, K, F_HZ, kind)
    g = reduced.freqresp(F_HZ).response
    err = np.abs(g - truth)
    bound = red.reduction_error(reduced, F_HZ)
    assert bound.shape == err.shape
    assert np.all(err <= bound)
    # the reduction is real: far fewer states than the 400 of the full model
    assert reduced.statespace().A.shape[0] < 0.3 * model.statespace().A.shape[0]
    # the estimate is informative (not a blanket bound): below 15 % of each channel's peak
    assert np.max(bound / np.abs(truth).max(axis=0)) < 0.15


def test_error_falls_with_the_fourth_power_of_the_margin():
    """The attachment vectors match the truncated modes' static and first inertia terms, so the
    error falls as ``(f_max / f_cut)^4``: from a 3x to a 6x margin by 16 (here to 1e-4 of each
    channel's in-band peak); every margin stays within its estimate."""
    model = _model()
    M, K = _grid()
    truth = _numpy_frf(M, K, F_HZ)
    peak = np.abs(truth).max(axis=0)
    rel = {}
    for margin in (3.0, 6.0):
        reduced = red.band_limited(model, F_HZ[-1], margin=margin, min_dof=0)
        g = reduced.freqresp(F_HZ).response
        assert np.all(np.abs(g - truth) <= red.reduction_error(reduced, F_HZ))
        rel[margin] = float(np.max(np.abs(g - truth) / peak))
    assert rel[6.0] <= 2.0 * rel[3.0] / 16.0
    assert rel[6.0] < 1e-4


@pytest.mark.parametrize(
    "effect",
    [rc.effects.AddedMass("dof 58", mass=0.04), rc.effects.SuspensionSpring("dof 58", stiffness=2e3),
     rc.effects.Dashpot("dof 103", damping=3.0)],
    ids=["mass", "spring", "dashpot"],
)
def test_low_rank_change_equals_reduction_of_the_changed_structure(effect):
    """The structural-dynamic-modification path (a change at one DOF re-solved in the base basis
    plus that DOF's attachment vector) equals building the modal model of the changed structure
    in the same Ritz basis from scratch (dense projection, scipy eigh), to round-off."""
    model = _model()
    reduced = red.band_limited(model, F_HZ[-1], min_dof=0)
    reduced.freqresp(F_HZ)  # the base reduction, cached
    changed = effect.apply(reduced)
    g_fast = changed.freqresp(F_HZ).response
    reducer = reduced.dynamics.reducer
    base = next(iter(reducer._bases.values()))
    mats = changed.build_structure().matrices()
    dofs = reducer.basis_and_dofs(mats)[1][0]
    assert dofs.size == 1  # found as a low-rank change, not reduced anew
    # independent: dense projection on W = [V, M-orthonormalised K_sigma^-1 e_J], scipy eigh
    Md, Kd = mats.mass.toarray(), mats.stiffness.toarray()
    E = np.zeros((Md.shape[0], 1))
    E[dofs[0], 0] = 1.0
    a = np.linalg.solve(base.stiffness.toarray() - base.sigma * base.mass.toarray(), E)
    W = np.hstack([base.V, a])
    lam, psi = sla.eigh(W.T @ Kd @ W, W.T @ Md @ W)
    shapes = W @ psi
    w = 2 * np.pi * F_HZ[:, None]
    wk = np.sqrt(lam)
    cs = np.zeros((wk.size, wk.size)) if mats.damping is None else shapes.T @ mats.damping.toarray() @ shapes
    b, c = mats.input_matrix, mats.output_matrix
    A = np.block([[np.zeros_like(cs), np.eye(wk.size)], [-np.diag(wk**2), -(np.diag(2 * ZETA * wk) + cs)]])
    B = np.vstack([np.zeros((wk.size, b.shape[1])), shapes.T @ b])
    Cd = c @ shapes
    C = Cd @ A[wk.size:]
    D = Cd @ (shapes.T @ b)
    g_ref = np.array([C @ np.linalg.solve(1j * wi * np.eye(A.shape[0]) - A, B) + D for wi in w[:, 0]])
    scale = np.abs(g_ref).max(axis=0)
    assert np.max(np.abs(g_fast - g_ref) / scale) < 1e-8


def test_low_rank_change_in_a_complete_basis_equals_the_full_rebuild():
    """With every mode kept (cut above the highest frequency) the low-rank path is exact: the
    added mass's response equals the full dense rebuild of the changed structure (numpy)."""
    model = _model()
    reduced = red.band_limited(model, 400.0, margin=2.0, min_dof=0)  # the grid's top mode: 143 Hz
    mass = 0.04
    g = rc.effects.AddedMass("dof 58", mass=mass).apply(reduced).freqresp(F_HZ).response
    M, K = _grid()
    M = M.tolil()
    M[57, 57] += mass
    truth = _numpy_frf(M.tocsr(), K, F_HZ)
    assert np.max(np.abs(g - truth) / np.abs(truth).max(axis=0)) < 1e-9


def test_small_models_keep_the_full_path():
    model = _model()
    assert red.band_limited(model, 20.0) .freqresp(F_HZ).response.tobytes() == \
        model.freqresp(F_HZ).response.tobytes()
    assert red.reduction_error(red.band_limited(model, 20.0), F_HZ) is None


def test_models_it_cannot_reduce_are_returned_unchanged():
    M, K = _grid()
    trunc = rc.structural_model(M, K, inputs={"F": "dof 1"}, outputs={"y": ("dof 2", "displacement")},
                                n_modes=10)
    assert red.band_limited(trunc, 20.0, min_dof=0) is trunc
    reduced = red.band_limited(_model(), 20.0, min_dof=0)
    assert red.band_limited(reduced, 30.0, min_dof=0) is reduced


def test_bad_band_limits_are_refused():
    with pytest.raises(ModelError, match="margin"):
        red.band_limited(_model(), 20.0, margin=0.5)
    with pytest.raises(ModelError, match="f_max_hz"):
        red.band_limited(_model(), -1.0)


def test_diagnose_ranks_the_same_with_the_reduced_and_the_full_path(monkeypatch):
    """A 200-DOF grid, 2 inputs x 5 outputs, a hidden added mass at a sensor node, 1 % noise
    made with numpy: the reduced path gives the full path's ranking of the candidates."""
    model = _model()
    M, K = _grid()
    M = M.tolil()
    M[57, 57] += 0.03
    truth = _numpy_frf(M.tocsr(), 1.02 * K, F_HZ)
    rng = np.random.default_rng(1)
    g = truth * np.exp(0.01 * (rng.standard_normal(truth.shape) + 1j * rng.standard_normal(truth.shape)))
    data = rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs)
    noise = rc.NoiseModel(F_HZ, np.full(g.shape, 0.01), "known synthetic noise")
    cands = rc.effects.calibrate(
        model, [rc.effects.AddedMass(f"dof {d}") for d in (48, 56, 57, 58, 59, 60, 68, 104)]
        + [rc.effects.SuspensionSpring("dof 58"), rc.effects.Dashpot("dof 58")], band=(3.0, 20.0))
    full = rc.diagnose(model, data, cands, noise=noise, workers=1)
    monkeypatch.setattr(red, "REDUCE_MIN_DOF", 0)
    reduced = rc.diagnose(model, data, cands, noise=noise, workers=1)
    assert [r.name for r in reduced.ranking] == [r.name for r in full.ranking]
    assert reduced.ranking[0].name == "added mass at dof 58"
    value = reduced.ranking[0].values["added_mass__dof_58"]
    assert value == pytest.approx(0.03, rel=0.15)
    assert reduced.ranking[0].gain == pytest.approx(full.ranking[0].gain, abs=0.05)


def test_band_limited_model_travels_to_worker_processes():
    """Pickled for a process pool, a band-limited model starts with empty bases and gives the
    same response bit for bit (the Lanczos start vector is fixed, not random)."""
    import pickle

    reduced = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    g = reduced.freqresp(F_HZ).response
    copy = pickle.loads(pickle.dumps(reduced))
    assert copy.dynamics.reducer._bases == {}
    assert copy.freqresp(F_HZ).response.tobytes() == g.tobytes()
