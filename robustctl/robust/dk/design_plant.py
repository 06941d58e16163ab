"""The design plant of D-K iteration: balanced truncation before synthesis on large plants.

A structure with a hundred or more modes gives a generalized plant of several hundred states.
Every K step of D-K solves two Riccati equations of that order (plus the D-scales' states),
and the controller inherits them all: at 160 modes (a 324-state plant) the first K steps
produce controllers of 300+ states and the second one's Riccati solution is numerically
singular (``X1`` with a reciprocal condition number near ``eps``). Most of those states are
lightly damped modes far above the loop's bandwidth that neither the weights nor the
controller can use.

:func:`reduce_design_plant` therefore truncates the whole generalized plant
``P = [w; u] -> [z; y]`` (weights included) by square-root balanced truncation
(:func:`robustctl.balanced.balanced_truncation`; Moore 1981, Glover 1984) before synthesis,
with the a-priori bound ``||P - P_r||_inf <= 2 sum_{i > r} sigma_i`` (Zhou, Doyle & Glover
1996, Theorem 7.9; the seed paper's eq. 13) stated in the result. The reduced plant is given
in balanced coordinates, where the controllability and observability Gramians are equal and
diagonal: the Riccati problems of the K steps are balanced as well as small. The controller
designed on ``P_r`` must not lean on the truncated modes: a K step on ``P_r`` alone is free to
put gain where ``P_r`` has none, and the full plant's high modes then go unstable (on a
160-mode chain every mode above 40 Hz did); covering only the loop's channel ``u -> y`` kept
the loop stable but let the disturbance and uncertainty channels' error raise mu from 1.35 on
the design plant to 1.68 on the full one. The truncation error ``E = P - P_r`` is therefore
folded into the design plant as an additive uncertainty block on the whole plant,
``[z; y] += w_e``, ``z_e = w_E [w; u]``, with a constant weight ``w_E >= max_f sigma_max(E)``
(evaluated on a grid holding every pole frequency of ``P``, times
:data:`DESIGN_COVER_MARGIN`): the full plant is one member of the design plant's uncertainty
set, so the design's robust-performance mu bounds the full plant's (Zhou, Doyle & Glover 1996,
Theorem 11.9, main loop theorem). The controller designed on the
augmented ``P_r`` is then closed around the *full* plant: its stability is checked and its
mu is verified there (:func:`robustctl.robust.dk.verify.verification_grid`), so the returned
peak of mu is the full plant's, not the design model's.

The order (``design_order="auto"``) comes from the truncation bound and the loop, not from a
fixed cap. The first order is the fewest states whose bound ``2 sum sigma_tail`` is at most
:data:`DESIGN_BOUND_RTOL` of ``sigma_1`` (the largest Hankel singular value, a lower bound on
the plant's peak gain ``||P||_inf``), whatever the plant's size: a plant whose Hankel singular
values fall slowly keeps more states (a fixed cap of 100 states left a bound of 19.3 on a
160-mode plant, and its controller did not stabilise the full plant). If the controller
designed on ``P_r`` still does not stabilise the full plant, the loop says how much error it
tolerates: with ``Q = K (I - G_r K)^-1`` (``G_r`` the design plant's ``u -> y``), the full loop
is stable when ``||G - G_r||_inf ||Q||_inf < 1`` (small gain; Zhou, Doyle & Glover 1996,
Theorem 9.5, additive uncertainty), so the next order is the fewest states whose bound is
at most :data:`DESIGN_LOOP_FRACTION` ``/ ||Q||_inf`` (and at least
:data:`DESIGN_ORDER_GROWTH` times the last order), and D-K runs again, at most
:data:`DESIGN_RETRIES` times (deterministic: orders from the Hankel singular values and the
controller only). Every order tried and its outcome is in :attr:`DesignReduction.tried`; a
loop no order stabilises is refused with that list, never returned.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...balanced import balanced_truncation
from ...errors import FitError, SynthesisError
from ...lti import freqresp_array, is_stable
from ..plant import GeneralizedPlant
from ..uncertainty.blocks import Block, BlockStructure
from .verify import closed_loop, verified_mu

__all__ = ["DesignReduction", "reduce_design_plant", "on_full_plant", "check_design_order",
           "design_on_reduced", "loop_tolerance", "truncation_bounds",
           "DESIGN_REDUCE_ABOVE", "DESIGN_BOUND_RTOL", "DESIGN_COVER_MARGIN", "DESIGN_RETRIES",
           "DESIGN_LOOP_FRACTION", "DESIGN_ORDER_GROWTH"]

#: ``design_order="auto"`` reduces plants with more states than this before synthesis (D-K on
#: 80-mode plants, 164 states, runs at full order in under a minute).
DESIGN_REDUCE_ABOVE = 200
#: ``design_order="auto"`` first keeps the fewest states whose truncation bound
#: ``2 sum sigma_tail`` is at most this fraction of the largest Hankel singular value (a lower
#: bound on the plant's peak gain); no fixed cap on the number of states.
DESIGN_BOUND_RTOL = 0.01
#: at most this many further designs at higher orders when a controller designed on the
#: reduced plant does not stabilise the full plant (``design_order="auto"`` only)
DESIGN_RETRIES = 3
#: a retry keeps the fewest states whose bound is at most this fraction of ``1 / ||Q||_inf``,
#: the additive error the last controller's loop tolerates (small gain)
DESIGN_LOOP_FRACTION = 0.5
#: a retry keeps at least this factor times the last order's states
DESIGN_ORDER_GROWTH = 1.25
#: the additive block's weight is this factor times the largest ``sigma_max(P - P_r)`` seen on
#: the grid (the peaks of the truncated lightly damped modes may sit between grid points)
DESIGN_COVER_MARGIN = 1.25


@dataclass(frozen=True)
class DesignReduction:
    """The balanced truncation of the design plant done by :func:`~robustctl.dksyn`.

    Attributes
    ----------
    order_before, order_after : int
        States of the generalized plant and of the design plant the K steps saw.
    bound : float
        ``2 sum_{i > order_after} sigma_i``: ``||P - P_r||_inf <= bound`` (Zhou, Doyle &
        Glover 1996, Theorem 7.9), in the plant's own units (``w, u -> z, y``).
    hsv : ndarray
        Hankel singular values of the plant, descending.
    reason : str
        Why this order (the rule or the caller's ``design_order``).
    error_peak : float
        ``max_f sigma_max(P - P_r)`` on the grid (plant units; at most ``bound``).
    error_weight : float
        The constant weight of the additive uncertainty block ("design reduction") that
        covers the truncation error in the design plant.
    mu_peak_design : float
        Verified peak of mu of the returned controller with the augmented reduced plant (its
        extra block included; NaN until set).
    mu_peak_full : float
        Verified peak of mu with the full plant (the result's ``mu_peak``; NaN until set).
    tried : tuple of (int, float, str)
        Every design order tried before this one: its states, its bound and why it was
        left (the full loop's largest closed-loop pole real part and the loop's tolerance).
    """

    order_before: int
    order_after: int
    bound: float
    hsv: np.ndarray = field(repr=False)
    reason: str
    error_peak: float = float("nan")
    error_weight: float = float("nan")
    mu_peak_design: float = float("nan")
    mu_peak_full: float = float("nan")
    tried: tuple = ()

    @property
    def relative_bound(self) -> float:
        """``bound`` over the largest Hankel singular value (a lower bound on ``||P||_inf``)."""
        return float(self.bound / self.hsv[0]) if self.hsv.size and self.hsv[0] > 0 else float("nan")

    def summary(self) -> str:
        """One sentence: the orders, the bound and the two verified peaks of mu."""
        return (
            f"Design plant reduced by balanced truncation from {self.order_before} to {self.order_after} "
            f"states (||P - P_r||_inf <= {self.bound:.3g}, {100 * self.relative_bound:.2g} % of the largest "
            f"Hankel singular value; {self.reason}), the error (peak {self.error_peak:.3g}) covered "
            f"by an additive uncertainty block of weight {self.error_weight:.3g}; the controller's "
            "verified mu is "
            f"{self.mu_peak_full:.4f} with the full plant ({self.mu_peak_design:.4f} with the reduced one)."
            + _tried_sentence(self.tried)
        )


def _tried_sentence(tried: tuple) -> str:
    if not tried:
        return ""
    parts = "; ".join(f"{r} states (bound {b:.3g}): {why}" for r, b, why in tried)
    return f" Orders tried first: {parts}."


def truncation_bounds(hsv: np.ndarray) -> np.ndarray:
    """``bounds[r] = 2 sum_{i > r} sigma_i`` for ``r = 0 .. n`` (Zhou, Doyle & Glover 1996, Thm 7.9)."""
    return 2.0 * np.concatenate([np.cumsum(hsv[::-1])[::-1], [0.0]])


def _order_within(hsv: np.ndarray, tol: float, at_least: int = 1) -> int:
    """The fewest states (at least ``at_least``, at most ``hsv.size``) whose truncation bound is
    at most ``tol``."""
    ok = np.flatnonzero(truncation_bounds(hsv) <= tol)
    return min(max(int(ok[0]) if ok.size else hsv.size, int(at_least), 1), hsv.size)


def _auto_order(hsv: np.ndarray) -> int:
    """The fewest states whose truncation bound is within ``DESIGN_BOUND_RTOL`` of ``hsv[0]``."""
    return _order_within(hsv, DESIGN_BOUND_RTOL * hsv[0])


def check_design_order(value: Any) -> Any:
    """The checked ``design_order`` of :func:`~robustctl.dksyn`.

    Parameters
    ----------
    value : None, "auto" or int
        ``None``, ``"auto"`` or a positive number of states.

    Returns
    -------
    None, "auto" or int

    Raises
    ------
    SynthesisError
        Anything else.
    """
    if value is None or (isinstance(value, str) and value == "auto"):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and value >= 1:
        return int(value)
    raise SynthesisError(
        f"design_order must be 'auto' (reduce plants above {DESIGN_REDUCE_ABOVE} states), None (never "
        f"reduce) or a positive number of states; got {value!r}."
    )


def reduce_design_plant(plant: GeneralizedPlant,
                        design_order: Any = "auto") -> tuple[GeneralizedPlant, DesignReduction | None]:
    """The design plant of D-K: ``plant`` itself, or its balanced truncation.

    Parameters
    ----------
    plant : GeneralizedPlant
        The checked plant (``P``, ``nmeas``, ``ncon``, ``blocks``).
    design_order : "auto", int or None
        ``"auto"``: plants of more than :data:`DESIGN_REDUCE_ABOVE` states are reduced to the
        fewest states whose bound ``2 sum sigma_tail`` is at most :data:`DESIGN_BOUND_RTOL`
        of the largest Hankel singular value (no fixed cap);
        plants that are not asymptotically stable are kept whole (balanced truncation needs
        stability). An integer: reduce to that many states (refused for an unstable plant).
        None: never reduce.

    Returns
    -------
    plant : GeneralizedPlant
        The design plant (same channels, ``D`` and blocks; balanced coordinates).
    reduction : DesignReduction or None
        None when the plant is kept whole.

    Raises
    ------
    SynthesisError
        A bad ``design_order``, or an explicit order for a plant balanced truncation cannot
        reduce (not asymptotically stable, or fewer significant Hankel singular values).

    References
    ----------
    Zhou, Doyle & Glover, *Robust and Optimal Control* (1996), sec. 7.2 and Theorem 7.9
    (the error bound); Moore (1981); the seed paper's eqs. 11-13.
    """
    design_order = check_design_order(design_order)
    n = int(plant.P.nstates)
    if design_order is None or (design_order == "auto" and n <= DESIGN_REDUCE_ABOVE):
        return plant, None
    if isinstance(design_order, int) and design_order >= n:
        return plant, None
    if not is_stable(plant.P, margin=0.0):
        if design_order == "auto":
            return plant, None
        raise SynthesisError(
            f"design_order={design_order} asks for a balanced truncation of the {n}-state generalized plant, "
            "which is not asymptotically stable (balanced truncation needs a stable plant: an unstable "
            "structure or a weight with an integrator); pass design_order=None."
        )
    try:
        full = balanced_truncation(plant.P, 1)
    except FitError as exc:
        raise SynthesisError(f"the design plant's balanced truncation failed: {exc}") from exc
    hsv = full.hsv
    if design_order == "auto":
        order = _auto_order(hsv)
        reason = (f"the fewest states within {100 * DESIGN_BOUND_RTOL:g} % of the largest Hankel "
                  "singular value")
    else:
        order, reason = int(design_order), "design_order given"
    if order >= n:
        return plant, None
    return _truncated(plant, order, hsv, reason)


def _truncated(plant: GeneralizedPlant, order: int, hsv: np.ndarray,
               reason: str) -> tuple[GeneralizedPlant, DesignReduction]:
    """The ``order``-state balanced truncation of ``plant`` with its error block."""
    n = int(plant.P.nstates)
    try:
        bt = balanced_truncation(plant.P, order)
    except FitError as exc:
        raise SynthesisError(
            f"design_order={order}: {exc} Ask for fewer states or pass design_order=None."
        ) from exc
    error = _error_peak(plant, bt.sys)
    weight = DESIGN_COVER_MARGIN * max(error, 1e-12 * float(hsv[0]))
    design = _with_error_block(plant, bt.sys, weight)
    return design, DesignReduction(n, order, float(bt.bound), hsv, reason, error, weight)


def _error_peak(plant: GeneralizedPlant, reduced: Any) -> float:
    """``max_f sigma_max(P - P_r)`` over DC, a log grid a decade beyond the plant's pole
    frequencies and every pole frequency of the full plant (where its truncated modes peak)."""
    poles = np.linalg.eigvals(np.asarray(plant.P.A))
    fp = np.abs(poles) / (2 * np.pi)
    fp = fp[fp > 0]
    lo, hi = (float(fp.min()), float(fp.max())) if fp.size else (1e-2, 1e2)
    f = np.unique(np.concatenate([[0.0], np.geomspace(lo / 10, hi * 10, 400), fp]))
    e = freqresp_array(plant.P, f) - freqresp_array(reduced, f)
    return float(np.max(np.linalg.norm(e, 2, axis=(1, 2))))


def _with_error_block(plant: GeneralizedPlant, P_r: Any, weight: float) -> GeneralizedPlant:
    """``P_r`` with an additive uncertainty on the whole plant, ``[z; y] += w_e``,
    ``z_e = weight [w; u]``: a full complex block ("design reduction", ``(nz + ny) x (nw + nu)``)
    inserted before the last block (the performance block stays last)."""
    import control

    A, B, C, D = (np.asarray(m, dtype=float) for m in (P_r.A, P_r.B, P_r.C, P_r.D))
    nw, nz, nu, ny, n = plant.nw, plant.nz, plant.ncon, plant.nmeas, A.shape[0]
    n_in, n_out = nw + nu, nz + ny
    blocks = tuple(plant.blocks)
    nw1 = int(sum(b.rows for b in blocks[:-1]))
    nz1 = int(sum(b.cols for b in blocks[:-1]))
    # extended matrices with the new channels appended (w_e after u, z_e after y), then permuted
    col_w = np.r_[np.arange(nw1), n_in + np.arange(n_out), np.arange(nw1, nw), nw + np.arange(nu)]
    row_z = np.r_[np.arange(nz1), n_out + np.arange(n_in), np.arange(nz1, nz), nz + np.arange(ny)]
    Bx = np.hstack([B, np.zeros((n, n_out))])
    Cx = np.vstack([C, np.zeros((n_in, n))])
    Dx = np.zeros((n_out + n_in, n_in + n_out))
    Dx[:n_out, :n_in] = D
    Dx[:n_out, n_in:] = np.eye(n_out)  # [z; y] += w_e
    Dx[n_out:, :n_in] = weight * np.eye(n_in)  # z_e = weight [w; u]
    ins = list(P_r.input_labels) + [f"design_err_in[{k}]" for k in range(n_out)]
    outs = list(P_r.output_labels) + [f"design_err_out[{k}]" for k in range(n_in)]
    P_aug = control.ss(A, Bx[:, col_w], Cx[row_z], Dx[np.ix_(row_z, col_w)],
                       inputs=[ins[k] for k in col_w], outputs=[outs[k] for k in row_z])
    new = blocks[:-1] + (Block("full", n_out, n_in, "design reduction"),) + blocks[-1:]
    return GeneralizedPlant(P_aug, plant.nmeas, plant.ncon, blocks=BlockStructure(new))


class _UnstabilisedError(SynthesisError):
    """The controller designed on the reduced plant does not stabilise the full plant."""

    def __init__(self, message: str, alpha: float) -> None:
        super().__init__(message)
        self.alpha = alpha


def on_full_plant(plant: GeneralizedPlant, blocks: Any, result: Any, reduction: DesignReduction) -> Any:
    """A D-K result designed on the reduced plant, closed around the full ``plant``.

    Parameters
    ----------
    plant : GeneralizedPlant
        The full plant.
    blocks : BlockStructure
        The analysis' block structure (real blocks complexified or not, as D-K used them).
    result : DKResult
        :func:`~robustctl.dksyn` on the design plant.
    reduction : DesignReduction
        What :func:`reduce_design_plant` did.

    Returns
    -------
    DKResult
        ``closed_loop``, ``mu`` and ``mu_peak`` of the full plant (mu verified on
        :func:`~robustctl.robust.dk.verify.verification_grid`, which holds the full loop's
        lightly damped poles), ``design_reduction`` with both verified peaks.

    Raises
    ------
    SynthesisError
        The controller does not stabilise the full plant.
    """
    from dataclasses import replace as _replace

    cl = closed_loop(plant.P, result.K, plant.nmeas, plant.ncon)
    if not is_stable(cl, margin=0.0):
        alpha = float(np.linalg.eigvals(np.asarray(cl.A)).real.max())
        raise _UnstabilisedError(
            f"the controller designed on the {reduction.order_after}-state balanced truncation of the "
            f"{reduction.order_before}-state plant (error bound {reduction.bound:.3g}) does not stabilise "
            "the full plant: the truncated dynamics matter to this loop. Pass a larger design_order (or "
            "None), or cover the truncated modes with uncertainty weights.", alpha)
    f = np.asarray(result.mu.f_hz, dtype=float)
    m = verified_mu(cl, blocks, f[f > 0])  # the verification grid adds DC itself
    done = _replace(reduction, mu_peak_design=float(result.mu_peak), mu_peak_full=float(m.peak))
    k = len(plant.blocks) - 1  # the design-reduction block's scale (the last block has none)
    d = tuple(result.d_scales)
    d = d[:k] + d[k + 1:] if len(d) > k else d
    return _replace(result, closed_loop=cl, mu=m, mu_peak=float(m.peak), design_reduction=done,
                    blocks=plant.blocks, d_scales=d)


def loop_tolerance(design: GeneralizedPlant, K: Any, f_hz: np.ndarray) -> float:
    """``1 / max_f sigma_max(K (I - G_r K)^-1)``: the additive error on ``G_r`` (the design
    plant's ``u -> y``) that the loop of ``K`` tolerates by the small-gain theorem (Zhou, Doyle &
    Glover 1996, Theorem 9.5), on ``f_hz`` and the pole frequencies of ``G_r`` and ``K``."""
    fp = [np.abs(np.linalg.eigvals(np.asarray(m.A))) / (2 * np.pi) for m in (design.P, K) if m.nstates]
    f = np.unique(np.concatenate([np.asarray(f_hz, dtype=float).ravel(), *fp, [0.0]]))
    ny, nu = design.nmeas, design.ncon
    G = freqresp_array(design.P, f)[:, -ny:, -nu:]
    Kf = freqresp_array(K, f)
    Q = Kf @ np.linalg.inv(np.eye(ny) - G @ Kf)
    peak = float(np.max(np.linalg.norm(Q, 2, axis=(1, 2))))
    return 1.0 / peak if peak > 0 else float("inf")


def design_on_reduced(plant: GeneralizedPlant, design_order: Any, blocks: Any, solve: Any) -> Any:
    """D-K on the design plant of ``design_order``, closed around the full plant, with retries at
    higher orders when the controller does not stabilise the full plant (module docstring).

    Parameters
    ----------
    plant : GeneralizedPlant
        The checked full plant.
    design_order : "auto", int or None
        As :func:`reduce_design_plant`; retries only for ``"auto"``.
    blocks : BlockStructure
        The analysis' block structure (for :func:`on_full_plant`).
    solve : callable ``(design_plant, with_error_block) -> DKResult``
        One D-K design; ``with_error_block`` says the plant carries the design-reduction block.

    Returns
    -------
    DKResult
        On the full plant; ``design_reduction.tried`` lists the orders left before.

    Raises
    ------
    SynthesisError
        No order tried gives a controller that stabilises the full plant (each order, its
        bound and the loop's tolerance are in the message).
    """
    from dataclasses import replace as _replace

    design, shrink = reduce_design_plant(plant, design_order)
    if shrink is None:
        return solve(plant, False)
    n = int(plant.P.nstates)
    tried: list[tuple[int, float, str]] = []
    for attempt in range(DESIGN_RETRIES + 1):
        designed = solve(design, True)
        try:
            result = on_full_plant(plant, blocks, designed, shrink)
        except _UnstabilisedError as exc:
            if check_design_order(design_order) != "auto":
                raise
            tol = loop_tolerance(design, designed.K, np.asarray(designed.mu.f_hz, dtype=float))
            why = (f"full loop unstable (largest pole real part {exc.alpha:.3g}), the loop tolerates "
                   f"{tol:.3g}")
            tried.append((shrink.order_after, float(shrink.bound), why))
            order = _order_within(shrink.hsv, DESIGN_LOOP_FRACTION * tol,
                                  at_least=int(np.ceil(DESIGN_ORDER_GROWTH * shrink.order_after)))
            if attempt == DESIGN_RETRIES or order >= n:
                raise SynthesisError(
                    f"no design order gives a controller that stabilises the full {n}-state plant; tried "
                    + "; ".join(f"{r} states (bound {b:.3g}): {w}" for r, b, w in tried)
                    + ". Pass design_order=None (the full plant) or cover the truncated modes with "
                    "uncertainty weights.") from exc
            reason = (f"raised after {len(tried)} design(s) that did not stabilise the full plant: the "
                      f"fewest states within {DESIGN_LOOP_FRACTION:g} of the loop's tolerance {tol:.3g}, at "
                      "least "
                      f"{DESIGN_ORDER_GROWTH:g} times {shrink.order_after}")
            design, shrink = _truncated(plant, order, shrink.hsv, reason)
            continue
        if tried:
            result = _replace(result, design_reduction=_replace(result.design_reduction, tried=tuple(tried)))
        return result
    raise AssertionError("unreachable")  # pragma: no cover
