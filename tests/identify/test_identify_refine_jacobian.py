"""The block refinement's analytic variable-projection Jacobian (Golub & Pereyra 1973) against
central differences of a projected residual written here with numpy's ``lstsq``, with and without
an impact record's truncation (eq. T1), and the refinement it drives recovering exact poles."""

import numpy as np
import pytest

from robustctl.identify.block_refine import ZETA_MIN, _Projection, refine_cluster
from robustctl.identify.tail import leaked_terms
from robustctl.measure.impact_view import TruncationSettings


def _cluster(seed: int = 0, noise: float = 0.05):
    """Two modes 3 % apart (10 and 10.3 Hz, 1 % damping), 3 outputs x 2 inputs, 60 lines."""
    rng = np.random.default_rng(seed)
    poles = 2 * np.pi * np.array([10.0, 10.3]) * (-0.01 + 1j)
    s = 2j * np.pi * np.linspace(9.0, 11.5, 60)
    bs = rng.normal(size=(2, 2)) + 1j * rng.normal(size=(2, 2))
    cs = rng.normal(size=(2, 3)) + 1j * rng.normal(size=(2, 3))
    a, ab = 1 / (s[:, None] - poles), 1 / (s[:, None] - np.conj(poles))
    g = np.einsum("km,mo,mi->koi", a, cs, bs) + np.einsum("km,mo,mi->koi", ab, np.conj(cs), np.conj(bs))
    g = g * (1 + noise * (rng.normal(size=g.shape) + 1j * rng.normal(size=g.shape)))
    rw = rng.uniform(0.5, 1.5, g.shape) / np.abs(g)
    return s, g, rw, poles, cs, bs


def _numpy_residual(theta, s, g, rw, m, n_in, truncation, term_pole, complex_constant, floor):
    """The projected residual from scratch: poles ``-(floor |w| + exp(theta)) + j w``, per output
    the real least-squares fit (numpy lstsq) of every term's columns ``a c b + ab conj(c b)`` (the
    term's pole ``term_pole[t]``) and a constant per input (complex or real), real and imaginary
    parts stacked."""
    omega = theta[m : 2 * m]
    poles = -(floor * np.abs(omega) + np.exp(theta[:m])) + 1j * omega
    b = theta[2 * m :].reshape(-1, 2, n_in)
    b = b[:, 0] + 1j * b[:, 1]
    a, ab, _, _ = leaked_terms(s, poles, truncation)
    out = np.zeros(g.shape, dtype=complex)
    for o in range(g.shape[1]):
        cols = []
        for t, q in enumerate(term_pole):
            cols += [
                a[:, q, None] * b[t] + ab[:, q, None] * np.conj(b[t]),
                1j * (a[:, q, None] * b[t] - ab[:, q, None] * np.conj(b[t])),
            ]
        for i in range(n_in):
            e = np.zeros((s.size, n_in), dtype=complex)
            e[:, i] = 1.0
            cols += [e, 1j * e] if complex_constant else [e]
        x = np.stack(cols, axis=-1) * rw[:, o, :, None]  # (K, n_in, U)
        x = x.reshape(-1, x.shape[-1])
        y = (rw[:, o] * g[:, o]).ravel()
        coef = np.linalg.lstsq(np.vstack([x.real, x.imag]), np.concatenate([y.real, y.imag]), rcond=None)[0]
        out[:, o] = (x @ coef - y).reshape(s.size, n_in)
    return np.concatenate([out.real.ravel(), out.imag.ravel()])


TRUNCATION = TruncationSettings(
    fs_hz=64.0, record_s=2.0, hit_times_s=(0.1, 0.2), hit_weights=(0.6, 0.4), hit_spreads_s=(0.01, 0.02)
)
#: (truncation, terms per pole, complex constant, damping floor): a block of the block refinement
#: (one term per mode, complex local constant, decay above ZETA_MIN), with an impact record's
#: truncation, and the joint refinement's (a rank-2 pole, real feedthrough D, plain log decay)
SETUPS = {
    "block": (None, [0, 1], True, ZETA_MIN),
    "block-truncated": (TRUNCATION, [0, 1], True, ZETA_MIN),
    "joint-rank-2": (None, [0, 1, 1], False, 0.0),
    "joint-rank-2-truncated": (TRUNCATION, [0, 0, 1], False, 0.0),
}


@pytest.mark.parametrize("setup", list(SETUPS))
def test_variable_projection_jacobian_matches_finite_differences(setup):
    truncation, term_pole, complex_constant, floor = SETUPS[setup]
    s, g, rw, poles, _, bs = _cluster()
    m, n_in = bs.shape
    rng = np.random.default_rng(5)
    b_terms = bs[term_pole] + 0.3 * (
        rng.normal(size=(len(term_pole), n_in)) + 1j * rng.normal(size=(len(term_pole), n_in))
    )
    # a point away from the optimum: decays 10 % up, frequencies 0.1 % up, input shapes moved
    theta = np.concatenate(
        [
            np.log(-poles.real * 1.1 - floor * poles.imag),
            poles.imag * 1.001,
            np.stack([b_terms.real, b_terms.imag], axis=1).ravel(),
        ]
    )
    proj = _Projection(s, g, rw, m, n_in, truncation, np.array(term_pole), complex_constant, floor)
    args = (s, g, rw, m, n_in, truncation, term_pole, complex_constant, floor)
    ref = _numpy_residual(theta, *args)
    np.testing.assert_allclose(proj.residual(theta), ref, atol=1e-9 * np.max(np.abs(ref)))
    jac = proj.jacobian(theta)
    fd = np.empty_like(jac)
    for j in range(theta.size):
        h = 1e-6 * max(1.0, abs(theta[j]))
        up, down = theta.copy(), theta.copy()
        up[j], down[j] = up[j] + h, down[j] - h
        fd[:, j] = (_numpy_residual(up, *args) - _numpy_residual(down, *args)) / (2 * h)
    # per column, relative to the column or to 5 % of the largest one: a rank-2 pole's input shapes
    # with 2 inputs span every input direction, so they leave the residual unchanged (a zero column,
    # which the Jacobian has to 1e-9 and the differences to their own noise, 3e-9 of the largest)
    norm = np.linalg.norm(fd, axis=0)
    err = np.linalg.norm(jac - fd, axis=0) / np.maximum(norm, 0.05 * norm.max())
    assert np.all(err < 1e-6), err  # measured 1e-9 - 2e-8 (the differences' own error)


def test_cluster_refinement_recovers_exact_poles_and_shapes():
    """Noise-free data of the two modes, starts 0.3 % off in frequency and 30 % in damping: the
    refined poles are the true ones to 1e-9 relative and the weighted cost falls to round-off."""
    s, g, rw, poles, cs, bs = _cluster(noise=0.0)
    start = poles.real * 1.3 + 1j * poles.imag * np.array([1.003, 0.997])
    p, c, b, before, after = refine_cluster(s, g, rw, start, cs, bs)
    order = np.argsort(p.imag)
    np.testing.assert_allclose(p[order], poles, rtol=1e-9)
    assert before > 1.0 and after < 1e-16 * before  # from 8.5 to 7e-20 measured
    model = np.einsum("km,mo,mi->koi", 1 / (s[:, None] - p), c, b)
    model += np.einsum("km,mo,mi->koi", 1 / (s[:, None] - np.conj(p)), np.conj(c), np.conj(b))
    assert np.max(np.abs(model / g - 1)) < 1e-8  # the shapes are the true ones (the constant is 0)


def test_cluster_refinement_holds_each_terms_largest_input_shape_entry():
    """``c b^T`` is unchanged by ``b -> alpha b, c -> c / alpha`` and ``c`` is eliminated, so each
    term's largest input-shape entry is held: with one input the whole ``b`` (measured: the
    Levenberg-Marquardt refinement that moved it sent it from 1 to 2e13 and 5e15, as the
    round-off in its null columns steered), with two inputs the start's largest entry. The
    refined poles, cost and model do not depend on the scale ``b`` starts at."""
    rng = np.random.default_rng(1)
    poles = 2 * np.pi * np.array([10.0, 10.3]) * (-0.01 + 1j)
    s = 2j * np.pi * np.linspace(9.0, 11.5, 60)
    r = np.array([1.0 + 0.3j, -0.6 + 0.5j])
    g = np.sum(r / (s[:, None] - poles) + np.conj(r) / (s[:, None] - np.conj(poles)), axis=1)
    g = (g * (1 + 0.05 * (rng.normal(size=g.shape) + 1j * rng.normal(size=g.shape))))[:, None, None]
    rw = rng.uniform(0.5, 1.5, g.shape) / np.abs(g)
    start = poles.real * 1.3 + 1j * poles.imag * np.array([1.003, 0.997])
    runs = []
    for alpha in (1.0, 1e3 * np.exp(0.7j)):
        bs = np.full((2, 1), alpha, dtype=complex)
        p, c, b, before, after = refine_cluster(s, g, rw, start, r[:, None] / alpha, bs)
        np.testing.assert_array_equal(b, bs)
        assert after < 0.3 * before  # 1.004 -> 0.264 measured (5 % noise)
        runs.append((p, after, (c * b).ravel()))
    (p1, cost1, r1), (p2, cost2, r2) = runs
    np.testing.assert_allclose(p2, p1, rtol=1e-10)
    assert cost2 == pytest.approx(cost1, rel=1e-10)
    np.testing.assert_allclose(r2, r1, rtol=1e-8)  # the residues c b (measured 1e-13)

    s2, g2, rw2, poles2, cs2, bs2 = _cluster()
    start2 = poles2.real * 1.3 + 1j * poles2.imag * np.array([1.003, 0.997])
    _, _, b2, _, _ = refine_cluster(s2, g2, rw2, start2, cs2, bs2)
    held = np.argmax(np.abs(bs2), axis=1)
    np.testing.assert_array_equal(b2[[0, 1], held], bs2[[0, 1], held])
    assert not np.allclose(b2, bs2)  # the other entry moved
