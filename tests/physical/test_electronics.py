"""Electronics of the I/O model (MACE Fig. 1) against scipy and closed forms."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
import scipy.interpolate
import scipy.signal as sg

from robustctl.errors import ModelError
from robustctl.physical import electronics as el
from robustctl.physical.model import PhysicalModel
from robustctl.physical.parameters import Parameter


def fr(sys, f_hz) -> np.ndarray:
    """Reference evaluation C (sI - A)^-1 B + D by a dense solve per frequency (n_freq, n_out, n_in).

    Independent of robustctl.lti.freqresp (whose fast modal path is tested elsewhere), and
    accurate in relative terms deep in a filter's stopband.
    """
    A, B, C, D = (np.asarray(getattr(sys, m), dtype=float) for m in ("A", "B", "C", "D"))
    eye = np.eye(A.shape[0])
    return np.array([D + C @ np.linalg.solve(2j * np.pi * f * eye - A, B) for f in np.atleast_1d(f_hz)])


def siso(sys, f_hz):
    return fr(sys, f_hz)[:, 0, 0]


F = np.logspace(-1, 4, 400)


def static(d):
    d = np.atleast_2d(d)
    return control.ss(np.zeros((0, 0)), np.zeros((0, d.shape[1])), np.zeros((d.shape[0], 0)), d)


# ------------------------------------------------------------------ analog low-pass filters
@pytest.mark.parametrize("order", range(1, 9))
@pytest.mark.parametrize("cutoff", [2.0, 160.0, 1000.0])
def test_bessel_and_butterworth_match_scipy(order, cutoff):
    for norm in ("phase", "mag", "delay"):
        b, a = sg.bessel(order, 2 * np.pi * cutoff, analog=True, norm=norm)
        _, ref = sg.freqs(b, a, 2 * np.pi * F)
        got = siso(el.bessel_lowpass(order, cutoff, norm=norm), F)
        assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-10
    b, a = sg.butter(order, 2 * np.pi * cutoff, analog=True)
    _, ref = sg.freqs(b, a, 2 * np.pi * F)
    got = siso(el.butterworth_lowpass(order, cutoff), F)
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-10


@pytest.mark.parametrize("order", [2, 4, 6])
def test_filter_normalisations_closed_form(order):
    fc = 1000.0
    # Bessel norm="phase" (MATLAB besself): the high-frequency asymptote (wc/w)^n of a
    # Butterworth filter, i.e. the product of the pole magnitudes is wc^n; unit DC gain
    wc = 2 * np.pi * fc
    A = np.asarray(el.bessel_lowpass(order, fc).A)
    assert np.isclose(abs(np.linalg.det(A)), wc**order, rtol=1e-10)
    assert np.isclose(siso(el.bessel_lowpass(order, fc), 1e-6)[0], 1.0, atol=1e-9)
    # norm="delay": group delay 1/wc at DC
    f_low = 1e-4 * fc
    phase = np.angle(siso(el.bessel_lowpass(order, fc, norm="delay"), f_low)[0])
    assert np.isclose(-phase / (2 * np.pi * f_low), 1 / wc, rtol=1e-6)
    # norm="mag": -3 dB at the cutoff; Butterworth: |H|^2 = 1 / (1 + (f/fc)^(2n))
    assert np.isclose(abs(siso(el.bessel_lowpass(order, fc, norm="mag"), fc)[0]), 2**-0.5, rtol=1e-10)
    f = np.array([10.0, 900.0, 3000.0])
    mag2 = np.abs(siso(el.butterworth_lowpass(order, fc), f)) ** 2
    assert np.allclose(mag2, 1 / (1 + (f / fc) ** (2 * order)), rtol=1e-10)


def test_realisation_is_well_conditioned_at_high_cutoff():
    good = np.asarray(el.bessel_lowpass(8, 1000.0).A)
    b, a = sg.bessel(8, 2 * np.pi * 1000.0, analog=True)
    companion = sg.tf2ss(b, a)[0]
    assert np.linalg.cond(good) < 100 < 1e6 < np.linalg.cond(companion)


def test_first_and_second_order_lowpass_and_gyro():
    s = 2j * np.pi * F
    wc = 2 * np.pi * 30.0
    assert np.allclose(siso(el.lowpass1(30.0), F), wc / (s + wc), rtol=1e-12)
    wn, z = 2 * np.pi * 80.0, 0.3
    ref = wn**2 / (s**2 + 2 * z * wn * s + wn**2)
    assert np.allclose(siso(el.lowpass2(80.0, 0.3), F), ref, rtol=1e-12)
    assert np.allclose(siso(el.rate_gyro(80.0, 0.3), F), ref, rtol=1e-12)
    for neutral in (el.lowpass1(math.inf), el.lowpass2(math.inf), el.bessel_lowpass(4, math.inf)):
        assert neutral.nstates == 0 and float(neutral.D[0, 0]) == 1.0


def test_notch_depth_and_width():
    f0, width = 50.0, 4.0
    ref_s = 2j * np.pi * F
    w0, zp = 2 * np.pi * f0, width / (2 * f0)
    zz = 0.1 * zp
    ref = (ref_s**2 + 2 * zz * w0 * ref_s + w0**2) / (ref_s**2 + 2 * zp * w0 * ref_s + w0**2)
    assert np.allclose(siso(el.notch(f0, 0.1, width), F), ref, rtol=1e-12)
    assert np.isclose(abs(siso(el.notch(f0, 0.1, width), f0)[0]), 0.1)
    # the -3 dB points of a perfect notch are width_hz apart
    lo, hi = np.sqrt(f0**2 + (width / 2) ** 2) + np.array([-1, 1]) * width / 2
    assert np.allclose(np.abs(siso(el.notch(f0, 0.0, width), [lo, hi])), 2**-0.5, rtol=1e-10)
    assert el.notch(f0, 1.0, width).nstates == 0


# ------------------------------------------------------------------ Pade delay
def pade_reference(delay, order, f_hz):
    """Independent [n/n] Pade of exp(-x) from its Taylor series (scipy.interpolate.pade)."""
    taylor = [(-1) ** k / math.factorial(k) for k in range(2 * order + 1)]
    p, q = scipy.interpolate.pade(taylor, order, order)
    x = 2j * np.pi * np.asarray(f_hz) * delay
    return p(x) / q(x)


@pytest.mark.parametrize("order", range(1, 7))
def test_pade_matches_independent_approximant(order):
    tau = 3.6e-3
    f = np.logspace(-1, 3, 200)
    got = siso(el.pade_delay(tau, order), f)
    ref = pade_reference(tau, order, f)
    assert np.max(np.abs(got - ref)) < 1e-10
    assert np.allclose(np.abs(got), 1.0, atol=1e-12)  # all-pass
    num, den = control.pade(tau, order)
    assert np.max(np.abs(got - np.polyval(num, 2j * np.pi * f) / np.polyval(den, 2j * np.pi * f))) < 1e-9


@pytest.mark.parametrize("order", range(1, 11))
def test_pade_matches_exact_rational_coefficients_up_to_order_10(order):
    """D(-x)/D(x) with c_k = (2n-k)! n! / ((2n)! k! (n-k)!) computed exactly in fractions."""
    from fractions import Fraction

    f = math.factorial
    n = order
    coef = [Fraction(f(2 * n - k) * f(n), f(2 * n) * f(k) * f(n - k)) for k in range(n + 1)]
    tau, freq = 3.6e-3, np.logspace(0, 3, 80)
    x = 2j * np.pi * freq * tau
    den = sum(float(c) * x**k for k, c in enumerate(coef))
    num = sum(float(c) * (-x) ** k for k, c in enumerate(coef))
    assert np.max(np.abs(siso(el.pade_delay(tau, order), freq) - num / den)) < 1e-12
    assert np.allclose(el.pade_coefficients(order), [float(c) for c in coef], rtol=1e-14)


def test_pade_phase_error_at_60_hz_for_mace_delay():
    tau, f = 3.6e-3, 60.0
    x = 2 * np.pi * f * tau
    exact = -x
    phase1 = np.angle(siso(el.pade_delay(tau, 1), f)[0])
    phase2 = np.angle(siso(el.pade_delay(tau, 2), f)[0])
    # closed forms: -2 arg D(j x) with D = 1 + x/2 and 1 + x/2 + x^2/12
    assert np.isclose(phase1, -2 * math.atan(x / 2), atol=1e-12)
    assert np.isclose(phase2, -2 * math.atan2(x / 2, 1 - x**2 / 12), atol=1e-12)
    assert np.degrees(abs(phase2 - exact)) < 0.33  # order 2 is good to a third of a degree
    assert np.degrees(abs(phase1 - exact)) > 9.0  # order 1 is not


def test_delay_zero_is_exact_identity():
    sys = control.ss([[-1.0]], [[1.0, 2.0]], [[3.0], [4.0]], [[0.0, 0.5], [0.0, 0.0]],
                     inputs=["u1", "u2"], outputs=["y1", "y2"])
    out = el.delay_outputs(sys, ["y1", "y2"], 0.0, order=3)
    inp = el.delay_inputs(sys, "u2", 0.0)
    for new in (out, inp):
        assert new.nstates == 1
        for m in ("A", "B", "C", "D"):
            assert np.array_equal(np.asarray(getattr(new, m)), np.asarray(getattr(sys, m)))


# ------------------------------------------------------------------ named series connections
def two_by_two():
    return control.ss(
        [[0, 1], [-40, -0.8]], [[0, 0], [1, 0.5]], [[1, 0], [0.3, 1]], [[0, 0], [0.1, 0]],
        inputs=["F", "T"], outputs=["x", "v"],
    )


def test_filter_outputs_and_inputs_multiply_the_named_channels():
    sys = two_by_two()
    filt = el.bessel_lowpass(4, 20.0)
    f = np.logspace(-1, 2, 60)
    base = fr(sys, f)
    h = siso(filt, f)
    out = el.filter_outputs(sys, ["v"], filt)
    assert out.output_labels == ["x", "v"] and out.input_labels == ["F", "T"]
    got = fr(out, f)
    assert np.allclose(got[:, 0], base[:, 0], rtol=1e-12)
    assert np.allclose(got[:, 1], base[:, 1] * h[:, None], rtol=1e-10)
    inp = fr(el.filter_inputs(sys, "T", filt), f)
    assert np.allclose(inp[:, :, 0], base[:, :, 0], rtol=1e-12)
    assert np.allclose(inp[:, :, 1], base[:, :, 1] * h[:, None], rtol=1e-10)
    tf = control.tf([1.0], [0.01, 1.0])  # a TransferFunction works too
    got = fr(el.filter_outputs(sys, "x", tf), f)
    assert np.allclose(got[:, 0], base[:, 0] / (1 + 0.01 * 2j * np.pi * f[:, None]), rtol=1e-10)


def test_gains_misalignment_and_gain_error():
    sys = two_by_two()
    f = np.array([0.5, 3.0])
    base = fr(sys, f)
    g = fr(el.scale_outputs(el.scale_inputs(sys, {"T": 2.0}), {"v": 10.0}), f)
    assert np.allclose(g, base * np.array([[1, 2], [10, 20]]), rtol=1e-12)
    t = 0.1
    rot = fr(el.misalign_outputs(sys, ("x", "v"), t), f)
    R = np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    assert np.allclose(rot, R @ base, rtol=1e-12)
    rin = fr(el.misalign_inputs(sys, ("F", "T"), t), f)
    assert np.allclose(rin, base @ R.T, rtol=1e-12)
    zero = el.misalign_outputs(sys, ("x", "v"), 0.0)
    assert np.array_equal(np.asarray(zero.C), np.asarray(sys.C))
    err = fr(el.sensor_gain_error(sys, "x", 0.05), f)
    assert np.allclose(err[:, 0], 1.05 * base[:, 0]) and np.allclose(err[:, 1], base[:, 1])
    ren = el.rename_signals(sys, outputs={"v": "v (V)"})
    assert ren.output_labels == ["x", "v (V)"]


# ------------------------------------------------------------------ servo loops
def one_dof(m=2.0, c=0.3, k=50.0):
    """m x'' + c x' + k x = F + d; outputs encoder x and accelerometer x''."""
    return control.ss(
        [[0, 1], [-k / m, -c / m]], [[0, 0], [1 / m, 1 / m]], [[1, 0], [-k / m, -c / m]],
        [[0, 0], [1 / m, 1 / m]], inputs=["F", "d"], outputs=["enc", "acc"],
    )


def test_servo_loop_matches_closed_form_on_one_dof():
    m, c, k = 2.0, 10.0, 50.0
    kp, fi, fl, tau = 30.0, 0.5, 20.0, 2e-3
    ctrl = el.servo_controller(kp, integral_hz=fi, lowpass_hz=fl, delay_s=tau, pade_order=2)
    cl = el.close_servo_loop(one_dof(m, c, k), "enc", "F", ctrl)
    assert cl.input_labels == ["enc ref", "d"] and cl.output_labels == ["enc", "acc"]
    f = np.logspace(-1.5, 2, 80)
    s = 2j * np.pi * f
    x = s * tau
    pade2 = (1 - x / 2 + x**2 / 12) / (1 + x / 2 + x**2 / 12)
    K = kp * (1 + 2 * np.pi * fi / s) * (2 * np.pi * fl / (s + 2 * np.pi * fl)) * pade2
    G = 1 / (m * s**2 + c * s + k)
    T = K * G / (1 + K * G)
    S_d = G / (1 + K * G)
    got = fr(cl, f)
    assert np.allclose(got[:, 0, 0], T, rtol=1e-9)
    assert np.allclose(got[:, 0, 1], S_d, rtol=1e-9)
    assert np.allclose(got[:, 1, 0], s**2 * T, rtol=1e-9)
    assert np.all(np.linalg.eigvals(np.asarray(cl.A)).real < 0)


def test_servo_loop_through_feedthrough_sensor():
    # accelerometer with feedthrough 1/m closed by a static gain: algebraic loop solved exactly
    m, c, k, g = 2.0, 0.3, 50.0, 0.7
    cl = el.close_servo_loop(one_dof(m, c, k), "acc", "F", g, reference_input_name="a_cmd")
    f = np.logspace(-1, 1.5, 40)
    s = 2j * np.pi * f
    P = s**2 / (m * s**2 + c * s + k)
    got = fr(cl, f)
    assert np.allclose(got[:, 1, 0], g * P / (1 + g * P), rtol=1e-10)
    assert cl.input_labels == ["a_cmd", "d"]


def test_servo_loop_errors():
    sys = one_dof()
    with pytest.raises(ModelError, match="unknown output 'gyro'"):
        el.close_servo_loop(sys, "gyro", "F", 1.0)
    with pytest.raises(ModelError, match="unknown input 'motor'"):
        el.close_servo_loop(sys, "enc", "motor", 1.0)
    with pytest.raises(ModelError, match="already an input"):
        el.close_servo_loop(sys, "enc", "F", 1.0, reference_input_name="d")
    with pytest.raises(ModelError, match="ill-posed"):
        el.close_servo_loop(sys, "acc", "F", -2.0)  # 1 + K D = 1 - 2 * 0.5 = 0
    with pytest.raises(ModelError, match="single-input single-output"):
        el.close_servo_loop(sys, "enc", "F", static(np.eye(2)))


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: el.bessel_lowpass(0, 10.0), "order must be an integer in 1..20"),
        (lambda: el.butterworth_lowpass(4, -1.0), "cutoff must be a positive number in Hz"),
        (lambda: el.bessel_lowpass(4, 10.0, norm="db"), "Bessel norm must be"),
        (lambda: el.pade_delay(-1e-3), "time delay must be a finite number of seconds >= 0"),
        (lambda: el.pade_delay(1e-3, 11), "Pade order must be an integer in 1..10"),
        (lambda: el.notch(50.0, -0.1, 2.0), "notch depth"),
        (lambda: el.notch(50.0, 0.1, 0.0), "notch width must be a positive number"),
        (lambda: el.lowpass2(10.0, 0.0), "damping ratio must be a positive number"),
        (lambda: el.filter_outputs(two_by_two(), "gyro", el.lowpass1(5.0)), "unknown output 'gyro'"),
        (lambda: el.filter_inputs(two_by_two(), ["T", "X"], el.lowpass1(5.0)), "unknown input 'X'"),
        (lambda: el.filter_outputs(two_by_two(), "x", static(np.eye(2))), "single-input"),
        (lambda: el.filter_outputs(two_by_two(), "x", control.tf([1], [1, 1], 0.01)), "discrete-time"),
        (lambda: el.misalign_outputs(two_by_two(), ("x", "x"), 0.1), "two different outputs"),
        (lambda: el.scale_outputs(two_by_two(), {"q": 2.0}), "unknown output 'q'"),
        (lambda: el.rename_signals(two_by_two(), outputs={"v": "x"}), "repeat a signal name"),
        (lambda: el.delay_stage("x", 0.0, side="middle"), "side must be"),
    ],
)
def test_bad_input_raises_model_error(call, match):
    with pytest.raises(ModelError, match=match):
        call()


# ------------------------------------------------------------------ stages read theta
def test_stages_read_parameters_by_name_and_vanish_at_neutral_values():
    plant = one_dof()
    params = (
        Parameter("tau", 3.6e-3, "s", bounds=(0, 0.1), neutral=0.0),
        Parameter("f_bessel", 100.0, "Hz", bounds=(1, 1e4)),
        Parameter("kp", 30.0, "N/m", bounds=(0, 1e3)),
        Parameter("g_acc", 0.1, "V/(m/s^2)", bounds=(0, 10)),
        Parameter("eps", 0.0, "", bounds=(-1, 1), neutral=0.0),
    )
    stages = (
        el.servo_stage("enc", "F", "kp", integral_hz=0.5, delay_s="tau"),
        el.gain_stage({"acc": "g_acc"}),
        el.bessel_stage(["acc"], 4, "f_bessel"),
        el.delay_stage(["acc"], "tau"),
        el.sensor_gain_error_stage("acc", "eps"),
        el.notch_stage("acc", 60.0, 1.0, lambda th: 2.0),
    )
    model = PhysicalModel(params, dynamics=lambda theta, _: plant, io_stages=stages)
    f = np.logspace(-1, 2, 50)
    got = fr(model.statespace(), f)[:, 1, 0]
    ctrl = el.servo_controller(30.0, integral_hz=0.5, delay_s=3.6e-3)
    ref_sys = el.close_servo_loop(plant, "enc", "F", ctrl)
    ref = (fr(ref_sys, f)[:, 1, 0] * 0.1
           * siso(el.bessel_lowpass(4, 100.0), f) * siso(el.pade_delay(3.6e-3), f))
    assert np.allclose(got, ref, rtol=1e-9)
    assert model.inputs == ("enc ref", "d")
    # tau = 0 removes the delay on the output and inside the servo loop exactly
    no_delay = model.statespace(tau=0.0)
    assert no_delay.nstates == model.statespace().nstates - 4  # two order-2 Pade delays
    assert [s.tags for s in stages][0] == ("electronics", "servo")
    assert model.without("servo").inputs == ("F", "d")
