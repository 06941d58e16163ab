"""Measurement models of real measured data (DaISy CD-player arm 2x2, robot arm 1x1).

The data live in ``../shared/data`` next to the repository (see its README and PROVENANCE);
the tests skip when that folder is absent, as in an installed copy. DaISy gives no sampling
time, so ``fs = 1`` and frequencies are in cycles/sample. scikit-rf's VectorFitting (a dev-only
dependency) fits the same FRF for comparison; it minimises the absolute error, so its
log-magnitude error is much larger where the response is small (antiresonances).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import pytest

import robustctl as rc
from robustctl.identify import channel_cost

# next to the repository, or where ROBUSTCTL_SHARED_DATA points (git worktrees live elsewhere)
DATA = Path(os.environ.get("ROBUSTCTL_SHARED_DATA", Path(__file__).parents[2] / ".." / "shared" / "data"))


def _load(name: str) -> np.ndarray:
    path = DATA / name
    if not path.exists():
        pytest.skip(f"real data not found at {path.resolve()} (the shared data folder is absent)")
    return np.loadtxt(path)


def _skrf_model(band: rc.FrequencyData, n_modes: int) -> np.ndarray:
    skrf = pytest.importorskip("skrf", reason="scikit-rf (dev dependency) is needed for the comparison")
    from skrf.vectorFitting import VectorFitting

    logging.getLogger("skrf").setLevel(logging.ERROR)
    net = skrf.Network(frequency=skrf.Frequency.from_f(band.f_hz, unit="hz"), s=band.response)
    vf = VectorFitting(net)
    vf.vector_fit(n_poles_real=0, n_poles_cmplx=n_modes, fit_constant=True, enforce_dc=False)
    g = [[vf.get_model_response(i, j, band.f_hz) for j in range(band.n_in)] for i in range(band.n_out)]
    return np.transpose(np.array(g), (2, 0, 1))


@pytest.fixture(scope="module")
def robot_arm():
    d = _load("daisy_robot_arm/robot_arm.dat")
    return rc.estimate_frf(d[:, 0], d[:, 1], fs=1.0, nperseg=512).band(0.005, 0.2)


@pytest.fixture(scope="module")
def cd_player():
    d = _load("daisy_cd_player_arm/CD_player_arm.dat")
    return rc.estimate_frf(d[:, :2], d[:, 2:], fs=1.0, nperseg=128).band(0.005, 0.3)


def test_robot_arm_measurement_model(robot_arm):
    mm = rc.fit_measurement_model(robot_arm, n_modes=3)
    f = np.array([m.f_hz for m in mm.modes])
    z = np.array([m.zeta for m in mm.modes])
    for f_res in (0.058, 0.127):  # the two resonances of PROVENANCE.md, cycles/sample
        k = np.argmin(np.abs(f - f_res))
        assert abs(f[k] - f_res) / f_res < 0.03 and z[k] < 0.02
    high = robot_arm.coherence > 0.9
    ours = channel_cost(robot_arm.response, mm.fit.response(robot_arm.f_hz), mask=high)
    assert ours.rms_db_total < 1.0
    assert ours.rms_db_total <= 0.731  # no regression (0.731 dB before the finished-candidate choice)
    theirs = channel_cost(robot_arm.response, _skrf_model(robot_arm, 3), mask=high)
    assert ours.rms_db_total < theirs.rms_db_total


@pytest.mark.filterwarnings("ignore::robustctl.identify.IdentifyWarning")
def test_cd_player_arm_measurement_model(cd_player):
    fit = rc.fit_rational(cd_player, 12, method="vf")
    high = cd_player.coherence > 0.9
    ours = channel_cost(cd_player.response, fit.response(cd_player.f_hz), mask=high)
    assert ours.rms_db_total < 2.0
    theirs = channel_cost(cd_player.response, _skrf_model(cd_player, 6), mask=high)
    assert ours.rms_db_total < theirs.rms_db_total
    with pytest.warns(rc.identify.IdentifyWarning) as caught:
        mm = rc.fit_measurement_model(cd_player, n_modes=6)
    # honest mode list: only in-band, lightly damped poles are modes (a 72 %-damped pole at
    # 0.32 cycles/sample, outside the band, used to be listed to make up the six); a shortfall
    # is said with the number the data support
    assert all(0.005 <= m.f_hz <= 0.3 and m.zeta < 0.2 for m in mm.modes)
    # the three resonances above 0.18 cycles/sample pass every test; the peak near 0.105 is fitted
    # by two poles of scattered phase, neither significant and stable alone: fillers, said so
    assert mm.n_modes >= 3
    assert all(mm.evidence.significance[k] >= 1 for k in np.flatnonzero(mm.evidence.physical))
    if mm.n_modes < 6:
        assert any(f"the data support {mm.n_modes} physical" in str(w.message) for w in caught)
    states = sum((2 if m.pole.imag else 1) * m.rank for m in mm.modes + mm.fillers)
    assert mm.sys.nstates == states and mm.sys.ninputs == 2 and mm.sys.noutputs == 2
    assert np.all(np.linalg.eigvals(mm.sys.A).real < 0)
    # the measurement model's accuracy where the data are trustworthy: no regression below the
    # 1.66 dB of the five-modes-plus-real-poles model (1.88 then 2.10 dB with six modes and fillers
    # from a 16-pole start; 1.32 dB with the best finished start)
    mm_high = channel_cost(cd_player.response, mm.fit.response(cd_player.f_hz), mask=high)
    assert mm_high.rms_db_total <= 1.66


def test_missing_data_folder_skips_with_a_clear_message(monkeypatch, tmp_path):
    import sys

    monkeypatch.setattr(sys.modules[__name__], "DATA", tmp_path / "absent")
    with pytest.raises(pytest.skip.Exception, match="real data not found"):
        _load("daisy_robot_arm/robot_arm.dat")
