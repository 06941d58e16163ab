"""Controller reduction after D-K iteration: balanced truncation of K, the order chosen by the
Hankel singular values and the mu of the truncated loop (:class:`Reduction`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...balanced import balanced_truncation
from ...checks import integer
from ...errors import SynthesisError
from ...interconnect import PartitionedPlant
from ...lti import is_stable
from ..plant import GeneralizedPlant
from ..reduction.controller import reducer
from ..uncertainty.blocks import BlockStructure
from .verify import closed_loop, mu_of

#: A reduced controller is kept when the peak of mu rises by at most this fraction.
REDUCE_MU_RTOL = 0.02
#: ``reduce="auto"`` truncates at least the states whose Hankel singular value is below this
#: fraction of the largest (numerically non-minimal: their truncation changes K by at most
#: ``2 sum sigma_i``, below 1e-7 of its gain).
HSV_RTOL = 1e-9
@dataclass(frozen=True)
class Reduction:
    """A final balanced-truncation reduction of the controller, re-checked by mu.

    ``accepted`` is False (and the full controller kept) when the reduced controller does
    not stabilise the plant or raises mu by more than ``mu_rtol``. ``method`` is "balanced",
    "weighted" or "coprime" and ``error`` the truncation's error figure at ``order_after``
    (:mod:`robustctl.robust.reduction.controller`): the a-priori bound ``2 sum sigma_tail`` on
    ``||K - Kr||_inf`` (balanced), the achieved ``||(K - Kr)(I - G K)^-1 G||_inf`` (weighted;
    below 1 certifies stability), or the achieved coprime-factor error (coprime).
    """

    order_before: int
    order_after: int
    mu_peak_before: float
    mu_peak_after: float
    accepted: bool
    reason: str
    method: str = "balanced"
    error: float = float("nan")


def _reduce(plant: GeneralizedPlant, blocks: BlockStructure, K: Any, cl: Any, m: Any, order: Any,
            base: np.ndarray, refine: bool, mu_rtol: float = REDUCE_MU_RTOL):
    """Balanced truncation of the controller (Moore 1981; seed eq. 13), re-checked by mu.

    ``order="auto"``: the smallest order whose truncation stabilises the loop and keeps the
    peak of mu within ``mu_rtol`` of the full controller's, found by bisection over the
    orders below the controller's numerically minimal order (Hankel singular values above
    ``HSV_RTOL`` of the largest); at most ``ceil(log2 n) + 1`` mu analyses.
    """
    method = "balanced"
    if isinstance(order, tuple) and len(order) == 2 and order[0] in ("weighted", "coprime"):
        method, order = order  # controller_reduction.py: closed-loop weighted or coprime-factor truncation
    auto = isinstance(order, str) and order == "auto"
    if not auto:
        integer(order, "reduce (the number of controller states)", SynthesisError, lo=1,
                alternative="'auto', or a pair ('weighted' or 'coprime', that)")
    n = K.nstates
    if not auto and order >= n:
        return K, cl, m, Reduction(n, n, m.peak, m.peak, False, f"the controller has only {n} states")
    if method != "coprime" and not is_stable(K, margin=0.0):
        return K, cl, m, Reduction(n, n if auto else order, m.peak, np.inf, False,
                                   "the controller is unstable (balanced truncation needs a stable one; "
                                   "use reduce=('coprime', order))")
    errors: dict[int, float] = {}
    if method == "balanced":
        hsv, reduce_to = None, balanced_truncation
    else:
        try:
            hsv, reduce_to = reducer(K, PartitionedPlant(plant.P, plant.nmeas, plant.ncon), method)
        except SynthesisError as exc:
            return K, cl, m, Reduction(n, n if auto else order, m.peak, np.inf, False, str(exc), method)

    def truncate(r: int) -> Any:
        red = reduce_to(K, r) if method == "balanced" else reduce_to(r)
        errors[r] = float(red.bound if method == "balanced" else red.error)
        return red.sys if method == "balanced" else red.K

    tried: dict[int, tuple] = {}

    def attempt(r: int) -> tuple:
        if r not in tried:
            try:
                tried[r] = _truncated_loop(plant, blocks, K, truncate(r), m, base, refine, mu_rtol)
            except SynthesisError as exc:
                tried[r] = (K, None, None, str(exc))
        return tried[r]

    if not auto:
        Kr, clr, mr, reason = attempt(int(order))
        err = errors.get(int(order), float("nan"))
        if reason:
            return K, cl, m, Reduction(n, order, m.peak, mr.peak if mr is not None else np.inf, False, reason,
                                       method, err)
        return Kr, clr, mr, Reduction(n, order, m.peak, mr.peak, True, "", method, err)
    r = _auto_order(balanced_truncation(K, 1).hsv if hsv is None else hsv, attempt)
    if r is None:
        return K, cl, m, Reduction(n, n, m.peak, m.peak, False, "no truncation kept mu within "
                                   f"{100 * mu_rtol:g} % of the full controller's", method)
    Kr, clr, mr, _ = attempt(r)
    return Kr, clr, mr, Reduction(n, r, m.peak, mr.peak, True, "", method, errors.get(r, float("nan")))


def _auto_order(hsv: np.ndarray, attempt: Callable[[int], tuple]) -> int | None:
    """Smallest order ``r`` with ``attempt(r)`` accepted, by bisection on ``[1, r_min]``, where
    ``r_min`` counts the Hankel singular values above ``HSV_RTOL`` of the largest; orders that
    would split (nearly) equal singular values move up by one. None when no order below the
    controller's own passes."""
    n = hsv.size
    r_min = int(np.count_nonzero(hsv > HSV_RTOL * hsv[0]))
    hi = n if r_min == n or attempt(r_min)[3] else r_min  # attempt(hi) succeeds (hi = n: K itself)
    lo = 0  # attempt(lo) fails (lo = 0: no controller)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        while mid < hi and hsv[mid - 1] <= hsv[mid] * (1 + 1e-6):  # do not split a pair
            mid += 1
        if mid >= hi:
            break
        if attempt(mid)[3]:
            lo = mid
        else:
            hi = mid
    return hi if hi < n else None


def _truncated_loop(plant: GeneralizedPlant, blocks: BlockStructure, K: Any, reduced: Any, m: Any,
                    base: np.ndarray,
                    refine: bool, mu_rtol: float) -> tuple:
    """``(Kr, closed loop, mu, reason)`` of a truncated controller; ``reason`` is empty when it
    stabilises the plant and raises the peak of mu by at most ``mu_rtol``."""
    import control

    Kr = control.ss(reduced.A, reduced.B, reduced.C, reduced.D, inputs=list(K.input_labels),
                    outputs=list(K.output_labels))
    clr = closed_loop(plant.P, Kr, plant.nmeas, plant.ncon)
    if not is_stable(clr, margin=0.0):
        return Kr, clr, None, "the reduced loop is unstable"
    mr, _ = mu_of(clr, blocks, base, refine)
    if mr.peak > m.peak * (1 + mu_rtol):
        return Kr, clr, mr, f"peak mu rose by more than {100 * mu_rtol:g} %"
    return Kr, clr, mr, ""
