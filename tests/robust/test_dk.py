"""D-K iteration (robustctl.robust.dk.iteration) and the generalized Nyquist test of the yardstick."""

from __future__ import annotations

import control
import numpy as np
import pytest

from robustctl.errors import SynthesisError
from robustctl.examples import DISTILLATION_BLOCKS, distillation_plant
from robustctl.lti import freqresp_array
from robustctl.robust.dk.iteration import _scale_plant, as_plant, closed_loop, dksyn
from robustctl.robust.uncertainty.blocks import as_block_structure
from robustctl.robust.yardsticks import nyquist_stability

BOOK_BLOCKS = DISTILLATION_BLOCKS


def test_distillation_plant_matches_its_transfer_functions():
    P = distillation_plant()
    s = 2j * np.pi * 0.03
    G = np.array([[87.8, -86.4], [108.2, -109.6]]) / (75 * s + 1)
    wI, wP = (s + 0.2) / (0.5 * s + 1), 0.5 * (10 * s + 1) / (10 * s + 1e-5)
    R = freqresp_array(P, [0.03])[0]
    I2 = np.eye(2)
    expect = np.block([[0 * I2, 0 * I2, wI * I2], [wP * G, wP * I2, wP * G], [-G, -I2, -G]])
    assert np.allclose(R, expect, rtol=1e-10, atol=1e-12)


def _brute_lft(P, K, nmeas, ncon, f):
    Pf, Kf = freqresp_array(P, f), freqresp_array(K, f)
    nz, nw = P.noutputs - nmeas, P.ninputs - ncon
    P11, P12, P21, P22 = Pf[:, :nz, :nw], Pf[:, :nz, nw:], Pf[:, nz:, :nw], Pf[:, nz:, nw:]
    inner = np.linalg.solve(np.eye(nmeas)[None] - P22 @ Kf, P21)
    return P11 + P12 @ Kf @ inner


@pytest.mark.parametrize("with_d22", [False, True])
def test_closed_loop_is_the_lower_lft(with_d22):
    rng = np.random.default_rng(3)
    P = control.rss(5, 5, 4, strictly_proper=False)
    if not with_d22:
        D = np.array(P.D)
        D[3:, 2:] = 0.0
        P = control.ss(P.A, P.B, P.C, D)
    K = control.ss(np.diag([-1.0, -2.0, -3.0]), rng.normal(size=(3, 2)), 0.3 * rng.normal(size=(2, 3)),
                   0.2 * rng.normal(size=(2, 2)))
    f = np.logspace(-2, 1, 7)
    assert np.allclose(freqresp_array(closed_loop(P, K, 2, 2), f), _brute_lft(P, K, 2, 2, f), atol=1e-10)


def test_scaled_plant_is_d_p_dinv_on_the_uncertainty_channels():
    P = distillation_plant()
    plant = as_plant((P, 2, 2, BOOK_BLOCKS))
    d1 = control.ss(control.tf([2.0, 1.0], [1.0, 3.0]))
    d2 = control.ss(control.tf([1.0, 0.5, 2.0], [1.0, 2.0, 1.0]))
    Ps = _scale_plant(plant, [d1, d2])
    f = np.logspace(-3, 1, 9)
    a, b = freqresp_array(d1, f)[:, 0, 0], freqresp_array(d2, f)[:, 0, 0]
    one = np.ones_like(a)
    left = np.stack([a, b, one, one, one, one], axis=1)      # z1, z2, zp1, zp2, y1, y2
    right = np.stack([1 / a, 1 / b, one, one, one, one], axis=1)  # di1, di2, w1, w2, u1, u2
    expect = left[:, :, None] * freqresp_array(P, f) * right[:, None, :]
    assert np.allclose(freqresp_array(Ps, f), expect, rtol=1e-9, atol=1e-9)
    assert list(Ps.input_labels) == list(P.input_labels)


def test_bad_plants_and_arguments_are_refused():
    P = distillation_plant()
    with pytest.raises(SynthesisError, match="nw=4"):
        dksyn((P, 2, 2, [[1, 1], [2, 2]]))
    with pytest.raises(SynthesisError, match="tuple"):
        dksyn(P)
    with pytest.raises(SynthesisError, match="max_iter"):
        dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=0)
    with pytest.raises(SynthesisError, match="time_budget_s"):
        dksyn((P, 2, 2, BOOK_BLOCKS), time_budget_s=-1)
    with pytest.raises(SynthesisError, match="f_hz"):
        dksyn((P, 2, 2, BOOK_BLOCKS), f_hz=[1.0, 0.5, 2.0])
    with pytest.raises(SynthesisError, match="order_d"):
        dksyn((P, 2, 2, BOOK_BLOCKS), order_d=[1, 2, 3], max_iter=2)


def test_one_iteration_is_the_hinf_controller_and_its_mu():
    """Iteration 1 (no scaling): S&P Table 8.2 gives peak mu 1.1818 for the H-infinity controller."""
    P = distillation_plant()
    dk = dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False)
    assert len(dk.history) == 1 and dk.best_iteration == 1
    assert dk.mu_peak == pytest.approx(1.1818, abs=0.005)
    assert dk.history[0].gamma == pytest.approx(1.1818, abs=0.005)
    assert dk.K.nstates == P.nstates
    # the closed loop is Fl(P, K) and the mu result belongs to it
    f = dk.mu.f_hz[::10]
    assert np.allclose(freqresp_array(dk.closed_loop, f), _brute_lft(P, dk.K, 2, 2, f), atol=1e-9)
    assert "mu peak" in str(dk.table()) and "not certified" in dk.summary()


def test_dksyn_on_a_sampled_plant_is_the_tustin_originals_design_mapped_back():
    """A sampled plant is designed through the bilinear map, which keeps stability and mu: the
    result is the Tustin original's design sampled again, and mu of the sampled loop on the unit
    circle (computed here from the sampled closed loop) is the continuous design's."""
    import robustctl as rc
    from robustctl.robust.dk.sampled_design import warped_hz
    from robustctl.robust.mu.bounds import mu

    dt = 0.5
    Pd = control.c2d(distillation_plant(), dt, method="zoh")
    dkd = dksyn((Pd, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False)
    dkc = dksyn((rc.d2c(Pd, method="tustin"), 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False)
    assert dkd.K.dt == dt and dkd.closed_loop.dt == dt
    assert dkd.mu_peak == pytest.approx(dkc.mu_peak, rel=1e-12)
    # the sampled controller takes the continuous one's values at the warped frequencies
    fc = np.logspace(-3, 1, 40)
    np.testing.assert_allclose(freqresp_array(dkd.K, warped_hz(fc, dt)), freqresp_array(dkc.K, fc),
                               rtol=1e-8, atol=1e-10)
    assert warped_hz(1e9, dt) == pytest.approx(1 / (2 * dt))  # infinity maps to the Nyquist frequency
    # mu of the sampled loop, from its own response on z = exp(j 2 pi f dt), at the reported frequencies
    m = mu(freqresp_array(dkd.closed_loop, dkd.mu.f_hz), dkd.blocks, f_hz=dkd.mu.f_hz, lower=False)
    assert m.peak == pytest.approx(dkd.mu_peak, rel=1e-6)
    assert np.all(dkd.mu.f_hz < 1 / (2 * dt))
    assert np.max(np.abs(np.linalg.eigvals(np.asarray(dkd.closed_loop.A)))) < 1.0
    # a sampled plant with a pole at z = -1 has no Tustin original
    bad = control.ss(np.diag([-1.0, 0.5]), np.eye(2), np.eye(2), np.zeros((2, 2)), dt)
    with pytest.raises(SynthesisError, match="z = -1"):
        dksyn((bad, 1, 1, [[1, 1]]), max_iter=1, progress=False)


def test_the_reported_time_is_the_calls_own():
    """``time_s`` (and the summary) is the whole call's wall-clock time -- the iterations, the
    verification on the denser grid and every strategy's runs -- and a second call does not
    add the first's (issue 33: 20.1 s reported for a call of 24.3 s)."""
    import time

    P = distillation_plant()
    for _ in range(2):
        t0 = time.perf_counter()
        dk = dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False)
        outside = time.perf_counter() - t0
        assert dk.iterations_time_s < dk.time_s <= outside
        assert dk.time_s >= 0.9 * outside
        assert f"The call took {dk.time_s:.2f} s, {dk.iterations_time_s:.2f} s of it" in dk.summary()
    from dataclasses import replace

    assert replace(dk, elapsed_s=float("nan")).time_s == dk.iterations_time_s  # built outside dksyn


@pytest.mark.slow
def test_distillation_reproduces_the_book_with_fourth_order_scales():
    """S&P Table 8.2 (4th-order D fits): 1.1818, 1.0238, 1.0189."""
    dk = dksyn((distillation_plant(), 2, 2, BOOK_BLOCKS), max_iter=3, order_d=4, progress=False,
               patience=10, autoscale=False)
    peaks = [h.mu_peak for h in dk.history]
    assert peaks[0] == pytest.approx(1.1818, abs=0.005)
    assert peaks[1] == pytest.approx(1.0238, abs=0.01)
    assert peaks[2] == pytest.approx(1.0189, abs=0.01)
    assert all(h.d_orders == (4, 4) for h in dk.history[1:])


@pytest.mark.slow
def test_distillation_dk_with_automatic_scales():
    """The target: peak mu <= 1.00 within 6 iterations (MATLAB's 2008 dksyn: 0.9975;
    mu-optimal 0.974). Plain D-K creeps (1.0145 at iteration 5); the D step's line search
    along the change of the scales gets there (0.9897 at iteration 5)."""
    dk = dksyn((distillation_plant(), 2, 2, BOOK_BLOCKS), max_iter=6, progress=False, autoscale=False)
    assert len(dk.history) <= 6
    assert dk.mu_peak <= 1.00
    assert dk.history[0].mu_peak == pytest.approx(1.1818, abs=0.005)
    # the line search was used: an extrapolated D step won at least once
    assert any(h.d_step > 0 and h.n_candidates > 1 for h in dk.history)
    # the kept controller is the best of the history; verified on the denser grid its mu is
    # at least the iteration grid's and close to it; the lower bound stays below
    assert dk.grid_mu_peak == pytest.approx(min(h.mu_peak for h in dk.history))
    assert dk.grid_mu_peak <= dk.mu_peak <= dk.grid_mu_peak * 1.002
    assert dk.mu.lower.max() <= dk.mu_peak * (1 + 1e-6)
    # every iteration above the best before it says so
    for k, h in enumerate(dk.history[1:], start=1):
        assert ("rose above" in h.note) == (h.mu_peak > min(g.mu_peak for g in dk.history[:k]))
    # certified on a grid 1e-7 .. 100 Hz too (mu is flat down to DC on this problem)
    from robustctl.robust.mu.bounds import mu

    fw = np.logspace(-7, 2, 400)
    wide = mu(freqresp_array(dk.closed_loop, fw), dk.blocks, f_hz=fw)
    assert wide.peak <= 1.001


@pytest.mark.slow
def test_distillation_with_the_weight_pole_at_1e5_reaches_mu_below_one():
    """eps = 1e-5: the grid reaches down to 1e-6 rad/s, and the D-scales are flat over its
    lowest five decades. hinfsyn once stopped D-K at iteration 1 (the scaled ||P11|| ~4e5);
    later the D fits, started with basis poles spread over all 7.8 decades, lost about one
    order each and D-K stalled at 1.019 (1.181 1.037 1.021 1.019 1.026). Now it follows
    eps = 1e-6 below 1, descending, and the returned mu holds on a grid down to DC."""
    from robustctl.robust.mu.bounds import mu

    dk = dksyn((distillation_plant(eps=1e-5), 2, 2, BOOK_BLOCKS), max_iter=6, progress=False, autoscale=False)
    peaks = [h.mu_peak for h in dk.history]
    assert peaks[0] == pytest.approx(1.181, abs=0.005)
    assert peaks[1] < 1.035 and dk.mu_peak < 1.0
    best = dk.best_iteration
    assert all(b < a for a, b in zip(peaks[:best], peaks[1:best]))  # no rise before the best
    fw = np.concatenate([[0.0], np.logspace(-9, 2, 1500)])
    dense = mu(freqresp_array(dk.closed_loop, fw), dk.blocks, f_hz=fw, lower=False).peak
    assert dense == pytest.approx(dk.mu_peak, rel=2e-3)


def _modal_plant(fn_hz, zeta, b, c):
    """A SISO modal plant ``sum_k b_k c_k w_k^2 / (s^2 + 2 zeta_k w_k s + w_k^2)``."""
    n = len(fn_hz)
    A, B, C = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 1)), np.zeros((1, 2 * n))
    for k, (f, z) in enumerate(zip(fn_hz, zeta)):
        w = 2 * np.pi * f
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0.0, 1.0], [-w * w, -2 * z * w]]
        B[2 * k + 1, 0], C[0, 2 * k] = b[k] * w, c[k] * w
    return control.ss(A, B, C, np.zeros((1, 1)))


def test_returned_mu_is_verified_between_and_beyond_the_grid():
    """With a coarse grid (14 points over 3 decades) the resonances of a two-mode plant fall
    between the points: the iteration sees mu 0.91 where it is 1.079. dksyn verifies the
    returned controller on a denser grid, the closed-loop resonances and a search of its
    highest maxima: its mu_peak is the one an independent fine grid finds, it warns, and
    grid_mu_peak keeps the grid's."""
    from robustctl.robust.mu.bounds import mu
    from robustctl.robust.plant import generalized_plant
    from robustctl.robust.uncertainty.weights import makeweight

    G = _modal_plant([5.0166, 13.6886], [0.0298, 0.0084], [-0.4547, 0.0601], [-0.9916, 1.3402])
    gp = generalized_plant(G, output_mult=makeweight(0.05, (3.0, 0.3), 2.0),
                           performance=makeweight(0.5, (0.5, 0.3), 0.01), disturbances=1.0,
                           control_weight=0.1, noise=0.01)
    with pytest.warns(RuntimeWarning, match="misses the peak"):
        dk = dksyn(gp, max_iter=2, f_hz=np.logspace(-1.5, 1.7, 14), progress=False, autoscale=False,
                   order_d=1)
    fw = np.logspace(-2, 2.5, 6000)
    dense = mu(freqresp_array(dk.closed_loop, fw), dk.blocks, f_hz=fw, lower=False)
    assert dk.grid_mu_peak < 0.9 * dense.peak           # the coarse grid missed the peak
    assert dk.mu_peak == pytest.approx(dense.peak, rel=2e-3)
    assert dk.mu.f_peak_hz == pytest.approx(dense.f_peak_hz, rel=0.01)
    assert dk.mu.lower.max() <= dk.mu_peak * (1 + 1e-6)
    assert "misses" not in dk.summary() and f"{dense.peak:.3f}"[:4] in dk.summary()


def test_d_orders_out_of_band_fall_back_to_lower_orders_not_a_constant(monkeypatch):
    """When every allowed order's fit has dynamics outside the band, the lower orders are
    tried (highest first) before a constant: a constant scale raised mu from 1.20 to 1.39
    on a random 28-state plant. Here fits of order >= 2 are declared out of band."""
    import robustctl.robust.dk.iteration as dkm
    import robustctl.robust.dk.scales as dks
    from robustctl.robust.hinf.synthesis import hinfsyn

    plant = as_plant((distillation_plant(), 2, 2, BOOK_BLOCKS))
    blocks = dkm._complexified(plant.blocks)
    cl = closed_loop(plant.P, hinfsyn(plant.P, 2, 2, backoff=1e-3).K, 2, 2)
    m, H = dkm.mu_of(cl, blocks, dkm.default_grid(plant.P), refine=True)
    _, orders, bound_free = dkm._fit_d_scales(H, m, blocks, 4, None, (), dkm._edge_response(cl))
    assert orders == (4, 4)
    in_band = dkm._dynamics_in_band
    monkeypatch.setattr(dks, "_dynamics_in_band",
                        lambda fit, f, margin=10.0: fit.nstates < 2 and in_band(fit, f))
    fits, orders, bound = dkm._fit_d_scales(H, m, blocks, 4, None, (), dkm._edge_response(cl))
    assert orders == (1, 1) and all(fit.nstates == 1 for fit in fits)
    # order 1 is what the fallback found best: its bound beats the constant scales'
    _, _, bound_const = dkm._fit_d_scales(H, m, blocks, 0, None, (), dkm._edge_response(cl))
    assert bound_free < bound < bound_const


def test_a_broken_fit_of_the_only_allowed_order_falls_back_to_lower_orders(monkeypatch):
    """Orders never drop below the previous iteration's (ORDER_D_DROP = 0), but when the only
    allowed order's fit bounds the loop far above what the block can reach, the lower ones
    are tried: on a random 12-state plant the order-8 fit rose 15x beyond the grid's top,
    its bound was 3.2 against mu 0.48, and the next K step's gamma 3.1. Here order 4's fits
    and above are spoiled by a factor 3 (bound ~3x mu)."""
    import robustctl.robust.dk.iteration as dkm
    import robustctl.robust.dk.scales as dks
    from robustctl.robust.hinf.synthesis import hinfsyn

    plant = as_plant((distillation_plant(), 2, 2, BOOK_BLOCKS))
    blocks = dkm._complexified(plant.blocks)
    cl = closed_loop(plant.P, hinfsyn(plant.P, 2, 2, backoff=1e-3).K, 2, 2)
    m, H = dkm.mu_of(cl, blocks, dkm.default_grid(plant.P), refine=True)
    edges = dkm._edge_response(cl)
    fit_one = dkm._fit_one
    monkeypatch.setattr(dks, "_fit_one", lambda args: 3.0 * fit_one(args) if args[2] >= 4 else fit_one(args))
    fits, orders, bound = dkm._fit_d_scales(H, m, blocks, None, None, (4, 4), edges)
    assert all(o < 4 for o in orders) and bound < 1.25 * m.peak
    monkeypatch.setattr(dks, "ORDER_D_BROKEN", np.inf)  # without the fallback: the spoiled fits
    _, orders, spoiled = dkm._fit_d_scales(H, m, blocks, None, None, (4, 4), edges)
    assert all(o >= 4 for o in orders) and spoiled > 2 * m.peak


def test_fit_roots_above_the_band_are_moved_to_its_edge():
    from robustctl.lti import zpk_statespace
    from robustctl.robust.dk.iteration import _dynamics_in_band, _into_band

    f = np.logspace(-3, 1, 50)           # band up to 10 Hz; margin 10 -> 628 rad/s
    d = zpk_statespace([-3e4, -0.5], [-2.0, -40.0], 1e-3)
    assert not _dynamics_in_band(d, f)
    moved = _into_band(d, f)
    assert _dynamics_in_band(moved, f)
    a, b = freqresp_array(d, f)[:, 0, 0], freqresp_array(moved, f)[:, 0, 0]
    assert np.max(np.abs(np.log(np.abs(b / a)))) < 0.006     # at most 0.5 % in the band
    assert abs(np.log(abs(b[0] / a[0]))) < 1e-6               # low frequencies kept
    inside = zpk_statespace([-0.5], [-2.0], 1.0)
    assert _into_band(inside, f) is inside
    # a far zero that rounding put in the right half plane comes back mirrored (stable inverse)
    rhp = control.ss(control.tf([-1.0 / 3e4, 1.0], [0.5, 1.0]))     # zero at +3e4 rad/s
    moved = _into_band(rhp, f)
    assert np.all(np.linalg.eigvals(np.asarray(moved.A)).real < 0)
    zeros = np.linalg.eigvals(np.asarray(moved.A - moved.B @ moved.C / moved.D[0, 0]))
    assert np.all(zeros.real < 0)
    a, b = freqresp_array(rhp, f)[:, 0, 0], freqresp_array(moved, f)[:, 0, 0]
    assert np.max(np.abs(np.log(np.abs(b / a)))) < 0.006


def test_reduction_is_rechecked_by_mu():
    P = distillation_plant()
    dk = dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, reduce=4, autoscale=False)
    r = dk.reduction
    assert r is not None and r.order_before == 6 and r.order_after == 4
    if r.accepted:
        assert dk.K.nstates == 4 and dk.mu_peak == pytest.approx(r.mu_peak_after)
        assert r.mu_peak_after <= r.mu_peak_before * 1.02
    else:
        assert dk.K.nstates == 6 and r.reason
    with pytest.raises(SynthesisError, match="reduce"):
        dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, reduce=0, autoscale=False)


def _mu_peak_of(P, K, blocks, f_hz):
    """Peak of the mu upper bound of Fl(P, K) on ``f_hz``, computed afresh (inf: unstable loop)."""
    from robustctl.robust.mu.bounds import mu

    cl = closed_loop(P, K, 2, 2)
    if np.max(np.linalg.eigvals(np.asarray(cl.A)).real) >= 0:
        return np.inf
    return mu(freqresp_array(cl, f_hz), as_block_structure(blocks), f_hz=f_hz).peak


def test_automatic_reduction_finds_the_smallest_order_that_keeps_mu():
    from robustctl.balanced import balanced_truncation

    P = distillation_plant()
    opts = {"max_iter": 2, "progress": False, "autoscale": False, "order_d": 4}
    dk = dksyn((P, 2, 2, BOOK_BLOCKS), reduce="auto", **opts)
    r = dk.reduction
    assert r is not None and r.accepted and r.order_after < r.order_before
    assert dk.K.nstates == r.order_after
    f = dk.mu.f_hz
    # the kept controller's mu, recomputed independently, is what dksyn reports, within 2 % of the full one
    assert _mu_peak_of(P, dk.K, BOOK_BLOCKS, f) == pytest.approx(dk.mu_peak, rel=1e-6)
    assert dk.mu_peak <= r.mu_peak_before * 1.02
    # and one state fewer breaks the 2 % rule (bisection ends next to a failing order)
    full = dksyn((P, 2, 2, BOOK_BLOCKS), **opts)
    assert full.K.nstates == r.order_before
    smaller = balanced_truncation(full.K, r.order_after - 1).sys
    assert _mu_peak_of(P, smaller, BOOK_BLOCKS, f) > r.mu_peak_before * 1.02
    with pytest.raises(SynthesisError, match="auto"):
        dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, reduce="smallest", autoscale=False)


# ---------------------------------------------------------------------------- Nyquist on data
def _loop(L_sys):
    return lambda f: freqresp_array(L_sys, f)


def _stable(cl) -> bool:
    return bool(np.all(np.linalg.eigvals(np.asarray(cl.A)).real < 0))


@pytest.mark.parametrize("k", [1.0, 2.5, 2.9, 5.0])
def test_nyquist_on_data_matches_closed_loop_poles(k):
    """L = k s/(s+1)^3 with det(I - L): the closed loop s^3 + 3s^2 + (3-k)s + 1 is stable iff k < 8/3."""
    L = k * control.ss(control.tf([1.0, 0.0], [1.0, 3.0, 3.0, 1.0]))
    f = np.linspace(1e-3, 200.0, 40000)
    v = nyquist_stability(f, _loop(L)(f), 0)
    assert v.stable is (k < 8 / 3)
    assert _stable(control.feedback(L, 1, sign=1)) is (k < 8 / 3)


@pytest.mark.parametrize("a", [-3.0, -1.5])
def test_nyquist_counts_open_loop_unstable_poles(a):
    """L = a(s+1)/((s-1)(s+2)): one RHP pole; det(I - L) stable iff s^2 + (1-a)s - 2 - a is Hurwitz."""
    L = control.ss(control.tf([a, a], [1.0, 1.0, -2.0]))
    f = np.linspace(1e-3, 300.0, 60000)
    v = nyquist_stability(f, _loop(L)(f), 1, model_loop=_loop(L))
    truth = _stable(control.feedback(L, 1, sign=1))
    assert truth is (a == -3.0)
    assert v.stable is truth
    # without the model below the band, |L(0)| = -a/2 > 0.9 leaves the low end unknown
    assert nyquist_stability(f, _loop(L)(f), 1).stable is (None if a == -3.0 else False)


def test_nyquist_mimo_against_closed_loop_poles():
    G = control.ss(control.tf([[[1.0], [0.5]], [[0.2], [2.0]]],
                              [[[1.0, 2.0, 1.0], [1.0, 1.0]], [[1.0, 3.0], [1.0, 2.0, 4.0]]]))
    f = np.linspace(1e-3, 500.0, 100000)
    verdicts = []
    for k in (0.5, 3.0, 30.0):
        L = -k * G
        truth = _stable(control.feedback(L, control.ss([], [], [], np.eye(2)), sign=1))
        v = nyquist_stability(f, _loop(L)(f), 0, model_loop=_loop(L))
        assert v.stable is truth
        verdicts.append(truth)
    assert True in verdicts and False in verdicts


def test_nyquist_cannot_tell():
    L = -30.0 * control.ss(control.tf([1.0], [1.0, 0.4, 1.0]))
    f = np.linspace(1e-3, 0.1, 2000)   # stops below the crossover (|L| ~ 30 at 0.16 Hz)
    v = nyquist_stability(f, _loop(L)(f), 0, model_loop=_loop(L))
    assert v.stable is None and v.label == "cannot tell" and "crossover" in v.reason
    f = np.linspace(1e-3, 50.0, 20000)
    v = nyquist_stability(f, _loop(L)(f), 0, model_loop=_loop(2 * L))
    assert v.stable is None and "disagree" in v.reason
    # a sharp resonance between the points: the unstable loop would look stable point by point
    L = 3.0 * control.ss(control.tf([1.0, 0.0], [1.0, 0.02, 1.0]))
    assert not _stable(control.feedback(L, 1, sign=1))
    f = np.linspace(1e-3, 50.0, 50)
    v = nyquist_stability(f, _loop(L)(f), 0, model_loop=_loop(L))
    assert v.stable is None and "coarse" in v.reason
    f = np.linspace(1e-3, 50.0, 400000)
    assert nyquist_stability(f, _loop(L)(f), 0, model_loop=_loop(L)).stable is False


@pytest.mark.parametrize("k", [-3.0, -0.5, 0.5, 3.0])
def test_nyquist_follows_resonances_sharper_than_any_grid(k):
    """A mode of damping 1e-6 at 5 Hz (behind a lag) and one of 1e-5 below the band: the
    yardstick's grid, a log grid plus points spread over each lightly damped pole's phase
    (its loop's and closed loop's poles), gives the closed-loop poles' verdict; a log grid of
    20,000 points misses the 5 Hz resonance (it cannot tell, or is right by luck)."""
    from robustctl.robust.yardsticks import _pole_points

    def mode(wn, zeta, dc):
        return control.ss(control.tf([dc * wn**2], [1.0, 2 * zeta * wn, wn**2]))

    L = k * (mode(2 * np.pi * 5.0, 1e-6, 1e-3) + mode(2 * np.pi * 0.02, 1e-5, 1e-6)) \
        * control.ss(control.tf([1.0], [0.02, 1.0]))
    closed = control.feedback(L, 1, sign=1)
    truth = _stable(closed)
    assert truth is (k > 0)
    poles = np.concatenate([L.poles(), closed.poles()])
    log = np.geomspace(0.1, 100.0, 20000)
    if k != 0.5:
        assert nyquist_stability(log, _loop(L)(log), 0, model_loop=_loop(L)).stable is None
    f = np.union1d(log, _pole_points(poles, 0.1, 100.0))
    assert nyquist_stability(f, _loop(L)(f), 0, model_loop=_loop(L), poles=poles).stable is truth


def test_block_structure_of_the_book_example():
    bs = as_block_structure(BOOK_BLOCKS)
    assert (bs.n_in, bs.n_out) == (4, 4)


@pytest.mark.slow
def test_executor_gives_the_same_iteration_and_results_render():
    from concurrent.futures import ThreadPoolExecutor

    P = distillation_plant()
    opts = {"max_iter": 3, "progress": False, "patience": 10, "autoscale": False}
    serial = dksyn((P, 2, 2, BOOK_BLOCKS), **opts)
    with ThreadPoolExecutor(2) as ex:
        threaded = dksyn((P, 2, 2, BOOK_BLOCKS), executor=ex, **opts)
    assert len(serial.history) == len(threaded.history) == 3
    # the executor ran the D fits of every order (iterations 1-2) and the extrapolated D
    # steps along the change of the scales (iteration 2, the candidates of iteration 3)
    assert serial.history[2].n_candidates > 1
    assert [h.n_candidates for h in threaded.history] == [h.n_candidates for h in serial.history]
    assert [h.d_orders for h in threaded.history] == [h.d_orders for h in serial.history]
    peaks = [h.mu_peak for h in serial.history]
    assert [h.mu_peak for h in threaded.history] == pytest.approx(peaks, rel=1e-6)
    assert threaded.mu_peak == pytest.approx(serial.mu_peak, rel=1e-6)
    assert serial.history[1].mu_peak < serial.history[0].mu_peak
    assert serial.plot() is not None and "<table>" in serial._repr_html_()
    with pytest.raises(Exception, match="executor"):
        dksyn((P, 2, 2, BOOK_BLOCKS), executor="threads")


@pytest.mark.parametrize("level", [0.3, 0.5])
def test_fitted_bound_is_the_scaled_loops_norm_including_dc(level):
    """The bound the D step reports is ``||D Fl(P, K) D^-1||_inf`` of the loop it was fitted on,
    checked by hinfnorm over all frequencies (not only the mu grid). On the Caltech plant an
    order-2 scale with a zero just below the grid fell 10x towards DC: the grid bound said
    1.02, the norm was 4.2 (at DC), and the next K step could not get below 3.8."""
    from robustctl.examples import caltech_design_plant, caltech_truss
    from robustctl.robust import hinfnorm
    from robustctl.robust.dk.iteration import (
        _complexified,
        _edge_response,
        _fit_d_scales,
        default_grid,
        mu_of,
    )
    from robustctl.robust.hinf.synthesis import hinfsyn

    plant = as_plant(caltech_design_plant(caltech_truss(), level=level))
    blocks = _complexified(plant.blocks)
    K = hinfsyn(plant.P, plant.nmeas, plant.ncon, backoff=1e-3).K
    for _ in range(2):  # the unscaled loop, then the loop of the first scaled K step
        cl = closed_loop(plant.P, K, plant.nmeas, plant.ncon)
        m, H = mu_of(cl, blocks, default_grid(plant.P), refine=True)
        fits, _, bound = _fit_d_scales(H, m, blocks, None, None, (), _edge_response(cl))
        scaled = _scale_plant(plant, fits)
        norm, _ = hinfnorm(closed_loop(scaled, K, plant.nmeas, plant.ncon))
        assert bound >= 0.99 * norm
        assert bound <= 1.25 * m.peak  # the fits stay close to the optimal scales
        K = hinfsyn(scaled, plant.nmeas, plant.ncon, backoff=1e-3).K
        assert np.all(np.linalg.eigvals(closed_loop(plant.P, K, plant.nmeas, plant.ncon).A).real < 0)


def _unscaled_distillation():
    """The column in the book's unscaled units, ``G0 / 100`` (Skogestad & Postlethwaite sec. 8.12.4)."""
    import control

    P = distillation_plant()
    B = np.array(P.B, dtype=float)
    B[0:2] *= 0.01  # the plant's first-order lag feeds G0 x: G0 / 100
    return control.ss(P.A, B, P.C, P.D, inputs=list(P.input_labels), outputs=list(P.output_labels))


def test_autoscaling_undoes_the_plant_units():
    # the scaled plant is the same whatever units the column is written in: the controls and
    # measurements at unit peak gain and the block scales from a covariant start
    from robustctl.robust.dk.iteration import _autoscaled, as_plant

    a, sa = _autoscaled(as_plant((distillation_plant(), 2, 2, BOOK_BLOCKS)))
    b, sb = _autoscaled(as_plant((_unscaled_distillation(), 2, 2, BOOK_BLOCKS)))
    f = np.logspace(-4, 1, 30)
    Ha, Hb = freqresp_array(a.P, f), freqresp_array(b.P, f)
    np.testing.assert_allclose(Ha, Hb, rtol=1e-6, atol=1e-9 * np.abs(Ha).max())
    np.testing.assert_allclose(sb.su, 100 * sa.su, rtol=1e-9)
    np.testing.assert_allclose(sb.d[:2], sa.d[:2] / 100, rtol=1e-3)


@pytest.mark.slow
def test_dk_result_does_not_depend_on_the_plant_units():
    # the book's unscaled column (G0 / 100) stopped at mu 1.09 (10 iterations) against 0.99
    # for the scaled one; automatically scaled, both reach the same mu, below 0.98
    from robustctl.robust.mu.bounds import mu

    out = []
    for P in (distillation_plant(), _unscaled_distillation()):
        dk = dksyn((P, 2, 2, BOOK_BLOCKS), progress=False)
        fw = np.logspace(-6, 2, 600)
        dense = mu(freqresp_array(dk.closed_loop, fw), dk.blocks, f_hz=fw, lower=False).peak
        assert dense <= dk.mu_peak * 1.002  # the returned loop is the user's plant's, verified
        out.append(dk.mu_peak)
    assert out[0] <= 0.98 and out[1] <= 0.98
    assert out[1] == pytest.approx(out[0], rel=0.01)


def test_fixed_design_level_sets_the_k_step_gamma():
    # the optimum of the first K step is 1.18; at a fixed level 1.5 the central controller
    # is designed there: its verified norm lies between the optimum and the level
    P = distillation_plant()
    free = dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False)
    fixed = dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False, gamma=1.5)
    assert free.history[0].gamma == pytest.approx(1.1818, abs=0.005)
    assert free.history[0].gamma * 1.01 < fixed.history[0].gamma <= 1.5 * (1 + 1e-6)
    # a level below the optimum leaves the optimum's design
    low = dksyn((P, 2, 2, BOOK_BLOCKS), max_iter=1, progress=False, autoscale=False, gamma=0.5)
    assert low.history[0].gamma == pytest.approx(free.history[0].gamma, rel=1e-9)
    with pytest.raises(SynthesisError, match="gamma"):
        dksyn((P, 2, 2, BOOK_BLOCKS), gamma=-1.0)



def test_himat_plant_is_the_mu_tools_interconnection():
    # the block-matrix construction against python-control's interconnect of the same pieces
    import control

    from robustctl.examples import himat_plant

    s = control.tf("s")
    for noise in (False, True):
        P, blocks = himat_plant(noise)
        G = control.ss(*(np.asarray(m) for m in (P.A[:4, :4], P.B[:4, -2:], P.C[-2:, :4], np.zeros((2, 2)))))
        wd = (50 * s + 5000) / (s + 1e4)
        wp = (0.5 * s + 0.9) / (s + 0.018) if noise else (0.5 * s + 1.5) / (s + 0.03)
        wn = (2 * s + 2.56) / (s + 320)
        f = np.array([0.01, 0.3, 3.0, 30.0])
        H = freqresp_array(P, f)
        Hg = freqresp_array(G, f)
        I2 = np.eye(2)
        for k, fk in enumerate(f):
            sk = 2j * np.pi * fk
            d, p, n = (complex(control.evalfr(w, sk)) for w in (wd, wp, wn))
            np.testing.assert_allclose(H[k, 0:2, -2:], d * I2, rtol=1e-9)  # z_del <- u
            np.testing.assert_allclose(H[k, 2:4, 0:2], p * Hg[k], rtol=1e-7)  # z_p <- pert
            np.testing.assert_allclose(H[k, 2:4, 2:4], p * I2, rtol=1e-9)  # z_p <- dist
            np.testing.assert_allclose(H[k, 4:6, -2:], Hg[k], rtol=1e-7)  # y <- u
            if noise:
                np.testing.assert_allclose(H[k, 4:6, 4:6], n * I2, rtol=1e-9)  # y <- noise input
        assert blocks == ([[2, 2], [4, 2]] if noise else [[2, 2], [2, 2]])


def test_himat_on_the_60_point_grid_completes_below_one():
    # mu-tools' himat_dk settings: logspace(-3, 3, 60) rad/s; the K step once failed there at
    # iteration 2 ("no feasible gamma up to 1e+14")
    from robustctl.examples import himat_plant

    P, blocks = himat_plant()
    dk = dksyn((P, 2, 2, blocks), f_hz=np.logspace(-3, 3, 60) / (2 * np.pi), progress=False)
    assert "failed" not in dk.stop_reason
    assert dk.mu_peak < 1.0


def _dense_mu_peak(cl, blocks, f_grid) -> float:
    """Peak of the complex mu upper bound of ``cl`` on 3000 log-spaced frequencies a decade
    beyond ``f_grid`` each way, DC, and 41 points across every closed-loop pole with damping
    below 0.3 (a grid of its own, not dksyn's verification grid)."""
    from robustctl.lti import pole_frequency_damping
    from robustctl.robust.mu.bounds import mu

    f_grid = np.asarray(f_grid)
    fpos = f_grid[f_grid > 0]
    parts = [np.zeros(1), np.logspace(np.log10(fpos[0]) - 1, np.log10(fpos[-1]) + 1, 3000)]
    fn, zeta = pole_frequency_damping(np.linalg.eigvals(np.asarray(cl.A)))
    for f0, z in zip(fn, zeta):
        if 0 < z < 0.3 and f0 > 0:
            parts.append(f0 * (1 + z * np.linspace(-3, 3, 41)))
    f = np.unique(np.concatenate(parts))
    return float(mu(freqresp_array(cl, f), blocks, f_hz=f, lower=False).peak)


@pytest.fixture(scope="module", params=[False, True], ids=["mkhic", "mkhicn"])
def himat_auto(request):
    """mu-tools' mkhic (``False``) or mkhicn (``True``) and its automatic D-order design."""
    from robustctl.examples import himat_plant

    P, blocks = himat_plant(request.param)
    return P, blocks, dksyn((P, 2, 2, blocks), progress=False)


@pytest.mark.slow
def test_automatic_d_order_on_himat_holds_on_a_dense_grid(himat_auto):
    _, blocks, auto = himat_auto
    dense = _dense_mu_peak(auto.closed_loop, blocks, auto.mu.f_hz)
    assert dense <= auto.mu_peak * (1 + 2e-3)
    assert auto.mu_peak <= dense * (1 + 2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("order", [3, 4, 5, 6])
def test_automatic_d_order_is_within_two_percent_of_each_fixed_order_on_himat(himat_auto, order):
    # mu-tools' mkhic / mkhicn: the automatic D orders against each fixed order with the same
    # defaults (max_iter 10); on mkhicn the automatic choice alone crept to 0.980 where order
    # 3 reaches 0.954. Orders 0-2 stay >= 4.6 % above the best fixed order on both (bench_dk:
    # mkhic 1.500 1.074 1.002 against order 5's 0.943, mkhicn 1.507 1.098 0.998 against order
    # 3's 0.954), so the best fixed order is among 3-6.
    P, blocks, auto = himat_auto
    fixed = dksyn((P, 2, 2, blocks), order_d=order, progress=False)
    assert auto.mu_peak <= 1.02 * fixed.mu_peak



def test_the_line_search_screen_skips_only_candidates_that_cannot_win(monkeypatch):
    """A line-search candidate infeasible at the best verified gamma so far is not synthesised
    (robustctl.robust.hinf.synthesis.gamma_feasible): three iterations of the distillation
    column (three candidates in the third K step) give the same gammas, peaks and
    controller bit for bit as with every candidate synthesised, and fewer syntheses."""
    import robustctl.robust.dk.iteration as dki

    calls = []
    real = dki.hinfsyn

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(dki, "hinfsyn", counted)
    gp = (distillation_plant(), 2, 2, BOOK_BLOCKS)
    screened = dksyn(gp, max_iter=3, order_d=4, autoscale=False, progress=False, patience=3)
    n_screened = len(calls)
    monkeypatch.setattr(dki, "gamma_feasible", lambda *a, **k: True)
    calls.clear()
    full = dksyn(gp, max_iter=3, order_d=4, autoscale=False, progress=False, patience=3)
    assert [h.gamma for h in screened.history] == [h.gamma for h in full.history]
    assert [h.mu_peak for h in screened.history] == [h.mu_peak for h in full.history]
    assert np.array_equal(np.asarray(screened.K.A), np.asarray(full.K.A))
    assert sum(h.n_candidates for h in full.history) > len(full.history)  # the line search ran
    assert n_screened < len(calls)
