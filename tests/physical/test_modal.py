"""Modal state space (MACE eqs. 2-4) against the direct second-order response."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robustctl.errors import ModelError
from robustctl.lti import freqresp
from robustctl.physical.modal import (
    ModalData,
    modal_data_statespace,
    modal_decomposition,
    modal_statespace,
)
from robustctl.physical.structure_base import StructuralMatrices

KINDS = ("displacement", "velocity", "acceleration")


def chain(n: int = 5, *, kinds=KINDS, cs: float = 0.4, free: bool = False, bands=()):
    """A spring-mass chain (grounded at dof 1 unless ``free``) with a dashpot at the tip."""
    rng = np.random.default_rng(3)
    m = 1.0 + rng.random(n)
    k = 1e3 * (1.0 + rng.random(n))
    K = np.zeros((n, n))
    for i in range(n):
        if i == 0 and not free:
            K[0, 0] += k[0]
        if i > 0:
            K[np.ix_([i - 1, i], [i - 1, i])] += k[i] * np.array([[1, -1], [-1, 1]])
    C = np.zeros((n, n))
    C[-1, -1] = cs
    b = np.zeros((n, 2))
    b[0, 0], b[n // 2, 1] = 1.0, 1.0
    c = np.zeros((len(kinds), n))
    for i in range(len(kinds)):
        c[i, (i + 1) % n] = 1.0
        c[i, -1] += 0.5
    outs = tuple(f"y{i}" for i in range(len(kinds)))
    return StructuralMatrices(
        np.diag(m), K, C, b, c, tuple(kinds), ("F1", "F2"), outs, tuple(f"dof {i + 1}" for i in range(n)),
        modal_damping_bands=tuple(bands),
    )


def direct_response(mats: StructuralMatrices, zeta, f_hz):
    """(K - w^2 M + j w C)^-1 with C = M Phi diag(2 zeta w) Phi^T M + Cs, per output kind."""
    d = modal_decomposition(mats, damping=zeta)
    M, K = mats.mass, mats.stiffness
    zeta = np.broadcast_to(np.asarray(zeta, float), d.omega.shape)
    C = M @ d.shapes @ np.diag(2 * zeta * d.omega) @ d.shapes.T @ M + mats.damping
    power = {"displacement": 0, "velocity": 1, "acceleration": 2}
    out = []
    for f in f_hz:
        s = 2j * np.pi * f
        q = np.linalg.solve(K + s * C + s * s * M, mats.input_matrix)
        rows = [s ** power[kind] * (mats.output_matrix[i] @ q) for i, kind in enumerate(mats.output_kinds)]
        out.append(np.array(rows))
    return np.array(out)


F = np.logspace(-1, 2.5, 300)


@pytest.mark.parametrize("zeta", [0.01, np.array([0.001, 0.02, 0.05, 0.003, 0.1])])
def test_all_modes_equal_direct_response(zeta):
    mats = chain()
    sys = modal_statespace(mats, damping=zeta)
    got = freqresp(sys, F).response
    ref = direct_response(mats, zeta, F)
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-8
    assert sys.input_labels == ["F1", "F2"] and sys.output_labels == ["y0", "y1", "y2"]


def test_acceleration_has_feedthrough_and_velocity_none():
    sys = modal_statespace(chain())
    D = np.asarray(sys.D)
    assert np.allclose(D[:2], 0) and np.abs(D[2]).max() > 0
    # high-frequency limit of an accelerometer: c M^-1 b
    mats = chain()
    assert np.allclose(D[2], mats.output_matrix[2] @ np.linalg.solve(mats.mass, mats.input_matrix))


def test_truncation_error_falls_as_modes_are_added():
    n = 6
    mats = chain(n, kinds=("displacement",))
    # collocated displacement sensor: every mode adds a positive static term (phi^T b)^2 / w^2
    mats = StructuralMatrices(
        mats.mass, mats.stiffness, mats.damping, mats.input_matrix[:, :1],
        mats.input_matrix[:, :1].T.copy(), ("displacement",), ("F1",), ("x1",), mats.dof_labels,
    )
    f1 = modal_decomposition(mats).f_hz[0]
    f = np.linspace(0.05, 0.5, 20) * f1
    ref = freqresp(modal_statespace(mats), f).response
    errors = [
        np.max(np.abs(freqresp(modal_statespace(mats, n_modes=k), f).response - ref) / np.abs(ref))
        for k in range(1, n + 1)
    ]
    assert all(a > b for a, b in zip(errors, errors[1:]))
    assert errors[-1] < 1e-12 and errors[0] > 1e-3
    # static correction: the residual flexibility removes most of the low-frequency error
    corrected = freqresp(modal_statespace(mats, n_modes=2, residual_flexibility=True), f).response
    assert np.max(np.abs(corrected - ref) / np.abs(ref)) < 0.05 * errors[1]


def test_residual_flexibility_exact_at_dc_for_grounded_chain():
    mats = chain(kinds=("displacement", "displacement", "velocity"))
    sys = modal_statespace(mats, n_modes=2, residual_flexibility=True)
    static = np.linalg.solve(mats.stiffness, mats.input_matrix)
    dc = np.asarray(sys.D) - np.asarray(sys.C) @ np.linalg.solve(np.asarray(sys.A), np.asarray(sys.B))
    assert np.allclose(dc[:2], mats.output_matrix[:2] @ static, rtol=1e-10)
    assert np.allclose(np.asarray(sys.D)[2], 0.0)  # no correction on velocity outputs
    # a band dropping the lowest mode takes the full-eigensolution path: same formula
    f = modal_decomposition(mats).f_hz
    d = modal_decomposition(mats, band_hz=(0.9 * f[1], 1.1 * f[2]), residual_flexibility=True)
    kept = d.output_shapes @ np.diag(d.omega**-2.0) @ d.input_shapes
    assert np.allclose(d.residual[:2], (mats.output_matrix @ static - kept)[:2], rtol=1e-10)


def test_free_free_rigid_body_modes_and_damping_rate():
    mats = chain(4, free=True, cs=0.0)
    d = modal_decomposition(mats)
    assert d.omega[0] == 0.0 and d.omega[1] > 1.0
    poles = np.linalg.eigvals(np.asarray(modal_statespace(mats).A))
    assert np.sum(np.abs(poles) < 1e-9) == 2  # the rigid-body double integrator
    poles = np.linalg.eigvals(np.asarray(modal_statespace(mats, rigid_body_damping=0.3).A))
    assert np.any(np.isclose(poles, -0.3)) and np.sum(np.abs(poles) < 1e-9) == 1
    sys = modal_statespace(mats, n_modes=3, residual_flexibility=True)
    assert np.all(np.isfinite(np.asarray(sys.D)))


def test_modal_damping_band_scales_modes_inside_only():
    base = chain(cs=0.0)
    f = modal_decomposition(base).f_hz
    band = (0.99 * f[1], 1.01 * f[2])
    mats = chain(cs=0.0, bands=[(band[0], band[1], 5.0)])
    d = modal_decomposition(mats, damping=0.01)
    assert np.allclose(d.zeta, [0.01, 0.05, 0.05, 0.01, 0.01])
    p = np.linalg.eigvals(np.asarray(modal_statespace(mats, damping=0.01).A))
    p = p[p.imag > 0]
    order = np.argsort(np.abs(p))
    assert np.allclose((-p.real / np.abs(p))[order], d.zeta, rtol=1e-9)


def test_band_with_no_modes_is_refused():
    f = modal_decomposition(chain()).f_hz
    mats = chain(bands=[(f[0] * 1.1, f[1] * 0.9, 2.0)])
    with pytest.raises(ModelError, match="contains no kept mode"):
        modal_statespace(mats)
    with pytest.raises(ModelError, match="no mode lies in the band"):
        modal_statespace(chain(), band_hz=(f[0] * 1.1, f[1] * 0.9))


def test_band_hz_keeps_modes_in_band():
    f = modal_decomposition(chain()).f_hz
    d = modal_decomposition(chain(), band_hz=(f[1] * 0.9, f[3] * 1.1))
    assert np.allclose(d.f_hz, f[1:4])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"damping": -0.01}, "finite and >= 0"),
        ({"damping": [0.01, 0.02]}, "2 values for 5 kept modes"),
        ({"rigid_body_damping": -1.0}, "rate in 1/s"),
        ({"n_modes": 9}, "n_modes must lie in 1..5"),
    ],
)
def test_bad_modal_arguments(kwargs, match):
    with pytest.raises(ModelError, match=match):
        modal_statespace(chain(), **kwargs)


def test_bad_structural_matrices():
    mats = chain()
    bad_kind = StructuralMatrices(
        mats.mass, mats.stiffness, mats.damping, mats.input_matrix, mats.output_matrix,
        ("displacement", "jerk", "velocity"), mats.inputs, mats.outputs, mats.dof_labels,
    )
    with pytest.raises(ModelError, match="output kinds must be one of"):
        modal_statespace(bad_kind)
    bad_c = StructuralMatrices(
        mats.mass, mats.stiffness, mats.damping, mats.input_matrix, mats.output_matrix[:, :3],
        mats.output_kinds, mats.inputs, mats.outputs, mats.dof_labels,
    )
    with pytest.raises(ModelError, match="one column per DOF"):
        modal_statespace(bad_c)
    singular = StructuralMatrices(
        np.diag([1.0, 0, 1, 1, 1]), mats.stiffness, None, mats.input_matrix, mats.output_matrix,
        mats.output_kinds, mats.inputs, mats.outputs, mats.dof_labels,
    )
    with pytest.raises(ModelError, match="mass matrix is singular"):
        modal_statespace(singular)


def test_modal_data_statespace_is_the_modal_sum():
    f = np.array([3.0, 1.0, 7.5])  # unsorted on purpose
    zeta = np.array([0.02, 0.01, 0.05])
    bs = np.array([[0.3, -0.2, 0.7]])
    cs = np.array([[0.5, 0.1, -0.4], [1.0, 0.0, 0.2]])
    sys = modal_data_statespace(f, zeta, bs, cs, inputs=["u"], outputs=["a", "b"], output_kind="velocity")
    freq = np.logspace(-1, 1.5, 50)
    w = 2 * np.pi * f
    s = 2j * np.pi * freq
    ref = np.zeros((freq.size, 2, 1), complex)
    for k in range(3):  # velocity: sum_k s c_k b_k / (s^2 + 2 zeta_k w_k s + w_k^2)
        ref[:, :, 0] += np.outer(s / (s**2 + 2 * zeta[k] * w[k] * s + w[k] ** 2), cs[:, k] * bs[0, k])
    got = freqresp(sys, freq).response
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-10


def test_modal_data_table_and_properties():
    d = modal_decomposition(chain(), damping=0.02)
    assert isinstance(d, ModalData) and d.n_modes == 5
    table = d.table()
    assert table.columns[1] == "f (Hz)" and len(table.rows) == 5
    assert np.allclose([r[1] for r in table.rows], d.f_hz)
    assert np.allclose(d.shapes.T @ chain().mass @ d.shapes, np.eye(5), atol=1e-12)


def test_sparse_matrices_give_the_dense_result():
    import scipy.sparse as sp

    mats = chain()
    sparse = StructuralMatrices(
        sp.csr_matrix(mats.mass), sp.csr_matrix(mats.stiffness), sp.csr_matrix(mats.damping),
        mats.input_matrix, mats.output_matrix, mats.output_kinds, mats.inputs, mats.outputs, mats.dof_labels,
    )
    dense_sys, sparse_sys = modal_statespace(mats, n_modes=3), modal_statespace(sparse, n_modes=3)
    f = np.logspace(0, 2, 40)
    assert np.allclose(freqresp(sparse_sys, f).response, freqresp(dense_sys, f).response, rtol=1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 8))
def test_property_full_modal_model_equals_direct_response(seed, n):
    """Random SPD mass, PSD+ stiffness, PSD dashpots, per-mode damping, all output kinds."""
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(n, n))
    M = L @ L.T + n * np.eye(n)
    R = rng.normal(size=(n, n))
    K = 1e3 * (R @ R.T + 0.1 * np.eye(n))
    S = rng.normal(size=(n, 2))
    Cs = 0.5 * S @ S.T
    kinds = tuple(KINDS[i % 3] for i in range(3))
    mats = StructuralMatrices(
        M, K, Cs, rng.normal(size=(n, 2)), rng.normal(size=(3, n)), kinds, ("u1", "u2"),
        ("y1", "y2", "y3"), tuple(f"dof {i + 1}" for i in range(n)),
    )
    zeta = rng.uniform(0.001, 0.1, size=n)
    f0 = modal_decomposition(mats).f_hz
    f = np.sort(np.concatenate([f0 * 0.97, f0 * 1.05, [f0[0] / 10, f0[-1] * 3]]))
    got = freqresp(modal_statespace(mats, damping=zeta), f).response
    ref = direct_response(mats, zeta, f)
    assert np.max(np.abs(got - ref)) < 1e-8 * np.max(np.abs(ref))
