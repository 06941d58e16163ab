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
residual is the relative one of MACE eq. 5 (``rw = sqrt(w)/|g|``). Levenberg-Marquardt
(``scipy.optimize.least_squares(method="lm")``) with the projected residual's exact Jacobian
(:class:`_Projection`), converged to ``CLUSTER_TOL``.
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
#: each residual entry where a parameter vector makes the projected residual inf or NaN: finite,
#: and its cost far above any start's, so the solver rejects that step and shrinks its region
NOT_FINITE = 1e150

__all__ = ["refine_cluster"]


def _basis(
    s: np.ndarray,
    poles: np.ndarray,
    bs: np.ndarray,
    truncation: Any = None,
    terms=None,
    term_pole: np.ndarray | None = None,
    complex_constant: bool = True,
) -> np.ndarray:
    """Columns (K, n_in, 2T + n_const): per term ``t`` (pole ``term_pole[t]``, default one term per
    pole) the Re c and Im c columns ``u = a b + ab conj(b)``, ``v = j (a b - ab conj(b))``, then
    the constants per input (complex: two columns each; real: one); ``a``, ``ab`` are the
    truncated record's terms with ``truncation`` (eq. T1); ``terms`` are
    :func:`.tail.leaked_terms` of ``poles`` when already computed."""
    a, ab, _, _ = leaked_terms(s, poles, truncation) if terms is None else terms  # (K, M)
    if term_pole is not None:
        a, ab = a[:, term_pole], ab[:, term_pole]
    u = a[:, None, :] * bs.T[None] + ab[:, None, :] * np.conj(bs.T)[None]  # (K, n_in, T)
    v = 1j * (a[:, None, :] * bs.T[None] - ab[:, None, :] * np.conj(bs.T)[None])
    k, n_in = s.size, bs.shape[1]
    cols = np.stack([u, v], axis=-1).reshape(k, n_in, -1)
    eye = np.broadcast_to(np.eye(n_in)[None], (k, n_in, n_in))
    const = [eye + 0j, 1j * eye] if complex_constant else [eye + 0j]
    return np.concatenate([cols, *const], axis=-1)


def _gram(x: np.ndarray, rw2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-output Gram matrices of the weighted real basis, column-scaled with a 1e-12 ridge:
    ``(gs, scale)`` with ``gs[o] = S G_o S + 1e-12 I`` and ``S = diag(scale[o])``; (n_out, U, U)."""
    k, n_in, u = x.shape
    z = (np.conj(x)[:, :, :, None] * x[:, :, None, :]).reshape(k * n_in, u * u)
    w = np.transpose(rw2, (0, 2, 1)).reshape(k * n_in, -1)  # (K n_in, n_out)
    gram = (z.real.T @ w).T.reshape(-1, u, u)
    scale = 1.0 / np.sqrt(np.maximum(np.einsum("oii->oi", gram), 1e-300))
    gs = gram * scale[:, :, None] * scale[:, None, :]
    gs += 1e-12 * np.eye(gs.shape[-1])[None]
    return gs, scale


def _gram_solve(gs: np.ndarray, scale: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``G_o^{-1} rhs[o]`` with the scaled, ridged Gram of :func:`_gram`; rhs (n_out, U, ...)."""
    tail = rhs.shape[2:]
    flat = rhs.reshape(rhs.shape[0], rhs.shape[1], -1) * scale[:, :, None]
    return (np.linalg.solve(gs, flat) * scale[:, :, None]).reshape(rhs.shape[:2] + tail)


def _solve(x: np.ndarray, target: np.ndarray, rw2: np.ndarray, gram=None) -> np.ndarray:
    """Per-output weighted least squares, batched normal equations; returns (n_out, n_cols)."""
    k, n_in, u = x.shape
    gs, scale = _gram(x, rw2) if gram is None else gram
    xc = np.conj(x).reshape(k * n_in, u)
    rhs = (xc.T @ np.transpose(rw2 * target, (0, 2, 1)).reshape(k * n_in, -1)).real.T
    return _gram_solve(gs, scale, rhs[:, :, None])[:, :, 0]


#: relative cost and step tolerance of a cluster's refinement: converged far below any decision
#: taken on the result (a swap kept, a block accepted), so round-off cannot move those decisions
CLUSTER_TOL = 1e-10
#: relative fall of the cost a refinement must reach for its result to replace the start: far above
#: round-off (1e-16) and far below any decision taken on the result, so that a refinement that
#: cannot improve returns its start whatever the BLAS kernel, not a round-off-different copy
ACCEPT_MARGIN = 1e-10
#: cap of a cluster's Levenberg-Marquardt residual evaluations, per nonlinear parameter (a bound on
#: the work, not the stopping rule: the refinement stops at CLUSTER_TOL)
MAX_ITER_PER_PARAM = 40


def _decay(theta: np.ndarray, omega: np.ndarray, floor: float = ZETA_MIN) -> np.ndarray:
    """``-Re p = ZETA_MIN |Im p| + exp(theta)``: the damping ratio stays above ``ZETA_MIN`` (the
    dense refinement's bound) for every ``theta``, so a step can never leave a marginal pole
    (``exp`` of a large negative ``theta`` underflows to 0 and gave ``Re p = 0``)."""
    return floor * np.abs(omega) + np.exp(np.minimum(theta, LOG_DECAY_MAX))


def _unpack(theta: np.ndarray, m: int, n_in: int, floor: float = ZETA_MIN):
    """Poles (``m``) and input shapes (one row per term) of the parameter vector; ``-Re p =
    floor |Im p| + exp(theta)`` (:func:`_decay`)."""
    omega = theta[m : 2 * m]
    poles = -_decay(theta[:m], omega, floor) + 1j * omega
    b = theta[2 * m :].reshape(-1, 2, n_in)
    return poles, b[:, 0] + 1j * b[:, 1]


def _column_derivatives(
    terms, bs: np.ndarray, term_pole: np.ndarray, dpole: tuple, n_cols: int
) -> np.ndarray:
    """``d X / d theta_j`` for every parameter ``j`` (parameters in the order of :func:`_unpack`:
    ``log`` decays, ``Im p``, then per term ``Re b`` and ``Im b``), (n_par, K, n_in, n_cols).

    A pole parameter moves ``a = 1/(s - p)`` by ``da dp`` and ``ab = 1/(s - conj p)`` by
    ``dab d conj(p)`` in the columns of every term of that pole (``dpole``: ``(dp, d conj p)``
    per pole for ``theta`` and for ``Im p``); an input shape entry ``b_i`` of a term moves only
    input ``i``'s rows of its columns ``u = a b + ab conj(b)`` and ``v = j (a b - ab conj(b))``."""
    a, ab, da, dab = terms  # (K, M)
    m = a.shape[1]
    t, n_in = bs.shape
    k = a.shape[0]
    out = np.zeros((2 * m + 2 * t * n_in, k, n_in, n_cols), dtype=complex)
    cols = 2 * np.arange(t)
    for q, (fp, fq) in enumerate(dpole):
        ea, eab = (da * fp[None])[:, term_pole], (dab * fq[None])[:, term_pole]  # (K, T)
        pa = ea[:, None, :] * bs.T[None]  # (K, n_in, T)
        pb = eab[:, None, :] * np.conj(bs.T)[None]
        rows = q * m + term_pole
        out[rows, :, :, cols] = np.moveaxis(pa + pb, -1, 0)
        out[rows, :, :, cols + 1] = np.moveaxis(1j * (pa - pb), -1, 0)
    plus, minus = (a + ab)[:, term_pole].T, (a - ab)[:, term_pole].T  # (T, K)
    for term in range(t):
        base = 2 * m + 2 * term * n_in
        for i in range(n_in):
            out[base + i, :, i, 2 * term], out[base + i, :, i, 2 * term + 1] = plus[term], 1j * minus[term]
            out[base + n_in + i, :, i, 2 * term] = 1j * minus[term]  # Im b_i
            out[base + n_in + i, :, i, 2 * term + 1] = -plus[term]
    return out


class _Projection:
    """The variable-projection residual of a set of terms and its exact Jacobian (Golub & Pereyra 1973).

    For poles and input shapes ``theta`` the weighted basis ``A_o = rw_o X`` of output ``o`` gives
    the linear coefficients ``c_o = A_o^+ b_o`` and the projected residual ``r_o = A_o c_o - b_o``
    (real-stacked rows). Its derivative is

        d r_o / d theta_j = P_o^perp (dA_o/dtheta_j) c_o - (A_o^+)^T (dA_o/dtheta_j)^T r_o
                          = v_j - A_o G_o^{-1} (A_o^T v_j + (dA_o/dtheta_j)^T r_o),

    with ``v_j = (dA_o/dtheta_j) c_o`` and ``G_o = A_o^T A_o`` (the Gram of the residual's own
    solve, same scaling and ridge). Both terms are kept (Kaufman's approximation drops the
    second), so the Jacobian is the residual's derivative to round-off and the finite differences
    of the residual check it. Each Jacobian costs about two residual evaluations, against
    ``n_par`` for finite differences. The state of the last ``theta`` is kept, since the solver
    asks for the residual and the Jacobian at the same point.

    ``term_pole`` maps terms to poles (several terms share a pole of rank above 1; default one
    term per pole); ``complex_constant`` chooses a complex constant per channel (a cluster's local
    constant) or a real one (the model's feedthrough ``D``); ``floor`` the damping ratio below the
    decay ``exp(theta)`` (:func:`_decay`; 0: ``-Re p = exp(theta)``, for a solver that bounds
    ``theta`` itself)."""

    def __init__(
        self, s, target, rw, m, n_in, truncation, term_pole=None, complex_constant=True, floor=ZETA_MIN
    ):
        self.s, self.target, self.rw, self.rw2 = s, target, rw, rw**2
        self.m, self.n_in, self.truncation = m, n_in, truncation
        self.term_pole = np.arange(m) if term_pole is None else np.asarray(term_pole)
        self.complex_constant, self.floor = complex_constant, floor
        self._key, self._state = None, None

    def state(self, theta: np.ndarray):
        key = theta.tobytes()
        if key != self._key:
            p, b = _unpack(theta, self.m, self.n_in, self.floor)
            terms = leaked_terms(self.s, p, self.truncation)
            x = _basis(
                self.s, p, b, terms=terms, term_pole=self.term_pole, complex_constant=self.complex_constant
            )
            gram = _gram(x, self.rw2)
            coef = _solve(x, self.target, self.rw2, gram)
            model = np.swapaxes(x @ coef.T, 1, 2)  # (K, n_out, n_in)
            self._key, self._state = key, (p, b, terms, x, gram, coef, model)
        return self._state

    def residual(self, theta: np.ndarray) -> np.ndarray:
        """The projected residual; at a ``theta`` where it is not finite (a singular projection, an
        overflow), ``NOT_FINITE`` in every entry, so that a solver's step there fails its cost test
        and the region shrinks (its Jacobian is never asked for there)."""
        model = self.state(theta)[-1]
        r = self.rw * (model - self.target)
        r = np.concatenate([r.real.ravel(), r.imag.ravel()])
        return r if np.all(np.isfinite(r)) else np.full(r.size, NOT_FINITE)

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        p, b, terms, x, (gs, scale), coef, model = self.state(theta)
        m = self.m
        omega = theta[m : 2 * m]
        clamped = theta[:m] >= LOG_DECAY_MAX  # d Re p / d theta is 0 there (not inf * 0)
        dsigma = np.where(clamped, 0.0, -np.exp(np.minimum(theta[:m], LOG_DECAY_MAX)))
        tilt = -self.floor * np.sign(omega)
        k, n_in, u = x.shape
        dx = _column_derivatives(
            terms, b, self.term_pole, ((dsigma + 0j, dsigma + 0j), (tilt + 1j, tilt - 1j)), u
        )
        n_par, n_out = dx.shape[0], coef.shape[0]
        flat = dx.reshape(n_par, k * n_in, u)
        delta = (flat @ coef.T).reshape(n_par, k, n_in, n_out)  # d(X c_o)/d theta_j
        delta = np.transpose(delta, (3, 1, 2, 0))  # (n_out, K, n_in, J)
        rho = np.transpose(self.rw2 * (model - self.target), (0, 2, 1)).reshape(k * n_in, n_out)
        w = (np.conj(np.swapaxes(flat, 1, 2)) @ rho).real  # (dA_j/dtheta)^T r: (J, U, n_out)
        w = np.transpose(w, (2, 1, 0))  # (n_out, U, J)
        xf = x.reshape(k * n_in, u)
        weighted = (np.transpose(self.rw2, (1, 0, 2))[..., None] * delta).reshape(n_out, k * n_in, n_par)
        z = (np.conj(xf).T @ weighted).real  # A_o^T v_j, (n_out, U, J)
        y = _gram_solve(gs, scale, z + w)
        jac = (delta - (xf @ y).reshape(n_out, k, n_in, n_par)) * np.transpose(self.rw, (1, 0, 2))[..., None]
        jac = np.transpose(jac, (1, 0, 2, 3)).reshape(-1, n_par)  # rows as the residual's (K, n_out, n_in)
        return np.concatenate([jac.real, jac.imag])


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
        Cap of residual evaluations (default ``MAX_ITER_PER_PARAM`` per nonlinear parameter); the
        refinement stops at ``CLUSTER_TOL`` well before it.
    truncation : TruncationSettings, optional
        Fit the truncated record's terms (eq. T1 of :mod:`.leakage`) to raw impact data.

    Returns
    -------
    poles, cs, bs, cost_before, cost_after
    """
    m, n_in = bs.shape
    rw2 = rw**2
    proj = _Projection(s, target, rw, m, n_in, truncation)

    floor = ZETA_MIN * np.abs(poles.imag)
    sigma = np.maximum(-poles.real - floor, floor)
    log_sigma = np.log(np.maximum(sigma, np.finfo(float).tiny))
    theta0 = np.concatenate([log_sigma, poles.imag, np.stack([bs.real, bs.imag], axis=1).ravel()])
    r0 = proj.residual(theta0)
    n_res = r0.size
    if n_res <= theta0.size:
        return poles, cs, bs, 0.0, 0.0
    cap = max_nfev if max_nfev is not None else MAX_ITER_PER_PARAM * theta0.size
    sol = least_squares(
        proj.residual,
        theta0,
        jac=proj.jacobian,
        method="lm",
        x_scale="jac",
        max_nfev=cap,
        ftol=CLUSTER_TOL,
        xtol=CLUSTER_TOL,
        gtol=CLUSTER_TOL,
    )
    before, after = float(r0 @ r0), float(sol.fun @ sol.fun)
    if not (np.all(np.isfinite(sol.x)) and after < before * (1 - ACCEPT_MARGIN)):
        return poles, cs, bs, before, before
    p, b = _unpack(sol.x, m, n_in)
    coef = _solve(_basis(s, p, b, truncation), target, rw2)
    if not np.all(np.isfinite(coef)):
        return poles, cs, bs, before, before
    c = coef[:, : 2 * m].reshape(-1, m, 2)
    c = (c[:, :, 0] + 1j * c[:, :, 1]).T  # (M, n_out)
    return p, c, b, before, after
