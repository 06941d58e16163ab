"""Peak picking in ``compare`` on data whose cross channels are decoupled by symmetry: those
channels hold round-off of the others, whose peaks are set by rounding. The truth and its
measurement are written here with numpy (two uncoupled axes, 1 % multiplicative noise)."""

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.correlate.comparison import peak_pick_modes
from robustctl.errors import DataError

#: (Hz, damping ratio) of each axis's modes
AXIS_MODES = (((2.0, 0.02), (5.0, 0.01)), ((3.0, 0.015), (7.0, 0.01)))
F_HZ = np.linspace(0.5, 10.0, 400)


def _axis(modes) -> control.StateSpace:
    """A sum of modes of unit static gain each: w^2 / (s^2 + 2 z w s + w^2)."""
    out = 0
    for f, z in modes:
        w = 2 * np.pi * f
        out = out + control.tf([w**2], [1, 2 * z * w, w**2])
    return control.ss(out)


def _data(seed: int) -> tuple[control.StateSpace, rc.FrequencyData]:
    """Diagonal 2 x 2 truth; the cross channels carry 1e-15 of the direct ones, drawn at random
    (round-off of a solve that does not decouple exactly); 1 % complex log-normal noise."""
    rng = np.random.default_rng(seed)
    axes = [_axis(m) for m in AXIS_MODES]
    truth = control.append(*axes)
    s = 2j * np.pi * F_HZ
    g = np.zeros((F_HZ.size, 2, 2), dtype=complex)
    for k, ax in enumerate(axes):
        g[:, k, k] = np.squeeze(ax(s))
    scale = np.max(np.abs(g), axis=(1, 2))
    g[:, 0, 1] = 1e-15 * scale * (rng.standard_normal(F_HZ.size) + 1j * rng.standard_normal(F_HZ.size))
    g[:, 1, 0] = 1e-15 * scale * (rng.standard_normal(F_HZ.size) + 1j * rng.standard_normal(F_HZ.size))
    g *= np.exp(0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    return truth, rc.FrequencyData(F_HZ, g, outputs=("y1", "y2"), inputs=("u1", "u2"))


def test_round_off_channels_do_not_make_peaks_and_the_mode_table_is_the_measured_channels():
    tables = []
    for seed in (0, 1, 2):
        truth, data = _data(seed)
        cmp = rc.compare(truth, data)
        f_data = np.array([m.f_data for m in cmp.modes if np.isfinite(m.f_data)])
        # the four modes, each picked within a line (0.024 Hz), and nothing else
        assert f_data.size == 4, f_data
        assert np.allclose(f_data, [2.0, 3.0, 5.0, 7.0], atol=F_HZ[1] - F_HZ[0]), f_data
        tables.append(f_data)
        # all channels summed, the round-off channels (normalised to the weight of measured ones)
        # add peaks of their own: the case is one the channel choice decides
        everything = [m.f_hz for m in peak_pick_modes(data.f_hz, data.response)]
        assert len(everything) > 4
    # the round-off channels' draw no longer moves the table (the direct channels' noise is drawn
    # from the same stream, so only the measured channels' own noise moves it, within a line)
    assert np.ptp(np.array(tables), axis=0).max() < F_HZ[1] - F_HZ[0]


@pytest.mark.parametrize("channels", [np.ones(4, bool), np.ones((2, 2)), np.zeros((2, 2), bool)])
def test_a_channel_mask_of_the_wrong_shape_type_or_empty_is_refused(channels):
    _, data = _data(0)
    with pytest.raises(DataError, match="boolean array of shape"):
        peak_pick_modes(data.f_hz, data.response, channels=channels)
