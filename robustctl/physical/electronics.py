"""Electronics of the I/O model (MACE Fig. 1): gains, filters, delays, servo loops.

MACE converts the physical modal model (N m in, rad/s out) into the model the control
computer sees (volts): electronic gains on each actuator and sensor, rate-gyro dynamics,
anti-aliasing Bessel and notch filters on the sensors, smoothing filters on the actuators,
analog and digital servo loops, and the 3.6 ms sampling delay as a Pade approximant on
the outputs. Every piece here exists twice:

* as a pure function on a named continuous-time ``control.StateSpace``
  (:func:`filter_outputs`, :func:`delay_outputs`, :func:`close_servo_loop` ...), and
* as a :class:`~robustctl.physical.model.Stage` factory (:func:`filter_stage`,
  :func:`delay_stage`, :func:`servo_stage` ...) whose numbers may be parameter names read
  from ``theta`` at build time, so examples and effects reuse the same code.

Realisations are built from first- and second-order sections in a frequency-scaled form
(every matrix entry is of the order of the section's natural frequency in rad/s), never
from expanded polynomials, so a 6th-order Bessel filter at 1 kHz stays well conditioned.

Neutral values make a piece vanish exactly (an identity with no states): delay 0, cutoff
``inf``, notch depth 1, misalignment angle 0, gain error 0.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import control
import numpy as np
import scipy.signal as signal

from ..checks import is_real_number, is_whole_number
from ..errors import ModelError
from ..lti import series_matrices
from ..signals import (
    abcd_matrices,
    named_statespace,
    rename_signals,
    scale_inputs,
    scale_outputs,
    signal_index,
    signal_names,
)
from .model import Stage

__all__ = [
    # filters (SISO StateSpace builders)
    "identity",
    "bessel_lowpass",
    "butterworth_lowpass",
    "lowpass1",
    "lowpass2",
    "notch",
    "rate_gyro",
    "pade_delay",
    "pade_coefficients",
    "zero_order_hold",
    "pi_controller",
    "servo_controller",
    "pd_controller",
    "series",
    # functions on named systems
    "scale_outputs",
    "scale_inputs",
    "rename_signals",
    "filter_outputs",
    "filter_inputs",
    "delay_outputs",
    "delay_inputs",
    "close_servo_loop",
    "misalign_outputs",
    "misalign_inputs",
    "sensor_gain_error",
    # stage factories
    "gain_stage",
    "filter_stage",
    "bessel_stage",
    "butterworth_stage",
    "lowpass1_stage",
    "lowpass2_stage",
    "notch_stage",
    "rate_gyro_stage",
    "delay_stage",
    "zero_order_hold_stage",
    "anti_alias_stage",
    "servo_stage",
    "misalignment_stage",
    "sensor_gain_error_stage",
]

#: A number in a stage factory: a constant, the name of a model parameter, or a function
#: of the parameter values.
Value = float | str | Callable[[Mapping[str, float]], float]

_MAX_FILTER_ORDER = 20
_MAX_PADE_ORDER = 10


# ============================================================================ helpers
def _siso(filt: Any, what: str = "filter"):
    A, B, C, D = abcd_matrices(filt, what)
    if B.shape[1] != 1 or C.shape[0] != 1:
        raise ModelError(
            f"the {what} must be single-input single-output (one copy is put on each named "
            f"channel); got {C.shape[0]} outputs and {B.shape[1]} inputs."
        )
    return A, B, C, D


def _number(value: Any, what: str) -> float:
    """``value`` as a float when it is a real number (:func:`robustctl.checks.is_real_number`:
    no strings, no booleans), else a ModelError."""
    if not is_real_number(value):
        raise ModelError(f"{what} must be a number; got {value!r}.")
    return float(value)


def _positive(value: float, what: str, unit: str, allow_inf: bool = False) -> float:
    if not is_real_number(value):
        hint = " (inf switches the filter off)" if allow_inf else ""
        raise ModelError(f"{what} must be a positive number in {unit}{hint}; got {value!r}.")
    value = float(value)
    if math.isnan(value) or value <= 0 or (math.isinf(value) and not allow_inf):
        hint = " (inf switches the filter off)" if allow_inf else ""
        raise ModelError(f"{what} must be a positive number in {unit}{hint}; got {value!r}.")
    return value


def _order(order: int, limit: int, what: str) -> int:
    if not is_whole_number(order) or not 1 <= int(order) <= limit:
        raise ModelError(f"{what} order must be an integer in 1..{limit}; got {order!r}.")
    return int(order)


def _cascade(sections: Sequence[tuple]) -> Any:
    out = _identity_abcd()
    for sec in sections:
        out = series_matrices(out, sec)
    return named_statespace(*out, ["u"], ["y"])


def _identity_abcd():
    return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1))


def _lowpass_section(wn: float, zeta: float):
    """``wn^2 / (s^2 + 2 zeta wn s + wn^2)``: states scaled so every entry is ~wn (rad/s)."""
    A = np.array([[0.0, wn], [-wn, -2.0 * zeta * wn]])
    return A, np.array([[0.0], [wn]]), np.array([[1.0, 0.0]]), np.zeros((1, 1))


def _first_order_section(p: float):
    """``p / (s + p)`` with ``p`` > 0 in rad/s."""
    return np.array([[-p]]), np.array([[p]]), np.ones((1, 1)), np.zeros((1, 1))


def _pole_sections(poles: np.ndarray) -> list[tuple]:
    """Unit-DC-gain all-pole sections for the left-half-plane ``poles`` (rad/s)."""
    sections = []
    for p in poles:
        if abs(p.imag) <= 1e-12 * abs(p):
            sections.append(_first_order_section(-p.real))
        elif p.imag > 0:
            wn = abs(p)
            sections.append(_lowpass_section(wn, -p.real / wn))
    return sections


# ============================================================================ SISO filters
def identity():
    """The unit static gain (no states): what every filter is at its neutral value."""
    return named_statespace(*_identity_abcd(), ["u"], ["y"])


def _analog_lowpass(kind: str, order: int, cutoff_hz: float, norm: str | None):
    order = _order(order, _MAX_FILTER_ORDER, f"{kind} filter")
    fc = _positive(cutoff_hz, f"the {kind} cutoff", "Hz", allow_inf=True)
    if math.isinf(fc):
        return identity()
    if kind == "Bessel" and norm not in ("phase", "delay", "mag"):
        raise ModelError(f"Bessel norm must be 'phase', 'delay' or 'mag'; got {norm!r}.")
    A, B, C, D = _lowpass_abcd(kind, order, fc, norm)
    return named_statespace(A.copy(), B.copy(), C.copy(), D.copy(), ["u"], ["y"])


@functools.lru_cache(maxsize=64)
def _lowpass_abcd(kind: str, order: int, fc: float, norm: str | None) -> tuple:
    """The realisation of :func:`_analog_lowpass` (made once per design: a model build puts the
    same sensor filters on at every evaluation). Callers copy the arrays."""
    wc = 2 * np.pi * fc
    if kind == "Bessel":
        _, p, k = signal.bessel(order, wc, analog=True, output="zpk", norm=norm)
    else:
        _, p, k = signal.butter(order, wc, analog=True, output="zpk")
    sys = _cascade(_pole_sections(np.asarray(p)))
    dc = float(np.real(k / np.prod(-np.asarray(p))))  # 1 for both families; kept for exactness
    return tuple(np.asarray(m, dtype=float) for m in (sys.A, sys.B, dc * np.asarray(sys.C), sys.D))


def bessel_lowpass(order: int, cutoff_hz: float, norm: str = "phase"):
    """Analog Bessel low-pass (anti-aliasing filter of MACE's sensors).

    Parameters
    ----------
    order : int
        Filter order, 1..20.
    cutoff_hz : float
        Cutoff frequency in Hz (``inf``: identity).
    norm : {"phase", "delay", "mag"}
        Normalisation as in ``scipy.signal.bessel``. The default ``"phase"`` (the
        "phase-matched" form, scipy's default and MATLAB's ``besself``) gives the same
        high-frequency magnitude asymptote ``(w_c / w)^order`` as a Butterworth filter
        with this cutoff. ``"mag"``: -3 dB at the cutoff; ``"delay"``: group delay
        ``1 / (2 pi cutoff_hz)`` s at DC.

    Returns
    -------
    control.StateSpace
        SISO, unit DC gain, equal to ``scipy.signal.bessel(order, 2 pi cutoff_hz,
        analog=True, norm=norm)``, realised as scaled second-order sections.
    """
    return _analog_lowpass("Bessel", order, cutoff_hz, norm)


def butterworth_lowpass(order: int, cutoff_hz: float):
    """Analog Butterworth low-pass ``|H(j w)|^2 = 1 / (1 + (w / w_c)^(2 order))``.

    Equal to ``scipy.signal.butter(order, 2 pi cutoff_hz, analog=True)``; ``cutoff_hz``
    in Hz (``inf``: identity); order 1..20.
    """
    return _analog_lowpass("Butterworth", order, cutoff_hz, None)


def lowpass1(cutoff_hz: float):
    """First-order low-pass ``w_c / (s + w_c)``, ``w_c = 2 pi cutoff_hz`` (``inf``: identity)."""
    fc = _positive(cutoff_hz, "the low-pass cutoff", "Hz", allow_inf=True)
    if math.isinf(fc):
        return identity()
    return _cascade([_first_order_section(2 * np.pi * fc)])


def lowpass2(cutoff_hz: float, damping: float = 0.7071067811865476):
    """Second-order low-pass ``w_n^2 / (s^2 + 2 zeta w_n s + w_n^2)``, ``w_n = 2 pi cutoff_hz``.

    ``cutoff_hz`` in Hz (``inf``: identity); ``damping`` is the ratio zeta > 0.
    """
    fc = _positive(cutoff_hz, "the low-pass natural frequency", "Hz", allow_inf=True)
    zeta = _positive(damping, "the low-pass damping ratio", "(dimensionless)")
    if math.isinf(fc):
        return identity()
    return _cascade([_lowpass_section(2 * np.pi * fc, zeta)])


def rate_gyro(natural_hz: float, damping: float):
    """Rate-gyro dynamics: a unit-DC-gain second-order low-pass at ``natural_hz`` (Hz).

    The gyro's internal resonance (MACE notches it in the signal conditioning); ``inf``
    gives an ideal gyro.
    """
    return lowpass2(natural_hz, damping)


def notch(centre_hz: float, depth: float, width_hz: float):
    """Notch ``(s^2 + 2 zeta_z w_0 s + w_0^2) / (s^2 + 2 zeta_p w_0 s + w_0^2)``.

    Parameters
    ----------
    centre_hz : float
        Centre frequency ``w_0 / 2 pi`` in Hz.
    depth : float
        Linear gain at the centre, ``|H(j w_0)| = zeta_z / zeta_p``: 0 is a perfect notch,
        1 no notch (identity), values above 1 a peak.
    width_hz : float
        Width in Hz, ``2 zeta_p f_0``: the -3 dB bandwidth of the perfect notch.
    """
    f0 = _positive(centre_hz, "the notch centre", "Hz")
    width = _positive(width_hz, "the notch width", "Hz")
    depth = _number(depth, "the notch depth")
    if not math.isfinite(depth) or depth < 0:
        raise ModelError(f"the notch depth is a linear gain >= 0 at the centre; got {depth!r}.")
    if depth == 1.0:
        return identity()
    w0 = 2 * np.pi * f0
    zeta_p = width / (2 * f0)
    A, B, _, _ = _lowpass_section(w0, zeta_p)
    C = np.array([[0.0, 2.0 * (depth - 1.0) * zeta_p]])  # H = 1 + 2 (zeta_z - zeta_p) w0 s / den
    return named_statespace(A, B, C, np.ones((1, 1)), ["u"], ["y"])


def pade_coefficients(order: int) -> np.ndarray:
    """Coefficients ``c_k`` (k = 0..order) of the [n/n] Pade denominator ``sum c_k (s tau)^k``.

    ``c_k = (2n - k)! n! / ((2n)! k! (n - k)!)``; the approximant is
    ``e^{-s tau} ~ D(-s tau) / D(s tau)``.
    """
    n = _order(order, _MAX_PADE_ORDER, "Pade")
    f = math.factorial
    return np.array([f(2 * n - k) * f(n) / (f(2 * n) * f(k) * f(n - k)) for k in range(n + 1)])


def pade_delay(delay_s: float, order: int = 2):
    """[n/n] Pade approximant of the delay ``e^{-s tau}`` (all-pass, unit gain at all w).

    Parameters
    ----------
    delay_s : float
        Delay ``tau`` in s (>= 0; 0 gives the identity exactly). MACE measured 3.6 ms.
    order : int
        Pade order n, 1..10. Phase ``-2 sum_i atan(w / p_i)``-type terms, i.e.
        ``-2 arg D(j w tau)``; error against ``-w tau`` grows like ``(w tau)^(2n+1)``.

    Returns
    -------
    control.StateSpace
        Realised as first-order ``(a - s)/(s + a)`` and second-order
        ``1 - 4 zeta w_n s / (s^2 + 2 zeta w_n s + w_n^2)`` all-pass sections.
    """
    tau = _number(delay_s, "a time delay (s)")
    if not math.isfinite(tau) or tau < 0:
        raise ModelError(f"a time delay must be a finite number of seconds >= 0; got {delay_s!r}.")
    coef = pade_coefficients(order)
    if tau == 0:
        return identity()
    roots = np.roots(coef[::-1]) / tau
    sections = []
    for p in roots:
        if abs(p.imag) <= 1e-12 * abs(p):
            a = -p.real
            sections.append((np.array([[-a]]), np.array([[2 * a]]), np.ones((1, 1)), -np.ones((1, 1))))
        elif p.imag > 0:
            wn = abs(p)
            zeta = -p.real / wn
            A, B, _, _ = _lowpass_section(wn, zeta)
            sections.append((A, B, np.array([[0.0, -4.0 * zeta]]), np.ones((1, 1))))
    return _cascade(sections)


def zero_order_hold(fs_hz: float, order: int = 4):
    """Rational model of a DAC's zero-order hold, ``(1 - e^{-sT}) / (sT)``, ``T = 1 / fs_hz``.

    A hold delays by half a sample and droops like ``sinc(f / fs)`` (Franklin, Powell &
    Workman, *Digital Control*, sec. 4.3.4). With the [n/n] Pade approximant
    ``e^{-x} ~ D(-x) / D(x)`` (``x = sT``, :func:`pade_coefficients`) the hold is
    ``2 sum_{k odd} c_k x^(k-1) / D(x)``: unit DC gain, strictly proper for even ``n``.

    Parameters
    ----------
    fs_hz : float
        Sampling (update) rate of the DAC, Hz.
    order : int
        Pade order n, 1..10 (4: phase error below 0.01 deg up to fs / 4).

    Returns
    -------
    control.StateSpace
        SISO, input ``u``, output ``y``.
    """
    fs = _number(fs_hz, "fs_hz (the DAC's sampling rate, Hz)")
    if not math.isfinite(fs) or fs <= 0:
        raise ModelError(f"fs_hz (the DAC's sampling rate, Hz) must be a positive number; got {fs_hz!r}.")
    c = pade_coefficients(order)
    t = 1.0 / fs
    den = [c[k] * t**k for k in range(c.size)][::-1]
    num = [2.0 * c[k] * t ** (k - 1) for k in range(1, c.size, 2)]
    num_poly = np.zeros(c.size - 1)
    for j, k in enumerate(range(1, c.size, 2)):
        num_poly[k - 1] = num[j]
    sys = control.ss(control.tf(num_poly[::-1], den))
    return named_statespace(sys.A, sys.B, sys.C, sys.D, ["u"], ["y"])


def pi_controller(gain: float, integral_hz: float | None = None):
    """``gain * (1 + w_i / s)``, ``w_i = 2 pi integral_hz`` (the PI corner in Hz); P only when None."""
    gain = _number(gain, "the PI gain")
    if integral_hz is None or _number(integral_hz, "the PI corner (Hz)") == 0:
        return named_statespace(*_identity_abcd()[:3], [[gain]], ["u"], ["y"])
    wi = 2 * np.pi * _positive(integral_hz, "the PI corner", "Hz")
    return named_statespace([[0.0]], [[wi]], [[gain]], [[gain]], ["u"], ["y"])


def servo_controller(
    gain: float,
    *,
    integral_hz: float | None = None,
    lowpass_hz: float = math.inf,
    delay_s: float = 0.0,
    pade_order: int = 2,
):
    """A servo compensator of MACE Fig. 1: gain, optional PI, first-order low-pass, delay.

    ``K(s) = gain (1 + w_i / s) w_c / (s + w_c) e^{-s delay}`` (Pade); frequencies in Hz,
    delay in s. A digitally closed loop (gimbal servo) carries the sampling delay.
    """
    return series(pi_controller(gain, integral_hz), lowpass1(lowpass_hz), pade_delay(delay_s, pade_order))


def pd_controller(
    gain: float,
    lead_hz: float,
    *,
    lowpass_hz: float = math.inf,
    delay_s: float = 0.0,
    rolloff_order: int = 2,
    pade_order: int = 2,
):
    """PD servo compensator ``K(s) = gain (1 + s / w_d) R(s) e^{-s delay}`` with roll-off R.

    ``R(s) = w_c / (s + w_c)`` (``rolloff_order=1``) or the Butterworth pair
    ``w_c^2 / (s^2 + sqrt(2) w_c s + w_c^2)`` (``rolloff_order=2``), unit gain at DC.
    MACE Fig. 1's gimbal servo: the encoder angle is differentiated digitally and fed back
    as angle and rate.

    Parameters
    ----------
    gain : float
        Proportional gain (actuator units per sensor unit, e.g. V/rad).
    lead_hz : float
        Derivative corner ``w_d / 2 pi`` in Hz (the rate feedback of MACE's digitally
        differentiated encoder); must be finite and > 0.
    lowpass_hz : float
        Roll-off corner ``w_c / 2 pi`` in Hz (> ``lead_hz``); must be finite (a PD without
        roll-off is improper).
    delay_s : float
        Sampling delay of the digital loop in s (Pade approximant of ``pade_order``).
    rolloff_order : {1, 2}
        Order of the roll-off.

    Returns
    -------
    control.StateSpace
        SISO, input ``u`` (error), output ``y`` (actuator command).
    """
    wd = 2 * math.pi * _number(lead_hz, "the PD lead corner (Hz)")
    wc = 2 * math.pi * _number(lowpass_hz, "the PD roll-off (Hz)")
    if not (math.isfinite(wd) and wd > 0):
        raise ModelError(f"the PD lead corner must be a finite frequency > 0 Hz; got {lead_hz!r}.")
    if not (math.isfinite(wc) and wc > wd):
        raise ModelError(
            f"the PD roll-off ({lowpass_hz!r} Hz) must be finite and above the lead corner ({lead_hz!r} Hz)."
        )
    if rolloff_order not in (1, 2):
        raise ModelError(f"rolloff_order must be 1 or 2; got {rolloff_order!r}.")
    g = _number(gain, "the PD gain")
    if rolloff_order == 1:
        # gain (1 + s/wd) wc/(s + wc) = gain wc/wd + gain wc (1 - wc/wd)/(s + wc)
        pd = named_statespace([[-wc]], [[wc]], [[g * (1 - wc / wd)]], [[g * wc / wd]], ["u"], ["y"])
    else:
        # states scaled by wc: x1' = wc x2, x2' = -wc x1 - sqrt2 wc x2 + wc u; R = x1
        z = math.sqrt(2.0)
        A = [[0.0, wc], [-wc, -z * wc]]
        pd = named_statespace(A, [[0.0], [wc]], [[g, g * wc / wd]], [[0.0]], ["u"], ["y"])
    if delay_s:
        pd = series(pd, pade_delay(delay_s, pade_order))
    return pd


def series(*parts: Any):
    """SISO series connection: ``parts[0]`` acts first, ``parts[-1]`` last.

    Parameters
    ----------
    *parts : LTI or float
        Continuous-time single-input single-output pieces (StateSpace, TransferFunction
        or a static gain).

    Returns
    -------
    control.StateSpace
        ``parts[-1](... parts[0](u))`` named ``u -> y``; states of the first part first.
    """
    out = _identity_abcd()
    for part in parts:
        out = series_matrices(out, _siso(part))
    return named_statespace(*out, ["u"], ["y"])


# ============================================================================ named systems
def _filter_one_output(abcd, i: int, f):
    A, B, C, D = abcd
    Af, Bf, Cf, Df = f
    n, nf = A.shape[0], Af.shape[0]
    A2 = np.block([[A, np.zeros((n, nf))], [Bf @ C[i : i + 1], Af]])
    B2 = np.vstack([B, Bf @ D[i : i + 1]])
    C2 = np.hstack([C, np.zeros((C.shape[0], nf))])
    C2[i] = np.hstack([Df @ C[i : i + 1], Cf])[0]
    D2 = D.copy()
    D2[i] = (Df @ D[i : i + 1])[0]
    return A2, B2, C2, D2


def _filter_one_input(abcd, j: int, f):
    A, B, C, D = abcd
    Af, Bf, Cf, Df = f
    n, nf = A.shape[0], Af.shape[0]
    A2 = np.block([[A, B[:, j : j + 1] @ Cf], [np.zeros((nf, n)), Af]])
    B2 = np.vstack([B, np.zeros((nf, B.shape[1]))])
    B2[:, j] = np.vstack([B[:, j : j + 1] @ Df, Bf])[:, 0]
    C2 = np.hstack([C, D[:, j : j + 1] @ Cf])
    D2 = D.copy()
    D2[:, j] = (D[:, j : j + 1] @ Df)[:, 0]
    return A2, B2, C2, D2


def filter_outputs(sys: Any, names: str | Sequence[str], filt: Any):
    """Put a copy of the SISO ``filt`` after each named output (sensor signal conditioning).

    Parameters
    ----------
    sys : control.StateSpace
        Named continuous-time system.
    names : str or sequence of str
        Output names; every name must exist.
    filt : LTI or float
        SISO continuous-time filter (e.g. :func:`bessel_lowpass`).

    Returns
    -------
    control.StateSpace
        Same input and output names; the filter states are appended.
    """
    f = _siso(filt)
    abcd = abcd_matrices(sys)
    for name in signal_names(names):
        abcd = _filter_one_output(abcd, signal_index(sys.output_labels, name, "output"), f)
    return named_statespace(*abcd, sys.input_labels, sys.output_labels)


def filter_inputs(sys: Any, names: str | Sequence[str], filt: Any):
    """Put a copy of the SISO ``filt`` before each named input (actuator smoothing filter).

    Same names in and out; see :func:`filter_outputs`.
    """
    f = _siso(filt)
    abcd = abcd_matrices(sys)
    for name in signal_names(names):
        abcd = _filter_one_input(abcd, signal_index(sys.input_labels, name, "input"), f)
    return named_statespace(*abcd, sys.input_labels, sys.output_labels)


def delay_outputs(sys: Any, names: str | Sequence[str], delay_s: float, order: int = 2):
    """Pade-approximated delay (s) on named outputs; MACE puts its 3.6 ms sampling delay here."""
    return filter_outputs(sys, names, pade_delay(delay_s, order))


def delay_inputs(sys: Any, names: str | Sequence[str], delay_s: float, order: int = 2):
    """Pade-approximated delay (s) on named inputs."""
    return filter_inputs(sys, names, pade_delay(delay_s, order))


def _close_loop(plant, ctrl, s: int, a: int, label: str):
    """State-space algebra of ``u_a = K (r - y_s)`` with ``r`` taking input slot ``a``.

    The algebraic loop through the feedthroughs is solved first: ``u = Ex x + Ek xk + Ev v``
    with ``v`` the new input vector, then substituted into plant and controller.
    """
    A, B, C, D = plant
    Ak, Bk, Ck, Dk = ctrl
    n, nk, m = A.shape[0], Ak.shape[0], B.shape[1]
    dk = float(Dk[0, 0])
    denom = 1.0 + dk * D[s, a]
    if abs(denom) < 1e-12:
        raise ModelError(
            f"the servo loop {label} is ill-posed (1 + K(inf) D = {denom:g}); "
            "add a roll-off to the controller."
        )
    other = np.ones(m, dtype=bool)
    other[a] = False
    Ev = np.eye(m)
    Ev[a, a] = dk / denom
    Ev[a, other] = -dk * D[s, other] / denom
    Ex = np.zeros((m, n))
    Ex[a] = -dk * C[s] / denom
    Ek = np.zeros((m, nk))
    Ek[a] = Ck[0] / denom
    Cx, Ck2, Dv = C + D @ Ex, D @ Ek, D @ Ev  # outputs
    e_x, e_k, e_v = -Cx[s], -Ck2[s], -Dv[s].copy()
    e_v[a] += 1.0  # error e = r - y_sensor
    A2 = np.block([[A + B @ Ex, B @ Ek], [Bk @ e_x[None], Ak + Bk @ e_k[None]]])
    B2 = np.vstack([B @ Ev, Bk @ e_v[None]])
    return A2, B2, np.hstack([Cx, Ck2]), Dv


def close_servo_loop(
    sys: Any,
    sensor: str,
    actuator: str,
    controller: Any,
    reference_input_name: str | None = None,
):
    """Close a local servo loop ``u_actuator = K (r - y_sensor)`` (MACE Fig. 1).

    The encoder (``sensor``) is fed back through the compensator ``controller`` to the
    gimbal motor (``actuator``); the actuator input is replaced, in place, by the
    reference ``r`` (same units as the sensor). All other inputs and all outputs keep
    their names and meaning; the controller states are appended.

    Parameters
    ----------
    sys : control.StateSpace
        Named continuous-time plant.
    sensor, actuator : str
        Output and input closing the loop.
    controller : LTI or float
        SISO compensator K(s) from the error ``r - y_sensor`` to the actuator input,
        e.g. :func:`servo_controller` (negative feedback).
    reference_input_name : str, optional
        Name of the new input (default ``"<sensor> ref"``).

    Raises
    ------
    ModelError
        Unknown names, a name clash, or an ill-posed loop (``1 + K(inf) D_sa = 0``).
    """
    A, B, C, D = abcd_matrices(sys)
    Ak, Bk, Ck, Dk = _siso(controller, "servo controller")
    s = signal_index(sys.output_labels, sensor, "output")
    a = signal_index(sys.input_labels, actuator, "input")
    ref = reference_input_name or f"{sensor} ref"
    inputs = list(sys.input_labels)
    if ref in inputs and ref != actuator:
        raise ModelError(f"the reference input name {ref!r} is already an input; pick another name.")
    inputs[a] = ref
    A2, B2, C2, D2 = _close_loop((A, B, C, D), (Ak, Bk, Ck, Dk), s, a, f"{sensor!r} -> {actuator!r}")
    return named_statespace(A2, B2, C2, D2, inputs, sys.output_labels)


def _rotation(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, s], [-s, c]])


def _pair(sys_labels: Sequence[str], pair: Sequence[str], what: str) -> list[int]:
    pair = tuple(pair)
    if len(pair) != 2 or pair[0] == pair[1]:
        raise ModelError(f"a misalignment acts on two different {what}s; got {pair!r}.")
    return [signal_index(sys_labels, p, what) for p in pair]


def misalign_outputs(sys: Any, pair: Sequence[str], angle_rad: float):
    """Sensor misalignment: the two sensors of ``pair`` are rotated by ``angle_rad``.

    ``[y_a, y_b] <- R [y_a, y_b]`` with ``R = [[cos t, sin t], [-sin t, cos t]]``: the
    readings are the true components projected onto axes turned by ``t`` (rad). 0: identity.
    """
    A, B, C, D = abcd_matrices(sys)
    idx = _pair(sys.output_labels, pair, "output")
    R = _rotation(_number(angle_rad, "the misalignment angle (rad)"))
    C, D = C.copy(), D.copy()
    C[idx], D[idx] = R @ C[idx], R @ D[idx]
    return named_statespace(A, B, C, D, sys.input_labels, sys.output_labels)


def misalign_inputs(sys: Any, pair: Sequence[str], angle_rad: float):
    """Actuator misalignment: the commands of ``pair`` act along axes turned by ``angle_rad``.

    The physical force components are ``R^T [u_a, u_b]`` (``R`` of :func:`misalign_outputs`).
    """
    A, B, C, D = abcd_matrices(sys)
    idx = _pair(sys.input_labels, pair, "input")
    R = _rotation(_number(angle_rad, "the misalignment angle (rad)"))
    B, D = B.copy(), D.copy()
    B[:, idx], D[:, idx] = B[:, idx] @ R.T, D[:, idx] @ R.T
    return named_statespace(A, B, C, D, sys.input_labels, sys.output_labels)


def sensor_gain_error(sys: Any, names: str | Sequence[str], error: float):
    """Relative sensor gain error: ``y <- (1 + error) y`` on each named output (0: identity)."""
    return scale_outputs(
        sys, {name: 1.0 + _number(error, "the sensor gain error") for name in signal_names(names)}
    )


# ============================================================================ stages
def _value(theta: Mapping[str, float], v: Value) -> float:
    if isinstance(v, str):
        return float(theta[v])
    if callable(v):
        return float(v(theta))
    return float(v)


def _side(side: str) -> str:
    side = side.rstrip("s")
    if side not in ("output", "input"):
        raise ModelError(f"side must be 'outputs' or 'inputs'; got {side!r}.")
    return side


def filter_stage(
    signals: str | Sequence[str],
    make_filter: Callable[..., Any],
    *,
    side: str = "outputs",
    name: str | None = None,
    tags: Sequence[str] = ("electronics",),
    **values: Value,
) -> Stage:
    """A Stage putting ``make_filter(**values)`` on each named signal.

    Each entry of ``values`` is a number, the name of a model parameter (read from
    ``theta`` at build time) or a function ``theta -> float``; e.g.
    ``filter_stage("gyro", bessel_lowpass, order=4, cutoff_hz="f_bessel")``.
    """
    which = _side(side)
    sigs = signal_names(signals)
    apply = filter_outputs if which == "output" else filter_inputs

    def fn(theta, sys):
        return apply(sys, sigs, make_filter(**{k: _value(theta, v) for k, v in values.items()}))

    label = name or f"{getattr(make_filter, '__name__', 'filter')} on {', '.join(sigs)}"
    return Stage(label, fn, tuple(tags))


def bessel_stage(signals, order: int, cutoff_hz: Value, *, side="outputs", norm="phase", **kw) -> Stage:
    """Stage: :func:`bessel_lowpass` on named signals (cutoff in Hz or a parameter name)."""
    return filter_stage(
        signals, lambda cutoff_hz: bessel_lowpass(order, cutoff_hz, norm), side=side,
        name=kw.pop("name", f"Bessel {order} on {', '.join(signal_names(signals))}"), cutoff_hz=cutoff_hz,
        **kw,
    )


def butterworth_stage(signals, order: int, cutoff_hz: Value, *, side="outputs", **kw) -> Stage:
    """Stage: :func:`butterworth_lowpass` on named signals."""
    return filter_stage(
        signals, lambda cutoff_hz: butterworth_lowpass(order, cutoff_hz), side=side,
        name=kw.pop("name", f"Butterworth {order} on {', '.join(signal_names(signals))}"),
        cutoff_hz=cutoff_hz,
        **kw,
    )


def lowpass1_stage(signals, cutoff_hz: Value, *, side="outputs", **kw) -> Stage:
    """Stage: :func:`lowpass1` on named signals."""
    return filter_stage(signals, lowpass1, side=side, cutoff_hz=cutoff_hz, **kw)


def lowpass2_stage(signals, cutoff_hz: Value, damping: Value, *, side="outputs", **kw) -> Stage:
    """Stage: :func:`lowpass2` on named signals."""
    return filter_stage(signals, lowpass2, side=side, cutoff_hz=cutoff_hz, damping=damping, **kw)


def notch_stage(signals, centre_hz: Value, depth: Value, width_hz: Value, *, side="outputs", **kw) -> Stage:
    """Stage: :func:`notch` on named signals."""
    return filter_stage(
        signals, notch, side=side, centre_hz=centre_hz, depth=depth, width_hz=width_hz, **kw
    )


def rate_gyro_stage(signals, natural_hz: Value, damping: Value, **kw) -> Stage:
    """Stage: :func:`rate_gyro` dynamics on named outputs."""
    return filter_stage(signals, rate_gyro, side="outputs", natural_hz=natural_hz, damping=damping, **kw)


def delay_stage(signals, delay_s: Value, order: int = 2, *, side="outputs", **kw) -> Stage:
    """Stage: :func:`pade_delay` on named signals (delay in s or a parameter name)."""
    return filter_stage(
        signals, lambda delay_s: pade_delay(delay_s, order), side=side,
        name=kw.pop("name", f"delay on {', '.join(signal_names(signals))}"), delay_s=delay_s, **kw,
    )


def zero_order_hold_stage(signals, fs_hz: Value, order: int = 4, *, side="inputs", **kw) -> Stage:
    """Stage: the DAC's zero-order hold (:func:`zero_order_hold`) on named signals (inputs).

    Add it deliberately when the data come from sampled records whose excitation was held
    by a DAC (``rc.simulate_experiment`` + ``rc.estimate_frf`` do exactly that): the hold's
    half-sample delay (2.5 ms at 200 Hz) is then a known part of the model, not an effect
    for ``rc.diagnose`` to find. The stage is tagged ``"zero_order_hold"``: compare, update
    and diagnose, which see a model through the H1 estimator when the data carry its
    settings, then sample the rest of the model through an exact hold instead of this
    rational approximation (aliasing and a direct feedthrough's timing included).
    """
    kw.setdefault("tags", ("electronics", "zero_order_hold"))
    return filter_stage(
        signals, lambda fs_hz: zero_order_hold(fs_hz, order), side=side,
        name=kw.pop("name", f"zero-order hold on {', '.join(signal_names(signals))}"), fs_hz=fs_hz, **kw,
    )


def anti_alias_stage(signals, cutoff_hz: Value, order: int = 4, *, kind: str = "butterworth", **kw) -> Stage:
    """Stage: an anti-alias low-pass (Butterworth or Bessel, ``order``) on named outputs."""
    if kind not in ("butterworth", "bessel"):
        raise ModelError(f"kind must be 'butterworth' or 'bessel'; got {kind!r}.")
    make = bessel_stage if kind == "bessel" else butterworth_stage
    return make(signals, order, cutoff_hz, side="outputs",
                name=kw.pop("name", f"anti-alias {kind} {order} on {', '.join(signal_names(signals))}"), **kw)


def gain_stage(
    gains: Mapping[str, Value],
    *,
    side: str = "outputs",
    name: str | None = None,
    tags: Sequence[str] = ("electronics",),
) -> Stage:
    """Stage: :func:`scale_outputs` / :func:`scale_inputs` with gains as numbers or parameter names."""
    which = _side(side)
    apply = scale_outputs if which == "output" else scale_inputs

    def fn(theta, sys):
        return apply(sys, {k: _value(theta, v) for k, v in gains.items()})

    return Stage(name or f"{which} gains", fn, tuple(tags))


def servo_stage(
    sensor: str,
    actuator: str,
    gain: Value,
    *,
    integral_hz: Value | None = None,
    lead_hz: Value | None = None,
    lowpass_hz: Value = math.inf,
    rolloff_order: int | None = None,
    delay_s: Value = 0.0,
    pade_order: int = 2,
    reference_input_name: str | None = None,
    name: str | None = None,
    tags: Sequence[str] = ("electronics", "servo"),
) -> Stage:
    """Stage: :func:`close_servo_loop` with a compensator built from theta at build time.

    Without ``lead_hz`` the compensator is :func:`servo_controller` (gain, optional PI,
    first-order low-pass, delay); with ``lead_hz`` it is the PD servo :func:`pd_controller`
    (MACE Fig. 1 gimbal servo; ``lowpass_hz`` finite, ``rolloff_order`` 1 or 2, default 2).
    Every number may be a constant, a parameter name or a function of theta.
    """
    if lead_hz is not None and integral_hz is not None:
        raise ModelError(
            "servo_stage builds a PI (integral_hz) or a PD (lead_hz) compensator, not both; "
            f"got integral_hz={integral_hz!r} and lead_hz={lead_hz!r}."
        )
    if lead_hz is None and rolloff_order not in (None, 1):
        raise ModelError(
            f"the P/PI servo has a first-order roll-off; rolloff_order={rolloff_order!r} needs lead_hz (PD)."
        )

    def controller(theta):
        if lead_hz is not None:
            return pd_controller(
                _value(theta, gain), _value(theta, lead_hz), lowpass_hz=_value(theta, lowpass_hz),
                delay_s=_value(theta, delay_s), rolloff_order=2 if rolloff_order is None else rolloff_order,
                pade_order=pade_order,
            )
        return servo_controller(
            _value(theta, gain),
            integral_hz=None if integral_hz is None else _value(theta, integral_hz),
            lowpass_hz=_value(theta, lowpass_hz),
            delay_s=_value(theta, delay_s),
            pade_order=pade_order,
        )

    def fn(theta, sys):
        return close_servo_loop(sys, sensor, actuator, controller(theta), reference_input_name)

    kind = "PD servo" if lead_hz is not None else "servo"
    return Stage(name or f"{kind} {sensor} -> {actuator}", fn, tuple(tags))


def misalignment_stage(pair: Sequence[str], angle_rad: Value, *, side="outputs", **kw) -> Stage:
    """Stage: :func:`misalign_outputs` / :func:`misalign_inputs` (angle in rad or a parameter name)."""
    which = _side(side)
    apply = misalign_outputs if which == "output" else misalign_inputs

    def fn(theta, sys):
        return apply(sys, pair, _value(theta, angle_rad))

    label = kw.get("name", f"misalignment of {tuple(pair)}")
    return Stage(label, fn, tuple(kw.get("tags", ("electronics",))))


def sensor_gain_error_stage(signals, error: Value, **kw) -> Stage:
    """Stage: :func:`sensor_gain_error` (relative error or a parameter name)."""

    def fn(theta, sys):
        return sensor_gain_error(sys, signals, _value(theta, error))

    return Stage(kw.get("name", f"gain error on {signals}"), fn, tuple(kw.get("tags", ("electronics",))))
