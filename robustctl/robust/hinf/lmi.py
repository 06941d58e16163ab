"""LMI route of H-infinity synthesis (Gahinet & Apkarian 1994), for singular problems.

Gahinet & Apkarian, "A linear matrix inequality approach to H-infinity control", *Int. J.
Robust Nonlinear Control* 4 (1994) 421-448, Theorem 4.3: for ``D22 = 0`` a controller of
order ``n`` with ``||Fl(P, K)||_inf < gamma`` exists iff there are symmetric ``R``, ``S`` with

.. math::

    \\begin{bmatrix} N_R & 0 \\\\ 0 & I \\end{bmatrix}^T
    \\begin{bmatrix} A R + R A^T & R C_1^T & B_1 \\\\ C_1 R & -\\gamma I & D_{11} \\\\
                     B_1^T & D_{11}^T & -\\gamma I \\end{bmatrix}
    \\begin{bmatrix} N_R & 0 \\\\ 0 & I \\end{bmatrix} < 0,\\quad
    \\begin{bmatrix} N_S & 0 \\\\ 0 & I \\end{bmatrix}^T
    \\begin{bmatrix} A^T S + S A & S B_1 & C_1^T \\\\ B_1^T S & -\\gamma I & D_{11}^T \\\\
                     C_1 & D_{11} & -\\gamma I \\end{bmatrix}
    \\begin{bmatrix} N_S & 0 \\\\ 0 & I \\end{bmatrix} < 0,\\quad
    \\begin{bmatrix} R & I \\\\ I & S \\end{bmatrix} \\ge 0,

``N_R``, ``N_S`` bases of the null spaces of ``[B2^T, D12^T]`` and ``[C2, D21]``. No rank or
imaginary-axis-zero assumption is needed (the infimum may then not be attained). ``gamma``
is minimised directly (no bisection). The controller is then reconstructed at a backed-off
``gamma`` from the equivalent LMI in the linearising variables of Scherer, Gahinet & Chilali
(1997), whose solution gives the controller matrices in closed form (:func:`lmi_controller`).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.linalg

from ...errors import SynthesisError

__all__ = ["lmi_gamma", "lmi_controller", "lmi_rescaled_gamma"]

#: Re-solves of the gamma LMI in the coordinates its last solution balances (:func:`lmi_rescaled_gamma`).
RESCALE_PASSES = 3
#: Relative change of gamma below which the re-solves stop.
RESCALE_RTOL = 1e-3


def _null(M: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the null space of ``M`` (columns)."""
    if M.shape[0] == 0:
        return np.eye(M.shape[1])
    return scipy.linalg.null_space(M, rcond=1e-10)


def _sym(M):
    return 0.5 * (M + M.T)


def _solve(prob, time_limit: float) -> None:
    """Solve with Clarabel, within ``time_limit`` s when finite (``inf``: Clarabel's iteration cap
    only, so the solution depends on nothing but the problem). An "inaccurate" status is not
    warned about here: the caller checks the margins and hinfsyn verifies the closed loop."""
    import warnings

    import cvxpy as cp

    limit = {} if not np.isfinite(time_limit) else {"time_limit": max(time_limit, 1.0)}
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Solution may be inaccurate")
            prob.solve(solver=cp.CLARABEL, **limit)
    except cp.error.SolverError as exc:
        raise SynthesisError(f"the LMI solver (Clarabel) failed: {exc}") from exc


def lmi_gamma(
    m: dict[str, np.ndarray],
    margin: float,
    time_limit: float,
    gamma_fixed: float | None = None,
    rho: float = 1.0,
) -> tuple[float, np.ndarray, np.ndarray]:
    """Minimal ``gamma`` of Theorem 4.3, or, with ``gamma_fixed``, a well-centred ``R, S`` at that gamma.

    Minimising gamma: the strict inequalities become ``<= -margin I``. At a fixed gamma the
    common margin ``eta`` of all three LMIs is maximised with ``R, S <= rho I``, which keeps
    ``I - R S`` (and so the reconstruction) well conditioned. Returns ``(gamma, R, S)``.
    """
    import cvxpy as cp

    A, B1, B2, C1, C2, D11, D12, D21 = (m[k] for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21"))
    n, m1, p1 = A.shape[0], B1.shape[1], C1.shape[0]
    NR = _null(np.hstack([B2.T, D12.T]))
    NS = _null(np.hstack([C2, D21]))
    R = cp.Variable((n, n), symmetric=True)
    S = cp.Variable((n, n), symmetric=True)
    g = cp.Variable() if gamma_fixed is None else cp.Constant(gamma_fixed)
    eta = cp.Constant(margin) if gamma_fixed is None else cp.Variable()
    ER = scipy.linalg.block_diag(NR, np.eye(m1))
    ES = scipy.linalg.block_diag(NS, np.eye(p1))
    LR = cp.bmat(
        [[A @ R + R @ A.T, R @ C1.T, B1], [C1 @ R, -g * np.eye(p1), D11], [B1.T, D11.T, -g * np.eye(m1)]]
    )
    LS = cp.bmat(
        [[A.T @ S + S @ A, S @ B1, C1.T], [B1.T @ S, -g * np.eye(m1), D11.T], [C1, D11, -g * np.eye(p1)]]
    )
    # LR is indexed [x; z; w] and N_R acts on [x; z]; LS is [x; w; z] and N_S acts on [x; w]
    cons = [
        _sym(ER.T @ LR @ ER) << -eta * np.eye(ER.shape[1]),
        _sym(ES.T @ LS @ ES) << -eta * np.eye(ES.shape[1]),
        cp.bmat([[R, np.eye(n)], [np.eye(n), S]]) >> eta * np.eye(2 * n),
    ]
    if gamma_fixed is None:
        objective = cp.Minimize(g + 1e-9 * (cp.trace(R) + cp.trace(S)))
    else:
        cons += [R << rho * np.eye(n), S << rho * np.eye(n)]
        objective = cp.Maximize(eta)
    prob = cp.Problem(objective, cons)
    _solve(prob, time_limit)
    if (
        prob.status not in ("optimal", "optimal_inaccurate")
        or R.value is None
        or (gamma_fixed is not None and not float(eta.value) > 0)
    ):
        raise SynthesisError(
            f"the LMI problem of H-infinity synthesis is {prob.status}"
            + (f" at gamma = {gamma_fixed:.6g}" if gamma_fixed is not None else "")
            + ": check that (A, B2) is stabilisable and (C2, A) detectable."
        )
    gamma = float(g.value) if gamma_fixed is None else float(gamma_fixed)
    return gamma, _sym(np.asarray(R.value)), _sym(np.asarray(S.value))


def lmi_controller(
    m: dict[str, np.ndarray], gamma: float, rho: float, time_limit: float,
    RS: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Controller ``(Ak, Bk, Ck, Dk)`` of order ``n`` with ``||Fl(P, K)|| < gamma`` (``D22 = 0``).

    The linearising change of variables of Scherer, Gahinet & Chilali (1997, *IEEE TAC* 42,
    896-911, sec. IV): with ``X`` the top-left block of the closed-loop Lyapunov matrix and
    ``Y`` that of its inverse, the bounded-real LMI is affine in ``(X, Y, Ah, Bh, Ch, Dh)``::

        [[A Y + Y A' + B2 Ch + (B2 Ch)',  Ah' + A + B2 Dh C2,  B1 + B2 Dh D21,  (C1 Y + D12 Ch)'],
         [*,  A' X + X A + Bh C2 + (Bh C2)',  X B1 + Bh D21,  (C1 + D12 Dh C2)'],
         [*,  *,  -gamma I,  (D11 + D12 Dh D21)'],
         [*,  *,  *,  -gamma I]] < 0,      [[Y, I], [I, X]] > 0.

    Its common margin is maximised with ``X, Y <= rho I`` (a well-centred, well-conditioned
    solution), then ``N M^T = I - X Y`` (SVD) and
    ``Dk = Dh``, ``Ck = (Ch - Dk C2 Y) M^-T``, ``Bk = N^-1 (Bh - X B2 Dk)``,
    ``Ak = N^-1 (Ah - N Bk C2 Y - X B2 Ck M^T - X (A + B2 Dk C2) Y) M^-T``.
    """
    import cvxpy as cp

    A, B1, B2, C1, C2, D11, D12, D21 = (m[k] for k in ("A", "B1", "B2", "C1", "C2", "D11", "D12", "D21"))
    n, m1, m2, p1, p2 = A.shape[0], B1.shape[1], B2.shape[1], C1.shape[0], C2.shape[0]
    if RS is None:
        X = cp.Variable((n, n), symmetric=True)
        Y = cp.Variable((n, n), symmetric=True)
    else:  # Y = R, X = S of Theorem 4.3 at this gamma: only the controller's variables remain
        X, Y = cp.Constant(_sym(RS[1])), cp.Constant(_sym(RS[0]))
    Ah, Bh = cp.Variable((n, n)), cp.Variable((n, p2))
    Ch, Dh = cp.Variable((m2, n)), cp.Variable((m2, p2))
    eta = cp.Variable()
    b11 = A @ Y + B2 @ Ch
    b22 = A.T @ X + Bh @ C2
    b21 = Ah + (A + B2 @ Dh @ C2).T
    b31 = (B1 + B2 @ Dh @ D21).T
    b32 = (X @ B1 + Bh @ D21).T
    b41 = C1 @ Y + D12 @ Ch
    b42 = C1 + D12 @ Dh @ C2
    b43 = D11 + D12 @ Dh @ D21
    big = cp.bmat(
        [
            [b11 + b11.T, b21.T, b31.T, b41.T],
            [b21, b22 + b22.T, b32.T, b42.T],
            [b31, b32, -gamma * np.eye(m1), b43.T],
            [b41, b42, b43, -gamma * np.eye(p1)],
        ]
    )
    size = 2 * n + m1 + p1
    hat_bound = 1e4 * rho * (1.0 + sum(float(np.abs(M).max()) for M in (A, B2, C2) if M.size))
    cons = [_sym(big) << -eta * np.eye(size), eta <= gamma]
    if RS is None:
        cons.append(cp.norm(cp.bmat([[Ah, Bh], [Ch, Dh]]), "fro") <= hat_bound)
        cons += [cp.bmat([[Y, np.eye(n)], [np.eye(n), X]]) >> eta * np.eye(2 * n),
                 X << rho * np.eye(n), Y << rho * np.eye(n)]
    prob = cp.Problem(cp.Maximize(eta), cons)
    t0 = time.monotonic()
    _solve(prob, time_limit)
    if eta.value is None or not eta.value > 0 or (RS is None and X.value is None):
        raise SynthesisError(
            f"LMI controller reconstruction failed at gamma = {gamma:.6g} (status {prob.status}, "
            f"margin {eta.value}, "
            f"{time.monotonic() - t0:.1f} s). Increase backoff."
        )
    Xv, Yv = (_sym(np.asarray(RS[1])), _sym(np.asarray(RS[0]))) if RS is not None else \
        (_sym(np.asarray(X.value)), _sym(np.asarray(Y.value)))
    U, s, Vt = np.linalg.svd(np.eye(n) - Xv @ Yv)
    N, Mt = U * np.sqrt(s)[None, :], np.sqrt(s)[:, None] * Vt  # N M^T = I - X Y
    Dk = np.asarray(Dh.value)
    Ck = np.linalg.solve(Mt.T, (np.asarray(Ch.value) - Dk @ C2 @ Yv).T).T
    Bk = np.linalg.solve(N, np.asarray(Bh.value) - Xv @ B2 @ Dk)
    inner = np.asarray(Ah.value) - N @ Bk @ C2 @ Yv - Xv @ B2 @ Ck @ Mt - Xv @ (A + B2 @ Dk @ C2) @ Yv
    Ak = np.linalg.solve(Mt.T, np.linalg.solve(N, inner).T).T
    return Ak, Bk, Ck, Dk


def _state_transformed(m: dict[str, np.ndarray], T: np.ndarray) -> dict[str, np.ndarray]:
    """The plant in the state coordinates ``x = T x_new`` (its transfer matrix unchanged)."""
    Ti = np.linalg.inv(T)
    return dict(m, A=Ti @ m["A"] @ T, B1=Ti @ m["B1"], B2=Ti @ m["B2"], C1=m["C1"] @ T, C2=m["C2"] @ T)


def _rs_balancing(R: np.ndarray, S: np.ndarray) -> np.ndarray | None:
    """``T`` with ``T^-1 R T^-T = T^T S T = Sigma^(1/2)`` diagonal (None when ill-defined).

    As in balanced realisation (Laub et al. 1987) with ``R`` and ``S`` in the roles of the
    two Gramians: ``R = L L^T``, ``L^T S L = U Sigma U^T``, ``T = L U Sigma^(-1/4)``. In the
    new coordinates both Lyapunov variables have the same eigenvalues ``sqrt(eig(R S))``,
    near 1 at the optimum where ``[[R, I], [I, S]] >= 0`` binds. Eigenvalues of ``R`` (an
    inaccurate solve's can be slightly negative) are floored at 1e-12 of its largest.
    """
    R, S = _sym(R), _sym(S)
    for M in (R, S):
        if not np.all(np.isfinite(M)):
            return None
    w, V = np.linalg.eigh(R)
    if w[-1] <= 0:
        return None
    L = V * np.sqrt(np.maximum(w, 1e-12 * w[-1]))[None, :]
    sig, U = np.linalg.eigh(_sym(L.T @ S @ L))
    if sig[-1] <= 0:
        return None
    sig = np.maximum(sig, 1e-12 * sig[-1])
    T = (L @ U) * (sig ** -0.25)[None, :]
    return T if np.linalg.cond(T) < 1e12 else None


def lmi_rescaled_gamma(m: dict[str, np.ndarray], margin: float,
                       time_limit: float) -> tuple[float, np.ndarray, np.ndarray, dict[str, np.ndarray], int]:
    """:func:`lmi_gamma` re-solved in the state coordinates its solution balances.

    An interior-point solver works on the scale of the data: a plant with states decades
    apart in speed (mu-tools' HIMAT: weight poles at 0.03 and 1e4 rad/s) has Lyapunov
    variables whose eigenvalues spread over ten decades, and Clarabel stopped "inaccurate" at
    gamma 2027 where the optimum is 1.675 (balancing ``[[A, B], [C, 0]]`` alone: 20.2). The
    solution, inaccurate as it is, tells the scale: in the coordinates of
    :func:`_rs_balancing` the next solve is well conditioned (1.686, then 1.681). Up to
    :data:`RESCALE_PASSES` re-solves, while gamma falls by more than :data:`RESCALE_RTOL`.

    Returns
    -------
    gamma : float
        The lowest gamma of the solves.
    R, S : ndarray
        Its Lyapunov variables, in the coordinates of ``m_t``.
    m_t : dict
        The plant in those coordinates (same transfer matrix).
    passes : int
        Solves done.
    """
    gamma, R, S = lmi_gamma(m, margin, time_limit)
    best, passes = (gamma, R, S, m), 1
    cur = m
    for _ in range(RESCALE_PASSES):
        T = _rs_balancing(R, S)
        if T is None:
            break
        cur = _state_transformed(cur, T)
        try:
            g, R, S = lmi_gamma(cur, margin, time_limit)
        except SynthesisError:
            break
        passes += 1
        improved = g < best[0] * (1 - RESCALE_RTOL)
        if g < best[0]:
            best = (g, R, S, cur)
        if not improved:
            break
    return best[0], best[1], best[2], best[3], passes
