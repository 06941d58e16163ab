"""Synthetic modal tests at the size of real ones: many channels, many modes, close pairs, noise.

:func:`modal_test_case` is a shaker test in the frequency domain: a force-to-acceleration modal
model (Caltech eq. 5 per mode, rank-1 residue ``c_k b_k^T``) evaluated on a regular grid, with
the random error of an H1 estimate of given coherence. :func:`impact_test_case` is a hammer test
in the time domain: repeated half-sine hits and the sampled response of the same kind of model
(exact sum of modal impulse responses), for :func:`robustctl.estimate_frf_impact`.
The truth (:class:`ModalTruth`) comes back with the data for checking.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from ..frd import FrequencyData

__all__ = ["ModalTruth", "modal_test_case", "impact_test_case"]


@dataclass(frozen=True)
class ModalTruth:
    """The modes behind a synthetic test.

    Attributes
    ----------
    f_hz : ndarray, shape (n_modes,)
        Natural frequencies, Hz, ascending.
    zeta : ndarray, shape (n_modes,)
        Damping ratios.
    output_shapes : ndarray, shape (n_out, n_modes)
        Sensor mode shapes ``c_k``.
    input_shapes : ndarray, shape (n_modes, n_in)
        Actuator mode shapes ``b_k``.
    """

    f_hz: np.ndarray
    zeta: np.ndarray
    output_shapes: np.ndarray
    input_shapes: np.ndarray

    def response(self, f_hz: np.ndarray) -> np.ndarray:
        """Force-to-acceleration response ``sum_k c_k b_k^T (-w^2)/(w_k^2 - w^2 + 2 j zeta_k w_k w)``,
        shape (n_freq, n_out, n_in)."""
        w = 2 * np.pi * np.asarray(f_hz, dtype=float)[:, None]
        wk = 2 * np.pi * self.f_hz[None, :]
        h = -(w**2) / (wk**2 - w**2 + 2j * self.zeta[None, :] * wk * w)  # (K, n_modes)
        return np.einsum("km,om,mi->koi", h, self.output_shapes, self.input_shapes)

    def impulse(self, t: np.ndarray) -> np.ndarray:
        """Impulse response of the dynamic part ``sum_k c_k b_k^T h_k(t)`` without the
        feedthrough ``sum_k c_k b_k^T`` (the acceleration's instantaneous part), (n_t, n_out, n_in);
        ``h_k(t) = -w_k^2 exp(-zeta w_k t) sin(w_d t + phi)/...``, from the partial fraction of
        ``-w_k^2 (2 zeta w_k s + w_k^2) / (s^2 + 2 zeta w_k s + w_k^2)``."""
        t = np.asarray(t, dtype=float)[:, None]
        wk = 2 * np.pi * self.f_hz[None, :]
        p = -self.zeta[None, :] * wk + 1j * wk * np.sqrt(1 - self.zeta[None, :] ** 2)
        # s^2/(s^2+2zws+w^2) = 1 + r/(s-p) + conj(r)/(s-conj p) with r = p^2 / (p - conj p)
        r = p**2 / (p - np.conj(p))
        h = 2 * np.real(r * np.exp(p * t))
        return np.einsum("km,om,mi->koi", h, self.output_shapes, self.input_shapes)


def _mode_frequencies(rng, n_modes: int, f_lo: float, f_hi: float, n_pairs: int) -> np.ndarray:
    """``n_modes - n_pairs`` frequencies spread (log-jittered) over the band, 1-2 % inside its
    edges, ``n_pairs`` of them (at spread positions) doubled into close pairs 0.3-0.6 % apart."""
    n_single = n_modes - n_pairs
    f_lo, f_hi = 1.01 * f_lo, f_hi / 1.02  # keep the modes (and pair partners) off the band edges
    base = np.geomspace(f_lo, f_hi, n_single)
    jitter = np.exp(rng.uniform(-0.25, 0.25, n_single) * np.log(f_hi / f_lo) / n_single)
    f = np.sort(np.clip(base * jitter, f_lo, f_hi))
    at = np.linspace(1, n_single - 2, n_pairs).round().astype(int) if n_pairs else np.array([], int)
    partner = f[at] * (1 + rng.uniform(0.003, 0.006, at.size))
    return np.sort(np.concatenate([f, partner]))


def _truth(n_in, n_out, n_modes, f_range, zeta_range, n_pairs, rng) -> ModalTruth:
    if n_pairs * 2 > n_modes:
        raise DataError(f"n_pairs={n_pairs} close pairs need at least {2 * n_pairs} modes; got {n_modes}.")
    f_lo, f_hi = (float(v) for v in f_range)
    f = _mode_frequencies(rng, n_modes, f_lo, f_hi, n_pairs)
    zeta = np.exp(rng.uniform(np.log(zeta_range[0]), np.log(zeta_range[1]), n_modes))
    c = rng.normal(size=(n_out, n_modes))
    b = rng.normal(size=(n_modes, n_in))
    # unit-norm shapes, modal mass scaled so that every mode peaks within a factor ~10 of the others
    c /= np.linalg.norm(c, axis=0, keepdims=True) / np.sqrt(n_out)
    b /= np.linalg.norm(b, axis=1, keepdims=True) / np.sqrt(n_in)
    scale = np.sqrt(zeta * rng.uniform(1.0, 3.0, n_modes))  # peak ~ 1/(2 zeta): keep peaks comparable
    return ModalTruth(f, zeta, c * scale[None, :], b * scale[:, None])


def _coherence(g: np.ndarray, c_lo: float, c_hi: float) -> np.ndarray:
    """Coherence growing with the response level of each channel from ``c_lo`` (its lowest
    level) to ``c_hi`` (its peak), as with sensor noise of constant spectrum."""
    level = np.log(np.abs(g))
    lo, hi = level.min(axis=0, keepdims=True), level.max(axis=0, keepdims=True)
    return c_lo + (c_hi - c_lo) * (level - lo) / np.maximum(hi - lo, 1e-12)


def modal_test_case(
    n_in: int = 2,
    n_out: int = 28,
    n_modes: int = 25,
    f_range: tuple[float, float] = (50.0, 450.0),
    n_freq: int = 800,
    zeta_range: tuple[float, float] = (0.002, 0.02),
    n_pairs: int = 3,
    coherence: tuple[float, float] = (0.95, 0.99),
    n_averages: int = 30,
    seed: int = 0,
) -> tuple[FrequencyData, ModalTruth]:
    """A shaker test's H1 estimate of a random lightly damped structure (frequency domain).

    The modes lie inside ``f_range`` (Hz) with ``n_pairs`` close pairs 0.3-0.6 % apart (less
    than the half-power bandwidth ``2 zeta f`` of the more damped ones); the response is
    force to acceleration. The measured FRF is the true one times ``1 + e`` with ``e`` complex
    Gaussian of variance ``(1 - c) / (n_averages c)``, the relative random error of an H1
    estimate of coherence ``c`` averaged ``n_averages`` times (Bendat & Piersol, *Random Data*,
    eq. 9.90); ``c`` rises from ``coherence[0]`` at a channel's lowest level to
    ``coherence[1]`` at its peaks.

    Parameters
    ----------
    n_in, n_out : int
        Shakers and accelerometers.
    n_modes : int
        Modes inside ``f_range``.
    f_range : (float, float)
        Band of the modes and of the ``n_freq`` equally spaced frequency points, Hz.
    n_freq : int
        Frequency points.
    zeta_range : (float, float)
        Damping ratios, drawn log-uniformly.
    n_pairs : int
        Close pairs among the modes.
    coherence : (float, float)
        Range of the coherence.
    n_averages : int
        Averages of the simulated estimate (sets the random error for a given coherence).
    seed : int
        Seed of ``numpy.random.default_rng``.

    Returns
    -------
    data : FrequencyData
        ``(n_freq, n_out, n_in)`` with coherence; inputs ``shaker1..``, outputs ``acc1..``.
    truth : ModalTruth
    """
    rng = np.random.default_rng(seed)
    truth = _truth(n_in, n_out, n_modes, f_range, zeta_range, n_pairs, rng)
    f = np.linspace(f_range[0], f_range[1], n_freq)
    g = truth.response(f)
    coh = _coherence(g, *coherence)
    sd = np.sqrt((1 - coh) / (n_averages * coh) / 2)
    noise = sd * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape))
    meta = {"source": "robustctl.examples.modal_test_case", "seed": seed, "n_averages": n_averages}
    data = FrequencyData(
        f,
        g * (1 + noise),
        inputs=[f"shaker{k + 1}" for k in range(n_in)],
        outputs=[f"acc{k + 1}" for k in range(n_out)],
        coherence=coh,
        units={"input": "N", "output": "m/s^2"},
        meta=meta,
    )
    return data, truth


def impact_test_case(
    n_out: int = 1,
    n_modes: int = 8,
    f_range: tuple[float, float] = (200.0, 2000.0),
    zeta_range: tuple[float, float] = (0.001, 0.01),
    fs: float = 8192.0,
    duration_s: float = 1.0,
    n_hits: int = 5,
    pulse_s: float = 2e-4,
    noise_rms: float = 1e-3,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, ModalTruth]:
    """Repeated hammer hits on a random lightly damped structure, sampled (time domain).

    Each hit is a half-sine force pulse of ``pulse_s`` seconds and random amplitude (0.7-1.3)
    at 5 % of its record; the response is the exact sum of the modal responses (the
    convolution of the sampled pulse with the sampled impulse response of :class:`ModalTruth`,
    plus the feedthrough) and white sensor noise of ``noise_rms`` times the response's rms.
    Records are ``duration_s`` long and start at rest, so lightly damped modes are truncated
    (leakage) unless an exponential window is used.

    Returns
    -------
    force : ndarray, shape (n_hits, n_samples)
        Force records, N.
    response : ndarray, shape (n_hits, n_samples, n_out)
        Acceleration records.
    truth : ModalTruth
        Modes (one input).
    """
    rng = np.random.default_rng(seed)
    truth = _truth(1, n_out, n_modes, f_range, zeta_range, 0, rng)
    n = int(round(fs * duration_s))
    t = np.arange(n) / fs
    h = truth.impulse(t)[:, :, 0] / fs  # sampled impulse response times dt: a discrete convolution kernel
    h[0] *= 0.5  # trapezoidal rule at the start of the causal kernel
    feed = truth.output_shapes @ truth.input_shapes[:, 0]
    m = max(2, int(round(pulse_s * fs)))
    pulse = np.sin(np.pi * (np.arange(m) + 0.5) / m)
    start = int(0.05 * n)
    force = np.zeros((n_hits, n))
    resp = np.zeros((n_hits, n, n_out))
    for k in range(n_hits):
        force[k, start : start + m] = rng.uniform(0.7, 1.3) * pulse
        spec = np.fft.rfft(force[k], 2 * n)[:, None] * np.fft.rfft(h, 2 * n, axis=0)
        resp[k] = np.fft.irfft(spec, 2 * n, axis=0)[:n] + force[k][:, None] * feed[None, :]
    resp += noise_rms * np.sqrt(np.mean(resp**2)) * rng.standard_normal(resp.shape)
    return force, resp, truth
