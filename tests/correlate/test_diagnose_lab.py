"""Diagnose on the laboratory corpus (tests/lab_corpus.py: numpy truths of five structures,
measured forces and held commands, random and periodic excitation, an impact test, H1 by
rc.estimate_frf told how the data were made): no exact truth proposes anything, and planted
effects -- physical ones and test-setup errors -- are named first and significant."""

from __future__ import annotations

import warnings

import lab_corpus as lc
import numpy as np
import pytest

import robustctl as rc


def _diagnose(case):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rc.diagnose(case.truth, case.data, band=case.description["band"], workers=1)


@pytest.mark.parametrize("name", list(lc.CASES))
def test_no_exact_truth_of_the_lab_corpus_proposes_anything(name):
    diag = _diagnose(lc.case(name, seed=1))
    assert diag.best is None, diag.summary()
    assert not diag.model_error and diag.channel_verdict == ""
    assert all(r.p_value > 1e-3 for r in diag.ranking if r.fitted)


def _swap01(f, g):
    return g[:, [1, 0] + list(range(2, g.shape[1]))]


def _flip1(f, g):
    g = g.copy()
    g[:, 1] *= -1.0
    return g


def _units2(f, g):
    g = g.copy()
    g[:, 2] *= 9.81
    return g


def _delay(f, g):
    return g * np.exp(-2j * np.pi * f * 2e-3)[:, None, None]


def _mass(dof, kg):
    def modify(M, K):
        M = M.copy()
        M[dof, dof] += kg
        return M, K

    return modify


@pytest.mark.parametrize(
    "name, planted, expected",
    [
        ("frame_measured_random", dict(transform=_swap01), "outputs ax1 and ay1 swapped"),
        ("beam_held_periodic", dict(transform=_swap01), "outputs a2 and a4 swapped"),
        ("hub_held_random", dict(transform=_flip1), "sign flip of output tipA"),
        ("grid_impact", dict(transform=_flip1), "sign flip of output a5"),
        ("mast_measured_random", dict(transform=_units2), "units slip on output a10"),
    ],
)
def test_a_test_setup_error_in_lab_data_is_named(name, planted, expected):
    diag = _diagnose(lc.case(name, seed=2, **planted))
    assert diag.best is not None and diag.best.name == expected, diag.summary()
    assert diag.best_result.significant


@pytest.mark.parametrize(
    "name, planted, expected, param, value",
    [
        ("beam_measured_random", dict(transform=_delay), "output delay", "output_delay", 2e-3),
        ("grid_measured_periodic", dict(modify=_mass(5, 0.3)), "added mass at dof 6", "added_mass__dof_6",
         0.3),
        ("frame_held_random", dict(modify=_mass(3, 3.0)), "added mass at dof 4", "added_mass__dof_4",
         3.0),
    ],
)
def test_a_physical_effect_in_lab_data_is_ranked_first_and_recovered_within_3_se(
    name, planted, expected, param, value
):
    case = lc.case(name, seed=2, **planted)
    diag = _diagnose(case)
    names = {diag.ranking[0].name} | set(diag.indistinguishable.names if diag.indistinguishable else ())
    assert diag.best is not None and expected in names, diag.summary()
    if diag.best.name == expected:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            upd = rc.update(case.truth.with_effect(diag.best), case.data, band=case.description["band"])
        assert abs(upd.model.param(param).value - value) < 3 * upd.std_errors[param]
