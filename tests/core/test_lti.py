"""Fast frequency responses (against python-control and closed forms) and the complex-log error."""

from __future__ import annotations

import warnings

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robustctl as rc
from robustctl import lti
from robustctl.errors import DataError, ModelError

F = np.logspace(-2, 2, 60)


def control_response(sys, f_hz):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        resp = control.frequency_response(sys, 2 * np.pi * np.asarray(f_hz))
    return np.transpose(np.asarray(resp.frdata).reshape(sys.noutputs, sys.ninputs, -1), (2, 0, 1))


def random_stable(seed: int, n: int, p: int, m: int) -> control.StateSpace:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) * rng.uniform(0.5, 20)
    A -= (np.max(np.linalg.eigvals(A).real) + rng.uniform(0.05, 2.0)) * np.eye(n)
    B = rng.standard_normal((n, m))
    C = rng.standard_normal((p, n))
    D = rng.standard_normal((p, m)) * rng.integers(0, 2)
    return control.ss(A, B, C, D)


def modal_system(n_modes=10, zeta=0.01, p=2, m=3, seed=0, real_jordan=True):
    rng = np.random.default_rng(seed)
    n = 2 * n_modes
    A = np.zeros((n, n))
    for i, f in enumerate(np.logspace(-0.5, 1.5, n_modes)):
        w = 2 * np.pi * f
        wd = w * np.sqrt(1 - zeta**2)
        blk = [[-zeta * w, wd], [-wd, -zeta * w]] if real_jordan else [[0, 1], [-w * w, -2 * zeta * w]]
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = blk
    return control.ss(A, rng.standard_normal((n, m)), rng.standard_normal((p, n)), np.zeros((p, m)))


def assert_rel(actual, desired, rtol):
    err = np.abs(actual - desired) / np.abs(desired)
    assert np.max(err) < rtol, f"max relative difference {np.max(err):.3g}"


# ------------------------------------------------------------------ freqresp accuracy
@settings(max_examples=15, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 14),
    p=st.integers(1, 3),
    m=st.integers(1, 3),
)
def test_freqresp_matches_python_control_random(seed, n, p, m):
    sys = random_stable(seed, n, p, m)
    assert_rel(rc.freqresp(sys, F).response, control_response(sys, F), 1e-9)


@pytest.mark.parametrize("real_jordan", [True, False])
def test_freqresp_modal_and_hidden_modal(real_jordan):
    sys = modal_system(real_jordan=real_jordan)
    ref = control_response(sys, F)
    assert_rel(rc.freqresp(sys, F).response, ref, 1e-9)
    Q, _ = np.linalg.qr(np.random.default_rng(1).standard_normal((sys.nstates, sys.nstates)))
    hidden = control.ss(Q @ sys.A @ Q.T, Q @ sys.B, sys.C @ Q.T, sys.D)
    assert_rel(rc.freqresp(hidden, F).response, control_response(hidden, F), 1e-9)


def test_freqresp_defective_jordan_block():
    A = np.zeros((5, 5))
    A[:3, :3] = [[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, -1.0]]  # Jordan block of (s+1)^3
    A[3:, 3:] = [[-0.2, 5.0], [-5.0, -0.2]]
    B = np.array([[0.0], [0.0], [1.0], [1.0], [0.0]])
    C = np.array([[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0]])
    sys = control.ss(A, B, C, [[0.0], [0.0]])
    s = 2j * np.pi * F
    exact = np.stack([1 / (s + 1) ** 3, (s + 0.2) / ((s + 0.2) ** 2 + 25)], axis=1)[:, :, None]
    got = rc.freqresp(sys, F).response
    assert_rel(got, exact, 1e-12)
    assert_rel(got, control_response(sys, F), 1e-9)
    # the Jordan block went through the Schur path, the oscillator was diagonalised
    _, _, _, bad = lti.modal_terms(A, B, C, lti.schur_blocks(A))
    assert [sorted(b) for b in bad] == [[0, 1, 2]]


def test_freqresp_nearly_defective():
    eps = 1e-9
    A = np.array([[-2.0, 1.0], [eps, -2.0]])  # eigenvalues -2 +- sqrt(eps): V nearly singular
    sys = control.ss(A, [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    s = 2j * np.pi * F
    exact = 1.0 / ((s + 2) ** 2 - eps)
    assert_rel(rc.freqresp(sys, F).response[:, 0, 0], exact, 1e-12)


def test_schur_path_alone_matches(monkeypatch):
    sys = random_stable(7, 12, 2, 3)
    monkeypatch.setattr(lti, "COND_LIMIT", 0.0)  # force every block through the Schur solver
    assert_rel(rc.freqresp(sys, F).response, control_response(sys, F), 1e-9)


def test_freqresp_discrete_names_and_models():
    sys = control.ss(modal_system(n_modes=3, p=1, m=2), inputs=["F1", "F2"], outputs=["acc"])
    sd = control.sample_system(sys, 0.01, "zoh")
    f = np.linspace(0.1, 49.0, 40)
    got = rc.freqresp(sd, f)
    assert got.inputs == ("F1", "F2") and got.outputs == ("acc",)
    assert_rel(got.response, control_response(sd, f), 1e-9)
    tf = rc.freqresp(control.tf([2.0], [1.0, 3.0]), [1.0])
    np.testing.assert_allclose(tf.response[0, 0, 0], 2 / (2j * np.pi + 3), rtol=1e-14)
    model = rc.PhysicalModel(params=(), dynamics=lambda theta, structure: sys)
    assert_rel(rc.freqresp(model, f).response, control_response(sys, f), 1e-12)
    static = rc.freqresp(control.ss([], [], [], [[1.5, 2.0]]), [1.0, 2.0])
    np.testing.assert_array_equal(static.response, [[[1.5, 2.0]]] * 2)
    arr = lti.freqresp_array(sys, [0.0, -1.0, 3.0])
    np.testing.assert_allclose(arr[0], sys.dcgain().reshape(1, 2), rtol=1e-12)


def test_freqresp_refuses_bad_input():
    sys = modal_system(n_modes=2)
    with pytest.raises(DataError, match="NaN or inf"):
        rc.freqresp(sys, [1.0, np.nan])
    with pytest.raises(DataError, match="strictly increasing"):
        rc.freqresp(sys, [2.0, 1.0])
    with pytest.raises(DataError, match="positive"):
        rc.freqresp(sys, [0.0, 1.0])
    with pytest.raises(ModelError, match="cannot convert str"):
        rc.freqresp("not a system", [1.0])
    with pytest.raises(ModelError, match="measured data, not a model"):
        rc.freqresp(rc.FrequencyData([1.0], [1.0]), [1.0])
    with pytest.raises(ModelError, match="unspecified sampling time"):
        rc.freqresp(control.ss([[0.5]], [[1]], [[1]], [[0]], True), [0.1])
    with pytest.raises(ModelError, match="has a pole at s = .* on the frequency grid"):
        rc.freqresp(control.ss([[0.0, 1.0], [-1.0, 0.0]], [[0], [1]], [[1, 0]], [[0]]), [1 / (2 * np.pi)])
    with pytest.raises(ModelError, match="NaN or inf"):
        rc.freqresp(control.ss([[np.nan]], [[1]], [[1]], [[0]]), [1.0])


def test_as_statespace_renames():
    sys = lti.as_statespace(modal_system(n_modes=1, p=1, m=2), inputs=["a", "b"], outputs="y")
    assert list(sys.input_labels) == ["a", "b"] and list(sys.output_labels) == ["y"]
    with pytest.raises(ModelError, match="give 2 distinct inputs names"):
        lti.as_statespace(sys, inputs=["a", "a"])


# ------------------------------------------------------------------ log error and cost
@pytest.fixture
def data_and_model():
    sys = control.ss(modal_system(n_modes=3, p=2, m=2), inputs=["u1", "u2"], outputs=["x1", "x2"])
    return rc.freqresp(sys, F), sys


def test_log_error_closed_forms(data_and_model):
    data, sys = data_and_model
    np.testing.assert_allclose(rc.log_error(sys, data), 0.0, atol=1e-12)
    tau = 0.003  # a pure delay of 3 ms and a gain of 2 in the data
    delayed = data.replace(response=2 * data.response * np.exp(-2j * np.pi * F * tau)[:, None, None])
    err = rc.log_error(sys, delayed)
    np.testing.assert_allclose(err.real, np.log(2.0), rtol=1e-12)
    phase = np.broadcast_to(np.angle(np.exp(-2j * np.pi * F * tau))[:, None, None], err.shape)
    np.testing.assert_allclose(err.imag, phase, atol=1e-12)
    assert err.shape == data.shape
    model_frd = rc.freqresp(sys, F)
    np.testing.assert_allclose(rc.log_error(model_frd, delayed), err, atol=1e-12)
    banded = rc.log_error(model_frd, delayed, band=(1.0, 10.0))
    assert banded.shape[0] == np.count_nonzero((F >= 1) & (F <= 10))


def test_log_cost_mace_eq5(data_and_model):
    data, sys = data_and_model
    scaled = data.replace(response=data.response * np.exp(0.1 + 0.2j))
    n = data.response.size
    np.testing.assert_allclose(rc.log_cost(sys, scaled), n * (0.1**2 + 0.2**2), rtol=1e-10)
    w = np.linspace(0, 1, data.n_freq)
    np.testing.assert_allclose(rc.log_cost(sys, scaled, point_weights=w), w.sum() * 4 * 0.05, rtol=1e-10)
    w_entry = np.array([[1.0, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(rc.log_cost(sys, scaled, point_weights=w_entry), data.n_freq * 0.05,
                               rtol=1e-10)
    band = (1.0, 10.0)
    k = np.count_nonzero((F >= 1) & (F <= 10))
    np.testing.assert_allclose(rc.log_cost(sys, scaled, band=band), k * 4 * 0.05, rtol=1e-10)
    np.testing.assert_allclose(rc.log_cost(sys, scaled, band=band, point_weights=np.ones(data.n_freq)),
                               k * 4 * 0.05, rtol=1e-10)
    with pytest.raises(DataError, match="do not fit the banded data"):
        rc.log_cost(sys, scaled, point_weights=np.ones(3))
    with pytest.raises(DataError, match="non-negative"):
        rc.log_cost(sys, scaled, point_weights=-w)


def test_log_error_matches_names_and_refuses_mismatch(data_and_model):
    data, sys = data_and_model
    swapped = lti.as_statespace(sys[:, ::-1], inputs=["u2", "u1"])
    np.testing.assert_allclose(rc.log_error(swapped, data), 0.0, atol=1e-12)  # reordered by name
    other = lti.as_statespace(sys, outputs=["acc", "vel"])
    with pytest.raises(DataError, match=r"model's outputs \['acc', 'vel'\] do not match"):
        rc.log_error(other, data)
    with pytest.raises(DataError, match=r"the model has 1 outputs \['x1'\] but the data has 2"):
        rc.log_error(sys[0, :], data)
    with pytest.raises(DataError, match="evaluate the model on data.f_hz"):
        rc.log_error(rc.freqresp(sys, F[:-1]), data)
    zero = data.response.copy()
    zero[5, 1, 0] = 0.0
    with pytest.raises(DataError, match=r"data response is exactly zero at .* \(output 'x2', input 'u1'\)"):
        rc.log_error(sys, data.replace(response=zero))
    with pytest.raises(DataError, match="data must be a FrequencyData"):
        rc.log_error(sys, np.ones(3))
    with pytest.warns(DeprecationWarning, match=r"log_error\(model, data\)"):
        old = rc.log_error(data, swapped)  # the old (data, system) order, unambiguous
    np.testing.assert_allclose(old, 0.0, atol=1e-12)


def test_physical_ordering_modal_form_splits_into_blocks():
    """States [q; dq/dt] (as a structural model builds them): blocks are found, not contiguous."""
    rng = np.random.default_rng(3)
    w = 2 * np.pi * np.array([1.0, 2.5, 7.0, 7.0, 30.0])  # a repeated frequency included
    n = w.size
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(w**2), -np.diag(0.02 * w)]])
    A = np.pad(A, ((0, 1), (0, 1)))
    A[-1, -1] = -4.0  # a first-order sensor filter state, decoupled
    B = rng.standard_normal((2 * n + 1, 2))
    C = rng.standard_normal((3, 2 * n + 1))
    sys = control.ss(A, B, C, np.zeros((3, 2)))
    sizes = sorted(b.shape[1] for b in lti.schur_blocks(A) for _ in range(b.shape[0]))
    assert sizes == [1] + [2] * n
    assert_rel(rc.freqresp(sys, F).response, control_response(sys, F), 1e-9)


@pytest.mark.parametrize("n_points", [3, 200])  # fewer points than states: LAPACK ztrtrs per point
@pytest.mark.parametrize("shape", [(3, 2), (2, 3)])  # (outputs, inputs): the transposed side too
def test_schur_factors_evaluate_the_transfer_function(n_points, shape):
    """The Schur path of blocks kept undiagonalised, both of its solvers, against dense solves."""
    p, m = shape
    rng = np.random.default_rng(4)
    n = 30
    A = rng.standard_normal((n, n)) - 3.0 * np.eye(n)
    B, C = rng.standard_normal((n, m)), rng.standard_normal((p, n))
    s = 1j * np.linspace(0.1, 10.0, n_points)
    ref = np.stack([C @ np.linalg.solve(sk * np.eye(n) - A, B) for sk in s])
    factors = lti.schur_factors(A, B, C)
    out = lti.schur_eval(factors, s)
    assert out.shape == (n_points, p, m)
    assert np.max(np.abs(out - ref)) <= 1e-11 * np.max(np.abs(ref))
    assert np.array_equal(lti.schur_eval(factors, s), out)  # the factors are reusable


def test_is_stable_is_a_strict_open_left_half_plane_test_with_an_explicit_margin():
    import control

    damped = control.ss([[0.0, 1.0], [-4.0, -0.4]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])  # Re p = -0.2
    assert rc.lti.spectral_abscissa(damped) == pytest.approx(-0.2, rel=1e-12)
    assert rc.lti.is_stable(damped, margin=0.0) and rc.lti.is_stable(damped, margin=0.19)
    assert not rc.lti.is_stable(damped, margin=0.21)
    integrator = control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]])
    assert not rc.lti.is_stable(integrator, margin=0.0)  # on the axis: not stable
    assert rc.lti.is_stable(integrator, margin=-1e-3)  # a negative margin tolerates it
    assert rc.lti.is_stable(control.ss([], [], [], [[2.0]]), margin=0.0)  # no states
    assert rc.lti.spectral_abscissa(np.zeros((0, 0))) == -np.inf
    assert not rc.lti.is_stable(np.array([[1.0, 0.0], [0.0, -3.0]]))  # a state matrix
    assert not rc.lti.is_stable(np.array([[np.nan]]))
