"""Test geometry, sensor placement and mode shapes in universal files; mode shapes drawn in 3-D."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import DataError
from robustctl.examples.caltech_truss_model import (
    CORNER_DEG,
    H_STORY_1,
    H_STORY_2,
    R_LONGERON,
    R_SENSOR,
    SENSOR_DIR_DEG,
    SENSOR_POS_DEG,
)

pytest.importorskip("pyuff")


def corner(angle_deg, radius, z):
    a = np.deg2rad(angle_deg)
    return (radius * np.cos(a), radius * np.sin(a), z)


def caltech_geometry() -> rc.Geometry:
    """The Caltech truss as a modal-test geometry: ceiling, two platforms, three accelerometers."""
    z1, z2 = -H_STORY_1, -H_STORY_1 - H_STORY_2
    nodes, lines = {}, []
    for i, ang in enumerate(CORNER_DEG, start=1):
        nodes[i] = corner(ang, R_LONGERON, 0.0)
        nodes[10 + i] = corner(ang, R_LONGERON, z1)
        nodes[20 + i] = corner(ang, R_LONGERON, z2)
        lines += [(i, 10 + i), (10 + i, 20 + i)]
    for a, b in [(1, 2), (2, 3), (3, 1)]:
        lines += [(10 + a, 10 + b), (20 + a, 20 + b)]
    sensors = {}
    for k, (pos, direction) in enumerate(zip(SENSOR_POS_DEG, SENSOR_DIR_DEG), start=1):
        nodes[30 + k] = corner(pos, R_SENSOR, z2)
        lines.append((21, 30 + k))
        sensors[f"S{k}"] = (30 + k, corner(direction, 1.0, 0.0))
    ids = sorted(nodes)
    return rc.Geometry(ids, [nodes[i] for i in ids], lines, sensors, name="Caltech truss")


def truss_modes(geo: rc.Geometry, n_modes: int = 4) -> rc.ModeShapes:
    rng = np.random.default_rng(3)
    shapes = rng.standard_normal((n_modes, geo.n_nodes, 6))
    shapes[:, :3, :] = 0.0  # the ceiling is clamped
    return rc.ModeShapes(
        f_hz=[1.17, 1.19, 2.26, 2.66][:n_modes],
        node_ids=geo.node_ids,
        shapes=shapes,
        zeta=[0.018, 0.018, 0.010, 0.016][:n_modes],
        generalized_mass=[2.0, 3.0, 4.0, 5.0][:n_modes],
        name="truss FE",
    )


def test_caltech_geometry_sensors_and_frfs_round_trip_through_pyuff(tmp_path):
    geo = caltech_geometry()
    modes = truss_modes(geo)
    f = np.linspace(0.5, 5.5, 11)
    rng = np.random.default_rng(0)
    resp = rng.standard_normal((f.size, 3, 2)) + 1j * rng.standard_normal((f.size, 3, 2))
    data = rc.FrequencyData(
        f,
        resp,
        inputs=("A1", "A2"),
        outputs=("S1", "S2", "S3"),
        units={"S1": "m/s^2", "S2": "m/s^2", "S3": "m/s^2", "A1": "N", "A2": "N"},
    )
    path = tmp_path / "caltech.uff"
    rc.write_uff_geometry(path, geo, modes=modes, data=data)

    back = rc.load_uff_geometry(path)
    np.testing.assert_array_equal(back.node_ids, geo.node_ids)
    np.testing.assert_allclose(back.xyz, geo.xyz, atol=1e-6)
    assert {tuple(sorted(x)) for x in back.lines.tolist()} == {tuple(sorted(x)) for x in geo.lines.tolist()}
    # the channels of the FRF file map to their nodes and directions without a table
    frd = rc.load_frd(path)
    rows, dirs = back.channel_map(frd.outputs)
    assert list(back.node_ids[rows]) == [31, 32, 33]
    np.testing.assert_allclose(dirs, [corner(d, 1.0, 0.0) for d in SENSOR_DIR_DEG], atol=1e-6)
    np.testing.assert_allclose(frd.response, resp, rtol=1e-6)

    shapes = rc.load_uff_modes(path)
    np.testing.assert_allclose(shapes.f_hz, modes.f_hz, rtol=1e-6)
    np.testing.assert_allclose(shapes.zeta, modes.zeta, rtol=1e-5)
    np.testing.assert_allclose(shapes.generalized_mass, modes.generalized_mass, rtol=1e-5)
    np.testing.assert_allclose(shapes.shapes, modes.shapes, rtol=1e-5, atol=1e-6)
    # shapes at the sensors: the tangential S3 reads cos 45 of x plus sin 45 of y at node 33
    at = shapes.at(["S3"], geometry=back, mass_normalized=False)[0]
    k33 = list(geo.node_ids).index(33)
    np.testing.assert_allclose(
        at, (modes.shapes[:, k33, 0] + modes.shapes[:, k33, 1]) / np.sqrt(2), rtol=1e-5, atol=1e-6
    )


def test_millimetre_files_become_metres(tmp_path):
    geo = caltech_geometry()
    path = tmp_path / "mm.uff"
    rc.write_uff_geometry(path, geo, unit="mm")
    raw = rc.load_uff_geometry(path)  # read as metres: a thousand times too large
    np.testing.assert_allclose(raw.xyz, 1e3 * geo.xyz, rtol=1e-6, atol=1e-3)
    np.testing.assert_allclose(rc.load_uff_geometry(path, unit="mm").xyz, geo.xyz, atol=1e-6)


def test_a_channel_without_a_node_is_named_with_the_fix():
    geo = caltech_geometry()
    with pytest.raises(DataError, match=r"channel 'S9' has no node.*with_sensors"):
        geo.channel_map(["S1", "S9"])
    modes = truss_modes(geo)
    missing = rc.ModeShapes(
        f_hz=[1.0],
        node_ids=[31],
        shapes=np.ones((1, 1, 6)),
        present=[[True, True, True, False, False, False]],
    )
    with pytest.raises(DataError, match=r"output '31:R1'.*lacks"):
        missing.at(["31:R1"], what="output")
    with pytest.raises(DataError, match=r"node 99 has no mode shape"):
        modes.at(["99:T1"])
    with pytest.raises(DataError, match="unit="):
        rc.load_uff_geometry(__file__, unit="furlong")


# ---------------------------------------------------------------------------- 3-D figures
def _deformed(fig):
    return [c for ax in fig.axes for c in ax.collections if c.get_gid() == "deformed"]


def test_plot_mode_shapes_draws_every_requested_mode_on_the_structure(tmp_path):
    geo = caltech_geometry()
    modes = truss_modes(geo)
    fig = rc.plot_mode_shapes(modes, geo)
    assert len(fig.axes) == 4 and len(_deformed(fig)) == 4
    assert all(ax.name == "3d" and "Hz" in ax.get_title() for ax in fig.axes)
    # the deformed wireframe moves the nodes by the shape (largest motion = 15 % of the size)
    seg = np.asarray(_deformed(fig)[0]._segments3d)
    assert seg.shape == (len(geo.lines), 2, 3)
    few = rc.plot_mode_shapes(modes, geo, max_modes=2)
    assert len(_deformed(few)) == 2 and "2 lowest of 4" in few._suptitle.get_text()
    fig.savefig(tmp_path / "shapes.png", dpi=90)
    assert (tmp_path / "shapes.png").stat().st_size > 10_000


def test_test_and_fe_shapes_side_by_side_paired_by_mac():
    geo = caltech_geometry()
    fe = truss_modes(geo)
    # "test" modes: the FE shapes at the sensors, in another order, as Modes with output shapes
    at = fe.at(["S1", "S2", "S3"], geometry=geo, mass_normalized=False)
    order = [2, 0, 3, 1]
    test = [
        rc.Mode(f_hz=fe.f_hz[k] * 1.05, zeta=0.02, residue=at[:, [k]], output_shape=at[:, [k]]) for k in order
    ]

    class Identified:  # what fit_measurement_model returns: .modes and .sys with output names
        modes = test

        class sys:  # noqa: N801
            output_labels = ["S1", "S2", "S3"]

    fig = rc.plot_mode_shapes(Identified(), geo, pair_with=fe, labels=("test", "FE"))
    named = rc.plot_mode_shapes(test, geo, outputs=["S1", "S2", "S3"], max_modes=2)  # Modes carry no names
    assert len(_deformed(named)) == 2
    assert len(fig.axes) == 8 and len(_deformed(fig)) == 8
    titles = [ax.get_title() for ax in fig.axes]
    for p, k in enumerate(sorted(order, key=lambda j: fe.f_hz[j] * 1.05)):
        assert titles[2 * p].startswith("test") and titles[2 * p + 1].startswith(f"FE mode {k + 1}:")
        assert "MAC 1.00" in titles[2 * p + 1]


def test_bars_for_28_sensors_do_not_overlap_and_say_what_is_left_out():
    rng = np.random.default_rng(1)
    outs = [f"accel {k:02d}" for k in range(28)]
    modes = []
    for k in range(14):
        v = rng.standard_normal((28, 1))
        modes.append(rc.Mode(f_hz=1.0 + k, zeta=0.01, residue=v, output_shape=v))
    fig = rc.plot_mode_shapes(modes, outputs=outs, max_modes=12)
    assert "12 lowest of 14" in fig._suptitle.get_text()
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    for ax in fig.axes:
        boxes = [t.get_window_extent(renderer) for t in ax.get_xticklabels()]
        assert len(boxes) == 28
        assert all(a.x1 <= b.x0 + 0.5 for a, b in zip(boxes, boxes[1:]))  # no label overlaps the next
    every = rc.plot_mode_shapes(modes, outputs=outs, max_modes=14)
    assert len(every.axes) == 14 and every._suptitle is None


def test_a_file_from_other_modal_software_maps_node_direction_channels(tmp_path):
    """Dataset 15 nodes, a dataset 82 trace line and dataset 58 FRFs named only by node and
    direction code (as test software writes them), written with pyuff directly."""
    import pyuff

    f = np.linspace(1.0, 10.0, 8)
    recs = [
        pyuff.prepare_15(
            node_nums=[1, 2, 3],
            def_cs=[0, 0, 0],
            disp_cs=[0, 0, 0],
            color=[1, 1, 1],
            x=[0.0, 1.0, 2.0],
            y=[0.0, 0.0, 0.0],
            z=[0.0, 0.0, 0.5],
        ),
        pyuff.prepare_82(trace_num=1, n_nodes=3, color=2, id="beam", nodes=np.array([1, 2, 3])),
    ]
    for node, direction in [(2, 3), (3, -1)]:
        recs.append(
            pyuff.prepare_58(
                binary=0,
                id1="frf",
                func_type=4,
                rsp_node=node,
                rsp_dir=direction,
                ref_node=1,
                ref_dir=3,
                data=(1.0 + node) * np.exp(1j * f),
                x=f,
                abscissa_spacing=0,
                abscissa_spec_data_type=18,
                ordinate_spec_data_type=12,
                orddenom_spec_data_type=13,
            )
        )
    path = tmp_path / "other.unv"
    pyuff.UFF(str(path)).write_sets(recs, mode="add")
    geo = rc.load_uff_geometry(path)
    assert list(geo.node_ids) == [1, 2, 3] and {tuple(x) for x in geo.lines.tolist()} == {(1, 2), (2, 3)}
    data = rc.load_frd(path)
    rows, dirs = geo.channel_map(data.outputs)
    assert list(geo.node_ids[rows]) == [2, 3]
    np.testing.assert_allclose(dirs, [[0, 0, 1], [-1, 0, 0]])


@pytest.mark.parametrize("backend", ["matplotlib", "pyvista"])
def test_animated_mode_swings_through_one_cycle(backend, tmp_path):
    if backend == "pyvista":
        pytest.importorskip("pyvista")
    geo = caltech_geometry()
    anim = rc.animate_mode_shape(truss_modes(geo), geo, mode=2, frames=8, size=(200, 160), backend=backend)
    assert (
        len(anim.frames) == 8 and anim.frames[0].shape == (160, 200, 3) and anim.f_hz == pytest.approx(1.19)
    )
    frames = np.asarray(anim.frames, dtype=float)
    # the quarter-cycle frames (cos = 0) show the undeformed structure: identical pictures
    assert np.array_equal(frames[2], frames[6])
    assert np.abs(frames[0] - frames[4]).mean() > 0.05  # the two extremes differ
    anim.save(tmp_path / "mode.gif")
    assert (tmp_path / "mode.gif").read_bytes()[:6] == b"GIF89a"
    assert anim._repr_html_().startswith('<img src="data:image/gif;base64,')
    with pytest.raises(DataError, match="mode must be an integer from 1 to 4"):
        rc.animate_mode_shape(truss_modes(geo), geo, mode=5)


def test_uff_mode_shapes_make_a_modal_model_at_the_test_channels(tmp_path):
    geo = caltech_geometry()
    modes = truss_modes(geo)
    path = tmp_path / "shapes.uff"
    rc.write_uff_geometry(path, geo, modes=modes)
    back, shapes = rc.load_uff_geometry(path), rc.load_uff_modes(path)
    placed = back.with_sensors(geo.sensors)  # sensors travel in dataset 58 records; none here
    model = rc.fe_modal_model(
        shapes,
        inputs=["21:T3"],
        outputs=["S1", "S3"],
        geometry=placed,
        damping="file",
        output_kind="displacement",
    )
    k21, k31, k33 = (list(geo.node_ids).index(n) for n in (21, 31, 33))
    phi = modes.shapes / np.sqrt(modes.generalized_mass)[:, None, None]
    b = phi[:, k21, 2][None, :]
    c = np.vstack(
        [phi[:, k31, 0], (phi[:, k33, 0] + phi[:, k33, 1]) / np.sqrt(2)]
    )  # S1 along x, S3 at 45 deg
    ref = rc.modal_model(
        modes.f_hz, modes.zeta, b, c, inputs=["21:T3"], outputs=["S1", "S3"], output_kind="displacement"
    )
    f = np.linspace(0.5, 4.0, 50)
    got, want = model.freqresp(f).response, ref.freqresp(f).response
    assert np.max(np.abs(got - want)) < 1e-4 * np.max(np.abs(want))  # UFF's 13-character numbers
    with pytest.raises(DataError, match="damping="):
        rc.fe_modal_model(
            rc.ModeShapes([1.0], [21], np.ones((1, 1, 6))), ["21:T3"], ["21:T3"], damping="file"
        )


def test_two_fe_mode_sets_pair_over_every_node_without_sensors():
    geo = caltech_geometry()
    bare = rc.Geometry(geo.node_ids, geo.xyz, geo.lines)  # no sensors
    fe = truss_modes(geo)
    swapped = rc.ModeShapes(fe.f_hz, fe.node_ids, fe.shapes[[1, 0, 3, 2]])  # shapes 1-2 and 3-4 swapped
    fig = rc.plot_mode_shapes(fe, bare, pair_with=swapped, labels=("A", "B"))
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[1].startswith("B mode 2:") and titles[3].startswith("B mode 1:")
    assert all("MAC 1.00" in t for t in titles[1::2])


def test_bad_geometry_is_refused_with_the_reason():
    with pytest.raises(DataError, match="pass geometry="):
        rc.plot_mode_shapes(truss_modes(caltech_geometry()))
    with pytest.raises(DataError, match="node 1 is defined twice"):
        rc.Geometry([1, 1], [(0, 0, 0), (1, 0, 0)])
    with pytest.raises(DataError, match=r"trace lines use node\(s\) \[7\]"):
        rc.Geometry([1, 2], [(0, 0, 0), (1, 0, 0)], [(1, 7)])
    with pytest.raises(DataError, match="sensor 'S1': direction 'RX' is a rotation"):
        rc.Geometry([1], [(0, 0, 0)], sensors={"S1": (1, "RX")})
    with pytest.raises(DataError, match="'12-Z' is not a DOF name"):
        rc.Geometry([1], [(0, 0, 0)]).with_sensors({"S1": "12-Z"})


def test_dataset_2412_elements_become_their_edges(tmp_path):
    import pyuff

    def element(num, descriptor, nodes, **rod):
        return dict(
            element_nums=num,
            fe_descriptor=descriptor,
            phys_table=1,
            mat_table=1,
            color=2,
            num_nodes=len(nodes),
            nodes_nums=nodes,
            **rod,
        )

    recs = [
        pyuff.prepare_2411(
            node_nums=np.array([1, 2, 3, 4, 5]),
            def_cs=np.ones(5, int),
            disp_cs=np.ones(5, int),
            color=np.ones(5, int),
            x=np.array([0, 1, 1, 0, 2.0]),
            y=np.array([0, 0, 1, 1, 0.0]),
            z=np.zeros(5),
        ),
        {
            "type": 2412,
            94: [element(1, 94, [1, 2, 3, 4])],
            11: [element(2, 11, [2, 5], beam_orientation=0, beam_foreend_cross=1, beam_aftend_cross=1)],
        },
    ]
    path = tmp_path / "elements.unv"
    pyuff.UFF(str(path)).write_sets(recs, mode="add")
    geo = rc.load_uff_geometry(path, unit="mm")
    assert {tuple(x) for x in geo.lines.tolist()} == {(1, 2), (2, 3), (3, 4), (1, 4), (2, 5)}
    np.testing.assert_allclose(geo.xyz[-1], [2e-3, 0, 0])


def test_complex_modes_round_trip_with_their_eigenvalues(tmp_path):
    geo = caltech_geometry()
    rng = np.random.default_rng(5)
    shapes = np.zeros((2, geo.n_nodes, 6), complex)
    shapes[:, :, :3] = rng.standard_normal((2, geo.n_nodes, 3)) + 1j * rng.standard_normal(
        (2, geo.n_nodes, 3)
    )
    modes = rc.ModeShapes([1.2, 2.7], geo.node_ids, shapes, zeta=[0.02, 0.05], name="test modes")
    path = tmp_path / "complex.uff"
    rc.write_uff_geometry(path, geo, modes=modes)
    back = rc.load_uff_modes(path)
    assert np.iscomplexobj(back.shapes)
    np.testing.assert_allclose(back.f_hz, [1.2, 2.7], rtol=1e-5)  # |lambda| / 2 pi
    np.testing.assert_allclose(back.zeta, [0.02, 0.05], rtol=1e-4)  # -Re lambda / |lambda|
    np.testing.assert_allclose(back.shapes, shapes, atol=1e-5)
    fig = rc.plot_mode_shapes(back, geo)  # drawn at the phase of each mode's largest entry
    assert len(fig.axes) == 2
