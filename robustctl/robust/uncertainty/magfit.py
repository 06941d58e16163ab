"""Stable, minimum-phase rational fits to a magnitude curve (log-Chebyshev, convex form).

``fit_magnitude`` finds a real-rational ``W(s)`` of a given order whose magnitude
``|W(j 2 pi f)|`` fits a positive curve on a frequency grid in the log-Chebyshev sense,
``min max_k w_k |ln|W(j w_k)| - ln m_k|``, optionally with ``|W| >= m`` at every point (a
covering bound for an uncertainty weight). It is the tool of MATLAB's ``fitmagfrd``: the
D-scale fit of D-K iteration (Packard-Doyle, Automatica 29 (1993) sec. 9; Balas-Doyle
1989, the Caltech seed's ref. [5]) and the weight fit of ``ucover``.

The convex formulation (Boyd-Vandenberghe, *Convex Optimization*, sec. 6.5.5 and
example 4.7, "magnitude fitting by rational functions"):

1. The squared magnitude of a real-rational ``W`` is a ratio of polynomials in
   ``x = w^2``: ``|W(jw)|^2 = A(x) / B(x)`` with ``A, B >= 0`` for ``x >= 0``.
2. For a fixed tolerance ``t = exp(2 gamma)`` the fit conditions
   ``y_k / t <= A(x_k) / B(x_k) <= t y_k`` (``y = m^2``) are *linear* in the coefficients
   of ``A`` and ``B`` (``B > 0``); the problem is quasiconvex and solved by bisection on
   ``gamma``, each step a linear program (scipy's HiGHS). A strictly feasible point gives
   its own achieved error, which tightens the upper end of the bracket at once.
3. Spectral factorisation: ``A(-s^2)`` has its roots in pairs ``+-s``; the ones in the
   left half plane make the zeros of ``W`` (minimum phase), those of ``B(-s^2)`` its poles
   (stable). The gain is fixed from the fitted curve.

Numerics: the frequency is scaled to ``x = (w / w0)^2`` with ``w0`` the grid's geometric
centre, and ``A / D``, ``B / D`` (``D(x) = prod (x + p_j)``, ``p_j`` log-spaced over the
grid) are written in the partial-fraction basis ``{1, p_j / (x + p_j)}``: every basis
function lies in (0, 1], so orders up to ~10 over several decades stay well conditioned,
unlike monomials in ``x``. Roots come from the generalised eigenvalues of the
Rosenbrock pencil of that representation (no polynomial coefficients are formed), and
``W`` is realised as a cascade of first- and second-order sections.
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ...budget import Deadline, as_deadline
from ...checks import flag, integer, optional_text, positive_number, real_array
from ...errors import FitError
from ...lti import conjugate_pairs, freqresp_array, is_stable, zpk_response, zpk_statespace

__all__ = ["fit_magnitude", "MagnitudeFit", "fit_magnitude_details", "zpk_statespace"]

DB_PER_NEPER = 20.0 / np.log(10.0)

#: Largest order accepted (the partial-fraction basis stays sound well beyond; the LP does not need more).
MAX_ORDER = 20
#: Prices of the coefficients' L1 norm (relative to that of the unpriced solution) against the
#: slack in each LP (see :func:`_clarabel_lp`), tried in turn while the roots fail to reproduce
#: the LP's curve (an over-parametrised fit drifting into large cancelling coefficients).
L1_PRICES = (0.0, 1e-6, 1e-4, 1e-2)
#: Excursion (nepers, 10 dB) beyond tolerance and interpolation allowed between two grid points
#: before the midpoint joins the fit (a spike or notch the grid would miss).
MID_SLACK = 1.15
#: ``|W(inf)|`` is kept below this factor times the curve's largest value (a proper W).
HF_CAP = 10.0
#: A cover's (``upper_bound``) ``|W|`` is kept below this factor times the curve's largest value
#: at every grid and guard point (its peak gain; off these points it may overshoot a little).
PEAK_CAP = 3.0
#: Poles and zeros of a polished fit stay between ``w_min / ROOT_SPAN`` and ``w_max * ROOT_SPAN``.
ROOT_SPAN = 1e3


# ---------------------------------------------------------------------------- checks
def _check_order(order: Any) -> int:
    return integer(order, "order", FitError, lo=0, hi=MAX_ORDER)


#: Widest magnitude range a fit accepts (decades of max / min): its squared, normalised curve
#: must stay within floating point (the LP failed from about 150 decades on).
MAX_DECADES = 100.0


def _check_curve(f_hz: Any, mag: Any) -> tuple[np.ndarray, np.ndarray]:
    f = real_array(f_hz, "f_hz", FitError).reshape(-1)
    m = real_array(mag, "mag", FitError).reshape(-1)
    if f.size != m.size:
        raise FitError(f"f_hz has {f.size} points but mag has {m.size}; give one magnitude per frequency.")
    if f.size < 2:
        raise FitError(f"a magnitude fit needs at least 2 frequency points; got {f.size}.")
    if not np.all(np.isfinite(f)) or np.any(f <= 0):
        raise FitError("f_hz must be finite and positive (Hz); drop f = 0 and NaN points.")
    if np.any(np.diff(f) <= 0):
        k = int(np.flatnonzero(np.diff(f) <= 0)[0])
        raise FitError(
            f"f_hz must be strictly increasing; f_hz[{k}] = {f[k]:g} Hz is followed by {f[k + 1]:g} Hz "
            "(sort it and drop duplicates, e.g. np.unique)."
        )
    if not np.all(np.isfinite(m)) or np.any(m <= 0):
        k = int(np.flatnonzero(~(np.isfinite(m) & (m > 0)))[0])
        raise FitError(
            f"mag must be finite and positive (a log fit); mag[{k}] = {m[k]!r} at {f[k]:g} Hz. Floor a "
            "zero envelope at a small positive value, or drop the point."
        )
    decades = float(np.log10(m.max()) - np.log10(m.min()))
    if decades > MAX_DECADES:
        raise FitError(
            f"mag spans {decades:.3g} decades ({m.min():.3g} to {m.max():.3g}); a magnitude fit handles at "
            f"most {MAX_DECADES:g} ({20 * MAX_DECADES:g} dB), beyond which its squared curve overflows. "
            "Check the units of the curve, or floor it where it does not matter."
        )
    return f, m


def _check_point_weights(point_weights: Any, n: int) -> np.ndarray:
    if point_weights is None:
        return np.ones(n)
    w = real_array(point_weights, "point_weights", FitError).reshape(-1)
    if w.size != n:
        raise FitError(f"point_weights has {w.size} values for {n} frequency points; give one per point.")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or not np.any(w > 0):
        raise FitError("point_weights must be finite, >= 0 and not all zero (0 drops a point from the fit).")
    return w / w.max()


# ---------------------------------------------------------------------------- basis
@dataclass(frozen=True)
class _Basis:
    """The partial-fraction basis ``{1, p_j / (x + p_j)}``, ``j = 1..n``, in scaled
    ``x = (w / w0)^2``: ``A(x) / D(x)`` with ``deg A <= n``, ``D = prod (x + p_j)``. Every
    basis function lies in (0, 1]; at ``x = inf`` the row is ``[1, 0, ...]`` (``A``'s leading
    coefficient)."""

    w0: float
    p: np.ndarray
    x_max: float

    def matrix(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            phi = np.where(np.isinf(x), 0.0, self.p / (x + self.p))
        return np.hstack([np.ones((x.shape[0], 1)), phi])

    def roots(self, c: np.ndarray) -> np.ndarray:
        """Finite roots in ``x`` of ``c0 + sum c_j p_j / (x + p_j)``.

        With ``c0`` not negligible they are the eigenvalues of ``-diag(p) - 1 (c_j p_j)' / c0``
        (its characteristic polynomial is ``prod (x + p_j)`` times the function over ``c0``), a
        standard problem that LAPACK balances: on a D-scale of the Caltech design plant whose
        ``B`` nearly touches zero (coefficients +-26 summing to 1e-7 on the grid) the
        generalised eigenvalues of the Rosenbrock pencil came out as two real roots where
        ``B`` is positive (residual 3e-6 against 4e-15 for these), and rounding of the data
        moved the realised fit by 20 %. Otherwise (the numerator's degree drops) the pencil."""
        n = self.p.size
        if abs(c[0]) > 1e-10 * float(np.abs(c).max()):
            lam = np.linalg.eigvals(-np.diag(self.p) - np.outer(np.ones(n), c[1:] * self.p) / c[0])
            return lam[np.isfinite(lam) & (np.abs(lam) < 1e8 * self.x_max)]
        M = np.zeros((n + 1, n + 1))
        M[:n, :n] = np.diag(-self.p)
        M[:n, n] = 1.0
        M[n, :n] = -c[1:] * self.p
        M[n, n] = -c[0]
        E = np.zeros_like(M)
        E[:n, :n] = np.eye(n)
        from scipy.linalg import eig

        lam = eig(M, E, right=False)
        # beyond 1e4 x the grid's top frequency a root acts as one at infinity
        return lam[np.isfinite(lam) & (np.abs(lam) < 1e8 * self.x_max)]


def _basis(w: np.ndarray, order: int, mag: np.ndarray | None = None) -> tuple[_Basis, np.ndarray]:
    """The start basis: poles log-spaced over the grid, or (given ``mag``) over the part of it
    where the curve changes (:func:`_active_range`)."""
    w0 = float(np.sqrt(w[0] * w[-1]))
    x = (w / w0) ** 2
    lo, hi = (x[0], x[-1]) if mag is None else _active_range(x, mag)
    if hi / lo < 1e2:  # a narrow range: spread the poles anyway
        c = np.sqrt(lo * hi)
        lo, hi = min(lo, c / 10), max(hi, c * 10)
    p = np.geomspace(lo, hi, order) if order > 1 else np.array([np.sqrt(lo * hi)])
    return _Basis(w0, p, float(x[-1])), x


#: A curve's end counts as flat while it stays within this fraction of its log range of the
#: end value (:func:`_active_range`).
FLAT_FRACTION = 0.02


def _active_range(x: np.ndarray, mag: np.ndarray) -> tuple[float, float]:
    """The ``x`` range between the curve's flat ends (points within ``FLAT_FRACTION`` of its
    log range of the end value; NaN points are ignored).

    Basis poles in a flat end are wasted, and worse: on a grid of many decades (a D-scale of
    the distillation example with the weight pole at 1e-5 rad/s, over 1e-6 .. 60 rad/s and
    flat below 1e-3 rad/s) poles log-spaced over the whole grid lay so far from the fit's own
    that ``A / D`` spanned ten decades on the grid, beyond the LP's accuracy: order 3 stopped
    at 3.5 dB where 0.96 dB exists (1.59 dB now), order 5 at 1.60 dB (0.52 dB now).
    """
    ok = np.flatnonzero(np.isfinite(mag) & (mag > 0))
    if ok.size < 2:
        return float(x[0]), float(x[-1])
    lm = np.log(mag[ok])
    band = FLAT_FRACTION * float(np.ptp(lm))
    moving_lo = np.flatnonzero(np.abs(lm - lm[0]) > band)
    moving_hi = np.flatnonzero(np.abs(lm - lm[-1]) > band)
    if band <= 0 or moving_lo.size == 0 or moving_hi.size == 0:
        return float(x[0]), float(x[-1])
    k0, k1 = ok[max(int(moving_lo[0]) - 1, 0)], ok[min(int(moving_hi[-1]) + 1, ok.size - 1)]
    return (float(x[k0]), float(x[k1])) if k1 > k0 else (float(x[0]), float(x[-1]))


def _midpoints(basis: _Basis, x: np.ndarray, y: np.ndarray, wt: np.ndarray) -> dict[str, np.ndarray]:
    """Geometric midpoints of the fitted grid with log-interpolated targets (cut candidates)."""
    xm = np.sqrt(x[:-1] * x[1:])
    slack = 0.25 * np.abs(np.diff(np.log(y))) + MID_SLACK
    return dict(
        mid_phi=basis.matrix(xm),
        mid_y=np.sqrt(y[:-1] * y[1:]),
        mid_wt=np.minimum(wt[:-1], wt[1:]),
        mid_slack=slack,
    )


def _dense_points(x: np.ndarray, per: int = 8) -> np.ndarray:
    """``per - 1`` log-spaced points inside each grid interval, and 3 decades of ``w`` beyond
    each end: where a cover's resonant peak between the grid points is looked for."""
    t = np.arange(1, per)[None, :] / per
    inner = (x[:-1, None] * (x[1:, None] / x[:-1, None]) ** t).ravel()
    lo, hi = np.log10(x[0]), np.log10(x[-1])
    return np.concatenate([inner, np.logspace(lo - 6, lo, 60), np.logspace(hi, hi + 6, 60)])


def _peak_violations(prob: _Problem, a: np.ndarray, b: np.ndarray, limit: int = 20) -> bool:
    """For a cover, move the dense points where ``|W|^2 = A / B`` exceeds the peak cap (a
    resonance between grid points) into the LP's cap rows (cutting planes); True if any moved."""
    if not prob.upper_bound or prob.dense.shape[0] == 0:
        return False
    A, B = prob.dense @ a, prob.dense @ b
    scale = max(float(np.abs(prob.dense @ b).max()), 1e-300)
    over = (A - prob.y_peak * (1 + 1e-3) * B) / (prob.y_peak * scale)
    viol = np.flatnonzero(over > 1e-9)
    if viol.size == 0:
        return False
    take = viol[np.argsort(-over[viol])[:limit]]
    rows = prob.dense[take]
    prob.peak = rows if prob.peak is None else np.vstack([prob.peak, rows])
    prob.dense = np.delete(prob.dense, take, axis=0)
    return True


def _guard_points(x: np.ndarray) -> np.ndarray:
    """Where A and B must be non-negative besides the grid: 0, infinity, between and beyond."""
    mid = np.sqrt(x[:-1] * x[1:])
    lo, hi = np.log10(x[0]), np.log10(x[-1])
    ext = np.concatenate([np.logspace(lo - 6, lo, 25), np.logspace(hi, hi + 6, 25)])
    return np.concatenate([[0.0, np.inf], mid, ext])


# ---------------------------------------------------------------------------- LP
@dataclass
class _Problem:
    phi: np.ndarray  # basis on the fitted points (m, n+1)
    y: np.ndarray  # squared target magnitudes, normalised (m,)
    wt: np.ndarray  # point weights in (0, 1] (m,)
    guard: np.ndarray  # basis on the guard points in the LP (g, n+1)
    guard_all: np.ndarray  # basis on every guard point (checked after each LP)
    upper_bound: bool
    y_inf: float  # cap of |W(inf)|^2 relative to t (properness)
    y_peak: float  # cap of a cover's |W|^2 at the points, the guard points and the ``peak`` points
    dense: np.ndarray  # basis between the grid points and beyond (where a cover's peak is checked)
    mid_phi: np.ndarray  # basis at the geometric midpoints of the grid (candidate cuts)
    mid_y: np.ndarray  # interpolated squared targets there
    mid_wt: np.ndarray
    mid_slack: np.ndarray  # allowed excursion beyond the tolerance there (nepers)
    price: float = 0.0  # L1 price of the coefficients, per unit of ``zscale``
    zscale: float = 1.0  # L1 norm of the unpriced solution's coefficients
    b_ref: np.ndarray | None = None  # B of the last feasible point (scales the slack)
    guard_used: np.ndarray = field(
        default_factory=lambda: np.zeros(0, dtype=int)
    )  # rows of guard_all in the LP
    peak: np.ndarray | None = None  # rows of ``dense`` where a cover's peak cap joined the LP


def _cut_midpoints(prob: _Problem, a: np.ndarray, b: np.ndarray, gamma: float, limit: int = 20) -> bool:
    """Move grid midpoints where the fit overshoots the tolerance (a spike or notch between
    points; for an upper bound, any dip below the log-interpolated bound) into the fitted
    points (cutting planes); True if any moved."""
    if prob.mid_y.size == 0:
        return False
    A, B = prob.mid_phi @ a, prob.mid_phi @ b
    pos = (A > 0) & (B > 0)  # signs are the guards' business (solver noise near zero)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(pos, 0.5 * (np.log(np.where(pos, A / B, 1.0)) - np.log(prob.mid_y)), 0.0)
    # the log interpolation is itself uncertain by about half the step between the two
    # neighbours (a sharp peak between them): only larger excursions are cut
    over = np.abs(e) * prob.mid_wt - gamma - prob.mid_slack
    if prob.upper_bound:  # a spike above the tolerance, or a notch below the interpolated bound
        over = np.where(e < 0, -e - prob.mid_slack, over)
    viol = np.flatnonzero(over > 1e-6 + 1e-3 * gamma)
    if viol.size == 0:
        return False
    take = viol[np.argsort(-over[viol])[:limit]]
    prob.phi = np.vstack([prob.phi, prob.mid_phi[take]])
    prob.y = np.concatenate([prob.y, prob.mid_y[take]])
    prob.wt = np.concatenate([prob.wt, prob.mid_wt[take]])
    keep = np.setdiff1d(np.arange(prob.mid_y.size), take)
    prob.mid_phi, prob.mid_y, prob.mid_wt = prob.mid_phi[keep], prob.mid_y[keep], prob.mid_wt[keep]
    prob.mid_slack = prob.mid_slack[keep]
    return True


def _lp_rows(prob: _Problem, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """Inequality rows ``G z <= 0`` and the equality row of the LP in ``z = [a, b, s]``."""
    phi, y, n1 = prob.phi, prob.y, prob.phi.shape[1]
    t = np.exp(2.0 * gamma / prob.wt)
    ys = y[:, None]
    # the slack is measured relative to B of the last feasible point (B may span decades)
    if prob.b_ref is None:
        bref = np.ones(y.size)
    else:
        bref = np.abs(phi @ prob.b_ref)
        bref = np.maximum(bref, 1e-9 * bref.max()) / bref.mean()
    # A - t y B + s t y Bref <= 0, i.e. A / (y B) <= t (1 - s Bref / B)
    up = np.hstack([phi, -(t * y)[:, None] * phi, (t * y * bref)[:, None]])
    if prob.upper_bound:
        lo = np.hstack([-phi, ys * phi, np.zeros((y.size, 1))])  # y B - A <= 0
    else:  # y B / t - A + s y Bref / t <= 0, i.e. A / (y B) >= (1 + s Bref / B) / t
        lo = np.hstack([-phi, (y / t)[:, None] * phi, (y / t * bref)[:, None]])
    g = prob.guard
    zg, z1 = np.zeros_like(g), np.zeros((g.shape[0], 1))
    guard = np.vstack([np.hstack([-g, zg, z1]), np.hstack([zg, -g, z1])])
    proper = np.zeros((1, 2 * n1 + 1))  # |W(inf)|^2 = lead A / lead B <= cap (a proper W)
    inf_row = prob.guard_all[1]  # the basis read at x = inf
    proper[0, :n1], proper[0, n1 : 2 * n1] = inf_row, -prob.y_inf * float(np.max(t)) * inf_row
    rows = [up, lo, guard, proper]
    if prob.upper_bound:  # a cover's peak: |W|^2 <= y_inf on the points and every guard point
        pts = np.vstack([phi, prob.guard_all] + ([] if prob.peak is None else [prob.peak]))
        rows.append(np.hstack([pts, -prob.y_peak * pts, np.zeros((pts.shape[0], 1))]))
    G = np.vstack(rows)
    G /= np.maximum(np.abs(G).max(axis=1, keepdims=True), 1e-300)
    eq = np.zeros(2 * n1 + 1)
    eq[n1 : 2 * n1] = phi.mean(axis=0)
    return G, eq


def _clarabel_lp(c: np.ndarray, G: np.ndarray, eq: np.ndarray, price: float) -> np.ndarray | None:
    """``min c z + price |z[:-1]|_1 / n`` s.t. ``G z <= 0``, ``eq z = 1``, ``z[-1] <= 1`` (Clarabel).

    An L1 price on the coefficients (when the unpriced fit's roots fail) keeps an
    over-parametrised fit (an order above the curve's) from drifting into large cancelling
    coefficients, whose roots would be inaccurate. Returns None unless solved.
    """
    import clarabel
    import scipy.sparse as sp

    nz = G.shape[1]
    nc = nz - 1
    I = np.eye(nc)
    rows = [
        np.hstack([eq[None], np.zeros((1, nc))]),
        np.hstack([G, np.zeros((G.shape[0], nc))]),
        np.hstack([np.zeros((1, nc)), [[1.0]], np.zeros((1, nc))]),
        np.hstack([I, np.zeros((nc, 1)), -I]),
        np.hstack([-I, np.zeros((nc, 1)), -I]),
    ]
    A = sp.csc_matrix(np.vstack(rows))
    rhs = np.concatenate([[1.0], np.zeros(G.shape[0]), [1.0], np.zeros(2 * nc)])
    q = np.concatenate([c, np.full(nc, price / nc)])
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_iter = 100
    cones = [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(G.shape[0] + 1 + 2 * nc)]
    sol = clarabel.DefaultSolver(sp.csc_matrix((nz + nc, nz + nc)), q, A, rhs, cones, settings).solve()
    status = str(sol.status)
    if status in ("Solved", "AlmostSolved"):
        return np.asarray(sol.x)[:nz]
    if "Infeasible" in status:
        return None
    # numerical trouble (thin feasible set): HiGHS's simplex on the same LP
    from scipy.optimize import linprog

    res = linprog(
        q,
        A_ub=A[1:].toarray(),
        b_ub=rhs[1:],
        A_eq=A[:1].toarray(),
        b_eq=rhs[:1],
        bounds=[(None, None)] * (nz + nc),
        method="highs",
    )
    return res.x[:nz] if res.status == 0 else None


def _solve_lp(prob: _Problem, gamma: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The (a, b) of largest slack for the tolerance ``gamma`` (nepers), or None.

    Variables ``[a, b, s]``; maximise the slack ``s`` (capped at 1) of
    ``A <= t_k y_k (B - s)``, ``A >= y_k (B + s) / t_k`` (or ``A >= y_k B`` for an upper
    bound), where ``t_k = exp(2 gamma / w_k)``; normalisation ``mean(B / D) = 1``. The slack
    is relative to ``B`` (of the last feasible point), so a positive one means a strictly
    smaller error; the caller judges feasibility by the solution's own error, which is
    robust to the solver's tolerance when the feasible set is thin. Clarabel's
    interior point gives a well-centred solution.
    """
    G, eq = _lp_rows(prob, gamma)
    n1 = (G.shape[1] - 1) // 2
    c = np.zeros(G.shape[1])
    c[-1] = -1.0
    z = _clarabel_lp(c, G, eq, prob.price / prob.zscale)
    return None if z is None else (z[:n1], z[n1 : 2 * n1])


def _mean_overbound(prob: _Problem, a: np.ndarray, b: np.ndarray) -> float:
    """Weighted mean of ``ln(|W| / mag)`` after the gain shift that covers every point."""
    A, B = prob.phi @ a, prob.phi @ b
    if np.any(A <= 0) or np.any(B <= 0):
        return np.inf
    e = 0.5 * (np.log(A / B) - np.log(prob.y))
    return float(np.sum((e - e.min()) * prob.wt) / np.sum(prob.wt))


def _tighten(prob: _Problem, a: np.ndarray, b: np.ndarray, cap: float, deadline: Deadline, n_iter: int = 6):
    """From a covering fit, lower the mean log overbound (Sanathanan-Koerner-like steps).

    Each LP minimises ``sum w_k A_k / A_prev_k`` (the linearised ``sum w_k ln A_k``) subject
    to ``A_k >= y_k B_k``, ``sum B_k / B_prev_k = n`` (the linearised fixed ``sum ln B_k``),
    the guards and ``A_k <= t y_k B_k`` with the overbound ``cap`` (nepers; at the minimax
    optimum this only breaks its ties, larger it trades the worst point for the typical
    one). Grid midpoints that spike above the cap join the points. The best iterate by
    the mean criterion is kept.
    """
    best, best_val, n_lp, it = (a, b), _mean_overbound(prob, a, b), 0, 0
    while it < n_iter and n_lp < 4 * n_iter and not deadline.expired():
        phi, n1 = prob.phi, prob.phi.shape[1]
        A_prev, B_prev = np.maximum(phi @ best[0], 1e-300), np.maximum(phi @ best[1], 1e-300)
        G, _ = _lp_rows(prob, cap)
        G = np.hstack([G[:, :-1], np.zeros((G.shape[0], 1))])  # no slack variable
        c = np.concatenate([(prob.wt / A_prev) @ phi, np.zeros(n1), [0.0]])
        eq = np.concatenate([np.zeros(n1), (1.0 / B_prev) @ phi / phi.shape[0], [0.0]])
        z = _clarabel_lp(c / np.abs(c).max(), G, eq, prob.price / prob.zscale)
        n_lp += 1
        if z is None:
            break
        sol = z[:n1], z[n1 : 2 * n1]
        if _guard_violations(prob, *sol) or _peak_violations(prob, *sol):
            continue
        if _cut_midpoints(prob, *sol, cap):
            continue
        it += 1
        val = _mean_overbound(prob, *sol)
        if not val < best_val - 1e-6:
            break
        best, best_val = sol, val
    return best[0], best[1], n_lp


def _achieved(prob: _Problem, a: np.ndarray, b: np.ndarray) -> float:
    """Weighted max log-magnitude error (nepers) of ``sqrt(A / B)`` on the fitted points
    (for an upper bound: after the gain shift that restores ``|W| >= mag``)."""
    A, B = prob.phi @ a, prob.phi @ b
    if np.any(A <= 0) or np.any(B <= 0):
        return np.inf
    e = 0.5 * (np.log(A / B) - np.log(prob.y))
    if prob.upper_bound:
        return float(np.max((e - min(float(e.min()), 0.0)) * prob.wt))
    return float(np.max(np.abs(e) * prob.wt))


def _guard_violations(prob: _Problem, a: np.ndarray, b: np.ndarray) -> bool:
    """Add to the LP the guard points (not yet in it) where ``A`` or ``B`` is negative beyond
    the solver's accuracy; True if any was added."""
    g = prob.guard_all
    A, B = g @ a, g @ b
    tol_a, tol_b = 1e-8 * np.abs(A).max(), 1e-8 * np.abs(B).max()
    bad = np.flatnonzero((-tol_a > A) | (-tol_b > B))
    bad = np.setdiff1d(bad, prob.guard_used)
    if bad.size == 0:
        return False
    prob.guard = np.vstack([prob.guard, g[bad]])
    prob.guard_used = np.union1d(prob.guard_used, bad)
    return True


def _minimise(
    prob: _Problem, hi: float, tol: float, deadline: Deadline, levels_only: bool = False
) -> tuple[np.ndarray, np.ndarray, int, float]:
    """Bisection on the tolerance (Boyd-Vandenberghe sec. 4.2.5, quasiconvex problems).

    The LP maximises a slack relative to ``B``, so a feasible point's own error is below the
    tolerance tried and becomes the new upper end of the bracket at once (unless
    ``levels_only``: then the bracket's ends are levels tried, so that they depend on the data
    only through which LPs were feasible, not through the solutions' rounding). Non-negativity
    of ``A`` and ``B`` off the grid is imposed lazily: guard points a solution violates join
    the LP and the step is repeated (cutting planes). Returns the best solution, the LPs
    solved and the bracket's upper end (a level with a feasible solution).
    """
    lo, best, n_lp = 0.0, None, 0
    while n_lp < 80:
        gamma = hi if best is None else 0.5 * (lo + hi)
        sol = _solve_lp(prob, gamma)
        n_lp += 1
        err = np.inf if sol is None else _achieved(prob, *sol)
        if err <= gamma + 1e-7:
            cut = _guard_violations(prob, *sol) or _cut_midpoints(prob, *sol, gamma)
            if cut or _peak_violations(prob, *sol):
                continue
            best, hi = sol, (gamma if levels_only else min(err, gamma))
            prob.b_ref = sol[1]
        elif best is None:
            hi *= 2.0  # not expected: a constant is feasible at the start
            if hi > 1e3:
                raise FitError("the magnitude fit found no feasible point; the curve may be degenerate.")
            continue
        else:
            lo = gamma
        if hi - lo <= tol or deadline.expired():
            break
    if best is None:
        raise FitError("the magnitude fit found no feasible point within its budget; raise time_budget_s.")
    return best[0], best[1], n_lp, hi


#: The least-squares choice among the fits (:func:`_least_squares_fit`) works at the bisection's
#: last feasible level plus this fraction of its tolerance (an interior for the barrier).
SELECT_MARGIN = 0.1
#: Ridge on the coefficients in that choice (relative to the mean diagonal of the squared
#: error's matrix): large cancelling coefficients put ``A``'s and ``B``'s roots at the mercy of
#: rounding.
SELECT_RIDGE = 1e-6
#: Weights ``tau`` of the barrier against the squared error on the way to the least-squares
#: fit (the last one is where it stops: a fixed, interior point).
SELECT_TAUS = (1.0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5)


def _least_squares_fit(data: _CentreData, gamma: float, a0: np.ndarray, b0: np.ndarray,
                       y_target: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """Among the fits within ``gamma`` (nepers), the one of least squared linearised error
    (kept off the set's boundary by a weak barrier): a unique choice, smooth in the data.

    Near the optimal level the max error is set by a few points (a notch or a step of a
    D-scale), the other coefficients are free within a set, and the LP's interior-point solution
    at the bisection's last level is a point of that set fixed only to the solver's accuracy: a
    1e-12 relative change of a D-scale moved its order-3 fit 1e-5 and an order-4 fit 1.5e-3 on
    the Caltech design plant (issue 36). Here, from the analytic centre of the set
    (:func:`_centre`), the barrier's weight falls over :data:`SELECT_TAUS` towards the minimiser of
    ``sum_k ((A_k - y_k B_k) / y_k)^2`` (scaled by its value at the centre) subject to the fit's
    constraints at ``gamma`` (:func:`_centre_rows`: points, midpoints, guard points, the cap at
    infinity) and ``mean B = 1``. Each stage is strictly convex and solved by Newton's method to
    rounding (:func:`_barrier_newton`), so the result is a smooth function of the data. Returns
    None when a stage fails (the caller keeps the LP's fit). ``y_target``: the squared targets
    of the squared error when they are not the band's centres ``data.y`` (a cover: its lower
    edge, :func:`_centre_data`).
    """
    n1 = data.phi.shape[1]
    G = _centre_rows(data, gamma)
    eq = np.concatenate([np.zeros(n1), data.phi.mean(axis=0)])
    ab = _centre(data, gamma, a0, b0)
    if ab is None:  # no strictly feasible start on the way to the constant fit: a phase-I LP
        Gs = np.hstack([G, np.ones((G.shape[0], 1))])  # G z + s <= 0 (rows of unit largest entry)
        c = np.zeros(2 * n1 + 1)
        c[-1] = -1.0
        z = _clarabel_lp(c, Gs, np.append(eq, 0.0), 0.0)
        if z is None or not z[-1] > 0:
            return None
        z = _barrier_newton(G, eq, z[:-1] / float(eq @ z[:-1]), None)
        if z is None:
            return None
        ab = z[:n1], z[n1:]
    y = data.y if y_target is None else y_target
    M = np.hstack([data.phi, -y[:, None] * data.phi]) / y[:, None]
    P = M.T @ M
    P += SELECT_RIDGE * float(np.trace(P)) / P.shape[0] * np.eye(P.shape[0])
    z = np.concatenate(ab)
    f0 = 0.5 * float(z @ P @ z)
    if not f0 > 0:
        return ab
    for tau in SELECT_TAUS:
        z = _barrier_newton(G, eq, z, P / (tau * f0))
        if z is None:
            return None
    return z[:n1], z[n1:]

#: Newton steps of the analytic centre (:func:`_centre`): a cap; self-concordance makes it
#: converge in ~10-30 steps from the bisection's solution.
CENTRE_MAX_NEWTON = 100
#: Squared Newton decrement that ends the centring (two full steps follow it, so the
#: returned point does not depend on where the test was passed).
CENTRE_DECREMENT = 1e-10


@dataclass(frozen=True)
class _CentreData:
    """The fit's constraints independent of the bisection's path: every point, midpoint and
    guard point (the LPs add midpoints and guard points lazily, in an order rounding decides)."""

    phi: np.ndarray  # basis on the fitted points
    y: np.ndarray  # squared targets there (normalised)
    wt: np.ndarray  # point weights
    mid_phi: np.ndarray  # basis at the grid's midpoints
    mid_y: np.ndarray
    mid_wt: np.ndarray
    mid_slack: np.ndarray  # allowed excursion there beyond the level (nepers)
    guard: np.ndarray  # basis on every guard point (A, B >= 0 there)
    y_inf: float  # cap of |W(inf)|^2 relative to the largest t
    peak: np.ndarray | None = None  # a cover's peak cap: basis where A <= y_peak B
    y_peak: float = 0.0


def _centre_data(prob: _Problem, cap: float | None = None) -> _CentreData:
    """The constraints of ``prob`` as its points stand (taken before its LPs add any, so that they
    do not depend on their path): every point, midpoint and guard point and the cap at infinity.

    ``cap`` None: a log-Chebyshev fit's band about ``y``. ``cap`` (nepers): a cover's at overbound
    ``cap``, as a band of half-width ``cap / 2`` about ``y e^(cap / wt)``: ``y <= A / B <= y
    e^(2 cap / wt)`` at the points, no dip below the log-interpolated bound beyond its slack at
    the midpoints (:func:`_cut_midpoints`), ``A, B >= 0`` at every guard point, and the peak cap
    ``A <= y_peak B`` at the points, every guard point and every dense point."""
    if cap is None:
        return _CentreData(phi=prob.phi, y=prob.y, wt=prob.wt, mid_phi=prob.mid_phi, mid_y=prob.mid_y,
                           mid_wt=prob.mid_wt, mid_slack=prob.mid_slack, guard=prob.guard_all,
                           y_inf=prob.y_inf)
    shift = np.exp(cap / prob.wt)
    mid_shift = np.exp(cap / prob.mid_wt) if prob.mid_y.size else np.ones(0)
    return _CentreData(
        phi=prob.phi, y=prob.y * shift, wt=prob.wt, mid_phi=prob.mid_phi, mid_y=prob.mid_y * mid_shift,
        mid_wt=prob.mid_wt, mid_slack=prob.mid_slack * prob.mid_wt, guard=prob.guard_all, y_inf=prob.y_inf,
        peak=np.vstack([prob.phi, prob.guard_all, prob.dense]), y_peak=prob.y_peak)


def _centre_rows(data: _CentreData, gamma: float) -> np.ndarray:
    """Rows ``G`` of ``G [a; b] <= 0``: the fit within ``gamma`` (nepers, per point over its weight)
    at the points, within ``gamma`` plus their slack at the midpoints, ``A, B >= 0`` at the guard
    points and ``|W(inf)|^2`` capped; each row scaled to unit largest entry."""
    rows = []
    t_max = 1.0
    for phi, y, wt, extra in ((data.phi, data.y, data.wt, 0.0),
                              (data.mid_phi, data.mid_y, data.mid_wt, data.mid_slack)):
        if y.size == 0:
            continue
        t = np.exp(2.0 * (gamma + extra) / wt)
        t_max = max(t_max, float(np.max(t)))
        rows.append(np.hstack([phi, -(t * y)[:, None] * phi]))  # A <= t y B
        rows.append(np.hstack([-phi, (y / t)[:, None] * phi]))  # A >= y B / t
    g, zg = data.guard, np.zeros_like(data.guard)
    rows += [np.hstack([-g, zg]), np.hstack([zg, -g])]
    inf_row = data.guard[1]  # the basis at x = inf
    rows.append(np.concatenate([inf_row, -data.y_inf * t_max * inf_row])[None])
    if data.peak is not None:
        rows.append(np.hstack([data.peak, -data.y_peak * data.peak]))
    G = np.vstack(rows)
    return G / np.maximum(np.abs(G).max(axis=1, keepdims=True), 1e-300)


def _centre(data: _CentreData, gamma: float, a0: np.ndarray,
            b0: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The analytic centre of the fits within ``gamma``: ``max sum ln s_i`` over the slacks
    ``s = -G z`` of :func:`_centre_rows`, normalised to ``mean B = 1`` on the points.

    The set is bounded (``A / B`` is pinned within a band at more points than coefficients,
    ``B >= 0`` with a fixed mean), so the centre is unique; it is a smooth function of the data
    while the set has an interior, and rounding of the data moves it in proportion (unlike a
    vertex of the LP at the bisection's last level, which rounding fixes only to the solver's
    accuracy when that level is close to the optimum). Newton's method with the damped steps of
    self-concordant barriers (Boyd-Vandenberghe sec. 9.6 and 10.2) from a strictly feasible
    start: ``(a0, b0)`` (feasible within the solver's accuracy) moved towards the best
    constant fit until every slack is positive. Returns None when no such start is found or
    the Newton steps stall (the caller keeps the LP's solution).
    """
    G = _centre_rows(data, gamma)
    n1 = data.phi.shape[1]
    eq = np.concatenate([np.zeros(n1), data.phi.mean(axis=0)])
    z1 = np.concatenate([a0, b0])
    zc = np.zeros(2 * n1)  # the constant fit at the log-centre of the targets (positive everywhere)
    zc[0], zc[n1] = float(np.sqrt(data.y.max() * data.y.min())), 1.0
    s1, sc = -G @ z1, -G @ zc
    # slacks on the segment z1 + lam (zc - z1) are linear in lam: the interval where all are positive
    lo_lam, hi_lam = 0.0, 1.0
    up = sc - s1
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(up > 0, -s1 / up, -np.inf)  # lam > need where s1 <= 0 < sc
        allow = np.where(up < 0, -s1 / up, np.inf)  # lam < allow where s1 > 0 > sc
    lo_lam = max(lo_lam, float(np.max(need[s1 <= 0], initial=0.0)))
    hi_lam = min(hi_lam, float(np.min(allow[s1 > 0], initial=1.0)))
    if not lo_lam < hi_lam:
        return None
    lam = 0.5 * (lo_lam + hi_lam) if lo_lam > 0 else min(0.5 * hi_lam, 1e-3)
    z = z1 + lam * (zc - z1)
    z = z / float(eq @ z)
    s = -G @ z
    if not np.all(s > 0):
        return None
    z = _barrier_newton(G, eq, z, None)
    return None if z is None else (z[:n1], z[n1:])


def _barrier_newton(G: np.ndarray, eq: np.ndarray, z: np.ndarray, Q: np.ndarray | None) -> np.ndarray | None:
    """Minimise ``z' Q z / 2 - sum ln s_i`` (``s = -G z``) subject to ``eq z = 1`` from a strictly
    feasible ``z`` by Newton's method (equality-constrained); ``Q`` None: the analytic centre.

    The function is self-concordant: backtracking (from the full step, or 0.99 of the way to
    the boundary) while the Newton decrement ``lambda^2`` is at least 1/16, then full steps,
    which converge quadratically (Boyd-Vandenberghe sec. 9.5-9.6): no comparison of function
    values near the minimum, where rounding would decide it.
    The minimiser is unique (strictly convex on a bounded set); the steps go on until the
    decrement is at rounding level (below :data:`CENTRE_DECREMENT`, or no longer falling), plus two
    full steps, so the result does not depend on where the test was passed. None when a step
    fails or :data:`CENTRE_MAX_NEWTON` steps do not converge.
    """
    n = z.size
    K = np.zeros((n + 1, n + 1))
    K[-1, :-1] = K[:-1, -1] = eq
    s = -G @ z

    def value(zz: np.ndarray, ss: np.ndarray) -> float:
        if not np.all(ss > 0):
            return np.inf
        return -float(np.sum(np.log(ss))) + (0.0 if Q is None else 0.5 * float(zz @ Q @ zz))

    extra, last = 0, np.inf
    for _ in range(CENTRE_MAX_NEWTON):
        g = G.T @ (1.0 / s)
        Gs = G / s[:, None]
        K[:-1, :-1] = Gs.T @ Gs
        if Q is not None:
            g = g + Q @ z
            K[:-1, :-1] += Q
        d = np.sqrt(np.maximum(np.diag(K[:-1, :-1]), 1e-300))  # Jacobi scaling of the KKT system
        D = np.append(1.0 / d, 1.0)
        try:
            sol = D * np.linalg.solve(D[:, None] * K * D[None, :], -D * np.append(g, 0.0))
        except np.linalg.LinAlgError:
            return None
        dz = sol[:-1]
        dec = float(-g @ dz)
        if not np.isfinite(dec):
            return None
        done = extra > 0 or dec < CENTRE_DECREMENT or (last < 1e-6 and dec > 0.25 * last)
        ds = -G @ dz
        if dec < 1.0 / 16.0:  # the quadratic phase: full steps
            step = 1.0
        else:  # backtracking from the full step (or 0.99 of the way to the boundary)
            with np.errstate(divide="ignore"):
                step = min(1.0, 0.99 * float(np.min(np.where(ds < 0, -s / ds, np.inf))))
            f0 = value(z, s)
            while value(z + step * dz, s + step * ds) > f0 - 0.25 * step * dec:
                step *= 0.5
                if step < 1e-12:
                    return None
        s_new = -G @ (z + step * dz)
        if not np.all(s_new > 0):
            return None
        z, s, last = z + step * dz, s_new, dec
        if done:
            extra += 1
            if extra >= 2:
                return z
    return None


# ---------------------------------------------------------------------------- realisation
def _lhp(x_roots: np.ndarray, w0: float) -> np.ndarray:
    """Left-half-plane ``s`` with ``s^2 = -w0^2 x`` for each root ``x`` of ``A`` (or ``B``).

    Roots on the positive real ``x`` axis (``A`` touching zero at ``w = w0 sqrt(x)``: a
    ``j w`` axis root of even multiplicity) are paired, sorted, into conjugate ``s`` roots
    nudged just into the left half plane; an unpaired one becomes a real root of that size.
    """
    x = np.asarray(x_roots, dtype=complex)
    axis = (x.real > 0) & (np.abs(x.imag) <= 1e-6 * np.abs(x))
    s = -w0 * np.sqrt(-x[~axis])
    floor = 1e-9 * w0 + 1e-9 * np.abs(s)
    s = np.where(s.real > -floor, -floor + 1j * s.imag, s)
    on = np.sort(x[axis].real)
    mag = w0 * np.sqrt(on)
    pairs = []
    for k in range(0, on.size - 1, 2):
        wk = 0.5 * (mag[k] + mag[k + 1])
        pairs += [-1e-9 * (w0 + wk) + 1j * wk, -1e-9 * (w0 + wk) - 1j * wk]
    if on.size % 2:
        pairs.append(-mag[-1] + 0j)
    return np.concatenate([s, np.array(pairs, dtype=complex)])


def _damping_floor(roots: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Roots no more lightly damped than the grid resolves: ``zeta >= dw / (4 w)`` (the local
    relative spacing of the grid over 4, at most 0.05).

    A pole or zero narrower than the grid spacing is invisible to the fit (A or B touching
    zero between two points): it would only put a needless near-``j w``-axis root into
    ``W`` or ``W^-1``. Its frequency ``|s|`` is kept.
    """
    if roots.size == 0 or w.size < 2:
        return roots
    mag = np.abs(roots)
    k = np.clip(np.searchsorted(w, mag), 1, w.size - 1)
    rel = (w[k] - w[k - 1]) / np.maximum(mag, 1e-300)
    zeta_min = np.clip(0.25 * rel, 1e-6, 0.05)
    zeta = -roots.real / np.maximum(mag, 1e-300)
    low = zeta < zeta_min
    fixed = mag * (-zeta_min + 1j * np.sign(roots.imag) * np.sqrt(1 - zeta_min**2))
    return np.where(low, fixed, roots)


def _proper(zeros: np.ndarray, n_poles: int) -> np.ndarray:
    """Drop the fastest zeros beyond the number of poles (far above the grid: the
    properness constraint keeps ``|W(inf)|`` bounded, so their product is fixed by the gain)."""
    if zeros.size <= n_poles:
        return zeros
    keep = np.argsort(np.abs(zeros))[:n_poles]
    kept = zeros[keep]
    if np.abs(kept.imag).max(initial=0) > 0 and not np.allclose(
        np.sort_complex(kept), np.sort_complex(kept.conj())
    ):
        keep = np.argsort(np.abs(zeros))[: n_poles - 1]  # do not split a conjugate pair
        kept = zeros[keep]
    return kept


@dataclass(frozen=True)
class MagnitudeFit:
    """Outcome of :func:`fit_magnitude_details`.

    Attributes
    ----------
    system : control.StateSpace
        The stable, minimum-phase SISO fit ``W``.
    f_hz, target, fitted : ndarray
        Grid (Hz), target magnitude and ``|W(j 2 pi f)|``.
    max_error_db : float
        ``max |20 log10(fitted / target)|`` over the points with non-zero weight (dB).
    zeros, poles : ndarray
        Of ``W`` (rad/s), all in the open left half plane.
    n_lp : int
        Linear programs solved by the bisection.
    time_s : float
        Wall time of the fit (s; for information, nothing depends on it).
    stopped_by_budget : bool
        A ``time_budget_s`` ended the bisection before its tolerance (see :mod:`robustctl.budget`).
    """

    system: Any
    f_hz: np.ndarray
    target: np.ndarray
    fitted: np.ndarray
    max_error_db: float
    zeros: np.ndarray
    poles: np.ndarray
    n_lp: int
    time_s: float
    stopped_by_budget: bool = False


def _pack(zeros: np.ndarray, poles: np.ndarray) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """Real parameters of left-half-plane roots: ``ln|r|`` for a real root; ``ln|s|`` and
    ``atanh(2 zeta - 1)`` for a complex pair (upper member)."""
    theta, layout = [], []
    for kind, roots in (("z", zeros), ("p", poles)):
        for g in conjugate_pairs(roots):
            if g.size == 1:
                theta.append(np.log(abs(g[0].real)))
                layout.append((kind, 1))
            else:
                r = abs(g[0])
                zeta = float(np.clip(-g[0].real / r, 1e-6, 1 - 1e-9))
                theta += [np.log(r), np.arctanh(2 * zeta - 1)]
                layout.append((kind, 2))
    return np.array(theta), layout


def _unpack(theta: np.ndarray, layout: list[tuple[str, int]]) -> tuple[np.ndarray, np.ndarray]:
    theta = np.clip(theta, -60.0, 60.0)
    out: dict[str, list[complex]] = {"z": [], "p": []}
    k = 0
    for kind, size in layout:
        if size == 1:
            out[kind].append(-np.exp(theta[k]) + 0j)
            k += 1
        else:
            r, zeta = np.exp(theta[k]), 0.5 * (1 + np.tanh(theta[k + 1]))
            s = r * (-zeta + 1j * np.sqrt(max(1 - zeta**2, 0.0)))
            out[kind] += [s, np.conj(s)]
            k += 2
    return np.array(out["z"], dtype=complex), np.array(out["p"], dtype=complex)


def _polish(zeros: np.ndarray, poles: np.ndarray, w: np.ndarray, target: np.ndarray, wt: np.ndarray,
            exact: bool = False):
    """Refine roots so ``ln|W|`` matches the LP's own curve ``target`` (least squares, gain
    free): a safety net when the roots of large cancelling coefficients came out inaccurate.
    The parametrisation keeps every root in the left half plane. ``exact``: iterate to the
    solver's limits (tolerances 1e-15), so that the roots are those of ``target`` and not of
    the eigenvalue solver's rounding."""
    from scipy.optimize import least_squares

    theta0, layout = _pack(zeros, poles)
    if theta0.size == 0:
        return zeros, poles
    # a root far outside the grid only tilts ln|W| there, and the free gain absorbs its size:
    # unbounded, least squares drifts it towards 0 or infinity (a pole at 1e26 rad/s) and the
    # realisation is lost. Root magnitudes stay within ROOT_SPAN of the grid.
    lo, hi = np.full(theta0.size, -np.inf), np.full(theta0.size, np.inf)
    k = 0
    for _, size in layout:
        lo[k], hi[k] = np.log(w[0] / ROOT_SPAN), np.log(w[-1] * ROOT_SPAN)
        k += size
    theta0 = np.clip(theta0, lo + 1e-9, hi - 1e-9)

    def resid(theta):
        z, p = _unpack(theta, layout)
        r = np.log(np.abs(zpk_response(z, p, 1j * w))) - target
        return wt * (r - np.average(r, weights=wt))

    tight = {"ftol": 1e-15, "xtol": 1e-15, "gtol": 1e-15} if exact else {}
    sol = least_squares(resid, theta0, bounds=(lo, hi), max_nfev=(30 if exact else 10) * theta0.size,
                        x_scale="jac", **tight)
    return _unpack(sol.x, layout)


def _realise(
    basis: _Basis,
    a: np.ndarray,
    b: np.ndarray,
    w: np.ndarray,
    m: np.ndarray,
    wt: np.ndarray,
    upper_bound: bool,
    exact: bool = False,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Spectral factors of ``A / B``, the gain, and the realised weighted max log error (dB).

    ``exact``: the roots are always polished onto ``A / B``'s curve to the solver's limits (the
    roots of coefficients that cancel over many decades carry the eigenvalue solver's rounding,
    amplified by their conditioning: 2e-3 on a D-scale of the Caltech design plant)."""
    Phi = basis.matrix((w / basis.w0) ** 2)
    target = 0.5 * np.log(np.maximum(Phi @ a, 1e-300) / np.maximum(Phi @ b, 1e-300))
    if exact:
        # polished from the roots as found (before the damping floor, which would move the start
        # away from the curve and let the polish settle wherever its start leads), taken as
        # polished: no comparison for rounding to decide
        zeros, poles = _lhp(basis.roots(a), basis.w0), _lhp(basis.roots(b), basis.w0)
        zeros = _proper(zeros, poles.size)
        zp = _polish(zeros, poles, w, target, np.maximum(wt, 1e-3), True)
        zeros, poles = _damping_floor(zp[0], w), _damping_floor(zp[1], w)
    else:
        zeros = _damping_floor(_lhp(basis.roots(a), basis.w0), w)
        poles = _damping_floor(_lhp(basis.roots(b), basis.w0), w)
        zeros = _proper(zeros, poles.size)
        shape = np.log(np.abs(zpk_response(zeros, poles, 1j * w)))
        if np.ptp(shape - target) > 1e-2:  # the roots do not reproduce the LP's curve: polish them
            zp = _polish(zeros, poles, w, target, np.maximum(wt, 1e-3), exact)
            shape_p = np.log(np.abs(zpk_response(*zp, 1j * w)))
            if np.ptp(shape_p - target) < np.ptp(shape - target):
                zeros, poles = _damping_floor(zp[0], w), _damping_floor(zp[1], w)
    r = np.log(m / np.abs(zpk_response(zeros, poles, 1j * w)))
    # a cover: the smallest gain that covers every point (with a rounding margin); else the
    # weighted Chebyshev centre of the log ratios
    c = float(r.max()) + 1e-9 if upper_bound else _weighted_centre(r, wt)
    return zeros, poles, float(np.exp(c)), float(DB_PER_NEPER * np.max(wt * np.abs(c - r)))


def _weighted_centre(r: np.ndarray, wt: np.ndarray) -> float:
    """``argmin_c max_k w_k |r_k - c|`` in closed form (points with ``w_k = 0`` ignored).

    The largest of ``w_i (r_i - c)`` falls and the largest of ``w_j (c - r_j)`` rises with ``c``;
    the minimum is where they meet, at the pair ``(i, j)`` with the largest
    ``w_i w_j (r_i - r_j) / (w_i + w_j)``: ``c = (w_i r_i + w_j r_j) / (w_i + w_j)``. Exact, unlike
    a scalar search (whose stopping point rounding can move by its tolerance).
    """
    keep = wt > 0
    r, wt = np.asarray(r, dtype=float)[keep], np.asarray(wt, dtype=float)[keep]
    if np.all(wt == wt[0]):
        return float(0.5 * (r.max() + r.min()))
    best, pair = -np.inf, (0, 0)
    for k0 in range(0, r.size, 1024):  # rows in blocks: memory stays ~8 MB per block
        wi, ri = wt[k0:k0 + 1024, None], r[k0:k0 + 1024, None]
        value = wi * wt[None, :] * (ri - r[None, :]) / (wi + wt[None, :])
        k = int(np.argmax(value))
        if value.flat[k] > best:
            best, pair = float(value.flat[k]), (k0 + k // r.size, k % r.size)
    i, j = pair
    return float((wt[i] * r[i] + wt[j] * r[j]) / (wt[i] + wt[j]))


def _peak_ratio(cand: tuple, w: np.ndarray, m: np.ndarray) -> float:
    """Peak of a realised cover's ``|W|`` on and between the grid points and 3 decades beyond,
    over the curve's largest value."""
    zeros, poles, k, _ = cand
    wd = np.sqrt(_dense_points(w**2, per=16))
    return float(k * np.abs(zpk_response(zeros, poles, 1j * np.concatenate([w, wd]))).max() / m.max())


def _check_realisation(
    sys: Any, f_hz: np.ndarray, fitted: np.ndarray, order: int, strict: bool
) -> np.ndarray:
    """The state space's ``|W|`` on the grid; FitError unless it is stable, finite and (when
    ``strict``: a cover, whose margin must be truthful) the fitted one to 1e-3 nepers."""
    if sys.nstates == 0:
        return np.full(f_hz.size, abs(float(sys.D[0, 0])))
    with np.errstate(all="ignore"):
        stable = bool(np.all(np.isfinite(sys.A)) and is_stable(sys, margin=0.0))
        mag = np.abs(freqresp_array(sys, f_hz)[:, 0, 0]) if stable else np.full(f_hz.size, np.nan)
        dev = float(np.max(np.abs(np.log(mag / fitted)))) if np.all(np.isfinite(mag) & (mag > 0)) else np.inf
    if not (dev <= 1e-3 or (stable and not strict and np.isfinite(dev))):  # 0.01 dB
        why = "is unstable or not finite" if not stable else f"misses the fitted |W| by {dev:.3g} nepers"
        raise FitError(
            f"the order-{order} magnitude fit could not be realised faithfully (its state space {why}); "
            f"the curve may not support {order} poles: try order={max(order - 1, 0)} or fewer."
        )
    return mag


def fit_magnitude_details(
    f_hz: Any,
    mag: Any,
    order: int,
    *,
    upper_bound: bool = False,
    point_weights: Any = None,
    objective: str = "max",
    tol_db: float = 0.05,
    time_budget_s: float | Deadline | None = None,
    name: str | None = None,
    centre: float | None = None,
) -> MagnitudeFit:
    """:func:`fit_magnitude` with the fit's figures (error, roots, LPs solved)."""
    t0 = time.perf_counter()
    own_clock = not isinstance(time_budget_s, Deadline)  # a caller's Deadline: the caller reports
    f, m = _check_curve(f_hz, mag)
    order = _check_order(order)
    wt = _check_point_weights(point_weights, f.size)
    upper_bound = flag(upper_bound, "upper_bound", FitError)
    optional_text(name, "name", FitError)
    if not isinstance(objective, str) or objective not in ("max", "mean") or (
        objective == "mean" and not upper_bound
    ):
        raise FitError(
            f'objective must be "max" (log-Chebyshev) or, with upper_bound=True, "mean" (the smallest '
            f"mean overbound); got {objective!r} with upper_bound={upper_bound!r}."
        )
    tol_db = positive_number(tol_db, "tol_db", FitError, unit="dB")
    if centre is not None:
        centre = positive_number(centre, "centre", FitError)
        if upper_bound:
            raise FitError("centre applies to a log-Chebyshev fit, not to a cover (upper_bound=True).")
    deadline = as_deadline(time_budget_s, FitError)
    use = wt > 0
    logm = np.log(m)
    scale = float(np.exp(np.mean(logm[use])))
    w = 2.0 * np.pi * f
    if order == 0:
        lo_, hi_ = logm[use].min(), logm[use].max()
        k = np.exp(hi_) if upper_bound else np.exp(0.5 * (lo_ + hi_))
        zeros = poles = np.zeros(0, dtype=complex)
        n_lp = 0
    else:
        basis, x = _basis(w, order, np.where(use, m, np.nan))
        y = (m[use] / scale) ** 2
        prob = _Problem(
            phi=basis.matrix(x[use]),
            y=y,
            wt=wt[use],
            guard=basis.matrix(np.array([0.0, np.inf])),
            guard_all=basis.matrix(_guard_points(x)),
            dense=basis.matrix(_dense_points(x[use])) if upper_bound else np.zeros((0, order + 1)),
            upper_bound=bool(upper_bound),
            y_inf=HF_CAP**2 * float(y.max()),
            y_peak=PEAK_CAP**2 * float(y.max()),
            **_midpoints(basis, x[use], y, wt[use]),
        )
        spread = 0.5 * float(np.log(y.max() / y.min()))
        hi = (2.0 * spread if upper_bound else spread) + 1e-3
        tol = tol_db / DB_PER_NEPER
        best, n_lp, worst_peak = None, 0, 0.0
        fixed = None if upper_bound else _centre_data(prob)
        start = replace(prob) if upper_bound else None  # the LPs replace, not mutate, its arrays
        for price in L1_PRICES:
            prob.price = price
            a, b, n, level = _minimise(prob, hi, tol, deadline, levels_only=True)
            n_lp += n
            exact = False
            if price == 0.0:
                if fixed is not None:
                    ab = (_centre(fixed, level * (1.0 + centre) + 1e-6, a, b) if centre is not None
                          else _least_squares_fit(fixed, level + SELECT_MARGIN * tol, a, b))
                elif objective == "max":  # the tightest cover (least squares to the bound) within the level
                    cap = level + SELECT_MARGIN * tol
                    ab = _least_squares_fit(_centre_data(start, cap), 0.5 * cap, a, b, y_target=start.y)
                else:
                    ab = None
                if ab is not None:
                    a, b = ab
                    exact = True
                prob.zscale = max(float(np.abs(a).sum() + np.abs(b).sum()), 1e-300)
            if upper_bound and not exact:  # minimax ties broken by the mean ("max"), or a traded worst point
                g_star = _achieved(prob, a, b)
                cap, n_it = (g_star + tol, 2) if objective == "max" else (2.0 * g_star + tol, 6)
                a, b, n = _tighten(prob, a, b, cap, deadline, n_it)
                n_lp += n
            cand = _realise(basis, a, b, w[use], m[use], wt[use], bool(upper_bound), exact)
            peak = _peak_ratio(cand, w[use], m[use]) if upper_bound else 0.0
            if peak <= 2.0 * PEAK_CAP and (best is None or cand[3] < best[3]):
                best = cand
            worst_peak = max(worst_peak, peak)
            if best is cand and (
                exact  # the least-squares choice: the priced LPs would bring back the solver's noise
                or cand[3] <= DB_PER_NEPER * _achieved(prob, a, b) + tol_db
                or deadline.expired()
            ):
                break  # the roots reproduce the LP's curve
        if best is None:
            raise FitError(
                f"the order-{order} covering fit peaks {worst_peak:.3g} times above the curve's largest "
                f"value between or beyond the grid points (a resonance the grid does not resolve); try "
                f"order={order - 1} or fewer, or a finer grid."
            )
        zeros, poles, k, _ = best
    sys = zpk_statespace(zeros, poles, k, name=name)
    # the reported |W| (and error) is the state space's own
    fitted = _check_realisation(sys, f, k * np.abs(zpk_response(zeros, poles, 1j * w)), order, upper_bound)
    short = float(np.max(m[use] / fitted[use]))
    if upper_bound and short > 1.0:  # the realisation's rounding (~1e-9) must not uncover a point
        k, fitted = k * short * (1 + 1e-9), fitted * (short * (1 + 1e-9))
        sys = zpk_statespace(zeros, poles, k, name=name)
    err = 20 * np.log10(fitted[use] / m[use])
    if own_clock and deadline.hit:
        deadline.warn(f"the order-{order} magnitude fit")
    return MagnitudeFit(
        system=sys,
        f_hz=f,
        target=m,
        fitted=fitted,
        max_error_db=float(np.max(np.abs(err))),
        zeros=zeros,
        poles=poles,
        n_lp=n_lp,
        time_s=time.perf_counter() - t0,
        stopped_by_budget=deadline.hit,
    )


def fit_magnitude(f_hz: Any, mag: Any, order: int, **options: Any):
    """A stable, minimum-phase ``W(s)`` whose magnitude fits ``mag`` on ``f_hz`` (log-Chebyshev).

    Minimises ``max_k w_k |ln|W(j 2 pi f_k)| - ln mag_k|`` over real-rational ``W`` with
    ``order`` poles (at most as many zeros: proper) by bisection on linear programs in the
    coefficients of ``|W|^2 = A(w^2) / B(w^2)`` (Boyd-Vandenberghe sec. 6.5.5), then spectral
    factorisation: zeros and poles are the left-half-plane roots of ``A(-s^2)`` and
    ``B(-s^2)``. See the module docstring for the basis and the numerics. The D-scale fit of
    D-K iteration (Packard-Doyle 1993) and the weight fit of an uncertainty cover (MATLAB
    ``fitmagfrd`` / ``ucover``). A log-Chebyshev fit (not a cover) returns, among the fits within
    the bisection's last feasible level (plus a tenth of ``tol_db``), the one of least squared
    error (:func:`_least_squares_fit`): unique and a smooth function of ``mag``, so that rounding
    of the data moves it in proportion (the LP's own solution there is fixed only to the
    solver's accuracy).

    Parameters
    ----------
    f_hz : array_like (n,)
        Frequencies in Hz, positive and strictly increasing.
    mag : array_like (n,)
        Target magnitude (positive, finite; any unit).
    order : int
        Number of poles of ``W`` (0 gives a constant).
    **options
        The keyword-only parameters ``upper_bound`` to ``centre`` below; the function's signature
        is that of :func:`fit_magnitude_details` (one parameter list for both).
    upper_bound : bool
        Require ``|W| >= mag`` at every grid point (with a non-zero weight) and make the
        largest overshoot as small as possible: a covering weight.
    point_weights : array_like (n,), optional
        Non-negative weights of the log error per point (the error allowed at a point is
        inversely proportional to its weight; 0 drops the point).
    objective : {"max", "mean"}
        ``"max"``: the log-Chebyshev fit. ``"mean"`` (with ``upper_bound=True``): start from
        it, then lower the weighted mean overbound ``mean ln(|W| / mag)`` by a few
        linearised LPs (a tighter cover over most of the band, see :func:`_tighten`).
    tol_db : float
        Bisection tolerance on the max error (dB).
    time_budget_s : float or None
        Optional wall-clock cap (s) of the bisection (:mod:`robustctl.budget`'s policy): None
        (default) bounds it by its LP counts only; when a budget stops it, the best fit so far
        is returned with a BudgetWarning. A caller's :class:`~robustctl.budget.Deadline` is
        shared (the caller then reports).
    name : str, optional
        Name of the returned system.
    centre : float, optional
        With a log-Chebyshev fit, return instead of the least-squares fit the unique analytic
        centre of the fits whose weighted max error is within ``(1 + centre)`` times the bisection's
        level (dimensionless, e.g. 0.05): also moved by rounding of ``mag`` only in proportion,
        about ``centre`` looser. None (default): the least-squares fit within the level.

    Returns
    -------
    control.StateSpace
        SISO, stable, minimum phase (poles and zeros in the open left half plane), proper.

    Raises
    ------
    FitError
        Non-positive, NaN or mismatched magnitudes; unsorted or duplicated frequencies;
        an order outside 0-20; an unstable or non-finite realisation; a cover the state
        space misses by more than 0.01 dB, or whose every candidate peaks above
        ``2 PEAK_CAP`` times the curve's largest value (the message suggests a lower order).

    Notes
    -----
    The LP works on ``|W|^2``: a curve spanning more than ~100 dB at a low order leaves a
    thin feasible set that the solver resolves only to ~1e-8, and the fit can stop several
    dB short of the optimum (D-scales and uncertainty envelopes span far less). Roots that
    do not reproduce the LP's own curve (an order above the curve's, with large cancelling
    coefficients) are polished by least squares on ``ln|W|``; poles and zeros more lightly
    damped than the grid resolves get the damping the grid can see (``_damping_floor``).
    Polished roots stay within ``ROOT_SPAN`` of the grid (a root far outside it only tilts
    ``ln|W|``, and unbounded least squares drifted one to 1e26 rad/s: a realisation with
    ``|W| ~ 1e11``). A cover keeps ``|W| <= PEAK_CAP max(mag)`` on the grid, between its points
    and beyond (cutting planes), and the returned ``|W|`` is checked against the state space
    (the reported ``fitted`` and ``max_error_db`` are always the state space's own).

    Examples
    --------
    >>> import numpy as np, robustctl as rc
    >>> f = np.logspace(-1, 2, 100)
    >>> W = rc.fit_magnitude(f, np.abs(0.1 + 1j * f) / np.abs(1 + 1j * f / 30), order=2)
    """
    return fit_magnitude_details(f_hz, mag, order, **options).system


#: one parameter list for both: what ``help`` and ``inspect.signature`` show of fit_magnitude
fit_magnitude.__signature__ = inspect.signature(fit_magnitude_details).replace(  # type: ignore[attr-defined]
    return_annotation=inspect.Signature.empty
)
