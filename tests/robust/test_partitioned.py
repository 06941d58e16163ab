"""One partitioned plant: PartitionedPlant behaves as a system for python-control, and
as_partitioned is the one coercion of hinfsyn, h2syn, dksyn and the yardstick."""

import pickle

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.examples import DISTILLATION_BLOCKS, distillation_plant
from robustctl.robust.dk.iteration import as_plant
from robustctl.robust.plant import GeneralizedPlant


def _mixed_sensitivity():
    G = control.tf([1.0], [1.0, 0.4, 1.0])
    return rc.mixed_sensitivity(G, control.tf([0.5, 1.0], [1.0, 0.01]), 0.1)


def test_python_control_hinfsyn_on_a_partitioned_plant_equals_it_on_the_bare_statespace():
    gp = _mixed_sensitivity()
    K1, CL1, gamma1, _ = control.hinfsyn(gp, 1, 1)
    K2, CL2, gamma2, _ = control.hinfsyn(gp.P, 1, 1)
    assert gamma1 == gamma2
    assert np.array_equal(K1.A, K2.A) and np.array_equal(K1.D, K2.D)
    # python-control's controller achieves ||Fl(P, K)||_inf <= gamma (ZDG thm 16.4), and rc.lft
    # closes the loop on the PartitionedPlant with it
    assert rc.hinfnorm(rc.lft(gp, K1))[0] <= gamma1 * (1 + 1e-6)
    # ours reaches python-control's optimum within its bisection tolerance
    assert rc.hinfsyn(gp).gamma_opt == pytest.approx(gamma1, rel=2e-2)
    K3 = control.h2syn(gp, 1, 1)
    K4 = control.h2syn(gp.P, 1, 1)
    assert np.array_equal(K3.C, K4.C)


def test_partitioned_plant_exposes_its_statespace():
    gp = _mixed_sensitivity()
    P = gp.P
    for k in ("A", "B", "C", "D"):
        assert np.array_equal(getattr(gp, k), getattr(P, k))
    assert (gp.ninputs, gp.noutputs, gp.nstates, gp.dt) == (P.ninputs, P.noutputs, P.nstates, P.dt)
    assert gp.input_labels == gp.w_names + gp.u_names and gp.output_labels == gp.z_names + gp.y_names
    assert gp.isctime() and not gp.isdtime()
    ss = rc.as_statespace(gp)
    assert np.array_equal(ss.A, P.A) and np.array_equal(ss.D, P.D) and ss.input_labels == P.input_labels
    back = pickle.loads(pickle.dumps(gp))
    assert back.nstates == gp.nstates and np.array_equal(back.B, gp.B)


def test_every_plant_form_gives_the_same_partition():
    P = distillation_plant()
    bs = rc.as_block_structure(DISTILLATION_BLOCKS)
    gp = rc.as_partitioned(P, 2, 2, DISTILLATION_BLOCKS)
    assert isinstance(gp, GeneralizedPlant) and gp.blocks == bs and (gp.nw, gp.nz) == (4, 4)
    assert rc.as_partitioned(gp) is gp and as_plant(gp) is gp
    from_tuple = as_plant((P, 2, 2, DISTILLATION_BLOCKS))
    assert from_tuple.P is P and (from_tuple.nmeas, from_tuple.ncon) == (2, 2) and from_tuple.blocks == bs
    pp = rc.PartitionedPlant(P, 2, 2)
    assert rc.as_partitioned(pp) is pp and rc.as_partitioned(pp, nmeas=2) is pp

    class Duck:  # any object carrying P, nmeas and ncon
        def __init__(self):
            self.P, self.nmeas, self.ncon = P, 2, 2

    duck = rc.as_partitioned(Duck())
    assert type(duck) is rc.PartitionedPlant and duck.P is P and duck.nw == 4


def test_refusals_are_one_error_naming_what_was_passed_and_the_fix():
    P = distillation_plant()
    with pytest.raises(rc.PlantError, match=r"number of measurements.*ndarray passed.*PartitionedPlant"):
        rc.as_partitioned(np.eye(2))
    with pytest.raises(rc.PlantError, match="nmeas=1 contradicts"):
        rc.as_partitioned(rc.PartitionedPlant(P, 2, 2), nmeas=1)
    with pytest.raises(rc.PlantError, match="need 2 w inputs"):
        rc.as_partitioned(P, 2, 2, [[1, 1], [1, 1]])
    with pytest.raises(rc.PlantError, match="nmeas = 0"):
        rc.as_partitioned(P, 0, 2)
    with pytest.raises(rc.PlantError, match=r"dksyn needs the .*block structure.*tuple"):
        rc.as_partitioned(rc.PartitionedPlant(P, 2, 2), who="dksyn", need_blocks=True)
    Pd = control.c2d(control.ss(control.tf([1.0], [1.0, 1.0])) * np.ones((2, 2)), 0.1)
    with pytest.raises(rc.PlantError, match=r"dksyn designs continuous-time.*dt = 0.1"):
        rc.as_partitioned(Pd, 1, 1, who="dksyn", allow_discrete=False)
    assert rc.as_partitioned(Pd, 1, 1).dt == 0.1
    # one class, caught as either stage's error
    for err in (rc.SynthesisError, rc.ModelError):
        with pytest.raises(err, match="tuple"):
            rc.dksyn(P)
        with pytest.raises(err, match="as_statespace"):
            rc.PartitionedPlant(np.eye(2), 1, 1)


def test_one_partitioned_plant_is_taken_by_every_design_entry_and_converted_once(monkeypatch):
    """hinfsyn, h2syn, lqg, mu, ncfsyn and sampled_plant take the same PartitionedPlant, each
    converting the user's object once at its entry, and give what they give for the plant's
    parts passed by hand (issue 32)."""
    import importlib

    from robustctl.lti import freqresp_array
    from robustctl.robust import partitioned

    rng = np.random.default_rng(3)
    A = np.diag([-0.5, -2.0, -0.1]) + 0.2 * rng.standard_normal((3, 3))
    B, C = rng.standard_normal((3, 2)), rng.standard_normal((2, 3))
    P = control.ss(A, B, C, [[0.0, 1.0], [1.0, 0.0]], inputs=["w", "u"], outputs=["z", "y"])
    pp = rc.as_partitioned(P, 1, 1)
    gp = rc.as_partitioned(P, 1, 1, blocks=[[1, 1]])
    seen = []
    real = partitioned.as_partitioned

    def counting(obj, *args, **kw):
        seen.append(obj)
        return real(obj, *args, **kw)

    for mod in ("robust.hinf.synthesis", "robust.h2.synthesis", "robust.h2.lqg_design",
                "robust.analysis.loop_shaping", "robust.sampled"):
        monkeypatch.setattr(importlib.import_module(f"robustctl.{mod}"), "as_partitioned", counting)

    def once(call):
        del seen[:]
        out = call()
        assert sum(o is pp or o is gp for o in seen) <= 1
        return out

    assert once(lambda: rc.hinfsyn(pp)).gamma == rc.hinfsyn(P, 1, 1).gamma
    assert once(lambda: rc.h2syn(pp)).norm == rc.h2syn(P, 1, 1).norm
    by_names = rc.lqg(P, 1.0, 0.1, 1.0, 0.01, controls=["u"], measurements=["y"], disturbances=["w"],
                      performance=["z"])
    assert once(lambda: rc.lqg(pp, 1.0, 0.1, 1.0, 0.01)).cost == pytest.approx(by_names.cost, rel=1e-12)
    f = np.logspace(-2, 1, 20)
    m = once(lambda: rc.mu(gp, f_hz=f))  # P11 with the plant's own blocks
    assert m.peak == pytest.approx(np.abs(freqresp_array(P, f)[:, 0, 0]).max(), rel=1e-6)
    ncf = once(lambda: rc.ncfsyn(pp))  # the u -> y part P22
    assert ncf.b_opt == pytest.approx(rc.ncfsyn(control.ss(P.A, P.B[:, 1:], P.C[1:], P.D[1:, 1:])).b_opt,
                                      rel=1e-12)
    assert once(lambda: rc.sampled_plant(pp, 0.01)).P.dt == 0.01
    assert len(seen) == 1
