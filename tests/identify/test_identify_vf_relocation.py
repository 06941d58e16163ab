"""The compressed VF pole relocation (per-channel QR / Gram elimination, Deschrijver et al. 2008)
against the uncompressed relaxed VF least-squares problem solved in one piece.

The reference here is written independently of ``robustctl.identify``: its own partial-fraction
basis, every channel's residue unknowns and the shared sigma unknowns stacked into one dense
block matrix with the relaxation row (Gustavsen 2006, eq. 9), solved by ``numpy.linalg.lstsq``,
and the zeros of ``sigma`` from its complex pole-residue form (eigenvalues of
``diag(q) - 1 r^T / d``). The compressed step eliminates the channel unknowns channel by channel
(only each channel's ``R22`` block or Schur complement enters the sigma system); both must give
the same new poles.
"""

from __future__ import annotations

import numpy as np
import pytest


def _case(n_ch: int = 5, seed: int = 4):
    """Three lightly damped modes, ``n_ch`` channels, 1 % complex noise, scaled band top 1j."""
    rng = np.random.default_rng(seed)
    s = 1j * np.linspace(0.08, 1.0, 240)
    wk = np.array([0.25, 0.55, 0.8])
    zk = np.array([0.02, 0.01, 0.03])
    p = -zk * wk + 1j * wk * np.sqrt(1 - zk**2)
    r = rng.normal(size=(3, n_ch)) + 1j * rng.normal(size=(3, n_ch))
    g = sum((r[k] / (s[:, None] - p[k]) + np.conj(r[k]) / (s[:, None] - np.conj(p[k]))) for k in range(3))
    g = g * (1 + 0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    rw = 1.0 / np.abs(g)
    start = np.array([-0.003 + 0.15j, -0.005 + 0.4j, -0.007 + 0.65j, -0.009 + 0.9j])
    return s, g, rw, start


def _basis(s: np.ndarray, poles: np.ndarray) -> np.ndarray:
    cols = []
    for q in poles:
        a, b = 1 / (s - q), 1 / (s - np.conj(q))
        cols += [a + b, 1j * (a - b)]
    return np.stack(cols, axis=1)


def _uncompressed_step(s, g, rw, poles):
    """Relaxed VF: min sum_c |rw_c (B r_c - g_c (d + Phi c))|^2 + (scale (K d + Re sum Phi c) - scale K)^2
    over all channels' residues and the shared (d, c) at once; returns the zeros of sigma (upper
    half plane, sorted by |z|) and the weighted cost of the current poles' fit."""
    k, n_ch = g.shape
    phi = _basis(s, poles)
    n = phi.shape[1]
    base = np.hstack([phi, np.ones((k, 1))])
    rows = []
    for c in range(n_ch):
        block = np.zeros((k, n_ch * (n + 1) + n + 1), dtype=complex)
        block[:, c * (n + 1):(c + 1) * (n + 1)] = base * rw[:, c:c + 1]
        block[:, n_ch * (n + 1)] = -g[:, c] * rw[:, c]
        block[:, n_ch * (n + 1) + 1:] = -phi * (g[:, c] * rw[:, c])[:, None]
        rows += [block.real, block.imag]
    scale = np.sqrt(np.sum(np.abs(rw * g) ** 2)) / k
    con = np.zeros(n_ch * (n + 1) + n + 1)
    con[n_ch * (n + 1)] = k * scale
    con[n_ch * (n + 1) + 1:] = np.sum(phi, axis=0).real * scale
    a = np.vstack(rows + [con[None, :]])
    rhs = np.zeros(a.shape[0])
    rhs[-1] = k * scale
    x = np.linalg.lstsq(a, rhs, rcond=None)[0]
    d, coef = x[n_ch * (n + 1)], x[n_ch * (n + 1) + 1:]
    res = coef[0::2] + 1j * coef[1::2]  # residue of sigma at each pole (its conjugate at conj(pole))
    q = np.concatenate([poles, np.conj(poles)])
    rq = np.concatenate([res, np.conj(res)])
    zeros = np.linalg.eigvals(np.diag(q) - np.outer(np.ones(q.size), rq) / d)
    # the current poles' weighted cost: each channel's residues fitted alone (sigma = 1)
    cost = 0.0
    for c in range(n_ch):
        m = base * rw[:, c:c + 1]
        m = np.vstack([m.real, m.imag])
        y = np.concatenate([(g[:, c] * rw[:, c]).real, (g[:, c] * rw[:, c]).imag])
        cost += float(np.sum((m @ np.linalg.lstsq(m, y, rcond=None)[0] - y) ** 2))
    return zeros, cost


def _all_roots(poles: np.ndarray) -> np.ndarray:
    """One pole per pair plus real poles -> every root (pairs with their conjugates)."""
    return np.concatenate([poles, np.conj(poles[poles.imag != 0])])


def _match_error(a: np.ndarray, b: np.ndarray) -> float:
    """Largest relative distance of each root of ``a`` to the nearest of ``b`` (same sizes)."""
    assert a.size == b.size
    return float(max(np.min(np.abs(b - z)) / abs(z) for z in a))


@pytest.mark.parametrize("gram", [False, True])
def test_compressed_relocation_equals_the_stacked_least_squares(gram):
    """One relocation by channel elimination (QR R22 blocks, or Schur complements from moment
    Gram matrices) gives the poles of the uncompressed stacked problem to 1e-8 relative, and the
    same weighted cost of the current poles."""
    from robustctl.identify.vector_fitting import vf_step

    s, g, rw, poles = _case()
    ref, ref_cost = _uncompressed_step(s, g, rw, poles)
    new, cost = vf_step(s, g, rw, poles, stable=False, gram=gram)
    roots = _all_roots(new)
    assert roots.size == ref.size == 2 * poles.size
    assert _match_error(ref, roots) < 1e-8 and _match_error(roots, ref) < 1e-8
    assert cost == pytest.approx(ref_cost, rel=1e-8)


def test_compressed_relocation_converges_to_the_true_modes():
    """Iterated compressed relocations from spread starting poles find the three modes of the
    data to the noise's accuracy (1e-3 relative), the same fixed point as the stacked problem."""
    from robustctl.identify.vector_fitting import vf_poles

    s, g, rw, start = _case(n_ch=8)
    poles, _, _ = vf_poles(s, g, rw, 6, max_iter=30, start=start[:3])
    ref = start[:3]
    for _ in range(30):
        z, _ = _uncompressed_step(s, g, rw, ref)
        z = np.where(z.real > 0, -z.real + 1j * z.imag, z)
        ref = z[z.imag > 0]
    wk = np.array([0.25, 0.55, 0.8])
    assert poles.size == 3 and ref.size == 3
    poles = poles[np.argsort(np.abs(poles))]
    assert np.max(np.abs(np.abs(poles) / wk - 1)) < 1e-3
    assert _match_error(poles, ref) < 1e-6
