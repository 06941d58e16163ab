"""Where a loop closed on measured data decides its Nyquist verdict (robustctl.robust.yardsticks).

The mechanism of a measurement-model controller that is unstable on the data: the measurement
model is fitted above a lightly damped low mode (a suspension mode below its band, where it holds
only a real filler pole), so a controller that acts there destabilises that mode, while the loop's
largest gain sits on a well-damped resonance higher up and a decoupled channel carries coherence 0.
The truth, its white-noise test and the H1 estimate are built here with numpy/scipy.
"""

from __future__ import annotations

import numpy as np
import scipy.signal as ss

from robustctl.frd import FrequencyData
from robustctl.robust.yardsticks import _loop_detail, nyquist_stability

#: modes of the truth: (Hz, damping ratio, rate residue); the first is the "suspension" mode
#: below the measurement model's band, the second carries the x channel's largest loop gain,
#: the third is the decoupled y channel's
MODES_X = ((0.55, 0.02, 1.0), (3.7, 0.04, 20.0))
MODE_Y = (7.5, 0.02, 5.0)
#: the measurement model's band (Hz), above the suspension mode; its real filler pole (Hz)
MM_BAND, FILLER_HZ = (1.0, 20.0), 0.43
#: the controller: rate feedback -G1 on x (damps the 3.7 Hz mode) plus +G2 through a band-pass
#: at the suspension mode (negative damping there: r1 (G2 - G1) = 0.5 > 2 zeta w = 0.14)
G1, G2, G3 = 0.5, 1.0, 0.5
FS, NPERSEG, N_SEG = 50.0, 4096, 24


def _mode(f_hz, zeta, r):
    w = 2 * np.pi * f_hz
    return np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]]), np.array([[0.0], [r]]), np.array([[0.0, 1.0]])


def truth_abcd():
    """Two inputs (x, y), two rate outputs; y decoupled from x."""
    blocks = [_mode(*m) for m in MODES_X]
    ax, bx, cx = (np.block([[blocks[0][0], np.zeros((2, 2))], [np.zeros((2, 2)), blocks[1][0]]]),
                  np.vstack([blocks[0][1], blocks[1][1]]), np.hstack([blocks[0][2], blocks[1][2]]))
    ay, by, cy = _mode(*MODE_Y)
    A = np.block([[ax, np.zeros((4, 2))], [np.zeros((2, 4)), ay]])
    B = np.zeros((6, 2))
    B[:4, :1], B[4:, 1:] = bx, by
    C = np.zeros((2, 6))
    C[:1, :4], C[1:, 4:] = cx, cy
    return A, B, C, np.zeros((2, 2))


def controller_abcd():
    """``u = K y``: x: -G1 + G2 * band-pass at the suspension mode (zeta 0.5); y: -G3."""
    wb = 2 * np.pi * MODES_X[0][0]
    A = np.array([[0.0, 1.0], [-wb * wb, -wb]])
    B = np.array([[0.0, 0.0], [1.0, 0.0]])
    C = np.array([[0.0, G2 * wb], [0.0, 0.0]])
    D = np.diag([-G1, -G3])
    return A, B, C, D


def _resp(abcd, f):
    A, B, C, D = abcd
    s = 2j * np.pi * np.asarray(f)
    return np.stack([C @ np.linalg.solve(x * np.eye(A.shape[0]) - A, B) + D for x in s])


def measured():
    """One white-noise experiment per input (ZOH, scipy.signal.dlsim), 1 % output noise, H1 and
    ordinary coherence by scipy.signal.csd/coherence (Hann, 50 % overlap), the hold's response
    ``exp(-j pi f / fs) sinc(f / fs)`` divided out."""
    A, B, C, D = truth_abcd()
    Ad, Bd, Cd, Dd, _ = ss.cont2discrete((A, B, C, D), 1 / FS, method="zoh")
    rng = np.random.default_rng(7)
    n = NPERSEG * N_SEG
    H = coh = None
    for j in range(2):
        u = np.zeros((n, 2))
        u[:, j] = rng.standard_normal(n)
        _, y, _ = ss.dlsim((Ad, Bd, Cd, Dd, 1 / FS), u)
        y = y + 0.01 * np.std(y[:, j]) * rng.standard_normal(y.shape)
        f, puu = ss.welch(u[:, j], fs=FS, nperseg=NPERSEG)
        if H is None:
            H = np.zeros((f.size, 2, 2), complex)
            coh = np.zeros((f.size, 2, 2))
        for i in range(2):
            _, puy = ss.csd(u[:, j], y[:, i], fs=FS, nperseg=NPERSEG)
            H[:, i, j] = puy / puu
            coh[:, i, j] = ss.coherence(u[:, j], y[:, i], fs=FS, nperseg=NPERSEG)[1]
    H = H / (np.exp(-1j * np.pi * f / FS) * np.sinc(f / FS))[:, None, None]   # the hold divided out
    keep = (f > 0.1) & (f < 12.0)
    return FrequencyData(f[keep], H[keep], inputs=("x", "y"), outputs=("x", "y"), coherence=coh[keep])


def measurement_model(data, band_hz=MM_BAND, modes=(MODES_X[1], MODE_Y)):
    """A "measurement model" on ``band_hz`` with ``modes`` and a real filler at 0.43 Hz (default: the
    1-20 Hz one, the 3.7 and 7.5 Hz modes),
    residues and feedthrough fitted per channel by linear least squares (numpy) inside the band;
    with the defaults it has no suspension mode. Returns (A, B, C, D), one block of states per channel."""
    band = (data.f_hz >= band_hz[0]) & (data.f_hz <= band_hz[1])
    s = 2j * np.pi * data.f_hz[band]
    poles = [complex(-z * 2 * np.pi * f, 2 * np.pi * f * np.sqrt(1 - z * z)) for f, z, _ in modes]
    a_f = 2 * np.pi * FILLER_HZ
    basis = ([1 / (s - p) + 1 / (s - np.conj(p)) for p in poles]
             + [1j / (s - p) - 1j / (s - np.conj(p)) for p in poles])
    M = np.array(basis + [1 / (s + a_f), np.ones_like(s)]).T
    n_st = 2 * len(poles) + 1
    A, B, C, D = (np.zeros((4 * n_st, 4 * n_st)), np.zeros((4 * n_st, 2)), np.zeros((2, 4 * n_st)),
                  np.zeros((2, 2)))
    for i in range(2):
        for j in range(2):
            y = data.response[band, i, j]
            rows, rhs = np.vstack([M.real, M.imag]), np.concatenate([y.real, y.imag])
            coef = np.linalg.lstsq(rows, rhs, rcond=None)[0]
            o = (2 * i + j) * n_st
            # r/(s-p) + conj = (2 Re r s - 2 Re(r conj p)) / (s^2 - 2 Re p s + |p|^2): companion block
            for k, p in enumerate(poles):
                r = coef[k] + 1j * coef[len(poles) + k]
                A[o + 2 * k:o + 2 * k + 2, o + 2 * k:o + 2 * k + 2] = [[0.0, 1.0], [-abs(p) ** 2, 2 * p.real]]
                B[o + 2 * k + 1, j] = 1.0
                C[i, o + 2 * k:o + 2 * k + 2] = [-2 * (r * np.conj(p)).real, 2 * r.real]
            A[o + n_st - 1, o + n_st - 1], B[o + n_st - 1, j], C[i, o + n_st - 1] = -a_f, 1.0, coef[-2]
            D[i, j] = coef[-1]
    return A, B, C, D


def _closed_loop_poles(g, k):
    """Poles of ``y = G u, u = K y`` (positive feedback) from the matrices."""
    (Ag, Bg, Cg, Dg), (Ak, Bk, Ck, Dk) = g, k
    # y = Cg x + Dg u, u = Ck xk + Dk y: y = (I - Dg Dk)^-1 (Cg x + Dg Ck xk)
    E = np.linalg.inv(np.eye(Dg.shape[0]) - Dg @ Dk)
    Cy = E @ np.hstack([Cg, Dg @ Ck])
    A = np.block([[Ag, Bg @ Ck], [np.zeros((Ak.shape[0], Ag.shape[0])), Ak]])
    A = A + np.vstack([Bg @ Dk, Bk]) @ Cy
    return np.linalg.eigvals(A)


def test_the_verdict_names_where_the_loop_meets_the_critical_point_not_its_largest_gain():
    data = measured()
    K = controller_abcd()
    mm = measurement_model(data)
    in_band = (data.f_hz >= MM_BAND[0]) & (data.f_hz <= MM_BAND[1])
    # the measurement model fits the data in its band and misses the suspension mode below it
    g_mm = _resp(mm, data.f_hz)
    err = np.abs(g_mm[in_band, 0, 0] - data.response[in_band, 0, 0]) / np.abs(data.response[in_band, 0, 0])
    assert np.median(err) < 0.05
    i_s = int(np.argmin(np.abs(data.f_hz - MODES_X[0][0])))
    assert abs(g_mm[i_s, 0, 0]) < 0.3 * abs(data.response[i_s, 0, 0])
    # the mechanism: stable on the measurement model, unstable on the truth at the suspension mode
    assert _closed_loop_poles(mm, K).real.max() < 0
    p = _closed_loop_poles(truth_abcd(), K)
    worst = p[np.argmax(p.real)]
    assert worst.real > 0 and abs(abs(worst.imag) / (2 * np.pi) - MODES_X[0][0]) < 0.05
    # on the data (fine enough to resolve the modes) the generalized Nyquist count agrees
    L = data.response @ _resp(K, data.f_hz)
    verdict = nyquist_stability(data.f_hz, L, 0)
    assert verdict.stable is False and verdict.label == "unstable"
    # the reason: the closest approach of det(I - GK) at the suspension mode, outside the model's
    # band, with the coherence of the loop's channels (high), not the decoupled channel's (~0)
    gain = np.linalg.norm(L, 2, axis=(1, 2))
    assert abs(data.f_hz[np.argmax(gain)] - MODES_X[1][0]) < 0.05   # the largest gain is elsewhere
    assert data.coherence[np.argmax(gain), 1, 0] < 0.05             # on a decoupled channel
    text = _loop_detail(data.f_hz, L, data.coherence, data.response, _resp(K, data.f_hz), MM_BAND)
    assert text.count("winds") == 1, text
    lo, hi = (float(x) for x in text.split("around the origin in ")[1].split(" Hz")[0].split("-"))
    assert lo < MODES_X[0][0] < hi and hi - lo < 0.2, text
    assert "outside the 1-20 Hz band" in text, text
    loop_coh = float(text.split("coherence is ")[1].split(" ")[0])
    lowest = float(text.split("carrying the loop, ")[1].split(" ")[0])
    assert loop_coh > 0.5 > 0.05 > lowest, text   # the decoupled channel's ~0 is not the loop's
    top = float(text.split("sigma_max(GK) = ")[1].split(" at ")[1].split(" Hz")[0])
    assert abs(top - MODES_X[1][0]) < 0.05, text
    # the cure: a measurement model fitted over the band where the loop acts (from 0.3 Hz) holds the
    # suspension mode, and the controller is unstable on it too: the design model would have told
    wide = measurement_model(data, (0.3, MM_BAND[1]), (MODES_X[0], *(MODES_X[1], MODE_Y)))
    assert _closed_loop_poles(wide, K).real.max() > 0
