"""Two hidden effects in an imported FE model with property groups: an added mass and a bolted
seam softer than modelled, named as a chain by the user's default ``rc.diagnose`` call.

The model is a spring-grid membrane as two panels joined by a seam (the neighbour springs across
its middle), its ``MAA``, ``KAA`` and group partitions ``KPANEL``, ``KSEAM`` written to an OP4
file and read with ``rc.load_nastran_matrices(..., fixed_groups=["seam"])``. The truth is made
here with scipy (a sparse direct solve per frequency, structural damping), not robustctl's
simulator: 0.03 kg at one node, the panels 2 % stiffer, the seam at 45 % of its stiffness.
"""

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import robustctl as rc

pytest.importorskip("pyNastran")

NX, NY = 20, 25  # 500 DOFs: reduced by diagnose; the seam 20 springs on 40 DOFs
MASS_NODE, MASS_KG, SEAM = 103, 0.03, 0.45
INS, OUTS = [95, 337], [25, 103, 160, 215, 290, 350, 410, 475]


def _parts():
    n = NX * NY
    idx = np.arange(n).reshape(NY, NX)

    def springs(p):
        i, j = p[:, 0], p[:, 1]
        vals = 1e4 * np.concatenate([np.ones(2 * i.size), -np.ones(2 * i.size)])
        return sp.coo_matrix((vals, (np.concatenate([i, j, i, j]), np.concatenate([i, j, j, i]))),
                             shape=(n, n)).tocsr()

    pairs = np.concatenate([np.stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()], axis=1),
                            np.stack([idx[:-1, :].ravel(), idx[1:, :].ravel()], axis=1)])
    K = springs(pairs) + 50.0 * sp.identity(n, format="csr")
    Ks = springs(np.stack([idx[NY // 2 - 1], idx[NY // 2]], axis=1))
    M = sp.diags(0.1 * (1.0 + 0.3 * np.linspace(0.0, 1.0, n) ** 2)).tocsr()
    return M, K, Ks


def _truth(f_hz):
    M, K, Ks = _parts()
    M = M.tolil()
    M[MASS_NODE, MASS_NODE] += MASS_KG
    Kt = (1.02 * (K - Ks) + SEAM * Ks) * (1 + 0.02j)
    b = np.zeros((M.shape[0], 2), dtype=complex)
    b[INS, [0, 1]] = 1.0
    out = np.empty((f_hz.size, len(OUTS), 2), dtype=complex)
    for k, f in enumerate(f_hz):
        w2 = (2 * np.pi * f) ** 2
        out[k] = -w2 * spla.spsolve((Kt - w2 * M.tocsr()).tocsc(), b)[OUTS]
    return out


@pytest.mark.slow
def test_a_hidden_mass_and_a_soft_seam_are_named_as_a_chain(tmp_path):
    M, K, Ks = _parts()
    path = str(tmp_path / "panels.op4")
    rc.write_nastran_matrices(path, {"MAA": M, "KAA": K, "KPANEL": (K - Ks).tocsr(), "KSEAM": Ks})
    model = rc.load_nastran_matrices(
        path, groups={"panels": "KPANEL", "seam": "KSEAM"}, fixed_groups=["seam"],
        dof_labels=[f"{i + 1}:T3" for i in range(M.shape[0])],
        inputs={f"F{k}": f"{d + 1}:T3" for k, d in enumerate(INS)},
        outputs={f"a{k}": (f"{d + 1}:T3", "acceleration") for k, d in enumerate(OUTS)}, damping=0.01)
    f = np.linspace(2.7, 20.0, 300)
    g = _truth(f)
    rng = np.random.default_rng(1)
    g = g * np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(f, g, inputs=["F0", "F1"], outputs=[f"a{k}" for k in range(len(OUTS))])
    diag = rc.diagnose(model, data, noise=rc.NoiseModel(f, np.full(g.shape, 0.01), "1 % log noise"))
    assert diag.verdict == "answer"
    named = {c.effect.name: c.effect for c in diag.chain}
    # the seam first (it holds nearly all the misfit), then the mass on the model with it
    assert [c.effect.name for c in diag.chain] == ["stiffness change of seam",
                                                   f"added mass at node {MASS_NODE + 1}:T3"]
    # the seam leaves 2.4 x the noise, in the mass's modes; the mass brings it to 1.5 x, spread evenly
    # over the bands and channels (the truth's structural damping against the model's modal damping)
    assert diag.chain[1].dispersion_before > 2.0 > diag.chain[1].dispersion_after
    assert diag.dispersion_left == pytest.approx(diag.chain[1].dispersion_after)
    seam = named["stiffness change of seam"].values["stiffness_change__seam"]
    mass = named[f"added mass at node {MASS_NODE + 1}:T3"].values
    # sizes: the seam at SEAM / 1.02 of the fitted panels' factor, the mass within 20 %
    assert abs((1 + seam) - SEAM / 1.02) < 0.06
    assert abs(next(iter(mass.values())) - MASS_KG) < 0.2 * MASS_KG
    # the 1,500 point effects were fitted in closed form, the seam and the other effects on the model
    assert diag.screening["closed form"] >= 1400 and diag.screening["exact"] >= 1
