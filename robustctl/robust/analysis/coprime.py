"""Normalized coprime factorizations: the kernel of loop shaping, the nu-gap and coprime-factor reduction.

For ``G = (A, B, C, D)`` with ``(A, B)`` stabilisable and ``(C, A)`` detectable, with
``R = I + D^T D`` and ``Rt = I + D D^T`` (Zhou, Doyle & Glover 1996, ch. 13, normalized
coprime factorizations; McFarlane & Glover 1990, "Robust Controller Design Using Normalized
Coprime Factor Plant Descriptions"):

* right factors ``G = N M^-1``, ``M~ M + N~ N = I``::

      X:  A^T X + X A - (X B + C^T D) R^-1 (B^T X + D^T C) + C^T C = 0
      F = -R^-1 (B^T X + D^T C)
      [M; N] = (A + B F, B R^-1/2, [F; C + D F], [R^-1/2; D R^-1/2])

* left factors ``G = Mt^-1 Nt``, ``Mt Mt~ + Nt Nt~ = I``::

      Z:  A Z + Z A^T - (Z C^T + B D^T) Rt^-1 (C Z + D B^T) + B B^T = 0
      H = -(Z C^T + B D^T) Rt^-1
      [Nt, Mt] = (A + H C, [B + H D, H], Rt^-1/2 C, [Rt^-1/2 D, Rt^-1/2])

(the cross-term forms of ZDG's Riccati equations of the normalized factors, solved by
``scipy.linalg.solve_continuous_are``).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ...errors import SynthesisError

__all__ = ["ncf_riccati", "right_ncf", "left_ncf"]


def _inv_sqrt(M: np.ndarray) -> np.ndarray:
    ev, V = np.linalg.eigh(M)
    return (V / np.sqrt(ev)) @ V.T


def ncf_riccati(A, B, C, D) -> tuple[np.ndarray, np.ndarray]:
    """``(X, Z)``: the control and filter Riccati solutions of the normalized coprime factorizations.

    ``X`` solves the equation of the right factors and ``Z`` that of the left factors (see the
    module docstring; these are also the two Riccati equations of Glover-McFarlane loop shaping).
    """
    p, m = D.shape
    R = np.eye(m) + D.T @ D
    Rt = np.eye(p) + D @ D.T
    try:
        # X: A^T X + X A - (X B + C^T D) R^-1 (B^T X + D^T C) + C^T C = 0
        X = scipy.linalg.solve_continuous_are(A, B, C.T @ C, R, s=C.T @ D)
        # Z: A Z + Z A^T - (Z C^T + B D^T) Rt^-1 (C Z + D B^T) + B B^T = 0
        Z = scipy.linalg.solve_continuous_are(A.T, C.T, B @ B.T, Rt, s=B @ D.T)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise SynthesisError(
            "no normalized coprime factorization: the Riccati equations have no stabilising solution "
            f"({exc}). "
            "The system must be stabilisable and detectable (no hidden unstable or undamped modes)."
        ) from exc
    return (X + X.T) / 2, (Z + Z.T) / 2


def right_ncf(A, B, C, D, X: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """``(Af, Bf, Cf, Df)`` of ``[M; N]`` (outputs: the m rows of M, then the p rows of N)."""
    if X is None:
        X, _ = ncf_riccati(A, B, C, D)
    m = D.shape[1]
    R = np.eye(m) + D.T @ D
    F = -np.linalg.solve(R, B.T @ X + D.T @ C)
    Ri = _inv_sqrt(R)
    return A + B @ F, B @ Ri, np.vstack([F, C + D @ F]), np.vstack([Ri, D @ Ri])


def left_ncf(A, B, C, D, Z: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """``(Af, Bf, Cf, Df)`` of ``[Nt, Mt]`` (inputs: the m inputs of Nt, then the p of Mt)."""
    if Z is None:
        _, Z = ncf_riccati(A, B, C, D)
    p = D.shape[0]
    Rt = np.eye(p) + D @ D.T
    H = -np.linalg.solve(Rt, C @ Z + D @ B.T).T
    Rti = _inv_sqrt(Rt)
    return A + H @ C, np.hstack([B + H @ D, H]), Rti @ C, np.hstack([Rti @ D, Rti])
