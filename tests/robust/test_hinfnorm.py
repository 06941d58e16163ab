"""rc.hinfnorm against closed forms, dense sweeps and SLICOT AB13DD (python-control's norm)."""

from __future__ import annotations

import warnings

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import ModelError, RobustctlError


def modal_system(
    n_modes: int,
    seed: int,
    zeta=None,
    n_in: int = 2,
    n_out: int = 2,
    with_d: bool = False,
    dense: bool = True,
) -> control.StateSpace:
    """Lightly damped modes 1-100 rad/s, random B, C (and D), optionally hidden by a random rotation."""
    rng = np.random.default_rng(seed)
    w = np.geomspace(1.0, 100.0, n_modes)
    z = rng.uniform(1e-3, 0.05, n_modes) if zeta is None else np.full(n_modes, zeta)
    A = np.zeros((2 * n_modes, 2 * n_modes))
    for k in range(n_modes):
        wd = w[k] * np.sqrt(1 - z[k] ** 2)
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[-z[k] * w[k], wd], [-wd, -z[k] * w[k]]]
    B = rng.standard_normal((2 * n_modes, n_in))
    C = rng.standard_normal((n_out, 2 * n_modes))
    D = rng.standard_normal((n_out, n_in)) if with_d else np.zeros((n_out, n_in))
    if dense:
        Q, _ = np.linalg.qr(rng.standard_normal((2 * n_modes, 2 * n_modes)))
        A, B, C = Q @ A @ Q.T, Q @ B, C @ Q.T
    return control.ss(A, B, C, D)


def sigma_direct(sys: control.StateSpace, w: np.ndarray) -> np.ndarray:
    """Largest singular value by a dense complex solve at each frequency (independent of rc's kernel)."""
    A, B, C, D = (np.asarray(m) for m in (sys.A, sys.B, sys.C, sys.D))
    n = A.shape[0]
    out = []
    for wk in w:
        G = C @ np.linalg.solve(1j * wk * np.eye(n) - A, B) + D
        out.append(np.linalg.svd(G, compute_uv=False)[0])
    return np.array(out)


def control_norm(sys) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(control.norm(sys, "inf"))


@pytest.mark.parametrize("zeta", [0.5, 0.1, 1e-2, 1e-4, 1e-6])
def test_second_order_peak_closed_form(zeta):
    g, f_peak = rc.hinfnorm(control.tf([1.0], [1.0, 2 * zeta, 1.0]))
    assert g == pytest.approx(1 / (2 * zeta * np.sqrt(1 - zeta**2)), rel=1e-9)
    assert 2 * np.pi * f_peak == pytest.approx(np.sqrt(1 - 2 * zeta**2), rel=1e-6)


def test_scaled_mode_frequency_in_hz():
    wn, zeta = 2 * np.pi * 12.5, 0.02  # 12.5 Hz mode, static gain 3
    g, f_peak = rc.hinfnorm(control.tf([3 * wn**2], [1.0, 2 * zeta * wn, wn**2]))
    assert g == pytest.approx(3 / (2 * zeta * np.sqrt(1 - zeta**2)), rel=1e-9)
    assert f_peak == pytest.approx(12.5 * np.sqrt(1 - 2 * zeta**2), rel=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_dense_sweep(seed):
    sys = modal_system(6, seed, with_d=seed == 2)
    g, f_peak = rc.hinfnorm(sys)
    # the value is attained: sigma_max at the reported peak (dense solve) equals the norm ...
    assert sigma_direct(sys, [2 * np.pi * f_peak])[0] == pytest.approx(g, rel=1e-9)
    # ... and no frequency of a dense sweep (plus a fine sweep around the peak) exceeds it
    w = np.concatenate([np.linspace(0, 200, 4001), 2 * np.pi * f_peak * (1 + np.linspace(-1e-3, 1e-3, 401))])
    assert sigma_direct(sys, w).max() <= g * (1 + 1e-9)


@pytest.mark.parametrize(
    "n_modes, zeta, with_d",
    [
        (2, None, False),
        (5, None, True),
        (10, 1e-4, False),
        (25, 1e-4, True),
        (30, None, False),
        (60, 1e-4, True),
    ],
)
def test_matches_slicot_ab13dd_modal(n_modes, zeta, with_d):
    sys = modal_system(n_modes, 10 + n_modes, zeta, with_d=with_d)
    g, _ = rc.hinfnorm(sys)
    assert g == pytest.approx(control_norm(sys), rel=1e-6)


@pytest.mark.parametrize("n, seed", [(4, 0), (20, 1), (60, 2), (3, 3)])
def test_matches_slicot_ab13dd_random(n, seed):
    np.random.seed(seed)
    sys = control.rss(n, 3, 2, strictly_proper=False)
    g, _ = rc.hinfnorm(sys)
    assert g == pytest.approx(control_norm(sys), rel=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("zeta", [None, 1e-4])
def test_matches_slicot_ab13dd_200_states(zeta):
    sys = modal_system(100, 7, zeta, n_in=3, n_out=3)
    g, _ = rc.hinfnorm(sys)
    assert g == pytest.approx(control_norm(sys), rel=1e-6)


def test_unstable_is_inf():
    g, f = rc.hinfnorm(control.tf([1.0], [1.0, -0.2, 4.0]))  # unstable pair at about 2 rad/s
    assert g == np.inf
    assert 2 * np.pi * f == pytest.approx(np.sqrt(4 - 0.01), rel=1e-9)
    assert rc.hinfnorm(control.tf([1.0], [1.0, 0.0]))[0] == np.inf  # integrator: pole on the axis


def test_static_gain_and_peak_at_infinity():
    g, f = rc.hinfnorm(control.ss([], [], [], [[3.0, 4.0]]))
    assert g == pytest.approx(5.0) and f == np.inf
    # high-pass 10 (s + 1) / (s + 10): norm 10 at infinite frequency
    g, f = rc.hinfnorm(control.tf([10.0, 10.0], [1.0, 10.0]))
    assert g == pytest.approx(10.0, rel=1e-9) and f == np.inf


def test_discrete_time_matches_unit_circle_sweep():
    dt = 0.01
    sysd = control.c2d(control.tf([1.0, 0.5], [1.0, 0.1, 25.0]), dt)
    g, f_peak = rc.hinfnorm(sysd)
    f = np.concatenate([np.linspace(0, 0.5 / dt, 20001), f_peak * (1 + np.linspace(-1e-3, 1e-3, 2001))])
    resp = np.abs(np.squeeze(sysd(np.exp(2j * np.pi * f * dt))))
    assert resp.max() <= g * (1 + 1e-9)
    assert resp.max() == pytest.approx(g, rel=1e-9)
    assert abs(f_peak - 5 / (2 * np.pi)) < 0.01  # the 5 rad/s mode
    assert g == pytest.approx(control_norm(sysd), rel=1e-6)


def test_zero_system():
    assert rc.hinfnorm(control.ss([[-1.0]], [[0.0]], [[1.0]], [[0.0]]))[0] == 0.0


@pytest.mark.parametrize("tol", [0, -1e-3, 0.5, np.nan, "1e-6", True])
def test_bad_tolerance(tol):
    with pytest.raises(RobustctlError, match="tol"):
        rc.hinfnorm(control.tf([1.0], [1.0, 1.0]), tol=tol)


def test_bad_system():
    with pytest.raises(ModelError, match="non-proper"):
        rc.hinfnorm(control.tf([1.0, 0.0, 0.0], [1.0, 1.0]))
    with pytest.raises(ModelError):
        rc.hinfnorm(rc.FrequencyData(np.array([1.0]), np.ones((1, 1, 1), complex)))


# ---------------------------------------------------------------------------- the modal peak search
@pytest.mark.parametrize("zeta", [0.3, 1e-2, 1e-5])
def test_modal_peak_search_reaches_the_closed_form_peak(zeta):
    """The parabolic steps on 1 / sigma^2 find the peak of one mode to ~1e-12, a lightly damped
    one in three calls of sigma (the 1 / sigma^2 of a lone resonance is exactly a parabola)."""
    from robustctl.robust.hinf.norm import PEAK_ROUNDS, _modal_peaks, _SigmaMax

    sys = control.ss(control.tf([1.0], [1.0, 2 * zeta, 1.0]))
    sigma = _SigmaMax(*(np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D)))
    calls = []
    counted = type("Counted", (), {"poles": sigma.poles, "peak_estimates": sigma.peak_estimates,
                                   "__call__": lambda self, w: calls.append(w.size) or sigma(w)})()
    s_peak, w_peak = _modal_peaks(counted)
    assert s_peak == pytest.approx(1 / (2 * zeta * np.sqrt(1 - zeta**2)), rel=1e-11)
    assert w_peak == pytest.approx(np.sqrt(1 - 2 * zeta**2), rel=1e-5)
    assert len(calls) <= (3 if zeta <= 0.01 else PEAK_ROUNDS)


def test_overlapping_modes_match_a_dense_sweep():
    """Three overlapping modes (1, 1.02, 1.05 rad/s) whose sum peaks between them, two heavily
    damped ones and a light mode whose lone peak estimate is large but whose peak is small."""
    rng = np.random.default_rng(5)
    w = np.array([1.0, 1.02, 1.05, 3.0, 3.1, 10.0])
    z = np.array([0.02, 0.03, 0.02, 0.2, 0.25, 0.01])
    A = np.zeros((12, 12))
    for k in range(6):
        wd = w[k] * np.sqrt(1 - z[k] ** 2)
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[-z[k] * w[k], wd], [-wd, -z[k] * w[k]]]
    B, C = rng.standard_normal((12, 2)), rng.standard_normal((2, 12))
    C[:, 10:] *= 0.05  # the light 10 rad/s mode alone: a large estimate, a small peak
    Q, _ = np.linalg.qr(rng.standard_normal((12, 12)))
    sys = control.ss(Q @ A @ Q.T, Q @ B, C @ Q.T, np.zeros((2, 2)))
    g, f_peak = rc.hinfnorm(sys)
    w_pk = 2 * np.pi * f_peak
    grid = np.concatenate([np.linspace(0, 15, 15001), w_pk * (1 + np.linspace(-1e-3, 1e-3, 401))])
    s = sigma_direct(sys, grid)
    assert s.max() <= g * (1 + 1e-9)
    assert sigma_direct(sys, [2 * np.pi * f_peak])[0] == pytest.approx(g, rel=1e-9)
    assert g == pytest.approx(control_norm(sys), rel=1e-6)


@pytest.mark.parametrize("start", [0.3, 0.999])
def test_level_set_iteration_from_a_poor_lower_bound(start):
    """The Hamiltonian iteration alone (started well below the norm, as when the modal search
    misses the peak) climbs to the dense-sweep peak and certifies it."""
    from robustctl.robust.hinf.norm import _Hamiltonian, _level_set_iteration, _SigmaMax

    sys = modal_system(8, 3, zeta=None, n_in=3, n_out=2)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    g_ref, f_ref = rc.hinfnorm(sys)
    sigma = _SigmaMax(A, B, C, D)
    g, w, steps = _level_set_iteration(_Hamiltonian(A, B, C, D), sigma, start * g_ref, 0.0, 1e-6)
    assert steps >= 2
    assert g == pytest.approx(g_ref, rel=2e-6) and g <= g_ref * (1 + 1e-12)
    assert sigma_direct(sys, [w])[0] == pytest.approx(g, rel=1e-9)  # attained where reported
    assert sigma_direct(sys, np.linspace(0, 150, 30001)).max() <= g * (1 + 2e-6)


def test_discrete_poles_on_unit_circle_to_round_off_give_infinite_norm():
    s = control.tf("s")
    sysd = control.ss(control.sample_system(1 / (s**2 + 1), 0.1))
    assert np.max(np.abs(np.linalg.eigvals(sysd.A))) < 1.0  # |z| = 1 - 3e-16: inside by round-off only
    g, f = rc.hinfnorm(sysd)
    assert g == np.inf
    assert f == pytest.approx(1 / (2 * np.pi), rel=1e-9)  # the undamped mode at 1 rad/s
    # a lightly damped sampled mode (1 - |z| = 1e-7) keeps its finite norm 1 / (2 zeta) at the mode
    zeta = 1e-6
    g2, _ = rc.hinfnorm(control.c2d(control.tf([1.0], [1.0, 2 * zeta, 1.0]), 0.1))
    assert np.isfinite(g2) and g2 > 1e5
