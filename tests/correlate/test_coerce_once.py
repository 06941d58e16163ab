"""The data of compare, diagnose, update and Residual are coerced and checked once.

The public entry point makes its data a FrequencyData, checks the band, builds the noise model
and the point weights once (``correlate.residual.check_data``), and the inner functions take
that object as it is. Every coercion and data check is counted here with a counter
monkeypatched into every robustctl module that holds it (calls inside ``checks`` and ``noise``
count too), for one public call on a 4-mass chain whose truth and H1 estimate are made here
with numpy (tests/verdict_corpus.py).
"""

from __future__ import annotations

import collections
import sys
import warnings

import numpy as np
import pytest
import verdict_corpus as vc

import robustctl as rc
from robustctl import checks, frd
from robustctl.correlate import residual
from robustctl.measure import noise

F_HZ = np.arange(2.0, 40.0, 0.125)
BAND = (3.0, 35.0)

#: (module, name) of every coercion or check of the data on their way through the correlate stage
COUNTED = [
    (frd, "as_frequency_data"),
    (checks, "check_band"),
    (checks, "band_mask"),
    (checks, "checked_band_mask"),
    (checks, "band_data"),
    (checks, "point_weights"),
    (checks, "coherence_weights"),
    (noise, "noise_model"),
    (noise, "averages_of"),
    (noise, "checked_averages"),
    (noise, "checked_noise_model"),
    (noise, "point_weight_bias"),
    (noise, "coherence_weight_bias"),
    (residual, "check_complex_response"),
    (residual, "check_data"),
]


@pytest.fixture(scope="module")
def chain():
    return vc.chain_model()


@pytest.fixture(scope="module")
def data(chain):
    M, K, B, C, kinds = vc.chain_matrices(s_k=1.04)
    g = vc.modal_frf(M, K, B, C, kinds, F_HZ)
    return vc.periodic_h1(g, n_avg=32, noise=0.05, seed=4, inputs=chain.inputs, outputs=chain.outputs,
                          f_hz=F_HZ)


@pytest.fixture
def counts(monkeypatch):
    """Counter of calls per counted function, and of channel matches per (names, names, what)."""
    found: collections.Counter = collections.Counter()
    modules = [m for name, m in list(sys.modules.items()) if name.split(".")[0] == "robustctl" and m]

    def counting(key, fn):
        def wrapper(*args, **kwargs):
            found[key] += 1
            return fn(*args, **kwargs)
        return wrapper

    def patch_everywhere(original, wrapped):  # under any name a module imported it as
        for module in modules:
            for attr, value in list(vars(module).items()):
                if value is original:
                    monkeypatch.setattr(module, attr, wrapped)

    for owner, name in COUNTED:
        original = getattr(owner, name)
        patch_everywhere(original, counting(name, original))
    match = checks.match_channels

    def matching(model_names, data_names, what, *args, **kwargs):
        found[("match_channels", tuple(model_names), tuple(data_names), what)] += 1
        return match(model_names, data_names, what, *args, **kwargs)

    patch_everywhere(match, matching)
    replace = frd.FrequencyData.replace

    def replacing(self, **changes):  # a copy of FrequencyData is validated again
        found["FrequencyData.replace"] += 1
        return replace(self, **changes)

    monkeypatch.setattr(frd.FrequencyData, "replace", replacing)
    return found


def _at_most_once(found: collections.Counter, *, allow: dict | None = None) -> None:
    allow = allow or {}
    twice = {k: n for k, n in found.items() if n > allow.get(k, 1)}
    assert not twice, f"coerced or checked more than once: {twice}"


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


def test_compare_coerces_its_data_once(chain, data, counts):
    cmp = rc.compare(chain, data, band=BAND)
    assert counts["as_frequency_data"] == 1 and counts["check_data"] == 1
    assert counts["checked_noise_model"] == 1 and counts["point_weights"] == 1
    _at_most_once(counts)
    assert cmp.noise is not None and cmp.noise.kind == "coherence"


def test_compare_of_a_pair_coerces_it_once(chain, data, counts):
    unnamed = rc.as_statespace(chain.statespace(), inputs=["u[0]"], outputs=["y[0]", "y[1]", "y[2]"])
    cmp = rc.compare(unnamed, (data.f_hz, data.response), band=BAND)
    assert counts["as_frequency_data"] == 1
    _at_most_once(counts)
    assert cmp.noise is None  # a pair carries no coherence


def test_update_coerces_its_data_once(chain, data, counts):
    upd = _quiet(rc.update, chain, data, band=BAND)
    assert counts["as_frequency_data"] == 1 and counts["check_data"] == 1
    _at_most_once(counts)
    assert upd.model.param("s_k").value == pytest.approx(1.04, abs=5 * upd.std_errors["s_k"])


def test_diagnose_coerces_its_data_once(chain, data, counts):
    diag = _quiet(rc.diagnose, chain, data, band=BAND, workers=1)
    assert counts["as_frequency_data"] == 1 and counts["check_data"] == 1
    # rc.effects.candidates, a public function of the physical stage, checks the band it is given
    _at_most_once(counts, allow={"check_band": 2})
    assert diag.ranking


def test_residual_coerces_its_data_once(chain, data, counts):
    res = rc.Residual(chain, data, band=BAND, point_weights="coherence")
    assert counts["as_frequency_data"] == 1 and counts["point_weight_bias"] == 1
    _at_most_once(counts)
    assert res.bias is not None and res.noise is not None


def test_the_counter_sees_a_second_coercion(chain, data, counts):
    """The counter itself: two Residuals coerce twice (so a path that re-checks is caught)."""
    rc.Residual(chain, data, band=BAND)
    rc.Residual(chain, data, band=BAND)
    assert counts["as_frequency_data"] == 2 and counts["check_band"] == 2
    with pytest.raises(AssertionError, match="more than once"):
        _at_most_once(counts)


def test_checked_data_give_the_numbers_of_a_fresh_check(chain, data):
    """``Residual.of_checked`` on data checked once gives the residual ``Residual(...)`` gives."""
    checked = residual.check_data(data, BAND)
    a = residual.Residual.of_checked(chain, checked)
    b = rc.Residual(chain, data, band=BAND)
    np.testing.assert_array_equal(a.vector(), b.vector())
    np.testing.assert_array_equal(a.noise.sigma, b.noise.sigma)
    mask = (data.f_hz >= BAND[0]) & (data.f_hz <= BAND[1])
    np.testing.assert_array_equal(checked.data.response, data.response[mask])
    np.testing.assert_array_equal(checked.data.coherence, data.coherence[mask])
    assert checked.data.experiment is data.experiment and checked.data.outputs == data.outputs


def test_points_of_frequency_data_are_read_only_copies(data):
    mask = np.zeros(data.n_freq, dtype=bool)
    mask[[3, 10, 50]] = True
    sub = data.points(mask)
    np.testing.assert_array_equal(sub.f_hz, data.f_hz[[3, 10, 50]])
    np.testing.assert_array_equal(sub.response, data.response[[3, 10, 50]])
    assert not sub.response.flags.writeable and not sub.f_hz.flags.writeable
    assert sub.meta == data.meta and sub.meta is not data.meta
    assert sub.replace().shape == sub.shape  # valid data: validation accepts them


@pytest.mark.parametrize("mask", [[3, 10, 50], np.zeros(5, dtype=bool), np.zeros(len(F_HZ), dtype=bool)])
def test_points_refuses_what_is_not_a_mask_over_the_data(data, mask):
    with pytest.raises(rc.DataError, match="boolean mask of shape"):
        data.points(mask)


# ---------------------------------------------------------------------------- the design half
@pytest.fixture
def plant_conversions(monkeypatch):
    """Types of the plants ``as_partitioned`` had to convert (a plant it returns as it is, the one
    type passed inside robust/, does not count), in every robustctl module that holds it."""
    from robustctl.robust import partitioned

    original = partitioned.as_partitioned
    converted: list[str] = []

    def counting(P, *args, **kwargs):
        out = original(P, *args, **kwargs)
        if out is not P:
            converted.append(type(P).__name__)
        return out

    for name, module in list(sys.modules.items()):
        if name.split(".")[0] == "robustctl" and module is not None:
            for attr, value in list(vars(module).items()):
                if value is original:
                    monkeypatch.setattr(module, attr, counting)
    return converted


@pytest.mark.slow
def test_dksyn_converts_its_plant_once(plant_conversions):
    """The autoscaled starts and the K steps get the GeneralizedPlant itself (they once repacked
    it as a (P, nmeas, ncon, blocks) tuple per start, converted again by dksyn); the H-infinity
    optimum of the first K step is the independent check that the plant arrived intact."""
    from robustctl.examples import DISTILLATION_BLOCKS, distillation_plant

    P = distillation_plant()
    dk = _quiet(rc.dksyn, (P, 2, 2, DISTILLATION_BLOCKS), max_iter=1, progress=False)
    assert plant_conversions == ["StateSpace"]
    assert len(dk.history) == 1 and np.isfinite(dk.mu_peak)
    plant_conversions.clear()
    gp = rc.robust.partitioned.as_partitioned(P, 2, 2, DISTILLATION_BLOCKS)
    assert plant_conversions == ["StateSpace"]
    plant_conversions.clear()
    _quiet(rc.dksyn, gp, max_iter=1, progress=False, autoscale=False)
    assert plant_conversions == []  # a GeneralizedPlant is taken as it is


def test_hinfsyn_converts_its_plant_once(plant_conversions):
    import control

    G = control.tf([1], [1, 0.2, 1])
    P = control.augw(G, w1=control.tf([0.5, 1], [1, 0.01]), w2=control.tf(0.1, 1))
    res = rc.hinfsyn(P, 1, 1)
    assert plant_conversions == ["StateSpace"]
    # python-control's own synthesis on the same plant: the same optimum within the bisection's tolerance
    K, _, gam, _ = control.hinfsyn(P, 1, 1)
    assert res.gamma_opt == pytest.approx(float(gam), rel=2e-3)
