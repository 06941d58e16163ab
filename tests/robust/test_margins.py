"""rc.diskmargin (models, FRF data, loop at a time and all at once) and rc.nugap against closed forms."""

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.errors import SynthesisError

s = control.tf("s")


# ---------------------------------------------------------------------------- disk margins
@pytest.mark.parametrize("k", [0.5, 3.0, 20.0])
@pytest.mark.parametrize("skew", [-0.5, 0.0, 0.5, 1.0])
def test_first_order_loop_closed_form(k, skew):
    # S(jw) = (jw + 1)/(jw + 1 + k) traces a circle with real diameter [1/(1+k), 1]; with c real
    # the largest |S + c| is at one end: alpha = 1 / max(|1/(1+k) + c|, |1 + c|), c = (skew - 1)/2
    c = (skew - 1) / 2
    alpha = 1 / max(abs(1 / (1 + k) + c), abs(1 + c))
    dm = rc.diskmargin(k / (s + 1), skew=skew)
    assert dm.simultaneous.alpha == pytest.approx(alpha, rel=1e-9)
    assert dm.loops[0].alpha == pytest.approx(alpha, rel=1e-9)
    assert dm.closed_loop_stable is True


def test_disk_gain_and_phase_formulas():
    # balanced disk: gains [(2 - a)/(2 + a), (2 + a)/(2 - a)], phase 2 arctan(a / 2)
    a = 0.6
    lo, hi, pm = rc.disk_gain_phase(a)
    assert lo == pytest.approx((2 - a) / (2 + a)) and hi == pytest.approx((2 + a) / (2 - a))
    assert pm == pytest.approx(np.degrees(2 * np.arctan(a / 2)))
    assert lo * hi == pytest.approx(1.0)


@pytest.mark.parametrize("k", [1.5, 3.0, 5.0])
def test_disk_margins_within_classical_margins(k):
    L = k / (s * (s + 1) * (s + 2))  # classical GM = 6 / k at sqrt(2) rad/s
    dm = rc.diskmargin(L)
    gm, pm, _, _ = control.margin(L)
    m = dm.simultaneous
    assert gm == pytest.approx(6 / k, rel=1e-6)
    assert 1 < m.gain_margin[1] <= gm and 1 / gm <= m.gain_margin[0] < 1
    assert 0 < m.phase_margin_deg <= pm
    # the disk through the critical point: |S - 1/2| peaks where alpha is attained (exact H-inf norm)
    S = 1 / (1 + L)
    w = 2 * np.pi * m.f_critical_hz
    assert 1 / abs(S(1j * w) - 0.5) == pytest.approx(m.alpha, rel=1e-8)


def test_same_margins_from_model_and_its_exact_frd():
    G = control.tf([2.0], [1.0, 0.4, 4.0]) * control.tf([1.0], [0.1, 1.0])
    K = control.tf([0.8, 1.0], [0.05, 1.0])  # u = -K y
    model = rc.diskmargin(G, K, sign=-1)
    f = np.unique(np.concatenate([np.geomspace(0.01, 100, 3000), [model.loops[0].f_critical_hz]]))
    data = rc.freqresp(G, f)
    from_data = rc.diskmargin(data, K, sign=-1)
    assert from_data.source == "data" and from_data.closed_loop_stable is None
    assert from_data.loops[0].alpha == pytest.approx(model.loops[0].alpha, rel=1e-9)
    assert from_data.loops[0].phase_margin_deg == pytest.approx(model.loops[0].phase_margin_deg, rel=1e-8)


def test_positive_feedback_sign_matches_negated_controller():
    G = control.tf([2.0], [1.0, 0.4, 4.0])
    K = control.tf([0.8, 1.0], [0.05, 1.0])
    a = rc.diskmargin(G, K, sign=-1).simultaneous.alpha
    b = rc.diskmargin(G, -K).simultaneous.alpha  # the default: u = +K y
    assert a == pytest.approx(b, rel=1e-12)


def test_multiloop_diagonal_and_coupled():
    L1, L2 = 3 / (s + 1), 2 / (s * (s + 1))
    Ld = control.ss(control.append(control.ss(L1), control.ss(L2)))
    dm = rc.diskmargin(Ld)
    a1, a2 = rc.diskmargin(L1).simultaneous.alpha, rc.diskmargin(L2).simultaneous.alpha
    assert [m.alpha for m in dm.loops] == pytest.approx([a1, a2], rel=1e-7)
    # mu of a diagonal M is its largest entry
    assert dm.simultaneous.alpha == pytest.approx(min(a1, a2), rel=1e-3)
    # a coupled plant: all-at-once cannot exceed any loop at a time, and the guaranteed disk keeps
    # the loop stable for gains f_i at its boundary in every channel (checked on a few corners)
    num = [[[1.0], [0.8]], [[-0.6], [1.0]]]
    den = [[[1.0, 1.0], [1.0, 2.0]], [[1.0, 3.0], [1.0, 1.0]]]
    G = control.ss(control.tf(num, den))
    K = control.ss([], [], [], 4.0 * np.eye(2))
    dm = rc.diskmargin(G, K, at="input", sign=-1)  # negative feedback, checked below
    assert dm.simultaneous.alpha <= min(m.alpha for m in dm.loops) * (1 + 1e-9)
    lo, hi = dm.simultaneous.gain_margin
    inside = [1 + 0.999 * (g - 1) for g in (lo, hi)]  # just inside the disk's real diameter
    for f1 in inside:
        for f2 in inside:
            F = control.ss([], [], [], np.diag([f1, f2]))  # the gains at the plant inputs (at="input")
            cl = control.feedback(G * F * K, np.eye(2))
            assert rc.is_stable(cl)


def test_unstable_closed_loop_has_zero_margin_and_bad_input_is_refused():
    dm = rc.diskmargin(-2 / (s + 1))  # 1 + L has a zero at s = 1
    assert dm.closed_loop_stable is False and dm.simultaneous.alpha == 0.0
    with pytest.raises(SynthesisError, match="square"):
        rc.diskmargin(control.ss(control.tf([[[1.0], [1.0]]], [[[1.0, 1.0], [1.0, 2.0]]])))
    with pytest.raises(SynthesisError, match="sign"):
        rc.diskmargin(1 / (s + 1), sign=2)
    with pytest.raises(SynthesisError, match="at"):
        rc.diskmargin(1 / (s + 1), 1.0, at="middle")


def test_diskmargin_reports():
    dm = rc.diskmargin(2 / (s * (s + 1) * (s + 2)))
    assert "all at once" in str(dm.table())
    assert "phase" in dm.summary()
    assert dm.plot().axes


# ---------------------------------------------------------------------------- nu-gap
@pytest.mark.parametrize("k1, k2", [(1.0, 3.0), (2.0, 2.5), (4.0, 0.5)])
def test_nugap_gains_closed_form(k1, k2):
    # kappa^2 = (k1 - k2)^2 x / ((x + k1^2)(x + k2^2)), x = w^2 + 1 >= 1: max at x = k1 k2 (when >= 1)
    gap, f = rc.nugap(k1 / (s + 1), k2 / (s + 1))
    assert gap == pytest.approx(abs(k1 - k2) / (k1 + k2), rel=1e-8)
    assert 2 * np.pi * f == pytest.approx(np.sqrt(k1 * k2 - 1), rel=1e-4)


@pytest.mark.parametrize("eps", [0.01, 0.1, 0.5])
def test_nugap_stable_and_unstable_pole_are_close(eps):
    # Vinnicombe's example: 1/(s + eps) and 1/(s - eps) are close; kappa(0) = 2 eps / (1 + eps^2)
    gap, _ = rc.nugap(1 / (s + eps), 1 / (s - eps))
    assert gap == pytest.approx(2 * eps / (1 + eps**2), rel=1e-8)
    assert rc.nugap(1 / (s - eps), 1 / (s + eps))[0] == pytest.approx(gap, rel=1e-8)


def test_nugap_is_one_when_the_winding_condition_fails():
    # chordal distance at most 0.8, but det(1 + G2~ G1) = (s + 1)(s + 3)/(s + 2)^2 winds 0 times
    # while eta(G1) - eta(G2) = 1: the nu-gap is 1
    G1, G2 = 1 / (s - 2), 1 / (s + 2)
    w = np.logspace(-3, 3, 2001)
    a, b = G1(1j * w), G2(1j * w)
    assert np.max(np.abs(a - b) / np.sqrt((1 + abs(a) ** 2) * (1 + abs(b) ** 2))) < 0.81
    assert rc.nugap(G1, G2)[0] == 1.0


def test_nugap_discrete_matches_unit_circle_chordal_distance():
    dt = 0.1
    G1 = control.c2d(control.tf([1.0], [1.0, 0.3, 1.0]), dt)
    G2 = control.c2d(control.tf([1.2], [1.0, 0.4, 1.1]), dt)
    gap, f = rc.nugap(G1, G2)
    z = np.exp(1j * np.linspace(0, np.pi, 20001))
    a, b = G1(z), G2(z)
    kappa = np.abs(a - b) / np.sqrt((1 + abs(a) ** 2) * (1 + abs(b) ** 2))
    assert gap == pytest.approx(kappa.max(), rel=1e-5)


def test_nugap_refuses_mismatched_models():
    with pytest.raises(SynthesisError, match="shape"):
        rc.nugap(1 / (s + 1), control.tf([[[1.0], [1.0]]], [[[1.0, 1.0], [1.0, 2.0]]]))
    with pytest.raises(SynthesisError, match="time base"):
        rc.nugap(1 / (s + 1), control.c2d(1 / (s + 1), 0.1))


def test_discrete_loop_margins_match_the_unit_circle():
    dt = 0.01
    L = control.c2d(3 / (s * (s + 1) * (s + 2)), dt)
    dm = rc.diskmargin(L)
    z = np.exp(1j * np.linspace(1e-6, np.pi, 200001))
    S = 1 / (1 + L(z))
    assert dm.closed_loop_stable is True
    grid = 1 / np.max(np.abs(S - 0.5))
    assert dm.simultaneous.alpha <= grid * (1 + 1e-12)  # the exact peak is at least the grid's
    assert dm.simultaneous.alpha == pytest.approx(grid, rel=1e-5)
    f_grid = np.angle(z[np.argmax(np.abs(S - 0.5))]) / (2 * np.pi * dt)
    assert dm.loops[0].f_critical_hz == pytest.approx(f_grid, rel=1e-3)


def test_simultaneous_disk_margin_holds_for_complex_gain_and_phase_changes():
    # independent, complex gains f_i in the disk D(0.99 alpha, sigma) at every loop-breaking point
    # leave the loop stable: A_cl = A - B (I + F D)^-1 F C for the negative-feedback loop L
    num = [[[1.0, 2.0], [0.8]], [[-0.6], [1.0, 0.5]]]
    den = [[[1.0, 1.0, 4.0], [1.0, 2.0]], [[1.0, 3.0], [1.0, 0.2, 1.0]]]
    L = control.ss(control.tf(num, den)) * 2.0
    rng = np.random.default_rng(0)
    for skew in (0.0, 0.5):
        dm = rc.diskmargin(L, skew=skew)
        assert dm.closed_loop_stable
        a = dm.simultaneous.alpha
        A, B, C, D = (np.asarray(m) for m in (L.A, L.B, L.C, L.D))
        for _ in range(200):
            delta = 0.99 * a * rng.uniform(0, 1, 2) ** 0.5 * np.exp(2j * np.pi * rng.uniform(0, 1, 2))
            f = (1 + (1 - skew) / 2 * delta) / (1 - (1 + skew) / 2 * delta)
            F = np.diag(f)
            Acl = A - B @ np.linalg.solve(np.eye(2) + F @ D, F @ C)
            assert np.max(np.linalg.eigvals(Acl).real) < 0


def test_hinfsyn_controller_default_sign_and_a_sign_slip_is_named():
    # rc.hinfsyn returns u = +K y; diskmargin's default is that sign (robust/conventions.py)
    G = control.ss(control.tf([1.0], [1.0, 0.2, 1.0]))
    gp = rc.generalized_plant(G, performance=control.tf([0.5, 1.0], [1.0, 0.01]), control_weight=0.1,
                              disturbances=1.0, noise=0.01)
    K = rc.hinfsyn(gp).K
    dm = rc.diskmargin(G, K)
    assert dm.closed_loop_stable and dm.simultaneous.alpha > 0.1
    # the MATLAB sign on the same controller: unstable, said so, and the other sign named
    slip = r"unstable with u = -K y \(sign=-1\) but stable with u = \+K y"
    with pytest.warns(rc.RobustctlWarning, match=slip):
        bad = rc.diskmargin(G, K, sign=-1)
    assert bad.closed_loop_stable is False and bad.simultaneous.alpha == 0
    assert "UNSTABLE with u = -K y (sign=-1)" in bad.summary()
