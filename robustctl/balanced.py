"""Balanced truncation by the square-root method (Caltech eqs. 11-13; Moore 1981, Glover 1984,
Laub et al. 1987 / Tombs & Postlethwaite 1987 square-root form).

The Gramians are never formed and inverted: their Cholesky factors ``P = Lc Lc^T``,
``Q = Lo Lo^T`` come from Hammarling's method (SLICOT SB03OD through slycot when available,
otherwise from scipy's Bartels-Stewart solution symmetrised and factored by a clipped
eigendecomposition). The Hankel singular values are the singular values of ``Lo^T Lc``, and the
projections ``T_l = S1^{-1/2} U1^T Lo^T``, ``T_r = Lc V1 S1^{-1/2}`` only divide by the *kept*
singular values, which is what keeps lightly damped systems with dozens of modes well posed.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Any

import control
import numpy as np
import scipy.linalg as sla

from .errors import FitError, ModelError
from .lti import as_statespace, rebuild_statespace, statespace_state
from .plots import single_axes
from .table import Table
from .threads import limit_blas

__all__ = ["BalancedTruncation", "balanced_truncation", "gramian_factor"]


@dataclass(frozen=True, eq=False)
class BalancedTruncation:
    """Result of :func:`balanced_truncation`.

    Attributes
    ----------
    sys : control.StateSpace
        Reduced model of ``order`` states (same signal names and ``D``).
    hsv : ndarray
        All Hankel singular values of the original system, descending.
    bound : float
        ``2 * sum(hsv[order:])``: the a-priori bound on ``||G - G_m||_inf`` (eq. 13).
    order : int
        States kept.
    """

    sys: Any
    hsv: np.ndarray
    bound: float
    order: int

    def statespace(self):
        """The reduced ``control.StateSpace`` (the state-space protocol, :func:`rc.as_statespace`)."""
        return self.sys

    def table(self) -> Table:
        """One row per Hankel singular value: its value, relative size and whether it is kept."""
        rows = [
            (k, float(h), float(h / self.hsv[0]) if self.hsv[0] > 0 else 0.0, k <= self.order)
            for k, h in enumerate(self.hsv, start=1)
        ]
        return Table(
            ("state", "Hankel singular value", "relative", "kept"),
            rows,
            title=f"Balanced truncation to {self.order} of {self.hsv.size} states (Caltech eq. 13)",
        )

    def summary(self) -> str:
        """One sentence: states kept and the a-priori error bound."""
        return (
            f"Balanced truncation kept {self.order} of {self.hsv.size} states; "
            f"||G - G_r||_inf <= {self.bound:.4g} (2 x the sum of the discarded Hankel singular values)."
        )

    def plot(self, fig: Any = None) -> Any:
        """The Hankel singular values, kept ones filled (matplotlib Figure)."""
        fig, ax = single_axes(fig, 6, 3.5)
        k = np.arange(1, self.hsv.size + 1)
        ax.semilogy(k[: self.order], self.hsv[: self.order], "C0o", label="kept")
        ax.semilogy(k[self.order :], self.hsv[self.order :], "C0o", mfc="none", label="discarded")
        ax.set_xlabel("state")
        ax.set_ylabel("Hankel singular value")
        ax.legend()
        return fig

    def _repr_html_(self) -> str:
        return f"<p>{html.escape(self.summary())}</p>" + self.table()._repr_html_()

    def __reduce__(self):
        """Pickle the state space as matrices and names (python-control's StateSpace holds a lambda)."""
        return (_rebuild, (statespace_state(self.sys), self.hsv, self.bound, self.order))

    def __repr__(self) -> str:
        return f"BalancedTruncation(order {self.order} of {self.hsv.size}, bound {self.bound:.4g})"


def _rebuild(state: dict, hsv: np.ndarray, bound: float, order: int) -> BalancedTruncation:
    return BalancedTruncation(rebuild_statespace(state), hsv, bound, order)


def hammarling_factor(a: np.ndarray, b: np.ndarray, transpose: bool, dico: str = "C") -> np.ndarray | None:
    """Cholesky factor of a Gramian by Hammarling's method, SLICOT SB03OD (None when unavailable).

    ``dico="C"``: ``A X + X A^T = -B B^T`` (``transpose=False``, ``X = U U^T``) or
    ``A^T X + X A = -C^T C`` (``transpose=True``, ``b`` is C, ``X = U^T U``); ``dico="D"``: the
    discrete Stein equations ``A X A^T - X = -B B^T`` / ``A^T X A - X = -C^T C``. Returns None when
    slycot is missing or SB03OD fails (not stable, no convergence), so callers fall back to scipy.
    """
    try:
        from slycot import sb03od
    except ImportError:
        return None
    n = a.shape[0]
    try:
        if transpose:
            m = b.shape[0]
            bb = np.zeros((max(m, n), n))
            bb[:m] = b
            u, scale, _ = sb03od(n, m, a.copy(), np.zeros((n, n)), bb, dico, trans="N")
            return np.triu(u[:n, :n]).T / scale
        m = b.shape[1]
        bb = np.zeros((n, max(m, n)))
        bb[:, :m] = b
        u, scale, _ = sb03od(n, m, a.copy(), np.zeros((n, n)), bb, dico, trans="T")
        return np.triu(u[:n, :n]) / scale
    except Exception:  # slycot raises on non-convergence or a non-stable A: fall back to scipy
        return None


def _factor_scipy(a: np.ndarray, b: np.ndarray, transpose: bool) -> np.ndarray:
    if transpose:
        x = sla.solve_continuous_lyapunov(a.T, -b.T @ b)
    else:
        x = sla.solve_continuous_lyapunov(a, -b @ b.T)
    x = 0.5 * (x + x.T)
    lam, v = np.linalg.eigh(x)
    return v * np.sqrt(np.clip(lam, 0.0, None))


def gramian_factor(a: np.ndarray, b: np.ndarray, observability: bool = False) -> np.ndarray:
    """A factor ``L`` with ``L L^T`` = the controllability Gramian of ``(A, B)`` (or, with
    ``observability=True`` and ``b = C``, the observability Gramian of ``(A, C)``)."""
    lc = hammarling_factor(a, b, observability)
    if lc is None or not np.all(np.isfinite(lc)):
        lc = _factor_scipy(a, b, observability)
    return lc


def _as_ss(sys: Any):
    ss = as_statespace(sys)
    if ss.dt not in (0, None):
        raise ModelError("balanced_truncation handles continuous-time systems only (dt = 0).")
    if not all(np.all(np.isfinite(np.asarray(m, dtype=complex))) for m in (ss.A, ss.B, ss.C, ss.D)):
        raise ModelError(
            "the system's state-space matrices hold NaN or inf; balanced truncation needs a finite "
            "system (check the model that produced it)."
        )
    return ss


def _check(ss: Any, order: Any) -> int:
    n = ss.nstates
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)) or not 0 < order <= n:
        raise FitError(f"order must be an integer number of states in 1..{n}; got {order!r}.")
    eig = np.linalg.eigvals(ss.A) if n else np.zeros(0)
    if np.any(eig.real >= 0):
        raise ModelError(
            f"balanced truncation needs an asymptotically stable system; {np.sum(eig.real >= 0)} "
            "eigenvalue(s) have Re >= 0. Separate the unstable part first."
        )
    return int(order)


@limit_blas
def balanced_truncation(sys: Any, order: int) -> BalancedTruncation:
    """Reduce a stable system to ``order`` states by square-root balanced truncation.

    Parameters
    ----------
    sys : system
        Anything :func:`robustctl.as_statespace` accepts: a PhysicalModel, MeasurementModel,
        RationalFit, ``control.StateSpace`` or transfer function.
        Continuous-time, asymptotically stable (e.g. the Caltech 12-mode model, 24 states).
    order : int
        States to keep (2 per mode: 12 for six modes).

    Returns
    -------
    BalancedTruncation
        ``.sys``, ``.hsv`` (Hankel singular values, eq. 13's sigma) and ``.bound`` =
        ``2 sum_{i > order} sigma_i`` with ``||G - G_m||_inf <= bound``.
    """
    ss = _as_ss(sys)
    order = _check(ss, order)
    a, b, c, d = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    lc = gramian_factor(a, b)
    lo = gramian_factor(a, c, observability=True)
    u, hsv, vt = np.linalg.svd(lo.T @ lc)
    if hsv[order - 1] <= 1e-14 * hsv[0]:
        raise FitError(
            f"the system has only {np.count_nonzero(hsv > 1e-14 * hsv[0])} numerically significant "
            f"Hankel singular values; ask for at most that many states (got order={order})."
        )
    root = 1.0 / np.sqrt(hsv[:order])
    tl = root[:, None] * (u[:, :order].T @ lo.T)
    tr = (lc @ vt[:order].T) * root[None, :]
    reduced = control.ss(
        tl @ a @ tr,
        tl @ b,
        c @ tr,
        d,
        inputs=ss.input_labels,
        outputs=ss.output_labels,
    )
    return BalancedTruncation(reduced, hsv, float(2 * np.sum(hsv[order:])), order)
