"""The H2 norm and H2-optimal output feedback: ``rc.h2norm(sys)``, ``rc.h2syn(P, nmeas, ncon)``.

* :func:`h2norm` from the controllability Gramian (Zhou, Doyle & Glover 1996, "Robust and
  Optimal Control", sec. 4.4 "H2 norm"): ``||G||_2^2 = trace(C Lc C^T)`` with
  ``A Lc + Lc A^T + B B^T = 0`` in continuous time (infinite for a nonzero ``D``), and
  ``||G||_2^2 = trace(C Lc C^T + D D^T)`` with ``A Lc A^T - Lc + B B^T = 0`` in discrete time
  (the sum of the squared Markov parameters). The smaller of the two Gramians (by the number
  of inputs or outputs) is used.
* :func:`h2syn` by two Riccati equations: continuous time by ZDG ch. 14 (the output-feedback
  H2 theorem, with general ``D12^T D12 = R1`` and ``D21 D21^T = R2`` and their cross terms with ``C1``
  and ``B1``; Doyle, Glover, Khargonekar & Francis 1989, sec. III), discrete time by the
  certainty-equivalence controller ``u = F x(k|k) + F0 w(k|k)`` with the filtered state and
  disturbance estimates of the Kalman filter (Chen & Francis 1995, "Optimal Sampled-Data
  Control Systems", sec. 6.4; the separation principle of discrete LQG with the cost
  ``E |z|^2`` of a unit white ``w``), which uses the current measurement (``Dk != 0``).

Every controller is verified: the closed loop ``Fl(P, K)`` is formed once, as arrays (which
also make the result's named ``closed_loop``), checked stable beyond round-off (continuous
time: from the real Schur form that also gives its norm; discrete: by
:func:`robustctl.lti.is_stable`), and its H2 norm computed as :func:`h2norm` does is the one
reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import control
import numpy as np
import scipy.linalg

from ..._lapack import real_schur, solve, svdvals
from ...errors import ModelError, SynthesisError
from ...interconnect import PartitionedPlant, PicklesStateSpaces, named_statespace
from ...lti import as_statespace, freqresp_array, is_stable, roundoff_margin
from ...plots import single_axes
from ...table import Table, result_html
from ..hinf.assumptions import check_assumptions, check_ranks, pbh_loses_rank
from ..hinf.synthesis import loop_shift, lower_lft_matrices
from ..mu.bounds import frequencies_hz
from ..partitioned import as_partitioned

__all__ = ["h2norm", "h2norm_matrices", "H2Result", "h2syn"]

#: Relative agreement required between the Riccati optimum and the closed loop's H2 norm.
VERIFY_RTOL = 1e-6


# ---------------------------------------------------------------------------- norm
def _is_discrete(dt: Any) -> bool:
    return dt not in (0, None)


def h2norm_matrices(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, dt: Any = 0) -> float:
    """H2 norm of ``(A, B, C, D)`` (arrays in; ``inf`` when unstable or, in continuous time, ``D != 0``).

    The kernel of :func:`h2norm` (no coercion). ``dt`` is 0/None for continuous time,
    anything else (a sampling time or True) for discrete time.
    """
    discrete = _is_discrete(dt)
    if B.shape[1] == 0 or C.shape[0] == 0:
        return 0.0
    if not discrete and D.any():
        return np.inf
    dd = float(np.sum(D * D)) if discrete else 0.0
    if A.shape[0] == 0:
        return float(np.sqrt(dd))
    if not discrete:  # one Schur form for the stability check and the Lyapunov solve
        h2, _ = _stable_continuous_h2(A, B, C)
        return np.inf if h2 is None else h2
    if not is_stable(A, roundoff_margin(A), dt=dt):
        return np.inf
    lyap = scipy.linalg.solve_discrete_lyapunov
    if B.shape[1] <= C.shape[0]:
        L = lyap(A, B @ B.T)  # controllability: A L A^T - L + B B^T = 0
        val = float(np.trace(C @ L @ C.T))
    else:
        L = lyap(A.T, C.T @ C)  # observability: A^T L A - L + C^T C = 0
        val = float(np.trace(B.T @ L @ B))
    return float(np.sqrt(max(val, 0.0) + dd))


def _stable_continuous_h2(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[float | None, float]:
    """``(||(A, B, C, 0)||_2, max Re eig(A))`` with one real Schur form for both the stability
    check (beyond :func:`roundoff_margin`) and the Lyapunov solve; the norm is None when unstable."""
    T, U, wr, _ = real_schur(A)
    abscissa = float(wr.max())
    if not abscissa < -roundoff_margin(A):
        return None, abscissa
    return float(np.sqrt(max(_continuous_h2_squared(A, B, C, (T, U)), 0.0))), abscissa


def _continuous_h2_squared(A: np.ndarray, B: np.ndarray, C: np.ndarray, schur: tuple | None = None) -> float:
    """``trace(C Lc C^T)`` (or ``trace(B^T Lo B)``) with one real Schur form ``A = U T U^T``.

    The Lyapunov equation ``T Y + Y T^T = -U^T B B^T U`` is solved by LAPACK ``dtrsyl`` on the
    quasi-triangular ``T`` (Bartels & Stewart 1972), so ``A`` is factored once (scipy's
    ``solve_continuous_lyapunov`` factors ``A`` and ``A^T``); the Gramian with the fewer
    columns on the outside is used.
    """
    T, U = real_schur(A)[:2] if schur is None else schur
    Bt, Ct = U.T @ B, C @ U
    if B.shape[1] <= C.shape[0]:
        Y, scale, info = scipy.linalg.lapack.dtrsyl(T, T, -(Bt @ Bt.T), trana="N", tranb="T")
        outer = Ct
    else:
        Y, scale, info = scipy.linalg.lapack.dtrsyl(T, T, -(Ct.T @ Ct), trana="T", tranb="N")
        outer = Bt.T
    if info < 0:  # pragma: no cover - an argument error would be a bug here
        raise ModelError(f"h2norm: LAPACK dtrsyl failed (info = {info}).")
    if scale != 1.0:  # dtrsyl scaled the solution down to avoid overflow
        Y = Y / scale
    return float((outer @ Y @ outer.T).trace())


def h2norm(sys: Any) -> float:
    """The H2 norm of a stable system, continuous or discrete.

    Parameters
    ----------
    sys : control.StateSpace, TransferFunction, PhysicalModel, ...
        Anything :func:`robustctl.lti.as_statespace` accepts.

    Returns
    -------
    float
        ``||G||_2 = sqrt(trace(C Lc C^T))`` (continuous; ``Lc`` the controllability Gramian,
        ZDG sec. 4.4), the root-mean-square output for unit-intensity white noise on every
        input, in the output's units per ``sqrt(input PSD)``; discrete:
        ``sqrt(trace(C Lc C^T + D D^T))``, the RMS output for unit-variance white
        sequences. ``inf`` for a continuous system with a nonzero feedthrough ``D`` and for
        an unstable system (a pole on or beyond the stability boundary, to round-off), as
        python-control's ``norm(sys, 2)``.

    Raises
    ------
    ModelError
        ``sys`` cannot be converted, or has NaN/inf in its matrices.

    See Also
    --------
    hinfnorm, h2syn

    Examples
    --------
    >>> import control, robustctl as rc
    >>> round(rc.h2norm(control.tf([1.0], [1.0, 2.0])), 12)  # 1/(s+a): 1/sqrt(2a)
    0.5
    """
    ss = as_statespace(sys, name="sys")
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    return h2norm_matrices(A, B, C, D, ss.dt)


# ---------------------------------------------------------------------------- result
@dataclass(frozen=True)
class H2Result(PicklesStateSpaces):
    """An H2-optimal design.

    Attributes
    ----------
    K : control.StateSpace
        The controller ``u = K y`` (inputs: the plant's measurement names; outputs: its
        control names), with the plant's time base.
    norm : float
        ``||Fl(P, K)||_2``, computed on the closed loop by :func:`h2norm` (verified equal to
        the Riccati optimum ``norm_riccati`` to ``VERIFY_RTOL``).
    closed_loop : control.StateSpace
        ``Fl(P, K)``: ``w -> z`` with the plant's names.
    X, Y : ndarray
        Stabilising solutions of the control and filter Riccati equations.
    F, L : ndarray
        State-feedback gain (``u = F x``) and filter gain (continuous: ``L`` in
        the observer ``dx = (A + L C2) x - L y + B2 u``, ``L = -(Y C2^T + B1 D21^T) R2^-1``;
        discrete: the filtered-state gain ``Lx`` of the current estimator).
    info : dict
        ``norm_riccati`` (the optimum from X and Y), ``full_information_norm``,
        ``closed_loop_spectral_abscissa`` (max Re of the poles, rad/s; discrete: spectral
        radius), ``discrete``, ``dt``.
    """

    K: Any
    norm: float
    closed_loop: Any
    X: np.ndarray
    Y: np.ndarray
    F: np.ndarray
    L: np.ndarray
    info: dict = field(default_factory=dict)

    def table(self) -> Table:
        """The design's key numbers, one per row."""
        i = self.info
        stab = "closed-loop spectral radius" if i.get("discrete") else "slowest closed-loop pole Re (rad/s)"
        rows = [
            ("time base", f"discrete, dt = {i.get('dt')} s" if i.get("discrete") else "continuous"),
            ("H2 norm (verified closed loop)", self.norm),
            ("H2 norm (Riccati optimum)", i.get("norm_riccati", float("nan"))),
            ("full-information part", i.get("full_information_norm", float("nan"))),
            ("controller order", self.K.nstates),
            (stab, i.get("closed_loop_stability", float("nan"))),
        ]
        return Table(("quantity", "value"), rows, title="H2 synthesis", digits=8)

    def summary(self) -> str:
        """A few sentences in plain words."""
        i = self.info
        base = f"discrete-time (dt = {i.get('dt')} s)" if i.get("discrete") else "continuous-time"
        return (
            f"H2-optimal {base} controller of order {self.K.nstates} for {self.K.ninputs} measurement(s) "
            f"and {self.K.noutputs} control input(s).\n"
            f"Closed-loop H2 norm {self.norm:.8g} (verified; the Riccati optimum is "
            f"{i.get('norm_riccati', np.nan):.8g}, of which the full-information part is "
            f"{i.get('full_information_norm', np.nan):.8g})."
        )

    def plot(self, f_hz: Any = None, fig: Any = None) -> Any:
        """Singular values of the closed loop ``w -> z`` over frequency (Hz). Returns the Figure."""
        return _plot_closed_loop(self.closed_loop, f_hz, fig, "H2 closed loop w -> z")

    def _repr_html_(self) -> str:
        return result_html(self.summary(), self.table())

    def __repr__(self) -> str:
        return f"H2Result(norm={self.norm:.8g}, order={self.K.nstates}, discrete={self.info.get('discrete')})"


def default_grid_hz(sys: Any) -> np.ndarray:
    """A log grid (Hz) a decade beyond the poles of ``sys`` each way (800 points); in discrete
    time 600 points up to Nyquist."""
    A = np.asarray(sys.A, dtype=float)
    dt = sys.dt
    if _is_discrete(dt):
        d = 1.0 if dt is True else float(dt)
        return np.geomspace(1e-4 / d, 0.5 / d, 600)
    poles = np.abs(np.linalg.eigvals(A)) / (2 * np.pi) if A.size else np.zeros(0)
    poles = poles[poles > 0]
    lo, hi = (poles.min() / 10, poles.max() * 10) if poles.size else (1e-2, 1e2)
    return np.geomspace(lo, hi, 800)


def _plot_closed_loop(cl: Any, f_hz: Any, fig: Any, title: str) -> Any:
    f_hz = default_grid_hz(cl) if f_hz is None else frequencies_hz(f_hz)
    sv = np.linalg.svd(freqresp_array(cl, f_hz), compute_uv=False)
    fig, ax = single_axes(fig, 7.0, 4.0)
    ax.loglog(f_hz, sv, lw=1)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("singular values")
    ax.set_title(title)
    return fig


# ---------------------------------------------------------------------------- Riccati kernels
def _hamiltonian_are(A, B, Q, R, S) -> np.ndarray | None:
    """Continuous Riccati solution from the ordered real Schur form of the ``2n`` Hamiltonian
    (Laub 1979, IEEE TAC 24(6); the method of SLICOT SB02RD that SB10HD uses), the cross term
    removed first: ``A_s = A - B R^-1 S^T``, ``Q_s = Q - S R^-1 S^T``,
    ``H = [[A_s, -B R^-1 B^T], [-Q_s, -A_s^T]]``, ``X = U21 U11^-1`` from the stable invariant
    subspace. None when the stable subspace is not ``n``-dimensional or ``U11`` is singular
    (the caller then uses the QZ solver)."""
    n = A.shape[0]
    RiSB = solve(R, np.hstack([S.T, B.T]))  # [R^-1 S^T, R^-1 B^T], one factorisation
    RiSt = RiSB[:, :n]
    As = A - B @ RiSt
    H = np.empty((2 * n, 2 * n))
    H[:n, :n], H[:n, n:], H[n:, :n], H[n:, n:] = As, -B @ RiSB[:, n:], -(Q - S @ RiSt), -As.T
    T, Z, _, sdim = real_schur(H, sort_lhp=True)
    if sdim != n:
        return None
    U11, U21 = Z[:n, :n], Z[n:, :n]
    sv = svdvals(U11)  # np.linalg.cond(U11) = sv[0] / sv[-1] (inf when singular)
    if not sv[-1] > 0 or sv[0] / sv[-1] > 1e12:
        return None
    X = solve(U11.T, U21.T).T
    return (X + X.T) / 2


def _are(A, B, Q, R, S, what: str, discrete: bool, fast: bool = False) -> np.ndarray:
    """Stabilising solution of the continuous or discrete Riccati equation with cross term ``S``
    (``fast``: the Hamiltonian Schur method first, :func:`_hamiltonian_are`)."""
    if fast and not discrete:
        X = _hamiltonian_are(A, B, Q, R, S)
        if X is not None:
            return X
    solve = scipy.linalg.solve_discrete_are if discrete else scipy.linalg.solve_continuous_are
    try:
        X = solve(A, B, Q, R, s=S)
    except (np.linalg.LinAlgError, ValueError) as exc:
        boundary = "unit circle" if discrete else "imaginary axis"
        raise SynthesisError(
            f"the {what} Riccati equation has no stabilising solution ({exc}); an assumption holds only "
            f"marginally (a nearly uncontrollable/unobservable mode on or near the {boundary}, or an "
            f"invariant zero of P12/P21 near it). Fix: damp the weights' poles and zeros slightly."
        ) from exc
    return (X + X.T) / 2


def _check_discrete_assumptions(m: dict[str, np.ndarray]) -> None:
    """(A1)-(A2) in discrete time: PBH tests at every ``|z| >= 1`` and the ranks of D12, D21."""
    A = m["A"]
    n = A.shape[0]
    if n:
        ev = np.linalg.eigvals(A)
        delta = 100 * np.finfo(float).eps * max(1.0, float(np.linalg.norm(A, 2)))
        for lam in ev[np.abs(ev) >= 1 - max(delta, 1e-9)]:
            if pbh_loses_rank(np.hstack([A - lam * np.eye(n), m["B2"]])):
                raise SynthesisError(
                    f"assumption (A1) violated: (A, B2) is not stabilisable -- the mode at z = {lam:.6g} "
                    "(|z| >= 1) cannot be moved by the control inputs u. Fix: make the weights stable, "
                    "or add an actuator."
                )
            if pbh_loses_rank(np.vstack([A - lam * np.eye(n), m["C2"]])):
                raise SynthesisError(
                    f"assumption (A1) violated: (C2, A) is not detectable -- the mode at z = {lam:.6g} "
                    "(|z| >= 1) is not seen by the measurements y. Fix: make the weights stable, or add a "
                    "sensor."
                )
    scale = max((float(np.linalg.norm(M, 2)) for M in m.values() if M.size), default=1.0)
    check_ranks(m["D12"], m["D21"], 1e-6 * scale)


def _continuous_design(m: dict[str, np.ndarray], fast: bool = False) -> tuple:
    """ZDG ch. 14 output-feedback H2 controller, general ``R1 = D12^T D12``, ``R2 = D21 D21^T`` (D22 = 0)."""
    A, B1, B2, C1, C2, D12, D21 = (m[k] for k in ("A", "B1", "B2", "C1", "C2", "D12", "D21"))
    R1, R2 = D12.T @ D12, D21 @ D21.T
    X = _are(A, B2, C1.T @ C1, R1, C1.T @ D12, "control (X)", False, fast)
    Y = _are(A.T, C2.T, B1 @ B1.T, R2, B1 @ D21.T, "filter (Y)", False, fast)
    F = -solve(R1, B2.T @ X + D12.T @ C1)  # state-feedback gain F2
    L = -solve(R2, C2 @ Y + D21 @ B1.T).T  # filter gain L2
    Ak = A + B2 @ F + L @ C2
    K = (Ak, -L, F, np.zeros((F.shape[0], L.shape[1])))  # the observer-based optimal controller
    fi2 = float(np.trace(B1.T @ X @ B1))
    opt2 = fi2 + float(np.trace(R1 @ F @ Y @ F.T))  # min ||T_zw||_2^2 = ||Gc B1||^2 + ||R1^1/2 F Gf||^2
    return K, X, Y, F, L, fi2, opt2


def _discrete_design(m: dict[str, np.ndarray]) -> tuple:
    """Certainty equivalence with the current estimator: ``u = F x(k|k) + F0 w(k|k)`` (D22 = 0)."""
    A, B1, B2, C1, C2, D11, D12, D21 = (m[k] for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21"))
    X = _are(A, B2, C1.T @ C1, D12.T @ D12, C1.T @ D12, "control (X)", True)
    Y = _are(A.T, C2.T, B1 @ B1.T, D21 @ D21.T, B1 @ D21.T, "filter (Y)", True)
    H = B2.T @ X @ B2 + D12.T @ D12
    F = -np.linalg.solve(H, B2.T @ X @ A + D12.T @ C1)  # LQR gain with cross term
    F0 = -np.linalg.solve(H, B2.T @ X @ B1 + D12.T @ D11)  # full-information feedthrough of w(k)
    V = C2 @ Y @ C2.T + D21 @ D21.T  # innovation covariance
    Lx = np.linalg.solve(V, C2 @ Y).T  # x(k|k) = x(k|k-1) + Lx e(k)
    Lw = np.linalg.solve(V, D21).T  # w(k|k) = Lw e(k)
    Lp = A @ Lx + B1 @ Lw  # x(k+1|k) = A x(k|k-1) + B2 u(k) + Lp e(k)
    Dk = F @ Lx + F0 @ Lw
    Ck = F - Dk @ C2
    Ak = A + B2 @ F - B2 @ Dk @ C2 - Lp @ C2
    Bk = Lp + B2 @ Dk
    Cfi = C1 + D12 @ F
    Dfi = D11 + D12 @ F0
    # full-information cost: ||(A + B2 F, B1 + B2 F0, C1 + D12 F, D11 + D12 F0)||_2^2
    fi2 = h2norm_matrices(A + B2 @ F, B1 + B2 @ F0, Cfi, Dfi, True) ** 2
    # plus the estimation penalty of certainty equivalence (Chen & Francis sec. 6.4)
    opt2 = fi2 + _estimation_penalty(A, B1, C2, D21, F, F0, H, Y, Lx, Lw, V)
    return (Ak, Bk, Ck, Dk), X, Y, F, Lx, fi2, opt2


def _estimation_penalty(A, B1, C2, D21, F, F0, H, Y, Lx, Lw, V) -> float:
    """``E |H^(1/2) (u - u_FI)|^2`` of the certainty-equivalent control, from the error covariances.

    ``u - u_FI = F (x(k|k) - x) + F0 (w(k|k) - w)``; the filtered errors' joint covariance is
    ``Cov([x; w] | y(0..k)) = blkdiag(Y, I) - [Y C2^T; D21^T] V^-1 [C2 Y, D21]``.
    """
    M = np.hstack([F, F0])
    G = np.vstack([Y @ C2.T, D21.T])
    P0 = scipy.linalg.block_diag(Y, np.eye(B1.shape[1]))
    Pf = P0 - G @ np.linalg.solve(V, G.T)
    return float(np.trace(H @ M @ Pf @ M.T))


# ---------------------------------------------------------------------------- surface
def h2syn(P: Any, nmeas: int | None = None, ncon: int | None = None) -> H2Result:
    """H2-optimal controller ``K`` minimising ``||Fl(P, K)||_2`` (continuous or discrete time).

    Parameters
    ----------
    P : PartitionedPlant, GeneralizedPlant, control.StateSpace, ...
        The generalized plant ``[z; y] = P [w; u]`` (a PartitionedPlant carries ``nmeas``
        and ``ncon``); a plant with ``dt`` gives a discrete-time controller with the same ``dt``.
    nmeas, ncon : int, optional
        Number of measurements (last outputs) and control inputs (last inputs).

    Returns
    -------
    H2Result
        ``K`` (named like the plant's y -> u), ``norm`` (verified ``||Fl(P, K)||_2``),
        ``closed_loop``, Riccati solutions and gains, ``info``.

    Raises
    ------
    SynthesisError
        A violated assumption, named: (A1) ``(A, B2)`` stabilisable and ``(C2, A)``
        detectable, (A2) ``D12`` full column rank and ``D21`` full row rank, (A3)/(A4) no
        invariant zero of ``P12``/``P21`` on the imaginary axis (continuous; ZDG ch. 14),
        and, in continuous time, ``D11 = 0`` (otherwise every closed loop has an infinite H2
        norm); a Riccati equation without stabilising solution; a closed loop that fails
        its check.

    See Also
    --------
    h2norm, hinfsyn, lqg

    References
    ----------
    Zhou, Doyle & Glover (1996), Robust and Optimal Control, ch. 14 (H2 optimal control).
    Doyle, Glover, Khargonekar & Francis (1989), State-space solutions to standard H2 and
    H-infinity control problems, IEEE TAC 34(8), sec. III.
    Chen & Francis (1995), Optimal Sampled-Data Control Systems, sec. 6.4.

    Examples
    --------
    >>> import control, robustctl as rc
    >>> P = control.ss(-1, [[1, 1]], [[1], [1]], [[0, 1], [1, 0]])
    >>> res = rc.h2syn(P, 1, 1)
    >>> [round(float(v), 9) for v in (res.K.A[0, 0], res.K.B[0, 0], res.K.C[0, 0])]
    [-3.0, 1.0, -1.0]
    """
    plant = as_partitioned(P, nmeas, ncon, who="h2syn", allow_discrete=True)
    m = plant.matrices()
    dt = plant.P.dt
    discrete = _is_discrete(dt)
    if not discrete:
        if np.any(m["D11"]):
            raise SynthesisError(
                "h2syn: D11 (z <- w feedthrough) must be zero in continuous time: a strictly proper "
                "controller leaves it in the closed loop, whose H2 norm is then infinite. Fix: filter the "
                "exogenous inputs or the regulated outputs (a strictly proper weight), or design in "
                "discrete time."
            )
        try:
            check_assumptions(m)
        except SynthesisError as exc:  # the H-infinity checks offer an LMI route that h2syn lacks
            raise SynthesisError(f"h2syn: {str(exc).replace(', or use method=' + repr('lmi'), '')}") from exc
    else:
        _check_discrete_assumptions(m)
    m0 = dict(m, D22=np.zeros_like(m["D22"]))
    # continuous: the Hamiltonian Schur solver first (SB10HD's method), then, if its closed loop
    # fails the checks below, scipy's QZ solver; every design is verified the same way
    for fast in ((True, False) if not discrete else (False,)):
        try:
            if discrete:
                K0, X, Y, F, L, fi2, opt2 = _discrete_design(m0)
            else:
                K0, X, Y, F, L, fi2, opt2 = _continuous_design(m0, fast=fast)
            K = loop_shift(K0, m["D22"])
            A_cl, B_cl, C_cl, D_cl = lower_lft_matrices(m, *K)
        except np.linalg.LinAlgError as exc:
            if fast:
                continue
            raise SynthesisError(f"h2syn: a singular matrix in the controller formulas ({exc}).") from exc
        if discrete:
            stable = is_stable(A_cl, roundoff_margin(A_cl), dt=dt)
            norm = h2norm_matrices(A_cl, B_cl, C_cl, D_cl, dt) if stable else np.inf
        else:  # D_cl = D11 = 0 here; one Schur form checks stability and gives the norm
            h2, abscissa = _stable_continuous_h2(A_cl, B_cl, C_cl) if A_cl.size else (0.0, 0.0)
            stable, norm = h2 is not None, (np.inf if h2 is None else h2)
        if not stable:
            if fast:
                continue
            raise SynthesisError(
                "h2syn: the closed loop Fl(P, K) is not stable (the Riccati solutions are not stabilising "
                "to working accuracy); rescale the plant or damp marginal weights."
            )
        opt = float(np.sqrt(max(opt2, 0.0)))
        if abs(norm - opt) <= VERIFY_RTOL * max(opt, 1e-300) + 1e-12 * max(1.0, norm):
            break
        if not fast:
            raise SynthesisError(
                f"h2syn: the closed loop's H2 norm {norm:.10g} differs from the Riccati optimum {opt:.10g} "
                "(ill-conditioned Riccati solutions); rescale the plant."
            )
    if discrete:
        ev = np.linalg.eigvals(A_cl) if A_cl.size else np.zeros(1)
        abscissa = float(np.max(np.abs(ev)))
    info = {
        "norm_riccati": opt,
        "full_information_norm": float(np.sqrt(max(fi2, 0.0))),
        "closed_loop_stability": abscissa,
        "discrete": discrete,
        "dt": dt,
    }
    Kss = _named_controller(plant, K, dt)
    closed_loop = named_statespace(A_cl, B_cl, C_cl, D_cl, dt, plant.w_names, plant.z_names,
                                   "closed loop Fl(P, K)")
    return H2Result(K=Kss, norm=norm, closed_loop=closed_loop, X=X, Y=Y, F=F, L=L, info=info)


def _named_controller(plant: PartitionedPlant, K: tuple, dt: Any):
    Ak, Bk, Ck, Dk = K
    try:
        return control.ss(
            Ak, Bk, Ck, Dk, dt,
            inputs=plant.y_names, outputs=plant.u_names,
            states=[f"xK{i + 1}" for i in range(Ak.shape[0])], name="K",
        )
    except ValueError as exc:  # pragma: no cover - shapes come from the plant
        raise ModelError(f"controller realisation failed: {exc}") from exc
