"""Independent LMI references for the synthesis tests (cvxpy + Clarabel), written from the books.

* H2 output feedback (continuous and discrete): Scherer, Gahinet & Chilali (1997),
  "Multiobjective output-feedback control via LMI optimization", IEEE TAC 42(7), with the
  linearising change of variables ``(X, Y, K, L, M, N)`` of Scherer & Weiland, "Linear
  Matrix Inequalities in Control", sec. 4.2: the closed loop's observability-Gramian
  inequalities after the congruence with ``[[X, I], [M^T, 0]]``.
* The discrete bounded-real lemma for output feedback (Gahinet & Apkarian 1994, sec. 5,
  "A linear matrix inequality approach to H-infinity control", IJRNC 4) in the same variables.

The tests compare these optima with the Riccati answers; nothing here is used by the package.
"""

from __future__ import annotations

import cvxpy as cp
import numpy as np


def _parts(P, nmeas: int, ncon: int):
    A, B, C, D = (np.asarray(m, dtype=float) for m in (P.A, P.B, P.C, P.D))
    nw, nz = B.shape[1] - ncon, C.shape[0] - nmeas
    return (A, B[:, :nw], B[:, nw:], C[:nz], C[nz:], D[:nz, :nw], D[:nz, nw:], D[nz:, :nw], D[nz:, nw:])


def _bold(P, nmeas, ncon, feedthrough: bool):
    A, B1, B2, C1, C2, D11, D12, D21, _ = _parts(P, nmeas, ncon)
    n = A.shape[0]
    X = cp.Variable((n, n), symmetric=True)
    Y = cp.Variable((n, n), symmetric=True)
    K = cp.Variable((n, n))
    L = cp.Variable((n, nmeas))
    M = cp.Variable((ncon, n))
    N = cp.Variable((ncon, nmeas)) if feedthrough else np.zeros((ncon, nmeas))
    I = np.eye(n)
    Ab = cp.bmat([[A @ X + B2 @ M, A + B2 @ N @ C2], [K, Y @ A + L @ C2]])
    Bb = cp.vstack([B1 + B2 @ N @ D21, Y @ B1 + L @ D21])
    Cb = cp.hstack([C1 @ X + D12 @ M, C1 + D12 @ N @ C2])
    Db = D11 + D12 @ N @ D21
    Xb = cp.bmat([[X, I], [I, Y]])
    return Ab, Bb, Cb, Db, Xb, (A, B1, B2, C1, C2, D11, D12, D21)


def _sym(M):
    return (M + M.T) / 2


def h2_lmi(P, nmeas: int, ncon: int, discrete: bool, eps: float = 1e-9) -> float:
    """min ||Fl(P, K)||_2 over all controllers of the plant's order, by the LMIs of SGC97."""
    Ab, Bb, Cb, Db, Xb, mats = _bold(P, nmeas, ncon, feedthrough=discrete)
    n2 = Xb.shape[0]
    nw, nz = mats[1].shape[1], mats[3].shape[0]
    Z = cp.Variable((nw, nw), symmetric=True)
    cons = []
    if discrete:  # X > A'XA + C'C and Z > B'XB + D'D (observability form, after congruence)
        big = cp.bmat([
            [Xb, Ab.T, Cb.T],
            [Ab, Xb, np.zeros((n2, nz))],
            [Cb, np.zeros((nz, n2)), np.eye(nz)],
        ])
        cons.append(_sym(big) >> eps * np.eye(big.shape[0]))
        z2 = cp.bmat([
            [Z, Bb.T, Db.T],
            [Bb, Xb, np.zeros((n2, nz))],
            [Db, np.zeros((nz, n2)), np.eye(nz)],
        ])
        cons.append(_sym(z2) >> eps * np.eye(z2.shape[0]))
    else:  # A'X + XA + C'C < 0 and Z > B'XB (D = 0)
        big = cp.bmat([[Ab + Ab.T, Cb.T], [Cb, -np.eye(nz)]])
        cons.append(_sym(big) << -eps * np.eye(big.shape[0]))
        z2 = cp.bmat([[Xb, Bb], [Bb.T, Z]])
        cons.append(_sym(z2) >> eps * np.eye(z2.shape[0]))
    prob = cp.Problem(cp.Minimize(cp.trace(Z)), cons)
    prob.solve(solver=cp.CLARABEL)
    assert prob.status == cp.OPTIMAL, prob.status
    return float(np.sqrt(prob.value))


def hinf_discrete_lmi(P, nmeas: int, ncon: int, eps: float = 1e-9) -> float:
    """min gamma of the discrete bounded-real lemma for the closed loop, in the SGC97 variables.

    ``[[X, A X, B, 0], [., X, 0, X C^T], [., ., I, D^T], [., ., ., gamma^2 I]] > 0`` with the
    closed-loop matrices replaced by their bold, linear counterparts (congruence as in h2_lmi).
    """
    Ab, Bb, Cb, Db, Xb, mats = _bold(P, nmeas, ncon, feedthrough=True)
    n2 = Xb.shape[0]
    nw, nz = mats[1].shape[1], mats[3].shape[0]
    g2 = cp.Variable()
    big = cp.bmat([
        [Xb, Ab, Bb, np.zeros((n2, nz))],
        [Ab.T, Xb, np.zeros((n2, nw)), Cb.T],
        [Bb.T, np.zeros((nw, n2)), np.eye(nw), Db.T],
        [np.zeros((nz, n2)), Cb, Db, g2 * np.eye(nz)],
    ])
    prob = cp.Problem(cp.Minimize(g2), [_sym(big) >> eps * np.eye(big.shape[0])])
    prob.solve(solver=cp.CLARABEL)
    assert prob.status in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE), prob.status
    return float(np.sqrt(g2.value))
