"""Controller reduction: Enns' weighted balanced truncation with the closed-loop weight, coprime factors."""

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import SynthesisError
from robustctl.lti import freqresp_array
from robustctl.robust.reduction.controller import (
    coprime_reduction,
    reduce_controller,
    weighted_balanced_truncation,
)

s = control.tf("s")


def flexible_plant():
    """Four alternating-sign lightly damped modes (a collocated-like structure)."""
    G = sum(control.tf([w**2 * (-1) ** i], [1, 2 * 0.02 * w, w**2]) for i, w in enumerate([1, 3, 7, 15]))
    G = control.ss(G)
    return control.ss(G.A, G.B, G.C, G.D, inputs=["u"], outputs=["y"])


@pytest.fixture(scope="module")
def loop():
    G = flexible_plant()
    res = rc.ncfsyn(G, (s + 2) / (s + 0.01), factor=1.1)
    return G, res.K


def test_unweighted_enns_is_balanced_truncation(loop):
    _, K = loop
    ours = weighted_balanced_truncation(K, 6).K
    ref = rc.balanced_truncation(K, 6).sys
    f = np.geomspace(0.01, 10, 50)
    np.testing.assert_allclose(freqresp_array(ours, f), freqresp_array(ref, f), rtol=1e-7, atol=1e-10)


def test_closed_loop_weight_error_and_stability_guarantee(loop):
    G, K = loop
    red = weighted_balanced_truncation(K, 6, plant=G)
    assert red.info["closed_loop_weight"] and red.stability_radius == 1.0
    # the reported error is ||(K - Kr)(I - G K)^-1 G||_inf: compare with a dense grid
    M = control.feedback(G, K, sign=+1)  # (I - G K)^-1 G = G (I - K G)^-1
    f = np.unique(np.concatenate([np.geomspace(1e-3, 100, 20000)]))
    E = (freqresp_array(K, f) - freqresp_array(red.K, f)) @ freqresp_array(M, f)
    grid = np.max(np.abs(E[:, 0, 0]))
    assert grid <= red.error * (1 + 1e-8) and grid >= 0.98 * red.error
    # error < 1 certifies the reduced loop (small gain), and the direct check agrees
    assert red.error < 1 and red.guaranteed
    assert red.closed_loop_stable is True
    assert rc.is_stable(control.feedback(G, red.K, sign=+1))
    assert list(red.K.input_labels) == list(K.input_labels)


def test_coprime_reduction_bound_and_exactness(loop):
    G, K = loop
    red = coprime_reduction(K, 7, plant=G)
    assert red.error <= red.bound * (1 + 1e-9)  # 2 sum of the discarded Hankel singular values
    assert red.error >= red.hsv[7] * (1 - 1e-9)  # no truncation beats the first discarded sigma
    full = coprime_reduction(K, K.nstates - 1, plant=G)
    # one discarded sigma of 1.2e-8: the error, an H-inf norm of a difference of factors of norm
    # ~ hsv[0], is computed to an absolute accuracy of a few eps x hsv[0] (1e-10 x hsv[0] here: on
    # OpenBLAS's Sandybridge kernel the error exceeded the bound by 6.7e-12, 2.7e-4 of it)
    assert full.error <= full.bound * (1 + 1e-9) + 1e-10 * full.hsv[0]


def test_coprime_reduction_of_an_unstable_controller():
    # a real RHP zero (s = 1) and infinity enclose one real RHP pole (s = 2): the parity interlacing
    # property fails, so every stabilising controller is unstable (Youla et al. 1974)
    G = control.ss((s - 1) / ((s - 2) * (s + 3)) * (10 / (s + 10)) * (4 / (s**2 + 0.2 * s + 4)))
    K = rc.ncfsyn(G, factor=1.05).K
    assert not rc.is_stable(K)
    with pytest.raises(SynthesisError, match="stable controller"):
        weighted_balanced_truncation(K, K.nstates - 1, plant=G)
    red = reduce_controller(K, K.nstates - 1, G)
    assert red.method == "coprime" and red.K.nstates == K.nstates - 1
    assert red.error <= red.bound * (1 + 1e-9)
    # error below b(G, K): stability is certified, and the direct check agrees
    assert red.stability_radius == pytest.approx(rc.stability_margin(G, K), rel=1e-12)
    assert red.guaranteed and red.closed_loop_stable is True
    assert rc.is_stable(control.feedback(G, red.K, sign=+1))
    # two states fewer: the error exceeds the radius and this loop is indeed unstable
    red3 = reduce_controller(K, K.nstates - 2, G)
    assert not red3.guaranteed and red3.closed_loop_stable is False


def test_reduction_refuses_bad_input(loop):
    _, K = loop
    with pytest.raises(SynthesisError, match="order"):
        reduce_controller(K, K.nstates)
    with pytest.raises(SynthesisError, match="method"):
        reduce_controller(K, 3, method="modal")
    with pytest.raises(SynthesisError, match="continuous"):
        reduce_controller(control.c2d(K, 0.01), 3)
    red = reduce_controller(K, 6, flexible_plant())
    assert "reduced from" in red.summary() and "method" in str(red.table()) and red.plot().axes


def test_dksyn_weighted_and_coprime_reduction_options():
    from test_dk import BOOK_BLOCKS, distillation_plant

    P = distillation_plant()
    # at 4 of 6 states, plain balanced truncation wrecks the loop (peak mu 1.18 -> 23) while the
    # closed-loop weight keeps it near (1.21): the weight puts the error where the loop is sensitive
    opts = {"max_iter": 1, "progress": False, "autoscale": False}
    runs = {method: rc.dksyn((P, 2, 2, BOOK_BLOCKS), reduce=(method, 4) if method != "balanced" else 4,
                             **opts) for method in ("balanced", "weighted", "coprime")}
    plain, weighted = runs["balanced"].reduction, runs["weighted"].reduction
    assert weighted.mu_peak_after < 1.1 * weighted.mu_peak_before < plain.mu_peak_after
    for method in ("weighted", "coprime"):
        dk = runs[method]
        r = dk.reduction
        assert r is not None and r.order_before == 6 and r.order_after == 4
        assert r.method == method and np.isfinite(r.error) and r.error > 0
        if r.accepted:
            assert dk.K.nstates == 4 and r.mu_peak_after <= r.mu_peak_before * 1.02
        else:
            assert dk.K.nstates == 6 and r.reason
    # the plain truncation's figure is the a-priori bound 2 sum of the discarded Hankel singular values
    assert plain.method == "balanced" and plain.error > 0
