"""A channel that is identically zero in the data (a dead or disconnected sensor or actuator) is
flagged, not silently taken for a decoupled axis, and does not poison the headline numbers.

Truth and data are written here with numpy: the receptance of a 2-DOF spring-mass chain."""

from __future__ import annotations

import numpy as np
import pytest
from test_residual import NOMINAL, analytic_receptance, chain_model

import robustctl as rc

F_HZ = np.linspace(0.5, 12.0, 120)


def _data(dead_output=None, dead_input=None):
    rng = np.random.default_rng(3)
    g = analytic_receptance({**NOMINAL, "k2": 2100.0}, F_HZ)
    g = g * (1 + 0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    if dead_output is not None:
        g[:, dead_output, :] = 0.0
    if dead_input is not None:
        g[:, :, dead_input] = 0.0
    return rc.FrequencyData(F_HZ, g, inputs=["f1", "f2"], outputs=["x1", "x2"])


def test_a_dead_sensor_is_flagged_and_the_rms_error_stays_finite():
    data = _data(dead_output=1)
    with pytest.warns(rc.errors.DataWarning, match=r"output x2 \(every input\).*dead or disconnected"):
        cmp = rc.compare(chain_model(), data)
    text = cmp.summary()
    assert "identically zero in the data" in text and "x2 <- f1" in text and "x2 <- f2" in text
    assert "negligible (decoupled)" not in text
    # the RMS figure is over the kept row only: the same as comparing the live row alone
    alone = rc.compare(chain_model().select(outputs=["x1"]), data.select(outputs=["x1"]))
    rms = float(text.split("RMS error ")[1].split(" dB")[0])
    assert np.isfinite(rms)
    assert rms == pytest.approx(np.sqrt(np.mean(alone.mag_error_db**2)), abs=0.006)


def test_update_with_a_dead_actuator_says_so():
    with pytest.warns(rc.errors.DataWarning, match=r"input f2 \(every output\)"):
        upd = rc.update(chain_model(), _data(dead_input=1), params=["k2"], max_iter=20)
    assert any("identically zero in the data" in n and "x1 <- f2" in n for n in upd.notes)
    assert upd.model.param("k2").value == pytest.approx(2100.0, rel=0.01)  # the live column still fits


def test_a_decoupled_but_live_channel_is_not_called_dead(recwarn):
    data = _data()
    data = rc.FrequencyData(F_HZ, data.response * np.array([[1.0, 1e-9], [1.0, 1.0]]),
                            inputs=data.inputs, outputs=data.outputs)
    rc.compare(chain_model(), data)
    assert not [w for w in recwarn if issubclass(w.category, rc.errors.DataWarning)]
