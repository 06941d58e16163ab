"""fit_rational: exact recovery, method agreement, stability, realisation, and bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import polynomial as poly
from test_identify_support import BAND, F_MODES, ZETA, caltech_measurement, exact_data, truss_system

import robustctl as rc
from robustctl.identify import IdentifyWarning
from robustctl.identify.chebyshev import chebyshev_basis, chebyshev_roots

F_GRID = np.linspace(0.5, 5.5, 400)


def _modal(fit):
    keep = (fit.poles.imag != 0) & (fit.f_hz > BAND[0]) & (fit.f_hz < BAND[1]) & (fit.zeta < 0.2)
    order = np.argsort(fit.f_hz[keep])
    return fit.f_hz[keep][order], fit.zeta[keep][order]


# --------------------------------------------------------------------------- reference checks
def test_chebyshev_basis_is_j_power_times_chebyshev_polynomial():
    x = np.linspace(-1, 1, 7)
    basis = chebyshev_basis(x, 4)
    t4 = 8 * x**4 - 8 * x**2 + 1  # T_4
    np.testing.assert_allclose(basis[:, 4], t4 * (1j**4))
    np.testing.assert_allclose(basis[:, 3], (4 * x**3 - 3 * x) * (1j**3))


def test_chebyshev_roots_match_power_basis_roots():
    # sum_m c_m j^m T_m(x) with x = -j s: convert to power form in x, take companion roots, s = j x
    coef = np.array([0.3, -1.2, 0.7, 2.0, 0.4])
    power_x = np.polynomial.chebyshev.cheb2poly(coef * 1j ** np.arange(coef.size))
    expected = 1j * poly.polyroots(power_x)
    got = chebyshev_roots(coef)
    np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(expected), rtol=1e-9)
    # the polynomial is real in s, so the roots are conjugate-symmetric
    assert np.max(np.abs(np.poly(got).imag)) < 1e-12


@pytest.mark.parametrize("method", ["chebyshev", "vf"])
def test_exact_mimo_system_is_recovered_to_machine_precision(method):
    data = exact_data(truss_system(), F_GRID)
    fit = rc.fit_rational(data, 12, method=method)
    err = np.max(np.abs(fit.response(F_GRID) - data.response)) / np.max(np.abs(data.response))
    assert err < 1e-8
    f, z = _modal(fit)
    np.testing.assert_allclose(f, F_MODES, rtol=1e-8)
    np.testing.assert_allclose(z, ZETA, rtol=1e-6)


@pytest.mark.parametrize("method", ["chebyshev", "vf"])
def test_odd_order_recovers_a_real_pole(method):
    f = np.linspace(0.1, 10, 300)
    s = 2j * np.pi * f
    g = 3.0 / (s + 4.0) + (1 + 2j) / (s - (-0.5 + 20j)) + (1 - 2j) / (s - (-0.5 - 20j)) + 0.2
    fit = rc.fit_rational((f, g), 3, method=method)
    real = fit.poles[fit.poles.imag == 0]
    np.testing.assert_allclose(real.real, [-4.0], rtol=1e-8)
    np.testing.assert_allclose(fit.response(f)[:, 0, 0], g, rtol=1e-8)


def test_chebyshev_and_vf_agree_on_measured_data():
    data = caltech_measurement()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifyWarning)
        cheb = rc.fit_rational(data, 12, band=BAND, method="chebyshev")
        vf = rc.fit_rational(data, 12, band=BAND, method="vf")
    # well-separated modes (2.26, 2.66, 2.75, 4.43 Hz) agree closely; costs agree within 25 %
    for fm in F_MODES[2:]:
        fc = cheb.f_hz[np.argmin(np.abs(cheb.f_hz - fm))]
        fv = vf.f_hz[np.argmin(np.abs(vf.f_hz - fm))]
        assert abs(fc - fv) / fm < 2e-3
    jc, jv = cheb.cost().total, vf.cost().total
    assert abs(jc - jv) / min(jc, jv) < 0.25
    gc, gv = cheb.response(data.band(*BAND).f_hz), vf.response(data.band(*BAND).f_hz)
    assert np.sqrt(np.mean(np.abs(np.log(gc / gv)) ** 2)) < 0.1  # < 0.9 dB rms between the models


def test_statespace_realisation_matches_pole_residue_response_and_names():
    data = exact_data(truss_system(), F_GRID)
    fit = rc.fit_rational(data, 12, method="vf")
    ss = fit.statespace()
    assert ss.input_labels == ["a1", "a2", "a3"] and ss.output_labels == ["s1", "s2", "s3"]
    g_ss = rc.freqresp(ss, F_GRID).response
    np.testing.assert_allclose(g_ss, fit.response(F_GRID), rtol=1e-9, atol=1e-12)
    # 2x2 blocks per complex pair: the A matrix is block diagonal with rotation blocks
    a = ss.A
    assert np.allclose(a[0, 2:], 0) and np.isclose(a[0, 0], a[1, 1]) and np.isclose(a[0, 1], -a[1, 0])
    assert np.all(np.linalg.eigvals(a).real < 0)


def test_unstable_poles_are_reflected_and_residues_refitted():
    f = np.linspace(0.5, 5, 300)
    s = 2j * np.pi * f
    p = 0.3 + 2j * np.pi * 2.0  # unstable mode: |G(jw)| equals that of its reflection times an all-pass
    g = (1 / (s - p) + 1 / (s - np.conj(p))) * 5.0
    fit = rc.fit_rational((f, g), 2, method="vf")
    assert np.all(fit.poles.real < 0)
    np.testing.assert_allclose(fit.poles[0], -0.3 + 2j * np.pi * 2.0, rtol=1e-6)
    loose = rc.fit_rational((f, g), 2, method="vf", stable=False)
    np.testing.assert_allclose(loose.poles[0], p, rtol=1e-8)


def test_pole_outside_band_warns():
    f = np.linspace(1, 3, 200)
    s = 2j * np.pi * f
    g = 1.0 / (s**2 + 2 * 0.01 * 12 * s + 144.0) + 0.5 / (s**2 + 2 * 0.02 * 60 * s + 3600.0)
    with pytest.warns(IdentifyWarning, match="outside the band"):
        rc.fit_rational((f, g), 4, method="vf")


@pytest.mark.filterwarnings("ignore::robustctl.identify.IdentifyWarning")
def test_simo_fits_per_input_combine_to_the_sum_of_their_states():
    data = exact_data(truss_system(), F_GRID)
    fit = rc.fit_rational(data, 12, common_denominator=False, method="vf")
    simo = [rc.fit_rational(data.select(inputs=[k]), 12, method="vf") for k in range(3)]
    assert fit.method == "combined" and fit.statespace().nstates == sum(f.n_states for f in simo)
    assert fit.order == 36 and all(f.order == 12 for f in simo)
    np.testing.assert_allclose(fit.response(F_GRID), data.response, rtol=1e-7, atol=1e-9)


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("order", [0, -2, 2.5, True])
def test_bad_order_is_refused(order):
    data = exact_data(truss_system(), F_GRID)
    with pytest.raises(rc.FitError, match="order must be a positive"):
        rc.fit_rational(data, order)


def test_band_with_too_few_points_is_refused():
    data = exact_data(truss_system(), F_GRID)
    with pytest.raises(rc.FitError, match="needs at least 13 points"):
        rc.fit_rational(data, 12, band=(1.0, 1.1))


def test_all_zero_data_is_refused():
    with pytest.raises(rc.DataError, match="identically zero"):
        rc.fit_rational((F_GRID, np.zeros(F_GRID.size)), 4)


def test_nan_data_is_refused():
    g = np.ones(F_GRID.size, dtype=complex)
    g[5] = np.nan
    with pytest.raises(rc.DataError, match="NaN"):
        rc.fit_rational((F_GRID, g), 4)


def test_nan_weights_and_unknown_method_are_refused():
    data = exact_data(truss_system(), F_GRID)
    w = np.ones(F_GRID.size)
    w[3] = np.nan
    with pytest.raises(rc.DataError, match="point_weights must be finite"):
        rc.fit_rational(data, 12, point_weights=w)
    with pytest.raises(rc.FitError, match="unknown method"):
        rc.fit_rational(data, 12, method="prony")
    with pytest.raises(rc.FitError, match="max_iter"):
        rc.fit_rational(data, 12, max_iter=0)
    with pytest.raises(rc.DataError, match="band .* holds 0 data points"):
        rc.fit_rational(data, 12, band=(100, 200))


def test_fast_gram_elimination_equals_the_qr_elimination():
    """The VF Gram path (partial-fraction moments for all channels) must give the same normal
    matrix of the sigma unknowns and the same current-pole cost as the per-channel QR path."""
    from robustctl.identify.poles import partial_fraction_basis
    from robustctl.identify.vector_fitting import _channel_blocks, _gram_normal, initial_poles

    rng = np.random.default_rng(0)
    s = 1j * np.linspace(0.1, 1, 200)
    g = rng.normal(size=(200, 4)) + 1j * rng.normal(size=(200, 4))
    rw = rng.uniform(0.5, 2, size=(200, 4))
    poles = initial_poles(7, 0.1, 1.0)
    phi = partial_fraction_basis(s, poles)
    normal, cost = _gram_normal(s, poles, g, rw)
    blocks, cost_qr = _channel_blocks(phi, g, rw)
    ref = sum(b.T @ b for b in blocks)
    np.testing.assert_allclose(normal, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(cost, cost_qr, rtol=1e-10)


def test_weights_prepared_once_give_the_same_gram_blocks_relocations_and_residues():
    """Weight columns prepared once (GramWeights, StepWeights, NormalWeights; with working arrays
    kept between calls) must give exactly (==) the numbers formed per call: the measurement
    model's fits are decided by round-off, so a reuse that moved them by one ulp would change
    models. Calls alternate between pole sets of equal and of different size (kept arrays
    reused and replaced)."""
    from robustctl.identify.poles import GramWeights, basis_gram
    from robustctl.identify.stabilisation import NormalWeights, residues_normal
    from robustctl.identify.vector_fitting import StepWeights, _gram_weights, initial_poles, vf_step

    rng = np.random.default_rng(5)
    s = 1j * np.linspace(0.1, 1.0, 300)
    g = rng.normal(size=(300, 6)) + 1j * rng.normal(size=(300, 6))
    rw = rng.uniform(0.5, 2.0, size=(300, 6))
    a, b = initial_poles(8, 0.1, 1.0), initial_poles(8, 0.12, 0.97) * (1 + 0.01j)
    c = np.r_[initial_poles(10, 0.1, 1.0), -0.3 + 0j]
    v = _gram_weights(g, rw)
    kept, step, normal = GramWeights(v, reuse=True), StepWeights(g, rw), NormalWeights(g, rw)
    for poles in (a, b, c, a, a):
        ref = basis_gram(s, poles, v)
        assert np.array_equal(basis_gram(s, poles, kept), ref)
        for gram in (True, False):  # the Gram path, and the QR path (the relaxation row's scale)
            new_ref, cost_ref = vf_step(s, g, rw, poles, gram=gram)
            new, cost = vf_step(s, g, rw, poles, gram=gram, weights=step)
            assert np.array_equal(new, new_ref) and cost == cost_ref
        res_ref, d_ref = residues_normal(s, g, rw, poles * 50)
        res, d = residues_normal(s, g, rw, poles * 50, normal)
        assert np.array_equal(res, res_ref) and np.array_equal(d, d_ref)


def test_moment_gram_equals_the_direct_product_for_light_damping_and_close_pairs():
    """basis_gram forms Re(B^H diag(v) B) from first moments of the partial fractions; it must
    match the O(K n^2) product to ~eps relative to the diagonal even with damping 1e-5, a pair
    0.01 % apart, a real pole and complex weights (a cancellation would show as 1e-8 or worse)."""
    from robustctl.identify.poles import basis_gram, partial_fraction_basis

    rng = np.random.default_rng(1)
    s = 1j * np.linspace(0.1, 1.0, 500)
    wn = rng.uniform(0.15, 0.95, 8)
    zeta = np.r_[1e-5, rng.uniform(1e-4, 0.05, 7)]
    poles = np.r_[-zeta * wn + 1j * wn, (-zeta[3] * wn[3] + 1j * wn[3]) * (1 + 1e-4), -0.4 + 0j]
    basis = np.hstack([partial_fraction_basis(s, poles), np.ones((s.size, 1))])
    noise = rng.normal(size=(s.size, 2)) + 1j * rng.normal(size=(s.size, 2))
    v = np.c_[rng.uniform(0.2, 3, (s.size, 2)), noise]
    gram = basis_gram(s, poles, v)
    assert gram.shape == (4, basis.shape[1], basis.shape[1])
    for c in range(v.shape[1]):
        ref = ((np.conj(basis).T * v[:, c]) @ basis).real
        d = np.sqrt(np.abs(np.diag(ref)))
        assert np.max(np.abs(gram[c] - ref) / np.outer(d, d)) < 1e-12


@settings(max_examples=25, deadline=None)
@given(
    n_pairs=st.integers(1, 4),
    n_real=st.integers(0, 2),
    n_out=st.integers(1, 3),
    n_in=st.integers(1, 3),
    seed=st.integers(0, 10_000),
)
def test_modal_realisation_reproduces_any_pole_residue_model(n_pairs, n_real, n_out, n_in, seed):
    """Property: the real 2x2-block realisation equals the pole-residue formula for random
    stable models, whatever the residue ranks."""
    from robustctl.identify.poles import evaluate
    from robustctl.identify.rational import RationalFit
    from robustctl.identify.realization import residue_rank

    rng = np.random.default_rng(seed)
    w = rng.uniform(1, 30, n_pairs)
    poles = np.concatenate(
        [-rng.uniform(0.01, 0.5, n_pairs) * w + 1j * w, -rng.uniform(0.5, 20, n_real) + 0j]
    )
    res = rng.normal(size=(poles.size, n_out, n_in)) + 1j * rng.normal(size=(poles.size, n_out, n_in))
    res[n_pairs:] = res[n_pairs:].real
    d = rng.normal(size=(n_out, n_in))
    ranks = np.array([residue_rank(r) for r in res])
    fit = RationalFit(
        poles,
        res,
        d,
        ranks,
        tuple(f"u{k}" for k in range(n_in)),
        tuple(f"y{k}" for k in range(n_out)),
        (0.1, 10.0),
        "test",
    )
    f = np.linspace(0.05, 8, 60)
    np.testing.assert_allclose(
        rc.freqresp(fit.statespace(), f).response,
        evaluate(2j * np.pi * f, poles, res, d),
        rtol=1e-9,
        atol=1e-9,
    )


def test_dense_low_modes_of_a_wide_band_are_all_found():
    """40 log-spaced modes over 20-820 Hz (8 % apart at the bottom, a few grid points): VF from
    linearly spread poles misses several of the low modes after 30 iterations; start_poles="data"
    (also poles where the data change, the lower cost kept) finds every mode within 0.1 %."""
    import warnings

    from robustctl.identify import IdentifyWarning
    from robustctl.identify._problem import prepare_problem
    from robustctl.identify.vector_fitting import vf_poles

    data, truth = rc.examples.modal_test_case(
        n_in=2, n_out=2, n_modes=40, n_pairs=0, n_freq=1200, f_range=(20.0, 820.0), seed=12
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifyWarning)
        fit = rc.fit_rational(data, 88, start_poles="data")

    def worst(f_hz):
        return max(np.min(np.abs(f_hz / ft - 1)) for ft in truth.f_hz)

    assert worst(fit.f_hz) < 1e-3
    prob = prepare_problem(data, 88, None, "auto")
    g = prob.g.reshape(prob.s.size, -1)
    w_s = np.abs(prob.s).max()
    lin, _, _ = vf_poles(prob.s / w_s, g, np.sqrt(prob.w.reshape(g.shape)) / np.abs(g), 88, 30, spacing="lin")
    assert worst(np.abs(lin * w_s) / (2 * np.pi)) > 0.02


def test_rank_one_residue_sweeps_recover_exact_shapes_from_a_poor_start():
    """refine_residues solves every output (and input) at once from the shared moment Gram
    matrices: on noise-free rank-1 data with the true poles it must recover c b^T of every mode
    (to 1e-8) from residues scrambled by 30 %, complex shapes and a real filler pole included."""
    from dataclasses import replace

    from robustctl.identify.rational import RationalFit
    from robustctl.identify.refine import refine_residues

    rng = np.random.default_rng(4)
    f = np.linspace(5, 60, 400)
    wn = 2 * np.pi * np.array([12.0, 12.2, 31.0, 47.0])
    poles = np.r_[-np.array([0.01, 0.004, 0.02, 0.002]) * wn + 1j * wn, -300.0 + 0j]
    cs = rng.normal(size=(4, 3)) + 1j * rng.normal(size=(4, 3))
    bs = rng.normal(size=(4, 2)) + 0.3j * rng.normal(size=(4, 2))
    res = np.concatenate([cs[:, :, None] * bs[:, None, :], 50 * rng.normal(size=(1, 3, 2)) + 0j])
    d = rng.normal(size=(3, 2))
    truth = RationalFit(poles, res, d, np.array([1, 1, 1, 1, 1]), ("u1", "u2"), ("y1", "y2", "y3"),
                        (5.0, 60.0), "vf")
    data = rc.FrequencyData(f, truth.response(f), inputs=("u1", "u2"), outputs=("y1", "y2", "y3"))
    scrambled = res * (1 + 0.3 * rng.normal(size=res.shape))
    scrambled[-1] = res[-1]  # real poles keep their residues
    start = replace(truth, residues=scrambled, d=np.zeros_like(d), data=data)
    out = refine_residues(start, sweeps=100)  # ALS converges slowly on the 12.0/12.2 Hz pair
    np.testing.assert_allclose(out.residues[:4], res[:4], atol=1e-8 * np.abs(res).max())
    np.testing.assert_allclose(out.d, d, atol=1e-8)
