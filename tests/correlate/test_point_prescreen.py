"""The misfit-guided location screen of diagnose's point effects (``screening._prescreen``: each
location's first-order share of the misfit, from the reduced modes' amplitudes there) keeps the
location of the hidden effect on structures, sizes and places it was not tuned on.

The data are the truth's exact FRF made here with numpy (dense generalised eigen-solution and
modal sum), not robustctl's simulator; the screen runs on diagnose's own residual after the null
fit of the update parameters, with its keep count lowered so that it drops 95 % of the locations.
"""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

import robustctl as rc
from benchmarks.scale_cases import grid_matrices
from robustctl.budget import Deadline
from robustctl.correlate.diagnosis import screening as scr
from robustctl.correlate.diagnosis.results import DECOUPLED_DB
from robustctl.correlate.diagnosis.workers import _evaluated
from robustctl.correlate.residual import check_data

ZETA = 0.01


def _chain(n):
    """A 1-D chain of ``n`` masses (0.1 kg, a gentle gradient) on springs of 1e4 N/m, each grounded
    by 50 N/m."""
    i = np.arange(n - 1)
    K = sp.coo_matrix((1e4 * np.concatenate([np.ones(2 * i.size), -np.ones(2 * i.size)]),
                       (np.concatenate([i, i + 1, i, i + 1]), np.concatenate([i, i + 1, i + 1, i]))),
                      shape=(n, n)).tocsr() + 50.0 * sp.identity(n, format="csr")
    M = sp.diags(0.1 * (1.0 + 0.3 * np.linspace(0.0, 1.0, n) ** 2)).tocsr()
    return M, K


def _screened(M, K, ins, outs, truth_dof, f_hz, kind="mass", size=0.03, seed=0):
    """The point screens of diagnose's default point candidates on the model (M, K) against data
    of the truth (``size`` kg, N/m or N s/m at ``truth_dof``, a 2 % stiffness error), and the
    truth's candidate name."""
    n = M.shape[0]
    Mt, Kt = M.toarray(), 1.02 * K.toarray()
    Ct = np.zeros((n, n))
    {"mass": Mt, "spring": Kt, "dashpot": Ct}[kind][truth_dof, truth_dof] += size
    lam, phi = sla.eigh(Kt, Mt)
    wk, w = np.sqrt(lam), 2 * np.pi * f_hz[:, None]
    cmod = phi.T @ Ct @ phi
    g = np.empty((f_hz.size, len(outs), len(ins)), dtype=complex)
    for f, wf in enumerate(w[:, 0]):  # modal damping ZETA plus the dashpot's modal damping matrix
        Z = np.diag(wk**2 - wf**2 + 2j * ZETA * wk * wf) + 1j * wf * cmod
        g[f] = -(wf**2) * phi[outs] @ np.linalg.solve(Z, phi[ins].T)
    rng = np.random.default_rng(seed)
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(f_hz, g, inputs=[f"F{k}" for k in range(len(ins))],
                            outputs=[f"a{k}" for k in range(len(outs))])
    noise = rc.NoiseModel(f_hz, np.full(g.shape, 0.01), "1 % log noise")
    par = rc.Parameter("k_scale", 1.0, "", (0.5, 2.0), meaning="stiffness scale")
    model = rc.structural_model(
        M, lambda th: th["k_scale"] * K, inputs={f"F{k}": f"dof {d + 1}" for k, d in enumerate(ins)},
        outputs={f"a{k}": (f"dof {d + 1}", "acceleration") for k, d in enumerate(outs)},
        damping=ZETA, params=[par], name="structure")
    checked = check_data(data, None, noise, None)
    model = _evaluated(model, checked.full, checked.band)
    res0, _ = scr._residual(model, checked, "auto", DECOUPLED_DB)
    null, _ = scr._null_fit(res0, ("k_scale",), 10, None, Deadline(None), res0.vector())
    model_u = model.with_values(**null.x)
    res_u = scr._residual_for(res0, model_u)
    cands = rc.effects.candidates(model, band=res0.band, kinds=["added_mass", "suspension_spring", "dashpot"])
    out = scr._screen_points(res_u, model_u, null, scr._project(null.Q, null.j), cands, None, Deadline(None))
    word = {"mass": "added mass", "spring": "suspension spring", "dashpot": "dashpot"}[kind]
    return out, cands, f"{word} at dof {truth_dof + 1}"


def _check_kept(out, cands, truth):
    k_truth = next(k for k, c in enumerate(cands) if c.name == truth)
    stages = [out[k]["stage"] for k in out]
    n_dropped = stages.count("first order")
    assert n_dropped > 0.9 * len(stages)  # the screen did drop most locations
    assert out[k_truth]["stage"] == "closed form"  # the truth's location was kept ...
    best = max(out, key=lambda k: out[k]["fraction"])
    assert best == k_truth  # ... and it is the best screened candidate
    return n_dropped


@pytest.fixture
def tight(monkeypatch):
    monkeypatch.setattr(scr, "PRESCREEN_MIN", 0)
    monkeypatch.setattr(scr, "PRESCREEN_KEEP", 45)


@pytest.mark.parametrize("seed", [0, 3])
def test_the_screen_keeps_a_mass_on_a_one_dimensional_chain(tight, seed):
    """A 300-DOF chain, the mass at node 131; two noise seeds."""
    M, K = _chain(300)
    f = np.linspace(3.0, 12.0, 160)
    out, cands, truth = _screened(M, K, [37, 211], [20, 90, 150, 190, 240, 290], 130, f, seed=seed)
    _check_kept(out, cands, truth)


def test_the_screen_keeps_a_spring_on_a_grid_of_another_size(tight):
    M, K = grid_matrices(15, 24)  # 360 DOFs
    f = np.linspace(3.0, 14.0, 240)
    out, cands, truth = _screened(M, K, [50, 271], [16, 80, 140, 200, 260, 330], 188, f, kind="spring",
                                  size=300.0)
    _check_kept(out, cands, truth)


def test_the_screen_keeps_a_mass_where_the_modes_are_small(tight):
    """The mass at the node where the band's modes have the smallest amplitude of those whose
    largest modal kinetic energy is at least a tenth of the chain's largest."""
    M, K = _chain(300)
    f = np.linspace(3.0, 12.0, 160)
    lam, phi = sla.eigh(K.toarray(), M.toarray())
    wk = np.sqrt(lam) / (2 * np.pi)
    band = phi[:, (wk > 3.0) & (wk < 12.0)]
    energy = (band**2).max(axis=1)
    j = int(np.argmin(np.where(energy > 0.1 * energy.max(), energy, np.inf)))  # smallest above 10 %
    out, cands, truth = _screened(M, K, [37, 211], [20, 90, 150, 190, 240, 290], j, f, size=0.08)
    _check_kept(out, cands, truth)
