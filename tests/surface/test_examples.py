"""The embedded example structures: the seeds' test articles as physical models."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.examples.caltech_truss_model import CALTECH_MODE_TYPES, R_LONGERON
from robustctl.examples.mace_beam_model import classify_mace_modes
from robustctl.physical.model import Stage


# ============================================================================ Caltech truss
@pytest.fixture(scope="module")
def truss():
    return rc.examples.caltech_truss()


def _platform_motion(frame, phi, k):
    """(translation, twist * radius) amplitudes of the two platforms in mode k."""
    labels = list(frame.matrices().dof_labels)

    def at(node, dof):
        return phi[labels.index(f"{node} {dof}"), k]

    trans = max(np.hypot(at(p, "ux"), at(p, "uy")) for p in ("platform_1", "platform_2"))
    twist = max(abs(at(p, "rz")) * R_LONGERON for p in ("platform_1", "platform_2"))
    return trans, twist


def test_caltech_first_six_modes_are_two_bending_pairs_and_two_torsions(truss):
    frame = truss.build_structure()
    f_hz, phi = frame.modes(n_modes=8)
    first = f_hz[:6]
    assert np.all((first > 0.5) & (first < 5.5)), first
    assert f_hz[6] > 5.5  # nothing else in the control band
    kinds = []
    for k in range(6):
        trans, twist = _platform_motion(frame, phi, k)
        kinds.append("bending" if trans > 3 * twist else "torsion" if twist > 3 * trans else "mixed")
    assert tuple(kinds) == CALTECH_MODE_TYPES
    # the bending modes come in pairs of near-equal frequency (perpendicular shapes)
    assert first[1] / first[0] - 1 < 0.03 and first[4] / first[3] - 1 < 0.03
    # torsion lies between the pairs, then above the second pair (Table I ordering)
    assert first[1] < first[2] < first[3] and first[5] > first[4] * 1.3
    # within 25 % of the seed's NASTRAN column and below the test column (taut wires)
    nastran = np.array(rc.examples.caltech_truss().meta["nastran_hz"])
    test = np.array(truss.meta["test_hz"])
    assert np.all(np.abs(first / nastran - 1) < 0.25)
    assert np.all(first < test)
    # the mode table tells the same story
    table = rc.examples.truss_modes(truss, n_modes=6)
    assert tuple(table.column("type")) == CALTECH_MODE_TYPES


def test_caltech_local_longeron_modes_lie_at_37_to_43_hz():
    bare = rc.examples.caltech_truss(diagonals=False)
    f_hz, _ = bare.build_structure().modes(band_hz=(5.5, 60.0))
    # 3 longerons x 2 stories x 2 planes x (first local bending) = 12 local modes
    assert f_hz.size == 12 and np.all((f_hz > 37.0) & (f_hz < 43.5)), f_hz
    f_all, _ = rc.examples.caltech_truss().build_structure().modes(band_hz=(5.5, 60.0))
    assert np.all((f_all > 30.0) & (f_all < 50.0)) and f_all.size == 18  # + 6 diagonal modes


def test_caltech_io_names_and_finite_nine_channel_frf(truss):
    assert truss.inputs == ("A1", "A2", "A3")
    assert truss.outputs == ("S1", "S2", "S3")
    f = np.linspace(0.1, 60.0, 600)
    frd = truss.freqresp(f)
    assert frd.response.shape == (600, 3, 3)
    assert np.all(np.isfinite(frd.response))
    band = (f > 0.5) & (f < 5.5)
    rms = np.sqrt((np.abs(frd.response[band]) ** 2).mean(axis=0))
    # A1S3 is an order of magnitude below the other actuator-1 responses (the seed)
    assert rms[2, 0] < 0.15 * min(rms[0, 0], rms[1, 0])
    # electronics are linear gains: doubling the actuator gain doubles the response
    k = truss.param("k_actuator").value
    doubled = truss.freqresp(f[:50], k_actuator=2 * k).response
    np.testing.assert_allclose(doubled, 2 * frd.response[:50], rtol=1e-9, atol=1e-14)
    # the 100-Hz Butterworth filter: -3 dB at its cutoff relative to the structure alone
    ss = truss.statespace()
    assert ss.nstates == 2 * 24 + 3 * 4  # 24 modes below 60 Hz, 4th-order filter per sensor


def test_caltech_gravity_tension_stiffening(truss):
    f_on, _ = truss.build_structure().modes(n_modes=6)
    f_off, _ = rc.examples.caltech_truss(gravity=False).build_structure().modes(n_modes=6)
    f_without, _ = truss.without("gravity").build_structure().modes(n_modes=6)
    np.testing.assert_allclose(f_without, f_off, rtol=1e-10)
    rise = f_on / f_off - 1
    assert np.all((rise > 0.03) & (rise < 0.2)), rise
    # longerons in tension: the story-1 columns carry the weight below them
    axial = truss.build_structure().axial_forces()
    story1 = [v for k, v in axial.items() if k.startswith("longerons_story_1")]
    story2 = [v for k, v in axial.items() if k.startswith("longerons_story_2")]
    assert min(story1) > 10.0 and min(story2) > 3.0 and min(story1) > max(story2)


def test_caltech_wire_tension_on_longeron_groups_stiffens_bending(truss):
    def wires(theta, structure):
        for group in ("longerons_story_1", "longerons_story_2"):
            structure.add_group_tension(group, 5.0)
        return structure

    stiffened = truss.add_structure_stage(Stage("taut accelerometer wires", wires))
    f0, _ = truss.build_structure().modes(n_modes=6)
    f1, _ = stiffened.build_structure().modes(n_modes=6)
    assert np.all(f1 / f0 - 1 > 0.02)
    assert set(truss.meta["element_groups"]) <= set(truss.build_structure().element_groups())


def test_caltech_parameters_are_physical_and_bad_options_refused(truss):
    for p in truss.params:
        assert p.unit is not None and p.meaning and p.bounds[0] <= p.value <= p.bounds[1]
    names = set(truss.param_names)
    assert {"E_aluminium", "rho_aluminium", "m_platform_1", "m_platform_2", "m_offset", "zeta_modal"} <= names
    assert truss.param("m_platform_1").value == 2.36 and truss.param("m_platform_2").value == 1.55
    assert "electronics" in truss.param("k_actuator").tags
    assert "gravity" in truss.param("g_local").tags
    with pytest.raises(rc.ModelError, match="n_elements_per_member"):
        rc.examples.caltech_truss(n_elements_per_member=0)
    with pytest.raises(rc.ModelError, match="band_hz"):
        rc.examples.caltech_truss(band_hz=(5.0, 1.0))


# ============================================================================ MACE-like bus
@pytest.fixture(scope="module")
def mace():
    return rc.examples.mace_beam()


def _bus_rigid_motion(frame, phi, k):
    """Mean bus-node displacement per DOF kind in mode k, normalised to the largest."""
    labels = list(frame.matrices().dof_labels)
    v = phi[:, k] / np.abs(phi[:, k]).max()
    return {
        d: float(np.mean([v[labels.index(f"bus_{i} {d}")] for i in range(1, 6)]))
        for d in ("ux", "uy", "uz", "rx", "ry", "rz")
    }


def test_mace_one_g_has_bounce_pendulum_and_violin_modes(mace):
    frame = mace.build_structure()
    assert frame.matrices().n_dof < 300
    f_hz, phi = frame.modes(n_modes=8)
    low = [(f_hz[k], _bus_rigid_motion(frame, phi, k)) for k in range(8) if f_hz[k] < 0.5]
    bounce = [f for f, m in low if abs(m["uz"]) > 0.9]
    pendulum_x = [f for f, m in low if abs(m["ux"]) > 0.9]
    pendulum_y = [f for f, m in low if abs(m["uy"]) > 0.9]
    assert len(bounce) == 1 and 0.17 < bounce[0] < 0.23  # seed: 0.2 Hz
    assert len(pendulum_x) == 1 and len(pendulum_y) == 1
    for f in pendulum_x + pendulum_y:
        assert abs(f - np.sqrt(9.81 / 5.0) / (2 * np.pi)) < 0.02  # seed: 0.23 Hz
    kinds = classify_mace_modes(mace, 30)
    violins = [r["f_hz"] for r in kinds if r["type"] == "violin"]
    outer = [f for f in violins if 6.5 < f < 8.5]  # seed: 7.26 / 7.34 Hz
    centre = [f for f in violins if 10.5 < f < 13.0]  # seed: 11.65 Hz
    assert len(outer) >= 4 and len(centre) >= 2
    assert min(f for f, _ in low) > 0.1  # no rigid-body mode left in 1 g


def test_mace_zero_g_rigid_modes_and_horizontal_bending_shift(mace):
    zero = mace.without("suspension", "gravity")
    f0, _ = zero.build_structure().modes(n_modes=12)
    assert np.sum(f0 < 1e-3) == 6 and f0[6] > 0.1
    one = classify_mace_modes(mace, 20)
    zer = classify_mace_modes(zero, 20)

    def first(info, kind):
        return next(r["f_hz"] for r in info if r["type"] == kind)

    h1, h0 = first(one, "horizontal bending"), first(zer, "horizontal bending")
    v1, v0 = first(one, "vertical bending"), first(zer, "vertical bending")
    shift = h1 / h0 - 1
    assert 0.03 < shift < 0.2, (h0, h1)  # MACE Table 1: 12.7 %
    assert abs(v1 / v0 - 1) < 0.03  # MACE Table 1: 1.4 %
    assert 2.0 < v0 < h0 < 4.5  # MACE Table 1, 0 g: 2.10 and 3.31 Hz


def test_mace_without_equals_zero_g_built_from_scratch(mace):
    removed = mace.without("suspension", "gravity")
    scratch = rc.examples.mace_beam(zero_g=True)
    assert removed.param_names == scratch.param_names
    a, b = removed.build_structure().matrices(sparse=False), scratch.build_structure().matrices(sparse=False)
    assert a.dof_labels == b.dof_labels and a.inputs == b.inputs and a.outputs == b.outputs
    for x, y in ((a.mass, b.mass), (a.stiffness, b.stiffness), (a.damping, b.damping),
                 (a.input_matrix, b.input_matrix), (a.output_matrix, b.output_matrix)):
        x, y = np.asarray(x), np.asarray(y)
        assert np.abs(x - y).max() <= 1e-10 * max(np.abs(y).max(), 1.0)
    fa, _ = removed.build_structure().modes(n_modes=20)
    fb, _ = scratch.build_structure().modes(n_modes=20)
    np.testing.assert_allclose(fa, fb, rtol=1e-10, atol=1e-10)
    # and the suspension and gravity are really gone, but nothing else
    assert not any("suspension" in p.tags or "gravity" in p.tags for p in removed.params)
    assert "load_rods" not in removed.build_structure().element_groups()
    assert mace.build_structure().preload() is not None and removed.build_structure().preload() is None


def test_mace_io_model_channels_servo_stability_and_frf(mace):
    assert mace.inputs == ("primary gimbal x command", "primary gimbal y command", "RWA x", "RWA y", "RWA z")
    assert mace.outputs == ("primary gyro x", "primary gyro y", "RWA gyro x", "RWA gyro y", "RWA gyro z")
    for model in (mace, mace.without("suspension", "gravity")):
        poles = np.linalg.eigvals(model.statespace().A)
        assert poles.real.max() < 1e-6  # gimbal servo loops stable in 1 g and 0 g
    frd = mace.freqresp(np.linspace(0.1, 60.0, 200))
    assert frd.response.shape == (200, 5, 5) and np.all(np.isfinite(frd.response))
    full = rc.examples.mace_beam(disturbance_inputs=True, encoder_outputs=True)
    assert "secondary gimbal x command" in full.inputs and "primary encoder y" in full.outputs
    open_loop = rc.examples.mace_beam(servo_loops=False)
    assert open_loop.inputs[:2] == ("primary gimbal x", "primary gimbal y")
    with pytest.raises(rc.ModelError, match="n_rod_elements"):
        rc.examples.mace_beam(n_rod_elements=1)


# ============================================================================ assembly helpers
def test_pd_controller_and_channel_combinations():
    import control

    from robustctl.examples._assembly import combine_inputs, combine_outputs, pd_controller, select_signals

    for order in (1, 2):
        k = pd_controller(2.0, 1.0, lowpass_hz=10.0, rolloff_order=order)
        for f in (0.0, 1.0, 10.0, 100.0):
            s = 2j * np.pi * f
            roll = (20 * np.pi / (s + 20 * np.pi)) if order == 1 else (
                (20 * np.pi) ** 2 / (s**2 + np.sqrt(2) * 20 * np.pi * s + (20 * np.pi) ** 2))
            expected = 2.0 * (1 + s / (2 * np.pi)) * roll
            assert complex(control.evalfr(k, s)) == pytest.approx(expected, rel=1e-12)
    with pytest.raises(rc.ModelError, match="roll-off"):
        pd_controller(1.0, 5.0, lowpass_hz=2.0)
    sys = control.ss(-np.eye(2), np.eye(2), np.eye(2), np.zeros((2, 2)), inputs=["a", "b"],
                     outputs=["p", "q"])
    pair = combine_inputs(sys, {"ab": {"a": 1.0, "b": -1.0}})
    assert list(pair.input_labels) == ["ab"] and np.allclose(pair.B, [[1.0], [-1.0]])
    rel = combine_outputs(sys, {"q-p": {"q": 1.0, "p": -1.0}})
    assert list(rel.output_labels) == ["q-p"] and np.allclose(rel.C, [[-1.0, 1.0]])
    assert list(select_signals(sys, ["b"], ["p"]).input_labels) == ["b"]
    with pytest.raises(rc.ModelError, match="unknown input"):
        combine_inputs(sys, {"x": {"nope": 1.0}})
