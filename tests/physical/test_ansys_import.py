"""ANSYS files shipped with ansys-mapdl-reader (written by MAPDL itself), read by robustctl."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import robustctl as rc
from robustctl.errors import DataError

reader = pytest.importorskip("ansys.mapdl.reader")
from ansys.mapdl.reader import examples  # noqa: E402


def test_modal_result_gives_frequencies_and_unit_mass_shapes_at_nodes():
    res = reader.read_binary(examples.rstfile)
    modes = rc.read_ansys_modes(examples.rstfile)
    np.testing.assert_array_equal(modes.f_hz, res.time_values)
    nnum, disp = res.nodal_displacement(2)
    np.testing.assert_array_equal(modes.node_ids, nnum)
    np.testing.assert_array_equal(modes.shapes[2][:, :3], disp)
    assert modes.present[:, :3].all() and not modes.present[:, 3:].any()  # a solid model: no rotations
    mm = rc.read_ansys_modes(examples.rstfile, units="mm-t-s")
    np.testing.assert_allclose(mm.shapes[..., :3], 1e-3 / np.sqrt(1e3) * modes.shapes[..., :3])
    node = int(nnum[np.argmax(np.abs(disp[:, 2]))])
    model = rc.load_ansys_modes(
        examples.rstfile,
        inputs=[f"{node}:T3"],
        outputs=[f"{node}:T3"],
        output_kind="displacement",
        damping=0.01,
    )
    # driving-point flexibility at 0 Hz: sum of phi^2 / omega^2 over the modes
    phi = modes.shapes[:, list(nnum).index(node), 2]
    static = np.sum(phi**2 / (2 * np.pi * modes.f_hz) ** 2)
    np.testing.assert_allclose(model.freqresp([1e-3]).response[0, 0, 0].real, static, rtol=1e-9)
    with pytest.raises(DataError, match=r"lacks"):
        rc.load_ansys_modes(examples.rstfile, inputs=[f"{node}:R1"], outputs=[f"{node}:T3"])


def test_full_file_matrices_without_constrained_dofs_give_the_same_modes_as_scipy():
    full = reader.read_binary(examples.fullfile)
    dof_ref, k, m = full.load_km(sort=True)
    K, M = k.toarray(), m.toarray()
    free = ~((np.diag(K) == 0) & (np.diag(M) == 0))
    # the file stores the upper triangles: scipy reads them as they are
    lam = sla.eigh(K[np.ix_(free, free)], M[np.ix_(free, free)], eigvals_only=True, lower=False)
    w_ref = np.sqrt(lam[:6]) / (2 * np.pi)
    Mi, Ki, labels = rc.read_ansys_matrices(examples.fullfile)
    assert len(labels) == free.sum() and labels[0].count(":") == 1
    node, comp = dof_ref[free][0]
    assert labels[0] == f"{node}:{('T1', 'T2', 'T3')[comp]}"
    model = rc.load_ansys_matrices(
        examples.fullfile,
        inputs=[labels[30]],
        outputs=[labels[30]],
        n_modes=6,
        lumped_masses={"probe": [labels[30]]},
    )
    poles = np.linalg.eigvals(model.statespace().A)
    f_model = np.sort(np.abs(poles[poles.imag > 0])) / (2 * np.pi)
    np.testing.assert_allclose(f_model, w_ref, rtol=1e-4)  # |p| = omega_n with 1 % damping
    assert "m_probe" in model.param_names


def test_mesh_geometry_and_a_3d_figure_of_the_ansys_modes(tmp_path):
    geo = rc.load_ansys_geometry(examples.rstfile)
    res = reader.read_binary(examples.rstfile)
    np.testing.assert_array_equal(geo.node_ids, res.mesh.nnum)
    used = geo.xyz[geo.index(np.unique(geo.lines))]  # the elements' corner edges span the whole beam
    np.testing.assert_allclose(
        [used.min(axis=0), used.max(axis=0)], [geo.xyz.min(axis=0), geo.xyz.max(axis=0)]
    )
    modes = rc.read_ansys_modes(examples.rstfile)
    fig = rc.plot_mode_shapes(modes, geo)
    deformed = [c for ax in fig.axes for c in ax.collections if c.get_gid() == "deformed"]
    assert len(deformed) == modes.n_modes == 6
    fig.savefig(tmp_path / "ansys.png", dpi=70)
