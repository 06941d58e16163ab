"""D-K on large plants: the design plant reduced by balanced truncation before synthesis
(robustctl.robust.dk.design_plant), the truncation error covered by an additive uncertainty block, the
controller closed around the full plant and its mu verified there. The plants are the numpy chains
of ``benchmarks/bench_scale_dk.py``."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg as sla

from benchmarks.bench_scale_dk import chain_plant, design_plant
from robustctl.errors import SynthesisError
from robustctl.lti import freqresp_array
from robustctl.robust.dk.design_plant import DESIGN_REDUCE_ABOVE, reduce_design_plant
from robustctl.robust.dk.iteration import dksyn
from robustctl.robust.plant import generalized_plant


def _hsv(P) -> np.ndarray:
    """Hankel singular values from scipy's Lyapunov solutions (independent of robustctl.balanced)."""
    A, B, C = (np.asarray(m) for m in (P.A, P.B, P.C))
    Wc = sla.solve_continuous_lyapunov(A, -B @ B.T)
    Wo = sla.solve_continuous_lyapunov(A.T, -C.T @ C)
    return np.sort(np.sqrt(np.abs(np.linalg.eigvals(Wc @ Wo))))[::-1]


def test_auto_design_order_keeps_the_bound_and_covers_the_truncation_error():
    """A 100-mode chain (204 states): reduced to the fewest states (no fixed cap) whose bound
    2 sum sigma_tail of scipy's Hankel singular values is within 1 % of the largest, the true
    error below the bound and the block's weight, and the augmented plant = the reduced one
    plus [z; y] += w_e, z_e = weight [w; u]."""
    gp = design_plant(100)
    assert gp.P.nstates > DESIGN_REDUCE_ABOVE
    design, red = reduce_design_plant(gp, "auto")
    assert red is not None and red.order_before == 204 and red.order_after < 204
    hsv = _hsv(gp.P)
    assert red.bound == pytest.approx(2 * hsv[red.order_after:].sum(), rel=1e-4)
    assert red.bound <= 0.01 * hsv[0] * (1 + 1e-6)
    assert 2 * hsv[red.order_after - 1:].sum() > 0.01 * hsv[0] and red.tried == ()
    f = np.r_[0.0, np.geomspace(0.05, 200, 300)]
    Hf, Hd = freqresp_array(gp.P, f), freqresp_array(design.P, f)
    nw, nz, nu, ny = gp.nw, gp.nz, gp.ncon, gp.nmeas
    n_in, n_out = nw + nu, nz + ny
    k = len(gp.blocks) - 1
    w1 = sum(b.rows for b in gp.blocks[:k])
    z1 = sum(b.cols for b in gp.blocks[:k])
    keep_w = np.r_[np.arange(w1), w1 + n_out + np.arange(nw - w1), nw + n_out + np.arange(nu)]
    keep_z = np.r_[np.arange(z1), z1 + n_in + np.arange(nz - z1), nz + n_in + np.arange(ny)]
    err = np.linalg.norm(Hf - Hd[np.ix_(np.arange(f.size), keep_z, keep_w)], 2, axis=(1, 2))
    assert err.max() <= red.bound and err.max() <= red.error_weight
    new_w, new_z = w1 + np.arange(n_out), z1 + np.arange(n_in)
    np.testing.assert_allclose(Hd[np.ix_(np.arange(f.size), keep_z, new_w)],
                               np.broadcast_to(np.eye(n_out), (f.size, n_out, n_out)))
    np.testing.assert_allclose(Hd[np.ix_(np.arange(f.size), new_z, keep_w)],
                               np.broadcast_to(red.error_weight * np.eye(n_in), (f.size, n_in, n_in)))
    assert np.all(Hd[np.ix_(np.arange(f.size), new_z, new_w)] == 0)
    assert [b.name for b in design.blocks][-2:] == ["design reduction", gp.blocks[-1].name]


def test_small_plants_are_not_reduced_and_bad_orders_are_refused():
    gp = design_plant(10)
    assert reduce_design_plant(gp, "auto")[1] is None
    assert reduce_design_plant(gp, None)[1] is None
    for bad in (0, -3, 2.5, "half", True):
        with pytest.raises(SynthesisError, match="design_order"):
            reduce_design_plant(gp, bad)
    G = chain_plant(3)
    unstable = control.ss(np.asarray(G.A) + 0.5 * np.eye(6), G.B, G.C, G.D)
    gpu = generalized_plant(unstable, performance=1.0, control_weight=0.1, noise=0.01, disturbances=1.0)
    with pytest.raises(SynthesisError, match="not asymptotically stable"):
        reduce_design_plant(gpu, 4)


def test_dksyn_on_a_reduced_design_plant_verifies_mu_with_the_full_plant():
    """A 10-mode chain designed on a 12-state truncation: the returned closed loop is the full
    plant's (its eigenvalues, from numpy, all stable), its mu is the verified full-plant mu,
    and the D-scales are one per block of the user's structure but the last."""
    gp = design_plant(10)
    dk = dksyn(gp, max_iter=2, progress=False, design_order=12, order_d=[2])  # one order per user block
    red = dk.design_reduction
    assert red is not None and (red.order_before, red.order_after) == (24, 12)
    assert dk.closed_loop.nstates == gp.P.nstates + dk.K.nstates
    A, B, C, D = (np.asarray(m) for m in (gp.P.A, gp.P.B, gp.P.C, gp.P.D))
    Ak, Bk, Ck, Dk = (np.asarray(m) for m in (dk.K.A, dk.K.B, dk.K.C, dk.K.D))
    B2, C2 = B[:, gp.nw:], C[gp.nz:]
    assert np.all(D[gp.nz:, gp.nw:] == 0)  # strictly proper G: u = K y closes without an algebraic loop
    Acl = np.block([[A + B2 @ Dk @ C2, B2 @ Ck], [Bk @ C2, Ak]])
    assert np.linalg.eigvals(Acl).real.max() < 0
    assert dk.mu_peak == pytest.approx(red.mu_peak_full) and dk.mu_peak == pytest.approx(dk.mu.peak)
    assert len(dk.d_scales) == len(gp.blocks) - 1
    assert dk.blocks == gp.blocks
    assert "balanced truncation from 24 to 12 states" in dk.summary()


@pytest.mark.slow
def test_dksyn_completes_on_a_160_mode_plant_with_mu_verified_on_the_full_plant():
    """The 160-mode chain (324 states) whose full-order K step fails: D-K completes on the
    reduced design plant, the controller stabilises the full plant (numpy eigenvalues) and mu
    is verified there, below the design plant's (measured: 1.346 against 1.484)."""
    gp = design_plant(160)
    dk = dksyn(gp, progress=False)
    red = dk.design_reduction
    assert red is not None and red.order_before == 324 and red.order_after < 324
    assert dk.K.nstates < 200
    assert np.linalg.eigvals(np.asarray(dk.closed_loop.A)).real.max() < 0
    assert np.isfinite(dk.mu_peak) and dk.mu_peak == pytest.approx(red.mu_peak_full)
    # the full plant is one member of the design plant's uncertainty set (the error block covers
    # P - P_r): its mu cannot exceed the design's but by the two verification grids' difference
    assert red.mu_peak_full <= red.mu_peak_design * 1.02


def _random_modal_plant(n_modes: int, seed: int):
    """A random lightly damped modal plant (2 forces -> 2 displacements; 0.5-50 Hz, 0.5-2 %
    damping, random mode shapes): Hankel singular values that fall slowly, unlike the chain's."""
    rng = np.random.default_rng(seed)
    wk = 2 * np.pi * np.sort(rng.uniform(0.5, 50.0, n_modes))
    zeta = rng.uniform(0.005, 0.02, n_modes)
    A = np.zeros((2 * n_modes, 2 * n_modes))
    B = np.zeros((2 * n_modes, 2))
    C = np.zeros((2, 2 * n_modes))
    for k in range(n_modes):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0, 1], [-wk[k] ** 2, -2 * zeta[k] * wk[k]]]
        B[2 * k + 1] = rng.standard_normal(2) * wk[0]
        C[:, 2 * k] = rng.standard_normal(2) * wk[0]
    return control.ss(A, B, C, np.zeros((2, 2)))


def test_measured_truncation_error_is_below_the_hankel_tail_bound():
    """Balanced truncation's a-priori bound (Glover 1984; Zhou, Doyle & Glover 1996, Thm 7.9):
    for a random 30-mode plant, ||G - G_r||_inf measured on a dense grid holding every pole
    frequency is below 2 sum_{i>r} sigma_i (scipy's Gramians) at every order tried, and the
    bounds the automatic order reads are those sums."""
    from robustctl.balanced import balanced_truncation
    from robustctl.robust.dk.design_plant import truncation_bounds

    G = _random_modal_plant(30, seed=4)
    hsv = _hsv(G)
    np.testing.assert_allclose(truncation_bounds(hsv)[[0, 10, 60]], [2 * hsv.sum(), 2 * hsv[10:].sum(), 0.0])
    fp = np.abs(np.linalg.eigvals(np.asarray(G.A))) / (2 * np.pi)
    f = np.unique(np.r_[0.0, np.geomspace(0.05, 500, 3000), fp])
    H = freqresp_array(G, f)
    for r in (8, 20, 36, 50):
        bt = balanced_truncation(G, r)
        err = np.linalg.norm(H - freqresp_array(bt.sys, f), 2, axis=(1, 2)).max()
        bound = 2 * hsv[r:].sum()
        assert bt.bound == pytest.approx(bound, rel=1e-6)
        assert err <= bound * (1 + 1e-9), (r, err, bound)
        assert err >= hsv[r] * (1 - 1e-3)  # and never below the first truncated sigma (lower bound)


def test_auto_order_has_no_fixed_cap_and_a_failed_design_raises_the_order(monkeypatch):
    """The automatic order follows the bound, not a fixed cap (slowly falling Hankel singular
    values keep more states), and a controller that does not stabilise the full plant makes
    D-K try again at a higher order chosen from the loop's small-gain tolerance; every order
    tried is in the result. On the 10-mode chain the error block keeps even a 2-state design
    plant's loop stable, so the first full-plant check is made to fail here."""
    import robustctl.robust.dk.design_plant as dp

    hsv = _hsv(_random_modal_plant(160, seed=1))  # 320 states
    r = dp._auto_order(hsv)
    assert r > 100 and dp.truncation_bounds(hsv)[r] <= 0.01 * hsv[0] < dp.truncation_bounds(hsv)[r - 1]
    assert dp.truncation_bounds(hsv)[100] > 0.2 * hsv[0]  # the old cap of 100 states left 0.247

    gp = design_plant(10)
    monkeypatch.setattr(dp, "DESIGN_REDUCE_ABOVE", 10)
    monkeypatch.setattr(dp, "DESIGN_BOUND_RTOL", 0.5)
    real_check, calls = dp.on_full_plant, []

    def first_fails(plant, blocks, result, reduction):
        calls.append(reduction.order_after)
        if len(calls) == 1:
            raise dp._UnstabilisedError("forced", 0.1)
        return real_check(plant, blocks, result, reduction)

    monkeypatch.setattr(dp, "on_full_plant", first_fails)
    dk = dksyn(gp, max_iter=2, progress=False, order_d=[2])
    red = dk.design_reduction
    assert red is not None and len(red.tried) == 1 and red.order_after == calls[1] > calls[0]
    assert red.order_after >= 1.25 * calls[0] and "raised after 1 design" in red.reason
    orders = [t[0] for t in red.tried] + [red.order_after]
    assert orders == sorted(orders) and len(set(orders)) == len(orders)
    assert all("unstable" in t[2] and "tolerates" in t[2] for t in red.tried)
    assert np.linalg.eigvals(np.asarray(dk.closed_loop.A)).real.max() < 0
    assert "Orders tried first" in red.summary()
