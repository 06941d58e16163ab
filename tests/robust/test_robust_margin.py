"""Robust-stability margin (rc.robstab) and worst-case gain (rc.wcgain) against closed forms,
textbook examples and an independent numpy stability scan; the destabilising values are
substituted and must put a pole on the imaginary axis."""

from __future__ import annotations

import control
import numpy as np
import pytest

import robustctl as rc
from robustctl.robust.uncertainty import append


def _integrator():
    return rc.as_uncertain(control.tf([1], [1, 0]))


def _pole_on_axis(margin, scale=1.0):
    """The substituted system has a pole on the imaginary axis (checked independently)."""
    assert abs(margin.pole.real) < 1e-6 * max(abs(margin.pole), scale)
    assert abs(abs(margin.pole.imag) - 2 * np.pi * margin.f_critical_hz) < 1e-6 * max(abs(margin.pole), scale)


def test_closed_form_damping_margin():
    # x'' + c x' + k x = 0: unstable exactly when c <= 0 or k <= 0, so the margin is
    # min(c0 / h_c, k0 / h_k) = min(1 / 0.5, 4 / 1) = 2, reached by c = 0 at w = sqrt(k0) = 2 rad/s
    c = rc.ureal("c", 1.0, percent=50)
    k = rc.ureal("k", 4.0, plusminus=1.0)
    x = _integrator()
    sys = (x * x.feedback(c)).feedback(k)
    m = rc.robstab(sys)
    # the D-G upper bound of mu is within 0.2 % of its LMI optimum: the guaranteed margin too
    assert 2.0 * (1 - 2e-3) <= m.lower <= 2.0 * (1 + 1e-9) and m.upper == pytest.approx(2.0, rel=1e-9)
    # c = 0 with any k in 4 +- 2 (the range at twice its size) puts poles at +-j sqrt(k)
    assert abs(m.destabilizing["c"]) < 1e-9 and abs(m.destabilizing["k"] - 4.0) <= 2.0 * (1 + 1e-9)
    assert 2 * np.pi * m.f_critical_hz == pytest.approx(np.sqrt(m.destabilizing["k"]), rel=1e-9)
    _pole_on_axis(m)
    assert m.robustly_stable  # margin 2 > 1


def test_closed_form_unmodelled_dynamics_margin():
    # L = G (1 + Delta), G = 4 / (s + 1)^2, unit feedback: T = 4 / (s^2 + 2 s + 5) has
    # |T(j w)|^2 = 16 / ((5 - w^2)^2 + 4 w^2), peak 1 at w = sqrt(3); the small-gain margin of
    # a bound-0.5 block is 1 / (0.5 ||T||) = 2 (Zhou, Doyle & Glover thm 9.1)
    d = rc.ultidyn("d", (1, 1), 0.5)
    G = rc.as_uncertain(control.tf([4], [1, 2, 1]))
    cl = (G * (1 + d)).feedback(1)
    m = rc.robstab(cl)
    assert m.lower == pytest.approx(2.0, rel=1e-4) and m.upper == pytest.approx(2.0, rel=1e-4)
    assert m.f_critical_hz == pytest.approx(np.sqrt(3) / (2 * np.pi), rel=1e-3)
    D = m.destabilizing["d"]  # a stable real system of norm 2 x 0.5
    assert np.all(np.linalg.eigvals(D.A).real < 0)
    w = np.geomspace(1e-3, 1e3, 2000)
    gain = max(abs(complex((D.C @ np.linalg.solve(1j * wk * np.eye(D.nstates) - D.A, D.B) + D.D)[0, 0]))
               for wk in w)
    assert gain == pytest.approx(1.0, rel=1e-6)
    _pole_on_axis(m)


def test_spinning_satellite_diagonal_input_gains():
    # Skogestad & Postlethwaite (2005) sec. 3.7.1: G = [[s - a^2, a (s + 1)], [-a (s + 1), s - a^2]]
    # / (s^2 + a^2), a = 10, K = I, input gains (1 + e1, 1 + e2). The closed-loop polynomial is
    # s^2 + (2 + e1 + e2) s + (1 + e1)(1 + e2) + a^2 e1 e2: it fails first through s = 0 at
    # e1 = -e2 = 1 / sqrt(1 + a^2) = 0.0995 ("unstable for e1 = -e2 = 0.1").
    a = 10.0
    G = control.ss([[0, a], [-a, 0]], np.eye(2), [[1, a], [-a, 1]], np.zeros((2, 2)))
    g1, g2 = rc.ureal("g1", 1.0, plusminus=1.0), rc.ureal("g2", 1.0, plusminus=1.0)
    cl = (rc.as_uncertain(G) * append(g1, g2)).feedback(np.eye(2))
    m = rc.robstab(cl)
    ref = 1 / np.sqrt(1 + a**2)
    assert m.lower == pytest.approx(ref, rel=1e-6) and m.upper == pytest.approx(ref, rel=1e-9)
    e1, e2 = m.destabilizing["g1"] - 1, m.destabilizing["g2"] - 1
    assert e1 == pytest.approx(-e2, rel=1e-9) and abs(e1) == pytest.approx(ref, rel=1e-9)
    assert m.f_critical_hz == 0.0 and abs(m.pole) < 1e-9
    # a full 2x2 block of the same size: the small-gain margin 1 / sigma_max(T(0)) = 1 / sqrt(101)
    Dfull = rc.ultidyn("D", (2, 2), 1.0)
    m2 = rc.robstab((rc.as_uncertain(G) * (np.eye(2) + Dfull)).feedback(np.eye(2)))
    assert m2.lower == pytest.approx(ref, rel=1e-4) and m2.upper == pytest.approx(ref, rel=1e-6)
    assert abs(m2.pole) < 1e-9


def _two_mass(k: float) -> np.ndarray:
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 0], A[2, 1], A[3, 0], A[3, 1] = -k, k, k, -k
    return A


def test_two_mass_spring_benchmark_against_a_numpy_scan():
    # Wie & Bernstein (1992) benchmark problem 1: m1 = m2 = 1, spring k in [0.5, 2], force on
    # mass 1, position of mass 2 measured (non-collocated). An LQG controller designed with
    # python-control at k = 1; the margin's reference is an independent eigenvalue scan in k.
    B = np.array([[0.0], [0.0], [1.0], [0.0]])
    C = np.array([[0.0, 1.0, 0.0, 0.0]])
    A1 = _two_mass(1.0)
    Kx, _, _ = control.lqr(A1, B, np.eye(4), 1.0)
    L, _, _ = control.lqe(A1, B, C, 1.0, 0.01)
    Ac, Bc, Cc = A1 - B @ Kx - L @ C, L, -Kx  # u = Cc xc, xc' = Ac xc + Bc y
    K = control.ss(Ac, Bc, Cc, 0)
    # the plant as an LFT in k: x1'' = u - f, x2'' = f, f = k (x1 - x2)
    k = rc.ureal("k", 1.25, range=(0.5, 2.0))
    P0 = control.ss(_two_mass(0.0), np.c_[B, [0, 0, -1, 1]], np.r_[[[1.0, -1.0, 0, 0]], C], 0)
    spring = rc.as_uncertain(np.array([[0.0, 0.0], [1.0, 0.0]])) * k
    P = rc.as_uncertain(P0).feedback(spring, sign=1)[1, 0]
    cl = P.feedback(K, sign=1)
    m = rc.robstab(cl)

    def abscissa(kv):
        Acl = np.block([[_two_mass(kv), B @ Cc], [Bc @ C, Ac]])
        return np.linalg.eigvals(Acl).real.max()

    def boundary(direction):
        lo, hi = 0.0, None
        for step in np.arange(1, 400) * 0.01:  # walk out from the centre, then bisect
            if abscissa(1.25 + direction * step) >= 0:
                hi = step
                break
            lo = step
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if abscissa(1.25 + direction * mid) < 0 else (lo, mid)
        return 0.5 * (lo + hi)

    ref = min(boundary(1.0), boundary(-1.0)) / 0.75
    assert m.upper == pytest.approx(ref, rel=1e-6)
    assert m.lower == pytest.approx(ref, rel=1e-3) and m.lower <= m.upper * (1 + 1e-9)
    assert abscissa(m.destabilizing["k"]) == pytest.approx(0.0, abs=1e-7)
    _pole_on_axis(m)


@pytest.mark.slow
def test_worst_case_gain_closed_form():
    # |1 / (j w + a)| is largest at w = 0 and a = a_min = 1: worst-case gain exactly 1
    a = rc.ureal("a", 2.0, plusminus=1.0)
    x = _integrator()
    G = x.feedback(a)  # 1 / (s + a)
    wc = rc.wcgain(G, f_hz=np.r_[0.0, np.geomspace(1e-2, 10.0, 12)])
    assert wc.lower == pytest.approx(1.0, rel=1e-3) and wc.upper >= wc.lower * (1 - 1e-9)
    assert wc.upper == pytest.approx(1.0, rel=1e-2)
    assert wc.worst_values["a"] == pytest.approx(1.0, abs=2e-3)
    assert wc.nominal_gain == pytest.approx(0.5, rel=1e-6)


def test_unstable_nominal_has_zero_margin():
    c = rc.ureal("c", -0.1, plusminus=0.05)
    x = _integrator()
    m = rc.robstab((x * x.feedback(c)).feedback(1))
    assert m.lower == 0 and m.upper == 0 and not m.nominal_stable and "unstable" in m.summary()


def test_uncertain_system_in_generalized_plant_and_mu():
    # the generalized plant of an uncertain system: its element's block first; closing that
    # block at a value gives the plant built directly at that value
    k = rc.ureal("k", 2.0, percent=50)
    G = rc.as_uncertain(control.ss(control.tf([1.0], [1.0, 0.5, 1.0]), inputs=["F"], outputs=["x"]))
    P = G * k
    gp = rc.generalized_plant(P, additive=0.1, performance=1.0, control_weight=0.1, disturbances=1.0,
                              noise=0.01)
    assert [b.name for b in gp.blocks][:2] == ["k", "additive"] and gp.blocks[0].kind == "real"
    f = np.array([0.05, 0.16, 0.4])
    Pf = np.stack([np.asarray(gp.P(2j * np.pi * x)) for x in f])
    # k = 2.5: delta = (2.5 - 2) / 1 = 0.5; close w_k = delta z_k (the first channel)
    d = 0.5
    closed = Pf[:, 1:, 1:] + Pf[:, 1:, :1] * d * Pf[:, :1, 1:] / (1 - d * Pf[:, :1, :1])
    G25 = control.ss(control.tf([2.5], [1.0, 0.5, 1.0]), inputs=["F"], outputs=["x"])
    gp_direct = rc.generalized_plant(G25, additive=0.1, performance=1.0, control_weight=0.1, disturbances=1.0,
                                     noise=0.01)
    direct = np.stack([np.asarray(gp_direct.P(2j * np.pi * x)) for x in f])
    assert np.abs(closed - direct).max() <= 1e-10 * np.abs(direct).max()
    # mu of an uncertain system: its M11 and its own blocks; |M11| = |k's half-range x G| here
    r = rc.mu(P, f_hz=f)
    assert np.allclose(r.upper, 0.0, atol=1e-12)  # k enters in series, no loop through it
    loop = (G * k).feedback(1)
    f2 = np.r_[0.0, f]
    r2 = rc.mu(loop, f_hz=f2)
    s = 2j * np.pi * f2
    m11 = np.abs(1.0 / (s**2 + 0.5 * s + 1 + 2.0))  # |h G / (1 + k0 G)|, h = 1, k0 = 2
    assert r2.upper[0] == pytest.approx(1 / 3, rel=1e-6) and r2.lower[0] == pytest.approx(1 / 3, rel=1e-6)
    assert np.all(r2.upper <= m11 * (1 + 2e-3))  # a real scalar's mu is at most |M11|


def test_additive_block_reads_the_control_when_asked():
    G = control.ss(control.tf([1.0], [1.0, 0.5, 1.0]))
    kw = dict(additive=0.5, performance=1.0, control_weight=0.1, disturbances=1.0, noise=0.01)
    plant = rc.generalized_plant(G, **kw)
    ctrl = rc.generalized_plant(G, additive_input="control", **kw)
    outs, ins = list(plant.P.output_labels), list(plant.P.input_labels)
    iz = outs.index(next(n for n in outs if n.startswith("unc_add_out")))
    iw = ins.index(next(n for n in ins if n.startswith("dist")))
    assert np.asarray(plant.P.D)[iz, iw] == pytest.approx(0.5)  # W_a d reaches z_add
    assert np.asarray(ctrl.P.D)[iz, iw] == 0.0
    with pytest.raises(rc.ModelError, match="additive_input"):
        rc.generalized_plant(G, additive_input="total", **kw)


def test_complex_scalar_margin_closed_form():
    # y' = -(1 + c) y with c = 1 + 0.5 delta, |delta| <= 1 complex: the pole -(1 + c) reaches the
    # axis first at c = -1 (delta = -4, the smallest |delta| with Re(1 + c) = 0): margin 4, s = 0
    c = rc.ucomplex("c", 1.0, 0.5)
    loop = _integrator().feedback(1 + c)
    m = rc.robstab(loop)
    assert m.lower == pytest.approx(4.0, rel=1e-3) and m.upper == pytest.approx(4.0, rel=1e-6)
    assert m.destabilizing["c"] == pytest.approx(-1.0, abs=1e-5)
    assert abs(m.pole) < 1e-5
    assert rc.as_statespace(loop).A[0, 0] == pytest.approx(-2.0)  # the nominal where a system is expected


def test_discrete_time_margins_closed_form():
    # x(k+1) = a x(k), a = 0.5 +- 0.2: |a| = 1 first at a = 1, 2.5 x the range, pole z = 1
    a = rc.ureal("a", 0.5, plusminus=0.2)
    delay = rc.as_uncertain(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))  # 1 / z
    m = rc.robstab(delay.feedback(a, sign=1))
    assert m.lower == pytest.approx(2.5, rel=1e-6) and m.upper == pytest.approx(2.5, rel=1e-9)
    assert m.destabilizing["a"] == pytest.approx(1.0, rel=1e-9) and abs(m.pole - 1) < 1e-9
    # x(k+1) = 0.5 (1 + D) x(k), ||D|| <= 0.3: small gain |0.5 D / (1 - 0.5 z^-1)|... peaks at z = 1
    # where 0.5 / (1 - 0.5) = 1: margin 1 / 0.3
    d = rc.ultidyn("d", 1, 0.3)
    m2 = rc.robstab((delay * 0.5).feedback(1 + d, sign=1))
    assert m2.upper == pytest.approx(1 / 0.3, rel=1e-6) and abs(abs(m2.pole) - 1) < 1e-9
