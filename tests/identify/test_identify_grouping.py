"""The Caltech route: SIMO fits -> 12-mode MIMO (combine_simo) -> SVD grouping to 6 modes, and
balanced truncation of the same 12-mode model with its a-priori bound (eqs. 9-13)."""

from __future__ import annotations

import numpy as np
import pytest
from test_identify_support import BAND, caltech_measurement, exact_data, modal_shapes, truss_system

import robustctl as rc
from robustctl.identify import cluster_modes


@pytest.fixture(scope="module")
def simo12():
    data = caltech_measurement()
    return rc.fit_rational(data, 8, band=BAND, method="chebyshev", common_denominator=False)


def _hinf_error(g, gm, f_hz):
    d = rc.freqresp(g, f_hz).response - rc.freqresp(gm, f_hz).response
    return max(np.linalg.norm(dk, 2) for dk in d)


def test_three_simo_fits_of_four_modes_make_a_twelve_mode_model(simo12):
    assert simo12.method == "combined" and simo12.n_modes == 12 and simo12.statespace().nstates == 24
    # each SIMO pole drives only its own input column
    for r in simo12.residues:
        assert np.count_nonzero(np.abs(r).sum(axis=0)) == 1


def test_svd_grouping_gives_six_modes_within_20_percent_of_the_twelve_mode_cost(simo12):
    six = rc.group_modes(simo12, (2, 1, 2, 1))
    assert six.n_modes == 6 and six.statespace().nstates == 12
    j12, j6 = simo12.cost().total, six.cost().total
    assert j6 <= 1.2 * j12
    # the groups sit at the truss's bending/torsion frequencies
    f = np.sort(six.f_hz)
    assert np.all(np.abs(f - [1.17, 1.19, 2.26, 2.66, 2.75, 4.43]) < 0.05)


def test_balanced_truncation_of_the_twelve_mode_model_respects_its_bound(simo12):
    sys12 = simo12.statespace()
    red = rc.balanced_truncation(sys12, 12)
    assert red.sys.nstates == 12 and red.hsv.size == 24
    np.testing.assert_allclose(red.bound, 2 * red.hsv[12:].sum())
    f = np.linspace(0.01, 20, 8000)
    err = _hinf_error(sys12, red.sys, f)
    assert err <= red.bound
    assert red.sys.input_labels == sys12.input_labels


def test_grouping_duplicated_exact_modes_is_exact():
    """Two inputs fitted separately see the same two modes; the summed rank-1 residues (eq. 9)
    rebuild the true MIMO model exactly."""
    f = np.linspace(0.5, 5.5, 300)
    sys = truss_system(f_modes=np.array([1.5, 3.5]), zeta=np.array([0.01, 0.02]))
    sys = sys[:, :2]
    data = exact_data(sys, f)
    fits = [rc.fit_rational(data.select(inputs=[k]), 4, method="vf") for k in range(2)]
    mimo = rc.combine_simo(fits)
    assert mimo.n_modes == 4
    two = rc.group_modes(mimo, (1, 1), refine=False)
    assert two.n_modes == 2
    np.testing.assert_allclose(two.response(f), data.response, rtol=1e-7, atol=1e-9)
    auto = rc.group_modes(mimo, 0.01, refine=False)  # automatic clustering and rank
    assert auto.n_modes == 2


@pytest.mark.filterwarnings("ignore::robustctl.identify.IdentifyWarning")
def test_explicit_groups_and_clustering():
    assert [list(c) for c in cluster_modes(np.array([1.17, 2.26, 1.19, 2.7, 2.66]), tol=0.05)] == [
        [0, 2],
        [1],
        [4, 3],
    ]
    assert len(cluster_modes(np.array([1.0, 1.1, 3.0, 3.05]), n_groups=2)) == 2
    f = np.linspace(0.5, 5.5, 300)
    data = exact_data(truss_system(), f)
    _, b = modal_shapes()
    seen = [int(np.sum(np.abs(b[:, k]) > 1e-9)) for k in range(3)]  # actuator 3 misses x-bending
    assert seen == [6, 6, 4]
    fits = [rc.fit_rational(data.select(inputs=[k]), 2 * seen[k], method="vf") for k in range(3)]
    mimo = rc.combine_simo(fits)
    grouped = rc.group_modes(mimo, [((1.0, 1.3), 2), ((2.2, 2.3), 1), ((2.6, 2.8), 2), ((4.3, 4.5), 1)])
    np.testing.assert_allclose(np.sort(grouped.f_hz), [1.17, 1.19, 2.26, 2.66, 2.75, 4.43], rtol=1e-6)
    rel = np.abs(grouped.response(f) - data.response).max() / np.abs(data.response).max()
    assert rel < 1e-6


@pytest.mark.filterwarnings("ignore::robustctl.identify.IdentifyWarning")
def test_grouping_bad_input():
    f = np.linspace(0.5, 5.5, 200)
    fit = rc.fit_rational(exact_data(truss_system(), f), 12, method="vf")
    with pytest.raises(rc.FitError, match="holds no mode"):
        rc.group_modes(fit, [((10, 20), 1)])
    with pytest.raises(rc.FitError, match="keep 1..3"):
        rc.group_modes(fit, [((1.0, 1.3), 4)])
    with pytest.raises(rc.FitError, match="cannot make 9 groups"):
        rc.group_modes(fit, (1,) * 9)
    with pytest.raises(rc.FitError, match="same outputs"):
        rc.combine_simo([fit, fit.freqresp(f) and rc.fit_rational(exact_data(truss_system()[:2, :], f), 4)])
    with pytest.raises(rc.FitError, match="input names repeat"):
        rc.combine_simo([fit, fit])


def test_one_call_caltech_route_through_fit_measurement_model(simo12):
    mm = rc.fit_measurement_model(
        caltech_measurement(), n_modes=4, band=BAND, groups=(2, 1, 2, 1), method="chebyshev"
    )
    assert mm.n_modes == 6 and mm.sys.nstates == 12
    assert mm.cost.total <= 1.2 * simo12.cost().total
