"""Controller export: discretisation against scipy and closed forms, file round trips for every
format, checks (stability, discretisation error, balancing), refusals, and a real C client."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import warnings
from pathlib import Path
from types import SimpleNamespace

import control
import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.io import loadmat, savemat
from scipy.signal import cont2discrete, dlsim, sosfreqz

import robustctl as rc
from robustctl.errors import DataError, ModelError
from robustctl.export import files as controller_data
from robustctl.export import formats, sos_file
from robustctl.lti import freqresp_array

C_CLIENT = Path(__file__).resolve().parents[1] / "c_client" / "run_controller.c"
FORMATS = ("json", "csv", "mat", "h")


# ---------------------------------------------------------------------------- controllers
def flexible_plant(seed: int = 0, zeta: float = 0.005):
    """A 2x2 six-mode structure (12 states), force actuators and displacement sensors."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * np.array([1.2, 2.5, 4.1, 7.3, 11.0, 17.0])
    n = w.size
    A, B, C = np.zeros((2 * n, 2 * n)), np.zeros((2 * n, 2)), np.zeros((2, 2 * n))
    for k in range(n):
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[0, 1], [-(w[k] ** 2), -2 * zeta * w[k]]]
        B[2 * k + 1] = rng.normal(size=2)
        C[:, 2 * k] = rng.normal(size=2)
    return control.ss(A, B, C, 0, inputs=["force_1", "force_2"], outputs=["disp_1", "disp_2"])


def lqg_controller(seed: int = 0):
    """The 12-state LQG controller of :func:`flexible_plant` (stable for these weights)."""
    G = flexible_plant(seed)
    Q = 1e4 * G.C.T @ G.C
    Kx, _, _ = control.lqr(G.A, G.B, (Q + Q.T) / 2, np.eye(2))
    L, _, _ = control.lqe(G.A, G.B, G.C, np.eye(2), 1e-4 * np.eye(2))
    return control.ss(
        G.A - G.B @ Kx - L @ G.C,
        L,
        -Kx,
        0,
        inputs=["disp_1", "disp_2"],
        outputs=["force_1", "force_2"],
        states=[f"xhat{i}" for i in range(G.nstates)],
    )


def light_controller(zeta: float = 0.002):
    """A 2x2, 8-state resonant controller (four modes, 0.2 % damping, 3 to 42 Hz) with feedthrough."""
    rng = np.random.default_rng(5)
    A, B, C = np.zeros((8, 8)), np.zeros((8, 2)), np.zeros((2, 8))
    for k, f in enumerate([3.0, 7.5, 19.0, 42.0]):
        w = 2 * np.pi * f
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[0, 1], [-(w**2), -2 * zeta * w]]
        B[2 * k + 1] = rng.normal(size=2) * w**2
        C[:, 2 * k] = rng.normal(size=2)
    return control.ss(A, B, C, [[0.1, 0.0], [0.02, -0.05]], inputs=["e1", "e2"], outputs=["v1", "v2"])


def notch_lead(f0: float = 12.0):
    """SISO: a lead filter times a lightly damped notch at f0 Hz (4 states)."""
    s = control.tf("s")
    w0 = 2 * np.pi * f0
    lead = 20 * (s / 6 + 1) / (s / 60 + 1)
    notch = (s**2 + 2 * 0.002 * w0 * s + w0**2) / (s**2 + 2 * 0.3 * w0 * s + w0**2)
    roll = 1 / (s / 150 + 1)
    return control.ss(lead * notch * roll, inputs=["err"], outputs=["cmd"])


def _grid(dt: float, n: int = 400) -> np.ndarray:
    return np.linspace(0.001, 0.499, n) / dt


def _rel_response_error(K1, K2) -> float:
    f = _grid(K1.dt)
    g1, g2 = freqresp_array(K1, f), freqresp_array(K2, f)
    return float(np.max(np.abs(g1 - g2)) / np.max(np.abs(g1)))


def _export(K, path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return rc.export_controller(K, path, **kw)


# ---------------------------------------------------------------------------- discretize
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("method,scipy_method", [("tustin", "bilinear"), ("zoh", "zoh")])
def test_discretize_matches_scipy_cont2discrete(seed, method, scipy_method):
    K = lqg_controller(seed) if seed else light_controller()
    fs = 250.0
    Kd = rc.discretize(K, fs, method)
    ref = cont2discrete((K.A, K.B, K.C, K.D), 1 / fs, scipy_method)
    for mine, theirs in zip((Kd.A, Kd.B, Kd.C, Kd.D), ref[:4]):
        np.testing.assert_allclose(mine, theirs, rtol=1e-12, atol=1e-12 * np.max(np.abs(theirs)))
    assert Kd.dt == 1 / fs
    assert Kd.input_labels == K.input_labels and Kd.output_labels == K.output_labels
    assert Kd.state_labels == K.state_labels


def test_zoh_is_step_invariant():
    """A ZOH equivalent reproduces the continuous step response exactly at the samples."""
    K = notch_lead()
    fs = 500.0
    Kd = rc.discretize(K, fs, "zoh")
    t = np.arange(200) / fs
    _, y_c = control.step_response(K, t)
    _, y_d = control.step_response(Kd, t)
    np.testing.assert_allclose(np.squeeze(y_d), np.squeeze(y_c), atol=1e-9 * np.max(np.abs(y_c)))


@pytest.mark.parametrize(
    "f0,zeta,fs,fp", [(5.0, 0.01, 100.0, 5.0), (40.0, 0.002, 200.0, 40.0), (3.0, 0.3, 50.0, 10.0)]
)
def test_prewarp_matches_analytic_bilinear(f0, zeta, fs, fp):
    """K = w^2/(s^2 + 2 zeta w s + w^2) with s = c (1 - z^-1)/(1 + z^-1), c = wp / tan(wp T/2):
    numerator w^2 (1 + z^-1)^2, denominator (c^2 + 2 zeta w c + w^2) + 2 (w^2 - c^2) z^-1
    + (c^2 - 2 zeta w c + w^2) z^-2."""
    w, wp, T = 2 * np.pi * f0, 2 * np.pi * fp, 1 / fs
    c = wp / np.tan(wp * T / 2)
    num = w**2 * np.array([1.0, 2.0, 1.0])
    den = np.array([c * c + 2 * zeta * w * c + w * w, 2 * (w * w - c * c), c * c - 2 * zeta * w * c + w * w])
    Kd = rc.discretize(control.tf([w**2], [1, 2 * zeta * w, w**2]), fs, prewarp_hz=fp)
    f = _grid(T)
    zinv = np.exp(-2j * np.pi * f * T)
    analytic = np.polyval(num[::-1], zinv) / np.polyval(den[::-1], zinv)
    got = freqresp_array(Kd, f)[:, 0, 0]
    np.testing.assert_allclose(got, analytic, rtol=1e-10)
    # and the prewarped frequency is matched exactly
    g_c = freqresp_array(control.tf([w**2], [1, 2 * zeta * w, w**2]), [fp])
    np.testing.assert_allclose(freqresp_array(Kd, [fp]), g_c, rtol=1e-11)


def test_prewarp_matches_mimo_response_at_the_prewarp_frequency():
    K = lqg_controller(3)
    for fp in (1.2, 7.3, 40.0):
        Kd = rc.discretize(K, 100.0, "tustin", prewarp_hz=fp)
        g, gd = freqresp_array(K, [fp]), freqresp_array(Kd, [fp])
        assert np.max(np.abs(gd - g)) <= 1e-10 * np.max(np.abs(g))
        plain = freqresp_array(rc.discretize(K, 100.0), [fp])
        if fp > 5:  # without prewarping the warping shows
            assert np.max(np.abs(plain - g)) > 1e-4 * np.max(np.abs(g))


def test_discretize_discrete_input_and_refusals():
    Kd = rc.discretize(light_controller(), 1000.0)
    assert rc.discretize(Kd, None) is Kd and rc.discretize(Kd, 1000.0) is Kd
    with pytest.raises(DataError, match="already discrete"):
        rc.discretize(Kd, 500.0)
    with pytest.raises(DataError, match="fs is required"):
        rc.discretize(light_controller(), None)
    for bad in (0.0, -5.0, np.nan, True, "100"):
        with pytest.raises(DataError, match="fs"):
            rc.discretize(light_controller(), bad)
    with pytest.raises(DataError, match="method"):
        rc.discretize(light_controller(), 100.0, method="foh")
    with pytest.raises(DataError, match="Nyquist"):
        rc.discretize(light_controller(), 100.0, prewarp_hz=50.0)
    with pytest.raises(DataError, match="tustin' only"):
        rc.discretize(light_controller(), 100.0, method="zoh", prewarp_hz=5.0)
    with pytest.raises(ModelError, match="singular"):  # a pole exactly at s = 2/T = 200 rad/s
        rc.discretize(control.ss(200.0, 1.0, 1.0, 0.0), 100.0)


# ---------------------------------------------------------------------------- round trips
@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("case", ["lqg", "light", "gain"])
def test_round_trip_is_bit_exact(tmp_path, fmt, case):
    K = {
        "lqg": lqg_controller(1),
        "light": light_controller(),
        "gain": control.ss([], [], [], [[1.5, -0.25]], inputs=["a", "b"], outputs=["c"]),
    }[case]
    units = {K.input_labels[0]: "m", K.output_labels[0]: "N"}
    rep = _export(K, tmp_path / f"ctrl.{fmt}", fs=400.0, units=units)
    back = rc.load_controller(rep.path)
    assert formats.READERS["." + fmt](rep.path).units == units
    Kd = rep.controller
    for key in "ABCD":  # every format stores exact decimal (or binary) doubles
        np.testing.assert_array_equal(getattr(back, key), getattr(Kd, key), err_msg=f"{fmt} {key}")
    assert back.dt == Kd.dt == 1 / 400.0
    assert back.input_labels == K.input_labels and back.output_labels == K.output_labels
    if K.nstates:
        assert _rel_response_error(Kd, back) == 0.0


def test_json_holds_the_documented_fields(tmp_path):
    result = SimpleNamespace(K=lqg_controller(), gamma=1.83, mu_peak=0.97)
    rep = _export(
        result,
        tmp_path / "k.json",
        fs=200.0,
        provenance={"plant": "truss v3", "author": "me"},
        units={"disp_1": "m"},
        crossover_hz=2.0,
    )
    doc = json.loads(rep.path.read_text())
    assert doc["format"] == "robustctl.controller" and doc["fs_hz"] == 200.0 and doc["dt_s"] == 0.005
    assert doc["inputs"] == ["disp_1", "disp_2"] and doc["units"] == {"disp_1": "m"}
    assert doc["design"] == {"gamma": 1.83, "mu": 0.97} and rep.gamma == 1.83 and rep.mu == 0.97
    assert doc["discretization"] == {"method": "tustin", "prewarp_hz": None}
    assert doc["provenance"]["plant"] == "truss v3" and doc["provenance"]["software"].startswith("robustctl")
    assert doc["checks"]["error_at_hz"] == 2.0
    assert np.array(doc["A"]).shape == (12, 12)


def test_mat_file_has_the_matlab_ss_layout(tmp_path):
    rep = _export(lqg_controller(), tmp_path / "k.mat", fs=200.0)
    m = loadmat(rep.path)
    assert m["A"].shape == (12, 12) and m["B"].shape == (12, 2) and float(m["Ts"][0, 0]) == 0.005
    assert [str(x[0]) for x in m["InputName"].ravel()] == ["disp_1", "disp_2"]


def test_load_a_users_continuous_mat_file(tmp_path):
    K = notch_lead()
    savemat(tmp_path / "user.mat", {"A": K.A, "B": K.B, "C": K.C, "D": K.D, "Ts": 0.0})
    back = rc.load_controller(tmp_path / "user.mat")
    assert back.dt == 0 and back.ninputs == 1
    np.testing.assert_array_equal(back.A, K.A)


def _direct_response(sys, z: np.ndarray) -> np.ndarray:
    """``C (z I - A)^-1 B + D`` of a SISO system by one linear solve per point: accurate to
    ``cond(z I - A) eps``, independent of the modal route of ``freqresp_array`` (whose error,
    ``cond(V) eps`` with ``cond(V) ~ 1e4`` for these sections, is itself about 1e-12)."""
    A, B, C, D = (np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
    eye = np.eye(A.shape[0])
    return np.array([(C @ np.linalg.solve(zk * eye - A, B) + D)[0, 0] for zk in z])


def test_sos_round_trip_siso(tmp_path):
    K = notch_lead()
    rep = _export(K, tmp_path / "k.sos", fs=1000.0)
    sos, meta = sos_file.read_sos_file(rep.path)
    back = rc.load_controller(rep.path)
    f = _grid(1e-3)
    _, h = sosfreqz(sos, worN=2 * np.pi * f * 1e-3)
    g = _direct_response(back, np.exp(2j * np.pi * f * 1e-3))
    assert np.max(np.abs(g - h)) <= 1e-12 * np.max(np.abs(h))  # the file's sections, reloaded
    assert rep.sos_error < 1e-9  # sections vs the discrete state space
    assert _rel_response_error(rep.controller, back) < 1e-9
    assert back.input_labels == ["err"] and back.output_labels == ["cmd"] and back.dt == 1e-3
    assert sos.shape == (2, 6) and np.all(sos[:, 3] == 1.0)


def test_sos_refuses_mimo_unless_a_channel_is_chosen(tmp_path):
    K = lqg_controller()
    with pytest.raises(DataError, match="channel=\\('force_1', 'disp_1'\\)"):
        _export(K, tmp_path / "k.sos", fs=200.0)
    assert not (tmp_path / "k.sos").exists()
    rep = _export(K, tmp_path / "k.sos", fs=200.0, channel=("force_2", "disp_1"))
    back = rc.load_controller(rep.path)
    ref = rc.discretize(K, 200.0)[1, 0]
    assert rep.channel == ("force_2", "disp_1") and rep.sos_error < 1e-8
    assert _rel_response_error(ref, back) < 1e-8
    with pytest.raises(DataError, match="channel output 'nope'"):
        _export(K, tmp_path / "k2.sos", fs=200.0, channel=("nope", 0))
    with pytest.raises(DataError, match="format 'sos' only"):
        _export(K, tmp_path / "k.json", fs=200.0, channel=(0, 0))


# ---------------------------------------------------------------------------- files: safety
def test_refuses_to_overwrite_unless_asked(tmp_path):
    path = tmp_path / "k.json"
    path.write_text("precious")
    with pytest.raises(DataError, match="already exists"):
        _export(light_controller(), path, fs=1000.0)
    assert path.read_text() == "precious"
    for flag in ("yes", 1, None):
        with pytest.raises(DataError, match="overwrite must be True or False"):
            _export(light_controller(), path, fs=1000.0, overwrite=flag)
    assert path.read_text() == "precious"
    _export(light_controller(), path, fs=1000.0, overwrite=True)
    assert rc.load_controller(path).nstates == 8


@pytest.mark.parametrize("existing", [False, True])
def test_failed_write_leaves_no_partial_file(tmp_path, monkeypatch, existing):
    path = tmp_path / "k.csv"
    if existing:
        path.write_text("old")

    def broken(ctrl, tmp, **_):
        tmp.write_text("field,row,col,value\nA,0,0,1.0\n")  # half a file, then the disk fills up
        raise OSError("No space left on device")

    monkeypatch.setitem(formats.WRITERS, ".csv", broken)
    with pytest.raises(rc.DataError, match="No space"):  # the cause is named (reliability rule)
        _export(light_controller(), path, fs=1000.0, overwrite=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == (["k.csv"] if existing else [])
    if existing:
        assert path.read_text() == "old"


# ---------------------------------------------------------------------------- checks
def test_stability_check_warns_or_refuses(tmp_path):
    unstable = control.ss([[0.5, 0], [0, -3.0]], [[1], [1]], [[1, 1]], 0)
    with pytest.warns(RuntimeWarning, match=r"\|z\| = 1.00"):
        rep = rc.export_controller(unstable, tmp_path / "u.json", fs=100.0)
    assert not rep.stable and rep.spectral_radius == pytest.approx(
        (1 + 0.5 / 200) / (1 - 0.5 / 200), rel=1e-12
    )
    with pytest.raises(ModelError, match="not asymptotically stable"):
        rc.export_controller(unstable, tmp_path / "v.json", fs=100.0, on_unstable="raise")
    assert not (tmp_path / "v.json").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rep = rc.export_controller(unstable, tmp_path / "w.json", fs=100.0, on_unstable="ignore")
    assert json.loads(rep.path.read_text())["checks"]["stable"] is False
    stable = rc.export_controller(notch_lead(), tmp_path / "s.json", fs=1000.0)
    assert stable.stable and stable.spectral_radius < 1


def test_discretisation_error_is_reported_at_the_crossover(tmp_path):
    K = lqg_controller()
    fc, fs = 3.0, 100.0
    rep_t = _export(K, tmp_path / "t.json", fs=fs, crossover_hz=fc)
    rep_z = _export(K, tmp_path / "z.json", fs=fs, crossover_hz=fc, method="zoh")
    rep_p = _export(K, tmp_path / "p.json", fs=fs, crossover_hz=fc, prewarp_hz=fc)
    g = freqresp_array(K, [fc])[0]
    for rep in (rep_t, rep_z, rep_p):
        gd = freqresp_array(rep.controller, [fc])[0]
        expected = np.linalg.norm(gd - g, 2) / np.linalg.norm(g, 2)
        assert rep.crossover_hz == fc and rep.discretization_error == pytest.approx(expected, rel=1e-9)
    assert rep_p.discretization_error < 1e-10 < rep_t.discretization_error < rep_z.discretization_error
    # the ZOH's half-sample delay: about |1 - exp(-j w T/2)| = w T / 2 (= 9.4 % here) of phase error
    assert rep_z.discretization_error > 0.05


def test_default_error_frequency_is_the_peak_gain(tmp_path):
    K = light_controller()
    with pytest.warns(RuntimeWarning, match="prewarp there"):
        rep = rc.export_controller(K, tmp_path / "k.json", fs=1000.0)
    f = np.geomspace(0.01, 499, 20000)
    peak = f[np.argmax(np.linalg.norm(freqresp_array(K, f), ord=2, axis=(1, 2)))]
    assert rep.crossover_hz == pytest.approx(peak, rel=2e-3)
    # the 0.2 %-damped 42 Hz resonance moves by (w T)^2 / 12 ~ 0.6 % under Tustin: a big error at its peak
    assert rep.discretization_error > 0.5
    fixed = _export(
        K, tmp_path / "p.json", fs=1000.0, prewarp_hz=rep.crossover_hz, crossover_hz=rep.crossover_hz
    )
    assert fixed.discretization_error < 1e-9


def test_already_discrete_controller_exports_without_error_figure(tmp_path):
    Kd = rc.discretize(lqg_controller(), 200.0)
    rep = _export(Kd, tmp_path / "k.json")
    assert rep.method is None and rep.discretization_error is None and rep.fs_hz == 200.0
    with pytest.raises(DataError, match="already discrete"):
        _export(Kd, tmp_path / "k2.json", fs=100.0)


def _badly_scaled(K):
    T = np.diag(10.0 ** np.linspace(-3, 3, K.nstates))
    Ti = np.linalg.inv(T)
    return control.ss(Ti @ K.A @ T, Ti @ K.B, K.C @ T, K.D, inputs=K.input_labels, outputs=K.output_labels)


@pytest.mark.parametrize("balance", [True, "diagonal", "balanced"])
def test_balancing_reduces_dynamic_range_and_keeps_the_response(tmp_path, balance):
    K = _badly_scaled(lqg_controller(2))
    rep = _export(K, tmp_path / "k.json", fs=200.0, balance=balance)
    plain = _export(K, tmp_path / "p.json", fs=200.0)
    assert plain.dynamic_range_balanced is None and rep.dynamic_range == plain.dynamic_range
    assert rep.dynamic_range_balanced < rep.dynamic_range / 100
    mats = [getattr(rep.controller, k) for k in "ABCD"]
    assert rep.dynamic_range_balanced == pytest.approx(rc.export.dynamic_range(*mats))
    assert _rel_response_error(plain.controller, rep.controller) < 1e-11
    if balance == "balanced":  # equal, diagonal discrete Gramians
        A, B, C = mats[:3]
        P = sla.solve_discrete_lyapunov(A, B @ B.T)
        Q = sla.solve_discrete_lyapunov(A.T, C.T @ C)
        assert np.max(np.abs(P - Q)) < 1e-9 * np.max(np.abs(P))
        assert np.max(np.abs(P - np.diag(np.diag(P)))) < 1e-9 * np.max(np.abs(P))
    else:  # a power-of-two diagonal similarity: C x A scaled exactly
        d = np.abs(rep.controller.C[0] / plain.controller.C[0])
        assert np.all(np.log2(d[np.isfinite(d) & (d > 0)]) % 1 == 0)


def test_balanced_refuses_non_minimal(tmp_path):
    K = lqg_controller()
    # a second copy of the states that no input reaches: not controllable, not minimal
    doubled = control.ss(sla.block_diag(K.A, K.A), np.vstack([K.B, 0 * K.B]), np.hstack([K.C, K.C]), K.D)
    with pytest.raises(ModelError, match="minimal"):
        _export(doubled, tmp_path / "k.json", fs=200.0, balance="balanced")


# ---------------------------------------------------------------------------- bad input
def test_bad_arguments_are_refused(tmp_path):
    K = light_controller()
    cases = [
        (dict(path=tmp_path / "k.txt", fs=100.0), "extension"),
        (dict(path=tmp_path / "k.json", fs=100.0, format="xls"), "format must be one of"),
        (dict(path=tmp_path / "k.json", fs=-1.0), "fs must be"),
        (dict(path=tmp_path / "k.json", fs=100.0, crossover_hz=60.0), "Nyquist"),
        (dict(path=tmp_path / "k.json", fs=100.0, provenance=["x"]), "provenance must be a dict"),
        (dict(path=tmp_path / "k.json", fs=100.0, units="m"), "units must be a dict"),
        (dict(path=tmp_path / "k.json", fs=100.0, balance="yes"), "balance must be one of"),
        (dict(path=tmp_path / "k.json", fs=100.0, on_unstable="maybe"), "on_unstable"),
        (dict(path=tmp_path / "k.h", fs=100.0, prefix="2 bad"), "not a C identifier"),
        (dict(path=tmp_path / "k.json", fs=100.0, prefix="K"), "format 'h'"),
        (dict(path=tmp_path / "missing" / "k.json", fs=100.0), "does not exist"),
        (dict(path=42, fs=100.0), "path must be"),
    ]
    for kwargs, message in cases:
        with pytest.raises(DataError, match=message):
            _export(K, **kwargs)
    with pytest.raises(rc.RobustctlError, match="cannot convert"):
        _export("not a system", tmp_path / "k.json", fs=100.0)
    assert sorted(os.listdir(tmp_path)) == []


def _corrupt_json(doc):
    doc["A"][0] = doc["A"][0][:-1]


@pytest.mark.parametrize(
    "edit,message",
    [
        (_corrupt_json, "A must be a matrix of numbers"),
        (lambda d: d.update(fs_hz=100.0), "disagree"),
        (lambda d: d.pop("D"), "lacks the field"),
        (lambda d: d.update(format="other"), "format"),
        (lambda d: d["B"][0].__setitem__(0, "x"), "matrix of numbers"),
        (lambda d: d.update(inputs=["only one"]), "inputs must be 2 names"),
        (lambda d: d.update(n_states=-1), "whole number"),
        (lambda d: d.update(version=99), "newer than this robustctl"),
    ],
)
def test_load_refuses_hand_edited_json(tmp_path, edit, message):
    rep = _export(light_controller(), tmp_path / "k.json", fs=1000.0)
    doc = json.loads(rep.path.read_text())
    edit(doc)
    rep.path.write_text(json.dumps(doc))
    with pytest.raises(DataError, match=message):
        rc.load_controller(rep.path)


def test_load_refuses_corrupt_files(tmp_path):
    K = light_controller()
    csv_path = _export(K, tmp_path / "k.csv", fs=1000.0).path
    lines = csv_path.read_text().splitlines()
    csv_path.write_text("\n".join(ln for ln in lines if not ln.startswith("A,3,4,")))
    with pytest.raises(DataError, match=r"A\[3,4\] is missing"):
        rc.load_controller(csv_path)
    csv_path.write_text("\n".join(ln.replace("C,1,2,", "C,1,9,") for ln in lines))
    with pytest.raises(DataError, match="C column index '9'"):
        rc.load_controller(csv_path)
    h_path = _export(K, tmp_path / "k.h", fs=1000.0).path
    text = h_path.read_text()
    start = text.index("static const double K_B[16] = {") + len("static const double K_B[16] = {")
    h_path.write_text(text[:start] + text[text.index(",", start) + 1 :])  # drop one coefficient of B
    with pytest.raises(DataError, match="array B holds 15 values"):
        rc.load_controller(h_path)
    mat_path = tmp_path / "bad.mat"
    savemat(mat_path, {"A": np.eye(3), "B": np.ones((2, 1)), "C": np.ones((1, 3)), "D": 0.0, "Ts": 0.01})
    with pytest.raises(DataError, match="B has shape"):
        rc.load_controller(mat_path)
    (tmp_path / "junk.mat").write_bytes(b"not a mat file at all")
    with pytest.raises(DataError, match="junk.mat"):
        rc.load_controller(tmp_path / "junk.mat")
    sos_path = _export(notch_lead(), tmp_path / "k.sos", fs=1000.0).path
    sos_path.write_text(sos_path.read_text() + "1.0,2.0\n")
    with pytest.raises(DataError, match="expected 6"):
        rc.load_controller(sos_path)
    with pytest.raises(DataError, match="no such file"):
        rc.load_controller(tmp_path / "absent.json")
    with pytest.raises(DataError, match="cannot tell the format"):
        rc.load_controller(tmp_path / "k.txt")


# ---------------------------------------------------------------------------- a real C client
def _run_c_client(tmp_path, K, fs, n_samples=3000, **kw):
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip(
            "no C compiler (cc/gcc/clang) on PATH: install one (e.g. apt-get install gcc) "
            "to run the exported-header client test"
        )
    rep = _export(K, tmp_path / "kctl.h", fs=fs, **kw)
    exe = tmp_path / "run_controller"
    subprocess.run(
        [
            cc,
            "-std=c99",
            "-O2",
            "-Wall",
            "-Wextra",
            "-pedantic",
            "-Werror",
            "-I",
            str(tmp_path),
            str(C_CLIENT),
            "-o",
            str(exe),
            "-lm",
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    rng = np.random.default_rng(11)
    t = np.arange(n_samples) / fs
    u = rng.normal(size=(n_samples, K.ninputs)) + np.sin(2 * np.pi * 3.0 * t)[:, None] + (t > 1)[:, None]
    np.savetxt(tmp_path / "u.txt", u, fmt="%.17g")
    out = subprocess.run(
        [str(exe), str(tmp_path / "u.txt")], check=True, capture_output=True, text=True, timeout=120
    ).stdout
    y = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
    Kd = rep.controller
    _, y_ref, _ = dlsim((Kd.A, Kd.B, Kd.C, Kd.D, Kd.dt), u)
    scale = np.max(np.abs(y_ref))
    p = K.noutputs
    assert y.shape == (n_samples, 2 * p)
    return np.max(np.abs(y[:, :p] - y_ref)) / scale, np.max(np.abs(y[:, p:] - y_ref)) / scale


@pytest.mark.parametrize(
    "case,balance", [("lqg", False), ("lqg", "balanced"), ("light", False), ("light", True)]
)
def test_c_client_matches_dlsim(tmp_path, case, balance):
    K, fs = (lqg_controller(), 200.0) if case == "lqg" else (light_controller(), 1000.0)
    err_double, err_float = _run_c_client(tmp_path, K, fs, balance=balance)
    assert err_double < 1e-9, f"double error {err_double:.3g} relative to the output's peak"
    assert err_float < 1e-4, f"float error {err_float:.3g} relative to the output's peak"


WEIRD = ["a,b", 'say "hi"', "back\\slash", "Δx [m/s²]", "end */ of comment", "two\nlines"]


@pytest.mark.parametrize("fmt", [*FORMATS, "sos"])
def test_signal_names_survive_every_format(tmp_path, fmt):
    """Commas, quotes, backslashes, non-ASCII, a C comment terminator and a newline in names."""
    rng = np.random.default_rng(4)
    n_in, n_out = (1, 1) if fmt == "sos" else (3, 3)
    sys = control.rss(4, n_out, n_in)
    A = sys.A - (np.max(np.linalg.eigvals(sys.A).real) + 1.0) * np.eye(4)
    K = control.ss(
        A, sys.B, sys.C, rng.normal(size=(n_out, n_in)), inputs=WEIRD[:n_in], outputs=WEIRD[-n_out:]
    )
    rep = _export(K, tmp_path / f"k.{fmt}", fs=100.0, provenance={"note": "a */ in provenance"})
    back = rc.load_controller(rep.path)
    assert back.input_labels == WEIRD[:n_in] and back.output_labels == WEIRD[-n_out:]
    # sections are a different realisation: exact only to their own fidelity (sos_error)
    assert _rel_response_error(rep.controller, back) < (1e-12 if fmt != "sos" else 1e-9)


def test_header_compiles_with_weird_names_and_refuses_float_overflow(tmp_path):
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH")
    K = control.ss(
        [[-1.0]], [[1.0, 2.0]], [[1.0], [3.0]], np.zeros((2, 2)), inputs=WEIRD[:2], outputs=WEIRD[-2:]
    )
    rep = _export(K, tmp_path / "kctl.h", fs=10.0, provenance={"note": "*/ #endif"})
    subprocess.run(
        [cc, "-std=c99", "-Wall", "-Werror", "-fsyntax-only", "-x", "c", str(rep.path)],
        check=True,
        capture_output=True,
        timeout=60,
    )
    huge = control.ss([[-1.0]], [[1e40]], [[1.0]], 0.0)
    with pytest.raises(DataError, match="float range"):
        _export(huge, tmp_path / "huge.h", fs=10.0)
    assert not (tmp_path / "huge.h").exists()


def test_sos_of_a_zero_channel_and_of_a_static_gain(tmp_path):
    K = control.ss(
        np.diag([-1.0, -2.0]),
        [[1, 0], [1, 0]],
        np.eye(2),
        [[0, 0], [0, 0.5]],
        inputs=["a", "b"],
        outputs=["c", "d"],
    )
    zero = _export(K, tmp_path / "z.sos", fs=10.0, channel=("c", "b"))
    assert zero.sos_error == 0.0 and np.max(np.abs(freqresp_array(rc.load_controller(zero.path), [1.0]))) == 0
    gain = _export(K, tmp_path / "g.sos", fs=10.0, channel=("d", "b"))
    back = rc.load_controller(gain.path)
    assert back.nstates == 0 and back.D[0, 0] == 0.5 and gain.sos_error < 1e-15


# ---------------------------------------------------------------------------- command line
def test_cli_export_discretises_a_users_mat_file(tmp_path, capsys):
    from robustctl.cli import main

    K = lqg_controller()
    savemat(tmp_path / "K.mat", {"A": K.A, "B": K.B, "C": K.C, "D": K.D, "Ts": 0.0})
    args = [
        str(tmp_path / "K.mat"),
        str(tmp_path / "K.h"),
        "--fs",
        "200",
        "--prewarp-hz",
        "2.5",
        "--balance",
        "diagonal",
    ]
    assert main(["export", *args]) == 0
    out = capsys.readouterr().out
    assert "controller written to" in out and "dynamic range after diagonal balancing" in out
    back = rc.load_controller(tmp_path / "K.h")
    ref = rc.discretize(K, 200.0, prewarp_hz=2.5)
    assert _rel_response_error(ref, back) < 1e-12
    assert main(["export", *args]) == 2  # exists: refused without --overwrite
    assert "already exists" in capsys.readouterr().err
    assert main(["export", *args, "--overwrite"]) == 0
    assert main(["export", str(tmp_path / "K.h"), str(tmp_path / "K1.sos"), "--channel", "y[1]", "u[0]"]) == 0
    assert rc.load_controller(tmp_path / "K1.sos").output_labels == ["y[1]"]


def test_gramian_factors_with_and_without_slycot(monkeypatch):
    from robustctl.export import realization

    Kd = rc.discretize(lqg_controller(1), 200.0)
    A, B, C = (np.asarray(m) for m in (Kd.A, Kd.B, Kd.C))
    P = sla.solve_discrete_lyapunov(A, B @ B.T)
    Q = sla.solve_discrete_lyapunov(A.T, C.T @ C)
    for fallback in (False, True):
        if fallback:
            monkeypatch.setattr(realization, "hammarling_factor", lambda *a, **k: None)
        Lc = realization._gramian_factor(A, B, observability=False)
        Lo = realization._gramian_factor(A, C, observability=True)
        assert np.max(np.abs(Lc @ Lc.T - P)) < 1e-8 * np.max(np.abs(P))
        assert np.max(np.abs(Lo @ Lo.T - Q)) < 1e-8 * np.max(np.abs(Q))


def test_format_argument_for_other_file_names(tmp_path):
    rep = _export(notch_lead(), tmp_path / "coefficients.txt", fs=1000.0, format="SOS")
    assert rep.format == "sos"
    with pytest.raises(DataError, match="cannot tell the format"):
        rc.load_controller(rep.path)
    back = rc.load_controller(rep.path, format="sos")
    assert _rel_response_error(rep.controller, back) < 1e-9
    rep = _export(lqg_controller(), tmp_path / "k.json", fs=200.0, format="csv")  # the content decides
    assert rc.load_controller(rep.path, format="csv").nstates == 12
    with pytest.raises(DataError, match="not valid JSON"):
        rc.load_controller(rep.path)


# ---------------------------------------------------------------------------- property: exact numbers
_VALUES = st.one_of(
    st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, -0.0, 5e-324, 2.2250738585072014e-308, 0.1, 1 / 3, -1e-300]),
)


@st.composite
def _controller_data(draw, float_range: bool):
    n, m, p = draw(st.integers(0, 3)), draw(st.integers(1, 3)), draw(st.integers(1, 3))
    values = _VALUES.filter(lambda v: abs(v) < 3e38) if float_range else _VALUES
    mats = [
        np.array(draw(st.lists(values, min_size=r * c, max_size=r * c)), dtype=float).reshape(r, c)
        for r, c in ((n, n), (n, m), (p, n), (p, m))
    ]
    dt = draw(st.floats(1e-6, 10.0))
    names = {
        k: tuple(f"{k[0]}{i}" for i in range(c)) for k, c in (("inputs", m), ("outputs", p), ("states", n))
    }
    return controller_data.ControllerData(*mats, dt, **names)


@pytest.mark.parametrize("fmt", FORMATS)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_every_double_survives_the_file_bit_exact(tmp_path, fmt, data):
    ctrl = data.draw(_controller_data(float_range=fmt == "h"))
    path = tmp_path / f"k.{fmt}"
    formats.WRITERS["." + fmt](ctrl, path, prefix="K")
    back = formats.READERS["." + fmt](path)
    for key in "ABCD":
        a, b = getattr(ctrl, key), getattr(back, key)
        assert a.shape == b.shape and a.tobytes() == b.tobytes(), key  # bit-exact, the sign of -0.0 too
    assert back.dt == ctrl.dt
    path.unlink()


def test_c_client_skips_with_a_message_without_a_compiler(tmp_path, monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(pytest.skip.Exception, match="no C compiler"):
        _run_c_client(tmp_path, notch_lead(), 1000.0)


def test_report_table_summary_and_html(tmp_path):
    result = SimpleNamespace(K=lqg_controller(), gamma=2.5, mu_peak=0.9)
    rep = _export(result, tmp_path / "k.sos", fs=200.0, channel=(1, 0), balance="diagonal", crossover_hz=2.0)
    rows = dict(rep.table().rows)
    assert rows["SOS channel (output <- input)"] == "force_2 <- disp_1"
    assert rows["gamma"] == 2.5 and rows["mu peak"] == 0.9 and rows["stable"] is True
    assert rows["relative discretisation error"] == rep.discretization_error
    assert rows["dynamic range after diagonal balancing"] == rep.dynamic_range_balanced
    text = rep.summary()
    assert "stable" in text and f"{100 * rep.discretization_error:.3g} % at 2 Hz" in text
    assert "<table>" in rep._repr_html_() and "force_2" in rep._repr_html_()
