"""The MACE demo's measurement model (the design half's yardstick) against the truth, and the
warning for modes whose damping the data do not determine."""

import warnings
from dataclasses import replace

import numpy as np
import pytest

from robustctl.identify import IdentifyWarning
from robustctl.identify.measurement_model import pinned_message, pinned_modes
from robustctl.modes import Mode

#: Lightly damped modes of the truth's RWA channels in 1-20 Hz that carry the responses (Hz).
TRUTH_MODES_HZ = (1.386, 3.684, 15.039, 16.974)
#: Channels that carry data (the others are decoupled by symmetry: noise, coherence ~0.02).
COUPLED = ((0, 0), (1, 1), (2, 2), (0, 2), (2, 0))


def test_modes_at_the_damping_bound_are_found_and_named():
    modes = (Mode(3.0, 0.02), Mode(16.87, 1e-6), Mode(15.1, 0.006))
    pinned = pinned_modes(modes)
    assert [m.f_hz for m in pinned] == [16.87]  # 0.6 % is a measurement, 1e-6 the bound
    msg = pinned_message(pinned, leakage_corrected=True)
    assert "16.87 Hz" in msg and "correct_leakage=False" in msg
    assert "resolution" in pinned_message(pinned, leakage_corrected=False)


def _rwa(sys):
    from robustctl.demo_mace import RWA_INPUTS, RWA_OUTPUTS

    return sys.select(outputs=RWA_OUTPUTS, inputs=RWA_INPUTS)


def _twin_bracket(modes, lo: float, hi: float, resolution: float):
    """Two modes of one shape (MAC of their residues above 0.99) on either side of ``lo``-``hi``,
    each within one bin of it, or None."""
    def mac(a, b):
        a, b = np.ravel(a), np.ravel(b)
        return abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real)

    below = [m for m in modes if lo - resolution < m.f_hz < lo]
    above = [m for m in modes if hi < m.f_hz < hi + resolution]
    pairs = [(a.f_hz, b.f_hz) for a in below for b in above if mac(a.residue, b.residue) > 0.99]
    return pairs[0] if pairs else None


@pytest.mark.slow
def test_mace_measurement_model_fits_the_design_channels_near_the_noise_with_physical_modes():
    from robustctl.demo import EXAMPLES
    from robustctl.demo_mace import RWA_INPUTS, RWA_OUTPUTS, _measurement_model
    from robustctl.lti import as_statespace

    data, truth = EXAMPLES["mace"]().experiment(0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IdentifyWarning)
        mm = _measurement_model(data)
    assert not any("damping bound" in str(w.message) for w in caught)
    f = mm.data.f_hz
    model = mm.freqresp(f).response
    true = truth.select(outputs=RWA_OUTPUTS, inputs=RWA_INPUTS).freqresp(f).response
    meas = data.select(outputs=RWA_OUTPUTS, inputs=RWA_INPUTS).response[np.isin(data.f_hz, f)]

    def rms_db(a):
        return float(np.sqrt(np.mean([(20 * np.log10(np.abs(a[:, i, j] / true[:, i, j]))) ** 2
                                      for i, j in COUPLED])))

    # the data sit 1.3-1.5 dB rms off the truth in these channels (noise, and the leakage of peaks
    # narrower than the 0.195 Hz bins, which a fit without the leakage correction reproduces);
    # the model with the leakage correction was 8.1 dB off (x-z coupling 9-15 dB). A model within
    # half the data's own error again of the truth is the fit the design half needs; the failure
    # guarded against is more than 3x beyond that (1.0-1.2x the data's error measured on different
    # BLAS kernels and data draws).
    assert rms_db(meas) > 1.0
    assert rms_db(model) < 1.5 * rms_db(meas)
    f_modes = np.array([m.f_hz for m in mm.modes])
    resolution = float(np.median(np.diff(data.f_hz)))  # 0.195 Hz, wider than the 1.39 Hz peak
    lam = np.linalg.eigvals(np.asarray(as_statespace(truth).A))
    f_all = np.abs(lam) / (2 * np.pi)
    f_all = f_all[(lam.imag > 0) & (-lam.real < 0.2 * np.abs(lam))]
    for f_true in TRUTH_MODES_HZ:
        # a resolution-limited peak is located to a fraction of a bin: a quarter bin. Truth modes
        # within a bin of each other (15.039-15.139 Hz: five modes in half a bin) are one peak of
        # these data: the cluster is located, not each member (14.90 and 15.12 Hz on OpenBLAS's
        # Haswell kernel, 15.04 elsewhere)
        # -- or bracketed: the unresolved peak fitted by a pole within a third of a bin on either
        # side (14.98 and 15.20 Hz around 15.04-15.14 Hz, since the stationary start is drawn
        # independently of the realization)
        cluster = f_all[np.abs(f_all - f_true) < resolution]
        lo, hi = min(cluster.min(), f_true), max(cluster.max(), f_true)
        gap = np.maximum(np.maximum(lo - f_modes, f_modes - hi), 0.0)
        below, above = lo - f_modes[f_modes < lo], f_modes[f_modes > hi] - hi
        bracketed = below.size and above.size and max(below.min(), above.min()) < resolution / 3
        # -- or fitted by a twin: two poles of one shape within a bin on either side, which the fit
        # spends on one peak when n_modes asks for more modes than the data hold (the demo asks 10
        # where 8 are supported, and which outcome a draw gives turns on round-off in the paths of
        # the spare poles, which fit noise): the modelled peak is then the truth's, to a quarter bin
        if not (np.min(gap) < 0.25 * resolution or bracketed):
            pair = _twin_bracket(mm.modes, lo, hi, resolution)
            assert pair is not None, (f_true, cluster, f_modes)
            grid = np.linspace(lo - resolution, hi + resolution, 401)
            peak = [float(grid[np.argmax(np.sum([np.abs(r[:, i, j]) for i, j in COUPLED], axis=0))])
                    for r in (mm.freqresp(grid).response, _rwa(truth).freqresp(grid).response)]
            assert abs(peak[0] - peak[1]) < 0.25 * resolution, (f_true, pair, peak)
    assert all(m.zeta < 0.2 for m in mm.modes)  # heavily damped servo poles are fillers, not modes
    zeta_17 = mm.modes[int(np.argmin(np.abs(f_modes - 16.974)))].zeta
    assert 0.003 < zeta_17 < 0.015  # truth 0.58 %; 0.195 Hz resolution broadens it, never to 0


def test_leakage_correction_consistency_holds_on_caltech_and_fails_on_the_leaking_mace_band():
    """Caltech's correction reaches its fixed point (the model's expected H1 meets the raw data as
    the model meets the corrected data); on MACE's 1-20 Hz band, with the 0.5-0.6 Hz suspension
    modes leaking in from below, the consistency flag and the damping-bound warning are raised
    exactly when their criteria hold, and a model that lacks a mode is flagged."""
    from robustctl.demo import EXAMPLES
    from robustctl.demo_mace import RWA_INPUTS, RWA_OUTPUTS
    from robustctl.identify import fit_measurement_model
    from robustctl.identify.leakage import estimator_settings
    from robustctl.identify.measurement_model import INCONSISTENT_DB, INCONSISTENT_RATIO, leakage_consistency

    data, _ = EXAMPLES["caltech"]().experiment(0)
    mm = fit_measurement_model(data, n_modes=6, band=(0.5, 5.5), correct_leakage=True)
    raw, used = leakage_consistency(mm.fit, mm.raw_data, mm.data, estimator_settings(data.meta), "auto")
    assert abs(raw / used - 1) < 0.1 and used < 0.3

    data, _ = EXAMPLES["mace"]().experiment(0)
    rwa = data.select(outputs=RWA_OUTPUTS, inputs=RWA_INPUTS)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IdentifyWarning)
        mm = fit_measurement_model(rwa, n_modes=8, band=(1.0, 20.0), correct_leakage=True)
    messages = " ".join(str(w.message) for w in caught)
    raw, used = leakage_consistency(mm.fit, mm.raw_data, mm.data, estimator_settings(rwa.meta), "auto")
    # the flag is raised exactly when the expected H1 misses the raw data by clearly more
    flagged = raw > INCONSISTENT_RATIO * used + INCONSISTENT_DB
    assert ("not self-consistent" in messages) == flagged
    assert ("lower damping bound" in messages) == bool(pinned_modes(mm.modes))
    # with every pole's damping kept above the bound in the refinement, the corrected fit keeps
    # the 17 Hz mode (truth 0.58 %, half-power bandwidth about one 0.195 Hz bin) off the bound
    f_modes = np.array([m.f_hz for m in mm.modes])
    zeta_17 = mm.modes[int(np.argmin(np.abs(f_modes - 16.974)))].zeta
    assert 0.003 < zeta_17 < 0.015
    # a model missing what leaks into the band is caught: without its 17 Hz mode the expected H1
    # misses the raw data far more than the corrected data it was scored on claims
    keep = np.abs(mm.fit.f_hz - 16.974) > 0.3
    cut = replace(mm.fit, poles=mm.fit.poles[keep], residues=mm.fit.residues[keep], ranks=mm.fit.ranks[keep])
    raw_cut, _ = leakage_consistency(cut, mm.raw_data, mm.data, estimator_settings(rwa.meta), "auto")
    assert raw_cut > INCONSISTENT_RATIO * used + INCONSISTENT_DB
