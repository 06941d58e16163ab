"""H-infinity synthesis that never hangs: ``rc.hinfsyn(P, nmeas, ncon)`` -> :class:`HinfResult`.

Two routes, both verified on the closed loop:

* ``method="riccati"`` (default): the DGKF / Glover-Doyle gamma iteration of
  :mod:`robustctl.robust.hinf.dgkf` (Zhou, Doyle & Glover 1996, ch. 16-17) on the plant with
  ``D12``, ``D21`` normalised and ``D22`` loop-shifted away (Safonov, Limebeer & Chiang 1989),
  after the assumption checks of :mod:`robustctl.robust.hinf.assumptions`. The optimal
  ``gamma`` is bracketed below by the Parrott bound of ``D11`` and above by ``||P11||_inf``
  (the open loop ``K = 0``, when ``P`` is stable) or by a geometric search, and bisected
  over the fixed grid ``gamma_k = (1 + gamma_tol)^k`` (integer ``k``) to the smallest feasible
  grid point: the result does not depend on the bracket the search started from, so a
  rounding-level change of the plant that changes the bracket does not move it. Each test is
  two Riccati equations (real Schur forms of order ``2n``).
* ``method="lmi"``: the Gahinet-Apkarian (1994) LMIs in cvxpy/Clarabel
  (:mod:`robustctl.robust.hinf.lmi`), without bisection and without the rank and
  imaginary-axis-zero assumptions; slower (a reference and a fallback for singular problems).

The controller is designed at ``gamma_opt (1 + backoff)``, because the Riccati solutions
blow up at the optimum (ZDG sec. 16.9), then ``Fl(P, K)`` is formed, and the result is
accepted only when the closed loop is stable and an upper bound of ``||Fl(P, K)||_inf`` is at
most ``gamma_design (1 + 1e-6)``; otherwise gamma is raised and the design repeated (at most
``MAX_RETRIES`` times). The bound is :func:`robustctl.robust.hinf.norm.hinfnorm`'s value ``g``
at ``NORM_TOL`` raised to ``g (1 + 2 NORM_TOL)``: the Bruinsma-Steinbuch iteration guarantees
``g <= ||G||_inf <= g (1 + 2 tol)``, so the reported ``gamma`` is never below the closed
loop's norm, and at most ``2 NORM_TOL`` (relative) above it. Every loop is capped in number; an
optional ``time_budget_s`` follows :mod:`robustctl.budget`'s policy.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np
import scipy.linalg

from ...budget import Deadline, as_deadline
from ...checks import positive_number
from ...errors import SynthesisError
from ...interconnect import PartitionedPlant, lft
from ...lti import freqresp_array, is_stable, spectral_abscissa
from ...plots import label_axes, single_axes
from ...table import Table, result_html
from ...threads import limit_blas
from ..mu.bounds import frequencies_hz
from ..partitioned import as_partitioned
from . import dgkf
from .assumptions import check_assumptions
from .lmi import lmi_controller, lmi_gamma, lmi_rescaled_gamma
from .norm import continuous_to_discrete, discrete_to_continuous, hinfnorm_matrices

__all__ = ["HinfResult", "hinfsyn"]

#: Design attempts above the bisection's gamma before giving up (each raises gamma).
MAX_RETRIES = 8
#: Gamma tests of the upper-bound search (factor 10 each) and of the bisection.
MAX_BRACKET_STEPS = 16
MAX_BISECTION_STEPS = 60
#: Without a positive lower bound (D11 = 0), the bisection's floor: this fraction of the first
#: feasible gamma or of 1, whichever is smaller (``||P11||_inf`` of a stable plant with a
#: near-integrator can be 1e15, and its fraction would cut the bisection off far above the
#: optimum). Not a proven bound: the Riccati tests lose their meaning far below it.
BISECTION_FLOOR = 1e-8
#: The finest ``gamma_tol``: the feasibility tests' own rounding is far above it.
MIN_GAMMA_TOL = 1e-12
#: Relative slack of the closed-loop check ``||Fl(P, K)||_inf <= gamma_design (1 + VERIFY_TOL)``.
VERIFY_TOL = 1e-6
#: Relative accuracy of the closed-loop norm (hinfnorm's ``tol``): the reported gamma is an
#: upper bound of ``||Fl(P, K)||_inf``, at most ``2 NORM_TOL`` (relative) above it.
NORM_TOL = 1e-7


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class HinfResult:
    """An H-infinity design.

    Attributes
    ----------
    K : control.StateSpace
        The controller ``u = K y``: inputs named like the plant's measurements, outputs like
        its control inputs.
    gamma : float
        Verified upper bound of the closed-loop H-infinity norm ``||Fl(P, K)||_inf`` of
        ``closed_loop``: ``||Fl|| <= gamma <= ||Fl|| (1 + 2 info["norm_tol"])``
        (:func:`hinfnorm`'s bracket, Bruinsma & Steinbuch 1990); exact for a static loop.
    gamma_opt : float
        Best achievable gamma found (the bisection's smallest feasible gamma, or the LMI optimum).
    closed_loop : control.StateSpace
        ``Fl(P, K)``: ``w -> z`` with the plant's names.
    info : dict
        ``method``, ``gamma_design``, ``backoff``, ``gamma_lower`` (largest gamma shown
        infeasible, or the Parrott bound), ``n_gamma_tests``, ``history`` (list of
        ``(gamma, feasible, reason)``), ``retries``, ``closed_loop_max_real_pole`` (rad/s),
        ``f_peak_hz``, ``time_s``, ``norm_tol`` (relative accuracy of ``gamma``),
        ``stopped_by_budget``, ``time_budget_s``.
    """

    K: Any
    gamma: float
    gamma_opt: float
    closed_loop: Any
    info: dict = field(default_factory=dict)

    def table(self) -> Table:
        """The design's key numbers, one per row."""
        i = self.info
        rows = [
            ("method", i.get("method", "")),
            ("gamma (verified closed-loop norm)", self.gamma),
            ("gamma_opt (best feasible)", self.gamma_opt),
            ("gamma lower bound", i.get("gamma_lower", float("nan"))),
            ("gamma design (backed off)", i.get("gamma_design", float("nan"))),
            ("closed-loop peak frequency (Hz)", i.get("f_peak_hz", float("nan"))),
            ("controller order", self.K.nstates),
            ("closed-loop spectral radius", i["closed_loop_spectral_radius"]) if i.get("discrete") else
            ("slowest closed-loop pole Re (rad/s)", i.get("closed_loop_max_real_pole", float("nan"))),
            ("gamma tests", i.get("n_gamma_tests", 0)),
            ("time (s)", i.get("time_s", float("nan"))),
        ]
        return Table(("quantity", "value"), rows, title="H-infinity synthesis", digits=6)

    def summary(self) -> str:
        """A few sentences in plain words."""
        i = self.info
        lines = [
            f"H-infinity controller ({i.get('method', '?')} route) of order {self.K.nstates} for "
            f"{self.K.ninputs} measurement(s) and {self.K.noutputs} control input(s).",
            f"Closed-loop H-infinity norm {self.gamma:.6g} (verified; peak at "
            f"{i.get('f_peak_hz', np.nan):.4g} Hz), designed at gamma = {i.get('gamma_design', np.nan):.6g}, "
            f"{100 * i.get('backoff', 0):.3g}% above "
            f"the best feasible gamma {self.gamma_opt:.6g} (lower bound {i.get('gamma_lower', np.nan):.6g}).",
        ]
        if i.get("stopped_by_budget"):
            lines.append(
                "The gamma bisection stopped at the time budget; gamma_opt may be above the optimum."
            )
        return "\n".join(lines)

    def plot(self, f_hz: Any = None, fig: Any = None) -> Any:
        """Singular values of the closed loop ``w -> z`` over frequency, with gamma and gamma_opt.

        Parameters
        ----------
        f_hz : array_like, optional
            Frequencies in Hz (default: 800 log-spaced points a decade beyond the closed
            loop's pole frequencies, plus the peak).
        fig : matplotlib Figure, optional

        Returns the matplotlib Figure.
        """
        f_peak = self.info.get("f_peak_hz", np.nan)
        if f_hz is not None:
            f_hz = frequencies_hz(f_hz)  # finite numbers >= 0 Hz, at least one
        dt = self.closed_loop.dt
        if f_hz is None and dt not in (0, None):  # up to the Nyquist frequency, four decades below
            nyquist = 0.5 / (1.0 if dt is True else float(dt))
            f_hz = np.geomspace(nyquist * 1e-4, nyquist, 800)
        if f_hz is None:
            A = np.asarray(self.closed_loop.A)
            poles = np.abs(np.linalg.eigvals(A)) / (2 * np.pi) if A.size else np.zeros(0)
            poles = poles[poles > 0]
            lo, hi = (poles.min() / 10, poles.max() * 10) if poles.size else (1e-2, 1e2)
            f_hz = np.geomspace(lo, hi, 800)
            if np.isfinite(f_peak) and f_peak > 0:
                f_hz = np.sort(np.append(f_hz, f_peak))
        f_hz = np.asarray(f_hz, dtype=float)
        sv = np.linalg.svd(freqresp_array(self.closed_loop, f_hz), compute_uv=False)
        fig, ax = single_axes(fig, 7.0, 4.0)
        ax.loglog(f_hz, sv, lw=1)
        ax.axhline(self.gamma, color="k", ls="--", lw=1, label=f"gamma = {self.gamma:.4g} (verified)")
        ax.axhline(self.gamma_opt, color="C3", ls=":", lw=1, label=f"gamma_opt = {self.gamma_opt:.4g}")
        if np.isfinite(f_peak) and f_peak > 0:
            ax.plot([f_peak], [self.gamma], "ko", ms=4)
        label_axes(ax, "frequency (Hz)", "singular values of Fl(P, K)", "H-infinity closed loop w -> z")
        return fig

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def __repr__(self) -> str:
        return (
            f"HinfResult(gamma={self.gamma:.6g}, gamma_opt={self.gamma_opt:.6g}, "
            f"order={self.K.nstates}, method={self.info.get('method')!r})"
        )


# ---------------------------------------------------------------------------- input checks
def _bounded(value: Any, name: str, upper: float, allow_zero: bool = False, unit: str = "") -> float:
    """A finite number in ``(0, upper]`` (``[0, upper]`` with ``allow_zero``), by the shared checks."""
    v = positive_number(value, name, SynthesisError, allow_zero=allow_zero, unit=unit)
    if v > upper:
        raise SynthesisError(f"{name} must be at most {upper:g}; got {value!r}.")
    return v


# ---------------------------------------------------------------------------- LFT kernel
def lower_lft_matrices(m: dict[str, np.ndarray], Ak, Bk, Ck, Dk) -> tuple[np.ndarray, ...]:
    """``Fl(P, K)`` as ``(A, B, C, D)``, states ``[x_P; x_K]`` (ZDG sec. 10.1).

    The array kernel of the design loop's closed-loop check (no named systems are built per
    retry); hinfsyn's named ``closed_loop`` comes from :func:`robustctl.interconnect.lft`,
    h2syn's from these arrays (the ones its norm is verified on).

    ``u = Ck xk + Dk y``, ``y = C2 x + D21 w + D22 u``; raises SynthesisError when
    ``I - Dk D22`` is singular (the loop is not well posed).
    """
    A, B1, B2, C1, C2 = m["A"], m["B1"], m["B2"], m["C1"], m["C2"]
    D11, D12, D21, D22 = m["D11"], m["D12"], m["D21"], m["D22"]
    n, nk = A.shape[0], Ak.shape[0]
    Fu = np.hstack([Dk @ C2, Ck, Dk @ D21])  # u = Fu [x; xk; w]
    if np.any(Dk):  # else I - Dk D22 = I
        E = np.eye(Dk.shape[0]) - Dk @ D22
        if np.linalg.cond(E) > 1e12:
            raise SynthesisError("the loop u = K y is not well posed: I - Dk D22 is singular.")
        Fu = np.linalg.solve(E, Fu)
    Fy = np.hstack([C2, np.zeros((C2.shape[0], nk)), D21]) + D22 @ Fu  # y = Fy [x; xk; w]
    top = np.hstack([A, np.zeros((n, nk)), B1]) + B2 @ Fu
    mid = np.hstack([np.zeros((nk, n)), Ak, np.zeros((nk, B1.shape[1]))]) + Bk @ Fy
    bot = np.hstack([C1, np.zeros((C1.shape[0], nk)), D11]) + D12 @ Fu
    nx = n + nk
    state = np.vstack([top, mid])
    return state[:, :nx], state[:, nx:], bot[:, :nx], bot[:, nx:]


def _closed_loop(m, K):
    return lower_lft_matrices(m, *K)


def loop_shift(K: tuple[np.ndarray, ...], D22: np.ndarray) -> tuple[np.ndarray, ...]:
    """``K = K0 (I + D22 K0)^-1`` (Safonov, Limebeer & Chiang 1989): the controller for the plant with D22."""
    Ak, Bk, Ck, Dk = K
    if not np.any(D22):
        return K
    M = np.linalg.inv(np.eye(Dk.shape[0]) + Dk @ D22)
    Ck2, Dk2 = M @ Ck, M @ Dk
    return Ak - Bk @ D22 @ Ck2, Bk - Bk @ D22 @ Dk2, Ck2, Dk2


# ---------------------------------------------------------------------------- Riccati route
def _balance(m: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A diagonal state similarity balancing ``[[A, B], [C, 0]]`` (LAPACK gebal, like MATLAB's ssbal).

    Balancing ``A`` alone can inflate ``B`` or ``C`` by orders of magnitude (a slow weight
    pole next to a large coupling), which inflates the Hamiltonians' norms and spoils the
    imaginary-axis test; including ``B`` and ``C`` keeps all three in proportion.
    """
    A = m["A"]
    n = A.shape[0]
    if n == 0:
        return dict(m)
    B = np.hstack([m["B1"], m["B2"]])
    C = np.vstack([m["C1"], m["C2"]])
    M = np.zeros((n + C.shape[0] + B.shape[1],) * 2)
    M[:n, :n], M[:n, n + C.shape[0] :], M[n : n + C.shape[0], :n] = A, B, C
    _, (scale, _) = scipy.linalg.matrix_balance(M, permute=False, separate=True)
    scale = scale[:n]
    out = dict(m)
    out["A"] = A * (scale[None, :] / scale[:, None])
    for k in ("B1", "B2"):
        out[k] = m[k] / scale[:, None]
    for k in ("C1", "C2"):
        out[k] = m[k] * scale[None, :]
    return out


def _upper_start(m: dict[str, np.ndarray], lower: float) -> tuple[float, bool]:
    """A first gamma to test and whether it is achievable in exact arithmetic.

    ``||P11||_inf`` (achieved by K = 0) when P is stable (True), else a guess (False).
    """
    A = m["A"]
    stable = is_stable(A, margin=0.0)
    if stable:
        g, _ = hinfnorm_matrices(A, m["B1"], m["C1"], m["D11"], 1e-3)
        if np.isfinite(g) and g > lower:
            return g * 1.01, True
    return max(2.0 * lower, 1.0), False


def _bisect(
    p: dgkf.Normalised, m, clock: Deadline, gamma_tol: float, history: list
) -> tuple[float, float, bool]:
    """Bracket and bisect gamma; returns ``(gamma_opt, gamma_lower, stopped_by_budget)``."""

    lower = dgkf.parrott_bound(p)

    def test(g: float) -> bool:
        t = dgkf.gamma_test(p, g, lower)
        history.append((g, t.feasible, t.reason))
        return t.feasible

    hi, achievable = _upper_start(m, lower)
    lo = lower
    for _ in range(MAX_BRACKET_STEPS):
        if test(hi):
            break
        if clock.expired():
            raise SynthesisError(
                f"time_budget_s={clock.budget_s:g} s ran out before any feasible gamma was found (tested up "
                f"to {hi:.3g}); raise time_budget_s or leave it None (the gamma tests are capped in number)."
            )
        if achievable:
            # K = 0 achieves ||P11||, and feasibility is monotone in gamma: this failure is
            # numerical. ||P11|| of a plant with a near-integrator weight is huge (4e5 on the
            # distillation example with eps = 1e-5, D-scaled) and its Riccati solutions lose
            # their sign there, at every larger gamma too. Climb from near the bottom instead.
            achievable, hi = False, max(2.0 * lower, 1e-6 * hi)
            continue
        lo, hi = hi, hi * 10.0
    else:
        reasons = "; ".join(sorted({h[2] for h in history[-3:]}))
        raise SynthesisError(
            f"no feasible gamma up to {hi / 10:.3g} ({reasons}). The plant is badly scaled or an assumption "
            "holds only marginally (a nearly unobservable/uncontrollable unstable or undamped mode); "
            "rescale the weights or try method='lmi'."
        )
    # bisection over the grid gamma_k = (1 + gamma_tol)^k: the smallest feasible grid point is a
    # function of the plant alone, whichever bracket (hence path) led to it
    step = np.log1p(gamma_tol)
    proven = lo  # largest gamma shown infeasible (or the Parrott bound)
    hi_k = int(np.ceil(np.log(hi) / step))
    if lo > 0:
        lo_k = int(np.floor(np.log(lo) / step))  # infeasible, or the Parrott bound
    else:
        # a floor, not a proven bound, below the unstable plant's start whatever ||P11|| is
        lo_k = int(np.floor(np.log(BISECTION_FLOOR * min(hi, 1.0)) / step))
    stopped = False
    for _ in range(MAX_BISECTION_STEPS):
        if hi_k - lo_k <= 1:
            break
        if clock.expired():
            stopped = True
            break
        mid_k = (lo_k + hi_k) // 2
        mid = float(np.exp(mid_k * step))
        if test(mid):
            hi_k = mid_k
        else:
            lo_k, proven = mid_k, mid
    return float(np.exp(hi_k * step)), proven, stopped


def _riccati_design(m: dict[str, np.ndarray], gamma: float) -> tuple[np.ndarray, ...]:
    """Central controller at ``gamma`` in the plant's own (u, y) coordinates, D22 loop-shifted back."""
    p = dgkf.normalise(m["A"], m["B1"], m["B2"], m["C1"], m["C2"], m["D11"], m["D12"], m["D21"])
    Ak, Bk, Ck, Dk = dgkf.central_controller(p, gamma)
    K0 = (Ak, Bk @ p.y_scale, p.u_scale @ Ck, p.u_scale @ Dk @ p.y_scale)
    return loop_shift(K0, m["D22"])


def _norm_bound(A, B, C, D) -> tuple[float, float]:
    """Upper bound of ``||(A, B, C, D)||_inf`` within ``2 NORM_TOL`` (relative) and the peak (rad/s).

    :func:`hinfnorm_matrices` returns ``g`` with ``g <= ||G|| <= g (1 + 2 tol)`` (Bruinsma &
    Steinbuch 1990); without states the norm ``sigma_max(D)`` is exact.
    """
    norm, w = hinfnorm_matrices(A, B, C, D, NORM_TOL)
    return (norm * (1.0 + 2.0 * NORM_TOL) if A.shape[0] else norm), w


def _verify(m, K, gamma_design: float) -> tuple[bool, float, float, float]:
    """Stable and ``||Fl(P,K)|| <= gamma_design (1+VERIFY_TOL)``? Returns (ok, norm bound, w_peak, max Re)."""
    A, B, C, D = _closed_loop(m, K)
    if not np.all(np.isfinite(A)) or not np.all(np.isfinite(B)):
        return False, np.inf, np.nan, np.inf
    max_re = spectral_abscissa(A)
    norm, w = _norm_bound(A, B, C, D)
    return bool(max_re < 0 and norm <= gamma_design * (1 + VERIFY_TOL)), norm, w, max_re


def _design_and_verify(m, design, gamma0: float, backoff: float, clock: Deadline, info: dict):
    """Design at ``gamma0 (1 + backoff)``, raise gamma until the closed-loop check passes (bounded)."""
    gamma_d = gamma0 * (1.0 + backoff)
    step = max(backoff, 0.01)
    last = ""
    for attempt in range(MAX_RETRIES + 1):
        try:
            K = design(gamma_d)
            ok, norm, w, max_re = _verify(m, K, gamma_d)
            last = f"closed-loop norm {norm:.6g}, max Re(pole) {max_re:.3g}"
        except (dgkf._InfeasibleError, np.linalg.LinAlgError, SynthesisError) as exc:
            ok, last = False, str(exc)
        if ok:
            info.update(
                gamma_design=gamma_d,
                retries=attempt,
                closed_loop_max_real_pole=max_re,
                f_peak_hz=w / (2 * np.pi),
            )
            return K, norm
        if clock.expired():
            break
        gamma_d *= 1.0 + step
        step *= 2.0
    raise SynthesisError(
        f"no controller passed the closed-loop check (stable, ||Fl(P,K)|| <= gamma) up to gamma = "
        f"{gamma_d:.6g} after {attempt + 1} attempts (last: {last}). Increase backoff, rescale the plant, "
        "or try method='lmi'."
    )


def _riccati(m, gamma_tol, backoff, clock, info):
    check_assumptions(m)
    mb = _balance(m)
    p = dgkf.normalise(mb["A"], mb["B1"], mb["B2"], mb["C1"], mb["C2"], mb["D11"], mb["D12"], mb["D21"])
    history: list = []
    gamma_opt, lower, stopped = _bisect(p, mb, clock, gamma_tol, history)
    info.update(
        gamma_lower=lower,
        parrott_bound=dgkf.parrott_bound(p),
        n_gamma_tests=len(history),
        history=history,
        stopped_by_budget=stopped,
    )
    K, norm = _design_and_verify(m, lambda g: _riccati_design(mb, g), gamma_opt, backoff, clock, info)
    return K, norm, gamma_opt


def _lmi(m, backoff, clock, info):
    if m["A"].shape[0] == 0:
        raise SynthesisError(
            "method='lmi' needs a plant with states; a static plant is a Parrott problem, solved by "
            "method='riccati'."
        )
    check_assumptions(m, ranks=False)
    # [[A, B], [C, 0]] balanced, then re-solved in the coordinates the solution balances
    # (lmi_rescaled_gamma); the controller is rebuilt in those coordinates (same transfer matrix)
    m0 = _balance(dict(m, D22=np.zeros_like(m["D22"])))
    scale = max(1.0, float(np.abs(m["D11"]).max()) if m["D11"].size else 1.0)
    gamma_opt, R0, S0, m0, passes = lmi_rescaled_gamma(m0, 1e-8 * scale, clock.remaining())
    rho = (
        10.0 * max(1.0, float(np.linalg.eigvalsh(R0)[-1]), float(np.linalg.eigvalsh(S0)[-1]))
        if R0.size
        else 1.0
    )
    info.update(
        gamma_lower=gamma_opt,
        n_gamma_tests=passes,
        history=[(gamma_opt, True, "LMI optimum")],
        stopped_by_budget=False,
    )

    def design(g):
        # Gahinet & Apkarian's two steps: the well-centred R, S of Theorem 4.3 at this gamma
        # (the common margin of its three LMIs maximised with R, S <= rho I), then the
        # controller's variables with X = S, Y = R fixed (Scherer, Gahinet & Chilali 1997);
        # the joint LMI in (X, Y, controller) is the fallback
        try:
            _, R, S = lmi_gamma(m0, 0.0, clock.remaining(), gamma_fixed=g, rho=rho)
            K = lmi_controller(m0, g, rho, clock.remaining(), RS=(R, S))
        except SynthesisError:
            K = lmi_controller(m0, g, rho, clock.remaining())
        return loop_shift(K, m["D22"])

    K, norm = _design_and_verify(m, design, gamma_opt, backoff, clock, info)
    return K, norm, gamma_opt


# ---------------------------------------------------------------------------- surface
@limit_blas
def hinfsyn(
    P: Any,
    nmeas: int | None = None,
    ncon: int | None = None,
    *,
    method: str = "riccati",
    gamma_tol: float = 1e-3,
    backoff: float = 0.01,
    time_budget_s: float | None = None,
) -> HinfResult:
    """H-infinity controller ``K`` minimising ``||Fl(P, K)||_inf`` (continuous or discrete time).

    A discrete plant (``dt`` set, e.g. from :func:`sampled_plant` with the hold and a
    computation delay) is mapped to continuous time by the bilinear map
    ``z = (1 + s) / (1 - s)``, which keeps every H-infinity norm (``w = tan(theta / 2)``),
    designed there, and the controller mapped back by ``s = (z - 1) / (z + 1)``; the discrete
    closed loop is then verified (spectral radius < 1, ``||Fl(P, K)||_inf <= gamma_design``
    over the unit circle). The controller has the plant's ``dt``.

    Parameters
    ----------
    P : PartitionedPlant, GeneralizedPlant, control.StateSpace, ...
        The generalized plant ``[z; y] = P [w; u]``. A PartitionedPlant (or a generalized
        plant built by ``rc.generalized_plant``) carries ``nmeas`` and ``ncon``; anything
        else is converted by :func:`robustctl.lti.as_statespace` and needs them.
    nmeas, ncon : int, optional
        Number of measurements (last outputs) and control inputs (last inputs).
    method : {"riccati", "lmi"}
        "riccati" (default): DGKF gamma bisection (fast; needs the standard assumptions).
        "lmi": Gahinet-Apkarian LMIs in cvxpy/Clarabel (slow; singular problems too),
        solved in the state coordinates their first solution balances
        (:func:`~robustctl.robust.hinf.lmi.lmi_rescaled_gamma`); the controller is rebuilt
        from well-centred ``R, S`` at the design gamma.
    gamma_tol : float
        Relative width of the final gamma bracket, ``gamma_opt <= gamma_lower (1 + gamma_tol)``,
        and the ratio of the bisection's grid (at least 1e-12).
    backoff : float
        The controller is designed at ``gamma_opt (1 + backoff)`` (relative, default 1%),
        which keeps the Riccati solutions well conditioned.
    time_budget_s : float or None
        Optional wall-clock budget (s) of the whole call, by :mod:`robustctl.budget`'s policy.
        None (default): the gamma tests (``MAX_BRACKET_STEPS``, ``MAX_BISECTION_STEPS``) and
        design retries (``MAX_RETRIES``) are capped in number, and the result depends only on
        the inputs. A number: the bisection may stop early (``info["stopped_by_budget"]``, the
        summary and a BudgetWarning say so); the LMI solver gets what is left as its limit.

    Returns
    -------
    HinfResult
        ``K`` (inputs = the plant's measurement names, outputs = its control names),
        ``gamma`` (verified ``||Fl(P, K)||_inf``), ``gamma_opt``, ``closed_loop``, ``info``.

    Raises
    ------
    SynthesisError
        A violated assumption (named, with a fix), bad ``nmeas``/``ncon``, a discrete plant with a
        pole at ``z = -1``,
        or no verified controller within the retries or the time budget.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> G = control.tf([1], [1, 0.2, 1])
    >>> P = control.augw(G, w1=control.tf([0.5, 1], [1, 0.01]), w2=control.tf(0.1, 1))
    >>> res = rc.hinfsyn(P, 1, 1)
    >>> res.gamma <= res.info["gamma_design"] * (1 + 1e-6)
    True
    """
    if not isinstance(method, str) or method not in ("riccati", "lmi"):
        raise SynthesisError(f"method must be 'riccati' or 'lmi'; got {method!r}.")
    gamma_tol = _bounded(gamma_tol, "gamma_tol", 0.5)
    if gamma_tol < MIN_GAMMA_TOL:
        raise SynthesisError(f"gamma_tol must be at least {MIN_GAMMA_TOL:g} (the gamma tests do not resolve "
                             f"finer); got {gamma_tol!r}.")
    backoff = _bounded(backoff, "backoff", 10.0, allow_zero=True)
    own_clock = not isinstance(time_budget_s, Deadline)  # a caller's (dksyn's) Deadline: it reports
    clock = as_deadline(time_budget_s, SynthesisError)
    plant = as_partitioned(P, nmeas, ncon, who="hinfsyn", allow_discrete=True)
    m = plant.matrices()
    if not all(np.all(np.isfinite(v)) for v in m.values()):
        raise SynthesisError("the plant's state-space matrices contain NaN or inf.")
    t0 = time.perf_counter()
    info: dict = {"method": method, "backoff": backoff, "gamma_tol": gamma_tol,
                  "time_budget_s": clock.budget_s}
    dt = plant.P.dt
    discrete = dt not in (0, None)
    mc = _bilinear_plant(m) if discrete else m
    if method == "riccati":
        K, norm, gamma_opt = _riccati(mc, gamma_tol, backoff, clock, info)
    else:
        K, norm, gamma_opt = _lmi(mc, backoff, clock, info)
    if discrete:
        K, norm = _discrete_controller(m, K, dt, info)
    info["discrete"] = discrete
    info["time_s"] = time.perf_counter() - t0
    if own_clock and info.get("stopped_by_budget"):
        clock.warn("hinfsyn's gamma bisection")
    return _result(plant, m, K, norm, gamma_opt, info)


def _bilinear_plant(m: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The discrete plant mapped by ``z = (1 + s) / (1 - s)``, partitioned like ``m``.

    The map sends the unit circle onto the imaginary axis (``w = tan(theta / 2)``) and commutes
    with the LFT, so ``||Fl(P, K)||_inf`` over ``|z| = 1`` equals that of the mapped loop over
    ``s = jw``: the discrete H-infinity problem and its optimal gamma are exactly those of
    the mapped continuous problem: ``s -> z`` is a Moebius map, so every transfer function of
    the loop is the same function of the new variable and the mapped realisations close the
    same loop. The assumptions (A1)-(A4) on the unit circle (SLICOT SB10DD's) become those of
    :mod:`~robustctl.robust.hinf.assumptions` on the imaginary axis.
    """
    n = m["A"].shape[0]
    if n and np.linalg.cond(np.eye(n) + m["A"]) > 1e12:
        raise SynthesisError(
            "the discrete plant has a pole at z = -1 (the Nyquist frequency), which the bilinear map "
            "sends to infinity. Fix: damp or remove the mode at fs/2 (e.g. a slightly smaller hold gain)."
        )
    nw, nu = m["B1"].shape[1], m["B2"].shape[1]
    nz = m["C1"].shape[0]
    B = np.hstack([m["B1"], m["B2"]])
    C = np.vstack([m["C1"], m["C2"]])
    D = np.block([[m["D11"], m["D12"]], [m["D21"], m["D22"]]])
    Ac, Bc, Cc, Dc = discrete_to_continuous(m["A"], B, C, D)
    return {
        "A": Ac, "B1": Bc[:, :nw], "B2": Bc[:, nw:], "C1": Cc[:nz], "C2": Cc[nz:],
        "D11": Dc[:nz, :nw], "D12": Dc[:nz, nw:], "D21": Dc[nz:, :nw], "D22": Dc[nz:, nw:nw + nu],
    }


def _discrete_controller(m: dict[str, np.ndarray], K: tuple, dt: Any, info: dict) -> tuple[tuple, float]:
    """The continuous design mapped back by ``s = (z - 1) / (z + 1)``, its discrete closed loop verified."""
    try:
        Kd = continuous_to_discrete(*K)
    except np.linalg.LinAlgError as exc:
        raise SynthesisError(
            "the continuous design has a controller pole at s = 1, which maps to z = infinity; change "
            "backoff slightly."
        ) from exc
    A, B, C, D = _closed_loop(m, Kd)
    rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    gamma_d = info["gamma_design"]
    norm, w = np.inf, np.nan
    if rho < 1.0:
        norm, w = _norm_bound(*discrete_to_continuous(A, B, C, D))
    if not (rho < 1.0 and norm <= gamma_d * (1 + VERIFY_TOL)):
        raise SynthesisError(
            f"the discrete controller failed its closed-loop check (spectral radius {rho:.12g}, "
            f"||Fl(P, K)||_inf = {norm:.6g} for gamma = {gamma_d:.6g}); rescale the plant or raise backoff."
        )
    theta = 2.0 * np.arctan(w) if np.isfinite(w) else np.pi
    info["closed_loop_spectral_radius"] = rho
    info["f_peak_hz"] = theta / (2.0 * np.pi * float(dt)) if dt is not True else np.nan
    info["f_peak_rad_per_sample"] = float(theta)
    return Kd, norm


def gamma_feasible(P: Any, nmeas: int | None = None, ncon: int | None = None, *, gamma: float) -> bool:
    """Is there a controller with ``||Fl(P, K)||_inf < gamma``? One gamma test of the Riccati route.

    The test :func:`hinfsyn`'s bisection makes (two Riccati equations of order ``2n`` on the
    same balanced, normalised plant; Glover & Doyle 1988), without a design: a caller that only
    needs to know whether a plant can beat a level (dksyn's line search, which keeps the lowest
    verified gamma of its candidates) learns it from one test instead of a bisection.

    Parameters
    ----------
    P : control.StateSpace, PartitionedPlant or GeneralizedPlant
        The plant ``[w; u] -> [z; y]`` (a discrete plant through the bilinear map, as hinfsyn).
    nmeas : int, optional
        Measurements (the last outputs of ``P``); not needed for a partitioned plant.
    ncon : int, optional
        Controls (the last inputs of ``P``); not needed for a partitioned plant.
    gamma : float
        The level (same units as ``||Fl(P, K)||_inf``), positive.

    Returns
    -------
    bool
        True when the Riccati test finds ``gamma`` feasible (hinfsyn would design below it).

    Raises
    ------
    SynthesisError
        A violated assumption of the Riccati route (as :func:`hinfsyn`), a bad ``gamma``.
    """
    gamma = positive_number(gamma, "gamma", SynthesisError)
    plant = as_partitioned(P, nmeas, ncon, who="gamma_feasible", allow_discrete=True)
    m = plant.matrices()
    if plant.P.dt not in (0, None):
        m = _bilinear_plant(m)
    check_assumptions(m)
    mb = _balance(m)
    p = dgkf.normalise(mb["A"], mb["B1"], mb["B2"], mb["C1"], mb["C2"], mb["D11"], mb["D12"], mb["D21"])
    return bool(dgkf.gamma_test(p, float(gamma)).feasible)


def _result(plant: PartitionedPlant, m, K, norm: float, gamma_opt: float, info: dict) -> HinfResult:
    Ak, Bk, Ck, Dk = K
    Kss = control.ss(
        Ak,
        Bk,
        Ck,
        Dk,
        plant.P.dt,
        inputs=plant.y_names,
        outputs=plant.u_names,
        states=[f"xK{i + 1}" for i in range(Ak.shape[0])],
        name="K",
    )
    cl = lft(plant, Kss)  # the shared named interconnection: w -> z with the plant's names
    # the bound of the realisation returned (the design loop's array LFT differs by rounding)
    mats = tuple(np.asarray(x, dtype=float) for x in (cl.A, cl.B, cl.C, cl.D))
    if info.get("discrete"):
        mats = discrete_to_continuous(*mats)  # the bilinear map keeps the H-infinity norm
    norm, _ = _norm_bound(*mats)
    info["norm_tol"] = NORM_TOL
    return HinfResult(K=Kss, gamma=float(norm), gamma_opt=float(gamma_opt), closed_loop=cl, info=info)
