"""Honest mode lists: ``MeasurementModel.modes`` holds exactly the physical modes in the band, every
other pole of the model is a filler (kept in the state space, listed apart), and ``n_modes=N``
gives N physical modes or a warning with the number the data support.

The structures and their data are built here with numpy/scipy: exact receptances of M, K, C
models with multiplicative complex noise, and the 3-storey frame's H1 from scipy-simulated ZOH
records (see test_measurement_model_consistency). Frequencies are checked against the
eigenvalues of the state matrix, damping ratios against ``-Re(lambda)/|lambda|``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from test_measurement_model_consistency import _assert_one_model, _chain, frame_records, frame_system

import robustctl as rc
from robustctl.identify import IdentifyWarning
from robustctl.identify.significance import modal_phase_collinearity, pole_evidence

#: frequency of a listed mode against the true one (exact data with 0.5 % noise: the fit's
#: frequency error is a small fraction of the half-power width, 2 zeta f)
F_TOL = 0.005


def _receptance(M, K, C, b, c, f_hz, noise, seed):
    """``c (K - w^2 M + j w C)^-1 b`` at ``f_hz`` with complex multiplicative noise, and the true
    modal frequencies (Hz) and damping ratios of the second-order system."""
    w = 2 * np.pi * np.asarray(f_hz)
    g = np.array([c @ np.linalg.solve(K - x**2 * M + 1j * x * C, b) for x in w])
    rng = np.random.default_rng(seed)
    g = g * (1 + noise * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)) / np.sqrt(2))
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    order = np.argsort(np.abs(lam))
    f_true = np.abs(lam[order]) / (2 * np.pi)
    z_true = -lam[order].real / np.abs(lam[order])
    data = rc.FrequencyData(f_hz, g, inputs=[f"u{i}" for i in range(b.shape[1])],
                            outputs=[f"y{i}" for i in range(c.shape[0])])
    return data, f_true, z_true


def chain():
    """A 5-mass chain fixed at one end, 2 forces x 3 displacements, 1-2 % Rayleigh damping."""
    M = np.diag([1.0, 1.2, 0.9, 1.1, 0.8])
    K = _chain([5e4, 4e4, 4.5e4, 3.5e4, 3e4])
    C = 2e-5 * K + 0.8 * M
    b = np.zeros((5, 2))
    b[0, 0], b[3, 1] = 1.0, 1.0
    c = np.zeros((3, 5))
    c[0, 1], c[1, 2], c[2, 4] = 1.0, 1.0, 1.0
    return _receptance(M, K, C, b, c, np.linspace(5.0, 95.0, 600), 0.005, 1)


def plate_grid():
    """A 3 x 3 grid of masses on springs to the ground and to their neighbours (a plate's lowest
    bending family: nine modes at 22-51 Hz, some 3-5 % apart), 2 forces x 5 displacements."""
    n_side = 3
    n = n_side * n_side
    M = np.diag(np.linspace(0.8, 1.2, n))
    K = np.eye(n) * 2e4
    for i in range(n_side):
        for j in range(n_side):
            a = i * n_side + j
            for di, dj, k in ((1, 0, 1.5e4), (0, 1, 1.1e4)):
                if i + di < n_side and j + dj < n_side:
                    bnode = (i + di) * n_side + j + dj
                    K[a, a] += k
                    K[bnode, bnode] += k
                    K[a, bnode] -= k
                    K[bnode, a] -= k
    C = 1.5e-5 * K + 0.5 * M
    b = np.zeros((n, 2))
    b[0, 0], b[5, 1] = 1.0, 1.0
    c = np.zeros((5, n))
    for row, node in enumerate((0, 2, 4, 6, 7)):
        c[row, node] = 1.0
    data, f_true, z_true = _receptance(M, K, C, b, c, np.linspace(15.0, 80.0, 700), 0.005, 2)
    return data, f_true, z_true


def close_pair():
    """Two modes 1.5 % apart with different shapes (a nearly symmetric pair) and a third mode;
    2 forces x 3 displacements."""
    M = np.eye(3)
    K = np.array([[2.0e4, 0.0, -3e3], [0.0, 2.06e4, -3e3], [-3e3, -3e3, 5.0e4]])
    C = 1e-5 * K + 0.6 * M
    b = np.array([[1.0, 0.3], [0.2, 1.0], [0.5, 0.0]])
    c = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.4, 0.4, 1.0]])
    return _receptance(M, K, C, b, c, np.linspace(12.0, 50.0, 700), 0.005, 3)


def weak_mode():
    """Two strong modes and a weak one between them: its modal term is a few per cent of the
    response in the channels (several times the 0.5 % noise at its peak); 2 x 2."""
    M = np.eye(3)
    K = np.diag([1.0e4, 4.0e4, 9.0e4])
    C = 1e-5 * K + 0.4 * M
    b = np.array([[1.0, 0.8], [0.012, 0.01], [0.9, -0.7]])
    c = b.T.copy()
    return _receptance(M, K, C, b, c, np.linspace(8.0, 60.0, 800), 0.005, 4)


STRUCTURES = {"chain": chain, "plate_grid": plate_grid, "close_pair": close_pair, "weak_mode": weak_mode}


def _fit(data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", IdentifyWarning)
        return rc.fit_measurement_model(data, progress=False, **kw)


def _assert_true_modes(mm, f_true, z_true, z_rtol):
    band = mm.band_hz
    inside = (f_true >= band[0]) & (f_true <= band[1])
    f_in, z_in = f_true[inside], z_true[inside]
    f = np.array([m.f_hz for m in mm.modes])
    z = np.array([m.zeta for m in mm.modes])
    assert f.size == f_in.size, (f, f_in)
    np.testing.assert_allclose(f, f_in, rtol=F_TOL)
    np.testing.assert_allclose(z, z_in, rtol=z_rtol)
    filler_f = [m.f_hz for m in mm.fillers]
    assert not set(np.round(filler_f, 6)) & set(np.round(f, 6))
    assert mm.n_modes == f_in.size and len(mm.table().rows) == f_in.size


@pytest.mark.slow
@pytest.mark.parametrize("name", list(STRUCTURES))
def test_automatic_order_lists_exactly_the_true_modes(name):
    data, f_true, z_true = STRUCTURES[name]()
    mm = _fit(data)
    _assert_true_modes(mm, f_true, z_true, 0.1)
    _assert_one_model(mm)


@pytest.mark.parametrize("name", list(STRUCTURES))
def test_given_order_lists_exactly_the_true_modes(name):
    data, f_true, z_true = STRUCTURES[name]()
    n = int(np.sum((f_true >= data.f_hz[0]) & (f_true <= data.f_hz[-1])))
    mm = _fit(data, n_modes=n)
    _assert_true_modes(mm, f_true, z_true, 0.1)
    _assert_one_model(mm)


def test_asking_for_more_modes_than_the_data_hold_warns_with_the_number():
    data, f_true, _ = close_pair()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mm = rc.fit_measurement_model(data, n_modes=5, progress=False)
    assert mm.n_modes == 3
    assert any("support 3 physical" in str(w.message) for w in caught)
    _assert_one_model(mm)


@pytest.fixture(scope="module")
def frame_welch():
    u, y = frame_records()
    return rc.estimate_frf(u, y, fs=256.0, nperseg=1024, window="hann", inputs=["s1", "s2"],
                           outputs=["a1", "a2", "a3", "a4"])


def _frame_truth():
    A, *_ = frame_system()
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]
    return np.abs(lam) / (2 * np.pi), -lam.real / np.abs(lam)


@pytest.mark.parametrize("leak", [False, True])
def test_frame_given_order_lists_the_six_modes_and_no_band_edge_pole(frame_welch, leak):
    """The frame (2 shakers x 4 accelerometers, 0.25 Hz bins, Hann): n_modes=6 lists the six modes
    (the weak 14.7 Hz torsion mode included, no pole fitting the sampling hold near 58 Hz)."""
    f_true, z_true = _frame_truth()
    mm = _fit(frame_welch, band=(1.0, 60.0), n_modes=6, correct_leakage=leak)
    f = np.array([m.f_hz for m in mm.modes])
    assert f.size == 6
    np.testing.assert_allclose(f, f_true, rtol=0.01)
    if leak:  # through the estimator, the damping of the leaky low modes is the true one
        np.testing.assert_allclose([m.zeta for m in mm.modes], z_true, rtol=0.15)
    _assert_one_model(mm)


@pytest.mark.slow
def test_frame_automatic_order_lists_the_six_modes(frame_welch):
    """Automatic order through the estimator (correct_leakage=True): the six modes within 0.5 % in
    frequency and 15 % in damping; every other pole a filler."""
    f_true, z_true = _frame_truth()
    mm = _fit(frame_welch, band=(1.0, 60.0), correct_leakage=True)
    f = np.array([m.f_hz for m in mm.modes])
    assert f.size == 6, f
    np.testing.assert_allclose(f, f_true, rtol=0.005)
    np.testing.assert_allclose([m.zeta for m in mm.modes], z_true, rtol=0.15)
    _assert_one_model(mm)


@pytest.mark.slow
def test_frame_automatic_order_on_a_scipy_h1_lists_the_six_modes():
    """The user's own H1 (scipy.signal.csd, no estimator settings): the automatic order keeps the
    poles it needs near the band edge (the sampling hold) and on the leaky 3.9 Hz peak, but lists
    only the six modes, each within 0.5 % of the true frequency or half the 0.25 Hz bin, whichever
    is wider. Without the estimator's description the fit sees the Hann window's leakage as the
    response: the 3.88 Hz mode decays in 2.6 s, about its 4 s segment, so its peak in the H1 is the
    window's main lobe (four bins wide) more than the mode (half-power width half a bin), and the
    fit places it to a fraction of a bin, not to 0.5 % (19 mHz): 3.845 Hz in one process with one
    BLAS thread, 3.818 Hz under xdist (issue 36: where rounding still moves this fit). Where the
    bins are fine enough the 0.5 % holds (14.7 Hz and above)."""
    from test_measurement_model_consistency import frame_h1

    f_true, _ = _frame_truth()
    data = frame_h1()
    mm = _fit(data, band=(1.0, 60.0))
    f = np.array([m.f_hz for m in mm.modes])
    assert f.size == 6, f
    tol = np.maximum(0.005 * f_true, 0.5 * np.diff(data.f_hz[:2])[0])
    assert np.all(np.abs(f - f_true) <= tol), (f, f_true, tol)
    assert mm.fillers and all(not mm.evidence.physical[k] for k in range(len(mm.fit.poles))
                              if abs(mm.fit.f_hz[k] - 58.0) < 6.0)
    _assert_one_model(mm)


def test_leakage_correction_no_longer_underdamps_the_frame_low_modes(frame_welch):
    """Through the estimator (variable projection on the raw H1) the 3.9 and 4.6 Hz modes keep
    their 1.6-1.7 % damping; the former fixed point left one at 0.7 % and lost the 14.7 Hz mode."""
    f_true, z_true = _frame_truth()
    mm = _fit(frame_welch, band=(1.0, 60.0), n_modes=6, correct_leakage=True)
    z = np.array([m.zeta for m in mm.modes])
    assert np.all(z[:2] > 0.75 * z_true[:2]) and np.all(z[:2] < 1.25 * z_true[:2])


def test_phase_collinearity_of_real_and_scattered_shapes():
    """MPC (Pappa et al. 1993): 1 for entries on one line through the origin, ~0 for a circle."""
    real = np.outer([1.0, -2.0, 0.5], [0.3, 1.0]) * np.exp(0.7j)
    assert modal_phase_collinearity(real) == pytest.approx(1.0, abs=1e-12)
    circle = np.exp(2j * np.pi * np.arange(8) / 8)
    assert modal_phase_collinearity(circle) == pytest.approx(0.0, abs=1e-12)


def test_a_pole_fitting_noise_is_not_significant():
    """A pole added where the data hold only noise (a flat response with 1 % noise) is judged not
    significant, while the true mode is."""
    f = np.linspace(10.0, 100.0, 500)
    p = -0.02 * 2 * np.pi * 40 + 2j * np.pi * 40 * np.sqrt(1 - 0.02**2)
    s = 2j * np.pi * f
    g = (1.0 / (s - p) + 1.0 / (s - np.conj(p)))[:, None, None] * 50.0 + 1.0
    rng = np.random.default_rng(0)
    g = g * (1 + 0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(f, g)
    q = -0.01 * 2 * np.pi * 80 + 2j * np.pi * 80
    from robustctl.identify.poles import fit_residues
    from robustctl.identify.rational_fit import RationalFit

    poles = np.array([p, q])
    res, d = fit_residues(s, g, np.ones(g.shape) / np.abs(g), poles)
    fit = RationalFit(poles, res, d, np.ones(2, dtype=int), ["u0"], ["y0"], (10.0, 100.0), "vf", 4, True,
                      data)
    ev = pole_evidence(fit)
    assert ev.physical.tolist() == [True, False]
    assert ev.significance[0] > 10 and ev.significance[1] < 1
