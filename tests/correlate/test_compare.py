"""rc.compare: MACE eq. 5 cost per channel, worst bands, Table-1 mode table and the
sensor / actuator / structural split of the log error, on a 3-DOF spring-mass chain."""

from __future__ import annotations

import control
import matplotlib
import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.comparison import compare, error_structure, peak_pick_modes
from robustctl.modes import mac

matplotlib.use("Agg")

NOM3 = dict(k1=1000.0, k2=1000.0, k3=1000.0, m1=1.0, m2=1.0, m3=1.0, c=0.4)
F = np.linspace(0.5, 15.0, 600)


def _mats(th):
    k = [th["k1"], th["k2"], th["k3"]]
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    return np.diag([th["m1"], th["m2"], th["m3"]]), K, th["c"] * np.eye(3)


def chain3(**values) -> rc.PhysicalModel:
    """Ground-k1-m1-k2-m2-k3-m3, forces f1..f3 in, displacements x1..x3 out."""
    vals = {**NOM3, **values}
    params = [rc.Parameter(n, x, bounds=(0.0, np.inf)) for n, x in vals.items()]

    def dynamics(th, _struct):
        M, K, C = _mats(th)
        Mi = np.linalg.inv(M)
        A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ K, -Mi @ C]])
        B = np.vstack([np.zeros((3, 3)), Mi])
        Cy = np.hstack([np.eye(3), np.zeros((3, 3))])
        return control.ss(A, B, Cy, np.zeros((3, 3)), inputs=["f1", "f2", "f3"], outputs=["x1", "x2", "x3"])

    return rc.PhysicalModel(params=params, dynamics=dynamics, name="3-dof chain")


@pytest.fixture(scope="module")
def model():
    return chain3()


@pytest.fixture(scope="module")
def nominal(model):
    return model.freqresp(F)


def test_cost_equals_direct_sum(model, nominal):
    rng = np.random.default_rng(0)
    g = nominal.response * np.exp(
        0.1 * (rng.standard_normal(nominal.shape) + 1j * rng.standard_normal(nominal.shape))
    )
    cmp = compare(model, nominal.replace(response=g), band=(1.0, 12.0))
    keep = (F >= 1.0) & (F <= 12.0)
    direct = np.sum(np.abs(np.log(g[keep] / nominal.response[keep])) ** 2)
    assert cmp.cost == pytest.approx(direct, rel=1e-9)
    assert cmp.channel_cost.sum() == pytest.approx(cmp.cost, rel=1e-12)
    assert cmp.cost_per_point == pytest.approx(direct / (keep.sum() * 9))
    assert np.allclose(cmp.mag_error_db, 20 * np.log10(np.abs(g[keep] / nominal.response[keep])))
    assert len(cmp.table().rows) == 9


def test_output_gain_error_is_sensor_side(model, nominal):
    g = nominal.response.copy()
    g[:, 1, :] *= 1.2
    s = compare(model, nominal.replace(response=g)).structure
    assert s.kind == "sensor" and s.dominant_output == "x2"
    assert s.sensor == pytest.approx(2 / 3) and s.interaction < 1e-12
    assert "sensor-side" in s.describe() and "'x2'" in s.describe()


def test_input_delay_is_actuator_side(model, nominal):
    g = nominal.response * np.exp(-2j * np.pi * F * 0.005)[:, None, None] ** np.array([0, 0, 1])
    s = compare(model, nominal.replace(response=g)).structure
    assert s.kind == "actuator" and s.dominant_input == "f3"
    assert s.actuator == pytest.approx(2 / 3)


def test_delay_on_every_channel_is_common(model, nominal):
    g = nominal.response * np.exp(-2j * np.pi * F * 0.004)[:, None, None]
    s = compare(model, nominal.replace(response=g)).structure
    assert s.kind == "common"
    assert s.common_delay_s == pytest.approx(0.004, rel=1e-6)


def test_stiffness_error_is_structural_and_worst_band_covers_shifted_mode(model):
    data = chain3(k2=1060.0).freqresp(F)
    cmp = compare(model, data)
    assert cmp.structure.kind == "structural"
    assert "structural" in cmp.summary()
    # mode table: three modes, paired by peak picking, frequencies within the grid step
    truth = [m.f_model for m in compare(chain3(k2=1060.0), data).modes]
    assert len(cmp.modes) == 3 and cmp.mode_source == "peak picking"
    for row, f_true in zip(cmp.modes, truth):
        assert abs(row.f_data - f_true) < F[1] - F[0]
        assert row.mac > 0.99
    worst = max(cmp.modes, key=lambda r: abs(r.f_error_pct))
    b = cmp.bands[0]
    assert b.lo_hz <= min(worst.f_model, worst.f_data) and max(worst.f_model, worst.f_data) <= b.hi_hz
    assert b.share > 0.5


def test_mode_table_from_measurement_model_is_exact(model):
    truth = chain3(k2=1060.0)
    data = truth.freqresp(F)
    cmp = compare(model, data, measurement_model=truth.statespace())
    lam = np.linalg.eigvals(np.asarray(truth.statespace().A))
    lam = lam[lam.imag > 0]
    f_true = np.sort(np.abs(lam) / (2 * np.pi))
    assert cmp.mode_source == "measurement model"
    assert np.allclose([r.f_data for r in cmp.modes], f_true, rtol=1e-9)
    tab = cmp.mode_table()
    assert tab.columns[:4] == ("mode", "f model (Hz)", "f data (Hz)", "f error (%)")
    # sign convention of MACE Table 1: (data - model) / model; stiffer data -> positive
    assert all(e > 0 for e in tab.column("f error (%)"))
    # any system is a measurement model (one coercion, rc.as_statespace): a PhysicalModel too
    cmp2 = compare(model, data, measurement_model=truth)
    assert [r.f_data for r in cmp2.modes] == [r.f_data for r in cmp.modes]


def test_peak_picking_half_power_damping():
    f = np.linspace(5.0, 15.0, 4001)
    fn, zeta = 10.0, 0.02
    s = 2j * np.pi * f
    wn = 2 * np.pi * fn
    g = (1.0 / (s**2 + 2 * zeta * wn * s + wn**2))[:, None, None]
    (mode,) = peak_pick_modes(f, g)
    assert mode.f_hz == pytest.approx(fn * np.sqrt(1 - 2 * zeta**2), rel=1e-4)
    assert mode.zeta == pytest.approx(zeta, rel=0.02)


def test_mac_and_structure_units():
    a = np.array([1.0, 2.0, -1.0])
    assert mac(a, (3 - 2j) * a) == pytest.approx(1.0)
    assert mac(a, np.array([2.0, -1.0, 0.0])) == pytest.approx(0.0)
    e = np.zeros((4, 2, 2), complex)
    e[:, 0, 1] = 1.0  # one channel only: neither a row nor a column
    s = error_structure(e, np.ones(4), ["a", "b"], ["u", "v"])
    assert s.common + s.sensor + s.actuator + s.interaction == pytest.approx(1.0)
    assert s.interaction == pytest.approx(0.25)


def test_plot_summary_and_html(model):
    import matplotlib.pyplot as plt

    cmp = compare(model, chain3(k2=1060.0).freqresp(F))
    open_before = len(plt.get_fignums())
    fig = cmp.plot()
    assert len(plt.get_fignums()) == open_before  # a plain Figure (robustctl.plots), no pyplot state
    assert len(fig.axes) == 9 + 2  # 3x3 channels, the error map and its colour bar
    assert "<table>" in cmp._repr_html_()
    assert "cost J" in cmp.summary()

    plt.close(fig)


def test_compare_bad_input(model, nominal):
    with pytest.raises(rc.DataError, match=r"holds 0 data point"):
        compare(model, nominal, band=(30.0, 40.0))
    with pytest.raises(rc.DataError, match=r"inputs .* do not match the data"):
        compare(model, nominal.replace(inputs=["a", "b", "c"]))
    with pytest.raises(rc.DataError, match=r"threshold_db must be positive"):
        compare(model, nominal, threshold_db=0.0)
    # NaN used to pass the check and silently find no failing band; a negative n_bands
    # silently dropped the last band(s) (bands[:n_bands])
    with pytest.raises(rc.DataError, match=r"threshold_db must be positive"):
        compare(model, nominal, threshold_db=float("nan"))
    with pytest.raises(rc.DataError, match=r"n_bands must be"):
        compare(model, nominal, n_bands=-1)


def test_mode_table_with_fitted_measurement_model(model):
    """rc.fit_measurement_model's .modes pair with the model modes, in any channel order."""
    data = chain3(k2=1060.0).freqresp(F)
    mm = rc.fit_measurement_model(data, n_modes=3)
    exact = compare(model, data, measurement_model=chain3(k2=1060.0).statespace())
    swapped = data.select(outputs=["x3", "x1", "x2"], inputs=["f2", "f3", "f1"])
    for d in (data, swapped):
        cmp = compare(model, d, measurement_model=mm)
        assert [r.f_data for r in cmp.modes] == pytest.approx([r.f_data for r in exact.modes], rel=1e-4)
        assert all(r.mac > 0.99 for r in cmp.modes)
