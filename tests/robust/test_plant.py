"""Generalized plant (Caltech Fig. 1 interconnection) and the mixed-sensitivity preset."""

import functools

import control
import numpy as np
import pytest

import robustctl as rc

S_POINTS = (0.05j, 0.9j, 3.7j, 25.0j, 0.3 + 2.0j)


def _at(sys, s):
    """Response at s: robustctl's accurate kernel on the j-omega axis, python-control's evalfr off it."""
    if complex(s).real == 0 and isinstance(sys, control.StateSpace):
        return rc.lti.freqresp_array(sys, [complex(s).imag / (2 * np.pi)])[0]
    return np.atleast_2d(np.asarray(sys(s), dtype=complex))


def _stable(seed, n, p, m, inputs=None, outputs=None, d=0.0):
    np.random.seed(seed)  # control.rss draws from numpy's global generator
    base = control.rss(n, p, m)
    D = d * np.random.default_rng(seed).standard_normal((p, m))
    return control.ss(base.A, base.B, base.C, D, inputs=inputs or m, outputs=outputs or p)


def _flex(nu=2, ny=2):
    """A small lightly damped modal plant with named actuators and sensors."""
    modes = [(1.2, 0.02), (2.9, 0.01), (5.5, 0.015)]
    rng = np.random.default_rng(5)
    A = np.zeros((6, 6))
    for k, (f, z) in enumerate(modes):
        w = 2 * np.pi * f
        A[2 * k: 2 * k + 2, 2 * k: 2 * k + 2] = [[0, 1], [-w * w, -2 * z * w]]
    B = np.zeros((6, nu))
    B[1::2] = rng.standard_normal((3, nu))
    C = np.zeros((ny, 6))
    C[:, 0::2] = rng.standard_normal((ny, 3)) * 10
    return control.ss(A, B, C, np.zeros((ny, nu)), inputs=[f"A{i + 1}" for i in range(nu)],
                      outputs=[f"S{i + 1}" for i in range(ny)])


WA = control.tf(8 * np.poly([-6, -12, -24]), np.poly([-0.6, -400, -400]))  # seed eq. 14
WP = control.tf([1.0], [1 / (2 * np.pi * 6.0), 1.0])
WU = control.tf([1.0, 2.0], [1.0, 200.0])


@functools.lru_cache(maxsize=1)
def _truss():
    return rc.examples.caltech_truss().statespace()


# ------------------------------------------------------------------ closed loop against hand algebra
def _hand_closed_loop(s, G, K, Wa=None, Wi=None, Wo=None, Wp=None, Wu=None, Wdi=None, Wdo=None, Wn=None,
                      additive_on_outputs=False):
    """Fl(P, K)(s) from the signal equations of the module docstring, solved for u by hand."""
    g, k = _at(G, s), _at(K, s)
    ny, nu = g.shape
    I_y, I_u = np.eye(ny), np.eye(nu)
    ev = {name: (None if W is None else _at(W, s)) for name, W in
          dict(a=Wa, i=Wi, o=Wo, p=Wp, u=Wu, di=Wdi, do=Wdo, n=Wn).items()}
    # w groups: (name, size, contribution to uG, to the additive/out side of y_add, to y_true, to y_meas)
    groups = []
    if Wa is not None:
        groups.append(("add", ny, None, ev["a"] if additive_on_outputs else I_y, None, None))
    if Wi is not None:
        groups.append(("im", nu, I_u, None, None, None))
    if Wo is not None:
        groups.append(("om", ny, None, None, I_y, None))
    if Wdi is not None:
        groups.append(("di", ev["di"].shape[1], ev["di"], None, None, None))
    if Wdo is not None:
        groups.append(("do", ev["do"].shape[1], None, None, ev["do"], None))
    if Wn is not None:
        groups.append(("n", ev["n"].shape[1], None, None, None, ev["n"]))
    nw = sum(gr[1] for gr in groups)
    uG_w, yadd_w, ytrue_w, ymeas_w = (np.zeros((n, nw), complex) for n in (nu, ny, ny, ny))
    col = 0
    for _, n, to_u, to_add, to_true, to_meas in groups:
        sl = slice(col, col + n)
        if to_u is not None:
            uG_w[:, sl] = to_u
        if to_add is not None:
            yadd_w[:, sl] = to_add
        if to_true is not None:
            ytrue_w[:, sl] = to_true
        if to_meas is not None:
            ymeas_w[:, sl] = to_meas
        col += n
    # y_meas = G u + r w with r = G uG_w + yadd_w + ytrue_w + ymeas_w; u = K y_meas
    r = g @ uG_w + yadd_w + ytrue_w + ymeas_w
    u = np.linalg.solve(I_u - k @ g, k @ r)
    uG = u + uG_w
    y_add = g @ uG + yadd_w
    y_true = y_add + ytrue_w
    z = []
    if Wa is not None:
        z.append(uG if additive_on_outputs else ev["a"] @ uG)
    if Wi is not None:
        z.append(ev["i"] @ u)
    if Wo is not None:
        z.append(ev["o"] @ y_add)
    if Wp is not None:
        z.append(ev["p"] @ y_true)
    if Wu is not None:
        z.append(ev["u"] @ u)
    return np.vstack(z)


def _check_closed_loop(gp, G, K, points=S_POINTS, tol=1e-10, **weights):
    cl = rc.lft(gp, K)
    assert list(cl.input_labels) == gp.w_names and list(cl.output_labels) == gp.z_names
    for s in points:
        hand = _hand_closed_loop(s, G, K, **weights)
        ours = _at(cl, s)
        assert np.abs(ours - hand).max() <= tol * max(1.0, np.abs(hand).max())


def test_closed_loop_with_a_known_controller_equals_the_hand_built_interconnection():
    G = _flex()
    K = _stable(3, 3, 2, 2, ["S1", "S2"], ["A1", "A2"], d=0.05)
    Wdi, Wn = control.tf([0.5], [1, 1.0]), 0.01
    gp = rc.generalized_plant(G, additive=WA, input_mult=0.04, output_mult=0.04, performance=WP,
                              control_weight=WU, disturbances=Wdi, noise=Wn)
    I2 = np.eye(2)
    _check_closed_loop(gp, G, K, Wa=_diag(WA, 2), Wi=0.04 * _static(I2), Wo=0.04 * _static(I2),
                       Wp=_diag(WP, 2), Wu=_diag(WU, 2), Wdi=_diag(Wdi, 2), Wn=0.01 * _static(I2))


def test_output_side_additive_weight_and_output_disturbances():
    G = _flex(nu=3, ny=2)  # 2 x 3: an ny x ny additive weight sits on the outputs
    Wa2 = _stable(7, 2, 2, 2, d=0.3)
    Wdo = _stable(8, 1, 2, 1, d=0.2)  # one disturbance into both sensors
    K = _stable(9, 2, 3, 2, ["S1", "S2"], ["A1", "A2", "A3"], d=0.05)
    gp = rc.generalized_plant(G, additive=Wa2, performance=2.0, control_weight=0.1,
                              disturbances={"output": Wdo}, noise=control.tf([0.02, 0.001], [0.01, 1]))
    assert gp.blocks.mussv().tolist() == [[2, 3], [3, 5]]
    assert gp.perf_w_names == ["dist_out[0]", "noise[S1]", "noise[S2]"]
    _check_closed_loop(gp, G, K, Wa=Wa2, Wp=2.0 * _static(np.eye(2)), Wu=0.1 * _static(np.eye(3)),
                       Wdo=Wdo, Wn=_diag(control.tf([0.02, 0.001], [0.01, 1]), 2), additive_on_outputs=True)


def test_caltech_truss_plant_closed_loop_and_names():
    """The seed's structure on the Caltech truss: eq. 14 additive, 4 % in/out, performance on sensors."""
    G = _truss()
    gp = rc.generalized_plant(G, additive=WA, input_mult=0.04, output_mult=0.04, performance=WP,
                              disturbances=1.0, noise=0.01)
    assert gp.u_names == ["A1", "A2", "A3"] and gp.y_names == ["S1", "S2", "S3"]
    assert gp.w_names[:3] == ["unc_add_in[S1]", "unc_add_in[S2]", "unc_add_in[S3]"]
    assert gp.z_names[-3:] == ["perf_y[S1]", "perf_y[S2]", "perf_y[S3]"]
    assert [b.name for b in gp.blocks] == ["additive", "input multiplicative", "output multiplicative",
                                           "performance"]
    assert (gp.blocks.n_in, gp.blocks.n_out) == (gp.nw, gp.nz) == (15, 12)
    assert (gp.n_perf_w, gp.n_perf_z) == (6, 3)
    assert gp.P.nstates == G.nstates + 9 + 3  # nominal + eq. 14 (3 states x 3) + performance (1 x 3)
    K = control.ss(-20 * np.eye(3), np.eye(3), 0.1 * np.eye(3), np.zeros((3, 3)),
                   inputs=["S1", "S2", "S3"], outputs=["A1", "A2", "A3"])
    I3 = np.eye(3)
    weights = dict(Wa=_diag(WA, 3), Wi=0.04 * _static(I3), Wo=0.04 * _static(I3), Wp=_diag(WP, 3),
                   Wdi=_static(I3), Wn=0.01 * _static(I3))
    points = (0.9j * 2 * np.pi, 2.3j * 2 * np.pi, 10j)
    # the plant itself (a controller with zero output) to 1e-10 of the hand-built interconnection
    K0 = control.ss(K.A, K.B, 0 * K.C, K.D, inputs=K.input_labels, outputs=K.output_labels)
    _check_closed_loop(gp, G, K0, points=points, **weights)
    # with the loop closed: the same realisation as python-control's (unnamed) lft, and the hand
    # algebra to 1e-8 -- evaluating a coupled 75-state loop of lightly damped modes costs ~1e-9
    cl = rc.lft(gp, K)
    for s in points:
        assert np.abs(_at(cl, s) - _at(gp.P.lft(K), s)).max() <= 1e-12 * np.abs(_at(cl, s)).max()
    _check_closed_loop(gp, G, K, points=points, tol=1e-8, **weights)
    assert "performance" in gp.summary() and "unc_add_in[S1]" in gp._repr_html_()
    assert gp.weight_table().rows[0][0] == "additive uncertainty"


def test_closing_an_uncertainty_block_gives_the_perturbed_plant():
    """Fu(P, Delta) with Delta on one block: G (I + W_i delta), G + W_a delta, (I + W_o delta) G."""
    G = _flex()
    gp = rc.generalized_plant(G, additive=WA, input_mult=0.04, output_mult=0.04, check_rank=False)
    d_add = np.array([[0.3, -0.2], [0.1, 0.5]])
    d_im = np.array([[0.7, 0.2], [-0.4, 0.1]])
    d_om = np.array([[-0.5, 0.3], [0.2, 0.6]])
    for which, delta in (("add", d_add), ("im", d_im), ("om", d_om)):
        full = np.zeros((6, 6))
        k = {"add": 0, "im": 2, "om": 4}[which]
        full[k: k + 2, k: k + 2] = delta
        pert = rc.upper_lft(gp, full)  # u -> y
        assert list(pert.input_labels) == ["A1", "A2"] and list(pert.output_labels) == ["S1", "S2"]
        for s in S_POINTS:
            g = _at(G, s)
            expected = {
                "add": g + complex(WA(s)) * delta,
                "im": g @ (np.eye(2) + 0.04 * delta),
                "om": (np.eye(2) + 0.04 * delta) @ g,
            }[which]
            assert np.allclose(_at(pert, s), expected, rtol=1e-10, atol=1e-12)


def _diag(W, n):
    return control.ss(control.append(*[control.ss(W)] * n))


def _static(M):
    M = np.asarray(M, float)
    return control.ss(np.zeros((0, 0)), np.zeros((0, M.shape[1])), np.zeros((M.shape[0], 0)), M)


# ------------------------------------------------------------------ mixed sensitivity against augw
@pytest.mark.filterwarnings("ignore:connect\\(\\) is deprecated:FutureWarning")  # inside control.augw
@pytest.mark.parametrize("case", ["siso_w1_w3", "siso_all", "mimo_w1_w2"])
def test_mixed_sensitivity_matches_control_augw(case):
    W1 = control.tf([0.5, 1.0], [1.0, 0.01])
    W2 = control.tf([1.0, 0.1], [0.01, 1.0])
    W3 = control.tf([1.0, 1.0], [0.02, 1.0])
    if case == "mimo_w1_w2":
        G = _stable(4, 4, 2, 2)
        weights = (W1, W2, None)
        augw_weights = (_diag(W1, 2), _diag(W2, 2), None)
    else:
        G = control.ss(control.tf([1.0], [1.0, 0.02, 1.0]))
        weights = (W1, None, 0.1) if case == "siso_w1_w3" else (W1, W2, W3)
        augw_weights = (W1, None, control.tf(0.1, 1)) if case == "siso_w1_w3" else weights
    gp = rc.mixed_sensitivity(G, *weights)
    ref = control.augw(G, *augw_weights)
    assert gp.P.ninputs == ref.ninputs and gp.P.noutputs == ref.noutputs
    for s in S_POINTS:
        a, b = _at(gp.P, s), _at(ref, s)
        assert np.abs(a - b).max() <= 1e-10 * max(1.0, np.abs(b).max())
    assert gp.blocks.mussv().tolist() == [[gp.nw, gp.nz]] and gp.n_perf_w == gp.nw
    assert gp.y_names[0].startswith("e[") and gp.w_names[0].startswith("ref[")


def test_mixed_sensitivity_closed_loop_is_w1s_w2ks_w3t():
    G = _flex()
    K = _stable(11, 2, 2, 2, d=0.02)
    W1, W3 = control.tf([1.0, 2.0], [1.0, 0.02]), 0.3
    gp = rc.mixed_sensitivity(G, W1, 0.05, W3)
    assert gp.z_names == ["perf_e[S1]", "perf_e[S2]", "perf_u[A1]", "perf_u[A2]", "perf_y[S1]",
                          "perf_y[S2]"]
    cl = rc.lft(gp, K)
    for s in S_POINTS:
        g, k = _at(G, s), _at(K, s)
        S = np.linalg.inv(np.eye(2) + g @ k)
        expected = np.vstack([complex(W1(s)) * S, 0.05 * k @ S, W3 * (g @ k @ S)])
        assert np.allclose(_at(cl, s), expected, rtol=1e-10, atol=1e-12)


# ------------------------------------------------------------------ structure and bad input
def test_blocks_sizes_follow_the_channels():
    G = _flex(nu=3, ny=2)
    gp = rc.generalized_plant(G, input_mult=0.1, performance=WP, control_weight=0.01,
                              disturbances={"input": 1.0, "output": 0.5}, noise=0.001)
    assert gp.blocks.mussv().tolist() == [[3, 3], [3 + 2 + 2, 2 + 3]]
    assert sum(b.rows for b in gp.blocks) == gp.nw and sum(b.cols for b in gp.blocks) == gp.nz
    assert gp.uncertainty_blocks.mussv().tolist() == [[3, 3]]
    nominal = gp.nominal_performance()
    assert nominal.nw == gp.n_perf_w and nominal.nz == gp.n_perf_z
    with pytest.raises(rc.ModelError, match="need nw"):
        rc.GeneralizedPlant(gp.P, gp.nmeas, gp.ncon, rc.robust.BlockStructure.from_mussv([[1, 1]]))
    pickled = __import__("pickle").loads(__import__("pickle").dumps(gp.blocks))
    assert pickled == gp.blocks


def test_rank_deficient_plants_are_refused_with_the_missing_weight_named():
    G = _flex()
    with pytest.raises(rc.ModelError, match="D12.*control_weight="):
        rc.generalized_plant(G, performance=WP, disturbances=1.0, noise=0.01)
    with pytest.raises(rc.ModelError, match="D21.*noise="):
        rc.generalized_plant(G, performance=WP, control_weight=0.1, disturbances=1.0)
    # an additive block on the plant inputs lets w_add reach every sensor directly: D21 full rank
    rc.generalized_plant(G, additive=WA, performance=WP, control_weight=0.1, disturbances=1.0)
    # constant multiplicative weights give full rank on their own (the seed's 4 %)
    gp = rc.generalized_plant(G, input_mult=0.04, output_mult=0.04)
    assert gp.n_perf_w == 0 and len(gp.blocks) == 2
    # the seed's eq. 14 weight is biproper (gain 8 at infinity): an additive block fills D12 too
    rc.generalized_plant(G, additive=WA, performance=WP, disturbances=1.0, noise=0.01)
    singular = rc.generalized_plant(G, performance=WP, disturbances=1.0, check_rank=False)
    assert np.linalg.matrix_rank(singular.matrices()["D12"]) == 0


class _Cover:
    def __init__(self, weight):
        self.weight = weight


@pytest.mark.parametrize("kwargs,match", [
    (dict(additive=control.tf([1.0, 0.0, 0.0], [1.0, 1.0])), "improper"),
    (dict(input_mult=-0.04), "number > 0"),
    (dict(output_mult=0.0), "number > 0"),
    (dict(input_mult=np.nan), "number > 0"),
    (dict(additive=control.tf([1.0], [1.0, -1.0])), "must be stable"),
    (dict(output_mult=0.04, performance=control.tf([1.0], [1.0, 0.0]), noise=0.1, disturbances=1.0),
     "must be stable.*1/\\(s \\+ 1e-3\\)"),
    (dict(input_mult=_static(np.ones((3, 3)))), "2 x 2"),
    (dict(additive=_stable(1, 1, 3, 3)), "SISO .*2 x 2"),
    (dict(input_mult=0.1, performance=WP), "need performance inputs.*disturbances="),
    (dict(input_mult=0.1, noise=0.1), "need performance outputs"),
    (dict(input_mult=0.1, disturbances={"sideways": 1.0}, performance=1.0), "'input' and/or"),
    (dict(), "nothing to build"),
    (dict(input_mult=control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], 0.01)), "discrete-time"),
])
def test_bad_weights_are_clear_errors(kwargs, match):
    with pytest.raises(rc.ModelError, match=match):
        rc.generalized_plant(_flex(), check_rank=False, **kwargs)


def test_cover_results_and_models_are_accepted():
    G = _flex()
    a = rc.generalized_plant(G, additive=_Cover(WA), output_mult=0.04, check_rank=False)
    b = rc.generalized_plant(G, additive=WA, output_mult=0.04, check_rank=False)
    for s in S_POINTS:
        assert np.allclose(_at(a.P, s), _at(b.P, s), rtol=1e-12)
    with pytest.raises(rc.ModelError, match="mixed_sensitivity needs at least one"):
        rc.mixed_sensitivity(G)
    with pytest.raises(rc.ModelError, match="W2"):
        rc.mixed_sensitivity(G, None, _stable(2, 1, 3, 3))


def test_generalized_plant_pickles_and_accepts_a_physical_model():
    import pickle

    model = rc.examples.caltech_truss()
    gp = rc.generalized_plant(model, additive=WA, input_mult=0.04, output_mult=0.04)
    assert gp.P.nstates == _truss().nstates + 9 and gp.u_names == ["A1", "A2", "A3"]
    back = pickle.loads(pickle.dumps(gp))
    assert back.blocks == gp.blocks and back.w_names == gp.w_names
    assert np.array_equal(back.P.A, gp.P.A) and back.weights[0].role == "additive uncertainty"
    assert back.weights[0].gain(np.inf) == pytest.approx(8.0)  # eq. 14 is biproper, gain 8 at infinity


def test_multiplicative_block_structure_options_change_blocks_only():
    G = _flex(nu=3, ny=2)
    full = rc.generalized_plant(G, input_mult=0.04, output_mult=0.1)
    diag = rc.generalized_plant(G, input_mult=0.04, output_mult=0.1, mult_structure="diagonal")
    rep = rc.generalized_plant(G, input_mult=0.04, output_mult=0.1, mult_structure="repeated")
    assert full.blocks.mussv().tolist() == [[3, 3], [2, 2]]
    assert diag.blocks.mussv().tolist() == [[1, 1]] * 5
    assert diag.blocks[0].name == "input multiplicative [A1]"
    assert rep.blocks.mussv().tolist() == [[3, 0], [2, 0]]
    assert np.array_equal(full.P.D, diag.P.D) and np.array_equal(full.P.A, rep.P.A)
    with pytest.raises(rc.ModelError, match="mult_structure"):
        rc.generalized_plant(G, additive=WA, mult_structure="blockwise")


def test_plot_draws_every_weight_and_the_nominal():
    import matplotlib

    matplotlib.use("Agg")
    gp = rc.generalized_plant(_flex(), additive=WA, input_mult=0.04, performance=WP, control_weight=0.1,
                              disturbances=1.0, noise=0.01)
    fig = gp.plot(np.geomspace(0.01, 100, 50))
    lines = fig.axes[0].get_lines()
    assert len(lines) == len(gp.weights) + 1
    eq14 = lines[0].get_ydata()
    f = np.geomspace(0.01, 100, 50)
    assert np.allclose(eq14, np.abs(WA(2j * np.pi * f)), rtol=1e-10)
    import matplotlib.pyplot as plt

    plt.close(fig)
