"""Uncertain models from what the update knows: the parametric LFT, its box, and the plant it feeds."""

from __future__ import annotations

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import FitError, ModelError
from robustctl.lti import freqresp_array
from robustctl.physical.uncertain import parametric_lft

NOMINAL = {"k1": 1000.0, "k2": 500.0, "m1": 1.0, "m2": 0.5, "c1": 0.5, "c2": 0.3}
F = np.linspace(1.0, 12.0, 120)


def receptance(th, f_hz):
    """x / f of the ground-k1-m1-k2-m2 chain by direct inversion (numpy only)."""
    M = np.diag([th["m1"], th["m2"]])
    K = np.array([[th["k1"] + th["k2"], -th["k2"]], [-th["k2"], th["k2"]]])
    C = np.array([[th["c1"] + th["c2"], -th["c2"]], [-th["c2"], th["c2"]]])
    return np.array([np.linalg.inv(K + 2j * np.pi * f * C - (2 * np.pi * f) ** 2 * M) for f in f_hz])


def chain(**values) -> rc.PhysicalModel:
    """The chain in physical coordinates (its state-space matrices are affine in k1, k2, c1, c2)."""
    vals = {**NOMINAL, **values}
    params = [rc.Parameter(n, v, bounds=(1e-6, 1e6)) for n, v in vals.items()]

    def dynamics(th, _struct):
        M = np.diag([th["m1"], th["m2"]])
        Mi = np.linalg.inv(M)
        K = np.array([[th["k1"] + th["k2"], -th["k2"]], [-th["k2"], th["k2"]]])
        C = np.array([[th["c1"] + th["c2"], -th["c2"]], [-th["c2"], th["c2"]]])
        A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Mi @ K, -Mi @ C]])
        B = np.vstack([np.zeros((2, 2)), Mi])
        return control.ss(A, B, np.hstack([np.eye(2), np.zeros((2, 2))]), np.zeros((2, 2)),
                          inputs=["f1", "f2"], outputs=["x1", "x2"])

    return rc.PhysicalModel(params=params, dynamics=dynamics, name="2-dof chain")


def test_stiffness_lft_is_exact_and_matches_direct_inversion():
    cov = np.array([[400.0, 150.0], [150.0, 100.0]])  # correlated k1, k2 (N/m)^2
    um = parametric_lft(chain(), ["k1", "k2"], [1000.0, 500.0], cov, n_sigma=2.0)
    assert um.exact and um.max_error < 1e-9
    # each axis mixes the two rank-1 stiffness patterns: a rank-2 change of A, a 2 x 2 repeated block
    assert um.multiplicity == (2, 2)
    # the box holds the 2-sigma ellipsoid along the principal axes: a Sigma^-1 a^T = 4 I
    np.testing.assert_allclose(um.axes @ np.linalg.solve(cov, um.axes.T), 4.0 * np.eye(2), atol=1e-9)
    delta = np.array([0.7, -0.4])
    th = {**NOMINAL, **um.parameter_values(delta)}
    np.testing.assert_allclose(freqresp_array(um.statespace(delta), F), receptance(th, F), rtol=1e-8,
                               atol=1e-14)


def test_mass_lft_is_first_order_with_its_error_stated():
    # M^-1 is not affine in m1: the LFT is the first-order one and says how far it is off
    um = parametric_lft(chain(), ["m1"], [1.0], [[0.05**2]], n_sigma=2.0, f_hz=F)
    assert not um.exact
    th = {**NOMINAL, "m1": 1.1}  # the box's end
    err = np.abs(freqresp_array(um.statespace([1.0]), F) - receptance(th, F)).max()
    assert um.max_error >= err / np.abs(freqresp_array(um.nominal, F)).max() * (1 - 1e-9)
    assert 0 < um.max_error < 1.0


def test_parametric_lft_refuses_a_zero_covariance():
    with pytest.raises(ModelError, match="covariance is zero"):
        parametric_lft(chain(), ["k1"], [1000.0], [[0.0]])


@pytest.fixture(scope="module")
def update_result():
    rng = np.random.default_rng(3)
    truth = {**NOMINAL, "k1": 1080.0, "k2": 470.0}
    g = receptance(truth, F)
    g = g * (1 + 0.02 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(F, g, inputs=["f1", "f2"], outputs=["x1", "x2"])
    return rc.update(chain(), data, params=["k1", "k2"], progress=False)


def test_update_result_uncertain_spans_the_fit(update_result):
    upd = update_result
    um = upd.uncertain(n_sigma=2.0)
    names = tuple(upd.fit.names)
    assert um.parameters == names and um.exact
    np.testing.assert_allclose(um.center, upd.fit.x_array)
    cov = np.asarray(upd.fit.covariance)
    np.testing.assert_allclose(um.axes @ np.linalg.solve(cov, um.axes.T), 4.0 * np.eye(len(names)), atol=1e-6)
    one = upd.uncertain(n_sigma=3.0, params=[names[0]])
    assert one.parameters == (names[0],)
    assert one.axes[0, 0] == pytest.approx(3.0 * np.sqrt(cov[0, 0]), rel=1e-9)
    with pytest.raises(FitError, match="params must be among"):
        upd.uncertain(params=["c1"])


def test_generalized_plant_takes_the_uncertain_model(update_result):
    um = update_result.uncertain()
    gp = rc.generalized_plant(um, performance=1.0, control_weight=0.1, noise=0.01)
    assert [b.kind for b in gp.blocks.blocks[:len(um.names)]] == ["real"] * len(um.names)
    plain = rc.generalized_plant(um.nominal, performance=1.0, control_weight=0.1, noise=0.01)
    nd = um.n_delta
    f = np.array([2.0, 5.0, 9.0])
    H = freqresp_array(gp.P, f)
    np.testing.assert_allclose(H[:, nd:, nd:], freqresp_array(plain.P, f), rtol=1e-9, atol=1e-15)
    # closing the parametric channels with delta reproduces the model at those parameters
    delta = np.array([1.0] + [0.0] * (len(um.names) - 1))
    Dl = np.diag(np.repeat(delta, um.multiplicity))
    loop = np.linalg.solve(np.eye(nd) - H[:, :nd, :nd] @ Dl, H[:, :nd, nd:])
    Hd = H[:, nd:, nd:] + H[:, nd:, :nd] @ Dl @ loop
    th = {**NOMINAL, **um.parameter_values(delta)}
    ny = 2
    G = receptance(th, f)  # perf_y = y_true = G u: the rows after z_delta, the u columns (last two)
    np.testing.assert_allclose(Hd[:, :ny, -2:], G, rtol=1e-7)


def test_axes_do_not_depend_on_the_parameters_units():
    # a stiffness in N/m and a mass in kg: both are uncertain whatever their numbers, and
    # the box is the same with the stiffness in kN/m
    cov = np.diag([50.0**2, 0.02**2])
    um = parametric_lft(chain(), ["k1", "m1"], [1000.0, 1.0], cov, n_sigma=2.0)
    assert len(um.names) == 2
    np.testing.assert_allclose(um.axes @ np.linalg.solve(cov, um.axes.T), 4.0 * np.eye(2), atol=1e-9)
    np.testing.assert_allclose(np.abs(um.axes).max(axis=0), [100.0, 0.04], rtol=1e-9)


def modal_chain() -> rc.PhysicalModel:
    """The chain re-solved into modal coordinates at every parameter value (its basis moves)."""
    params = [rc.Parameter(n, v, bounds=(1e-6, 1e6)) for n, v in NOMINAL.items()]

    def dynamics(th, _struct):
        M = np.diag([th["m1"], th["m2"]])
        K = np.array([[th["k1"] + th["k2"], -th["k2"]], [-th["k2"], th["k2"]]])
        w2, phi = np.linalg.eigh(np.linalg.solve(np.sqrt(M), np.linalg.solve(np.sqrt(M), K).T))
        phi = np.linalg.solve(np.sqrt(M), phi)  # mass-normalised shapes
        phi = phi * np.sign(phi[0])[None, :]
        if th["k2"] < 500.0:  # an eigen-solver's arbitrary sign: the basis flips inside the box
            phi[:, 1] = -phi[:, 1]
        w = np.sqrt(w2)
        A = np.zeros((4, 4))
        for i in range(2):
            A[2 * i:2 * i + 2, 2 * i:2 * i + 2] = [[0, 1], [-w2[i], -2 * 0.01 * w[i]]]
        B = np.zeros((4, 2))
        B[1::2] = phi.T
        C = np.zeros((2, 4))
        C[:, 0::2] = phi
        return control.ss(A, B, C, np.zeros((2, 2)), inputs=["f1", "f2"], outputs=["x1", "x2"])

    return rc.PhysicalModel(params=params, dynamics=dynamics, name="modal chain")


def test_modal_form_follows_each_modes_frequency():
    # a stiffness moves both modes' frequencies and (a little) their shapes; in the model's
    # own basis, which flips inside the box, the first-order LFT is meaningless; in the
    # nominal's modal coordinates with the eigenvalues moving it follows the modes (at 1 %
    # damping a first-order frequency error still shows near the peaks: 25 % of the peak
    # response), and its stated error holds at the box's end
    um = parametric_lft(modal_chain(), ["k2"], [500.0], [[25.0**2]], n_sigma=2.0, f_hz=F)
    assert um.form == "modal" and not um.exact
    model = modal_chain()
    end = freqresp_array(model.statespace(k2=550.0), F)
    peak = np.abs(freqresp_array(um.nominal, F)).max()
    err = np.abs(end - freqresp_array(um.statespace([1.0]), F)).max() / peak
    assert err <= um.max_error * (1 + 1e-9) and um.max_error < 0.5


def chain_poles(th):
    """Upper-half-plane eigenvalues of the chain (numpy: the quadratic eigenproblem as a 4 x 4 one)."""
    M = np.diag([th["m1"], th["m2"]])
    K = np.array([[th["k1"] + th["k2"], -th["k2"]], [-th["k2"], th["k2"]]])
    C = np.array([[th["c1"] + th["c2"], -th["c2"]], [-th["c2"], th["c2"]]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam = np.linalg.eigvals(A)
    return np.sort_complex(lam[lam.imag > 0])


def test_modes_form_moves_each_mode_to_the_sampled_frequency():
    # a 5 % stiffness: both modes move by a few half-power bandwidths at 3 sigma; the modes
    # form gives one real scalar per mode, and the LFT member standing for a sampled model
    # has that model's eigenvalues (to second order in the shift)
    um = parametric_lft(chain(), ["k2"], [500.0], [[25.0**2]], n_sigma=3.0, f_hz=F, form="modes")
    assert um.form == "modes" and um.multiplicity == (1, 1) and len(um.names) == 2
    for k2 in (450.0, 530.0, 570.0):
        th = {**NOMINAL, "k2": k2}
        delta = um.delta_of(chain(k2=k2))
        assert np.all(np.abs(delta) <= 1.0)
        lam = np.linalg.eigvals(np.asarray(um.statespace(delta).A))
        got = np.sort_complex(lam[lam.imag > 0])
        want, nominal = chain_poles(th), chain_poles(NOMINAL)
        assert np.all(np.abs(got - want) < 0.05 * np.abs(want - nominal))


def test_remainder_cover_holds_every_sample_and_is_smaller_than_a_complex_cover():
    rng = np.random.default_rng(7)
    cov = np.array([[40.0**2, 0.0], [0.0, 20.0**2]])  # k1, k2 at 4 % (N/m)^2
    um = parametric_lft(chain(), ["k1", "k2"], [1000.0, 500.0], cov, n_sigma=3.0, f_hz=F, form="modes")
    draws = rng.multivariate_normal([1000.0, 500.0], cov, 12)
    samples = [chain(k1=a, k2=b) for a, b in draws]
    with_rem = rc.cover_remainder(um, samples, order=4, f_hz=F, smooth_octaves=0.0)
    rem = with_rem.remainder
    assert with_rem.names == um.names and rem.kind == "additive"
    w = np.abs(freqresp_array(rem.weight, F)[:, 0, 0])
    for (a, b), s in zip(draws, samples):
        # the sample (numpy receptance) against its LFT member: inside |W| at every frequency
        member = freqresp_array(um.statespace(um.delta_of(s)), F)
        gap = np.linalg.norm(receptance({**NOMINAL, "k1": a, "k2": b}, F) - member, 2, axis=(1, 2))
        assert np.all(gap <= w * (1 + 1e-6))
    plain = rc.cover_additive(um.nominal, samples, order=4, f_hz=F, smooth_octaves=0.0)
    assert rem.envelope.max() < 0.25 * plain.envelope.max()


def test_generalized_plant_places_the_remainder_by_its_kind():
    um = parametric_lft(chain(), ["k2"], [500.0], [[25.0**2]], n_sigma=2.0, f_hz=F, form="modes")
    um = rc.cover_remainder(um, [chain(k2=480.0), chain(k2=530.0)], order=2, f_hz=F)
    gp = rc.generalized_plant(um, performance=1.0, control_weight=0.1, noise=0.01)
    kinds = [(b.kind, b.name) for b in gp.blocks.blocks]
    assert kinds[:2] == [("real", um.names[0]), ("real", um.names[1])] and kinds[2] == ("full", "additive")
    assert any(w.system is not None and w.role == "additive uncertainty" for w in gp.weights)
    with pytest.raises(ModelError, match="remainder"):
        rc.generalized_plant(um, additive=0.1, performance=1.0, control_weight=0.1, noise=0.01)
    with pytest.raises(FitError, match="UncertainModel"):
        rc.cover_remainder(um.nominal, [chain()], f_hz=F)


def test_without_holds_the_dropped_block_at_zero():
    um = parametric_lft(chain(), ["k2"], [500.0], [[25.0**2]], n_sigma=3.0, f_hz=F, form="modes")
    one = um.without([um.names[0]])
    assert one.names == um.names[1:] and one.n_delta == um.n_delta - 1
    np.testing.assert_allclose(freqresp_array(one.statespace([0.6]), F),
                               freqresp_array(um.statespace([0.0, 0.6]), F), rtol=1e-10, atol=1e-15)
    with pytest.raises(ModelError, match="no real block"):
        um.without(["stiffness"])


def test_fold_keeps_the_cover_and_drops_only_small_blocks():
    rng = np.random.default_rng(11)
    cov = np.array([[40.0**2, 0.0], [0.0, 20.0**2]])
    um = parametric_lft(chain(), ["k1", "k2"], [1000.0, 500.0], cov, n_sigma=3.0, f_hz=F, form="modes")
    samples = [chain(k1=a, k2=b) for a, b in rng.multivariate_normal([1000.0, 500.0], cov, 8)]
    kept = rc.cover_remainder(um, samples, order=4, f_hz=F, smooth_octaves=0.0, fold=1e-6)
    assert kept.names == um.names  # every mode moves by far more than the remainder
    # folding everything leaves the plain complex cover of the samples about the nominal
    none = rc.cover_remainder(um, samples, order=4, f_hz=F, smooth_octaves=0.0, fold=1e6)
    plain = rc.cover_additive(um.nominal, samples, order=4, f_hz=F, smooth_octaves=0.0)
    assert none.names == () and none.n_delta == 0
    np.testing.assert_allclose(none.remainder.envelope, plain.envelope, rtol=1e-9)
    gp = rc.generalized_plant(none, performance=1.0, control_weight=0.1, noise=0.01)
    assert [b.kind for b in gp.blocks.blocks] == ["full", "full"]
