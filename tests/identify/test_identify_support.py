"""Shared truth systems and simulated measurements for the identify tests (and their own checks).

The synthetic truss mirrors the Caltech structure (Balas & Doyle, Table I): six modes in
0.5-5.5 Hz with two near-coincident bending pairs (1.17/1.19 and 2.66/2.75 Hz, perpendicular
shapes), two torsion modes (2.26, 4.43 Hz), 0.9-1.8 % damping; three actuators on the
diagonals (0, 120, 240 deg + 30), three accelerometers along x, y and 45 deg.
"""

from __future__ import annotations

from functools import lru_cache

import control
import numpy as np

import robustctl as rc

F_MODES = np.array([1.17, 1.19, 2.26, 2.66, 2.75, 4.43])
ZETA = np.array([0.018, 0.018, 0.010, 0.016, 0.018, 0.009])
BAND = (0.5, 5.5)


def modal_shapes() -> tuple[np.ndarray, np.ndarray]:
    """Sensor shapes c (3, 6) and actuator shapes b (6, 3) of the truss-like structure."""
    ang_s, ang_a = np.radians([0, 90, 45]), np.radians([30, 150, 270])
    dirs = [0.0, np.pi / 2, None, 0.0, np.pi / 2, None]
    amp = [1.0, 1.0, 0.6, 0.5, 0.5, 0.4]
    c, b = np.zeros((3, 6)), np.zeros((6, 3))
    for k, (d, a) in enumerate(zip(dirs, amp)):
        if d is None:  # torsion: every actuator, every sensor
            c[:, k], b[k] = a * np.array([0.8, 0.6, -0.7]), a * np.ones(3)
        else:
            c[:, k], b[k] = a * np.cos(ang_s - d), a * np.cos(ang_a - d)
    return c, b


def truss_system(f_modes=F_MODES, zeta=ZETA) -> control.StateSpace:
    """Force-to-acceleration modal model (Caltech eq. 5 per mode), 3 inputs x 3 outputs."""
    c, b = modal_shapes()
    n = len(f_modes)
    a_m, b_m, c_m = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 3)), np.zeros((3, 2 * n))
    for k in range(n):
        w = 2 * np.pi * f_modes[k]
        a_m[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[0, 1], [-w * w, -2 * zeta[k] * w]]
        b_m[2 * k + 1] = b[k]
        c_m[:, 2 * k] = -w * w * c[:, k]
        c_m[:, 2 * k + 1] = -2 * zeta[k] * w * c[:, k]
    return control.ss(a_m, b_m, c_m, c @ b, inputs=["a1", "a2", "a3"], outputs=["s1", "s2", "s3"])


def random_modal_system(
    n_modes: int, n_out: int, n_in: int, f_lo=1.0, f_hi=50.0, seed=0
) -> control.StateSpace:
    """Lightly damped (0.5-2 %) random modal system, displacement-like (strictly proper + D)."""
    rng = np.random.default_rng(seed)
    f = np.sort(rng.uniform(f_lo, f_hi, n_modes))
    z = rng.uniform(0.005, 0.02, n_modes)
    a = np.zeros((2 * n_modes, 2 * n_modes))
    b = np.zeros((2 * n_modes, n_in))
    c = np.zeros((n_out, 2 * n_modes))
    for k in range(n_modes):
        w = 2 * np.pi * f[k]
        a[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[0, 1], [-w * w, -2 * z[k] * w]]
        b[2 * k + 1] = rng.normal(size=n_in) * w
        c[:, 2 * k] = rng.normal(size=n_out) * w
    return control.ss(a, b, c, 0.1 * rng.normal(size=(n_out, n_in)))


def exact_data(sys: control.StateSpace, f_hz: np.ndarray) -> rc.FrequencyData:
    """Noise-free response of ``sys`` at ``f_hz``."""
    return rc.freqresp(sys, f_hz)


@lru_cache(maxsize=4)
def caltech_measurement(noise_rms: float = 0.05, seed: int = 0) -> rc.FrequencyData:
    """The Caltech experiment on the truss: one SIMO white-noise run per actuator, 200 Hz,
    81,920 samples, 4096-point Hamming windows with 2048 overlap, sensor noise."""
    sys = truss_system()
    runs = []
    for k in range(3):
        u, y = rc.simulate_experiment(
            sys, fs=200.0, n_samples=81920, noise_rms=noise_rms, seed=seed + k, inputs=[k]
        )
        runs.append(
            rc.estimate_frf(
                u,
                y,
                fs=200.0,
                nperseg=4096,
                noverlap=2048,
                window="hamming",
                inputs=[sys.input_labels[k]],
                outputs=sys.output_labels,
            )
        )
    return rc.combine_experiments(runs)


def test_truss_system_has_the_caltech_modes():
    sys = truss_system()
    p = np.linalg.eigvals(sys.A)
    p = p[p.imag > 0]
    f = np.sort(np.abs(p) / (2 * np.pi))
    np.testing.assert_allclose(f, F_MODES, rtol=1e-12)


def test_caltech_measurement_uses_the_caltech_settings():
    data = caltech_measurement()
    assert data.shape == (2048, 3, 3)
    assert data.f_hz[1] - data.f_hz[0] == 200.0 / 4096
    assert all(m["n_averages"] == 39 for m in data.meta["experiments"])
