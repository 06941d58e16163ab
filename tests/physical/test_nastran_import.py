"""Nastran files written by pyNastran's own writers from rc.Frame models, read back by robustctl."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import robustctl as rc
from robustctl.errors import DataError

pytest.importorskip("pyNastran")
pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
from robustctl.physical.nastran_import import _pynastran, write_nastran_matrices, write_nastran_modes  # noqa: E402

OP2, OP4, BDF = _pynastran()

PROPS = dict(E=7.0e10, G=2.6e10, rho=2700.0, A=2.0e-4, Iy=3.0e-9, Iz=5.0e-9, J=6.0e-9)
# a clamped 3-D portal frame: four columns, four beams, grids named by Nastran ids
BASE = {1001: (0, 0, 0), 1002: (1.0, 0, 0), 1003: (1.0, 0.8, 0), 1004: (0, 0.8, 0)}
TOP = {2001: (0, 0, 1.2), 2002: (1.0, 0, 1.2), 2003: (1.0, 0.8, 1.2), 2004: (0, 0.8, 1.2)}
COMPONENT = {"ux": "T1", "uy": "T2", "uz": "T3", "rx": "R1", "ry": "R2", "rz": "R3"}
GROUPS = ("columns", "beams")


def portal_frame(k_columns: float = 1.0, k_beams: float = 1.0, tip_mass: float = 0.0) -> rc.Frame:
    fr = rc.Frame()
    for nid, xyz in {**BASE, **TOP}.items():
        fr.add_node(str(nid), xyz)
    for b, t in zip(BASE, TOP):
        fr.add_beam("columns", str(b), str(t), **PROPS)
        fr.fix(str(b))
    tops = list(TOP)
    for a, b in zip(tops, tops[1:] + tops[:1]):
        fr.add_beam("beams", str(a), str(b), **PROPS)
    fr.add_mass("2003", 0.8 + tip_mass)
    fr.add_force_input("F", "2001", "x")
    fr.add_output("a", "2003", "y")
    if k_columns != 1.0:
        fr.scale_group_stiffness("columns", k_columns)
    if k_beams != 1.0:
        fr.scale_group_stiffness("beams", k_beams)
    return fr


def nastran_labels(frame_labels):
    return [f"{lb.split()[0]}:{COMPONENT[lb.split()[1]]}" for lb in frame_labels]


def frame_matrices(**kw):
    m = portal_frame(**kw).matrices(sparse=False)
    return np.asarray(m.mass), np.asarray(m.stiffness), nastran_labels(m.dof_labels)


# ---------------------------------------------------------------------------- file writers (pyNastran)
def write_modes_op2(path, f_hz_32, shapes_32, node_ids, genmass_32):
    modes = rc.ModeShapes(
        f_hz=f_hz_32.astype(float),
        node_ids=node_ids,
        shapes=shapes_32.astype(float),
        generalized_mass=genmass_32.astype(float),
    )
    write_nastran_modes(path, modes)


def write_op4(path, matrices):
    write_nastran_matrices(path, matrices)


def frame_mode_file(tmp_path):
    """The portal frame's modes at every grid as an OP2 (NORM=MAX shapes, LAMA generalised masses),
    and the exactly representable numbers written."""
    fr = portal_frame()
    f, phi = fr.modes()
    labels = fr.matrices().dof_labels
    nodes = sorted({int(lb.split()[0]) for lb in labels} | set(BASE))
    shapes = np.zeros((f.size, len(nodes), 6))
    for row, lb in enumerate(labels):
        node, comp = lb.split()
        shapes[:, nodes.index(int(node)), list(COMPONENT).index(comp)] = phi[row]
    peak = np.max(np.abs(shapes.reshape(f.size, -1)), axis=1).astype(np.float32)
    shapes_32 = (shapes / peak[:, None, None]).astype(np.float32)  # NORM=MAX
    genmass_32 = (1.0 / peak.astype(float) ** 2).astype(np.float32)
    f_32 = f.astype(np.float32)
    path = tmp_path / "portal.op2"
    write_modes_op2(path, f_32, shapes_32, np.array(nodes), genmass_32)
    return path, f_32, shapes_32, genmass_32, nodes


# ---------------------------------------------------------------------------- OP2 modes
def test_op2_modal_model_equals_the_builtin_modal_model(tmp_path):
    path, f_32, shapes_32, gm_32, nodes = frame_mode_file(tmp_path)
    ins, outs = ["2001:T1", "2002:T3"], ["2003:T2", "2004:T1", "2002:R1"]
    model = rc.load_nastran_modes(path, inputs=ins, outputs=outs, damping=0.02, output_kind="displacement")
    assert model.inputs == tuple(ins) and model.outputs == tuple(outs)

    # the built-in model from the numbers written: frequency from the stored eigenvalue
    # (2 pi f)^2 in float32, shapes divided by sqrt(generalised mass)
    eig_32 = ((2 * np.pi * f_32.astype(float)) ** 2).astype(np.float32).astype(float)
    f_ref = np.sqrt(eig_32) / (2 * np.pi)
    phi = shapes_32.astype(float) / np.sqrt(gm_32.astype(float))[:, None, None]

    def at(dof):
        node, comp = dof.split(":")
        return phi[:, nodes.index(int(node)), ["T1", "T2", "T3", "R1", "R2", "R3"].index(comp)]

    ref = rc.modal_model(
        f_ref,
        0.02,
        np.array([at(d) for d in ins]),
        np.array([at(d) for d in outs]),
        inputs=ins,
        outputs=outs,
        output_kind="displacement",
    )
    f_hz = np.geomspace(1.0, 1.5 * f_ref.max(), 400)
    got, want = model.freqresp(f_hz).response, ref.freqresp(f_hz).response
    assert np.max(np.abs(got - want) / np.max(np.abs(want))) < 1e-10

    # and the frame's own modal model (float64) to single precision
    mats = portal_frame().matrices(sparse=False)
    labels = nastran_labels(mats.dof_labels)
    w, vecs = sla.eigh(mats.stiffness, mats.mass)
    w = np.sqrt(w)
    b = vecs[[labels.index(d) for d in ins]]
    c = vecs[[labels.index(d) for d in outs]]
    s = 2j * np.pi * f_hz[:, None]
    h = np.einsum("ok,fk,ik->foi", c, 1.0 / (w**2 + 2 * 0.02 * w * s + s**2), b)
    assert np.max(np.abs(got - h) / np.max(np.abs(h))) < 1e-5


def test_op2_read_gives_frequencies_generalised_masses_and_shapes(tmp_path):
    path, f_32, shapes_32, gm_32, nodes = frame_mode_file(tmp_path)
    modes = rc.read_nastran_modes(path)
    assert modes.n_modes == f_32.size and list(modes.node_ids) == nodes
    np.testing.assert_allclose(modes.f_hz, f_32, rtol=1e-6)
    np.testing.assert_array_equal(modes.generalized_mass, gm_32.astype(float))
    np.testing.assert_array_equal(modes.shapes, shapes_32.astype(float))
    mm = rc.read_nastran_modes(path, units="mm-t-s")  # mm and tonnes: phi_SI = 1e-3 / sqrt(1e3) phi
    np.testing.assert_allclose(
        mm.mass_normalized()[..., :3], 1e-3 / np.sqrt(1e3) * modes.mass_normalized()[..., :3]
    )


def test_op2_missing_grid_or_direction_names_the_channel_and_the_fix(tmp_path):
    path, *_ = frame_mode_file(tmp_path)
    with pytest.raises(DataError, match=r"output '9999:T3'.*node 9999"):
        rc.load_nastran_modes(path, inputs=["2001:T1"], outputs=["9999:T3"])
    with pytest.raises(DataError, match=r"output 'S1'.*'node:direction'"):
        rc.load_nastran_modes(path, inputs=["2001:T1"], outputs=["S1"])
    with pytest.raises(DataError, match="units="):
        rc.load_nastran_modes(path, inputs=["2001:T1"], outputs=["2003:T2"], units="cm-g-s")
    geo = rc.Geometry([2003], [(1.0, 0.8, 1.2)], sensors={"S1": (2003, (0.0, 0.6, 0.8))})
    model = rc.load_nastran_modes(path, inputs=["2001:T1"], outputs=["S1"], geometry=geo)
    ref = rc.load_nastran_modes(path, inputs=["2001:T1"], outputs=["2003:T2", "2003:T3"])
    f = np.array([3.0, 7.0, 20.0])
    both = ref.freqresp(f).response[:, :, 0]
    np.testing.assert_allclose(
        model.freqresp(f).response[:, 0, 0], 0.6 * both[:, 0] + 0.8 * both[:, 1], rtol=1e-12
    )


# ---------------------------------------------------------------------------- OP4 matrices
def group_partitions():
    M, K, labels = frame_matrices()
    parts = {}
    for g in GROUPS:
        _, K2, _ = frame_matrices(**{f"k_{g}": 2.0})
        parts[g] = K2 - K
    return M, K, parts, labels


@pytest.fixture(scope="module")
def op4_file(tmp_path_factory):
    M, K, parts, labels = group_partitions()
    path = tmp_path_factory.mktemp("op4") / "portal.op4"
    write_op4(path, {"MAA": M, "KAA": K, "KCOL": parts["columns"], "KBEAM": parts["beams"]})
    return path, labels


def _imported(op4_file, **kw):
    path, labels = op4_file
    return rc.load_nastran_matrices(
        path,
        inputs={"F": "2001:T1"},
        outputs={"a": "2003:T2"},
        groups={"columns": "kcol", "beams": "KBEAM"},
        dof_labels=labels,
        damping=0.01,
        **kw,
    )


def test_op4_group_partitions_reproduce_the_frame_for_several_superparameters(op4_file):
    model = _imported(op4_file)
    assert {"k_columns", "k_beams"} <= set(model.param_names)
    f_hz = np.geomspace(2.0, 400.0, 300)
    for kc, kb in [(1.0, 1.0), (1.3, 1.0), (0.7, 1.6), (1.1, 0.5)]:
        M, K, labels = frame_matrices(k_columns=kc, k_beams=kb)
        ref = rc.structural_model(
            M,
            K,
            inputs={"F": "2001:T1"},
            outputs={"a": ("2003:T2", "acceleration")},
            dof_labels=labels,
            damping=0.01,
        )
        got = model.freqresp(f_hz, k_columns=kc, k_beams=kb).response
        want = ref.freqresp(f_hz).response
        assert np.max(np.abs(got - want) / np.max(np.abs(want))) < 1e-9, (kc, kb)


def test_op4_lumped_mass_parameter_adds_kilograms_at_the_grid(op4_file):
    path, labels = op4_file
    model = rc.load_nastran_matrices(
        path, inputs=["2001:T1"], outputs=["2003:T2"], dof_labels=labels, lumped_masses={"tip": 2003}
    )
    M, K, _ = frame_matrices(tip_mass=0.5)
    ref = rc.structural_model(
        M,
        K,
        inputs={"2001:T1": "2001:T1"},
        outputs={"2003:T2": ("2003:T2", "acceleration")},
        dof_labels=labels,
    )
    f_hz = np.geomspace(2.0, 400.0, 200)
    got, want = model.freqresp(f_hz, m_tip=0.5).response, ref.freqresp(f_hz).response
    assert np.max(np.abs(got - want) / np.max(np.abs(want))) < 1e-9


def test_op4_errors_name_the_dof_and_the_fix(op4_file):
    path, labels = op4_file
    with pytest.raises(DataError, match=r"dof_labels"):
        rc.load_nastran_matrices(path, inputs=["2001:T1"], outputs=["2003:T2"])
    with pytest.raises(DataError, match=r"output '1001:T3'.*grid 1001 is not in the matrices"):
        rc.load_nastran_matrices(path, inputs=["2001:T1"], outputs=["1001:T3"], dof_labels=labels)
    with pytest.raises(DataError, match=r"no matrix 'KXX'"):
        rc.load_nastran_matrices(
            path, inputs=["2001:T1"], outputs=["2003:T2"], dof_labels=labels, groups={"x": "KXX"}
        )
    with pytest.raises(DataError, match=r"12 names but the matrices have 24"):
        rc.load_nastran_matrices(path, inputs=["2001:T1"], outputs=["2003:T2"], dof_labels=labels[:12])


def test_update_on_the_imported_model_recovers_a_hidden_column_stiffness_change(op4_file):
    truth_k = 1.06
    M, K, labels = frame_matrices(k_columns=truth_k)
    w2, vecs = sla.eigh(K, M)  # the measurement: modal synthesis with numpy/scipy, not the simulator
    w = np.sqrt(w2)
    i, o = labels.index("2001:T1"), labels.index("2003:T2")
    f_hz = np.linspace(5.0, 1.2 * w[5] / (2 * np.pi), 600)
    s = 2j * np.pi * f_hz
    h = s**2 * np.sum(vecs[o] * vecs[i] / (w**2 + 2 * 0.01 * w * s[:, None] + s[:, None] ** 2), axis=1)
    rng = np.random.default_rng(7)
    noisy = h * (1 + 0.01 * (rng.standard_normal(h.size) + 1j * rng.standard_normal(h.size)) / np.sqrt(2))
    data = rc.FrequencyData(f_hz, noisy[:, None, None], inputs=("F",), outputs=("a",))
    model = _imported(op4_file)
    upd = rc.update(
        model,
        data,
        params=["k_columns"],
        band=(f_hz[0], f_hz[-1]),
        select=False,
        drift_bands=0,
        point_weights=None,
        progress=False,
    )
    est = upd.model.values["k_columns"]
    se = upd.std_errors["k_columns"]
    assert 0 < se < 0.01
    assert abs(est - truth_k) < 2 * se


# ---------------------------------------------------------------------------- DMIG and BDF
def grid_component(label):
    grid, comp = label.split(":")
    return int(grid), ["T1", "T2", "T3", "R1", "R2", "R3"].index(comp) + 1


def test_dmig_matrices_in_a_bdf_carry_their_dof_names(tmp_path):
    def ten_digits(a):  # what a 16-character DMIG* field holds exactly
        return np.vectorize(lambda x: float(f"{x:.9e}"))(a)

    M, K, parts, labels = group_partitions()
    M, K = ten_digits(M), ten_digits(K)
    parts = {g: ten_digits(k) for g, k in parts.items()}
    model = BDF(debug=None)
    for nid, xyz in {**BASE, **TOP}.items():
        model.add_grid(nid, list(xyz))
    for name, mat in {"MAA": M, "KAA": K, "KCOL": parts["columns"], "KBEAM": parts["beams"]}.items():
        gcj, gci, real = [], [], []
        for c in range(mat.shape[1]):
            for r in range(c, mat.shape[0]):  # lower triangle of a symmetric (ifo=6) matrix
                if mat[r, c] != 0.0:
                    gcj.append(grid_component(labels[c]))
                    gci.append(grid_component(labels[r]))
                    real.append(float(mat[r, c]))
        model.add_dmig(name, 6, 2, 2, 0, 0, gcj, gci, real)
    for k, (b, t) in enumerate(zip(BASE, TOP), start=1):
        model.add_conrod(k, 1, [b, t], A=1.0)
    path = tmp_path / "portal.bdf"
    model.write_bdf(str(path), size=16, is_double=True)
    mats, found = rc.read_nastran_matrices(path)
    assert sorted(found) == sorted(labels)
    perm = [found.index(lb) for lb in labels]
    np.testing.assert_allclose(mats["KAA"].toarray()[np.ix_(perm, perm)], K, rtol=1e-14)
    imported = rc.load_nastran_matrices(
        path, inputs={"F": "2001:T1"}, outputs={"a": "2003:T2"}, groups={"columns": "KCOL", "beams": "KBEAM"}
    )
    ref = rc.structural_model(
        M,
        K + 0.4 * parts["beams"],
        inputs={"F": "2001:T1"},
        outputs={"a": ("2003:T2", "acceleration")},
        dof_labels=labels,
    )
    f_hz = np.geomspace(2.0, 300.0, 200)
    got, want = imported.freqresp(f_hz, k_beams=1.4).response, ref.freqresp(f_hz).response
    assert np.max(np.abs(got - want) / np.max(np.abs(want))) < 1e-9
    geo = rc.load_bdf_geometry(path, sensors={"S1": "2003:+Y"})
    assert list(geo.node_ids) == sorted({**BASE, **TOP})
    np.testing.assert_allclose(geo.xyz[geo.index([2003])[0]], TOP[2003])
    assert {tuple(x) for x in geo.lines.tolist()} == {(b, t) for b, t in zip(BASE, TOP)}
    assert geo.sensor("S1")[0] == 2003 and np.allclose(geo.sensor("S1")[1], [0, 1, 0])
    mm = rc.load_bdf_geometry(path, units="mm-t-s")
    np.testing.assert_allclose(mm.xyz, 1e-3 * geo.xyz)


def test_op2_from_pynastrans_own_writer_without_lama_is_taken_as_mass_normalised(tmp_path):
    from pyNastran.op2.tables.oug.oug_eigenvectors import RealEigenvectorArray

    fr = portal_frame()
    f, phi = fr.modes()
    labels = nastran_labels(fr.matrices().dof_labels)
    nodes = sorted(TOP)
    data = np.zeros((f.size, len(nodes), 6), np.float32)
    for row, lb in enumerate(labels):
        grid, comp = lb.split(":")
        data[:, nodes.index(int(grid)), ["T1", "T2", "T3", "R1", "R2", "R3"].index(comp)] = phi[row]
    op2 = OP2(debug=None)
    op2.set_mode("msc")
    grid = np.column_stack([nodes, np.ones(len(nodes), int)])
    eigs = (2 * np.pi * f) ** 2
    op2.eigenvectors[1] = RealEigenvectorArray.add_modal_case(
        "OUGV1", grid, data, 1, np.arange(1, f.size + 1), eigs, f, is_sort1=True
    )
    op2.write_op2(str(tmp_path / "plain.op2"), post=-1, endian=b"<")
    modes = rc.read_nastran_modes(tmp_path / "plain.op2")
    np.testing.assert_array_equal(modes.generalized_mass, 1.0)
    np.testing.assert_allclose(modes.f_hz, f, rtol=1e-7)  # eigenvalues stored in single precision
    np.testing.assert_array_equal(modes.shapes, data.astype(float))


def test_a_model_built_in_millimetres_and_tonnes_imports_in_si(tmp_path):
    """The same frame assembled in mm-t-s (N/mm^2, t/mm^3, mm^4) and read with units="mm-t-s"."""
    mm = dict(E=7.0e4, G=2.6e4, rho=2.7e-9, A=200.0, Iy=3.0e3, Iz=5.0e3, J=6.0e3)
    fr = rc.Frame()
    for nid, xyz in {**BASE, **TOP}.items():
        fr.add_node(str(nid), tuple(1e3 * np.asarray(xyz, float)))
    for b, t in zip(BASE, TOP):
        fr.add_beam("columns", str(b), str(t), **mm)
        fr.fix(str(b))
    tops = list(TOP)
    for a, b in zip(tops, tops[1:] + tops[:1]):
        fr.add_beam("beams", str(a), str(b), **mm)
    fr.add_mass("2003", 0.8e-3)
    m = fr.matrices(sparse=False)
    labels = nastran_labels(m.dof_labels)
    write_op4(tmp_path / "mm.op4", {"MAA": np.asarray(m.mass), "KAA": np.asarray(m.stiffness)})
    model = rc.load_nastran_matrices(
        tmp_path / "mm.op4",
        inputs=["2001:T1"],
        outputs=["2003:T2", "2002:R1"],
        dof_labels=labels,
        units="mm-t-s",
        output_kind="displacement",
    )
    M, K, _ = frame_matrices()
    ref = rc.structural_model(
        M,
        K,
        inputs={"2001:T1": "2001:T1"},
        dof_labels=labels,
        outputs={"2003:T2": ("2003:T2", "displacement"), "2002:R1": ("2002:R1", "displacement")},
    )
    f_hz = np.geomspace(2.0, 300.0, 200)
    got, want = model.freqresp(f_hz).response, ref.freqresp(f_hz).response
    assert np.max(np.abs(got - want) / np.max(np.abs(want), axis=0)) < 1e-8  # m/N and rad/N


def test_bdf_grid_with_a_local_displacement_frame_is_refused_with_the_fix(tmp_path):
    (tmp_path / "cd.bdf").write_text(
        "BEGIN BULK\nGRID,1,,0.,0.,0.,5\nGRID,2,,1.,0.,0.\nCORD2R,5,,0.,0.,0.,0.,0.,1.\n,1.,0.,0.\nENDDATA\n"
    )
    with pytest.raises(DataError, match=r"grid 1 uses displacement frame CD=5.*OUGCORD"):
        rc.load_bdf_geometry(tmp_path / "cd.bdf")


def test_dmig_writer_round_trip_keeps_the_matrices_to_field_precision(tmp_path):
    M, K, parts, labels = group_partitions()
    path = tmp_path / "portal.pch"
    write_nastran_matrices(path, {"MAA": M, "KAA": K, "KCOL": parts["columns"]}, dof_labels=labels)
    mats, found = rc.read_nastran_matrices(path)
    perm = [found.index(lb) for lb in labels]
    for name, want in (("MAA", M), ("KAA", K), ("KCOL", parts["columns"])):
        got = mats[name].toarray()[np.ix_(perm, perm)]
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12 * np.abs(want).max())  # 10 digits
    with pytest.raises(DataError, match="dof_labels"):
        write_nastran_matrices(tmp_path / "x.bdf", {"KAA": K})
