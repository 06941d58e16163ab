"""The time-budget policy (robustctl.budget): no clock by default; a used-up budget (0 s) is
flagged in the result, its summary and a BudgetWarning, or refused when nothing usable exists.

Every budget here is 0 s or None: no test depends on how fast the machine is."""

from __future__ import annotations

import inspect
import pickle
import warnings

import numpy as np
import pytest

import robustctl as rc
from robustctl.budget import Deadline, as_deadline
from robustctl.examples import DISTILLATION_BLOCKS, distillation_plant

# the routines that take a time budget
BUDGETED = [rc.dksyn, rc.hinfsyn, rc.diagnose, rc.update, rc.mu, rc.fit_magnitude, rc.cover_additive,
            rc.cover_multiplicative, rc.fit_measurement_model]


@pytest.mark.parametrize("fn", BUDGETED, ids=lambda f: f.__name__)
def test_no_routine_reads_the_clock_by_default(fn):
    assert inspect.signature(fn).parameters["time_budget_s"].default is None


def test_deadline_without_budget_never_expires_and_zero_expires_at_once():
    free = Deadline(None)
    assert not free.active and not free.expired() and free.remaining() == np.inf and not free.hit
    assert free.budget_or_none() is None
    spent = Deadline(0)
    assert spent.active and spent.expired() and spent.hit and spent.remaining() == 0.0
    assert as_deadline(spent) is spent and as_deadline(None).budget_s is None
    # what is left travels to a worker process
    back = pickle.loads(pickle.dumps(spent))
    assert back.budget_s == 0 and back.expired()
    assert pickle.loads(pickle.dumps(free)).remaining() == np.inf


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), "10", True, [1.0]])
def test_deadline_refuses_what_is_not_seconds(bad):
    with pytest.raises(rc.SynthesisError, match="time_budget_s"):
        Deadline(bad, error=rc.SynthesisError)


def test_budget_warning_is_a_robustctl_and_a_runtime_warning():
    assert issubclass(rc.BudgetWarning, rc.RobustctlWarning) and issubclass(rc.BudgetWarning, RuntimeWarning)
    with pytest.warns(rc.BudgetWarning, match="stopped by time_budget_s=0 s"):
        Deadline(0).warn("the thing")


def test_fit_magnitude_used_up_budget_returns_a_flagged_fit():
    from robustctl.robust.uncertainty.magfit import fit_magnitude_details

    f = np.logspace(-1, 2, 60)
    mag = np.abs(0.1 + 1j * f) / np.abs(1 + 1j * f / 30)
    with pytest.warns(rc.BudgetWarning):
        cut = fit_magnitude_details(f, mag, 2, time_budget_s=0)
    free = fit_magnitude_details(f, mag, 2)
    assert cut.stopped_by_budget and not free.stopped_by_budget
    # the bisection's first feasible point against the converged one (within its 0.05 dB tolerance)
    assert free.max_error_db <= cut.max_error_db + 0.05 + 1e-9
    with warnings.catch_warnings():
        warnings.simplefilter("error", rc.BudgetWarning)  # no clock, no warning
        fit_magnitude_details(f, mag, 2)


def test_mu_used_up_budget_keeps_a_valid_bound():
    rng = np.random.default_rng(3)
    M = rng.standard_normal((5, 3, 3)) + 1j * rng.standard_normal((5, 3, 3))
    with pytest.warns(rc.BudgetWarning):
        cut = rc.mu(M, [[1, 1], [1, 1], [1, 1]], time_budget_s=0)
    free = rc.mu(M, [[1, 1], [1, 1], [1, 1]])
    assert cut.info["stopped_by_budget"] and not free.info["stopped_by_budget"]
    # an upper bound stopped early is still an upper bound, only less tight
    assert np.all(cut.upper >= free.upper * (1 - 1e-12)) and np.all(free.lower <= free.upper * (1 + 1e-12))


def test_mu_lower_bound_does_not_depend_on_how_the_grid_is_split():
    """Each frequency draws its random restart from (seed, its index): chunks give the serial numbers."""
    rng = np.random.default_rng(5)
    M = rng.standard_normal((24, 4, 4)) + 1j * rng.standard_normal((24, 4, 4))
    blocks = [[-1, 0], [1, 0], [2, 2]]
    whole = rc.mu(M, blocks)
    split = rc.mu(M, blocks, chunk=5)
    np.testing.assert_array_equal(whole.lower, split.lower)
    np.testing.assert_array_equal(whole.upper, split.upper)


def test_dksyn_used_up_budget_returns_its_first_controller_flagged():
    gp = (distillation_plant(), 2, 2, DISTILLATION_BLOCKS)
    with pytest.warns(rc.BudgetWarning, match="dksyn"):
        dk = rc.dksyn(gp, max_iter=3, time_budget_s=0)
    assert dk.stopped_by_budget and len(dk.history) == 1 and "time budget" in dk.summary()
    assert "time budget" in dk.stop_reason


def test_update_used_up_budget_is_flagged_and_warned():
    data, _ = rc.examples.caltech_truss_experiment(seed=0)
    model = rc.examples.caltech_truss()
    with pytest.warns(rc.BudgetWarning, match="update"):
        upd = rc.update(model, data, band=(0.5, 20), params=["E_aluminium"], time_budget_s=0)
    assert upd.stopped_by_budget and upd.fit.stopped_by_budget and upd.fit.n_iter == 0
    assert any("time budget" in w for w in upd.warnings)
