"""Named interconnection: lft / upper_lft / star / series / parallel / feedback keep names and
agree with python-control's unnamed operations; the PD servo option of servo_stage."""

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.physical import electronics as el

S_POINTS = (0.37j, 2.1j, 0.5 + 7.0j, 40.0j)


def _resp(sys, s):
    return np.atleast_2d(np.asarray(sys(s), dtype=complex))


def _max_rel_diff(a, b, points=S_POINTS):
    return max(
        np.abs(_resp(a, s) - _resp(b, s)).max() / max(np.abs(_resp(b, s)).max(), 1e-300) for s in points
    )


def _random(seed, n, p, m, inputs=None, outputs=None, d_scale=1.0):
    """A stable random system with a random (nonzero) feedthrough and the given names."""
    rng = np.random.default_rng(seed)
    D = d_scale * rng.standard_normal((p, m))
    if n == 0:
        return control.ss(np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0)), D,
                          inputs=inputs or m, outputs=outputs or p)
    np.random.seed(seed)  # control.rss draws from numpy's global generator
    base = control.rss(n, p, m)
    return control.ss(base.A, base.B, base.C, D, inputs=inputs or m, outputs=outputs or p)


def _plant(seed, n, nw, nu, nz, ny):
    w = [f"w{i}" for i in range(nw)] + [f"u{i}" for i in range(nu)]
    z = [f"z{i}" for i in range(nz)] + [f"y{i}" for i in range(ny)]
    return _random(seed, n, nz + ny, nw + nu, w, z, d_scale=0.3)


# ------------------------------------------------------------------ lower LFT
@pytest.mark.parametrize("seed,n,nk,nw,nu,nz,ny", [
    (0, 5, 3, 3, 2, 2, 2), (1, 8, 2, 1, 1, 1, 1), (2, 4, 0, 2, 3, 4, 1), (3, 12, 6, 4, 2, 3, 3),
])
def test_named_lft_agrees_with_python_control_and_keeps_names(seed, n, nk, nw, nu, nz, ny):
    P = _plant(seed, n, nw, nu, nz, ny)
    K = _random(seed + 100, nk, nu, ny, d_scale=0.2)
    ours = rc.lft(P, K)
    theirs = P.lft(K)
    assert _max_rel_diff(ours, theirs) < 1e-12
    assert list(ours.input_labels) == [f"w{i}" for i in range(nw)]
    assert list(ours.output_labels) == [f"z{i}" for i in range(nz)]
    assert list(theirs.input_labels)[0] == "u[0]"  # what python-control 0.10 does
    assert ours.nstates == n + nk
    # the same through a PartitionedPlant, with nmeas/ncon taken from it
    pp = rc.PartitionedPlant(P, nmeas=ny, ncon=nu)
    assert _max_rel_diff(rc.lft(pp, K), theirs) < 1e-12
    assert _max_rel_diff(rc.interconnect.lft(P, K, ny, nu), P.lft(K, nu=nu, ny=ny)) < 1e-12


def test_lft_with_static_gain_and_by_name_reordering():
    P = _plant(7, 6, 2, 2, 2, 2)
    Kd = np.array([[0.3, -0.1], [0.2, 0.4]])
    static = rc.lft(P, Kd)
    assert static.nstates == 6
    Kss = control.ss([], [], [], Kd)
    assert _max_rel_diff(static, P.lft(Kss)) < 1e-12
    # a controller named by the plant's y/u names is connected by name, whatever its order
    K = _random(8, 3, 2, 2, ["y0", "y1"], ["u0", "u1"], d_scale=0.1)
    swapped = rc.select_signals(K, ["y1", "y0"], ["u1", "u0"])
    assert _max_rel_diff(rc.lft(P, swapped), rc.lft(P, K)) < 1e-12
    assert _max_rel_diff(rc.lft(P, K), P.lft(K)) < 1e-12


def test_lft_well_posedness_and_size_errors():
    # D22 = 1 with K = 1: I - D22 Dk = 0
    P = control.ss([[-1.0]], [[1.0, 1.0]], [[1.0], [1.0]], [[0.0, 0.0], [0.0, 1.0]],
                   inputs=["w", "u"], outputs=["z", "y"])
    with pytest.raises(rc.ModelError, match="not well posed"):
        rc.lft(P, 1.0)
    with pytest.raises(rc.ModelError, match="nmeas = 1 inputs and ncon = 1 outputs"):
        rc.lft(P, np.ones((2, 1)), nmeas=1, ncon=1)
    with pytest.raises(rc.ModelError, match="nmeas"):
        rc.lft(P, np.ones((1, 3)))


# ------------------------------------------------------------------ upper LFT and star product
def test_upper_lft_matches_formula_and_keeps_names():
    P = _plant(11, 5, 3, 2, 3, 2)  # inputs w0..w2, u0, u1; outputs z0..z2, y0, y1
    Delta = _random(12, 2, 2, 2, d_scale=0.2)  # z0, z1 -> Delta -> w0, w1
    Fu = rc.upper_lft(P, Delta)
    assert list(Fu.input_labels) == ["w2", "u0", "u1"]
    assert list(Fu.output_labels) == ["z2", "y0", "y1"]
    for s in S_POINTS:
        G = _resp(P, s)
        D = _resp(Delta, s)
        P11, P12, P21, P22 = G[:2, :2], G[:2, 2:], G[2:, :2], G[2:, 2:]
        expected = P22 + P21 @ D @ np.linalg.solve(np.eye(2) - P11 @ D, P12)
        assert np.allclose(_resp(Fu, s), expected, rtol=1e-11, atol=1e-13)


def test_star_product_equals_two_successive_lfts():
    """Fl(star(P, Q), K) == Fl(P, Fl(Q, K)) when Q's open channels feed K (associativity)."""
    P = _plant(21, 4, 2, 2, 2, 2)  # w0 w1 u0 u1 -> z0 z1 y0 y1
    # Q: inputs [y0, y1 (from P), v (from K)] -> outputs [u0, u1 (to P), e (to K)]
    Q = _random(22, 3, 3, 3, ["y0", "y1", "v"], ["u0", "u1", "e"], d_scale=0.2)
    K = _random(23, 2, 1, 1, ["e"], ["v"], d_scale=0.2)
    S = rc.star(P, Q, n_forward=2, n_back=2)
    assert list(S.input_labels) == ["w0", "w1", "v"] and list(S.output_labels) == ["z0", "z1", "e"]
    two_step = rc.lft(P, rc.lft(Q, K, 1, 1), 2, 2)
    assert _max_rel_diff(rc.lft(S, K, 1, 1), two_step) < 1e-10
    # star with a controller that has no open channels is the lower LFT, and with a
    # perturbation that has none it is the upper LFT
    K2 = _random(24, 2, 2, 2, d_scale=0.2)
    assert _max_rel_diff(rc.star(P, K2, 2, 2), P.lft(K2)) < 1e-12
    Delta = _random(25, 1, 2, 2, d_scale=0.2)
    assert _max_rel_diff(rc.star(Delta, P, 2, 2), rc.upper_lft(P, Delta)) < 1e-12
    with pytest.raises(rc.ModelError, match="repeated input names"):
        rc.star(P, rc.rename_signals(Q, inputs={"v": "w0"}), 2, 2)
    with pytest.raises(rc.ModelError, match="n_forward"):
        rc.star(P, Q)


# ------------------------------------------------------------------ feedback, series, parallel
@pytest.mark.parametrize("sign", [-1, 1])
def test_feedback_agrees_with_control_feedback(sign):
    G = _random(31, 5, 3, 3, d_scale=0.2)
    H = _random(32, 2, 3, 3, d_scale=0.2)
    ours = rc.feedback(G, H, sign)  # default names u[i]/y[i] match by name (H: y -> u)
    ours_pos = rc.feedback(G, H, sign, by_name=False)
    theirs = control.feedback(G, H, sign)
    assert _max_rel_diff(ours_pos, theirs) < 1e-12
    # by name: H's inputs are y[0..2] (= G's outputs), its outputs u[0..2] (= G's inputs)
    assert _max_rel_diff(ours, theirs) < 1e-12
    assert _max_rel_diff(rc.feedback(G, 0.5, sign), control.feedback(G, 0.5 * np.eye(3), sign)) < 1e-12


def test_feedback_by_name_closes_only_the_named_channels():
    G = _random(33, 4, 2, 2, ["u_a", "u_b"], ["y_a", "y_b"], d_scale=0.1)
    k = _random(34, 1, 1, 1, ["y_b"], ["u_a"], d_scale=0.3)
    ours = rc.feedback(G, k)
    assert list(ours.input_labels) == ["u_a", "u_b"] and list(ours.output_labels) == ["y_a", "y_b"]
    # the same loop by position with a 2x2 feedback that is zero except K[u_a, y_b]
    Kfull = control.ss(k.A, k.B @ np.array([[0.0, 1.0]]), np.array([[1.0], [0.0]]) @ k.C,
                       np.array([[0.0, float(k.D[0, 0])], [0.0, 0.0]]))
    assert _max_rel_diff(ours, control.feedback(G, Kfull)) < 1e-12
    with pytest.raises(rc.ModelError, match=r"unknown input\(s\) of the feedback system \['nope'\].*y_a"):
        rc.feedback(G, rc.rename_signals(k, inputs={"y_b": "nope"}))


def test_series_and_parallel_agree_with_python_control():
    G1 = _random(41, 3, 2, 3, ["a", "b", "c"], ["p", "q"], d_scale=0.2)
    G2 = _random(42, 4, 3, 2, ["p", "q"], ["r", "s", "t"], d_scale=0.2)
    ours = rc.series(G1, G2)
    assert list(ours.input_labels) == ["a", "b", "c"] and list(ours.output_labels) == ["r", "s", "t"]
    assert _max_rel_diff(ours, control.series(G1, G2)) < 1e-12
    # by name: G2 reading (q, p) swapped equals the positional series with a swap in between
    G2s = rc.select_signals(G2, ["q", "p"], None)
    swap = np.array([[0.0, 1.0], [1.0, 0.0]])
    assert _max_rel_diff(rc.series(G1, G2s), control.series(G1, swap, G2s)) < 1e-12
    with pytest.raises(rc.ModelError, match=r"unknown input\(s\).*\['p', 'q'\].*by_name=False"):
        rc.series(G1, rc.rename_signals(G2, inputs={"p": "x"}))
    assert _max_rel_diff(rc.series(G1, rc.rename_signals(G2, inputs={"p": "x"}), by_name=False),
                         control.series(G1, G2)) < 1e-12
    H1 = _random(43, 3, 2, 2, d_scale=0.2)
    H2 = _random(44, 2, 2, 2, d_scale=0.2)
    assert _max_rel_diff(rc.parallel(H1, H2), control.parallel(H1, H2)) < 1e-12
    assert _max_rel_diff(rc.parallel(H1, 2.0), control.parallel(H1, 2.0 * np.eye(2))) < 1e-12


def test_parallel_by_name_unions_the_signals():
    A = _random(51, 2, 1, 1, ["f"], ["x"], d_scale=0.3)
    B = _random(52, 2, 2, 1, ["f"], ["x", "v"], d_scale=0.3)
    both = rc.parallel(A, B)
    assert list(both.input_labels) == ["f"] and list(both.output_labels) == ["x", "v"]
    for s in S_POINTS:
        expected = np.array([[_resp(A, s)[0, 0] + _resp(B, s)[0, 0]], [_resp(B, s)[1, 0]]])
        assert np.allclose(_resp(both, s), expected, rtol=1e-12)


# ----------------------------------------------- interconnect holds the LFTs, PD servo option
def test_interconnect_holds_the_lfts_and_lti_does_not_reexport_them():
    assert rc.interconnect.lft is rc.lft and rc.interconnect.star is rc.star
    assert rc.interconnect.feedback is rc.feedback
    assert rc.interconnect.PartitionedPlant is rc.PartitionedPlant
    assert not hasattr(rc.lti, "lft") and not hasattr(rc.lti, "PartitionedPlant")


def test_servo_stage_pd_option_equals_the_pd_controller_loop():
    G = control.ss([[0.0, 1.0], [-4.0, -0.1]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]],
                   inputs=["motor"], outputs=["encoder"])
    stage = el.servo_stage("encoder", "motor", "k", lead_hz="f_lead", lowpass_hz=20.0, delay_s=0.002,
                           reference_input_name="command")
    closed = stage.fn({"k": 3.0, "f_lead": 1.5}, G)
    assert list(closed.input_labels) == ["command"]
    k = el.pd_controller(3.0, 1.5, lowpass_hz=20.0, delay_s=0.002)
    assert _max_rel_diff(closed, control.feedback(control.series(k, G), 1)) < 1e-11
    assert "PD servo" in stage.name
    with pytest.raises(rc.ModelError, match="PI .* or a PD"):
        el.servo_stage("encoder", "motor", 1.0, lead_hz=1.0, integral_hz=0.1)
    with pytest.raises(rc.ModelError, match="rolloff_order"):
        el.servo_stage("encoder", "motor", 1.0, rolloff_order=2)


def test_named_signal_maps_live_in_one_place():
    from robustctl.examples import _assembly

    assert el.scale_outputs is rc.scale_outputs and el.rename_signals is rc.rename_signals
    assert _assembly.combine_inputs is rc.combine_inputs and _assembly.select_signals is rc.select_signals
    assert _assembly.pd_controller is el.pd_controller
    assert not hasattr(_assembly, "pd_servo_stage")


def test_block_diagonal_agrees_with_control_append_and_keeps_names():
    A = _random(61, 2, 1, 2, ["a1", "a2"], ["p"], d_scale=0.3)
    B = _random(62, 3, 2, 1, ["b"], ["q1", "q2"], d_scale=0.3)
    both = rc.block_diagonal(A, B, 2.0)
    assert list(both.input_labels) == ["a1", "a2", "b", "u[0]"]
    assert list(both.output_labels) == ["p", "q1", "q2", "y[0]"]
    ref = control.append(A, B, control.ss([], [], [], [[2.0]]))
    assert _max_rel_diff(both, ref) < 1e-12
    with pytest.raises(rc.ModelError, match="repeated input names"):
        rc.block_diagonal(A, A)


def test_partitioned_plant_pickles_by_matrices_and_names():
    import pickle

    P = _plant(71, 4, 2, 1, 2, 1)
    pp = rc.PartitionedPlant(P, nmeas=1, ncon=1)
    static = control.ss([], [], [], [[0.1]])
    assert _max_rel_diff(pp.closed_loop(0.1 * np.ones((1, 1))), P.lft(static)) < 1e-12
    assert "w = 2, u = 1 -> z = 2, y = 1" in pp.summary() and "y0" in pp._repr_html_()
    assert [row[2] for row in pp.table().rows] == [2, 1, 2, 1]
    back = pickle.loads(pickle.dumps(pp))
    assert back.w_names == pp.w_names and back.y_names == pp.y_names and back.nmeas == 1
    assert all(np.array_equal(back.matrices()[k], pp.matrices()[k]) for k in pp.matrices())


def test_partitioned_plant_groups_partitions_and_errors():
    P = _plant(81, 5, 3, 2, 2, 1)  # w0..w2, u0, u1 -> z0, z1, y0
    pp = rc.PartitionedPlant(P, nmeas=1, ncon=2)
    assert (pp.nw, pp.nu, pp.nz, pp.ny) == (3, 2, 2, 1)
    assert pp.w_names == ["w0", "w1", "w2"] and pp.u_names == ["u0", "u1"] and pp.y_names == ["y0"]
    m = pp.matrices()
    assert m["B2"].shape == (5, 2) and m["D21"].shape == (1, 3) and np.array_equal(m["D12"], P.D[:2, 3:])
    P21 = pp.sub("y", "w")
    assert list(P21.input_labels) == pp.w_names and list(P21.output_labels) == ["y0"]
    for s in S_POINTS:
        assert np.allclose(_resp(P21, s), _resp(P, s)[2:, :3], rtol=1e-12)
    with pytest.raises(rc.ModelError, match=r"nmeas \(number of measurements\) must be an integer in \[0, 3"):
        rc.PartitionedPlant(P, nmeas=4, ncon=1)
    with pytest.raises(rc.ModelError, match="as_statespace"):
        rc.PartitionedPlant(np.eye(2), 1, 1)
    with pytest.raises(rc.ModelError, match="rows in"):
        pp.sub("w", "z")
