"""Uncertain elements and systems: LFT algebra against direct evaluation at sampled values.

The reference is independent of robustctl's LFT code: every expression is also evaluated
directly in the frequency domain with numpy (products, sums, ``(I - s G K)^-1 G``, matrix
inverses) from python-control's responses of the certain parts and the sampled values.
"""

from __future__ import annotations

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import SynthesisError
from robustctl.robust.uncertainty import append, hstack, vstack

F_HZ = np.array([0.0, 0.013, 0.11, 0.47, 1.3, 5.1])
S = 2j * np.pi * F_HZ


def _eval_tf(sys) -> np.ndarray:
    ss = control.ss(sys)
    A, B, C, D = (np.asarray(x) for x in (ss.A, ss.B, ss.C, ss.D))
    return np.stack([C @ np.linalg.solve(s * np.eye(A.shape[0]) - A, B) + D if A.size else D for s in S])


def _random_stable(rng, order=None):
    n = int(rng.integers(1, 4)) if order is None else order
    poles = -rng.uniform(0.3, 5.0, n)
    A = np.diag(poles) + np.triu(rng.standard_normal((n, n)) * 0.3, 1)
    B, C, D = rng.standard_normal((n, 1)), rng.standard_normal((1, n)), rng.standard_normal((1, 1))
    return control.ss(A, B, C, D)


def _leaves(rng, n_elements):
    els = []
    for i in range(n_elements):
        kind = rng.integers(0, 3)
        if kind == 0:
            els.append(rc.ureal(f"p{i}", float(rng.uniform(0.5, 2)), percent=float(rng.uniform(5, 40))))
        elif kind == 1:
            els.append(rc.ucomplex(f"c{i}", complex(rng.uniform(0.5, 1.5), rng.uniform(-0.5, 0.5)), 0.3))
        else:
            els.append(rc.ultidyn(f"d{i}", (1, 1), float(rng.uniform(0.1, 0.5))))
    return els


def _value_frf(el, value):
    if isinstance(value, control.StateSpace):
        return _eval_tf(value)
    return np.full((F_HZ.size, 1, 1), value, complex)


def _build(rng, els, vals):
    """A random expression: (uncertain system, its direct response at ``vals``)."""
    items = []
    for el in els:
        items.append((rc.as_uncertain(el), _value_frf(el, vals[el.name])))
    for _ in range(2):
        G = _random_stable(rng)
        items.append((rc.as_uncertain(G), _eval_tf(G)))
    for _ in range(int(rng.integers(4, 8))):
        i, j = rng.integers(0, len(items), 2)  # with replacement: elements reappear
        (a, fa), (b, fb) = items[i], items[j]
        op = rng.integers(0, 6)
        if op == 0:
            new = (a + b, fa + fb)
        elif op == 1:
            new = (a - b, fa - fb)
        elif op == 2:
            new = (a * b, fa @ fb)
        elif op == 3:
            new = (a.feedback(b), np.linalg.solve(np.eye(1) + fa @ fb, fa))
        elif op == 4:
            new = (a.feedback(b, sign=1), np.linalg.solve(np.eye(1) - fa @ fb, fa))
        else:
            new = (2.0 * a + 1.5, 2.0 * fa + 1.5)
        items.append(new)
    return items[-1]


@pytest.mark.parametrize("seed", range(8))
def test_lft_at_sampled_values_equals_the_system_built_at_those_values(seed):
    rng = np.random.default_rng(seed)
    els = _leaves(rng, int(rng.integers(3, 7)))
    probe = rc.as_uncertain(els[0])
    for e in els[1:]:
        probe = probe + e
    for vals in probe.sample(3, seed=seed):
        usys, direct = _build(np.random.default_rng(seed), els, vals)
        vals_used = {k: v for k, v in vals.items() if k in usys.elements}
        lft = usys.freqresp(F_HZ, vals_used)
        scale = max(np.abs(direct).max(), 1.0)
        assert np.abs(lft - direct).max() <= 1e-10 * scale
        sub = usys.substitute(vals_used)  # the state-space closure, evaluated on its own
        resp = _eval_tf(sub) if isinstance(sub, control.StateSpace) else sub.freqresp(F_HZ)
        assert np.abs(resp - direct).max() <= 1e-10 * scale


def test_mimo_concatenation_indexing_and_names_against_direct_evaluation():
    rng = np.random.default_rng(3)
    k = rc.ureal("k", 2.0, plusminus=0.5)
    d = rc.ultidyn("d", (1, 1), 0.2)
    G1 = control.ss(_random_stable(rng, 2), inputs=["force"], outputs=["disp"])
    G2 = _random_stable(rng, 1)
    P = append(k * G1, G2 * (1 + d))
    assert P.inputs == ("force", "u[0]") and P.outputs[0] == "disp"
    vals = {"k": 1.7, "d": control.ss([[-2.0]], [[1.0]], [[0.3]], [[0.05]])}
    D = _eval_tf(vals["d"])
    direct = np.zeros((F_HZ.size, 2, 2), complex)
    direct[:, :1, :1] = 1.7 * _eval_tf(G1)
    direct[:, 1:, 1:] = _eval_tf(G2) * (1 + D)
    assert np.abs(P.freqresp(F_HZ, vals) - direct).max() <= 1e-10 * np.abs(direct).max()
    H = hstack(k * G1, G2)
    V = vstack(G1, d * G2)
    row = np.c_[1.7 * _eval_tf(G1)[:, 0, 0], _eval_tf(G2)[:, 0, 0]]
    assert np.abs(H.freqresp(F_HZ, vals)[:, 0, :] - row).max() <= 1e-12 * np.abs(row).max()
    assert np.abs(V.freqresp(F_HZ, vals)[:, 1, 0] - D[:, 0, 0] * _eval_tf(G2)[:, 0, 0]).max() <= 1e-12
    sub = P[1, 1]
    assert np.abs(sub.freqresp(F_HZ, vals)[:, 0, 0] - direct[:, 1, 1]).max() <= 1e-12
    # the inverse of a biproper factor
    B = rc.as_uncertain(control.ss([[-1.0]], [[1.0]], [[1.0]], [[2.0]])) * k + 1
    Bi = (1 / B).freqresp(F_HZ, {"k": 2.3})
    assert np.abs(Bi[:, 0, 0] * (2.3 * (1 / (S + 1) + 2) + 1) - 1).max() <= 1e-12


def test_repeated_uses_collapse_to_the_fewest_copies():
    k = rc.ureal("k", 2.0, percent=20)
    G = control.tf([1], [1, 1])
    H = control.tf([1, 2], [1, 3, 5])
    # both branches read k u (reachability), or both outputs of k are summed (observability):
    # one copy suffices (the structured Kalman reduction)
    assert (G * k + H * k).multiplicity == {"k": 1}
    assert (k * G + k * H).multiplicity == {"k": 1}
    ref = 1.9 * (1 / (S + 1) + (S + 2) / (S**2 + 3 * S + 5))
    assert np.abs((k * G + k * H).freqresp(F_HZ, {"k": 1.9})[:, 0, 0] - ref).max() <= 1e-12
    # k G k is k^2 G: the structure needs two
    assert (k * G * k).multiplicity == {"k": 2}
    # a mass-spring-damper 1 / (m s^2 + c s + k): each parameter once
    m, c = rc.ureal("m", 3.0, percent=40), rc.ureal("c", 1.0, percent=20)
    x = rc.as_uncertain(control.tf([1], [1, 0]))
    msd = (x * (x * (1 / m)).feedback(c)).feedback(k)
    assert msd.multiplicity == {"m": 1, "c": 1, "k": 1}
    v = {"m": 2.1, "c": 1.1, "k": 2.5}
    ref = 1 / (2.1 * S**2 + 1.1 * S + 2.5)
    assert np.abs(msd.freqresp(F_HZ, v)[:, 0, 0] - ref).max() <= 1e-12 * np.abs(ref).max()
    lft = msd.lft()
    assert [b.kind for b in lft.blocks] == ["real"] * 3
    assert lft.M.ninputs == 4 and lft.M.noutputs == 4


def test_sampling_is_seeded_and_inside_the_ranges():
    k = rc.ureal("k", 2.0, range=(1.0, 4.0))
    c = rc.ucomplex("c", 1j, 0.5)
    d = rc.ultidyn("d", (2, 1), 0.3)
    sys = rc.as_uncertain(np.ones((2, 1))) * (k + c) + d
    a, b = sys.sample(20, seed=7), sys.sample(20, seed=7)
    assert [x["k"] for x in a] == [x["k"] for x in b]
    assert all(1.0 <= x["k"] <= 4.0 and abs(x["c"] - 1j) <= 0.5 for x in a)
    for x in a:  # a sampled dynamics value: stable, norm within the bound
        D = x["d"]
        assert np.all(np.linalg.eigvals(D.A).real < 0)
        w = np.geomspace(1e-3, 1e4, 150)
        gains = [np.linalg.norm(D.C @ np.linalg.solve(1j * wk * np.eye(D.nstates) - D.A, D.B) + D.D, 2)
                 for wk in w]
        assert max(gains) <= 0.3 * (1 + 1e-9)
    frs = sys.freqresp(F_HZ, a[:4])
    assert frs.shape == (4, F_HZ.size, 2, 1)


def test_compact_repr_and_clear_errors():
    k = rc.ureal("k", 10.0, percent=50)
    sys = k * control.tf([1], [1, 1])
    text = repr(sys)
    assert "k: real 10 +- 5 (50 %)" in text and "A =" not in text and len(text.splitlines()) == 2
    with pytest.raises(SynthesisError, match="exactly one of"):
        rc.ureal("k", 1.0)
    with pytest.raises(SynthesisError, match="contain the nominal"):
        rc.ureal("k", 0.0, percent=10)
    with pytest.raises(SynthesisError, match="invertible feedthrough"):
        1 / (k * control.tf([1], [1, 1]))
    with pytest.raises(SynthesisError, match="no uncertain element named"):
        sys.substitute(q=1.0)
    with pytest.raises(SynthesisError, match="both named"):
        k + rc.ureal("k", 1.0, percent=5)


def test_update_parameters_as_uncertain_reals_and_the_model_as_an_uncertain_system():
    from test_residual import NOMINAL, analytic_receptance, chain_model

    f = np.linspace(0.5, 12.0, 120)
    rng = np.random.default_rng(3)
    g = analytic_receptance({**NOMINAL, "k2": 2100.0}, f)  # the truth, in numpy
    g = g * (1 + 0.01 * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    data = rc.FrequencyData(f, g, inputs=["f1", "f2"], outputs=["x1", "x2"])
    upd = rc.update(chain_model(), data, params=["k2"], max_iter=20)
    reals = upd.uncertain_parameters(n_sigma=2.0)
    k2 = reals["k2"]
    se = upd.std_errors["k2"]
    assert k2.nominal == pytest.approx(upd.model.values["k2"], rel=1e-12)
    assert (k2.low, k2.high) == pytest.approx((k2.nominal - 2 * se, k2.nominal + 2 * se), rel=1e-12)
    assert k2.low < 2100.0 < k2.high  # the truth inside the 2-sigma interval
    # the updated model with k2 uncertain: exact (stiffness is affine), checked against numpy
    usys = rc.physical_uncertain(upd.model, reals)
    assert usys.multiplicity == {"k2": 1} and "k2: real" in repr(usys)
    for kv in (k2.low, k2.nominal, k2.high):
        th = {**dict(upd.model.values), "k2": kv}
        ref = analytic_receptance(th, f[:5])
        got = usys.freqresp(f[:5], {"k2": kv})
        assert np.abs(got - ref).max() <= 1e-9 * np.abs(ref).max()


def test_uncertain_model_prints_in_a_few_lines():
    from test_uncertain_model import chain

    from robustctl.physical.uncertain import parametric_lft

    um = parametric_lft(chain(), ["k1", "k2"], [1000.0, 500.0], np.diag([400.0, 100.0]), n_sigma=2.0)
    text = repr(um)
    assert text.startswith("UncertainModel(2x2, 4 states") and "\n" not in text and "array" not in text
    usys = rc.as_uncertain(um)  # its blocks as normalised reals, the same LFT
    d = {um.names[0]: 0.3, um.names[1]: -0.8}
    ref = freqresp_um(um, [0.3, -0.8])
    np.testing.assert_allclose(usys.freqresp(F_HZ[1:], d), ref, rtol=1e-10, atol=1e-16)


def freqresp_um(um, delta):
    from robustctl.lti import freqresp_array

    return freqresp_array(um.statespace(np.array(delta)), F_HZ[1:])
