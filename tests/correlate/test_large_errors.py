"""Large model errors: diagnose and update when the hidden effect moves modes by a factor of 2-4
and parameters are off by -40 % / +50 %.

The model is a user's own 6-mass chain (``rc.structural_model`` from matrices): 0.1 kg masses,
1 kN/m chain springs (``k_chain``), a soft 50 N/m suspension at mass 1 (``k_ground``), 5 %
modal damping, forces at masses 1 and 6, accelerometers at masses 3 and 6. The data are the
truth's exact FRF times ``exp(e)``, ``e`` complex white noise of 0.5 % per part, with the
coherence of a 40-average H1 estimate of that noise level (Bendat & Piersol, eq. 9.52:
``var(ln G) = (1 - g2) / (2 n_d g2)``), so the coherence weights are the true inverse
variances and the truth's own cost is the noise floor.
"""

import numpy as np
import pytest
import scipy.linalg as sla

import robustctl as rc
from robustctl.correlate.diagnosis import SCREEN_MULTIPLES
from robustctl.correlate.diagnosis.screening import _probe_sizes
from robustctl.correlate.residual import Residual
from robustctl.physical import effects as fx
from robustctl.physical.fem import Frame
from robustctl.physical.modal import modal_dynamics

N_MASS = 6
F_HZ = np.linspace(0.3, 40.0, 500)
UPDATE = ("k_chain", "k_ground", "zeta_modal")
NOISE = 0.005
N_AVERAGES = 40


def _chain():
    k_chain = rc.Parameter("k_chain", 1e3, "N/m", (1e2, 1e4), meaning="chain springs")
    k_ground = rc.Parameter("k_ground", 50.0, "N/m", (5.0, 500.0), meaning="suspension of mass 1")
    unit = np.zeros((N_MASS, N_MASS))
    for i in range(N_MASS - 1):
        unit[i : i + 2, i : i + 2] += [[1.0, -1.0], [-1.0, 1.0]]

    def stiffness(th):
        k = th["k_chain"] * unit
        k[0, 0] += th["k_ground"]
        return k

    return rc.structural_model(
        0.1 * np.eye(N_MASS), stiffness, inputs={"F1": "dof 1", "F6": "dof 6"},
        outputs={"a3": ("dof 3", "acceleration"), "a6": ("dof 6", "acceleration")},
        damping=0.05, params=[k_chain, k_ground], name="6-mass chain",
    )


def _data(model, truth, seed):
    g = truth.freqresp(F_HZ).response
    rng = np.random.default_rng(seed)
    g = g * np.exp(NOISE * (rng.standard_normal(g.shape) + 1j * rng.standard_normal(g.shape)))
    g2 = 1.0 / (1.0 + 2 * N_AVERAGES * NOISE**2)  # (1 - g2) / (2 n g2) = NOISE^2
    return rc.FrequencyData(F_HZ, g, inputs=model.inputs, outputs=model.outputs,
                            coherence=np.full(g.shape, g2), meta={"n_averages": N_AVERAGES})


def _modes_hz(model):
    mats = model.build_structure().matrices()
    return np.sqrt(sla.eigh(mats.stiffness, mats.mass, eigvals_only=True)) / (2 * np.pi)


def _lowest_hz(model):
    return float(_modes_hz(model)[0])


@pytest.fixture(scope="module")
def chain():
    model = _chain()
    return model, fx.candidates(model)


CASES = {
    # a grounded spring at the free end: the lowest mode moves from 1.40 to 3.96 Hz (x 2.8)
    "grounded spring": (fx.SuspensionSpring("dof 6", stiffness=600.0), {"k_chain": 0.02}),
    # 50 % of a lumped mass added at mass 3
    "added mass": (fx.AddedMass("dof 3", mass=0.05), {"k_chain": 0.02}),
    # chain springs -40 %, suspension +50 % and a 5 ms delay the model lacks
    "stiffness errors and delay": (fx.OutputDelay(delay=5e-3), {"k_chain": -0.4, "k_ground": 0.5}),
}


@pytest.mark.parametrize("which", list(CASES), ids=lambda s: s.replace(" ", "-"))
def test_large_hidden_effect_is_ranked_first_and_recovered(chain, which):
    model, cands = chain
    hidden, errors = CASES[which]
    truth = model.with_values(**{k: model.param(k).value * (1 + e) for k, e in errors.items()})
    truth = truth.with_effect(hidden)
    if which == "grounded spring":
        assert 2.0 < _lowest_hz(truth) / _lowest_hz(model) < 4.0
    data = _data(model, truth, seed=len(which))
    diag = rc.diagnose(model, data, cands, params=UPDATE)
    top = diag.ranking[0]
    assert (top.kind, top.location) == (hidden.kind, hidden.location), diag.summary()
    assert diag.best is not None and top.significant

    (pname,) = hidden.param_names
    upd = rc.update(model.with_effect(diag.best), data, params=UPDATE + (pname,),
                    point_weights=diag.point_weights, select=False, drift_bands=0)
    nominal = Residual(model, data, point_weights=diag.point_weights).cost()
    floor = Residual(truth, data, point_weights=diag.point_weights).cost()
    assert upd.cost_after <= 0.05 * nominal, (upd.cost_after, nominal)
    assert upd.cost_after <= 1.001 * floor  # at the noise floor: no better minimum exists
    for name in ("k_chain", "k_ground", pname):
        assert upd.model.param(name).value == pytest.approx(truth.param(name).value, rel=0.02), name


@pytest.mark.parametrize(("errors", "hidden_mode", "change"), [({"k_chain": -0.4}, 2, 1.0),
                                                             ({"k_chain": 0.5, "k_ground": -0.3}, 4, -0.6)])
def test_a_damping_change_is_found_where_parameter_errors_moved_its_mode(chain, errors, hidden_mode, change):
    """Chain springs -40 % move mode 2 from 8.48 to 6.68 Hz (+50 %: mode 4 from 22.6 to 27.6 Hz),
    out of any band placed at the nominal modes: the damping candidates were such bands and a
    dashpot at mass 1 came first. By mode number, the change of that mode's damping (set in the
    truth as a band around its moved frequency) is ranked first, and the update recovers it
    within twice its standard error, with the spring errors."""
    model, cands = chain
    truth = model.with_values(**{k: model.param(k).value * (1 + e) for k, e in errors.items()})
    f_true = _modes_hz(truth)[hidden_mode - 1]
    hidden = fx.ModalDamping(lo_hz=0.98 * f_true, hi_hz=1.02 * f_true, change=change)
    assert abs(f_true / _modes_hz(model)[hidden_mode - 1] - 1) > 0.15  # far outside a 3 % band at it
    truth = truth.with_effect(hidden)
    data = _data(model, truth, seed=hidden_mode)
    diag = rc.diagnose(model, data, cands, params=UPDATE)
    top = diag.ranking[0]
    assert (top.kind, top.location) == ("modal_damping", f"mode {hidden_mode}"), diag.summary()
    assert diag.best is not None and top.significant
    (pname,) = diag.best.param_names
    upd = rc.update(model.with_effect(diag.best), data, params=UPDATE + (pname,),
                    point_weights=diag.point_weights, select=False, drift_bands=0)
    assert abs(upd.model.param(pname).value - change) < 2 * upd.std_errors[pname], (upd.std_errors, change)
    assert upd.model.param(pname).value == pytest.approx(change, rel=0.02)
    for name in ("k_chain", "k_ground"):
        assert upd.model.param(name).value == pytest.approx(truth.param(name).value, rel=0.01), name


def test_screening_at_decades_sees_an_effect_the_secant_misses(chain):
    """A spring that moves the lowest mode by x 2.8 is 100-1000 calibrated steps: the secant's
    linear estimate explains a fraction of what the probe at the right decade finds."""
    model, cands = chain
    spring = next(c for c in cands if c.kind == "suspension_spring" and c.location == "dof 6")
    truth = model.with_effect(fx.SuspensionSpring("dof 6", stiffness=600.0))
    data = _data(model, truth, seed=3)
    res = Residual(model.with_effect(spring.with_values(**spring.neutral_values)), data,
                   point_weights="coherence")
    pname = spring.param_names[0]
    j0 = res.vector()
    q = np.zeros((j0.size, 0))
    share, value, n = _probe_sizes(res, pname, (0.0, *spring.parameters[0].bounds), spring.typical_size,
                                   1.0, q, float(j0 @ j0))
    assert 1 <= n <= len(SCREEN_MULTIPLES)
    # the probe picks the decade of the truth (600 N/m) and explains most of the error
    assert 0.1 * 600.0 < value < 10 * 600.0 and spring.typical_size * 10 <= value
    j = res.vector(**{pname: value})
    assert share == pytest.approx(1.0 - float(j @ j) / float(j0 @ j0))
    assert share > 0.5


def test_update_from_an_effect_size_a_decade_off_finds_the_global_minimum(chain):
    """The effect added at a tenth of its true size (a hand guess): the coarse start moves it
    to the right decade before Levenberg-Marquardt, which then lands on the truth."""
    model, _ = chain
    hidden = fx.SuspensionSpring("dof 6", stiffness=600.0)
    truth = model.with_effect(hidden)
    data = _data(model, truth, seed=5)
    guess = model.with_effect(hidden.with_values(stiffness=60.0))
    pname = hidden.param_names[0]
    upd = rc.update(guess, data, params=UPDATE + (pname,), select=False, drift_bands=0)
    assert upd.model.param(pname).value == pytest.approx(600.0, rel=0.02)
    started = [n for n in upd.notes if n.startswith("started")]
    assert started and "suspension_spring__dof_6 at 600 (model 60)" in started[0], upd.notes
    assert upd.cost_after <= 0.05 * upd.cost_before


# ---------------------------------------------------------------------------- mode pairing
def _mode(f_hz, shape):
    return rc.Mode(f_hz, 0.02, residue=np.asarray(shape, dtype=complex).reshape(2, 2))


def test_pairing_follows_the_shapes_through_large_shifts_and_crossings():
    from robustctl.modes import pair_modes

    e = np.eye(4)
    model = [_mode(1.0, e[0]), _mode(2.5, e[1]), _mode(6.0, e[2])]
    # mode 1 moved x 3 past mode 2 (a crossing); mode 3 by +31 %
    data = [_mode(2.4, e[1]), _mode(3.0, e[0]), _mode(7.86, e[2])]
    assert pair_modes(model, data) == [(0, 1), (1, 0), (2, 2)]
    # without shapes (NaN MAC) only the frequency rule pairs: the far modes stay apart
    bare = [rc.Mode(m.f_hz, 0.02) for m in data]
    assert (0, None) in pair_modes(model, bare) and (None, 1) in pair_modes(model, bare)
    # beyond max_ratio nothing pairs, however alike the shapes
    assert pair_modes([_mode(1.0, e[0])], [_mode(5.0, e[0])]) == [(0, None), (None, 0)]
    # dissimilar shapes far apart stay unpaired
    assert pair_modes([_mode(1.0, e[0])], [_mode(1.5, e[3])]) == [(0, None), (None, 0)]


def test_diagnose_says_when_the_time_budget_cuts_its_fits(chain):
    """A budget that runs out is an error (no partial ranking); one that cuts fits short warns
    that the ranking depends on the machine's load (the budget is a safety cap)."""
    from robustctl.correlate.diagnosis.workers import _warn_if_hurried

    model, cands = chain
    data = _data(model, model.with_effect(fx.AddedMass("dof 3", mass=0.05)), seed=7)
    with pytest.raises(rc.FitError, match=r"time_budget_s=0 s ran out during the null fit"):
        rc.diagnose(model, data, cands[:4], params=UPDATE, time_budget_s=0)
    with pytest.warns(RuntimeWarning, match=r"time budget \(5 s\) stopped the null fit and 2 local fits"):
        _warn_if_hurried(True, 2, 5.0)


# ---------------------------------------------------------------------------- a frame
def _tower():
    """A 1.5 m steel tower (three 8 mm rod columns, 2 kg floors, clamped base): beam
    elements of :class:`~robustctl.physical.fem.Frame`, forces and accelerometers along x."""
    E = rc.Parameter("E_steel", 2.1e11, "Pa", (5e10, 5e11), meaning="Young's modulus")
    m = rc.Parameter("m_floor", 2.0, "kg", (0.5, 10.0), meaning="floor masses")
    z = rc.Parameter("zeta_modal", 0.05, "", (0.005, 0.3), meaning="modal damping")
    r = 4e-3
    A, inertia = np.pi * r**2, np.pi * r**4 / 4

    def structure(th):
        fr = Frame()
        for k in range(4):
            fr.add_node(f"n{k}", (0.0, 0.0, 0.5 * k))
        for k in range(3):
            fr.add_beam("columns", f"n{k}", f"n{k + 1}", E=th["E_steel"], G=th["E_steel"] / 2.6, rho=7850.0,
                        A=A, Iy=inertia, Iz=inertia, J=2 * inertia, n_elements=2)
            fr.add_mass(f"n{k + 1}", th["m_floor"])
        fr.fix("n0")
        fr.add_force_input("F3", "n3", "x")
        fr.add_force_input("F1", "n1", "x")
        fr.add_output("a3", "n3", "x")
        fr.add_output("a2", "n2", "x")
        return fr

    return rc.PhysicalModel(params=[E, m, z], structure=structure,
                            dynamics=modal_dynamics(damping_param="zeta_modal"), name="3-floor tower")


@pytest.mark.slow
@pytest.mark.parametrize("hidden", [fx.SuspensionSpring("n3", direction="x", stiffness=300.0),
                                    fx.AddedMass("n2", mass=1.0)], ids=lambda e: e.kind)
def test_frame_large_hidden_effect_is_ranked_first_and_recovered(hidden):
    """On a frame: a spring at the top floor that moves the lowest bending mode in x from
    0.59 Hz by x 2-4, or half a floor's mass added at floor 2; Young's modulus +3 %."""
    model = _tower()
    cands = fx.candidates(model, locations=("n1", "n2", "n3"))
    truth = model.with_values(E_steel=2.1e11 * 1.03).with_effect(hidden)
    if hidden.kind == "suspension_spring":
        f0 = model.build_structure().modes(n_modes=2)[0]
        f1 = truth.build_structure().modes(n_modes=2)[0]
        assert 2.0 < f1[1] / f0[1] < 4.0  # the x-mode (the y-mode is the unchanged first)
    data = _data(model, truth, seed=11)
    params = ("E_steel", "m_floor", "zeta_modal")
    diag = rc.diagnose(model, data, cands, params=params)
    top = diag.ranking[0]
    assert (top.kind, top.location) == (hidden.kind, hidden.location), diag.summary()
    assert diag.best is not None and top.significant
    (pname,) = hidden.param_names
    upd = rc.update(model.with_effect(diag.best), data, params=params + (pname,),
                    point_weights=diag.point_weights, select=False, drift_bands=0)
    nominal = Residual(model, data, point_weights=diag.point_weights).cost()
    assert upd.cost_after <= 0.05 * nominal, (upd.cost_after, nominal)
    for name in ("E_steel", "m_floor", pname):
        assert upd.model.param(name).value == pytest.approx(truth.param(name).value, rel=0.02), name


def test_only_candidates_whose_secant_points_beyond_its_step_are_probed(chain, monkeypatch):
    """Probing at 10-1000 steps is for effects the data ask more of than the secant measured
    (|c| > PROBE_MIN_COEF); the others are not walked out, and the large spring still wins."""
    import importlib

    diagnose_module = importlib.import_module("robustctl.correlate.diagnosis.screening")
    model, cands = chain
    seen = []
    real = diagnose_module._probe_sizes

    def spy(res_c, pname, span, step, coef, *args):
        seen.append((pname, coef))
        return real(res_c, pname, span, step, coef, *args)

    monkeypatch.setattr(diagnose_module, "_probe_sizes", spy)
    hidden, errors = CASES["grounded spring"]
    truth = model.with_values(**{k: model.param(k).value * (1 + e) for k, e in errors.items()})
    data = _data(model, truth.with_effect(hidden), seed=len("grounded spring"))
    diag = rc.diagnose(model, data, cands, params=UPDATE, workers=1)
    assert diag.ranking[0].name == hidden.name and diag.ranking[0].significant
    assert seen and all(abs(c) > diagnose_module.PROBE_MIN_COEF for _, c in seen)
    assert len(seen) < len(cands) - 1  # most candidates' secants already cover what the data ask


# ---------------------------------------------------------------------------- H1 data, large errors
def _chain4():
    """A user's 4-mass chain whose masses, chain springs and suspension are all parameters."""
    unit = np.zeros((4, 4))
    for i in range(3):
        unit[i : i + 2, i : i + 2] += [[1.0, -1.0], [-1.0, 1.0]]

    def stiffness(th):
        k = th["k_chain"] * unit
        k[0, 0] += th["k_ground"]
        return k

    params = [rc.Parameter("k_chain", 2e3, "N/m", (2e2, 2e4), meaning="chain springs"),
              rc.Parameter("k_ground", 300.0, "N/m", (30.0, 3e3), meaning="suspension of mass 1"),
              rc.Parameter("m_mass", 0.5, "kg", (0.05, 5.0), meaning="the four masses")]
    return rc.structural_model(lambda th: th["m_mass"] * np.eye(4), stiffness, inputs={"F1": "dof 1"},
                               outputs={"a3": ("dof 3", "acceleration"), "a4": ("dof 4", "acceleration")},
                               damping=0.02, params=params, name="4-mass chain")


def test_a_sensor_filter_under_40_percent_errors_is_found_from_h1_data():
    """Chain springs -40 %, suspension +50 %, masses +20 % (modes 30 % lower) and a 20 Hz
    first-order sensor filter, measured by H1 estimates of a simulated white-noise test. From the
    model's values the null fit stops in a local minimum 97 % above the global one, and the
    parameter error left in the residual made a second-order filter rank first; diagnose starts
    the null fit where update does (its coarse multi-start), so the true filter ranks first, and
    the update recovers every parameter within 3 reported SEs."""
    model = _chain4()
    hidden = fx.SensorLowPass(order=1, time_constant=1 / (2 * np.pi * 20.0))
    errors = {"k_chain": -0.4, "k_ground": 0.5, "m_mass": 0.2}
    data, truth = rc.examples.make_experiment(model, hidden, errors, noise_rms=0.01, seed=1,
                                              n_samples=40960, nperseg=2048)
    band = (0.5, 40.0)
    diag = rc.diagnose(model, data, band=band, workers=1)
    top = diag.ranking[0]
    assert (top.kind, top.effect.order) == ("sensor_lowpass", 1), diag.summary()
    assert diag.best is not None and top.significant
    assert diag.cost_update < 0.1 * diag.cost_nominal  # the null fit reached the global basin
    upd = rc.update(model.with_effect(diag.best), data, band=band)
    assert upd.cost_after < 1e-3 * upd.cost_before
    for name in ("k_chain", "k_ground", "m_mass", hidden.param_names[0]):
        value, se = upd.model.param(name).value, upd.std_errors[name]
        assert abs(value - truth.param(name).value) < 3 * se, (name, value, truth.param(name).value, se)


# ---------------------------------------------------------------------------- gravity switched on
def _hanging_chain():
    """Two 1 kg bobs on 0.4 m steel wires (1.5 mm radius beams) hanging from a clamp; the model's
    gravity preload is switched off (a 0-g model compared with a 1-g test)."""
    E = rc.Parameter("E_steel", 2.1e11, "Pa", (5e10, 5e11), meaning="Young's modulus")
    m = rc.Parameter("m_bob", 1.0, "kg", (0.1, 10.0), meaning="bob masses")
    r = 1.5e-3
    A, inertia = np.pi * r**2, np.pi * r**4 / 4

    def structure(th):
        fr = Frame(gravity=9.81).set_gravity(False)
        fr.add_node("top", (0.0, 0.0, 0.8))
        prev = "top"
        for k in (1, 2):
            fr.add_node(f"b{k}", (0.0, 0.0, 0.8 - 0.4 * k))
            fr.add_beam("wires", prev, f"b{k}", E=th["E_steel"], G=th["E_steel"] / 2.6, rho=7850.0, A=A,
                        Iy=inertia, Iz=inertia, J=2 * inertia, n_elements=2)
            fr.add_mass(f"b{k}", th["m_bob"], inertia=(1e-3, 1e-3, 1e-3))
            prev = f"b{k}"
        fr.fix("top")
        fr.add_force_input("Fx2", "b2", "x")
        fr.add_output("a2x", "b2", "x")
        fr.add_output("a1x", "b1", "x")
        return fr

    return rc.PhysicalModel(params=[E, m, rc.Parameter("zeta_modal", 0.02, "", (0.002, 0.3))],
                            structure=structure, dynamics=modal_dynamics(damping_param="zeta_modal"),
                            name="hanging chain")


def test_gravity_switched_on_is_ranked_first_with_its_update_parameters_refitted():
    """A 0-g model of a hanging chain against 1-g data (Young's modulus +10 %): gravity moves the
    pendulum modes by x 3-4. The switch's local fit must refit the update parameters on its own
    sensitivities -- the null fit's belong to the 0-g state, and with them the switch explained
    a third of the residual and ranked below grounded springs that mimic it."""
    model = _hanging_chain()
    data, truth = rc.examples.make_experiment(model, fx.GravityStiffening(enabled=True, switch=1.0),
                                              {"E_steel": 0.1}, seed=2, n_samples=40960, nperseg=4096)
    cands = fx.candidates(model, band=(0.3, 30.0), kinds=("gravity", "suspension_spring", "added_mass"))
    diag = rc.diagnose(model, data, cands, band=(0.3, 30.0), workers=1)
    top = diag.ranking[0]
    assert top.kind == "gravity" and top.significant, diag.summary()
    assert top.gain > 0.99  # the switch with E refitted explains the residual
    fixed = model.with_effect(diag.best)
    upd = rc.update(fixed, data, band=(0.3, 30.0))
    for name in ("E_steel", "m_bob"):
        value, se = upd.model.param(name).value, upd.std_errors[name]
        assert abs(value - truth.param(name).value) < 3 * se, (name, value, truth.param(name).value, se)


# ---------------------------------------------------------------------------- converged contenders
def _portal():
    """A 2-storey 3-D steel frame (0.4 x 0.3 m, 0.5 m storeys, 5 mm rod columns, stiff floor
    beams, 3 kg floors, clamped), shaken and measured at floor 2 in x and y and at floor 1 in x."""
    E = rc.Parameter("E_steel", 2.1e11, "Pa", (5e10, 5e11), meaning="Young's modulus")
    m = rc.Parameter("m_floor", 3.0, "kg", (0.5, 20.0), meaning="floor masses")
    r = 5e-3
    A, inertia = np.pi * r**2, np.pi * r**4 / 4
    corners = [(0, 0), (0.4, 0), (0.4, 0.3), (0, 0.3)]

    def structure(th):
        fr = Frame()
        sec = dict(E=th["E_steel"], G=th["E_steel"] / 2.6, rho=7850.0)
        for lev in range(3):
            for c, (x, y) in enumerate(corners):
                fr.add_node(f"f{lev}c{c}", (x, y, 0.5 * lev))
        for lev in range(2):
            for c in range(4):
                fr.add_beam(f"columns_{lev + 1}", f"f{lev}c{c}", f"f{lev + 1}c{c}", A=A, Iy=inertia,
                            Iz=inertia, J=2 * inertia, n_elements=2, **sec)
                fr.add_beam(f"beams_{lev + 1}", f"f{lev + 1}c{c}", f"f{lev + 1}c{(c + 1) % 4}", A=4 * A,
                            Iy=16 * inertia, Iz=16 * inertia, J=32 * inertia, **sec)
                fr.add_mass(f"f{lev + 1}c{c}", th["m_floor"] / 4)
        for c in range(4):
            fr.fix(f"f0c{c}")
        fr.add_force_input("Fx", "f2c0", "x")
        fr.add_force_input("Fy", "f2c2", "y")
        fr.add_output("a2x", "f2c0", "x")
        fr.add_output("a2y", "f2c2", "y")
        fr.add_output("a1x", "f1c1", "x")
        return fr

    zeta = rc.Parameter("zeta_modal", 0.02, "", (0.002, 0.3))
    return rc.PhysicalModel(params=[E, m, zeta], structure=structure,
                            dynamics=modal_dynamics(damping_param="zeta_modal"), name="2-storey frame")


@pytest.mark.slow
def test_contenders_are_polished_to_convergence_before_the_vuong_test():
    """A spring at floor 1 against one at the middle of the column below it, 5 % sensor noise,
    E +15 %, floor masses +10 %: two polishing iterations left the true spring 20 % above its
    converged cost, behind the mimic, and the Vuong test called the mimic's lead significant.
    Polished to convergence the true spring is first and the mimic significantly behind."""
    model = _portal()
    hidden = fx.SuspensionSpring("f1c0", direction="x", stiffness=3000.0)
    data, _ = rc.examples.make_experiment(model, hidden, {"E_steel": 0.15, "m_floor": 0.1}, noise_rms=0.05,
                                          seed=1, n_samples=20480, nperseg=2048)
    cands = fx.candidates(model, band=(0.5, 50.0), locations=("f1c0", "f0c0-f1c0/1"),
                          kinds=("suspension_spring",))
    diag = rc.diagnose(model, data, cands, band=(0.5, 50.0), workers=1)
    top = diag.ranking[0]
    assert (top.kind, top.location, top.effect.direction) == ("suspension_spring", "f1c0", "x"), \
        diag.summary()
    assert diag.indistinguishable is None  # the mimic is behind beyond the noise
    assert next(iter(diag.best.values.values())) == pytest.approx(3000.0, rel=0.05)


@pytest.mark.slow
def test_frame_damping_change_on_a_close_pair_under_a_30_percent_modulus_error():
    """The 2-storey frame with E -30 % (every mode 16 % lower: the 7.1 Hz bending pair at 6.0 Hz)
    and +150 % damping on that pair: diagnose said "nothing significant" when its damping
    candidates were bands at the nominal modes (the top was a dashpot, not significant). By mode
    number the pair's own candidate (not the octave's modes 1-3) comes first, and the update
    recovers the change within twice its standard error and E within 1 %."""
    model = _portal()
    truth_f = _modes_hz(model.with_values(E_steel=2.1e11 * 0.7))
    hidden = fx.ModalDamping(lo_hz=0.97 * truth_f[0], hi_hz=1.03 * truth_f[1], change=1.5)
    data, truth = rc.examples.make_experiment(model, hidden, {"E_steel": -0.3}, noise_rms=0.01, seed=1,
                                              n_samples=20480, nperseg=2048, band=(0.5, 50.0))
    cands = fx.candidates(model, band=(0.5, 50.0), locations=("f1c0", "f2c0", "f2c2"))
    params = ("E_steel", "m_floor", "zeta_modal")
    diag = rc.diagnose(model, data, cands, band=(0.5, 50.0), params=params, workers=1)
    top = diag.ranking[0]
    assert (top.kind, top.location) == ("modal_damping", "modes 1-2"), diag.summary()
    assert diag.best is not None and top.significant
    (pname,) = diag.best.param_names
    upd = rc.update(model.with_effect(diag.best), data, params=params + (pname,), band=(0.5, 50.0),
                    point_weights=diag.point_weights, select=False, drift_bands=0)
    assert abs(upd.model.param(pname).value - 1.5) < 2 * upd.std_errors[pname], upd.std_errors
    assert upd.model.param("E_steel").value == pytest.approx(2.1e11 * 0.7, rel=0.01)
