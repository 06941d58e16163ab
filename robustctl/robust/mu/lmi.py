"""The LMI route to the mu upper bound (cvxpy + Clarabel), one frequency at a time.

Solves the generalized eigenvalue problem (Fan, Tits & Doyle 1991, IEEE TAC 36(1), Thm 2.1;
Young, Newlin & Doyle 1995; Packard & Doyle 1993, eq. 8.5 without G)

    minimise beta  s.t.  M^H X_L M + j (G M - M^H G^H) - beta^2 X_R <= 0,  X > 0,

with ``X`` in the commutant of ``Delta`` (``x_i I`` on full blocks, a full Hermitian
``X_i`` on repeated scalar blocks) and ``G`` Hermitian on the repeated real blocks only,
by bisection on ``t = beta^2``: for fixed ``t`` the problem
``min s  s.t.  M^H X_L M + j(...) - t X_R <= s I,  X_i >= eps I,  trace(X_R) = n_in`` is an
SDP (one compilation per frequency, ``t`` a cvxpy Parameter), and ``t`` is feasible when
``s <= 0``. It is slow (tenths of a second per frequency) and is the reference for the
batched bound in :mod:`robustctl.robust.mu.upper`.
"""

from __future__ import annotations

import warnings

import numpy as np

from ...errors import SynthesisError
from .layout import Layout

__all__ = ["lmi_upper_bound"]


def _problem(M: np.ndarray, lay: Layout, eps: float):
    import cvxpy as cp

    n_in = lay.n_in
    t = cp.Parameter(nonneg=True)
    s = cp.Variable()
    xl, xr, cons, xs, gs = [], [], [], [], []
    gterm = 0
    for o, i, kind, m in zip(lay.out, lay.inp, lay.kinds, lay.dsize):
        if m == 1:
            x = cp.Variable(nonneg=True)
            xs.append(x)
            cons.append(x >= eps)
            xl.append((o, x * np.eye(o.stop - o.start)))
            xr.append((i, x * np.eye(i.stop - i.start)))
        else:
            X = cp.Variable((m, m), hermitian=True)
            xs.append(X)
            cons.append(X >> eps * np.eye(m))
            xl.append((o, X))
            xr.append((i, X))
        if kind == "real":
            r = i.stop - i.start
            Gk = cp.Variable((r, r), hermitian=True)
            gs.append(Gk)
            E_in = np.zeros((n_in, r))
            E_in[i, :] = np.eye(r)
            E_out = np.zeros((lay.n_out, r))
            E_out[o, :] = np.eye(r)
            Gfull = E_in @ Gk @ E_out.T
            gterm = gterm + 1j * (Gfull @ M - M.conj().T @ Gfull.H)
    XL = sum(_embed(sl, X, lay.n_out) for sl, X in xl)
    XR = sum(_embed(sl, X, n_in) for sl, X in xr)
    lhs = M.conj().T @ XL @ M + gterm - t * XR
    lhs = 0.5 * (lhs + lhs.H)
    cons += [lhs << s * np.eye(n_in), cp.real(cp.trace(XR)) == n_in]
    prob = cp.Problem(cp.Minimize(s), cons)
    return prob, t, s, xs, gs


def _embed(sl: slice, X, n: int):
    E = np.zeros((n, sl.stop - sl.start))
    E[sl, :] = np.eye(sl.stop - sl.start)
    return E @ X @ E.T


def _feasible(prob, t, s, value: float) -> bool:
    import cvxpy as cp

    t.value = value
    for solver, kw in ((cp.CLARABEL, {}), (cp.SCS, {"eps": 1e-9, "max_iters": 100_000})):
        try:
            with warnings.catch_warnings():  # "solution may be inaccurate" near the optimum: s decides
                warnings.simplefilter("ignore", UserWarning)
                prob.solve(solver=solver, **kw)
        except cp.error.SolverError:
            continue  # Clarabel failed: the same SDP by SCS
        break
    else:
        return False
    if prob.status in (cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE):
        return True  # s unbounded below: strictly feasible (e.g. mu = 0 with real blocks only)
    if s.value is None:
        return False
    return float(s.value) <= 0.0


def lmi_upper_bound(M: np.ndarray, lay: Layout, *, rel_tol: float = 1e-4, eps: float = 1e-7,
                    bracket: tuple[float, float] | None = None, max_bisect: int = 60):
    """The LMI upper bound ``beta`` of mu for one matrix ``M`` (n_out, n_in), with its scales.

    Parameters
    ----------
    M : ndarray, complex, (n_out, n_in)
    lay : Layout
    rel_tol : float
        Relative width of the final bisection bracket on ``beta``.
    eps : float
        Lower bound on the eigenvalues of the scalings (the problem is normalised by
        ``trace(X_R) = n_in``).
    bracket : (lo, hi), optional
        Known bounds on ``beta`` (e.g. the power-iteration lower bound and any upper bound);
        default ``(0, sigma_max(M))``.
    max_bisect : int
        Bisection cap.

    Returns
    -------
    beta : float
        The upper end of the final bracket (a feasible value).
    xblocks : list of ndarray
        ``X_i = D_i^H D_i`` per block (``(1, 1)`` for scalar scales) at ``beta``.
    gblocks : list of ndarray
        ``G_i`` of the real blocks (zeros elsewhere), scaled to the original ``M``.
    """
    try:
        import cvxpy  # noqa: F401
    except ImportError as exc:  # pragma: no cover - a dependency
        raise SynthesisError("method='lmi' needs cvxpy (pip install cvxpy clarabel).") from exc
    scale = float(np.linalg.norm(M, 2))
    if scale == 0.0:
        return 0.0, [np.eye(m) for m in lay.dsize], [None] * lay.n_blocks
    prob, t, s, xs, gs = _problem(M / scale, lay, eps)
    lo, hi = (0.0, 1.0) if bracket is None else (bracket[0] / scale, bracket[1] / scale)
    lo, hi = max(lo * (1 - 1e-6), 0.0), hi * (1 + 1e-6)
    while not _feasible(prob, t, s, hi**2):  # the given upper end was not feasible numerically
        hi *= 1.5
        if hi > 1e6:
            raise SynthesisError("the LMI route found no feasible bound; M may be badly scaled.")
    best = _values(xs, gs)
    for _ in range(max_bisect):
        if hi - lo <= rel_tol * hi:
            break
        mid = 0.5 * (lo + hi)
        if _feasible(prob, t, s, mid**2):
            hi, best = mid, _values(xs, gs)
        else:
            lo = mid
    xblocks, graw = best
    gblocks, it = [], iter(graw)
    for kind, _m in zip(lay.kinds, lay.dsize):
        gblocks.append(next(it) * scale if kind == "real" else None)
    return hi * scale, xblocks, gblocks


def _values(xs, gs):
    x = [np.atleast_2d(np.asarray(v.value, dtype=complex)) for v in xs]
    return x, [np.atleast_2d(np.asarray(g.value, dtype=complex)) for g in gs]
