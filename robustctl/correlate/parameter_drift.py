"""Drift tests of an update: the noise covariance of the fitted parameters, the chi-square test
of a parameter move (:func:`move_test`) and the per-band drift of the fitted values."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .optimize import LMResult
from .residual import (
    Residual,
)
from .verdict import ALPHA


# ---------------------------------------------------------------------------- drift
@dataclass(frozen=True)
class Drift:
    """Sub-band estimates of one parameter (model-form check).

    ``bands`` (Hz), ``values`` and ``std_errors`` (parameter units) per sub-band;
    ``flagged`` when two sub-bands disagree by more than ``k`` combined standard errors
    and by more than the relative floor.
    """

    name: str
    bands: tuple[tuple[float, float], ...]
    values: tuple[float, ...]
    std_errors: tuple[float, ...]
    flagged: bool


def _row_mask(residual: Residual, keep_freq: np.ndarray) -> np.ndarray:
    per_freq = residual.data.n_out * residual.data.n_in
    half = np.repeat(keep_freq, per_freq)
    return np.concatenate([half, half])


def _row_noise(residual: Residual) -> np.ndarray | None:
    """Variance of each row of the residual vector from the noise model, or None.

    A row is ``sqrt(W) Re e`` or ``sqrt(W) Im e``: variance ``W sigma^2``, inflated by the
    Satterthwaite factor of the window's bin correlation (neighbouring rows are not
    independent).
    """
    nm = residual.noise
    if nm is None:
        return None
    v = (residual.point_weights * nm.sigma**2 * nm.dof_factor).ravel()
    return np.concatenate([v, v])


def _noise_covariance(residual: Residual, fit: LMResult) -> np.ndarray | None:
    """Covariance of the fitted parameters from the noise model (parameter units), or None.

    The sandwich ``(J^T J)^-1 J^T diag(v) J (J^T J)^-1`` with ``v`` the rows' noise variances
    (Gauss-Newton estimate under heteroscedastic noise; White 1980), computed with unit-norm
    columns so parameters of very different units do not spoil the conditioning.

    Known limitation (conservative): the meat treats the rows as independent, each inflated by
    the noise-only factor ``dof_factor``. At lightly damped resonances, where the information
    is, the H1 error is mostly leakage, whose errors at neighbouring bins correlate negatively
    (about -0.35 at one bin on the Caltech truss, against +0.30 for output noise; see
    :mod:`robustctl.measure.noise`) and across the outputs of one input; the variance of ``J^T r`` over
    40 seeds was 0.12-0.84 of this meat's, and the standard errors are 1.25-2.4 x the scatter
    of the estimates over seeds (Caltech truss and the user chain of the tests). A meat from
    the residuals themselves (Newey-West over the two lags at which a Hamming window's bins
    correlate, all channels of a bin together) is right on average but, with the information in
    a few peak bins, varies by a factor of 2-3 from seed to seed.
    """
    v = _row_noise(residual)
    if v is None or not len(fit.names):
        return None
    J = np.asarray(fit.jacobian, dtype=float)
    norms = np.linalg.norm(J, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    Js = J / norms
    inv = np.linalg.pinv(Js.T @ Js)
    return inv @ ((Js * v[:, None]).T @ Js) @ inv / np.outer(norms, norms)


def _std_errors(cov: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    """Square roots of the covariance diagonal by parameter name."""
    return {n: float(np.sqrt(max(cov[k, k], 0.0))) for k, n in enumerate(names)}


def move_test(move: np.ndarray, cov: np.ndarray) -> tuple[float, int, float]:
    """Joint test of a parameter move against its noise covariance.

    Under "the initial values are the truth" a consistent estimator moves the parameters by
    ``N(0, C)``, so ``T = m^T C^+ m`` is chi-square with ``r = rank(C)`` degrees of freedom
    (Wald 1943; Seber & Wild, *Nonlinear Regression*, sec. 5.2). Individual moves of one or two
    standard errors are then expected (about 32 % of parameters exceed one SE on noise alone);
    the joint test says whether the data moved the parameters beyond that.

    Parameters
    ----------
    move : ndarray (p,)
        Updated minus initial values (parameter units).
    cov : ndarray (p, p)
        Noise covariance of the estimates (parameter units squared).

    Returns
    -------
    (T, r, p_value) : (float, int, float)
    """
    from scipy.stats import chi2

    m = np.asarray(move, dtype=float)
    scale = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    scale = np.where(scale > 0, scale, 1.0)
    c = cov / np.outer(scale, scale)  # a correlation matrix: pinv is well conditioned
    z = m / scale
    w, vec = np.linalg.eigh(0.5 * (c + c.T))
    keep = w > 1e-10 * max(float(w.max()), 1e-300)
    r = int(keep.sum())
    if r == 0:
        return 0.0, 0, 1.0
    t = float(np.sum((vec[:, keep].T @ z) ** 2 / w[keep]))
    return t, r, float(chi2.sf(t, r))


def _drift_threshold(k_sigma: float | None, n_params: int, n_bands: int, alpha: float) -> float:
    """``k_sigma``, or with a noise model the Bonferroni normal quantile over all band pairs."""
    if k_sigma is not None:
        return float(k_sigma)
    from scipy.stats import norm

    n_tests = max(n_params * n_bands * (n_bands - 1) // 2, 1)
    return float(norm.isf(alpha / (2 * n_tests)))


def _drift(
    residual: Residual,
    fit: LMResult,
    n_bands: int,
    k_sigma: float | None,
    rel_floor: float,
    alpha: float = ALPHA,
) -> tuple[Drift, ...]:
    """One Gauss-Newton step from the full-band optimum on each sub-band's rows.

    At the optimum ``x`` the sub-band estimate is ``x - (J_b^T J_b)^-1 J_b^T r_b`` to first
    order, with covariance ``s_b^2 (J_b^T J_b)^-1`` -- or, with a noise model, the sandwich
    ``(J_b^T J_b)^-1 J_b^T diag(v) J_b (J_b^T J_b)^-1`` with the rows' noise variances ``v``
    (the same noise as compare's verdicts, on the same testable points): no new model
    evaluations. Two sub-band estimates
    disagree when they differ by more than ``k`` combined standard errors, ``k`` the
    Bonferroni normal quantile at family-wise ``alpha`` when ``k_sigma`` is None.
    """
    v_rows = _row_noise(residual)
    if k_sigma is None and v_rows is None:
        k_sigma = 3.0
    k_sigma = _drift_threshold(k_sigma, len(fit.names), n_bands, alpha)
    f = residual.f_hz
    if n_bands < 2 or f.size < 4 * n_bands:
        return ()
    edges = np.array_split(np.arange(f.size), n_bands)
    est, ses, bands = [], [], []
    for idx in edges:
        keep = np.zeros(f.size, dtype=bool)
        keep[idx] = True
        rows = _row_mask(residual, keep)
        if residual.noise is not None:  # noise-dominated points say nothing (as in the verdicts)
            ok = residual.noise.testable.ravel()
            rows = rows & np.concatenate([ok, ok])
        J, r = fit.jacobian[rows], fit.vector[rows]
        norms = np.linalg.norm(J, axis=0)
        norms = np.where(norms > 0, norms, 1.0)
        Js = J / norms  # unit-norm columns: parameters of very different units
        step = -np.linalg.lstsq(Js, r, rcond=None)[0] / norms
        rr = r + J @ step
        inv = np.linalg.pinv(Js.T @ Js)
        if v_rows is None:
            s2 = float(rr @ rr) / max(J.shape[0] - J.shape[1], 1)
            cov = s2 * inv / np.outer(norms, norms)
        else:
            meat = (Js * v_rows[rows][:, None]).T @ Js
            cov = inv @ meat @ inv / np.outer(norms, norms)
        est.append(fit.x_array + step)
        ses.append(np.sqrt(np.clip(np.diag(cov), 0, None)))
        bands.append((float(f[idx[0]]), float(f[idx[-1]])))
    est, ses = np.array(est), np.array(ses)
    out = []
    for p, name in enumerate(fit.names):
        v, s = est[:, p], ses[:, p]
        ref = max(abs(fit.x[name]), 1e-300)
        # a sub-band that cannot pin the parameter to 20 % says nothing: its one linear step
        # from the full-band optimum would leave the range where the linearisation holds
        usable = s < 0.2 * ref
        flagged = False
        for i in np.flatnonzero(usable):
            for k in np.flatnonzero(usable):
                if k <= i:
                    continue
                diff = abs(v[i] - v[k])
                if diff > k_sigma * np.hypot(s[i], s[k]) and diff > rel_floor * ref:
                    flagged = True
        out.append(Drift(name, tuple(bands), tuple(map(float, v)), tuple(map(float, s)), flagged))
    return tuple(out)


