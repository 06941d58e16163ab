"""The Caltech truss after its update: a design on the update's real mode blocks plus a
remainder cover (A) against the complex-cover design (B) at the same performance weight."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import robustctl as rc
from robustctl import examples as ex
from robustctl.lti import freqresp_array

pytestmark = pytest.mark.slow

N_TRUTHS = 500
#: Performance weight gain in the band: robust stability and performance are reachable (mu about 0.9),
#: so the guaranteed scale is informative (at ModelCoverRecipe's 0.5 robust stability fails for both
#: designs, mu 1.3-1.7, and the guaranteed scale is 0 for both)
LEVEL = 0.1


def closed_loop_poles(G, K) -> np.ndarray:
    """Poles of ``u = K y``, ``y = G u`` from the state-space matrices (numpy only)."""
    A, B, C, D = (np.asarray(x, float) for x in (G.A, G.B, G.C, G.D))
    Ak, Bk, Ck, Dk = (np.asarray(x, float) for x in (K.A, K.B, K.C, K.D))
    E = np.linalg.inv(np.eye(Dk.shape[0]) - Dk @ D)
    Acl = np.block([[A + B @ E @ Dk @ C, B @ E @ Ck],
                    [Bk @ (C + D @ E @ Dk @ C), Ak + Bk @ D @ E @ Ck]])
    return np.linalg.eigvals(Acl)


@pytest.fixture(scope="module")
def comparison():
    data, _truth = ex.caltech_truss_experiment(seed=0)
    model = ex.caltech_truss()
    diag = rc.diagnose(model, data, band=(0.5, 50.0))
    upd = rc.update(model.with_effect(diag.best), data, band=(0.5, 50.0), progress=False)
    plants = ex.caltech_parametric_plants(upd, data, n_sigma=3.0, level=LEVEL)
    G0 = plants.uncertain.nominal
    # two copies of the nominal: the yardstick's recipe tells the designs apart by the object
    GA, GB = (rc.as_statespace(G0).__class__(G0.A, G0.B, G0.C, G0.D, inputs=list(G0.input_labels),
                                             outputs=list(G0.output_labels)) for _ in range(2))

    def recipe(g):
        return plants.parametric if g is GA else plants.complex

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.YardstickWarning)
        yard = rc.yardstick(data, {"A": GA, "B": GB}, recipe, reference="B", max_iter=3, band=(0.8, 6.0),
                            progress=False)
    return data, upd, plants, yard


def test_modes_lft_ranges_match_an_independent_eigen_sensitivity(comparison):
    _, upd, plants, _ = comparison
    um = plants.uncertain
    names, x, cov = upd.fit.names, np.asarray(upd.fit.x_array), np.asarray(upd.fit.covariance)
    sd = np.sqrt(np.diag(cov))

    def pq(values):
        lam = np.linalg.eigvals(np.asarray(upd.model.with_values(**values).statespace().A))
        return lam

    J = []
    for j in range(len(names)):
        hi, lo = x.copy(), x.copy()
        hi[j] += sd[j]
        lo[j] -= sd[j]
        lh, ll = pq(dict(zip(names, hi))), pq(dict(zip(names, lo)))
        rows = []
        for l0, _u, _h in um.modes:
            a, b = lh[np.argmin(np.abs(lh - l0))], ll[np.argmin(np.abs(ll - l0))]
            rows.append([(abs(a) ** 2 - abs(b) ** 2) / (2 * sd[j]), -(a.real - b.real) / sd[j]])
        J.append(rows)
    J = np.transpose(np.array(J), (1, 2, 0))  # (mode, (p, q), parameter)
    assert len(um.modes) >= 1  # the blocks kept after folding the small ones into the remainder
    for (_l0, u, half), Ji in zip(um.modes, J):
        want = 3.0 * np.sqrt(u @ Ji @ cov @ Ji.T @ u)
        assert half == pytest.approx(want, rel=0.05)
    # and the remainder holds every source it was fitted on (data and sampled models)
    assert um.remainder.margin >= 1.0 and plants.cover.margin >= 1.0
    assert um.max_error < 0.01


def test_both_designs_are_stable_on_500_truths_at_three_times_the_spread_and_on_the_data(comparison):
    data, upd, plants, yard = comparison
    names, x, cov = upd.fit.names, np.asarray(upd.fit.x_array), np.asarray(upd.fit.covariance)
    rng = np.random.default_rng(2026)
    draws = rng.multivariate_normal(x, 9.0 * cov, N_TRUTHS)
    worst = {"A": -np.inf, "B": -np.inf}
    for th in draws:
        G = upd.model.with_values(**dict(zip(names, map(float, th)))).statespace()
        for lab in worst:
            worst[lab] = max(worst[lab], float(closed_loop_poles(G, yard.designs[lab].K).real.max()))
    for lab in ("A", "B"):
        assert worst[lab] < 0, f"design {lab} destabilises a truth (pole real part {worst[lab]:.3g})"
        assert yard.stability[lab].stable is True
    print({lab: round(w, 4) for lab, w in worst.items()}, yard.summary())


def test_guaranteed_level_and_attenuation_are_measured_for_both(comparison):
    _, _, plants, yard = comparison
    levels = {}
    for lab, gp in (("A", plants.parametric), ("B", plants.complex)):
        a, rs = ex.performance_scale(gp, yard.designs[lab].K)
        levels[lab] = (a, rs)
        # the bisection's answer is what mu says: at the scale robust performance holds
        if a > 0:
            cl = rc.robust.dk.verify.closed_loop(gp.P, yard.designs[lab].K, gp.nmeas, gp.ncon)
            # on the grid the bisection used (the design's own verification grid may hold points,
            # e.g. at the iterations' resonances, where mu at that scale is above 1 by 2e-5)
            f = rc.robust.dk.verify.verification_grid(cl, rc.robust.dk.verify.default_grid(gp.P))
            H = freqresp_array(cl, f)
            H[:, H.shape[1] - gp.n_perf_z:, :] *= a
            assert rc.mu(H, gp.blocks, f_hz=f, lower=False).peak <= 1.0 + 1e-6
        else:
            assert rs > 1.0
    print("guaranteed (scale, RS mu):", levels, "attenuation dB:", yard.attenuation_db)
    assert all(np.isfinite(v) for v in yard.attenuation_db.values())
    # what the method guarantees (not which description's design ends higher, which is path luck:
    # 1.151 against 0.783 where developed, 0.7905 against 1.1152 on another machine): the mixed
    # design on the real blocks is never above the complex D-K design it starts from
    dA = yard.designs["A"]
    assert np.isfinite(dA.complex_mu_peak) and dA.mu_peak <= dA.complex_mu_peak * (1 + 1e-12)
    assert not np.isfinite(yard.designs["B"].complex_mu_peak)  # no real block: plain D-K
