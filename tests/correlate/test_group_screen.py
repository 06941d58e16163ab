"""The screen of an element group whose secant goes the other way than the data ask
(``screening._group_sizes``): the share at sizes along the way to the secant's estimate.

At 20,000 DOFs the fe20k seam (at 40 % of its modelled stiffness) was estimated by its secant
(taken at +190 %, a calibrated stiffening step) at -95 %, where it explains a quarter of the
misfit; it explains 0.89 at -60 % (0.99 fitted with the update). The residual here is a made-up
quadratic in the size, so that the best share and its size are known exactly.
"""

import numpy as np
import pytest

from robustctl.correlate.diagnosis import screening as scr
from robustctl.errors import ModelError


class _Quadratic:
    """A residual ``j(v) = r (v - v_true) / v_true`` (share ``1 - ((v - v_true) / v_true)^2``)."""

    def __init__(self, r, v_true, fail_below=None):
        self.r, self.v_true, self.fail_below, self.calls = r, v_true, fail_below, []

    def vector(self, **kw):
        (v,) = kw.values()
        self.calls.append(v)
        if self.fail_below is not None and v < self.fail_below:
            raise ModelError("cannot be built at this size")
        return self.r * (v - self.v_true) / self.v_true


def test_the_best_size_between_neutral_and_an_overshooting_estimate():
    """Estimate -0.95, truth -0.6: four sizes and two halvings find -0.59375 (share 0.9997) in
    eight evaluations; the share at the estimate alone is 0.66."""
    r = np.random.default_rng(1).standard_normal(40)
    rr = float(r @ r)
    res = _Quadratic(r, -0.6)
    share, value, n = scr._group_sizes(res, "s", 0.0, -0.95, np.zeros((40, 0)), rr)
    assert n == 8 == len(res.calls)
    assert value == pytest.approx(-0.59375, abs=1e-12)
    assert share == pytest.approx(1.0 - (0.00625 / 0.6) ** 2, rel=1e-12)
    assert 1.0 - ((-0.95 + 0.6) / 0.6) ** 2 < 0.7


def test_sizes_that_cannot_be_evaluated_are_skipped_and_the_update_is_projected_out():
    """A size the model cannot be built with counts as no share; the residual's part along the
    update parameters' sensitivities (``Q``) is projected out, as in the exact screening."""
    rng = np.random.default_rng(2)
    Q = np.linalg.qr(rng.standard_normal((40, 2)))[0]
    r = rng.standard_normal(40)
    r = r - Q @ (Q.T @ r)
    res = _Quadratic(r, -0.3, fail_below=-0.5)
    share, value, _ = scr._group_sizes(res, "s", 0.0, -0.95, Q, float(r @ r))
    assert value == pytest.approx(-0.296875, abs=1e-12)
    assert share == pytest.approx(1.0 - (0.003125 / 0.3) ** 2, rel=1e-12)
    none = _Quadratic(r, -0.3, fail_below=0.0)
    assert scr._group_sizes(none, "s", 0.0, -0.95, Q, float(r @ r))[:2] == (0.0, 0.0)
