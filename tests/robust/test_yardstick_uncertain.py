"""The measurement-model yardstick with an uncertain system among its models (issue 33)."""

from __future__ import annotations

import warnings

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.interconnect import lft
from robustctl.lti import freqresp_array
from robustctl.robust.dk.verify import default_grid, mu_of
from robustctl.robust.mu.bounds import mu
from robustctl.robust.uncertainty.blocks import Block, BlockStructure

ZETA = 0.01


def _two_modes(f2_hz):
    """Collocated force -> velocity of modes at 1 Hz and ``f2_hz`` (numpy matrices)."""
    A = np.zeros((4, 4))
    for k, f in enumerate((1.0, f2_hz)):
        w = 2 * np.pi * f
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0.0, 1.0], [-w * w, -2 * ZETA * w]]
    B = np.array([[0.0], [1.0], [0.0], [1.0]])
    return control.ss(A, B, B.T, 0.0, inputs=["f"], outputs=["v"])


def _uncertain():
    """The same plant with the second mode's frequency 4 Hz +-5 % (``rc.ureal``)."""
    w = rc.ureal("f2", 2 * np.pi * 4.0, percent=5)
    integ = control.tf([1.0], [1.0, 0.0])
    mode2 = rc.as_uncertain(integ).feedback(2 * ZETA * w + w * w * integ)
    mode1 = control.tf([1.0, 0.0], [1.0, 2 * ZETA * 2 * np.pi, (2 * np.pi) ** 2])
    return (mode2 + mode1).with_names(inputs=["f"], outputs=["v"])


def _recipe(model):
    return rc.generalized_plant(model, input_mult=0.2, performance=rc.makeweight(3.0, (3.0, 0.25), 0.01),
                                disturbances=1.0, noise=0.01)


@pytest.mark.slow
def test_yardstick_designs_on_an_uncertain_system_and_scores_it_on_the_data():
    truth = _two_modes(4.1)  # inside the uncertain model's range, not its nominal
    f = np.logspace(-2.5, 2.5, 800)
    data = rc.FrequencyData(f, freqresp_array(truth, f), inputs=("f",), outputs=("v",))
    models = {"nominal": _two_modes(4.0), "uncertain": _uncertain()}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rc.RobustctlWarning)
        yard = rc.yardstick(data, models, _recipe, reference="uncertain", max_iter=2, autoscale=False,
                            order_d=1, progress=False)
    du, dn = yard.designs["uncertain"], yard.designs["nominal"]
    # the uncertain system's design is mixed mu with its element's real block, no worse than complex
    assert [b.kind for b in du.blocks][0] == "real" and du.blocks.blocks[0].name == "f2"
    assert np.isfinite(du.complex_mu_peak) and du.mu_peak <= du.complex_mu_peak
    assert not np.isfinite(dn.complex_mu_peak)
    # attenuation recomputed with numpy from the data: 20 log10(rms |G| / rms |(1 - G K)^-1 G|), u = K y
    G = freqresp_array(truth, f)[:, 0, 0]
    for lab, d in yard.designs.items():
        K = freqresp_array(d.K, f)[:, 0, 0]
        T = G / (1 - G * K)
        want = 20 * np.log10(np.sqrt(np.mean(np.abs(G) ** 2)) / np.sqrt(np.mean(np.abs(T) ** 2)))
        assert yard.attenuation_db[lab] == pytest.approx(want, rel=1e-9)
        # the data's verdict is the truth's: closed-loop poles by numpy
        Acl = np.block([[truth.A + truth.B @ d.K.D @ truth.C, truth.B @ d.K.C], [d.K.B @ truth.C, d.K.A]])
        assert yard.stability[lab].stable is bool(np.linalg.eigvals(Acl).real.max() < 0)
    # mu of the nominal design against the uncertain model's set is mixed mu, the real block real.
    # It spikes between grid points (0.2 at 3.0 and 3.4 Hz, 0.49 at 3.2 Hz, where measured): the
    # yardstick verifies it, and an independent grid of 600 points per decade finds the peak within
    # 2 %; treating the block as complex would give a figure ten times higher
    gp = _recipe(models["uncertain"])
    loop = lft(gp.P, dn.K, gp.nmeas, gp.ncon)
    dense = np.logspace(-1, 1.5, 1500)
    peak = mu(freqresp_array(loop, dense), gp.blocks, f_hz=dense, lower=False).peak
    i, j = yard.labels.index("nominal"), yard.labels.index("uncertain")
    assert peak * (1 - 1e-3) <= yard.mu_cross[i, j] <= 1.02 * peak  # a refined maximum: at least the grid's
    assert mu_of(loop, gp.blocks, default_grid(gp.P), refine=True)[0].peak < 0.9 * peak  # the grid misses it
    complexified = [Block("complex", b.rows, b.cols, b.name) if b.kind == "real" else b for b in gp.blocks]
    as_complex = mu_of(loop, BlockStructure(tuple(complexified)), default_grid(gp.P), refine=True)[0].peak
    assert yard.mu_cross[i, j] < 0.2 * as_complex
