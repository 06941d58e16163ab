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


def test_band_limited_model_travels_to_worker_processes(monkeypatch):
    """Pickled for a process pool before any evaluation, a band-limited model starts with empty
    bases and gives the same response bit for bit (the Lanczos start vector is fixed, not random);
    pickled after one, it carries that basis without its factor (no Lanczos run on the other
    side), makes the factor again and gives the same response and low-rank change bit for bit.
    Copies of one reducer unpickled in one process are one object (a worker's payloads share it)."""
    import pickle
    import weakref

    reduced = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    fresh = pickle.loads(pickle.dumps(reduced))
    assert fresh.dynamics.reducer._bases == {}
    assert pickle.loads(pickle.dumps(reduced)).dynamics.reducer is fresh.dynamics.reducer
    g = reduced.freqresp(F_HZ).response
    assert fresh.freqresp(F_HZ).response.tobytes() == g.tobytes()
    mass = rc.effects.AddedMass("dof 58")
    g_mass = mass.apply(reduced).freqresp(F_HZ, added_mass__dof_58=0.02).response
    monkeypatch.setattr(red, "_RESTORED", weakref.WeakValueDictionary())  # as in a new process
    copy = pickle.loads(pickle.dumps(mass.apply(reduced)))
    (base,) = copy.dynamics.reducer._bases.values()
    assert base.lu is None
    calls = []
    reduce = red._reduce
    monkeypatch.setattr(red, "_reduce", lambda *a: calls.append(a) or reduce(*a))
    assert copy.freqresp(F_HZ).response.tobytes() == g.tobytes()
    assert copy.freqresp(F_HZ, added_mass__dof_58=0.02).response.tobytes() == g_mass.tobytes()
    assert not calls


def _point_candidates(model):
    """A mass, a grounded spring and a dashpot at 15 DOFs around the hidden mass, calibrated on 3-20 Hz."""
    dofs = (36, 46, 47, 48, 49, 56, 57, 58, 59, 60, 66, 67, 68, 69, 104)
    return rc.effects.calibrate(
        model, [rc.effects.AddedMass(f"dof {d}") for d in dofs]
        + [rc.effects.SuspensionSpring(f"dof {d}") for d in dofs]
        + [rc.effects.Dashpot(f"dof {d}") for d in dofs], band=(3.0, 20.0))


def _hidden_mass_data(model, dof=57, mass=0.03, seed=1):
    M, K = _grid()
    M = M.tolil()
    M[dof, dof] += mass
    truth = _numpy_frf(M.tocsr(), 1.02 * K, F_HZ)
    rng = np.random.default_rng(seed)
    g = truth * np.exp(0.01 * (rng.standard_normal(truth.shape) + 1j * rng.standard_normal(truth.shape)))
    data = rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs)
    return data, rc.NoiseModel(F_HZ, np.full(g.shape, 0.01), "known synthetic noise")


@pytest.mark.slow
def test_closed_form_screening_keeps_the_exact_ranking(monkeypatch):
    """A 200-DOF grid in reduced coordinates with 45 point candidates (masses, springs and dashpots
    around a hidden 0.03 kg mass at a sensor node): the closed-form screening with exact leaders
    gives the fitted ranking and verdicts of the exact screening of every candidate, with costs
    equal to 1e-3, and the full dense path's winner and gain within the reduction's error (0.05)."""
    import robustctl.correlate.diagnosis.screening as scr

    model = _model()
    data, noise = _hidden_mass_data(model)
    cands = _point_candidates(model)
    kw = dict(noise=noise, workers=1, n_fit=2)
    full = rc.diagnose(model, data, cands, **kw)
    reduced = red.band_limited(model, F_HZ[-1], min_dof=0)
    fast = rc.diagnose(reduced, data, cands, **kw)
    calls = []
    monkeypatch.setattr(scr, "_screen_points", lambda *a, **k: calls.append(1))
    exact = rc.diagnose(reduced, data, cands, **kw)
    assert calls  # the exact run did not use the closed form
    fitted = [r for r in fast.ranking if r.fitted]
    assert len(fitted) >= 2
    assert [r.name for r in fitted] == [r.name for r in exact.ranking if r.fitted]
    for a, b in zip(fitted, exact.ranking):
        assert a.cost == pytest.approx(b.cost, rel=1e-3)
        assert a.significant == b.significant
    assert fast.ranking[0].name == full.ranking[0].name == "added mass at dof 58"
    assert fast.ranking[0].significant
    assert fast.ranking[0].gain == pytest.approx(full.ranking[0].gain, abs=0.05)
    assert fast.n_evals < exact.n_evals


def test_point_modification_by_woodbury_equals_the_direct_solve():
    """The closed form of a rank-two change (a mass and a spring on two DOFs, with a dashpot) equals
    the direct solve of the changed reduced modal model, ``k c V (Z + U^T B U)^{-1} V^T b``, per
    frequency; with no change it is the band-limited model's response itself."""
    model = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    pm = red.point_modal(model, F_HZ, residual=False)
    assert np.max(np.abs(pm.H - model.freqresp(F_HZ).response)) <= 1e-10 * np.max(np.abs(pm.H))
    change = red.PointChange(np.array([20, 57]), np.diag([0.02, 0.0]),
                             np.array([[300.0, -300.0], [-300.0, 300.0]]), np.diag([0.0, 0.5]))
    v = 1.7
    got = pm.responses(pm.terms(change), np.array([0.0, v]))
    assert np.array_equal(got[0], pm.H)
    U = pm.V[change.dofs]
    w = 2 * np.pi * F_HZ
    for k in (0, 150, 299):
        Z = np.diag(1.0 / pm.zinv[k])
        Bk = change.stiffness - w[k] ** 2 * change.mass + 1j * w[k] * change.damping
        direct = pm.k_out[k][:, None] * (pm.cphi @ np.linalg.solve(Z + v * U.T @ Bk @ U, pm.phib))
        assert np.max(np.abs(got[1, k] - direct)) <= 1e-9 * np.max(np.abs(direct))


def test_point_modification_with_the_residual_flexibility_equals_the_direct_solve():
    """With the static residual flexibility ``R = (K - sigma M)^-1 - V (Lambda - sigma)^-1 V^T``
    (dense numpy inverse here), the closed form of a rank-two change equals the direct solve of the
    compliance ``G = V Z^-1 V^T + R`` changed by ``v B`` at ``J`` (Woodbury written out per
    frequency), and ``resid_c``, ``R_JJ`` equal ``c R`` and ``R[J, J]``."""
    model = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    pm = red.point_modal(model, F_HZ)
    base = next(reversed(model.dynamics.reducer._bases.values()))
    M, K = _grid()
    R = np.linalg.inv((K - base.sigma * M).toarray()) - (pm.V * pm._shift_inv) @ pm.V.T
    assert np.max(np.abs(R[OUTS] - pm.resid_c)) <= 1e-9 * np.max(np.abs(R[OUTS]))
    KV = (K - base.sigma * M) @ pm.V  # R is what K_sigma^-1 holds beyond the basis: R K_sigma V = 0
    assert np.max(np.abs(R[OUTS] @ KV)) <= 1e-8 * np.max(np.abs(R[OUTS])) * np.abs(KV).max()
    change = red.PointChange(np.array([20, 57]), np.diag([0.02, 0.0]),
                             np.array([[300.0, -300.0], [-300.0, 300.0]]), np.diag([0.0, 0.5]))
    change = pm.with_residuals([change])[0]
    assert np.max(np.abs(change.residual - R[np.ix_([20, 57], [20, 57])])) <= 1e-9 * np.max(np.abs(R))
    assert pm.with_residuals([red.PointChange(np.array([57]), *np.zeros((3, 1, 1)))])[0].residual[0, 0] == \
        pytest.approx(R[57, 57], rel=1e-9)
    v = 1.7
    got = pm.responses(pm.terms(change), np.array([v]))[0]
    J = change.dofs
    w = 2 * np.pi * F_HZ
    c = np.zeros((len(OUTS), M.shape[0]))
    c[np.arange(len(OUTS)), OUTS] = 1.0
    b = np.zeros((M.shape[0], len(INS)))
    b[INS, np.arange(len(INS))] = 1.0
    for k in (0, 150, 299):
        G = (pm.V * pm.zinv[k]) @ pm.V.T + R
        Bk = change.stiffness - w[k] ** 2 * change.mass + 1j * w[k] * change.damping
        Gv = G - G[:, J] @ np.linalg.solve(np.eye(2) + v * Bk @ G[np.ix_(J, J)], v * Bk @ G[J])
        direct = pm.k_out[k][:, None] * (c @ Gv @ b)
        assert np.max(np.abs(got[k] - direct)) <= 1e-9 * np.max(np.abs(direct))


def test_point_modification_with_the_residual_flexibility_is_exact_at_statics():
    """At 1 mHz (displacement outputs) a 10^4 N/m spring at a sensor node and a 3x10^4 N/m spring
    between two nodes change the response by the static flexibility of the grid, most of it above
    the cut: the closed form with the residual flexibility matches the numpy solve of the changed
    stiffness to 2e-3 of the change (3e-4 and 5e-6 seen; what is left is the reduced basis's own
    static error, a few 1e-6 of the flexibility, the shift ``sigma`` against the residual modes), the
    closed form without it misses 6 % and 34 % of the change."""
    f = np.array([1e-3])
    model = red.band_limited(_model("displacement"), F_HZ[-1], min_dof=0)
    M, K = _grid()
    j = OUTS[1]
    for dofs, dK in (([j], np.array([[1e4]])), ([20, 57], np.array([[3e4, -3e4], [-3e4, 3e4]]))):
        change = red.PointChange(np.array(dofs), np.zeros_like(dK), dK, np.zeros_like(dK))
        Kd = K.tolil()
        Kd[np.ix_(dofs, dofs)] = Kd[np.ix_(dofs, dofs)].toarray() + dK
        before = np.linalg.solve(K.toarray(), np.eye(M.shape[0])[:, INS])[OUTS]
        after = np.linalg.solve(Kd.toarray(), np.eye(M.shape[0])[:, INS])[OUTS]
        errors = []
        for residual in (True, False):
            pm = red.point_modal(model, f, residual=residual)
            got = pm.responses(pm.terms(pm.with_residuals([change])[0]), np.array([1.0]))[0, 0]
            errors.append(np.max(np.abs(got - after)) / np.max(np.abs(after - before)))
        assert errors[0] <= 2e-3
        assert errors[1] >= 0.05


def test_point_modification_follows_the_exact_structure():
    """A 0.03 kg mass and a 300 N/m spring at the sensor node of a 200-DOF grid: the closed form
    against the numpy modal sum of the changed structure (dense eigen-solution, every mode damped
    by the model's ratio) and the exact reduced evaluation (the basis augmented by the DOF's
    attachment vector). With the DOF's residual flexibility what it leaves out (the residual's
    inertia, the changed modes' damping) is within 3 % of the change; without it, over 2 % of the
    mass's (its flexibility at the sensor's own DOF)."""
    model = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    pm = red.point_modal(model, F_HZ)
    bare = red.point_modal(model, F_HZ, residual=False)
    struct = model.build_structure()
    mats = struct.matrices()
    M, K = _grid()
    base = _numpy_frf(M, K, F_HZ)
    j = OUTS[1]
    for effect, value in ((rc.effects.AddedMass(f"dof {j + 1}"), 0.03),
                          (rc.effects.SuspensionSpring(f"dof {j + 1}"), 300.0)):
        change = red.point_change(effect, model, struct, mats)
        assert change.dofs.tolist() == [j]
        got = pm.responses(pm.terms(pm.with_residuals([change])[0]), np.array([value]))[0]
        Md, Kd = M.tolil(), K.tolil()
        (Md if effect.kind == "added_mass" else Kd)[j, j] += value
        truth = _numpy_frf(Md.tocsr(), Kd.tocsr(), F_HZ)
        exact = effect.apply(model).freqresp(F_HZ, **{effect.param_names[0]: value}).response
        assert np.max(np.abs(got - truth)) <= 0.03 * np.max(np.abs(truth - base))
        assert np.max(np.abs(got - exact)) <= 0.03 * np.max(np.abs(exact - base))
        if effect.kind == "added_mass":
            without = bare.responses(bare.terms(change), np.array([value]))[0]
            assert np.max(np.abs(without - exact)) >= 0.02 * np.max(np.abs(exact - base))


def test_a_reduction_is_reused_for_a_stiffness_scale_and_not_for_a_softer_structure():
    """A uniform stiffness scale keeps the mode shapes: the reducer reuses the nominal reduction
    (no Lanczos run) and gives a fresh reduction's response; a softer structure brings modes into
    the cut that the old basis lacks, so its reduction is made anew."""
    model = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    model.freqresp(F_HZ)
    reducer = model.dynamics.reducer
    f_cut = reducer.f_cut_hz
    lam_cut = (2 * np.pi * f_cut) ** 2
    base = next(iter(reducer._bases.values()))
    stiffer = model.build_structure(k_scale=1.05).matrices()
    reused = red._reuse(base, stiffer, lam_cut)
    fresh = red._reduce(stiffer, f_cut)
    assert reused is not None and reused.n_exact == fresh.n_exact
    assert np.allclose(reused.lam[: reused.n_exact], fresh.lam[: fresh.n_exact], rtol=1e-10)
    g_reused = model.freqresp(F_HZ, k_scale=1.05).response
    fresh_model = red.band_limited(_model().with_values(k_scale=1.05), F_HZ[-1], min_dof=0)  # its own root
    g_fresh = fresh_model.freqresp(F_HZ).response
    assert np.max(np.abs(g_reused - g_fresh)) <= 1e-8 * np.max(np.abs(g_fresh))
    assert red._reuse(base, model.build_structure(k_scale=0.8).matrices(), lam_cut) is None


def test_a_scaled_structure_with_a_point_change_is_a_low_rank_change_of_its_scaled_reduction(monkeypatch):
    """An update parameter and a candidate in one fit (a stiffness scale and an added mass): no new
    Lanczos run, and the response of a reducer that reduced the scaled structure first."""
    effect = rc.effects.AddedMass("dof 58")
    point = {"k_scale": 1.03, "added_mass__dof_58": 0.02}
    other = effect.apply(red.band_limited(_model(), F_HZ[-1], min_dof=0))
    other.freqresp(F_HZ, k_scale=1.03)
    expected = other.freqresp(F_HZ, **point).response
    model = effect.apply(red.band_limited(_model(), F_HZ[-1], min_dof=0))
    model.freqresp(F_HZ)
    calls = []
    reduce = red._reduce
    monkeypatch.setattr(red, "_reduce", lambda *a: calls.append(a) or reduce(*a))
    got = model.freqresp(F_HZ, **point).response
    assert not calls
    assert np.max(np.abs(got - expected)) <= 1e-9 * np.max(np.abs(expected))


@pytest.mark.slow
def test_first_order_prescreen_equals_the_closed_forms_derivative(monkeypatch):
    """The prescreen's share of each point effect (its first-order direction, two matrix products
    per block of DOFs) equals the share of the closed form's residual derivative by a central
    difference at 1e-7 of its typical size, to 1e-5; the 40 it leaves out carry that share, and
    the 5 it keeps include the hidden mass, which still ranks first."""
    import robustctl.correlate.diagnosis.screening as scr

    model = _model()
    data, noise = _hidden_mass_data(model)
    cands = _point_candidates(model)
    seen = []
    real = scr._prescreen

    def spy(shared, items, keep):
        out = real(shared, items, keep)
        seen.append((shared, items, out))
        return out

    monkeypatch.setattr(scr, "PRESCREEN_MIN", 10)
    monkeypatch.setattr(scr, "PRESCREEN_KEEP", 5)
    monkeypatch.setattr(scr, "_prescreen", spy)
    reduced = red.band_limited(model, F_HZ[-1], min_dof=0)
    diag = rc.diagnose(reduced, data, cands, noise=noise, workers=1, n_fit=2)
    assert diag.ranking[0].name == "added mass at dof 58"
    shared, items, (kept, rest) = seen[0]
    assert len(kept) == 5 and len(rest) == 40
    assert "added mass at dof 58" in [it[1].name for it in kept]
    r = shared["r_perp"]
    Q = shared["Q"]
    for k, effect, change in items:
        h = 1e-7 * float(effect.typical_size)
        j = scr._point_vectors(shared, shared["pm"].terms(change), np.array([h, -h]))
        d = scr._project(Q, (j[0] - j[1]) / (2 * h))
        want = float(d @ r) ** 2 / (float(d @ d) * float(r @ r))
        if k in rest:
            assert rest[k]["fraction"] == pytest.approx(want, rel=1e-5, abs=1e-12)
            assert rest[k]["first_order"]
        else:
            assert want >= max(sc["fraction"] for sc in rest.values()) * (1 - 1e-5)


def test_a_slightly_softer_structure_extends_the_reduction_by_the_modes_that_came_in(monkeypatch):
    """A 7 % softer grid brings two modes into the cut: the reducer keeps the nominal modes (made
    eigenpairs by Rayleigh-Ritz), finds the new ones by one Lanczos run about the middle of the
    gap, and gives a fresh reduction's modes (to 1e-9) and response (to 1e-8) without reducing
    anew; a 30 % softer one (too many new modes) is reduced anew."""
    model = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    model.freqresp(F_HZ)
    reducer = model.dynamics.reducer
    lam_cut = (2 * np.pi * reducer.f_cut_hz) ** 2
    base = next(iter(reducer._bases.values()))
    softer = model.build_structure(k_scale=0.93).matrices()
    assert red._reuse(base, softer, lam_cut) is None
    ext = red._extend(base, softer, lam_cut)
    fresh = red._reduce(softer, reducer.f_cut_hz)
    assert ext is not None and ext.n_exact == fresh.n_exact > base.n_exact
    assert np.allclose(ext.lam[: ext.n_exact], fresh.lam[: fresh.n_exact], rtol=1e-9)
    calls = []
    reduce = red._reduce
    monkeypatch.setattr(red, "_reduce", lambda *a: calls.append(a) or reduce(*a))
    got = model.freqresp(F_HZ, k_scale=0.93).response
    assert not calls
    want = red.band_limited(_model().with_values(k_scale=0.93), F_HZ[-1], min_dof=0).freqresp(F_HZ).response
    assert np.max(np.abs(got - want)) <= 1e-8 * np.max(np.abs(want))
    assert red._extend(base, model.build_structure(k_scale=0.7).matrices(), lam_cut) is None


def test_a_scaled_structure_with_masses_at_ten_dofs_skips_the_ritz_step_it_would_reject(monkeypatch):
    """A transducer mass at 10 DOFs with a stiffness scale (an update parameter and a candidate in
    one fit): a low-rank change of the scaled structure's reduction, found without a Lanczos run
    and without a Rayleigh-Ritz step (the scaled structure's reduction is the base's, scaled; the
    changed structure's own Ritz step would be rejected), and its response within the reduction's
    error of the dense numpy truth."""
    mounts = tuple(f"dof {d}" for d in (3, 21, 40, 58, 77, 99, 121, 140, 166, 195))
    effect = rc.effects.TransducerMass(location="sensors", mounts=mounts)
    model = effect.apply(red.band_limited(_model(), F_HZ[-1], min_dof=0))
    model.freqresp(F_HZ)
    reduces, ritz = [], []
    reduce, ritz_step = red._reduce, red._ritz
    monkeypatch.setattr(red, "_reduce", lambda *a: reduces.append(a) or reduce(*a))
    monkeypatch.setattr(red, "_ritz", lambda *a: ritz.append(a) or ritz_step(*a))
    point = {"k_scale": 1.03, effect.param_names[0]: 0.01}
    got = model.freqresp(F_HZ, **point).response
    assert not reduces and not ritz
    M, K = _grid()
    M = M.tolil()
    for m in mounts:
        d = int(m.split()[1]) - 1
        M[d, d] += 0.01
    truth = _numpy_frf(M.tocsr(), 1.03 * K, F_HZ)
    # the band-limited model's error (modes to 3x the band's top, residual modes for the rest):
    # 2.9e-4 of the peak here
    assert np.max(np.abs(got - truth)) <= 2e-3 * np.max(np.abs(truth))


def _seam_grid(nx=20, ny=20):
    """A 400-DOF grid as two panels and a seam: the springs crossing its middle (40 DOFs), their
    stiffness ``Ks`` a property group of its own."""
    n = nx * ny
    idx = np.arange(n).reshape(ny, nx)
    pairs = np.concatenate([
        np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1),
        np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], axis=1),
    ])

    def springs(p):
        i, j = p[:, 0], p[:, 1]
        vals = 1e4 * np.concatenate([np.ones(2 * i.size), -np.ones(2 * i.size)])
        rows, cols = np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i])
        return sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()

    K = springs(pairs) + 50.0 * sp.identity(n, format="csr")
    Ks = springs(np.stack([idx[ny // 2 - 1], idx[ny // 2]], axis=1))
    M = sp.diags(0.1 * (1.0 + 0.3 * np.linspace(0.0, 1.0, n) ** 2)).tocsr()
    ins, outs = [85, 263], [30, 117, 182, 250, 388]
    model = rc.physical.fe_model.fe_structural_model(
        M, K, groups={"panels": K - Ks, "seam": Ks}, fixed_groups=["seam"],
        dof_labels=[f"{i + 1}:T3" for i in range(n)],
        inputs={f"F{k}": f"{d + 1}:T3" for k, d in enumerate(ins)},
        outputs={f"y{k}": (f"{d + 1}:T3", "acceleration") for k, d in enumerate(outs)},
        damping=ZETA, name="seam grid")
    return model, M, K, Ks, ins, outs


def test_a_group_change_is_a_low_rank_change_with_its_attachment_vectors_made_once(monkeypatch):
    """A seam softened by half (a group of 40 DOFs, over :data:`LOW_RANK_MAX_DOFS`): no new Lanczos
    run for any of its sizes, the attachment vectors of its DOFs solved once, and each size's
    response within 0.5 % of each channel's peak of the truth (numpy: dense eigen-solution of the
    changed structure, modal sum) -- as close as a fresh reduction of the changed structure."""
    model, M, K, Ks, ins, outs = _seam_grid()
    reduced = red.band_limited(model, F_HZ[-1], min_dof=0)
    reduced.freqresp(F_HZ)  # the base reduction
    calls, solves = [], []
    reduce, attach = red._reduce, red._m_orthonormal
    monkeypatch.setattr(red, "_reduce", lambda *a: calls.append(a) or reduce(*a))
    monkeypatch.setattr(red, "_m_orthonormal", lambda *a, **k: solves.append(a) or attach(*a, **k))
    seam = rc.effects.GroupStiffness("seam")
    changed = seam.apply(reduced)
    pname = seam.param_names[0]
    for c in (-0.5, 0.3):
        got = changed.freqresp(F_HZ, **{pname: c}).response
        lam, phi = sla.eigh((K + c * Ks).toarray(), M.toarray())
        wk, w = np.sqrt(lam), 2 * np.pi * F_HZ[:, None]
        truth = np.einsum("fk,ok,ik->foi", -(w**2) / (wk**2 - w**2 + 2j * ZETA * wk * w), phi[outs], phi[ins])
        err = np.max(np.abs(got - truth) / np.abs(truth).max(axis=0))
        # a fresh reduction of the changed structure: the root of a band-limited model at its values
        fresh = red.band_limited(seam.apply(model).with_values(**{pname: c}), F_HZ[-1], min_dof=0)
        fresh = fresh.freqresp(F_HZ).response
        err_fresh = np.max(np.abs(fresh - truth) / np.abs(truth).max(axis=0))
        assert err < 5e-3 and err < 2.0 * err_fresh + 1e-6
        # the change moves the response far more than the error: a real test of the route
        base = reduced.freqresp(F_HZ).response
        assert np.max(np.abs(base - truth) / np.abs(truth).max(axis=0)) > 20 * err
    assert len(calls) == 2  # the two fresh reductions of the check, none for the group change
    # one attachment block for the seam's 40 DOFs, reused at every size (the others: the fresh ones')
    assert len(solves) == 1 + len(calls)
    dofs = reduced.dynamics.reducer.basis_and_dofs(changed.build_structure(**{pname: -0.5}).matrices())[1][0]
    assert dofs.size == 40


def test_fixed_groups_are_left_to_the_diagnosis():
    """``fixed_groups`` keeps a group's factor out of the update (not free) and diagnose's default
    candidates check it (``stiffness change of seam``); an unknown group is refused."""
    model = _seam_grid()[0]
    free = {p.name: p.free for p in model.params}
    assert free["k_panels"] and not free["k_seam"]
    names = [c.name for c in rc.effects.candidates(model, band=(3.0, 20.0), points=False, calibrate=False)]
    assert "stiffness change of seam" in names
    M, K = sp.identity(4, format="csr"), 2.0 * sp.identity(4, format="csr")
    with pytest.raises(rc.DataError, match="fixed_groups"):
        rc.physical.fe_model.fe_structural_model(M, K, groups={"a": K}, fixed_groups=["b"], inputs=[],
                                                 outputs=[])


def _seam_truth(M, K, f_hz, ins, outs):
    """Acceleration FRF of ``(M, K)`` by a dense generalised eigen-solution and the modal sum (numpy)."""
    lam, phi = sla.eigh(K.toarray(), M.toarray())
    wk, w = np.sqrt(lam), 2 * np.pi * f_hz[:, None]
    return np.einsum("fk,ok,ik->foi", -(w**2) / (wk**2 - w**2 + 2j * ZETA * wk * w), phi[outs], phi[ins])


def test_a_group_factor_beside_a_group_change_reuses_the_reduction_and_its_attachment_blocks(monkeypatch):
    """``k_panels`` stepped beside a softened seam (an update parameter and the seam's candidate in
    one fit: ``K = K0 + dk (K0 - Ks) + c Ks``, a scale of ``K0`` plus a change on the seam's 40 DOFs):
    no Lanczos run, Rayleigh-Ritz step or attachment solve for any of three steps (up and down, one
    lifting modes over the cut), and each response within 0.5 % of each channel's peak of the dense
    numpy truth and within twice a fresh reduction's error."""
    model, M, K, Ks, ins, outs = _seam_grid()
    seam = rc.effects.GroupStiffness("seam")
    pname = seam.param_names[0]
    changed = seam.apply(red.band_limited(model, F_HZ[-1], min_dof=0))
    changed.freqresp(F_HZ)  # the base reduction
    changed.freqresp(F_HZ, **{pname: -0.5})  # the seam's attachment blocks
    calls = []
    for name in ("_reduce", "_ritz", "_m_orthonormal"):
        real = getattr(red, name)
        monkeypatch.setattr(red, name,
                            lambda *a, real=real, name=name, **k: calls.append(name) or real(*a, **k))
    truths, got = {}, {}
    for kp in (1.04, 0.99, 1.3):
        got[kp] = changed.freqresp(F_HZ, k_panels=kp, **{pname: -0.5}).response
    assert not calls
    reducer = changed.dynamics.reducer
    lam_cut = (2 * np.pi * reducer.f_cut_hz) ** 2
    assert any(b.lam[: b.n_exact].max() > lam_cut for b in reducer._bases.values())  # a mode over the cut
    monkeypatch.undo()
    for kp in (1.04, 0.99, 1.3):
        truths[kp] = _seam_truth(M, K + (kp - 1.0) * (K - Ks) - 0.5 * Ks, F_HZ, ins, outs)
        peak = np.abs(truths[kp]).max(axis=0)
        err = np.max(np.abs(got[kp] - truths[kp]) / peak)
        fresh = red.band_limited(seam.apply(model).with_values(k_panels=kp, **{pname: -0.5}), F_HZ[-1],
                                 min_dof=0)  # a fresh reduction of the changed structure (its root)
        g_fresh = fresh.freqresp(F_HZ).response
        err_fresh = np.max(np.abs(g_fresh - truths[kp]) / peak)
        assert err < 5e-3 and err < 2.0 * err_fresh + 1e-6
        # the step moves the response far more than the error: the scale is really applied
        assert np.max(np.abs(got[kp] - got[0.99 if kp != 0.99 else 1.04]) / peak) > 20 * err


def test_a_scaled_reduction_is_the_scaled_structures_own():
    """The reduction of ``1.1 M0``, ``1.3 K0`` plus a seam change (the scales and the change found by
    ``_scale_split``) read off the base's (no solve): its
    exact modes are the dense eigenpairs of the scaled pencil (to 1e-9, M-orthonormal), and the
    seam's change on it with the base's attachment blocks scaled gives the same reduced model
    (eigenvalues and the transfer function at three frequencies, to 1e-8) as attachment vectors
    solved anew on the scaled basis; a scale that lets modes in below the cut is refused."""
    from dataclasses import replace

    model, M, K, Ks, ins, outs = _seam_grid()
    seam = rc.effects.GroupStiffness("seam")
    changed = seam.apply(red.band_limited(model, F_HZ[-1], min_dof=0))
    changed.freqresp(F_HZ)  # the base reduction
    changed.freqresp(F_HZ, **{seam.param_names[0]: -0.5})  # the seam's attachment blocks
    reducer = changed.dynamics.reducer
    lam_cut = (2 * np.pi * reducer.f_cut_hz) ** 2
    base = next(iter(reducer._bases.values()))
    assert base.attached  # the seam's blocks
    mats0 = changed.build_structure().matrices()
    mats = replace(mats0, mass=1.1 * mats0.mass, stiffness=(1.3 * K - 0.6 * Ks).tocsr())
    a_m, a_k, change = red._scale_split(base, mats)
    assert a_m == pytest.approx(1.1, rel=1e-14) and a_k == pytest.approx(1.3, rel=1e-14)
    assert change[0].size == 40
    assert np.allclose(change[1][1], -0.6 * Ks.toarray()[np.ix_(change[0], change[0])], rtol=1e-12, atol=1e-9)
    sb = red._scaled_basis(base, a_m, a_k, change[0].size <= red.LOW_RANK_MAX_DOFS, lam_cut)
    assert sb is not None and sb.n_exact == base.n_exact
    lam, phi = sla.eigh(1.3 * K.toarray(), 1.1 * M.toarray())
    n = sb.n_exact
    assert np.allclose(sb.lam[:n], lam[:n], rtol=1e-9)
    Ve = sb.V[:, :n]
    assert np.allclose(Ve.T @ (1.1 * M) @ Ve, np.eye(n), atol=1e-9)
    assert np.max(np.abs(1.3 * K @ Ve - 1.1 * M @ Ve * sb.lam[:n])) < 1e-7 * np.max(np.abs(1.3 * K @ Ve))

    def frf(basis):
        md = red._ritz_modal(basis, mats, change)
        w2 = (2 * np.pi * np.array([5.0, 11.0, 17.0])) ** 2
        return md.omega, np.einsum("ok,fk,ki->foi", md.output_shapes, 1.0 / (md.omega**2 - w2[:, None]),
                                   md.input_shapes)

    om_scaled, h_scaled = frf(sb)
    om_new, h_new = frf(replace(sb, attached=None, scale=None))  # the seam's attachment vectors solved on sb
    assert np.allclose(om_scaled, om_new, rtol=1e-8)
    assert np.max(np.abs(h_scaled - h_new)) < 1e-8 * np.max(np.abs(h_new))
    # softer by half: modes come into the cut that the base lacks
    softer = replace(mats0, stiffness=(0.5 * K).tocsr())
    a_m, a_k, change = red._scale_split(base, softer)
    assert (a_m, a_k, change[0].size) == (1.0, 0.5, 0)
    assert red._scaled_basis(base, a_m, a_k, True, lam_cut) is None


def _top_half_model():
    """The 200-DOF grid with the stiffness of its upper half scaled by ``k_top`` (an update parameter
    that is no scale of the whole structure: 100 DOFs change, over :func:`red._max_changed`)."""
    M, K = _grid()
    n = M.shape[0]
    top = sp.diags((np.arange(n) >= n // 2).astype(float))
    K_top = (top @ K @ top).tocsr()
    par = rc.Parameter("k_top", 1.0, "", (0.5, 2.0), meaning="stiffness scale of the upper half")
    model = rc.structural_model(
        M, lambda th: K + (th["k_top"] - 1.0) * K_top,
        inputs={f"F{k}": f"dof {d + 1}" for k, d in enumerate(INS)},
        outputs={f"y{k}": (f"dof {d + 1}", "acceleration") for k, d in enumerate(OUTS)},
        damping=ZETA, params=[par], name="grid, upper half")
    return model, M, K, K_top


def test_an_evaluation_does_not_depend_on_the_evaluations_before_it(monkeypatch):
    """A band-limited model's response at a parameter point is the same bit for bit whatever the
    reducer evaluated before (other stiffness scales, softer ones that need a new reduction, other
    candidates and sizes, more points than it keeps bases for) and in a copy unpickled as in a worker
    process: a candidate on a stiffer and on a softer structure (extension, a rung of the ladder), a
    moved sensor (new outputs) and, on a model whose update parameter is no scale, a candidate made
    a change of its anchor's reduction (one Lanczos run for the anchor, none per size), within the
    reduction's error of the dense numpy truth, and a resonator (a DOF added) on a reduction of its
    own at a rung of sizes, within 1e-3 of the full path."""
    import pickle
    import weakref

    mass = rc.effects.AddedMass("dof 58")
    spring = rc.effects.SuspensionSpring("dof 48")
    moved = rc.effects.SensorMoved("y1", to="dof 59", moved=1.0)
    pm, ps = mass.param_names[0], spring.param_names[0]
    points = [(mass, {"k_scale": 1.03, pm: 0.02}), (mass, {"k_scale": 0.93, pm: 0.02}),
              (mass, {"k_scale": 0.6, pm: 0.01}), (None, {"k_scale": 0.7}), (moved, {"k_scale": 1.03}),
              (None, {"k_scale": 1.03})]
    others = [(spring, {"k_scale": 1.2, ps: 500.0}), (None, {"k_scale": 0.8}),
              (mass, {"k_scale": 0.55, pm: 0.03}), (spring, {"k_scale": 0.96, ps: 100.0}),
              (None, {"k_scale": 1.5}), (mass, {"k_scale": 1.03, pm: 0.05}), (moved, {"k_scale": 0.9}),
              (None, {"k_scale": 1.1}), (spring, {"k_scale": 1.03, ps: 1e3})]

    def run(base, seq):
        return [(base if e is None else e.apply(base)).freqresp(F_HZ, **v).response for e, v in seq]

    first = run(red.band_limited(_model(), F_HZ[-1], min_dof=0), points)
    busy = red.band_limited(_model(), F_HZ[-1], min_dof=0)
    run(busy, others)  # more scales than the reducer keeps bases for: some are dropped and made again
    mixed = []
    for k, p in enumerate(points[::-1]):  # the points in reverse, two other evaluations before each
        run(busy, others[k:k + 2])
        mixed.insert(0, run(busy, [p])[0])
    monkeypatch.setattr(red, "_RESTORED", weakref.WeakValueDictionary())  # as in a new process
    copy = pickle.loads(pickle.dumps(busy))
    shipped = run(copy, points)
    for a, b, c in zip(first, mixed, shipped):
        assert a.tobytes() == b.tobytes() == c.tobytes()
    M, K = _grid()
    M = M.tolil()
    M[57, 57] += 0.02
    truth = _numpy_frf(M.tocsr(), 0.93 * K, F_HZ)
    assert np.max(np.abs(first[1] - truth)) <= 2e-3 * np.max(np.abs(truth))

    # an update parameter that is no scale: the candidate is a change of its anchor's own reduction
    model, M, K, K_top = _top_half_model()
    calls = []
    reduce = red._reduce
    monkeypatch.setattr(red, "_reduce", lambda *a: calls.append(a) or reduce(*a))
    cand = mass.apply(red.band_limited(model, F_HZ[-1], min_dof=0))
    g = {v: cand.freqresp(F_HZ, k_top=1.1, **{pm: v}).response for v in (0.01, 0.02, 0.03)}
    assert len(calls) == 2  # the root and the anchor (k_top = 1.1 without the mass)
    again = mass.apply(red.band_limited(model, F_HZ[-1], min_dof=0))
    again.freqresp(F_HZ, k_top=1.2, **{pm: 0.04})
    for v in (0.03, 0.01, 0.02):
        assert again.freqresp(F_HZ, k_top=1.1, **{pm: v}).response.tobytes() == g[v].tobytes()
    M = M.tolil()
    M[57, 57] += 0.02
    truth = _numpy_frf(M.tocsr(), K + 0.1 * K_top, F_HZ)
    assert np.max(np.abs(g[0.02] - truth)) <= 2e-3 * np.max(np.abs(truth))

    # an effect that adds a DOF (a resonator): a change of its own reduction at the sizes rounded
    # down to a power of two (0.02 and 0.03 kg share the rung 2**-6 kg), within 1e-3 of the full path
    res = rc.effects.AttachedResonator("dof 58", frequency=8.0)
    rm, rf = res.param_names
    calls.clear()
    sizes = (0.02, 0.03, 0.05)
    cand = res.apply(red.band_limited(_model(), F_HZ[-1], min_dof=0))
    g = {m: cand.freqresp(F_HZ, k_scale=1.03, **{rm: m, rf: 8.2}).response for m in sizes}
    assert len(calls) == 3  # the root, the rungs 2**-6 and 2**-5 kg
    again = res.apply(red.band_limited(_model(), F_HZ[-1], min_dof=0))
    for m in sizes[::-1]:
        assert again.freqresp(F_HZ, k_scale=1.03, **{rm: m, rf: 8.2}).response.tobytes() == g[m].tobytes()
    full = res.apply(_model()).freqresp(F_HZ, k_scale=1.03, **{rm: 0.03, rf: 8.2}).response
    assert np.max(np.abs(g[0.03] - full)) <= 1e-3 * np.max(np.abs(full))


def test_diagnose_in_a_process_pool_equals_the_serial_diagnosis_bit_for_bit():
    """rc.diagnose of a band-limited model (30 point candidates around a hidden mass: masses and
    grounded springs at 15 DOFs) gives the same ranking and costs, bit for bit, serially, in two
    threads and in a pool of two worker processes (each process evaluates other points in another
    order)."""
    from concurrent.futures import ThreadPoolExecutor

    import robustctl.executors as ex

    model = _model()
    data, noise = _hidden_mass_data(model)
    cands = _point_candidates(model)[:30]

    def diag(**kw):
        d = rc.diagnose(red.band_limited(model, F_HZ[-1], min_dof=0), data, cands, noise=noise, **kw)
        return [(r.name, r.cost, r.fraction, r.fitted, r.significant) for r in d.ranking]

    serial = diag(workers=1)
    with ThreadPoolExecutor(2) as pool:
        threads = diag(executor=pool)
    with ex.process_pool(2, 100, 1) as pool:
        assert pool is not None
        procs = diag(executor=pool)
    assert serial == threads == procs
    assert serial[0][0] == "added mass at dof 58"
