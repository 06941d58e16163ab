"""mu bounds: exact cases, brute-force grids, the LMI reference, certificates, bad input."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.robust.mu.layout import layout_of
from robustctl.robust.mu.lmi import lmi_upper_bound
from robustctl.robust.uncertainty.blocks import Block, as_block_structure


def crandn(rng, *shape):
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def _dl_dr(res, k):
    """Assembled D_L, D_R of a MuResult at frequency index k."""
    bs = res.blocks
    DL = np.zeros((bs.n_out, bs.n_out), complex)
    DR = np.zeros((bs.n_in, bs.n_in), complex)
    for d, o, i in zip(res.d_matrices, bs.row_slices(), bs.col_slices()):
        dk = d[k]
        DL[o, o] = dk if dk.shape[0] > 1 else dk[0, 0] * np.eye(o.stop - o.start)
        DR[i, i] = dk if dk.shape[0] > 1 else dk[0, 0] * np.eye(i.stop - i.start)
    return DL, DR


# ---------------------------------------------------------------------------- exact cases
@pytest.mark.parametrize("shape", [(3, 3), (3, 5), (4, 2)])
def test_one_full_block_is_max_singular_value(shape):
    rng = np.random.default_rng(sum(shape))
    M = crandn(rng, 7, *shape)
    res = rc.mu(M, [[shape[1], shape[0]]])  # block r x c with M (c x r)
    sv = np.linalg.svd(M, compute_uv=False)[:, 0]
    np.testing.assert_allclose(res.upper, sv, rtol=1e-10)
    np.testing.assert_allclose(res.lower, sv, rtol=1e-6)


@pytest.mark.parametrize("n, seed", [(3, 0), (5, 1), (6, 2)])
def test_rank_one_scalar_blocks_sum_of_products(n, seed):
    rng = np.random.default_rng(seed)
    a, b = crandn(rng, 4, n), crandn(rng, 4, n)
    M = a[:, :, None] * b.conj()[:, None, :]
    exact = np.sum(np.abs(a) * np.abs(b), axis=1)
    res = rc.mu(M, [[1, 0]] * n)
    np.testing.assert_allclose(res.upper, exact, rtol=2e-3)
    np.testing.assert_allclose(res.lower, exact, rtol=1e-6)
    assert np.all(res.upper >= exact * (1 - 1e-9))


def test_complex_2x2_scalar_against_grid():
    # complex mu = max over diagonal unitary Q of rho(M Q) (Packard & Doyle 1993, Thm 7.2)
    rng = np.random.default_rng(7)
    theta = np.linspace(0.0, 2 * np.pi, 4001)
    for _ in range(4):
        M = crandn(rng, 2, 2)
        Q = np.zeros((theta.size, 2, 2), complex)
        Q[:, 0, 0], Q[:, 1, 1] = 1.0, np.exp(1j * theta)
        grid = np.abs(np.linalg.eigvals(M @ Q)).max()
        res = rc.mu(M, [[1, 0], [1, 0]])
        assert res.lower[0] <= grid * (1 + 1e-6)  # the grid misses the maximum by < 1e-6
        assert res.upper[0] >= grid * (1 - 1e-6)
        assert res.upper[0] == pytest.approx(grid, rel=1e-3)  # D-scaling is exact for two scalar blocks


def _real_grid_mu(M, n=200001):
    """1 / min max(|d1|, |d2|) over real d with det(I - M diag(d1, d2)) = 0 (real M)."""
    m11, m12, m21, m22 = M[0, 0], M[0, 1], M[1, 0], M[1, 1]
    det = m11 * m22 - m12 * m21
    d1 = np.linspace(-20.0, 20.0, n)
    den = m22 - det * d1
    d2 = (1.0 - m11 * d1) / np.where(np.abs(den) > 1e-14, den, np.nan)
    size = np.nanmin(np.maximum(np.abs(d1), np.abs(d2)))
    # d1 = 0 exactly: singular when d2 = 1 / m22; d2 = 0: d1 = 1 / m11
    for alt in (1 / abs(m11) if m11 else np.inf, 1 / abs(m22) if m22 else np.inf):
        size = min(size, alt)
    return 1.0 / size


def test_real_2x2_scalar_against_grid():
    rng = np.random.default_rng(11)
    for _ in range(4):
        M = rng.standard_normal((2, 2))
        grid = _real_grid_mu(M)
        res = rc.mu(M, [[-1, 0], [-1, 0]])
        assert res.upper[0] >= grid * (1 - 1e-3)
        assert res.lower[0] <= grid * (1 + 1e-3)
        assert res.lower[0] == pytest.approx(grid, rel=2e-3)
        assert res.upper[0] == pytest.approx(grid, rel=0.05)


# ---------------------------------------------------------------------------- bounds and certificates
STRUCTURES = [
    [[1, 0], [1, 0], [1, 0], [3, 3]],
    [[2, 0], [1, 1], [2, 3]],
    [[-1, 0], [1, 0], [2, 2]],
    [[-2, 0], [1, 0], [1, 2]],
    [[3, 2], [2, 0]],
]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("blocks", STRUCTURES)
def test_lower_below_upper_and_certificates(blocks, seed):
    bs = as_block_structure(blocks)
    rng = np.random.default_rng(seed)
    M = crandn(rng, 40, bs.n_out, bs.n_in) * rng.uniform(0.1, 10.0)
    res = rc.mu(M, bs)
    assert np.all(res.lower <= res.upper * (1 + 1e-9))
    assert np.all(res.upper > 0)
    if not bs.has_real:  # complex structures: the power iteration always finds a bound, mostly tight
        assert np.all(res.lower > 0)
        assert np.median(res.upper / res.lower) < 1.02
    # the D (and G) scales certify the upper bound (Fan, Tits & Doyle 1991, Thm 2.1)
    for k in range(0, 40, 7):
        DL, DR = _dl_dr(res, k)
        XL, XR = DL.conj().T @ DL, DR.conj().T @ DR
        H = M[k].conj().T @ XL @ M[k] - res.upper[k] ** 2 * XR
        if bs.has_real:
            G = np.zeros((bs.n_in, bs.n_out), complex)
            for g, o, i in zip(res.g_matrices, bs.row_slices(), bs.col_slices()):
                if g.shape[-1] == i.stop - i.start and o.stop - o.start == i.stop - i.start:
                    G[i, o] = g[k]
            H = H + 1j * (G @ M[k] - M[k].conj().T @ G.conj().T)
        lam = np.linalg.eigvalsh(0.5 * (H + H.conj().T))
        assert lam.max() <= 1e-8 * res.upper[k] ** 2 * np.abs(lam).max() + 1e-12


@pytest.mark.parametrize("blocks", STRUCTURES[:4])
def test_worst_perturbation_is_structured_and_destabilising(blocks):
    bs = as_block_structure(blocks)
    rng = np.random.default_rng(5)
    M = crandn(rng, 25, bs.n_out, bs.n_in)
    res = rc.mu(M, bs)
    k = int(np.argmax(res.lower))
    D = res.worst_perturbation
    assert res.f_worst_hz is not None
    assert np.linalg.norm(D, 2) == pytest.approx(1.0 / res.lower_peak, rel=1e-8)
    smin = np.linalg.svd(np.eye(bs.n_out) - M[k] @ D, compute_uv=False)[-1]
    assert smin < 1e-6
    mask = np.zeros_like(D, dtype=bool)
    for b, o, i in zip(bs.blocks, bs.row_slices(), bs.col_slices()):
        mask[i, o] = True
        blk = D[i, o]
        if b.kind != "full":
            assert np.allclose(blk, blk[0, 0] * np.eye(b.rows))
        if b.kind == "real":
            assert abs(blk[0, 0].imag) < 1e-12
    assert np.all(D[~mask] == 0)


@pytest.mark.parametrize(
    "blocks, seed",
    [([[1, 0], [1, 0], [1, 0], [3, 3]], 0), ([[-1, 0], [1, 0], [2, 2]], 1), ([[2, 0], [-1, 0], [1, 2]], 2),
     ([[-2, 0], [2, 2]], 3)],
)
def test_upper_within_one_percent_of_lmi(blocks, seed):
    bs = as_block_structure(blocks)
    lay = layout_of(bs)
    rng = np.random.default_rng(seed)
    M = crandn(rng, 2, bs.n_out, bs.n_in)
    res = rc.mu(M, bs)
    for k in range(2):
        ref, _, _ = lmi_upper_bound(M[k], lay, bracket=(res.lower[k], np.linalg.norm(M[k], 2)), rel_tol=2e-4)
        assert res.upper[k] <= ref * 1.01
        assert res.upper[k] >= ref * (1 - 1e-3)  # the LMI optimum is the best D-G bound


def _modal_response(seed, f_hz, n=6):
    """A seeded lightly damped 12-state n x n system's response (the mu benchmark's case)."""
    rng = np.random.default_rng(seed)
    A = np.zeros((12, 12))
    for k, f in enumerate(np.geomspace(0.5, 50.0, 6)):
        w, z = 2 * np.pi * f, rng.uniform(0.01, 0.05)
        A[2 * k: 2 * k + 2, 2 * k: 2 * k + 2] = [[-z * w, w], [-w, -z * w]]
    B, C = rng.standard_normal((12, n)), rng.standard_normal((n, 12))
    D = 0.3 * rng.standard_normal((n, n))
    return rc.freqresp(control.ss(A, B, C, D), f_hz).response


def test_mixed_upper_within_two_permille_of_lmi_on_modal_response():
    # two real scalars, a complex scalar and a 3x3 full block; at these frequencies of the
    # 1000-point benchmark grid the bound used to stop 0.4-0.75 % above the LMI optimum
    blocks = [[-1, 0], [-1, 0], [1, 0], [3, 3]]
    f = np.geomspace(0.1, 100.0, 1000)[[180, 240, 250, 260, 270]]
    M = _modal_response(0, f)
    lay = layout_of(as_block_structure(blocks))
    res = rc.mu(M, blocks, f_hz=f)
    for k in range(f.size):
        ref, _, _ = lmi_upper_bound(M[k], lay, bracket=(res.lower[k], np.linalg.norm(M[k], 2)), rel_tol=1e-5)
        assert res.upper[k] <= ref * 1.002
        assert res.upper[k] >= ref * (1 - 1e-4)


@pytest.mark.parametrize("blocks, seed", [([[-1, 0], [-1, 0], [-1, 0], [1, 1]], 2),
                                          ([[-1, 0], [2, 0], [-1, 0], [1, 2]], 0),
                                          ([[-2, 0], [1, 0], [2, 2]], 1)])
def test_mixed_upper_within_two_permille_of_lmi_random(blocks, seed):
    bs = as_block_structure(blocks)
    lay = layout_of(bs)
    M = crandn(np.random.default_rng(seed), 4, bs.n_out, bs.n_in)
    res = rc.mu(M, bs)
    for k in range(4):
        ref, _, _ = lmi_upper_bound(M[k], lay, bracket=(res.lower[k], np.linalg.norm(M[k], 2)), rel_tol=1e-5)
        assert res.upper[k] <= ref * 1.002 + 1e-12
        assert res.upper[k] >= ref * (1 - 1e-4) - 1e-12


def test_lmi_route_reads_unbounded_as_feasible():
    # real blocks only and a complex M: mu is 0 (no real Delta makes I - M Delta singular
    # generically); the LMI's objective is unbounded below at every level
    lay = layout_of(as_block_structure([[-1, 0], [-1, 0]]))
    M = crandn(np.random.default_rng(0), 2, 2)
    beta, _, _ = lmi_upper_bound(M, lay)
    assert beta <= 1e-6 * np.linalg.norm(M, 2)


def test_lmi_method_matches_batched():
    rng = np.random.default_rng(4)
    M = crandn(rng, 2, 4, 4)
    auto = rc.mu(M, [[-1, 0], [1, 0], [2, 2]])
    lmi = rc.mu(M, [[-1, 0], [1, 0], [2, 2]], method="lmi")
    assert lmi.method == "lmi"
    np.testing.assert_allclose(auto.upper, lmi.upper, rtol=5e-3)
    np.testing.assert_allclose(lmi.d_scales[:, -1], 1.0)


# ---------------------------------------------------------------------------- spellings and inputs
def test_mussv_spelling_and_blocks_agree():
    rng = np.random.default_rng(3)
    M = crandn(rng, 5, 4, 4)
    a = rc.mu(M, [[2, 0], [-1, 0], [1, 1]])
    b = rc.mu(M, [Block("complex", 2, 2), Block("real", 1, 1), Block("full", 1, 1)])
    c = rc.mu(M, np.array([[2, 0], [-1, 0], [1, 1]]))
    np.testing.assert_allclose(a.upper, b.upper, rtol=1e-12)
    np.testing.assert_allclose(a.upper, c.upper, rtol=1e-12)
    assert a.blocks.mussv().tolist() == [[2, 0], [-1, 0], [1, 1]]
    assert a.d_scales.shape == (5, 3) and np.allclose(a.d_scales[:, -1], 1.0)
    assert a.d_matrices[0].shape == (5, 2, 2)
    assert a.g_scales.shape == (5, 3) and np.all(a.g_scales[:, [0, 2]] == 0)


def test_frequency_dependent_inputs_agree():
    A = np.array([[-0.2, 3.0, 0.0], [-3.0, -0.2, 0.0], [0.0, 0.0, -1.0]])
    B = np.array([[1.0, 0.0], [0.5, 1.0], [0.0, 1.0]])
    C = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, -1.0]])
    sys = control.ss(A, B, C, np.zeros((2, 2)))
    f = np.geomspace(0.01, 5.0, 120)
    blocks = [[1, 0], [1, 0]]
    r_sys = rc.mu(sys, blocks, f)
    G = rc.freqresp(sys, f)
    r_frd = rc.mu(G, blocks)
    r_arr = rc.mu(G.response, blocks, f)
    np.testing.assert_allclose(r_sys.upper, r_frd.upper, rtol=1e-10)
    np.testing.assert_allclose(r_sys.upper, r_arr.upper, rtol=1e-10)
    np.testing.assert_allclose(r_sys.f_hz, f)
    k = int(np.argmax(r_sys.upper))
    assert r_sys.f_peak_hz == f[k] and r_sys.peak == r_sys.upper[k]
    assert 0.3 < r_sys.f_peak_hz < 0.7  # the resonance at 3 rad/s = 0.477 Hz
    # a SISO system with one full block: mu is |G(j w)|
    g = control.tf([2.0], [1.0, 0.4, 1.0])
    r = rc.mu(g, [[1, 1]], f)
    np.testing.assert_allclose(r.upper, np.abs(rc.freqresp(g, f).response[:, 0, 0]), rtol=1e-10)


def test_executor_chunks_match_serial():
    rng = np.random.default_rng(9)
    M = crandn(rng, 60, 4, 4)
    serial = rc.mu(M, [[1, 0], [1, 0], [2, 2]])
    with ThreadPoolExecutor(2) as ex:
        par = rc.mu(M, [[1, 0], [1, 0], [2, 2]], executor=ex, chunk=16)
    assert par.info["n_chunks"] == 4
    np.testing.assert_allclose(par.upper, serial.upper, rtol=1e-3)
    assert np.all(par.lower <= par.upper * (1 + 1e-9))


@pytest.mark.parametrize(
    "M, blocks, f_hz, words",
    [
        (np.ones((3, 3)), [[1, 0], [1, 1]], None, "M must be 2 x 2"),
        (np.ones((5, 2, 3)), [[1, 0], [1, 0]], None, "got shape (5, 2, 3)"),
        (np.full((2, 2), np.nan), [[1, 0], [1, 0]], None, "NaN"),
        (np.zeros((0, 2, 2)), [[1, 0], [1, 0]], None, "empty"),
        (np.ones((4, 2, 2)), [[1, 0], [1, 0]], [1.0, 2.0], "f_hz has 2 frequencies"),
        (control.tf([1.0], [1.0, 1.0]), [[1, 1]], None, "pass f_hz"),
        (np.ones((2, 2)), [[0, 1]], None, "is not a block"),
        (np.ones((2, 2)), "complex", None, "blocks must be"),
        (np.ones((1, 1)), [[1, 1]], [np.nan], "NaN or inf"),
    ],
)
def test_bad_input_is_refused_clearly(M, blocks, f_hz, words):
    with pytest.raises(rc.SynthesisError, match=None) as err:
        rc.mu(M, blocks, f_hz)
    assert words in str(err.value)


def test_bad_options_are_refused():
    with pytest.raises(rc.SynthesisError, match="method"):
        rc.mu(np.eye(2), [[1, 0], [1, 0]], method="bisect")
    with pytest.raises(rc.RobustctlError, match="executor must be"):
        rc.mu(np.eye(2), [[1, 0], [1, 0]], executor=object())
    with pytest.raises(rc.SynthesisError, match="chunk"):
        rc.mu(np.eye(2), [[1, 0], [1, 0]], chunk=0)
    fd = rc.freqresp(control.tf([1.0], [1.0, 1.0]), [1.0, 2.0])
    with pytest.raises(rc.SynthesisError, match="own frequencies"):
        rc.mu(fd, [[1, 1]], [1.0, 2.0])


# ---------------------------------------------------------------------------- analyses
def test_robust_stability_performance_and_worst_case_gain():
    rng = np.random.default_rng(1)
    N = 0.4 * crandn(rng, 8, 2, 2)  # [[N11, N12], [N21, N22]]: complex scalar uncertainty, SISO performance
    th = np.exp(1j * np.linspace(0, 2 * np.pi, 20001))
    rs = rc.robust_stability(N, [[1, 0]])
    np.testing.assert_allclose(rs.upper, np.abs(N[:, 0, 0]), rtol=1e-10)
    assert rs.stability_margin == pytest.approx(1 / np.abs(N[:, 0, 0]).max())
    rp = rc.robust_performance(N, [[1, 0]])
    assert rp.blocks.mussv().tolist() == [[1, 0], [1, 1]]
    assert rp.blocks[-1].name == "performance"
    np.testing.assert_allclose(rc.robust_performance(N, [[1, 0], [1, 1]]).upper, rp.upper)  # given in full
    wc = rc.worst_case_gain(N, [[1, 0]])
    assert np.any(np.abs(N[:, 0, 0]) >= 1) and np.any(np.abs(N[:, 0, 0]) < 1)
    for k in range(8):
        a, b, c, d = N[k, 0, 0], N[k, 0, 1], N[k, 1, 0], N[k, 1, 1]
        if abs(a) >= 1:  # not robustly stable: unbounded worst-case gain
            assert wc.upper[k] == np.inf and wc.lower[k] == np.inf
            continue
        brute = np.abs(d + c * th * b / (1 - a * th)).max()
        assert wc.lower[k] <= brute * (1 + 1e-6) and wc.upper[k] >= brute * (1 - 1e-6)
        assert wc.upper[k] == pytest.approx(brute, rel=3e-3)
        # main loop theorem: robust performance (mu < 1) iff the worst-case gain is below 1
        assert (rp.upper[k] < 1) == (wc.upper[k] < 1) or abs(rp.upper[k] - 1) < 5e-3


def test_analyses_refuse_mismatched_channels():
    with pytest.raises(rc.SynthesisError, match="uncertainty channels"):
        rc.robust_stability(np.ones((2, 2)), [[3, 3]])
    with pytest.raises(rc.SynthesisError, match="performance channels"):
        rc.robust_performance(np.ones((3, 2)), [[2, 2]])


# ---------------------------------------------------------------------------- presentation
def test_result_presentation():
    f = np.geomspace(0.1, 10.0, 50)
    sys = control.ss([[-0.1, 2.0], [-2.0, -0.1]], np.eye(2), np.eye(2), np.zeros((2, 2)))
    res = rc.mu(sys, [[1, 0], [1, 0]], f)
    tab = res.table()
    assert tab.column("mu upper")[0] == pytest.approx(res.peak)
    assert "peak upper bound" in res.summary() and f"{res.peak:.4g}" in res.summary()
    assert "<table>" in res._repr_html_()
    fig = res.plot()
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and ax.get_xlabel() == "frequency (Hz)" and ax.get_ylabel() == "mu"
    labels = [line.get_label() for line in ax.get_lines()]
    assert "mu upper bound" in labels and "mu lower bound" in labels
    lo, hi = res.stability_margin_bounds
    assert lo == pytest.approx(1 / res.peak) and hi >= lo * (1 - 1e-12)


def test_edge_cases_zero_nilpotent_scale_and_single_real():
    M = np.zeros((3, 3, 3), complex)
    M[1] = np.triu(np.ones((3, 3)), 1)  # nilpotent: mu = 0, approached by extreme D-scales
    M[2] = 2.0 * np.eye(3)
    res = rc.mu(M, [[1, 0]] * 3)
    assert res.upper[0] == 0 and res.lower[0] == 0
    assert res.upper[1] < 1e-6 and res.lower[1] == 0
    assert res.upper[2] == pytest.approx(2.0) and res.lower[2] == pytest.approx(2.0)
    base = np.array([[1.0, 2.0], [0.5j, -1.0]])
    ref = rc.mu(base, [[1, 0], [1, 0]])
    for c in (1e-200, 1e200):  # mu(c M) = c mu(M) without over- or underflow
        res = rc.mu(c * base, [[1, 0], [1, 0]])
        assert res.upper[0] == pytest.approx(c * ref.upper[0], rel=1e-9)
        assert res.lower[0] == pytest.approx(c * ref.lower[0], rel=1e-9)
    # one real scalar: mu = |m| for real m, 0 for purely imaginary m (1 - j delta never vanishes)
    assert rc.mu(np.array([[-3.0]]), [[-1, 0]]).lower[0] == pytest.approx(3.0)
    assert rc.mu(np.array([[-3.0]]), [[-1, 0]]).upper[0] == pytest.approx(3.0)
    assert rc.mu(np.array([[2j]]), [[-1, 0]]).upper[0] < 1e-6


def test_analyses_on_a_system_and_worst_case_presentation():
    # closed loop with one complex scalar uncertainty channel and one performance channel
    A = np.array([[-0.3, 2.0], [-2.0, -0.3]])
    B = np.array([[0.3, 1.0], [0.2, 0.0]])
    C = np.array([[0.4, 0.1], [0.0, 1.0]])
    sys = control.ss(A, B, C, np.zeros((2, 2)))
    f = np.geomspace(0.05, 2.0, 40)
    N = rc.freqresp(sys, f).response
    rs = rc.robust_stability(sys, [[1, 0]], f)
    np.testing.assert_allclose(rs.upper, np.abs(N[:, 0, 0]), rtol=1e-9)
    assert rs.peak < 1
    wc = rc.worst_case_gain(sys, [[1, 0]], f, rel_tol=1e-4)
    th = np.exp(1j * np.linspace(0, 2 * np.pi, 4001))
    a, b, c, d = (N[:, i, j, None] for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)))
    brute = np.abs(d + c * th * b / (1 - a * th)).max(axis=1)  # F_u(N, delta) over |delta| = 1
    np.testing.assert_allclose(wc.upper, brute, rtol=2e-3)
    assert np.all(wc.lower <= brute * (1 + 1e-6)) and np.all(wc.upper >= brute * (1 - 1e-6))
    assert np.all(wc.upper >= wc.nominal * (1 - 1e-9))
    assert wc.f_peak_hz == f[int(np.argmax(wc.upper))]
    assert "Worst-case gain" in wc.summary() and "<table>" in wc._repr_html_()
    assert wc.table().column("worst-case gain <=")[0] == pytest.approx(wc.peak)
    assert wc.plot().axes[0].get_yscale() == "log"


def test_scalar_and_python_control_frd_inputs():
    assert rc.mu(3.0, [[1, 0]]).upper[0] == pytest.approx(3.0)
    f = np.array([0.1, 1.0])
    g = rc.freqresp(control.tf([1.0], [1.0, 1.0]), f)
    frd = control.frd(g.response[:, 0, 0], 2 * np.pi * f)
    res = rc.mu(frd, [[1, 1]])
    np.testing.assert_allclose(res.upper, np.abs(g.response[:, 0, 0]), rtol=1e-10)
    np.testing.assert_allclose(res.f_hz, f)
    with pytest.raises(rc.SynthesisError, match="time_budget_s"):
        rc.mu(np.eye(2), [[1, 0], [1, 0]], time_budget_s=-1.0)


def test_repeated_scalar_blocks_get_hermitian_d_matrices():
    rng = np.random.default_rng(8)
    M = crandn(rng, 6, 5, 5)
    res = rc.mu(M, [[3, 0], [2, 2]])
    D = res.d_matrices[0]
    assert D.shape == (6, 3, 3)
    np.testing.assert_allclose(D, np.swapaxes(D, 1, 2).conj(), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(D) > 0)
    for k in range(6):  # the scaled matrix attains the bound
        DL, DR = _dl_dr(res, k)
        assert np.linalg.norm(DL @ M[k] @ np.linalg.inv(DR), 2) == pytest.approx(res.upper[k], rel=1e-9)


def test_results_pickle():
    import pickle

    rng = np.random.default_rng(2)
    N = 0.3 * crandn(rng, 5, 3, 3)
    res = rc.mu(N, [[-1, 0], [2, 2]], np.linspace(1.0, 5.0, 5))
    back = pickle.loads(pickle.dumps(res))
    np.testing.assert_array_equal(back.upper, res.upper)
    assert back.blocks == res.blocks and back.summary() == res.summary()
    wc = rc.worst_case_gain(N, [[1, 0], [1, 0]])
    assert pickle.loads(pickle.dumps(wc)).peak == wc.peak


def test_analyses_take_a_generalized_plant_and_its_blocks():
    num = [[[1.0], [0.5]], [[0.2], [1.0]]]
    den = [[[1.0, 0.4, 1.0], [1.0, 1.0]], [[1.0, 2.0], [1.0, 0.6, 4.0]]]
    G = control.ss(control.tf(num, den))
    gp = rc.generalized_plant(G, input_mult=0.1, output_mult=0.1, performance=0.5, noise=0.01)
    assert gp.blocks[-1].name == "performance"
    cl = rc.interconnect.lft(gp, control.ss([], [], [], -0.5 * np.eye(2)))
    f = np.geomspace(0.05, 2.0, 30)
    unc = as_block_structure(gp.blocks.blocks[:-1])
    rs_plain = rc.robust_stability(cl, unc, f)
    np.testing.assert_allclose(rc.robust_stability(cl, gp.blocks, f).upper, rs_plain.upper)
    np.testing.assert_allclose(rc.robust_stability(cl, gp, f).upper, rs_plain.upper)
    rp = rc.robust_performance(cl, gp, f)
    assert rp.blocks.mussv().tolist() == gp.blocks.mussv().tolist()
    assert np.all(rp.upper >= rs_plain.upper * (1 - 1e-9))  # adding a block cannot lower mu


def test_lmi_route_falls_back_to_scs_when_clarabel_fails(monkeypatch):
    import cvxpy as cp

    original = cp.Problem.solve

    def failing_clarabel(self, *args, **kwargs):
        if kwargs.get("solver") == cp.CLARABEL:
            raise cp.error.SolverError("Solver 'CLARABEL' failed (forced by the test)")
        return original(self, *args, **kwargs)

    blocks = [[-1, 0], [1, 0], [2, 2]]
    lay = layout_of(as_block_structure(blocks))
    M = crandn(np.random.default_rng(4), 4, 4)
    ref, _, _ = lmi_upper_bound(M, lay, rel_tol=1e-5)
    monkeypatch.setattr(cp.Problem, "solve", failing_clarabel)
    beta, _, _ = lmi_upper_bound(M, lay, rel_tol=1e-5)
    assert beta == pytest.approx(ref, rel=2e-3)
