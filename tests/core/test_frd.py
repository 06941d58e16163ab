"""FrequencyData core: validation with clear messages, views, python-control conversion."""

from __future__ import annotations

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import DataError


@pytest.fixture
def data():
    f = np.array([1.0, 2.0, 5.0, 10.0])
    g = np.arange(24).reshape(4, 2, 3) + 1j
    return rc.FrequencyData(f, g, inputs=["F1", "F2", "F3"], outputs=["a1", "a2"],
                            coherence=np.full(g.shape, 0.9), units={"a1": "m/s^2"}, meta={"src": "test"})


def test_shapes_names_and_views(data):
    assert data.shape == (4, 2, 3) and data.n_freq == 4 and data.n_out == 2 and data.n_in == 3
    np.testing.assert_allclose(data.w, 2 * np.pi * data.f_hz)
    sub = data.select(outputs="a2", inputs=["F3", 0])
    assert sub.outputs == ("a2",) and sub.inputs == ("F3", "F1")
    np.testing.assert_array_equal(sub.response[:, 0, :], data.response[:, 1][:, [2, 0]])
    band = data.band(2.0, 5.0)
    np.testing.assert_array_equal(band.f_hz, [2.0, 5.0])
    assert band.coherence.shape == (2, 2, 3) and band.meta == {"src": "test"}
    siso = rc.FrequencyData([1.0, 2.0], [1.0, 2.0 + 1j])
    assert siso.shape == (2, 1, 1) and siso.inputs == ("u1",) and siso.outputs == ("y1",)
    assert "4 points" in repr(data) and "with coherence" in repr(data)
    with pytest.raises(ValueError):
        data.response[0, 0, 0] = 1.0  # read-only


def test_control_round_trip(data):
    frd = data.to_control()
    back = rc.FrequencyData.from_control(frd)
    np.testing.assert_allclose(back.f_hz, data.f_hz, rtol=1e-15)
    np.testing.assert_array_equal(back.response, data.response)
    assert back.inputs == data.inputs and back.outputs == data.outputs
    sys = control.tf([1.0], [1.0, 1.0])
    ref = control.frequency_response(sys, 2 * np.pi * np.array([0.5, 1.0]))
    fd = rc.FrequencyData.from_control(control.frd(ref))
    np.testing.assert_allclose(fd.response[:, 0, 0], 1 / (2j * np.pi * np.array([0.5, 1.0]) + 1), rtol=1e-12)


def test_bad_input_messages():
    with pytest.raises(DataError, match="response contains NaN or inf"):
        rc.FrequencyData([1.0, 2.0], [1.0, np.nan])
    with pytest.raises(DataError, match="response contains NaN or inf"):
        rc.FrequencyData([1.0, 2.0], [1.0, np.inf])
    with pytest.raises(DataError, match="f_hz contains NaN or inf"):
        rc.FrequencyData([1.0, np.nan], [1.0, 2.0])
    with pytest.raises(DataError, match="strictly increasing"):
        rc.FrequencyData([2.0, 1.0], [1.0, 2.0])
    with pytest.raises(DataError, match="strictly increasing"):
        rc.FrequencyData([1.0, 1.0], [1.0, 2.0])
    with pytest.raises(DataError, match="must be positive"):
        rc.FrequencyData([0.0, 1.0], [1.0, 2.0])
    with pytest.raises(DataError, match="f_hz is empty"):
        rc.FrequencyData([], [])
    with pytest.raises(DataError, match="response has 3 frequency points but f_hz has 2"):
        rc.FrequencyData([1.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(DataError, match=r"shape \(n_freq, n_out, n_in\)"):
        rc.FrequencyData([1.0, 2.0], np.ones((2, 2)))
    with pytest.raises(DataError, match="inputs has 2 names but the response has 1 inputs"):
        rc.FrequencyData([1.0], [1.0], inputs=["a", "b"])
    with pytest.raises(DataError, match=r"names must be unique; repeated: \['y'\]"):
        rc.FrequencyData([1.0], np.ones((1, 2, 1)), outputs=["y", "y"])
    with pytest.raises(DataError, match=r"coherence has shape \(2, 1, 1\) but response has shape"):
        rc.FrequencyData([1.0], [1.0], coherence=np.ones((2, 1, 1)))
    with pytest.raises(DataError, match=r"coherence must be finite and lie in \[0, 1\]"):
        rc.FrequencyData([1.0], [1.0], coherence=[1.5])


def test_bad_views(data):
    with pytest.raises(DataError, match="holds 0 data points"):
        data.band(20.0, 30.0)
    with pytest.raises(DataError, match="is empty or not finite; give finite f_lo_hz < f_hi_hz"):
        data.band(5.0, 2.0)
    with pytest.raises(DataError, match=r"unknown output 'zz'; the data has outputs \['a1', 'a2'\]"):
        data.select(outputs="zz")
    with pytest.raises(DataError, match="inputs index 5 is out of range"):
        data.select(inputs=[5])
    with pytest.raises(DataError, match="needs a control.FrequencyResponseData"):
        rc.FrequencyData.from_control(3.0)
