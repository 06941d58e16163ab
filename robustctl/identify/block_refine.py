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
residual is the relative one of MACE eq. 5 (``rw = sqrt(w)/|g|``). A bounded trust region
(``scipy.optimize.least_squares(method="trf")``, :func:`_solve_bounded`) with the projected
residual's exact Jacobian (:class:`_Projection`) moves the scaled parameters of
:func:`_scaled_problem` (the ones :func:`.modal_refine.refine_modes` moves for all modes at once),
converged to ``CLUSTER_TOL``.
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
    real_terms: np.ndarray | None = None,
) -> np.ndarray:
    """Columns (K, n_in, 2T + n_const + R n_in): per term ``t`` (pole ``term_pole[t]``, default one
    term per pole) the Re c and Im c columns ``u = a b + ab conj(b)``, ``v = j (a b - ab conj(b))``,
    then the constants per input (complex: two columns each; real: one), then per column ``r`` of
    ``real_terms`` (K, R) one column per input (``real_terms[:, r]`` on that input's rows: a held
    real pole's ``1/(s - p)``, whose real residue is a linear unknown); ``a``, ``ab`` are the
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
    if real_terms is not None and real_terms.shape[1]:
        held = real_terms[:, None, None, :] * np.eye(n_in)[None, :, :, None]  # (K, n_in, n_in, R)
        const.append(np.swapaxes(held, 2, 3).reshape(k, n_in, -1) + 0j)
    return np.concatenate([cols, *const], axis=-1)


#: ridge of the column-scaled Gram matrices of :func:`_gram` (relative to their unit diagonal)
GRAM_RIDGE = 1e-12
#: iterative-refinement steps of the linear coefficients in :func:`_solve`
SOLVE_REFINEMENTS = 2


def _gram(x: np.ndarray, rw2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-output Gram matrices of the weighted real basis, column-scaled with a ridge:
    ``(gs, scale)`` with ``gs[o] = S G_o S + GRAM_RIDGE I`` and ``S = diag(scale[o])``; (n_out, U, U)."""
    k, n_in, u = x.shape
    z = (np.conj(x)[:, :, :, None] * x[:, :, None, :]).reshape(k * n_in, u * u)
    w = np.transpose(rw2, (0, 2, 1)).reshape(k * n_in, -1)  # (K n_in, n_out)
    gram = (z.real.T @ w).T.reshape(-1, u, u)
    scale = 1.0 / np.sqrt(np.maximum(np.einsum("oii->oi", gram), 1e-300))
    gs = gram * scale[:, :, None] * scale[:, None, :]
    gs += GRAM_RIDGE * np.eye(gs.shape[-1])[None]
    return gs, scale


def _gram_solve(gs: np.ndarray, scale: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``G_o^{-1} rhs[o]`` with the scaled, ridged Gram of :func:`_gram`; rhs (n_out, U, ...)."""
    tail = rhs.shape[2:]
    flat = rhs.reshape(rhs.shape[0], rhs.shape[1], -1) * scale[:, :, None]
    return (np.linalg.solve(gs, flat) * scale[:, :, None]).reshape(rhs.shape[:2] + tail)


def _solve(x: np.ndarray, target: np.ndarray, rw2: np.ndarray, gram=None) -> np.ndarray:
    """Per-output weighted least squares with the ridge of :func:`_gram`: batched normal equations,
    then ``SOLVE_REFINEMENTS`` steps of iterative refinement on the residual computed from the basis
    itself, ``c += G^-1 (A^T (b - A c) - ridge c)``; returns (n_out, n_cols).

    Forming ``G = A^T A`` costs the solution ``eps cond(A)^2``: with the scaled Gram's condition up
    to the ridge's 1e12 that is 1e-4 of the coefficients, and the projected residual carried noise of
    that size, under which a trust region stalls where the path happened to be, so where round-off
    (a BLAS kernel) left it. Each refinement step contracts that error by ``eps cond(G)``, so two
    bring it to round-off of the residual (Golub & Van Loan, sec. 3.5.3 and 5.3.7)."""
    k, n_in, u = x.shape
    gs, scale = _gram(x, rw2) if gram is None else gram
    xc = np.conj(x).reshape(k * n_in, u)

    def normal_rhs(res: np.ndarray) -> np.ndarray:  # A_o^T W_o res_o, (n_out, U)
        return (xc.T @ np.transpose(rw2 * res, (0, 2, 1)).reshape(k * n_in, -1)).real.T

    coef = _gram_solve(gs, scale, normal_rhs(target)[:, :, None])[:, :, 0]
    for _ in range(SOLVE_REFINEMENTS):
        model = np.swapaxes(x @ coef.T, 1, 2)  # (K, n_out, n_in)
        rhs = normal_rhs(target - model) - GRAM_RIDGE * coef / scale**2
        coef = coef + _gram_solve(gs, scale, rhs[:, :, None])[:, :, 0]
    return coef


#: relative cost and step tolerance of a cluster's refinement: converged far below any decision
#: taken on the result (a swap kept, a block accepted), so round-off cannot move those decisions
CLUSTER_TOL = 1e-10
#: relative fall of the cost a refinement must reach for its result to replace the start: far above
#: round-off (1e-16) and far below any decision taken on the result, so that a refinement that
#: cannot improve returns its start whatever the BLAS kernel, not a round-off-different copy
ACCEPT_MARGIN = 1e-10
#: a complex pole decaying faster than this many times its frequency (damping ratio above
#: 1 - 1e-7) is no oscillation but a numerically real pole (a pole identification can leave one at
#: -1e41 with a residue of 1e32): it is held fixed, since its log-decay parameter would step
#: past exp's range and turn the Jacobian into inf and NaN.
NOT_AN_OSCILLATION = 1e3
#: smallest ``Im p`` of a refined complex pole, relative to its start's ``|p|`` (a step may not turn
#: it into a real pair or its own conjugate)
OMEGA_MIN = 1e-3
#: smallest unit of a pole's ``Im p`` in the trust region, relative to its ``|p|`` (a pole at the
#: damping bound would otherwise move in steps of 1e-6 of its frequency)
OMEGA_UNIT_MIN = 1e-4
#: cap of a cluster's trust-region residual evaluations, per nonlinear parameter (a bound on
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
    ``theta`` itself); ``real_terms`` (K, R), optional: the partial fractions ``1/(s - p_r)`` of
    held real poles, whose real residues (one per channel) are eliminated with the other linear
    unknowns (columns after the constants, :func:`_basis`; ``d X / d theta`` is 0 there)."""

    def __init__(
        self, s, target, rw, m, n_in, truncation, term_pole=None, complex_constant=True, floor=ZETA_MIN,
        real_terms=None,
    ):
        self.s, self.target, self.rw, self.rw2 = s, target, rw, rw**2
        self.m, self.n_in, self.truncation = m, n_in, truncation
        self.term_pole = np.arange(m) if term_pole is None else np.asarray(term_pole)
        self.complex_constant, self.floor = complex_constant, floor
        self.real_terms = real_terms
        self._key, self._state = None, None

    def state(self, theta: np.ndarray):
        key = theta.tobytes()
        if key != self._key:
            p, b = _unpack(theta, self.m, self.n_in, self.floor)
            terms = leaked_terms(self.s, p, self.truncation)
            x = _basis(
                self.s, p, b, terms=terms, term_pole=self.term_pole, complex_constant=self.complex_constant,
                real_terms=self.real_terms,
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

    def jacobian(self, theta: np.ndarray, free: np.ndarray | None = None) -> np.ndarray:
        """The Jacobian of :meth:`residual`; with ``free`` (bool per parameter) only those columns."""
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
        if free is not None:
            dx = dx[free]
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


def _scaled_problem(poles0: np.ndarray, bs: np.ndarray):
    """The start ``theta0`` of :class:`_Projection` (``log(-Re p)``, ``Im p``, ``Re b``,
    ``Im b``), each parameter's unit and its bounds: the solver moves ``x = (theta - theta0) /
    unit``, which starts at 0 (a trust region's first radius is then 1 unit, not the norm of the
    start: about 1e4 rad/s of ``Im p``, which let the first step send a decay to ``exp(1e4)``).
    Units: 1 for a log decay, the pole's decay ``-Re p`` (a half-power half-width, at least
    ``OMEGA_UNIT_MIN |p|``) for ``Im p``, the term's ``|b|`` for its input shape. Bounds: the
    damping ratio at least ``ZETA_MIN`` (of the start's ``|p|``) and the decay at most ``e
    NOT_AN_OSCILLATION |p|`` (``exp`` and every Jacobian term finite), ``Im p`` at least
    ``OMEGA_MIN |p|`` (a complex pole stays one). ``free`` marks the parameters the solver moves
    (all but each term's largest input-shape entry)."""
    m = poles0.size
    mag = np.abs(poles0)
    sigma = np.maximum(-poles0.real, 1e-9 * mag)  # damping kept strictly positive
    lo_t, hi_t = np.log(ZETA_MIN * mag), np.log(NOT_AN_OSCILLATION * mag) + 1.0
    log_sigma = np.clip(np.log(sigma), lo_t + 1e-12, hi_t - 1.0)
    theta0 = np.concatenate([log_sigma, poles0.imag, np.stack([bs.real, bs.imag], axis=1).ravel()])
    b_norm = np.linalg.norm(bs, axis=1)
    b_unit = np.where(b_norm > 0, b_norm, 1.0)
    omega_unit = np.maximum(sigma, OMEGA_UNIT_MIN * mag)
    unit = np.concatenate([np.ones(m), omega_unit, np.repeat(b_unit, 2 * bs.shape[1])])
    lower = np.full(theta0.size, -np.inf)
    upper = np.full(theta0.size, np.inf)
    lower[:m], upper[:m] = lo_t, hi_t
    lower[m : 2 * m] = np.minimum(OMEGA_MIN * mag, poles0.imag * (1 - 1e-9))
    # c b^T is unchanged by b -> alpha b, c -> c / alpha, and c is eliminated: each term's largest
    # input-shape entry stays as it starts, which removes that null space of the Jacobian
    free = np.ones(theta0.size, dtype=bool)
    n_in = bs.shape[1]
    for term, row in enumerate(bs):
        if np.any(row != 0):
            ref = 2 * m + 2 * term * n_in + int(np.argmax(np.abs(row)))
            free[[ref, ref + n_in]] = False
    return theta0, unit, free, (lower - theta0)[free] / unit[free], (upper - theta0)[free] / unit[free]


class _Best:
    """The residual and Jacobian of :class:`_Projection` in the scaled parameters of
    :func:`_scaled_problem`, remembering the lowest finite cost evaluated (the refinement's
    answer if the solver fails) and refusing a non-finite Jacobian (:class:`_NotFiniteError`)."""

    def __init__(self, proj: _Projection, theta0: np.ndarray, unit: np.ndarray, free: np.ndarray):
        self.proj, self.theta0, self.unit, self.free = proj, theta0, unit[free], free
        self.cost, self.x = np.inf, None

    def theta(self, x: np.ndarray) -> np.ndarray:
        theta = np.array(self.theta0)
        theta[self.free] += self.unit * x
        return theta

    def residual(self, x: np.ndarray) -> np.ndarray:
        r = self.proj.residual(self.theta(x))
        cost = float(r @ r)
        if np.isfinite(cost) and np.all(r != NOT_FINITE) and cost < self.cost:
            self.cost, self.x = cost, np.array(x)
        return r

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        jac = self.proj.jacobian(self.theta(x), self.free)
        jac *= self.unit
        if not np.all(np.isfinite(jac)):
            raise _NotFiniteError
        return jac


class _NotFiniteError(ArithmeticError):
    """A Jacobian entry overflowed: the solver stops and the best point so far is kept."""


def _solve_bounded(
    proj: _Projection, poles0: np.ndarray, bs: np.ndarray, max_nfev: int, before: float, tol: float
):
    """The trust-region solve (``least_squares(method="trf")``, relative cost, step and gradient
    tolerance ``tol``) of :func:`refine_cluster` and :func:`.modal_refine.refine_modes` in the
    scaled, bounded parameters of :func:`_scaled_problem`; the refined ``theta`` of
    :class:`_Projection` (built with ``floor=0``), or ``None``
    when nothing lowers the starting ``before`` cost by ``ACCEPT_MARGIN`` (relative). A solver
    failure (a non-finite Jacobian, an SVD that does not converge) keeps the lowest-cost point it
    evaluated."""
    theta0, unit, free, lb, ub = _scaled_problem(poles0, bs)
    best = _Best(proj, theta0, unit, free)
    x0 = np.zeros(lb.size)
    if not np.all(np.isfinite(best.residual(x0))):
        return None
    try:
        # unit scaling, not x_scale="jac": near the damping bound the log-decay column vanishes
        # with exp(theta), and a Jacobian-scaled trust region then lets that pole jump to the bound
        # or not as round-off decides (the two-mode fit's spare pole: 15.09 Hz or 15.53 Hz)
        sol = least_squares(
            best.residual,
            x0,
            jac=best.jacobian,
            bounds=(lb, ub),
            method="trf",
            x_scale=1.0,
            max_nfev=max_nfev,
            ftol=tol,
            xtol=tol,
            gtol=tol,
        )
        x = sol.x if np.all(np.isfinite(sol.fun)) and np.all(sol.fun != NOT_FINITE) else best.x
    except (_NotFiniteError, np.linalg.LinAlgError, ValueError):
        x = best.x
    if x is None:
        return None
    r = best.residual(x)
    finite = np.all(np.isfinite(r)) and np.all(r != NOT_FINITE)
    if not (finite and float(r @ r) < before * (1 - ACCEPT_MARGIN)):
        return None
    return best.theta(x)


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
    proj = _Projection(s, target, rw, m, n_in, truncation, floor=0.0)
    n_par = 2 * m * (1 + n_in)
    if 2 * target.size <= n_par:
        return poles, cs, bs, 0.0, 0.0
    # the start's own cost (output shapes and constants re-fitted to its poles and input shapes)
    decay = np.maximum(-poles.real, np.finfo(float).tiny)
    start = np.concatenate([np.log(decay), poles.imag, np.stack([bs.real, bs.imag], axis=1).ravel()])
    r0 = proj.residual(start)
    before = float(r0 @ r0)
    if not (np.isfinite(before) and np.all(r0 != NOT_FINITE)):
        return poles, cs, bs, before, before
    cap = max_nfev if max_nfev is not None else MAX_ITER_PER_PARAM * n_par
    theta = _solve_bounded(proj, poles, bs, cap, before, CLUSTER_TOL)
    if theta is None:
        return poles, cs, bs, before, before
    r = proj.residual(theta)
    p, b, _, _, _, coef, _ = proj.state(theta)
    if not np.all(np.isfinite(coef)):
        return poles, cs, bs, before, before
    c = coef[:, : 2 * m].reshape(-1, m, 2)
    c = (c[:, :, 0] + 1j * c[:, :, 1]).T  # (M, n_out)
    return p, c, b, before, float(r @ r)
