"""Impact tests with few hits: the exact truth passes compare within the noise at the designed rate.

With ``n`` hits (one average each) the coherence noise model's sigma is a plug-in from the bin's
own coherence, so a bin's ``t = |e / sigma|^2 / 2`` is ``(n - 2) Exp(1) / Gamma(n - 1)`` (an
F-distributed variable of mean 1, variance 2 at 5 hits, infinite at 3), not the ``Exp(1)`` a
chi-square test assumes. The test sums the exact scores ``(n - 1) ln(1 + t / (n - 2))``
(:func:`robustctl.measure.noise.plug_in_scores`). The hammer records are written with numpy
(closed-form pulse responses of the numpy truths of ``tests/lab_corpus.py`` on a 16x finer grid,
a scipy FIR anti-aliasing filter, white noise on force and responses: ``test_impact_window.hammer``),
never with robustctl's simulator.

The force channel's noise (kept by the force window from the record start to the pulse's end)
enters H1 as a relative error common to every output and correlated over about ``n / (window
length)`` bins (eq. N1 of :func:`robustctl.measure.impact._force_noise`); each cell's
Satterthwaite factor counts it (:func:`robustctl.measure.noise.cell_chi2_factor`).

Designed false-alarm rate: compare's family-wise alpha, 0.01 per data set (Bonferroni over its
cells); over 8 seeds x 3 hit counts = 24 data sets per structure the expected count is 0.24 and
at most two failing data sets are allowed (P(>= 3) = 0.002 at the designed rate; over 100 other
seeds of the beam at 3 hits none failed). The plain chi-square on ``sum t`` failed 9 of 30 mast
and 22 of 30 beam data sets at 3 hits.
"""

from __future__ import annotations

import warnings

import lab_corpus as lc
import numpy as np
import pytest
from scipy import stats
from test_impact_window import BAND, FS, _mass, hammer

import robustctl as rc
from robustctl.measure.noise import chi2_verdict, plug_in_scores

HITS = (3, 5, 10)
SEEDS = range(100, 108)
NOISE = (5e-4, 0.01)  # force: 0.05 % of the peak force; responses: 1 % of their rms


def _compare(structure, n_hits, seed, modify=None):
    F, Y = hammer(structure, n_hits=n_hits, seed=seed, noise=NOISE, modify=modify)
    data = rc.estimate_frf_impact(F, Y, FS, inputs=list(structure.inputs), outputs=list(structure.outputs))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.compare(structure.model(), data, band=BAND)


@pytest.mark.parametrize("n", [3, 5, 10])
def test_the_scores_of_a_plug_in_sigma_are_exactly_exponential(n):
    """Draw ``t = (n - 2) Exp / Gamma(n - 1)`` in numpy: its variance is ``2 (n - 2) / (n - 3) - 1``
    (a chi-square test's Exp(1) has 1), the scores are Exp(1) (KS), and they tend to ``t``."""
    rng = np.random.default_rng(n)
    t = (n - 2) * rng.exponential(size=200_000) / rng.gamma(n - 1, size=200_000)
    x = plug_in_scores(t, n)
    assert abs(t.mean() - 1) < 0.05 and abs(x.mean() - 1) < 0.01 and abs(x.var() - 1) < 0.02
    if n > 3:
        assert abs(t.var() / (2 * (n - 2) / (n - 3) - 1) - 1) < 0.15  # 2.0 at 5 hits, 1.29 at 10
    assert stats.kstest(x, "expon").pvalue > 1e-3
    assert stats.kstest(t, "expon").pvalue < 1e-10
    big = np.linspace(0, 20, 9)
    np.testing.assert_allclose(plug_in_scores(big, 1e7), big, rtol=3e-6, atol=0)


def test_a_cell_of_plug_in_errors_passes_at_its_alpha():
    """10^4 cells of 40 independent points at 3 averages: the exact scores reject at the nominal
    1 %, the plain chi-square of ``sum t`` at 6-7 x that."""
    rng = np.random.default_rng(7)
    n, cells, points = 3, 10_000, 40
    t = (n - 2) * rng.exponential(size=(cells, points)) / rng.gamma(n - 1, size=(cells, points))
    z = np.sqrt(2 * t)
    exact = np.mean([chi2_verdict(row, 1.0, n)[2] < 0.01 for row in z])
    plain = np.mean([chi2_verdict(row, 1.0)[2] < 0.01 for row in z])
    assert 0.007 < exact < 0.013 and plain > 0.05


@pytest.fixture(scope="module", params=["mast", "beam"])
def structure(request):
    return {"mast": lc.mast, "beam": lc.two_span_beam}[request.param]()


@pytest.mark.slow
def test_the_exact_truth_passes_compare_at_every_hit_count(structure):
    """8 seeds x 3, 5, 10 hits on a grounded 10-mass chain (exponential window: its 2 Hz mode
    rings) and a two-span beam (decays: no window): at most one of 24 data sets with a failing
    cell; mean cell ratio S / 2n within 10 % of 1 at each hit count."""
    failing_sets, cells = 0, 0
    for n_hits in HITS:
        ratios = []
        for seed in SEEDS:
            test = _compare(structure, n_hits, seed).noise_test
            failing_sets += int(not test.within)
            cells += len(test.cells)
            ratios += [c.ratio for c in test.cells]
        assert abs(np.mean(ratios) - 1) < 0.1, (n_hits, np.mean(ratios))
    assert failing_sets <= 2, (structure.name, failing_sets, cells)


def test_the_exact_truth_of_three_hits_passes_compare(structure):
    """Six seeds at 3 hits: at most one data set with a failing cell (expected 0.06)."""
    failing = [seed for seed in range(100, 106) if not _compare(structure, 3, seed).within_noise]
    assert len(failing) <= 1, failing


def test_force_noise_is_counted_with_its_band_wide_correlation():
    """Force noise 0.5 % of the peak on the mast, 5 seeds x 3, 5, 10 hits: no more than one of
    15 data sets fails (10 of 45 with independent bins, 0 of 45 with eq. N1's correlation)."""
    mast = lc.mast()
    for n_hits in HITS:
        failing = 0
        for seed in range(100, 105):
            F, Y = hammer(mast, n_hits=n_hits, seed=seed, noise=(5e-3, 0.01))
            data = rc.estimate_frf_impact(F, Y, FS, inputs=list(mast.inputs), outputs=list(mast.outputs))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                failing += int(not rc.compare(mast.model(), data, band=BAND).within_noise)
        assert failing <= 1, (n_hits, failing)


@pytest.mark.parametrize("tau", [None, 1.0])
def test_the_force_noise_record_matches_a_monte_carlo(tau):
    """Eq. N1 against 300 numpy trials of hits whose response is the clean force (H = 1) and whose
    force gauge adds white noise: the variance of ``H1 - 1`` per bin and its correlation one and
    five bins apart, 5 Hz-40 Hz."""
    fs, n, n_hits, sd = 256.0, 512, 4, 0.05
    t = np.arange(n) / fs
    rng = np.random.default_rng(11)
    clean = []
    for k in range(n_hits):
        start = 0.06 + 0.004 * k
        on = (t >= start) & (t <= start + 0.008)
        clean.append(np.where(on, (100.0 + 10 * k) * np.sin(np.pi * (t - start) / 0.008), 0.0))
    clean = np.array(clean)
    errs, predicted = [], []
    for _ in range(300):
        noisy = clean + sd * rng.standard_normal(clean.shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = rc.estimate_frf_impact(noisy, clean[:, :, None], fs, exp_window=tau, force_window=0.02)
        errs.append(d.response[:, 0, 0] - 1.0)
        predicted.append(d.meta["force_noise"]["rel_var"])  # from each trial's own pre-trigger
    rec = d.meta["force_noise"]
    e = np.array(errs)
    f = np.asarray(rec["f_hz"])
    band = (f > 5) & (f < 40)
    v = np.mean(np.abs(e) ** 2, axis=0)
    ratio = v[band] / np.mean(predicted, axis=0)[band]
    assert np.all(np.abs(ratio - 1) < 0.15), ratio
    corr = np.asarray(rec["corr"])
    for m in (1, 5):
        c = np.abs(np.mean(e[:, :-m] * np.conj(e[:, m:]), axis=0)) / np.sqrt(v[:-m] * v[m:])
        assert np.all(c[band[:-m]] < corr[m] + 0.1), (m, c[band[:-m]].max(), corr[m])  # a bound
        assert np.mean(c[band[:-m]]) > 0.5 * corr[m], (m, np.mean(c[band[:-m]]), corr[m])
    assert corr[1] > 0.9  # a 20 ms force window: correlated over many 0.5 Hz bins


@pytest.mark.parametrize("n_hits", [3, 5, 10])
def test_five_percent_more_mass_at_a_node_is_still_flagged(n_hits):
    """+5 % mass (0.6 kg of 12 kg) at dof 5 of the mast: beyond the noise at every hit count."""
    mast = lc.mast()
    cmp = _compare(mast, n_hits, 100, modify=_mass(4, 0.6))
    test = cmp.noise_test
    assert not test.within, test.sentence()
    assert max(c.ratio for c in test.failing) > 3


@pytest.mark.slow
def test_the_satellite_of_issue_34_by_impact():
    """The free-free satellite of ``tests/satellite_corpus.py`` (120 DOF, numpy truth, exact
    first-order-hold discretisation on a 16384 Hz grid), hammer at F1 (2 ms half-sine), a scipy
    FIR anti-aliasing filter, 1024 Hz, 8 s records, 5 hits, exponential window: the exact truth
    is within the noise in three seeds (4 of 8 seeds had failing cells with the plain chi-square,
    0-4 of 36); 0.15 kg more at the boom tip is beyond it in most cells."""
    import satellite_corpus as sc
    from scipy.signal import firwin, lfilter

    fs, over, n = 1024.0, 16, 8192
    t = np.arange(n * over + 1) / (fs * over)
    taps = firwin(20 * over + 1, 0.8 / over)
    model = sc.nominal_model().select(inputs=["F1"])

    def compare(seed, effects=()):
        rng = np.random.default_rng(seed)
        forces, responses = [], []
        for _ in range(5):
            start, width, amp = 0.05 + rng.uniform(0, 0.01), 0.002, 100 * (1 + 0.2 * rng.standard_normal())
            f = np.where((t >= start) & (t <= start + width),
                         amp * np.sin(np.pi * np.clip(t - start, 0, width) / width), 0.0)
            y = sc.simulate(np.column_stack([f, np.zeros_like(f)]), 1 / (fs * over), effects)
            forces.append(lfilter(taps, 1.0, f)[::over][:n])
            responses.append(lfilter(taps, 1.0, y, axis=0)[::over][:n])
        F, Y = np.array(forces), np.array(responses)
        F += 5e-4 * np.abs(F[0]).max() * rng.standard_normal(F.shape)
        Y += 0.01 * Y[0].std(axis=0) * rng.standard_normal(Y.shape)
        data = rc.estimate_frf_impact(F, Y, fs, inputs=["F1"], outputs=list(sc.OUTPUTS))
        assert data.meta["exp_window_tau_s"] is not None  # the suspension modes ring
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return rc.compare(model, data, band=sc.BAND).noise_test

    for seed in (501, 503, 506):  # the seeds whose plain chi-square flagged 4, 3 and 1 cells
        test = compare(seed)
        assert test.within, test.sentence()
        assert abs(test.overall_ratio - 1) < 0.35  # about 4 x its scatter (F variance 2, chi2_factor 4.6)
    flagged = compare(501, ("tip_mass",))
    assert len(flagged.failing) > len(flagged.cells) // 2, flagged.sentence()
