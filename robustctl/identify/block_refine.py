"""Variable-projection refinement of one cluster of modes on the frequencies around it.

For a cluster of ``M`` neighbouring modes with rank-1 residues ``c_m b_m^T`` (Caltech eq. 9),
the model on the cluster's frequencies is

    g_oi(s) = sum_m [c_om b_mi / (s - p_m) + conj(c_om b_mi) / (s - conj p_m)] + e_oi + fixed_oi(s),

with ``fixed`` the other modes' terms (held) and ``e`` a local constant per channel that absorbs
their error. For given poles ``p`` and input shapes ``b`` it is linear in the output shapes
``c_o`` and ``e_o`` of every output ``o`` separately, so those are eliminated (Golub & Pereyra
1973, variable projection): the nonlinear problem has only ``2 M (1 + n_in)`` unknowns
(``log(-Re p)``, ``Im p``, ``Re b``, ``Im b``), whatever the number of outputs, and each
residual evaluation is one batched solve of ``n_out`` small normal-equation systems. The
residual is the relative one of MACE eq. 5 (``rw = sqrt(w)/|g|``). Levenberg-Marquardt with a
finite-difference Jacobian (``scipy.optimize.least_squares(method="lm")``), converged to
``CLUSTER_TOL``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import least_squares

from .tail import leaked_terms

#: smallest damping ratio a refined mode may take (keeps the model strictly stable; not a
#: judgement on the mode: very lightly damped modes are real in bolted and welded structures)
ZETA_MIN = 1e-6
#: largest ``theta`` of the decay rate ``exp(theta)``, 1/s (keeps ``exp`` finite for any step)
LOG_DECAY_MAX = 700.0

__all__ = ["refine_cluster"]


def _basis(s: np.ndarray, poles: np.ndarray, bs: np.ndarray, truncation: Any = None) -> np.ndarray:
    """Columns (K, n_in, 2M + 2 n_in): per mode the Re c and Im c columns, then the complex constants
    (the truncated record's terms with ``truncation``, eq. T1)."""
    a, ab, _, _ = leaked_terms(s, poles, truncation)  # (K, M)
    u = a[:, None, :] * bs.T[None] + ab[:, None, :] * np.conj(bs.T)[None]  # (K, n_in, M)
    v = 1j * (a[:, None, :] * bs.T[None] - ab[:, None, :] * np.conj(bs.T)[None])
    k, n_in = s.size, bs.shape[1]
    cols = np.stack([u, v], axis=-1).reshape(k, n_in, -1)
    eye = np.broadcast_to(np.eye(n_in)[None], (k, n_in, n_in))
    return np.concatenate([cols, eye + 0j, 1j * eye], axis=-1)


def _solve(x: np.ndarray, target: np.ndarray, rw2: np.ndarray) -> np.ndarray:
    """Per-output weighted least squares, batched normal equations; returns (n_out, n_cols)."""
    k, n_in, u = x.shape
    z = (np.conj(x)[:, :, :, None] * x[:, :, None, :]).reshape(k * n_in, u * u)
    w = np.transpose(rw2, (0, 2, 1)).reshape(k * n_in, -1)  # (K n_in, n_out)
    gram = (z.real.T @ w).T.reshape(-1, u, u)
    xc = np.conj(x).reshape(k * n_in, u)
    rhs = (xc.T @ np.transpose(rw2 * target, (0, 2, 1)).reshape(k * n_in, -1)).real.T
    scale = 1.0 / np.sqrt(np.maximum(np.einsum("oii->oi", gram), 1e-300))
    gs = gram * scale[:, :, None] * scale[:, None, :]
    gs += 1e-12 * np.eye(gs.shape[-1])[None]
    return np.linalg.solve(gs, (rhs * scale)[:, :, None])[:, :, 0] * scale


#: relative cost and step tolerance of a cluster's refinement: converged far below any decision
#: taken on the result (a swap kept, a block accepted), so round-off cannot move those decisions
CLUSTER_TOL = 1e-10
#: cap of a cluster's Levenberg-Marquardt iterations, per nonlinear parameter (a bound on the work;
#: the Jacobian's finite differences are counted apart)
MAX_ITER_PER_PARAM = 40


def _decay(theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``-Re p = ZETA_MIN |Im p| + exp(theta)``: the damping ratio stays above ``ZETA_MIN`` (the
    dense refinement's bound) for every ``theta``, so a step can never leave a marginal pole
    (``exp`` of a large negative ``theta`` underflows to 0 and gave ``Re p = 0``)."""
    return ZETA_MIN * np.abs(omega) + np.exp(np.minimum(theta, LOG_DECAY_MAX))


def _unpack(theta: np.ndarray, m: int, n_in: int):
    omega = theta[m : 2 * m]
    poles = -_decay(theta[:m], omega) + 1j * omega
    b = theta[2 * m :].reshape(m, 2, n_in)
    return poles, b[:, 0] + 1j * b[:, 1]


def refine_cluster(
    s: np.ndarray,
    target: np.ndarray,
    rw: np.ndarray,
    poles: np.ndarray,
    cs: np.ndarray,
    bs: np.ndarray,
    max_nfev: int | None = None,
    truncation: Any = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Refine a cluster's poles and shapes by variable projection.

    Parameters
    ----------
    s : ndarray, complex, shape (K,)
        Laplace variable of the cluster's frequencies, rad/s.
    target : ndarray, complex, shape (K, n_out, n_in)
        Data minus the other modes' terms.
    rw : ndarray, shape (K, n_out, n_in)
        Relative row weights of the full data.
    poles : ndarray, complex, shape (M,)
        Starting poles (``Im p > 0``, ``Re p < 0``), rad/s.
    cs : ndarray, complex, shape (M, n_out)
        Starting output shapes (only the starting cost uses them).
    bs : ndarray, complex, shape (M, n_in)
        Starting input shapes.
    max_nfev : int, optional
        Cap of residual evaluations, the finite-difference Jacobian's included (default
        ``MAX_ITER_PER_PARAM`` iterations per parameter); the refinement stops at ``CLUSTER_TOL``.
    truncation : TruncationSettings, optional
        Fit the truncated record's terms (eq. T1 of :mod:`.leakage`) to raw impact data.

    Returns
    -------
    poles, cs, bs, cost_before, cost_after
    """
    m, n_in = bs.shape
    rw2 = rw**2

    def resid(theta):
        p, b = _unpack(theta, m, n_in)
        x = _basis(s, p, b, truncation)
        coef = _solve(x, target, rw2)
        model = np.swapaxes(x @ coef.T, 1, 2)  # (K, n_out, n_in)
        r = rw * (model - target)
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    floor = ZETA_MIN * np.abs(poles.imag)
    sigma = np.maximum(-poles.real - floor, floor)
    log_sigma = np.log(np.maximum(sigma, np.finfo(float).tiny))
    theta0 = np.concatenate([log_sigma, poles.imag, np.stack([bs.real, bs.imag], axis=1).ravel()])
    r0 = resid(theta0)
    n_res = r0.size
    if n_res <= theta0.size:
        return poles, cs, bs, 0.0, 0.0
    cap = max_nfev if max_nfev is not None else MAX_ITER_PER_PARAM * theta0.size * (theta0.size + 1)
    sol = least_squares(resid, theta0, method="lm", x_scale="jac", max_nfev=cap, ftol=CLUSTER_TOL,
                        xtol=CLUSTER_TOL, gtol=CLUSTER_TOL)
    before, after = float(r0 @ r0), float(sol.fun @ sol.fun)
    if not after < before:
        return poles, cs, bs, before, before
    p, b = _unpack(sol.x, m, n_in)
    coef = _solve(_basis(s, p, b, truncation), target, rw2)
    c = coef[:, : 2 * m].reshape(-1, m, 2)
    c = (c[:, :, 0] + 1j * c[:, :, 1]).T  # (M, n_out)
    return p, c, b, before, after
