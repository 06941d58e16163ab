"""``fit_rational``: common-denominator rational fits of SIMO/MIMO frequency responses.

Poles come from the Chebyshev/Sanathanan-Koerner iteration of the Caltech paper
(``method="chebyshev"``) or from relaxed vector fitting (``method="vf"``); both share the same
validation, stability enforcement (reflection of unstable poles) and final linear
identification of residues, and both return a :class:`RationalFit` that converts to a real
modal state space with named signals.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ..budget import Deadline, as_deadline
from ..checks import UNSET, flag, positive_number, renamed_keyword
from ..errors import FitError
from ..lti import pole_frequency_damping
from ..threads import limit_blas
from ._problem import FitProblem, as_frequency_data, prepare_problem
from .chebyshev import chebyshev_poles
from .grouping import combine_simo
from .poles import fit_residues, reflect_unstable
from .rational_fit import IdentifyWarning, RationalFit
from .realization import residue_rank
from .vector_fitting import vf_poles

__all__ = ["RationalFit", "fit_rational", "IdentifyWarning"]

METHODS = ("chebyshev", "vf")
DEFAULT_MAX_ITER = {"chebyshev": 100, "vf": 30}


# --------------------------------------------------------------------------- fitting
def _pole_kernel(
    prob: FitProblem,
    method: str,
    max_iter: int,
    tol: float,
    stable: bool,
    deadline: Deadline | None = None,
    start_poles: str = "lin",
) -> tuple[np.ndarray, int, bool]:
    w_s = float(np.max(np.abs(prob.s)))
    k = prob.s.size
    g = prob.g.reshape(k, -1)
    rw = np.sqrt(prob.w.reshape(k, -1)) / np.abs(g)
    if method == "chebyshev":
        poles, iters, ok = chebyshev_poles(
            prob.s / w_s, g, rw, prob.order, max_iter=max_iter, tol=tol, stable=stable
        )
    else:
        poles, iters, ok = vf_poles(
            prob.s / w_s, g, rw, prob.order, max_iter=max_iter, tol=tol, stable=stable, deadline=deadline,
            spacing=start_poles,
        )
    return poles * w_s, iters, ok


def _warn_out_of_band(poles: np.ndarray, band: tuple[float, float]) -> None:
    f = pole_frequency_damping(poles)[0]
    out = f[(f < band[0]) | (f > band[1])]
    if out.size:
        warnings.warn(
            f"{out.size} fitted pole(s) lie outside the band {band[0]:.4g}-{band[1]:.4g} Hz "
            f"(natural frequencies {np.array2string(out, precision=4)} Hz); they model out-of-band "
            "dynamics or noise. Lower the order or widen the band if they are not wanted.",
            IdentifyWarning,
            stacklevel=4,
        )


def _check_method(method: str) -> str:
    if method not in METHODS:
        raise FitError(f"unknown method {method!r}; use one of {METHODS}.")
    return method


def _check_iter(max_iter: Any) -> int:
    if isinstance(max_iter, (bool, np.bool_)) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise FitError(f"max_iter must be a positive integer iteration cap; got {max_iter!r}.")
    return int(max_iter)


def _fit_simo_each(data: Any, order: int, band: Any, weights: Any, **kw: Any) -> RationalFit:
    """One SIMO fit per input column (own denominator each), joined by :func:`combine_simo`."""
    from ..checks import point_weights  # the name of fit_rational's parameter: kept local

    fd = as_frequency_data(data)
    if weights is not None and not isinstance(weights, str):
        weights = point_weights(weights, fd)
    fits = []
    for j, name in enumerate(fd.inputs):
        wj = weights[:, :, j : j + 1] if isinstance(weights, np.ndarray) else weights
        fits.append(fit_rational(fd.select(inputs=[name]), order, band, point_weights=wj, **kw))
    return combine_simo(fits)


@limit_blas
def _check_tolerances(tol: Any, rank_tol: Any) -> tuple[float, float]:
    """``tol`` > 0 (relative pole change that stops the iteration) and ``0 <= rank_tol < 1``
    (singular values below ``rank_tol`` times the largest do not count in a residue's rank)."""
    tol = positive_number(tol, "tol", FitError)
    rank_tol = positive_number(rank_tol, "rank_tol", FitError, allow_zero=True)
    if rank_tol >= 1:
        raise FitError(
            f"rank_tol is relative to the largest singular value: give 0 <= rank_tol < 1; got {rank_tol!r}."
        )
    return tol, rank_tol


def _check_scale(g: np.ndarray) -> None:
    """Refuse responses whose magnitudes the fit's squares would overflow or underflow."""
    mag = np.abs(g[g != 0])
    if mag.size == 0:
        raise FitError("the response is zero at every point in the band; there is nothing to fit.")
    lo, hi = float(mag.min()), float(mag.max())
    if lo < 1e-150 or hi > 1e150:
        raise FitError(
            f"the response magnitudes span {lo:.3g} to {hi:.3g}; their squares leave the floating-point "
            "range. Rescale the data (other units, e.g. mm instead of m) to magnitudes near 1."
        )


def fit_rational(
    data: Any,
    order: int,
    band: tuple[float, float] | None = None,
    method: str = "vf",
    point_weights: Any = "auto",
    common_denominator: bool = True,
    stable: bool = True,
    max_iter: int | None = None,
    tol: float = 1e-6,
    feedthrough: bool = True,
    rank_tol: float = 1e-8,
    time_budget_s: float | None = None,
    *,
    start_poles: str = "lin",
    weights: Any = UNSET,
) -> RationalFit:
    """Fit a rational model with one common denominator to SIMO/MIMO frequency-response data.

    Parameters
    ----------
    data : FrequencyData, control.FrequencyResponseData or (f_hz, response)
        Measured response, shape (n_freq, n_out, n_in), frequencies in Hz.
    order : int
        Number of poles counting conjugates: ``2 * n_modes`` for ``n_modes`` lightly damped
        modes (an odd order adds one real pole). Numerators are proper (same degree).
    band : (f_lo, f_hi), optional
        Fitted band in Hz (default: all the data).
    method : {"vf", "chebyshev"}
        ``"vf"`` (default): relaxed vector fitting with pole flipping, QR-compressed per
        channel. ``"chebyshev"``: Caltech eq. 4 with Chebyshev bases and the SK re-weighting of
        steps 1-6; it agrees with VF on narrow bands (0.5-5.5 Hz) but SK stalls in poorer
        fixed points on wide bands with spare poles (Caltech truss 0.5-30 Hz: 1.0 dB vs 0.44 dB).
    point_weights : "auto", None, "coherence" or array_like
        Data-point weights on the squared residuals (:func:`robustctl.checks.point_weights`):
        ``"auto"`` (default) the coherence weights ``g2/(1-g2)`` (capped at 0.999, mean 1)
        when the data carry coherence, else 1; an array of shape (n_freq,) or (n_freq, n_out,
        n_in). Each row is further normalised by ``|g|`` (and by ``|d|`` in the SK loop) so
        the fit has constant relative accuracy in log magnitude and phase. ``weights=`` is the
        deprecated name.
    weights
        Deprecated name of ``point_weights``.
    common_denominator : bool
        ``True``: one denominator for all channels. ``False``: one per input column (SIMO
        fits, the Caltech procedure), joined by :func:`combine_simo`.
    stable : bool
        Reflect unstable poles into the left half plane before the residues are fitted.
    max_iter : int, optional
        Cap of pole-relocation iterations; default 100 for ``"chebyshev"`` (the SK fixed point
        is reached slowly when modes nearly coincide) and 30 for ``"vf"``.
    tol : float
        Relative pole change that counts as converged.
    feedthrough : bool
        Fit a constant term ``D``.
    rank_tol : float
        Residue singular values below ``rank_tol * sigma_1`` are dropped in the realisation.
    time_budget_s : float or Deadline, optional
        Opt-in wall-time budget of the VF pole iteration (seconds, or a shared
        :class:`robustctl.Deadline`); when it runs out the best poles so far are used and the fit
        is flagged not converged (the policy of :mod:`robustctl.budget`).
    start_poles : {"lin", "log", "data"}
        Starting poles of VF: spread linearly (default) or logarithmically over the band, or
        ``"data"``: two runs, from poles where the data change
        (:func:`.vector_fitting.data_poles`) and from the linear spread, the lower weighted cost
        kept (dense low modes of a wide band, which a linear start misses). Unused by Chebyshev.

    Returns
    -------
    RationalFit

    Raises
    ------
    FitError
        Bad order, band, weights, method or iteration cap; too few points for the order.
    DataError
        Malformed data, NaN, all-zero channels.
    """
    weights = renamed_keyword(point_weights, weights, "point_weights", "weights", default="auto")
    method = _check_method(method)
    if start_poles not in ("lin", "log", "data"):
        raise FitError(f"start_poles must be 'lin', 'log' or 'data'; got {start_poles!r}.")
    max_iter = _check_iter(DEFAULT_MAX_ITER[method] if max_iter is None else max_iter)
    tol, rank_tol = _check_tolerances(tol, rank_tol)
    stable, feedthrough = flag(stable, "stable", FitError), flag(feedthrough, "feedthrough", FitError)
    common_denominator = flag(common_denominator, "common_denominator", FitError)
    kw = dict(
        method=method, stable=stable, max_iter=max_iter, tol=tol, feedthrough=feedthrough, rank_tol=rank_tol
    )
    prob = prepare_problem(data, order, band, weights)
    _check_scale(prob.g)
    if not common_denominator and len(prob.inputs) > 1:
        return _fit_simo_each(data, order, band, weights, common_denominator=True, **kw)
    deadline = None if time_budget_s is None else as_deadline(time_budget_s, FitError)
    try:
        poles, iters, converged = _pole_kernel(prob, method, max_iter, tol, stable, deadline, start_poles)
        if stable:
            poles, _ = reflect_unstable(poles)
        rw = np.sqrt(prob.w) / np.abs(prob.g)
        residues, d = fit_residues(prob.s, prob.g, rw, poles, feedthrough)
    except np.linalg.LinAlgError as exc:
        raise FitError(
            f"the least-squares problem of the {method} fit is singular ({exc}): the data hold fewer "
            f"independent features than order={order} poles (e.g. a constant or nearly constant "
            "response); lower the order or widen the band."
        ) from None
    ranks = np.array([residue_rank(r, rank_tol) for r in residues], dtype=int)
    if not converged:
        warnings.warn(
            f"{method} pole iteration did not converge in {max_iter} iterations (tol {tol:g}); "
            "the fit is usable but raise max_iter or check the order.",
            IdentifyWarning,
            stacklevel=3,  # past the limit_blas wrapper to the caller
        )
    _warn_out_of_band(poles, prob.band_hz)
    return RationalFit(
        poles,
        residues,
        d,
        ranks,
        prob.inputs,
        prob.outputs,
        prob.band_hz,
        method,
        iters,
        converged,
        prob.data,
    )
