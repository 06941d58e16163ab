"""BLAS thread limits: in force inside, restored after, env-var default, decorator use."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

import robustctl as rc
from robustctl import threads
from robustctl.errors import RobustctlError

#: BLAS libraries built single-threaded (they stay at 1 thread whatever the limit; cvxpy's solvers load
#: one, libopenblas-r0, once an LMI has been solved in the test process). Found by the fixture.
_SINGLE_THREADED: set[str] = set()


def blas_counts() -> list[int]:
    return [
        p["num_threads"]
        for p in threadpool_info()
        if p["user_api"] == "blas" and p["filepath"] not in _SINGLE_THREADED
    ]


@pytest.fixture
def two_threads():
    """Run with a known outside setting of 2 BLAS threads (restored afterwards)."""
    np.linalg.eigvals(np.eye(3))  # make sure numpy's BLAS is loaded
    with threadpool_limits(2, user_api="blas"):
        _SINGLE_THREADED.update(
            p["filepath"] for p in threadpool_info() if p["user_api"] == "blas" and p["num_threads"] == 1
        )
        yield


def test_context_manager_limits_and_restores(two_threads):
    assert blas_counts() and all(n == 2 for n in blas_counts())
    with rc.blas_threads(1):
        assert all(n == 1 for n in blas_counts())
        with rc.blas_threads(1):  # nested: unchanged, and restored correctly
            assert all(n == 1 for n in blas_counts())
        assert all(n == 1 for n in blas_counts())
    assert all(n == 2 for n in blas_counts())


def test_decorators_use_setting(two_threads):
    seen = {}

    @threads.limit_blas
    def kernel():
        seen["inside"] = blas_counts()
        return 7

    @rc.blas_threads(1)
    def explicit():
        seen["explicit"] = blas_counts()

    old = rc.set_blas_threads(1)
    try:
        assert kernel() == 7 and all(n == 1 for n in seen["inside"])
        explicit()
        assert all(n == 1 for n in seen["explicit"])
        rc.set_blas_threads(None)  # no limit: the outside setting stays
        kernel()
        assert all(n == 2 for n in seen["inside"])
        assert threads.get_blas_threads() is None
    finally:
        rc.set_blas_threads(old)
    assert all(n == 2 for n in blas_counts())


def test_restored_after_exception(two_threads):
    with pytest.raises(ZeroDivisionError), rc.blas_threads(1):
        raise ZeroDivisionError
    assert all(n == 2 for n in blas_counts())


def test_robustctl_kernels_run_limited(two_threads, monkeypatch):
    """freqresp's dense kernel runs under the global limit."""
    import control

    from robustctl import lti

    seen = []
    original = lti.modal_terms

    def spy(*args, **kwargs):
        seen.append(blas_counts())
        return original(*args, **kwargs)

    monkeypatch.setattr(lti, "modal_terms", spy)
    rc.freqresp(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), [1.0])
    assert seen and all(n == 1 for n in seen[0])


def test_bad_settings():
    with pytest.raises(RobustctlError, match="positive integer"):
        rc.set_blas_threads(-2)
    with pytest.raises(RobustctlError, match="positive integer"):
        rc.blas_threads(1.5)
    with pytest.raises(RobustctlError, match="positive integer"):
        rc.set_blas_threads("many")
    assert threads._parse("0", "x") is None and threads._parse(np.int64(3), "x") == 3


def test_environment_variable_sets_default(monkeypatch):
    monkeypatch.setenv("ROBUSTCTL_BLAS_THREADS", "2")
    assert threads._initial_setting() == 2
    monkeypatch.setenv("ROBUSTCTL_BLAS_THREADS", "none")
    assert threads._initial_setting() is None
    monkeypatch.delenv("ROBUSTCTL_BLAS_THREADS")
    assert threads._initial_setting() == 1
    monkeypatch.setenv("ROBUSTCTL_BLAS_THREADS", "lots")
    with pytest.warns(RuntimeWarning, match="Using 1 BLAS thread"):
        assert threads._initial_setting() == 1
