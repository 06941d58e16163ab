"""Disk margins of a feedback loop (model or measured FRF) and the nu-gap between two models.

**Disk margins** (Seiler, Packard & Gahinet 2020, "An introduction to disk margins", IEEE
Control Systems Magazine 40(5), 78-95; Blight, Dailey & Gangsaas 1994). The loop ``L``
(negative feedback) tolerates every simultaneous gain and phase change ``f`` in the disk

    ``D(alpha, sigma) = { (1 + (1 - sigma)/2 delta) / (1 - (1 + sigma)/2 delta) : |delta| < alpha }``

up to the disk margin ``alpha = 1 / ||S + (sigma - 1)/2 I||`` (Seiler et al. eq. (7), with
``S = (I + L)^-1``; ``sigma`` the skew, 0 for the balanced disk where
``alpha = 2 / ||S - T||_inf``). The disk's real diameter gives the gain margins
``[(1 - alpha (1 - sigma)/2) / (1 + alpha (1 + sigma)/2), (1 + alpha (1 - sigma)/2) /
(1 - alpha (1 + sigma)/2)]`` (eq. (9)) and its intersection with the unit circle the phase
margin ``arccos((1 + g_lo g_hi) / (g_lo + g_hi))`` (eq. (11)).

* loop at a time: loop ``i`` broken with the others closed sees ``1 / (1 + L_i) = S_ii``,
  so ``alpha_i = 1 / ||S_ii + (sigma - 1)/2||_inf`` (exact for a model, by :func:`hinfnorm`);
* all loops at once (independent, simultaneous disks in every channel): ``alpha =
  1 / mu(S + (sigma - 1)/2 I)`` with a diagonal complex structure (Seiler et al. sec.
  "Multiloop disk margins"), from the upper bound of :func:`robustctl.robust.mu.mu`: a
  guaranteed margin on the frequency grid.

On measured data (a FrequencyData loop, or a plant FRF closed through a controller model)
the margins are those of the measured points; the closed loop's stability cannot be read
from the data and is reported as not checked.

**nu-gap** (Vinnicombe 1993, "Frequency domain uncertainty and the graph topology", IEEE TAC
38(9); Vinnicombe 2001, "Uncertainty and Feedback", Definition 3.1):
``delta_nu(G1, G2) = ||Nt2 M1 - Mt2 N1||_inf`` (normalized coprime factors of
:mod:`robustctl.robust.analysis.coprime`; equal to ``sup_w kappa(G1(jw), G2(jw))``, the chordal
distance) when ``det(I + G2~ G1)`` has no zero on the imaginary axis and
``wno det(I + G2~ G1) + eta(G1) - eta(G2) - eta0(G2) = 0``, and 1 otherwise.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np

from ...checks import choice, finite_number
from ...errors import SynthesisError
from ...frd import FrequencyData, as_frequency_data
from ...lti import as_statespace, freqresp_array, is_stable, roundoff_margin
from ...plots import label_axes, single_axes
from ...table import Table, result_html
from ..conventions import LOOP_SIGN, LoopSignWarning, loop_sign_words
from ..hinf.norm import discrete_to_continuous, hinfnorm, hinfnorm_matrices
from ..mu.bounds import frequencies_hz, mu
from .coprime import left_ncf, right_ncf

__all__ = ["DiskMargin", "DiskMarginResult", "diskmargin", "disk_gain_phase", "nugap"]


# ---------------------------------------------------------------------------- disk geometry
def disk_gain_phase(alpha: float, skew: float = 0.0) -> tuple[float, float, float]:
    """Gain margins (low, high; factors) and phase margin (deg) of the disk ``D(alpha, skew)``.

    Seiler, Packard & Gahinet (2020) eqs. (9)-(11). ``high`` is ``inf`` once the disk
    contains the half-plane to the right of ``low`` (``alpha (1 + skew)/2 >= 1``).

    Parameters
    ----------
    alpha : float
        Disk size (the disk margin), >= 0.
    skew : float
        Disk skew ``sigma`` (0: balanced, gain margins ``g`` and ``1/g``).

    Returns
    -------
    low, high : float
        Gain factors tolerated with the phase unchanged.
    phase_deg : float
        Phase change tolerated (deg) with the gain unchanged.
    """
    a, s = float(alpha), float(skew)
    lo = max((1 - a * (1 - s) / 2) / (1 + a * (1 + s) / 2), 0.0)
    den = 1 - a * (1 + s) / 2
    hi = (1 + a * (1 - s) / 2) / den if den > 0 else np.inf
    if a == 0:
        return 1.0, 1.0, 0.0
    x = lo if not np.isfinite(hi) else (1 + lo * hi) / (lo + hi)
    return lo, hi, float(np.degrees(np.arccos(np.clip(x, -1.0, 1.0))))


@dataclass(frozen=True)
class DiskMargin:
    """One disk margin: size, gain and phase margins and where it is smallest.

    Attributes
    ----------
    loop : str
        The channel's name, or ``"all at once"``.
    alpha : float
        Disk size (0 for an unstable closed loop).
    gain_margin : tuple of float
        ``(low, high)`` gain factors tolerated (with the phase unchanged).
    gain_margin_db : tuple of float
        The same in dB.
    phase_margin_deg : float
        Phase change tolerated (deg, with the gain unchanged).
    f_critical_hz : float
        Frequency (Hz) of the smallest disk.
    """

    loop: str
    alpha: float
    gain_margin: tuple[float, float]
    gain_margin_db: tuple[float, float]
    phase_margin_deg: float
    f_critical_hz: float


def _margin(loop: str, alpha: float, skew: float, f: float) -> DiskMargin:
    lo, hi, pm = disk_gain_phase(alpha, skew)
    with np.errstate(divide="ignore"):
        db = (float(20 * np.log10(lo)) if lo > 0 else -np.inf, float(20 * np.log10(hi)))
    return DiskMargin(loop, float(alpha), (lo, hi), db, pm, float(f))


@dataclass(frozen=True)
class DiskMarginResult:
    """Disk margins loop at a time and all loops at once.

    Attributes
    ----------
    loops : tuple of DiskMargin
        One per channel (loop broken at that channel, the others closed).
    simultaneous : DiskMargin
        Independent simultaneous variations in every channel (equals ``loops[0]`` for SISO).
    f_hz : ndarray
        The frequency grid of the curves (Hz).
    alpha_curves : ndarray, (n_loops + 1, nf)
        Disk size per frequency, loop at a time then all at once.
    skew : float
    source : str
        ``"model"`` (exact loop-at-a-time minima by the H-infinity norm) or ``"data"``.
    closed_loop_stable : bool or None
        Nominal stability of ``(I + L)^-1`` (``None``: data, not checked).
    info : dict
        ``at`` (where the loops were broken) and ``sign`` (the controller's feedback sign).
    """

    loops: tuple
    simultaneous: DiskMargin
    f_hz: np.ndarray
    alpha_curves: np.ndarray
    skew: float
    source: str
    closed_loop_stable: bool | None
    info: dict = field(default_factory=dict)

    def table(self) -> Table:
        """One row per loop and one for all loops at once."""
        rows = [
            (m.loop, m.alpha, m.gain_margin[0], m.gain_margin[1], m.gain_margin_db[0], m.gain_margin_db[1],
             m.phase_margin_deg, m.f_critical_hz)
            for m in (*self.loops, self.simultaneous)
        ]
        cols = ("loop", "disk margin", "gain low", "gain high", "gain low (dB)", "gain high (dB)",
                "phase (deg)", "f critical (Hz)")
        return Table(cols, rows, title=f"Disk margins (skew {self.skew:g}, {self.source})", digits=5)

    def summary(self) -> str:
        """A few sentences in plain words."""
        s = self.simultaneous
        conv = self.info.get("convention", "")
        stab = {True: "stable", False: f"UNSTABLE with {conv}: margins 0",
                None: "not checked (measured data)"}
        stab = stab[self.closed_loop_stable]
        worst = min(self.loops, key=lambda m: m.alpha)
        return (
            f"Disk margins of {len(self.loops)} loop(s) from {self.source}; nominal closed loop {stab}.\n"
            f"All loops at once: gain x[{s.gain_margin[0]:.4g}, {s.gain_margin[1]:.4g}] "
            f"({s.gain_margin_db[0]:.3g} / +{s.gain_margin_db[1]:.3g} dB) or phase "
            f"+-{s.phase_margin_deg:.3g} deg, "
            f"smallest at {s.f_critical_hz:.4g} Hz.\n"
            f"Weakest single loop: {worst.loop} (phase +-{worst.phase_margin_deg:.3g} deg at "
            f"{worst.f_critical_hz:.4g} Hz)."
        )

    def plot(self, fig: Any = None) -> Any:
        """Disk size over frequency for each loop and all at once. Returns the Figure."""
        fig, ax = single_axes(fig, 7.0, 4.0)
        names = [m.loop for m in self.loops] + ["all at once"]
        for curve, name in zip(self.alpha_curves, names):
            ax.semilogx(self.f_hz, curve, lw=1, ls="--" if name == "all at once" else "-", label=name)
        label_axes(ax, "frequency (Hz)", "disk margin alpha", "Disk margins")
        return fig

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())


def _warn_other_sign(Lss: Any, sign: float) -> None:
    """An unstable loop that the other controller sign would stabilise is most likely a sign slip."""
    import control

    n = Lss.ninputs
    other = control.feedback(control.ss([], [], [], np.eye(n), Lss.dt), -Lss)
    if is_stable(other, roundoff_margin(other)):
        warnings.warn(
            f"diskmargin: the closed loop is unstable with {loop_sign_words(sign)} but stable with "
            f"{loop_sign_words(-sign)}; robustctl's controllers are u = +K y (sign=+1), MATLAB's "
            "diskmargin(G, K) assumes u = -K y: pass the sign of your controller.",
            LoopSignWarning, stacklevel=3)


# ---------------------------------------------------------------------------- loop assembly
def _is_data(x: Any) -> bool:
    frd = hasattr(x, "omega") and (hasattr(x, "frdata") or hasattr(x, "fresp"))  # python-control's FRD
    return isinstance(x, FrequencyData) or frd


def _default_grid(sys: Any) -> np.ndarray:
    A = np.asarray(sys.A, dtype=float)
    w = np.abs(np.linalg.eigvals(A)) if A.size else np.zeros(0)
    w = w[w > 0] / (2 * np.pi)
    lo, hi = (w.min() / 100, w.max() * 100) if w.size else (1e-3, 1e3)
    if sys.dt not in (0, None):
        hi = min(hi, 0.5 / float(sys.dt))
        lo = min(lo, hi / 1e4)
    return np.geomspace(lo, hi, 1200)


def _model_loop(L: Any, K: Any, sign: float, at: str):
    G = as_statespace(L, name="L")
    if K is None:
        return G, list(G.input_labels)
    Kss = as_statespace(K, name="K")
    Lss = (Kss * G) if at == "input" else (G * Kss)
    names = list(G.input_labels) if at == "input" else list(G.output_labels)
    return -sign * Lss, names


def _data_loop(L: Any, K: Any, sign: float, at: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
    data = as_frequency_data(L, "L")
    H = np.asarray(data.response, complex)
    if K is None:
        return data.f_hz, H, list(data.inputs)
    Kf = freqresp_array(as_statespace(K, name="K"), data.f_hz)
    try:
        Lf = Kf @ H if at == "input" else H @ Kf
    except ValueError as exc:
        raise SynthesisError(
            f"diskmargin: the plant data ({H.shape[1]} outputs x {H.shape[2]} inputs) and the controller "
            f"({Kf.shape[1]} x {Kf.shape[2]}) do not form a loop; K maps the plant's outputs to its inputs."
        ) from exc
    return data.f_hz, -sign * Lf, list(data.inputs) if at == "input" else list(data.outputs)


def _simultaneous(Mf: np.ndarray, f: np.ndarray) -> np.ndarray:
    n = Mf.shape[1]
    if n == 1:
        return 1.0 / np.maximum(np.abs(Mf[:, 0, 0]), 1e-300)
    r = mu(Mf, [[1, 0]] * n, lower=False)
    return 1.0 / np.maximum(r.upper, 1e-300)


def diskmargin(L: Any, K: Any = None, *, f_hz: Any = None, skew: float = 0.0, sign: float = LOOP_SIGN,
               at: str = "output") -> DiskMarginResult:
    """Disk margins of a feedback loop, loop at a time and all loops at once.

    Parameters
    ----------
    L : system or FrequencyData
        The loop transfer function (square, negative feedback ``u = -L e``), or with ``K`` the
        plant ``G`` (a model or its measured FRF, shape (nf, n_out, n_in)).
    K : system, optional
        A controller closing the loop around ``G``: ``L = G K`` (``at="output"``, loops
        broken at the plant outputs) or ``K G`` (``at="input"``).
    f_hz : array_like, optional
        Frequencies (Hz) of the curves for a model (default: two decades beyond its poles);
        data use their own frequencies.
    skew : float
        Disk skew ``sigma`` (0: balanced, gain margins ``g`` and ``1/g``; > 0 more gain
        increase, < 0 more decrease; Seiler et al. 2020 sec. "Skewed disks").
    sign : {+1, -1}
        The feedback sign of ``K``: +1 (default) for ``u = K y``, robustctl's one loop sign
        (:mod:`robustctl.robust.conventions`; what :func:`hinfsyn`, :func:`h2syn`, :func:`lqg`,
        :func:`dksyn` return), -1 for ``u = -K y`` (MATLAB's ``diskmargin(G, K)``). A closed
        loop that is unstable with this sign is reported as such (``closed_loop_stable``,
        the summary names the sign) and, when the other sign would be stable, a
        :class:`~robustctl.robust.conventions.LoopSignWarning` says so.
    at : {"output", "input"}
        Where the loops are broken when ``K`` is given.

    Returns
    -------
    DiskMarginResult
        ``loops`` (one :class:`DiskMargin` per channel), ``simultaneous``, the curves.

    Raises
    ------
    SynthesisError
        A non-square loop, a controller that does not fit the plant, a bad skew, sign or ``at``.

    References
    ----------
    Seiler, Packard & Gahinet (2020), "An introduction to disk margins", IEEE CSM 40(5), eqs. (7)-(11).

    Examples
    --------
    >>> import control, robustctl as rc
    >>> dm = rc.diskmargin(control.tf([3.0], [1.0, 1.0]))   # S - T = (s - 2)/(s + 4): alpha = 2
    >>> round(dm.simultaneous.alpha, 9), round(dm.simultaneous.phase_margin_deg, 6)
    (2.0, 90.0)
    """
    skew = finite_number(skew, "skew", SynthesisError)
    at = choice(at, "at", ("output", "input"), SynthesisError)
    if sign not in (-1, 1, -1.0, 1.0) or isinstance(sign, bool):
        raise SynthesisError(f"sign must be -1 (u = -K y) or +1 (u = K y); got {sign!r}.")
    c = (skew - 1.0) / 2.0
    if _is_data(L):
        if f_hz is not None:
            raise SynthesisError("diskmargin: data carry their own frequencies; do not pass f_hz.")
        f, Lf, names = _data_loop(L, K, float(sign), at)
        stable, Lss = None, None
    else:
        Lss, names = _model_loop(L, K, float(sign), at)
        f = _default_grid(Lss) if f_hz is None else frequencies_hz(f_hz)
        Lf = freqresp_array(Lss, f)
    n = Lf.shape[1]
    if Lf.shape[1] != Lf.shape[2]:
        raise SynthesisError(f"diskmargin needs a square loop; L is {Lf.shape[1]} x {Lf.shape[2]}.")
    Sf = np.linalg.inv(np.eye(n) + Lf)
    Mf = Sf + c * np.eye(n)
    curves = np.vstack([1.0 / np.maximum(np.abs(Mf[:, i, i]), 1e-300) for i in range(n)]
                       + [_simultaneous(Mf, f)])
    loops = []
    if Lss is not None:
        S = control.feedback(control.ss([], [], [], np.eye(n), Lss.dt), Lss)
        stable = is_stable(S, roundoff_margin(S))
        if not stable and K is not None:
            _warn_other_sign(Lss, float(sign))
        for i in range(n):
            if not stable:
                loops.append(_margin(names[i], 0.0, skew, np.nan))
                continue
            Si = control.ss(S.A, S.B[:, i:i + 1], S.C[i:i + 1, :], S.D[i:i + 1, i:i + 1] + c, S.dt)
            g, fpk = hinfnorm(Si)
            k = int(np.argmin(curves[i]))
            if curves[i][k] < 1.0 / g:  # the grid cannot be below the exact minimum; keep the exact one
                g, fpk = 1.0 / curves[i][k], f[k]
            loops.append(_margin(names[i], 1.0 / g, skew, fpk))
    else:
        for i in range(n):
            k = int(np.argmin(curves[i]))
            loops.append(_margin(names[i], curves[i][k], skew, f[k]))
    k = int(np.argmin(curves[-1]))
    if n == 1:
        sim = _margin("all at once", loops[0].alpha, skew, loops[0].f_critical_hz)
        curves[-1] = curves[0]
    elif stable is False:
        sim = _margin("all at once", 0.0, skew, np.nan)
    else:
        sim = _margin("all at once", min(curves[-1][k], min(m.alpha for m in loops)), skew, f[k])
    return DiskMarginResult(
        loops=tuple(loops), simultaneous=sim, f_hz=np.asarray(f, float), alpha_curves=curves, skew=skew,
        source="data" if Lss is None else "model", closed_loop_stable=stable,
        info={"at": at, "sign": float(sign), "convention": loop_sign_words(float(sign)) if K is not None
              else "L in negative feedback, closed loop (I + L)^-1"},
    )


# ---------------------------------------------------------------------------- nu-gap
def _continuous(ss: Any) -> tuple[np.ndarray, ...]:
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    if ss.dt in (0, None):
        return A, B, C, D
    return discrete_to_continuous(A, B, C, D)


def _count(ev: np.ndarray, scale: float) -> tuple[int, int]:
    """(open right half plane, imaginary axis) counts with the round-off margin of lti.is_stable."""
    tol = 64 * np.finfo(float).eps * max(1.0, scale)
    return int(np.sum(ev.real > tol)), int(np.sum(np.abs(ev.real) <= tol))


def _poles_count(A: np.ndarray) -> tuple[int, int]:
    if A.shape[0] == 0:
        return 0, 0
    return _count(np.linalg.eigvals(A), float(np.linalg.norm(A, 1)))


def _winding_ok(m1: tuple, m2: tuple) -> bool:
    """Vinnicombe's condition for ``det(I + G2~ G1)``: no zero on the axis and the winding number test.

    ``wno`` (Nyquist contour, clockwise) = RHP zeros - RHP poles of ``det(I + G2~ G1)``, from the
    state space ``H = I + G2~ G1`` (hidden modes appear as both a pole and a zero and cancel).
    """
    A1, B1, C1, D1 = m1
    A2, B2, C2, D2 = m2
    n1, n2 = A1.shape[0], A2.shape[0]
    # G2~(s) = G2(-s)^T = (-A2^T, -C2^T, B2^T, D2^T); H = I + G2~ G1 (G1 first)
    AH = np.block([[A1, np.zeros((n1, n2))], [-C2.T @ C1, -A2.T]])
    BH = np.vstack([B1, -C2.T @ D1])
    CH = np.hstack([D2.T @ C1, B2.T])
    DH = np.eye(D1.shape[1]) + D2.T @ D1
    if np.linalg.cond(DH) > 1e12:
        return False  # det(I + G2~ G1) vanishes at infinite frequency
    zeros = np.linalg.eigvals(AH - BH @ np.linalg.solve(DH, CH)) if AH.size else np.zeros(0)
    poles = np.linalg.eigvals(AH) if AH.size else np.zeros(0)
    scale = float(np.linalg.norm(AH, 1)) if AH.size else 1.0
    z_rhp, z_axis = _count(zeros, scale)
    p_rhp, _ = _count(poles, scale)
    if z_axis:
        return False
    eta1, _ = _poles_count(A1)
    eta2, eta02 = _poles_count(A2)
    return (z_rhp - p_rhp) + eta1 - eta2 - eta02 == 0


def nugap(G1: Any, G2: Any) -> tuple[float, float]:
    """Vinnicombe's nu-gap between two models of the same shape and time base.

    Parameters
    ----------
    G1, G2 : system
        Anything :func:`robustctl.lti.as_statespace` accepts (minimal realisations: hidden
        unstable modes are counted as poles), both continuous or both discrete with equal ``dt``.

    Returns
    -------
    gap : float
        ``delta_nu(G1, G2)`` in [0, 1]: ``||Nt2 M1 - Mt2 N1||_inf`` when the winding-number
        condition holds, else 1. A controller with ``b(G1, K) > gap`` stabilises ``G2``
        (Vinnicombe 2001, Theorem 3.8).
    f_hz : float
        Frequency (Hz) of the largest chordal distance (NaN when the gap is 1 by the condition).

    Raises
    ------
    SynthesisError
        Different shapes or time bases.

    References
    ----------
    Vinnicombe (2001), Uncertainty and Feedback: H-infinity loop-shaping and the nu-gap
    metric, Definition 3.1 and Lemma 3.5.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> round(rc.nugap(control.tf([1], [1, 1]), control.tf([3], [1, 1]))[0], 9)  # |k1-k2|/(k1+k2)
    0.5
    """
    s1, s2 = as_statespace(G1, name="G1"), as_statespace(G2, name="G2")
    if (s1.noutputs, s1.ninputs) != (s2.noutputs, s2.ninputs):
        raise SynthesisError(
            f"nugap compares models of one shape; G1 is {s1.noutputs}x{s1.ninputs}, "
            f"G2 {s2.noutputs}x{s2.ninputs}."
        )
    if (s1.dt in (0, None)) != (s2.dt in (0, None)) or (s1.dt not in (0, None) and s1.dt != s2.dt):
        raise SynthesisError(f"nugap compares models of one time base; dt = {s1.dt} and {s2.dt}.")
    m1, m2 = _continuous(s1), _continuous(s2)
    if not _winding_ok(m1, m2):
        return 1.0, float("nan")
    Ar, Br, Cr, Dr = right_ncf(*m1)  # [M1; N1]
    Al, Bl, Cl, Dl = left_ncf(*m2)  # [Nt2, Mt2]
    p, m = s1.noutputs, s1.ninputs
    # Psi = [-Nt2, Mt2] [M1; N1]: series (right factors first)
    Bl_ = np.hstack([-Bl[:, :m], Bl[:, m:]])
    Dl_ = np.hstack([-Dl[:, :m], Dl[:, m:]])
    n1 = Ar.shape[0]
    A = np.block([[Ar, np.zeros((n1, Al.shape[0]))], [Bl_ @ Cr, Al]])
    B = np.vstack([Br, Bl_ @ Dr])
    C = np.hstack([Dl_ @ Cr, Cl])
    D = Dl_ @ Dr
    g, w = hinfnorm_matrices(A, B, C, D, 1e-9)
    del p
    if s1.dt not in (0, None):
        theta = 2 * np.arctan(w) if np.isfinite(w) else np.pi
        return float(min(g, 1.0)), float(theta / (2 * np.pi * float(s1.dt)))
    return float(min(g, 1.0)), float(w / (2 * np.pi))
