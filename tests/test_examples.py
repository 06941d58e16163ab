"""The embedded example structures: the seeds' test articles as physical models."""

from __future__ import annotations

import numpy as np
import pytest

import robustctl as rc
from robustctl.examples.caltech_truss import CALTECH_MODE_TYPES, R_LONGERON
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
